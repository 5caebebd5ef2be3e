"""Closed-form checks of the controller models (camsmooth.controller.blocks and .linuxcnc) written
against the mutants benchmarks/mutation.py left alive (targets controller-blocks and
controller-linuxcnc).

The oracles are worked by hand: the trapezoid and triangle of a single block from rest to rest
(time L/v + v/a, or 2 sqrt(L/a)), the chain of parabolic blends at half the acceleration (the next
block starts when the one before it decelerates below the blend speed: n equal triangle blocks take
(n + 1) sqrt(L/a_h), two equal trapezoid blocks 2 L/v + v/a_h), the ``G64 P`` corner cap
2 sqrt(a_h P / cos(theta/2)) (LinuxCNC 2.9 ``blendmath.c``, tpComputeBlendVelocity), the sagitta of
chords of a circle and brute force over short rows. The default AB head (pivot 150 mm; X Y Z
500 mm/s, 3000 mm/s^2; A B 60 deg/s, 300 deg/s^2) with a LinuxCNC post throughout; servo period
1 ms. Units mm, s, deg in the programs; rad inside.
"""

from __future__ import annotations

import itertools
import tomllib
from types import SimpleNamespace

import numpy as np
import pytest

from camsmooth.controller import blocks as B
from camsmooth.controller import linuxcnc as L
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, machine_from_dict

DT = L.SERVO_PERIOD_S
A_LIN = 3000.0  # mm/s^2, X Y Z of the default machine
V_LIN = 500.0  # mm/s


def _machine():
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["post"] = {"dialect": "linuxcnc", "mode": "machine"}
    return machine_from_dict(data, "<test machine>")


M = _machine()
PIVOT = M.pivot


def _feed_run(joints, feed_mm_min, *, tolerance: float = 0.0, start=None):
    """The planner model's BlockTimes of G94 feed moves (X Y Z mm, A B deg) from ``start``."""
    joints = np.atleast_2d(np.asarray(joints, float))
    n = len(joints)
    p = L.LinuxCNCPlanner(tolerance=tolerance)
    seg = p.segments(M, np.zeros(5) if start is None else np.asarray(start, float), joints, np.zeros(n, bool),
                     np.full(n, float(feed_mm_min)), np.zeros(n, bool))
    return p.run(seg), seg


# ---- linuxcnc.py: the canonical layer ---------------------------------------------------------------------


def test_move_limits_of_a_combined_move_by_hand():
    """X 3, Y -4 mm and B 2 deg in one move: length 5 mm (the XYZ distance), v_ini = 5 / max(3/500, 4/500,
    2/60) = 150 mm/s, acc = 5 / max(3/3000, 4/3000, 2/300) = 750 mm/s^2; a Z of 5e-8 mm (below
    emccanon's 1e-7) does not move the axis (nor count in the length); the direction is the signed
    move over the length, (0.6, -0.8, 1e-8)."""
    vmax, amax = L._limits(M)
    dq = np.array([[3.0, -4.0, 5e-8, 0.0, 2.0]])
    length, v_ini, acc, maxvel, pure, direction = L._move_limits(dq, vmax, amax, DT, 1e9)
    assert length[0] == pytest.approx(5.0, rel=1e-15)
    assert v_ini[0] == pytest.approx(150.0, rel=1e-12)
    assert acc[0] == pytest.approx(750.0, rel=1e-12)
    assert maxvel[0] == pytest.approx(150.0, rel=1e-12)
    assert not pure[0]
    assert np.allclose(direction[0], [0.6, -0.8, 1e-8], atol=1e-15)
    # the sample rate caps the speed: 0.1 mm in 1.02 cycles; and [TRAJ] MAX_LINEAR_VELOCITY
    dq = np.array([[0.1, 0.0, 0.0, 0.0, 0.0]])
    assert L._move_limits(dq, vmax, amax, DT, 1e9)[3][0] == pytest.approx(0.1 / (1.02 * DT), rel=1e-12)
    assert L._move_limits(dq, vmax, amax, DT, 20.0)[3][0] == pytest.approx(20.0, rel=1e-15)


def test_move_limits_of_a_pure_rotary_and_a_pure_linear_move():
    """B alone by 10 deg: length 10 deg, 60 deg/s and 300 deg/s^2 (only the rotary axes count), the
    linear speed limit does not apply, no XYZ direction; X alone by 2 mm: the linear axis only."""
    vmax, amax = L._limits(M)
    assert np.allclose(vmax, [500, 500, 500, 60, 60]) and np.allclose(amax, [3000, 3000, 3000, 300, 300])
    length, v_ini, acc, maxvel, pure, direction = L._move_limits(
        np.array([[0.0, 0, 0, 0, -10.0], [2.0, 0, 0, 0, 0]]), vmax, amax, DT, 5.0)
    assert list(pure) == [True, False]
    assert np.allclose(length, [10.0, 2.0])
    assert np.allclose(v_ini, [60.0, 500.0]) and np.allclose(acc, [300.0, 3000.0])
    assert np.allclose(maxvel, [60.0, 5.0])
    assert np.allclose(direction, [[0, 0, 0], [1, 0, 0]])
    # no move at all: no length, unbounded speed and acceleration (LinuxCNC drops the segment)
    length, v_ini, acc, *_ = L._move_limits(np.zeros((1, 5)), vmax, amax, DT, 5.0)
    assert length[0] == 0 and np.isinf(v_ini[0]) and np.isinf(acc[0])


def test_canon_segments_feed_modes_rapids_and_stops():
    """G93: rate = length * F / 60; G94: F / 60; a rapid at v_ini; a segment stops where the motion mode
    changes and at the program's end; the joints are taken after ``start``; G64 P carried."""
    start = np.array([1.0, 0, 0, 0, 0])
    joints = np.array([[4.0, 4.0, 0, 0, 0], [4.0, 4.0, 2.0, 0, 0], [4.0, 4.0, 12.0, 0, 0], [4.0, 4.0, 12.1, 0, 0]])
    seg = L.canon_segments(start, joints, np.array([False, False, True, False]), np.array([6.0, 600.0, 1.0, 1e6]),
                           np.array([True, False, False, False]), M, tolerance=0.002)
    assert np.allclose(seg.length, [5.0, 2.0, 10.0, 0.1])
    assert seg.reqvel[0] == pytest.approx(5.0 * 6.0 / 60.0)  # G93: 0.5 mm/s
    assert seg.reqvel[1] == pytest.approx(10.0)  # G94: 600 mm/min
    assert seg.reqvel[2] == pytest.approx(500.0)  # rapid: v_ini, whatever F
    assert seg.reqvel[3] == pytest.approx(500.0)  # F above the axes: v_ini
    assert list(seg.stop_after) == [False, True, True, True]
    assert list(seg.rapid) == [False, False, True, False]
    assert seg.tolerance == 0.002
    assert np.allclose(seg.maxvel, [500.0, 500.0, 500.0, 0.1 / (1.02 * DT)])
    # v_limit caps the linear speed; None takes the fastest linear axis
    slow = L.canon_segments(start, joints, np.zeros(4, bool), np.full(4, 1e6), np.zeros(4, bool), M, v_limit=7.0)
    assert np.allclose(slow.maxvel, 7.0)
    assert np.allclose(slow.reqvel, [625.0, 500.0, 500.0, 500.0])  # 3-4-5: v_ini = 5 / (4 / 500)
    p = L.LinuxCNCPlanner(v_limit=7.0, tolerance=0.003)
    via = p.segments(M, start, joints, np.zeros(4, bool), np.full(4, 1e6), np.zeros(4, bool))
    assert np.allclose(via.maxvel, 7.0) and via.tolerance == 0.003


def test_the_default_speed_limit_is_the_fastest_linear_axis():
    """[TRAJ] MAX_LINEAR_VELOCITY defaults to the fastest linear axis, not a rotary one: on a machine of
    40 mm/s linear axes and 90 deg/s rotary ones, a 3-4-5 move (v_ini = 5 / (4 / 40) = 50 mm/s) is
    capped at 40 mm/s."""
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["post"] = {"dialect": "linuxcnc", "mode": "machine"}
    for ax in "XYZ":
        data["axis"][ax]["vmax"] = 40.0
    for ax in "AB":
        data["axis"][ax]["vmax"] = 90.0
    slow = machine_from_dict(data, "<slow linear axes>")
    seg = L.canon_segments(np.zeros(5), np.array([[3.0, 4.0, 0, 0, 0]]), np.zeros(1, bool), np.full(1, 1e6),
                           np.zeros(1, bool), slow)
    assert seg.reqvel[0] == pytest.approx(50.0) and seg.maxvel[0] == pytest.approx(40.0)


def test_linuxcnc_sense_is_the_machines():
    assert np.array_equal(L.linuxcnc_sense(M), [1.0, 1.0])
    assert L.linuxcnc_sense(M).dtype == float


# ---- linuxcnc.py: the planner's kernels ------------------------------------------------------------------


def test_trapezoid_velocity_by_hand():
    """findTrapezoidalDesiredVel: the speed that still stops within dx, -a dt/2 + sqrt(vf^2 + a (2 dx - v dt)
    + (a dt / 2)^2); 0 when that square root has no real value."""
    a, dx, vf, v, dt = 2000.0, 0.3, 4.0, 10.0, 0.001
    want = -a * dt / 2 + np.sqrt(vf ** 2 + a * (2 * dx - v * dt) + (a * dt / 2) ** 2)
    assert L._trapezoid_vel(a, dx, vf, v, dt) == pytest.approx(want, rel=1e-14)
    assert L._trapezoid_vel(a, -1.0, 0.0, 10.0, dt) == 0.0


def test_solo_segment_is_the_triangle_or_the_trapezoid():
    """From rest to rest at a = 1000 mm/s^2: L = 1 mm reaches sqrt(a L) = 31.6 mm/s in 2 sqrt(L/a);
    capped at 10 mm/s it cruises: L/v + v/a; no length, no time."""
    t, v = L._solo(1.0, 100.0, 1000.0)
    assert (t, v) == (pytest.approx(2 * np.sqrt(1e-3), rel=1e-14), pytest.approx(np.sqrt(1000.0), rel=1e-14))
    t, v = L._solo(1.0, 10.0, 1000.0)
    assert (t, v) == (pytest.approx(0.1 + 0.01, rel=1e-14), 10.0)
    assert L._solo(0.0, 10.0, 1000.0) == (0.0, 0.0)
    # exactly at the cap: both formulas agree
    t, v = L._solo(0.1, 10.0, 1000.0)
    assert t == pytest.approx(0.02, rel=1e-12) and v == pytest.approx(10.0, rel=1e-12)


