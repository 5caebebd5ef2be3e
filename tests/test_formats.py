"""File formats in camsmooth.io: the one CSV table reader, APT/NX CLSF, CL CSV, format detection.

Expected values are computed here from the file text written by the test (unit conversion, the
MSYS transform, the arc geometry), not taken from the readers' output."""

from __future__ import annotations

import math

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.geometry.paths import CCPath
from camsmooth.io.apt import read_apt
from camsmooth.io.ccpath import read_cc_csv, write_cc_csv
from camsmooth.io.clcsv import read_cl_csv, write_cl_csv
from camsmooth.io.program import CLProgram, detect_format
from camsmooth.io.table import read_table
from camsmooth.post import load_program

IN = 25.4


# ----------------------------------------------------------------------------------------------
# the table reader
def _write(tmp_path, name, text, encoding="utf-8"):
    p = tmp_path / name
    p.write_bytes(text.encode(encoding))
    return p


def test_table_bom_case_quotes_blank_lines_and_rows(tmp_path):
    p = _write(tmp_path, "t.csv", '\ufeff X ,"y",Note,n\n1,2,a,3\n\n"4",5.5,b,-2\r\n7,8,c,1\n', "utf-8")
    t = read_table(p, ["x", "Y"], ["n", "missing"], integer=["n"])
    np.testing.assert_array_equal(t["x"], [1, 4, 7])
    np.testing.assert_array_equal(t["Y"], [2, 5.5, 8])
    assert t["n"].dtype == np.int64 and t["n"].tolist() == [3, -2, 1]
    assert t.rows.tolist() == [1, 3, 4]  # the blank line keeps its number: row = line - 1
    assert t.ignored == ("Note",) and "missing" not in t
    # 'x' and 'X' both present: exact spelling wins (the result CSV has both)
    q = _write(tmp_path, "q.csv", "x,X\n1,2\n")
    t = read_table(q, ["x", "X"])
    assert (t["x"][0], t["X"][0]) == (1.0, 2.0)


@pytest.mark.parametrize("text, needle, row, column", [
    ("x;y\n1;2\n", "uses ';' as delimiter", 0, None),
    ("x\ty\n1\t2\n", "uses a tab as delimiter", 0, None),
    ("xx,y\n1,2\n", "missing column 'x' (found 'xx': misspelt?)", 0, "x"),
    ("x,y\n1,2\n3,nan\n", "non-finite value nan", 2, "y"),
    ("x,y\n1,2\n3,inf\n", "non-finite value inf", 2, "y"),
    ("x,y\n1,2\n\n3,abc\n", "unparsable value 'abc'", 3, "y"),
    ("x,y\n1,2\n3,\n", "empty value", 2, "y"),
    ("x,y\n1,2\n3,4,5\n", "3 fields but the header has 2", 2, None),
    ("x,y\n1,2\n3\n", "missing value", 2, "y"),
    ("x,y,x\n1,2,3\n", "appears twice", 0, "x"),
    ("x,y\n", "no data rows", None, None),
    ("", "empty file", None, None),
])
def test_table_errors_name_file_row_column(tmp_path, text, needle, row, column):
    p = _write(tmp_path, "bad.csv", text)
    with pytest.raises(InputError) as exc:
        read_table(p, ["x", "y"])
    msg = str(exc.value)
    assert needle in msg and str(p) in msg, msg
    assert exc.value.row == row and exc.value.column == column
    assert "np.float64" not in msg


def test_table_utf16_and_missing_file(tmp_path):
    p = _write(tmp_path, "u.csv", "\ufeffx,y\n1,2\n", "utf-16")
    with pytest.raises(InputError, match="UTF-16"):
        read_table(p, ["x"])
    with pytest.raises(InputError, match="not found"):
        read_table(tmp_path / "nope.csv", ["x"])
    with pytest.raises(InputError, match=r"not an integer: 1\.5"):
        read_table(_write(tmp_path, "i.csv", "x\n1\n1.5\n"), ["x"], integer=["x"])


def test_table_nonfinite_allowed_where_declared(tmp_path):
    p = _write(tmp_path, "n.csv", "x,d\n1,nan\n2,-inf\n")
    t = read_table(p, ["x", "d"], nonfinite=["d"])
    assert np.isnan(t["d"][0]) and t["d"][1] == -np.inf


