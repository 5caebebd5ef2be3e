"""APT CLDATA in the Siemens NX CLSF dialect -> CLProgram (tool tip and axis per point, mm).

Records read (one per line; ``MAJOR/arg,arg,...`` or a bare major word):

- ``$$`` starts a comment (to the end of the line); a line ending in a single ``$`` continues on
  the next line (APT continuation).
- ``TOOL PATH/name,TOOL,toolname``: starts a tool path (operation); ``END-OF-PATH`` ends it.
  Points outside any tool path form an unnamed one.
- ``TLDATA/MILL,D,R,L,taper,tip[,...]``: the tool path's milling cutter: diameter D, lower corner
  radius R, length L (file units). Other ``TLDATA/`` kinds are kept by name, without dimensions.
- ``LOAD/TOOL,n[,ADJUST,m]`` and ``LOADTL/n``: the tool number.
- ``MSYS/x,y,z,a,b,c,d,e,f``: the machine coordinate system (MCS) the following points are given
  in: origin (x, y, z) and the unit X (a, b, c) and Y (d, e, f) axes of the MCS in the absolute
  (workpiece) frame; Z = X x Y. Points and axes are mapped to the workpiece frame:
  p_W = o + [X Y Z] p_MCS, T_W = [X Y Z] T_MCS.
- ``UNITS/MM`` or ``UNITS/INCHES`` (``INCH``): the length unit. NX often writes no UNITS record for
  an inch part, only inch feeds: without UNITS the unit is taken from the feed units in the file
  (IPM/IPR -> inch, MMPM/MMPR -> mm), else mm (with a warning), unless ``units=`` says. Inch
  coordinates, radii, tool dimensions and feeds are converted to mm (1 in = 25.4 mm).
- ``FEDRAT/[MMPM|IPM|MMPR|IPR|PERMIN|PERREV,]f`` (either order): the feed of the following moves,
  converted to mm/min (per-revolution feeds times the ``SPINDL/[RPM,]n`` speed).
- ``RAPID``: the next motion record is a rapid move (APT RAPID is not modal).
- ``GOTO/x,y,z`` and ``GOTO/x,y,z,i,j,k``: a tool tip position and, when given, the unit tool
  axis (tip -> spindle); the axis is modal (APT starts with (0, 0, 1)). Lines holding only
  numbers after a GOTO are further points of it (multi-point GOTO). ``FROM/`` is read as a
  rapid position.
- ``CIRCLE/xc,yc,zc,i,j,k,r,t,f,d,e``: the next GOTO ends an arc about the centre c and axis
  (i, j, k) of radius r, starting at the current point; NX gives the axis "assuming a clockwise
  direction", i.e. the tool moves clockwise about (i, j, k) (counter-clockwise about -(i, j, k)).
  The arc (a helix when start and end differ along the axis) is replaced by chords whose
  deviation from it is at most ``chord_tol`` mm. A full circle when start = end. ``TIMES,n``
  (multi-turn helix) is refused.
- Known records that do not change the geometry (PAINT, PPRINT, PARTNO, COOLNT, SPINDL, SELECT,
  INSERT, DISPLY, OPSKIP, OPSTOP, STOP, FINI, SET, MACHIN, CLRSRF) are skipped; any other record
  is listed once among the warnings with the lines it appears on (``CUTCOM``, ``CYCLE`` ... are
  not applied).

Sources for the record formats: Siemens NX documentation, "User Defined Operations and CLSF ->
CLSF Manager" (CIRCLE/ argument list, quoted on the Siemens PLM community forum thread "Circle
record explanation"); the MSYS/ and TLDATA/MILL argument lists as documented in STEP Tools'
APT-to-STEP-NC converter (apt2step, Apache-2.0) and the PTC Creo "CLDATA output for circular
interpolation" page (CIRCLE/x,y,z,i,j,k,r after the start GOTO, end GOTO after it); the APT
``$`` continuation and ``$$`` comment syntax and the non-modal RAPID as in that converter.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

import numpy as np

from camsmooth.errors import InputError
from camsmooth.geometry.paths import UNIT_TOL
from camsmooth.io.program import CLProgram, Tool, ToolPath
from camsmooth.io.table import read_text_file

__all__ = ["read_apt", "INCH_MM", "DEFAULT_CHORD_TOL"]

INCH_MM = 25.4
#: default chordal tolerance of the arc interpolation (mm)
DEFAULT_CHORD_TOL = 1e-3
_SKIPPED = {"PAINT", "PPRINT", "PARTNO", "COOLNT", "SELECT", "INSERT", "DISPLY", "OPSKIP", "OPSTOP", "STOP",
            "FINI", "SET", "MACHIN", "CLRSRF", "REMARK", "PPFUN"}
_UNIT_WORDS = {"MM": "mm", "MILLIMETERS": "mm", "INCHES": "inch", "INCH": "inch", "IN": "inch"}
_FEED_UNIT = {"MMPM": ("mm", False), "IPM": ("inch", False), "MMPR": ("mm", True), "IPR": ("inch", True),
              "PERMIN": (None, False), "PERREV": (None, True)}


@dataclass
class _Record:
    line: int
    major: str
    args: list[str]
    text: str


def _records(text: str) -> list[_Record]:
    """Logical records: comments dropped, continuation lines joined, major word upper-cased."""
    out: list[_Record] = []
    pending: tuple[int, str] | None = None
    for number, raw in enumerate(text.split("\n"), start=1):
        body = raw.split("$$", 1)[0].rstrip()
        if pending is not None:
            start, prefix = pending
            body = prefix + body.strip()
        else:
            start = number
        if body.endswith("$"):
            pending = (start, body[:-1].rstrip())
            continue
        pending = None
        body = body.strip()
        if not body:
            continue
        major, slash, rest = body.partition("/")
        args = [a.strip() for a in rest.split(",")] if slash else []
        out.append(_Record(start, major.strip().upper(), args, body))
    if pending is not None:
        out.append(_Record(pending[0], pending[1].partition("/")[0].strip().upper(),
                           [a.strip() for a in pending[1].partition("/")[2].split(",")], pending[1]))
    return out


def _numbers(rec: _Record, file: str, what: str, counts: tuple[int, ...], args: list[str] | None = None
             ) -> list[float]:
    args = rec.args if args is None else args
    if len(args) not in counts:
        want = " or ".join(str(c) for c in counts)
        raise InputError(f"malformed {what}: expected {want} numbers, got {len(args)} ({rec.text!r})", file=file,
                         row=rec.line)
    out = []
    for a in args:
        try:
            v = float(a)
        except ValueError:
            raise InputError(f"malformed {what}: {a!r} is not a number ({rec.text!r})", file=file,
                             row=rec.line) from None
        if not math.isfinite(v):
            raise InputError(f"malformed {what}: {a!r} is not a finite number", file=file, row=rec.line)
        out.append(v)
    return out


def _unit_axis(v: np.ndarray, rec: _Record, file: str, what: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n < 1e-12 or abs(n - 1.0) > UNIT_TOL:
        raise InputError(f"{what} ({', '.join(f'{x:g}' for x in v)}) is not a unit vector (length {n:.9g}, "
                         f"allowed 1 +- {UNIT_TOL:g})", file=file, row=rec.line)
    return v / n


def _file_unit(recs: list[_Record], file: str, units: str | None, warnings: list[str]) -> str:
    if units is not None:
        if units not in ("mm", "inch"):
            raise InputError(f"units must be 'mm' or 'inch', got {units!r}", file=file)
        return units
    for r in recs:
        if r.major == "UNITS":
            word = r.args[0].upper() if r.args else ""
            if word not in _UNIT_WORDS:
                raise InputError(f"unknown units {word or r.text!r} (expected UNITS/MM or UNITS/INCHES)", file=file,
                                 row=r.line)
            return _UNIT_WORDS[word]
    seen: dict[str, int] = {}
    for r in recs:
        if r.major == "FEDRAT":
            for a in r.args:
                u = _FEED_UNIT.get(a.upper(), (None, False))[0]
                if u is not None:
                    seen.setdefault(u, r.line)
    if len(seen) == 2:
        raise InputError(f"cannot tell the length unit: no UNITS/ record and both inch feeds (line {seen['inch']}) "
                         f"and mm feeds (line {seen['mm']})", file=file)
    if seen:
        return next(iter(seen))
    warnings.append("no UNITS/ record and no feed unit: lengths read as mm")
    return "mm"


def _msys(rec: _Record, file: str, scale: float) -> np.ndarray:
    v = _numbers(rec, file, "MSYS", (9,))
    X = _unit_axis(np.array(v[3:6]), rec, file, "MSYS X axis")
    Y = _unit_axis(np.array(v[6:9]), rec, file, "MSYS Y axis")
    if abs(float(X @ Y)) > 1e-4:
        raise InputError(f"MSYS axes are not perpendicular (X.Y = {float(X @ Y):.3g})", file=file, row=rec.line)
    Y = Y - (X @ Y) * X
    Y /= np.linalg.norm(Y)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([X, Y, np.cross(X, Y)])
    T[:3, 3] = np.array(v[:3]) * scale
    return T


@dataclass
class _Arc:
    centre: np.ndarray
    axis: np.ndarray
    radius: float
    line: int


@dataclass
class _State:
    file: str
    scale: float
    unit: str
    chord_tol: float
    pts: list[np.ndarray] = field(default_factory=list)  # MCS tips
    axes: list[np.ndarray] = field(default_factory=list)  # MCS axes
    feed: list[float] = field(default_factory=list)
    rapid: list[bool] = field(default_factory=list)
    line: list[int] = field(default_factory=list)
    xform: list[int] = field(default_factory=list)  # index into transforms per point


def _arc_points(p0: np.ndarray, p1: np.ndarray, arc: _Arc, tol: float, file: str) -> np.ndarray:
    """Intermediate points (k-1, 3) of the arc from p0 to p1 (both excluded), chordal deviation <= tol.

    Rotation: clockwise about arc.axis (NX CLSF convention), i.e. by the right-hand rule about
    n = -axis; the height along n and the radius vary linearly with the angle (helix)."""
    n = -arc.axis
    v0, v1 = p0 - arc.centre, p1 - arc.centre
    h0, h1 = float(v0 @ n), float(v1 @ n)
    u0, u1 = v0 - h0 * n, v1 - h1 * n
    r0, r1 = float(np.linalg.norm(u0)), float(np.linalg.norm(u1))
    slack = max(10 * tol, 1e-3 * arc.radius, 1e-4)
    for r, which in ((r0, "start"), (r1, "end")):
        if abs(r - arc.radius) > slack:
            raise InputError(f"CIRCLE: the arc's {which} point is {r:.6g} mm from the axis, the radius is "
                             f"{arc.radius:.6g} mm", file=file, row=arc.line)
    phi = math.atan2(float(np.cross(u0, u1) @ n), float(u0 @ u1))
    if phi <= 1e-12:
        phi += 2.0 * math.pi  # the sweep is in (0, 2 pi]; start = end is a full circle
    r = max(r0, r1)
    step = 2.0 * math.acos(max(-1.0, 1.0 - tol / r)) if tol < r else math.pi / 2
    k = max(1, math.ceil(phi / min(step, math.pi / 2)))
    s = np.arange(1, k) / k
    th = phi * s
    e1 = u0 / r0
    e2 = np.cross(n, e1)
    rad = r0 + (r1 - r0) * s
    hh = h0 + (h1 - h0) * s
    return arc.centre + (rad * np.cos(th))[:, None] * e1 + (rad * np.sin(th))[:, None] * e2 + hh[:, None] * n


def read_apt(path: str | os.PathLike, chord_tol: float = DEFAULT_CHORD_TOL, units: str | None = None
             ) -> CLProgram:
    """Read an APT CLDATA / NX CLSF file (module docstring) as a CLProgram in mm, workpiece frame.

    chord_tol: chordal tolerance of the CIRCLE interpolation (mm). units: 'mm' or 'inch' to
    override the unit found in the file. InputError naming the file and line for a malformed
    GOTO / CIRCLE / MSYS / FEDRAT / TLDATA, unknown units, a tool axis or MSYS axis that is not
    unit, a CIRCLE not followed by a GOTO, a multi-turn helix, a file without any position.
    """
    file = str(path)
    if not (chord_tol > 0 and math.isfinite(chord_tol)):
        raise InputError(f"chord_tol must be a finite number > 0 mm, got {chord_tol!r}", file=file)
    recs = _records(read_text_file(path, "APT file"))
    warnings: list[str] = []
    unit = _file_unit(recs, file, units, warnings)
    st = _State(file=file, scale=INCH_MM if unit == "inch" else 1.0, unit=unit, chord_tol=chord_tol)
    transforms: list[np.ndarray] = [np.eye(4)]
    cur_xform = 0
    axis = np.array([0.0, 0.0, 1.0])
    feed = math.nan
    feed_unit: tuple[str | None, bool] = (None, False)
    rpm: float | None = None
    rapid_next = False
    arc: _Arc | None = None
    unknown: dict[str, list[int]] = {}
    toolpaths: list[ToolPath] = []
    open_tp: ToolPath | None = None
    last_tool: Tool | None = None
    tool_name: str | None = None
    last_motion = ""
    record_rapid = False

    def start_toolpath(name: str | None, line: int | None) -> ToolPath:
        tp = ToolPath(name=name, tool=None, start=len(st.pts), stop=len(st.pts), line=line,
                      transform=transforms[cur_xform].copy())
        toolpaths.append(tp)
        return tp

    def add_point(p: np.ndarray, a: np.ndarray, rapid: bool, line: int) -> None:
        nonlocal open_tp
        if open_tp is None:
            open_tp = start_toolpath(None, None)
        st.pts.append(p)
        st.axes.append(a)
        st.feed.append(math.nan if rapid else feed)
        st.rapid.append(rapid)
        st.line.append(line)
        st.xform.append(cur_xform)

    for rec in recs:
        m = rec.major
        if m in ("GOTO", "FROM") or (not rec.args and last_motion == "GOTO" and _is_numbers(rec.text)):
            if m not in ("GOTO", "FROM"):  # a further point of a multi-point GOTO
                args = [a.strip() for a in rec.text.split(",")]
            else:
                args = rec.args
            v = _numbers(rec, file, m, (3, 6), args)
            p = np.array(v[:3]) * st.scale
            if len(v) == 6:
                axis = _unit_axis(np.array(v[3:]), rec, file, "tool axis (i, j, k)")
            if m != "GOTO" and m != "FROM":
                rapid = record_rapid  # further points of a multi-point GOTO move like its first
            else:
                rapid = rapid_next or m == "FROM"
                record_rapid = rapid
            if arc is not None:
                if not st.pts:
                    raise InputError("CIRCLE before any position: the arc has no start point", file=file,
                                     row=arc.line)
                p0 = st.pts[-1]
                for q in _arc_points(p0, p, arc, chord_tol, file):
                    add_point(q, axis, rapid, rec.line)
                arc = None
            add_point(p, axis, rapid, rec.line)
            if m == "GOTO":
                rapid_next = False  # RAPID holds for the whole motion record (all its points)
                last_motion = "GOTO"
            continue
        last_motion = m
        if m == "RAPID":
            rapid_next = True
        elif m == "FEDRAT":
            words = [a.upper() for a in rec.args if a and not _is_number(a)]
            nums = [a for a in rec.args if _is_number(a)]
            if len(nums) != 1 or len(words) > 1 or (words and words[0] not in _FEED_UNIT):
                raise InputError(f"malformed FEDRAT: expected FEDRAT/[MMPM|IPM|MMPR|IPR,]f ({rec.text!r})",
                                 file=file, row=rec.line)
            if words:
                feed_unit = _FEED_UNIT[words[0]]
            value = float(nums[0])
            if not (value > 0 and math.isfinite(value)):
                raise InputError(f"FEDRAT must be > 0, got {nums[0]}", file=file, row=rec.line)
            length, per_rev = feed_unit
            scale = INCH_MM if (length or unit) == "inch" else 1.0
            if per_rev:
                if not rpm:
                    raise InputError("feed per revolution without a spindle speed (SPINDL/RPM,n)", file=file,
                                     row=rec.line)
                value *= rpm
            feed = value * scale
        elif m == "SPINDL":
            nums = [float(a) for a in rec.args if _is_number(a)]
            if nums:
                rpm = abs(nums[0])
        elif m == "CIRCLE":
            args = rec.args
            if "TIMES" in [a.upper() for a in args]:
                raise InputError("CIRCLE with TIMES (a helix of several turns) is not supported", file=file,
                                 row=rec.line)
            v = _numbers(rec, file, "CIRCLE", tuple(range(7, 12)), args)
            c_axis = _unit_axis(np.array(v[3:6]), rec, file, "CIRCLE axis")
            if not v[6] > 0:
                raise InputError(f"CIRCLE radius must be > 0, got {v[6]:g}", file=file, row=rec.line)
            arc = _Arc(np.array(v[:3]) * st.scale, c_axis, v[6] * st.scale, rec.line)
        elif m == "MSYS":
            transforms.append(_msys(rec, file, st.scale))
            cur_xform = len(transforms) - 1
            if open_tp is not None and open_tp.start == len(st.pts):
                open_tp.transform = transforms[cur_xform].copy()
        elif m == "UNITS":
            word = rec.args[0].upper() if rec.args else ""
            if word not in _UNIT_WORDS:
                raise InputError(f"unknown units {word or rec.text!r} (expected UNITS/MM or UNITS/INCHES)", file=file,
                                 row=rec.line)
            if units is None:
                unit = _UNIT_WORDS[word]
                st.scale = INCH_MM if unit == "inch" else 1.0
        elif m == "TOOL PATH":
            if open_tp is not None:
                open_tp.stop = len(st.pts)
            tool_name = rec.args[2] if len(rec.args) > 2 and rec.args[1].upper() == "TOOL" else None
            open_tp = start_toolpath(rec.args[0] if rec.args and rec.args[0] else None, rec.line)
            if last_tool is not None and tool_name is not None and last_tool.name == tool_name:
                open_tp.tool = last_tool
        elif m == "END-OF-PATH":
            if arc is not None:
                raise InputError("CIRCLE is not followed by a GOTO (the arc has no end point)", file=file,
                                 row=arc.line)
            if open_tp is not None:
                open_tp.stop = len(st.pts)
                open_tp = None
        elif m == "TLDATA":
            kind = rec.args[0].lower() if rec.args else ""
            if kind == "mill":
                v = _numbers(rec, file, "TLDATA/MILL", tuple(range(3, 12)), rec.args[1:])
                d, r = v[0] * st.scale, v[1] * st.scale
                if not (d > 0 and 0 <= r <= d / 2 + 1e-12):
                    raise InputError(f"TLDATA/MILL: need diameter > 0 and 0 <= corner radius <= diameter / 2, got "
                                     f"D = {v[0]:g}, R = {v[1]:g}", file=file, row=rec.line)
                tool = Tool(name=tool_name, kind="mill", diameter=d, corner_radius=min(r, d / 2),
                            length=v[2] * st.scale, line=rec.line)
            else:
                tool = Tool(name=tool_name, kind=kind or "unknown", diameter=None, corner_radius=None, line=rec.line)
                warnings.append(f"line {rec.line}: TLDATA/{kind.upper()} kept without dimensions (only MILL is read)")
            if open_tp is None:
                open_tp = start_toolpath(None, None)
            open_tp.tool = tool
            last_tool = tool
        elif m in ("LOAD", "LOADTL"):
            nums = [a for a in rec.args if _is_number(a)]
            if nums and open_tp is not None and open_tp.tool is not None:
                open_tp.tool = _with_number(open_tp.tool, int(float(nums[0])))
                last_tool = open_tp.tool
        elif m in _SKIPPED:
            pass
        else:
            unknown.setdefault(m, []).append(rec.line)
    if arc is not None:
        raise InputError("CIRCLE is not followed by a GOTO (the arc has no end point)", file=file, row=arc.line)
    if open_tp is not None:
        open_tp.stop = len(st.pts)
    if not st.pts:
        raise InputError("no GOTO record: the file holds no tool position", file=file)
    for major, lines in unknown.items():
        shown = ", ".join(str(x) for x in lines[:10]) + (f", ... ({len(lines)} in all)" if len(lines) > 10 else "")
        what = "line" if len(lines) == 1 else "lines"
        warnings.append(f"record {major} ignored ({what} {shown})")
    return _program(st, transforms, toolpaths, warnings)


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _is_numbers(text: str) -> bool:
    parts = [p.strip() for p in text.split(",")]
    return len(parts) in (3, 6) and all(_is_number(p) for p in parts)


def _with_number(tool: Tool, number: int) -> Tool:
    return Tool(name=tool.name, kind=tool.kind, diameter=tool.diameter, corner_radius=tool.corner_radius,
                length=tool.length, number=number, line=tool.line)


def _program(st: _State, transforms: list[np.ndarray], toolpaths: list[ToolPath], warnings: list[str]) -> CLProgram:
    P = np.asarray(st.pts, dtype=float)
    T = np.asarray(st.axes, dtype=float)
    xf = np.asarray(st.xform, dtype=np.int64)
    tip, axis = np.empty_like(P), np.empty_like(T)
    for k, M in enumerate(transforms):  # loop over coordinate systems (few), not points
        sel = xf == k
        tip[sel] = P[sel] @ M[:3, :3].T + M[:3, 3]
        axis[sel] = T[sel] @ M[:3, :3].T
    rapid = np.asarray(st.rapid, dtype=bool)
    # rows: runs of feed moves, split by rapids and by tool path boundaries
    tp_id = np.full(len(P), -1, dtype=np.int64)
    for k, tp in enumerate(toolpaths):
        tp_id[tp.start:tp.stop] = k
    new = ~rapid & np.r_[True, rapid[:-1] | (tp_id[1:] != tp_id[:-1])]
    rows = np.where(rapid, -1, np.cumsum(new) - 1)
    feed = np.asarray(st.feed, dtype=float)
    unknown_feed = ~rapid & ~np.isfinite(feed)
    if unknown_feed.any():
        lines = np.asarray(st.line)[unknown_feed]
        warnings.append(f"{int(unknown_feed.sum())} feed move(s) before any FEDRAT (first on line {int(lines[0])}): "
                        "feed unknown (NaN)")
    return CLProgram(tip=tip, axis=axis, rows=rows, feed=feed, rapid=rapid, line=np.asarray(st.line),
                     toolpaths=toolpaths, source=st.file, format="apt", warnings=warnings)
