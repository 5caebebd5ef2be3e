"""The row NLP against an independent formulation, case by case: every group of constraints made
to bind in turn, and the result checked with the test's own differences and angles and certified
as a KKT point of the plain reference NLP (benchmarks/reference_nlp.py: angles written out,
derivatives by automatic differentiation, multipliers by NNLS; nothing of
camsmooth.smoothing.nlp). Also the difference operators, the spline method, the violation report
and the elastic diagnosis against closed forms.

The NLP is not convex (a 30-point row with a 120 deg/s^2 B limit has local minima at Gamma 98.7
and 67.9; with the tilt window [2, 15] deg camsmooth stops at a KKT point of Gamma 84.5 from which
the reference's exact-Hessian IPOPT walks to 83.8), so the certificate is first-order optimality
in the reference's formulation (residual < 1e-3 of |grad f|; the warm starts score 0.75-0.88),
not "the" optimum.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import camsmooth.smoothing.nlp as nlp_mod
from benchmarks import reference_nlp as ref
from camsmooth.errors import InfeasibleError
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import load_machine
from camsmooth.smoothing.nlp import (
    BACKOFF,
    WINDOW_BACKOFF,
    Binding,
    LeadBounds,
    RowNLP,
    elastic_diagnosis,
    fd_operators,
    gamma,
    rates,
    spline_row,
)
from camsmooth.smoothing.orientation import local_frames

N = 30
RZ = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # the row turned 90 deg about z


def wave_row(n: int = N, turned: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), local frames (columns X_L feed, Y_L, n; workpiece frame) and the surface normals'
    tool axes tilted 11 deg forward (lead) of a row on z = 5 sin(x / 10) mm at 0.4 mm spacing and
    2000 mm/min; ``turned``: the same row along y, so that A moves instead of B."""
    x = np.arange(n) * 0.4
    dz = 0.5 * np.cos(x / 10)
    nrm = np.stack([-dz, 0 * x, np.ones_like(x)], 1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    fr = local_frames(nrm, np.stack([np.ones_like(x), 0 * x, dz], 1))
    lead = np.radians(11.0)
    T = np.cos(lead) * fr[:, :, 2] + np.sin(lead) * fr[:, :, 0]
    p = np.stack([x, 0 * x, 5 * np.sin(x / 10)], 1)
    t = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1) / (2000 / 60))])
    if turned:
        fr, T = np.einsum("ij,njk->nik", RZ, fr), T @ RZ.T
    return t, fr, T


def with_limits(machine, **deg):
    """The machine with some limits replaced: A_vmax=45 -> A's vmax 45 deg/s (deg, deg/s, deg/s^2)."""
    lim = dict(machine.limits)
    for key, value in deg.items():
        axis, field = key.split("_")
        lim[axis] = dataclasses.replace(lim[axis], **{field: np.radians(value)})
    return dataclasses.replace(machine, limits=lim)


def backed_off(machine, b: float = BACKOFF):
    """The limits the NLP promises to meet (RowNLP.bounds' docstring): the A/B travel shrunk by b/2
    of its span at each end, velocity and acceleration by the fraction b."""
    lim = dict(machine.limits)
    for axis in "AB":
        L = lim[axis]
        w = (L.max - L.min) * b / 2
        lim[axis] = dataclasses.replace(L, min=L.min + w, max=L.max - w, vmax=L.vmax * (1 - b), amax=L.amax * (1 - b))
    return dataclasses.replace(machine, limits=lim)


