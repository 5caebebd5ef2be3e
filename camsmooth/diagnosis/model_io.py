"""Model files of the diagnosis: the one machine-model JSON (camsmooth.machine.model.ErrorModel,
with its ``servo`` and ``spindle_runout`` sections) read and written for `camsmooth diagnose`."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from camsmooth.machine.model import ErrorModel


def physics_from_model(data: Mapping[str, Any], source: str = "<model>") -> ErrorModel:
    """The model from a parsed model JSON document (``ErrorModel.from_dict``; a document holding
    only ``servo`` / ``spindle_runout`` is accepted too)."""
    return ErrorModel.from_dict(data, source)


def load_model(path: str | None) -> ErrorModel:
    """Read a model JSON (``ErrorModel.from_json``); None gives the ideal model."""
    return ErrorModel() if path is None else ErrorModel.from_json(path)


def model_json(ph: ErrorModel, note: str = "") -> dict[str, Any]:
    """The extended model as a JSON document (``ErrorModel.to_dict``), zero entries left out and
    ``note`` recorded in meta['diagnose']."""
    out = ph.copy()
    if note:
        out.meta["diagnose"] = note
    out.geometric = {k: float(v) for k, v in out.geometric.items() if v != 0.0}
    out.thermal = {k: dict(d) for k, d in out.thermal.items() if d["gain"] != 0.0}
    out.tau = {a: t for a, t in out.tau.items() if t > 0}
    out.backlash = {a: b for a, b in out.backlash.items() if b != 0.0}
    return out.to_dict()
