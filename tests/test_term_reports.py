"""What the diagnosis report says about each term (camsmooth.diagnosis.terms): the unit
conversions of ``report`` (Kv = 1/tau with its propagated uncertainty, radians to degrees,
runout radius and phase from its two components) computed here by hand, and the sentences a
user reads, written out in full."""

from __future__ import annotations

import math

import pytest

from camsmooth.diagnosis.terms import SEPARATING, separating_measurement, term
from camsmooth.diagnosis.terms.base import fmt, none_text


def test_number_formatting():
    assert fmt(None) == "n/a" and fmt(float("inf"), "mm") == "n/a" and fmt(float("nan")) == "n/a"
    assert fmt(0.0, "mm") == "0 mm" and fmt(0.0123456, "mm") == "0.0123 mm" and fmt(-1234.5) == "-1.23e+03"
    assert fmt(0.001) == "0.001" and fmt(0.000999, "rad") == "9.99e-04 rad" and fmt(-2e-7) == "-2.00e-07"
    assert none_text([]) == "" and none_text(["X", "A"]) == "; none measurable on X, A"


def test_servo_lag_reports_the_gain_kv_as_one_over_tau():
    t = term("servo_lag")
    par, unc, unit = t.report(["tau_X", "tau_A", "tau_Z"], [0.02, 0.0, 0.05], [0.001, 0.1, float("inf")])
    # Kv = 1 / tau; sd(Kv) = sd(tau) / tau^2 (first-order propagation); tau = 0: no gain
    assert par == {"Kv_X": pytest.approx(50.0), "Kv_A": None, "Kv_Z": pytest.approx(20.0)}
    assert unc == {"Kv_X": pytest.approx(2.5), "Kv_A": None, "Kv_Z": None}
    assert unit == {"Kv_X": "1/s", "Kv_A": "1/s", "Kv_Z": "1/s"}
    assert t.sentence({"Kv_X": 50.0, "Kv_A": None}, {"Kv_X": 2.5}, ["Y"]) == \
        "X lags its command by v/Kv with Kv = 50 ± 2.5 1/s; none measurable on Y"
    assert t.sentence({"Kv_X": 50.0, "Kv_Z": 20.0}, {"Kv_X": 2.5, "Kv_Z": 0.5}, []) == \
        "X, Z lag their command by v/Kv with Kv = 50 ± 2.5, 20 ± 0.5 1/s"


def test_backlash_reports_mm_for_linear_and_degrees_for_rotary_axes():
    t = term("backlash")
    par, unc, unit = t.report(["b_X", "b_A"], [0.01, math.radians(0.5)], [0.001, math.radians(0.02)])
    assert par == {"backlash_X": pytest.approx(0.01), "backlash_A": pytest.approx(0.5)}
    assert unc == {"backlash_X": pytest.approx(0.001), "backlash_A": pytest.approx(0.02)}
    assert unit == {"backlash_X": "mm", "backlash_A": "deg"}
    assert t.sentence({"backlash_X": 0.01, "backlash_A": 0.5}, {"backlash_X": 0.001, "backlash_A": 0.02}, ["Z"]) == \
        "The axes lose motion at each reversal (backlash X 0.01 mm ± 0.001 mm, A 0.5 deg ± 0.02 deg; " \
        "none measurable on Z)"


def test_time_offset_sentence_says_behind_or_ahead():
    t = term("time_offset")
    assert t.report(["offset_s"], [0.012], [5e-4]) == ({"offset_s": 0.012}, {"offset_s": 5e-4}, {"offset_s": "s"})
    assert t.sentence({"offset_s": 0.012}, {"offset_s": 5e-4}, []) == \
        "The recording runs 12 ± 0.5 ms behind the program's clock"
    assert t.sentence({"offset_s": -0.003}, {"offset_s": 1e-3}, []) == \
        "The recording runs -3 ± 1 ms ahead of the program's clock"
    assert t.sentence({"offset_s": 0.0}, {"offset_s": 1e-3}, []).endswith(" behind the program's clock")


