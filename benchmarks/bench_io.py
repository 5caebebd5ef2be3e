"""Reading and writing speed of the file formats (camsmooth.io); prints its figures.

Inputs are generated here: a CC path CSV of N rows written by write_cc_csv ('%.17g', 7-10
columns), a CL CSV with 4-decimal coordinates (as CAM systems write them), an NX-style CLSF with
N GOTO/x,y,z,i,j,k records, and G-code for a program of M points (machine mode, G93, whose block
times need the forward kinematics). Usage: python benchmarks/bench_io.py [N] [M]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from camsmooth.geometry.paths import CCPath
from camsmooth.io.apt import read_apt
from camsmooth.io.ccpath import read_cc_csv, write_cc_csv
from camsmooth.io.clcsv import read_cl_csv
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import load_machine
from camsmooth.smoothing.posting import write_gcode
from camsmooth.smoothing.result import MethodResult


def _timed(fn, *args, **kw):
    t0 = time.perf_counter()
    out = fn(*args, **kw)
    return out, time.perf_counter() - t0


def main(n: int = 1_000_000, m: int = 100_000) -> None:
    rng = np.random.default_rng(0)
    rows = np.repeat(np.arange(n // 1000 + 1), 1000)[:n]
    s = np.arange(n, dtype=float)
    pts = np.column_stack([s % 1000 * 0.1, rows * 0.5, 0.01 * np.sin(s / 50)])
    nrm = rng.normal(size=(n, 3)) * 0.05 + [0, 0, 1]
    nrm /= np.linalg.norm(nrm, axis=1)[:, None]
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        cc = CCPath(pts, nrm, rows, feed=np.full(n, 1200.0))
        _, tw = _timed(write_cc_csv, d / "cc.csv", cc)
        back, tr = _timed(read_cc_csv, d / "cc.csv")
        assert np.array_equal(back.points, pts)
        mb = (d / "cc.csv").stat().st_size / 1e6
        print(f"CC path CSV, {n} rows x 8 columns ('%.17g', {mb:.0f} MB): write {tw:.2f} s, read {tr:.2f} s")

        body = "\n".join(f"{p[0]:.4f},{p[1]:.4f},{p[2]:.4f},{a[0]:.7f},{a[1]:.7f},{a[2]:.7f},{r}"
                         for p, a, r in zip(pts, nrm, rows, strict=True))
        (d / "cl.csv").write_text("x,y,z,i,j,k,row\n" + body + "\n")
        _, tr = _timed(read_cl_csv, d / "cl.csv")
        mb = (d / "cl.csv").stat().st_size / 1e6
        print(f"CL CSV, {n} rows x 7 columns (4-7 decimals, {mb:.0f} MB): read {tr:.2f} s")

        lines = ["TOOL PATH/BENCH,TOOL,T1", "TLDATA/MILL,10.0000,1.0000,50.0000,0.0000,0.0000",
                 "MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000",
                 "FEDRAT/MMPM,1200.0000"]
        lines += [f"GOTO/{p[0]:.4f},{p[1]:.4f},{p[2]:.4f},{a[0]:.7f},{a[1]:.7f},{a[2]:.7f}"
                  for p, a in zip(pts, nrm, strict=True)]
        (d / "p.cls").write_text("\n".join(lines + ["END-OF-PATH"]) + "\n")
        prog, tr = _timed(read_apt, d / "p.cls")
        assert len(prog) == n
        print(f"NX CLSF, {n} GOTO/x,y,z,i,j,k records: read {tr:.2f} s")

        machine = load_machine(None)
        k = np.arange(m)
        r = k // 500
        tip = np.column_stack([k % 500 * 0.2, r * 0.5, np.zeros(m)])
        b = np.radians(20 * np.sin(k / 80))
        a = np.radians(10 * np.cos(k / 60))
        T = machine.tool_axis_np(a, b)
        z0 = np.zeros(m)
        res = MethodResult(method="nlp", rows=r, idx=k % 500, t=z0, cc=tip, normals=T, cl=tip, axis=T,
                           lead=z0, tilt=z0, rotary=RotaryValues.of(machine.rotary, a, b),
                           rotary_vel=RotaryValues.zeros(machine.rotary, m),
                           rotary_acc=RotaryValues.zeros(machine.rotary, m),
                           xyz=machine.linear_axes(tip, a, b), delta=z0, lift=z0, lead_window=np.zeros((m, 2)),
                           tilt_window=np.zeros((m, 2)), compound_acc=z0)
        cutter = type("C", (), {"R": 3.0, "r": 1.0})()
        for mode in ("machine", "tcp"):
            _, tw = _timed(write_gcode, d / f"p_{mode}.nc", res, machine, cutter, np.full(m, 1500.0),
                           dialect="fanuc", mode=mode, check_limits=False)
            print(f"G-code, {m} points, fanuc {mode} mode: write {tw:.2f} s")


if __name__ == "__main__":
    main(*(int(a) for a in sys.argv[1:3]))
