"""The blocks a program is written in, and what a controller makes of them.

Two steps between the planned time law (camsmooth.smoothing.feed, what the axes allow) and the
G-code (camsmooth.io.gcode):

1. ``decimate``: fewer, longer blocks where the axes are smooth. A controller that plans each
   block on its own (LinuxCNC blends five-axis blocks parabolically, camsmooth.controller.linuxcnc)
   reaches only about sqrt(a/2 L) in a block of length L, so a program of 0.5 mm blocks runs at a
   fraction of its feed. A point is dropped when the block that skips it still passes every
   dropped tool tip (and the tip of every dropped block's middle) within ``BLOCK_TOLERANCE_SHARE``
   of the tolerance: the tip is evaluated by the machine's forward kinematics at the joints the
   controller interpolates linearly (X Y Z A B), at the fraction of the block's pivot travel the
   dropped point sits at (an upper bound on the distance to the block's tip curve). The rest of
   the tolerance is left to the controller's blending (``G64 P`` in LinuxCNC).
2. ``ControllerPlan``: the blocks' times as the controller runs them (a planner model, e.g.
   ``LinuxCNCPlanner``), per point: ``t_plan`` and ``feed_plan`` of the controller (points inside
   a block are timed by their share of the block's pivot travel).

Units: mm, s, rad inside; F words in 1/min (G93) as written.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from camsmooth.geometry.paths import _row_runs
from camsmooth.machine.kinematics import Machine

__all__ = ["BLOCK_TOLERANCE_SHARE", "MAX_BLOCK_POINTS", "decimate", "ControllerPlan", "Planner", "predict"]

#: share of the user's tolerance the longer blocks may use (the rest is the controller's blending)
BLOCK_TOLERANCE_SHARE = 0.5
#: most points one block may replace (bounds the vectorised search)
MAX_BLOCK_POINTS = 16
#: intervals of the polyline that stands for a block's tip curve
_CURVE_SAMPLES = 16


def tool_tips(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Tool tips (..., 3) mm of joints q (..., 5) X Y Z mm A B rad (the machine's forward kinematics)."""
    tip, _ = machine.tool_pose_np(q[..., 3], q[..., 4], q[..., 0], q[..., 1], q[..., 2])
    return np.asarray(tip)


