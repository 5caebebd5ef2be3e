"""Signals at any moment (issue 21, part 1): SIGINT and SIGTERM, to the process and to its process
group, after delays from start-up (imports, numba's cache) through the worker pool to the end, on
a multi-process ``smooth`` of the blade's first rows: one message, exit 130 / 143, no traceback,
no crash, nothing left behind, the earlier outputs intact (or replaced whole by a run that
finished). The long sweep on the full blade is benchmarks/signal_sweep.py."""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))

from signal_sweep import blade_program, run_once, smooth_argv, summary  # noqa: E402

#: 16 interrupted runs, from start-up (imports, numba's cache) to the end of the run, 0.2 to 4.7 s
#: (the 30-run and longer sweeps: benchmarks/signal_sweep.py)
DELAYS = tuple(round(0.2 + 0.3 * k, 2) for k in range(16))
KINDS = ((signal.SIGINT, True), (signal.SIGTERM, False), (signal.SIGINT, False), (signal.SIGTERM, True))


@pytest.fixture(scope="module")
def program(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return blade_program(tmp_path_factory.mktemp("sweep"), rows=4)


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="POSIX signals")
def test_signal_sweep(program: Path) -> None:
    # children start with SIGINT handled, as from a terminal (a background job would inherit it ignored)
    old = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        outcomes = [run_once(smooth_argv(program), d, *KINDS[k % len(KINDS)], timeout=120)
                    for k, d in enumerate(DELAYS)]
    finally:
        signal.signal(signal.SIGINT, old)
    assert not any(o.problems for o in outcomes), summary(outcomes)
    assert sum(not o.finished_first for o in outcomes) >= len(DELAYS) // 2, summary(outcomes)
