"""The merged machine model (issue 11): linear-axis geometric errors against closed forms, the one
first-order integrator against the closed form for a step and a ramp, the space Jacobian from
the screws against finite differences, the servo/runout sections of the one JSON format, and
type errors in a model file named by file and key."""

from __future__ import annotations

import json
import math

import casadi as ca
import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import load_machine, space_jacobian
from camsmooth.machine.model import (
    ErrorModel,
    compensate,
    first_order_between,
    first_order_knots,
    first_order_response,
    interval_slopes,
)


@pytest.fixture(scope="module")
def machine():
    return load_machine()


LINEAR = {"EXX": 3.3e-3, "EXX2": -2e-6, "EYY3": 1e-9, "EYX2": 4e-7, "EZY3": -2e-9, "EXZ2": 5e-7,
          "EC0Y": 50e-6, "EB0Z": -30e-6, "EA0Z": 20e-6}


def _closed_form_tip(A, B, X, Y, Z, L):
    """Nominal AB head (METHODS section 1) with the linear errors written out by hand."""
    g = LINEAR
    Xr = X + g["EXX"] * X + g["EXX2"] * X ** 2
    Yr = Y + g["EYY3"] * Y ** 3
    Zr = Z
    carriage = (Xr * np.array([1.0, 0, 0])[:, None]
                + Yr * np.array([-math.sin(g["EC0Y"]), math.cos(g["EC0Y"]), 0.0])[:, None]
                + Zr * np.array([math.sin(g["EB0Z"]), -math.sin(g["EA0Z"]) * math.cos(g["EB0Z"]),
                                 math.cos(g["EA0Z"]) * math.cos(g["EB0Z"])])[:, None])
    carriage[1] += g["EYX2"] * X ** 2
    carriage[2] += g["EZY3"] * Y ** 3
    carriage[0] += g["EXZ2"] * Z ** 2
    T = np.stack([np.sin(B), -np.sin(A) * np.cos(B), np.cos(A) * np.cos(B)])
    return (carriage - L * T).T


def test_linear_axis_errors_against_the_closed_form(machine):
    rng = np.random.default_rng(0)
    A, B = np.radians(rng.uniform(-60, 60, (2, 30)))
    X, Y, Z = rng.uniform(-400, 400, (3, 30))
    tip, _ = ErrorModel(dict(LINEAR)).apply(machine).tool_pose_np(A, B, X, Y, Z)
    assert np.allclose(tip, _closed_form_tip(A, B, X, Y, Z, machine.pivot), rtol=0, atol=1e-10)


def test_real_chain_numpy_and_casadi_agree(machine):
    real = ErrorModel(dict(LINEAR), thermal={}).apply(machine, thermal_state={"mz": 0.01, "dz": 0.002})
    q = ca.SX.sym("q", 5)
    tip, axis = real.tool_pose(q[0], q[1], q[2], q[3], q[4])
    f = ca.Function("f", [q], [ca.vertcat(*tip, *axis)])
    vals = np.array([0.3, -0.2, 120.0, -80.0, 40.0])
    t_np, a_np = real.tool_pose_np(*[np.array([v]) for v in vals])
    got = np.asarray(f(vals)).ravel()
    assert np.allclose(got, np.r_[t_np[0], a_np[0]], rtol=0, atol=1e-11)


def test_space_jacobian_matches_finite_differences(machine):
    chain = ErrorModel({"EY0A": 0.02, "EC0A": 1e-4, "EZ0B": -0.01, "EC0Y": 1e-4}).chain(machine)
    q0 = {"X": np.array([10.0, -5.0]), "Y": np.array([3.0, 7.0]), "Z": np.array([-2.0, 1.0]),
          "A": np.array([0.4, -0.7]), "B": np.array([-0.3, 1.1])}
    J = space_jacobian(chain, q0)
    f0 = chain.forward(q0)
    p0 = np.stack(np.broadcast_arrays(*f0.p), -1)
    a0 = np.stack(np.broadcast_arrays(*(f0.R[i][2] for i in range(3))), -1)
    for i, name in enumerate(chain.names):
        h = 1e-6
        q1 = dict(q0)
        q1[name] = q0[name] + h
        f1 = chain.forward(q1)
        dp = (np.stack(np.broadcast_arrays(*f1.p), -1) - p0) / h
        da = (np.stack(np.broadcast_arrays(*(f1.R[k][2] for k in range(3))), -1) - a0) / h
        w, v = J[:, :3, i], J[:, 3:, i]
        assert np.allclose(dp, v + np.cross(w, p0), atol=1e-5), name
        assert np.allclose(da, np.cross(w, a0), atol=1e-6), name


