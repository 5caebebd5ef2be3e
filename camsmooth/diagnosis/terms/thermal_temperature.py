"""thermal_temperature: growth that follows the recorded temperatures, not time: on the trace's
thermal axis the actual stands sum_ch gain_ch * L_ch(T_ch - T_ch(0)) off its command, L_ch a
first-order lag of time constant tau_ch (camsmooth.diagnosis.trace). The channels are chosen
greedily (at most ``MAX_CHANNELS``, each lowering the floor-weighted residual by ``MIN_FALL`` of
what is left); the selector then keeps a channel only when its gain is resolved (each channel is
a group). Parameters gain_<channel> (unit/degC) and tau_<channel> (s, optional: 0, growth in step
with the temperature, when not resolvable). Trace only, with temp_<name> columns."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms._trace import NOT_TRACE, trace_of
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem

MAX_CHANNELS = 3
MIN_FALL = 0.05
DIFFERENCES = 40


def _ols(cols: list[np.ndarray], r: np.ndarray) -> tuple[np.ndarray, float]:
    A = np.stack(cols, axis=1)
    g, *_ = np.linalg.lstsq(A, r, rcond=None)
    e = r - A @ g
    return g, float(e @ e)


class ThermalTemperature(Term):
    name = "thermal_temperature"
    needs = "temperature columns (temp_<name>) in a trace"

    def applicable(self, P: Problem) -> str | None:
        tr = trace_of(P)
        if tr is None:
            return NOT_TRACE
        if not tr.temps:
            return "the trace has no temp_<name> column"
        if not any(np.ptp(v) > 0 for v in tr.temps.values()):
            return "no recorded temperature changes"
        if not self._choose(P):
            return (f"no recorded temperature, lagged or not, lowers the residual of "
                    f"{P.base.thermal_axis}_act by {100 * MIN_FALL:g}%")
        return None

    def _taus(self, P: Problem) -> np.ndarray:
        span = float(P.t[-1] - P.t[0])
        return np.r_[0.0, np.geomspace(max(P.dt, span / 1000), 2.0 * span, 10)]

    def _choose(self, P: Problem) -> dict[str, tuple[float, float]]:
        """channel -> (gain, tau) starting values, greedy on the baseline residual of the thermal axis."""
        key = "thermal_temperature:channels"
        if key in P.memo:
            return P.memo[key]
        a = P.base.thermal_axis
        j = P.channels.index(f"{a}_act")
        ok = P.valid_fit[:, j]
        w = P.w_fit[ok, j]
        r = (P.data_fit[:, j] - P.sim_fit.run(P.base)[:, j])[ok] * w
        sim = P.sim_fit
        chosen: dict[str, float] = {}
        cols: list[np.ndarray] = [w]  # a constant offset beside the temperatures
        _, left = _ols(cols, r)
        for _ in range(MAX_CHANNELS):
            best = None
            for ch in P.trace.temps:
                if ch in chosen or np.ptp(P.trace.temps[ch]) == 0:
                    continue
                for tau in self._taus(P):
                    c = sim.temperature(ch, tau)[ok] * w
                    _, rss = _ols(cols + [c], r)
                    if best is None or rss < best[0]:
                        best = (rss, ch, tau, c)
            if best is None or best[0] > (1.0 - MIN_FALL) * left:
                break
            left = best[0]
            chosen[best[1]] = best[2]
            cols.append(best[3])
        out = {}
        if chosen:
            g, _ = _ols(cols, r)
            out = {ch: (float(gi), float(tau)) for (ch, tau), gi in zip(chosen.items(), g[1:], strict=True)}
        P.memo[key] = out
        return out

    def params(self, P: Problem) -> list[Param]:
        span = float(P.t[-1] - P.t[0])
        out = []
        for ch in self._choose(P):
            T = P.trace.temps[ch]
            g = 1.0 / max(float(np.ptp(T)), 1e-6)
            out += [Param(f"gain_{ch}", -1e3 * g, 1e3 * g, 1e-4 * g, "unit/degC", ch),
                    Param(f"tau_{ch}", 0.0, 5.0 * span, 1e-3 * span, "s", ch, optional=True)]
        return out

    def write(self, model: Any, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            kind, ch = n.split("_", 1)
            g, tau = model.thermal.get(ch, (0.0, 0.0))
            model.thermal[ch] = (float(v), tau) if kind == "gain" else (g, max(float(v), 0.0))

    def read(self, model: Any, names: Sequence[str]) -> np.ndarray:
        out = []
        for n in names:
            kind, ch = n.split("_", 1)
            g, tau = model.thermal.get(ch, (0.0, 0.0))
            out.append(g if kind == "gain" else tau)
        return np.array(out, float)

    def initial(self, P: Problem, model: Any, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        start = self._choose(P)
        x = self.read(model, names)
        for i, n in enumerate(names):
            kind, ch = n.split("_", 1)
            if ch in start and not model.thermal.get(ch, (0.0, 0.0))[0]:
                x[i] = start[ch][0] if kind == "gain" else start[ch][1]
        return x

    def veto(self, P: Problem, names: Sequence[str], x: np.ndarray) -> str | None:
        """Two slowly wandering series (a drift and a temperature that happens to trend alike)
        correlate without any relation between them (a spurious regression). Growth driven by a
        temperature follows its changes as well: on ``DIFFERENCES`` non-overlapping changes of the
        baseline residual and of the lagged temperatures, some gain must stand beyond
        ``Options.resolvable_sigma`` standard errors."""
        tr = trace_of(P)
        j = P.channels.index(f"{P.base.thermal_axis}_act")
        val = dict(zip(names, x, strict=True))
        chans = [n[5:] for n in names if n.startswith("gain_")]
        if not chans:
            return None
        ok = P.valid[:, j]
        m = max(1, int(ok.sum()) // DIFFERENCES)
        idx = np.flatnonzero(ok)[::m]
        if len(idx) < len(chans) + 5:
            return None
        dr = np.diff(P.resid0[idx, j])
        dC = np.diff(np.stack([P.sim_all.temperature(ch, float(val.get(f"tau_{ch}", 0.0)))[idx] for ch in chans],
                              axis=1), axis=0)
        g, *_ = np.linalg.lstsq(dC, dr, rcond=None)
        e = dr - dC @ g
        s2 = float(e @ e) / max(len(dr) - len(chans), 1)
        sd = np.sqrt(np.clip(np.diag(np.linalg.pinv(dC.T @ dC)) * s2, 0.0, None))
        z = np.abs(g) / np.maximum(sd, 1e-300)
        if np.all(z < P.options.resolvable_sigma):
            return (f"the growth does not follow the temperatures' changes: on {len(dr)} changes over "
                    f"{m * tr.dt:.3g} s the gains stand {', '.join(f'{v:.2g}' for v in z)} standard errors from "
                    f"zero (at least {P.options.resolvable_sigma:g}); two series that merely trend alike")
        return None

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par = {n: float(v) for n, v in zip(names, x, strict=True)}
        unc = {n: float(s) for n, s in zip(names, sd, strict=True)}
        return par, unc, {n: ("unit/degC" if n.startswith("gain_") else "s") for n in names}

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        parts = [f"{k[5:]}: {fmt(v)} ± {fmt(unc.get(k))} per degC, tau {fmt(params.get('tau_' + k[5:]), 's')}"
                 for k, v in params.items() if k.startswith("gain_")]
        return f"The axis grows with the recorded temperatures ({'; '.join(parts)}{none_text(none)})"

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        ch = names[0].split("_", 1)[1]
        return f"temperature {ch} (degC)", P.trace.temps[ch][P.fit_idx], "degC"
