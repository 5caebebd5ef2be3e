"""APT CLDATA (Siemens NX CLSF, ISO 4343 and other CAM systems' APT) -> CLProgram (tool tip and
axis per point, mm).

Records read (one per line; ``MAJOR/arg,arg,...`` or a bare major word):

- ``$$`` starts a comment (to the end of the line); a line ending in a single ``$`` continues on
  the next line (APT continuation).
- ``TOOL PATH/name,TOOL,toolname``: starts a tool path (operation); ``END-OF-PATH`` ends it.
  Points outside any tool path form an unnamed one.
- ``TLDATA/MILL,D,R,L,taper,tip[,...]``: the tool path's milling cutter: diameter D, lower corner
  radius R, length L (file units; ``TLDATA/MILL,D,R`` without the length is read too). Other
  ``TLDATA/`` kinds are kept by name, without dimensions.
- ``CUTTER/d[,r,e,f,a,b,h]`` (the 7-parameter APT cutter, ISO 4343): a milling cutter of diameter
  d and corner radius r (0 when absent). A ``TLDATA/`` or ``CUTTER/`` after motion in the same
  tool path starts a new tool path (a tool change). Both cover the toroid family
  (camsmooth.geometry.cutter): r = 0 (``TLDATA/MILL,10,0``, ``CUTTER/10``) is a flat end of
  ring radius D/2, r = D/2 a ball end, 0 < r < D/2 a bull nose.
- ``LOAD/TOOL,n[,ADJUST,m]`` and ``LOADTL/n[,...]``: the tool number.
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
  deviation from it is at most ``chord_tol`` mm. A full circle when start = end (within the
  tolerance of the radius check below: a rounded end point a hair past the start).
- ``CIRCLE/xc,yc,zc,i,j,k,r,t,f,d,e,TIMES,n``: a helix about the same axis, in the same sense, of n
  full turns plus the angle from the start to the following GOTO (in [0, 360) deg; an end within
  the tolerance of the start angle ends after exactly n turns). The rise along the axis from the
  start to that GOTO is spread evenly over the whole angle (pitch = rise / turns made); the GOTO
  must lie at the radius (within max(10 chord_tol, 1e-3 r, 1e-4 mm)), else an InputError naming
  the CIRCLE line. Points within ``chord_tol`` of the helix as for the arc. NX's own example of a
  helix record (the forum thread below) gives the centre at the height of the end point; only
  the projection of the centre on the plane normal to the axis is used, so either is read.
- ``CIRCLE/xc,yc,zc,i,j,k`` (SOLIDWORKS CAM: no radius): the next GOTO ends an arc about the
  centre and axis whose radius is the start point's distance from the axis, counter-clockwise
  about (i, j, k) by the right-hand rule (the direction its files show: each lead-in arc ends
  tangent to the arc after it, tests/test_posted_readers.py). ``UNIT/MM`` is read as ``UNITS/``.
- ``MOVARC/xc,yc,zc,i,j,k,r,ANGLE,s`` (ISO 4343, Fusion / HSM): the next GOTO ends an arc about
  the centre c of radius r, counter-clockwise about (i, j, k) (right-hand rule; the post flips the
  normal for a clockwise arc), sweeping s degrees (0 < s <= 360; 360 with start = end is a full
  circle); the sweep must agree with the start and end points.
- ``TLAXIS/i,j,k``: the modal tool axis (as a 6-number GOTO sets it; CATIA writes it before
  3-number GOTOs); other TLAXIS forms (APT source words) are not applied.
- Known records that do not change the geometry are skipped without a warning: text and display
  (PAINT, PPRINT, PARTNO, REMARK, INSERT, DISPLY, CLPRNT, TPRINT, PLABEL, OPNAME, HEADER, LETTER,
  ISN, SEQNO, TMARK, LEADER, TRAILER, VERIFY), machine functions (COOLNT, SPINDL, SELECT, SELCTL,
  AUXFUN, PREFUN, PPFUN, OPSKIP, OPSTOP, STOP, DELAY, DWELL, REWIND, TOOLNO, TLCHG, MACHIN, MODE,
  SET, END, FINI), tolerances and APT source words without motion (INTOL, OUTTOL, TOLER, AUTOPS,
  INDIRV, CLEARP, CLRSRF, PPLOT), MULTAX (no state: a GOTO with 3 numbers keeps the modal axis)
  and ``CYCLE/OFF``. ``MULTAX/OFF`` while the modal axis is tilted is named in a warning: the
  3-number GOTOs after it keep that axis (CATIA's APT locks the last axis; Autodesk's ISO 4343
  post writes MULTAX/OFF for Z-axis sections). Every other record (``CUTCOM``, other ``CYCLE/``
  records, ``GODLTA``, ``TRACUT``, ``ORIGIN``, ``ROTABL``, unknown words ...) is not applied and
  listed in ONE warning with the lines it appears on: ``records ignored (not applied): CUTCOM
  (lines 18, 31); ...``.
- A record is ``MAJOR/args`` or a bare word; spaces may surround the ``/`` (``GOTO / 1, 2, 3``);
  a record without ``/`` whose text holds several words (``PPRINT text``, ``PARTNO name``,
  ``CHANNEL,1``) has its first word as major word.

A file that is not UTF-8 (a CAM system's code page in PPRINT / PARTNO text) is read as Latin-1
with a warning. Numbers beyond +-1e9 (MAX_ABS) are errors. A record that cannot be read costs
only its tool path: the file is cut into tool paths at ``TOOL PATH/`` and ``END-OF-PATH`` (in a
file without ``TOOL PATH/`` records at the tool changes, ``TLDATA/`` and ``CUTTER/``); the bad
tool path's points are dropped, the records up to the next cut are skipped (their modal settings
too), and the program's warnings name it with the file, the line and the reason (``tool path
'NAME' (line L) dropped: FILE, line N: reason``). Only when no tool path could be read is it an
InputError (the error itself when there was one).

Sources for the record formats: Siemens NX documentation, "User Defined Operations and CLSF ->
CLSF Manager" (CIRCLE/ argument list ``CIRCLE/x,y,z,i,j,k,r,t,f,d,e,[TIMES,n]``: centre and axis
"of the curve or helix in MCS", the axis "assuming a clockwise direction", r the radius, t the
total tolerance INTOL + OUTTOL, f = INTOL / t, d the tool diameter, e its corner radius; quoted on
the Siemens PLM community forum thread "Circle record explanation", whose helix example is a
TIMES,2 record followed by its end GOTO; the documentation quoted there does not spell out n, read
here as the full turns made before the final part turn); the MSYS/ and TLDATA/MILL argument
lists as documented in STEP Tools' APT-to-STEP-NC converter (apt2step, Apache-2.0) and the PTC
Creo "CLDATA output for circular interpolation" page (CIRCLE/x,y,z,i,j,k,r after the start GOTO,
end GOTO after it); the APT ``$`` continuation and ``$$`` comment syntax and the non-modal RAPID
as in that converter;
CUTTER/, MOVARC/, MULTAX/, LOADTL/ as written by Autodesk's "Common ISO 4343 APT" post (apt.cps),
which also writes ``PPRINT/'text'`` (text holding '/' and ','), ``COOLNT/ON|flood|MIST|THRU|OFF``,
``CUTCOM/ON|LEFT|RIGHT[,n]|OFF``, ``DELAY/t``, ``CYCLE/DRILL|DEEP|TAP|BORE,...`` (hole positions as
GOTOs) ending with ``CYCLE/OFF``, ``STOP``/``OPSTOP``, ``END``/``FINI`` and ``MULTAX/OFF`` with
3-number GOTOs for Z-axis sections. Other CAM systems' APT: the Vericut help page "Supported
APT-CLS NC Program Records" (the APT words a verifier skips: AUTOPS, AUXFUN, CLPRNT, DELAY,
DISPLY, INSERT, INTOL, OUTTOL, ISN, MACHIN, OPSKIP, PAINT, PARTNO, PPFUN, PREFUN, REMARK, SELCTL,
SELECT, SEQNO, TMARK, TOOLNO, ...; spaces anywhere in a record; ``$`` continues a record), the
CATIA / 3DEXPERIENCE APT format pages (``PARTNO text`` and ``PPRINT text`` without '/',
``GOTO / x, y, z``, ``CUTTER/`` continued with ``$``, ``TOOLNO/``, MULTAX/OFF locking the last
axis, INDIRV/ in APT source), ICAM's CL command list (TLAXIS, MULTAX, CUTTER, FROM, GODLTA) and a
generic APT post-processor's command list (COOLNT, CUTCOM, CYCLE, DWELL, CLEARP, RETRCT, GOHOME,
ROTABL, TRANS, ORIGIN ...; the last five move or transform and are not applied here). No
documentation of PowerMill's or Mastercam's own APT output was found among the references
searched; the corpus files of tests/data/apt named after them are generic APT of that kind.
"""

