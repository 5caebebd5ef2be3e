"""Calibration inputs (camsmooth.machine.calibration): the exact message for every measurement
set that cannot determine what it is meant to (probing, spindle analyser, ballbar), the files'
round trips with degrees on disk and radians inside, and the ballbar circles' geometry against
the cone written out here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.calibration import (
    BallbarData,
    ProbeData,
    SpindleData,
    read_ballbar_csv,
    read_probe_csv,
    read_spindle_csv,
    validate_ballbar,
    validate_probe,
    validate_spindle,
    write_ballbar_csv,
    write_probe_csv,
    write_spindle_csv,
)


def _message(fn, data):
    with pytest.raises(InputError) as exc:
        fn(data)
    return str(exc.value)


def _probe(A_deg, B_deg):
    n = len(A_deg)
    X = np.arange(n, dtype=float)
    return ProbeData(np.radians(A_deg), np.radians(B_deg), X, 2 * X, -X, np.zeros((n, 3)), "p.csv")


def test_probing_data_that_cannot_determine_the_axes():
    good = _probe([0.0, 30.0, -30.0, 10.0], [0.0, 20.0, -20.0, 5.0])
    validate_probe(good)
    bad = _probe([0.0, 30.0, -30.0, 10.0], [0.0, 20.0, -20.0, 5.0])
    bad.Y[2] = np.nan
    assert _message(validate_probe, bad) == "p.csv, row 3, column 'Y': not a finite number"
    bad = _probe([0.0, 30.0, -30.0, 10.0], [0.0, 20.0, -20.0, 5.0])
    bad.centre[1, 2] = np.inf
    assert _message(validate_probe, bad) == "p.csv, row 2, column 'sz': not a finite number"
    dup = _probe([0.0, 30.0, 0.0, 10.0], [0.0, 20.0, 0.0, 5.0])
    dup.X[2], dup.Y[2], dup.Z[2] = dup.X[0], dup.Y[0], dup.Z[0]
    assert _message(validate_probe, dup) == (
        "p.csv: duplicate poses: rows [1, 3] repeat the same A, B, X, Y, Z (each pose must be probed once; "
        "average repeated probings first)")
    assert _message(validate_probe, _probe([10.0] * 4, [0.0, 20.0, -20.0, 5.0])) == (
        "p.csv: all 4 poses at A = 10 deg: the A-axis errors EY0A, EZ0A, EB0A, EC0A cannot be determined (the A "
        "axis never turns, so its errors look like a shift of the sphere); probe at three or more distinct A "
        "angles")
    assert _message(validate_probe, _probe([0.0, 30.0, -30.0], [-5.0] * 3)) == (
        "p.csv: all 3 poses at B = -5 deg: the B-axis errors EX0B, EZ0B, EA0B, EC0B cannot be determined (the B "
        "axis never turns, so its errors look like a shift of the sphere); probe at three or more distinct B "
        "angles")


def _spindle(theta_deg, ext):
    n = len(theta_deg)
    return SpindleData(np.radians(theta_deg), np.asarray(ext, float), np.zeros((n, 3)), "s.csv")


def test_spindle_data_that_cannot_separate_the_bearings():
    th = [0.0, 90.0, 180.0, 270.0]
    validate_spindle(_spindle(th + th, [5.0] * 4 + [25.0] * 4))
    bad = _spindle(th + th, [5.0] * 4 + [25.0] * 4)
    bad.ball[5, 1] = np.nan
    assert _message(validate_spindle, bad) == "s.csv, row 6, column 'y': not a finite number"
    bad = _spindle(th + th, [5.0] * 4 + [25.0] * 3 + [np.nan])
    assert _message(validate_spindle, bad) == "s.csv, row 8, column 'ext': not a finite number"
    assert _message(validate_spindle, _spindle(th, [5.0] * 4)) == (
        "s.csv: all samples at one ball height (ext = 5 mm): the upper and lower bearing runouts r1, theta1, r2, "
        "theta2 cannot be separated (one circle shows only their combined effect); measure the ball at two heights")
    assert _message(validate_spindle, _spindle(th + [90.0] + th, [5.0] * 5 + [25.0] * 4)) == (
        "s.csv: duplicate samples: rows [2, 5] repeat the same theta and ext")
    for angles in ([0.0, 90.0, 180.0], [0.0, 40.0, 80.0, 120.0]):   # too few angles; a gap of 240 deg
        data = _spindle(th + angles, [5.0] * 4 + [25.0] * len(angles))
        assert _message(validate_spindle, data) == (
            "s.csv: ball height ext = 25 mm: the samples do not go round the spindle (at least 4 angles, no gap "
            "above 180 deg): the runout phase cannot be determined")
    validate_spindle(_spindle(th + [10.0, 100.0, 200.0, 350.0], [5.0] * 4 + [25.0] * 4))   # largest gap 150 deg


def _ballbar(times=(0.0, 600.0), rpms=(0.0, 8000.0), angles=(30.0, 60.0), phis=tuple(range(0, 360, 30)), L0=150.0):
    t, rpm, ang, d, ph = [], [], [], [], []
    for tk, rk in zip(times, rpms, strict=True):
        for a in angles:
            for direction in (1, -1):
                for p in phis:
                    t.append(tk), rpm.append(rk), ang.append(a), d.append(direction), ph.append(p)
    n = len(t)
    return BallbarData(np.array(t), np.array(rpm, float), np.radians(ang), np.array(d), np.radians(ph),
                       np.full(n, L0), np.zeros(n), "b.csv")


def test_ballbar_circles_geometry():
    cir = validate_ballbar(_ballbar())
    L = 150.0
    assert cir.times.tolist() == [0.0, 600.0] and cir.rpm.tolist() == [0.0, 8000.0] and cir.L0 == L
    np.testing.assert_allclose(cir.angles, np.radians([30.0, 60.0]))
    np.testing.assert_allclose(cir.heights, [0.0, L * (math.sin(math.radians(60)) - 0.5)], atol=1e-12)
    ph = np.radians(cir.phi_deg)
    expect = np.column_stack([L * np.cos(np.radians(30 + 30 * cir.cone_idx)) * np.cos(ph),
                              L * np.cos(np.radians(30 + 30 * cir.cone_idx)) * np.sin(ph),
                              L * np.sin(np.radians(30 + 30 * cir.cone_idx))])
    np.testing.assert_allclose(cir.P, expect, atol=1e-9)
    assert [(k, c) for k, c, _, _ in cir.blocks] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert all(i1 - i0 == 24 for _, _, i0, i1 in cir.blocks)   # 12 angles, both directions
    assert set(cir.direction.tolist()) == {-1, 1}


def test_ballbar_data_that_cannot_determine_the_drift():
    bad = _ballbar()
    bad.dL[7] = np.nan
    assert _message(validate_ballbar, bad) == "b.csv, row 8, column 'dL': not a finite number"
    bad = _ballbar()
    bad.L0[3] = 100.0
    assert _message(validate_ballbar, bad) == \
        "b.csv, column 'L0': the bar length L0 must be one positive value, got [100.0, 150.0]"
    assert _message(validate_ballbar, _ballbar(L0=-5.0)) == \
        "b.csv, column 'L0': the bar length L0 must be one positive value, got [-5.0]"
    dup = _ballbar()
    dup.phi[1] = dup.phi[0]
    assert _message(validate_ballbar, dup) == "b.csv: duplicate samples: rows [1, 2] repeat the same t, angle, dir, phi"
    assert _message(validate_ballbar, _ballbar(angles=(30.0,))) == (
        "b.csv: all circles at one bar angle (30 deg): the spindle tilts exz, eyz cannot be determined (they need "
        "two cone heights, METHODS section 5)")
    assert _message(validate_ballbar, _ballbar(angles=(30.0, 90.0))) == \
        "b.csv, column 'angle': bar angles must be between 0 and 90 deg, got [30.0, 90.0]"
    assert _message(validate_ballbar, _ballbar(angles=(0.0, 30.0))) == \
        "b.csv, column 'angle': bar angles must be between 0 and 90 deg, got [0.0, 30.0]"
    assert _message(validate_ballbar, _ballbar(times=(0.0,), rpms=(0.0,))) == (
        "b.csv, column 't': only one measurement set: the thermal drift needs the cold reference set and at least "
        "one later set")
    mixed = _ballbar()
    mixed.rpm[-1] = 9000.0
    assert _message(validate_ballbar, mixed) == \
        "b.csv, column 'rpm': set at t = 600 s has several spindle speeds [8000.0, 9000.0] (the speed holds per set)"
    gap = _ballbar(phis=(0, 30, 60, 90, 120, 150, 180, 210))   # a 150 deg gap
    assert _message(validate_ballbar, gap) == (
        "b.csv: set at t = 0 s: the circle at 30 deg is missing or does not go round (needs samples with no gap "
        "above 120 deg), so the drift of that set cannot be determined")
    validate_ballbar(_ballbar(phis=(0, 120, 240)))   # three samples 120 deg apart go round


def test_measurement_files_round_trip_in_degrees(tmp_path):
    p = _probe([0.0, 30.0, -30.0, 10.0], [0.0, 20.0, -20.0, 5.0])
    p.centre = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0], [0.5, 0.25, 0.125]])
    write_probe_csv(tmp_path / "p.csv", p)
    text = (tmp_path / "p.csv").read_text().splitlines()
    assert text[0] == "A,B,X,Y,Z,sx,sy,sz" and text[2].split(",")[:2] == ["30.000000000", "20.000000000"]
    q = read_probe_csv(tmp_path / "p.csv")
    for name in ("A", "B", "X", "Y", "Z", "centre"):
        np.testing.assert_allclose(getattr(q, name), getattr(p, name), atol=1e-9, err_msg=name)
    assert q.source == str(tmp_path / "p.csv")
    s = _spindle([0.0, 90.0, 180.0, 270.0], [5.0, 5.0, 25.0, 25.0])
    s.ball = np.arange(12.0).reshape(4, 3) / 7
    write_spindle_csv(tmp_path / "s.csv", s)
    assert (tmp_path / "s.csv").read_text().splitlines()[0] == "theta,ext,x,y,z"
    r = read_spindle_csv(tmp_path / "s.csv")
    np.testing.assert_allclose(r.theta, s.theta, atol=1e-9)
    np.testing.assert_allclose(r.ext, s.ext)
    np.testing.assert_allclose(r.ball, s.ball, atol=1e-8)
    b = _ballbar(phis=(0, 120, 240))
    b.dL = np.linspace(-1e-3, 1e-3, len(b.t))
    write_ballbar_csv(tmp_path / "b.csv", b)
    lines = (tmp_path / "b.csv").read_text().splitlines()
    assert lines[0] == "t,rpm,angle,dir,phi,L0,dL" and lines[1].split(",")[3] == "1"
    c = read_ballbar_csv(tmp_path / "b.csv")
    for name in ("t", "rpm", "angle", "phi", "L0", "dL"):
        np.testing.assert_allclose(getattr(c, name), getattr(b, name), atol=1e-7, err_msg=name)
    assert c.direction.tolist() == b.direction.tolist() and c.direction.dtype.kind == "i"
    lines[3] = lines[3].replace(",-1,", ",0,").replace(",1,", ",0,")
    (tmp_path / "bad.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError) as exc:
        read_ballbar_csv(tmp_path / "bad.csv")
    assert str(exc.value) == f"{tmp_path / 'bad.csv'}, row 3, column 'dir': dir must be +1 or -1"


def test_report_summary_in_display_units():
    from camsmooth.machine.calibration import CalibrationReport
    from camsmooth.machine.model import ErrorModel

    r = CalibrationReport(kind="probe", model=ErrorModel(), parameters={"EY0A": 0.0125, "EB0A": -2.5e-5,
                                                                        "theta1": math.pi / 4, "tau": 30.0},
                          uncertainties={"EY0A": 0.0005, "EB0A": 1e-6, "theta1": math.pi / 180},
                          units={"EY0A": "mm", "EB0A": "rad", "theta1": "rad", "tau": "s"},
                          unidentifiable={"EZ0T": "confounded with EZ0A"}, rms_before=0.0042, rms_after=0.00051,
                          singular_values=np.array([120.0, 3.5, 0.25]), condition_number=480.0, n_observations=24)
    lines = r.summary().split("\n")
    assert lines[0] == "calibration: probe  (24 observations)"
    assert lines[1] == "  residual RMS before 4.2000 um, after 0.5100 um"
    assert lines[2] == "  parameter             value              std. uncertainty"
    # mm -> um, rad -> urad, phases (theta...) in degrees; other units as given; no uncertainty: nan
    assert lines[3].split() == ["EY0A", "12.5", "um", "+-", "0.5"]
    assert lines[4].split() == ["EB0A", "-25", "urad", "+-", "1"]
    assert lines[5].split() == ["theta1", "45", "deg", "+-", "1"]
    assert lines[6].split() == ["tau", "30", "s", "+-", "nan"]
    assert lines[7] == ("  identification Jacobian (um per um / urad): singular values [120, 3.5, 0.25], "
                        "condition number 480")
    assert lines[8:] == ["  not determinable from these data (not fitted):", "    EZ0T: confounded with EZ0A"]
    r.singular_values = np.arange(13.0, 0.0, -1.0)   # more than 12: the range only
    r.residual_unit, r.rms_before, r.rms_after, r.unidentifiable = "deg", 0.5, 0.125, {}
    lines = r.summary().split("\n")
    assert lines[1] == "  residual RMS before 0.5 deg, after 0.125 deg"
    assert lines[-1].endswith("singular values (13 values, 13 ... 1), condition number 480")
    r.singular_values = np.arange(12.0, 0.0, -1.0)   # twelve are listed
    assert r.summary().split("\n")[-1].count(", ") == 12
