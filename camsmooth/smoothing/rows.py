"""One row of the NLP method, with the tool's clearance inside the optimisation.

``solve_row`` is a pure function of a ``RowTask`` (the row's data) and a ``RowContext`` (what
every row of one program shares), so rows run serially, in processes or on Dask with identical
results (camsmooth.smoothing.parallel). Per row:

1. Map: at the points where an orientation the pipeline already evaluated gouges (the 'none'
   and 'spline' poses), and their neighbours within a cutter radius, compute the accessibility
   map (camsmooth.geometry.accessibility): which lead/tilt of the window clears the mesh, as a
   lead floor and ceiling smooth in tilt and a clear tilt range. Why not every point: a map costs
   about 110 exact clearance evaluations per point (a million-point program: ~10^8, tens of
   minutes), and where no evaluated pose gouges the window's floor seldom binds; points the
   solution then brings into a gouge are mapped in the next round (step 4), and every final
   pose is verified exactly. The benchmark's reference (benchmarks/reference_nlp.py) maps every
   point and finds the same Gamma within 0.01% on every shipped sample.
2. Solve the NLP (camsmooth.smoothing.nlp.RowNLP) with those as constraints. On dense rows (CC
   points closer in time than ``knot_dt``) the NLP's variables sit on every k-th point, the
   *knots*, k = knot_dt / (median time step), and A, B in between are the cubic spline through
   the knots (scipy CubicSpline, not-a-knot); every mapped point is a knot. The interpolated
   program is then checked at every point against the travel, the velocity and acceleration
   limits (the same finite differences as the metrics) and the windows; points that leave them
   become knots and the row is solved again. Limits are backed off by KNOT_BACKOFF on such rows
   so that this is rare. Knots 15 ms apart are finer than a position loop's time constant
   1 / Kv (Kv 15-130 1/s, METHODS section 6: 8-67 ms), so the axes could not follow the detail
   left out; the samples' rows (9-12 ms) are solved whole. Measured on the blade at 0.08 mm
   spacing (2.4 ms, knots every 6th point): the NLP 8x faster, Gamma 1.9% above solving every
   point.
3. Verify with the exact clearance only the poses that moved: a pose whose tool moved by less
   than MOVE_TOL (a bound over the whole tool solid: tip displacement plus axis rotation times
   the tool's reach) keeps its clearance; the first round checks every pose.
   If IPOPT finds the row infeasible with the map's constraints, an elastic re-solve with the
   floor and ceiling soft (camsmooth.smoothing.nlp.clearance_elastic) names the points whose clear
   region the limits keep the axis from (a floor climbing to the window's top faster than B may
   turn, before a blocked stretch): their floor (ceiling) is moved to what the limits allow,
   they are not refined again and fall back to the lift (``unreachable_clear``); the row is
   re-solved from the elastic program. Only when the limits and windows alone admit no program
   is the row refused, naming the binding limit (the user's windows first).
4. Refine: points that gouge and were not mapped are mapped (step 1); mapped points that still
   gouge (the map is a sampled approximation between its samples) get their floor or ceiling
   moved to the exact boundary at the solution's tilt. Re-solve, from the last solution.

The lift along the normal is the fallback only for points whose whole window the map found
blocked (``blocked``; ``best_delta`` is the best clearance the map found there), and for points
that the machine's limits keep from reaching their clear region (``unreachable_clear``); both are
named by the pipeline with their size. Units: mm, s, rad; workpiece frame.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.ndimage import binary_dilation

from camsmooth.errors import InfeasibleError
from camsmooth.geometry.accessibility import accessibility_map, clear_region, pose_clearance
from camsmooth.geometry.clearance import MeshIndex, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.frames import lead_tilt_from_axis
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import Machine
from camsmooth.smoothing.finish import merge_ceilings
from camsmooth.smoothing.nlp import (
    BACKOFF,
    LeadBounds,
    RowNLP,
    clearance_elastic,
    elastic_diagnosis,
    fd_operators,
)
from camsmooth.smoothing.pole import POLE_CONE_DEG

__all__ = ["RowContext", "RowOptions", "RowSolution", "RowTask", "solve_row"]

MOVE_TOL = 1e-6  # mm: a pose whose tool moved less keeps its verified clearance
KNOT_BACKOFF = 0.02  # limits backed off by this fraction when the NLP runs on knots
# ... and the windows, by a margin in the tool axis: between knots the interpolated axis departs
# from the chord of its knot values by up to h^2 amax / 8 (a cubic whose second derivative is at
# most amax, knots h apart), and the local frame departs from the chord of the knots' frames by
# what the fine points show (at a G1 blend the normal turns with a kink). KNOT_MARGIN times their
# sum narrows the lead window, and that divided by sin(lead) the tilt window (tilt is
# ill-conditioned at small leads). Measured on ten 1025-point rows of the blade at 0.08 mm spacing
# (knots every 6th point): without it every row needed a second solve (0.06 deg over the lead
# bound at G1 blends, 0.4 deg over the tilt bound at a 2 deg lead) and Gamma came out 2.7% above
# solving every point; with a factor 1, one solve and +1.9%; with 2, +3%.
KNOT_MARGIN = 1.0
MAP_FRACTION = 0.5  # the map calls an orientation clear at delta >= -MAP_FRACTION * tolerance
REFINE_MARGIN = np.radians(0.05)  # rad: a floor moved to the exact boundary goes this much beyond
LIFT_STEPS = 12  # re-checks of the fallback lift along the normal (secant steps after the first)
MAX_RELIEFS = 2  # soft-clearance re-solves per row (module docstring, step 2)
RELIEF_TOL = 1e-7  # rad: a point whose lead stays this far outside its clear region gives it up
CLEARANCE_WEIGHT = 1e3  # in the relief, a radian outside the clear region costs this many of the finish budget's


@dataclass(frozen=True)
class RowOptions:
    """Tuning of the row solver: map grid (leads x tilts) and bisection steps, verification
    rounds, the knot spacing (s) of dense rows (module docstring, step 2; 0 solves every point)
    and IPOPT options."""

    map_grid: tuple[int, int] = (9, 7)
    map_refine: int = 6
    max_rounds: int = 6
    knot_dt: float = 0.015
    ipopt_options: dict | None = None


@dataclass(frozen=True)
class RowContext:
    """What every row of one program shares: the machines the NLP may smooth on (a task names
    one: the nominal machine, or the error model's real machine), the cutter, the mesh (vertices
    (V, 3) mm and faces (F, 3)), the tolerance (mm: a clearance below -tolerance is a gouge) and the
    options. ``key`` names the program so a worker builds its search structure once; ``source``
    the program's file, for messages."""

    machines: tuple[Machine, ...]
    cutter: ToroidalCutter
    vertices: np.ndarray
    faces: np.ndarray
    tolerance: float
    options: RowOptions = field(default_factory=RowOptions)
    key: str = ""
    source: str | None = None


