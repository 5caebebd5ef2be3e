"""The jerk-limited time law (camsmooth.smoothing.jerk, issue 22 item 5): every limit met at every
sample, checked from the output arrays alone; the cycle time against an independent formulation,
a direct CasADi NLP in time (uniform time grid, triple integrator of the closed-form path's own
parameter, exact path derivatives by automatic differentiation); TOPP-RA as the jmax -> inf limit.

The path: the tool tip on a helix (radius 20 mm, pitch 2 mm/rad, half a turn) while A and B
swing (A = 12 deg sin(theta), B = 20 deg (1 - cos(theta))), X Y Z the pivot 150 mm up the tool
axis, feed 3000 mm/min (binds in the middle)."""

from __future__ import annotations

import tomllib
from functools import cache

import casadi as ca
import numpy as np
import pytest

from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, Machine, machine_from_dict
from camsmooth.smoothing.feed import axis_limits, finite_difference_rates, plan_row, row_path
from camsmooth.smoothing.jerk import jerk_law, law_rates

THETA = np.pi  # rad of helix
FEED = 3000.0  # mm/min
SLACK = 1e-6  # relative, on every check of a limit


def machine(jmax_rot: float | None = 2000.0, jmax_lin: float = 20000.0) -> Machine:
    """The default machine with jmax given (deg/s^3 for A B, mm/s^3 for X Y Z); None: as shipped."""
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    if jmax_rot is not None:
        for ax in ("A", "B"):
            data["axis"][ax]["jmax"] = jmax_rot
        for ax in ("X", "Y", "Z"):
            data["axis"][ax]["jmax"] = jmax_lin
    return machine_from_dict(data, "<jerk test>")


def helix(th, m: Machine):
    """(tip (3,), joints (5,)) at theta; numpy arrays or a CasADi symbol."""
    sin, cos = (ca.sin, ca.cos) if isinstance(th, (ca.SX, ca.MX)) else (np.sin, np.cos)
    tip = [20.0 * cos(th), 20.0 * sin(th), 2.0 * th]
    a, b = np.radians(12.0) * sin(th), np.radians(20.0) * (1 - cos(th))
    axis = m.tool_axis(a, b)
    return tip, [tip[k] + m.pivot * axis[k] for k in range(3)] + [a, b]


def row(m: Machine, n: int = 300) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    th = np.linspace(0.0, THETA, n)
    tip, q = helix(th, m)
    return np.column_stack(q), np.column_stack(tip), np.full(n, FEED)


