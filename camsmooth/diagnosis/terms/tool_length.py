"""tool_length: the tool longer than nominal by EZ0T (mm), along the tool axis."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import TIP_CHANNELS
from camsmooth.diagnosis.terms.base import Geometric, rotary_state

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class ToolLength(Geometric):
    name = "tool_length"
    channels_seen = TIP_CHANNELS
    what = "The tool length is off"

    def candidates_for(self, P: Problem) -> list[tuple[Any, ...]]:
        return [("EZ0T", "mm", 5.0, 1e-3, "EZ0T")]

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return rotary_state(P)
