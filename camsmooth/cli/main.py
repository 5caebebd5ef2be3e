"""Command line: a thin layer over the Python API (degrees and mm/min here, radians inside).

Verbs: smooth, path, demo (this module); calibrate, simulate, predict (camsmooth.cli.model);
diagnose (camsmooth.cli.diagnose); iso230 (camsmooth.cli.iso230). Every numeric option is
range-checked while the command line is parsed. All outputs of a command are one transaction
(camsmooth.io.atomic.output_transaction): they appear together at the end or not at all.

Exit status: 0 done; 1 with --strict when a point was lifted along the normal beyond the
tolerance, gouges beyond it or is unreachable (one message naming the rows, nothing written); 2
bad input or any other anticipated failure (one message on stderr, no output written); 70
internal error (a bug: one line on stderr, the traceback with --debug); 130 interrupted by Ctrl-C
(SIGINT); 143 terminated (SIGTERM).
"""

from __future__ import annotations

import argparse
import math
import re
import sys
import traceback
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.cli.entry import interrupted, signum_of, version_line
from camsmooth.cli.options import CliParser, angle_range, number, vector3
from camsmooth.constants import DEFAULT_TOLERANCE_MM
from camsmooth.errors import CamsmoothError, InputError
from camsmooth.io.atomic import (
    install_signal_handlers,
    output_transaction,
    raise_if_signalled,
    restore_signal_handlers,
    signal_received,
)

SAMPLES_DIR = Path(__file__).resolve().parents[2] / "surfaces"

EXIT_OK, EXIT_STRICT, EXIT_INPUT, EXIT_BUG, EXIT_SIGINT, EXIT_SIGTERM = 0, 1, 2, 70, 130, 143
#: Most CC points `camsmooth path` writes (a tiny --stepover or --spacing would exhaust memory).
MAX_PATH_POINTS = 10_000_000

_POSITIVE_MM = number(gt=0, unit="mm")


def _cutter(args: argparse.Namespace, declared: Any = None):
    """The cutter of the command line; where it gives no radii, the program's own (``declared``,
    a ToroidalCutter from the CL program's TLDATA)."""
    from camsmooth.geometry.cutter import ToroidalCutter

    if args.cutter_radius is None or args.corner_radius is None:
        if declared is None:
            raise InputError("give --cutter-radius and --corner-radius (mm): the input declares no cutter")
        if args.cutter_radius is not None or args.corner_radius is not None:
            raise InputError("give both --cutter-radius and --corner-radius, or neither (the program's TLDATA)")
        args = argparse.Namespace(**{**vars(args), "cutter_radius": declared.R, "corner_radius": declared.r})
    kw = {}
    if args.shank_length is not None:
        kw["shank_length"] = args.shank_length
    if args.holder_radius is not None:
        kw["holder_radius"] = args.holder_radius
        kw["holder_length"] = args.holder_length
    return ToroidalCutter(R=args.cutter_radius, r=args.corner_radius, **kw)


def _add_cutter_args(p: argparse.ArgumentParser, required: bool = True) -> None:
    p.add_argument("--cutter-radius", type=number(ge=0, unit="mm"), required=required, metavar="R",
                   help="ring radius R (mm, >= 0; 0 is a ball nose); the cutter diameter is 2(R + r)"
                   + ("" if required else "; default: the program's TLDATA (CL input)"))
    p.add_argument("--corner-radius", type=number(ge=0, unit="mm"), required=required, metavar="r",
                   help="corner radius r (mm, >= 0; 0 is a flat end)")
    p.add_argument("--shank-length", type=_POSITIVE_MM, default=None, metavar="L",
                   help="length of the cylindrical part from the tip (mm, >= r; default 4 x (R + r))")
    p.add_argument("--holder-radius", type=_POSITIVE_MM, default=None, metavar="RH",
                   help="tool holder radius (mm, > R + r; optional)")
    p.add_argument("--holder-length", type=_POSITIVE_MM, default=40.0, metavar="LH",
                   help="tool holder length (mm, > 0; default 40)")


def load_error_model(path: str | None, option: str = "--model") -> Any:
    """ErrorModel from a JSON file (camsmooth.machine.model), or None; a malformed file is an
    InputError naming the option, the file and the key."""
    if path is None:
        return None
    from camsmooth.machine.model import ErrorModel

    try:
        return ErrorModel.from_json(path)
    except InputError as exc:
        raise exc.about(option) from None


def _check_outputs_options(args: argparse.Namespace) -> None:
    if getattr(args, "force", False) and not getattr(args, "report", None):
        raise InputError("--force replaces the --report folder whole; it needs --report DIR")


def load_input(args: argparse.Namespace, surface: Any, machine: Any) -> tuple[Any, Any]:
    """The program to smooth (any format of camsmooth.post.load_program, detected from the
    content or --format) and the cutter: a CC path as it is, a CL program made a CamProgram on the
    surface (camsmooth.smoothing.cam), with the program's cutter unless the command line names one."""
    from camsmooth.cli.part import place_and_check, reach_of
    from camsmooth.geometry.clearance import MeshIndex
    from camsmooth.geometry.paths import CCPath
    from camsmooth.post import load_program
    from camsmooth.smoothing.cam import cam_program, cutter_of

    program = load_program(args.path, args.format, machine=machine)
    if not isinstance(program, CCPath) and (program.modes is not None or getattr(args, "operations", None)):
        from camsmooth.post.rewrite import select_operations  # a posted program: its chosen operations

        program = select_operations(program, getattr(args, "operations", None))
        if program.modes is not None and getattr(args, "gcode", None):
            from camsmooth.post.rewrite import WRITER_DIALECT

            if program.dialect not in WRITER_DIALECT:  # said before the smoothing, not after
                raise InputError(f"--gcode: writing smoothed blocks into a {program.dialect} program is not supported "
                                 f"(supported: {', '.join(sorted(WRITER_DIALECT))})", file=program.source)
    if not isinstance(program, CCPath) and program.format == "result-csv":
        from camsmooth.io.ccpath import read_cc_csv

        program = read_cc_csv(args.path)  # camsmooth's result CSV: its CC path, smoothed again
    if isinstance(program, CCPath):
        place_and_check(args, surface, program, reach_of(program))
        return program, _cutter(args)
    declared = cutter_of(program) if args.cutter_radius is None and args.corner_radius is None else None
    cutter = _cutter(args, declared)
    place_and_check(args, surface, program, reach_of(program, cutter))  # the part where the program is
    return cam_program(program, MeshIndex(surface.mesh), cutter, args.tolerance, feed=args.feed,
                       mesh=surface.mesh), cutter


