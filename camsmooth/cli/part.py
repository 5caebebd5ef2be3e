"""The part on the command line: ``--surface`` (mesh, definition or CAD part) and ``--part-frame``,
and the check that the program lies on the part (camsmooth.geometry.placement).

``--surface PART.step`` (.stp, .iges, .igs) is meshed to tolerance / 5 (mm) and measured against
its exact faces (camsmooth.geometry.step); without OpenCASCADE installed it is one line saying how
to install it (exit 2). ``--part-frame X,Y,Z[,RX,RY,RZ]`` (mm, deg) or ``msys`` places the part in
the program's frame before anything else uses it.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.constants import DEFAULT_TOLERANCE_MM
from camsmooth.errors import InputError

__all__ = ["add_part_args", "part_frame", "load_part", "reach_of", "place_and_check", "exact_clearance_report"]

CAD_CHORD_SHARE = 0.2   # a CAD part is meshed to this share of the tolerance (linear deflection)


def part_frame(text: str) -> str | tuple[float, ...]:
    """argparse type of --part-frame: 'msys', or x,y,z (mm) with optional rx,ry,rz (deg)."""
    if text.strip().lower() == "msys":
        return "msys"
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) not in (3, 6) or not all(math.isfinite(x) for x in v):
        raise argparse.ArgumentTypeError(f"expected 'msys', X,Y,Z (mm) or X,Y,Z,RX,RY,RZ (mm, deg), got {text!r}")
    return v


def add_part_args(p: argparse.ArgumentParser) -> None:
    """Add --part-frame to a verb that takes --surface."""
    p.add_argument("--part-frame", type=part_frame, default=None, metavar="X,Y,Z[,RX,RY,RZ]|msys",
                   help="place the part in the program's frame: translate by X,Y,Z (mm) after rotating by RX, RY, "
                        "RZ (deg, about the fixed X, then Y, then Z axes), or 'msys': the CLSF's MSYS record (a "
                        "part exported in the machine coordinate system)")


def _tolerance(args: argparse.Namespace) -> float:
    tol = getattr(args, "tolerance", None)
    return float(tol) if tol is not None else DEFAULT_TOLERANCE_MM


def load_part(args: argparse.Namespace) -> Any:
    """The Surface of ``args.surface`` (a CAD part meshed to CAD_CHORD_SHARE x the tolerance), placed
    by a numeric ``--part-frame`` ('msys' waits for the program: ``place_and_check``)."""
    from camsmooth.geometry.placement import place, rigid_transform
    from camsmooth.geometry.step import CAD_SUFFIXES
    from camsmooth.geometry.surfaces import load_surface

    if Path(args.surface).suffix.lower() in CAD_SUFFIXES:
        surface = load_surface(args.surface, chord_tol=CAD_CHORD_SHARE * _tolerance(args))
    else:
        surface = load_surface(args.surface)
    frame = getattr(args, "part_frame", None)
    if frame is not None and frame != "msys":
        try:
            place(surface, rigid_transform(frame[:3], frame[3:] if len(frame) == 6 else (0.0, 0.0, 0.0)))
        except ValueError as exc:
            raise InputError(f"--part-frame: {exc}", file=args.surface) from None
    return surface


def _msys(program: Any) -> np.ndarray | None:
    """The program's MSYS transform (4x4 MCS -> absolute) when its tool paths have one, else None;
    InputError when they have several different ones."""
    mats = [np.asarray(tp.transform) for tp in getattr(program, "toolpaths", []) or []
            if not np.allclose(tp.transform, np.eye(4))]
    if not mats:
        return None
    for M in mats[1:]:
        if not np.allclose(M, mats[0], atol=1e-9):
            raise InputError("the program has several different MSYS records: give the part's placement as "
                             "--part-frame X,Y,Z,RX,RY,RZ", file=getattr(program, "source", None))
    return mats[0]


def reach_of(program: Any, cutter: Any = None, args: argparse.Namespace | None = None) -> float:
    """How far (mm) a program's point may lie from the part and still be on it: 1 mm for CC points;
    for tool tips the cutter's radius R + r (``cutter``, else --cutter-radius + --corner-radius in
    ``args``, else the largest declared tool) plus 1 mm, 25 mm when no cutter is known."""
    from camsmooth.geometry.paths import CCPath

    if isinstance(program, CCPath):
        return 1.0
    if cutter is not None:
        return float(cutter.R + cutter.r) + 1.0
    if args is not None and getattr(args, "cutter_radius", None) is not None \
            and getattr(args, "corner_radius", None) is not None:
        return float(args.cutter_radius + args.corner_radius) + 1.0
    radii = [0.5 * tp.tool.diameter for tp in getattr(program, "toolpaths", []) or []
             if tp.tool is not None and tp.tool.diameter]
    return max(radii) + 1.0 if radii else 25.0


def place_and_check(args: argparse.Namespace, surface: Any, program: Any, reach: float) -> None:
    """Apply ``--part-frame msys`` (needs a CLSF with an MSYS record), then check that the program's
    cutting points lie within ``reach`` mm of the part; InputError naming the likely cause (a work
    offset with the offset that aligns them, the MSYS, inch vs mm) when most do not."""
    from camsmooth.geometry.paths import CCPath
    from camsmooth.geometry.placement import check_frame, place

    msys = None if isinstance(program, CCPath) else _msys(program)
    if getattr(args, "part_frame", None) == "msys":
        if msys is None:
            raise InputError("--part-frame msys needs a CLSF with an MSYS record; this program has none",
                             file=getattr(program, "source", None))
        try:
            place(surface, msys)
        except ValueError as exc:
            raise InputError(f"--part-frame msys: {exc}", file=args.surface) from None
        msys = None  # applied: not a cause any more
    if isinstance(program, CCPath):
        points = program.points
    else:
        points = program.tip[program.rows >= 0] if len(program.tip) else program.tip
    placed = " (after --part-frame)" if getattr(args, "part_frame", None) is not None else ""
    result = check_frame(points, surface.mesh, reach, msys=msys, what=f"program{placed}",
                         part=f"part {args.surface}")
    if result.message:
        raise InputError(result.message, file=getattr(program, "source", None) or getattr(args, "path", None))


EXACT_WORST = 5  # poses of the written method whose clearance is re-measured on the exact part


def exact_clearance_report(result: Any, surface: Any, worst: int = EXACT_WORST) -> list[str]:
    """Lines for the summary: the ``worst`` smallest clearances of the written method re-measured on
    the exact part (camsmooth.geometry.step.exact_clearance: the tool's signed distance minimised
    over the exact face near the mesh's witness), beside the mesh's figure; a warning line when the
    exact part is gouged beyond the tolerance where the mesh is not. [] without a B-rep."""
    brep = getattr(surface, "brep", None)
    if brep is None:
        return []
    from camsmooth.geometry.clearance import MeshIndex, clearance
    from camsmooth.geometry.step import exact_clearance

    r = result.methods[result.primary]
    ok = np.flatnonzero(np.isfinite(r.delta))
    if len(ok) == 0:
        return []
    k = ok[np.argsort(r.delta[ok])[:worst]]
    mesh_cl = clearance(MeshIndex(surface.mesh), result.cutter, r.cl[k], r.axis[k])
    exact = exact_clearance(brep, result.cutter, r.cl[k], r.axis[k], mesh_cl.witness)
    tol = float(result.result.metrics.tolerance_mm) if result.result.metrics is not None else DEFAULT_TOLERANCE_MM
    pts = "; ".join(f"row {int(r.rows[i])} point {int(r.idx[i])}: mesh {1e3 * r.delta[i]:.4g} um, exact "
                    f"{'-' if not np.isfinite(e) else format(1e3 * e, '.4g')} um"
                    for i, e in zip(k, exact, strict=True))
    lines = [f"clearance on the exact part ({Path(brep.source).name}, B-rep; mesh within {1e3 * brep.deviation:.3g} um "
             f"of it): the {len(k)} smallest of {result.primary}: {pts}"]
    gouged = [int(i) for i, e in zip(k, exact, strict=True) if np.isfinite(e) and e < -tol <= r.delta[i]]
    if gouged:
        lines.append(f"camsmooth: warning: on the exact part, {len(gouged)} of these points gouge beyond the tolerance "
                     f"({1e3 * tol:.3g} um) where the mesh does not (rows {sorted({int(r.rows[i]) for i in gouged})})")
    return lines
