"""CAD parts (STEP, IGES) as workpiece surfaces: read, tessellate, measure the chord deviation, place.

Library
-------
OpenCASCADE Technology (OCCT) through OCP, its Python binding from the CadQuery project (PyPI
``cadquery-ocp-novtk``, module ``OCP``; ``pip install 'camsmooth[cad]'``). Why this one: OCCT is
the open B-rep kernel that FreeCAD, CadQuery and build123d all stand on; its STEP reader
(STEPControl_Reader) converts the file's length unit to millimetres, its mesher
(BRepMesh_IncrementalMesh) meshes trimmed faces to a linear and an angular deflection, and its
geometry evaluates the exact faces for the measurement below. CadQuery and build123d are modelling
layers over the same OCP module (they add an API for making parts, which camsmooth does not need);
pythonocc-core binds the same kernel but ships through conda only. OCP is on PyPI with manylinux
wheels for CPython 3.11. The ``-novtk`` build is the same module without OCCT's VTK bridge:
``cadquery-ocp`` pins ``vtk==9.6.2``, which would replace the VTK that pyvista (the report's
renderer) runs on.

Frames, units, sides
--------------------
Lengths in mm. The part is read in its CAD frame (the frame the file's coordinates are given in);
``BRepPart.transform`` (4x4, part frame -> program frame, identity unless the part is placed with
``camsmooth.geometry.placement.place``) maps it into the frame of the program, and ``Surface.mesh``
is always in the program's frame. STEP files in inch (or any other unit) are scaled to mm by the
reader (xstep.cascade.unit = MM, OCCT's default); ``BRepPart.unit`` names the unit the file
declared. Face normals of the mesh point out of the material for a solid (OCCT's face
orientation); an open shell keeps the side its faces are oriented to.

Chord deviation: how it is measured
-----------------------------------
The mesh is made with the Delabella algorithm of BRepMesh (about 6x faster than the default Watson
at 1 um) to a linear deflection (``deflection``, mm; the CLI asks for tolerance / 5) and an
angular deflection (``angular``, rad). BRepMesh's own deflection figure is an estimate, so the
deviation is measured both ways against the exact faces:

* mesh -> B-rep (``mesh_to_brep``): on every triangle (at most ``MEASURE_TRIANGLES``; above that
  the largest half and a random half of the rest) the centroid and the three edge midpoints are
  projected onto the face's exact surface by Gauss-Newton in the face parameters (u, v), started
  at the parameters interpolated from the triangle's nodes; the distance |P - S(u, v)| is an upper
  bound of the distance to the surface. The signed edge-midpoint deviations give the triangle's
  largest deviation by the quadratic interpolation bound of ``surfaces._triangle_max_error`` (the
  same bound the definition tessellations use).
* B-rep -> mesh (``brep_to_mesh``): points sampled uniformly by area on the exact faces (random
  barycentric points of the face's parameter triangulation, which covers the trimmed face, mapped
  through S(u, v)); each point's distance to the mesh is bounded by its distance to the point with
  the same barycentric coordinates on its triangle, and the ``EXACT_SAMPLES`` samples with the
  largest bounds get their exact closest-point distance (trimesh). The figure is the largest of
  those, i.e. an upper bound of the largest distance over all samples.

``BRepPart.deviation`` = max of the two is what ``surfaces.chord_deviation`` reports for the mesh
(the pipeline compares it with the tolerance). When it exceeds 1.5 x the deflection asked for, the
part is meshed again with a proportionally smaller deflection (at most ``REMESH_ROUNDS`` times).

``exact_distance`` gives the distance of points to the exact B-rep (BRepExtrema_DistShapeShape),
and ``exact_clearance`` the clearance of tool poses against the exact faces near the mesh's
witness points (the final clearance report re-measures the worst poses with it).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import sys
import tempfile
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import trimesh

from camsmooth.errors import InputError

__all__ = [
    "STEP_SUFFIXES",
    "IGES_SUFFIXES",
    "CAD_SUFFIXES",
    "INSTALL_HINT",
    "BRepPart",
    "read_cad",
    "tessellate_brep",
    "load_cad",
    "exact_distance",
    "exact_clearance",
]

STEP_SUFFIXES = (".step", ".stp")
IGES_SUFFIXES = (".iges", ".igs")
CAD_SUFFIXES = STEP_SUFFIXES + IGES_SUFFIXES
INSTALL_HINT = "pip install 'camsmooth[cad]' (the OpenCASCADE binding cadquery-ocp-novtk)"

DEFAULT_ANGULAR = 0.2          # rad: BRepMesh angular deflection (the linear deflection binds above R = 8 d / 0.04)
MEASURE_TRIANGLES = 60_000     # triangles whose centroid and edge midpoints are projected (all below this)
BREP_SAMPLES = 20_000          # points sampled on the exact faces (at most; 2 per triangle below that)
EXACT_SAMPLES = 2_000          # of which these (the largest bounds) get an exact closest-point distance
REMESH_ROUNDS = 3
MAX_TRIANGLES = 4_000_000      # no finer remeshing once the mesh has half of this
_SEED = 20301                  # fixed: the measurement is reproducible


def _ocp() -> Any:
    """Import OCP or raise the one-line install hint (InputError: the CLI exits 2)."""
    try:
        import OCP  # noqa: F401
    except ImportError:
        raise InputError(f"reading a CAD part (STEP/IGES) needs OpenCASCADE: {INSTALL_HINT}") from None
    import OCP

    return OCP


@dataclass
class BRepPart:
    """The exact part behind a tessellated Surface.

    shape: OCP TopoDS_Shape in the part's CAD frame (mm). source: the file. unit: the length unit
    the file declared ('MM', 'INCH', ...; '' when it names none). deflection (mm) and angular (rad):
    what BRepMesh was asked for. mesh_to_brep, brep_to_mesh (mm): the measured deviations (module
    docstring); triangles: how many the mesh has, measured: how many were measured. transform:
    4x4 part frame -> program frame.
    """

    shape: Any
    source: str
    unit: str
    deflection: float
    angular: float
    mesh_to_brep: float
    brep_to_mesh: float
    triangles: int
    measured: int
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))

    @property
    def deviation(self) -> float:
        """Largest measured distance between the mesh and the exact faces, either way (mm)."""
        return max(self.mesh_to_brep, self.brep_to_mesh)


# ---------------------------------------------------------------------------------------------
# reading


def _step_units(reader: Any) -> str:
    """The length unit names the STEP file declares (upper case, comma-joined; '' if unknown)."""
    try:  # OCP 7.8+ exposes OCCT's NCollection sequences here, older builds in TColStd
        from OCP.OCP.collections import Sequence_TCollection_AsciiString as Sequence
    except ImportError:
        try:
            from OCP.TColStd import TColStd_SequenceOfAsciiString as Sequence
        except ImportError:
            return ""
    length, angle, solid = (Sequence() for _ in range(3))
    try:
        reader.FileUnits(length, angle, solid)
    except Exception:  # the unit name is only reported: the reader scales the geometry itself
        return ""
    names = sorted({length.Value(i).ToCString().upper() for i in range(1, length.Length() + 1)})
    return ",".join(names)


@contextlib.contextmanager
def _quiet_fds(sink: list[str]) -> Iterator[None]:
    """Capture what OpenCASCADE prints on the process's stdout / stderr (its reader's parse errors)
    into ``sink`` (one string, ANSI colours removed) instead of letting it reach the terminal."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as tmp:
        try:
            os.dup2(tmp.fileno(), 1)
            os.dup2(tmp.fileno(), 2)
            yield
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            tmp.seek(0)
            text = tmp.read().decode("utf-8", "replace")
            sink.append(re.sub(r"\x1b\[[0-9;]*m", "", text))


