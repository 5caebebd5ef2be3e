"""Plain result data passed from the smoothing pipeline to outputs and reports.

All arrays are per CC point, in path order (rows contiguous). Inside the code: mm, s, radians;
the CSV and the report convert angles to degrees.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

OUTPUT_COLUMNS = ("row", "idx", "t", "x", "y", "z", "nx", "ny", "nz", "clx", "cly", "clz", "i", "j", "k",
                  "lead", "tilt", "A", "B", "X", "Y", "Z", "delta")


@dataclass(kw_only=True)
class MethodResult:
    """The tool program one smoothing method produced.

    method: 'none' | 'spline' | 'nlp'. rows, idx: row id and index within the row. t: time along
    the row (s, 0 at each row's first point, from the programmed feed). cc, normals: CC points
    (mm) and unit normals (material -> tool), workpiece frame. cl: tool tip (mm); axis: unit tool
    axis (tip -> spindle), workpiece frame. lead, tilt: rad (METHODS section 1 local frame).
    A, B: rad; A_vel, B_vel (rad/s), A_acc, B_acc (rad/s^2) by finite differences over t.
    xyz: linear axes (mm). delta: minimum signed clearance tool-to-mesh (mm; < 0 = gouge).
    lift: distance the tool was lifted along the normal as the fallback (mm, 0 where none).
    lead_window, tilt_window: (N, 2) admissible [min, max] per point (rad) after curvature
    (gouge) tightening. compound_acc: |d^2 T / dt^2| per point (1/s^2).
    metrics: summary (camsmooth.smoothing.pipeline): gamma (1/s^4), peak_A_acc, peak_B_acc (deg/s^2),
    min_delta, violations (dict name -> count), runtime_s, unclean_rows, unreachable, cycle_time_s
    (the planned time law's) and limiting (the constraint that binds longest).
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
    A: np.ndarray
    B: np.ndarray
    A_vel: np.ndarray
    B_vel: np.ndarray
    A_acc: np.ndarray
    B_acc: np.ndarray
    xyz: np.ndarray
    delta: np.ndarray
    lift: np.ndarray
    lead_window: np.ndarray
    tilt_window: np.ndarray
    compound_acc: np.ndarray
    metrics: dict[str, Any] = field(default_factory=dict)
    feed_dirs: np.ndarray | None = None  # (N, 3) unit feed directions X_L used for lead/tilt
    plan: Any = None  # camsmooth.smoothing.feed.FeedPlan: the time-optimal time law of this program
    lead_clear: np.ndarray | None = None  # (N, 2) the accessibility map's lead floor, ceiling (rad; NaN: none)

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
        """The output CSV table (columns OUTPUT_COLUMNS) of the primary method, angles in deg."""
        r = self.result
        deg = np.degrees
        return np.column_stack([r.rows, r.idx, r.t, r.cc, r.normals, r.cl, r.axis, deg(r.lead), deg(r.tilt),
                                deg(r.A), deg(r.B), r.xyz, r.delta])
