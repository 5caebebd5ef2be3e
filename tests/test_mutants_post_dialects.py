"""What the mutation runs of the post writer and the dialect readers (benchmarks/mutation.py, targets
"post-writer", "post-iso", "post-heidenhain", "post-siemens", "post-millplus", "post-own") showed the
writer / reader tests leave open, against values worked by hand here: the writer's number formats,
comments, row breaks, block feeds and the program's frame words; the readers' words, frames and
modes. Units: mm, mm/min, s; degrees in the files.
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
from camsmooth.post.writer import (
    _fixed,
    _fixed_sig,
    _row_slices,
    format_blocks,
    paren,
    semicolon,
    settings,
    write_program,
)

PIVOT = 150.0


def _machine(dialect: str = "generic", mode: str = "machine", tool: int = 1, vmax: float = 60.0, pivot: float = PIVOT,
             **post):
    axes = {a: {"min": -110.0, "max": 110.0, "vmax": vmax, "amax": 300.0} for a in ("A", "B")}
    return machine_from_dict({"machine": {"name": "mutants AB head", "kind": "AB-head", "pivot": pivot},
                              "axis": axes, "post": {"dialect": dialect, "mode": mode, "tool": tool, **post}},
                             "<mutants>")


def _line_program(n: int = 4, step: float = 2.0, feed: float = 600.0, rows=None, tolerance=None) -> PostProgram:
    """The tip steps ``step`` mm along X at Z = 0, tool axis vertical (A = B = 0): the AB head's pivot
    is the tip + (0, 0, 150)."""
    tips = np.column_stack([step * np.arange(n), np.zeros(n), np.zeros(n)])
    T = np.tile([0.0, 0.0, 1.0], (n, 1))
    joints = np.column_stack([tips + PIVOT * T, np.zeros(n), np.zeros(n)])
    return PostProgram(rows=np.zeros(n, int) if rows is None else np.asarray(rows), idx=np.arange(n), joints=joints,
                       tips=tips, axis=T, feed=np.full(n, feed), tolerance=tolerance)


def _code(line: str) -> str:
    return re.sub(r"\([^()]*\)", "", line.split(";", 1)[0]).strip()


def _words(line: str) -> dict[str, float]:
    return {w: float(v) for w, v in re.findall(r"([A-Z])\s*([-+]?\d+\.?\d*)", _code(line))}


def _lines(path: Path) -> list[str]:
    return path.read_text().splitlines()


# ---- writer: text helpers and number formats --------------------------------------------------------
def test_comments_keep_their_delimiters_out():
    """An ISO comment cannot hold '(' or ')' (the first ')' would end it) nor ';' (a comment start for
    many parsers) nor a line break; a ';' comment cannot hold a line break."""
    assert paren("a(b)c;d\ne") == "(a[b]c,d e)"
    assert semicolon("x\ny; z") == "; x y; z"


def test_fixed_point_text_rounds_and_never_writes_minus_zero():
    """4 decimals: -0.00004 rounds to 0 and is written '0.0000' (no '-0'); 1.23456 -> 1.2346;
    -2.5 -> -2.5000; 12 -> 12.0000; with sign: '+' on the non-negative values; 1 decimal: 599.96 -> 600.0."""
    assert list(_fixed(np.array([-0.00004, 1.23456, -2.5, 12.0]))) == ["0.0000", "1.2346", "-2.5000", "12.0000"]
    assert list(_fixed(np.array([0.0, 3.0, -3.0]), sign=True)) == ["+0.0000", "+3.0000", "-3.0000"]
    assert list(_fixed(np.array([599.96, 0.04]), 1)) == ["600.0", "0.0"]
    assert list(_fixed(np.array([0.000123456789]), 9)) == ["0.000123457"]


def test_fixed_significant_digits():
    """7 significant digits, 1 to 5 decimals: 300 -> 300.0000 (exponent 2: 4 decimals), 60 ->
    60.00000, 0.5 -> 0.50000 (7 would be needed, 5 at most), 12345.678 -> 12345.68, 1234567.8 ->
    1234567.8 (at least 1 decimal), 1 -> 1.000000 (exponent 0: 6 decimals, clipped to 5)."""
    got = _fixed_sig(np.array([300.0, 60.0, 0.5, 12345.678, 1234567.8, 1.0]))
    assert list(got) == ["300.0000", "60.00000", "0.50000", "12345.68", "1234567.8", "1.00000"]


def test_row_slices_break_where_the_row_id_changes():
    assert _row_slices(np.array([0, 0, 1, 1, 1, 0])) == [slice(0, 2), slice(2, 5), slice(5, 6)]
    assert _row_slices(np.array([7])) == [slice(0, 1)]
    assert _row_slices(np.array([], int)) == []


# ---- writer: settings ---------------------------------------------------------------------------------
def test_settings_take_the_machine_post_and_refuse_what_cannot_be_written():
    m = _machine("fanuc", "tcp", tool=5, tcp_on="G43.4 H{tool} (MINE)", tcp_off="G49 (MINE)")
    st = settings(m, safe_height=0.0)
    assert (st.entry.name, st.mode, st.tool, st.tcp_on, st.tcp_off, st.safe_height) == \
        ("fanuc", "tcp", 5, "G43.4 H{tool} (MINE)", "G49 (MINE)", 0.0)
    st = settings(m, dialect="siemens", mode="machine")
    assert (st.entry.name, st.mode, st.tcp_on) == ("siemens", "machine", "G43.4 H{tool} (MINE)")
    plain = settings(_machine("siemens", "tcp"))
    assert (plain.tcp_on, plain.tcp_off, plain.tool, plain.safe_height) == ("TRAORI", "TRAFOOF", 1, 10.0)
    none = settings(object())  # no [post]: generic, machine mode, tool 1, no TCP words
    assert (none.entry.name, none.mode, none.tool, none.tcp_on, none.tcp_off) == ("generic", "machine", 1, None, None)
    with pytest.raises(InputError, match="unknown G-code dialect 'haas'"):
        settings(m, dialect="haas")
    with pytest.raises(InputError, match="unknown G-code mode 'tool'"):
        settings(m, mode="tool")
    with pytest.raises(InputError, match="Heidenhain controls have no inverse-time feed"):
        settings(m, dialect="heidenhain", mode="machine")
    with pytest.raises(InputError, match="the generic dialect has no tool-centre-point command"):
        settings(_machine("generic", "tcp"))
    for bad in (-0.1, math.nan, math.inf):
        with pytest.raises(InputError, match="safe height must be a finite number >= 0 mm"):
            settings(m, safe_height=bad)


def test_settings_of_a_post_table_without_a_tool_or_tcp_words():
    """A [post] given as a bare object with dialect and mode only: tool 1, the dialect's TCP words."""
    from types import SimpleNamespace

    st = settings(SimpleNamespace(post=SimpleNamespace(dialect="fanuc", mode="tcp")))
    assert (st.tool, st.tcp_on, st.tcp_off) == (1, "G43.4 H{tool}", "G49")


def test_a_retract_out_of_travel_is_named(tmp_path):
    """The pivot runs at Z = 150 (tip Z 0 + 150); Z travels up to 155 mm: the points fit, the retract
    10 mm up the tool axis (Z 160) does not, at row 3, point 0 (the row's first point)."""
    from camsmooth.errors import InfeasibleError

    axes = {a: {"min": -110.0, "max": 110.0, "vmax": 60.0, "amax": 300.0} for a in ("A", "B")}
    axes["Z"] = {"min": -500.0, "max": 155.0, "vmax": 500.0, "amax": 3000.0}
    m = machine_from_dict({"machine": {"name": "short Z", "kind": "AB-head", "pivot": PIVOT}, "axis": axes}, "<z>")
    p = _line_program(rows=[3, 3, 3, 3])
    with pytest.raises(InfeasibleError, match=r"G-code retract \(10 mm along the tool axis\): axis Z = 160.0000 mm "
                       r"outside travel \[-500.0000, 155.0000\] mm at row 3, point 0"):
        write_program(tmp_path / "z.nc", p, m)
    write_program(tmp_path / "z.nc", p, m, safe_height=5.0)  # Z 155: within travel


# ---- writer: whole programs ---------------------------------------------------------------------------
def test_bad_feed_and_non_finite_points_are_named(tmp_path):
    p = _line_program()
    p.feed[2] = 0.0
    with pytest.raises(InputError, match=r"feed must be a finite number > 0 mm/min at row 0, point 2, got 0.0"):
        write_program(tmp_path / "a.nc", p, _machine())
    p = _line_program()
    p.feed[1] = math.nan
    with pytest.raises(InputError, match="at row 0, point 1, got nan"):
        write_program(tmp_path / "a.nc", p, _machine())
    for field in ("joints", "axis", "tips"):
        p = _line_program()
        getattr(p, field)[3, 1] = math.inf
        with pytest.raises(InputError, match="non-finite axis value at row 0, point 3"):
            write_program(tmp_path / "b.nc", p, _machine())
    assert not (tmp_path / "a.nc").exists() and not (tmp_path / "b.nc").exists()


