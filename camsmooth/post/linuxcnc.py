"""LinuxCNC: its programs are ISO G-code read by camsmooth.post.iso (``read_iso`` with the
'linuxcnc' dialect: ``#<name>`` parameters, o-words, M428/M429); this module holds what is its
own when camsmooth writes for it.

- Program start ``G21 G90 G17 G40 G49``, inverse time G93, home ``G53 G00 Z0`` (LinuxCNC G-code
  reference, "G53 Move in Machine Coordinates").
- Path blending ``G64 P<s T> Q<q T>`` (T the user's tolerance; P the blending tolerance, s =
  camsmooth.constants.PATH_TOLERANCE_SHARE: in LinuxCNC 2.9 a cap on the speed of its XYZ corner
  blends; the block times of camsmooth.controller.blocks hold the tool tip of every servo cycle of
  the planner model within EXECUTED_TOLERANCE_SHARE of T; Q the naive-CAM detector's, q =
  NAIVE_CAM_TOLERANCE_SHARE, below T). Where the controller plan stops each row's entry move
  (``ControllerPlan.entry_stop``: P over T), ``G61`` (exact path) before the entry move and the
  ``G64`` line again after it, so that the move ends at rest.
- Tool-centre-point: LinuxCNC has no standard G-code for it; its shipped five-axis configurations
  (``xyzac-trt.ini``, ``xyzbc-trt.ini``) remap ``M428`` to kinematics type 1 (the trt kinematics)
  and ``M429`` to type 0 (identity), so TCP on is ``M428`` and off ``M429`` (``[post] tcp_on /
  tcp_off`` for another configuration).
- The rotary sense (``Machine.linuxcnc_sense``): the trt kinematics take a table axis' value as
  the table's own rotation, joints = r + Rx(a) Rz(c) (pos - r) (xyzac) or r + Ry(b) Rz(c)
  (pos - r) (xyzbc), so on a preset table machine a = -A, c = -C (b = -B) with r the table centre;
  a head axis keeps its sign (camsmooth.post.writer's module docstring).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from camsmooth.io.program import CLProgram
from camsmooth.post.iso import read_iso
from camsmooth.post.model import PostDialect
from camsmooth.post.writer import Words, paren

__all__ = ["LINUXCNC", "DIALECTS", "linuxcnc_sense"]

#: the writer's words for LinuxCNC (module docstring)
LINUXCNC = Words("linuxcnc", paren, ("G21", "G90", "G17", "G40", "G49"), home=("G53 G00 Z0",), tcp_on="M428",
                 tcp_off="M429", path_tolerance=("G64 P{blend} Q{naive}",), exact_stop="G61")


def linuxcnc_sense(machine: Any) -> np.ndarray:
    """(2,) the sign of each rotary axis value LinuxCNC is given against camsmooth's
    (``Machine.rotary`` order; ``Machine.linuxcnc_sense``, module docstring): -1 for a preset's
    table axis, 1 for a head axis and for a chain given explicitly (written as described)."""
    return np.asarray(machine.linuxcnc_sense, float)


def _read(path: str, text: str, machine: Any = None, dialect: str = "linuxcnc",
          chord_tol: float | None = None) -> CLProgram:
    return read_iso(path, text, machine, "linuxcnc", chord_tol)


DIALECTS = (PostDialect("linuxcnc", _read, LINUXCNC, sense=linuxcnc_sense),)
