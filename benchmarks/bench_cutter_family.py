"""The toroid family on the shipped wave sample (issue 30, item 2): figures, printed.

1. Axial drop of a flat end, a ball end and a bull nose (D10; r = 0, 5, 1 mm) on surfaces/wave.stl
   (71 022 faces) at random points: camsmooth.geometry.clearance.axial_drop against OpenCAMLib's
   BatchDropCutter (CylCutter, BallCutter, BullCutter) on the same triangles: the largest
   difference of the tip's z and both run times.
2. A flat end D10 in an NX CLSF (TLDATA/MILL,10.0000,0.0000,...) at a constant lead (11 and 16
   deg), no tilt, on rows of the wave sample, smoothed with `camsmooth smooth` (lead 2:30, tilt
   -10:10, tolerance 0.005 mm): the CAM program's own clearance (at 11 deg its heel gouges the
   troughs: they are concave along the feed down to a radius of 20 mm, and a flat end's heel
   clears a trough of radius rho only from sin(lead) = R / rho, 14.5 deg here; those poses do not
   touch within the tolerance and are left out of the rows, as for any cutter), the smoothed
   program's clearance on the mesh and on the exact surface (sampled here), and its lead where the
   troughs are deepest, beside the circular-trough floor asin(R / rho) with rho the local radius
   along the feed (conservative on the wave: its curvature falls off behind the contact, and the
   accessibility map finds the true floor by exact clearance).

Usage: python benchmarks/bench_cutter_family.py [--rows N] [--points N]
(needs `pip install opencamlib` for part 1).
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
import time
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np
import trimesh

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from camsmooth.cli.main import main  # noqa: E402
from camsmooth.geometry.clearance import MeshIndex, axial_drop  # noqa: E402
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl  # noqa: E402
from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames  # noqa: E402
from camsmooth.io.ccpath import read_cc_csv  # noqa: E402
from camsmooth.io.result_csv import read_result_csv  # noqa: E402


def drop_against_opencamlib(mesh: trimesh.Trimesh, n_points: int) -> None:
    import opencamlib as ocl

    surf = ocl.STLSurf()
    for tri in np.asarray(mesh.triangles, float):
        surf.addTriangle(ocl.Triangle(*[ocl.Point(*map(float, v)) for v in tri]))
    idx = MeshIndex(mesh)
    rng = np.random.default_rng(30)
    xy = rng.uniform(mesh.bounds[0, :2] + 5, mesh.bounds[1, :2] - 5, size=(n_points, 2))
    print(f"1. axial drop on surfaces/wave.stl ({len(mesh.faces)} faces), {n_points} random points, axis +z")
    for cut, tool in ((ToroidalCutter(R=5.0, r=0.0), ocl.CylCutter(10.0, 50.0)),
                      (ToroidalCutter(R=0.0, r=5.0), ocl.BallCutter(10.0, 50.0)),
                      (ToroidalCutter(R=4.0, r=1.0), ocl.BullCutter(10.0, 1.0, 50.0))):
        t0 = time.perf_counter()
        bdc = ocl.BatchDropCutter()
        bdc.setSTL(surf)
        bdc.setCutter(tool)
        for x, y in xy:
            bdc.appendPoint(ocl.CLPoint(float(x), float(y), -1e3))
        bdc.run()
        z_ocl = np.array([p.z for p in bdc.getCLPoints()])
        t1 = time.perf_counter()
        drop = axial_drop(idx, cut, np.column_stack([xy, np.full(len(xy), 100.0)]), np.array([0.0, 0.0, 1.0]))
        t2 = time.perf_counter()
        diff = np.abs(drop.cl[:, 2] - z_ocl)
        print(f"   {cut.kind:5s} D{cut.diameter:g} r{cut.r:g}: max |z - z_OpenCAMLib| = {diff.max():.2e} mm, "
              f"OpenCAMLib {t1 - t0:.2f} s, camsmooth {t2 - t1:.2f} s")


def nx_flat_end_clsf(tips: np.ndarray, axes: np.ndarray, rows: np.ndarray) -> str:
    lines = ["TOOL PATH/VARIABLE_CONTOUR,TOOL,FLAT_D10", "TLDATA/MILL,10.0000,0.0000,50.0000,0.0000,0.0000",
             "LOAD/TOOL,1", "FEDRAT/MMPM,2000.0000"]
    for r in np.unique(rows):
        k = np.flatnonzero(rows == r)
        p, a = tips[k], axes[k]
        up = p[0] + 10.0 * a[0]
        lines += ["RAPID", f"GOTO/{up[0]:.4f},{up[1]:.4f},{up[2]:.4f},{a[0, 0]:.7f},{a[0, 1]:.7f},{a[0, 2]:.7f}"]
        lines += [f"GOTO/{x[0]:.4f},{x[1]:.4f},{x[2]:.4f},{t[0]:.7f},{t[1]:.7f},{t[2]:.7f}"
                  for x, t in zip(p, a, strict=True)]
        away = p[-1] + 10.0 * a[-1]
        lines += ["RAPID", f"GOTO/{away[0]:.4f},{away[1]:.4f},{away[2]:.4f}"]
    return "\n".join(lines + ["END-OF-PATH"]) + "\n"


def _wave_z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """surfaces/wave.toml: z = 10 + A sin(kx x) sin(ky y) on [0, 80] x [20, 60] (NaN outside)."""
    A, kx, ky = 2.5, 0.14151318259413484, 0.039269908169872414
    on = (x >= 0.0) & (x <= 80.0) & (y >= 20.0) & (y <= 60.0)
    return np.where(on, 10.0 + A * np.sin(kx * x) * np.sin(ky * y), np.nan)


def _flat_sd(cut: ToroidalCutter, tip: np.ndarray, T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Signed distance (mm) of points to the flat end's solid cylinder (radius R, tip to tip + L T)."""
    q = p - tip
    a = q @ T
    rho = np.linalg.norm(q - a[..., None] * T, axis=-1)
    dr, dz = rho - cut.R, np.maximum(-a, a - float(cut.shank_length))
    return np.where((dr > 0) | (dz > 0), np.hypot(np.maximum(dr, 0), np.maximum(dz, 0)), np.maximum(dr, dz))


