"""Regenerate the sample surfaces in this folder: ``python surfaces/make_samples.py [NAME ...]``.

For each sample NAME it writes NAME.toml (definition), NAME_path.csv (zig-zag CC path, about 30
rows of 200 points, feed 2000 mm/min) and NAME.ply (binary PLY mesh, chord error <= 2e-4 mm, its
grid lines through the rows and graded along them, ``row_aligned_grid``), checks them (definition
round trip, chord error measured independently on the PLY, mesh offset at the CC points, file
size < 4 MB, normals up) and prints a summary: size, curvature radii, normal swing per row and,
for the B-spline samples, the curvature jump across every G1 blend (double knot). See README.md
in this folder.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import trimesh
from scipy.interpolate import BSpline, PchipInterpolator
from scipy.spatial import cKDTree

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))  # run from a source checkout without installing

from camsmooth.geometry.paths import CCPath, zigzag_extents, zigzag_path  # noqa: E402
from camsmooth.geometry.surfaces import (  # noqa: E402
    BSplineSurface,
    ParametricSurface,
    Saddle,
    Sinusoid,
    clamped_knots,
    grid_chord_error,
    load_definition,
    load_surface,
    save_definition,
    save_mesh,
)
from camsmooth.io.ccpath import read_cc_csv, write_cc_csv  # noqa: E402

CHORD_TOL = 2e-4  # mm, required of the PLY mesh
# PLY stores float32 vertices (rounding <= 4e-6 mm at 100 mm): tessellate a little tighter
TESSELLATION_TOL = 1.9e-4
# mesh deviation allowed where the surface is concave along the rows: chords lie above the
# surface there, and the pipeline's clear-orientation test (pipeline.CLEAR_MARGIN, -5e-5 mm)
# rejects every orientation at a CC point the mesh covers by more
CONCAVE_TOL = 2.5e-5
MAX_FILE_BYTES = 4_000_000
ROWS, POINTS, FEED = 30, 200, 2000.0  # rows per path, points per row, mm/min


def greville(knots: np.ndarray, degree: int) -> np.ndarray:
    """Greville abscissae: control points placed there make x(u) = u exactly (linear precision)."""
    n = len(knots) - degree - 1
    return np.array([knots[i + 1:i + degree + 1].mean() for i in range(n)])


# ---------------------------------------------------------------------------------------------
# G1 profiles (circular arcs and lines) and their B-spline surfaces with double knots

Piece = tuple[float, float]  # (arc length in mm, curvature in 1/mm; > 0 concave seen from above)
Sections = Callable[[float], tuple[list[Piece], float]]  # y (mm) -> (pieces, start slope angle in rad)


def g1_chain(sigma: np.ndarray, pieces: list[Piece], psi0: float) -> tuple[np.ndarray, np.ndarray]:
    """(x, z) in mm at arc lengths ``sigma`` (mm) along a tangent-continuous chain of circular arcs
    and straight lines in the x-z plane, starting at the origin with slope angle psi0 (rad, from
    +x toward +z) and running through ``pieces`` (length, kappa) in turn.

    On a piece starting at (x_k, z_k, psi_k) the slope angle is psi = psi_k + kappa t (t = arc
    length into the piece), so x = x_k + (sin psi - sin psi_k) / kappa, z = z_k - (cos psi -
    cos psi_k) / kappa (a line: x_k + t cos psi_k, z_k + t sin psi_k). The slope is continuous at
    the joins and the curvature jumps there: a G1 blend as in filleted CAD models.
    """
    sigma = np.asarray(sigma, dtype=float)
    ell = np.array([p[0] for p in pieces])
    kap = np.array([p[1] for p in pieces])
    s0 = np.r_[0.0, np.cumsum(ell)]
    x0, z0, psi = [0.0], [0.0], [float(psi0)]
    for n, k in zip(ell, kap, strict=True):
        x, z = _piece(n, psi[-1], k)
        x0.append(x0[-1] + x)
        z0.append(z0[-1] + z)
        psi.append(psi[-1] + k * n)
    i = np.clip(np.searchsorted(s0, sigma, side="right") - 1, 0, len(pieces) - 1)
    x, z = _piece(sigma - s0[i], np.array(psi)[i], kap[i])
    return np.array(x0)[i] + x, np.array(z0)[i] + z


def _piece(t: np.ndarray | float, psi: np.ndarray | float, kappa: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Displacement (dx, dz) along an arc (or line, kappa = 0) of length t from slope angle psi."""
    t, psi, kappa = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (t, psi, kappa)))
    k = np.where(kappa == 0, 1.0, kappa)
    e = psi + kappa * t
    dx = np.where(kappa == 0, t * np.cos(psi), (np.sin(e) - np.sin(psi)) / k)
    dz = np.where(kappa == 0, t * np.sin(psi), (np.cos(psi) - np.cos(e)) / k)
    return dx, dz


