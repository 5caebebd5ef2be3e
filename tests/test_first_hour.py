"""The first hour of a new user (issue 32): ``analyze --report`` on every machine kind names the
machine's own rotary axes (it crashed with KeyError 'B_range_deg' on A/C and B/C machines), full
tool-path names and the limit each violation breaks, ``--version``, progress only on a terminal,
and LinuxCNC simulations that run beside another LinuxCNC on the same machine and say why when
they fail.

Expected values are computed here from the tool axes the test writes (closed forms of each
kind's inverse, docs/CONVENTIONS.md), not taken from camsmooth's output.
"""

from __future__ import annotations

import fcntl
import io
import json
import os
import pty
import shutil
import struct
import subprocess
import sys
import tempfile
import termios
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from camsmooth.cli.main import main
from tests.conftest import ROOT

# a short program: the tool axis tilted 35..45 deg from z at azimuth 20..70 deg, one row per tool
# path, both rotary axes of every kind moving; the tips along x at y = Y0
N = 24
TILT = np.radians(np.linspace(35.0, 45.0, N))
AZIM = np.radians(np.linspace(20.0, 70.0, N))
AXES = np.column_stack([np.sin(TILT) * np.cos(AZIM), np.sin(TILT) * np.sin(AZIM), np.cos(TILT)])
Y0 = 5.0
TIPS = np.column_stack([np.linspace(-20.0, 20.0, N), np.full(N, Y0), np.zeros(N)])
LONG = "VARIABLE_AXIS_GUIDING_CURVES_FINISH_"  # 36 characters: longer than the 24 the summary kept
NAMES = (LONG + "WALL_LEFT", LONG + "WALL_RIGHT")

KIND_AXES = {"AB-head": ("A", "B"), "AC-table": ("A", "C"), "BC-table": ("B", "C"), "BC-head-table": ("B", "C")}


def _apt(path: Path) -> Path:
    """Two tool paths (NAMES) of the same N poses, feed 1000 mm/min, a D 10 R 1 mill."""
    lines = []
    for name in NAMES:
        lines += [f"TOOL PATH/{name},TOOL,MILL", "TLDATA/MILL,10.0000,1.0000,60.0000,0.0000,0.0000",
                  "FEDRAT/MMPM,1000.0000"]
        lines += [f"GOTO/{p[0]:.4f},{p[1]:.4f},{p[2]:.4f},{a[0]:.7f},{a[1]:.7f},{a[2]:.7f}"
                  for p, a in zip(TIPS, AXES, strict=True)]
        lines.append("END-OF-PATH")
    path.write_text("\n".join(lines) + "\n")
    return path


def _machine_toml(path: Path, kind: str, y_max: float = 1000.0) -> Path:
    """A machine of ``kind`` whose rotary travel leaves one inverse branch for these axes: the
    tilt axis (A or B) within [-100, 10] deg on a table (the first branch, tilt <= 0) and within
    +-100 deg on the head (B in [-90, 90]); C continuous. Y travel [-1000, y_max] mm."""
    lines = ["[machine]", f'name = "test {kind}"', f'kind = "{kind}"']
    if kind in ("AB-head", "BC-head-table"):
        lines.append("pivot = 150.0")
    if kind != "AB-head":
        lines.append("table_centre = [0.0, 0.0, -20.0]")
    for ax in KIND_AXES[kind]:
        lines.append(f"[axis.{ax}]")
        if ax != "C":
            lines += (["min = -100.0", "max = 100.0"] if kind == "AB-head" else ["min = -100.0", "max = 10.0"])
        lines += ["vmax = 60.0", "amax = 300.0"]
    lines += ["[axis.X]", "min = -1000.0", "max = 1000.0", "[axis.Y]", "min = -1000.0", f"max = {y_max}",
              "[axis.Z]", "min = -1000.0", "max = 1000.0"]
    path.write_text("\n".join(lines) + "\n")
    return path


