"""The diagnosis terms on a five-axis recording (camsmooth.diagnosis.terms): which parameters
each term offers (names, units from the error model's own table, groups, optional higher-order
parts), where a term does not apply and why, how parameters land in the error model, the states
reported, and the starting points against closed forms: a residual that is exactly a lag or a
clock offset gives that lag or offset back, and one Gauss-Newton step recovers a tool-length
error that enters linearly."""

from __future__ import annotations

import copy
import dataclasses
import math
import re

import numpy as np
import pytest

from benchmarks.synthetic import make_program, record
from camsmooth.diagnosis.problem import prepare
from camsmooth.diagnosis.terms import term
from camsmooth.machine.model import GEOMETRIC_PARAMETERS, ErrorModel

NOISE = {"axes": 1e-6, "tip": 1e-6, "rotary": 1e-8, "axis": 1e-8}


@pytest.fixture(scope="module")
def P():
    prog = make_program("rotary", duration=4.0, rate=50.0, seed=2, spindle=6000.0)
    return prepare(prog, record(prog, {"EZ0T": 0.05}, channels=("axes", "tip", "axis"), noise=NOISE, seed=1))


@pytest.fixture(scope="module")
def P_axes_only():
    prog = make_program("rotary", duration=4.0, rate=50.0, seed=2, spindle=0.0)
    return prepare(prog, record(prog, {}, channels=("axes",), noise=NOISE, seed=1))


def _names(t, P):
    return [p.name for p in term(t).params(P)]


def test_parameters_offered_on_a_five_axis_program(P):
    assert _names("servo_lag", P) == ["tau_X", "tau_Y", "tau_Z", "tau_A", "tau_B"]
    assert _names("backlash", P) == ["b_X", "b_Y", "b_Z", "b_A", "b_B"]
    assert _names("rotary_location", P) == ["EY0A", "EZ0A", "EX0B", "EZ0B"]
    assert _names("rotary_squareness", P) == ["EB0A", "EC0A", "EA0B", "EC0B"]
    assert _names("spindle_tilt", P) == ["EA0S", "EB0S"]
    assert _names("tool_length", P) == ["EZ0T"]
    assert _names("spindle_runout", P) == ["rc", "rs"]
    assert _names("linear_positioning", P) == [f"E{a}{a}{k}" for a in "XYZ" for k in ("", "2", "3")]
    assert _names("linear_straightness", P) == [f"E{b}{a}{k}" for a in "XYZ" for b in "XYZ" if b != a
                                                for k in ("2", "3")]
    assert _names("linear_squareness", P) == ["EC0Y", "EB0Z", "EA0Z"]
    for name in ("rotary_location", "rotary_squareness", "spindle_tilt", "tool_length", "linear_positioning",
                 "linear_straightness", "linear_squareness"):
        for p in term(name).params(P):
            assert p.unit == GEOMETRIC_PARAMETERS[p.name][0], p   # the model's own unit for it
            assert p.lo == -p.hi and p.hi > 0 and p.scale > 0
            # the higher-order parts (pitch and cubic of positioning, cubic of straightness, whose
            # leading part is quadratic) are dropped on their own; the leading ones are not
            higher = {"linear_positioning": "23", "linear_straightness": "3"}.get(name, "")
            assert p.optional == (p.name[-1] in higher if higher else False), p
    groups = {p.name: p.group for t in ("rotary_location", "linear_straightness", "backlash", "servo_lag")
              for p in term(t).params(P)}
    assert groups["EZ0A"] == "A" and groups["EX0B"] == "B" and groups["EZY3"] == "Y in Z"
    assert groups["b_A"] == "A" and groups["tau_Z"] == "Z"
    units = {p.name: p.unit for t in ("backlash", "servo_lag", "spindle_runout", "time_offset")
             for p in term(t).params(P)}
    assert (units["b_X"], units["b_A"], units["tau_A"], units["rc"], units["offset_s"]) == ("mm", "rad", "s", "mm", "s")


