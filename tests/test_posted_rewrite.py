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
from camsmooth.io.program import CLProgram
from camsmooth.machine.kinematics import load_machine
from camsmooth.post import load_program
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


# ---- Fanuc G43.4 and Siemens TRAORI programs written as the manuals show --------------------
def _cl_rows(machine):
    """The two dome rows' CL data (tips mm, unit axes) with rotary angles (deg) from the machine's
    inverse kinematics, per row."""
    prog = load_program(DATA / "dome_two_rows.cls")
    out = []
    for sl in prog.row_slices():
        tip, axis = prog.tip[sl], prog.axis[sl]
        ik = machine.solve_row(axis, tip)
        out.append((tip, axis, np.degrees(ik.rotary.values)))
    return out


def _w(v: np.ndarray) -> str:
    return " ".join(f"{c}{x:.4f}" for c, x in zip("XYZAC", v, strict=True))


def _posted_tcp(machine, dialect: str) -> str:
    """A shop's TCP program of the dome rows. Fanuc: Series 30i-B operator's manual (B-64484EN),
    "Tool center point control" (G43.4 H.. ; rotary axis positions type 1 ; G49 cancels), G94 feed
    per minute, '%' tape marks, 'O' number. Siemens: SINUMERIK 840D sl programming manual job
    planning (6FC5398-2BP40), "Transformations: three-, four- and five-axis transformation (TRAORI)"
    (TRAORI on, TRAFOOF off), G71 metric, ';' comments."""
    fanuc = dialect == "fanuc"
    c = (lambda s: f"({s})") if fanuc else (lambda s: f";{s}")
    lines = ["%", "O1000 (DOME FINISH)"] if fanuc else [";DOME FINISH", "G71 G90 G17 G40"]
    if fanuc:
        lines += ["G21 G90 G17 G40 G49 G80"]
    lines += ["G54", "T1 M6" if fanuc else "T1 D1", *([] if fanuc else ["M6"]), "S12000 M3", "M8",
              "(Operation Name: FINISH_5AX)" if fanuc else ";(FINISH_5AX)", "G94",
              "G43.4 H1" if fanuc else "TRAORI"]
    for k, (tip, axis, q) in enumerate(_cl_rows(machine)):
        lines.append(c(f"pass {k + 1}"))
        above = np.r_[tip[0] + 10.0 * axis[0], q[0]]
        lines.append("G0 " + _w(above))
        lines.append("G1 " + _w(np.r_[tip[0] + 0.5 * axis[0], q[0]]) + " F800.")  # plunge to 0.5 mm above
        lines.append("G1 " + _w(np.r_[tip[0], q[0]]) + " F2000.")
        lines += ["G1 " + _w(np.r_[t, a]) for t, a in zip(tip[1:], q[1:], strict=True)]
        lines.append("G0 " + _w(np.r_[tip[-1] + 10.0 * axis[-1], q[-1]]))
    lines += ["G49" if fanuc else "TRAFOOF", "M9", "M5", c("Operation Name: FACE") if fanuc else ";(FACE)",
              "G0 X-20. Y-20. Z15. A0. C0.", "G1 Z10. F800.", "G1 X20.", "G1 Y-10.", "G0 Z30.",
              "G91 G28 Z0." if fanuc else "G0 SUPA Z0", *(["G90"] if fanuc else []), "M30", *(["%"] if fanuc else [])]
    return "\n".join(lines) + "\n"


def _klartext(v: np.ndarray) -> str:
    return " ".join(f"{c}{x:+.3f}" for c, x in zip("XYZAC", v, strict=True))


