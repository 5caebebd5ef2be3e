"""A model of LinuxCNC's trajectory planner for the programs camsmooth writes.

What LinuxCNC does with a block (LinuxCNC 2.9, ``src/emc/task/emccanon.cc``,
``src/emc/tp/tp.c``, ``tc.c``, ``blendmath.c``; derived from the source, checked against the
headless simulation in ``benchmarks/bench_controller.py`` and ``tests/test_controller.py``):

1. The interpreter turns an inverse-time block (G93, ``F`` in 1/min) into a feed rate
   ``rate = length * F`` where ``length`` is the XYZ distance of the block (the rotary distance in
   degrees for a block that moves only rotary axes).
2. The canonical layer gives every straight move a requested speed ``vel = min(rate, v_ini)``, a
   largest speed ``v_ini = d_tot / max_i(|d_i| / vmax_i)`` and an acceleration
   ``acc = d_tot / max_i(|d_i| / amax_i)`` over all axes that move (``d_tot`` the XYZ length;
   "a combined move is handled like a linear move, with the angular axes given the time to
   finish", NIST IR 6556); a rapid's ``vel`` is ``v_ini``.
3. The planner (``tpAddLine``) makes one segment per move with length ``d_tot``; its speed is
   capped at ``length / (1.02 cycle)`` (sample rate) and at ``[TRAJ] MAX_LINEAR_VELOCITY`` (not for
   pure rotary moves).
4. Consecutive segments that move a rotary axis are never joined tangentially nor by a blend arc
   (``tpSetupTangent`` and ``tpCheckBlendArcType`` both refuse rotary motion): they end in a
   *parabolic* blend. Each such segment plans a trapezoid from its own current speed to rest at
   its end with *half* its acceleration (``tcGetTangentialMaxAccel``: the two overlapping segments
   share the limit); once it is on its final deceleration and slower than its blend speed
   (``tpComputeBlendVelocity``), the next segment starts and runs at the same time, its target
   speed ramped by the progress of the current one's deceleration (``tpUpdateBlend``). A feed
   block next to a rapid stops (``handleModeChange``). So the speed a short block reaches is
   about ``sqrt(a/2 L)``: that, not the programmed feed, sets the pace of a program of short
   five-axis blocks.
5. Everything runs at the servo period (1 ms), with the segment end split inside a cycle
   (``checkEndCondition``, ``tpHandleSplitCycle``).

Only what camsmooth's programs use is modelled: straight moves (G00, G01) in G93 or G94, the
parabolic blend of step 4 and the stop of a mode change; moves without rotary motion are
modelled with the same parabolic blend (LinuxCNC would join them tangentially or by an arc, which
is faster), so the model is conservative there. The ``G64 P`` tolerance caps the blend speed at
``2 sqrt(a/2 P / cos(theta))`` for corners, which camsmooth's near-collinear blocks do not reach.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from camsmooth.controller.blocks import tool_tips
from camsmooth.machine.kinematics import Machine
from camsmooth.smoothing.feed import axis_limits

__all__ = ["LinuxCNCPlanner", "Segments", "canon_segments", "SERVO_PERIOD_S", "LINUXCNC_SENSE", "linuxcnc_sense"]

#: per machine kind, the sign of each rotary axis value LinuxCNC is given against camsmooth's
#: (``Machine.rotary`` order). camsmooth's angles are the tool's rotation relative to the workpiece
#: (ISO 841); LinuxCNC's trt kinematics (xyzac-trt, xyzbc-trt) take a table axis' value as the
#: table's own rotation, the opposite turn: joints = r + Rx(a) Rz(c) (pos - r) (xyzac) or
#: r + Ry(b) Rz(c) (pos - r) (xyzbc), against camsmooth's X = c + Rx(-A) Rz(-C) (CL - c), so
#: a = -A, c = -C (b = -B) with r = the table centre. A head axis turns the tool: no change.
LINUXCNC_SENSE: dict[str, tuple[float, float]] = {"AB-head": (1.0, 1.0), "AC-table": (-1.0, -1.0),
                                                  "BC-table": (-1.0, -1.0), "BC-head-table": (1.0, -1.0)}


def linuxcnc_sense(machine: Machine) -> np.ndarray:
    """(2,) the signs LINUXCNC_SENSE gives the machine's rotary axes (1, 1 for an unknown kind)."""
    return np.array(LINUXCNC_SENSE.get(getattr(machine, "kind", "AB-head"), (1.0, 1.0)))