def _first_error(text: str) -> str:
    for line in text.splitlines():
        line = line.strip(" *")
        if "ERR" in line or "Error" in line or "error" in line:
            return " ".join(line.split())
    return ""


def read_cad(path: str | Path) -> tuple[Any, str]:
    """Read a STEP (.step/.stp) or IGES (.iges/.igs) file -> (OCP shape in mm, declared length unit).

    Raises InputError naming the file when OCP is missing (the install line), the file cannot be
    read as STEP/IGES, or it holds no shape.
    """
    _ocp()
    from OCP.IFSelect import IFSelect_RetDone

    file = str(path)
    suffix = Path(file).suffix.lower()
    if suffix in STEP_SUFFIXES:
        from OCP.STEPControl import STEPControl_Reader

        reader = STEPControl_Reader()
        kind = "STEP"
    elif suffix in IGES_SUFFIXES:
        from OCP.IGESControl import IGESControl_Reader

        reader = IGESControl_Reader()
        kind = "IGES"
    else:
        raise InputError(f"not a CAD file suffix '{Path(file).suffix}' (expected {', '.join(CAD_SUFFIXES)})",
                         file=file)
    printed: list[str] = []
    with _quiet_fds(printed):
        status = reader.ReadFile(file)
        transferred = reader.TransferRoots() if status == IFSelect_RetDone else 0
    if status != IFSelect_RetDone:
        why = _first_error(printed[0]) if printed else ""
        raise InputError(f"cannot read the file as {kind}" + (f": {why}" if why else "")
                         + f" (OpenCASCADE reader status {status.name})", file=file)
    unit = _step_units(reader) if kind == "STEP" else ""
    if transferred == 0 or reader.NbShapes() == 0:
        raise InputError(f"the {kind} file holds no shape that could be transferred (no geometry)", file=file)
    shape = reader.OneShape()
    if shape.IsNull():
        raise InputError(f"the {kind} file holds no shape (null shape after transfer)", file=file)
    return shape, unit


