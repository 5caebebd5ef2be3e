"""What the mutation run of camsmooth/smoothing/pole.py (benchmarks/mutation.py, target "pole")
showed the pole tests leave open: the passage's figures (turn and peak speed of the outer axis from
the angles it is given, the limit it is compared with), passages on rows after the first, the cone
half-angle argument, and the warm start where a passage touches a row's end (held outer axis) or the
times are uneven (the outer axis linear in time, not in point index). Expected values are computed
here from the definitions in the module docstring (cone membership from the pole's direction,
speeds as finite differences of the angles given)."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.machine.kinematics import load_machine
from camsmooth.smoothing.pole import POLE_CONE_DEG, find_passages, passage_mask, pole_start

EX, EY, EZ = np.eye(3)


def _row(miss_deg: float, n: int = 41, span_deg: float = 30.0) -> np.ndarray:
    """Unit tool axes on a great circle passing miss_deg from +X (the AB head's pole B = +90 deg),
    tilted toward +Z, moving along Y: T(u) = cos u p + sin u e_y, u in +-span (u = 0 at n // 2)."""
    d = np.radians(miss_deg)
    p = np.cos(d) * EX + np.sin(d) * EZ
    u = np.radians(np.linspace(-span_deg, span_deg, n))
    return np.cos(u)[:, None] * p + np.sin(u)[:, None] * EY


def _cone(T: np.ndarray, cone_deg: float = POLE_CONE_DEG) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(np.abs(T @ EX), 0.0, 1.0))) < cone_deg


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    out, k = [], 0
    while k < len(mask):
        if mask[k]:
            j = k
            while j + 1 < len(mask) and mask[j + 1]:
                j += 1
            out.append((k, j))
            k = j + 1
        else:
            k += 1
    return out


def _uneven_times(n: int) -> np.ndarray:
    """0, 0.01, 0.025, 0.035, 0.05, ... s: steps alternating 10 and 15 ms."""
    return np.r_[0.0, np.cumsum(np.where(np.arange(n - 1) % 2 == 0, 0.010, 0.015))]


def _exact(m, T: np.ndarray) -> np.ndarray:
    return m.solve_row(T).rotary.values


def test_passage_figures_from_the_angles_given_on_the_second_row():
    """Row 3 stays 40 deg from the pole, row 7 passes it 3 deg away. With an outer angle given as
    q = 0.2 + 5 t^2 (rad, t s from the row's start, uneven steps) the passage's turn is |q(hi) -
    q(lo)| and its peak speed the largest |dq / dt| between lo and hi, lo and hi the points just
    outside the cone (deg, deg/s); indices are within the row; the limit is the A axis' vmax
    (60 deg/s on the default machine)."""
    m = load_machine(None)
    o = m.outer_index
    far = _row(40.0, n=15)
    near = _row(3.0)
    T = np.r_[far, near]
    rows = np.r_[np.full(len(far), 3), np.full(len(near), 7)]
    t = np.r_[_uneven_times(len(far)), _uneven_times(len(near))]
    angles = np.zeros((len(T), 2))
    angles[:, o] = 0.2 + 5.0 * t ** 2
    angles[:, 1 - o] = 0.3
    got = find_passages(m, T, rows, t, angles)
    [(a, b)] = _runs(_cone(near))
    assert len(got) == 1
    p = got[0]
    assert (p.row, p.first, p.last, p.points) == (7, a, b, b - a + 1)
    assert p.closest_point == len(near) // 2 and p.closest_deg == pytest.approx(3.0, abs=1e-9)
    assert p.outer == "A"
    tn = _uneven_times(len(near))
    q = 0.2 + 5.0 * tn ** 2
    lo, hi = a - 1, b + 1
    assert p.outer_turn_deg == pytest.approx(np.degrees(q[hi] - q[lo]), rel=1e-12)
    speeds = [(q[k + 1] - q[k]) / (tn[k + 1] - tn[k]) for k in range(lo, hi)]
    assert p.outer_peak_speed == pytest.approx(np.degrees(max(speeds)), rel=1e-12)
    assert p.outer_vmax == pytest.approx(60.0, rel=1e-12)
    assert p.gamma_cost is None


