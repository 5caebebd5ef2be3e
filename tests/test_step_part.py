"""CAD parts (STEP / IGES) as workpiece surfaces: camsmooth.geometry.step, camsmooth.geometry.placement
and the --surface PART.step / --part-frame options.

The mesh is checked against the exact part by means independent of the code under test: closed
forms (a cylinder + hemisphere solid made with OCP), OCCT's own global point projection
(GeomAPI_ProjectPointOnSurf) at random points inside the triangles, and points sampled on the exact
faces by OCCT's face classifier (not by the parameter triangulation the measurement samples). The
public part is pythonocc-core's splinecage.stp (tests/data/step/SOURCES.md).
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

pytest.importorskip("OCP", reason="OpenCASCADE (pip install 'camsmooth[cad]') not installed")

from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace  # noqa: E402
from OCP.BRepPrimAPI import BRepPrimAPI_MakeBox, BRepPrimAPI_MakeCylinder, BRepPrimAPI_MakeSphere  # noqa: E402
from OCP.gp import gp_Ax2, gp_Dir, gp_Pnt  # noqa: E402
from OCP.Interface import Interface_Static  # noqa: E402
from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer  # noqa: E402

from camsmooth.cli.main import main  # noqa: E402
from camsmooth.errors import InputError  # noqa: E402
from camsmooth.geometry.placement import check_frame, place, rigid_transform  # noqa: E402
from camsmooth.geometry.surfaces import chord_deviation, load_surface  # noqa: E402

DATA = Path(__file__).parent / "data" / "step"
RNG = np.random.default_rng(30)


def _write_step(shape, path: Path, unit: int | None = None) -> Path:
    """STEP file of an OCP shape; unit: OCCT's write.step.unit (1 = inch) for this file only."""
    w = STEPControl_Writer()  # first: it sets the STEP parameters to their defaults
    old = Interface_Static.IVal_s("write.step.unit")
    if unit is not None:
        Interface_Static.SetIVal_s("write.step.unit", unit)
    try:
        w.Transfer(shape, STEPControl_AsIs)
        w.Write(str(path))
    finally:
        Interface_Static.SetIVal_s("write.step.unit", old)
    return path


def _cylinder_sphere() -> object:
    from OCP.BRepAlgoAPI import BRepAlgoAPI_Fuse

    cyl = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), 10.0, 30.0).Shape()
    sph = BRepPrimAPI_MakeSphere(gp_Pnt(0, 0, 30), 10.0).Shape()
    fuse = BRepAlgoAPI_Fuse(cyl, sph)
    fuse.Build()
    return fuse.Shape()


def _height(x, y):
    return 6.0 * np.sin(x / 17.0) * np.cos(y / 23.0) + 0.002 * x * y


def _freeform_face() -> object:
    """A bicubic B-spline face through z = _height(x, y) on [0, 100] x [0, 80] mm (OCCT's fit)."""
    from OCP.GeomAPI import GeomAPI_PointsToBSplineSurface
    from OCP.OCP.collections import Array2_gp_Pnt

    nx, ny = 21, 17
    arr = Array2_gp_Pnt(1, nx, 1, ny)
    for i, x in enumerate(np.linspace(0, 100, nx)):
        for j, y in enumerate(np.linspace(0, 80, ny)):
            arr.SetValue(i + 1, j + 1, gp_Pnt(float(x), float(y), float(_height(x, y))))
    surf = GeomAPI_PointsToBSplineSurface(arr, 3, 3).Surface()
    return BRepBuilderAPI_MakeFace(surf, 1e-6).Face()


def _inside_points(mesh: trimesh.Trimesh, per_face: int) -> np.ndarray:
    w = RNG.dirichlet([1.0, 1.0, 1.0], size=(len(mesh.faces), per_face))
    return np.einsum("fki,fij->fkj", w, mesh.triangles).reshape(-1, 3)


def _occ_distance(shape, points: np.ndarray) -> np.ndarray:
    """Distance of points to the faces of ``shape`` by OCCT's global projection on each face's surface
    (within the face's parameter bounds): an oracle independent of step.py's Gauss-Newton."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepTools import BRepTools
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    best = np.full(len(points), np.inf)
    ex = TopExp_Explorer(shape, TopAbs_FACE)
    while ex.More():
        face = TopoDS.Face(ex.Current())
        ex.Next()
        surf = BRep_Tool.Surface_s(face)
        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        for i, p in enumerate(points):
            proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, p)), surf, u0, u1, v0, v1)
            if proj.NbPoints():
                best[i] = min(best[i], proj.LowerDistance())
    return best


def _face_samples(shape, n_per_face: int) -> np.ndarray:
    """Points on the exact faces: random (u, v) in each face's bounds kept where OCCT's classifier
    says they are inside the trimmed face, mapped through the surface."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepClass import BRepClass_FaceClassifier
    from OCP.BRepTools import BRepTools
    from OCP.gp import gp_Pnt2d
    from OCP.TopAbs import TopAbs_FACE, TopAbs_IN
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    out = []
    ex = TopExp_Explorer(shape, TopAbs_FACE)
    while ex.More():
        face = TopoDS.Face(ex.Current())
        ex.Next()
        surf = BRep_Tool.Surface_s(face)
        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        for u, v in zip(RNG.uniform(u0, u1, n_per_face), RNG.uniform(v0, v1, n_per_face), strict=True):
            if BRepClass_FaceClassifier(face, gp_Pnt2d(u, v), 1e-9).State() == TopAbs_IN:
                out.append(surf.Value(u, v).Coord())
    return np.array(out)


