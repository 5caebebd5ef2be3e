"""Cutter / mesh interference: exact clearance of tool poses and axial drop-cutter.

The part surface is a triangle mesh (a sheet; it need not be closed).  Everything here is exact
against the piecewise-linear mesh, up to rounding and the stated tolerances (clearance: 1e-12 mm
certificate on edge minima, 1e-10 mm pruning; drop: golden section to ~1e-10 mm, pruning
1e-9 mm).  (Against the surface the mesh approximates, the chord error of the tessellation
remains: a tool placed at a CC point of the true surface "gouges" a mesh whose chords lie above
a concave region by up to that error.)

* :func:`clearance` - minimum signed distance ``delta`` between the tool solid (cutter + shank +
  holder, camsmooth.geometry.cutter) and the mesh triangles for many poses, with the witness
  mesh point and the contact normal.  Compiled kernels (camsmooth.geometry._kernels, numba):
  per pose, a nearest-first descent of a bounding-volume hierarchy of oriented boxes, pruned by
  rigorous lower bounds (tangent planes of the convex signed distance); per triangle the exact
  minimum of the convex signed distance: interior (facet test, closed form via the support point
  of the core cylinder), edges (1-D convex minimisation on the slope with a certified gap), or,
  when the triangle's plane cuts the core cylinder, the plane's deepest point (closed form).
* :func:`axial_drop` - drop-cutter along any axis: the lowest tip position along the axis at
  which the cutter touches the mesh (vertex, facet and edge tests), as in the classic 3-axis
  drop-cutter (e.g. the OpenCAMLib drop-cutter) generalised to an arbitrary axis.  Vectorised
  numpy over chunks of points; candidates from a cKDTree over the vertices, sound for any mesh
  because the search reaches beyond the footprint by the longest edge (coarse meshes with long
  edges make that large: pass ``max_edge`` to :class:`MeshIndex`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from camsmooth.errors import InputError
from camsmooth.geometry import _kernels
from camsmooth.geometry.cutter import ToroidalCutter

__all__ = ["Clearance", "Drop", "MeshIndex", "axial_drop", "clearance"]

_INVPHI = (math.sqrt(5.0) - 1.0) / 2.0
_SQRT3 = math.sqrt(3.0)
_PRUNE_TOL = 1e-9          # mm: an element that can improve the answer by less than this is skipped
_TIE = 1e-13               # relative: drop parameters this close (times the mesh's size) are a tie
_BARY_TOL = 1e-12
_CHUNK = 512              # poses / points per chunk (bounds memory)
_LEAF = 8                 # triangles per leaf of the bounding-volume hierarchy


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _csr_expand(ptr: np.ndarray, data: np.ndarray, owners: np.ndarray,
                items: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each (owner, item) pair emit (owner, x) for every x in data[ptr[item]:ptr[item + 1]]."""
    starts = ptr[items]
    counts = ptr[items + 1] - starts
    total = int(counts.sum())
    if total == 0:
        return np.empty(0, np.intp), np.empty(0, np.intp)
    first = np.cumsum(counts) - counts
    offs = np.arange(total) - np.repeat(first, counts)
    return np.repeat(owners, counts), data[np.repeat(starts, counts) + offs]