def close_chain(pieces: list[Piece], psi0: float, length: float) -> list[Piece]:
    """``pieces`` with the last one's length set so that the chain ends at x = ``length`` (mm)."""
    x, psi = 0.0, psi0
    for n, k in pieces[:-1]:
        x += float(_piece(n, psi, k)[0])
        psi += k * n
    dx, k = length - x, pieces[-1][1]
    if not dx > 0:
        raise ValueError("the profile is longer than the sample")
    n = dx / math.cos(psi) if k == 0 else (math.asin(math.sin(psi) + k * dx) - psi) / k
    return [*pieces[:-1], (n, k)]


def knots_with_joins(lo: float, hi: float, joins: np.ndarray, spacing: float, degree: int = 3) -> np.ndarray:
    """Clamped knot vector on [lo, hi] with a knot of multiplicity degree - 1 at each join (C1 there:
    the tangent is continuous, the curvature may jump) and single knots about ``spacing`` apart
    inside the pieces."""
    breaks = np.r_[lo, joins, hi]
    inner = [float(j) for j in joins for _ in range(degree - 1)]
    for a, b in zip(breaks[:-1], breaks[1:], strict=True):
        inner += np.linspace(a, b, max(1, round((b - a) / spacing)) + 1)[1:-1].tolist()
    return np.r_[[float(lo)] * (degree + 1), sorted(inner), [float(hi)] * (degree + 1)]


def g1_surface(sections: Sections, length: float, width: float, n_ctrl_v: int = 10, spacing: float = 5.0,
               extra: Callable[[np.ndarray, float], np.ndarray] | None = None,
               n_fit: tuple[int, int] = (1601, 121)) -> BSplineSurface:
    """Bicubic B-spline through G1 sections across the rows (rows along u, roughly along x).

    ``sections(y)`` gives (pieces, psi0) of the section at y: a ``g1_chain`` in the x-z plane
    from x = 0 (z = 0) to x = ``length`` (the last piece's length is set by ``close_chain``), all
    sections with the same number of pieces; the joins may move with y. The target point at
    (u, v) is (x, v, z + extra(x, v)) at arc length sigma(u, v) along the section at y = v, where
    sigma is the monotone C1 cubic (PCHIP) in u taking 0, the mean joins u_k and the mean total
    length to 0, the joins and the total length of that section; the target is therefore C1 in u
    with its curvature jumps exactly on the lines u = u_k, and u runs at about unit speed. The
    knot vector in u has double knots at the u_k and single knots about ``spacing`` mm apart; in
    v it is clamped uniform (n_ctrl_v control points). The control net is the separable least-
    squares fit on an n_fit grid; the control y are the Greville abscissae (y = v exactly). The
    knot multiplicity, not the fit, makes the surface C1 (and not C2) across the knot lines.
    """
    def closed(y: float) -> tuple[list[Piece], float]:
        pieces, psi0 = sections(y)
        return close_chain(pieces, psi0, length), psi0

    def breaks(pieces: list[Piece]) -> np.ndarray:
        return np.cumsum([p[0] for p in pieces])

    # rounded to 1e-6 mm only to keep the knots in the definition file short
    nodes = np.round(np.mean([breaks(closed(y)[0]) for y in np.linspace(0.0, width, 61)], axis=0), 6)
    u_joins, u_len = nodes[:-1], float(nodes[-1])
    tu = knots_with_joins(0.0, u_len, u_joins, spacing)
    tv = clamped_knots(n_ctrl_v, 3, 0.0, width)
    us = np.unique(np.r_[np.linspace(0.0, u_len, n_fit[0]), u_joins])
    vs = np.linspace(0.0, width, n_fit[1])
    F = np.empty((len(us), len(vs), 3))
    for j, y in enumerate(vs):  # loop over sections (~100), not points
        pieces, psi0 = closed(y)
        sigma = PchipInterpolator(np.r_[0.0, nodes], np.r_[0.0, breaks(pieces)])(us)
        x, z = g1_chain(sigma, pieces, psi0)
        x[-1] = length  # exactly, not to rounding
        F[:, j] = np.stack([x, np.full_like(x, y), z + (0.0 if extra is None else extra(x, y))], -1)
    Bu = BSpline.design_matrix(us, tu, 3).toarray()
    Bv = BSpline.design_matrix(vs, tv, 3).toarray()
    control = np.einsum("ia,abk,jb->ijk", np.linalg.pinv(Bu), F, np.linalg.pinv(Bv))
    control[:, :, 1] = greville(tv, 3)[None, :]
    # round to 1e-9 mm so the definition file stays short; the geometry changes by < 1e-8 mm
    return BSplineSurface(np.round(control, 9), degree=(3, 3), knots_u=tu, knots_v=tv)


