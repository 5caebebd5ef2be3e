"""The smoothing pipeline: a CC path on a surface -> smooth, clear A/B programs.

``smooth`` is the Python API the CLI calls; it takes objects (CCPath, Surface, Machine,
ToroidalCutter, ErrorModel), not paths. Steps (METHODS section 1):

1. ``prepare``: local frames, time stamps from the programmed feed, curvature-based windows and
   the initial (locally gouge-free) orientation (camsmooth.smoothing.orientation);
2. 'none': that orientation through inverse kinematics;
3. 'spline': the published method: A and B sampled every ``spline_step``-th point, cubic
   splines, and the lift along the normal where the tool gouges (METHODS section 1, E(3));
4. 'nlp': the NLP per row with the tool's clearance inside the optimisation
   (camsmooth.smoothing.rows: accessibility map, constraints, exact verification), rows in
   parallel on all cores or on Dask (camsmooth.smoothing.parallel) with the serial run's results.

Every clearance decision uses the user's ``tolerance`` (mm): a clearance below -tolerance is a
gouge. The mesh's chord deviation is estimated (camsmooth.geometry.surfaces.chord_deviation) and
a tolerance below it is named in ``SmoothResult.warnings``: on concave regions the mesh's chords
lie above the true surface by up to that much, so a tool touching the true surface reads as
gouging the mesh. Units: mm, s, rad; workpiece frame.
"""

from __future__ import annotations

import time
import uuid
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from camsmooth.constants import DEFAULT_TOLERANCE_MM
from camsmooth.errors import InputError
from camsmooth.geometry.clearance import MeshIndex
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.paths import CCPath, check_contact_with_mesh, check_normals_against_mesh, estimate_feed_dirs
from camsmooth.geometry.surfaces import Surface, chord_deviation
from camsmooth.machine.axes import PerAxis, RotaryValues
from camsmooth.machine.kinematics import Machine, load_machine
from camsmooth.progress import Steps
from camsmooth.smoothing.cam import CamProgram
from camsmooth.smoothing.evaluate import axis_violations, gamma_of
from camsmooth.smoothing.finish import lead_ceiling, neighbour_stepover, point_scallop
from camsmooth.smoothing.nlp import program_rates, spline_row
from camsmooth.smoothing.orientation import (
    Orientation,
    initial_orientation,
    lead_tilt_from_axis,
    local_frames,
    surface_curvature_tensors,
)
from camsmooth.smoothing.parallel import RowPool, default_workers
from camsmooth.smoothing.pole import PolePassage, find_passages, pole_start
from camsmooth.smoothing.result import (
    FeedPeak,
    JointPeak,
    MethodResult,
    Metrics,
    PointNote,
    ScallopMiss,
    SmoothResult,
    interferes,
)
from camsmooth.smoothing.rows import (
    RowContext,
    RowOptions,
    RowSolution,
    RowTask,
    adopt_index,
    chunk_clearance,
    lift_along_normal,
    plan_chunk,
    solve_row,
)

__all__ = ["DEFAULT_TOLERANCE_MM", "METHODS", "Program", "ProgramSmoother", "SmoothOptions", "prepare", "row_times",
           "smooth"]

METHODS = ("none", "spline", "nlp")
PARALLEL_MIN_POINTS = 5000  # below this a program runs serially by default (worker start-up ~1-2 s)
CHUNK = 20000  # poses per task of a whole-program clearance pass


@dataclass(frozen=True)
class SmoothOptions:
    """Tuning of the pipeline: spline_step (the spline method samples every spline_step-th CC
    point), the row solver's options, workers (processes; None: all cores for programs of
    PARALLEL_MIN_POINTS points or more, else 1; the command line's default) and dask (None,
    "local" or a scheduler address: rows on a Dask cluster). More than one worker starts
    processes the forkserver way: a script calling ``smooth`` then needs the usual
    ``if __name__ == "__main__":`` guard, which is why the API's default is one. max_scallop (mm):
    the scallop 'nlp' may leave at any point (camsmooth.smoothing.finish; None: no bound);
    cam_scallop: when the input is a CAM program with its own axes, 'nlp''s scallop may exceed the
    CAM program's at no point by more than the tolerance (the tighter of the two applies);
    hold_feed: on a controller camsmooth models (LinuxCNC), the blocks are also held so that its
    planner's blends never take the tool tip faster than the programmed feed (they can: in a
    parabolic blend both blocks move; camsmooth.controller.blocks.tip_speed_over)."""

    spline_step: int = 10
    rows: RowOptions = field(default_factory=RowOptions)
    workers: int | None = 1
    dask: str | None = None
    max_scallop: float | None = None  # mm: the finish budget of 'nlp' at every point (camsmooth.smoothing.finish)
    cam_scallop: bool = True  # with a CAM program: 'nlp' no rougher than it anywhere, within the tolerance
    hold_feed: bool = False  # a modelled controller's blends kept from taking the tool tip past the programmed feed


