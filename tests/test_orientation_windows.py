"""Local-gouge windows (camsmooth.smoothing.orientation) at their edges: the cutter's curvature
tensor in closed form (ball nose, small ring radius, zero lead), the smallest gouge-free lead in
exactly solvable cases (a flat part, a corner that cannot fit, a 90 deg lead limit) without
floating-point warnings, and the lead/tilt windows: which bounds are accepted, the message for
each refusal, the default preferred orientation and the lead required over the tilt window."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from camsmooth.errors import InfeasibleError, InputError
from camsmooth.smoothing.orientation import cutter_curvature_tensors, initial_orientation, min_gouge_free_lead


def _torus_tensor(R, r, lead, tilt):
    """k_m m m^T + k p p^T with k_m = 1/r along the meridian m = (cos tilt, sin tilt) and
    k = sin(lead) / (R + r sin(lead)) across it (1/r for a ball nose), written out."""
    km = 1.0 / r
    k = 1.0 / r if R == 0 else math.sin(lead) / (R + r * math.sin(lead))
    m = np.array([math.cos(tilt), math.sin(tilt)])
    p = np.array([-math.sin(tilt), math.cos(tilt)])
    return km * np.outer(m, m) + k * np.outer(p, p)


@pytest.mark.parametrize("R,r", [(0.0, 2.0), (0.5, 1.5), (3.0, 1.0)])
def test_cutter_curvature_tensor_closed_form(R, r):
    lead = np.array([0.0, 0.3, 1.2])
    tilt = np.array([0.0, -0.7, 0.4])
    K = cutter_curvature_tensors(R, r, lead, tilt)
    for i in range(3):
        np.testing.assert_allclose(K[i], _torus_tensor(R, r, lead[i], tilt[i]), atol=1e-15)
    assert cutter_curvature_tensors(R, r, 0.3, [0.0, 1.0]).shape == (2, 2, 2)   # broadcast


def _no_warnings(fn, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return fn(*args, **kw)


def test_smallest_gouge_free_lead_in_solvable_cases():
    r, R = 0.5, 2.0
    flat = np.zeros((2, 2))
    # a flat part needs no lead, even when the lead limit is 0
    assert _no_warnings(min_gouge_free_lead, R, r, flat, 0.0, 0.0, margin=0.0) == 0.0
    # concave across the feed with curvature k: sin(lead) = k R / (1 - k r) (METHODS section 1)
    k = 0.3
    K = np.array([[0.0, 0.0], [0.0, k]])
    expect = math.asin(k * R / (1 - k * r))
    assert _no_warnings(min_gouge_free_lead, R, r, K, 0.0, 1.4, margin=0.0) == pytest.approx(expect, rel=1e-12)
    assert math.isnan(_no_warnings(min_gouge_free_lead, R, r, K, 0.0, expect - 1e-6, margin=0.0))
    # the same with a ring radius below 1 mm and with a ball nose (its cross curvature never changes)
    k2 = 0.2
    K2 = np.array([[0.0, 0.0], [0.0, k2]])
    assert _no_warnings(min_gouge_free_lead, 0.5, 1.0, K2, 0.0, 1.4, margin=0.0) == \
        pytest.approx(math.asin(k2 * 0.5 / (1 - k2 * 1.0)), rel=1e-12)
    assert _no_warnings(min_gouge_free_lead, 0.0, 1.0, K2, 0.0, 1.4, margin=0.0) == 0.0
    # a concave curvature the ball cannot follow: 2 > 1/r
    assert math.isnan(_no_warnings(min_gouge_free_lead, 0.0, 0.4, np.diag([0.0, 2.6]), 0.0, 1.4, margin=0.0))
    # across-feed curvature 1/r or more: no lead fits the corner, even with a 90 deg lead limit
    # (k r = 1 exactly: the formula's denominator is zero)
    for kk in (2.0, 3.0):
        got = _no_warnings(min_gouge_free_lead, R, r, np.diag([0.0, kk]), 0.0, math.pi / 2, margin=0.0)
        assert math.isnan(got), kk
    # k R / (1 - k r) > 1: sin(lead) would exceed 1
    got = _no_warnings(min_gouge_free_lead, R, r, np.diag([0.0, 0.8]), 0.0, math.pi / 2, margin=0.0)
    assert math.isnan(got)
    # along the feed the meridian curvature 1/r is the limit whatever the lead (m^T C m = 0 exactly)
    got = _no_warnings(min_gouge_free_lead, R, r, np.diag([2.0, 0.0]), 0.0, 1.4, margin=0.0)
    assert math.isnan(got)


def _flat_frames(n):
    return np.tile(np.eye(3), (n, 1, 1))


def test_windows_bounds_messages_and_defaults():
    frames, K = _flat_frames(2), np.zeros((2, 2, 2))
    d = math.radians

    def run(lead, tilt, **kw):
        return initial_orientation(frames, K, 2.0, 0.5, lead, tilt, **kw)

    o = run((0.0, d(40)), (d(-80), d(80)))   # lead may start at 0; tilt up to +-80 deg
    np.testing.assert_allclose(o.lead, d(20))
    np.testing.assert_allclose(o.tilt, 0.0, atol=1e-15)
    o = run((d(10), d(70)), (d(-70), d(30)))   # defaults: the midpoints of the windows
    np.testing.assert_allclose(o.lead, d(40), rtol=1e-15)
    np.testing.assert_allclose(o.tilt, d(-20), rtol=1e-15)
    np.testing.assert_allclose(o.lead_window, [[d(10), d(70)]] * 2, rtol=1e-15)
    np.testing.assert_allclose(o.tilt_window, [[d(-70), d(30)]] * 2, rtol=1e-15)
    o = run((d(10), d(30)), (d(5), d(5)), prefer_lead=d(10))   # a single tilt; preferred lead on the edge
    np.testing.assert_allclose([o.lead[0], o.tilt[0]], [d(10), d(5)], rtol=1e-15)
    o = run((d(10), d(30)), (d(-5), d(5)), prefer_lead=d(30), prefer_tilt=d(5))
    np.testing.assert_allclose([o.lead[0], o.tilt[0]], [d(30), d(5)], rtol=1e-15)
    bad = [
        ((d(10), d(10)), (0, 0), "lead window [10, 10] deg must satisfy 0 <= min < max < 90"),
        ((d(-1), d(10)), (0, 0), "lead window [-1, 10] deg must satisfy 0 <= min < max < 90"),
        ((0.0, math.pi / 2), (0, 0), "lead window [0, 90] deg must satisfy 0 <= min < max < 90"),
        ((0.0, 1.6), (0, 0), "lead window [0, 91.6732] deg must satisfy 0 <= min < max < 90"),
        ((0.0, 0.5), (-math.pi / 2, 0), "tilt window [-90, 0] deg must satisfy -90 < min <= max < 90"),
        ((0.0, 0.5), (0, math.pi / 2), "tilt window [0, 90] deg must satisfy -90 < min <= max < 90"),
        ((0.0, 0.5), (d(10), d(-10)), "tilt window [10, -10] deg must satisfy -90 < min <= max < 90"),
        ((0.0, 0.5), (-1.6, 0), "tilt window [-91.6732, 0] deg must satisfy -90 < min <= max < 90"),
        ((0.0, 0.5), (0, 1.6), "tilt window [0, 91.6732] deg must satisfy -90 < min <= max < 90"),
    ]
    for lead, tilt, message in bad:
        with pytest.raises(InputError) as exc:
            run(lead, tilt)
        assert str(exc.value) == message
    for kw in (dict(prefer_lead=0.6), dict(prefer_tilt=0.2), dict(prefer_lead=0.2, prefer_tilt=-0.2)):
        with pytest.raises(InputError) as exc:
            run((0.1, 0.5), (-0.1, 0.1), **kw)
        assert str(exc.value) == "the preferred lead/tilt must lie inside the lead/tilt windows"
    o = run((0.1, 0.5), (-1.2, 1.2))   # wide windows are accepted
    assert o.lead_window.shape == (2, 2)


def test_lead_required_is_the_largest_over_the_tilt_window():
    # a part concave along x only: the need for lead depends on the tilt (the meridian turns)
    R, r, n = 2.0, 0.5, 3
    K = np.tile(np.diag([0.35, 0.0]), (n, 1, 1))
    lead_max = math.radians(80)
    tmin, tmax = math.radians(-40), math.radians(50)
    o = initial_orientation(_flat_frames(n), K, R, r, (0.0, lead_max), (tmin, tmax))
    tilts = np.linspace(tmin, tmax, 9)   # n_tilt = 9 tilts spanning the window
    expect = max(min_gouge_free_lead(R, r, K[0], t, lead_max) for t in tilts)
    assert expect > 0.05
    np.testing.assert_allclose(o.lead_required, expect, rtol=1e-12)
    np.testing.assert_allclose(o.lead_window[:, 0], expect, rtol=1e-12)
    assert np.all(o.lead >= o.lead_window[:, 0]) and np.all(o.lead <= lead_max)


def _feasible_brute(R, r, K, tilt, lead_max, margin=1e-4, n=4001):
    """Some lead on a fine grid of [0, lead_max] leaves K_cutter - K - margin I positive semidefinite."""
    for lead in np.linspace(0.0, lead_max, n):
        if np.linalg.eigvalsh(_torus_tensor(R, r, lead, tilt) - K)[0] >= margin:
            return True
    return False


def test_tilt_window_shrinks_to_the_feasible_span_around_the_preferred_tilt():
    # concave 1 / mm along x, 0.2 / mm along y: tilting the meridian away from x needs more lead
    # than the corner can give (at most sin 80 / (R + r sin 80) = 0.395 / mm), so only tilts near 0 fit
    R, r, lead_max = 2.0, 0.5, math.radians(80)
    K = np.diag([1.0, 0.2])
    tmin, tmax = math.radians(-60), math.radians(60)
    tilts = np.linspace(tmin, tmax, 9)
    feas = np.array([_feasible_brute(R, r, K, t, lead_max) for t in tilts])
    assert feas.any() and not feas.all()
    ok = np.flatnonzero(feas)
    assert np.all(np.diff(ok) == 1)   # one contiguous span
    frames = _flat_frames(1)
    o = initial_orientation(frames, K[None], R, r, (0.0, lead_max), (tmin, tmax))
    np.testing.assert_allclose(o.tilt_window[0], [tilts[ok[0]], tilts[ok[-1]]], rtol=1e-15)
    assert tilts[ok[0]] <= o.tilt[0] <= tilts[ok[-1]]
    expect = max(min_gouge_free_lead(R, r, K, t, lead_max) for t in tilts[ok])
    np.testing.assert_allclose(o.lead_required, expect, rtol=1e-12)
    # a preferred tilt outside the span: the span is still the feasible one, the tilt is clipped into it
    o = initial_orientation(frames, K[None], R, r, (0.0, lead_max), (tmin, tmax), prefer_tilt=tmax)
    np.testing.assert_allclose(o.tilt_window[0], [tilts[ok[0]], tilts[ok[-1]]], rtol=1e-15)
    np.testing.assert_allclose(o.tilt, tilts[ok[-1]], rtol=1e-15)
    # a part concave along (1, 1) only (eigenvalues 0.85 and -0.25): only positive tilts fit; from an
    # infeasible preferred tilt the span starts at the first feasible tilt, and the tilt is clipped into it
    Ks = np.array([[0.3, 0.55], [0.55, 0.3]])
    feas = np.array([_feasible_brute(R, r, Ks, t, lead_max) for t in tilts])
    ok = np.flatnonzero(feas)
    assert ok.tolist() == list(range(ok[0], 9)) and ok[0] > 2
    o = initial_orientation(frames, Ks[None], R, r, (0.0, lead_max), (tmin, tmax), prefer_tilt=tilts[2])
    np.testing.assert_allclose(o.tilt_window[0], [tilts[ok[0]], tmax], rtol=1e-15)
    np.testing.assert_allclose(o.tilt, tilts[ok[0]], rtol=1e-15)


def test_no_feasible_tilt_names_the_point_the_curvature_and_the_cutter():
    R, r, lead_max = 2.0, 0.5, math.radians(80)
    K = np.array([np.diag([0.0, 0.1]), np.diag([1.25, 1.0])])   # point 1: concave 1.25 / mm both ways
    frames = _flat_frames(2)
    message = ("no lead in [0, 80] deg avoids local gouging (surface curvature 1.25 1/mm, concave radius 0.8 mm; "
               "cutter corner radius r = 0.5 mm, ring radius R = 2 mm): widen the lead window or use a smaller "
               "corner radius")
    with pytest.raises(InfeasibleError) as exc:
        initial_orientation(frames, K, R, r, (0.0, lead_max), (-0.3, 0.3))
    assert str(exc.value) == "point 1: " + message
    with pytest.raises(InfeasibleError) as exc:
        initial_orientation(frames, K, R, r, (0.0, lead_max), (-0.3, 0.3), point_name=lambda i: f"row 7, point {i}")
    assert str(exc.value) == "row 7, point 1: " + message
    K[1] = np.diag([1.0, 1.0])   # concave radius exactly 1 mm
    with pytest.raises(InfeasibleError, match=r"surface curvature 1 1/mm, concave radius 1 mm;"):
        initial_orientation(frames, K, R, r, (0.0, lead_max), (-0.3, 0.3))
