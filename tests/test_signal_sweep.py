"""Signals at any moment (issue 21, part 1): SIGINT and SIGTERM, to the process and to its process
group, after delays from camsmooth's first statement (imports, numba's cache) through the worker pool to the end, on
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

#: 16 interrupted runs, from camsmooth's first statement (imports, numba's cache) to the end of the
#: run, 0 to 4.5 s after it (the 30-run and longer sweeps: benchmarks/signal_sweep.py)
DELAYS = tuple(round(0.3 * k, 2) for k in range(16))
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


@pytest.mark.parametrize("signum, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_noted_before_the_entry_ends_the_command(signum: int, code: int) -> None:
    # a signal between camsmooth's first statement and the entry's handlers (noted, not raised)
    # ends the command at once: its one message and status, nothing run, no traceback
    import subprocess

    script = ("import sys, signal, camsmooth.__main__ as m\n"
              f"signal.raise_signal({int(signum)})\n"
              "sys.argv = ['camsmooth', 'smooth', 'missing.csv']\n"
              "sys.exit(m.main())\n")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert done.returncode == code, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("camsmooth: "), done.stderr
    assert "missing.csv" not in done.stderr  # the command did not start
