"""Geometric errors of the linear axes (ISO 230-1; camsmooth.machine.model for the definitions):

* linear_positioning: E_AA(q) = EAA q + EAA2 q^2 + EAA3 q^3 along each moving axis A (scale
  and smooth pitch error; seen by an external measurement of the axis and by the tool tip);
* linear_straightness: E_BA(q) = EBA2 q^2 + EBA3 q^3, axis A moving off its line along B (tool
  tip only);
* linear_squareness: EC0Y, EB0Z, EA0Z, the Y and Z directions out of square with X (tool tip).

Reversal error at direction changes stays ``backlash``. The higher-order (pitch, cubic) parts
are dropped on their own when the recording does not resolve them."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import LINEAR_AXES, TIP_CHANNELS
from camsmooth.diagnosis.terms.base import Geometric, travel
from camsmooth.machine.model import POSITIONING, STRAIGHTNESS, ErrorModel

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


def _directions(model) -> dict[str, np.ndarray]:
    """The real directions of X, Y, Z (camsmooth.machine.model: squareness)."""
    g = model.get
    c, a, b = g("EC0Y"), g("EA0Z"), g("EB0Z")
    return {"X": np.array([1.0, 0.0, 0.0]), "Y": np.array([-math.sin(c), math.cos(c), 0.0]),
            "Z": np.array([math.sin(b), -math.sin(a) * math.cos(b), math.cos(a) * math.cos(b)])}


def _power(y, k):
    return y if k == 1 else y ** k


def linear_jacobian(P: Problem, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
    """Exact columns of the floor-weighted residual for the linear-axis parameters: the carriages
    sit at the base of the chain, so a parameter moves the tip along a fixed direction by a
    polynomial of the axis position: d tip / d EAAk = w_A y^k, d tip_B / d EBAk = y^k,
    d tip / d EC0Y = (y + E_YY(y)) d w_Y / d EC0Y (likewise for Z); an external axis channel
    moves by y^k (y the axis position after lag and backlash, w the real axis direction)."""
    sim = P.sim_fit
    n, C = P.data_fit.shape
    w = _directions(model)
    y = {a: np.broadcast_to(np.asarray(sim.axis(a, model), float), (n,)) for a in LINEAR_AXES}
    tip = [P.channels.index(c) if c in P.channels else None for c in TIP_CHANNELS]
    rows = []
    for name in names:
        D = np.zeros((n, C))
        if name in POSITIONING:
            a, k = POSITIONING[name]
            col = _power(y[a], k)
            if f"{a}_act" in P.channels:
                D[:, P.channels.index(f"{a}_act")] = col
            for i, j in enumerate(tip):
                if j is not None:
                    D[:, j] = w[a][i] * col
        elif name in STRAIGHTNESS:
            a, b, k = STRAIGHTNESS[name]
            j = tip[LINEAR_AXES.index(b)]
            if j is not None:
                D[:, j] = _power(y[a], k)
        else:
            g = model.get
            if name == "EC0Y":
                a, c = "Y", g("EC0Y")
                dw = np.array([-math.cos(c), -math.sin(c), 0.0])
            else:
                a, ea, eb = "Z", g("EA0Z"), g("EB0Z")
                dw = (np.array([0.0, -math.cos(ea) * math.cos(eb), -math.sin(ea) * math.cos(eb)]) if name == "EA0Z"
                      else np.array([math.cos(eb), math.sin(ea) * math.sin(eb), -math.cos(ea) * math.sin(eb)]))
            q = y[a] + sum(model.get(p) * _power(y[a], k) for p, (b, k) in POSITIONING.items() if b == a)
            for i, j in enumerate(tip):
                if j is not None:
                    D[:, j] = dw[i] * q
        rows.append(-(D * P.w_fit)[P.valid_fit])
    return np.stack(rows)


def _pos_state(P, names):
    a = next((n[1] for n in names if n[1] in LINEAR_AXES), "X")
    return f"commanded position {a} (mm)", P.states[f"pos_{a}"], "mm"


class LinearPositioning(Geometric):
    def jacobian(self, P: Problem, model: ErrorModel, names: Sequence[str]) -> np.ndarray | None:
        return linear_jacobian(P, model, names)

    name = "linear_positioning"
    channels_seen = ("X_act", "Y_act", "Z_act") + TIP_CHANNELS
    what = "The linear axes position off their scale"

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        out = []
        tip = any(c in P.channels for c in TIP_CHANNELS)
        for a in LINEAR_AXES:
            if not P.knots.moves(a) or not (tip or f"{a}_act" in P.channels):
                continue
            R = travel(P, a)
            out += [(f"E{a}{a}", "1", 0.05, 1e-3 / R, a), (f"E{a}{a}2", "1/mm", 0.05 / R, 1e-3 / R ** 2, a, True),
                    (f"E{a}{a}3", "1/mm2", 0.05 / R ** 2, 1e-3 / R ** 3, a, True)]
        return out

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        parts = []
        for k, v in params.items():
            if len(k) == 3:
                parts.append(f"{k} {v * 1e3:.3g} ± {(unc.get(k) or 0.0) * 1e3:.2g} um per mm of travel")
            else:
                parts.append(f"{k} = {v:.3g} {'1/mm' if k.endswith('2') else '1/mm^2'} (pitch)")
        return f"{self.what} ({', '.join(parts)}{'; none measurable on ' + ', '.join(none) if none else ''})"

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return _pos_state(P, names)


class LinearStraightness(Geometric):
    def jacobian(self, P: Problem, model: ErrorModel, names: Sequence[str]) -> np.ndarray | None:
        return linear_jacobian(P, model, names)

    name = "linear_straightness"
    channels_seen = TIP_CHANNELS
    what = "The linear axes move off their straight lines"

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        out = []
        for a in LINEAR_AXES:
            if not P.knots.moves(a):
                continue
            R = travel(P, a)
            for b in LINEAR_AXES:
                if b != a and f"tip_{b.lower()}" in P.channels:
                    out += [(f"E{b}{a}2", "1/mm", 0.05 / R, 1e-3 / R ** 2, f"{a} in {b}"),
                            (f"E{b}{a}3", "1/mm2", 0.05 / R ** 2, 1e-3 / R ** 3, f"{a} in {b}", True)]
        return out

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = names[0][2]
        return f"commanded position {a} (mm)", P.states[f"pos_{a}"], "mm"


class LinearSquareness(Geometric):
    def jacobian(self, P: Problem, model: ErrorModel, names: Sequence[str]) -> np.ndarray | None:
        return linear_jacobian(P, model, names)

    name = "linear_squareness"
    channels_seen = TIP_CHANNELS
    what = "The linear axes are out of square"

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        out = []
        if P.knots.moves("Y"):
            out.append(("EC0Y", "rad", 0.01, 1e-6 * 100 / travel(P, "Y"), "EC0Y"))
        if P.knots.moves("Z"):
            s = 1e-6 * 100 / travel(P, "Z")
            out += [("EB0Z", "rad", 0.01, s, "EB0Z"), ("EA0Z", "rad", 0.01, s, "EA0Z")]
        return out

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        a = "Y" if names[0] == "EC0Y" else "Z"
        return f"commanded position {a} (mm)", P.states[f"pos_{a}"], "mm"