# ----------------------------------------------------------------------------------------------
# APT / NX CLSF
NX_FILE = """\
$$ NX CLSF written by the camsmooth tests (inch part: no UNITS record, IPM feeds)
TOOL PATH/ROUGH_A,TOOL,MILL_D12R2
TLDATA/MILL,0.5000,0.0625,3.0000,0.0000,0.0000
LOAD/TOOL,3,ADJUST,3
MSYS/1.0000,2.0000,0.5000,0.0000000,1.0000000,0.0000000,-1.0000000,0.0000000,0.0000000
$$ centerline data
PAINT/PATH
SPINDL/RPM,8000,CLW
RAPID
GOTO/0.0000,0.0000,1.0000
RAPID
GOTO/0.0000,0.0000,0.1000,0.0000000,0.0000000,1.0000000
FEDRAT/IPM,20.0000
GOTO/0.0000,0.0000,0.0000
GOTO/1.0000,0.0000,0.0000,0.0000000,0.2588190,0.9659258
GOTO/2.0000,0.0000,0.0000
GOTO/2.0000,$
 1.0000,0.0000
CUTCOM/LEFT
CIRCLE/2.0000,2.0000,0.0000,0.0000000,0.0000000,1.0000000,1.0000,0.0020,0.5000,0.5000,0.0625
GOTO/3.0000,2.0000,0.0000
RAPID
GOTO/3.0000,2.0000,1.0000
END-OF-PATH
TOOL PATH/FINISH_B,TOOL,BALL_D6
TLDATA/MILL,0.2500,0.1250,2.0000,0.0000,0.0000
MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000
FEDRAT/IPM,10.0000
GOTO/0.5000,0.5000,0.0000,0.0000000,-0.6000000,0.8000000
GOTO/0.6000,0.5000,0.0000
GOTO/0.7000,0.5000,0.0000 $$ last point
CUTCOM/OFF
END-OF-PATH
"""


def _line_of(text, needle, nth=0):
    hits = [k for k, ln in enumerate(text.splitlines(), start=1) if needle in ln]
    return hits[nth]


