"""Tests of camsmooth.geometry.clearance: clearance against brute force and closed forms (touching,
penetration, shank and holder gouges, caps, subdivision, chunking) and the axial drop against
closed forms on a plane, a sphere and a cylinder, a dense-sampling bound and the clearance."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from scipy.optimize import minimize

from camsmooth.errors import InputError
from camsmooth.geometry.clearance import MeshIndex, axial_drop, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl, cl_to_cc, signed_distance


def _grid_mesh(n: int, size: float, height=None) -> trimesh.Trimesh:
    """Square grid sheet centred on the origin; ``height(x, y)`` (default 0) gives z."""
    xs = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    Z = np.zeros_like(X) if height is None else height(X, Y)
    V = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    F = np.concatenate([np.stack([a, a + n, a + n + 1], 1), np.stack([a, a + n + 1, a + 1], 1)])
    return trimesh.Trimesh(V, F, process=False)


def _lead_tilt_axis(lead: float, tilt: float, f=(1.0, 0.0, 0.0), n=(0.0, 0.0, 1.0)) -> np.ndarray:
    f, n = np.asarray(f, float), np.asarray(n, float)
    y = np.cross(n, f)
    return (math.sin(lead) * math.cos(tilt) * f + math.sin(lead) * math.sin(tilt) * y
            + math.cos(lead) * n)


def _on_mesh(points: np.ndarray, mesh: trimesh.Trimesh) -> np.ndarray:
    """Distance from points to the mesh triangles (independent: trimesh's closest point)."""
    _, dist, _ = trimesh.proximity.closest_point(mesh, points)
    return dist


# ---------------------------------------------------------------------------------------------
# brute force: minimum of the tool's signed distance over each triangle

def _proj_simplex(u, v):
    u, v = np.maximum(u, 0.0), np.maximum(v, 0.0)
    s = u + v
    big = s > 1.0
    return np.where(big, u / np.where(big, s, 1.0), u), np.where(big, v / np.where(big, s, 1.0), v)


def _tri_min_sampled(f, a, b, c, n=40, levels=34, m=8):
    """Dense barycentric grid, then a pattern search shrinking by 2 per level."""
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    k = i + j <= n
    u, v = i[k] / n, j[k] / n
    vals = f(a + u[:, None] * (b - a) + v[:, None] * (c - a))
    q = int(np.argmin(vals))
    bu, bv, best = u[q], v[q], vals[q]
    w = 1.0 / n
    g = np.linspace(-1.0, 1.0, 2 * m + 1)
    for _ in range(levels):
        U, W = np.meshgrid(bu + w * g, bv + w * g, indexing="ij")
        U, W = _proj_simplex(U.ravel(), W.ravel())
        vals = f(a + U[:, None] * (b - a) + W[:, None] * (c - a))
        q = int(np.argmin(vals))
        if vals[q] <= best:
            bu, bv, best = U[q], W[q], vals[q]
        w /= 2.0
    # the pattern search can stall on long thin triangles: finish with SLSQP from its best point
    res = minimize(lambda x: float(f(a + x[0] * (b - a) + x[1] * (c - a))), [bu, bv], method="SLSQP",
                   bounds=[(0, 1), (0, 1)], constraints=[dict(type="ineq", fun=lambda x: 1 - x[0] - x[1])],
                   options=dict(ftol=1e-15, maxiter=500))
    if res.success and min(res.x) >= -1e-12 and res.x.sum() <= 1 + 1e-12:
        best = min(best, float(res.fun))
    return best


def _tri_min_inside(base, axis, h, R, a, b, c):
    """min over the triangle of max(rho - R, -z, z - h) (the solid cylinder's signed distance
    where negative) by SLSQP on the epigraph; +inf if no start converges."""
    def x_of(x):
        return a + x[0] * (b - a) + x[1] * (c - a)

    def cons(x):
        p = x_of(x) - base
        z = p @ axis
        w = p - z * axis
        t = x[2]
        return np.array([(t + R) ** 2 - w @ w, t + R, t + z, t - z + h, x[0], x[1], 1 - x[0] - x[1]])

    best = np.inf
    for x0 in [(1 / 3, 1 / 3), (0.8, 0.1), (0.1, 0.8), (0.1, 0.1), (0.45, 0.45), (0.5, 0.0), (0.0, 0.5)]:
        p = x_of(x0) - base
        z = p @ axis
        t0 = max(np.linalg.norm(p - z * axis) - R, -z, z - h) + 1.0
        res = minimize(lambda x: x[2], [x0[0], x0[1], t0], constraints=[dict(type="ineq", fun=cons)],
                       method="SLSQP", options=dict(ftol=1e-14, maxiter=500))
        if res.success and np.all(cons(res.x) > -1e-10):
            best = min(best, res.x[2])
    return best


def _brute_clearance(cutter, tip, axis, V, F):
    def f(P):
        return signed_distance(cutter, tip, axis, P)

    best = min(_tri_min_sampled(f, *V[t]) for t in F)
    bodies = [(tip + cutter.r * axis, cutter.core_height, cutter.R, cutter.r)]
    if cutter.has_holder:
        bodies.append((tip + cutter.shank_length * axis, cutter.holder_length, cutter.holder_radius, 0.0))
    for base, h, R, off in bodies:
        for t in F:
            d = _tri_min_inside(base, axis, h, R, *V[t])
            if d <= 0.0:
                best = min(best, d - off)
    return best


def _numeric_normal(cutter, tip, axis, x, h=1e-6):
    """Minus the central-difference gradient of the (numpy) signed distance at x."""
    e = np.eye(3) * h
    g = np.array([signed_distance(cutter, tip, axis, x + e[k]) - signed_distance(cutter, tip, axis, x - e[k])
                  for k in range(3)]) / (2 * h)
    return -g


def test_clearance_matches_brute_force_on_random_meshes():
    rng = np.random.default_rng(7)
    kinds = set()
    for trial in range(24):
        R = (0.0, 2.0, 3.0)[trial % 3]
        holder = trial % 2 == 0
        cutter = ToroidalCutter(R=R, r=1.0, shank_length=6.0, holder_radius=5.0 if holder else None,
                                holder_length=4.0 if holder else 0.0)
        V = rng.uniform(-5, 5, (10, 3))
        V[:, 2] = rng.uniform(-2, 10, 10)
        F = rng.integers(0, 10, (6, 3))
        F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 0] != F[:, 2])]
        mesh = trimesh.Trimesh(V, F, process=False)
        axis = rng.normal(size=3)
        axis[2] = abs(axis[2]) + 0.3
        axis /= np.linalg.norm(axis)
        tip = rng.uniform(-3, 3, 3) + rng.uniform(-4, 6) * axis
        if trial % 4 == 1:
            tip += np.array([8.0, 0.0, 0.0])
        res = clearance(MeshIndex(mesh), cutter, tip[None], axis, margin=2.0)
        brute = _brute_clearance(cutter, tip, axis, V, F)
        if brute >= 2.0:
            assert res.capped[0] and res.delta[0] == 2.0 and np.all(np.isnan(res.witness[0]))
            kinds.add("capped")
            continue
        kinds.add("deep" if brute < -cutter.r else "shallow" if brute < 0 else "clear")
        assert not res.capped[0]
        assert res.delta[0] == pytest.approx(brute, abs=1e-6)
        # the witness is a mesh point with that signed distance
        assert _on_mesh(res.witness, mesh)[0] < 1e-9
        assert signed_distance(cutter, tip, axis, res.witness[0]) == pytest.approx(res.delta[0], abs=1e-12)
        # the normal is minus the gradient of the tool's signed distance at the witness (where
        # that gradient exists, i.e. the finite difference has unit length)
        num = _numeric_normal(cutter, tip, axis, res.witness[0])
        assert np.linalg.norm(res.normal[0]) == pytest.approx(1.0, abs=1e-12)
        if abs(np.linalg.norm(num) - 1.0) < 1e-6:
            np.testing.assert_allclose(res.normal[0], num, atol=1e-5)
            kinds.add("normal checked")
    assert kinds == {"capped", "deep", "shallow", "clear", "normal checked"}


