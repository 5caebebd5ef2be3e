"""rotary_location: the A and B axis lines displaced from their nominal places (EY0A, EZ0A,
EX0B, EZ0B; camsmooth.machine.model)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import TIP_CHANNELS
from camsmooth.diagnosis.terms.base import Geometric, rotary_state

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class RotaryLocation(Geometric):
    name = "rotary_location"
    channels_seen = TIP_CHANNELS
    what = "The rotary axes are displaced from their nominal lines"

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        out = []
        if P.knots.moves("A"):
            out += [("EY0A", "mm", 5.0, 1e-3, "A"), ("EZ0A", "mm", 5.0, 1e-3, "A")]
        if P.knots.moves("B"):
            out += [("EX0B", "mm", 5.0, 1e-3, "B"), ("EZ0B", "mm", 5.0, 1e-3, "B")]
        return out

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
