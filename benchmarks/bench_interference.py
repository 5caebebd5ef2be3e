"""Benchmark of camsmooth.geometry.clearance: clearance poses/s and axial_drop points/s.

Surface: a 200 x 200 grid (40 000 vertices, 79 202 triangles) of the wavy sheet
z = 4 sin(x/9) cos(y/13) + 0.02 x over 100 x 100 mm.  Poses: 6000 CC points on the sheet with
the exact surface normal, feed along +x, lead 10 deg, tilt 0, toroidal cutter R = 3, r = 2 mm with
a holder; CL from cc_to_cl, so the tool touches at CC and gouges where the sheet is concave.

Run:  python3 benchmarks/bench_interference.py
"""

from __future__ import annotations

import math
import time

import numpy as np
import trimesh

from camsmooth.geometry.clearance import MeshIndex, axial_drop, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl


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


def best_of(fn, repeat: int = 3) -> float:
    """Best wall time of ``repeat`` runs (s); the CPU time of that run goes to CPU_TIME."""
    best = (math.inf, math.inf)
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        best = min(best, (time.perf_counter() - t0, time.process_time() - c0))
    CPU_TIME[0] = best[1]
    return best[0]


CPU_TIME = [0.0]


def main() -> None:
    mesh = grid_mesh()
    cutter = ToroidalCutter(R=3.0, r=2.0, shank_length=30.0, holder_radius=12.0, holder_length=40.0)
    t0 = time.perf_counter()
    index = MeshIndex(mesh)
    t_index = time.perf_counter() - t0
    print(f"mesh: {len(index.vertices)} vertices, {len(index.faces)} faces; "
          f"MeshIndex built in {t_index:.3f} s")

    cc, nrm, T = poses(6000)
    cl = cc_to_cl(cutter, cc, nrm, T)
    res = clearance(index, cutter, cl, T, margin=1.0)
    t = best_of(lambda: clearance(index, cutter, cl, T, margin=1.0))
    print(f"clearance: {len(cl)} poses in {t:.3f} s = {len(cl) / t:,.0f} poses/s "
          f"(gouging {int(np.sum(res.delta < -1e-9))}, min delta {res.delta.min():.4f} mm, "
          f"capped {int(res.capped.sum())}; CPU {CPU_TIME[0]:.3f} s)")

    lifted = cl + 0.5 * nrm
    t = best_of(lambda: clearance(index, cutter, lifted, T, margin=1.0))
    print(f"clearance (tools lifted 0.5 mm along n): {len(cl) / t:,.0f} poses/s (CPU {CPU_TIME[0]:.3f} s)")

    pts = np.stack([cc[:, 0], cc[:, 1], np.full(len(cc), 50.0)], axis=1)
    for name, ax in [("vertical axis", np.array([0.0, 0.0, 1.0])),
                     ("common tilted axis", np.array([0.3, -0.2, 1.0]) / np.linalg.norm([0.3, -0.2, 1.0])),
                     ("per-point axes", T)]:
        drop = axial_drop(index, cutter, pts, ax)
        t = best_of(lambda ax=ax: axial_drop(index, cutter, pts, ax))
        print(f"axial_drop ({name}): {len(pts)} points in {t:.3f} s = {len(pts) / t:,.0f} points/s "
              f"(hit {int(drop.hit.sum())}; CPU {CPU_TIME[0]:.3f} s)")


if __name__ == "__main__":
    main()