def test_spindle_runout_radius_and_phase_from_its_components():
    t = term("spindle_runout")
    # components (rc, rs) = (0.003, 0.004) mm: radius 0.005 mm at atan2(4, 3) = 53.13 deg
    par, unc, unit = t.report(["rc", "rs"], [0.003, 0.004], [0.0005, 0.0005])
    assert par["radius"] == pytest.approx(0.005) and par["phase_deg"] == pytest.approx(math.degrees(math.atan2(4, 3)))
    sr = math.hypot(0.003 * 0.0005, 0.004 * 0.0005) / 0.005
    assert unc["radius"] == pytest.approx(sr) and unc["phase_deg"] == pytest.approx(math.degrees(sr / 0.005))
    assert unit == {"radius": "mm", "phase_deg": "deg"}
    par, unc, _ = t.report(["rc", "rs"], [0.0, 0.0], [0.0002, 0.0007])   # no runout: no phase
    assert par["radius"] == 0.0 and unc["radius"] == 0.0007 and unc["phase_deg"] is None
    assert t.sentence({"radius": 0.005, "phase_deg": 53.13}, {}, []) == \
        "The tool tip runs out at 1x spindle revolution with radius 0.005 mm at phase 53.1 deg"


def test_thermal_terms_report_gain_and_time_constant_per_element():
    t = term("thermal_drift")
    names = ["gain_dz", "tau_dz", "gain_exz", "tau_exz"]
    par, unc, unit = t.report(names, [0.02, 600.0, 1e-5, 300.0], [0.001, 30.0, 1e-6, 20.0])
    assert par == {"dz_gain": 0.02, "dz_tau": 600.0, "exz_gain": 1e-5, "exz_tau": 300.0}
    assert unc == {"dz_gain": 0.001, "dz_tau": 30.0, "exz_gain": 1e-6, "exz_tau": 20.0}
    assert unit == {"dz_gain": "mm per 1000 rpm", "dz_tau": "s", "exz_gain": "rad per 1000 rpm", "exz_tau": "s"}
    assert t.sentence(par, unc, ["dx"]) == ("The spindle grows thermally (dz gain 0.02 per 1000 rpm, tau 600 s; "
                                            "exz gain 1.00e-05 per 1000 rpm, tau 300 s; none measurable on dx)")
    m = term("thermal_machine")
    assert m.sentence({"mx_gain": 0.5, "mx_tau": 90.0}, {}, []) == \
        "The machine's axes and column grow thermally, in the machine frame (mx gain 0.5 per 1000 rpm, tau 90 s)"


def test_geometric_terms_report_in_the_parameters_units():
    t = term("tool_length")
    assert t.report(["EZ0T"], [0.05], [0.002]) == ({"EZ0T": 0.05}, {"EZ0T": 0.002}, {"EZ0T": "mm"})
    assert t.sentence({"EZ0T": 0.05}, {}, []) == "The tool length is off (EZ0T = 0.05 mm)"
    r = term("rotary_squareness")
    assert r.report(["EB0A", "EC0B"], [1e-4, -2e-4], [1e-5, 1e-5])[2] == {"EB0A": "rad", "EC0B": "rad"}
    assert r.sentence({"EB0A": 1e-4}, {}, ["B"]) == \
        "The rotary axes are tilted from their nominal directions (EB0A = 1.00e-04 rad; none measurable on B)"
    p = term("linear_positioning")
    assert p.sentence({"EXX": 3.3e-3, "EXX2": -2e-6, "EYY3": 1e-9}, {"EXX": 1e-4}, ["Z"]) == (
        "The linear axes position off their scale (EXX 3.3 ± 0.1 um per mm of travel, EXX2 = -2e-06 1/mm (pitch), "
        "EYY3 = 1e-09 1/mm^2 (pitch); none measurable on Z)")
    assert p.sentence({"EYY": 1e-3}, {}, []) == \
        "The linear axes position off their scale (EYY 1 ± 0 um per mm of travel)"


def test_separating_measurements_are_symmetric_with_a_generic_fallback():
    assert separating_measurement("backlash", "servo_lag") == separating_measurement("servo_lag", "backlash") == \
        SEPARATING[frozenset({"servo_lag", "backlash"})]
    assert separating_measurement("tool_length", "thermal_machine").startswith(
        "a program that moves the machine through states where the two predictions differ")