def blade() -> BSplineSurface:
    """Mould/blade-like free-form of G1 pieces across x (80 x 60 mm): convex leading region
    (R 44..52), straight, concave camber (R 41..47), straight, convex trailing region (R 43..49);
    radii and the start slope vary along y, the joins are swept (they move by 4 mm along x over
    y), plus a twist and a spanwise bow. Double knots in u at the four joins."""
    length, width = 80.0, 60.0

    def sections(y: float) -> tuple[list[Piece], float]:
        s = (y - 30.0) / 30.0
        return ([(16.0 + 2.0 * s, -1 / (48.0 - 4.0 * s)), (8.0, 0.0), (24.0, 1 / (44.0 + 3.0 * s)), (8.0, 0.0),
                 (0.0, -1 / (46.0 + 3.0 * s))], math.radians(10.0 + 2.0 * s))

    def extra(x: np.ndarray, y: float) -> np.ndarray:
        return 4.0 + (x - 40.0) * (y - 30.0) / 600.0 + (y - 30.0) ** 2 / 800.0

    return g1_surface(sections, length, width, extra=extra)


def mould() -> BSplineSurface:
    """Mould wall crossed by every row (80 x 60 mm): floor -> concave fillet (R 36 -> 34 along y)
    -> drafted wall (41 -> 46 deg, 8 -> 6 mm long) -> convex round (R 40..43) -> top, joined G1
    (double knots in u at the four joins). The floor and the top share the x left over by the
    fillet, wall and round, and the floor is lengthened by 2 sin(pi y / 60) mm, so the wall is
    curved in plan."""
    length, width = 80.0, 60.0

    def sections(y: float) -> tuple[list[Piece], float]:
        s = y / width
        alpha = math.radians(41.0 + 5.0 * s)
        r_fillet, r_round, wall = 36.0 - 2.0 * s, 40.0 + 3.0 * math.sin(math.pi * s), 8.0 - 2.0 * s
        middle = (r_fillet + r_round) * math.sin(alpha) + wall * math.cos(alpha)  # x taken by the wall
        floor = (length - middle) / 2 - 1.0 + 2.0 * math.sin(math.pi * s)
        return ([(floor, 0.0), (r_fillet * alpha, 1 / r_fillet), (wall, 0.0), (r_round * alpha, -1 / r_round),
                 (0.0, 0.0)], 0.0)

    return g1_surface(sections, length, width)


