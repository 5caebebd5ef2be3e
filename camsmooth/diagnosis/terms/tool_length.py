"""tool_length: the tool longer than nominal by EZ0T (mm), along the tool axis."""

from __future__ import annotations

from camsmooth.diagnosis.recordings import TIP_CHANNELS
from camsmooth.diagnosis.terms.base import Geometric, rotary_state


class ToolLength(Geometric):
    name = "tool_length"
    channels_seen = TIP_CHANNELS
    what = "The tool length is off"

    def candidates_for(self, P):
        return [("EZ0T", "mm", 5.0, 1e-3, "EZ0T")]

    def state(self, P, names):
        return rotary_state(P)
