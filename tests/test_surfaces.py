"""Tests of camsmooth.geometry.surfaces: derivatives, curvature (value and sign), tessellation, definition
files and mesh loading. Geometry is checked against finite differences and closed forms."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import trimesh

from camsmooth.errors import InputError
from camsmooth.geometry.surfaces import (
    BSplineSurface,
    Cylinder,
    Plane,
    Saddle,
    Sinusoid,
    SpherePatch,
    load_definition,
    load_mesh,
    load_surface,
    save_definition,
    save_mesh,
    surface_normals_at,
    tessellate,
    tessellate_to_tolerance,
)


def _bspline(custom_knots: bool = False) -> BSplineSurface:
    x = np.linspace(0.0, 40.0, 6)
    y = np.linspace(0.0, 30.0, 5)
    X, Y = np.meshgrid(x, y, indexing="ij")
    Z = 4.0 * np.sin(X / 12.0) * np.cos(Y / 15.0) + 0.002 * X * Y
    control = np.stack([X + 0.5 * np.sin(Y / 7.0), Y, Z], axis=-1)
    if custom_knots:
        tu = [0.0, 0.0, 0.0, 0.0, 10.0, 25.0, 40.0, 40.0, 40.0, 40.0]
        tv = [0.0, 0.0, 0.0, 0.0, 12.0, 30.0, 30.0, 30.0, 30.0]
        return BSplineSurface(control, degree=(3, 3), knots_u=tu, knots_v=tv)
    return BSplineSurface(control, degree=3, u_range=(0.0, 40.0), v_range=(0.0, 30.0))


SURFACES = {
    "plane": lambda: Plane((0.0, 10.0), (-5.0, 5.0), origin=(1.0, 2.0, 3.0), u_dir=(1.0, 0.0, 0.2),
                           v_dir=(0.1, 1.0, 0.0)),
    "cylinder": lambda: Cylinder(40.0, (-10.0, 10.0), (-20.0, 20.0), axis=(1.0, 0.3, 0.1),
                                 center=(0, 0, -30)),
    "cylinder_in": lambda: Cylinder(35.0, (-10.0, 10.0), (-20.0, 20.0), axis=(0.0, 1.0, 0.0), concave=True),
    "sphere": lambda: SpherePatch(50.0, (-20.0, 25.0), (-20.0, 20.0), center=(1.0, -2.0, 0.0)),
    "sphere_in": lambda: SpherePatch(45.0, (-20.0, 20.0), (-15.0, 20.0), concave=True),
    "saddle": lambda: Saddle(1 / 90, 1 / 70, (-30.0, 30.0), (-25.0, 30.0), center=(2.0, 1.0, 5.0)),
    "sinusoid": lambda: Sinusoid(3.0, 0.12, 0.09, (0.0, 40.0), (0.0, 30.0), center=(0.0, 0.0, 1.0)),
    "bspline": _bspline,
    "bspline_knots": lambda: _bspline(custom_knots=True),
}


def _random_uv(s, n=40, seed=0):
    rng = np.random.default_rng(seed)
    (u0, u1), (v0, v1) = s.u_range, s.v_range
    pad_u, pad_v = 0.02 * (u1 - u0), 0.02 * (v1 - v0)
    return rng.uniform(u0 + pad_u, u1 - pad_u, n), rng.uniform(v0 + pad_v, v1 - pad_v, n)


@pytest.mark.parametrize("name", SURFACES)
def test_derivatives_match_finite_differences(name):
    s = SURFACES[name]()
    u, v = _random_uv(s)
    d = s.derivatives(u, v)
    scale = max(np.ptp(s.u_range), np.ptp(s.v_range))
    h = 1e-4 * scale
    P = s.point
    fd = {
        "Su": (P(u + h, v) - P(u - h, v)) / (2 * h),
        "Sv": (P(u, v + h) - P(u, v - h)) / (2 * h),
    }
    h2 = 1e-3 * scale
    fd["Suu"] = (P(u + h2, v) - 2 * P(u, v) + P(u - h2, v)) / h2**2
    fd["Svv"] = (P(u, v + h2) - 2 * P(u, v) + P(u, v - h2)) / h2**2
    fd["Suv"] = (P(u + h2, v + h2) - P(u + h2, v - h2) - P(u - h2, v + h2) + P(u - h2, v - h2)) / (4 * h2**2)
    for key, approx in fd.items():
        exact = getattr(d, key)
        assert exact.shape == (len(u), 3)
        tol = 1e-6 if key in ("Su", "Sv") else 1e-4
        np.testing.assert_allclose(exact, approx, atol=tol * max(1.0, np.abs(approx).max()), err_msg=key)


@pytest.mark.parametrize("name", SURFACES)
def test_normal_unit_orthogonal_and_shapes(name):
    s = SURFACES[name]()
    u, v = _random_uv(s, 24)
    U, V = u.reshape(4, 6), v.reshape(4, 6)
    n = s.normal(U, V)
    d = s.derivatives(U, V)
    assert n.shape == (4, 6, 3) and s.point(U, V).shape == (4, 6, 3)
    np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-12)
    assert np.abs(np.sum(n * d.Su, -1)).max() < 1e-10 * np.abs(d.Su).max()
    assert np.abs(np.sum(n * d.Sv, -1)).max() < 1e-10 * np.abs(d.Sv).max()
    # scalar inputs work too
    assert s.point(float(u[0]), float(v[0])).shape == (3,)
    assert s.principal_curvatures(u[:3], v[:3])[2].shape == (3, 3)


def test_shipped_kinds_normals_point_up():
    for name, make in SURFACES.items():
        if name == "plane":
            continue
        s = make()
        u, v = _random_uv(s)
        assert np.all(s.normal(u, v)[:, 2] > 0), name


@pytest.mark.parametrize("name", SURFACES)
def test_normal_curvature_sign_and_value_against_geometry(name):
    """k(w) from the curvature tensor equals 2 h / |dS|^2, h the height of a nearby surface point
    above the tangent plane measured along n (independent of the fundamental forms code)."""
    s = SURFACES[name]()
    u, v = _random_uv(s, 12, seed=3)
    rng = np.random.default_rng(4)
    ang = rng.uniform(0, np.pi, len(u))
    d = s.derivatives(u, v)
    n = s.normal(u, v)
    w = np.cos(ang)[:, None] * d.Su / np.linalg.norm(d.Su, axis=1)[:, None] + \
        np.sin(ang)[:, None] * d.Sv / np.linalg.norm(d.Sv, axis=1)[:, None]
    w -= np.sum(w * n, 1)[:, None] * n
    w /= np.linalg.norm(w, axis=1)[:, None]
    # parameter step that moves along w: solve [Su Sv] [a b]^T = w
    J = np.stack([d.Su, d.Sv], axis=-1)  # (n, 3, 2)
    ab = np.linalg.solve(np.swapaxes(J, 1, 2) @ J, (np.swapaxes(J, 1, 2) @ w[:, :, None]))[:, :, 0]
    t = 1e-3 * max(np.ptp(s.u_range), np.ptp(s.v_range)) / np.linalg.norm(ab, axis=1)
    k_geo = []
    for sign in (1.0, -1.0):  # symmetric steps cancel the third-order term
        q = s.point(u + sign * t * ab[:, 0], v + sign * t * ab[:, 1]) - s.point(u, v)
        k_geo.append(2 * np.sum(q * n, 1) / np.sum(q * q, 1))
    k_geo = 0.5 * (k_geo[0] + k_geo[1])
    e2 = np.cross(n, w)
    k_tensor = s.curvature_tensor(u, v, w, e2)[:, 0, 0]
    np.testing.assert_allclose(k_tensor, k_geo, atol=2e-6)
    # Euler's formula with the principal curvatures
    k1, k2, d1, d2 = s.principal_curvatures(u, v)
    c = np.sum(w * d1, 1)
    np.testing.assert_allclose(k1 * c**2 + k2 * (1 - c**2), k_tensor, atol=1e-10)
    assert np.all(k1 >= k2)
    np.testing.assert_allclose(np.linalg.norm(d1, axis=1), 1, atol=1e-12)
    assert np.abs(np.sum(d1 * d2, 1)).max() < 1e-12 and np.abs(np.sum(d1 * n, 1)).max() < 1e-12
    np.testing.assert_allclose(np.cross(d1, d2), n, atol=1e-12)


def test_principal_curvatures_closed_forms():
    u, v = np.array([-3.0, 0.0, 4.0]), np.array([2.0, 0.0, -5.0])
    k1, k2, _, _ = SURFACES["plane"]().principal_curvatures(u, v)
    assert np.abs(k1).max() < 1e-15 and np.abs(k2).max() < 1e-15
    R = 50.0
    k1, k2, _, _ = SpherePatch(R, (-20, 20), (-20, 20)).principal_curvatures(u, v)
    np.testing.assert_allclose([k1, k2], -1 / R, rtol=1e-12)  # convex: bends away from n
    k1, k2, _, _ = SpherePatch(R, (-20, 20), (-20, 20), concave=True).principal_curvatures(u, v)
    np.testing.assert_allclose([k1, k2], 1 / R, rtol=1e-12)  # concave bowl: bends toward n
    axis = np.array([1.0, 0.3, 0.1])
    cyl = Cylinder(R, (-10, 10), (-20, 20), axis=axis)
    k1, k2, d1, d2 = cyl.principal_curvatures(u, v)
    np.testing.assert_allclose(k1, 0, atol=1e-15)
    np.testing.assert_allclose(k2, -1 / R, rtol=1e-12)
    np.testing.assert_allclose(np.abs(d1 @ axis / np.linalg.norm(axis)), 1, atol=1e-12)  # flat along the axis
    k1, k2, d1, _ = Cylinder(R, (-10, 10), (-20, 20), axis=axis, concave=True).principal_curvatures(u, v)
    np.testing.assert_allclose(k1, 1 / R, rtol=1e-12)
    np.testing.assert_allclose(k2, 0, atol=1e-15)
    assert np.abs(d1 @ axis).max() < 1e-12  # curved around the axis
    # curvature tensor in a rotated basis is the rotated diagonal tensor
    cyl_in = Cylinder(R, (-10, 10), (-20, 20), concave=True)
    d = cyl_in.derivatives(0.5, 1.0)
    n = cyl_in.normal(0.5, 1.0)
    a, b = d.Su / np.linalg.norm(d.Su), d.Sv / np.linalg.norm(d.Sv)
    th = 0.3
    e1, e2 = math.cos(th) * a + math.sin(th) * b, -math.sin(th) * a + math.cos(th) * b
    t = cyl_in.curvature_tensor(0.5, 1.0, e1, e2)
    rot = np.array([[math.cos(th), math.sin(th)], [-math.sin(th), math.cos(th)]])
    np.testing.assert_allclose(t, rot @ np.diag([0, 1 / R]) @ rot.T, atol=1e-14)
    assert np.allclose(np.cross(e1, e2), n)


def test_saddle_gaussian_and_principal_curvatures():
    a, b = 1 / 90, 1 / 70
    s = Saddle(a, b, (-30, 30), (-30, 30), center=(2.0, 1.0, 5.0))
    k1, k2, d1, _ = s.principal_curvatures(2.0, 1.0)  # at the centre: 2a along x (concave), -2b along y
    assert k1 == pytest.approx(2 * a, rel=1e-12) and k2 == pytest.approx(-2 * b, rel=1e-12)
    assert abs(d1[0]) == pytest.approx(1.0)
    x, y = 17.0, -11.0
    k1, k2, _, _ = s.principal_curvatures(x, y)
    gx, gy = 2 * a * (x - 2.0), -2 * b * (y - 1.0)
    K = -4 * a * b / (1 + gx**2 + gy**2) ** 2
    assert k1 * k2 == pytest.approx(K, rel=1e-10)
    assert s.gaussian_curvature(x, y) == pytest.approx(K, rel=1e-14)


# ---------------------------------------------------------------------------------------------
# tessellation


def _cell_distance(s, mesh, n=4000, seed=5):
    """Upper bound of the distance from random surface points to the mesh: distance to the two
    triangles of the grid cell that contains the point's parameters (exact per triangle)."""
    rng = np.random.default_rng(seed)
    nu, nv = mesh.metadata["grid"]
    u, v = rng.uniform(*s.u_range, n), rng.uniform(*s.v_range, n)
    i = np.clip(np.searchsorted(np.linspace(*s.u_range, nu), u) - 1, 0, nu - 2)
    j = np.clip(np.searchsorted(np.linspace(*s.v_range, nv), v) - 1, 0, nv - 2)
    t = 2 * (i * (nv - 1) + j)
    p = s.point(u, v)
    d = [np.linalg.norm(trimesh.triangles.closest_point(mesh.triangles[t + k], p) - p, axis=1)
         for k in (0, 1)]
    return np.minimum(*d)


