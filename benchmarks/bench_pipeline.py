"""Issue 2 figures: per shipped sample and method, Gamma and its reduction, peaks, clearance and
limit violations; NLP scaling on one row of 1k / 10k / 100k points; the whole demo pipeline.

    python benchmarks/bench_pipeline.py [--samples blade,saddle,mould] [--sizes 1000,10000,100000]
                                        [--skip-samples] [--skip-scaling]

Settings (the demo's): toroidal cutter R = 4, r = 1 mm (diameter 10), lead 2:20 deg, tilt
-15:15 deg, preferred lead 11 deg / tilt 0 (the window middles), the default AB head
(A, B +-100 deg, 60 deg/s, 300 deg/s^2), feed from the path CSV (2000 mm/min).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camsmooth.geometry.cutter import ToroidalCutter  # noqa: E402
from camsmooth.machine.kinematics import load_machine  # noqa: E402
from camsmooth.smoothing.nlp import RowNLP, gamma, spline_row  # noqa: E402
from camsmooth.smoothing.orientation import axis_from_lead_tilt, local_frames  # noqa: E402
from camsmooth.smoothing.pipeline import smooth  # noqa: E402

LEAD = tuple(np.radians([2.0, 20.0]))
TILT = tuple(np.radians([-15.0, 15.0]))
CUTTER = ToroidalCutter(R=4.0, r=1.0)


def bench_samples(names: list[str]) -> bool:
    ok_all = True
    for name in names:
        path, mesh = ROOT / "surfaces" / f"{name}_path.csv", ROOT / "surfaces" / f"{name}.ply"
        t0 = time.perf_counter()
        res = smooth(path, mesh, None, CUTTER, lead_range=LEAD, tilt_range=TILT, method="nlp")
        total = time.perf_counter() - t0
        n = len(res.result)
        rows = len(np.unique(res.result.rows))
        print(f"\n== sample {name}: {rows} rows, {n} points, whole smooth() {total:.1f} s "
              f"({n / total:.0f} points/s)")
        g = {k: r.metrics["gamma"] for k, r in res.methods.items()}
        head = ("method", "Gamma", "vs none", "vs spline", "peak|A''|", "peak|B''|", "min delta", "lifted", "time s")
        print("{:7s} {:>10s} {:>8s} {:>9s} {:>9s} {:>9s} {:>10s} {:>6s} {:>7s}  violations".format(*head))
        for k, r in res.methods.items():
            m = r.metrics
            viol = {a: b for a, b in m["violations"].items() if b}
            print(f"{k:7s} {m['gamma']:10.4g} {1 - g[k] / g['none']:8.1%} {1 - g[k] / g['spline']:9.1%} "
                  f"{m['peak_A_acc']:9.3g} {m['peak_B_acc']:9.3g} {m['min_delta']:10.5f} {m['lifted_points']:6d} "
                  f"{m['runtime_s']:7.2f}  {viol or 'none'}")
        r = res.methods["nlp"]
        checks = {
            "Gamma -90% vs none": g["nlp"] <= 0.1 * g["none"],
            "Gamma -50% vs spline": g["nlp"] <= 0.5 * g["spline"],
            "A/B travel, velocity, acceleration met at every sample": all(
                r.metrics["violations"][f"{a} {c}"] == 0 for a in "AB" for c in ("travel", "velocity", "acceleration")),
            "lead and tilt inside their windows": r.metrics["violations"]["lead window"] == 0
            and r.metrics["violations"]["tilt window"] == 0,
            "no delta below -0.001 mm": r.metrics["min_delta"] >= -1e-3,
            "no lift needed": r.metrics["lifted_points"] == 0,
        }
        for k, v in checks.items():
            print(f"  [{'PASS' if v else 'FAIL'}] {k}")
        ok_all &= all(checks.values())
    return ok_all


def synthetic_row(n: int, length_mm: float = None) -> tuple[np.ndarray, ...]:
    """One row on z = 5 sin(x / 10) (mm), CC spacing 0.4 mm, feed 2000 mm/min, with the
    per-point lead jittered +-3 deg as a CAM system's raw axes can be."""
    x = np.arange(n) * 0.4
    z, dz = 5 * np.sin(x / 10), 0.5 * np.cos(x / 10)
    nrm = np.stack([-dz, 0 * x, np.ones_like(x)], 1)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    fr = local_frames(nrm, np.stack([np.ones_like(x), 0 * x, dz], 1))
    rng = np.random.default_rng(0)
    T = axis_from_lead_tilt(np.radians(11 + 3 * rng.uniform(-1, 1, n)), np.zeros(n), fr)
    p = np.stack([x, 0 * x, z], 1)
    t = np.concatenate([[0], np.cumsum(np.linalg.norm(np.diff(p, axis=0), axis=1) / (2000 / 60))])
    return t, fr, T