from __future__ import annotations

import math
import os
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsmooth.errors import InputError
from camsmooth.geometry.paths import UNIT_TOL
from camsmooth.io.program import CLProgram, Tool, ToolPath
from camsmooth.io.table import read_text_file

__all__ = ["read_apt", "INCH_MM", "DEFAULT_CHORD_TOL"]

INCH_MM = 25.4
#: default chordal tolerance of the arc interpolation (mm)
DEFAULT_CHORD_TOL = 1e-3
#: the most points one arc or helix is interpolated with (a larger need is an InputError)
MAX_ARC_POINTS = 1_000_000
#: the most interpolated arc and helix points in one file
MAX_ARC_POINTS_TOTAL = 10_000_000
#: the largest magnitude of a number in a record (lengths in mm or inch, feeds, speeds): larger
#: ones are errors, so that no product or square of them overflows
MAX_ABS = 1e9
#: the most full turns a CIRCLE ... TIMES,n helix may make
MAX_TURNS = 100_000
#: records that change nothing the reader gives (display, text, machine functions, tolerances,
#: post-processor words without motion): skipped without a warning
_SKIPPED = {"PAINT", "PPRINT", "PARTNO", "COOLNT", "SELECT", "INSERT", "DISPLY", "OPSKIP", "OPSTOP", "STOP",
            "END", "FINI", "SET", "MACHIN", "MODE", "MULTAX", "DELAY", "CLRSRF", "REMARK", "PPFUN",
            "AUTOPS", "AUXFUN", "CLPRNT", "DWELL", "HEADER", "INTOL", "OUTTOL", "TOLER", "ISN", "LETTER",
            "PPLOT", "PREFUN", "REWIND", "SELCTL", "SEQNO", "TMARK", "TOOLNO", "TLCHG", "INDIRV", "CLEARP",
            "OPNAME", "TPRINT", "PLABEL", "VERIFY", "LEADER", "TRAILER"}
_UNIT_WORDS = {"MM": "mm", "MILLIMETERS": "mm", "INCHES": "inch", "INCH": "inch", "IN": "inch"}
_FEED_UNIT = {"MMPM": ("mm", False), "IPM": ("inch", False), "MMPR": ("mm", True), "IPR": ("inch", True),
              "PERMIN": (None, False), "PERREV": (None, True)}


