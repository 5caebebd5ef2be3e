"""velocity_limit and acceleration_limit: an axis that saturates at a speed vmax (its position
moves by at most vmax a second) or an acceleration amax (its velocity follows the commanded one
changing by at most amax a second), camsmooth.diagnosis.trace. Parameters iv_<axis> = 1/vmax
(s/unit) and ia_<axis> = 1/amax (s^2/unit), 0 for no limit; reported as vmax_<axis> (unit/s)
and amax_<axis> (unit/s^2). A limit the commanded motion never reaches has no effect and is not
fitted. Trace only."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms._trace import NOT_TRACE, grid_start, moving_axes, smooth_speed, trace_of
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class _Limit(Term):
    prefix = ""
    what = ""
    report_name = ""
    report_unit = ""

    def _peaks(self, P: Problem, a: str) -> tuple[float, float]:
        """(largest commanded, largest actual) speed or acceleration of axis a (smoothed)."""
        tr = P.trace
        c, y = smooth_speed(tr.t, tr.cmd[a]), smooth_speed(tr.t, tr.act[a])
        if self.prefix == "ia":
            c = smooth_speed(tr.t, np.gradient(tr.cmd[a], tr.t))
            y = smooth_speed(tr.t, np.gradient(np.convolve(tr.act[a], np.ones(5) / 5, mode="same"), tr.t))
        return float(np.max(c)), float(np.percentile(y, 99.5))

    def _axes(self, P: Problem) -> list[str]:
        key = f"limit_axes:{self.name}"
        if key not in P.memo:
            P.memo[key] = [a for a in moving_axes(P) if self._peaks(P, a)[0] > 0.0]
        return P.memo[key]

    def applicable(self, P: Problem) -> str | None:
        if trace_of(P) is None:
            return NOT_TRACE
        return None if self._axes(P) else "no axis moves in the trace"

    def params(self, P: Problem) -> list[Param]:
        out = []
        for a in self._axes(P):
            cmax = self._peaks(P, a)[0]
            out.append(Param(f"{self.prefix}_{a}", 0.0, 1e3 / cmax, 1e-2 / cmax, "", a))
        return out

    def write(self, model: Any, names: Sequence[str], x: np.ndarray) -> None:
        table = getattr(model, self.prefix)
        for n, v in zip(names, x, strict=True):
            table[n[3:]] = float(v)

    def read(self, model: Any, names: Sequence[str]) -> np.ndarray:
        table = getattr(model, self.prefix)
        return np.array([table.get(n[3:], 0.0) for n in names])

    def initial(self, P: Problem, model: Any, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        """Per axis the best of a grid of limits between the actual's peak and the command's peak."""
        x = self.read(model, names)
        for i, n in enumerate(names):
            cmax, ymax = self._peaks(P, n[3:])
            lo = max(min(ymax, cmax), 1e-3 * cmax)
            grid = [np.array([0.0])] + [np.array([1.0 / v]) for v in np.geomspace(0.5 * lo, 1.2 * cmax, 16)]
            x[i] = grid_start(P, self, model, [n], grid)[0]
            model = model.copy()
            self.write(model, [n], x[i:i + 1])
        return x

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            k = f"{self.report_name}_{n[3:]}"
            par[k] = float(1.0 / v) if v > 0 else None
            unc[k] = float(s / v ** 2) if v > 0 and np.isfinite(s) else None
            unit[k] = self.report_unit
        return par, unc, unit

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        u = self.report_unit
        parts = [f"{k.split('_', 1)[1]} {fmt(v, u)} ± {fmt(unc.get(k), u)}" for k, v in params.items() if v is not None]
        return f"The axes saturate at {self.what} ({', '.join(parts)}{none_text(none)})"

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = names[0][3:]
        return f"commanded velocity {a}", P.states[f"v_{a}"], "unit/s"


class VelocityLimit(_Limit):
    name = "velocity_limit"
    needs = "moves commanded faster than the axis can go"
    prefix = "iv"
    what = "a velocity limit"
    report_name = "vmax"
    report_unit = "unit/s"


class AccelerationLimit(_Limit):
    name = "acceleration_limit"
    needs = "velocity changes commanded faster than the axis can follow"
    prefix = "ia"
    what = "an acceleration limit"
    report_name = "amax"
    report_unit = "unit/s^2"
