"""What the mutation run of camsmooth/smoothing/jerk.py (benchmarks/mutation.py, target "jerk")
showed the plan-level tests leave open: the law's building blocks, each against a closed form
written here (the nodes of a row, the feed bound of a piece, a law evaluated by the chain rule on a
path whose axes are polynomials in s, the uniform slow-down, the limit ratios). The plan-level
tests (tests/test_jerk.py: an independent direct NLP, the dense check) take minutes; these take
milliseconds, so a mutant of the building blocks is caught without replanning."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from scipy.interpolate import CubicSpline

from camsmooth.smoothing.jerk import GRADING, MIN_INTERVALS, JerkLaw, Rates, _nodes, _piece_feed, _slowed, law_rates


def test_nodes_split_each_piece_and_grade_the_ends():
    """Three points s = 0, 1, 2: each piece in r = ceil(120 / 2) = 60 equal parts, plus the first
    and last intervals halved GRADING (12) times toward the row's ends: 121 + 24 nodes; the points
    are nodes 0, 72 and 144; a node's piece is the piece it starts."""
    assert (MIN_INTERVALS, GRADING) == (120, 12)
    rp = SimpleNamespace(s=np.array([0.0, 1.0, 2.0]))
    s, points, piece = _nodes(rp)
    h = 1 / 60
    uniform = np.r_[np.arange(120) * h, 2.0]
    graded = np.r_[h * 0.5 ** np.arange(12, 0, -1), 2.0 - h * 0.5 ** np.arange(12, 0, -1)]
    np.testing.assert_allclose(s, np.sort(np.r_[uniform, graded]), atol=1e-15)
    assert len(s) == 145
    assert points.tolist() == [0, 72, 144]
    np.testing.assert_array_equal(s[points], rp.s)
    assert piece.tolist() == [0] * 72 + [1] * 72


def test_a_long_row_keeps_one_interval_per_piece():
    """200 points: 120 intervals need no split (r = 1): the nodes are the points and the 24 graded
    ones."""
    rp = SimpleNamespace(s=np.linspace(0.0, 10.0, 200))
    s, points, piece = _nodes(rp)
    assert len(s) == 200 + 24
    np.testing.assert_array_equal(s[points], rp.s)
    assert piece[0] == 0 and piece[-1] == 198 and np.all(np.diff(piece) >= 0)


def test_a_row_whose_pieces_do_not_divide_the_intervals_evenly():
    """50 points (49 pieces): r = ceil(120 / 49) = 3 equal parts each, thirds of a piece: 147 + 1 + 24
    nodes, every point a node."""
    rp = SimpleNamespace(s=np.arange(50.0))
    s, points, _ = _nodes(rp)
    assert len(s) == 147 + 1 + 24
    np.testing.assert_array_equal(s[points], rp.s)
    k = points[4]
    np.testing.assert_allclose(s[k:k + 4], [4.0, 4 + 1 / 3, 4 + 2 / 3, 5.0], atol=1e-12)


def test_piece_feed_is_the_block_feed_recovered_from_the_point_bounds():
    """Blocks at 100, 50 and 80 mm/s: the point bounds are min(F_i, F_i+1) = 100, 50, 50, 80 at the
    points 0..4 of pieces (100, 50, 50, 80): each piece takes the larger of its two ends."""
    rp = SimpleNamespace(feed_bound=np.array([100.0, 100.0, 50.0, 50.0, 80.0]))
    assert _piece_feed(rp).tolist() == [100.0, 100.0, 50.0, 80.0]


def _quadratic_path():
    """Axes q(s) = (s^2, 3 s, 0, 0.5 s, 0) and tip p(s) = (s^2, 3 s, 0) on s = 0..2: CubicSpline
    (not-a-knot) reproduces them exactly."""
    s = np.linspace(0.0, 2.0, 5)
    q = np.column_stack([s ** 2, 3 * s, 0 * s, 0.5 * s, 0 * s])
    return SimpleNamespace(s=s, spline=CubicSpline(s, q), tip_spline=CubicSpline(s, q[:, :3]),
                           feed_bound=np.array([40.0, 40.0, 30.0, 30.0, 30.0]))