def test_lag_is_the_time_until_the_blend_speed_on_the_final_deceleration():
    """Two trapezoid segments (10 mm at 50 mm/s, a_h = 1500): blend speed 50, so the next starts when
    the first begins to decelerate, at L/v = 0.2 s; at a 90 deg corner with G64 P = 1 um the cap
    2 sqrt(a_h P / cos 45 deg) holds it back to T - v_tol / a_h; straight on, no cap."""
    ap = 1500.0
    tp = 10 / 50 + 50 / ap
    x, y = np.array([1.0, 0, 0]), np.array([0.0, 1, 0])
    assert L._lag(10.0, 50.0, ap, tp, x, 10.0, 50.0, ap, y, 0.0) == pytest.approx(0.2, rel=1e-12)
    v_tol = 2 * np.sqrt(ap * 0.001 / np.cos(np.pi / 4))
    assert L._lag(10.0, 50.0, ap, tp, x, 10.0, 50.0, ap, y, 0.001) == pytest.approx(tp - v_tol / ap, rel=1e-12)
    assert L._lag(10.0, 50.0, ap, tp, x, 10.0, 50.0, ap, x, 0.001) == pytest.approx(0.2, rel=1e-12)
    # triangle segments (1 mm, a_h 1000): the blend speed is the peak sqrt(a_h L): the next starts at the top
    tp, vp = L._solo(1.0, 1e3, 1000.0)
    assert L._lag(1.0, vp, 1000.0, tp, x, 1.0, vp, 1000.0, x, 0.0) == pytest.approx(tp / 2, rel=1e-12)
    # a short next segment (0.25 mm: it reaches it in half the time) lowers the blend speed
    tn, vn = L._solo(0.25, 1e3, 1000.0)
    t_blend = min(1.0 / vp, 0.25 / vn)  # = the time to cover the next at its peak
    assert L._lag(1.0, vp, 1000.0, tp, x, 0.25, vn, 1000.0, x, 0.0) == pytest.approx(tp - t_blend, rel=1e-12)


def test_one_block_from_rest_to_rest_is_the_trapezoid_or_the_triangle():
    """A lone block (the program's last: full acceleration 3000 mm/s^2). 20 mm at 50 mm/s: L/v + v/a;
    0.7 mm and 11 mm with no feed limit: the triangle 2 sqrt(L/a); 120 mm reaches 500 mm/s. Within
    the servo cycle the end falls in (the end is counted at the end of its cycle)."""
    bt, seg = _feed_run([[20.0, 0, 0, 0, 0]], 3000.0)
    t = 20 / 50 + 50 / A_LIN
    assert bt.start[0] == 0.0
    assert t - 1e-9 <= bt.end[0] <= t + DT
    for length in (0.7, 11.0):
        bt, _ = _feed_run([[0, length, 0, 0, 0]], 1e6)
        t = 2 * np.sqrt(length / A_LIN)
        assert t - 1e-9 <= bt.end[0] <= t + DT, length
    bt, _ = _feed_run([[0, 0, 120.0, 0, 0]], 1e6)
    t = 120.0 / V_LIN + V_LIN / A_LIN
    assert t - 1e-9 <= bt.end[0] <= t + DT
    bt, _ = _feed_run([[0, 0.3, 0, 0, 0]], 1e6)
    t = 2 * np.sqrt(0.3 / A_LIN)
    assert t - 1e-9 <= bt.end[0] <= t + DT
    # one cycle per record, ending at the end point; the head past the last after the end
    pos = bt.positions(np.zeros(5), np.array([[0, 0.3, 0, 0, 0]]))
    assert len(pos) == round(bt.end[0] / DT)
    assert np.allclose(pos[-1], [0, 0.3, 0, 0, 0])
    assert np.all(np.diff(pos[:, 1]) >= 0)


def test_a_pure_rotary_block_runs_its_degrees():
    """B alone by 30 deg at 60 deg/s, 300 deg/s^2 (a lone block): 30/60 + 60/300 = 0.7 s; 0.5 deg: the
    triangle 2 sqrt(0.5 / 300). It comes to rest: no step of the last cycles longer than one cycle's
    change of speed allows (a dt^2), and they shrink."""
    bt, seg = _feed_run([[0, 0, 0, 0, 30.0]], 1e6)
    assert seg.pure_rotary[0] and seg.length[0] == 30.0
    assert 0.7 - 1e-9 <= bt.end[0] <= 0.7 + DT
    for b_deg in (30.0, 0.5):
        bt, _ = _feed_run([[0, 0, 0, 0, b_deg]], 1e6)
        if b_deg < 1:
            t = 2 * np.sqrt(0.5 / 300.0)
            assert t - 1e-9 <= bt.end[0] <= t + DT
        pos = bt.positions(np.zeros(5), np.array([[0, 0, 0, 0, b_deg]]))
        steps = np.diff(pos[-4:, 4])
        assert np.all(np.diff(steps) < 0) and steps[-1] <= 300.0 * DT * DT * (1 + 1e-9), steps
        assert pos[-1, 4] == pytest.approx(b_deg, abs=1e-12)


@pytest.mark.parametrize("n", [2, 5])
def test_equal_triangle_blocks_chain_at_half_the_acceleration(n):
    """n equal blocks of L = 0.4 mm along X, too short to reach their feed. The inner blocks (they end in
    a parabolic blend) run their triangles at half the acceleration, a_h = 1500 mm/s^2, in
    2 h with h = sqrt(L/a_h); between two of them the blend speed is the peak sqrt(a_h L) (t_blend =
    min(L/v, v/a_h) = h), so the next starts at the top of the one before: inner block k starts at k h and
    ends at (k + 2) h. The last block ends at rest and runs at the whole a = 3000 (2 sqrt(L/a) = sqrt(2) h,
    peak sqrt(a L)): into it t_reach = min(L/sqrt(a_h L), L/sqrt(a L)) = sqrt(L/a) = h/sqrt(2) sets t_blend,
    so the blend speed is a_h h/sqrt(2) = sqrt(a_h L)/sqrt(2), reached h (1 - 1/sqrt(2)) after the peak of
    the block before: the last starts at (n - 1/sqrt(2)) h and ends at (n + 1/sqrt(2)) h."""
    x = 0.4 * np.arange(1, n + 1)
    joints = np.column_stack([x, np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)])
    bt, _ = _feed_run(joints, 1e6)
    h = np.sqrt(0.4 / (A_LIN / 2))
    want = h * np.r_[np.arange(2, n + 1), n + 1 / np.sqrt(2)]
    # each blend starts on a servo cycle: up to half a cycle later per block
    assert np.all(bt.end >= want - 1e-9) and np.all(bt.end <= want + 0.5 * np.arange(2, n + 2) * DT), bt.end - want
    assert np.array_equal(bt.start, np.r_[0.0, bt.end[:-1]])  # the head of the queue once the one before ends


def test_two_trapezoid_blocks_blend_at_full_speed():
    """Two 10 mm blocks along X at v = 50 mm/s: the first (parabolic end) a trapezoid at a_h = 1500, L/v +
    v/a_h; the second ends at rest, a trapezoid at the whole a = 3000, L/v + v/a. The blend speed is v
    (t_blend = max(v/a_h, v/a) = v/a_h, a_h t_blend = v), so the second starts when the first begins to
    decelerate (L/v) and the row ends at 2 L/v + v/a. In the blend the first falls at a_h while the second
    rises at a: their sum peaks when the second reaches v (v/a in), at v + (a - a_h) v/a = 1.5 v."""
    bt, _ = _feed_run([[10.0, 0, 0, 0, 0], [20.0, 0, 0, 0, 0]], 3000.0)
    t = 2 * 10 / 50 + 50 / A_LIN
    assert t - 1e-9 <= bt.end[-1] <= t + DT
    assert bt.end[0] == pytest.approx(10 / 50 + 50 / 1500, abs=2 * DT) and bt.start[1] == bt.end[0]
    pos = bt.positions(np.zeros(5), np.array([[10.0, 0, 0, 0, 0], [20.0, 0, 0, 0, 0]]))
    speed = np.diff(pos[:, 0]) / DT
    # the peak of a tent of slopes +-1500 mm/s^2 seen through one-cycle averages: within 1500 DT below it
    assert 75.0 - 1500 * DT <= speed.max() <= 75.0 * (1 + 1e-9)


@pytest.mark.parametrize("tol", [0.0, 0.001])
def test_a_corner_blend_is_capped_by_the_g64_tolerance(tol):
    """10 mm along X then 10 mm along Y at v = 50 mm/s, the first at a_h = 1500 (parabolic end), the last
    at the whole a = 3000 (ends at rest): without G64 P the second starts at the first's deceleration
    (L/v) and ends L/v + v/a later, 2 L/v + v/a; with P = 1 um the blend speed is capped at
    2 sqrt(a_h P / cos 45) = 2.91 mm/s (a_h the first's, tpComputeBlendVelocity), so the second starts
    (v - v_tol)/a_h later."""
    bt, _ = _feed_run([[10.0, 0, 0, 0, 0], [10.0, 10.0, 0, 0, 0]], 3000.0, tolerance=tol)
    t = 2 * 10 / 50 + 50 / A_LIN
    lo = t
    if tol:
        v_tol = 2 * np.sqrt(1500 * tol / np.cos(np.pi / 4))
        t += (50 - v_tol) / 1500
        # the second moves in the cycle in which the first falls below v_tol: up to a cycle before the
        # continuous crossing (without the cap the crossing is the first decelerating cycle, at L/v exactly)
        lo = t - DT
    assert lo - 1e-9 <= bt.end[-1] <= t + DT
    # straight on with the same tolerance: no cap (the corner is closer to straight than 1e-3 rad)
    bt, _ = _feed_run([[10.0, 0, 0, 0, 0], [20.0, 0, 0, 0, 0]], 3000.0, tolerance=tol)
    assert bt.end[-1] <= 2 * 10 / 50 + 50 / A_LIN + 2 * DT


