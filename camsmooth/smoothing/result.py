"""Plain result data passed from the smoothing pipeline to outputs and reports.

All arrays are per CC point, in path order (rows contiguous). Inside the code: mm, s, radians;
the CSV and the report convert angles to degrees.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.machine.axes import PerAxis, RotaryValues


def interferes(delta: np.ndarray, tolerance: float) -> np.ndarray:
    """Where a pose interferes: its signed clearance ``delta`` (mm, negative = gouge) is below
    ``-tolerance`` (mm, the part's allowed deviation, camsmooth.constants.DEFAULT_TOLERANCE_MM by
    default). A NaN clearance (unknown) does not interfere. The one rule for the metrics'
    'interference' count, the result CSV's status and ``--strict``."""
    with np.errstate(invalid="ignore"):
        return np.asarray(delta, dtype=float) < -float(tolerance)


@dataclass(frozen=True)
class JointPeak:
    """A row where the controller's planner (its model, camsmooth.controller) takes a joint past its
    limit: row id, the joint (the machine's axis name) and the larger of its largest |velocity| /
    vmax and |acceleration| / amax over the row's servo cycles (more than 1.01)."""

    row: int
    axis: str
    ratio: float


@dataclass(frozen=True)
class FeedPeak:
    """Where the controller's planner (its model) takes the tool tip past the programmed feed: the
    row id where it goes farthest, the tip's largest speed there over the row's programmed feed
    (more than 1.01), and how many rows go more than 1% past it."""

    row: int
    ratio: float
    rows: int


@dataclass(kw_only=True)
class PointNote:
    """A point the summary names: its name in the input (file and row), row id, index in the
    row, the lift along the normal it got (mm) and, for a blocked point, the best clearance the
    accessibility map found over its lead/tilt window (mm; < 0 = gouge)."""

    point: str
    row: int
    idx: int
    lift_mm: float
    best_clearance_mm: float | None = None


@dataclass(kw_only=True)
class ScallopMiss:
    """A row whose finish budget could not be met (camsmooth.smoothing.pipeline.budget_misses):
    its id, the index of its worst point, the scallop there and the budget (um), and how many of
    its points miss."""

    row: int
    idx: int
    scallop_um: float
    budget_um: float
    points: int