def _posted_heidenhain(machine) -> str:
    """The dome rows as a Heidenhain Klartext program: TNC 640 user's manual (Klartext), "FUNCTION
    TCPM" (tool-centre-point management, the successor of M128; FUNCTION RESET TCPM cancels), L
    blocks with R0 FMAX rapids, TOOL CALL with the spindle speed, '* -' section headings."""
    lines = ["BEGIN PGM DOME MM", "* - FINISH_5AX", "TOOL CALL 1 Z S12000", "M3", "M8",
             "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS"]
    for k, (tip, axis, q) in enumerate(_cl_rows(machine)):
        lines.append(f"; pass {k + 1}")
        lines.append("L " + _klartext(np.r_[tip[0] + 10.0 * axis[0], q[0]]) + " R0 FMAX")
        lines.append("L " + _klartext(np.r_[tip[0] + 0.5 * axis[0], q[0]]) + " F800")
        lines.append("L " + _klartext(np.r_[tip[0], q[0]]) + " F2000")
        lines += ["L " + _klartext(np.r_[t, a]) for t, a in zip(tip[1:], q[1:], strict=True)]
        lines.append("L " + _klartext(np.r_[tip[-1] + 10.0 * axis[-1], q[-1]]) + " R0 FMAX")
    lines += ["FUNCTION RESET TCPM", "M9", "M5", "* - FACE", "L X-20 Y-20 Z+15 A+0 C+0 R0 FMAX", "L Z+10 F800",
              "L X+20", "L Y-10", "L Z+30 R0 FMAX", "M30", "END PGM DOME MM"]
    return "\n".join(f"{k} {ln}" for k, ln in enumerate(lines)) + "\n"


@pytest.mark.parametrize("dialect", ["fanuc", "siemens", "heidenhain"])
def test_tcp_dialects_round_trip(tmp_path, dialect):
    machine = load_machine(DOME_MACHINE)
    src = tmp_path / {"fanuc": "dome.nc", "siemens": "dome.mpf", "heidenhain": "dome.h"}[dialect]
    src.write_text(_posted_heidenhain(machine) if dialect == "heidenhain" else _posted_tcp(machine, dialect))
    prog_in = load_program(src, machine=machine, machine_given=True)
    assert prog_in.dialect == ("iso" if dialect == "fanuc" else dialect)
    assert [tp.name for tp in prog_in.toolpaths][:2] == ["FINISH_5AX", "FACE"]
    out, csv = _smooth(tmp_path, src, DOME_MACHINE)
    res = pl.read_csv(csv)
    a, b = src.read_text().splitlines(), out.read_text().splitlines()
    klartext = dialect == "heidenhain"
    if klartext:  # the blocks are numbered again: compare their text, and the numbers run 0, 1, 2, ...
        assert [int(ln.split()[0]) for ln in b] == list(range(len(b)))
        a, b = [ln.split(" ", 1)[1] for ln in a], [ln.split(" ", 1)[1] for ln in b]

    def cuts(ln: str) -> bool:
        return ln.startswith("L ") and "FMAX" not in ln if klartext else _is_cut(ln)

    # every line that is not a cutting block of FINISH_5AX is in the output, unchanged and in order
    end = next(i for i, ln in enumerate(a) if ln in ("G49", "TRAFOOF", "FUNCTION RESET TCPM"))
    kept = [ln for i, ln in enumerate(a) if not (i < end and cuts(ln))]
    it = iter(b)
    assert all(any(x == y for y in it) for x in kept)
    written = re.compile(r"L X[+-]\d+\.\d{4} " if klartext else r"G01 ")  # the writer's blocks: 4 decimals
    new = [ln for ln in b if written.match(ln)]
    assert len(new) == len(res)  # one block per smoothed point, in the writer's format
    prog = load_program(out, machine=machine, machine_given=True)
    assert prog.dialect == prog_in.dialect
    tips = res.select(["clx", "cly", "clz"]).to_numpy()
    axes = res.select(["i", "j", "k"]).to_numpy()
    d = np.linalg.norm(prog.tip[None, :, :] - tips[:, None, :], axis=2)
    k = d.argmin(axis=1)
    # TCP: X Y Z is the tip as written (4 decimals), the axis from A C rounded to 4 decimals of a degree
    assert d[np.arange(len(k)), k].max() <= np.sqrt(3) * 5e-5 + 1e-9
    assert np.linalg.norm(prog.axis[k] - axes, axis=1).max() < AXIS_TOL
    # cycle time at the written feeds (G94, F modal): sum of chord / F over the smoothed blocks
    feeds, f = [], None
    for ln in b:
        m = re.search(r"F([\d.]+)", ln)
        f = float(m.group(1)) if m else f
        if written.match(ln):
            feeds.append(f)
    rows, t_opt = res["row"].to_numpy(), res["t_opt"].to_numpy()
    for r in np.unique(rows):
        sel = np.flatnonzero(rows == r)
        chord = np.linalg.norm(np.diff(np.round(tips[sel], 4), axis=0), axis=1)
        commanded = float(np.sum(60.0 * chord / np.asarray(feeds)[sel[1:]]))
        planned = float(t_opt[sel[-1]] - t_opt[sel[0]])
        assert abs(commanded - planned) <= 5e-3 * planned, (r, commanded, planned)
    got = analyze_program(prog, machine).toolpaths[0]
    exact = CLProgram(tip=prog.tip.copy(), axis=prog.axis.copy(), rows=prog.rows, feed=prog.feed, rapid=prog.rapid,
                      line=prog.line, toolpaths=prog.toolpaths, source=prog.source, format=prog.format,
                      angles=prog.angles, rotary=prog.rotary)
    exact.tip[k], exact.axis[k] = tips, axes
    ref = analyze_program(exact, machine).toolpaths[0]
    assert abs(got.gamma - ref.gamma) <= 5e-3 * ref.gamma
    assert abs(got.cycle_time_optimal_s - ref.cycle_time_optimal_s) <= 5e-3 * ref.cycle_time_optimal_s


