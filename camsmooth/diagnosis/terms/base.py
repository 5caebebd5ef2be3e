"""The interface every physics term of the diagnosis library implements (PySINDy-like split:
this library of terms, the optimiser in camsmooth.machine.fitting and the selector in
camsmooth.diagnosis.selector).

A term is a parametric addition to the simulation: its parameters (names, bounds, a scale for
finite differences, units and the group - the axis, element or direction - each belongs to),
how they enter the machine model (``write``/``read``), where the data can show it
(``applicable``), a starting point, an optional analytic Jacobian, how its fitted values are
reported (``report``, ``sentence``) and the rules that refuse a fitted value as not physics
(``unresolvable``, ``veto``). Fitting, scoring and selection are done by the selector through
the simulator.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import DIR_CHANNELS, ROTARY_AXES, TIP_CHANNELS
from camsmooth.machine import fitting
from camsmooth.machine.model import ErrorModel

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


@dataclass(frozen=True)
class Param:
    """One parameter of a term (internal units): bounds lo..hi, a typical size ``scale`` (finite
    difference steps are 1e-4 of it), its ``unit`` and the ``group`` (axis, element, direction)
    a 'none measurable' decision applies to."""

    name: str
    lo: float
    hi: float
    scale: float
    unit: str = ""
    group: str = ""
    optional: bool = False  # a higher-order part dropped on its own when not resolvable


class Term:
    """One candidate physics (module docstring)."""

    name = ""
    needs = ""  # plain words for reports

    def applicable(self, P: Problem) -> str | None:
        """None when the data can show this effect, else the reason it cannot."""
        return None

    def params(self, P: Problem) -> list[Param]:
        raise NotImplementedError

    def write(self, model: ErrorModel, names: Sequence[str], x: np.ndarray) -> None:
        raise NotImplementedError

    def read(self, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
        raise NotImplementedError

    def initial(self, P: Problem, model: ErrorModel, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        """A starting point; default: one Gauss-Newton step from the base values."""
        return gn_initial(P, self, model, names, self.read(model, names))

    def jacobian(self, P: Problem, model: ErrorModel, names: Sequence[str]) -> np.ndarray | None:
        """Analytic columns of the floor-weighted residual (p, m) at the valid fit entries, or None
        for finite differences (the default)."""
        return None

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        """(parameters, uncertainties, units) in report units."""
        return ({n: float(v) for n, v in zip(names, x, strict=True)},
                {n: float(s) for n, s in zip(names, sd, strict=True)}, {n: "" for n in names})

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        """The plain description of the fitted effect (the selector adds the RMS figures)."""
        raise NotImplementedError

    def unresolvable(self, P: Problem, names: Sequence[str], x: np.ndarray, sd: np.ndarray) -> str | None:
        """A reason the fitted value is not resolvable on this recording (beyond the generic
        effect-size and uncertainty rules of the selector), or None."""
        return None

    def veto(self, P: Problem, names: Sequence[str], x: np.ndarray) -> str | None:
        """A reason to refuse a fitted value that makes the term something else, or None."""
        return None

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        """(label, values at the fit samples, unit) of the state this effect depends on."""
        return "elapsed time (s)", P.states["elapsed"], "s"


def fmt(v: float | None, unit: str = "") -> str:
    if v is None or not np.isfinite(v):
        return "n/a"
    a = abs(v)
    s = f"{v:.3g}" if (a >= 1e-3 or a == 0) else f"{v:.2e}"
    return f"{s} {unit}".strip()


def none_text(none: Sequence[str]) -> str:
    return f"; none measurable on {', '.join(none)}" if none else ""


def gn_initial(P: Problem, term: Term, model: ErrorModel, names: Sequence[str], x0: np.ndarray) -> np.ndarray:
    """One Gauss-Newton step from x0 on the fit samples (finite-difference columns)."""
    byname = {p.name: p for p in term.params(P)}
    params = [byname[n] for n in names]
    scale = np.array([p.scale for p in params])
    base = model.copy()
    term.write(base, names, x0)
    s0 = P.sim_fit.run(base)
    r0 = ((P.data_fit - s0) * P.w_fit)[P.valid_fit]
    cols = []
    for j in range(len(names)):
        x = x0.copy()
        x[j] += scale[j]
        trial = base.copy()
        term.write(trial, names, x)
        cols.append(((P.sim_fit.run(trial) - s0) * P.w_fit)[P.valid_fit] / scale[j])
    H, g = fitting.gram(np.stack(cols), r0)
    step = np.linalg.pinv(H) @ g
    lo = np.array([p.lo for p in params])
    hi = np.array([p.hi for p in params])
    return np.clip(x0 + step, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))


class Geometric(Term):
    """Geometric model parameters through the chain; only the parameters the program's motion
    can show (checked by the rank of their columns at the base model) are fitted."""

    channels_seen: tuple[str, ...] = TIP_CHANNELS + DIR_CHANNELS
    what = ""

    def present(self, P: Problem) -> list[str]:
        return [c for c in P.channels if c in self.channels_seen]

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        """(name, unit, bound, scale, group[, optional]) of the parameters to try."""
        raise NotImplementedError

    def applicable(self, P: Problem) -> str | None:
        if not self.present(P):
            return "needs measured tool-tip or tool-axis channels"
        if not self.params(P):
            return "the program's motion does not show these parameters"
        return None

    def params(self, P: Problem) -> list[Param]:
        key = f"identifiable:{self.name}"
        cands = self.candidates_for(P)
        if key not in P.memo:
            P.memo[key] = identifiable(P, [c[0] for c in cands], [c[3] for c in cands])
        keep = set(P.memo[key])
        return [Param(c[0], -c[2], c[2], c[3], c[1], c[4], bool(c[5]) if len(c) > 5 else False)
                for c in cands if c[0] in keep]

    def unresolvable(self, P: Problem, names: Sequence[str], x: np.ndarray, sd: np.ndarray) -> str | None:
        """A geometric error whose effect stays below the resolution (quantisation step) of every
        channel it acts on is not a finding, however many samples average it. Judged on the
        channels the fitted error moves (``acted_channels``), each against its own resolution: a
        channel with no detected quantum resolves any effect, so an error on X seen by X_act is
        never refused for the resolution of tip_y, which it does not move."""
        peaks = acted_channels(P, self, names, x)
        if not peaks:
            return None
        res = {c: P.floor_info[c]["q_recording_rms"] for c in peaks}
        if all(peaks[c] < res[c] for c in peaks):
            worst = max(peaks, key=lambda c: peaks[c] / res[c])
            f, u = (1e3, "um") if channel_is_length(worst) else (1.0, "")
            return (f"its largest effect ({peaks[worst] * f:.3g} {u} on {worst}) stays below the recording's "
                    f"resolution ({res[worst] * f:.3g} {u})").replace(" )", ")")
        return None

    def write(self, model: ErrorModel, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            model.geometric[n] = float(v)

    def read(self, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
        return np.array([model.geometric.get(n, 0.0) for n in names])

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        from camsmooth.machine.model import GEOMETRIC_PARAMETERS

        unit = {n: GEOMETRIC_PARAMETERS[n][0] for n in names}
        return ({n: float(v) for n, v in zip(names, x, strict=True)},
                {n: float(s) for n, s in zip(names, sd, strict=True)}, unit)

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        from camsmooth.machine.model import GEOMETRIC_PARAMETERS

        parts = [f"{k} = {fmt(v, GEOMETRIC_PARAMETERS[k][0])}" for k, v in params.items()]
        return f"{self.what} ({', '.join(parts)}{none_text(none)})"


def identifiable(P: Problem, names: Sequence[str], scales: Sequence[float]) -> list[str]:
    """Geometric parameters whose weighted-residual columns at the base model are not negligible
    and not linear combinations of earlier ones (fitting.identifiable_columns)."""
    if not names:
        return []
    base = P.base.copy()
    s0 = P.sim_fit.run(base)
    cols = []
    for n, sc in zip(names, scales, strict=True):
        # the effect of a typical-size change (1 um / 1 urad at the travel's end): comparable columns
        trial = base.copy()
        trial.geometric[n] = trial.geometric.get(n, 0.0) + sc
        cols.append(((P.sim_fit.run(trial) - s0) * P.w_fit)[P.valid_fit])
    keep = fitting.identifiable_columns(np.stack(cols, axis=1), rel_norm=1e-6, tol=1e-3)
    return [names[i] for i in keep]


def travel(P: Problem, a: str) -> float:
    """The largest |position| (mm) axis a reaches in the program (at least 1 mm)."""
    u = P.knots.u.get(a)
    return max(1.0, float(np.max(np.abs(u)))) if u is not None else 1.0


def acted_channels(P: Problem, t: Term, names: Sequence[str], x: np.ndarray, rel: float = 0.01
                   ) -> dict[str, float]:
    """The channels term ``t`` with parameters ``names`` = x (over the base model) acts on: channel
    -> largest |change| of the simulated channel (internal units), for the channels whose change
    exceeds ``rel`` of the largest change in noise floors (a term that does not move a channel is
    not judged there)."""
    m = P.base.copy()
    t.write(m, names, x)
    d = np.abs(P.sim_fit.run(m) - P.sim_fit.run(P.base))
    peaks = {c: float(np.max(d[:, j])) for j, c in enumerate(P.channels)}
    z = {c: float(np.max(d[:, j] * P.w_fit[:, j])) for j, c in enumerate(P.channels)}
    top = max(z.values(), default=0.0)
    if not top > 0.0:
        return {}
    return {c: peaks[c] for c in P.channels if z[c] > rel * top}


def channel_is_length(c: str) -> bool:
    return c in TIP_CHANNELS or c in ("X_act", "Y_act", "Z_act")


def rotary_state(P: Problem) -> tuple[str, np.ndarray, str]:
    for a in ROTARY_AXES:
        if P.knots.moves(a):
            return f"rotary axis {a} (deg)", np.degrees(P.states[f"pos_{a}"]), "deg"
    return "elapsed time (s)", P.states["elapsed"], "s"