def bench_scaling(sizes: list[int], repeats: int = 3) -> None:
    print("\n== NLP scaling on one row (CasADi + IPOPT/MUMPS; structured derivatives, constraint screening)")
    print("init: RowNLP(machine, N) (kinematics and derivative pieces); solve: RowNLP.solve, including the "
          "IPOPT builds of its screening rounds")
    print(f"{'points':>8s} {'init s':>7s} {'solve s best/median':>20s} {'total s':>8s} {'iters':>6s} "
          f"{'rounds':>6s} {'NLP rows':>14s} {'points/s':>9s} {'Gamma none':>11s} {'Gamma nlp':>10s} status")
    m = load_machine()
    lw, tw = np.array(LEAD), np.array(TILT)
    for n in sizes:
        t, fr, T = synthetic_row(n)
        ik = m.solve_row(T)
        As, Bs = spline_row(ik.A, ik.B, t)
        times = []
        for _ in range(repeats if n <= 20000 else 1):
            nlp = RowNLP(m, n)
            A, B, st = nlp.solve(t, fr, As, Bs, np.tile(lw, (n, 1)), np.tile(tw, (n, 1)))
            times.append(st.time_s)
        best, med = min(times), float(np.median(times))
        print(f"{n:8d} {nlp.build_s:7.3f} {best:11.3f} / {med:6.3f} {nlp.build_s + med:8.3f} {st.iterations:6d} "
              f"{st.rounds:6d} {st.rows:6d}/{st.total_rows:<7d} {n / (nlp.build_s + med):9.0f} "
              f"{gamma(T, t):11.4g} {gamma(m.tool_axis_np(A, B), t):10.4g} {st.status}")


def bench_demo() -> None:
    import tempfile

    from camsmooth.io.output import write_gcode, write_result_csv
    from camsmooth.report.smoothing import write_report

    print("\n== whole demo pipeline (blade): smooth + CSV + G-code + report")
    t0 = time.perf_counter()
    res = smooth(ROOT / "surfaces" / "blade_path.csv", ROOT / "surfaces" / "blade.ply", None, CUTTER,
                 lead_range=LEAD, tilt_range=TILT, method="nlp")
    t1 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        write_result_csv(Path(d) / "o.csv", res)
        write_gcode(Path(d) / "o.nc", res, res.machine, res.cutter, 2000.0)
        write_report(res, Path(d) / "report")
    t2 = time.perf_counter()
    n = len(res.result)
    print(f"smooth {t1 - t0:.1f} s, outputs + report {t2 - t1:.1f} s, total {t2 - t0:.1f} s "
          f"for {n} points = {n / (t2 - t0):.0f} points/s")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default=",".join(sorted(p.name[:-9] for p in (ROOT / "surfaces").glob("*_path.csv"))))
    ap.add_argument("--sizes", default="1000,10000,100000")
    ap.add_argument("--skip-samples", action="store_true")
    ap.add_argument("--skip-scaling", action="store_true")
    ap.add_argument("--skip-demo", action="store_true")
    a = ap.parse_args()
    ok = True
    if not a.skip_samples:
        ok = bench_samples([s for s in a.samples.split(",") if s])
    if not a.skip_scaling:
        bench_scaling([int(s) for s in a.sizes.split(",")])
    if not a.skip_demo:
        bench_demo()
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
