"""`camsmooth diagnose`: simulation versus recordings (camsmooth.diagnosis).

    camsmooth diagnose --program P.csv --recording R.csv [--machine M.toml] [--model MODEL.json]
                       --out FINDINGS.json [--report DIR [--force]] [--model-out NEW_MODEL.json]
    camsmooth diagnose --format umich FILE.csv [FILE.csv ...] --out FINDINGS.json [...]
                       [--validate FILE.csv ...]

    camsmooth diagnose --trace FILE.csv [--units mm|deg] [--columns t=1,X_cmd=3,X_act=4] [--scale S]
                       [--sample-period S]
                       --out FINDINGS.json [--report DIR]
    camsmooth diagnose --points FILE.csv --out FINDINGS.json

With ``--trace`` a controller trace (command and actual per axis, camsmooth.diagnosis.trace) is
diagnosed on its own, with no program; with ``--points`` nominal against measured points
(camsmooth.diagnosis.points) are fitted with the setup and the linear-axis geometry.
With ``--format umich`` each University of Michigan CNC-mill experiment file is read as program
and recording at once (camsmooth.diagnosis.recordings.read_umich); several files are fitted together
(kept apart in time), and ``--validate`` files are only predicted with the fitted model, never
fitted. The outputs are one transaction (camsmooth.io.atomic.output_transaction); the report's files
are written into DIR (other files left alone; --force replaces DIR whole); bad input raises
InputError (exit 2 from the CLI).
"""

from __future__ import annotations

import argparse
import json
from typing import Any

from camsmooth.cli.options import number
from camsmooth.errors import InputError


def register(subparsers: Any) -> None:
    """Add the `diagnose` verb to the CLI's subparsers."""
    p = subparsers.add_parser(
        "diagnose", help="compare recordings with the simulation; name, fit and validate the missing physics",
        description="Simulate the recorded channels from the program and the current model, locate where the "
                    "residual stands above the noise floor, name the missing physics from a library of "
                    "candidates (chosen on held-out data), fit it and write the findings and the extended model.")
    p.add_argument("files", nargs="*", metavar="FILE.csv",
                   help="with --format umich: Michigan CNC-mill experiment file(s), program and recording in one")
    p.add_argument("--format", choices=("csv", "umich"), default="csv",
                   help="csv: --program and --recording CSVs (default); umich: Michigan CNC-mill traces")
    p.add_argument("--program", help="program CSV: t (s), X, Y, Z (mm), A, B (deg), optional S (rpm), segment")
    p.add_argument("--recording", help="recording CSV: t and X_act.., tip_x.., axis_i.., temp_* channels")
    p.add_argument("--trace", metavar="FILE.csv", help="controller trace: t (s), <AX>_cmd, <AX>_act (mm, or deg "
                   "with --units deg), optional <AX>_load, <AX>_vel_act, <AX>_current, temp_<name> (deg C)")
    p.add_argument("--units", choices=("mm", "deg"), default="mm", help="with --trace: unit of the positions")
    p.add_argument("--columns", metavar="MAP", help="with --trace: read a plain delimited log by field numbers, "
                   "e.g. t=1,X_cmd=3,X_act=4 (1-based; a header line, if any, is skipped)")
    p.add_argument("--scale", type=number(gt=0), default=1.0, metavar="S",
                   help="with --trace: units per count of positions logged as encoder counts (default 1)")
    p.add_argument("--sample-period", type=number(gt=0, unit="s"), default=None, metavar="S",
                   help="with --trace: the t column counts samples (halsampler -t, a row index); t = count * S")
    p.add_argument("--points", metavar="FILE.csv", help="nominal against measured points: x_nom, y_nom[, z_nom], "
                   "x_meas, y_meas[, z_meas] (mm)")
    p.add_argument("--machine", help="machine TOML (default: the ideal AB head)")
    p.add_argument("--model", help="current model JSON (ErrorModel JSON, optional servo section)")
    p.add_argument("--out", required=True, help="FINDINGS.json to write")
    p.add_argument("--report", metavar="DIR", help="folder for the plots and report.html (its own files are "
                   "replaced, other files there are left alone)")
    p.add_argument("--force", action="store_true", help="with --report: replace the folder DIR whole")
    p.add_argument("--model-out", help="write the extended model JSON here (ErrorModel JSON + servo section)")
    p.add_argument("--validate", nargs="+", default=[], metavar="FILE.csv",
                   help="with --format umich: files to predict with the fitted model (not fitted)")
    p.add_argument("--folds", type=number(ge=2, integer=True), default=5,
                   help="blocked time folds for held-out scoring (>= 2, default 5)")
    p.add_argument("--max-fit-samples", type=number(ge=100, integer=True), default=None, metavar="N",
                   help="fit on at most N samples (an even random subset; N >= 100, default 60000)")
    p.add_argument("--candidates", help="comma list restricting the candidate library")
    p.add_argument("--quiet", action="store_true", help="no summary of the findings on stdout")
    p.set_defaults(func=run_diagnose)


