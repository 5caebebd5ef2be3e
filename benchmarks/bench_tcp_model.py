"""TCP mode against machine mode, on camsmooth's model of LinuxCNC's planner (the experiment that
camsmooth.controller.tcp grew from: the library's TCP mode places its blocks by the model, holds
the F words per row and models the last block's stop at the whole acceleration).

In TCP mode (M428 with LinuxCNC's trt switchkins kinematics) the program gives the tool tip and
the rotary axes; LinuxCNC's planner plans those world coordinates with the [AXIS_*] limits and
the tip feed (G94), and the kinematics turns every servo cycle's world position into joints,
whose velocity and acceleration nobody limits (LinuxCNC #1738). The tool tip then moves on the
chord between two programmed tips, so a block may skip the points whose tips lie within the
tolerance of that chord (no pivot lever bends the block).

This script does NOT run LinuxCNC (bench_controller.py does in machine mode, bench_tcp_sim.py in
TCP mode on LinuxCNC's xyzac-trt kinematics): it runs the same planner model
(camsmooth.controller.linuxcnc, checked against LinuxCNC in machine mode within 1%) on the world
coordinates, to see what TCP mode could give before building it. On the dome's rows 14-16 it gave
2.103 / 2.103 / 2.183 s in TCP mode; LinuxCNC ran TCP blocks of the same rule (with the
time-optimal law's block times) in 2.091 / 2.091 / 2.165 s. For each
table machine and a few smoothed rows (bench_controller.smoothed) it prints per row:

- machine: the machine-mode program camsmooth writes, the model's time (its prediction);
- tcp free: the TCP-mode program (blocks: the longest whose skipped tips stay within
  BLOCK_TOLERANCE_SHARE of the tolerance of the chord, F = the programmed tip feed), the model's
  time, and the joints' largest velocity and acceleration over the machine file's limits at the
  model's servo cycles (inverse kinematics of the world positions, finite differences at 1 ms);
- tcp held: the same blocks with F lowered (one factor per row, bisection) until every joint is
  within its limits at every servo cycle, and its time;
- the model's largest tip distance from the programmed tips' polyline in TCP mode.

    .venv/bin/python benchmarks/bench_tcp_model.py [--samples dome,blade] [--rows 3]

(blade runs on surfaces/trunnion_ab_machine.toml, dome on its own A/C trunnion.)
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

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM  # noqa: E402
from camsmooth.controller import PATH_TOLERANCE_SHARE, LinuxCNCPlanner  # noqa: E402
from camsmooth.controller.blocks import BLOCK_TOLERANCE_SHARE, tip_deviation  # noqa: E402
from camsmooth.controller.linuxcnc import SERVO_PERIOD_S, canon_segments  # noqa: E402
from camsmooth.controller.tcp import chord_reach  # noqa: E402
from camsmooth.machine.kinematics import axis_limits  # noqa: E402

FEED = 2000.0
MACHINES = {"blade": ROOT / "surfaces" / "trunnion_ab_machine.toml", "dome": None}


def _rotary(r) -> np.ndarray:
    return np.asarray(r.rotary.values, float)


def tcp_row(machine, planner: LinuxCNCPlanner, tip: np.ndarray, rot: np.ndarray, axis0: np.ndarray,
            scale: float) -> dict:
    """One row in TCP mode on the model: blocks, time (s), joint peaks over the limits, tip error."""
    n = len(tip)
    reach = chord_reach(np.zeros(n, int), tip, BLOCK_TOLERANCE_SHARE * TOLERANCE).sum(axis=1)
    k, i = [0], 0
    while i < n - 1:
        i = min(i + int(reach[i]), n - 1)
        k.append(i)
    k = np.asarray(k)
    world = np.column_stack([tip, np.degrees(rot)])
    entry = world[0].copy()
    entry[:3] += DEFAULT_SAFE_HEIGHT_MM * axis0
    m = len(k)
    seg = canon_segments(entry, world[k], np.zeros(m, bool), np.full(m, FEED * scale), np.zeros(m, bool), machine,
                         tolerance=planner.tolerance)
    bt = planner.run(seg)
    pos = bt.positions(entry, world[k])
    first = int(np.searchsorted(np.arange(len(pos)) + 1, bt.end[0] / SERVO_PERIOD_S))  # cut blocks only
    pos = pos[first:]
    q1, q2 = np.radians(pos[:, 3]), np.radians(pos[:, 4])
    joints = np.column_stack([machine.linear_axes(pos[:, :3], q1, q2), q1, q2])
    vmax, amax, _ = axis_limits(machine)
    v = np.abs(np.diff(joints, axis=0)) / SERVO_PERIOD_S
    a = np.abs(np.diff(joints, 2, axis=0)) / SERVO_PERIOD_S ** 2
    return dict(time=float(bt.end[-1] - bt.end[0]), blocks=m - 1, v_ratio=float((v / vmax).max()),
                a_ratio=float((a / amax).max()), tip_um=1e3 * float(tip_deviation(pos[:, :3], tip).max()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", default="dome,blade")
    ap.add_argument("--rows", type=int, default=3)
    args = ap.parse_args()
    print(f"planner model (LinuxCNC 2.9), tolerance {TOLERANCE} mm, feed {FEED:g} mm/min; joint peaks over the "
          "machine file's limits at 1 ms")
    print(f"{'sample':7s} {'row':>4s} {'machine s':>9s} {'blocks':>6s} {'tcp free s':>10s} {'blocks':>6s} "
          f"{'v/vmax':>7s} {'a/amax':>7s} {'tcp held s':>10s} {'F scale':>7s} {'tip um':>6s}")
    for sample in args.samples.split(","):
        machine, _, res = smoothed(sample, args.rows, ["nlp"], MACHINES.get(sample))
        r = res.methods["nlp"]
        rot = _rotary(r)
        planner = LinuxCNCPlanner(tolerance=PATH_TOLERANCE_SHARE * TOLERANCE)
        for j, rid in enumerate(r.controller.row_ids):
            sel = np.flatnonzero(r.rows == rid)
            free = tcp_row(machine, planner, r.cl[sel], rot[sel], r.axis[sel[0]], 1.0)
            held, s = free, 1.0
            if max(free["v_ratio"], free["a_ratio"]) > 1.0:
                lo, hi = 0.02, 1.0
                for _ in range(12):
                    mid = 0.5 * (lo + hi)
                    x = tcp_row(machine, planner, r.cl[sel], rot[sel], r.axis[sel[0]], mid)
                    if max(x["v_ratio"], x["a_ratio"]) <= 1.0:
                        lo, held = mid, x
                    else:
                        hi = mid
                s = lo
                if held is free:
                    held = tcp_row(machine, planner, r.cl[sel], rot[sel], r.axis[sel[0]], lo)
            mblocks = int(r.controller.keep[sel].sum() - 1)
            print(f"{sample:7s} {int(rid):4d} {r.controller.row_cycle_time[j]:9.3f} {mblocks:6d} {free['time']:10.3f} "
                  f"{free['blocks']:6d} {free['v_ratio']:7.2f} {free['a_ratio']:7.2f} {held['time']:10.3f} {s:7.3f} "
                  f"{free['tip_um']:6.2f}")


if __name__ == "__main__":
    main()
