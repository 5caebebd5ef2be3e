"""Where camsmooth's G-code lived: the writer, the dialects and the reader of camsmooth's own
programs are in camsmooth.post now (one module per dialect, camsmooth.post.DIALECTS; the writer
camsmooth.post.writer over camsmooth.post.model.PostProgram; the reader camsmooth.post.own), and
``write_gcode`` (a smoothing result written in the machine's dialect) in
camsmooth.smoothing.posting. These names stay importable from here for existing callers.
"""

from __future__ import annotations

from typing import Any

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM
from camsmooth.post import DIALECTS as _ALL
from camsmooth.post.model import tip_path_lengths
from camsmooth.post.own import read_gcode
from camsmooth.post.writer import Words, format_blocks

__all__ = ["read_gcode", "tip_path_lengths", "format_blocks", "DEFAULT_SAFE_HEIGHT_MM", "DIALECTS",
           "Words"]

#: the dialects camsmooth writes whole programs in -> their writer's words (camsmooth.post.writer.Words)
DIALECTS: dict[str, Words] = {name: e.words for name, e in _ALL.items() if e.own}


def __getattr__(name: str) -> Any:
    """``write_gcode`` from camsmooth.smoothing.posting, imported when asked for (this io module
    does not import the smoothing)."""
    if name == "write_gcode":
        from camsmooth.smoothing.posting import write_gcode

        return write_gcode
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
