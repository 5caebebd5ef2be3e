"""Bad input and faults across every verb (issue 9): each case asserts the exit status, one message
without a traceback, nothing left behind and no user file touched.

Every case runs in a fresh folder holding the inputs and a user file; the folder's full state
(names, sizes, contents, modification times, hidden files included) is compared before and after.
The CLI runs in-process (camsmooth.cli.main.main); only the signal cases use a subprocess.
"""

from __future__ import annotations

import errno
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from camsmooth.cli.main import main
from camsmooth.errors import InputError
from camsmooth.geometry.paths import CCPath, check_contact_with_mesh, check_normals_against_mesh
from camsmooth.io.ccpath import write_cc_csv
from tests.conftest import ROOT, snapshot, user_workspace

NP_REPR = re.compile(r"np\.[a-z_]+\d*\(")


# ----------------------------------------------------------------------------------------------
# inputs: a 50 x 40 mm plane z = 0 (normals +z), a 3-row x 5-point path on it, models, measurements
def plane_mesh(flip: bool = False, size: tuple[float, float] = (50.0, 40.0), n: int = 6) -> trimesh.Trimesh:
    xs, ys = np.linspace(-5.0, size[0] - 5.0, n), np.linspace(-5.0, size[1] - 5.0, n)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a, b = (i * n + j).ravel(), ((i + 1) * n + j).ravel()
    F = np.concatenate([np.column_stack([a, b, b + 1]), np.column_stack([a, b + 1, a + 1])])
    return trimesh.Trimesh(V, F[:, ::-1] if flip else F, process=False)


def plane_path(z: float = 0.0) -> CCPath:
    pts, rows = [], []
    for r in range(3):
        xs = np.linspace(5.0, 35.0, 5)
        pts += [[x, 5.0 + 10.0 * r, z] for x in (xs if r % 2 == 0 else xs[::-1])]
        rows += [r] * 5
    pts = np.array(pts)
    return CCPath(pts, np.tile([0.0, 0.0, 1.0], (len(pts), 1)), np.array(rows), None, None, "p.csv")


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    from benchmarks.synthetic import make_program
    from camsmooth.diagnosis.recordings import write_program_csv, write_recording_csv
    from camsmooth.diagnosis.simulator import physics_from_settings, simulate_recording
    from camsmooth.machine import calibration, simulate
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.machine.model import ErrorModel

    d = tmp_path_factory.mktemp("inputs")
    plane_mesh().export(d / "plane.ply")
    plane_mesh(flip=True).export(d / "flipped.ply")
    write_cc_csv(d / "p.csv", plane_path())
    write_cc_csv(d / "above.csv", plane_path(z=100.0))
    model = ErrorModel(geometric={"EY0A": 0.02, "EZ0B": -0.01, "EZ0T": 0.03})
    model.to_json(d / "model.json")
    machine = load_machine()
    calibration.write_probe_csv(d / "probe.csv", simulate.simulate_probe(
        model, machine, poses=simulate.default_probe_poses(machine, 5, 90.0), seed=1))
    calibration.write_spindle_csv(d / "spindle.csv", simulate.simulate_spindle(model, samples_per_rev=12, seed=1))
    prog = make_program("lines", duration=2.0, rate=100.0, seed=1)
    write_program_csv(d / "program.csv", prog)
    write_recording_csv(d / "recording.csv", simulate_recording(
        prog, None, physics_from_settings({"Kv_X": 40.0}), channels=["axes"], noise={"axes": 0.001}, seed=1))
    (d / "binary.dat").write_bytes(bytes(range(256)) * 4)
    # a sample folder for `demo --samples`
    (d / "samples").mkdir()
    shutil.copy(d / "p.csv", d / "samples" / "tiny_path.csv")
    shutil.copy(d / "plane.ply", d / "samples" / "tiny.ply")
    return d


@pytest.fixture
def ws(data, tmp_path, monkeypatch) -> Path:
    """A working folder with the inputs, a user file and a user folder; the current folder."""
    user_workspace(data, tmp_path)
    (tmp_path / "adir").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.fixture
def no_render(monkeypatch):
    """Quick reports: no 3D render child process and no PNG rasterising (seconds each; the real
    report is tested in test_report.py). The report's files and folder handling are the real ones."""
    import camsmooth.report.smoothing as rs

    real = rs.write_report
    monkeypatch.setattr(rs, "write_report", lambda result, out, **kw: real(result, out, render_3d=False, **kw))
    monkeypatch.setattr(rs, "_save_png", lambda fig, path: Path(path).write_bytes(b"\x89PNG stand-in"))


SMOOTH = ["smooth", "p.csv", "--surface", "plane.ply", "--cutter-radius", "4", "--corner-radius", "1",
          "--feed", "1000", "--lead", "2:20", "--tilt", "-15:15", "--quiet", "--method", "spline"]