#: LinuxCNC's usual servo (and trajectory) period, s
SERVO_PERIOD_S = 0.001
#: tp_types.h: a segment lasts at least this many cycles
_MIN_SEGMENT_CYCLES = 1.02
#: tp_types.h / blendmath.h epsilons
_POS_EPSILON = 1e-12
_VEL_EPSILON = 1e-8
_TIME_EPSILON = 1e-12
#: tp_types.h: corners closer to straight than this (rad) are not capped by the tolerance
_MIN_ARC_ANGLE = 1e-3
#: emccanon.cc: a move shorter than this on an axis does not move it
_TINY = 1e-7


@dataclass(frozen=True, kw_only=True)
class Segments:
    """What LinuxCNC's canonical layer hands the planner, one segment per block.

    length: (M,) the segment's length (mm of XYZ travel; deg for a pure rotary move); reqvel: (M,)
    requested speed along it (mm/s or deg/s); maxvel: (M,) its largest speed from the axis limits
    and the sample rate; acc: (M,) its acceleration limit; rapid: (M,) bool; pure_rotary: (M,)
    bool; stop_after: (M,) bool, the segment ends at rest (a mode change or the program's end);
    direction: (M, 3) unit XYZ direction (0 for a pure rotary move); tolerance: the ``G64 P``
    blending tolerance (mm, 0 for none).
    """

    length: np.ndarray
    reqvel: np.ndarray
    maxvel: np.ndarray
    acc: np.ndarray
    rapid: np.ndarray
    pure_rotary: np.ndarray
    stop_after: np.ndarray
    direction: np.ndarray
    tolerance: float = 0.0


def _limits(machine: Machine) -> tuple[np.ndarray, np.ndarray]:
    """(vmax, amax) per joint X Y Z A B in program units (mm/s, mm/s^2, deg/s, deg/s^2)."""
    vmax, amax, _ = axis_limits(machine)
    deg = np.array([1.0, 1.0, 1.0, 180.0 / np.pi, 180.0 / np.pi])
    return vmax * deg, amax * deg


