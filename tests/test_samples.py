"""The shipped sample surfaces (surfaces/NAME.toml, NAME.ply, NAME_path.csv; see surfaces/README.md).

Fast checks of the files as shipped: they load, are small enough, the paths have about 30 rows of
200 points at 2000 mm/min, the CC points lie on the mesh and on the exact surface, the path normals
agree with the mesh and the exact normals, and the B-spline samples really are G1 (C1 with a
curvature jump) across their double knots and C2 elsewhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial import cKDTree

from camsmooth.geometry.surfaces import BSplineSurface, Saddle, load_definition, load_surface
from camsmooth.io.ccpath import read_cc_csv

HERE = Path(__file__).resolve().parent.parent / "surfaces"
SAMPLES = ("blade", "saddle", "mould")
MAX_BYTES = 4_000_000


@pytest.fixture(scope="module", params=SAMPLES)
def sample(request):
    name = request.param
    return (name, load_definition(HERE / f"{name}.toml"), load_surface(HERE / f"{name}.ply").mesh,
            read_cc_csv(HERE / f"{name}_path.csv"))


def closest_on_mesh(mesh: trimesh.Trimesh, points: np.ndarray, k: int = 32) -> tuple[np.ndarray, np.ndarray]:
    """(distance, face) of the closest mesh point to each point: exact per-triangle distances to
    every face around the k nearest vertices (not trimesh.proximity, whose search is unreliable
    at the 1e-4 mm level)."""
    _, nb = cKDTree(mesh.vertices).query(points, k=k)
    vf = mesh.vertex_faces[nb].reshape(len(points), -1)
    owner, slot = np.nonzero(vf >= 0)
    face = vf[owner, slot]
    c = trimesh.triangles.closest_point(mesh.triangles[face], points[owner])
    d = np.linalg.norm(c - points[owner], axis=1)
    order = np.lexsort((d, owner))  # per owner, the nearest candidate first
    first = order[np.r_[True, owner[order][1:] != owner[order][:-1]]]
    assert np.array_equal(owner[first], np.arange(len(points)))
    return d[first], face[first]


def test_the_shipped_set():
    machines = ("dome_machine", "nutating_machine", "trunnion_ab_machine")  # docs/machines.md
    assert sorted(p.stem for p in HERE.glob("*.toml")) == sorted(SAMPLES + ("wave", "dome") + machines)
    for f in ("dome.toml", "dome.stl", "dome_path.csv", "dome_machine.toml", "dome.cls"):
        assert 0 < (HERE / f).stat().st_size < MAX_BYTES, f
    for name in SAMPLES:
        for f in (f"{name}.toml", f"{name}.ply", f"{name}_path.csv"):
            assert 0 < (HERE / f).stat().st_size < MAX_BYTES, f
    for f in ("wave.toml", "wave.stl", "wave_path.csv"):
        assert 0 < (HERE / f).stat().st_size < MAX_BYTES, f
    assert not list(HERE.glob("bump*"))


def test_wave_is_an_unaligned_cad_like_mesh_with_concave_troughs():
    """The wave sample's STL is a uniform 0.3 mm grid like a CAD export, not aligned with the
    path: the CC points lie within its chord error of the mesh, on both sides; the troughs along
    the rows are concave with radius down to 20 mm (closed form: 1 / (A kx^2))."""
    s = load_definition(HERE / "wave.toml")
    mesh = load_surface(HERE / "wave.stl").mesh
    path = read_cc_csv(HERE / "wave_path.csv")
    d, face = closest_on_mesh(mesh, path.points)
    side = np.sum((path.points - mesh.triangles_center[face]) * mesh.face_normals[face], axis=1)
    assert d.max() < 1e-3 and (side > 1e-5).any() and (side < -1e-5).any()
    assert abs(1.0 / (s.amplitude * s.kx ** 2) - 20.0) < 0.05
    counts = np.array([sl.stop - sl.start for sl in path.row_slices()])
    assert len(counts) == 30 and counts.min() >= 190 and np.allclose(path.feed, 2000.0)


def test_path_shape_and_feed(sample):
    name, _, _, path = sample
    counts = np.array([s.stop - s.start for s in path.row_slices()])
    assert len(counts) == 30
    assert counts.min() >= 190 and counts.max() <= 200
    assert np.array_equal(np.unique(path.rows), np.arange(30))
    assert np.all(path.feed == 2000.0)
    assert np.all(path.normals[:, 2] > 0)  # normals up, out of the material
    assert np.allclose(np.linalg.norm(path.feed_dirs, axis=1), 1, atol=1e-12)
    assert np.abs(np.sum(path.feed_dirs * path.normals, axis=1)).max() < 1e-9
    # zig-zag: consecutive rows run in opposite directions along x
    start_x = np.array([path.points[s.start, 0] - path.points[s.stop - 1, 0] for s in path.row_slices()])
    assert np.all(np.sign(start_x[:-1]) == -np.sign(start_x[1:]))


def test_path_points_lie_on_mesh_and_normals_agree(sample):
    name, _, mesh, path = sample
    assert np.all(mesh.face_normals[:, 2] > 0)
    d, face = closest_on_mesh(mesh, path.points)
    assert d.max() < 1e-3, (name, d.max())
    assert d.max() < 2e-4  # the chord tolerance of the meshes
    cos = np.sum(path.normals * mesh.face_normals[face], axis=1)
    assert np.degrees(np.arccos(np.clip(cos.min(), -1, 1))) < 1.0


def test_path_points_lie_on_the_definition(sample):
    name, surface, _, path = sample
    if isinstance(surface, Saddle):
        x, y = path.points[:, 0], path.points[:, 1]
        z = surface.center[2] + surface.a * (x - surface.center[0]) ** 2 - surface.b * (y - surface.center[1]) ** 2
        assert np.abs(path.points[:, 2] - z).max() < 1e-9
        return
    # the B-spline samples have y(u, v) = v and x increasing with u: find u per point by bisection
    assert isinstance(surface, BSplineSurface)
    v = path.points[:, 1]
    lo, hi = np.full(len(v), surface.u_range[0]), np.full(len(v), surface.u_range[1])
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        right = surface.point(mid, v)[:, 0] < path.points[:, 0]
        lo, hi = np.where(right, mid, lo), np.where(right, hi, mid)
    u = 0.5 * (lo + hi)
    assert np.abs(surface.point(u, v) - path.points).max() < 1e-9
    assert np.abs(surface.normal(u, v) - path.normals).max() < 1e-9


def interior_knots(surface: BSplineSurface) -> tuple[np.ndarray, np.ndarray]:
    t, k = surface.knots_u, surface.degree[0]
    return np.unique(t[k + 1:-k - 1], return_counts=True)


@pytest.mark.parametrize("name", ["blade", "mould"])
def test_g1_blends_at_double_knots(name):
    surface = load_definition(HERE / f"{name}.toml")
    assert isinstance(surface, BSplineSurface) and surface.degree == (3, 3)
    knots, mult = interior_knots(surface)
    joins = knots[mult == 2]
    assert len(joins) == 4 and set(mult) == {1, 2}
    v = np.linspace(*surface.v_range, 61)
    eps = 1e-7
    for uk in joins:
        left, right = np.full_like(v, uk - eps), np.full_like(v, uk + eps)
        dl, dr = surface.derivatives(left, v), surface.derivatives(right, v)
        # C1: first derivatives continuous, hence the normal too
        assert np.abs(dl.Su - dr.Su).max() < 1e-5 and np.abs(dl.Sv - dr.Sv).max() < 1e-5
        assert np.degrees(np.arccos(np.clip(np.sum(surface.normal(left, v) * surface.normal(right, v), -1), -1, 1))
                          ).max() < 1e-3
        # ... but not C2: on every row the curvature jumps by at least 1/60 1/mm (about 1/R)
        kl, kr = surface.principal_curvatures(left, v), surface.principal_curvatures(right, v)
        jump = np.maximum(np.abs(kl[0] - kr[0]), np.abs(kl[1] - kr[1]))
        assert jump.min() > 1 / 60, (name, uk, jump.min())
    # elsewhere (single knots, knot-free spans) the curvature is continuous
    others = np.r_[knots[mult == 1], 0.5 * (knots[:-1] + knots[1:])]
    for uk in others:
        kl = surface.principal_curvatures(np.full_like(v, uk - eps), v)
        kr = surface.principal_curvatures(np.full_like(v, uk + eps), v)
        assert max(np.abs(kl[0] - kr[0]).max(), np.abs(kl[1] - kr[1]).max()) < 1e-5


def row_swings(path) -> np.ndarray:
    """Largest angle (deg) between two normals of the same row, per row."""
    return np.array([np.degrees(np.arccos(np.clip(path.normals[s] @ path.normals[s].T, -1, 1))).max()
                     for s in path.row_slices()])


@pytest.mark.parametrize("name, min_concave, swing", [
    ("blade", 35.0, (25.0, 40.0)),
    ("saddle", 100.0, (20.0, 30.0)),
    ("mould", 30.0, (40.0, 50.0)),
])
def test_design_figures(name, min_concave, swing):
    surface = load_definition(HERE / f"{name}.toml")
    U, V = surface.grid(401, 61)
    k1, _, _, _ = surface.principal_curvatures(U, V)
    assert 1 / k1.max() >= min_concave
    s = row_swings(read_cc_csv(HERE / f"{name}_path.csv"))
    assert swing[0] <= s.min() and s.max() <= swing[1], (name, s.min(), s.max())


def test_dome_sample_passes_the_pole_of_its_machines_c_axis():
    """The dome ships an A/C trunnion machine whose C axis runs through the dome's top: the CAM-style
    orientation (lead 11 deg) of the middle rows passes within 1 deg of the pole, where the exact
    inverse turns C more than five times faster than its limit at the programmed feed."""
    from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.smoothing.pole import find_passages

    m = load_machine(HERE / "dome_machine.toml")
    assert m.kind == "AC-table" and m.rotary == ("A", "C") and not np.isfinite(m.limits["C"].max)
    path = read_cc_csv(HERE / "dome_path.csv")
    T = axis_from_lead_tilt(np.full(len(path), np.radians(11.0)), np.zeros(len(path)),
                            local_frames(path.normals, path.feed_dirs))
    rows = path.rows
    seg = np.r_[0.0, np.linalg.norm(np.diff(path.points, axis=0), axis=1)]
    seg[np.r_[True, rows[1:] != rows[:-1]]] = 0.0
    t = np.zeros(len(rows))
    for s in path.row_slices():
        t[s] = np.cumsum(seg[s]) / (2000.0 / 60.0)
    ang = np.zeros((len(rows), 2))
    for s in path.row_slices():
        r = m.solve_row(T[s])
        ang[s] = r.rotary.values
    passages = find_passages(m, T, rows, t, ang)
    assert min(q.closest_deg for q in passages) < 1.0
    assert max(q.outer_peak_speed for q in passages) > 5 * np.degrees(m.limits["C"].vmax)
