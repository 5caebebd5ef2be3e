"""rotary_squareness: the rotary axes tilted from their nominal directions (EB0A, EC0A, EA0B,
EC0B; EA0C, EB0C on a table; a chain's own; METHODS section 3), those of the machine
(camsmooth.machine.model.rotary_errors) whose axis moves."""

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
        from camsmooth.machine.model import rotary_errors

        unit, bound, scale = "rad", 0.05, 1e-6
        return [(n, unit, bound, scale, a) for a, names in rotary_errors(P.machine, "orientation").items()
                if P.knots.moves(a) for n in names]

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
