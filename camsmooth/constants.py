"""Defaults shared across the package, each written once here and imported where used.

Plain Python numbers only (no numpy), so the command line can import them without loading the
numerical stack.
"""

from __future__ import annotations

__all__ = ["DEFAULT_TOLERANCE_MM", "WRITTEN_DECIMALS", "DEFAULT_SAFE_HEIGHT_MM", "PATH_TOLERANCE_SHARE"]

#: The part's allowed deviation (mm) when the user gives none (``--tolerance``; ``smooth``,
#: ``analyze_program``): a finishing tolerance. It decides every clearance question: a pose whose
#: signed clearance delta (mm, negative = gouge) is below -tolerance interferes
#: (camsmooth.smoothing.result.interferes), a lift along the normal beyond it is reported.
DEFAULT_TOLERANCE_MM: float = 0.005

#: Decimals camsmooth writes positions with in G-code (mm for X Y Z, degrees for the rotary axes):
#: the "as written" rounding (camsmooth.post.model.written_joints) every figure is judged on.
WRITTEN_DECIMALS: int = 4

#: Default retract height between rows, along the tool axis (mm; camsmooth.post.writer).
DEFAULT_SAFE_HEIGHT_MM: float = 10.0

#: Share of the user's tolerance the controller's own blend tolerance gets (LinuxCNC ``G64 P``): its
#: bound on how far a blend cuts an XYZ corner, which holds the corner of a row's entry move; the
#: tool tip at every servo cycle is held within EXECUTED_TOLERANCE_SHARE (camsmooth.controller) by
#: the block times. Written by the linuxcnc post (camsmooth.post.linuxcnc), used by its planner model.
PATH_TOLERANCE_SHARE: float = 0.6
