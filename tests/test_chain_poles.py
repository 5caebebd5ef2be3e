"""A program through each described chain's pole meets every limit (issue #28, "What must be
shown"): the shipped nutating B head over a C table, the shipped A/B trunnion (B the platter) and
a fork head (C on the ram, A in the fork). Two saddle rows whose programmed tool axis passes within
a degree of vertical, the pole of the axis about z on each machine (C of the table, B of the
platter, C of the head): the exact inverse turns that axis far faster than its limit; the nlp
program meets both rotary axes' velocity, acceleration and travel limits and the lead/tilt
windows at every sample, recomputed here from the output arrays by plain finite differences,
and its tool axes are the machine's forward kinematics of its angles (written here with plain
rotation matrices from the chain's directions)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from camsmooth.machine.kinematics import load_machine, machine_from_dict

ROOT = Path(__file__).resolve().parents[1]
FORK = {"machine": {"name": "fork head", "table": [], "head": ["C", "A"], "gauge": [0.0, 0.0, 420.0]},
        "axis": {"C": {"direction": [0, 0, 1], "point": [0, 0, 420.0], "min": -360.0, "max": 360.0,
                       "vmax": 120.0, "amax": 600.0},
                 "A": {"direction": [1, 0, 0], "point": [0, 0, 180.0], "min": -100.0, "max": 100.0,
                       "vmax": 60.0, "amax": 300.0},
                 "X": {"min": -900.0, "max": 900.0}, "Y": {"min": -900.0, "max": 900.0},
                 "Z": {"min": -900.0, "max": 900.0}}}


def _machine(name: str):
    if name == "fork":
        return machine_from_dict(FORK)
    return load_machine(str(ROOT / "surfaces" / f"{name}_machine.toml"))


def _rot(d, q):
    """Rotation matrices (N, 3, 3) by angles q (N,) rad about the unit direction d (Rodrigues)."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    K = np.array([[0, -d[2], d[1]], [d[2], 0, -d[0]], [-d[1], d[0], 0]])
    s, c = np.sin(q)[:, None, None], np.cos(q)[:, None, None]
    return np.eye(3) + s * K + (1 - c) * (K @ K)


#: per machine: the axes from the workpiece's end of the chain, t_n ... t_1 then h_1 ... h_m
#: (T = R(t_n) ... R(t_1) R(h_1) ... R(h_m) e_z), with their directions
CHAINS = {"nutating": [("C", (0, 0, 1)), ("B", (0, 1, 1))],
          "trunnion_ab": [("B", (0, 0, 1)), ("A", (1, 0, 0))],
          "fork": [("C", (0, 0, 1)), ("A", (1, 0, 0))]}
POLE_AXIS = {"nutating": "C", "trunnion_ab": "B", "fork": "C"}


def _rates(r, q):
    same = r.rows[1:] == r.rows[:-1]
    h = np.diff(r.t)
    v = np.diff(q)[same] / h[same]
    mid = same[:-1] & same[1:]
    hl, hr = h[:-1][mid], h[1:][mid]
    a = 2 * ((q[2:] - q[1:-1])[mid] / hr - (q[1:-1] - q[:-2])[mid] / hl) / (hl + hr)
    return np.abs(v), np.abs(a)


@pytest.mark.parametrize("name", ["nutating", "trunnion_ab", "fork"])
def test_a_program_through_the_chains_pole_meets_every_limit(tmp_path, name):
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import SmoothOptions, smooth

    lines = (ROOT / "surfaces" / "saddle_path.csv").read_text().splitlines()
    col = lines[0].split(",").index("row")
    keep = [ln for ln in lines[1:] if int(float(ln.split(",")[col])) in (14, 15)]
    path = tmp_path / "rows.csv"
    path.write_text("\n".join([lines[0], *keep]) + "\n")
    m = _machine(name)
    res = smooth(read_cc_csv(path), load_surface(ROOT / "surfaces" / "saddle.ply"), m, ToroidalCutter(R=4.0, r=1.0),
                 feed=2000.0, lead_range=tuple(np.radians([2.0, 20.0])),
                 tilt_range=tuple(np.radians([-15.0, 15.0])), method="nlp", options=SmoothOptions(workers=1),
                 progress=False)
    none, nlp = res.methods["none"], res.methods["nlp"]
    pole = POLE_AXIS[name]
    # the programmed axes pass the pole: the exact inverse turns the pole's axis beyond its limit
    assert _rates(none, none.rotary[pole])[0].max() > 3 * m.limits[pole].vmax
    for ax in m.rotary:
        lim = m.limits[ax]
        q = nlp.rotary[ax]
        v, a = _rates(nlp, q)
        assert v.max() <= lim.vmax * (1 + 1e-6), (ax, v.max(), lim.vmax)
        assert a.max() <= lim.amax * (1 + 1e-6), (ax, a.max(), lim.amax)
        assert np.all((q >= lim.min - 1e-9) & (q <= lim.max + 1e-9)), ax  # inf: continuous
    tol = 1e-6
    assert np.all((nlp.lead >= nlp.lead_window[:, 0] - tol) & (nlp.lead <= nlp.lead_window[:, 1] + tol))
    assert np.all((nlp.tilt >= nlp.tilt_window[:, 0] - tol) & (nlp.tilt <= nlp.tilt_window[:, 1] + tol))
    R = np.broadcast_to(np.eye(3), (len(nlp.t), 3, 3))
    for ax, d in CHAINS[name]:
        R = R @ _rot(d, nlp.rotary[ax])
    np.testing.assert_allclose(R[:, :, 2], nlp.axis, atol=1e-9)
    assert sum(nlp.metrics.violations.values()) == 0, nlp.metrics.violations
