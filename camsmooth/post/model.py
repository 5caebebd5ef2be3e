"""The one program model the dialect writers take, the dialect registry's entry, and what every
writer shares: the "as written" rounding, the tool-tip path of a block and the travel check.

This module sits below the smoothing and the controller in the import graph: it imports only
numpy, camsmooth.constants and camsmooth.errors; the machine is passed in (its kinematics,
duck-typed: ``tool_pose_np``, ``linear_axes``, ``limits``, ``rotary``).

``PostProgram`` is what a writer needs to write a program, as plain typed data: per point the
joints by the machine's axis names (X Y Z the linear axes in mm, then the two rotary axes in
``rotary`` order, rad), the tool tip (mm) and unit tool axis (tip -> spindle) in the workpiece
frame, the programmed feed (mm/min), the row breaks, the block times a controller plan gives, the
header's texts; the conversion from a smoothing result is camsmooth.smoothing.posting.
Units: mm, mm/min, s; rad inside, degrees in the written words.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM, WRITTEN_DECIMALS
from camsmooth.errors import InfeasibleError

__all__ = ["PostProgram", "PostDialect", "WRITTEN_DECIMALS", "DEFAULT_SAFE_HEIGHT_MM", "written_joints",
           "tip_path_lengths", "check_travel"]

#: Sub-steps per block for the tip path length (Richardson with half as many).
_SUBSTEPS = 16


@dataclass
class PostProgram:
    """A program to write, in the writer's terms (module docstring).

    rows, idx: (N,) row id and index within the row of each point (the row breaks: consecutive
    points of one row id are one row). joints: (N, 5) X Y Z (mm, the machine's linear axes:
    ``Machine.linear_axes``) and the two rotary axes (rad, ``rotary`` order, ISO 841 sense: the
    tool's rotation relative to the workpiece). tips: (N, 3) tool tip mm; axis: (N, 3) unit tool
    axis, both workpiece frame. feed: (N,) the programmed tip feed of the move ending at each
    point, mm/min (a row's first value also sets its entry move). t_prog: (N,) s from the row's
    start at the programmed feed, f_prog: (N,) that feed (mm/min), written beside each block;
    block_time: (N,) s, a controller plan's time of the block ending at each point (nan where the
    feed decides); t_opt: (N,) s from the row's start under the time-optimal law (written beside
    the blocks where the block times are the controller plan's). method, inputs (label, text),
    tool_text (the header's tool line after 'tool: '), n_points (the points of the method, before a
    controller plan kept some of them as blocks: ``read_gcode`` tells a decimated program by it),
    tolerance (mm): the header; blend_tolerance (mm): the controller's blend tolerance a controller
    plan was timed with (LinuxCNC ``G64 P``; None: the writer's default share of the tolerance);
    entry_stop: the plan stops each row's entry move (``ControllerPlan.entry_stop``), which the
    writer writes with the dialect's exact stop; end_offset: mm, how far the joints' tool tips sit
    off the method's points (``ControllerPlan.end_offset``: the plan moved its block ends inside the
    tolerance), said in the header.
    """

    rows: np.ndarray
    idx: np.ndarray
    joints: np.ndarray
    tips: np.ndarray
    axis: np.ndarray
    feed: np.ndarray
    method: str = "unknown"
    inputs: list[tuple[str, str]] = field(default_factory=list)
    tool_text: str = ""
    n_points: int | None = None
    tolerance: float | None = None
    t_prog: np.ndarray | None = None
    f_prog: np.ndarray | None = None
    block_time: np.ndarray | None = None
    t_opt: np.ndarray | None = None
    blend_tolerance: float | None = None
    entry_stop: bool = False
    end_offset: float = 0.0

    def __len__(self) -> int:
        return len(self.rows)


@dataclass(frozen=True)
class PostDialect:
    """One dialect of the registry (camsmooth.post.DIALECTS): its name, its reader, its writer
    (``write``: the one writer with this dialect's words) and whether camsmooth writes whole
    programs in it.

    reader(path, text, machine, dialect, chord_tol) -> CLProgram reads a posted program;
    words: the writer's table (camsmooth.post.writer.Words: program start and end, the
    tool-centre-point and tolerance words, the comment form) whose blocks a rewrite of a posted
    program of this dialect takes; own: ``write_gcode`` writes whole programs in this dialect
    (``[post] dialect`` of a machine file names it); sense(machine) -> (2,) the sign each rotary
    axis is written with (LinuxCNC's trt sense; 1 elsewhere)."""

    name: str
    reader: Callable[..., Any]
    words: Any
    own: bool = True
    sense: Callable[[Any], np.ndarray] | None = None

    def write(self, path: Any, program: PostProgram, machine: Any, **options: Any) -> Any:
        """Write ``program`` as a whole program of this dialect (camsmooth.post.writer.write_program:
        ``mode``, ``safe_height``, ``check_limits``, ``program_name``, ``setup``); InputError for a
        dialect camsmooth writes only blocks of (``own`` False)."""
        from camsmooth.post.writer import write_program

        return write_program(path, program, machine, dialect=self.name, **options)

    def signs(self, machine: Any) -> np.ndarray:
        """(2,) the sign each rotary axis of ``machine`` is written with in this dialect."""
        return np.ones(2) if self.sense is None else np.asarray(self.sense(machine), float)


def written_joints(q: np.ndarray) -> np.ndarray:
    """(N, 5) joints X Y Z (mm) and two rotary axes (rad) rounded as the G-code writer writes them (X Y Z to
    WRITTEN_DECIMALS decimals of a mm, A B of a degree), back in mm and rad."""
    q = np.array(q, dtype=float).reshape(-1, 5)
    q[:, :3] = np.round(q[:, :3], WRITTEN_DECIMALS)
    q[:, 3:] = np.radians(np.round(np.degrees(q[:, 3:]), WRITTEN_DECIMALS))
    return q


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


def check_travel(machine: Any, rows: np.ndarray, idx: np.ndarray, A: np.ndarray, B: np.ndarray, xyz: np.ndarray,
                 what: str) -> None:
    """InfeasibleError naming axis, limit, row and point when a commanded value is out of travel
    (A, B: the machine's first and second rotary axis, ``Machine.rotary``, rad; xyz mm)."""
    import math

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
