"""Regenerate the sample surfaces in this folder: ``python surfaces/make_samples.py``.

For each sample NAME it writes NAME.toml (definition), NAME.ply (binary PLY mesh, chord error
<= 2e-4 mm) and NAME_path.csv (zig-zag CC path, about 30 rows of 200 points, feed 2000 mm/min),
checks them (definition round trip, chord error measured independently, file size < 4 MB,
normals up, curvature limits) and prints a summary. See README.md in this folder.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import trimesh
from scipy.interpolate import BSpline

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # run from a source checkout without installing

from camsmooth.paths import read_cc_csv, write_cc_csv, zigzag_extents, zigzag_path  # noqa: E402
from camsmooth.surfaces import (  # noqa: E402
    BSplineSurface,
    ParametricSurface,
    Saddle,
    clamped_knots,
    load_definition,
    load_surface,
    save_definition,
    save_mesh,
    tessellate_to_tolerance,
)

CHORD_TOL = 2e-4  # mm, required of the PLY mesh
# PLY stores float32 vertices (rounding <= 4e-6 mm at 100 mm): tessellate a little tighter
TESSELLATION_TOL = 1.9e-4
MAX_FILE_BYTES = 4_000_000
ROWS, POINTS, FEED = 30, 200, 2000.0  # rows per path, points per row, mm/min
MAX_MESH_POINTS = 100_000  # ~3.8 MB of binary PLY


def greville(knots: np.ndarray, degree: int) -> np.ndarray:
    """Greville abscissae: control points placed there make x(u) = u exactly (linear precision)."""
    n = len(knots) - degree - 1
    return np.array([knots[i + 1:i + degree + 1].mean() for i in range(n)])


def fit_height_field(f, x_range, y_range, n_ctrl, degree=3, n_fit=241) -> BSplineSurface:
    """Bicubic B-spline z = f(x, y) over u = x, v = y: control x, y at the Greville abscissae, control
    z by separable least squares on an n_fit x n_fit grid (z ~ Bu Z Bv^T)."""
    tu = clamped_knots(n_ctrl[0], degree, *x_range)
    tv = clamped_knots(n_ctrl[1], degree, *y_range)
    xs, ys = np.linspace(*x_range, n_fit), np.linspace(*y_range, n_fit)
    Bu = BSpline.design_matrix(xs, tu, degree).toarray()
    Bv = BSpline.design_matrix(ys, tv, degree).toarray()
    F = f(xs[:, None], ys[None, :])
    Z = np.linalg.pinv(Bu) @ F @ np.linalg.pinv(Bv).T
    gx, gy = np.meshgrid(greville(tu, degree), greville(tv, degree), indexing="ij")
    control = np.stack([gx, gy, Z], axis=-1)
    # round to 1e-9 mm so the definition file stays short; the geometry changes by < 1e-8 mm
    return BSplineSurface(np.round(control, 9), degree=(degree, degree), u_range=x_range, v_range=y_range)


def blade() -> BSplineSurface:
    """Mould/blade-like free-form: cambered across x (concave for x < 40, convex beyond), camber
    growing along y, a twist and a gentle spanwise bow; 80 x 60 mm."""
    def f(x, y):
        xc, yc = x - 40.0, y - 30.0
        amp = 5.0 * (1.0 + 0.12 * yc / 30.0)
        return 8.0 + amp * np.sin(math.pi * xc / 50.0) + xc * yc / 600.0 + yc**2 / (2 * 400.0)
    return fit_height_field(f, (0.0, 80.0), (0.0, 60.0), (14, 10))


def saddle() -> Saddle:
    """z = 10 + (x^2 - y^2) / 90 on 60 x 60 mm: radius of curvature 45 mm at the centre."""
    return Saddle(a=1 / 90, b=1 / 90, u_range=(-30.0, 30.0), v_range=(-30.0, 30.0), center=(0.0, 0.0, 10.0))


def bump() -> BSplineSurface:
    """Steep bowl across x whose radius grows from 36 to 40 mm along y and whose floor rises
    gently: the normal swings by about +-45..52 degrees along every row (rows along x)."""
    def f(x, y):
        radius = 36.0 + 4.0 * y / 60.0
        return 2.0 + 0.05 * y + radius - np.sqrt(radius**2 - (x - 28.5) ** 2)
    return fit_height_field(f, (0.0, 57.0), (0.0, 60.0), (16, 8))


SAMPLES = {"blade": blade, "saddle": saddle, "bump": bump}


def curvature_report(surface: ParametricSurface, n: int = 401) -> tuple[float, float]:
    """(min concave radius, min convex radius) in mm on an n x n grid; inf if none (radius > 10 m)."""
    U, V = surface.grid(n, n)
    k1, k2, _, _ = surface.principal_curvatures(U, V)
    kmax, kmin = float(k1.max()), float(k2.min())
    return (1 / kmax if kmax > 1e-4 else math.inf), (-1 / kmin if kmin < -1e-4 else math.inf)


def independent_chord_error(surface: ParametricSurface, mesh: trimesh.Trimesh, grid: tuple[int, int],
                            n: int = 50_000) -> float:
    """Largest distance from random surface points to the two triangles of their grid cell (an
    upper bound of the distance to the mesh), exact per triangle. ``mesh`` keeps the grid's
    vertex and face order (vertex (i, j) = i*nv + j, two faces per cell)."""
    rng = np.random.default_rng(1)
    nu, nv = grid
    u = rng.uniform(*surface.u_range, n)
    v = rng.uniform(*surface.v_range, n)
    i = np.clip(np.searchsorted(np.linspace(*surface.u_range, nu), u) - 1, 0, nu - 2)
    j = np.clip(np.searchsorted(np.linspace(*surface.v_range, nv), v) - 1, 0, nv - 2)
    t = 2 * (i * (nv - 1) + j)
    p = surface.point(u, v)
    d = [np.linalg.norm(trimesh.triangles.closest_point(mesh.triangles[t + k], p) - p, axis=1)
         for k in (0, 1)]
    return float(np.minimum(*d).max())


def make(name: str, surface: ParametricSurface) -> dict:
    toml, ply, csv = HERE / f"{name}.toml", HERE / f"{name}.ply", HERE / f"{name}_path.csv"
    save_definition(surface, toml)
    back = load_definition(toml)
    U, V = surface.grid(37, 41)
    assert back.parameters() == surface.parameters() and np.array_equal(back.point(U, V), surface.point(U, V))

    mesh = tessellate_to_tolerance(surface, chord_tol=TESSELLATION_TOL, max_points=MAX_MESH_POINTS)
    save_mesh(mesh, ply)
    assert ply.stat().st_size < MAX_FILE_BYTES, (name, ply.stat().st_size)
    loaded = load_surface(ply).mesh
    assert np.array_equal(loaded.faces, mesh.faces) and np.all(loaded.face_normals[:, 2] > 0)
    chord = independent_chord_error(surface, loaded, mesh.metadata["grid"])
    assert chord <= CHORD_TOL, (name, chord)

    length, width = zigzag_extents(surface, "u")
    path = zigzag_path(surface, stepover=width / (ROWS - 1), spacing=length / (POINTS - 1), along="u",
                       feed=FEED)
    write_cc_csv(csv, path)
    path = read_cc_csv(csv)
    assert np.all(path.normals[:, 2] > 0)

    counts = [s.stop - s.start for s in path.row_slices()]
    tilt = np.degrees(np.arctan2(path.normals[:, 0], path.normals[:, 2]))  # in the x-z plane (rows along x)
    swing = max(float(np.degrees(np.arccos(np.clip(path.normals[s] @ path.normals[s].T, -1, 1))).max())
                for s in path.row_slices())
    concave, convex = curvature_report(surface)
    return dict(name=name, rows=len(counts), pts=(min(counts), max(counts)), n=len(path),
                verts=len(mesh.vertices), faces=len(mesh.faces), grid=mesh.metadata["grid"],
                chord_est=mesh.metadata["chord_error"], chord=chord,
                sizes={p.name: p.stat().st_size for p in (toml, ply, csv)}, concave=concave, convex=convex,
                tilt=(float(tilt.min()), float(tilt.max())),
                max_tilt=float(np.degrees(np.arccos(path.normals[:, 2].min()))), swing=swing,
                z=(float(mesh.vertices[:, 2].min()), float(mesh.vertices[:, 2].max())),
                xy=np.ptp(mesh.vertices[:, :2], axis=0).tolist())


def main() -> None:
    for name, build in SAMPLES.items():
        r = make(name, build())
        print(f"{r['name']}: {r['xy'][0]:.1f} x {r['xy'][1]:.1f} mm, z {r['z'][0]:.2f}..{r['z'][1]:.2f} mm")
        print(f"  path: {r['rows']} rows x {r['pts'][0]}..{r['pts'][1]} points ({r['n']} points)")
        print(f"  mesh: grid {r['grid'][0]} x {r['grid'][1]}, {r['verts']} vertices, {r['faces']} faces, "
              f"chord error {r['chord_est']:.3g} mm (estimate), {r['chord']:.3g} mm (measured on the PLY)")
        print("  files: " + ", ".join(f"{k} {v / 1e6:.2f} MB" for k, v in r["sizes"].items()))
        print(f"  min concave radius {r['concave']:.1f} mm, min convex radius {r['convex']:.1f} mm")
        print(f"  normal tilt in x-z along rows {r['tilt'][0]:.1f}..{r['tilt'][1]:.1f} deg, "
              f"max from vertical {r['max_tilt']:.1f} deg, max swing within a row {r['swing']:.1f} deg")


if __name__ == "__main__":
    main()
