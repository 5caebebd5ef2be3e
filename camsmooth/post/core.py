"""The shared core of the posted-program readers: a ``Builder`` that a dialect's interpreter feeds
with the end points of its motion blocks, the modal state that decides what those points mean
(tool-centre-point or machine mode, the active frame, feed mode, units) and the operations they
belong to, and that turns them into the one program model (camsmooth.io.program.CLProgram).

What a point means (X Y Z as written, converted to mm; rotary words as written, degrees):

Rotary words are the tool's rotation relative to the workpiece (ISO 841) except in the linuxcnc
dialect, whose trt kinematics take a table axis' value as the table's own turn: there they are
multiplied by ``machine.linuxcnc_sense`` (camsmooth.post.linuxcnc; camsmooth.post.writer, "LinuxCNC's sign mapping").
CLProgram.angles are the values in camsmooth's sense, never wrapped (an unwound C is kept).

- **TCP mode** (Fanuc G43.4, Haas G234, Siemens TRAORI, Heidenhain M128 / FUNCTION TCPM,
  LinuxCNC M428 on its trt configurations): X Y Z is the tool tip in the program's frame; the
  tool axis is ``machine.tool_axis_np(q1, q2)`` of the rotary words, or the written vector where
  the block gives one (Fanuc G43.5 I J K, Siemens A3 B3 C3, Heidenhain LN TX TY TZ).
- **machine mode** (no TCP): X Y Z and the rotary words are the machine's joints:
  ``machine.tool_pose_np(q1, q2, X, Y, Z)`` gives tip and axis in the workpiece frame.
- **no rotary word in the whole program** (three-axis): X Y Z is the tip, the axis +Z.
- **dynamic work offset** (Haas G254): the control moves the work offset with the table: tip =
  ``tool_pose(q, XYZ) - tool_pose(q, 0)`` (exact on table machines, whose tip does not depend
  on where their axes are), axis from the rotary words.
- **a rotated frame** (Fanuc G68.2 / G68, Siemens CYCLE800 / ROT / AROT, Heidenhain PLANE): X Y Z
  are in the tilted frame F = (R, o): tip = o + R p; the tool stands along the frame's Z, axis =
  R e_z (3+2 machining: the controller turns the rotary axes to it, G53.1 / TURN / CYCLE800 TC).
  A frame that only translates (datum shifts) adds its origin to the tip.

The work offset the program selects (G54-G59, G54.1 P, Siemens G500 ... G599, Heidenhain
presets) is recorded, not added: tips are in the program's workpiece frame. Feeds: G94 F (mm/min
after the unit conversion); G95 F x S; G93 (inverse time) F / min x the length of the block's
tool-tip path; in machine mode with G94 F is the feed of the joint motion and is reported as
written, with a warning (the tool tip's feed is not what F says there).

A construct the reader does not know is named (file, line, text) and costs only its operation:
the operation's points are dropped and the program's warnings say why. Rows (CLProgram.rows) are
runs of feed moves split by rapids, by operations and by moves in machine coordinates (G53,
G28, G30, M91), which are not points of the program (their positions are not in the workpiece
frame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.program import CLProgram, Cycle, Tool, ToolPath
from camsmooth.machine.model import rot_x, rot_y, rot_z  # the one set of rotation helpers

__all__ = ["Builder", "Frame3", "Skip", "rot_x", "rot_y", "rot_z", "arc_points", "nominal_machine", "INCH_MM",
           "CHORD_TOL_MM", "MAX_WORD"]

INCH_MM = 25.4
#: the chordal deviation of the arc and helix interpolation (mm)
CHORD_TOL_MM = 1e-3
#: the largest magnitude of a position or feed word (mm, deg, mm/min): larger is not a machine's
MAX_WORD = 1e7
#: the most points one arc may be interpolated with
MAX_ARC_POINTS = 200_000


class Skip(Exception):
    """A construct the reader does not apply: costs the operation it is in (``Builder.skip``)."""

    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


@dataclass(frozen=True)
class Frame3:
    """A program frame: a point p written in it is o + R p in the workpiece frame (mm)."""

    R: np.ndarray = field(default_factory=lambda: np.eye(3))
    o: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @property
    def rotates(self) -> bool:
        return not np.allclose(self.R, np.eye(3), atol=1e-12)

    @property
    def identity(self) -> bool:
        return not self.rotates and not np.any(self.o)

    def then(self, other: Frame3) -> Frame3:
        """The frame ``other`` written inside this one (a chained / additive frame)."""
        return Frame3(self.R @ other.R, self.o + self.R @ other.o)

    def matrix(self) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = self.R, self.o
        return m


def arc_points(start: np.ndarray, end: np.ndarray, centre: np.ndarray, normal: np.ndarray, ccw: bool,
               turns: int = 0, chord_tol: float = CHORD_TOL_MM) -> tuple[np.ndarray, float]:
    """Points (K, 3) after ``start`` up to ``end`` of a circular or helical arc, and its length.

    The arc turns about ``centre`` (its projection on the plane through start normal to the unit
    ``normal``) counter-clockwise about ``normal`` when ``ccw``; the radius is the start's; the
    motion along ``normal`` is linear in the angle (a helix). End = start in the plane gives a full
    circle; ``turns`` extra full turns are added (Fanuc/LinuxCNC P word). Chords deviate from the
    arc by at most ``chord_tol`` (mm). InputError-free: the caller checks the end radius."""
    n = normal / np.linalg.norm(normal)
    c = centre + n * float(np.dot(start - centre, n))
    u = start - c
    r = float(np.linalg.norm(u))
    v_end = end - c
    h = float(np.dot(v_end, n))
    v_end = v_end - h * n
    if r < 1e-12:
        return end[None, :].copy(), float(np.linalg.norm(end - start))
    e1 = u / r
    e2 = np.cross(n, e1)
    ang = math.atan2(float(np.dot(v_end, e2)), float(np.dot(v_end, e1)))
    if not ccw:
        ang = -ang
    if ang <= 1e-12:
        ang += 2 * math.pi
    ang += 2 * math.pi * turns
    step = 2 * math.acos(max(-1.0, 1 - chord_tol / r)) if chord_tol < r else math.pi / 2
    k = min(MAX_ARC_POINTS, max(1, math.ceil(ang / max(step, 1e-9))))
    t = np.arange(1, k + 1) / k
    th = (ang if ccw else -ang) * t
    pts = c + r * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2) + (t * h)[:, None] * n
    pts[-1] = end
    length = math.hypot(r * ang, h)
    return pts, length


def nominal_machine(letters: tuple[str, str]) -> Any:
    """The nominal camsmooth machine whose rotary axes are ``letters`` (the machine package's
    ``nominal_machine``: A B the default AB head, A C and B C a trunnion centred at the origin)."""
    from camsmooth.machine.kinematics import nominal_machine as machine_of_letters

    return machine_of_letters(letters)


@dataclass
class _Op:
    name: str | None
    line: int
    tool: Tool | None
    skipped: str | None = None  # why its points are dropped (file, line, text)
    kind: str = "motion"
    frames: set[int] = field(default_factory=set)


class Builder:
    """Collects a posted program's points, operations, cycles and named constructs.

    The dialect's interpreter sets the modal fields (``tcp``, ``dwo``, ``frame``, ``feed_mode``,
    ``inch``) and calls ``move`` / ``arc`` with end points in the program frame (mm, rotary deg),
    ``operation`` at an operation's start, ``tool`` at a tool change, ``cycle`` for canned cycles,
    ``machine_move`` for moves in machine coordinates and ``skip`` / ``note`` for constructs not
    applied. ``finish(machine)`` gives the CLProgram."""

    def __init__(self, file: str, dialect: str) -> None:
        self.file, self.dialect = file, dialect
        self.tcp = False
        self.dwo = False
        self.frame = Frame3()
        self.feed_mode = 94  # 93 inverse time, 94 per minute, 95 per revolution
        self.F = math.nan  # mm/min (94), mm/rev (95) or 1/min (93), already in mm
        self.S = math.nan
        self.chord_tol = CHORD_TOL_MM
        self.work_offset: str | None = None
        self._frames: list[Frame3] = [Frame3()]
        self._frame_id: dict[int, int] = {id(self._frames[0]): 0}
        self._xyz: list[tuple[float, float, float]] = []
        self._rot: list[dict[str, float]] = []
        self._vec: list[tuple[float, float, float] | None] = []
        self._mode: list[int] = []  # 0 machine, 1 tcp, 2 dwo
        self._fid: list[int] = []
        self._rapid: list[bool] = []
        self._F: list[float] = []
        self._fmode: list[int] = []
        self._line: list[int] = []
        self._block: list[int] = []
        self._op: list[int] = []
        self._blen: dict[int, float] = {}
        self._break: set[int] = set()  # point indices that start a new row
        self._nblock = 0
        self.ops: list[_Op] = []
        self.cycles: list[Cycle] = []
        self.notes: dict[str, list[int]] = {}
        self.skipped_ops: list[str] = []
        self.offsets: dict[str, list[int]] = {}
        self._tool: Tool | None = None
        self.letters_used: set[str] = set()

    # ---- operations ------------------------------------------------------------------------
    def _current(self, line: int) -> _Op:
        if not self.ops:
            self.ops.append(_Op(None, line, self._tool))
        return self.ops[-1]

    def has_motion(self) -> bool:
        """Whether the current operation has points already."""
        return bool(self.ops) and bool(self._op) and self._op[-1] == len(self.ops) - 1

    def operation(self, name: str | None, line: int) -> None:
        """Start an operation named ``name`` (None: numbered) at ``line``; an operation without
        points yet is renamed instead."""
        if self.ops and not self.has_motion() and not any(c.operation == len(self.ops) - 1 for c in self.cycles):
            op = self.ops[-1]
            if name is not None or op.name is None:
                op.name, op.line = name, line
            return
        self.ops.append(_Op(name, line, self._tool))

    def name_operation(self, name: str, line: int) -> None:
        """Give the current operation a name if it has none (a comment after its tool change)."""
        op = self._current(line)
        if op.name is None:
            op.name = name

    def tool(self, tool: Tool, line: int) -> None:
        """A tool change: starts a new operation when the current one has points."""
        self._tool = tool
        if self.has_motion():
            self.ops.append(_Op(None, line, tool))
        else:
            self._current(line).tool = tool

    def skip(self, line: int, text: str, reason: str) -> None:
        """The construct at ``line`` is not applied: the current operation is dropped."""
        op = self._current(line)
        if op.skipped is None:
            op.skipped = f"{self.file}, line {line}: {text.strip()[:80]!r}: {reason}"

    def note(self, what: str, line: int) -> None:
        """A construct read without effect on the tool path (named in one warning)."""
        self.notes.setdefault(what, []).append(line)

    def offset(self, name: str, line: int) -> None:
        """The work offset the program selects (recorded, not added)."""
        self.work_offset = name
        self.offsets.setdefault(name, []).append(line)

    def machine_move(self, line: int, what: str) -> None:
        """A move in machine coordinates (not a point of the program): ends the current row."""
        self._break.add(len(self._xyz))
        self.note(what, line)

    def set_frame(self, frame: Frame3) -> None:
        self.frame = frame

    # ---- motion ----------------------------------------------------------------------------
    def _fid_now(self) -> int:
        key = id(self.frame)
        if key not in self._frame_id:
            self._frame_id[key] = len(self._frames)
            self._frames.append(self.frame)
        fid = self._frame_id[key]
        self._current(0).frames.add(fid)
        return fid

    def move(self, line: int, rapid: bool, xyz: tuple[float, float, float], rot: dict[str, float],
             vec: tuple[float, float, float] | None = None) -> None:
        """A straight move to ``xyz`` (program frame, mm) with the rotary words ``rot`` (deg)."""
        for v in (*xyz, *rot.values()):
            if not abs(v) <= MAX_WORD:
                raise InputError(f"position word {v:g} is beyond +-{MAX_WORD:g} (not a position of a machine)",
                                 file=self.file, line=line)
        self._nblock += 1
        self._append(line, rapid, xyz, rot, vec)

    def _append(self, line: int, rapid: bool, xyz: tuple[float, float, float], rot: dict[str, float],
                vec: tuple[float, float, float] | None) -> None:
        op = self._current(line)
        self._xyz.append(xyz)
        self._rot.append(rot)
        self._vec.append(vec)
        self._mode.append(1 if self.tcp else (2 if self.dwo else 0))
        self._fid.append(self._fid_now())
        self._rapid.append(rapid)
        self._F.append(math.nan if rapid else self.F)
        self._fmode.append(self.feed_mode)
        self._line.append(line)
        self._block.append(self._nblock)
        self._op.append(len(self.ops) - 1 if op is self.ops[-1] else self.ops.index(op))
        self.letters_used.update(rot)

    def arc(self, line: int, start: np.ndarray, end: np.ndarray, centre: np.ndarray, normal: np.ndarray, ccw: bool,
            rot0: dict[str, float], rot1: dict[str, float], turns: int = 0) -> None:
        """A circular or helical arc from ``start`` to ``end`` (program frame, mm) about ``centre``
        (counter-clockwise about ``normal`` when ``ccw``); rotary words interpolated linearly."""
        for v in (*end, *centre):
            if not abs(v) <= MAX_WORD:
                raise InputError(f"arc word {v:g} is beyond +-{MAX_WORD:g}", file=self.file, line=line)
        pts, length = arc_points(start, end, centre, normal, ccw, turns, self.chord_tol)
        self._nblock += 1
        self._blen[self._nblock] = length
        k = len(pts)
        for i, p in enumerate(pts):
            f = (i + 1) / k
            rot = {a: rot0.get(a, rot1[a]) + f * (rot1[a] - rot0.get(a, rot1[a])) for a in rot1}
            self._append(line, False, (float(p[0]), float(p[1]), float(p[2])), rot, None)

    def cycle(self, code: str, line: int, hole: np.ndarray, text: str) -> None:
        """A hole of a canned cycle (``hole``: the bottom of the hole, program frame, mm)."""
        op = self._current(line)
        op.kind = "cycle"
        fr = self.frame
        tip = fr.o + fr.R @ hole
        opi = len(self.ops) - 1
        if self.cycles and self.cycles[-1].line == line and self.cycles[-1].operation == opi:
            c = self.cycles[-1]
            c.holes = np.vstack([c.holes, tip])
            return
        prev = next((c for c in reversed(self.cycles) if c.operation == opi and c.code == code), None)
        if prev is not None and prev.modal:
            prev.holes = np.vstack([prev.holes, tip])
            prev.lines.append(line)
            return
        self.cycles.append(Cycle(code=code, line=line, text=text.strip(), holes=tip[None, :], operation=opi,
                                 lines=[line]))

    def end_cycle(self) -> None:
        for c in self.cycles:
            c.modal = False

    # ---- the program -----------------------------------------------------------------------
    def finish(self, machine: Any = None, fmt: str = "posted") -> CLProgram:
        """The CLProgram of the points read (module docstring), through ``machine``'s kinematics
        (None: the nominal machine of the rotary letters the program uses, with a warning)."""
        warnings: list[str] = []
        n = len(self._xyz)
        letters = self._letters(machine, warnings)
        if machine is None:
            machine = nominal_machine(letters)
        extra = sorted(self.letters_used - set(letters))
        q = np.zeros((n, 2))
        for i, rot in enumerate(self._rot):
            q[i, 0] = rot.get(letters[0], 0.0)
            q[i, 1] = rot.get(letters[1], 0.0)
        if self.dialect == "linuxcnc":  # LinuxCNC's trt kinematics take a table axis' value as the table's turn
            q = q * np.asarray(getattr(machine, "linuxcnc_sense", (1.0, 1.0)), float)
        op_of = np.asarray(self._op, np.int64)
        if extra:
            for i, rot in enumerate(self._rot):
                bad = [a for a in extra if abs(rot.get(a, 0.0)) > 1e-9]
                if bad:
                    self.ops[op_of[i]].skipped = self.ops[op_of[i]].skipped or (
                        f"{self.file}, line {self._line[i]}: rotary axis {bad[0]} = {rot[bad[0]]:g} deg: the machine "
                        f"has {letters[0]} and {letters[1]}")
        xyz = np.asarray(self._xyz, float).reshape(-1, 3)
        qr = np.radians(q)
        tip = np.empty((n, 3))
        axis = np.empty((n, 3))
        mode = np.asarray(self._mode, np.int64)
        fid = np.asarray(self._fid, np.int64)
        if n:
            t_m, a_m = machine.tool_pose_np(qr[:, 0], qr[:, 1], xyz[:, 0], xyz[:, 1], xyz[:, 2])
            a_t = machine.tool_axis_np(qr[:, 0], qr[:, 1])
            z = np.zeros(n)
            t_0, _ = machine.tool_pose_np(qr[:, 0], qr[:, 1], z, z, z)
            tip = np.where((mode == 0)[:, None], t_m, np.where((mode == 2)[:, None], t_m - t_0, xyz))
            axis = np.where((mode == 0)[:, None], a_m, a_t)
            if not self.letters_used:  # a three-axis program: X Y Z is the tip (tool length by the control), axis +Z
                tip = xyz.copy()
                axis = np.tile([0.0, 0.0, 1.0], (n, 1))
            vec = np.array([v if v is not None else (np.nan,) * 3 for v in self._vec], float).reshape(-1, 3)
            has = np.isfinite(vec).all(axis=1)
            if has.any():
                nv = np.linalg.norm(vec[has], axis=1)
                bad = nv < 1e-9
                if bad.any():
                    i = int(np.flatnonzero(has)[np.flatnonzero(bad)[0]])
                    raise InputError("tool vector (0, 0, 0) is not a direction", file=self.file, line=self._line[i])
                axis[has] = vec[has] / nv[:, None]
            for k, fr in enumerate(self._frames):
                sel = fid == k
                if not sel.any() or fr.identity:
                    continue
                if fr.rotates:
                    tip[sel] = fr.o + xyz[sel] @ fr.R.T
                    axis[sel] = fr.R[:, 2]
                else:
                    tip[sel] = tip[sel] + fr.o
        rapid = np.asarray(self._rapid, bool)
        line = np.asarray(self._line, np.int64)
        F = np.asarray(self._F, float)
        fm = np.asarray(self._fmode, np.int64)
        block = np.asarray(self._block, np.int64)
        curved = self._curved_lengths(machine, xyz, qr, mode, fid, block, rapid, np.asarray(self._fmode, np.int64))
        feed = self._feeds(tip, rapid, F, fm, block, mode, q, warnings, curved)
        # operations: drop the skipped ones
        keep = np.ones(n, bool)
        for k, op in enumerate(self.ops):
            if op.skipped is not None:
                keep &= op_of != k
                self.skipped_ops.append(f"operation '{self._op_name(k)}' (line {op.line}) dropped: {op.skipped}")
        brk = np.zeros(n, bool)
        for b in self._break:
            if b < n:
                brk[b] = True
        idx = np.flatnonzero(keep)
        tip, axis, rapid, feed, line, q, brk = (a[idx] for a in (tip, axis, rapid, feed, line, q, brk))
        op_k = op_of[idx]
        toolpaths: list[ToolPath] = []
        cycles_kept: list[Cycle] = []
        for k, op in enumerate(self.ops):
            if op.skipped is not None:
                continue
            sel = np.flatnonzero(op_k == k)
            start = int(sel[0]) if len(sel) else (toolpaths[-1].stop if toolpaths else 0)
            stop = int(sel[-1]) + 1 if len(sel) else start
            fr = [self._frames[f] for f in op.frames]
            xf = next((f.matrix() for f in fr if not f.identity), np.eye(4))
            cut = sel[~rapid[sel]] if len(sel) else sel
            kind = "cycle" if op.kind == "cycle" and not len(cut) else "motion"
            kind = "3+2" if kind == "motion" and any(f.rotates for f in fr) else kind
            if kind == "motion" and len(cut):
                moving = np.ptp(q[cut], axis=0).max() > 1e-9
                kind = "5-axis" if moving else ("3+2" if np.abs(q[cut]).max() > 1e-9 else "3-axis")
            tp = ToolPath(name=self._op_name(k), tool=op.tool, start=start, stop=stop, line=op.line, transform=xf,
                          kind=kind)
            toolpaths.append(tp)
            for c in self.cycles:
                if c.operation == k:
                    c.op_name = tp.name
                    cycles_kept.append(c)
        tp_id = np.full(len(idx), -1, np.int64)
        for k, tp in enumerate(toolpaths):
            tp_id[tp.start:tp.stop] = k
        m = len(idx)
        new = ~rapid & np.r_[True, rapid[:-1] | (tp_id[1:] != tp_id[:-1]) | brk[1:]] if m else np.zeros(0, bool)
        rows = np.where(rapid, -1, np.cumsum(new) - 1)
        warnings += self.skipped_ops
        if self.notes:
            parts = [f"{w} (line{'s' if len(ls) > 1 else ''} {_lines(ls)})" for w, ls in self.notes.items()]
            warnings.append(f"{self.file}: read without moving the tool path: {'; '.join(parts[:30])}")
        for c in cycles_kept:
            warnings.append(f"{self.file}, line {c.line}: canned cycle {c.code} ({len(c.holes)} hole"
                            f"{'s' if len(c.holes) != 1 else ''}) in operation '{c.op_name}': "
                            "listed, not smoothed")
        if self.offsets:
            warnings.append(f"work offset(s) {', '.join(self.offsets)} selected: tips are in the program's workpiece "
                            "frame (offsets recorded, not added)")
        if not (~rapid).any():  # nothing to analyse or smooth: say what there was
            if self.skipped_ops:
                raise InputError(f"no operation could be read: {self.skipped_ops[0]}", file=self.file)
            if cycles_kept:
                listed = "; ".join(f"{c.code} line {c.line} ({len(c.holes)} holes)" for c in cycles_kept[:10])
                raise InputError(f"no cutting move: only canned cycles ({listed}), which are listed, not smoothed",
                                 file=self.file)
            raise InputError("no cutting move: the program holds no feed motion (rapids and machine moves only)",
                             file=self.file)
        prog = CLProgram(tip=tip, axis=axis, rows=rows, feed=feed, rapid=rapid, line=line, toolpaths=toolpaths,
                         source=self.file, format=fmt, warnings=warnings, angles=np.radians(q),
                         rotary=tuple(letters))  # type: ignore[arg-type]
        prog.dialect = self.dialect
        prog.cycles = cycles_kept
        # per point what its block meant (camsmooth.post.rewrite writes new blocks in the same mode)
        origin = np.array([self._frames[f].o for f in fid], float).reshape(-1, 3)
        turned = np.array([self._frames[f].rotates for f in fid], bool)
        prog.modes = {"tcp": mode[idx], "feed_mode": fm[idx], "frame_origin": origin[idx], "frame_rotates": turned[idx]}
        prog.work_offset = self.work_offset
        return prog

    def _op_name(self, k: int) -> str:
        return self.ops[k].name or str(k + 1)

    def _letters(self, machine: Any, warnings: list[str]) -> tuple[str, str]:
        if machine is not None:
            return tuple(machine.rotary)  # type: ignore[return-value]
        used = self.letters_used
        if used <= {"A", "B"}:
            letters = ("A", "B")
        elif used <= {"A", "C"}:
            letters = ("A", "C")
        elif used <= {"B", "C"}:
            letters = ("B", "C")
        else:
            raise InputError(f"the program moves the rotary axes {', '.join(sorted(used))}: give the machine file "
                             "(--machine) that names its two", file=self.file)
        if used and self.tcp_or_machine_points():
            kind = {("A", "B"): "the default AB head", ("A", "C"): "a nominal AC table",
                    ("B", "C"): "a nominal BC table"}[letters]
            warnings.append(f"no machine file: the tool axis is that of {kind} (rotary axes {letters[0]}, "
                            f"{letters[1]}); give --machine for the program's machine")
        return letters

    def tcp_or_machine_points(self) -> bool:
        return any(self._fid[i] == 0 or not self._frames[self._fid[i]].rotates for i in range(len(self._fid)))

    def _curved_lengths(self, machine: Any, xyz: np.ndarray, qr: np.ndarray, mode: np.ndarray, fid: np.ndarray,
                        block: np.ndarray, rapid: np.ndarray, fm: np.ndarray) -> dict[int, float]:
        """Tool-tip path length (mm) of the inverse-time straight blocks in machine mode that turn a
        rotary axis: the controller interpolates the joints linearly, so the tip follows a curve, whose
        length camsmooth.post.model.tip_path_lengths gives (the forward kinematics sampled and
        Richardson-extrapolated). Block id -> length; other blocks keep their chords."""
        n = len(xyz)
        if n < 2:
            return {}
        k = np.arange(1, n)
        sel = k[(fm[k] == 93) & ~rapid[k] & (mode[k] == 0) & (mode[k - 1] == 0) & (fid[k] == fid[k - 1])
                & (block[k] != block[k - 1]) & np.any(np.abs(qr[k] - qr[k - 1]) > 1e-12, axis=1)]
        sel = sel[[not self._frames[f].rotates for f in fid[sel]]] if len(sel) else sel
        if not len(sel):
            return {}
        single = np.bincount(block, minlength=int(block.max()) + 1)[block[sel]] == 1  # straight blocks only
        sel = sel[single]
        if not len(sel):
            return {}
        from camsmooth.post.model import tip_path_lengths

        j1 = np.column_stack([xyz[sel], qr[sel]])
        j0 = np.column_stack([xyz[sel - 1], qr[sel - 1]])
        return dict(zip(block[sel].tolist(), tip_path_lengths(machine, j0, j1).tolist(), strict=True))

    def _feeds(self, tip: np.ndarray, rapid: np.ndarray, F: np.ndarray, fm: np.ndarray, block: np.ndarray,
               mode: np.ndarray, q: np.ndarray, warnings: list[str], curved: dict[int, float] | None = None
               ) -> np.ndarray:
        """Feed (mm/min) per point (module docstring); a warning where machine-mode G94 moves turn a
        rotary axis (F is then the joints' feed, not the tip's). curved: block id -> tip path length
        (mm) where it is not the chord (``_curved_lengths``)."""
        n = len(tip)
        feed = np.where(rapid, np.nan, F)
        if n == 0:
            return feed
        per_rev = (fm == 95) & ~rapid
        if per_rev.any():
            feed[per_rev] = F[per_rev] * self.S if math.isfinite(self.S) else np.nan
        inv = (fm == 93) & ~rapid
        if inv.any():
            chord = np.r_[0.0, np.linalg.norm(np.diff(tip, axis=0), axis=1)]
            blen = np.bincount(block, weights=chord)  # tip path length per block
            for b, length in (curved or {}).items():
                blen[b] = length
            with np.errstate(invalid="ignore"):
                feed[inv] = blen[block[inv]] * F[inv]
            # a block whose tool tip does not move (only a rotary axis turns, or nothing): its tip feed
            # is not defined; it takes the feed of the move before it (or after it, at a row's start)
            still = inv & (blen[block] <= 1e-9)
            if still.any():
                known = ~rapid & np.isfinite(feed) & ~still
                idx = np.where(known, np.arange(n), -1)
                prev = np.maximum.accumulate(idx)
                nxt = np.minimum.accumulate(np.where(known, np.arange(n), n)[::-1])[::-1]
                src = np.where(prev >= 0, prev, nxt)
                ok = still & (src < n)
                feed[ok] = feed[src[ok]]
        turns = np.r_[False, np.any(np.abs(np.diff(q, axis=0)) > 1e-9, axis=1)] if n else np.zeros(0, bool)
        g94_machine = (fm == 94) & ~rapid & (mode == 0) & turns
        if g94_machine.any():
            warnings.append("machine-mode moves in feed per minute (G94): F applies to the joint motion; the tool "
                            "tip's feed is reported as F written")
        return feed


def _lines(ls: list[int]) -> str:
    shown = ", ".join(str(x) for x in ls[:8])
    return shown + (f", ... ({len(ls)} in all)" if len(ls) > 8 else "")
