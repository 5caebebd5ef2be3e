"""Feed planning (issue 8): machine limits for all five axes, the time-optimal time law per row
against closed forms (trapezoids) and an independent minimum-time solve, limits at every sample
from this file's own finite differences, and the feed plot.

Discretisation tolerance of the per-sample checks: the planner holds the limits at the points of
the C2 spline through them (module docstring of camsmooth.smoothing.feed); chord velocities and
three-point accelerations over the same points differ from the spline's by O(h^2), measured below
0.1% on these rows; the checks allow 0.5%. The programmed feed is checked to 1e-6 relative.
"""

from __future__ import annotations

import dataclasses
import tomllib

import casadi as ca
import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, load_machine, machine_from_dict
from camsmooth.smoothing.feed import CONSTRAINTS, plan_program, plan_row

FD_TOL = 5e-3


def _machine(**over):
    """The default machine with some limits replaced: over = {"Y": {"amax": 2000.0}, ...} (mm, s;
    rotary values in deg as in the file)."""
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    for ax, vals in over.items():
        data["axis"][ax].update(vals)
    return machine_from_dict(data, "test.toml")


def _limits(m):
    names = ("X", "Y", "Z", "A", "B")
    return (np.array([m.limits[a].vmax for a in names]), np.array([m.limits[a].amax for a in names]))


def _row(m, tip, A, B):
    return np.column_stack([m.linear_axes(tip, A, B), A, B])


def _trapezoid(s, L, v, a):
    """Closed-form rest-to-rest time at arc length s along a path of length L with speed limit v
    and acceleration limit a (triangle when L < v^2 / a)."""
    if L < v * v / a:
        v = np.sqrt(a * L)
    sa = v * v / (2 * a)
    total = L / v + v / a
    return np.where(s < sa, np.sqrt(2 * s / a),
                    np.where(s > L - sa, total - np.sqrt(2 * np.maximum(L - s, 0.0) / a), v / a + (s - sa) / v))


def _check_limits(m, q, tip, feed, t):
    """Chord velocities, three-point accelerations (this file's own differences) and the tip's
    chord feed against every limit; returns the worst ratios (velocity, acceleration) per axis."""
    vmax, amax = _limits(m)
    dt = np.diff(t)
    assert np.all(dt > 0)
    v = np.diff(q, axis=0) / dt[:, None]
    a = np.empty((len(q), 5))
    a[1:-1] = 2 * (v[1:] - v[:-1]) / (t[2:] - t[:-2])[:, None]
    a[0] = 2 * v[0] / dt[0]  # from rest
    a[-1] = -2 * v[-1] / dt[-1]  # to rest
    rv, ra = np.abs(v).max(axis=0) / vmax, np.abs(a).max(axis=0) / amax
    assert np.all(rv <= 1 + FD_TOL), rv
    assert np.all(ra <= 1 + FD_TOL), ra
    tip_feed = np.linalg.norm(np.diff(tip, axis=0), axis=1) / dt * 60.0
    assert np.all(tip_feed <= feed[1:] * (1 + 1e-6))
    return rv, ra


def reference_time(m, q, tip, feed):
    """Independent minimum-time schedule on the points themselves (no spline, no toppra): segment
    durations h (IPOPT) with chord velocities within vmax, the tip's chord speed within the block's
    feed and three-point accelerations within amax, starting and ending at rest (a ghost segment of
    zero velocity at both ends). Returns the time stamps."""
    vmax, amax = _limits(m)
    dq = np.diff(q, axis=0)
    dp = np.linalg.norm(np.diff(tip, axis=0), axis=1)
    n = len(dq)
    lo = np.maximum(np.max(np.column_stack([np.abs(dq) / vmax, dp / (feed[1:] / 60.0)]), axis=1), 1e-9)
    h = ca.MX.sym("h", n)
    V = ca.DM(dq) / ca.repmat(h, 1, 5)
    acc = ca.vertcat(2 * V[0, :] / h[0], 2 * (V[1:, :] - V[:-1, :]) / ca.repmat(h[1:] + h[:-1], 1, 5),
                     -2 * V[-1, :] / h[-1])
    g = ca.vec(acc / ca.DM(np.tile(amax, (n + 1, 1))))
    solver = ca.nlpsol("ref", "ipopt", {"x": h, "f": ca.sum1(h), "g": g},
                       {"ipopt.print_level": 0, "print_time": 0, "ipopt.tol": 1e-10, "ipopt.sb": "yes"})
    start = lo + np.sqrt(2 * np.abs(dq).max(axis=1) / amax.min())  # slow and feasible
    r = solver(x0=start, lbx=lo, ubx=np.inf, lbg=-1, ubg=1)
    assert solver.stats()["success"]
    return np.r_[0.0, np.cumsum(np.asarray(r["x"]).ravel())]


