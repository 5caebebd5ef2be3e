"""Failures AFTER the first output of a command has been written (issue 12): nothing is left.

tests/test_cli_faults.py replaces whole writer functions (write_gcode, write_report, ...) with
fakes that fail before the real code runs, and tests/test_atomic.py the transaction alone. Here
the real writers run and the failure comes from below them, where the operating system would
raise it:

- the commit of the second output fails after the first output has been moved into place: the
  rename raises ENOSPC (rename(2) can: "the directory has no room for the new entry"), or a
  folder appears at the second output's name just before its rename and the kernel refuses the
  rename itself (EISDIR). The first output must be rolled back, a user's earlier file at its
  name restored byte for byte;
- a folder appears at the second output's name after the first was written (another program
  made it): the commit's check refuses before anything moves;
- a write() of the G-code fails with ENOSPC half-way through (the real writer, the file object's
  write raising, as a full disk does);
- SIGTERM reaches a real ``camsmooth`` process while the G-code (a JSON report for calibrate) is
  half written to its temporary by the real writer, the CSV (model) already complete;
- the issue's own case, ``smooth ... -o out.csv --gcode out.nc`` with a Z the machine cannot
  reach, in a real process, with an earlier run's out.csv in place.

Each proves: the exit status, one message naming the user's path (never a temporary), and the
folder exactly as before (names, contents, modification times; hidden files included), so no
final file, no temporary and no backup is left and the user's files are untouched.
"""

from __future__ import annotations

import errno
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from camsmooth.cli.main import main
from camsmooth.io.ccpath import write_cc_csv
from tests.conftest import ROOT, snapshot, user_workspace
from tests.test_cli_faults import one_message, plane_mesh, plane_path

TAG = ".camsmooth-"
SMOOTH = ["smooth", "p.csv", "--surface", "plane.ply", "--cutter-radius", "4", "--corner-radius", "1",
          "--feed", "1000", "--lead", "2:20", "--tilt", "-15:15", "--quiet", "--method", "spline"]
CALIBRATE = ["calibrate", "probe", "probe.csv"]
DIAGNOSE = ["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--quiet"]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> Path:
    from benchmarks.synthetic import make_program
    from camsmooth.diagnosis.recordings import write_program_csv, write_recording_csv
    from camsmooth.diagnosis.simulator import physics_from_settings, simulate_recording
    from camsmooth.machine import calibration, simulate
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.machine.model import ErrorModel

    d = tmp_path_factory.mktemp("inputs")
    plane_mesh().export(d / "plane.ply")
    write_cc_csv(d / "p.csv", plane_path())
    model = ErrorModel(geometric={"EY0A": 0.02, "EZ0B": -0.01, "EZ0T": 0.03})
    machine = load_machine()
    calibration.write_probe_csv(d / "probe.csv", simulate.simulate_probe(
        model, machine, poses=simulate.default_probe_poses(machine, 5, 90.0), seed=1))
    prog = make_program("lines", duration=2.0, rate=100.0, seed=1)
    write_program_csv(d / "program.csv", prog)
    write_recording_csv(d / "recording.csv", simulate_recording(
        prog, None, physics_from_settings({"Kv_X": 40.0}), channels=["axes"], noise={"axes": 0.001}, seed=1))
    (d / "samples").mkdir()
    shutil.copy(d / "p.csv", d / "samples" / "tiny_path.csv")
    shutil.copy(d / "plane.ply", d / "samples" / "tiny.ply")
    return d


@pytest.fixture
def ws(inputs, tmp_path, monkeypatch) -> Path:
    """A working folder (the current folder) with the inputs and a user's own files."""
    user_workspace(inputs, tmp_path)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture
def quick_report(monkeypatch):
    """No 3D render child process and no PNG rasterising (tested in test_report.py); the
    report's files and folder handling are the real ones."""
    import camsmooth.report.smoothing as rs

    real = rs.write_report
    monkeypatch.setattr(rs, "write_report", lambda result, out, **kw: real(result, out, render_3d=False, **kw))
    monkeypatch.setattr(rs, "_save_png", lambda fig, path: Path(path).write_bytes(b"\x89PNG stand-in"))


