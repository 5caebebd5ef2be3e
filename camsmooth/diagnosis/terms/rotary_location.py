"""rotary_location: the rotary axis lines displaced from their nominal places (EY0A, EZ0A, EX0B,
EZ0B on any kind that has them; EX0C, EY0C on a table; camsmooth.machine.model), those of the
machine (``machine_parameters``) whose axis moves."""

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

    #: the parameters per rotary axis (the machine's kind keeps those it has)
    PER_AXIS = {"A": ("EY0A", "EZ0A"), "B": ("EX0B", "EZ0B"), "C": ("EX0C", "EY0C")}

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        from camsmooth.machine.model import machine_parameters

        own = set(machine_parameters(P.machine))
        unit, bound, scale = "mm", 5.0, 1e-3
        return [(n, unit, bound, scale, a) for a, names in self.PER_AXIS.items() if P.knots.moves(a)
                for n in names if n in own]

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