@dataclass(frozen=True)
class RowTask:
    """One row: its id, time stamps t (N,) s, local frames (N, 3, 3), CC points and unit normals
    (N, 3), lead/tilt windows (N, 2) rad, the warm start ``start`` (the machine's rotary axes, rad,
    named by them: ``task.start["C"]``) and the points where an
    orientation evaluated before gouged (``risk``, (N,) bool); ``machine`` indexes
    RowContext.machines; ``pole`` the programmed tool axis' angle from the pole of the outer
    rotary axis (N,) rad, for naming a passage the windows cannot contain (None: not known);
    ``lead_cap`` and ``has_cap`` the lead ceiling c0 + c1 tilt + c2 tilt^2 (rad, (N, 3)) a finish
    budget sets (camsmooth.smoothing.finish.lead_ceiling; None: no budget)."""

    row: int
    t: np.ndarray
    frames: np.ndarray
    cc: np.ndarray
    normals: np.ndarray
    lead_window: np.ndarray
    tilt_window: np.ndarray
    start: RotaryValues
    risk: np.ndarray
    machine: int = 0
    pole: np.ndarray | None = None
    lead_cap: np.ndarray | None = None  # (N, 3) the finish budget's lead ceiling (camsmooth.smoothing.finish)
    has_cap: np.ndarray | None = None  # (N,) where it applies