def lead_tilt(T: np.ndarray, fr: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lead (angle from the normal) and tilt (azimuth from X_L towards Y_L) in rad, written here."""
    x, y, z = (np.einsum("ni,ni->n", T, fr[:, :, k]) for k in range(3))
    return np.arctan2(np.hypot(x, y), z), np.arctan2(y, x)


M0 = load_machine()
# name -> (machine, lead window deg, tilt window deg, turned row, (what binds, check)). The lead window
# [10, 12] makes the axis follow the wave, so every limit below is met only by smoothing against it.
CASES = {
    "lead window": (M0, (10, 12), (-15, 15), False, "lead"),
    "B acceleration": (with_limits(M0, B_amax=120), (10, 12), (-15, 15), False, "B amax"),
    "B velocity": (with_limits(M0, B_vmax=54), (10, 12), (-15, 15), False, "B vmax"),
    "B min": (with_limits(M0, B_min=-15.5), (10, 12), (-15, 15), False, "B min"),
    "A acceleration": (with_limits(M0, A_amax=120), (10, 12), (-15, 15), True, "A amax"),
    "A velocity": (with_limits(M0, A_vmax=54), (10, 12), (-15, 15), True, "A vmax"),
    "A max": (with_limits(M0, A_max=15.5), (10, 12), (-15, 15), True, "A max"),
    "tilt min": (M0, (10, 12), (-15, -2), False, "tilt min"),
    "tilt max": (M0, (10, 12), (2, 15), False, "tilt max"),
}


def _d1(q, t):
    return np.diff(q) / np.diff(t)


def _d2(q, t):
    h = np.diff(t)
    return 2 * np.diff(np.diff(q) / h) / (h[:-1] + h[1:])


def certify(machine, t, fr, lw, tw, A, B, bounds: LeadBounds | None = None) -> float:
    """Assert (A, B) meets the user's limits and windows at every sample (the test's own
    differences and angles) and is a KKT point of the reference NLP (on the backed-off limits the
    NLP promises); returns its Gamma."""
    for name, q in (("A", A), ("B", B)):
        L = machine.limits[name]
        assert np.all((q >= L.min - 1e-12) & (q <= L.max + 1e-12)), f"{name} travel"
        assert np.abs(_d1(q, t)).max() <= L.vmax * (1 + 1e-9), f"{name} velocity"
        assert np.abs(_d2(q, t)).max() <= L.amax * (1 + 1e-9), f"{name} acceleration"
    lead, tilt = lead_tilt(machine.tool_axis_np(A, B), fr)
    assert np.all((lead >= lw[:, 0] - 1e-9) & (lead <= lw[:, 1] + 1e-9)), "lead window"
    assert np.all((tilt >= tw[:, 0] - 1e-9) & (tilt <= tw[:, 1] + 1e-9)), "tilt window"
    extra = {}
    if bounds is not None:
        quad = lambda c: c[:, 0] + c[:, 1] * tilt + c[:, 2] * tilt ** 2  # noqa: E731
        assert np.all(lead[bounds.has_floor] >= quad(bounds.floor)[bounds.has_floor] - 1e-9), "clearance floor"
        assert np.all(lead[bounds.has_ceiling] <= quad(bounds.ceiling)[bounds.has_ceiling] + 1e-9), \
            "clearance ceiling"
        shift = np.array([WINDOW_BACKOFF, 0.0, 0.0])  # the NLP keeps 2e-6 rad inside, as in the windows
        extra = dict(floor=bounds.floor + shift, ceiling=bounds.ceiling - shift, has_floor=bounds.has_floor,
                     has_ceiling=bounds.has_ceiling)
    narrow = np.array([WINDOW_BACKOFF, -WINDOW_BACKOFF])
    kkt = ref.stationarity(backed_off(machine), t, fr, lw + narrow, tw + narrow, A, B, **extra)
    assert kkt.violation < 1e-8, kkt
    assert kkt.residual < 1e-3, f"not a KKT point of the reference formulation: {kkt}"
    return ref.gamma_of(machine, A, B, t)


def binds(what: str, machine, t, fr, lw, tw, A, B) -> bool:
    """Whether the named limit or window is reached (within 0.5% of the backed-off limit or 0.01 deg)."""
    lim = backed_off(machine).limits
    if what == "lead":
        lead, _ = lead_tilt(machine.tool_axis_np(A, B), fr)
        return bool(np.any(lead <= lw[:, 0] + 1.7e-4) and np.any(lead >= lw[:, 1] - 1.7e-4))
    if what.startswith("tilt"):
        _, tilt = lead_tilt(machine.tool_axis_np(A, B), fr)
        side = 0 if what == "tilt min" else 1
        return bool(np.any(np.abs(tilt - tw[:, side]) < 1.7e-4))
    axis, field = what.split()
    q = A if axis == "A" else B
    L = lim[axis]
    if field in ("min", "max"):
        return bool(np.any(np.abs(q - getattr(L, field)) < 1.7e-4))
    peak = np.abs(_d1(q, t) if field == "vmax" else _d2(q, t)).max()
    return bool(peak >= 0.995 * getattr(L, field))


@pytest.mark.parametrize("screening", [False, True], ids=["whole", "screened"])
@pytest.mark.parametrize("case", list(CASES))
def test_each_limit_binds_and_the_result_is_a_reference_optimum(case, screening):
    machine, lw_deg, tw_deg, turned, what = CASES[case]
    t, fr, T = wave_row(turned=turned)
    lw, tw = np.tile(np.radians(lw_deg), (N, 1)), np.tile(np.radians(tw_deg), (N, 1))
    ik = machine.solve_row(T)
    start = RotaryValues.of(machine.rotary,
                            np.clip(ik.rotary["A"], machine.limits["A"].min, machine.limits["A"].max),
                            np.clip(ik.rotary["B"], machine.limits["B"].min, machine.limits["B"].max))
    row = RowNLP(machine, N, screening=screening)
    q, st = row.solve(t, fr, start, lw, tw)
    assert q.names == ("A", "B")
    A, B = q["A"], q["B"]
    assert st.success, st.status
    assert st.total_rows == 2 * (N - 1) + 2 * (N - 2) + 3 * N
    assert st.rows <= st.total_rows and (screening or st.rows == st.total_rows)
    assert binds(what, machine, t, fr, lw, tw, A, B), f"{what} does not bind: the case tests nothing"
    certify(machine, t, fr, lw, tw, A, B)
    assert row.constraint_report(t, q) == []


@pytest.mark.parametrize("side", ["floor", "ceiling"])
def test_clearance_bounds_bind_and_are_met(side):
    """The accessibility map's lead floor / ceiling (quadratics in tilt) on a third of the points."""
    t, fr, T = wave_row()
    lw, tw = np.tile(np.radians([2.0, 20.0]), (N, 1)), np.tile(np.radians([-15.0, 15.0]), (N, 1))
    on = np.zeros(N, bool)
    on[8:18] = True
    coef = np.tile(np.radians([[19.0, 0.0, 0.0]]) if side == "floor" else np.radians([[8.0, 0.0, 0.0]]), (N, 1))
    coef[:, 1] = 0.05
    coef[:, 2] = -0.2
    bounds = LeadBounds(coef if side == "floor" else np.zeros((N, 3)), coef if side == "ceiling" else np.zeros((N, 3)),
                        on if side == "floor" else np.zeros(N, bool), on if side == "ceiling" else np.zeros(N, bool))
    ik = M0.solve_row(T)
    row = RowNLP(M0, N, screening=False)
    q, st = row.solve(t, fr, ik.rotary, lw, tw, bounds)
    A, B = q["A"], q["B"]
    assert st.success, st.status
    assert st.total_rows == 2 * (N - 1) + 2 * (N - 2) + 3 * N + int(on.sum())
    lead, tilt = lead_tilt(M0.tool_axis_np(A, B), fr)
    need = coef[:, 0] + coef[:, 1] * tilt + coef[:, 2] * tilt ** 2
    assert np.min(np.abs(lead - need)[on]) < 1e-5  # it binds
    free, _ = RowNLP(M0, N, screening=False).solve(t, fr, ik.rotary, lw, tw)
    lead_free, _ = lead_tilt(M0.tool_axis_np(free["A"], free["B"]), fr)
    assert (np.any(lead_free[on] < need[on] - 1e-3) if side == "floor" else np.any(lead_free[on] > need[on] + 1e-3))
    certify(M0, t, fr, lw, tw, A, B, bounds)