def load_physics(path: str | None, option: str = "--model") -> Any:
    """The diagnosis's machine model (camsmooth.diagnosis.engine.load_model: the base model when
    ``path`` is None); a malformed file is an InputError naming the option, the file and the key."""
    from camsmooth.diagnosis.engine import load_model

    try:
        return load_model(path)
    except InputError as exc:
        raise exc.about(option) from None


def _options(args: argparse.Namespace) -> Any:
    from dataclasses import replace

    from camsmooth.diagnosis.engine import CANDIDATES, Options

    opt = Options()
    if args.folds < 2:  # also checked while parsing; kept for callers that build args themselves
        raise InputError(f"--folds must be >= 2, got {args.folds}")
    opt = replace(opt, folds=args.folds)
    if args.max_fit_samples is not None:
        if args.max_fit_samples < 100:
            raise InputError(f"--max-fit-samples must be >= 100, got {args.max_fit_samples}")
        opt = replace(opt, max_fit_samples=args.max_fit_samples)
    if args.candidates:
        names = tuple(c.strip() for c in args.candidates.split(",") if c.strip())
        unknown = [c for c in names if c not in CANDIDATES]
        if unknown:
            raise InputError(f"--candidates: unknown {', '.join(unknown)}; known: {', '.join(CANDIDATES)}")
        opt = replace(opt, candidates=names)
    return opt


def run_diagnose(args: argparse.Namespace) -> int:
    """Run `camsmooth diagnose` (module docstring)."""
    from camsmooth.diagnosis.engine import diagnose, validate, write_findings, write_model
    from camsmooth.diagnosis.recordings import concatenate, read_program_csv, read_recording_csv, read_umich
    from camsmooth.io.atomic import output_transaction
    from camsmooth.machine.kinematics import load_machine

    if getattr(args, "force", False) and not args.report:
        raise InputError("--force replaces the --report folder whole; it needs --report DIR")
    if getattr(args, "trace", None) or getattr(args, "points", None):
        return run_trace_or_points(args)
    if args.format == "umich":
        if not args.files:
            raise InputError("--format umich needs at least one FILE.csv")
        if args.program or args.recording:
            raise InputError("--format umich reads program and recording from FILE.csv; drop --program/--recording")
    else:
        if args.files:
            raise InputError(f"unexpected file argument(s) {' '.join(args.files)} (use --program and --recording, "
                             "or --format umich)")
        if not args.program or not args.recording:
            raise InputError("diagnose needs --program P.csv and --recording R.csv (or --format umich FILE.csv)")
        if args.validate:
            raise InputError("--validate is for --format umich files")
    options = _options(args)
    inputs = [p for p in (*args.files, *args.validate, args.program, args.recording, args.machine, args.model) if p]
    with output_transaction() as tx:
        out = tx.file(args.out)
        model_out = tx.file(args.model_out) if args.model_out else None
        report = tx.folder(args.report, replace=getattr(args, "force", False), keep=inputs) if args.report else None
        if args.format == "umich":
            pairs = [read_umich(f) for f in args.files]
            program, recording = pairs[0] if len(pairs) == 1 else concatenate(pairs)
        else:
            program = read_program_csv(args.program)
            recording = read_recording_csv(args.recording)
        machine = load_machine(args.machine)
        base = load_physics(args.model)
        diag = diagnose(program, recording, machine, base, options)
        if args.validate:
            diag.result.validation = [validate(*read_umich(f), diag, machine) for f in args.validate]
        write_findings(out, diag)
        if model_out is not None:
            write_model(model_out, diag)
        if report is not None:
            from camsmooth.report.diagnosis import write_report

            write_report(diag, report)
    if not args.quiet:
        print(summary_text(diag.findings))
        print(f"findings: {args.out}" + (f"; report: {args.report}" if args.report else "")
              + (f"; model: {args.model_out}" if args.model_out else ""))
    return 0


