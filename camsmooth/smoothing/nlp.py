"""Smoothing the rotary axes of one row: the published spline method and the NLP.

Time derivatives are finite differences over the row's (non-uniform) time stamps t (s):
segment velocities s_i = (q_(i+1) - q_i) / h_i and the three-point second difference
q''_i = 2 (s_i - s_(i-1)) / (h_(i-1) + h_i) at interior points. These are the definitions the
NLP constrains AND the metrics check, so "limits met at every sample" means the same thing in
both places. (np.gradient's velocities are convex combinations of the segment velocities, so
they obey the same bound.)

NLP (METHODS section 1, step D, solved with CasADi + IPOPT): variables q1_i, q2_i (rad), the
machine's two rotary axes in ``Machine.rotary`` order (CasADi symbols named by axis: "q_A", "q_C"
on an A/C table); minimise Gamma = sum_i |T''(t_i)|^2 over interior points, T(q1, q2) from the
machine's POE chain (camsmooth.machine.kinematics, through CasADi symbols), subject to travel,
segment velocity and second-difference acceleration limits, and the per-point lead/tilt windows,
which are linear in T in the local frame:
    cos(lead_max) <= n . T <= cos(lead_min),
    y cos(tilt_min) - x sin(tilt_min) >= 0,   x sin(tilt_max) - y cos(tilt_max) >= 0,
with x = X_L . T, y = Y_L . T (tilt windows narrower than 180 degrees). Where the accessibility
map (camsmooth.geometry.accessibility) found interference inside the window, clearance rows keep
the axis in the clear region: lead >= floor(tilt) and lead <= ceiling(tilt), with
lead = atan2(|(x, y)|, n . T), tilt = atan2(y, x) and floor, ceiling quadratics in tilt.
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import casadi as ca
import numpy as np
import scipy.sparse as sp
from scipy.interpolate import CubicSpline
from scipy.ndimage import binary_dilation

from camsmooth.errors import InfeasibleError
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import AxisLimits, Machine

# Limits are tightened by this fraction inside the NLP so that IPOPT's tolerance never shows
# as a violation when the result is checked against the true limits.
BACKOFF = 2e-3
WINDOW_BACKOFF = 2e-6  # rad (0.4 arc-seconds): far below any machine error a model describes


def enforced_limits(machine: Machine, backoff: float = BACKOFF) -> dict[str, AxisLimits]:
    """The rotary axes' limits the NLP enforces (rad, rad/s, rad/s^2), keyed by name
    (``Machine.rotary``): the machine's travel shrunk by backoff / 2 of its span at each end (a
    continuous axis keeps no travel limit), velocity and acceleration limits by the fraction backoff."""
    out = {}
    for name in machine.rotary:
        L = machine.limits[name]
        w = (L.max - L.min) * backoff * 0.5 if np.isfinite(L.max - L.min) else 0.0
        out[name] = AxisLimits(L.min + w, L.max - w, L.vmax * (1 - backoff), L.amax * (1 - backoff))
    return out


def narrowed(window: np.ndarray) -> np.ndarray:
    """Per-point (lo, hi) windows (N, 2), rad, moved WINDOW_BACKOFF inward at each side (never past
    their middle): the lead and tilt windows the NLP enforces."""
    window = np.asarray(window, float)
    mid = window.mean(axis=1)
    return np.column_stack([np.minimum(window[:, 0] + WINDOW_BACKOFF, mid),
                            np.maximum(window[:, 1] - WINDOW_BACKOFF, mid)])


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


@dataclass(frozen=True)
class ProgramRates:
    """Finite differences of a quantity over a whole program of rows at once (the definitions of
    this module, row by row, without a Python loop over rows): seg_vel (M,) the segment velocities
    of the segments inside rows and seg (M,) the index of each segment's first point; sec (K,) the
    second differences at interior points and mid (K,) their point indices; vel, acc (N, ...) per
    point as ``rates`` gives them."""

    seg_vel: np.ndarray
    seg: np.ndarray
    sec: np.ndarray
    mid: np.ndarray
    vel: np.ndarray
    acc: np.ndarray


def program_rates(q: np.ndarray, t: np.ndarray, rows: np.ndarray) -> ProgramRates:
    """Velocities and second differences of q(t) (N or (N, k)) over a program whose rows are runs
    of equal ``rows``, vectorised over the whole program; per point, velocity as np.gradient
    (second order inside a row, one-sided at its ends) and acceleration as the three-point second
    difference (a row's end points repeat their neighbour; 0 in a row of one or two points, which
    has none)."""
    q = np.asarray(q, float)
    t = np.asarray(t, float)
    rows = np.asarray(rows)
    same = rows[1:] == rows[:-1]
    h = np.diff(t)
    shape = (-1,) + (1,) * (q.ndim - 1)
    seg = np.flatnonzero(same)
    seg_vel = (q[seg + 1] - q[seg]) / h[seg].reshape(shape)
    mid = np.flatnonzero(same[:-1] & same[1:]) + 1  # i with i-1, i, i+1 in one row
    hl, hr = h[mid - 1].reshape(shape), h[mid].reshape(shape)
    vl, vr = (q[mid] - q[mid - 1]) / hl, (q[mid + 1] - q[mid]) / hr
    sec = 2 * (vr - vl) / (hl + hr)
    vel = np.zeros_like(q)
    vel[mid] = (hl * vr + hr * vl) / (hl + hr)  # np.gradient's second-order interior formula
    start = np.flatnonzero(np.r_[True, ~same])
    end = np.flatnonzero(np.r_[~same, True])
    size = end - start + 1
    s2, e2 = start[size >= 2], end[size >= 2]  # a one-point row stands still; a two-point row has no curvature
    vel[s2] = (q[s2 + 1] - q[s2]) / h[s2].reshape(shape)
    vel[e2] = (q[e2] - q[e2 - 1]) / h[e2 - 1].reshape(shape)
    acc = np.zeros_like(q)
    acc[mid] = sec
    s3, e3 = start[size >= 3], end[size >= 3]
    acc[s3] = acc[s3 + 1]
    acc[e3] = acc[e3 - 1]
    return ProgramRates(seg_vel, seg, sec, mid, vel, acc)


def limit_violations(limits: Mapping[str, Any], joints: Mapping[str, np.ndarray], t: np.ndarray, rows: np.ndarray,
                     resolution: Mapping[str, float] | None = None) -> tuple[dict[str, int], dict[str, float]]:
    """Samples of a program outside each axis's limits under the time law t (s), and the peaks.

    joints: axis name -> position per point (X, Y, Z mm; A, B rad; machine axes), in program
    order; limits: name -> AxisLimits (min, max, vmax, amax in the same units; axes without
    limits get peaks only). Counted per axis: positions outside [min, max], segment velocities
    over vmax, three-point second differences over amax (``program_rates``; 1e-9 relative slack).
    resolution: name -> e, the half unit of the last decimal the positions are written with (mm,
    rad; camsmooth.smoothing.evaluate): a sample then counts only beyond what rounding the
    positions by e can change it (travel + e, segment velocity + 2e/h, second difference +
    4e/(h_l h_r)) and the relative slack is 1e-6 (the 7 significant digits of a written F).
    Returns ({'<axis> travel|velocity|acceleration': count}, {'<axis> velocity|acceleration':
    largest |value|}, internal units). The one counter of the pipeline's metrics and ``analyze``."""
    viol: dict[str, int] = {}
    peaks: dict[str, float] = {}
    rel = 1e-6 if resolution else 1e-9
    for name, q in joints.items():
        rq = program_rates(q, t, rows)
        v, a = np.abs(rq.seg_vel), np.abs(rq.sec)
        peaks[f"{name} velocity"] = float(v.max(initial=0.0))
        peaks[f"{name} acceleration"] = float(a.max(initial=0.0))
        lim = limits.get(name)
        if lim is None:
            continue
        e = float(resolution.get(name, 0.0)) if resolution else 0.0
        slack_v = slack_a = 0.0
        if e > 0:
            h = np.diff(np.asarray(t, float))
            with np.errstate(divide="ignore"):
                slack_v = 2 * e / h[rq.seg]
                slack_a = 4 * e / (h[rq.mid - 1] * h[rq.mid])
        viol[f"{name} travel"] = int(np.sum((q < lim.min - 1e-9 - e) | (q > lim.max + 1e-9 + e)))
        viol[f"{name} velocity"] = int(np.sum(v > lim.vmax * (1 + rel) + slack_v))
        viol[f"{name} acceleration"] = int(np.sum(a > lim.amax * (1 + rel) + slack_a))
    return viol, peaks


