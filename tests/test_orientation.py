"""Orientation: frames, lead/tilt round trips, curvature from meshes against closed forms, the
gouge criterion against an independent cutter-vs-surface height comparison."""

import numpy as np
import pytest
import trimesh

from camsmooth.errors import InfeasibleError, InputError
from camsmooth.smoothing.orientation import (
    axis_from_lead_tilt,
    cutter_curvature_tensors,
    initial_orientation,
    lead_tilt_from_axis,
    local_frames,
    min_gouge_free_lead,
    surface_curvature_tensors,
)


def _grid_mesh(fz, half=10.0, n=161):
    x, y = np.meshgrid(np.linspace(-half, half, n), np.linspace(-half, half, n), indexing="ij")
    v = np.column_stack([x.ravel(), y.ravel(), fz(x.ravel(), y.ravel())])
    return v


def test_lead_tilt_round_trip_and_closed_form():
    rng = np.random.default_rng(0)
    n = rng.normal(size=(100, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    f = rng.normal(size=(100, 3))
    fr = local_frames(n, f)
    np.testing.assert_allclose(np.einsum("nji,njk->nik", fr, fr), np.tile(np.eye(3), (100, 1, 1)), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(fr), 1.0, atol=1e-12)
    lead, tilt = rng.uniform(0.01, 1.2, 100), rng.uniform(-1.2, 1.2, 100)
    T = axis_from_lead_tilt(lead, tilt, fr)
    # METHODS section 1: T_L = (sin th cos ph, sin th sin ph, cos th)
    tl = np.einsum("nji,nj->ni", fr, T)
    np.testing.assert_allclose(tl, np.stack([np.sin(lead) * np.cos(tilt), np.sin(lead) * np.sin(tilt),
                                             np.cos(lead)], -1), atol=1e-14)
    l2, t2 = lead_tilt_from_axis(T, fr)
    np.testing.assert_allclose(l2, lead, atol=1e-12)
    np.testing.assert_allclose(t2, tilt, atol=1e-12)


@pytest.mark.parametrize("kind", ["sphere_concave", "sphere_convex", "cylinder", "saddle"])
def test_surface_curvature_from_mesh_against_closed_form(kind):
    Rs = 30.0
    if kind == "sphere_concave":  # bowl: bends toward +z normal => +1/R
        fz, K_true = (lambda x, y: Rs - np.sqrt(Rs**2 - x**2 - y**2)), np.diag([1 / Rs, 1 / Rs])
    elif kind == "sphere_convex":
        fz, K_true = (lambda x, y: np.sqrt(Rs**2 - x**2 - y**2) - Rs), np.diag([-1 / Rs, -1 / Rs])
    elif kind == "cylinder":  # convex along y only
        fz, K_true = (lambda x, y: np.sqrt(Rs**2 - y**2) - Rs), np.diag([0.0, -1 / Rs])
    else:  # z = (x^2 - y^2) / (2 Rs): second fundamental form at the origin diag(1/Rs, -1/Rs)
        fz, K_true = (lambda x, y: (x**2 - y**2) / (2 * Rs)), np.diag([1 / Rs, -1 / Rs])
    v = _grid_mesh(fz)
    p = np.array([[0.0, 0.0, fz(np.array(0.0), np.array(0.0))]])
    fr = local_frames(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    K = surface_curvature_tensors(v, p, fr)[0]
    np.testing.assert_allclose(K, K_true, atol=2e-4)


def test_curvature_on_anisotropic_boundary_mesh_is_sane():
    # spacing 0.05 mm along x, 1.5 mm along y; point on the y boundary: nearest neighbours are
    # collinear, the fit must grow its neighbourhood instead of blowing up
    x, y = np.meshgrid(np.arange(-10, 10.001, 0.05), np.arange(-15, 0.001, 1.5), indexing="ij")
    z = (x**2 + y**2) / 80.0
    v = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    p = np.array([[0.0, 0.0, 0.0]])
    fr = local_frames(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))
    K = surface_curvature_tensors(v, p, fr)[0]
    np.testing.assert_allclose(K, np.diag([1 / 40, 1 / 40]), atol=1e-6)


def test_cutter_curvature_closed_form():
    R, r = 4.0, 1.0
    K = cutter_curvature_tensors(R, r, np.radians(10.0), 0.0)
    np.testing.assert_allclose(K, np.diag([1 / r, 1 / (R / np.sin(np.radians(10.0)) + r)]), atol=1e-14)
    K = cutter_curvature_tensors(R, r, np.radians(10.0), np.pi / 2)  # meridian along Y_L
    np.testing.assert_allclose(K, np.diag([1 / (R / np.sin(np.radians(10.0)) + r), 1 / r]), atol=1e-14)


def test_min_gouge_free_lead_against_height_comparison():
    # concave across the feed, radius Rc: tilt 0 needs R/sin(lead) + r <= Rc
    R, r, Rc = 4.0, 1.0, 20.0
    K = np.diag([0.0, 1 / Rc])[None]
    lead = min_gouge_free_lead(R, r, K, np.zeros(1), np.radians(60), margin=0.0)[0]
    np.testing.assert_allclose(np.sin(lead), R / (Rc - r), rtol=1e-8)
    # independent check: the cutter's effective cross-feed profile vs the surface, heights
    for th, expect_gouge in ((lead * 0.9, True), (lead * 1.1, False)):
        rho = R / np.sin(th) + r
        yy = np.linspace(-0.5, 0.5, 101)
        cutter = rho - np.sqrt(rho**2 - yy**2)
        surf = Rc - np.sqrt(Rc**2 - yy**2)
        assert np.any(cutter < surf - 1e-12) == expect_gouge


def test_initial_orientation_raises_lead_where_concave_and_names_infeasible_points():
    n = np.tile([0.0, 0.0, 1.0], (3, 1))
    fr = local_frames(n, np.tile([1.0, 0.0, 0.0], (3, 1)))
    K = np.stack([np.zeros((2, 2)), np.diag([0.0, 1 / 15.0]), np.zeros((2, 2))])
    o = initial_orientation(fr, K, 4.0, 1.0, (np.radians(2), np.radians(40)), (0.0, 0.0),
                            prefer_lead=np.radians(5), prefer_tilt=0.0)
    assert o.lead[0] == pytest.approx(np.radians(5))
    assert o.lead[1] >= np.arcsin(4.0 / 14.0) - 1e-6
    assert o.lead_window[1, 0] > o.lead_window[0, 0]
    K_bad = np.stack([np.zeros((2, 2)), np.diag([1 / 0.8, 0.0]), np.zeros((2, 2))])  # tighter than r along feed
    with pytest.raises(InfeasibleError, match="point 1.*corner radius"):
        initial_orientation(fr, K_bad, 4.0, 1.0, (np.radians(2), np.radians(40)), (0.0, 0.0))
    with pytest.raises(InputError, match="lead window"):
        initial_orientation(fr, K, 4.0, 1.0, (np.radians(20), np.radians(10)), (0.0, 0.0))


def test_mesh_quadric_agrees_with_trimesh_sphere():
    # an independent mesh generator: trimesh's icosphere, concave side seen from inside
    m = trimesh.creation.icosphere(subdivisions=6, radius=25.0)
    v = np.asarray(m.vertices)
    p = np.array([[0.0, 0.0, -25.0]])
    fr = local_frames(np.array([[0.0, 0.0, 1.0]]), np.array([[1.0, 0.0, 0.0]]))  # inside: normal up
    K = surface_curvature_tensors(v, p, fr, k=64)[0]
    np.testing.assert_allclose(np.linalg.eigvalsh(K), [1 / 25.0, 1 / 25.0], rtol=0.05)


def test_min_gouge_free_lead_closed_form_against_bisection():
    """The closed form against a bisection on the Loewner condition itself (the smallest
    eigenvalue of K_cutter - K_surface), on random symmetric surface tensors and tilts."""
    from camsmooth.smoothing.orientation import cutter_curvature_tensors

    def min_eig(K):
        a, b, c = K[..., 0, 0], K[..., 0, 1], K[..., 1, 1]
        return 0.5 * (a + c) - np.sqrt(0.25 * (a - c) ** 2 + b ** 2)

    rng = np.random.default_rng(0)
    A = rng.normal(size=(4000, 2, 2)) * 0.1
    K = 0.5 * (A + A.transpose(0, 2, 1))
    tilt = rng.uniform(-1, 1, 4000)
    lead_max, margin = np.radians(60), 1e-4
    for R, r in ((4.0, 1.0), (0.0, 2.0), (3.0, 0.5)):
        def ok(lead, R=R, r=r):
            return min_eig(cutter_curvature_tensors(R, r, lead, tilt) - K) >= margin

        lo, hi = np.zeros(len(K)), np.full(len(K), lead_max)
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            good = ok(mid)
            lo, hi = np.where(good, lo, mid), np.where(good, mid, hi)
        ref = np.where(ok(np.full(len(K), lead_max)), np.where(ok(np.zeros(len(K))), 0.0, hi), np.nan)
        got = min_gouge_free_lead(R, r, K, tilt, lead_max, margin=margin)
        assert np.array_equal(np.isnan(got), np.isnan(ref))
        np.testing.assert_allclose(got[~np.isnan(ref)], ref[~np.isnan(ref)], atol=1e-12)
        assert np.isnan(ref).any() or R == 0.0  # some points gouge at every lead: the NaN path is exercised