def test_a_failed_solve_keeps_a_feasible_start_and_reports_an_infeasible_one():
    """IPOPT stopped after one iteration: the warm start is kept when it meets every row (and the
    status says so), and the failure is reported when it does not."""
    t, fr, T = wave_row()
    t = 2 * t  # half the feed: the start's B velocity is within the limit
    lw, tw = np.tile(np.radians([2.0, 20.0]), (N, 1)), np.tile(np.radians([-15.0, 15.0]), (N, 1))
    ik = M0.solve_row(T)
    row = RowNLP(M0, N, screening=False, ipopt_options={"ipopt.max_iter": 1})
    q, st = row.solve(t, fr, ik.rotary, lw, tw)
    A, B = q["A"], q["B"]
    assert st.success and st.status.endswith("a feasible point kept")
    assert gamma(M0.tool_axis_np(A, B), t) <= gamma(T, t) * (1 + 1e-12)
    narrow = np.tile(np.radians([2.0, 3.0]), (N, 1))  # the start (lead 11 deg) is outside
    _, st = row.solve(t, fr, ik.rotary, narrow, tw)
    assert not st.success and "feasible" not in st.status


def test_rows_shorter_than_three_points_are_refused():
    with pytest.raises(InfeasibleError, match="at least 3 points"):
        RowNLP(M0, 2)


