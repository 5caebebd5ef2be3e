"""Programs as they come in: the typed result of every program reader (CLProgram, Tool, ToolPath,
Cycle, Written), the detection of a program file's format from its content (``detect_format``),
camsmooth's result CSV read as the program it describes, and the CL table ``analyze --cl``
writes. The one entry point that picks the reader is camsmooth.post.load_program (it reaches the
G-code readers of the post layer, above this one).

A cutter-location (CL) program is a sequence of tool poses: the tool tip (the centre of the
cutter's bottom face, CONVENTIONS.md) and the unit tool axis from the tip toward the spindle, in
the workpiece frame, mm.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.geometry.paths import CCPath

__all__ = ["Tool", "ToolPath", "CLProgram", "Cycle", "detect_format", "FORMATS", "read_result_program",
           "CL_COLUMNS", "cl_columns", "cl_of_cc", "write_cl_table"]


@dataclass(frozen=True)
class Tool:
    """A cutter as a CAM program declares it (APT ``TLDATA/MILL,D,R,L,...``).

    kind: 'mill' (others as named by the file, lower case). diameter D and corner_radius r in
    mm; a toroidal cutter has ring radius R = D/2 - r (CONVENTIONS.md: D = 2 (R + r)); a ball
    end mill has r = D/2, a flat end mill r = 0. length: mm or None. name: the CAM tool name;
    number: the tool number (``LOAD/TOOL,n``) or None. line: the line of the record that defined
    it.
    """

    name: str | None
    kind: str
    diameter: float | None
    corner_radius: float | None
    length: float | None = None
    number: int | None = None
    line: int | None = None

    @property
    def ring_radius(self) -> float | None:
        """R = D/2 - r (mm), the radius of the corner's centre circle; None when unknown."""
        if self.diameter is None or self.corner_radius is None:
            return None
        return 0.5 * self.diameter - self.corner_radius


@dataclass
class ToolPath:
    """One tool path (CAM operation) of a program: points ``start:stop`` of the CLProgram.

    name: the operation name (``TOOL PATH/name``) or None; tool: the cutter or None when the file
    declares none; line: the line that started it (None for formats without tool paths);
    transform: the 4x4 MCS -> workpiece transform applied to its first point (identity when none;
    a posted program: its tilted frame). kind: 'motion' (CL data), '5-axis' (a posted operation
    whose rotary axes move while cutting), '3+2' (in a tilted frame), 'cycle' (canned cycles only).
    """

    name: str | None
    tool: Tool | None
    start: int
    stop: int
    line: int | None = None
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    kind: str = "motion"

    @property
    def points(self) -> slice:
        return slice(self.start, self.stop)


@dataclass
class Cycle:
    """A canned cycle of a posted program (G81-G89, G73, G74, G76; CYCLE81...; CYCL DEF 200...):
    listed, not smoothed. code: the word ('G83'); line: its first line; text: that block; holes:
    (N, 3) the bottom of each hole, mm, workpiece frame; lines: the line of each block that made
    holes; operation: index of the operation in the reader's list, op_name its name."""

    code: str
    line: int
    text: str
    holes: np.ndarray
    operation: int
    lines: list[int] = field(default_factory=list)
    modal: bool = True
    op_name: str | None = None


@dataclass
class Written:
    """What camsmooth wrote beside the poses of its own output (a result CSV or G-code), so that
    ``analyze`` evaluates the program as ``smooth`` did (camsmooth.smoothing.evaluate).

    method: the smoothing method ('nlp', ...) or None; tolerance: mm, the run's, or None;
    every_point: all of smooth's points are written (False for the longer blocks of a modelled
    controller, camsmooth.controller); dialect: the G-code dialect it was written for (None: CSV).
    Per point (None where not written): t s from the row's
    start at the programmed feed; feed mm/min, the programmed feed; t_plan s from the row's start,
    the time law the program commands (G93 block times, the CSV's ``t_opt``); t_blocks s from the
    row's start, the law of the G-code's own F words (its controller's block times, which the
    controller runs as written); row_id, idx: smooth's
    row id and index in the row; cc, normals (mm; CSV); delta (mm) and status (CSV).
    """

    method: str | None = None
    tolerance: float | None = None
    every_point: bool = True
    dialect: str | None = None
    t: np.ndarray | None = None
    feed: np.ndarray | None = None
    t_plan: np.ndarray | None = None
    t_blocks: np.ndarray | None = None
    row_id: np.ndarray | None = None
    idx: np.ndarray | None = None
    cc: np.ndarray | None = None
    normals: np.ndarray | None = None
    delta: np.ndarray | None = None
    status: np.ndarray | None = None

    _PER_POINT = ("t", "feed", "t_plan", "t_blocks", "row_id", "idx", "cc", "normals", "delta", "status")

    def take(self, keep: np.ndarray) -> Written:
        """A copy with the per-point arrays at the points ``keep`` (bool mask or indices)."""
        per = {k: (None if getattr(self, k) is None else getattr(self, k)[keep]) for k in self._PER_POINT}
        return Written(method=self.method, tolerance=self.tolerance, every_point=self.every_point,
                       dialect=self.dialect, **per)