def _mesh_distance(mesh: trimesh.Trimesh, points: np.ndarray) -> np.ndarray:
    return trimesh.proximity.closest_point(mesh, points)[1]


# ---------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def cylsph(tmp_path_factory):
    path = _write_step(_cylinder_sphere(), tmp_path_factory.mktemp("step") / "cylsph.step")
    return load_surface(path, chord_tol=0.005)


def test_cylinder_sphere_against_closed_form(cylsph):
    """Mesh of a cylinder (R 10, 0 <= z <= 30) capped by a hemisphere: every vertex on the exact
    surface, points inside the triangles and points on the exact surface within the measured
    deviation of each other, by the closed-form distances."""
    mesh, part = cylsph.mesh, cylsph.brep

    def dist(p):
        x, y, z = p.T
        r = np.hypot(x, y)
        d_cyl = np.where((z >= 0) & (z <= 30), np.abs(r - 10), np.inf)
        d_sph = np.where(z >= 30, np.abs(np.linalg.norm(p - [0, 0, 30], axis=1) - 10), np.inf)
        d_disk = np.where(r <= 10, np.abs(z), np.inf)
        return np.minimum(np.minimum(d_cyl, d_sph), d_disk)

    assert mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume > 0  # outward normals: out of the material
    assert dist(mesh.vertices).max() < 1e-7
    inside = dist(_inside_points(mesh, 6)).max()
    assert inside <= part.mesh_to_brep * (1 + 1e-6) + 1e-9  # the measurement bounds the true sag
    assert inside >= 0.6 * part.mesh_to_brep                 # and is not a loose over-estimate
    n = 6000
    th, z = RNG.uniform(0, 2 * np.pi, n), RNG.uniform(0, 30, n)
    v = RNG.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    v[:, 2] = np.abs(v[:, 2])
    exact = np.concatenate([np.c_[10 * np.cos(th), 10 * np.sin(th), z], 10 * v + [0, 0, 30]])
    assert _mesh_distance(mesh, exact).max() <= part.deviation * 1.05
    # well below the tolerance the chord was asked for (tolerance 0.025 mm -> deflection 0.005 mm)
    assert part.deviation <= 1.5 * 0.005
    assert chord_deviation(cylsph) == part.deviation
    # volume of the solid within the chord error times the area
    v_exact = np.pi * 100 * 30 + 2 / 3 * np.pi * 1000
    assert abs(mesh.volume - v_exact) <= part.deviation * mesh.area


def test_freeform_bspline_face_and_iges(tmp_path):
    """A bicubic B-spline face: OCCT's projection of points inside the triangles stays within the
    measured mesh->B-rep deviation; points on the exact face (classifier sampling) stay within the
    measured deviation of the mesh. The same face from IGES gives the same part."""
    face = _freeform_face()
    surf = load_surface(_write_step(face, tmp_path / "free.stp"), chord_tol=0.01)
    mesh, part = surf.mesh, surf.brep
    pts = _inside_points(mesh, 2)
    pts = pts[RNG.choice(len(pts), 800, replace=False)]
    oracle = _occ_distance(part.shape, pts)
    assert oracle.max() <= part.mesh_to_brep * (1 + 1e-6) + 1e-9
    assert oracle.max() >= 0.5 * part.mesh_to_brep
    samples = _face_samples(part.shape, 1000)
    assert len(samples) > 800
    assert _mesh_distance(mesh, samples).max() <= part.deviation * 1.05
    assert part.deviation <= 1.5 * 0.01
    lo, hi = mesh.bounds
    assert np.allclose([lo[0], lo[1], hi[0], hi[1]], [0, 0, 100, 80], atol=1e-6)

    from OCP.IGESControl import IGESControl_Writer

    w = IGESControl_Writer("MM", 0)
    w.AddShape(face)
    w.ComputeModel()
    assert w.Write(str(tmp_path / "free.igs"))
    iges = load_surface(tmp_path / "free.igs", chord_tol=0.01)
    assert np.allclose(iges.mesh.bounds, mesh.bounds, atol=1e-6)
    assert iges.brep.deviation <= 1.5 * 0.01