def test_build_and_solve_times_are_durations():
    t, fr, T = wave_row()
    lw, tw = np.tile(np.radians([10.0, 12.0]), (N, 1)), np.tile(np.radians([-15.0, 15.0]), (N, 1))
    ik = M0.solve_row(T)
    row = RowNLP(M0, N)
    assert 0.0 <= row.build_s < 60.0
    _, st = row.solve(t, fr, ik.rotary, lw, tw)
    assert 0.0 < st.build_s < 60.0 and 0.0 < st.time_s < 60.0 and st.iterations > 0
    _, again = row.solve(t, fr, ik.rotary, lw, tw)
    assert again.build_s == 0.0  # the solver of these rows is cached


def test_bounds_back_off_the_limits_and_the_windows():
    m = with_limits(M0, A_min=-30, A_max=50, B_vmax=40, A_amax=200)
    row = RowNLP(m, 5, backoff=0.01)
    lw = np.radians([[2.0, 20.0], [5.0, 5.0], [2.0, 20.0], [2.0, 20.0], [2.0, 20.0]])
    lbx, ubx, lbg, ubg = row.bounds(lw)
    span = np.radians(80.0)
    np.testing.assert_allclose(lbx[0::2], np.radians(-30.0) + 0.005 * span)
    np.testing.assert_allclose(ubx[0::2], np.radians(50.0) - 0.005 * span)
    np.testing.assert_allclose(ubx[1::2], np.radians(100.0) - 0.005 * np.radians(200.0))
    vb = ubg[4:8]  # B velocity rows
    np.testing.assert_allclose(vb, np.radians(40.0) * 0.99)
    np.testing.assert_allclose(lbg[4:8], -np.radians(40.0) * 0.99)
    np.testing.assert_allclose(ubg[8:11], np.radians(200.0) * 0.99)  # A acceleration
    lead = slice(14, 19)
    inward = WINDOW_BACKOFF * np.array([1.0, 0.0, 1.0, 1.0, 1.0])  # a zero-width window stays as it is
    np.testing.assert_allclose(lbg[lead], np.cos(np.radians([20.0, 5.0, 20.0, 20.0, 20.0]) - inward))
    np.testing.assert_allclose(ubg[lead], np.cos(np.radians([2.0, 5.0, 2.0, 2.0, 2.0]) + inward))


