"""G-code dialects and modes, checked with an independent parser from PyPI.

pygcode (RS274NGC / LinuxCNC semantics: modal motion, G90, G21, G93/G94 feed-rate modes, F words)
parses every written file; the tool-tip path is rebuilt from the parsed blocks with the machine's
kinematics (Machine.tool_pose_np) and compared with the CL points (1 um), and the tip speed implied
by the blocks is compared with the programmed feed: in G93 the tip path of each block under linear
joint interpolation is sampled here at 1024 steps (independently of the writer's own Richardson
estimate) and length x F must equal the feed within 0.1 %; in TCP mode F must be the feed.
Statements that are not RS274NGC (Siemens TRAORI/TRAFOOF/G71, Fanuc G43.4, LinuxCNC's
configuration M-codes, Heidenhain FUNCTION TCPM) are checked by name and kept away from pygcode;
Heidenhain Klartext ``L`` blocks are given to pygcode as G00 (FMAX) / G01 with the same words
(block number, ``L``, ``R0`` and the explicit '+' signs removed).
"""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np
import pytest
from pygcode import Line
from pygcode import Machine as RS274Machine
from pygcode.gcodes import (
    GCodeFeedRate,
    GCodeInverseTimeMode,
    GCodeLinearMove,
    GCodeRapidMove,
    GCodeUnitsPerMinuteMode,
)

from camsmooth.errors import InputError
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import load_machine, machine_from_dict
from camsmooth.post import DIALECTS as REGISTRY
from camsmooth.post import load_program
from camsmooth.post.own import read_gcode
from camsmooth.smoothing.posting import write_gcode
from camsmooth.smoothing.result import MethodResult

MACHINE = load_machine(None)
CUTTER = SimpleNamespace(R=3.0, r=1.0, shank_length=40.0, diameter=8.0)
H = 7.5
COMBOS = [(d, m) for d in REGISTRY if REGISTRY[d].own for m in ("machine", "tcp")
          if not (d == "heidenhain" and m == "machine") and not (d == "generic" and m == "tcp")]


class _ABMachine(RS274Machine):
    axes = set("XYZAB")


def _method(seed: int = 3) -> tuple[MethodResult, np.ndarray]:
    """A hard case not tuned for the writer: three rows over a dome with the axis swinging +-35 deg,
    block lengths from 0.02 mm to 3 mm (short blocks where the axis still turns), feed varying per point."""
    rng = np.random.default_rng(seed)
    rows, tips, axes = [], [], []
    for k in range(3):
        steps = rng.choice([0.02, 0.1, 0.5, 3.0], size=30, p=[0.2, 0.3, 0.3, 0.2])
        x = np.r_[0.0, np.cumsum(steps)] - 20.0
        x = x if k % 2 == 0 else x[::-1]
        y = np.full_like(x, 8.0 * k - 8.0) + 0.3 * np.sin(x / 5.0)
        z = 30.0 - (x**2 + y**2) / 80.0
        b = np.radians(35.0) * np.tanh(x / 15.0)
        a = np.radians(-20.0) * np.sin(y / 10.0 + 0.05 * x)
        T = np.column_stack([np.sin(b), -np.sin(a) * np.cos(b), np.cos(a) * np.cos(b)])
        tips.append(np.column_stack([x, y, z]))
        axes.append(T)
        rows.append(np.full(len(x), k))
    rows, cl, T = np.concatenate(rows), np.concatenate(tips), np.concatenate(axes)
    A, B = np.arctan2(-T[:, 1], T[:, 2]), np.arcsin(T[:, 0])
    n = len(rows)
    idx = np.concatenate([np.arange(np.sum(rows == k)) for k in range(3)])
    z0 = np.zeros(n)
    m = MethodResult(method="nlp", rows=rows, idx=idx, t=z0, cc=cl, normals=T, cl=cl, axis=T, lead=z0, tilt=z0,
                     rotary=RotaryValues.of(("A", "B"), A, B), rotary_vel=RotaryValues.zeros(("A", "B"), n),
                     rotary_acc=RotaryValues.zeros(("A", "B"), n), xyz=MACHINE.linear_axes(cl, A, B), delta=z0, lift=z0,
                     lead_window=np.zeros((n, 2)), tilt_window=np.zeros((n, 2)), compound_acc=z0)
    feed = 600.0 + 900.0 * rng.random(n)
    return m, feed