def run_smooth(args: argparse.Namespace) -> int:
    from camsmooth.cli.part import exact_clearance_report, load_part
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.smoothing.pipeline import SmoothOptions, smooth

    _check_outputs_options(args)
    from camsmooth.post.setup import parse_work_offset

    parse_work_offset(args.work_offset)  # a bad --work-offset fails before the computation
    lead, tilt = args.lead, args.tilt
    for opt, value, (lo, hi) in (("--prefer-lead", args.prefer_lead, lead), ("--prefer-tilt", args.prefer_tilt, tilt)):
        if value is not None and not lo <= value <= hi:
            raise InputError(f"{opt} {value:g} deg lies outside the window {lo:g}:{hi:g} deg")
    model = load_error_model(args.model)
    inputs = [p for p in (args.path, args.surface, args.machine, args.model) if p]
    with output_transaction() as tx:
        # staged before the computation so that a bad output path fails at once
        out_csv = tx.file(args.output)
        gcode = tx.file(args.gcode) if args.gcode else None
        report = tx.folder(args.report, replace=args.force, keep=inputs) if args.report else None
        options = SmoothOptions(workers=args.workers, dask=args.dask,  # workers None: all cores when worth it
                                max_scallop=args.max_scallop, hold_feed=args.hold_feed)
        surface, machine = load_part(args), load_machine(args.machine)  # STEP, mesh or definition
        program, cutter = load_input(args, surface, machine)
        result = smooth(program, surface, machine, cutter,
                        feed=args.feed, lead_range=tuple(np.radians(lead)), tilt_range=tuple(np.radians(tilt)),
                        method=args.method,
                        prefer_lead=None if args.prefer_lead is None else np.radians(args.prefer_lead),
                        prefer_tilt=None if args.prefer_tilt is None else np.radians(args.prefer_tilt),
                        model=model, compensate=args.compensate, tolerance=args.tolerance, options=options,
                        progress=not args.quiet)
        # --strict: a lift beyond the tolerance, a gouge or an unreachable point is a failure, and
        # a failure writes nothing (the transaction rolls back)
        failure = _strict_failure(result) if args.strict else None
        if failure:
            raise StrictFailure(failure)
        posted = program if getattr(getattr(program, "program", None), "modes", None) else None
        _write_outputs(result, out_csv, gcode, report, args.feed, progress=not args.quiet, posted=posted,
                       setup=None if posted is not None else _shop_setup(args, program))
    if not args.quiet:
        _print_summary(result)
        for line in exact_clearance_report(result, surface):  # a CAD part: the worst clearances on its B-rep
            print(line, file=sys.stderr if line.startswith("camsmooth: warning") else sys.stdout)
    return EXIT_OK


STRICT_ROWS_NAMED = 10  # rows the --strict message details (one line, even for a million-point program)


class StrictFailure(CamsmoothError):
    """``smooth --strict`` refused the program (exit status 1); the message names the rows."""


def _strict_failure(result: Any) -> str | None:
    """What --strict refuses in the primary method, row by row: points lifted along the normal
    beyond the tolerance (count, largest lift mm, where), gouges beyond it (count, deepest
    clearance mm, where) and unreachable points; None when there is none."""
    from camsmooth.smoothing.output import point_status
    from camsmooth.smoothing.result import interferes

    r = result.result
    tol = float(result.inputs["tolerance"])
    lifted = r.lift > tol
    gouge = interferes(r.delta, tol)
    unreachable = point_status(r) == "unreachable"
    parts = []
    bad_rows = np.unique(r.rows[lifted | gouge | unreachable])
    for row in bad_rows[:STRICT_ROWS_NAMED]:
        m = r.rows == row
        bits = []
        for sel, what, value, worst in ((lifted & m, "lifted along the normal", r.lift, np.argmax),
                                        (gouge & m, "gouging", r.delta, np.argmin)):
            if sel.any():
                k = np.flatnonzero(sel)
                i = k[worst(value[k])]
                size = "largest lift" if what.startswith("lifted") else "clearance"
                bits.append(f"{len(k)} point{'s' * (len(k) > 1)} {what} ({size} {value[i]:.4g} mm at point "
                            f"{int(r.idx[i])})")
        if (unreachable & m).any():
            k = np.flatnonzero(unreachable & m)
            bits.append(f"{len(k)} point{'s' * (len(k) > 1)} unreachable (first at point {int(r.idx[k[0]])})")
        parts.append(f"row {int(row)}: " + ", ".join(bits))
    if not parts:
        return None
    if len(bad_rows) > STRICT_ROWS_NAMED:
        parts.append(f"and {len(bad_rows) - STRICT_ROWS_NAMED} more rows")
    return (f"--strict: not clean within the tolerance {tol:g} mm: " + "; ".join(parts)
            + "; nothing written")


def _shop_setup(args: argparse.Namespace, program: Any) -> Any:
    """The tool call, spindle, coolant and work offset the CAM input names (camsmooth.post.setup)."""
    from camsmooth.post.setup import shop_setup

    return shop_setup(getattr(program, "program", None), args.path, getattr(args, "work_offset", None))