def test_public_freeform_part_splinecage():
    """pythonocc-core's splinecage.stp (Rhino B-spline patches, mm): measured both ways and
    checked with OCCT's projection and classifier samples."""
    surf = load_surface(DATA / "splinecage.stp", chord_tol=0.005)
    mesh, part = surf.mesh, surf.brep
    assert part.unit == "MILLIMETRE"
    assert len(mesh.faces) > 500 and mesh.is_winding_consistent
    pts = _inside_points(mesh, 1)
    pts = pts[RNG.choice(len(pts), 600, replace=False)]
    assert _occ_distance(part.shape, pts).max() <= part.mesh_to_brep * (1 + 1e-6) + 1e-9
    samples = _face_samples(part.shape, 300)
    assert _mesh_distance(mesh, samples).max() <= part.deviation * 1.05
    assert 0.001 < part.deviation <= 1.5 * 0.005
    # the patch with the z relief: z between the control net's extremes
    assert -2.6 < mesh.bounds[0][2] < 0 < mesh.bounds[1][2] < 1.3


def test_inch_step_is_read_in_mm(tmp_path):
    """A box of 10 x 20 x 30 mm written in inch: the file's numbers are inch (30 / 25.4), the part
    is 10 x 20 x 30 mm and the note names the unit."""
    path = _write_step(BRepPrimAPI_MakeBox(10.0, 20.0, 30.0).Shape(), tmp_path / "box_inch.step", unit=1)
    text = path.read_text()
    assert "CONVERSION_BASED_UNIT('INCH'" in text
    coords = [float(c) for pt in re.findall(r"CARTESIAN_POINT\('',\(([^)]*)\)", text) for c in pt.split(",")]
    assert max(coords) == pytest.approx(30 / 25.4, rel=1e-9)
    with pytest.warns(RuntimeWarning, match="length unit INCH in the file, scaled to mm"):
        surf = load_surface(path, chord_tol=0.01)
    assert np.allclose(surf.mesh.extents, [10, 20, 30], atol=1e-9)
    assert surf.brep.unit == "INCH"
    assert any("INCH" in n and "mm" in n for n in surf.notes)


def test_frame_mismatch_named_with_its_offset(cylsph):
    """Tool tips of a ball end (r 3) on the part, shifted by 300 mm in X: the check names the work
    offset and gives the offset that aligns them; placed with it, the check passes; an inch
    program is named by its ratio."""
    mesh = cylsph.mesh
    pts, idx = trimesh.sample.sample_surface(mesh, 3000, seed=3)
    n = mesh.face_normals[idx]
    up = n[:, 2] > 0.3  # a ball end (r 3) along +Z touches where the part faces up
    tips = (pts + 3.0 * n - 3.0 * np.array([0.0, 0.0, 1.0]))[up]
    assert check_frame(tips, mesh, reach=4.0).message is None
    res = check_frame(tips + [300.0, 0.0, 0.0], mesh, reach=4.0, what="program p.cls", part="part p.step")
    assert res.cause == "offset" and res.near < 0.1
    # the tips lie up to the ball's radius off the surface, and the program covers the top only: the
    # offset is found to within about the radius (3.1 mm here); the check passes at the offset found
    assert np.linalg.norm(np.subtract(res.offset, [300.0, 0.0, 0.0])) <= 2 * 3.0
    assert f"--part-frame {res.offset[0]:g}," in res.message and "work offset" in res.message
    assert check_frame(tips + [300.0, 0.0, 0.0] - res.offset, mesh, reach=4.0).message is None
    # inch read as mm: with the part away from the origin (scaled about the origin, a program near
    # it would still touch a part that holds the origin)
    moved = mesh.copy()
    moved.apply_translation([120.0, 80.0, 10.0])
    inch_tips = tips + [120.0, 80.0, 10.0]
    assert check_frame(inch_tips, moved, reach=4.0).message is None
    inch = check_frame(inch_tips / 25.4, moved, reach=4.0)
    assert inch.cause == "units" and "inch vs mm" in inch.message and "times 25.4" in inch.message


def test_place_moves_mesh_and_brep(tmp_path):
    surf = load_surface(_write_step(BRepPrimAPI_MakeBox(10.0, 20.0, 30.0).Shape(), tmp_path / "b.step"),
                        chord_tol=0.01)
    T = rigid_transform((300, -5, 2), (0, 0, 90))
    place(surf, T)
    assert np.allclose(surf.mesh.bounds, [[280, -5, 2], [300, 5, 32]], atol=1e-9)
    from camsmooth.geometry.step import exact_distance

    d = exact_distance(surf.brep, np.array([[300.0, 0.0, 40.0], [310.0, 0.0, 17.0], [290.0, 0.0, 17.0]]))
    assert d == pytest.approx([8.0, 10.0, 0.0], abs=1e-9)  # the last inside the solid