def test_two_rows_are_entered_and_left_along_the_tool_axis(tmp_path):
    """Rows 0 (points 0, 1) and 1 (points 2, 3), tips 2 mm apart along X, safe height 5 mm, generic
    machine mode: per row a rapid to 5 mm above its first point (pivot Z 155), a feed onto it (5 mm
    at 600 mm/min: F = 120), the row (2 mm: F = 300), a rapid 5 mm up; each row opened by its
    comment '(row <id>: <points> points)'."""
    p = _line_program(rows=[0, 0, 1, 1])
    lines = _lines(write_program(tmp_path / "r.nc", p, _machine(), safe_height=5.0))
    body = lines[next(k for k, ln in enumerate(lines) if ln.startswith("(row 0")):]
    expect = ["(row 0: 2 points)",
              "G00 X0.0000 Y0.0000 Z155.0000 A0.0000 B0.0000",
              "G01 X0.0000 Y0.0000 Z150.0000 A0.0000 B0.0000 F120.0000",
              "G01 X2.0000 Y0.0000 Z150.0000 A0.0000 B0.0000 F300.0000",
              "G00 X2.0000 Y0.0000 Z155.0000 A0.0000 B0.0000",
              "(row 1: 2 points)",
              "G00 X4.0000 Y0.0000 Z155.0000 A0.0000 B0.0000",
              "G01 X4.0000 Y0.0000 Z150.0000 A0.0000 B0.0000 F120.0000",
              "G01 X6.0000 Y0.0000 Z150.0000 A0.0000 B0.0000 F300.0000",
              "G00 X6.0000 Y0.0000 Z155.0000 A0.0000 B0.0000",
              "G94", "M30"]
    assert body == expect


def test_a_block_that_only_turns_is_timed_by_the_rotary_speed_limit(tmp_path):
    """On a head of pivot 0 (the tip is the pivot) the tip stays at the origin while B turns 0 -> 6
    -> 12 deg (A = 0): the tip path of each block is 0, so its time is the rotary move over the
    axis speed limit, 6 deg at 60 deg/s = 0.1 s = 1/600 min: F = 600 (1/min); the entry block moves
    nothing at all (safe height 0): the 1e-6 min floor, F = 1e6. The header counts the three
    blocks. A machine without speed limits times them at the floor."""
    n = 3
    B = np.radians([0.0, 6.0, 12.0])
    T = np.column_stack([np.sin(B), np.zeros(n), np.cos(B)])
    tips = np.zeros((n, 3))
    joints = np.column_stack([tips, np.zeros(n), B])
    p = PostProgram(rows=np.zeros(n, int), idx=np.arange(n), joints=joints, tips=tips, axis=T, feed=np.full(n, 600.0))
    lines = _lines(write_program(tmp_path / "s.nc", p, _machine(vmax=60.0, pivot=0.0), safe_height=0.0))
    assert any("3 block[s] turn A/B without moving the tip: timed by the rotary speed limits" in ln for ln in lines)
    feeds = [_words(ln)["F"] for ln in lines if _code(ln).startswith("G01")]
    assert feeds == pytest.approx([1e6, 600.0, 600.0], rel=1e-6)
    slow = _lines(write_program(tmp_path / "t.nc", p, _machine(vmax=30.0, pivot=0.0), safe_height=0.0))
    assert [_words(ln)["F"] for ln in slow if _code(ln).startswith("G01")] == pytest.approx([1e6, 300.0, 300.0])


def test_a_table_machine_times_its_first_rotary_axis_and_says_linuxcncs_sense(tmp_path):
    """A BC table (rotary axes B, C; B turns at most 30 deg/s, C 90 deg/s) with the tip at the table
    centre while B turns 0 -> 6 -> 12 deg: the linear axes stay at the centre and the tip does not
    move, so each block takes 6 deg / 30 deg/s = 0.2 s = 1/300 min (F = 300), timed by B's limit, not
    C's (which does not turn); LinuxCNC writes the table's own turn, b = -B (B-6.0000), and the header
    says 'b = -B, c = -C'."""
    axes = {"B": {"min": -110.0, "max": 110.0, "vmax": 30.0, "amax": 300.0},
            "C": {"min": -400.0, "max": 400.0, "vmax": 90.0, "amax": 300.0}}
    m = machine_from_dict({"machine": {"name": "bc", "kind": "BC-table"}, "axis": axes,
                           "post": {"dialect": "linuxcnc", "mode": "machine"}}, "<bc>")
    n = 3
    B, C = np.radians([0.0, 6.0, 12.0]), np.zeros(n)
    tips = np.zeros((n, 3))
    T = np.column_stack([np.sin(B), np.zeros(n), np.cos(B)])  # Rz(0) Ry(B) e_z
    p = PostProgram(rows=np.zeros(n, int), idx=np.arange(n), joints=np.column_stack([tips, B, C]), tips=tips, axis=T,
                    feed=np.full(n, 600.0))
    lines = _lines(write_program(tmp_path / "bc.ngc", p, m, safe_height=0.0))
    moves = [ln for ln in lines if _code(ln).startswith("G01")]
    assert [_words(ln)["F"] for ln in moves] == pytest.approx([1e6, 300.0, 300.0])
    assert [_words(ln)["B"] for ln in moves] == [0.0, -6.0, -12.0]
    assert any("b = -B, c = -C, where B C are the tool's rotation" in ln for ln in lines)


def test_an_empty_program_is_its_frame_only(tmp_path):
    p = PostProgram(rows=np.zeros(0, int), idx=np.zeros(0, int), joints=np.zeros((0, 5)), tips=np.zeros((0, 3)),
                    axis=np.zeros((0, 3)), feed=np.zeros(0))
    code = [_code(ln) for ln in _lines(write_program(tmp_path / "e.nc", p, _machine())) if _code(ln)]
    assert code == ["G21", "G90", "G17", "G93", "G94", "M30"]


def test_format_blocks_inverse_time_and_per_minute():
    """format_blocks: G93 F on every feed block (7 significant digits), none on a rapid; per minute F
    written where it changes or after a rapid (1 decimal)."""
    coords = np.array([[0, 0, 1, 0, 0], [1, 0, 1, 0, 0], [2, 0, 1, 0, 0], [3, 0, 1, 0, 0]], float)
    rapid = np.array([True, False, False, False])
    inv = format_blocks("generic", coords, np.array([math.nan, 250.0, 250.0, 125.0]), rapid, "XYZAB", True)
    assert inv == ["G00 X0.0000 Y0.0000 Z1.0000 A0.0000 B0.0000",
                   "G01 X1.0000 Y0.0000 Z1.0000 A0.0000 B0.0000 F250.0000",
                   "G01 X2.0000 Y0.0000 Z1.0000 A0.0000 B0.0000 F250.0000",
                   "G01 X3.0000 Y0.0000 Z1.0000 A0.0000 B0.0000 F125.0000"]
    per = format_blocks("heidenhain", coords, np.array([math.nan, 600.0, 600.0, 450.0]), rapid, "XYZBC", False)
    assert per == ["L X+0.0000 Y+0.0000 Z+1.0000 B+0.0000 C+0.0000 R0 FMAX",
                   "L X+1.0000 Y+0.0000 Z+1.0000 B+0.0000 C+0.0000 F600.0",
                   "L X+2.0000 Y+0.0000 Z+1.0000 B+0.0000 C+0.0000",
                   "L X+3.0000 Y+0.0000 Z+1.0000 B+0.0000 C+0.0000 F450.0"]


def test_heidenhain_program_is_numbered_and_framed(tmp_path):
    """Klartext: every line numbered from 0, BEGIN PGM <name> MM first and END PGM <name> MM last,
    TOOL CALL <tool> Z, cycle 32 with T = the tolerance, FUNCTION TCPM after it, the blocks' F the tip
    feed (600.0) once, FUNCTION RESET TCPM, M140 MB MAX, M30; the annotations t= / f= after ';'."""
    p = _line_program(tolerance=0.015)
    p.t_prog = np.array([0.0, 0.2, 0.4, 0.6])
    p.f_prog = np.array([600.0, 600.0, 500.0, 500.0])
    lines = _lines(write_program(tmp_path / "h.h", p, _machine("heidenhain", "tcp", tool=3), program_name="PART7"))
    assert [int(ln.split()[0]) for ln in lines] == list(range(len(lines)))
    text = [ln.split(" ", 1)[1] for ln in lines]
    assert text[0] == "BEGIN PGM PART7 MM" and text[-1] == "END PGM PART7 MM"
    k = text.index("TOOL CALL 3 Z")
    assert text[k + 1:k + 5] == ["CYCL DEF 32.0 TOLERANCE", "CYCL DEF 32.1 T0.0150", "CYCL DEF 32.2 HSC-MODE:0",
                                 "FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS"]
    assert text[-5:-1] == ["L X+6.0000 Y+0.0000 Z+10.0000 A+0.0000 B+0.0000 R0 FMAX", "FUNCTION RESET TCPM",
                           "M140 MB MAX", "M30"]
    rows = [t for t in text if t.startswith("L ") and "FMAX" not in t]
    assert rows == ["L X+0.0000 Y+0.0000 Z+0.0000 A+0.0000 B+0.0000 F600.0 ; t=0.000000000 f=600.000",
                    "L X+2.0000 Y+0.0000 Z+0.0000 A+0.0000 B+0.0000 ; t=0.200000000",
                    "L X+4.0000 Y+0.0000 Z+0.0000 A+0.0000 B+0.0000 ; t=0.400000000 f=500.000",
                    "L X+6.0000 Y+0.0000 Z+0.0000 A+0.0000 B+0.0000 ; t=0.600000000"]