# ---------------------------------------------------------------------------------------------
# tessellation


@dataclass
class _Face:
    face: Any                 # TopoDS_Face
    adaptor: Any              # BRepAdaptor_Surface (global coordinates)
    xyz: np.ndarray           # (n, 3) nodes, mm, part frame
    uv: np.ndarray            # (n, 2) node parameters
    tri: np.ndarray           # (m, 3) node indices (0-based), wound so the normal is out of the material
    offset: int               # index of node 0 in the merged vertex array (before merging)
    bounds: tuple[float, float, float, float]


def _mesh_faces(shape: Any, deflection: float, angular: float) -> list[_Face]:
    from OCP.BRep import BRep_Tool
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.IMeshTools import IMeshTools_MeshAlgoType_Delabella, IMeshTools_Parameters
    from OCP.Message import Message_ProgressRange
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    BRepTools.Clean_s(shape)
    params = IMeshTools_Parameters()
    params.Deflection = float(deflection)
    params.Angle = float(angular)
    params.InParallel = True
    params.MeshAlgo = IMeshTools_MeshAlgoType_Delabella
    BRepMesh_IncrementalMesh(shape, params, Message_ProgressRange())
    faces: list[_Face] = []
    offset = 0
    ex = TopExp_Explorer(shape, TopAbs_FACE)
    while ex.More():
        face = TopoDS.Face(ex.Current())
        ex.Next()
        loc = TopLoc_Location()
        tri = BRep_Tool.Triangulation_s(face, loc)
        if tri is None or tri.NbTriangles() == 0:
            continue
        n, m = tri.NbNodes(), tri.NbTriangles()
        trsf = None if loc.IsIdentity() else loc.Transformation()
        if trsf is None:
            xyz = np.array([tri.Node(i).Coord() for i in range(1, n + 1)])
        else:
            xyz = np.array([tri.Node(i).Transformed(trsf).Coord() for i in range(1, n + 1)])
        uv = np.array([tri.UVNode(i).Coord() for i in range(1, n + 1)])
        idx = np.array([tri.Triangle(k + 1).Get() for k in range(m)], dtype=np.int64) - 1
        if face.Orientation() == TopAbs_REVERSED:
            idx = idx[:, ::-1]
        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)
        faces.append(_Face(face, BRepAdaptor_Surface(face), xyz, uv, idx, offset, (u0, u1, v0, v1)))
        offset += n
    return faces