# ----------------------------------------------------------------------------------------------
# machine file
def test_machine_limits_for_all_axes_and_defaults():
    m = load_machine(None)
    for ax in "XYZ":
        lim = m.limits[ax]
        assert (lim.vmax, lim.amax, lim.jmax) == (500.0, 3000.0, 50000.0)
    assert m.limits["A"].jmax == pytest.approx(np.radians(5000.0))
    # an existing machine file: no X/Y/Z tables, no jmax -> the documented defaults, unlimited travel
    old = {"machine": {"kind": "AB-head", "pivot": 100.0},
           "axis": {k: {"min": -90.0, "max": 90.0, "vmax": 30.0, "amax": 100.0} for k in "AB"}}
    mo = machine_from_dict(old)
    assert mo.limits["Y"].vmax == 500.0 and mo.limits["Y"].min == -np.inf and mo.within("Y", np.array([1e6])).all()
    assert mo.limits["B"].jmax == pytest.approx(np.radians(5000.0))
    # given values: linear in mm, rotary degrees in the file -> radians inside
    given = dict(old, axis=dict(old["axis"], X={"min": -10.0, "max": 10.0, "vmax": 100.0, "amax": 200.0,
                                                "jmax": 900.0}))
    given["axis"]["A"] = dict(given["axis"]["A"], jmax=720.0)
    mg = machine_from_dict(given)
    assert (mg.limits["X"].vmax, mg.limits["X"].amax, mg.limits["X"].jmax) == (100.0, 200.0, 900.0)
    assert mg.limits["A"].jmax == pytest.approx(4 * np.pi)


@pytest.mark.parametrize("axis,key,value,needle", [
    ("X", "vmax", True, "[axis.X] vmax must be a finite number, got true"),
    ("Y", "amax", "fast", '[axis.Y] amax must be a finite number, got "fast"'),
    ("Z", "jmax", -5.0, "[axis.Z] jmax must be > 0"),
    ("A", "jmax", 0.0, "[axis.A] jmax must be > 0"),
    ("Z", "amax", float("inf"), "[axis.Z] amax must be a finite number"),
    ("B", "jerk", 10.0, "unknown key(s) jerk in [axis.B]"),
])
def test_machine_limit_errors_name_file_and_key(axis, key, value, needle):
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["axis"][axis][key] = value
    with pytest.raises(InputError) as exc:
        machine_from_dict(data, "mill.toml")
    assert needle in str(exc.value) and "mill.toml" in str(exc.value)


# ----------------------------------------------------------------------------------------------
# closed forms
def test_straight_line_is_the_closed_form_trapezoid():
    """Tip along (0.6, 0.8, 0) at constant A = B = 0: the tip may accelerate at
    min(amax_X / 0.6, amax_Y / 0.8) = 2500 mm/s^2 (Y binds), then cruises at the feed."""
    m = _machine(Y={"amax": 2000.0})
    n, L, F = 301, 60.0, 6000.0
    s = np.linspace(0.0, L, n)
    tip = s[:, None] * np.array([0.6, 0.8, 0.0])
    q = _row(m, tip, np.zeros(n), np.zeros(n))
    plan = plan_row(m, q, tip, np.full(n, F))
    t_exact = _trapezoid(s, L, F / 60.0, 2500.0)
    assert plan.cycle_time == pytest.approx(L / (F / 60) + (F / 60) / 2500.0, rel=1e-3)
    # one segment's worth of time where the switch falls inside a segment
    assert np.abs(plan.t_plan - t_exact).max() < 0.2 / (F / 60)
    names = {CONSTRAINTS[k] for k in plan.limit}
    assert names == {"feed", "Y acceleration"} and plan.limiting == "feed"
    v_exact = np.minimum.reduce([np.sqrt(2 * 2500.0 * s), np.full(n, F / 60), np.sqrt(2 * 2500.0 * (L - s))])
    assert np.abs(plan.feed_plan - 60 * v_exact).max() < 0.01 * F
    _check_limits(m, q, tip, np.full(n, F), plan.t_plan)


