"""Geometric errors of the linear axes (ISO 230-1; camsmooth.machine.model for the definitions):

* linear_positioning: E_AA(q) = EAA q + EAA2 q^2 + EAA3 q^3 along each moving axis A (scale
  and smooth pitch error; seen by an external measurement of the axis and by the tool tip);
* linear_straightness: E_BA(q) = EBA2 q^2 + EBA3 q^3, axis A moving off its line along B (tool
  tip only);
* linear_squareness: EC0Y, EB0Z, EA0Z, the Y and Z directions out of square with X (tool tip).

Reversal error at direction changes stays ``backlash``. The higher-order (pitch, cubic) parts
are dropped on their own when the recording does not resolve them."""

from __future__ import annotations

from camsmooth.diagnosis.recordings import LINEAR_AXES, TIP_CHANNELS
from camsmooth.diagnosis.terms.base import Geometric, travel


def _pos_state(P, names):
    a = next((n[1] for n in names if n[1] in LINEAR_AXES), "X")
    return f"commanded position {a} (mm)", P.states[f"pos_{a}"], "mm"


class LinearPositioning(Geometric):
    name = "linear_positioning"
    channels_seen = ("X_act", "Y_act", "Z_act") + TIP_CHANNELS
    what = "The linear axes position off their scale"

    def candidates_for(self, P):
        out = []
        tip = any(c in P.channels for c in TIP_CHANNELS)
        for a in LINEAR_AXES:
            if not P.knots.moves(a) or not (tip or f"{a}_act" in P.channels):
                continue
            R = travel(P, a)
            out += [(f"E{a}{a}", "1", 0.05, 1e-3 / R, a), (f"E{a}{a}2", "1/mm", 0.05 / R, 1e-3 / R ** 2, a, True),
                    (f"E{a}{a}3", "1/mm2", 0.05 / R ** 2, 1e-3 / R ** 3, a, True)]
        return out

    def sentence(self, params, unc, none):
        parts = []
        for k, v in params.items():
            if len(k) == 3:
                parts.append(f"{k} {v * 1e3:.3g} ± {(unc.get(k) or 0.0) * 1e3:.2g} um per mm of travel")
            else:
                parts.append(f"{k} = {v:.3g} {'1/mm' if k.endswith('2') else '1/mm^2'} (pitch)")
        return f"{self.what} ({', '.join(parts)}{'; none measurable on ' + ', '.join(none) if none else ''})"

    def state(self, P, names):
        return _pos_state(P, names)


class LinearStraightness(Geometric):
    name = "linear_straightness"
    channels_seen = TIP_CHANNELS
    what = "The linear axes move off their straight lines"

    def candidates_for(self, P):
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

    def state(self, P, names):
        a = names[0][2]
        return f"commanded position {a} (mm)", P.states[f"pos_{a}"], "mm"


class LinearSquareness(Geometric):
    name = "linear_squareness"
    channels_seen = TIP_CHANNELS
    what = "The linear axes are out of square"

    def candidates_for(self, P):
        out = []
        if P.knots.moves("Y"):
            out.append(("EC0Y", "rad", 0.01, 1e-6 * 100 / travel(P, "Y"), "EC0Y"))
        if P.knots.moves("Z"):
            s = 1e-6 * 100 / travel(P, "Z")
            out += [("EB0Z", "rad", 0.01, s, "EB0Z"), ("EA0Z", "rad", 0.01, s, "EA0Z")]
        return out

    def state(self, P, names):
        a = "Y" if names[0] == "EC0Y" else "Z"
        return f"commanded position {a} (mm)", P.states[f"pos_{a}"], "mm"