def test_iso_annotations_and_the_time_optimal_law(tmp_path):
    """Parenthesised annotations: '(t=<s> f=<mm/min> o=<s>)' where the time-optimal law is given, f=
    at the row's entry and where the programmed feed changes."""
    p = _line_program()
    p.t_prog = np.array([0.0, 0.2, 0.4, 0.6])
    p.f_prog = np.array([600.0, 600.0, 600.0, 300.0])
    p.t_opt = np.array([0.0, 0.1, 0.2, 0.3])
    lines = _lines(write_program(tmp_path / "o.nc", p, _machine("fanuc", "tcp")))
    notes = [ln[ln.index("(t="):] for ln in lines if ln.startswith("G01")]
    assert notes == ["(t=0.000000000 f=600.000 o=0.000000000)", "(t=0.200000000 o=0.100000000)",
                     "(t=0.400000000 o=0.200000000)", "(t=0.600000000 f=300.000 o=0.300000000)"]


# ---- ISO reader (camsmooth.post.iso): three-axis programs, X Y Z the tool tip --------------------------
def _iso(tmp_path: Path, body: str, dialect: str = "iso", head: str = "G90 G21 G17\n"):
    """A program of two operations: GOOD (a rapid to (0, 0, 5) and a feed to (1, 0, 5)) and BAD
    (``body``, from line 6 on); no rotary word, so every point's X Y Z is the tip."""
    path = tmp_path / "t.nc"
    path.write_text(head + "(Operation: GOOD)\nG00 X0 Y0 Z5\nG01 X1 Y0 Z5 F100\n(Operation: BAD)\n" + body + "\nM30\n")
    p = read_posted(path, dialect=dialect)
    notes = [w for w in p.warnings if "nominal" not in w and "no machine file" not in w]
    return p, " | ".join(notes)


@pytest.mark.parametrize("body, points", [
    # G68 in the G17 plane: (2, 0) turned 90 deg about (1, 0) is (1, 1); G69 ends it
    ("G68 X1 Y0 R90\nG01 X2 Y0 Z5\nG69\nG01 X3 Y0 Z5", [[1, 1, 5], [3, 0, 5]]),
    # G68 about the vector I J K = +X through the origin by 90 deg: (0, 1, 5) -> (0, -5, 1)
    ("G68 X0 Y0 Z0 I1 J0 K0 R90\nG01 X0 Y1 Z5", [[0, -5, 1]]),
    # G68 in the G18 (ZX) plane turns about +Y: (2, 0, 5) about the origin by 90 deg -> (5, 0, -2)
    ("G18\nG68 X0 Z0 R90\nG01 X2 Y0 Z5", [[5, 0, -2]]),
    # G52 shifts the local frame by its X Y Z; G52 X0 Y0 takes the shift away
    ("G52 X10 Y20\nG01 X1 Y1 Z5\nG52 X0 Y0\nG01 X2 Y2 Z5", [[11, 21, 5], [2, 2, 5]]),
    # G91 incremental from (1, 0, 5); G20 inch: X.1 = 2.54 mm
    ("G91\nG01 X1 Y2 Z0\nG90", [[2, 2, 5]]),
    ("G20\nG01 X.1 Y0 Z.5", [[2.54, 0, 12.7]]),
    # '#' parameters and an expression
    ("#100=2.5\nG01 X[#100*2] Y#100 Z5", [[5, 2.5, 5]]),
    # G53 / G28 move in machine coordinates: no point
    ("G53 X0 Y0 Z0\nG01 X2 Y0 Z5", [[2, 0, 5]]),
    ("G28 X0\nG01 X2 Y0 Z5", [[2, 0, 5]]),
    # G99: after a hole the tool stands at the R level, the next move starts there
    ("G99 G81 X2 Y0 Z-2 R1\nG80\nG01 X4 Y0", [[4, 0, 1]]),
    # G98 (the default): back to the initial level; the hole is no point
    ("G81 X2 Y0 Z-2 R1\nG80\nG01 X4 Y0", [[4, 0, 5]]),
    # a block-delete '/' block is read as executed
    ("/G01 X3 Y0 Z5", [[3, 0, 5]]),
])
def test_iso_frames_units_and_parameters(tmp_path, body, points):
    p, _ = _iso(tmp_path, body)
    np.testing.assert_allclose(p.tip[2:], points, atol=1e-9)


@pytest.mark.parametrize("body, reason", [
    ("G68 X0 Y0 Z0 I0 J0 K0 R90\nG01 X0 Y1 Z5", "G68 with a zero rotation vector"),
    ("M98 P1234", "M98 P1234: subprogram O1234 is not in this file"),
    ("M98", "M98 without P"),
    ("M97 P77", "M97 P77: no block N77 in this file"),
    ("M97", "M97 P: no block N in this file"),
    ("G68.2 P1 X0 Y0 Z0 I0 J0 K0", "G68.2 P1 (a tilted plane given by roll-pitch-yaw"),
    ("G01 X1 Y0 Z5 U3", "word U not read by this reader"),
    ("G01 X1 Y0 Z5 U3 V2", "words U, V not read by this reader"),
    ("G80\nX3 Y0 Z5", "a position without a motion mode (G0/G1/G2/G3)"),
    ("G02 X2 Y0 Z5 R0.2", "arc radius R0.2 is smaller than half the chord (0.5 mm)"),
    ("G02 X1 Y0 Z5 R1", "a full circle given by R (the centre is not defined)"),
    ("G02 X3 Y0 Z5 I1 J0.5", ""),
    ("G02 X3 Y0 Z5 I2.1 J0", "arc end point radius 0.1 mm differs from the start radius 2.1 mm"),
    ("G18\nG81 X1 Y0 Z-2 R1", "canned cycle G81 in plane G18 (only G17 cycles are read)"),
    ("G91\nG81 X1 Y0 Z-2 R1", "canned cycle G81 in incremental mode (G91)"),
    ("G81 X1 Y0 R1", "canned cycle G81 without a depth Z"),
    ("#1 2\nG01 X1", "a '#' word that is not an assignment"),
    ("G01 X Y1", "word X has no value ('XY1')"),
    ("G01 X1 X2", "word X twice in one block"),
    ("G01 X1 *2", "'*2' is not a word (a letter and its value)"),
    ("G93\nG01 X2 Y0 Z5 F0", "F0 in inverse time (G93) is not a block time"),
    ("G41 D1\nG01 X1 Y0 Z5", "cutter radius compensation (G41): the programmed path is not the tool's"),
    ("G300\nG01 X2 Y0 Z5", "G300 is not read by the iso reader"),
    ("o100 sub\nG01 X2 Y0 Z5", "LinuxCNC o-word sub (control flow and subroutines of o-words are not executed"),
    ("o100 return", "LinuxCNC o-word return (control flow"),
    ("o<name> while [1 LT 2]", "LinuxCNC o-word while (control flow"),
    ("G01 X[1/0] Y0 Z5", "has no value (division by zero or out of range)"),
])
def test_iso_refusals_name_their_reason_and_cost_only_their_operation(tmp_path, body, reason):
    p, notes = _iso(tmp_path, body)
    if reason:
        assert "operation 'BAD' (line 5) dropped" in notes and reason in notes, notes
        np.testing.assert_allclose(p.tip, [[0, 0, 5], [1, 0, 5]])
    else:  # the arc is read: its end point is (3, 0, 5), every point on the circle of radius hypot(1, .5)
        np.testing.assert_allclose(p.tip[-1], [3, 0, 5], atol=1e-12)
        np.testing.assert_allclose(np.hypot(p.tip[2:, 0] - 2, p.tip[2:, 1] - 0.5), math.hypot(1, 0.5), atol=1e-9)
        assert len(p.tip) > 12 and p.tip[:, 1].max() == pytest.approx(0.5 + math.hypot(1, 0.5), abs=1e-3)


def test_iso_words_that_move_nothing_are_named(tmp_path):
    """G10 (offset data), G05.1, G61, G13.1, G234 / G49 on a three-axis program, the extra work
    offsets: named, and no point is added or moved."""
    p, notes = _iso(tmp_path, "G10 L2 P1 X0\nG05.1 Q1\nG61\nG13.1\nG54.1 P3\nG154 P7\nG112\nG01 X2 Y0 Z5")
    np.testing.assert_allclose(p.tip[2:], [[2, 0, 5]])
    for word in ("G10 (offset data) (line 6)", "G05.1 (look-ahead) (line 7)", "G61 (line 8)", "G13.1 (line 9)",
                 "G54.1 P3, G154 P7, G112"):
        assert word in notes, (word, notes)
    assert "G01 X1 F2" not in notes


def test_iso_the_program_is_between_the_percent_lines(tmp_path):
    """A listing banner before the first '%' and whatever follows the second '%' are not program."""
    path = tmp_path / "b.nc"
    path.write_text("BANNER G01 X99 Y99 Z99\n%\nG90 G21\nG00 X0 Y0 Z5\nG01 X1 Y0 Z5 F100\n%\nG01 X50 Y50 Z50\n")
    p = read_posted(path, dialect="iso")
    np.testing.assert_allclose(p.tip, [[0, 0, 5], [1, 0, 5]])


