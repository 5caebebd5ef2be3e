"""False positives of `diagnose` on null recordings (no effect at all): four programs (lines,
laser, grid, rotary), white noise and AR(1) coloured noise (rho 0.9, 0.95, 0.99) plus a white part,
six seeds each; prints every recording where something was named and the count (issue 20: zero
expected). About 2-4 minutes on 2 cores.

Run: .venv/bin/python benchmarks/bench_nulls.py
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import numpy as np
from scipy.signal import lfilter

from benchmarks.synthetic import make_program, make_special_program, record
from camsmooth.diagnosis.engine import diagnose

tot = bad = 0
for kind in ("lines", "laser", "grid", "rotary"):
    for rho in (0.0, 0.9, 0.95, 0.99):
        for seed in range(10, 16):
            prog = make_program("lines", duration=8.0, rate=250.0, seed=seed) if kind == "lines" else \
                make_special_program(kind, rate=50.0, seed=seed)
            chans = ("tip",) if kind in ("grid", "rotary") else ("axes",)
            rec = record(prog, {}, channels=chans, noise={}, seed=seed)
            rng = np.random.default_rng(seed + 100)
            for c in rec.channels:
                n = len(rec.t)
                ar = (lfilter([1.0], [1.0, -rho], rng.normal(0.0, 1e-3 * np.sqrt(1 - rho ** 2), n)) if rho
                      else rng.normal(0, 1e-3, n))  # stationary sigma 1 um either way
                rec.channels[c] = rec.channels[c] + ar + rng.normal(0, 3e-4, n)
            f = diagnose(prog, rec).findings
            tot += 1
            if f["named"]:
                bad += 1
                print("FP", kind, rho, seed, f["named"], flush=True)
print(f"nulls {tot}, with a finding {bad}")
print(f"BENCH null_false_positives {bad}")