@pytest.mark.parametrize("R, r", [(3.0, 2.0), (0.0, 1.5)])
def test_clearance_zero_when_touching_a_plane(R, r):
    # (a holder of radius R + r + 1 stays clear of the plane up to a lead of 75 deg)
    cutter = ToroidalCutter(R=R, r=r, holder_radius=R + r + 1.0, holder_length=10.0)
    mesh = _grid_mesh(41, 40.0)
    index = MeshIndex(mesh)
    rng = np.random.default_rng(8)
    leads = np.radians([0.0, 0.0, 3.0, 10.0, 25.0, 60.0, 75.0])
    tilts = np.radians([0.0, 40.0, -30.0, 170.0, 10.0, 95.0, -60.0])
    cc = np.column_stack([rng.uniform(-3, 3, 7), rng.uniform(-3, 3, 7), np.zeros(7)])
    T = np.array([_lead_tilt_axis(a, b) for a, b in zip(leads, tilts, strict=True)])
    n = np.array([0.0, 0.0, 1.0])
    cl = cc_to_cl(cutter, cc, n, T)
    res = clearance(index, cutter, cl, T)
    np.testing.assert_allclose(res.delta, 0.0, atol=1e-9)
    assert not res.capped.any()
    np.testing.assert_allclose(res.witness[:, 2], 0.0, atol=1e-12)
    # with lead the contact is a single point: the CC point
    np.testing.assert_allclose(res.witness[2:], cc[2:], atol=1e-6)
    # a facet contact: the normal is the plane's, on the tool's side
    np.testing.assert_allclose(res.normal, np.tile(n, (7, 1)), atol=1e-12)
    # the same tools mirrored below the sheet: the normal points down, toward them
    flip = np.array([1.0, 1.0, -1.0])
    below = clearance(index, cutter, cl * flip, T * flip)
    np.testing.assert_allclose(below.delta, 0.0, atol=1e-9)
    np.testing.assert_allclose(below.normal, np.tile(-n, (7, 1)), atol=1e-12)


def test_penetration_depth_into_a_plane():
    cutter = ToroidalCutter(R=3.0, r=2.0, shank_length=30.0)
    index = MeshIndex(_grid_mesh(61, 60.0))
    n = np.array([0.0, 0.0, 1.0])
    # tilted tools pushed along n by d < r: depth d exactly
    T = np.array([_lead_tilt_axis(a, b) for a, b in [(0.2, 0.0), (0.5, 1.0), (1.0, -2.0), (0.05, 0.3)]])
    cc = np.array([[0.3, 0.1, 0.0]] * 4)
    cl = cc_to_cl(cutter, cc, n, T)
    for d in (0.01, 0.5, 1.9):
        res = clearance(index, cutter, cl - d * n, T)
        np.testing.assert_allclose(res.delta, -d, atol=1e-9)
        # the separating direction is the plane's normal; moving the tool by -delta along it
        # makes it touch
        np.testing.assert_allclose(res.normal, np.tile(n, (4, 1)), atol=1e-12)
        back = clearance(index, cutter, cl - d * n - res.delta[:, None] * res.normal, T)
        np.testing.assert_allclose(back.delta, 0.0, atol=1e-9)
    # vertical tool pushed by d: on the plane the deepest point is the axis, at depth
    # min(d, R + r) from the tool's boundary (bottom face or shank wall)
    for d in (0.5, 1.0, 2.0, 3.5, 5.0, 9.0):
        res = clearance(index, cutter, np.array([[1.0, -2.0, -d]]), n)
        assert res.delta[0] == pytest.approx(-min(d, 5.0), abs=1e-9)
        if d < 5.0:  # the bottom face is nearest: lift the tool
            np.testing.assert_allclose(res.normal[0], n, atol=1e-12)
        else:  # buried deeper than its radius: any direction across the axis separates
            assert abs(res.normal[0] @ n) < 1e-12 and np.linalg.norm(res.normal[0]) == pytest.approx(1.0)


def test_deep_penetration_into_two_large_triangles_against_brute_force():
    """A tilted 100 mm square plane of two triangles; tilted tools with holders buried 1.5-8 mm
    along its normal (deeper than r: the deepest point lies inside a triangle, far from its
    edges, in the core cylinder or in the holder) against the brute force."""
    def height(x, y):
        return 0.03 * x - 0.02 * y

    V = np.array([[x, y, height(x, y)] for x, y in [(-50, -50), (50, -50), (50, 50), (-50, 50)]], dtype=float)
    F = np.array([[0, 1, 2], [0, 2, 3]])
    mesh = trimesh.Trimesh(V, F, process=False)
    index = MeshIndex(mesh)
    n = np.array([-0.03, 0.02, 1.0]) / np.linalg.norm([-0.03, 0.02, 1.0])
    rng = np.random.default_rng(23)
    deep = 0
    for trial in range(8):
        cutter = [ToroidalCutter(R=3.0, r=1.0, shank_length=8.0, holder_radius=6.0, holder_length=6.0),
                  ToroidalCutter(R=0.0, r=1.0, shank_length=3.0, holder_radius=3.0, holder_length=4.0)][trial % 2]
        axis = rng.normal(size=3)
        axis[2] = abs(axis[2]) + 1.0
        axis /= np.linalg.norm(axis)
        x, y = rng.uniform(-10, 10, 2)
        tip = np.array([x, y, height(x, y)]) - rng.uniform(1.5, 8.0) * n
        res = clearance(index, cutter, tip[None], axis)
        brute = _brute_clearance(cutter, tip, axis, V, F)
        deep += brute < -cutter.r
        assert res.delta[0] == pytest.approx(brute, abs=1e-6)
        assert signed_distance(cutter, tip, axis, res.witness[0]) == pytest.approx(res.delta[0], abs=1e-12)
        assert _on_mesh(res.witness, mesh)[0] < 1e-9
        num = _numeric_normal(cutter, tip, axis, res.witness[0])
        if abs(np.linalg.norm(num) - 1.0) < 1e-6:
            np.testing.assert_allclose(res.normal[0], num, atol=1e-5)
    assert deep >= 3


