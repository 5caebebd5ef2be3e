"""CL -> CC on the mesh (camsmooth.geometry.contact) against closed forms: poses built from known
contact points and normals with the CC -> CL formula (METHODS section 1) on a plane, a sphere and
a cylinder, recovered to 1e-6 mm and 1e-6 rad; a pose in the air and a gouging one are flagged."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from camsmooth.geometry.clearance import MeshIndex
from camsmooth.geometry.contact import contacts
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames

CUT = ToroidalCutter(R=3.0, r=1.5)


def _poses(cc: np.ndarray, n: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    f = np.cross(n, rng.normal(size=(len(n), 3)))
    fr = local_frames(n, f)
    T = axis_from_lead_tilt(rng.uniform(np.radians(3), np.radians(25), len(n)),
                            rng.uniform(np.radians(-20), np.radians(20), len(n)), fr)
    return cc_to_cl(CUT, cc, n, T), T


def _facet_points(mesh: trimesh.Trimesh, faces: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Random points well inside the given faces (barycentric weights >= 0.2)."""
    w = rng.dirichlet([4.0, 4.0, 4.0], len(faces))
    w = 0.2 + 0.4 * w
    w /= w.sum(axis=1, keepdims=True)
    return np.einsum("fk,fkj->fj", w, mesh.triangles[faces])


@pytest.mark.parametrize("shape", ["plane", "sphere", "cylinder"])
def test_cl_to_cc_recovers_contact_and_normal(shape):
    rng = np.random.default_rng(7)
    if shape == "plane":
        mesh = trimesh.Trimesh([[-50, -50, 2], [50, -50, 2], [50, 50, 2], [-50, 50, 2]], [[0, 1, 2], [0, 2, 3]])
        cc = np.column_stack([rng.uniform(-20, 20, 40), rng.uniform(-20, 20, 40), np.full(40, 2.0)])
        n = np.tile([0.0, 0.0, 1.0], (40, 1))
    else:
        # the exact geometry is the mesh itself: contacts inside facets, with the facet normal,
        # on the convex side (a concave side could touch elsewhere first)
        if shape == "sphere":
            mesh = trimesh.creation.icosphere(4, radius=40.0)
            up = np.flatnonzero((mesh.face_normals[:, 2] > 0.5) & (mesh.face_normals[:, 2] < 0.97))
        else:  # the side of a cylinder lying along x: long thin facets (80 x 0.74 mm)
            mesh = trimesh.creation.cylinder(radius=30.0, height=80.0, sections=256)
            mesh.apply_transform(trimesh.transformations.rotation_matrix(np.pi / 2, [0, 1, 0]))
            up = np.flatnonzero((np.abs(mesh.face_normals[:, 0]) < 1e-9) & (mesh.face_normals[:, 2] > 0.6))
        faces = rng.choice(up, 40, replace=False)
        cc = _facet_points(mesh, faces, rng)
        n = mesh.face_normals[faces]
    tips, T = _poses(cc, n, rng)
    got = contacts(MeshIndex(mesh), CUT, tips, T, tolerance=1e-4)
    assert got.touching.all()
    np.testing.assert_allclose(got.points, cc, atol=1e-6)
    ang = np.arccos(np.clip(np.sum(got.normals * n, axis=1), -1, 1))
    assert ang.max() < 1e-6
    np.testing.assert_allclose(cc_to_cl(CUT, got.points, got.normals, T), tips, atol=1e-6)


def test_air_and_gouging_poses_are_flagged_with_their_clearance():
    mesh = trimesh.Trimesh([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], [[0, 1, 2], [0, 2, 3]])
    T = np.tile([0.0, np.sin(0.2), np.cos(0.2)], (3, 1))
    cc = np.zeros((3, 3))
    tips = cc_to_cl(CUT, cc, np.tile([0.0, 0, 1], (3, 1)), T) + np.array([[0, 0, 0.0], [0, 0, 0.5], [0, 0, -0.3]])
    got = contacts(MeshIndex(mesh), CUT, tips, T, tolerance=1e-3)
    assert got.touching.tolist() == [True, False, False]
    np.testing.assert_allclose(got.clearance[1:], [0.5, -0.3], atol=1e-9)