def _expected_deg(kind: str) -> dict[str, np.ndarray]:
    """The rotary angles (deg) of AXES by each kind's closed-form inverse (docs/CONVENTIONS.md):
    AB head T = Rx(A) Ry(B) e_z = (sin B, -sin A cos B, cos A cos B); A/C table T = Rz(C) Rx(A) e_z
    = (sin A sin C, -sin A cos C, cos A); B/C T = Rz(C) Ry(B) e_z = (sin B cos C, sin B sin C, cos B);
    on the tables the first branch (tilt <= 0)."""
    i, j, k = AXES.T
    if kind == "AB-head":
        return {"A": np.degrees(np.arctan2(-j, k)), "B": np.degrees(np.arcsin(i))}
    tilt = -np.arccos(k)
    s = np.sin(tilt)
    if kind == "AC-table":
        return {"A": np.degrees(tilt), "C": np.degrees(np.arctan2(i / s, -j / s))}
    return {"B": np.degrees(tilt), "C": np.degrees(np.arctan2(j / s, i / s))}


@pytest.mark.parametrize("kind", tuple(KIND_AXES))
def test_analyze_report_names_the_machines_rotary_axes(kind, tmp_path, capsys):
    """analyze --report --json on each kind: exit 0 (was 70 on A/C and B/C machines), the JSON's
    ranges are the machine's two rotary axes with the closed-form angles, the report's table,
    caption and figure name those axes and no other."""
    prog = _apt(tmp_path / "two.cls")
    toml = _machine_toml(tmp_path / "machine.toml", kind)
    out, rep = tmp_path / "a.json", tmp_path / "report"
    assert main(["analyze", str(prog), "--machine", str(toml), "--json", str(out), "--report", str(rep)]) == 0
    doc = json.loads(out.read_text())
    r1, r2 = KIND_AXES[kind]
    assert doc["rotary"] == [r1, r2]
    want = _expected_deg(kind)
    for tp in doc["toolpaths"]:
        assert sorted(k for k in tp if k.endswith("_range_deg")) == sorted([f"{r1}_range_deg", f"{r2}_range_deg"])
        for r in (r1, r2):
            assert tp[f"{r}_range_deg"] == pytest.approx([want[r].min(), want[r].max()], abs=2e-3), (kind, r)
        assert tp["branch"].endswith("(the first branch of docs/METHODS.md section 1.4)")
    assert sorted(p.name for p in rep.iterdir()) == ["program_axes.png", "report.html"]
    html = (rep / "report.html").read_text()
    other = ({"A", "B", "C"} - {r1, r2}).pop()
    assert f"<th>{r1} (deg)</th>" in html and f"<th>{r2} (deg)</th>" in html
    assert f"<th>{other} (deg)</th>" not in html
    assert f"Rotary axes {r1} and {r2}" in html
    for name in NAMES:  # full operation names, in the table and the summary
        assert f"<td>{name}</td>" in html
    printed = capsys.readouterr().out
    assert f"{r1} deg" in printed and f"{r2} deg" in printed and f"{other} deg" not in printed
    for name in NAMES:
        assert sum(ln.startswith(name + " ") for ln in printed.splitlines()) == 1, printed

    from camsmooth.machine.kinematics import load_machine
    from camsmooth.post import load_program
    from camsmooth.report.analysis import axes_figure
    from camsmooth.smoothing.analysis import analyze_program

    machine = load_machine(toml)
    series = analyze_program(load_program(prog), machine).series
    assert {k.split()[0] for k in series if k != "t"} == {r1, r2}
    fig = axes_figure(series, machine)
    for ax in fig.axes:
        assert [t.get_text() for t in ax.get_legend().get_texts()] == [r1, r2]
    assert f"rotary axes {r1} and {r2}" in fig._suptitle.get_text()