def test_where_a_term_does_not_apply_and_why(P, P_axes_only):
    assert term("tool_length").applicable(P_axes_only) == "needs measured tool-tip or tool-axis channels"
    assert term("spindle_runout").applicable(P_axes_only) == "needs measured tool-tip channels"
    assert term("thermal_drift").applicable(P_axes_only) == "needs measured tool-tip or tool-axis channels"
    knots = copy.copy(P.knots)   # a plain object: a shallow copy with the spindle stopped
    knots.S = np.zeros_like(P.knots.S)
    no_spindle = dataclasses.replace(P, knots=knots)
    assert term("spindle_runout").applicable(no_spindle) == "the spindle does not turn in the program"
    assert term("thermal_machine").applicable(no_spindle) == "the spindle does not turn in the program"
    for name in ("servo_lag", "time_offset", "backlash", "spindle_runout", "thermal_drift", "rotary_location"):
        assert term(name).applicable(P) is None, name


def test_parameters_land_in_the_error_model():
    m = ErrorModel()
    term("servo_lag").write(m, ["tau_X", "tau_B"], [0.02, 0.05])
    term("backlash").write(m, ["b_Y", "b_A"], [0.01, 1e-4])
    term("time_offset").write(m, ["offset_s"], [0.003])
    term("spindle_runout").write(m, ["rc", "rs"], [0.002, -0.001])
    term("tool_length").write(m, ["EZ0T"], [0.05])
    term("thermal_drift").write(m, ["gain_dz", "tau_dz"], [0.01, 40.0])
    assert m.tau == {"X": 0.02, "B": 0.05} and m.backlash == {"Y": 0.01, "A": 1e-4}
    assert (m.offset_s, m.runout, m.geometric["EZ0T"]) == (0.003, (0.002, -0.001), 0.05)
    assert m.thermal["dz"] == {"gain": 0.01, "tau": 40.0}
    assert term("servo_lag").read(m, ["tau_X", "tau_Y"]).tolist() == [0.02, 0.0]
    assert term("backlash").read(m, ["b_A", "b_X"]).tolist() == [1e-4, 0.0]
    assert term("thermal_drift").read(m, ["gain_dz", "tau_dz", "gain_dx"]).tolist() == [0.01, 40.0, 0.0]
    assert math.isnan(term("thermal_drift").read(m, ["tau_dx"])[0])
    assert term("time_offset").read(m, ["offset_s"]).tolist() == [0.003]
    assert term("spindle_runout").read(m, ["rc", "rs"]).tolist() == [0.002, -0.001]
    assert term("tool_length").read(m, ["EZ0T", "EX0S"]).tolist() == [0.05, 0.0]


def test_lag_and_clock_offset_starting_points_from_an_exact_residual(P):
    # a residual that is exactly -tau v on the X axis channel: the starting lag is tau
    resid = np.zeros_like(P.data_fit)
    jx = P.channels.index("X_act")
    resid[:, jx] = -0.03 * P.states["v_X"]
    x = term("servo_lag").initial(P, ErrorModel(), ["tau_X", "tau_Y"], resid)
    assert x[0] == pytest.approx(0.03, rel=1e-9) and x[1] == 0.0
    # a lag already in the model is kept
    assert term("servo_lag").initial(P, ErrorModel(tau={"X": 0.1}), ["tau_X"], resid)[0] == 0.1
    # a residual that is -d v on every moving axis: the recording runs d behind, from 1 ms already in the model
    d = 0.004
    for a in "XYZAB":
        resid[:, P.channels.index(f"{a}_act")] = -d * P.states[f"v_{a}"]
    model = ErrorModel()
    model.offset_s = 0.001
    assert term("time_offset").initial(P, model, ["offset_s"], resid)[0] == pytest.approx(0.001 + d, rel=1e-9)


def test_one_gauss_newton_step_recovers_a_linear_effect(P):
    # the recording has a tool 0.05 mm long: the tip moves along the axis, linearly in EZ0T
    x = term("tool_length").initial(P, P.base.copy(), ["EZ0T"], np.zeros_like(P.data_fit))
    assert x[0] == pytest.approx(0.05, abs=1e-5)


