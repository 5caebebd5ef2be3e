"""backlash_load: a lost motion that switches with the sign of the recorded load (a held axis
pushed one way then the other, a gravity load that changes side), not with the direction of
motion: the actual stands -(b/2) sign(load) off its command (camsmooth.diagnosis.trace).
Parameters bl_<axis> (unit), reported as backlash_load_<axis>. Trace only, with <AX>_load."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms._trace import NOT_TRACE, trace_of
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class BacklashLoad(Term):
    name = "backlash_load"
    needs = "a load column whose sign changes (<AX>_load)"

    def _axes(self, P: Problem) -> list[str]:
        tr = trace_of(P)
        out = []
        for a in tr.axes:
            ld = tr.extra[a].get("load")
            if ld is not None and np.any(ld > 0) and np.any(ld < 0):
                out.append(a)
        return out

    def applicable(self, P: Problem) -> str | None:
        if trace_of(P) is None:
            return NOT_TRACE
        return None if self._axes(P) else "no <AX>_load column changes sign"

    def params(self, P: Problem) -> list[Param]:
        out = []
        for a in self._axes(P):
            span = max(float(np.ptp(P.trace.act[a])), 1e-3)
            out.append(Param(f"bl_{a}", -span, span, 1e-3 * span, "unit", a))
        return out

    def write(self, model: Any, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            model.backlash_load[n[3:]] = float(v)

    def read(self, model: Any, names: Sequence[str]) -> np.ndarray:
        return np.array([model.backlash_load.get(n[3:], 0.0) for n in names])

    def jacobian(self, P: Problem, model: Any, names: Sequence[str]) -> np.ndarray | None:
        rows = []
        for n in names:
            a = n[3:]
            d = np.zeros_like(P.data_fit)
            d[:, P.channels.index(f"{a}_act")] = 0.5 * P.sim_fit.load_sign[a]
            rows.append((d * P.w_fit)[P.valid_fit])
        return np.stack(rows)

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par = {f"backlash_load_{n[3:]}": float(v) for n, v in zip(names, x, strict=True)}
        unc = {f"backlash_load_{n[3:]}": float(s) for n, s in zip(names, sd, strict=True)}
        return par, unc, {k: "unit" for k in par}

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        parts = [f"{k[14:]} {fmt(v)} ± {fmt(unc.get(k))}" for k, v in params.items()]
        return f"The axes shift when the load changes sign (load backlash {', '.join(parts)}{none_text(none)})"

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = names[0][3:]
        return f"sign of the load on {a}", P.sim_fit.load_sign[a], "1"