def saddle() -> Saddle:
    """z = 10 + (y^2 - x^2) / 250 on 60 x 60 mm: radius of curvature 125 mm at the centre, convex
    along x (the rows) and concave across them."""
    return Saddle(a=-1 / 250, b=-1 / 250, u_range=(-30.0, 30.0), v_range=(-30.0, 30.0),
                  center=(0.0, 0.0, 10.0))


def wave() -> Sinusoid:
    """z = 10 + 2.5 sin(2 pi x / 44.4) sin(2 pi y / 160) on 80 x 40 mm (y from 20 to 60): along the
    rows (x) concave troughs of radius 20-28 mm, where a toroidal cutter's heel gouges at low lead,
    between convex crests; the amplitude varies gently across the rows."""
    return Sinusoid(amplitude=2.5, kx=2 * math.pi / 44.4, ky=2 * math.pi / 160.0, u_range=(0.0, 80.0),
                    v_range=(20.0, 60.0), center=(0.0, 0.0, 10.0))


def dome() -> Saddle:
    """z = 10 - (x^2 + y^2) / 200 on 60 x 60 mm: a dome (radius of curvature 100 mm at the top),
    convex both ways, like an impeller hub or a mould's crown. Machined on a table-table machine
    (surfaces/dome_machine.toml, an A/C trunnion with the C axis through the top), the rows near
    the top carry the tool axis past the C axis: the pole of the C axis."""
    return Saddle(a=-1 / 200, b=1 / 200, u_range=(-30.0, 30.0), v_range=(-30.0, 30.0), center=(0.0, 0.0, 10.0))


SAMPLES = {"blade": blade, "saddle": saddle, "mould": mould, "wave": wave, "dome": dome}
#: Samples whose mesh is a uniform grid exported like a CAD system's STL (triangles of about
#: MESH_STEP mm, not aligned with the path, chord error what that step gives): the case the
#: pipeline meets in practice, unlike the row-aligned PLYs of the other samples.
STL_SAMPLES = {"wave": 0.3, "dome": 0.4}


def grid_mesh(surface: ParametricSurface, us: np.ndarray, vs: np.ndarray) -> trimesh.Trimesh:
    """Triangle mesh on the parameter grid us x vs: vertex (i, j) = i * len(vs) + j, exact unit
    vertex normals, two faces per cell wound like ``camsmooth.geometry.surfaces.tessellate`` (face normals
    along Su x Sv, i.e. up)."""
    nu, nv = len(us), len(vs)
    U, V = np.meshgrid(us, vs, indexing="ij")
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    faces = np.stack([np.stack([a, a + nv, a + nv + 1], -1), np.stack([a, a + nv + 1, a + 1], -1)], 1).reshape(-1, 3)
    mesh = trimesh.Trimesh(vertices=surface.point(U, V).reshape(-1, 3), faces=faces,
                           vertex_normals=surface.normal(U, V).reshape(-1, 3), process=False)
    mesh.metadata["grid"] = (nu, nv)
    return mesh