def test_states_the_report_plots_against(P):
    label, values, unit = term("servo_lag").state(P, ["tau_X", "tau_A"])
    k = max(("X", "A"), key=lambda a: np.std(P.states[f"v_{a}"]))
    assert unit == ("deg/s" if k == "A" else "mm/s") and label == f"commanded velocity {k} ({unit})"
    np.testing.assert_allclose(values, P.states[f"v_{k}"] * (180 / math.pi if k == "A" else 1.0))
    assert term("backlash").state(P, ["b_Y"])[0] == "last direction of Y (-1/+1)"
    label, values, unit = term("tool_length").state(P, ["EZ0T"])
    assert (label, unit) == ("rotary axis A (deg)", "deg")
    np.testing.assert_allclose(values, np.degrees(P.states["pos_A"]))
    assert term("linear_positioning").state(P, ["EYY2"])[0] == "commanded position Y (mm)"
    assert term("linear_straightness").state(P, ["EXZ2"])[0] == "commanded position Z (mm)"
    assert term("linear_squareness").state(P, ["EC0Y"])[0] == "commanded position Y (mm)"
    assert term("linear_squareness").state(P, ["EA0Z"])[0] == "commanded position Z (mm)"
    label, values, unit = term("spindle_runout").state(P, ["rc", "rs"])
    assert (label, unit) == ("spindle angle (deg, mod 360)", "deg") and values.min() >= 0 and values.max() < 360
    assert term("thermal_drift").state(P, ["gain_dz"])[0] == "elapsed time (s)"


def test_refusals_of_fitted_values(P):
    t = term("time_offset")
    period = P.dt
    assert t.unresolvable(P, ["offset_s"], [0.05 * period], [0.0]).startswith(
        f"the fitted clock offset {0.05 * period * 1e6:.3g} us is below 0.1 of the sample period")
    assert t.unresolvable(P, ["offset_s"], [0.5 * period], [0.0]) is None
    # a geometric error whose effect stays below a 10 um quantisation step of every tip channel
    Q = dataclasses.replace(P, floor_info={c: dict(v, q_recording_rms=0.01) for c, v in P.floor_info.items()})
    why = term("tool_length").unresolvable(Q, ["EZ0T"], np.array([1e-4]), np.array([1e-5]))
    assert re.fullmatch(r"its largest effect \(0\.1 um on tip_[xyz]\) stays below the recording's resolution "
                        r"\(10 um\)", why), why
    assert term("tool_length").unresolvable(Q, ["EZ0T"], np.array([0.05]), np.array([1e-5])) is None
    assert term("tool_length").unresolvable(P, ["EZ0T"], np.array([1e-4]), np.array([1e-5])) is None


@pytest.fixture(scope="module")
def P_warm():
    """The spindle grows 0.01 mm per 1000 rpm along the tool axis with a 1 s time constant."""
    prog = make_program("rotary", duration=4.0, rate=50.0, seed=2, spindle=6000.0)
    truth = {"thermal_dz_gain": 0.01, "thermal_dz_tau": 1.0}
    return prepare(prog, record(prog, truth, channels=("axes", "tip", "axis"), noise=NOISE, seed=1))


def test_thermal_growth_is_found_in_the_spindle_frame_with_a_start_near_the_truth(P_warm):
    t = term("thermal_drift")
    assert t.elements(P_warm) == ["dx", "dy", "dz", "exz", "eyz"]
    assert t.select_elements(P_warm, P_warm.base) == ["dz"]
    span = float(P_warm.t[-1] - P_warm.t[0])
    (tau_lo, tau_hi), = [(p.lo, p.hi) for p in t.params(P_warm) if p.name == "tau_dz"]
    # a time constant below 5% of the record cannot be told from an offset; at most 20 records
    assert (tau_lo, tau_hi) == pytest.approx((0.05 * span, 20 * span))
    names = [p.name for p in t.params(P_warm)]
    assert names == ["gain_dz", "tau_dz"]
    x0 = t.initial(P_warm, ErrorModel(), names, None)
    assert x0[0] == pytest.approx(0.01, rel=0.2) and 0.5 <= x0[1] <= 2.0
    # a fitted time constant on its lower bound is a step, not a drift
    lo = 0.05 * span
    assert t.veto(P_warm, names, [0.01, lo]) == (
        f"the fitted time constant of dz sits on its lower bound ({lo:.3g} s, 5% of the record): a step, not a "
        "drift; it cannot be told from a constant offset")
    assert t.veto(P_warm, names, [0.01, 1.0]) is None
    # the machine frame sees only tip elements
    assert term("thermal_machine").elements(P_warm) == ["mx", "my", "mz"]


