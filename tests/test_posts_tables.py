"""G-code posts for table machines (issue 18): AC-table, BC-table and BC-head-table in every
dialect and mode, checked against independent formulas and against LinuxCNC itself.

- Every dialect/mode: the rotary words carry the machine's letters; machine mode X Y Z are the
  linear axes of the closed forms written out here (table: c + R_wp (CL - c); head-table:
  c + Rz(-C)(CL - c) + L_p Ry(B) e_z), tcp mode X Y Z are the tips; the angles are the ISO ones
  except in the linuxcnc dialect, which writes LinuxCNC's trt sense (a table axis negated); the
  header states kind, table centre and sense; ``read_gcode`` reads everything back.
- The oracle: LinuxCNC's xyzac-trt / xyzbc-trt kinematics (LinuxCNC 2.9 trtfuncs.c, offsets 0,
  no tool offset), transcribed here, with a = -A (b = -B), c = -C and the rot-point at the table
  centre, give camsmooth's linear axes to 1e-9.
- LinuxCNC's interpreter (rs274) reads the table programs: machine mode positions are the
  program's joints; tcp mode runs under the M428/M429 remaps of LinuxCNC's shipped xyzac-trt /
  xyzbc-trt configurations, and the trt inverse of its positions gives the machine-mode joints.
- The headless simulation (trivkins ``coordinates=XYZAC``) runs a short smoothed dome program
  on the A/C trunnion: the row times as the planner model predicts, the tip within the tolerance.

The LinuxCNC tests need the Debian package linuxcnc-uspace; without it they skip and say so.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tomllib
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from camsmooth.controller.linuxcnc_sim import interpret, linuxcnc_missing
from camsmooth.errors import InputError
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import load_machine, machine_from_dict
from camsmooth.post import DIALECTS as REGISTRY
from camsmooth.post.own import read_gcode
from camsmooth.smoothing.posting import write_gcode
from camsmooth.smoothing.result import MethodResult

ROOT = Path(__file__).resolve().parent.parent
MISSING = linuxcnc_missing()
needs_linuxcnc = pytest.mark.skipif(MISSING is not None, reason=f"LinuxCNC not installed: {MISSING}")
TRT = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/table-rotary-tilting")
CUTTER = SimpleNamespace(R=3.0, r=1.0, shank_length=40.0, diameter=8.0)
COMBOS = [(d, m) for d in REGISTRY if REGISTRY[d].own for m in ("machine", "tcp")
          if not (d == "heidenhain" and m == "machine") and not (d == "generic" and m == "tcp")]
KINDS = ("AC-table", "BC-table", "BC-head-table")
CENTRE = (3.0, -2.0, -20.0)


def _table_machine(kind: str, dialect: str = "linuxcnc", mode: str = "machine"):
    tilt = "A" if kind == "AC-table" else "B"
    data = {"machine": {"name": f"test {kind}", "kind": kind, "table_centre": list(CENTRE)},
            "axis": {tilt: {"min": -110.0, "max": 110.0, "vmax": 60.0, "amax": 300.0},
                     "C": {"vmax": 180.0, "amax": 900.0}},
            "post": {"dialect": dialect, "mode": mode}}
    if kind == "BC-head-table":
        data["machine"]["pivot"] = 120.0
    return machine_from_dict(data, f"<{kind}>")


def _rx(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    o, z = np.ones_like(t), np.zeros_like(t)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def _ry(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    o, z = np.ones_like(t), np.zeros_like(t)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1), np.stack([-s, z, c], -1)], -2)


def _rz(t: np.ndarray) -> np.ndarray:
    c, s = np.cos(t), np.sin(t)
    o, z = np.ones_like(t), np.zeros_like(t)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _closed_form_axes(kind: str, cl: np.ndarray, q1: np.ndarray, q2: np.ndarray, pivot: float = 0.0) -> np.ndarray:
    """The issue's closed forms of the linear axes (independent of the chain)."""
    c = np.asarray(CENTRE)
    if kind == "AC-table":
        return c + np.einsum("nij,nj->ni", _rx(-q1) @ _rz(-q2), cl - c)
    if kind == "BC-table":
        return c + np.einsum("nij,nj->ni", _ry(-q1) @ _rz(-q2), cl - c)
    return c + np.einsum("nij,nj->ni", _rz(-q2), cl - c) + pivot * _ry(q1)[:, :, 2]


