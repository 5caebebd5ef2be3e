"""Every cutter of the toroid family (issue 30, item 2): ball end (R = 0) and flat end (r = 0)
against closed forms written here (a ball and a flat end on a plane, a sphere, a bowl and a
cylinder), OpenCAMLib's drop-cutter (BallCutter / CylCutter / BullCutter on the same triangles) as
an independent oracle for the axial drop and `camsmooth path --raster`, the exact clearance of a
flat end against brute force on a mesh, the lead floor of a flat end in a trough (sin(lead) = R /
rho), the readers (TLDATA/MILL,D,0 and CUTTER/D), and an NX-style CLSF with TLDATA/MILL,10,0
smoothed end to end on the shipped dome, checked against the dome's exact surface."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from camsmooth.cli.main import main
from camsmooth.errors import InputError
from camsmooth.geometry.accessibility import accessibility_map
from camsmooth.geometry.clearance import MeshIndex, axial_drop, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl, cl_to_cc
from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames
from camsmooth.geometry.surfaces import Cylinder, tessellate_to_tolerance
from camsmooth.io.ccpath import read_cc_csv
from camsmooth.io.result_csv import read_result_csv
from camsmooth.post import load_program
from camsmooth.smoothing.cam import cutter_of
from camsmooth.smoothing.orientation import min_gouge_free_lead

ROOT = Path(__file__).resolve().parents[1]
Z = np.array([0.0, 0.0, 1.0])
FLAT = ToroidalCutter(R=5.0, r=0.0)      # D10 flat end
BALL = ToroidalCutter(R=0.0, r=3.0)      # D6 ball end
BULL = ToroidalCutter(R=2.0, r=3.0)      # D10 r3 bull nose
RS = 20.0                                # sphere / bowl radius (mm)


# ---------------------------------------------------------------------------------------------
# independent oracles written here

def _sd_tool(cutter: ToroidalCutter, tip: np.ndarray, T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Signed distance (mm) of points p (..., 3) to a flat end (the solid cylinder of radius R from
    the tip to tip + L T) or a ball end (the capsule of radius r round the segment from tip + r T
    to tip + (L - r) T), from the definitions."""
    L = float(cutter.shank_length)
    q = p - tip
    a = q @ T
    if cutter.r == 0.0:
        rho = np.linalg.norm(q - a[..., None] * T, axis=-1)
        dr, dz = rho - cutter.R, np.maximum(-a, a - L)
        return np.where((dr > 0) | (dz > 0), np.hypot(np.maximum(dr, 0), np.maximum(dz, 0)), np.maximum(dr, dz))
    assert cutter.R == 0.0
    s = np.clip(a, cutter.r, L - cutter.r)
    return np.linalg.norm(q - s[..., None] * T, axis=-1) - cutter.r


_OCL_SURFS: dict = {}  # the OpenCAMLib surfaces built so far, by the triangles' bytes


def _ocl_drop(mesh: trimesh.Trimesh, cutter: ToroidalCutter, xy: np.ndarray) -> np.ndarray:
    """OpenCAMLib's batch drop-cutter (z of the tip) on the mesh's triangles at the points xy."""
    ocl = pytest.importorskip("opencamlib")
    key = np.asarray(mesh.triangles, float).tobytes()
    surf = _OCL_SURFS.get(key)
    if surf is None:
        surf = _OCL_SURFS[key] = ocl.STLSurf()
        for tri in np.asarray(mesh.triangles, float):
            surf.addTriangle(ocl.Triangle(*[ocl.Point(*map(float, v)) for v in tri]))
    d = 2.0 * cutter.radius
    tool = (ocl.CylCutter(d, 50.0) if cutter.kind == "flat" else ocl.BallCutter(d, 50.0) if cutter.kind == "ball"
            else ocl.BullCutter(d, cutter.r, 50.0))
    bdc = ocl.BatchDropCutter()
    bdc.setSTL(surf)
    bdc.setCutter(tool)
    for x, y in xy:
        bdc.appendPoint(ocl.CLPoint(float(x), float(y), -1e3))
    bdc.run()
    pts = bdc.getCLPoints()
    got = np.array([[p.x, p.y, p.z] for p in pts])
    np.testing.assert_allclose(got[:, :2], xy, atol=1e-9)  # the batch keeps the order
    return got[:, 2]