def test_interface_defaults_of_a_new_term(P):
    from camsmooth.diagnosis.terms.base import Term

    class Plain(Term):
        name = "plain"

    t = Plain()
    assert t.applicable(P) is None and t.jacobian(P, ErrorModel(), ["a"]) is None
    assert t.unresolvable(P, ["a"], [1.0], [0.1]) is None and t.veto(P, ["a"], [1.0]) is None
    par, unc, unit = t.report(["a", "b"], np.array([1.5, -2.0]), np.array([0.25, 0.5]))
    assert par == {"a": 1.5, "b": -2.0} and unc == {"a": 0.25, "b": 0.5} and unit == {"a": "", "b": ""}
    assert all(type(v) is float for v in (*par.values(), *unc.values()))
    label, values, unit = t.state(P, ["a"])
    assert (label, unit) == ("elapsed time (s)", "s")
    np.testing.assert_array_equal(values, P.states["elapsed"])


def test_travel_is_the_largest_commanded_position_and_at_least_1_mm(P):
    from camsmooth.diagnosis.terms.base import travel

    prog = make_program("rotary", duration=4.0, rate=50.0, seed=2, spindle=6000.0)
    for a in "XYZ":
        assert travel(P, a) == pytest.approx(max(1.0, float(np.max(np.abs(prog.axes[a])))))
    assert travel(P, "W") == 1.0   # an axis the program does not have
    small = dataclasses.replace(P, knots=copy.copy(P.knots))
    small.knots.u = {**P.knots.u, "X": 0.25 * np.sin(np.linspace(0, 3, len(P.knots.u["X"])))}
    assert travel(small, "X") == 1.0


def test_bounds_follow_the_record_whatever_its_start_time(P_warm):
    from camsmooth.diagnosis.terms.base import channel_is_length

    late = dataclasses.replace(P_warm, t=P_warm.t + 100.0, memo={"thermal:thermal_drift": ["dz", "exz"]})
    span = float(P_warm.t[-1] - P_warm.t[0])
    params = {p.name: p for p in term("thermal_drift").params(late)}
    assert list(params) == ["gain_dz", "tau_dz", "gain_exz", "tau_exz"]
    assert (params["tau_dz"].lo, params["tau_dz"].hi) == pytest.approx((0.05 * span, 20 * span))
    assert (params["gain_dz"].unit, params["gain_exz"].unit, params["tau_exz"].unit) == \
        ("mm/1000rpm", "rad/1000rpm", "s")
    assert params["gain_exz"].group == "exz" and params["gain_dz"].lo == -params["gain_dz"].hi
    assert params["gain_exz"].hi < params["gain_dz"].hi   # a tilt (rad) bounded tighter than a length (mm)
    (off,) = term("time_offset").params(late)
    assert (off.lo, off.hi, off.unit, off.group) == (pytest.approx(-span / 4), pytest.approx(span / 4), "s", "clock")
    runout = term("spindle_runout").params(late)
    assert [(p.name, p.unit, p.group) for p in runout] == [("rc", "mm", "runout"), ("rs", "mm", "runout")]
    assert [c for c in late.channels if channel_is_length(c)] == ["X_act", "Y_act", "Z_act", "tip_x", "tip_y",
                                                                  "tip_z"]
    # with no element chosen yet, the start is no gain and a fifth of the record
    fresh = dataclasses.replace(late, memo={"thermal:thermal_drift": ["dz"]})
    x = term("thermal_drift").initial(fresh, ErrorModel(), ["gain_dz", "tau_dz"], None)
    assert x.tolist() == pytest.approx([0.0, 0.2 * span])
    kept = ErrorModel(thermal={"dz": {"gain": 0.02, "tau": 3.0}})
    assert term("thermal_drift").initial(fresh, kept, ["gain_dz", "tau_dz"], None).tolist() == [0.02, 3.0]


def test_lag_start_without_a_usable_axis_channel(P):
    t = term("servo_lag")
    resid = np.zeros_like(P.data_fit)
    jx = P.channels.index("X_act")
    blind = dataclasses.replace(P, valid_fit=P.valid_fit.copy())
    blind.valid_fit[:, jx] = False   # no valid sample on X: the 10 ms default
    assert t.initial(blind, ErrorModel(), ["tau_X"], resid).tolist() == [0.01]
    resid[:, jx] = 5.0 * P.states["v_X"]   # a lead, not a lag: clipped at 0
    assert t.initial(P, ErrorModel(), ["tau_X"], resid).tolist() == [0.0]
    resid[:, jx] = -3.0 * P.states["v_X"]   # 3 s: clipped at 1 s
    assert t.initial(P, ErrorModel(), ["tau_X"], resid).tolist() == [1.0]
    tip_only = dataclasses.replace(P, channels=tuple(c for c in P.channels if not c.endswith("_act")))
    assert t.initial(tip_only, ErrorModel(), ["tau_X", "tau_B"], resid).tolist() == [0.01, 0.01]
    assert t.initial(tip_only, ErrorModel(tau={"B": 0.2}), ["tau_B"], resid).tolist() == [0.2]


