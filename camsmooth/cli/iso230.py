"""`camsmooth iso230`: the ISO 230-2 figures of a bidirectional positioning run and the LinuxCNC
pitch-error compensation table (camsmooth.diagnosis.iso230).

    camsmooth iso230 RUN.csv [--axis X] [--table terms|means] [--comp OUT.comp] [--json OUT.json]
                             [--check HELD.csv] [--quiet]

RUN.csv: columns target (mm), direction (+1/-1), run (int), deviation (mm, measured - target).
--table: build the compensation from the fitted terms (default: linear positioning error and
reversal, camsmooth.diagnosis.iso230.fit_terms) or from the mean deviations at the targets. With
'terms' the held-out RMS the table leaves is printed (leave one run out, ``crossvalidate``).
--check: a second run, not used to build the table: its RMS deviation before and after the table.
Only the LinuxCNC format is written (COMP_FILE_TYPE 1).
The outputs are one transaction; bad input raises InputError (exit 2 from the CLI).
"""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    """Add the `iso230` verb to the CLI's subparsers."""
    p = subparsers.add_parser(
        "iso230", help="ISO 230-2 positioning figures of a linear axis and its LinuxCNC compensation table",
        description="Read a bidirectional positioning run (target, direction, run, deviation; mm), print the "
                    "ISO 230-2 figures (reversal B, repeatability R, systematic deviation E, M, accuracy A) and "
                    "write the pitch-error compensation table LinuxCNC loads (COMP_FILE_TYPE = 1).")
    p.add_argument("run", metavar="RUN.csv", help="positioning run CSV: target, direction, run, deviation (mm)")
    p.add_argument("--axis", default="X", help="axis name for the outputs (default X)")
    p.add_argument("--table", choices=("terms", "means"), default="terms",
                   help="build the table from the fitted positioning error and reversal (default) or from the "
                        "mean deviations at the targets")
    p.add_argument("--comp", metavar="OUT.comp", help="write the LinuxCNC compensation file (type 1, mm)")
    p.add_argument("--json", metavar="OUT.json", help="write the figures (and table, held-out RMS) as JSON (mm)")
    p.add_argument("--check", metavar="HELD.csv", help="a second run: RMS deviation before / after the table")
    p.add_argument("--quiet", action="store_true", help="no summary on stdout")
    p.set_defaults(func=run_iso230)


def run_iso230(args: argparse.Namespace) -> int:
    """Run `camsmooth iso230` (module docstring)."""
    from camsmooth.diagnosis.iso230 import (
        comp_text,
        compensation_from_terms,
        compensation_table,
        crossvalidate,
        evaluate,
        fit_terms,
        heldout_rms,
        read_run,
        result_json,
    )
    from camsmooth.io.atomic import output_transaction

    run = read_run(args.run)
    result = evaluate(run, axis=args.axis)
    terms = fit_terms(run)
    cross = crossvalidate(run) if args.table == "terms" and len(set(run.run.tolist())) > 1 else None
    table = compensation_from_terms(terms, result.targets) if args.table == "terms" else compensation_table(result)
    held = heldout_rms(read_run(args.check), table) if args.check else None
    with output_transaction() as tx:
        if args.comp:
            tx.file(args.comp).write_text(comp_text(table), encoding="utf-8")
        if args.json:
            tx.file(args.json).write_text(result_json(result, table, held, terms, cross, args.table),
                                          encoding="utf-8")
    if not args.quiet:
        um = 1000.0
        n = min(result.n_up + result.n_down)
        print(f"axis {result.axis}: {len(result.targets)} targets, at least {n} approaches per direction "
              "(ISO 230-2, um)")
        print(f"  reversal B {result.B * um:.2f} (mean {result.B_mean * um:+.2f}), repeatability R {result.R * um:.2f} "
              f"(R+ {result.R_up * um:.2f}, R- {result.R_down * um:.2f})")
        print(f"  systematic E {result.E * um:.2f}, mean bidirectional M {result.M * um:.2f}, "
              f"accuracy A {result.A * um:.2f}")
        print(f"  fitted terms: positioning {terms.scale * 1e6:+.2f} +- {terms.sd_scale * 1e6:.2f} um/m "
              f"(offset {terms.offset * um:+.2f} um), reversal {terms.reversal * um:+.2f} +- "
              f"{terms.sd_reversal * um:.2f} um; residual RMS {terms.residual_rms * um:.2f} um")
        if cross is not None:
            print(f"  table from the fitted terms, held out (leave one of {cross['folds']} runs out): RMS "
                  f"{cross['before'] * um:.2f} um without it, {cross['after'] * um:.2f} um with it "
                  f"(noise, pooled s: {cross['noise'] * um:.2f} um)")
        if held is not None:
            print(f"  held-out {args.check}: RMS {held[0] * um:.2f} um without the table, "
                  f"{held[1] * um:.2f} um with it")
        outs = [f"{k}: {v}" for k, v in (("comp", args.comp), ("json", args.json)) if v]
        if outs:
            print("; ".join(outs) + (" (LinuxCNC: COMP_FILE_TYPE = 1)" if args.comp else ""))
    return 0