def _write_outputs(result: Any, out_csv: Path, gcode: Path | None, report: Path | None, feed: float | None,
                   progress: bool = False, posted: Any = None, setup: Any = None) -> None:
    """Write the result CSV, G-code (the planned feed per block) and report to (temporary) paths;
    progress: a line on a terminal while the report is written (camsmooth.progress). posted: the
    CamProgram of a posted input: the G-code is that program with the smoothed blocks written in
    (camsmooth.post.rewrite); setup: the input's tool call, spindle, coolant and work offset for
    camsmooth's own program (camsmooth.post.setup.ShopSetup)."""
    from camsmooth.smoothing.feed import block_feeds
    from camsmooth.smoothing.output import write_gcode, write_result_csv

    write_result_csv(out_csv, result)
    if gcode:
        r = result.result
        programmed = np.asarray(result.inputs["feed"], float)
        f = block_feeds(r.plan, r.cl, r.rows, programmed) if r.plan is not None else programmed
        if posted is not None:
            from camsmooth.post import posted_text
            from camsmooth.post.rewrite import rewrite_posted
            from camsmooth.smoothing.posting import post_points

            cl = posted.program
            new = rewrite_posted(posted_text(cl.source, []), cl, post_points(r), posted.source_index, result.machine,
                                 np.broadcast_to(np.asarray(f, float), (len(r.rows),)))
            for w in new.warnings:
                print(f"camsmooth: warning: {w}", file=sys.stderr)
            Path(gcode).write_text(new.text)
        else:
            write_gcode(gcode, result, result.machine, result.cutter, f, setup=setup)
    if report:
        from camsmooth.progress import Steps
        from camsmooth.report.smoothing import write_report

        with Steps(1, enabled=progress) as steps, steps.step("report: plots, 3D render"):
            write_report(result, report)


def _scallop_cell(um: float | None) -> str:
    """The summary table's scallop cell (um): '-' unknown, 'no overlap' where passes do not meet."""
    if um is None:
        return "-"
    return format(um, ".4g") if math.isfinite(um) else "no overlap"


def _print_summary(result) -> None:
    from camsmooth.report.headline import headline

    head = headline(result)  # what smoothing bought and cost: the same facts as the report's
    if head is not None:
        print(head.text())
    m = result.result.metrics
    ctrl = m.controller or "axes"
    r1, r2 = m.peak_acc_plan.names  # the machine's rotary axes, as the result names them
    head = ("method", "Gamma", f"peak|{r1}''|", f"peak|{r2}''|", "min delta", "scallop um", "violations", "at feed",
            "optimal s", f"{ctrl} s", "limited by", "time s")
    print("{:8s} {:>12s} {:>10s} {:>10s} {:>10s} {:>10s} {:>10s} {:>8s} {:>9s} {:>11s} {:>16s} {:>8s}".format(*head))
    for name, r in result.methods.items():
        mm = r.metrics
        nviol = sum(mm.violations.values())
        nfeed = sum(mm.violations_programmed.values())
        sc = getattr(mm, "scallop_max_um", None)
        print(f"{name:8s} {mm.gamma:12.4g} {mm.peak_acc_plan[r1]:10.4g} {mm.peak_acc_plan[r2]:10.4g} "
              f"{mm.min_delta:10.4g} {_scallop_cell(sc):>10s} {nviol:10d} {nfeed:8d} "
              f"{mm.cycle_time_optimal_s:9.2f} {mm.cycle_time_s:11.2f} {mm.limiting or '-':>16s} {mm.runtime_s:8.2f}")
    print("peaks (deg/s^2) and violations under the planned time law; 'at feed': violations at the programmed "
          "feed, before planning; scallop: the largest between adjacent passes")
    if any(r.metrics.scallop_max_um is not None and not math.isfinite(r.metrics.scallop_max_um)
           for r in result.methods.values()):
        print("scallop 'no overlap': somewhere adjacent passes do not overlap (the effective cutting radius is below "
              "half the stepover), so material is left standing between them: no finite scallop")
    for name, r in result.methods.items():
        for peak in getattr(r.metrics, "controller_joint_peaks", []):
            print(f"camsmooth: warning: {name}: row {peak.row}: the {r.metrics.controller} planner takes "
                  f"{peak.axis} to {peak.ratio:.3g} of its velocity or acceleration limit where two blocks blend "
                  f"(its own parabolic blend, as its model runs the program)", file=sys.stderr)
        fp = getattr(r.metrics, "controller_feed_peak", None)
        if fp is not None:
            print(f"camsmooth: warning: {name}: the {r.metrics.controller} planner's blends take the tool tip to "
                  f"{fp.ratio:.3g} of the programmed feed (row {fp.row}; {fp.rows} row{'s' * (fp.rows > 1)} more "
                  f"than 1% past it); smooth --hold-feed holds the blocks so that it does not", file=sys.stderr)
        for miss in getattr(r.metrics, "scallop_missed", []):
            print(f"camsmooth: warning: {name}: row {miss.row}: finish budget missed at {miss.points} point"
                  f"{'s' * (miss.points > 1)}: scallop {miss.scallop_um:.4g} um against {miss.budget_um:.4g} um at "
                  f"point {miss.idx} (no lead/tilt of the windows within the machine's limits meets it)",
                  file=sys.stderr)
    if m.controller:
        dev = (f"; its tool tip within {1e3 * m.controller_deviation_mm:.3g} um of the programmed path at every servo "
               f"cycle" if m.controller_deviation_mm is not None else "")
        print(f"cycle times: 'optimal' is the time-optimal law under the axes' limits; '{ctrl}' what the {ctrl} "
              f"controller's planner makes of the program as written ({m.blocks} cut blocks{dev})")
        _print_floor(result)
    if m.pole:
        _print_pole(result)
    for w in result.warnings:
        print(f"camsmooth: warning: {w}", file=sys.stderr)
    if m.blocked:
        worst = max(m.blocked, key=lambda b: b.lift_mm)
        print(f"camsmooth: warning: {len(m.blocked)} points lifted along the normal because no orientation of "
              f"their lead/tilt window clears the mesh; largest lift {worst.lift_mm:.4g} mm at {worst.point} "
              f"(best clearance the map found there {worst.best_clearance_mm:.4g} mm)", file=sys.stderr)
    if m.unreachable_clear:
        worst = max(m.unreachable_clear, key=lambda b: b.lift_mm)
        print(f"camsmooth: warning: {len(m.unreachable_clear)} points lifted along the normal because the "
              f"machine's limits kept the axis out of their clear region; largest lift {worst.lift_mm:.4g} mm at "
              f"{worst.point}", file=sys.stderr)
    if m.unclean_rows:
        r = result.result
        i = int(np.argmax(r.lift))  # the largest lift, whichever method lifted (the spline's names no map)
        largest = (f"; largest lift {r.lift[i]:.4g} mm at row {int(r.rows[i])}, point {int(r.idx[i])}"
                   if r.lift[i] > 0 else "")
        print(f"camsmooth: warning: rows not clean without lifting along the normal: {m.unclean_rows}{largest}",
              file=sys.stderr)
    if m.unreachable:
        print(f"camsmooth: warning: {len(m.unreachable)} unreachable points, first {m.unreachable[:5]}",
              file=sys.stderr)


