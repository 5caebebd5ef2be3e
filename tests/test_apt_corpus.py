"""The APT corpus of tests/data/apt: four files shaped like the CL output of NX (CLSF), Autodesk
Fusion / HSM (ISO 4343), PowerMill-style and Mastercam-style APT posts, written for these tests from
the record descriptions (no CAM system's output copied). Every expected point is worked out here
from the numbers in the file (MSYS transform, helix and arc closed forms, inch conversion)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from camsmooth.io.apt import DEFAULT_CHORD_TOL, read_apt
from camsmooth.io.program import detect_format
from camsmooth.post import load_program

DATA = Path(__file__).parent / "data" / "apt"
S10, C10 = math.sin(math.radians(10)), math.cos(math.radians(10))


def _segments(sweep: float, r: float, tol: float = DEFAULT_CHORD_TOL) -> int:
    """Chords the reader needs for a sweep (rad) at radius r: the sagitta of each <= tol."""
    return math.ceil(sweep / min(2 * math.acos(1 - tol / r), math.pi / 2))


@pytest.mark.parametrize("name", ["nx_helix_multi.cls", "fusion_iso4343.apt", "powermill_like.apt",
                                  "mastercam_like.apt"])
def test_corpus_files_are_detected_as_apt(name):
    assert detect_format(DATA / name) == "apt"
    assert load_program(DATA / name).format == "apt"


def test_nx_helix_and_three_tool_paths():
    prog = read_apt(DATA / "nx_helix_multi.cls")
    assert [tp.name for tp in prog.toolpaths] == ["HELIX_ENTRY", "FIVE_AXIS_FINISH", "CORNER_ARC"]
    assert prog.warnings == ["records ignored (not applied): CUTCOM (lines 40, 47)"]
    t1, t2, t3 = prog.toolpaths
    assert (t1.tool.diameter, t1.tool.corner_radius, t1.tool.number) == (10.0, 1.0, 4)
    assert (t2.tool.diameter, t2.tool.corner_radius, t2.tool.number) == (6.0, 3.0, 7)

    # 1: two rapids, the helix (centre (45, 20), r 5, axis -z: counter-clockwise seen from +z, 2 turns
    # plus 90 deg from (50, 20, 5) to (45, 25, -1)), a rapid up
    total = 2 * 2 * math.pi + math.pi / 2
    k = _segments(total, 5.0)
    assert t1.stop - t1.start == 2 + k + 1
    tip = prog.tip[t1.points]
    np.testing.assert_allclose(tip[:2], [[50, 20, 30], [50, 20, 5]])
    helix = tip[1:-1]
    rel = helix - [45.0, 20.0, 0.0]
    np.testing.assert_allclose(np.hypot(rel[:, 0], rel[:, 1]), 5.0, rtol=1e-12)
    ang = np.unwrap(np.arctan2(rel[:, 1], rel[:, 0]))
    assert np.all(np.diff(ang) > 0) and math.isclose(ang[-1], total, abs_tol=1e-9)
    np.testing.assert_allclose(helix[:, 2], 5.0 - 6.0 * ang / total, atol=1e-9)  # 6 mm down over 2.25 turns
    np.testing.assert_allclose(tip[-1], [45, 25, 30])
    assert prog.rapid[t1.points].tolist() == [True, True] + [False] * k + [True]
    assert np.all(prog.feed[t1.start + 2:t1.stop - 1] == 800.0)
    np.testing.assert_allclose(prog.axis[t1.points], np.tile([0, 0, 1.0], (t1.stop - t1.start, 1)))

    # 2: MSYS origin (100, 0, 10), X = (0, 1, 0), Y = (-1, 0, 0): (x, y, z) -> (100 - y, x, 10 + z),
    # axis (a, b, c) -> (-b, a, c); a continued GOTO and a multi-point GOTO (one extra point with axis)
    np.testing.assert_allclose(prog.tip[t2.points], [[100, 0, 30], [100, 0, 10], [100, 5, 10.25], [100, 10, 11],
                                                     [100, 11, 11.2], [100, 12, 11.44], [100, 12, 30]], atol=1e-12)
    lead = [0, S10, C10]
    np.testing.assert_allclose(prog.axis[t2.points], [[0, 0, 1], lead, lead, lead, lead, [-S10, 0, C10],
                                                      [-S10, 0, C10]], atol=1e-7)
    assert prog.rows[t2.points].tolist() == [-1, 1, 1, 1, 1, 1, -1] and np.all(prog.feed[t2.start + 1:t2.stop - 1]
                                                                               == 1200.0)

    # 3: a plain CIRCLE, axis +z: clockwise seen from +z, a quarter turn from (0, 10) to (10, 0)
    arc = prog.tip[t3.points]
    assert len(arc) == _segments(math.pi / 2, 10.0) + 1
    ang = np.unwrap(np.arctan2(arc[:, 1], arc[:, 0]))
    np.testing.assert_allclose(np.hypot(arc[:, 0], arc[:, 1]), 10.0, rtol=1e-12)
    assert math.isclose(ang[0], math.pi / 2) and math.isclose(ang[-1], 0.0, abs_tol=1e-12)
    assert np.all(np.diff(ang) < 0) and np.all(prog.feed[t3.points] == 600.0) and set(prog.rows[t3.points]) == {2}


def test_fusion_iso4343_five_axis_and_a_drill_section():
    prog = read_apt(DATA / "fusion_iso4343.apt")
    assert len(prog.toolpaths) == 2
    t1, t2 = prog.toolpaths
    assert (t1.tool.diameter, t1.tool.corner_radius, t1.tool.number) == (8.0, 4.0, 12)
    assert (t2.tool.diameter, t2.tool.number) == (6.0, 3)
    assert len(prog.warnings) == 2
    assert prog.warnings[0].startswith("MULTAX/OFF on line 28 while the tool axis is tilted")
    assert prog.warnings[1] == "records ignored (not applied): CYCLE (line 35)"
    # rapids, three feed moves with a turning axis, a half turn about +x (centre (20, 30, 1), r 10)
    k = _segments(math.pi, 10.0)
    assert t1.stop - t1.start == 2 + 3 + k + 1
    tip = prog.tip[t1.points]
    np.testing.assert_allclose(tip[:5], [[20, 0, 40], [20, 0, 5], [20, 0, 0], [20, 10, 0], [20, 20, 1]])
    arc = tip[4:-1]
    rel = arc - [20.0, 30.0, 1.0]
    assert np.all(rel[:, 0] == 0.0)
    np.testing.assert_allclose(np.hypot(rel[:, 1], rel[:, 2]), 10.0, rtol=1e-12)
    ang = np.unwrap(np.arctan2(rel[:, 2], rel[:, 1]))  # counter-clockwise about +x: y toward z
    assert math.isclose(ang[0], math.pi) and math.isclose(ang[-1], 2 * math.pi) and np.all(np.diff(ang) > 0)
    assert math.isclose(arc[:, 2].min(), -9.0, abs_tol=1e-3)  # under the centre half way (0.001 mm chords)
    np.testing.assert_allclose(tip[-1], [20, 40, 40])
    np.testing.assert_allclose(prog.axis[t1.start + 3], [0, 0.173648178, 0.984807753])
    assert np.all(prog.feed[t1.start + 2:t1.stop - 1] == 2000.0)
    # the drill section: 3-number GOTOs keep the last axis (named in the warning above)
    np.testing.assert_allclose(prog.tip[t2.points], [[0, 0, 20], [0, 0, 0], [10, 0, 0]])
    np.testing.assert_allclose(prog.axis[t2.points], np.tile([0, 0.342020143, 0.939692621], (3, 1)))
    assert np.all(prog.feed[t2.start + 1:t2.stop] == 300.0)


def test_powermill_like_from_tlaxis_and_spaced_records():
    prog = read_apt(DATA / "powermill_like.apt")
    assert prog.warnings == ["records ignored (not applied): RETRCT (line 21)"]
    (tp,) = prog.toolpaths
    assert (tp.tool.diameter, tp.tool.corner_radius, tp.tool.number) == (10.0, 1.0, 5)
    np.testing.assert_allclose(prog.tip, [[0, 0, 100], [10, 0, 5], [10, 0, 0], [11, 0, 0], [12, 0, 0], [13, 0, 0],
                                          [30, 0, 10], [30, 0, 0], [31, 1, 0], [32, 2, 0]])
    tl = [0, -0.5, math.sqrt(0.75)]
    np.testing.assert_allclose(prog.axis, [[0, 0, 1], [0, 0, 1], [0, 0, 1], [0, -0.1736482, 0.9848078],
                                           [0, -0.3420201, 0.9396926], tl, tl, tl, tl, tl], atol=1e-7)
    assert prog.rapid.tolist() == [True, True, False, False, False, False, True, False, False, False]
    assert prog.rows.tolist() == [-1, -1, 0, 0, 0, 0, -1, 1, 1, 1]
    np.testing.assert_array_equal(prog.feed[~prog.rapid], [1500] * 4 + [900] * 3)


def test_mastercam_like_inch_file():
    prog = read_apt(DATA / "mastercam_like.apt")
    assert prog.warnings == ["records ignored (not applied): CUTCOM (lines 22, 24)"]
    (tp,) = prog.toolpaths
    assert (tp.tool.diameter, tp.tool.corner_radius, tp.tool.number) == (12.7, 1.5875, 2)
    inch = 25.4
    np.testing.assert_allclose(prog.tip, np.array([[1, 1, 1], [1, 1, 0], [2, 1, 0], [3, 1, 0.1], [4, 1, 0.2],
                                                   [4, 1, 1]]) * inch, atol=1e-12)
    s15, c15 = math.sin(math.radians(15)), math.cos(math.radians(15))
    c30 = math.sqrt(0.75)
    np.testing.assert_allclose(prog.axis, [[0, 0, 1], [0, 0, 1], [0, s15, c15], [0, s15, c15], [0, 0.5, c30],
                                           [0, 0.5, c30]], atol=1e-7)
    np.testing.assert_allclose(prog.feed[1:5], 40 * inch)
    assert prog.rows.tolist() == [-1, 0, 0, 0, 0, -1]