def test_only_a_segments_own_parabolic_end_halves_its_acceleration():
    """B alone by 10 deg, then by 10 deg more (a = 300 deg/s^2, far from 60 deg/s), the program's end
    after the second. The first ends in a parabolic blend: a/2 = 150 deg/s^2. The last ends at rest: its
    whole a = 300, also while the first blends into it (tcGetTangentialMaxAccel halves a segment whose own
    term_cond is TC_TERM_COND_PARABOLIC; measured on LinuxCNC 2.9's headless simulation, the last blend of
    a row, benchmarks/bench_controller.py). So the per-cycle speed of the first ramps by +-150 deg/s^2
    and that of the last by +-300 deg/s^2, the latter rising while the former falls. Times by hand (L = 10,
    a_h = a/2): the first is a triangle, 2 sqrt(L/a_h) = 0.516 s, peak sqrt(a_h L); into the last t_blend =
    t_reach = min(L/sqrt(a_h L), L/sqrt(a L)) = sqrt(L/a), blend speed a_h sqrt(L/a), reached
    sqrt(L/a_h) - sqrt(L/a) after the peak; the last then runs its triangle 2 sqrt(L/a): it ends at
    2 sqrt(L/a_h) + sqrt(L/a) = 0.699 s (halved as well it would end at 3 sqrt(L/a_h) = 0.775 s)."""
    a, length = 300.0, 10.0
    joints = np.array([[0, 0, 0, 0, length], [0, 0, 0, 0, 2 * length]])
    bt, seg = _feed_run(joints, 1e6)
    assert np.all(seg.acc == a) and seg.stop_after.tolist() == [False, True]
    t0 = 2 * np.sqrt(length / (a / 2))
    assert t0 - 1e-9 <= bt.end[0] <= t0 + DT
    t1 = 2 * np.sqrt(length / (a / 2)) + np.sqrt(length / a)
    assert t1 - DT <= bt.end[1] <= t1 + DT  # the blend begins on a cycle: up to one before the crossing
    # each segment's progress (deg) at the end of every cycle, its speed per cycle and that speed's slope
    h = bt.head
    p0 = np.r_[0.0, np.where(h == 0, bt.head_fraction, 1.0)] * length
    p1 = np.r_[0.0, np.where(h == 0, bt.following_fraction, np.where(h == 1, bt.head_fraction, 1.0))] * length
    v0, v1 = np.diff(p0) / DT, np.diff(p1) / DT
    s0, s1 = np.diff(np.r_[0.0, v0]) / DT, np.diff(np.r_[0.0, v1]) / DT
    assert np.abs(s0).max() <= a / 2 * (1 + 1e-9) and np.abs(s1).max() <= a * (1 + 1e-9)
    # all but the few cycles where a ramp turns or a segment starts or ends run at exactly +-a/2 and +-a
    assert np.sum(np.isclose(np.abs(s0), a / 2, rtol=1e-6)) >= round(t0 / DT) - 6
    assert np.sum(np.isclose(np.abs(s1), a, rtol=1e-6)) >= round(2 * np.sqrt(length / a) / DT) - 6
    both = np.flatnonzero((v0 > 0) & (v1 > 0))[2:-2]  # the blend, sqrt(L/a) long: both move
    assert len(both) >= round(np.sqrt(length / a) / DT) - 6
    assert np.allclose(s0[both], -a / 2, rtol=1e-6) and np.allclose(s1[both], a, rtol=1e-6)


def test_a_mode_change_stops_the_feed_block():
    """A feed block followed by a rapid ends at rest at full acceleration: 10 mm at 50 mm/s takes
    L/v + v/a = 0.2167 s, then the rapid (10 mm at 500 mm/s, a 3000: a triangle 2 sqrt(L/a)) starts."""
    p = L.LinuxCNCPlanner()
    joints = np.array([[10.0, 0, 0, 0, 0], [20.0, 0, 0, 0, 0]])
    seg = p.segments(M, np.zeros(5), joints, np.array([False, True]), np.array([3000.0, 0.0]), np.zeros(2, bool))
    bt = p.run(seg)
    t0 = 10 / 50 + 50 / A_LIN
    assert t0 - 1e-9 <= bt.end[0] <= t0 + DT
    assert bt.start[1] == bt.end[0]
    t1 = 2 * np.sqrt(10 / A_LIN)
    assert bt.end[0] + t1 - 1e-9 <= bt.end[1] <= bt.end[0] + t1 + DT


def test_dropped_segments_keep_the_positions_of_the_others():
    """A repeated point first and in the middle: the BlockTimes of the moving segments with the
    dropped ones ending where the one before ends (the first at 0), and the positions at every
    cycle those of the program without them."""
    p = L.LinuxCNCPlanner()
    joints = np.array([[0.0, 0, 0, 0, 0], [1.0, 0, 0, 0, 0.5], [1.0, 0, 0, 0, 0.5], [2.0, 0, 0, 0, 1.0]])
    seg = p.segments(M, np.zeros(5), joints, np.zeros(4, bool), np.full(4, 600.0), np.ones(4, bool))
    t = p.run(seg)
    w = p.run(p.segments(M, np.zeros(5), joints[[1, 3]], np.zeros(2, bool), np.full(2, 600.0), np.ones(2, bool)))
    assert t.end[0] == 0.0 and t.start[0] == 0.0
    assert t.start[1] == w.start[0] and t.end[1] == w.end[0]
    assert t.start[2] == t.end[2] == w.end[0]
    assert t.start[3] == w.start[1] and t.end[3] == w.end[1]
    assert np.array_equal(t.head[t.head < 4], np.array([1, 3])[w.head[w.head < 2]])
    assert np.all(t.head[w.head == 2] == 4)
    assert np.allclose(t.positions(np.zeros(5), joints), w.positions(np.zeros(5), joints[[1, 3]]), atol=1e-12)


def test_positions_are_the_head_and_following_fractions_by_hand():
    bt = L.BlockTimes(start=np.zeros(2), end=np.ones(2), head=np.array([0, 0, 1, 2]),
                      head_fraction=np.array([0.5, 0.9, 0.25, 0.0]), following=np.array([1, 1, 2, 3]),
                      following_fraction=np.array([0.0, 0.1, 0.0, 0.0]))
    start = np.array([0.0, 0.0])
    joints = np.array([[2.0, 0.0], [2.0, 4.0]])
    pos = bt.positions(start, joints)
    assert np.allclose(pos, [[1.0, 0.0], [1.8, 0.4], [2.0, 1.0], [2.0, 4.0]])


def test_row_run_writes_four_decimals_and_degrees():
    """row_run rounds the joints as the writer does (4 decimals, mm and deg) and returns radians;
    its block times are G93 F = 60 / t; row_times counts from the row's first point."""
    p = L.LinuxCNCPlanner()
    entry = np.array([0.0, 0.0, 10.0, 0.0, 0.0])
    q = np.array([[0.0, 0.0, 0.0, 0.0, 0.0], [5.00004, 0.0, 0.0, 0.0, np.radians(1.00004)],
                  [10.0, 0.0, 0.0, 0.0, np.radians(2.0)]])
    bt, joints = p.row_run(M, q, np.array([2.0, 2.0]), entry, 4.0)
    assert np.allclose(joints[-1], [10.0, 0, 0, 0, np.radians(2.0)], atol=1e-12)
    at_corner = bt.head == 2  # the last block runs
    seg = p.segments(M, [0, 0, 10.0, 0, 0], [[0, 0, 0, 0, 0], [5.0, 0, 0, 0, 1.0], [10.0, 0, 0, 0, 2.0]],
                     np.zeros(3, bool), np.array([15.0, 30.0, 30.0]), np.ones(3, bool))
    want = p.run(seg)
    assert np.array_equal(want.end, bt.end) and at_corner.any()
    assert np.allclose(p.row_times(M, q, np.array([2.0, 2.0]), entry, 4.0), bt.end[1:] - bt.end[0])
    # each block long enough to run at its feed: 2 s apiece after the 4 s entry move (plus the ramps)
    assert bt.end[-1] == pytest.approx(8.0, abs=0.05)
    # block times below 1 us are taken as 1 us (F of at most 6e7)
    fast, _ = p.row_run(M, q, np.array([0.0, 0.0]), entry, 0.0)
    assert np.all(np.isfinite(fast.end))


# ---- linuxcnc.py: the floor and the block ends -----------------------------------------------------------


def _straight_row(n: int, b_deg: float, length: float = 20.0):
    x = np.linspace(0, length, n)
    Bq = np.radians(np.linspace(0, b_deg, n))
    q = np.column_stack([x, np.zeros(n), np.full(n, PIVOT), np.zeros(n), Bq])
    tip = M.tool_pose_np(np.zeros(n), Bq, q[:, 0], q[:, 1], q[:, 2])[0]
    return q, tip


def test_row_floor_without_a_feed_is_the_bound_of_the_axes_only():
    """feed None (or 0 at a point) does not bound a block: the floor of a straight row moving X 20 mm
    with B still is one block at the X speed, 20/500 s; with a feed of 600 mm/min, 20 mm / 10 mm/s."""
    q, tip = _straight_row(9, 0.0)
    p = L.LinuxCNCPlanner()
    rows = np.zeros(9, int)
    assert p.row_floor(M, rows, q, tip, None, 0.01)[0] == pytest.approx(20 / 500, rel=1e-9)
    assert p.row_floor(M, rows, q, tip, np.zeros(9), 0.01)[0] == pytest.approx(20 / 500, rel=1e-9)
    assert p.row_floor(M, rows, q, tip, np.full(9, 600.0), 0.01)[0] == pytest.approx(2.0, rel=1e-9)
    # the longest block considered: 4 points, so the 9 points are at least 3 blocks (2 of 3 steps, 1 of 2)
    got = L.least_row_times(M, rows, q, tip, np.full(9, 600.0), 0.01, max_points=3)[0]
    assert got == pytest.approx(2.0, rel=1e-9)
    # with B turning 8 deg over the row: each block at least sqrt(2 max(d_i / a_i)), best with 3 blocks
    q, tip = _straight_row(9, 8.0)
    got = L.least_row_times(M, rows, q, tip, np.full(9, 1e9), 100.0, max_points=3)[0]
    d_b = np.radians(8.0) / 8  # per step
    want = min(
        sum(max(np.sqrt(2 * max(s * 2.5 / 3000, s * d_b / np.radians(300.0))), s * 2.5 / 500, s * d_b / np.radians(60))
            for s in split)
        for split in ((3, 3, 2), (3, 2, 3), (2, 3, 3)))
    assert got == pytest.approx(want, rel=1e-12)


def test_block_ends_of_short_rows_and_rows_without_motion():
    """A row of one point is its own end; a row of repeated points has no chain of moving blocks: None."""
    p = L.LinuxCNCPlanner()
    q = np.zeros((1, 5))
    assert np.array_equal(p.block_ends(M, q, np.zeros(1), np.ones((1, 4), bool), q[0], 1.0), [0])
    q = np.zeros((3, 5))
    assert p.block_ends(M, q, np.arange(3.0), np.ones((3, 4), bool), q[0] + [0, 0, 10, 0, 0], 1.0) is None


def _chain_time(p, q, t, ends, entry_q, entry_time):
    return float(p.row_run(M, q[ends], np.diff(t[ends]), entry_q, entry_time)[0].end[-1])


