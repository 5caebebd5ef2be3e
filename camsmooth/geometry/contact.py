"""Where a cutter-location pose touches the mesh: CL -> CC with the surface.

A CAM system's CL pose (tool tip and axis, workpiece frame, mm) places the tool tangent to the
part at one point. The exact clearance (camsmooth.geometry.clearance) finds the mesh point
nearest the tool solid, its *witness*; when the pose touches (|clearance| <= tolerance) that is
the cutter-contact point, and the surface normal there is the clearance's ``normal``, the
tool's outward normal at the contact, -grad sd_tool(witness) (at a tangent contact the part's and
the tool's normals coincide, and on a mesh edge or vertex the tool's normal is the one the
CC -> CL formula of METHODS section 1 needs). With these, ``cc_to_cl(cutter, cc, n, T)`` gives the pose back (tested).

Where the flat bottom touches (n parallel to T) every point of the contact disc is a contact;
the CC -> CL formula then puts the tip on the contact (CL = CC), so the tip is taken as the CC
point when it lies on the mesh within the tolerance. Poses that do not touch (air moves,
lead-ins) or that gouge beyond the tolerance are flagged, with their clearance.

The same holds for every cutter of the toroid family. A ball end touches at one point of its
sphere. A flat end (r = 0) touches with its sharp bottom rim, where the tool's normals form a
cone (from the axis to the radial direction); the clearance's normal lies in that cone (a facet's
normal for a facet contact, the direction toward the tool for a vertex or an edge) and every
normal of the cone gives the same CL (CL = CC + R u, u the unit radial direction from the contact
toward the axis); a flat end standing on a plane along its normal (a facing program) is the face
contact above.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from camsmooth.geometry.clearance import MeshIndex, clearance
from camsmooth.geometry.cutter import ToroidalCutter

__all__ = ["Contacts", "contacts", "interpolated_normals"]

PARALLEL = 1e-9  # 1 - n.T below this: the flat bottom touches


@dataclass(frozen=True)
class Contacts:
    """Contacts of N poses. points: (N, 3) contact points (mm; the witness where not touching);
    normals: (N, 3) unit surface normals at the contact, from the material toward the tool;
    clearance: (N,) the pose's clearance (mm, negative = gouge); touching: (N,) |clearance| <=
    the tolerance. Workpiece frame."""

    points: np.ndarray
    normals: np.ndarray
    clearance: np.ndarray
    touching: np.ndarray


def contacts(index: MeshIndex, cutter: ToroidalCutter, tips: np.ndarray, axes: np.ndarray,
             tolerance: float) -> Contacts:
    """Contact points and normals of CL poses (tips (N, 3) mm, unit axes (N, 3) tip -> spindle,
    workpiece frame) on the mesh (module docstring)."""
    tips = np.asarray(tips, float)
    axes = np.asarray(axes, float)
    axes = axes / np.linalg.norm(axes, axis=1, keepdims=True)
    c = clearance(index, cutter, tips, axes)
    w = np.where(np.isfinite(c.witness), c.witness, tips)
    n = np.where(np.isfinite(c.normal), c.normal, axes)
    flat = 1.0 - np.sum(n * axes, axis=1) < PARALLEL
    if flat.any():  # the flat bottom: CL = CC where the tip lies on the mesh
        d_tip = _tip_gap(index, tips[flat], axes[flat])
        on = np.abs(d_tip) <= tolerance
        k = np.flatnonzero(flat)[on]
        w[k], n[k] = tips[k], axes[k]
    touching = np.abs(c.delta) <= tolerance
    return Contacts(points=w, normals=n, clearance=c.delta, touching=touching)


def _tip_gap(index: MeshIndex, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """Distance (mm) from each tip to the closest point of the mesh (trimesh.proximity)."""
    mesh = trimesh.Trimesh(index.vertices, index.faces, process=False)
    _, d, _ = trimesh.proximity.closest_point(mesh, tips)
    return d


def interpolated_normals(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    """Unit normals (N, 3) at points on the mesh, interpolated over the closest face from its
    vertex normals (barycentric weights; Phong-style): continuous across edges, where the facet
    normals jump by the dihedral angle. The vertex normals are the mesh's own (a PLY may carry the
    exact ones) or trimesh's area-weighted average of the faces around each vertex."""
    _, _, face = trimesh.proximity.closest_point(mesh, points)
    tri = mesh.triangles[face]
    w = trimesh.triangles.points_to_barycentric(tri, points)
    w = np.clip(w, 0.0, None)
    w /= np.maximum(w.sum(axis=1, keepdims=True), 1e-300)
    vn = np.asarray(mesh.vertex_normals)[mesh.faces[face]]
    n = np.einsum("nk,nkj->nj", w, vn)
    return n / np.linalg.norm(n, axis=1, keepdims=True)
