"""backlash: reversal error of an axis, -(b/2) sign(last commanded direction) (ISO 230-2
reversal value b; mm, deg for A, B in reports). Only axes that reverse in the program."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import AXES, ROTARY_AXES
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text
from camsmooth.machine.model import ErrorModel

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class Backlash(Term):
    name = "backlash"
    needs = "axis reversals"

    def _axes(self, P):
        return [a for a in getattr(P, "axes", AXES) if P.knots.reverses(a)]  # a trace names its own axes

    def applicable(self, P: Problem) -> str | None:
        return None if self._axes(P) else "no axis reverses in the program"

    def params(self, P: Problem) -> list[Param]:
        return [Param(f"b_{a}", -0.2 if a in ROTARY_AXES else -10.0, 0.2 if a in ROTARY_AXES else 10.0,
                      1e-5 if a in ROTARY_AXES else 1e-3, "rad" if a in ROTARY_AXES else "mm", a)
                for a in self._axes(P)]

    def write(self, model: ErrorModel, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            model.backlash[n[2:]] = float(v)

    def read(self, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
        return np.array([model.backlash.get(n[2:], 0.0) for n in names])

    def jacobian(self, P: Problem, model: ErrorModel, names: Sequence[str]) -> np.ndarray | None:
        """Exact columns: the axis stands -(b/2) sign(last commanded direction) off its lagged
        command, so d channel / d b = -(1/2) dir d channel / d q (the chain's space Jacobian,
        ``Simulator.joint_derivatives``)."""
        sim = P.sim_fit
        axes = [n[2:] for n in names]
        dq = sim.joint_derivatives(model, axes)
        k, _ = sim.loc(model.offset_s)
        rows = []
        for a in axes:
            d = -0.5 * P.knots.direction(a)[k]
            rows.append(-(dq[a] * d[:, None] * P.w_fit)[P.valid_fit])
        return np.stack(rows)

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            a = n[2:]
            f = math.degrees(1.0) if a in ROTARY_AXES else 1.0
            par[f"backlash_{a}"] = float(v * f)
            unc[f"backlash_{a}"] = float(s * f)
            unit[f"backlash_{a}"] = "deg" if a in ROTARY_AXES else "mm"
        return par, unc, unit

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        parts = [f"{k[9:]} {fmt(v, 'deg' if k[9:] in ROTARY_AXES else 'mm')} ± "
                 f"{fmt(unc.get(k), 'deg' if k[9:] in ROTARY_AXES else 'mm')}" for k, v in params.items()]
        return f"The axes lose motion at each reversal (backlash {', '.join(parts)}{none_text(none)})"

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = names[0][2:]
        return f"last direction of {a} (-1/+1)", P.states[f"dir_{a}"], "1"