def _method(machine) -> MethodResult:
    """Three rows over a dome, the tool axis along the surface normal (the tilt swings to about
    +-27 deg, C turns through a half turn), solved by the machine's own inverse."""
    rows, cl, T = [], [], []
    for k in range(3):
        x = np.linspace(-20.0, 20.0, 40) * (1 if k % 2 == 0 else -1)
        y = np.full_like(x, 8.0 * k - 8.0) + 0.3 * np.sin(x / 5.0)
        z = 30.0 - (x ** 2 + y ** 2) / 80.0
        nrm = np.column_stack([x / 40.0, y / 40.0, np.ones_like(x)])
        rows.append(np.full(len(x), k))
        cl.append(np.column_stack([x, y, z]))
        T.append(nrm / np.linalg.norm(nrm, axis=1)[:, None])
    rows, cl, T = (np.concatenate(v) for v in (rows, cl, T))
    ik = machine.solve_row(T, cl)
    assert len(ik.unreachable) == 0
    n = len(rows)
    z0 = np.zeros(n)
    idx = np.concatenate([np.arange(np.sum(rows == k)) for k in range(3)])
    return MethodResult(method="nlp", rows=rows, idx=idx, t=z0, cc=cl, normals=T, cl=cl, axis=T, lead=z0, tilt=z0,
                        rotary=ik.rotary, rotary_vel=RotaryValues.zeros(ik.rotary.names, n),
                        rotary_acc=RotaryValues.zeros(ik.rotary.names, n), xyz=ik.xyz, delta=z0, lift=z0,
                        lead_window=np.zeros((n, 2)), tilt_window=np.zeros((n, 2)), compound_acc=z0)


def _motion_words(text: str, letters: str) -> tuple[np.ndarray, np.ndarray]:
    """Positions (M, 5) by ``letters`` after each motion block (modal words carried) and a rapid
    flag, read with a plain regular expression (Heidenhain ``L`` blocks included)."""
    state = dict.fromkeys(letters, np.nan)
    out, rapid = [], []
    motion = None
    for raw in text.splitlines():
        s = re.sub(r"\(.*?\)|;.*$", "", re.sub(r"^\d+\s+", "", raw)).strip()
        if not s or "G53" in s or "G28" in s:
            continue
        if s.startswith("L "):
            motion = 0 if "FMAX" in s else 1
        else:
            g = re.findall(r"G0*([01])(?![\d.])", s)
            if g:
                motion = int(g[-1])
        words = dict(re.findall(r"([XYZABC])\s*([+-]?\d+\.\d+)", s))
        if motion is None or not any(w in words for w in letters):
            continue
        for w in letters:
            if w in words:
                state[w] = float(words[w])
        out.append([state[w] for w in letters])
        rapid.append(motion == 0)
    return np.asarray(out), np.asarray(rapid)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("dialect, mode", COMBOS)
def test_table_post_words_closed_forms_and_round_trip(tmp_path, kind, dialect, mode):
    machine = _table_machine(kind)
    m = _method(machine)
    path = write_gcode(tmp_path / "p.nc", m, machine, CUTTER, 900.0, dialect=dialect, mode=mode, safe_height=5.0)
    text = path.read_text()
    letters = "XYZ" + "".join(machine.rotary)
    other = ({"A", "B", "C"} - set(machine.rotary)).pop()
    assert not re.search(rf"^(\d+ )?(G0[01]|L) .*\b{other}[+-]?\d", text, re.M)  # no word of another axis
    q, rapid = _motion_words(text, letters)
    cut = q[~rapid]
    assert len(cut) == len(m.rows)
    # the angles: ISO 841, LinuxCNC's trt sense on its dialect (a table axis negated)
    sign = np.ones(2)
    if dialect == "linuxcnc":
        sign = np.array([1.0, -1.0]) if kind == "BC-head-table" else np.array([-1.0, -1.0])
    np.testing.assert_allclose(cut[:, 3:], np.degrees(m.rotary.values) * sign, atol=0.6e-4)
    if mode == "machine":
        xyz = _closed_form_axes(kind, m.cl, *m.rotary.pair, machine.pivot)
        np.testing.assert_allclose(cut[:, :3], xyz, atol=0.6e-4)
    else:
        np.testing.assert_allclose(cut[:, :3], m.cl, atol=0.6e-4)
    # the header: kind, table centre, sense
    head = "\n".join(text.splitlines()[:30])
    assert f"kind {kind}" in head and f"kind={kind}" in head
    assert "table centre 3.0000 -2.0000 -20.0000 mm" in head and "centre=3.000000,-2.000000,-20.000000" in head
    assert ("sense=linuxcnc" in head) == (dialect == "linuxcnc")
    # round trip, with the machine and from the header alone
    for given in (machine, None):
        prog = read_gcode(path, machine=given)
        assert prog.rotary == machine.rotary
        c = prog.cutting()
        np.testing.assert_allclose(c.tip, m.cl, atol=2e-4)
        np.testing.assert_allclose(c.axis, m.axis, atol=2e-6)
        np.testing.assert_allclose(c.angles, m.rotary.values, atol=np.radians(0.6e-4))


