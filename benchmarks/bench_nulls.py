"""False positives of `diagnose` on null recordings (no effect at all): four programs (lines,
laser, grid, rotary), white noise and AR(1) coloured noise (rho 0.9, 0.95, 0.99) plus a white part,
six seeds each; prints every recording where something was named and the count (issue 20: zero
expected). About 2-4 minutes on 2 cores.

Run: .venv/bin/python benchmarks/bench_nulls.py
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.synthetic import null_case  # noqa: E402
from camsmooth.diagnosis.engine import diagnose  # noqa: E402


def main() -> int:
    """Run the null sweep; print each recording where something was named and the count."""
    tot = bad = 0
    for kind in ("lines", "laser", "grid", "rotary"):
        for rho in (0.0, 0.9, 0.95, 0.99):
            for seed in range(10, 16):
                prog, rec = null_case(kind, rho, seed)
                f = diagnose(prog, rec).findings
                tot += 1
                if f["named"]:
                    bad += 1
                    print("FP", kind, rho, seed, f["named"], flush=True)
    print(f"nulls {tot}, with a finding {bad}")
    print(f"BENCH null_false_positives {bad}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