def canon_segments(start: np.ndarray, joints: np.ndarray, rapid: np.ndarray, fword: np.ndarray,
                   inverse_time: np.ndarray, machine: Machine, *, servo_period: float = SERVO_PERIOD_S,
                   v_limit: float | None = None, tolerance: float = 0.0) -> Segments:
    """The segments LinuxCNC makes of straight moves (module docstring, steps 1-3).

    start: (5,) joints before the first move; joints: (M, 5) X Y Z (mm) A B (deg) at the end of
    each move, as written in the program; rapid: (M,) G00; fword: (M,) the F in force (1/min in
    G93, mm/min in G94; ignored for rapids); inverse_time: (M,) G93 in force. v_limit: [TRAJ]
    MAX_LINEAR_VELOCITY (mm/s); None takes the fastest linear axis; tolerance: ``G64 P`` (mm).
    """
    vmax, amax = _limits(machine)
    q = np.vstack([np.asarray(start, float)[None, :], np.asarray(joints, float)])
    d = np.abs(np.diff(q, axis=0))
    d[d < _TINY] = 0.0
    lin = np.linalg.norm(d[:, :3], axis=1)
    ang = np.linalg.norm(d[:, 3:], axis=1)
    pure_rot = (lin == 0) & (ang > 0)
    dtot = np.where(pure_rot, ang, lin)
    # emccanon: only the axes of the move's kind count for a pure move, all of them for a combined
    # one (the linear distance sets the length)
    use = np.ones_like(d, bool)
    use[pure_rot, :3] = False
    use[(lin > 0) & (ang == 0), 3:] = False
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = np.where(use & (d > 0), d / vmax, 0.0).max(axis=1)
        ta = np.where(use & (d > 0), d / amax, 0.0).max(axis=1)
        v_ini = np.where(tv > 0, dtot / tv, np.inf)
        acc = np.where(ta > 0, dtot / ta, np.inf)
    fword = np.asarray(fword, float)
    rate = np.where(np.asarray(inverse_time, bool), dtot * fword / 60.0, fword / 60.0)
    rapid = np.asarray(rapid, bool)
    reqvel = np.where(rapid, v_ini, np.minimum(rate, v_ini))
    vlim = float(np.max(vmax[:3])) if v_limit is None else float(v_limit)
    maxvel = np.minimum(v_ini, dtot / (servo_period * _MIN_SEGMENT_CYCLES))
    maxvel = np.where(pure_rot, maxvel, np.minimum(maxvel, vlim))
    stop = np.r_[rapid[1:] != rapid[:-1], True]
    lin_d = np.diff(q[:, :3], axis=0)
    direction = np.where((lin > 0)[:, None], lin_d / np.maximum(lin, 1e-300)[:, None], 0.0)
    return Segments(length=dtot, reqvel=reqvel, maxvel=maxvel, acc=acc, rapid=rapid, pure_rotary=pure_rot,
                    stop_after=stop, direction=direction, tolerance=float(tolerance))


@njit(cache=True)
def _trapezoid_vel(a: float, dx: float, v_final: float, v: float, dt: float) -> float:  # pragma: no cover
    """blendmath.c findTrapezoidalDesiredVel: the speed that still stops (reaches v_final) at dx."""
    half = a * dt * 0.5
    disc = v_final * v_final + a * (2.0 * dx - v * dt) + half * half
    return 0.0 if disc < 0 else -half + np.sqrt(disc)


@njit(cache=True)
def _update(k: int, tv_cap: float, length: np.ndarray, reqvel: np.ndarray, maxvel: np.ndarray, acc_h: np.ndarray,
            progress: np.ndarray, vel: np.ndarray, dt_k: np.ndarray, blending_next: np.ndarray,
            vel_at_blend_start: np.ndarray, on_final_decel: np.ndarray, splitting: np.ndarray,
            dt: float) -> None:  # pragma: no cover - compiled
    """tpUpdateCycle on segment k (trapezoidal, final speed 0: parabolic or stop), then
    tpCheckEndCondition."""
    if not blending_next[k]:
        vel_at_blend_start[k] = vel[k]
    tv = min(reqvel[k], maxvel[k], tv_cap)
    a = acc_h[k]
    cyc = dt_k[k]
    dx = length[k] - progress[k]
    maxnew = _trapezoid_vel(a, dx, 0.0, vel[k], cyc)
    newvel = min(maxnew, tv)
    acc = (newvel - vel[k]) / max(cyc, _TIME_EPSILON)
    acc = min(max(acc, -a), a)
    # tcUpdateDistFromAccel
    v_next = vel[k] + acc * cyc
    if v_next < 0.0:
        v_next = 0.0
        if dx < vel[k] * cyc:
            progress[k] = length[k]
    else:
        progress[k] = min(progress[k] + (v_next + vel[k]) * 0.5 * cyc, length[k])
    vel[k] = v_next
    on_final_decel[k] = abs(maxnew - vel[k]) < _VEL_EPSILON and acc < 0.0
    # checkEndCondition with v_f = 0
    rem = length[k] - progress[k]
    if rem <= _POS_EPSILON:
        t_left = _TIME_EPSILON / 2.0
    else:
        v_avg = vel[k] / 2.0
        if v_avg > _VEL_EPSILON:
            t_left = max(_TIME_EPSILON / 2.0, rem / v_avg)
            # the end speed 0 may need more than a: then the stop is reached sooner at a
            if vel[k] / t_left > a:
                disc = vel[k] * vel[k] - 2.0 * a * rem
                t_left = (vel[k] - np.sqrt(max(disc, 0.0))) / a
        else:
            t_left = 1e300
    if t_left < dt:
        splitting[k] = True
        dt_k[k] = 0.0 if t_left < _TIME_EPSILON else t_left


