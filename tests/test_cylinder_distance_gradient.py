"""The capped-cylinder primitives under the cutter solid (camsmooth.geometry.cutter): the
subgradient of the signed distance against central finite differences and the outward normal
on the surface, the compiled kernels (camsmooth.geometry._kernels, which mutation testing cannot
mutate) against the numpy reference with the same subgradient choices, support-point ties in
closed form, and the argument each bad-input message names."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.geometry import _kernels
from camsmooth.geometry.cutter import ToroidalCutter, _cylinder_sd, support_point

# (height, radius): a cylinder, a segment (capsule core, ball nose) and a disc (short shank)
SHAPES = [(4.0, 1.5), (3.0, 0.0), (0.0, 2.0)]


def _random_frame(rng):
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    return rng.normal(size=3), axis


def _reference(points, base, axis, height, radius):
    """Signed distance from the definition, written independently of the code: in (axial a,
    radial rho) coordinates the solid is the rectangle [0, h] x [0, radius]; outside, the distance
    to its clamped closest point; inside, minus the distance to the nearest of its three sides."""
    p = points - base
    a = p @ axis
    rho = np.linalg.norm(p - a[:, None] * axis, axis=1)
    qa = np.clip(a, 0.0, height)
    qr = np.clip(rho, 0.0, radius)
    outside = np.hypot(a - qa, rho - qr)
    inside = -np.minimum.reduce([a, height - a, radius - rho])
    return np.where((a < 0) | (a > height) | (rho > radius), outside, inside)


@pytest.mark.parametrize("height,radius", SHAPES)
def test_gradient_matches_finite_differences_where_differentiable(height, radius):
    rng = np.random.default_rng(7)
    base, axis = _random_frame(rng)
    pts = base + rng.normal(scale=2.5, size=(400, 3)) + 0.5 * height * axis
    sd, g = _cylinder_sd(base, axis, height, radius, pts, grad=True)
    np.testing.assert_allclose(sd, _reference(pts, base, axis, height, radius), atol=1e-12)
    h = 1e-6
    fd = np.stack([(_cylinder_sd(base, axis, height, radius, pts + h * e)[0]
                    - _cylinder_sd(base, axis, height, radius, pts - h * e)[0]) / (2 * h) for e in np.eye(3)], -1)
    # keep points away from the kinks: the medial surfaces inside, the axis and the cap planes
    p = pts - base
    a = p @ axis
    rho = np.linalg.norm(p - a[:, None] * axis, axis=1)
    dz = np.abs(a - 0.5 * height) - 0.5 * height
    dr = rho - radius
    smooth = (np.abs(dr - dz) > 1e-3) & (rho > 1e-3) & (np.abs(a - 0.5 * height) > 1e-3) \
        & (np.abs(dr) > 1e-3) & (np.abs(dz) > 1e-3)
    assert smooth.sum() > 200
    np.testing.assert_allclose(g[smooth], fd[smooth], atol=1e-6)
    # outside, the gradient is the unit direction away from the closest point
    out = smooth & (sd > 0)
    assert out.sum() > 50
    np.testing.assert_allclose(np.linalg.norm(g[out], axis=1), 1.0, atol=1e-12)


def test_gradient_on_the_surface_and_on_the_axis_is_the_outward_normal():
    base, axis = np.zeros(3), np.array([0.0, 0.0, 1.0])
    # on the side (rho == radius exactly), on the top cap, on the axis above and below the caps
    pts = np.array([[2.0, 0.0, 1.0], [0.0, -2.0, 3.0], [0.5, 0.0, 4.0], [0.0, 0.0, 6.0], [0.0, 0.0, -1.0]])
    sd, g = _cylinder_sd(base, axis, 4.0, 2.0, pts, grad=True)
    np.testing.assert_allclose(sd, [0.0, 0.0, 0.0, 2.0, 1.0], atol=1e-15)
    np.testing.assert_allclose(g, [[1, 0, 0], [0, -1, 0], [0, 0, 1], [0, 0, 1], [0, 0, -1]], atol=1e-15)


def test_compiled_kernels_agree_with_the_numpy_reference():
    rng = np.random.default_rng(11)
    for height, radius in SHAPES:
        base, axis = _random_frame(rng)
        pts = base + rng.normal(scale=2.5, size=(200, 3)) + 0.5 * height * axis
        # plus points on the axis and at mid-height, where the subgradient is a choice
        mid = base + 0.5 * height * axis
        pts = np.vstack([pts, mid, mid + 5.0 * axis, mid - 5.0 * axis])
        sd, g = _cylinder_sd(base, axis, height, radius, pts, grad=True)
        for k, p in enumerate(pts):
            args = (*p, *base, *axis, height, radius)
            s1, *g1 = _kernels._sd_grad(*args)
            assert _kernels._sd(*args) == pytest.approx(sd[k], abs=1e-12)
            assert s1 == pytest.approx(sd[k], abs=1e-12)
            np.testing.assert_allclose(g1, g[k], atol=1e-12)
    # inside, 1 mm from both the side and the bottom cap (an exact tie): both pick the side's normal
    p = np.array([1.0, 0.0, 1.0])
    sd, g = _cylinder_sd(np.zeros(3), np.array([0.0, 0.0, 1.0]), 4.0, 2.0, p, grad=True)
    s1, *g1 = _kernels._sd_grad(*p, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 4.0, 2.0)
    assert sd == s1 == -1.0
    np.testing.assert_array_equal(g, [1.0, 0.0, 0.0])
    np.testing.assert_array_equal(g1, [1.0, 0.0, 0.0])


def test_support_point_ties_in_closed_form():
    tip, T = np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 1.0])
    for cutter in (ToroidalCutter(R=2.0, r=1.0, shank_length=10.0), ToroidalCutter(R=2.0, r=1.5, shank_length=2.0)):
        R, r, L = cutter.R, cutter.r, cutter.shank_length
        # straight down: the flat bottom ties, the tip (axis point) is returned
        np.testing.assert_allclose(support_point(cutter, tip, T, -T), tip, atol=1e-15)
        # straight up: the axis point on top of the body, max(L, 2 r) above the tip
        np.testing.assert_allclose(support_point(cutter, tip, T, T), tip + max(L, 2 * r) * T, atol=1e-15)
        # sideways: the whole shank side ties, the lowest point of the full-radius band is returned
        d = np.array([0.6, 0.8, 0.0])
        np.testing.assert_allclose(support_point(cutter, tip, T, d), tip + r * T + (R + r) * d, atol=1e-15)
    s = support_point(ToroidalCutter(R=1, r=1), [0, 0, 0], [0, 0, 1], [0, 0, 1])
    assert s.dtype == np.float64