def test_law_rates_are_the_chain_rule_on_the_path():
    """A law with y, z, w given on two intervals: s(t) the cubic of each interval; X = s^2 gives
    X' = 2 s s', X'' = 2 s'^2 + 2 s s'', X''' = 6 s' s'' + 2 s s'''; Y = 3 s gives 3 s', 3 s'', 3 s''';
    the tip speed |p'(s)| s' = sqrt(4 s^2 + 9) s'; the feed bound of the piece each interval starts in."""
    rp = _quadratic_path()
    law = JerkLaw(s=np.array([0.0, 0.25, 1.0]), points=np.array([0, 2]), t=np.array([0.0, 0.5, 1.25]),
                  y=np.array([0.0, 1.0, 1.0]), z=np.array([0.0, 2.0, -1.0]), w=np.array([24.0, -4.0]),
                  slowdown=1.0, converged=True, iterations=0, solve_time=0.0)
    r = law_rates(rp, law, per_interval=5)
    tau = np.r_[np.linspace(0, 0.5, 5), np.linspace(0, 0.75, 5)]
    s0 = np.repeat([0.0, 0.25], 5)
    y, z, w = np.repeat([0.0, 1.0], 5), np.repeat([0.0, 2.0], 5), np.repeat([24.0, -4.0], 5)
    s = np.minimum(s0 + y * tau + z * tau ** 2 / 2 + w * tau ** 3 / 6, np.repeat([0.25, 1.0], 5))
    sd = y + z * tau + w * tau ** 2 / 2
    sdd = z + w * tau
    np.testing.assert_allclose(r.t, np.r_[np.linspace(0, 0.5, 5), 0.5 + np.linspace(0, 0.75, 5)], atol=1e-15)
    np.testing.assert_allclose(r.s, s, atol=1e-12)
    np.testing.assert_allclose(r.sd, np.maximum(sd, 0.0), atol=1e-12)
    sdp = np.maximum(sd, 0.0)
    np.testing.assert_allclose(r.velocity[:, 0], 2 * s * sdp, atol=1e-9)
    np.testing.assert_allclose(r.velocity[:, 1], 3 * sdp, atol=1e-9)
    np.testing.assert_allclose(r.velocity[:, 3], 0.5 * sdp, atol=1e-9)
    np.testing.assert_allclose(r.acceleration[:, 0], 2 * sdp ** 2 + 2 * s * sdd, atol=1e-9)
    np.testing.assert_allclose(r.acceleration[:, 1], 3 * sdd, atol=1e-9)
    np.testing.assert_allclose(r.jerk[:, 0], 6 * sdp * sdd + 2 * s * w, atol=1e-9)
    np.testing.assert_allclose(r.jerk[:, 1], 3 * w, atol=1e-9)
    np.testing.assert_allclose(r.velocity[:, [2, 4]], 0.0, atol=1e-12)
    np.testing.assert_allclose(r.tip_speed, np.sqrt(4 * s ** 2 + 9) * sdp, atol=1e-9)
    assert r.feed.tolist() == [40.0] * 5 + [40.0] * 5  # both intervals start in piece 0 (s < 0.5)
    # pieces [0, .5), [.5, 1), [1, 1.5), [1.5, 2] at max(40, 40), max(40, 30), 30, 30: a second interval
    # from s = 1.25 (piece 2) runs at 30
    law2 = JerkLaw(**{**law.__dict__, "s": np.array([0.0, 1.25, 1.5])})
    assert law_rates(rp, law2, per_interval=3).feed.tolist() == [40.0] * 3 + [30.0] * 3


def test_slowing_a_law_by_c_scales_time_and_its_derivatives():
    """t -> c t: s' / c, s'' / c^2, s''' / c^3; the slow-down factors multiply; the rest is kept."""
    law = JerkLaw(s=np.array([0.0, 1.0]), points=np.array([0, 1]), t=np.array([0.0, 2.0]), y=np.array([0.0, 3.0]),
                  z=np.array([4.0, 8.0]), w=np.array([16.0]), slowdown=1.5, converged=False, iterations=7,
                  solve_time=0.25)
    out = _slowed(law, 2.0)
    assert out.t.tolist() == [0.0, 4.0] and out.y.tolist() == [0.0, 1.5] and out.z.tolist() == [1.0, 2.0]
    assert out.w.tolist() == [2.0] and out.slowdown == 3.0 and out.cycle_time == 4.0
    assert (out.converged, out.iterations, out.solve_time) == (False, 7, 0.25)
    np.testing.assert_array_equal(out.s, law.s)
    np.testing.assert_array_equal(out.points, law.points)


def test_limit_ratios():
    """The largest |value| / limit per kind; a tip speed where the feed bound is 0 or missing counts 0."""
    r = Rates(t=np.zeros(3), s=np.zeros(3), sd=np.zeros(3),
              velocity=np.array([[1.0, -4.0, 0, 0, 0], [0.5, 0, 0, 0, 0], [0, 0, 0, 0, -0.2]]),
              acceleration=np.array([[0, 0, 0, 0, 0], [-30.0, 0, 0, 0, 0], [0, 0, 0, 0, 5.0]]),
              jerk=np.array([[0, 0, 0, 900.0, 0], [0, 0, 0, 0, 0], [0, 0, 0, 0, 0]]),
              tip_speed=np.array([10.0, 25.0, 3.0]), feed=np.array([20.0, 0.0, 2.0]))
    vmax = np.array([2.0, 8.0, 1.0, 1.0, 1.0])
    amax = np.array([100.0, 1.0, 1.0, 1.0, 10.0])
    jmax = np.array([1.0, 1.0, 1.0, 1000.0, 1.0])
    assert r.ratio(vmax, amax, jmax) == pytest.approx((1.5, 0.5, 0.5, 0.9))
    empty = Rates(t=np.zeros(0), s=np.zeros(0), sd=np.zeros(0), velocity=np.zeros((0, 5)),
                  acceleration=np.zeros((0, 5)), jerk=np.zeros((0, 5)), tip_speed=np.zeros(0), feed=np.zeros(0))
    assert empty.ratio(vmax, amax, jmax) == (0.0, 0.0, 0.0, 0.0)