@dataclass
class CLProgram:
    """A cutter-location program, per point in machining order.

    tip: (N, 3) tool tip, mm, workpiece frame. axis: (N, 3) unit tool axis (tip -> spindle) or
    None where the format gives none. rows: (N,) int64: cutting rows are runs of feed moves,
    numbered 0, 1, ... over the whole program; a rapid move splits rows and its end point has row
    -1. feed: (N,) mm/min of the move that ends at the point (NaN at rapid points and where the
    file sets no feed). rapid: (N,) bool, the point is reached by a rapid move. line: (N,) int64
    the line (data row for CSV) of the record that produced the point. toolpaths: contiguous
    point ranges with name and tool. dialect: the posted program's dialect (camsmooth.post) or
    None; cycles: its canned cycles (listed, not smoothed); work_offset: the last work offset it
    selects ('G54'), recorded, not added. angles: (N, 2) commanded rotary angles (rad) when the
    file commands them (G-code, a result CSV) else None, in the order ``rotary`` names them (the
    axes of the machine the file was written for: ("A", "B"), ("A", "C"), ("B", "C")). source: the
    file; format: the reader's format name;
    warnings: messages naming lines (records ignored, assumptions made). written: what camsmooth
    wrote beside the poses when the file is camsmooth's own output (``Written``), else None.
    """

    tip: np.ndarray
    axis: np.ndarray | None
    rows: np.ndarray
    feed: np.ndarray
    rapid: np.ndarray
    line: np.ndarray
    toolpaths: list[ToolPath]
    source: str | None = None
    format: str = "cl"
    warnings: list[str] = field(default_factory=list)
    angles: np.ndarray | None = None
    written: Written | None = None
    rotary: tuple[str, str] = ("A", "B")
    dialect: str | None = None
    cycles: list[Cycle] = field(default_factory=list)
    work_offset: str | None = None
    #: a posted program's per point modes (camsmooth.post.core.Builder.finish): 'tcp' (0 machine, 1 TCP,
    #: 2 dynamic work offset), 'feed_mode' (93, 94, 95), 'frame_origin' (N, 3) mm, 'frame_rotates'
    modes: dict[str, np.ndarray] | None = None

    def __post_init__(self) -> None:
        self.tip = np.asarray(self.tip, dtype=float).reshape(-1, 3)
        n = len(self.tip)
        if self.axis is not None:
            self.axis = np.asarray(self.axis, dtype=float).reshape(-1, 3)
        self.rows = np.asarray(self.rows, dtype=np.int64).reshape(-1)
        self.feed = np.asarray(self.feed, dtype=float).reshape(-1)
        self.rapid = np.asarray(self.rapid, dtype=bool).reshape(-1)
        self.line = np.asarray(self.line, dtype=np.int64).reshape(-1)
        if self.angles is not None:
            self.angles = np.asarray(self.angles, dtype=float).reshape(-1, 2)
        for name in ("axis", "rows", "feed", "rapid", "line", "angles"):
            a = getattr(self, name)
            if a is not None and len(a) != n:
                raise ValueError(f"CLProgram.{name} has {len(a)} entries for {n} points")

    def __len__(self) -> int:
        return len(self.tip)

    def row_slices(self) -> list[slice]:
        """Index ranges of the cutting rows (runs of equal row id >= 0), in order."""
        r = self.rows
        if len(r) == 0:
            return []
        starts = np.flatnonzero(np.r_[True, r[1:] != r[:-1]])
        ends = np.r_[starts[1:], len(r)]
        return [slice(int(s), int(e)) for s, e in zip(starts, ends, strict=True) if r[s] >= 0]

    def cutting(self) -> CLProgram:
        """A copy with the cutting points only (rapid points dropped; rows, tool paths and
        angles kept). A tool path keeps its place with an empty range when all its points are
        rapids."""
        keep = self.rows >= 0
        new_index = np.cumsum(np.r_[0, keep.astype(np.int64)])
        tps = [ToolPath(tp.name, tp.tool, int(new_index[tp.start]), int(new_index[tp.stop]), tp.line,
                        tp.transform, tp.kind) for tp in self.toolpaths]
        return CLProgram(tip=self.tip[keep], axis=None if self.axis is None else self.axis[keep],
                         rows=self.rows[keep], feed=self.feed[keep], rapid=self.rapid[keep], line=self.line[keep],
                         toolpaths=tps, source=self.source, format=self.format, warnings=list(self.warnings),
                         angles=None if self.angles is None else self.angles[keep],
                         written=None if self.written is None else self.written.take(keep), rotary=self.rotary,
                         dialect=self.dialect, cycles=list(self.cycles), work_offset=self.work_offset)

    def toolpath_of(self, index: int) -> ToolPath | None:
        """The tool path holding point ``index`` (None if none does)."""
        for tp in self.toolpaths:
            if tp.start <= index < tp.stop:
                return tp
        return None

    def require_axis(self) -> np.ndarray:
        """The tool axes; InputError naming the file when the program has none."""
        if self.axis is None:
            raise InputError("the program gives no tool axis (a 3-axis program?)", file=self.source)
        return self.axis

    def require_tool(self, toolpath: ToolPath) -> Tool:
        """The tool path's mill, with diameter and corner radius; InputError naming the file and
        the line of the tool path when the file gives none (for APT: no ``TLDATA/MILL`` record)."""
        tool = toolpath.tool
        what = f"tool path '{toolpath.name}'" if toolpath.name else "the program"
        where = f" (line {toolpath.line})" if toolpath.line is not None else ""
        if tool is None:
            hint = " (no TLDATA/MILL or CUTTER record)" if self.format == "apt" else ""
            raise InputError(f"{what}{where} declares no tool{hint}: the cutter's diameter and corner radius "
                             "are unknown", file=self.source, row=None)
        if tool.kind != "mill" or tool.diameter is None or tool.corner_radius is None:
            raise InputError(f"{what}{where}: tool '{tool.name}' is a {tool.kind} without diameter and corner "
                             f"radius (line {tool.line}); a milling cutter (TLDATA/MILL or CUTTER) is needed",
                             file=self.source)
        return tool


