"""Benchmark: diagnose a 30-minute recording sampled at 1 kHz (1.8 million samples).

A synthetic 'lines' program (X, Y, Z rest-to-rest moves with reversals, spindle on) at 1 kHz is
simulated with a concealed servo lag (Kv X 40, Y 60, Z 80 1/s) and backlash (X 10, Y 15,
Z 20 um), white noise 1 um, on the axis actuals and the measured tool tip (6 channels). The
script prints the wall and CPU time of `diagnose` on the arrays (and the load average: wall time
on a busy machine says little), of reading the two CSV files, and what was found.
Run:  python benchmarks/bench_diagnose.py [--minutes 30] [--rate 1000] [--csv]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from benchmarks.synthetic import make_program  # noqa: E402
from camsmooth.diagnosis.findings import diagnose  # noqa: E402
from camsmooth.diagnosis.recordings import (  # noqa: E402
    read_program_csv,
    read_recording_csv,
    write_program_csv,
    write_recording_csv,
)
from camsmooth.diagnosis.simulator import physics_from_settings, simulate_recording  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=30.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--channels", default="axes,tip")
    ap.add_argument("--csv", action="store_true", help="also time writing and reading the CSV files")
    args = ap.parse_args()
    t0 = time.perf_counter()
    program = make_program("lines", duration=60.0 * args.minutes, rate=args.rate, seed=7)
    truth = {"Kv_X": 40.0, "Kv_Y": 60.0, "Kv_Z": 80.0, "backlash_X": 0.010, "backlash_Y": 0.015,
             "backlash_Z": 0.020}
    recording = simulate_recording(program, physics=physics_from_settings(truth),
                                   channels=args.channels.split(","), noise={"axes": 1e-3, "tip": 1e-3}, seed=1)
    print(f"made {len(recording.t)} samples x {len(recording.channels)} channels "
          f"({len(program.t)} program rows) in {time.perf_counter() - t0:.1f} s")
    if args.csv:
        with tempfile.TemporaryDirectory() as d:
            pp, rp = os.path.join(d, "program.csv"), os.path.join(d, "recording.csv")
            t1 = time.perf_counter()
            write_program_csv(pp, program)
            write_recording_csv(rp, recording)
            t2 = time.perf_counter()
            program = read_program_csv(pp)
            recording = read_recording_csv(rp)
            t3 = time.perf_counter()
            print(f"CSV write {t2 - t1:.1f} s (not part of diagnose), CSV read {t3 - t2:.1f} s")
    load = os.getloadavg()[0]
    t4, c4 = time.perf_counter(), time.process_time()
    diag = diagnose(program, recording)
    elapsed, cpu = time.perf_counter() - t4, time.process_time() - c4
    f = diag.findings
    print(f"diagnose: {elapsed:.1f} s wall, {cpu:.1f} s CPU (load average {load:.2f} before, on "
          f"{os.cpu_count()} cores) for {f['selection']['samples']} samples (fits on "
          f"{f['selection']['fit_samples']}); named {f['named']}")
    for e in f["effects"]:
        print("  " + e["sentence"][:300])
    print(f"BENCH diagnose_seconds {elapsed:.2f}")
    print(f"BENCH diagnose_cpu_seconds {cpu:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
