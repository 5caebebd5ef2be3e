"""Local frames at CC points and lead/tilt <-> tool axis (METHODS section 1).

At a CC point with unit normal n (material -> tool) and feed direction f: X_L = f (projected onto
the tangent plane), Z_L = n, Y_L = Z_L x X_L (right-handed). Lead theta rotates the tool axis
about Y_L, tilt phi about Z_L:

    T_L = (sin theta cos phi, sin theta sin phi, cos theta),  T_W = [X_L Y_L Z_L] T_L.

Angles in radians; vectors in the workpiece frame.
"""

from __future__ import annotations

import numpy as np

from camsmooth.errors import InputError


def local_frames(normals: np.ndarray, feed_dirs: np.ndarray) -> np.ndarray:
    """(N, 3, 3) local frames whose columns are X_L, Y_L, Z_L (workpiece frame).

    The feed direction is projected onto the tangent plane of n, so it need only be roughly
    tangent. Raises InputError where it is parallel to n.
    """
    n = np.asarray(normals, dtype=float)
    f = np.asarray(feed_dirs, dtype=float)
    x = f - np.sum(f * n, axis=1, keepdims=True) * n
    norm = np.linalg.norm(x, axis=1, keepdims=True)
    bad = np.flatnonzero(norm[:, 0] < 1e-9)
    if bad.size:
        raise InputError(f"feed direction parallel to the normal at point {bad[0]}")
    x /= norm
    y = np.cross(n, x)
    return np.stack([x, y, n], axis=2)


def axis_from_lead_tilt(lead: np.ndarray, tilt: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Unit tool axes T (N, 3), workpiece frame, from lead and tilt (rad) in the local frames."""
    lead, tilt = np.broadcast_arrays(np.asarray(lead, float), np.asarray(tilt, float))
    tl = np.stack([np.sin(lead) * np.cos(tilt), np.sin(lead) * np.sin(tilt), np.cos(lead)], axis=-1)
    return np.einsum("nij,nj->ni", frames, tl)


def lead_tilt_from_axis(axes: np.ndarray, frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(lead, tilt) in rad of unit tool axes (N, 3) in the local frames; tilt is 0 where the
    lead is 0 (the axis is along the normal and tilt is undefined)."""
    tl = np.einsum("nji,nj->ni", frames, np.asarray(axes, float))
    rho = np.hypot(tl[:, 0], tl[:, 1])
    lead = np.arctan2(rho, tl[:, 2])
    tilt = np.where(rho > 1e-12, np.arctan2(tl[:, 1], tl[:, 0]), 0.0)
    return lead, tilt
