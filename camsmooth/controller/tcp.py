"""LinuxCNC's TCP mode on a rotary-tilting table: the program gives the tool tip and the rotary axes.

LinuxCNC's sample configurations ``xyzac-trt.ini`` and ``xyzbc-trt.ini`` (table-rotary-tilting,
switchkins) run a program in two kinematics: identity (type 0, ``M429``: X Y Z are the joints,
machine mode, camsmooth.controller.linuxcnc) and the trt kinematics (type 1, ``M428``): X Y Z are
the tool tip in the workpiece frame and A C (B C) the table's rotation, joints = r + Rx(a) Rz(c)
(pos - r) (Ry(b) on xyzbc) with r the rotation point (the machine file's table centre).
camsmooth.post.writer writes TCP programs (``[post] mode = "tcp"``: ``M428`` ... ``M429``, G94, F =
the tip feed mm/min). What that changes for the planner (LinuxCNC 2.9, ``tp.c``, ``emccanon.cc``):

1. The planner plans the WORLD coordinates (tip X Y Z, the rotary axes), with the ``[AXIS_*]``
   limits, exactly as it plans the joints in machine mode (the same canonical layer, the same
   parabolic blends between blocks that move a rotary axis): ``LinuxCNCPlanner`` run on them.
2. The tool tip moves on the chord between two programmed tips (no pivot lever bends the
   block), so a block may skip the points whose tips lie within the tolerance of the chord
   (``chord_reach``): blocks can be longer than in machine mode.
3. Nobody limits the joints: the kinematics turns every servo cycle's world position into joints
   (``world_joints``: ``Machine.linear_axes`` of the tip at the rotary angles), whose velocity and
   acceleration may exceed the joints' limits (LinuxCNC's issue tracker, #1738). So the block
   times are held (``TCPPlanner.predict``): first block by block, as in machine mode
   (camsmooth.controller.blocks._hold_row), the blocks whose blends take the model's tool tip
   farther than EXECUTED_TOLERANCE_SHARE of the tolerance from the programmed tips' polyline, and
   those during which a rotary axis goes past its amax (the parabolic blend into a row's last
   block adds the last block's whole acceleration to the half of the block before); then one
   factor on the row's block times (bisection) until every linear joint's finite-difference
   velocity and acceleration over the model's servo cycles is within the machine file's ``vmax``
   / ``amax``.
4. The blend tolerance (``G64 P``) is ``blend_tolerance``'s with
   TCP_PARABOLIC_PATH_TOLERANCE_SHARE: twice the tolerance where every move turns a rotary axis
   (parabolic blends only; the holds above keep the tip), else PATH_TOLERANCE_SHARE of it. The
   entry move blends into the row's first block (machine mode stops it, and takes a larger P).

The floor (``TCPPlanner.row_floor``) is ``least_row_times``' bound on the world coordinates with
the chord rule: no program of straight TCP blocks through the points runs faster on LinuxCNC 2.9
(its planner limits the world coordinates only, so the held program cannot beat it either).

Only for machines the trt kinematics describe (``trt_kinematics``): two table axes, the tilt
along X (A) or Y (B) and C along Z, both through the table centre, no head, no gauge offset.
Units: mm, s, rad inside (world rotary coordinates in camsmooth's sense: the planner is symmetric
in the sign of an axis, the post writes LinuxCNC's); F mm/min.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from camsmooth.constants import PATH_TOLERANCE_SHARE, TCP_PARABOLIC_PATH_TOLERANCE_SHARE
from camsmooth.controller.blocks import (
    BLOCK_TOLERANCE_SHARE,
    EXECUTED_TOLERANCE_SHARE,
    MAX_BLOCK_POINTS,
    ControllerPlan,
    _feed_check,
    _hold_row,
    _row_bounds,
    _run_deviation,
    acceleration_over,
    decimate,
    joint_ratio,
    points_timing,
    reach_table,
    rotary_turns,
    sooner_blocks,
    through_points_where_sooner,
)
from camsmooth.controller.linuxcnc import (
    LEAST_TIME_BLOCK_POINTS,
    SERVO_PERIOD_S,
    BlockTimes,
    LinuxCNCPlanner,
    blend_tolerance,
    canon_segments,
    least_block_times,
)
from camsmooth.machine.kinematics import Machine, axis_limits

__all__ = ["trt_kinematics", "world_coordinates", "world_joints", "chord_reach", "joint_ratio", "TCPPlan",
           "TCPPlanner", "tcp_planner_for", "mode_text", "LOWEST_FEED_SCALE"]

#: the least factor the F words of a row are held down by; a row that needs less is not held
LOWEST_FEED_SCALE = 0.02
#: bisection steps of the feed factor (the factor to 1 / 2^12 of the range)
_BISECTIONS = 12
#: the F words are written with one decimal (mm/min); LinuxCNC refuses F0 in a feed block
_LEAST_F = 0.1


def trt_kinematics(machine: Machine) -> str | None:
    """LinuxCNC's trt kinematics module for ``machine`` ('xyzac-trt-kins' or 'xyzbc-trt-kins'), or
    None when it does not describe the machine: two table axes, the outer (tilt) one named A along
    X or B along Y, the inner one C along Z, both through the table centre (the kinematics' single
    rotation point, its y/z offsets 0), no head axis and no gauge offset; each axis turning the
    table the way LinuxCNC's does for the value the post writes (``Machine.linuxcnc_sense``)."""
    d = machine.description
    if d.head or len(d.table) != 2 or np.linalg.norm(np.asarray(d.gauge, float)) > 1e-9:
        return None
    tilt, rot = d.table  # t_1 (carries t_2), t_2 (carries the workpiece)
    sense = dict(zip(machine.rotary, machine.linuxcnc_sense, strict=True))
    want = {"A": 0, "B": 1}
    if tilt.name not in want or rot.name != "C":
        return None
    c = np.asarray(rot.point, float)
    for ax, k in ((tilt, want[tilt.name]), (rot, 2)):
        u = np.asarray(ax.direction, float)
        # LinuxCNC's value v turns the table by R_k(v); camsmooth's angle q by R_u(-q), v = sense q
        if abs(abs(u[k]) - 1.0) > 1e-12 or u[k] * sense[ax.name] != -1.0:
            return None
        off = c - np.asarray(ax.point, float)
        if np.linalg.norm(off - (off @ u) * u) > 1e-9:  # the axis does not pass through the centre
            return None
    return f"xyz{tilt.name.lower()}c-trt-kins"