def test_iso_subprograms_repeat(tmp_path):
    """M98 P2000 L3 runs O2000 (one incremental step of 1 mm in X) three times; the Fanuc form
    M98 P20002000 (repeats and number in one word) twice; M99 returns."""
    sub = "O2000\nG91 G01 X1\nG90\nM99\n"
    for call, n in (("M98 P2000 L3", 3), ("M98 P22000", 2)):
        path = tmp_path / "s.nc"
        path.write_text(f"%\nO1000\nG90 G21\nG00 X0 Y0 Z5\nG01 X0 Y0 Z4 F100\n{call}\nM30\n{sub}%\n")
        p = read_posted(path, dialect="iso")
        np.testing.assert_allclose(p.tip[2:, 0], np.arange(1, n + 1), err_msg=call)


# ---- Heidenhain Klartext reader (camsmooth.post.heidenhain) ----------------------------------------------
def _klartext(tmp_path: Path, body: str, head: str = "BEGIN PGM T MM"):
    """Operations GOOD (TOOL CALL with F500, a rapid to (0, 0, 5), a feed to (1, 0, 5) at F100) and
    BAD (``body``, from line 7 on); no rotary word: X Y Z is the tip, the axis +Z."""
    path = tmp_path / "t.h"
    path.write_text(head + "\n* - GOOD\nTOOL CALL 1 Z S1000 F500\nL X+0 Y+0 Z+5 R0 FMAX\nL X+1 Y+0 Z+5 F100\n"
                    "* - BAD\n" + body + "\nEND PGM T MM\n")
    p = read_posted(path, dialect="heidenhain")
    notes = [w for w in p.warnings if "nominal" not in w and "no machine file" not in w]
    return p, " | ".join(notes)


@pytest.mark.parametrize("body, tip, axis, feed", [
    # PLANE EULER: R = Rz(PR) Rx(NU) Rz(ROT); PR = 90: (1, 0, 5) -> (0, 1, 5)
    ("PLANE EULER EULPR+90 EULNU+0 EULROT+0 TURN\nL X+1 Y+0 Z+5", [0, 1, 5], [0, 0, 1], 100),
    # PLANE EULER NU = 90 tilts Z to -Y: (0, 0, 5) -> (0, -5, 0), the axis R e_z = (0, -1, 0)
    ("PLANE EULER EULPR+0 EULNU+90 EULROT+0 TURN\nL X+0 Y+0 Z+5", [0, -5, 0], [0, -1, 0], 100),
    # the angles left out are 0: PLANE EULER EULPR+90 alone is Rz(90)
    ("PLANE EULER EULPR+90 TURN\nL X+1 Y+0 Z+5", [0, 1, 5], [0, 0, 1], 100),
    ("PLANE SPATIAL SPC+90 TURN\nL X+1 Y+0 Z+5", [0, 1, 5], [0, 0, 1], 100),
    # PLANE VECTOR: Z along N = -Y, X along B = +X, Y = Z x X = +Z: (1, 2, 3) -> (1, -3, 2)
    ("PLANE VECTOR BX+1 BY+0 BZ+0 NX+0 NY-1 NZ+0 STAY\nL X+1 Y+2 Z+3", [1, -3, 2], [0, -1, 0], 100),
    # incremental words, Q parameters (Qn = and FN 0:), F AUTO = the TOOL CALL's F
    ("L IX+1 IY+2", [2, 2, 5], [0, 0, 1], 100),
    ("Q1 = 2\nL X+Q1", [2, 0, 5], [0, 0, 1], 100),
    ("FN 0: Q2 = +3\nL Y+Q2", [1, 3, 5], [0, 0, 1], 100),
    ("L X+2 F AUTO", [2, 0, 5], [0, 0, 1], 500),
    ("L X+2 F250", [2, 0, 5], [0, 0, 1], 250),
    # STOP, BLK FORM, CYCL DEF 247 and M140 move nothing
    ("STOP\nL X+2", [2, 0, 5], [0, 0, 1], 100),
    ("BLK FORM 0.1 Z X+0 Y+0 Z-10\nL X+2", [2, 0, 5], [0, 0, 1], 100),
    ("CYCL DEF 247 DATUM SETTING ~\nQ339=+3 ;DATUM NUMBER\nL X+2", [2, 0, 5], [0, 0, 1], 100),
    ("L Z+50 R0 FMAX M140 MB MAX\nL X+2 Y+0 Z+5", [2, 0, 5], [0, 0, 1], 100),
    # LN with the tool vector TX TY TZ: the axis is the vector
    ("LN X+2 Y+0 Z+5 TX+0 TY+0.6 TZ+0.8", [2, 0, 5], [0, 0.6, 0.8], 100),
])
def test_klartext_planes_words_and_feeds(tmp_path, body, tip, axis, feed):
    p, _ = _klartext(tmp_path, body)
    np.testing.assert_allclose(p.tip[2], tip, atol=1e-9)
    np.testing.assert_allclose(p.axis[2], axis, atol=1e-9)
    assert p.feed[2] == pytest.approx(feed)
    assert len(p.tip) == 3


@pytest.mark.parametrize("body", ["CC X+0 Y+0\nC X+0 Y+1 DR+", "CR X+0 Y+1 R+1 DR+", "CR X+0 Y+1 R-1 DR-"])
def test_klartext_quarter_arcs(tmp_path, body):
    """(1, 0) -> (0, 1) on the unit circle about the origin (the circle of radius 1 through both
    points centred there or at (1, 1)): counter-clockwise, the short way, for C about CC with DR+
    and CR R+1 DR+ (R+: central angle <= 180 deg); clockwise, the long way (270 deg, through
    (0, -1) and (-1, 0)), for CR R-1 DR- (R-: more than 180 deg) -- about the origin too."""
    p, _ = _klartext(tmp_path, body)
    arc = p.tip[2:]
    np.testing.assert_allclose(arc[-1], [0, 1, 5], atol=1e-12)
    np.testing.assert_allclose(np.hypot(arc[:, 0], arc[:, 1]), 1.0, atol=1e-9)
    turn = np.diff(np.unwrap(np.r_[0.0, np.arctan2(arc[:, 1], arc[:, 0])]))
    if "R-1" in body:
        assert np.all(turn < 0) and turn.sum() == pytest.approx(-1.5 * math.pi)
        assert arc[:, 1].min() == pytest.approx(-1.0, abs=1e-3) and arc[:, 0].min() == pytest.approx(-1.0, abs=1e-3)
    else:
        assert np.all(turn > 0) and turn.sum() == pytest.approx(0.5 * math.pi)


def test_klartext_inch_program(tmp_path):
    """BEGIN PGM ... INCH: X Y Z in inch (X+1 = 25.4 mm), F in 0.1 inch/min (F100 = 10 inch/min =
    254 mm/min)."""
    p, _ = _klartext(tmp_path, "L X+1 Y+0 Z+1 F100", head="BEGIN PGM T INCH")
    np.testing.assert_allclose(p.tip[2], [25.4, 0, 25.4], atol=1e-9)
    assert p.feed[2] == pytest.approx(254.0)


@pytest.mark.parametrize("body, reason", [
    ("PLANE VECTOR BX+1 BY+0 BZ+0 NX+0 NY+0 NZ+0 STAY", "PLANE VECTOR with a zero normal"),
    ("PLANE VECTOR BX+0 BY+0 BZ+1 NX+0 NY+0 NZ+1 STAY", "PLANE VECTOR whose base vector is along the normal"),
    ("PLANE RELATIV STAY", "PLANE RELATIV without SPA, SPB or SPC"),
    ("PLANE AXIAL B+30 STAY", "PLANE AXIAL is not read (SPATIAL, EULER, VECTOR, RELATIV and RESET are)"),
    ("C X+0 Y+1", "C without DR+ or DR-"),
    ("C X+0 Y+1 DR+", "C without a circle centre CC"),
    ("CR X+0 Y+1 R+0.2 DR+", "CR radius 0.2 does not fit the chord 1.41421 mm"),
    ("CC X+0 Y+0\nC X+0 Y+2 DR+", "arc end point radius 2 mm differs from the start radius 1 mm"),
    ("L X+2 Y+0 Z+5 RL", "radius compensation RL/RR: the programmed path is not the tool's"),
    ("L X+2 Y+0 Z+5 RR F100", "radius compensation RL/RR"),
    ("CT X+2 Y+1", "CT is not read"),
    ("CALL PGM SUB.H", "CALL PGM (another program file) is not read"),
    ("CALL LBL 9", "label 9 is not in this program"),
    ("CALL LBL", "CALL LBL without a label"),
    ("FOO 3", "FOO is not read by the heidenhain reader"),
    ("FN 20: Q1 = +1", "FN 20 (jump, error, print or table functions) is not executed"),
    ("FN 9: IF +1 EQU +1 GOTO LBL 5", "jump to label 5, which is not in this program"),
    ("CYCL DEF 7.0 DATUM SHIFT\nCYCL DEF 7.1 #5", "CYCL DEF 7 from a datum table (#) is not read"),
    ("CYCL DEF 10.0 ROTATION\nCYCL DEF 10.1 IROT", "CYCL DEF 10 without ROT"),
    ("CYCL DEF 19.0 WORKING PLANE", "CYCL DEF 19 (tilted plane by cycle) is not read; PLANE is"),
    ("CYCL DEF 999", "CYCL DEF 999 is not read"),
    ("CYCL DEF ABC", "CYCL DEF without a cycle number"),
    ("CYCL CALL", "cycle call without a CYCL DEF"),
    ("CYCL DEF 200 DRILLING ~\nQ201=-5 ;DEPTH ~\nQ203=+1 ;SURFACE COORDINATE\nCYCL CALL PAT",
     "CYCL CALL PAT (point tables) is not read"),
])
def test_klartext_refusals_name_their_reason(tmp_path, body, reason):
    p, notes = _klartext(tmp_path, body)
    assert "operation 'BAD' (line 6) dropped" in notes and reason in notes, notes
    np.testing.assert_allclose(p.tip, [[0, 0, 5], [1, 0, 5]])