def _pygcode_blocks(text: str, dialect: str) -> tuple[list[dict], list[tuple[int, str]]]:
    """Motion blocks as pygcode reads them (position after the block, rapid, feed mode, modal F),
    and the dialect statements kept from it, with their line index."""
    machine = _ABMachine()
    blocks, statements = [], []
    f_modal = None
    for k, raw in enumerate(text.splitlines()):
        s = raw.strip()
        if dialect == "heidenhain":
            s = re.sub(r"^\d+\s+", "", s)
            if s.startswith(";"):
                continue
            if not s.startswith("L "):
                statements.append((k, s))
                continue
            code = "G00" if "FMAX" in s else "G01"
            s = code + " " + re.sub(r"([XYZABF])\+", r"\1", s[2:].replace(" R0", "").replace(" FMAX", ""))
            if code == "G01":
                s = "G94 " + s
        first = s.split()[0] if s.split() else ""
        if first in ("TRAORI", "TRAFOOF", "G71", "G43.4", "M428", "M429") or "G28" in s or "G53" in s:
            statements.append((k, s))
            continue
        line = Line(s)
        before = dict(machine.pos.values)
        machine.process_block(line.block)
        for g in line.block.gcodes:
            if isinstance(g, GCodeFeedRate):
                f_modal = float(g.word.value)
        after = dict(machine.pos.values)
        motion = machine.mode.motion
        moved = any(w.letter in "XYZAB" for w in line.block.words) and isinstance(
            motion, (GCodeRapidMove, GCodeLinearMove))
        if moved:
            blocks.append({"k": k, "pos": np.array([after[a] for a in "XYZAB"]),
                           "rapid": isinstance(motion, GCodeRapidMove),
                           "inverse": isinstance(machine.mode.feed_rate_mode, GCodeInverseTimeMode),
                           "per_min": isinstance(machine.mode.feed_rate_mode, GCodeUnitsPerMinuteMode),
                           "F": f_modal, "before": before})
    return blocks, statements


def _fine_tip_lengths(q0: np.ndarray, q1: np.ndarray, steps: int = 1024) -> np.ndarray:
    s = np.linspace(0.0, 1.0, steps + 1)[None, :, None]
    q = q0[:, None, :] + s * (q1 - q0)[:, None, :]
    flat = q.reshape(-1, 5)
    tip, _ = MACHINE.tool_pose_np(np.radians(flat[:, 3]), np.radians(flat[:, 4]), *flat[:, :3].T)
    return np.linalg.norm(np.diff(tip.reshape(len(q0), steps + 1, 3), axis=1), axis=2).sum(axis=1)


