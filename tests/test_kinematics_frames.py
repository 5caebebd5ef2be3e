"""Rigid transforms and the AB head (camsmooth.machine.kinematics) against plain 4x4 matrix
algebra written here: Frame composition, points and directions with float, numpy and CasADi
entries (including the exact 0 and 1 entries the products skip), joint screws, the pivot
placement, the travel mask and both inverse branches at the ends of their ranges."""

from __future__ import annotations

import math
import tomllib
import warnings

import casadi as ca
import numpy as np
import pytest

from camsmooth.machine.kinematics import (
    DEFAULT_MACHINE_TOML,
    IDENTITY,
    Chain,
    Frame,
    Joint,
    exp_twist,
    load_machine,
    machine_from_dict,
    space_jacobian,
)


def _rot(axis, angle):
    """Rodrigues' rotation matrix, written out."""
    k = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _matrix(R, p):
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, p
    return M


# a quarter turn about z with a unit translation: entries exactly 0, 1 and -1
QUARTER = _matrix([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], [1.0, 1.0, 0.0])
GENERAL = _matrix(_rot([1.0, 2.0, -0.5], 0.7), [0.3, -2.0, 5.0])


@pytest.mark.parametrize("M", [QUARTER, GENERAL, np.eye(4)])
def test_points_directions_and_products_match_matrix_algebra(M):
    f = Frame.from_matrix(M)
    np.testing.assert_array_equal(f.to_numpy(), M)
    for x in ([1.0, 1.0, 1.0], [0.0, 1.0, 0.0], [2.5, -1.0, 0.25], [2.0, 2.0, 2.0]):
        np.testing.assert_allclose(f.apply(tuple(x)), M[:3, :3] @ x + M[:3, 3], atol=1e-15)
        np.testing.assert_allclose(f.rotate(tuple(x)), M[:3, :3] @ x, atol=1e-15)
    for N in (QUARTER, GENERAL):
        np.testing.assert_allclose((f @ Frame.from_matrix(N)).to_numpy(), M @ N, atol=1e-14)
    # numpy entries: (n,) arrays per coordinate, one transform per column
    xs = np.array([[1.0, 0.0, -1.0], [2.0, 1.0, 0.0], [0.0, 3.0, 1.0]])
    np.testing.assert_allclose(np.array(f.apply(tuple(xs))), M[:3, :3] @ xs + M[:3, 3:], atol=1e-14)
    np.testing.assert_allclose(np.array(f.rotate(tuple(xs))), M[:3, :3] @ xs, atol=1e-14)


