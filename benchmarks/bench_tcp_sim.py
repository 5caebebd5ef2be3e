"""TCP mode against machine mode on LinuxCNC itself (an experiment): the dome's rows on its A/C
trunnion, the same blocks and block times written twice and run on the headless simulation.

- machine mode: camsmooth's LinuxCNC program (joints, G93), trivkins (bench_controller.py);
- TCP mode ("tcp"): the same blocks written in TCP mode (tool tips and A C, ``M428`` on, F = the
  tip feed that gives each block the same time); "tcp chord": TCP blocks of their own, the longest
  whose skipped tips stay within BLOCK_TOLERANCE_SHARE of the tolerance of the chord (the tip path
  of a TCP block; camsmooth.controller.tcp.chord_reach), timed by the time-optimal law; both on
  LinuxCNC's own ``xyzac-trt-kins`` switchkins
  kinematics, configured as its sample ``xyzac-trt.ini`` does: ``sparm=identityfirst``, the
  shipped ``M428``/``M429`` remap subroutines (``HAL_PIN_VARS = 1``), ``motion.analog-out-03``
  netted to ``motion.switchkins-type``, the rotation point at the machine file's table centre
  and no offsets (``x/y/z-rot-point``, offsets 0: camsmooth.controller.linuxcnc_sim.trt_config).
  camsmooth's own TCP-mode program (its blocks and held F words, camsmooth.controller.tcp) is
  what ``bench_controller.py --mode tcp`` runs.

Per row and mode: the executed cut time (first to last servo sample of the row's cut blocks), the
tool tip's largest distance (forward kinematics of the recorded joints) from the programmed tips'
polyline, and the joints' largest velocity and acceleration over the machine file's limits
(finite differences of the recorded joints at 1 ms; LinuxCNC limits the world coordinates in TCP
mode, not the joints: LinuxCNC #1738).

    .venv/bin/python benchmarks/bench_tcp_sim.py [--rows 3] [--keep DIR]

Measured (3 dome rows, 2026-11-27): machine 2.163 / 2.163 / 2.531 s, tip 4.04 um; tcp (machine
mode's blocks) 8.7 / 8.7 / 2.1% slower and the tip 14.06 um off (the chords of blocks chosen for
joint interpolation: exactly their skipped tips' distance from the chord); tcp chord 3.3 / 3.3 /
14.5% faster than machine mode, tip 4.31 um, joints within 0.20 of their velocity limits and at
1.00 of their acceleration limits (machine mode: 1.08 by these finite differences).

Needs linuxcnc-uspace and LinuxCNC's sample configurations (the remap subroutines).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from bench_controller import TOLERANCE, smoothed  # noqa: E402

from camsmooth.controller.blocks import BLOCK_TOLERANCE_SHARE, tip_deviation  # noqa: E402
from camsmooth.controller.linuxcnc_sim import camsmooth_joints, row_samples, simulate, trt_missing  # noqa: E402
from camsmooth.controller.tcp import chord_reach  # noqa: E402
from camsmooth.machine.kinematics import PostConfig, axis_limits  # noqa: E402
from camsmooth.smoothing.posting import write_gcode  # noqa: E402

FEED = 2000.0


def per_row(machine, r, text: str, run) -> dict[int, dict]:
    """Executed time, tip error and joint peaks per row of a simulation run."""
    joints = camsmooth_joints(machine, run.joints)
    tip, _ = machine.tool_pose_np(joints[:, 3], joints[:, 4], joints[:, 0], joints[:, 1], joints[:, 2])
    vmax, amax, _ = axis_limits(machine)
    dt = run.servo_period
    out = {}
    for row, idx in row_samples(text, run).items():
        sel = r.rows == row
        k = np.arange(idx[0], idx[-1] + 1)
        q = joints[max(k[0] - 1, 0):k[-1] + 2]
        v = np.abs(np.diff(q, axis=0)) / dt
        a = np.abs(np.diff(q, 2, axis=0)) / dt ** 2
        out[row] = dict(time=len(k) * dt, tip_um=1e3 * float(tip_deviation(tip[k], r.cl[sel]).max()),
                        v=float((v / vmax).max()), a=float((a / amax).max()))
    return out


def chord_blocks(r):
    """The MethodResult with TCP blocks of its own (module docstring, "tcp chord")."""
    keep = np.zeros(len(r.rows), bool)
    ok = chord_reach(r.rows, r.cl, BLOCK_TOLERANCE_SHARE * TOLERANCE)
    for rid in np.unique(r.rows):
        sel = np.flatnonzero(r.rows == rid)
        reach = ok[sel].sum(axis=1)
        i = 0
        keep[sel[0]] = True
        while i < len(sel) - 1:
            i = min(i + int(reach[i]), len(sel) - 1)
            keep[sel[i]] = True
    t = r.plan.t_plan
    bt = np.zeros(len(t))
    for rid in np.unique(r.rows):
        k = np.flatnonzero((r.rows == rid) & keep)
        bt[k[1:]] = np.diff(t[k])
    return dataclasses.replace(r, controller=dataclasses.replace(r.controller, keep=keep, block_time=bt))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=3)
    ap.add_argument("--keep", type=Path, default=None)
    args = ap.parse_args()
    machine, cutter, res = smoothed("dome", args.rows, ["nlp"])
    missing = trt_missing(machine)
    if missing:
        sys.exit(f"bench_tcp_sim: {missing}")
    r = res.methods["nlp"]
    got = {}
    with tempfile.TemporaryDirectory() as tmp:
        for mode in ("machine", "tcp", "tcp chord"):
            m = dataclasses.replace(machine, post=PostConfig(dialect="linuxcnc", mode=mode.split()[0]))
            ngc = Path(tmp) / f"dome_{mode.replace(' ', '_')}.ngc"
            prog = chord_blocks(r) if mode == "tcp chord" else r
            write_gcode(ngc, prog, m, cutter, FEED, tolerance=TOLERANCE)
            keep = args.keep / mode.replace(" ", "_") if args.keep else None
            run = simulate(ngc, machine, keep=keep, timeout=300, trt=mode != "machine")
            got[mode] = per_row(machine, r, ngc.read_text(), run)
            got[mode]["blocks"] = {int(x): int(prog.controller.keep[r.rows == x].sum() - 1) for x in np.unique(r.rows)}
    print(f"LinuxCNC simulation, dome rows on {machine.name}, tolerance {TOLERANCE} mm; tcp: machine mode's blocks "
          "and times in TCP mode, tcp chord: TCP blocks of its own; joint peaks over the machine file's limits")
    print(f"{'mode':9s} {'row':>4s} {'blocks':>6s} {'executed s':>10s} {'/machine':>8s} {'tip um':>7s} {'v/vmax':>7s} "
          f"{'a/amax':>7s}")
    for mode, rows in got.items():
        blocks = rows.pop("blocks")
        for row in sorted(rows):
            x, base = rows[row], got["machine"][row]["time"]
            print(f"{mode:9s} {row:4d} {blocks[row]:6d} {x['time']:10.3f} {x['time'] / base:8.3f} {x['tip_um']:7.2f} "
                  f"{x['v']:7.2f} {x['a']:7.2f}")


if __name__ == "__main__":
    main()
