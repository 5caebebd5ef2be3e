"""A program as it is: what it asks of the machine, per tool path (``camsmooth analyze``).

For each tool path of a program (camsmooth.io.program: APT/CLSF, CL CSV, camsmooth's G-code; a
CC path is analysed with a constant lead and tilt, as a CAM system would program it): points,
tool, programmed feed, the machine's two rotary axes (``Machine.rotary``: A B, A C or B C) by inverse
kinematics (METHODS section 1: nearest branch, row by row; a G-code program's own angles as
commanded) with the branch used, travel / velocity / acceleration violations of all five axes, each
named by its axis and quantity ('Y travel', 'B acceleration': ``named_violations``), at the
programmed feed (the finite differences of camsmooth.smoothing.nlp, times from the tip's path at the
programmed feed) and under the planned time law, Gamma, peak rates, passes near the pole of the
outer rotary axis (where it turns the tool about itself: |B| = 90 deg on the AB head, C's pole on a
table),
clearance against a mesh when one is given, and the cycle time of the time-optimal time law
under every axis's limits (camsmooth.smoothing.feed). Units: mm, s, degrees in the result (it is
written as JSON for the user); radians inside.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from camsmooth.constants import DEFAULT_TOLERANCE_MM
from camsmooth.geometry.clearance import MeshIndex, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames
from camsmooth.geometry.paths import CCPath, estimate_feed_dirs
from camsmooth.io.program import CLProgram, Tool, Written
from camsmooth.machine.kinematics import Machine
from camsmooth.progress import Steps
from camsmooth.smoothing.evaluate import evaluate_program
from camsmooth.smoothing.nlp import program_rates
from camsmooth.smoothing.result import interferes

__all__ = ["SINGULAR_DEG", "ProgramAnalysis", "ToolpathAnalysis", "analyze_program", "limits_json",
           "named_violations"]

SINGULAR_DEG = 5.0  # tool axis within this of the pole (Machine.pole_angle): near the singularity


@dataclass(frozen=True)
class ToolpathAnalysis:
    """One tool path (module docstring). tool: diameter, corner_radius (mm), kind (None when the
    program declares none); feed: the programmed feeds (mm/min) as [min, max]; range_deg: rotary
    axis name -> [min, max] (deg; ``<axis>_range_deg`` in the JSON); range_mm: X, Y, Z -> [min, max]
    of the linear axes (mm, machine coordinates; ``<axis>_range_mm``); branch: which inverse-kinematics
    branch the program runs on (``Machine.branch_of``, in words: ``Machine.branch_words``);
    violations: count of samples over each limit, keyed '<axis> travel|velocity|acceleration' (the
    limit it breaks; ``named_violations`` writes them as '107 Y travel'); gamma (1/s^4); peaks:
    largest |velocity| and
    |acceleration| per axis (deg/s, deg/s^2, mm/s, mm/s^2); singular: points and passes within
    SINGULAR_DEG of the pole (``Machine.pole_angle``: the C axis of a table, |B| = 90 deg on the AB
    head); clearance: min, gouges (below -tolerance), air points (above it)
    or None without a mesh (camsmooth's result CSV: as it was written); violations and peaks under
    the planned time law (the headline, as ``smooth`` counts them; 'interference' when the clearance
    is known), violations_programmed and peaks_programmed at the programmed feed;
    cycle_time_optimal_s: the time-optimal law's (s), cycle_time_s: the controller's where camsmooth
    models it (controller: its name), else the same; limiting: the constraint that binds longest;
    rows: row ids, with row_cycle_time_s and row_cycle_time_optimal_s (s); method: the smoothing
    method of a program camsmooth wrote (else None)."""

    name: str
    tool: dict[str, Any] | None
    points: int
    feed: list[float]
    range_deg: dict[str, list[float]]
    branch: str
    violations: dict[str, int]
    gamma: float
    peaks: dict[str, float]
    singular: dict[str, int]
    clearance: dict[str, float] | None
    cycle_time_s: float
    limiting: str
    violations_programmed: dict[str, int] = field(default_factory=dict)
    peaks_programmed: dict[str, float] = field(default_factory=dict)
    cycle_time_optimal_s: float = float("nan")
    controller: str = ""
    rows: list[int] = field(default_factory=list)
    row_cycle_time_s: list[float] = field(default_factory=list)
    row_cycle_time_optimal_s: list[float] = field(default_factory=list)
    method: str | None = None
    range_mm: dict[str, list[float]] = field(default_factory=dict)


@dataclass(frozen=True)
class ProgramAnalysis:
    """The whole program: its file and format, points (cutting points analysed), warnings, one
    ToolpathAnalysis per tool path, and per point (``series``): 't' program time at the programmed
    feed (s, rows concatenated) and '<rotary axis> angle|velocity|acceleration' (deg, deg/s,
    deg/s^2; the machine's rotary axes, e.g. 'C velocity'); rotary: the machine's two rotary axis
    names; limits: the machine's limit per axis (``limits_json``: mm, deg). ``to_json`` gives the
    pinned JSON: units, points, warnings, rotary, limits, toolpaths with name, tool, points, feed,
    ``<axis>_range_deg`` of each rotary axis (A_range_deg and B_range_deg on the AB head,
    A_range_deg and C_range_deg on an A/C table), ``<axis>_range_mm``, violations, gamma, and the
    other fields."""

    source: str | None
    format: str
    points: int
    toolpaths: list[ToolpathAnalysis]
    warnings: list[str] = field(default_factory=list)
    series: dict[str, np.ndarray] = field(default_factory=dict)  # per point, for plots (not in the JSON)
    rotary: tuple[str, str] = ("A", "B")
    limits: dict[str, dict[str, float | None]] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """The analysis as JSON-ready data (class docstring)."""
        return {"units": "mm", "angles": "deg", "source": self.source, "format": self.format, "points": self.points,
                "warnings": list(self.warnings), "rotary": list(self.rotary), "limits": self.limits,
                "toolpaths": [_toolpath_json(t) for t in self.toolpaths]}


def named_violations(counts: Mapping[str, int]) -> str:
    """The non-zero counts of a violations dict ('<axis> travel|velocity|acceleration',
    'interference', ...) as text naming the limit each breaks: '107 Y travel, 3 B acceleration';
    'none' when there is none."""
    return ", ".join(f"{int(v)} {k}" for k, v in counts.items() if v) or "none"


def limits_json(machine: Machine) -> dict[str, dict[str, float | None]]:
    """Each axis's limits (``machine.joint_names``) as the user wrote them: min, max (mm; deg for a
    rotary axis; None where unbounded, e.g. a continuous C), vmax (mm/s, deg/s), amax (mm/s^2,
    deg/s^2) and unit."""
    out: dict[str, dict[str, float | None]] = {}
    for name in machine.joint_names:
        lim = machine.limits.get(name)
        if lim is None:
            continue
        k = np.degrees(1.0) if name in machine.rotary else 1.0
        out[name] = {key: (float(v * k) if np.isfinite(v) else None)
                     for key, v in (("min", lim.min), ("max", lim.max), ("vmax", lim.vmax), ("amax", lim.amax))}
        out[name]["unit"] = "deg" if name in machine.rotary else "mm"  # type: ignore[assignment]
    return out


def _toolpath_json(tp: ToolpathAnalysis) -> dict[str, Any]:
    """A ToolpathAnalysis as the pinned JSON: its fields, the ranges as ``<axis>_range_deg`` (rotary)
    and ``<axis>_range_mm`` (X, Y, Z)."""
    out: dict[str, Any] = {}
    for k, v in asdict(tp).items():
        if k in ("range_deg", "range_mm"):
            out.update({f"{axis}_{k}": rng for axis, rng in v.items()})
        else:
            out[k] = v
    return out


def _tool_json(tool: Tool | None) -> dict[str, Any] | None:
    if tool is None:
        return None
    return {"diameter": tool.diameter, "corner_radius": tool.corner_radius, "kind": tool.kind, "name": tool.name}


def _times(tip: np.ndarray, feed: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Time (s) from each row's start at the programmed feed (mm/min): |dp| / F per block."""
    seg = np.r_[0.0, np.linalg.norm(np.diff(tip, axis=0), axis=1) / (feed[1:] / 60.0)]
    seg[np.r_[True, rows[1:] != rows[:-1]]] = 0.0
    out = np.cumsum(seg)
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    return out - np.repeat(out[starts], np.diff(np.r_[starts, len(rows)]))


def _ik(machine: Machine, axes: np.ndarray, rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The machine's two rotary angles (rad, ``machine.rotary`` order) for unit tool axes, row by row
    from the previous row's end (``Machine.solve_row``)."""
    q1, q2 = np.empty(len(axes)), np.empty(len(axes))
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    prev = None
    for a, b in zip(starts, np.r_[starts[1:], len(rows)], strict=True):
        r = machine.solve_row(axes[a:b], previous=prev)
        q1[a:b], q2[a:b] = r.rotary.pair  # the row's first and second rotary angle (machine.rotary)
        prev = (r.rotary.first[-1], r.rotary.second[-1])
    return q1, q2


def _toolpath(name: str, tool: Tool | None, machine: Machine, tip: np.ndarray, axes: np.ndarray, feed: np.ndarray,
              rows: np.ndarray, angles: np.ndarray | None, index: MeshIndex | None, cutter: ToroidalCutter | None,
              tolerance: float, written: Written | None = None, own_blocks: bool = False
              ) -> tuple[ToolpathAnalysis, dict[str, np.ndarray]]:
    """One tool path through camsmooth.smoothing.evaluate (the functions smooth reports with).
    written: what camsmooth wrote beside its own program (its programmed-feed time, feed and
    planned time law; the positions are then judged as written, with their rounding allowed
    for); own_blocks: the points are the controller's blocks already (camsmooth's G-code), timed
    by their F words as the controller runs them."""
    q1, q2 = (angles[:, 0], angles[:, 1]) if angles is not None else _ik(machine, axes, rows)
    T = machine.tool_axis_np(q1, q2)
    xyz = machine.linear_axes(tip, q1, q2)
    own = written is not None
    t = written.t if own and written.t is not None else _times(tip, feed, rows)
    f = written.feed if own and written.feed is not None else feed
    q = np.column_stack([xyz, q1, q2])
    ev = evaluate_program(machine, rows, t, q, tip, T, f, tolerance=tolerance, written=own,
                          t_plan=written.t_plan if own else None,
                          keep=np.ones(len(rows), bool) if own_blocks else None,
                          t_blocks=written.t_blocks if own_blocks and own else None)
    law = ev.law
    deg = {k: (np.degrees(1.0) if k.split()[0] in machine.rotary else 1.0) for k in ev.peaks}
    peaks = {k: v * deg[k] for k, v in ev.peaks.items()}
    peaks_p = {k: v * deg[k] for k, v in ev.peaks_programmed.items()}
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    ends = np.r_[starts[1:], len(t)] - 1
    offset = np.repeat(np.r_[0.0, np.cumsum(t[ends])[:-1]], np.diff(np.r_[starts, len(t)]))
    series = {"t": t + offset}
    for name_, qq in zip(machine.rotary, (q1, q2), strict=True):
        rq = program_rates(qq, t, rows)
        series[f"{name_} angle"], series[f"{name_} velocity"] = np.degrees(qq), np.degrees(rq.vel)
        series[f"{name_} acceleration"] = np.degrees(rq.acc)
    near = machine.pole_angle(T) < np.radians(SINGULAR_DEG)
    passes = int(np.sum(np.diff(np.r_[0, near.astype(int)]) == 1))
    clear = None
    viol, viol_p = dict(ev.violations), dict(ev.violations_programmed)
    if index is not None and cutter is not None:
        d = clearance(index, cutter, tip, T).delta
        clear = {"min_mm": float(d.min()), "gouges": int(np.sum(interferes(d, tolerance))),
                 "air": int(np.sum(d > tolerance)), "tolerance_mm": float(tolerance)}
    elif own and written.delta is not None and written.status is not None:  # as smooth wrote them
        d = np.asarray(written.delta, float)
        clear = {"min_mm": float(np.nanmin(d)) if np.isfinite(d).any() else float("nan"),
                 "gouges": int(np.sum(written.status == "interference")), "air": int(np.sum(d > tolerance)),
                 "tolerance_mm": float(tolerance)}
    if clear is not None:
        viol["interference"] = viol_p["interference"] = clear["gouges"]
    second = int(machine.branch_of(q1, q2).sum())
    words = machine.branch_words()
    branch = (f"{words[0]} (the first branch of docs/METHODS.md section 1.4)" if not second
              else f"{words[1]} at {second} points (the second branch)")
    row_ids = (written.row_id[starts] if own and written.row_id is not None else rows[starts]).tolist()
    ctrl = law.controller
    return ToolpathAnalysis(name=name, tool=_tool_json(tool), points=len(tip),
                            feed=[float(f[1:].min(initial=f[0])), float(f[1:].max(initial=f[0]))],
                            range_deg={r: [float(np.degrees(q.min())), float(np.degrees(q.max()))]
                                       for r, q in zip(machine.rotary, (q1, q2), strict=True)}, branch=branch,
                            range_mm={r: [float(xyz[:, k].min()), float(xyz[:, k].max())]
                                      for k, r in enumerate("XYZ")},
                            violations=viol, gamma=ev.gamma, peaks=peaks, singular={"points": int(near.sum()),
                                                                                    "passes": passes},
                            clearance=clear, cycle_time_s=law.cycle_time, limiting=law.limiting,
                            violations_programmed=viol_p, peaks_programmed=peaks_p,
                            cycle_time_optimal_s=law.cycle_time_optimal,
                            controller=ctrl.controller if ctrl is not None else "",
                            rows=[int(r) for r in row_ids], row_cycle_time_s=law.row_cycle_time.tolist(),
                            row_cycle_time_optimal_s=law.row_cycle_time_optimal.tolist(),
                            method=written.method if own else None), series


def analyze_program(program: CLProgram | CCPath, machine: Machine, *, index: MeshIndex | None = None,
                    cutter: ToroidalCutter | None = None, tolerance: float | None = None,
                    feed: float | None = None, lead: float = np.radians(11.0), tilt: float = 0.0,
                    progress: bool = False) -> ProgramAnalysis:
    """The program as it is (module docstring). machine: any kind (its rotary axes name the results);
    index, cutter: the mesh and the tool for the clearance (optional); tolerance (mm); feed (mm/min)
    where the program gives none; lead, tilt (rad, local frame of METHODS section 1): the constant orientation a CC path
    is analysed with. A program camsmooth wrote (its result CSV or G-code, ``CLProgram.written``)
    is evaluated as smooth evaluated it: on its programmed-feed time, with its planned time law and
    its tolerance (``tolerance`` None: the program's own, else DEFAULT_TOLERANCE_MM). progress: a
    line on a terminal naming the tool path being evaluated (camsmooth.progress)."""
    warnings: list[str] = []
    written = getattr(program, "written", None)
    if tolerance is None:
        tolerance = written.tolerance if written is not None and written.tolerance else DEFAULT_TOLERANCE_MM
    if written is not None and written.dialect and written.dialect != machine.post.dialect:
        # the program was written for this controller: its timing is that controller's
        machine = replace(machine, post=replace(machine.post, dialect=written.dialect))
    if isinstance(program, CCPath):
        if cutter is None:
            from camsmooth.errors import InputError

            raise InputError("a CC path needs a cutter to be analysed: give --cutter-radius and --corner-radius",
                             file=program.source)
        fd = program.feed_dirs if program.feed_dirs is not None else estimate_feed_dirs(program.points,
                                                                                        program.normals, program.rows)
        fr = local_frames(program.normals, fd)
        axes = axis_from_lead_tilt(np.full(len(fr), lead), np.full(len(fr), tilt), fr)
        tip = cc_to_cl(cutter, program.points, program.normals, axes)
        f = program.feed if program.feed is not None else np.full(len(tip), float(feed or np.nan))
        _check_feed(f, program.source, None)
        warnings.append(f"a CC path has no tool axes: analysed at a constant lead {np.degrees(lead):g} deg and tilt "
                        f"{np.degrees(tilt):g} deg, as a CAM system would program it")
        with Steps(1, enabled=progress) as steps, steps.step("CC path"):
            tp, series = _toolpath("CC path", None, machine, tip, axes, f, program.rows, None, index, cutter,
                                   tolerance)
        return ProgramAnalysis(program.source, "cc-csv", len(tip), [tp], warnings, series, machine.rotary,
                               limits_json(machine))
    prog = program.cutting()
    axes = prog.require_axis()
    rotary = tuple(program.rotary)  # the file's (CLProgram.cutting does not carry it)
    if prog.angles is not None and rotary != machine.rotary:
        from camsmooth.errors import InputError

        raise InputError(f"the program commands rotary axes {','.join(rotary)} but the machine ({machine.name}) "
                         f"has {','.join(machine.rotary)}: give the machine file it was written for (--machine)",
                         file=program.source)
    f = np.where(np.isfinite(prog.feed), prog.feed, np.nan if feed is None else float(feed))
    f = _fill_starts(f, prog.rows)
    _check_feed(f, program.source, prog.line)
    out, parts = [], []
    steps = Steps(sum(tp.stop - tp.start >= 2 for tp in prog.toolpaths), enabled=progress)
    for k, tp in enumerate(prog.toolpaths):
        s = slice(tp.start, tp.stop)
        if tp.stop - tp.start < 2:
            continue
        tool = tp.tool
        tcut = cutter
        if tcut is None and tool is not None and tool.diameter is not None and tool.corner_radius is not None \
                and tool.ring_radius is not None and tool.ring_radius >= 0 and tool.corner_radius > 0:
            tcut = ToroidalCutter(R=tool.ring_radius, r=tool.corner_radius)
        own = None if prog.written is None else prog.written.take(s)
        name = tp.name or f"tool path {k + 1}"
        with steps.step(f"{name} ({tp.stop - tp.start} points)"):
            a, series = _toolpath(name, tool, machine, prog.tip[s], axes[s], f[s], prog.rows[s],
                                  None if prog.angles is None else prog.angles[s], index, tcut, tolerance,
                                  written=own, own_blocks=own is not None and program.format == "gcode")
        out.append(a)
        if parts:
            series["t"] = series["t"] + parts[-1]["t"][-1]
        parts.append(series)
    steps.close()
    merged = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]} if parts else {}
    return ProgramAnalysis(program.source, program.format, len(prog), out, list(program.warnings) + warnings, merged,
                           machine.rotary, limits_json(machine))


def _fill_starts(f: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Feeds with each row's first value (the rapid that reaches it) set to the row's next one: a
    row's first feed is never used (camsmooth.smoothing.feed.plan_row), only its being finite."""
    f = f.copy()
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    nxt = np.minimum(starts + 1, len(f) - 1)
    f[starts] = np.where(np.isfinite(f[starts]), f[starts], f[nxt])
    return f


def _check_feed(f: np.ndarray, source: str | None, lines: np.ndarray | None) -> None:
    from camsmooth.errors import InputError

    bad = ~(np.isfinite(f) & (f > 0))
    bad[0] = False  # a first point's feed is never used (nor a row's, reached by a rapid: see _fill_starts)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise InputError("no feed for this move (no FEDRAT or feed column before it): give --feed", file=source,
                         line=None if lines is None else int(lines[k]), row=None if lines is not None else k + 1)
