"""Diagnose the University of Michigan CNC-mill recordings: fit on some files, validate on others.

Each experiment file holds the controller's command and actual position of X, Y, Z every 100 ms
(stored to about 3 significant figures). The recordings are not shipped: `--data DIR` or
$CAMSMOOTH_UMICH names their folder (default: shared/data/umich-cnc-mill beside the repository). The simulation says
actual == command; `camsmooth diagnose` is asked what is missing. We fit on experiments 01-06
(joined, kept apart in time) and predict 07-12 with the fitted model without refitting.

Run:  python examples/diagnose_umich.py [--data DIR] [--report DIR]
Prints: the named effect with Kv per axis, RMS before/after on the fitted files (all samples and
held-out), per validation file, what was rejected and why, and whether the data can tell a servo
lag from a clock offset.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from camsmooth.diagnosis.engine import diagnose, validate  # noqa: E402
from camsmooth.diagnosis.recordings import concatenate, read_umich  # noqa: E402

# the recordings live in shared/ beside the repository; CAMSMOOTH_UMICH overrides
DATA = Path(os.environ.get("CAMSMOOTH_UMICH",
                           Path(__file__).resolve().parents[2] / "shared" / "data" / "umich-cnc-mill"))
FIT = [1, 2, 3, 4, 5, 6]
VALIDATE = [7, 8, 9, 10, 11, 12]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(DATA), help="folder of experiment_NN.csv (default: %(default)s)")
    ap.add_argument("--report", help="write the plots and report.html here")
    args = ap.parse_args()
    data = Path(args.data)
    files = {i: data / f"experiment_{i:02d}.csv" for i in FIT + VALIDATE}
    program, recording = concatenate([read_umich(files[i]) for i in FIT])
    diag = diagnose(program, recording)
    f = diag.findings
    chans = list(f["channels"])
    print(f"fitted on experiments {FIT[0]:02d}-{FIT[-1]:02d}: {f['selection']['samples']} samples, "
          f"{f['selection']['folds']} blocked folds")
    print(f"verdict: {f['verdict']}; named: {', '.join(f['named']) or 'nothing'}")
    for e in f["effects"]:
        if e["name"] == "servo_lag":
            for k, v in e["parameters"].items():
                print(f"  {k} = {v:.1f} +- {e['uncertainties'][k]:.1f} 1/s  (lag time constant {1000 / v:.2f} ms)")
        print(f"  {e['sentence']}")
    print("\nresidual RMS (mm)          floor   before(all) after(all)  before(held-out) after(held-out)")
    for c in chans:
        b, a, fl = f["baseline_rms"][c], f["final_rms"][c], f["noise_floor"][c]["rms"]
        print(f"  {c:8s}               {fl:7.4f}   {b['fit']:8.4f}   {a['fit']:8.4f}     {b['heldout']:8.4f}"
              f"         {a['heldout']:8.4f}")
    print("\nvalidation (files never fitted), residual RMS before -> after (mm):")
    tot_b = {c: 0.0 for c in chans}
    tot_a = {c: 0.0 for c in chans}
    tot_n = {c: 0 for c in chans}
    for i in VALIDATE:
        v = validate(*read_umich(files[i]), diag)
        parts = []
        for c in chans:
            d = v["channels"][c]
            parts.append(f"{c} {d['rms_before']:.4f} -> {d['rms_after']:.4f}")
            tot_b[c] += d["rms_before"] ** 2 * d["samples"]
            tot_a[c] += d["rms_after"] ** 2 * d["samples"]
            tot_n[c] += d["samples"]
        print(f"  experiment {i:02d}: " + "; ".join(parts))
    print("  all validation files: " + "; ".join(
        f"{c} {(tot_b[c] / tot_n[c]) ** 0.5:.4f} -> {(tot_a[c] / tot_n[c]) ** 0.5:.4f} "
        f"({100 * (1 - (tot_a[c] / tot_b[c]) ** 0.5):.0f}% lower)" for c in chans))
    print("\nrejected:")
    for r in f["rejected"]:
        print(f"  {r['name']}: {r['reason']}")
    lv = f["lag_vs_offset"]
    print("\nservo lag or clock offset?")
    print(f"  held-out RMS in floors: per-axis lag {lv['heldout_per_axis_lag']:.4f}, one common lag "
          f"{lv['heldout_common_lag']:.4f}, one clock offset {lv['heldout_offset']:.4f}")
    print("  per-axis delays: " + ", ".join(f"{a} {d['delay_ms']:.2f} +- {d['sd_ms']:.2f} ms"
                                         for a, d in lv["per_axis_delays"].items()))
    print(f"  {lv['verdict']}")
    if args.report:
        from camsmooth.report.diagnosis import write_report

        write_report(diag, args.report)
        print(f"\nreport: {args.report}/report.html")
    return 0


if __name__ == "__main__":
    sys.exit(main())
