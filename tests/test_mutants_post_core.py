"""What the mutation run of camsmooth/post/core.py (benchmarks/mutation.py, target "post-core")
showed the reader tests leave open, against closed forms written here: the arc interpolation
(radius, direction, full turns, helix length, chord tolerance), program frames, and the feed of a
point in each feed mode (G94 per minute, G95 per revolution times S, G93 inverse time times the
block's tip path, a tip that does not move taking its neighbour's feed)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.post import read_posted
from camsmooth.post.core import MAX_ARC_POINTS, Frame3, arc_points


# ---- arcs -----------------------------------------------------------------------------------------------
def test_quarter_arc_counter_clockwise_and_its_chords():
    """(10, 0) -> (0, 10) about the origin, ccw about +Z: a quarter of a circle of radius 10, length
    5 pi; chords of angle step = 2 acos(1 - tol / r), so k = ceil((pi / 2) / step) points, each on the
    circle, the last the end point, every chord's sagitta r (1 - cos(step / 2)) within tol."""
    tol = 0.01
    pts, length = arc_points(np.array([10.0, 0, 0]), np.array([0, 10.0, 0]), np.zeros(3), np.array([0, 0, 1.0]),
                             True, chord_tol=tol)
    assert length == pytest.approx(5 * math.pi, rel=1e-12)
    step = 2 * math.acos(1 - tol / 10.0)
    assert len(pts) == math.ceil((math.pi / 2) / step)
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), 10.0, atol=1e-9)
    np.testing.assert_allclose(pts[-1], [0, 10.0, 0], atol=0)
    ang = np.arctan2(pts[:, 1], pts[:, 0])
    assert np.all(np.diff(ang) > 0) and ang[0] > 0 and ang[0] <= step + 1e-12  # ccw, from after the start
    chord = np.linalg.norm(np.diff(np.vstack([[10.0, 0, 0], pts]), axis=0), axis=1)
    sag = 10.0 - np.sqrt(100.0 - (chord / 2) ** 2)
    assert sag.max() <= tol + 1e-12


def test_the_same_end_points_clockwise_go_the_long_way():
    """cw from (10, 0) to (0, 10): three quarters through (0, -10), length 15 pi."""
    pts, length = arc_points(np.array([10.0, 0, 0]), np.array([0, 10.0, 0]), np.zeros(3), np.array([0, 0, 1.0]),
                             False, chord_tol=0.01)
    assert length == pytest.approx(15 * math.pi, rel=1e-12)
    assert np.min(np.linalg.norm(pts - [0, -10.0, 0], axis=1)) < 0.5
    ang = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    assert np.all(np.diff(ang) < 0)
    assert ang[-1] == pytest.approx(-1.5 * math.pi, abs=1e-9)


def test_full_circles_extra_turns_and_a_helix():
    """End = start: a full circle (2 pi r); turns = 2 adds two more; a helix rising 3 mm over one
    turn has length hypot(2 pi r, 3) and its height linear in the angle; the centre is taken in the
    plane through the start (a centre given 5 mm above changes nothing)."""
    s = np.array([5.0, 0, 0])
    z = np.array([0, 0, 1.0])
    _, full = arc_points(s, s, np.zeros(3), z, True)
    assert full == pytest.approx(10 * math.pi, rel=1e-12)
    pts3, three = arc_points(s, s, np.zeros(3), z, True, turns=2)
    assert three == pytest.approx(30 * math.pi, rel=1e-12)
    assert np.unwrap(np.arctan2(pts3[:, 1], pts3[:, 0]))[-1] == pytest.approx(6 * math.pi, abs=1e-9)
    pts, helix = arc_points(s, s + [0, 0, 3.0], np.array([0, 0, 5.0]), z, True, chord_tol=0.001)
    assert helix == pytest.approx(math.hypot(10 * math.pi, 3.0), rel=1e-12)
    ang = np.unwrap(np.arctan2(pts[:, 1], pts[:, 0]))
    ang[ang < 0] += 2 * math.pi  # the first points have small positive angles
    np.testing.assert_allclose(pts[:, 2], 3.0 * ang / (2 * math.pi), atol=1e-9)
    np.testing.assert_allclose(np.hypot(pts[:, 0], pts[:, 1]), 5.0, atol=1e-9)