def row_times(points: np.ndarray, feed_mm_min: np.ndarray) -> np.ndarray:
    """t_0 = 0, t_i - t_(i-1) = |CC_i - CC_(i-1)| / F_i (s), F in mm/min (the issue's rule)."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(seg / (feed_mm_min[1:] / 60.0))])


@dataclass(frozen=True)
class Program:
    """A CC path ready for smoothing: the path, its local frames (N, 3, 3) (columns X_L, Y_L, n),
    time stamps t (N,) s from each row's start at the programmed feed (N,) mm/min, the index of
    each point within its row, the row slices and the initial orientation with its windows."""

    path: CCPath
    frames: np.ndarray
    t: np.ndarray
    feed: np.ndarray
    idx: np.ndarray
    slices: tuple[slice, ...]
    orientation: Orientation
    curvature: np.ndarray | None = None  # (N, 2, 2) the surface's curvature tensors (1/mm, basis X_L, Y_L)
    stepover: np.ndarray | None = None  # (N, 2) mm to the previous and the next row (camsmooth.smoothing.finish)

    def __len__(self) -> int:
        return len(self.t)

    def name(self, i: int) -> str:
        """How messages name point i: by its row id and index within the row."""
        return f"row {int(self.path.rows[i])}, point {int(self.idx[i])}"


def prepare(path: CCPath, index: MeshIndex, cutter: ToroidalCutter, feed: float | None,
            lead_range: tuple[float, float], tilt_range: tuple[float, float], prefer_lead: float | None = None,
            prefer_tilt: float | None = None) -> Program:
    """Frames, times and the initial orientation of a CC path on a mesh (steps 1 of the module
    docstring). Angles rad; feed mm/min, used where the path has no feed column."""
    n = len(path.points)
    if path.feed is not None:
        feed_arr = np.asarray(path.feed, float)
    elif feed is not None:
        if not np.isfinite(feed) or feed <= 0:
            raise InputError(f"--feed must be a positive number of mm/min, got {feed}")
        feed_arr = np.full(n, float(feed))
    else:
        raise InputError("no feed: give --feed (mm/min) or a 'feed' column in the path CSV")
    feed_dirs = path.feed_dirs if path.feed_dirs is not None else estimate_feed_dirs(path.points, path.normals,
                                                                                      path.rows)
    frames = local_frames(path.normals, feed_dirs)
    K_s = surface_curvature_tensors(index.vertices, path.points, frames, tree=index.tree)
    slices = tuple(path.row_slices())
    idx = np.concatenate([np.arange(s.stop - s.start) for s in slices])
    orient = initial_orientation(frames, K_s, cutter.R, cutter.r, lead_range, tilt_range, prefer_lead, prefer_tilt,
                                 point_name=lambda i: f"row {path.rows[i]}, point {idx[i]}")
    t = np.concatenate([row_times(path.points[s], feed_arr[s]) for s in slices])
    step = neighbour_stepover(path.points, path.rows, reach=2.0 * (cutter.R + cutter.r))
    return Program(path=path, frames=frames, t=t, feed=feed_arr, idx=idx, slices=slices, orientation=orient,
                   curvature=K_s, stepover=step)


def smooth(path: CCPath | CamProgram, surface: Surface, machine: Machine | None = None,
           cutter: ToroidalCutter | None = None, *,
           feed: float | None = None,
           lead_range: tuple[float, float] = (np.radians(2.0), np.radians(20.0)),
           tilt_range: tuple[float, float] = (np.radians(-15.0), np.radians(15.0)),
           method: str = "nlp", prefer_lead: float | None = None, prefer_tilt: float | None = None,
           model: Any = None, compensate: bool = False, tolerance: float = DEFAULT_TOLERANCE_MM,
           options: SmoothOptions | None = None, progress: bool = False) -> SmoothResult:
    """Smooth a CC path on a surface (the whole pipeline; see the module docstring).

    path: CCPath (mm; normals from the material toward the tool), or a CamProgram (a CAM system's
    CL program on this surface, camsmooth.smoothing.cam.cam_program: its own axes then appear as
    the method 'cam'). surface: Surface (its mesh).
    machine: Machine (None: the default AB head). cutter: ToroidalCutter (R ring radius, r corner
    radius, mm). feed: programmed feed (mm/min), used where the path has no feed column.
    lead_range, tilt_range: admissible windows (RADIANS; lead in [0, pi/2), tilt in (-pi/2, pi/2),
    local frame of METHODS section 1). method: 'none', 'spline' or 'nlp'; 'none' is always
    computed as the baseline and 'spline' whenever 'nlp' is (its warm start). model: an error
    model (camsmooth.machine.model.ErrorModel): the NLP then smooths and windows the predicted
    real tool axis; compensate: also solve the linear axes so the predicted real tip is the CL
    point. tolerance: mm, the part's allowed deviation, used for every clearance decision.
    Returns a SmoothResult (per-method arrays and metrics).
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r} (choose from {', '.join(METHODS)})")
    cam = None
    if isinstance(path, CamProgram):
        cam, path = path, path.path
    if not isinstance(path, CCPath):
        raise InputError(f"path must be a CCPath (read one with camsmooth.io.ccpath.read_cc_csv) or a CamProgram, "
                         f"got {type(path).__name__}")
    if not isinstance(surface, Surface):
        raise InputError(f"surface must be a Surface (load one with camsmooth.geometry.surfaces.load_surface), "
                         f"got {type(surface).__name__}")
    if cutter is None:
        raise InputError("a cutter is required (ToroidalCutter(R, r))")
    if not (np.isfinite(tolerance) and tolerance > 0):
        raise InputError(f"tolerance must be a positive length in mm, got {tolerance}")
    opts = options or SmoothOptions()
    t_start = time.perf_counter()
    check_contact_with_mesh(path, surface.mesh)
    check_normals_against_mesh(path, surface.mesh, mesh_file=surface.source)
    nominal = machine if machine is not None else load_machine(None)
    real = nominal
    if model is not None:
        real = model.apply(nominal)
    # progress: one line naming the step (camsmooth.progress; shown on a terminal only)
    steps = Steps(3 + (cam is not None) + (method != "none") + (method == "nlp") * (1 + (model is not None)),
                  enabled=progress)
    with steps.step("mesh index, orientation windows"):
        index = MeshIndex(surface.mesh)
        program = prepare(path, index, cutter, feed, lead_range, tilt_range, prefer_lead, prefer_tilt)
    chord = chord_deviation(surface)
    warnings = cam.warnings() if cam is not None else []
    if chord > tolerance:
        warnings.append(f"the mesh's chord deviation (estimated {chord:.4g} mm) exceeds the tolerance "
                        f"({tolerance:g} mm): on concave regions a tool on the true surface reads as gouging the "
                        "mesh by up to that much; export the mesh finer or raise --tolerance")
    n = len(program)
    workers = opts.workers if opts.workers is not None else (default_workers() if n >= PARALLEL_MIN_POINTS else 1)
    results: dict[str, MethodResult] = {}
    with ProgramSmoother(program, index, nominal, real, cutter, tolerance, opts, workers=workers, model=model,
                         compensate=compensate) as sm:
        if cam is not None:
            with steps.step("cam: the CAM's own axes"):
                results["cam"] = sm.cam(cam)
        with steps.step("none: inverse kinematics, clearance"):
            results["none"] = none = sm.none()
        if method in ("spline", "nlp"):
            with steps.step("spline"):
                results["spline"], spline_gouge = sm.spline(none)
        sm.budget = scallop_budget(opts, results.get("cam"), tolerance, n)
        if method == "nlp":
            risk = (none.delta < -tolerance) | spline_gouge
            with steps.step("nlp"):
                results["nlp"] = sm.nlp(results["spline"], risk, "nlp", progress, exact=none)
            if model is not None:
                with steps.step("nlp-ideal"):
                    results["nlp-ideal"] = sm.nlp(results["spline"], risk, "nlp-ideal", progress, exact=none)
        with steps.step("time laws"):
            for r in results.values():
                sm.plan(r)
    steps.close()
    for r in results.values():
        r.metrics.chord_deviation_mm = chord
    return SmoothResult(methods=results, primary=method, machine=nominal, cutter=cutter, surface_mesh=surface.mesh,
                        warnings=warnings,
                        inputs={"path": path.source, "surface": surface.source, "feed": program.feed,
                                "lead_range": tuple(lead_range), "tilt_range": tuple(tilt_range), "model": model,
                                "compensate": compensate, "real_machine": real, "tolerance": tolerance,
                                "chord_deviation": chord, "max_scallop": opts.max_scallop,
                                "total_runtime_s": time.perf_counter() - t_start})


