"""Jerk-limited time law (issue 22 item 5): per case, the TOPP-RA time (no jerk limit), the
jerk-limited time (camsmooth.smoothing.jerk), an independent reference NLP's time, their relative
difference, the largest jerk / jmax over the samples (finite differences at the points and on a
resampling of the law, 16 instants per interval) and the planner's wall time per row.

    python benchmarks/bench_jerk.py [--rows 2] [--ref-n 240,480] [--blade-only]

The blade rows' reference (a piecewise polynomial of 200 pieces in CasADi) takes minutes per row;
``--ref-n ""`` plans without it.

Reference: a direct NLP in time (uniform grid over the free final time T, states s, s', s'' of
the path's own parameter, s''' constant per step and integrated exactly, every limit at every
instant, rest to rest, minimise T), given the path as a CasADi function: the closed form for the
helix, a CasADi B-spline interpolant of the points for a blade row (a path the planner was not
tuned on: surfaces/blade_path.csv, tool axis = the surface normal, tip = the contact point, feed
as in the file). Machine: the default one with jmax given (A B 2000 deg/s^3 or 500, X Y Z
20000 mm/s^3 or 5000).
"""

from __future__ import annotations

import argparse
import sys
import time
import tomllib
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camsmooth.io.ccpath import read_cc_csv  # noqa: E402
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, Machine, machine_from_dict  # noqa: E402
from camsmooth.smoothing.feed import (  # noqa: E402
    _xmax,
    axis_limits,
    finite_difference_rates,
    forward_backward,
    plan_from_law,
    plan_from_speed,
    row_path,
)
from camsmooth.smoothing.jerk import jerk_law  # noqa: E402


def machine(jmax_rot: float | None = 2000.0, jmax_lin: float = 20000.0) -> Machine:
    """The default machine with jmax given (deg/s^3 for A B, mm/s^3 for X Y Z); None: as shipped."""
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    if jmax_rot is not None:
        for ax in ("A", "B"):
            data["axis"][ax]["jmax"] = jmax_rot
        for ax in ("X", "Y", "Z"):
            data["axis"][ax]["jmax"] = jmax_lin
    return machine_from_dict(data, "<bench>")


def helix(th, m: Machine):
    """The helix of the jerk tests (tip (3,), joints (5,)) at theta (rad): tip on a 20 mm radius
    helix rising 2 mm/rad, A and B swinging; numpy arrays or a CasADi symbol."""
    sin, cos = (ca.sin, ca.cos) if isinstance(th, (ca.SX, ca.MX)) else (np.sin, np.cos)
    tip = [20.0 * cos(th), 20.0 * sin(th), 2.0 * th]
    a, b = np.radians(12.0) * sin(th), np.radians(20.0) * (1 - cos(th))
    axis = m.tool_axis(a, b)
    return tip, [tip[k] + m.pivot * axis[k] for k in range(3)] + [a, b]


def helix_function(m: Machine) -> ca.Function:
    """theta -> (joints (5,), tip (3,)) of ``helix`` as a CasADi function, for ``reference_time``."""
    sym = ca.SX.sym("th")
    tip_s, q_s = helix(sym, m)
    return ca.Function("p", [sym], [ca.vertcat(*q_s), ca.vertcat(*tip_s)])


def helix_case(m: Machine, n: int = 240):
    """The tests' helix: q, tip, feed and the closed form for the reference."""
    th = np.linspace(0.0, np.pi, n)
    tip, q = helix(th, m)
    return np.column_stack(q), np.column_stack(tip), np.full(n, 3000.0), helix_function(m), float(np.pi)


def blade_case(m: Machine, row: int):
    """One row of the blade sample: contact points as tips, normals as tool axes (branch 0 of the
    inverse, unwrapped), X Y Z the pivot; the path for the reference: the planner's own C2 cubic
    spline (the path of a sampled row), rebuilt as a CasADi piecewise polynomial of s."""
    path = read_cc_csv(ROOT / "surfaces" / "blade_path.csv")
    rows = np.asarray(path.rows)
    k = rows == np.unique(rows)[row]
    tip = np.asarray(path.points, float)[k]
    T = np.asarray(path.normals, float)[k]
    ab = np.unwrap(m.inverse_axis(T)[:, 0, :], axis=0)
    q = np.column_stack([m.linear_axes(tip, ab[:, 0], ab[:, 1]), ab])
    return q, tip, np.asarray(path.feed, float)[k], None, None