def test_analyze_report_of_the_shipped_table_sample(tmp_path, capsys):
    """The issue's command on the shipped A/C sample (surfaces/dome.cls, cut to its first 125
    GOTOs, with surfaces/dome_machine.toml, a LinuxCNC machine): exit 0 (was 70), A and C named,
    the LinuxCNC controller's time in the summary, and the angles those of the closed-form
    inverse of the file's tool axes on the branch the JSON names (A in (0, 180) deg: A = acos k,
    C = atan2(i / sin A, -j / sin A))."""
    lines = (ROOT / "surfaces" / "dome.cls").read_text().splitlines()
    head = lines[:130] + ["END-OF-PATH"]
    prog = tmp_path / "dome_head.cls"
    prog.write_text("\n".join(head) + "\n")
    out, rep = tmp_path / "a.json", tmp_path / "report"
    assert main(["analyze", str(prog), "--machine", str(ROOT / "surfaces" / "dome_machine.toml"), "--json", str(out),
                 "--report", str(rep)]) == 0
    tp = json.loads(out.read_text())["toolpaths"][0]
    assert tp["controller"] == "linuxcnc" and "B_range_deg" not in tp
    ijk = np.array([[float(v) for v in ln.split("/")[1].split(",")[3:6]] for ln in head if ln.startswith("GOTO/")])
    ijk = ijk[1:]  # the first GOTO follows RAPID: the approach, not a cut
    assert tp["points"] == len(ijk)
    assert tp["branch"] == f"A in (0, 180) deg at {len(ijk)} points (the second branch)"
    a = np.arccos(ijk[:, 2])
    c = np.degrees(np.unwrap(np.arctan2(ijk[:, 0] / np.sin(a), -ijk[:, 1] / np.sin(a))))
    assert tp["A_range_deg"] == pytest.approx([np.degrees(a).min(), np.degrees(a).max()], abs=2e-3)
    assert tp["C_range_deg"] == pytest.approx([c.min(), c.max()], abs=2e-3)
    html = (rep / "report.html").read_text()
    assert "<th>A (deg)</th>" in html and "<th>C (deg)</th>" in html and "<th>B (deg)</th>" not in html
    printed = capsys.readouterr().out
    assert "linuxcnc s" in printed and "A deg" in printed and "C deg" in printed


def test_analyze_names_the_limit_each_violation_breaks(tmp_path, capsys):
    """Y travel of the AB head ends at 60 mm: the pivot (tip + 150 mm x tool axis, METHODS
    section 1) goes past it where Y0 + 150 j > 60; the count, written '<n> Y travel', is in the
    summary, the JSON and the report of each tool path."""
    prog = _apt(tmp_path / "two.cls")
    toml = _machine_toml(tmp_path / "machine.toml", "AB-head", y_max=60.0)
    over = int(np.sum(Y0 + 150.0 * AXES[:, 1] > 60.0))
    assert 0 < over < N
    out, rep = tmp_path / "a.json", tmp_path / "report"
    assert main(["analyze", str(prog), "--machine", str(toml), "--json", str(out), "--report", str(rep)]) == 0
    doc = json.loads(out.read_text())
    assert doc["limits"]["Y"]["max"] == 60.0 and doc["limits"]["Y"]["unit"] == "mm"
    for tp in doc["toolpaths"]:
        assert tp["violations"]["Y travel"] == over
        assert tp["violations_programmed"]["Y travel"] == over
        assert tp["Y_range_mm"][1] == pytest.approx(Y0 + 150.0 * AXES[:, 1].max(), abs=1e-3)
    printed = capsys.readouterr().out
    lines = [ln for ln in printed.splitlines() if ln.startswith(LONG)]
    assert len(lines) == 2 and all(f"{over} Y travel" in ln for ln in lines), printed
    html = (rep / "report.html").read_text()
    assert html.count(f"{over} Y travel") >= 2


def test_version_is_the_installed_packages(tmp_path, capsys):
    """camsmooth --version prints the version of the installed package, which is pyproject's."""
    want = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    exe = Path(sys.executable).parent / "camsmooth"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "camsmooth"]
    proc = subprocess.run([*cmd, "--version"], capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert proc.returncode == 0 and proc.stdout.strip() == f"camsmooth {want}", proc
    assert main(["--version"]) == 0  # the parser's option says the same
    assert capsys.readouterr().out.strip() == f"camsmooth {want}"


def test_progress_line_on_a_real_terminal():
    """On a terminal (a pty as stderr, 120 columns) the progress line names each step and its
    elapsed time, and is cleared at the end. (A pty reporting 0 columns, as a bare pty does, would
    get an empty tqdm line: Steps falls back to a width.)"""
    code = ("import time\nfrom camsmooth.progress import Steps\n"
            "with Steps(2) as s:\n    with s.step('first step'): time.sleep(0.7)\n"
            "    with s.step('second step'): pass\n")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    for cols in (120, 0):
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, cols, 0, 0))
        proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=slave, env=env)
        os.close(slave)
        chunks = []
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:  # the child closed the pty
                break
            if not data:
                break
            chunks.append(data)
        proc.wait(timeout=60)
        os.close(master)
        shown = b"".join(chunks).decode(errors="replace")
        assert proc.returncode == 0, shown
        assert "camsmooth: 1/2 first step [00:00]" in shown and "camsmooth: 2/2 second step" in shown, shown
        assert shown.endswith("\r"), shown  # cleared (leave=False): the next output starts a clean line