def _print_floor(result) -> None:
    """Per method whose controller has a floor (camsmooth.controller, e.g. LinuxCNC): the least time
    any program of straight blocks through its points can take there, beside its predicted time."""
    from camsmooth.controller import floor_text, mode_text

    for name, r in result.methods.items():
        mm = r.metrics
        if mm.controller and mm.controller_floor_s is not None:
            text = floor_text(mm.controller, mm.controller_floor_s, mm.cycle_time_s, mm.controller_end_offset_mm)
            print(f"{name}: {text} "
                  f"({mm.cycle_time_s / max(mm.controller_floor_s, 1e-12):.3f}x the floor)")
        if mm.tcp_cycle_time_s is not None and mm.machine_cycle_time_s is not None:  # both LinuxCNC modes
            modes = mode_text(mm.tcp_cycle_time_s, mm.tcp_floor_s, mm.machine_cycle_time_s, mm.machine_floor_s,
                              bool(mm.tcp_within_limits))
            print(f"{name}: {modes}")
    mm = result.result.metrics  # the written method: say how to write it in the faster mode
    written = getattr(getattr(getattr(result, "machine", None), "post", None), "mode", None)
    if mm.tcp_cycle_time_s is not None and mm.machine_cycle_time_s is not None and mm.tcp_within_limits:
        faster = "tcp" if mm.tcp_cycle_time_s < mm.machine_cycle_time_s else "machine"
        if written is not None and faster != written:
            print(f"{result.result.method} is written in {written} mode; [post] mode = \"{faster}\" in the machine "
                  f"file writes it in {faster} mode, which LinuxCNC runs faster")


def _print_pole(result) -> None:
    """Every passage near the pole of the outer rotary axis (camsmooth.smoothing.pole)."""
    from camsmooth.smoothing.pole import POLE_CONE_DEG

    m = result.result.metrics
    q0 = m.pole[0]
    print(f"pole passages: {len(m.pole)} (tool axis within {POLE_CONE_DEG:g} deg of the {q0.outer} axis; the exact "
          f"inverse turns {q0.outer} up to {max(q.outer_peak_speed for q in m.pole):.4g} deg/s at the programmed "
          f"feed, limit {q0.outer_vmax:.4g} deg/s)")
    print(f"{'row':>5s} {'points':>11s} {'closest deg':>11s} {q0.outer + ' turn deg':>11s} "
          f"{'exact ' + q0.outer + ' deg/s':>14s} {'Gamma cost':>11s}")
    for q in m.pole:
        cost = "-" if q.gamma_cost is None else f"{q.gamma_cost:+.4g}"
        print(f"{q.row:5d} {q.first:5d}..{q.last:<5d} {q.closest_deg:11.3g} {q.outer_turn_deg:11.4g} "
              f"{q.outer_peak_speed:14.4g} {cost:>11s}")
    print(f"Gamma cost: sum of |T''|^2 (1/s^4) over the passage, {result.primary} minus the programmed orientation")


def _check_path_size(n_rows: float, n_points: float) -> None:
    total = n_rows * n_points
    if not total <= MAX_PATH_POINTS:
        raise InputError(f"--stepover/--spacing would give about {total:.3g} CC points ({n_rows:.3g} rows of "
                         f"{n_points:.3g}); at most {MAX_PATH_POINTS:.0e} are written: use larger steps")


def run_path(args: argparse.Namespace) -> int:
    from camsmooth.cli.part import load_part
    from camsmooth.geometry.paths import raster_path_on_mesh, zigzag_extents, zigzag_path
    from camsmooth.io.ccpath import write_cc_csv

    with output_transaction() as tx:
        out = tx.file(args.output)
        surf = load_part(args)
        if surf.parametric is not None and not args.raster:
            length, width = zigzag_extents(surf.parametric, args.along)
            _check_path_size(width / args.stepover + 1, length / args.spacing + 1)
            cc = zigzag_path(surf.parametric, args.stepover, args.spacing, along=args.along)
        else:
            from camsmooth.geometry.clearance import axial_drop

            if args.cutter_radius is None or args.corner_radius is None:
                raise InputError("a raster path on a mesh needs --cutter-radius and --corner-radius")
            axis = np.asarray(args.axis, dtype=float)
            axis = axis / np.linalg.norm(axis)
            size = float(np.ptp(np.asarray(surf.mesh.vertices), axis=0).max())
            _check_path_size(size / args.stepover + 1, size / args.spacing + 1)
            try:
                cc = raster_path_on_mesh(surf.mesh, _cutter(args), axis, args.stepover, args.spacing, axial_drop)
            except InputError as exc:
                raise InputError(exc.message, file=args.surface) from None
            if len(cc.points) == 0:
                raise InputError(f"the cutter touches the mesh nowhere along --axis {args.axis}: no CC points",
                                 file=args.surface)
        if args.feed is not None:
            cc.feed = np.full(len(cc.points), float(args.feed))
        write_cc_csv(out, cc)
    if not args.quiet:
        print(f"wrote {len(cc.points)} CC points in {len(cc.row_slices())} rows to {args.output}")
    return EXIT_OK