def test_short_line_never_reaches_the_feed_triangle():
    m = _machine(X={"amax": 500.0})
    n, L, F = 101, 2.0, 6000.0  # L < v^2 / a = 10 mm
    s = np.linspace(0.0, L, n)
    tip = np.column_stack([s, np.zeros(n), np.zeros(n)])
    plan = plan_row(m, _row(m, tip, np.zeros(n), np.zeros(n)), tip, np.full(n, F))
    assert plan.cycle_time == pytest.approx(2 * np.sqrt(L / 500.0), rel=1e-3)
    assert plan.limiting == "X acceleration" and plan.feed_plan.max() < F


@pytest.mark.parametrize("L,expect", [
    (10.0, lambda v, a, L: L / v + v / a),           # a trapezoid: it reaches the feed
    (0.01, lambda v, a, L: 2 * np.sqrt(L / a)),      # a triangle: it never does
])
def test_a_row_of_one_straight_block_is_its_closed_form(L, expect):
    """A row of two points (one G1 block from rest to rest: a CL program's single move) has a finite
    time law, the closed form of the block (X amax 500 mm/s^2, feed 3000 mm/min), with rest at both
    ends; the rates of a two-point row are its segment's."""
    from camsmooth.smoothing.nlp import program_rates

    m = _machine(X={"amax": 500.0})
    tip = np.array([[0.0, 0.0, 0.0], [L, 0.0, 0.0]])
    plan = plan_row(m, _row(m, tip, np.zeros(2), np.zeros(2)), tip, np.full(2, 3000.0))
    assert plan.cycle_time == pytest.approx(expect(50.0, 500.0, L), rel=1e-9)
    assert plan.t_plan[0] == 0.0 and plan.feed_plan.tolist() == [0.0, 0.0]
    r = program_rates(np.array([0.0, L, 5.0]), np.array([0.0, 1.0, 0.0]), np.array([0, 0, 1]))
    assert r.vel.tolist() == [L, L, 0.0] and r.acc.tolist() == [0.0, 0.0, 0.0]


def test_pure_rotary_move_is_the_rotary_trapezoid():
    """The tip stays put while A turns 60 deg: the tip feed is 0 throughout (the programmed feed
    says nothing about such a block), the pivot swings on a circle of radius L_p, and with the
    default linear limits A's own limits bind: T = dA / vmax + vmax / amax."""
    m = load_machine(None)
    n = 121
    A = np.radians(np.linspace(0.0, 60.0, n))
    tip = np.zeros((n, 3))
    q = _row(m, tip, A, np.zeros(n))
    plan = plan_row(m, q, tip, np.full(n, 2000.0))
    vm, am = m.limits["A"].vmax, m.limits["A"].amax
    assert plan.cycle_time == pytest.approx(np.radians(60.0) / vm + vm / am, rel=1e-4)
    assert np.abs(plan.t_plan - _trapezoid(A, A[-1], vm, am)).max() < 1e-3
    assert np.all(plan.feed_plan == 0.0) and plan.limiting == "A velocity"
    _check_limits(m, q, tip, np.full(n, 2000.0), plan.t_plan)


def test_rotary_move_with_the_pivot_bound_by_a_linear_axis():
    """Tip fixed, A turns +-20 deg about 0: the pivot moves at L_p * A' (Y = -L_p sin A), so with
    Y vmax 30 mm/s the Y velocity binds instead of A's 60 deg/s; the cycle lies between the
    trapezoids for the rotary speeds vY / L_p and vY / (L_p cos 20deg)."""
    m = _machine(Y={"vmax": 30.0})
    n = 161
    A = np.radians(np.linspace(-20.0, 20.0, n))
    tip = np.zeros((n, 3))
    q = _row(m, tip, A, np.zeros(n))
    plan = plan_row(m, q, tip, np.full(n, 2000.0))
    am = m.limits["A"].amax
    w_lo, w_hi = 30.0 / m.pivot, 30.0 / (m.pivot * np.cos(np.radians(20.0)))
    slow = _trapezoid(np.array([A[-1] - A[0]]), A[-1] - A[0], w_lo, am)[0]
    fast = _trapezoid(np.array([A[-1] - A[0]]), A[-1] - A[0], w_hi, am)[0]
    assert fast * (1 - 1e-3) <= plan.cycle_time <= slow * (1 + 1e-3)
    assert plan.limiting == "Y velocity"
    _check_limits(m, q, tip, np.full(n, 2000.0), plan.t_plan)