class _Terminal(io.StringIO):
    """A stderr that says it is a terminal."""

    def isatty(self) -> bool:
        return True


@pytest.mark.parametrize("stream, quiet, expect", [(_Terminal, False, True), (_Terminal, True, False),
                                                    (io.StringIO, False, False)], ids=["terminal", "quiet", "pipe"])
def test_progress_only_on_a_terminal_and_not_with_quiet(stream, quiet, expect, tmp_path, monkeypatch, capsys):
    """The progress line goes to a terminal unless --quiet, and never to a pipe or a file."""
    prog = _apt(tmp_path / "two.cls")
    err = stream()
    monkeypatch.setattr(sys, "stderr", err)
    assert main(["analyze", str(prog), *(["--quiet"] if quiet else [])]) == 0
    assert (f"camsmooth: 1/2 {NAMES[0]}" in err.getvalue()) == expect, err.getvalue()
    if not expect:
        assert err.getvalue() == ""


# ----------------------------------------------------------------------------------------------
# LinuxCNC beside another LinuxCNC
def _linuxcnc_ready() -> str | None:
    from camsmooth.controller.linuxcnc_sim import isolation_missing, linuxcnc_missing

    return linuxcnc_missing() or isolation_missing()


def _default_linuxcnc_machine():
    from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, machine_from_dict

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["post"] = {"dialect": "linuxcnc", "mode": "machine"}
    return machine_from_dict(data, "<test machine>")


@pytest.fixture
def other_linuxcnc():
    """A LinuxCNC started the way a user starts one (``linuxcnc sim.ini``, not isolated, as the
    unprivileged user camsmooth's non-isolated runs use): it holds /tmp/linuxcnc.lock, HAL's
    shared memory and linuxcncsvr's port until the test ends."""
    from camsmooth.controller import linuxcnc_sim as sim

    if sim.LINUXCNC_LOCK.exists():
        pytest.skip("a LinuxCNC already runs here: this test starts its own")
    d = Path(tempfile.mkdtemp(prefix="camsmooth-other-lcnc-", dir="/tmp"))  # the user can reach it
    ini = sim._ini(_default_linuxcnc_machine(), d, None)
    (d / "sim.hal").write_text(sim._HAL)
    (d / "driver.py").write_text("#!/usr/bin/python3\nimport time\ntime.sleep(600)\n")
    os.chmod(d / "driver.py", 0o755)
    (d / "tool.tbl").write_text("T1 P1 Z0 D10 ;\n")
    uid, gid = sim._user(sim.LINUXCNC_USER)
    os.chmod(d, 0o777)
    for p in (d, *d.iterdir()):
        os.chown(p, uid, gid)
    env = {"PATH": "/usr/bin:/bin:/usr/sbin:/sbin", "HOME": str(d)}
    proc = subprocess.Popen(["linuxcnc", str(ini)], cwd=d, env=env, stdin=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, user=uid, group=gid,
                            start_new_session=True)
    end = time.monotonic() + 60
    while not (sim.LINUXCNC_LOCK.exists() and _pids("milltask")):
        assert proc.poll() is None and time.monotonic() < end, "the other LinuxCNC did not start"
        time.sleep(0.2)
    time.sleep(1.0)
    yield proc
    os.killpg(proc.pid, 15)  # its script traps SIGTERM and cleans up
    try:
        proc.wait(timeout=60)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, 9)
        proc.wait()
    shutil.rmtree(d, ignore_errors=True)


