"""Benchmark of camsmooth.geometry.clearance: clearance poses/s, kernel compile time, and
axial_drop points/s.

Case 1, wavy sheet: a 200 x 200 grid (40 000 vertices, 79 202 triangles) of
z = 4 sin(x/9) cos(y/13) + 0.02 x over 100 x 100 mm.  Poses: 6000 random CC points on the sheet
with the exact surface normal, feed along +x, lead 10 deg, tilt 0, toroidal cutter R = 3, r = 2 mm,
shank 30 mm, holder radius 12 mm x 40 mm; CL from cc_to_cl, so the tool touches at CC and gouges
where the sheet is concave.  Also the same tools lifted 0.5 mm along the normal.

Case 2, the shipped saddle sample: surfaces/saddle.ply (20 732 vertices, 40 890 triangles) and the
6000 CC points of surfaces/saddle_path.csv in path order; cutter R = 4, r = 1 mm (default shank,
no holder), lead 11 deg, tilt 0 in the local frame of camsmooth.smoothing.orientation, CL from
cc_to_cl.

Compile time: two fresh interpreters share an empty NUMBA_CACHE_DIR; the first compiles the
kernels (cold cache), the second loads them (warm).

Run:  python3 benchmarks/bench_interference.py [--repeat 5]
Figures are single-threaded (the kernels are sequential); on a shared machine they are noisy,
so the best of --repeat runs is printed with its CPU time.

Before the numba kernels (commit ef4cdd0 of branch ``clearance``, which ran both): the former
vectorised numpy clearance measured 4,715 poses/s (CPU) on case 1 touching, 3,037 lifted, and
3,033 on case 2, against 78,549 / 77,295 / 83,527 for the kernels in the same run (16.7x,
25.4x, 27.5x); the largest |delta| difference between the two was 7.6e-15 mm (case 1) and
4.9e-15 mm (case 2), with the same capped poses.
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
import trimesh

from camsmooth.geometry.clearance import MeshIndex, axial_drop, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.surfaces import load_mesh
from camsmooth.io.ccpath import read_cc_csv
from camsmooth.smoothing.orientation import axis_from_lead_tilt, local_frames

ROOT = Path(__file__).resolve().parent.parent


def surface(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    z = 4.0 * np.sin(x / 9.0) * np.cos(y / 13.0) + 0.02 * x
    zx = 4.0 / 9.0 * np.cos(x / 9.0) * np.cos(y / 13.0) + 0.02
    zy = -4.0 / 13.0 * np.sin(x / 9.0) * np.sin(y / 13.0)
    n = np.stack([-zx, -zy, np.ones_like(z)], axis=-1)
    return z, n / np.linalg.norm(n, axis=-1, keepdims=True)


def grid_mesh(n: int = 200, size: float = 100.0) -> trimesh.Trimesh:
    xs = np.linspace(0.0, size, n)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    Z, _ = surface(X, Y)
    V = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    F = np.concatenate([np.stack([a, a + n, a + n + 1], 1), np.stack([a, a + n + 1, a + 1], 1)])
    return trimesh.Trimesh(V, F, process=False)


def poses(n_poses: int, lead_deg: float = 10.0, seed: int = 0):
    rng = np.random.default_rng(seed)
    x = rng.uniform(10.0, 90.0, n_poses)
    y = rng.uniform(10.0, 90.0, n_poses)
    z, nrm = surface(x, y)
    cc = np.stack([x, y, z], axis=1)
    f = np.array([1.0, 0.0, 0.0]) - nrm[:, :1] * nrm      # feed = x projected on the tangent plane
    f /= np.linalg.norm(f, axis=1, keepdims=True)
    th = np.radians(lead_deg)
    T = np.sin(th) * f + np.cos(th) * nrm                 # lead about Y_L, tilt 0
    return cc, nrm, T


def saddle_case():
    """The shipped saddle sample: (mesh, cutter, CL tips, axes, normals)."""
    path = read_cc_csv(ROOT / "surfaces" / "saddle_path.csv")
    mesh, _ = load_mesh(ROOT / "surfaces" / "saddle.ply")
    frames = local_frames(path.normals, path.feed_dirs)
    T = axis_from_lead_tilt(np.full(len(path), math.radians(11.0)), np.zeros(len(path)), frames)
    cutter = ToroidalCutter(R=4.0, r=1.0)
    return mesh, cutter, cc_to_cl(cutter, path.points, path.normals, T), T, path.normals


def best_of(fn, repeat: int) -> tuple[float, float]:
    """Best (wall, CPU) time of ``repeat`` runs, s."""
    best = (math.inf, math.inf)
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        best = min(best, (time.perf_counter() - t0, time.process_time() - c0))
    return best


COMPILE_SCRIPT = textwrap.dedent("""
    import time
    t0 = time.perf_counter()
    import numpy as np, trimesh
    from camsmooth.geometry.clearance import MeshIndex, clearance
    from camsmooth.geometry.cutter import ToroidalCutter
    t1 = time.perf_counter()
    index = MeshIndex(trimesh.creation.icosphere(subdivisions=1))
    t2 = time.perf_counter()
    clearance(index, ToroidalCutter(R=1.0, r=0.5, holder_radius=3.0, holder_length=2.0),
              np.array([[0.0, 0.0, 1.2]]), np.array([0.0, 0.0, 1.0]))
    t3 = time.perf_counter()
    print(f"{t1 - t0:.3f} {t2 - t1:.3f} {t3 - t2:.3f}")