# ----------------------------------------------------------------------------------------------
# format detection
#: the program formats (camsmooth.post.load_program reads each)
FORMATS = ("apt", "cl-csv", "cc-csv", "gcode", "result-csv")
#: header columns that make a CSV camsmooth's own result CSV (camsmooth.smoothing.output.write_result_csv)
RESULT_MARK = ("row", "idx", "t", "clx", "cly", "clz", "i", "j", "k", "x", "y", "z", "delta", "status")
_APT_RECORD = re.compile(r"^\s*(TOOL PATH/|GOTO/|TLDATA/|CUTTER/|MSYS/|FEDRAT/|RAPID\s*$|LOADTL/|LOAD/|PARTNO|"
                         r"UNITS/|MULTAX/|CIRCLE/|MOVARC/|END-OF-PATH|FROM/|\$\$)", re.IGNORECASE | re.MULTILINE)
_GCODE_LINE = re.compile(r"^\s*(%|O\d+|N\d+|G\d|M\d|\(|;|\d+\s+BEGIN PGM|BEGIN PGM|T\d|TRAORI)",
                         re.IGNORECASE | re.MULTILINE)
_EXTENSIONS = {".cls": "apt", ".clsf": "apt", ".apt": "apt", ".aptsource": "apt", ".cl": "apt",
               ".nc": "gcode", ".ngc": "gcode", ".gcode": "gcode", ".tap": "gcode", ".mpf": "gcode",
               ".h": "gcode", ".ptp": "gcode", ".cnc": "gcode"}