def test_compensation_with_linear_axis_errors(machine):
    model = ErrorModel({**LINEAR, "EZ0A": 0.02, "EC0A": 40e-6})
    rng = np.random.default_rng(4)
    A, B = np.radians(rng.uniform(-50, 50, (2, 20)))
    X, Y, Z = rng.uniform(-200, 200, (3, 20))
    tip, axis = machine.tool_pose_np(A, B, X, Y, Z)
    res = compensate(model, machine, tip, axis, A, B)
    after = model.predict(machine, *res)
    assert np.max(np.linalg.norm(after.tip - tip, axis=1)) < 1e-9
    assert res.iterations < 10


# ---- the one first-order integrator ------------------------------------------------------------
def test_first_order_step_and_ramp_closed_forms():
    tau = 40.0
    t = np.linspace(0.0, 300.0, 61)
    # a step to 5 at t = 0, held: y = 5 (1 - exp(-t / tau))
    y = first_order_response(t, np.full_like(t, 5.0), 1.0, tau, hold="step")
    assert np.allclose(y, 5 * (1 - np.exp(-t / tau)), rtol=0, atol=1e-13)
    # a ramp u = r t, linear between knots: y = r (t - tau (1 - exp(-t / tau)))
    r = 0.2
    y = first_order_response(t, r * t, 1.0, tau, hold="linear")
    assert np.allclose(y, r * (t - tau * (1 - np.exp(-t / tau))), rtol=0, atol=1e-12)
    # ... and between the knots, from the knot values
    u = r * t
    s = interval_slopes(t, u)
    e = first_order_knots(t, u, tau)
    te = np.sort(np.random.default_rng(1).uniform(0, 299, 50))
    k = np.searchsorted(t, te, side="right") - 1
    got = first_order_between(u, s, e, tau, k, te - t[k])
    assert np.allclose(got, r * (te - tau * (1 - np.exp(-te / tau))), rtol=0, atol=1e-12)
    # the two holds differ when the speed changes between samples (a ramp held in steps lags more)
    ys = first_order_response(t, u, 1.0, tau, hold="step")
    assert np.all(ys[1:] < y[1:])


def test_thermal_state_uses_the_shared_integrator():
    m = ErrorModel(thermal={"mz": {"gain": 0.01, "tau": 100.0}, "dz": {"gain": -0.004, "tau": 50.0}})
    t = np.linspace(0, 500, 11)
    rpm = np.where(t < 250, 6000.0, 0.0)
    st = m.thermal_state(t, rpm)
    assert np.allclose(st["mz"], first_order_response(t, rpm / 1000, 0.01, 100.0))
    lin = m.thermal_state(t, 3000.0 + 0 * t, hold="linear")
    assert np.allclose(lin["dz"], -0.004 * 3 * (1 - np.exp(-t / 50.0)))


def test_machine_frame_growth_does_not_turn_with_the_head(machine):
    m = ErrorModel(thermal={"mz": {"gain": 0.01, "tau": 100.0}, "dz": {"gain": 0.01, "tau": 100.0}})
    A = np.radians(np.array([0.0, 30.0, 30.0]))
    B = np.radians(np.array([0.0, 0.0, -45.0]))
    z = np.zeros(3)
    t = np.array([0.0, 1e5, 2e5])  # cold, then steady: 0.01 mm per 1000 rpm at 1000 rpm
    only_m = ErrorModel(thermal={"mz": {"gain": 0.01, "tau": 100.0}})
    d = only_m.predict(machine, A, B, z, z, z, t=t, spindle_rpm=1000.0)
    assert np.allclose(d.tip - d.ideal_tip, [[0, 0, 0.0], [0, 0, 0.01], [0, 0, 0.01]], atol=1e-12)
    only_s = ErrorModel(thermal={"dz": {"gain": 0.01, "tau": 100.0}})
    d = only_s.predict(machine, A, B, z, z, z, t=t, spindle_rpm=1000.0)
    assert np.allclose((d.tip - d.ideal_tip)[1:], 0.01 * d.ideal_axis[1:], atol=1e-12)  # along the tool axis
    both = m.predict(machine, A, B, z, z, z, t=t, spindle_rpm=1000.0)
    assert np.allclose(both.tip_dev_um[1:], 10.0 * np.linalg.norm(d.ideal_axis[1:] + [0, 0, 1], axis=1))