def row_aligned_grid(surface: ParametricSurface, row_v: np.ndarray, chord_tol: float, concave_tol: float,
                     n_sample: tuple[int, int] = (2001, 61)) -> tuple[np.ndarray, np.ndarray, float]:
    """Parameter lines (us, vs) of a mesh for a path whose rows run along u at v = ``row_v``.

    vs holds every row (so each CC point lies on a mesh edge along its row) and splits the gaps
    between rows evenly. us is graded by the normal curvature along u (max over v of |L|, in mm
    per parameter^2): the edge deviation |L| du^2 / 8 stays within a share of chord_tol, and
    within concave_tol where the surface is concave along the rows (L > 0), so that there the
    mesh lies at most concave_tol above the CC points. For each share (the rest goes to the
    spacing across the rows) both spacings are scaled until the chord error
    (``grid_chord_error``) is within chord_tol; the grid with the fewest points is returned as
    (us, vs, chord error).
    """
    (u0, u1), (v0, v1) = surface.u_range, surface.v_range
    U, V = surface.grid(*n_sample)
    ff = surface.fundamental_forms(U, V)
    L_abs, M_abs = np.abs(ff.L).max(axis=1), np.abs(ff.M).max(axis=1)
    L_concave = np.clip(ff.L, 0, None).max(axis=1)
    N_max = max(float(np.abs(ff.N).max()), 1e-12)
    u_s = U[:, 0]
    rows = np.unique(np.r_[v0, np.asarray(row_v, dtype=float), v1])
    rows = rows[np.r_[np.diff(rows) > 1e-9, True]]  # a row at v1 - 1e-14 is the line v1
    rows[-1] = v1

    def spacing_v(share: float, scale: float) -> float:
        return math.sqrt(8 * (1 - share) * chord_tol / N_max) / scale

    def u_lines(share: float, scale: float) -> np.ndarray:
        # (|L| du^2 + 2 |M| du dv) / 8 <= share * chord_tol, solved for du (lines per unit = 1 / du)
        b = M_abs * spacing_v(share, scale)
        c = 8 * share * chord_tol / scale**2
        du = c / (b + np.sqrt(b * b + L_abs * c))
        density = np.maximum.reduce([1 / du, np.sqrt(L_concave / (8 * concave_tol)), np.ones_like(u_s)])
        # no coarse cell may straddle a curvature jump: spread each density over its own spacing
        reach = np.ceil(1.0 / (density * (u_s[1] - u_s[0]))).astype(int)
        spread = density.copy()
        for k in np.flatnonzero(reach > 1):  # loop over the ~2000 samples, once per grid tried
            lo, hi = max(0, k - reach[k]), k + reach[k] + 1
            spread[lo:hi] = np.maximum(spread[lo:hi], density[k])
        cum = np.r_[0.0, np.cumsum(0.5 * (spread[1:] + spread[:-1]) * np.diff(u_s))]
        us = np.interp(np.linspace(0.0, cum[-1], math.ceil(cum[-1]) + 1), cum, u_s)
        us[0], us[-1] = u0, u1
        return us

    def v_lines(share: float, scale: float) -> np.ndarray:
        dv = spacing_v(share, scale)
        splits = [np.linspace(a, b, math.ceil((b - a) / dv) + 1)[:-1]
                  for a, b in zip(rows[:-1], rows[1:], strict=True)]
        return np.r_[np.concatenate(splits), v1]

    best: tuple[int, np.ndarray, np.ndarray, float] | None = None
    for share in (0.3, 0.5, 0.7, 0.9):
        scale = 1.0
        for _ in range(8):  # the error scales with the square of the spacing: aim just under chord_tol
            us, vs = u_lines(share, scale), v_lines(share, scale)
            err = grid_chord_error(surface, us, vs)
            if err <= chord_tol and (best is None or len(us) * len(vs) < best[0]):
                best = (len(us) * len(vs), us, vs, err)
            if 0.9 * chord_tol <= err <= chord_tol:
                break
            scale *= math.sqrt(err / (0.95 * chord_tol))
    if best is None:
        raise RuntimeError("row_aligned_grid did not reach the chord tolerance")
    return best[1], best[2], best[3]


def mesh_offsets(mesh: trimesh.Trimesh, points: np.ndarray, normals: np.ndarray, k: int = 32) -> np.ndarray:
    """Signed offset (mm) of the mesh from each point along its normal, > 0 where the mesh lies
    above (outside) the point: exact closest points on the faces around the k nearest vertices."""
    _, nb = cKDTree(mesh.vertices).query(points, k=k)
    vf = mesh.vertex_faces[nb].reshape(len(points), -1)  # padded with -1
    owner, face = np.nonzero(vf >= 0)
    face = vf[owner, face]
    c = trimesh.triangles.closest_point(mesh.triangles[face], points[owner])
    d = np.linalg.norm(c - points[owner], axis=1)
    best = np.full(len(points), np.inf)
    np.minimum.at(best, owner, d)
    pick = d <= best[owner]
    sign = np.zeros(len(points))
    sign[owner[pick]] = np.einsum("ij,ij->i", c[pick] - points[owner[pick]], normals[owner[pick]])
    return np.where(sign >= 0, best, -best)