def gamma(T: np.ndarray, t: np.ndarray) -> float:
    """Gamma = sum over interior points of |T''|^2 (1/s^4), METHODS section 1 step D."""
    if len(T) < 3:
        return 0.0
    _, D2 = fd_operators(t)
    return float(np.sum((D2 @ T) ** 2))


def spline_row(q1: np.ndarray, q2: np.ndarray, t: np.ndarray, step: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """The published method (METHODS section 1, step E(2)): sample the two rotary axes q1, q2 (rad,
    ``Machine.rotary`` order) every ``step``-th CC
    point (and the last), fit each with a not-a-knot cubic spline over time (scipy CubicSpline)
    and evaluate it at every CC point."""
    n = len(t)
    idx = np.unique(np.concatenate([np.arange(0, n, step), [n - 1]]))
    if len(idx) < 4:
        idx = np.unique(np.linspace(0, n - 1, min(n, 4)).round().astype(int))
    if len(idx) < 2:
        return q1.copy(), q2.copy()
    bc = "not-a-knot" if len(idx) >= 4 else "natural"
    return (CubicSpline(t[idx], q1[idx], bc_type=bc)(t), CubicSpline(t[idx], q2[idx], bc_type=bc)(t))


def _dm_sparse(M: sp.spmatrix) -> ca.DM:
    M = sp.csc_matrix(M)
    return ca.DM(ca.Sparsity(M.shape[0], M.shape[1], M.indptr.tolist(), M.indices.tolist()), M.data)


@dataclass
class NLPStatus:
    """What IPOPT said: success flag, return status text, iterations (summed over screening
    rounds), solve time (s), build time (s) of the solvers this solve needed, screening rounds,
    the number of constraint rows in the last round and in the whole NLP."""

    success: bool
    status: str
    iterations: int
    time_s: float
    build_s: float
    rounds: int = 1
    rows: int = 0
    total_rows: int = 0


# Constraint groups of one row, in the order of the NLP's g: segment velocities of the first (q1)
# and second (q2) rotary axis of ``Machine.rotary`` (N-1 each), second differences of q1 and q2
# (N-2 each), the lead window n.T and the two tilt half-planes (N each).
GROUPS = ("q1 velocity", "q2 velocity", "q1 acceleration", "q2 acceleration", "lead window", "tilt min", "tilt max",
          "clear floor", "clear ceiling")
N_LINEAR = 4  # the first groups are linear in (q1, q2); the rest are per-point functions of the tool axis


@dataclass(frozen=True)
class LeadBounds:
    """Clearance constraints of one row from the accessibility map: per point, lead >= floor and
    lead <= ceiling with floor, ceiling = c0 + c1 tilt + c2 tilt^2 (rad; (N, 3) coefficients), where
    has_floor / has_ceiling (N,) say so (camsmooth.geometry.accessibility.ClearRegion)."""

    floor: np.ndarray
    ceiling: np.ndarray
    has_floor: np.ndarray
    has_ceiling: np.ndarray

    @staticmethod
    def none(n: int) -> LeadBounds:
        z = np.zeros((n, 3))
        return LeadBounds(z, z, np.zeros(n, bool), np.zeros(n, bool))

# Constraint screening (an active-set outer loop around IPOPT; most of the 7N rows are slack at
# the optimum, and IPOPT's linear algebra pays for every row). The lead-window rows are always in
# the NLP: Gamma is invariant to rotations of the whole axis trajectory, and the lead rows are
# what pins it. Tilt rows within SCREEN_TILT_MARGIN of their bound at the start enter, and
# velocity and acceleration rows within SCREEN_MARGIN (a fraction of the limit) of their bound
# but not past it: rows the warm start violates are mostly its own roughness, which the NLP
# removes. After each solve, every row left out is checked; violated ones enter with
# SCREEN_DILATE neighbours on each side and the NLP is solved again from the warm start (IPOPT
# restarts badly from a point that violates the new rows). The loop ends when no row left out is
# violated, so the result is a KKT point of the whole NLP; if it has not ended after SCREEN_ROUNDS
# rounds, or a round fails, the row is solved with every constraint.
SCREEN_MARGIN = 0.1
SCREEN_TILT_MARGIN = np.radians(3.0)
SCREEN_DILATE = 4
SCREEN_ROUNDS = 8
# Rows shorter than this are solved whole: measured on the saddle sample (200-point rows whose
# tilt drifts to the window), screening took 3 rounds and 0.10 s a row against 0.045 s whole.
SCREEN_MIN_POINTS = 1000


def _symbols(machine: Machine, n: int) -> tuple[ca.MX, ca.MX]:
    """The CasADi MX columns (n x 1, rad) of the machine's two rotary axes, ``Machine.rotary``
    order, named by axis ("q_A", "q_C" on an A/C table)."""
    r1, r2 = machine.rotary
    return ca.MX.sym(f"q_{r1}", n), ca.MX.sym(f"q_{r2}", n)


def _axis_functions(machine: Machine, n: int) -> tuple[ca.Function, ca.Function, ca.Function]:
    """The tool axis T(q1, q2) (n x 3, workpiece frame) of n poses from the machine's POE chain,
    evaluated element-wise on CasADi MX columns, with its first and second partial derivatives
    (forward AD along a seed of ones: T_i depends on q1_i, q2_i only). Returns three functions of
    (q1, q2) (rad, n x 1 each, ``Machine.rotary`` order): T; (T, T_1, T_2); (T, T_1, T_2, T_11,
    T_12, T_22)."""
    a, b = _symbols(machine, n)
    comps = machine.tool_axis(a, b)
    T = ca.horzcat(*[c if isinstance(c, ca.MX) else ca.MX(ca.DM.ones(n) * float(c)) for c in comps])
    one = ca.DM.ones(n)
    Ta, Tb = ca.jtimes(T, a, one), ca.jtimes(T, b, one)
    Taa, Tab, Tbb = ca.jtimes(Ta, a, one), ca.jtimes(Ta, b, one), ca.jtimes(Tb, b, one)
    names = [a.name(), b.name()]
    return (ca.Function("axis", [a, b], [T], names, ["T"]),
            ca.Function("axis_d1", [a, b], [T, Ta, Tb], names, ["T", "T_1", "T_2"]),
            ca.Function("axis_d2", [a, b], [T, Ta, Tb, Taa, Tab, Tbb], names,
                        ["T", "T_1", "T_2", "T_11", "T_12", "T_22"]))


def _lead_functions(machine: Machine, n: int) -> ca.Function:
    """lead(T) - c0 - c1 tilt(T) - c2 tilt(T)^2 per point and its first and second partials in q1
    and q2 (element-wise forward AD, as ``_axis_functions``), for axes T(q1, q2) of the machine's
    chain and local frames X_L, Y_L, n (n x 3 each); lead = atan2(|(x, y)|, z), tilt = atan2(y, x)
    in the local frame (rad). Inputs (q1, q2, X, Y, Z, C) with C the (n x 3) coefficients; outputs
    (g, g_1, g_2, g_11, g_12, g_22)."""
    a, b = _symbols(machine, n)
    X, Y, Z, C = (ca.MX.sym(k, n, 3) for k in "XYZC")
    comps = machine.tool_axis(a, b)
    T = ca.horzcat(*[c if isinstance(c, ca.MX) else ca.MX(ca.DM.ones(n) * float(c)) for c in comps])
    x, y, z = ca.sum2(X * T), ca.sum2(Y * T), ca.sum2(Z * T)
    tilt = ca.atan2(y, x)
    lead = ca.atan2(ca.sqrt(x ** 2 + y ** 2 + 1e-24), z)
    g = lead - C[:, 0] - C[:, 1] * tilt - C[:, 2] * tilt ** 2
    one = ca.DM.ones(n)
    ga, gb = ca.jtimes(g, a, one), ca.jtimes(g, b, one)
    return ca.Function("lead_bound", [a, b, X, Y, Z, C],
                       [g, ga, gb, ca.jtimes(ga, a, one), ca.jtimes(ga, b, one), ca.jtimes(gb, b, one)],
                       [a.name(), b.name(), "X_L", "Y_L", "n", "coef"], ["g", "g_1", "g_2", "g_11", "g_12", "g_22"])


def _psd_part(a: ca.MX, b: ca.MX, c: ca.MX) -> tuple[ca.MX, ca.MX, ca.MX]:
    """The positive semidefinite part of the symmetric 2x2 matrices [[a, b], [b, c]] (element-wise
    over vectors): eigenvalues clipped at zero, in closed form."""
    m, d = 0.5 * (a + c), 0.5 * (a - c)
    r = ca.sqrt(d ** 2 + b ** 2 + 1e-300)
    lp, lm = ca.fmax(m + r, 0), ca.fmax(m - r, 0)
    # C+ = lp P+ + lm P-, P+ = (C - (m - r) I) / 2r, P- = ((m + r) I - C) / 2r, written with
    # d = a - m so that a multiple of the identity (r -> 0) keeps its half-and-half split
    kp, km = lp / (2 * r), lm / (2 * r)
    return kp * (r + d) + km * (r - d), (kp - km) * b, kp * (r - d) + km * (r + d)


def _dilate(mask: np.ndarray, sizes: Sequence[int], k: int) -> np.ndarray:
    """``mask`` grown by k rows on each side within each group of rows (group lengths sizes)."""
    parts = np.split(mask, np.cumsum(sizes)[:-1])
    return np.concatenate([binary_dilation(m, np.ones(2 * k + 1, bool)) if m.any() else m for m in parts])


def _sparse_mx(nrow: int, ncol: int, rows: np.ndarray, cols: np.ndarray, vals: ca.MX) -> ca.MX:
    """An MX sparse matrix from triplets (numpy rows and cols, MX values in the same order)."""
    order = np.lexsort((rows, cols))
    colind = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=ncol))])
    sp_ = ca.Sparsity(nrow, ncol, colind.tolist(), rows[order].tolist())
    return ca.MX(sp_, vals[order.tolist()])


