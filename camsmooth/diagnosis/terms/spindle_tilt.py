"""spindle_tilt: the spindle axis tilted about the pivot (EA0S, EB0S)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms.base import Geometric, rotary_state

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class SpindleTilt(Geometric):
    name = "spindle_tilt"
    what = "The spindle axis is tilted"

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        return [("EA0S", "rad", 0.05, 1e-6, "EA0S"), ("EB0S", "rad", 0.05, 1e-6, "EB0S")]

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
