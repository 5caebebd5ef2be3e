"""The shipped wave sample's narrow windows (issue 21, part 3): every row is either smoothed within
the limits and windows (points whose clear region the limits keep the axis from are lifted and
named) or refused naming the binding constraint and what to change; never a request to report a
bug. A few rows of the sample keep it fast."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from camsmooth.errors import InfeasibleError
from camsmooth.geometry.cutter import ToroidalCutter
from camsmooth.geometry.surfaces import load_surface
from camsmooth.io.ccpath import read_cc_csv
from camsmooth.smoothing.nlp import fd_operators
from camsmooth.smoothing.pipeline import smooth

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def wave():
    return load_surface(ROOT / "surfaces" / "wave.toml")


def _rows(tmp_path: Path, rows: tuple[int, ...]) -> Path:
    """The wave path's rows ``rows`` as a CC path CSV."""
    lines = (ROOT / "surfaces" / "wave_path.csv").read_text().splitlines(keepends=True)
    col = lines[0].strip().split(",").index("row")
    keep = [ln for ln in lines[1:] if int(float(ln.split(",")[col])) in rows]
    out = tmp_path / "wave_rows.csv"
    out.write_text(lines[0] + "".join(keep))
    return out


def test_clear_region_out_of_reach_is_lifted_not_a_bug(wave, tmp_path):
    """Lead 2:12: the map's lead floor climbs faster before a blocked stretch than B may turn.
    Before: 'the NLP solver failed (Infeasible_Problem_Detected) although no limit binds ... please
    report this row as a bug'. Now the row is smoothed, within every limit and window, and the
    points the limits keep out of their clear region are lifted and named."""
    path = read_cc_csv(_rows(tmp_path, (9, 10)))
    res = smooth(path, wave, None, ToroidalCutter(R=4.0, r=1.0), lead_range=tuple(np.radians([2, 12])),
                 tilt_range=tuple(np.radians([-15, 15])), method="nlp")
    nlp = res.methods["nlp"]
    m = nlp.metrics
    assert sum(m.violations.values()) == 0
    assert m.unreachable_clear and all(b.lift_mm > 0 for b in m.unreachable_clear)
    tol = res.inputs["tolerance"]
    assert np.all(nlp.delta >= -tol - 1e-9)  # lifted where the limits kept the axis from clearing
    # the user's windows (the result's lead and tilt are from the axis written)
    assert np.all(np.degrees(nlp.lead) >= 2 - 1e-6) and np.all(np.degrees(nlp.lead) <= 12 + 1e-6)
    assert np.all(np.abs(np.degrees(nlp.tilt)) <= 15 + 1e-6)
    # velocity within the machine's limit, from the written angles
    for rid in np.unique(nlp.rows):
        k = nlp.rows == rid
        D1, _ = fd_operators(nlp.t[k])
        assert np.all(np.abs(D1 @ nlp.rotary["B"][k]) <= res.machine.limits["B"].vmax * (1 + 1e-9))


def test_windows_the_limits_cannot_follow_are_refused_naming_them(wave, tmp_path):
    """Lead 2:5, tilt -3:3: the windows alone need B faster than 60 deg/s on row 3. Refused naming
    the constraint, where, by how much, the windows and what to change."""
    path = read_cc_csv(_rows(tmp_path, (3,)))
    with pytest.raises(InfeasibleError) as exc:
        smooth(path, wave, None, ToroidalCutter(R=4.0, r=1.0), lead_range=tuple(np.radians([2, 5])),
               tilt_range=tuple(np.radians([-3, 3])), method="nlp")
    msg = str(exc.value)
    assert "bug" not in msg and "report" not in msg
    assert "B velocity limit 60 deg/s" in msg and "near point" in msg and "need at least" in msg
    assert "lead window 2:5 deg and tilt window -3:3 deg" in msg and "widen" in msg
