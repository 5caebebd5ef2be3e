"""The error model on table machines (issue 18): the C-axis and tilt-axis location errors as
perturbed screws of the one chain per kind, checked against the first-order error vectors of
METHODS section 3 (the C row, and the tilt axis' row) to O(S^2), against closed forms of the table
kinematics, numpy against CasADi, the kind checks, the JSON ``machine_kind`` and compensation on an
AC table."""

from __future__ import annotations

import json

import casadi as ca
import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import load_machine, machine_from_dict
from camsmooth.machine.model import (
    GEOMETRIC_PARAMETERS,
    ROTARY_BY_KIND,
    ErrorModel,
    compensate,
    kind_parameters,
    rot_x,
    rot_y,
    rot_z,
)

CENTRE = (12.0, -25.0, -60.0)


def table_machine(kind: str, centre=CENTRE, pivot: float = 120.0):
    """A nominal machine of the kind, tilt travel -120 .. 120 deg, continuous C."""
    tilt = "A" if kind == "AC-table" else "B"
    m = {"kind": kind, "table_centre": list(centre)}
    if kind == "BC-head-table":
        m["pivot"] = pivot
    axes = {tilt: {"min": -120.0, "max": 120.0, "vmax": 60.0, "amax": 300.0}, "C": {"vmax": 180.0, "amax": 900.0}}
    return machine_from_dict({"machine": m, "axis": axes})


@pytest.fixture(scope="module", params=["AC-table", "BC-table", "BC-head-table"])
def machine(request):
    return table_machine(request.param)


def _poses(n: int = 30, seed: int = 0):
    rng = np.random.default_rng(seed)
    return (np.radians(rng.uniform(-110, 110, n)), np.radians(rng.uniform(-180, 180, n)),
            rng.uniform(-200, 200, n), rng.uniform(-200, 200, n), rng.uniform(-200, 200, n))


def _rotary_errors(kind: str, S: float, L: float = 40.0) -> dict[str, float]:
    """Every rotary-axis error of the kind: angles of order S (rad), offsets of order L S (mm)."""
    angles = iter([0.7, -1.3, 0.9, -0.6])
    offsets = iter([1.0, -0.8, 0.6, -1.1])
    return {n: (next(offsets) * L * S if u == "mm" else next(angles) * S)
            for n, (u, _) in ROTARY_BY_KIND[kind].items()}


# ----------------------------------------------------------------------------------------------
# METHODS section 3: the C row (and the tilt axis' row) against the exact perturbed chain
def _first_order(kind: str, g: dict[str, float], machine, q):
    """Tool-tip and tool-axis error (N,3 each) to first order, from the error vectors of METHODS
    section 3 (C row as stated; A row with the corrected sign; B row as stated) and the location
    terms of section 3.1: an axis turned by q with rotation error e(q) about its line through
    c and a line offset d moves a point x (in the frame after the axis) by e x (x - c) +
    (R(-q) - I) d; the tool error is that motion carried out by the axes before it."""
    t, C, X, Y, Z = q
    c = np.asarray(machine.table_centre)
    n = len(C)
    zero = np.zeros(n)
    # C row: S_cx = -EB0C, S_cy = EA0C
    Scx, Scy = -g.get("EB0C", 0.0), g.get("EA0C", 0.0)
    eC = np.column_stack([-Scy + Scy * np.cos(C) - Scx * np.sin(C), Scx - Scx * np.cos(C) - Scy * np.sin(C), zero])
    dC = np.array([g.get("EX0C", 0.0), g.get("EY0C", 0.0), 0.0])
    RC = np.stack([rot_z(v) for v in C])
    RCinv = np.transpose(RC, (0, 2, 1))
    # the frame after C: the tool pose with C = 0 (the tilt axis and the linear axes)
    G_tip, G_axis = machine.tool_pose_np(t, zero, X, Y, Z)
    local = np.cross(eC, G_tip - c) + (RCinv @ dC) - dC
    d_tip = np.einsum("nij,nj->ni", RC, local)
    d_axis = np.einsum("nij,nj->ni", RC, np.cross(eC, G_axis))
    # the tilt axis
    tilt = machine.rotary[0]
    if tilt == "A":  # S_az = EB0A, S_ay = -EC0A; A row with -S_ay sin a in e_y
        Say, Saz = -g.get("EC0A", 0.0), g.get("EB0A", 0.0)
        eT = np.column_stack([zero, -Saz + Saz * np.cos(t) - Say * np.sin(t), Say - Say * np.cos(t) - Saz * np.sin(t)])
        dT = np.array([0.0, g.get("EY0A", 0.0), g.get("EZ0A", 0.0)])
        RT = np.stack([rot_x(v) for v in t])
    else:  # S_bx = EC0B, S_bz = -EA0B
        Sbx, Sbz = g.get("EC0B", 0.0), -g.get("EA0B", 0.0)
        eT = np.column_stack([Sbz - Sbz * np.cos(t) - Sbx * np.sin(t), zero, -Sbx + Sbx * np.cos(t) - Sbz * np.sin(t)])
        dT = np.array([g.get("EX0B", 0.0), 0.0, g.get("EZ0B", 0.0)])
        RT = np.stack([rot_y(v) for v in t])
    RTinv = np.transpose(RT, (0, 2, 1))
    if machine.kind == "BC-head-table":
        # C, X, Y, Z, then the head's B about the pivot o = (X, Y, Z) after the carriage: the frame
        # after B is the home tool frame carried by the linear axes
        o = np.zeros(3)
        home_tip = np.asarray(machine.chain.home)[:3, 3]
        h_tip = np.broadcast_to(home_tip, (n, 3))
        h_axis = np.broadcast_to([0.0, 0.0, 1.0], (n, 3))
        before = RC  # C, then pure translations
    else:
        o = c
        h_tip = np.column_stack([X, Y, Z])  # the frame after the tilt axis: the linear axes and M = I
        h_axis = np.broadcast_to([0.0, 0.0, 1.0], (n, 3))
        before = RC @ RT
    local_t = np.cross(eT, h_tip - o) + (RTinv @ dT) - dT
    if machine.kind == "BC-head-table":
        local_t = np.einsum("nij,nj->ni", RT, local_t)  # B comes after the carriage: rotate into its frame
        before = RC
    d_tip += np.einsum("nij,nj->ni", before, local_t)
    ax_local = np.cross(eT, h_axis)
    if machine.kind == "BC-head-table":
        ax_local = np.einsum("nij,nj->ni", RT, ax_local)
    d_axis += np.einsum("nij,nj->ni", before, ax_local)
    return d_tip, d_axis


