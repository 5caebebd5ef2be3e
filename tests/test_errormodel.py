"""The error model: JSON round trip, the perturbed POE chain against METHODS section 3 (first-order
squareness error vectors) and section 4 (multi-body product of homogeneous matrices), numpy vs
CasADi evaluation, the thermal first-order response, the spindle screw model, prediction and
compensation."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.spatial.transform import Rotation

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import exp_twist, load_machine
from camsmooth.machine.model import (
    CHAIN_GEOMETRIC,
    GEOMETRIC_NAMES,
    GEOMETRIC_PARAMETERS,
    ROTARY_GEOMETRIC,
    TABLE_GEOMETRIC,
    ErrorModel,
    SpindleScrew,
    compensate,
    first_order_response,
    kind_parameters,
    thermal_frame,
)

GEO = {"EY0A": 0.020, "EZ0A": -0.035, "EB0A": 30e-6, "EC0A": -45e-6, "EX0B": 0.015, "EZ0B": -0.025,
       "EA0B": 40e-6, "EC0B": -20e-6, "EX0S": 0.010, "EY0S": -0.030, "EA0S": 25e-6, "EB0S": -15e-6,
       "EZ0T": 0.050}
THERMAL = {"dx": {"gain": 0.002, "tau": 1200.0}, "dy": {"gain": -0.003, "tau": 1500.0},
           "dz": {"gain": -0.006, "tau": 900.0}, "exz": {"gain": 4e-6, "tau": 1800.0},
           "eyz": {"gain": -3e-6, "tau": 1400.0}}
SPINDLE = SpindleScrew(r1=0.004, theta1=0.7, r2=0.006, theta2=-2.1, cos_alpha=1.5e-5, cos_beta=-2.5e-5,
                       rho1=0.002, rho2=-0.001, delta3=0.012)


@pytest.fixture(scope="module")
def machine():
    return load_machine()


@pytest.fixture(scope="module")
def full_model():
    return ErrorModel(dict(GEO), SPINDLE, {k: dict(v) for k, v in THERMAL.items()}, {"note": "test"})


def _poses(n: int = 40, seed: int = 0):
    rng = np.random.default_rng(seed)
    return (np.radians(rng.uniform(-100, 100, n)), np.radians(rng.uniform(-100, 100, n)),
            rng.uniform(-300, 300, n), rng.uniform(-300, 300, n), rng.uniform(-300, 300, n))


# ----------------------------------------------------------------------------------------------
# JSON
def test_json_round_trip_is_exact_key_by_key(tmp_path, full_model):
    path = full_model.to_json(tmp_path / "model.json")
    back = ErrorModel.from_json(path)
    assert back.geometric == full_model.geometric  # exact float equality, key by key
    assert back.spindle == full_model.spindle
    assert back.thermal == full_model.thermal
    assert back.meta == full_model.meta
    doc = json.loads(path.read_text())
    assert doc["geometric"]["EB0A"] == {"value": 30e-6, "unit": "rad"}
    assert doc["thermal"]["dz"]["gain"]["unit"] == "mm/1000rpm"
    assert doc["spindle"]["theta1"]["unit"] == "rad"
    assert not list(tmp_path.glob(".*"))  # atomic write leaves no temporary file


def test_json_other_units_are_converted(tmp_path):
    doc = {"format": "camsmooth-error-model", "version": 1,
           "geometric": {"EY0A": {"value": 20.0, "unit": "um"}, "EB0A": {"value": 30.0, "unit": "urad"}},
           "spindle": None,
           "thermal": {"dz": {"gain": {"value": -6.0, "unit": "um/1000rpm"},
                              "tau": {"value": 15, "unit": "min"}}}}
    p = tmp_path / "m.json"
    p.write_text(json.dumps(doc))
    m = ErrorModel.from_json(p)
    assert m.get("EY0A") == pytest.approx(0.020, rel=1e-15)
    assert m.get("EB0A") == pytest.approx(30e-6, rel=1e-15)
    assert m.thermal["dz"] == pytest.approx({"gain": -0.006, "tau": 900.0})


@pytest.mark.parametrize("doc, words", [
    ({"format": "other"}, "not a camsmooth error model"),
    ({"format": "camsmooth-error-model", "version": 1, "geometric": {"EQ0A": {"value": 1, "unit": "mm"}}},
     "EQ0A"),
    ({"format": "camsmooth-error-model", "version": 1, "geometric": {"EY0A": {"value": 1, "unit": "rad"}}},
     "not a mm unit"),
    ({"format": "camsmooth-error-model", "version": 1, "geometric": {"EY0A": {"value": "x", "unit": "mm"}}},
     "finite number"),
    ({"format": "camsmooth-error-model", "version": 1,
      "thermal": {"dz": {"gain": {"value": 1, "unit": "mm/1000rpm"}, "tau": {"value": -1, "unit": "s"}}}},
     "tau > 0"),
])
def test_json_bad_input(tmp_path, doc, words):
    p = tmp_path / "bad.json"
    p.write_text(json.dumps(doc))
    with pytest.raises(InputError, match=words):
        ErrorModel.from_json(p)


def test_missing_model_file(tmp_path):
    with pytest.raises(InputError, match="not found"):
        ErrorModel.from_json(tmp_path / "none.json")


# ----------------------------------------------------------------------------------------------
# METHODS section 3: first-order squareness error vectors against the exact POE error
def _vee(R: np.ndarray) -> np.ndarray:
    return Rotation.from_matrix(R).as_rotvec()


def _exact_error(screw_real, screw_ideal, q) -> np.ndarray:
    """[dx, dy, dz, ex, ey, ez] of T_e = T_i^-1 T_r (body frame), exact log of the rotation."""
    Ti = exp_twist(*screw_ideal, q).to_numpy()
    Tr = exp_twist(*screw_real, q).to_numpy()
    Te = np.linalg.inv(Ti) @ Tr
    return np.concatenate([Te[:3, 3], _vee(Te[:3, :3])])


def _methods_rows(axis: str, S1: float, S2: float, q: float) -> np.ndarray:
    """The first-order vectors exactly as METHODS section 3 states them."""
    c, s = np.cos(q), np.sin(q)
    if axis == "A":
        Say, Saz = S1, S2
        return np.array([0, 0, 0, 0, -Saz + Saz * c + Say * s, Say - Say * c - Saz * s])
    if axis == "B":
        Sbx, Sbz = S1, S2
        return np.array([0, 0, 0, Sbz - Sbz * c - Sbx * s, 0, -Sbx + Sbx * c - Sbz * s])
    Scx, Scy = S1, S2
    return np.array([0, 0, 0, -Scy + Scy * c - Scx * s, Scx - Scx * c - Scy * s, 0])


@pytest.mark.parametrize("S", [1e-3, 1e-4])
def test_squareness_error_vectors_match_methods_to_second_order(machine, S):
    """B and C rows as stated, A row with the sign of its S_ay sin(a) term in e_y flipped (see the
    errormodel docstring): the exact body-frame POE error agrees to O(S^2)."""
    S1, S2 = 0.7 * S, -1.3 * S
    q = np.linspace(-2.5, 2.5, 11)
    # A axis through the perturbed chain: S_az = EB0A, S_ay = -EC0A
    chain = ErrorModel({"EB0A": S2, "EC0A": -S1}).chain(machine)
    nominal = machine.chain.joint_screws()
    wA = chain.joint_screws()[3][0]
    assert np.allclose(wA, [np.cos(S2) * np.cos(S1), -np.cos(S2) * np.sin(S1), -np.sin(S2)], atol=1e-15)
    # B axis: S_bx = EC0B, S_bz = -EA0B
    chainB = ErrorModel({"EC0B": S1, "EA0B": -S2}).chain(machine)
    wB = chainB.joint_screws()[4][0]
    assert np.allclose(wB, [-np.sin(S1), np.cos(S1) * np.cos(S2), -np.cos(S1) * np.sin(S2)], atol=1e-15)
    # C axis (not on this machine): the generic POE with the METHODS direction
    wC = np.array([-np.sin(S1), -np.cos(S1) * np.sin(S2), np.cos(S1) * np.cos(S2)])
    cases = {"A": (chain.joint_screws()[3], nominal[3]), "B": (chainB.joint_screws()[4], nominal[4]),
             "C": ((wC, np.zeros(3)), (np.array([0.0, 0.0, 1.0]), np.zeros(3)))}
    for axis, (real, ideal) in cases.items():
        for qi in q:
            exact = _exact_error(real, ideal, qi)
            first = _methods_rows(axis, S1, S2, qi)
            if axis == "A":
                first = first.copy()
                first[4] -= 2 * S1 * np.sin(qi)  # corrected sign of S_ay sin(a) in e_y
            assert np.max(np.abs(exact - first)) < 2 * S ** 2, (axis, qi)


def test_methods_A_row_as_stated_is_off_at_first_order(machine):
    """Documented finding: the stated A row's e_y differs from the exact error by 2 S_ay sin(a),
    first order in S, in the body frame and in the spatial frame alike."""
    S1, S2, a = 1e-4, -2e-4, 0.9
    chain = ErrorModel({"EB0A": S2, "EC0A": -S1}).chain(machine)
    real, ideal = chain.joint_screws()[3], machine.chain.joint_screws()[3]
    body = _exact_error(real, ideal, a)
    Ti, Tr = exp_twist(*ideal, a).to_numpy(), exp_twist(*real, a).to_numpy()
    spatial = _vee((Tr @ np.linalg.inv(Ti))[:3, :3])
    stated = _methods_rows("A", S1, S2, a)
    assert abs(body[4] - stated[4]) == pytest.approx(2 * S1 * np.sin(a), rel=1e-3)
    assert np.max(np.abs(spatial - stated[3:])) > S1 * 0.5


# ----------------------------------------------------------------------------------------------
# METHODS section 4: multi-body product of homogeneous matrices
def _T(R=None, p=None) -> np.ndarray:
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def _R(axis: str, angle: float) -> np.ndarray:
    return Rotation.from_euler(axis, angle).as_matrix()


def _mbs_tool_pose(model: ErrorModel, pivot: float, q: tuple) -> np.ndarray:
    """Independent multi-body model: per adjacent body pair the product of four homogeneous
    matrices (ideal static, static error, ideal motion, motion error), from the bed to the tool.
    Bodies: bed/workpiece - X slide - Y slide - Z ram - A cradle - B head - tool. The error
    parameters are turned into static error matrices directly from their definitions."""
    A, B, X, Y, Z = q
    g = model.get
    E_A = _T(_R("z", g("EC0A")) @ _R("y", g("EB0A")), [0.0, g("EY0A"), g("EZ0A")])   # real A axis frame
    E_B = _T(_R("x", g("EA0B")) @ _R("z", g("EC0B")), [g("EX0B"), 0.0, g("EZ0B")])   # B relative to A
    R_S = _R("x", g("EA0S")) @ _R("y", g("EB0S"))
    S = _T(R_S, [g("EX0S"), g("EY0S"), 0.0])                                          # spindle in the head
    tool = _T(p=[0.0, 0.0, -g("EZ0T")])
    if model.spindle is not None:
        tool = tool @ model.spindle.static_tip_transform()
    # The spindle errors are defined against the nominal head, so relative to the (real) B body
    # frame F_B = E_A E_B the tool's static error is F_B^-1 S (ideal static) tool.
    ideal_tool = _T(p=[0.0, 0.0, -pivot])
    E_tool = np.linalg.inv(ideal_tool) @ np.linalg.inv(E_A @ E_B) @ S @ ideal_tool @ tool
    I4 = np.eye(4)
    pairs = [  # (ideal static, static error, ideal motion, motion error)
        (I4, I4, _T(p=[X, 0, 0]), I4),
        (I4, I4, _T(p=[0, Y, 0]), I4),
        (I4, I4, _T(p=[0, 0, Z]), I4),
        (I4, E_A, _T(_R("x", A)), I4),
        (I4, E_B, _T(_R("y", B)), I4),
        (ideal_tool, E_tool, I4, I4),
    ]
    T = np.eye(4)
    for Tp, Tpe, Ts, Tse in pairs:
        T = T @ Tp @ Tpe @ Ts @ Tse
    return T


def test_poe_chain_equals_multibody_product(machine):
    model = ErrorModel(dict(GEO), SPINDLE)
    real = model.apply(machine)
    A, B, X, Y, Z = _poses(25, seed=3)
    tip, axis = real.tool_pose_np(A, B, X, Y, Z)
    for i in range(len(A)):
        T = _mbs_tool_pose(model, machine.pivot, (A[i], B[i], X[i], Y[i], Z[i]))
        assert np.max(np.abs(T[:3, 3] - tip[i])) < 1e-12
        assert np.max(np.abs(T[:3, 2] - axis[i])) < 1e-12
    # the same product with all errors zero is the nominal machine
    T0 = _mbs_tool_pose(ErrorModel(), machine.pivot, (A[0], B[0], X[0], Y[0], Z[0]))
    tip0, axis0 = machine.tool_pose_np(A[:1], B[:1], X[:1], Y[:1], Z[:1])
    assert np.max(np.abs(T0[:3, 3] - tip0[0])) < 1e-12 and np.max(np.abs(T0[:3, 2] - axis0[0])) < 1e-15


def test_axis_line_errors_do_not_move_the_home_pose(machine):
    axis_only = {k: v for k, v in GEO.items() if k[-1] in "AB"}
    tip, axis = ErrorModel(axis_only).apply(machine).tool_pose_np([0.0], [0.0], [0.0], [0.0], [0.0])
    assert np.allclose(tip, [[0, 0, -machine.pivot]], atol=1e-15)
    assert np.allclose(axis, [[0, 0, 1]], atol=1e-15)


def test_zero_model_is_the_nominal_machine(machine):
    q = _poses(10)
    a = ErrorModel().apply(machine).tool_pose_np(*q)
    b = machine.tool_pose_np(*q)
    assert np.max(np.abs(a[0] - b[0])) < 1e-12 and np.max(np.abs(a[1] - b[1])) < 1e-15


def test_numpy_and_casadi_evaluate_the_same_perturbed_machine(machine, full_model):
    state = {k: float(v[-1]) for k, v in full_model.thermal_state(np.array([0.0, 3600.0]), 5000.0).items()}
    real = full_model.apply(machine, thermal_state=state)
    A, B, X, Y, Z = _poses(15, seed=5)
    tip, axis = real.tool_pose_np(A, B, X, Y, Z)
    for sym in (ca.SX, ca.MX):
        q = sym.sym("q", 5)
        t_s, a_s = real.tool_pose(q[0], q[1], q[2], q[3], q[4])
        f = ca.Function("f", [q], [ca.vertcat(*t_s, *a_s)])
        out = np.array(f(np.vstack([A, B, X, Y, Z]))).T if sym is ca.SX else np.hstack(
            [np.array(f(np.array([A[i], B[i], X[i], Y[i], Z[i]]))) for i in range(len(A))]).T
        assert np.max(np.abs(out[:, :3] - tip)) < 1e-11
        assert np.max(np.abs(out[:, 3:] - axis)) < 1e-14
    # and tool_axis with symbols (what the smoother uses)
    a_sym, b_sym = ca.SX.sym("a"), ca.SX.sym("b")
    f = ca.Function("g", [a_sym, b_sym], [ca.vertcat(*real.tool_axis(a_sym, b_sym))])
    assert np.allclose(np.array(f(A[0], B[0])).ravel(), axis[0], atol=1e-15)


def test_bad_machine_for_the_model(machine):
    perturbed = ErrorModel({"EY0A": 0.01}).apply(machine)
    with pytest.raises(ValueError, match="nominal machine"):
        ErrorModel().chain(perturbed)
    with pytest.raises(InputError, match="unknown geometric"):
        ErrorModel({"EQ0A": 1.0})


# ----------------------------------------------------------------------------------------------
# thermal
def test_thermal_state_matches_the_analytic_response(full_model):
    t = np.linspace(0, 7200, 13)
    st = full_model.thermal_state(t, 5000.0)
    g, tau = THERMAL["dz"]["gain"], THERMAL["dz"]["tau"]
    assert np.allclose(st["dz"], g * 5 * (1 - np.exp(-t / tau)), rtol=0, atol=1e-15)
    # heating then cooling: speed 5000 on [0, 3600), 0 afterwards (held from each sample)
    t2 = np.array([0.0, 1800.0, 3600.0, 5400.0, 9000.0])
    rpm = np.array([5000.0, 5000.0, 0.0, 0.0, 0.0])
    e = full_model.thermal_state(t2, rpm)["dx"]
    g, tau = THERMAL["dx"]["gain"], THERMAL["dx"]["tau"]
    e3600 = g * 5 * (1 - np.exp(-3600 / tau))
    assert e[2] == pytest.approx(e3600, rel=1e-13)
    assert e[4] == pytest.approx(e3600 * np.exp(-5400 / tau), rel=1e-12)


def test_first_order_response_against_ode_integration_and_long_histories():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(5, 200, 60))
    t -= t[0]
    u = rng.uniform(0, 8, 60)
    e = first_order_response(t, u, 0.7, 300.0)

    def rhs(time, y):
        j = min(np.searchsorted(t, time, side="right") - 1, len(u) - 1)
        return [(0.7 * u[j] - y[0]) / 300.0]

    sol = solve_ivp(rhs, (0, t[-1]), [0.0], t_eval=t, max_step=2.0, rtol=1e-10, atol=1e-13)
    assert np.max(np.abs(sol.y[0] - e)) < 1e-6
    # long history with tiny tau (many chunks of the closed form) against the plain recurrence
    t = np.arange(0.0, 2e5, 7.0)
    u = np.where((t // 5000) % 2 == 0, 3.0, 0.5)
    e = first_order_response(t, u, 1.3, 40.0)
    ref = np.zeros_like(t)
    d = np.exp(-7.0 / 40.0)
    for i in range(len(t) - 1):
        ref[i + 1] = d * ref[i] + (1 - d) * 1.3 * u[i]
    assert np.max(np.abs(e - ref)) < 1e-11 * np.max(np.abs(ref))


def test_thermal_prediction_moves_the_tip_and_tilts_the_axis(machine):
    model = ErrorModel(thermal={k: dict(v) for k, v in THERMAL.items()})
    t = np.array([0.0, 600.0, 1800.0, 3600.0])
    z = np.zeros(4)
    pred = model.predict(machine, z, z, z, z, z, t=t, spindle_rpm=5000.0)
    st = model.thermal_state(t, 5000.0)
    assert np.allclose(pred.tip - pred.ideal_tip, np.column_stack([st["dx"], st["dy"], st["dz"]]), atol=1e-15)
    assert np.allclose(pred.axis_dev_urad, np.hypot(st["exz"], st["eyz"]) * 1e6, rtol=1e-9)
    # the axis tilts to (-exz, -eyz, 1) (module docstring): a point h above the tip moves by -exz h in x
    assert np.allclose(pred.axis[:, 0], -st["exz"], atol=1e-13)
    assert np.allclose(pred.axis[:, 1], -st["eyz"], atol=1e-13)
    f = thermal_frame({"exz": 2e-5, "eyz": -1e-5})
    moved = np.array(f.apply((0.0, 0.0, 100.0)))
    assert np.allclose(moved - [0, 0, 100.0], [-2e-5 * 100, 1e-5 * 100, 0], atol=1e-7)  # 2nd order in z
    with pytest.raises(InputError, match="both t and spindle_rpm"):
        model.predict(machine, z, z, z, z, z, t=t)
    with pytest.raises(InputError, match="must not decrease"):
        model.thermal_state(t[::-1], 5000.0)


# ----------------------------------------------------------------------------------------------
# spindle screw model (METHODS section 2)
def _line_distance(p1, d1, p2, d2):
    n = np.cross(d1, d2)
    return abs(np.dot(p2 - p1, n)) / np.linalg.norm(n)


def test_spindle_screw_plucker_line_and_screw_error():
    sp = SPINDLE
    theta = np.linspace(0, 2 * np.pi, 9)
    l, m = sp.tool_line(theta)
    assert np.allclose(np.linalg.norm(l, axis=1), 1.0) and np.allclose(np.sum(l * m, axis=1), 0.0, atol=1e-15)
    th_e, d_e = sp.screw_error(theta)
    tips = sp.tip(theta)
    for i in range(len(theta)):
        angle = np.arcsin(np.linalg.norm(np.cross(l[i], [0.0, 0.0, 1.0])))
        assert th_e[i] == pytest.approx(angle, rel=1e-9)
        ref = _line_distance(np.zeros(3), np.array([0, 0, 1.0]), tips[i], l[i])
        assert d_e[i] == pytest.approx(ref, rel=1e-6)
    # special cases: pure tilt of the rotation axis -> a line through the origin, angle = tilt
    tilt = SpindleScrew(cos_alpha=2e-5)
    te, de = tilt.screw_error(np.array([0.3]))
    assert te[0] == pytest.approx(np.arcsin(2e-5), rel=1e-9) and de[0] < 1e-12
    # equal runouts in phase -> a parallel line at distance r
    par = SpindleScrew(r1=0.005, r2=0.005, theta1=1.0, theta2=1.0)
    te, de = par.screw_error(np.array([0.0, 2.0]))
    assert np.all(te < 1e-12) and np.allclose(de, 0.005, rtol=1e-9)


def test_spindle_static_transform_is_the_mean_tool_over_a_revolution(machine):
    sp = SPINDLE
    theta = np.linspace(0, 2 * np.pi, 360, endpoint=False)
    mean_tip = sp.tip(theta).mean(axis=0)
    T = sp.static_tip_transform()
    assert np.allclose(sp.nominal_tip() + T[:3, 3], mean_tip, atol=1e-12)
    assert np.allclose(T[:3, 2], sp.direction(), atol=1e-15)
    tip, axis = ErrorModel(spindle=sp).apply(machine).tool_pose_np([0.0], [0.0], [0.0], [0.0], [0.0])
    assert np.allclose(tip[0], [0, 0, -machine.pivot] + T[:3, 3], atol=1e-12)
    assert sp.runout() == pytest.approx(np.max(np.linalg.norm(sp.tip(theta) - mean_tip, axis=1)), rel=1e-9)


# ----------------------------------------------------------------------------------------------
# compensation (issue 3: A out of square by 50 urad and offset by 20 um)
def test_compensation_brings_the_predicted_tip_under_one_micron(machine):
    model = ErrorModel({"EC0A": 50e-6, "EZ0A": 0.020, "EB0S": 10e-6, "EZ0T": 0.01}, SPINDLE)
    A, B, X, Y, Z = _poses(60, seed=7)
    ideal_tip, ideal_axis = machine.tool_pose_np(A, B, X, Y, Z)
    before = model.predict(machine, A, B, X, Y, Z)
    assert before.tip_dev_um.max() > 5.0
    res = compensate(model, machine, ideal_tip, ideal_axis, A, B)
    Ac, Bc, Xc, Yc, Zc = res
    after = model.predict(machine, Ac, Bc, Xc, Yc, Zc)
    assert np.max(np.linalg.norm(after.tip - ideal_tip, axis=1)) * 1e3 < 1e-6
    ang = np.linalg.norm(np.cross(after.axis, ideal_axis), axis=1)
    assert np.max(ang) < 1e-12
    assert res.tip_residual_um.max() < 1e-6 and res.axis_residual_urad.max() < 1e-3
    assert np.max(np.abs(Ac - A)) < 1e-2  # same branch (A is ill-conditioned only near B = +-90 deg)
    # with thermal drift at a given time
    thermal = ErrorModel(dict(model.geometric), SPINDLE, {k: dict(v) for k, v in THERMAL.items()})
    t = np.linspace(0, 3000, len(A))
    res = compensate(thermal, machine, ideal_tip, ideal_axis, A, B, t=t, spindle_rpm=5000.0)
    after = thermal.predict(machine, *res, t=t, spindle_rpm=5000.0)
    assert np.max(np.linalg.norm(after.tip - ideal_tip, axis=1)) * 1e3 < 1e-6


def test_every_geometric_parameter_moves_the_tool(machine):
    q = _poses(12, seed=9)
    base = machine.tool_pose_np(*q)[0]
    chain_only = set(CHAIN_GEOMETRIC) - set(ROTARY_GEOMETRIC) - set(TABLE_GEOMETRIC)  # a chain machine's own
    assert set(kind_parameters("AB-head")) == set(GEOMETRIC_NAMES) - set(TABLE_GEOMETRIC) - chain_only
    for name in kind_parameters("AB-head"):
        value = 1e-3 if GEOMETRIC_PARAMETERS[name][0] == "mm" else 1e-5
        tip = ErrorModel({name: value}).apply(machine)
        assert np.max(np.abs(tip.tool_pose_np(*q)[0] - base)) > 1e-5, name