@pytest.mark.parametrize("dialect, mode", COMBOS)
def test_dialect_mode_rebuilds_tip_path_and_feed(tmp_path, dialect, mode):
    m, feed = _method()
    path = write_gcode(tmp_path / f"p_{dialect}_{mode}.nc", m, MACHINE, CUTTER, feed, safe_height=H,
                       dialect=dialect, mode=mode)
    text = path.read_text()
    blocks, statements = _pygcode_blocks(text, dialect)
    cut = [b for b in blocks if not b["rapid"]]
    rap = [b for b in blocks if b["rapid"]]
    assert len(cut) == len(m.rows) and len(rap) == 2 * 3  # entry and exit rapid per row
    q = np.array([b["pos"] for b in cut])
    A, B = np.radians(q[:, 3]), np.radians(q[:, 4])
    if mode == "machine":
        tip, axis = MACHINE.tool_pose_np(A, B, q[:, 0], q[:, 1], q[:, 2])
    else:
        tip, axis = q[:, :3], MACHINE.tool_axis_np(A, B)
    np.testing.assert_allclose(tip, m.cl, atol=1e-3)  # 1 um
    np.testing.assert_allclose(axis, m.axis, atol=1e-5)
    # the rapids sit H mm up along the tool axis of each row's first / last point
    ends = np.ravel([[np.flatnonzero(m.rows == k)[0], np.flatnonzero(m.rows == k)[-1]] for k in range(3)])
    qr = np.array([b["pos"] for b in rap])
    tip_r = (MACHINE.tool_pose_np(np.radians(qr[:, 3]), np.radians(qr[:, 4]), *qr[:, :3].T)[0]
             if mode == "machine" else qr[:, :3])
    np.testing.assert_allclose(tip_r, m.cl[ends] + H * m.axis[ends], atol=1e-3)
    F = np.array([b["F"] for b in cut], dtype=float)
    if mode == "machine":
        assert all(b["inverse"] for b in cut)
        q0 = np.array([[b["before"][a] for a in "XYZAB"] for b in cut])
        speed = _fine_tip_lengths(q0, q) * F  # mm per block x blocks per minute
        np.testing.assert_allclose(speed, feed, rtol=1e-3)
        assert text.splitlines().count("G93") == 1
    else:
        assert all(b["per_min"] for b in cut)
        np.testing.assert_allclose(F, feed, atol=0.05 + 1e-9)  # F written with one decimal
        on = {"linuxcnc": "M428", "fanuc": "G43.4 H1", "siemens": "TRAORI",
              "heidenhain": "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS"}[dialect]
        off = {"linuxcnc": "M429", "fanuc": "G49", "siemens": "TRAFOOF", "heidenhain": "FUNCTION RESET TCPM"}[dialect]
        bare = [re.sub(r"^\d+\s+", "", ln).strip() for ln in text.splitlines()]
        k_on = bare.index(on)
        k_off = len(bare) - 1 - bare[::-1].index(off)
        assert k_on < blocks[0]["k"] and k_off > blocks[-1]["k"]
    # program frame of each dialect
    lines = text.splitlines()
    if dialect == "heidenhain":
        assert lines[0] == "0 BEGIN PGM CAMSMOOTH MM" and lines[-1].endswith("END PGM CAMSMOOTH MM")
        assert [int(ln.split()[0]) for ln in lines] == list(range(len(lines)))
    elif dialect == "fanuc":
        assert lines[0] == "%" and lines[1].startswith("O0001") and lines[-1] == "%" and lines[-2] == "M30"
    else:
        assert lines[-1] == "M30"
    if dialect != "heidenhain":
        units = "G71" if dialect == "siemens" else "G21"
        assert lines.index(units) < next(k for k, ln in enumerate(lines) if ln.startswith("G0"))
    # round trip through camsmooth's own reader
    prog = load_program(path, machine=MACHINE)
    assert prog.format == "gcode"
    c = prog.cutting()
    np.testing.assert_allclose(c.tip, m.cl, atol=1e-3)
    np.testing.assert_allclose(c.axis, m.axis, atol=1e-5)
    np.testing.assert_allclose(c.feed[1:], feed[1:], rtol=1e-3)  # the first point of the program has no block
    assert [s.stop - s.start for s in c.row_slices()] == [int(np.sum(m.rows == k)) for k in range(3)]
    np.testing.assert_allclose(np.degrees(c.angles), np.degrees(m.rotary.values), atol=0.5e-4 + 1e-9)


