"""thermal_time: growth that follows time alone, gain * (1 - exp(-(t - t0) / tau)) on the trace's
thermal axis (camsmooth.diagnosis.trace): the competitor of thermal_temperature, so that growth
is put down to the recorded temperatures only when they explain it better than the clock does.
Parameters gain_time (unit) and tau_time (s). Trace only, with temp_<name> columns."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms._trace import NOT_TRACE, grid_start, trace_of
from camsmooth.diagnosis.terms.base import Param, Term, fmt

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class ThermalTime(Term):
    name = "thermal_time"
    needs = "temperature columns (temp_<name>) in a trace: growth against time, beside growth against them"

    def applicable(self, P: Problem) -> str | None:
        tr = trace_of(P)
        if tr is None:
            return NOT_TRACE
        return None if tr.temps else "the trace has no temp_<name> column (the competitor of thermal_temperature)"

    def params(self, P: Problem) -> list[Param]:
        span = float(P.t[-1] - P.t[0])
        a = P.base.thermal_axis
        size = max(float(np.ptp(P.trace.act[a] - P.trace.cmd[a])), 1e-6)
        return [Param("gain_time", -10 * size, 10 * size, 1e-3 * size, "unit", "time"),
                Param("tau_time", 1e-3 * span, 10.0 * span, 1e-3 * span, "s", "time")]

    def write(self, model: Any, names: Sequence[str], x: np.ndarray) -> None:
        g, tau = model.drift
        for n, v in zip(names, x, strict=True):
            g, tau = (float(v), tau) if n == "gain_time" else (g, float(v))
        model.drift = (g, tau)

    def read(self, model: Any, names: Sequence[str]) -> np.ndarray:
        return np.array([model.drift[0] if n == "gain_time" else model.drift[1] for n in names], float)

    def initial(self, P: Problem, model: Any, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        span = float(P.t[-1] - P.t[0])
        j = P.channels.index(f"{P.base.thermal_axis}_act")
        ok = P.valid_fit[:, j]
        grid = []
        for tau in span * np.geomspace(0.01, 5.0, 12):
            c = 1.0 - np.exp(-(P.t[P.fit_idx][ok] - P.t[0]) / tau)
            g = float(np.sum(c * resid[ok, j]) / max(float(np.sum(c * c)), 1e-300))
            grid.append(np.array([g, tau]) if names[0] == "gain_time" else np.array([tau, g]))
        return grid_start(P, self, model, names, grid)

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par = {n: float(v) for n, v in zip(names, x, strict=True)}
        unc = {n: float(s) for n, s in zip(names, sd, strict=True)}
        return par, unc, {n: ("unit" if n == "gain_time" else "s") for n in names}

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        return (f"The axis grows with time, not with the recorded temperatures ({fmt(params.get('gain_time'))} "
                f"± {fmt(unc.get('gain_time'))} unit with time constant {fmt(params.get('tau_time'), 's')})")

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return "elapsed time (s)", P.states["elapsed"], "s"
