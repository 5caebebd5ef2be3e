"""Signals at any moment: SIGINT or SIGTERM, to the process or its process group, after a sweep
of delays over a multi-process ``camsmooth smooth`` (issue 21); prints what went wrong.

Each run starts ``python -m camsmooth smooth ... -o out.csv --gcode out.nc --workers 2`` in a
fresh folder holding an earlier run's out.csv and out.nc, waits the delay from camsmooth's first
statement (the interpreter's start-up before it is Python's), sends the signal and
checks: the exit status (130 SIGINT, 143 SIGTERM; 0 only when the run finished before the signal
or within IGNORED_AFTER_S of it with its outputs complete: a signal as the command ends, its
outputs committed, is ignored), one ``camsmooth:`` message on stderr and no traceback or other
output, no crash (a negative status or 70), no hang, no file left behind (hidden temporaries),
no process of the group left running, and the earlier outputs intact (or both replaced by a
complete run). Usage (from the repository's root; 30 runs take about 2 minutes on the blade)::

    python benchmarks/signal_sweep.py [--runs 30] [--min 0] [--max 4] [--rows N]
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EARLIER = {"out.csv": "an earlier run's CSV\n", "out.nc": "(an earlier run's G-code)\n"}
IGNORED_AFTER_S = 1.0  # a run ending 0 this long after the signal ignored it
EXPECTED = {signal.SIGINT: 130, signal.SIGTERM: 143}


@dataclass
class Outcome:
    """One run: what was sent when, and what went wrong (``problems`` empty: all well)."""

    delay: float
    signum: int
    group: bool
    code: int | None
    finished_first: bool
    problems: list[str] = field(default_factory=list)
    stderr: str = ""


def blade_program(folder: Path, rows: int | None = None) -> Path:
    """The shipped blade path (its first ``rows`` rows when given) copied into ``folder``."""
    src = ROOT / "surfaces" / "blade_path.csv"
    dst = folder / "blade_path.csv"
    if rows is None:
        shutil.copy(src, dst)
        return dst
    lines = src.read_text().splitlines(keepends=True)
    col = lines[0].strip().split(",").index("row")
    keep = [ln for ln in lines[1:] if int(float(ln.split(",")[col])) < rows]
    dst.write_text(lines[0] + "".join(keep))
    return dst


def smooth_argv(program: Path) -> list[str]:
    """The issue's command line on ``program`` (the blade's definition, two workers)."""
    return ["smooth", str(program), "--surface", str(ROOT / "surfaces" / "blade.toml"), "--lead", "2:20",
            "--tilt", "-15:15", "--cutter-radius", "4", "--corner-radius", "1", "--feed", "2000",
            "-o", "out.csv", "--gcode", "out.nc", "--workers", "2"]


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if ".camsmooth-" in p.name)


def _group_alive(pgid: int, wait: float) -> bool:
    """Whether a process of the group ``pgid`` is still running after ``wait`` s."""
    deadline = time.monotonic() + wait
    while True:
        try:
            os.killpg(pgid, 0)
        except ProcessLookupError:
            return False
        if time.monotonic() > deadline:
            return True
        time.sleep(0.05)


def _caught(pid: int, signum: int, timeout: float = 30.0) -> float:
    """Wait until process ``pid`` catches ``signum`` (Linux: /proc/PID/status SigCgt), that is
    until camsmooth's first statement (camsmooth.__main__) ran: before it, the interpreter's own
    start-up is Python's. The seconds waited (0 where /proc is not there)."""
    status, t0 = Path(f"/proc/{pid}/status"), time.monotonic()
    while time.monotonic() - t0 < timeout:
        try:
            text = status.read_text()
        except OSError:
            return time.monotonic() - t0
        m = re.search(r"^SigCgt:\s*([0-9a-f]+)", text, re.M)
        if m is None or int(m.group(1), 16) >> (signum - 1) & 1:
            return time.monotonic() - t0
        time.sleep(0.002)
    return time.monotonic() - t0


