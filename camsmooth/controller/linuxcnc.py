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
   (``tpComputeBlendVelocity``), the next segment starts and runs at the same time, accelerating
   at its own half acceleration from that cycle on (``tpUpdateBlend`` ramps the next segment's
   ``target_vel``, but ``tpCalculateTrapezoidalAccel`` takes ``tpGetRealTargetVel``, which is
   ``reqvel`` for a move not synchronized to the spindle). A feed block next to a rapid stops
   (``handleModeChange``). The halving follows a segment's OWN end: the last block of a row, which
   ends at rest, accelerates at its whole acceleration, also while the block before it blends into
   it (measured on the headless LinuxCNC, dome rows of ``benchmarks/bench_controller.py``: with
   it halved the model put the tip up to 1.3 um nearer the path than LinuxCNC in that last blend
   and the row 0.4-0.7% longer). So the speed a short block reaches is about ``sqrt(a/2 L)``: that,
   not the programmed feed, sets the pace of a program of short five-axis blocks.
5. Everything runs at the servo period (1 ms), with the segment end split inside a cycle
   (``checkEndCondition``, ``tpHandleSplitCycle``).

Only what camsmooth's programs use is modelled: straight moves (G00, G01) in G93 or G94, the
parabolic blend of step 4 and the stop of a mode change; moves without rotary motion are
modelled with the same parabolic blend (LinuxCNC would join them tangentially or by an arc, which
is faster), so the model is conservative there. The ``G64 P`` tolerance caps the blend speed at
``2 sqrt(a/2 P / cos(theta))`` (theta half the turn between the two segments' XYZ directions):
in the joints of a five-axis row consecutive blocks turn by a few degrees, so at a small P this
cap, not the blocks, sets the pace (camsmooth.constants.PATH_TOLERANCE_SHARE; where every move
turns a rotary axis P is PARABOLIC_PATH_TOLERANCE_SHARE of the tolerance, ``blend_tolerance``). A
stop after a segment (a mode change, ``G61`` for a row's entry move: ``LinuxCNCPlanner.entry_stop``)
ends it at rest and starts the next from rest.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from camsmooth.constants import PARABOLIC_PATH_TOLERANCE_SHARE, PATH_TOLERANCE_SHARE
from camsmooth.controller.blocks import _row_bounds, block_reach
from camsmooth.machine.kinematics import Machine, axis_limits

__all__ = ["LinuxCNCPlanner", "blend_tolerance", "Segments", "canon_segments", "least_row_times", "least_block_times",
           "SERVO_PERIOD_S", "linuxcnc_sense"]

def linuxcnc_sense(machine: Machine) -> np.ndarray:
    """(2,) the sign of each rotary axis value LinuxCNC is given against camsmooth's
    (``Machine.rotary`` order; ``Machine.linuxcnc_sense``). camsmooth's angles are the tool's
    rotation relative to the workpiece (ISO 841); LinuxCNC's trt kinematics (xyzac-trt,
    xyzbc-trt) take a table axis' value as the table's own rotation, the opposite turn:
    joints = r + Rx(a) Rz(c) (pos - r) (xyzac) or r + Ry(b) Rz(c) (pos - r) (xyzbc), against
    camsmooth's X = c + Rx(-A) Rz(-C) (CL - c), so a preset's a = -A, c = -C (b = -B) with r the
    table centre; a head axis turns the tool: no change. A chain given explicitly is written as
    described (1, 1)."""
    return np.asarray(machine.linuxcnc_sense, float)


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


def _move_limits(dq: np.ndarray, vmax: np.ndarray, amax: np.ndarray, servo_period: float, vlim: float
                 ) -> tuple[np.ndarray, ...]:
    """Steps 2-3 of the module docstring for straight moves dq (..., 5) (X Y Z mm A B deg, signed):
    length (mm, deg for a pure rotary move), v_ini, acceleration, largest speed (sample rate and
    [TRAJ] MAX_LINEAR_VELOCITY ``vlim`` included), pure-rotary flag and unit XYZ direction."""
    d = np.abs(dq)
    d[d < _TINY] = 0.0
    lin = np.linalg.norm(d[..., :3], axis=-1)
    ang = np.linalg.norm(d[..., 3:], axis=-1)
    pure_rot = (lin == 0) & (ang > 0)
    dtot = np.where(pure_rot, ang, lin)
    # emccanon: only the axes of the move's kind count for a pure move, all of them for a combined
    # one (the linear distance sets the length)
    use = np.ones_like(d, bool)
    use[pure_rot, :3] = False
    use[(lin > 0) & (ang == 0), 3:] = False
    with np.errstate(divide="ignore", invalid="ignore"):
        tv = np.where(use & (d > 0), d / vmax, 0.0).max(axis=-1)
        ta = np.where(use & (d > 0), d / amax, 0.0).max(axis=-1)
        v_ini = np.where(tv > 0, dtot / tv, np.inf)
        acc = np.where(ta > 0, dtot / ta, np.inf)
    maxvel = np.minimum(v_ini, dtot / (servo_period * _MIN_SEGMENT_CYCLES))
    maxvel = np.where(pure_rot, maxvel, np.minimum(maxvel, vlim))
    direction = np.where((lin > 0)[..., None], dq[..., :3] / np.maximum(lin, 1e-300)[..., None], 0.0)
    return dtot, v_ini, acc, maxvel, pure_rot, direction


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
    vlim = float(np.max(vmax[:3])) if v_limit is None else float(v_limit)
    dtot, v_ini, acc, maxvel, pure_rot, direction = _move_limits(np.diff(q, axis=0), vmax, amax, servo_period, vlim)
    fword = np.asarray(fword, float)
    rate = np.where(np.asarray(inverse_time, bool), dtot * fword / 60.0, fword / 60.0)
    rapid = np.asarray(rapid, bool)
    reqvel = np.where(rapid, v_ini, np.minimum(rate, v_ini))
    stop = np.r_[rapid[1:] != rapid[:-1], True]
    return Segments(length=dtot, reqvel=reqvel, maxvel=maxvel, acc=acc, rapid=rapid, pure_rotary=pure_rot,
                    stop_after=stop, direction=direction, tolerance=float(tolerance))


@njit(cache=True)
def _trapezoid_vel(a: float, dx: float, v_final: float, v: float, dt: float) -> float:  # pragma: no cover
    """blendmath.c findTrapezoidalDesiredVel: the speed that still stops (reaches v_final) at dx."""
    half = a * dt * 0.5
    disc = v_final * v_final + a * (2.0 * dx - v * dt) + half * half
    return 0.0 if disc < 0 else -half + np.sqrt(disc)


@njit(cache=True)
def _update(k: int, length: np.ndarray, reqvel: np.ndarray, maxvel: np.ndarray, acc_h: np.ndarray,
            progress: np.ndarray, vel: np.ndarray, dt_k: np.ndarray, on_final_decel: np.ndarray,
            splitting: np.ndarray, dt: float) -> None:  # pragma: no cover - compiled
    """tpUpdateCycle on segment k (trapezoidal, final speed 0: parabolic or stop), then
    tpCheckEndCondition."""
    tv = min(reqvel[k], maxvel[k])
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
         max_cycles: int) -> tuple[np.ndarray, ...]:  # pragma: no cover - compiled
    """tpRunCycle until the queue is empty: per segment the cycle it became the head of the queue
    (active) and the cycle at whose end it was removed (done); per cycle, at its end, the head
    segment and the progress (length units) of it and of the segment after it (which moves at the
    same time while the head blends into it)."""
    n = len(length)
    progress = np.zeros(n)
    vel = np.zeros(n)
    dt_k = np.full(n, dt)
    blending_next = np.zeros(n, np.bool_)
    on_final_decel = np.zeros(n, np.bool_)
    splitting = np.zeros(n, np.bool_)
    blend_vel = np.zeros(n)
    acc_h = np.empty(n)
    for k in range(n):
        # halved by the segment's own parabolic end only (module docstring, step 4)
        acc_h[k] = acc[k] * (0.5 if parabolic[k] else 1.0)
    start = np.full(n, -1, np.int64)
    done = np.full(n, -1, np.int64)
    cap = 1024
    head = np.full(cap, n, np.int64)
    head_progress = np.zeros(cap)
    next_progress = np.zeros(cap)
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
                _update(nx, length, reqvel, maxvel, acc_h, progress, vel, dt_k, on_final_decel, splitting, dt)
            done[tc] = cyc
            i += 1
        else:
            dt_k[tc] = dt
            _update(tc, length, reqvel, maxvel, acc_h, progress, vel, dt_k, on_final_decel, splitting, dt)
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
                    # tpUpdateBlend ramps the next segment's target_vel with the blend's progress,
                    # but tpCalculateTrapezoidalAccel takes tpGetRealTargetVel, which is reqvel for
                    # a move not synchronized to the spindle: the next segment accelerates at its
                    # own (half) acceleration from the blend's first cycle
                    dt_k[nx] = dt
                    _update(nx, length, reqvel, maxvel, acc_h, progress, vel, dt_k,
                            on_final_decel, splitting, dt)
        if cyc == cap:  # grow the per-cycle record
            cap *= 2
            head = np.concatenate((head, np.full(cap - cyc, n, np.int64)))
            head_progress = np.concatenate((head_progress, np.zeros(cap - cyc)))
            next_progress = np.concatenate((next_progress, np.zeros(cap - cyc)))
        head[cyc] = i
        if i < n:
            head_progress[cyc] = progress[i]
            if i + 1 < n:
                next_progress[cyc] = progress[i + 1]
        cyc += 1
    return start, done, head[:cyc], head_progress[:cyc], next_progress[:cyc]


@njit(cache=True)
def _solo(length: float, vcap: float, acc_h: float) -> tuple[float, float]:  # pragma: no cover - compiled
    """A segment on its own from rest to rest at acceleration acc_h, speed at most vcap: its time
    (s) and top speed (the trapezoid of ``_update``, without the servo cycles)."""
    if length <= 0.0:
        return 0.0, 0.0
    v_peak = np.sqrt(acc_h * length)
    if v_peak <= vcap:
        return 2.0 * length / v_peak, v_peak
    return length / vcap + vcap / acc_h, vcap


@njit(cache=True)
def _lag(lp: float, vp: float, ap: float, tp: float, dp: np.ndarray, ln: float, vn: float, an: float,
         dn: np.ndarray, tolerance: float) -> float:  # pragma: no cover - compiled
    """Time (s) from the start of segment p to the start of the segment n after it: p runs on its
    own (time tp, top speed vp) and n starts once p decelerates below the blend speed of
    ``_run`` (tpComputeBlendVelocity, the ``G64 P`` cap included)."""
    t_reach = min(lp / max(vp, 1e-300), ln / max(vn, 1e-300))
    t_blend = min(t_reach, max(vp / ap, vn / an))
    bv = min(vp, t_blend * ap)
    if tolerance > 0.0:
        dot = dp[0] * dn[0] + dp[1] * dn[1] + dp[2] * dn[2]
        cos_theta = np.cos(np.arccos(min(max(-dot, -1.0), 1.0)) / 2.0)
        if cos_theta > np.sin(_MIN_ARC_ANGLE):
            bv = min(bv, 2.0 * np.sqrt(ap * tolerance / cos_theta))
    return tp - bv / ap


@njit(cache=True)
def _place_row(ok: np.ndarray, length: np.ndarray, vcap: np.ndarray, acc_h: np.ndarray, direction: np.ndarray,
               entry: np.ndarray, entry_dir: np.ndarray, tolerance: float,
               dt: float) -> tuple[float, np.ndarray]:  # pragma: no cover - compiled
    """The block ends of one row of n points that end its last block soonest on the planner
    (``LinuxCNCPlanner.block_ends``). ok (n, K): block from point i over k + 1 points allowed;
    length, vcap, acc_h (n, K) and direction (n, K, 3) of that block's segment; entry: (3,)
    length, vcap, acc_h of the row's entry move, entry_dir its direction.

    The row as a chain of parabolic blends (``_run``): each segment runs its own trapezoid, the
    next starts once it decelerates below the blend speed (``_lag``) but not before the segment
    before it has ended (two segments move at once), on a servo cycle. A state is the last block
    (its end point and its points); it keeps the earliest start of that block and, for it, when the
    block before it ends. Returns the last block's end (s from the entry move's start) and the
    block ends (indices, 0 and n - 1 included)."""
    n, K = ok.shape
    big = 1e300
    start = np.full((n, K), big)
    before_end = np.full((n, K), big)
    back = np.full((n, K), -1, np.int64)
    T = np.zeros((n, K))
    V = np.zeros((n, K))
    for i in range(n):
        for k in range(K):
            if ok[i, k] and i + k + 1 <= n - 1:
                T[i, k], V[i, k] = _solo(length[i, k], vcap[i, k], acc_h[i, k])
    te, ve = _solo(entry[0], entry[1], entry[2])
    for k in range(min(K, n - 1)):
        if ok[0, k]:
            s = max(0.0, _lag(entry[0], ve, entry[2], te, entry_dir, length[0, k], V[0, k], acc_h[0, k],
                              direction[0, k], tolerance))
            start[k + 1, k] = np.ceil(s / dt - 1e-9) * dt
            before_end[k + 1, k] = te
    for j in range(1, n - 1):
        for k in range(K):
            if start[j, k] >= big:
                continue
            i = j - k - 1
            end_here = start[j, k] + T[i, k]
            for k2 in range(K):
                j2 = j + k2 + 1
                if j2 > n - 1:
                    break
                if not ok[j, k2]:
                    continue
                s = max(before_end[j, k], start[j, k] + _lag(length[i, k], V[i, k], acc_h[i, k], T[i, k],
                                                             direction[i, k], length[j, k2], V[j, k2], acc_h[j, k2],
                                                             direction[j, k2], tolerance))
                s = np.ceil(s / dt - 1e-9) * dt
                if s < start[j2, k2] - 1e-12 or (s < start[j2, k2] + 1e-12 and end_here < before_end[j2, k2]):
                    start[j2, k2] = s
                    before_end[j2, k2] = end_here
                    back[j2, k2] = k
    best = big
    bk = -1
    for k in range(min(K, n - 1)):
        if start[n - 1, k] < big:
            f = start[n - 1, k] + T[n - 2 - k, k]
            if f < best:
                best, bk = f, k
    ends = np.empty(n, np.int64)
    m = 0
    j, k = n - 1, bk
    ends[m] = j
    while j > 0 and k >= 0:
        pk = back[j, k]
        j = j - k - 1
        m += 1
        ends[m] = j
        k = pk
    return best, ends[:m + 1][::-1].copy()


def blend_tolerance(rows: np.ndarray, q: np.ndarray, tolerance: float,
                    parabolic_share: float = PARABOLIC_PATH_TOLERANCE_SHARE) -> float:
    """The blend tolerance (mm, LinuxCNC ``G64 P``) a program of the points q (N, 5), rows (N,), is
    written and timed with for the user's ``tolerance`` (mm); q: X Y Z mm (the joints in machine
    mode, the tool tip in TCP mode) and the rotary axes rad. ``parabolic_share`` of it (machine
    mode's PARABOLIC_PATH_TOLERANCE_SHARE, TCP mode's TCP_PARABOLIC_PATH_TOLERANCE_SHARE) where
    every move between two points of a row turns a rotary axis as written (4 decimals, deg):
    LinuxCNC joins those only by parabolic blends, whose path the block times hold (in either
    mode); else PATH_TOLERANCE_SHARE, the bound of the blend arc by which it may join two moves
    that turn none."""
    rows = np.asarray(rows)
    deg = np.round(np.degrees(np.asarray(q, float)[:, 3:]), 4)
    same_row = rows[1:] == rows[:-1]
    turns = np.any(deg[1:] != deg[:-1], axis=1)
    share = parabolic_share if bool(np.all(turns[same_row])) else PATH_TOLERANCE_SHARE
    return share * float(tolerance)


#: longest block (in points) the lower bound of ``least_row_times`` considers
LEAST_TIME_BLOCK_POINTS = 64


def least_row_times(machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, feed: np.ndarray,
                    tolerance: float, *, max_points: int = LEAST_TIME_BLOCK_POINTS,
                    end_offset: float = 0.0) -> np.ndarray:
    """A lower bound (s, per row in order of appearance) on the cut time of ANY program of straight
    blocks that LinuxCNC 2.9 can run through a row's points within ``tolerance`` (mm); with
    ``end_offset`` (mm), of any whose block ends' tool tips may sit that far off the points.

    Why it bounds: a block that moves a rotary axis is joined to its neighbours only by a
    parabolic blend (module docstring, step 4). Each segment then rises from rest and falls back
    to rest at half its acceleration a_s = L / max_i(|d_i| / a_i) (L its length, d_i the joint
    moves), overlapping only its two neighbours, so its share of the time is at least
    L / v >= 2 v / a_s, that is at least sqrt(2 max_i |d_i| / a_i) (a block that moves no rotary
    axis may be joined tangentially and gets no such term; a row's last block ramps at its whole
    acceleration, but from rest to rest and alone once the one before it is done: at least
    2 sqrt(max_i |d_i| / a_i), more than its term). It also lasts at least
    max_i |d_i| / vmax_i and its tip chord over the programmed feed (this term holds for a program
    whose tip keeps the feed: LinuxCNC's blends can take it past, camsmooth.controller.blocks.
    tip_speed_over, and a feed-bound row then runs a little under the bound, 0.5% on the saddle
    rows of benchmarks/bench_controller.py, unless held: SmoothOptions.hold_feed). The bound is
    the least sum of these over every choice of block ends among the row's points whose blocks keep the skipped
    tips within the WHOLE tolerance (``block_reach``): it credits the blends with no deviation and
    the blocks with the whole tolerance, and ignores the first acceleration and the last stop.
    Dynamic programming over the block ends, blocks of at most ``max_points`` points.

    Block ends off the points (camsmooth.controller.blocks.vertex_shift): the linear joints move
    the tip by a rotation, and a block interpolates its joints linearly, so moving its ends by at
    most e moves every point of its tip curve by at most e. A block that keeps the skipped tips
    within T with its ends moved keeps them within T + e with its ends on the points, so the
    bound takes the blocks ``block_reach`` allows at tolerance + end_offset, and shortens each
    block's tip chord and linear joint moves by 2 e.

    rows (N,); q (N, 5) X Y Z mm A B rad; tip (N, 3) mm (workpiece frame); feed (N,) mm/min, the
    programmed tip feed."""
    q = np.asarray(q, float)
    tip = np.asarray(tip, float)
    vmax, amax, _ = axis_limits(machine)
    ok = block_reach(machine, rows, q, tip, float(tolerance) + float(end_offset), max_points)
    return least_block_times(vmax, amax, rows, q, tip, feed, ok, max_points, slack=float(end_offset))


def least_block_times(vmax: np.ndarray, amax: np.ndarray, rows: np.ndarray, q: np.ndarray, tip: np.ndarray,
                      feed: np.ndarray, ok: np.ndarray, max_points: int = LEAST_TIME_BLOCK_POINTS,
                      slack: float = 0.0) -> np.ndarray:
    """The dynamic programme of ``least_row_times`` over given coordinates and allowed blocks: per
    row (s), the least sum over a choice of block ends of max(tip chord / feed, max_i |d_i| /
    vmax_i, sqrt(2 max_i |d_i| / amax_i) where a rotary coordinate moves). q (N, 5) the planned
    coordinates (X Y Z mm, the rotary axes rad: the joints in machine mode, the tool tip and the
    rotary axes in TCP mode); vmax, amax (5,) their limits (mm/s, mm/s^2, rad/s, rad/s^2); tip
    (N, 3) mm; feed (N,) mm/min; ok (N, K) bool, ``block_reach``'s layout (K >= max_points);
    slack mm: how far each block end may sit off its point (chords and linear moves 2 slack shorter)."""
    q = np.asarray(q, float)
    tip = np.asarray(tip, float)
    feed = np.asarray(feed, float) / 60.0
    starts, ends = _row_bounds(rows)
    out = np.zeros(len(starts))
    for r, (a, b) in enumerate(zip(starts, ends, strict=True)):
        best = np.full(b - a, np.inf)
        best[0] = 0.0
        for j in range(1, b - a):
            k = np.arange(1, min(max_points, j) + 1)
            i = j - k
            good = ok[a + i, k - 1]
            i = i[good]
            d = np.abs(q[a + j] - q[a + i])
            d[:, :3] = np.maximum(d[:, :3] - 2.0 * slack, 0.0)
            chord = np.maximum(np.linalg.norm(tip[a + j] - tip[a + i], axis=1) - 2.0 * slack, 0.0)
            # only a block that turns a rotary axis is bound to the parabolic blend
            rest = np.where(d[:, 3:].max(axis=1) > 0, np.sqrt(2.0 * (d / amax).max(axis=1)), 0.0)
            cost = np.maximum.reduce([chord / feed[a + j], (d / vmax).max(axis=1), rest])
            best[j] = np.min(best[i] + cost)
        out[r] = best[-1]
    return out


@dataclass(frozen=True, kw_only=True)
class BlockTimes:
    """When LinuxCNC runs each block: start (s, the cycle it became the executing segment) and
    end (s, the end of the cycle it finished in), both from the first block's start; and where it
    is at the end of every servo cycle k (time (k + 1) x period): head[k], the executing segment
    (M past the last), with head_fraction[k] of it done, and following_fraction[k] done of the
    segment following[k] that moves at the same time while the head blends into it (the next
    one LinuxCNC did not drop). Position at the end of cycle k: the start of segment head[k] plus
    those fractions of the two segments."""

    start: np.ndarray
    end: np.ndarray
    head: np.ndarray
    head_fraction: np.ndarray
    following: np.ndarray
    following_fraction: np.ndarray

    def positions(self, start: np.ndarray, joints: np.ndarray) -> np.ndarray:
        """(K, D) the commanded position at the end of every servo cycle, for segments from
        ``start`` (D,) through ``joints`` (M, D) (any units; LinuxCNC interpolates each segment
        linearly in its joints)."""
        q = np.vstack([np.asarray(start, float)[None, :], np.asarray(joints, float)])
        d = np.vstack([np.diff(q, axis=0), np.zeros((2, q.shape[1]))])
        h = self.head
        return (q[np.minimum(h, len(q) - 1)] + self.head_fraction[:, None] * d[h]
                + self.following_fraction[:, None] * d[self.following])


@dataclass(frozen=True, kw_only=True)
class LinuxCNCPlanner:
    """LinuxCNC 2.9's trajectory planner for straight moves (module docstring).

    servo_period: s; v_limit: [TRAJ] MAX_LINEAR_VELOCITY in mm/s (None: the fastest linear
    axis, as camsmooth's simulation configuration sets it); tolerance: the program's ``G64 P``
    (mm; the program's: camsmooth.controller.blend_tolerance, which camsmooth.post.writer writes);
    entry_stop: each row's entry move ends at rest (the writer's ``G61`` for it: the first block
    then starts from rest, and no blend joins the entry's corner, which the block times could
    not hold once P exceeds the tolerance).
    """

    servo_period: float = SERVO_PERIOD_S
    v_limit: float | None = None
    tolerance: float = 0.0
    entry_stop: bool = False
    name: str = "linuxcnc"
    title: str = "LinuxCNC"

    def block_ends(self, machine: Machine, q: np.ndarray, t_opt: np.ndarray, ok: np.ndarray, entry_q: np.ndarray,
                   entry_time: float) -> np.ndarray | None:
        """The block ends of one row (indices into its points, the first and last included) that
        LinuxCNC runs soonest, among the blocks ``ok`` allows: (n, K) bool, block from point i over
        k + 1 points (camsmooth.controller.blocks.block_reach). q (n, 5) X Y Z mm A B rad; t_opt (n,)
        s, the time law whose differences the G93 blocks command; the row is entered from rest at
        entry_q by a feed move of entry_time s, as in ``row_run``. Dynamic programme over the block
        ends on this model's chain of parabolic blends (``_place_row``: each segment's own trapezoid
        at half its acceleration, the row's last at its whole, the next started at the blend speed,
        two segments at a time): a row of short blocks runs at sqrt(a/2 L) per block, and a shorter
        block after a longer one waits, so neither the fewest blocks nor the longest first is the
        fastest choice. None where no chain of moving blocks goes through the row (a repeated
        point)."""
        q = np.asarray(q, float)
        t_opt = np.asarray(t_opt, float)
        n, K = np.asarray(ok).shape
        if n < 2:
            return np.arange(n)
        vmax, amax = _limits(machine)
        vlim = float(np.max(vmax[:3])) if self.v_limit is None else float(self.v_limit)
        deg = np.array([1.0, 1.0, 1.0, 180.0 / np.pi, 180.0 / np.pi])
        i = np.arange(n)[:, None]
        j = np.minimum(i + np.arange(1, K + 1)[None, :], n - 1)
        dq = (q[j] - q[i]) * deg
        length, v_ini, acc, maxvel, _, direction = _move_limits(dq, vmax, amax, self.servo_period, vlim)
        with np.errstate(divide="ignore", invalid="ignore"):
            vcap = np.minimum(np.minimum(length / np.maximum(t_opt[j] - t_opt[i], 1e-6), v_ini), maxvel)
        allowed = np.asarray(ok, bool) & (i + np.arange(1, K + 1)[None, :] <= n - 1) & (length > 0)
        el, ev, ea, emax, _, ed = _move_limits((q[0] - np.asarray(entry_q, float)) * deg, vmax, amax,
                                               self.servo_period, vlim)
        entry = np.array([float(el), min(float(el) / max(entry_time, 1e-6), float(ev), float(emax)), 0.5 * float(ea)])
        if not entry[0] > 0 or self.entry_stop:  # no entry move, or one that ends at rest: the row starts at rest
            entry = np.array([0.0, 0.0, 1.0])
        # half the acceleration for a block ending in a parabolic blend, the whole for the row's last (step 4)
        acc_h = np.where(i + np.arange(1, K + 1)[None, :] == n - 1, acc, 0.5 * acc)
        best, ends = _place_row(allowed, length, vcap, acc_h, np.ascontiguousarray(direction), entry,
                                np.asarray(ed, float), self.tolerance, self.servo_period)
        if not np.isfinite(best) or best >= 1e300 or ends[0] != 0:
            return None  # no chain of moving blocks through the row (repeated points): no choice made
        return ends

    def row_floor(self, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray,
                  feed: np.ndarray | None, tolerance: float, end_offset: float = 0.0) -> np.ndarray:
        """The floor (s, per row in order of appearance): the least time any program of straight
        blocks through the row's points (their ends' tips within ``end_offset`` mm of them) can
        take on LinuxCNC 2.9 within ``tolerance`` (mm), by ``least_row_times``. q (N, 5) X Y Z mm
        A B rad; tip (N, 3) mm; feed (N,) mm/min, the programmed tip feed (None: unknown, then the
        feed does not bound a block)."""
        f = np.full(len(q), np.inf) if feed is None else np.where(np.asarray(feed, float) > 0, feed, np.inf)
        return least_row_times(machine, rows, q, tip, f, tolerance, end_offset=end_offset)

    def segments(self, machine: Machine, start: np.ndarray, joints: np.ndarray, rapid: np.ndarray,
                 fword: np.ndarray, inverse_time: np.ndarray) -> Segments:
        """``canon_segments`` with this planner's servo period and speed limit."""
        return canon_segments(start, joints, rapid, fword, inverse_time, machine, servo_period=self.servo_period,
                              v_limit=self.v_limit, tolerance=self.tolerance)

    def row_run(self, machine: Machine, q_blocks: np.ndarray, block_time: np.ndarray, entry_q: np.ndarray,
                entry_time: float) -> tuple[BlockTimes, np.ndarray]:
        """One row as LinuxCNC runs it: the row is entered from rest at ``entry_q`` by a feed move
        of ``entry_time`` s onto q_blocks[0] (blended into the row, as LinuxCNC does between two
        feed moves, or ending at rest with ``entry_stop``), then one G93 block per further point
        with the commanded block times ``block_time`` (s), and ends at rest (the rapid that
        follows). Joints X Y Z mm A B rad; the values are rounded as the G-code writer writes them
        (4 decimals, mm and degrees). Returns the segments' BlockTimes (the entry move first) and
        (K, 5) the joints (mm, rad) commanded at the end of every servo cycle."""
        def written(q: np.ndarray) -> np.ndarray:
            q = np.atleast_2d(np.asarray(q, float))
            return np.round(np.column_stack([q[:, :3], np.degrees(q[:, 3:])]), 4)

        times = np.maximum(np.r_[entry_time, np.asarray(block_time, float)], 1e-6)
        k = len(times)
        start, joints = written(entry_q)[0], written(q_blocks)
        seg = self.segments(machine, start, joints, np.zeros(k, bool), 60.0 / times, np.ones(k, bool))
        seg.stop_after[0] |= self.entry_stop
        bt = self.run(seg)
        q = bt.positions(start, joints)
        return bt, np.column_stack([q[:, :3], np.radians(q[:, 3:])])

    def row_times(self, machine: Machine, q_blocks: np.ndarray, block_time: np.ndarray, entry_q: np.ndarray,
                  entry_time: float) -> np.ndarray:
        """End times (s from the row's first point) of the blocks of one row as LinuxCNC runs them
        (``row_run``)."""
        bt, _ = self.row_run(machine, q_blocks, block_time, entry_q, entry_time)
        return bt.end[1:] - bt.end[0]

    def run(self, seg: Segments) -> BlockTimes:
        """Start and end time of every segment (s) and where the program is at every servo cycle;
        a segment of zero length (LinuxCNC drops it) takes no time."""
        moving = seg.length > 0
        if not moving.all():  # run the moving segments; a dropped one ends when the one before it does
            idx = np.flatnonzero(moving)
            fields = {f: (v[idx] if isinstance(v, np.ndarray) else v) for f, v in vars(seg).items()}
            # LinuxCNC never queues a dropped move: a stop after it is the stop of the moving one before
            fields["stop_after"] = np.add.reduceat(seg.stop_after.astype(np.int64), idx) > 0
            inner = self.run(Segments(**fields))
            before = np.searchsorted(idx, np.arange(len(moving)), side="right") - 1
            end = np.where(before >= 0, np.r_[inner.end, 0.0][before], 0.0)
            start = np.where(moving, np.r_[inner.start, 0.0][np.maximum(before, 0)], end)
            m = len(moving)
            return BlockTimes(start=start, end=end, head=np.r_[idx, m][inner.head],
                              head_fraction=inner.head_fraction, following=np.r_[idx, m, m][inner.following],
                              following_fraction=inner.following_fraction)
        speed = np.minimum(seg.reqvel, seg.maxvel)
        if not np.all(speed > 0):  # a move at F0: LinuxCNC refuses it; the run would never end
            k = int(np.flatnonzero(~(speed > 0))[0])
            raise RuntimeError(f"LinuxCNC planner model: segment {k} cannot move (speed {speed[k]:g}: F0)")
        parabolic = ~seg.stop_after
        expect = float(np.sum(seg.length / speed))
        max_cycles = int(10 * expect / self.servo_period + 10 * len(seg.length) + 1e5)
        length = seg.length.astype(float)
        start, done, head, p_head, p_next = _run(length, seg.reqvel.astype(float), seg.maxvel.astype(float),
                                                 seg.acc.astype(float), parabolic, seg.direction.astype(float),
                                                 float(seg.tolerance), self.servo_period, max_cycles)
        if (done < 0).any():
            raise RuntimeError("LinuxCNC planner model did not finish the program (a segment that cannot move)")
        L = np.r_[length, 1.0, 1.0]
        return BlockTimes(start=start * self.servo_period, end=(done + 1) * self.servo_period, head=head,
                          head_fraction=np.minimum(p_head / L[head], 1.0), following=head + 1,
                          following_fraction=np.minimum(p_next / L[head + 1], 1.0))