""")


def compile_times() -> None:
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, NUMBA_CACHE_DIR=cache, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get(
            "PYTHONPATH", ""))
        for label in ("cold cache (compiles)", "warm cache (loads)"):
            out = subprocess.run([sys.executable, "-c", COMPILE_SCRIPT], env=env, capture_output=True, text=True,
                                 check=True).stdout.split()
            imp, build, first = (float(v) for v in out)
            print(f"  {label}: import {imp:.2f} s, first MeshIndex {build:.2f} s, first clearance call "
                  f"{first:.2f} s")


def clearance_case(name: str, index: MeshIndex, cutter: ToroidalCutter, tips: np.ndarray, axes: np.ndarray,
                   repeat: int) -> None:
    res = clearance(index, cutter, tips, axes, margin=1.0)
    wall, cpu = best_of(lambda: clearance(index, cutter, tips, axes, margin=1.0), repeat)
    n = len(tips)
    print(f"  {name}: {n} poses in {wall:.3f} s = {n / wall:,.0f} poses/s (CPU {cpu:.3f} s = {n / cpu:,.0f} "
          f"poses/s; gouging {int(np.sum(res.delta < -1e-9))}, min delta {res.delta.min():.4f} mm, "
          f"capped {int(res.capped.sum())})")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    print("kernel compile (numba, cache=True):")
    compile_times()

    mesh = grid_mesh()
    cutter = ToroidalCutter(R=3.0, r=2.0, shank_length=30.0, holder_radius=12.0, holder_length=40.0)
    t0 = time.perf_counter()
    index = MeshIndex(mesh)
    print(f"wavy sheet: {len(index.vertices)} vertices, {len(index.faces)} faces; MeshIndex built in "
          f"{time.perf_counter() - t0:.3f} s")
    cc, nrm, T = poses(6000)
    cl = cc_to_cl(cutter, cc, nrm, T)
    clearance_case("clearance, touching", index, cutter, cl, T, args.repeat)
    clearance_case("clearance, lifted 0.5 mm along n", index, cutter, cl + 0.5 * nrm, T, args.repeat)

    smesh, scutter, scl, sT, _ = saddle_case()
    t0 = time.perf_counter()
    sindex = MeshIndex(smesh)
    print(f"saddle sample: {len(sindex.vertices)} vertices, {len(sindex.faces)} faces; MeshIndex built in "
          f"{time.perf_counter() - t0:.3f} s")
    clearance_case("clearance, path CL points", sindex, scutter, scl, sT, args.repeat)

    pts = np.stack([cc[:, 0], cc[:, 1], np.full(len(cc), 50.0)], axis=1)
    print("axial_drop on the wavy sheet:")
    for name, ax in [("vertical axis", np.array([0.0, 0.0, 1.0])),
                     ("common tilted axis", np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])),
                     ("per-point axes", T)]:
        drop = axial_drop(index, cutter, pts, ax)
        wall, cpu = best_of(lambda ax=ax: axial_drop(index, cutter, pts, ax), args.repeat)
        print(f"  {name}: {len(pts)} points in {wall:.3f} s = {len(pts) / wall:,.0f} points/s "
              f"(hit {int(drop.hit.sum())}; CPU {cpu:.3f} s)")


if __name__ == "__main__":
    main()
