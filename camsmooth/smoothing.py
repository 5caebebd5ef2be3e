"""Smoothing the rotary axes of one row: the published spline method and the NLP.

Time derivatives are finite differences over the row's (non-uniform) time stamps t (s):
segment velocities s_i = (q_(i+1) - q_i) / h_i and the three-point second difference
q''_i = 2 (s_i - s_(i-1)) / (h_(i-1) + h_i) at interior points. These are the definitions the
NLP constrains AND the metrics check, so "limits met at every sample" means the same thing in
both places. (np.gradient's velocities are convex combinations of the segment velocities, so
they obey the same bound.)

NLP (METHODS section 1, step D, solved with CasADi + IPOPT): variables A_i, B_i (rad);
minimise Gamma = sum_i |T''(t_i)|^2 over interior points, T(A, B) from the machine's POE chain
(camsmooth.kinematics, through CasADi symbols), subject to A/B travel, segment velocity and
second-difference acceleration limits, and the per-point lead/tilt windows, which are linear in T
in the local frame:
    cos(lead_max) <= n . T <= cos(lead_min),
    y cos(tilt_min) - x sin(tilt_min) >= 0,   x sin(tilt_max) - y cos(tilt_max) >= 0,
with x = X_L . T, y = Y_L . T (tilt windows narrower than 180 degrees).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.sparse as sp
from scipy.interpolate import CubicSpline

from .errors import InfeasibleError
from .kinematics import Machine

# Limits are tightened by this fraction inside the NLP so that IPOPT's tolerance never shows
# as a violation when the result is checked against the true limits.
BACKOFF = 2e-3
WINDOW_BACKOFF = 2e-6  # rad (0.4 arc-seconds): far below any machine error a model describes


def fd_operators(t: np.ndarray) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """Sparse first-difference (N-1, N) and second-difference (N-2, N) operators for time
    stamps t (s, strictly increasing); see the module docstring."""
    t = np.asarray(t, float)
    n = len(t)
    h = np.diff(t)
    if np.any(h <= 0):
        raise InfeasibleError("time stamps must increase strictly along a row")
    i = np.arange(n - 1)
    D1 = sp.csr_matrix((np.concatenate([-1 / h, 1 / h]), (np.concatenate([i, i]), np.concatenate([i, i + 1]))),
                       shape=(n - 1, n))
    if n < 3:
        return D1, sp.csr_matrix((0, n))
    hl, hr = h[:-1], h[1:]
    j = np.arange(n - 2)
    vals = np.concatenate([2 / (hl * (hl + hr)), -2 / (hl * hr), 2 / (hr * (hl + hr))])
    D2 = sp.csr_matrix((vals, (np.tile(j, 3), np.concatenate([j, j + 1, j + 2]))), shape=(n - 2, n))
    return D1, D2


def rates(q: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-point velocity (np.gradient, second order) and acceleration (three-point second
    difference; the end points repeat their neighbour) of q(t)."""
    q = np.asarray(q, float)
    if len(q) < 2:
        return np.zeros_like(q), np.zeros_like(q)
    vel = np.gradient(q, t, axis=0)
    if len(q) < 3:
        return vel, np.zeros_like(q)
    _, D2 = fd_operators(t)
    acc_i = D2 @ q
    acc = np.concatenate([acc_i[:1], acc_i, acc_i[-1:]], axis=0)
    return vel, acc


def compound_acceleration(T: np.ndarray, t: np.ndarray) -> np.ndarray:
    """|d^2 T / dt^2| per point (1/s^2) for unit axes T (N, 3) (end points repeat their
    neighbour)."""
    _, acc = rates(T, t)
    return np.linalg.norm(acc, axis=1)


def gamma(T: np.ndarray, t: np.ndarray) -> float:
    """Gamma = sum over interior points of |T''|^2 (1/s^4), METHODS section 1 step D."""
    if len(T) < 3:
        return 0.0
    _, D2 = fd_operators(t)
    return float(np.sum((D2 @ T) ** 2))


