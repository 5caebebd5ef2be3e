"""Feed planning figures (issue 8): cycle time per shipped sample and method, what planning costs
against smoothing, scaling in points, and toppra against a hand-written forward-backward pass.

    python benchmarks/bench_feed.py samples [--names blade,mould,saddle,wave]
    python benchmarks/bench_feed.py scaling [--sizes 1000,10000,100000]
    python benchmarks/bench_feed.py solvers [--sizes 1000,10000,100000]
    python benchmarks/bench_feed.py            # all three

samples: every surfaces/*_path.csv with its mesh, smoothed by camsmooth.smoothing.pipeline.smooth
(method "nlp", so none, spline and nlp; settings of benchmarks/bench_pipeline.py: cutter R = 4,
r = 1 mm, lead 2:20 deg, tilt -15:15 deg, tolerance 0.005 mm, default machine, feed from the path
CSV), then every method planned by camsmooth.smoothing.feed.plan_method (serial, one process).
Smoothing time = the wall time of ``smooth`` (it uses the machine's cores for rows); planning time
= the wall time of the three plans.

scaling: one long synthetic row (a wave with rotary motion, 0.1 mm spacing) planned whole.

solvers: the same gridpoints, spline and constraints solved by the toppra package (TOPP-RA,
seidel LPs, Python loop over stages: benchmarks/toppra_reference.py) and by the planner's own
``forward_backward`` (the same discretisation: backward pass of the largest controllable s'^2,
forward pass of the largest s'', each stage a 2-variable LP solved exactly by eliminating s'';
numba), on (a) a straight line whose exact time law is the trapezoid (error of the cycle time and
of t at the points) and (b) the wave row (agreement between the two, limits from finite
differences on the points).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from toppra_reference import toppra_speed  # noqa: E402

from camsmooth.geometry.cutter import ToroidalCutter  # noqa: E402
from camsmooth.geometry.surfaces import load_surface  # noqa: E402
from camsmooth.io.ccpath import read_cc_csv  # noqa: E402
from camsmooth.machine.kinematics import load_machine  # noqa: E402
from camsmooth.smoothing.feed import (  # noqa: E402
    AXES,
    CONSTRAINTS,
    _xmax,
    finite_difference_rates,
    forward_backward,
    plan_from_speed,
    plan_method,
    plan_row,
    row_path,
)
from camsmooth.smoothing.pipeline import smooth  # noqa: E402

LEAD = tuple(np.radians([2.0, 20.0]))
TILT = tuple(np.radians([-15.0, 15.0]))
CUTTER = ToroidalCutter(R=4.0, r=1.0)
TOL = 0.005
METHODS = ("none", "spline", "nlp")


def _mesh_file(name: str) -> Path:
    return next(p for p in (ROOT / "surfaces" / f"{name}.ply", ROOT / "surfaces" / f"{name}.stl") if p.exists())


def _samples() -> list[str]:
    return sorted(p.name[:-len("_path.csv")] for p in (ROOT / "surfaces").glob("*_path.csv"))


def bench_samples(names: list[str]) -> None:
    machine = load_machine(None)
    print("== samples: cycle time per method (rest-to-rest rows, rapids between rows not counted), default machine "
          "(X Y Z 500 mm/s, 3000 mm/s^2; A B 60 deg/s, 300 deg/s^2)")
    print(f"{'sample':>8s} {'points':>7s} {'rows':>5s} {'none s':>8s} {'spline s':>9s} {'nlp s':>8s} "
          f"{'nlp/none':>9s} {'nlp/spline':>10s} {'limits most (none | spline | nlp)':>58s} "
          f"{'smooth s':>9s} {'plan s':>7s} {'plan/smooth':>11s} {'us/pt/method':>12s}")
    for name in names:
        path = read_cc_csv(ROOT / "surfaces" / f"{name}_path.csv")
        surf = load_surface(_mesh_file(name))
        t0 = time.perf_counter()
        res = smooth(path, surf, machine, CUTTER, lead_range=LEAD, tilt_range=TILT, method="nlp", tolerance=TOL)
        t_smooth = time.perf_counter() - t0
        feed = res.inputs["feed"]
        t0 = time.perf_counter()
        plans = {m: plan_method(machine, res.methods[m], feed) for m in METHODS}
        t_plan = time.perf_counter() - t0
        c = {m: plans[m].cycle_time for m in METHODS}
        n = len(res.methods["none"])

        def share(p, axes_only=False):
            lt = p.limit_time.copy()
            if axes_only:
                lt[CONSTRAINTS.index("feed")] = -1.0
            k = int(np.argmax(lt))
            if lt[k] <= 0:
                return "none"
            return f"{CONSTRAINTS[k]} {100 * p.limit_time[k] / p.cycle_time:.0f}%"

        limits = " | ".join(share(plans[m]) for m in METHODS)
        axis_limits = " | ".join(share(plans[m], axes_only=True) for m in METHODS)
        print(f"{name:>8s} {n:7d} {len(plans['nlp'].row_ids):5d} {c['none']:8.3f} {c['spline']:9.3f} "
              f"{c['nlp']:8.3f} {100 * (c['nlp'] / c['none'] - 1):+8.2f}% {100 * (c['nlp'] / c['spline'] - 1):+9.2f}% "
              f"{limits:>58s} {t_smooth:9.2f} {t_plan:7.2f} {t_plan / t_smooth:11.3f} "
              f"{1e6 * t_plan / (3 * n):12.1f}")
        print(f"{'':>8s} axis that limits most (share of the cycle): {axis_limits}")
        over = {m: int(plans[m].jerk_over.sum()) for m in METHODS}
        print(f"{'':>8s} jerk (finite differences at the points, not enforced): samples over jmax "
              f"none {over['none']}, spline {over['spline']}, nlp {over['nlp']}; nlp peak A "
              f"{np.degrees(plans['nlp'].jerk_peak[3]):.3g} deg/s^3, B {np.degrees(plans['nlp'].jerk_peak[4]):.3g}")


def wave_row(n: int, spacing: float = 0.1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A long synthetic row: tip on a wave, A and B swinging (+-20, +-25 deg); q, tip, feed."""
    machine = load_machine(None)
    s = np.arange(n) * spacing
    tip = np.column_stack([s, 5 * np.sin(s / 7), 3 * np.cos(s / 11)])
    A, B = np.radians(20 * np.sin(s / 9)), np.radians(25 * np.cos(s / 13))
    q = np.column_stack([machine.linear_axes(tip, A, B), A, B])
    feed = np.where((s // 50) % 2 == 0, 3000.0, 1500.0)
    return q, tip, feed


def bench_scaling(sizes: list[int]) -> None:
    machine = load_machine(None)
    print("== scaling: one synthetic row (wave, 0.1 mm spacing), plan_row wall time (best of 3; 1 run at >= 100k)")
    print(f"{'points':>8s} {'total s':>8s} {'us/point':>9s} {'cycle s':>8s}")
    for n in sizes:
        q, tip, feed = wave_row(n)
        best = np.inf
        for _ in range(1 if n >= 100_000 else 3):
            t0 = time.perf_counter()
            plan = plan_row(machine, q, tip, feed)
            best = min(best, time.perf_counter() - t0)
        print(f"{n:8d} {best:8.3f} {1e6 * best / n:9.1f} {plan.cycle_time:8.2f}")


# ----------------------------------------------------------------------------------------------
# the hand-written alternative: same discretisation as toppra's TOPP-RA (interpolation scheme)
def plan_row_toppra(machine, q, tip, feed):
    rp = row_path(machine, q, tip, feed)
    return plan_from_speed(rp, toppra_speed(rp))


def bench_solvers(sizes: list[int]) -> None:
    machine = load_machine(None)
    forward_backward(*(np.linspace(0, 1, 4), np.ones((4, 5)), np.zeros((4, 5)), np.ones(5), np.ones(4)))  # jit
    print("== solvers: toppra (TOPP-RA, seidel) vs hand-written forward-backward pass (numba), same spline and "
          "gridpoints")
    # (a) closed form: a straight line along X at 6000 mm/min, X amax 3000 mm/s^2, 0.5 mm spacing
    n, L, F = 201, 100.0, 6000.0
    x = np.linspace(0, L, n)
    tip = np.column_stack([x, np.zeros((n, 2))])
    q = np.column_stack([tip + machine.pivot * np.array([0, 0, 1.0]), np.zeros((n, 2))])
    v, a = F / 60, machine.limits["X"].amax
    sa = v * v / (2 * a)
    exact = np.where(x < sa, np.sqrt(2 * x / a), np.where(x > L - sa, L / v + v / a - np.sqrt(2 * (L - x) / a),
                                                         v / a + (x - sa) / v))
    for label, fn in (("toppra", plan_row_toppra), ("forward-backward", plan_row)):
        p = fn(machine, q, tip, np.full(n, F))
        print(f"  trapezoid (exact cycle {L / v + v / a:.6f} s), {label:>16s}: cycle error "
              f"{p.cycle_time - (L / v + v / a):+.2e} s, max |t - exact| {np.abs(p.t_plan - exact).max():.2e} s")
    print(f"{'points':>8s} {'toppra s':>9s} {'us/pt':>7s} {'f-b s':>7s} {'us/pt':>7s} {'speed-up':>8s} "
          f"{'cycle toppra':>12s} {'cycle f-b':>10s} {'diff':>9s} {'fd v/vmax':>9s} {'fd a/amax':>9s}")
    vmax = np.array([machine.limits[k].vmax for k in AXES])
    amax = np.array([machine.limits[k].amax for k in AXES])
    for n in sizes:
        q, tip, feed = wave_row(n)
        rp = row_path(machine, q, tip, feed)
        t0 = time.perf_counter()
        sd_t = toppra_speed(rp)
        t_toppra = time.perf_counter() - t0
        xmax = _xmax(rp)
        t0 = time.perf_counter()
        sd_f = forward_backward(rp.s, rp.dq, rp.ddq, rp.amax, xmax)
        t_fb = time.perf_counter() - t0
        pt, pf = plan_from_speed(rp, sd_t), plan_from_speed(rp, sd_f)
        worst_v = worst_a = 0.0
        for p in (pt, pf):
            vv, aa, _ = finite_difference_rates(q, p.t_plan)
            worst_v = max(worst_v, float((np.abs(vv).max(0) / vmax).max()))
            worst_a = max(worst_a, float((np.abs(aa).max(0) / amax).max()))
        print(f"{n:8d} {t_toppra:9.3f} {1e6 * t_toppra / n:7.1f} {t_fb:7.4f} {1e6 * t_fb / n:7.2f} "
              f"{t_toppra / t_fb:7.0f}x {pt.cycle_time:12.4f} {pf.cycle_time:10.4f} "
              f"{pf.cycle_time / pt.cycle_time - 1:+9.1e} {worst_v:9.5f} {worst_a:9.5f}")
    print("  (solver time only: spline, derivatives and the plan's bookkeeping are shared and not counted here)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", nargs="?", default="all", choices=("all", "samples", "scaling", "solvers"))
    ap.add_argument("--names", default=",".join(_samples()))
    ap.add_argument("--sizes", default="1000,10000,100000")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    if args.what in ("all", "samples"):
        bench_samples(args.names.split(","))
    if args.what in ("all", "scaling"):
        bench_scaling(sizes)
    if args.what in ("all", "solvers"):
        bench_solvers(sizes)


if __name__ == "__main__":
    main()
