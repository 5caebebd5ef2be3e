"""One evaluation of a tool program: the figures ``smooth`` prints for the program it writes and
``analyze`` reports for a program it reads come from these functions, so that ``analyze`` of a
program camsmooth wrote reproduces what ``smooth`` said about it.

- ``gamma_of``: Gamma = sum |T''|^2 (1/s^4) over the programmed-feed time t (METHODS section 1.6).
- ``axis_violations``: samples over each axis's travel / velocity / acceleration limit under a
  time law (camsmooth.smoothing.nlp.limit_violations), judged on the positions as camsmooth
  writes them (``WRITTEN_DECIMALS`` decimals in mm and degrees) with the allowance that rounding
  can explain (``written_resolution``): a value counts only when it is beyond the limit by more
  than the rounding of the written program could have changed it. ``smooth`` and ``analyze``
  both round before counting, so both count on the same values (a result CSV, written to full
  precision, is rounded the same way).
- ``time_law``: the time-optimal law (camsmooth.smoothing.feed) or the law the program itself
  commands (a camsmooth G-code's G93 F words), and the controller's timing of it
  (camsmooth.controller) where camsmooth models the machine's controller.

The headline violations are those under the planned (time-optimal) time law t_plan, the law the
program's F words command; the counts at the programmed feed (the time law the CC path's feed
would give, before planning) are kept beside them and always labelled "at the programmed feed".
Units: mm, s, rad inside.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from camsmooth.machine.kinematics import Machine
from camsmooth.post.model import WRITTEN_DECIMALS, written_joints  # the "as written" rounding of the writer
from camsmooth.smoothing.feed import FeedPlan, machine_label, plan_program, row_slices
from camsmooth.smoothing.nlp import limit_violations, program_rates

__all__ = ["WRITTEN_DECIMALS", "TimeLaw", "Evaluation", "axis_violations", "evaluate_program", "gamma_of",
           "joints", "time_law", "written_joints", "written_resolution"]


def written_resolution(machine: Machine) -> dict[str, float]:
    """Half the unit of the last written decimal per axis (mm; rad for the rotary axes)."""
    e = 0.5 * 10.0 ** -WRITTEN_DECIMALS
    return {"X": e, "Y": e, "Z": e} | {r: float(np.radians(e)) for r in machine.rotary}


def joints(q: np.ndarray, machine: Machine) -> dict[str, np.ndarray]:
    """Axis name -> column of (N, 5) joints X Y Z and the machine's rotary axes
    (``Machine.joint_names``)."""
    q = np.asarray(q, float).reshape(-1, 5)
    return {name: q[:, k] for k, name in enumerate(machine.joint_names)}


def gamma_of(T: np.ndarray, t: np.ndarray, rows: np.ndarray) -> float:
    """Gamma = sum over interior points of |T''|^2 (1/s^4): T (N, 3) unit tool axes, t (N,) s from
    each row's start, three-point second differences (camsmooth.smoothing.nlp.program_rates)."""
    return float(np.sum(program_rates(np.asarray(T, float), t, rows).sec ** 2))


def axis_violations(machine: Machine, q: np.ndarray, t: np.ndarray, rows: np.ndarray, *, written: bool = True
                    ) -> tuple[dict[str, int], dict[str, float]]:
    """Samples over each axis's limits under the time law t (s from each row's start), and the
    peaks (internal units). written: judge the positions as camsmooth writes them (module
    docstring); False: as given, 1e-9 relative slack (a program read from another system)."""
    if written:
        return limit_violations(machine.limits, joints(written_joints(q), machine), t, rows,
                                resolution=written_resolution(machine))
    return limit_violations(machine.limits, joints(q, machine), t, rows)


