"""camsmooth's own G-code read back: a program ``write_program`` (camsmooth.post.writer) wrote,
in any dialect and either mode, recognised by its header's ``camsmooth post:`` tag, as a
CLProgram with what camsmooth wrote beside the blocks (``Written``: method, tolerance, the
programmed-feed times ``t=``, feeds ``f=``, the time-optimal law ``o=``, the row ids), for round
trips and ``load_program``. A posted program (no tag) is read by its dialect's reader
(camsmooth.post.read_posted).

The angles are the rotary words of ``machine.rotary`` (degrees in the file, rad inside), negated
back where the header says they are in LinuxCNC's sense (camsmooth.post.linuxcnc). Units: mm,
mm/min, s.
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.program import CLProgram, Tool, ToolPath, Written
from camsmooth.io.table import read_text_file
from camsmooth.post.model import tip_path_lengths
from camsmooth.post.writer import POST_TAG

__all__ = ["read_gcode", "POST_TAG", "MAX_WORD"]

#: the largest magnitude of an axis word (mm, deg) or header pivot the reader takes
MAX_WORD = 1e9
_WORD = re.compile(r"([A-Z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
#: the per-block annotation the writer adds (``_annotations``)
_ANNOT = re.compile(r"[(;]\s*t=(\d+\.\d+)(?:\s+f=(\d+\.\d+))?(?:\s+o=(\d+\.\d+))?")
_ROW_COMMENT = re.compile(r"[(;]\s*row (-?\d+): (\d+) points")
_TOOL = re.compile(r"tool: (?:toroidal|bull nose|ball end|flat end) R ([\d.]+) mm, r ([\d.]+) mm, diameter ([\d.]+) mm"
                   r"(?:, shank ([\d.]+) mm)?")
_METHOD = re.compile(r"method: ([\w-]+)[;,] (\d+) points")


def _strip_comment(line: str, klartext: bool) -> str:
    line = line.split(";", 1)[0]
    if not klartext:
        line = re.sub(r"\(.*?\)", "", line)
    return line.strip()


def _header_pivot(text: str | None, default: float, file: str, line: int | None) -> float:
    """The pivot length of the camsmooth post header (``pivot=L``, mm), or ``default`` without
    one; InputError naming the line when it is not a finite number >= 0."""
    if text is None:
        return default
    try:
        pivot = float(text)
    except ValueError:
        pivot = math.nan
    if not 0 <= pivot <= MAX_WORD:
        raise InputError(f"the camsmooth post header gives pivot={text}: not a length of 0 to {MAX_WORD:g} mm",
                         file=file, line=line)
    return pivot


def _header_centre(text: str | None, file: str, line: int | None) -> tuple[float, float, float]:
    """The table centre of the camsmooth post header (``centre=x,y,z``, mm), the origin without
    one; InputError naming the line when it is not three finite numbers."""
    if text is None:
        return (0.0, 0.0, 0.0)
    try:
        vals = tuple(float(v) for v in text.split(","))
    except ValueError:
        vals = ()
    if len(vals) != 3 or not all(abs(v) <= MAX_WORD for v in vals):
        raise InputError(f"the camsmooth post header gives centre={text}: not three lengths x,y,z (mm)", file=file,
                         line=line)
    return vals  # type: ignore[return-value]


def read_gcode(path: str | os.PathLike, machine: Any = None) -> CLProgram:
    """Read a program written by ``write_program`` (``write_gcode``) (any dialect, either mode) as a CLProgram.

    Tips and axes come from the blocks through the machine's kinematics: machine mode
    tip, axis = machine.tool_pose_np(q1, q2, X, Y, Z); tcp mode tip = (X, Y, Z), axis =
    machine.tool_axis_np(q1, q2), with q1 q2 the words of ``machine.rotary`` (A B, A C, B C; the
    program's ``rotary``), negated back where the header says they are in LinuxCNC's sense
    (module docstring). machine: a camsmooth Machine; None builds the nominal machine of the
    header's kind with its pivot length and table centre (the AB head without a header).
    InputError when the header names a kind whose rotary axes the given machine does not have.
    Feed per point: tcp mode F; machine mode the block's tip path length x F (inverse time); a G94
    machine-mode file (older camsmooth output) gives F as written, with a warning. Rapid blocks
    split rows; their points have row -1.
    """
    from camsmooth.machine.kinematics import machine_from_header

    file = str(path)
    text = read_text_file(path, "G-code file")
    lines = text.split("\n")
    tag = next((ln for ln in lines[:60] if POST_TAG in ln), None)
    info = dict(re.findall(r"(\w+)=([\w.,+-]+)", tag.split(POST_TAG, 1)[1])) if tag else {}
    klartext = any("BEGIN PGM" in ln for ln in lines[:5])
    dialect = info.get("dialect") or ("heidenhain" if klartext else "generic")
    warnings: list[str] = []
    if tag is None:
        warnings.append("no camsmooth post header: read as generic G-code")
    tag_line = lines.index(tag) + 1 if tag else None
    kind = info.get("kind")
    pivot = None if info.get("pivot") is None else _header_pivot(info.get("pivot"), 0.0, file, tag_line)
    rotary = info.get("rotary")
    machine = machine_from_header(kind, pivot, _header_centre(info.get("centre"), file, tag_line), machine,
                                  tuple(rotary.split(",")) if rotary else None, file, tag_line)
    letters = tuple(getattr(machine, "rotary", ("A", "B")))
    sense = np.ones(2)
    if info.get("sense") == "linuxcnc":
        from camsmooth.post.linuxcnc import linuxcnc_sense

        sense = linuxcnc_sense(machine)
    elif info.get("sense") not in (None, "iso"):
        raise InputError(f"the camsmooth post header gives sense={info['sense']}: not iso or linuxcnc", file=file,
                         line=tag_line)
    mode = info.get("mode")
    from camsmooth.post import DIALECTS

    tcp_words = {d.words.tcp_on.split()[0] for d in DIALECTS.values() if d.words.tcp_on}
    joints: list[list[float]] = []
    rapid: list[bool] = []
    fword: list[float] = []
    line_no: list[int] = []
    t_ann: list[float] = []
    f_ann: list[float] = []
    o_ann: list[float] = []
    row_ids: list[int] = []
    inverse = False
    inv_flag: list[bool] = []
    units_inch = False
    state = {w: math.nan for w in ("X", "Y", "Z") + letters}
    motion = None
    f_modal = math.nan
    tcp_seen = False
    for k, raw in enumerate(lines, start=1):
        if tag is not None:
            row_c = _ROW_COMMENT.search(raw)
            if row_c:
                row_ids.append(int(row_c.group(1)))
        s = _strip_comment(raw, klartext)
        if not s or s.startswith("%"):
            continue
        if klartext:
            s = re.sub(r"^\d+\s+", "", s)
            if s.split()[0] in ("FUNCTION",) and "TCPM" in s and "RESET" not in s:
                tcp_seen = True
            if not s.startswith("L "):
                continue
            words = dict((w, float(v)) for w, v in _WORD.findall(s[2:].replace("FMAX", "")))
            is_rapid = "FMAX" in s
            if "F" in words:
                f_modal = words["F"]
        else:
            if s.split()[0] in tcp_words:
                tcp_seen = True
            words_l = _WORD.findall(s.upper())
            if any(w == "G" and float(v) in (28.0, 53.0, 91.0) for w, v in words_l):
                continue  # returns to the reference point / machine coordinates: not part of the path
            words = {}
            for w, v in words_l:
                if w == "G":
                    g = float(v)
                    if g in (0.0, 1.0):
                        motion = int(g)
                    elif g == 93.0:
                        inverse = True
                    elif g == 94.0:
                        inverse = False
                    elif g == 20.0:
                        units_inch = True
                    elif g == 43.4:
                        tcp_seen = True
                elif w in state or w == "F":
                    words[w] = float(v)
            if "F" in words:
                f_modal = words["F"]
            if motion is None or not any(w in state for w in words):
                continue
            is_rapid = motion == 0
        if not any(w in state for w in words):
            continue
        big = next((w for w in state if w in words and not abs(words[w]) <= MAX_WORD), None)
        if big is not None:
            raise InputError(f"{big}{words[big]:g} is beyond +-{MAX_WORD:g} (not a position of a machine)", file=file,
                             line=k)
        for w in state:
            if w in words:
                state[w] = words[w]
        if any(math.isnan(v) for v in state.values()):
            missing = [w for w, v in state.items() if math.isnan(v)]
            raise InputError(f"first motion block does not give {', '.join(missing)}", file=file, line=k)
        joints.append([state[w] for w in ("X", "Y", "Z") + letters])
        ann = _ANNOT.search(raw) if tag is not None and not is_rapid else None
        t_ann.append(float(ann.group(1)) if ann else math.nan)
        f_ann.append(float(ann.group(2)) if ann and ann.group(2) else math.nan)
        o_ann.append(float(ann.group(3)) if ann and ann.group(3) else math.nan)
        rapid.append(is_rapid)
        fword.append(math.nan if is_rapid else f_modal)
        inv_flag.append(inverse)
        line_no.append(k)
    if not joints:
        raise InputError(f"no motion block (G00/G01 or L with X Y Z {' '.join(letters)})", file=file)
    if units_inch:
        raise InputError("inch programs (G20) are not read: camsmooth writes mm", file=file)
    if mode is None:
        mode = "tcp" if tcp_seen else "machine"
    q = np.asarray(joints, dtype=float)
    q[:, 3:] = np.radians(q[:, 3:]) * sense  # back to the tool's rotation (ISO 841) where LinuxCNC's sense was written
    rap = np.asarray(rapid, dtype=bool)
    F = np.asarray(fword, dtype=float)
    if mode == "machine":
        tip, axis = machine.tool_pose_np(q[:, 3], q[:, 4], q[:, 0], q[:, 1], q[:, 2])
        feed = np.full(len(q), np.nan)
        cut = np.flatnonzero(~rap[1:]) + 1
        inv = np.asarray(inv_flag, dtype=bool)[cut]
        feed[cut] = np.where(inv, tip_path_lengths(machine, q[cut - 1], q[cut]) * F[cut], F[cut])
        if not inv.all():
            warnings.append("machine-mode program in feed per minute (G94): F applies to the joint motion, the tool "
                            "tip feed is not known; feed = F as written")
        if not rap[0]:
            feed[0] = np.nan
    else:
        tip = q[:, :3].copy()
        axis = machine.tool_axis_np(q[:, 3], q[:, 4])
        feed = np.where(rap, np.nan, F)
    new = ~rap & np.r_[True, rap[:-1]]
    rows = np.where(rap, -1, np.cumsum(new) - 1)
    tool, written = _own_header(lines, tag, info, rows, rap, q, F, inv_flag, t_ann, f_ann, row_ids, tip, mode,
                                o_ann)
    tp = ToolPath(name=Path(file).stem, tool=tool, start=0, stop=len(q), line=None)
    prog = CLProgram(tip=tip, axis=axis, rows=rows, feed=feed, rapid=rap, line=np.asarray(line_no), toolpaths=[tp],
                     source=file, format="gcode", warnings=warnings, angles=q[:, 3:], written=written,
                     rotary=letters)
    prog.warnings.append(f"dialect {dialect}, mode {mode}")
    return prog


def _own_header(lines: list[str], tag: str | None, info: dict[str, str], rows: np.ndarray, rapid: np.ndarray,
                q: np.ndarray, F: np.ndarray, inverse: list[bool], t_ann: list[float], f_ann: list[float],
                row_ids: list[int], tip: np.ndarray, mode: str,
                o_ann: list[float] | None = None) -> tuple[Tool | None, Written | None]:
    """The tool and what camsmooth wrote beside the blocks (``Written``) of a program camsmooth
    wrote (its ``camsmooth post:`` header), (None, None) for another program. t_plan: the
    time-optimal law from each row's start: the ``o=`` annotations where the writer gave them (a
    controller plan's blocks, whose F words carry the controller's block times), else the block
    times the program commands (G93: 60 / F s; tcp mode: the tip chord / F), which are t_blocks."""
    if tag is None:
        return None, None
    head = "\n".join(lines[:80])
    tool = None
    m = _TOOL.search(head)
    try:
        if m:
            r_c, dia = float(m.group(2)), float(m.group(3))
            tool = Tool(name="camsmooth", kind="mill", diameter=dia, corner_radius=r_c,
                        length=float(m.group(4)) if m.group(4) else None, line=None)
    except ValueError:  # a mangled header: the tool is not known
        tool = None
    mm = _METHOD.search(head)
    method = info.get("method") or (mm.group(1) if mm else None)
    n_points = int(mm.group(2)) if mm else None
    try:
        tol = float(info["tolerance"]) if "tolerance" in info else None
    except ValueError:
        tol = None
    n = len(rows)
    t = np.asarray(t_ann, float)
    f = np.asarray(f_ann, float)
    # the programmed feed is written where it changes: carry it forward within each row
    cut = ~rapid
    starts = cut & np.r_[True, rapid[:-1]]
    grp = np.cumsum(starts)
    marker = np.where(cut & (np.isfinite(f) | starts), np.arange(n), -1)  # a row's start resets it
    last = np.maximum.accumulate(marker) if n else marker
    feed = np.where(cut & (last >= 0), f[np.maximum(last, 0)], np.nan)
    dt = np.full(n, np.nan)
    inv = np.asarray(inverse, bool)
    if mode == "machine":
        with np.errstate(divide="ignore"):
            dt = np.where(inv, 60.0 / F, np.nan)
    else:
        chord = np.r_[np.nan, np.linalg.norm(np.diff(tip, axis=0), axis=1)]
        with np.errstate(divide="ignore", invalid="ignore"):
            dt = 60.0 * chord / F
    dt = np.where(cut & ~starts, dt, 0.0)
    t_plan = t_blocks = None
    if np.all(np.isfinite(dt[cut])):
        total = np.cumsum(dt)
        first = np.flatnonzero(starts)
        t_blocks = np.full(n, np.nan)
        t_blocks[cut] = total[cut] - total[first][grp[cut] - 1]
    o = np.asarray(o_ann if o_ann is not None else [], float)
    if len(o) == n and np.all(np.isfinite(o[cut])):
        t_plan = np.where(cut, o, np.nan)
    else:
        t_plan = t_blocks
    n_rows = int(starts.sum())
    row_id = None
    if len(row_ids) == n_rows:
        row_id = np.full(n, -1, np.int64)
        row_id[cut] = np.asarray(row_ids, np.int64)[rows[cut]]
    every = n_points is None or int(cut.sum()) == n_points
    inner = np.flatnonzero(cut & ~starts)
    with np.errstate(invalid="ignore"):
        t_ok = bool(np.isfinite(t[cut]).all() and np.all(t[inner] > t[inner - 1]))  # increasing along each row
    written = Written(method=method, tolerance=tol, every_point=every, dialect=info.get("dialect"),
                      t=t if t_ok else None,
                      feed=feed if np.isfinite(feed[cut]).all() else None, t_plan=t_plan, t_blocks=t_blocks,
                      row_id=row_id)
    return tool, written