@pytest.mark.parametrize("entry_mm", [0.0, 10.0])
def test_block_ends_are_the_fastest_on_the_model_by_brute_force(entry_mm):
    """A straight row of 7 points along X with B turning, every block allowed but those over 4 points:
    the chosen ends run through the planner model (servo cycles) no slower than the best of every choice
    but a cycle per block, and the one block that fits is not allowed, so the choice is a real one.
    Without an entry move (entry at the first point) the row starts from rest."""
    n = 7
    q, tip = _straight_row(n, 3.0, 3.0)
    t = np.linspace(0.0, 0.03, n)  # the law asks for 100 mm/s: more than short blocks reach
    ok = np.ones((n, 4), bool)
    p = L.LinuxCNCPlanner()
    entry_q = q[0] + [0, 0, entry_mm, 0, 0]
    entry_time = 60 * entry_mm / 2000.0
    ends = p.block_ends(M, q, t, ok, entry_q, entry_time)
    assert ends[0] == 0 and ends[-1] == n - 1 and np.diff(ends).max() <= 4
    best = min(_chain_time(p, q, t, np.r_[0, 1 + np.flatnonzero(mask), n - 1], entry_q, entry_time)
               for mask in itertools.product([False, True], repeat=n - 2)
               if np.diff(np.r_[0, 1 + np.flatnonzero(mask), n - 1]).max() <= 4)
    assert _chain_time(p, q, t, ends, entry_q, entry_time) <= best + (len(ends) - 1) * DT


# ---- blocks.py --------------------------------------------------------------------------------------------


def test_tool_tips_are_the_pivot_less_the_tool_axis():
    """tip = (X, Y, Z) - pivot T, T = (sin B, -sin A cos B, cos A cos B) on the AB head."""
    q = np.array([[1.0, 2.0, 3.0, 0.0, 0.0], [1.0, 2.0, 3.0, 0.0, np.pi / 2], [1.0, 2.0, 3.0, np.pi / 2, 0.0]])
    assert np.allclose(B.tool_tips(M, q), [[1, 2, 3 - PIVOT], [1 - PIVOT, 2, 3], [1, 2 + PIVOT, 3]], atol=1e-12)


def test_row_entry_is_up_the_tool_axis_at_the_entry_feed():
    q = np.array([1.0, 2.0, 3.0, 0.0, np.pi / 2])
    entry_q, t = B.row_entry(M, q, 10.0, 2000.0)
    assert np.allclose(entry_q, [11.0, 2.0, 3.0, 0.0, np.pi / 2]) and t == pytest.approx(0.3)
    assert np.array_equal(q, [1.0, 2.0, 3.0, 0.0, np.pi / 2])  # the point itself is not moved


def _brute_distance(pts, curve):
    a, d = curve[:-1], np.diff(curve, axis=0)
    rel = pts[:, None, :] - a[None]
    t = np.clip((rel * d).sum(-1) / np.maximum((d * d).sum(-1), 1e-300), 0, 1)
    return np.linalg.norm(rel - t[..., None] * d, axis=-1).min(axis=1)


def test_polyline_distance_in_chunks_is_the_distance_to_every_segment(monkeypatch):
    """Random polylines and points: the same distances whole and in chunks of a few floats (one block's
    points split, and blocks split)."""
    rng = np.random.default_rng(11)
    curve = np.cumsum(rng.normal(0, 1, (5, 6, 3)), axis=1)
    pts = rng.normal(0, 2, (5, 7, 3))
    want = np.array([_brute_distance(pts[b], curve[b]) for b in range(5)])
    assert np.allclose(B._polyline_distance(pts, curve), want, atol=1e-12)
    for chunk in (1, 20, 100, 200, 250, 400):  # 105 floats a block: blocks by 1, 2 and 3
        monkeypatch.setattr(B, "_DISTANCE_CHUNK", chunk)
        assert np.allclose(B._polyline_distance(pts, curve), want, atol=1e-12), chunk
    # a degenerate segment (two equal vertices) is a point
    curve = np.zeros((1, 2, 3))
    assert np.allclose(B._polyline_distance(np.array([[[3.0, 4.0, 0.0]]]), curve), [[5.0]])


def test_tip_deviation_of_a_point_path_and_in_batches(monkeypatch):
    path = np.array([[1.0, 1.0, 1.0]])
    assert np.allclose(B.tip_deviation([[1.0, 1.0, 4.0], [1.0, 5.0, 4.0]], path), [3.0, 5.0])
    # a path of one segment: the distance to the segment, not to its first vertex
    seg = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0]])
    assert np.allclose(B.tip_deviation([[5.0, 2.0, 0.0], [12.0, 0.0, 1.0]], seg), [2.0, np.sqrt(5.0)])
    rng = np.random.default_rng(5)
    path = np.cumsum(rng.normal(0, 1, (9, 3)), axis=0)
    pts = rng.normal(0, 3, (13, 3))
    want = _brute_distance(pts, path)
    monkeypatch.setattr(B, "_DEVIATION_BATCH", 17)  # two segments' worth: batches of two points
    assert np.allclose(B.tip_deviation(pts, path), want, atol=1e-12)
    assert np.allclose(B.tip_deviation(pts[0], path), want[:1], atol=1e-12)


def test_programmed_tip_path_steps_and_vertices():
    """Three points: X 1 mm with B still (sub = 2 steps) then B 1 deg (4 steps of 0.25 deg): 7
    vertices, each the tip of the linearly interpolated joints, after the entry tip."""
    q = np.array([[0.0, 0, PIVOT, 0, 0], [1.0, 0, PIVOT, 0, 0], [1.0, 0, PIVOT, 0, np.radians(1.0)]])
    path, at = B._tip_polyline(M, q, None, 2, np.radians(0.25))
    assert np.array_equal(at, [0, 2, 6])
    s = np.r_[0.0, 0.5, 1.0, 1.25, 1.5, 1.75, 2.0]
    qs = np.array([q[0] + min(v, 1.0) * (q[1] - q[0]) + max(v - 1.0, 0.0) * (q[2] - q[1]) for v in s])
    assert np.allclose(path, B.tool_tips(M, qs), atol=1e-12)
    entry = np.array([0.0, 0.0, 10.0])
    full, at = B._tip_polyline(M, q, entry, 2, np.radians(0.25))
    assert np.array_equal(at, [1, 3, 7]) and np.allclose(full[0], entry) and np.allclose(full[1:], path)
    assert np.allclose(B.programmed_tip_path(M, q, entry, 2, np.radians(0.25)), full)
    # the defaults: 16 steps a block, and a step turns B by at most 0.25 deg
    assert len(B.programmed_tip_path(M, q)) == 1 + 16 + 16
    q[2, 4] = np.radians(5.0)
    assert len(B.programmed_tip_path(M, q)) == 1 + 16 + 20


def _arc(n: int, radius: float, step_deg: float, rows=None):
    """Tips on a circle in the XY plane, the tool vertical (A = B = 0): a block's tip curve is its chord."""
    th = np.radians(step_deg * np.arange(n))
    tip = np.column_stack([radius * np.sin(th), radius * (1 - np.cos(th)), np.zeros(n)])
    q = np.column_stack([tip + [0, 0, PIVOT], np.zeros(n), np.zeros(n)])
    return (np.zeros(n, int) if rows is None else np.asarray(rows)), q, tip


def test_block_reach_is_the_sagitta_rule_on_a_circle():
    """Chords of a circle (R 100 mm, 0.2 deg a point): a block of k steps passes when every skipped tip is
    within the tolerance of its chord, (worked here point by point), and once it fails the longer
    ones from that point are not tried; blocks stop at their row's end and at max_points."""
    rows = np.repeat([0, 1], [12, 9])
    rows, q, tip = _arc(21, 100.0, 0.2, rows)
    tol = 0.004
    ok = B.block_reach(M, rows, q, tip, tol, 8)
    assert ok.shape == (21, 8) and ok[:, 0].all()
    for a in range(21):
        alive = True
        for k in range(2, 9):
            b = a + k
            fits = b < 21 and rows[b] == rows[a]
            if fits:
                dev = _brute_distance(tip[a + 1:b], tip[[a, b]]).max()
                alive = alive and dev <= tol
            assert ok[a, k - 1] == (fits and alive), (a, k)
    # the sagitta R (1 - cos(k theta / 2)) of an even k: 4 steps 2.4 um, 6 steps 5.5 um; 5 steps:
    # R (cos(theta / 2) - cos(5 theta / 2)) = 3.7 um
    assert ok[0, 3] and ok[0, 4] and not ok[0, 5]
    assert B.block_reach(M, rows[:0], q[:0], tip[:0], tol).shape == (0, B.MAX_BLOCK_POINTS)
    one = B.block_reach(M, rows[:1], q[:1], tip[:1], tol, 4)
    assert one.tolist() == [[True, False, False, False]]


def test_block_reach_also_holds_the_middle_of_each_skipped_step():
    """Tips on the X axis, B alternating 0 / 2 deg with X set so that every tip stays on the line: the
    skipped tip of a two-step block (B 0 -> 0) lies on its chord, but the tip at the middle of each
    skipped step (joints interpolated linearly) swings off the line: the block fails a tolerance
    below that swing and passes above it."""
    n = 5
    x = np.arange(n) * 1.0
    Bq = np.radians(np.array([0.0, 2.0, 0.0, 2.0, 0.0]))
    tip = np.column_stack([x, np.zeros(n), np.zeros(n)])
    q = np.column_stack([M.linear_axes(tip, np.zeros(n), Bq), np.zeros(n), Bq])
    mid = B.tool_tips(M, 0.5 * (q[1:] + q[:-1]))
    off = np.linalg.norm(mid[:, 1:], axis=1).max()
    assert off > 1e-3
    ok = B.block_reach(M, np.zeros(n, int), q, tip, 0.5 * off, 4)
    assert not ok[0, 1]  # the skipped tip of a 2-step block (B 0 -> 0) is on the chord, its middles are not
    assert B.block_reach(M, np.zeros(n, int), q, tip, 2 * off + 1e-3, 4)[0, 1]


def test_decimate_is_the_greedy_walk_over_the_reach():
    """Hand example: rows of 6 and 4 points; from 0 two points reach, from 2 three (to the row's end), from
    6 one, from 7 three (clipped at the row's end 9): ends 0 2 5 | 6 7 9."""
    rows = np.repeat([0, 1], [6, 4])
    ok = np.zeros((10, 3), bool)
    ok[:, 0] = True
    ok[0, :2] = True
    ok[2, :] = True
    ok[7, :] = True
    keep = B.decimate(M, rows, np.zeros((10, 5)), np.zeros((10, 3)), 0.005, ok=ok)
    assert np.flatnonzero(keep).tolist() == [0, 2, 5, 6, 7, 9] and keep.dtype == bool
    assert B.decimate(M, rows[:0], np.zeros((0, 5)), np.zeros((0, 3)), 0.005).shape == (0,)
    # without ok: block_reach at BLOCK_TOLERANCE_SHARE of the tolerance
    rows, q, tip = _arc(21, 100.0, 0.2)
    tol = 0.004 / B.BLOCK_TOLERANCE_SHARE
    ok = B.block_reach(M, rows, q, tip, 0.004)
    assert np.array_equal(B.decimate(M, rows, q, tip, tol), B.decimate(M, rows, q, tip, tol, ok=ok))
    assert np.flatnonzero(B.decimate(M, rows, q, tip, tol)).tolist() == [0, 5, 10, 15, 20]


