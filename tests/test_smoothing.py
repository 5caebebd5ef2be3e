"""The row NLP itself: the derivatives IPOPT receives against CasADi's automatic differentiation
of an independent formulation, the convexified constraint curvature against numpy's eigh, and
constraint screening against solving with every row."""

import dataclasses

import casadi as ca
import numpy as np
import pytest

import camsmooth.smoothing.nlp as smoothing
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import load_machine
from camsmooth.smoothing.nlp import RowNLP, _psd_part, fd_operators, gamma, spline_row
from camsmooth.smoothing.orientation import axis_from_lead_tilt, local_frames

LEAD, TILT = np.radians([2.0, 20.0]), np.radians([-15.0, 15.0])


def wavy_row(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (s), local frames and rough CAM axes of a row on z = 5 sin(x / 10) mm, 0.4 mm
    spacing at 2000 mm/min, the lead jittered by +-3 degrees."""
    x = np.arange(n) * 0.4
    dz = 0.5 * np.cos(x / 10)
    nrm = np.stack([-dz, 0 * x, np.ones_like(x)], 1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    fr = local_frames(nrm, np.stack([np.ones_like(x), 0 * x, dz], 1))
    lead = np.radians(11 + 3 * np.random.default_rng(seed).uniform(-1, 1, n))
    p = np.stack([x, 0 * x, 5 * np.sin(x / 10)], 1)
    t = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1) / (2000 / 60))])
    return t, fr, axis_from_lead_tilt(lead, np.zeros(n), fr)


def perturbed_machine():
    """The default AB head with its A and B screws tilted and moved (an error model's chain)."""
    m = load_machine()
    screws = []
    rng = np.random.default_rng(3)
    for w, v in m.chain.joint_screws():
        if np.any(w):
            w = w + 1e-2 * rng.standard_normal(3)
            w = w / np.linalg.norm(w)
            v = -np.cross(w, rng.standard_normal(3))
        screws.append((w, v))
    return dataclasses.replace(m, chain=m.chain.with_screws(screws))


def test_psd_part_matches_eigh():
    rng = np.random.default_rng(1)
    M = rng.standard_normal((200, 2, 2))
    M = M + M.transpose(0, 2, 1)
    M[:3] = [[[1, 0], [0, 1]], [[-1, 0], [0, -1]], [[2, 0], [0, 2]]]  # repeated eigenvalues
    f = ca.Function("f", [a := ca.MX.sym("a", 200), b := ca.MX.sym("b", 200), c := ca.MX.sym("c", 200)],
                    list(_psd_part(a, b, c)))
    got = [np.asarray(v).ravel() for v in f(M[:, 0, 0], M[:, 0, 1], M[:, 1, 1])]
    lam, V = np.linalg.eigh(M)
    ref = np.einsum("nij,nj,nkj->nik", V, np.maximum(lam, 0), V)
    np.testing.assert_allclose(got[0], ref[:, 0, 0], atol=1e-12)
    np.testing.assert_allclose(got[1], ref[:, 0, 1], atol=1e-12)
    np.testing.assert_allclose(got[2], ref[:, 1, 1], atol=1e-12)


@pytest.mark.parametrize("machine", [load_machine(), perturbed_machine()], ids=["nominal", "perturbed"])
def test_derivatives_match_automatic_differentiation(machine):
    """Objective, gradient, constraints, Jacobian and Hessian of the Lagrangian as IPOPT gets
    them, against CasADi AD of the NLP written directly in SX with scipy difference operators
    (window rows and the accessibility map's lead floor and ceiling rows included)."""
    n = 9
    t, fr, T = wavy_row(n)
    t = np.concatenate([[0], np.cumsum(np.diff(t) * (1 + 0.5 * np.sin(np.arange(n - 1))))])  # non-uniform
    tw = np.tile(TILT, (n, 1)) + np.radians([[-3.0, 2.0]])
    nlp = RowNLP(machine, n, screening=False)
    rows = [np.arange(k) for k in nlp.sizes]
    solver, _ = nlp._solver(rows)
    scale = 0.37
    rng = np.random.default_rng(2)
    cf = np.column_stack([rng.uniform(0.05, 0.2, n), rng.uniform(-0.3, 0.3, n), rng.uniform(-1, 1, n)])
    cc = cf + np.array([0.2, 0.0, 0.0])
    bounds = smoothing.LeadBounds(cf, cc, np.ones(n, bool), np.ones(n, bool))
    p = nlp._params(t, fr, tw, scale, bounds)
    x = rng.uniform(-0.4, 0.4, 2 * n)
    lam_g = rng.standard_normal(sum(nlp.sizes))
    lam_f = 1.3

    # independent formulation
    xs = ca.SX.sym("x", 2 * n)
    A, B = xs[0::2], xs[1::2]
    Ts = ca.horzcat(*machine.tool_axis(A, B))
    D1, D2 = (ca.DM(M.toarray()) for M in fd_operators(t))
    f = scale * ca.sumsqr(ca.mtimes(D2, Ts))
    X, Y, Z = fr[:, :, 0], fr[:, :, 1], fr[:, :, 2]
    lo, hi = tw[:, :1] + smoothing.WINDOW_BACKOFF, tw[:, 1:] - smoothing.WINDOW_BACKOFF
    Cmin, Cmax = Y * np.cos(lo) - X * np.sin(lo), X * np.sin(hi) - Y * np.cos(hi)
    gw = [ca.sum2(ca.DM(C) * Ts) for C in (Z, Cmin, Cmax)]
    x_, y_, z_ = (ca.sum2(ca.DM(C) * Ts) for C in (X, Y, Z))
    tilt_, lead_ = ca.atan2(y_, x_), ca.atan2(ca.sqrt(x_ ** 2 + y_ ** 2), z_)
    gw += [lead_ - ca.DM(C[:, 0]) - ca.DM(C[:, 1]) * tilt_ - ca.DM(C[:, 2]) * tilt_ ** 2 for C in (cf, cc)]
    g = ca.vertcat(ca.mtimes(D1, A), ca.mtimes(D1, B), ca.mtimes(D2, A), ca.mtimes(D2, B), *gw)
    lw = ca.SX.sym("lw", 5 * n)
    ref = ca.Function("ref", [xs, lw], [f, ca.gradient(f, xs), g, ca.jacobian(g, xs),
                                        ca.hessian(lam_f * f, xs)[0], ca.hessian(ca.dot(lw, ca.vertcat(*gw)), xs)[0]])
    f_r, grad_r, g_r, J_r, Hf_r, Hw_r = (np.asarray(ca.DM(v)) for v in ref(x, lam_g[-5 * n:]))

    f_c, grad_c = (np.asarray(ca.DM(v)) for v in solver.get_function("nlp_grad_f")(x, p))
    g_c, J_c = (np.asarray(ca.DM(v)) for v in solver.get_function("nlp_jac_g")(x, p))
    H_c = np.asarray(ca.DM(solver.get_function("nlp_hess_l")(x, p, lam_f, lam_g)))
    H_c = H_c + np.triu(H_c, 1).T
    np.testing.assert_allclose(f_c, f_r, rtol=1e-12)
    np.testing.assert_allclose(grad_c, grad_r, rtol=1e-10, atol=1e-12 * np.abs(grad_r).max())
    np.testing.assert_allclose(g_c, g_r, atol=1e-12)
    np.testing.assert_allclose(J_c, J_r, rtol=1e-9, atol=1e-12)
    # window and clearance curvature: only its positive semidefinite part, point by point
    blocks = np.stack([Hw_r[2 * k:2 * k + 2, 2 * k:2 * k + 2] for k in range(n)])
    assert np.count_nonzero(Hw_r) == np.count_nonzero([b for b in blocks])  # block diagonal
    lam, V = np.linalg.eigh(blocks)
    assert (lam < 0).any()  # the test exercises the clipping
    H_ref = Hf_r.copy()
    for k, Bk in enumerate(np.einsum("nij,nj,nkj->nik", V, np.maximum(lam, 0), V)):
        H_ref[2 * k:2 * k + 2, 2 * k:2 * k + 2] += Bk
    # entry by entry: the stencil weights make the largest entries ~1e9, so a tolerance relative to the
    # largest would hide an error of order 1 in the small ones
    np.testing.assert_allclose(H_c, H_ref, rtol=1e-8, atol=1e-15 * np.abs(H_ref).max())


def _all_rows_feasible(nlp: RowNLP, t, fr, lw, tw, A, B) -> bool:
    x = np.empty(2 * nlp.n)
    x[0::2], x[1::2] = A, B
    _, _, lbg, ubg = nlp.bounds(lw)
    g = np.asarray(nlp.g_all(x, nlp._params(t, fr, tw, 1.0, smoothing.LeadBounds.none(nlp.n)))).ravel()
    ok = (g >= lbg - 1e-9) & (g <= ubg + 1e-9)
    return bool(np.all(ok[:sum(nlp.sizes[:7])]))  # no clearance rows in these rows


@pytest.fixture(scope="module")
def binding_row():
    """A 1200-point rough row on a machine whose B acceleration limit (150 deg/s^2) binds."""
    m = load_machine()
    lim = dict(m.limits)
    lim["B"] = dataclasses.replace(lim["B"], amax=np.radians(150.0))
    m = dataclasses.replace(m, limits=lim)
    n = 1200
    t, fr, T = wavy_row(n)
    ik = m.solve_row(T)
    start = RotaryValues.of(m.rotary, *spline_row(*ik.rotary.pair, t))
    lw, tw = np.tile(LEAD, (n, 1)), np.tile(TILT, (n, 1))
    full = RowNLP(m, n, screening=False)
    q, st = full.solve(t, fr, start, lw, tw)
    assert st.success and st.rows == st.total_rows
    return m, t, fr, lw, tw, start, gamma(m.tool_axis_np(q["A"], q["B"]), t)


def test_screening_brings_in_binding_rows(binding_row):
    m, t, fr, lw, tw, start, g_full = binding_row
    nlp = RowNLP(m, len(t))
    assert nlp.screening  # long rows screen by default
    q, st = nlp.solve(t, fr, start, lw, tw)
    A, B = q["A"], q["B"]
    assert st.success, st.status
    assert st.rounds >= 2 and st.rows < st.total_rows / 2
    assert nlp.constraint_report(t, q) == []
    assert _all_rows_feasible(nlp, t, fr, lw, tw, A, B)
    D2 = fd_operators(t)[1]
    assert np.abs(D2 @ B).max() > 0.99 * m.limits["B"].amax  # the limit really binds
    assert gamma(m.tool_axis_np(A, B), t) == pytest.approx(g_full, rel=1e-5)


def test_screening_falls_back_to_every_row(binding_row, monkeypatch):
    m, t, fr, lw, tw, start, g_full = binding_row
    monkeypatch.setattr(smoothing, "SCREEN_ROUNDS", 1)
    nlp = RowNLP(m, len(t))
    q, st = nlp.solve(t, fr, start, lw, tw)
    A, B = q["A"], q["B"]
    assert st.success and st.rows == st.total_rows and st.rounds == 2
    assert _all_rows_feasible(nlp, t, fr, lw, tw, A, B)
    assert gamma(m.tool_axis_np(A, B), t) == pytest.approx(g_full, rel=1e-9)


def test_program_rates_equal_the_row_by_row_definitions():
    """The whole-program differences against fd_operators and rates row by row, on rows of uneven
    lengths and steps (3 points being the shortest row)."""
    rng = np.random.default_rng(0)
    lens = [5, 3, 17, 40]
    rows = np.concatenate([np.full(k, 10 + i) for i, k in enumerate(lens)])
    t = np.concatenate([np.cumsum(rng.uniform(0.01, 0.03, k)) for k in lens])
    q = rng.normal(size=(len(t), 3))
    pr = smoothing.program_rates(q, t, rows)
    start = 0
    total = 0.0
    for k in lens:
        sl = slice(start, start + k)
        start += k
        v, a = smoothing.rates(q[sl], t[sl])
        np.testing.assert_allclose(pr.vel[sl], v, rtol=1e-12)
        np.testing.assert_allclose(pr.acc[sl], a, rtol=1e-12)
        D1, D2 = fd_operators(t[sl])
        np.testing.assert_allclose(pr.seg_vel[(pr.seg >= sl.start) & (pr.seg < sl.stop - 1)], D1 @ q[sl], rtol=1e-12)
        np.testing.assert_allclose(pr.sec[(pr.mid > sl.start) & (pr.mid < sl.stop - 1)], D2 @ q[sl], rtol=1e-12)
        total += gamma(q[sl], t[sl])
    assert len(pr.seg_vel) == len(t) - len(lens) and len(pr.sec) == len(t) - 2 * len(lens)
    np.testing.assert_allclose(np.sum(pr.sec ** 2), total, rtol=1e-12)