@pytest.mark.parametrize("kind", ["AC-table", "BC-table"])
def test_C_row_of_methods_against_the_exact_chain_to_second_order(kind):
    """The C error vector of METHODS section 3 (with the location terms of section 3.1) against the
    exact POE error: the difference is O(S^2); halving S quarters it."""
    machine = table_machine(kind)
    q = _poses(40, seed=1)
    nominal = machine.tool_pose_np(*q)
    worst = []
    for S in (1e-3, 5e-4, 2.5e-4, 1.25e-4):
        g = {k: v for k, v in _rotary_errors(kind, S).items() if k in ("EX0C", "EY0C", "EA0C", "EB0C")}
        real = ErrorModel(g, kind=kind).apply(machine).tool_pose_np(*q)
        d_tip, d_axis = _first_order(kind, g, machine, q)
        exact_tip, exact_axis = real[0] - nominal[0], real[1] - nominal[1]
        assert np.max(np.abs(exact_tip)) > 40 * S * 0.5  # the first-order effect is there
        worst.append((np.max(np.abs(exact_tip - d_tip)), np.max(np.abs(exact_axis - d_axis))))
    worst = np.array(worst)
    ratios = worst[:-1] / worst[1:]
    assert np.all((ratios > 3.6) & (ratios < 4.4)), ratios
    # and the remainder is small against the effect: O(S^2 |x|) with |x| ~ 400 mm (mm, rad)
    assert worst[0, 0] < 2e-3 and worst[0, 1] < 5e-6


def test_tilt_and_C_rows_together_to_second_order(machine):
    """All rotary-axis errors of the kind at once, C row and tilt row (A row with the corrected sign
    of METHODS section 3, B row as stated): first order plus O(S^2), ratio ~4 on halving S."""
    kind = machine.kind
    q = _poses(40, seed=2)
    nominal = machine.tool_pose_np(*q)
    worst = []
    for S in (1e-3, 5e-4, 2.5e-4):
        g = _rotary_errors(kind, S)
        real = ErrorModel(g, kind=kind).apply(machine).tool_pose_np(*q)
        d_tip, d_axis = _first_order(kind, g, machine, q)
        worst.append(max(np.max(np.abs(real[0] - nominal[0] - d_tip)),
                         100 * np.max(np.abs(real[1] - nominal[1] - d_axis))))
    ratios = np.array(worst[:-1]) / np.array(worst[1:])
    assert np.all((ratios > 3.6) & (ratios < 4.4)), (kind, ratios, worst)


def test_C_axis_direction_is_the_methods_direction():
    machine = table_machine("AC-table")
    Scx, Scy = 3e-4, -7e-4
    w = ErrorModel({"EB0C": -Scx, "EA0C": Scy}, kind="AC-table").chain(machine).joint_screws()[0][0]
    assert np.allclose(w, [-np.sin(Scx), -np.cos(Scx) * np.sin(Scy), np.cos(Scx) * np.cos(Scy)], atol=1e-16)