def test_reading_a_table_program_with_another_machine_names_both(tmp_path):
    machine = _table_machine("AC-table")
    path = write_gcode(tmp_path / "p.ngc", _method(machine), machine, CUTTER, 900.0)
    with pytest.raises(InputError, match="AC-table machine .* but the machine is an AB-head"):
        read_gcode(path, machine=load_machine(None))
    bc = _table_machine("BC-table")
    with pytest.raises(InputError, match="rotary axes A,C"):
        read_gcode(path, machine=bc)


def test_dome_sample_machine_writes_and_analyzes(tmp_path):
    """The dome sample's A/C trunnion (linuxcnc, machine mode): ``analyze`` of the written program
    gives the ranges of its own axes, equal to the program's."""
    from camsmooth.post import load_program
    from camsmooth.smoothing.analysis import analyze_program

    machine = load_machine(str(ROOT / "surfaces" / "dome_machine.toml"))
    m = _method(machine)
    path = write_gcode(tmp_path / "dome.ngc", m, machine, CUTTER, 900.0)
    prog = load_program(path, machine=machine)
    assert prog.rotary == ("A", "C")
    out = analyze_program(prog, machine).to_json()
    tp = out["toolpaths"][0]
    for k, name in enumerate(("A", "C")):
        want = np.degrees([*m.rotary.pair][k])
        assert tp[f"{name}_range_deg"] == pytest.approx([want.min(), want.max()], abs=1e-3)
    assert "B_range_deg" not in tp


# ----------------------------------------------------------------------------------------------
# LinuxCNC's trt kinematics as the oracle (LinuxCNC 2.9 trtfuncs.c; x/y/z offsets and tool offset 0)
def _xyzac_trt_inverse(pos: np.ndarray, a_deg: np.ndarray, c_deg: np.ndarray, r: np.ndarray) -> np.ndarray:
    a, c = np.radians(a_deg), np.radians(c_deg)
    x, y, z = (pos - r).T
    jx = np.cos(c) * x - np.sin(c) * y + r[0]
    jy = np.sin(c) * np.cos(a) * x + np.cos(c) * np.cos(a) * y - np.sin(a) * z + r[1]
    jz = np.sin(c) * np.sin(a) * x + np.cos(c) * np.sin(a) * y + np.cos(a) * z + r[2]
    return np.column_stack([jx, jy, jz])


def _xyzac_trt_forward(j: np.ndarray, a_deg: np.ndarray, c_deg: np.ndarray, r: np.ndarray) -> np.ndarray:
    a, c = np.radians(a_deg), np.radians(c_deg)
    jx, jy, jz = (j - r).T
    x = np.cos(c) * jx + np.sin(c) * np.cos(a) * jy + np.sin(c) * np.sin(a) * jz + r[0]
    y = -np.sin(c) * jx + np.cos(c) * np.cos(a) * jy + np.cos(c) * np.sin(a) * jz + r[1]
    z = -np.sin(a) * jy + np.cos(a) * jz + r[2]
    return np.column_stack([x, y, z])


def _xyzbc_trt_inverse(pos: np.ndarray, b_deg: np.ndarray, c_deg: np.ndarray, r: np.ndarray) -> np.ndarray:
    b, c = np.radians(b_deg), np.radians(c_deg)
    x, y, z = (pos - r).T
    jx = np.cos(c) * np.cos(b) * x - np.sin(c) * np.cos(b) * y + np.sin(b) * z + r[0]
    jy = np.sin(c) * x + np.cos(c) * y + r[1]
    jz = -np.cos(c) * np.sin(b) * x + np.sin(c) * np.sin(b) * y + np.cos(b) * z + r[2]
    return np.column_stack([jx, jy, jz])


def _xyzbc_trt_forward(j: np.ndarray, b_deg: np.ndarray, c_deg: np.ndarray, r: np.ndarray) -> np.ndarray:
    b, c = np.radians(b_deg), np.radians(c_deg)
    jx, jy, jz = (j - r).T
    x = np.cos(c) * np.cos(b) * jx + np.sin(c) * jy - np.cos(c) * np.sin(b) * jz + r[0]
    y = -np.sin(c) * np.cos(b) * jx + np.cos(c) * jy + np.sin(c) * np.sin(b) * jz + r[1]
    z = np.sin(b) * jx + np.cos(b) * jz + r[2]
    return np.column_stack([x, y, z])


