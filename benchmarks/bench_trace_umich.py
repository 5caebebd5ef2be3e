"""`camsmooth diagnose --trace` on the real Michigan CNC-mill recordings (shared/data/umich-cnc-mill, beside
the repository; CC0; see its README), read as a plain log through a column map, as a user would read a drive's
export: t = row index x 0.1 s, X/Y/Z command and actual positions and commanded velocities (the
latter mark the rows missing from the log: a commanded jump faster than the commanded velocity).
Prints, per file, what is named, the fitted values and the held-out RMS by time blocks (before ->
after), to set beside the program-based diagnosis (README: Kv 111 / 127 / 124 1/s fitted on 01-06).

    .venv/bin/python benchmarks/bench_trace_umich.py [DATA_DIR]
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from camsmooth.diagnosis.trace import diagnose_trace, read_trace

COLUMNS = {"t": 1, "X_act": 2, "X_cmd": 5, "X_vel_cmd": 6, "Y_act": 13, "Y_cmd": 16, "Y_vel_cmd": 17, "Z_act": 24,
           "Z_cmd": 27, "Z_vel_cmd": 28}


def main(data: Path) -> None:
    files = sorted(data.glob("experiment_*.csv"))
    for f in files:
        t0 = time.perf_counter()
        tr = read_trace(str(f), columns=COLUMNS, sample_period=0.1)
        d = diagnose_trace(tr).findings
        h = d["heldout"]
        vals = "; ".join(f"{e['name']}: " + ", ".join(f"{k} {v:.4g}" for k, v in e["parameters"].items()
                                                         if v is not None) for e in d["effects"])
        ho = ", ".join(f"{c} {h['rms_before'][c]:.3g} -> {h['rms_after'][c]:.3g}" for c in h["rms_before"])
        print(f"{f.name}: {len(tr.t)} samples; named {d['named'] or 'nothing'}; {vals}; held-out mm {ho}; "
              f"{time.perf_counter() - t0:.1f} s", flush=True)


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "shared" / "data"
         / "umich-cnc-mill")
