"""Invariants that hold whatever the code does inside (issue 31 item 1): metamorphic relations
between two runs of the code, or properties every correct answer has, never numbers copied from
the code's output.

- units: the same APT program in inch and in mm (GOTO, MOVARC, CIRCLE, FEDRAT IPM/IPR/MMPM/MMPR)
  reads the same, and so does a posted program in G20 and G21; the bulk GOTO path reads as record
  by record;
- numbering: the rows and lines errors name are the file's (blank lines, comments, BOM, CRLF);
- frames: a tool-axis row turned about the table's C axis gives the same tilt and C shifted by
  the turn, through several turns both ways (limited and continuous C);
- the pole: a row mirrored left/right gives mirrored passages and warm starts (the far pole of
  the AB head, tool axis toward -X); every point inside the cone is in a passage; the warm start
  keeps the tool axis within the pole angle of the programmed one;
- the accessibility floor and ceiling sit a margin inside every sample, and mirror with the tilt;
- feed: a row whose feed drops by 4% mid-row takes no longer than the whole row at the lower feed
  and no less than at the higher; scaling every feed, vmax, amax by k, k^2 scales times by 1/k.

Kinematics only through the public Machine API (machine_from_dict, solve_row, inverse_axis,
pole_angle, tool_axis_np, rotary), so the tests hold across a refactor of the chain.
"""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from camsmooth.errors import InputError

INCH = 25.4


# ---- units: APT in inch and in mm ------------------------------------------------------------------
def _apt_program(unit: str, feed_word: str = "MMPM", feed: float = 1000.0, rpm: float | None = None) -> str:
    """A program written in mm, converted to ``unit``: a tilted 6-number GOTO, 3-number GOTOs that
    keep its axis, a MOVARC quarter circle, a CIRCLE half circle and a helix-free straight end."""
    k = 1.0 if unit == "mm" else 1.0 / INCH

    def n(v: float) -> str:
        return repr(float(v * k))

    ax = np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])
    head = "UNITS/MM\n" if unit == "mm" else "UNITS/INCHES\n"
    spindle = f"SPINDL/RPM,{rpm!r},CLW\n" if rpm else ""
    word = feed_word if unit == "mm" else {"MMPM": "IPM", "MMPR": "IPR"}[feed_word]
    return (head + spindle + f"FEDRAT/{word},{float(feed * k)!r}\n"
            f"GOTO/{n(12.0)},{n(0.0)},{n(5.0)},{','.join(repr(float(v)) for v in ax)}\n"
            f"GOTO/{n(10.0)},{n(0.0)},{n(5.0)}\n"
            f"MOVARC/{n(0.0)},{n(0.0)},{n(5.0)},0,0,1,{n(10.0)},ANGLE,90\n"
            f"GOTO/{n(0.0)},{n(10.0)},{n(5.0)}\n"
            f"CIRCLE/{n(0.0)},{n(0.0)},{n(5.0)},0,0,1,{n(10.0)},{n(0.01)},0.5,{n(6.0)},{n(1.0)}\n"
            f"GOTO/{n(0.0)},{n(-10.0)},{n(5.0)}\n"
            f"GOTO/{n(20.0)},{n(-10.0)},{n(3.0)}\n")


def _read(tmp_path, name: str, text: str, newline: str = "\n", bom: bool = False):
    from camsmooth.io.apt import read_apt

    p = tmp_path / name
    p.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.replace("\n", newline).encode())
    return read_apt(p)


def test_apt_inch_and_mm_programs_read_the_same(tmp_path):
    """Every coordinate, the MOVARC and CIRCLE centres and radii (arc points on the 10 mm circle)
    and the feed read the same from the inch program as from the mm one."""
    mm = _read(tmp_path, "mm.cls", _apt_program("mm"))
    inch = _read(tmp_path, "inch.cls", _apt_program("inch"))
    assert mm.tip.shape == inch.tip.shape and len(mm.tip) > 8
    np.testing.assert_allclose(inch.tip, mm.tip, atol=1e-9)
    np.testing.assert_allclose(inch.axis, mm.axis, atol=1e-12)
    np.testing.assert_allclose(inch.feed, mm.feed, rtol=1e-12)
    # the arcs (points from the MOVARC to the CIRCLE's end) lie on the 10 mm circle about (0, 0, 5)
    arc = (mm.line >= 5) & (mm.line <= 8)
    for prog in (mm, inch):
        r = np.hypot(prog.tip[arc, 0], prog.tip[arc, 1])
        np.testing.assert_allclose(r, 10.0, atol=1e-9)
        np.testing.assert_allclose(prog.tip[arc, 2], 5.0, atol=1e-9)