# ---- Siemens 840D reader (camsmooth.post.siemens) ---------------------------------------------------------
def _sinumerik(tmp_path: Path, body: str):
    """Operations GOOD (a rapid to (0, 0, 5), a feed to (1, 0, 5) at F100) and BAD (``body``, from line 6
    on), ';(NAME)' headings as NX's Sinumerik posts write them; no rotary word: X Y Z is the tip."""
    path = tmp_path / "t.mpf"
    path.write_text("G71 G90 G17\n;(GOOD)\nG0 X0 Y0 Z5\nG1 X1 Y0 Z5 F100\n;(BAD)\n" + body + "\nM30\n")
    p = read_posted(path, dialect="siemens")
    notes = [w for w in p.warnings if "nominal" not in w and "no machine file" not in w]
    return p, " | ".join(notes)


@pytest.mark.parametrize("body, tips", [
    # DEF variables and R parameters as word values (840D Fundamentals, "Assignments": X=R1+5, user
    # variables DEF REAL name=value): X=XX is 2 when DEF REAL XX=2
    ("DEF REAL XX=2, YY=3\nG1 X=XX Y=YY Z5", [[2, 3, 5]]),
    ("R1=1.5 R2=R1*2\nG1 X=R1+1 Y=R2 Z5", [[2.5, 3, 5]]),
    ("DEF REAL DX=0.5\nG1 X=IC(DX) Y0 Z5", [[1.5, 0, 5]]),
    # per-word incremental IC() from the current position (1, 0, 5)
    ("G1 X=IC(1) Y0 Z=IC(2)", [[2, 0, 7]]),
    # TRANS replaces the programmable frame, ATRANS adds to it, TRANS alone resets it
    ("TRANS X10\nG1 X1 Y0 Z5\nATRANS Y5\nG1 X1 Y0 Z5\nTRANS\nG1 X1 Y0 Z5", [[11, 0, 5], [11, 5, 5], [1, 0, 5]]),
    # ROT Z90 turns (1, 0, 5) to (0, 1, 5); AROT X90 then turns about the rotated X: (1, 0, 5) -> R (1, -5, 0)
    # with R = Rz(90) Rx(90): (5, 1, 0); ROT alone resets
    ("ROT Z90\nG1 X1 Y0 Z5\nAROT X90\nG1 X1 Y0 Z5\nROT\nG1 X1 Y0 Z5", [[0, 1, 5], [5, 1, 0], [1, 0, 5]]),
    # CYCLE800 axis by axis, _MODE 57 = 0b111001 (X, then Y, then Z): A = 90 about X: (1, 0, 5) -> (1, -5, 0)
    ('CYCLE800(1,"TC1",0,57,0,0,0,90,0,0,0,0,0,1)\nG1 X1 Y0 Z5', [[1, -5, 0]]),
    # ... with the reference point X0 = (10, 0, 0) and the zero point X1 = (0, 0, 1): 10 + Rx(90) (1, 0, 6)
    ('CYCLE800(1,"TC1",0,57,10,0,0,90,0,0,0,0,1,1)\nG1 X1 Y0 Z5', [[11, -6, 0]]),
    # G70 inch, G71 mm; SUPA (machine coordinates) is no point; settings and dwell move nothing
    ("G70\nG1 X1 Y0 Z1\nG71", [[25.4, 0, 25.4]]),
    ("SUPA G0 Z0\nG1 X2 Y0 Z5", [[2, 0, 5]]),
    ("FFWON SOFT COMPCAD\nG642\nCTOL=0.01\nG4 F2\nG1 X2", [[2, 0, 5]]),
    ('T="MILL" D1\nM6\nG500\nG505\nG1 X2', [[2, 0, 5]]),
])
def test_sinumerik_variables_frames_and_units(tmp_path, body, tips):
    p, notes = _sinumerik(tmp_path, body)
    assert "dropped" not in notes, notes
    if "G500" in body:
        assert "work offset(s) G500 (settable frames off), G505 selected" in notes
    np.testing.assert_allclose(p.tip[2:], tips, atol=1e-9)


def test_sinumerik_tool_vector_radius_arc_and_centre_ac(tmp_path):
    """A3 B3 C3 give the tool vector; CR=0.5 from (1, 0) to (2, 0) clockwise is the half circle about
    (1.5, 0); I=AC(1.5) J=AC(0) gives the same centre absolutely."""
    p, _ = _sinumerik(tmp_path, "G1 X2 Y0 Z5 A3=0 B3=0.6 C3=0.8")
    np.testing.assert_allclose(p.axis[2], [0, 0.6, 0.8], atol=1e-12)
    for body in ("G2 X2 Y0 Z5 CR=0.5", "G2 X2 Y0 Z5 I=AC(1.5) J=AC(0)"):
        p, _ = _sinumerik(tmp_path, body)
        arc = p.tip[2:]
        np.testing.assert_allclose(arc[-1], [2, 0, 5], atol=1e-12)
        np.testing.assert_allclose(np.hypot(arc[:, 0] - 1.5, arc[:, 1]), 0.5, atol=1e-9)
        assert len(arc) > 10 and np.all(arc[:-1, 1] > 0)  # clockwise from (1, 0) about (1.5, 0): above the X axis
        assert arc[:, 1].max() == pytest.approx(0.5, abs=1e-3)  # through (1.5, 0.5)


def test_sinumerik_mcall_holes(tmp_path):
    """MCALL CYCLE81(RTP 10, RFP 0, SDIS 2, DP -5): a hole at every X Y position until MCALL alone;
    CYCLE81 with DPR 3 (relative depth) and no DP: the bottom at RFP - DPR = -3."""
    p, notes = _sinumerik(tmp_path, "MCALL CYCLE81(10,0,2,-5)\nG0 X2 Y0\nX3\nMCALL\nG0 X4")
    holes = [h for c in p.cycles for h in c.holes]
    np.testing.assert_allclose(holes, [[2, 0, -5], [3, 0, -5]])
    assert "CYCLE81 (2 holes)" in notes
    p, _ = _sinumerik(tmp_path, "CYCLE81(10,0,2,,3)")
    np.testing.assert_allclose([h for c in p.cycles for h in c.holes], [[1, 0, -3]])


@pytest.mark.parametrize("body, reason", [
    ("IF R1 > 2 GOTOF END", "control flow IF is not executed by this reader"),
    ("CIP X2 Y1 I1=1 J1=1", "CIP (arc through an intermediate point / tangential arc) is not read"),
    ("MIRROR X0", "MIRROR (a frame from the tool, a mirror or a scale) is not read"),
    ("G1 X2 Y0 Z5 QQ=3", "QQ=3 is not read"),
    ("G1 X2 I=IC(1)", "I=IC(1) (IC on I) is not read"),
    ("CYCLE800", "CYCLE800 without its arguments"),
    ('CYCLE800(1,"TC1",0,57)', "CYCLE800 with fewer than 13 arguments"),
    ('CYCLE800(1,"TC1",0,128,0,0,0,0,0,0,0,0,0,1)', "CYCLE800 mode 128 (projection, solid or direct angles"),
    ("CYCLE81", "CYCLE81 without its arguments"),
    ("G600\nG1 X2", "G600 is not read by the siemens reader"),
    ("ASCALE X2", "ASCALE (a frame from the tool, a mirror or a scale) is not read"),
])
def test_sinumerik_refusals_name_their_reason(tmp_path, body, reason):
    p, notes = _sinumerik(tmp_path, body)
    assert "operation 'BAD' (line 5) dropped" in notes and reason in notes, notes
    np.testing.assert_allclose(p.tip, [[0, 0, 5], [1, 0, 5]])


# ---- camsmooth's own G-code read back (camsmooth.post.own) ------------------------------------------------
OWN = """(camsmooth post: dialect=generic mode=machine units=mm pivot=150.000000 method=nlp tolerance=0.01 \
kind=AB-head rotary=A,B sense=iso)
(tool: ball end R 0.0 mm, r 3.0 mm, diameter 6.0 mm, shank 40.0 mm)
(method: nlp; 3 points)
G21 G90 G17
G93
(row 5: 3 points)
G00 X0 Y0 Z160 A0 B0
G01 X0 Y0 Z150 A0 B0 F60. (t=0.000000000 f=600.000)
G01 X2 Y0 Z150 A0 B0 F300. (t=0.200000000)
G01 X4 Y0 Z150 A0 B0 F300. (t=0.400000000)
G00 X4 Y0 Z160 A0 B0
G94
M30
"""


def _own(tmp_path: Path, text: str):
    from camsmooth.post.own import read_gcode

    path = tmp_path / "own.nc"
    path.write_text(text)
    return read_gcode(path)