def test_nx_clsf_reads_to_the_right_points_in_mm(tmp_path):
    p = _write(tmp_path, "part.cls", NX_FILE)
    tol = 1e-3
    prog = read_apt(p, chord_tol=tol)
    assert isinstance(prog, CLProgram) and prog.format == "apt" and prog.source == str(p)

    # MSYS of tool path 1: origin (1, 2, 0.5) in, X = (0, 1, 0), Y = (-1, 0, 0), Z = X x Y = (0, 0, 1):
    # a point (x, y, z) of the MCS is (1 - y, 2 + x, 0.5 + z) in the workpiece frame
    def w1(x, y, z):
        return np.array([1 - y, 2 + x, 0.5 + z]) * IN

    tilt = np.array([-0.2588190, 0.0, 0.9659258])  # MCS axis (0, .2588, .9659) turned by the MSYS
    tilt /= np.linalg.norm(tilt)
    tp1, tp2 = prog.toolpaths
    assert (tp1.name, tp2.name) == ("ROUGH_A", "FINISH_B")
    assert tp1.line == _line_of(NX_FILE, "TOOL PATH/ROUGH_A") and tp2.line == _line_of(NX_FILE, "TOOL PATH/FINISH")
    t1, t2 = prog.require_tool(tp1), prog.require_tool(tp2)
    assert (t1.name, t1.number, t1.kind) == ("MILL_D12R2", 3, "mill")
    assert math.isclose(t1.diameter, 12.7) and math.isclose(t1.corner_radius, 1.5875)
    assert math.isclose(t1.ring_radius, 6.35 - 1.5875)
    assert math.isclose(t2.diameter, 6.35) and math.isclose(t2.corner_radius, 3.175)  # ball end

    pts = prog.tip[tp1.points]
    ax = prog.axis[tp1.points]
    # rapids, plunge, two straight cuts (the second with the modal axis), the continued GOTO
    np.testing.assert_allclose(pts[0], w1(0, 0, 1), atol=1e-12)
    np.testing.assert_allclose(pts[1], w1(0, 0, 0.1), atol=1e-12)
    np.testing.assert_allclose(pts[2:6], [w1(0, 0, 0), w1(1, 0, 0), w1(2, 0, 0), w1(2, 1, 0)], atol=1e-12)
    np.testing.assert_allclose(ax[:3], [[0, 0, 1]] * 3, atol=1e-12)
    np.testing.assert_allclose(ax[3:], np.tile(tilt, (len(ax) - 3, 1)), atol=1e-7)  # modal to the end of the path
    assert prog.rapid[tp1.points][:2].all() and not prog.rapid[tp1.points][2:-1].any() and prog.rapid[tp1.stop - 1]
    np.testing.assert_allclose(pts[-2], w1(3, 2, 0), atol=1e-12)
    np.testing.assert_allclose(pts[-1], w1(3, 2, 1), atol=1e-12)
    feed1 = prog.feed[tp1.points]
    assert np.isnan(feed1[:2]).all() and np.isnan(feed1[-1]) and np.allclose(feed1[2:-1], 20 * IN)

    # CIRCLE: centre (2, 2, 0) in, axis +z, r 1 in, from (2, 1) to (3, 2): NX gives the axis for a clockwise
    # turn, so the tool goes clockwise seen from +z: -90 deg -> -180 -> -270 -> -360 deg (a 270 deg arc)
    arc = pts[5:-1]  # start (2, 1), interpolated points, end (3, 2)
    centre = w1(2, 2, 0)
    rel = arc - centre
    np.testing.assert_allclose(np.linalg.norm(rel, axis=1), IN, rtol=1e-12)
    np.testing.assert_allclose(rel[:, 2], 0.0, atol=1e-12)
    # in the workpiece frame the MCS is turned +90 deg about z: MCS angle a is workpiece angle a + 90
    ang = np.degrees(np.unwrap(np.arctan2(rel[:, 1], rel[:, 0])))
    assert math.isclose(ang[0], 0.0, abs_tol=1e-9) and math.isclose(ang[-1], -270.0, abs_tol=1e-9)
    assert np.all(np.diff(ang) < 0)  # clockwise throughout
    half = np.radians(np.abs(np.diff(ang))) / 2
    assert np.all(IN * (1 - np.cos(half)) <= tol * (1 + 1e-9))  # chordal deviation within the tolerance
    assert len(arc) - 2 >= math.ceil(math.radians(270) / (2 * math.acos(1 - tol / IN))) - 1
    assert np.all(prog.line[5 + 1:tp1.stop - 1] == _line_of(NX_FILE, "GOTO/3.0000,2.0000,0.0000"))

    # rows: one cutting row per tool path here (rapids and the tool path boundary split rows)
    assert prog.rows[tp1.points][:2].tolist() == [-1, -1] and prog.rows[tp1.stop - 1] == -1
    assert set(prog.rows[tp1.start + 2:tp1.stop - 1]) == {0}
    assert set(prog.rows[tp2.points]) == {1}
    # tool path 2: identity MSYS, axis (0, -0.6, 0.8), 10 in/min, comment after the last GOTO
    np.testing.assert_allclose(prog.tip[tp2.points], np.array([[0.5, 0.5, 0], [0.6, 0.5, 0], [0.7, 0.5, 0]]) * IN,
                               atol=1e-12)
    np.testing.assert_allclose(prog.axis[tp2.points], [[0, -0.6, 0.8]] * 3, atol=1e-12)
    assert np.allclose(prog.feed[tp2.points], 10 * IN)

    # the unknown record is listed once, with both its lines; skipped display records are not
    cut = [w for w in prog.warnings if "CUTCOM" in w]
    assert len(cut) == 1
    assert f"CUTCOM (lines {_line_of(NX_FILE, 'CUTCOM/LEFT')}, {_line_of(NX_FILE, 'CUTCOM/OFF')})" in cut[0]
    assert not [w for w in prog.warnings if "PAINT" in w or "SPINDL" in w]

    # the cutting view keeps rows and tool paths
    c = prog.cutting()
    assert (c.rows >= 0).all() and [s.stop - s.start for s in c.row_slices()] == [len(arc) + 3, 3]
    assert (c.toolpaths[0].start, c.toolpaths[1].start) == (0, len(arc) + 3)