@pytest.mark.parametrize("unit", ["mm", "inch"])
def test_apt_feed_units_give_the_same_feed(tmp_path, unit):
    """FEDRAT per minute and per revolution (times SPINDL/RPM), in mm and in inch: 1000 mm/min
    = 0.1 mm/rev at 10000 rpm = 1000 / 25.4 in/min = 0.1 / 25.4 in/rev."""
    per_min = _read(tmp_path, "min.cls", _apt_program(unit, "MMPM", 1000.0))
    per_rev = _read(tmp_path, "rev.cls", _apt_program(unit, "MMPR", 0.1, rpm=10000.0))
    cut = ~per_min.rapid & np.isfinite(per_min.feed)
    assert cut.sum() > 5
    np.testing.assert_allclose(per_min.feed[cut], 1000.0, rtol=1e-12)
    np.testing.assert_allclose(per_rev.feed[cut], 1000.0, rtol=1e-12)


def _bulk_text(breaks: bool, unit: str = "mm") -> str:
    """20 six-number GOTOs whose axis turns, a FEDRAT, then 4 three-number GOTOs (they keep the last axis);
    with ``breaks`` a FEDRAT at the same feed after every 7th GOTO splits the run into short
    ones (read record by record)."""
    k = 1.0 if unit == "mm" else 1.0 / INCH
    lines = ["UNITS/MM" if unit == "mm" else "UNITS/INCHES", f"FEDRAT/{'MMPM' if unit == 'mm' else 'IPM'},{800 * k!r}"]
    for i in range(20):
        b = np.radians(2.0 * i)
        lines.append(f"GOTO/{i * k!r},{0.5 * i * k!r},{3.0 * k!r},{float(np.sin(b))!r},0.0,{float(np.cos(b))!r}")
        if breaks and i % 7 == 6:
            lines.append(lines[1])
    lines.append(lines[1])  # a record between: the axis must stay modal beyond the run
    lines += [f"GOTO/{(20 + i) * k!r},{10.0 * k!r},{3.0 * k!r}" for i in range(4)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("unit", ["mm", "inch"])
def test_apt_bulk_run_and_record_by_record_agree(tmp_path, unit):
    bulk = _read(tmp_path, "bulk.cls", _bulk_text(False, unit))
    single = _read(tmp_path, "single.cls", _bulk_text(True, unit))
    np.testing.assert_allclose(bulk.tip, single.tip, atol=1e-9)
    np.testing.assert_allclose(bulk.axis, single.axis, atol=1e-12)
    np.testing.assert_allclose(bulk.feed, single.feed, rtol=1e-12)
    b = np.radians(38.0)  # the last 6-number GOTO's axis, modal for the 3-number GOTOs after it
    np.testing.assert_allclose(bulk.axis[-4:], np.tile([np.sin(b), 0.0, np.cos(b)], (4, 1)), atol=1e-12)
    np.testing.assert_allclose(bulk.tip[-1], [23.0, 10.0, 3.0], atol=1e-9)



def _iso_program(inch: bool) -> str:
    """A posted ISO (Fanuc-style) program in mm (G21) or the same in inch (G20): lines, a G2 arc by
    its centre (I J), a G3 arc by its radius (R), feed per minute; rotary words in degrees."""
    k = 1.0 / INCH if inch else 1.0

    def f(v: float) -> str:
        return f"{v * k:.10f}"

    return "\n".join([
        "%", "O1000", "G20 G90 G17" if inch else "G21 G90 G17", "T1 M6", "G43.4 H1", f"G0 X0 Y0 Z{f(50)} A0 B0",
        f"G1 X{f(10)} Y{f(0)} Z{f(5)} A0 B10. F{f(1000)}", f"G1 X{f(20)} Y{f(5)} Z{f(5)} A5. B10.",
        f"G2 X{f(30)} Y{f(-5)} I{f(0)} J{f(-10)}", f"G3 X{f(40)} Y{f(5)} R{f(10)}", f"G1 X{f(50)} Y{f(5)} Z{f(4)}",
        "G49", "M30", "%"]) + "\n"


def test_posted_g20_and_g21_programs_read_the_same(tmp_path):
    """The same posted program in inch (G20) and in mm (G21): the same tips (arcs by I J and by R
    included), tool axes and feeds."""
    from camsmooth.post import read_posted

    progs = []
    for inch in (False, True):
        p = tmp_path / f"p{int(inch)}.nc"
        p.write_text(_iso_program(inch))
        progs.append(read_posted(p))
    mm, inch = progs
    assert mm.tip.shape == inch.tip.shape and len(mm.tip) > 10
    np.testing.assert_allclose(inch.tip, mm.tip, atol=1e-7)
    np.testing.assert_allclose(inch.axis, mm.axis, atol=1e-12)
    np.testing.assert_allclose(inch.feed, mm.feed, rtol=1e-9)
    cut = ~mm.rapid
    np.testing.assert_allclose(mm.feed[cut][1:], 1000.0, rtol=1e-9)
    assert np.ptp(mm.tip[:, 0]) == pytest.approx(50.0, abs=1e-9)

# ---- numbering -----------------------------------------------------------------------------------
@pytest.mark.parametrize("newline, bom", [("\n", False), ("\r\n", False), ("\r\n", True), ("\n", True)])
def test_error_rows_are_the_file_lines_minus_one(tmp_path, newline, bom):
    """A record the caller refuses after reading (ISO 230-2 run: direction 2) is named by its row,
    the line an editor shows minus one (header = row 0), with blank lines before it."""
    from camsmooth.diagnosis.iso230 import read_run

    lines = ["target,direction,run,deviation", "0,1,1,0.001", "", "0,-1,1,0.002", "   ", "", "100,1,1,0.0",
             "100,2,1,0.0", "100,-1,1,0.0"]
    p = tmp_path / "run.csv"
    p.write_bytes((b"\xef\xbb\xbf" if bom else b"") + newline.join(lines).encode() + newline.encode())
    with pytest.raises(InputError) as exc:
        read_run(p)
    line = lines.index("100,2,1,0.0") + 1  # 1-based line in the file
    assert exc.value.row == line - 1, str(exc.value)
    assert exc.value.column == "direction"
    # a record repeated: the message names the first one's row too
    lines[7] = "0,1,1,0.003"
    p.write_bytes((b"\xef\xbb\xbf" if bom else b"") + newline.join(lines).encode() + newline.encode())
    with pytest.raises(InputError) as exc:
        read_run(p)
    assert exc.value.row == 8 - 1 and "first on row 1" in str(exc.value), str(exc.value)


@pytest.mark.parametrize("newline, bom", [("\n", False), ("\r\n", True)])
def test_apt_lines_in_messages_are_the_file_lines(tmp_path, newline, bom):
    """A bad record after comments ($$) and blank lines is named by the line it is on."""
    text = ("$$ a comment\n\nUNITS/MM\n$$ another\nTOOL PATH/A,TOOL,T1\nFEDRAT/MMPM,500\nGOTO/0,0,0\n\nGOTO/1,0,0\n"
            "END-OF-PATH\nTOOL PATH/B,TOOL,T1\n\n$$ x\nGOTO/2,0,0\nFEDRAT/IPR,0.1\nGOTO/3,0,0\nEND-OF-PATH\n")
    prog = _read(tmp_path, "c.cls", text, newline, bom)
    bad = text.splitlines().index("FEDRAT/IPR,0.1") + 1
    dropped = [w for w in prog.warnings if "dropped" in w]
    assert len(dropped) == 1 and f"line {bad}" in dropped[0], prog.warnings
    assert prog.line.tolist() == [7, 9]



@pytest.mark.parametrize("newline, bom", [("\n", False), ("\r\n", True), ("\r", False)])
def test_posted_lines_in_messages_and_points_are_the_file_lines(tmp_path, newline, bom):
    """A posted program with comments and blank lines, in LF, CRLF with a BOM and old-Mac CR: the
    points' lines, the TCP words' lines and the canned cycle's line are the lines an editor shows."""
    from camsmooth.post import read_posted

    text = ("%\nO1000 (NUMBERING)\n\n(a comment)\nG21 G90 G17\nT1 M6\nG43.4 H1\nG0 X0 Y0 Z50 A0 B0\n"
            "G1 X10 Z5 F1000\n\n(another)\nG81 X20 Y0 Z-5 R2 F100\nX30\nG80\nG1 X40 Y5 Z5\nG49\nM30\n%\n")
    lines = text.splitlines()
    p = tmp_path / "num.nc"
    p.write_bytes((b"\xef\xbb\xbf" if bom else b"") + text.replace("\n", newline).encode())
    prog = read_posted(p)
    at = {k: lines.index(k) + 1 for k in ("G0 X0 Y0 Z50 A0 B0", "G1 X10 Z5 F1000", "G1 X40 Y5 Z5", "G43.4 H1",
                                          "G49", "G81 X20 Y0 Z-5 R2 F100")}
    assert prog.line.tolist() == [at["G0 X0 Y0 Z50 A0 B0"], at["G1 X10 Z5 F1000"], at["G1 X40 Y5 Z5"]]
    said = " ".join(prog.warnings)
    assert f"G43.4 (TCP on) (line {at['G43.4 H1']})" in said and f"G49 (line {at['G49']})" in said, said
    assert f"line {at['G81 X20 Y0 Z-5 R2 F100']}: canned cycle G81" in said, said

# ---- frames: the part turned about the table's C axis -------------------------------------------------
def _ac_table(c_travel: tuple[float, float] | None):
    from camsmooth.machine.kinematics import machine_from_dict

    c = {"vmax": 90.0, "amax": 300.0}
    if c_travel is not None:
        c |= {"min": c_travel[0], "max": c_travel[1]}
    return machine_from_dict({"machine": {"kind": "AC-table"},
                              "axis": {"A": {"min": -110.0, "max": 30.0, "vmax": 60.0, "amax": 300.0}, "C": c}})


def _rz(phi: np.ndarray) -> np.ndarray:
    c, s = np.cos(phi), np.sin(phi)
    z, o = np.zeros_like(phi), np.ones_like(phi)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


@pytest.mark.parametrize("c_travel", [(-720.0, 720.0), None], ids=["C-two-turns", "C-continuous"])
def test_c_follows_a_part_turned_several_times_both_ways(c_travel):
    """A fixed tilt (A = -40 deg; the other branch, A = +40, is outside A's travel) with the part
    turned about C up to 700 deg one way, back, and 700 deg the other way: A stays put and C is
    the turn, continuously (no jump to another turn, no point lost)."""
    m = _ac_table(c_travel)
    assert m.rotary == ("A", "C")
    phi = np.radians(np.r_[np.arange(0.0, 700.0, 2.0), np.arange(700.0, -700.0, -2.0), np.arange(-700.0, 0.1, 2.0)])
    T0 = np.atleast_2d(m.tool_axis_np(np.radians(-40.0), 0.0))[0]
    T = _rz(phi) @ T0
    r = m.solve_row(T)
    assert r.unreachable.size == 0
    np.testing.assert_allclose(r.rotary["A"], np.radians(-40.0), atol=1e-9)
    np.testing.assert_allclose(r.rotary["C"], phi, atol=1e-9)
    np.testing.assert_allclose(m.tool_axis_np(*r.rotary.pair), T, atol=1e-12)


def test_a_row_turned_about_c_gives_c_shifted_by_the_turn():
    """Any smooth row of tool axes and the same row turned by phi about the table's C axis: the same
    A and C + phi (started from the turned start), for turns of either sign beyond a half turn."""
    m = _ac_table((-720.0, 720.0))
    s = np.linspace(0.0, 1.0, 80)
    a = np.radians(-25.0 - 30.0 * s + 8.0 * np.sin(5 * s))
    c = np.radians(40.0 * np.sin(3 * s) + 200.0 * s)
    T = m.tool_axis_np(a, c)
    base = m.solve_row(T, previous=(float(a[0]), float(c[0])))
    np.testing.assert_allclose(base.rotary["A"], a, atol=1e-9)
    np.testing.assert_allclose(base.rotary["C"], c, atol=1e-9)
    for turn in (250.0, -300.0, 95.0):
        ph = np.radians(turn)
        r = m.solve_row(T @ _rz(np.array(ph)).T, previous=(float(a[0]), float(c[0]) + ph))
        np.testing.assert_allclose(r.rotary["A"], base.rotary["A"], atol=1e-9)
        np.testing.assert_allclose(r.rotary["C"], base.rotary["C"] + ph, atol=1e-9)


# ---- the pole ----------------------------------------------------------------------------------------
def _ab_head():
    from camsmooth.machine.kinematics import load_machine

    return load_machine(None)


def _near_pole_row(pole: np.ndarray, side: np.ndarray, other: np.ndarray, miss_deg: float, n: int = 61,
                   span_deg: float = 30.0) -> np.ndarray:
    """Unit tool axes on a great circle that passes ``miss_deg`` from the unit ``pole`` (tilted
    toward ``side``) moving along ``other``: T(u) = cos u p + sin u other, u in +-span."""
    d = np.radians(miss_deg)
    p = np.cos(d) * pole + np.sin(d) * side
    u = np.radians(np.linspace(-span_deg, span_deg, n))
    return np.cos(u)[:, None] * p + np.sin(u)[:, None] * other


def _passages(m, T: np.ndarray):
    from camsmooth.smoothing.pole import find_passages, pole_start

    n = len(T)
    rows, t = np.zeros(n, int), np.arange(n) * 0.01
    r = m.solve_row(T)
    angles = r.rotary.values
    return find_passages(m, T, rows, t, angles), pole_start(m, T, rows, t, angles), angles


def test_mirrored_pole_passages_give_mirrored_tilts():
    """The AB head's poles are B = +90 and B = -90 deg (tool axis along +X and -X; A, the outer
    axis, about X). A row passing 3 deg from +X and the row mirrored left/right (x -> -x, passing -X)
    have mirrored angles (A, B) -> (A, -B), the same passages and mirrored warm starts."""
    m = _ab_head()
    ex, ey, ez = np.eye(3)
    T = _near_pole_row(ex, ez, ey, 3.0)
    M = T * np.array([-1.0, 1.0, 1.0])
    np.testing.assert_allclose(m.pole_angle(M), m.pole_angle(T), atol=1e-12)
    np.testing.assert_allclose(m.pole_angle(np.array([[1.0, 0, 0], [-1.0, 0, 0]])), 0.0, atol=1e-9)
    pa, sa, qa = _passages(m, T)
    pb, sb, qb = _passages(m, M)
    mirror = np.array([1.0, -1.0])
    np.testing.assert_allclose(qb, qa * mirror, atol=1e-9)
    assert len(pa) == 1 and len(pb) == 1
    a, b = pa[0], pb[0]
    assert (a.first, a.last, a.closest_point) == (b.first, b.last, b.closest_point)
    assert a.closest_deg == pytest.approx(3.0, abs=1e-9) and b.closest_deg == pytest.approx(3.0, abs=1e-9)
    assert b.outer_turn_deg == pytest.approx(a.outer_turn_deg, abs=1e-9) and a.outer_turn_deg > 90.0
    np.testing.assert_allclose(sb, sa * mirror, atol=1e-9)


def _angle(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.arctan2(np.linalg.norm(np.cross(u, v), axis=-1), np.einsum("ij,ij->i", u, v))


@pytest.mark.parametrize("kind", ["AB-head +X", "AB-head -X", "AC-table"])
def test_pole_start_keeps_the_tool_axis_within_the_pole_angle(kind):
    """The warm start across a passage holds the outer axis on a line in time and points the tool
    as near the programmed axis as that allows: every tool axis reachable with the outer angle
    fixed passes through the pole, so the start's axis is within the pole angle of the programmed
    one (Machine.nearest_with_outer); before the passage it is the exact inverse, after it an exact
    inverse (the row may continue on the other branch)."""
    ex, ey, ez = np.eye(3)
    if kind == "AC-table":
        m = _ac_table((-720.0, 720.0))
        T = _near_pole_row(ez, -ex, ey, 2.0, span_deg=25.0)
        pole_axis = ez
    else:
        m = _ab_head()
        sgn = 1.0 if "+X" in kind else -1.0
        T = _near_pole_row(sgn * ex, ez, ey, 2.0)
        pole_axis = ex
    passages, start, exact = _passages(m, T)
    assert len(passages) == 1
    p = passages[0]
    inside = np.zeros(len(T), bool)
    inside[p.first:p.last + 1] = True
    got = m.tool_axis_np(start[:, 0], start[:, 1])
    dev = _angle(got, T)
    pole = np.arccos(np.clip(np.abs(T @ pole_axis), 0.0, 1.0))
    assert np.all(dev[inside] <= pole[inside] + 1e-9), np.degrees(dev[inside] - pole[inside]).max()
    np.testing.assert_allclose(start[:p.first], exact[:p.first], atol=1e-12)
    np.testing.assert_allclose(got[~inside], T[~inside], atol=1e-12)
    o = 1 if kind == "AC-table" else 0  # the outer axis: C of the table (A, C), A of the head (A, B)
    outer = start[p.first - 1:p.last + 2, o]
    assert np.all(np.diff(outer) * np.sign(outer[-1] - outer[0]) >= -1e-12)  # moves one way, no overshoot
    assert np.abs(outer).max() > np.radians(5.0)  # the outer axis is turned in the passage: its sign matters


@pytest.mark.parametrize("miss_deg, span", [(3.0, 30.0), (0.5, 12.0), (6.0, 20.0)])
def test_every_point_inside_the_cone_is_in_a_passage(miss_deg, span):
    """Passages are exactly the runs of points within POLE_CONE_DEG of the pole (computed here from
    the pole's direction), ends included; a row that starts and one that ends inside the cone too."""
    from camsmooth.smoothing.pole import POLE_CONE_DEG

    m = _ab_head()
    ex, ey, ez = np.eye(3)
    full = _near_pole_row(ex, ez, ey, miss_deg, n=81, span_deg=span)
    for T in (full, full[30:], full[:50], np.r_[full, full[::-1][1:]]):
        passages, _, _ = _passages(m, T)
        cone = np.degrees(np.arccos(np.clip(np.abs(T @ ex), 0.0, 1.0))) < POLE_CONE_DEG
        covered = np.zeros(len(T), bool)
        for p in passages:
            assert cone[p.first:p.last + 1].all()
            assert p.first == 0 or not cone[p.first - 1]
            assert p.last == len(T) - 1 or not cone[p.last + 1]
            covered[p.first:p.last + 1] = True
        np.testing.assert_array_equal(covered, cone)


# ---- accessibility: floor and ceiling a margin inside every sample -------------------------------------
def _map(tilt_sign: float = 1.0):
    from camsmooth.geometry.accessibility import AccessibilityMap

    nt, nl = 7, 9
    tilt = np.radians(np.linspace(-12.0, 12.0, nt))[None] * np.ones((2, 1))
    lead = np.radians(np.linspace(-5.0, 20.0, nl))[None] * np.ones((2, 1))
    # point 0: a rising floor and a wavy ceiling; point 1: a ceiling only (wall on the right)
    t = tilt[0] * tilt_sign  # the mirrored map at tilt t holds the samples of the map at -t
    floor = np.radians(np.vstack([-2.0 + 3.0 * np.sin(2.0 * t) + 9.0 * t, np.full(nt, -5.0)]))
    ceiling = np.radians(np.vstack([15.0 + 1.5 * np.cos(7.0 * t) - 20.0 * t ** 2,
                                    12.0 - 2.0 * np.sign(t) * np.abs(np.degrees(t)) ** 0.5]))
    fa = np.vstack([np.ones(nt, bool), np.zeros(nt, bool)])
    ca = np.ones((2, nt), bool)
    delta = np.ones((2, nl, nt))
    return AccessibilityMap(lead, tilt, delta, 0.01, floor, ceiling, fa, ca), np.radians([[-5.0, 20.0]] * 2)


def _poly(c: np.ndarray, t: np.ndarray) -> np.ndarray:
    return c[:, :1] + c[:, 1:2] * t + c[:, 2:3] * t ** 2


@pytest.mark.parametrize("margin_deg", [0.02, 0.5])
def test_clear_region_bounds_sit_a_margin_inside_every_sample(margin_deg):
    """clear_region's floor is at least ``margin`` above every refined floor sample and its ceiling
    at least ``margin`` below every ceiling sample (module docstring, step 3), on both sides of
    the tilt window; the mirrored map (tilt -> -tilt) gives the mirrored bounds."""
    from camsmooth.geometry.accessibility import clear_region

    amap, window = _map()
    margin = np.radians(margin_deg)
    reg = clear_region(amap, window, margin)
    assert reg.has_floor.tolist() == [True, False] and reg.has_ceiling.tolist() == [True, True]
    lo, hi = _poly(reg.floor, amap.tilt), _poly(reg.ceiling, amap.tilt)
    assert np.all(lo[0] >= amap.floor[0] + margin - 1e-12), np.degrees(lo[0] - amap.floor[0])
    assert np.all(hi <= amap.ceiling - margin + 1e-12), np.degrees(hi - amap.ceiling)
    # and tight: a least-squares fit shifted onto its samples touches one of them
    assert np.min(lo[0] - amap.floor[0]) == pytest.approx(margin, abs=1e-12)
    assert np.min(amap.ceiling - hi, axis=1) == pytest.approx([margin, margin], abs=1e-12)
    mirrored, _ = _map(-1.0)
    reg_m = clear_region(mirrored, window, margin)
    for a, b in ((reg.floor, reg_m.floor), (reg.ceiling, reg_m.ceiling)):
        np.testing.assert_allclose(b * np.array([1.0, -1.0, 1.0]), a, atol=1e-9)
    np.testing.assert_allclose(reg_m.tilt_window, -reg.tilt_window[:, ::-1], atol=1e-12)


# ---- feed ----------------------------------------------------------------------------------------------
def _ab_machine(scale: float = 1.0, jerk: bool = False):
    """The default AB head with every vmax x k, amax x k^2 (and jmax x k^3 when given)."""
    from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, machine_from_dict

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    for ax, lim in data["axis"].items():
        lim["vmax"] *= scale
        lim["amax"] *= scale ** 2
        if jerk:
            lim["jmax"] = (2000.0 if ax in "AB" else 20000.0) * scale ** 3
    return machine_from_dict(data, "<test>")


def _line_row(m, n: int, length: float = 30.0, swing_deg: float = 0.0):
    """A straight row along X (tip at z = 0) with B swinging by ``swing_deg`` over it."""
    x = np.linspace(0.0, length, n)
    b = np.radians(swing_deg) * np.sin(np.pi * x / length)
    tip = np.column_stack([x, np.zeros(n), np.zeros(n)])
    T = m.tool_axis_np(np.zeros(n), b)
    q = np.column_stack([tip + m.pivot * T, np.zeros(n), b])
    return q, tip


@pytest.mark.parametrize("jerk", [False, True], ids=["time-optimal", "jerk-limited"])
def test_scaling_feeds_and_limits_by_k_scales_times_by_one_over_k(jerk):
    """Time reparametrisation t -> t / k: feed x k, vmax x k, amax x k^2, jmax x k^3 give the same
    law k times faster, whatever binds (feed, velocity, acceleration, jerk)."""
    from camsmooth.smoothing.feed import plan_row

    k = 1.7
    m1, mk = _ab_machine(1.0, jerk), _ab_machine(k, jerk)
    q, tip = _line_row(m1, 20, swing_deg=25.0)
    feed = np.r_[np.full(10, 2400.0), np.full(10, 1500.0)]
    a, b = plan_row(m1, q, tip, feed), plan_row(mk, q, tip, feed * k)
    assert b.cycle_time == pytest.approx(a.cycle_time / k, rel=2e-3 if jerk else 1e-9)
    np.testing.assert_allclose(b.t_plan, a.t_plan / k, rtol=2e-3 if jerk else 1e-9, atol=1e-9)


@pytest.mark.parametrize("jerk", [False, True], ids=["time-optimal", "jerk-limited"])
def test_a_feed_drop_mid_row_costs_no_more_than_the_lower_feed(jerk):
    """A straight row whose programmed feed drops by 4 % halfway: never faster than each block's
    feed, no faster than the row at the higher feed throughout and no slower than at the lower
    one (a law feasible for the lower feed everywhere is feasible for the mixed feeds)."""
    from camsmooth.smoothing.feed import plan_row

    m = _ab_machine(1.0, jerk)
    n = 24  # fewer points than the jerk law's intervals: its pieces are split, the piece feed matters
    q, tip = _line_row(m, n, length=40.0)
    hi, lo = 3000.0, 0.96 * 3000.0
    mixed = np.r_[np.full(n // 2, hi), np.full(n - n // 2, lo)]
    fast, slow, mid = (plan_row(m, q, tip, f) for f in (np.full(n, hi), np.full(n, lo), mixed))
    rel = 2e-3 if jerk else 1e-9
    assert fast.cycle_time * (1 - rel) <= mid.cycle_time <= slow.cycle_time * (1 + rel)
    # the saving is real: most of the time is spent at the feed (the ramps take a few hundredths of a second)
    assert mid.cycle_time < slow.cycle_time - 0.3 * (slow.cycle_time - fast.cycle_time)
    # the planned tip speed at each point within the feed of the blocks on both sides of it
    bound = np.minimum(np.r_[mixed[1], mixed[1:]], np.r_[mixed[1:], mixed[-1]])
    assert np.all(mid.feed_plan <= bound * (1 + 1e-6))