# ---- one JSON format ---------------------------------------------------------------------------
def test_servo_and_runout_sections_round_trip(tmp_path):
    m = ErrorModel({"EZ0T": 0.04, "EXX": 3e-3}, tau={"X": 1 / 50, "A": 1 / 30}, backlash={"B": math.radians(0.01)},
                   offset_s=0.002, runout=(0.003, -0.001), thermal={"mz": {"gain": 0.01, "tau": 60.0}})
    back = ErrorModel.from_json(m.to_json(tmp_path / "m.json"))
    assert back.geometric == m.geometric and back.thermal == m.thermal
    assert back.tau == pytest.approx(m.tau) and back.backlash == pytest.approx(m.backlash)
    assert back.offset_s == m.offset_s and back.runout == pytest.approx(m.runout)
    # a plain ErrorModel file (no servo section) still reads, and writes no servo section
    doc = ErrorModel({"EZ0T": 0.01}).to_dict()
    assert "servo" not in doc and "spindle_runout" not in doc


@pytest.mark.parametrize("doc, key", [
    ({"format": "camsmooth-error-model", "version": 1, "geometric": [1, 2]}, "geometric"),
    ({"format": "camsmooth-error-model", "version": 1, "geometric": {"EZ0T": "0.01"}}, "geometric.EZ0T"),
    ({"format": "camsmooth-error-model", "version": 1, "geometric": {"EZ0T": {"value": "0.01", "unit": "mm"}}},
     "geometric.EZ0T"),
    ({"format": "camsmooth-error-model", "version": 1, "thermal": "hot"}, "thermal"),
    ({"format": "camsmooth-error-model", "version": 1, "thermal": {"dz": {"gain": 3, "tau": 1}}}, "thermal.dz.gain"),
    ({"format": "camsmooth-error-model", "version": 1, "spindle": {"r1": {"value": [1], "unit": "mm"}}},
     "spindle.r1"),
    ({"format": "camsmooth-error-model", "version": 1, "meta": [1]}, "meta"),
    ({"servo": {"Kv": {"X": "fast"}}}, "servo.Kv.X"),
    ({"servo": {"Kv": [40]}}, "servo.Kv"),
    ({"servo": 3}, "servo"),
    ({"spindle_runout": {"radius": None}}, "spindle_runout.radius"),
    ([1, 2, 3], None),
])
def test_type_errors_name_the_file_and_the_key(tmp_path, doc, key):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError) as e:
        ErrorModel.from_json(path)
    assert e.value.file == str(path)
    assert e.value.key == key


def test_first_order_jumps_and_restarts_against_a_plain_loop():
    """Zero-length intervals carry jumps of the input; restarts put the system at rest on its
    input; equal and unequal steps take different code paths: all against the plain recurrence."""
    rng = np.random.default_rng(5)
    for uniform in (True, False):
        t = np.arange(40) * 0.1 if uniform else np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.15, 39)])
        u = rng.normal(size=40)
        restart = np.zeros(40, bool)
        restart[[15, 30]] = True
        s = interval_slopes(t, u)
        s[[14, 29]] = 0.0  # across the restarts
        tau = 0.2
        e = first_order_knots(t, u, tau, slope=s, restart=restart)
        ref = np.zeros(40)
        ref[0] = u[0]
        for k in range(39):
            a = math.exp(-(t[k + 1] - t[k]) / tau)
            jump = u[k + 1] - u[k] - s[k] * (t[k + 1] - t[k])
            ref[k + 1] = 0.0 if restart[k + 1] else a * ref[k] + (1 - a) * tau * s[k] + jump
        assert np.allclose(e, ref, atol=1e-12)
    # a held step through repeated knot times (a jump): y = 2 (1 - exp(-(t - 1) / tau)) after t = 1
    t = np.array([0.0, 1.0, 1.0, 2.0, 3.0])
    u = np.array([0.0, 0.0, 2.0, 2.0, 2.0])
    y = u - first_order_knots(t, u, 0.5)
    assert np.allclose(y, [0, 0, 0, 2 * (1 - math.exp(-2)), 2 * (1 - math.exp(-4))], atol=1e-14)
