"""quantisation: the measured channel is rounded to a grid, an encoder's count or the logger's last
digit: act = v0 + q round((y - v0) / q), y the axis position the other terms predict
(camsmooth.diagnosis.trace). The step q and the grid's origin v0 are the act channel's own value
grid (camsmooth.diagnosis.recordings.quantisation_steps: a uniform grid of the values, else the
written decimals or figures, per sample), read from the data, not fitted; the fitted parameter is
the share g_<axis> of the rounding the recording shows (0 switches it off, 1 is the whole
staircase), through the rounding's mean under a small jitter (``trace.QUANT_JITTER`` of q: a smooth
function of y, so the other terms keep their derivatives). Reported as q_<axis> (unit) and
share_<axis>. The noise floor already holds q / sqrt(12); the staircase is named only where the
rest of the model predicts y well enough to show where each step falls (white noise well below q):
a share below ``MIN_SHARE`` is refused as not the channel's rounding. Trace only."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms._trace import NOT_TRACE, moving_axes, trace_of
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem

#: a fitted share of the staircase below this is not the channel's rounding (a staircase that
#: white noise comparable with q smears shows as a small share: the steps are not where y puts them)
MIN_SHARE = 0.5


class Quantisation(Term):
    name = "quantisation"
    needs = "a moving axis whose actual channel lies on a grid of values"

    def _axes(self, P: Problem) -> list[str]:
        return [a for a in moving_axes(P) if float(np.max(P.sim_fit.quant_grid(a)[0], initial=0.0)) > 0.0]

    def applicable(self, P: Problem) -> str | None:
        if trace_of(P) is None:
            return NOT_TRACE
        return None if self._axes(P) else "no moving axis's actual channel lies on a grid of values"

    def params(self, P: Problem) -> list[Param]:
        return [Param(f"qg_{a}", 0.0, 1.5, 1e-2, "", a) for a in self._axes(P)]

    def write(self, model: Any, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            model.quant[n[3:]] = float(v)

    def read(self, model: Any, names: Sequence[str]) -> np.ndarray:
        return np.array([model.quant.get(n[3:], 0.0) for n in names])

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        """share_<axis>; the step q_<axis> is added by the trace's report (it is the data's)."""
        return ({f"share_{n[3:]}": float(v) for n, v in zip(names, x, strict=True)},
                {f"share_{n[3:]}": float(s) for n, s in zip(names, sd, strict=True)},
                {f"share_{n[3:]}": "" for n in names})

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        ax = [k[6:] for k in params if k.startswith("share_")]
        parts = [f"{a}_act in steps of {fmt(params.get(f'q_{a}'), 'unit')} (share {fmt(params[f'share_{a}'])} ± "
                 f"{fmt(unc.get(f'share_{a}'))})" for a in ax]
        return f"The measured channel is quantised: {', '.join(parts)}{none_text(none)}"

    def veto(self, P: Problem, names: Sequence[str], x: np.ndarray) -> str | None:
        low = [f"{n[3:]} {v:.2g}" for n, v in zip(names, x, strict=True) if v < MIN_SHARE]
        if low:
            return (f"the fitted share of the staircase ({', '.join(low)}) is below {MIN_SHARE:g}: the steps are not "
                    "where the predicted position puts them, so this is not the channel's rounding")
        return None

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = names[0][3:]
        return f"commanded position {a}", P.states[f"pos_{a}"], "unit"
