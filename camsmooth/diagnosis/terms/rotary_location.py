"""rotary_location: the rotary axis lines displaced from their nominal places (EY0A, EZ0A, EX0B,
EZ0B on any kind that has them; EX0C, EY0C on a table; a chain's own), those of the machine
(camsmooth.machine.model.rotary_errors) whose axis moves."""

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
        from camsmooth.machine.model import rotary_errors

        unit, bound, scale = "mm", 5.0, 1e-3
        return [(n, unit, bound, scale, a) for a, names in rotary_errors(P.machine, "location").items()
                if P.knots.moves(a) for n in names]

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
