"""The controller: what the machine's control does with a program camsmooth writes.

- ``blocks``: the blocks a program is written in (longer blocks where the axes are smooth,
  within the tolerance, their ends moved off the points inside it: ``vertex_shift``),
  ``ControllerPlan``, a controller's timing of them per point, and the check that the planner
  model's tool tip stays within the tolerance at every servo cycle;
- ``linuxcnc``: a model of LinuxCNC's trajectory planner (derived from its source), and the least
  time any program of straight blocks can take on it (``least_row_times``);
- ``tcp``: LinuxCNC's TCP mode (M428, its trt kinematics) on an A/C or B/C table: the planner on
  the world coordinates, TCP blocks, F words held so that the joints stay within their limits,
  the TCP floor (``tcp_planner_for``, ``mode_text``: which mode runs a program faster);
- ``linuxcnc_sim``: LinuxCNC itself, its interpreter and a headless simulation (tests and
  benchmarks, needs the ``linuxcnc-uspace`` package).

``planner_for(machine)`` gives the planner model of the machine's post (``[post] dialect``) with
the program's blend tolerance (``blend_tolerance``: LinuxCNC's ``G64 P``), or None where camsmooth
has no model of the controller (then the time-optimal law is what is
reported). A second controller is one more entry in ``PLANNERS``.
"""

from __future__ import annotations

import numpy as np

from camsmooth.constants import PATH_TOLERANCE_SHARE  # the linuxcnc post's G64 P
from camsmooth.controller.blocks import (
    BLOCK_TOLERANCE_SHARE,
    EXECUTED_TOLERANCE_SHARE,
    ControllerPlan,
    Planner,
    decimate,
    place,
    plan_blocks,
    predict,
    vertex_shift,
)
from camsmooth.controller.linuxcnc import LinuxCNCPlanner, blend_tolerance
from camsmooth.controller.tcp import TCPPlanner, mode_text, tcp_planner_for
from camsmooth.machine.kinematics import Machine

__all__ = ["PLANNERS", "PATH_TOLERANCE_SHARE", "BLOCK_TOLERANCE_SHARE", "EXECUTED_TOLERANCE_SHARE", "planner_for",
           "blend_tolerance",
           "floor_text", "ControllerPlan", "Planner", "decimate", "place", "predict", "LinuxCNCPlanner", "TCPPlanner",
           "tcp_planner_for", "mode_text", "vertex_shift", "plan_blocks"]

#: dialect of the machine's post -> the model of that controller's planner
PLANNERS: dict[str, type] = {"linuxcnc": LinuxCNCPlanner}


def planner_for(machine: Machine, tolerance: float, rows: np.ndarray | None = None,
                q: np.ndarray | None = None) -> Planner | None:
    """The planner model of the machine's controller (by its ``[post] dialect``) for a program
    written for the user's ``tolerance`` (mm), None if camsmooth has no model of it; with the
    program's rows (N,) and points q (N, 5) its blend tolerance is ``blend_tolerance``'s, else
    PATH_TOLERANCE_SHARE of the tolerance. A blend tolerance over the tolerance comes with an
    exact stop at the end of each row's entry move (``entry_stop``)."""
    post = getattr(machine, "post", None)
    cls = PLANNERS.get(getattr(post, "dialect", ""))
    if cls is None:
        return None
    blend = PATH_TOLERANCE_SHARE * tolerance if q is None or rows is None else blend_tolerance(rows, q, tolerance)
    return cls(tolerance=blend, entry_stop=blend > tolerance)


def floor_text(controller: str, floor_s: float, program_s: float, end_offset_mm: float = 0.0) -> str:
    """The floor beside the prediction, as ``smooth`` and the report say it: the controller (by its
    planner's name, e.g. 'linuxcnc'), its floor and the program's predicted time (s);
    end_offset_mm: how far the program's block ends sit off the points (``ControllerPlan.end_offset``;
    the floor is then the one for block ends that far off them)."""
    title = getattr(PLANNERS.get(controller), "title", None) or {TCPPlanner.name: TCPPlanner.title}.get(controller,
                                                                                                        controller)
    where = (f"with their ends within {1e3 * end_offset_mm:.2g} um of these points" if end_offset_mm > 0
             else "through these points")
    return f"{title} cannot run straight blocks {where} in less than {floor_s:.4g} s; this program: {program_s:.4g} s"