def run_trace_or_points(args: argparse.Namespace) -> int:
    """`camsmooth diagnose --trace` / `--points` (module docstring): what was read is printed
    first; the outputs are one transaction."""
    from camsmooth.io.atomic import output_transaction

    if args.trace and args.points:
        raise InputError("give --trace or --points, not both")
    other = [o for o, v in (("--program", args.program), ("--recording", args.recording), ("--model", args.model),
                            ("--model-out", args.model_out), ("--validate", args.validate), ("FILE.csv", args.files))
             if v]
    if other or args.format != "csv":
        raise InputError(f"{'--trace' if args.trace else '--points'} is diagnosed on its own; drop "
                         f"{', '.join(other) or '--format'}")
    if args.points and (args.columns or args.units != "mm" or args.scale != 1.0 or args.report
                        or args.sample_period):
        raise InputError("--columns, --units, --scale, --sample-period and --report go with --trace, not --points")
    if args.trace:
        from camsmooth.diagnosis.trace import diagnose_trace, parse_columns, read_trace, write_trace_report
        from camsmooth.diagnosis.trace import summary_text as trace_summary

        columns = parse_columns(args.columns) if args.columns else None
        trace = read_trace(args.trace, units=args.units, columns=columns, scale=args.scale,
                           sample_period=args.sample_period)
        if not args.quiet:
            print(trace.summary(), flush=True)
        options = _options(args)
        with output_transaction() as tx:
            out = tx.file(args.out)
            report = tx.folder(args.report, replace=args.force, keep=[args.trace]) if args.report else None
            diag = diagnose_trace(trace, options)
            out.write_text(json.dumps(diag.findings, indent=2) + "\n", encoding="utf-8")
            if report is not None:
                write_trace_report(diag, report)
        f = diag.findings
        if not args.quiet:
            print(trace_summary(f))
    else:
        from camsmooth.diagnosis.points import diagnose_points, read_points
        from camsmooth.diagnosis.points import summary_text as points_summary

        pts = read_points(args.points)
        if not args.quiet:
            print(pts.summary(), flush=True)
        with output_transaction() as tx:
            out = tx.file(args.out)
            f = diagnose_points(pts)
            out.write_text(json.dumps(f, indent=2) + "\n", encoding="utf-8")
        if not args.quiet:
            print(points_summary(f))
    if not args.quiet:
        print(f"findings: {args.out}" + (f"; report: {args.report}" if args.report else ""))
    return 0


def summary_text(f: dict[str, Any]) -> str:
    """A few plain lines: the verdict, one sentence per effect, what was rejected."""
    lines = [f"verdict: {f['verdict']}"]
    for e in f["effects"]:
        lines.append(f"- {e['sentence']}")
    for r in f["rejected"]:
        if not r["reason"].startswith("not applicable"):
            lines.append(f"  rejected {r['name']}: {r['reason']}")
    lv = f.get("lag_vs_offset")
    if lv:
        lines.append(f"lag vs offset: {lv['verdict']}")
    for v in f.get("validation", []):
        lines.append(f"validation {v['recording']}: " + "; ".join(
            f"{c} {d['rms_before']:.4g} -> {d['rms_after']:.4g}" for c, d in v["channels"].items()))
    return "\n".join(lines)