def _icosphere() -> trimesh.Trimesh:
    return trimesh.creation.icosphere(subdivisions=5, radius=RS)


#: chord error of the icosphere (0.7 mm edges): RS minus the least distance of a face's plane
#: from the centre (the deepest point of a face below the sphere), about 5.5e-3 mm
CHORD = RS - float(np.min(np.abs(np.sum(_icosphere().face_normals * _icosphere().triangles[:, 0], axis=1))))


def _sphere(lower: bool) -> trimesh.Trimesh:
    """The icosphere's upper half (a dome) or lower half (a bowl)."""
    s = _icosphere()
    keep = s.triangles_center[:, 2] < 0 if lower else s.triangles_center[:, 2] > 0
    return s.submesh([np.flatnonzero(keep)], append=True)


def _wavy(step: float = 0.5) -> trimesh.Trimesh:
    """Grid mesh of z = 2 sin(x / 5) cos(y / 7) on [-15, 15]^2."""
    g = np.arange(-15.0, 15.0 + 1e-9, step)
    X, Y = np.meshgrid(g, g, indexing="ij")
    V = np.column_stack([X.ravel(), Y.ravel(), (2 * np.sin(X / 5) * np.cos(Y / 7)).ravel()])
    n = len(g)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1), indexing="ij")
    a = (i * n + j).ravel()
    F = np.concatenate([np.column_stack([a, a + n, a + n + 1]), np.column_stack([a, a + n + 1, a + 1])])
    return trimesh.Trimesh(V, F, process=False)


def _check_contacts(mesh: trimesh.Trimesh, cutter: ToroidalCutter, drop) -> None:
    """The drop's contacts lie on the mesh; off the flat bottom the contact and its normal give the
    pose back (CC -> CL); on it (face contact, normal = axis) the contact is at the tip's height
    within the bottom's radius (the tip itself where the facet under the tip touches)."""
    h = drop.hit
    _, dist, _ = trimesh.proximity.closest_point(mesh, drop.contact[h])
    assert np.all(dist < 1e-9)
    face = drop.contact_normal[h] @ Z > 1.0 - 1e-12
    c, n, cl = drop.contact[h], drop.contact_normal[h], drop.cl[h]
    np.testing.assert_allclose(cc_to_cl(cutter, c[~face], n[~face], Z), cl[~face], atol=1e-9)
    assert np.all(np.abs(c[face, 2] - cl[face, 2]) < 1e-9)
    assert np.all(np.linalg.norm(c[face, :2] - cl[face, :2], axis=1) <= cutter.R + 1e-9)


# ---------------------------------------------------------------------------------------------
# the family

def test_family_kinds_and_the_empty_cutter():
    assert (FLAT.kind, BALL.kind, BULL.kind) == ("flat", "ball", "bull")
    assert FLAT.radius == 5.0 and FLAT.core_height == FLAT.shank_length == 20.0
    with pytest.raises(InputError, match="R \\+ r must be > 0"):
        ToroidalCutter(R=0.0, r=0.0)
    with pytest.raises(InputError, match="corner radius r must be >= 0"):
        ToroidalCutter(R=5.0, r=-0.1)


