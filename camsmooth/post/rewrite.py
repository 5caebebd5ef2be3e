"""Smoothed motion written back into a posted program: the program a shop runs, with the cutting
blocks of the chosen operations replaced by camsmooth's and every other line kept as it is.

What is replaced: per smoothed row (a run of cutting points of one operation that touches the
part, camsmooth.smoothing.cam), the input lines from the block of its first point to the block of
its last. What is kept, unchanged and in order: every other line (header, tool changes, spindle,
coolant, offsets, planes, cycles, comments, rapids, the leads in and out, the operations not
chosen, the footer), and lines inside a replaced span that hold no point (a comment, an M code)
before the first new block whose input point came after them. Non-motion words of a replaced
block (``G93``, ``M8``, ``S``, ``T``, ``D``, ``H``) are written as a block of their own before its
replacement; in feed per minute the input's F in force after the span is restored (``F...``
block) when it is not the last one written, so the kept blocks run at their own feed (not in
Klartext, whose kept blocks without an F run at the last one written). Heidenhain Klartext: the
blocks are numbered again in order (the input's blocks keep their text, their number moves).

New blocks: the dialect's block format of camsmooth's writer (camsmooth.post.writer.format_blocks:
4 decimals, mm and deg), in the input's mode at those points: machine mode X Y Z the machine's
linear axes (``Machine.linear_axes``) and the rotary words; TCP mode X Y Z the tool tip; rotary
words in the dialect's sense (LinuxCNC: ``linuxcnc_sense``), shifted by whole turns to the
input's value at the row's first point (an unwound C stays unwound). Feed: inverse time (G93:
F = 1 / block time, 1/min) where the input's block was G93 -- machine mode on the tip path the
joints' linear interpolation gives (camsmooth.post.writer's rule), TCP mode on the tip's chord --
else the planned feed (mm/min). Not rewritten (InputError naming the operation): inch programs,
feed per revolution, a tilted or shifted frame, Haas's dynamic work offset, Heidenhain blocks
without M128 / FUNCTION TCPM.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.program import CLProgram
from camsmooth.post import DIALECTS
from camsmooth.post.model import WRITTEN_DECIMALS, PostProgram, check_travel, written_joints
from camsmooth.post.writer import _block_feeds, _Moves, format_blocks

__all__ = ["WRITER_DIALECT", "select_operations", "rewrite_posted", "Rewritten"]

#: the posted reader's dialect -> the writer's words whose blocks it takes (camsmooth.post.DIALECTS:
#: ISO and Haas take Fanuc's, MillPlus the generic ones)
WRITER_DIALECT = {name: e.words.name for name, e in DIALECTS.items()}
#: rotary words that differ by more than this from the input's at a row's start (deg, after whole
#: turns) are named: the smoothing chose the other inverse-kinematics branch there
BRANCH_WARN_DEG = 20.0
_INCH = {"siemens": re.compile(r"\bG70\b|\bG700\b"), "iso": re.compile(r"\bG20\b"),
         "heidenhain": re.compile(r"\bBEGIN\s+PGM\s+\S+\s+INCH\b")}
_NEW = "\x00"  # marks the lines the rewrite writes, until Klartext's blocks are numbered
_KEEP_WORD = re.compile(r"(?<![A-Z_])([GMSTDH])\s*(\d+(?:\.\d+)?)")
_F_WORD = re.compile(r"(?<![A-Z_])F\s*=?\s*([-+]?(?:\d+\.?\d*|\.\d+))")


@dataclass
class Rewritten:
    """The new program text, the operations rewritten, the rows and blocks written, warnings."""

    text: str
    operations: list[str]
    rows: int
    blocks: int
    warnings: list[str] = field(default_factory=list)


def _code(line: str) -> str:
    """A line without its comments ('( )' and ';'), upper case."""
    return re.sub(r"\([^()]*\)", "", line.split(";", 1)[0]).upper()


def select_operations(program: CLProgram, names: str | None) -> CLProgram:
    """A copy of ``program`` whose cutting rows are those of the operations ``names`` (comma
    separated, as ``analyze --cl`` names them) or, None, of every simultaneous five-axis operation
    (``ToolPath.kind == '5-axis'``); the other points get row -1 (not smoothed, still indexed).
    InputError naming the operations when a name is unknown or none is chosen."""
    tps = program.toolpaths
    if names is None:
        chosen = [k for k, tp in enumerate(tps) if tp.kind == "5-axis"]
        if not chosen:
            have = ", ".join(f"{tp.name} ({tp.kind})" for tp in tps) or "none"
            raise InputError(f"no simultaneous five-axis operation to smooth (operations: {have}): name them with "
                             "--operations NAME,...", file=program.source)
    else:
        wanted = [w.strip() for w in names.split(",") if w.strip()]
        by_name = {tp.name: k for k, tp in enumerate(tps)}
        unknown = [w for w in wanted if w not in by_name]
        if unknown or not wanted:
            raise InputError(f"--operations {names!r}: no operation {', '.join(unknown) or '(empty)'} (operations: "
                             f"{', '.join(tp.name for tp in tps)})", file=program.source)
        chosen = sorted({by_name[w] for w in wanted})
    keep = np.zeros(len(program), bool)
    for k in chosen:
        keep[tps[k].start:tps[k].stop] = True
    rows = np.where(keep, program.rows, -1)
    out = CLProgram(tip=program.tip, axis=program.axis, rows=rows, feed=program.feed, rapid=program.rapid,
                    line=program.line, toolpaths=program.toolpaths, source=program.source, format=program.format,
                    warnings=list(program.warnings), angles=program.angles, written=program.written,
                    rotary=program.rotary, dialect=program.dialect, cycles=list(program.cycles),
                    work_offset=program.work_offset, modes=program.modes)
    return out


def rewrite_posted(text: str, program: CLProgram, result: PostProgram, source_index: np.ndarray, machine: Any,
                   feed: np.ndarray) -> Rewritten:
    """The posted program ``text`` (as read: LF line ends) with the smoothed rows of ``result``
    written in place of the blocks they came from (module docstring).

    program: the CLProgram the posted reader made of ``text`` (its ``modes``); result: the smoothed
    points (camsmooth.post.model.PostProgram: rows, idx, joints X Y Z linear axes mm and the rotary
    axes rad in ``machine.rotary`` order, tips mm, workpiece frame; from a smoothing result
    camsmooth.smoothing.posting.post_points); source_index: (N,) each result point's index in
    ``program``; feed: (N,) the planned feed per point (mm/min, camsmooth.smoothing.feed.block_feeds).
    InputError naming the operation for what cannot be rewritten; InfeasibleError for a value
    outside the machine's travel (camsmooth.post.model.check_travel)."""
    file = program.source
    modes = program.modes
    dialect = program.dialect
    if modes is None or dialect is None:
        raise InputError("not a posted program: the smoothed blocks cannot be written back into it", file=file)
    if dialect not in WRITER_DIALECT:
        raise InputError(f"writing smoothed blocks into a {dialect} program is not supported (supported: "
                         f"{', '.join(sorted(WRITER_DIALECT))}); write camsmooth's own program instead", file=file)
    wd = WRITER_DIALECT[dialect]
    lines = text.split("\n")
    trailing = bool(lines) and lines[-1] == ""
    if trailing:
        lines = lines[:-1]
    klartext = dialect == "heidenhain"
    inch = _INCH[dialect if dialect in _INCH else "iso"]
    for k, ln in enumerate(lines, start=1):
        if inch.search(_code(ln)):
            raise InputError("inch programs are not rewritten (camsmooth writes mm blocks)", file=file, line=k)
    rows = np.asarray(result.rows)
    src = np.asarray(source_index, np.int64)
    n = len(rows)
    if len(src) != n or len(feed) != n:
        raise InputError(f"the smoothed program has {n} points for {len(src)} input points: cannot map it back",
                         file=file)
    letters = "XYZ" + "".join(machine.rotary)
    sense = DIALECTS[dialect].signs(machine)
    joints = np.asarray(result.joints, float).reshape(-1, 5)
    A = joints[:, 3].copy()  # the machine's rotary axes (rad)
    B = joints[:, 4].copy()
    warnings: list[str] = []
    spans: list[tuple[int, int, np.ndarray]] = []  # (first line, last line, result point indices)
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]]) if n else np.zeros(0, np.int64)
    ends = np.r_[starts[1:], n]
    ops: list[str] = []
    for a, b in zip(starts, ends, strict=True):
        pts = src[a:b]
        tp = program.toolpath_of(int(pts[0]))
        name = tp.name if tp is not None else "?"
        if name not in ops:
            ops.append(name)
        tcp = modes["tcp"][pts]
        fm = modes["feed_mode"][pts]
        if np.any(modes["frame_rotates"][pts]) or np.any(modes["frame_origin"][pts] != 0):
            raise InputError(f"operation '{name}': its blocks are written in a shifted or tilted frame; rewriting them "
                             "is not supported", file=file, line=int(program.line[pts[0]]))
        if np.any(tcp == 2) or len(np.unique(tcp)) > 1:
            raise InputError(f"operation '{name}': dynamic work offset or a mode change inside a row: not rewritten",
                             file=file, line=int(program.line[pts[0]]))
        if klartext and np.any(tcp == 0):
            raise InputError(f"operation '{name}': Heidenhain machine-mode blocks (no M128 / FUNCTION TCPM) have no "
                             "inverse-time feed to hold the tip's feed: not rewritten", file=file,
                             line=int(program.line[pts[0]]))
        if np.any(fm == 95) or len(np.unique(fm)) > 1:
            raise InputError(f"operation '{name}': feed per revolution or a feed-mode change inside a row: not "
                             "rewritten", file=file, line=int(program.line[pts[0]]))
        # whole turns toward the input's rotary words at the row's start (an unwound C stays unwound)
        if program.angles is not None:
            q_in = np.degrees(program.angles[pts[0]])
            for j, q in enumerate((A, B)):
                turn = 360.0 * round((q_in[j] - math.degrees(q[a])) / 360.0)
                q[a:b] += math.radians(turn)
                off = abs(q_in[j] - math.degrees(q[a]))
                if off > BRANCH_WARN_DEG:
                    warnings.append(f"{file}, line {int(program.line[pts[0]])}: operation '{name}': "
                                    f"{machine.rotary[j]} starts {off:.1f} deg from the input's (another "
                                    "inverse-kinematics branch): check the move into the row")
        spans.append((int(program.line[pts[0]]), int(program.line[pts[-1]]), np.arange(a, b)))
    spans.sort(key=lambda s: s[0])
    for (_, hi0, _), (lo1, _, _) in zip(spans[:-1], spans[1:], strict=True):
        if lo1 <= hi0:
            raise InputError("two smoothed rows come from one block (an arc split by the part's contact): not "
                             "rewritten", file=file, line=lo1)
    xyz = joints[:, :3]
    tip = np.asarray(result.tips, float).reshape(-1, 3)
    check_travel(machine, rows, np.asarray(result.idx), A, B, xyz, "point")
    feed = np.asarray(feed, float)
    point_lines = set(program.line.tolist())
    out: list[str] = []
    cursor = 1  # the next input line to copy
    n_blocks = 0
    for lo, hi, sel in spans:
        out.extend(lines[cursor - 1:lo - 1])
        pts = src[sel]
        mode_tcp = bool(modes["tcp"][pts[0]] == 1)
        inverse = bool(modes["feed_mode"][pts[0]] == 93)
        q = written_joints(np.column_stack([xyz[sel], A[sel], B[sel]]))
        tips = np.round(tip[sel], WRITTEN_DECIMALS)
        prev = int(pts[0]) - 1
        if prev >= 0 and program.angles is not None:
            qa = program.angles[prev]
            p_xyz = machine.linear_axes(program.tip[prev:prev + 1], qa[:1], qa[1:])[0]
            q_prev = np.r_[p_xyz, qa]
            t_prev = program.tip[prev]
        else:
            q_prev, t_prev = q[0], tips[0]
        f = feed[sel]
        if not inverse:
            F = f
        elif not mode_tcp:
            mv = _Moves(np.vstack([q_prev, q]), np.vstack([t_prev, tips]), np.r_[True, np.zeros(len(q), bool)],
                        np.r_[np.nan, f])
            F = _block_feeds(machine, mv, "machine")[0][1:]
        else:
            chord = np.linalg.norm(np.diff(np.vstack([t_prev, tips]), axis=0), axis=1)
            minutes = chord / f
            limits = getattr(machine, "limits", {}) or {}
            dq = np.abs(np.diff(np.vstack([q_prev, q]), axis=0))
            for j, name in ((3, machine.rotary[0]), (4, machine.rotary[1])):
                lim = limits.get(name)
                if lim is not None and np.isfinite(lim.vmax):
                    minutes = np.maximum(minutes, dq[:, j] / lim.vmax / 60.0)
            F = 1.0 / np.maximum(minutes, 1e-6 / 60.0)
        coords = np.column_stack([q[:, :3] if not mode_tcp else tips, np.degrees(q[:, 3:]) * sense])
        blocks = [_NEW + b for b in format_blocks(wd, coords, F, np.zeros(len(q), bool), letters, inverse)]
        n_blocks += len(blocks)
        # the input lines of the span: a point's block is replaced; its other words and the lines
        # without a point are kept before the new block that follows them
        src_line = program.line[pts]
        k = 0
        for ln_no in range(lo, hi + 1):
            raw = lines[ln_no - 1]
            if ln_no in point_lines:
                extra = [f"{w}{v}" for w, v in _KEEP_WORD.findall(_code(_unnumbered(raw) if klartext else raw))
                         if not (w == "G" and float(v) in (0.0, 1.0, 2.0, 3.0)) and (w == "M" or not klartext)]
                if extra:
                    out.append(_NEW + " ".join(extra))
                while k < len(blocks) and src_line[k] <= ln_no:
                    out.append(blocks[k])
                    k += 1
            else:
                out.append(raw)
        out.extend(blocks[k:])
        if not inverse and not klartext:  # the feed in force after the span is the input's again
            f_in = next((m.group(1) for ln in reversed(lines[:hi]) for m in [_last_f(ln)] if m), None)
            if f_in is not None and not math.isclose(float(f_in), float(np.round(F[-1], 1)), abs_tol=0.05):
                out.append(f"{_NEW}F{f_in}")
        modal = _modal_motion(lines[:hi])
        if modal in (2, 3) and _relies_on_modal(lines[hi:]):
            warnings.append(f"{file}, line {hi + 1}: the block after the smoothed blocks moves in the modal G{modal} "
                            "of the input's last cutting block, which the smoothed G01 blocks replaced: check it")
        cursor = hi + 1
    out.extend(lines[cursor - 1:])
    if klartext:
        out = _numbered(out)
    new_text = "\n".join(ln.removeprefix(_NEW) for ln in out) + ("\n" if trailing else "")
    return Rewritten(text=new_text, operations=ops, rows=len(spans), blocks=n_blocks, warnings=warnings)


