"""A smoothing result's outputs: the per-point result CSV (its format and reader:
camsmooth.io.result_csv) and the G-code (``write_gcode``, camsmooth.smoothing.posting; the
five-axis writer is camsmooth.post.writer).

Files are written atomically (``camsmooth.io.atomic.atomic_path``): a failed write never leaves a
partial file. Units in files: mm, s, degrees (radians inside the code; CONVENTIONS.md).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from camsmooth.constants import DEFAULT_TOLERANCE_MM
from camsmooth.io.result_csv import INT_COLUMNS, STATUSES, output_columns
from camsmooth.io.table import write_table
from camsmooth.smoothing.posting import write_gcode
from camsmooth.smoothing.result import MethodResult, SmoothResult, interferes

__all__ = ["STATUSES", "point_status", "write_result_csv", "write_gcode"]


# ----------------------------------------------------------------------------------------------
# per-point status
def point_status(result: MethodResult, tolerance: float | None = None) -> np.ndarray:
    """Status string per point of one method (array of str, values in STATUSES).

    'unreachable': (row, idx) is listed in ``metrics.unreachable`` (no inverse-kinematics
    solution within the travel limits); else 'interference': clearance ``delta`` < -``tolerance``
    mm (gouge left after smoothing and any lift; camsmooth.smoothing.result.interferes, the rule
    the metrics count with); else 'lifted': the fallback lift along the normal was applied
    (``lift`` > 0); else 'ok'. A NaN delta is not counted as interference. ``tolerance`` (mm,
    the part's allowed deviation) defaults to the one the method's metrics were computed with
    (``metrics.tolerance_mm``, the user's ``--tolerance``), else DEFAULT_TOLERANCE_MM.
    """
    if tolerance is None:
        tolerance = result.metrics.tolerance_mm if result.metrics is not None else DEFAULT_TOLERANCE_MM
    n = len(result)
    status = np.full(n, "ok", dtype=object)
    lift = np.asarray(result.lift, dtype=float)
    status[np.nan_to_num(lift, nan=0.0) > 0.0] = "lifted"
    status[interferes(result.delta, tolerance)] = "interference"
    unreachable = result.metrics.unreachable if result.metrics is not None else []
    if len(unreachable):
        pairs = np.asarray(unreachable, dtype=np.int64).reshape(-1, 2)
        rows = np.asarray(result.rows, dtype=np.int64)
        idx = np.asarray(result.idx, dtype=np.int64)
        # structured view compares (row, idx) pairs as one key without a Python loop per point
        key_dtype = np.dtype([("r", np.int64), ("i", np.int64)])
        points = np.empty(n, key_dtype)
        points["r"], points["i"] = rows, idx
        listed = np.empty(len(pairs), key_dtype)
        listed["r"], listed["i"] = pairs[:, 0], pairs[:, 1]
        status[np.isin(points, listed)] = "unreachable"
    return status.astype(str)


# ----------------------------------------------------------------------------------------------
# result CSV
def write_result_csv(path: str | os.PathLike, result: SmoothResult) -> Path:
    """Write the primary method's per-point table to ``path`` atomically; return the path.

    Columns: RESULT_CSV_COLUMNS = OUTPUT_COLUMNS (mm, s, degrees; see camsmooth.io.result_csv) then
    ``lift`` (mm, fallback lift along the normal, 0 where none) and ``status`` (see
    ``point_status``), then ``fx,fy,fz`` (unit feed direction, the local frame's X_L) when the
    result carries them, then ``t_plan`` (s from the row's start) and ``feed_plan`` (mm/min,
    tool-tip feed) as the machine's controller runs the program (camsmooth.controller, where
    camsmooth models the controller; else the time-optimal law) and ``t_opt``, ``feed_opt``, the
    time-optimal law (camsmooth.smoothing.feed), when it has a plan. Floats in their shortest
    exact round-trip form; ``row`` and ``idx`` as integers (camsmooth.io.table.write_table).
    """
    r = result.result
    table = result.table()
    names = output_columns(r.rotary.names)  # the rotary columns as the result names them
    if table.shape[1] != len(names):
        raise ValueError(f"SmoothResult.table() has {table.shape[1]} columns, expected {len(names)}")
    columns: dict[str, np.ndarray] = {}
    for k, name in enumerate(names):
        columns[name] = table[:, k].astype(np.int64) if name in INT_COLUMNS else table[:, k]
    columns["lift"] = np.asarray(r.lift, float)
    columns["status"] = point_status(r)
    if r.feed_dirs is not None:  # the local frame's X_L, so predict can re-evaluate lead/tilt exactly
        for k, name in enumerate(("fx", "fy", "fz")):
            columns[name] = r.feed_dirs[:, k]
    if r.plan is not None:  # the controller's timing where camsmooth models it, else the time-optimal law
        ctrl = getattr(r, "controller", None)
        timing = ctrl if ctrl is not None else r.plan
        columns["t_plan"] = timing.t_plan
        columns["feed_plan"] = timing.feed_plan
        columns["t_opt"] = r.plan.t_plan
        columns["feed_opt"] = r.plan.feed_plan
    return write_table(path, columns)