# ---- the same CL data through two posts: two dialects, two machines --------------------------
def _method_result(machine, rows_cl):
    """A MethodResult of the CL rows on ``machine`` (angles from its inverse kinematics, linear
    axes from its chain), the other fields empty: what write_gcode reads."""
    from camsmooth.machine.axes import RotaryValues
    from camsmooth.smoothing.result import MethodResult

    tip = np.vstack([t for t, _, _ in rows_cl])
    axis = np.vstack([a for _, a, _ in rows_cl])
    rows = np.concatenate([np.full(len(t), k) for k, (t, _, _) in enumerate(rows_cl)])
    idx = np.concatenate([np.arange(len(t)) for t, _, _ in rows_cl])
    q = np.vstack([machine.solve_row(a, t).rotary.values for t, a, _ in rows_cl])
    n, z, z3 = len(tip), np.zeros(len(tip)), np.zeros((len(tip), 3))
    return MethodResult(method="none", rows=rows, idx=idx, t=z, cc=tip, normals=axis, cl=tip, axis=axis, lead=z,
                        tilt=z, rotary=RotaryValues(machine.rotary, q),
                        rotary_vel=RotaryValues.zeros(machine.rotary, n),
                        rotary_acc=RotaryValues.zeros(machine.rotary, n),
                        xyz=machine.linear_axes(tip, q[:, 0], q[:, 1]), delta=z, lift=z, lead_window=np.zeros((n, 2)),
                        tilt_window=np.zeros((n, 2)), compound_acc=z, feed_dirs=z3)