def run(capsys, argv) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err


# ----------------------------------------------------------------------------------------------
# 1. the commit of the second output fails after the first is in place
# verb: (argv, the outputs in commit order; the first gets an earlier user's file)
VERBS = {
    "smooth": (SMOOTH + ["-o", "out.csv", "--gcode", "out.nc", "--report", "rep"], ["out.csv", "out.nc", "rep"]),
    "calibrate": (CALIBRATE + ["-o", "cal.json", "--report", "rep.json"], ["cal.json", "rep.json"]),
    "diagnose": (DIAGNOSE + ["--out", "f.json", "--model-out", "m.json", "--report", "rep"],
                 ["f.json", "m.json", "rep"]),
    "demo": (["demo", "--samples", "samples", "--sample", "tiny", "--out", "demo", "--quiet"],
             ["demo/tiny_smoothed.csv", "demo/tiny_smoothed.nc", "demo/tiny_report"]),
    "analyze": (["analyze", "p.csv", "--surface", "plane.ply", "--cutter-radius", "4", "--corner-radius", "1",
                 "--feed", "1000", "--json", "a.json", "--report", "rep", "--quiet"], ["a.json", "rep"]),
}
# a folder renamed onto an empty folder is allowed by the kernel: no "folder appears" failure there
FOLDER_SECOND = {"analyze"}


def _commit_renames(monkeypatch, on_second):
    """Wrap os.replace: the commit's renames (a temporary onto a final name) are counted and the
    second one is handed to ``on_second(real_replace, src, dst)``; every other rename (the
    writers' own atomic renames onto their temporaries, the rollback's restores) runs as is."""
    real = os.replace
    seen: list[str] = []

    def replace(src, dst):
        commit = TAG in os.fspath(src) and TAG not in os.fspath(dst)
        if commit:
            seen.append(os.fspath(dst))
            if len(seen) == 2:
                return on_second(real, src, dst)
        return real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    return seen


def _no_space(real, src, dst):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), os.fspath(src), None, os.fspath(dst))


def _folder_appears(real, src, dst):
    os.mkdir(dst)  # another program makes a folder there; the kernel then refuses the rename
    return real(src, dst)


@pytest.mark.parametrize("verb,failure", [(v, f) for v in VERBS for f in ("no space", "folder appears")
                                          if not (f == "folder appears" and v in FOLDER_SECOND)])
def test_commit_fails_on_the_second_output(capsys, ws, monkeypatch, quick_report, verb, failure):
    argv, outputs = VERBS[verb]
    first, second = ws / outputs[0], ws / outputs[1]
    first.parent.mkdir(exist_ok=True)
    first.write_text("an earlier run's output\n")  # must come back byte for byte
    before = snapshot(ws)
    seen = _commit_renames(monkeypatch, _no_space if failure == "no space" else _folder_appears)
    code, err = run(capsys, argv)
    assert len(seen) >= 2 and Path(seen[0]).resolve() == first.resolve(), seen  # the first WAS in place
    assert Path(seen[1]).resolve() == second.resolve(), seen
    assert code == 2, err
    msg = one_message(err)
    assert outputs[1] in msg and TAG not in msg, msg
    assert ("No space left on device" if failure == "no space" else "directory") in msg, msg
    after = snapshot(ws)
    if failure == "folder appears":
        assert after.pop(outputs[1] + "/") == ()  # the other program's folder stays, empty
    assert after == before