def curvature_report(surface: ParametricSurface, n: int = 401) -> tuple[float, float]:
    """(min concave radius, min convex radius) in mm on an n x n grid; inf if none (radius > 10 m)."""
    U, V = surface.grid(n, n)
    k1, k2, _, _ = surface.principal_curvatures(U, V)
    kmax, kmin = float(k1.max()), float(k2.min())
    return (1 / kmax if kmax > 1e-4 else math.inf), (-1 / kmin if kmin < -1e-4 else math.inf)


def blend_report(surface: ParametricSurface, n: int = 121, eps: float = 1e-7) -> list[dict]:
    """Per double interior u knot of a B-spline (a G1 blend): u, the largest normal angle (deg) and
    the smallest / largest principal-curvature jump (1/mm) across it over n values of v."""
    if not isinstance(surface, BSplineSurface):
        return []
    t, k = surface.knots_u, surface.degree[0]
    vals, counts = np.unique(t[k + 1:-k - 1], return_counts=True)
    v = np.linspace(*surface.v_range, n)
    out = []
    for uk in vals[counts == k - 1]:
        lo, hi = np.full(n, uk - eps), np.full(n, uk + eps)
        a, b = surface.principal_curvatures(lo, v), surface.principal_curvatures(hi, v)
        jump = np.maximum(np.abs(a[0] - b[0]), np.abs(a[1] - b[1]))
        cos = np.sum(surface.normal(lo, v) * surface.normal(hi, v), axis=-1)
        out.append(dict(u=float(uk), kink=float(np.degrees(np.arccos(np.clip(cos.min(), -1, 1)))),
                        jump=(float(jump.min()), float(jump.max())),
                        left=(float(a[1].min()), float(a[0].max())), right=(float(b[1].min()), float(b[0].max()))))
    return out


def independent_chord_error(surface: ParametricSurface, mesh: trimesh.Trimesh, us: np.ndarray, vs: np.ndarray,
                            n: int = 50_000) -> float:
    """Largest distance from random surface points to the triangles of their grid cell and its
    eight neighbours (an upper bound of the distance to the mesh; the neighbours matter in thin
    cells, whose iso-lines may bend sideways by more than the cell width), exact per triangle.
    ``mesh`` keeps the order of ``grid_mesh`` on the lines us x vs (vertex (i, j) = i*nv + j,
    two faces per cell)."""
    rng = np.random.default_rng(1)
    nu, nv = len(us), len(vs)
    u = rng.uniform(*surface.u_range, n)
    v = rng.uniform(*surface.v_range, n)
    i = np.clip(np.searchsorted(us, u) - 1, 0, nu - 2)
    j = np.clip(np.searchsorted(vs, v) - 1, 0, nv - 2)
    p = surface.point(u, v)
    best = np.full(n, np.inf)
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            t = 2 * (np.clip(i + di, 0, nu - 2) * (nv - 1) + np.clip(j + dj, 0, nv - 2))
            for k in (0, 1):
                c = trimesh.triangles.closest_point(mesh.triangles[t + k], p)
                best = np.minimum(best, np.linalg.norm(c - p, axis=1))
    return float(best.max())


def definition_and_path(surface: ParametricSurface, toml: Path, csv: Path) -> CCPath:
    """Write the definition (checked: it reads back bit for bit) and the zig-zag path (ROWS rows
    of POINTS points along u at FEED), and return the path as read back."""
    save_definition(surface, toml)
    back = load_definition(toml)
    U, V = surface.grid(37, 41)
    assert back.parameters() == surface.parameters() and np.array_equal(back.point(U, V), surface.point(U, V))
    length, width = zigzag_extents(surface, "u")
    path = zigzag_path(surface, stepover=width / (ROWS - 1), spacing=length / (POINTS - 1), along="u", feed=FEED)
    write_cc_csv(csv, path)
    return read_cc_csv(csv)