def test_controller_plan_floor_and_blocks():
    plan = B.ControllerPlan(controller="x", keep=np.array([True, False, True, True, True]), block_time=np.zeros(5),
                            t_plan=np.zeros(5), feed_plan=np.zeros(5), row_ids=np.array([0, 1]),
                            row_cycle_time=np.zeros(2), cycle_time=0.0, row_deviation=np.zeros(2),
                            row_floor=np.array([0.5, 0.25]))
    assert plan.blocks == 2 and plan.floor == 0.75
    assert B.ControllerPlan(**{**vars(plan), "row_floor": None}).floor is None


def test_blend_excess_counts_the_head_of_a_blend_over_the_limit_and_both_on_request():
    """Samples: (head, following, fraction, deviation). Only samples in a blend (fraction > 0) over the
    limit count: on the block that decelerates into it (the head), and with ``following`` also on the
    block it blends into; the entry move's (segment 0) goes to the first block."""
    run = SimpleNamespace(head=np.array([0, 1, 1, 2, 2, 3]), following=np.array([1, 2, 2, 3, 3, 4]),
                          following_fraction=np.array([0.2, 0.0, 0.5, 0.1, 0.3, 0.0]))
    dev = np.array([7.0, 9.0, 3.0, 6.0, 5.0, 8.0])
    # sample 0 (entry -> block 1, 7): block 1; sample 2 (1 -> 2, 3): under; samples 3, 4 (2 -> 3, 6 and 5):
    # block 2 (and block 3 as the following one); samples 1 and 5 are not in a blend
    assert B._blend_excess(run, dev, 4.0, 3).tolist() == [7.0, 6.0, 0.0]
    assert B._blend_excess(run, dev, 4.0, 3, following=True).tolist() == [7.0, 6.0, 6.0]


class _FakePlanner:
    """A planner that runs every block in its commanded time (no blends; ``slow``: a row of that many
    blocks runs 3 times slower) and proposes the block ends ``ends``."""

    name = "fake"
    title = "Fake"

    def __init__(self, ends=None, floor=None, slow=-1):
        self.ends, self.floor, self.slow, self.calls = ends, floor, slow, []

    def block_ends(self, machine, q, t_opt, ok, entry_q, entry_time):
        self.calls.append(len(q))
        return None if self.ends is None else np.asarray(self.ends)

    def row_floor(self, machine, rows, q, tip, feed, tolerance, end_offset=0.0):
        self.floor_args = (feed, tolerance)
        return self.floor

    def row_run(self, machine, q_blocks, block_time, entry, entry_time):
        bt = np.asarray(block_time, float) * (3.0 if len(block_time) == self.slow else 1.0)
        end = np.cumsum(np.r_[entry_time, bt])
        k = len(end)
        run = SimpleNamespace(end=end, head=np.arange(k), following=np.arange(1, k + 1),
                              following_fraction=np.zeros(k))
        return run, np.asarray(q_blocks, float)  # one "servo cycle" per segment, at its end (the protocol's layout)


def test_place_takes_the_planner_ends_only_when_the_model_runs_them_faster():
    """A straight row of 9 points (every block fits: decimate keeps 0 and 8) and a row of 2. The planner
    proposes 0 4 8: at the same time decimate's ends stay; when the model runs the one block 3 times
    slower the proposal is taken, when it runs the two blocks slower it is not; None keeps decimate's
    ends; a row of fewer than 3 points is not asked."""
    rows = np.repeat([0, 1], [9, 2])
    x = np.r_[np.linspace(0, 4, 9), 10.0, 11.0]
    tip = np.column_stack([x, np.zeros(11), np.zeros(11)])
    q = np.column_stack([tip + [0, 0, PIVOT], np.zeros(11), np.zeros(11)])
    t = np.r_[np.arange(9.0), 0.0, 1.0]
    feed = np.full(2, 2000.0)

    def placed(p):
        return np.flatnonzero(B.place(p, M, rows, q, tip, t, 0.005, entry_height=10.0, entry_feed=feed)).tolist()

    p = _FakePlanner(ends=[0, 4, 8])
    assert placed(p) == [0, 8, 9, 10] and p.calls == [9]
    assert placed(_FakePlanner(ends=[0, 4, 8], slow=1)) == [0, 4, 8, 9, 10]
    assert placed(_FakePlanner(ends=[0, 4, 8], slow=2)) == [0, 8, 9, 10]
    assert placed(_FakePlanner(ends=[0, 8], slow=1)) == [0, 8, 9, 10]
    assert placed(_FakePlanner(ends=None)) == [0, 8, 9, 10]
    # entered as predict enters a row: 10 mm up the tool axis at the row's entry feed (0.3 s at 2000 mm/min)
    p = _FakePlanner(ends=[0, 4, 8])
    seen = []
    p.block_ends = lambda m, qq, tt, ok, eq, et: seen.append((eq, et, ok.shape)) or np.array([0, 4, 8])
    placed(p)
    assert np.allclose(seen[0][0], q[0] + [0, 0, 10.0, 0, 0]) and seen[0][1] == pytest.approx(0.3)
    assert seen[0][2] == (9, B.MAX_BLOCK_POINTS)


def test_predict_times_points_by_their_share_of_the_pivot_travel():
    """The fake model runs each block in its commanded time: a row of 5 points with blocks 0-2-4 (pivot
    travel 1, 1, 2, 2 mm; law at 1 s a point): t_plan at the dropped point 1 is 1/2 of the first block's
    2 s, at point 3 1/2 of the second's 2 s after 2 s; the feed is the block's tip chord over its time
    at its end, interpolated by the pivot travel between, 0 at the row's ends;
    the row's time from the first point (the entry move not counted)."""
    x = np.array([0.0, 1.0, 2.0, 4.0, 6.0])
    tip = np.column_stack([x, np.zeros(5), np.zeros(5)])
    q = np.column_stack([tip + [0, 0, PIVOT], np.zeros(5), np.zeros(5)])
    t = np.arange(5.0)
    p = _FakePlanner(floor=np.array([1.5]))
    keep = np.array([True, False, True, False, True])
    plan = B.predict(p, M, np.zeros(5, int), q, tip, t, keep, entry_height=10.0, entry_feed=np.array([2000.0]))
    assert plan.controller == "fake"
    assert np.allclose(plan.t_plan, [0.0, 1.0, 2.0, 2.0 + 2 / 4 * 2, 4.0])
    assert np.allclose(plan.block_time, [0, 0, 2.0, 0, 2.0])
    # blocks' feeds 60 * 2 mm / 2 s and 60 * 4 mm / 2 s at their ends (s = 2, 6), linear in s between
    assert np.allclose(plan.feed_plan, [0.0, 60.0, 60.0, 90.0, 0.0])
    assert plan.row_cycle_time.tolist() == [4.0] and plan.cycle_time == 4.0
    assert plan.row_floor is None and plan.row_deviation.tolist() == [0.0]
    assert plan.keep.tolist() == keep.tolist() and plan.row_ids.tolist() == [0]
    # with a tolerance: the floor asked for at the tolerance and with the programmed feed
    plan = B.predict(p, M, np.zeros(5, int), q, tip, t, keep, entry_height=10.0, entry_feed=np.array([2000.0]),
                     tolerance=1.0, feed=np.full(5, 600.0))
    assert plan.row_floor.tolist() == [1.5] and plan.floor == 1.5
    assert p.floor_args[1] == 1.0 and np.array_equal(p.floor_args[0], np.full(5, 600.0))
    assert plan.row_deviation[0] == pytest.approx(0.0, abs=1e-9)  # the blocks run on the straight path
    B.predict(p, M, np.zeros(5, int), q, tip, t, keep, entry_height=10.0, entry_feed=np.array([2000.0]), tolerance=1.0)
    assert p.floor_args[0] is None  # the feed not given: unknown to the floor


def test_predict_times_each_row_from_its_own_first_point():
    """Two rows of the same shape (the second after the first in the arrays, entered at 6000 mm/min): the
    same plan per row, each row's times from its own first point."""
    x = np.array([0.0, 1.0, 2.0, 4.0, 6.0])
    tip = np.column_stack([np.r_[x, x + 50.0], np.zeros(10), np.zeros(10)])
    q = np.column_stack([tip + [0, 0, PIVOT], np.zeros(10), np.zeros(10)])
    t = np.r_[np.arange(5.0), np.arange(5.0)]
    keep = np.tile([True, False, True, False, True], 2)
    p = _FakePlanner()
    plan = B.predict(p, M, np.repeat([7, 3], 5), q, tip, t, keep, entry_height=10.0,
                     entry_feed=np.array([2000.0, 6000.0]))
    assert np.allclose(plan.t_plan, np.tile([0.0, 1.0, 2.0, 3.0, 4.0], 2))
    assert np.allclose(plan.feed_plan, np.tile([0.0, 60.0, 60.0, 90.0, 0.0], 2))
    assert plan.row_ids.tolist() == [7, 3] and np.allclose(plan.row_cycle_time, [4.0, 4.0])
    assert plan.cycle_time == pytest.approx(8.0)


def test_run_deviation_measures_each_head_against_its_window_of_the_path():
    """The path: vertices at x = 0 .. 15 mm on the X axis; segments end at vertices 2, 5, 9, 12 (segment 0
    the entry move). A sample while segment h executes is measured against the path from the vertex
    before h's start to the vertex after the end of the segment after h (h = 0 from the path's start;
    past the last segment, around the last end). Tips at every vertex under every head: distance 0
    inside the window, the distance along the line to the window outside it."""
    path = np.column_stack([np.arange(16.0), np.zeros(16), np.zeros(16)])
    ends = np.array([2, 5, 9, 12])
    window = {0: (0, 6), 1: (1, 10), 2: (4, 13), 3: (8, 13), 4: (11, 13)}  # (first, last) vertex, by hand
    heads = np.repeat(np.arange(5), 16)
    tips = np.tile(path, (5, 1)) + [0.0, 0.0, 0.0]
    got = B._run_deviation(SimpleNamespace(head=heads), tips, path, ends)
    want = np.array([max(window[h][0] - v, 0, v - window[h][1]) for h in range(5) for v in range(16)], float)
    assert np.allclose(got, want, atol=1e-12)
    # off the line by 0.5 mm: the distance to the nearest window vertex
    got = B._run_deviation(SimpleNamespace(head=heads), tips + [0.0, 0.5, 0.0], path, ends)
    assert np.allclose(got, np.hypot(want, 0.5), atol=1e-12)


