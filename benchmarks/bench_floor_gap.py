"""Where the distance between LinuxCNC's executed time and its floor comes from (machine mode, the
planner model camsmooth.controller.linuxcnc; no LinuxCNC run).

1. Block lengths: chains of straight segments run on the planner model, each segment's floor
   sqrt(2 L / a) (least_row_times' per-block term), printed as model time / sum of the floors:
   equal segments, two lengths alternating, a slow ramp of lengths. The parabolic blend lets the
   next segment start only when the current one is below a blend speed set by the shorter of the
   two, so a chain of unequal neighbours costs more than its floor.
2. The tolerance: the floor lets a block use the whole tolerance; camsmooth's blocks keep
   BLOCK_TOLERANCE_SHARE of it (the rest for the blends and the model's distance from LinuxCNC).
   Per row of the nlp program on a sample (bench_controller.smoothed): predicted / floor at the
   whole tolerance and / floor at the blocks' share.
3. Block ends between the points (``--spline 2,4``): each row's joints resampled on a cubic spline
   through its points (K candidate ends per interval), the tips their forward kinematics, placed
   and predicted again (camsmooth.smoothing.evaluate.time_law): predicted / floor of the original
   points.
4. The best any placement through the points reaches on the planner model (``--best``): blocks
   that may use the WHOLE tolerance (as the floor's) and blends left unchecked (no servo-cycle
   tolerance), the planner's dynamic programme over the block ends (Planner.block_ends), then a
   local search on the model's executed time (drop, add or move any block end by one point, until
   no move helps), then each block's G93 time made 1.3x or 2x longer where that runs the row sooner
   (a slower block can let its neighbour blend sooner). What it prints is an estimate of the best
   any program through these points reaches on LinuxCNC 2.9, not a bound; the model is within
   0.2-2% of the headless LinuxCNC per row (bench_controller.py).

    .venv/bin/python benchmarks/bench_floor_gap.py [--samples dome,wave] [--rows 3] [--spline 2,4] [--best]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_controller import TOLERANCE, smoothed  # noqa: E402
from scipy.interpolate import CubicSpline  # noqa: E402

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM  # noqa: E402
from camsmooth.controller import planner_for  # noqa: E402
from camsmooth.controller.blocks import (  # noqa: E402
    BLOCK_TOLERANCE_SHARE,
    MAX_BLOCK_POINTS,
    block_reach,
    row_entry,
    tool_tips,
)
from camsmooth.controller.linuxcnc import LinuxCNCPlanner, Segments, least_row_times  # noqa: E402
from camsmooth.smoothing.evaluate import time_law  # noqa: E402

ACC = 500.0  # mm/s^2 of the synthetic chains


def chain_ratio(lengths: np.ndarray, acc: float = ACC) -> float:
    """Planner-model time of a chain of collinear segments (mm) at ``acc`` (mm/s^2), from rest to
    rest, over the sum of their floors sqrt(2 L / a)."""
    m = len(lengths)
    seg = Segments(length=np.asarray(lengths, float), reqvel=np.full(m, 1e4), maxvel=np.full(m, 1e4),
                   acc=np.full(m, acc), rapid=np.zeros(m, bool), pure_rotary=np.zeros(m, bool),
                   stop_after=np.r_[np.zeros(m - 1, bool), True], direction=np.tile([1.0, 0.0, 0.0], (m, 1)))
    return float(LinuxCNCPlanner().run(seg).end[-1] / np.sqrt(2.0 * np.asarray(lengths) / acc).sum())


def best_through_points(machine, q: np.ndarray, tip: np.ndarray, t_opt: np.ndarray) -> tuple[float, float, float]:
    """One row (q (n, 5) X Y Z mm A B rad, tip (n, 3) mm, t_opt (n,) s): the planner model's time
    (s) of the blocks its dynamic programme picks within the whole TOLERANCE (blends unchecked), after
    the local search over block ends, and after the search over slower G93 block times (part 4)."""
    planner = planner_for(machine, TOLERANCE, np.zeros(len(q)), q)
    ok = block_reach(machine, np.zeros(len(q)), q, tip, TOLERANCE)
    entry_q, entry_time = row_entry(machine, q[0], DEFAULT_SAFE_HEIGHT_MM, 2000.0)

    def took(k: np.ndarray, bt: np.ndarray | None = None) -> float:
        run, _ = planner.row_run(machine, q[k], np.diff(t_opt[k]) if bt is None else bt, entry_q, entry_time)
        return float(run.end[-1] - run.end[0])

    def allowed(k: np.ndarray) -> bool:
        steps = np.diff(k)
        return bool(np.all(steps <= MAX_BLOCK_POINTS) and np.all(ok[k[:-1], steps - 1]))

    k = np.asarray(planner.block_ends(machine, q, t_opt, ok, entry_q, entry_time))
    dp = best = took(k)
    better = True
    while better:
        better = False
        moves = [np.delete(k, i) for i in range(1, len(k) - 1)]
        moves += [np.sort(np.r_[k, j]) for j in np.setdiff1d(np.arange(1, len(q) - 1), k)]
        for i in range(1, len(k) - 1):
            for step in (-1, 1):
                kk = k.copy()
                kk[i] += step
                if kk[i - 1] < kk[i] < kk[i + 1]:
                    moves.append(kk)
        for kk in moves:
            if allowed(kk) and (t := took(kk)) < best - 1e-4:
                k, best, better = kk, t, True
    bt = np.diff(t_opt[k])
    slow = best
    for i in range(len(bt)):
        for factor in (1.3, 2.0):
            b2 = bt.copy()
            b2[i] *= factor
            if (t := took(k, b2)) < slow - 1e-4:
                bt, slow = b2, t
    return dp, best, slow


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", default="dome,wave")
    ap.add_argument("--rows", type=int, default=3)
    ap.add_argument("--spline", default="", help="candidate block ends per point interval, e.g. 2,4 (part 3)")
    ap.add_argument("--best", action="store_true", help="the best placement through the points on the model (part 4)")
    args = ap.parse_args()
    print(f"== 1. chains of 60 segments at {ACC:g} mm/s^2: model time / sum of the per-block floors")
    for label, pattern in (("equal 0.5 mm", [0.5]), ("equal 2 mm", [2.0]), ("0.5 / 0.75 alternating", [0.5, 0.75]),
                           ("0.5 / 1 alternating", [0.5, 1.0]), ("0.5 / 2 alternating", [0.5, 2.0]),
                           ("ten 0.5 then ten 1", [0.5] * 10 + [1.0] * 10)):
        print(f"  {label:26s} {chain_ratio(np.tile(pattern, 60 // len(pattern))):.3f}")
    print(f"  {'ramp 0.5 -> 2 mm':26s} {chain_ratio(np.linspace(0.5, 2.0, 60)):.3f}")
    print(f"== 2. nlp rows, tolerance {TOLERANCE * 1e3:g} um: predicted / floor (whole tolerance) and "
          f"/ floor ({BLOCK_TOLERANCE_SHARE} of it, the blocks' share)")
    for sample in args.samples.split(","):
        machine, _, res = smoothed(sample, args.rows, ["nlp"])
        r = res.methods["nlp"]
        q = np.column_stack([r.xyz, r.rotary.values])
        feed = np.full(len(q), 2000.0)
        whole = least_row_times(machine, r.rows, q, r.cl, feed, TOLERANCE)
        share = least_row_times(machine, r.rows, q, r.cl, feed, TOLERANCE * BLOCK_TOLERANCE_SHARE)
        for k, row in enumerate(r.controller.row_ids):
            pred = r.controller.row_cycle_time[k]
            print(f"  {sample:6s} row {row:3d}: predicted {pred:7.3f} s, floor {whole[k]:7.3f} s "
                  f"({pred / whole[k]:.3f}x), floor at the share {share[k]:7.3f} s ({pred / share[k]:.3f}x), "
                  f"{int(r.controller.keep[r.rows == row].sum()) - 1} blocks")
        for k in [int(x) for x in args.spline.split(",") if x]:
            rows = np.unique(r.rows)
            dense = [CubicSpline(np.arange(int((r.rows == row).sum())), q[r.rows == row], axis=0)(
                np.linspace(0.0, (r.rows == row).sum() - 1.0, int((r.rows == row).sum() - 1) * k + 1)) for row in rows]
            qd = np.vstack(dense)
            rd = np.concatenate([np.full(len(d), row) for d, row in zip(dense, rows, strict=True)])
            law = time_law(machine, rd, qd, tool_tips(machine, qd), np.full(len(qd), 2000.0), tolerance=TOLERANCE)
            pred = law.controller.row_cycle_time
            print(f"  {sample:6s} {k} ends per interval: predicted {np.round(pred, 3)} s, "
                  f"{np.round(pred / whole, 3)}x the floor of the points, {law.controller.blocks} blocks")
        if args.best:
            print(f"== 4. {sample}: the best placement through the points on the model, the whole tolerance, "
                  "blends unchecked: / floor")
            for k, row in enumerate(r.controller.row_ids):
                sel = r.rows == row
                dp, local, slow = best_through_points(machine, q[sel], r.cl[sel], r.plan.t_plan[sel])
                print(f"  {sample:6s} row {row:3d}: dynamic programme {dp / whole[k]:.3f}x, local search "
                      f"{local / whole[k]:.3f}x, slower G93 blocks {slow / whole[k]:.3f}x (camsmooth's program "
                      f"{r.controller.row_cycle_time[k] / whole[k]:.3f}x)")


if __name__ == "__main__":
    main()
