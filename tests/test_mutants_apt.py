"""What the mutation run of camsmooth/io/apt.py (benchmarks/mutation.py, target "apt") showed the
APT tests leave open, against closed forms and values worked by hand here."""

from __future__ import annotations

import math

import numpy as np
import pytest

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