def test_arc_about_another_axis_and_the_degenerate_cases():
    """About +X (the YZ plane, ccw seen from +X): (0, 0, 2) -> (0, -2, 0) is a quarter. A start on
    the centre gives the end point alone and the straight length; a tolerance at or above the radius
    steps a quarter turn at a time; the points per arc are capped."""
    pts, length = arc_points(np.array([0, 0, 2.0]), np.array([0, -2.0, 0]), np.zeros(3), np.array([3.0, 0, 0]), True)
    assert length == pytest.approx(math.pi, rel=1e-12)
    mid = pts[len(pts) // 2]
    assert mid[1] < 0 and mid[2] > 0 and mid[0] == pytest.approx(0.0, abs=1e-12)
    one, straight = arc_points(np.zeros(3), np.array([3.0, 4.0, 0]), np.zeros(3), np.array([0, 0, 1.0]), True)
    assert one.tolist() == [[3.0, 4.0, 0.0]] and straight == pytest.approx(5.0)
    coarse, _ = arc_points(np.array([1.0, 0, 0]), np.array([1.0, 0, 0]), np.zeros(3), np.array([0, 0, 1.0]), True,
                           chord_tol=1.0)
    assert len(coarse) == 4
    fine, _ = arc_points(np.array([1000.0, 0, 0]), np.array([1000.0, 0, 0]), np.zeros(3), np.array([0, 0, 1.0]),
                         True, turns=50, chord_tol=1e-9)
    assert len(fine) == MAX_ARC_POINTS


# ---- frames ---------------------------------------------------------------------------------------------
def test_frames_chain_and_their_matrix():
    """A frame turned 90 deg about Z at (10, 0, 0), and inside it one at (0, 5, 0) turned 90 deg
    about X: a point p of the inner frame is 10 e_x + Rz (5 e_y + Rx p)."""
    rz = np.array([[0, -1.0, 0], [1.0, 0, 0], [0, 0, 1.0]])
    rx = np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]])
    a, b = Frame3(rz, np.array([10.0, 0, 0])), Frame3(rx, np.array([0, 5.0, 0]))
    ab = a.then(b)
    p = np.array([1.0, 2.0, 3.0])
    want = np.array([10.0, 0, 0]) + rz @ (np.array([0, 5.0, 0]) + rx @ p)
    np.testing.assert_allclose(ab.o + ab.R @ p, want, atol=1e-12)
    np.testing.assert_allclose(ab.matrix() @ np.r_[p, 1.0], np.r_[want, 1.0], atol=1e-12)
    assert a.rotates and not a.identity
    shift = Frame3(o=np.array([0, 0, 1.0]))
    assert not shift.rotates and not shift.identity
    assert Frame3().identity and not Frame3().rotates
    np.testing.assert_array_equal(Frame3().matrix(), np.eye(4))


# ---- feeds ------------------------------------------------------------------------------------------------
def _read(tmp_path, body: str):
    p = tmp_path / "f.nc"
    p.write_text("%\nO1\nG21 G90 G17\n" + body + "M30\n%\n")
    return read_posted(p)


def _feed_at(prog, line: int) -> np.ndarray:
    return prog.feed[prog.line == line]


def test_feed_per_minute_and_per_revolution(tmp_path):
    """G94 F300: 300 mm/min; G95 F0.1 with S2000: 0.1 mm/rev x 2000 rev/min = 200 mm/min; rapids
    carry no feed."""
    prog = _read(tmp_path, "S2000 M3\nG0 X0 Y0 Z0\nG94 G1 X10 F300\nG95 G1 X20 F0.1\nG94 G1 X30 F250\n")
    assert np.isnan(_feed_at(prog, 5)).all()
    assert _feed_at(prog, 6).tolist() == [300.0]
    assert _feed_at(prog, 7) == pytest.approx([200.0])
    assert _feed_at(prog, 8).tolist() == [250.0]


def test_feed_per_revolution_without_a_spindle_speed_is_unknown(tmp_path):
    prog = _read(tmp_path, "G0 X0 Y0 Z0\nG1 X5 F100\nG95 G1 X20 F0.1\n")
    assert np.isnan(_feed_at(prog, 6)).all()


def test_inverse_time_feed_is_the_block_length_times_f(tmp_path):
    """TCP (G43.4: X Y Z is the tip), G93 F4 (the block takes 1/4 min): a 12 mm move at 48 mm/min, a
    3-4-5 move at 20 mm/min; a block that turns only A (the tip stands still) takes the feed of the
    move before it; a 10 mm move at F1 10 mm/min."""
    prog = _read(tmp_path, "G43.4 H1\nG0 X0 Y0 Z0 A0\nG93\nG1 X12 F4\nG1 X15 Y4 F4\nG1 A10 F2\nG1 X15 Y14 F1\n")
    assert _feed_at(prog, 7) == pytest.approx([48.0])
    assert _feed_at(prog, 8) == pytest.approx([20.0])
    assert _feed_at(prog, 9) == pytest.approx([20.0])
    assert _feed_at(prog, 10) == pytest.approx([10.0])