def _pids(name: str, session: int | None = None) -> set[int]:
    """The pids of the processes called ``name``; with ``session``, only those of that session
    (another simulation of the suite, running beside it, has its own)."""
    out = subprocess.run(["pidof", name], capture_output=True, text=True).stdout

    def sid(p: int) -> int | None:
        try:
            return os.getsid(p)
        except OSError:  # gone since pidof
            return None

    return {int(p) for p in out.split() if session is None or sid(int(p)) == session}


@pytest.mark.skipif(_linuxcnc_ready() is not None, reason=f"LinuxCNC simulation not isolable: {_linuxcnc_ready()}")
def test_simulation_runs_beside_another_linuxcnc_and_leaves_it_running(other_linuxcnc, tmp_path):
    """With another LinuxCNC up, a simulation runs to the end (a 10 mm move at 600 mm/min: 1 s of
    motion) and the other one is still there afterwards, its lock and milltask untouched (the
    start script used to clean the other instance up, and the other's clean-up to remove the
    simulation's HAL memory)."""
    from camsmooth.controller.linuxcnc_sim import LINUXCNC_LOCK, simulate

    before = _pids("milltask", other_linuxcnc.pid)
    assert before
    prog = tmp_path / "move.ngc"
    prog.write_text("G21 G90\nG01 X10 F600\nM30\n")
    run = simulate(prog, _default_linuxcnc_machine(), timeout=60)
    moving = np.flatnonzero(np.abs(np.diff(run.joints[:, 0])) > 0)
    assert run.joints[-1, 0] == pytest.approx(10.0, abs=1e-6)
    assert (moving[-1] - moving[0] + 1) * run.servo_period >= 1.0  # at least 10 mm / (600 mm/min)
    assert other_linuxcnc.poll() is None and LINUXCNC_LOCK.exists()
    assert before <= _pids("milltask", other_linuxcnc.pid)


@pytest.mark.skipif(_linuxcnc_ready() is not None, reason=f"LinuxCNC simulation not isolable: {_linuxcnc_ready()}")
def test_a_failed_simulation_says_why(tmp_path):
    """A program LinuxCNC refuses (a word it does not know) fails with LinuxCNC's own message in
    the error, not an empty one."""
    from camsmooth.controller.linuxcnc_sim import simulate

    prog = tmp_path / "bad.ngc"
    prog.write_text("G21 G90\nG01 X1 F600\nG01 X2 Q@\nM30\n")
    with pytest.raises(RuntimeError) as exc:
        simulate(prog, _default_linuxcnc_machine(), timeout=30)
    text = str(exc.value)
    assert "exit" in text and "LinuxCNC" in text
    assert "linuxcnc error" in text.lower() or "program did not finish" in text, text


def test_run_lock_serialises_and_gives_up_after_the_bounded_wait(tmp_path, monkeypatch):
    """Two simulations take turns on RUN_LOCK; a wait that runs out names the holder's pid."""
    import fcntl

    from camsmooth.controller import linuxcnc_sim as sim

    lock = tmp_path / "run.lock"
    monkeypatch.setattr(sim, "RUN_LOCK", lock)
    holder = subprocess.Popen([sys.executable, "-c", (
        "import fcntl, os, sys, time\n"
        f"fd = os.open({str(lock)!r}, os.O_RDWR | os.O_CREAT)\n"
        "fcntl.flock(fd, fcntl.LOCK_EX); os.pwrite(fd, b'%d\\n' % os.getpid(), 0)\n"
        "print('held', flush=True); time.sleep(30)\n")], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        t0 = time.monotonic()
        with pytest.raises(RuntimeError, match=f"pid {holder.pid}"), sim._turn(1.0):
            pass
        assert 1.0 <= time.monotonic() - t0 < 5.0
    finally:
        holder.kill()
        holder.wait()
    with sim._turn(1.0):  # free again: taken at once, and exclusive while held
        fd = os.open(lock, os.O_RDWR)
        with pytest.raises(BlockingIOError):
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.close(fd)