@pytest.mark.parametrize("lead_deg", [0.0, 3.0, 11.0, 35.0])
def test_flat_end_on_a_plane_touches_with_its_lowest_rim_point(lead_deg):
    """CC on the plane z = 0, lead about y: the tip is CC - R (cos lead, 0, -sin lead) (the rim
    point lowest along n is on the leading side); lead 0 is the face contact, tip = CC. Checked
    also by sampling the rim (the lowest sample is the CC, within the sampling's R dphi^2 / 2)."""
    th = np.radians(lead_deg)
    T = np.array([np.sin(th), 0.0, np.cos(th)])
    cc = np.array([[3.0, -2.0, 0.0]])
    tip = cc_to_cl(FLAT, cc, Z, T)[0]
    want = cc[0] - (FLAT.R * np.array([np.cos(th), 0.0, -np.sin(th)]) if lead_deg > 0 else 0.0)
    np.testing.assert_allclose(tip, want, atol=1e-12)
    np.testing.assert_allclose(cl_to_cc(FLAT, tip[None], Z, T)[0], cc[0], atol=1e-12)
    if lead_deg > 0:
        e1 = np.array([np.cos(th), 0.0, -np.sin(th)])
        phi = np.linspace(0.0, 2 * np.pi, 3600, endpoint=False)
        rim = tip + FLAT.R * (np.cos(phi)[:, None] * e1 + np.sin(phi)[:, None] * np.array([0.0, 1.0, 0.0]))
        low = rim[np.argmin(rim[:, 2])]
        assert abs(low[2]) < 1e-12 and np.linalg.norm(low - cc[0]) < FLAT.R * (2 * np.pi / 3600) ** 2
    # the pose touches a plane mesh: clearance 0, witness the CC
    plane = trimesh.Trimesh([[-40, -40, 0], [40, -40, 0], [40, 40, 0], [-40, 40, 0]], [[0, 1, 2], [0, 2, 3]])
    c = clearance(plane, FLAT, tip[None], T)
    assert abs(c.delta[0]) < 1e-12
    if lead_deg > 0:
        np.testing.assert_allclose(c.witness[0], cc[0], atol=1e-9)
    else:  # face contact: the drop's contact is the tip (the facet under it wins the tie), normal the axis
        drop = axial_drop(plane, FLAT, np.array([[3.0, -2.0, 10.0], [7.3, 1.1, 10.0], [-20.0, 30.0, 5.0]]), Z)
        np.testing.assert_allclose(drop.contact, drop.cl, atol=1e-12)
        np.testing.assert_allclose(drop.cl[:, 2], 0.0, atol=1e-12)
        np.testing.assert_allclose(drop.contact_normal, np.tile(Z, (3, 1)), atol=1e-12)


def test_contacts_of_flat_end_poses_on_a_tilted_plane():
    """CL poses of a flat end on the plane z = x tan(12 deg) (as a CL program gives them): along the
    normal (a facing program, face contact) the contact is the tip itself; at a lead the rim's
    lowest point CC = tip + R u; both with the plane's normal, and CC -> CL gives the tips back."""
    from camsmooth.geometry.contact import contacts

    s = np.radians(12.0)
    n = np.array([-np.sin(s), 0.0, np.cos(s)])
    V = np.array([[x, y, x * np.tan(s)] for x, y in ((-40, -40), (60, -40), (60, 40), (-40, 40))], float)
    plane = MeshIndex(trimesh.Trimesh(V, [[0, 1, 2], [0, 2, 3]], process=False))
    cc = np.array([[x, y, x * np.tan(s)] for x, y in ((0.0, 0.0), (10.0, 3.0), (20.0, -7.0))])
    fr = local_frames(np.tile(n, (3, 1)), np.tile([np.cos(s), 0.0, np.sin(s)], (3, 1)))
    for lead in (0.0, 4.0, 15.0):
        T = axis_from_lead_tilt(np.full(3, np.radians(lead)), np.array([0.0, 0.3, -0.2]), fr)
        tips = cc_to_cl(FLAT, cc, np.tile(n, (3, 1)), T)
        c = contacts(plane, FLAT, tips, T, tolerance=1e-6)
        assert c.touching.all() and np.all(np.abs(c.clearance) < 1e-9)
        np.testing.assert_allclose(c.points, cc, atol=1e-9)
        np.testing.assert_allclose(c.normals, np.tile(n, (3, 1)), atol=1e-9)
        np.testing.assert_allclose(cc_to_cl(FLAT, c.points, c.normals, T), tips, atol=1e-9)
        if lead == 0.0:
            np.testing.assert_allclose(tips, cc, atol=1e-12)