def scallop_budget(options: SmoothOptions, cam: MethodResult | None, tolerance: float, n: int) -> np.ndarray | None:
    """The scallop (mm) 'nlp' may leave per point: ``options.max_scallop`` and, with a CAM
    program (its result ``cam``) and ``options.cam_scallop``, the CAM program's own scallop plus
    the tolerance (mm), whichever is smaller (inf where neither applies); None when neither
    applies anywhere."""
    limit = np.full(n, np.inf)
    if options.max_scallop is not None:
        if not (np.isfinite(options.max_scallop) and options.max_scallop > 0):
            raise InputError(f"the scallop budget must be a positive length in mm, got {options.max_scallop}")
        limit[:] = float(options.max_scallop)
    if cam is not None and options.cam_scallop and cam.scallop is not None:
        own = np.where(np.isfinite(cam.scallop), cam.scallop + tolerance, np.inf)
        limit = np.minimum(limit, own)
    return limit if np.isfinite(limit).any() else None


#: a point misses its finish budget when its scallop exceeds it by more than this (mm)
BUDGET_SLACK_MM = 1e-5


def budget_misses(res: MethodResult, budget: np.ndarray) -> list[ScallopMiss]:
    """Per row, where the method's scallop exceeds the budget (mm) by more than BUDGET_SLACK_MM:
    the worst point, its scallop and budget (um) and how many points miss."""
    over = np.asarray(res.scallop, float) - budget
    with np.errstate(invalid="ignore"):
        bad = over > BUDGET_SLACK_MM
    out = []
    for row in np.unique(res.rows[bad]):
        k = np.flatnonzero(bad & (res.rows == row))
        i = k[np.argmax(over[k])]
        out.append(ScallopMiss(row=int(row), idx=int(res.idx[i]), scallop_um=float(1e3 * res.scallop[i]),
                               budget_um=float(1e3 * budget[i]), points=len(k)))
    return out