@dataclass(kw_only=True)
class Metrics:
    """Summary of one method's program (camsmooth.smoothing.pipeline.ProgramSmoother.metrics).

    At the programmed feed: gamma = sum |T''|^2 (1/s^4); peak_acc (deg/s^2, PerAxis named by the
    machine's rotary axes: ``peak_acc["C"]``);
    violations_programmed: samples outside each axis's TRUE travel, velocity, acceleration limits
    (all five axes, camsmooth.smoothing.evaluate.axis_violations: on the positions as written,
    beyond what their rounding explains) and the user's windows, and 'interference' (points with
    delta < -tolerance_mm). violations: the same counts with the axes' velocities and
    accelerations under the planned time law (t_plan; the headline; equal to
    violations_programmed until the program is planned); peak_acc_plan (deg/s^2, PerAxis by
    rotary axis; NaN until the program is planned) under it. min_delta (mm). Lifts along the normal (mm) and the rows
    that are not clean; unreachable: (row, idx) without inverse kinematics. Planned time law
    (camsmooth.smoothing.feed): cycle_time_optimal_s, limiting; what the machine's controller
    makes of the program (camsmooth.controller, where camsmooth has a model of it, else the
    time-optimal figures): cycle_time_s, row_cycle_time_s, controller (its name, '' for none),
    blocks (cut blocks written), controller_deviation_mm (the largest distance of the tool tip the
    controller's planner model commands at any servo cycle from the programmed path),
    controller_joint_peaks (the rows where the controller's own planner takes a joint past its
    velocity or acceleration limit at a servo cycle of its model: ``JointPeak``, empty where none),
    controller_feed_peak (where its blends take the tool tip past the programmed feed: ``FeedPeak``,
    None where they do not by more than 1% or the feed is held: ``SmoothOptions.hold_feed``),
    controller_floor_s and row_controller_floor_s (the least time any program of straight blocks
    through the program's points can take on that controller within the tolerance, s, in total
    and per row; None / [] where the controller has no floor), controller_end_offset_mm (how far
    the written block ends' tool tips sit off the points, inside the tolerance, mm; the floor is
    then the one for block ends that far off them); these are the written mode's
    (``[post] mode``). On a table LinuxCNC's trt kinematics describes (camsmooth.controller.tcp),
    both LinuxCNC modes: tcp_cycle_time_s, tcp_floor_s, row_tcp_cycle_time_s, row_tcp_floor_s (TCP
    mode, M428: the prediction with the F words held so that the joints stay within their limits,
    and its floor, s), tcp_within_limits (the held F words keep every linear joint within its
    limits), machine_cycle_time_s and machine_floor_s (machine mode's, s); None / [] elsewhere.
    Row NLP work (nlp
    methods): IPOPT iterations, rounds, points mapped, clearance evaluations, times (s), the
    points lifted because their whole window is blocked or the limits kept them out of their
    clear region. With an error model: the largest tip error (um) with and without compensation
    and the axis error (urad). chord_deviation_mm: the mesh's estimated chord deviation. pole: the
    passages near the pole of the outer rotary axis (camsmooth.smoothing.pole.PolePassage, nlp
    methods; with what each cost in Gamma). scallop_max_um: the largest scallop between adjacent
    passes (um, camsmooth.smoothing.finish; None where unknown); scallop_budget_um: the tightest
    finish budget the method was held to (um; None: none), scallop_missed: the rows that miss it."""

    gamma: float
    peak_acc: PerAxis
    peak_acc_plan: PerAxis
    min_delta: float
    violations: dict[str, int]
    lifted_points: int
    max_lift_mm: float
    lifted_beyond_tolerance: int
    unclean_rows: list[int]
    unreachable: list[tuple[int, int]]
    tolerance_mm: float
    runtime_s: float
    cycle_time_s: float = float("nan")
    cycle_time_optimal_s: float = float("nan")
    row_cycle_time_optimal_s: list[float] = field(default_factory=list)
    violations_programmed: dict[str, int] = field(default_factory=dict)
    controller: str = ""
    blocks: int | None = None
    controller_deviation_mm: float | None = None
    controller_joint_peaks: list[JointPeak] = field(default_factory=list)
    controller_feed_peak: FeedPeak | None = None
    controller_floor_s: float | None = None
    row_controller_floor_s: list[float] = field(default_factory=list)
    controller_end_offset_mm: float = 0.0
    tcp_cycle_time_s: float | None = None
    tcp_floor_s: float | None = None
    row_tcp_cycle_time_s: list[float] = field(default_factory=list)
    row_tcp_floor_s: list[float] = field(default_factory=list)
    tcp_within_limits: bool | None = None
    machine_cycle_time_s: float | None = None
    machine_floor_s: float | None = None
    limiting: str = ""
    row_cycle_time_s: list[float] = field(default_factory=list)
    ipopt_iterations: int = 0
    rounds_max: int = 0
    mapped_points: int | None = None
    clearance_evals: int = 0
    nlp_solve_s: float = 0.0
    map_s: float = 0.0
    check_s: float = 0.0
    blocked: list[PointNote] = field(default_factory=list)
    unreachable_clear: list[PointNote] = field(default_factory=list)
    tip_error_um_max: float | None = None
    tip_error_um_max_uncompensated: float | None = None
    axis_error_urad_max: float | None = None
    compensated: bool | None = None
    chord_deviation_mm: float | None = None
    pole: list[Any] = field(default_factory=list)
    scallop_max_um: float | None = None
    scallop_budget_um: float | None = None
    scallop_missed: list[ScallopMiss] = field(default_factory=list)