def test_ball_end_centre_does_not_depend_on_the_axis():
    """A ball end touching a sphere of radius RS at CC = RS n: the ball's centre is (RS + r) n
    whatever the axis, the tip that centre - r T; the pose touches the sphere's mesh."""
    rng = np.random.default_rng(4)
    n = rng.normal(size=(40, 3))
    n[:, 2] = np.abs(n[:, 2]) + 0.5
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    T = n + 0.4 * rng.normal(size=(40, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    T[np.sum(T * n, axis=1) < 0] *= -1
    tip = cc_to_cl(BALL, RS * n, n, T)
    np.testing.assert_allclose(tip + BALL.r * T, (RS + BALL.r) * n, atol=1e-12)
    c = clearance(_icosphere(), BALL, tip, T)
    # the mesh lies inside the sphere by at most its chord error: 0 <= delta <= CHORD
    assert np.all(c.delta > -1e-9) and np.all(c.delta <= CHORD + 1e-9)


def test_drop_on_sphere_bowl_and_cylinder_closed_forms():
    """Axial drop (z) of the flat end and the ball end at horizontal offsets d from the axis of:
    a sphere (flat: RS for d <= R, face contact at the top, else sqrt(RS^2 - (d - R)^2); ball:
    sqrt((RS + r)^2 - d^2) - r), a bowl (flat: -sqrt(RS^2 - (d + R)^2); ball: -sqrt((RS - r)^2 -
    d^2) - r) and a cylinder about x (flat: sqrt(RC^2 - (d - R)^2) for d > R; ball:
    sqrt((RC + r)^2 - d^2) - r). The meshes' chord error bounds the difference."""
    d = np.array([0.0, 2.0, 4.9, 5.1, 7.0, 9.5, 12.0])
    xy = np.column_stack([d * np.cos(0.3), d * np.sin(0.3)])
    top, bowl = _sphere(False), _sphere(True)
    # (mesh, want z, horizontal radius of the contact on the sphere, side) per cutter
    cases = [(top, FLAT, np.where(d <= FLAT.R, RS, np.sqrt(RS ** 2 - np.maximum(d - FLAT.R, 0) ** 2)),
              np.maximum(d - FLAT.R, 0), -1),
             (top, BALL, np.sqrt((RS + BALL.r) ** 2 - d ** 2) - BALL.r, d * RS / (RS + BALL.r), -1),
             (bowl, FLAT, -np.sqrt(RS ** 2 - (d + FLAT.R) ** 2), d + FLAT.R, 1),
             (bowl, BALL, -np.sqrt((RS - BALL.r) ** 2 - d ** 2) - BALL.r, d * RS / (RS - BALL.r), 1)]
    for mesh, cut, want, rho_c, sign in cases:
        drop = axial_drop(mesh, cut, np.column_stack([xy, np.full(len(d), 50.0)]), Z)
        assert drop.hit.all()
        err = drop.cl[:, 2] - want
        # a convex mesh lies inside the sphere (drop lower), a bowl's chords above it (higher), by
        # at most the chord error along the sphere's normal at the contact, seen along z
        bound = CHORD / np.sqrt(1.0 - (rho_c / RS) ** 2)
        assert np.all(sign * err > -1e-9) and np.all(np.abs(err) <= bound + 1e-9), (cut.kind, err, bound)
        _check_contacts(mesh, cut, drop)
    RC = 15.0
    cyl = tessellate_to_tolerance(Cylinder(radius=RC, u_range=(-20.0, 20.0), v_range=(-20.0, 20.0)), 1e-3)
    y = np.array([5.5, 7.0, 10.0, 12.0])
    pts = np.column_stack([np.full(len(y), 1.3), y, np.full(len(y), 50.0)])
    for cut, want, rho_c in ((FLAT, np.sqrt(RC ** 2 - (y - FLAT.R) ** 2), y - FLAT.R),
                             (BALL, np.sqrt((RC + BALL.r) ** 2 - y ** 2) - BALL.r, y * RC / (RC + BALL.r))):
        drop = axial_drop(cyl, cut, pts, Z)
        err = drop.cl[:, 2] - want
        bound = 1e-3 / np.sqrt(1.0 - (rho_c / RC) ** 2)  # chord error 1e-3 mm at most, seen along z
        assert np.all(err < 1e-9) and np.all(np.abs(err) <= bound), (cut.kind, err)  # chords inside


@pytest.mark.parametrize("cutter", [FLAT, BALL, BULL], ids=lambda c: c.kind)
def test_axial_drop_against_opencamlib(cutter):
    """The drop of every kind on a wavy grid mesh and on a hemisphere equals OpenCAMLib's
    drop-cutter on the same triangles (independent code: its own vertex, facet and edge tests)."""
    rng = np.random.default_rng(7)
    for mesh in (_wavy(1.0), _sphere(False)):
        lo, hi = mesh.bounds[0, :2] - 3.0, mesh.bounds[1, :2] + 3.0
        xy = rng.uniform(lo, hi, size=(100, 2))
        want = _ocl_drop(mesh, cutter, xy)
        drop = axial_drop(mesh, cutter, np.column_stack([xy, np.full(len(xy), 100.0)]), Z)
        hit = want > -1e2
        np.testing.assert_array_equal(drop.hit, hit)
        np.testing.assert_allclose(drop.cl[hit, 2], want[hit], atol=1e-6)
        _check_contacts(mesh, cutter, drop)


def test_path_raster_with_a_flat_end_against_opencamlib(tmp_path):
    """`camsmooth path --raster` with --corner-radius 0: the CL of every written CC point (CC ->
    CL with its normal) is OpenCAMLib's drop at the same x, y."""
    mesh = _wavy(1.0)
    mesh.export(tmp_path / "wavy.stl")
    args = ["path", "--surface", str(tmp_path / "wavy.stl"), "--raster", "--cutter-radius", "5", "--stepover", "2",
            "--spacing", "1", "--quiet", "--corner-radius"]
    rc = main(args + ["0", "-o", str(tmp_path / "cc.csv")])
    assert rc == 0
    cc = read_cc_csv(tmp_path / "cc.csv")
    print(len(cc.points))
    assert len(cc.points) > 300
    cl = cc_to_cl(FLAT, cc.points, cc.normals, Z)
    want = _ocl_drop(mesh, FLAT, cl[:, :2])
    # the CSV's 6-decimal CC points and normals: CL within 1e-4 mm
    np.testing.assert_allclose(cl[:, 2], want, atol=1e-4)
    assert main(args + ["-1", "-o", str(tmp_path / "x.csv")]) == 2


@pytest.mark.parametrize("cutter", [ToroidalCutter(R=5.0, r=0.0, shank_length=8.0),
                                    ToroidalCutter(R=0.0, r=3.0, shank_length=8.0)], ids=lambda c: c.kind)
def test_clearance_against_brute_force(cutter):
    """Exact clearance of random poses (touching, gouging and clear, axes up to 40 deg off z) on
    the wavy mesh against the minimum of the signed distance written here over a dense sampling of
    all the triangles (spacing h): delta <= brute <= delta + h, and delta is attained at the
    witness."""
    mesh = _wavy(1.0)
    rng = np.random.default_rng(11)
    m = 16
    xy = rng.uniform(-9, 9, size=(m, 2))
    tip = np.column_stack([xy, 2 * np.sin(xy[:, 0] / 5) * np.cos(xy[:, 1] / 7) + rng.uniform(-1.0, 4.0, m)])
    T = np.column_stack([rng.normal(size=(m, 2)) * 0.3, np.ones(m)])
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    c = clearance(mesh, cutter, tip, T, margin=50.0)
    k = 12  # barycentric subdivisions per edge (1.41 mm long at most): samples within h of every point
    u, v = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
    keep = (u + v) <= k
    w = np.column_stack([u[keep], v[keep]]) / k
    tri = np.asarray(mesh.triangles)
    pts = tri[:, 0, None] + w[None, :, :1] * (tri[:, 1] - tri[:, 0])[:, None] + w[None, :, 1:] * (
        tri[:, 2] - tri[:, 0])[:, None]
    pts = pts.reshape(-1, 3)
    h = np.sqrt(2.0) / k
    assert not c.capped.any()
    for i in range(m):
        brute = _sd_tool(cutter, tip[i], T[i], pts).min()
        assert c.delta[i] <= brute + 1e-9 and brute <= c.delta[i] + h, (i, c.delta[i], brute)
        assert abs(_sd_tool(cutter, tip[i], T[i], c.witness[i]) - c.delta[i]) < 1e-9
    assert np.sum(c.delta < -0.1) >= 3 and np.sum(c.delta > 0.1) >= 3, c.delta  # gouging and clear poses both


def test_flat_end_lead_floor_in_a_trough():
    """A trough curving along the feed (a concave cylinder of radius rho, axis Y_L): a flat end
    touching its bottom clears it iff its bottom's chord 2R fits the arc's chord 2 rho sin(lead):
    lead >= asin(R / rho) (the heel); a ball end (r < rho) clears it at every lead (no floor)."""
    rho = 20.0
    s = Cylinder(radius=rho, u_range=(-15.0, 15.0), v_range=(-16.0, 16.0), axis=(0.0, 1.0, 0.0),
                 center=(0.0, 0.0, rho), concave=True)
    idx = MeshIndex(tessellate_to_tolerance(s, 1e-4))
    fr = local_frames(Z[None], np.array([[1.0, 0.0, 0.0]]))
    window = np.radians([[1.0, 30.0]])
    flat = ToroidalCutter(R=5.0, r=0.0, shank_length=12.0)
    amap = accessibility_map(idx, flat, np.zeros((1, 3)), Z[None], fr, window, np.zeros((1, 2)), 1e-4,
                             n_lead=9, n_tilt=1, refine=12)
    assert amap.floor_active[0, 0] and not amap.ceiling_active[0, 0]
    assert abs(amap.floor[0, 0] - np.arcsin(5.0 / rho)) < np.radians(0.05), np.degrees(amap.floor[0, 0])
    ball = ToroidalCutter(R=0.0, r=5.0, shank_length=12.0)
    bmap = accessibility_map(idx, ball, np.zeros((1, 3)), Z[None], fr, window, np.zeros((1, 2)), 1e-4, n_lead=9,
                             n_tilt=1)
    assert np.all(bmap.delta >= -1e-4) and not bmap.floor_active[0, 0]
    # the local (curvature) floor across the feed, sin(lead) = R k for a flat end, none for a ball
    K = np.array([[0.0, 0.0], [0.0, 1.0 / rho]])  # concave across the feed
    lead = min_gouge_free_lead(5.0, 0.0, K, np.array(0.0), np.radians(80.0), margin=0.0)
    assert abs(lead - np.arcsin(5.0 / rho)) < 1e-12
    assert min_gouge_free_lead(0.0, 5.0, K, np.array(0.0), np.radians(80.0)) == 0.0


# ---------------------------------------------------------------------------------------------
# readers and the program end to end

@pytest.mark.parametrize("record, kind, R, r", [
    ("TLDATA/MILL,10.0000,0.0000,50.0000,0.0000,0.0000", "flat", 5.0, 0.0),
    ("TLDATA/MILL,10,0", "flat", 5.0, 0.0),
    ("TLDATA/MILL,10.0000,5.0000,50.0000,0.0000,0.0000", "ball", 0.0, 5.0),
    ("CUTTER/10", "flat", 5.0, 0.0),
    ("CUTTER/10,5", "ball", 0.0, 5.0),
    ("CUTTER/10,1", "bull", 4.0, 1.0),
])
def test_readers_give_every_kind(tmp_path, record, kind, R, r):
    text = "\n".join(["TOOL PATH/PLANAR_MILL,TOOL,T1", record, "FEDRAT/MMPM,1000.0000",
                      "GOTO/0.0000,0.0000,1.0000,0.0000000,0.0000000,1.0000000",
                      "GOTO/5.0000,0.0000,1.0000", "GOTO/10.0000,0.0000,1.0000", "END-OF-PATH"]) + "\n"
    (tmp_path / "p.cls").write_text(text)
    cut = cutter_of(load_program(tmp_path / "p.cls"))
    assert (cut.kind, cut.R, cut.r) == (kind, R, r)


def _nx_clsf(tips: np.ndarray, axes: np.ndarray, rows: list[slice]) -> str:
    """NX CLSF text as NX writes a flat-end finishing operation (TOOL PATH, TLDATA/MILL with a 0
    corner radius, MSYS, PAINT, rapids between rows, 4 and 7 decimals)."""
    lines = ["TOOL PATH/VARIABLE_CONTOUR,TOOL,FLAT_D10", "TLDATA/MILL,10.0000,0.0000,50.0000,0.0000,0.0000",
             "MSYS/0.0000,0.0000,0.0000,1.0000000,0.0000000,0.0000000,0.0000000,1.0000000,0.0000000",
             "$$ centerline data", "PAINT/PATH", "PAINT/SPEED,10", "LOAD/TOOL,1", "FEDRAT/MMPM,2000.0000"]
    for sl in rows:
        p, a = tips[sl], axes[sl]
        up = p[0] + 10.0 * a[0]
        lines += ["RAPID", f"GOTO/{up[0]:.4f},{up[1]:.4f},{up[2]:.4f},{a[0, 0]:.7f},{a[0, 1]:.7f},{a[0, 2]:.7f}"]
        lines += [f"GOTO/{x[0]:.4f},{x[1]:.4f},{x[2]:.4f},{t[0]:.7f},{t[1]:.7f},{t[2]:.7f}"
                  for x, t in zip(p, a, strict=True)]
        away = p[-1] + 10.0 * a[-1]
        lines += ["RAPID", f"GOTO/{away[0]:.4f},{away[1]:.4f},{away[2]:.4f}"]
    return "\n".join(lines + ["PAINT/SPEED,10", "END-OF-PATH"]) + "\n"


def _dome_sd_min(tip: np.ndarray, T: np.ndarray, cutter: ToroidalCutter) -> float:
    """Minimum of the tool's signed distance over the dome's exact surface z = 10 - (x^2 + y^2)
    / 200 on [-30, 30]^2 (surfaces/dome.toml) near the tool: a 0.1 mm grid, then a 1 um grid about
    its best."""
    def sd_on(x, y):
        p = np.stack([x, y, 10.0 - (x * x + y * y) / 200.0], -1)
        on_part = (np.abs(x) <= 30.0) & (np.abs(y) <= 30.0)  # u_range, v_range of surfaces/dome.toml
        return np.where(on_part, _sd_tool(cutter, tip, T, p), np.inf)

    reach = cutter.radius + float(cutter.shank_length) * np.linalg.norm(T[:2]) + 1.0
    g = np.arange(-reach, reach, 0.1)
    X, Y = np.meshgrid(tip[0] + g, tip[1] + g, indexing="ij")
    s = sd_on(X, Y)
    i = np.unravel_index(np.argmin(s), s.shape)
    f = np.arange(-0.11, 0.11, 0.001)
    X, Y = np.meshgrid(X[i] + f, Y[i] + f, indexing="ij")
    return float(min(s.min(), sd_on(X, Y).min()))


def test_nx_flat_end_program_smoothed_on_the_dome(tmp_path, capsys):
    """An NX CLSF with TLDATA/MILL,10,0 (two rows of the dome sample at a constant lead of 11 deg,
    the tip on the rim's lowest point) smoothed end to end: every nlp pose clears the mesh
    (its delta) and the dome's exact surface (sampled here) within the 0.005 mm tolerance."""
    path = read_cc_csv(ROOT / "surfaces" / "dome_path.csv")
    k = np.isin(path.rows, [13, 14])
    pts, nrm, rows = path.points[k], path.normals[k], path.rows[k]
    fr = local_frames(nrm, path.feed_dirs_or_estimate()[k])
    T = axis_from_lead_tilt(np.full(len(pts), np.radians(11.0)), np.zeros(len(pts)), fr)
    tips = cc_to_cl(FLAT, pts, nrm, T)
    slices = [slice(0, int(np.sum(rows == 13))), slice(int(np.sum(rows == 13)), len(pts))]
    (tmp_path / "flat.cls").write_text(_nx_clsf(tips, T, slices))
    rc = main(["smooth", str(tmp_path / "flat.cls"), "--surface", str(ROOT / "surfaces" / "dome.stl"),
               "--lead", "2:20", "--tilt", "-10:10", "--tolerance", "0.005", "-o", str(tmp_path / "out.csv")])
    text = capsys.readouterr()
    assert rc == 0, text.err
    assert any(line.startswith("cam ") for line in text.out.splitlines())  # the program as it came
    out = read_result_csv(tmp_path / "out.csv")
    assert len(out["x"]) == len(pts) and np.all(out["delta"] >= -0.005)
    cl = np.column_stack([out["clx"], out["cly"], out["clz"]])
    ax = np.column_stack([out["i"], out["j"], out["k"]])
    assert np.ptp(out["lead"]) > 1.0  # the smoothing moved the axes: not the program as it came
    worst = min(_dome_sd_min(cl[j], ax[j] / np.linalg.norm(ax[j]), FLAT) for j in range(0, len(cl), 8))
    # exact surface: within the tolerance plus the STL's chord error (4e-4 mm)
    assert worst >= -0.005 - 4e-4, worst