@njit(cache=True)
def _run(length: np.ndarray, reqvel: np.ndarray, maxvel: np.ndarray, acc: np.ndarray, parabolic: np.ndarray,
         direction: np.ndarray, tolerance: float, dt: float,
         max_cycles: int) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """tpRunCycle until the queue is empty: per segment the cycle it became the head of the queue
    (active) and the cycle at whose end it was removed (done)."""
    n = len(length)
    progress = np.zeros(n)
    vel = np.zeros(n)
    dt_k = np.full(n, dt)
    blending_next = np.zeros(n, np.bool_)
    is_blending = np.zeros(n, np.bool_)
    vel_at_blend_start = np.zeros(n)
    on_final_decel = np.zeros(n, np.bool_)
    splitting = np.zeros(n, np.bool_)
    blend_vel = np.zeros(n)
    acc_h = np.empty(n)
    for k in range(n):
        half = parabolic[k] or (k > 0 and parabolic[k - 1])
        acc_h[k] = acc[k] * (0.5 if half else 1.0)
    start = np.full(n, -1, np.int64)
    done = np.full(n, -1, np.int64)
    i = 0
    cyc = 0
    while i < n and cyc < max_cycles:
        tc = i
        nx = i + 1 if i + 1 < n else -1
        if start[tc] < 0:
            start[tc] = cyc
            blending_next[tc] = False
            on_final_decel[tc] = False
        if splitting[tc]:
            progress[tc] = length[tc]
            if nx >= 0 and parabolic[tc]:
                dt_k[nx] = dt
                _update(nx, np.inf, length, reqvel, maxvel, acc_h, progress, vel, dt_k, blending_next,
                        vel_at_blend_start, on_final_decel, splitting, dt)
            done[tc] = cyc
            i += 1
        else:
            dt_k[tc] = dt
            _update(tc, np.inf, length, reqvel, maxvel, acc_h, progress, vel, dt_k, blending_next,
                    vel_at_blend_start, on_final_decel, splitting, dt)
            if nx >= 0 and parabolic[tc]:
                # tpComputeBlendVelocity (finalized segments; no tolerance)
                v_this = min(np.sqrt(acc_h[tc] * length[tc]), min(reqvel[tc], maxvel[tc]))
                v_next = min(np.sqrt(acc_h[nx] * length[nx]), min(reqvel[nx], maxvel[nx]))
                t_reach = min(length[tc] / max(v_this, 1e-300), length[nx] / max(v_next, 1e-300))
                t_blend = min(t_reach, max(v_this / acc_h[tc], v_next / acc_h[nx]))
                blend_vel[tc] = min(v_this, t_blend * acc_h[tc])
                blend_vel[nx] = min(v_next, t_blend * acc_h[nx])
                if tolerance > 0.0:  # G64 P: the corner's blend speed (tpComputeBlendVelocity)
                    dot = 0.0
                    for j in range(3):
                        dot += direction[tc, j] * direction[nx, j]
                    cos_theta = np.cos(np.arccos(min(max(-dot, -1.0), 1.0)) / 2.0)
                    if cos_theta > np.sin(_MIN_ARC_ANGLE):
                        v_tol = 2.0 * np.sqrt(acc_h[tc] * tolerance / cos_theta)
                        blend_vel[tc] = min(blend_vel[tc], v_tol)
                        blend_vel[nx] = min(blend_vel[nx], v_tol)
                # tcIsBlending
                if on_final_decel[tc] and vel[tc] < blend_vel[tc]:
                    blending_next[tc] = True
                if blending_next[tc]:
                    dv = vel_at_blend_start[tc] - vel[tc]
                    vs = max(vel_at_blend_start[tc], _VEL_EPSILON)
                    prog = max(min(dv / vs, 1.0), 0.0)
                    scale = vel_at_blend_start[tc] / max(blend_vel[tc], 1e-300)
                    is_blending[nx] = True
                    dt_k[nx] = dt
                    _update(nx, prog * blend_vel[nx] * scale, length, reqvel, maxvel, acc_h, progress, vel, dt_k,
                            blending_next, vel_at_blend_start, on_final_decel, splitting, dt)
        cyc += 1
    return start, done


