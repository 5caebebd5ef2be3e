"""servo_lag: each axis follows its command through a first-order lag, tau dy/dt = u - y with
tau = 1/Kv (METHODS section 6: lag = v / Kv in steady motion, Kv typically 15-130 1/s).
Parameters tau_<axis> (s), reported as Kv_<axis> (1/s); an axis whose lag is not measurable is
reported as such, never with a gain at its bound."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import AXES, ROTARY_AXES
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text
from camsmooth.machine.model import ErrorModel

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class ServoLag(Term):
    name = "servo_lag"
    needs = "moving axes"

    def _axes(self, P):
        return [a for a in getattr(P, "axes", AXES) if P.knots.moves(a)]  # a trace names its own axes

    def applicable(self, P: Problem) -> str | None:
        return None if self._axes(P) else "no axis moves in the program"

    def params(self, P: Problem) -> list[Param]:
        return [Param(f"tau_{a}", 0.0, 2.0, 1e-3, "s", a) for a in self._axes(P)]

    def write(self, model: ErrorModel, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            model.tau[n[4:]] = float(v)

    def read(self, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
        return np.array([model.tau.get(n[4:], 0.0) for n in names])

    def initial(self, P: Problem, model: ErrorModel, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        x = self.read(model, names)
        for i, n in enumerate(names):
            a = n[4:]
            c = f"{a}_act"
            if c in P.channels and x[i] == 0.0:
                j = P.channels.index(c)
                v = P.states[f"v_{a}"]
                ok = P.valid_fit[:, j]
                den = float(np.sum(v[ok] ** 2))
                x[i] = float(np.clip(-np.sum(resid[ok, j] * v[ok]) / den, 0.0, 1.0)) if den > 0 else 0.01
            elif x[i] == 0.0:
                x[i] = 0.01
        return x

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            key = f"Kv_{n[4:]}"
            par[key] = float(1.0 / v) if v > 0 else None
            unc[key] = float(s / v ** 2) if v > 0 and np.isfinite(s) else None
            unit[key] = "1/s"
        return par, unc, unit

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        ax = [k[3:] for k, v in params.items() if v is not None]
        kv = ", ".join(f"{fmt(params[f'Kv_{a}'])} ± {fmt(unc.get(f'Kv_{a}'))}" for a in ax)
        verb = "lags its" if len(ax) == 1 else "lag their"
        return f"{', '.join(ax)} {verb} command by v/Kv with Kv = {kv} 1/s{none_text(none)}"

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = max(names, key=lambda n: np.std(P.states[f"v_{n[4:]}"]))[4:]
        unit = "deg/s" if a in ROTARY_AXES else "mm/s"
        f = np.degrees(1.0) if a in ROTARY_AXES else 1.0
        return f"commanded velocity {a} ({unit})", P.states[f"v_{a}"] * f, unit