def test_shank_and_holder_gouges_against_a_wall():
    # wall: the plane x = 0 (y, z in [-20, 40]), normal +x
    ys = np.linspace(-20, 20, 41)
    zs = np.linspace(-20, 40, 61)
    Y, Z = np.meshgrid(ys, zs, indexing="ij")
    V = np.stack([np.zeros(Y.size), Y.ravel(), Z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(len(ys) - 1), np.arange(len(zs) - 1), indexing="ij")
    a = (i * len(zs) + j).ravel()
    nz = len(zs)
    F = np.concatenate([np.stack([a, a + nz, a + nz + 1], 1), np.stack([a, a + nz + 1, a + 1], 1)])
    wall = MeshIndex(trimesh.Trimesh(V, F, process=False))
    # a vertical tool whose cutter clears the wall but whose holder (radius 8) reaches 2 mm into it
    cutter = ToroidalCutter(R=2.0, r=1.0, shank_length=12.0, holder_radius=8.0, holder_length=10.0)
    res = clearance(wall, cutter, np.array([[6.0, 0.0, 0.0]]), np.array([0.0, 0.0, 1.0]))
    assert res.delta[0] == pytest.approx(6.0 - 8.0, abs=1e-9)
    assert 12.0 - 1e-9 <= res.witness[0, 2] <= 22.0 + 1e-9
    np.testing.assert_allclose(res.normal[0], [1.0, 0.0, 0.0], atol=1e-12)  # move the tool away: +x
    no_holder = ToroidalCutter(R=2.0, r=1.0, shank_length=12.0)
    res = clearance(wall, no_holder, np.array([[6.0, 0.0, 0.0]]), np.array([0.0, 0.0, 1.0]))
    assert res.capped[0] and res.delta[0] == 1.0
    res = clearance(wall, no_holder, np.array([[6.0, 0.0, 0.0]]), np.array([0.0, 0.0, 1.0]), margin=5.0)
    assert res.delta[0] == pytest.approx(3.0, abs=1e-9)
    # a tool leaning toward the wall: tip 4 mm away (cutter clear), shank through the wall
    T = np.array([-math.sin(0.4), 0.0, math.cos(0.4)])
    res = clearance(wall, no_holder, np.array([[4.0, 0.0, 0.0]]), T)
    top = np.array([4.0, 0.0, 0.0]) + 11.0 * T  # a shank axis point well inside: x < 0
    assert top[0] < 0
    assert res.delta[0] < -2.0
    assert res.witness[0, 2] > 3.0  # the deepest wall point is up along the shank, not at the tip
    assert signed_distance(no_holder, np.array([4.0, 0.0, 0.0]), T, res.witness[0]) == pytest.approx(
        res.delta[0], abs=1e-12)


def test_margin_caps_and_passes():
    cutter = ToroidalCutter(R=2.0, r=1.0)
    index = MeshIndex(_grid_mesh(41, 40.0))
    up = np.array([0.0, 0.0, 1.0])
    tips = np.array([[0.0, 0.0, 0.02], [0.0, 0.0, 0.3], [0.0, 0.0, 0.99], [0.0, 0.0, 1.5], [0, 0, 50.0],
                     [0.0, 0.0, -0.4]])
    res = clearance(index, cutter, tips, up, margin=1.0)
    np.testing.assert_allclose(res.delta, [0.02, 0.3, 0.99, 1.0, 1.0, -0.4], atol=1e-12)
    np.testing.assert_array_equal(res.capped, [False, False, False, True, True, False])
    assert np.all(np.isnan(res.witness[res.capped])) and np.all(np.isfinite(res.witness[~res.capped]))
    assert np.all(np.isnan(res.normal[res.capped])) and np.all(np.isfinite(res.normal[~res.capped]))
    empty = clearance(index, cutter, np.zeros((0, 3)), up)
    assert empty.delta.shape == (0,) and empty.witness.shape == (0, 3) and empty.normal.shape == (0, 3)
    res0 = clearance(index, cutter, tips, up, margin=0.0)
    np.testing.assert_allclose(res0.delta, [0, 0, 0, 0, 0, -0.4], atol=1e-12)
    assert res0.capped.tolist() == [True] * 5 + [False]


def _prism(radius: float, length: float, sections: int) -> trimesh.Trimesh:
    """Closed regular prism around the z axis (|z| <= length / 2): vertices at angles 2 pi k /
    sections on both rims, each side a long thin quad split into two triangles, fan caps."""
    phi = 2 * np.pi * np.arange(sections) / sections
    ring = np.column_stack([radius * np.cos(phi), radius * np.sin(phi)])
    V = np.vstack([np.column_stack([ring, np.full(sections, -length / 2)]),
                   np.column_stack([ring, np.full(sections, length / 2)]), [[0, 0, -length / 2], [0, 0, length / 2]]])
    k = np.arange(sections)
    k1 = (k + 1) % sections
    F = np.concatenate([np.stack([k, k1, k1 + sections], 1), np.stack([k, k1 + sections, k + sections], 1),
                        np.stack([np.full(sections, 2 * sections), k1, k], 1),
                        np.stack([np.full(sections, 2 * sections + 1), k + sections, k1 + sections], 1)])
    return trimesh.Trimesh(V, F, process=False)


def test_contact_normals_on_a_prism_closed_form():
    """Facet, edge and vertex contacts on a 16-sided prism of long thin triangles (120 x 7.8 mm),
    touching, clear and penetrating; every expected value is a closed form."""
    Rc, L, S = 20.0, 120.0, 16
    index = MeshIndex(_prism(Rc, L, S))
    apothem = Rc * math.cos(math.pi / S)
    ez = np.array([0.0, 0.0, 1.0])
    torus = ToroidalCutter(R=2.0, r=1.0, holder_radius=6.0, holder_length=10.0)
    ball = ToroidalCutter(R=0.0, r=1.5, holder_radius=5.0, holder_length=10.0)
    for g in (-0.5, 0.0, 0.4):
        # facet: CC on side k (off its middle and on the diagonal edge), feed along z, lead
        # 5-30 deg: the torus touches at CC, the normal is the side's
        for k, dphi, z0, lead in [(0, 0.0, 0.0, 0.3), (3, 0.05, 17.0, 0.1), (9, -0.1, -40.0, 0.5),
                                  (12, 0.02, 3.0, 0.09)]:
            psi = (k + 0.5) * 2 * math.pi / S
            n = np.array([math.cos(psi), math.sin(psi), 0.0])
            cc = apothem * n + Rc * math.tan(dphi) * np.array([-n[1], n[0], 0.0]) + z0 * ez
            T = math.sin(lead) * ez + math.cos(lead) * n
            tip = cc_to_cl(torus, cc, n, T) + g * n
            res = clearance(index, torus, tip[None], T, margin=1.0)
            assert res.delta[0] == pytest.approx(g, abs=1e-9)
            np.testing.assert_allclose(res.witness[0], cc, atol=1e-9)
            np.testing.assert_allclose(res.normal[0], n, atol=1e-12)
        # edge: ball nose with its axis through a ridge, and a flat bottom parallel to a ridge
        # (every ridge point under the bottom face ties)
        for k, z0 in [(2, 0.0), (7, 31.3), (15, -52.0)]:
            u = np.array([math.cos(2 * math.pi * k / S), math.sin(2 * math.pi * k / S), 0.0])
            ridge = Rc * u + z0 * ez
            res = clearance(index, ball, (ridge + (g + ball.r) * u - ball.r * u)[None], u, margin=1.0)
            assert res.delta[0] == pytest.approx(g, abs=1e-9)
            np.testing.assert_allclose(res.witness[0], ridge, atol=1e-9)
            np.testing.assert_allclose(res.normal[0], u, atol=1e-9)
            res = clearance(index, torus, (ridge + g * u)[None], u, margin=1.0)
            assert res.delta[0] == pytest.approx(g, abs=1e-9)
            w = res.witness[0]
            assert abs(w[2] - z0) <= torus.R + 1e-9
            np.testing.assert_allclose(w - w[2] * ez, Rc * u, atol=1e-9)
            np.testing.assert_allclose(res.normal[0], u, atol=1e-9)
        # vertex: ball nose over a rim vertex, its axis inside the vertex's normal cone
        for k, top in [(4, 1.0), (11, -1.0)]:
            vert = Rc * np.array([math.cos(2 * math.pi * k / S), math.sin(2 * math.pi * k / S), 0.0]) + top * L / 2 * ez
            u = (vert - top * L / 2 * ez) / Rc + 0.7 * top * ez
            u /= np.linalg.norm(u)
            res = clearance(index, ball, (vert + (g + ball.r) * u - ball.r * u)[None], u, margin=1.0)
            assert res.delta[0] == pytest.approx(g, abs=1e-9)
            np.testing.assert_allclose(res.witness[0], vert, atol=1e-9)
            np.testing.assert_allclose(res.normal[0], u, atol=1e-9)


def test_ball_nose_on_a_sphere_mesh_against_closest_points():
    """Ball nose near an icosphere mesh: with the axis within 20 deg of the radial direction and
    the ball centre c outside the mesh, the nearest point of the capsule to every mesh point is
    c, so delta = dist(c, mesh) - r, the witness is the mesh's closest point to c and the normal
    points from it to c (trimesh.proximity.closest_point: independent).  Facet, edge and vertex
    contacts all occur."""
    Rs, r = 10.0, 1.5
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=Rs)
    cutter = ToroidalCutter(R=0.0, r=r, holder_radius=4.0, holder_length=10.0)
    rng = np.random.default_rng(21)
    N = 300
    d = rng.normal(size=(N, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    c = (Rs + r + rng.uniform(-0.9 * r, 0.5, N))[:, None] * d
    t = rng.normal(size=(N, 3))
    t -= np.sum(t * d, axis=1, keepdims=True) * d
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    ang = np.radians(rng.uniform(0.0, 20.0, N))
    T = np.cos(ang)[:, None] * d + np.sin(ang)[:, None] * t
    res = clearance(MeshIndex(mesh), cutter, c - r * T, T, margin=2.0)
    cp, dist, tri = trimesh.proximity.closest_point(mesh, c)
    assert not res.capped.any()
    np.testing.assert_allclose(res.delta, dist - r, atol=1e-9)
    np.testing.assert_allclose(res.witness, cp, atol=1e-9)
    np.testing.assert_allclose(res.normal, (c - cp) / dist[:, None], atol=1e-9)
    # witness + delta * normal is the point of the tool's surface nearest the witness
    np.testing.assert_allclose(signed_distance(cutter, c - r * T, T, res.witness + res.delta[:, None] * res.normal),
                               0.0, atol=1e-9)
    # kinds of contact: barycentric coordinates of the closest point on its triangle
    bary = trimesh.triangles.points_to_barycentric(mesh.triangles[tri], cp)
    zeros = np.sum(bary < 1e-9, axis=1)
    assert {0, 1, 2} <= set(zeros.tolist())  # interior, edge, vertex


def test_coarse_sliver_strip_against_brute_force():
    """A bumpy strip of long thin triangles (40 x 4 mm), toroidal, ball-nose and held cutters in
    random poses from clear to deeper than r, against the brute force."""
    rng = np.random.default_rng(22)
    xs = np.array([-40.0, 0.0, 40.0])
    V = np.vstack([np.column_stack([xs, np.full(3, -2.0), rng.uniform(-1, 1, 3)]),
                   np.column_stack([xs + 20.0, np.full(3, 2.0), rng.uniform(-1, 1, 3)])])
    F = np.array([[0, 1, 3], [1, 4, 3], [1, 2, 4], [2, 5, 4]])
    mesh = trimesh.Trimesh(V, F, process=False)
    index = MeshIndex(mesh)
    kinds = set()
    for trial in range(12):
        cutter = [ToroidalCutter(R=3.0, r=1.0), ToroidalCutter(R=0.0, r=2.0),
                  ToroidalCutter(R=1.5, r=0.5, shank_length=4.0, holder_radius=4.0, holder_length=5.0)][trial % 3]
        axis = rng.normal(size=3)
        axis[2] = abs(axis[2]) + 0.5
        axis /= np.linalg.norm(axis)
        tip = np.array([rng.uniform(-20, 30), rng.uniform(-1.5, 1.5), rng.uniform(-2.5, 1.5)])
        res = clearance(index, cutter, tip[None], axis, margin=3.0)
        brute = _brute_clearance(cutter, tip, axis, V, F)
        assert brute < 3.0
        kinds.add("deep" if brute < -cutter.r else "shallow" if brute < 0 else "clear")
        assert res.delta[0] == pytest.approx(brute, abs=1e-6)
        assert signed_distance(cutter, tip, axis, res.witness[0]) == pytest.approx(res.delta[0], abs=1e-12)
        assert _on_mesh(res.witness, mesh)[0] < 1e-9
    assert kinds == {"deep", "shallow", "clear"}


def test_subdivision_gives_the_same_exact_answer():
    # two triangles for a 100 mm plane, and a coarse icosphere, with and without max_edge
    rng = np.random.default_rng(9)
    cutter = ToroidalCutter(R=2.0, r=1.0)
    plane = trimesh.Trimesh([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], [[0, 1, 2], [0, 2, 3]],
                            process=False)
    ball = trimesh.creation.icosphere(subdivisions=1, radius=15.0)
    for mesh in (plane, ball):
        coarse, fine = MeshIndex(mesh), MeshIndex(mesh, max_edge=2.0)
        assert fine.face_long.max() <= 2.0 + 1e-9 and len(fine.faces) > 50 * len(coarse.faces)
        T = rng.normal(size=(60, 3))
        T[:, 2] = np.abs(T[:, 2]) + 0.5
        T /= np.linalg.norm(T, axis=1, keepdims=True)
        tips = rng.uniform(-12, 12, (60, 3))
        tips[:, 2] = rng.uniform(-2, 18, 60) if mesh is ball else rng.uniform(-1.5, 1.0, 60)
        a = clearance(coarse, cutter, tips, T, margin=3.0)
        b = clearance(fine, cutter, tips, T, margin=3.0)
        np.testing.assert_allclose(a.delta, b.delta, atol=1e-8)
        np.testing.assert_array_equal(a.capped, b.capped)


def test_many_poses_match_single_pose_calls_and_ignore_loose_vertices():
    rng = np.random.default_rng(10)
    mesh = _grid_mesh(61, 60.0, lambda x, y: 3 * np.sin(x / 6) * np.cos(y / 9))
    # an unused far vertex must not count
    loose = trimesh.Trimesh(np.vstack([mesh.vertices, [[0.0, 0.0, 1.0]]]), mesh.faces, process=False)
    index = MeshIndex(loose)
    assert len(index.vertices) == len(mesh.vertices)
    cutter = ToroidalCutter(R=3.0, r=1.0, holder_radius=6.0, holder_length=20.0)
    N = 1100  # more than one chunk
    tips = np.column_stack([rng.uniform(-25, 25, N), rng.uniform(-25, 25, N), rng.uniform(-1, 5, N)])
    T = rng.normal(size=(N, 3))
    T[:, 2] = np.abs(T[:, 2]) + 1.0
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    res = clearance(index, cutter, tips, T)
    assert res.capped.sum() > 50 and (res.delta < 0).sum() > 50
    for i in rng.choice(N, 25, replace=False):
        one = clearance(index, cutter, tips[i:i + 1], T[i])
        assert one.delta[0] == res.delta[i]
    # delta is a lower bound of the signed distance at every mesh vertex
    sd = signed_distance(cutter, tips[:, None, :], T[:, None, :], index.vertices[None, ::7, :])
    assert np.all(res.delta[:, None] <= sd + 1e-12)


def test_clearance_bad_input():
    index = MeshIndex(_grid_mesh(5, 10.0))
    cutter = ToroidalCutter(R=1.0, r=1.0)
    up = np.array([0.0, 0.0, 1.0])
    with pytest.raises(InputError, match="shape"):
        clearance(index, cutter, np.zeros(3), up)
    with pytest.raises(InputError, match="axes"):
        clearance(index, cutter, np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(InputError, match="zero length"):
        clearance(index, cutter, np.zeros((2, 3)), np.zeros(3))
    with pytest.raises(InputError, match="finite"):
        clearance(index, cutter, np.full((1, 3), np.nan), up)
    with pytest.raises(InputError, match="margin"):
        clearance(index, cutter, np.zeros((1, 3)), up, margin=-1.0)
    with pytest.raises(InputError, match="max_edge"):
        MeshIndex(_grid_mesh(5, 10.0), max_edge=0.0)
    with pytest.raises(InputError) as err:
        MeshIndex(np.zeros((3, 3)))
    assert str(err.value) == "mesh must be a trimesh.Trimesh, got ndarray"


@pytest.mark.parametrize("vertices, faces, message", [
    (np.zeros((3, 3)), np.zeros((0, 3), int), "mesh has no triangles"),
    (np.eye(3), np.array([[0, 1, 3]]), "mesh faces index missing vertices"),
    (np.eye(3), np.array([[0, 1, -1]]), "mesh faces index missing vertices"),
    (np.array([[0.0, 0, 0], [1, 0, 0], [0, np.inf, 0]]), np.array([[0, 1, 2]]),
     "mesh has non-finite vertex coordinates"),
])
def test_mesh_index_names_what_is_wrong_with_the_mesh(vertices, faces, message):
    with pytest.raises(InputError) as err:
        MeshIndex(trimesh.Trimesh(vertices, faces, process=False, validate=False))
    assert str(err.value) == message
    # a one-triangle mesh is valid (3 vertices, 1 face), and a small positive max_edge too
    MeshIndex(trimesh.Trimesh(np.eye(3), [[0, 1, 2]], process=False), max_edge=0.5)


def test_zero_axes_are_named_by_their_row_in_the_callers_words():
    index = MeshIndex(_grid_mesh(5, 10.0))
    cutter = ToroidalCutter(R=1.0, r=1.0)
    axes = np.array([[0.0, 0, 1], [0, 0, 1], [0, 0, 0]])
    with pytest.raises(InputError) as err:
        clearance(index, cutter, np.zeros((3, 3)), axes)
    assert str(err.value).startswith("tool axis of tool tip 3 has zero length")
    with pytest.raises(InputError) as err:
        axial_drop(index, cutter, np.zeros((3, 3)), axes)
    assert str(err.value).startswith("tool axis of point 3 has zero length")


def test_axes_of_any_length_are_normalised():
    """Docstrings: 'normalised here'. Axes scaled by 3 and by 0.2 give the unit axes' answers."""
    mesh = _grid_mesh(9, 20.0, lambda x, y: np.sin(x / 3) * np.cos(y / 4))
    index = MeshIndex(mesh)
    cutter = ToroidalCutter(R=2.0, r=1.0)
    rng = np.random.default_rng(5)
    A = rng.normal(size=(30, 3)) * [0.3, 0.3, 0.0] + [0, 0, 1]
    A /= np.linalg.norm(A, axis=1, keepdims=True)
    P = np.column_stack([rng.uniform(-6, 6, 30), rng.uniform(-6, 6, 30), np.full(30, 3.0)])
    unit = clearance(index, cutter, P, A, margin=5.0)
    drop = axial_drop(index, cutter, P, A)
    for k in (3.0, 0.2):
        np.testing.assert_allclose(clearance(index, cutter, P, k * A, margin=5.0).delta, unit.delta, atol=1e-12)
        np.testing.assert_allclose(axial_drop(index, cutter, P, k * A).cl, drop.cl, atol=1e-12)
    assert unit.margin == 5.0
    assert np.array_equal(unit.capped, unit.delta >= 5.0)


@pytest.mark.parametrize("shift", [0, 1, 2])
def test_axial_drop_onto_a_ridge_edge(shift):
    """A ball-nose dropped onto the ridge of a tent (faces sloping down at 45 deg from the x axis):
    the ridge's normal cone holds +z, so the ball's lowest point sits on the ridge (cl_z = 0) and
    touches it right below the tip. The faces' vertex order is rotated by ``shift``, so the ridge is each of
    a face's three edges in turn."""
    V = np.array([[-10.0, 0, 0], [10, 0, 0], [10, 10, -10], [-10, 10, -10], [10, -10, -10], [-10, -10, -10]])
    F = np.roll(np.array([[0, 1, 2], [0, 2, 3], [1, 0, 5], [1, 5, 4]]), shift, axis=1)
    mesh = trimesh.Trimesh(V, F, process=False)
    cutter = ToroidalCutter(R=0.0, r=2.0)
    x = np.linspace(-6, 6, 7)
    P = np.column_stack([x, np.zeros(7), np.full(7, 5.0)])
    drop = axial_drop(MeshIndex(mesh), cutter, P, np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(drop.cl[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(drop.contact, np.column_stack([x, np.zeros(7), np.zeros(7)]), atol=1e-6)


def test_axial_drop_in_several_chunks_equals_point_by_point():
    """More points than one chunk (512): every chunk's answer lands on its own points."""
    mesh = _grid_mesh(9, 20.0, lambda x, y: np.sin(x / 3) * np.cos(y / 4))
    index = MeshIndex(mesh)
    cutter = ToroidalCutter(R=2.0, r=1.0)
    rng = np.random.default_rng(6)
    P = np.column_stack([rng.uniform(-6, 6, 1100), rng.uniform(-6, 6, 1100), np.full(1100, 3.0)])
    up = np.array([0.0, 0.0, 1.0])
    drop = axial_drop(index, cutter, P, up)
    for k in (0, 511, 512, 1023, 1024, 1099):
        np.testing.assert_allclose(axial_drop(index, cutter, P[k:k + 1], up).cl[0], drop.cl[k], atol=1e-12)


# ---------------------------------------------------------------------------------------------
# axial drop

def _sphere_drop(cutter, p, A, O, Rs):
    """Closed form: the core disc (radius R, r above the tip) at distance Rs + r from O."""
    q = O - p
    h = q @ A if q.ndim == 1 else np.sum(q * A, axis=-1)
    rho = np.linalg.norm(q - h[..., None] * A, axis=-1)
    x = np.maximum(rho - cutter.R, 0.0)
    return h - cutter.r + np.sqrt((Rs + cutter.r) ** 2 - x * x)


def test_axial_drop_on_a_plane_closed_form():
    cutter = ToroidalCutter(R=3.0, r=2.0)
    mesh = _grid_mesh(31, 60.0)
    index = MeshIndex(mesh)
    rng = np.random.default_rng(11)
    foot = np.column_stack([rng.uniform(-15, 15, 200), rng.uniform(-15, 15, 200), np.zeros(200)])
    n = np.array([0.0, 0.0, 1.0])
    for A in (n, _lead_tilt_axis(0.3, 0.7), _lead_tilt_axis(1.2, -2.0)):
        pts = foot + rng.uniform(-5, 30, 200)[:, None] * A  # lines through the plane's middle
        na = A @ n
        s = (cutter.r * (1 - na) + cutter.R * math.sqrt(max(1 - na * na, 0.0)) - pts @ n) / na
        for axis in (A, np.tile(A, (len(pts), 1))):
            drop = axial_drop(index, cutter, pts, axis)
            assert drop.hit.all()
            np.testing.assert_allclose(drop.cl, pts + s[:, None] * A, atol=1e-9)
            np.testing.assert_allclose(drop.contact[:, 2], 0.0, atol=1e-9)
            np.testing.assert_allclose(drop.contact_normal, np.tile(n, (len(pts), 1)), atol=1e-9)
            if na < 1:
                np.testing.assert_allclose(cl_to_cc(cutter, drop.cl, n, A), drop.contact, atol=1e-7)
    # the mesh object itself is accepted too
    d2 = axial_drop(mesh, cutter, foot[:5] + 10.0 * n, n)
    np.testing.assert_allclose(d2.cl, foot[:5], atol=1e-9)


def test_axial_drop_on_a_sphere_within_chord_error():
    Rs = 10.0
    mesh = trimesh.creation.icosphere(subdivisions=4, radius=Rs)
    centres = mesh.triangles_center
    nrm = mesh.face_normals
    sag = Rs - float(np.min(np.sum(centres * nrm, axis=1)))  # the mesh holds the sphere Rs - sag
    assert 0 < sag < 0.02
    O = np.zeros(3)
    rng = np.random.default_rng(12)
    for cutter in (ToroidalCutter(R=3.0, r=2.0), ToroidalCutter(R=0.0, r=1.0)):
        for A in (np.array([0.0, 0.0, 1.0]), _lead_tilt_axis(0.6, 0.4)):
            e1 = np.cross(A, [1.0, 0, 0])
            e1 /= np.linalg.norm(e1)
            e2 = np.cross(A, e1)
            rad = (Rs + cutter.R) * np.sqrt(rng.uniform(0, 1, 150))
            ang = rng.uniform(-math.pi, math.pi, 150)
            pts = 40 * A + rad[:, None] * (np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2)
            drop = axial_drop(mesh, cutter, pts, A)
            assert drop.hit.all()
            s = np.sum((drop.cl - pts) * A, axis=1)
            hi = _sphere_drop(cutter, pts, A, O, Rs)
            lo = _sphere_drop(cutter, pts, A, O, Rs - sag)
            assert np.all(s <= hi + 1e-9) and np.all(s >= lo - 1e-9)
            # the contact lies on the mesh and its normal is close to the sphere's
            assert np.all(_on_mesh(drop.contact, mesh) < 1e-9)
            sph = drop.contact / np.linalg.norm(drop.contact, axis=1, keepdims=True)
            assert np.all(np.sum(sph * drop.contact_normal, axis=1) > math.cos(0.1))


def test_axial_drop_on_a_cylinder_within_chord_error():
    Rc, sections = 8.0, 256
    mesh = trimesh.creation.cylinder(radius=Rc, height=120.0, sections=sections)
    mesh.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [0, 1, 0]))  # axis -> x
    index = MeshIndex(mesh)
    fine = MeshIndex(mesh, max_edge=4.0)  # same surface, split facets: same answer
    u = np.array([1.0, 0.0, 0.0])
    inner = Rc * math.cos(math.pi / sections)
    rng = np.random.default_rng(13)
    cutter = ToroidalCutter(R=2.5, r=1.5)
    for tilt in (0.0, 0.5):
        A = np.array([0.0, math.sin(tilt), math.cos(tilt)])  # perpendicular to the cylinder's axis
        e = np.cross(A, u)
        pts = np.column_stack([rng.uniform(-40, 40, 200), np.zeros(200), np.zeros(200)]) + \
            rng.uniform(-(Rc + 2.0), Rc + 2.0, 200)[:, None] * e + 30.0 * A
        drop = axial_drop(index, cutter, pts, A)
        assert drop.hit.all()
        s = np.sum((drop.cl - pts) * A, axis=1)
        np.testing.assert_allclose(axial_drop(fine, cutter, pts[:20], A).cl, drop.cl[:20], atol=1e-9)

        def closed(radius, pts=pts, A=A, e=e):
            d = -pts - (-pts @ u)[:, None] * u
            x = np.maximum(np.abs(d @ e) - cutter.R, 0.0)
            return d @ A - cutter.r + np.sqrt((radius + cutter.r) ** 2 - x * x)

        assert np.all(s <= closed(Rc) + 1e-9) and np.all(s >= closed(inner) - 1e-9)
        assert np.max(closed(Rc) - closed(inner)) < 2e-3


def test_axial_drop_misses_and_per_point_axes():
    cutter = ToroidalCutter(R=2.0, r=1.0)
    mesh = _grid_mesh(21, 20.0, lambda x, y: np.sin(x / 3) + 0.1 * y)
    index = MeshIndex(mesh)
    pts = np.array([[0.0, 0.0, 20.0], [50.0, 0.0, 20.0], [12.5, 0.0, 5.0], [13.5, 0.0, 5.0]])
    drop = axial_drop(index, cutter, pts, np.array([0.0, 0.0, 1.0]))
    assert drop.hit.tolist() == [True, False, True, False]  # 12.5 reaches the edge at 10 + R + r
    assert np.all(np.isnan(drop.cl[~drop.hit])) and np.all(np.isnan(drop.contact_normal[~drop.hit]))
    rng = np.random.default_rng(14)
    P = np.column_stack([rng.uniform(-12, 12, 300), rng.uniform(-12, 12, 300), rng.uniform(-3, 8, 300)])
    A = rng.normal(size=(300, 3))
    A[:, 2] = np.abs(A[:, 2]) + 1.0
    A /= np.linalg.norm(A, axis=1, keepdims=True)
    each = axial_drop(index, cutter, P, A)
    for k in rng.choice(300, 10, replace=False):
        one = axial_drop(index, cutter, P[k:k + 1], A[k])
        assert one.hit[0] == each.hit[k]
        if one.hit[0]:
            np.testing.assert_allclose(one.cl[0], each.cl[k], atol=1e-9)


def _mesh_samples(mesh: trimesh.Trimesh, k: int) -> np.ndarray:
    """Points of a barycentric grid of k + 1 per side on every triangle."""
    tri = mesh.triangles
    i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    m = i + j <= k
    bu, bv = i[m] / k, j[m] / k
    return (tri[:, None, 0] + bu[None, :, None] * (tri[:, None, 1] - tri[:, None, 0])
            + bv[None, :, None] * (tri[:, None, 2] - tri[:, None, 0])).reshape(-1, 3)


def _check_drop(mesh, index, cutter, P, A, drop, samples, gap):
    """At every dropped position the tool touches without penetrating (clearance 0, the compiled
    kernels: an independent algorithm), the contact is a mesh point (trimesh) at zero signed
    distance, no sampled mesh point asks for a higher tool and the best sample is within ``gap``
    (mm) of the drop; the contact normal is unit and the tool's tangent plane there."""
    A = np.broadcast_to(A, P.shape)
    s = np.sum((drop.cl - P) * A, axis=1)
    res = clearance(index, cutter, drop.cl, A)
    np.testing.assert_allclose(res.delta, 0.0, atol=1e-8)
    assert np.all(_on_mesh(drop.contact, mesh) < 1e-9)
    np.testing.assert_allclose(signed_distance(cutter, drop.cl, A, drop.contact), 0.0, atol=1e-9)
    q = samples[None, :, :] - P[:, None, :]
    h = np.einsum("nmk,nk->nm", q, A)
    rho = np.linalg.norm(q - h[..., None] * A[:, None, :], axis=-1)
    x = np.clip(rho - cutter.R, 0.0, cutter.r)
    sv = np.where(rho <= cutter.R + cutter.r, h - (cutter.r - np.sqrt(cutter.r ** 2 - x * x)), -np.inf)
    assert np.all(sv.max(axis=1) <= s + 1e-9)
    assert np.all(sv.max(axis=1) >= s - gap)
    np.testing.assert_allclose(np.linalg.norm(drop.contact_normal, axis=1), 1.0, atol=1e-12)
    below = drop.contact - 1e-4 * drop.contact_normal
    np.testing.assert_allclose(signed_distance(cutter, drop.cl, A, below), 1e-4, atol=1e-9)


def test_axial_drop_agrees_with_clearance_and_dense_sampling():
    """Per-point axes within ~27 deg of +z over a noisy wave (``_check_drop``), three cutters."""
    rng = np.random.default_rng(15)
    mesh = _grid_mesh(13, 24.0,
                      lambda x, y: 2 * np.sin(x / 2.5) * np.cos(y / 3.5) + 0.3 * rng.normal(size=x.shape))
    index = MeshIndex(mesh)
    samples = _mesh_samples(mesh, 12)
    for cutter in (ToroidalCutter(R=2.0, r=1.0), ToroidalCutter(R=0.0, r=1.5), ToroidalCutter(R=3.0, r=0.5)):
        N = 60
        A = rng.normal(size=(N, 3))
        A[:, 2] = np.abs(A[:, 2]) + 2.0
        A /= np.linalg.norm(A, axis=1, keepdims=True)
        P = np.column_stack([rng.uniform(-8, 8, N), rng.uniform(-8, 8, N), np.full(N, 5.0)])
        drop = axial_drop(index, cutter, P, A)
        assert drop.hit.all()
        _check_drop(mesh, index, cutter, P, A, drop, samples, 0.05)


@pytest.mark.parametrize("case", ["steep axes, coarse mesh", "fixed tilted axis", "from far below",
                                  "axis in a coordinate plane"])
def test_axial_drop_hard_cases(case):
    """Cases the wave above does not reach: axes 50-70 deg from +z over triangles larger than the
    cutter (the line crosses the mesh's box through its sides, facet contacts dominate); one
    common tilted axis (the projected-tree path); drop lines starting far below and beyond the
    mesh (the line is clipped to the box: the whole line counts, not the ray); axes with a zero
    component (a slab parallel to the line). Checked as ``_check_drop``; unpacking gives
    (cl, contact, contact_normal)."""
    rng = np.random.default_rng(21)
    coarse = case == "steep axes, coarse mesh"
    mesh = _grid_mesh(5 if coarse else 11, 30.0,
                      lambda x, y: 3 * np.sin(x / 4) * np.cos(y / 5) + 0.4 * rng.normal(size=x.shape))
    index = MeshIndex(mesh)
    samples = _mesh_samples(mesh, 40 if coarse else 14)
    cutter = ToroidalCutter(R=2.5, r=1.0)
    N = 40
    P = np.column_stack([rng.uniform(-9, 9, N), rng.uniform(-9, 9, N), np.full(N, 4.0)])
    if coarse:
        polar, az = np.radians(rng.uniform(50, 70, N)), rng.uniform(0, 2 * np.pi, N)
        A = np.column_stack([np.sin(polar) * np.cos(az), np.sin(polar) * np.sin(az), np.cos(polar)])
    elif case == "fixed tilted axis":
        A = np.array([0.5, -0.3, 0.8])
        A = A / np.linalg.norm(A)
    elif case == "from far below":
        A = rng.normal(size=(N, 3)) * [0.4, 0.4, 0.0] + [0.0, 0.0, 1.0]
        A /= np.linalg.norm(A, axis=1, keepdims=True)
        P = P - 60.0 * A  # 60 mm back along the axis: below the mesh's box
    else:
        A = np.tile([[0.6, 0.0, 0.8], [0.0, -0.6, 0.8], [0.0, 0.0, 1.0]], (N // 3 + 1, 1))[:N]
    drop = axial_drop(index, cutter, P, A)
    keep = drop.hit
    assert keep.sum() >= N // 2
    if A.ndim == 1:
        fixed = axial_drop(index, cutter, P, np.tile(A, (N, 1)))  # the per-point path agrees
        np.testing.assert_allclose(fixed.cl[keep], drop.cl[keep], atol=1e-9)
        assert np.array_equal(fixed.hit, drop.hit)
    cl, contact, normal = drop
    assert cl is drop.cl and contact is drop.contact and normal is drop.contact_normal
    Ak = A[keep] if A.ndim == 2 else A
    sub = type(drop)(cl=drop.cl[keep], contact=drop.contact[keep], contact_normal=drop.contact_normal[keep],
                     hit=drop.hit[keep])
    _check_drop(mesh, index, cutter, P[keep], Ak, sub, samples, 0.1 if coarse else 0.05)


def test_axial_drop_bad_input():
    index = MeshIndex(_grid_mesh(5, 10.0))
    cutter = ToroidalCutter(R=1.0, r=1.0)
    with pytest.raises(InputError, match="shape"):
        axial_drop(index, cutter, np.zeros((2, 2)), np.array([0, 0, 1.0]))
    with pytest.raises(InputError, match="axes"):
        axial_drop(index, cutter, np.zeros((2, 3)), np.zeros((3, 3)))
    with pytest.raises(InputError, match="zero length"):
        axial_drop(index, cutter, np.zeros((2, 3)), np.zeros(3))


def test_mesh_index_leaf_order_maps_back_to_the_faces():
    """``bvh_faces`` is a permutation of the faces and the kernels' per-triangle tables are the
    faces in that order; edges are each undirected edge once, three per face."""
    mesh = _grid_mesh(7, 10.0, lambda x, y: np.sin(x) * np.cos(y))
    index = MeshIndex(mesh)
    assert sorted(index.bvh_faces.tolist()) == list(range(len(mesh.faces)))
    np.testing.assert_array_equal(index._bvh_ti, mesh.faces[index.bvh_faces])
    np.testing.assert_allclose(index._bvh_tf[:, 3:6], mesh.triangles[index.bvh_faces].mean(axis=1))
    undirected = {tuple(sorted(e)) for f in mesh.faces for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    assert {tuple(e) for e in index.edges.tolist()} == undirected and len(index.edges) == len(undirected)
    for k, f in enumerate(mesh.faces):
        assert {tuple(index.edges[e]) for e in index.face_edges[k]} == \
            {tuple(sorted(e)) for e in ((f[0], f[1]), (f[1], f[2]), (f[2], f[0]))}
    # vertex -> faces table
    for v in range(len(mesh.vertices)):
        got = sorted(index.vf_faces[index.vf_ptr[v]:index.vf_ptr[v + 1]].tolist())
        assert got == sorted(np.flatnonzero((mesh.faces == v).any(axis=1)).tolist())


def test_axial_drop_per_point_axes_parallel_to_box_faces_and_missing_lines():
    """Per-point axes with zero components (slabs parallel to the line) from points outside the
    mesh's box in those coordinates: misses, as the fixed-axis path says; inside: the same drops."""
    mesh = _grid_mesh(9, 20.0, lambda x, y: np.sin(x / 3) * np.cos(y / 4))
    index = MeshIndex(mesh)
    cutter = ToroidalCutter(R=2.0, r=1.0)
    P = np.array([[0.0, 0.0, 5.0], [40.0, 0.0, 5.0], [0.0, -40.0, 5.0], [3.0, 2.0, -30.0], [14.0, 0.0, 5.0]])
    up = np.array([0.0, 0.0, 1.0])
    fixed = axial_drop(index, cutter, P, up)
    each = axial_drop(index, cutter, P, np.tile(up, (len(P), 1)))
    assert fixed.hit.tolist() == [True, False, False, True, False] and each.hit.tolist() == fixed.hit.tolist()
    np.testing.assert_allclose(each.cl[fixed.hit], fixed.cl[fixed.hit], atol=1e-12)
    # a line along x far off the mesh in y misses; one through it (x varies along the line) hits
    side = axial_drop(index, cutter, np.array([[0.0, 30.0, 0.0], [-30.0, 0.0, -0.5]]),
                      np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]))
    assert side.hit.tolist() == [False, True]


def test_axial_drop_contact_on_the_axis_has_the_surface_normal():
    """A ball-nose dropped onto a flat grid right above one of its vertices touches it on the axis:
    the contact normal is the plane's normal (+z), not undefined."""
    index = MeshIndex(_grid_mesh(5, 10.0))
    for cutter in (ToroidalCutter(R=0.0, r=1.5), ToroidalCutter(R=2.0, r=1.0)):
        drop = axial_drop(index, cutter, np.array([[0.0, 0.0, 3.0], [2.5, -2.5, 3.0]]), np.array([0.0, 0.0, 1.0]))
        np.testing.assert_allclose(drop.cl[:, 2], 0.0, atol=1e-12)
        np.testing.assert_allclose(drop.contact_normal, [[0.0, 0.0, 1.0]] * 2, atol=1e-12)