@dataclass(frozen=True)
class RowSolution:
    """The row's program and how it was reached.

    rotary: the machine's rotary axes (N, 2) rad, named by them (``sol.rotary["C"]``); delta:
    exact clearance of the final poses (mm); lift: along the normal (mm, 0 where none);
    lead_window, tilt_window: the windows with the map's tilt narrowing (rad);
    mapped: points that got a map; blocked: points whose whole window the map found blocked;
    unreachable_clear: mapped points with a clear region that the limits kept the solution out
    of; best_delta: the best clearance the map found (mm, NaN where not mapped); lead_clear: (N, 2)
    the map's lead floor and ceiling (rad) at the solution's tilt (NaN where none); iterations
    (IPOPT, summed), rounds (solve/verify), clearance_evals (poses checked, map included),
    solve_s, map_s, check_s: time in the NLP, the map and the verification (s).
    """

    rotary: RotaryValues
    delta: np.ndarray
    lift: np.ndarray
    lead_window: np.ndarray
    tilt_window: np.ndarray
    mapped: np.ndarray
    blocked: np.ndarray
    unreachable_clear: np.ndarray
    best_delta: np.ndarray
    lead_clear: np.ndarray
    iterations: int
    rounds: int
    clearance_evals: int
    solve_s: float
    map_s: float
    check_s: float


class _Worker:
    """Per-process state built once per program: the mesh's search structure and the NLPs by
    row length (both are pure caches: results never depend on them)."""

    def __init__(self, ctx: RowContext, index: MeshIndex | None = None) -> None:
        import trimesh

        self.index = index if index is not None else MeshIndex(trimesh.Trimesh(ctx.vertices, ctx.faces,
                                                                               process=False))
        self.nlps: dict[tuple[int, int, float], RowNLP] = {}

    def nlp(self, ctx: RowContext, machine: int, n: int, backoff: float) -> RowNLP:
        key = (machine, n, backoff)
        if key not in self.nlps:
            if len(self.nlps) >= 8:
                self.nlps.pop(next(iter(self.nlps)))
            self.nlps[key] = RowNLP(ctx.machines[machine], n, ipopt_options=ctx.options.ipopt_options,
                                    backoff=backoff)
        return self.nlps[key]


_WORKERS: dict[tuple[str, int], _Worker] = {}


def _worker(ctx: RowContext, index: MeshIndex | None = None) -> _Worker:
    """This process's state for the context's program (built at the first call; ``index``: a
    search structure of the same mesh the caller already has)."""
    key = (ctx.key, 0 if ctx.key else id(ctx))
    w = _WORKERS.get(key)
    if w is None:
        if len(_WORKERS) >= 2:
            _WORKERS.pop(next(iter(_WORKERS)))
        w = _WORKERS[key] = _Worker(ctx, index)
    return w


def adopt_index(ctx: RowContext, index: MeshIndex) -> None:
    """Let rows run in this process use ``index`` (built from the context's mesh) instead of
    building their own."""
    _worker(ctx, index)


def tool_reach(cutter: ToroidalCutter) -> float:
    """Largest distance (mm) from the tool tip to any point of the tool solid: the lever arm
    that turns an axis rotation (rad) into a displacement bound."""
    top = cutter.shank_length + (cutter.holder_length if cutter.holder_radius is not None else 0.0)
    radius = max(cutter.R + cutter.r, cutter.holder_radius or 0.0)
    return float(np.hypot(top, radius))


def _neighbours(mask: np.ndarray, cc: np.ndarray, reach: float) -> np.ndarray:
    """mask grown to the points within ``reach`` mm along the row (at least one point each side)."""
    if not mask.any():
        return mask
    seg = np.linalg.norm(np.diff(cc, axis=0), axis=1)
    k = int(np.clip(np.ceil(reach / max(float(np.median(seg)), 1e-9)), 1, 50))
    return binary_dilation(mask, np.ones(2 * k + 1, bool))