class RowNLP:
    """The smoothing NLP of one row length N (module docstring), solved by CasADi + IPOPT.

    The problem is banded, and its derivatives are written from that structure rather than left
    to CasADi's generic sparsity detection (which took 8.5 s to build a 10k-point row): the tool
    axis and its partial derivatives come from the machine's POE chain element-wise over the row
    (MX columns, forward AD), the objective gradient is J^T r through the second-difference
    stencil, the Jacobian is assembled from the stencils, and the Hessian of the Lagrangian is
    the Gauss-Newton part (bandwidth two points) plus the block-diagonal curvature of T weighted
    by the residuals (exact) and by the window multipliers (its positive semidefinite part; see
    ``_solver``). Building costs milliseconds and every evaluation is a handful of vector
    operations, so cost grows linearly with N.

    Rows of SCREEN_MIN_POINTS points or more are solved with constraint screening (the comment
    at SCREEN_MARGIN); ``screening`` forces it on or off.

    machine: kinematics (nominal or with an error model applied: the axis T is whatever its POE
    chain gives). Time steps, local frames, windows and the objective scale are parameters, so
    the interference loop re-solves without rebuilding.
    """

    def __init__(self, machine: Machine, n: int, *, ipopt_options: dict | None = None,
                 screening: bool | None = None, backoff: float = BACKOFF) -> None:
        t0 = time.perf_counter()
        if n < 3:
            raise InfeasibleError(f"a row needs at least 3 points to smooth, got {n}")
        self.machine, self.n, self.backoff = machine, n, float(backoff)
        self.screening = n >= SCREEN_MIN_POINTS if screening is None else screening
        # tol 1e-8: IPOPT's tolerance applies to Gamma scaled by the warm start's, and at 1e-6 it
        # stopped far above the optimum on gentle rows (a 10k-point row: Gamma 1.8e-4 against
        # 4.6e-9, the warm start's being 70); on the samples it changes nothing in six digits and
        # costs at most 40% more iterations (saddle).
        self.options = {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.max_iter": 500,
                        "ipopt.tol": 1e-8, "ipopt.acceptable_tol": 1e-4, "ipopt.mu_strategy": "adaptive",
                        "ipopt.constr_viol_tol": 1e-10, "ipopt.acceptable_constr_viol_tol": 1e-9,
                        "ipopt.linear_solver": "mumps", "ipopt.mumps_mem_percent": 5}
        self.options.update(ipopt_options or {})
        self.sizes = (n - 1, n - 1, n - 2, n - 2, n, n, n, n, n)
        axis0, axis1, axis2 = _axis_functions(machine, n)
        bound = _lead_functions(machine, n)
        m1, m2 = n - 1, n - 2
        # parameters: 1/h (n-1), second-difference weights c0, c1, c2 (n-2 each), window
        # coefficient vectors (normal, tilt-min and tilt-max rows; 3n each), objective scale,
        # the local frames' X_L and Y_L (3n each), floor and ceiling coefficients (3n each).
        x = ca.MX.sym("x", 2 * n)
        p = ca.MX.sym("p", m1 + 3 * m2 + 9 * n + 1 + 12 * n)
        self._x, self._p = x, p
        q1, q2 = x[0::2], x[1::2]
        invh = p[0:m1]
        c0, c1, c2 = (p[m1 + k * m2:m1 + (k + 1) * m2] for k in range(3))
        off = m1 + 3 * m2
        W = [ca.reshape(p[off + 3 * k * n:off + 3 * (k + 1) * n], n, 3) for k in range(3)]
        scale = p[off + 9 * n]
        XL, YL, CF, CC = (ca.reshape(p[off + 9 * n + 1 + 3 * k * n:off + 9 * n + 1 + 3 * (k + 1) * n], n, 3)
                          for k in range(4))
        floor = bound(q1, q2, XL, YL, W[0], CF)
        ceiling = bound(q1, q2, XL, YL, W[0], CC)

        def stencil(q: ca.MX) -> ca.MX:  # second differences of the rows of q
            cols = q.shape[1]
            return (ca.repmat(c0, 1, cols) * q[0:m2, :] + ca.repmat(c1, 1, cols) * q[1:m2 + 1, :]
                    + ca.repmat(c2, 1, cols) * q[2:n, :])

        def groups(T: ca.MX) -> list[ca.MX]:
            return [(q1[1:n] - q1[0:m1]) * invh, (q2[1:n] - q2[0:m1]) * invh, stencil(q1), stencil(q2),
                    ca.sum2(W[0] * T), ca.sum2(W[1] * T), ca.sum2(W[2] * T), floor[0], ceiling[0]]

        T0 = axis0(q1, q2)
        self._f = scale * ca.sumsqr(stencil(T0))
        self._g_groups = groups(T0)
        self.g_all = ca.Function("g_all", [x, p], [ca.vertcat(*self._g_groups)])

        # first derivatives
        T1, Ta1, Tb1 = axis1(q1, q2)
        r1 = stencil(T1)
        z2 = ca.MX.zeros(2, 3)

        def adjoint(r: ca.MX) -> ca.MX:  # D2^T r, row by row (n x 3)
            c = lambda v: ca.repmat(v, 1, 3)  # noqa: E731
            return (ca.vertcat(c(c0) * r, z2) + ca.vertcat(ca.MX.zeros(1, 3), c(c1) * r, ca.MX.zeros(1, 3))
                    + ca.vertcat(z2, c(c2) * r))

        u1 = adjoint(r1)
        grad = 2 * scale * ca.reshape(ca.horzcat(ca.sum2(u1 * Ta1), ca.sum2(u1 * Tb1)).T, 2 * n, 1)
        self._grad_f = ca.Function("grad_f", [x, p], [scale * ca.sumsqr(r1), grad])
        self._g1 = groups(T1)
        self._jac_parts = {"invh": invh, "c": (c0, c1, c2),
                           "win": [(ca.sum2(Wk * Ta1), ca.sum2(Wk * Tb1)) for Wk in W]
                           + [(floor[1], floor[2]), (ceiling[1], ceiling[2])]}
        self._bound_curv = (floor[3:6], ceiling[3:6])

        # second derivatives: kept as pieces; the window multipliers are scattered per solver
        T2, Ta, Tb, Taa, Tab, Tbb = axis2(q1, q2)
        u2 = adjoint(stencil(T2))
        d0 = ca.vertcat(c0 ** 2, 0, 0) + ca.vertcat(0, c1 ** 2, 0) + ca.vertcat(0, 0, c2 ** 2)
        e1 = ca.vertcat(c0 * c1, 0) + ca.vertcat(0, c1 * c2)
        e2 = c0 * c2
        dot = lambda P, Q: ca.sum2(P * Q)  # noqa: E731
        self._hess_parts = (scale, u2, W, (Taa, Tab, Tbb),
                            [d0 * dot(Ta, Ta), d0 * dot(Ta, Tb), d0 * dot(Tb, Tb)],
                            [e1 * dot(Ta[0:m1, :], Ta[1:n, :]), e1 * dot(Ta[0:m1, :], Tb[1:n, :]),
                             e1 * dot(Tb[0:m1, :], Ta[1:n, :]), e1 * dot(Tb[0:m1, :], Tb[1:n, :])],
                            [e2 * dot(Ta[0:m2, :], Ta[2:n, :]), e2 * dot(Ta[0:m2, :], Tb[2:n, :]),
                             e2 * dot(Tb[0:m2, :], Ta[2:n, :]), e2 * dot(Tb[0:m2, :], Tb[2:n, :])])
        k0, k1, k2 = np.arange(n), np.arange(m1), np.arange(m2)
        self._hess_rows = np.concatenate([2 * k0, 2 * k0, 2 * k0 + 1, 2 * k1, 2 * k1, 2 * k1 + 1, 2 * k1 + 1,
                                          2 * k2, 2 * k2, 2 * k2 + 1, 2 * k2 + 1])
        self._hess_cols = np.concatenate([2 * k0, 2 * k0 + 1, 2 * k0 + 1, 2 * k1 + 2, 2 * k1 + 3, 2 * k1 + 2,
                                          2 * k1 + 3, 2 * k2 + 4, 2 * k2 + 5, 2 * k2 + 4, 2 * k2 + 5])
        self._solvers: dict[bytes, tuple[ca.Function, float]] = {}
        self.build_s = time.perf_counter() - t0

    # ---- one solver per set of constraint rows ------------------------------------------------
    def _solver(self, rows: list[np.ndarray]) -> tuple[ca.Function, float]:
        """IPOPT on the rows ``rows`` (row indices per group of GROUPS); cached."""
        key = b"|".join(np.asarray(r, np.int64).tobytes() for r in rows)
        if key in self._solvers:
            return self._solvers[key][0], 0.0
        t0 = time.perf_counter()
        n, x, p = self.n, self._x, self._p
        sel = [k.tolist() for k in rows]
        m = sum(len(k) for k in rows)
        g = ca.vertcat(*[grp[k] for grp, k in zip(self._g_groups, sel, strict=True)]) if m else ca.MX(0, 1)
        # Jacobian from the stencils
        R, C, V = [], [], []
        r0 = 0
        invh, (c0, c1, c2) = self._jac_parts["invh"], self._jac_parts["c"]
        for gi, k in enumerate(rows):
            k = np.asarray(k, np.int64)
            r = r0 + np.arange(len(k))
            r0 += len(k)
            if not len(k):
                continue
            kl = k.tolist()
            if gi < 2:
                R += [r, r]
                C += [2 * k + gi, 2 * k + 2 + gi]
                V += [-invh[kl], invh[kl]]
            elif gi < 4:
                R += [r, r, r]
                C += [2 * k + gi - 2, 2 * k + gi, 2 * k + gi + 2]
                V += [c0[kl], c1[kl], c2[kl]]
            else:
                dA, dB = self._jac_parts["win"][gi - N_LINEAR]
                R += [r, r]
                C += [2 * k, 2 * k + 1]
                V += [dA[kl], dB[kl]]
        if m:
            J = _sparse_mx(m, 2 * n, np.concatenate(R), np.concatenate(C), ca.vertcat(*V))
        else:
            J = ca.MX(0, 2 * n)
        g1 = ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=True)]) if m else ca.MX(0, 1)
        jac_g = ca.Function("jac_g", [x, p], [g1, J])
        # Hessian of the Lagrangian lam_f f + lam_g' g (upper triangle)
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", m)
        scale, u, W, (Taa, Tab, Tbb), diag, off1, off2 = self._hess_parts
        wo = 2 * scale * lam_f * u
        wc = ca.MX.zeros(n, 3)
        starts = np.cumsum([0] + [len(k) for k in rows])
        bc = [ca.MX.zeros(n, 1) for _ in range(3)]  # curvature of the clearance rows, weighted
        for gi in range(N_LINEAR, len(GROUPS)):
            k = np.asarray(rows[gi], np.int64)
            if len(k):
                P = sp.csc_matrix((np.ones(len(k)), (k, np.arange(len(k)))), shape=(n, len(k)))
                lam = ca.mtimes(_dm_sparse(P), lam_g[int(starts[gi]):int(starts[gi + 1])])
                if gi < 7:
                    wc = wc + ca.repmat(lam, 1, 3) * W[gi - N_LINEAR]
                else:
                    bc = [acc + lam * h for acc, h in zip(bc, self._bound_curv[gi - 7], strict=True)]
        S = 2 * scale * lam_f
        # objective curvature exact; constraint curvature (window and clearance rows, weighted by
        # their multipliers) replaced by its positive semidefinite part, point by point. Measured:
        # the exact form makes IPOPT correct the inertia at nearly every iteration (several
        # factorizations each) on rough rows, clipping the objective's curvature too slows gentle
        # rows (saddle sample) down to hundreds of iterations; this split does neither.
        blocks = lambda w: (ca.sum2(w * Taa), ca.sum2(w * Tab), ca.sum2(w * Tbb))  # noqa: E731
        curv = [w + h for w, h in zip(blocks(wc), bc, strict=True)]
        a, b, c = (p_ + q_ for p_, q_ in zip(blocks(wo), _psd_part(*curv), strict=True))
        vals = ca.vertcat(a + S * diag[0], b + S * diag[1],
                          c + S * diag[2], *[S * v for v in off1], *[S * v for v in off2])
        H = _sparse_mx(2 * n, 2 * n, self._hess_rows, self._hess_cols, vals)
        hess = ca.Function("hess_lag", [x, p, lam_f, lam_g], [H])
        opts = dict(self.options, grad_f=self._grad_f, jac_g=jac_g, hess_lag=hess)
        solver = ca.nlpsol("smooth_row", "ipopt", {"x": x, "p": p, "f": self._f, "g": g}, opts)
        dt = time.perf_counter() - t0
        if len(self._solvers) >= 16:
            self._solvers.pop(next(iter(self._solvers)))
        self._solvers[key] = (solver, dt)
        return solver, dt

    # ---- parameters and bounds ------------------------------------------------------------------
    def _params(self, t: np.ndarray, frames: np.ndarray, tilt_window: np.ndarray, scale: float,
                bounds: LeadBounds) -> np.ndarray:
        h = np.diff(t)
        hl, hr = h[:-1], h[1:]
        X, Y, Z = frames[:, :, 0], frames[:, :, 1], frames[:, :, 2]
        tw = narrowed(tilt_window)
        tmin, tmax = tw[:, 0:1], tw[:, 1:2]
        cmin = Y * np.cos(tmin) - X * np.sin(tmin)
        cmax = X * np.sin(tmax) - Y * np.cos(tmax)
        return np.concatenate([1 / h, 2 / (hl * (hl + hr)), -2 / (hl * hr), 2 / (hr * (hl + hr)),
                               Z.T.ravel(), cmin.T.ravel(), cmax.T.ravel(), [scale], X.T.ravel(), Y.T.ravel(),
                               np.asarray(bounds.floor, float).T.ravel(), np.asarray(bounds.ceiling, float).T.ravel()])

    def bounds(self, lead_window: np.ndarray) -> tuple[np.ndarray, ...]:
        """lbx, ubx, lbg, ubg (every row of GROUPS) for the current windows: ``enforced_limits``
        with the fraction ``backoff`` (BACKOFF by default) and the ``narrowed`` windows."""
        n = self.n
        la, lb = (enforced_limits(self.machine, self.backoff)[k] for k in self.machine.rotary)
        lbx = np.empty(2 * n)
        ubx = np.empty(2 * n)
        lbx[0::2], ubx[0::2], lbx[1::2], ubx[1::2] = la.min, la.max, lb.min, lb.max
        lo_l, hi_l = narrowed(lead_window).T
        lbg = np.concatenate([np.full(n - 1, -la.vmax), np.full(n - 1, -lb.vmax),
                              np.full(n - 2, -la.amax), np.full(n - 2, -lb.amax),
                              np.cos(hi_l), np.zeros(n), np.zeros(n), np.full(n, WINDOW_BACKOFF), np.full(n, -np.inf)])
        ubg = np.concatenate([np.full(n - 1, la.vmax), np.full(n - 1, lb.vmax),
                              np.full(n - 2, la.amax), np.full(n - 2, lb.amax),
                              np.cos(lo_l), np.full(n, np.inf), np.full(n, np.inf), np.full(n, np.inf),
                              np.full(n, -WINDOW_BACKOFF)])
        return lbx, ubx, lbg, ubg

    def _split(self, v: np.ndarray) -> list[np.ndarray]:
        return np.split(v, np.cumsum(self.sizes)[:-1])

    def _near(self, g: np.ndarray, lbg: np.ndarray, ubg: np.ndarray) -> np.ndarray:
        """Rows within the screening margin of a bound, or past it: velocity and acceleration
        rows within SCREEN_MARGIN of the limit, tilt rows within SCREEN_TILT_MARGIN (rad; a tilt
        row's value is sin(tilt - bound) times sin(lead))."""
        la, lb = self.machine.rotary_limits()
        gl = self._split(g)[4]
        rho = np.maximum(np.sqrt(np.clip(1 - gl ** 2, 0, 1)), np.sin(np.radians(0.5)))
        scale = np.concatenate([np.full(self.sizes[0], la.vmax * SCREEN_MARGIN),
                                np.full(self.sizes[1], lb.vmax * SCREEN_MARGIN),
                                np.full(self.sizes[2], la.amax * SCREEN_MARGIN),
                                np.full(self.sizes[3], lb.amax * SCREEN_MARGIN),
                                np.full(self.sizes[4], np.inf), rho * SCREEN_TILT_MARGIN, rho * SCREEN_TILT_MARGIN,
                                np.full(2 * self.n, np.inf)])
        with np.errstate(invalid="ignore"):
            return np.minimum(g - lbg, ubg - g) < scale

    def _row_ends(self) -> np.ndarray:
        """Velocity and acceleration rows of the first and last SCREEN_DILATE + 1 points: a row's
        free ends swing as far as the limits let them, so their rows are always in."""
        out = []
        for gi, m in enumerate(self.sizes):
            e = np.zeros(m, bool)
            if gi < 4:
                e[:SCREEN_DILATE + 1] = e[-SCREEN_DILATE - 1:] = True
            out.append(e)
        return np.concatenate(out)

    # ---- solve ----------------------------------------------------------------------------------
    def solve(self, t: np.ndarray, frames: np.ndarray, start: RotaryValues, lead_window: np.ndarray,
              tilt_window: np.ndarray, bounds: LeadBounds | None = None) -> tuple[RotaryValues, NLPStatus]:
        """Solve one row: time stamps t (N,) s, local frames (N, 3, 3) (columns X_L, Y_L, n in
        the workpiece frame), the warm start ``start`` (the machine's rotary axes, rad, named by
        them), lead/tilt windows (N, 2) rad, clearance bounds on the lead from the accessibility
        map (rows only where they apply). Returns the solution on the same axes (rad) and the
        status."""
        q1_0, q2_0 = start.pair
        n = self.n
        bounds = LeadBounds.none(n) if bounds is None else bounds
        exists = np.concatenate([np.ones(sum(self.sizes[:7]), bool), np.asarray(bounds.has_floor, bool),
                                 np.asarray(bounds.has_ceiling, bool)])
        t = np.asarray(t, float)
        x = np.empty(2 * n)
        x[0::2], x[1::2] = q1_0, q2_0
        scale = 1.0 / max(gamma(self.machine.tool_axis_np(q1_0, q2_0), t), 1e-6)
        lbx, ubx, lbg, ubg = self.bounds(lead_window)
        x = np.clip(x, lbx, ubx)
        t0 = time.perf_counter()
        p = self._params(t, frames, tilt_window, scale, bounds)
        x_start = x.copy()
        if self.screening:
            g = np.asarray(self.g_all(x, p)).ravel()
            outside = (g < lbg) | (g > ubg)
            # the lead and clearance rows are always in: they pin the trajectory
            keep = exists & (np.repeat([False] * 4 + [True] + [False] * 2 + [True] * 2, self.sizes)
                             | self._row_ends() | (self._near(g, lbg, ubg) & ~outside))
        else:
            keep = exists.copy()
        build = iters = rounds = 0
        status, success = "not solved", False
        while True:
            rounds += 1
            solver, b = self._solver([np.flatnonzero(k) for k in self._split(keep)])
            build += b
            sol = solver(x0=x, p=p, lbx=lbx, ubx=ubx, lbg=lbg[keep], ubg=ubg[keep])
            st = solver.stats()
            iters += int(st.get("iter_count", 0))
            status, success = str(st["return_status"]), bool(st["success"])
            x = np.asarray(sol["x"]).ravel()
            if not (exists & ~keep).any():
                break
            bad = np.zeros_like(keep)
            if success:
                g = np.asarray(self.g_all(x, p)).ravel()
                bad = ((g < lbg - 1e-9) | (g > ubg + 1e-9)) & ~keep & exists
                if not bad.any():
                    break
            if not success or rounds >= SCREEN_ROUNDS:
                # screening did not work out for this row: every row, from the original start
                keep = exists.copy()
                x = x_start.copy()
                continue
            keep |= (_dilate(bad, self.sizes, SCREEN_DILATE) | self._near(g, lbg, ubg)) & exists
            x = x_start.copy()  # IPOPT restarts badly from a point that violates the new rows
        if not success:
            # IPOPT can fail numerically (e.g. Error_In_Step_Computation on a row whose warm start is
            # already optimal, Gamma = 0 on a plane): a point that meets every row is a program, so
            # the better of the last iterate and the warm start is taken when one of them does
            x, status, success = self._feasible_fallback(x, x_start, p, lbx, ubx, lbg, ubg, exists, t, status)
        dt = time.perf_counter() - t0
        return RotaryValues.of(start.names, x[0::2], x[1::2]), NLPStatus(
            success=success, status=status, iterations=iters, time_s=dt, build_s=build, rounds=rounds,
            rows=int(keep.sum()), total_rows=int(exists.sum()))

    def _feasible_fallback(self, x: np.ndarray, x0: np.ndarray, p: np.ndarray, lbx: np.ndarray, ubx: np.ndarray,
                           lbg: np.ndarray, ubg: np.ndarray, exists: np.ndarray, t: np.ndarray,
                           status: str) -> tuple[np.ndarray, str, bool]:
        best = None
        for cand in (x, x0):
            if not (np.all(np.isfinite(cand)) and np.all(cand >= lbx - 1e-12) and np.all(cand <= ubx + 1e-12)):
                continue
            g = np.asarray(self.g_all(cand, p)).ravel()
            if not np.all(((g >= lbg - 1e-9) & (g <= ubg + 1e-9)) | ~exists):
                continue
            gam = gamma(self.machine.tool_axis_np(cand[0::2], cand[1::2]), t)
            if best is None or gam < best[1]:
                best = (cand, gam)
        if best is None:
            return x, status, False
        return best[0], f"{status}; a feasible point kept", True

    def constraint_report(self, t: np.ndarray, qs: RotaryValues) -> list[tuple[str, int, float]]:
        """Constraint groups violated by the rotary axes ``qs`` (rad) against the TRUE limits (no back-off): a list of
        (constraint name, point index, amount in the constraint's units, rad-based)."""
        out: list[tuple[str, int, float]] = []
        lim = self.machine.limits
        D1, D2 = fd_operators(t)
        for name in self.machine.rotary:
            L = lim[name]
            q = qs[name]
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


