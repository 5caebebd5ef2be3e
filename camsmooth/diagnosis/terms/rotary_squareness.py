"""rotary_squareness: the A and B axes tilted from their nominal directions (EB0A, EC0A, EA0B,
EC0B; METHODS section 3)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.terms.base import Geometric, rotary_state

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class RotarySquareness(Geometric):
    name = "rotary_squareness"
    what = "The rotary axes are tilted from their nominal directions"

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        out = []
        if P.knots.moves("A"):
            out += [("EB0A", "rad", 0.05, 1e-6, "A"), ("EC0A", "rad", 0.05, 1e-6, "A")]
        if P.knots.moves("B"):
            out += [("EA0B", "rad", 0.05, 1e-6, "B"), ("EC0B", "rad", 0.05, 1e-6, "B")]
        return out

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