def solve_row(ctx: RowContext, task: RowTask) -> RowSolution:
    """The NLP method on one row with the clearance inside the optimisation (module docstring).
    Raises InfeasibleError naming the binding limit when no program meets the limits and the
    windows."""
    w = _worker(ctx)
    cut, mach, opts = ctx.cutter, ctx.machines[task.machine], ctx.options
    n = len(task.t)
    tol = float(ctx.tolerance)
    thr = MAP_FRACTION * tol
    lw, tw = task.lead_window.copy(), task.tilt_window.copy()
    floor, ceiling = np.zeros((n, 3)), np.zeros((n, 3))
    has_floor, has_ceiling = np.zeros(n, bool), np.zeros(n, bool)
    mapped, blocked = np.zeros(n, bool), np.zeros(n, bool)
    best = np.full(n, np.nan)
    delta = np.full(n, np.nan)
    last_cl, last_T = np.full((n, 3), np.nan), np.full((n, 3), np.nan)
    reach = tool_reach(cut)
    stride = knot_stride(task.t, opts.knot_dt)
    knots = np.zeros(n, bool)
    knots[::stride] = knots[-1] = True
    backoff = KNOT_BACKOFF if stride > 1 else BACKOFF
    names = task.start.names  # the machine's rotary axes: q1, q2 below are their angles (rad)
    q1, q2 = task.start.pair
    good: tuple[np.ndarray, np.ndarray] | None = None
    evals = iters = rounds = 0
    t_solve = t_map = t_check = 0.0
    to_map = _neighbours(task.risk, task.cc, cut.R + cut.r)
    refine = np.zeros(n, bool)
    gave_up = np.zeros(n, bool)  # mapped points whose clear region the limits keep the axis out of
    reliefs = 0
    # the finish budget's lead ceiling, merged with the map's clearance ceiling where both apply
    cap = np.zeros((n, 3)) if task.lead_cap is None else np.array(task.lead_cap, float)
    has_cap = np.zeros(n, bool) if task.has_cap is None else np.asarray(task.has_cap, bool).copy()

    def ceilings() -> tuple[np.ndarray, np.ndarray]:
        return merge_ceilings(ceiling, has_ceiling, cap, has_cap, tw)

    for rounds in range(1, opts.max_rounds + 1):  # noqa: B007
        t0 = time.perf_counter()
        if to_map.any():
            k = np.flatnonzero(to_map)
            amap = accessibility_map(w.index, cut, task.cc[k], task.normals[k], task.frames[k], lw[k], tw[k], thr,
                                     *opts.map_grid, refine=opts.map_refine)
            evals += amap.delta.size + opts.map_refine * int(amap.floor_active.sum() + amap.ceiling_active.sum())
            reg = clear_region(amap, lw[k])
            floor[k], ceiling[k] = reg.floor, reg.ceiling
            has_floor[k], has_ceiling[k] = reg.has_floor, reg.has_ceiling
            tw[k] = np.where(reg.blocked[:, None], tw[k], reg.tilt_window)
            blocked[k], best[k] = reg.blocked, reg.best_delta
            mapped |= to_map
        if refine.any():
            evals += _move_bounds(w.index, cut, task, refine, q1, q2, mach, lw, floor, ceiling, has_floor, has_ceiling,
                                  thr, opts.map_refine)
        t_map += time.perf_counter() - t0
        t0 = time.perf_counter()
        knots |= mapped  # clearance-constrained points carry their own variables
        if rounds == opts.max_rounds:
            knots[:] = True  # the last round solves every point, so its program meets every limit
        kk = np.flatnonzero(knots)
        nlp = w.nlp(ctx, task.machine, len(kk), backoff)
        ceil_m, has_m = ceilings()
        bounds = LeadBounds(floor[kk], ceil_m[kk], has_floor[kk], has_m[kk])
        if len(kk) < n:  # each knot holds the tightest window of the points around it, narrowed
            eps = KNOT_MARGIN * _knot_margin(task, kk, max(L.amax for L in mach.rotary_limits()))
            lw_k = _narrowed(_around(lw, kk), eps)
            tw_k = _narrowed(_around(tw, kk), eps / np.sin(np.maximum(lw_k[:, 0], np.radians(0.5))))
        else:
            lw_k, tw_k = lw, tw
        sol, st = nlp.solve(task.t[kk], task.frames[kk], RotaryValues.of(names, q1[kk], q2[kk]), lw_k, tw_k, bounds)
        q1_k, q2_k = sol.pair
        iters += st.iterations
        t_solve += time.perf_counter() - t0
        if not st.success and len(kk) < n:
            knots[:], backoff = True, BACKOFF  # the knots' wider back-off may be what binds: solve whole
            continue
        if not st.success and reliefs < MAX_RELIEFS and (has_floor.any() or has_ceiling.any() or has_cap.any()):
            # the clear regions of the map may be what no program within the limits reaches (a
            # floor climbing to the window's top before a blocked stretch): soft clearance names
            # those points, which keep only the windows and fall back to the lift
            reliefs += 1
            ceil_m, has_m = ceilings()
            clear_w = np.full(n, CLEARANCE_WEIGHT)  # the map's bounds give way after the finish budget's
            relief = clearance_elastic(mach, task.t, task.frames, lw, tw,
                                       LeadBounds(floor, ceil_m, has_floor, has_m), RotaryValues.of(names, q1, q2),
                                       backoff=nlp.backoff,
                                       weights=(clear_w, np.where(has_ceiling, CLEARANCE_WEIGHT, 1.0)))
            if relief.feasible:
                # those points keep the clear side as near as the limits allow: their floor
                # (ceiling) moves down (up) by what the limits keep the lead from; a finish
                # budget's ceiling too (its miss is named with its size by the pipeline)
                up = relief.ceiling_short > RELIEF_TOL
                short = (relief.floor_short > RELIEF_TOL) | (up & has_ceiling)
                gave_up |= short
                cap[:, 0] += np.where(has_cap & up, relief.ceiling_short + RELIEF_TOL, 0.0)
                floor[:, 0] -= np.where(relief.floor_short > RELIEF_TOL, relief.floor_short + RELIEF_TOL, 0.0)
                ceiling[:, 0] += np.where(relief.ceiling_short > RELIEF_TOL, relief.ceiling_short + RELIEF_TOL, 0.0)
                q1, q2 = relief.rotary.pair  # meets the limits and windows: a start IPOPT can leave
                to_map[:] = refine[:] = False
                continue
        if not st.success:
            if good is None:
                _raise_infeasible(ctx, task, nlp, lw, tw, q1_k, q2_k, st.status, mapped.any())
            q1, q2 = good  # the last verified solution; what still gouges is named below
            break
        if len(kk) < n:
            q1, q2 = (CubicSpline(task.t[kk], q)(task.t) for q in (q1_k, q2_k))
            off = _off_limits(mach, task, q1, q2, lw, tw, ceilings()) & ~knots
            if off.any():  # the interpolation left a limit or a window: those points become knots
                knots |= binary_dilation(off, np.ones(5, bool))
                to_map[:] = refine[:] = False
                continue
        else:
            q1, q2 = q1_k, q2_k
        t0 = time.perf_counter()
        T = mach.tool_axis_np(q1, q2)
        cl = cc_to_cl(cut, task.cc, task.normals, T)
        moved = (np.linalg.norm(cl - last_cl, axis=1) + reach * np.linalg.norm(T - last_T, axis=1))
        check = ~(moved <= MOVE_TOL)  # NaN (never checked) included
        if check.any():
            delta[check] = clearance(w.index, cut, cl[check], T[check]).delta
            last_cl[check], last_T[check] = cl[check], T[check]
            evals += int(check.sum())
        t_check += time.perf_counter() - t0
        good = (q1, q2)
        bad = (delta < -tol) & ~blocked & ~gave_up
        if not bad.any():
            break
        to_map = _neighbours(bad & ~mapped, task.cc, cut.R + cut.r) & ~mapped
        refine = bad & mapped
    # what still gouges: whole window blocked, or a clear region the limits did not let the
    # solution reach
    bad = delta < -tol
    unreachable_clear = bad & ~blocked
    lift = np.zeros(n)
    if bad.any():
        T = mach.tool_axis_np(q1, q2)
        cl = cc_to_cl(cut, task.cc, task.normals, T)
        lift, delta = lift_along_normal(w.index, cut, cl, T, task.normals, delta, bad, tol)
    _, tilt = lead_tilt_from_axis(mach.tool_axis_np(q1, q2), task.frames)
    p = np.stack([np.ones_like(tilt), tilt, tilt ** 2], -1)
    lead_clear = np.column_stack([np.where(has_floor, np.sum(floor * p, -1), np.nan),
                                  np.where(has_ceiling, np.sum(ceiling * p, -1), np.nan)])
    return RowSolution(rotary=RotaryValues.of(names, q1, q2), delta=delta, lift=lift, lead_window=lw,
                       tilt_window=tw, mapped=mapped, blocked=blocked, unreachable_clear=unreachable_clear,
                       best_delta=best, lead_clear=lead_clear, iterations=iters, rounds=rounds,
                       clearance_evals=evals, solve_s=t_solve, map_s=t_map, check_s=t_check)