def test_gauss_newton_start_from_a_non_zero_value_and_at_the_bounds():
    prog = make_program("rotary", duration=4.0, rate=50.0, seed=2, spindle=6000.0)
    t = term("tool_length")
    for truth in (0.05, 6.0, -6.0):   # the bound of EZ0T is 5 mm
        P = prepare(prog, record(prog, {"EZ0T": truth}, channels=("axes", "tip", "axis"), noise=NOISE, seed=1))
        x = t.initial(P, ErrorModel({"EZ0T": 0.02}), ["EZ0T"], None)[0]
        if abs(truth) < 5:
            assert x == pytest.approx(truth, abs=1e-5)
        else:
            assert abs(x) < 5.0 and abs(x) == pytest.approx(5.0, abs=1e-9) and np.sign(x) == np.sign(truth)


def test_states_pick_the_axis_that_shows_the_effect(P):
    std = {a: float(np.std(P.states[f"v_{a}"])) for a in "XYZAB"}
    # among the names, the axis whose commanded velocity varies most (whatever the names' order)
    for pair in (("X", "Y"), ("Y", "Z"), ("X", "Z"), ("A", "B")):
        names = [f"tau_{a}" for a in sorted(pair, key=lambda a: std[a])]   # the larger spread last
        label, values, unit = term("servo_lag").state(P, names[::-1])
        k = names[-1][4:]
        rot = k in "AB"
        assert (label, unit) == (f"commanded velocity {k} ({'deg/s' if rot else 'mm/s'})", "deg/s" if rot else "mm/s")
        np.testing.assert_allclose(values, P.states[f"v_{k}"] * (180 / math.pi if rot else 1.0))
    k = max((a for a in "XYZAB"), key=lambda a: std[a])
    label, values, unit = term("time_offset").state(P, ["offset_s"])
    assert (label, unit) == (f"commanded velocity {k}", "mm/s")
    np.testing.assert_array_equal(values, P.states[f"v_{k}"])
    assert term("linear_positioning").state(P, ["EZZ3"])[2] == "mm"
    # rotary states: the first rotary axis that moves, else elapsed time
    knots = copy.copy(P.knots)
    knots.u = {**P.knots.u, "A": np.zeros_like(P.knots.u["A"])}
    only_b = dataclasses.replace(P, knots=knots)
    assert term("spindle_tilt").state(only_b, ["EA0S"])[0] == "rotary axis B (deg)"
    knots2 = copy.copy(knots)
    knots2.u = {**knots.u, "B": np.zeros_like(P.knots.u["B"])}
    still = dataclasses.replace(P, knots=knots2)
    label, values, unit = term("rotary_location").state(still, ["EY0A"])
    assert (label, unit) == ("elapsed time (s)", "s")
    np.testing.assert_array_equal(values, P.states["elapsed"])


def test_linear_terms_use_the_exact_columns(P):
    from camsmooth.diagnosis.terms.linear import linear_jacobian

    model = ErrorModel({"EXX": 1e-4})
    for name, names in (("linear_positioning", ["EXX", "EYY2"]), ("linear_straightness", ["EYX2"]),
                        ("linear_squareness", ["EC0Y", "EA0Z"])):
        np.testing.assert_array_equal(term(name).jacobian(P, model, names), linear_jacobian(P, model, names))


def test_backlash_bounds_and_steps_in_each_axis_units(P):
    params = {p.name: p for p in term("backlash").params(P)}
    for a in "XYZ":
        for r in "AB":
            # 0.2 rad and 1e-5 rad against 10 mm and 1e-3 mm: the rotary ones are the smaller numbers
            assert params[f"b_{r}"].hi < params[f"b_{a}"].hi and params[f"b_{r}"].scale < params[f"b_{a}"].scale
            assert params[f"b_{r}"].lo == -params[f"b_{r}"].hi < 0 and params[f"b_{a}"].lo == -params[f"b_{a}"].hi


