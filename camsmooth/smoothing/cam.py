"""A CAM system's cutter-location program made ready for the pipeline.

A CL program (camsmooth.io.program.CLProgram: tool tips and axes per point, workpiece frame, mm)
says where the tool is, not where it touches the part. With the mesh and the cutter,
``cam_program`` finds for every pose the contact point and the surface normal there
(camsmooth.geometry.contact), so that the program becomes a CC path and every method applies; the
CAM's own axes become the method 'cam' beside none, spline and nlp.

Poses that do not touch the mesh within the tolerance (air moves, lead-ins and -outs, or a pose
that gouges) cannot be CC points: they are left out of the smoothed rows (which split there) and
named with their clearance and file lines (``OffContact``). Runs of fewer than three touching
points cannot be smoothed either and are named the same way. The G-code links the smoothed rows
by the dialect's retract and re-entry (camsmooth.post.writer), not by the CAM's lead moves.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from camsmooth.errors import InputError
from camsmooth.geometry.clearance import MeshIndex
from camsmooth.geometry.contact import contacts, interpolated_normals
from camsmooth.geometry.cutter import ToroidalCutter
from camsmooth.geometry.paths import MIN_ROW_POINTS, CCPath, estimate_feed_dirs
from camsmooth.io.program import CLProgram

__all__ = ["CamProgram", "OffContact", "cam_program", "cutter_of"]


@dataclass(frozen=True)
class OffContact:
    """A run of program points ``start:stop`` (indices into the CL program, in file order) left
    out of the smoothed rows: ``why`` 'air' (the tool clears the mesh), 'gouge' (it cuts deeper
    than the tolerance) or 'short' (fewer than 3 touching points between such runs); ``clearance``
    the run's smallest and largest clearance (mm); ``lines`` the file lines of its first and last
    point."""

    start: int
    stop: int
    why: str
    clearance: tuple[float, float]
    lines: tuple[int, int]


@dataclass(frozen=True)
class CamProgram:
    """The touching points of a CL program as a CC path (``path``: contact points and normals,
    rows split where the program leaves the surface; feed from the program), with the CAM's own
    tool tips and axes at those points (``tips``, ``axes``, (N, 3), mm and unit, workpiece frame),
    each point's index in the CL program (``source_index``), the runs left out (``off_contact``),
    the cutter and the program itself."""

    path: CCPath
    tips: np.ndarray
    axes: np.ndarray
    source_index: np.ndarray
    off_contact: list[OffContact]
    cutter: ToroidalCutter
    program: CLProgram

    def warnings(self) -> list[str]:
        """The program reader's warnings (records ignored, tool paths dropped), then one line per
        run left out, naming the file lines and the clearance."""
        out = list(self.program.warnings)
        for o in self.off_contact:
            what = {"air": "does not touch the mesh (an air move or a lead)", "gouge": "cuts into the mesh",
                    "short": "touches for fewer than 3 points"}[o.why]
            out.append(f"{self.program.source}: lines {o.lines[0]}-{o.lines[1]} ({o.stop - o.start} points) {what}: "
                       f"clearance {o.clearance[0]:.4g} to {o.clearance[1]:.4g} mm; kept out of the smoothed rows")
        return out


def cutter_of(program: CLProgram) -> ToroidalCutter:
    """The toroidal cutter the program declares (every cutting tool path the same mill; R = D/2 - r).
    InputError naming the file and the line when there is none or the tool paths disagree."""
    tools = []
    for tp in program.toolpaths:
        if tp.stop > tp.start and np.any(program.rows[tp.start:tp.stop] >= 0):
            tools.append((tp, program.require_tool(tp)))
    if not tools:
        raise InputError("the program declares no cutter: give --cutter-radius and --corner-radius",
                         file=program.source)
    first = tools[0][1]
    for _, tool in tools[1:]:
        if (tool.diameter, tool.corner_radius) != (first.diameter, first.corner_radius):
            raise InputError(f"tool paths use different cutters (D {first.diameter:g} r {first.corner_radius:g} mm and "
                             f"D {tool.diameter:g} r {tool.corner_radius:g} mm at line {tool.line}): smooth one "
                             "cutter's tool paths at a time", file=program.source, line=tool.line)
    return ToroidalCutter(R=float(first.ring_radius), r=float(first.corner_radius))


def cam_program(program: CLProgram, index: MeshIndex, cutter: ToroidalCutter, tolerance: float,
                feed: float | None = None, mesh: trimesh.Trimesh | None = None) -> CamProgram:
    """The program's touching points as a CC path (module docstring). ``feed`` (mm/min) stands in
    where the program sets none; InputError naming the line where neither gives one, or when no
    three consecutive points touch the mesh. With the ``mesh``, the CC normals are its normals
    interpolated from the vertex normals at the contacts (camsmooth.geometry.contact
    .interpolated_normals) instead of the contact's own (the facet's, on a facet): the facet
    normals jump by the mesh's dihedral angles, and local frames built on them jerk the methods
    that keep a constant lead (measured on the blade sample: Gamma of 'none' 2.2e6 with facet
    normals, the CAM's own program 2.9e5)."""
    prog = program.cutting()
    axes = prog.require_axis()
    n = len(prog)
    if n == 0:
        raise InputError("the program has no cutting moves (only rapids)", file=program.source)
    c = contacts(index, cutter, prog.tip, axes, tolerance)
    rows_in = prog.rows
    # runs: consecutive points of one program row that all touch (or all do not)
    key = np.where(c.touching, 1, np.where(c.clearance > 0, 0, 2))
    brk = np.r_[True, (rows_in[1:] != rows_in[:-1]) | (key[1:] != key[:-1])]
    starts = np.flatnonzero(brk)
    ends = np.r_[starts[1:], n]
    cutting = np.flatnonzero(program.rows >= 0)  # index in the CL program of each cutting point
    keep = np.zeros(n, bool)
    row_of = np.full(n, -1, np.int64)
    off: list[OffContact] = []
    next_row = 0
    for a, b in zip(starts, ends, strict=True):  # loop over runs, not points
        if key[a] == 1 and b - a >= MIN_ROW_POINTS:
            keep[a:b] = True
            row_of[a:b] = next_row
            next_row += 1
            continue
        why = "short" if key[a] == 1 else ("air" if key[a] == 0 else "gouge")
        cl = c.clearance[a:b]
        off.append(OffContact(start=int(cutting[a]), stop=int(cutting[b - 1]) + 1, why=why,
                              clearance=(float(cl.min()), float(cl.max())),
                              lines=(int(prog.line[a]), int(prog.line[b - 1]))))
    if not keep.any():
        worst = off[0] if off else None
        raise InputError("no three consecutive points of the program touch the mesh within the tolerance "
                         f"({tolerance:g} mm)" + (f"; e.g. lines {worst.lines[0]}-{worst.lines[1]} have clearance "
                                                 f"{worst.clearance[0]:.4g} to {worst.clearance[1]:.4g} mm"
                                                 if worst else "")
                         + ": are the program, the mesh and the cutter the same part, frame and units?",
                         file=program.source)
    f = prog.feed[keep]
    if np.any(~np.isfinite(f)):
        if feed is None:
            k = int(np.flatnonzero(keep)[np.flatnonzero(~np.isfinite(f))[0]])
            raise InputError("no feed for this move (no FEDRAT before it): give --feed", file=program.source,
                             line=int(prog.line[k]))
        f = np.where(np.isfinite(f), f, float(feed))
    pts, nrm, rows = c.points[keep], c.normals[keep], row_of[keep]
    if mesh is not None:
        nrm = interpolated_normals(mesh, pts)
    # the feed direction from the tool tips' path (the CAM's smooth output), not from the contacts,
    # which wander along the cutter by tens of micrometres where the surface is nearly flat (on the
    # blade sample the contacts' directions were off by up to 4.7 deg, and 'none' jerked with them)
    fd = estimate_feed_dirs(prog.tip[keep], nrm, rows)
    path = CCPath(points=pts, normals=nrm, rows=rows, feed_dirs=fd, feed=f, source=program.source)
    return CamProgram(path=path, tips=prog.tip[keep], axes=axes[keep], source_index=cutting[keep], off_contact=off,
                      cutter=cutter, program=program)
