"""NX CLSF helices: ``CIRCLE/x,y,z,i,j,k,r,t,f,d,e,TIMES,n`` then the end GOTO.

Expected points come from the closed form of the helix written by the test (centre, axis,
radius, turns, start and end), not from the reader: every point at radius r from the axis, the
angle monotone in the sense NX gives (clockwise about (i, j, k)), the height linear in the angle,
the ends at the start and the GOTO, chords within the tolerance."""

from __future__ import annotations

import math

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.io.apt import read_apt


def _frame(m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit e1, e2 with (e1, e2, m) right-handed."""
    t = np.array([1.0, 0, 0]) if abs(m[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = t - (t @ m) * m
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(m, e1)


def _helix_file(tmp_path, centre, axis, r, turns, end_angle, z0, z1, tol, name="h.cls"):
    """A file: start GOTO at angle 0 and height z0, the CIRCLE ... TIMES record, the end GOTO at
    end_angle (rad, counter-clockwise about -axis) and height z1. Returns path, start, end, frame."""
    c, a = np.asarray(centre, float), np.asarray(axis, float)
    m = -a / np.linalg.norm(a)  # NX's axis is for a clockwise turn: counter-clockwise about -axis
    e1, e2 = _frame(m)
    p0 = c + r * e1 + z0 * m
    p1 = c + r * (math.cos(end_angle) * e1 + math.sin(end_angle) * e2) + z1 * m

    def f(v):
        return ",".join(f"{x:.12f}" for x in v)

    text = (f"UNITS/MM\nTOOL PATH/HELIX,TOOL,D10\nTLDATA/MILL,10,1,50,0,0\nFEDRAT/MMPM,500\n"
            f"GOTO/{f(p0)},{f(-m)}\n"
            f"CIRCLE/{f(c)},{f(a)},{r:.12f},{tol},0.5,10,1,TIMES,{turns}\n"
            f"GOTO/{f(p1)}\nEND-OF-PATH\n")
    p = tmp_path / name
    p.write_text(text)
    return p, p0, p1, (c, m, e1, e2)


@pytest.mark.parametrize("axis", [(0, 0, 1), (0, 0, -1), (0.3, -0.4, math.sqrt(1 - 0.25))])
@pytest.mark.parametrize("turns, end_deg", [(1, 90.0), (3, 250.0), (2, 0.0), (5, 359.0)])
def test_helix_points_follow_the_closed_form(tmp_path, axis, turns, end_deg):
    r, tol, z0, z1 = 4.0, 0.002, 10.0, 2.5  # a descending helical ramp
    path, p0, p1, (c, m, e1, e2) = _helix_file(tmp_path, (5.0, -3.0, 1.0), axis, r, turns, math.radians(end_deg),
                                               z0, z1, tol)
    prog = read_apt(path, chord_tol=tol)
    q = prog.tip
    np.testing.assert_allclose(q[0], p0, atol=1e-9)
    np.testing.assert_allclose(q[-1], p1, atol=1e-9)
    rel = q - c
    h = rel @ m
    radial = rel - h[:, None] * m
    np.testing.assert_allclose(np.linalg.norm(radial, axis=1), r, rtol=1e-9)
    theta = np.unwrap(np.arctan2(radial @ e2, radial @ e1))
    total = 2 * math.pi * turns + math.radians(end_deg)
    assert math.isclose(theta[0], 0.0, abs_tol=1e-9) and math.isclose(theta[-1], total, abs_tol=1e-7)
    assert np.all(np.diff(theta) > 0)  # one sense throughout: counter-clockwise about -axis
    np.testing.assert_allclose(h, z0 + (z1 - z0) * theta / total, atol=1e-9)  # pitch from the end GOTO
    pitch = (z1 - z0) / (total / (2 * math.pi))
    np.testing.assert_allclose(np.diff(h) / np.diff(theta) * 2 * math.pi, pitch, rtol=1e-6)
    steps = np.diff(theta)
    assert np.all(r * (1 - np.cos(steps / 2)) <= tol * (1 + 1e-9))  # chord error within the tolerance
    assert len(q) - 1 >= math.ceil(total / (2 * math.acos(1 - tol / r)))
    assert len(prog.toolpaths) == 1 and prog.toolpaths[0].name == "HELIX" and not prog.warnings
    np.testing.assert_allclose(prog.axis, np.tile(-m, (len(q), 1)), atol=1e-12)  # the modal axis


def test_helix_sense_matches_the_plain_circle(tmp_path):
    """TIMES,1 from a point to the same point is one full turn, in the sense of the plain CIRCLE."""
    plain = "UNITS/MM\nFEDRAT/MMPM,100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1\nGOTO/0,-10,0\n"
    a = read_apt(_write(tmp_path, "a.cls", plain), chord_tol=0.01)
    ang = np.unwrap(np.arctan2(a.tip[:, 1], a.tip[:, 0]))
    assert math.isclose(ang[-1], -math.pi / 2, abs_tol=1e-12)  # clockwise about +z: a quarter turn
    helix = plain.replace("6,1\n", "6,1,TIMES,1\n").replace("GOTO/0,-10,0", "GOTO/0,-10,-3")
    b = read_apt(_write(tmp_path, "b.cls", helix), chord_tol=0.01)
    ang = np.unwrap(np.arctan2(b.tip[:, 1], b.tip[:, 0]))
    assert math.isclose(ang[-1], -2.5 * math.pi, abs_tol=1e-12) and np.all(np.diff(ang) < 0)
    np.testing.assert_allclose(b.tip[:, 2], -3 * ang / ang[-1], atol=1e-12)
    # TIMES,0 is the plain arc
    zero = read_apt(_write(tmp_path, "c.cls", plain.replace("6,1\n", "6,1,TIMES,0\n")), chord_tol=0.01)
    np.testing.assert_array_equal(zero.tip, a.tip)


def test_helix_end_within_the_tolerance_of_whole_turns(tmp_path):
    # the end GOTO a hair short of the start angle: exactly 2 turns, not 3 less a hair
    eps = 1e-7
    text = (f"UNITS/MM\nFEDRAT/MMPM,100\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10,0.01,0.5,6,1,TIMES,2\n"
            f"GOTO/{10 * math.cos(-eps):.12f},{10 * math.sin(-eps):.12f},-4\n")
    prog = read_apt(_write(tmp_path, "w.cls", text), chord_tol=0.01)
    ang = np.unwrap(np.arctan2(prog.tip[:, 1], prog.tip[:, 0]))
    assert abs(ang[-1] - 4 * math.pi) < 1e-5 and np.all(np.diff(ang) > 0)


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("circle, end, needle", [
    ("CIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1,TIMES,2", "GOTO/0,12,-2",
     "CIRCLE TIMES,2: the arc's end point is 12 mm from the axis, the radius is 10 mm"),
    ("CIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1,TIMES,2.5", "GOTO/0,10,-2", "TIMES must be followed by one whole number"),
    ("CIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1,TIMES", "GOTO/0,10,-2", "TIMES must be followed by one whole number"),
    ("CIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1,TIMES,-1", "GOTO/0,10,-2", "TIMES must be followed by one whole number"),
    ("CIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1,TIMES,1e12", "GOTO/0,10,-2", "TIMES must be followed by one whole number"),
    ("CIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1,TIMES,90000", "GOTO/0,10,-2", "points would be needed"),
])
def test_helix_bad_end_or_turns_named(tmp_path, circle, end, needle):
    p = _write(tmp_path, "bad.cls", f"UNITS/MM\nFEDRAT/MMPM,100\nGOTO/10,0,0\n{circle}\n{end}\n")
    with pytest.raises(InputError) as exc:
        read_apt(p, chord_tol=1e-4)
    assert needle in str(exc.value) and exc.value.line == 4 and str(p) in str(exc.value), str(exc.value)


def test_arcs_past_the_file_limit_are_named(tmp_path, monkeypatch):
    import camsmooth.io.apt as apt

    monkeypatch.setattr(apt, "MAX_ARC_POINTS_TOTAL", 500)
    arc = "CIRCLE/0,0,0,0,0,1,10,0.01,0.5,6,1,TIMES,1\nGOTO/10,0,-1\n"
    text = "UNITS/MM\nFEDRAT/MMPM,100\nGOTO/10,0,0\n" + arc * 3  # 222 points a turn: two fit, the third does not
    with pytest.raises(InputError, match="at most 500 in a file") as exc:
        read_apt(_write(tmp_path, "many.cls", text), chord_tol=0.001)
    assert exc.value.line == 8


def test_circle_end_a_hair_past_the_start_is_a_full_circle(tmp_path):
    """A full NX circle whose end GOTO is rounded a hair past the start: a full turn, not an arc of
    a few micrometres (the record gives no sweep to tell)."""
    text = "UNITS/MM\nGOTO/10,0,0\nCIRCLE/0,0,0,0,0,-1,10,0.01,0.5,6,1\nGOTO/10,0.00001,0\n"
    prog = read_apt(_write(tmp_path, "full.cls", text), chord_tol=0.01)
    ang = np.unwrap(np.arctan2(prog.tip[:, 1], prog.tip[:, 0]))
    assert len(prog) == 72 and math.isclose(ang[-1], 2 * math.pi + 1e-6, abs_tol=1e-6)  # 71 chords of 0.01 mm