def test_own_program_read_back_by_hand(tmp_path):
    """Machine mode on the AB head of pivot 150 at A = B = 0: tip = pivot position - (0, 0, 150); G93
    feed = the block's tip path x F: the entry 10 mm x 60 = 600, the row 2 mm x 300 = 600 (mm/min);
    the t= annotations, the programmed feed, the row id 5, the method's 3 points (every point
    written), the tolerance and the tool of the header; the block times 60 / F from the row's start:
    0, 0.2, 0.4 s."""
    p = _own(tmp_path, OWN)
    np.testing.assert_allclose(p.tip, [[0, 0, 10], [0, 0, 0], [2, 0, 0], [4, 0, 0], [4, 0, 10]], atol=1e-9)
    np.testing.assert_allclose(p.feed, [np.nan, 600, 600, 600, np.nan])
    assert p.rows.tolist() == [-1, 0, 0, 0, -1] and p.rapid.tolist() == [True, False, False, False, True]
    w = p.written
    assert (w.method, w.tolerance, w.every_point, w.dialect) == ("nlp", 0.01, True, "generic")
    np.testing.assert_allclose(w.t, [np.nan, 0, 0.2, 0.4, np.nan])
    np.testing.assert_allclose(w.feed, [np.nan, 600, 600, 600, np.nan])
    np.testing.assert_allclose(w.t_plan, [np.nan, 0, 0.2, 0.4, np.nan])
    assert w.row_id.tolist() == [-1, 5, 5, 5, -1]
    tool = p.toolpaths[0].tool
    assert (tool.diameter, tool.corner_radius, tool.length, tool.kind) == (6.0, 3.0, 40.0, "mill")
    assert p.warnings == ["dialect generic, mode machine"]


def test_own_program_variants(tmp_path):
    """A method that wrote 4 points of which 3 are here: not every point; a mangled tolerance: None;
    a row comment count that does not match the rows: no row ids; no post tag: read as generic with
    a warning, mode from the TCP word (G43.4: tcp, X Y Z the tip); feed per minute in machine mode:
    F as written, with a warning."""
    w = _own(tmp_path, OWN.replace("3 points)", "4 points)", 1).replace("tolerance=0.01", "tolerance=x")).written
    assert w.every_point is False and w.tolerance is None
    assert _own(tmp_path, OWN.replace("(row 5: 3 points)\n", "")).written.row_id is None
    untagged = "G21 G90\nG43.4 H1\nG00 X0 Y0 Z10 A0 B0\nG01 X1 Y0 Z0 A0 B0 F500\nG49\nM30\n"
    p = _own(tmp_path, untagged)
    assert p.warnings[0] == "no camsmooth post header: read as generic G-code"
    assert p.warnings[-1] == "dialect generic, mode tcp" and p.written is None
    np.testing.assert_allclose(p.tip, [[0, 0, 10], [1, 0, 0]])
    np.testing.assert_allclose(p.feed, [np.nan, 500])
    p = _own(tmp_path, OWN.replace("G93\n", "G94\n"))
    assert "machine-mode program in feed per minute (G94): F applies to the joint motion, the tool tip feed is not " \
        "known; feed = F as written" in p.warnings
    np.testing.assert_allclose(p.feed, [np.nan, 60, 300, 300, np.nan])


@pytest.mark.parametrize("change, message", [
    (("pivot=150.000000", "pivot=abc"), "gives pivot=abc: not a length of 0 to"),
    (("pivot=150.000000", "pivot=-1"), "gives pivot=-1: not a length of 0 to"),
    (("sense=iso", "sense=left"), "gives sense=left: not iso or linuxcnc"),
    (("kind=AB-head", "kind=AB-head centre=1,2"), "gives centre=1,2: not three lengths x,y,z (mm)"),
    (("kind=AB-head", "kind=AB-head centre=1,2,x"), "gives centre=1,2,x: not three lengths"),
    (("G01 X2 Y0", "G01 X2000000000 Y0"), "X2e+09 is beyond +-1e+09 (not a position of a machine)"),
    (("G00 X0 Y0 Z160 A0 B0", "G00 X0 Y0 Z160 A0"), "first motion block does not give B"),
    (("G21 G90 G17", "G20 G90 G17"), "inch programs (G20) are not read: camsmooth writes mm"),
    (("G00 X0 Y0 Z160 A0 B0\nG01 X0", "(G00 X0 Y0 Z160 A0 B0)\nG01 X0"), ""),
])
def test_own_program_refusals(tmp_path, change, message):
    text = OWN.replace(*change)
    if not message:  # the first block commented out: the next one misses nothing, the program reads
        assert len(_own(tmp_path, text).tip) == 4
        return
    with pytest.raises(InputError, match=re.escape(message)):
        _own(tmp_path, text)


# ---- MillPlus reader (camsmooth.post.millplus) ------------------------------------------------------------
def _millplus(tmp_path: Path, body: str):
    path = tmp_path / "t.pm"
    path.write_text("%PM\nN9000 (T)\nG17\n(Operation: GOOD)\nG0 X0 Y0 Z5\nG1 X1 Y0 Z5 F100\n(Operation: BAD)\n" + body
                    + "\nM30\n")
    p = read_posted(path, dialect="millplus")
    notes = [w for w in p.warnings if "nominal" not in w and "no machine file" not in w]
    return p, " | ".join(notes)


@pytest.mark.parametrize("body, tips, axis", [
    # G7 A5=90: R = Rz(0) Ry(0) Rx(90): (1, 0, 5) -> (1, -5, 0), the axis Rx(90) e_z = (0, -1, 0); G7 alone resets
    ("G7 A5=90 B5=0 C5=0 L1=0\nG1 X1 Y0 Z5\nG7 L1=0\nG1 X1 Y0 Z5", [[1, -5, 0], [1, 0, 5]], [0, -1, 0]),
    ("G7 A5=0 B5=0 C5=90 L1=1\nG1 X1 Y0 Z5", [[0, 1, 5]], [0, 0, 1]),
    # G93 the absolute datum shift, G92 the incremental one
    ("G93 X10 Y0 Z0\nG1 X1 Y0 Z5\nG92 X0 Y5 Z0\nG1 X1 Y0 Z5\nG93 X0 Y0 Z0\nG1 X1", [[11, 0, 5], [11, 5, 5], [1, 0, 5]],
     [0, 0, 1]),
    # no motion: G141 with its correction data, G4 dwell, G74 machine move, F2= words
    ("G141 R3 R1=2 L2=1\nG4 X2\nG74 Z0 L1\nG1 X2 F2=50", [[2, 0, 5]], [0, 0, 1]),
])
def test_millplus_frames_and_words(tmp_path, body, tips, axis):
    p, notes = _millplus(tmp_path, body)
    assert "dropped" not in notes, notes
    np.testing.assert_allclose(p.tip[2:], tips, atol=1e-9)
    np.testing.assert_allclose(p.axis[2], axis, atol=1e-9)
    if "F2=" in body:
        assert "F2= (not applied)" in notes and "G141 R R1= L2= (3D tool correction data)" in notes
        assert not np.asarray(p.modes["tcp"]).any()


def test_millplus_drilling_and_arcs(tmp_path):
    """G81 Z-5 defines a hole 5 mm below its surface; G79 X2 Y0 Z1 drills at (2, 0) from Z1: bottom
    Z = -4; G3 with I J the absolute centre (2, 0): from (1, 0) counter-clockwise to (3, 0), the half
    circle below the X axis... about (2, 0) radius 1."""
    p, notes = _millplus(tmp_path, "G81 Z-5 Y2 B1\nG79 X2 Y0 Z1")
    np.testing.assert_allclose([h for c in p.cycles for h in c.holes], [[2, 0, -4]])
    p, _ = _millplus(tmp_path, "G3 X3 Y0 Z5 I2 J0")
    arc = p.tip[2:]
    np.testing.assert_allclose(arc[-1], [3, 0, 5], atol=1e-12)
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 2, arc[:, 1]), 1.0, atol=1e-9)
    assert np.all(arc[:-1, 1] < 0)


@pytest.mark.parametrize("body, reason", [
    ("G81 Y2 B1", "G81 without its depth Z"),
    ("G79 X2 Y0 Z1", "G79 (cycle call) without a cycle definition"),
])
def test_millplus_refusals(tmp_path, body, reason):
    p, notes = _millplus(tmp_path, body)
    assert "operation 'BAD' (line 7) dropped" in notes and reason in notes, notes


def test_iso_tool_change_names_the_operation_after_its_comment(tmp_path):
    """'(FINISH WALLS)' before 'T3 M6' names the operation the tool change starts; the tool is T3,
    number 3, called at line 5."""
    path = tmp_path / "t.nc"
    path.write_text("G90 G21 G17\nG00 X0 Y0 Z5\nG01 X1 Y0 Z5 F100\n(FINISH WALLS)\nT3 M6\nG01 X2 Y0 Z5\nM30\n")
    p = read_posted(path, dialect="iso")
    tp = p.toolpaths[-1]
    assert (tp.name, tp.tool.name, tp.tool.number, tp.tool.line) == ("FINISH WALLS", "T3", 3, 5)


