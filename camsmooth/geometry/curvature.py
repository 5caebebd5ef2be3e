"""Curvature of a meshed surface at given points, from least-squares quadrics.

At each point, in its local frame (a, b tangent along X_L, Y_L; h along the normal n), the
quadric h = c + d a + e b + (L a^2 + 2 M a b + N b^2) / 2 is fitted to the k nearest mesh
vertices; [[L, M], [M, N]] is the second fundamental form in the basis (X_L, Y_L). Sign:
positive where the surface bends toward n (concave as seen from the tool), the convention of
camsmooth.geometry.surfaces. Exact for quadric patches. Anisotropic or one-sided neighbourhoods
(fine spacing along one parameter, surface boundaries) make the nearest vertices collinear: the
neighbourhood doubles per point until the fit is well conditioned (smallest eigenvalue of the
scaled normal matrix above 1e-4 of the largest).

The fit runs in a compiled kernel (numba), a point at a time over its neighbours: a million
points in a few seconds, where the batched numpy version took ~25 s (measured on the blade
sample at a 0.06 mm step-over).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy.spatial import cKDTree

__all__ = ["surface_curvature_tensors"]

COND = 1e-4


@njit(cache=True)
def _fit(vertices: np.ndarray, nb: np.ndarray, points: np.ndarray, frames: np.ndarray
         ) -> tuple[np.ndarray, np.ndarray]:  # pragma: no cover - compiled
    n, k = nb.shape
    out = np.full((n, 3), np.nan)
    ok = np.zeros(n, np.bool_)
    phi = np.empty((k, 6))
    h = np.empty(k)
    a = np.empty(k)
    b = np.empty(k)
    for i in range(n):
        p0, p1, p2 = points[i, 0], points[i, 1], points[i, 2]
        ss = 0.0
        for j in range(k):
            v = nb[i, j]
            d0, d1, d2 = vertices[v, 0] - p0, vertices[v, 1] - p1, vertices[v, 2] - p2
            a[j] = d0 * frames[i, 0, 0] + d1 * frames[i, 1, 0] + d2 * frames[i, 2, 0]
            b[j] = d0 * frames[i, 0, 1] + d1 * frames[i, 1, 1] + d2 * frames[i, 2, 1]
            h[j] = d0 * frames[i, 0, 2] + d1 * frames[i, 1, 2] + d2 * frames[i, 2, 2]
            ss += a[j] * a[j] + b[j] * b[j]
        scale = np.sqrt(ss / k) + 1e-12
        for j in range(k):
            x, y = a[j] / scale, b[j] / scale
            phi[j, 0] = 1.0
            phi[j, 1] = x
            phi[j, 2] = y
            phi[j, 3] = 0.5 * x * x
            phi[j, 4] = x * y
            phi[j, 5] = 0.5 * y * y
        ata = phi.T @ phi / k
        ev = np.linalg.eigvalsh(ata)
        ok[i] = ev[0] > COND * ev[5]
        rhs = phi.T @ h / k
        coef = np.linalg.solve(ata + 1e-12 * np.eye(6), rhs)
        s2 = scale * scale
        out[i, 0], out[i, 1], out[i, 2] = coef[3] / s2, coef[4] / s2, coef[5] / s2
    return out, ok


def surface_curvature_tensors(vertices: np.ndarray, points: np.ndarray, frames: np.ndarray, k: int = 32,
                              tree: cKDTree | None = None) -> np.ndarray:
    """Curvature tensors (N, 2, 2) (1/mm) of the surface at points (N, 3) mm, in the basis
    (X_L, Y_L) of their local frames (N, 3, 3) (module docstring)."""
    vertices = np.ascontiguousarray(vertices, dtype=float)
    tree = tree if tree is not None else cKDTree(vertices)
    points = np.ascontiguousarray(points, dtype=float)
    frames = np.ascontiguousarray(frames, dtype=float)
    K = np.full((len(points), 2, 2), np.nan)
    todo = np.arange(len(points))
    while todo.size:
        kk = min(k, len(vertices))
        _, nb = tree.query(points[todo], k=kk, workers=-1)
        lmn, ok = _fit(vertices, np.ascontiguousarray(nb.reshape(len(todo), kk), dtype=np.int64), points[todo],
                       frames[todo])
        done = ok | (kk >= len(vertices)) | (kk >= 4096)
        idx = todo[done]
        K[idx, 0, 0], K[idx, 0, 1], K[idx, 1, 0], K[idx, 1, 1] = (lmn[done, 0], lmn[done, 1], lmn[done, 1],
                                                                    lmn[done, 2])
        todo = todo[~done]
        k *= 2
    return K