@dataclass(slots=True)
class _Record:
    line: int
    major: str
    args: list[str] | None  # None: a plain GOTO whose arguments are split when needed
    text: str
    run: list[str] | None = None  # major "GOTO-RUN": consecutive plain GOTO lines from ``line`` on

    def split(self) -> list[str]:
        if self.args is None:
            self.args = [a.strip() for a in self.text.partition("/")[2].split(",")]
        return self.args


def _records(text: str) -> list[_Record]:
    """Logical records: comments dropped, continuation lines joined, major word upper-cased."""
    out: list[_Record] = []
    pending: tuple[int, str] | None = None
    for number, raw in enumerate(text.split("\n"), start=1):
        if pending is None and raw.startswith("GOTO/") and "$" not in raw:
            # the hot path: consecutive plain GOTO lines are kept as one run, parsed at once later
            last = out[-1] if out else None
            if last is not None and last.run is not None and last.line + len(last.run) == number:
                last.run.append(raw)
            else:
                out.append(_Record(number, "GOTO-RUN", None, "", [raw]))
            continue
        body = raw.split("$$", 1)[0].rstrip() if "$" in raw else raw.rstrip()
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
        out.append(_Record(start, _major(major), args, body))
    if pending is not None:
        major, slash, rest = pending[1].partition("/")
        out.append(_Record(pending[0], _major(major), [a.strip() for a in rest.split(",")] if slash else [],
                           pending[1]))
    return out


def _major(head: str) -> str:
    """The major word of a record from the text before its '/': upper case; a head holding more
    than one word (``PPRINT text``, ``PARTNO name``, ``CHANNEL,1``) is its first word, except
    ``TOOL PATH``."""
    major = head.strip().upper()
    if major != "TOOL PATH" and any(c in major for c in " \t,"):
        words = major.replace(",", " ").split()
        major = words[0] if words else major  # a head of commas alone stays as it is (an unknown record)
    return major


def _numbers(rec: _Record, file: str, what: str, counts: tuple[int, ...], args: list[str] | None = None
             ) -> list[float]:
    args = rec.args if args is None else args
    if len(args) not in counts:
        want = " or ".join(str(c) for c in counts)
        raise InputError(f"malformed {what}: expected {want} numbers, got {len(args)} ({rec.text!r})", file=file,
                         line=rec.line)
    out = []
    for a in args:
        try:
            v = float(a)
        except ValueError:
            raise InputError(f"malformed {what}: {a!r} is not a number ({rec.text!r})", file=file,
                             line=rec.line) from None
        if not math.isfinite(v):
            raise InputError(f"malformed {what}: {a!r} is not a finite number", file=file, line=rec.line)
        if abs(v) > MAX_ABS:
            raise InputError(f"malformed {what}: {a!r} is beyond +-{MAX_ABS:g} (no length, feed or speed of a CAM "
                             "program is that large)", file=file, line=rec.line)
        out.append(v)
    return out


def _goto_numbers(rec: _Record, file: str, what: str, args: list[str]) -> list[float]:
    """The 3 or 6 numbers of a GOTO (fast path; the checked parser names what is wrong)."""
    try:
        v = [float(a) for a in args]
    except ValueError:
        v = []
    # every number compared (NaN fails the comparison); max() would skip a NaN after the first number
    if len(v) in (3, 6) and all(abs(x) <= MAX_ABS for x in v):
        return v
    return _numbers(rec, file, what, (3, 6), args)


def _unit_tuple(i: float, j: float, k: float, rec: _Record, file: str) -> tuple[float, float, float]:
    n = math.sqrt(i * i + j * j + k * k)
    if n < 1e-12 or abs(n - 1.0) > UNIT_TOL:
        _unit_axis(np.array([i, j, k]), rec, file, "tool axis (i, j, k)")
    return (i / n, j / n, k / n)


def _unit_axis(v: np.ndarray, rec: _Record, file: str, what: str) -> np.ndarray:
    with np.errstate(over="ignore", invalid="ignore"):
        n = float(np.linalg.norm(v))
    if n < 1e-12 or abs(n - 1.0) > UNIT_TOL:
        raise InputError(f"{what} ({', '.join(f'{x:g}' for x in v)}) is not a unit vector (length {n:.9g}, "
                         f"allowed 1 +- {UNIT_TOL:g})", file=file, line=rec.line)
    return v / n


def _file_unit(recs: list[_Record], file: str, units: str | None, warnings: list[str]) -> str:
    if units is not None:
        if units not in ("mm", "inch"):
            raise InputError(f"units must be 'mm' or 'inch', got {units!r}", file=file)
        return units
    for r in recs:
        if r.major in ("UNITS", "UNIT"):
            word = r.args[0].upper() if r.args else ""
            if word not in _UNIT_WORDS:
                raise InputError(f"unknown units {word or r.text!r} (expected UNITS/MM or UNITS/INCHES)", file=file,
                                 line=r.line)
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
        raise InputError(f"MSYS axes are not perpendicular (X.Y = {float(X @ Y):.3g})", file=file, line=rec.line)
    Y = Y - (X @ Y) * X
    Y /= np.linalg.norm(Y)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([X, Y, np.cross(X, Y)])
    T[:3, 3] = np.array(v[:3]) * scale
    return T


@dataclass
class _Arc:
    centre: np.ndarray
    normal: np.ndarray  # the motion is counter-clockwise about it (right-hand rule)
    radius: float
    line: int
    record: str  # CIRCLE or MOVARC, for messages
    sweep: float | None = None  # rad, when the record gives it (MOVARC ANGLE)
    turns: int = 0  # CIRCLE ... TIMES,n: full turns before the angle to the end point (helix)