def _knot_margin(task: RowTask, knots: np.ndarray, amax: float) -> np.ndarray:
    """Per knot (rad): how far the tool axis can drift from the window's bound between it and its
    neighbours (the comment at KNOT_MARGIN): h^2 amax / 8 plus the largest distance of the fine
    points' frame axes (normal, X_L) from the chord between the knots' frames."""
    t = task.t
    seg = np.searchsorted(knots, np.arange(len(t)), side="right") - 1  # the knot interval of each point
    seg = np.clip(seg, 0, len(knots) - 2)
    k0, k1 = knots[seg], knots[seg + 1]
    w = ((t - t[k0]) / (t[k1] - t[k0]))[:, None]
    dev = np.zeros(len(t))
    for col in (2, 0):  # the normal and X_L
        f = task.frames[:, :, col]
        dev = np.maximum(dev, np.linalg.norm(f - ((1 - w) * f[k0] + w * f[k1]), axis=1))
    per_seg = np.zeros(len(knots) - 1)
    np.maximum.at(per_seg, seg, dev)
    h = np.diff(t[knots])
    per_seg += h * h * amax / 8.0
    return np.maximum(np.concatenate([per_seg[:1], per_seg]), np.concatenate([per_seg, per_seg[-1:]]))


def _around(window: np.ndarray, knots: np.ndarray) -> np.ndarray:
    """Per knot, the intersection of the windows (N, 2) of every point from the previous knot to
    the next (the spline between knots must stay inside all of them)."""
    lo = np.maximum.reduceat(window[:, 0], knots)  # knot j .. knot j+1 - 1
    hi = np.minimum.reduceat(window[:, 1], knots)
    lo_prev = np.concatenate([lo[:1], lo[:-1]])
    hi_prev = np.concatenate([hi[:1], hi[:-1]])
    lo = np.maximum(lo, lo_prev)
    hi = np.minimum(hi, hi_prev)
    lo_e, hi_e = window[knots, 0], window[knots, 1]
    ok = lo <= hi  # an empty intersection (windows jumping apart between knots): the knot's own
    return np.column_stack([np.where(ok, lo, lo_e), np.where(ok, hi, hi_e)])