def world_coordinates(q: np.ndarray, tip: np.ndarray) -> np.ndarray:
    """(N, 5) TCP mode's world coordinates: the tool tip X Y Z (mm, workpiece frame) and the two
    rotary axes (rad, camsmooth's sense) of joints q (N, 5) with tool tips tip (N, 3)."""
    q = np.atleast_2d(np.asarray(q, float))
    return np.column_stack([np.asarray(tip, float).reshape(-1, 3), q[:, 3:]])


def world_joints(machine: Machine, world: np.ndarray) -> np.ndarray:
    """(K, 5) the joints (X Y Z mm, rotary rad) the trt kinematics commands for world positions
    (K, 5) (tip mm, rotary rad): ``Machine.linear_axes`` of the tip at the rotary angles."""
    w = np.atleast_2d(np.asarray(world, float))
    return np.column_stack([machine.linear_axes(w[:, :3], w[:, 3], w[:, 4]), w[:, 3:]])


def chord_reach(rows: np.ndarray, tip: np.ndarray, tolerance: float, max_points: int = MAX_BLOCK_POINTS, *,
                shift: np.ndarray | None = None) -> np.ndarray:
    """Which TCP blocks keep the tips they skip within ``tolerance`` (mm) of their chord (the tip
    path of a TCP block): (N, max_points) bool in ``block_reach``'s layout, entry [a, k - 1] for the
    block from point a to point a + k inside a's row (always True for k = 1). Once a block from a
    fails, the longer ones from a are not tried. tip (N, 3) mm; shift (N, 3+): the chords run
    between the tips moved by its first three columns (``vertex_shift`` with ``world``; None: not
    moved), the tips they must pass stay tip (the path between two skipped tips is their chord,
    never farther from the block's than its ends)."""
    tip = np.asarray(tip, float)
    ends = tip if shift is None else tip + np.asarray(shift, float)[:, :3]
    tol2 = float(tolerance) ** 2

    def passes(a: np.ndarray, k: int) -> np.ndarray:
        p0, d = ends[a], ends[a + k] - ends[a]
        rel = tip[a[:, None] + np.arange(1, k)[None, :]] - p0[:, None, :]
        t = np.clip(np.einsum("bpk,bk->bp", rel, d) / np.maximum(np.einsum("bk,bk->b", d, d), 1e-300)[:, None],
                    0.0, 1.0)
        off = rel - t[..., None] * d[:, None, :]
        return np.einsum("bpk,bpk->bp", off, off).max(axis=1) <= tol2

    return reach_table(rows, len(tip), max_points, passes)