def detect_format(path: str | os.PathLike, head: str | None = None) -> str:
    """The format of a program file ('apt', 'cl-csv', 'cc-csv', 'gcode' or 'result-csv') from its
    content: APT records, camsmooth's result CSV (its header, RESULT_MARK), a CSV header naming
    x,y,z and nx,ny,nz (CC) or i,j,k (CL), G-code blocks; the
    extension decides only when the content does not. InputError when neither tells."""
    file = str(path)
    if head is None:
        try:
            with open(path, "rb") as fh:
                raw = fh.read(65536)
        except FileNotFoundError:
            raise InputError("cannot read the program: file not found", file=file) from None
        except OSError as exc:
            raise InputError(f"cannot read the program: {exc.strerror or exc}", file=file) from None
        head = raw.decode("utf-8-sig", errors="replace").replace("\r", "\n")
    first = next((ln for ln in head.split("\n") if ln.strip()), "")
    names = {h.strip().strip('"').lower() for h in re.split(r"[,;\t]", first)}
    if set(RESULT_MARK) <= names:
        return "result-csv"
    if {"x", "y", "z"} <= names:
        if {"nx", "ny", "nz"} <= names:
            return "cc-csv"
        if {"i", "j", "k"} <= names:
            return "cl-csv"
    if _APT_RECORD.search(head):
        return "apt"
    if _GCODE_LINE.search(head):
        return "gcode"
    ext = Path(file).suffix.lower()
    if ext in _EXTENSIONS:
        return _EXTENSIONS[ext]
    if ext == ".csv":
        raise InputError(f"a CSV program needs a header naming x,y,z and i,j,k (CL) or nx,ny,nz (CC); "
                         f"the first line is {first.strip()[:80]!r}", file=file, row=0)
    raise InputError("cannot tell the program's format from its content (APT/CLSF, CL CSV, CC CSV or G-code); "
                     "name it with format=", file=file)


def read_result_program(path: str | os.PathLike) -> CLProgram:
    """camsmooth's result CSV (camsmooth.smoothing.output.write_result_csv) as the program it describes:
    tool tips ``clx,cly,clz``, axes ``i,j,k``, the commanded rotary angles (A,B or A,C or B,C:
    ``CLProgram.rotary``) and the linear axes X Y Z, one row per
    ``row`` id, and beside them (``Written``) the programmed-feed time ``t``, the programmed feed
    (``feed``, or from t and the CC points in files without it), the time-optimal law ``t_opt``,
    the CC points, normals, clearance and status."""
    from camsmooth.io.result_csv import read_result_csv, result_rotary

    rotary = result_rotary(path)
    c = read_result_csv(path)
    rows_id = np.asarray(c["row"], np.int64)
    n = len(rows_id)
    starts = np.r_[True, rows_id[1:] != rows_id[:-1]] if n else np.zeros(0, bool)
    rows = np.cumsum(starts) - 1
    cc = np.column_stack([c["x"], c["y"], c["z"]])
    t = np.asarray(c["t"], float)
    if "feed" in c:
        feed = np.asarray(c["feed"], float)
    else:  # t_i - t_(i-1) = |CC_i - CC_(i-1)| / F_i (camsmooth.smoothing.pipeline.row_times)
        dt = np.r_[np.nan, np.diff(t)]
        seg = np.r_[np.nan, np.linalg.norm(np.diff(cc, axis=0), axis=1)]
        with np.errstate(invalid="ignore", divide="ignore"):
            feed = np.where(starts, np.nan, 60.0 * seg / dt)
        nxt = np.minimum(np.flatnonzero(starts) + 1, max(n - 1, 0))
        feed[starts] = feed[nxt]
    ang = np.radians(np.column_stack([c[rotary[0]], c[rotary[1]]]))
    written = Written(method=None, tolerance=None, every_point=True, t=t, feed=feed,
                      t_plan=np.asarray(c["t_opt"], float) if "t_opt" in c else None, row_id=rows_id,
                      idx=np.asarray(c["idx"], np.int64), cc=cc,
                      normals=np.column_stack([c["nx"], c["ny"], c["nz"]]) if "nx" in c else None,
                      delta=np.asarray(c["delta"], float), status=np.asarray(c["status"]))
    tp = ToolPath(name=Path(str(path)).stem, tool=None, start=0, stop=n, line=None)
    return CLProgram(tip=np.column_stack([c["clx"], c["cly"], c["clz"]]),
                     axis=np.column_stack([c["i"], c["j"], c["k"]]), rows=rows, feed=feed,
                     rapid=np.zeros(n, bool), line=np.arange(1, n + 1), toolpaths=[tp],
                     source=str(path), format="result-csv", angles=ang, written=written, rotary=rotary)


