"""Where the part is: placing a workpiece surface in the program's frame, and checking that the
program and the part are in the same frame and units.

Frames and units
----------------
mm and deg on the command line, radians inside. The part file (STEP, mesh, definition) gives the
part in its own frame P; the program's points are in its frame W (a CLSF's points are mapped to
the absolute frame through their MSYS by camsmooth.io.apt). A placement is the rigid 4x4 T with
p_W = T p_P: ``--part-frame x,y,z[,rx,ry,rz]`` is T = Trans(x, y, z) Rz(rz) Ry(ry) Rx(rx)
(rotations about the fixed axes X, then Y, then Z), ``--part-frame msys`` the CLSF's MSYS
transform (MCS -> absolute), for a part exported in the machine coordinate system (NX's
"export relative to WCS" with the WCS on the MCS).

The frame check
---------------
The distance of the program's points (at most ``CHECK_POINTS`` of its cutting points) from the
part mesh: a point farther than ``reach`` (the cutter's radius R + r plus 1 mm for a CL program's
tool tips; 1 mm for CC points) is off the part. When more than half are off (``FAR_SHARE``), the
likely cause is looked for among: a translation (a work offset / MSYS not applied: the offset that
best aligns them, from the difference of the bounding boxes' centres, lower and upper corners,
refined by a trimmed point-to-surface fit of the translation alone), the CLSF's MSYS transform,
and a unit factor (25.4: inch vs mm; 1000: m vs mm; the program's points scaled about the
origin, only where the scaled program is larger than a few reaches and not larger than the
part). The cause that puts the most points back on the part is named in one message with the
option or fix that applies it. Distances come from a k-d tree of the mesh's vertices and points
sampled on it every reach / 4 (exact closest-point queries from 300 mm away visit every triangle).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh

__all__ = ["rigid_transform", "place", "FrameCheck", "check_frame", "CHECK_POINTS", "FAR_SHARE"]

CHECK_POINTS = 2000     # program points whose distance to the part is measured (a seeded subsample above this)
FAR_SHARE = 0.5         # more than this share of the points off the part: a frame / unit mismatch
_UNIT_FACTORS = ((25.4, "inch vs mm"), (1 / 25.4, "inch vs mm"), (1000.0, "m vs mm"), (1e-3, "m vs mm"))


def rigid_transform(translation: Any = (0.0, 0.0, 0.0), rotation_deg: Any = (0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 T with T p = Rz(rz) Ry(ry) Rx(rx) p + t (deg about the fixed X, Y, Z axes in that order;
    t in mm)."""
    rx, ry, rz = np.radians(np.asarray(rotation_deg, dtype=float))
    cx, sx, cy, sy, cz, sz = math.cos(rx), math.sin(rx), math.cos(ry), math.sin(ry), math.cos(rz), math.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    T = np.eye(4)
    T[:3, :3] = Rz @ Ry @ Rx
    T[:3, 3] = np.asarray(translation, dtype=float)
    return T


def place(surface: Any, T: np.ndarray) -> None:
    """Move a ``surfaces.Surface`` in place by the rigid 4x4 ``T`` (part frame -> program frame):
    its mesh and, for a CAD part, its exact part's ``transform``. A parametric definition cannot
    follow (ValueError): place its definition file instead."""
    T = np.asarray(T, dtype=float)
    R = T[:3, :3]
    if T.shape != (4, 4) or not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0:
        raise ValueError("a placement must be a rigid 4x4 transform (rotation and translation)")
    if getattr(surface, "parametric", None) is not None:
        raise ValueError("a surface definition (.toml) cannot be placed: move it in the definition file")
    surface.mesh.apply_transform(T)
    brep = getattr(surface, "brep", None)
    if brep is not None:
        brep.transform = T @ brep.transform


