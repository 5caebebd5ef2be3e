"""The smoothing pipeline: surface + CC path -> smooth, interference-free A/B program.

``smooth`` is the Python API the CLI calls. Steps (METHODS section 1): local frames and
curvature-based windows (camsmooth.smoothing.orientation) -> initial axes and inverse kinematics
('none') -> the published spline method ('spline', lift-along-normal for interference) -> the
NLP ('nlp', CasADi + IPOPT, with interference fixed by tightening the window where the tool
gouges and re-solving; lift only as a reported fallback).
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.errors import InfeasibleError, InputError
from camsmooth.geometry.clearance import MeshIndex, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.paths import CCPath, check_normals_against_mesh, estimate_feed_dirs, read_cc_csv
from camsmooth.geometry.surfaces import Surface, load_surface
from camsmooth.machine.kinematics import Machine, load_machine
from camsmooth.smoothing.nlp import RowNLP, elastic_diagnosis, fd_operators, gamma, rates, spline_row
from camsmooth.smoothing.orientation import (
    Orientation,
    axis_from_lead_tilt,
    initial_orientation,
    lead_tilt_from_axis,
    local_frames,
    surface_curvature_tensors,
)
from camsmooth.smoothing.result import MethodResult, SmoothResult

METHODS = ("none", "spline", "nlp")
GOUGE_TOL = 1e-3  # mm: a delta below -GOUGE_TOL is interference (the acceptance threshold)
FIX_TOL = 2e-4  # mm: the NLP loop acts on delta below -FIX_TOL, safely inside GOUGE_TOL
# mm: a candidate orientation counts as clear at or above this clearance. The tool always
# touches the surface at its CC point, and on concave regions the mesh's flat facets sit above
# the true surface by up to the tessellation's chord error, so a perfect orientation reads about
# -(chord error) there: "clear" is "no penetration beyond what the fix loop tolerates".
CLEAR_MARGIN = -0.75 * FIX_TOL
DILATE = 3  # points on each side of a gouging point that share its raised lead bound


@dataclass
class SmoothOptions:
    """Tuning of the pipeline. spline_step: the spline method samples every spline_step-th CC
    point; max_passes: interference re-solves of the NLP; tilt_grid: (lead, tilt) candidates per
    window in the clear-orientation search."""

    spline_step: int = 10
    max_passes: int = 6
    tilt_grid: tuple[int, int] = (9, 11)
    ipopt_options: dict | None = None


def _as_path(path: CCPath | str | Path) -> CCPath:
    return path if isinstance(path, CCPath) else read_cc_csv(path)


def _as_surface(surface: Surface | str | Path) -> Surface:
    return surface if isinstance(surface, Surface) else load_surface(surface)


def _as_machine(machine: Machine | str | Path | None) -> Machine:
    return machine if isinstance(machine, Machine) else load_machine(None if machine is None else str(machine))


def row_times(points: np.ndarray, feed_mm_min: np.ndarray) -> np.ndarray:
    """t_0 = 0, t_i - t_(i-1) = |CC_i - CC_(i-1)| / F_i (s), F in mm/min (the issue's rule)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg / (feed_mm_min[1:] / 60.0))])


def smooth(path: CCPath | str | Path, surface: Surface | str | Path, machine: Machine | str | Path | None = None,
           cutter: ToroidalCutter | None = None, *, feed: float | None = None,
           lead_range: tuple[float, float] = (np.radians(2.0), np.radians(20.0)),
           tilt_range: tuple[float, float] = (np.radians(-15.0), np.radians(15.0)),
           method: str = "nlp", prefer_lead: float | None = None, prefer_tilt: float | None = None,
           model: Any = None, compensate: bool = False, options: SmoothOptions | None = None,
           progress: bool = False) -> SmoothResult:
    """Smooth a CC path on a surface (the whole pipeline; see the module docstring).

    path: CCPath or CSV file (mm; normals from the material toward the tool). surface: Surface,
    a definition (.toml) or a mesh file (.stl/.obj/.ply). machine: Machine, a machine TOML or
    None for the default AB head. cutter: ToroidalCutter (R ring radius, r corner radius, mm).
    feed: programmed feed (mm/min), used where the path has no feed column. lead_range,
    tilt_range: admissible windows (RADIANS; lead in [0, pi/2), tilt in (-pi/2, pi/2), local frame
    of METHODS section 1). method: 'none', 'spline' or 'nlp'; 'none' is always computed as the
    baseline and 'spline' whenever 'nlp' is (its warm start). model: an error model
    (camsmooth.machine.model.ErrorModel or a JSON path): the NLP then smooths and windows the
    predicted real tool axis; compensate: also solve the linear axes so the predicted real tip is
    the CL point. Returns a SmoothResult (per-method arrays and metrics).
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r} (choose from {', '.join(METHODS)})")
    if cutter is None:
        raise InputError("a cutter is required (ToroidalCutter(R, r))")
    opts = options or SmoothOptions()
    t_start = time.perf_counter()
    cc = _as_path(path)
    surf = _as_surface(surface)
    check_normals_against_mesh(cc, surf.mesh)
    nominal = _as_machine(machine)
    real = nominal
    if model is not None:
        from camsmooth.machine.model import ErrorModel

        model = model if isinstance(model, ErrorModel) else ErrorModel.from_json(model)
        real = model.apply(nominal)
    n = len(cc.points)
    if cc.feed is not None:
        feed_arr = np.asarray(cc.feed, float)
    elif feed is not None:
        if not np.isfinite(feed) or feed <= 0:
            raise InputError(f"--feed must be a positive number of mm/min, got {feed}")
        feed_arr = np.full(n, float(feed))
    else:
        raise InputError("no feed: give --feed (mm/min) or a 'feed' column in the path CSV")
    feed_dirs = cc.feed_dirs if cc.feed_dirs is not None else estimate_feed_dirs(cc.points, cc.normals, cc.rows)
    frames = local_frames(cc.normals, feed_dirs)
    index = MeshIndex(surf.mesh)
    K_s = surface_curvature_tensors(np.asarray(surf.mesh.vertices), cc.points, frames, tree=index.tree)
    slices = cc.row_slices()
    idx = np.concatenate([np.arange(s.stop - s.start) for s in slices])
    orient = initial_orientation(frames, K_s, cutter.R, cutter.r, lead_range, tilt_range, prefer_lead,
                                 prefer_tilt, point_name=lambda i: f"row {cc.rows[i]}, point {idx[i]}")
    t = np.concatenate([row_times(cc.points[s], feed_arr[s]) for s in slices])

    wanted = ["none"] + (["spline"] if method in ("spline", "nlp") else []) + (["nlp"] if method == "nlp" else [])
    ctx = _Context(cc, frames, t, idx, slices, nominal, real, cutter, index, orient, opts, model, compensate)
    results: dict[str, MethodResult] = {}
    # -- none: the initial orientation through inverse kinematics
    t0 = time.perf_counter()
    A0, B0, unreach0 = ctx.ik(orient.axis)
    results["none"] = ctx.finish("none", A0, B0, np.zeros(n), unreach0, time.perf_counter() - t0)
    if "spline" in wanted:
        t0 = time.perf_counter()
        As, Bs = np.empty(n), np.empty(n)
        for s in slices:
            As[s], Bs[s] = spline_row(A0[s], B0[s], t[s], opts.spline_step)
        lift = ctx.lift_fallback(As, Bs, np.ones(n, bool))
        results["spline"] = ctx.finish("spline", As, Bs, lift, unreach0, time.perf_counter() - t0)
    if "nlp" in wanted:
        runs = [("nlp", real)] + ([("nlp-ideal", nominal)] if model is not None else [])
        for label, mach in runs:
            results[label] = _run_nlp(ctx, mach, As, Bs, label, progress)
    return SmoothResult(methods=results, primary=method, machine=nominal, cutter=cutter, surface_mesh=surf.mesh,
                        inputs={"path": cc.source, "surface": surf.source, "feed": feed_arr,
                                "lead_range": tuple(lead_range), "tilt_range": tuple(tilt_range),
                                "model": model, "compensate": compensate, "real_machine": real,
                                "total_runtime_s": time.perf_counter() - t_start})


def _run_nlp(ctx: _Context, machine: Machine, As: np.ndarray, Bs: np.ndarray, label: str, progress: bool
             ) -> MethodResult:
    """The NLP over all rows on ``machine`` (the real one when a model is given), warm-started
    from the spline solution; one solver per row length."""
    t0 = time.perf_counter()
    n = len(As)
    An, Bn = np.empty(n), np.empty(n)
    lead_w, tilt_w = ctx.orient.lead_window.copy(), ctx.orient.tilt_window.copy()
    needs_lift = np.zeros(n, bool)
    solvers: dict[int, RowNLP] = {}
    iterator = ctx.slices
    if progress:
        from tqdm import tqdm

        iterator = tqdm(ctx.slices, desc=f"{label} rows", unit="row")
    stats = []
    for s in iterator:
        m = s.stop - s.start
        if m not in solvers:
            solvers[m] = RowNLP(machine, m, ipopt_options=ctx.opts.ipopt_options)
        a, b, lw, tw, lift_mask, st = ctx.nlp_row(solvers[m], s, As[s], Bs[s], lead_w[s], tilt_w[s])
        An[s], Bn[s], lead_w[s], tilt_w[s], needs_lift[s] = a, b, lw, tw, lift_mask
        stats.append(st)
    lift = ctx.lift_fallback(An, Bn, needs_lift)
    res = ctx.finish(label, An, Bn, lift, np.zeros(0, int), time.perf_counter() - t0, lead_w, tilt_w)
    res.metrics["ipopt_iterations"] = int(sum(st.iterations for st in stats))
    res.metrics["nlp_build_s"] = float(sum(sv.build_s for sv in solvers.values()) + sum(st.build_s for st in stats))
    res.metrics["interference_passes"] = int(max((st.passes for st in stats), default=0))
    return res


@dataclass
class _RowStats:
    iterations: int
    passes: int
    build_s: float = 0.0


class _Context:
    """Shared state of one smooth() call; methods act on whole arrays or one row slice."""

    def __init__(self, cc: CCPath, frames: np.ndarray, t: np.ndarray, idx: np.ndarray, slices: Sequence[slice],
                 nominal: Machine, real: Machine, cutter: ToroidalCutter, index: MeshIndex, orient: Orientation,
                 opts: SmoothOptions, model: Any, compensate: bool) -> None:
        self.cc, self.frames, self.t, self.idx, self.slices = cc, frames, t, idx, slices
        self.nominal, self.real, self.cutter, self.index = nominal, real, cutter, index
        self.orient, self.opts, self.model, self.compensate = orient, opts, model, compensate

    # ---- kinematics --------------------------------------------------------------------------
    def ik(self, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nominal IK row by row (nearest branch, unwrapped); unreachable point indices."""
        A, B = np.empty(len(axes)), np.empty(len(axes))
        bad = []
        prev = None
        for s in self.slices:
            r = self.nominal.solve_row(axes[s], previous=prev)
            A[s], B[s] = r.A, r.B
            prev = (r.A[-1], r.B[-1])  # a zig-zag row starts where the previous one ended
            bad.extend((r.unreachable + s.start).tolist())
        return A, B, np.asarray(bad, int)

    def axes_of(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """Tool axes the machine really produces for commanded A, B (the error model's chain
        when a model is given)."""
        return self.real.tool_axis_np(A, B)

    def delta(self, cl: np.ndarray, T: np.ndarray) -> np.ndarray:
        return clearance(self.index, self.cutter, cl, T).delta

    # ---- the NLP with the interference loop ---------------------------------------------------
    def nlp_row(self, solver: RowNLP, s: slice, A0: np.ndarray, B0: np.ndarray, lead_w: np.ndarray,
                tilt_w: np.ndarray) -> tuple[np.ndarray, ...]:
        frames, t, cc, nrm = self.frames[s], self.t[s], self.cc.points[s], self.cc.normals[s]
        row = int(self.cc.rows[s.start])
        lead_w, tilt_w = lead_w.copy(), tilt_w.copy()
        no_clean = np.zeros(len(t), bool)
        A, B = A0, B0
        iters = 0
        passes = 0
        build = 0.0
        prev_w = (lead_w.copy(), tilt_w.copy())
        for passes in range(1, self.opts.max_passes + 1):  # noqa: B007
            A_new, B_new, st = solver.solve(t, frames, A, B, lead_w, tilt_w)
            iters += st.iterations
            build += st.build_s
            if not st.success:
                viol = solver.constraint_report(t, A_new, B_new)
                if passes == 1:
                    name, i, need = elastic_diagnosis(self.real, t, frames, lead_w, tilt_w, A0, B0)
                    unit = "deg/s" if "velocity" in name else "deg/s^2"
                    lim = self.real.limits[name[0]]
                    have = np.degrees(lim.vmax if "velocity" in name else lim.amax)
                    raise InfeasibleError(
                        f"row {row}: no program meets the limits (IPOPT: {st.status}); binding constraint: "
                        f"{name} limit {have:g} {unit} near point {i} (t = {t[min(i, len(t) - 1)]:.3f} s), "
                        f"the lead/tilt windows need at least {need:.4g} {unit} there"
                        + (f"; also violated: {viol}" if viol else ""))
                # a tightened window made the row infeasible: keep the last feasible solution
                # and its windows; the fallback lift handles the remaining points
                lead_w, tilt_w = prev_w
                break
            A, B = A_new, B_new
            T = solver.machine.tool_axis_np(A, B)
            cl = cc_to_cl(self.cutter, cc, nrm, T)
            d = self.delta(cl, T)
            bad = np.flatnonzero((d < -FIX_TOL) & ~no_clean)
            if bad.size == 0:
                break
            if passes == self.opts.max_passes:
                break
            prev_w = (lead_w.copy(), tilt_w.copy())
            found = self._clear_windows(bad, s, T, lead_w, tilt_w)
            no_clean[bad[~found]] = True
        T = solver.machine.tool_axis_np(A, B)
        d = self.delta(cc_to_cl(self.cutter, cc, nrm, T), T)
        return A, B, lead_w, tilt_w, d < -FIX_TOL, _RowStats(iters, passes, build)

    def _clearance_at(self, s: slice, pts: np.ndarray, lead: np.ndarray, tilt: np.ndarray) -> np.ndarray:
        """Clearance (mm) of the tool at row-local points ``pts`` for the given lead/tilt (rad)."""
        fr = self.frames[s][pts]
        T = axis_from_lead_tilt(lead, tilt, fr)
        return self.delta(cc_to_cl(self.cutter, self.cc.points[s][pts], self.cc.normals[s][pts], T), T)

    def _clear_windows(self, bad: np.ndarray, s: slice, T: np.ndarray, lead_w: np.ndarray,
                       tilt_w: np.ndarray) -> np.ndarray:
        """Shrink the windows of gouging points toward clear orientations (in place).

        1. Lead search at the current tilt: if the window's largest lead is clear, bisect for the
           smallest clear lead and raise lead_min there (and at the DILATE neighbours on each
           side, so the next solve cannot just move the gouge next door). Rear (heel) gouging on
           concave regions, the common case, is cured this way.
        2. Otherwise a tilt search over a lead x tilt grid: the clear orientation nearest the
           current axis; the window is cut at it on the side away from the current orientation.
        Returns which points found a clear orientation.
        """
        fr = self.frames[s][bad]
        cur_l, cur_t = lead_tilt_from_axis(T[bad], fr)
        lw, tw = lead_w[bad], tilt_w[bad]
        hi_clear = self._clearance_at(s, bad, lw[:, 1], cur_t) >= CLEAR_MARGIN
        lo = np.minimum(cur_l, lw[:, 1])
        hi = lw[:, 1].copy()
        for _ in range(8):
            mid = 0.5 * (lo + hi)
            ok = self._clearance_at(s, bad, mid, cur_t) >= CLEAR_MARGIN
            hi = np.where(ok, mid, hi)
            lo = np.where(ok, lo, mid)
        need = np.minimum(hi + np.radians(0.25), lw[:, 1])
        n = len(lead_w)
        for k in np.flatnonzero(hi_clear):
            a, b = max(0, bad[k] - DILATE), min(n, bad[k] + DILATE + 1)
            lead_w[a:b, 0] = np.maximum(lead_w[a:b, 0], np.minimum(need[k], lead_w[a:b, 1] - np.radians(0.05)))
            tilt_w[bad[k]] = tw[k]
        found = hi_clear.copy()
        rest = np.flatnonzero(~hi_clear)
        if rest.size:
            found[rest] = self._tilt_search(bad[rest], s, T, lead_w, tilt_w)
        return found

    def _tilt_search(self, bad: np.ndarray, s: slice, T: np.ndarray, lead_w: np.ndarray,
                     tilt_w: np.ndarray) -> np.ndarray:
        """Grid search over the window for the clear orientation nearest the current axis; cut
        the window at it on the side away from the current orientation (in place)."""
        nl, nt = self.opts.tilt_grid
        fr = self.frames[s][bad]
        lw, tw = lead_w[bad], tilt_w[bad]
        cur_l, cur_t = lead_tilt_from_axis(T[bad], fr)
        L = lw[:, :1] + (lw[:, 1:] - lw[:, :1]) * np.repeat(np.linspace(0, 1, nl), nt)[None]
        P = tw[:, :1] + (tw[:, 1:] - tw[:, :1]) * np.tile(np.linspace(0, 1, nt), nl)[None]
        k = L.shape[1]
        d = self._clearance_at(s, np.repeat(bad, k), L.ravel(), P.ravel()).reshape(len(bad), k)
        Tc = axis_from_lead_tilt(L.ravel(), P.ravel(), np.repeat(fr, k, axis=0)).reshape(len(bad), k, 3)
        ang = np.arccos(np.clip(np.einsum("nkj,nj->nk", Tc, T[bad]), -1, 1))
        score = np.where(d >= CLEAR_MARGIN, ang, np.inf)
        best = np.argmin(score, axis=1)
        ar = np.arange(len(bad))
        found = np.isfinite(score[ar, best])
        lc, tc = L[ar, best], P[ar, best]
        eps = 1e-9
        new_l, new_t = lw.copy(), tw.copy()
        new_l[:, 0] = np.where(lc > cur_l + eps, lc, lw[:, 0])
        new_l[:, 1] = np.where(lc < cur_l - eps, lc, lw[:, 1])
        new_t[:, 0] = np.where(tc > cur_t + eps, tc, tw[:, 0])
        new_t[:, 1] = np.where(tc < cur_t - eps, tc, tw[:, 1])
        lead_w[bad] = np.where(found[:, None], new_l, lw)
        tilt_w[bad] = np.where(found[:, None], new_t, tw)
        return found

    # ---- fallback lift and assembling results -------------------------------------------------
    def lift_fallback(self, A: np.ndarray, B: np.ndarray, mask: np.ndarray) -> np.ndarray:
        """The patent's fallback (METHODS section 1, step E(3)): where delta < -FIX_TOL, move the
        tool along the CC normal by |delta|, re-check, repeat (up to 5 times). Returns the lift
        per point (mm)."""
        T = self.axes_of(A, B)
        cl = cc_to_cl(self.cutter, self.cc.points, self.cc.normals, T)
        lift = np.zeros(len(A))
        todo = np.flatnonzero(mask)
        for _ in range(5):
            if todo.size == 0:
                break
            d = self.delta(cl[todo] + lift[todo, None] * self.cc.normals[todo], T[todo])
            bad = d < -FIX_TOL
            if not bad.any():
                break
            todo = todo[bad]
            lift[todo] += -d[bad] + FIX_TOL
        return lift

    def finish(self, method: str, A: np.ndarray, B: np.ndarray, lift: np.ndarray, unreachable: np.ndarray,
               runtime: float, lead_w: np.ndarray | None = None, tilt_w: np.ndarray | None = None) -> MethodResult:
        lead_w = self.orient.lead_window if lead_w is None else lead_w
        tilt_w = self.orient.tilt_window if tilt_w is None else tilt_w
        T = self.axes_of(A, B)
        cc, nrm = self.cc.points, self.cc.normals
        cl = cc_to_cl(self.cutter, cc, nrm, T) + lift[:, None] * nrm
        xyz_nominal = self.nominal.linear_axes(cl, self.nominal.tool_axis_np(A, B))
        xyz = _linear_axes_for_tip(self.real, A, B, cl) if (self.compensate and self.model is not None) \
            else xyz_nominal
        # the tool really sits at the predicted real tip: check clearance there
        tip_real = self.real.tool_pose_np(A, B, *xyz.T)[0] if self.model is not None else cl
        delta = self.delta(tip_real, T)
        lead, tilt = lead_tilt_from_axis(T, self.frames)
        n = len(A)
        A_vel, B_vel, A_acc, B_acc = (np.empty(n) for _ in range(4))
        comp = np.empty(n)
        g = 0.0
        for s in self.slices:
            A_vel[s], A_acc[s] = rates(A[s], self.t[s])
            B_vel[s], B_acc[s] = rates(B[s], self.t[s])
            _, acc = rates(T[s], self.t[s])
            comp[s] = np.linalg.norm(acc, axis=1)
            g += gamma(T[s], self.t[s])
        res = MethodResult(method, self.cc.rows.copy(), self.idx.copy(), self.t.copy(), cc, nrm, cl, T, lead, tilt,
                           A, B, A_vel, B_vel, A_acc, B_acc, xyz, delta, lift, lead_w.copy(), tilt_w.copy(), comp,
                           feed_dirs=self.frames[:, :, 0].copy())
        res.metrics = self.metrics(res, g, unreachable, runtime)
        if self.model is not None:
            # ideal (the intended CL point and the axis the ideal machine would give for the
            # same A, B) against the predicted real machine, with and without compensation
            tip_unc = self.real.tool_pose_np(A, B, *xyz_nominal.T)[0]
            ideal_axis = self.nominal.tool_axis_np(A, B)
            res.metrics["tip_error_um_max"] = float(1e3 * np.max(np.linalg.norm(tip_real - cl, axis=1)))
            res.metrics["tip_error_um_max_uncompensated"] = float(
                1e3 * np.max(np.linalg.norm(tip_unc - cl, axis=1)))
            res.metrics["axis_error_urad_max"] = float(1e6 * np.max(np.arccos(np.clip(
                np.sum(ideal_axis * T, axis=1), -1, 1))))
            res.metrics["compensated"] = bool(self.compensate)
        return res

    def metrics(self, r: MethodResult, g: float, unreachable: np.ndarray, runtime: float) -> dict[str, Any]:
        """Summary: gamma (1/s^4), peaks (deg/s^2), min delta (mm), violation counts per
        constraint (samples outside the TRUE limits, the definitions of camsmooth.smoothing.nlp)."""
        lim = self.nominal.limits
        viol: dict[str, int] = {}
        for name, q in (("A", r.A), ("B", r.B)):
            L = lim[name]
            viol[f"{name} travel"] = int(np.sum((q > L.max + 1e-9) | (q < L.min - 1e-9)))
            nv = na = 0
            for s in self.slices:
                D1, D2 = fd_operators(self.t[s])
                nv += int(np.sum(np.abs(D1 @ q[s]) > L.vmax * (1 + 1e-9)))
                na += int(np.sum(np.abs(D2 @ q[s]) > L.amax * (1 + 1e-9)))
            viol[f"{name} velocity"] = nv
            viol[f"{name} acceleration"] = na
        tol = 1e-6
        viol["lead window"] = int(np.sum((r.lead < r.lead_window[:, 0] - tol) | (r.lead > r.lead_window[:, 1] + tol)))
        viol["tilt window"] = int(np.sum((r.tilt < r.tilt_window[:, 0] - tol) | (r.tilt > r.tilt_window[:, 1] + tol)))
        viol["interference"] = int(np.sum(r.delta < -GOUGE_TOL))
        unclean = sorted({int(x) for x in r.rows[(r.delta < -GOUGE_TOL) | (r.lift > 0)]})
        return {
            "gamma": g,
            "peak_A_acc": float(np.degrees(np.max(np.abs(r.A_acc)))),
            "peak_B_acc": float(np.degrees(np.max(np.abs(r.B_acc)))),
            "min_delta": float(np.min(r.delta)),
            "violations": viol,
            "lifted_points": int(np.sum(r.lift > 0)),
            "unclean_rows": unclean,
            "unreachable": [(int(r.rows[i]), int(r.idx[i])) for i in unreachable],
            "runtime_s": runtime,
        }


def _linear_axes_for_tip(machine: Machine, A: np.ndarray, B: np.ndarray, tip: np.ndarray) -> np.ndarray:
    """X, Y, Z (mm) that put the predicted tool tip of ``machine`` at ``tip`` for the given
    A, B. The linear axes enter the POE chain as prismatic joints, so the tip is affine in
    (X, Y, Z): solve the 3x3 system per point from the chain itself (columns by unit steps)."""
    z = np.zeros_like(A)
    p0, _ = machine.tool_pose_np(A, B, z, z, z)
    cols = [machine.tool_pose_np(A, B, *(z + (k == j) for j in range(3)))[0] - p0 for k in range(3)]
    J = np.stack(cols, axis=-1)  # (N, 3, 3)
    return np.linalg.solve(J, (tip - p0)[..., None])[..., 0]
