"""The jerk-limited time law (camsmooth.smoothing.jerk, issue 22 item 5): every limit met at every
sample, checked from the output arrays alone; the cycle time against an independent formulation,
a direct CasADi NLP in time (uniform time grid, triple integrator of the closed-form path's own
parameter, exact path derivatives by automatic differentiation); TOPP-RA as the jmax -> inf limit.

The path: the tool tip on a helix (radius 20 mm, pitch 2 mm/rad, half a turn) while A and B
swing (A = 12 deg sin(theta), B = 20 deg (1 - cos(theta))), X Y Z the pivot 150 mm up the tool
axis, feed 3000 mm/min (binds in the middle)."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from benchmarks.bench_jerk import helix, helix_function, machine
from benchmarks.bench_jerk import reference_time as direct_nlp_time
from camsmooth.machine.kinematics import Machine, axis_limits
from camsmooth.smoothing.feed import finite_difference_rates, plan_row, row_path
from camsmooth.smoothing.jerk import jerk_law, law_rates

THETA = np.pi  # rad of helix
FEED = 3000.0  # mm/min
SLACK = 1e-6  # relative, on every check of a limit


def row(m: Machine, n: int = 300) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    th = np.linspace(0.0, THETA, n)
    tip, q = helix(th, m)
    return np.column_stack(q), np.column_stack(tip), np.full(n, FEED)


def reference_time(m: Machine, n: int = 240) -> float:
    """The independent direct NLP in time (benchmarks/bench_jerk.reference_time: a triple
    integrator in the path parameter on a uniform grid over the free final time, every axis's
    velocity, acceleration and jerk by the chain rule on the closed form) on the helix."""
    t = direct_nlp_time(m, helix_function(m), THETA, FEED, n, 3.0)
    assert np.isfinite(t), "the reference NLP did not converge"
    return t


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