def test_run_deviation_is_each_samples_distance_to_its_window_by_brute_force():
    """A random walk of 300 path vertices, 40 segments, 5000 samples around it under heads in any
    order: each sample's distance equals tip_deviation (every segment, batched numpy) against the
    stretch of the path its head's window covers (the rule of the test above)."""
    rng = np.random.default_rng(3)
    path = np.cumsum(rng.normal(0.0, 1.0, (300, 3)), axis=0)
    ends = np.sort(rng.choice(np.arange(1, 300), 40, replace=False))
    heads = rng.integers(0, 42, 5000)
    tips = path[rng.integers(0, 300, 5000)] + rng.normal(0.0, 0.3, (5000, 3))
    got = B._run_deviation(SimpleNamespace(head=heads), tips, path, ends)
    m = len(ends)
    for i in range(0, 5000, 7):
        h = heads[i]
        lo = 0 if h == 0 else ends[min(h - 1, m - 1)]
        hi = ends[min(h + 1, m - 1)]
        want = B.tip_deviation(tips[i], path[max(lo - 1, 0):min(hi + 2, 300)])[0]
        assert got[i] == pytest.approx(want, abs=1e-12), i


def test_chord_deviation_is_each_blocks_chord_against_its_stretch_of_the_path():
    """Tool vertical (A = B = 0): a block's tip curve is its chord. Points at x = 0, 2, 4 mm on the X axis,
    at path vertices 0, 2, 4 of the path (0,0) (1,1) (2,0) (3,-2) (4,0) (3,0.1): the first chord's middle
    is 1/sqrt 2 from the tent over it, the second's 2/sqrt 5 from the V under it (the path's last vertex,
    after the block's end, is not its stretch)."""
    tip = np.array([[0.0, 0, 0], [2.0, 0, 0], [4.0, 0, 0]])
    q = np.column_stack([tip + [0, 0, PIVOT], np.zeros(3), np.zeros(3)])
    path = np.array([[0.0, 0, 0], [1.0, 1, 0], [2.0, 0, 0], [3.0, -2, 0], [4.0, 0, 0], [3.0, 0.1, 0]])
    got = B._chord_deviation(M, q, np.array([0, 1, 2]), path, np.array([0, 2, 4]))
    assert np.allclose(got, [1 / np.sqrt(2), 2 / np.sqrt(5)], atol=1e-12)
    got = B._chord_deviation(M, q, np.array([0, 2]), path, np.array([0, 2, 4]))
    assert got.shape == (1,) and got[0] == pytest.approx(2 / np.sqrt(5), rel=1e-12)  # one block 0-4: the V


class _BlendPlanner:
    """Runs each block in max(commanded, t_min) s; at every junction between blocks i and i + 1 one servo
    sample in the blend, off the path (in Y) by c_i / (T_i T_{i+1}) (a parabolic blend's deviation grows
    with the square of the speed; c one value for every junction or one per junction), and one sample
    at every block end, on the path."""

    name = "blend"

    def __init__(self, c: float, t_min: float = 0.0):
        self.c, self.t_min, self.calls = c, t_min, 0

    def row_run(self, machine, q_blocks, block_time, entry, entry_time):
        self.calls += 1
        T = np.maximum(np.asarray(block_time, float), self.t_min)
        end = np.cumsum(np.r_[entry_time, T])
        heads, follow, frac, joints = [], [], [], []
        for i in range(1, len(q_blocks)):  # block i ends at q_blocks[i]
            heads.append(i)
            follow.append(i + 1)
            frac.append(0.0)
            joints.append(q_blocks[i])
            if i + 1 < len(q_blocks):
                heads.append(i)
                follow.append(i + 1)
                frac.append(0.5)
                c = np.broadcast_to(np.asarray(self.c, float), (len(q_blocks) - 2,))[i - 1]
                joints.append(q_blocks[i] + [0.0, c / (T[i - 1] * T[i]), 0, 0, 0])
        run = SimpleNamespace(end=end, head=np.array(heads), following=np.array(follow),
                              following_fraction=np.array(frac))
        return run, np.array(joints)


def _line(n: int, bump: float = 0.0):
    tip = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
    tip[3 if n > 3 else 0, 1] = bump
    q = np.column_stack([tip + [0, 0, PIVOT], np.zeros(n), np.zeros(n)])
    return q, tip


def test_hold_row_slows_the_block_heading_a_blend_over_the_limit_in_fourth_root_steps():
    """Blocks 0-2-4-6 on a straight path, 2 s each; the fake blend between blocks i and i + 1 deviates
    c_i / (T_i T_(i+1)): at point 4 (blocks 2 and 3) 4 limits, at point 2 half a limit. Each round
    lengthens the block heading a blend over the limit, block 2, by sqrt(dev / limit) and 2%, until
    16 limits s^2 / (2 s T_2) <= 1 limit (T_2 >= 8 s): 2 -> 4.08 -> 5.83 -> 6.96 -> 7.61 -> 7.96 -> 8.14 s;
    blocks 1 and 3 keep their 2 s. Worked here by that recurrence, one run per round and one to check.
    Without a path one run at the law's times."""
    q, tip = _line(7)
    t = np.arange(7.0)
    k = np.array([0, 2, 4, 6])
    lim = 0.01
    p = _BlendPlanner(c=[0.5 * lim * 4.0, 4 * lim * 4.0])  # c / (T_i T_{i+1}) at T = 2 s
    kk, bt, tk, worst = B._hold_row(p, M, q, k, t, q[0], 0.0, tip, np.arange(7), lim)
    T2, runs = 2.0, 1
    while 16.0 / (2.0 * T2) > 1.0:
        T2 *= (16.0 / (2.0 * T2)) ** 0.5 * 1.02
        runs += 1
    assert kk.tolist() == [0, 2, 4, 6] and p.calls == runs == 7
    assert np.allclose(bt, [2.0, T2, 2.0], rtol=1e-12)
    assert worst == pytest.approx(16.0 * lim / (2.0 * T2), rel=1e-9) and worst <= lim
    assert np.allclose(tk, np.r_[0.0, np.cumsum(bt)], rtol=1e-12)
    p = _BlendPlanner(c=p.c)
    kk, bt, tk, worst = B._hold_row(p, M, q, k, t, q[0], 0.0, None, None, lim)
    assert p.calls == 1 and bt.tolist() == [2.0, 2.0, 2.0] and worst == 0.0 and tk.tolist() == [0, 2, 4, 6]


def test_hold_row_lengthens_from_what_the_model_took_and_stops_after_its_rounds():
    """The model runs no block in less than 3 s: the block heading the blend over the limit (4 limits
    at 3 s x 3 s) is lengthened from the 3 s it took, not the 2 s commanded: 3 x sqrt(4) x 1.02 on the
    second run. A blend that no speed helps (it is off the path whatever the times) is tried _ROUNDS
    times, both of its blocks slowed once a round does not bring it down, and run once more on the
    times the last round set (what it returns is what was run); a deviation off every blend (the
    block's own tip curve) stops at once."""
    q, tip = _line(7)
    t = np.arange(7.0)
    k = np.array([0, 2, 4, 6])
    lim = 0.01

    class Logged(_BlendPlanner):
        def row_run(self, machine, q_blocks, block_time, entry, entry_time):
            self.times = [*getattr(self, "times", []), np.array(block_time, float)]
            return super().row_run(machine, q_blocks, block_time, entry, entry_time)

    p = Logged(c=[0.0, 4 * lim * 3.0 * 3.0], t_min=3.0)
    _, bt, tk, worst = B._hold_row(p, M, q, k, t, q[0], 0.0, tip, np.arange(7), lim)
    assert p.times[1].tolist() == pytest.approx([2.0, 3.0 * 2.0 * 1.02, 2.0], rel=1e-12)
    assert worst <= lim and np.allclose(tk, np.r_[0.0, np.cumsum(np.maximum(bt, 3.0))])

    class Stuck(Logged):
        def row_run(self, machine, q_blocks, block_time, entry, entry_time):
            run, joints = super().row_run(machine, q_blocks, block_time, entry, entry_time)
            joints[run.following_fraction > 0, 1] = self.c  # the blend sample stays c off the path
            return run, joints

    p = Stuck(c=2 * lim)
    _, bt, _, worst = B._hold_row(p, M, q, k, t, q[0], 0.0, tip, np.arange(7), lim)
    assert p.calls == B._ROUNDS + 1 and worst == pytest.approx(2 * lim)
    assert np.array_equal(p.times[-1], bt) and not np.array_equal(p.times[-2], bt)
    # round 1 slows the heads (blocks 1, 2) only; from round 2 on (no better) both blocks of each blend
    assert p.times[1][2] == 2.0 and p.times[2][2] > 2.0

    class Own(_BlendPlanner):
        def row_run(self, machine, q_blocks, block_time, entry, entry_time):
            run, joints = super().row_run(machine, q_blocks, block_time, entry, entry_time)
            run.following_fraction = np.zeros_like(run.following_fraction)  # no sample is in a blend
            return run, joints

    p = Own(c=4 * lim * 4.0)
    _, bt, _, worst = B._hold_row(p, M, q, k, t, q[0], 0.0, tip, np.arange(7), lim)
    assert p.calls == 1 and bt.tolist() == [2.0, 2.0, 2.0] and worst == pytest.approx(4 * lim)


@pytest.mark.parametrize("lim, split", [(0.005, True), (0.0102, False)])
def test_hold_row_splits_a_block_whose_own_chord_leaves_too_little(lim, split):
    """Points on the X axis, point 3 lifted 0.01 mm: the block 2-6 skips it, its chord 0.01 mm off the
    path: over 0.99 of a 5 um limit it is split into its points (2 3 4 5 6); a limit of 10.2 um takes it
    (0.99 limit = 10.1 um). The straight block 0-2 is never split."""
    q, tip = _line(7, bump=0.01)
    t = np.arange(7.0)
    p = _BlendPlanner(c=0.0)
    kk, bt, _, _ = B._hold_row(p, M, q, np.array([0, 2, 6]), t, q[0], 0.0, tip, np.arange(7), lim)
    assert kk.tolist() == ([0, 2, 3, 4, 5, 6] if split else [0, 2, 6])
    assert bt.tolist() == ([2.0, 1.0, 1.0, 1.0, 1.0] if split else [2.0, 4.0])
    # a row of that one block alone
    kk, bt, _, _ = B._hold_row(p, M, q, np.array([2, 6]), t, q[0], 0.0, tip, np.arange(7), lim)
    assert kk.tolist() == ([2, 3, 4, 5, 6] if split else [2, 6])