def test_ab_sign_convention():
    """T(A, B) = Rx(A) Ry(B) e_z (METHODS section 1, right-hand rule about +X and +Y): A = +30 deg puts the
    spindle toward -Y, B = +30 deg toward +X; in a written program those tilts give positive A / B words."""
    s, c = 0.5, np.sqrt(3) / 2
    np.testing.assert_allclose(MACHINE.tool_axis_np(np.radians([30.0, 0.0]), np.radians([0.0, 30.0])),
                               [[0, -s, c], [s, 0, c]], atol=1e-15)
    A, B = np.radians(np.linspace(-80, 80, 9))[:, None], np.radians(np.linspace(-70, 70, 8))[None, :]
    A, B = np.broadcast_arrays(A, B)
    closed = np.stack([np.sin(B), -np.sin(A) * np.cos(B), np.cos(A) * np.cos(B)], -1).reshape(-1, 3)
    np.testing.assert_allclose(MACHINE.tool_axis_np(A.ravel(), B.ravel()), closed, atol=1e-14)
    # right-hand rule: a small positive A turns +z toward -y (omega = +x, dT = omega x z = -y)
    d = MACHINE.tool_axis_np(np.array([1e-6]), np.array([0.0]))[0] - [0, 0, 1]
    assert d[1] < 0 and abs(d[0]) < 1e-12


def test_sign_convention_in_written_program(tmp_path):
    T = np.array([[0, -0.5, np.sqrt(3) / 2], [0, -0.5, np.sqrt(3) / 2], [0.5, 0, np.sqrt(3) / 2]])
    cl = np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    ik = MACHINE.solve_row(T, cl)
    n = 3
    z0 = np.zeros(n)
    m = MethodResult(method="cam", rows=np.zeros(n, int), idx=np.arange(n), t=z0, cc=cl, normals=T, cl=cl, axis=T,
                     lead=z0, tilt=z0, rotary=ik.rotary, rotary_vel=RotaryValues.zeros(("A", "B"), n),
                     rotary_acc=RotaryValues.zeros(("A", "B"), n), xyz=ik.xyz, delta=z0,
                     lift=z0, lead_window=np.zeros((n, 2)), tilt_window=np.zeros((n, 2)), compound_acc=z0)
    text = write_gcode(tmp_path / "s.nc", m, MACHINE, CUTTER, 500.0, dialect="linuxcnc", mode="tcp").read_text()
    blocks, _ = _pygcode_blocks(text, "linuxcnc")
    cut = np.array([b["pos"] for b in blocks if not b["rapid"]])
    np.testing.assert_allclose(cut[:, 3:], [[30, 0], [30, 0], [0, 30]], atol=1e-4)


def test_refusals_and_bad_feeds(tmp_path):
    m, feed = _method()
    with pytest.raises(InputError, match="no inverse-time feed"):
        write_gcode(tmp_path / "h.nc", m, MACHINE, CUTTER, feed, dialect="heidenhain", mode="machine")
    with pytest.raises(InputError, match="no tool-centre-point command"):
        write_gcode(tmp_path / "g.nc", m, MACHINE, CUTTER, feed, dialect="generic", mode="tcp")
    with pytest.raises(InputError, match="unknown G-code dialect"):
        write_gcode(tmp_path / "g.nc", m, MACHINE, CUTTER, feed, dialect="mazak")
    bad = feed.copy()
    bad[40] = np.nan
    with pytest.raises(InputError, match=rf"row {int(m.rows[40])}, point {int(m.idx[40])}"):
        write_gcode(tmp_path / "g.nc", m, MACHINE, CUTTER, bad)
    with pytest.raises(InputError, match="values for"):
        write_gcode(tmp_path / "g.nc", m, MACHINE, CUTTER, feed[:-1])
    assert not list(tmp_path.iterdir())


def test_post_table_in_machine_file(tmp_path):
    base = {"machine": {"name": "m", "kind": "AB-head", "pivot": 100.0},
            "axis": {k: {"min": -90.0, "max": 90.0, "vmax": 30.0, "amax": 100.0} for k in "AB"}}
    assert machine_from_dict(base).post.dialect == "generic" and machine_from_dict(base).post.mode == "machine"
    mc = machine_from_dict({**base, "post": {"dialect": "siemens", "mode": "tcp", "tool": 4}})
    assert (mc.post.dialect, mc.post.mode, mc.post.tool) == ("siemens", "tcp", 4)
    for post, needle in (({"dialect": "mazak"}, "dialect = 'mazak'"), ({"mode": "rtcp"}, "mode = 'rtcp'"),
                         ({"tool": -1}, "tool must be"), ({"colour": 1}, "unknown key")):
        with pytest.raises(InputError, match=needle):
            machine_from_dict({**base, "post": post}, "m.toml")
    # the machine's post decides when the caller does not
    m, feed = _method()
    own = machine_from_dict({**base, "post": {"dialect": "linuxcnc", "mode": "tcp", "tcp_on": "M129",
                                              "tcp_off": "M128"}})
    own = type(own)(own.name, MACHINE.description, MACHINE.chain, {}, own.post)
    text = write_gcode(tmp_path / "own.nc", m, own, CUTTER, feed).read_text()
    assert "M129" in text.splitlines() and "M128" in text.splitlines() and "G93" not in text


