"""ISO 230-2 positioning test of a simulated linear axis and its LinuxCNC compensation table
(issue 20 item 3; camsmooth.diagnosis.iso230).

    python examples/iso230_demo.py [OUT]        (default OUT = iso230_out)

Writes OUT/run.csv (11 irregularly spaced targets over 500 mm, 5 bidirectional runs: pitch error
20 um/m, a 5 um screw term of 10 mm period, 18 um reversal, 1 um noise) and OUT/held.csv (a second
run between those targets, not used to build the table), then runs

    camsmooth iso230 OUT/run.csv --axis X --comp OUT/x.comp --json OUT/x.json --check OUT/held.csv
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from camsmooth.cli.main import main
from camsmooth.diagnosis.iso230 import simulate_run, write_run_csv

TARGETS = np.arange(11) * 50.0 + np.array([0, 3.1, 7.3, 1.9, 5.7, 8.9, 2.3, 6.1, 9.4, 4.2, 0.0])
HELD = (TARGETS[:-1] + TARGETS[1:]) / 2 + 1.7


if __name__ == "__main__":
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "iso230_out")
    write_run_csv(out / "run.csv", simulate_run(TARGETS, 5, seed=1))
    write_run_csv(out / "held.csv", simulate_run(HELD, 5, seed=11))
    sys.exit(main(["iso230", str(out / "run.csv"), "--axis", "X", "--comp", str(out / "x.comp"),
                   "--json", str(out / "x.json"), "--check", str(out / "held.csv")]))