def test_apt_units_record_and_mm_feed(tmp_path):
    text = "UNITS/INCHES\nFEDRAT/MMPM,500\nGOTO/1,2,3\nGOTO/2,2,3\nFEDRAT/PERMIN,4\nGOTO/3,2,3\n"
    prog = read_apt(_write(tmp_path, "u.apt", text))
    np.testing.assert_allclose(prog.tip, np.array([[1, 2, 3], [2, 2, 3], [3, 2, 3]]) * IN)
    np.testing.assert_allclose(prog.feed, [500, 500, 4 * IN])  # MMPM stays mm/min; PERMIN follows UNITS
    assert prog.toolpaths[0].tool is None
    with pytest.raises(InputError, match="declares no tool"):
        prog.require_tool(prog.toolpaths[0])
    mm = read_apt(_write(tmp_path, "m.apt", "GOTO/1,2,3\nGOTO/2,2,3\n"))
    assert any("no UNITS" in w for w in mm.warnings) and np.allclose(mm.tip[0], [1, 2, 3])
    assert any("before any FEDRAT" in w for w in mm.warnings) and np.isnan(mm.feed).all()


def test_apt_full_circle_and_counter_clockwise_axis(tmp_path):
    # axis -z: clockwise about -z = counter-clockwise seen from +z; start = end: a full circle
    text = "FEDRAT/MMPM,100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10,0.01,0.5,6,1\nGOTO/10,0,0\n"
    prog = read_apt(_write(tmp_path, "c.apt", text), chord_tol=0.01)
    ang = np.degrees(np.unwrap(np.arctan2(prog.tip[:, 1], prog.tip[:, 0])))
    assert math.isclose(ang[-1], 360.0, abs_tol=1e-9) and np.all(np.diff(ang) > 0)


# The ISO 4343 APT of Autodesk Fusion / HSM posts (apt.cps): CUTTER/, LOADTL/, MULTAX/, MOVARC/
# with the feed before its unit, ", " separators and no TOOL PATH records.
FUSION = """MACHIN/Generic 5-axis
MODE/MILL
PARTNO/'blade'
PPRINT/'roughing'
UNITS/MM
MULTAX/ON
CUTTER/10.000000, 2.000000, 6.000000, 2.000000, 0.000000, 0.000000, 25.000000
LOADTL/3, 0, 50.000000, 0
SPINDL/12000.000000, RPM, CLW
RAPID
GOTO/30.000000, 0.000000, 5.000000, 0.000000000, 0.000000000, 1.000000000
FEDRAT/1500.000000, MMPM
GOTO/30.000000, 0.000000, 0.000000
MOVARC/0.000000, 0.000000, 0.000000, 0.000000, 0.000000, 1.000000, 30.000000, ANGLE, 90.000000
GOTO/0.000000, 30.000000, 0.000000
MOVARC/0.000000, 0.000000, 0.000000, 0.000000, 0.000000, -1.000000, 30.000000, ANGLE, 90.000000
GOTO/30.000000, 0.000000, 0.000000
CUTCOM/ON
CUTTER/6.000000, 3.000000, 0.000000, 3.000000, 0.000000, 0.000000, 20.000000
LOADTL/7, 0, 40.000000, 0
GOTO/30.000000, 0.000000, -1.000000, 0.000000000, 0.707106781, 0.707106781
MOVARC/0.000000, 0.000000, -1.000000, 0.000000, 0.000000, 1.000000, 30.000000, ANGLE, 360.000000
GOTO/30.000000, 0.000000, -1.000000
END
FINI
"""