@dataclass(frozen=True)
class Binding:
    """What an elastic re-solve found binds on a row: the constraint ('A travel', 'B velocity',
    ...), the point index, the value the windows need there, the machine's limit and the limit the
    NLP enforces (the machine's backed off by ``backoff``, RowNLP.bounds), in ``unit`` (deg, deg/s
    or deg/s^2; travel angles in the machine's sign convention); ``lower`` when the limit is a
    lower bound (the travel's min). ``binds`` says whether the need is past the enforced limit (by
    more than 1e-6 of it); ``past_machine_limit`` whether it is past the machine's own."""

    constraint: str
    point: int
    need: float
    limit: float
    unit: str
    lower: bool = False
    enforced: float | None = None

    def _past(self, bound: float) -> bool:
        tol = 1e-6 * abs(bound)
        return self.need < bound - tol if self.lower else self.need > bound + tol

    @property
    def binds(self) -> bool:
        return self._past(self.limit if self.enforced is None else self.enforced)

    @property
    def past_machine_limit(self) -> bool:
        return self._past(self.limit)


def elastic_diagnosis(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_window: np.ndarray,
                      tilt_window: np.ndarray, start: RotaryValues, backoff: float = BACKOFF) -> Binding:
    """Name the binding constraint of an infeasible row: re-solve with every limit group made
    elastic (non-negative slacks on the travel of both rotary axes, as a fraction of their span, and on the
    velocity and acceleration limits, as a fraction of the limit) and minimise the sum of slacks;
    the largest slack names the constraint, the point and what it would need. The limits and
    windows are the ones RowNLP enforces (backed off by ``backoff`` and WINDOW_BACKOFF), so a row
    that fits the machine only without that margin is named too. ``start``: the warm start (the
    machine's rotary axes, rad). Angles rad, times s."""
    q1_0, q2_0 = start.pair
    n = len(t)
    D1, D2 = fd_operators(t)
    lim = enforced_limits(machine, backoff)
    lead_window, tilt_window = narrowed(lead_window), narrowed(tilt_window)
    x = ca.SX.sym("x", 2 * n)  # q1_0, q2_0, q1_1, ... (Machine.rotary order)
    q1, q2 = x[0::2], x[1::2]
    Tx, Ty, Tz = machine.tool_axis(q1, q2)
    s = ca.SX.sym("s", 6)  # q1, q2 vel, q1, q2 acc (fraction of the limit), q1, q2 travel (of the span)
    d1, d2 = _dm_sparse(D1), _dm_sparse(D2)
    X, Y, Z = frames[:, :, 0], frames[:, :, 1], frames[:, :, 2]
    tmin, tmax = tilt_window[:, 0:1], tilt_window[:, 1:2]
    cmin = Y * np.cos(tmin) - X * np.sin(tmin)
    cmax = X * np.sin(tmax) - Y * np.cos(tmax)
    dotc = lambda C: C[:, 0] * Tx + C[:, 1] * Ty + C[:, 2] * Tz  # noqa: E731
    r1, r2 = machine.rotary
    L1, L2 = lim[r1], lim[r2]
    va, vb = ca.mtimes(d1, q1) / L1.vmax, ca.mtimes(d1, q2) / L2.vmax
    aa, ab = ca.mtimes(d2, q1) / L1.amax, ca.mtimes(d2, q2) / L2.amax

    def travel(q: ca.SX, L: AxisLimits) -> ca.SX:  # within +-1/2 inside the travel; 0 when continuous
        w = L.max - L.min
        return (q - 0.5 * (L.max + L.min)) / w if np.isfinite(w) else 0 * q

    ta, tb = travel(q1, L1), travel(q2, L2)
    g = ca.vertcat(va - s[0], va + s[0], vb - s[1], vb + s[1], aa - s[2], aa + s[2], ab - s[3], ab + s[3],
                   ta - s[4], ta + s[4], tb - s[5], tb + s[5], dotc(Z), dotc(cmin), dotc(cmax))
    m1, m2 = n - 1, n - 2
    inf = np.inf
    lo = lambda k, v: np.full(k, v)  # noqa: E731
    lbg = np.concatenate([lo(m1, -inf), lo(m1, -1), lo(m1, -inf), lo(m1, -1), lo(m2, -inf), lo(m2, -1),
                          lo(m2, -inf), lo(m2, -1), lo(n, -inf), lo(n, -0.5), lo(n, -inf), lo(n, -0.5),
                          np.cos(lead_window[:, 1]), np.zeros(n), np.zeros(n)])
    ubg = np.concatenate([lo(m1, 1), lo(m1, inf), lo(m1, 1), lo(m1, inf), lo(m2, 1), lo(m2, inf), lo(m2, 1),
                          lo(m2, inf), lo(n, 0.5), lo(n, inf), lo(n, 0.5), lo(n, inf),
                          np.cos(lead_window[:, 0]), np.full(n, inf), np.full(n, inf)])
    lbx = np.concatenate([np.full(2 * n, -inf), np.zeros(6)])
    ubx = np.full(2 * n + 6, inf)
    solver = ca.nlpsol("elastic", "ipopt", {"x": ca.vertcat(x, s), "f": ca.sum1(s), "g": g},
                       {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.max_iter": 1000})
    x0 = np.concatenate([np.ravel(np.column_stack([q1_0, q2_0])), np.full(6, 10.0)])
    sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    xs = np.asarray(sol["x"]).ravel()
    slack = xs[2 * n:]
    k = int(np.argmax(slack))
    q1_opt, q2_opt = xs[0:2 * n:2], xs[1:2 * n:2]
    names = (f"{r1} velocity", f"{r2} velocity", f"{r1} acceleration", f"{r2} acceleration", f"{r1} travel",
             f"{r2} travel")
    axis = names[k].split()[0]
    q = q1_opt if axis == r1 else q2_opt
    L, M = lim[axis], machine.limits[axis]
    if k >= 4:  # travel: the point furthest outside, and the angle it needs
        over = np.maximum(q - L.max, L.min - q)
        i = int(np.argmax(over))
        lower = bool(q[i] < L.min)
        return Binding(names[k], i, float(np.degrees(q[i])), float(np.degrees(M.min if lower else M.max)), "deg",
                       lower=lower, enforced=float(np.degrees(L.min if lower else L.max)))
    vals = np.abs(D1 @ q) if k < 2 else np.abs(D2 @ q)
    i = int(np.argmax(vals)) + (0 if k < 2 else 1)
    return Binding(names[k], i, float(np.degrees(vals.max())), float(np.degrees(M.vmax if k < 2 else M.amax)),
                   "deg/s" if k < 2 else "deg/s^2", enforced=float(np.degrees(L.vmax if k < 2 else L.amax)))


@dataclass(frozen=True)
class ClearanceRelief:
    """What an elastic re-solve with soft clearance constraints found (``clearance_elastic``):
    ``feasible`` whether the limits and the windows alone admit a program (when not, the binding
    limit is ``elastic_diagnosis``'s to name); ``floor_short`` and ``ceiling_short`` (N,) rad, how
    far below its clear floor (above its ceiling) each point's lead had to stay; ``rotary`` that
    program (the machine's rotary axes, rad, named by them: a warm start that meets the limits and
    windows)."""

    feasible: bool
    floor_short: np.ndarray
    ceiling_short: np.ndarray
    rotary: RotaryValues


def clearance_elastic(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_window: np.ndarray,
                      tilt_window: np.ndarray, bounds: LeadBounds, start: RotaryValues,
                      backoff: float = BACKOFF, weights: tuple[np.ndarray, np.ndarray] | None = None
                      ) -> ClearanceRelief:
    """The row of RowNLP with its limits and windows hard (as enforced) and the accessibility
    map's floor and ceiling soft: minimise the sum of the per-point amounts (rad) by which the lead
    stays outside its clear region. Points with a positive amount are those the machine's limits
    keep out of their clear region. ``weights``: (floor, ceiling) per point (N,) weights of those
    amounts (default 1; a finish budget's ceiling weighs less than clearance, so the limits give
    up the finish before the clearance, camsmooth.smoothing.rows). ``start``: the warm start (the
    machine's rotary axes, rad). Angles rad, times s."""
    q1_0, q2_0 = start.pair
    n = len(t)
    D1, D2 = fd_operators(t)
    lim = enforced_limits(machine, backoff)
    lead_window, tilt_window = narrowed(lead_window), narrowed(tilt_window)
    fl, ce = np.flatnonzero(bounds.has_floor), np.flatnonzero(bounds.has_ceiling)
    x = ca.SX.sym("x", 2 * n)
    s = ca.SX.sym("s", len(fl) + len(ce))
    q1, q2 = x[0::2], x[1::2]
    Tx, Ty, Tz = machine.tool_axis(q1, q2)
    X, Y, Z = frames[:, :, 0], frames[:, :, 1], frames[:, :, 2]
    tmin, tmax = tilt_window[:, 0:1], tilt_window[:, 1:2]
    cmin = Y * np.cos(tmin) - X * np.sin(tmin)
    cmax = X * np.sin(tmax) - Y * np.cos(tmax)
    dotc = lambda C: C[:, 0] * Tx + C[:, 1] * Ty + C[:, 2] * Tz  # noqa: E731
    lx, ly, lz = dotc(X), dotc(Y), dotc(Z)
    tilt = ca.atan2(ly, lx)
    lead = ca.atan2(ca.sqrt(lx ** 2 + ly ** 2 + 1e-24), lz)
    poly = lambda c, k: c[k, 0] + c[k, 1] * tilt[k.tolist()] + c[k, 2] * tilt[k.tolist()] ** 2  # noqa: E731
    d1, d2 = _dm_sparse(D1), _dm_sparse(D2)
    g = ca.vertcat(ca.mtimes(d1, q1), ca.mtimes(d1, q2), ca.mtimes(d2, q1), ca.mtimes(d2, q2), lz, dotc(cmin),
                   dotc(cmax), lead[fl.tolist()] - poly(bounds.floor, fl) + s[:len(fl)],
                   poly(bounds.ceiling, ce) - lead[ce.tolist()] + s[len(fl):])
    m1, m2, inf = n - 1, n - 2, np.inf
    full = np.full
    L1, L2 = (lim[r] for r in machine.rotary)
    lbg = np.concatenate([full(m1, -L1.vmax), full(m1, -L2.vmax), full(m2, -L1.amax),
                          full(m2, -L2.amax), np.cos(lead_window[:, 1]), np.zeros(2 * n),
                          full(len(fl) + len(ce), WINDOW_BACKOFF)])
    ubg = np.concatenate([full(m1, L1.vmax), full(m1, L2.vmax), full(m2, L1.amax),
                          full(m2, L2.amax), np.cos(lead_window[:, 0]), full(2 * n, inf),
                          full(len(fl) + len(ce), inf)])
    lbx = np.concatenate([np.ravel(np.column_stack([full(n, L1.min), full(n, L2.min)])),
                          np.zeros(len(s.nz))])
    ubx = np.concatenate([np.ravel(np.column_stack([full(n, L1.max), full(n, L2.max)])),
                          full(len(s.nz), inf)])
    w = (np.ones(len(s.nz)) if weights is None
         else np.concatenate([np.asarray(weights[0], float)[fl], np.asarray(weights[1], float)[ce]]))
    solver = ca.nlpsol("clearance_elastic", "ipopt", {"x": ca.vertcat(x, s), "f": ca.dot(ca.DM(w), s), "g": g},
                       {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.max_iter": 1000,
                        "ipopt.tol": 1e-10, "ipopt.constr_viol_tol": 1e-10})
    x0 = np.concatenate([np.clip(np.ravel(np.column_stack([q1_0, q2_0])), lbx[:2 * n], ubx[:2 * n]),
                         full(len(s.nz), 0.1)])
    sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    xs = np.asarray(sol["x"]).ravel()
    gs = np.asarray(sol["g"]).ravel()
    ok = bool(np.all(np.isfinite(xs)) and np.all(gs[:-len(s.nz) or None] >= lbg[:len(gs) - len(s.nz)] - 1e-8)
              and np.all(gs[:len(gs) - len(s.nz)] <= ubg[:len(gs) - len(s.nz)] + 1e-8))
    floor_short, ceiling_short = np.zeros(n), np.zeros(n)
    floor_short[fl] = np.maximum(xs[2 * n:2 * n + len(fl)], 0.0)
    ceiling_short[ce] = np.maximum(xs[2 * n + len(fl):], 0.0)
    return ClearanceRelief(feasible=ok, floor_short=floor_short, ceiling_short=ceiling_short,
                           rotary=RotaryValues.of(start.names, xs[0:2 * n:2], xs[1:2 * n:2]))