def test_a_still_first_inverse_time_block_takes_the_feed_after_it(tmp_path):
    prog = _read(tmp_path, "G43.4 H1\nG0 X0 Y0 Z0 A0\nG93\nG1 A10 F2\nG1 X6 Y8 F3\n")
    assert _feed_at(prog, 7) == pytest.approx([30.0])
    assert _feed_at(prog, 8) == pytest.approx([30.0])


def test_inverse_time_in_machine_mode_uses_the_tip_path_of_the_turn(tmp_path):
    """Machine mode on the default AB head (tip 150 mm from the A axis at A = 0, B = 0): G93 F2 on
    a block turning A by 10 deg moves the tip along an arc of 150 x 10 deg = 26.18 mm, so its feed
    is 2 x 26.18 mm/min (the controller interpolates the joints, not the chord)."""
    from camsmooth.post.core import nominal_machine

    pivot = nominal_machine(("A", "B")).pivot
    assert pivot == pytest.approx(150.0)
    prog = _read(tmp_path, "G0 X0 Y0 Z0 A0\nG93\nG1 X12 F4\nG1 A10 F2\n")
    assert _feed_at(prog, 6) == pytest.approx([48.0])
    assert _feed_at(prog, 7) == pytest.approx([2 * pivot * math.radians(10.0)], rel=1e-6)
    assert any("default AB head" in w for w in prog.warnings)


def test_tool_vectors_are_normalised_and_a_zero_one_is_refused_with_its_line(tmp_path):
    """G43.5 (Fanuc tool-axis-direction TCP) I J K: the tool axis is the unit vector along (I, J, K);
    (0, 0, 0) is no direction: refused, naming the file and line."""
    p = tmp_path / "v.nc"
    p.write_text("%\nO1\nG21 G90\nG43.5 H1\nG0 X0 Y0 Z10\nG1 X1 Y0 Z0 I0 J3 K4 F100\nM30\n%\n")
    np.testing.assert_allclose(read_posted(p).axis[-1], [0, 0.6, 0.8], atol=1e-12)
    p.write_text("%\nO1\nG21 G90\nG43.5 H1\nG0 X0 Y0 Z10\nG1 X1 Y0 Z0 I0 J0 K0 F100\nM30\n%\n")
    with pytest.raises(InputError, match=r"v\.nc, line 6: tool vector \(0, 0, 0\) is not a direction"):
        read_posted(p)


# ---- operations, tools, cycles and what is named ------------------------------------------------------------
_OPS = ("%\nO1\nG21 G90 G17\nT1 M6\n(OPERATION: ROUGH)\nG0 X0 Y0 Z5\nG1 Z0 F100\nG1 X10\nG64\n(OPERATION: FINISH)\n"
        "G1 X20\nG64\nG1 X30\nG81 X0 Y0 Z-5 R2 F50\nX10\nX20\nG80\nG1 X40\nM30\n%\n")


def test_operations_keep_the_tool_and_modal_cycles_collect_their_holes(tmp_path):
    """Line numbers of _OPS: T1 on 4, operations on 5 and 10, G64 on 9 and 12, a modal G81 on 14
    with holes repeated on 15 and 16. Both operations cut with T1; the three holes are one cycle
    of operation FINISH (lines 14, 15, 16); the G64s are named once with their lines."""
    p = tmp_path / "o.nc"
    p.write_text(_OPS)
    prog = read_posted(p)
    assert [tp.name for tp in prog.toolpaths] == ["ROUGH", "FINISH"]
    assert [tp.tool.name for tp in prog.toolpaths] == ["T1", "T1"]
    assert [(tp.start, tp.stop) for tp in prog.toolpaths] == [(0, 3), (3, 6)]
    [c] = prog.cycles
    assert (c.code, c.lines, c.op_name) == ("G81", [14, 15, 16], "FINISH")
    np.testing.assert_array_equal(c.holes, [[0, 0, -5.0], [10.0, 0, -5.0], [20.0, 0, -5.0]])
    assert f"{p}: read without moving the tool path: G64 (lines 9, 12)" in prog.warnings
    assert f"{p}, line 14: canned cycle G81 (3 holes) in operation 'FINISH': listed, not smoothed" in prog.warnings


