"""time_offset: the recording clock runs offset_s behind the program's, sim(t) = model(t - d).
A clock offset far below the sample period is not a finding: it must reach
``Options.min_offset_periods`` of the sample period (and clear the generic effect rules)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import AXES
from camsmooth.diagnosis.terms.base import Param, Term, fmt
from camsmooth.machine.model import ErrorModel

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class TimeOffset(Term):
    name = "time_offset"
    needs = "moving axes"

    def applicable(self, P: Problem) -> str | None:
        moving = any(P.knots.moves(a) for a in getattr(P, "axes", AXES))  # a trace names its own axes
        return None if moving or P.knots.S is not None else "nothing moves"

    def params(self, P: Problem) -> list[Param]:
        span = float(P.t[-1] - P.t[0])
        b = min(5.0, 0.25 * span)
        return [Param("offset_s", -b, b, 1e-3, "s", "clock")]

    def write(self, model: ErrorModel, names: Sequence[str], x: np.ndarray) -> None:
        model.offset_s = float(x[0])

    def read(self, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
        return np.array([model.offset_s])

    def initial(self, P: Problem, model: ErrorModel, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        num = den = 0.0
        for a in getattr(P, "axes", AXES):  # a trace names its own axes
            c = f"{a}_act"
            if c in P.channels and P.knots.moves(a):
                j = P.channels.index(c)
                ok = P.valid_fit[:, j]
                v = P.states[f"v_{a}"][ok] * P.w_fit[ok, j]
                num += float(np.sum(resid[ok, j] * P.w_fit[ok, j] * v))
                den += float(np.sum(v * v))
        x0 = model.offset_s + (-num / den if den > 0 else 0.0)
        p = self.params(P)[0]
        return np.array([float(np.clip(x0, p.lo, p.hi))])

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        return {"offset_s": float(x[0])}, {"offset_s": float(sd[0])}, {"offset_s": "s"}

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        return (f"The recording runs {fmt(params['offset_s'] * 1000)} ± {fmt(unc['offset_s'] * 1000)} ms "
                f"{'behind' if params['offset_s'] >= 0 else 'ahead of'} the program's clock")

    def unresolvable(self, P: Problem, names: Sequence[str], x: np.ndarray, sd: np.ndarray) -> str | None:
        d = abs(float(x[0] - P.base.offset_s))
        limit = P.options.min_offset_periods * P.dt
        if d < limit:
            return (f"the fitted clock offset {d * 1e6:.3g} us is below {P.options.min_offset_periods:g} of the "
                    f"sample period ({P.dt * 1e3:.3g} ms): not resolvable on this recording")
        return None

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = max((a for a in getattr(P, "axes", AXES) if f"v_{a}" in P.states), key=lambda a: np.std(P.states[f"v_{a}"]))
        return f"commanded velocity {a}", P.states[f"v_{a}"], "mm/s"