@dataclass
class _State:
    """Points in MCS coordinates, in blocks (numpy) and a pending list of single points."""

    file: str
    scale: float
    unit: str
    chord_tol: float
    blocks: list[tuple[np.ndarray, ...]] = field(default_factory=list)
    pending: list[tuple] = field(default_factory=list)  # (p, axis, rapid, feed, line, xform)
    done: int = 0
    last: tuple | None = None

    @property
    def count(self) -> int:
        return self.done + len(self.pending)

    def add(self, p: tuple, a: tuple, rapid: bool, feed: float, line: int, xform: int) -> None:
        self.pending.append((p, a, rapid, math.nan if rapid else feed, line, xform))
        self.last = p

    def flush(self) -> None:
        if self.pending:
            p, a, r, f, ln, x = zip(*self.pending, strict=True)
            self.blocks.append((np.asarray(p, float), np.asarray(a, float), np.asarray(r, bool),
                                np.asarray(f, float), np.asarray(ln, np.int64), np.asarray(x, np.int64)))
            self.done += len(self.pending)
            self.pending = []

    def add_block(self, P: np.ndarray, T: np.ndarray, rapid: np.ndarray, feed: np.ndarray, line: np.ndarray,
                  xform: int) -> None:
        self.flush()
        self.blocks.append((P, T, rapid, feed, line, np.full(len(P), xform, np.int64)))
        self.done += len(P)
        self.last = tuple(P[-1].tolist())

    def truncate(self, n: int) -> None:
        """Drop the points from index n on."""
        self.flush()
        while self.blocks and self.done - len(self.blocks[-1][0]) >= n:
            self.done -= len(self.blocks.pop()[0])
        if self.done > n:
            keep = len(self.blocks[-1][0]) - (self.done - n)
            self.blocks[-1] = tuple(b[:keep] for b in self.blocks[-1])
            self.done = n
        self.last = tuple(self.blocks[-1][0][-1].tolist()) if self.blocks else None

    def arrays(self) -> tuple[np.ndarray, ...]:
        self.flush()
        return tuple(np.concatenate([b[k] for b in self.blocks]) for k in range(6))


def _bulk_goto(run: list[str], scale: float, axis: tuple) -> tuple[np.ndarray, np.ndarray] | None:
    """Tips (n, 3) and modal axes (n, 3) of a run of plain GOTO records parsed at once (numpy), or
    None when any record is malformed (the record-by-record path then names it)."""
    import io

    rests = [r[5:] for r in run]
    n = len(run)
    try:  # the usual case: every record of the run has the same count (3 or 6)
        arr = np.loadtxt(io.StringIO("\n".join(rests)), delimiter=",", ndmin=2, comments=None)
        counts = np.full(n, arr.shape[1], dtype=np.int64) if arr.shape[0] == n else None
    except ValueError:
        counts = None
    if counts is None:
        counts = np.fromiter((x.count(",") for x in rests), dtype=np.int64, count=n) + 1
        arr = None
    if not np.isin(counts, (3, 6)).all():
        return None
    P = np.empty((n, 3))
    given = np.full(n, -1, dtype=np.int64)
    V = np.zeros((0, 3))
    for c in (3, 6):
        sel = np.flatnonzero(counts == c)
        if not len(sel):
            continue
        if arr is not None:
            part = arr
        else:
            try:
                part = np.loadtxt(io.StringIO("\n".join(rests[k] for k in sel)), delimiter=",", ndmin=2,
                                  comments=None)
            except ValueError:
                return None
        if part.shape != (len(sel), c) or not (np.abs(part) <= MAX_ABS).all():
            return None
        P[sel] = part[:, :3]
        if c == 6:
            norm = np.linalg.norm(part[:, 3:], axis=1)
            if ((norm < 1e-12) | (np.abs(norm - 1.0) > UNIT_TOL)).any():
                return None
            V = part[:, 3:] / norm[:, None]
            given[sel] = np.arange(len(sel))
    ff = np.maximum.accumulate(given)
    T = np.where((ff >= 0)[:, None], V[np.maximum(ff, 0)] if len(V) else 0.0, np.asarray(axis, float))
    return P * scale, T