def run(capsys, argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def one_message(err: str) -> str:
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, f"expected one message, got:\n{err}"
    assert "Traceback" not in err and not NP_REPR.search(err), err
    assert lines[0].startswith("camsmooth"), err
    return lines[0]


def fails(capsys, ws: Path, argv, *needles: str, code: int = 2) -> str:
    """Run, expect ``code`` and one message holding every needle; the folder must be unchanged."""
    before = snapshot(ws)
    rc, _, err = run(capsys, argv)
    assert rc == code, err
    msg = one_message(err)
    for n in needles:
        assert n in msg, msg
    assert snapshot(ws) == before, "files were left behind or changed"
    assert ".camsmooth-" not in msg, f"a temporary name in the message: {msg}"
    return msg


# ----------------------------------------------------------------------------------------------
# 1. report folders never delete user files
def test_report_into_folder_keeps_the_users_files(capsys, ws, no_render):
    rc, _, err = run(capsys, SMOOTH + ["-o", "out.csv", "--report", "keep"])
    assert rc == 0, err
    assert (ws / "keep" / "notes.txt").read_text() == "keep me\n"
    assert (ws / "keep" / "report.html").stat().st_size > 0
    assert not [p for p in ws.rglob("*") if ".camsmooth-" in p.name]
    # a second run replaces the report's own files and still keeps the user's
    html = (ws / "keep" / "report.html").stat().st_mtime_ns
    time.sleep(0.01)
    assert run(capsys, SMOOTH + ["-o", "out.csv", "--report", "keep"])[0] == 0
    assert (ws / "keep" / "report.html").stat().st_mtime_ns > html
    assert (ws / "keep" / "notes.txt").read_text() == "keep me\n"


def test_report_into_current_folder_keeps_inputs_and_outputs(capsys, ws, no_render):
    before = {k: v for k, v in snapshot(ws).items()}
    rc, _, err = run(capsys, SMOOTH + ["-o", "out.csv", "--report", "."])
    assert rc == 0, err
    after = snapshot(ws)
    assert all(after[k] == v for k, v in before.items()), "an existing file was changed"
    assert {"out.csv", "report.html", "clearance.png"} <= set(after)
    assert not [p for p in ws.rglob("*") if ".camsmooth-" in p.name]


def test_force_replaces_the_report_folder_whole(capsys, ws, no_render):
    rc, _, err = run(capsys, SMOOTH + ["-o", "out.csv", "--report", "keep", "--force"])
    assert rc == 0, err
    assert not (ws / "keep" / "notes.txt").exists() and (ws / "keep" / "report.html").exists()
    assert (ws / "user.txt").exists() and (ws / "out.csv").exists()


@pytest.mark.parametrize("target", [".", ".."])
def test_force_refuses_the_current_folder_and_its_parents(capsys, ws, monkeypatch, target):
    monkeypatch.chdir(ws / "keep")  # so that '..' is the test's own folder
    argv = [a if a not in ("p.csv", "plane.ply") else f"../{a}" for a in SMOOTH]
    fails(capsys, ws, argv + ["-o", "../out.csv", "--report", target, "--force"], "current folder")


def test_force_refuses_a_folder_holding_an_input(capsys, ws):
    shutil.copy(ws / "p.csv", ws / "keep" / "p.csv")
    fails(capsys, ws, [*SMOOTH[:1], "keep/p.csv", *SMOOTH[2:], "-o", "out.csv", "--report", "keep", "--force"],
          "keep", "input or output")


def test_force_refuses_a_folder_holding_another_output(capsys, ws):
    fails(capsys, ws, SMOOTH + ["-o", "keep/out.csv", "--report", "keep", "--force"], "input or output")


def test_force_needs_report(capsys, ws):
    fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--force"], "--force", "--report")


def test_report_on_an_existing_file_is_refused(capsys, ws):
    fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--report", "user.txt"], "user.txt", "folder")


def test_diagnose_report_into_folder_keeps_the_users_files(capsys, ws):
    rc, _, err = run(capsys, ["diagnose", "--program", "program.csv", "--recording", "recording.csv",
                              "--out", "f.json", "--report", "keep", "--quiet"])
    assert rc == 0, err
    assert (ws / "keep" / "notes.txt").read_text() == "keep me\n" and (ws / "keep" / "report.html").exists()


def test_diagnose_force_refuses_the_current_folder(capsys, ws):
    fails(capsys, ws, ["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "f.json",
                       "--report", ".", "--force", "--quiet"], "current folder")


def test_demo_keeps_the_users_files_in_out_and_report(capsys, ws, no_render):
    (ws / "keep" / "tiny_report").mkdir()
    (ws / "keep" / "tiny_report" / "mine.txt").write_text("mine\n")
    rc, _, err = run(capsys, ["demo", "--samples", "samples", "--sample", "tiny", "--out", "keep", "--quiet"])
    assert rc == 0, err
    assert (ws / "keep" / "notes.txt").exists() and (ws / "keep" / "tiny_report" / "mine.txt").exists()
    assert {"tiny_smoothed.csv", "tiny_smoothed.nc"} <= {p.name for p in (ws / "keep").iterdir()}


def test_demo_of_one_sample_leaves_another_samples_outputs_alone(capsys, ws, no_render):
    """Issue 19: `demo --sample X` once replaced the report of the sample run before it in OUT."""
    shutil.copy(ws / "samples" / "tiny_path.csv", ws / "samples" / "other_path.csv")
    shutil.copy(ws / "samples" / "tiny.ply", ws / "samples" / "other.ply")
    demo = ["demo", "--samples", "samples", "--out", "d", "--quiet"]
    for sample in ("tiny", "other"):
        rc, _, err = run(capsys, demo + ["--sample", sample])
        assert rc == 0, err
        if sample == "tiny":
            first = snapshot(ws / "d")
    names = {p.name for p in (ws / "d").iterdir()}
    assert names == {f"{s}_{kind}" for s in ("tiny", "other") for kind in ("smoothed.csv", "smoothed.nc", "report")}
    assert (ws / "d" / "other_report" / "report.html").is_file()
    after = snapshot(ws / "d")
    assert {k: v for k, v in after.items() if not str(k).startswith("other")} == first   # tiny's files untouched
    # --force replaces only the sample's own report folder
    rc, _, err = run(capsys, demo + ["--sample", "other", "--force"])
    assert rc == 0, err
    assert {k: v for k, v in snapshot(ws / "d").items() if not str(k).startswith("other")} == first


def test_demo_out_on_a_file_is_refused(capsys, ws):
    fails(capsys, ws, ["demo", "--samples", "samples", "--sample", "tiny", "--out", "user.txt", "--quiet"],
          "user.txt")


# ----------------------------------------------------------------------------------------------
# 2. output paths that cannot be written: one message naming the user's path, nothing left
PROC = pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs /proc")


@pytest.mark.parametrize("extra,needle", [
    (["-o", "adir"], "adir: is a folder"),
    (["-o", "out.csv", "--gcode", "adir"], "adir: is a folder"),
    (["-o", "user.txt/out.csv"], "user.txt: is a file"),
    (["-o", "out.csv", "--gcode", "user.txt/x.nc"], "user.txt: is a file"),
    (["-o", "out.csv", "--gcode", "out.csv"], "named twice"),
    (["-o", "new/sub/out.csv", "--gcode", "adir"], "adir"),  # the folders made for out.csv go again
    pytest.param(["-o", "/proc/camsmooth-out.csv"], "/proc/camsmooth-out.csv: cannot create files", marks=PROC),
    pytest.param(["-o", "out.csv", "--gcode", "/proc/x.nc"], "/proc/x.nc", marks=PROC),
    pytest.param(["-o", "out.csv", "--report", "/proc/rep"], "/proc/rep", marks=PROC),
])
def test_smooth_bad_output_paths(capsys, ws, extra, needle):
    fails(capsys, ws, SMOOTH + extra, needle)


@pytest.mark.skipif(not Path("/sys/kernel").is_dir(), reason="needs /sys")
def test_read_only_place(capsys, ws):
    fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--gcode", "/sys/camsmooth.nc"], "/sys/camsmooth.nc")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_folder(capsys, ws):
    (ws / "ro").mkdir()
    os.chmod(ws / "ro", 0o500)
    try:
        fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--gcode", "ro/x.nc"], "ro/x.nc", "ermission")
    finally:
        os.chmod(ws / "ro", 0o700)


@pytest.mark.parametrize("argv,needle", [
    (["path", "--surface", "plane.ply", "--raster", "--cutter-radius", "4", "--corner-radius", "1", "--stepover",
      "10", "--spacing", "5", "-o", "adir"], "adir"),
    (["calibrate", "probe", "probe.csv", "-o", "adir"], "adir"),
    (["calibrate", "probe", "probe.csv", "-o", "cal.json", "--report", "adir"], "adir"),
    (["calibrate", "spindle", "spindle.csv", "--no-pso", "-o", "user.txt/cal.json"], "user.txt"),
    (["simulate", "probe", "--model", "model.json", "--grid", "3", "-o", "adir"], "adir"),
    (["simulate", "spindle", "--model", "model.json", "-o", "user.txt/x.csv"], "user.txt"),
    (["predict", "out_ok.csv", "--model", "model.json", "-o", "adir"], "adir"),
    (["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "adir", "--quiet"], "adir"),
    (["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "f.json",
      "--model-out", "adir", "--quiet"], "adir"),
    (["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "f.json",
      "--report", "user.txt", "--quiet"], "user.txt"),
    pytest.param(["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "f.json",
                  "--model-out", "/proc/m.json", "--quiet"], "/proc/m.json", marks=PROC),
    pytest.param(["simulate", "ballbar", "--model", "model.json", "--step", "30", "-o", "/proc/b.csv"], "/proc/b.csv",
                 marks=PROC),
])
def test_other_verbs_bad_output_paths(capsys, ws, argv, needle):
    if "out_ok.csv" in argv:
        assert run(capsys, SMOOTH + ["-o", "out_ok.csv"])[0] == 0
    fails(capsys, ws, argv, needle)


# ----------------------------------------------------------------------------------------------
# 3. all outputs of a command as one transaction: a failure after the first file leaves nothing
def _disk_full(path, *args, **kwargs):
    Path(path).write_text("partial")
    raise OSError(errno.ENOSPC, "No space left on device", str(path))


def test_smooth_disk_full_on_the_gcode_leaves_no_csv(capsys, ws, monkeypatch):
    import camsmooth.smoothing.output as out

    monkeypatch.setattr(out, "write_gcode", _disk_full)
    msg = fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc"], "No space left on device")
    assert "out.nc" in msg


def test_smooth_disk_full_on_the_report_leaves_no_csv_or_gcode(capsys, ws, monkeypatch):
    import camsmooth.report.smoothing as rs

    def full(result, folder, **kw):
        (Path(folder) / "axes_angles.png").write_bytes(b"partial")
        raise OSError(errno.ENOSPC, "No space left on device", str(Path(folder) / "clearance.png"))

    monkeypatch.setattr(rs, "write_report", full)
    msg = fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc", "--report", "keep"], "No space")
    assert "keep/clearance.png" in msg  # the user's folder, not the temporary one


def test_smooth_failure_keeps_the_previous_outputs(capsys, ws, monkeypatch):
    """An earlier run's outputs survive a failed run unchanged (not replaced, not removed)."""
    assert run(capsys, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc"])[0] == 0
    import camsmooth.smoothing.output as out

    monkeypatch.setattr(out, "write_gcode", _disk_full)
    fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc"], "No space")


def test_smooth_gcode_beyond_travel_leaves_no_csv(capsys, ws):
    (ws / "tight.toml").write_text("[machine]\nkind = \"AB-head\"\npivot = 150.0\n"
                                   "[axis.A]\nmin = -100.0\nmax = 100.0\nvmax = 60.0\namax = 300.0\n"
                                   "[axis.B]\nmin = -100.0\nmax = 100.0\nvmax = 60.0\namax = 300.0\n"
                                   "[axis.Z]\nmin = -1000.0\nmax = 155.0\n")
    fails(capsys, ws, SMOOTH + ["--machine", "tight.toml", "-o", "out.csv", "--gcode", "out.nc"], "travel")


def test_calibrate_disk_full_on_the_report_leaves_no_model(capsys, ws, monkeypatch):
    import camsmooth.io.atomic as atomic

    monkeypatch.setattr(atomic, "write_text_atomic", _disk_full)
    fails(capsys, ws, ["calibrate", "probe", "probe.csv", "-o", "cal.json", "--report", "rep.json"],
          "rep.json", "No space")


def test_diagnose_disk_full_on_the_model_leaves_no_findings(capsys, ws, monkeypatch):
    import camsmooth.diagnosis.engine as engine

    monkeypatch.setattr(engine, "write_model", _disk_full)
    fails(capsys, ws, ["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "f.json",
                       "--model-out", "m.json", "--quiet"], "m.json", "No space")


def test_diagnose_disk_full_on_the_report_leaves_no_findings_or_model(capsys, ws, monkeypatch):
    import camsmooth.report.diagnosis as rd

    monkeypatch.setattr(rd, "write_report", lambda diag, folder, **kw: _disk_full(Path(folder) / "report.html"))
    fails(capsys, ws, ["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "f.json",
                       "--model-out", "m.json", "--report", "rep", "--quiet"], "rep/report.html", "No space")


def test_path_disk_full_leaves_nothing(capsys, ws, monkeypatch):
    import camsmooth.io.ccpath as ccpath

    monkeypatch.setattr(ccpath, "write_cc_csv", _disk_full)
    fails(capsys, ws, ["path", "--surface", "plane.ply", "--raster", "--cutter-radius", "4", "--corner-radius", "1",
                       "--stepover", "10", "--spacing", "5", "-o", "cc.csv"], "cc.csv", "No space")


def test_simulate_disk_full_leaves_nothing(capsys, ws, monkeypatch):
    import camsmooth.machine.calibration as calibration

    monkeypatch.setattr(calibration, "write_probe_csv", _disk_full)
    fails(capsys, ws, ["simulate", "probe", "--model", "model.json", "--grid", "3", "-o", "sim.csv"], "sim.csv")


def test_predict_disk_full_leaves_nothing(capsys, ws, monkeypatch):
    assert run(capsys, SMOOTH + ["-o", "res.csv"])[0] == 0
    import camsmooth.cli.model as cli_model

    calls = []

    def cell(v):
        calls.append(v)
        if len(calls) > 50:
            raise OSError(errno.ENOSPC, "No space left on device")
        return str(v)

    monkeypatch.setattr(cli_model, "_cell", cell)
    fails(capsys, ws, ["predict", "res.csv", "--model", "model.json", "-o", "pred.csv"], "No space")


def test_demo_disk_full_leaves_nothing(capsys, ws, monkeypatch):
    import camsmooth.smoothing.output as out

    monkeypatch.setattr(out, "write_gcode", _disk_full)
    fails(capsys, ws, ["demo", "--samples", "samples", "--sample", "tiny", "--out", "demo", "--quiet"], "No space")


def test_ctrl_c_in_process_leaves_nothing(capsys, ws, monkeypatch):
    import camsmooth.smoothing.output as out

    def interrupt(path, *a, **k):
        Path(path).write_text("partial")
        raise KeyboardInterrupt

    monkeypatch.setattr(out, "write_gcode", interrupt)
    fails(capsys, ws, SMOOTH + ["-o", "out.csv", "--gcode", "out.nc"], "interrupted", code=130)


SIGNAL_SCRIPT = """
import sys, time
from pathlib import Path
import camsmooth.smoothing.output as out

def slow(path, *args, **kwargs):
    Path(path).write_text("partial")
    Path(sys.argv[1]).write_text("ready")
    time.sleep(60)

out.write_gcode = slow
from camsmooth.cli.main import main
sys.exit(main(sys.argv[2:]))
"""


@pytest.mark.parametrize("signum,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_signal_while_writing_leaves_nothing(ws, tmp_path_factory, signum, code):
    marker = tmp_path_factory.mktemp("signal") / "ready"
    before = snapshot(ws)
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen([sys.executable, "-c", SIGNAL_SCRIPT, str(marker), *SMOOTH, "-o", "out.csv",
                             "--gcode", "out.nc", "--report", "keep"], cwd=ws, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while not marker.exists():
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline
            time.sleep(0.05)
        # the CSV is written (to its temporary) and the G-code half-written: now the signal
        assert [p for p in ws.iterdir() if ".camsmooth-" in p.name]
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == code, err
    assert "signal" in one_message(err).lower() or "interrupted" in err or "terminated" in err
    assert snapshot(ws) == before


# ----------------------------------------------------------------------------------------------
# 4. option values checked while parsing, for every verb
SIM_BALLBAR = ["simulate", "ballbar", "--model", "model.json", "-o", "b.csv"]
SIM_PROBE = ["simulate", "probe", "--model", "model.json", "-o", "pr.csv"]
SIM_SPINDLE = ["simulate", "spindle", "--model", "model.json", "-o", "sp.csv"]
PATH = ["path", "--surface", "plane.ply", "-o", "cc.csv"]
DIAG = ["diagnose", "--program", "program.csv", "--recording", "recording.csv", "--out", "f.json", "--quiet"]
SIM_REC = ["simulate", "recording", "--program", "program.csv", "-o", "r.csv"]


@pytest.mark.parametrize("argv,needles", [
    (SMOOTH + ["-o", "o.csv", "--corner-radius", "-1"], ("--corner-radius", ">= 0 mm")),
    (SMOOTH + ["-o", "o.csv", "--cutter-radius", "-1"], ("--cutter-radius", ">= 0 mm")),
    (SMOOTH + ["-o", "o.csv", "--feed", "0"], ("--feed", "mm/min")),
    (SMOOTH + ["-o", "o.csv", "--feed", "nan"], ("--feed",)),
    (SMOOTH + ["-o", "o.csv", "--lead", "20:2"], ("--lead", "MIN < MAX")),
    (SMOOTH + ["-o", "o.csv", "--lead", "2:95"], ("--lead", "< 90")),
    (SMOOTH + ["-o", "o.csv", "--tilt", "-95:0"], ("--tilt",)),
    (SMOOTH + ["-o", "o.csv", "--prefer-lead", "30"], ("--prefer-lead", "window")),
    (SMOOTH + ["-o", "o.csv", "--shank-length", "0"], ("--shank-length",)),
    (SMOOTH + ["-o", "o.csv", "--holder-radius", "-2"], ("--holder-radius",)),
    (SMOOTH + ["-o", "o.csv", "--method", "magic"], ("--method",)),
    (PATH + ["--stepover", "0", "--spacing", "1"], ("--stepover", "positive")),
    (PATH + ["--stepover", "5", "--spacing", "-1"], ("--spacing", "positive")),
    (PATH + ["--stepover", "5", "--spacing", "1", "--axis", "abc"], ("--axis", "i,j,k")),
    (PATH + ["--stepover", "5", "--spacing", "1", "--axis", "0,0,0"], ("--axis", "not all zero")),
    (PATH + ["--stepover", "5", "--spacing", "1", "--feed", "-5"], ("--feed",)),
    (PATH + ["--raster", "--cutter-radius", "4", "--corner-radius", "1", "--stepover", "1e-5", "--spacing", "1e-5"],
     ("CC points", "larger steps")),
    (SIM_BALLBAR + ["--step", "0"], ("--step", "positive")),
    (SIM_BALLBAR + ["--step", "-1"], ("--step", "positive")),
    (SIM_BALLBAR + ["--step", "7"], ("--step", "divide 360")),
    (SIM_BALLBAR + ["--duration", "-10"], ("--duration", ">= 0 s")),
    (SIM_BALLBAR + ["--interval", "0"], ("--interval",)),
    (SIM_BALLBAR + ["--bar-length", "0"], ("--bar-length",)),
    (SIM_BALLBAR + ["--angles", "30,95"], ("--angles", "< 90")),
    (SIM_BALLBAR + ["--angles", "30,30"], ("--angles", "two or more")),
    (SIM_BALLBAR + ["--rpm", "-1"], ("--rpm",)),
    (SIM_BALLBAR + ["--noise", "-0.1"], ("--noise", ">= 0 mm")),
    (SIM_BALLBAR + ["--seed", "-1"], ("--seed",)),
    (SIM_PROBE + ["--grid", "0"], ("--grid", ">= 2")),
    (SIM_PROBE + ["--max-angle", "500"], ("--max-angle", "travel", "A [-100, 100] deg")),
    (SIM_PROBE + ["--max-angle", "-5"], ("--max-angle",)),
    (SIM_SPINDLE + ["--samples", "2"], ("--samples", ">= 4")),
    (SIM_SPINDLE + ["--revolutions", "0"], ("--revolutions",)),
    (SIM_SPINDLE + ["--exts", "0,100"], ("--exts", "positive")),
    (SIM_REC + ["--rate", "0"], ("--rate",)),
    (SIM_REC + ["--noise-mm", "-1"], ("--noise",)),
    (["predict", "p.csv", "--model", "model.json", "--rpm", "-1"], ("--rpm",)),
    (DIAG + ["--folds", "1"], ("--folds", ">= 2")),
    (DIAG + ["--max-fit-samples", "10"], ("--max-fit-samples",)),
    (DIAG + ["--candidates", "servo_lag,magic"], ("--candidates", "magic")),
    (["calibrate", "spindle", "spindle.csv", "-o", "c.json", "--seed", "-3"], ("--seed",)),
    (["frobnicate"], ("invalid choice",)),
])
def test_option_ranges(capsys, ws, argv, needles):
    fails(capsys, ws, argv, *needles)


def test_max_angle_within_travel_is_accepted(capsys, ws):
    rc, _, err = run(capsys, SIM_PROBE + ["--grid", "3", "--max-angle", "100"])
    assert rc == 0, err
    A = np.loadtxt(ws / "pr.csv", delimiter=",", skiprows=1)[:, 0]
    assert A.min() == pytest.approx(-100.0) and A.max() == pytest.approx(100.0)


def test_calibrate_help_lists_columns_with_units(capsys):
    for kind, cols in (("probe", ("A, B (deg)", "sx, sy, sz (mm)")), ("spindle", ("theta (deg)", "ext (mm)")),
                       ("ballbar", ("t (s)", "dL (mm)"))):
        assert main(["calibrate", kind, "--help"]) == 0
        out = " ".join(capsys.readouterr().out.split())
        for c in cols:
            assert c in out, (kind, c)


# ----------------------------------------------------------------------------------------------
# 5. input files of the wrong kind or with wrong types
TOML_HEAD = "[machine]\nkind = \"AB-head\"\npivot = 150.0\n"
AXES = ("[axis.A]\nmin = -100.0\nmax = 100.0\nvmax = 60.0\namax = 300.0\n"
        "[axis.B]\nmin = -100.0\nmax = 100.0\nvmax = 60.0\namax = 300.0\n")


@pytest.mark.parametrize("text,needles", [
    (TOML_HEAD + "[axis]\nA = 5\n", ("m.toml", "[axis] A = 5", "table")),
    (TOML_HEAD.replace("150.0", '"abc"') + AXES, ("m.toml", "pivot", "number", '"abc"')),
    (TOML_HEAD + AXES.replace("vmax = 60.0", "vmax = true", 1), ("m.toml", "[axis.A] vmax", "true")),
    ("axis = 5\n" + TOML_HEAD, ("m.toml", "axis = 5", "table")),
    (TOML_HEAD.replace('"AB-head"', "3") + AXES, ("m.toml", "kind = 3")),
    (TOML_HEAD.replace("pivot = 150.0", "name = [1]\npivot = 150.0") + AXES, ("m.toml", "name", "string")),
    (TOML_HEAD + AXES + "[axis.X]\nmin = 10\nmax = -10\n", ("m.toml", "[axis.X] min")),
    ("[machine\nkind=", ("m.toml", "not valid TOML")),
    (TOML_HEAD + AXES + "[posts]\ndialect = \"fanuc\"\n", ("m.toml", "unknown table(s) [posts]", "[post]")),
    (TOML_HEAD.replace("[machine]", "[machin]") + AXES, ("m.toml", "[machin]", "known: [machine]")),
    (TOML_HEAD + AXES + "[axis.Q]\nmin = 0\n", ("m.toml", "axis table(s) Q", "A, B, X, Y, Z")),
])
def test_machine_toml_with_wrong_types(capsys, ws, text, needles):
    (ws / "m.toml").write_text(text)
    fails(capsys, ws, SMOOTH + ["--machine", "m.toml", "-o", "o.csv"], *needles)


def test_machine_toml_with_a_bom_is_read(capsys, ws):
    (ws / "m.toml").write_bytes(b"\xef\xbb\xbf" + (TOML_HEAD + AXES).encode())
    rc, _, err = run(capsys, SMOOTH + ["--machine", "m.toml", "-o", "o.csv"])
    assert rc == 0, err


@pytest.mark.parametrize("argv,needles", [
    (SMOOTH + ["--machine", "adir", "-o", "o.csv"], ("adir", "folder")),
    (SMOOTH + ["--machine", "binary.dat", "-o", "o.csv"], ("binary.dat", "UTF-8")),
    (SMOOTH + ["--machine", "missing.toml", "-o", "o.csv"], ("missing.toml", "not found")),
    (SMOOTH + ["--model", "adir", "-o", "o.csv"], ("adir",)),
    (SMOOTH + ["--model", "binary.dat", "-o", "o.csv"], ("binary.dat", "--model")),
    (["predict", "p.csv", "--model", "binary.dat"], ("binary.dat",)),
    (SIM_PROBE + ["--model", "adir"], ("adir",)),
    (SIM_PROBE + ["--machine", "binary.dat"], ("binary.dat",)),
    (["calibrate", "probe", "adir", "-o", "c.json"], ("adir",)),
    (["calibrate", "probe", "probe.csv", "--base", "binary.dat", "-o", "c.json"], ("binary.dat", "--base")),
    (["calibrate", "probe", "probe.csv", "--machine", "adir", "-o", "c.json"], ("adir",)),
    ([*SMOOTH[:1], "adir", *SMOOTH[2:], "-o", "o.csv"], ("adir",)),
    ([*SMOOTH[:1], "binary.dat", *SMOOTH[2:], "-o", "o.csv"], ("binary.dat",)),
    ([*SMOOTH[:1], "missing.csv", *SMOOTH[2:], "-o", "o.csv"], ("missing.csv",)),
    (DIAG[:2] + ["adir"] + DIAG[3:], ("adir",)),
    (DIAG + ["--model", "binary.dat"], ("binary.dat", "--model")),
    (DIAG + ["--machine", "adir"], ("adir",)),
    (SIM_REC + ["--model", "binary.dat"], ("binary.dat",)),
])
def test_input_files_of_the_wrong_kind(capsys, ws, argv, needles):
    fails(capsys, ws, argv, *needles)


@pytest.mark.parametrize("doc,needles", [
    ('{"format": "camsmooth-error-model", "version": 1, "geometric": [1, 2]}', ("geometric", "array")),
    ('{"format": "camsmooth-error-model", "version": 1, "thermal": "hot"}', ("thermal", "string")),
    ("[1, 2, 3]", ("JSON object",)),
    ('{"format": "camsmooth-error-model", "version": 1, "geometric": {"EY0A": "x"}}', ("EY0A",)),
])
@pytest.mark.parametrize("verb", ["smooth", "simulate", "predict", "calibrate", "diagnose"])
def test_model_json_with_wrong_types(capsys, ws, doc, needles, verb):
    from camsmooth.machine.model import FORMAT, FORMAT_VERSION

    (ws / "bad.json").write_text(doc.replace("camsmooth-error-model", FORMAT).replace('"version": 1',
                                                                                     f'"version": {FORMAT_VERSION}'))
    argv = {"smooth": SMOOTH + ["--model", "bad.json", "-o", "o.csv"],
            "simulate": SIM_PROBE[:3] + ["bad.json"] + SIM_PROBE[4:],
            "predict": ["predict", "p.csv", "--model", "bad.json"],
            "calibrate": ["calibrate", "probe", "probe.csv", "--base", "bad.json", "-o", "c.json"],
            "diagnose": DIAG + ["--model", "bad.json"]}[verb]
    fails(capsys, ws, argv, "bad.json", *needles)


# ----------------------------------------------------------------------------------------------
# 6. bad data: a path away from the mesh, a flipped mesh, NaN in predict
def test_flipped_mesh_is_named_not_the_csv_normals(capsys, ws):
    msg = fails(capsys, ws, [*SMOOTH[:3], "flipped.ply", *SMOOTH[4:], "-o", "o.csv"], "winding")
    assert "flipped" in msg


def test_flipped_mesh_message_names_the_mesh_file(data):
    mesh = trimesh.load(data / "flipped.ply", process=False)
    with pytest.raises(InputError, match="winding") as e:
        check_normals_against_mesh(plane_path(), mesh, mesh_file="flipped.ply")
    assert e.value.file == "flipped.ply" and "15 of 15" in str(e.value)
    # a few reversed CSV normals on a good mesh are still blamed on the CSV, with the row
    path = plane_path()
    path.normals[3] *= -1
    with pytest.raises(InputError, match="into the material") as e:
        check_normals_against_mesh(path, plane_mesh(), mesh_file="plane.ply")
    assert e.value.row == 4 and e.value.file == "p.csv"


def test_predict_nan_cell_is_an_error(capsys, ws):
    assert run(capsys, SMOOTH + ["-o", "res.csv"])[0] == 0
    lines = (ws / "res.csv").read_text().splitlines()
    cols = lines[0].split(",")
    cells = lines[3].split(",")
    cells[cols.index("B")] = "nan"
    lines[3] = ",".join(cells)
    (ws / "res.csv").write_text("\n".join(lines) + "\n")
    fails(capsys, ws, ["predict", "res.csv", "--model", "model.json", "-o", "pred.csv"],
          "res.csv", "row 3", "column 'B'")


@pytest.mark.parametrize("z,expect", [(100.0, "100"), (1e9, "1e+09")])
def test_path_away_from_the_mesh_is_no_contact(z, expect):
    mesh = plane_mesh()
    with pytest.raises(InputError, match="no contact within 1 mm") as e:
        check_contact_with_mesh(plane_path(z), mesh)
    assert e.value.file == "p.csv" and e.value.row == 1
    assert f"{expect} mm" in str(e.value) and "the whole path" in str(e.value)


def test_contact_check_on_a_coarse_mesh_uses_exact_distances():
    """Two triangles 1 km wide: the vertices are far from every point, the surface is not."""
    mesh = trimesh.Trimesh([[-500, -500, 0], [500, -500, 0], [500, 500, 0], [-500, 500, 0]],
                           [[0, 1, 2], [0, 2, 3]], process=False)
    check_contact_with_mesh(plane_path(0.9), mesh)  # 0.9 mm above: contact within 1 mm
    path = plane_path(0.0)
    path.points[7, 2] = 2.5  # one point (data row 8) lifted 2.5 mm
    with pytest.raises(InputError) as e:
        check_contact_with_mesh(path, mesh)
    assert e.value.row == 8 and "1 of 15 CC points" in str(e.value) and "2.5 mm" in str(e.value)
    check_contact_with_mesh(path, mesh, max_distance=3.0)


def test_contact_distances_match_brute_force():
    """Random points near a wavy mesh: flagged exactly when the brute-force distance exceeds the
    tolerance (distance to every triangle by trimesh's closest_point on the whole mesh)."""
    rng = np.random.default_rng(3)
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=20.0)
    for _ in range(5):
        pts = rng.uniform(-30, 30, (40, 3))
        brute = trimesh.proximity.closest_point_naive(mesh, pts)[1]
        tol = float(np.median(brute))
        path = CCPath(pts, np.tile([0, 0, 1.0], (40, 1)), np.zeros(40, int), None, None, "r.csv")
        far = np.flatnonzero(brute > tol)
        with pytest.raises(InputError) as e:
            check_contact_with_mesh(path, mesh, max_distance=tol)
        assert e.value.row == far[0] + 1 and f"{len(far)} of 40" in str(e.value)


# ----------------------------------------------------------------------------------------------
# 7. the boundary itself: warnings as one line, internal errors, --debug
def test_internal_error_asks_for_a_bug_report(capsys, ws, monkeypatch):
    import camsmooth.smoothing.pipeline as pipeline

    def broken(*a, **k):
        raise TypeError("unsupported operand")

    monkeypatch.setattr(pipeline, "smooth", broken)
    msg = fails(capsys, ws, SMOOTH + ["-o", "o.csv"], "internal error", "bug", "--debug", code=70)
    assert "TypeError" in msg
    rc, _, err = run(capsys, SMOOTH + ["-o", "o.csv", "--debug"])
    assert rc == 70 and "Traceback" in err and "broken" in err


def test_warnings_are_one_line_without_source(capsys, ws):
    mesh = plane_mesh()
    faces = mesh.faces.copy()
    faces[:3] = faces[:3, ::-1]  # a minority of faces wound the other way: repaired with a warning
    trimesh.Trimesh(mesh.vertices, faces, process=False).export(ws / "mixed.ply")
    rc, _, err = run(capsys, [*SMOOTH[:3], "mixed.ply", *SMOOTH[4:], "-o", "o.csv"])
    assert rc == 0, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert lines and all(ln.startswith("camsmooth: warning: ") for ln in lines), err
    assert "warnings.warn" not in err and ".py:" not in err