@dataclass(frozen=True, kw_only=True)
class TimeLaw:
    """A program's time law. plan: the time-optimal plan (camsmooth.smoothing.feed.FeedPlan) or
    None when the program's programmed feed is unknown; t_plan (N,) s from each row's start, the
    law the program commands; row_cycle_time_optimal (R,) s and cycle_time_optimal s over it;
    limiting: the constraint that binds longest ('' when unknown); controller: the controller's
    ControllerPlan (camsmooth.controller) or None; cycle_time s and row_cycle_time (R,) s: the
    controller's where there is one, else the planned law's."""

    plan: FeedPlan | None
    t_plan: np.ndarray
    row_cycle_time_optimal: np.ndarray
    cycle_time_optimal: float
    limiting: str
    controller: Any
    cycle_time: float
    row_cycle_time: np.ndarray
    #: on a table LinuxCNC's trt kinematics describes (camsmooth.controller.tcp): the TCP-mode
    #: program's plan (TCPPlan) and machine mode's (ControllerPlan), ``controller`` the one of the
    #: mode the program is written in (``[post] mode``); None elsewhere
    tcp: Any = None
    machine_mode: Any = None


def _row_ends(t: np.ndarray, rows: np.ndarray) -> np.ndarray:
    return np.array([float(t[s.stop - 1] - t[s.start]) for s in row_slices(rows)])


def time_law(machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, feed: np.ndarray | None, *,
             tolerance: float, plan: FeedPlan | None = None, t_plan: np.ndarray | None = None,
             keep: np.ndarray | None = None, real: Machine | None = None, hold_feed: bool = False,
             t_blocks: np.ndarray | None = None) -> TimeLaw:
    """The program's time law (module docstring). rows (N,), q (N, 5) X Y Z mm A B rad, tip (N, 3)
    mm, feed (N,) programmed tip feed mm/min (None: unknown, then ``t_plan`` must be given).
    plan: an already computed time-optimal plan (else planned here); t_plan: the law the program
    itself commands (a written program's block times), used instead of the plan's; keep: the
    points that end a controller block (None: camsmooth.controller.place, as the writer does,
    with the block ends moved off the points inside the tolerance: vertex_shift); real: the
    machine the tips are decimated on (an error model's, default ``machine``);
    tolerance: mm, the user's; hold_feed: the controller's blocks are also held so that its model's
    tool tip never goes faster than the programmed feed (its blends can take it past; the plan's
    ``row_feed_peak`` says by how much when not held); t_blocks (N,) s from each row's start, with
    ``keep``: the block times a written program commands (its F words), which the controller
    runs as written (camsmooth held them when it wrote them, against the path through the points
    it smoothed, which a program whose block ends sit off them no longer carries)."""
    from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM
    from camsmooth.controller import plan_blocks, planner_for, predict, vertex_shift
    from camsmooth.controller.tcp import tcp_planner_for

    rows = np.asarray(rows)
    if plan is None and feed is not None:
        plan = plan_program(machine, rows, q, tip, feed)
    if t_plan is None:
        if plan is None:
            raise ValueError("time_law needs the programmed feed or the program's own time law")
        t_plan = plan.t_plan
    t_plan = np.asarray(t_plan, float)
    row_opt = _row_ends(t_plan, rows)
    law = dict(plan=plan, t_plan=t_plan, row_cycle_time_optimal=row_opt, cycle_time_optimal=float(row_opt.sum()),
               limiting=machine_label(plan.limiting, machine) if plan is not None else "", controller=None,
               cycle_time=float(row_opt.sum()), row_cycle_time=row_opt)
    planner = planner_for(machine, tolerance, rows, q)
    if planner is not None and len(rows):
        starts = [s.start for s in row_slices(rows)]
        entry = np.asarray(feed, float)[starts] if feed is not None else np.full(len(starts), np.nan)
        if not np.all(np.isfinite(entry) & (entry > 0)):
            # the entry move's feed is unknown: the first block's planned tip feed stands in
            nxt = np.minimum(np.asarray(starts) + 1, len(rows) - 1)
            chord = np.linalg.norm(tip[nxt] - tip[starts], axis=1)
            dt = np.maximum(t_plan[nxt] - t_plan[starts], 1e-9)
            entry = np.where(np.isfinite(entry) & (entry > 0), entry, 60.0 * chord / dt)
        keep_given = keep
        if keep is None:  # the blocks the controller runs soonest (camsmooth.controller.place), their ends
            # moved off the points inside the tolerance where that runs sooner (camsmooth.controller.vertex_shift)
            ctrl = plan_blocks(planner, machine, rows, q, tip, t_plan, tolerance, entry_height=DEFAULT_SAFE_HEIGHT_MM,
                               entry_feed=entry, real=real, feed=feed, hold_feed=hold_feed,
                               shift=vertex_shift(real or machine, rows, q, tip, tolerance))
        else:
            as_written = t_blocks is not None
            ctrl = predict(planner, machine, rows, q, tip, np.asarray(t_blocks, float) if as_written else t_plan,
                           np.asarray(keep, bool), entry_height=DEFAULT_SAFE_HEIGHT_MM, entry_feed=entry,
                           tolerance=tolerance, feed=feed, hold_feed=hold_feed, hold=not as_written)
        law.update(controller=ctrl, cycle_time=float(ctrl.cycle_time), row_cycle_time=np.asarray(ctrl.row_cycle_time))
        tcp_planner = tcp_planner_for(machine, tolerance, rows, q) if keep_given is None else None
        if tcp_planner is not None:  # TCP mode beside machine mode; the written mode's plan is the controller's
            tcp = tcp_planner.plan(machine, rows, q, tip, t_plan, tolerance, entry_height=DEFAULT_SAFE_HEIGHT_MM,
                                   entry_feed=entry, feed=feed, hold_feed=hold_feed,
                                   shift=vertex_shift(real or machine, rows, q, tip, tolerance, world=True))
            law.update(tcp=tcp, machine_mode=ctrl)
            if getattr(getattr(machine, "post", None), "mode", "machine") == "tcp":
                law.update(controller=tcp, cycle_time=float(tcp.cycle_time),
                           row_cycle_time=np.asarray(tcp.row_cycle_time))
    return TimeLaw(**law)