def test_tessellate_vertices_on_surface_and_winding():
    s = SpherePatch(30.0, (-15, 15), (-10, 12), center=(1.0, 2.0, 3.0), concave=True)
    m = tessellate(s, 21, 17)
    assert m.vertices.shape == (21 * 17, 3) and m.faces.shape == (2 * 20 * 16, 3)
    np.testing.assert_allclose(np.linalg.norm(m.vertices - [1.0, 2.0, 3.0], axis=1), 30.0, rtol=1e-13)
    assert np.all(m.vertices[:, 2] < 3.0)  # the bowl is below its centre
    # face normals agree with the surface normal at the face's parameter centroid
    U, V = s.grid(21, 17)
    uv = np.stack([U.ravel(), V.ravel()], 1)[m.faces].mean(axis=1)
    n = s.normal(uv[:, 0], uv[:, 1])
    assert np.min(np.sum(m.face_normals * n, 1)) > 0.999
    cyl = Cylinder(20.0, (-5, 5), (-15, 15), axis=(1, 1, 0))
    mc = tessellate(cyl, 5, 30)
    axis = np.array([1.0, 1.0, 0.0]) / math.sqrt(2)
    radial = mc.vertices - np.outer(mc.vertices @ axis, axis)
    np.testing.assert_allclose(np.linalg.norm(radial, axis=1), 20.0, rtol=1e-13)
    tc = mc.triangles_center
    outward = _unit(tc - np.outer(tc @ axis, axis))
    assert np.all(np.sum(mc.face_normals * outward, 1) > 0.99)  # convex: normals point away from the axis