def test_casadi_entries_give_the_same_transform_without_the_numpy_fallback():
    # CasADi expressions are built with CasADi's own sin/cos: the numpy ufunc path on CasADi
    # objects is deprecated (FutureWarning) and must not be what the NLP relies on
    m = load_machine()
    q = ca.SX.sym("q", 5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tip, axis = m.tool_pose(q[0], q[1], q[2], q[3], q[4])
        f = exp_twist([0.0, 0.0, 1.0], [0.0, -1.0, 0.0], q[0])
        pt = f.apply((q[1], 1.0, 0.0))
    fun = ca.Function("f", [q], [ca.vertcat(*tip), ca.vertcat(*axis), ca.vertcat(*pt)])
    vals = np.array([0.4, -0.3, 10.0, -20.0, 5.0])
    tip_c, axis_c, pt_c = (np.asarray(v).ravel() for v in fun(vals))
    tip_n, axis_n = m.tool_pose_np(*vals)
    np.testing.assert_allclose(tip_c, tip_n, atol=1e-12)
    np.testing.assert_allclose(axis_c, axis_n, atol=1e-15)
    # screw about z through (1, 0, 0) (v = -w x p = (0, -1, 0)): rotation by q0 about that line
    R = _rot([0, 0, 1], 0.4)
    np.testing.assert_allclose(pt_c, R @ (np.array([-0.3, 1.0, 0.0]) - [1, 0, 0]) + [1, 0, 0], atol=1e-15)


def test_joint_screws_from_direction_and_point():
    w, v = Joint("A", "revolute", (0.0, 2.0, 0.0), (2, 0, 0)).screw()   # direction normalised here
    np.testing.assert_array_equal(w, [0.0, 1.0, 0.0])
    np.testing.assert_array_equal(v, [0.0, 0.0, 2.0])   # v = -w x p
    w, v = Joint("X", "prismatic", (0, 0, 5)).screw()
    np.testing.assert_array_equal(w, [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(v, [0.0, 0.0, 1.0])
    with pytest.raises(ValueError, match=r"^joint C: unknown kind 'helical'$"):
        Joint("C", "helical", (0, 0, 1)).screw()
    # the revolute screw turns points about its own line: (2, y, 0) stays on it, others turn about it
    f = exp_twist(*Joint("A", "revolute", (0.0, 2.0, 0.0), (2, 0, 0)).screw(), 1.2)
    np.testing.assert_allclose(f.apply((2.0, 7.0, 0.0)), [2.0, 7.0, 0.0], atol=1e-14)
    np.testing.assert_allclose(f.apply((3.0, 1.0, 0.0)), _rot([0, 1, 0], 1.2) @ [1.0, 1.0, 0.0] + [2, 0, 0],
                               atol=1e-14)


def test_pivot_placement_and_default_linear_axes():
    m = load_machine()  # pivot 150 mm
    cl = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
    T = np.array([[0.0, 0.6, 0.8], [1.0, 0.0, 0.0]])
    ang = m.inverse_axis(T)[:, 0]
    # pivot = CL + L_p T
    np.testing.assert_allclose(m.linear_axes(cl, ang[:, 0], ang[:, 1]), cl + 150.0 * T, atol=1e-13)
    # X = Y = Z = 0 by default: the pivot at the origin, the tip pivot length below it along -T
    A, B = 0.3, -0.2
    tip, axis = m.tool_pose_np(A, B, 0.0, 0.0, 0.0)
    tip_d, axis_d = m.tool_pose(A, B)
    np.testing.assert_allclose(np.array(tip_d, float), tip, atol=1e-14)
    np.testing.assert_allclose(m.tool_axis_np(A, B), axis, atol=1e-15)
    # plain floats (the products skip exact zeros and ones)
    tip_f, _ = m.tool_pose(0.0, 0.0, 1.0, 2.0, 3.0)
    np.testing.assert_allclose(np.array(tip_f, float), [1.0, 2.0, 3.0 - 150.0], atol=0)
    np.testing.assert_allclose(tip, -150.0 * axis, atol=1e-12)
    # several poses come back as (N, 3) rows
    tips, axes = m.tool_pose_np([0.0, A], [0.0, B], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0])
    assert tips.shape == axes.shape == (2, 3)
    np.testing.assert_allclose(tips[0], [1.0, 2.0, 3.0 - 150.0], atol=1e-12)
    np.testing.assert_allclose(m.tool_axis_np([0.0, A], [0.0, B])[1],
                               [math.sin(B), -math.sin(A) * math.cos(B), math.cos(A) * math.cos(B)], atol=1e-15)


def test_travel_mask_includes_its_ends_and_unlimited_axes():
    m = load_machine()  # A in [-100, 100] deg
    lo, hi = m.limits["A"].min, m.limits["A"].max
    vals = np.array([lo - 1e-6, lo - 5e-10, lo, hi, hi + 5e-10, hi + 1e-6])
    assert m.within("A", vals).tolist() == [False, True, True, True, True, False]
    assert m.within("A", vals, tol=0.0).tolist() == [False, False, True, True, False, False]
    free = m.within("C", np.zeros((2, 3)))   # no limits for an axis the machine does not list
    assert free.dtype == bool and free.shape == (2, 3) and free.all()


def test_both_inverse_branches_at_the_ends_of_their_ranges():
    m = load_machine()
    # T with |i| slightly above 1 from rounding, straight up, and the two horizontal extremes
    T = np.array([[1.0 + 1e-15, 0.0, 0.0], [-1.0 - 1e-15, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    sol = m.inverse_axis(T)
    assert sol.shape == (4, 2, 2)
    assert np.all(np.isfinite(sol))
    np.testing.assert_allclose(sol[0, 0, 1], math.pi / 2, atol=1e-7)
    np.testing.assert_allclose(sol[1, 0, 1], -math.pi / 2, atol=1e-7)
    np.testing.assert_allclose(sol[2], [[0.0, 0.0], [math.pi, math.pi]], atol=1e-15)
    np.testing.assert_allclose(sol[3, 0], [math.pi / 2, 0.0], atol=1e-15)
    # branch 1 is A + pi, pi - B wrapped to (-pi, pi]: A = pi / 2 -> -pi / 2
    np.testing.assert_allclose(sol[3, 1], [-math.pi / 2, math.pi], atol=1e-15)
    for b in range(2):
        np.testing.assert_allclose(m.tool_axis_np(sol[:, b, 0], sol[:, b, 1]), np.clip(T, -1, 1), atol=1e-7)
    # a single axis as a 1-D vector
    assert m.inverse_axis([0.0, 0.0, 1.0]).shape == (1, 2, 2)


def test_identity_frame_leaves_points_in_place():
    x = (1.0, -2.0, 3.0)
    assert IDENTITY.apply(x) == x and IDENTITY.rotate(x) == x


def _rpr_chain():
    """An R-P-R-P arm (not the AB head): prismatic joints after rotations."""
    joints = (Joint("R1", "revolute", (0.0, 0.0, 1.0), (1.0, 0.0, 0.0)),
              Joint("P", "prismatic", (1.0, 0.0, 0.0)),
              Joint("R2", "revolute", (0.0, 1.0, 0.0), (2.0, 0.0, 3.0)),
              Joint("P2", "prismatic", (0.0, 0.6, 0.8)))
    home = _matrix(_rot([1, 1, 0], 0.3), [4.0, -1.0, 2.0])
    return Chain(joints, home)


def _forward_matrix(chain, q):
    """T(q) = prod exp([S_i] q_i) M with each exponential as a 4x4 matrix (scipy expm)."""
    from scipy.linalg import expm

    M = np.eye(4)
    for j, (w, v) in zip(chain.joints, chain.joint_screws(), strict=True):
        S = np.zeros((4, 4))
        S[:3, :3] = [[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]]
        S[:3, 3] = v
        M = M @ expm(S * q.get(j.name, 0.0))
    return M @ chain.home


def test_space_jacobian_of_a_general_chain_against_finite_differences():
    chain = _rpr_chain()
    q = {"R1": 0.7, "P": 1.5, "R2": -0.4, "P2": 2.0}
    np.testing.assert_allclose(chain.forward(q).to_numpy(), _forward_matrix(chain, q), atol=1e-12)
    J = space_jacobian(chain, {k: np.array([v]) for k, v in q.items()})[0]
    h = 1e-6
    T0 = _forward_matrix(chain, q)
    tip = T0[:3, 3]
    for i, name in enumerate(chain.names):
        dT = (_forward_matrix(chain, {**q, name: q[name] + h}) - _forward_matrix(chain, {**q, name: q[name] - h}))
        dT /= 2 * h
        w, v = J[:3, i], J[3:, i]
        np.testing.assert_allclose(dT[:3, 3], v + np.cross(w, tip), atol=1e-7)   # d tip / dq = v + w x tip
        np.testing.assert_allclose(dT[:3, :3], np.cross(w, T0[:3, :3].T).T, atol=1e-7)
    # one column wanted: the same column, the others zero; none wanted: all zero
    J1 = space_jacobian(chain, {k: np.array([v]) for k, v in q.items()}, joints=["P"])[0]
    np.testing.assert_array_equal(J1[:, 1], J[:, 1])
    assert not J1[:, [0, 2, 3]].any()
    assert not space_jacobian(chain, q, joints=[]).any()
    # missing joints are at 0
    np.testing.assert_allclose(space_jacobian(chain, {"P": 1.5})[0],
                               space_jacobian(chain, {"R1": 0.0, "P": 1.5, "R2": 0.0, "P2": 0.0})[0], atol=0)
    np.testing.assert_allclose(chain.forward({"P": 1.5}).to_numpy(), _forward_matrix(chain, {"P": 1.5}), atol=1e-12)


def test_chain_with_other_screws_and_home():
    chain = _rpr_chain()
    q = {"R1": 0.2, "P": -0.5, "R2": 1.0, "P2": 0.3}
    same = chain.with_screws([(list(w), list(v)) for w, v in chain.joint_screws()])
    np.testing.assert_allclose(same.forward(q).to_numpy(), chain.forward(q).to_numpy(), atol=0)
    moved = chain.with_screws(chain.joint_screws(), home=np.eye(4))
    np.testing.assert_allclose(moved.forward(q).to_numpy() @ chain.home, chain.forward(q).to_numpy(), atol=1e-14)
    # a screw list that does not match the joints is refused, not silently truncated
    short = chain.with_screws(chain.joint_screws()[:2])
    with pytest.raises(ValueError):
        short.forward(q)
    with pytest.raises(ValueError):
        space_jacobian(short, q)


def _machine(a_deg, b_deg, x_mm=None):
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["axis"]["A"].update(min=-a_deg, max=a_deg)
    data["axis"]["B"].update(min=-b_deg, max=b_deg)
    if x_mm is not None:
        data["axis"]["X"].update(min=-x_mm, max=x_mm)
    return machine_from_dict(data)


def test_solve_row_reaches_every_axis_within_travel():
    m = load_machine()  # A, B in [-100, 100] deg
    # the first point is reachable on branch 0 only, the second on branch 1 only (A0 = -150 deg)
    A = np.radians([0.0, -150.0, 20.0])
    B = np.radians([0.0, 85.0, -10.0])
    T = m.tool_axis_np(A, B)
    res = m.solve_row(T)
    assert res.unreachable.size == 0 and res.xyz is None
    np.testing.assert_allclose(m.tool_axis_np(*res.rotary.pair), T, atol=1e-12)
    assert m.within("A", res.rotary["A"]).all() and m.within("B", res.rotary["B"]).all()
    np.testing.assert_allclose(np.degrees([res.rotary["A"][1], res.rotary["B"][1]]), [30.0, 95.0], atol=1e-9)


def test_solve_row_start_and_out_of_travel_points():
    wide = _machine(200.0, 100.0, x_mm=100.0)
    T = wide.tool_axis_np(np.radians([-160.0, 170.0, 0.0]), np.radians([0.0, 0.0, 0.0]))
    # from (0, 0) the first point takes A = -160 (nearer than +200)
    res = wide.solve_row(T[:1])
    assert np.degrees(res.rotary["A"][0]) == pytest.approx(-160.0)
    # (A, B) = (120, 50) deg: nearer to (0, 0) than the other branch (-60, 130) deg, which is nearer to
    # (0, 57) deg: the start is (0, 0) in both angles
    tall = _machine(200.0, 180.0)
    res = tall.solve_row(tall.tool_axis_np(np.radians([120.0]), np.radians([50.0])))
    np.testing.assert_allclose(np.degrees([res.rotary["A"][0], res.rotary["B"][0]]), [120.0, 50.0], atol=1e-9)
    # from a previous A of 400 deg the nearest candidate (530 deg) is out of travel: 170 is taken
    res = wide.solve_row(T[1:2], previous=(np.radians(400.0), 0.0))
    assert np.degrees(res.rotary["A"][0]) == pytest.approx(170.0) and res.unreachable.size == 0
    # X beyond its travel: X = cl_x + pivot T_x with pivot 150 mm, T vertical
    cl = np.array([[0.0, 0.0, 0.0], [120.0, 0.0, 0.0], [-50.0, 0.0, 0.0]])
    up = np.tile([0.0, 0.0, 1.0], (3, 1))
    res = wide.solve_row(up, cl)
    np.testing.assert_allclose(res.xyz, cl + 150.0 * up, atol=0)
    assert res.unreachable.tolist() == [1]