@dataclass(frozen=True, kw_only=True)
class Evaluation:
    """A program evaluated (``evaluate_program``): gamma (1/s^4, programmed-feed time); violations
    and peaks under the planned time law; violations_programmed and peaks_programmed at the
    programmed feed (name -> count; peaks in internal units, rad for A B); law: the TimeLaw."""

    gamma: float
    violations: dict[str, int]
    peaks: dict[str, float]
    violations_programmed: dict[str, int]
    peaks_programmed: dict[str, float]
    law: TimeLaw


def evaluate_program(machine: Machine, rows: np.ndarray, t: np.ndarray, q: np.ndarray, tip: np.ndarray,
                     T: np.ndarray, feed: np.ndarray | None, *, tolerance: float, written: bool = True,
                     plan: FeedPlan | None = None, t_plan: np.ndarray | None = None,
                     keep: np.ndarray | None = None, t_blocks: np.ndarray | None = None) -> Evaluation:
    """Everything ``smooth`` reports about a program's motion, for ``analyze`` (the pipeline calls
    the same pieces). t: (N,) s from each row's start at the programmed feed; T: (N, 3) unit tool
    axes; other arguments as ``time_law`` and ``axis_violations``."""
    law = time_law(machine, rows, q, tip, feed, tolerance=tolerance, plan=plan, t_plan=t_plan, keep=keep,
                   t_blocks=t_blocks)
    viol, peaks = axis_violations(machine, q, law.t_plan, rows, written=written)
    viol_p, peaks_p = axis_violations(machine, q, t, rows, written=written)
    return Evaluation(gamma=gamma_of(T, t, rows), violations=viol, peaks=peaks, violations_programmed=viol_p,
                      peaks_programmed=peaks_p, law=law)


def merge_counts(axes: Mapping[str, int], **others: int) -> dict[str, int]:
    """Axis counts and the other named counts (windows, interference) in one dict."""
    return {**dict(axes), **others}