def test_predict_with_a_tolerance_splits_the_blocks_and_marks_their_points():
    """predict with the user's tolerance 5 um (executed limit 4 um): the block 2-6 over a point lifted
    10 um is split back (keep gains 3 4 5; their block times the law's 1 s), the row's time the law's."""
    q, tip = _line(7, bump=0.01)
    t = np.arange(7.0)
    keep = np.array([True, False, True, False, False, False, True])
    p = _FakePlanner(floor=np.array([0.5]))
    plan = B.predict(p, M, np.zeros(7, int), q, tip, t, keep, entry_height=10.0, entry_feed=np.array([2000.0]),
                     tolerance=0.005)
    assert np.flatnonzero(plan.keep).tolist() == [0, 2, 3, 4, 5, 6]
    assert np.allclose(plan.block_time, [0, 0, 2.0, 1.0, 1.0, 1.0, 1.0])
    assert plan.row_cycle_time.tolist() == [6.0] and np.allclose(plan.t_plan, t)
    assert keep.tolist() == [True, False, True, False, False, False, True]  # the caller's array is not changed


def _triangle_chain(parts, step: float, a: float) -> float:
    """End (s) of a chain of triangle blocks of ``parts`` steps of ``step`` mm each, started from rest at
    0 (no entry move): ``_blend_chain`` without a speed cap (the inner blocks at a/2, the last at a)."""
    return _blend_chain([p * step for p in parts], a, np.inf)


@pytest.mark.parametrize("blocked, want", [((), [0, 2, 6]), (((0, 1), (0, 2)), [0, 1, 2, 6]),
                                            (tuple((i, k) for i in range(7) for k in (2, 3)), [0, 2, 4, 6])])
def test_block_ends_are_the_best_partition_of_a_triangle_chain(blocked, want):
    """Seven points l = 2 mm apart along X, a law too fast to bind, no entry move, blocks of up to 4 steps:
    the placement's chain model is the chain of triangle blocks, the inner ones at a/2 and the last (it
    ends at rest) at the whole a; the best partition of the 6 steps (brute force, blocks ``blocked``
    (i, k) not allowed). By hand with u = sqrt(l/a) = 25.8 ms: 2 + 4 steps, the first peaks at
    sqrt(2 l/(a/2)) = 2u, where the last starts (t_blend = 2u), which runs 2 sqrt(4 l/a) = 4u: 6u = 155 ms,
    against 3 + 3 steps (2 sqrt 6 + sqrt 3) u = 171 ms (the last starts sqrt(3) u before the first ends);
    without blocks of 2 and 3 steps from the first point 1 + 1 + 4, the long block starts when the first
    ends (2 sqrt 2 u): (4 + 2 sqrt 2) u = 176 ms against 4 + 2, 5 sqrt(2) u = 183 ms; with blocks of at
    most 2 steps 2 + 2 + 2, the last starts (6 - sqrt 2) u and runs 2 sqrt(2) u: (6 + sqrt 2) u = 191 ms."""
    n, step = 7, 2.0
    x = step * np.arange(n)
    q = np.column_stack([x, np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)])
    ok = np.ones((n, 4), bool)
    for i, k in blocked:
        ok[i, k] = False
    best, best_ends, second = np.inf, None, np.inf
    for parts in itertools.chain.from_iterable(itertools.product(range(1, 5), repeat=m) for m in range(1, 7)):
        if sum(parts) != n - 1:
            continue
        ends = np.r_[0, np.cumsum(parts)]
        if not all(ok[i, j - i - 1] for i, j in zip(ends[:-1], ends[1:], strict=True)):
            continue
        t = _triangle_chain(parts, step, A_LIN)
        if t < best:
            best, best_ends, second = t, ends.tolist(), best
        elif t < second:
            second = t
    assert second - best > len(best_ends) * DT  # a clear winner, beyond the servo cycles' rounding
    if want is not None:
        assert best_ends == want
    p = L.LinuxCNCPlanner()
    got = p.block_ends(M, q, np.zeros(n), ok, q[0], 0.0)
    assert got.tolist() == best_ends


def test_a_segment_that_cannot_move_raises_instead_of_exhausting_memory():
    """A G94 move at F0 (LinuxCNC's interpreter refuses it; the model should say it cannot finish). Run in
    a child process whose heap may grow by 300 MB only, so the failure cannot take the machine's memory."""
    import subprocess
    import sys

    code = (
        "import resource, re, numpy as np\n"
        "from tests.test_mutants_controller import M, L\n"
        "data = int(re.search(r'VmData:\\s+(\\d+)', open('/proc/self/status').read()).group(1)) * 1024\n"
        "resource.setrlimit(resource.RLIMIT_DATA, (data + 300 * 2 ** 20, resource.RLIM_INFINITY))\n"
        "p = L.LinuxCNCPlanner()\n"
        "seg = p.segments(M, np.zeros(5), np.array([[10.0, 0, 0, 0, 0]]), np.zeros(1, bool), np.zeros(1), "
        "np.zeros(1, bool))\n"
        "try:\n"
        "    p.run(seg)\n"
        "except RuntimeError as exc:\n"
        "    print('RuntimeError', exc)\n"
        "except MemoryError:\n"
        "    print('MemoryError')\n")
    from pathlib import Path

    root = Path(__file__).resolve().parent.parent
    out = subprocess.run([sys.executable, "-c", code], cwd=root, capture_output=True, text=True, timeout=120)
    assert out.stdout.startswith("RuntimeError"), (out.stdout, out.stderr[-500:])


def _one_update(length: float, progress: float, vel: float, a: float = 1000.0, v_cap: float = 100.0):
    """One servo cycle of ``_update`` on a lone segment; returns (progress, vel, splitting, dt_k)."""
    arrays = [np.array([x], float) for x in (length, v_cap, v_cap, a, progress, vel, DT)]
    length_a, reqvel, maxvel, acc_h, prog, v, dt_k = arrays
    fd, split = np.zeros(1, bool), np.zeros(1, bool)
    L._update(0, length_a, reqvel, maxvel, acc_h, prog, v, dt_k, fd, split, DT)
    return prog[0], v[0], bool(split[0]), dt_k[0]


def test_update_ends_a_segment_that_cannot_stop_in_time_at_the_full_deceleration():
    """checkEndCondition by hand (a = 1000 mm/s^2, 1 ms): 1 mm segment, 0.01 mm left at 10 mm/s. The
    cycle decelerates at -a: 9 mm/s, 9.5 um done, 0.5 um left. At the average speed 4.5 mm/s that is
    0.111 ms, but stopping from 9 mm/s within 0.5 um needs more than a: the end comes sooner, when
    v t - a t^2 / 2 = rem: t = (9 - sqrt(81 - 2 a rem)) / a = 55.7 us: the segment splits there."""
    prog, vel, split, dt_k = _one_update(1.0, 0.99, 10.0)
    assert vel == pytest.approx(9.0, rel=1e-12) and prog == pytest.approx(0.9995, rel=1e-12)
    assert split and dt_k == pytest.approx((9.0 - np.sqrt(81.0 - 2 * 1000 * 0.0005)) / 1000, rel=1e-9)
    # far from the end: no split; at a crawl with nothing left: ends at once (dt 0)
    prog, vel, split, dt_k = _one_update(1.0, 0.5, 10.0)
    assert not split and dt_k == DT and vel == pytest.approx(11.0) and prog == pytest.approx(0.5105)


def test_update_stops_a_crawling_segment_at_its_end():
    """0.5 mm/s with 0.2 um left (less than v dt / 2): findTrapezoidalDesiredVel has no positive speed,
    the speed would turn negative: it is 0 and the segment is at its end (dx < v dt), which splits at
    once (dt 0)."""
    prog, vel, split, dt_k = _one_update(1.0, 1.0 - 2e-4, 0.5)
    assert vel == 0.0 and prog == 1.0 and split and dt_k == 0.0
    # the same speed with 0.6 um left: 0.25 um this cycle, not yet the end
    prog, vel, split, dt_k = _one_update(1.0, 1.0 - 6e-4, 0.5)
    assert 0.0 < vel < 0.5 and prog < 1.0


def test_place_row_of_one_block_after_the_entry_by_hand():
    """One block (10 mm at 50 mm/s, a_h 1500) after an entry move of the same (trapezoids of 0.2333 s):
    the block starts when the entry decelerates below the blend speed 50 mm/s, at 0.2 s, and ends at
    0.4333 s; with G64 P = 1 um at the 90 deg corner between them the blend speed is 2 sqrt(a_h P /
    cos 45) = 2.91 mm/s: it starts at 0.2333 - 2.91 / 1500 s, on the next servo cycle (0.232 s). The
    direction that counts is the block's from the first point (the second point's is straight on)."""
    ok = np.array([[True], [False]])
    length = np.array([[10.0], [0.0]])
    vcap = np.array([[50.0], [0.0]])
    acc_h = np.array([[1500.0], [1.0]])
    direction = np.array([[[1.0, 0, 0]], [[0.0, 0, -1.0]]])
    entry = np.array([10.0, 50.0, 1500.0])
    down = np.array([0.0, 0.0, -1.0])
    T = 10 / 50 + 50 / 1500
    best, ends = L._place_row(ok, length, vcap, acc_h, direction, entry, down, 0.0, DT)
    assert ends.tolist() == [0, 1] and best == pytest.approx(0.2 + T, abs=1e-9)
    best, ends = L._place_row(ok, length, vcap, acc_h, direction, entry, down, 0.001, DT)
    v_tol = 2 * np.sqrt(1500 * 0.001 / np.cos(np.pi / 4))
    start = np.ceil((T - v_tol / 1500) / DT) * DT
    assert start == pytest.approx(0.232) and best == pytest.approx(start + T, abs=1e-9)
    # no entry move (length 0): the block starts at once
    best, ends = L._place_row(ok, length, vcap, acc_h, direction, np.array([0.0, 0.0, 1.0]), down, 0.001, DT)
    assert best == pytest.approx(T, abs=1e-12)
    # a slow axis: entry and block 10 mm at 2 mm/s, a_h 1 mm/s^2 (7 s each): the blend speed is 2 mm/s
    # (t_blend = max(v / a) = 2 s, under the 5 s either takes to cover its length at 2 mm/s), so the
    # block starts at 7 - 2 = 5 s and ends at 12 s
    slow = np.array([[2.0], [0.0]])
    best, ends = L._place_row(ok, length, slow, np.array([[1.0], [1.0]]), direction, np.array([10.0, 2.0, 1.0]),
                              np.array([1.0, 0.0, 0.0]), 0.0, DT)
    assert best == pytest.approx(12.0, abs=1e-9)


