"""A smoothing result as the post layer's program (camsmooth.post.model.PostProgram), and
``write_gcode``, which writes it in the machine's dialect (camsmooth.post.writer).

What the writer is given from a MethodResult: the joints by the machine's axis names (``xyz`` the
linear axes mm, then the two rotary axes in ``Machine.rotary`` order, rad), the tool tip ``cl``
and axis (workpiece frame), the programmed feed per point (mm/min), the programmed-feed times
``t`` (s from each row's start), and the block times: a controller plan's (``controller``:
camsmooth.controller.blocks.ControllerPlan, its kept points are the blocks, G93 F = 1 / its block
time) or, without one, the planned time law's (``plan.t_plan``) between consecutive points. The
header carries the method, the run's inputs (camsmooth.smoothing.result.describe_inputs), the
cutter and the tolerance (mm).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM
from camsmooth.errors import InputError
from camsmooth.post.model import PostProgram
from camsmooth.post.writer import settings, write_program
from camsmooth.smoothing.result import MethodResult, SmoothResult, describe_inputs

__all__ = ["post_program", "post_points", "write_gcode", "tool_text"]

#: the header's name of each cutter of the toroid family (camsmooth.geometry.cutter.ToroidalCutter.kind)
_CUTTER_WORDS = {"bull": "bull nose", "ball": "ball end", "flat": "flat end"}


def rotary_of(r: Any) -> np.ndarray:
    """(N, 2) the two rotary axes of a MethodResult (rad, ``Machine.rotary`` order: its ``rotary``,
    camsmooth.machine.axes.RotaryValues)."""
    return np.asarray(r.rotary.values, dtype=float)


def tool_text(cutter: Any) -> str:
    """The header's tool line (after 'tool: '): kind, R, r, diameter and shank (mm)."""
    R, r_c = float(cutter.R), float(cutter.r)
    diameter = float(getattr(cutter, "diameter", 2.0 * (R + r_c)))
    shank = getattr(cutter, "shank_length", None)
    shank_txt = "n/a" if shank is None else f"{float(shank):.4f} mm"
    return (f"{_CUTTER_WORDS.get(getattr(cutter, 'kind', 'bull'), 'toroidal')} R {R:.4f} mm, r {r_c:.4f} mm, "
            f"diameter {diameter:.4f} mm, shank {shank_txt}")


def post_points(r: Any) -> PostProgram:
    """The points of a MethodResult as a PostProgram (rows, idx, joints, tips, axis; feed nan):
    what camsmooth.post.rewrite writes into a posted program."""
    rows = np.asarray(r.rows, dtype=np.int64)
    joints = np.column_stack([np.asarray(r.xyz, dtype=float).reshape(-1, 3), rotary_of(r)])
    return PostProgram(rows=rows, idx=np.asarray(r.idx, dtype=np.int64), joints=joints,
                       tips=np.asarray(r.cl, dtype=float).reshape(-1, 3),
                       axis=np.asarray(r.axis, dtype=float).reshape(-1, 3), feed=np.full(len(rows), np.nan),
                       method=getattr(r, "method", "unknown"))