def run_analyze(args: argparse.Namespace) -> int:
    """`camsmooth analyze`: a program as it is (camsmooth.smoothing.analysis)."""
    import json

    from camsmooth.cli.part import load_part, place_and_check, reach_of
    from camsmooth.geometry.clearance import MeshIndex
    from camsmooth.geometry.paths import CCPath
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.post import load_program
    from camsmooth.smoothing.analysis import analyze_program

    _check_outputs_options(args)
    machine = load_machine(args.machine)
    if args.model:  # the program as the real machine executes it, as smooth --model evaluates it
        machine = load_error_model(args.model).apply(machine)
    inputs = [p for p in (args.program, args.surface, args.machine, args.model) if p]
    with output_transaction() as tx:
        out_json = tx.file(args.json) if args.json else None
        report = tx.folder(args.report, replace=args.force, keep=inputs) if args.report else None
        out_cl = tx.file(args.cl) if args.cl else None
        program = load_program(args.program, args.format, machine=machine, machine_given=args.machine is not None)
        if args.machine is None and getattr(program, "dialect", None) and tuple(program.rotary) != machine.rotary:
            from camsmooth.post.core import nominal_machine  # a posted program for another kind of machine

            machine = nominal_machine(tuple(program.rotary))
        surface = load_part(args) if args.surface else None
        if surface is not None:
            place_and_check(args, surface, program, reach_of(program, args=args))
        index = MeshIndex(surface.mesh) if surface is not None else None
        cutter = None
        if args.cutter_radius is not None or args.corner_radius is not None or isinstance(program, CCPath):
            cutter = _cutter(args)
        lead = np.radians(np.mean(args.lead)) if args.lead else np.radians(11.0)
        tilt = np.radians(np.mean(args.tilt)) if args.tilt else 0.0
        analysis = analyze_program(program, machine, index=index, cutter=cutter, tolerance=args.tolerance,
                                   feed=args.feed, lead=lead, tilt=tilt, progress=not args.quiet)
        if out_cl is not None:  # the CL program as read (camsmooth.io.program.cl_columns)
            from camsmooth.io.program import cl_of_cc, write_cl_table

            write_cl_table(out_cl, cl_of_cc(program, cutter, lead, tilt) if isinstance(program, CCPath) else program)
        if out_json is not None:
            out_json.write_text(json.dumps(analysis.to_json(), indent=2) + "\n", encoding="utf-8")
        if report is not None:
            from camsmooth.io.program import cl_of_cc
            from camsmooth.report.analysis import write_analysis_report
            from camsmooth.report.view3d import scene_of_program

            cl = cl_of_cc(program, cutter, lead, tilt) if isinstance(program, CCPath) else program
            write_analysis_report(analysis, analysis.series, machine, report,
                                  scene=scene_of_program(cl, surface.mesh if surface is not None else None))
    if not args.quiet:
        print(f"{analysis.source} ({analysis.format}): {analysis.points} cutting points, "
              f"{len(analysis.toolpaths)} tool path(s)")
        _print_analysis(analysis, machine)
        for w in analysis.warnings:
            print(f"camsmooth: warning: {w}", file=sys.stderr)
    return EXIT_OK


def _print_analysis(analysis: Any, machine: Any) -> None:
    """The summary of ``analyze``: one line per tool path, its full name, the machine's rotary axes
    by name, and each violation named by the limit it breaks ('107 Y travel')."""
    from camsmooth.smoothing.analysis import named_violations

    width = max([len("tool path")] + [len(tp.name) for tp in analysis.toolpaths])
    ctrl = next((tp.controller for tp in analysis.toolpaths if tp.controller), "")
    head = ("points", *(f"{r} deg" for r in machine.rotary), "Gamma", "optimal s", f"{ctrl} s" if ctrl else "",
            "limited by", "min delta")
    print(f"{'tool path':{width}s} " + "{:>7s} {:>17s} {:>17s} {:>10s} {:>9s} {:>11s} {:>16s} {:>10s}  {}".format(
        *head, "violations, planned law | at the programmed feed"))
    for tp in analysis.toolpaths:
        md = "-" if tp.clearance is None else f"{tp.clearance['min_mm']:.4g}"
        r1, r2 = (tp.range_deg[r] for r in machine.rotary)
        c = f"{tp.cycle_time_s:.2f}" if tp.controller else ""
        print(f"{tp.name:{width}s} {tp.points:7d} {r1[0]:8.2f}..{r1[1]:<7.2f} {r2[0]:8.2f}..{r2[1]:<7.2f} "
              f"{tp.gamma:10.4g} {tp.cycle_time_optimal_s:9.2f} {c:>11s} {tp.limiting or '-':>16s} {md:>10s}  "
              f"{named_violations(tp.violations)} | {named_violations(tp.violations_programmed)}")
    print("violations: samples over a limit, named by axis and quantity, under the planned time law (what the "
          "program's F words command) | at the programmed feed, before planning; optimal s: the time-optimal law"
          + (f"; {ctrl} s: what the {ctrl} controller's planner makes of the program" if ctrl else ""))


def demo_outputs(out: str | Path, sample: str) -> tuple[Path, Path, Path]:
    """The files ``camsmooth demo --out OUT --sample SAMPLE`` writes: the result CSV, the G-code and
    the report folder, each carrying the sample's name so that one sample's demo never replaces
    another's (README: ``make demo`` writes these for the blade into demo_out/)."""
    out = Path(out)
    return out / f"{sample}_smoothed.csv", out / f"{sample}_smoothed.nc", out / f"{sample}_report"