@dataclass(frozen=True)
class FrameCheck:
    """Result of ``check_frame``. near: share of the checked points within ``reach`` mm of the part;
    median: their median distance (mm); points: how many were checked; message: None when the
    frames agree, else the one-line diagnosis; offset: the translation (mm, part -> program) that
    best aligns them when that is the cause; cause: 'offset', 'msys', 'units' or 'unknown'."""

    near: float
    median: float
    points: int
    reach: float
    message: str | None = None
    offset: tuple[float, float, float] | None = None
    cause: str | None = None


class _Near:
    """Distances to a mesh for the check: a k-d tree over its vertices and points sampled on its
    faces every ``spacing`` mm (the distances are upper bounds, at most ``spacing`` too large; exact
    closest-point queries from far away are slow: trimesh visits every triangle in the box)."""

    def __init__(self, mesh: trimesh.Trimesh, spacing: float) -> None:
        from scipy.spatial import cKDTree

        count = int(min(300_000, max(20_000, mesh.area / spacing ** 2)))
        samples, face = trimesh.sample.sample_surface(mesh, count, seed=11)
        self.points = np.concatenate([np.asarray(mesh.vertices), samples])
        self.normals = np.concatenate([np.asarray(mesh.vertex_normals), np.asarray(mesh.face_normals)[face]])
        self.tree = cKDTree(self.points)

    def distance(self, q: np.ndarray) -> np.ndarray:
        return self.tree.query(q)[0]

    def closest(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest sample, its distance and the surface normal there."""
        d, i = self.tree.query(q)
        return self.points[i], d, self.normals[i]


def _fit_translation(near: _Near, points: np.ndarray, t: np.ndarray, band: float, rounds: int = 8) -> np.ndarray:
    """Refine t (p_program = p_part + t) so the points (minus t) come within ``band`` mm of the part:
    each round moves by the median of the residuals beyond the band of the nearest half of the
    points (trimmed: the far half are air moves); then point-to-plane Gauss-Newton steps on the
    nearest half (which a curved part constrains in every direction). The tool's tip lies up to
    its radius off the surface, so t is determined to about that radius."""
    for fine in (False, True):
        for _ in range(rounds):
            q = points - t
            c, d, n = near.closest(q)
            keep = d <= (float(np.median(d)) if fine else max(float(np.median(d)), band))
            if not keep.any():
                break
            if fine:  # point-to-plane Gauss-Newton: min sum (n.(q - s - c))^2 over the step s
                nk, e = n[keep], np.einsum("ij,ij->i", n[keep], (q - c)[keep])
                step = -np.linalg.solve(nk.T @ nk + 1e-9 * np.eye(3), nk.T @ e)
            else:
                r, dk = (c - q)[keep], d[keep][:, None]
                step = np.median(np.where(dk > band, r * (1 - band / np.maximum(dk, 1e-300)), 0.0), axis=0)
            t = t - step
            if np.linalg.norm(step) < 1e-5:
                break
    return t


def check_frame(points: Any, mesh: trimesh.Trimesh, reach: float, msys: np.ndarray | None = None,
                what: str = "program", part: str = "part") -> FrameCheck:
    """Check that the program's points (N, 3, mm) lie on the part mesh (module docstring).

    ``reach`` mm: how far a point may be from the part and still be on it. ``msys``: the CLSF's
    MSYS transform (4x4) when it has one. ``what`` and ``part`` name the two files in the message.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if len(pts) > CHECK_POINTS:
        pts = pts[np.random.default_rng(7).choice(len(pts), CHECK_POINTS, replace=False)]
    if len(pts) == 0:
        return FrameCheck(near=1.0, median=0.0, points=0, reach=reach)
    prox = _Near(mesh, spacing=max(reach, 1e-3) / 4)
    d = prox.distance(pts)
    near = float(np.mean(d <= reach))
    med = float(np.median(d))
    if near >= 1.0 - FAR_SHARE:
        return FrameCheck(near=near, median=med, points=len(pts), reach=reach)

    V = np.asarray(mesh.vertices)
    candidates: list[tuple[float, str, Any]] = []
    # a translation: start from the bounding boxes' centres and lower corners, refine on the surface
    starts = {tuple(np.round((pts.min(0) + pts.max(0)) / 2 - (V.min(0) + V.max(0)) / 2, 9)),
              tuple(np.round(pts.min(0) - V.min(0), 9)), tuple(np.round(pts.max(0) - V.max(0), 9))}
    best_t, best_key = None, (-1.0, 0.0)
    for s in sorted(starts):
        t = _fit_translation(prox, pts, np.asarray(s), band=max(reach - 1.0, 0.5 * reach))
        dt = prox.distance(pts - t)
        key = (float(np.mean(dt <= reach)), -float(np.mean(np.minimum(dt, reach))))  # on ties: the closer fit
        if key > best_key:
            best_t, best_key = t, key
    candidates.append((best_key[0], "offset", best_t))
    if msys is not None and not np.allclose(msys, np.eye(4)):
        inv = np.linalg.inv(msys)
        share = float(np.mean(prox.distance(pts @ inv[:3, :3].T + inv[:3, 3]) <= reach))
        candidates.append((share, "msys", msys))
    size, part_size = float(np.linalg.norm(np.ptp(pts, axis=0))), float(np.linalg.norm(np.ptp(V, axis=0)))
    for f, name in _UNIT_FACTORS:
        if not 4 * reach <= f * size <= 1.5 * part_size + 2 * reach:
            continue  # scaled, the program would collapse to a dot (on the part anywhere) or outgrow it
        share = float(np.mean(prox.distance(pts * f) <= reach))
        candidates.append((share, "units", (f, name)))
    # the file's own MSYS, then a unit factor (one number) before a translation (three numbers, which
    # fit a program scaled down to a dot anywhere on the part) when they explain nearly as much
    top = max(c[0] for c in candidates)
    rank = {"msys": 0, "units": 1, "offset": 2}
    share, cause, arg = min((c for c in candidates if c[0] >= top - 0.02), key=lambda c: (rank[c[1]], -c[0]))
    head = (f"the {what} and the {part} are not in the same frame or units: {1 - near:.0%} of the {len(pts)} "
            f"points checked lie more than {reach:.3g} mm from the part (median distance {med:.4g} mm)")
    offset = None
    if share < 1.0 - FAR_SHARE:
        cause = "unknown"
        tail = ("no translation, MSYS or unit factor (25.4, 1000) brings them together: check that the part file is "
                "the programmed part and place it with --part-frame x,y,z,rx,ry,rz (mm, deg)")
    elif cause == "offset":
        offset = tuple(float(x) + 0.0 for x in np.round(arg, 3))  # + 0.0: no '-0'
        tail = (f"likely cause: a work offset (MSYS / G54) not applied: moving the part by ({offset[0]:.3f}, "
                f"{offset[1]:.3f}, {offset[2]:.3f}) mm puts {share:.0%} of the points on it (to within the "
                f"cutter's radius; the CAM system's work offset is the exact figure): give --part-frame "
                f"{offset[0]:g},{offset[1]:g},{offset[2]:g}")
    elif cause == "msys":
        tail = (f"likely cause: the part is in the CLSF's machine coordinate system (MSYS): placing it with the MSYS "
                f"puts {share:.0%} of the points on it: give --part-frame msys")
    else:
        f, name = arg
        ratio = f"{f:g}" if f >= 1 else f"1/{1 / f:g}"
        tail = (f"likely cause: {name}: the {what}'s coordinates times {ratio} lie on the part ({share:.0%} of the "
                f"points): the program's or the part's length unit is not the one its numbers are in (a CLSF in "
                f"inch needs UNITS/INCHES or inch feeds; a STEP file declares its unit)")
    return FrameCheck(near=near, median=med, points=len(pts), reach=reach, message=f"{head}; {tail}",
                      offset=offset, cause=cause)