def test_a_construct_named_on_many_lines_lists_eight_and_the_count(tmp_path):
    body = "".join(f"G64\nG1 X{k + 1}\n" for k in range(10))
    p = tmp_path / "n.nc"
    p.write_text("%\nO1\nG21 G90\nG0 X0 Y0 Z0\nG1 X0.5 F100\n" + body + "M30\n%\n")
    [w] = [w for w in read_posted(p).warnings if "G64" in w]
    assert w.endswith("G64 (lines 6, 8, 10, 12, 14, 16, 18, 20, ... (10 in all))")


def test_skip_carries_its_reason():
    from camsmooth.post.core import Skip

    exc = Skip("loops are not executed")
    assert exc.reason == "loops are not executed" and str(exc) == "loops are not executed"


def test_an_operation_of_cycles_only_is_an_empty_tool_path_and_rows_start_at_zero(tmp_path):
    """A program that starts cutting without a rapid: its first feed point opens row 0; an operation
    holding only a drilling cycle is a tool path of kind 'cycle' without points (start = stop), and
    the operation after it opens the next row."""
    p = tmp_path / "d.nc"
    p.write_text("%\nO1\nG21 G90 G17\nT1 M6\n(OPERATION: ROUGH)\nG1 X0 Y0 Z5 F100\nG1 X10\n(OPERATION: DRILL)\n"
                 "G81 X0 Y0 Z-5 R2 F50\nG80\n(OPERATION: FINISH)\nG1 X20\nG1 X30\nM30\n%\n")
    prog = read_posted(p)
    assert [(tp.name, tp.start, tp.stop, tp.kind) for tp in prog.toolpaths] == [
        ("ROUGH", 0, 2, "3-axis"), ("DRILL", 2, 2, "cycle"), ("FINISH", 2, 4, "3-axis")]
    assert prog.rows.tolist() == [0, 0, 1, 1]
    assert prog.line.tolist() == [6, 7, 12, 13]


def test_inverse_time_blocks_that_only_turn_a_rotary_axis_have_no_neighbour_to_borrow_from(tmp_path):
    """TCP, G93, the tip never moves: no block has a tip feed to lend, so each keeps its own, the
    tip path (0 mm) times F: 0 mm/min (and the reader does not fail looking past the last point)."""
    prog = _read(tmp_path, "G43.4 H1\nG0 X0 Y0 Z0 A0\nG93\nG1 A10 F2\nG1 A20 F2\n")
    assert prog.line.tolist() == [5, 7, 8]
    assert np.isnan(prog.feed[0]) and prog.feed[1:].tolist() == [0.0, 0.0]


def test_a_program_of_cycles_only_lists_the_first_ten(tmp_path):
    """Eleven drilling cycles (each ended by G80) and no cutting move: an InputError listing the
    first ten (lines 5, 7, ..., 23), not the eleventh (line 25)."""
    body = "".join(f"G81 X{k} Y0 Z-5 R2 F50\nG80\n" for k in range(11))
    p = tmp_path / "c.nc"
    p.write_text("%\nO1\nG21 G90 G17\nG0 X0 Y0 Z5\n" + body + "M30\n%\n")
    with pytest.raises(InputError) as exc:
        read_posted(p)
    msg = str(exc.value)
    assert "no cutting move: only canned cycles (" in msg
    assert [int(x) for x in re.findall(r"G81 line (\d+) \(1 holes\)", msg)] == list(range(5, 25, 2))


def test_still_blocks_at_a_row_start_take_the_first_feed_after_them(tmp_path):
    """TCP, G93: two A-only blocks (tip still) and then moves of 10 mm at F3, F4, F5 (30, 40, 50
    mm/min): both still blocks take 30 mm/min, the feed of the first move after them."""
    prog = _read(tmp_path, "G43.4 H1\nG0 X0 Y0 Z0 A0\nG93\nG1 A10 F2\nG1 A20 F2\nG1 X6 Y8 F3\nG1 X6 Y18 F4\n"
                           "G1 X6 Y28 F5\n")
    assert prog.line.tolist() == [5, 7, 8, 9, 10, 11]
    np.testing.assert_allclose(prog.feed[1:], [30.0, 30.0, 30.0, 40.0, 50.0], rtol=1e-12)