def exact_surface_clearance(cut: ToroidalCutter, tip: np.ndarray, T: np.ndarray) -> float:
    """Least signed distance of the wave's exact surface (not the mesh) from the tool: a 0.1 mm
    grid about the tool, then a 1 um grid about its best point."""
    def sd(x, y):
        z = _wave_z(x, y)
        v = _flat_sd(cut, tip, T, np.stack([x, y, np.nan_to_num(z, nan=-1e3)], -1))
        return np.where(np.isnan(z), np.inf, v)

    reach = cut.radius + float(cut.shank_length) * np.linalg.norm(T[:2]) + 1.0
    g = np.arange(-reach, reach, 0.1)
    X, Y = np.meshgrid(tip[0] + g, tip[1] + g, indexing="ij")
    v = sd(X, Y)
    i = np.unravel_index(np.argmin(v), v.shape)
    f = np.arange(-0.11, 0.11, 0.001)
    X2, Y2 = np.meshgrid(X[i] + f, Y[i] + f, indexing="ij")
    return float(min(v.min(), sd(X2, Y2).min()))


def flat_end_on_the_wave(n_rows: int, lead_deg: float) -> None:
    path = read_cc_csv(ROOT / "surfaces" / "wave_path.csv")
    ids = np.unique(path.rows)
    k = np.isin(path.rows, ids[:n_rows])  # the first rows, at y = 20 mm: the deepest waves
    pts, nrm, rows = path.points[k], path.normals[k], path.rows[k]
    fr = local_frames(nrm, path.feed_dirs_or_estimate()[k])
    T = axis_from_lead_tilt(np.full(len(pts), np.radians(lead_deg)), np.zeros(len(pts)), fr)
    cut = ToroidalCutter(R=5.0, r=0.0)
    tips = cc_to_cl(cut, pts, nrm, T)
    with tempfile.TemporaryDirectory() as tmp:
        cls = Path(tmp) / "flat.cls"
        cls.write_text(nx_flat_end_clsf(tips, T, rows))
        out = Path(tmp) / "out.csv"
        buf = io.StringIO()
        t0 = time.perf_counter()
        with redirect_stdout(buf):
            rc = main(["smooth", str(cls), "--surface", str(ROOT / "surfaces" / "wave.stl"), "--lead", "2:30",
                       "--tilt", "-10:10", "--tolerance", "0.005", "-o", str(out), "--workers", "1"])
        dt = time.perf_counter() - t0
        res = read_result_csv(out) if rc == 0 else None
    print(f"2. NX CLSF, TLDATA/MILL,10,0 (flat end D10), lead {lead_deg:g} deg, {n_rows} rows of the wave "
          f"({len(pts)} points); smooth exit {rc} in {dt:.1f} s:")
    for line in buf.getvalue().splitlines():
        if line.split()[:1] and line.split()[0] in ("method", "cam", "none", "spline", "nlp"):
            print("   " + line)
    if res is None:
        return
    # the troughs: z = 10 + A sin(kx x) sin(ky y) (surfaces/wave.toml) is concave along the feed (x)
    # where sin(kx x) < 0, with radius rho = 1 / (A kx^2 |sin(kx x) sin(ky y)|) (small slopes)
    A, kx, ky = 2.5, 0.14151318259413484, 0.039269908169872414
    kappa = A * kx * kx * np.maximum(-np.sin(kx * res["x"]) * np.sin(ky * res["y"]), 0.0)
    floor = np.degrees(np.arcsin(np.minimum(5.0 * kappa, 1.0)))
    inner = (res["x"] >= 10.0) & (res["x"] <= 70.0)  # the heel (2 R behind the contact) on the part
    trough = inner & (floor > 0.9 * floor[inner].max())
    print(f"   nlp: {len(res['x'])} points, min delta {res['delta'].min():.4g} mm (tolerance 0.005); lead "
          f"{res['lead'].min():.2f}..{res['lead'].max():.2f} deg; at the {int(trough.sum())} trough points (heel "
          f"floor asin(R / rho) >= {0.9 * floor[inner].max():.2f} deg, rho the radius along the feed, smallest "
          f"{1 / kappa.max():.1f} mm, x in [10, 70] so that the heel is on the part) lead "
          f"{res['lead'][trough].min():.2f}..{res['lead'][trough].max():.2f} deg")
    cl = np.column_stack([res["clx"], res["cly"], res["clz"]])
    ax = np.column_stack([res["i"], res["j"], res["k"]])
    ax /= np.linalg.norm(ax, axis=1, keepdims=True)
    ex = np.array([exact_surface_clearance(cut, cl[j], ax[j]) for j in range(len(cl))])
    print(f"   nlp poses against the wave's exact surface (sampled, independent of the mesh): least clearance "
          f"{ex.min():.4g} mm (the STL's chord error is 6e-4 mm); at the trough points {ex[trough].min():.4g} mm")


def run() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rows", type=int, default=4)
    ap.add_argument("--points", type=int, default=500)
    ap.add_argument("--lead", type=float, nargs="+", default=[11.0, 16.0], help="the CAM programs' leads (deg)")
    a = ap.parse_args()
    mesh = trimesh.load(ROOT / "surfaces" / "wave.stl", force="mesh")
    try:
        if a.points > 0:
            drop_against_opencamlib(mesh, a.points)
    except ImportError:
        print("1. skipped: OpenCAMLib is not installed (pip install opencamlib)")
    for lead in a.lead:
        flat_end_on_the_wave(a.rows, lead)


if __name__ == "__main__":
    run()