def _last_f(line: str) -> re.Match[str] | None:
    ms = list(_F_WORD.finditer(_code(line)))
    return ms[-1] if ms else None


_MOTION = re.compile(r"(?<![A-Z_.\d])G0?([0-3])(?![\d.])")
_AXIS = re.compile(r"(?<![A-Z_])[XYZABC]\s*=?\s*[-+.\d]")


def _modal_motion(lines: list[str]) -> int | None:
    """The motion G code (0-3) in force after ``lines``."""
    for ln in reversed(lines):
        ms = _MOTION.findall(_code(ln))
        if ms:
            return int(ms[-1])
    return None


def _relies_on_modal(lines: list[str]) -> bool:
    """Whether the next block with axis words in ``lines`` has no motion G code of its own."""
    for ln in lines:
        code = _code(ln)
        if _AXIS.search(code):
            return not _MOTION.search(code)
    return False


_BLOCK_NO = re.compile(r"^\s*(\d+)\s+")


def _unnumbered(line: str) -> str:
    return _BLOCK_NO.sub("", line, count=1)


def _numbered(lines: list[str]) -> list[str]:
    """Klartext blocks numbered in order from the first block's number: the input's numbered
    blocks keep their text with the new number, the new blocks get one, other lines (a cycle's
    continuation lines, blank lines) are left as they are."""
    first = next((int(m.group(1)) for ln in lines for m in [_BLOCK_NO.match(ln)] if m), 0)
    out, k = [], first
    for ln in lines:
        if ln.startswith(_NEW):
            out.append(f"{k} {ln[len(_NEW):]}")
            k += 1
        elif _BLOCK_NO.match(ln):
            out.append(f"{k} {_unnumbered(ln)}")
            k += 1
        else:
            out.append(ln)
    return out