def make_stl(name: str, surface: ParametricSurface, step: float) -> dict:
    """Definition, path and an STL on a uniform parameter grid of about ``step`` mm (binary STL,
    float32 vertices), checked: definition round trip, chord error measured independently on the
    STL as written, file size."""
    toml, stl, csv = HERE / f"{name}.toml", HERE / f"{name}.stl", HERE / f"{name}_path.csv"
    path = definition_and_path(surface, toml, csv)
    (u0, u1), (v0, v1) = surface.u_range, surface.v_range
    us = np.linspace(u0, u1, round((u1 - u0) / step) + 1)
    vs = np.linspace(v0, v1, round((v1 - v0) / step) + 1)
    mesh = grid_mesh(surface, us, vs)
    mesh.export(stl)
    assert stl.stat().st_size < MAX_FILE_BYTES, (name, stl.stat().st_size)
    loaded = load_surface(stl).mesh
    assert np.all(loaded.face_normals[:, 2] > 0)
    chord = independent_chord_error(surface, grid_mesh(surface, us, vs), us, vs)
    offset = mesh_offsets(loaded, path.points, path.normals)
    counts = [s.stop - s.start for s in path.row_slices()]
    concave, convex = curvature_report(surface)
    return dict(name=name, rows=len(counts), pts=(min(counts), max(counts)), n=len(path),
                verts=len(mesh.vertices), faces=len(mesh.faces), grid=(len(us), len(vs)), chord_est=chord,
                chord=chord, offset=(float(offset.min()), float(offset.max())),
                du=(float(np.diff(us).min()), float(np.diff(us).max())),
                sizes={p.name: p.stat().st_size for p in (toml, stl, csv)}, concave=concave, convex=convex,
                tilt=(float(np.degrees(np.arctan2(path.normals[:, 0], path.normals[:, 2])).min()),
                      float(np.degrees(np.arctan2(path.normals[:, 0], path.normals[:, 2])).max())),
                max_tilt=float(np.degrees(np.arccos(path.normals[:, 2].min()))),
                swing=(min(_swings(path)), max(_swings(path))), blends=[],
                z=(float(mesh.vertices[:, 2].min()), float(mesh.vertices[:, 2].max())),
                xy=np.ptp(mesh.vertices[:, :2], axis=0).tolist())


def _swings(path: CCPath) -> list[float]:
    return [float(np.degrees(np.arccos(np.clip(path.normals[s] @ path.normals[s].T, -1, 1))).max())
            for s in path.row_slices()]


def make(name: str, surface: ParametricSurface) -> dict:
    if name in STL_SAMPLES:
        return make_stl(name, surface, STL_SAMPLES[name])
    toml, ply, csv = HERE / f"{name}.toml", HERE / f"{name}.ply", HERE / f"{name}_path.csv"
    path = definition_and_path(surface, toml, csv)
    assert np.all(path.normals[:, 2] > 0)

    # the rows lie at v = y (every sample has y(u, v) = v): put mesh lines through them
    row_v = np.array([path.points[s.start, 1] for s in path.row_slices()])
    assert np.allclose(surface.point(np.full_like(row_v, surface.u_range[0]), row_v)[:, 1], row_v, atol=1e-9)
    us, vs, chord_est = row_aligned_grid(surface, row_v, TESSELLATION_TOL, CONCAVE_TOL)
    mesh = grid_mesh(surface, us, vs)
    save_mesh(mesh, ply)
    assert ply.stat().st_size < MAX_FILE_BYTES, (name, ply.stat().st_size)
    loaded = load_surface(ply).mesh
    assert np.array_equal(loaded.faces, mesh.faces) and np.all(loaded.face_normals[:, 2] > 0)
    chord = independent_chord_error(surface, loaded, us, vs)
    assert chord <= CHORD_TOL, (name, chord)
    offset = mesh_offsets(loaded, path.points, path.normals)
    # the CC points lie on mesh edges: never more than concave_tol under the mesh
    assert offset.max() <= 1.2 * CONCAVE_TOL and -offset.min() <= CHORD_TOL, (name, offset.min(), offset.max())

    counts = [s.stop - s.start for s in path.row_slices()]
    tilt = np.degrees(np.arctan2(path.normals[:, 0], path.normals[:, 2]))  # in the x-z plane (rows along x)
    swings = [float(np.degrees(np.arccos(np.clip(path.normals[s] @ path.normals[s].T, -1, 1))).max())
              for s in path.row_slices()]
    concave, convex = curvature_report(surface)
    return dict(name=name, rows=len(counts), pts=(min(counts), max(counts)), n=len(path),
                verts=len(mesh.vertices), faces=len(mesh.faces), grid=mesh.metadata["grid"],
                chord_est=chord_est, chord=chord, offset=(float(offset.min()), float(offset.max())),
                du=(float(np.diff(us).min()), float(np.diff(us).max())),
                sizes={p.name: p.stat().st_size for p in (toml, ply, csv)}, concave=concave, convex=convex,
                tilt=(float(tilt.min()), float(tilt.max())),
                max_tilt=float(np.degrees(np.arccos(path.normals[:, 2].min()))),
                swing=(min(swings), max(swings)), blends=blend_report(surface),
                z=(float(mesh.vertices[:, 2].min()), float(mesh.vertices[:, 2].max())),
                xy=np.ptp(mesh.vertices[:, :2], axis=0).tolist())