@pytest.mark.parametrize("body, tip", [
    # G68.2 with I and K left out: R = Rz(0) Rx(J) Rz(0), J = 90: (1, 0, 5) -> (1, -5, 0)
    ("G68.2 X0 Y0 Z0 J90\nG01 X1 Y0 Z5", [1, -5, 0]),
    # ... with its origin (10, 0, 0): 10 + Rx(90) (1, 0, 5)
    ("G68.2 X10 Y0 Z0 I0 J90 K0\nG01 X1 Y0 Z5", [11, -5, 0]),
    # a function in an assignment: 4 SIN[30] = 2
    ("#100=4*SIN[30]\nG01 X#100 Y0 Z5", [2, 0, 5]),
    ("#100=4*sin[30] #101=3\nG01 X#100 Y#101 Z5", [2, 3, 5]),
])
def test_iso_tilted_plane_and_functions(tmp_path, body, tip):
    p, notes = _iso(tmp_path, body)
    assert "dropped" not in notes, notes
    np.testing.assert_allclose(p.tip[-1], tip, atol=1e-9)


def test_iso_full_circles_and_their_turns(tmp_path):
    """G03 from (1, 0) back to (1, 0) about the origin (I-1 J0): a full circle; with P2 two turns
    (RS274/NGC and LinuxCNC: P = the number of turns), 4 pi of angle, every point on the unit circle.
    read_iso reads as the 'iso' dialect by default, where P counts."""
    from camsmooth.post.iso import read_iso

    text = "G90 G21 G17\nG00 X1 Y0 Z5\nG01 X1 Y0 Z4 F100\nG03 X1 Y0 Z4 I-1 J0 P2\nM30\n"
    path = tmp_path / "c.nc"
    path.write_text(text)
    for p in (read_posted(path, dialect="iso"), read_iso(str(path), text)):
        arc = p.tip[2:]
        np.testing.assert_allclose(np.hypot(arc[:, 0], arc[:, 1]), 1.0, atol=1e-9)
        turn = np.diff(np.unwrap(np.r_[0.0, np.arctan2(arc[:, 1], arc[:, 0])]))
        assert np.all(turn > 0) and turn.sum() == pytest.approx(4 * math.pi)


def test_iso_incremental_rotary_words_start_from_zero(tmp_path):
    """G91 C5 before any C word: C = 0 + 5; then B2 C5 adds to both: B 2, C 10 (deg)."""
    path = tmp_path / "r.nc"
    path.write_text("G90 G21 G17\nG00 X0 Y0 Z5 B0\nG91 G01 C5 F100\nG01 B2 C5\nM30\n")
    p = read_posted(path, dialect="iso")
    assert p.rotary == ("B", "C")
    np.testing.assert_allclose(np.degrees(p.angles), [[0, 0], [0, 5], [2, 10]], atol=1e-12)


def test_iso_a_first_position_without_a_motion_mode_and_a_feed_beyond_any_machine(tmp_path):
    """A program's first position before any G0 / G1: no motion mode yet, refused by name (its only
    operation dropped: nothing to read); F 2e9 mm/min is no feed: InputError naming file and line."""
    path = tmp_path / "f.nc"
    path.write_text("G90 G21\nX0 Y0 Z5\nG00 X0 Y0 Z5\nG01 X1 Y0 Z5 F100\nM30\n")
    with pytest.raises(InputError, match="a position without a motion mode"):
        read_posted(path, dialect="iso")
    path.write_text("G90 G21\nG00 X0 Y0 Z5\nG01 X1 Y0 Z5 F2000000000.\nM30\n")
    with pytest.raises(InputError, match=re.escape(f"{path}, line 3: F2e+09 is not a feed")):
        read_posted(path, dialect="iso")


def test_klartext_plane_q_parameters_rotation_and_named_cycles(tmp_path):
    """After PLANE the rotary positions Q120-Q122 the control computes read as 0 (named: the plane
    gives the tool axis), so 'B+Q121 C+Q122' reads; CYCL DEF 10 ROT+90 turns (1, 0, 5) to (0, 1, 5);
    CYCL DEF 13 and FUNCTION PARAX move nothing; each is named."""
    p, notes = _klartext(tmp_path, "PLANE SPATIAL SPA+0 SPB+0 SPC+0 TURN\nL X+1 Y+0 Z+5 B+Q121 C+Q122\n"
                                   "CYCL DEF 13.0 ORIENTATION\nCYCL DEF 10.0 ROTATION\nCYCL DEF 10.1 ROT+90\n"
                                   "L X+1 Y+0 Z+5\nFUNCTION PARAXCOMP DISPLAY")
    assert "dropped" not in notes, notes
    np.testing.assert_allclose(p.tip[2:], [[1, 0, 5], [0, 1, 5]], atol=1e-9)
    np.testing.assert_allclose(np.degrees(p.angles[2]), [0, 0], atol=1e-12)
    q, _ = _klartext(tmp_path, "PLANE RESET STAY\nPLANE SPATIAL SPA+0 SPB+0 SPC+0 TURN\nL X+Q120 Y+Q121 Z+5")
    np.testing.assert_allclose(q.tip[2:], [[0, 0, 5]], atol=1e-12)  # Q120 and Q121 are 0 after PLANE
    for note in ("Q120-Q122 (rotary positions the control computes for PLANE) read as 0: the plane gives the tool "
                 "axis (line 7)", "CYCL DEF 13 (oriented spindle stop) (line 9)", "CYCL DEF 10 (rotation) (line 11)",
                 "FUNCTION PARAXCOMP (line 13)"):
        assert note in notes, (note, notes)


def test_klartext_plane_vector_base_words_left_out_are_zero(tmp_path):
    """PLANE VECTOR BX+1 (BY, BZ left out: 0) with N = +Z: the identity, (1, 2, 3) stays."""
    p, _ = _klartext(tmp_path, "PLANE VECTOR BX+1 NX+0 NY+0 NZ+1 STAY\nL X+1 Y+2 Z+3")
    np.testing.assert_allclose(p.tip[2], [1, 2, 3], atol=1e-12)


def test_iso_g43_5_vector_and_g49_are_named(tmp_path):
    """G43.5 (TCP with the tool vector I J K) and G49 move nothing and are named; the block's I J K is
    the tool axis."""
    p, notes = _iso(tmp_path, "G43.5 H1\nG01 X2 Y0 Z5 I0 J0.6 K0.8\nG49")
    assert "G43.5 (TCP, tool vector I J K) (line 6)" in notes and "G49 (line 8)" in notes
    np.testing.assert_allclose(p.axis[2], [0, 0.6, 0.8], atol=1e-12)


def test_millplus_names_its_words_and_takes_the_chord_tolerance(tmp_path):
    """G7 with C5 only (A5, B5 left out: 0) is Rz(90); G7, G141, G4 and G74 are named; the program's
    source is its path; a half circle of radius 1 (G3 about the absolute centre (2, 0)) in chords of
    sagitta 0.1 mm: angle step 2 acos(1 - 0.1) = 0.902 rad, ceil(pi / 0.902) = 4 points."""
    p, notes = _millplus(tmp_path, "G7 C5=90 L1=1\nG1 X1 Y0 Z5\nG7 L1=0\nG141\nG4 X2\nG74 Z0 L1\nG1 X2 Y0 Z5\nG40")
    assert "dropped" not in notes, notes
    np.testing.assert_allclose(p.tip[2:], [[0, 1, 5], [2, 0, 5]], atol=1e-9)
    for note in ("G7 (tilted working plane) (lines 8, 10)", "G141 (tool centre point) (line 11)",
                 "G4 (dwell) (line 12)", "G74 (machine-coordinate move) (line 13)"):
        assert note in notes, (note, notes)
    assert p.source == str(tmp_path / "t.pm")
    path = tmp_path / "a.pm"
    path.write_text("%PM\nN9000\nG0 X1 Y0 Z5\nG1 X1 Y0 Z4 F100\nG3 X3 Y0 Z4 I2 J0\nM30\n")
    steps = 2 * math.acos(1 - 0.1)
    assert len(read_posted(path, dialect="millplus", chord_tol=0.1).tip) == 2 + math.ceil(math.pi / steps)


def test_millplus_hole_positions(tmp_path):
    """G79 without Y drills at the current Y (0); G79 before any position is refused by name."""
    p, _ = _millplus(tmp_path, "G81 Z-5\nG79 X2 Z1")
    np.testing.assert_allclose([h for c in p.cycles for h in c.holes], [[2, 0, -4]])
    path = tmp_path / "u.pm"
    path.write_text("%PM\nN9000\nG81 Z-5\nG79 X2\nG0 X0 Y0 Z5\nG1 X1 Y0 Z5 F100\nM30\n")
    with pytest.raises(InputError, match="G79 at an unknown position"):
        read_posted(path, dialect="millplus")