def post_program(result: SmoothResult | MethodResult, cutter: Any, feed_mm_min: float | np.ndarray,
                 tolerance: float | None = None) -> PostProgram:
    """The program the writer writes for ``result`` (a SmoothResult: its primary method; or one
    MethodResult) cut with ``cutter`` at the programmed tip feed ``feed_mm_min`` (mm/min, one
    number or one per point: the feed of the move that ends at the point). tolerance: mm for the
    controller's path tolerance words (None: the result's ``metrics.tolerance_mm``). Where a
    controller plan timed the program, its blocks are the points it kept. InputError for a feed
    that is not a finite number > 0 or not one per point."""
    if isinstance(result, SmoothResult):
        r, method, inputs = result.result, result.primary, result.inputs
    else:
        r, method, inputs = result, result.method, {}
    prog = post_points(r)
    rows, idx = prog.rows, prog.idx
    n = len(rows)
    feed_in = np.asarray(feed_mm_min, dtype=float)
    if feed_in.ndim == 0:
        if not (math.isfinite(float(feed_in)) and float(feed_in) > 0):
            raise InputError(f"feed must be a finite number > 0 mm/min, got {float(feed_in)!r}", column="feed")
        feed = np.full(n, float(feed_in))
    else:
        if feed_in.shape != (n,):
            raise InputError(f"feed has {feed_in.size} values for {n} points", column="feed")
        feed = feed_in.astype(float)
        bad = ~(np.isfinite(feed) & (feed > 0))
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError(f"feed must be a finite number > 0 mm/min at row {int(rows[k])}, point {int(idx[k])}, "
                             f"got {float(feed[k])!r}", column="feed")
    ctrl = getattr(r, "controller", None)
    plan = getattr(r, "plan", None)
    t_prog = np.asarray(r.t, float) if getattr(r, "t", None) is not None and len(r.t) == n else None
    f_prog = np.asarray(inputs.get("feed", feed), float).reshape(-1)
    f_prog = f_prog if f_prog.shape == (n,) else feed
    joints, tips, axis = prog.joints, prog.tips, prog.axis
    block_time = None
    t_opt = None
    if ctrl is not None:  # the blocks the controller plan timed (camsmooth.controller.blocks)
        sel = np.asarray(ctrl.keep, bool)
        if getattr(ctrl, "joint_shift", None) is not None:  # the block ends the plan moved off the points
            joints = joints + np.asarray(ctrl.joint_shift, float)
            tips = tips + np.asarray(ctrl.tip_shift, float)
        rows, idx, joints, tips, axis, feed = (v[sel] for v in (rows, idx, joints, tips, axis, feed))
        t_prog = None if t_prog is None else t_prog[sel]
        f_prog = f_prog[sel]
        block_time = np.asarray(ctrl.block_time, float)[sel]
        if plan is not None and len(plan.t_plan) == len(sel):
            t_opt = np.asarray(plan.t_plan, float)[sel]
    elif plan is not None and len(plan.t_plan) == n:  # every point a block, timed by the planned law
        same = np.r_[False, rows[1:] == rows[:-1]]
        block_time = np.where(same, np.r_[0.0, np.diff(np.asarray(plan.t_plan, float))], np.nan)
        block_time[same & ~(block_time > 0)] = np.nan  # a repeat the plan gives no time: the feed decides
    if tolerance is None:
        metrics = getattr(r, "metrics", None)
        tolerance = getattr(metrics, "tolerance_mm", None)
    return PostProgram(rows=rows, idx=idx, joints=joints, tips=tips, axis=axis, feed=feed, method=method,
                       inputs=list(describe_inputs(inputs)), tool_text=tool_text(cutter), n_points=n,
                       tolerance=tolerance, t_prog=t_prog, f_prog=f_prog, block_time=block_time, t_opt=t_opt,
                       blend_tolerance=getattr(ctrl, "blend_tolerance", None),
                       entry_stop=bool(getattr(ctrl, "entry_stop", False)),
                       end_offset=float(getattr(ctrl, "end_offset", 0.0) or 0.0))


def write_gcode(path: str | os.PathLike, result: SmoothResult | MethodResult, machine: Any, cutter: Any,
                feed_mm_min: float | np.ndarray, *, safe_height: float = DEFAULT_SAFE_HEIGHT_MM,
                check_limits: bool = True, dialect: str | None = None, mode: str | None = None,
                program_name: str = "CAMSMOOTH", tolerance: float | None = None, setup: Any = None) -> Path:
    """Write a method's program as five-axis G-code to ``path`` atomically (camsmooth.post.writer).

    result: a SmoothResult (its primary method) or one MethodResult: rows, idx, cl (tool tip,
    mm), axis (unit, tip -> spindle), the rotary axes (rad), xyz (linear axes, mm), all workpiece
    frame. feed_mm_min: the programmed tip feed, mm/min, one number or one per point (a row's
    first value also sets its entry move). dialect, mode: override ``machine.post``
    (camsmooth.machine.kinematics.PostConfig). safe_height: retract along the tool axis between
    rows (mm). check_limits: InfeasibleError naming the axis, travel, row and point for a value
    out of travel, the retracts included. setup: the input's tool call, spindle, coolant and work
    offset (camsmooth.post.setup.ShopSetup). InputError for a feed that is not finite and > 0,
    non-finite coordinates, an unknown dialect or mode, machine mode on Heidenhain, tcp mode on the
    generic dialect.
    """
    settings(machine, dialect, mode, safe_height)  # the settings' errors before the feed's
    program = post_program(result, cutter, feed_mm_min, tolerance)
    return write_program(path, program, machine, dialect=dialect, mode=mode, safe_height=safe_height,
                         check_limits=check_limits, program_name=program_name, setup=setup)
