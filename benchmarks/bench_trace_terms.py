"""The trace terms over seeds: each new term's closed-form trace (tests/test_trace_diagnosis.py,
not camsmooth's simulator) named with its value, and nulls (white noise, coloured noise, a clean
first-order servo, a random walk beside temperatures) where nothing new is named. Prints, per
case, how often the expected set is named and the worst relative error of the value.

    .venv/bin/python benchmarks/bench_trace_terms.py [SEEDS [CASE ...]]
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from camsmooth.diagnosis.trace import diagnose_trace, read_trace  # noqa: E402
from tests.test_trace_diagnosis import NEW, Q, effect, motion_trace, thermal_trace, two_axis_trace  # noqa: E402

CASES = {  # case: (expected names, term, parameter, truth)
    "second_order": (["servo_second_order"], "servo_second_order", "wn_X", 120.0),
    "velocity_limit": (["velocity_limit"], "velocity_limit", "vmax_X", 35.0),
    "acceleration_limit": (["acceleration_limit"], "acceleration_limit", "amax_X", 2000.0),
    "backlash_load": (["backlash_load"], "backlash_load", "backlash_load_X", 0.02),
    "delay": (["time_offset"], "time_offset", "offset_s", 0.012),
    "thermal": (["thermal_temperature"], "thermal_temperature", "gain_spindle", 0.012),
    "thermal_clock": (["thermal_time"], "thermal_time", "gain_time", 0.05),
    "lag": (["servo_lag"], "servo_lag", "Kv_X", 40.0),
    "lag_ar1": (["servo_lag"], "servo_lag", "Kv_X", 40.0),
    "second_order_delay": (["servo_second_order", "time_offset"], "servo_second_order", "wn_X", 120.0),
    "staircase": (["quantisation"], "quantisation", "q_X", Q),
    "staircase_lag": (["servo_lag", "quantisation"], "quantisation", "q_X", Q),
    "rounded_noise": ([], None, None, None),
    "two_delay_y": (["transport_delay"], "transport_delay", "delay_Y", 0.012),
    "two_lag_delay_y": (["servo_lag", "transport_delay"], "transport_delay", "delay_Y", 0.012),
    "two_same_delay": (["time_offset"], "time_offset", "offset_s", 0.012),
    "two_null": ([], None, None, None),
    "pitch": ([], None, None, None),
    "white": ([], None, None, None),
    "coloured": ([], None, None, None),
    "thermal_null": ([], None, None, None),
}


def main(seeds: int, only: list[str] | None = None) -> None:
    with tempfile.TemporaryDirectory() as td:
        d = Path(td)
        for case, (want, name, key, truth) in CASES.items():
            if only and case not in only:
                continue
            right, worst, new, t0 = 0, 0.0, 0, time.perf_counter()
            for seed in range(seeds):
                if case.startswith("two_"):  # X white, lagged or delayed like Y; Y delayed 12 ms (or not)
                    x = {"two_delay_y": "white", "two_lag_delay_y": "lag", "two_same_delay": "same_delay",
                         "two_null": "white"}[case]
                    path = two_axis_trace(d, x, 0.0 if case == "two_null" else 0.012, seed=100 + seed)
                elif case.startswith("thermal"):
                    path = thermal_trace(d, null=case == "thermal_null", seed=100 + seed, clock=case == "thermal_clock")
                else:
                    path = motion_trace(d, case, seed=100 + seed)
                f = diagnose_trace(read_trace(path)).findings
                right += sorted(f["named"]) == sorted(want)
                new += bool(set(f["named"]) & NEW - set(want))
                if name and name in f["named"]:
                    worst = max(worst, abs(effect(f, name)["parameters"][key] / truth - 1.0))
            print(f"{case:20s} expected {want or 'nothing'}: {right}/{seeds}; a term not there named in {new}/{seeds}"
                  + (f"; worst {key} error {100 * worst:.2g}%" if name else "")
                  + f"; {time.perf_counter() - t0:.1f} s", flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10, sys.argv[2:] or None)