# ----------------------------------------------------------------------------------------------
# 2. a folder appears at the second output's name once the first output is written
def test_folder_made_at_the_gcode_name_during_the_run(capsys, ws, monkeypatch):
    import camsmooth.smoothing.output as output

    real = output.write_result_csv

    def then_a_folder(path, result):
        written = real(path, result)
        assert Path(path).stat().st_size > 0 and TAG in Path(path).name  # the CSV's temporary, complete
        os.mkdir(ws / "out.nc")
        return written

    monkeypatch.setattr(output, "write_result_csv", then_a_folder)
    (ws / "out.csv").write_text("earlier\n")
    before = snapshot(ws)
    code, err = run(capsys, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc"])
    assert code == 2, err
    msg = one_message(err)
    assert "out.nc" in msg and "folder" in msg and TAG not in msg, msg
    after = snapshot(ws)
    assert after.pop("out.nc/") == ()
    assert after == before


def test_file_made_at_the_report_folder_name_during_the_run(capsys, ws, monkeypatch, quick_report):
    import camsmooth.smoothing.output as output

    real = output.write_gcode

    def then_a_file(path, *args, **kwargs):
        written = real(path, *args, **kwargs)
        (ws / "rep").write_text("another program's file where the report goes\n")
        return written

    monkeypatch.setattr(output, "write_gcode", then_a_file)
    (ws / "out.csv").write_text("earlier\n")
    before = snapshot(ws)
    code, err = run(capsys, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc", "--report", "rep"])
    assert code == 2, err
    msg = one_message(err)
    assert "rep" in msg and "folder" in msg and TAG not in msg, msg
    after = snapshot(ws)
    assert after.pop("rep")  # the other program's file stays
    assert after == before


def test_a_folder_inside_the_report_where_a_report_file_goes(capsys, ws, quick_report):
    """The user's report folder holds a FOLDER named report.html: refused at the commit, before
    the CSV and the G-code move; the user's folder and its files untouched."""
    (ws / "keep" / "report.html").mkdir()
    (ws / "keep" / "report.html" / "mine.txt").write_text("mine\n")
    before = snapshot(ws)
    code, err = run(capsys, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc", "--report", "keep"])
    assert code == 2, err
    msg = one_message(err)
    assert "keep/report.html" in msg and TAG not in msg, msg
    assert snapshot(ws) == before


# ----------------------------------------------------------------------------------------------
# 3. write() fails half-way through the second output: the disk is full
class _FullDisk:
    """A text file whose write() takes ``room`` characters, then raises ENOSPC like write(2)."""

    def __init__(self, fh, room: int) -> None:
        self.fh, self.room = fh, room

    def write(self, text: str) -> int:
        if len(text) > self.room:
            self.fh.write(text[:self.room])
            self.fh.flush()
            self.room = 0
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.room -= len(text)
        return self.fh.write(text)

    def __getattr__(self, name):
        return getattr(self.fh, name)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.fh.close()


def test_disk_full_while_writing_the_gcode(capsys, ws, monkeypatch):
    """The real G-code writer, its file's write() failing after 200 characters: the CSV is
    complete on its temporary by then, and nothing of either stays."""
    real_open = Path.open
    hit = []

    def open_(self, mode="r", *args, **kwargs):
        fh = real_open(self, mode, *args, **kwargs)
        if "w" in mode and "out.nc" in self.name:
            hit.append(self.name)
            return _FullDisk(fh, 200)
        return fh

    monkeypatch.setattr(Path, "open", open_)
    (ws / "out.csv").write_text("earlier\n")
    before = snapshot(ws)
    code, err = run(capsys, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc"])
    assert hit, "the G-code was not written through Path.open"
    assert code == 2, err
    msg = one_message(err)
    assert "No space left on device" in msg and "out.nc" in msg and TAG not in msg, msg
    assert snapshot(ws) == before


# ----------------------------------------------------------------------------------------------
# 4. SIGTERM to a real process while the second output is half written by the real writer
HOOK = """
import os, sys, time
from pathlib import Path

marker, name = Path(sys.argv[1]), sys.argv[2]
real = Path.write_text

def slow(self, data, *args, **kwargs):
    if name not in self.name:
        return real(self, data, *args, **kwargs)
    with open(self, "w") as fh:  # half of it, on the disk, then the process is stopped there
        fh.write(data[: len(data) // 2])
        fh.flush()
        os.fsync(fh.fileno())
    marker.write_text(self.name)
    time.sleep(60)
    return real(self, data, *args, **kwargs)

Path.write_text = slow
from camsmooth.cli.main import main
sys.exit(main(sys.argv[3:]))
"""


def _sigterm_mid_write(ws: Path, tmp: Path, name: str, argv: list[str]) -> tuple[subprocess.Popen, str, str]:
    marker = tmp / "ready"
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", HOOK, str(marker), name, *argv], cwd=ws, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not marker.exists():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the writer was never reached"
            time.sleep(0.05)
        half = marker.read_text()
        temps = [p.name for p in ws.rglob(f"*{TAG}*")]
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert half in temps  # the half-written file was a temporary, beside the others
    return proc, err, half


@pytest.mark.parametrize("verb,argv,second,first", [
    ("smooth", SMOOTH + ["-o", "out.csv", "--gcode", "out.nc"], "out.nc", "out.csv"),
    ("calibrate", CALIBRATE + ["-o", "cal.json", "--report", "rep.json"], "rep.json", "cal.json"),
])
def test_sigterm_while_the_second_output_is_half_written(ws, tmp_path_factory, verb, argv, second, first):
    (ws / first).write_text("an earlier run's output\n")
    (ws / second).write_text("an earlier run's second output\n")
    before = snapshot(ws)
    proc, err, half = _sigterm_mid_write(ws, tmp_path_factory.mktemp("sig"), second, argv)
    assert proc.returncode == 143, err
    assert "terminated" in one_message(err)
    assert snapshot(ws) == before


# ----------------------------------------------------------------------------------------------
# 5. the case in a real process: an unreachable Z with G-code, an earlier out.csv
def test_unreachable_z_in_a_real_process_leaves_the_earlier_csv(ws):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    ok = subprocess.run([sys.executable, "-m", "camsmooth", *SMOOTH, "-o", "out.csv"], cwd=ws, env=env,
                        capture_output=True, text=True, timeout=300)
    assert ok.returncode == 0, ok.stderr
    # the pivot sits 150 mm above the tool tip on a part at z = 0: a Z travel ending at 120 mm
    # cannot hold it
    (ws / "low.toml").write_text('[machine]\nkind = "AB-head"\npivot = 150.0\n'
                                 "[axis.A]\nmin = -100.0\nmax = 100.0\nvmax = 60.0\namax = 300.0\n"
                                 "[axis.B]\nmin = -100.0\nmax = 100.0\nvmax = 60.0\namax = 300.0\n"
                                 "[axis.Z]\nmin = -1000.0\nmax = 120.0\n")
    before = snapshot(ws)
    p = subprocess.run([sys.executable, "-m", "camsmooth", *SMOOTH, "--machine", "low.toml", "-o", "out.csv",
                        "--gcode", "out.nc"], cwd=ws, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 2, p.stderr
    msg = one_message(p.stderr)
    assert "Z" in msg and "travel" in msg, msg
    assert snapshot(ws) == before  # out.csv as the earlier run wrote it, no out.nc, no temporary


# ----------------------------------------------------------------------------------------------
# 6. the API's writers replace a file, they never write into it (issue 12's planted bug: a result
#    CSV written in place passed, because the failure tests raised before any file was opened)
def _writers():
    from camsmooth.machine.model import ErrorModel
    from camsmooth.smoothing.output import write_gcode, write_result_csv
    from tests.test_output import CUTTER, MACHINE, make_result

    res = make_result(n_rows=2, n_pts=20)
    return {
        "result csv": lambda p: write_result_csv(p, res),
        "gcode": lambda p: write_gcode(p, res, MACHINE, CUTTER, 1500.0),
        "cc csv": lambda p: write_cc_csv(p, plane_path()),
        "model json": lambda p: ErrorModel(geometric={"EY0A": 0.02}).to_json(p),
    }


@pytest.mark.parametrize("writer", ["result csv", "gcode", "cc csv", "model json"])
def test_writer_replaces_the_file_and_never_writes_into_it(tmp_path, writer):
    """A second name (hard link) of the earlier file keeps the earlier content: the new file is a
    new inode renamed into place, so a reader of the old one never sees a half-written file."""
    target, link = tmp_path / "out", tmp_path / "earlier"
    target.write_text("earlier\n")
    os.link(target, link)
    _writers()[writer](target)
    assert link.read_text() == "earlier\n"
    assert target.read_text() != "earlier\n" and target.stat().st_size > 20
    assert sorted(p.name for p in tmp_path.iterdir()) == ["earlier", "out"]


@pytest.mark.parametrize("writer", ["result csv", "cc csv"])
def test_table_writer_failing_half_way_leaves_the_earlier_file(tmp_path, monkeypatch, writer):
    """polars' CSV writer fails half-way (it has written part of its file): the earlier file is
    intact and no partial file or temporary is left."""
    import polars as pl

    def half(self, file, *args, **kwargs):
        Path(file).write_text("row,idx\n1,")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(pl.DataFrame, "write_csv", half)
    target = tmp_path / "out.csv"
    target.write_text("earlier\n")
    with pytest.raises(OSError):
        _writers()[writer](target)
    assert target.read_text() == "earlier\n"
    assert [p.name for p in tmp_path.iterdir()] == ["out.csv"]


# ----------------------------------------------------------------------------------------------
# 7. SIGTERM while the rows are solved in worker processes: no output, no process left behind
def _descendants(pid: int) -> set[int]:
    """Every process below ``pid`` (from /proc)."""
    children: dict[int, list[int]] = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                ppid = int((d / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(ppid, []).append(int(d.name))
    out, todo = set(), [pid]
    while todo:
        for c in children.get(todo.pop(), []):
            if c not in out:
                out.add(c)
                todo.append(c)
    return out


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs /proc")
def test_sigterm_while_workers_solve_rows(ws, tmp_path_factory):
    import threading

    from camsmooth.geometry.paths import zigzag_path
    from camsmooth.geometry.surfaces import Sinusoid, tessellate_to_tolerance

    s = Sinusoid(amplitude=3.0, kx=2 * np.pi / 50.0, ky=2 * np.pi / 70.0, u_range=(0.0, 50.0), v_range=(0.0, 60.0))
    tessellate_to_tolerance(s, chord_tol=1e-3).export(ws / "eggbox.ply")
    write_cc_csv(ws / "egg.csv", zigzag_path(s, stepover=2.0, spacing=1.0, feed=2000.0))
    (ws / "out.csv").write_text("an earlier run's output\n")
    before = snapshot(ws)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-m", "camsmooth", "smooth", "egg.csv", "--surface", "eggbox.ply",
                             "--cutter-radius", "3", "--corner-radius", "1", "--lead", "2:20", "--tilt", "-15:15",
                             "--workers", "2", "-o", "out.csv", "--gcode", "out.nc"], cwd=ws, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    chunks: list[bytes] = []

    def read() -> None:
        while chunk := os.read(proc.stderr.fileno(), 4096):
            chunks.append(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        deadline = time.monotonic() + 180
        workers: set[int] = set()
        while True:  # the NLP's progress bar is up and the pool has started its workers
            assert proc.poll() is None, b"".join(chunks).decode()
            assert time.monotonic() < deadline, "the NLP never started in workers"
            if b"nlp rows" in b"".join(chunks):
                workers = _descendants(proc.pid)
                if len(workers) >= 2:
                    break
            time.sleep(0.05)
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    reader.join(timeout=10)
    text = b"".join(chunks).decode()
    assert proc.returncode == 143, text
    last = [ln for ln in text.replace("\r", "\n").splitlines() if ln.startswith("camsmooth")]
    assert len(last) == 1 and "terminated" in last[0], text
    assert snapshot(ws) == before
    deadline = time.monotonic() + 30  # the workers and the fork server follow their parent out
    while any(_alive(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not [p for p in workers if _alive(p)], "worker processes outlived the command"
