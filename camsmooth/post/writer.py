"""Five-axis G-code for real controllers: the one writer over the dialects' tables (``Words``,
each in its dialect's module: camsmooth.post.iso generic and fanuc, camsmooth.post.linuxcnc,
camsmooth.post.siemens, camsmooth.post.heidenhain); it writes a ``PostProgram``
(camsmooth.post.model). The reader of the programs it writes is camsmooth.post.own.

Dialects (``[post] dialect`` of the machine file, camsmooth.machine.kinematics.PostConfig):
generic, linuxcnc, fanuc, siemens (ISO G-code) and heidenhain (Klartext, ``L`` blocks).
Modes (``[post] mode``):

- ``machine``: every block commands the joints, X Y Z = the machine's linear axes
  (``Machine.linear_axes``: on the AB head the head pivot, METHODS section 1: pivot = CL + L_p T,
  no tool length compensation active; on a table machine c + R_wp (CL - c), the tool tip in the
  machine frame with the table turned, tool length by the controller; on the BC head-table
  c + Rz(-C)(CL - c) + L_p Ry(B) e_z) and the two rotary axes by the machine's names
  (``Machine.rotary``: A B, A C or B C), with **inverse-time feed**
  (G93: F = 1 / block time in 1/min). The block time is the length of the path the tool tip
  follows while the controller interpolates the joints linearly, divided by the programmed feed
  of the block, so the tip moves at the programmed feed (a controller in G94 applies F to the
  combined joint motion instead: LinuxCNC issue #2410, FreeCAD issue #18101). The tip path length
  is the polyline length of the forward kinematics sampled at 8 and 16 sub-steps per block,
  Richardson-extrapolated (error O(h^4)).
  Heidenhain has no inverse-time feed: the TNC reads F on a rotary axis in degrees/min, and M116
  (F in mm/min on rotary axes) works on rotary tables only, not on swivel heads (HEIDENHAIN
  iTNC 530 / TNC 640 user's manuals, "Miscellaneous functions for rotary axes, M116"); the
  writer refuses machine mode for Heidenhain: use mode = "tcp".
- ``tcp``: every block commands the tool tip X Y Z (workpiece frame, mm) and the rotary axis
  positions (A B, A C or B C) under the controller's tool-centre-point function, with F = the
  programmed tip feed (G94, mm/min): Fanuc ``G43.4 H<tool>`` ... ``G49`` (type 1: rotary axis
  positions); Siemens ``TRAORI`` ... ``TRAFOOF``; Heidenhain ``FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS``
  ... ``FUNCTION RESET TCPM`` (the successor of M128, which HEIDENHAIN recommends instead);
  LinuxCNC has no standard G-code for TCP: it switches kinematics (switchkins) by M-codes that
  the configuration remaps; the writer follows LinuxCNC's shipped five-axis configurations
  (``xyzac-trt.ini``, ``xyzbc-trt.ini``: ``M428`` remaps to kinematics type 1, the five-axis
  kinematics, and ``M429`` to type 0, identity), so TCP on is ``M428`` and off ``M429``; set
  ``[post] tcp_on / tcp_off`` for another configuration. The generic dialect has no TCP command
  and refuses tcp mode.

Path tolerance (how far the controller may blend off the programmed path), set after the
program start from the user's tolerance T (mm), by each controller manual's name for it:
LinuxCNC "path blending" ``G64 P<s T> Q<q T>`` (P the blending tolerance: a controller plan's
(``ControllerPlan.blend_tolerance``, camsmooth.controller.blend_tolerance), else s =
camsmooth.constants.PATH_TOLERANCE_SHARE; the block times of camsmooth.controller.blocks hold the
tool tip of every servo cycle of the planner model within EXECUTED_TOLERANCE_SHARE of T; Q the
naive-CAM detector's, q = NAIVE_CAM_TOLERANCE_SHARE, below T; where the plan stops each row's entry
move, ``ControllerPlan.entry_stop``, the dialect's exact stop ``G61`` before that move and the
``G64`` line again after it);
Heidenhain cycle 32 TOLERANCE (``CYCL DEF 32.0 TOLERANCE`` / ``32.1 T<T>`` / ``32.2 HSC-MODE:0``,
finishing); Siemens high-speed settings ``CYCLE832(<T>, _FINISH, 1)``; Fanuc AI contour control
``G05.1 Q1`` (look-ahead on; the Fanuc tolerance is a machine parameter, not a program word). A
machine whose controller camsmooth models (camsmooth.controller: LinuxCNC) gets the blocks and the
block times of its ``ControllerPlan``: G93 F = 1 / the plan's block time.

A and B sign convention (METHODS section 1; RS274NGC / ISO 841, as LinuxCNC's G-code manual
states under "Rotational axes"): A turns about +X, B about +Y, both by the right-hand rule, and
describe the tool's rotation relative to the workpiece: the tool axis (tip -> spindle) is
T(A, B) = Rx(A) Ry(B) e_z = (sin B, -sin A cos B, cos A cos B). So A = +30 deg, B = 0 tilts the
spindle toward -Y (T = (0, -0.5, 0.866)); A = 0, B = +30 deg toward +X (T = (0.5, 0, 0.866)).
LinuxCNC issue #2435 lists kinematics modules that turn the other way; check a machine with a
slow single-axis move before running a program.

Table machines (``[machine] kind``, camsmooth.machine.kinematics): the angles are still the tool's
rotation relative to the workpiece (ISO 841, right-hand rule): AC-table T = Rz(C) Rx(A) e_z,
BC-table and BC-head-table T = Rz(C) Ry(B) e_z; the table turns the workpiece the other way,
R_wp = Rx(-A) Rz(-C) (AC) or Ry(-B) Rz(-C) (BC), about the table centre c. Fanuc, Siemens,
Heidenhain and generic programs write these angles as they are. **LinuxCNC's sign mapping**: its
table-rotary-tilting kinematics (``xyzac-trt``, ``xyzbc-trt``) take a table axis' value as the
table's own rotation, joints = r + Rx(a) Rz(c) (pos - r) (xyzac) or r + Ry(b) Rz(c) (pos - r)
(xyzbc) with r the rot-point, which is camsmooth's c + R_wp (CL - c) with a = -A (b = -B),
c = -C and r = c. So on a table machine the linuxcnc dialect writes a = -A, c = -C (b = -B) in
both modes (a head's B of the BC head-table is the tool's rotation and keeps its sign;
camsmooth.post.linuxcnc.linuxcnc_sense): machine mode then gives the joints of an xyzac-trt /
xyzbc-trt configuration in identity kinematics (X Y Z = its joints, the tool tip), tcp mode
(``M428``, the trt kinematics on) X Y Z = the tool tip in the workpiece frame, the rot-point pins
set to the table centre. The header says so (``sense=linuxcnc`` in the post tag) and
``read_gcode`` negates the angles back.

Program layout: header comments (machine and its kind, the table centre of a table machine, tool,
method, inputs, post, conventions), the dialect's
program start (units mm, absolute, plane XY, offsets cancelled), then per row: rapid to a point
``safe_height`` mm above the row's first point along its tool axis, feed move onto it, the row at
the programmed feed, rapid back out ``safe_height`` along the last point's axis (the tip backs
out along its own axis, orientation held); between rows the rapid goes from above the last point
of one row to above the first of the next (A and B may turn there, at the safe height). Program
end: the dialect's end (TCP off, the usual retract to the top of Z travel for Fanuc ``G91 G28
Z0.``, LinuxCNC ``G53 G00 Z0``, Heidenhain ``M140 MB MAX``; none for generic and Siemens), M30.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth import __version__
from camsmooth.constants import (
    DEFAULT_SAFE_HEIGHT_MM,
    NAIVE_CAM_TOLERANCE_SHARE,
    PATH_TOLERANCE_SHARE,
    WRITTEN_DECIMALS,
)
from camsmooth.errors import InputError
from camsmooth.io.atomic import atomic_path
from camsmooth.post.model import PostDialect, PostProgram, check_travel, tip_path_lengths, written_joints

__all__ = ["Words", "Settings", "settings", "write_program", "format_blocks", "paren", "semicolon", "POST_TAG"]

#: the tag of the header line that tells camsmooth's own programs (camsmooth.post.own.read_gcode)
POST_TAG = "camsmooth post:"


def paren(text: str) -> str:
    """An ISO comment; parentheses inside a comment would end it, so they become brackets, and ';' (a
    comment start for many parsers, pygcode among them) becomes ','."""
    return "(" + text.replace("(", "[").replace(")", "]").replace(";", ",").replace("\n", " ") + ")"


def semicolon(text: str) -> str:
    """A ';' comment to the end of the line (Siemens, Heidenhain)."""
    return "; " + text.replace("\n", " ")


@dataclass(frozen=True)
class Words:
    """How one controller family spells a program (module docstring): the writer's table of a
    dialect, given by the dialect's module (camsmooth.post.iso, linuxcnc, siemens, heidenhain)."""

    name: str
    comment: Callable[[str], str]
    start: tuple[str, ...]
    end: tuple[str, ...] = ("M30",)
    home: tuple[str, ...] = ()
    tcp_on: str | None = None
    tcp_off: str | None = None
    inverse_time: str | None = "G93"
    per_minute: str = "G94"
    klartext: bool = False
    percent: bool = False
    path_tolerance: tuple[str, ...] | None = None  # lines setting the path tolerance ({tol}, {blend}, {naive}: mm)
    exact_stop: str | None = None  # modal exact stop for a plan's entry stop (path_tolerance again after it)