def test_clock_offset_start_without_axis_channels(P):
    tip_only = dataclasses.replace(P, channels=tuple(c for c in P.channels if not c.endswith("_act")))
    model = ErrorModel()
    model.offset_s = 0.002
    resid = np.ones_like(P.data_fit)
    assert term("time_offset").initial(tip_only, model, ["offset_s"], resid).tolist() == [0.002]
    model.offset_s = 50.0   # beyond a quarter of the record: clipped to it
    span = float(P.t[-1] - P.t[0])
    assert term("time_offset").initial(tip_only, model, ["offset_s"], resid).tolist() == [pytest.approx(span / 4)]
    model.offset_s = -50.0
    assert term("time_offset").initial(tip_only, model, ["offset_s"], resid).tolist() == [pytest.approx(-span / 4)]


def test_unresolvable_names_the_channel_where_the_effect_is_largest_against_its_step(P):
    t = term("tool_length")
    q = {"tip_x": 0.004, "tip_y": 0.02, "tip_z": 0.05}
    Q = dataclasses.replace(P, floor_info={c: dict(v, q_recording_rms=q.get(c, 0.0)) for c, v in P.floor_info.items()})
    m = P.base.copy()
    m.geometric["EZ0T"] = 1e-3
    d = P.sim_fit.run(m) - P.sim_fit.run(P.base)
    peaks = {c: float(np.max(np.abs(d[:, P.channels.index(c)]))) for c in q}
    assert all(peaks[c] < q[c] for c in q)
    worst = max(q, key=lambda c: peaks[c] / q[c])
    assert t.unresolvable(Q, ["EZ0T"], np.array([1e-3]), np.array([1e-5])) == (
        f"its largest effect ({peaks[worst] * 1e3:.3g} um on {worst}) stays below the recording's resolution "
        f"({q[worst] * 1e3:.3g} um)")


def test_thermal_element_fit_recovers_an_exact_response(P):
    t = term("thermal_drift")
    late = dataclasses.replace(P, t=P.t + 50.0, memo={})
    span = float(P.t[-1] - P.t[0])
    grid = t._tau_grid(late)
    assert grid == sorted(grid) and grid[0] > 0.05 * span and grid[-1] >= 3 * span   # from a step to a ramp
    np.testing.assert_allclose(np.diff(np.log(grid[2:])), math.log(2.0))           # doubling
    base = P.base.copy()
    for el, gain in (("dz", 0.02), ("exz", 2e-4)):
        tau = grid[3]
        m = base.copy()
        m.thermal[el] = {"gain": gain, "tau": tau}
        resid = P.sim_fit.run(m) - P.sim_fit.run(base)
        g, tau_fit, drop, z = t._element_fit(late, el, resid, base)
        # a length enters linearly (exact); a tilt through the rotation, linear to 1e-5 at this size
        tol = 1e-9 if el == "dz" else 1e-4
        assert g == pytest.approx(gain, rel=tol) and tau_fit == tau and drop == pytest.approx(1.0, abs=tol)
        assert z > 100
        memo = dataclasses.replace(late, data_fit=P.sim_fit.run(m), memo={})
        assert t.select_elements(memo, base) == [el]
        assert memo.memo["thermal_init:thermal_drift"][el] == (pytest.approx(gain, rel=tol), tau)
    quiet = dataclasses.replace(late, data_fit=P.sim_fit.run(base), memo={})
    assert len(t.select_elements(quiet, base)) == 1   # nothing to see: the strongest one is still scored


@pytest.mark.parametrize("name", ["rotary_location", "rotary_squareness", "spindle_tilt", "tool_length",
                                  "linear_positioning", "linear_straightness", "linear_squareness"])
def test_finite_difference_steps_are_a_typical_small_effect(P, name):
    """Each geometric parameter's scale (finite-difference steps are 1e-4 of it; identifiability
    compares columns of one scale step) moves the tool tip by 1 nm to 10 micrometres over the
    program: comparable columns, far above rounding."""
    tip = [P.channels.index(c) for c in ("tip_x", "tip_y", "tip_z")]
    s0 = P.sim_fit.run(P.base)
    for p in term(name).params(P):
        m = P.base.copy()
        m.geometric[p.name] = p.scale
        peak = float(np.max(np.abs((P.sim_fit.run(m) - s0)[:, tip])))
        assert 1e-6 <= peak <= 1e-2, (p.name, peak)
