"""The full concealed-effect sweep: every candidate alone, the pairs and the null case, on four
programs (linear moves with reversals, circles, A/B rotary sweeps, spindle-speed steps) at
several noise levels and seeds. diagnose sees only the program and the recording; a case is
right when exactly the hidden effects are named and their parameters are within 10%.

Run:  python benchmarks/bench_concealed.py [--noise 0.0005 0.002 0.005] [--seeds 1 2] [--quick]
Prints every case that went wrong, the success rate, the null-case false alarms and the time.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from camsmooth.diagnosis.engine import CONCEALED_PROGRAMS, concealed_case, concealed_cases  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", type=float, nargs="+", default=[0.0005, 0.002, 0.005],
                    help="white noise sigma on mm channels (rad channels get 1e-3 of it)")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--kinds", nargs="+", default=list(CONCEALED_PROGRAMS))
    ap.add_argument("--quick", action="store_true", help="short recordings (as the test suite uses)")
    args = ap.parse_args()
    t0 = time.perf_counter()
    results = []
    for seed in args.seeds:
        for noise in args.noise:
            for kind, names in concealed_cases(args.kinds):
                kw = {}
                if args.quick:
                    kw = {"duration": 20.0 if kind == "spindle" else 8.0, "rate": 100.0 if kind == "spindle" else 250.0}
                r = concealed_case(kind, names, noise, seed=seed, **kw)
                results.append(r)
                if not r["ok"]:
                    print(f"WRONG {kind:8s} noise {noise:g} seed {seed} hidden {list(names)}: {r['problems']}",
                          flush=True)
    n = len(results)
    ok = sum(r["ok"] for r in results)
    null = [r for r in results if not r["effects"]]
    false_alarms = sum(bool(r["named"]) for r in null)
    single = [r for r in results if len(r["effects"]) == 1]
    pairs = [r for r in results if len(r["effects"]) == 2]
    print(f"cases {n}: right {ok} ({100 * ok / n:.1f}%); single effects {sum(r['ok'] for r in single)}/{len(single)}, "
          f"pairs {sum(r['ok'] for r in pairs)}/{len(pairs)}, null cases with something named "
          f"{false_alarms}/{len(null)}")
    print(f"samples per case {min(r['samples'] for r in results)}-{max(r['samples'] for r in results)}; "
          f"diagnose time per case median {sorted(r['seconds'] for r in results)[n // 2]:.2f} s; "
          f"total {time.perf_counter() - t0:.0f} s")
    print(f"BENCH concealed_success_pct {100 * ok / n:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
