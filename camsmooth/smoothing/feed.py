"""Feed planning: the time-optimal time law along one row of a five-axis program (issue 8).

Problem. One row is a sequence of N poses: joints q_i = (X, Y, Z, A, B) (mm, mm, mm, rad, rad;
X Y Z carry the head's pivot, METHODS section 1: pivot = CL + L_p T), tool tips p_i (CL points,
mm, workpiece frame) and the programmed feed F_i (mm/min) of the block that ends at point i (the
G-code rule, also ``pipeline.row_times``). Find the fastest time law t(s) along the path such that

- the tool-tip speed never exceeds the programmed feed: at point i, |p'(s)| s' <= min(F_i, F_(i+1))
  (the controller enters block i+1 no faster than its F and leaves block i no faster than its F);
- every axis j stays within its velocity and acceleration limits: |q_j' s'| <= vmax_j and
  |q_j' s'' + q_j'' s'^2| <= amax_j;
- the row starts and ends at rest (the program's entry and exit moves are rapids).

Geometric path. The points are interpolated by a C2 cubic spline (scipy ``CubicSpline``,
not-a-knot) in the path parameter s with increments
ds_i = sqrt(|p_i - p_(i-1)|^2 + (ROTARY_LENGTH * |(A, B)_i - (A, B)_(i-1)|)^2): the tool tip's arc
length wherever the tip moves, and still increasing where only the rotary axes turn (a pure rotary
block). A piecewise-linear joint path would have unbounded acceleration at every point (the
controller must stop or blend there); the C2 spline is the smooth path a look-ahead controller
follows within its tolerance, and it meets the points exactly. Exact repeats (ds = 0) are merged:
they get the time of the point before.

Solver. The time-optimal path parameterisation of Pham & Pham (2018, "A new approach to
time-optimal path parameterization based on reachability analysis", IEEE T-RO 34(3), TOPP-RA) on
the gridpoints = the points, with its interpolation discretisation (each segment's constant s''
checked at both ends): a backward pass computes the largest controllable s'^2 at every gridpoint
(a two-variable LP per stage, solved exactly by eliminating s''), a forward pass then takes the
largest s'' reachable. The five axes' velocity and acceleration limits and the tip feed (as
s'^2 <= (F / |p'(s)|)^2) are the constraints. Between gridpoints s'' is constant, so s'^2 is
linear in s and t_(i+1) - t_i = 2 ds / (s'_i + s'_(i+1)).

Why not the ``toppra`` package itself: this pass (numba) solves the same problem on the same
discretisation; tested against toppra (tests/test_feed.py: cycle times and speeds agree to 1e-8
relative) and against closed forms. It is 25-60x faster (about 1 against 23-54 us per point,
benchmarks/bench_feed.py "solvers"), and that is what lets a million-point program be planned for
every method within the smoothing's own time budget (toppra would have taken ~3 minutes there).

Jerk. TOPP-RA is a second-order method: s'' switches instantly, so the axis jerk is unbounded in
the continuous model. Where the machine file gives ``jmax`` for an axis (``Machine.jerk_limited``)
``plan_row`` returns the jerk-limited time-optimal law instead (camsmooth.smoothing.jerk: an NLP
on the same spline, fixed path nodes with free durations, started from this law), which meets
every axis's vmax, amax, jmax and the tip feed at every instant; then ``jerk_over`` is 0 and
``limit_time`` has the jerk constraints too. Otherwise jmax (a default) is only reported: each
plan gives the finite-difference jerk of every axis at the points (``jerk_peak``, 6 x the third
divided difference) and how many samples exceed jmax (``jerk_over``); a real controller limits the
jerk itself and takes a little longer than ``cycle_time``. The jerk-limited law costs an IPOPT
solve per row (tens of ms per point, benchmarks/bench_jerk.py), so the default machine does not
give jmax.

Units inside: mm, s, rad; feeds in mm/min at the interface (the CSV and the G-code unit).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit
from scipy.interpolate import CubicSpline

from camsmooth.errors import InputError
from camsmooth.geometry.paths import _row_runs
from camsmooth.machine.kinematics import Machine, axis_limits

#: joint order of ``q`` (X Y Z mm: the linear axes; "A" "B": the machine's first and second rotary
#: axis, rad, ``Machine.rotary``; names in CONSTRAINTS are mapped by ``machine_label``)
AXES = ("X", "Y", "Z", "A", "B")
#: constraint names, indexed by ``RowPlan.limit`` and ``limit_time``
CONSTRAINTS = (("feed",) + tuple(f"{a} velocity" for a in AXES) + tuple(f"{a} acceleration" for a in AXES)
               + tuple(f"{a} jerk" for a in AXES))
#: mm of path parameter per rad of rotary motion: weighs rotation only where the tip barely moves
#: (1 degree counts as 0.017 mm, far below a usual 0.1-1 mm point spacing)
ROTARY_LENGTH = 1.0
#: parameter increments below this (mm) are repeats of the previous point
REPEAT_DS = 1e-9
#: bound standing in for "unlimited" (the stage LPs need finite numbers)
_UNLIMITED = 1e12



@dataclass(frozen=True, kw_only=True)
class RowPlan:
    """The planned time law of one row.

    t_plan: (N,) s from the row's first point. feed_plan: (N,) mm/min, planned tool-tip speed at
    each point (0 at both ends: the row starts and ends at rest). limit: (N,) index into
    CONSTRAINTS of the constraint that binds at each point (the largest ratio of value to limit;
    -1 for a row that does not move). limit_time: (len(CONSTRAINTS),) s of the row spent with each
    constraint binding (per segment). cycle_time: s. jerk_peak: (5,) largest finite-difference
    jerk per axis (mm/s^3 for X Y Z, rad/s^3 for A B); jerk_over: (5,) samples above jmax.
    """

    t_plan: np.ndarray
    feed_plan: np.ndarray
    limit: np.ndarray
    limit_time: np.ndarray
    cycle_time: float
    jerk_peak: np.ndarray
    jerk_over: np.ndarray

    @property
    def limiting(self) -> str:
        """Name of the constraint that binds for the longest time ('none' for a still row)."""
        return limiting_name(self.limit_time)


@dataclass(frozen=True, kw_only=True)
class FeedPlan:
    """Planned time laws of a whole program (rows contiguous, in path order).

    t_plan, feed_plan, limit: per point as in RowPlan. row_ids: (R,) row id per row;
    row_cycle_time: (R,) s; row_limit_time: (R, len(CONSTRAINTS)) s. cycle_time: sum over rows
    (s; the rapids between rows are not included). limit_time: (len(CONSTRAINTS),) s over all rows.
    jerk_peak, jerk_over: (5,) over all rows.
    """

    t_plan: np.ndarray
    feed_plan: np.ndarray
    limit: np.ndarray
    row_ids: np.ndarray
    row_cycle_time: np.ndarray
    row_limit_time: np.ndarray
    cycle_time: float
    limit_time: np.ndarray
    jerk_peak: np.ndarray
    jerk_over: np.ndarray

    @property
    def limiting(self) -> str:
        """Constraint that binds for the longest time over the program."""
        return limiting_name(self.limit_time)

    def row_limiting(self) -> list[str]:
        """Per row, the constraint that binds for the longest time."""
        return [limiting_name(lt) for lt in self.row_limit_time]


def machine_label(name: str, machine: Machine) -> str:
    """A CONSTRAINTS name with the joint position ("A", "B": the first and second rotary axis)
    replaced by the machine's own axis name ("B velocity" is "C velocity" on an AC table)."""
    head, _, rest = name.partition(" ")
    if rest and head in AXES:
        return f"{machine.joint_names[AXES.index(head)]} {rest}"
    return name