def test_cross_post_consistency(tmp_path):
    """Fanuc G43.4 (TCP) on the A/C trunnion of the dome sample and Siemens in machine mode (G93
    joints) on the nutating B-head / C-table machine, both from camsmooth's writer, read back by the
    posted readers: the same tips within the posts' rounding and the same axes within 0.01 deg."""
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.post import read_posted
    from camsmooth.smoothing.posting import write_gcode

    ac = load_machine(DOME_MACHINE)
    nut = load_machine(ROOT / "surfaces" / "nutating_machine.toml")
    cl = load_program(DATA / "dome_two_rows.cls")
    rows_cl = [(cl.tip[sl], cl.axis[sl], None) for sl in cl.row_slices()]
    cutter = ToroidalCutter(R=4.0, r=1.0)
    got = {}
    for name, machine, dialect, mode in (("fanuc", ac, "fanuc", "tcp"), ("siemens", nut, "siemens", "machine")):
        path = tmp_path / f"{name}.nc"
        write_gcode(path, _method_result(machine, rows_cl), machine, cutter, 2000.0, dialect=dialect, mode=mode)
        prog = read_posted(path, machine=machine)
        assert prog.dialect == ("iso" if name == "fanuc" else "siemens")
        got[name] = (prog.tip[~prog.rapid], prog.axis[~prog.rapid])
    ref_tip, ref_axis = cl.cutting().tip, cl.cutting().axis
    # TCP: the tip as written; machine mode: joints rounded to 5e-5 mm / 5e-5 deg, the tip moved by
    # the rotary rounding times the lever from the rotary axes to the tip (nutating: gauge 300 mm,
    # C axis within 80 mm of the dome's points)
    e = np.radians(5e-5)
    bounds = {"fanuc": np.sqrt(3) * 5e-5, "siemens": np.sqrt(3) * 5e-5 + e * (300.0 + 200.0) + e * 130.0}
    for name, (tip, axis) in got.items():
        assert len(tip) == len(ref_tip)
        assert np.linalg.norm(tip - ref_tip, axis=1).max() <= bounds[name] + 1e-9, name
        ang = np.degrees(np.arccos(np.clip(np.sum(axis * ref_axis, axis=1), -1, 1)))
        assert ang.max() < 0.01 / 2, name
    (t1, a1), (t2, a2) = got["fanuc"], got["siemens"]
    assert np.linalg.norm(t1 - t2, axis=1).max() <= bounds["fanuc"] + bounds["siemens"]
    assert np.degrees(np.arccos(np.clip(np.sum(a1 * a2, axis=1), -1, 1))).max() < 0.01


# ---- from APT: the program carries the input's tool call, spindle, coolant and work offset ----
@needs_rs274
def test_apt_setup_written_and_run(tmp_path):
    """LOAD/TOOL,1, SPINDL/RPM,12000,CLW and COOLNT/FLOOD in the CLSF, --work-offset G55: the LinuxCNC
    program has them in the order a shop runs them, and rs274 executes them (its canonical calls)."""
    feed = "FEDRAT/MMPM,2000.0000"
    text = (DATA / "dome_two_rows.cls").read_text().replace(feed, f"SPINDL/RPM,12000,CLW\nCOOLNT/FLOOD\n{feed}", 1)
    src = tmp_path / "dome.cls"
    src.write_text(text)
    out, _ = _smooth(tmp_path, src, DOME_MACHINE, "--work-offset", "G55")
    lines = out.read_text().splitlines()
    order = [lines.index(x) for x in ("G55", "T1 M6", "S12000 M3", "M8", "G93", "M9", "M5", "M30")]
    assert order == sorted(order)
    canon_file = tmp_path / "canon.txt"
    tbl = tmp_path / "tool.tbl"
    tbl.write_text("T1 P1 Z0 D10 ;\n")
    subprocess.run(["rs274", "-t", str(tbl), "-g", str(out), str(canon_file)], capture_output=True, text=True,
                   stdin=subprocess.DEVNULL, timeout=120, check=False)
    canon = canon_file.read_text()
    calls = [c for c in ("SET_G5X_OFFSET(2", "CHANGE_TOOL(", "SET_SPINDLE_SPEED(0, 12000", "START_SPINDLE_CLOCKWISE",
                         "FLOOD_ON", "STRAIGHT_FEED", "FLOOD_OFF", "STOP_SPINDLE_TURNING", "PROGRAM_END")]
    at = 0
    for c in calls:  # each after the one before (the tool change stops the spindle on its own too)
        at = canon.find(c, at)
        assert at >= 0, c