def test_difference_operators_are_exact_on_quadratics():
    """On non-uniform steps the segment velocity of a t^2 + b t + c is a (t_i + t_(i+1)) + b and the
    three-point second difference is 2a exactly; np.gradient is exact inside the row."""
    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.01, 0.05, 12))
    a, b, c = 3.0, -2.0, 0.5
    q = a * t ** 2 + b * t + c
    D1, D2 = fd_operators(t)
    np.testing.assert_allclose(D1 @ q, a * (t[1:] + t[:-1]) + b, rtol=1e-10)
    np.testing.assert_allclose(D2 @ q, 2 * a, rtol=1e-9)
    vel, acc = rates(q, t)
    np.testing.assert_allclose(vel[1:-1], 2 * a * t[1:-1] + b, rtol=1e-9)
    np.testing.assert_allclose(acc, 2 * a, rtol=1e-9)
    T = np.stack([q, -q, 0.5 * q], 1)
    assert gamma(T, t) == pytest.approx((len(t) - 2) * (2 * a) ** 2 * 2.25, rel=1e-9)
    assert gamma(T[:2], t[:2]) == 0.0
    assert fd_operators(t[:2])[1].shape == (0, 2)
    v2, a2 = rates(q[:2], t[:2])
    np.testing.assert_allclose(v2, (q[1] - q[0]) / (t[1] - t[0]))
    assert np.all(a2 == 0)
    v1, a1 = rates(q[:1], t[:1])
    assert np.all(v1 == 0) and np.all(a1 == 0)
    with pytest.raises(InfeasibleError, match="increase strictly"):
        fd_operators(np.array([0.0, 0.1, 0.1, 0.2]))


@pytest.mark.parametrize("n", [2, 3, 5, 11, 47])
def test_spline_row_interpolates_its_knots_and_reproduces_cubics(n):
    """Knots every step-th point and the last; a cubic is reproduced exactly from 4 knots on (not-a-knot),
    a line from 3 (natural); 2 points are returned as they are."""
    t = np.cumsum(np.random.default_rng(n).uniform(0.01, 0.03, n))
    cubic = 1 + 2 * t - 3 * t ** 2 + 40 * t ** 3
    line = 0.3 - 2 * t
    A, B = spline_row(cubic, line, t, step=10)
    if n == 2:
        np.testing.assert_array_equal(A, cubic)
        return
    np.testing.assert_allclose(B, line, atol=1e-12)
    if n >= 5:
        np.testing.assert_allclose(A, cubic, atol=1e-10)
    rough = np.sin(50 * t) + np.random.default_rng(0).normal(0, 0.1, n)
    R, _ = spline_row(rough, rough, t, step=10)
    knots = np.unique(np.concatenate([np.arange(0, n, 10), [n - 1]]))
    if len(knots) >= 4:
        np.testing.assert_allclose(R[knots], rough[knots], atol=1e-12)
    assert R[-1] == pytest.approx(rough[-1], abs=1e-12)


