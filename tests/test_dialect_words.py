"""Each dialect's tool-centre-point, feed and path-tolerance words against the controller manual's
text (issue 31 item 2), quoted in each test's docstring; tests/test_oracles_hand.py does the same for
Siemens CYCLE832 / TRAORI, Heidenhain cycle 32 / FUNCTION TCPM and LinuxCNC G64.

The programs are one row of four points worked by hand: the tool tip steps 2 mm along X at Z = 0
with the tool axis vertical (A = B = 0, T = e_z), on an AB head of pivot 150 mm (METHODS section 1:
pivot = tip + 150 T, so the machine-mode X Y Z are the tip + (0, 0, 150)), the programmed feed
600 mm/min, the retract 10 mm up the tool axis (DEFAULT_SAFE_HEIGHT_MM). Every value the tests
expect is worked from these numbers here, not read from the writer's output. Units: mm, mm/min,
degrees in the files.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import machine_from_dict
from camsmooth.post import read_posted
from camsmooth.post.model import PostProgram
from camsmooth.post.writer import write_program

PIVOT = 150.0
FEED = 600.0
STEP = 2.0
SAFE = 10.0
N = 4


def _machine(dialect: str, mode: str, tool: int = 1):
    axes = {a: {"min": -110.0, "max": 110.0, "vmax": 60.0, "amax": 300.0} for a in ("A", "B")}
    return machine_from_dict({"machine": {"name": "words AB head", "kind": "AB-head", "pivot": PIVOT},
                              "axis": axes, "post": {"dialect": dialect, "mode": mode, "tool": tool}}, "<words>")


def _program(tolerance: float | None = 0.02) -> PostProgram:
    tips = np.column_stack([STEP * np.arange(N), np.zeros(N), np.zeros(N)])
    T = np.tile([0.0, 0.0, 1.0], (N, 1))
    joints = np.column_stack([tips + PIVOT * T, np.zeros(N), np.zeros(N)])
    return PostProgram(rows=np.zeros(N, int), idx=np.arange(N), joints=joints, tips=tips, axis=T,
                       feed=np.full(N, FEED), tolerance=tolerance)


def _write(tmp_path: Path, dialect: str, mode: str, tool: int = 1, tolerance: float | None = 0.02) -> list[str]:
    path = write_program(tmp_path / f"{dialect}-{mode}.nc", _program(tolerance), _machine(dialect, mode, tool))
    return [ln.strip() for ln in path.read_text().splitlines()]


def _code(line: str) -> str:
    return re.sub(r"\([^()]*\)", "", line).strip()


def _words(line: str) -> dict[str, float]:
    return {w: float(v) for w, v in re.findall(r"([A-Z])\s*([-+]?\d+\.?\d*)", _code(line))}


def _motion(lines: list[str]) -> list[int]:
    return [k for k, ln in enumerate(lines) if _code(ln).startswith(("G00 ", "G01 "))]


# ---- inverse time (G93) in machine mode: generic (RS274/NGC) and Fanuc ------------------------------
@pytest.mark.parametrize("dialect", ["generic", "fanuc"])
def test_machine_mode_inverse_time_words(tmp_path, dialect):
    """LinuxCNC G-code manual (the NIST RS274/NGC Interpreter's text), "G93, G94, G95: Feed Rate
    Mode": "In inverse time feed rate mode, an F word means the move should be completed in [one
    divided by the F number] minutes. ... When the inverse time feed rate mode is active, an F word
    must appear on every line which has a G1, G2, or G3 motion ... Being in inverse time feed rate
    mode does not affect G0 (rapid traverse) motions." (the NIST RS274NGC Interpreter version 3,
    section "Set Feed Rate Mode", has the same words).

    By hand: the three row blocks move the tip 2 mm at fixed angles, 2 / 600 min each: F = 300;
    the entry block moves it 10 mm down the tool axis: 10 / 600 min, F = 60. G93 stands before the
    first G01, G94 is restored after the last one, the rapids carry no F."""
    lines = _write(tmp_path, dialect, "machine")
    moves = _motion(lines)
    feeds = [k for k in moves if _code(lines[k]).startswith("G01")]
    rapids = [k for k in moves if _code(lines[k]).startswith("G00")]
    assert len(feeds) == N and len(rapids) == 2
    g93 = [k for k, ln in enumerate(lines) if _code(ln) == "G93"]
    assert len(g93) == 1 and g93[0] < moves[0]
    assert [k for k, ln in enumerate(lines) if _code(ln) == "G94"] and \
        min(k for k, ln in enumerate(lines) if _code(ln) == "G94") > moves[-1]
    f = [_words(lines[k])["F"] for k in feeds]
    assert f == pytest.approx([FEED / SAFE, FEED / STEP, FEED / STEP, FEED / STEP], rel=1e-6)
    assert all("F" not in _words(lines[k]) for k in rapids)
    # the blocks command the joints: the pivot 150 mm above the tip
    first = _words(lines[feeds[1]])
    assert (first["X"], first["Y"], first["Z"], first["A"], first["B"]) == pytest.approx((STEP, 0.0, PIVOT, 0.0, 0.0))


# ---- Fanuc: tool centre point control G43.4 ... G49 -------------------------------------------------
def test_fanuc_tcp_is_g43_4_with_the_tool_offset_and_g49_cancels_it(tmp_path):
    """FANUC Series 30i/300i/300is-MODEL A Descriptions (B-63942EN/02), Appendix B "List of
    functions and program format", "Tool center point control (TYPE1) (G43.4)": "G43.4 IP α β H ;
    Tool center point control (TYPE1) start ... IP : In the case of an absolute command, the
    coordinate value of the end point of the tool tip movement ... α, β : In the case of an absolute
    command, the coordinate value of the end point of the rotation axes ... H : Tool compensation
    number", and under "Tool length compensation (G43, G44, G49)": "G49 : Cancel" (Series 15i
    connection manual, "Canceling tool center point control: G49").

    So in tcp mode the Fanuc program says G43.4 H<the [post] tool> in absolute mode (G90 before
    it) and feed per minute (G94: F the tip feed 600 mm/min), every block between G43.4 and G49
    gives the tool tip X Y Z (the row's points, 2 mm apart at Z = 0; the rapids 10 mm above them)
    and the rotary positions in degrees, and G49 comes after the last motion block."""
    lines = _write(tmp_path, "fanuc", "tcp", tool=7)
    on = [k for k, ln in enumerate(lines) if _code(ln).startswith("G43.4")]
    off = [k for k, ln in enumerate(lines) if _code(ln) == "G49"]
    assert len(on) == 1 and _code(lines[on[0]]) == "G43.4 H7"
    moves = _motion(lines)
    assert on[0] < moves[0] and any(k > moves[-1] for k in off)
    assert not [k for k in off if on[0] < k < moves[-1]]  # no cancel inside the TCP span
    assert min(k for k, ln in enumerate(lines) if _code(ln) == "G90") < on[0]
    assert max(k for k, ln in enumerate(lines) if _code(ln) == "G94") < on[0]
    assert not any(_code(ln) == "G93" for ln in lines)
    expect = [(0.0, SAFE)] + [(STEP * i, 0.0) for i in range(N)] + [(STEP * (N - 1), SAFE)]
    got = [_words(lines[k]) for k in moves]
    assert np.allclose([(w["X"], w["Z"]) for w in got], expect, atol=1e-9)
    assert all(w["Y"] == 0.0 and w["A"] == 0.0 and w["B"] == 0.0 for w in got)
    feeds = [w["F"] for w in got if "F" in w]
    assert feeds == [FEED]  # G94 F is modal: written once, at the entry


def test_fanuc_look_ahead_word_and_no_tolerance_word(tmp_path):
    """FANUC Series 30i/300i/300is-MODEL A, list of G codes (machining centre): "G05.1, group 00:
    AI contour control / Nano smoothing / Smooth interpolation". camsmooth writes G05.1 Q1 (AI
    contour control on) and no tolerance word: the G05.1 entry takes no tolerance value (the
    tolerance of AI contour control is a CNC parameter; camsmooth.post.iso, FANUC). So a Fanuc
    program given a path tolerance switches AI contour control on once, after the program start
    and before the first motion, and writes the tolerance (0.02 mm) in no block; a program without
    one writes no G05.1."""
    lines = _write(tmp_path, "fanuc", "machine", tolerance=0.02)
    g051 = [k for k, ln in enumerate(lines) if _code(ln).startswith("G05.1")]
    assert [_code(lines[k]) for k in g051] == ["G05.1 Q1"]
    assert g051[0] < _motion(lines)[0]
    assert all(min(k for k, ln in enumerate(lines) if _code(ln) == g) < g051[0] for g in ("G21", "G90", "G17"))
    assert not any("0.02" in _code(ln) for ln in lines)
    (tmp_path / "none").mkdir()
    bare = _write(tmp_path / "none", "fanuc", "machine", tolerance=None)
    assert _motion(bare)
    assert not any(_code(ln).startswith("G05.1") for ln in bare)


# ---- generic (ISO 6983 / RS274/NGC): no tool-centre-point word, no tolerance word --------------------
def test_generic_has_no_tcp_or_tolerance_word(tmp_path):
    """RS274/NGC (NIST RS274NGC Interpreter version 3, "Input: the G codes"; the LinuxCNC G-code
    manual's quick-reference table) has no tool-centre-point G code and no path-tolerance word (G64
    P is LinuxCNC's own addition): the generic dialect refuses tcp mode and its program carries no
    G64, G05.1, CYCLE832 or cycle 32 word, whatever the tolerance."""
    with pytest.raises(InputError, match="no tool-centre-point command"):
        _write(tmp_path, "generic", "tcp")
    code = [_code(ln) for ln in _write(tmp_path, "generic", "machine", tolerance=0.05)]
    assert not any(c.startswith(("G64", "G05.1", "CYCLE832", "CYCL", "G43.4", "G234")) for c in code)
    assert [c for c in code if c][:3] == ["G21", "G90", "G17"]  # mm, absolute, XY plane before anything else


# ---- Haas (read): G234 TCPC ... G49, G187 without motion --------------------------------------------
HAAS = """%
O01000 (HAAS TCPC)
G90 G21 G17 G40 G80
G54
G187 P1 E0.02
G00 X0. Y0. Z50. B0. C0.
G234 H1
G01 X10. Y0. Z5. B10. C0. F500.
G01 X12. Y1. Z5. B10. C5.
G49
G01 X14. Y2. Z20. B0. C0.
M30
%
"""


def test_haas_g234_tcpc_until_g49_and_g187_moves_nothing(tmp_path):
    """Haas Next Generation Control Mill Operator's Manual, "G234 - Tool Center Point Control
    (TCPC) (Group 08)": "The Haas CNC control combines the known centers of rotation for the
    rotary table (MRZP) and the location of the workpiece (e.g., active work offset G54) into a
    coordinate system. TCPC makes sure that this coordinate system remains fixed relative to the
    table": under G234 X Y Z are the tool tip in the workpiece frame. Group 08 is the tool length
    offset group (RS274/NGC, Table 4 "Modal Groups": "8: G43, G49, tool length offset"), so G49
    ends G234. G187 (the Haas accuracy control: smoothness P, corner rounding E) is a group 00 code
    that moves no axis: its E is not a position.

    By hand: the two blocks between G234 and G49 are TCP points whose tips are their X Y Z words,
    with the tool axis of a BC table T = Rz(C) Ry(B) e_z = (sin B cos C, sin B sin C, cos B); the
    block after G49 is a machine-mode point; G187 adds no point."""
    path = tmp_path / "haas.nc"
    path.write_text(HAAS)
    p = read_posted(path)
    assert [int(v) for v in p.modes["tcp"]] == [0, 1, 1, 0]
    assert np.allclose(p.tip, [[0, 0, 50], [10, 0, 5], [12, 1, 5], [14, 2, 20]])
    b, c = math.radians(10.0), math.radians(5.0)
    assert np.allclose(p.axis[2], [math.sin(b) * math.cos(c), math.sin(b) * math.sin(c), math.cos(b)], atol=1e-12)
    assert np.allclose(p.axis[1], [math.sin(b), 0.0, math.cos(b)], atol=1e-12)
    assert list(p.line) == [6, 8, 9, 11]  # no point from G187 (line 5), G234 (7) or G49 (10)
    assert any("G187" in w and "G234" in w for w in p.warnings)


def test_haas_g234_is_not_tcp_in_linuxcnc(tmp_path):
    """LinuxCNC G-code manual: G234 is not a LinuxCNC G code (TCP there is the M428 / M429 remap of
    the trt configurations), so a LinuxCNC program's G234 is refused by name (its operation, the
    only one, is dropped), never read as TCP on."""
    path = tmp_path / "l.ngc"
    path.write_text(HAAS.replace("G187 P1 E0.02\n", ""))
    with pytest.raises(InputError, match="G234 is not read by the linuxcnc reader"):
        read_posted(path, dialect="linuxcnc")


# ---- MillPlus (read): G141 ... G40 ------------------------------------------------------------------
def test_millplus_g141_tcp_until_g40(tmp_path):
    """MillPlus: no MillPlus IT programming manual was found among the references searched
    (camsmooth.post.millplus says so); the words are those of the output of Autodesk's generic
    Heidenhain MillPlus post (millplus.cps), which writes ``G141`` alone to start tool-centre-point
    motion (X Y Z the tool tip, B C the rotary axes) and ``G40`` to end it. By hand as for Haas: the
    two blocks between G141 and G40 are TCP points at their X Y Z words."""
    path = tmp_path / "p.pm"
    path.write_text("%PM\nN9000 (MP)\nG17\nG0 X0 Y0 Z50 B0 C0\nG141\nG1 X10 Y0 Z5 B10 C0 F500\n"
                    "G1 X12 Y1 Z5 B10 C5\nG40\nG1 X14 Y2 Z20 B0 C0\nM30\n")
    p = read_posted(path)
    assert [int(v) for v in p.modes["tcp"]] == [0, 1, 1, 0]
    assert np.allclose(p.tip, [[0, 0, 50], [10, 0, 5], [12, 1, 5], [14, 2, 20]])


# ---- Heidenhain: FUNCTION TCPM F TCP AXIS POS -------------------------------------------------------------
def test_heidenhain_tcpm_feed_at_the_tool_point_and_axis_positions(tmp_path):
    """HEIDENHAIN TNC 640 User's Manual (DIN/ISO programming, 5/2013), 12.5 "FUNCTION TCPM", "Mode of
    action of the programmed feed rate": "F TCP determines that the programmed feed rate is
    interpreted as the actual relative velocity between the tool point (tool center point) and the
    workpiece"; "Interpretation of the programmed rotary axis coordinates": "AXIS POS determines that
    the TNC interprets the programmed coordinates of rotary axes as the nominal position of the
    respective axis".

    So camsmooth's Klartext TCP program says F TCP and AXIS POS, its blocks carry the tool tip X Y Z
    (the row 2 mm apart at Z = 0, the rapids 10 mm above), the rotary axes' positions (A = B = 0
    here), and F the tip feed 600 mm/min (written once: F is modal in Klartext), so each 2 mm block
    takes 2 / 600 min = 0.2 s, the t= annotation's step."""
    p = _program()
    p.t_prog = np.array([0.0, 0.2, 0.4, 0.6])
    path = write_program(tmp_path / "h.h", p, _machine("heidenhain", "tcp"))
    lines = [ln.split(" ", 1)[1] for ln in path.read_text().splitlines()]
    tcpm = [ln for ln in lines if ln.startswith("FUNCTION TCPM")]
    assert len(tcpm) == 1 and " F TCP " in tcpm[0] + " " and " AXIS POS " in tcpm[0] + " "
    blocks = [ln for ln in lines if ln.startswith("L ")]
    assert lines.index(tcpm[0]) < lines.index(blocks[0])
    words = [_words(ln.split(";")[0]) for ln in blocks]
    assert np.allclose([(w["X"], w["Z"]) for w in words],
                       [(0.0, SAFE)] + [(STEP * i, 0.0) for i in range(N)] + [(STEP * (N - 1), SAFE)])
    assert all(w["A"] == 0.0 and w["B"] == 0.0 for w in words)
    assert [w["F"] for w in words if "F" in w] == [FEED]
    t = [float(ln.split("t=")[1].split()[0]) for ln in blocks if "t=" in ln]
    assert np.allclose(np.diff(t), 60.0 * STEP / FEED)