def _merge(faces: list[_Face]) -> trimesh.Trimesh:
    vertices = np.concatenate([f.xyz for f in faces])
    tris = np.concatenate([f.tri + f.offset for f in faces])
    mesh = trimesh.Trimesh(vertices=vertices, faces=tris, process=False)
    mesh.merge_vertices()  # faces share their edges' nodes: equal coordinates, merged to one vertex
    # a pole (of a sphere, a cone's apex) is several parameter nodes at one point: its slivers collapse
    f = mesh.faces
    mesh.update_faces((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2]))
    mesh.remove_unreferenced_vertices()
    return mesh


def _eval(face: _Face, uv: np.ndarray, derivatives: bool) -> tuple[np.ndarray, ...]:
    """S(u, v) (and Su, Sv) at (k, 2) parameters of a face, part frame, mm."""
    from OCP.gp import gp_Pnt, gp_Vec

    a = face.adaptor
    if not derivatives:
        return (np.array([a.Value(u, v).Coord() for u, v in uv.tolist()]).reshape(-1, 3),)
    P, U, V = gp_Pnt(), gp_Vec(), gp_Vec()
    out = np.empty((len(uv), 9))
    for i, (u, v) in enumerate(uv.tolist()):
        a.D1(u, v, P, U, V)
        out[i] = P.Coord() + U.Coord() + V.Coord()
    return out[:, :3], out[:, 3:6], out[:, 6:]