#: samples that ship a CAM program too (NAME.cls, NX CLSF): constant lead (deg), no tilt, as CAM
#: lead/tilt axis control writes it; the demo smooths it and shows its axes as the method 'cam'
CL_SAMPLES = {"dome": 11.0}


def make_cls(name: str, lead_deg: float) -> None:
    sys.path.insert(0, str(HERE.parent / "benchmarks"))
    from bench_controller import cam_clsf

    from camsmooth.geometry.cutter import ToroidalCutter

    text = cam_clsf(read_cc_csv(HERE / f"{name}_path.csv"), ToroidalCutter(R=4.0, r=1.0), lead_deg)
    (HERE / f"{name}.cls").write_text(text)
    print(f"  CAM program {name}.cls: constant lead {lead_deg:g} deg, {len(text) / 1e6:.2f} MB")


def main(names: list[str]) -> None:
    for name in names or list(SAMPLES):
        r = make(name, SAMPLES[name]())
        if name in CL_SAMPLES:
            make_cls(name, CL_SAMPLES[name])
        print(f"{r['name']}: {r['xy'][0]:.1f} x {r['xy'][1]:.1f} mm, z {r['z'][0]:.2f}..{r['z'][1]:.2f} mm")
        print(f"  path: {r['rows']} rows x {r['pts'][0]}..{r['pts'][1]} points ({r['n']} points)")
        print(f"  mesh: grid {r['grid'][0]} x {r['grid'][1]}, {r['verts']} vertices, {r['faces']} faces, "
              f"chord error {r['chord_est']:.3g} mm (estimate), {r['chord']:.3g} mm (measured on the mesh file)")
        print(f"  mesh u spacing {r['du'][0]:.3f}..{r['du'][1]:.3f}; mesh offset from the CC points along their "
              f"normals {r['offset'][0]:.2e}..{r['offset'][1]:.2e} mm")
        print("  files: " + ", ".join(f"{k} {v / 1e6:.2f} MB" for k, v in r["sizes"].items()))
        print(f"  min concave radius {r['concave']:.1f} mm, min convex radius {r['convex']:.1f} mm")
        print(f"  normal tilt in x-z along rows {r['tilt'][0]:.1f}..{r['tilt'][1]:.1f} deg, max from vertical "
              f"{r['max_tilt']:.1f} deg, swing within a row {r['swing'][0]:.1f}..{r['swing'][1]:.1f} deg")
        for b in r["blends"]:
            print(f"  G1 blend at u = {b['u']:.3f}: normal kink {b['kink']:.1e} deg, curvature "
                  f"{b['left'][0]:+.4f}..{b['left'][1]:+.4f} -> {b['right'][0]:+.4f}..{b['right'][1]:+.4f} 1/mm, "
                  f"jump {b['jump'][0]:.4f}..{b['jump'][1]:.4f} 1/mm")


if __name__ == "__main__":
    main(sys.argv[1:])  # optional sample names; default all