# ----------------------------------------------------------------------------------------------
# every sample within every limit
def _wavy_row(m, n=400, length=80.0):
    s = np.linspace(0.0, length, n)
    tip = np.column_stack([s, 5 * np.sin(s / 7), 3 * np.cos(s / 11)])
    A, B = np.radians(20 * np.sin(s / 9)), np.radians(25 * np.cos(s / 13))
    return _row(m, tip, A, B), tip, s


def test_every_sample_within_every_limit_and_the_feed():
    """A curved row with a feed step (3000 then 1500 mm/min) on a machine whose linear axes are
    slow enough to bind too."""
    m = _machine(Y={"amax": 600.0}, Z={"amax": 600.0})
    q, tip, s = _wavy_row(m)
    feed = np.where(s < 40.0, 3000.0, 1500.0)
    plan = plan_row(m, q, tip, feed)
    rv, ra = _check_limits(m, q, tip, feed, plan.t_plan)
    # the limits really bind (else the check proves little)
    assert max(rv.max(), ra.max()) > 0.99
    bound = np.minimum(np.r_[feed[1], feed[1:]], np.r_[feed[1:], feed[-1]])
    assert np.all(plan.feed_plan <= bound * (1 + 1e-6))
    assert plan.feed_plan[0] == 0.0 and plan.feed_plan[-1] == 0.0
    used = {CONSTRAINTS[k] for k in plan.limit}
    assert {"feed", "A velocity", "A acceleration", "Y acceleration"} <= used
    assert plan.limit_time.sum() == pytest.approx(plan.cycle_time)


# ----------------------------------------------------------------------------------------------
# hard cases against the independent minimum-time solve
def test_near_singular_orientation_against_independent_solve():
    """B 82 -> 88 deg (the AB head's singularity is B = 90 deg, where A no longer moves the axis):
    the tool axis circles close to +X while A sweeps 80 deg, so A runs at its limit while the tip
    crawls. Not tuned for: compared with reference_time (different discretisation and solver)."""
    m = load_machine(None)
    n = 300
    u = np.linspace(0.0, 1.0, n)
    tip = np.column_stack([np.zeros(n), 40 * u, 2 * np.sin(3 * u)])
    beta, phi = np.radians(8 - 6 * u), np.radians(-40 + 80 * u + 10 * np.sin(6 * u))
    T = np.column_stack([np.cos(beta), np.sin(beta) * np.sin(phi), np.sin(beta) * np.cos(phi)])
    ik = m.solve_row(T)
    assert np.degrees(ik.rotary["B"]).max() > 87.9 and len(ik.unreachable) == 0
    q = np.column_stack([m.linear_axes(tip, *ik.rotary.pair), *ik.rotary.pair])
    feed = np.full(n, 3000.0)
    plan = plan_row(m, q, tip, feed)
    t_ref = reference_time(m, q, tip, feed)
    assert plan.cycle_time == pytest.approx(t_ref[-1], rel=5e-3)
    assert np.abs(plan.t_plan - t_ref).max() < 5e-3 * t_ref[-1]
    assert plan.limiting.startswith("A ")
    _check_limits(m, q, tip, feed, plan.t_plan)


def test_one_mm_per_s2_axis_against_independent_solve():
    """Z may accelerate at 1 mm/s^2 only; the row undulates 0.5 mm in Z: Z's acceleration limit
    governs the whole row."""
    m = _machine(Z={"amax": 1.0})
    n = 300
    x = np.linspace(0.0, 60.0, n)
    tip = np.column_stack([x, 0.3 * x, 0.5 * np.sin(x / 10)])
    q = _row(m, tip, np.radians(10 * np.sin(x / 20)), np.radians(5 * np.cos(x / 15)))
    feed = np.full(n, 3000.0)
    plan = plan_row(m, q, tip, feed)
    t_ref = reference_time(m, q, tip, feed)
    assert plan.cycle_time == pytest.approx(t_ref[-1], rel=1e-2)
    assert plan.limiting == "Z acceleration"
    _check_limits(m, q, tip, feed, plan.t_plan)