def test_a_passage_at_the_start_of_a_row_measures_from_the_row_start():
    """A row that starts inside the cone: the passage begins at point 0 and its turn and speed are
    measured from point 0 (there is no point before it), up to the point after it."""
    m = load_machine(None)
    o = m.outer_index
    T = _row(3.0)[15:]
    t = _uneven_times(len(T))
    angles = np.zeros((len(T), 2))
    angles[:, o] = -1.0 + 3.0 * t
    [p] = find_passages(m, T, np.zeros(len(T), int), t, angles)
    [(a, b)] = _runs(_cone(T))
    assert (p.first, p.last) == (0, b) and a == 0
    assert p.outer_turn_deg == pytest.approx(np.degrees(3.0 * (t[b + 1] - t[0])), rel=1e-12)
    assert p.outer_peak_speed == pytest.approx(np.degrees(3.0), rel=1e-9)


@pytest.mark.parametrize("cone_deg", [4.0, 10.0, 15.0])
def test_the_cone_half_angle_decides_the_passage(cone_deg):
    m = load_machine(None)
    T = _row(2.0, n=81)
    np.testing.assert_array_equal(passage_mask(m, T, cone_deg), _cone(T, cone_deg))
    t = np.arange(len(T)) * 0.01
    [p] = find_passages(m, T, np.zeros(len(T), int), t, _exact(m, T), cone_deg=cone_deg)
    assert [(p.first, p.last)] == _runs(_cone(T, cone_deg))
    start = pole_start(m, T, np.zeros(len(T), int), t, _exact(m, T), cone_deg=cone_deg)
    exact = _exact(m, T)
    np.testing.assert_allclose(start[:p.first], exact[:p.first], atol=1e-12)
    assert not np.allclose(start[p.first:p.last + 1], exact[p.first:p.last + 1], atol=1e-6)


def test_the_warm_start_turns_the_outer_axis_linearly_in_time():
    """Uneven times: across the passage the outer angle is the straight line in time between the
    point before and the point after it (not in point index); before the passage the exact inverse,
    after it an exact inverse (the tool axis is the programmed one)."""
    m = load_machine(None)
    o = m.outer_index
    T = _row(2.0)
    t = _uneven_times(len(T))
    exact = _exact(m, T)
    start = pole_start(m, T, np.zeros(len(T), int), t, exact)
    [(a, b)] = _runs(_cone(T))
    want = np.interp(t[a:b + 1], [t[a - 1], t[b + 1]], [start[a - 1, o], start[b + 1, o]])
    np.testing.assert_allclose(start[a:b + 1, o], want, atol=1e-12)
    np.testing.assert_allclose(start[:a], exact[:a], atol=1e-12)
    got = m.tool_axis_np(start[:, 0], start[:, 1])
    np.testing.assert_allclose(got[b + 1:], T[b + 1:], atol=1e-9)
    assert abs(start[b + 1, o] - start[a - 1, o]) > np.radians(5.0)


def test_a_passage_at_a_row_end_holds_the_outer_axis():
    """A row that starts inside the cone holds the outer axis at its value just after the passage;
    one that ends inside holds it at its value just before; a row entirely inside holds it at the
    row's first angle. Each row of a two-row program on its own (row 2 does not start from row 1's
    last point)."""
    m = load_machine(None)
    o = m.outer_index
    full = _row(3.0)
    head, tail = full[15:], full[:26]
    inside = _row(1.0, n=9, span_deg=5.0)
    for T in (head, tail, inside):
        assert _cone(T)[0] or _cone(T)[-1]
    T = np.r_[tail, head, inside]
    rows = np.r_[np.zeros(len(tail), int), np.ones(len(head), int), np.full(len(inside), 2)]
    t = np.r_[_uneven_times(len(tail)), _uneven_times(len(head)), _uneven_times(len(inside))]
    exact = np.r_[_exact(m, tail), _exact(m, head), _exact(m, inside)]
    start = pole_start(m, T, rows, t, exact)
    s_tail, s_head, s_in = start[:len(tail)], start[len(tail):len(tail) + len(head)], start[len(tail) + len(head):]
    [(a, _)] = _runs(_cone(tail))
    np.testing.assert_allclose(s_tail[a:, o], exact[a - 1, o], atol=1e-12)
    [(_, b)] = _runs(_cone(head))
    e_head = exact[len(tail):len(tail) + len(head)]
    np.testing.assert_allclose(s_head[:b + 1, o], e_head[b + 1, o], atol=1e-12)
    np.testing.assert_allclose(s_head[b + 1:], e_head[b + 1:], atol=1e-12)
    np.testing.assert_allclose(s_in[:, o], exact[len(tail) + len(head), o], atol=1e-12)
    # the tool axis stays within the pole angle of the programmed one where the outer axis is held
    got = m.tool_axis_np(start[:, 0], start[:, 1])
    dev = np.arccos(np.clip(np.einsum("ij,ij->i", got, T), -1.0, 1.0))
    pole = np.arccos(np.clip(np.abs(T @ EX), 0.0, 1.0))
    assert np.all(dev <= pole + 1e-9)