def test_constraint_report_names_each_violation_with_its_size():
    """A hand-made pair of angle sequences that leaves each limit once by a known amount."""
    m = M0
    t = np.array([0.0, 0.010, 0.021, 0.030, 0.042, 0.050, 0.061, 0.070])  # uneven: no ties
    LA, LB = m.limits["A"], m.limits["B"]
    A = np.zeros(8)
    A[6] = LA.max + 0.02                      # travel by 0.02 rad at point 6 (and a jump)
    B = np.zeros(8)
    B[2] = B[3] = 1.5 * LB.vmax * 0.011      # segment 1 -> 2 at 1.5 vmax (3 -> 4 is longer)
    got = {name: (i, v) for name, i, v in RowNLP(m, 8).constraint_report(t, RotaryValues.of(m.rotary, A, B))}
    assert got["A travel"] == (6, pytest.approx(0.02))
    seg_a = np.abs(np.diff(A) / np.diff(t))
    assert got["A velocity"] == (int(np.argmax(seg_a)), pytest.approx(seg_a.max() - LA.vmax))
    acc_a = np.abs(_d2(A, t))
    assert got["A acceleration"] == (int(np.argmax(acc_a)) + 1, pytest.approx(acc_a.max() - LA.amax))
    assert got["B velocity"] == (1, pytest.approx(0.5 * LB.vmax))
    acc_b = np.abs(_d2(B, t))
    assert got["B acceleration"] == (int(np.argmax(acc_b)) + 1, pytest.approx(acc_b.max() - LB.amax))
    assert "B travel" not in got
    assert RowNLP(m, 8).constraint_report(t, RotaryValues.of(m.rotary, np.zeros(8), np.full(8, LB.min))) == []


def _mirrored(fr: np.ndarray, k: int) -> np.ndarray:
    """Local frames mirrored in the workpiece's coordinate k (kept right-handed): the row's normals
    tip the other way, so the axis that follows them moves with the opposite sign."""
    mirror = np.eye(3)
    mirror[k, k] = -1.0
    out = np.einsum("ij,njk->nik", mirror, fr)
    out[:, :, 1] *= -1
    return out


@pytest.mark.parametrize("mirrored", [False, True], ids=["", "mirrored"])
@pytest.mark.parametrize("turned", [False, True], ids=["B", "A"])
@pytest.mark.parametrize("kind", ["velocity", "acceleration"])
def test_elastic_diagnosis_names_the_rate_the_windows_need_and_where(kind, turned, mirrored):
    """The lead window [0, 0.01] deg pins the axis to the surface normal, so the moving axis (B on the
    row along x, A along y) must follow the normal's angle beta = atan(dz/dx) (closed form on the
    wave): a limit at 0.4 of max |beta'| or |beta''| (the test's own differences) is named with
    that need (within 2.5%: the window's 0.01 deg of slack) at the point where beta needs it; the
    mirrored row needs the same rates with the other sign."""
    t, fr, _ = wave_row(turned=turned)
    if mirrored:
        fr = _mirrored(fr, 1 if turned else 0)
    x = np.arange(N) * 0.4
    beta = np.degrees(np.arctan(0.5 * np.cos(x / 10)))
    rate = np.abs(_d1(beta, t) if kind == "velocity" else _d2(beta, t))
    where = int(np.argmax(rate)) + (0 if kind == "velocity" else 1)
    axis = "A" if turned else "B"
    field = "vmax" if kind == "velocity" else "amax"
    m = with_limits(M0, **{f"{axis}_{field}": 0.4 * rate.max()})
    lw, tw = np.tile(np.radians([0.0, 0.01]), (N, 1)), np.tile(np.radians([-15.0, 15.0]), (N, 1))
    ik = m.solve_row(fr[:, :, 2])
    b = elastic_diagnosis(m, t, fr, lw, tw, ik.rotary)
    assert b.constraint == f"{axis} {kind}" and b.binds and not b.lower
    assert b.unit == ("deg/s" if kind == "velocity" else "deg/s^2")
    assert b.limit == pytest.approx(0.4 * rate.max())
    assert b.need == pytest.approx(rate.max(), rel=0.025)
    assert b.point == where