@dataclass(frozen=True, kw_only=True)
class BlockTimes:
    """When LinuxCNC runs each block: start (s, the cycle it became the executing segment) and
    end (s, the end of the cycle it finished in), both from the first block's start."""

    start: np.ndarray
    end: np.ndarray


@dataclass(frozen=True, kw_only=True)
class LinuxCNCPlanner:
    """LinuxCNC 2.9's trajectory planner for straight moves (module docstring).

    servo_period: s; v_limit: [TRAJ] MAX_LINEAR_VELOCITY in mm/s (None: the fastest linear
    axis, as camsmooth's simulation configuration sets it); tolerance: the program's ``G64 P``
    (mm; camsmooth writes half the user's tolerance, camsmooth.io.gcode).
    """

    servo_period: float = SERVO_PERIOD_S
    v_limit: float | None = None
    tolerance: float = 0.0
    name: str = "linuxcnc"

    def segments(self, machine: Machine, start: np.ndarray, joints: np.ndarray, rapid: np.ndarray,
                 fword: np.ndarray, inverse_time: np.ndarray) -> Segments:
        """``canon_segments`` with this planner's servo period and speed limit."""
        return canon_segments(start, joints, rapid, fword, inverse_time, machine, servo_period=self.servo_period,
                              v_limit=self.v_limit, tolerance=self.tolerance)

    def row_times(self, machine: Machine, q_blocks: np.ndarray, block_time: np.ndarray, entry_q: np.ndarray,
                  entry_time: float) -> np.ndarray:
        """End times (s from the row's first point) of the blocks of one row as LinuxCNC runs them:
        the row is entered from rest at ``entry_q`` by a feed move of ``entry_time`` s onto
        q_blocks[0] (blended into the row, as LinuxCNC does between two feed moves), then one G93
        block per further point with the commanded block times ``block_time`` (s), and ends at
        rest (the rapid that follows). Joints X Y Z mm A B rad; the values are rounded as the
        G-code writer writes them (4 decimals, mm and degrees)."""
        def written(q: np.ndarray) -> np.ndarray:
            q = np.atleast_2d(np.asarray(q, float))
            return np.round(np.column_stack([q[:, :3], np.degrees(q[:, 3:])]), 4)

        times = np.maximum(np.r_[entry_time, np.asarray(block_time, float)], 1e-6)
        k = len(times)
        seg = self.segments(machine, written(entry_q)[0], written(q_blocks), np.zeros(k, bool), 60.0 / times,
                            np.ones(k, bool))
        bt = self.run(seg)
        return bt.end[1:] - bt.end[0]

    def safe_block_times(self, machine: Machine, q_blocks: np.ndarray, block_time: np.ndarray,
                         tolerance: float) -> np.ndarray:
        """The block times (s) to command so that LinuxCNC's parabolic blends keep the tool tip
        within ``tolerance`` (mm) of the blocks' tip path: at least ``block_time``.

        Why: LinuxCNC blends all five joints at once between two rotary blocks, from the moment
        the first one, decelerating at a/2, is slower than the blend speed v_b: the joints then
        follow a parabola from J - d w_1 to J + d w_2 (J the corner, w the joint change per mm of
        the block's XYZ length, d = v_b^2 / a, a the smaller segment acceleration), whose
        middle lies (d / 4) (w_2 - w_1) from J in joint space. Its tip error grows with the
        pivot lever; ``G64 P`` bounds only the XYZ part. So the commanded speed of both blocks is
        capped at sqrt(a d_max) with d_max the d whose tip error across the path is
        ``tolerance`` (the tip error is linear in d: the Jacobian of the forward kinematics,
        evaluated by a finite step). Joints X Y Z mm A B rad."""
        q = np.asarray(q_blocks, float)
        bt = np.asarray(block_time, float).copy()
        if len(q) < 3:
            return bt
        dq = np.diff(q, axis=0)
        L = np.linalg.norm(dq[:, :3], axis=1)
        ok = L > 0
        w = np.where(ok[:, None], dq / np.maximum(L, 1e-300)[:, None], 0.0)
        jq = q[1:-1]  # corners between block k and k + 1
        step = 0.01  # mm of d for the finite step (the error is linear in d)
        dw = 0.25 * (w[1:] - w[:-1])
        tip0 = tool_tips(machine, jq)
        err = (tool_tips(machine, jq + step * dw) - tip0) / step
        tangent = tool_tips(machine, jq + step * w[1:]) - tool_tips(machine, jq - step * w[:-1])
        tangent /= np.maximum(np.linalg.norm(tangent, axis=1), 1e-300)[:, None]
        err -= np.sum(err * tangent, axis=1)[:, None] * tangent
        per_d = np.linalg.norm(err, axis=1)  # mm of tip error per mm of d
        vmax, amax = _limits(machine)
        deg = np.r_[1.0, 1.0, 1.0, 180.0 / np.pi, 180.0 / np.pi]
        d_prog = np.abs(dq) * deg
        with np.errstate(divide="ignore", invalid="ignore"):
            acc = np.where(L > 0, L / np.max(np.where(d_prog > 0, d_prog / amax, 0.0), axis=1), np.inf)
        a = np.minimum(acc[1:], acc[:-1])  # the blend's d uses the slower of the two decelerations
        with np.errstate(divide="ignore"):
            d_max = np.where(per_d > 0, tolerance / per_d, np.inf)
        v_cap = np.sqrt(a * d_max)
        ok_corner = ok[1:] & ok[:-1]
        for side in (0, 1):  # the block before the corner and the block after it
            k = np.flatnonzero(ok_corner) + side
            v = v_cap[ok_corner]
            bt[k] = np.maximum(bt[k], L[k] / v)
        return bt

    def run(self, seg: Segments) -> BlockTimes:
        """Start and end time of every segment (s); a segment of zero length (LinuxCNC drops it)
        takes no time."""
        moving = seg.length > 0
        if not moving.all():  # run the moving segments; a dropped one ends when the one before it does
            idx = np.flatnonzero(moving)
            inner = self.run(Segments(**{f: (v[idx] if isinstance(v, np.ndarray) else v)
                                         for f, v in vars(seg).items()}))
            before = np.searchsorted(idx, np.arange(len(moving)), side="right") - 1
            end = np.where(before >= 0, np.r_[inner.end, 0.0][before], 0.0)
            start = np.where(moving, np.r_[inner.start, 0.0][np.maximum(before, 0)], end)
            return BlockTimes(start=start, end=end)
        parabolic = ~seg.stop_after
        expect = float(np.sum(seg.length / np.maximum(np.minimum(seg.reqvel, seg.maxvel), 1e-9)))
        max_cycles = int(10 * expect / self.servo_period + 10 * len(seg.length) + 1e5)
        start, done = _run(seg.length.astype(float), seg.reqvel.astype(float), seg.maxvel.astype(float),
                           seg.acc.astype(float), parabolic, seg.direction.astype(float), float(seg.tolerance),
                           self.servo_period, max_cycles)
        if (done < 0).any():
            raise RuntimeError("LinuxCNC planner model did not finish the program (a segment that cannot move)")
        return BlockTimes(start=start * self.servo_period, end=(done + 1) * self.servo_period)
