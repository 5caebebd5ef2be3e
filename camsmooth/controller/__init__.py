"""The controller: what the machine's control does with a program camsmooth writes.

- ``blocks``: the blocks a program is written in (longer blocks where the axes are smooth,
  within the tolerance) and ``ControllerPlan``, a controller's timing of them per point;
- ``linuxcnc``: a model of LinuxCNC's trajectory planner (derived from its source);
- ``linuxcnc_sim``: LinuxCNC itself, its interpreter and a headless simulation (tests and
  benchmarks, needs the ``linuxcnc-uspace`` package).

``planner_for(machine)`` gives the planner model of the machine's post (``[post] dialect``), or
None where camsmooth has no model of the controller (then the time-optimal law is what is
reported). A second controller is one more entry in ``PLANNERS``.
"""

from __future__ import annotations

from camsmooth.controller.blocks import BLOCK_TOLERANCE_SHARE, ControllerPlan, Planner, decimate, predict
from camsmooth.controller.linuxcnc import LinuxCNCPlanner
from camsmooth.machine.kinematics import Machine

__all__ = ["PLANNERS", "PATH_TOLERANCE_SHARE", "BLOCK_TOLERANCE_SHARE", "planner_for", "ControllerPlan", "Planner",
           "decimate", "predict", "LinuxCNCPlanner"]

#: share of the user's tolerance the controller may blend off the path (G64 P), the rest is the blocks'
PATH_TOLERANCE_SHARE = 1.0 - BLOCK_TOLERANCE_SHARE
#: dialect of the machine's post -> the model of that controller's planner
PLANNERS: dict[str, type] = {"linuxcnc": LinuxCNCPlanner}


def planner_for(machine: Machine, tolerance: float) -> Planner | None:
    """The planner model of the machine's controller (by its ``[post] dialect``) for a program
    written for the user's ``tolerance`` (mm), None if camsmooth has no model of it."""
    post = getattr(machine, "post", None)
    cls = PLANNERS.get(getattr(post, "dialect", ""))
    return cls(tolerance=PATH_TOLERANCE_SHARE * tolerance) if cls is not None else None