def _unique_pairs(owner: np.ndarray, item: np.ndarray, n_items: int) -> tuple[np.ndarray, np.ndarray]:
    key = np.unique(owner.astype(np.int64) * n_items + item)
    return (key // n_items).astype(np.intp), (key % n_items).astype(np.intp)


def _inside_triangle(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
                     tol: float = _BARY_TOL) -> np.ndarray:
    """Barycentric inside test for points in the triangles' planes (valid triangles only)."""
    v0, v1, v2 = b - a, c - a, p - a
    d00, d01, d11 = _dot(v0, v0), _dot(v0, v1), _dot(v1, v1)
    d20, d21 = _dot(v2, v0), _dot(v2, v1)
    den = d00 * d11 - d01 * d01
    den = np.where(den > 0.0, den, 1.0)
    v = (d11 * d20 - d01 * d21) / den
    w = (d00 * d21 - d01 * d20) / den
    return (v >= -tol) & (w >= -tol) & (1.0 - v - w >= -tol)


def _golden_min(f, lo: np.ndarray, hi: np.ndarray, iters: int) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised golden-section minimisation of functions convex (unimodal) on [lo, hi];
    one evaluation of ``f`` (on all items at once) per iteration.  Returns (argmin, min)."""
    a, b = lo.astype(float), hi.astype(float)
    c = b - _INVPHI * (b - a)
    d = a + _INVPHI * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(iters):
        left = fc <= fd
        a, b = np.where(left, a, c), np.where(left, d, b)
        keep, fkeep = np.where(left, c, d), np.where(left, fc, fd)
        x = np.where(left, b - _INVPHI * (b - a), a + _INVPHI * (b - a))
        fx = f(x)
        c, fc = np.where(left, x, keep), np.where(left, fx, fkeep)
        d, fd = np.where(left, keep, x), np.where(left, fkeep, fx)
    better = fc <= fd
    return np.where(better, c, d), np.where(better, fc, fd)


def _golden_iters(length: float) -> int:
    """Iterations that shrink a bracket of ``length`` mm below ~1e-10 mm (at least 40)."""
    if not length > 1e-10:
        return 40
    return int(min(90, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI)))))


# ---------------------------------------------------------------------------------------------

class MeshIndex:
    """Search structures over a triangle mesh for :func:`clearance` and :func:`axial_drop`.

    Parameters
    ----------
    mesh : trimesh.Trimesh, mm, workpiece frame.  A surface sheet (need not be closed or
        manifold); face normals should point from the material toward the tool, although the
        computations here are purely geometric and do not use the orientation.  Vertices used
        by no face are dropped.
    max_edge : optional, mm.  Subdivide (trimesh.remesh.subdivide_to_size: shared midpoints, no
        cracks, the surface itself unchanged) until no edge is longer than this.  Results are
        exact either way.  :func:`axial_drop` reaches beyond the tool by the longest edge, so on
        a coarse mesh (e.g. a CAD STL with long thin facets) every point examines most of the
        mesh; subdividing to about the corner radius r keeps it local.  :func:`clearance` is
        insensitive to long edges (its hierarchy bounds the triangles themselves).

    Attributes: ``vertices`` (V, 3), ``faces`` (F, 3), ``edges`` (E, 2) unique edges,
    ``face_edges`` (F, 3) edge ids per face, ``face_normals`` (F, 3) unit (zero for degenerate
    faces), ``face_valid`` (F,), ``face_long`` (F,) longest edge per face, ``vertex_long`` (V,)
    longest edge of the faces around each vertex, ``vf_ptr``/``vf_faces`` vertex -> face CSR
    adjacency, ``tree`` cKDTree over the vertices; for :func:`clearance` a bounding-volume
    hierarchy: ``bvh_faces`` (F,) the faces in leaf order, ``bvh_nodes`` (M, 18) per node an
    oriented box (centre, three orthonormal axes, half-extents) holding its triangles, first
    child (-1 for a leaf), first face (leaf order) and face count (camsmooth.geometry._kernels).
    """

    def __init__(self, mesh: trimesh.Trimesh, max_edge: float | None = None) -> None:
        if not isinstance(mesh, trimesh.Trimesh):
            raise InputError(f"mesh must be a trimesh.Trimesh, got {type(mesh).__name__}")
        V = np.asarray(mesh.vertices, dtype=float)
        F = np.asarray(mesh.faces, dtype=np.intp)
        if F.ndim != 2 or F.shape[1] != 3 or len(F) == 0 or len(V) < 3:
            raise InputError("mesh has no triangles")
        if F.min() < 0 or F.max() >= len(V):
            raise InputError("mesh faces index missing vertices")
        if not np.all(np.isfinite(V)):
            raise InputError("mesh has non-finite vertex coordinates")
        if max_edge is not None:
            max_edge = float(max_edge)
            if not (math.isfinite(max_edge) and max_edge > 0):
                raise InputError(f"max_edge must be a positive length in mm, got {max_edge}")
            longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1)))
            iters = max(10, math.ceil(math.log2(max(longest / max_edge, 1.0))) + 3)
            V, F = trimesh.remesh.subdivide_to_size(V, F, max_edge=max_edge, max_iter=iters)
            V = np.asarray(V, dtype=float)
            F = np.asarray(F, dtype=np.intp)
        # Vertices used by no face are not part of the surface: drop them.
        used = np.zeros(len(V), bool)
        used[F.ravel()] = True
        if not used.all():
            remap = np.cumsum(used) - 1
            V, F = V[used], remap[F].astype(np.intp)
        V = np.ascontiguousarray(V, dtype=float)
        self.vertices = V
        self.faces = F
        nv, nf = len(V), len(F)

        raw = np.sort(np.stack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=1), axis=-1)  # (F,3,2)
        key = raw[..., 0].astype(np.int64) * nv + raw[..., 1]
        ukey, inv = np.unique(key.ravel(), return_inverse=True)
        self.edges = np.stack([ukey // nv, ukey % nv], axis=1).astype(np.intp)
        self.face_edges = inv.reshape(nf, 3).astype(np.intp)

        tri = V[F]
        cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area2 = np.linalg.norm(cr, axis=1)
        elen = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=-1)
        self.face_long = elen.max(axis=1)
        self.face_valid = area2 > 1e-12 * np.maximum(self.face_long, 1e-300) ** 2
        self.face_normals = np.where(self.face_valid[:, None],
                                     cr / np.where(area2 > 0, area2, 1.0)[:, None], 0.0)

        order = np.argsort(F.ravel(), kind="stable")
        self.vf_faces = (order // 3).astype(np.intp)
        counts = np.bincount(F.ravel(), minlength=nv)
        self.vf_ptr = np.concatenate([[0], np.cumsum(counts)]).astype(np.intp)
        reach = np.zeros(nv)
        np.maximum.at(reach, F.ravel(), np.repeat(self.face_long, 3))
        self.vertex_long = reach
        self.long_max = float(reach.max())

        self.tree = cKDTree(V)
        # Bounding-volume hierarchy for the clearance kernels: leaves of at most _LEAF
        # triangles; per-triangle data stored in leaf order (``bvh_faces`` maps back).
        perm, left, start, count, box = _kernels.build_bvh(V, F.astype(np.int64), _LEAF)
        self.bvh_faces = perm
        self.bvh_nodes = np.ascontiguousarray(np.column_stack([box, left, start, count]), dtype=float)
        Fp = F[perm]
        self._bvh_ti = np.ascontiguousarray(Fp, dtype=np.int64)
        self._bvh_tf = np.ascontiguousarray(np.column_stack(
            [self.face_normals[perm], V[Fp].mean(axis=1), self.face_valid[perm], V[Fp].reshape(-1, 9)]), dtype=float)
        lo, hi = V.min(axis=0), V.max(axis=0)
        self.box = np.stack([lo, hi])
        self._proj_cache: dict[bytes, tuple[cKDTree, np.ndarray]] = {}

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def _projected_tree(self, axis: np.ndarray) -> tuple[cKDTree, np.ndarray]:
        """2-D cKDTree of the vertices projected along ``axis`` (cached) and the (2, 3) basis."""
        key = np.round(axis, 14).tobytes()
        hit = self._proj_cache.get(key)
        if hit is None:
            e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])
            e1 /= np.linalg.norm(e1)
            basis = np.stack([e1, np.cross(axis, e1)])
            if len(self._proj_cache) >= 8:
                self._proj_cache.clear()
            hit = (cKDTree(self.vertices @ basis.T), basis)
            self._proj_cache[key] = hit
        return hit


def _as_index(mesh_or_index: trimesh.Trimesh | MeshIndex) -> MeshIndex:
    return mesh_or_index if isinstance(mesh_or_index, MeshIndex) else MeshIndex(mesh_or_index)


def _poses(points: np.ndarray, axes: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"{what} must have shape (N, 3), got {p.shape}")
    a = np.asarray(axes, dtype=float)
    if a.shape == (3,):
        a = np.broadcast_to(a, p.shape)
    if a.shape != p.shape:
        raise InputError(f"tool axes must have shape (3,) or {p.shape}, got {a.shape}")
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(a))):
        raise InputError(f"{what} and tool axes must be finite")
    nrm = np.linalg.norm(a, axis=1)
    if np.any(nrm < 1e-12):
        raise InputError(f"tool axis of {what[:-1] if what.endswith('s') else what} "
                         f"{int(np.argmin(nrm)) + 1} has zero length")
    return p, a / nrm[:, None]


# ---------------------------------------------------------------------------------------------
# clearance

@dataclass
class Clearance:
    """Result of :func:`clearance` for N poses.

    delta : (N,) mm, minimum signed distance between the tool solid and the mesh triangles
        (negative = penetration / gouge depth), exact where ``capped`` is False; where the true
        value is >= ``margin`` the pose is reported as ``delta = margin`` (a lower bound).
    witness : (N, 3) mesh point attaining ``delta``, mm, workpiece frame (NaN where capped).
    normal : (N, 3) unit vector, workpiece frame (NaN where capped): the direction from the
        witness toward the nearest point of the tool solid, i.e. minus the gradient of the tool's
        signed distance at the witness.  Translating the tool by ``t * normal`` changes the
        clearance at the witness to ``delta + t`` to first order, so where ``delta < 0`` it is
        the direction that separates the tool from the mesh.  At a touching contact it is the
        tool's outward surface normal there, pointing from the material toward the tool (the
        ``n`` of cc_to_cl), and ``witness + delta * normal`` is the point of the tool's surface
        nearest the witness (for any sign of delta).  For a facet contact it is exactly the
        facet normal on the tool's side; for an edge, vertex or deep contact it is computed from
        the witness (an edge witness is placed where the slope along the edge changes sign, to
        rounding).  On the core axis of a tool buried deeper than its radius every direction
        across the axis separates equally; one of them is returned.
    capped : (N,) bool, True where no mesh point is closer than ``margin``.
    margin : mm, the cap used.
    """

    delta: np.ndarray
    witness: np.ndarray
    normal: np.ndarray
    capped: np.ndarray
    margin: float


def _morton_order(points: np.ndarray, bits: int = 10) -> np.ndarray:
    """Permutation sorting (N, 3) points along a Z-order curve over their bounding box."""
    if len(points) < 2:
        return np.arange(len(points))
    lo, hi = points.min(axis=0), points.max(axis=0)
    q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64)
    code = np.zeros(len(points), np.int64)
    for b in range(bits):
        for k in range(3):
            code |= ((q[:, k] >> b) & 1) << (3 * b + k)
    return np.argsort(code, kind="stable")


def clearance(index: MeshIndex | trimesh.Trimesh, cutter: ToroidalCutter, tips: np.ndarray,
              axes: np.ndarray, *, margin: float = 1.0) -> Clearance:
    """Minimum signed distance between the tool solid and the mesh for N tool poses.

    Parameters
    ----------
    index : MeshIndex (or a trimesh.Trimesh, indexed on the fly).
    cutter : the tool; its solid is cutter + shank (convex) united with the holder
        (camsmooth.geometry.cutter).
    tips : (N, 3) tool tips (CL points), mm, workpiece frame.
    axes : (N, 3) or (3,) tool axes (tip -> spindle), normalised here.
    margin : mm, >= 0.  Poses whose clearance is >= margin are reported as ``delta = margin``
        with ``capped = True`` (a lower bound, no witness); smaller values are exact.  The work
        for poses that clear the mesh grows with the margin; touching or gouging poses are cheap.

    Returns
    -------
    Clearance: ``delta`` (N,) mm = min over mesh points x of signed_distance(tool, x), negative
    for penetration (its magnitude is the depth of the deepest mesh point inside the tool);
    ``witness`` (N, 3) the mesh point attaining it; ``normal`` (N, 3) the unit direction from
    the witness toward the tool (see :class:`Clearance`).

    Exactness: against the piecewise-linear mesh, to ~1e-10 mm (in practice to rounding).  The
    cutter + shank and the holder are each convex, so their signed distance is convex on each
    triangle; its minimum there is at the foot of the support point (facet test), on an edge (a
    1-D convex minimisation on the slope, Illinois regula falsi with bisection safeguards,
    accepted once the tangent lines at its bracket ends certify it within 1e-12 mm), or, only
    when the triangle's plane cuts the core cylinder (penetration deeper than r, or into the
    holder), at the plane's deepest point in the cylinder (closed form) if that lies in the
    triangle.  Triangles are visited through a bounding-volume hierarchy of oriented boxes,
    nearest first, and pruned only with rigorous lower bounds (tangent planes of the convex
    signed distance over the boxes and triangles).  The test is geometric and ignores face
    orientation: a tool wholly on the material side of a sheet without crossing it reports a
    positive distance.  Compiled, single-threaded kernels: camsmooth.geometry._kernels; scratch
    memory is independent of N.
    """
    idx = _as_index(index)
    tips, axes = _poses(tips, axes, "tool tips")
    margin = float(margin)
    if not (math.isfinite(margin) and margin >= 0.0):
        raise InputError(f"margin must be a finite length >= 0 mm, got {margin}")
    bodies = [(cutter.r, cutter.core_height, cutter.R, cutter.r)]
    if cutter.has_holder:
        bodies.append((float(cutter.shank_length), float(cutter.holder_length), float(cutter.holder_radius), 0.0))
    # Poses in Morton (Z-curve) order of their tips: neighbouring poses touch the same part of
    # the mesh and the hierarchy, which keeps the kernel's memory accesses in cache.
    order = _morton_order(tips)
    delta, witness, normal = np.empty(len(tips)), np.empty((len(tips), 3)), np.empty((len(tips), 3))
    delta[order], witness[order], normal[order] = _kernels.clearance_kernel(
        np.ascontiguousarray(tips[order]), np.ascontiguousarray(axes[order]), np.array(bodies, dtype=float),
        margin, idx.vertices, idx._bvh_ti, idx._bvh_tf, idx.bvh_nodes)
    capped = np.isnan(witness[:, 0])
    return Clearance(delta=delta, witness=witness, normal=normal, capped=capped, margin=margin)


# ---------------------------------------------------------------------------------------------
# axial drop

@dataclass
class Drop:
    """Result of :func:`axial_drop` for N points.

    cl : (N, 3) lowest tool tip positions, mm (NaN where ``hit`` is False).
    contact : (N, 3) the mesh point touched.
    contact_normal : (N, 3) unit normal of the cutter surface at the contact, pointing from the
        material toward the tool (into the cutter), i.e. the ``n`` of cc_to_cl.  Where the flat
        bottom touches (face contact: the contact inside the bottom's rim, normal = axis), cc_to_cl
        takes the contact at the bottom's centre (CL = CC): on a plane across the axis the facet
        under the tip wins the tie and the contact is the tip; where the bottom rests on a vertex
        off its centre (the top of a bump) that vertex is reported, and CC -> CL gives the pose
        with the bottom's centre on it instead (as :func:`camsmooth.geometry.contact.contacts`).
        A flat end's rim has a cone of normals (any of them gives the same CL): the part's normal
        moved into that cone (``_rim_normals``).
    hit : (N,) bool, False where the tool's footprint misses the mesh.

    Unpacks as ``cl, contact, contact_normal = drop`` (the triple that
    camsmooth.geometry.paths.raster_path_on_mesh expects of its ``drop`` function).
    """

    cl: np.ndarray
    contact: np.ndarray
    contact_normal: np.ndarray
    hit: np.ndarray

    def __iter__(self) -> Iterator[np.ndarray]:
        return iter((self.cl, self.contact, self.contact_normal))


def _zlow(cutter: ToroidalCutter, rho: np.ndarray) -> np.ndarray:
    """Height of the cutter's lower envelope above the tip at radial distance rho (<= R + r)."""
    x = np.maximum(rho - cutter.R, 0.0)
    return cutter.r - np.sqrt(np.maximum(cutter.r ** 2 - x * x, 0.0))


def _scatter_max(S: np.ndarray, C: np.ndarray, idx: np.ndarray, val: np.ndarray, pts: np.ndarray,
                 NF: np.ndarray, nrm: np.ndarray | None = None, tie: float = 0.0) -> None:
    """S[i] = max(S[i], val) per owner i; where val wins (or comes within ``tie`` mm of the best
    so far), C[i] = its point and NF[i] = its facet normal (NaN for a vertex or an edge contact,
    ``nrm`` None)."""
    if len(idx) == 0:
        return
    old = S[idx]
    np.maximum.at(S, idx, val)
    m = (val > old - tie) & (val >= S[idx] - tie)
    C[idx[m]] = pts[m]
    NF[idx[m]] = np.nan if nrm is None else nrm[m]


def _drop_candidates(index: MeshIndex, p: np.ndarray, A: np.ndarray, fixed: bool,
                     reach: float) -> tuple[np.ndarray, np.ndarray]:
    """(point, vertex) pairs holding every vertex within ``reach`` of the point's axis line."""
    N = len(p)
    if fixed:
        tree, basis = index._projected_tree(A[0])
        hits = tree.sparse_distance_matrix(cKDTree(p @ basis.T), reach, output_type="ndarray")
        return hits["j"].astype(np.intp), hits["i"].astype(np.intp)
    # Per-point axes: a vertex within ``reach`` of the line has its foot on the line inside the
    # mesh's bounding box grown by ``reach``: cover that stretch of the line with balls.
    lo, hi = index.box[0] - reach, index.box[1] + reach
    t0, t1 = np.full(N, -np.inf), np.full(N, np.inf)
    for k in range(3):  # the three slabs of the box
        ak = A[:, k]
        par = np.abs(ak) < 1e-12
        ta = (lo[k] - p[:, k]) / np.where(par, 1.0, ak)
        tb = (hi[k] - p[:, k]) / np.where(par, 1.0, ak)
        inside = (p[:, k] >= lo[k]) & (p[:, k] <= hi[k])
        t0 = np.where(par, np.where(inside, t0, np.inf), np.maximum(t0, np.minimum(ta, tb)))
        t1 = np.where(par, np.where(inside, t1, -np.inf), np.minimum(t1, np.maximum(ta, tb)))
    step = reach
    ok = t1 >= t0
    K = np.where(ok, np.ceil(np.where(ok, t1 - t0, 0.0) / step).astype(np.intp) + 1, 0)
    owner = np.repeat(np.arange(N), K)
    if len(owner) == 0:
        return owner, owner
    kb = np.arange(len(owner)) - np.repeat(np.cumsum(K) - K, K)
    spacing = (t1 - t0) / np.maximum(K - 1, 1)
    t = t0[owner] + kb * spacing[owner]
    centres = p[owner] + t[:, None] * A[owner]
    hits = index.tree.sparse_distance_matrix(cKDTree(centres), math.hypot(reach, 0.5 * step),
                                             output_type="ndarray")
    ball, vid = hits["j"], hits["i"].astype(np.intp)
    pid = owner[ball]
    # Overlapping balls: keep each pair once, for the ball nearest the vertex's foot on the line.
    tv = _dot(index.vertices[vid] - p[pid], A[pid])
    near = np.clip(np.floor((tv - t0[pid]) / np.where(spacing[pid] > 0, spacing[pid], 1.0) + 0.5),
                   0, K[pid] - 1)
    keep = near == kb[ball]
    return pid[keep], vid[keep]


def _drop_chunk(index: MeshIndex, cutter: ToroidalCutter, p: np.ndarray, A: np.ndarray,
                fixed: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(S, C, NF) of the points of a chunk: drop parameter, contact point, facet normal of a
    facet contact (oriented n.A > 0; NaN for vertex and edge contacts)."""
    V, F, E = index.vertices, index.faces, index.edges
    R, r = cutter.R, cutter.r
    Rc = R + r
    N = len(p)
    S = np.full(N, -np.inf)
    C = np.full((N, 3), np.nan)
    NF = np.full((N, 3), np.nan)

    def local(pts, pp, aa):
        q = pts - pp
        h = _dot(q, aa)
        w = q - h[..., None] * aa
        return h, w, np.sqrt(_dot(w, w))

    pid, vid = _drop_candidates(index, p, A, fixed, Rc + index.long_max)
    if len(vid) == 0:
        return S, C, NF
    h, _, rho = local(V[vid], p[pid], A[pid])
    keep = rho <= Rc + index.vertex_long[vid]
    pid, vid, h, rho = pid[keep], vid[keep], h[keep], rho[keep]

    # Vertex test (closed form): s = (v - p).A - zlow(rho).
    inn = rho <= Rc
    _scatter_max(S, C, pid[inn], h[inn] - _zlow(cutter, rho[inn]), V[vid[inn]], NF)

    # Faces worth testing: if a point x of a face has s(x) > S, the face's highest vertex v
    # (h is linear on the face) has h_v >= h(x) > S + zlow(rho(x)) >= S + zlow(rho_v - l_v), as
    # rho is 1-Lipschitz, |x - v| <= l_v and zlow is nondecreasing.
    lv = index.vertex_long[vid]
    shrunk = np.maximum(rho - lv, 0.0)
    m = (shrunk <= Rc) & (h > S[pid] + _zlow(cutter, np.minimum(shrunk, Rc)) + _PRUNE_TOL)
    if not np.any(m):
        return S, C, NF
    fp, ff = _csr_expand(index.vf_ptr, index.vf_faces, pid[m], vid[m])
    fp, ff = _unique_pairs(fp, ff, len(F))
    pp, aa = p[fp], A[fp]
    tri = V[F[ff]]
    ht, wt, rt = local(tri, pp[:, None, :], aa[:, None, :])      # (M,3)
    # Upper bounds: max height minus the envelope at a lower bound of rho over the face, and the
    # tangent planes of the concave s at vertices strictly inside the footprint.
    rlb = np.maximum(rt.min(axis=1) - index.face_long[ff] / _SQRT3, 0.0)
    ubf = np.where(rlb <= Rc, ht.max(axis=1) - _zlow(cutter, np.minimum(rlb, Rc)), -np.inf)
    xin = np.maximum(rt - R, 0.0)
    strict = xin < r * (1.0 - 1e-9)
    slope = xin / np.sqrt(np.where(strict, r * r - xin * xin, 1.0))
    e_r = wt / np.where(rt > 0.0, rt, 1.0)[..., None]
    grad = aa[:, None, :] - (slope[..., None] * e_r)                # (M,3,3) gradient of s at vertices
    sv = ht - _zlow(cutter, np.minimum(rt, Rc))
    tang = sv[:, :, None] + np.einsum("mik,mijk->mij", grad, tri[:, None, :, :] - tri[:, :, None, :])
    tang_ub = np.where(strict & (rt <= Rc), tang.max(axis=2), np.inf).min(axis=1)
    ubf = np.minimum(ubf, tang_ub)
    k = ubf > S[fp] + _PRUNE_TOL
    fp, ff, pp, aa, tri = fp[k], ff[k], pp[k], aa[k], tri[k]
    if len(fp) == 0:
        return S, C, NF

    # Facet test (closed form): the plane, oriented so n.A > 0, touches the offset disc where
    # CL = CC + r n + R u - r A (METHODS.md section 1); accept if CC lies in the triangle.
    n = index.face_normals[ff]
    na = _dot(n, aa)
    n = np.where((na < 0.0)[:, None], -n, n)
    na = np.abs(na)
    ok = index.face_valid[ff] & (na > 1e-12)
    wn = n - na[:, None] * aa
    wl = np.sqrt(_dot(wn, wn))
    u = wn / np.where(wl > 1e-12, wl, np.inf)[:, None]
    s_f = (r + R * wl - r * na - _dot(n, pp - tri[:, 0])) / np.where(ok, na, 1.0)
    cc = pp + s_f[:, None] * aa - r * n - R * u + r * aa
    ok &= _inside_triangle(cc, tri[:, 0], tri[:, 1], tri[:, 2])
    # a facet wins a tie with a vertex: on a face contact (a plane across the axis) its contact
    # is the bottom's centre, the tip, as cc_to_cl takes it, where a vertex is any point under it
    _scatter_max(S, C, fp[ok], s_f[ok], cc[ok], NF, n[ok], tie=_TIE * (1.0 + float(np.max(np.abs(index.box)))))

    # Edge test: s(t) is concave on the part of the edge inside the footprint (linear height
    # minus a convex nondecreasing function of a convex rho): golden section on that interval.
    ep, ee = _unique_pairs(np.repeat(fp, 3), index.face_edges[ff].ravel(), len(E))
    pp, aa = p[ep], A[ep]
    pa = V[E[ee, 0]]
    d = V[E[ee, 1]] - pa
    ha, wa, _ = local(pa, pp, aa)
    hd = _dot(d, aa)
    wd = d - hd[:, None] * aa
    qa, qb, qc = _dot(wd, wd), 2.0 * _dot(wa, wd), _dot(wa, wa) - Rc * Rc
    disc = qb * qb - 4.0 * qa * qc
    feas = (qa > 0.0) & (disc >= 0.0)
    sq = np.sqrt(np.maximum(disc, 0.0))
    den = np.where(qa > 0.0, 2.0 * qa, 1.0)
    t0 = np.maximum((-qb - sq) / den, 0.0)
    t1 = np.minimum((-qb + sq) / den, 1.0)
    feas &= t0 <= t1
    tm = np.clip(-qb / den, t0, t1)
    rmin = np.sqrt(np.maximum(qa * tm * tm + qb * tm + qc + Rc * Rc, 0.0))
    ube = np.maximum(ha + t0 * hd, ha + t1 * hd) - _zlow(cutter, np.minimum(rmin, Rc))
    k = feas & (ube > S[ep] + _PRUNE_TOL)
    if np.any(k):
        ep, pa, d, pp, aa, t0, t1 = ep[k], pa[k], d[k], pp[k], aa[k], t0[k], t1[k]

        def negs(t):
            hh, _, rr = local(pa + t[:, None] * d, pp, aa)
            return -(hh - _zlow(cutter, np.minimum(rr, Rc)))

        iters = _golden_iters(float(np.max((t1 - t0) * np.sqrt(_dot(d, d)))))
        t, val = _golden_min(negs, t0, t1, iters)
        for tt in (t0, t1):
            vv = negs(tt)
            better = vv < val
            t, val = np.where(better, tt, t), np.where(better, vv, val)
        _scatter_max(S, C, ep, -val, pa + t[:, None] * d, NF)
    return S, C, NF


def axial_drop(mesh_or_index: MeshIndex | trimesh.Trimesh, cutter: ToroidalCutter, points: np.ndarray,
               axis: np.ndarray) -> Drop:
    """Drop-cutter along a tool axis: the lowest tip ``cl = p + s * axis`` at which the cutter
    touches the mesh, for each point ``p``.

    ``s`` is the maximum over mesh elements inside the cutter's footprint cylinder (radius
    R + r around the line p + t axis) of the contact parameter: vertices (closed form
    ``s = (v - p).axis - zlow(rho)`` with the lower envelope zlow of the torus / flat bottom),
    facets (closed form: the plane touching the offset disc, contact inside the triangle) and
    edges (``s`` is concave along an edge: golden section).  This is the classic 3-axis
    drop-cutter with the axis free.

    Assumptions: the cutter comes from +infinity along ``axis``, so the result is the position
    where it first touches the mesh (mesh above ``p`` counts).  Only the cutting end (torus and
    flat bottom) can touch: any mesh point inside the footprint meets the lower envelope first,
    and the shank, whose wall is the footprint boundary, is never hit from below.  The holder is
    ignored.  Face orientation is not used.

    Parameters
    ----------
    mesh_or_index : trimesh.Trimesh or MeshIndex, mm.
    points : (N, 3) points on the drop lines, mm.
    axis : (3,) common tool axis (fast path: a cached projected 2-D tree) or (N, 3) per point;
        normalised here.

    Returns Drop (cl, contact, contact_normal, hit); rows where the line misses are NaN.
    """
    idx = _as_index(mesh_or_index)
    ax = np.asarray(axis, dtype=float)
    fixed = ax.shape == (3,)
    p, A = _poses(points, ax, "points")
    N = len(p)
    S = np.full(N, -np.inf)
    C = np.full((N, 3), np.nan)
    NF = np.full((N, 3), np.nan)
    for lo in range(0, N, _CHUNK):
        sl = slice(lo, min(lo + _CHUNK, N))
        S[sl], C[sl], NF[sl] = _drop_chunk(idx, cutter, p[sl], A[sl], fixed)
    hit = np.isfinite(S)
    cl = np.where(hit[:, None], p + np.where(hit, S, 0.0)[:, None] * A, np.nan)
    C = np.where(hit[:, None], C, np.nan)
    # Cutter normal at the contact: from the contact toward the nearest point of the core disc
    # (radius R at height r): r n = core point - contact.
    q = C - cl
    hq = _dot(q, A)
    wq = q - hq[:, None] * A
    rq = np.sqrt(_dot(wq, wq))
    core = cl + cutter.r * A + (np.minimum(rq, cutter.R) / np.where(rq > 0.0, rq, 1.0))[:, None] * wq
    nrm = core - C
    ln = np.linalg.norm(nrm, axis=1)
    normal = np.where(hit[:, None], nrm / np.where(ln > 0.0, ln, 1.0)[:, None], np.nan)
    # Face contact (the contact on the flat bottom, inside its rim): the bottom's normal, the axis.
    scale = 1.0 + float(np.max(np.abs(idx.box)))
    face = hit & (np.abs(hq) <= 1e-9 * scale) & (rq < cutter.R * (1.0 - 1e-9))
    normal[face] = A[face]
    if cutter.r == 0.0:
        rim = hit & ~face
        if np.any(rim):
            normal[rim] = _rim_normals(idx, C[rim], A[rim], wq[rim] / rq[rim, None], NF[rim])
    return Drop(cl=cl, contact=C, contact_normal=normal, hit=hit)


def _rim_normals(index: MeshIndex, contact: np.ndarray, A: np.ndarray, e: np.ndarray,
                 facet: np.ndarray) -> np.ndarray:
    """Contact normals (n of cc_to_cl) where a flat end's sharp rim touches (unit radial
    direction ``e`` of the contact from the axis): the tool's normals there form the cone
    a A - b e (a, b >= 0) and any of them places the tool right (CL = CC - R e); the one closest
    to the part's normal is taken: the facet's for a facet contact, else the mean of the face
    normals round the vertex nearest the contact, projected onto the cone, with b >= 1e-6 a so
    that the contact stays on the rim (a part normal along the axis there is a face contact tied
    with the rim)."""
    m = facet.copy()
    need = np.flatnonzero(~np.all(np.isfinite(m), axis=1))
    if len(need):  # a vertex or an edge: the mean of the faces' normals round the nearest vertex
        _, v = index.tree.query(contact[need])
        owner, face = _csr_expand(index.vf_ptr, index.vf_faces, np.arange(len(need)), np.asarray(v, np.intp))
        fn = index.face_normals[face]
        fn = np.where((_dot(fn, A[need][owner]) < 0.0)[:, None], -fn, fn)
        acc = np.zeros((len(need), 3))
        np.add.at(acc, owner, fn)
        m[need] = acc
    a = _dot(m, A)
    m = np.where((a < 0.0)[:, None], -m, m)
    a = np.abs(a)
    b = np.maximum(-_dot(m, e), 0.0)
    a = np.where(a + b > 0.0, a, 1.0)
    b = np.maximum(b, 1e-6 * a)
    n = a[:, None] * A - b[:, None] * e
    return n / np.linalg.norm(n, axis=1, keepdims=True)