def spline_row(A: np.ndarray, B: np.ndarray, t: np.ndarray, step: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """The published method (METHODS section 1, step E(2)): sample A and B every ``step``-th CC
    point (and the last), fit each with a not-a-knot cubic spline over time (scipy CubicSpline)
    and evaluate it at every CC point."""
    n = len(t)
    idx = np.unique(np.concatenate([np.arange(0, n, step), [n - 1]]))
    if len(idx) < 4:
        idx = np.unique(np.linspace(0, n - 1, min(n, 4)).round().astype(int))
    if len(idx) < 2:
        return A.copy(), B.copy()
    bc = "not-a-knot" if len(idx) >= 4 else "natural"
    return (CubicSpline(t[idx], A[idx], bc_type=bc)(t), CubicSpline(t[idx], B[idx], bc_type=bc)(t))


def _dm_sparse(M: sp.spmatrix) -> ca.DM:
    M = sp.csc_matrix(M)
    return ca.DM(ca.Sparsity(M.shape[0], M.shape[1], M.indptr.tolist(), M.indices.tolist()), M.data)


@dataclass
class NLPStatus:
    """What IPOPT said: success flag, return status text, iterations, solve time (s)."""

    success: bool
    status: str
    iterations: int
    time_s: float
    build_s: float


class RowNLP:
    """The smoothing NLP of one row length N, built once and solved for any row of that length
    (time steps, local frames, lead/tilt windows and the objective scale are parameters; the
    interference loop re-solves with tightened windows without a rebuild).

    machine: kinematics (nominal or with an error model applied: the axis T is whatever its POE
    chain gives, evaluated on CasADi symbols). Build cost grows linearly with N.
    """

    def __init__(self, machine: Machine, n: int, *, ipopt_options: dict | None = None) -> None:
        import time

        if n < 3:
            raise InfeasibleError(f"a row needs at least 3 points to smooth, got {n}")
        t0 = time.perf_counter()
        self.machine, self.n = machine, n
        x = ca.SX.sym("x", 2 * n)
        A, B = x[0::2], x[1::2]
        T = [e if isinstance(e, ca.SX) else ca.SX(e) * ca.SX.ones(n) for e in machine.tool_axis(A, B)]
        # parameters: 1/h (n-1), second-difference weights c0, c1, c2 (n-2 each), window
        # coefficient vectors (9 n: normal, tilt-min and tilt-max rows), objective scale.
        m1, m2 = n - 1, n - 2
        p = ca.SX.sym("p", m1 + 3 * m2 + 9 * n + 1)
        invh = p[0:m1]
        c0, c1, c2 = (p[m1 + k * m2:m1 + (k + 1) * m2] for k in range(3))
        off = m1 + 3 * m2
        W = [p[off + k * n:off + (k + 1) * n] for k in range(9)]
        scale = p[off + 9 * n]

        def d1(q: ca.SX) -> ca.SX:
            return (q[1:] - q[:-1]) * invh

        def d2(q: ca.SX) -> ca.SX:
            return c0 * q[:-2] + c1 * q[1:-1] + c2 * q[2:]

        obj = (ca.sumsqr(d2(T[0])) + ca.sumsqr(d2(T[1])) + ca.sumsqr(d2(T[2]))) * scale
        dot = lambda a, b, c: a * T[0] + b * T[1] + c * T[2]  # noqa: E731
        g = ca.vertcat(d1(A), d1(B), d2(A), d2(B), dot(*W[0:3]), dot(*W[3:6]), dot(*W[6:9]))
        opts = {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.max_iter": 500,
                "ipopt.tol": 1e-6, "ipopt.acceptable_tol": 1e-4, "ipopt.mu_strategy": "adaptive",
                "ipopt.constr_viol_tol": 1e-10, "ipopt.acceptable_constr_viol_tol": 1e-9,
                "ipopt.linear_solver": "mumps"}
        opts.update(ipopt_options or {})
        self.solver = ca.nlpsol("smooth_row", "ipopt", {"x": x, "p": p, "f": obj, "g": g}, opts)
        self.build_s = time.perf_counter() - t0

    def _params(self, t: np.ndarray, frames: np.ndarray, tilt_window: np.ndarray, scale: float) -> np.ndarray:
        h = np.diff(t)
        hl, hr = h[:-1], h[1:]
        X, Y, Z = frames[:, :, 0], frames[:, :, 1], frames[:, :, 2]
        mid = 0.5 * (tilt_window[:, 0:1] + tilt_window[:, 1:2])
        tmin = np.minimum(tilt_window[:, 0:1] + WINDOW_BACKOFF, mid)
        tmax = np.maximum(tilt_window[:, 1:2] - WINDOW_BACKOFF, mid)
        cmin = Y * np.cos(tmin) - X * np.sin(tmin)
        cmax = X * np.sin(tmax) - Y * np.cos(tmax)
        return np.concatenate([1 / h, 2 / (hl * (hl + hr)), -2 / (hl * hr), 2 / (hr * (hl + hr)),
                               Z.T.ravel(), cmin.T.ravel(), cmax.T.ravel(), [scale]])

    def bounds(self, lead_window: np.ndarray) -> tuple[np.ndarray, ...]:
        """lbx, ubx, lbg, ubg for the current windows (limits backed off by BACKOFF)."""
        n, lim = self.n, self.machine.limits
        la, lb = lim["A"], lim["B"]

        def band(lo: float, hi: float) -> tuple[float, float]:
            w = (hi - lo) * BACKOFF * 0.5
            return lo + w, hi - w

        a_lo, a_hi = band(la.min, la.max)
        b_lo, b_hi = band(lb.min, lb.max)
        lbx = np.empty(2 * n)
        ubx = np.empty(2 * n)
        lbx[0::2], ubx[0::2], lbx[1::2], ubx[1::2] = a_lo, a_hi, b_lo, b_hi
        f = 1.0 - BACKOFF
        lo_l = np.minimum(lead_window[:, 0] + WINDOW_BACKOFF, lead_window.mean(axis=1))
        hi_l = np.maximum(lead_window[:, 1] - WINDOW_BACKOFF, lead_window.mean(axis=1))
        lbg = np.concatenate([np.full(n - 1, -la.vmax * f), np.full(n - 1, -lb.vmax * f),
                              np.full(max(n - 2, 0), -la.amax * f), np.full(max(n - 2, 0), -lb.amax * f),
                              np.cos(hi_l), np.zeros(n), np.zeros(n)])
        ubg = np.concatenate([np.full(n - 1, la.vmax * f), np.full(n - 1, lb.vmax * f),
                              np.full(max(n - 2, 0), la.amax * f), np.full(max(n - 2, 0), lb.amax * f),
                              np.cos(lo_l), np.full(n, np.inf), np.full(n, np.inf)])
        return lbx, ubx, lbg, ubg

    def solve(self, t: np.ndarray, frames: np.ndarray, A0: np.ndarray, B0: np.ndarray, lead_window: np.ndarray,
              tilt_window: np.ndarray) -> tuple[np.ndarray, np.ndarray, NLPStatus]:
        """Solve one row: time stamps t (N,) s, local frames (N, 3, 3) (columns X_L, Y_L, n),
        warm start (A0, B0) rad, windows (N, 2) rad. Returns A, B (rad) and the status."""
        import time

        x0 = np.empty(2 * self.n)
        x0[0::2], x0[1::2] = A0, B0
        T0 = self.machine.tool_axis_np(A0, B0)
        scale = 1.0 / max(gamma(T0, t), 1e-6)
        lbx, ubx, lbg, ubg = self.bounds(lead_window)
        x0 = np.clip(x0, lbx, ubx)
        t0 = time.perf_counter()
        p = self._params(np.asarray(t, float), frames, tilt_window, scale)
        sol = self.solver(x0=x0, p=p, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        dt = time.perf_counter() - t0
        stats = self.solver.stats()
        x = np.asarray(sol["x"]).ravel()
        return x[0::2], x[1::2], NLPStatus(bool(stats["success"]), str(stats["return_status"]),
                                           int(stats.get("iter_count", -1)), dt, self.build_s)

    def constraint_report(self, t: np.ndarray, A: np.ndarray, B: np.ndarray) -> list[tuple[str, int, float]]:
        """Constraint groups violated by (A, B) against the TRUE limits (no back-off): a list of
        (constraint name, point index, amount in the constraint's units, rad-based)."""
        out: list[tuple[str, int, float]] = []
        lim = self.machine.limits
        D1, D2 = fd_operators(t)
        for name, q in (("A", A), ("B", B)):
            L = lim[name]
            over = np.maximum(q - L.max, L.min - q)
            if np.any(over > 1e-9):
                i = int(np.argmax(over))
                out.append((f"{name} travel", i, float(over[i])))
            v = D1 @ q
            over = np.abs(v) - L.vmax
            if np.any(over > 1e-9 * L.vmax):
                i = int(np.argmax(over))
                out.append((f"{name} velocity", i, float(over[i])))
            over = np.abs(D2 @ q) - L.amax
            if np.any(over > 1e-9 * L.amax):
                i = int(np.argmax(over))
                out.append((f"{name} acceleration", i + 1, float(over[i])))
        return out


def elastic_diagnosis(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_window: np.ndarray,
                      tilt_window: np.ndarray, A0: np.ndarray, B0: np.ndarray) -> tuple[str, int, float]:
    """Name the binding constraint of an infeasible row: re-solve with every limit group made
    elastic (non-negative slacks on velocity and acceleration limits, scaled by the limit) and
    minimise the sum of slacks; the largest slack names the constraint, the point and how much
    more it would need. Returns (constraint, point index, required value in deg/s or deg/s^2)."""
    n = len(t)
    D1, D2 = fd_operators(t)
    lim = machine.limits
    x = ca.SX.sym("x", 2 * n)
    A, B = x[0::2], x[1::2]
    Tx, Ty, Tz = machine.tool_axis(A, B)
    s = ca.SX.sym("s", 4)  # one slack per group: A vel, B vel, A acc, B acc (fraction of the limit)
    d1, d2 = _dm_sparse(D1), _dm_sparse(D2)
    X, Y, Z = frames[:, :, 0], frames[:, :, 1], frames[:, :, 2]
    tmin, tmax = tilt_window[:, 0:1], tilt_window[:, 1:2]
    cmin = Y * np.cos(tmin) - X * np.sin(tmin)
    cmax = X * np.sin(tmax) - Y * np.cos(tmax)
    dotc = lambda C: C[:, 0] * Tx + C[:, 1] * Ty + C[:, 2] * Tz  # noqa: E731
    va, vb = ca.mtimes(d1, A) / lim["A"].vmax, ca.mtimes(d1, B) / lim["B"].vmax
    aa, ab = ca.mtimes(d2, A) / lim["A"].amax, ca.mtimes(d2, B) / lim["B"].amax
    g = ca.vertcat(va - s[0], va + s[0], vb - s[1], vb + s[1], aa - s[2], aa + s[2], ab - s[3], ab + s[3],
                   dotc(Z), dotc(cmin), dotc(cmax))
    m1, m2 = n - 1, n - 2
    inf = np.inf
    lbg = np.concatenate([np.full(m1, -inf), np.full(m1, -1), np.full(m1, -inf), np.full(m1, -1),
                          np.full(m2, -inf), np.full(m2, -1), np.full(m2, -inf), np.full(m2, -1),
                          np.cos(lead_window[:, 1]), np.zeros(n), np.zeros(n)])
    ubg = np.concatenate([np.full(m1, 1), np.full(m1, inf), np.full(m1, 1), np.full(m1, inf),
                          np.full(m2, 1), np.full(m2, inf), np.full(m2, 1), np.full(m2, inf),
                          np.cos(lead_window[:, 0]), np.full(n, inf), np.full(n, inf)])
    lbx = np.concatenate([np.tile([lim["A"].min, lim["B"].min], n), np.zeros(4)])
    ubx = np.concatenate([np.tile([lim["A"].max, lim["B"].max], n), np.full(4, inf)])
    solver = ca.nlpsol("elastic", "ipopt", {"x": ca.vertcat(x, s), "f": ca.sum1(s), "g": g},
                       {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.max_iter": 1000})
    x0 = np.concatenate([np.ravel(np.column_stack([A0, B0])), np.full(4, 10.0)])
    sol = solver(x0=np.clip(x0, lbx, ubx), lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    xs = np.asarray(sol["x"]).ravel()
    slack = xs[2 * n:]
    k = int(np.argmax(slack))
    Aopt, Bopt = xs[0:2 * n:2], xs[1:2 * n:2]
    names = ("A velocity", "B velocity", "A acceleration", "B acceleration")
    q = Aopt if k in (0, 2) else Bopt
    vals = np.abs(D1 @ q) if k < 2 else np.abs(D2 @ q)
    i = int(np.argmax(vals)) + (0 if k < 2 else 1)
    return names[k], i, float(np.degrees(vals.max()))