# ----------------------------------------------------------------------------------------------
# closed forms and backends
def test_table_axis_lines_against_the_closed_form():
    """tip = p_C + R_C (p_A + R_A (P - p_A) - p_C) with R_C, R_A the rotations about the real lines
    (direction w through point p), written out with Rodrigues."""
    machine = table_machine("AC-table")
    g = _rotary_errors("AC-table", 1e-3)
    real = ErrorModel(g, kind="AC-table").apply(machine)
    A, C, X, Y, Z = _poses(20, seed=3)
    tip, axis = real.tool_pose_np(A, C, X, Y, Z)
    c = np.asarray(CENTRE)
    wC = rot_x(g["EA0C"]) @ rot_y(g["EB0C"]) @ [0, 0, 1.0]
    pC = c + [g["EX0C"], g["EY0C"], 0.0]
    wA = rot_z(g["EC0A"]) @ rot_y(g["EB0A"]) @ [1.0, 0, 0]
    pA = c + [0.0, g["EY0A"], g["EZ0A"]]

    def rod(w, a):
        K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
        return np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K

    for i in range(len(A)):
        RA, RC = rod(wA, A[i]), rod(wC, C[i])
        P = np.array([X[i], Y[i], Z[i]])
        expect = pC + RC @ (pA + RA @ (P - pA) - pC)
        assert np.allclose(tip[i], expect, atol=1e-11)
        assert np.allclose(axis[i], RC @ RA @ [0, 0, 1.0], atol=1e-15)


def test_straightness_and_machine_thermal_turn_with_the_table():
    """On a table the carriage offset (straightness, machine-frame thermal growth) is in the machine
    frame: tip = c + Rz(C) Rx(A) (P + d - c)."""
    machine = table_machine("AC-table")
    model = ErrorModel({"EYX2": 4e-7, "EXZ2": 5e-7, "EXX": 2e-4})
    A, C, X, Y, Z = _poses(15, seed=4)
    tip = model.apply(machine).tool_pose_np(A, C, X, Y, Z)[0]
    state = {"mx": 0.003, "my": -0.002, "mz": 0.004}
    f = model.real_frame(machine, {"A": A, "C": C, "X": X, "Y": Y, "Z": Z}, state)
    c = np.asarray(CENTRE)
    for i in range(len(A)):
        P = np.array([X[i] * (1 + 2e-4), Y[i], Z[i]])
        d = np.array([5e-7 * Z[i] ** 2, 4e-7 * X[i] ** 2, 0.0])
        R = rot_z(C[i]) @ rot_x(A[i])
        assert np.allclose(tip[i], c + R @ (P + d - c), atol=1e-11)
        th = c + R @ (P + d + [0.003, -0.002, 0.004] - c)
        assert np.allclose([f.p[k][i] for k in range(3)], th, atol=1e-11)


def test_numpy_and_casadi_evaluate_the_same_perturbed_table(machine):
    model = ErrorModel({**_rotary_errors(machine.kind, 1e-3), "EC0Y": 3e-5, "EYX2": 4e-7, "EZ0T": 0.02,
                        "EA0S": 2e-5}, kind=machine.kind)
    real = model.apply(machine)
    q1, q2, X, Y, Z = _poses(10, seed=5)
    tip, axis = real.tool_pose_np(q1, q2, X, Y, Z)
    s = ca.SX.sym("q", 5)
    t_s, a_s = real.tool_pose(s[0], s[1], s[2], s[3], s[4])
    f = ca.Function("f", [s], [ca.vertcat(*t_s, *a_s)])
    out = np.array(f(np.vstack([q1, q2, X, Y, Z]))).T
    assert np.max(np.abs(out[:, :3] - tip)) < 1e-11 and np.max(np.abs(out[:, 3:] - axis)) < 1e-14


def test_every_parameter_of_a_table_kind_moves_the_tool(machine):
    q = _poses(12, seed=9)
    base_tip, base_axis = machine.tool_pose_np(*q)
    for name in kind_parameters(machine.kind):
        value = 1e-3 if GEOMETRIC_PARAMETERS[name][0] == "mm" else 1e-5
        tip, axis = ErrorModel({name: value}, kind=machine.kind).apply(machine).tool_pose_np(*q)
        moved = max(np.max(np.abs(tip - base_tip)), 100.0 * np.max(np.abs(axis - base_axis)))
        assert moved > 1e-5, name


def test_zero_model_and_axis_errors_at_home(machine):
    q = _poses(8, seed=6)
    a = ErrorModel(kind=machine.kind).apply(machine).tool_pose_np(*q)
    b = machine.tool_pose_np(*q)
    assert np.max(np.abs(a[0] - b[0])) < 1e-12 and np.max(np.abs(a[1] - b[1])) < 1e-15
    real = ErrorModel(_rotary_errors(machine.kind, 1e-3), kind=machine.kind).apply(machine)
    assert real.table_centre == machine.table_centre and real.post == machine.post and real.kind == machine.kind
    zero = np.zeros(1)
    home = real.tool_pose_np(zero, zero, zero, zero, zero)
    assert np.allclose(home[0], machine.tool_pose_np(zero, zero, zero, zero, zero)[0], atol=1e-15)