def test_fusion_iso4343_apt(tmp_path):
    p = _write(tmp_path, "op.apt", FUSION)
    assert detect_format(p) == "apt"
    prog = read_apt(p, chord_tol=0.001)
    assert prog.warnings == ["records ignored (not applied): CUTCOM (line 18)"], prog.warnings
    # two tools, a tool change after motion splits the tool path
    assert len(prog.toolpaths) == 2
    t1, t2 = (tp.tool for tp in prog.toolpaths)
    assert (t1.diameter, t1.corner_radius, t1.number, t1.ring_radius) == (10.0, 2.0, 3, 3.0)
    assert (t2.diameter, t2.corner_radius, t2.number) == (6.0, 3.0, 7)
    first = slice(prog.toolpaths[0].start, prog.toolpaths[0].stop)
    tip, axis = prog.tip[first], prog.axis[first]
    assert prog.rapid[first].tolist()[:2] == [True, False] and np.all(prog.feed[first][1:] == 1500.0)
    np.testing.assert_allclose(axis, np.tile([0, 0, 1.0], (len(axis), 1)))  # 3-number GOTOs keep the axis
    arc = tip[2:]
    r = np.hypot(arc[:, 0], arc[:, 1])
    np.testing.assert_allclose(r, 30.0, atol=1e-12)
    ang = np.degrees(np.unwrap(np.arctan2(arc[:, 1], arc[:, 0])))
    k = int(np.argmax(ang))  # counter-clockwise about +z to 90 deg, then back clockwise (normal -z)
    assert math.isclose(ang[k], 90.0, abs_tol=1e-9) and np.all(np.diff(ang[:k + 1]) > 0)
    assert np.all(np.diff(ang[k:]) < 0) and math.isclose(ang[-1], 0.0, abs_tol=1e-9)
    # chord deviation within the tolerance: sagitta of the largest step
    step = np.radians(np.abs(np.diff(ang)).max())
    assert 30.0 * (1 - math.cos(step / 2)) <= 0.001 + 1e-12
    second = slice(prog.toolpaths[1].start, prog.toolpaths[1].stop)
    ring = prog.tip[second]
    np.testing.assert_allclose(prog.axis[second], np.tile([0, math.sqrt(0.5), math.sqrt(0.5)], (len(ring), 1)))
    full = np.degrees(np.unwrap(np.arctan2(ring[:, 1], ring[:, 0])))
    assert math.isclose(full[-1], 360.0, abs_tol=1e-9) and np.all(np.diff(full) > 0)
    assert np.allclose(ring[:, 2], -1.0)


@pytest.mark.parametrize("arc, needle", [
    ("MOVARC/0,0,0,0,0,1,30,ANGLE,270", "sweep is 270 deg but the start and end points are 90 deg apart"),
    ("MOVARC/0,0,0,0,0,-1,30,ANGLE,90", "sweep is 90 deg but the start and end points are 270 deg apart"),
    ("MOVARC/0,0,0,0,0,1,30,ANGLE,720", "sweep must be in (0, 360]"),
    ("MOVARC/0,0,0,0,0,1,30,90", "malformed MOVARC"),
    ("MOVARC/0,0,0,0,0,1,25,ANGLE,90", "start point is 30 mm from the axis, the radius is 25 mm"),
])
def test_fusion_movarc_bad_input(tmp_path, arc, needle):
    p = _write(tmp_path, "bad.apt", f"UNITS/MM\nFEDRAT/100,MMPM\nGOTO/30,0,0\n{arc}\nGOTO/0,30,0\n")
    with pytest.raises(InputError) as exc:
        read_apt(p)
    assert needle in str(exc.value) and exc.value.line == 4 and str(p) in str(exc.value), str(exc.value)


@pytest.mark.parametrize("body, needle, bad_line", [
    ("GOTO/1.0,2.0\n", "malformed GOTO: expected 3 or 6 numbers", 2),
    ("GOTO/1.0,abc,3.0\n", "malformed GOTO: 'abc' is not a number", 2),
    ("GOTO/0,0,0,0,0,2\n", "tool axis (i, j, k) (0, 0, 2) is not a unit vector", 2),
    ("UNITS/FEET\nGOTO/0,0,0\n", "unknown units 'FEET'", 2),
    ("GOTO/0,0,0\nCIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1\nEND-OF-PATH\n", "not followed by a GOTO", 3),
    ("GOTO/5,0,0\nCIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1,TIMES,two\nGOTO/5,0,0\n", "TIMES must be followed", 3),
    ("GOTO/7,0,0\nCIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1\nGOTO/0,5,0\n", "start point is 7 mm from the axis", 3),
    ("MSYS/0,0,0,1,0,0,1,0,0\nGOTO/0,0,0\n", "not perpendicular", 2),
    ("FEDRAT/XPM,5\nGOTO/0,0,0\n", "malformed FEDRAT", 2),
    ("FEDRAT/IPR,0.01\nGOTO/0,0,0\n", "without a spindle speed", 2),
])
def test_apt_bad_input_names_file_and_line(tmp_path, body, needle, bad_line):
    p = _write(tmp_path, "bad.cls", "$$ header comment\n" + body)
    with pytest.raises(InputError) as exc:
        read_apt(p)
    msg = str(exc.value)
    assert needle in msg and str(p) in msg and exc.value.line == bad_line and f"line {bad_line}" in msg, msg