# ----------------------------------------------------------------------------------------------
# rows, repeats, bad input
def test_program_is_its_rows_and_repeats_keep_their_time():
    m = load_machine(None)
    q, tip, s = _wavy_row(m, n=120, length=30.0)
    feed = np.full(len(s), 2400.0)
    one = plan_row(m, q, tip, feed)
    # a repeated point inside the row changes nothing and takes its predecessor's time
    k = 50
    qr, tr, fr = np.insert(q, k, q[k], axis=0), np.insert(tip, k, tip[k], axis=0), np.insert(feed, k, feed[k])
    rep = plan_row(m, qr, tr, fr)
    assert rep.t_plan[k + 1] == rep.t_plan[k] and rep.cycle_time == pytest.approx(one.cycle_time, rel=1e-12)
    rows = np.r_[np.full(len(s), 3), np.full(len(s), 7)]
    prog = plan_program(m, rows, np.r_[q, q[::-1]], np.r_[tip, tip[::-1]], np.r_[feed, feed])
    assert list(prog.row_ids) == [3, 7]
    assert prog.cycle_time == pytest.approx(prog.row_cycle_time.sum())
    np.testing.assert_array_equal(prog.t_plan[:len(s)], one.t_plan)
    assert prog.t_plan[len(s)] == 0.0
    # a one-point row and a row that does not move
    still = plan_row(m, np.repeat(q[:1], 4, axis=0), np.repeat(tip[:1], 4, axis=0), np.full(4, 1000.0))
    assert still.cycle_time == 0.0 and still.limiting == "none"


@pytest.mark.parametrize("bad", ["feed0", "nan", "shape"])
def test_bad_row_input(bad):
    m = load_machine(None)
    q, tip, s = _wavy_row(m, n=20, length=5.0)
    feed = np.full(len(s), 1000.0)
    if bad == "feed0":
        feed[7] = 0.0
    elif bad == "nan":
        q[3, 4] = np.nan
    else:
        tip = tip[:-1]
    with pytest.raises(InputError) as exc:
        plan_row(m, q, tip, feed)
    assert {"feed0": "point 7", "nan": "non-finite", "shape": "(N, 3)"}[bad] in str(exc.value)


def test_no_axis_limit_left_means_no_axis_constraint():
    """A machine built in code with limits for A and B only: X Y Z unconstrained, so a straight
    line at constant A, B reaches the feed within its first segment (and stops within its last,
    each at half the feed on average, so each costs one extra ds / v): cycle = (L + 2 ds) / v."""
    m = load_machine(None)
    m = dataclasses.replace(m, limits={k: m.limits[k] for k in "AB"})
    n, L, F = 51, 10.0, 3000.0
    tip = np.column_stack([np.linspace(0, L, n), np.zeros(n), np.zeros(n)])
    plan = plan_row(m, _row(m, tip, np.zeros(n), np.zeros(n)), tip, np.full(n, F))
    assert plan.cycle_time == pytest.approx((L + 2 * L / (n - 1)) / (F / 60), rel=1e-6)


def test_plan_method_on_a_pipeline_result():
    """A real program (the wavy surface of test_pipeline, method 'none'): every row within every
    limit and its feed, rows restart at t = 0, and the program's cycle is the sum of its rows."""
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.paths import zigzag_path
    from camsmooth.geometry.surfaces import Sinusoid, Surface, tessellate_to_tolerance
    from camsmooth.smoothing.feed import plan_method
    from camsmooth.smoothing.pipeline import smooth

    surf = Sinusoid(amplitude=2.0, kx=2 * np.pi / 60.0, ky=2 * np.pi / 90.0, u_range=(0.0, 40.0),
                    v_range=(0.0, 12.0))
    path = zigzag_path(surf, stepover=4.0, spacing=0.6, feed=2000.0)
    m = _machine(X={"amax": 400.0}, Y={"amax": 400.0}, Z={"amax": 400.0})
    res = smooth(path, Surface(tessellate_to_tolerance(surf, chord_tol=2e-4), surf, "wavy"), m,
                 ToroidalCutter(R=4.0, r=1.0), method="none")
    r = res.methods["none"]
    feed = res.inputs["feed"]
    plan = plan_method(m, r, feed)
    assert list(plan.row_ids) == list(dict.fromkeys(r.rows.tolist()))
    q = np.column_stack([r.xyz, r.rotary.values])
    for row in plan.row_ids:
        k = r.rows == row
        assert plan.t_plan[k][0] == 0.0
        _check_limits(m, q[k], r.cl[k], feed[k], plan.t_plan[k])
    assert plan.cycle_time == pytest.approx(plan.row_cycle_time.sum())
    # the planned time is at least the time at the programmed feed along the tool tip
    tip_time = sum(np.linalg.norm(np.diff(r.cl[r.rows == row], axis=0), axis=1).sum() for row in plan.row_ids)
    assert plan.cycle_time > tip_time / (2000.0 / 60.0)