TRT_ORACLE = {"AC-table": (_xyzac_trt_inverse, _xyzac_trt_forward),
              "BC-table": (_xyzbc_trt_inverse, _xyzbc_trt_forward)}


@pytest.mark.parametrize("kind", ["AC-table", "BC-table"])
def test_linear_axes_are_linuxcncs_trt_kinematics_with_the_sign_mapping(kind):
    """Random poses and a random table centre: camsmooth's X Y Z of a tool tip CL at angles
    (q1, C) equal LinuxCNC's trt inverse of CL at a = -q1, c = -C with the rot-point at the table
    centre (1e-9 mm), and its forward kinematics takes them back to CL; the same holds for the
    angles as the linuxcnc dialect writes them (LINUXCNC_SENSE)."""
    from camsmooth.controller.linuxcnc import linuxcnc_sense

    rng = np.random.default_rng(18)
    for _ in range(5):
        centre = rng.uniform(-200, 200, 3)
        data = {"machine": {"kind": kind, "table_centre": centre.tolist()},
                "axis": {kind[0]: {"min": -180.0, "max": 180.0, "vmax": 60.0, "amax": 300.0},
                         "C": {"vmax": 180.0, "amax": 900.0}}}
        machine = machine_from_dict(data)
        n = 200
        cl = rng.uniform(-300, 300, (n, 3))
        q = rng.uniform(-2 * np.pi, 2 * np.pi, (n, 2))
        xyz = machine.linear_axes(cl, q[:, 0], q[:, 1])
        inverse, forward = TRT_ORACLE[kind]
        lc = np.degrees(q) * linuxcnc_sense(machine)  # the words the linuxcnc dialect writes
        np.testing.assert_allclose(lc, -np.degrees(q), atol=0)
        np.testing.assert_allclose(xyz, inverse(cl, lc[:, 0], lc[:, 1], centre), atol=1e-9, rtol=0)
        np.testing.assert_allclose(forward(xyz, lc[:, 0], lc[:, 1], centre), cl, atol=1e-9, rtol=0)
        # the tool axis: the table turns the workpiece by R_wp, so the machine's +z (the spindle)
        # is T = R_wp^-1 e_z in the workpiece frame
        ez = np.tile([0.0, 0.0, 1.0], (n, 1))
        T = forward(centre + ez, lc[:, 0], lc[:, 1], centre) - forward(np.tile(centre, (n, 1)), lc[:, 0], lc[:, 1],
                                                                     centre)
        np.testing.assert_allclose(machine.tool_axis_np(q[:, 0], q[:, 1]), T, atol=1e-12)


# ----------------------------------------------------------------------------------------------
# LinuxCNC's interpreter
def _trt_config(tmp_path: Path, kind: str) -> Path:
    """An interpreter configuration with the M428/M429 remaps of LinuxCNC's shipped xyzac-trt
    (xyzbc-trt) configuration, the HAL checks of the remap subroutines left out (the stand-alone
    interpreter has no HAL), as tests/test_controller.py builds it for the AB head."""
    name = "xyzac-trt" if kind == "AC-table" else "xyzbc-trt"
    cfg = tmp_path / name
    (cfg / "remap_subs").mkdir(parents=True, exist_ok=True)
    for code in ("428", "429"):
        sub = (TRT / "remap_subs" / f"{code}remap.ngc").read_text()
        sub = re.sub(r"\n\s*o(\d) if.*?o\1 endif", "", sub, flags=re.S)
        (cfg / "remap_subs" / f"{code}remap.ngc").write_text(sub)
    ini_text = (TRT / f"{name}.ini").read_text()
    assert f"KINEMATICS = {name}-kins" in ini_text
    remaps = [ln.strip() for ln in ini_text.splitlines()
              if ln.strip().startswith("REMAP") and ("M428" in ln or "M429" in ln)]
    ini = cfg / f"{name}.ini"
    ini.write_text("[RS274NGC]\nSUBROUTINE_PATH = ./remap_subs\n" + "\n".join(remaps) + "\n")
    return ini