def _ac_table():
    from camsmooth.machine.kinematics import machine_from_dict

    return machine_from_dict({"machine": {"kind": "AC-table"},
                              "axis": {"A": {"min": -110.0, "max": 30.0, "vmax": 60.0, "amax": 300.0},
                                       "C": {"vmax": 90.0, "amax": 300.0, "min": -720.0, "max": 720.0}}})


def _nearest_branch(m, T_exit: np.ndarray, entry: float) -> np.ndarray:
    """Of both inverse branches at T_exit, each unwound by whole turns toward ``entry``, the one within
    the travel whose outer angle is nearest ``entry`` (brute force over Machine.inverse_axis)."""
    o = m.outer_index
    best = None
    for cand in m.inverse_axis(T_exit[None])[0]:
        c = cand.copy()
        c[o] += 2 * np.pi * np.round((entry - c[o]) / (2 * np.pi))
        if all(bool(m.within(n, c[k])) for k, n in enumerate(m.rotary)):
            if best is None or abs(c[o] - entry) < abs(best[o] - entry):
                best = c
    return best


@pytest.mark.parametrize("kind, turn_deg", [("AB-head", 0.0), ("AC-table", 0.0), ("AC-table", 90.0),
                                            ("AC-table", -90.0), ("AC-table", 180.0)])
def test_after_the_passage_the_branch_nearest_the_entry_within_the_travel(kind, turn_deg):
    """At the passage's exit the start takes, of the two inverse branches (each unwound by whole
    turns toward the outer angle before the passage) within the travel, the one whose outer angle is
    nearest the entry's (brute force here), and the rest of the row continues on it as an exact
    inverse. On the AC table the exact inverse turns C by 110-177 deg across these passages and the
    other branch (-A, C + 180 deg) is the nearer one: the start changes branch; the part and the row
    turned about C give the same choice with C shifted."""
    m = load_machine(None) if kind == "AB-head" else _ac_table()
    o = m.outer_index
    pole = EX if kind == "AB-head" else EZ
    side = EZ if kind == "AB-head" else -EX
    ph = np.radians(turn_deg)
    rz = np.array([[np.cos(ph), -np.sin(ph), 0.0], [np.sin(ph), np.cos(ph), 0.0], [0.0, 0.0, 1.0]])
    for miss in (0.5, 2.0, 6.0):
        d = np.radians(miss)
        u = np.radians(np.linspace(-25.0, 25.0, 41))
        T = (np.cos(u)[:, None] * (np.cos(d) * pole + np.sin(d) * side) + np.sin(u)[:, None] * EY) @ rz.T
        t = np.arange(len(T)) * 0.01
        exact = _exact(m, T)
        start = pole_start(m, T, np.zeros(len(T), int), t, exact)
        cone = np.degrees(np.arccos(np.clip(np.abs(T @ pole), 0.0, 1.0))) < POLE_CONE_DEG
        [(a, b)] = _runs(cone)
        best = _nearest_branch(m, T[b + 1], start[a - 1, o])
        np.testing.assert_allclose(start[b + 1], best, atol=1e-9)
        if kind == "AC-table":
            assert abs(start[b + 1, o] - exact[b + 1, o]) > np.radians(90.0)  # the branch did change
        got = m.tool_axis_np(start[b + 1:, 0], start[b + 1:, 1])
        np.testing.assert_allclose(got, T[b + 1:], atol=1e-9)
        assert np.all(np.abs(np.diff(start[b + 1:], axis=0)) < np.radians(10.0))  # continues on that branch


