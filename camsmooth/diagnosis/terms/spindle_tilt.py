"""spindle_tilt: the spindle axis tilted about the pivot (EA0S, EB0S)."""

from __future__ import annotations

from camsmooth.diagnosis.terms.base import Geometric, rotary_state


class SpindleTilt(Geometric):
    name = "spindle_tilt"
    what = "The spindle axis is tilted"

    def candidates_for(self, P):
        return [("EA0S", "rad", 0.05, 1e-6, "EA0S"), ("EB0S", "rad", 0.05, 1e-6, "EB0S")]

    def state(self, P, names):
        return rotary_state(P)