@dataclass(kw_only=True)
class MethodResult:
    """The tool program one smoothing method produced.

    method: 'none' | 'spline' | 'nlp'. rows, idx: row id and index within the row. t: time along
    the row (s, 0 at each row's first point, from the programmed feed). cc, normals: CC points
    (mm) and unit normals (material -> tool), workpiece frame. cl: tool tip (mm); axis: unit tool
    axis (tip -> spindle), workpiece frame. lead, tilt: rad (METHODS section 1 local frame).
    rotary: the machine's two rotary axes (N, 2) rad, named by them (``RotaryValues``:
    ``r.rotary["C"]``; machine sign convention, camsmooth.machine.kinematics.Machine);
    rotary_vel (rad/s), rotary_acc (rad/s^2): their rates by finite differences over t
    (camsmooth.smoothing.nlp.program_rates), on the same axes.
    xyz: linear axes (mm). delta: minimum signed clearance tool-to-mesh (mm; < 0 = gouge).
    lift: distance the tool was lifted along the normal as the fallback (mm, 0 where none).
    lead_window, tilt_window: (N, 2) admissible [min, max] per point (rad) after curvature
    (gouge) tightening. compound_acc: |d^2 T / dt^2| per point (1/s^2).
    metrics: the summary (``Metrics``), None for a result built outside the pipeline.
    plan: the planned time law under every axis's limits and the programmed feed
    (camsmooth.smoothing.feed.FeedPlan: t_plan s from each row's start, feed_plan mm/min per point).
    """

    method: str
    rows: np.ndarray
    idx: np.ndarray
    t: np.ndarray
    cc: np.ndarray
    normals: np.ndarray
    cl: np.ndarray
    axis: np.ndarray
    lead: np.ndarray
    tilt: np.ndarray
    rotary: RotaryValues
    rotary_vel: RotaryValues
    rotary_acc: RotaryValues
    xyz: np.ndarray
    delta: np.ndarray
    lift: np.ndarray
    lead_window: np.ndarray
    tilt_window: np.ndarray
    compound_acc: np.ndarray
    metrics: Metrics | None = None
    feed_dirs: np.ndarray | None = None  # (N, 3) unit feed directions X_L used for lead/tilt
    plan: Any = None  # camsmooth.smoothing.feed.FeedPlan: the time-optimal time law of this program
    controller: Any = None  # camsmooth.controller.ControllerPlan: the blocks and the controller's timing
    lead_clear: np.ndarray | None = None  # (N, 2) the accessibility map's lead floor, ceiling (rad; NaN: none)
    scallop: np.ndarray | None = None  # (N,) mm: the scallop toward the neighbouring passes (smoothing.finish)

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class SmoothResult:
    """Everything one `smooth` call produced: a MethodResult per method run, the chosen one
    (``primary``), what went in (machine, cutter, surface source, path source, limits) and
    warnings for the user (e.g. a tolerance below what the mesh can resolve)."""

    methods: dict[str, MethodResult]
    primary: str
    machine: Any
    cutter: Any
    surface_mesh: Any
    inputs: dict[str, Any] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def result(self) -> MethodResult:
        return self.methods[self.primary]

    def table(self) -> np.ndarray:
        """The output CSV table (columns ``output_columns(result.rotary.names)``) of the primary method,
        angles in deg."""
        r = self.result
        deg = np.degrees
        return np.column_stack([r.rows, r.idx, r.t, r.cc, r.normals, r.cl, r.axis, deg(r.lead), deg(r.tilt),
                                deg(r.rotary.values), r.xyz, r.delta])


def _plain(value: Any) -> str:
    """A value as a person reads it: numbers to 4 significant digits, text as is, no Python reprs."""
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        return "\u2014" if not np.isfinite(value) else f"{float(value):.4g}"
    if isinstance(value, (str, os.PathLike)):
        return str(value)
    name = getattr(value, "name", None)
    return str(name) if isinstance(name, str) else type(value).__name__


def describe_inputs(inputs: dict[str, Any]) -> list[tuple[str, str]]:
    """What went into a smoothing run (``SmoothResult.inputs``) as (label, text) rows in mm, mm/min,
    degrees and s, rounded, for the report's Setup table and the G-code header."""
    labels = {"path": "program", "surface": "surface", "feed": "programmed feed", "lead_range": "lead window",
              "tilt_range": "tilt window", "tolerance": "tolerance", "chord_deviation": "mesh chord deviation",
              "model": "error model", "compensate": "compensated", "total_runtime_s": "run time",
              "max_scallop": "finish budget (largest scallop)"}
    units = {"tolerance": " mm", "chord_deviation": " mm", "total_runtime_s": " s", "max_scallop": " mm"}
    rows: list[tuple[str, str]] = []
    for key, value in inputs.items():
        if key == "real_machine" or value is None or (key == "compensate" and inputs.get("model") is None):
            continue
        label = labels.get(key, key.replace("_", " "))
        if key == "feed":
            f = np.asarray(value, float).reshape(-1)
            f = f[np.isfinite(f)]
            if not f.size:
                continue
            lo, hi = float(f.min()), float(f.max())
            text = f"{lo:.4g} mm/min" if np.isclose(lo, hi) else f"{lo:.4g} to {hi:.4g} mm/min"
        elif key in ("lead_range", "tilt_range"):
            lo, hi = np.degrees(np.asarray(value, float).reshape(2))
            text = f"{lo:.4g} to {hi:.4g} deg"
        else:
            text = _plain(value) + units.get(key, "")
        rows.append((label, text))
    return rows
