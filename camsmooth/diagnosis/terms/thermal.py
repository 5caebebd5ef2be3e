"""Thermal growth, first-order in the spindle speed (METHODS section 5; the model's one
integrator), in two frames (camsmooth.machine.model):

* thermal_drift: the spindle frame, moving with the head: tip displacement dx, dy, dz in the
  tool frame and the spindle tilts exz, eyz;
* thermal_machine: the machine frame (axes, column, ram): tip displacement mx, my, mz along the
  workpiece axes, the same at every head pose.

With rotary motion in the program the two predict different tips; without it the tool frame is
the machine frame and they are reported as 'cannot tell apart'. Each element has a gain (per 1000
rpm) and a time constant; only elements with a clear signal in the residual are fitted."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import DIR_CHANNELS, TIP_CHANNELS
from camsmooth.diagnosis.terms.base import Param, Term, fmt, none_text
from camsmooth.machine import fitting
from camsmooth.machine.model import ErrorModel

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class ThermalDrift(Term):
    name = "thermal_drift"
    frame = "spindle"
    tip_elements = ("dx", "dy", "dz")
    tilt_elements = ("exz", "eyz")

    def elements(self, P: Problem) -> list[str]:
        out = []
        if any(c in P.channels for c in TIP_CHANNELS):
            out += list(self.tip_elements)
        if any(c in P.channels for c in DIR_CHANNELS[:2]):
            out += list(self.tilt_elements)
        return out

    def applicable(self, P: Problem) -> str | None:
        if not self.elements(P):
            return "needs measured tool-tip or tool-axis channels"
        if P.knots.S is None or not np.any(P.knots.S > 0):
            return "the spindle does not turn in the program"
        return None

    def chosen(self, P: Problem) -> list[str]:
        """The elements fitted (set by the selector through ``select_elements``)."""
        key = f"thermal:{self.name}"
        if key not in P.memo:
            P.memo[key] = self.select_elements(P, P.base)
        return P.memo[key]

    def params(self, P: Problem) -> list[Param]:
        span = float(P.t[-1] - P.t[0])
        out = []
        for el in self.chosen(P):
            ang = el.startswith("e")
            out.append(Param(f"gain_{el}", -1.0 if ang else -100.0, 1.0 if ang else 100.0, 1e-6 if ang else 1e-3,
                             "rad/1000rpm" if ang else "mm/1000rpm", el))
            # a time constant far below the record cannot be told from a constant offset
            out.append(Param(f"tau_{el}", max(1e-3, 2 * P.dt, 0.05 * span), 20.0 * span, 1.0, "s", el))
        return out

    def _tau_grid(self, P):
        span = float(P.t[-1] - P.t[0])
        return [span * f for f in (0.06, 0.1, 0.2, 0.4, 0.8, 1.6, 3.2)]

    def _element_fit(self, P, el, resid, base):
        """Best (gain, tau, fraction of the residual's sum of squares removed, z) for one element
        alone, by linear regression of the residual on its unit response over a tau grid."""
        base = base.copy()
        base.thermal.pop(el, None)
        s0 = P.sim_fit.run(base)
        r = (resid * P.w_fit)[P.valid_fit]
        rss0 = fitting.dot(r, r)
        best = (0.0, 1.0, 0.0, 0.0)
        for tau in self._tau_grid(P):
            trial = base.copy()
            g0 = 1.0 if not el.startswith("e") else 1e-3
            trial.thermal[el] = {"gain": g0, "tau": tau}
            col = ((P.sim_fit.run(trial) - s0) * P.w_fit)[P.valid_fit] / g0
            den = fitting.dot(col, col)
            if den <= 0:
                continue
            g = fitting.dot(col, r) / den
            drop = g * g * den / max(rss0, 1e-300)
            sd = math.sqrt(max(rss0 - g * g * den, 0.0) / max(len(r) - 1, 1) / den)
            if drop > best[2]:
                best = (g, tau, drop, abs(g) / max(sd, 1e-300))
        return best

    def select_elements(self, P: Problem, base: ErrorModel) -> list[str]:
        """The elements with a clear signal in the residual left by ``base`` (at least the
        strongest one, so the candidate can be scored); records their starting values."""
        resid = P.data_fit - P.sim_fit.run(base)
        fits = {el: self._element_fit(P, el, resid, base) for el in self.elements(P)}
        P.memo[f"thermal_init:{self.name}"] = {el: (f[0], f[1]) for el, f in fits.items()}
        strong = [el for el, f in fits.items() if f[2] > 1e-3 and f[3] > 8.0]
        if not strong and fits:
            strong = [max(fits, key=lambda e: fits[e][2])]
        return strong

    def write(self, model: ErrorModel, names: Sequence[str], x: np.ndarray) -> None:
        vals = dict(zip(names, x, strict=True))
        for n in names:
            if n.startswith("gain_"):
                el = n[5:]
                model.thermal[el] = {"gain": float(vals[n]), "tau": float(vals[f"tau_{el}"])}

    def read(self, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
        out = []
        for n in names:
            el = n.split("_", 1)[1]
            d = model.thermal.get(el, {"gain": 0.0, "tau": math.nan})
            out.append(d["gain"] if n.startswith("gain_") else d["tau"])
        return np.array(out, float)

    def initial(self, P: Problem, model: ErrorModel, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        x = self.read(model, names)
        init = P.memo.get(f"thermal_init:{self.name}", {})
        for i, n in enumerate(names):
            el = n.split("_", 1)[1]
            g, tau = init.get(el, (0.0, float(P.t[-1] - P.t[0]) * 0.2))
            if n.startswith("gain_") and x[i] == 0.0:
                x[i] = g
            if n.startswith("tau_") and not np.isfinite(x[i]):
                x[i] = tau
        byname = {p.name: p for p in self.params(P)}
        return np.clip(x, [byname[n].lo for n in names], [byname[n].hi for n in names])

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            el = n.split("_", 1)[1]
            key = f"{el}_{n.split('_', 1)[0]}"
            par[key], unc[key] = float(v), float(s)
            unit[key] = "s" if n.startswith("tau_") else ("rad per 1000 rpm" if el.startswith("e")
                                                         else "mm per 1000 rpm")
        return par, unc, unit

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        els = sorted({k.rsplit("_", 1)[0] for k in params})
        parts = [f"{e} gain {fmt(params[e + '_gain'])} per 1000 rpm, tau {fmt(params[e + '_tau'], 's')}"
                 for e in els]
        where = ("The spindle grows thermally" if self.frame == "spindle"
                 else "The machine's axes and column grow thermally, in the machine frame")
        return f"{where} ({'; '.join(parts)}{none_text(none)})"

    def veto(self, P: Problem, names: Sequence[str], x: np.ndarray) -> str | None:
        lo = {p.name: p.lo for p in self.params(P)}
        fast = [n[4:] for n, v in zip(names, x, strict=True) if n.startswith("tau_") and v <= 1.01 * lo[n]]
        if fast:
            bound = lo["tau_" + fast[0]]
            return (f"the fitted time constant of {', '.join(fast)} sits on its lower bound ({bound:.3g} s, "
                    "5% of the record): a step, not a drift; it cannot be told from a constant offset")
        return None


class ThermalMachine(ThermalDrift):
    name = "thermal_machine"
    frame = "machine"
    tip_elements = ("mx", "my", "mz")
    tilt_elements = ()