def test_place_row_chains_a_long_block_between_two_short_ones():
    """Three blocks, a long one between two short ones (no entry), triangles at a_h = 1000: 1 mm (63.2 ms),
    16 mm (253 ms), 1 mm: the second starts at the first's peak (31.6 ms, the next servo cycle), the
    third 253 - 31.6 ms after the second (the blend speed is the short one's peak), each start on a
    servo cycle; the row ends when the third does."""
    n, K = 4, 1
    ok = np.zeros((n, K), bool)
    ok[:3, 0] = True
    length = np.array([[1.0], [16.0], [1.0], [0.0]])
    vcap = np.full((n, K), 1e3)
    acc_h = np.full((n, K), 1000.0)
    direction = np.zeros((n, K, 3))
    direction[..., 0] = 1.0
    best, ends = L._place_row(ok, length, vcap, acc_h, direction, np.array([0.0, 0.0, 1.0]), np.zeros(3), 0.0, DT)
    t1, t2 = 2 * np.sqrt(1e-3), 2 * np.sqrt(16e-3)
    s2 = np.ceil((t1 / 2) / DT - 1e-9) * DT
    s3 = np.ceil((s2 + t2 - t1 / 2) / DT - 1e-9) * DT
    assert ends.tolist() == [0, 1, 2, 3]
    assert best == pytest.approx(s3 + t1, abs=1e-9)


def test_the_floor_gives_the_blend_term_only_to_blocks_that_turn():
    """A row whose B turns over its first half only: a block of the second half moves no rotary axis
    and is bound by its chord and the axes' speeds alone; by brute force of the definition over every
    choice of block ends (blocks of up to 3 points), at a tolerance every block meets."""
    n = 8
    x = np.linspace(0.0, 7.0, n)
    Bq = np.radians(np.r_[np.linspace(0.0, 3.0, 4), np.full(4, 3.0)])
    q = np.column_stack([x, np.zeros(n), np.full(n, PIVOT), np.zeros(n), Bq])
    tip = M.tool_pose_np(np.zeros(n), Bq, q[:, 0], q[:, 1], q[:, 2])[0]
    feed = 6000.0
    from camsmooth.machine.kinematics import axis_limits

    vmax, amax, _ = axis_limits(M)
    best = np.inf
    for mask in itertools.product([False, True], repeat=n - 2):
        ends = np.r_[0, 1 + np.flatnonzero(mask), n - 1]
        if np.diff(ends).max() > 3:
            continue
        total = 0.0
        for i, j in zip(ends[:-1], ends[1:], strict=True):
            d = np.abs(q[j] - q[i])
            rest = np.sqrt(2 * np.max(d / amax)) if d[3:].max() > 0 else 0.0
            total += max(np.linalg.norm(tip[j] - tip[i]) / (feed / 60), np.max(d / vmax), rest)
        best = min(best, total)
    got = L.least_row_times(M, np.zeros(n, int), q, tip, np.full(n, feed), 100.0, max_points=3)[0]
    assert got == pytest.approx(best, rel=1e-12)
    # two rows: each its own floor, in order
    rows = np.repeat([5, 2], [n, n])
    both = L.least_row_times(M, rows, np.vstack([q, q]), np.vstack([tip, tip]), np.full(2 * n, feed), 100.0,
                             max_points=3)
    assert both == pytest.approx([best, best], rel=1e-12)


def test_block_ends_of_two_points():
    """Two points: the one block, or None where they are the same point."""
    p = L.LinuxCNCPlanner()
    q = np.array([[0.0, 0, 0, 0, 0], [1.0, 0, 0, 0, 0]])
    assert p.block_ends(M, q, np.array([0.0, 1.0]), np.ones((2, 4), bool), q[0], 0.0).tolist() == [0, 1]
    assert p.block_ends(M, q[[0, 0]], np.array([0.0, 1.0]), np.ones((2, 4), bool), q[0], 0.0) is None


def test_a_repeated_last_point_takes_no_time():
    """The program's last point repeated (a zero-length last block, dropped): it ends when the block before
    it does, and the program takes as long as without it (the last moving block has no next to blend
    into)."""
    p = L.LinuxCNCPlanner()
    joints = np.array([[1.0, 0, 0, 0, 0.5], [2.0, 0, 0, 0, 1.0], [2.0, 0, 0, 0, 1.0]])
    t = p.run(p.segments(M, np.zeros(5), joints, np.zeros(3, bool), np.full(3, 600.0), np.ones(3, bool)))
    w = p.run(p.segments(M, np.zeros(5), joints[:2], np.zeros(2, bool), np.full(2, 600.0), np.ones(2, bool)))
    assert t.end[2] == t.end[1] == w.end[1] and t.end[0] == w.end[0]
    assert np.allclose(t.positions(np.zeros(5), joints), w.positions(np.zeros(5), joints[:2]), atol=1e-12)


def _blend_chain(lengths, a: float, vcap: float) -> float:
    """End (s) of a chain of blocks of ``lengths`` mm from rest (no entry move), speed at most vcap: each
    block but the last ends in a parabolic blend and runs at a_j = a/2, the last ends at rest and runs at
    the whole a; each its own triangle (2 sqrt(L / a_j), peak sqrt(a_j L)) or trapezoid (L / v + v / a_j);
    the next starts when it decelerates below the blend speed bv = min(v, a_j t_blend), t_blend =
    min(L / v, L' / v', max(v / a_j, v' / a_j')) (tpComputeBlendVelocity), i.e. bv / a_j before its end,
    and not before the block before it has ended."""
    acc = [a if j == len(lengths) - 1 else a / 2 for j in range(len(lengths))]
    TV = []
    for length, aj in zip(lengths, acc, strict=True):
        peak = np.sqrt(aj * length)
        TV.append((2 * length / peak, peak) if peak <= vcap else (length / vcap + vcap / aj, vcap))
    start = [0.0]
    for j in range(1, len(lengths)):
        (tp, vp), (_, vn), ap, an = TV[j - 1], TV[j], acc[j - 1], acc[j]
        t_blend = min(lengths[j - 1] / vp, lengths[j] / vn, max(vp / ap, vn / an))
        s = start[-1] + tp - min(vp, ap * t_blend) / ap
        if j >= 2:
            s = max(s, start[-2] + TV[j - 2][0])
        start.append(s)
    return start[-1] + TV[-1][0]


def test_block_ends_follow_the_speed_limit():
    """Points along X at steps of 1, 2, 16, 16, 0.5 mm (no entry, a law too fast to bind, blocks of up to
    4 steps): by brute force over every choice of ends on the chain of blends (inner blocks at a/2 = 1500,
    the last at a = 3000 mm/s^2), the blocks 0-1-5 are the fastest at the axes' 500 mm/s: the 1 mm block
    peaks at sqrt(1500) mm/s after 25.8 ms, where the 34.5 mm last block starts, a triangle at 3000
    (peak 322 mm/s) of 2 sqrt(34.5 / 3000) = 214.5 ms: 240.3 ms (0-2-5: 252.9 ms). Under [TRAJ]
    MAX_LINEAR_VELOCITY 120 mm/s that long block is capped (34.5 / 120 + 120 / 3000, 353.3 ms in all) and
    0-3-5 wins: 19 mm at 1500 (19/120 + 120/1500 = 238.3 ms), the last 16.5 mm started at its deceleration
    (t_blend = 120/1500: the blend speed is 120) 158.3 ms in, 16.5/120 + 120/3000 = 177.5 ms: 335.8 ms. The
    placement follows its planner's v_limit."""
    x = np.r_[0.0, np.cumsum([1.0, 2.0, 16.0, 16.0, 0.5])]
    n = len(x)
    q = np.column_stack([x, np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(n)])
    ok = np.ones((n, 4), bool)
    for v_limit in (None, 120.0):
        times = {}
        for mask in itertools.product([False, True], repeat=n - 2):
            ends = np.r_[0, 1 + np.flatnonzero(mask), n - 1]
            if np.diff(ends).max() <= 4:
                times[tuple(ends.tolist())] = _blend_chain(np.diff(x[ends]), A_LIN, v_limit or V_LIN)
        ranked = sorted(times, key=times.get)
        assert times[ranked[1]] - times[ranked[0]] > len(ranked[0]) * DT
        assert ranked[0] == ((0, 1, 5) if v_limit is None else (0, 3, 5))
        got = L.LinuxCNCPlanner(v_limit=v_limit).block_ends(M, q, np.zeros(n), ok, q[0], 0.0)
        assert tuple(got.tolist()) == ranked[0]


def test_least_block_times_gives_the_blend_term_only_to_the_blocks_that_turn():
    """X at 0, 1, 2, 22 mm, B turning 0.5 deg between the second and third points only, blocks of up to
    2 steps, a feed that binds nothing. Each block's bound is max(max_i |d_i| / vmax_i, sqrt(2 max_i
    |d_i| / a_i) if it turns B): 0-1 2 ms, 1-2 and 0-2 sqrt(2 * 0.5 / 300) = 57.7 ms, 2-3 (X alone)
    20 / 500 = 40 ms, 1-3 sqrt(2 * 21 / 3000) = 118 ms. The least is 0-2-3, 97.7 ms: the block 2-3 moves
    no rotary axis, so the blend term (sqrt(2 * 20 / 3000) = 115 ms) is not its bound although the other
    block into point 3 turns."""
    from camsmooth.machine.kinematics import axis_limits

    x = np.array([0.0, 1.0, 2.0, 22.0])
    Bq = np.radians([0.0, 0.0, 0.5, 0.5])
    q = np.column_stack([x, np.zeros(4), np.full(4, PIVOT), np.zeros(4), Bq])
    tip = M.tool_pose_np(np.zeros(4), Bq, q[:, 0], q[:, 1], q[:, 2])[0]
    vmax, amax, _ = axis_limits(M)
    got = L.least_block_times(vmax, amax, np.zeros(4, int), q, tip, np.full(4, 1e12), np.ones((4, 2), bool), 2)
    want = np.sqrt(2 * 0.5 / 300.0) + 20 / 500.0
    assert got.tolist() == [pytest.approx(want, rel=1e-12)]


def test_a_stalled_limit_hold_returns_to_the_round_that_did_best():
    """over_limits' largest ratio per round 1.3, 1.2 (block 2 lengthened by _LIMIT_STEP each round
    it is over), then 1.25 for _STALLED rounds: the hold stops and the block times go back to those
    of the round at 1.2 (block 2 lengthened once), which it runs again and returns; the path is not
    checked (None)."""
    q, tip = _line(7)
    t = np.arange(7.0)
    k = np.array([0, 2, 4, 6])
    ratios = iter([1.3, 1.2] + [1.25] * B._STALLED + [9.0])

    def over(run, joints):
        return np.array([0.0, next(ratios), 0.0])

    p = _BlendPlanner(c=0.0)
    _, bt, tk, _ = B._hold_row(p, M, q, k, t, q[0], 0.0, None, None, 0.0, over_limits=over)
    assert bt == pytest.approx([2.0, 2.0 * B._LIMIT_STEP, 2.0], rel=1e-12)
    assert np.allclose(tk, np.r_[0.0, np.cumsum(bt)])
    assert p.calls == 2 + B._STALLED + 1