def test_klartext_tool_machine_blocks_modal_rotaries_and_m129(tmp_path):
    """An M91 block (machine-referenced) is no point, but its
    rotary words hold for the next block (B 10, C 5 deg); rotary words are modal (B 10 kept by 'L X+2');
    M129 in a block turns TCPM off for that block's own point."""
    p, notes = _klartext(tmp_path, "L X+5 Y+5 Z+50 R0 FMAX M91\nL X+2 Y+0 Z+5")
    np.testing.assert_allclose(p.tip[2:], [[2, 0, 5]])
    assert "M91/M92 (machine-referenced block) (line 7)" in notes
    p, _ = _klartext(tmp_path, "L X+5 Y+5 Z+50 B+10 C+5 R0 FMAX M91\nL X+2 Y+0 Z+5")
    assert p.rotary == ("B", "C") and len(p.tip) == 3
    np.testing.assert_allclose(np.degrees(p.angles[2]), [10, 5], atol=1e-12)
    p, _ = _klartext(tmp_path, "L X+1 Y+0 Z+5 B+10 C+0\nL X+2")
    np.testing.assert_allclose(np.degrees(p.angles[2:]), [[10, 0], [10, 0]], atol=1e-12)
    p, _ = _klartext(tmp_path, "M128\nL X+2 Y+0 Z+5 B+0 C+0\nL X+3 M129")
    assert [int(v) for v in p.modes["tcp"]] == [0, 0, 1, 0]


def test_klartext_tool_number(tmp_path):
    path = tmp_path / "n.h"
    path.write_text("BEGIN PGM T MM\nTOOL CALL 5 Z S1000\nL X+0 Y+0 Z+5 R0 FMAX\nL X+1 Y+0 Z+5 F100\nEND PGM T MM\n")
    tool = read_posted(path, dialect="heidenhain").toolpaths[0].tool
    assert (tool.name, tool.number, tool.line) == ("5", 5, 2)


@pytest.mark.parametrize("levels", [8, 9])
def test_klartext_subprograms_nest_eight_deep(tmp_path, levels):
    """CALL LBL 1 calls LBL 2 ... calls LBL <levels>, whose block is the point: 8 levels are read,
    a 9th is refused ('subprograms nested deeper than 8')."""
    body = "CALL LBL 1\nM30\n" + "".join(f"LBL {k}\nCALL LBL {k + 1}\nLBL 0\n" for k in range(1, levels)) + \
        f"LBL {levels}\nL X+2 Y+0 Z+5\nLBL 0"
    p, notes = _klartext(tmp_path, body)
    if levels == 8:
        np.testing.assert_allclose(p.tip[2:], [[2, 0, 5]])
    else:
        assert "subprograms nested deeper than 8" in notes and len(p.tip) == 2


def test_klartext_half_circle_and_a_first_move_with_unknown_axes(tmp_path):
    """CR from (1, 0) to (3, 0) with R+1: the radius is exactly half the chord, a half circle about
    (2, 0), counter-clockwise (DR+) below the X axis. A first block that gives Z only is no point (X
    and Y not known yet); the next blocks are."""
    p, _ = _klartext(tmp_path, "CR X+3 Y+0 R+1 DR+")
    arc = p.tip[2:]
    np.testing.assert_allclose(arc[-1], [3, 0, 5], atol=1e-9)
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 2, arc[:, 1]), 1.0, atol=1e-6)
    assert np.all(arc[:-1, 1] < 0)
    path = tmp_path / "z.h"
    path.write_text("BEGIN PGM T MM\nL Z+50 R0 FMAX\nL X+0 Y+0 R0 FMAX\nL Z+5 F100\nL X+1\nEND PGM T MM\n")
    p = read_posted(path, dialect="heidenhain")
    np.testing.assert_allclose(p.tip, [[0, 0, 50], [0, 0, 5], [1, 0, 5]])
    assert any("move before X, Y and Z are all known (not a point) (line 2)" in w for w in p.warnings)


def test_iso_m428_m429_and_a_partial_tool_vector(tmp_path):
    """In the iso dialect M428 turns TCP on (LinuxCNC's trt kinematics) and M429 off; G43.5 with K1
    alone (I, J left out: 0) gives the tool axis +Z; machine moves name their G code."""
    path = tmp_path / "m.nc"
    path.write_text("G90 G21 G17\nG00 X0 Y0 Z5\nG01 X1 Y0 Z5 F100\nM428\nG01 X2 Y0 Z5 B10 C0\nM429\n"
                    "G01 X3 Y0 Z5 B0 C0\nG43.5 H1\nG01 X2 Y0 Z5 K1\nG49\nG53 Z0\nM30\n")
    p = read_posted(path, dialect="iso")
    assert [int(v) for v in p.modes["tcp"]] == [0, 0, 1, 0, 1]
    np.testing.assert_allclose(p.axis[4], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(p.tip[2], [2, 0, 5], atol=1e-12)  # TCP: X Y Z is the tip
    notes = " | ".join(p.warnings)
    assert "M428 (LinuxCNC trt kinematics: TCP on) (line 4)" in notes and "M429 (LinuxCNC identity kinematics: TCP " \
        "off) (line 6)" in notes and "machine-coordinate move (G53) (line 11)" in notes


def test_iso_subprogram_repeats_by_k(tmp_path):
    """M98 P2000 K2 (the repeat count as K) runs O2000 twice."""
    path = tmp_path / "k.nc"
    path.write_text("%\nO1000\nG90 G21\nG00 X0 Y0 Z5\nG01 X0 Y0 Z4 F100\nM98 P2000 K2\nM30\nO2000\nG91 G01 X1\nG90\n"
                    "M99\n%\n")
    p = read_posted(path, dialect="iso")
    np.testing.assert_allclose(p.tip[2:, 0], [1, 2])


@pytest.mark.parametrize("body, tips", [
    # ROT Y90: Ry(90) (1, 0, 5) = (5, 0, -1)
    ("ROT Y90\nG1 X1 Y0 Z5", [[5, 0, -1]]),
    # CYCLE800 with empty arguments resets the swivel: the point is as written
    ('CYCLE800(1,"TC1",0,57,0,0,0,90,0,0,0,0,0,1)\nCYCLE800(,,)\nG1 X1 Y0 Z5', [[1, 0, 5]]),
])
def test_sinumerik_rot_about_y_and_a_swivel_reset(tmp_path, body, tips):
    p, notes = _sinumerik(tmp_path, body)
    np.testing.assert_allclose(p.tip[2:], tips, atol=1e-9)
    if "CYCLE800(1" in body:
        assert "CYCLE800 (swivel plane) (line 6)" in notes


def test_sinumerik_zx_arc_with_absolute_centre_incremental_rotary_and_cycle_name(tmp_path):
    """G18 (ZX plane): G2 from (1, 0, 5) to (1, 0, 7) about I=AC(1) K=AC(6), every point 1 mm from
    (X 1, Z 6); B=IC(5) after B10 is B 15; a CYCLE81 hole is listed under its name."""
    p, _ = _sinumerik(tmp_path, "G18\nG2 X1 Y0 Z7 I=AC(1) K=AC(6)")
    arc = p.tip[2:]
    np.testing.assert_allclose(arc[-1], [1, 0, 7], atol=1e-9)
    np.testing.assert_allclose(np.hypot(arc[:, 0] - 1, arc[:, 2] - 6), 1.0, atol=1e-9)
    assert len(arc) > 10 and np.abs(arc[:, 0] - 1).max() == pytest.approx(1.0, abs=1e-3)  # a half circle in ZX
    p, _ = _sinumerik(tmp_path, "G1 X1 Y0 Z5 B10 C0\nG1 B=IC(5)")
    np.testing.assert_allclose(np.degrees(p.angles[2:]), [[10, 0], [15, 0]], atol=1e-12)
    p, _ = _sinumerik(tmp_path, "CYCLE81(10,0,2,-5)")
    assert [c.code for c in p.cycles] == ["CYCLE81"]


def test_sinumerik_settings_and_dwell_are_named(tmp_path):
    """FFWON, SOFT, COMPCAD, G642 and G4 (a dwell: its F is a time, not a feed) move nothing and are
    named with their lines; the next block keeps the feed 100 mm/min."""
    p, notes = _sinumerik(tmp_path, "FFWON SOFT COMPCAD\nG642\nG4 F2\nG1 X2")
    for note in ("FFWON (line 6)", "SOFT (line 6)", "COMPCAD (line 6)", "G642 (line 7)", "G4 (dwell) (line 8)"):
        assert note in notes, (note, notes)
    assert p.feed[-1] == pytest.approx(100.0)


def test_own_program_mode_from_the_header_or_the_tcp_words(tmp_path):
    """The header's mode=tcp holds without a TCP word: X Y Z are the tip (the first point (0, 0, 160));
    an untagged program without a TCP word is machine mode (tip = pivot position - 150 e_z on the
    default AB head: (0, 0, 10)); errors name their line."""
    p = _own(tmp_path, OWN.replace("mode=machine", "mode=tcp").replace("G93\n", "G94\n"))
    np.testing.assert_allclose(p.tip[0], [0, 0, 160])
    assert p.warnings[-1] == "dialect generic, mode tcp"
    p = _own(tmp_path, "G21 G90\nG00 X0 Y0 Z160 A0 B0\nG01 X0 Y0 Z150 A0 B0 F500\nM30\n")
    assert p.warnings[-1] == "dialect generic, mode machine"
    np.testing.assert_allclose(p.tip, [[0, 0, 10], [0, 0, 0]], atol=1e-9)
    for change, line in ((("G01 X2 Y0", "G01 X2000000000 Y0"), 9), (("G00 X0 Y0 Z160 A0 B0", "G00 X0 Y0 Z160 A0"), 7)):
        with pytest.raises(InputError) as err:
            _own(tmp_path, OWN.replace(*change))
        assert err.value.line == line
