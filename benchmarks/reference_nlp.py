"""An independent reference for the smoothing NLP: the plain formulation, written here.

One row: variables A_i, B_i (rad) at every CC point; objective Gamma = sum over interior points
of |T''|^2 with T'' by second differences written out from the time stamps; constraints written
as angles (not the pipeline's half-planes and cosines): A, B within travel, velocities and
accelerations within the limits, lead = atan2(|(x, y)|, z) within the lead window, tilt =
atan2(y, x) within the tilt window, and where the accessibility map gives them lead >= floor(tilt)
and lead <= ceiling(tilt). CasADi builds the exact Hessian by automatic differentiation; IPOPT
solves from several starts and the best feasible solution is kept. Nothing of
camsmooth.smoothing.nlp (structured derivatives, screening, knots, convexified curvature) is used.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import casadi as ca
import numpy as np

from camsmooth.machine.kinematics import Machine


@dataclass(frozen=True)
class ReferenceRow:
    A: np.ndarray
    B: np.ndarray
    gamma: float
    start: str
    feasible: bool
    build_s: float
    solve_s: float


def second_differences(q: np.ndarray, t: np.ndarray) -> np.ndarray:
    """2 (v_i - v_(i-1)) / (h_(i-1) + h_i) with v the segment velocities (numpy, any leading axis)."""
    h = np.diff(t)
    v = np.diff(q, axis=0) / h.reshape(-1, *([1] * (q.ndim - 1)))
    return 2 * np.diff(v, axis=0) / (h[:-1] + h[1:]).reshape(-1, *([1] * (q.ndim - 1)))


def gamma_of(machine: Machine, A: np.ndarray, B: np.ndarray, t: np.ndarray) -> float:
    return float(np.sum(second_differences(machine.tool_axis_np(A, B), t) ** 2))


@dataclass(frozen=True)
class Formulation:
    """The plain NLP of one row: variables x = (A_0, B_0, A_1, ...) rad, objective f, constraint
    rows g with bounds lbg <= g <= ubg and box bounds lbx <= x <= ubx (CasADi SX)."""

    x: ca.SX
    f: ca.SX
    g: ca.SX
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray


def formulate(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_w: np.ndarray, tilt_w: np.ndarray,
              floor: np.ndarray | None = None, ceiling: np.ndarray | None = None, has_floor: np.ndarray | None = None,
              has_ceiling: np.ndarray | None = None, rate_scale: float = 1.0) -> Formulation:
    """The plain NLP of one row (module docstring); the rotary axes by the machine's names (a
    continuous C has no travel bounds); rate_scale multiplies their velocity and acceleration
    limits (the continuation of ``continuation_start``)."""
    n = len(t)
    x = ca.SX.sym("x", 2 * n)
    A, B = x[0::2], x[1::2]
    T = ca.horzcat(*machine.tool_axis(A, B))
    h = np.diff(t)

    def vel(q):
        return (q[1:] - q[:-1]) / ca.DM(h)

    def acc(q):
        v = vel(q)
        return 2 * (v[1:] - v[:-1]) / ca.DM(h[:-1] + h[1:])

    f = sum(ca.sumsqr(acc(T[:, k])) for k in range(3))
    xl, yl, zl = (ca.sum2(T * ca.DM(frames[:, :, j])) for j in range(3))
    tilt = ca.atan2(yl, xl)
    lead = ca.atan2(ca.sqrt(xl ** 2 + yl ** 2), zl)
    la, lb = (replace(L, vmax=L.vmax * rate_scale, amax=L.amax * rate_scale) for L in machine.rotary_limits())
    g = [vel(A), vel(B), acc(A), acc(B), lead, tilt]
    lbg = [np.full(n - 1, -la.vmax), np.full(n - 1, -lb.vmax), np.full(n - 2, -la.amax),
           np.full(n - 2, -lb.amax), lead_w[:, 0], tilt_w[:, 0]]
    ubg = [np.full(n - 1, la.vmax), np.full(n - 1, lb.vmax), np.full(n - 2, la.amax),
           np.full(n - 2, lb.amax), lead_w[:, 1], tilt_w[:, 1]]
    for coef, has, upper in ((floor, has_floor, False), (ceiling, has_ceiling, True)):
        if coef is None or not np.any(has):
            continue
        k = np.flatnonzero(has)
        bound = ca.DM(coef[k, 0]) + ca.DM(coef[k, 1]) * tilt[k.tolist()] + ca.DM(coef[k, 2]) * tilt[k.tolist()] ** 2
        g.append(lead[k.tolist()] - bound)
        lbg.append(np.full(len(k), -np.inf if upper else 0.0))
        ubg.append(np.full(len(k), 0.0 if upper else np.inf))
    lbx = np.tile([la.min, lb.min], n)
    ubx = np.tile([la.max, lb.max], n)
    return Formulation(x, f, ca.vertcat(*g), lbx, ubx, np.concatenate(lbg), np.concatenate(ubg))


def build(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_w: np.ndarray, tilt_w: np.ndarray,
          floor: np.ndarray | None = None, ceiling: np.ndarray | None = None, has_floor: np.ndarray | None = None,
          has_ceiling: np.ndarray | None = None, tol: float = 1e-8, rate_scale: float = 1.0
          ) -> tuple[ca.Function, np.ndarray, ...]:
    """The plain NLP of one row (module docstring) as an IPOPT solver and its bounds."""
    fm = formulate(machine, t, frames, lead_w, tilt_w, floor, ceiling, has_floor, has_ceiling, rate_scale)
    solver = ca.nlpsol("reference", "ipopt", {"x": fm.x, "f": fm.f, "g": fm.g},
                       {"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.tol": tol,
                        "ipopt.max_iter": 3000})
    return solver, fm.lbx, fm.ubx, fm.lbg, fm.ubg


@dataclass(frozen=True)
class Stationarity:
    """First-order optimality of a point in the plain formulation: the largest violation of a
    bound (in each row's units), the number of active rows (within ``active_tol`` of a bound) and
    the stationarity residual |grad f + sum mu_i grad c_i| / |grad f| with the best multipliers
    mu >= 0 of the active rows (non-negative least squares)."""

    violation: float
    active: int
    residual: float


def stationarity(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_w: np.ndarray, tilt_w: np.ndarray,
                 A: np.ndarray, B: np.ndarray, active_tol: float = 1e-6, **bounds) -> Stationarity:
    """How far (A, B) (rad) is from a KKT point of the plain NLP (``Stationarity``); derivatives
    by CasADi's automatic differentiation of ``formulate``, multipliers by scipy's NNLS."""
    from scipy.optimize import nnls

    fm = formulate(machine, t, frames, lead_w, tilt_w, **bounds)
    ev = ca.Function("ev", [fm.x], [fm.g, ca.gradient(fm.f, fm.x), ca.jacobian(fm.g, fm.x)])
    xv = np.empty(2 * len(t))
    xv[0::2], xv[1::2] = A, B
    g, grad, J = (np.asarray(ca.DM(v)) for v in ev(xv))
    g, grad, J = g.ravel(), grad.ravel(), J.reshape(len(g), len(xv))
    viol = max(float(np.max(fm.lbg - g, initial=0.0)), float(np.max(g - fm.ubg, initial=0.0)),
               float(np.max(fm.lbx - xv, initial=0.0)), float(np.max(xv - fm.ubx, initial=0.0)))
    eye = np.eye(len(xv))
    # minimise f: at an upper bound grad f + mu grad c = 0, at a lower bound grad f - mu grad c = 0
    cols = [J[g >= fm.ubg - active_tol], -J[g <= fm.lbg + active_tol],
            eye[xv >= fm.ubx - active_tol], -eye[xv <= fm.lbx + active_tol]]
    G = np.concatenate(cols).T
    if G.shape[1] == 0:
        return Stationarity(viol, 0, float(np.linalg.norm(grad) / max(np.linalg.norm(grad), 1e-300)) if np.any(grad)
                            else 0.0)
    _, res = nnls(G, -grad, maxiter=50 * G.shape[1])
    return Stationarity(viol, G.shape[1], float(res / max(np.linalg.norm(grad), 1e-300)))


def solve(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_w: np.ndarray, tilt_w: np.ndarray,
          starts: dict[str, tuple[np.ndarray, np.ndarray]], **bounds) -> ReferenceRow:
    """Best feasible solution (lowest Gamma) over the starts (name -> (A, B) rad)."""
    import time

    t0 = time.perf_counter()
    solver, lbx, ubx, lbg, ubg = build(machine, t, frames, lead_w, tilt_w, **bounds)
    build_s = time.perf_counter() - t0
    best: ReferenceRow | None = None
    t0 = time.perf_counter()
    for name, (A0, B0) in starts.items():
        x0 = np.empty(2 * len(t))
        x0[0::2], x0[1::2] = A0, B0
        sol = solver(x0=np.clip(x0, lbx, ubx), lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        x = np.asarray(sol["x"]).ravel()
        g = np.asarray(sol["g"]).ravel()
        feasible = bool(solver.stats()["success"]) and bool(np.all(g >= lbg - 1e-7) and np.all(g <= ubg + 1e-7))
        row = ReferenceRow(x[0::2], x[1::2], gamma_of(machine, x[0::2], x[1::2], t), name, feasible, build_s, 0.0)
        if feasible and (best is None or row.gamma < best.gamma):
            best = row
    solve_s = time.perf_counter() - t0
    if best is None:
        return ReferenceRow(A0, B0, np.inf, "none feasible", False, build_s, solve_s)
    return ReferenceRow(best.A, best.B, best.gamma, best.start, True, build_s, solve_s)


#: the rotary axes' velocity and acceleration limits of the continuation, as multiples of the
#: machine's: the exact inverse passes a pole far beyond them, so the first problem accepts it
CONTINUATION = (1000.0, 100.0, 30.0, 10.0, 3.0, 1.0)


def continuation_start(machine: Machine, t: np.ndarray, frames: np.ndarray, lead_w: np.ndarray,
                       tilt_w: np.ndarray, A0: np.ndarray, B0: np.ndarray, **bounds) -> tuple[np.ndarray, np.ndarray]:
    """A start for the rows that pass the pole of the outer axis, independent of camsmooth's pole
    start: the plain NLP solved from (A0, B0) (the exact inverse) with the rotary limits relaxed by
    CONTINUATION's factors, each solve starting from the last, down to the machine's own."""
    x = np.empty(2 * len(t))
    x[0::2], x[1::2] = A0, B0
    for k in CONTINUATION:
        solver, lbx, ubx, lbg, ubg = build(machine, t, frames, lead_w, tilt_w, rate_scale=k, **bounds)
        x = np.asarray(solver(x0=np.clip(x, lbx, ubx), lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)["x"]).ravel()
    return x[0::2], x[1::2]