def _arc_points(p0: np.ndarray, p1: np.ndarray, arc: _Arc, tol: float, file: str) -> np.ndarray:
    """Intermediate points (k-1, 3) of the arc from p0 to p1 (both excluded), chordal deviation <= tol.

    Rotation: by the right-hand rule about arc.normal, through ``arc.turns`` full turns plus the
    angle from p0 to p1; the height along the normal and the radius vary linearly with the angle
    (a helix whose pitch is the rise from p0 to p1 over the turns made)."""
    n = arc.normal
    v0, v1 = p0 - arc.centre, p1 - arc.centre
    h0, h1 = float(v0 @ n), float(v1 @ n)
    u0, u1 = v0 - h0 * n, v1 - h1 * n
    r0, r1 = float(np.linalg.norm(u0)), float(np.linalg.norm(u1))
    slack = max(10 * tol, 1e-3 * arc.radius, 1e-4)
    what = f"{arc.record} TIMES,{arc.turns}" if arc.turns else arc.record
    for r, which in ((r0, "start"), (r1, "end")):
        if abs(r - arc.radius) > slack:
            raise InputError(f"{what}: the arc's {which} point is {r:.6g} mm from the axis, the radius is "
                             f"{arc.radius:.6g} mm", file=file, line=arc.line)
        if not r > 1e-9:
            raise InputError(f"{what}: the arc's {which} point lies on the axis (radius {arc.radius:.6g} mm): it "
                             "gives no angle", file=file, line=arc.line)
    phi = math.atan2(float(np.cross(u0, u1) @ n), float(u0 @ u1))
    if arc.turns:
        # n full turns plus the angle to the end point in [0, 2 pi); an end point within the
        # tolerance of the start angle ends after exactly n turns
        if phi < 0:
            phi += 2.0 * math.pi
        if min(phi, 2.0 * math.pi - phi) * arc.radius <= slack:
            phi = 0.0
        phi += 2.0 * math.pi * arc.turns
    elif phi <= 1e-12 or (arc.sweep is None and phi * arc.radius <= slack):
        phi += 2.0 * math.pi  # the sweep is in (0, 2 pi]; start = end (within the tolerance) is a full circle
    if arc.sweep is not None:
        # the points decide; where start and end are within the tolerance of each other their angle
        # is known only modulo a turn (a tiny arc or a full circle): the record's sweep decides
        if abs(phi - arc.sweep) * arc.radius > slack:
            if min(abs(phi + 2 * math.pi - arc.sweep), abs(phi - 2 * math.pi - arc.sweep)) * arc.radius <= slack:
                phi = arc.sweep
            else:
                raise InputError(f"{arc.record}: the sweep is {math.degrees(arc.sweep):.6g} deg but the start and "
                                 f"end points are {math.degrees(phi):.6g} deg apart counter-clockwise about the "
                                 "normal", file=file, line=arc.line)
    r = max(r0, r1)
    step = 2.0 * math.acos(max(-1.0, 1.0 - tol / r)) if tol < r else math.pi / 2
    k_float = phi / min(step, math.pi / 2)
    if not k_float <= MAX_ARC_POINTS:
        raise InputError(f"{what}: {k_float:.3g} points would be needed to keep the chord error within {tol:g} mm "
                         f"(radius {r:.6g} mm, sweep {math.degrees(phi):.6g} deg; at most {MAX_ARC_POINTS} per arc): "
                         "raise chord_tol", file=file, line=arc.line)
    k = max(1, math.ceil(k_float))
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
    override the unit found in the file. A record that cannot be read (a malformed GOTO / CIRCLE /
    MOVARC / MSYS / FEDRAT / TLDATA / CUTTER / LOAD, a tool axis or MSYS axis that is not unit, a
    CIRCLE not followed by a GOTO, a helix whose end GOTO is off its radius, a number beyond
    MAX_ABS) drops its tool path with a warning naming the file, the line and the reason; it is an
    InputError naming them when no tool path could be read. InputError for unknown units and a
    file without any position.
    """
    file = str(path)
    if not (chord_tol > 0 and math.isfinite(chord_tol)):
        raise InputError(f"chord_tol must be a finite number > 0 mm, got {chord_tol!r}", file=file)
    warnings: list[str] = []
    recs = _records(_apt_text(path, warnings))
    unit = _file_unit(recs, file, units, warnings)
    st = _State(file=file, scale=INCH_MM if unit == "inch" else 1.0, unit=unit, chord_tol=chord_tol)
    transforms: list[np.ndarray] = [np.eye(4)]
    cur_xform = 0
    axis = (0.0, 0.0, 1.0)
    feed = math.nan
    feed_unit: tuple[str | None, bool] = (None, False)
    rpm: float | None = None
    rapid_next = False
    arc: _Arc | None = None
    unknown: dict[str, list[int]] = {}
    arc_points = 0  # interpolated arc points so far
    multax_off: list[tuple[int, tuple]] = []  # MULTAX/OFF while the modal axis is tilted: (line, axis)
    toolpaths: list[ToolPath] = []
    open_tp: ToolPath | None = None
    last_tool: Tool | None = None
    tool_name: str | None = None
    last_motion = ""
    record_rapid = False

    def start_toolpath(name: str | None, line: int | None) -> ToolPath:
        tp = ToolPath(name=name, tool=None, start=st.count, stop=st.count, line=line,
                      transform=transforms[cur_xform].copy())
        toolpaths.append(tp)
        first_line[id(tp)] = cur_line
        return tp

    def add_point(p: tuple, a: tuple, rapid: bool, line: int) -> None:
        nonlocal open_tp
        if open_tp is None:
            open_tp = start_toolpath(None, None)
        st.add(p, a, rapid, feed, line, cur_xform)

    # a record that cannot be read costs only its tool path: the file is cut into tool paths at
    # TOOL PATH/ and END-OF-PATH (files without TOOL PATH/ records: at tool changes, TLDATA/ and
    # CUTTER/); the bad one's points are dropped and the records up to the next cut skipped
    boundaries = {"TOOL PATH", "END-OF-PATH"}
    if not any(r.major == "TOOL PATH" for r in recs):
        boundaries |= {"TLDATA", "CUTTER"}
    dropped: list[InputError] = []
    skipping = False
    first_line: dict[int, int] = {}  # id(tool path) -> the line of the record that opened it

    def drop(exc: InputError, major: str) -> None:
        nonlocal open_tp, arc, rapid_next, record_rapid, last_motion, skipping
        tp = open_tp
        if tp is not None and major in boundaries and major != "END-OF-PATH" and st.count > tp.start:
            tp.stop = st.count  # a bad tool change: the tool path before it is whole, the new one is lost
            tp = None
        if tp is not None:
            st.truncate(tp.start)
            k = next(k for k, t in enumerate(toolpaths) if t is tp)
            del toolpaths[k]
            line = tp.line if tp.line is not None else first_line.get(id(tp), exc.line)
            desc = f"'{tp.name}' (line {line})" if tp.name else f"(unnamed, from line {line})"
        else:
            desc = f"(unnamed, from line {exc.line})"
        dropped.append(exc)
        warnings.append(f"tool path {desc} dropped: {exc}")
        open_tp, arc = None, None
        rapid_next = record_rapid = False
        last_motion = ""
        skipping = major != "END-OF-PATH"  # a bad END-OF-PATH (an arc without end) is the cut itself

    queue: deque[_Record] = deque()
    i = 0
    cur_line = 0
    while i < len(recs) or queue:
        if queue:
            rec = queue.popleft()
        else:
            rec = recs[i]
            i += 1
        if skipping:
            if rec.major not in boundaries:
                continue
            skipping = False
            if rec.major == "END-OF-PATH":
                continue
        cur_line = rec.line
        try:
            m = rec.major
            if m == "GOTO-RUN":
                texts = rec.run or []
                if arc is not None:  # the first GOTO ends an arc: on its own, then the rest as a run
                    queue.appendleft(_Record(rec.line, "GOTO", None, texts[0].rstrip()))
                    if len(texts) > 1:
                        queue.insert(1, _Record(rec.line + 1, "GOTO-RUN", None, "", texts[1:]))
                    continue
                got = _bulk_goto(texts, st.scale, axis) if len(texts) >= 16 else None
                if got is None:  # short, or something to report: record by record
                    queue.extendleft(_Record(rec.line + k, "GOTO", None, t.rstrip()) for k, t in
                                     reversed(list(enumerate(texts))))
                    continue
                P, Tm = got
                if open_tp is None:
                    open_tp = start_toolpath(None, None)
                rap = np.zeros(len(P), dtype=bool)
                rap[0] = rapid_next
                st.add_block(P, Tm, rap, np.where(rap, np.nan, feed), np.arange(rec.line, rec.line + len(P)), cur_xform)
                axis = tuple(Tm[-1].tolist())
                rapid_next = record_rapid = False
                last_motion = "GOTO"
                continue
            if m in ("GOTO", "FROM") or (rec.args == [] and last_motion == "GOTO" and _is_numbers(rec.text)):
                if m not in ("GOTO", "FROM"):  # a further point of a multi-point GOTO
                    args = [a.strip() for a in rec.text.split(",")]
                else:
                    args = rec.split()
                v = _goto_numbers(rec, file, m, args)
                sc = st.scale
                p = (v[0] * sc, v[1] * sc, v[2] * sc)
                if len(v) == 6:
                    axis = _unit_tuple(v[3], v[4], v[5], rec, file)
                if m != "GOTO" and m != "FROM":
                    rapid = record_rapid  # further points of a multi-point GOTO move like its first
                else:
                    rapid = rapid_next or m == "FROM"
                    record_rapid = rapid
                if arc is not None:
                    if st.last is None:
                        raise InputError(f"{arc.record} before any position: the arc has no start point", file=file,
                                         line=arc.line)
                    if math.isnan(arc.radius):  # a CIRCLE without radius: the start point's distance from the axis
                        u0 = np.array(st.last) - arc.centre
                        arc.radius = float(np.linalg.norm(u0 - (u0 @ arc.normal) * arc.normal))
                    Q = _arc_points(np.array(st.last), np.array(p), arc, chord_tol, file)
                    arc_points += len(Q)
                    if arc_points > MAX_ARC_POINTS_TOTAL:
                        raise InputError(f"{arc.record}: the arcs up to here need {arc_points} points to keep the "
                                         f"chord error within {chord_tol:g} mm (at most {MAX_ARC_POINTS_TOTAL} in a "
                                         "file): raise chord_tol", file=file, line=arc.line)
                    if len(Q):
                        if open_tp is None:
                            open_tp = start_toolpath(None, None)
                        n = len(Q)
                        st.add_block(Q, np.tile(np.asarray(axis, float), (n, 1)), np.full(n, rapid),
                                     np.full(n, math.nan if rapid else feed), np.full(n, rec.line, np.int64), cur_xform)
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
                                     file=file, line=rec.line)
                if words:
                    feed_unit = _FEED_UNIT[words[0]]
                value = float(nums[0])
                if not (0 < value <= MAX_ABS):
                    raise InputError(f"FEDRAT must be > 0 and at most {MAX_ABS:g}, got {nums[0]}", file=file,
                                     line=rec.line)
                length, per_rev = feed_unit
                scale = INCH_MM if (length or unit) == "inch" else 1.0
                if per_rev:
                    if not rpm:
                        raise InputError("feed per revolution without a spindle speed (SPINDL/RPM,n)", file=file,
                                         line=rec.line)
                    value *= rpm
                feed = value * scale
            elif m == "SPINDL":
                nums = [float(a) for a in rec.args if _is_number(a)]
                if nums:
                    if not abs(nums[0]) <= MAX_ABS:
                        raise InputError(f"malformed SPINDL: the speed {nums[0]:g} is not a number up to {MAX_ABS:g}",
                                         file=file, line=rec.line)
                    rpm = abs(nums[0])
            elif m == "CIRCLE":
                args, turns = _circle_times(rec, file)
                v = _numbers(rec, file, "CIRCLE", tuple(range(6, 12)), args)
                c_axis = _unit_axis(np.array(v[3:6]), rec, file, "CIRCLE axis")
                if len(v) == 6:
                    # SOLIDWORKS CAM: centre and axis, no radius (the start point's distance from the
                    # axis), the motion counter-clockwise about the axis (right-hand rule)
                    arc = _Arc(np.array(v[:3]) * st.scale, c_axis, math.nan, rec.line, "CIRCLE", turns=turns)
                elif not v[6] > 0:
                    raise InputError(f"CIRCLE radius must be > 0, got {v[6]:g}", file=file, line=rec.line)
                else:  # NX gives the axis for a clockwise motion: counter-clockwise about its opposite
                    arc = _Arc(np.array(v[:3]) * st.scale, -c_axis, v[6] * st.scale, rec.line, "CIRCLE", turns=turns)
            elif m == "MOVARC":
                words = [a.upper() for a in rec.args]
                if len(rec.args) != 9 or words[7] != "ANGLE":
                    raise InputError(f"malformed MOVARC: expected MOVARC/xc,yc,zc,i,j,k,r,ANGLE,sweep ({rec.text!r})",
                                     file=file, line=rec.line)
                v = _numbers(rec, file, "MOVARC", (8,), rec.args[:7] + rec.args[8:])
                normal = _unit_axis(np.array(v[3:6]), rec, file, "MOVARC normal")
                if not v[6] > 0:
                    raise InputError(f"MOVARC radius must be > 0, got {v[6]:g}", file=file, line=rec.line)
                if not 0 < v[7] <= 360 + 1e-9:
                    raise InputError(f"MOVARC sweep must be in (0, 360] deg (several turns are not supported), got "
                                     f"{v[7]:g}", file=file, line=rec.line)
                arc = _Arc(np.array(v[:3]) * st.scale, normal, v[6] * st.scale, rec.line, "MOVARC",
                           math.radians(min(v[7], 360.0)))
            elif m == "MSYS":
                transforms.append(_msys(rec, file, st.scale))
                cur_xform = len(transforms) - 1
                if open_tp is not None and open_tp.start == st.count:
                    open_tp.transform = transforms[cur_xform].copy()
            elif m in ("UNITS", "UNIT"):  # SOLIDWORKS CAM writes UNIT/MM
                word = rec.args[0].upper() if rec.args else ""
                if word not in _UNIT_WORDS:
                    raise InputError(f"unknown units {word or rec.text!r} (expected UNITS/MM or UNITS/INCHES)",
                                     file=file, line=rec.line)
                if units is None:
                    unit = _UNIT_WORDS[word]
                    st.scale = INCH_MM if unit == "inch" else 1.0
            elif m == "TOOL PATH":
                if open_tp is not None:
                    open_tp.stop = st.count
                tool_name = rec.args[2] if len(rec.args) > 2 and rec.args[1].upper() == "TOOL" else None
                open_tp = start_toolpath(rec.args[0] if rec.args and rec.args[0] else None, rec.line)
                if last_tool is not None and tool_name is not None and last_tool.name == tool_name:
                    open_tp.tool = last_tool
            elif m == "END-OF-PATH":
                if arc is not None:
                    raise InputError(f"{arc.record} is not followed by a GOTO (the arc has no end point)", file=file,
                                     line=arc.line)
                if open_tp is not None:
                    open_tp.stop = st.count
                    open_tp = None
            elif m in ("TLDATA", "CUTTER"):
                if m == "CUTTER":
                    v = _numbers(rec, file, "CUTTER", tuple(range(1, 8)), rec.args)
                    tool = _mill(v[0], v[1] if len(v) > 1 else 0.0, None, "CUTTER", rec, file, st.scale, tool_name)
                elif rec.args and rec.args[0].lower() == "mill":
                    v = _numbers(rec, file, "TLDATA/MILL", tuple(range(2, 12)), rec.args[1:])
                    tool = _mill(v[0], v[1], v[2] if len(v) > 2 else None, "TLDATA/MILL", rec, file, st.scale,
                                 tool_name)
                else:
                    kind = rec.args[0].lower() if rec.args else ""
                    tool = Tool(name=tool_name, kind=kind or "unknown", diameter=None, corner_radius=None,
                                line=rec.line)
                    warnings.append(f"line {rec.line}: TLDATA/{kind.upper()} kept without dimensions "
                                    "(only MILL is read)")
                if open_tp is not None and st.count > open_tp.start and open_tp.tool is not None:
                    open_tp.stop = st.count  # a tool change after motion: the next points are another tool path
                    open_tp = start_toolpath(None, rec.line)
                if open_tp is None:
                    open_tp = start_toolpath(None, None)
                open_tp.tool = tool
                last_tool = tool
            elif m in ("LOAD", "LOADTL"):
                nums = [float(a) for a in rec.args if _is_number(a)]
                if nums and not (math.isfinite(nums[0]) and nums[0] == int(nums[0]) and abs(nums[0]) < 2**31):
                    raise InputError(f"malformed {m}: the tool number {nums[0]:g} is not a whole number ({rec.text!r})",
                                     file=file, line=rec.line)
                if nums and open_tp is not None and open_tp.tool is not None:
                    open_tp.tool = _with_number(open_tp.tool, int(nums[0]))
                    last_tool = open_tp.tool
            elif m == "TLAXIS" and len(rec.args) == 3 and all(_is_number(a) for a in rec.args):
                v = _numbers(rec, file, "TLAXIS", (3,))
                axis = _unit_tuple(v[0], v[1], v[2], rec, file)  # the modal axis of 3-number GOTOs
            elif m == "MULTAX" and [a.upper() for a in rec.args] == ["OFF"] and abs(axis[2] - 1.0) > 1e-9:
                multax_off.append((rec.line, axis))
            elif m in _SKIPPED or (m == "CYCLE" and [a.upper() for a in rec.args] in (["OFF"], ["INIT"])):
                pass
            else:
                unknown.setdefault(m or rec.text.strip()[:40], []).append(rec.line)
        except InputError as exc:
            drop(exc, rec.major)
    if arc is not None:
        try:
            raise InputError(f"{arc.record} is not followed by a GOTO (the arc has no end point)", file=file,
                             line=arc.line)
        except InputError as exc:
            drop(exc, "")
    if open_tp is not None:
        open_tp.stop = st.count
    if st.count == 0:
        if len(dropped) == 1:
            raise dropped[0]
        if dropped:
            raise InputError(f"no tool path could be read: all {len(dropped)} were dropped (the first: "
                             f"{dropped[0].message}, line {dropped[0].line})", file=file, line=dropped[0].line)
        raise InputError("no GOTO record: the file holds no tool position", file=file)
    if multax_off:
        ln, a = multax_off[0]
        more = f" (and {len(multax_off) - 1} more)" if len(multax_off) > 1 else ""
        warnings.append(f"MULTAX/OFF on line {ln}{more} while the tool axis is tilted: the 3-number GOTOs after it "
                        f"keep the last axis ({a[0]:.6g}, {a[1]:.6g}, {a[2]:.6g}) as APT locks it; a post meaning "
                        "the Z axis there (a Fusion / HSM 3-axis section) gives the axis as a 6-number GOTO")
    if unknown:  # one warning for all the records not applied
        parts = []
        for major, lines in unknown.items():
            shown = ", ".join(str(x) for x in lines[:10]) + (f", ... ({len(lines)} in all)" if len(lines) > 10 else "")
            parts.append(f"{major[:40]} ({'line' if len(lines) == 1 else 'lines'} {shown})")
        if len(parts) > 20:
            parts = parts[:20] + [f"and {len(parts) - 20} more"]
        warnings.append(f"records ignored (not applied): {'; '.join(parts)}")
    program = _program(st, transforms, toolpaths, warnings)
    if program.rapid.all():  # FROM/, RAPID GOTOs, GOHOME only (a drilling CLSF whose holes are reached by rapids)
        raise InputError(f"no cutting move: all {len(program)} positions are rapid (FROM/, GOTO after RAPID); the file "
                         "holds no feed motion to analyse or smooth", file=file,
                         line=int(program.line[0]) if len(program) else None)
    return program


def _mill(d: float, r: float, length: float | None, what: str, rec: _Record, file: str, scale: float,
          name: str | None) -> Tool:
    """A milling cutter of diameter d and corner radius r (file units) as a Tool in mm."""
    if not (d > 0 and 0 <= r <= d / 2 + 1e-12):
        raise InputError(f"{what}: need diameter > 0 and 0 <= corner radius <= diameter / 2, got D = {d:g}, "
                         f"R = {r:g}", file=file, line=rec.line)
    return Tool(name=name, kind="mill", diameter=d * scale, corner_radius=min(r, d / 2) * scale,
                length=None if length is None else length * scale, line=rec.line)


def _apt_text(path: str | os.PathLike, warnings: list[str]) -> str:
    """The file's text: UTF-8, or else Latin-1 with a warning (CAM systems on Windows write
    PPRINT / PARTNO text in their code page: 'Fräser Ø10'; the records themselves are ASCII)."""
    try:
        return read_text_file(path, "APT file")
    except InputError as exc:
        if "is not UTF-8 text" not in exc.message:
            raise
        reason = exc.message
    raw = Path(path).read_bytes()
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    warnings.append(f"{reason}: read as Latin-1 (only text records such as PPRINT should hold such bytes)")
    return raw.decode("latin-1").replace("\r\n", "\n").replace("\r", "\n")


def _circle_times(rec: _Record, file: str) -> tuple[list[str], int]:
    """The CIRCLE arguments before ``TIMES`` and the number of full turns n after it (0 without)."""
    words = [a.upper() for a in rec.args]
    if "TIMES" not in words:
        return rec.args, 0
    k = words.index("TIMES")
    tail = rec.args[k + 1:]
    try:
        n = float(tail[0]) if len(tail) == 1 else math.nan
    except ValueError:
        n = math.nan
    if not (math.isfinite(n) and n >= 0 and n == int(n) and n <= MAX_TURNS):
        raise InputError(f"malformed CIRCLE: TIMES must be followed by one whole number of turns 0..{MAX_TURNS} "
                         f"({rec.text!r})", file=file, line=rec.line)
    return rec.args[:k], int(n)


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
    P, T, rapid, feed, line, xf = st.arrays()
    tip, axis = np.empty_like(P), np.empty_like(T)
    for k, M in enumerate(transforms):  # loop over coordinate systems (few), not points
        sel = xf == k
        # einsum: (N, 3) x (3, 3) through BLAS matmul is slower here than the plain sum of products
        tip[sel] = np.einsum("ij,kj->ik", P[sel], M[:3, :3]) + M[:3, 3]
        axis[sel] = np.einsum("ij,kj->ik", T[sel], M[:3, :3])
    # rows: runs of feed moves, split by rapids and by tool path boundaries
    tp_id = np.full(len(P), -1, dtype=np.int64)
    for k, tp in enumerate(toolpaths):
        tp_id[tp.start:tp.stop] = k
    new = ~rapid & np.r_[True, rapid[:-1] | (tp_id[1:] != tp_id[:-1])]
    rows = np.where(rapid, -1, np.cumsum(new) - 1)
    unknown_feed = ~rapid & ~np.isfinite(feed)
    if unknown_feed.any():
        lines = line[unknown_feed]
        warnings.append(f"{int(unknown_feed.sum())} feed move(s) before any FEDRAT (first on line {int(lines[0])}): "
                        "feed unknown (NaN)")
    return CLProgram(tip=tip, axis=axis, rows=rows, feed=feed, rapid=rapid, line=line,
                     toolpaths=toolpaths, source=st.file, format="apt", warnings=warnings)