@needs_linuxcnc
@pytest.mark.parametrize("kind", ["AC-table", "BC-table"])
@pytest.mark.parametrize("mode", ["machine", "tcp"])
def test_linuxcnc_interpreter_reads_table_programs(tmp_path, kind, mode):
    """rs274 reads a linuxcnc table program: machine mode, its canonical X Y Z and rotary
    positions are the program's joints (1e-4; angles in LinuxCNC's sense); tcp mode (the
    shipped trt configuration's M428 before the moves, M429 after them), its positions are the
    tips and the trt inverse of them (the oracle above) gives the machine-mode joints (1e-3 mm:
    4-decimal words)."""
    machine = _table_machine(kind, mode=mode)
    m = _method(machine)
    ngc = write_gcode(tmp_path / f"{kind}_{mode}.ngc", m, machine, CUTTER, 900.0)
    if mode == "tcp" and not TRT.is_dir():
        pytest.skip("TCP mode needs the M428/M429 remaps of LinuxCNC's sample configurations")
    canon = interpret(ngc, ini=_trt_config(tmp_path, kind) if mode == "tcp" else None)
    got = canon.axes(machine.joint_names)
    keep = ~canon.rapid & (np.abs(got[:, 2]) < 1e3)  # not the final G53 retract
    got = got[keep]
    other = ({"A", "B", "C"} - set(machine.rotary)).pop()
    assert np.all(canon.axes(other)[keep] == 0)
    assert len(got) == len(m.rows)
    words = np.degrees(m.rotary.values) * -1.0  # trt sense
    np.testing.assert_allclose(got[:, 3:], words, atol=1e-4 + 1e-9)
    if mode == "machine":
        np.testing.assert_allclose(got[:, :3], m.xyz, atol=1e-4 + 1e-9)
        assert canon.inverse_time[keep].all()
    else:
        np.testing.assert_allclose(got[:, :3], m.cl, atol=1e-4 + 1e-9)
        joints = TRT_ORACLE[kind][0](got[:, :3], got[:, 3], got[:, 4], np.asarray(CENTRE))
        np.testing.assert_allclose(joints, m.xyz, atol=1e-3)
        values = [v for _, k, v in canon.aux if k == 3]  # SWITCHKINS_PIN = 3 in the remaps
        assert values[0] == 1.0 and values[-1] == 0.0  # trt kinematics on, identity at the end
        assert min(i for i, _, _ in canon.aux) == 0


# ----------------------------------------------------------------------------------------------
# the headless simulation on the A/C trunnion
@pytest.fixture(scope="module")
def dome_rows():
    """Three rows of the shipped dome, smoothed (nlp) for its A/C trunnion (LinuxCNC, machine mode)."""
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.paths import CCPath
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import smooth

    path = read_cc_csv(ROOT / "surfaces" / "dome_path.csv")
    k = np.isin(path.rows, np.unique(path.rows)[8:11])
    path = CCPath(points=path.points[k], normals=path.normals[k], rows=path.rows[k], source=path.source)
    machine = load_machine(str(ROOT / "surfaces" / "dome_machine.toml"))
    return smooth(path, load_surface(ROOT / "surfaces" / "dome.stl"), machine, ToroidalCutter(R=4.0, r=1.0),
                  feed=2000.0, method="nlp", tolerance=0.005)


@needs_linuxcnc
@pytest.mark.skipif(os.geteuid() != 0 and shutil.which("sudo") is None, reason="the simulation needs a user to run as")
def test_dome_rows_on_linuxcnc_xyzac_take_the_predicted_time_and_stay_within_the_tolerance(dome_rows, tmp_path):
    """Three smoothed dome rows on the A/C trunnion, written for LinuxCNC and run on its headless
    simulation (trivkins coordinates=XYZAC, the A travel mirrored into LinuxCNC's sense): each
    row's executed cut time is within 5% of camsmooth's prediction, and the tool tip (forward
    kinematics of the commanded joints, LinuxCNC's sense undone) stays within the tolerance of the
    path the full-density program commands."""
    from camsmooth.controller.linuxcnc_sim import row_runs, simulate

    m = dome_rows.machine
    r = dome_rows.methods["nlp"]
    ngc = tmp_path / "dome.ngc"
    write_gcode(ngc, r, m, dome_rows.cutter, 2000.0)
    try:
        run = simulate(ngc, m, timeout=120)
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        if "recorded nothing" in str(exc):
            pytest.skip(f"the LinuxCNC simulation does not start on this machine: {exc}")
        raise
    rows = row_runs(m, r, ngc.read_text(), run)
    assert sorted(x.row for x in rows) == sorted(int(x) for x in np.unique(r.rows))
    for x in rows:
        assert x.predicted == pytest.approx(x.executed, rel=0.05), x
        assert x.deviation <= 0.005, x


def test_dome_machine_file_is_the_sample():
    data = tomllib.loads((ROOT / "surfaces" / "dome_machine.toml").read_text())
    assert data["machine"]["kind"] == "AC-table" and data["post"]["dialect"] == "linuxcnc"
