"""Cutter-contact (CC) paths: the CCPath type and simple path generators.

Frames and units: workpiece frame W, mm; feed in mm/min (as in the file). The CC normal n points
from the material toward the tool (CONVENTIONS.md); the feed direction f is the unit tangent of
the path in the direction of travel (X_L of the local frame, METHODS.md section 1).

The pinned CSV format of a CC path is read and written by ``camsmooth.io.ccpath``
(``read_cc_csv``, ``write_cc_csv``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from camsmooth.errors import InputError
from camsmooth.geometry.surfaces import ParametricSurface, surface_normals_at

__all__ = [
    "CCPath",
    "estimate_feed_dirs",
    "check_normals_against_mesh",
    "check_contact_with_mesh",
    "CONTACT_TOL",
    "zigzag_path",
    "zigzag_extents",
    "raster_path_on_mesh",
    "UNIT_TOL",
    "REPEAT_TOL",
    "TANGENT_TOL",
    "MIN_ROW_POINTS",
]

UNIT_TOL = 1e-3  # | |n| - 1 | above this is an error, below it n is normalised
REPEAT_TOL = 1e-9  # mm: consecutive points of a row closer than this are a repeat
TANGENT_TOL = 1e-2  # |f . n| above this: feed direction not tangent (0.57 degrees)
MIN_ROW_POINTS = 3



def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


@dataclass
class CCPath:
    """A cutter-contact path in the workpiece frame.

    points (N, 3) mm; normals (N, 3) unit, out of the material; rows (N,) int row ids, each row a
    contiguous run, in machining order; feed_dirs (N, 3) unit tangents along travel or None;
    feed (N,) mm/min or None; source: the file it came from, if any.
    """

    points: np.ndarray
    normals: np.ndarray
    rows: np.ndarray
    feed_dirs: np.ndarray | None = None
    feed: np.ndarray | None = None
    source: str | None = None

    def __post_init__(self) -> None:
        self.points = np.asarray(self.points, dtype=float).reshape(-1, 3)
        n = len(self.points)
        self.normals = np.asarray(self.normals, dtype=float).reshape(-1, 3)
        self.rows = np.asarray(self.rows).astype(np.int64).reshape(-1)
        if self.feed_dirs is not None:
            self.feed_dirs = np.asarray(self.feed_dirs, dtype=float).reshape(-1, 3)
        if self.feed is not None:
            self.feed = np.asarray(self.feed, dtype=float).reshape(-1)
        for name in ("normals", "rows", "feed_dirs", "feed"):
            a = getattr(self, name)
            if a is not None and len(a) != n:
                raise ValueError(f"CCPath.{name} has {len(a)} entries for {n} points")

    def __len__(self) -> int:
        return len(self.points)

    def row_slices(self) -> list[slice]:
        """Index ranges of the rows in order. A row id that reappears after another row is an
        InputError (naming the 1-based data row where it reappears)."""
        starts, again = _row_runs(self.rows)
        if again is not None:
            raise InputError(f"row id {self.rows[again]} reappears after other rows (rows must be "
                             "contiguous runs)", file=self.source, row=again + 1, column="row")
        ends = np.r_[starts[1:], len(self.rows)]
        return [slice(int(s), int(e)) for s, e in zip(starts, ends, strict=True)]

    def feed_dirs_or_estimate(self) -> np.ndarray:
        """The feed directions, estimated by ``estimate_feed_dirs`` when the path has none."""
        if self.feed_dirs is not None:
            return self.feed_dirs
        return estimate_feed_dirs(self.points, self.normals, self.rows)


def _row_runs(rows: np.ndarray) -> tuple[np.ndarray, int | None]:
    """Start indices of the runs of equal row id, and the index where an id first reappears
    after another run (None if every id forms one contiguous run)."""
    r = np.asarray(rows).reshape(-1)
    if len(r) == 0:
        return np.zeros(0, dtype=np.int64), None
    starts = np.flatnonzero(np.r_[True, r[1:] != r[:-1]])
    ids = r[starts]
    if len(np.unique(ids)) == len(ids):
        return starts, None
    seen: set[int] = set()
    for k, rid in enumerate(ids.tolist()):  # loop over rows, only on the error path
        if rid in seen:
            return starts, int(starts[k])
        seen.add(rid)
    return starts, None  # pragma: no cover


def estimate_feed_dirs(points: Any, normals: Any, rows: Any) -> np.ndarray:
    """Unit feed directions (N, 3) from the point sequence within each row.

    Central difference p[i+1] - p[i-1] inside a row, one-sided at its ends, projected onto the
    tangent plane of n (t - (t.n) n) and normalised. Rows are runs of equal id in ``rows``; a row
    of a single point has no direction (InputError).
    """
    p = np.asarray(points, dtype=float).reshape(-1, 3)
    n = np.asarray(normals, dtype=float).reshape(-1, 3)
    r = np.asarray(rows).reshape(-1)
    if len(p) == 0:
        return np.zeros((0, 3))
    same = r[1:] == r[:-1]
    has_next = np.r_[same, False]
    has_prev = np.r_[False, same]
    nxt = np.where(has_next[:, None], np.roll(p, -1, axis=0), p)
    prv = np.where(has_prev[:, None], np.roll(p, 1, axis=0), p)
    t = nxt - prv
    t = t - _dot(t, n)[:, None] * n
    norm = np.linalg.norm(t, axis=1)
    bad = ~(norm > 0)
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise InputError(f"cannot estimate a feed direction at point {k + 1} (row id {r[k]}): the row has a "
                         "single point or the step is along the normal", row=k + 1)
    return t / norm[:, None]


def check_normals_against_mesh(path: CCPath, mesh: trimesh.Trimesh, mesh_file: str | None = None) -> None:
    """InputError naming the first CC point whose normal points into the material.

    A normal points into the material when n . m < 0, m the mesh face normal at the closest point
    (``surface_normals_at``; the mesh's face normals must point out of the material); points whose
    normal agrees with the nearest vertex's normal (n . m_v >= 0.2) are cleared without it. The row
    named is the 1-based index of the point in the path (the data row of its CSV file). When most
    normals disagree, the likelier cause is a mesh wound the other way round (its face normals
    pointing into the material), and the message says so, naming ``mesh_file`` when given.
    """
    # screen with the nearest vertex's normal (a KD-tree query); only points it cannot clear
    # get the exact face normal at the closest point
    _, near = mesh.kdtree.query(path.points)
    dots = _dot(path.normals, np.asarray(mesh.vertex_normals)[near])
    unsure = np.flatnonzero(dots < 0.2)
    if len(unsure):
        dots[unsure] = _dot(path.normals[unsure], surface_normals_at(mesh, path.points[unsure]))
    bad = dots < 0
    if not np.any(bad):
        return
    k = int(np.flatnonzero(bad)[0])
    nbad, n = int(np.sum(bad)), len(bad)
    if 2 * nbad > n:
        mesh_name = f"the mesh {mesh_file}" if mesh_file else "the mesh"
        csv_name = f" in {path.source}" if path.source else ""
        raise InputError(f"{nbad} of {n} CC normals{csv_name} point against the face normals of {mesh_name}: the "
                         "mesh's face winding is probably flipped (its normals pointing into the material); "
                         "re-export it with outward normals (or, if the mesh is right, the CSV's normals are "
                         "reversed)", file=mesh_file)
    raise InputError(f"normal points into the material (n . mesh normal = {float(dots[k]):.3g} at row id "
                     f"{int(path.rows[k])}, point {path.points[k].round(6).tolist()}); "
                     f"{nbad} of {n} points affected", file=path.source, row=k + 1, column="nx,ny,nz")


#: Largest distance (mm) from a CC point to the surface mesh that still counts as contact: CC
#: points lie on the surface, the mesh approximates it within its chord tolerance.
CONTACT_TOL = 1.0


def check_contact_with_mesh(path: CCPath, mesh: trimesh.Trimesh, max_distance: float = CONTACT_TOL) -> None:
    """InputError when a CC point lies farther than ``max_distance`` mm from the surface mesh.

    CC points are contact points on the surface; one far from the mesh means the path and the
    mesh are in different frames or units, or belong to different parts, and every clearance
    computed would be meaningless. The message names the file (``path.source``), the first
    offending data rows (1-based point index, as in ``check_normals_against_mesh``) with their
    distances (mm) and how many points are affected.

    Cost: a KD-tree query over the mesh vertices for every point (a vertex within the tolerance
    proves contact), and the exact distance (``trimesh.proximity.closest_point``) only for the
    few points the vertex distance cannot decide: the surface lies within the longest edge of
    some vertex, so a vertex distance above ``max_distance`` + longest edge proves no contact.
    """
    tol = float(max_distance)
    if not (math.isfinite(tol) and tol >= 0):
        raise InputError(f"max_distance must be a finite number >= 0 mm, got {max_distance!r}")
    pts = np.asarray(path.points, dtype=float).reshape(-1, 3)
    if len(pts) == 0:
        return
    faces = np.asarray(mesh.faces)
    used = np.unique(faces)
    V = np.asarray(mesh.vertices, dtype=float)
    tree = mesh.kdtree if len(used) == len(V) else cKDTree(V[used])
    d_vert, _ = tree.query(pts)
    unsure = np.flatnonzero(d_vert > tol)
    if len(unsure) == 0:
        return
    longest = float(np.max(mesh.edges_unique_length))
    dist = d_vert.copy()  # an upper bound of the distance; exact where it decides
    exact = unsure[d_vert[unsure] - longest <= tol]
    if len(exact):
        dist[exact] = trimesh.proximity.closest_point(mesh, pts[exact])[1]
    far = np.flatnonzero(dist > tol)
    if len(far) == 0:
        return
    first = far[:5]
    d_first = trimesh.proximity.closest_point(mesh, pts[first])[1]
    listed = ", ".join(f"{int(i) + 1} (row id {int(path.rows[i])}, {float(d):.4g} mm)"
                       for i, d in zip(first, d_first, strict=True))
    whole = "the whole path" if len(far) == len(pts) else f"{len(far)} of {len(pts)} CC points"
    raise InputError(f"no contact within {tol:g} mm of the surface mesh: {whole} lie farther away; first at data "
                     f"rows {listed}. Are the path and the surface in the same frame and units?",
                     file=path.source, row=int(first[0]) + 1)


# ---------------------------------------------------------------------------------------------
# path generators


def _counts(length: float, step: float) -> int:
    """Points needed so that ``length`` is split into intervals no longer than ``step``."""
    return max(2, math.ceil(length / step - 1e-9) + 1)


def _swap(surface: ParametricSurface, along: str) -> tuple[tuple[float, float], tuple[float, float]]:
    """(range along the rows, range across them)."""
    if along not in ("u", "v"):
        raise ValueError("along must be 'u' or 'v'")
    if along == "u":
        return surface.u_range, surface.v_range
    return surface.v_range, surface.u_range


def _uv(along: str, a: Any, c: Any) -> tuple[np.ndarray, np.ndarray]:
    a, c = np.broadcast_arrays(np.asarray(a, dtype=float), np.asarray(c, dtype=float))
    return (a, c) if along == "u" else (c, a)


def _cross_distance(surface: ParametricSurface, along: str, n_dense: int) -> tuple[np.ndarray, np.ndarray]:
    """Cross parameter samples and the cumulative across-row distance (mm) at them.

    The distance between neighbouring iso-curves per unit cross parameter is |Su x Sv| / |S_along|
    (the part of S_cross normal to the row direction); its maximum along the row is integrated.
    """
    a_range, c_range = _swap(surface, along)
    a_s = np.linspace(*a_range, 101)
    c_d = np.linspace(*c_range, min(n_dense, 1001))  # the width varies smoothly: trapezoids suffice
    d = surface.derivatives(*_uv(along, a_s[:, None], c_d[None, :]))
    s_along = np.linalg.norm(d.Su if along == "u" else d.Sv, axis=-1)
    w = (np.linalg.norm(np.cross(d.Su, d.Sv), axis=-1) / s_along).max(axis=0)
    return c_d, np.r_[0.0, np.cumsum(0.5 * (w[1:] + w[:-1]) * np.diff(c_d))]


def zigzag_extents(surface: ParametricSurface, along: str = "u", n_dense: int = 4001) -> tuple[float, float]:
    """(longest row length, across-row width) in mm of the zig-zag region of ``zigzag_path``
    (no margin): e.g. stepover = width / (rows - 1), spacing = length / (points - 1)."""
    a_range, c_range = _swap(surface, along)
    _, s_cross = _cross_distance(surface, along, n_dense)
    c_s = np.linspace(*c_range, 101)
    P = surface.point(*_uv(along, np.linspace(*a_range, n_dense)[None, :], c_s[:, None]))
    length = np.linalg.norm(np.diff(P, axis=1), axis=-1).sum(axis=1).max()
    return float(length), float(s_cross[-1])


def zigzag_path(surface: ParametricSurface, stepover: float, spacing: float, along: str = "u",
                margin: float = 0.0, feed: float | None = None, n_dense: int = 4001) -> CCPath:
    """Iso-parametric zig-zag CC path on a parametric surface.

    Rows run along ``along`` ('u': rows at constant v; 'v': rows at constant u); consecutive rows
    alternate direction, rows are numbered 0, 1, ... in machining order. Row placement: the
    across-row distance between neighbouring iso-curves is |Su x Sv| / |S_along| per unit of the
    other parameter; its maximum over the row is integrated across, and rows are placed at equal
    steps of that distance, no more than ``stepover`` mm apart. Within a row, the iso-curve is
    sampled densely (``n_dense``), its cumulative chord length computed, and points placed at equal
    arc-length steps no longer than ``spacing`` mm (parameter found with ``np.interp``, then the
    surface evaluated exactly). ``margin`` (mm) is left free at both ends of every row and before
    the first / after the last row. feed_dirs are the exact unit tangents along travel;
    ``feed`` (mm/min), if given, is set on every point.
    """
    a_range, _ = _swap(surface, along)
    if not (stepover > 0 and spacing > 0 and margin >= 0):
        raise ValueError("stepover and spacing must be > 0 and margin >= 0")

    def uv(a: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return _uv(along, a, c)

    def along_deriv(d: Any) -> np.ndarray:
        return d.Su if along == "u" else d.Sv

    c_d, s_cross = _cross_distance(surface, along, n_dense)
    avail = s_cross[-1] - 2 * margin
    if not avail >= 0:
        raise ValueError(f"margin {margin} mm leaves no room across the rows ({s_cross[-1]:.6g} mm)")
    n_rows = _counts(avail, stepover) if avail > 0 else 1
    c_rows = np.interp(np.linspace(margin, s_cross[-1] - margin, n_rows), s_cross, c_d)

    a_d = np.linspace(*a_range, n_dense)
    P = surface.point(*uv(a_d[None, :], c_rows[:, None]))  # (n_rows, n_dense, 3)
    chords = np.linalg.norm(np.diff(P, axis=1), axis=-1)
    s_row = np.concatenate([np.zeros((n_rows, 1)), np.cumsum(chords, axis=1)], axis=1)

    pts, nrm, fdirs, rows = [], [], [], []
    for k in range(n_rows):  # loop over rows (tens), not points
        length = s_row[k, -1] - 2 * margin
        if not length > 0:
            raise ValueError(f"margin {margin} mm leaves no room along row {k} ({s_row[k, -1]:.6g} mm)")
        s_t = np.linspace(margin, s_row[k, -1] - margin, _counts(length, spacing))
        a_t = np.interp(s_t, s_row[k], a_d)
        sign = 1.0
        if k % 2:
            a_t, sign = a_t[::-1], -1.0
        uu, vv = uv(a_t, np.full_like(a_t, c_rows[k]))
        dk = surface.derivatives(uu, vv)
        t = along_deriv(dk)
        pts.append(surface.point(uu, vv))
        nrm.append(np.cross(dk.Su, dk.Sv) / np.linalg.norm(np.cross(dk.Su, dk.Sv), axis=-1)[:, None])
        fdirs.append(sign * t / np.linalg.norm(t, axis=-1)[:, None])
        rows.append(np.full(len(a_t), k))
    points = np.concatenate(pts)
    return CCPath(points=points, normals=np.concatenate(nrm), rows=np.concatenate(rows),
                  feed_dirs=np.concatenate(fdirs),
                  feed=None if feed is None else np.full(len(points), float(feed)))


DropFunction = Callable[[trimesh.Trimesh, Any, np.ndarray, np.ndarray],
                        tuple[np.ndarray, np.ndarray, np.ndarray]]


INCH_MM = 25.4


def _no_raster_rows(cutter: Any, across1: float, across2: float, stepover: float, spacing: float) -> str:
    """Why a raster found no row of MIN_ROW_POINTS points, and what to change: a part narrower
    than the cutter that would fit it 25.4x larger is most likely a mesh in inches."""
    R, r = float(getattr(cutter, "R", 0.0)), float(getattr(cutter, "r", 0.0))
    diameter = 2.0 * (R + r)
    size = (f"the part is {across1:.4g} x {across2:.4g} mm across the tool axis (cutter diameter {diameter:g} mm, "
            f"--stepover {stepover:g}, --spacing {spacing:g} mm)")
    if max(across1, across2) < diameter <= INCH_MM * max(across1, across2):
        return (f"the cutter touches the mesh in no raster row: {size}; the part looks {INCH_MM:g}x smaller than the "
                "cutter and the steps expect (a mesh in inches?): scale the mesh to mm, or give --cutter-radius, "
                "--corner-radius, --stepover and --spacing in the mesh's units")
    if max(across1, across2) < diameter:
        return (f"the cutter touches the mesh in no raster row: {size}; the part is smaller than the cutter: "
                "use a smaller cutter, or check the mesh's units")
    return (f"the cutter touches the mesh in no raster row of {MIN_ROW_POINTS} points: {size}: use a smaller "
            "--spacing or --stepover, or check --axis (the side of the part the tool comes from)")


def raster_path_on_mesh(mesh: trimesh.Trimesh, cutter: Any, axis: Any, stepover: float, spacing: float,
                        drop: DropFunction, feed: float | None = None) -> CCPath:
    """Zig-zag raster CC path on a mesh by dropping the cutter along a fixed tool axis.

    Raster lines lie in the plane normal to ``axis`` (unit T, from tool tip toward spindle):
    travel along e1 (the world x axis projected onto that plane, or y if x is nearly parallel to T),
    lines spaced ``stepover`` mm along e2 = T x e1, points ``spacing`` mm apart, both grids centred
    on the mesh's extent. The start points sit on a plane 1 mm (or 1 % of the mesh size) above the
    mesh's highest point along T. ``drop(mesh, cutter, points, axis)`` (e.g.
    ``camsmooth.geometry.clearance.axial_drop``) returns (cl, contact, contact_normal), each (N, 3), NaN
    where the cutter misses. Misses split a line into separate rows; consecutive repeated contact
    points (the cutter rolling over an edge) are kept once; rows of fewer than 3 points are
    dropped. Lines alternate direction; rows are numbered 0, 1, ... in machining order. Feed
    directions are the travel direction projected onto each contact's tangent plane.
    """
    T = np.asarray(axis, dtype=float)
    T = T / np.linalg.norm(T)
    if not (stepover > 0 and spacing > 0):
        raise ValueError("stepover and spacing must be > 0")
    e1 = np.array([1.0, 0.0, 0.0]) - T[0] * T
    if np.linalg.norm(e1) < 0.1:
        e1 = np.array([0.0, 1.0, 0.0]) - T[1] * T
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(T, e1)
    V = np.asarray(mesh.vertices)
    p1, p2, pa = V @ e1, V @ e2, V @ T

    def centred(lo: float, hi: float, step: float) -> np.ndarray:
        n = int(math.floor((hi - lo) / step + 1e-9)) + 1
        return lo + 0.5 * ((hi - lo) - (n - 1) * step) + step * np.arange(n)

    t1 = centred(p1.min(), p1.max(), spacing)
    t2 = centred(p2.min(), p2.max(), stepover)
    top = pa.max() + max(1.0, 0.01 * float(np.ptp(V, axis=0).max()))
    grid = t1[None, :, None] * e1 + t2[:, None, None] * e2 + top * T  # (lines, points, 3)
    _, contact, cn = drop(mesh, cutter, grid.reshape(-1, 3), T)
    contact = np.asarray(contact, dtype=float).reshape(len(t2), len(t1), 3)
    cn = np.asarray(cn, dtype=float).reshape(len(t2), len(t1), 3)
    hit = np.all(np.isfinite(contact), axis=-1) & np.all(np.isfinite(cn), axis=-1)

    pts, nrm, fdirs, rows = [], [], [], []
    for j in range(len(t2)):  # loop over raster lines, not points
        order = np.arange(len(t1)) if j % 2 == 0 else np.arange(len(t1))[::-1]
        travel = e1 if j % 2 == 0 else -e1
        h = hit[j, order]
        # runs of consecutive hits along the travel order
        edges = np.flatnonzero(np.diff(np.r_[0, h.astype(np.int8), 0]))
        for s, e in zip(edges[::2], edges[1::2], strict=True):
            idx = order[s:e]
            c = contact[j, idx]
            keep = np.r_[True, np.linalg.norm(np.diff(c, axis=0), axis=1) >= REPEAT_TOL]
            c, n = c[keep], cn[j, idx][keep]
            if len(c) < MIN_ROW_POINTS:
                continue
            n = n / np.linalg.norm(n, axis=1)[:, None]
            f = travel - _dot(n, travel)[:, None] * n
            fl = np.linalg.norm(f, axis=1)
            f = np.where(fl[:, None] > 1e-9, f / np.where(fl > 1e-9, fl, 1.0)[:, None], np.nan)
            pts.append(c)
            nrm.append(n)
            fdirs.append(f)
            rows.append(np.full(len(c), len(rows)))
    if not pts:
        raise InputError(_no_raster_rows(cutter, np.ptp(p1), np.ptp(p2), stepover, spacing))
    points, normals, rr = np.concatenate(pts), np.concatenate(nrm), np.concatenate(rows)
    f = np.concatenate(fdirs)
    bad = ~np.all(np.isfinite(f), axis=1)
    if np.any(bad):  # contact normal along the travel direction: fall back on the point sequence
        f[bad] = estimate_feed_dirs(points, normals, rr)[bad]
    return CCPath(points=points, normals=normals, rows=rr, feed_dirs=f,
                  feed=None if feed is None else np.full(len(points), float(feed)))