@dataclass(frozen=True, kw_only=True)
class TCPPlan(ControllerPlan):
    """A TCP-mode program's blocks and LinuxCNC's timing of them (``ControllerPlan``; block_time:
    the held block times, whose tip feeds the TCP program's F words are), and per row:
    row_feed_scale (R,), the factor the block feeds were held down by on top of the per-block
    holds (1: not at all), row_joint_ratio (R,), the linear joints' largest velocity or
    acceleration over their limits at the model's servo cycles with those F words (<= 1: within
    the limits; the rotary joints are world coordinates, which the planner holds within theirs but
    for the blend into a row's last block, which the per-block hold covers)."""

    row_feed_scale: np.ndarray = field(default_factory=lambda: np.zeros(0))
    row_joint_ratio: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def within_limits(self) -> bool:
        """Every row's joints within their limits at every servo cycle of the model."""
        return bool(np.all(self.row_joint_ratio <= 1.0))


@dataclass(frozen=True, kw_only=True)
class TCPPlanner:
    """LinuxCNC 2.9's planner in TCP mode (module docstring): ``LinuxCNCPlanner`` on the world
    coordinates. servo_period s; v_limit [TRAJ] MAX_LINEAR_VELOCITY mm/s (None: the fastest
    linear axis); tolerance: the program's ``G64 P`` (mm)."""

    servo_period: float = SERVO_PERIOD_S
    v_limit: float | None = None
    tolerance: float = 0.0
    name: str = "linuxcnc-tcp"
    title: str = "LinuxCNC TCP mode (M428)"

    def _world_planner(self) -> LinuxCNCPlanner:
        return LinuxCNCPlanner(servo_period=self.servo_period, v_limit=self.v_limit, tolerance=self.tolerance)

    def block_ends(self, machine: Machine, world: np.ndarray, t_opt: np.ndarray, ok: np.ndarray,
                   entry_world: np.ndarray, entry_time: float) -> np.ndarray | None:
        """``LinuxCNCPlanner.block_ends`` on the world coordinates (n, 5) (tip mm, rotary rad): the
        block ends of one row the planner runs soonest among the blocks ok (``chord_reach``)."""
        return self._world_planner().block_ends(machine, world, t_opt, ok, entry_world, entry_time)

    def row_run(self, machine: Machine, world_blocks: np.ndarray, block_time: np.ndarray, entry_world: np.ndarray,
                entry_time: float) -> tuple[BlockTimes, np.ndarray]:
        """One row as LinuxCNC runs it in TCP mode: entered from rest at ``entry_world`` by a feed
        move of ``entry_time`` s, then one G94 block per further world position with F = the tip
        chord over the block time ``block_time`` (s), written with one decimal (mm/min; a block
        whose tip does not move: its rotary travel, deg/min, as LinuxCNC reads F there), ending at
        rest. Positions rounded as the writer writes them (4 decimals, mm and degrees). Returns the
        segments' BlockTimes (the entry move first) and (K, 5) the world position (tip mm, rotary
        rad) at the end of every servo cycle."""
        def written(w: np.ndarray) -> np.ndarray:
            w = np.atleast_2d(np.asarray(w, float))
            return np.round(np.column_stack([w[:, :3], np.degrees(w[:, 3:])]), 4)

        start, pts = written(entry_world)[0], written(world_blocks)
        if len(pts) != len(np.atleast_1d(block_time)) + 1:
            raise ValueError(f"{len(pts)} world positions need {len(pts) - 1} block times, got {len(block_time)}")
        d = np.diff(np.vstack([start[None, :], pts]), axis=0)
        chord = np.linalg.norm(d[:, :3], axis=1)
        # a block that turns the rotary axes about a still tip is a pure rotary move: F in deg/min
        chord = np.where(chord > 0, chord, np.linalg.norm(d[:, 3:], axis=1))
        times = np.maximum(np.r_[entry_time, np.asarray(block_time, float)], 1e-6)
        fword = np.maximum(np.round(60.0 * chord / times, 1), _LEAST_F)
        k = len(times)
        seg = canon_segments(start, pts, np.zeros(k, bool), fword, np.zeros(k, bool), machine,
                             servo_period=self.servo_period, v_limit=self.v_limit, tolerance=self.tolerance)
        bt = self._world_planner().run(seg)
        w = bt.positions(start, pts)
        return bt, np.column_stack([w[:, :3], np.radians(w[:, 3:])])

    def row_floor(self, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray,
                  feed: np.ndarray | None, tolerance: float, end_offset: float = 0.0) -> np.ndarray:
        """The TCP floor (s, per row in order of appearance): ``least_row_times``' bound on the world
        coordinates, blocks whose skipped tips stay within the whole ``tolerance`` (mm) of their
        chord (``chord_reach``), the [AXIS] limits the machine file's; with ``end_offset`` (mm), for
        block ends whose tips may sit that far off the points (the chords within ``tolerance`` +
        end_offset, each chord 2 end_offset shorter: ``least_row_times``). q (N, 5) joints (mm,
        rad); tip (N, 3) mm; feed (N,) mm/min (None: unknown)."""
        f = np.full(len(q), np.inf) if feed is None else np.where(np.asarray(feed, float) > 0, feed, np.inf)
        vmax, amax, _ = axis_limits(machine)
        ok = chord_reach(rows, tip, float(tolerance) + float(end_offset), LEAST_TIME_BLOCK_POINTS)
        return least_block_times(vmax, amax, rows, world_coordinates(q, tip), tip, f, ok, LEAST_TIME_BLOCK_POINTS,
                                 slack=float(end_offset))

    def _entry(self, machine: Machine, q: np.ndarray, tip: np.ndarray, entry_height: float,
               entry_feed: float) -> tuple[np.ndarray, float]:
        """A row's entry move in TCP mode: the world position ``entry_height`` mm up the tool axis
        from the first point (joints q (5,), tip (3,)) and its time (s) at ``entry_feed`` mm/min."""
        _, axis = machine.tool_pose_np(q[3], q[4], q[0], q[1], q[2])
        w = world_coordinates(q[None, :], tip[None, :])[0]
        w[:3] += entry_height * np.asarray(axis, float).reshape(3)
        return w, 60.0 * entry_height / float(entry_feed)

    def place(self, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, t_opt: np.ndarray,
              tolerance: float, *, entry_height: float, entry_feed: np.ndarray,
              shift: np.ndarray | None = None) -> np.ndarray:
        """Points that end a TCP block (bool (N,)): per row, among the blocks whose skipped tips stay
        within ``BLOCK_TOLERANCE_SHARE * tolerance`` (mm) of their chord, the block ends the model
        runs soonest (``block_ends``) where they run faster than the longest blocks (``decimate``'s
        greedy rule on ``chord_reach``), else those. t_opt (N,) s, the law the blocks command;
        entry_height mm, entry_feed (R,) mm/min as ``predict``; shift (N, 5): the world
        coordinates' move at each point that ends a block (``vertex_shift`` with ``world``; None:
        none)."""
        rows = np.asarray(rows)
        q, tip, t_opt = (np.asarray(x, float) for x in (q, tip, t_opt))
        w = world_coordinates(q, tip) + (0.0 if shift is None else np.asarray(shift, float))
        ok = chord_reach(rows, tip, BLOCK_TOLERANCE_SHARE * float(tolerance), shift=shift)
        if self.tolerance > tolerance:  # G64 P past the tolerance: only blocks LinuxCNC blends parabolically
            ok = np.logical_and.accumulate(ok & rotary_turns(q, ok.shape[1]), axis=1)
        keep = decimate(machine, rows, q, tip, tolerance, ok=ok)
        return sooner_blocks(self, machine, rows, w, t_opt, ok, keep,
                             lambda r, a: self._entry(machine, q[a], tip[a], entry_height, float(entry_feed[r])))

    def _rotary_over(self, machine: Machine, run: BlockTimes, world: np.ndarray) -> np.ndarray:
        """Per block of a row run, the rotary axes' ``acceleration_over`` their amax: LinuxCNC
        limits them as world coordinates, but not in a blend into a row's last block."""
        return acceleration_over(run, np.asarray(world, float)[:, 3:], axis_limits(machine)[1][3:], self.servo_period)

    def _held_row(self, machine: Machine, w: np.ndarray, tip_path: np.ndarray, k: np.ndarray, t_opt: np.ndarray,
                  entry_w: np.ndarray, entry_time: float, limit: float | None,
                  feed_over: Callable[[BlockTimes, np.ndarray], np.ndarray] | None = None
                  ) -> tuple[np.ndarray, float, BlockTimes, np.ndarray, float, float]:
        """One row's blocks k (indices into w, the row's world coordinates; tip_path: the entry tip
        then the row's tips, mm) with the time-optimal law's block times (t_opt, s) held: first
        per block, the blends that take the model's tip farther than ``limit`` mm from the polyline
        (None: not checked) and the blocks where a rotary axis goes past its amax (and, with
        ``feed_over``, the tip past the programmed feed: ``tip_speed_over``) lengthened
        (camsmooth.controller.blocks._hold_row); then all of them divided by s, the largest factor
        in [LOWEST_FEED_SCALE, 1] (bisection) at which every linear joint stays within its
        limits and the tip within ``limit``. Returns the held block times, s, the run, its world
        positions per servo cycle, the linear joints' largest ratio to their limits and the tip's
        largest distance (mm)."""
        at = np.arange(len(w)) + 1  # the path vertex of each point (the entry tip is vertex 0)
        _, bt0, _, _ = _hold_row(self, machine, w, k, t_opt, entry_w, entry_time,
                                 None if limit is None else tip_path, at, limit or 0.0, tips=lambda x: x[:, :3],
                                 split=False, over_limits=lambda run, pos: np.maximum(
                                     self._rotary_over(machine, run, pos),
                                     0.0 if feed_over is None else feed_over(run, pos)))

        def attempt(s: float) -> tuple[bool, BlockTimes, np.ndarray, float, float]:
            run, pos = self.row_run(machine, w[k], bt0 / s, entry_w, entry_time)
            # the linear joints: the rotary ones are world coordinates, which the planner limits
            ratio = float(joint_ratio(machine, np.vstack([world_joints(machine, entry_w[None, :]),
                                                          world_joints(machine, pos)]), self.servo_period)[:, :3].max())
            dev = 0.0 if limit is None else float(_run_deviation(run, pos[:, :3], tip_path, at[k]).max(initial=0.0))
            return ratio <= 1.0 and (limit is None or dev <= limit), run, pos, ratio, dev

        good, run, pos, ratio, dev = attempt(1.0)
        if good:
            return bt0, 1.0, run, pos, ratio, dev
        lo, hi = LOWEST_FEED_SCALE, 1.0
        good, *best = attempt(lo)
        if good:
            for _ in range(_BISECTIONS):
                mid = 0.5 * (lo + hi)
                good, *got = attempt(mid)
                if good:
                    lo, best = mid, got
                else:
                    hi = mid
        # not held even at the lowest factor: reported as it is
        return (bt0 / lo, lo, *best)

    def predict(self, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, t_opt: np.ndarray,
                keep: np.ndarray, *, entry_height: float, entry_feed: np.ndarray, tolerance: float | None = None,
                feed: np.ndarray | None = None, hold_feed: bool = False, shift: np.ndarray | None = None) -> TCPPlan:
        """LinuxCNC's timing of a TCP program written in the blocks ``keep`` with the time-optimal
        law's block times (t_opt, s from each row's start) held per block and row (``_held_row``; with
        ``tolerance`` (mm, the user's) the model's tip is also held within EXECUTED_TOLERANCE_SHARE
        of it from the polyline of the programmed tips, the entry tip first). q (N, 5) joints mm
        rad; tip (N, 3) mm; entry_height mm and entry_feed (R,) mm/min, the rows' entry moves as the
        writer writes them; feed (N,) mm/min, the programmed tip feed, for the floor, the plan's
        row_feed_peak and, with ``hold_feed``, the blocks' hold (as machine mode's). Points inside
        a block are timed by their share of the block's tip chord. shift (N, 5): the world coordinates'
        move at the points that end a block, as ``place`` chose them (None: none); the programmed
        tips stay tip."""
        rows = np.asarray(rows)
        q, tip, t_opt = (np.asarray(x, float) for x in (q, tip, t_opt))
        keep = np.array(keep, bool)
        w = world_coordinates(q, tip) + (0.0 if shift is None else np.asarray(shift, float))
        n = len(rows)
        starts, ends = _row_bounds(rows)
        block_time, t_ctrl, feed_plan = np.zeros(n), np.zeros(n), np.zeros(n)
        row_cycle, row_dev = np.zeros(len(starts)), np.zeros(len(starts))
        scale, ratio = np.ones(len(starts)), np.zeros(len(starts))
        peak = np.zeros((len(starts), 5))
        feed_peak = np.full(len(starts), np.nan)
        limit = None if tolerance is None else EXECUTED_TOLERANCE_SHARE * float(tolerance)
        for r, (a, b) in enumerate(zip(starts, ends, strict=True)):
            k = a + np.flatnonzero(keep[a:b])
            tk = np.zeros(1)
            if len(k) > 1:
                entry_w, entry_time = self._entry(machine, q[a], tip[a], entry_height, float(entry_feed[r]))
                path = np.vstack([entry_w[None, :3], tip[a:b]])
                speed = _feed_check(self, feed if hold_feed else None, a, b, entry_w[:3], lambda x: x[:, :3])
                block_time[k[1:]], scale[r], run, pos, ratio[r], row_dev[r] = self._held_row(
                    machine, w[a:b], path, k - a, t_opt[a:b], entry_w, entry_time, limit, speed)
                over = _feed_check(self, feed, a, b, entry_w[:3], lambda x: x[:, :3], slack=0.0)
                if over is not None:
                    feed_peak[r] = float(over(run, pos).max(initial=0.0))
                tk = np.r_[0.0, run.end[1:] - run.end[0]]
                joints = world_joints(machine, np.vstack([entry_w[None, :], pos]))
                # over 5 cycles, as machine mode's (camsmooth.controller.blocks.predict)
                peak[r] = joint_ratio(machine, joints, self.servo_period, stride=5).max(axis=0)
            s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(tip[a:b], axis=0), axis=1))]
            t_ctrl[a:b], feed_plan[a:b] = points_timing(s, k - a, tk, tip[k])
            row_cycle[r] = tk[-1]
        floor = joint_shift = tip_shift = None
        off = 0.0
        if shift is not None:
            tip_shift = np.where(keep[:, None], np.asarray(shift, float)[:, :3], 0.0)
            joint_shift = np.zeros((n, 5))
            joint_shift[keep] = world_joints(machine, w[keep]) - world_joints(machine, w[keep] - np.asarray(
                shift, float)[keep])
            off = float(np.linalg.norm(tip_shift, axis=1).max(initial=0.0))
        if tolerance is not None and n:  # for block ends as far off the points as this program's
            floor = self.row_floor(machine, rows, q, tip, feed, float(tolerance), off)
        return TCPPlan(controller=self.name, keep=keep, block_time=block_time, t_plan=t_ctrl, feed_plan=feed_plan,
                       row_ids=rows[starts].astype(np.int64), row_cycle_time=row_cycle,
                       cycle_time=float(row_cycle.sum()), row_deviation=row_dev, row_floor=floor,
                       row_feed_scale=scale, row_joint_ratio=ratio, blend_tolerance=self.tolerance,
                       row_joint_peak=peak, row_feed_peak=None if feed is None else feed_peak,
                       joint_shift=joint_shift, tip_shift=tip_shift)

    def plan(self, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, t_opt: np.ndarray,
             tolerance: float, *, entry_height: float, entry_feed: np.ndarray, feed: np.ndarray | None = None,
             hold_feed: bool = False, shift: np.ndarray | None = None) -> TCPPlan:
        """``place`` then ``predict``: the TCP program camsmooth writes and LinuxCNC's timing of it
        (shift: the block ends' move off the points, ``vertex_shift`` with ``world``, per row where
        that runs sooner than through them: ``through_points_where_sooner``; None: none)."""
        kw = dict(entry_height=entry_height, entry_feed=entry_feed, tolerance=tolerance, feed=feed,
                  hold_feed=hold_feed)

        def planned(s: np.ndarray | None) -> TCPPlan:
            keep = self.place(machine, rows, q, tip, t_opt, tolerance, entry_height=entry_height,
                              entry_feed=entry_feed, shift=s)
            return self.predict(machine, rows, q, tip, t_opt, keep, shift=s, **kw)

        off = planned(shift)
        if shift is None:
            return off
        mixed = through_points_where_sooner(rows, shift, off, planned(None))
        return off if mixed is None else self.predict(machine, rows, q, tip, t_opt, mixed[0], shift=mixed[1], **kw)


