"""Tests of camsmooth.geometry.cutter: CC -> CL against a torus built point by point, signed distance
against dense surface samples and at constructed points, support points, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from camsmooth.errors import InputError
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl, cl_to_cc, signed_distance, support_point

RNG_SEED = 20240611


def _frame(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    e1 = np.cross(T, [1.0, 0.0, 0.0] if abs(T[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(T, e1)


def _torus(cutter: ToroidalCutter, T: np.ndarray, psi: np.ndarray, beta: np.ndarray):
    """Point (relative to the tip) and outward normal of the torus corner: psi around the axis,
    beta from the equator (0) down to the bottom (pi/2)."""
    e1, e2 = _frame(T)
    radial = np.cos(psi)[..., None] * e1 + np.sin(psi)[..., None] * e2
    normal = np.cos(beta)[..., None] * radial - np.sin(beta)[..., None] * T
    point = cutter.R * radial + cutter.r * T + cutter.r * normal
    return point, normal


def _random_unit(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


# ---------------------------------------------------------------------------------------------
# construction and validation

def test_defaults_and_properties():
    c = ToroidalCutter(R=3.0, r=2.0)
    assert c.diameter == pytest.approx(10.0)
    assert c.shank_length == pytest.approx(20.0)
    assert c.holder_radius is None and not c.has_holder
    b = ToroidalCutter(R=0, r=1.5, holder_radius=4, holder_length=10)
    assert b.diameter == pytest.approx(3.0) and b.has_holder


@pytest.mark.parametrize("kwargs, words", [
    (dict(R=float("nan"), r=1.0), "finite"),
    (dict(R=1.0, r=float("inf")), "finite"),
    (dict(R=0.0, r=0.0), "cutter radius R"),
    (dict(R=1.0, r=-1.0), "corner radius"),
    (dict(R=-0.5, r=1.0), "ring radius"),
    (dict(R=1.0, r=2.0, shank_length=1.5), "shank_length"),
    (dict(R=1.0, r=1.0, shank_length=float("nan")), "finite"),
    (dict(R=1.0, r=1.0, holder_radius=2.0, holder_length=5), "holder_radius"),
    (dict(R=1.0, r=1.0, holder_radius=1.5, holder_length=5), "holder_radius"),
    (dict(R=1.0, r=1.0, holder_radius=3.0, holder_length=-1.0), "holder_length"),
    (dict(R="abc", r=1.0), "number"),
])
def test_bad_cutter_raises(kwargs, words):
    with pytest.raises(InputError, match=words):
        ToroidalCutter(**kwargs)


# ---------------------------------------------------------------------------------------------
# CC <-> CL

@pytest.mark.parametrize("R, r", [(3.0, 2.0), (0.0, 1.5), (5.0, 0.5)])
def test_cc_to_cl_matches_sampled_torus(R, r):
    """Independent construction: sample the torus, pick the sample whose outward normal is -n,
    refine (psi, beta) by least squares on the normal, and place the tool so that this torus
    point sits on CC."""
    cutter = ToroidalCutter(R=R, r=r)
    rng = np.random.default_rng(RNG_SEED)
    T = _random_unit(rng, 40)
    n = _random_unit(rng, 40)
    n = np.where((np.sum(n * T, axis=1) < 0.05)[:, None], n + 1.2 * T, n)  # keep n.T > 0
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    cc = rng.uniform(-50, 50, (40, 3))
    cl = cc_to_cl(cutter, cc, n, T)
    psi_g, beta_g = np.meshgrid(np.linspace(-math.pi, math.pi, 361), np.linspace(0, math.pi / 2, 91),
                                indexing="ij")
    for i in range(len(cc)):
        _, nrm = _torus(cutter, T[i], psi_g, beta_g)
        k = np.unravel_index(np.argmin(np.linalg.norm(nrm + n[i], axis=-1)), psi_g.shape)
        x0 = np.array([psi_g[k], beta_g[k]])
        sol = least_squares(lambda x, i=i: _torus(cutter, T[i], x[0], x[1])[1] + n[i], x0,
                            xtol=1e-15, ftol=1e-15, gtol=1e-15)
        point, nrm = _torus(cutter, T[i], sol.x[0], sol.x[1])
        assert np.linalg.norm(nrm + n[i]) < 1e-9
        np.testing.assert_allclose(cl[i], cc[i] - point, atol=1e-6)


def test_cc_to_cl_parallel_and_roundtrip():
    cutter = ToroidalCutter(R=2.0, r=1.0)
    cc = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 0.0]])
    T = np.array([[0.0, 0.0, 1.0], [0.0, 0.6, 0.8]])
    np.testing.assert_allclose(cc_to_cl(cutter, cc, T, T), cc, atol=1e-15)
    rng = np.random.default_rng(1)
    T = _random_unit(rng, 200)
    n = _random_unit(rng, 200)
    n = np.where((np.sum(n * T, axis=1) < 0)[:, None], -n, n)
    cc = rng.uniform(-10, 10, (200, 3))
    cl = cc_to_cl(cutter, cc, n, T)
    np.testing.assert_allclose(cl_to_cc(cutter, cl, n, T), cc, atol=1e-12)
    # one axis broadcast against many points; normals need not be unit
    up = np.array([0.0, 0.0, 1.0])
    n_up = np.where((n[:, 2] < 0)[:, None], -n, n)
    np.testing.assert_allclose(cc_to_cl(cutter, cc, 3.0 * n_up, up),
                               cc_to_cl(cutter, cc, n_up, np.tile(up, (len(cc), 1))), atol=1e-13)


def test_cc_point_has_zero_signed_distance():
    rng = np.random.default_rng(2)
    for cutter in (ToroidalCutter(R=3, r=2), ToroidalCutter(R=0, r=1), ToroidalCutter(R=4, r=0.5)):
        T = _random_unit(rng, 100)
        n = _random_unit(rng, 100)
        n = np.where((np.sum(n * T, axis=1) < 0)[:, None], -n, n)
        cc = rng.uniform(-10, 10, (100, 3))
        cl = cc_to_cl(cutter, cc, n, T)
        np.testing.assert_allclose(signed_distance(cutter, cl, T, cc), 0.0, atol=1e-12)
        # just outside along n (into the air beside the tool) and just inside
        np.testing.assert_allclose(signed_distance(cutter, cl, T, cc - 1e-3 * n), 1e-3, atol=1e-12)
        np.testing.assert_allclose(signed_distance(cutter, cl, T, cc + 1e-3 * n), -1e-3, atol=1e-12)


def test_cc_to_cl_rejects_axis_into_material_and_bad_vectors():
    cutter = ToroidalCutter(R=1, r=1)
    with pytest.raises(InputError, match="into the material"):
        cc_to_cl(cutter, np.zeros((2, 3)), np.array([[0, 0, 1.0], [0, 0, 1.0]]), np.array([0, 0.6, -0.8]))
    with pytest.raises(InputError, match="zero-length"):
        cc_to_cl(cutter, np.zeros(3), np.zeros(3), np.array([0, 0, 1.0]))
    with pytest.raises(InputError, match="finite"):
        cc_to_cl(cutter, np.zeros(3), np.array([0, 0, np.nan]), np.array([0, 0, 1.0]))
    with pytest.raises(InputError, match="shape"):
        cl_to_cc(cutter, np.zeros(3), np.array([0, 1.0]), np.array([0, 0, 1.0]))


# ---------------------------------------------------------------------------------------------
# signed distance

def _surface_cloud(cutter: ToroidalCutter, h: float) -> np.ndarray:
    """Dense points (tool frame: tip at 0, axis +z) on the bottom disc, torus, shank and holder."""
    R, r, L = cutter.R, cutter.r, cutter.shank_length
    pts = []
    nrad = max(int(R / h), 1)
    for rad in np.linspace(0, R, nrad + 1):
        k = max(int(2 * math.pi * rad / h), 1)
        a = np.linspace(0, 2 * math.pi, k, endpoint=False)
        pts.append(np.stack([rad * np.cos(a), rad * np.sin(a), np.zeros(k)], 1))
    for beta in np.linspace(0, math.pi / 2, int(math.pi / 2 * r / h) + 2):
        rad = R + r * math.cos(beta)
        k = int(2 * math.pi * rad / h) + 1
        a = np.linspace(0, 2 * math.pi, k, endpoint=False)
        pts.append(np.stack([rad * np.cos(a), rad * np.sin(a), np.full(k, r - r * math.sin(beta))], 1))
    k = int(2 * math.pi * (R + r) / h) + 1
    a = np.linspace(0, 2 * math.pi, k, endpoint=False)
    for z in np.linspace(r, L, int((L - r) / h) + 2):
        pts.append(np.stack([(R + r) * np.cos(a), (R + r) * np.sin(a), np.full(k, z)], 1))
    if cutter.has_holder:
        Rh, Lh = cutter.holder_radius, cutter.holder_length
        k = int(2 * math.pi * Rh / h) + 1
        a = np.linspace(0, 2 * math.pi, k, endpoint=False)
        for z in np.linspace(L, L + Lh, int(Lh / h) + 2):
            pts.append(np.stack([Rh * np.cos(a), Rh * np.sin(a), np.full(k, z)], 1))
        for rad in np.linspace(R + r, Rh, int((Rh - R - r) / h) + 2):
            kk = int(2 * math.pi * rad / h) + 1
            aa = np.linspace(0, 2 * math.pi, kk, endpoint=False)
            pts.append(np.stack([rad * np.cos(aa), rad * np.sin(aa), np.full(kk, L)], 1))
        for rad in np.linspace(0, Rh, int(Rh / h) + 2):
            kk = max(int(2 * math.pi * rad / h), 1)
            aa = np.linspace(0, 2 * math.pi, kk, endpoint=False)
            pts.append(np.stack([rad * np.cos(aa), rad * np.sin(aa), np.full(kk, L + Lh)], 1))
    return np.concatenate(pts)


def _inside(cutter: ToroidalCutter, q: np.ndarray) -> np.ndarray:
    """Independent inside test in the tool frame from the lower envelope of the cutter."""
    rho = np.hypot(q[:, 0], q[:, 1])
    z = q[:, 2]
    x = np.clip(rho - cutter.R, 0, cutter.r)
    zlow = np.where(rho <= cutter.R, 0.0, cutter.r - np.sqrt(np.maximum(cutter.r ** 2 - x * x, 0)))
    inside = (rho <= cutter.R + cutter.r) & (z >= zlow) & (z <= cutter.shank_length)
    if cutter.has_holder:
        inside |= (rho <= cutter.holder_radius) & (z >= cutter.shank_length) & (
            z <= cutter.shank_length + cutter.holder_length)
    return inside


@pytest.mark.parametrize("cutter", [ToroidalCutter(R=3.0, r=2.0, shank_length=12.0),
                                    ToroidalCutter(R=0.0, r=2.0, shank_length=10.0),
                                    ToroidalCutter(R=2.0, r=1.0, shank_length=6.0, holder_radius=5.0,
                                                   holder_length=4.0)])
def test_signed_distance_against_dense_surface_samples(cutter):
    h = 0.05
    cloud = _surface_cloud(cutter, h)
    tree = cKDTree(cloud)
    rng = np.random.default_rng(3)
    top = cutter.shank_length + cutter.holder_length
    q = np.column_stack([rng.uniform(-8, 8, 4000), rng.uniform(-8, 8, 4000), rng.uniform(-3, top + 2, 4000)])
    # The solid's rounded top (between shank_length - r and shank_length) differs from the real
    # flat-topped shank on purpose: compare only where the nearest surface is elsewhere.
    d_cloud, _ = tree.query(q)
    near_top = np.abs(q[:, 2] - cutter.shank_length) < cutter.r + d_cloud + 2 * h
    q, d_cloud = q[~near_top], d_cloud[~near_top]
    sign = np.where(_inside(cutter, q), -1.0, 1.0)
    # The solid is given at a random pose: transform the query points with it.
    T = np.array([0.3, -0.5, 0.8])
    T /= np.linalg.norm(T)
    e1, e2 = _frame(T)
    tip = np.array([5.0, -2.0, 7.0])
    world = tip + q[:, :1] * e1 + q[:, 1:2] * e2 + q[:, 2:] * T
    sd = signed_distance(cutter, tip, T, world)
    # Cloud points lie on the surface, so the cloud distance is never below the true one, and
    # exceeds it by at most the cloud's gap (< 0.75 h here).
    assert len(q) > 1000
    assert np.all(np.abs(sd) <= d_cloud + 1e-9)
    assert np.all(np.abs(sd - sign * d_cloud) < 0.75 * h), np.abs(sd - sign * d_cloud).max()
    clear = np.abs(sd) > 1e-9
    assert np.all(np.sign(sd[clear]) == sign[clear])


@pytest.mark.parametrize("R, r", [(3.0, 2.0), (0.0, 1.0), (1.5, 0.25)])
def test_signed_distance_exact_at_constructed_points(R, r):
    L = 10.0 * (R + r) + 5.0
    cutter = ToroidalCutter(R=R, r=r, shank_length=L)
    rng = np.random.default_rng(4)
    T = np.array([-0.2, 0.1, 1.0])
    T /= np.linalg.norm(T)
    e1, e2 = _frame(T)
    tip = np.array([1.0, 2.0, -3.0])
    m = 300
    # torus: along the outward normal, outside any distance, inside less than r
    psi = rng.uniform(-math.pi, math.pi, m)
    beta = rng.uniform(0.0, math.pi / 2, m)
    point, normal = _torus(cutter, T, psi, beta)
    for t in (rng.uniform(0.0, 5.0, m), -rng.uniform(0.0, 0.99 * r, m)):
        np.testing.assert_allclose(signed_distance(cutter, tip, T, tip + point + t[:, None] * normal), t,
                                   atol=1e-9)
    # flat bottom: below at any distance, above by less than r
    rad = R * np.sqrt(rng.uniform(0, 1, m))
    ang = rng.uniform(-math.pi, math.pi, m)
    base = tip + rad[:, None] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
    for t in (rng.uniform(0, 5, m), -rng.uniform(0, 0.99 * r, m)):
        np.testing.assert_allclose(signed_distance(cutter, tip, T, base - t[:, None] * T), t, atol=1e-9)
    # shank wall between r and L - r: outside any distance, inside less than r
    z = rng.uniform(r, L - 2 * r, m)
    radial = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
    for t in (rng.uniform(0, 5, m), -rng.uniform(0, 0.99 * r, m)):
        pts = tip + z[:, None] * T + (R + r + t)[:, None] * radial
        np.testing.assert_allclose(signed_distance(cutter, tip, T, pts), t, atol=1e-9)


def test_signed_distance_holder_and_broadcasting():
    cutter = ToroidalCutter(R=2.0, r=1.0, shank_length=10.0, holder_radius=6.0, holder_length=8.0)
    tip = np.zeros(3)
    T = np.array([0.0, 0.0, 1.0])
    # beside the holder (radial 7 at height 14): 1 mm outside; inside it 1 mm from its wall
    pts = np.array([[7.0, 0, 14.0], [5.0, 0, 14.0], [0.0, 0.0, 19.0], [4.0, 0.0, 9.0]])
    np.testing.assert_allclose(signed_distance(cutter, tip, T, pts), [1.0, -1.0, 1.0, 1.0], atol=1e-12)
    # (N,3) tips/axes against (N,3) points and (3,) against (N,3)
    tips = np.zeros((4, 3))
    axes = np.tile(T, (4, 1))
    np.testing.assert_allclose(signed_distance(cutter, tips, axes, pts),
                               signed_distance(cutter, tip, T, pts))
    grid = signed_distance(cutter, tips[:, None, :], axes[:, None, :], pts[None, :, :])
    assert grid.shape == (4, 4)


def test_support_point_is_extreme():
    rng = np.random.default_rng(5)
    for cutter in (ToroidalCutter(R=3.0, r=2.0), ToroidalCutter(R=0.0, r=1.0, shank_length=3.0),
                   ToroidalCutter(R=2.0, r=1.0, shank_length=1.5)):
        cloud = _surface_cloud(cutter, 0.1)
        T = np.array([0.0, 0.0, 1.0])
        d = _random_unit(rng, 200)
        s = support_point(cutter, np.zeros(3), T, d)
        np.testing.assert_allclose(signed_distance(cutter, np.zeros(3), T, s), 0.0, atol=1e-12)
        # no surface sample goes further in the direction than the support point (the rounded
        # top of the solid lies inside the flat-topped cloud, so only check directions pointing
        # down or sideways)
        low = d[:, 2] <= 0.0
        best = (cloud @ d[low].T).max(axis=0)
        assert np.all(np.sum(s[low] * d[low], axis=1) >= best - 1e-9)
        assert np.all(np.sum(s[low] * d[low], axis=1) <= best + 0.01)
