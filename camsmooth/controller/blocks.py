"""The blocks a program is written in, and what a controller makes of them.

Two steps between the planned time law (camsmooth.smoothing.feed, what the axes allow) and the
G-code (camsmooth.post.writer):

1. ``place``: fewer, longer blocks where the axes are smooth. A controller that plans each
   block on its own (LinuxCNC blends five-axis blocks parabolically, camsmooth.controller.linuxcnc)
   reaches only about sqrt(a/2 L) in a block of length L, so a program of 0.5 mm blocks runs at a
   fraction of its feed. A point may be dropped when the block that skips it still passes every
   dropped tool tip (and the tip of every dropped block's middle) within ``BLOCK_TOLERANCE_SHARE``
   of the tolerance: the tip is evaluated by the machine's forward kinematics at the joints the
   controller interpolates linearly (X Y Z A B), at the fraction of the block's pivot travel the
   dropped point sits at (an upper bound on the distance to the block's tip curve). Among those
   blocks, ``decimate`` takes the longest from each end; ``place`` the ends the planner model runs
   soonest (``Planner.block_ends``; on LinuxCNC a shorter block after a longer one waits for it).
   The blocks may end off the points (``vertex_shift``): each point that ends a block is written
   with its tool tip moved to the outside of the path's curve by up to VERTEX_SHIFT_SHARE of the
   tolerance, so a chord's deviation is split between its middle and its ends.
2. ``predict``: the blocks' times as the controller runs them (a planner model, e.g.
   ``LinuxCNCPlanner``), made slow enough where the controller's blends would take the tool tip
   the model commands at some servo cycle farther than EXECUTED_TOLERANCE_SHARE of the tolerance
   from the programmed path (``programmed_tip_path``), and per point the ``ControllerPlan``:
   ``t_plan`` and ``feed_plan`` of the controller (points inside a block are timed by their share
   of the block's pivot travel) and each row's largest tip deviation.

Units: mm, s, rad inside; F words in 1/min (G93) as written.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numba import njit

from camsmooth.constants import WRITTEN_DECIMALS
from camsmooth.geometry.paths import _row_runs
from camsmooth.machine.kinematics import Machine, axis_limits

__all__ = ["BLOCK_TOLERANCE_SHARE", "MAX_BLOCK_POINTS", "VERTEX_SHIFT_SHARE", "vertex_shift", "block_reach",
           "rotary_turns", "tip_speed_over", "block_peaks", "decimate", "place", "row_entry", "ControllerPlan",
           "Planner", "predict", "plan_blocks", "joint_ratio"]

#: share of the user's tolerance the longer blocks may use: their tip curves keep every dropped tip
#: this close; the blends then get what is left up to EXECUTED_TOLERANCE_SHARE, checked on the
#: planner model's servo cycles (``predict``): a blend's deviation sits at a block's end, where its
#: own tip curve meets the path. Measured on the planner model over the blade, wave, ridge, dome and
#: teapot rows of benchmarks/bench_controller.py (G64 P at twice the tolerance), executed / floor
#: per surface: 0.96 with an executed share of 0.98 runs them in 1.091 / 1.081 / 1.085 / 1.022 /
#: 1.099, against 1.098 / 1.088 / 1.087 / 1.027 / 1.126 at 0.93 with 0.95 and 1.094 / 1.084 / 1.080 /
#: 1.066 / 1.064 at 0.99 with 0.99 (the dome's blends left no room); 0.93 with 0.95 ran them 0.4-1.4%
#: sooner than 0.88 with 0.9, and 1.4-5% sooner than 0.78 with 0.8.
BLOCK_TOLERANCE_SHARE = 0.96
#: most points one block may replace (bounds the vectorised search)
MAX_BLOCK_POINTS = 16
#: share of the user's tolerance a block end may be moved off its point (``vertex_shift``): the
#: tip path's chords then sit across the path instead of on one side of it, and a block may span
#: a sagitta of up to (1 + this) x its share instead of 1 x. On the planner model over four nlp
#: rows each of the blade, wave, ridge, dome and teapot of benchmarks/bench_controller.py (G64 P
#: at 12 T), predicted / floor through the points per row: 0.98-1.02 / 0.96-1.00 / 0.97-1.00 /
#: 0.98-0.99 / 0.77-0.94 at 0.5, against 1.06-1.07 / 1.05-1.07 / 1.05-1.06 / 1.02-1.03 / 1.05-1.24
#: with the ends on the points. 0.7 ran a first version 1-4% sooner still, but puts the ends 3.5
#: of 5 um off the points, where the path curves towards the part that is into it; at 0.5 the
#: chord is centred in the band.
VERTEX_SHIFT_SHARE = 0.5
#: points on each side of a point whose block's tip curve says which side of the path is outside
_SHIFT_SPAN = 4
#: points per batch of ``vertex_shift``
_SHIFT_CHUNK = 20_000
#: intervals of the polyline that stands for a block's tip curve
_CURVE_SAMPLES = 16
#: point-segment pairs per batch of ``tip_deviation``
_DEVIATION_BATCH = 2_000_000


def tool_tips(machine: Machine, q: np.ndarray) -> np.ndarray:
    """Tool tips (..., 3) mm of joints q (..., 5) X Y Z mm A B rad (the machine's forward kinematics)."""
    tip, _ = machine.tool_pose_np(q[..., 3], q[..., 4], q[..., 0], q[..., 1], q[..., 2])
    return np.asarray(tip)


#: floats in one intermediate (block, point, segment, xyz) array of ``_polyline_distance``: blocks,
#: and one block's points, are taken in chunks so that long blocks and long servo runs (near a
#: pole, a table turning far in one block) do not need gigabytes (`camsmooth analyze
#: surfaces/dome.cls --machine surfaces/dome_machine.toml`: peak RSS 2.0 GB without, 0.35 GB with)
_DISTANCE_CHUNK = 1 << 22


def _polyline_distance(pts: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Distance (B, P) of points pts (B, P, 3) to the polylines curve (B, S, 3)."""
    per_point = max(curve.shape[1] - 1, 1) * 3
    if pts.shape[1] * per_point > _DISTANCE_CHUNK and pts.shape[1] > 1:  # one block's points in chunks
        step = max(1, _DISTANCE_CHUNK // per_point)
        return np.concatenate([_polyline_distance(pts[:, i:i + step], curve)
                               for i in range(0, pts.shape[1], step)], axis=1)
    step = max(1, _DISTANCE_CHUNK // max(pts.shape[1] * per_point, 1))
    if len(pts) > step:
        return np.concatenate([_polyline_distance(pts[i:i + step], curve[i:i + step])
                               for i in range(0, len(pts), step)])
    a = curve[:, :-1, :]
    d = curve[:, 1:, :] - a
    dd = np.maximum(np.einsum("bsk,bsk->bs", d, d), 1e-300)
    rel = pts[:, :, None, :] - a[:, None, :, :]
    t = np.clip(np.einsum("bpsk,bsk->bps", rel, d) / dd[:, None, :], 0.0, 1.0)
    close = rel - t[..., None] * d[:, None, :, :]
    return np.sqrt(np.einsum("bpsk,bpsk->bps", close, close).min(axis=2))


@njit(cache=True)
def _all_within(pts: np.ndarray, curve: np.ndarray, frac: np.ndarray,
                tolerance: float) -> np.ndarray:  # pragma: no cover - compiled
    """(B,) bool: every point pts[b] (B, P, 3) within ``tolerance`` of the polyline curve[b] (B, S, 3),
    as ``_polyline_distance(pts, curve).max(axis=1) <= tolerance``, but each point stops at the
    first segment within reach, searched outward from the segment at its fraction frac (P,) of the
    polyline, and a block stops at its first point out of reach."""
    nb, npts, ns = pts.shape[0], pts.shape[1], curve.shape[1] - 1
    tol2 = tolerance * tolerance
    out = np.ones(nb, np.bool_)
    for b in range(nb):
        for p in range(npts):
            s0 = min(max(int(frac[p] * ns), 0), ns - 1)
            found = False
            for step in range(2 * ns):
                s = s0 + (step + 1) // 2 if step % 2 else s0 - step // 2
                if s < 0 or s >= ns:
                    continue
                d0 = curve[b, s + 1, 0] - curve[b, s, 0]
                d1 = curve[b, s + 1, 1] - curve[b, s, 1]
                d2 = curve[b, s + 1, 2] - curve[b, s, 2]
                r0 = pts[b, p, 0] - curve[b, s, 0]
                r1 = pts[b, p, 1] - curve[b, s, 1]
                r2 = pts[b, p, 2] - curve[b, s, 2]
                dd = max(d0 * d0 + d1 * d1 + d2 * d2, 1e-300)
                t = min(max((r0 * d0 + r1 * d1 + r2 * d2) / dd, 0.0), 1.0)
                e0, e1, e2 = r0 - t * d0, r1 - t * d1, r2 - t * d2
                if e0 * e0 + e1 * e1 + e2 * e2 <= tol2:
                    found = True
                    break
            if not found:
                out[b] = False
                break
    return out


def _row_bounds(rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (exclusive) index of every row (geometry.paths' row splitter)."""
    starts, _ = _row_runs(np.asarray(rows))
    return starts, np.r_[starts[1:], len(np.asarray(rows))]


def _tip_polyline(machine: Machine, q: np.ndarray, entry: np.ndarray | None, sub: int,
                  max_turn: float) -> tuple[np.ndarray, np.ndarray]:
    """``programmed_tip_path`` and, per point of q, the index of its vertex in it."""
    q = np.asarray(q, float)
    dq = np.diff(q, axis=0)
    steps = np.maximum(int(sub), np.ceil(np.abs(dq[:, 3:]).max(axis=1, initial=0.0) / max_turn)).astype(np.int64)
    owner = np.repeat(np.arange(len(dq)), steps)
    frac = (np.arange(len(owner)) - np.repeat(np.cumsum(steps) - steps, steps)) / steps[owner]
    tip = tool_tips(machine, np.vstack([q[owner] + frac[:, None] * dq[owner], q[-1:]]))
    at = np.r_[0, np.cumsum(steps)]
    if entry is None:
        return tip, at
    return np.vstack([np.asarray(entry, float)[None, :], tip]), at + 1


def programmed_tip_path(machine: Machine, q: np.ndarray, entry: np.ndarray | None = None, sub: int = 16,
                        max_turn: float = np.radians(0.25)) -> np.ndarray:
    """The tool-tip path a row commands, as a polyline (mm, workpiece frame): the forward
    kinematics of each block's joints interpolated linearly (q: (N, 5) X Y Z mm and the rotary
    axes of ``machine.rotary`` rad, the full-density program) at ``sub`` steps, and more where a
    step would turn a rotary axis by more than ``max_turn`` (rad; a table turning 16 deg in one
    block swings the tip along an arc), after the tip ``entry`` where the row's entry feed move
    starts (the controller blends that move into the row)."""
    return _tip_polyline(machine, q, entry, sub, max_turn)[0]


def tip_deviation(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """Distance (mm) of each point (M, 3) to the polyline ``path`` (K, 3), against every segment
    (in batches of bounded memory)."""
    points = np.atleast_2d(np.asarray(points, float))
    path = np.asarray(path, float)
    if len(path) < 2:
        return np.linalg.norm(points - path[:1], axis=1)
    step = max(1, _DEVIATION_BATCH // (len(path) - 1))
    return np.concatenate([_polyline_distance(points[None, c:c + step], path[None])[0]
                           for c in range(0, len(points), step)])


def _run_deviation(run: RowRun, tips: np.ndarray, path: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distance (mm) of the tool tip at every servo cycle of a row run to the programmed path
    ``path``: the samples while segment h executes are measured against the path from segment
    h's start to the end of the segment after it (the one it blends into). ends: (M,) the path
    vertex where each segment ends (segment 0 the entry move, which starts at vertex 0)."""
    ends = np.asarray(ends, np.int64)
    m = len(ends)
    h = np.asarray(run.head, np.int64)
    lo = np.where(h == 0, 0, ends[np.clip(h - 1, 0, m - 1)])
    hi = ends[np.minimum(h + 1, m - 1)]
    return _window_distance(np.asarray(tips, float), np.asarray(path, float), np.maximum(lo - 1, 0),
                            np.minimum(hi + 2, len(path)))


@njit(cache=True)
def _window_distance(pts: np.ndarray, path: np.ndarray, first: np.ndarray,
                     stop: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """Distance (K,) of each point pts[i] (K, 3) to the polyline of the vertices path[first[i]:
    stop[i]] (a single vertex: the distance to it); one pass over each point's own window, where
    a run has thousands of segments and a quarter of a million servo cycles."""
    out = np.empty(len(pts))
    for i in range(len(pts)):
        a, b = first[i], stop[i]
        best = np.inf
        for s in range(a, max(b - 1, a + 1)):
            r0 = pts[i, 0] - path[s, 0]
            r1 = pts[i, 1] - path[s, 1]
            r2 = pts[i, 2] - path[s, 2]
            t = 0.0
            if s + 1 < b:
                d0 = path[s + 1, 0] - path[s, 0]
                d1 = path[s + 1, 1] - path[s, 1]
                d2 = path[s + 1, 2] - path[s, 2]
                dd = d0 * d0 + d1 * d1 + d2 * d2
                if dd > 0.0:
                    t = min(max((r0 * d0 + r1 * d1 + r2 * d2) / dd, 0.0), 1.0)
                r0 -= t * d0
                r1 -= t * d1
                r2 -= t * d2
            e = r0 * r0 + r1 * r1 + r2 * r2
            if e < best:
                best = e
        out[i] = np.sqrt(best)
    return out


def _chord_deviation(machine: Machine, q: np.ndarray, k: np.ndarray, path: np.ndarray,
                     at: np.ndarray) -> np.ndarray:
    """Per block of k (indices into q), the largest distance (mm) of its tip curve (the joints
    interpolated linearly, _CURVE_SAMPLES steps) from ``path``, against the path between its ends
    (at: the path vertex of each point of q): what the block costs before any blending."""
    s = np.linspace(0.0, 1.0, _CURVE_SAMPLES + 1)
    qa, qb = q[k[:-1]], q[k[1:]]
    curve = tool_tips(machine, qa[:, None, :] + s[None, :, None] * (qb - qa)[:, None, :])
    out = np.empty(len(qa))
    for j in range(len(qa)):
        seg = path[at[k[j]]:at[k[j + 1]] + 1]
        out[j] = _polyline_distance(curve[None, j], seg[None])[0].max()
    return out


def _nearest_on(pts: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """The point (B, 3) of each polyline curve[b] (B, S, 3) nearest to pts[b] (B, 3)."""
    a = curve[:, :-1, :]
    d = curve[:, 1:, :] - a
    t = np.clip(np.einsum("bsk,bsk->bs", pts[:, None, :] - a, d) / np.maximum(np.einsum("bsk,bsk->bs", d, d), 1e-300),
                0.0, 1.0)
    close = a + t[..., None] * d
    best = np.argmin(np.einsum("bsk,bsk->bs", close - pts[:, None, :], close - pts[:, None, :]), axis=1)
    return close[np.arange(len(pts)), best]


def vertex_shift(machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, tolerance: float,
                 share: float = VERTEX_SHIFT_SHARE, *, world: bool = False) -> np.ndarray:
    """Where each point would be written if it ends a block: (N, 5) the shift of its coordinates
    that moves its tool tip off the path, to the outside of the tip path of the block from
    _SHIFT_SPAN points before it to as many after (fewer near a row's ends), by half that block's
    sagitta and at most ``share`` x ``tolerance`` (mm); the rotary axes and each row's first and
    last points do not move. A chord of a curved path lies on its inside; with its ends moved out
    by half its sagitta its deviation is shared between the middle and the ends, as a CAM system's
    inner and outer tolerances share a band, so a block may span a longer stretch of path within
    the same band. The tool axes are not moved.

    Machine mode (``world`` False): a block's tip path is the forward kinematics of its joints
    interpolated linearly, and the shift is the joints' X Y Z (mm), the tip's move through the
    linear axes' Jacobian (exact: they translate the tip, by a rotation in the workpiece frame on a
    table). TCP mode (``world`` True): the tip path is the chord between the tips, and the shift is
    the tip's (mm, workpiece frame). q (N, 5) X Y Z mm A B rad; tip (N, 3) mm, workpiece frame."""
    q = np.asarray(q, float)
    tip = np.asarray(tip, float)
    n = len(q)
    out = np.zeros((n, 5))
    if n < 3 or share <= 0:
        return out
    starts, ends = _row_bounds(rows)
    j = np.arange(n)
    first, last = np.repeat(starts, ends - starts), np.repeat(ends - 1, ends - starts)
    h = np.minimum(_SHIFT_SPAN, np.minimum(j - first, last - j))
    j, h = j[h > 0], h[h > 0]
    s = np.linspace(0.0, 1.0, 2 * _CURVE_SAMPLES + 1)
    for c in range(0, len(j), _SHIFT_CHUNK):  # bounded memory on programs of a million points
        jc, hc = j[c:c + _SHIFT_CHUNK], h[c:c + _SHIFT_CHUNK]
        if world:
            curve = np.stack([tip[jc - hc], tip[jc + hc]], axis=1)
        else:
            qa, qb = q[jc - hc], q[jc + hc]
            curve = tool_tips(machine, qa[:, None, :] + s[None, :, None] * (qb - qa)[:, None, :])
        out_dir = tip[jc] - _nearest_on(tip[jc], curve)
        sag = np.linalg.norm(out_dir, axis=1)
        move = np.where(sag > 0, np.minimum(share * float(tolerance), 0.5 * sag) / np.maximum(sag, 1e-300), 0.0)
        step = move[:, None] * out_dir
        if world:
            out[jc, :3] = step
            continue
        base = tool_tips(machine, q[jc])
        jac = np.stack([tool_tips(machine, q[jc] + np.eye(5)[i]) - base for i in range(3)], axis=2)  # tip per mm
        out[jc, :3] = np.linalg.solve(jac, step[..., None])[..., 0]
    return out


def block_reach(machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, tolerance: float,
                max_points: int = MAX_BLOCK_POINTS, *, shift: np.ndarray | None = None) -> np.ndarray:
    """Which blocks keep the tips they skip within ``tolerance`` (mm): (N, max_points) bool, entry
    [a, k - 1] for the block from point a to point a + k inside a's row (always True for k = 1).

    A block passes when every skipped tip and the tip of every skipped block's middle lies within
    ``tolerance`` of the block's tip curve: the machine's forward kinematics of the joints
    interpolated linearly (what the controller does), as a polyline of _CURVE_SAMPLES steps. Once
    a block from a fails, the longer ones from a are not tried (they are marked False). q: (N, 5)
    X Y Z mm A B rad; tip: (N, 3) mm, workpiece frame; shift (N, 5): the blocks run between the
    joints q + shift (``vertex_shift``; None: q), the tips they must pass stay q's."""
    q = np.asarray(q, float)
    tip = np.asarray(tip, float)
    mid = tool_tips(machine, 0.5 * (q[1:] + q[:-1])) if len(q) > 1 else np.zeros((0, 3))
    s = np.linspace(0.0, 1.0, _CURVE_SAMPLES + 1)
    qc = q if shift is None else q + np.asarray(shift, float)

    def passes(a: np.ndarray, k: int) -> np.ndarray:
        curve = tool_tips(machine, qc[a][:, None, :] + s[None, :, None] * (qc[a + k] - qc[a])[:, None, :])
        pts = np.concatenate([tip[a[:, None] + np.arange(1, k)[None, :]],
                              mid[a[:, None] + np.arange(0, k)[None, :]]], axis=1)
        frac = np.r_[np.arange(1, k) / k, (np.arange(k) + 0.5) / k]
        return _all_within(pts, curve, frac, tolerance)

    return reach_table(rows, len(q), max_points, passes)


def rotary_turns(q: np.ndarray, max_points: int = MAX_BLOCK_POINTS) -> np.ndarray:
    """(N, max_points) bool in ``block_reach``'s layout: whether the block from point a to a + k
    turns a rotary axis as written (WRITTEN_DECIMALS decimals of a degree; False past the last
    point). LinuxCNC joins such blocks by parabolic blends only; a block that turns none may be
    joined by a blend arc as far off as ``G64 P``, so where P exceeds the tolerance ``place``
    keeps only blocks that turn one (and none longer from a point than the first that does not).
    q (N, 5) X Y Z mm, rotary rad."""
    deg = np.round(np.degrees(np.asarray(q, float)[:, 3:]), WRITTEN_DECIMALS)
    out = np.zeros((len(deg), int(max_points)), bool)
    for k in range(1, min(int(max_points), len(deg) - 1) + 1):
        out[:-k, k - 1] = np.any(deg[k:] != deg[:-k], axis=1)
    return out


def reach_table(rows: np.ndarray, n: int, max_points: int,
                passes: Callable[[np.ndarray, int], np.ndarray]) -> np.ndarray:
    """(n, max_points) bool: entry [a, k - 1] says whether the block from point a over k points
    (inside a's row) passes ``passes(a, k)`` (a: the start points still in the running, k >= 2;
    returns a bool per start); always True for k = 1. Once a block from a fails, the longer ones
    from a are not tried (marked False). The one search of ``block_reach`` (machine mode's tip
    curve) and camsmooth.controller.tcp.chord_reach (the chord)."""
    K = int(max_points)
    ok = np.zeros((n, K), bool)
    if n == 0:
        return ok
    ok[:, 0] = True
    starts, ends = _row_bounds(rows)
    row_end = np.repeat(ends - 1, ends - starts)
    a_idx = np.arange(n)
    alive = np.ones(n, bool)
    for k in range(2, K + 1):
        alive &= a_idx + k <= row_end
        if not alive.any():
            break
        a = a_idx[alive]
        good = passes(a, k)
        ok[a, k - 1] = good
        alive[a[~good]] = False  # a longer block from a is not tried once one fails
    return ok


def decimate(machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, tolerance: float, *,
             ok: np.ndarray | None = None) -> np.ndarray:
    """Points that end a block (bool (N,)): every row's first and last point, and greedily the
    farthest point (at most MAX_BLOCK_POINTS on) whose block keeps the skipped tips within
    ``BLOCK_TOLERANCE_SHARE * tolerance`` (``block_reach``; module docstring). q: (N, 5) X Y Z mm
    A B rad; tip: (N, 3) the tool tips the program must pass (mm, workpiece frame); ok: that
    ``block_reach`` when already computed."""
    n = len(np.asarray(q))
    keep = np.zeros(n, bool)
    if n == 0:
        return keep
    starts, ends = _row_bounds(rows)
    last_of_row = np.zeros(n, bool)
    last_of_row[ends - 1] = True
    row_end = np.repeat(ends - 1, ends - starts)
    if ok is None:
        ok = block_reach(machine, rows, q, tip, BLOCK_TOLERANCE_SHARE * float(tolerance))
    reach = np.asarray(ok).sum(axis=1)
    i = 0
    while i < n:  # one step per block, not per point
        keep[i] = True
        if last_of_row[i]:
            i += 1
            continue
        i = min(i + int(reach[i]), int(row_end[i]))
    keep[ends - 1] = True
    return keep


def row_entry(machine: Machine, q: np.ndarray, entry_height: float, entry_feed: float) -> tuple[np.ndarray, float]:
    """Where a row's entry feed move starts and how long it takes, as the G-code writer writes it:
    the tool tip ``entry_height`` mm up the tool axis from the row's first point q (5,) (X Y Z mm,
    rotary rad; workpiece frame), the angles held (``Machine.linear_axes``: on a head the pivot
    moves by the same, on a table the linear axes by the table's rotation of it), at
    ``entry_feed`` mm/min. Returns the joints (5,) and the time (s)."""
    q = np.asarray(q, float)
    tip, axis = machine.tool_pose_np(q[3], q[4], q[0], q[1], q[2])
    up = (np.asarray(tip, float) + entry_height * np.asarray(axis, float)).reshape(1, 3)
    entry_q = q.copy()
    entry_q[:3] = np.asarray(machine.linear_axes(up, q[3:4], q[4:5]), float).reshape(3)
    return entry_q, 60.0 * entry_height / float(entry_feed)


def place(planner: Planner, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray, t_opt: np.ndarray,
          tolerance: float, *, entry_height: float, entry_feed: np.ndarray, real: Machine | None = None,
          hold_feed: np.ndarray | None = None, shift: np.ndarray | None = None) -> np.ndarray:
    """Points that end a block (bool (N,)), chosen against the planner model's executed time: among
    the blocks that keep the skipped tips within ``BLOCK_TOLERANCE_SHARE * tolerance`` (mm) on
    ``real`` (the machine the tips are on, default ``machine``; ``block_reach``), the block ends the
    planner runs soonest (``Planner.block_ends``, a dynamic programme over the row's points), per
    row where the model runs them faster than ``decimate``'s longest blocks (else those), both
    timed as ``predict`` times them: with their blends held within the tolerance (``_hold_row``).
    t_opt: (N,) s from each row's start, the law whose differences the blocks command; rows are
    entered as ``predict`` enters them (entry_height mm, entry_feed (R,) mm/min); hold_feed (N,)
    mm/min: the programmed tip feed the held times also keep the tool tip within (``predict``;
    None: not held); shift (N, 5): the block ends are written at q + shift (``vertex_shift``; None:
    at q), the tips the blocks must pass stay q's."""
    rows = np.asarray(rows)
    q = np.asarray(q, float)
    t_opt = np.asarray(t_opt, float)
    ok = block_reach(real or machine, rows, q, tip, BLOCK_TOLERANCE_SHARE * float(tolerance), shift=shift)
    if getattr(planner, "tolerance", 0.0) > tolerance:  # G64 P past it: only blocks blended parabolically
        ok = np.logical_and.accumulate(ok & rotary_turns(q, ok.shape[1]), axis=1)
    qc = q if shift is None else q + np.asarray(shift, float)  # the joints the blocks are written with
    keep = decimate(real or machine, rows, q, tip, tolerance, ok=ok)
    starts, ends = _row_bounds(rows)
    limit = EXECUTED_TOLERANCE_SHARE * float(tolerance)

    def held(r: int, k: np.ndarray) -> float:
        a, b = starts[r], ends[r]
        entry_q, entry_time = row_entry(machine, q[a], entry_height, float(entry_feed[r]))
        path, at = _tip_polyline(machine, q[a:b], tool_tips(machine, entry_q[None, :])[0], 4, np.radians(0.25))
        return _hold_row(planner, machine, qc[a:b], k - a, t_opt[a:b], entry_q, entry_time, path, at, limit,
                         over_limits=_limit_check(planner, machine, hold_feed, a, b, entry_q))[2][-1]

    return sooner_blocks(planner, machine, rows, qc, t_opt, ok, keep,
                         lambda r, a: row_entry(machine, q[a], entry_height, float(entry_feed[r])), held)


def sooner_blocks(planner: Planner, machine: Machine, rows: np.ndarray, x: np.ndarray, t_opt: np.ndarray,
                  ok: np.ndarray, keep: np.ndarray, entry: Callable[[int, int], tuple[np.ndarray, float]],
                  row_time: Callable[[int, np.ndarray], float] | None = None) -> np.ndarray:
    """``keep`` (N,) bool with each row's blocks replaced by the planner's (``Planner.block_ends``
    among the blocks ``ok`` allows) where they run sooner: by ``row_time(r, k)`` (s, row r written in
    the blocks ending at the points k, indices into x) or, without it, by the model's run of the
    commanded law (``Planner.row_run``). x (N, D) the coordinates the planner runs (joints in machine
    mode, world coordinates in TCP mode); t_opt (N,) s, the commanded law; entry(r, a): row r's
    (first point a) entry position and time (s). One rule for both of LinuxCNC's modes (``place``
    and camsmooth.controller.tcp)."""
    keep = np.array(keep, bool)
    starts, ends = _row_bounds(rows)
    for r, (a, b) in enumerate(zip(starts, ends, strict=True)):
        if b - a < 3:
            continue
        entry_x, entry_time = entry(r, a)
        found = planner.block_ends(machine, x[a:b], t_opt[a:b], ok[a:b], entry_x, entry_time)
        if found is None:
            continue
        old, new = a + np.flatnonzero(keep[a:b]), a + np.asarray(found)
        if len(old) == len(new) and np.array_equal(old, new):
            continue
        if row_time is None:
            took = [planner.row_run(machine, x[k], np.diff(t_opt[k]), entry_x, entry_time)[0].end[-1]
                    for k in (old, new)]
        else:
            took = [row_time(r, k) for k in (old, new)]
        if took[1] < took[0]:
            keep[a:b] = False
            keep[new] = True
    return keep


@dataclass(frozen=True, kw_only=True)
class ControllerPlan:
    """A program's blocks and the controller's timing of them.

    controller: the planner model's name; keep: (N,) bool, the points that end a block (the
    G-code blocks); block_time: (N,) s, at a kept point the time of the block ending there as the
    program commands it (the time-optimal law's; 0 at a row's first point and at dropped points);
    t_plan: (N,) s from the row's first point, when the controller passes each point;
    feed_plan: (N,) mm/min, the controller's tool-tip feed at each point (block average);
    row_ids, row_cycle_time: (R,) s per row; cycle_time: s, the sum over rows (rapids not counted);
    row_deviation: (R,) mm, the largest distance of the model's tool tip from the programmed path
    over the row's servo cycles (0 where it was not checked); row_floor: (R,) s, the least time any
    program of straight blocks through the row's points (their ends as far off them as this
    program's, ``end_offset``) can take on this controller within the
    user's tolerance (``Planner.row_floor``; None where the controller has no floor or the
    tolerance was not given): row_cycle_time can come down to it, never below; blend_tolerance: mm,
    the controller's blend tolerance the plan was timed with (LinuxCNC ``G64 P``, which the program
    must be written with), None where the planner has none; entry_stop: each row's entry move
    ends at rest (LinuxCNC ``G61`` for it, which the program must be written with); row_joint_peak: (R, 5), per row and
    joint (X Y Z and the rotary axes) the larger of its largest |velocity| / vmax and |acceleration|
    / amax over the planner model's servo cycles (None: not computed): above 1 the controller's own
    planner takes the joint past its limit (LinuxCNC where two blocks overlap in a blend);
    row_feed_peak: (R,) the tool tip's largest speed over the row's programmed feed at the model's
    servo cycles after the entry (0 where within, None where the feed was not given): in a
    parabolic blend both blocks move, and the tip can go faster than either commands;
    joint_shift: (N, 5) X Y Z mm (rotary 0), what the program adds to the joints of each point it
    keeps (``vertex_shift``: the block ends sit off the points, inside the tolerance; 0 at the
    points it drops), None where the blocks end on the points; tip_shift: (N, 3) mm, workpiece
    frame, the same move of the tool tip (what a TCP program adds to the tips it writes).
    """

    controller: str
    keep: np.ndarray
    block_time: np.ndarray
    t_plan: np.ndarray
    feed_plan: np.ndarray
    row_ids: np.ndarray
    row_cycle_time: np.ndarray
    cycle_time: float
    row_deviation: np.ndarray
    row_floor: np.ndarray | None = None
    blend_tolerance: float | None = None
    entry_stop: bool = False
    row_joint_peak: np.ndarray | None = None
    row_feed_peak: np.ndarray | None = None
    joint_shift: np.ndarray | None = None
    tip_shift: np.ndarray | None = None

    @property
    def floor(self) -> float | None:
        """s, the sum of ``row_floor`` over the rows (None without one)."""
        return None if self.row_floor is None else float(np.sum(self.row_floor))

    @property
    def end_offset(self) -> float:
        """mm, the largest distance of a block end's tool tip from its point (``tip_shift``; 0
        where the blocks end on the points)."""
        if self.tip_shift is None or not len(self.tip_shift):
            return 0.0
        return float(np.linalg.norm(np.asarray(self.tip_shift, float), axis=1).max())

    @property
    def blocks(self) -> int:
        """Number of cut blocks (kept points that are not a row's first)."""
        return int(self.keep.sum() - len(self.row_ids))


class RowRun(Protocol):
    """A row as a planner model runs it (camsmooth.controller.linuxcnc.BlockTimes): ``end`` (s) of
    every segment (the row's entry move first), and per servo cycle the executing segment
    ``head`` and the segment ``following`` it that moves at the same time while the head blends
    into it, with ``following_fraction`` of it done."""

    end: np.ndarray
    head: np.ndarray
    following: np.ndarray
    following_fraction: np.ndarray


class Planner(Protocol):
    """A model of a controller's trajectory planner (camsmooth.controller.linuxcnc.LinuxCNCPlanner)."""

    name: str
    title: str

    def block_ends(self, machine: Machine, q: np.ndarray, t_opt: np.ndarray, ok: np.ndarray, entry_q: np.ndarray,
                   entry_time: float) -> np.ndarray | None:
        """The block ends of one row (indices into its points q (n, 5)) the controller runs
        soonest among the blocks ok (n, K) allows (``block_reach``), None if it cannot tell; t_opt
        (n,) s, the commanded law; the row entered from rest at entry_q by a move of entry_time s."""
        ...

    def row_floor(self, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray,
                  feed: np.ndarray | None, tolerance: float, end_offset: float = 0.0) -> np.ndarray | None:
        """(R,) s per row: the least time any program of straight blocks through the points (their
        ends' tool tips within ``end_offset`` mm of them) can take on the controller within
        ``tolerance`` (mm), None if unknown. feed (N,) mm/min or None."""
        ...

    def row_run(self, machine: Machine, q_blocks: np.ndarray, block_time: np.ndarray, entry: np.ndarray,
                entry_time: float) -> tuple[RowRun, np.ndarray]:
        """One row run from its entry move: the segments' timing and (K, 5) the joints commanded at
        the end of every servo cycle (X Y Z mm A B rad)."""
        ...


#: the share of the user's tolerance the controller model's tool tip may use at any servo cycle:
#: the rest covers the model's differences from the real planner. On the headless LinuxCNC 2.9 the
#: model's tip agrees with the executed one to 0.01-0.03 um at every row's worst servo cycle (blade,
#: wave, ridge, dome, teapot rows of benchmarks/bench_controller.py, 2026-11-28); the 0.1 um left of
#: 5 um also covers the programmed path drawn as a polyline of the tip curves
#: (``programmed_tip_path``). See BLOCK_TOLERANCE_SHARE for what the shares were chosen on.
EXECUTED_TOLERANCE_SHARE = 0.98
#: rounds of lengthening the blocks whose blends go too far, at most
_ROUNDS = 30
#: a block whose own tip curve comes farther than this share of the executed limit from the
#: programmed path is split back into the program's points (its blends get the rest)
_SPLIT_SHARE = 0.99
#: factor a block is lengthened by per round while the run takes a coordinate past its limit during it
_LIMIT_STEP = 1.1
#: share a servo cycle's tool-tip speed may exceed the programmed feed by (a rest stop's one-cycle step)
_FEED_SLACK = 1e-3
#: rounds in a row in which over_limits' largest ratio does not come down before that hold stops
_STALLED = 3
#: share a coordinate's one-cycle finite-difference acceleration may exceed its amax by: a rest
#: stop's last cycle reads 1.003 of it on LinuxCNC's own stop, which no block time changes
_ACC_SLACK = 5e-3


def _blend_excess(run: RowRun, dev: np.ndarray, limit: float, n_blocks: int, following: bool = False) -> np.ndarray:
    """Per block (n_blocks,), the largest deviation (mm) past ``limit`` of a servo sample in a
    blend it heads (0 where none): the block that decelerates into the blend, and with
    ``following`` also the one it blends into; the entry move (segment 0) counted on the first block
    (it keeps its feed). A sample outside any blend is the block's own tip curve, which no speed
    changes."""
    over = (dev > limit) & (run.following_fraction > 0)
    worst = np.zeros(n_blocks + 2)
    for seg in (run.head[over], run.following[over])[:2 if following else 1]:
        np.maximum.at(worst, np.minimum(seg, n_blocks + 1), dev[over])
    worst[1] = max(worst[1], worst[0])
    return worst[1:n_blocks + 1]


def tip_speed_over(run: RowRun, tips: np.ndarray, period: float, feed: float, slack: float = 1e-3) -> np.ndarray:
    """Per block of a row run (n_blocks,), the tool tip's largest speed over ``feed`` (mm/min, the
    row's programmed feed) at the servo cycles the block moves in (executing or blended into), 0
    where within ``slack`` (a rest stop's one-cycle step). In a parabolic blend both blocks move:
    where the one blended into accelerates faster than the other decelerates, their speeds add up
    past either's (on the headless LinuxCNC the tip reached 1.63 of the feed on a blade row). The
    entry move (the run's first segment, at its own feed) is not counted. tips (K + 1, 3) mm: where
    the row's motion starts (at rest) and the tool tip at the end of each servo cycle of ``period`` s."""
    speed = np.linalg.norm(np.diff(np.asarray(tips, float), axis=0), axis=1) * 60.0 / period / float(feed)
    cyc = np.flatnonzero((speed > 1.0 + slack) & (run.head >= 1))
    return block_peaks(run, speed[cyc], run.head[cyc],
                       np.where(run.following_fraction[cyc] > 0, run.following[cyc], run.head[cyc]))


def block_peaks(run: RowRun, ratio: np.ndarray, *segments: np.ndarray) -> np.ndarray:
    """Per block of a row run (n_blocks,), the largest of ``ratio`` (one value per servo cycle
    picked) over the cycles each ``segments`` array (the segment each picked cycle is charged to:
    0 the entry move, counted on the first block; past the last, on the last) charges to it, 0
    where none: what the holds of ``_hold_row`` lengthen."""
    n = len(run.end) - 1
    out = np.zeros(n + 2)
    for seg in segments:
        np.maximum.at(out, np.minimum(np.asarray(seg, np.int64), n + 1), ratio)
    out[1] = max(out[1], out[0])
    return out[1:n + 1]


def acceleration_over(run: RowRun, positions: np.ndarray, amax: np.ndarray, period: float,
                      slack: float = _ACC_SLACK, stride: int = 1, start: np.ndarray | None = None) -> np.ndarray:
    """Per block of a row run (n_blocks,), the largest acceleration over its limit of any planned
    coordinate (positions (K, D) at the end of every servo cycle of ``period`` s, amax (D,) in the
    same units per s^2; second differences over ``stride`` cycles, at rest at ``start`` (D,)
    before the first (None: at the first) and at the last after it: over 5 a segment that ends
    inside a cycle, a one-cycle step, does not count)
    at the cycles the block accelerates at its whole rate (the one blended into, else the
    executing one), 0 where within ``slack``. LinuxCNC limits each coordinate per block, but a
    parabolic blend into a row's last block overlaps the block before's deceleration at half its
    acceleration with the last block's at the whole one (1.11 of amax on the dome's rotary axis in
    TCP mode, 1.10 on a B/C trunnion's in machine mode, both on the headless LinuxCNC)."""
    n = len(run.end) - 1
    w = np.asarray(positions, float)
    s = int(stride)
    rest = w[:1] if start is None else np.asarray(start, float).reshape(1, -1)
    w = np.vstack([np.repeat(rest, s, axis=0), w, np.repeat(w[-1:], s, axis=0)])
    acc = (np.abs(w[2 * s:] - 2.0 * w[s:-s] + w[:-2 * s]) / (s * period) ** 2 / np.asarray(amax, float)).max(axis=1)
    cyc = np.flatnonzero(acc > 1.0 + slack)
    return block_peaks(run, acc[cyc], np.where((run.following_fraction[cyc] > 0) & (run.following[cyc] <= n),
                                               run.following[cyc], run.head[cyc]))


def _limit_check(planner: Planner, machine: Machine, feed: np.ndarray | None, a: int, b: int, entry_q: np.ndarray
                 ) -> Callable[[RowRun, np.ndarray], np.ndarray]:
    """Machine mode's over_limits for ``_hold_row`` on the row of points a:b entered from rest at
    the joints entry_q: every joint's ``acceleration_over`` its amax, and where ``feed`` (mm/min)
    is given the tool tip's ``tip_speed_over`` it (``_feed_check``)."""
    amax = axis_limits(machine)[1]
    period = float(getattr(planner, "servo_period", 1e-3))
    speed = _feed_check(planner, feed, a, b, tool_tips(machine, np.asarray(entry_q, float)[None, :])[0],
                        lambda j: tool_tips(machine, j))

    def over(run: RowRun, joints: np.ndarray) -> np.ndarray:
        out = acceleration_over(run, joints, amax, period, stride=5, start=entry_q)  # as predict's row_joint_peak
        return out if speed is None else np.maximum(out, speed(run, joints))

    return over


def _feed_check(planner: Planner, feed: np.ndarray | None, a: int, b: int, start_tip: np.ndarray,
                tips: Callable[[np.ndarray], np.ndarray], slack: float = _FEED_SLACK
                ) -> Callable[[RowRun, np.ndarray], np.ndarray] | None:
    """``_hold_row``'s over_limits for the row of points a:b: ``tip_speed_over`` against the row's
    programmed feed (mm/min, its largest; None where the feed is not known). start_tip (3,) mm:
    where the row's motion starts; tips: the tool tips (K, 3) of the positions a run commands."""
    if feed is None:
        return None
    f = np.asarray(feed, float)[a:b]
    f = f[np.isfinite(f) & (f > 0)]
    if not len(f):
        return None
    period = float(getattr(planner, "servo_period", 1e-3))
    return lambda run, pos: tip_speed_over(run, np.vstack([np.asarray(start_tip, float).reshape(1, 3), tips(pos)]),
                                           period, float(f.max()), slack)


def _hold_row(planner: Planner, machine: Machine, q: np.ndarray, k: np.ndarray, t_opt: np.ndarray,
              entry_q: np.ndarray, entry_time: float, path: np.ndarray | None, at: np.ndarray | None,
              limit: float, *, tips: Callable[[np.ndarray], np.ndarray] | None = None, split: bool = True,
              over_limits: Callable[[RowRun, np.ndarray], np.ndarray] | None = None
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """One row's blocks k (indices into q) and their times, starting from the time-optimal law's
    t_opt, made such that the planner model's tool tip at every servo cycle stays within ``limit``
    (mm) of ``path`` (None: not checked; at: the path vertex of each point of q). With ``split``, a
    block whose own tip curve comes farther than _SPLIT_SHARE of the limit is split back into the
    program's points; then, at most _ROUNDS times, a blend that goes farther than the limit is
    slowed: the block that decelerates into it lengthened from what it took by sqrt(excess /
    limit) and 2% (a parabolic blend's deviation grows with the square of its speed; on the blade
    rows of benchmarks/bench_controller.py slowing this block alone runs 2.5% sooner than slowing
    both blocks of the blend, and needs fewer rounds than steps of the fourth root), and both
    blocks of the blend once a round no longer brings the worst deviation down.

    tips: the tool tips (K, 3) mm of the positions (K, 5) the planner commands (default: the
    machine's forward kinematics of joints; TCP mode: the world coordinates' first three);
    over_limits(run, positions): (n_blocks,) per block the largest ratio of a coordinate's
    acceleration (or velocity) to its limit while the block moves (None: not checked); a block
    over 1 is lengthened by _LIMIT_STEP per round (in the rounds whose blends keep the path) until
    the largest ratio has not come down for _STALLED rounds in a row, when the block times go back
    to those of the round it was lowest in.
    Returns k, the block times (s), the blocks' end times (s from the row's start, starting with
    0) and the largest deviation of the last run (mm, 0 when not checked)."""
    tips = tips or (lambda joints: tool_tips(machine, joints))
    if split and path is not None and len(k) > 1:
        cut = (_chord_deviation(machine, q, k, path, at) > _SPLIT_SHARE * limit) & (np.diff(k) > 1)
        if cut.any():
            k = np.r_[np.concatenate([np.arange(k[j], k[j + 1]) if cut[j] else k[j:j + 1]
                                      for j in range(len(k) - 1)]), k[-1]]
    bt = np.diff(t_opt[k])
    worst = 0.0
    both = False
    peak: float | None = np.inf  # over_limits' lowest largest ratio so far (None: no longer held)
    best = bt  # the block times of the round that reached it
    stalled = 0  # rounds since it last came down
    ran = None
    for _ in range(_ROUNDS if path is not None or over_limits is not None else 1):
        run, joints = planner.row_run(machine, q[k], bt, entry_q, entry_time)
        ran = bt
        excess = np.zeros(len(bt))
        if path is not None:
            dev = _run_deviation(run, tips(joints), path, at[k])
            before, worst = worst, float(dev.max())
            if worst > limit:
                both = both or (before > 0 and worst >= before)
                # zero where what is left is a block's own tip curve: slowing down cannot help it
                excess = _blend_excess(run, dev, limit, len(bt), following=both)
        over = np.zeros(len(bt), bool)
        # the limits once the blends keep the path: slower blends may already keep them
        if over_limits is not None and peak is not None and not excess.any():
            ratio = over_limits(run, joints)
            top = float(ratio.max(initial=0.0))
            if top < peak:
                peak, best, stalled = top, bt, 0
            else:
                stalled += 1
            if stalled >= _STALLED:  # lengthening does not bring it down: back to the round that did best
                peak = None
                if not np.array_equal(bt, best):
                    bt = best
                    continue
            else:
                over = ratio > 1.0
        if not excess.any() and not over.any():
            break
        # the controller runs short five-axis blocks slower than commanded: slow down from what it did
        slow = np.maximum(bt, np.diff(run.end))
        grow = np.sqrt(np.divide(excess, limit, out=np.zeros_like(excess), where=excess > 0)) * 1.02
        bt = np.where(excess > 0, slow * grow, np.where(over, slow * _LIMIT_STEP, bt))
    if ran is not bt:  # the rounds ran out on block times not yet run
        run, joints = planner.row_run(machine, q[k], bt, entry_q, entry_time)
        if path is not None:
            worst = float(_run_deviation(run, tips(joints), path, at[k]).max())
    return k, bt, np.r_[0.0, run.end[1:] - run.end[0]], worst


def joint_ratio(machine: Machine, joints: np.ndarray, period: float, stride: int = 1) -> np.ndarray:
    """(2, 5) the largest |velocity| / vmax (row 0) and |acceleration| / amax (row 1) of each joint
    over servo samples joints (K, 5) X Y Z mm, rotary rad, at ``period`` s (first differences, and
    second differences over ``stride`` cycles: 1 sees a one-cycle step where a segment ends inside a
    cycle, a few see an acceleration that lasts; the motion starts and ends at rest: the first and
    last sample are held)."""
    vmax, amax, _ = axis_limits(machine)
    q = np.asarray(joints, float)
    k = int(stride)
    q = np.vstack([np.repeat(q[:1], k, axis=0), q, np.repeat(q[-1:], k, axis=0)])
    v = np.abs(np.diff(q, axis=0)) / period
    a = np.abs(q[2 * k:] - 2.0 * q[k:-k] + q[:-2 * k]) / (k * period) ** 2
    return np.vstack([v.max(axis=0, initial=0.0) / vmax, a.max(axis=0, initial=0.0) / amax])


def points_timing(s: np.ndarray, k: np.ndarray, tk: np.ndarray, tip_k: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One row's points as the controller passes them: (n,) s from the row's start and (n,) the
    tool-tip feed (mm/min, each block's chord over its time; 0 at the row's first and last point).
    s (n,): the points' travel along the row, by which a point inside a block gets its share of the
    block's time (the pivot's in machine mode, the tip's in TCP mode, mm); k (m,) the block ends
    (indices into the row, the first point first); tk (m,) their times (s); tip_k (m, 3) their tips
    (mm, workpiece frame)."""
    t = np.interp(s, s[k], tk)
    chord = np.linalg.norm(np.diff(tip_k, axis=0), axis=1)
    dt = np.diff(tk)
    fb = np.where(dt > 0, 60.0 * chord / np.maximum(dt, 1e-12), 0.0)
    feed = np.interp(s, s[k][1:], fb) if len(fb) else np.zeros(len(s))
    feed[0] = 0.0
    feed[-1] = 0.0
    return t, feed


def predict(planner: Planner, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray,
            t_opt: np.ndarray, keep: np.ndarray, *, entry_height: float, entry_feed: np.ndarray,
            tolerance: float | None = None, feed: np.ndarray | None = None, hold_feed: bool = False,
            shift: np.ndarray | None = None, hold: bool = True) -> ControllerPlan:
    """The controller's timing of a program written in the blocks ``keep`` with the block times
    of the time-optimal law ``t_opt`` (s from each row's start). q: (N, 5) X Y Z mm A B rad;
    tip: (N, 3) mm. Each row is entered by a feed move of ``entry_height`` mm along the tool axis
    at the row's programmed feed ``entry_feed`` (mm/min, per row), as the G-code writer does.

    tolerance: the user's (mm). Then the blocks are also made slow enough that the tool tip the
    planner model commands at every servo cycle (forward kinematics of its joints) stays within
    EXECUTED_TOLERANCE_SHARE of it from the path the full-density program commands
    (``programmed_tip_path``): a block whose own tip curve comes too near the limit is split back
    into the program's points, and a block whose blend goes farther is lengthened and the row
    run again, at most _ROUNDS times (``_hold_row``). ``row_deviation`` is what the last run gives; the
    plan's ``keep`` has the split blocks' points. With the tolerance, ``row_floor`` is the planner's
    floor through the same points, for block ends as far off them as the plan's (``Planner.row_floor``;
    feed (N,) mm/min the programmed tip feed, None: unknown). shift (N, 5): the blocks are written
    between the joints q + shift (``vertex_shift``, as ``place`` chose them; None: q); the
    programmed path stays q's. hold False: t_opt is the program's own block times (a written
    program's F words), run as written, neither split nor lengthened (row_deviation 0: not
    checked)."""
    rows = np.asarray(rows)
    keep = np.array(keep, bool)
    q = np.asarray(q, float)
    qc = q if shift is None else q + np.asarray(shift, float)
    prog_feed = None if feed is None else np.asarray(feed, float)
    n = len(rows)
    starts, ends = _row_bounds(rows)
    block_time = np.zeros(n)
    t_ctrl = np.zeros(n)
    feed = np.zeros(n)
    row_cycle = np.zeros(len(starts))
    row_dev = np.zeros(len(starts))
    peak = np.zeros((len(starts), 5))
    feed_peak = np.full(len(starts), np.nan)
    at = np.zeros(n, np.int64)  # per point, its vertex in its row's programmed tip path
    for r, (a, b) in enumerate(zip(starts, ends, strict=True)):
        k = a + np.flatnonzero(keep[a:b])
        bt = np.zeros(0)
        entry_q, entry_time = row_entry(machine, q[a], entry_height, float(entry_feed[r]))
        tk = np.zeros(1)
        if len(k) > 1:
            path = None
            entry_tip = tool_tips(machine, entry_q[None, :])[0]
            if tolerance is not None and hold:
                path, at[a:b] = _tip_polyline(machine, q[a:b], entry_tip, 4, np.radians(0.25))
            limit = EXECUTED_TOLERANCE_SHARE * float(tolerance or 0.0)
            k, bt, tk, row_dev[r] = _hold_row(planner, machine, qc, k, t_opt, entry_q, entry_time, path, at, limit,
                                              over_limits=_limit_check(planner, machine, prog_feed if hold_feed else
                                                                       None, a, b, entry_q) if hold else None)
            keep[k] = True
            run, joints = planner.row_run(machine, qc[k], bt, entry_q, entry_time)
            # over 5 cycles: an overlap of two blends lasts; a segment ending inside a cycle is a one-cycle step.
            # From the entry's start, where the row's motion starts at rest
            period = getattr(planner, "servo_period", 1e-3)
            peak[r] = joint_ratio(machine, np.vstack([entry_q[None, :], joints]), period, stride=5).max(axis=0)
            speed = _feed_check(planner, prog_feed, a, b, entry_tip, lambda j: tool_tips(machine, j), slack=0.0)
            if speed is not None:
                feed_peak[r] = float(speed(run, joints).max(initial=0.0))
        block_time[k[1:]] = bt
        # points inside a block: by their share of the block's pivot travel
        s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(q[a:b, :3], axis=0), axis=1))]
        t_ctrl[a:b], feed[a:b] = points_timing(s, k - a, tk, tip[k])
        row_cycle[r] = tk[-1]
    floor = None
    joint_shift = tip_shift = None
    off = 0.0
    if shift is not None:
        joint_shift = np.where(keep[:, None], qc - q, 0.0)
        tip_shift = np.zeros((n, 3))
        tip_shift[keep] = tool_tips(machine, qc[keep]) - tool_tips(machine, q[keep])
        off = float(np.linalg.norm(tip_shift, axis=1).max(initial=0.0))
    if tolerance is not None and n:  # the floor of programs whose block ends sit as far off the points
        floor = planner.row_floor(machine, rows, q, tip, prog_feed, float(tolerance), off)
    return ControllerPlan(controller=planner.name, keep=keep, block_time=block_time, t_plan=t_ctrl,
                          feed_plan=feed, row_ids=rows[starts].astype(np.int64), row_cycle_time=row_cycle,
                          cycle_time=float(row_cycle.sum()), row_deviation=row_dev,
                          row_floor=None if floor is None else np.asarray(floor, float),
                          blend_tolerance=getattr(planner, "tolerance", None),
                          entry_stop=bool(getattr(planner, "entry_stop", False)), row_joint_peak=peak,
                          row_feed_peak=None if prog_feed is None else feed_peak,
                          joint_shift=joint_shift, tip_shift=tip_shift)


def through_points_where_sooner(rows: np.ndarray, shift: np.ndarray, off: ControllerPlan, through: ControllerPlan
                                ) -> tuple[np.ndarray, np.ndarray] | None:
    """Per row the sooner of two plans of the same points, one with its block ends moved off them
    by ``shift`` (N, 5) and one through them: the blocks (N,) bool and the shift (N, 5), 0 on the
    rows the plan through the points runs sooner; None where no row does (then ``off`` stands).
    On rows the feed paces, the longer blocks off the points blend less often and run a little
    later (the saddle rows of benchmarks/bench_controller.py: 1.1%)."""
    faster = np.asarray(through.row_cycle_time) < np.asarray(off.row_cycle_time)
    if not faster.any():
        return None
    starts, ends = _row_bounds(rows)
    on = np.ones(len(rows), bool)
    for a, b in zip(starts[faster], ends[faster], strict=True):
        on[a:b] = False
    return np.where(on, off.keep, through.keep), np.where(on[:, None], shift, 0.0)


def plan_blocks(planner: Planner, machine: Machine, rows: np.ndarray, q: np.ndarray, tip: np.ndarray,
                t_opt: np.ndarray, tolerance: float, *, entry_height: float, entry_feed: np.ndarray,
                real: Machine | None = None, feed: np.ndarray | None = None, hold_feed: bool = False,
                shift: np.ndarray | None = None) -> ControllerPlan:
    """``place`` then ``predict``: the program camsmooth writes and the controller's timing of it
    (arguments as theirs; feed (N,) mm/min the programmed tip feed, held with ``hold_feed``). With
    ``shift`` (``vertex_shift``), per row the sooner of its blocks ending off the points and
    through them (``through_points_where_sooner``)."""
    kw = dict(entry_height=entry_height, entry_feed=entry_feed)
    hold = feed if hold_feed else None

    def planned(s: np.ndarray | None) -> ControllerPlan:
        keep = place(planner, machine, rows, q, tip, t_opt, tolerance, real=real, hold_feed=hold, shift=s, **kw)
        return predict(planner, machine, rows, q, tip, t_opt, keep, tolerance=tolerance, feed=feed,
                       hold_feed=hold_feed, shift=s, **kw)

    off = planned(shift)
    if shift is None:
        return off
    mixed = through_points_where_sooner(rows, shift, off, planned(None))
    if mixed is None:
        return off
    return predict(planner, machine, rows, q, tip, t_opt, mixed[0], tolerance=tolerance, feed=feed,
                   hold_feed=hold_feed, shift=mixed[1], **kw)