def test_apt_missing_tldata_named_at_the_tool_path(tmp_path):
    text = "TOOL PATH/OP1,TOOL,T1\nFEDRAT/MMPM,100\nGOTO/0,0,0\nGOTO/1,0,0\nEND-OF-PATH\n"
    prog = read_apt(_write(tmp_path, "nt.cls", text))
    with pytest.raises(InputError) as exc:
        prog.require_tool(prog.toolpaths[0])
    assert "tool path 'OP1' (line 1)" in str(exc.value) and "TLDATA/MILL" in str(exc.value)
    assert str(tmp_path / "nt.cls") in str(exc.value)


def test_apt_rejects_mixed_feed_units_without_units_record(tmp_path):
    text = "FEDRAT/IPM,10\nGOTO/0,0,0\nFEDRAT/MMPM,100\nGOTO/1,0,0\n"
    with pytest.raises(InputError, match="cannot tell the length unit"):
        read_apt(_write(tmp_path, "mix.cls", text))
    prog = read_apt(tmp_path / "mix.cls", units="mm")  # the caller can say
    np.testing.assert_allclose(prog.feed, [10 * IN, 100])


# ----------------------------------------------------------------------------------------------
# CL CSV
def _cl_program(n=6):
    s = np.linspace(0, 1, n)
    tip = np.column_stack([10 * s, np.sin(s), 0.3 * s**2])
    lead = 0.2 * np.sin(3 * s)
    axis = np.column_stack([np.sin(lead), np.zeros(n), np.cos(lead)])
    return tip, axis


def test_cl_csv_round_trip_and_errors(tmp_path):
    tip, axis = _cl_program()
    rows = np.array([4, 4, 4, 9, 9, 9])
    lines = ["X,Y,Z,I,J,K,Row,Feed"] + [",".join(repr(float(v)) for v in (*t, *a)) + f",{r},{800 + k}"
                                       for k, (t, a, r) in enumerate(zip(tip, axis, rows, strict=True))]
    p = _write(tmp_path, "cl.csv", "\n".join(lines) + "\n")
    prog = read_cl_csv(p)
    np.testing.assert_array_equal(prog.tip, tip)
    np.testing.assert_allclose(prog.axis, axis, rtol=1e-15)
    assert prog.rows.tolist() == rows.tolist() and prog.feed.tolist() == [800 + k for k in range(6)]
    assert not prog.rapid.any() and prog.line.tolist() == [1, 2, 3, 4, 5, 6]
    back = read_cl_csv(write_cl_csv(tmp_path / "again.csv", prog))
    np.testing.assert_array_equal(back.tip, prog.tip)
    np.testing.assert_array_equal(back.axis, prog.axis)
    np.testing.assert_array_equal(back.feed, prog.feed)
    # an axis that is not unit, a NaN, a BOM'd semicolon file
    bad = list(lines)
    bad[3] = bad[3].replace(repr(float(axis[2, 2])), "1.5", 1)
    with pytest.raises(InputError) as exc:
        read_cl_csv(_write(tmp_path, "b.csv", "\n".join(bad) + "\n"))
    assert exc.value.row == 3 and exc.value.column == "i,j,k" and "not a unit vector" in str(exc.value)
    bad = list(lines)
    bad[5] = "nan" + bad[5][bad[5].index(","):]
    with pytest.raises(InputError) as exc:
        read_cl_csv(_write(tmp_path, "n.csv", "\n".join(bad) + "\n"))
    assert (exc.value.row, exc.value.column) == (5, "x")
    semi = "\ufeff" + "\n".join(ln.replace(",", ";") for ln in lines) + "\n"
    with pytest.raises(InputError, match="uses ';' as delimiter") as exc:
        read_cl_csv(_write(tmp_path, "s.csv", semi))
    assert exc.value.row == 0


