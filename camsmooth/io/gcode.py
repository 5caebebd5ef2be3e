"""Five-axis G-code for real controllers: one writer with per-dialect tables, and a reader of the
programs it writes (for round trips and ``load_program``).

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
LinuxCNC "path blending" ``G64 P<s T> Q<s T>`` (P the blending tolerance, Q the naive-CAM
detector's; s = camsmooth.controller.PATH_TOLERANCE_SHARE: LinuxCNC's own bound on its XYZ corner
blends, while the block times of camsmooth.controller.blocks hold the tool tip of every servo
cycle of the planner model within EXECUTED_TOLERANCE_SHARE of T);
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
camsmooth.controller.linuxcnc.linuxcnc_sense): machine mode then gives the joints of an xyzac-trt /
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
import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth import __version__
from camsmooth.controller import PATH_TOLERANCE_SHARE
from camsmooth.errors import InfeasibleError, InputError
from camsmooth.io.atomic import atomic_path
from camsmooth.io.program import CLProgram, Tool, ToolPath, Written
from camsmooth.io.table import read_text_file
from camsmooth.smoothing.evaluate import WRITTEN_DECIMALS, written_joints
from camsmooth.smoothing.result import MethodResult, SmoothResult, describe_inputs

__all__ = ["write_gcode", "read_gcode", "tip_path_lengths", "format_blocks", "DEFAULT_SAFE_HEIGHT_MM", "DIALECTS"]

#: Default retract height between rows, along the tool axis (mm).
DEFAULT_SAFE_HEIGHT_MM = 10.0
#: Sub-steps per block for the tip path length (Richardson with half as many).
_SUBSTEPS = 16


def _paren(text: str) -> str:
    """An ISO comment; parentheses inside a comment would end it, so they become brackets, and ';' (a
    comment start for many parsers, pygcode among them) becomes ','."""
    return "(" + text.replace("(", "[").replace(")", "]").replace(";", ",").replace("\n", " ") + ")"


def _semicolon(text: str) -> str:
    return "; " + text.replace("\n", " ")


@dataclass(frozen=True)
class Dialect:
    """How one controller family spells a program (see the module docstring)."""

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
    path_tolerance: tuple[str, ...] | None = None  # lines setting the path tolerance ({tol}, {blend}: mm)


DIALECTS: dict[str, Dialect] = {
    "generic": Dialect("generic", _paren, ("G21", "G90", "G17")),
    "linuxcnc": Dialect("linuxcnc", _paren, ("G21", "G90", "G17", "G40", "G49"), home=("G53 G00 Z0",),
                        tcp_on="M428", tcp_off="M429", path_tolerance=("G64 P{blend} Q{blend}",)),
    "fanuc": Dialect("fanuc", _paren, ("G21", "G90", "G17", "G40", "G49", "G80"), home=("G91 G28 Z0.", "G90"),
                     tcp_on="G43.4 H{tool}", tcp_off="G49", percent=True, path_tolerance=("G05.1 Q1",)),
    "siemens": Dialect("siemens", _semicolon, ("G71", "G90", "G17", "G40"), tcp_on="TRAORI", tcp_off="TRAFOOF",
                       path_tolerance=("CYCLE832({tol}, _FINISH, 1)",)),
    "heidenhain": Dialect("heidenhain", _semicolon, (), end=("M30",), home=("M140 MB MAX",),
                          tcp_on="FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS", tcp_off="FUNCTION RESET TCPM",
                          inverse_time=None, per_minute="", klartext=True,
                          path_tolerance=("CYCL DEF 32.0 TOLERANCE", "CYCL DEF 32.1 T{tol}",
                                          "CYCL DEF 32.2 HSC-MODE:0")),
}
_POST_TAG = "camsmooth post:"


# ----------------------------------------------------------------------------------------------
# kinematics helpers
def tip_path_lengths(machine: Any, q0: np.ndarray, q1: np.ndarray, substeps: int = _SUBSTEPS) -> np.ndarray:
    """Length (mm) of the tool-tip path of each block when the joints move linearly from q0 to q1.

    q0, q1: (M, 5) joints (X, Y, Z mm: the linear axes; the two rotary axes in ``machine.rotary``
    order, rad). The tip path tip(s) = machine.tool_pose_np(q0 + s (q1 - q0)), s in [0, 1], is
    sampled at ``substeps`` and ``substeps / 2`` intervals; the polyline lengths are
    Richardson-extrapolated (L = L_n + (L_n - L_n/2) / 3) since a polyline's length error falls
    as 1 / n^2. Blocks whose tip path is straight to 1e-6 relative on two intervals against one
    (short blocks with little rotation, the usual case) are not sampled further.
    """
    q0 = np.atleast_2d(np.asarray(q0, float))
    q1 = np.atleast_2d(np.asarray(q1, float))
    out = _richardson(machine, q0, q1, 2)
    chord = _richardson(machine, q0, q1, 1, richardson=False)
    curved = np.abs(out - chord) > 1e-6 * np.maximum(chord, 1e-12)
    if curved.any():
        out[curved] = _richardson(machine, q0[curved], q1[curved], substeps)
    return out


def _richardson(machine: Any, q0: np.ndarray, q1: np.ndarray, substeps: int, richardson: bool = True) -> np.ndarray:
    s = np.linspace(0.0, 1.0, substeps + 1)
    q = q0[:, None, :] + s[None, :, None] * (q1 - q0)[:, None, :]
    flat = q.reshape(-1, 5)
    tip, _ = machine.tool_pose_np(flat[:, 3], flat[:, 4], flat[:, 0], flat[:, 1], flat[:, 2])
    tip = tip.reshape(len(q0), substeps + 1, 3)
    fine = np.linalg.norm(np.diff(tip, axis=1), axis=2).sum(axis=1)
    if not richardson or substeps < 2:
        return fine
    coarse = np.linalg.norm(np.diff(tip[:, ::2], axis=1), axis=2).sum(axis=1)
    return fine + (fine - coarse) / 3.0


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


def _check_travel(machine: Any, rows: np.ndarray, idx: np.ndarray, A: np.ndarray, B: np.ndarray, xyz: np.ndarray,
                  what: str) -> None:
    """InfeasibleError naming axis, limit, row and point when a commanded value is out of travel
    (A, B: the machine's first and second rotary axis, ``Machine.rotary``)."""
    limits = getattr(machine, "limits", {}) or {}
    names = getattr(machine, "rotary", ("A", "B"))
    for name, values in ((names[0], A), (names[1], B), ("X", xyz[:, 0]), ("Y", xyz[:, 1]), ("Z", xyz[:, 2])):
        lim = limits.get(name)
        if lim is None:
            continue
        bad = (values < lim.min - 1e-9) | (values > lim.max + 1e-9)
        if bad.any():
            i = int(np.argmax(bad))
            rotary = name in names
            conv = math.degrees if rotary else float
            unit = "deg" if rotary else "mm"
            raise InfeasibleError(
                f"G-code {what}: axis {name} = {conv(values[i]):.4f} {unit} outside travel "
                f"[{conv(lim.min):.4f}, {conv(lim.max):.4f}] {unit} at row {int(rows[i])}, point {int(idx[i])}")


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
    axes' speed limits)."""
    F = np.full(len(mv.rapid), np.nan)
    cut = np.flatnonzero(~mv.rapid)
    if mode == "tcp" or len(cut) == 0:
        F[cut] = mv.feed[cut]
        if mv.block_time is not None and len(cut):
            timed = cut[np.isfinite(mv.block_time[cut])]
            chord = np.linalg.norm(mv.tips[timed] - mv.tips[timed - 1], axis=1)
            F[timed] = np.round(60.0 * chord / np.maximum(mv.block_time[timed], 1e-6), 1)
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


def _header(dialect: Dialect, mode: str, machine: Any, cutter: Any, method: str, inputs: dict[str, Any],
            n_points: int, h: float, still: int, tolerance: float | None = None) -> list[str]:
    """The header comments: machine, tool, method, the run's inputs (mm, mm/min, degrees), the post
    tag ``camsmooth post:`` that ``read_gcode`` recognises, and the conventions."""
    c = dialect.comment
    R, r_c = float(cutter.R), float(cutter.r)
    diameter = float(getattr(cutter, "diameter", 2.0 * (R + r_c)))
    shank = getattr(cutter, "shank_length", None)
    shank_txt = "n/a" if shank is None else f"{float(shank):.4f} mm"
    pivot = float(machine.pivot)
    kind = machine.kind
    centre = tuple(float(v) for v in machine.table_centre)
    table = machine.has_table
    centre_txt = f", table centre {centre[0]:.4f} {centre[1]:.4f} {centre[2]:.4f} mm" if table else ""
    head = [
        c(f"generated by camsmooth {__version__} - five-axis tool-axis smoothing"),
        c(f"machine: {machine.name}, kind {kind}, pivot {pivot:.4f} mm{centre_txt}"),
        c(f"tool: {_CUTTER_WORDS.get(getattr(cutter, 'kind', 'bull'), 'toroidal')} R {R:.4f} mm, r {r_c:.4f} mm, "
          f"diameter {diameter:.4f} mm, shank {shank_txt}"),
        c(f"method: {method}; {n_points} points"),
    ]
    if machine.description.preset is None:
        head.insert(2, c(f"chain: {machine.description.summary()}"))
    head.extend(c(f"input {k}: {v}") for k, v in _simple_items(inputs))
    tol = "" if tolerance is None else f" tolerance={float(tolerance):.6g}"
    r1, r2 = machine.rotary
    sign = _sense(dialect, machine)
    sense = "linuxcnc" if (sign != 1.0).any() else "iso"
    where = f" centre={centre[0]:.6f},{centre[1]:.6f},{centre[2]:.6f}" if table else ""
    head.append(c(f"{_POST_TAG} dialect={dialect.name} mode={mode} units=mm pivot={pivot:.6f} method={method}{tol} "
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
    return head


def _sense(dialect: Dialect, machine: Any) -> np.ndarray:
    """(2,) the sign each rotary axis is written with: LinuxCNC's trt sense on its dialect
    (camsmooth.controller.linuxcnc.linuxcnc_sense: a preset's table axis turns the other way), else 1."""
    from camsmooth.controller.linuxcnc import linuxcnc_sense

    return linuxcnc_sense(machine) if dialect.name == "linuxcnc" else np.ones(2)


def _simple_items(inputs: dict[str, Any]) -> Iterable[tuple[str, str]]:
    """The run's inputs as (label, text), mm, mm/min and degrees (camsmooth.smoothing.result.describe_inputs)."""
    yield from describe_inputs(inputs)


def write_gcode(path: str | os.PathLike, result: SmoothResult | MethodResult, machine: Any, cutter: Any,
                feed_mm_min: float | np.ndarray, *, safe_height: float = DEFAULT_SAFE_HEIGHT_MM,
                check_limits: bool = True, dialect: str | None = None, mode: str | None = None,
                program_name: str = "CAMSMOOTH", tolerance: float | None = None, setup: Any = None) -> Path:
    """Write a method's program as five-axis G-code to ``path`` atomically (module docstring).

    result: a SmoothResult (its primary method) or one MethodResult: rows, idx, cl (tool tip,
    mm), axis (unit, tip -> spindle), A, B (rad), xyz (pivot, mm), all workpiece frame.
    feed_mm_min: the programmed tip feed, mm/min, one number or one per point (the feed of the
    move that ends at the point; a row's first value also sets its entry move). dialect, mode:
    override ``machine.post`` (camsmooth.machine.kinematics.PostConfig). safe_height: retract
    along the tool axis between rows (mm). Coordinates are written with 4 decimals (mm, deg).

    With ``check_limits`` every commanded joint value (pivot X Y Z, A, B), the retracts included,
    is checked against ``machine.limits``: InfeasibleError naming the axis, travel, row and point.
    InputError for a feed that is not finite and > 0, non-finite coordinates, an unknown dialect or
    mode, machine mode on Heidenhain, tcp mode on the generic dialect. setup: the tool call,
    spindle, coolant and work offset the input names (camsmooth.post.setup.ShopSetup), written
    after the program start (before the TCP command), M9 M5 before the end; None writes neither.
    """
    post = getattr(machine, "post", None)
    dname = dialect or (post.dialect if post is not None else "generic")
    mode = mode or (post.mode if post is not None else "machine")
    if dname not in DIALECTS:
        raise InputError(f"unknown G-code dialect {dname!r} (known: {', '.join(DIALECTS)})")
    if mode not in ("machine", "tcp"):
        raise InputError(f"unknown G-code mode {mode!r} (known: machine, tcp)")
    d = DIALECTS[dname]
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

    if isinstance(result, SmoothResult):
        r, method, inputs = result.result, result.primary, result.inputs
    else:
        r, method, inputs = result, result.method, {}
    rows = np.asarray(r.rows, dtype=np.int64)
    idx = np.asarray(r.idx, dtype=np.int64)
    xyz = np.asarray(r.xyz, dtype=float).reshape(-1, 3)
    A, B = (np.asarray(v, dtype=float) for v in r.rotary.pair)  # the machine's first, second rotary axis (rad)
    T = np.asarray(r.axis, dtype=float).reshape(-1, 3)
    tip = np.asarray(r.cl, dtype=float).reshape(-1, 3)
    n = len(rows)
    feed_in = np.asarray(feed_mm_min, dtype=float)
    if feed_in.ndim == 0:
        if not (math.isfinite(float(feed_in)) and float(feed_in) > 0):
            raise InputError(f"feed must be a finite number > 0 mm/min, got {float(feed_in)!r}", column="feed")
        feed = np.full(n, float(feed_in))
    else:
        if feed_in.shape != (n,):
            raise InputError(f"feed has {feed_in.size} values for {n} points", column="feed")
        feed = feed_in.astype(float)
        bad = ~(np.isfinite(feed) & (feed > 0))
        if bad.any():
            k = int(np.argmax(bad))
            raise InputError(f"feed must be a finite number > 0 mm/min at row {int(rows[k])}, point {int(idx[k])}, "
                             f"got {float(feed[k])!r}", column="feed")
    ctrl = getattr(r, "controller", None)
    plan = getattr(r, "plan", None)
    t_prog = np.asarray(r.t, float) if getattr(r, "t", None) is not None and len(r.t) == n else None
    f_prog = np.asarray(inputs.get("feed", feed), float).reshape(-1)
    f_prog = f_prog if f_prog.shape == (n,) else feed
    block_time = None
    t_opt = None
    if ctrl is not None:  # the blocks the controller plan timed (camsmooth.controller.blocks)
        sel = np.asarray(ctrl.keep, bool)
        rows, idx, xyz, A, B, T, tip, feed = (v[sel] for v in (rows, idx, xyz, A, B, T, tip, feed))
        t_prog = None if t_prog is None else t_prog[sel]
        f_prog = f_prog[sel]
        block_time = np.asarray(ctrl.block_time, float)[sel]
        if plan is not None and len(plan.t_plan) == len(sel):
            t_opt = np.asarray(plan.t_plan, float)[sel]
    elif plan is not None and len(plan.t_plan) == n:  # every point a block, timed by the planned law
        same = np.r_[False, rows[1:] == rows[:-1]]
        block_time = np.where(same, np.r_[0.0, np.diff(np.asarray(plan.t_plan, float))], np.nan)
        block_time[same & ~(block_time > 0)] = np.nan  # a repeat the plan gives no time: the feed decides
    if tolerance is None:
        metrics = getattr(r, "metrics", None)
        tolerance = getattr(metrics, "tolerance_mm", None)
    finite = (np.isfinite(xyz).all(axis=1) & np.isfinite(A) & np.isfinite(B) & np.isfinite(T).all(axis=1)
              & np.isfinite(tip).all(axis=1))
    if not finite.all():
        i = int(np.argmin(finite))
        raise InputError(f"non-finite axis value at row {int(rows[i])}, point {int(idx[i])}; cannot write G-code")
    # the retract poses: the tip h mm up its tool axis, the angles held (on a head the pivot moves
    # by h T; on a table the linear axes move along the machine's tool axis)
    up = machine.linear_axes(tip + h * T, A, B) if hasattr(machine, "linear_axes") else xyz + h * T
    if check_limits:
        _check_travel(machine, rows, idx, A, B, xyz, "point")
        _check_travel(machine, rows, idx, A, B, up, f"retract ({h:g} mm along the tool axis)")

    joints = np.column_stack([xyz, A, B])
    mv = _moves(rows, joints, tip, T, feed, h, np.column_stack([up, A, B]), block_time, t_prog, f_prog, t_opt)
    # the controller runs the values as written (4 decimals, mm and degrees): time the blocks on those
    mv.joints = written_joints(mv.joints)
    mv.tips = np.round(mv.tips, WRITTEN_DECIMALS)
    F, still = _block_feeds(machine, mv, mode)
    lines = _program_open(d, program_name) + _header(d, mode, machine, cutter, method, inputs, n, h, still,
                                                     tolerance)
    start = _program_start(d, mode, tcp_on, tool_no, tolerance)
    if setup is not None and not setup.empty:  # the input's tool call, spindle, coolant, work offset
        blocks = setup.start_blocks(d.name)
        at = len(d.start) if not d.klartext else 0
        if d.klartext and any(b.startswith("TOOL CALL") for b in blocks):
            start = start[1:]  # the setup's TOOL CALL (with the spindle speed) replaces the writer's
        start = start[:at] + blocks + start[at:]
    lines += start
    deg = np.degrees
    coords = np.column_stack([mv.joints[:, :3] if mode == "machine" else mv.tips,
                              deg(mv.joints[:, 3:]) * _sense(d, machine)])
    lines += _blocks(d, mode, mv, coords, F, "XYZ" + "".join(getattr(machine, "rotary", ("A", "B"))))
    end = _program_end(d, mode, tcp_off, program_name)
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


def _blocks(d: Dialect, mode: str, mv: Any, coords: np.ndarray, F: np.ndarray, letters: str = "XYZAB") -> list[str]:
    """One formatted line per block (numbers formatted as whole columns by polars, not one by
    one), with a comment line at each row's start; ``letters`` the address of each coordinate
    column (X Y Z and the machine's rotary axes). F is modal in G94 and in Klartext: written when
    it changes or after a rapid; in G93 every feed block carries its own."""
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
        out.extend(block[a_:b_])
    return out


def format_blocks(dialect: str, coords: np.ndarray, F: np.ndarray, rapid: np.ndarray, letters: str,
                  inverse_time: bool) -> list[str]:
    """The motion blocks of ``dialect`` (a key of DIALECTS) exactly as ``write_gcode`` formats them,
    one line per block: coords (M, 5) the words of ``letters`` (X Y Z mm, rotary deg, as they are
    to be written), F (M,) the F word (1/min with ``inverse_time``: on every feed block, 7
    significant digits; else mm/min, 1 decimal, written where it changes), rapid (M,) bool. No row
    comments, no annotations (camsmooth.post.rewrite writes blocks into a posted program)."""
    coords = np.asarray(coords, float).reshape(-1, len(letters))
    rapid = np.asarray(rapid, bool)
    mv = _Moves(np.zeros((len(coords), 5)), np.zeros((len(coords), 3)), rapid, np.asarray(F, float))
    return _blocks(DIALECTS[dialect], "machine" if inverse_time else "tcp", mv, coords, F, letters)


def _annotations(d: Dialect, mv: Any, rapid: np.ndarray) -> np.ndarray:
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
    out[k] = np.array([" " + d.comment(x) for x in text], dtype=object) if d.comment is not _paren else \
        " (" + text + ")"
    return out


def _program_open(d: Dialect, name: str) -> list[str]:
    """What must come first: Heidenhain's BEGIN PGM line, Fanuc's tape start and program number."""
    if d.klartext:
        return [f"BEGIN PGM {name} MM"]
    if d.percent:
        return ["%", f"O0001 {_paren(name)}"]
    return []


def _program_start(d: Dialect, mode: str, tcp_on: str | None, tool: int, tolerance: float | None = None) -> list[str]:
    tol: list[str] = []
    if tolerance is not None and d.path_tolerance is not None:
        words = _fixed(np.array([tolerance, PATH_TOLERANCE_SHARE * tolerance]), 4)
        tol = [ln.format(tol=words[0], blend=words[1]) for ln in d.path_tolerance]
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


def _program_end(d: Dialect, mode: str, tcp_off: str | None, name: str) -> list[str]:
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


# ----------------------------------------------------------------------------------------------
# reader
#: the largest magnitude of an axis word (mm, deg) or header pivot the reader takes
MAX_WORD = 1e9
_WORD = re.compile(r"([A-Z])\s*([+-]?(?:\d+\.?\d*|\.\d+))")
#: the per-block annotation the writer adds (``_annotations``)
_ANNOT = re.compile(r"[(;]\s*t=(\d+\.\d+)(?:\s+f=(\d+\.\d+))?(?:\s+o=(\d+\.\d+))?")
_ROW_COMMENT = re.compile(r"[(;]\s*row (-?\d+): (\d+) points")
#: the header's name of each cutter of the toroid family (camsmooth.geometry.cutter.ToroidalCutter.kind)
_CUTTER_WORDS = {"bull": "bull nose", "ball": "ball end", "flat": "flat end"}
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
    """Read a program written by ``write_gcode`` (any dialect, either mode) as a CLProgram.

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
    tag = next((ln for ln in lines[:60] if _POST_TAG in ln), None)
    info = dict(re.findall(r"(\w+)=([\w.,+-]+)", tag.split(_POST_TAG, 1)[1])) if tag else {}
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
        from camsmooth.controller.linuxcnc import linuxcnc_sense

        sense = linuxcnc_sense(machine)
    elif info.get("sense") not in (None, "iso"):
        raise InputError(f"the camsmooth post header gives sense={info['sense']}: not iso or linuxcnc", file=file,
                         line=tag_line)
    mode = info.get("mode")
    tcp_words = {d.tcp_on.split()[0] for d in DIALECTS.values() if d.tcp_on}
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
    times the program commands (G93: 60 / F s; tcp mode: the tip chord / F)."""
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
    t_plan = None
    o = np.asarray(o_ann if o_ann is not None else [], float)
    if len(o) == n and np.all(np.isfinite(o[cut])):
        t_plan = np.where(cut, o, np.nan)
    elif np.all(np.isfinite(dt[cut])):
        total = np.cumsum(dt)
        first = np.flatnonzero(starts)
        t_plan = np.full(n, np.nan)
        t_plan[cut] = total[cut] - total[first][grp[cut] - 1]
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
                      feed=feed if np.isfinite(feed[cut]).all() else None, t_plan=t_plan, row_id=row_id)
    return tool, written
