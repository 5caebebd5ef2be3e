"""smooth of a posted program writes that program back with the smoothed blocks in it
(camsmooth.post.rewrite): the other blocks unchanged and in order, LinuxCNC's rs274 runs it, and
reading it back gives the smoothed tips, axes, Gamma and cycle time."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import polars as pl
import pytest

from camsmooth.cli.main import main
from camsmooth.controller.linuxcnc_sim import parse_canon
from camsmooth.io.program import CLProgram, load_program
from camsmooth.machine.kinematics import load_machine
from camsmooth.smoothing.analysis import analyze_program

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "posted_rewrite"
DOME = ROOT / "surfaces" / "dome.stl"
DOME_MACHINE = ROOT / "surfaces" / "dome_machine.toml"
needs_rs274 = pytest.mark.skipif(shutil.which("rs274") is None, reason="LinuxCNC's rs274 not installed (make linuxcnc)")
#: a tip from joints rounded to 4 decimals (mm, deg) on the dome's table (|tip - centre| < 80 mm)
TIP_TOL_MM = np.sqrt(3) * 5e-5 + 2 * 80.0 * np.radians(5e-5)
AXIS_TOL = 2 * np.radians(5e-5) * 1.01


def _smooth(tmp_path: Path, program: Path, machine: Path, *extra: str) -> tuple[Path, Path]:
    out, csv = tmp_path / ("out" + program.suffix), tmp_path / "result.csv"
    code = main(["smooth", str(program), "--surface", str(DOME), "--machine", str(machine), "--lead", "0:20",
                 "--tilt", "-10:10", "--method", "spline", "--cutter-radius", "4", "--corner-radius", "1",
                 "-o", str(csv), "--gcode", str(out), "--quiet", *extra])
    assert code == 0
    return out, csv


def _is_cut(line: str) -> bool:
    return bool(re.match(r"\s*G0?1\s", line))


@pytest.fixture(scope="module")
def dome_round_trip(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rw")
    src = DATA / "dome_ac_linuxcnc.ngc"
    out, csv = _smooth(tmp, src, DOME_MACHINE)
    return tmp, src, out, pl.read_csv(csv)


def test_other_blocks_kept_in_order(dome_round_trip):
    _, src, out, res = dome_round_trip
    a = src.read_text().splitlines()
    b = out.read_text().splitlines()
    op = [i for i, ln in enumerate(a) if "Operation Name" in ln]
    finish = range(op[0], op[1])  # FINISH_5AX: its G01 blocks are the ones smoothed (and the rows' entries)
    kept = [ln for i, ln in enumerate(a) if not (i in finish and _is_cut(ln))]
    it = iter(b)
    assert all(any(x == y for y in it) for x in kept), "a non-cutting block is missing or out of order"
    # the output is the kept lines and G01 blocks only, as many as the input had (one per point)
    assert len(b) == len(a)
    assert sum(_is_cut(ln) for ln in b) == sum(_is_cut(ln) for ln in a)
    changed = [(x, y) for x, y in zip(a, b, strict=True) if x != y]
    assert len(changed) == len(res) and all(_is_cut(x) and _is_cut(y) for x, y in changed)
    assert (res["status"] == "ok").all()


def test_read_back_reproduces_the_smoothed_program(dome_round_trip):
    _, _, out, res = dome_round_trip
    machine = load_machine(DOME_MACHINE)
    prog = load_program(out, machine=machine, machine_given=True)
    assert prog.dialect == "linuxcnc"
    tips = res.select(["clx", "cly", "clz"]).to_numpy()
    axes = res.select(["i", "j", "k"]).to_numpy()
    # each smoothed point is a block of the output: the nearest tip read back
    d = np.linalg.norm(prog.tip[None, :, :] - tips[:, None, :], axis=2)
    k = d.argmin(axis=1)
    assert d[np.arange(len(k)), k].max() < TIP_TOL_MM
    assert np.linalg.norm(prog.axis[k] - axes, axis=1).max() < AXIS_TOL
    # Gamma: the output as read against the same program with the smoothed poses at full precision
    exact = CLProgram(tip=prog.tip.copy(), axis=prog.axis.copy(), rows=prog.rows, feed=prog.feed, rapid=prog.rapid,
                      line=prog.line, toolpaths=prog.toolpaths, source=prog.source, format=prog.format,
                      angles=prog.angles, rotary=prog.rotary)
    exact.tip[k], exact.axis[k] = tips, axes
    got = analyze_program(prog, machine).toolpaths[0]
    ref = analyze_program(exact, machine).toolpaths[0]
    assert got.name == "FINISH_5AX" and ref.gamma > 0
    assert abs(got.gamma - ref.gamma) <= 5e-3 * ref.gamma
    # cycle time: the G93 words of the smoothed blocks (60 / F s each) against the time-optimal law smooth planned
    b = out.read_text().splitlines()
    rows = res["row"].to_numpy()
    t_opt = res["t_opt"].to_numpy()
    for r in np.unique(rows):
        sel = np.flatnonzero(rows == r)
        lines = prog.line[k[sel]]
        f = np.array([float(re.search(r"F([\d.]+)", b[ln - 1]).group(1)) for ln in lines[1:]])
        commanded = float(np.sum(60.0 / f))
        planned = float(t_opt[sel[-1]] - t_opt[sel[0]])
        assert abs(commanded - planned) <= 5e-3 * planned, (r, commanded, planned)


@needs_rs274
def test_rs274_runs_the_output(dome_round_trip):
    tmp, _, out, res = dome_round_trip
    canon_file = tmp / "canon.txt"
    run = subprocess.run(["rs274", "-g", str(out), str(canon_file)], capture_output=True, text=True,
                         stdin=subprocess.DEVNULL, timeout=120, check=False)
    text = canon_file.read_text()
    assert run.returncode == 0 and "PROGRAM_END" in text, run.stdout + run.stderr
    assert not re.search(r"error", run.stdout + run.stderr, re.I)
    canon = parse_canon(text)
    # rs274's joints (identity kinematics: X Y Z and a, c in LinuxCNC's sense) through the machine's chain
    machine = load_machine(DOME_MACHINE)
    feed = canon.positions[~canon.rapid]
    a, c = -np.radians(feed[:, 3]), -np.radians(feed[:, 5])
    tip, _ = machine.tool_pose_np(a, c, feed[:, 0], feed[:, 1], feed[:, 2])
    tips = res.select(["clx", "cly", "clz"]).to_numpy()
    d = np.linalg.norm(tip[None, :, :] - tips[:, None, :], axis=2).min(axis=1)
    assert d.max() < TIP_TOL_MM