@pytest.mark.parametrize("turned", [False, True], ids=["B", "A"])
def test_elastic_diagnosis_names_the_travel_the_windows_need_on_either_side(turned):
    """As above with the travel limited to +-half of max |beta|: the angle needed is named, on
    each side of the range (the row mirrored in its feed direction needs the other sign)."""
    t, fr, _ = wave_row(turned=turned)
    x = np.arange(N) * 0.4
    beta = np.degrees(np.arctan(0.5 * np.cos(x / 10)))
    half = 0.5 * np.abs(beta).max()
    axis = "A" if turned else "B"
    m = with_limits(M0, **{f"{axis}_min": -half, f"{axis}_max": half})
    lw, tw = np.tile(np.radians([0.0, 0.01]), (N, 1)), np.tile(np.radians([-15.0, 15.0]), (N, 1))
    sides = set()
    for frames in (fr, _mirrored(fr, 1 if turned else 0)):
        ik = m.solve_row(frames[:, :, 2])
        lim = np.radians(half)
        b = elastic_diagnosis(m, t, frames, lw, tw, RotaryValues(m.rotary, np.clip(ik.rotary.values, -lim, lim)))
        assert b.constraint == f"{axis} travel" and b.unit == "deg" and b.binds
        assert abs(b.need) == pytest.approx(np.abs(beta).max(), abs=0.05)
        assert b.point == 0  # the wave is steepest at its start
        assert b.limit == pytest.approx(-half if b.lower else half)
        assert np.sign(b.need) == np.sign(b.limit)
        sides.add(b.lower)
    assert sides == {True, False}


def test_the_fallback_keeps_the_better_feasible_candidate():
    """Of the last iterate and the warm start, the one with the lower Gamma that meets every row
    (IPOPT failed); neither meeting them is a failure."""
    t, fr, T = wave_row()
    t = 2 * t
    lw, tw = np.tile(np.radians([2.0, 20.0]), (N, 1)), np.tile(np.radians([-15.0, 15.0]), (N, 1))
    ik = M0.solve_row(T)
    row = RowNLP(M0, N, screening=False)
    q, st = row.solve(t, fr, ik.rotary, lw, tw)
    A, B = q["A"], q["B"]
    x0, x1 = np.empty(2 * N), np.empty(2 * N)
    x0[0::2], x0[1::2] = ik.rotary.pair
    x1[0::2], x1[1::2] = A, B
    lbx, ubx, lbg, ubg = row.bounds(lw)
    p = row._params(t, fr, tw, 1.0, LeadBounds.none(N))
    exists = np.arange(len(lbg)) < sum(row.sizes[:7])
    for first, second in ((x1, x0), (x0, x1)):
        x, status, ok = row._feasible_fallback(first, second, p, lbx, ubx, lbg, ubg, exists, t, "Failed")
        assert ok and status == "Failed; a feasible point kept"
        np.testing.assert_array_equal(x, x1)  # the optimum, whichever comes first
    bad = x0 + 1.0  # outside the lead window everywhere
    x, status, ok = row._feasible_fallback(bad, bad, p, lbx, ubx, lbg, ubg, exists, t, "Failed")
    assert not ok and status == "Failed"


def test_spline_row_on_short_rows_uses_four_spread_knots():
    """A 5-point row has knots 0, 1, 3, 4 (four spread points): not-a-knot through four points is
    their interpolating cubic (numpy polyfit of degree 3), so point 2 is that cubic's value."""
    t = np.array([0.0, 0.011, 0.019, 0.032, 0.040])
    y = np.array([0.0, 1.0, -3.0, 0.5, 2.0])
    A, _ = spline_row(y, y, t)
    knots = [0, 1, 3, 4]
    np.testing.assert_allclose(A[knots], y[knots], atol=1e-12)
    assert A[2] == pytest.approx(np.polyval(np.polyfit(t[knots], y[knots], 3), t[2]), rel=1e-9)