# ----------------------------------------------------------------------------------------------
# plot
def test_feed_plot_draws_every_method_and_the_programmed_feed():
    from camsmooth.report.feed import path_length, plot_planned_feed

    m = load_machine(None)
    q, tip, s = _wavy_row(m, n=150, length=40.0)
    rows = np.r_[np.zeros(75, int), np.ones(75, int)]
    feed = np.where(s < 20, 3000.0, 1500.0)
    plans = {"none": plan_program(m, rows, q, tip, feed), "nlp": plan_program(m, rows, q, tip, feed * 0.9)}
    fig = plot_planned_feed({"none": tip, "nlp": tip}, rows, plans, feed, primary="nlp")
    axes = fig.get_axes()
    assert len(axes) == 2
    for ax, name in zip(axes, ("none", "nlp"), strict=True):
        assert ax.get_title().startswith(name)
        labels = [ln.get_label() for ln in ax.get_lines()]
        assert labels == [f"{name}: planned", "programmed"]
        planned = ax.get_lines()[0].get_ydata()
        assert np.nanmax(planned) == pytest.approx(plans[name].feed_plan.max())
    L = path_length(tip, rows)
    assert L[75] == L[74] and L[-1] == pytest.approx(np.linalg.norm(np.diff(tip, axis=0), axis=1).sum()
                                                     - np.linalg.norm(tip[75] - tip[74]))


@pytest.mark.parametrize("n", [50, 400])
def test_planner_agrees_with_the_toppra_package(n):
    """The planner's forward-backward pass against toppra's TOPP-RA on the same gridpoints,
    spline and constraints (benchmarks/toppra_reference.py), on a row whose rotary axes swing and
    whose feed changes: the same speed at every gridpoint, the same cycle time."""
    from benchmarks.bench_feed import wave_row
    from benchmarks.toppra_reference import toppra_speed
    from camsmooth.smoothing.feed import _xmax, forward_backward, plan_from_speed, row_path

    m = load_machine()
    q, tip, feed = wave_row(n)
    feed = feed * (1.0 + 0.5 * np.sin(np.arange(n) / 7.0))
    rp = row_path(m, q, tip, feed)
    ours = forward_backward(rp.s, rp.dq, rp.ddq, rp.amax, _xmax(rp))
    ref = toppra_speed(rp)
    np.testing.assert_allclose(ours, ref, rtol=2e-4, atol=1e-9 * ref.max())
    a, b = plan_from_speed(rp, ours), plan_from_speed(rp, ref)
    assert abs(a.cycle_time / b.cycle_time - 1) < 1e-4


@pytest.mark.parametrize("left", [0.0, 1e-8])  # exactly at rest, or within rounding of it (met on a real row)
def test_a_segment_left_at_rest_at_both_ends_takes_its_rest_to_rest_time(left):
    """Where the discretisation leaves both ends of a segment at rest (a stop at the last interior
    gridpoint, met on a real CLSF's row), the segment takes the triangle of the path acceleration
    its axes allow, 2 sqrt(ds / a), not an infinite time. A straight line along X (amax_X 500
    mm/s^2): a = 500 mm/s^2 along the path, in the planner's scaled parameter s."""
    from camsmooth.smoothing.feed import forward_backward, plan_from_speed, row_path

    m = _machine(X={"amax": 500.0})
    n = 21
    tip = np.column_stack([np.linspace(0.0, 10.0, n), np.zeros(n), np.zeros(n)])
    rp = row_path(m, _row(m, tip, np.zeros(n), np.zeros(n)), tip, np.full(n, 3000.0))
    sd = forward_backward(rp.s, rp.dq, rp.ddq, rp.amax, np.minimum(rp.x_feed, 1e12))
    sd[-2] = left  # both ends of the last segment at rest
    plan = plan_from_speed(rp, sd)
    ds_mm = 10.0 / (n - 1)
    assert np.isfinite(plan.cycle_time)
    assert plan.t_plan[-1] - plan.t_plan[-2] == pytest.approx(2.0 * np.sqrt(ds_mm / 500.0), rel=1e-9)