def _cl_csv(path: Path, tips: np.ndarray) -> Path:
    rows = ["x,y,z,i,j,k,row,feed"] + [f"{x:.6f},{y:.6f},{z:.6f},0,0,1,{k // 50},1000"
                                       for k, (x, y, z) in enumerate(tips)]
    path.write_text("\n".join(rows) + "\n")
    return path


def test_cli_step_surface_frame_check_and_part_frame(tmp_path, capsys):
    """analyze --surface PART.step: a program 300 mm off is refused (exit 2) with the offset named;
    --part-frame -300,0,0 (a negative first number, not an option) places the part and the program
    is analysed against it."""
    step = _write_step(_freeform_face(), tmp_path / "free.step")
    xs, ys = np.meshgrid(np.linspace(20, 80, 10), np.linspace(20, 60, 10))
    cc = np.c_[xs.ravel(), ys.ravel(), _height(xs, ys).ravel()]
    tips = cc - [300.0, 0.0, 0.0]  # a ball end's tip is within r of the surface: here on it
    prog = _cl_csv(tmp_path / "p.csv", tips)
    base = ["analyze", str(prog), "--surface", str(step), "--cutter-radius", "0", "--corner-radius", "3",
            "--tolerance", "0.1", "--quiet"]
    assert main(base) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "not in the same frame" in err[0] and "work offset" in err[0]
    offset = [float(v) for v in re.search(r"--part-frame (\S+)$", err[0]).group(1).split(",")]
    assert np.allclose(offset, [-300.0, 0.0, 0.0], atol=0.1)  # the tips are on the surface here
    assert main(base + ["--part-frame", "-300,0,0"]) == 0
    assert main(base + ["--part-frame", "msys"]) == 2
    assert "needs a CLSF with an MSYS record" in capsys.readouterr().err


def test_cli_without_opencascade_says_how_to_install(tmp_path, capsys, monkeypatch):
    step = tmp_path / "x.step"
    step.write_text("ISO-10303-21;\n")
    monkeypatch.setitem(sys.modules, "OCP", None)  # import OCP raises ImportError
    code = main(["path", "--surface", str(step), "--stepover", "1", "--spacing", "1", "-o", str(tmp_path / "o.csv"),
                 "--cutter-radius", "0", "--corner-radius", "3"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1
    assert "pip install 'camsmooth[cad]'" in err[0] and "Traceback" not in err[0]
    assert not (tmp_path / "o.csv").exists()


def test_bad_step_file_named(tmp_path, capsys):
    bad = tmp_path / "bad.step"
    bad.write_text("ISO-10303-21;\nHEADER;\nENDSEC;\nDATA;\n#1=FOO(;\nENDSEC;\nEND-ISO-10303-21;\n")
    with pytest.raises(InputError, match=r"bad\.step.*cannot read the file as STEP.*Line \d+"):
        load_surface(bad)
    assert capsys.readouterr().out == ""  # OCCT's parser message is in the error, not on the terminal


def test_exact_clearance_against_closed_form(cylsph):
    """A ball end (r 3, axis +Z) at h above the hemisphere (ball centre at 13 + h from the sphere's
    centre): the exact clearance is h (closed form); the mesh's differs from it by at most the
    measured chord deviation."""
    from camsmooth.geometry.clearance import MeshIndex, clearance
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.step import exact_clearance

    cutter = ToroidalCutter(R=0.0, r=3.0)
    h = np.array([0.01, 0.0, -0.02, 0.05, 0.003])
    phi, az = np.radians([10, 25, 40, 55, 0]), np.radians([0, 37, 100, 200, 0])
    d = np.c_[np.sin(phi) * np.cos(az), np.sin(phi) * np.sin(az), np.cos(phi)]
    tips = d * (13 + h)[:, None] + [0, 0, 27.0]  # ball centre minus r along the axis
    axes = np.tile([0.0, 0.0, 1.0], (len(h), 1))
    mesh_cl = clearance(MeshIndex(cylsph.mesh), cutter, tips, axes)
    exact = exact_clearance(cylsph.brep, cutter, tips, axes, mesh_cl.witness)
    assert exact == pytest.approx(h, abs=1e-7)
    assert np.all(np.abs(mesh_cl.delta - h) <= cylsph.brep.deviation + 1e-9)
    assert np.abs(mesh_cl.delta - h).max() > 1e-4  # the mesh's figure is not the exact one
