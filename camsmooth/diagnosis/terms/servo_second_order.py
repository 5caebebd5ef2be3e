"""servo_second_order: an axis that overshoots and rings, y'' + 2 zeta wn y' + wn^2 y = wn^2 u
(camsmooth.diagnosis.trace); beside the first-order servo_lag, whose exponential approach has
neither. Parameters T2_<axis> = 1/wn (s; 0 switches it off) and zeta_<axis> (1 when unset),
reported as wn_<axis> (rad/s) and zeta_<axis>. Trace only."""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms._trace import NOT_TRACE, grid_start, moving_axes, trace_of
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class ServoSecondOrder(Term):
    name = "servo_second_order"
    needs = "moving axes in a controller trace"

    def applicable(self, P: Problem) -> str | None:
        if trace_of(P) is None:
            return NOT_TRACE
        return None if moving_axes(P) else "no axis moves in the trace"

    def params(self, P: Problem) -> list[Param]:
        out = []
        for a in moving_axes(P):
            out += [Param(f"T2_{a}", 0.0, 2.0, 1e-3, "s", a), Param(f"zeta_{a}", 0.02, 5.0, 1e-2, "", a)]
        return out

    def write(self, model: Any, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            kind, a = n.split("_", 1)
            (model.t2 if kind == "T2" else model.zeta)[a] = float(v)

    def read(self, model: Any, names: Sequence[str]) -> np.ndarray:
        return np.array([model.t2.get(n[3:], 0.0) if n.startswith("T2_") else model.zeta.get(n[5:], 1.0)
                         for n in names])

    def initial(self, P: Problem, model: Any, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        """Per axis the best of a grid of (1/wn, zeta), the others held at their current values."""
        x = self.read(model, names)
        dt = max(P.dt, 1e-6)
        for a in sorted({n.split("_", 1)[1] for n in names}):
            i, j = names.index(f"T2_{a}"), names.index(f"zeta_{a}")
            sub = [names[i], names[j]]
            grid = itertools.product(dt * np.geomspace(1.0, 2000.0, 12), (0.1, 0.25, 0.45, 0.7, 1.0))
            best = grid_start(P, self, model, sub, (np.array(g) for g in grid))
            x[i], x[j] = best
            self.write(model := model.copy(), sub, best)
        return x

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            kind, a = n.split("_", 1)
            if kind == "T2":
                par[f"wn_{a}"] = float(1.0 / v) if v > 0 else None
                unc[f"wn_{a}"] = float(s / v ** 2) if v > 0 and np.isfinite(s) else None
                unit[f"wn_{a}"] = "rad/s"
            else:
                par[f"zeta_{a}"], unc[f"zeta_{a}"], unit[f"zeta_{a}"] = float(v), float(s), ""
        return par, unc, unit

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        ax = [k[3:] for k, v in params.items() if k.startswith("wn_") and v is not None]
        parts = [f"{a}: wn = {fmt(params[f'wn_{a}'])} ± {fmt(unc.get(f'wn_{a}'))} rad/s, zeta = "
                 f"{fmt(params.get(f'zeta_{a}'))} ± {fmt(unc.get(f'zeta_{a}'))}" for a in ax]
        return f"The servo responds as a second-order system, overshooting and ringing ({'; '.join(parts)}" \
               f"{none_text(none)})"

    def unresolvable(self, P: Problem, names: Sequence[str], x: np.ndarray, sd: np.ndarray) -> str | None:
        """A response faster than the sampling is not a finding: 1/wn below one sample period on every
        axis (a ZOH-discretised controller's own filters leave such a rest on a noise-free trace)."""
        t2 = {n[3:]: float(v) for n, v in zip(names, x, strict=True) if n.startswith("T2_")}
        if t2 and all(v < P.dt for v in t2.values()):
            worst = max(t2, key=lambda a: t2[a])
            return (f"1/wn ({t2[worst] * 1e3:.3g} ms on {worst}) is below the sample period ({P.dt * 1e3:.3g} ms): "
                    "a response faster than the sampling is not resolvable on this recording")
        return None

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = names[0].split("_", 1)[1]
        return f"commanded acceleration {a}", P.states[f"acc_{a}"], "unit/s^2"
