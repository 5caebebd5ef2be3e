"""The jerk-limited time-optimal law along one row (issue 22 item 5).

TOPP-RA (camsmooth.smoothing.feed) is a second-order method: s'' jumps between the grid points,
so the axes' jerk is unbounded in the continuous model. Where the machine file gives ``jmax``
(``Machine.jerk_limited``) the planned law must also keep every axis's jerk within its jmax, as
most commercial controllers do. No open planner solves that along a fixed five-axis path, so
camsmooth solves it as a nonlinear program (CasADi + IPOPT) on the same geometric path as
TOPP-RA: the row's C2 cubic spline q(s) (``feed.row_path``; s is the planner's scaled path
parameter, X Y Z in mm, A B in rad, the tool tip p(s) in mm in the workpiece frame).

Formulation ("fixed path nodes, free durations"). The nodes are the row's points (each spline
piece split into equal parts where a row has fewer than ``MIN_INTERVALS`` pieces). The law is a
triple integrator in time: s''' = w_k is constant on interval k, whose duration h_k is a
variable, and the states y = s', z = s'' at the nodes obey the exact integration of that jerk,

    s_(k+1) - s_k = y_k h_k + z_k h_k^2 / 2 + w_k h_k^3 / 6,
    y_(k+1) = y_k + z_k h_k + w_k h_k^2 / 2,      z_(k+1) = z_k + w_k h_k.

The objective is the row's time sum h_k, exactly (no quadrature of 1 / s'). Constraints, with
q', q'' of the spline at the nodes and q''' constant on each spline piece:

- tip feed and axis velocities: y_k^2 <= the TOPP-RA bound at the node (``feed._xmax``: the
  programmed feed over |p'(s)|, every axis's vmax over |q_j'|, and at the points the chord bounds);
- axis acceleration at every node: |q_j'' y^2 + q_j' z| <= amax_j;
- axis jerk at both ends of every interval (with that interval's w, so the jump of s''' and of
  the cubic's q''' at a knot is seen from both sides): |q_j''' y^3 + 3 q_j'' y z + q_j' w| <= jmax_j;
- rest at both ends (y = z = 0 at the first and last node).

Why this and not the s-domain form (y, z, w at nodes, d(y^2/2)/ds = z and y dz/ds = w by the
trapezoid rule, time = sum 2 ds / (y_k + y_(k+1))): that form is a consistent discretisation only
where s' is bounded away from 0. Starting from rest under a jerk limit, s ~ t^3, y ~ s^(2/3) and
z ~ s^(1/3): the trapezoid rule is O(1) wrong on the first intervals (it demands 1.5x the jerk
for the same z y, and its time formula, exact for constant s'', gives 2/3 of the first
interval's time), so the result moved by 0.3-4.6 % with the node count and the path's degree.
Here the dynamics are integrated exactly for piecewise-constant jerk and the time is the sum of
the durations, so the law is exactly a jerk-limited motion; the only approximation is that the
limits are imposed at the nodes. That is closed by a dense check: the law is evaluated at
``DENSE`` instants per interval (exact chain rule on the spline: velocity q' s', acceleration
q'' s'^2 + q' s'', jerk q''' s'^3 + 3 q'' s' s'' + q' s'''; tip speed |p'| s' against the
block's feed) and, where a ratio to its limit exceeds 1, the whole law is slowed uniformly by the
smallest factor c that restores it (times x c, s' / c, s'' / c^2, s''' / c^3). IPOPT plans against
the limits x (1 - MARGIN), so c = 1 almost always. Because the law's jerk is bounded everywhere,
the finite differences of the sampled points (velocity = chord / time, acceleration and jerk =
2 and 6 times the divided differences, ``feed.finite_difference_rates``) are within the limits
too: a divided difference equals the derivative at some instant of its span.

Start: the TOPP-RA law (speeds at the points), slowed by the factor that brings its
finite-difference jerk within jmax; IPOPT need not start feasible. Checked against an independent
direct NLP in time (uniform time grid, states s s' s'', closed-form path; tests/test_jerk.py,
benchmarks/bench_jerk.py): within 0.5 % (the requirement is 2 %).

Units: s (time), the scaled path parameter of the RowPath (y in 1/s, z in 1/s^2, w in 1/s^3),
mm and rad for the axes.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import casadi as ca
import numpy as np

from camsmooth.smoothing.feed import RowPath, _xmax, forward_backward

__all__ = ["DENSE", "GRADING", "MARGIN", "MIN_INTERVALS", "JerkLaw", "Rates", "jerk_law", "law_rates"]

#: fewest intervals of a row's law (a row of fewer points has each piece split in equal parts)
MIN_INTERVALS = 120
#: IPOPT plans against every limit x (1 - MARGIN); the dense check takes up what is left
MARGIN = 5e-4
#: halvings of the first and last interval: a start from rest at a large jmax has a short jerk
#: ramp, and a ramp cannot be shorter than the interval it lies in (its time error ~ sqrt(ds))
GRADING = 12
#: instants per interval of the dense check (both ends included)
DENSE = 9
_IPOPT = {"ipopt.print_level": 0, "print_time": False, "expand": True, "ipopt.sb": "yes",
          "ipopt.max_iter": 1000, "ipopt.tol": 1e-8, "ipopt.constr_viol_tol": 1e-8, "ipopt.mu_strategy": "adaptive"}


@dataclass(frozen=True, kw_only=True)
class JerkLaw:
    """A jerk-limited law of one row. s (n+1,): the nodes (RowPath's scaled parameter); points
    (M,): the node index of each of the RowPath's points; t (n+1,) s; y, z (n+1,): s', s'' at
    the nodes; w (n,): s''' on each interval; slowdown: the factor c >= 1 the dense check slowed
    IPOPT's law by; converged: IPOPT succeeded (else the slowed start, feasible after the dense
    check, is returned); iterations; solve_time: s of wall time (building and solving)."""

    s: np.ndarray
    points: np.ndarray
    t: np.ndarray
    y: np.ndarray
    z: np.ndarray
    w: np.ndarray
    slowdown: float
    converged: bool
    iterations: int
    solve_time: float

    @property
    def cycle_time(self) -> float:
        """The row's time (s)."""
        return float(self.t[-1])


@dataclass(frozen=True, kw_only=True)
class Rates:
    """A law evaluated at instants (``law_rates``): t, s, sd (K,); velocity, acceleration, jerk
    (K, 5) per axis (mm/s^k for X Y Z, rad/s^k for A B); tip_speed (K,) mm/s; feed (K,) mm/s,
    the bound of the block being run."""

    t: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    jerk: np.ndarray
    tip_speed: np.ndarray
    feed: np.ndarray

    def ratio(self, vmax: np.ndarray, amax: np.ndarray, jmax: np.ndarray) -> tuple[float, float, float, float]:
        """Largest ratio to its limit of the tip speed, the axis velocities, accelerations, jerks."""
        with np.errstate(divide="ignore", invalid="ignore"):
            tip = np.nan_to_num(self.tip_speed / self.feed, nan=0.0, posinf=0.0)
        return (float(tip.max(initial=0.0)), float((np.abs(self.velocity) / vmax).max(initial=0.0)),
                float((np.abs(self.acceleration) / amax).max(initial=0.0)),
                float((np.abs(self.jerk) / jmax).max(initial=0.0)))


def _nodes(rp: RowPath) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes s, the node index of every point, and the spline piece of every interval: the points,
    each piece split in r equal parts (r * (M - 1) >= MIN_INTERVALS), and the first and last
    intervals split geometrically (``GRADING``)."""
    m = len(rp.s)
    r = max(1, -(-MIN_INTERVALS // (m - 1)))
    frac = np.arange(r) / r
    s = np.r_[(rp.s[:-1, None] + frac[None, :] * np.diff(rp.s)[:, None]).ravel(), rp.s[-1]]
    g = 0.5 ** np.arange(GRADING, 0, -1)
    s = np.unique(np.r_[s, s[0] + g * (s[1] - s[0]), s[-1] - g * (s[-1] - s[-2])])
    piece = np.clip(np.searchsorted(rp.s, s[:-1], side="right") - 1, 0, m - 2)
    return s, np.searchsorted(s, rp.s), piece


def _piece_feed(rp: RowPath) -> np.ndarray:
    """Tip speed bound (mm/s) of each spline piece: the block's programmed feed, recovered from the
    points' bounds min(F_i, F_(i+1)) as the larger of its two ends (exact but at a one-block peak)."""
    return np.maximum(rp.feed_bound[:-1], rp.feed_bound[1:])


_INTERVAL: list[ca.Function] = []


def _interval_function() -> ca.Function:
    """The constraints of one interval (scaled; module docstring), a CasADi function of its
    variables (y_k, z_k, y_(k+1), z_(k+1), w_k, h_k, scaled) and data (a column of ``jerk_law``'s
    ``par``): 3 integration equalities, then |acceleration| <= 1 at the first node, |jerk| <= 1 at
    both ends, |acceleration| <= 1 and |jerk| <= 1 at the middle instant, s' there <= 1 (over the
    mean of the ends' bounds). Built once; mapped over the intervals."""
    if _INTERVAL:
        return _INTERVAL[0]
    args = [ca.SX.sym(k) for k in ("yk", "zk", "yk1", "zk1", "w", "h")]
    p = ca.SX.sym("p", 41)
    ds, a1, a2, b1, b2, c3 = p[0], p[1:6], p[6:11], p[11:16], p[16:21], p[21:26]
    inv_a, inv_j, inv_ym, Y, Z, W, H = p[26:31], p[31:36], p[36], p[37], p[38], p[39], p[40]
    yk, zk, yk1, zk1, w, h = (sc * a for sc, a in zip((Y, Z, Y, Z, W, H), args, strict=True))
    hm = h / 2
    e = yk * hm + zk * hm**2 / 2 + w * hm**3 / 6  # s - s_k at the middle
    ym, zm = yk + zk * hm + w * hm**2 / 2, zk + w * hm
    m1, m2 = a1 + a2 * e + c3 * e**2 / 2, a2 + c3 * e  # q', q'' there (q is a cubic on the piece)
    out = ca.vertcat(
        (yk * h + zk * h**2 / 2 + w * h**3 / 6) / ds - 1.0, (yk + zk * h + w * h**2 / 2 - yk1) / Y,
        (zk + w * h - zk1) / Z,
        (a2 * yk**2 + a1 * zk) * inv_a,
        (c3 * yk**3 + 3 * a2 * yk * zk + a1 * w) * inv_j,
        (c3 * yk1**3 + 3 * b2 * yk1 * zk1 + b1 * w) * inv_j,
        (m2 * ym**2 + m1 * zm) * inv_a,
        (c3 * ym**3 + 3 * m2 * ym * zm + m1 * w) * inv_j,
        ym * inv_ym)
    _INTERVAL.append(ca.Function("interval", [*args, p], [out]))
    return _INTERVAL[0]


def law_rates(rp: RowPath, law: JerkLaw, per_interval: int = DENSE) -> Rates:
    """The law at ``per_interval`` equally spaced instants of every interval (both ends included),
    evaluated exactly: s(t) is the cubic of each interval, the axes by the chain rule on the
    spline (module docstring)."""
    h = np.diff(law.t)
    f = np.linspace(0.0, 1.0, per_interval)
    tau = h[:, None] * f[None, :]
    y, z, w = law.y[:-1, None], law.z[:-1, None], law.w[:, None]
    s0, s1 = law.s[:-1, None], law.s[1:, None]
    s = np.clip(s0 + y * tau + z * tau**2 / 2 + w * tau**3 / 6, s0, s1)
    sd = np.maximum(y + z * tau + w * tau**2 / 2, 0.0)
    sdd = z + w * tau
    piece = np.searchsorted(rp.s, law.s[:-1], side="right") - 1
    mid = 0.5 * (rp.s[piece] + rp.s[piece + 1])
    d3 = rp.spline(mid, 3)[:, None, :]
    sf = s.ravel()
    d1 = rp.spline(sf, 1).reshape(*s.shape, 5)
    d2 = rp.spline(sf, 2).reshape(*s.shape, 5)
    sd3, sdd3, w3 = sd[..., None], sdd[..., None], np.broadcast_to(w, s.shape)[..., None]
    vel = d1 * sd3
    acc = d2 * sd3**2 + d1 * sdd3
    jerk = d3 * sd3**3 + 3 * d2 * sd3 * sdd3 + d1 * w3
    tip = np.linalg.norm(rp.tip_spline(sf, 1), axis=1) * sd.ravel()
    feed = np.repeat(_piece_feed(rp)[piece], per_interval)
    return Rates(t=(law.t[:-1, None] + tau).ravel(), s=sf, sd=sd.ravel(), velocity=vel.reshape(-1, 5),
                 acceleration=acc.reshape(-1, 5), jerk=jerk.reshape(-1, 5), tip_speed=tip, feed=feed)


def _slowed(law: JerkLaw, c: float) -> JerkLaw:
    return JerkLaw(s=law.s, points=law.points, t=law.t * c, y=law.y / c, z=law.z / c**2, w=law.w / c**3,
                   slowdown=law.slowdown * c, converged=law.converged, iterations=law.iterations,
                   solve_time=law.solve_time)


def _start(rp: RowPath, s: np.ndarray, d1: np.ndarray, d2: np.ndarray, d3: np.ndarray,
           jmax: np.ndarray, sd_points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The TOPP-RA law at the nodes (s'^2 linear in s between points), slowed until its
    finite-difference jerk is within jmax: y, z, w, h."""
    y = np.sqrt(np.maximum(np.interp(s, rp.s, sd_points**2), 0.0))
    y[[0, -1]] = 0.0
    ds = np.diff(s)
    h = 2 * ds / np.maximum(y[1:] + y[:-1], 1e-300)
    t = np.r_[0.0, np.cumsum(h)]
    z = np.gradient(y, t)
    z[[0, -1]] = 0.0
    w = np.diff(z) / h
    jerk = d3 * y[:-1, None] ** 3 + 3 * d2[:-1] * (y * z)[:-1, None] + d1[:-1] * w[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        c = max(1.0, float(np.nanmax(np.abs(jerk) / jmax, initial=0.0)) ** (1 / 3))
    return y / c, z / c**2, w / c**3, h * c


def jerk_law(rp: RowPath, sd_points: np.ndarray | None = None) -> JerkLaw:
    """The jerk-limited time-optimal law of a row (module docstring): every axis's vmax, amax,
    jmax (``rp.vmax``, ``rp.amax``, ``rp.jmax``: mm and rad, per s, s^2, s^3) and the tip feed
    (``rp.feed_bound``, mm/s) at every instant of the dense check, rest to rest.
    sd_points: the TOPP-RA speeds s' at the points (computed when not given), the start."""
    t0 = time.perf_counter()
    if sd_points is None:
        sd_points = forward_backward(rp.s, rp.dq, rp.ddq, rp.amax, _xmax(rp))
    s, points, piece = _nodes(rp)
    n = len(s) - 1
    vmax, amax, jmax = rp.vmax, rp.amax, rp.jmax
    d1, d2 = rp.spline(s, 1), rp.spline(s, 2)
    d3 = rp.spline(0.5 * (rp.s[piece] + rp.s[piece + 1]), 3)  # (n, 5): constant on a piece
    # s'^2 bound at the nodes: TOPP-RA's at the points; in a piece, its feed and the axes' vmax
    xb = np.empty(n + 1)
    xb[points] = _xmax(rp)
    sub = np.setdiff1d(np.arange(n + 1), points)
    if sub.size:
        dp = np.linalg.norm(rp.tip_spline(s[sub], 1), axis=1)
        with np.errstate(divide="ignore"):
            xb[sub] = np.minimum((_piece_feed(rp)[piece[sub]] / dp) ** 2,
                                 np.min((vmax / np.abs(d1[sub])) ** 2, axis=1))
    xb = np.minimum(xb, 1e12)
    ymax = np.sqrt(xb) * (1.0 - MARGIN)
    ds = np.diff(s)
    y0, z0, w0, h0 = _start(rp, s, d1, d2, d3, jmax, sd_points)

    # scales: y, z, w, h and the time are all O(1) in the NLP's variables
    with np.errstate(divide="ignore"):
        Y = float(np.median(np.minimum(ymax, ymax[ymax > 0].min(initial=1.0) * 1e3))) or 1.0
        Z = float(np.median(np.min(amax / np.abs(d1), axis=1))) if np.isfinite(amax).any() else Y**2
        W = float(np.median(np.min(jmax / np.abs(d1), axis=1)))
    Z = Z if np.isfinite(Z) and Z > 0 else Y**2
    W = W if np.isfinite(W) and W > 0 else Z**1.5
    H = float(np.median(ds)) / Y
    T0 = float(h0.sum())

    # per-interval data (columns of par): ds, q' q'' at both ends, q''', reciprocal limits (0 for
    # an axis that stands still or has no limit), the middle's speed bound and the scales
    moving = np.array([np.ptp(rp.q[:, j]) > 0.0 for j in range(5)])
    with np.errstate(divide="ignore"):
        inv_a = np.where(moving & np.isfinite(amax), 1.0 / (amax * (1.0 - MARGIN)), 0.0)
        inv_j = np.where(moving & np.isfinite(jmax), 1.0 / (jmax * (1.0 - MARGIN)), 0.0)
    par = np.column_stack([ds, d1[:-1], d2[:-1], d1[1:], d2[1:], d3, np.tile(inv_a, (n, 1)), np.tile(inv_j, (n, 1)),
                           2.0 / (ymax[:-1] + ymax[1:] + 1e-300), np.tile([Y, Z, W, H], (n, 1))]).T
    v = ca.MX.sym("v", 4, n)  # per interval: y, z at its first node, its w and h (scaled)
    last = ca.MX.sym("last", 2)  # y, z at the last node
    yk1 = ca.horzcat(v[0, 1:], last[0])
    zk1 = ca.horzcat(v[1, 1:], last[1])
    g = _interval_function().map(n, "serial")(v[0, :], v[1, :], yk1, zk1, v[2, :], v[3, :], ca.DM(par))
    rows = g.shape[0]
    lbg = np.tile(np.r_[np.zeros(3), -np.ones(rows - 4), -np.inf], n)
    ubg = np.tile(np.r_[np.zeros(3), np.ones(rows - 3)], n)
    x = ca.vertcat(ca.vec(v), last)
    lbx = np.column_stack([np.zeros(n), np.full(n, -np.inf), np.full(n, -np.inf), np.zeros(n)]).ravel()
    ubx = np.column_stack([ymax[:-1] / Y, np.full((n, 3), np.inf)]).ravel()
    lbx[:2] = ubx[:2] = 0.0  # rest at both ends
    lbx, ubx = np.r_[lbx, 0.0, 0.0], np.r_[ubx, 0.0, 0.0]
    solver = ca.nlpsol("jerk", "ipopt", {"x": x, "f": ca.sum2(v[3, :]) * (H / T0), "g": ca.vec(g)}, _IPOPT)
    for slow in (1.0, 2.0, 4.0):  # a failed solve is retried from a slower start
        start = np.r_[np.column_stack([np.minimum(y0 / slow, ymax)[:-1] / Y, z0[:-1] / (Z * slow**2),
                                       w0 / (W * slow**3), h0 * slow / H]).ravel(), 0.0, 0.0]
        sol = solver(x0=start, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
        stats = solver.stats()
        converged = bool(stats["success"]) or stats["return_status"] == "Solved_To_Acceptable_Level"
        if converged:
            break
    else:
        raise RuntimeError(f"jerk-limited time law: IPOPT did not converge ({stats['return_status']}) on a row of "
                           f"{len(rp.s)} points")
    xs = np.asarray(sol["x"]).ravel()
    vs = xs[:-2].reshape(n, 4)
    ys = np.maximum(np.r_[vs[:, 0], xs[-2]] * Y, 0.0)
    zs = np.r_[vs[:, 1], xs[-1]] * Z
    ws = vs[:, 2] * W
    hs = np.maximum(vs[:, 3] * H, 0.0)
    law = JerkLaw(s=s, points=points, t=np.r_[0.0, np.cumsum(hs)], y=ys, z=zs, w=ws, slowdown=1.0,
                  converged=converged, iterations=int(stats.get("iter_count", 0)), solve_time=0.0)
    # the dense check: slow the whole law down to where every limit holds at every instant
    tip, vel, acc, jrk = law_rates(rp, law).ratio(vmax, amax, jmax)
    c = max(1.0, tip, vel, np.sqrt(acc), np.cbrt(jrk))
    if c > 1.0:
        law = _slowed(law, c * (1.0 + 1e-9))
    return JerkLaw(**{**law.__dict__, "solve_time": time.perf_counter() - t0})