def test_bad_work_offset_and_operation(tmp_path, capsys):
    args = ["smooth", str(DATA / "dome_ac_linuxcnc.ngc"), "--surface", str(DOME), "--machine", str(DOME_MACHINE),
            "--lead", "0:20", "--tilt", "-10:10", "--cutter-radius", "4", "--corner-radius", "1",
            "-o", str(tmp_path / "r.csv"), "--gcode", str(tmp_path / "o.ngc")]
    assert main([*args, "--work-offset", "G99"]) == 2
    assert "--work-offset 'G99'" in capsys.readouterr().err
    assert main([*args, "--operations", "ROUGH"]) == 2
    err = capsys.readouterr().err
    assert "no operation ROUGH" in err and "FINISH_5AX" in err and "Traceback" not in err
    assert not (tmp_path / "o.ngc").exists() and not (tmp_path / "r.csv").exists()


def test_arc_blocks_rewritten_as_their_points(tmp_path):
    """A Fanuc TCP row with a G02 arc (Fanuc 30i operator's manual, "Circular interpolation", G17 I J)
    written back with its own poses: the arc becomes G01 blocks through the reader's interpolated
    points (chordal error <= 1 um), which read back on the circle; the other lines are kept."""
    from camsmooth.post import read_posted
    from camsmooth.post.core import nominal_machine
    from camsmooth.post.model import PostProgram
    from camsmooth.post.rewrite import rewrite_posted

    text = ("%\nO2000\nG21 G90 G17\nG54\nT1 M6\nS8000 M3\n(Operation Name: ARCS)\nG94\nG43.4 H1\n"
            "G0 X0 Y0 Z10. A10. C0\nG1 Z0 F500.\nG1 X10. A12. C5.\nG2 X20. Y0 I5. J0 A14. C10.\nG1 X30. A15. C12.\n"
            "G0 Z10.\nG49\nM5\nM30\n%\n")
    src = tmp_path / "arc.nc"
    src.write_text(text)
    machine = nominal_machine(("A", "C"))
    prog = read_posted(src, machine=machine)
    cut = np.flatnonzero(prog.rows >= 0)
    q = prog.angles[cut]
    xyz = machine.linear_axes(prog.tip[cut], q[:, 0], q[:, 1])
    result = PostProgram(rows=prog.rows[cut], idx=np.arange(len(cut)), joints=np.column_stack([xyz, q]),
                         tips=prog.tip[cut], axis=prog.axis[cut], feed=np.full(len(cut), 500.0))
    new = rewrite_posted(text, prog, result, cut, machine, np.full(len(cut), 500.0))
    out = new.text.splitlines()
    kept = [ln for ln in text.splitlines() if not re.match(r"G[12] ", ln)]
    it = iter(out)
    assert all(any(x == y for y in it) for x in kept)
    assert sum(ln.startswith("G01 ") for ln in out) == len(cut) > 20
    (tmp_path / "out.nc").write_text(new.text)
    back = read_posted(tmp_path / "out.nc", machine=machine)
    on_arc = (back.tip[:, 0] > 10 + 1e-6) & (back.tip[:, 0] < 20 - 1e-6) & ~back.rapid
    r = np.hypot(back.tip[on_arc, 0] - 15.0, back.tip[on_arc, 1])
    assert on_arc.sum() > 20 and np.abs(r - 5.0).max() < 1e-4
    assert np.all(back.tip[on_arc, 1] >= -1e-4)  # G02 from (10, 0) to (20, 0) about (15, 0): through +Y
    c = np.degrees(back.angles[~back.rapid][:, 1])
    assert np.all(np.diff(c) >= -1e-9) and abs(c[-1] - 12.0) < 1e-9  # C linear along the arc, as written
