"""What the mutation run of camsmooth/io/apt.py (benchmarks/mutation.py, target "apt") showed the
APT tests leave open, against closed forms and values worked by hand here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.io.apt import read_apt


def _write(tmp_path, text: str):
    p = tmp_path / "t.apt"
    p.write_text(text)
    return p


@pytest.mark.parametrize("end_y", [0.001, -0.001])
def test_a_full_movarc_whose_end_is_a_hair_off_the_start(tmp_path, end_y):
    """MOVARC ANGLE 360 about +Z, radius 30, the end 1 um counter-clockwise past the start (or 1 um
    short of it): within the tolerance of the start, so the record's sweep decides: one full turn,
    every point on the circle."""
    p = _write(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/30,0,0\nMOVARC/0,0,0,0,0,1,30,ANGLE,360\n"
                         f"GOTO/30,{end_y},0\n")
    prog = read_apt(p, chord_tol=0.01)
    arc = prog.tip[1:]
    ang = np.degrees(np.unwrap(np.arctan2(arc[:, 1], arc[:, 0])))
    assert np.all(np.diff(ang) > 0)
    assert ang[-1] == pytest.approx(360.0 + math.degrees(math.atan2(end_y, 30.0)), abs=1e-9)  # the GOTO end
    np.testing.assert_allclose(np.hypot(arc[:-1, 0], arc[:-1, 1]), 30.0, atol=1e-3)


def _read(tmp_path, text: str, **kw):
    return read_apt(_write(tmp_path, text), **kw)


@pytest.mark.parametrize("goto", ["GOTO/0,0,nan", "GOTO/nan,0,0", "GOTO/0,inf,0", "GOTO/0,0,0,0,nan,1"])
def test_a_goto_that_is_not_finite_is_refused_with_its_line(tmp_path, goto):
    """A NaN or infinite coordinate anywhere in a GOTO is no position: refused naming the file and
    line (a NaN after the first number used to pass the fast check and give a NaN point)."""
    p = _write(tmp_path, f"UNITS/MM\nFEDRAT/100,MMPM\n{goto}\n")
    with pytest.raises(InputError) as exc:
        read_apt(p)
    assert exc.value.line == 3 and f"{p}, line 3: malformed GOTO" in str(exc.value)
    assert "is not a finite number" in str(exc.value)


def test_a_goto_beyond_the_largest_number_names_file_and_line(tmp_path):
    p = _write(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0\nGOTO/3,0,1e12\n")
    with pytest.raises(InputError, match=r"t\.apt, line 4: malformed GOTO: '1e12' is beyond \+-1e\+09"):
        read_apt(p)


def test_a_record_continued_at_the_end_of_the_file_is_read(tmp_path):
    """The last record ends with '$' and nothing follows: it is still a record (here a malformed
    MSYS of 3 numbers, named on its line)."""
    for last in ("MSYS/0,0,0$", "msys/0,0,0 $"):  # the major word upper-cased there too; no final newline
        p = _write(tmp_path, f"UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0\n{last}")
        with pytest.raises(InputError, match=r"line 4: malformed MSYS: expected 9 numbers, got 3"):
            read_apt(p)


def test_units_given_by_the_caller_override_the_file(tmp_path):
    """units='inch': 1, 2, 3 in are 25.4, 50.8, 76.2 mm; units='mm' keeps them; other words refused."""
    text = "FEDRAT/10,IPM\nGOTO/1,2,3\n"
    np.testing.assert_allclose(_read(tmp_path, text, units="inch").tip, [[25.4, 50.8, 76.2]], atol=1e-12)
    np.testing.assert_allclose(_read(tmp_path, text, units="mm").tip, [[1.0, 2.0, 3.0]], atol=1e-12)
    with pytest.raises(InputError, match="units must be 'mm' or 'inch', got 'cm'"):
        _read(tmp_path, text, units="cm")


@pytest.mark.parametrize("tol", [0.0, -0.1, math.inf, math.nan])
def test_the_chord_tolerance_must_be_a_positive_number(tmp_path, tol):
    with pytest.raises(InputError, match="chord_tol must be a finite number > 0 mm"):
        _read(tmp_path, "UNITS/MM\nGOTO/0,0,0\n", chord_tol=tol)


def test_a_coarse_tolerance_still_steps_at_most_a_quarter_turn(tmp_path):
    """Radius 1 mm, chord_tol 0.5 mm: the chordal step 2 acos(1 - 0.5) = 120 deg is capped at 90 deg,
    so a full circle takes 4 chords (3 points between start and end), each end on the circle."""
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/1,0,0\nCIRCLE/0,0,0,0,0,1,1,0.5,0.5,6,1\nGOTO/1,0,0\n",
                 chord_tol=0.5)
    assert len(prog.tip) == 5
    np.testing.assert_allclose(np.hypot(prog.tip[:, 0], prog.tip[:, 1]), 1.0, atol=1e-12)
    chords = np.linalg.norm(np.diff(prog.tip, axis=0), axis=1)
    np.testing.assert_allclose(chords, math.sqrt(2.0), atol=1e-12)


def test_an_arc_too_fine_for_the_limit_asks_for_a_coarser_tolerance(tmp_path):
    """Radius 1000 mm, 270 deg at chord_tol 1e-9 mm needs (3 pi / 2) / (2 acos(1 - 1e-12)) = 1.67e6
    points, over the 1e6 an arc may have: named, with what to do."""
    p = _write(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/1000,0,0\nCIRCLE/0,0,0,0,0,1,1000,1e-9,0.5,6,1\n"
                         "GOTO/0,1000,0\n")
    with pytest.raises(InputError) as exc:
        read_apt(p, chord_tol=1e-9)
    need = (1.5 * math.pi) / (2 * math.acos(1 - 1e-12))
    assert f"{need:.3g} points would be needed" in str(exc.value)
    assert str(exc.value).endswith("raise chord_tol") and exc.value.line == 4


def test_an_arc_after_the_end_of_a_path_opens_the_next_one(tmp_path):
    """END-OF-PATH closes the first tool path (one point); a CIRCLE and its GOTO after it are the
    second tool path's points, every one on the circle of radius 5 (the arc starts at the last
    position, (5, 0, 0))."""
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/5,0,0\nEND-OF-PATH\nCIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1\n"
                           "GOTO/0,5,0\n")
    assert [(tp.start, tp.stop) for tp in prog.toolpaths] == [(0, 1), (1, len(prog.tip))]
    assert len(prog.tip) > 10
    np.testing.assert_allclose(np.hypot(prog.tip[:, 0], prog.tip[:, 1]), 5.0, atol=1e-9)
    np.testing.assert_allclose(prog.tip[-1], [0, 5.0, 0], atol=1e-12)


def test_a_dropped_unnamed_tool_path_is_named_by_the_line_that_opened_it(tmp_path):
    """The second tool path opens on line 5 and fails on line 7: the warning names line 5."""
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/0,0,0\nEND-OF-PATH\nGOTO/1,0,0\nGOTO/2,0,0\n"
                           "GOTO/3,0,1e12\n")
    assert len(prog.toolpaths) == 1 and len(prog.tip) == 1
    [w] = [w for w in prog.warnings if "dropped" in w]
    assert w.startswith("tool path (unnamed, from line 5) dropped: ") and "line 7" in w


def test_an_arc_after_a_dropped_tool_path_starts_from_the_last_point_kept(tmp_path):
    """The second tool path (line 5 on) is dropped at line 6; the CIRCLE of the third starts from the
    last point kept, (5, 0, 0), not from the dropped (7, 0, 0): every point on radius 5."""
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/5,0,0\nEND-OF-PATH\nGOTO/7,0,0\nGOTO/3,0,1e12\n"
                           "END-OF-PATH\nCIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1\nGOTO/0,5,0\n")
    assert [(tp.start, tp.stop) for tp in prog.toolpaths] == [(0, 1), (1, len(prog.tip))]
    np.testing.assert_allclose(np.hypot(prog.tip[:, 0], prog.tip[:, 1]), 5.0, atol=1e-9)
    assert any("from line 5) dropped" in w for w in prog.warnings)


def test_a_circle_given_by_centre_and_axis_alone_takes_the_start_radius(tmp_path):
    """CIRCLE/0,0,0,0,0,1 (SOLIDWORKS CAM: no radius): the radius is the start's distance from the
    axis, 5 mm from (3, 4, 0); the motion is counter-clockwise about +Z from 53.13 deg to (-4, 3) at
    143.13 deg: 90 deg of arc, every point at 5 mm."""
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nGOTO/3,4,0\nCIRCLE/0,0,0,0,0,1\nGOTO/-4,3,0\n")
    np.testing.assert_allclose(np.hypot(prog.tip[:, 0], prog.tip[:, 1]), 5.0, atol=1e-9)
    ang = np.degrees(np.arctan2(prog.tip[:, 1], prog.tip[:, 0]))
    assert np.all(np.diff(ang) > 0)
    assert ang[0] == pytest.approx(math.degrees(math.atan2(4, 3))) and ang[-1] == pytest.approx(ang[0] + 90.0)


@pytest.mark.parametrize("body, needle", [
    ("GOTO/5,0,0\nCIRCLE/0,0,0,0,0,1,0,0.01,0.5,6,1\nGOTO/0,5,0\n", "line 4: CIRCLE radius must be > 0, got 0"),
    ("GOTO/30,0,0\nMOVARC/0,0,0,0,0,2,30,ANGLE,90\nGOTO/0,30,0\n",
     "line 4: MOVARC normal (0, 0, 2) is not a unit vector (length 2, allowed 1 +- 0.001)"),
])
def test_circle_and_movarc_refusals_name_what_and_where(tmp_path, body, needle):
    p = _write(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\n" + body)
    with pytest.raises(InputError) as exc:
        read_apt(p)
    assert f"{p}, {needle}" in str(exc.value)


@pytest.mark.parametrize("units", [None, "mm"])
def test_a_units_record_without_a_word_is_named(tmp_path, units):
    """Found when the file's unit is looked for, and when the caller gives the unit (the record is
    then checked where it stands)."""
    p = _write(tmp_path, "UNITS\nFEDRAT/100,MMPM\nGOTO/30,0,0\n")
    with pytest.raises(InputError, match=r"line 1: unknown units 'UNITS' \(expected UNITS/MM or UNITS/INCHES\)"):
        read_apt(p, units=units)


def test_a_latin1_file_with_a_byte_order_mark_is_read(tmp_path):
    """A UTF-8 byte order mark, then Latin-1 text ('Fraeser' with a Latin-1 umlaut): the records are
    read (the BOM is not part of the first record) with a warning that the text was read as Latin-1."""
    p = tmp_path / "b.apt"
    p.write_bytes(b"\xef\xbb\xbfUNITS/INCHES\nPPRINT Fr\xe4ser\nFEDRAT/10,IPM\nGOTO/1,2,3\n")
    prog = read_apt(p)
    np.testing.assert_allclose(prog.tip, [[25.4, 50.8, 76.2]], atol=1e-12)
    assert any("read as Latin-1" in w for w in prog.warnings)


@pytest.mark.parametrize("record, needle", [
    ("CUTTER/abc", "line 3: malformed CUTTER: 'abc' is not a number ('CUTTER/abc')"),
    ("CUTTER/-5", "line 3: CUTTER: need diameter > 0 and 0 <= corner radius <= diameter / 2, got D = -5, R = 0"),
])
def test_a_bad_cutter_record_is_named(tmp_path, record, needle):
    p = _write(tmp_path, f"UNITS/MM\nFEDRAT/100,MMPM\n{record}\nGOTO/0,0,0\n")
    with pytest.raises(InputError) as exc:
        read_apt(p)
    assert f"{p}, {needle}" in str(exc.value)


def test_a_tldata_record_without_words_keeps_an_unknown_tool(tmp_path):
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nTLDATA\nGOTO/0,0,0\n")
    assert prog.warnings == ["line 3: TLDATA/ kept without dimensions (only MILL is read)"]
    assert prog.toolpaths[0].tool.kind == "unknown" and prog.toolpaths[0].tool.line == 3


@pytest.mark.parametrize("n, listed", [(10, "lines 3, 4, 5, 6, 7, 8, 9, 10, 11, 12)"),
                                       (11, "lines 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, ... (11 in all))")])
def test_ignored_records_list_ten_lines_then_the_count(tmp_path, n, listed):
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\n" + "FOO/1\n" * n + "GOTO/0,0,0\n")
    assert prog.warnings == [f"records ignored (not applied): FOO ({listed}"]


def test_multax_off_while_tilted_is_named_once_with_the_count(tmp_path):
    """Three MULTAX/OFF records (lines 4, 6, 8) while the axis is tilted: one warning naming the first
    'and 2 more'."""
    prog = _read(tmp_path, "UNITS/MM\nFEDRAT/100,MMPM\nTLAXIS/0,0.6,0.8\nMULTAX/OFF\nGOTO/0,0,0\nMULTAX/OFF\n"
                           "GOTO/1,0,0\nMULTAX/OFF\nGOTO/2,0,0\n")
    [w] = prog.warnings
    assert w.startswith("MULTAX/OFF on line 4 (and 2 more) while the tool axis is tilted")
    np.testing.assert_allclose(prog.axis, np.tile([0, 0.6, 0.8], (3, 1)), atol=1e-12)