def spline_function(rp) -> tuple[ca.Function, float]:
    """The RowPath's splines q(s), p(s) as a CasADi function (piecewise cubic by pw_const)."""
    s = ca.SX.sym("s")
    x = rp.s
    x0 = ca.pw_const(s, ca.DM(x[1:-1]), ca.DM(x[:-1]))
    d = s - x0

    def pp(spline) -> ca.SX:
        c = spline.c  # (4, pieces, dims)
        out = []
        for j in range(c.shape[2]):
            co = [ca.pw_const(s, ca.DM(x[1:-1]), ca.DM(c[k, :, j])) for k in range(4)]
            out.append(co[0] * d**3 + co[1] * d**2 + co[2] * d + co[3])
        return ca.vertcat(*out)

    return ca.Function("p", [s], [pp(rp.spline), pp(rp.tip_spline)]), float(x[-1])


def reference_time(m: Machine, fn: ca.Function, s_end: float, feed: float, n: int, t_guess: float) -> float:
    """The direct NLP in time (module docstring) on the path fn(s) -> (q (5,), tip (3,))."""
    vmax, amax, jmax = axis_limits(m)
    s = ca.MX.sym("s")
    q, tip = fn(s)
    d1 = ca.jacobian(q, s)
    d2 = ca.jacobian(d1, s)
    d3 = ca.jacobian(d2, s)
    f = ca.Function("f", [s], [d1, d2, d3, ca.norm_2(ca.jacobian(tip, s))]).map(n + 1)
    T = ca.MX.sym("T")
    X = ca.MX.sym("X", 3, n + 1)
    U = ca.MX.sym("U", 1, n)
    h = T / n
    sv, v, a = X[0, :-1], X[1, :-1], X[2, :-1]
    dyn = ca.vertcat(X[0, 1:] - (sv + h * v + h**2 / 2 * a + h**3 / 6 * U),
                     X[1, 1:] - (v + h * a + h**2 / 2 * U), X[2, 1:] - (a + h * U))
    q1, q2, q3, spd = f(X[0, :])
    v, a = ca.repmat(X[1, :], 5, 1), ca.repmat(X[2, :], 5, 1)
    u = ca.repmat(ca.horzcat(U, U[-1]), 5, 1)
    u_left = ca.repmat(ca.horzcat(U[0], U), 5, 1)
    lim = [(q1 * v, vmax), (q2 * v**2 + q1 * a, amax), (q3 * v**3 + 3 * q2 * v * a + q1 * u, jmax),
           (q3 * v**3 + 3 * q2 * v * a + q1 * u_left, jmax)]
    g = [ca.vec(dyn)] + [ca.vec(e / ca.repmat(ca.DM(lm), 1, n + 1)) for e, lm in lim] + [ca.vec(spd * X[1, :])]
    lbg = np.r_[np.zeros(3 * n), -np.ones(20 * (n + 1)), np.full(n + 1, -np.inf)]
    ubg = np.r_[np.zeros(3 * n), np.ones(20 * (n + 1)), np.full(n + 1, feed / 60.0)]
    x = ca.vertcat(T, ca.vec(X), ca.vec(U))
    lbx = np.r_[1e-3, np.tile([-np.inf, 0.0, -np.inf], n + 1), np.full(n, -np.inf)]
    ubx = np.full(1 + 3 * (n + 1) + n, np.inf)
    for k, val in ((0, 0.0), (1, 0.0), (2, 0.0), (3 * n, s_end), (3 * n + 1, 0.0), (3 * n + 2, 0.0)):
        lbx[1 + k] = ubx[1 + k] = val
    tt = np.linspace(0, 1, n + 1)
    x0 = np.r_[t_guess, np.column_stack([s_end * (3 * tt**2 - 2 * tt**3), s_end * 6 * (tt - tt**2) / t_guess,
                                         s_end * 6 * (1 - 2 * tt) / t_guess**2]).ravel(), np.zeros(n)]
    solver = ca.nlpsol("ref", "ipopt", {"x": x, "f": T, "g": ca.vertcat(*g)},
                       {"print_time": False, "ipopt.print_level": 0, "ipopt.sb": "yes", "ipopt.max_iter": 3000})
    sol = solver(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    return float(sol["x"][0]) if solver.stats()["success"] else float("nan")


def worst_jerk(m: Machine, rp, law, t_points: np.ndarray, per: int = 16) -> float:
    """Largest |jerk| / jmax: finite differences at the points and on the law resampled."""
    jmax = axis_limits(m)[2]
    _, _, j = finite_difference_rates(rp.q, t_points)
    tau = np.diff(law.t)[:, None] * (np.arange(per) / per)[None, :]
    s = (law.s[:-1, None] + law.y[:-1, None] * tau + law.z[:-1, None] * tau**2 / 2
         + law.w[:, None] * tau**3 / 6).ravel()
    t = (law.t[:-1, None] + tau).ravel()
    _, _, jd = finite_difference_rates(rp.spline(np.r_[s, law.s[-1]]), np.r_[t, law.t[-1]])
    return float(max((np.abs(j) / jmax).max(), (np.abs(jd) / jmax).max()))


def run_case(name: str, m: Machine, q, tip, feed, fn, s_end, ref_ns: list[int]) -> None:
    rp = row_path(m, q, tip, feed)
    if fn is None:
        fn, s_end = spline_function(rp)
    t0 = time.perf_counter()
    sd = forward_backward(rp.s, rp.dq, rp.ddq, rp.amax, _xmax(rp))
    topp = plan_from_speed(rp, sd)
    t_topp = time.perf_counter() - t0
    t0 = time.perf_counter()
    law = jerk_law(rp, sd)
    plan = plan_from_law(rp, law)
    t_jerk = time.perf_counter() - t0
    refs = []
    for n in ref_ns:
        t0 = time.perf_counter()
        refs.append((n, reference_time(m, fn, s_end, float(np.min(feed[1:])), n, plan.cycle_time),
                     time.perf_counter() - t0))
    ref_txt = "  ".join(f"ref(n={n}) {r:.4f} s ({100 * (plan.cycle_time / r - 1):+.2f}%, {tr:.1f} s)"
                        for n, r, tr in refs)
    print(f"{name:28s} {len(q):6d} pts  TOPP-RA {topp.cycle_time:8.4f} s  jerk-limited {plan.cycle_time:8.4f} s "
          f"({100 * (plan.cycle_time / topp.cycle_time - 1):+.1f}%)  {ref_txt}")
    print(f"{'':28s} max jerk/jmax {worst_jerk(m, rp, law, plan.t_plan):.4f}  jerk_over {int(plan.jerk_over.sum())}  "
          f"slowdown {law.slowdown:.4f}  IPOPT iterations {law.iterations}  run time: TOPP-RA {t_topp:.3f} s, "
          f"jerk-limited {t_jerk:.2f} s ({1e3 * t_jerk / len(q):.1f} ms/point)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=2, help="blade rows to plan (first N)")
    ap.add_argument("--ref-n", default="240,480", help="reference NLP grid sizes")
    ap.add_argument("--blade-only", action="store_true", help="only the blade rows")
    args = ap.parse_args()
    ref_ns = [int(v) for v in args.ref_n.split(",") if v]
    print("== jerk-limited law against TOPP-RA and a direct NLP in time (wall times on this machine)")
    for jr, jl in () if args.blade_only else ((2000.0, 20000.0), (500.0, 5000.0)):
        m = machine(jr, jl)
        run_case(f"helix, jmax {jr:g} deg/s^3", m, *helix_case(m), ref_ns)
    m = machine(2000.0, 20000.0)
    for r in range(args.rows):
        run_case(f"blade row {r}, jmax 2000", m, *blade_case(m, r), ref_ns)


if __name__ == "__main__":
    main()