def test_binding_threshold():
    assert Binding("B velocity", 3, 60.001, 60.0, "deg/s").binds
    assert not Binding("B velocity", 3, 60.00001, 60.0, "deg/s").binds
    assert Binding("B travel", 3, -30.001, -30.0, "deg", lower=True).binds
    assert not Binding("B travel", 3, -29.0, -30.0, "deg", lower=True).binds
    assert Binding("A travel", 3, -2.0, -3.0, "deg").binds  # a negative max
    assert not Binding("A travel", 3, -3.0, -3.0, "deg").binds
    # past the limit the NLP enforces (backed off), inside the machine's
    near = Binding("B travel", 3, 29.99, 30.0, "deg", enforced=29.97)
    assert near.binds and not near.past_machine_limit
    low = Binding("B travel", 3, -29.99, -30.0, "deg", lower=True, enforced=-29.97)
    assert low.binds and not low.past_machine_limit
    assert Binding("B velocity", 3, 61.0, 60.0, "deg/s", enforced=59.88).past_machine_limit


def test_dilate_stays_inside_each_group():
    mask = np.zeros(12, bool)
    mask[[0, 6]] = True
    got = nlp_mod._dilate(mask, [5, 3, 4], 2)
    np.testing.assert_array_equal(got, [1, 1, 1, 0, 0, 1, 1, 1, 0, 0, 0, 0])


def test_limit_violation_peaks_are_the_largest_rates_even_below_one():
    """The peaks ``limit_violations`` reports are the largest |segment velocity| and |second
    difference| of each axis (the test's own differences), also when they are below 1 (a slow
    program in rad/s), and nothing is counted inside the limits."""
    t = np.array([0.0, 0.1, 0.25, 0.35, 0.0, 0.2, 0.3])
    t[4:] += 1.0
    rows = np.array([0, 0, 0, 0, 1, 1, 1])
    q = np.array([0.0, 0.01, 0.015, 0.03, 0.5, 0.52, 0.5])
    viol, peaks = nlp_mod.limit_violations(M0.limits, {"A": q}, t, rows)
    v = np.concatenate([_d1(q[:4], t[:4]), _d1(q[4:], t[4:])])
    a = np.concatenate([_d2(q[:4], t[:4]), _d2(q[4:], t[4:])])
    assert peaks["A velocity"] == pytest.approx(np.abs(v).max(), rel=1e-12) and np.abs(v).max() < 1
    assert peaks["A acceleration"] == pytest.approx(np.abs(a).max(), rel=1e-12)
    assert viol == {"A travel": 0, "A velocity": 0, "A acceleration": 0}


def test_rows_from_a_thousand_points_are_screened_by_default():
    assert RowNLP(M0, nlp_mod.SCREEN_MIN_POINTS).screening
    assert not RowNLP(M0, nlp_mod.SCREEN_MIN_POINTS - 1).screening


def test_travel_is_counted_alike_at_both_ends():
    """Travel violations at the min and at the max, mirror images (issue 21 item 5 (a)): travel
    [-1, 1], the counts worked out here. Without a resolution a point at either end is inside and
    a point 1e-6 past either end is out; with the written resolution e = 0.01 only points more than
    e past an end count, at both ends alike."""
    from camsmooth.machine.kinematics import AxisLimits

    lim = {"A": AxisLimits(-1.0, 1.0, 1e9, 1e12)}
    q = np.array([-1.02, -1.005, -1.0, -1.000001, 0.0, 0.995, 1.0, 1.000001, 1.005, 1.02])
    t, rows = np.arange(len(q), dtype=float), np.zeros(len(q), np.int64)
    for sel, plain, resolved in (([0, 1, 2, 4], 2, 1), ([4, 5, 6, 8, 9], 2, 1), ([2, 3, 4, 6, 7], 2, 0),
                                 (list(range(len(q))), 6, 2)):
        viol, _ = nlp_mod.limit_violations(lim, {"A": q[sel]}, t[:len(sel)], rows[:len(sel)])
        assert viol["A travel"] == plain, (q[sel], viol)
        viol, _ = nlp_mod.limit_violations(lim, {"A": q[sel]}, t[:len(sel)], rows[:len(sel)], resolution={"A": 0.01})
        assert viol["A travel"] == resolved, (q[sel], viol)