def tcp_planner_for(machine: Machine, tolerance: float, rows: np.ndarray | None = None,
                    q: np.ndarray | None = None) -> TCPPlanner | None:
    """The TCP-mode planner model for ``machine`` when its post is LinuxCNC's and LinuxCNC's trt
    kinematics describes it (``trt_kinematics``), for a program written for the user's
    ``tolerance`` (mm); else None. With the program's rows (N,) and joints q (N, 5) (mm, rad) its
    ``G64 P`` is ``blend_tolerance``'s with TCP_PARABOLIC_PATH_TOLERANCE_SHARE (the entry move
    blends into the row: a larger P lets that blend go farther than slower blocks can hold), else
    PATH_TOLERANCE_SHARE of the tolerance."""
    post = getattr(machine, "post", None)
    if getattr(post, "dialect", "") != "linuxcnc" or trt_kinematics(machine) is None:
        return None
    blend = (PATH_TOLERANCE_SHARE * tolerance if q is None or rows is None
             else blend_tolerance(rows, q, tolerance, TCP_PARABOLIC_PATH_TOLERANCE_SHARE))
    return TCPPlanner(tolerance=blend)


def mode_text(tcp_s: float, tcp_floor_s: float | None, machine_s: float, machine_floor_s: float | None,
              within_limits: bool = True) -> str:
    """Both LinuxCNC modes in one line, as ``smooth`` and the report say it: 'TCP mode (M428): X s,
    floor Y s; machine mode: Z s, floor W s: TCP mode is faster by D s (P%)' (times s; D the
    difference, P it over the slower mode's time); ``within_limits``: the TCP program keeps the
    joints within their limits (else it is not offered as the faster one)."""
    def part(name: str, t: float, fl: float | None) -> str:
        return f"{name}: {t:.4g} s" + (f", floor {fl:.4g} s" if fl is not None else "")

    text = f"{part('TCP mode (M428)', tcp_s, tcp_floor_s)}; {part('machine mode', machine_s, machine_floor_s)}"
    if not within_limits:
        return text + ": TCP mode cannot keep the joints within their limits, machine mode is the one to run"
    faster, fast, slow = ("TCP mode", tcp_s, machine_s) if tcp_s < machine_s else ("machine mode", machine_s, tcp_s)
    return text + f": {faster} is faster by {slow - fast:.4g} s ({100.0 * (1.0 - fast / slow):.3g}%)"
