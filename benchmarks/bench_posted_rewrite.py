"""smooth of a real posted program, written back (camsmooth.post.rewrite): LinuxCNC's
impeller demo (tests/data/posted/impeller-7bl-xyzac.ngc, M428 TCP, G93, an unwound C up to
400 deg), one operation smoothed on a synthetic surface made for it.

The demo ships without its part, so the surface is a ribbon per row through the program's own
tool tips: +-W mm across the feed direction, normal to the feed, touched by a ball of radius R at
each tip (the ball's centre tip + R axis). Its normal is not the real part's (where the CAM tilts
the tool along the feed, the window --lead keeps the smoothed axis near the ribbon's normal
instead), so the figures say how the rewrite behaves on a real program's text (its lines, modal
words, G93 words, unwound C), not what smoothing buys on this part.

Run:  python benchmarks/bench_posted_rewrite.py [--operation "Operation 3"] [--method spline]
Prints: the lines in and out, the lines changed (all of them cutting blocks?), the non-cutting
lines kept in order, rs274's exit status and errors, the largest tip and axis differences read
back against the smoothed result, the C range written, the time.
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from camsmooth.cli.main import main  # noqa: E402
from camsmooth.machine.kinematics import load_machine  # noqa: E402
from camsmooth.post import load_program  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
PROGRAM = ROOT / "tests" / "data" / "posted" / "impeller-7bl-xyzac.ngc"
MACHINE = """[machine]
name = "LinuxCNC xyzac-trt (impeller demo)"
kind = "AC-table"
table_centre = [0.0, 0.0, 0.0]

[axis.A]
min = -120.0
max = 120.0
vmax = 60.0
amax = 300.0

[axis.C]
vmax = 180.0
amax = 900.0

[post]
dialect = "linuxcnc"
mode = "tcp"
"""


def ribbon(program, operation: str, width: float, ball: float):
    """A trimesh ribbon per row of ``operation`` through the ball's contacts (module docstring)."""
    import trimesh

    tp = next(t for t in program.toolpaths if t.name == operation)
    V, F = [], []
    for sl in program.row_slices():
        if not tp.start <= sl.start < tp.stop:
            continue
        tip, ax = program.tip[sl], program.axis[sl]
        d = np.gradient(tip, axis=0)
        d /= np.linalg.norm(d, axis=1)[:, None]
        side = np.cross(ax, d)
        side /= np.linalg.norm(side, axis=1)[:, None]
        n = np.cross(d, side)
        n /= np.linalg.norm(n, axis=1)[:, None]
        contact = tip + ball * (ax - n)
        base = len(V)
        for c, s in zip(contact, side, strict=True):
            V += [c - width * s, c + width * s]
        for i in range(len(tip) - 1):
            a, b, c, e = (base + 2 * i + k for k in range(4))
            F += [[a, c, b], [b, c, e]]
    return trimesh.Trimesh(np.asarray(V), np.asarray(F), process=False)


def run(operation: str, method: str, width: float, ball: float) -> None:
    t0 = time.perf_counter()
    tmp = Path(tempfile.mkdtemp(prefix="bench_rewrite_"))
    mfile = tmp / "machine.toml"
    mfile.write_text(MACHINE)
    machine = load_machine(str(mfile))
    prog = load_program(PROGRAM, machine=machine, machine_given=True)
    mesh = tmp / "ribbon.stl"
    ribbon(prog, operation, width, ball).export(mesh)
    out, csv = tmp / "out.ngc", tmp / "result.csv"
    code = main(["smooth", str(PROGRAM), "--operations", operation, "--surface", str(mesh), "--machine", str(mfile),
                 "--cutter-radius", "0", "--corner-radius", str(ball), "--lead", "0:10", "--tilt", "-5:5",
                 "--method", method, "-o", str(csv), "--gcode", str(out), "--quiet"])
    print(f"smooth exit status {code}")
    a, b = PROGRAM.read_text().splitlines(), out.read_text().splitlines()
    changed = [(x, y) for x, y in zip(a, b, strict=False) if x != y]
    cut = re.compile(r"\s*G0?1\s")
    print(f"lines in {len(a)}, out {len(b)}; changed {len(changed)}, all cutting blocks: "
          f"{all(cut.match(x) and cut.match(y) for x, y in changed)}")
    it = iter(b)
    kept = [x for x in a if not cut.match(x)]
    print(f"non-cutting lines {len(kept)} kept in order: {all(any(x == y for y in it) for x in kept)}")
    if shutil.which("rs274"):
        src = tmp / "rs.ngc"
        src.write_text(re.sub(r"\bM42[89]\b", "", out.read_text()))
        run_ = subprocess.run(["rs274", "-g", str(src), str(tmp / "canon.txt")], capture_output=True, text=True,
                              stdin=subprocess.DEVNULL, timeout=600, check=False)
        errors = len(re.findall(r"error", run_.stdout + run_.stderr, re.I))
        print(f"rs274 exit status {run_.returncode}, error lines {errors}")
    import polars as pl

    res = pl.read_csv(csv)
    back = load_program(out, machine=machine, machine_given=True)
    tips = res.select(["clx", "cly", "clz"]).to_numpy()
    axes = res.select(["i", "j", "k"]).to_numpy()
    dist = np.linalg.norm(back.tip[None, :, :] - tips[:, None, :], axis=2)
    k = dist.argmin(axis=1)
    ang = np.degrees(np.arccos(np.clip(np.sum(back.axis[k] * axes, axis=1), -1, 1)))
    c_words = [float(m.group(1)) for ln in b if ln.startswith("G01 ") for m in [re.search(r"C(-?[\d.]+)", ln)] if m]
    print(f"smoothed points {len(res)}: read back tip max {dist[np.arange(len(k)), k].max() * 1e3:.3f} um, "
          f"axis max {ang.max():.2e} deg; C words written {min(c_words):.1f} .. {max(c_words):.1f} deg")
    print(f"time {time.perf_counter() - t0:.1f} s ({tmp})")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--operation", default="Operation 3")
    ap.add_argument("--method", default="spline", choices=("none", "spline", "nlp"))
    ap.add_argument("--width", type=float, default=1.5, help="ribbon half width (mm)")
    ap.add_argument("--ball", type=float, default=0.2, help="ball radius (mm)")
    args = ap.parse_args()
    run(args.operation, args.method, args.width, args.ball)