# ----------------------------------------------------------------------------------------------
# kinds: a model for one kind on another is an InputError naming both
def test_kind_mismatch_is_an_input_error():
    ab, ac, bc = load_machine(), table_machine("AC-table"), table_machine("BC-table")
    legacy = ErrorModel({"EY0A": 0.01})  # no kind: every model before machine kinds was an AB-head model
    legacy.apply(ab)
    with pytest.raises(InputError, match="for an AB-head machine .*states no machine kind.*machine is AC-table"):
        legacy.apply(ac)
    with pytest.raises(InputError, match="for an AC-table machine, but the machine is AB-head"):
        ErrorModel({"EY0A": 0.01}, kind="AC-table").apply(ab)
    with pytest.raises(InputError, match="for an AC-table machine, but the machine is BC-table"):
        ErrorModel({"EX0C": 0.01}, kind="AC-table").apply(bc)
    with pytest.raises(InputError, match="EX0C are not errors of an AB-head machine"):
        ErrorModel({"EX0C": 0.01}).apply(ab)
    with pytest.raises(InputError, match="EY0A are not errors of a BC-table machine"):
        ErrorModel({"EX0C": 0.01, "EY0A": 0.01}).apply(bc)
    with pytest.raises(InputError, match="EX0B are not errors of an AC-table"):
        ErrorModel({"EX0B": 0.01}, kind="AC-table")
    with pytest.raises(InputError, match="not one of"):
        ErrorModel(kind="AC-head")
    # no rotary-axis errors: any kind; C errors without a kind: any table kind
    for m in (ab, ac, bc):
        ErrorModel({"EXX": 1e-4, "EZ0T": 0.01}).apply(m)
    ErrorModel({"EX0C": 0.01}).apply(ac)
    ErrorModel({"EX0C": 0.01, "EX0B": 0.01}).apply(bc)


def test_json_machine_kind_round_trip(tmp_path):
    model = ErrorModel(_rotary_errors("AC-table", 1e-3), kind="AC-table")
    path = model.to_json(tmp_path / "m.json")
    doc = json.loads(path.read_text())
    assert doc["machine_kind"] == "AC-table"
    back = ErrorModel.from_json(path)
    assert back.kind == "AC-table" and back.geometric == model.geometric
    assert "machine_kind" not in ErrorModel({"EY0A": 0.01}).to_dict()  # AB-head files are unchanged
    doc["machine_kind"] = "XY-table"
    (tmp_path / "bad.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match="machine_kind") as exc:
        ErrorModel.from_json(tmp_path / "bad.json")
    assert exc.value.key == "machine_kind"
    doc["machine_kind"] = "BC-table"
    (tmp_path / "bad2.json").write_text(json.dumps(doc))
    with pytest.raises(InputError, match="EY0A, EZ0A, EB0A, EC0A are not errors of a BC-table"):
        ErrorModel.from_json(tmp_path / "bad2.json")
    assert ErrorModel(kind="BC-table").copy().kind == "BC-table"


# ----------------------------------------------------------------------------------------------
# compensation on an AC table
def test_compensation_round_trip_on_an_ac_table():
    machine = table_machine("AC-table")
    model = ErrorModel({**_rotary_errors("AC-table", 1e-3), "EZ0T": 0.01, "EC0Y": 2e-5, "EYX2": 3e-7},
                       kind="AC-table")
    rng = np.random.default_rng(7)
    n = 50
    A, C = np.radians(rng.uniform(-100, -5, n)), np.radians(rng.uniform(-180, 180, n))
    tip = rng.uniform(-80, 80, (n, 3))
    axis = machine.tool_axis_np(A, C)
    before = model.predict(machine, A, C, *machine.linear_axes(tip, A, C).T)
    assert before.tip_dev_um.max() > 20.0
    res = compensate(model, machine, tip, axis, A, C)
    after = model.predict(machine, *res)
    assert np.max(np.linalg.norm(after.tip - tip, axis=1)) * 1e3 < 1e-6  # um
    assert np.max(np.linalg.norm(np.cross(after.axis, axis), axis=1)) < 1e-12
    assert res.tip_residual_um.max() < 1e-6 and res.iterations < 10
    # the same branch; C moves by up to ~ the axis errors / sin(A) near the pole
    assert np.max(np.abs(res[0] - A)) < 1e-2
    assert np.all(np.abs(res[1] - C) < 5e-3 / np.abs(np.sin(A)))
