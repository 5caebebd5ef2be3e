"""rotary_squareness: the rotary axes tilted from their nominal directions (EB0A, EC0A, EA0B,
EC0B; EA0C, EB0C on a table; METHODS section 3), those of the machine's kind whose axis moves."""

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

    #: the parameters per rotary axis (the machine's kind keeps those it has)
    PER_AXIS = {"A": ("EB0A", "EC0A"), "B": ("EA0B", "EC0B"), "C": ("EA0C", "EB0C")}

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        from camsmooth.machine.model import machine_parameters

        own = set(machine_parameters(P.machine))
        unit, bound, scale = "rad", 0.05, 1e-6
        return [(n, unit, bound, scale, a) for a, names in self.PER_AXIS.items() if P.knots.moves(a)
                for n in names if n in own]

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