def reference_time(m: Machine, n: int = 240) -> float:
    """Independent direct NLP in time: states theta, theta', theta'' at n + 1 instants of a
    uniform grid over the free final time T, theta''' constant per step (exact integration);
    every axis's velocity, acceleration and jerk (chain rule, derivatives of the closed form by
    CasADi) and the tip speed within limits at every instant; rest to rest. Minimise T."""
    vmax, amax, jmax = axis_limits(m)
    th = ca.SX.sym("th")
    tip, q = helix(th, m)
    q = ca.vertcat(*q)
    d1 = ca.jacobian(q, th)
    d2 = ca.jacobian(d1, th)
    d3 = ca.jacobian(d2, th)
    sp = ca.norm_2(ca.jacobian(ca.vertcat(*tip), th))
    f = ca.Function("f", [th], [d1, d2, d3, sp]).map(n + 1)
    T = ca.SX.sym("T")
    X = ca.SX.sym("X", 3, n + 1)
    U = ca.SX.sym("U", 1, n)
    h = T / n
    s, v, a = X[0, :-1], X[1, :-1], X[2, :-1]
    dyn = ca.vertcat(X[0, 1:] - (s + h * v + h**2 / 2 * a + h**3 / 6 * U),
                     X[1, 1:] - (v + h * a + h**2 / 2 * U), X[2, 1:] - (a + h * U))
    q1, q2, q3, spd = f(X[0, :])
    v, a = ca.repmat(X[1, :], 5, 1), ca.repmat(X[2, :], 5, 1)
    u = ca.repmat(ca.horzcat(U, U[-1]), 5, 1)
    u_left = ca.repmat(ca.horzcat(U[0], U), 5, 1)
    lim = [(q1 * v, vmax), (q2 * v**2 + q1 * a, amax), (q3 * v**3 + 3 * q2 * v * a + q1 * u, jmax),
           (q3 * v**3 + 3 * q2 * v * a + q1 * u_left, jmax)]
    g = [ca.vec(dyn)] + [ca.vec(e / ca.repmat(ca.DM(lm), 1, n + 1)) for e, lm in lim] + [ca.vec(spd * X[1, :])]
    lbg = np.r_[np.zeros(3 * n), -np.ones(20 * (n + 1)), np.full(n + 1, -np.inf)]
    ubg = np.r_[np.zeros(3 * n), np.ones(20 * (n + 1)), np.full(n + 1, FEED / 60.0)]
    x = ca.vertcat(T, ca.vec(X), ca.vec(U))
    lbx = np.r_[0.05, np.tile([-np.inf, 0.0, -np.inf], n + 1), np.full(n, -np.inf)]
    ubx = np.r_[np.inf, np.full(3 * (n + 1) + n, np.inf)]
    for k, val in ((0, 0.0), (1, 0.0), (2, 0.0), (3 * n, THETA), (3 * n + 1, 0.0), (3 * n + 2, 0.0)):
        lbx[1 + k] = ubx[1 + k] = val
    t_guess = 3.0
    tt = np.linspace(0, 1, n + 1)
    x0 = np.r_[t_guess, np.column_stack([THETA * (3 * tt**2 - 2 * tt**3), THETA * 6 * (tt - tt**2) / t_guess,
                                         THETA * 6 * (1 - 2 * tt) / t_guess**2]).ravel(), np.zeros(n)]
    solver = ca.nlpsol("ref", "ipopt", {"x": x, "f": T, "g": ca.vertcat(*g)},
                       {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.max_iter": 3000})
    sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    assert solver.stats()["success"]
    return float(sol["x"][0])


@cache
def solved(jmax_rot: float | None = 2000.0, jmax_lin: float = 20000.0, n: int = 240) -> tuple:
    """(machine, q, tip, feed, plan_row's plan, the RowPath, the jerk-limited law or None), once."""
    m = machine(jmax_rot, jmax_lin)
    q, tip, feed = row(m, n)
    rp = row_path(m, q, tip, feed)
    return m, q, tip, feed, plan_row(m, q, tip, feed), rp, jerk_law(rp) if m.jerk_limited else None


def _ratios(m: Machine, q: np.ndarray, tip: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Largest ratio to its limit of (tip speed, velocity, acceleration, jerk) by finite
    differences (chord over time; 2 and 6 times the divided differences) of samples q, tip at t."""
    vmax, amax, jmax = axis_limits(m)
    v, a, j = finite_difference_rates(q, t)
    speed = np.linalg.norm(np.diff(tip, axis=0), axis=1) / np.diff(t)
    return np.array([speed.max() / (FEED / 60.0), (np.abs(v) / vmax).max(), (np.abs(a) / amax).max(),
                     (np.abs(j) / jmax).max()])


def dense_check(jmax_rot: float, jmax_lin: float, per: int = 16) -> np.ndarray:
    """The ratios of ``_ratios`` at the points under plan_row's times, and on a resampling of the
    jerk-limited law at ``per`` instants per interval: positions q(s(t)), p(s(t)) on the row's
    spline, s(t) the law's cubic on each interval (from its arrays t, s, y = s', z = s'', w = s''')."""
    m, q, tip, _, plan, rp, law = solved(jmax_rot, jmax_lin)
    at_points = _ratios(m, q, tip, plan.t_plan)
    assert np.allclose(law.t[law.points][rp.owner], plan.t_plan)
    tau = np.diff(law.t)[:, None] * (np.arange(per) / per)[None, :]
    s = (law.s[:-1, None] + law.y[:-1, None] * tau + law.z[:-1, None] * tau**2 / 2
         + law.w[:, None] * tau**3 / 6).ravel()
    t = (law.t[:-1, None] + tau).ravel()
    s, t = np.r_[s, law.s[-1]], np.r_[t, law.t[-1]]
    dense = _ratios(m, rp.spline(s), rp.tip_spline(s), t)
    return np.maximum(at_points, dense)


@pytest.fixture(scope="module")
def reference() -> float:
    return reference_time(machine())


def test_jerk_limited_time_matches_an_independent_direct_nlp_in_time(reference):
    m, *_, plan, _, law = solved()
    assert m.jerk_limited and law.converged
    assert plan.cycle_time == pytest.approx(reference, rel=0.02)
    assert plan.cycle_time == pytest.approx(reference, rel=0.005)  # what it does: 0.1 %


def test_every_limit_is_met_at_every_sample():
    *_, plan, rp, law = solved()
    assert np.all(np.diff(plan.t_plan) > 0)
    assert np.all(dense_check(2000.0, 20000.0) <= 1 + SLACK)
    assert plan.jerk_over.sum() == 0
    # and the law itself, evaluated exactly (chain rule on the spline) between its nodes
    assert max(law_rates(rp, law, 33).ratio(rp.vmax, rp.amax, rp.jmax)) <= 1 + SLACK


def test_jerk_limited_time_is_above_topp_ra_and_tends_to_it_as_jmax_grows():
    free, *_, topp, _, _ = solved(None)
    assert not free.jerk_limited
    times = [solved(j, 10 * j)[4].cycle_time for j in (2000.0, 2e4, 2e6)]
    assert all(t >= topp.cycle_time * (1 - 1e-6) for t in times)
    assert times[0] > times[1] > times[2]
    assert times[2] == pytest.approx(topp.cycle_time, rel=0.01)


def test_a_binding_jerk_limit_slows_the_row_measurably():
    m, q, *_, plan, _, _ = solved(500.0, 5000.0)
    topp = solved(None)[4]
    assert plan.cycle_time > 1.1 * topp.cycle_time
    _, _, jerk = finite_difference_rates(q, topp.t_plan)
    assert (np.abs(jerk) / axis_limits(m)[2]).max() > 2.0  # the TOPP-RA law breaks the jerk limit
    assert np.all(dense_check(500.0, 5000.0) <= 1 + SLACK)


def test_default_machine_reports_jerk_without_enforcing_it():
    m = machine(None)
    assert not m.jerk_limited
    assert np.isfinite(axis_limits(m)[2]).all()  # the documented default jmax is still reported