def run_demo(args: argparse.Namespace) -> int:
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.smoothing.pipeline import SmoothOptions, smooth

    samples = Path(args.samples) if args.samples else SAMPLES_DIR
    name = args.sample
    path = samples / f"{name}_path.csv"
    mesh = next((m for m in (samples / f"{name}.ply", samples / f"{name}.stl") if m.is_file()), samples / f"{name}.ply")
    if not path.is_file() or not mesh.is_file():
        raise InputError(f"sample {name!r} not found in {samples} (expected {path.name} and {name}.ply or "
                         f"{name}.stl)")
    out = Path(args.out)
    machine_file = samples / f"{name}_machine.toml"  # a sample made for another machine ships its machine
    if args.machine is not None:  # the sample on another machine: its outputs carry the machine's name
        machine_file = Path(args.machine)
    csv, nc, rep = demo_outputs(out, name if args.machine is None else f"{name}_{machine_file.stem}")
    cutter = ToroidalCutter(R=4.0, r=1.0)
    from camsmooth.machine.kinematics import load_machine

    machine = load_machine(machine_file if machine_file.is_file() or args.machine is not None else None)
    with output_transaction() as tx:
        tmp_csv, tmp_nc = tx.file(csv), tx.file(nc)
        tmp_rep = tx.folder(rep, replace=args.force, keep=(path, mesh))
        if not args.quiet:
            on = f"{machine.name}, {machine_file}" if machine_file.is_file() else "default AB head"
            src = samples / f"{name}.cls" if (samples / f"{name}.cls").is_file() else path
            print(f"camsmooth demo: smoothing {src} on {mesh} (toroidal cutter R=4 r=1 mm, lead 2:20, "
                  f"tilt -15:15 deg, {on}) -> {out}/")
        from camsmooth.geometry.surfaces import load_surface
        from camsmooth.io.ccpath import read_cc_csv

        surface = load_surface(mesh)
        program = read_cc_csv(path)
        cls = samples / f"{name}.cls"
        if cls.is_file():  # a sample that ships its CAM program: smoothed from it, its axes shown as 'cam'
            from camsmooth.geometry.clearance import MeshIndex
            from camsmooth.post import load_program
            from camsmooth.smoothing.cam import cam_program

            program = cam_program(load_program(cls), MeshIndex(surface.mesh), cutter, DEFAULT_TOLERANCE_MM,
                                  mesh=surface.mesh)
        result = smooth(program, surface, machine, cutter, feed=2000.0,
                        lead_range=tuple(np.radians([2.0, 20.0])), tilt_range=tuple(np.radians([-15.0, 15.0])),
                        method="nlp", options=SmoothOptions(workers=None), progress=not args.quiet)
        _write_outputs(result, tmp_csv, tmp_nc, tmp_rep, 2000.0, progress=not args.quiet)
    if not args.quiet:
        _print_summary(result)
        print(f"wrote {csv}, {nc} and {rep / 'report.html'}")
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    from camsmooth.cli.part import add_part_args

    parser = CliParser(prog="camsmooth", description=__doc__.split("\n\n")[0],
                       epilog="Exit status: 0 done, 1 --strict and a lifted row, 2 bad input (one message), "
                              "70 internal error (a bug), 130 Ctrl-C, 143 SIGTERM. --debug (anywhere on the "
                              "command line) prints the traceback of an error.",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--debug", action="store_true", help="print the traceback of an error")
    parser.add_argument("--version", action="version", version=version_line(),
                        help="print camsmooth's version (the installed package's) and exit")
    sub = parser.add_subparsers(dest="verb", required=True)

    p = sub.add_parser("smooth", help="smooth a program: tool axes, A/B angles, interference check")
    p.add_argument("path", help="the program: a CC path CSV (x,y,z,nx,ny,nz[,row,fx,fy,fz,feed]), an APT/CLSF CL "
                   "file, a CL CSV (x,y,z,i,j,k[,row,feed]) or camsmooth's G-code; the format is detected from the "
                   "content")
    p.add_argument("--format", default=None, choices=("apt", "cl-csv", "cc-csv", "gcode"),
                   help="the program's format, when detection should not decide")
    p.add_argument("--surface", required=True, help="the part: CAD (.step/.stp/.iges/.igs; pip install "
                   "'camsmooth[cad]'), mesh (.stl/.obj/.ply) or definition (.toml)")
    add_part_args(p)
    p.add_argument("--machine", default=None, help="machine TOML (default: the built-in AB head)")
    _add_cutter_args(p, required=False)
    p.add_argument("--feed", type=number(gt=0, unit="mm/min"), default=None, metavar="F",
                   help="programmed feed F (mm/min, > 0) where the CSV has none")
    p.add_argument("--lead", required=True, type=angle_range(0, 90, strict=True), metavar="MIN:MAX",
                   help="lead window (deg), 0 <= MIN < MAX < 90")
    p.add_argument("--tilt", required=True, type=angle_range(-90, 90, lo_open=True), metavar="MIN:MAX",
                   help="tilt window (deg), -90 < MIN <= MAX < 90")
    p.add_argument("--prefer-lead", type=number(ge=0, lt=90, unit="deg"), default=None, metavar="DEG",
                   help="preferred lead (deg, inside the lead window; default its middle)")
    p.add_argument("--prefer-tilt", type=number(gt=-90, lt=90, unit="deg"), default=None, metavar="DEG",
                   help="preferred tilt (deg, inside the tilt window; default its middle)")
    p.add_argument("--method", choices=("nlp", "spline", "none"), default="nlp",
                   help="the method whose axes are written (default nlp): none the initial lead/tilt axes, spline "
                   "the published cubic-spline smoothing, nlp the optimisation; the methods before it are computed "
                   "too and compared in the summary and report")
    p.add_argument("--tolerance", type=_POSITIVE_MM, default=DEFAULT_TOLERANCE_MM, metavar="MM",
                   help=f"the part's allowed deviation (mm, default {DEFAULT_TOLERANCE_MM:g}): a clearance below "
                   "-MM is a gouge, for every clearance decision")
    p.add_argument("--max-scallop", type=_POSITIVE_MM, default=None, metavar="MM",
                   help="finish budget: the largest scallop between adjacent passes (mm) nlp may leave at any point "
                   "(from the cutter's effective radius at its lead and tilt, the surface's curvature and the "
                   "stepover measured on the path); with a CAM program, nlp is also held to the CAM's own scallop "
                   "plus the tolerance; rows that cannot meet it are named with the size")
    p.add_argument("--hold-feed", action="store_true",
                   help="on a controller camsmooth models (LinuxCNC): hold the blocks so that its planner's blends "
                   "never take the tool tip faster than the programmed feed (by default they may, and smooth says "
                   "by how much; holding costs cycle time)")
    p.add_argument("--workers", type=number(ge=1, le=1024, integer=True, unit=""), default=None, metavar="N",
                   help="processes for the rows (default: all cores for programs of 5000 points or more)")
    p.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run the rows on a Dask cluster: a scheduler address, or 'local' for a LocalCluster "
                   "(pip install 'camsmooth[dask]')")
    p.add_argument("--model", default=None, help="machine error model JSON: smooth the predicted real axis")
    p.add_argument("--compensate", action="store_true", help="with --model: command the axes so the "
                   "predicted real tool tip is the ideal one")
    p.add_argument("-o", "--output", required=True, help="output CSV (columns: README, 'File formats')")
    p.add_argument("--gcode", default=None, help="also write G-code (G01 X Y Z A B F); from a posted program, that "
                   "program in its dialect and mode with the smoothed blocks written in (camsmooth.post.rewrite)")
    p.add_argument("--operations", default=None, metavar="NAME,...",
                   help="the operations of a posted program to smooth (names as analyze --cl gives them; default "
                   "every simultaneous five-axis one); the others are written as they are")
    p.add_argument("--work-offset", default=None, metavar="G54",
                   help="the work offset --gcode selects where the input names none (G54 ... G59, G54.1 P<n>, "
                   "G500 ... G599); the tool call, spindle and coolant come from the APT/CLSF input")
    p.add_argument("--report", default=None, metavar="DIR",
                   help="also write a report (PNG plots, render, report.html) into the folder DIR; its own files "
                        "are replaced, other files there are left alone")
    p.add_argument("--force", action="store_true", help="with --report: replace the folder DIR whole")
    p.add_argument("--strict", action="store_true", help="exit 1 when a point had to be lifted along the normal by "
                   "more than the tolerance, gouges beyond it, or is unreachable; one message names the rows and "
                   "nothing is written")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=run_smooth)

    p = sub.add_parser("path", help="generate a CC path: zig-zag on a definition, or raster by axial drop on a mesh")
    p.add_argument("--surface", required=True, help="surface definition (.toml), mesh or CAD part (.step/.iges)")
    add_part_args(p)
    p.add_argument("--stepover", type=_POSITIVE_MM, required=True, metavar="MM",
                   help="distance between rows (mm, > 0)")
    p.add_argument("--spacing", type=_POSITIVE_MM, required=True, metavar="MM",
                   help="distance between points along a row (mm, > 0)")
    p.add_argument("--along", choices=("u", "v"), default="u", help="iso-parametric direction of the rows")
    p.add_argument("--raster", action="store_true", help="raster rows by axial drop even for a definition")
    p.add_argument("--axis", type=vector3, default=(0.0, 0.0, 1.0), metavar="I,J,K",
                   help="fixed tool axis i,j,k for the axial drop (not all zero; default 0,0,1)")
    _add_cutter_args(p, required=False)
    p.add_argument("--feed", type=number(gt=0, unit="mm/min"), default=None, metavar="F",
                   help="write this feed (mm/min, > 0) into the CSV")
    p.add_argument("-o", "--output", required=True, help="CC path CSV to write")
    p.add_argument("--quiet", action="store_true", help="no summary on stdout")
    p.set_defaults(func=run_path)

    p = sub.add_parser("analyze", help="analyse a program as it is: axes, limits, Gamma, cycle time, clearance")
    p.add_argument("program", help="APT/CLSF, CL CSV, CC CSV or camsmooth G-code (format detected from the content)")
    p.add_argument("--format", default=None, choices=("apt", "cl-csv", "cc-csv", "gcode", "result-csv"),
                   help="the program's format, when detection should not decide (result-csv: camsmooth's own "
                   "result CSV, recognised by its header)")
    p.add_argument("--machine", default=None, help="machine TOML (default: the built-in AB head)")
    p.add_argument("--surface", default=None, help="the part (mesh, definition or CAD .step/.iges): adds the "
                   "clearance of every pose")
    add_part_args(p)
    p.add_argument("--model", default=None, metavar="MODEL.json",
                   help="the machine's error model (calibrate): evaluate the program on the tool pose the real "
                        "machine executes, as smooth --model does")
    _add_cutter_args(p, required=False)
    p.add_argument("--tolerance", type=_POSITIVE_MM, default=None, metavar="MM",
                   help=f"clearance tolerance (mm; default the one a camsmooth program was written with, else "
                        f"{DEFAULT_TOLERANCE_MM:g})")
    p.add_argument("--feed", type=number(gt=0, unit="mm/min"), default=None, metavar="F",
                   help="feed (mm/min, > 0) where the program sets none")
    p.add_argument("--lead", type=angle_range(0, 90, strict=True), default=None, metavar="MIN:MAX",
                   help="CC input only: analysed at the middle of this lead window (deg; default 11)")
    p.add_argument("--tilt", type=angle_range(-90, 90, lo_open=True), default=None, metavar="MIN:MAX",
                   help="CC input only: analysed at the middle of this tilt window (deg; default 0)")
    p.add_argument("--json", default=None, metavar="OUT.json", help="write the analysis as JSON (units mm, deg)")
    p.add_argument("--cl", default=None, metavar="OUT.csv", help="write the CL program as read: operation,row,line,"
                   "x,y,z,i,j,k,feed (tool tip mm and unit axis in the workpiece frame, feed mm/min; one record per "
                   "feed motion end point; a CC path: at the --lead/--tilt it is analysed with)")
    p.add_argument("--report", default=None, metavar="DIR", help="also write a report into the folder DIR")
    p.add_argument("--force", action="store_true", help="with --report: replace the folder DIR whole")
    p.add_argument("--quiet", action="store_true", help="no summary on stdout")
    p.set_defaults(func=run_analyze)

    p = sub.add_parser("demo", help="smooth a shipped sample and write the CSV, G-code and report")
    p.add_argument("--out", default="demo_out", help="output folder (default demo_out): OUT/SAMPLE_smoothed.csv, "
                   "OUT/SAMPLE_smoothed.nc and the report in OUT/SAMPLE_report, so samples do not replace each other")
    p.add_argument("--sample", default="blade", help="sample name in surfaces/ (blade, saddle, mould, wave; dome: "
                   "an A/C trunnion "
                   "table through the pole of its C axis)")
    p.add_argument("--samples", default=None, help="folder of the samples (default: the repository's surfaces/)")
    p.add_argument("--machine", default=None, metavar="M.toml",
                   help="run the sample on this machine instead of its own (e.g. surfaces/nutating_machine.toml); "
                        "the outputs are named SAMPLE_MACHINE_smoothed.*")
    p.add_argument("--force", action="store_true", help="replace the folder OUT/SAMPLE_report whole")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=run_demo)

    from camsmooth.cli import diagnose, iso230, model

    model.register(sub)
    diagnose.register(sub)
    iso230.register(sub)
    return parser