# ----------------------------------------------------------------------------------------------
# detection and the entry point
def test_load_program_detects_the_format_from_content(tmp_path):
    tip, axis = _cl_program()
    apt = _write(tmp_path, "prog.txt", "$$ no extension hint\nFEDRAT/MMPM,100\nGOTO/0,0,0\nGOTO/1,0,0,0,0,1\n")
    cl = _write(tmp_path, "table.dat", "x,y,z,i,j,k\n" + "\n".join(
        ",".join(repr(float(v)) for v in (*t, *a)) for t, a in zip(tip, axis, strict=True)) + "\n")
    cc = tmp_path / "cc.data"
    write_cc_csv(cc, CCPath(tip, np.tile([0, 0, 1.0], (6, 1)), np.zeros(6)))
    assert detect_format(apt) == "apt" and detect_format(cl) == "cl-csv" and detect_format(cc) == "cc-csv"
    assert isinstance(load_program(apt), CLProgram) and load_program(apt).format == "apt"
    assert load_program(cl).format == "cl-csv"
    got = load_program(cc)
    assert isinstance(got, CCPath) and np.array_equal(got.points, read_cc_csv(cc).points)
    assert load_program(cl, format="cl").format == "cl-csv"
    with pytest.raises(InputError, match="unknown program format"):
        load_program(cl, format="step")
    odd = _write(tmp_path, "what.bin", "hello world\n")
    with pytest.raises(InputError, match="cannot tell the program's format"):
        load_program(odd)
    with pytest.raises(InputError, match="not found"):
        load_program(tmp_path / "missing.cls")


def test_apt_long_goto_runs_match_record_by_record(tmp_path):
    """Long runs of plain GOTO lines are parsed at once; the result must equal the record-by-record
    reading (forced here by a '$$' comment on every line) and the modal axis rule."""
    rng = np.random.default_rng(5)
    n = 60
    pts = rng.normal(size=(n, 3))
    ax = rng.normal(size=(n, 3)) * 0.2 + [0, 0, 1]
    ax /= np.linalg.norm(ax, axis=1)[:, None]
    given = rng.random(n) < 0.4
    given[0] = False  # the first points take the axis in force before the run: (0, 0, 1)
    recs = [f"GOTO/{p[0]:.4f},{p[1]:.4f},{p[2]:.4f}" + (f",{a[0]:.7f},{a[1]:.7f},{a[2]:.7f}" if g else "")
            for p, a, g in zip(pts, ax, given, strict=True)]
    head = "UNITS/MM\nFEDRAT/MMPM,300\nRAPID\n"
    fast = read_apt(_write(tmp_path, "fast.cls", head + "\n".join(recs) + "\n"))
    slow = read_apt(_write(tmp_path, "slow.cls", head + "\n".join(r + " $$ c" for r in recs) + "\n"))
    np.testing.assert_array_equal(fast.tip, slow.tip)
    np.testing.assert_allclose(fast.axis, slow.axis, atol=1e-15)
    np.testing.assert_array_equal(fast.line, slow.line)
    np.testing.assert_array_equal(fast.rapid, slow.rapid)
    np.testing.assert_array_equal(fast.feed, slow.feed)
    last = np.where(given, np.arange(n), -1)
    last = np.maximum.accumulate(last)
    expect = np.where((last >= 0)[:, None], np.round(ax, 7)[np.maximum(last, 0)], [0.0, 0.0, 1.0])
    np.testing.assert_allclose(fast.axis, expect / np.linalg.norm(expect, axis=1)[:, None], atol=1e-12)
    np.testing.assert_allclose(fast.tip, np.round(pts, 4), atol=1e-12)
    assert fast.rapid[0] and not fast.rapid[1:].any() and fast.line[0] == 4
    bad = list(recs)
    bad[37] = "GOTO/1.0,2.0,x"
    with pytest.raises(InputError) as exc:
        read_apt(_write(tmp_path, "bad.cls", head + "\n".join(bad) + "\n"))
    assert exc.value.line == 4 + 37 and "'x' is not a number" in str(exc.value)


def test_table_text_columns_quotes_commas_blanks(tmp_path):
    # a quoted text cell may hold the delimiter; text is stripped; an empty text cell stays empty
    p = _write(tmp_path, "t.csv", 'x,note,y\n1," a, b ",2\n3,plain ,4\n5,,6\n')
    t = read_table(p, ["x", "y"], ["note"], text=["note"])
    assert t["note"].tolist() == ["a, b", "plain", ""]
    np.testing.assert_array_equal(t["x"], [1, 3, 5])
    np.testing.assert_array_equal(t["y"], [2, 4, 6])
