"""Kinematics: the POE chain against METHODS section 1 closed forms, IK branches and round trips,
numpy/CasADi agreement, machine-file errors."""

import casadi as ca
import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, exp_twist, load_machine, machine_from_dict


def _rx(a):
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _ry(b):
    return np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])


def _wide_machine():
    import tomllib

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["axis"]["A"].update(min=-360.0, max=360.0)
    data["axis"]["B"].update(min=-180.0, max=180.0)
    return machine_from_dict(data)


def test_forward_matches_rotation_product_and_pivot():
    m = load_machine()
    rng = np.random.default_rng(1)
    A, B = rng.uniform(-1.5, 1.5, 50), rng.uniform(-1.5, 1.5, 50)
    X, Y, Z = rng.uniform(-100, 100, (3, 50))
    tip, axis = m.tool_pose_np(A, B, X, Y, Z)
    for k in range(50):
        R = _rx(A[k]) @ _ry(B[k])
        np.testing.assert_allclose(axis[k], R[:, 2], atol=1e-14)
        np.testing.assert_allclose(tip[k], np.array([X[k], Y[k], Z[k]]) - m.pivot * R[:, 2], atol=1e-11)
    closed = np.stack([np.sin(B), -np.sin(A) * np.cos(B), np.cos(A) * np.cos(B)], -1)
    np.testing.assert_allclose(axis, closed, atol=1e-14)


def test_exp_twist_is_a_rigid_motion_and_matches_scipy_expm():
    from scipy.linalg import expm

    w = np.array([0.3, -0.5, 0.8])
    w /= np.linalg.norm(w)
    v = -np.cross(w, [10.0, -3.0, 7.0])
    theta = 0.7
    S = np.zeros((4, 4))
    S[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
    S[:3, 3] = v
    np.testing.assert_allclose(exp_twist(w, v, theta).to_numpy(), expm(S * theta), atol=1e-12)


def test_ik_fk_round_trip_both_branches():
    m = _wide_machine()
    rng = np.random.default_rng(2)
    T = rng.normal(size=(200, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    sols = m.inverse_axis(T)
    for branch in (0, 1):
        back = m.tool_axis_np(sols[:, branch, 0], sols[:, branch, 1])
        np.testing.assert_allclose(back, T, atol=1e-12)
    # the two branches are different joint configurations
    assert np.all(np.abs(sols[:, 0] - sols[:, 1]).max(axis=1) > 1e-3)


def test_solve_row_picks_branch_in_limits_and_unwraps():
    m = load_machine()  # A, B in [-100, 100] deg: only branch 0 reachable for modest axes
    s = np.linspace(0, 1, 100)
    A_true, B_true = np.radians(30) * np.sin(3 * s), np.radians(20) * np.cos(2 * s)
    T = m.tool_axis_np(A_true, B_true)
    r = m.solve_row(T)
    np.testing.assert_allclose(r.rotary["A"], A_true, atol=1e-12)
    np.testing.assert_allclose(r.rotary["B"], B_true, atol=1e-12)
    assert r.unreachable.size == 0
    # a wide machine: continuity across the +-180 deg wrap of A
    w = _wide_machine()
    A_wrap = np.radians(np.linspace(170, 190, 50))
    T = w.tool_axis_np(A_wrap, np.full(50, 0.2))
    r = w.solve_row(T, previous=(A_wrap[0], 0.2))
    assert np.max(np.abs(np.diff(r.rotary["A"]))) < np.radians(1.0)
    np.testing.assert_allclose(w.tool_axis_np(*r.rotary.pair), T, atol=1e-12)


def test_unreachable_points_are_named():
    m = load_machine()
    T = m.tool_axis_np(np.radians([0, 10, 20]), np.radians([0, 0, 0]))
    T[1] = [0.0, -1.0, -0.2]  # needs A beyond 100 deg
    T[1] /= np.linalg.norm(T[1])
    r = m.solve_row(T)
    assert list(r.unreachable) == [1]


def test_numpy_and_casadi_share_one_chain():
    m = load_machine()
    a, b, x, y, z = (ca.SX.sym(k) for k in "abxyz")
    tip, axis = m.tool_pose(a, b, x, y, z)
    f = ca.Function("f", [a, b, x, y, z], [ca.vertcat(*tip), ca.vertcat(*axis)])
    rng = np.random.default_rng(3)
    for _ in range(10):
        q = rng.uniform(-1, 1, 5) * np.array([1.5, 1.5, 100, 100, 100])
        tip_c, axis_c = (np.asarray(v).ravel() for v in f(*q))
        tip_n, axis_n = m.tool_pose_np(*[np.array([v]) for v in q])
        np.testing.assert_allclose(tip_c, tip_n[0], atol=1e-12)
        np.testing.assert_allclose(axis_c, axis_n[0], atol=1e-14)


@pytest.mark.parametrize("patch, words", [
    ({"machine": {"kind": "XY-table", "pivot": 100.0}}, "not supported"),
    ({"machine": {"kind": "AC-table", "pivot": 100.0}}, "no head pivot"),
    ({"machine": {"kind": "AB-head", "pivot": -5.0}}, "pivot"),
    ({"axis": {"A": {"min": 10.0, "max": -10.0, "vmax": 1.0, "amax": 1.0}}}, "min"),
    ({"axis": {"B": {"min": -10.0, "max": 10.0, "vmax": 0.0, "amax": 1.0}}}, "vmax"),
])
def test_bad_machine_file(tmp_path, patch, words):
    import tomllib

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    for key, value in patch.items():
        data[key] = {**data[key], **value}
    with pytest.raises(InputError, match=words):
        machine_from_dict(data, "m.toml")


def test_missing_machine_file_named(tmp_path):
    with pytest.raises(InputError, match="not found"):
        load_machine(str(tmp_path / "nope.toml"))


def test_inverse_candidates_are_every_solution_within_limits():
    m = _wide_machine()  # A in [-360, 360], B in [-180, 180] deg
    T = m.tool_axis_np(np.radians([30.0, -120.0]), np.radians([20.0, -60.0]))
    cand, ok = m.inverse_candidates(T)
    for i in range(2):
        sols = cand[i][ok[i]]
        np.testing.assert_allclose(m.tool_axis_np(sols[:, 0], sols[:, 1]), np.tile(T[i], (len(sols), 1)), atol=1e-12)
        # independent count: A = a0 + 2 pi k within +-360 deg (2 or 3 values per branch), B within +-180
        expected = 0
        for a0, b0 in m.inverse_axis(T[i:i + 1])[0]:
            na = sum(-2 * np.pi <= a0 + 2 * np.pi * k <= 2 * np.pi for k in (-1, 0, 1))
            nb = sum(-np.pi <= b0 + 2 * np.pi * k <= np.pi for k in (-1, 0, 1))
            expected += na * nb
        assert ok[i].sum() == expected >= 4