RANGE_OPTIONS = ("--lead", "--tilt", "--part-frame")  # smooth and analyze (--part-frame: path too)


def _join_ranges(argv: list[str]) -> list[str]:
    """Let '--tilt -15:15' through: argparse would take '-15:15' for an option."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        if argv[i] in RANGE_OPTIONS and i + 1 < len(argv):
            out.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            out.append(argv[i])
            i += 1
    return out


# ----------------------------------------------------------------------------------------------
# the error boundary
_NUMPY_REPR = re.compile(r"np\.(?:float|int|uint|bool|str|complex)_?\d*\(([^()]*)\)")


def error_message(exc: BaseException) -> str:
    """One line for an anticipated failure: the message, the file names, no numpy reprs."""
    if isinstance(exc, OSError) and exc.strerror:
        where = " -> ".join(str(f) for f in (exc.filename, exc.filename2) if f is not None)
        text = f"{where}: {exc.strerror}" if where else exc.strerror
    elif isinstance(exc, UnicodeDecodeError):
        text = f"a file is not text (UTF-8): {exc.reason} at byte {exc.start}"
    elif isinstance(exc, MemoryError):
        text = "out of memory: the input is too large for this machine"
    else:
        text = str(exc) or type(exc).__name__
    text = " ".join(line.strip() for line in text.splitlines() if line.strip())
    return _NUMPY_REPR.sub(r"\1", text)


def _show_warning(message: Any, category: type, filename: str, lineno: int, file: Any = None,
                  line: str | None = None) -> None:
    """Warnings as one line 'camsmooth: warning: ...' (never the Python source line)."""
    print(f"camsmooth: warning: {error_message(Exception(str(message)))}", file=sys.stderr if file is None else file)


def run(args: argparse.Namespace, debug: bool = False) -> int:
    """Run a parsed command inside the error boundary; return the exit status (module docstring).
    A signal (SIGINT, SIGTERM) wins over whatever error it caused (a worker gone, a library's
    SystemError): the interruption escapes to ``main``, which prints its one message."""
    with warnings.catch_warnings():
        warnings.showwarning = _show_warning
        try:
            code = int(args.func(args) or 0)
        except StrictFailure as exc:
            raise_if_signalled()
            print(f"camsmooth: error: {error_message(exc)}", file=sys.stderr)
            return EXIT_STRICT
        except (CamsmoothError, OSError, UnicodeDecodeError, MemoryError) as exc:
            raise_if_signalled()
            if debug:
                traceback.print_exc()
            print(f"camsmooth: error: {error_message(exc)}", file=sys.stderr)
            return EXIT_INPUT
        except Exception as exc:
            raise_if_signalled()
            if debug:
                traceback.print_exc()
            hint = "" if debug else " (run with --debug for the traceback)"
            print(f"camsmooth: internal error: {type(exc).__name__}: {error_message(exc)}. This is a bug in "
                  f"camsmooth: please report it with the command line and the input files{hint}", file=sys.stderr)
            return EXIT_BUG
        raise_if_signalled()
        return code


def main(argv: Sequence[str] | None = None) -> int:
    """The `camsmooth` command: parse ``argv`` (default sys.argv[1:]), run, return the exit status."""
    installed = install_signal_handlers()  # done already by camsmooth.cli.entry for the command
    try:
        argv = list(sys.argv[1:] if argv is None else argv)
        debug = "--debug" in argv
        argv = [a for a in argv if a != "--debug"]
        try:
            args = build_parser().parse_args(_join_ranges(argv))
        except SystemExit as exc:  # --help (0) or a bad option (2; CliParser printed one line)
            raise_if_signalled()
            return exc.code if isinstance(exc.code, int) else EXIT_INPUT
        return run(args, debug=debug)
    except KeyboardInterrupt as exc:  # SIGINT or SIGTERM (Terminated), wherever it arrived
        return interrupted(signal_received() or signum_of(exc))
    finally:
        if installed:
            restore_signal_handlers()


if __name__ == "__main__":
    sys.exit(main())