def _project(face: _Face, P: np.ndarray, uv: np.ndarray, iterations: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Signed distance (mm) of points P (k, 3) to the face's surface by Gauss-Newton from uv (k, 2):
    |P - S(u*, v*)| (an upper bound of the distance to the untrimmed surface), signed by the side
    of the surface normal Su x Sv; and whether the foot is a true projection (P - S orthogonal to
    Su and Sv within 1 %; False where the parametrisation degenerates or Newton stopped short)."""
    u0, u1, v0, v1 = face.bounds
    du, dv = (u1 - u0) * 1e-3, (v1 - v0) * 1e-3
    uv = uv.copy()
    for it in range(iterations + 1):
        S, Su, Sv = _eval(face, uv, True)
        r = P - S
        a, b, c = np.einsum("ij,ij->i", Su, Su), np.einsum("ij,ij->i", Su, Sv), np.einsum("ij,ij->i", Sv, Sv)
        g1, g2 = np.einsum("ij,ij->i", Su, r), np.einsum("ij,ij->i", Sv, r)
        if it == iterations:
            break
        det = a * c - b * b
        ok = det > 1e-24 * np.maximum(a * c, 1e-300)
        det = np.where(ok, det, 1.0)
        step = np.where(ok[:, None], np.stack([(c * g1 - b * g2) / det, (a * g2 - b * g1) / det], -1), 0.0)
        uv = uv + step
        uv[:, 0] = np.clip(uv[:, 0], u0 - du, u1 + du)
        uv[:, 1] = np.clip(uv[:, 1], v0 - dv, v1 + dv)
    dist = np.linalg.norm(r, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        tangential = np.maximum(np.abs(g1) / np.sqrt(a), np.abs(g2) / np.sqrt(c))
    good = (tangential <= 0.01 * dist + 1e-12) & (a > 0) & (c > 0)
    side = np.sign(np.einsum("ij,ij->i", np.cross(Su, Sv), r))
    return np.where(side == 0, 1.0, side) * dist, good


def _extrema(face: _Face, P: np.ndarray) -> np.ndarray:
    """Distance (mm) of points P (k, 3) to the face's surface within its parameter bounds by OCCT's
    global Extrema (GeomAPI_ProjectPointOnSurf): slower than ``_project``, but right where the
    parametrisation degenerates (the pole of a sphere, where interpolated parameters mislead)."""
    from OCP.BRep import BRep_Tool
    from OCP.GeomAPI import GeomAPI_ProjectPointOnSurf
    from OCP.gp import gp_Pnt

    surf = BRep_Tool.Surface_s(face.face)  # with the face's location applied
    u0, u1, v0, v1 = face.bounds
    out = np.full(len(P), np.inf)
    for i, p in enumerate(P):
        proj = GeomAPI_ProjectPointOnSurf(gp_Pnt(*map(float, p)), surf, u0, u1, v0, v1)
        if proj.NbPoints() > 0:
            out[i] = proj.LowerDistance()
    return out


def _mesh_to_brep(faces: list[_Face], rng: np.random.Generator, deflection: float) -> tuple[float, int]:
    from camsmooth.geometry.surfaces import _triangle_max_error

    total = sum(len(f.tri) for f in faces)
    keep_share = min(1.0, MEASURE_TRIANGLES / max(total, 1))
    worst, measured = 0.0, 0
    for f in faces:
        tri = f.tri
        if keep_share < 1.0:  # the largest half of the budget by area, a random half of the rest
            area = np.linalg.norm(np.cross(f.xyz[tri[:, 1]] - f.xyz[tri[:, 0]], f.xyz[tri[:, 2]] - f.xyz[tri[:, 0]]),
                                  axis=1)
            quota = max(1, int(round(keep_share * len(tri))))
            order = np.argsort(-area)
            big = order[: quota // 2]
            rest = order[quota // 2:]
            tri = tri[np.concatenate([big, rng.choice(rest, size=min(len(rest), quota - len(big)), replace=False)])]
        m = len(tri)
        # the midpoints of the triangles' distinct edges (12, 13, 23 of each triangle), then the centroids
        ends = np.sort(np.concatenate([tri[:, [0, 1]], tri[:, [0, 2]], tri[:, [1, 2]]]), axis=1)
        edges, which = np.unique(ends, axis=0, return_inverse=True)
        P = np.concatenate([f.xyz[edges].mean(axis=1), f.xyz[tri].mean(axis=1)])
        uv = np.concatenate([f.uv[edges].mean(axis=1), f.uv[tri].mean(axis=1)])
        d, good = _project(f, P, uv)
        suspect = np.flatnonzero(~good & (np.abs(d) > 0.1 * deflection))  # not a true foot and not small:
        if len(suspect):                                                   # ask OCCT's global Extrema too
            d[suspect] = np.sign(d[suspect]) * np.minimum(np.abs(d[suspect]), _extrema(f, P[suspect]))
        mid = d[:len(edges)][which.reshape(-1)].reshape(3, m)
        e = np.maximum(_triangle_max_error(mid[0], mid[1], mid[2]), np.abs(d[len(edges):]))
        worst = max(worst, float(e.max()))
        measured += len(tri)
    return worst, measured


def _brep_to_mesh(faces: list[_Face], mesh: trimesh.Trimesh, rng: np.random.Generator) -> float:
    areas = [np.linalg.norm(np.cross(f.xyz[f.tri[:, 1]] - f.xyz[f.tri[:, 0]], f.xyz[f.tri[:, 2]] - f.xyz[f.tri[:, 0]]),
                            axis=1) for f in faces]
    total_area = float(sum(a.sum() for a in areas))
    n_total = min(BREP_SAMPLES, 2 * sum(len(f.tri) for f in faces))
    points, bounds = [], []
    for f, a in zip(faces, areas, strict=True):
        k = int(math.ceil(n_total * a.sum() / max(total_area, 1e-300)))
        if k == 0:
            continue
        t = rng.choice(len(f.tri), size=k, p=a / a.sum())
        r1, r2 = np.sqrt(rng.random(k)), rng.random(k)
        w = np.stack([1 - r1, r1 * (1 - r2), r1 * r2], -1)  # uniform barycentric points
        uv = np.einsum("ki,kij->kj", w, f.uv[f.tri[t]])
        S = _eval(f, uv, False)[0]
        flat = np.einsum("ki,kij->kj", w, f.xyz[f.tri[t]])
        points.append(S)
        bounds.append(np.linalg.norm(S - flat, axis=1))
    if not points:
        return 0.0
    S, ub = np.concatenate(points), np.concatenate(bounds)
    top = np.argsort(-ub)[:EXACT_SAMPLES]
    _, dist, _ = trimesh.proximity.closest_point(mesh, S[top])
    rest = np.ones(len(ub), bool)
    rest[top] = False
    return float(max(np.max(dist, initial=0.0), np.max(ub[rest], initial=0.0)))


def tessellate_brep(shape: Any, deflection: float, angular: float = DEFAULT_ANGULAR
                    ) -> tuple[trimesh.Trimesh, float, float, int]:
    """Mesh ``shape`` (part frame, mm) -> (mesh, mesh_to_brep mm, brep_to_mesh mm, triangles measured).

    BRepMesh (Delabella) to ``deflection`` mm and ``angular`` rad, then measured both ways against
    the exact faces (module docstring). Raises InputError when the shape has no face to mesh.
    """
    _ocp()
    if not (deflection > 0 and math.isfinite(deflection)):
        raise ValueError(f"deflection must be a positive number of mm, got {deflection!r}")
    faces = _mesh_faces(shape, deflection, angular)
    if not faces:
        raise InputError("the part has no faces to mesh (a wireframe or point set, not a surface)")
    mesh = _merge(faces)
    rng = np.random.default_rng(_SEED)
    m2b, measured = _mesh_to_brep(faces, rng, deflection)
    b2m = _brep_to_mesh(faces, mesh, rng)
    return mesh, m2b, b2m, measured


def load_cad(path: str | Path, deflection: float, angular: float = DEFAULT_ANGULAR) -> Any:
    """A CAD part as a ``surfaces.Surface``: read (``read_cad``), meshed to ``deflection`` mm and
    measured (``tessellate_brep``; meshed again, finer, while the measured deviation exceeds 1.5 x
    the deflection), its winding checked (``surfaces.check_mesh_orientation``), with the exact
    part as ``Surface.brep`` (a ``BRepPart``, identity placement)."""
    from camsmooth.geometry.surfaces import Surface, check_mesh_orientation

    file = str(path)
    shape, unit = read_cad(file)
    d = float(deflection)
    for _ in range(REMESH_ROUNDS + 1):
        mesh, m2b, b2m, measured = tessellate_brep(shape, d, angular)
        dev = max(m2b, b2m)
        if dev <= 1.5 * deflection or d <= 0.1 * deflection or len(mesh.faces) > MAX_TRIANGLES / 2:
            break
        d = max(d * 0.8 * deflection / dev, 0.1 * deflection)  # at most 10x finer than asked: ~10x the triangles
    notes = []
    if dev > 1.5 * deflection:
        notes.append(f"{file}: measured chord deviation {dev * 1e3:.3g} um exceeds the deflection asked for "
                     f"({deflection * 1e3:.3g} um) after {REMESH_ROUNDS} finer meshes")
    note = check_mesh_orientation(mesh, file)
    if note:
        notes.append(note)
    if unit and unit not in ("MM", "MILLIMETRE", "MILLIMETER"):
        notes.append(f"{file}: length unit {unit} in the file, scaled to mm")
    for note in notes:  # the CLI prints each as one 'camsmooth: warning:' line
        warnings.warn(note, RuntimeWarning, stacklevel=2)
    part = BRepPart(shape=shape, source=file, unit=unit, deflection=d, angular=angular, mesh_to_brep=m2b,
                    brep_to_mesh=b2m, triangles=len(mesh.faces), measured=measured)
    mesh.metadata["chord_error"] = part.deviation
    mesh.metadata["chord_tol"] = float(deflection)
    return Surface(mesh=mesh, parametric=None, source=file, notes=notes, brep=part)


# ---------------------------------------------------------------------------------------------
# exact distances (placement: camsmooth.geometry.placement)


def _to_part(brep: BRepPart, points: np.ndarray) -> np.ndarray:
    T = np.linalg.inv(brep.transform)
    return np.asarray(points, dtype=float).reshape(-1, 3) @ T[:3, :3].T + T[:3, 3]


def exact_distance(brep: BRepPart, points: Any) -> np.ndarray:
    """Unsigned distance (mm) of points (N, 3, program frame) to the exact part (BRepExtrema_DistShapeShape
    from a vertex to the shape; about a millisecond a point)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape
    from OCP.gp import gp_Pnt

    out = []
    for p in _to_part(brep, points):
        v = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex()
        ext = BRepExtrema_DistShapeShape(v, brep.shape)
        out.append(ext.Value() if ext.IsDone() else math.nan)
    return np.asarray(out)


def _closest_on_brep(brep: BRepPart, p: np.ndarray) -> tuple[Any, float, float] | None:
    """The face and (u, v) of the exact part nearest to the point p (part frame). Where the nearest
    point is on an edge or a vertex (a seam, a boundary), the face whose surface passes nearest to it."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeVertex
    from OCP.BRepExtrema import BRepExtrema_DistShapeShape, BRepExtrema_IsInFace
    from OCP.gp import gp_Pnt
    from OCP.ShapeAnalysis import ShapeAnalysis_Surface
    from OCP.TopAbs import TopAbs_FACE
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopoDS import TopoDS

    v = BRepBuilderAPI_MakeVertex(gp_Pnt(*map(float, p))).Vertex()
    ext = BRepExtrema_DistShapeShape(v, brep.shape)
    if not ext.IsDone() or ext.NbSolution() == 0:
        return None
    for k in range(1, ext.NbSolution() + 1):
        if ext.SupportTypeShape2(k) == BRepExtrema_IsInFace:
            u, w = ext.ParOnFaceS2(k)
            return TopoDS.Face(ext.SupportOnShape2(k)), float(u), float(w)
    q = ext.PointOnShape2(1)
    best = None
    ex = TopExp_Explorer(brep.shape, TopAbs_FACE)
    while ex.More():
        face = TopoDS.Face(ex.Current())
        ex.Next()
        sas = ShapeAnalysis_Surface(BRep_Tool.Surface_s(face))
        uv = sas.ValueOfUV(q, 1e-7)
        gap = sas.Gap()
        if best is None or gap < best[0]:
            best = (gap, face, uv.X(), uv.Y())
    return None if best is None else (best[1], float(best[2]), float(best[3]))


def exact_clearance(brep: BRepPart, cutter: Any, tips: Any, axes: Any, witness: Any) -> np.ndarray:
    """Clearance (mm, negative = gouge) of tool poses against the exact faces near their mesh witness.

    For each pose (tip, unit axis: (N, 3), program frame) the exact face point nearest to the
    mesh's witness point is found (BRepExtrema) and the tool's signed distance
    (``cutter.signed_distance``) is minimised over that face's parameters from there (bounded
    L-BFGS). The result is the clearance against the exact surface in the witness's neighbourhood
    (NaN where no face point was found): for the worst poses of a result, where the witness is the
    deepest mesh point, it is the figure the mesh's one stands for.
    """
    from OCP.BRepAdaptor import BRepAdaptor_Surface
    from OCP.BRepTools import BRepTools
    from scipy.optimize import minimize

    from camsmooth.geometry.cutter import signed_distance

    T = brep.transform
    tips = np.asarray(tips, dtype=float).reshape(-1, 3)
    axes = np.asarray(axes, dtype=float).reshape(-1, 3)
    wit_part = _to_part(brep, witness)
    out = np.full(len(tips), math.nan)
    for i in range(len(tips)):
        if not np.all(np.isfinite(wit_part[i])):
            continue
        hit = _closest_on_brep(brep, wit_part[i])
        if hit is None:
            continue
        face, u, v = hit
        a = BRepAdaptor_Surface(face)
        u0, u1, v0, v1 = BRepTools.UVBounds_s(face)

        def f(x: np.ndarray, a: Any = a, i: int = i) -> float:
            p = a.Value(float(x[0]), float(x[1]))
            q = T[:3, :3] @ np.array([p.X(), p.Y(), p.Z()]) + T[:3, 3]
            return float(signed_distance(cutter, tips[i], axes[i], q[None, :])[0])

        res = minimize(f, np.array([u, v]), method="L-BFGS-B", bounds=[(u0, u1), (v0, v1)],
                       options={"ftol": 1e-14, "gtol": 1e-10, "maxiter": 200})
        out[i] = min(float(res.fun), f(np.array([u, v])))
    return out