# ----------------------------------------------------------------------------------------------
# number formats
def _fixed(values: np.ndarray, decimals: int = 4, sign: bool = False) -> Any:
    """Fixed-point text with ``decimals`` decimals for every value at once (no exponent, no '-0';
    a '+' with ``sign``), as a polars String Series: integer arithmetic and polars' string casts,
    a million values in well under a second (Python's f-strings took ~10 s)."""
    import polars as pl

    scaled = np.round(np.asarray(values, float) * 10.0 ** decimals).astype(np.int64)
    mag = np.abs(scaled)
    unit = 10 ** decimals
    df = pl.DataFrame({"i": mag // unit, "f": mag % unit, "neg": scaled < 0})
    prefix = pl.when(pl.col("neg")).then(pl.lit("-")).otherwise(pl.lit("+" if sign else ""))
    return df.select(pl.concat_str([prefix, pl.col("i").cast(pl.String), pl.lit("."),
                                    pl.col("f").cast(pl.String).str.zfill(decimals)]).alias("t"))["t"]


def _fixed_sig(values: np.ndarray, digits: int = 7, max_decimals: int = 5) -> np.ndarray:
    """Fixed-point text of positive values with at least ``digits`` significant digits (up to
    ``max_decimals`` decimals; controllers do not read exponents), as an array of str."""
    v = np.asarray(values, float)
    exp = np.floor(np.log10(np.where(v > 0, v, 1.0))).astype(int)
    decimals = np.clip(digits - 1 - exp, 1, max_decimals)
    out = np.empty(len(v), dtype=object)
    for dd in np.unique(decimals):
        k = decimals == dd
        out[k] = _fixed(v[k], int(dd)).to_numpy()
    return out


# ----------------------------------------------------------------------------------------------
# writer
#: a block whose tip moves less than this (mm) stands still (its F is the rotary feed in tcp mode)
_STILL_MM = 1e-6
#: ... and whose rotary axes turn less than this (deg) does not move at all
_STILL_DEG = 1e-6


@dataclass
class _Moves:
    joints: np.ndarray  # (M, 5) X Y Z (pivot) A B
    tips: np.ndarray  # (M, 3)
    rapid: np.ndarray  # (M,) bool
    feed: np.ndarray  # (M,) mm/min (nan for rapids)
    row_start: list[tuple[int, int, int]] = field(default_factory=list)  # (move index, row id, points)
    block_time: np.ndarray | None = None  # (M,) s commanded per block, nan where the feed decides
    t_prog: np.ndarray | None = None  # (M,) s from the row's start at the programmed feed (nan for rapids)
    f_prog: np.ndarray | None = None  # (M,) mm/min the programmed feed (nan for rapids)
    t_opt: np.ndarray | None = None  # (M,) s from the row's start, time-optimal law (nan: not written)




def _row_slices(rows: np.ndarray) -> list[slice]:
    rows = np.asarray(rows)
    if len(rows) == 0:
        return []
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    ends = np.r_[starts[1:], len(rows)]
    return [slice(int(s), int(e)) for s, e in zip(starts, ends, strict=True)]


def _moves(rows: np.ndarray, joints: np.ndarray, tips: np.ndarray, T: np.ndarray, feed: np.ndarray,
           h: float, lifted: np.ndarray, block_time: np.ndarray | None = None, t_prog: np.ndarray | None = None,
           f_prog: np.ndarray | None = None, t_opt: np.ndarray | None = None) -> _Moves:
    """Entry rapid, row points, exit rapid per row (loop over rows, not points). lifted: (N, 5)
    the joints with the tip ``h`` mm up the tool axis T (the retract poses). block_time: (N,)
    s per point, the commanded time of the block ending there (nan where the feed decides);
    t_prog: (N,) s from the row's start at the programmed feed (written beside each block); t_opt:
    (N,) s from the row's start under the time-optimal law, written beside each block where the
    block times are the controller plan's (they no longer tell the time-optimal law)."""
    J, P, R, F, starts, BT, TP, FP, TO = [], [], [], [], [], [], [], [], []
    count = 0
    for sl in _row_slices(rows):
        first, last = sl.start, sl.stop - 1
        n = sl.stop - sl.start
        J += [lifted[first:first + 1], joints[sl], lifted[last:last + 1]]
        P += [tips[first:first + 1] + h * T[first], tips[sl], tips[last:last + 1] + h * T[last]]
        R += [np.array([True]), np.zeros(n, bool), np.array([True])]
        F += [np.array([np.nan]), feed[sl], np.array([np.nan])]
        bt = np.full(n, np.nan) if block_time is None else np.asarray(block_time[sl], float).copy()
        bt[0] = np.nan  # the entry move runs at the programmed feed
        BT += [np.array([np.nan]), bt, np.array([np.nan])]
        tp = np.full(n, np.nan) if t_prog is None else np.asarray(t_prog[sl], float)
        TP += [np.array([np.nan]), tp, np.array([np.nan])]
        fp = feed[sl] if f_prog is None else np.asarray(f_prog[sl], float)
        FP += [np.array([np.nan]), fp, np.array([np.nan])]
        to = np.full(n, np.nan) if t_opt is None else np.asarray(t_opt[sl], float)
        TO += [np.array([np.nan]), to, np.array([np.nan])]
        starts.append((count, int(rows[first]), n))
        count += n + 2
    if not J:
        return _Moves(np.zeros((0, 5)), np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0), [], np.zeros(0))
    return _Moves(np.concatenate(J), np.concatenate(P), np.concatenate(R), np.concatenate(F), starts,
                  np.concatenate(BT), np.concatenate(TP), np.concatenate(FP), np.concatenate(TO))


def _block_feeds(machine: Any, mv: _Moves, mode: str) -> tuple[np.ndarray, int]:
    """F word per move: inverse time (1/min) in machine mode, the tip feed (mm/min) in tcp mode;
    nan for rapids. Also the number of cut blocks whose tip does not move (time from the rotary
    axes' speed limits).

    In tcp mode a block of given time whose tip stands still (it only turns the tool about its
    tip) gets the rotary feed, deg/min over the rotary axes' Euclidean distance: under G94 the F of
    a move whose linear axes do not move is the rotation in degrees per minute, two rotary axes
    together by D = sqrt(dA^2 + dB^2 + dC^2) (LinuxCNC's machining-centre overview, "Feed Rate",
    after RS274/NGC 3 section 2.1.2.5; a tip feed there would be F0, which LinuxCNC refuses); a
    block that moves neither keeps the programmed feed."""
    F = np.full(len(mv.rapid), np.nan)
    cut = np.flatnonzero(~mv.rapid)
    if mode == "tcp" or len(cut) == 0:
        F[cut] = mv.feed[cut]
        if mv.block_time is not None and len(cut):
            timed = cut[np.isfinite(mv.block_time[cut])]
            chord = np.linalg.norm(mv.tips[timed] - mv.tips[timed - 1], axis=1)
            turn = np.degrees(np.linalg.norm(mv.joints[timed, 3:] - mv.joints[timed - 1, 3:], axis=1))
            minutes = np.maximum(mv.block_time[timed], 1e-6) / 60.0
            rate = np.where(chord >= _STILL_MM, chord, turn) / minutes
            moves = (chord >= _STILL_MM) | (turn >= _STILL_DEG)
            F[timed[moves]] = np.maximum(np.round(rate[moves], 1), 0.1)
        return F, 0
    q0 = mv.joints[cut - 1]  # a row always starts with its entry rapid, so cut - 1 >= 0
    q1 = mv.joints[cut]
    L = tip_path_lengths(machine, q0, q1)
    t = L / mv.feed[cut]  # minutes
    still = L < 1e-9
    if still.any():
        limits = getattr(machine, "limits", {}) or {}
        rot = np.zeros(int(still.sum()))
        for k, name in ((3, getattr(machine, "rotary", "AB")[0]), (4, getattr(machine, "rotary", "AB")[1])):
            lim = limits.get(name)
            if lim is not None and np.isfinite(lim.vmax):
                rot = np.maximum(rot, np.abs(q1[still, k] - q0[still, k]) / lim.vmax / 60.0)
        t[still] = np.maximum(rot, 1e-6)
    F[cut] = 1.0 / t
    if mv.block_time is not None:  # the controller plan's blocks: F = 1 / (its block time)
        timed = cut[np.isfinite(mv.block_time[cut])]
        F[timed] = 60.0 / np.maximum(mv.block_time[timed], 1e-6)
    return F, int(still.sum())


def _header(dialect: Words, mode: str, machine: Any, program: PostProgram, h: float, still: int,
            sign: np.ndarray) -> list[str]:
    """The header comments: machine, tool, method, the run's inputs (mm, mm/min, degrees), the post
    tag ``camsmooth post:`` that ``read_gcode`` recognises, and the conventions. sign: (2,) the sign
    each rotary axis is written with (PostDialect.signs)."""
    c = dialect.comment
    method, inputs, n_points, tolerance = program.method, program.inputs, program.n_points, program.tolerance
    pivot = float(machine.pivot)
    kind = machine.kind
    centre = tuple(float(v) for v in machine.table_centre)
    table = machine.has_table
    centre_txt = f", table centre {centre[0]:.4f} {centre[1]:.4f} {centre[2]:.4f} mm" if table else ""
    head = [
        c(f"generated by camsmooth {__version__} - five-axis tool-axis smoothing"),
        c(f"machine: {machine.name}, kind {kind}, pivot {pivot:.4f} mm{centre_txt}"),
        c(f"tool: {program.tool_text}"),
        c(f"method: {method}; {n_points} points"),
    ]
    if machine.description.preset is None:
        head.insert(2, c(f"chain: {machine.description.summary()}"))
    head.extend(c(f"input {k}: {v}") for k, v in inputs)
    tol = "" if tolerance is None else f" tolerance={float(tolerance):.6g}"
    r1, r2 = machine.rotary
    sense = "linuxcnc" if (sign != 1.0).any() else "iso"
    where = f" centre={centre[0]:.6f},{centre[1]:.6f},{centre[2]:.6f}" if table else ""
    head.append(c(f"{POST_TAG} dialect={dialect.name} mode={mode} units=mm pivot={pivot:.6f} method={method}{tol} "
                  f"kind={kind} rotary={r1},{r2}{where} sense={sense}"))
    if mode == "machine":
        if not table:
            head.append(c(f"X Y Z: head pivot position mm (no tool length compensation); {r1} {r2}: degrees"))
        elif machine.has_head:
            head.append(c(f"X Y Z: head pivot position mm, machine frame (the table turns the workpiece about "
                          f"its axes; no tool length compensation); {r1} {r2}: degrees"))
        else:
            head.append(c(f"X Y Z: machine linear axes mm, the tool tip in the machine frame (the table turns the "
                          f"workpiece about its axes; tool length by the controller); {r1} {r2}: degrees"))
        head.append(c("F: inverse time 1/min (G93), so the tool tip moves at the planned feed"))
        if still:
            head.append(c(f"{still} block(s) turn {r1}/{r2} without moving the tip: timed by the rotary speed limits"))
    else:
        head.append(c(f"X Y Z: tool tip mm, workpiece frame; {r1} {r2}: rotary axis positions, degrees; "
                      "F: tip feed mm/min"))
    about = " / ".join(machine.description.about(r) for r in (r1, r2))
    formula = machine.description.axis_formula()
    if sense == "iso":
        head.append(c(f"{r1} {r2}: right-hand rule about {about}, tool relative to workpiece (ISO 841): {formula}"))
    else:
        flipped = [n for n, s_ in zip((r1, r2), sign, strict=True) if s_ < 0]
        words = ", ".join(f"{n.lower()} = -{n}" for n in flipped)
        head.append(c(f"{r1} {r2} written in LinuxCNC's sense (its trt kinematics: a table axis' value is the "
                      f"table's rotation): {words}, where {r1} {r2} are the tool's rotation relative to the "
                      f"workpiece (ISO 841), right-hand rule about {about}: {formula}"))
    if table:
        head.append(c(f"table centre {centre[0]:.4f} {centre[1]:.4f} {centre[2]:.4f} mm (workpiece frame at zero "
                      "angles, where the table's axes cross"
                      + ("; LinuxCNC: the rot-point of the trt kinematics)" if sense != "iso" else ")")))
    head.append(c(f"rows are entered and left by rapids {h:.4f} mm up along the tool axis"))
    head.append(c("t= beside a block: s from the row's start at the programmed feed f= (mm/min, given where it "
                  "changes)"))
    blend, tol = getattr(program, "blend_tolerance", None), getattr(program, "tolerance", None)
    if blend is not None and tol is not None and blend > tol and "G64" in (dialect.path_tolerance or ("",))[0]:
        head.append(c(f"G64 P{blend:.4f} over the {tol:.4f} mm tolerance: every move turns a rotary axis, "
                      "joined by parabolic blends only,"))
        head.append(c("where P caps the blend speed: the block times hold the tool tip within the tolerance at "
                      "every servo cycle"))
        if getattr(program, "entry_stop", False) and dialect.exact_stop is not None:
            head.append(c(f"each row's entry move ends at rest: {dialect.exact_stop} before it, the G64 line again "
                          "after it"))
    off = float(getattr(program, "end_offset", 0.0) or 0.0)
    if off > 0:
        head.append(c(f"block ends up to {1e3 * off:.2g} um off the path's points, to the outside of its curve and "
                      "inside the tolerance (the tool axes as planned)"))
    return head


@dataclass(frozen=True)
class Settings:
    """What a program is written with: the dialect's entry, the mode ('machine' or 'tcp'), the tool
    number, the TCP on / off blocks (``[post]`` or the dialect's) and the retract height (mm)."""

    entry: PostDialect
    mode: str
    tool: int
    tcp_on: str | None
    tcp_off: str | None
    safe_height: float


def settings(machine: Any, dialect: str | None = None, mode: str | None = None,
             safe_height: float = DEFAULT_SAFE_HEIGHT_MM) -> Settings:
    """The writer's settings for ``machine`` (its ``post``, camsmooth.machine.kinematics.PostConfig,
    where ``dialect`` / ``mode`` are None). InputError for an unknown dialect or mode, machine mode
    on Heidenhain, tcp mode on a dialect without a tool-centre-point command, a safe height that
    is not a finite number >= 0 mm."""
    from camsmooth.post import DIALECTS

    post = getattr(machine, "post", None)
    dname = dialect or (post.dialect if post is not None else "generic")
    mode = mode or (post.mode if post is not None else "machine")
    own = [k for k, v in DIALECTS.items() if v.own]
    if dname not in own:
        raise InputError(f"unknown G-code dialect {dname!r} (known: {', '.join(own)})")
    if mode not in ("machine", "tcp"):
        raise InputError(f"unknown G-code mode {mode!r} (known: machine, tcp)")
    entry: PostDialect = DIALECTS[dname]
    d: Words = entry.words
    tool_no = int(getattr(post, "tool", 1) if post is not None else 1)
    tcp_on = (getattr(post, "tcp_on", None) if post is not None else None) or d.tcp_on
    tcp_off = (getattr(post, "tcp_off", None) if post is not None else None) or d.tcp_off
    if mode == "machine" and d.inverse_time is None:
        raise InputError("Heidenhain controls have no inverse-time feed and M116 does not apply to swivel heads (on "
                         "a rotary table it gives F in mm/min on the rotary axes, not the tool tip's feed), so machine "
                         "mode cannot hold the tip feed: set [post] mode = \"tcp\" (FUNCTION TCPM)")
    if mode == "tcp" and tcp_on is None:
        raise InputError(f"the {dname} dialect has no tool-centre-point command: set [post] dialect to linuxcnc, "
                         "fanuc, heidenhain or siemens, or mode = \"machine\"")
    h = float(safe_height)
    if not math.isfinite(h) or h < 0:
        raise InputError(f"safe height must be a finite number >= 0 mm, got {safe_height!r}")
    return Settings(entry, mode, tool_no, tcp_on, tcp_off, h)


def write_program(path: str | os.PathLike, program: PostProgram, machine: Any, *, dialect: str | None = None,
                  mode: str | None = None, safe_height: float = DEFAULT_SAFE_HEIGHT_MM, check_limits: bool = True,
                  program_name: str = "CAMSMOOTH", setup: Any = None) -> Path:
    """Write ``program`` as five-axis G-code to ``path`` atomically, in ``dialect`` (a key of
    camsmooth.post.DIALECTS that camsmooth writes whole programs in) and ``mode`` ('machine' or
    'tcp'; both default to ``machine.post``, camsmooth.machine.kinematics.PostConfig). Module
    docstring for the layout; coordinates are written with WRITTEN_DECIMALS decimals (mm, deg).

    machine: the kinematics (``tool_pose_np`` for the block times, ``linear_axes`` for the
    retracts, ``limits``, ``rotary``) and the header's machine words. safe_height: retract along
    the tool axis between rows (mm). With ``check_limits`` every commanded joint value, the
    retracts included, is checked against ``machine.limits``: InfeasibleError naming the axis,
    travel, row and point. InputError for an unknown dialect or mode, machine mode on Heidenhain,
    tcp mode on the generic dialect, a feed that is not finite and > 0, non-finite coordinates.
    setup: the tool call, spindle, coolant and work offset the input names
    (camsmooth.post.setup.ShopSetup), written after the program start (before the TCP command),
    M9 M5 before the end; None writes neither.
    """
    st = settings(machine, dialect, mode, safe_height)
    entry, d, mode, h = st.entry, st.entry.words, st.mode, st.safe_height

    rows = np.asarray(program.rows, dtype=np.int64)
    idx = np.asarray(program.idx, dtype=np.int64)
    q = np.asarray(program.joints, dtype=float).reshape(-1, 5)
    xyz, A, B = q[:, :3], q[:, 3], q[:, 4]
    T = np.asarray(program.axis, dtype=float).reshape(-1, 3)
    tip = np.asarray(program.tips, dtype=float).reshape(-1, 3)
    feed = np.asarray(program.feed, dtype=float)
    bad = ~(np.isfinite(feed) & (feed > 0))
    if bad.any():
        k = int(np.argmax(bad))
        raise InputError(f"feed must be a finite number > 0 mm/min at row {int(rows[k])}, point {int(idx[k])}, "
                         f"got {float(feed[k])!r}", column="feed")
    finite = np.isfinite(q).all(axis=1) & np.isfinite(T).all(axis=1) & np.isfinite(tip).all(axis=1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise InputError(f"non-finite axis value at row {int(rows[i])}, point {int(idx[i])}; cannot write G-code")
    # the retract poses: the tip h mm up its tool axis, the angles held (on a head the pivot moves
    # by h T; on a table the linear axes move along the machine's tool axis)
    up = machine.linear_axes(tip + h * T, A, B) if hasattr(machine, "linear_axes") else xyz + h * T
    if check_limits:
        check_travel(machine, rows, idx, A, B, xyz, "point")
        check_travel(machine, rows, idx, A, B, up, f"retract ({h:g} mm along the tool axis)")

    mv = _moves(rows, q, tip, T, feed, h, np.column_stack([up, A, B]), program.block_time, program.t_prog,
                program.f_prog, program.t_opt)
    # the controller runs the values as written (4 decimals, mm and degrees): time the blocks on those
    mv.joints = written_joints(mv.joints)
    mv.tips = np.round(mv.tips, WRITTEN_DECIMALS)
    F, still = _block_feeds(machine, mv, mode)
    sign = entry.signs(machine)
    lines = _program_open(d, program_name) + _header(d, mode, machine, program, h, still, sign)
    # the blend tolerance the controller plan was timed with (camsmooth.controller.blend_tolerance)
    start = _program_start(d, mode, st.tcp_on, st.tool, program.tolerance, program.blend_tolerance)
    if setup is not None and not setup.empty:  # the input's tool call, spindle, coolant, work offset
        blocks = setup.start_blocks(d.name)
        at = len(d.start) if not d.klartext else 0
        if d.klartext and any(b.startswith("TOOL CALL") for b in blocks):
            start = start[1:]  # the setup's TOOL CALL (with the spindle speed) replaces the writer's
        start = start[:at] + blocks + start[at:]
    lines += start
    coords = np.column_stack([mv.joints[:, :3] if mode == "machine" else mv.tips, np.degrees(mv.joints[:, 3:]) * sign])
    stop = None
    if getattr(program, "entry_stop", False) and d.exact_stop is not None and program.tolerance is not None:
        # the entry ends at rest; the path tolerance the program started with is set again after it
        stop = ([d.exact_stop], _path_tolerance(d, program.tolerance, program.blend_tolerance))
    lines += _blocks(d, mode, mv, coords, F, "XYZ" + "".join(getattr(machine, "rotary", ("A", "B"))), stop)
    end = _program_end(d, mode, st.tcp_off, program_name)
    if setup is not None and not setup.empty:
        at = len(end) - len(d.home) - len(d.end) - int(d.klartext) - int(d.percent)
        end = end[:at] + setup.end_blocks() + end[at:]
    lines += end
    if d.klartext:
        lines = [f"{k} {ln}" for k, ln in enumerate(lines)]
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return path


def _blocks(d: Words, mode: str, mv: Any, coords: np.ndarray, F: np.ndarray, letters: str = "XYZAB",
            entry_stop: tuple[list[str], list[str]] | None = None) -> list[str]:
    """One formatted line per block (numbers formatted as whole columns by polars, not one by
    one), with a comment line at each row's start; ``letters`` the address of each coordinate
    column (X Y Z and the machine's rotary axes). F is modal in G94 and in Klartext: written when
    it changes or after a rapid; in G93 every feed block carries its own. entry_stop: the lines
    written before and after each row's first feed move (its entry), which then ends at rest."""
    import polars as pl

    n = len(coords)
    rapid = np.asarray(mv.rapid, bool)
    f_vals = np.asarray(F, float)
    write_f = ~rapid
    if mode == "tcp":
        prev = np.concatenate([[np.nan], f_vals[:-1]])
        prev_rapid = np.concatenate([[True], rapid[:-1]])
        write_f &= ~((f_vals == prev) & ~prev_rapid)
    f_text = np.full(n, "", dtype=object)
    k = np.flatnonzero(write_f)
    if len(k):
        f_text[k] = _fixed_sig(f_vals[k]) if mode == "machine" else _fixed(f_vals[k], 1).to_numpy()
        f_text[k] = " F" + f_text[k]
    f_text = f_text + _annotations(d, mv, rapid)
    cols = {c: _fixed(coords[:, j], sign=d.klartext) for j, c in enumerate(letters)}
    df = pl.DataFrame({**cols, "rapid": rapid, "f": f_text.astype(str)})
    words = [pl.lit(c) + pl.col(c) for c in letters]
    if d.klartext:
        head, tail = pl.lit("L"), pl.when(pl.col("rapid")).then(pl.lit(" R0 FMAX")).otherwise(pl.col("f"))
    else:
        head, tail = pl.when(pl.col("rapid")).then(pl.lit("G00")).otherwise(pl.lit("G01")), pl.col("f")
    block = df.select((pl.concat_str([head, *words], separator=" ") + tail).alias("b"))["b"].to_list()
    starts = {s_: (row, cnt) for s_, row, cnt in mv.row_start}
    edges = sorted(set(starts) | {0, n})
    out: list[str] = []
    for a_, b_ in zip(edges[:-1], edges[1:], strict=True):
        if a_ in starts:
            row, cnt = starts[a_]
            out.append(d.comment(f"row {row}: {cnt} points"))
        feed = a_ + np.flatnonzero(~rapid[a_:b_])
        if entry_stop is not None and a_ in starts and len(feed):
            e = int(feed[0])
            out.extend(block[a_:e] + entry_stop[0] + block[e:e + 1] + entry_stop[1] + block[e + 1:b_])
        else:
            out.extend(block[a_:b_])
    return out


def format_blocks(dialect: str, coords: np.ndarray, F: np.ndarray, rapid: np.ndarray, letters: str,
                  inverse_time: bool) -> list[str]:
    """The motion blocks of ``dialect`` (a key of camsmooth.post.DIALECTS) exactly as ``write_program`` formats them,
    one line per block: coords (M, 5) the words of ``letters`` (X Y Z mm, rotary deg, as they are
    to be written), F (M,) the F word (1/min with ``inverse_time``: on every feed block, 7
    significant digits; else mm/min, 1 decimal, written where it changes), rapid (M,) bool. No row
    comments, no annotations (camsmooth.post.rewrite writes blocks into a posted program)."""
    coords = np.asarray(coords, float).reshape(-1, len(letters))
    rapid = np.asarray(rapid, bool)
    mv = _Moves(np.zeros((len(coords), 5)), np.zeros((len(coords), 3)), rapid, np.asarray(F, float))
    from camsmooth.post import DIALECTS

    return _blocks(DIALECTS[dialect].words, "machine" if inverse_time else "tcp", mv, coords, F, letters)


def _annotations(d: Words, mv: Any, rapid: np.ndarray) -> np.ndarray:
    """Per block the comment ``t=<s> [f=<mm/min>]``: the programmed-feed time from the row's start
    (9 decimals) and, where it changes (and at each row's entry), the programmed feed, so that
    ``read_gcode`` recovers the time base smooth computed Gamma on ("" for rapids and when the
    writer was given no times)."""
    n = len(rapid)
    out = np.full(n, "", dtype=object)
    t = getattr(mv, "t_prog", None)
    if t is None:
        return out
    k = np.flatnonzero(~rapid & np.isfinite(t))
    if not len(k):
        return out
    text = "t=" + _fixed(np.asarray(t)[k], 9).to_numpy().astype(object)
    feed = np.asarray(mv.f_prog if mv.f_prog is not None else mv.feed, float)
    prev_cut = np.r_[True, rapid[:-1]]
    prev_feed = np.r_[np.nan, feed[:-1]]
    new_f = (prev_cut | (feed != prev_feed))[k] & np.isfinite(feed[k])
    if new_f.any():
        text[new_f] = text[new_f] + " f=" + _fixed(feed[k][new_f], 3).to_numpy().astype(object)
    t_opt = getattr(mv, "t_opt", None)
    if t_opt is not None and np.isfinite(np.asarray(t_opt)[k]).all():
        text = text + " o=" + _fixed(np.asarray(t_opt)[k], 9).to_numpy().astype(object)
    out[k] = np.array([" " + d.comment(x) for x in text], dtype=object) if d.comment is not paren else \
        " (" + text + ")"
    return out


def _program_open(d: Words, name: str) -> list[str]:
    """What must come first: Heidenhain's BEGIN PGM line, Fanuc's tape start and program number."""
    if d.klartext:
        return [f"BEGIN PGM {name} MM"]
    if d.percent:
        return ["%", f"O0001 {paren(name)}"]
    return []


def _path_tolerance(d: Words, tolerance: float, blend: float | None = None) -> list[str]:
    """The dialect's path-tolerance lines for the user's ``tolerance`` (mm) and the controller's
    blend tolerance ``blend`` (mm; None: PATH_TOLERANCE_SHARE of the tolerance); [] without any."""
    if d.path_tolerance is None:
        return []
    p = PATH_TOLERANCE_SHARE * tolerance if blend is None else blend
    words = _fixed(np.array([tolerance, p, NAIVE_CAM_TOLERANCE_SHARE * tolerance]), 4)
    return [ln.format(tol=words[0], blend=words[1], naive=words[2]) for ln in d.path_tolerance]


def _program_start(d: Words, mode: str, tcp_on: str | None, tool: int, tolerance: float | None = None,
                   blend: float | None = None) -> list[str]:
    tol = [] if tolerance is None else _path_tolerance(d, tolerance, blend)
    if d.klartext:
        out = [f"TOOL CALL {tool} Z"] + tol
        if mode == "tcp":
            out.append(tcp_on or "")
        return out
    out = list(d.start) + tol
    if mode == "machine":
        out.append(d.inverse_time or "")
    else:
        out.append(d.per_minute)
        out.append((tcp_on or "").format(tool=tool))
    return out


def _program_end(d: Words, mode: str, tcp_off: str | None, name: str) -> list[str]:
    out = []
    if mode == "tcp" and tcp_off:
        out.append(tcp_off)
    if mode == "machine" and d.per_minute:
        out.append(d.per_minute)
    out += list(d.home) + list(d.end)
    if d.klartext:
        out.append(f"END PGM {name} MM")
    if d.percent:
        out.append("%")
    return out