def limiting_name(limit_time: np.ndarray) -> str:
    """The name in CONSTRAINTS with the largest time, 'none' when all are 0."""
    limit_time = np.asarray(limit_time, float)
    return CONSTRAINTS[int(np.argmax(limit_time))] if limit_time.size and limit_time.max() > 0 else "none"


def _check_row(q: np.ndarray, tip: np.ndarray, feed: np.ndarray) -> None:
    n = len(q)
    if q.shape != (n, 5) or tip.shape != (n, 3) or feed.shape != (n,):
        raise InputError(f"feed planning needs q (N, 5), tip (N, 3) and feed (N,); got {q.shape}, {tip.shape}, "
                         f"{feed.shape}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(tip))):
        raise InputError("feed planning: non-finite joint or tip coordinates")
    bad = ~(np.isfinite(feed) & (feed > 0))
    if n > 1 and bad[1:].any():
        k = int(np.flatnonzero(bad[1:])[0]) + 1
        raise InputError(f"feed must be a finite number > 0 mm/min, got {feed[k]!r} at point {k}", column="feed")


def _still(n: int) -> RowPlan:
    return RowPlan(t_plan=np.zeros(n), feed_plan=np.zeros(n), limit=np.full(n, -1, np.int16),
                   limit_time=np.zeros(len(CONSTRAINTS)), cycle_time=0.0, jerk_peak=np.zeros(5),
                   jerk_over=np.zeros(5, np.int64))


def finite_difference_rates(q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segment velocities (N-1, k), point accelerations at the interior points (N-2, k) and
    jerks between consecutive interior points (N-3, k) of q(t) sampled at strictly increasing t
    (s): v = dq/dt per segment, a_i = 2 (v_(i+1/2) - v_(i-1/2)) / (t_(i+1) - t_(i-1)) (the
    three-point rule of ``nlp.fd_operators``), j_i = 3 (a_(i+1) - a_i) / (t_(i+2) - t_(i-1)).
    Each is k! times the divided difference of k + 1 consecutive samples, so it equals the k-th
    derivative of any smooth q(t) through them at some instant of their span: a law whose
    continuous velocity, acceleration and jerk are within limits has these within the limits on
    any grid (da / dt_i, the form before issue 22, is not bounded so on an uneven grid: 1.85x the
    jerk at a start from rest at constant jerk on points even in s)."""
    dt = np.diff(t)
    v = np.diff(q, axis=0) / dt[:, None]
    a = 2.0 * np.diff(v, axis=0) / (t[2:] - t[:-2])[:, None]
    j = 3.0 * np.diff(a, axis=0) / (t[3:] - t[:-3])[:, None]
    return v, a, j


@dataclass(frozen=True, kw_only=True)
class RowPath:
    """One row's geometric path as the solver sees it (``row_path``): the distinct points
    (``keep``; ``owner`` maps every input point to its distinct point), the scaled path parameter
    s at the distinct points (``s_mm / scale``), the spline (scipy CubicSpline, not-a-knot) and its
    derivatives dq = q'(s), ddq = q''(s) (M, 5), the tip's |p'(s)| (M,), the feed bound per point
    (mm/s) and the s'^2 bounds from the tip feed and the chords' velocities (x_feed: every axis's
    and the tip's average speed over each block within its limit), the five axes' limits and the
    tool tip's spline p(s) (``tip_spline``, mm)."""

    n: int
    keep: np.ndarray
    owner: np.ndarray
    s: np.ndarray
    scale: float
    spline: CubicSpline
    q: np.ndarray
    dq: np.ndarray
    ddq: np.ndarray
    dp: np.ndarray
    feed_bound: np.ndarray
    x_feed: np.ndarray
    vmax: np.ndarray
    amax: np.ndarray
    jmax: np.ndarray
    tip_spline: CubicSpline


#: a path speed s' below this share of the row's largest is rest (``plan_from_speed``)
REST_SPEED = 1e-6


def row_path(machine: Machine, q: np.ndarray, tip: np.ndarray, feed: np.ndarray) -> RowPath | None:
    """The row's geometric path and constraint data (module docstring); None when the row has
    fewer than two distinct points. Arguments as in ``plan_row``."""
    q = np.asarray(q, float)
    tip = np.asarray(tip, float)
    feed = np.asarray(feed, float)
    _check_row(q, tip, feed)
    if len(q) < 2:
        return None
    vmax, amax, jmax = axis_limits(machine)
    rot = np.linalg.norm(np.diff(q[:, 3:], axis=0), axis=1)
    ds_all = np.hypot(np.linalg.norm(np.diff(tip, axis=0), axis=1), ROTARY_LENGTH * rot)
    keep = np.r_[True, ds_all > REPEAT_DS]
    m = int(keep.sum())
    if m < 2:
        return None
    qk, pk = q[keep], tip[keep]
    # feed of each kept segment: the block that ends at its end point
    fseg = feed[keep][1:] / 60.0
    owner = np.cumsum(keep) - 1
    ds_k = ds_all[keep[1:]]
    if m == 2:
        # one straight block from rest to rest: TOPP-RA's constant s'' per segment cannot leave rest
        # on a single segment (its time would be infinite). Its exact law is a trapezoid (or a
        # triangle) of the path's acceleration a and speed v on the straight joint path, so the
        # gridpoints go where it switches, s_a = v^2 / (2 a) from either end, which makes the
        # discretisation exact.
        length = ds_k[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            rate = np.abs(qk[1] - qk[0]) / length  # |dq_j / ds| on the straight joint path
            v = min(fseg[0] * length / max(np.linalg.norm(pk[1] - pk[0]), 1e-300), float(np.min(vmax / rate)))
            a = float(np.min(amax / rate))
        s_a = v * v / (2.0 * a) if np.isfinite(v) and a > 0 else 0.5 * length
        w = np.array([0.0, s_a / length, 1.0 - s_a / length, 1.0]) if 2.0 * s_a < length else np.array([0.0, 0.5, 1.0])
        w = w[:, None]
        qk, pk = qk[0] + w * (qk[1] - qk[0]), pk[0] + w * (pk[1] - pk[0])
        ds_k = np.diff(w[:, 0]) * length
        fseg = np.full(len(ds_k), fseg[0])
        owner = owner * len(ds_k)
        m = len(w)
    fpt = np.minimum(np.r_[fseg[0], fseg], np.r_[fseg, fseg[-1]])  # mm/s bound at each kept point
    s_mm = np.r_[0.0, np.cumsum(ds_k)]
    # scale s so that s'^2 ~ 1 at the velocity bound (chord estimate of the bound's median)
    ds = np.diff(s_mm)
    chord_q = np.abs(np.diff(qk, axis=0)) / ds[:, None]
    chord_p = np.linalg.norm(np.diff(pk, axis=0), axis=1) / ds
    with np.errstate(divide="ignore"):
        sd_chord = np.minimum(np.min(vmax / chord_q, axis=1), fseg / chord_p)
    finite = sd_chord[np.isfinite(sd_chord)]
    scale = float(np.median(finite)) if finite.size else 1.0
    s = s_mm / scale
    spline = CubicSpline(s, qk)
    tip_spline = CubicSpline(s, pk)
    dp = np.linalg.norm(tip_spline(s, 1), axis=1)
    # s'^2 bound from the tip feed; where the tip stands still (|p'| ~ 0) the feed does not bind
    x_feed = np.full(m, _UNLIMITED)
    moving = dp * np.sqrt(_UNLIMITED) > fpt
    x_feed[moving] = (fpt[moving] / dp[moving]) ** 2
    # the same bounds on the chords between the points: a block's average speed is its chord over
    # its time, (chord / ds) (s'_i + s'_(i+1)) / 2, so s' at both its ends within limit / (chord /
    # ds) keeps every axis's block velocity and the tip's block speed (the G-code's) within limits
    with np.errstate(divide="ignore", invalid="ignore"):
        seg = np.column_stack([np.abs(np.diff(qk, axis=0)) / vmax, np.linalg.norm(np.diff(pk, axis=0), axis=1) / fseg])
        slope = np.max(np.nan_to_num(seg / np.diff(s)[:, None], nan=0.0), axis=1)  # per segment, s' <= 1 / slope
    x_seg = np.where(slope > 0, 1.0 / np.maximum(slope, 1e-300) ** 2, _UNLIMITED)
    x_feed = np.minimum(x_feed, np.minimum(np.r_[x_seg, _UNLIMITED], np.r_[_UNLIMITED, x_seg]))
    return RowPath(n=len(q), keep=keep, owner=owner, s=s, scale=scale, spline=spline, q=qk,
                   dq=spline(s, 1), ddq=spline(s, 2), dp=dp, feed_bound=fpt, x_feed=x_feed,
                   vmax=np.minimum(vmax, _UNLIMITED), amax=np.minimum(amax, _UNLIMITED), jmax=jmax,
                   tip_spline=tip_spline)


@njit(cache=True)
def _stage_rows(i: int, ds: float, dq: np.ndarray, ddq: np.ndarray, amax: np.ndarray,
                k_next: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    """Rows c u + d x <= e of stage i (u = s'' on segment i, x = s'^2 at point i): every axis's
    acceleration at both ends of the segment (x_(i+1) = x + 2 ds u) and 0 <= x_(i+1) <= k_next."""
    nj = dq.shape[1]
    c = np.empty(4 * nj + 2)
    d = np.empty(4 * nj + 2)
    e = np.empty(4 * nj + 2)
    r = 0
    for j in range(nj):
        for end in range(2):
            if end == 0:
                cj, dj = dq[i, j], ddq[i, j]
            else:
                cj, dj = dq[i + 1, j] + 2 * ds * ddq[i + 1, j], ddq[i + 1, j]
            c[r], d[r], e[r] = cj, dj, amax[j]
            c[r + 1], d[r + 1], e[r + 1] = -cj, -dj, amax[j]
            r += 2
    c[r], d[r], e[r] = 2 * ds, 1.0, k_next
    c[r + 1], d[r + 1], e[r + 1] = -2 * ds, -1.0, 0.0
    return c, d, e


@njit(cache=True)
def forward_backward(s: np.ndarray, dq: np.ndarray, ddq: np.ndarray, amax: np.ndarray,
                     xmax: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """s' at the gridpoints, rest to rest: backward pass (largest controllable x per stage: the
    2-variable LP max x s.t. rows, solved by pairing every lower bound on u with every upper one),
    then forward pass (largest u at the reached x)."""
    m = len(s)
    K = np.empty(m)
    K[m - 1] = 0.0
    for i in range(m - 2, -1, -1):
        ds = s[i + 1] - s[i]
        c, d, e = _stage_rows(i, ds, dq, ddq, amax, K[i + 1])
        xhi = xmax[i]
        for a in range(len(c)):
            if c[a] == 0.0 and d[a] > 0.0:
                xhi = min(xhi, e[a] / d[a])
        for a in range(len(c)):  # lower bounds on u: c < 0
            if c[a] >= 0.0:
                continue
            pa, ra = e[a] / c[a], -d[a] / c[a]
            for b in range(len(c)):  # upper bounds: c > 0
                if c[b] <= 0.0:
                    continue
                pb, rb = e[b] / c[b], -d[b] / c[b]
                den = ra - rb
                if den > 1e-300:
                    xhi = min(xhi, (pb - pa) / den)
        K[i] = max(xhi, 0.0)
    x = np.empty(m)
    x[0] = 0.0
    for i in range(m - 1):
        ds = s[i + 1] - s[i]
        c, d, e = _stage_rows(i, ds, dq, ddq, amax, K[i + 1])
        uhi = np.inf
        for a in range(len(c)):
            if c[a] > 0.0:
                uhi = min(uhi, (e[a] - d[a] * x[i]) / c[a])
        x[i + 1] = min(max(x[i] + 2 * ds * uhi, 0.0), K[i + 1])
    return np.sqrt(x)


def _xmax(rp: RowPath) -> np.ndarray:
    """s'^2 bound per gridpoint from the tip feed and every axis's velocity limit."""
    with np.errstate(divide="ignore", over="ignore"):
        return np.minimum(rp.x_feed, np.min((rp.vmax / np.abs(rp.dq)) ** 2, axis=1))


def plan_from_speed(rp: RowPath, sd: np.ndarray) -> RowPlan:
    """The RowPlan of path speeds s' at the gridpoints (constant s'' per segment): times, tip
    feed, binding constraints and the jerk report."""
    s, dq, ddq, dp, fpt, vl, al = rp.s, rp.dq, rp.ddq, rp.dp, rp.feed_bound, rp.vmax, rp.amax
    x = sd ** 2
    dsc = np.diff(s)
    u = np.diff(x) / (2.0 * dsc)  # s'' per segment, consistent with t below
    den = sd[:-1] + sd[1:]
    # at rest: 0, or within rounding of 0 (1e-8 against s' ~ 1 at the velocity bound, the scaled s)
    still = sd <= REST_SPEED * max(float(sd.max(initial=0.0)), 1e-300)
    dt = 2.0 * dsc / np.where(den > 0.0, den, 1.0)
    rest = np.flatnonzero(still[:-1] & still[1:])
    if rest.size:
        # a segment with both ends at rest (the discretisation found no speed at either, e.g. the
        # last segment of a row where the spline bends sharply): it takes its rest-to-rest time,
        # a triangle at the path acceleration its axes allow at both ends, not an infinite one
        rate = np.maximum(np.abs(dq[rest]), np.abs(dq[rest + 1]))
        with np.errstate(divide="ignore"):
            a_path = np.min(np.where(rate > 0.0, al / np.maximum(rate, 1e-300), np.inf), axis=1)
        a_path = np.where(np.isfinite(a_path) & (a_path > 0.0), a_path, _UNLIMITED)
        dt[rest] = 2.0 * np.sqrt(dsc[rest] / a_path)
    t = np.r_[0.0, np.cumsum(dt)]

    # which constraint binds: ratio of value to limit at each end of each segment
    r_feed = np.where(fpt > 0, dp * sd / fpt, 0.0)
    r_vel = np.abs(dq) * sd[:, None] / vl
    acc0 = np.abs(dq[:-1] * u[:, None] + ddq[:-1] * x[:-1, None]) / al
    acc1 = np.abs(dq[1:] * u[:, None] + ddq[1:] * x[1:, None]) / al
    r_acc_pt = np.zeros_like(r_vel)
    r_acc_pt[:-1] = acc0
    r_acc_pt[1:] = np.maximum(r_acc_pt[1:], acc1)
    ratios_pt = np.column_stack([r_feed, r_vel, r_acc_pt])
    ratios_seg = np.column_stack([np.maximum(r_feed[:-1], r_feed[1:]), np.maximum(r_vel[:-1], r_vel[1:]),
                                  np.maximum(acc0, acc1)])
    limit_k = np.argmax(ratios_pt, axis=1).astype(np.int16)
    limit_time = np.bincount(np.argmax(ratios_seg, axis=1), weights=dt, minlength=len(CONSTRAINTS))

    jerk_peak, jerk_over = _jerk_report(rp, t)
    o = rp.owner
    return RowPlan(t_plan=t[o], feed_plan=60.0 * dp[o] * sd[o], limit=limit_k[o], limit_time=limit_time,
                   cycle_time=float(t[-1]), jerk_peak=jerk_peak, jerk_over=jerk_over)


def _jerk_report(rp: RowPath, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Largest finite-difference jerk per joint at the row's distinct points under the times t
    (``finite_difference_rates``) and the samples above jmax; zeros for rows under 4 points."""
    if len(t) < 4:
        return np.zeros(5), np.zeros(5, np.int64)
    _, _, jerk = finite_difference_rates(rp.q, t)
    return np.abs(jerk).max(axis=0), np.sum(np.abs(jerk) > rp.jmax, axis=0)


def plan_row(machine: Machine, q: np.ndarray, tip: np.ndarray, feed: np.ndarray) -> RowPlan:
    """Time-optimal time law of one row (module docstring): a pure function of the machine's axis
    limits and the row's arrays.

    q: (N, 5) joints X Y Z (mm, the pivot) A B (rad); tip: (N, 3) tool tips (CL points, mm,
    workpiece frame); feed: (N,) programmed tip feed (mm/min) of the block ending at each point
    (feed[0] is not used). InputError for wrong shapes, non-finite values or a feed <= 0;
    """
    rp = row_path(machine, q, tip, feed)
    if rp is None:
        return _still(len(q))
    sd = forward_backward(rp.s, rp.dq, rp.ddq, rp.amax, _xmax(rp))
    if not machine.jerk_limited:
        return plan_from_speed(rp, sd)
    from camsmooth.smoothing.jerk import jerk_law

    return plan_from_law(rp, jerk_law(rp, sd))


def plan_from_law(rp: RowPath, law: object) -> RowPlan:
    """The RowPlan of a jerk-limited law (camsmooth.smoothing.jerk.JerkLaw): times and tip feed
    at the points; the binding constraint (largest ratio of value to limit, jerk included) at each
    point and its time, both from the law evaluated exactly at its dense-check instants; the jerk
    report from the finite differences of the points."""
    from camsmooth.smoothing.jerk import DENSE, law_rates

    rates = law_rates(rp, law, DENSE)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.column_stack([np.nan_to_num(rates.tip_speed / rates.feed, nan=0.0, posinf=0.0),
                                  np.abs(rates.velocity) / rp.vmax, np.abs(rates.acceleration) / rp.amax,
                                  np.abs(rates.jerk) / rp.jmax])
    k = np.argmax(ratios, axis=1).reshape(-1, DENSE)
    h = np.diff(law.t)
    wts = np.full(DENSE, 1.0 / (DENSE - 1))
    wts[[0, -1]] *= 0.5
    limit_time = np.bincount(k.ravel(), weights=(h[:, None] * wts[None, :]).ravel(), minlength=len(CONSTRAINTS))
    at_node = np.r_[k[:, 0], k[-1, -1]].astype(np.int16)
    t = law.t[law.points]
    jerk_peak, jerk_over = _jerk_report(rp, t)
    o = rp.owner
    return RowPlan(t_plan=t[o], feed_plan=(60.0 * rp.dp * law.y[law.points])[o], limit=at_node[law.points][o],
                   limit_time=limit_time, cycle_time=float(law.t[-1]), jerk_peak=jerk_peak, jerk_over=jerk_over)


def combine(row_ids: Sequence[int], plans: Sequence[RowPlan]) -> FeedPlan:
    """One FeedPlan from per-row plans in path order (e.g. from a parallel map over rows)."""
    k = len(CONSTRAINTS)

    def cat(name: str, dtype: type) -> np.ndarray:
        return np.concatenate([getattr(p, name) for p in plans]).astype(dtype) if plans else np.zeros(0, dtype)

    row_lt = np.array([p.limit_time for p in plans], float).reshape(-1, k)
    peaks = np.array([p.jerk_peak for p in plans], float).reshape(-1, 5)
    over = np.array([p.jerk_over for p in plans], np.int64).reshape(-1, 5)
    return FeedPlan(t_plan=cat("t_plan", float), feed_plan=cat("feed_plan", float), limit=cat("limit", np.int16),
                    row_ids=np.asarray(row_ids, np.int64), row_cycle_time=np.array([p.cycle_time for p in plans]),
                    row_limit_time=row_lt, cycle_time=float(sum(p.cycle_time for p in plans)),
                    limit_time=row_lt.sum(axis=0), jerk_peak=peaks.max(axis=0, initial=0.0),
                    jerk_over=over.sum(axis=0))


def block_feeds(plan: FeedPlan, tip: np.ndarray, rows: np.ndarray, programmed: np.ndarray) -> np.ndarray:
    """Per point, the feed (mm/min) of the block that ends there under the planned time law: the
    tip's chord over the block's planned time, so that a controller given these feeds (F in
    G94/TCP mode, or 1/time in G93) runs the plan. A row's first point, and blocks the plan gives no
    time (merged repeats), keep the programmed feed. Never above the programmed feed."""
    tip = np.asarray(tip, float)
    out = np.asarray(programmed, float).copy()
    same = np.r_[False, np.asarray(rows)[1:] == np.asarray(rows)[:-1]]
    dt = np.r_[0.0, np.diff(plan.t_plan)]
    chord = np.r_[0.0, np.linalg.norm(np.diff(tip, axis=0), axis=1)]
    k = same & (dt > 0) & (chord > 0)
    out[k] = np.minimum(60.0 * chord[k] / dt[k], out[k])
    return out


def row_slices(rows: np.ndarray) -> list[slice]:
    """Slices of the contiguous runs of equal row ids (``geometry.paths._row_runs``)."""
    starts, _ = _row_runs(rows)
    ends = np.r_[starts[1:], len(np.asarray(rows).reshape(-1))]
    return [slice(int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


def plan_program(machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, feed: np.ndarray) -> FeedPlan:
    """``plan_row`` over every row (serial; rows are independent, so a caller may map
    ``plan_row`` over ``row_slices(rows)`` in parallel and ``combine`` the results).

    rows: (N,) row id per point (rows contiguous); q (N, 5), tip (N, 3), feed (N,) as in plan_row.
    """
    q, tip, feed = np.asarray(q, float), np.asarray(tip, float), np.asarray(feed, float)
    slices = row_slices(rows)
    plans = [plan_row(machine, q[s], tip[s], feed[s]) for s in slices]
    return combine([int(np.asarray(rows)[s.start]) for s in slices], plans)


def method_joints(result: object) -> np.ndarray:
    """(N, 5) joints of a MethodResult in ``Machine.joint_names`` order: X Y Z (mm, its ``xyz``)
    and its two rotary axes (rad, its ``rotary``)."""
    return np.column_stack([result.xyz, result.rotary.values])


def plan_method(machine: Machine, result: object, feed: np.ndarray) -> FeedPlan:
    """``plan_program`` for a smoothing MethodResult (camsmooth.smoothing.result): its rows,
    joints (xyz, A, B) and tool tips (cl); feed (N,) mm/min, the program's per-point feed."""
    return plan_program(machine, result.rows, method_joints(result), result.cl, feed)