def run_once(argv: list[str], delay: float, signum: int, group: bool, timeout: float = 120.0) -> Outcome:
    """Start camsmooth in a fresh folder, send ``signum`` ``delay`` s after camsmooth's first
    statement ran (``_caught``; to the process group when ``group``), wait and judge (module
    docstring)."""
    with tempfile.TemporaryDirectory(prefix="signal-sweep-") as d:
        ws = Path(d)
        for name, text in EARLIER.items():
            (ws / name).write_text(text)
        env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
        proc = subprocess.Popen([sys.executable, "-m", "camsmooth", *argv], cwd=ws, env=env,
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                start_new_session=True)
        finished_first = hung = False
        sent = ended = 0.0
        try:
            _caught(proc.pid, signal.SIGTERM)
            time.sleep(delay)
            finished_first = proc.poll() is not None
            if not finished_first:
                if group:
                    os.killpg(proc.pid, signum)
                else:
                    proc.send_signal(signum)
            sent = time.monotonic()
            try:
                _, err = proc.communicate(timeout=timeout)
                ended = time.monotonic()
            except subprocess.TimeoutExpired:
                hung = True
                os.killpg(proc.pid, signal.SIGKILL)
                _, err = proc.communicate()
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        left = _group_alive(proc.pid, 10.0)  # the fork server and workers follow their parent out
        if left:
            os.killpg(proc.pid, signal.SIGKILL)
        out = Outcome(delay, int(signum), group, proc.returncode, finished_first, stderr=err)
        code = proc.returncode
        if hung:
            out.problems.append("hang")
            code = None
        want = 0 if finished_first else EXPECTED[signum]
        if code is not None and code < 0:
            out.problems.append("crash")
        elif code == 70:
            out.problems.append("internal error")
        elif code is not None and code != want and not (code == 0 and not finished_first):
            out.problems.append("wrong exit status")
        if code == 0 and not finished_first and ended - sent > IGNORED_AFTER_S:
            out.problems.append("signal ignored")  # it ran on (a signal as the command ends is too late)
        if "Traceback" in err:
            out.problems.append("traceback")
        stray = [ln for ln in err.replace("\r", "\n").splitlines()
                 if ln.strip() and not ln.startswith("camsmooth") and not re.match(r"^\w+ rows:", ln)]
        if stray and "Traceback" not in err:
            out.problems.append("stray output")
        msgs = [ln for ln in err.replace("\r", "\n").splitlines() if ln.startswith("camsmooth")]
        if code not in (0, None) and len(msgs) != 1:
            out.problems.append("not one message")
        if _leftovers(ws):
            out.problems.append("leftover files")
        now = {n: (ws / n).read_text() if (ws / n).exists() else None for n in EARLIER}
        intact = now == EARLIER
        replaced = all(v is not None and v != EARLIER[n] for n, v in now.items())
        if code == 0 and not replaced:
            out.problems.append("outputs missing after success")
        elif code != 0 and not intact and not (replaced and code in EXPECTED.values()):
            out.problems.append("earlier outputs damaged")
        if left:
            out.problems.append("processes left running")
        return out


def sweep(argv: list[str], runs: int, lo: float, hi: float, verbose: bool = False) -> list[Outcome]:
    """``runs`` runs with delays spread over [lo, hi] s, alternating SIGINT / SIGTERM and process /
    group."""
    outcomes = []
    kinds = [(signal.SIGINT, False), (signal.SIGINT, True), (signal.SIGTERM, False), (signal.SIGTERM, True)]
    for k in range(runs):
        delay = lo + (hi - lo) * k / max(runs - 1, 1)
        signum, group = kinds[k % len(kinds)]
        o = run_once(argv, delay, signum, group)
        outcomes.append(o)
        if verbose:
            print(f"  run {k + 1}/{runs}: delay {delay:.2f} s {signal.Signals(signum).name} "
                  f"{'group' if group else 'process'} -> {o.code} {', '.join(o.problems) or 'ok'}", flush=True)
    return outcomes


def summary(outcomes: list[Outcome]) -> str:
    """Counts of each problem and the runs that had one."""
    counts = Counter(p for o in outcomes for p in o.problems)
    lines = [f"runs {len(outcomes)}, finished before the signal {sum(o.finished_first for o in outcomes)}, "
             f"with a problem {sum(bool(o.problems) for o in outcomes)}"]
    for name in ("hang", "traceback", "stray output", "crash", "internal error", "leftover files", "wrong exit status",
                 "signal ignored", "not one message", "earlier outputs damaged", "outputs missing after success",
                 "processes left running"):
        lines.append(f"  {name:32s} {counts.get(name, 0)}")
    for o in outcomes:
        if o.problems:
            last = o.stderr.strip().replace("\r", "\n").splitlines()[-1:] or [""]
            lines.append(f"  delay {o.delay:.2f} s {signal.Signals(o.signum).name} {'group' if o.group else 'process'}"
                         f" -> {o.code}: {', '.join(o.problems)} | {last[0][:160]}")
    return "\n".join(lines)


def main() -> None:
    signal.signal(signal.SIGINT, signal.default_int_handler)  # children start with SIGINT not ignored
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=30)
    ap.add_argument("--min", type=float, default=0.0)
    ap.add_argument("--max", type=float, default=4.0)
    ap.add_argument("--rows", type=int, default=None, help="only the blade's first N rows (default all 30)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="signal-sweep-in-") as d:
        program = blade_program(Path(d), a.rows)
        t0 = time.monotonic()
        outcomes = sweep(smooth_argv(program), a.runs, a.min, a.max, verbose=True)
        print(summary(outcomes))
        print(f"wall time {time.monotonic() - t0:.0f} s")


if __name__ == "__main__":
    main()