def _polyline_distance(pts: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Distance (B, P) of points pts (B, P, 3) to the polylines curve (B, S, 3)."""
    a = curve[:, :-1, :]
    d = curve[:, 1:, :] - a
    dd = np.maximum(np.einsum("bsk,bsk->bs", d, d), 1e-300)
    rel = pts[:, :, None, :] - a[:, None, :, :]
    t = np.clip(np.einsum("bpsk,bsk->bps", rel, d) / dd[:, None, :], 0.0, 1.0)
    close = rel - t[..., None] * d[:, None, :, :]
    return np.sqrt(np.einsum("bpsk,bpsk->bps", close, close).min(axis=2))


def _row_bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) index of every row (geometry.paths' row splitter)."""
    starts, _ = _row_runs(np.asarray(rows))
    return starts, np.r_[starts[1:], len(np.asarray(rows))]


def decimate(machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, tolerance: float) -> np.ndarray:
    """Points that end a block (bool (N,)): every row's first and last point, and greedily the
    farthest point (at most MAX_BLOCK_POINTS on) whose block keeps the skipped tips within
    ``BLOCK_TOLERANCE_SHARE * tolerance`` (module docstring). q: (N, 5) X Y Z mm A B rad; tip:
    (N, 3) the tool tips the program must pass (mm, workpiece frame)."""
    q = np.asarray(q, float)
    tip = np.asarray(tip, float)
    n = len(q)
    keep = np.zeros(n, bool)
    if n == 0:
        return keep
    tol = BLOCK_TOLERANCE_SHARE * float(tolerance)
    starts, ends = _row_bounds(rows)
    last_of_row = np.zeros(n, bool)
    last_of_row[ends - 1] = True
    row_end = np.repeat(ends - 1, ends - starts)
    # ok[a, k-1]: the block a -> a + k keeps its skipped points within tol
    K = MAX_BLOCK_POINTS
    ok = np.zeros((n, K), bool)
    ok[:, 0] = True
    mid = tool_tips(machine, 0.5 * (q[1:] + q[:-1])) if n > 1 else np.zeros((0, 3))
    a_idx = np.arange(n)
    alive = np.ones(n, bool)
    s = np.linspace(0.0, 1.0, _CURVE_SAMPLES + 1)
    for k in range(2, K + 1):
        alive &= a_idx + k <= row_end
        if not alive.any():
            break
        a = a_idx[alive]
        bb = a + k
        # the tip curve of the block (the joints interpolated linearly), as a fine polyline
        curve = tool_tips(machine, q[a][:, None, :] + s[None, :, None] * (q[bb] - q[a])[:, None, :])
        pts = np.concatenate([tip[a[:, None] + np.arange(1, k)[None, :]],
                              mid[a[:, None] + np.arange(0, k)[None, :]]], axis=1)
        good = _polyline_distance(pts, curve).max(axis=1) <= tol
        ok[a, k - 1] = good
        alive[a[~good]] = False  # a longer block from a is not tried once one fails
    reach = ok.sum(axis=1)  # ok is a prefix of True per row of the table
    i = 0
    while i < n:  # one step per block, not per point
        keep[i] = True
        if last_of_row[i]:
            i += 1
            continue
        i = min(i + int(reach[i]), int(row_end[i]))
    keep[ends - 1] = True
    return keep


@dataclass(frozen=True, kw_only=True)
class ControllerPlan:
    """A program's blocks and the controller's timing of them.

    controller: the planner model's name; keep: (N,) bool, the points that end a block (the
    G-code blocks); block_time: (N,) s, at a kept point the time of the block ending there as the
    program commands it (the time-optimal law's; 0 at a row's first point and at dropped points);
    t_plan: (N,) s from the row's first point, when the controller passes each point;
    feed_plan: (N,) mm/min, the controller's tool-tip feed at each point (block average);
    row_ids, row_cycle_time: (R,) s per row; cycle_time: s, the sum over rows (rapids not counted).
    """

    controller: str
    keep: np.ndarray
    block_time: np.ndarray
    t_plan: np.ndarray
    feed_plan: np.ndarray
    row_ids: np.ndarray
    row_cycle_time: np.ndarray
    cycle_time: float

    @property
    def blocks(self) -> int:
        """Number of cut blocks (kept points that are not a row's first)."""
        return int(self.keep.sum() - len(self.row_ids))


class Planner(Protocol):
    """A model of a controller's trajectory planner (camsmooth.controller.linuxcnc.LinuxCNCPlanner)."""

    name: str

    def row_times(self, machine: Machine, q_blocks: np.ndarray, block_time: np.ndarray, entry: np.ndarray,
                  entry_time: float) -> np.ndarray:
        """End time (s from the row's first point) of each block of one row."""
        ...

    def safe_block_times(self, machine: Machine, q_blocks: np.ndarray, block_time: np.ndarray,
                         tolerance: float) -> np.ndarray:
        """Block times (s, at least ``block_time``) that keep the controller's blending within
        ``tolerance`` (mm)."""
        ...


def predict(planner: Planner, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray,
            t_opt: np.ndarray, keep: np.ndarray, *, entry_height: float, entry_feed: np.ndarray,
            blend_tolerance: float | None = None) -> ControllerPlan:
    """The controller's timing of a program written in the blocks ``keep`` with the block times
    of the time-optimal law ``t_opt`` (s from each row's start). q: (N, 5) X Y Z mm A B rad;
    tip: (N, 3) mm. Each row is entered by a feed move of ``entry_height`` mm along the tool axis
    at the row's programmed feed ``entry_feed`` (mm/min, per row), as the G-code writer does.
    blend_tolerance: mm the controller's blends may take the tip off the path; the block times
    are lengthened where its blends would go farther (``Planner.safe_block_times``)."""
    rows = np.asarray(rows)
    n = len(rows)
    starts, ends = _row_bounds(rows)
    block_time = np.zeros(n)
    t_ctrl = np.zeros(n)
    feed = np.zeros(n)
    row_cycle = np.zeros(len(starts))
    for r, (a, b) in enumerate(zip(starts, ends, strict=True)):
        k = a + np.flatnonzero(keep[a:b])
        bt = np.diff(t_opt[k])
        if blend_tolerance is not None and len(k) > 2:
            bt = planner.safe_block_times(machine, q[k], bt, blend_tolerance)
        block_time[k[1:]] = bt
        _, axis = machine.tool_pose_np(q[a, 3], q[a, 4], q[a, 0], q[a, 1], q[a, 2])
        entry_q = q[a].copy()
        entry_q[:3] += entry_height * np.asarray(axis, float).reshape(3)
        entry_time = 60.0 * entry_height / float(entry_feed[r])
        ends_t = planner.row_times(machine, q[k], bt, entry_q, entry_time) if len(k) > 1 else np.zeros(0)
        tk = np.r_[0.0, ends_t]
        # points inside a block: by their share of the block's pivot travel
        s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(q[a:b, :3], axis=0), axis=1))]
        t_ctrl[a:b] = np.interp(s, s[k - a], tk)
        row_cycle[r] = tk[-1]
        chord = np.linalg.norm(np.diff(tip[k], axis=0), axis=1)
        dt = np.diff(tk)
        fb = np.where(dt > 0, 60.0 * chord / np.maximum(dt, 1e-12), 0.0)
        feed[a:b] = np.interp(s, s[k - a][1:], fb) if len(fb) else 0.0
        feed[a] = 0.0
        feed[b - 1] = 0.0
    return ControllerPlan(controller=planner.name, keep=np.asarray(keep, bool), block_time=block_time, t_plan=t_ctrl,
                          feed_plan=feed, row_ids=rows[starts].astype(np.int64), row_cycle_time=row_cycle,
                          cycle_time=float(row_cycle.sum()))
