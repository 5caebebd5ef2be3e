"""Defaults shared across the package, each written once here and imported where used.

Plain Python numbers only (no numpy), so the command line can import them without loading the
numerical stack.
"""

from __future__ import annotations

__all__ = ["DEFAULT_TOLERANCE_MM", "WRITTEN_DECIMALS", "DEFAULT_SAFE_HEIGHT_MM", "PATH_TOLERANCE_SHARE",
           "PARABOLIC_PATH_TOLERANCE_SHARE", "TCP_PARABOLIC_PATH_TOLERANCE_SHARE", "NAIVE_CAM_TOLERANCE_SHARE"]

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
#: bound on how far a blend cuts an XYZ corner, which is the bound where LinuxCNC may join two moves
#: that turn no rotary axis by a blend arc; the tool tip at every servo cycle is held within
#: EXECUTED_TOLERANCE_SHARE (camsmooth.controller) by the block times. Written by the linuxcnc post
#: (camsmooth.post.linuxcnc), used by its planner model.
PATH_TOLERANCE_SHARE: float = 0.6
#: ``G64 P`` over the user's tolerance for a machine-mode program in which every move between two
#: points turns a rotary axis (camsmooth.controller.blend_tolerance). LinuxCNC 2.9 joins such moves
#: by parabolic blends only, where P is no bound on the path but a cap on the blend speed, 2 sqrt(a/2
#: P / cos(theta)) at an XYZ corner of the joints (camsmooth.controller.linuxcnc); the tip is held by
#: the block times, which the planner model checks cycle by cycle, and each row's entry move ends at
#: rest (``G61`` for it; its blend at the 90 deg corner into the row is what P would let go too
#: far). Measured on the planner model, executed / floor over the blade, wave, ridge and dome rows
#: of benchmarks/bench_controller.py on their machines (blocks within 0.96 and servo cycles within
#: 0.98 of the tolerance): 2.0 -> 1.091 / 1.081 / 1.085 / 1.022 (entry blended), 6.0 -> 1.070 /
#: 1.061 / 1.062 / 1.026, 12.0 -> 1.067 / 1.055 / 1.054 / 1.026, 40.0 -> 1.067 / 1.054 / 1.052 /
#: 1.026 (entry stopped); wave and blade on a B/C trunnion: 1.192 / 1.116 at 2.0, 1.118 / 1.083 at
#: 12.0. With the entry blended, 3.0 and 4.0 ran some rows 30-45% later.
PARABOLIC_PATH_TOLERANCE_SHARE: float = 12.0
#: TCP mode's share where every move turns a rotary axis (camsmooth.controller.tcp): its entry move
#: blends into the row (stopped, the entry's acceleration along the tool axis, turned into the
#: joints by the table, takes a linear joint past its amax), so P stays where the block times can
#: hold that blend. On LinuxCNC (bench_controller.py --mode tcp, the dome on its A/C table, wave,
#: blade, ridge and teapot on a B/C one) 2.0 runs the rows in 1.02-1.09 of the TCP floor against
#: 1.10-1.29 at 0.6, with the blends held block by block.
TCP_PARABOLIC_PATH_TOLERANCE_SHARE: float = 2.0
#: The share of the user's tolerance LinuxCNC's naive-CAM detector gets (``G64 Q``): it joins
#: consecutive XYZ-only moves that lie within Q of a line, which the planner model does not model;
#: kept below the tolerance (without Q, LinuxCNC takes Q = P).
NAIVE_CAM_TOLERANCE_SHARE: float = 0.6