def test_interval_constraints_are_the_derivatives_of_the_composed_motion():
    """The NLP's per-interval rows against q(s(t)) composed as polynomials (numpy.polynomial, exact):
    s(t) = s_k + y t + z t^2 / 2 + w t^3 / 6 on [0, h], each axis q(s) a cubic about s_k with
    q' = a1, q'' = a2, q''' = c3 there. Rows: the interval's length and the continuity of s', s''
    (all 0 for a consistent end), then q'' at t = 0, q''' at t = 0 and t = h, q'' and q''' at t = h / 2,
    each times its reciprocal limit, and s'(h / 2) over the speed bound; variables scaled by Y Z W H."""
    from numpy.polynomial import polynomial as P

    from camsmooth.smoothing.jerk import _interval_function

    rng = np.random.default_rng(5)
    y, z, w, h = 1.3, -0.7, 2.1, 0.4
    a1, a2, c3 = rng.normal(size=5), rng.normal(size=5), rng.normal(size=5)
    inv_a, inv_j = rng.uniform(0.5, 2.0, 5), rng.uniform(0.5, 2.0, 5)
    inv_ym, (Y, Z, W, H) = 0.8, (2.0, 0.5, 4.0, 0.1)
    st = np.array([0.0, y, z / 2, w / 6])                        # s(t) - s_k
    ds = P.polyval(h, st)
    yk1, zk1 = P.polyval(h, P.polyder(st)), P.polyval(h, P.polyder(st, 2))
    b1, b2 = a1 + a2 * ds + c3 * ds ** 2 / 2, a2 + c3 * ds
    par = np.r_[ds, a1, a2, b1, b2, c3, inv_a, inv_j, inv_ym, Y, Z, W, H]
    out = np.asarray(_interval_function()(y / Y, z / Z, yk1 / Y, zk1 / Z, w / W, h / H, par)).ravel()
    assert out.shape == (29,)
    np.testing.assert_allclose(out[:3], 0.0, atol=1e-12)
    acc0, jerk0, jerk1, accm, jerkm = (np.empty(5) for _ in range(5))
    for j in range(5):
        qs = np.array([0.0, a1[j], a2[j] / 2, c3[j] / 6])       # q(s) - q(s_k) as a polynomial in s - s_k
        qt = np.zeros(1)
        for k in (1, 2, 3):
            qt = P.polyadd(qt, qs[k] * P.polypow(st, k))
        d2, d3 = P.polyder(qt, 2), P.polyder(qt, 3)
        acc0[j], jerk0[j], jerk1[j] = P.polyval(0.0, d2), P.polyval(0.0, d3), P.polyval(h, d3)
        accm[j], jerkm[j] = P.polyval(h / 2, d2), P.polyval(h / 2, d3)
    np.testing.assert_allclose(out[3:8], acc0 * inv_a, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out[8:13], jerk0 * inv_j, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out[13:18], jerk1 * inv_j, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out[18:23], accm * inv_a, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(out[23:28], jerkm * inv_j, rtol=1e-10, atol=1e-12)
    assert out[28] == pytest.approx(P.polyval(h / 2, P.polyder(st)) * inv_ym, rel=1e-12)
    # an end that does not continue the interval shows in the rows of s' and s''
    off = np.asarray(_interval_function()(y / Y, z / Z, (yk1 + 0.2) / Y, (zk1 - 0.1) / Z, w / W, h / H, par)).ravel()
    assert off[1] == pytest.approx(-0.2 / Y) and off[2] == pytest.approx(0.1 / Z)


def test_the_dense_check_has_nothing_left_to_slow_on_the_reference_helix():
    """IPOPT plans against every limit times (1 - MARGIN) with the nodes' bounds right, so the dense
    check of the plan finds every limit met and leaves the law as solved (slowdown 1): the helix of
    tests/test_jerk.py (benchmarks/bench_jerk.py) at jmax 2000 deg/s^3, 20000 mm/s^3."""
    from tests.test_jerk import solved

    *_, rp, law = solved()
    assert law.converged and law.slowdown == 1.0
    assert max(law_rates(rp, law).ratio(rp.vmax, rp.amax, rp.jmax)) <= 1.0