class ProgramSmoother:
    """The methods over one prepared program: 'none', 'spline' and 'nlp' (module docstring),
    their clearance checks and their results. A context manager: worker processes (or the Dask
    client) live until it closes."""

    def __init__(self, program: Program, index: MeshIndex, nominal: Machine, real: Machine, cutter: ToroidalCutter,
                 tolerance: float, options: SmoothOptions, *, workers: int = 1, model: Any = None,
                 compensate: bool = False) -> None:
        self.program, self.index, self.nominal, self.real = program, index, nominal, real
        self.cutter, self.tolerance, self.options = cutter, float(tolerance), options
        self.model, self.compensate = model, compensate
        machines = (real,) if real is nominal else (real, nominal)
        self.ctx = RowContext(machines=machines, cutter=cutter, vertices=index.vertices, faces=index.faces,
                              tolerance=self.tolerance, options=options.rows, key=uuid.uuid4().hex,
                              source=program.path.source)
        self.pool = RowPool(self.ctx, workers=workers, dask=options.dask)
        self.budget: np.ndarray | None = None  # (N,) mm: the finish budget of 'nlp' (``scallop_budget``)
        adopt_index(self.ctx, index)  # rows run here (serially) share this process's search structure

    def __enter__(self) -> ProgramSmoother:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, *exc: object) -> None:
        self.pool.close(abort=exc_type is not None)

    # ---- building blocks ------------------------------------------------------------------------
    def ik(self, axes: np.ndarray) -> tuple[RotaryValues, np.ndarray]:
        """Nominal inverse kinematics row by row (nearest branch, unwrapped), each row starting
        from the previous row's end (a zig-zag row starts where the last one ended). Returns the
        rotary angles (rad, named by the machine's axes) and the indices of unreachable points."""
        q = np.empty((len(axes), 2))
        bad = []
        prev = None
        for s in self.program.slices:
            r = self.nominal.solve_row(axes[s], previous=prev)
            q[s] = r.rotary.values
            prev = (r.rotary.first[-1], r.rotary.second[-1])
            bad.extend((r.unreachable + s.start).tolist())
        return RotaryValues(self.nominal.rotary, q), np.asarray(bad, int)

    def clearance(self, tips: np.ndarray, axes: np.ndarray) -> np.ndarray:
        """Exact clearance (mm) of many poses: in chunks on the workers when there are many."""
        n = len(tips)
        if not self.pool.parallel or n < 2 * CHUNK:
            return chunk_clearance(self.ctx, (tips, axes))
        parts = [(tips[k:k + CHUNK], axes[k:k + CHUNK]) for k in range(0, n, CHUNK)]
        return np.concatenate(self.pool.map(chunk_clearance, parts))

    def cl_points(self, axes: np.ndarray) -> np.ndarray:
        """Tool tips (mm) touching every CC point with the given axes (METHODS section 1, CC -> CL)."""
        return cc_to_cl(self.cutter, self.program.path.points, self.program.path.normals, axes)

    def _lift(self, axes: np.ndarray, delta: np.ndarray, mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The patent's lift along the normal (METHODS section 1, E(3)) at the masked points, with
        the clearance after it."""
        return lift_along_normal(self.index, self.cutter, self.cl_points(axes), axes, self.program.path.normals,
                                 delta, mask, self.tolerance)

    # ---- the methods --------------------------------------------------------------------------------
    def cam(self, cam: CamProgram) -> MethodResult:
        """The CAM system's own program: its axes through inverse kinematics, its tool tips."""
        t0 = time.perf_counter()
        q, unreachable = self.ik(cam.axes)
        return self._result("cam", q, delta=None, lift=np.zeros(len(q)), unreachable=unreachable,
                            runtime=time.perf_counter() - t0, cl=cam.tips)

    def none(self) -> MethodResult:
        """The initial orientation through inverse kinematics, as it is."""
        t0 = time.perf_counter()
        q, unreachable = self.ik(self.program.orientation.axis)
        T = self.real.tool_axis_np(*q.pair)
        delta = self.clearance(self.cl_points(T), T)
        self.unreachable = unreachable
        return self._result("none", q, delta=delta, lift=np.zeros(len(q)), unreachable=unreachable,
                            runtime=time.perf_counter() - t0)

    def spline(self, none: MethodResult) -> tuple[MethodResult, np.ndarray]:
        """The published spline method, lifted where it gouges. Returns the result and where the
        spline's poses gouged before the lift."""
        t0 = time.perf_counter()
        n = len(self.program)
        q = RotaryValues.zeros(none.rotary.names, n)
        for s in self.program.slices:
            q.values[s, 0], q.values[s, 1] = spline_row(none.rotary.first[s], none.rotary.second[s],
                                                        self.program.t[s], self.options.spline_step)
        T = self.real.tool_axis_np(*q.pair)
        delta = self.clearance(self.cl_points(T), T)
        gouge = delta < -self.tolerance
        lift, delta = self._lift(T, delta, gouge) if gouge.any() else (np.zeros(n), delta)
        res = self._result("spline", q, delta=delta, lift=lift, unreachable=self.unreachable,
                           runtime=time.perf_counter() - t0)
        return res, gouge

    def nlp(self, warm: MethodResult, risk: np.ndarray, label: str, progress: bool = False,
            exact: MethodResult | None = None) -> MethodResult:
        """The NLP over every row (camsmooth.smoothing.rows.solve_row) on the real machine
        (``label`` 'nlp') or the nominal one ('nlp-ideal'), warm-started from ``warm``; rows that
        pass the pole start from ``camsmooth.smoothing.pole.pole_start`` on ``exact`` (the exact
        inverse, the 'none' program), and the result names every passage (``Metrics.pole``)."""
        t0 = time.perf_counter()
        p, o = self.program, self.program.orientation
        machine = 0 if label == "nlp" else 1
        q0 = warm.rotary
        pole = self.nominal.pole_angle(o.axis)
        passages = []
        if exact is not None:
            exact_q = exact.rotary.values
            passages = find_passages(self.nominal, o.axis, p.path.rows, p.t, exact_q)
            if passages:
                start = pole_start(self.nominal, o.axis, p.path.rows, p.t, exact_q)
                pole_rows = np.isin(p.path.rows, [q.row for q in passages])
                q0 = RotaryValues(q0.names, np.where(pole_rows[:, None], start, q0.values))
        cap = None
        if self.budget is not None:
            cap = lead_ceiling(self.cutter, self.budget, p.curvature, p.stepover, o.lead_window, o.tilt_window)
        tasks = [RowTask(row=int(p.path.rows[s.start]), t=p.t[s], frames=p.frames[s], cc=p.path.points[s],
                         normals=p.path.normals[s], lead_window=o.lead_window[s], tilt_window=o.tilt_window[s],
                         start=q0.take(s), risk=risk[s], machine=machine, pole=pole[s],
                         lead_cap=None if cap is None else cap.ceiling[s], has_cap=None if cap is None else cap.has[s])
                 for s in p.slices]
        sols: list[RowSolution] = self.pool.map(solve_row, tasks, progress=f"{label} rows" if progress else None)
        cat = lambda name: np.concatenate([getattr(s, name) for s in sols])  # noqa: E731
        q = RotaryValues(q0.names, np.concatenate([s.rotary.values for s in sols]))
        delta, lift = cat("delta"), cat("lift")
        if self.model is not None:
            delta = None  # measured at the predicted real tip in _result
        res = self._result(label, q, delta=delta, lift=lift, unreachable=np.zeros(0, int),
                           runtime=time.perf_counter() - t0, lead_window=cat("lead_window"),
                           tilt_window=cat("tilt_window"))
        res.lead_clear = cat("lead_clear")
        blocked, unreach, mapped = cat("blocked"), cat("unreachable_clear"), cat("mapped")
        best = cat("best_delta")
        m = res.metrics
        m.ipopt_iterations = int(sum(s.iterations for s in sols))
        m.rounds_max = int(max((s.rounds for s in sols), default=0))
        m.mapped_points = int(mapped.sum())
        m.clearance_evals = int(sum(s.clearance_evals for s in sols))
        m.nlp_solve_s = float(sum(s.solve_s for s in sols))
        m.map_s = float(sum(s.map_s for s in sols))
        m.check_s = float(sum(s.check_s for s in sols))
        name = self._point_names
        m.blocked = [PointNote(point=name(i), row=int(p.path.rows[i]), idx=int(p.idx[i]), lift_mm=float(lift[i]),
                               best_clearance_mm=float(best[i])) for i in np.flatnonzero(blocked & (lift > 0))]
        m.unreachable_clear = [PointNote(point=name(i), row=int(p.path.rows[i]), idx=int(p.idx[i]),
                                         lift_mm=float(lift[i])) for i in np.flatnonzero(unreach)]
        if passages:
            m.pole = self._pole_costs(passages, res.axis, exact.axis)
        if self.budget is not None:
            m.scallop_budget_um = float(1e3 * np.min(self.budget))
            m.scallop_missed = budget_misses(res, self.budget)
        return res

    def _pole_costs(self, passages: list[PolePassage], T: np.ndarray, T_exact: np.ndarray) -> list[PolePassage]:
        """Each passage with its cost in Gamma: sum of |T''|^2 (1/s^4, programmed-feed time) over
        its points, the smoothed program's T minus the exact inverse's (camsmooth.smoothing.pole)."""
        p = self.program
        sec = program_rates(T, p.t, p.path.rows)
        sec0 = program_rates(T_exact, p.t, p.path.rows)
        g, g0 = np.zeros(len(p)), np.zeros(len(p))
        g[sec.mid], g0[sec0.mid] = np.sum(sec.sec ** 2, axis=1), np.sum(sec0.sec ** 2, axis=1)
        out = []
        starts = {int(p.path.rows[s.start]): s.start for s in p.slices}
        for q in passages:
            k = slice(starts[q.row] + q.first, starts[q.row] + q.last + 1)
            out.append(replace(q, gamma_cost=float(g[k].sum() - g0[k].sum())))
        return out

    def plan(self, r: MethodResult) -> None:
        """The time-optimal time law of a method's program under every axis's limits and the
        programmed feed (camsmooth.smoothing.feed), rows in chunks on the workers, and the
        controller's timing of it (camsmooth.smoothing.evaluate.time_law); sets ``r.plan``,
        ``r.controller`` and the metrics' cycle times, limiting and the headline violations, under
        the planned law (in place: the result is being built)."""
        from camsmooth.smoothing.evaluate import axis_violations, time_law
        from camsmooth.smoothing.feed import combine

        p = self.program
        q = np.column_stack([r.xyz, r.rotary.values])
        tip = self.real.tool_pose_np(*r.rotary.pair, *r.xyz.T)[0] if self.model is not None else r.cl
        cuts = [0]  # whole rows, about CHUNK points a task
        for s in p.slices:
            if s.stop - cuts[-1] >= CHUNK:
                cuts.append(s.stop)
        if cuts[-1] != len(p):
            cuts.append(len(p))
        parts = [(p.path.rows[a:b], q[a:b], tip[a:b], p.feed[a:b]) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
        plans = [x for part in self.pool.map(plan_chunk, parts) for x in part]
        plan = combine([int(p.path.rows[s.start]) for s in p.slices], plans)
        law = time_law(self.nominal, p.path.rows, q, tip, p.feed, tolerance=self.tolerance, plan=plan, real=self.real,
                       hold_feed=self.options.hold_feed)
        r.plan, r.controller = plan, law.controller
        m = r.metrics
        m.cycle_time_optimal_s = law.cycle_time_optimal
        m.row_cycle_time_optimal_s = law.row_cycle_time_optimal.tolist()
        m.limiting = law.limiting
        m.cycle_time_s = law.cycle_time
        m.row_cycle_time_s = law.row_cycle_time.tolist()
        if law.controller is not None:
            m.controller = law.controller.controller
            m.blocks = law.controller.blocks
            m.controller_deviation_mm = float(np.max(law.controller.row_deviation, initial=0.0))
            peak = law.controller.row_joint_peak
            if peak is not None:  # LinuxCNC's own blends past a joint's limit, by more than 1%
                names = list(self.nominal.joint_names)
                m.controller_joint_peaks = [JointPeak(int(law.controller.row_ids[r]), names[int(np.argmax(peak[r]))],
                                                      float(peak[r].max()))
                                            for r in np.flatnonzero(peak.max(axis=1) > 1.01)]
            fp = law.controller.row_feed_peak
            if fp is not None and np.any(fp > 1.01):  # the blends take the tip past the programmed feed
                worst = int(np.nanargmax(fp))
                m.controller_feed_peak = FeedPeak(int(law.controller.row_ids[worst]), float(fp[worst]),
                                                  int(np.sum(fp > 1.01)))
            if law.controller.row_floor is not None:
                m.controller_floor_s = law.controller.floor
                m.row_controller_floor_s = law.controller.row_floor.tolist()
            m.controller_end_offset_mm = law.controller.end_offset
        if law.tcp is not None:  # both LinuxCNC modes (camsmooth.controller.tcp)
            m.tcp_cycle_time_s = float(law.tcp.cycle_time)
            m.row_tcp_cycle_time_s = np.asarray(law.tcp.row_cycle_time, float).tolist()
            m.tcp_floor_s = law.tcp.floor
            m.row_tcp_floor_s = [] if law.tcp.row_floor is None else np.asarray(law.tcp.row_floor, float).tolist()
            m.tcp_within_limits = law.tcp.within_limits
            m.machine_cycle_time_s = float(law.machine_mode.cycle_time)
            m.machine_floor_s = law.machine_mode.floor
        viol, peaks = axis_violations(self.nominal, q, law.t_plan, p.path.rows)
        m.violations = {**viol, **{k: v for k, v in m.violations_programmed.items() if k not in viol}}
        names = r.rotary.names
        m.peak_acc_plan = PerAxis(names, tuple(float(np.degrees(peaks[f"{n} acceleration"])) for n in names))

    def _point_names(self, i: int) -> str:
        return self.program.name(i)

    # ---- results ------------------------------------------------------------------------------------
    def _result(self, method: str, q: RotaryValues, *, delta: np.ndarray | None, lift: np.ndarray,
                unreachable: np.ndarray, runtime: float, lead_window: np.ndarray | None = None,
                tilt_window: np.ndarray | None = None, cl: np.ndarray | None = None) -> MethodResult:
        """The program a method commands (q: the rotary axes, rad; lift mm), as the real machine executes it: the
        tool axis of the error model's chain when there is a model (so 'nlp-ideal' shows what an
        ideal-machine program does on the real one), clearance at the predicted real tip. ``cl``:
        the tool tips when the program gives them (the CAM's own), else from the CC points."""
        p, o = self.program, self.program.orientation
        A, B = q.pair  # the machine's first and second rotary axis (rad)
        T = self.real.tool_axis_np(A, B)
        cc, nrm = p.path.points, p.path.normals
        cl = (self.cl_points(T) if cl is None else cl) + lift[:, None] * nrm
        xyz_nominal = self.nominal.linear_axes(cl, A, B)
        modelled = self.model is not None
        xyz = self.real.linear_axes(cl, A, B) if (self.compensate and modelled) else xyz_nominal
        if delta is None:  # the tool really sits at the predicted real tip: check clearance there
            tip = self.real.tool_pose_np(A, B, *xyz.T)[0] if modelled else cl
            delta = self.clearance(tip, T)
        lead, tilt = lead_tilt_from_axis(T, p.frames)
        ra, rb, rt = (program_rates(q, p.t, p.path.rows) for q in (A, B, T))
        g = gamma_of(T, p.t, p.path.rows)
        comp = np.linalg.norm(rt.acc, axis=1)
        res = MethodResult(method=method, rows=p.path.rows, idx=p.idx, t=p.t, cc=cc, normals=nrm, cl=cl, axis=T,
                           lead=lead, tilt=tilt, rotary=q, rotary_vel=RotaryValues.of(q.names, ra.vel, rb.vel),
                           rotary_acc=RotaryValues.of(q.names, ra.acc, rb.acc),
                           xyz=xyz, delta=delta, lift=lift,
                           lead_window=o.lead_window if lead_window is None else lead_window,
                           tilt_window=o.tilt_window if tilt_window is None else tilt_window,
                           compound_acc=comp, feed_dirs=p.frames[:, :, 0])
        if p.curvature is not None and p.stepover is not None:
            res.scallop = point_scallop(self.cutter, lead, tilt, p.curvature, p.stepover)
        res.metrics = self.metrics(res, g, unreachable, runtime)
        if res.scallop is not None and np.isfinite(res.scallop).any():
            res.metrics.scallop_max_um = float(1e3 * np.nanmax(res.scallop))
        if modelled:
            # ideal (the intended CL point and the axis the ideal machine would give for the
            # same A, B) against the predicted real machine, with and without compensation
            tip_real = self.real.tool_pose_np(A, B, *xyz.T)[0]
            tip_unc = self.real.tool_pose_np(A, B, *xyz_nominal.T)[0]
            ideal_axis = self.nominal.tool_axis_np(A, B)
            res.metrics.tip_error_um_max = float(1e3 * np.max(np.linalg.norm(tip_real - cl, axis=1)))
            res.metrics.tip_error_um_max_uncompensated = float(
                1e3 * np.max(np.linalg.norm(tip_unc - cl, axis=1)))
            # atan2(|a x b|, a.b): arccos near 1 would give ~1e-8 rad of rounding
            res.metrics.axis_error_urad_max = float(1e6 * np.max(np.arctan2(
                np.linalg.norm(np.cross(ideal_axis, T), axis=1), np.sum(ideal_axis * T, axis=1))))
            res.metrics.compensated = bool(self.compensate)
        return res

    def metrics(self, r: MethodResult, g: float, unreachable: np.ndarray, runtime: float) -> Metrics:
        """Summary: gamma (1/s^4), peaks (deg/s^2), min delta (mm), violation counts per
        constraint at the programmed feed (samples outside the TRUE limits of all five axes, the
        pivot's X Y Z included, ``camsmooth.smoothing.nlp.limit_violations``, and outside the
        user's windows), interference (points with delta < -tolerance), lifts (mm)."""
        p = self.program
        viol, _ = axis_violations(self.nominal, np.column_stack([r.xyz, r.rotary.values]), p.t, p.path.rows)
        tol = 1e-6
        viol["lead window"] = int(np.sum((r.lead < r.lead_window[:, 0] - tol) | (r.lead > r.lead_window[:, 1] + tol)))
        viol["tilt window"] = int(np.sum((r.tilt < r.tilt_window[:, 0] - tol) | (r.tilt > r.tilt_window[:, 1] + tol)))
        gouge = interferes(r.delta, self.tolerance)
        viol["interference"] = int(np.sum(gouge))
        lifted = r.lift > 0
        unclean = sorted({int(x) for x in r.rows[gouge | lifted]})
        peak = tuple(float(np.degrees(np.max(np.abs(acc)))) for _, acc in r.rotary_acc.items())
        return Metrics(gamma=g, peak_acc=PerAxis(r.rotary.names, peak), peak_acc_plan=PerAxis.nan(r.rotary.names),
                       min_delta=float(np.min(r.delta)),
                       violations=viol, violations_programmed=dict(viol), lifted_points=int(np.sum(lifted)),
                       max_lift_mm=float(np.max(r.lift, initial=0.0)),
                       lifted_beyond_tolerance=int(np.sum(r.lift > self.tolerance)), unclean_rows=unclean,
                       unreachable=[(int(r.rows[i]), int(r.idx[i])) for i in unreachable],
                       tolerance_mm=self.tolerance, runtime_s=runtime)