def _narrowed(window: np.ndarray, by: float | np.ndarray) -> np.ndarray:
    """Windows (N, 2) rad narrowed by ``by`` (rad, scalar or (N,)) at each end, by at most a
    quarter of their width."""
    by = np.minimum(by, 0.25 * (window[:, 1] - window[:, 0]))
    return np.column_stack([window[:, 0] + by, window[:, 1] - by])


def knot_stride(t: np.ndarray, knot_dt: float) -> int:
    """Every how many points a row's NLP variables sit (module docstring, step 2): the median
    time step (s) into ``knot_dt`` (s), at least 1."""
    if knot_dt <= 0 or len(t) < 8:
        return 1
    return max(1, int(knot_dt // max(float(np.median(np.diff(t))), 1e-12)))


def _off_limits(machine: Machine, task: RowTask, q1: np.ndarray, q2: np.ndarray, lw: np.ndarray,
                tw: np.ndarray, ceiling: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Points where an interpolated program leaves the travel, the velocity or acceleration limit
    (the finite differences of camsmooth.smoothing.nlp, against the true limits), the lead/tilt
    windows (rad) or a lead ceiling (coefficients (N, 3), where (N,): the finish budget's and the
    map's)."""
    D1, D2 = fd_operators(task.t)
    off = np.zeros(len(q1), bool)
    for L, q in zip(machine.rotary_limits(), (q1, q2), strict=True):
        off |= (q < L.min) | (q > L.max)
        v = np.abs(D1 @ q) > L.vmax
        off[:-1] |= v
        off[1:] |= v
        a = np.abs(D2 @ q) > L.amax
        off[:-2] |= a
        off[1:-1] |= a
        off[2:] |= a
    lead, tilt = lead_tilt_from_axis(machine.tool_axis_np(q1, q2), task.frames)
    eps = 1e-9
    off |= (lead < lw[:, 0] - eps) | (lead > lw[:, 1] + eps) | (tilt < tw[:, 0] - eps) | (tilt > tw[:, 1] + eps)
    if ceiling is not None:
        coef, has = ceiling
        off |= has & (lead > coef[:, 0] + coef[:, 1] * tilt + coef[:, 2] * tilt ** 2 + eps)
    return off


def _move_bounds(index: MeshIndex, cut: ToroidalCutter, task: RowTask, pts: np.ndarray, q1: np.ndarray,
                 q2: np.ndarray, machine: Machine, lw: np.ndarray, floor: np.ndarray, ceiling: np.ndarray,
                 has_floor: np.ndarray, has_ceiling: np.ndarray, thr: float, steps: int) -> int:
    """Mapped points whose solution still gouges: at the solution's tilt, find by bisection the
    exact clear boundary between the solution's lead and the window's other end and move the
    floor (up) or ceiling (down) there plus REFINE_MARGIN, in place. Returns the clearance
    evaluations made."""
    k = np.flatnonzero(pts)
    fr, cc, nrm = task.frames[k], task.cc[k], task.normals[k]
    lead, tilt = lead_tilt_from_axis(machine.tool_axis_np(q1[k], q2[k]), fr)
    hi_ok = pose_clearance(index, cut, cc, nrm, fr, lw[k, 1], tilt) >= -thr
    lo_ok = ~hi_ok & (pose_clearance(index, cut, cc, nrm, fr, lw[k, 0], tilt) >= -thr)
    # bisect toward the clear end: up for a floor, down for a ceiling
    good = np.where(hi_ok, lw[k, 1], lw[k, 0])
    bad = lead.copy()
    for _ in range(steps + 2):
        mid = 0.5 * (good + bad)
        ok = pose_clearance(index, cut, cc, nrm, fr, mid, tilt) >= -thr
        good, bad = np.where(ok, mid, good), np.where(ok, bad, mid)
    p = np.stack([np.ones_like(tilt), tilt, tilt ** 2], -1)
    for side, coef, has, sign in ((hi_ok, floor, has_floor, 1.0), (lo_ok, ceiling, has_ceiling, -1.0)):
        j = k[side]
        target = good[side] + sign * REFINE_MARGIN
        fresh = ~has[j]
        now = np.sum(coef[j] * p[side], -1)
        coef[j[~fresh], 0] += sign * np.maximum(sign * (target - now), 0.0)[~fresh]
        coef[j[fresh]] = np.column_stack([target[fresh], np.zeros((int(fresh.sum()), 2))])
        has[j] = True
    return 2 * len(k) + (steps + 2) * len(k)


def lift_along_normal(index: MeshIndex, cut: ToroidalCutter, cl: np.ndarray, T: np.ndarray, normals: np.ndarray,
          delta: np.ndarray, mask: np.ndarray, tol: float) -> tuple[np.ndarray, np.ndarray]:
    """The patent's fallback (METHODS section 1, step E(3)) at the masked points: move the tool
    along the CC normal until it clears the mesh within ``tol``, by the least lift found.

    The patent's step is the gouge depth; where the obstacle is not below the tool (a wall, an
    overhang) the clearance grows slower than the lift, so later steps divide the depth by the
    measured growth per mm (a secant step, at most 10x the depth), for up to LIFT_STEPS re-checks.
    A lift that clears is then bisected down against the last one that did not, to 0.1 ``tol``.
    Returns the lift (mm) and the clearance after it (still < -tol where no lift found clears)."""
    lift = np.zeros(len(cl))
    delta = delta.copy()
    clear_at = -0.5 * tol

    def check(k: np.ndarray, h: np.ndarray) -> np.ndarray:
        return clearance(index, cut, cl[k] + h[:, None] * normals[k], T[k]).delta

    todo = np.flatnonzero(mask)
    lo = np.zeros(len(cl))  # the largest lift known not to clear
    rate = np.ones(len(cl))  # clearance gained per mm of lift, measured at the last step
    for _ in range(LIFT_STEPS):
        if todo.size == 0:
            break
        step = -delta[todo] / rate[todo] + 0.1 * tol
        before = delta[todo]
        lo[todo] = lift[todo]
        lift[todo] += step
        delta[todo] = check(todo, lift[todo])
        rate[todo] = np.clip((delta[todo] - before) / step, 0.1, 1.0)
        todo = todo[delta[todo] < clear_at]
    k = np.flatnonzero(mask & (delta >= clear_at))
    for _ in range(40):
        k = k[lift[k] - lo[k] > 0.1 * tol]
        if k.size == 0:
            break
        mid = 0.5 * (lo[k] + lift[k])
        d = check(k, mid)
        ok = d >= clear_at
        lift[k[ok]], delta[k[ok]] = mid[ok], d[ok]
        lo[k[~ok]] = mid[~ok]
    return lift, delta


def _raise_infeasible(ctx: RowContext, task: RowTask, nlp: RowNLP, lw: np.ndarray, tw: np.ndarray, q1: np.ndarray,
                      q2: np.ndarray, status: str, with_map: bool) -> None:
    """Name the binding limit of a row no program can meet (elastic re-solve); when no limit
    binds, say that the solver failed."""
    machine = ctx.machines[task.machine]
    where = f"{ctx.source}: " if ctx.source else ""
    # the user's windows alone first: what to change is then the windows (or the feed)
    b = elastic_diagnosis(machine, task.t, task.frames, task.lead_window, task.tilt_window, task.start,
                          backoff=nlp.backoff)
    own = b.binds
    if not own:
        b = elastic_diagnosis(machine, task.t, task.frames, lw, tw, task.start, backoff=nlp.backoff)
    i = min(b.point, len(task.t) - 1)
    margin = "" if b.past_machine_limit else (
        " (inside the machine's limit, but past the margin the optimiser keeps from it: "
        + (f"{50 * nlp.backoff:g}% of the span at each end)" if b.constraint.endswith("travel")
           else f"{100 * nlp.backoff:g}% of the limit)"))
    if own:  # name the user's windows there; a rate limit can also be met at a lower feed
        lo_l, hi_l = np.degrees(task.lead_window[i])
        lo_t, hi_t = np.degrees(task.tilt_window[i])
        windows = f"lead window {lo_l:g}:{hi_l:g} deg and tilt window {lo_t:g}:{hi_t:g} deg"
        hint = "" if b.constraint.endswith("travel") else "; widen the windows or lower the feed"
    else:
        windows = "lead/tilt windows" + (" and the clear regions of the accessibility map" if with_map else "")
        hint = "" if b.constraint.endswith("travel") else "; lower the feed or widen the windows"
    if b.constraint.endswith("travel"):
        detail = (f"{b.constraint} {np.degrees(machine.limits[b.constraint[0]].min):g}..."
                  f"{np.degrees(machine.limits[b.constraint[0]].max):g} deg: the {windows} need "
                  f"{b.constraint[0]} = {b.need:.6g} deg near point {i}{margin}")
    else:
        detail = (f"{b.constraint} limit {b.limit:g} {b.unit} near point {i} (t = {task.t[i]:.3f} s): the {windows} "
                  f"need at least {b.need:.4g} {b.unit} there{margin}{hint}")
    outer = machine.rotary[machine.outer_index]
    pole = task.pole
    if pole is not None and b.constraint.split()[0] == outer and pole.min() < np.radians(POLE_CONE_DEG):
        k = int(np.argmin(pole))  # a pole passage: say so, with how close it comes
        detail += (f" (a pole passage: the row's tool axis passes {np.degrees(pole[k]):.3g} deg from the {outer} axis "
                   f"at point {k}, and the windows keep it from passing through or far enough around)")
    if b.binds:
        raise InfeasibleError(f"{where}row id {task.row}: no program meets the limits; binding constraint: {detail}")
    raise InfeasibleError(f"{where}row id {task.row}: the NLP solver failed ({status}) although no limit binds (the "
                          "largest "
                          f"need, {b.need:.4g} {b.unit} of {b.constraint}, is within its limit {b.limit:g}); "
                          "please report this row as a bug")


def chunk_clearance(ctx: RowContext, poses: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """Exact clearance (mm) of a chunk of poses (tips (N, 3) mm, unit axes (N, 3)) against the
    context's mesh: the pipeline's whole-program passes, run like rows."""
    tips, axes = poses
    return clearance(_worker(ctx).index, ctx.cutter, tips, axes).delta


def plan_chunk(ctx: RowContext, rows: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]) -> list:
    """Time-optimal time laws (camsmooth.smoothing.feed.plan_row) of consecutive rows of one
    program: (row ids (N,), joints (N, 5) X Y Z mm A B rad, tips (N, 3) mm, feed (N,) mm/min);
    one RowPlan per row, on the context's first machine's limits."""
    from camsmooth.smoothing.feed import plan_row

    ids, q, tip, feed = rows
    out = []
    starts = np.flatnonzero(np.r_[True, ids[1:] != ids[:-1]])
    for a, b in zip(starts, np.r_[starts[1:], len(ids)], strict=True):
        out.append(plan_row(ctx.machines[0], q[a:b], tip[a:b], feed[a:b]))
    return out