# ----------------------------------------------------------------------------------------------
# the CL program as read (``camsmooth analyze --cl OUT.csv``)
#: the header of the CL table, in order (pinned)
CL_COLUMNS = ("operation", "row", "line", "x", "y", "z", "i", "j", "k", "feed")


def cl_columns(program: CLProgram) -> dict[str, np.ndarray]:
    """The CL program as read, one record per feed-motion end point (rapids left out, arcs as
    interpolated): ``operation`` the tool path's name as the program gives it (never shortened),
    else its number from 1; ``row`` the row id (a camsmooth result CSV or G-code: smooth's row id,
    else the program's row numbering); ``line`` the file line (CSV: data row) of the motion;
    ``x,y,z`` the tool tip (mm) and ``i,j,k`` the unit tool axis (tip -> spindle), both in the
    program's workpiece frame; ``feed`` mm/min (NaN where the program sets none)."""
    axis = program.require_axis()
    keep = ~program.rapid & (program.rows >= 0)
    names = np.empty(len(program), dtype=object)
    names[:] = ""
    for k, tp in enumerate(program.toolpaths):
        names[tp.start:tp.stop] = tp.name if tp.name else str(k + 1)
    row = program.rows
    w = program.written
    if w is not None and w.row_id is not None and len(w.row_id) == len(program):
        row = np.where(w.row_id >= 0, w.row_id, row)
    idx = np.flatnonzero(keep)
    return {"operation": names[idx].astype(str), "row": row[idx].astype(np.int64),
            "line": program.line[idx].astype(np.int64), "x": program.tip[idx, 0], "y": program.tip[idx, 1],
            "z": program.tip[idx, 2], "i": axis[idx, 0], "j": axis[idx, 1], "k": axis[idx, 2],
            "feed": program.feed[idx]}


def cl_of_cc(path: CCPath, cutter: Any, lead: float, tilt: float) -> CLProgram:
    """A CC path as the CL program ``analyze`` evaluates (camsmooth.smoothing.analysis): the tool
    axis at the constant lead and tilt (rad, local frame of METHODS section 1), the tip of the
    cutter touching each CC point; rows and feed as the CC file gives them; line = the data row."""
    from camsmooth.geometry.cutter import cc_to_cl
    from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames
    from camsmooth.geometry.paths import estimate_feed_dirs

    fd = path.feed_dirs if path.feed_dirs is not None else estimate_feed_dirs(path.points, path.normals, path.rows)
    fr = local_frames(path.normals, fd)
    axes = axis_from_lead_tilt(np.full(len(fr), lead), np.full(len(fr), tilt), fr)
    tip = cc_to_cl(cutter, path.points, path.normals, axes)
    n = len(tip)
    starts = np.r_[True, path.rows[1:] != path.rows[:-1]] if n else np.zeros(0, bool)
    feed = path.feed if path.feed is not None else np.full(n, np.nan)
    return CLProgram(tip=tip, axis=axes, rows=np.cumsum(starts) - 1, feed=feed, rapid=np.zeros(n, bool),
                     line=np.arange(1, n + 1), toolpaths=[ToolPath("CC path", None, 0, n)], source=path.source,
                     format="cc-csv")


def write_cl_table(path: str | os.PathLike, program: CLProgram) -> None:
    """Write ``cl_columns(program)`` as a CSV (camsmooth.io.table.write_table, atomic)."""
    from camsmooth.io.table import write_table

    write_table(path, cl_columns(program))