def test_read_gcode_header_pivot_and_bad_file(tmp_path):
    m, feed = _method()
    p = write_gcode(tmp_path / "p.nc", m, MACHINE, CUTTER, feed, dialect="fanuc", mode="machine")
    prog = read_gcode(p)  # no machine given: the nominal AB head with the header's pivot
    np.testing.assert_allclose(prog.cutting().tip, m.cl, atol=1e-3)
    (tmp_path / "empty.nc").write_text("G21\nG90\nM30\n")
    with pytest.raises(InputError, match="no motion block"):
        read_gcode(tmp_path / "empty.nc")


#: each dialect's frame spelled by hand (issue 21 item 5 (e)): the statements before the first
#: motion block and after the last one, comments left out and Heidenhain's block numbers stripped.
#: Machine mode programs G93 before the moves and G94 back after them (a controller left in
#: inverse time reads the next program's F words as 1/min); TCP mode switches TCP on and off.
_FRAMES = {
    ("generic", "machine"): (["G21", "G90", "G17", "G93"], ["G94", "M30"]),
    ("linuxcnc", "machine"): (["G21", "G90", "G17", "G40", "G49", "G93"], ["G94", "G53 G00 Z0", "M30"]),
    ("linuxcnc", "tcp"): (["G21", "G90", "G17", "G40", "G49", "G94", "M428"], ["M429", "G53 G00 Z0", "M30"]),
    ("fanuc", "machine"): (["%", "O0001 (CAMSMOOTH)", "G21", "G90", "G17", "G40", "G49", "G80", "G93"],
                           ["G94", "G91 G28 Z0.", "G90", "M30", "%"]),
    ("fanuc", "tcp"): (["%", "O0001 (CAMSMOOTH)", "G21", "G90", "G17", "G40", "G49", "G80", "G94", "G43.4 H1"],
                       ["G49", "G91 G28 Z0.", "G90", "M30", "%"]),
    ("siemens", "machine"): (["G71", "G90", "G17", "G40", "G93"], ["G94", "M30"]),
    ("siemens", "tcp"): (["G71", "G90", "G17", "G40", "G94", "TRAORI"], ["TRAFOOF", "M30"]),
    ("heidenhain", "tcp"): (["BEGIN PGM CAMSMOOTH MM", "TOOL CALL 1 Z", "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS"],
                            ["FUNCTION RESET TCPM", "M140 MB MAX", "M30", "END PGM CAMSMOOTH MM"]),
}


@pytest.mark.parametrize("dialect, mode", COMBOS)
def test_program_frame_before_and_after_the_moves(tmp_path, dialect, mode):
    assert set(_FRAMES) == set(COMBOS)
    m, feed = _method()
    text = write_gcode(tmp_path / "p.nc", m, MACHINE, CUTTER, feed, safe_height=H, dialect=dialect,
                       mode=mode).read_text()
    bare = [re.sub(r"^\d+\s+", "", ln).strip() for ln in text.splitlines()] if dialect == "heidenhain" \
        else [ln.strip() for ln in text.splitlines()]
    bare = [ln for ln in bare if ln and not ln.startswith(("(", ";"))]
    moves = [k for k, ln in enumerate(bare) if re.match(r"(G0[01]|L) ", ln)]
    head, tail = _FRAMES[(dialect, mode)]
    assert bare[:moves[0]] == head
    assert bare[moves[-1] + 1:] == tail
