"""transport_delay: one axis follows its command after a pure delay of its own, y_a(t) = model_a(t - d_a)
(camsmooth.diagnosis.trace): a drive's or a bus's dead time on that axis. Beside time_offset (one
delay of every axis: the recording's clock) and servo_lag (a lag rounds the velocity corners, a
delay only shifts them). Parameters delay_<axis> (s, >= 0: a delay is causal), tried only where a
trace has two or more moving axes (on one axis a delay of its own is the clock offset). A delay
below ``Options.min_offset_periods`` of the sample period is not resolvable. Trace only."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms._trace import NOT_TRACE, moving_axes, trace_of
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class TransportDelay(Term):
    name = "transport_delay"
    needs = "two or more moving axes in a controller trace"

    def applicable(self, P: Problem) -> str | None:
        if trace_of(P) is None:
            return NOT_TRACE
        if len(moving_axes(P)) < 2:
            return "fewer than two moving axes: one axis's own delay is the clock offset (time_offset)"
        return None

    def params(self, P: Problem) -> list[Param]:
        b = min(0.5, 0.25 * float(P.t[-1] - P.t[0]))
        return [Param(f"delay_{a}", 0.0, b, 1e-3, "s", a) for a in moving_axes(P)]

    def write(self, model: Any, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            model.delay[n[6:]] = float(v)

    def read(self, model: Any, names: Sequence[str]) -> np.ndarray:
        return np.array([model.delay.get(n[6:], 0.0) for n in names])

    def initial(self, P: Problem, model: Any, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        """Per axis the delay that best explains the residual as -d v (v the commanded velocity)."""
        x = self.read(model, names)
        hi = {p.name: p.hi for p in self.params(P)}
        for i, n in enumerate(names):
            a = n[6:]
            j = P.channels.index(f"{a}_act")
            ok = P.valid_fit[:, j]
            v = P.states[f"v_{a}"][ok]
            den = float(np.sum(v * v))
            d = x[i] - (float(np.sum(resid[ok, j] * v)) / den if den > 0 else 0.0)
            x[i] = float(np.clip(d, 1e-6 * hi[n], hi[n]))
        return x

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        return ({n: float(v) for n, v in zip(names, x, strict=True)},
                {n: float(s) for n, s in zip(names, sd, strict=True)}, {n: "s" for n in names})

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        parts = [f"{n[6:]} {fmt(v * 1e3)} ± {fmt((unc.get(n) or 0.0) * 1e3)} ms" for n, v in params.items()]
        return f"An axis follows its command after a transport delay of its own ({', '.join(parts)}{none_text(none)})"

    def unresolvable(self, P: Problem, names: Sequence[str], x: np.ndarray, sd: np.ndarray) -> str | None:
        limit = P.options.min_offset_periods * P.dt
        if np.all(np.abs(x) < limit):
            return (f"every fitted delay is below {P.options.min_offset_periods:g} of the sample period "
                    f"({P.dt * 1e3:.3g} ms): not resolvable on this recording")
        return None

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = max(names, key=lambda n: np.std(P.states[f"v_{n[6:]}"]))[6:]
        return f"commanded velocity {a}", P.states[f"v_{a}"], "unit/s"
