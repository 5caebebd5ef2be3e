"""Program outputs: the per-point result CSV (the five-axis G-code writer is camsmooth.post.writer,
a smoothing result's ``write_gcode`` camsmooth.smoothing.posting, re-exported here for existing
callers).

Files are written atomically (``camsmooth.io.atomic.atomic_path``): a failed write never leaves a
partial file. Units in files: mm, s, degrees (radians inside the code; CONVENTIONS.md).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM, DEFAULT_TOLERANCE_MM
from camsmooth.io.table import read_table, write_table
from camsmooth.smoothing.posting import write_gcode
from camsmooth.smoothing.result import OUTPUT_COLUMNS, MethodResult, SmoothResult, interferes, output_columns

__all__ = ["RESULT_CSV_COLUMNS", "STATUSES", "DEFAULT_SAFE_HEIGHT_MM", "point_status",
           "write_result_csv", "read_result_csv", "write_gcode"]

#: Columns of the result CSV: OUTPUT_COLUMNS, then ``lift`` (mm) and ``status``.
RESULT_CSV_COLUMNS: tuple[str, ...] = OUTPUT_COLUMNS + ("lift", "status")
#: Per-point status values, least to most severe; a point gets the most severe that applies.
STATUSES: tuple[str, ...] = ("ok", "lifted", "interference", "unreachable")

_INT_COLUMNS = ("row", "idx")
_STR_COLUMNS = ("status",)


# ----------------------------------------------------------------------------------------------
# per-point status
def point_status(result: MethodResult, tolerance: float | None = None) -> np.ndarray:
    """Status string per point of one method (array of str, values in STATUSES).

    'unreachable': (row, idx) is listed in ``metrics.unreachable`` (no inverse-kinematics
    solution within the travel limits); else 'interference': clearance ``delta`` < -``tolerance``
    mm (gouge left after smoothing and any lift; camsmooth.smoothing.result.interferes, the rule
    the metrics count with); else 'lifted': the fallback lift along the normal was applied
    (``lift`` > 0); else 'ok'. A NaN delta is not counted as interference. ``tolerance`` (mm,
    the part's allowed deviation) defaults to the one the method's metrics were computed with
    (``metrics.tolerance_mm``, the user's ``--tolerance``), else DEFAULT_TOLERANCE_MM.
    """
    if tolerance is None:
        tolerance = result.metrics.tolerance_mm if result.metrics is not None else DEFAULT_TOLERANCE_MM
    n = len(result)
    status = np.full(n, "ok", dtype=object)
    lift = np.asarray(result.lift, dtype=float)
    status[np.nan_to_num(lift, nan=0.0) > 0.0] = "lifted"
    status[interferes(result.delta, tolerance)] = "interference"
    unreachable = result.metrics.unreachable if result.metrics is not None else []
    if len(unreachable):
        pairs = np.asarray(unreachable, dtype=np.int64).reshape(-1, 2)
        rows = np.asarray(result.rows, dtype=np.int64)
        idx = np.asarray(result.idx, dtype=np.int64)
        # structured view compares (row, idx) pairs as one key without a Python loop per point
        key_dtype = np.dtype([("r", np.int64), ("i", np.int64)])
        points = np.empty(n, key_dtype)
        points["r"], points["i"] = rows, idx
        listed = np.empty(len(pairs), key_dtype)
        listed["r"], listed["i"] = pairs[:, 0], pairs[:, 1]
        status[np.isin(points, listed)] = "unreachable"
    return status.astype(str)


# ----------------------------------------------------------------------------------------------
# result CSV
def write_result_csv(path: str | os.PathLike, result: SmoothResult) -> Path:
    """Write the primary method's per-point table to ``path`` atomically; return the path.

    Columns: RESULT_CSV_COLUMNS = OUTPUT_COLUMNS (mm, s, degrees; see camsmooth.smoothing.result) then
    ``lift`` (mm, fallback lift along the normal, 0 where none) and ``status`` (see
    ``point_status``), then ``fx,fy,fz`` (unit feed direction, the local frame's X_L) when the
    result carries them, then ``t_plan`` (s from the row's start) and ``feed_plan`` (mm/min,
    tool-tip feed) as the machine's controller runs the program (camsmooth.controller, where
    camsmooth models the controller; else the time-optimal law) and ``t_opt``, ``feed_opt``, the
    time-optimal law (camsmooth.smoothing.feed), when it has a plan. Floats in their shortest
    exact round-trip form; ``row`` and ``idx`` as integers (camsmooth.io.table.write_table).
    """
    r = result.result
    table = result.table()
    names = output_columns(r.rotary.names)  # the rotary columns as the result names them
    if table.shape[1] != len(names):
        raise ValueError(f"SmoothResult.table() has {table.shape[1]} columns, expected {len(names)}")
    columns: dict[str, np.ndarray] = {}
    for k, name in enumerate(names):
        columns[name] = table[:, k].astype(np.int64) if name in _INT_COLUMNS else table[:, k]
    columns["lift"] = np.asarray(r.lift, float)
    columns["status"] = point_status(r)
    if r.feed_dirs is not None:  # the local frame's X_L, so predict can re-evaluate lead/tilt exactly
        for k, name in enumerate(("fx", "fy", "fz")):
            columns[name] = r.feed_dirs[:, k]
    if r.plan is not None:  # the controller's timing where camsmooth models it, else the time-optimal law
        ctrl = getattr(r, "controller", None)
        timing = ctrl if ctrl is not None else r.plan
        columns["t_plan"] = timing.t_plan
        columns["feed_plan"] = timing.feed_plan
        columns["t_opt"] = r.plan.t_plan
        columns["feed_opt"] = r.plan.feed_plan
    return write_table(path, columns)


def read_result_csv(path: str | os.PathLike, required: Sequence[str] | None = None
                    ) -> dict[str, np.ndarray]:
    """Read a result CSV (as written by ``write_result_csv``) into column arrays.

    Returns name -> array for every column in the file: ``row`` and ``idx`` int64, ``status``
    str, all others float (NaN allowed: an unknown clearance is written as nan; units as in the
    file: mm, s, degrees). Read by ``camsmooth.io.table.read_table``: InputError naming the file,
    row and column when the file is missing or empty, a ``required`` column is absent, a row has
    the wrong number of fields or a value is not a number / not an integer. required: None for
    the output columns of any machine kind (``output_columns`` with the rotary pair the header
    names: A,B or A,C or B,C).
    """
    if required is None:
        required = output_columns(result_rotary(path))
    declared = tuple(dict.fromkeys(list(required) + list(_INT_COLUMNS) + list(_STR_COLUMNS)))
    table = read_table(path, required, [c for c in declared if c not in required], integer=_INT_COLUMNS,
                       text=_STR_COLUMNS, nonfinite=[c for c in declared if c not in _INT_COLUMNS],
                       others="float", min_rows=0, what="result file")
    return dict(table.columns)


def result_rotary(path: str | os.PathLike) -> tuple[str, str]:
    """The rotary columns a result CSV's header names (("A", "B") on an AB head, ("A", "C") on an
    AC table, ...): the two of A, B, C that are columns, in alphabetical order (the order of
    ``Machine.rotary``); ("A", "B") when not exactly two are (the reader then names the missing
    columns)."""
    from camsmooth.io.table import read_text_file
    from camsmooth.machine.kinematics import ROTARY_NAMES

    text = read_text_file(path, "result file")
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    names = {h.strip().strip('"') for h in first.split(",")}
    present = [n for n in ROTARY_NAMES if n in names]
    return (present[0], present[1]) if len(present) == 2 else ("A", "B")