def _unit(a):
    return a / np.linalg.norm(a, axis=1)[:, None]


@pytest.mark.parametrize("name", ["sphere_in", "saddle", "sinusoid", "bspline", "cylinder"])
def test_tessellate_to_tolerance_meets_chord_bound(name):
    s = SURFACES[name]()
    tol = 2e-3
    m = tessellate_to_tolerance(s, chord_tol=tol)
    nu, nv = m.metadata["grid"]
    assert m.metadata["chord_error"] <= tol
    assert _cell_distance(s, m).max() <= tol
    # not absurdly fine: half the grid spacing would violate the tolerance by a clear margin
    coarse = tessellate(s, max(2, (nu + 1) // 2), max(2, (nv + 1) // 2))
    coarse.metadata["grid"] = (max(2, (nu + 1) // 2), max(2, (nv + 1) // 2))
    assert _cell_distance(s, coarse).max() > tol
    fn = m.face_normals
    tc = m.triangles_center
    assert np.all(fn[:, 2] > 0) and np.all(np.isfinite(tc))


def test_triangle_error_model_against_brute_force():
    """Max |4 (a l1 l2 + b l1 l3 + c l2 l3)| over the simplex, against a dense barycentric lattice."""
    from camsmooth.geometry.surfaces import _triangle_max_error

    rng = np.random.default_rng(7)
    abc = rng.normal(size=(200, 3))
    abc[:50] = np.abs(abc[:50])  # same-sign cases have interior maxima
    abc[50] = [1.0, 1.0, 1.0]
    n = 300
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    keep = i + j <= n
    l1, l2 = i[keep] / n, j[keep] / n
    l3 = 1 - l1 - l2
    a, b, c = abc[:, :1], abc[:, 1:2], abc[:, 2:]
    brute = np.abs(4 * (a * l1 * l2 + b * l1 * l3 + c * l2 * l3)).max(axis=1)
    got = _triangle_max_error(abc[:, 0], abc[:, 1], abc[:, 2])
    assert np.all(got >= brute - 1e-12)
    np.testing.assert_allclose(got, brute, rtol=2e-4)
    assert got[50] == pytest.approx(4 / 3)


def test_tessellate_to_tolerance_plane_and_cap():
    m = tessellate_to_tolerance(SURFACES["plane"]())
    assert m.metadata["grid"] == (2, 2)
    s = SURFACES["sphere"]()
    with pytest.warns(RuntimeWarning, match="capped"):
        m = tessellate_to_tolerance(s, chord_tol=1e-5, max_points=400)
    assert len(m.vertices) <= 400 and m.metadata["chord_error"] > 1e-5


# ---------------------------------------------------------------------------------------------
# definition files


@pytest.mark.parametrize("name", SURFACES)
def test_definition_round_trip_exact(name, tmp_path):
    s = SURFACES[name]()
    path = tmp_path / f"{name}.toml"
    save_definition(s, path)
    back = load_definition(path)
    assert type(back) is type(s) and back.parameters() == s.parameters()
    assert back.u_range == s.u_range and back.v_range == s.v_range
    U, V = s.grid(9, 7)
    assert np.array_equal(back.point(U, V), s.point(U, V))
    save_definition(back, tmp_path / "again.toml")
    assert (tmp_path / "again.toml").read_text() == path.read_text()


def _write(tmp_path, text, name="bad.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


@pytest.mark.parametrize("text, key", [
    ('[surface]\nkind = "sphere"\nradius = 10.0\nu_range = [0.0, 1.0]\n', "v_range"),
    ('[surface]\nkind = "sphere"\nradius = 10.0\nu_range = [0.0, 1.0]\nv_range = [0.0, 1.0]\nradious = 3\n',
     "radious"),
    ('[surface]\nkind = "spere"\n', "kind"),
    ('[surface]\nkind = "plane"\nu_range = [0.0, "a"]\nv_range = [0.0, 1.0]\n', "u_range"),
    ('[surface]\nkind = "plane"\nu_range = [1.0, 0.0]\nv_range = [0.0, 1.0]\n', "u_range"),
    ('[surface]\nkind = "cylinder"\nradius = -1.0\nu_range = [0.0, 1.0]\nv_range = [0.0, 1.0]\n', "radius"),
    ('[surface]\nkind = "cylinder"\nradius = 5.0\nu_range = [0.0, 1.0]\nv_range = [0.0, 1.0]\nconcave = 1\n',
     "concave"),
    ('[surface]\nkind = "sphere"\nradius = 10.0\nu_range = [-9.0, 9.0]\nv_range = [-9.0, 9.0]\n', "u_range"),
    ('[surface]\nkind = "saddle"\na = nan\nb = 0.1\nu_range = [0.0, 1.0]\nv_range = [0.0, 1.0]\n', "a"),
    ('[surface]\nkind = "bspline"\ncontrol = [[[0.0, 0.0, 0.0]], [[1.0, 0.0]]]\n', "control"),
    ('[surface]\nkind = "bspline"\ndegree = 2.5\ncontrol = [[[0.0, 0.0, 0.0]]]\n', "degree"),
    ('[surface]\nkind = "bspline"\ncontrol = [[[0.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0], '
     '[1.0, 1.0, 0.0]]]\n', "control"),
    ('kind = "plane"\n', "kind"),
])
def test_bad_definition_names_file_and_key(tmp_path, text, key):
    p = _write(tmp_path, text)
    with pytest.raises(InputError) as exc:
        load_definition(p)
    msg = str(exc.value)
    assert str(p) in msg and f"'{key}'" in msg, msg


def test_bad_definition_files(tmp_path):
    with pytest.raises(InputError, match="missing the \\[surface\\] table"):
        load_definition(_write(tmp_path, "# nothing\n"))
    with pytest.raises(InputError, match="not valid TOML"):
        load_definition(_write(tmp_path, "[surface\nkind = 1\n"))
    with pytest.raises(InputError, match="cannot read"):
        load_definition(tmp_path / "missing.toml")
    with pytest.raises(InputError, match="did you mean 'radius'"):
        load_definition(_write(tmp_path, '[surface]\nkind = "sphere"\nradious = 3.0\nu_range = [0.0, 1.0]\n'
                                         'v_range = [0.0, 1.0]\nradius = 5.0\n'))


# ---------------------------------------------------------------------------------------------
# meshes


@pytest.mark.parametrize("suffix", [".ply", ".stl", ".obj"])
def test_mesh_file_round_trip(tmp_path, suffix):
    s = SURFACES["saddle"]()
    m = tessellate(s, 30, 25)
    path = tmp_path / f"saddle{suffix}"
    save_mesh(m, path)
    surf = load_surface(path)
    assert surf.parametric is None and surf.source == str(path) and not surf.notes
    got = surf.mesh
    assert len(got.vertices) == len(m.vertices) and len(got.faces) == len(m.faces)
    # same triangles in the same order and winding (float32 in PLY / STL)
    np.testing.assert_allclose(got.triangles, m.triangles, atol=1e-5)
    np.testing.assert_allclose(got.face_normals, m.face_normals, atol=1e-4)


def test_load_surface_from_definition(tmp_path):
    s = SURFACES["sphere_in"]()
    save_definition(s, tmp_path / "bowl.toml")
    surf = load_surface(tmp_path / "bowl.toml", chord_tol=1e-3)
    assert isinstance(surf.parametric, SpherePatch) and surf.mesh.metadata["chord_error"] <= 1e-3
    np.testing.assert_allclose(np.linalg.norm(surf.mesh.vertices, axis=1), 45.0, rtol=1e-12)


def _grid_mesh(nu=8, nv=7):
    return tessellate(Plane((0, 7), (0, 6)), nu, nv)


def test_bad_meshes(tmp_path):
    def expect(path, pattern):
        with pytest.raises(InputError, match=pattern) as exc:
            load_surface(path)
        assert str(path) in str(exc.value)

    (tmp_path / "empty.stl").write_text("")
    expect(tmp_path / "empty.stl", "empty")
    trimesh.PointCloud(np.random.default_rng(0).random((20, 3))).export(str(tmp_path / "cloud.ply"))
    expect(tmp_path / "cloud.ply", "no faces")
    (tmp_path / "nan.obj").write_text("v 0 0 nan\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    expect(tmp_path / "nan.obj", "non-finite")
    (tmp_path / "degenerate.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 3 0 0\nv 0 1 0\nf 1 2 3\nf 2 3 4\nf 1 3 4\nf 1 2 5\n")
    expect(tmp_path / "degenerate.obj", "zero area")
    (tmp_path / "lines.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nl 1 2 3\n")
    expect(tmp_path / "lines.obj", "empty|no faces|not a triangle mesh")
    (tmp_path / "surface.dat").write_text("1 2 3\n")
    expect(tmp_path / "surface.dat", "unknown surface file type")
    expect(tmp_path / "missing.ply", "no such file")
    # non-manifold and inconsistently wound: three triangles on one edge, one of them flipped
    (tmp_path / "fan.obj").write_text("v 0 0 0\nv 1 0 0\nv 0.5 1 0\nv 0.5 -1 0\nv 0.5 0 1\n"
                                      "f 1 2 3\nf 1 4 2\nf 1 2 5\n")
    expect(tmp_path / "fan.obj", "non-manifold")
    # half the area flipped: no safe majority
    m = _grid_mesh(2, 3)
    faces = m.faces.copy()
    faces[:2] = faces[:2, ::-1]
    trimesh.Trimesh(m.vertices, faces, process=False).export(str(tmp_path / "split.obj"))
    expect(tmp_path / "split.obj", "no clear majority")


def test_inconsistent_winding_minority_is_repaired(tmp_path):
    m = _grid_mesh()
    faces = m.faces.copy()
    faces[[0, 10, 11]] = faces[[0, 10, 11], ::-1]  # face 0 too: trimesh orients from it
    trimesh.Trimesh(m.vertices, faces, process=False).export(str(tmp_path / "flipped.ply"))
    with pytest.warns(RuntimeWarning, match="3 of 84 faces flipped"):
        surf = load_surface(tmp_path / "flipped.ply")
    assert surf.mesh.is_winding_consistent and np.all(surf.mesh.face_normals[:, 2] > 0.99)
    assert surf.notes and "flipped" in surf.notes[0]


def test_few_degenerate_faces_removed(tmp_path):
    m = _grid_mesh()
    verts = np.vstack([m.vertices, [[0, 0, 0], [1, 0, 0], [2, 0, 0]]])
    faces = np.vstack([m.faces, [[len(m.vertices), len(m.vertices) + 1, len(m.vertices) + 2]]])
    trimesh.Trimesh(verts, faces, process=False).export(str(tmp_path / "one_bad.obj"))
    mesh, notes = load_mesh(tmp_path / "one_bad.obj")
    assert len(mesh.faces) == len(m.faces) and "zero-area" in notes[0]


def test_surface_normals_at():
    s = SpherePatch(20.0, (-12, 12), (-12, 12))
    m = tessellate_to_tolerance(s, chord_tol=1e-3)
    rng = np.random.default_rng(2)
    u, v = rng.uniform(-10, 10, 50), rng.uniform(-10, 10, 50)
    p = s.point(u, v) + 0.3 * s.normal(u, v)  # slightly off the surface, on the tool side
    n = surface_normals_at(m, p)
    assert n.shape == (50, 3)
    assert np.min(np.sum(n * s.normal(u, v), 1)) > 0.99


def test_constructor_rejections():
    with pytest.raises(ValueError, match="vertical"):
        Cylinder(10, (0, 1), (0, 1), axis=(0, 0, 1))
    with pytest.raises(ValueError, match="parallel"):
        Plane((0, 1), (0, 1), u_dir=(1, 0, 0), v_dir=(2, 0, 0))
    with pytest.raises(ValueError, match="knots_u"):
        BSplineSurface(np.zeros((4, 4, 3)), knots_u=[0, 0, 0, 1, 1, 1, 1, 1])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        BSplineSurface(np.zeros((4, 4, 3)))  # minimal bicubic patch is fine