def test_the_warm_start_leaves_the_angles_given_untouched():
    """pole_start returns a new array: the exact inverse the caller passes (and keeps using for the
    programmed orientation) is not overwritten by the start across the passage."""
    m = load_machine(None)
    T = _row(2.0)
    t = np.arange(len(T)) * 0.01
    exact = _exact(m, T)
    kept = exact.copy()
    start = pole_start(m, T, np.zeros(len(T), int), t, exact)
    np.testing.assert_array_equal(exact, kept)
    assert not np.allclose(start, kept)


def test_points_at_the_same_instant_give_an_infinite_peak_speed_without_a_warning():
    """Two points of the passage at the same time (a repeated point of the program): where the
    outer angle jumps between them the speed is infinite, where it does not 0 / 0 is no speed; both
    are computed silently (no bare numpy warning reaches the user)."""
    import warnings

    m = load_machine(None)
    o = m.outer_index
    T = _row(3.0)
    [(a, b)] = _runs(_cone(T))
    t = np.arange(len(T)) * 0.01
    t[a + 2:] -= 0.01          # points a + 1 and a + 2 at the same instant
    t[a + 5:] -= 0.01          # and a + 4, a + 5
    angles = np.zeros((len(T), 2))
    angles[:, o] = np.arange(len(T)) * 0.1
    angles[a + 5:, o] -= 0.1   # the angle stands still between a + 4 and a + 5
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        [p] = find_passages(m, T, np.zeros(len(T), int), t, angles)
    assert p.outer_peak_speed == np.inf
    angles[a + 2:, o] -= 0.1   # no jump at the first repeated instant either: the largest finite speed
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        [p] = find_passages(m, T, np.zeros(len(T), int), t, angles)
    assert p.outer_peak_speed == pytest.approx(np.degrees(0.1 / 0.01), rel=1e-12)


def test_the_peak_speed_is_taken_over_the_passage_only():
    """A fast outer axis before the passage (1 rad per 10 ms step) does not count: the peak is that
    of the passage and its two neighbours (0.05 rad per step, 5 rad/s)."""
    m = load_machine(None)
    o = m.outer_index
    T = _row(3.0)
    [(a, b)] = _runs(_cone(T))
    t = np.arange(len(T)) * 0.01
    step = np.where(np.arange(len(T)) < a - 2, 1.0, 0.05)
    angles = np.zeros((len(T), 2))
    angles[:, o] = np.r_[0.0, np.cumsum(step[:-1])]
    [p] = find_passages(m, T, np.zeros(len(T), int), t, angles)
    assert p.outer_peak_speed == pytest.approx(np.degrees(5.0), rel=1e-12)


def test_a_one_point_row_in_the_cone_has_no_speed():
    m = load_machine(None)
    T = _row(1.0, n=1, span_deg=0.0)
    [p] = find_passages(m, T, np.zeros(1, int), np.zeros(1), np.zeros((1, 2)))
    assert (p.first, p.last, p.outer_turn_deg, p.outer_peak_speed) == (0, 0, 0.0, 0.0)


def test_a_passage_ending_one_point_before_the_row_end_turns_toward_the_last_point():
    """The row's last point is the first outside the cone: the outer axis turns, linearly in time,
    from the point before the passage to that last point (it is not held)."""
    m = load_machine(None)
    o = m.outer_index
    full = _row(2.0)
    [(a, b)] = _runs(_cone(full))
    T = full[:b + 2]
    t = _uneven_times(len(T))
    start = pole_start(m, T, np.zeros(len(T), int), t, _exact(m, T))
    want = np.interp(t[a:b + 1], [t[a - 1], t[b + 1]], [start[a - 1, o], start[b + 1, o]])
    np.testing.assert_allclose(start[a:b + 1, o], want, atol=1e-12)
    assert abs(start[b + 1, o] - start[a - 1, o]) > np.radians(5.0)
