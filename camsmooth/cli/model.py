"""CLI verbs of the error model: ``calibrate``, ``simulate`` and ``predict``.

``register(subparsers)`` adds them to the main parser's subparsers; each sub-command sets
``func`` to a handler taking the parsed args and returning an exit code (0), and the handlers
are thin calls into camsmooth.machine.calibration / simulate / errormodel. Bad input raises
camsmooth.errors.InputError (the main CLI prints it). Units on the command line: mm, s, deg.

    camsmooth calibrate probe|rtest|spindle|ballbar MEASUREMENT.csv [--machine M.toml]
                        [--base MODEL.json] -o MODEL.json [--report REPORT.json]
    camsmooth simulate probe|rtest|spindle|ballbar|recording --model MODEL.json [--machine M.toml]
                       [--noise MM] [--seed N] -o OUT.csv
    camsmooth predict OUT.csv --model MODEL.json [--machine M.toml] [-o PREDICTED.csv]
                      [--rpm RPM]
"""

from __future__ import annotations

import argparse
import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.cli.main import _POSITIVE_MM, load_error_model
from camsmooth.cli.options import number, number_list, tighten
from camsmooth.errors import InputError

#: Columns of the calibration measurement files, with units (camsmooth.machine.calibration).
MEASUREMENT_COLUMNS = {
    "probe": "A, B (deg) commanded rotary axes; X, Y, Z (mm) commanded linear axes; sx, sy, sz (mm) the sphere "
             "centre the control computed with its nominal kinematics",
    "rtest": "the machine's two rotary axes (deg; A, C on an AC table, B, C on a BC table, A, B on the AB head) "
             "commanded; X, Y, Z (mm) commanded linear axes (the nominal tool tip kept on the sphere); dx, dy, dz "
             "(mm) the sphere centre read by the R-test nest, along the spindle's x, y, z",
    "spindle": "theta (deg) spindle angle; ext (mm) ball distance beyond the collet centre (two or more "
               "values); x, y, z (mm) measured ball centre in the spindle frame",
    "ballbar": "t (s) time of the set; rpm (1/min) spindle speed until the next set; angle (deg) bar elevation; "
               "dir (+1 counter-clockwise, -1 clockwise); phi (deg) position on the circle; L0 (mm) bar "
               "length; dL (mm) reading minus L0",
}
_NOISE = number(ge=0, unit="mm")
_SEED = number(ge=0, integer=True)


def register(subparsers: Any) -> None:
    """Add the ``calibrate``, ``simulate`` and ``predict`` sub-commands."""
    cal = subparsers.add_parser("calibrate", help="identify the error model from measurements",
                                description="Fit error-model parameters to a measurement file and write the "
                                "model JSON (prints parameters, uncertainties, residuals, Jacobian singular "
                                "values and the parameters the data cannot determine).")
    csub = cal.add_subparsers(dest="calibrate_kind", metavar="KIND", required=True)
    helps = {"probe": "rotary-axis errors from reference-sphere probing (AB head)",
             "rtest": "rotary-axis location errors of any machine kind from an R-test (sphere on the table)",
             "spindle": "spindle screw from spindle-analyser data",
             "ballbar": "spindle thermal drift from a ballbar cone test"}
    for kind, text in helps.items():
        p = csub.add_parser(kind, help=text, description=f"{text[0].upper()}{text[1:]}. Measurement CSV "
                            f"(one header row, comma separated) columns: {MEASUREMENT_COLUMNS[kind]}.")
        p.add_argument("measurement", help=f"measurement CSV: {MEASUREMENT_COLUMNS[kind]}")
        p.add_argument("--machine", help="machine TOML (default: the built-in AB head)")
        p.add_argument("--base", help="model JSON to start from; its other parts are kept")
        p.add_argument("-o", "--output", required=True, help="model JSON to write")
        p.add_argument("--report", help="also write the calibration report as JSON")
        if kind == "spindle":
            p.add_argument("--no-pso", action="store_true", help="skip the particle-swarm comparison")
            p.add_argument("--seed", type=_SEED, default=0, help="PSO seed (whole number >= 0, default 0)")
        p.set_defaults(func=calibrate_cli, calibrate_kind=kind)

    sim = subparsers.add_parser("simulate", help="write simulated measurement files from an error model")
    ssub = sim.add_subparsers(dest="simulate_kind", metavar="KIND", required=True)
    for kind, text in (("probe", "reference-sphere probing"), ("rtest", "an R-test (sphere on the table)"),
                       ("spindle", "spindle-analyser data"), ("ballbar", "ballbar cone test")):
        p = ssub.add_parser(kind, help=text, description=f"Simulate {text} from an error model; the CSV has "
                            f"the columns of `camsmooth calibrate {kind}`: {MEASUREMENT_COLUMNS[kind]}.")
        p.add_argument("--model", required=True, help="error model JSON")
        p.add_argument("--machine", help="machine TOML (default: the built-in AB head)")
        p.add_argument("--noise", type=_NOISE, default=None, metavar="MM",
                       help="measurement noise, mm (one standard deviation, >= 0)")
        p.add_argument("--seed", type=_SEED, default=0, help="random seed (whole number >= 0, default 0)")
        p.add_argument("-o", "--output", required=True, help="CSV file to write")
        if kind == "probe":
            p.add_argument("--grid", type=number(ge=2, integer=True), default=11, metavar="N",
                           help="N x N grid of A, B poses (N >= 2, default 11)")
            p.add_argument("--max-angle", type=number(gt=0, unit="deg"), default=None, metavar="DEG",
                           help="grid extent +-DEG (deg, > 0, within the machine's A and B travel; default: "
                                "the largest the travel allows)")
        elif kind == "rtest":
            p.add_argument("--tilt-angles", type=number(ge=3, integer=True), default=7, metavar="N",
                           help="angles of the tilt axis (A on the AB head), spread over +-90 deg within its "
                                "travel (>= 3, default 7)")
            p.add_argument("--outer-angles", type=number(ge=3, integer=True), default=12, metavar="N",
                           help="angles of the other rotary axis: a full turn for a C axis, else +-90 deg within "
                                "its travel (>= 3, default 12)")
            p.add_argument("--sphere", type=number_list(unit="mm"), default=None, metavar="X,Y,Z",
                           help="nominal sphere centre, mm, workpiece frame (default: the table centre + "
                                "(120, 60, 80))")
        elif kind == "spindle":
            p.add_argument("--exts", type=number_list(gt=0, unit="mm"), default=[50.0, 150.0], metavar="MM,MM",
                           help="ball extensions beyond the collet, mm (each > 0, two or more; default 50,150)")
            p.add_argument("--revolutions", type=number(ge=1, integer=True), default=3,
                           help="spindle turns (>= 1, default 3)")
            p.add_argument("--samples", type=number(ge=4, integer=True), default=72,
                           help="samples per revolution (>= 4, default 72)")
        elif kind == "ballbar":
            p.add_argument("--bar-length", type=_POSITIVE_MM, default=150.0, metavar="MM",
                           help="mm (> 0, default 150)")
            p.add_argument("--angles", type=number_list(gt=0, lt=90, unit="deg"), default=[30.0, 60.0],
                           metavar="DEG,DEG", help="bar elevations, deg (each > 0 and < 90; default 30,60)")
            p.add_argument("--step", type=number(gt=0, le=120, unit="deg"), default=0.1, metavar="DEG",
                           help="sample spacing on the circle, deg (> 0, dividing 360; default 0.1)")
            p.add_argument("--interval", type=number(gt=0, unit="s"), default=900.0, metavar="S",
                           help="time between sets, s (> 0, default 900)")
            p.add_argument("--duration", type=number(ge=0, unit="s"), default=14400.0, metavar="S",
                           help="time of the last set, s (>= 0, default 14400)")
            p.add_argument("--heat", type=number(ge=0, unit="s"), default=10800.0, metavar="S",
                           help="the spindle runs until this time, s (>= 0, default 10800)")
            p.add_argument("--rpm", type=number(ge=0, unit="1/min"), default=5000.0,
                           help="spindle speed while running, 1/min (>= 0, default 5000)")
        p.set_defaults(func=simulate_cli, simulate_kind=kind)
    # `simulate recording` belongs to camsmooth.diagnosis.engine: its arguments come from there (ranges
    # added here), the handler is imported only when the sub-command runs.
    p = ssub.add_parser("recording", help="a machine recording (diagnosis)",
                        description="Simulate a machine recording from a program and a model "
                        "(camsmooth.diagnosis.engine).")
    from camsmooth.diagnosis.engine import add_simulate_recording_arguments

    add_simulate_recording_arguments(p)
    tighten(p, {"rate": (number(gt=0, unit="Hz"), "> 0"), "noise_mm": (_NOISE, ">= 0"),
                "noise_deg": (number(ge=0, unit="deg"), ">= 0"), "noise_axis": (number(ge=0), ">= 0"),
                "quantise_mm": (number(ge=0, unit="mm"), ">= 0"), "seed": (_SEED, "whole number >= 0")})
    p.set_defaults(func=simulate_cli, simulate_kind="recording")

    pred = subparsers.add_parser("predict", help="predict the real tool tip and axis of a tool program",
                                 description="Real tool tip and axis for every commanded pose of a "
                                 "smoothing output CSV (columns: the machine's rotary axes, e.g. A, B or A, C, in "
                                 "deg and X, Y, Z in mm at least), "
                                 "their deviation from the ideal, and lead/tilt (and a first-order "
                                 "clearance estimate) re-evaluated on the real axis.")
    pred.add_argument("input", help="smoothing output CSV (camsmooth smooth -o)")
    pred.add_argument("--model", required=True, help="error model JSON")
    pred.add_argument("--machine", help="machine TOML (default: the built-in AB head)")
    pred.add_argument("-o", "--output", help="CSV to write (default: INPUT_predicted.csv beside the input)")
    pred.add_argument("--rpm", type=number(ge=0, unit="1/min"), default=None,
                      help="spindle speed from the program start, 1/min (>= 0), for thermal drift (time = the "
                      "file's t, rows run one after another)")
    pred.set_defaults(func=predict_cli)


def _machine(args: argparse.Namespace) -> Any:
    from camsmooth.machine.kinematics import load_machine

    return load_machine(getattr(args, "machine", None))


def _report_json(report: Any) -> dict[str, Any]:
    def clean(v: Any) -> Any:
        if isinstance(v, np.ndarray):
            return v.tolist()
        if isinstance(v, dict):
            return {str(k): clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        if isinstance(v, (np.floating, np.integer)):
            return v.item()
        return v

    return clean({"kind": report.kind, "parameters": report.parameters, "uncertainties": report.uncertainties,
                  "units": report.units, "unidentifiable": report.unidentifiable,
                  "rms_before_mm": report.rms_before, "rms_after_mm": report.rms_after,
                  "singular_values": report.singular_values,
                  "condition_number": report.condition_number, "observations": report.n_observations,
                  "details": report.details})


def calibrate_cli(args: argparse.Namespace) -> int:
    """`camsmooth calibrate KIND`: fit, print the summary, write the model (and report) JSON."""
    from camsmooth.io.atomic import output_transaction, write_text_atomic
    from camsmooth.machine import calibration

    base = load_error_model(args.base, "--base")
    kind = args.calibrate_kind
    with output_transaction() as tx:
        out = tx.file(args.output)
        rep = tx.file(args.report) if args.report else None
        if kind == "probe":
            report = calibration.calibrate_probe(args.measurement, _machine(args), base)
        elif kind == "rtest":
            report = calibration.calibrate_rtest(args.measurement, _machine(args), base)
        elif kind == "spindle":
            report = calibration.calibrate_spindle(args.measurement, base, pso_compare=not args.no_pso,
                                                   seed=args.seed)
        else:
            report = calibration.calibrate_ballbar(args.measurement, base)
        report.model.to_json(out)
        if rep is not None:
            write_text_atomic(rep, json.dumps(_report_json(report), indent=1, default=str) + "\n")
    print(report.summary())
    print(f"wrote {args.output}" + (f" and {args.report}" if args.report else ""))
    return 0


def _probe_extent(machine: Any, max_angle: float | None) -> float:
    """The probe grid's +-extent (deg): ``max_angle`` checked against the A and B travel, or the
    largest symmetric extent the travel allows."""
    from camsmooth.machine.simulate import require_probe_machine

    require_probe_machine(machine, "simulate probe: probing")
    lims = {name: np.degrees([machine.limits[name].min, machine.limits[name].max]) for name in ("A", "B")}
    allowed = min(min(-lo, hi) for lo, hi in lims.values())
    travel = ", ".join(f"{n} [{lo:g}, {hi:g}] deg" for n, (lo, hi) in lims.items())
    if allowed <= 0:
        raise InputError(f"simulate probe: the machine's travel ({travel}) holds no grid symmetric about 0 deg")
    if max_angle is None:
        return float(allowed)
    if max_angle > allowed + 1e-9:
        raise InputError(f"--max-angle {max_angle:g} deg is beyond the machine's travel ({travel}): at most "
                         f"{allowed:g} deg")
    return float(max_angle)


def simulate_cli(args: argparse.Namespace) -> int:
    """`camsmooth simulate KIND`: write a simulated measurement file."""
    from camsmooth.io.atomic import output_transaction

    kind = args.simulate_kind
    if kind == "recording":
        from camsmooth.cli.diagnose import load_physics
        from camsmooth.diagnosis.engine import simulate_recording_cli

        load_physics(args.model)  # a malformed model is named here, before the engine reads it
        return simulate_recording_cli(args)  # one output, written by atomic_path
    from camsmooth.machine import calibration, simulate

    model = load_error_model(args.model)
    noise = simulate.DEFAULT_NOISE[kind] if args.noise is None else args.noise
    with output_transaction() as tx:
        out = tx.file(args.output)
        if kind == "probe":
            machine = _machine(args)
            poses = simulate.default_probe_poses(machine, args.grid, _probe_extent(machine, args.max_angle))
            data = simulate.simulate_probe(model, machine, poses=poses, noise=noise, seed=args.seed)
            calibration.write_probe_csv(out, data)
        elif kind == "rtest":
            machine = _machine(args)
            if args.sphere is not None and len(args.sphere) != 3:
                raise InputError(f"--sphere needs three numbers x,y,z (mm), got {len(args.sphere)}")
            poses = simulate.default_rtest_poses(machine, args.tilt_angles, args.outer_angles)
            data = simulate.simulate_rtest(model, machine, poses=poses, sphere=args.sphere, noise=noise,
                                           seed=args.seed)
            calibration.write_rtest_csv(out, data, machine)
        elif kind == "spindle":
            data = simulate.simulate_spindle(model, exts=args.exts, revolutions=args.revolutions,
                                             samples_per_rev=args.samples, noise=noise, seed=args.seed)
            calibration.write_spindle_csv(out, data)
        else:
            n = 360.0 / args.step
            if abs(n - round(n)) > 1e-6 * n or round(n) < 3:
                raise InputError(f"--step {args.step:g} deg must divide 360 deg into 3 or more steps")
            if len(set(args.angles)) < 2:
                raise InputError("--angles needs two or more different bar elevations, got "
                                 + ",".join(f"{a:g}" for a in args.angles))
            times, rpm = simulate.default_ballbar_schedule(args.duration, args.interval, args.heat, args.rpm)
            data = simulate.simulate_ballbar(model, _machine(args), times=times, rpm=rpm,
                                             bar_length=args.bar_length, angles_deg=args.angles,
                                             step_deg=args.step, noise=noise, seed=args.seed)
            calibration.write_ballbar_csv(out, data)
    print(f"wrote {args.output}")
    return 0


def predict_cli(args: argparse.Namespace) -> int:
    """`camsmooth predict`: real tool pose per commanded pose, written as CSV, summary printed."""
    from camsmooth.io.atomic import output_transaction
    from camsmooth.io.result_csv import read_result_csv

    model = load_error_model(args.model)
    machine = _machine(args)
    axes = (*machine.rotary, "X", "Y", "Z")
    need = axes + (("t",) if args.rpm is not None else ())
    cols = read_result_csv(args.input, required=axes)
    for name in need:
        if name not in cols:
            continue  # read_result_csv named the missing required columns; 't' is checked by predict_table
        bad = ~np.isfinite(cols[name])
        if bad.any():
            i = int(np.argmax(bad))
            raise InputError("not a finite number", file=args.input, row=i + 1, column=name)
    src = Path(args.input)
    out = Path(args.output) if args.output else src.with_name(src.stem + "_predicted.csv")
    with output_transaction() as tx:
        tmp = tx.file(out)
        table = predict_table(model, machine, cols, args.rpm, source=args.input)
        names = list(cols) + [k for k in table if k not in cols]
        data = {**cols, **table}
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(names)
            for i in range(len(data["X"])):
                w.writerow([_cell(data[k][i]) for k in names])
    dev, ang = table["tip_dev_um"], table["axis_dev_urad"]
    if len(dev):
        print(f"{len(dev)} poses: tool-tip deviation max {dev.max():.3f} um, mean {dev.mean():.3f} um; "
              f"tool-axis deviation max {ang.max():.3f} urad, mean {ang.mean():.3f} urad")
    if "real_lead" in table and np.isfinite(table["real_lead"]).any():
        dl = np.abs(table["real_lead"] - cols["lead"])
        dt = np.abs(table["real_tilt"] - cols["tilt"])
        print(f"lead change max {np.nanmax(dl) * 3600:.2f} arcsec, "
              f"tilt change max {np.nanmax(dt) * 3600:.2f} arcsec")
    print(f"wrote {out}")
    return 0


def _cell(v: Any) -> str:
    if isinstance(v, (float, np.floating)):
        return f"{float(v):.10g}"
    return str(v)


def predict_table(model: Any, machine: Any, cols: dict[str, np.ndarray], rpm: float | None = None,
                  source: str | None = None) -> dict[str, np.ndarray]:
    """Prediction columns for a result table (angles in deg as in the file, the machine's two
    rotary axes ``machine.rotary``, e.g. A, C on an AC table): real tip (real_clx,
    real_cly, real_clz, mm), real axis (real_i, real_j, real_k), tip_dev_um, axis_dev_urad and,
    when the table has CC points, normals, lead and tilt: real_lead, real_tilt (deg) = the file's
    value plus the change of lead/tilt from the ideal to the real axis in the local frame
    (METHODS section 1; feed direction from the CC points along each row), and, with a
    ``delta`` column, real_delta_est = delta + (displacement of the cutter at the CC point) . n,
    a first-order clearance estimate valid where the closest approach is at the contact."""
    r1, r2 = machine.rotary
    A, B = np.radians(cols[r1]), np.radians(cols[r2])
    X, Y, Z = cols["X"], cols["Y"], cols["Z"]
    t = None
    if rpm is not None:
        if "t" not in cols:
            raise InputError("--rpm needs a 't' column (time along the rows)", file=source, column="t")
        t = _program_time(cols["t"], cols.get("row"))
    pred = model.predict(machine, A, B, X, Y, Z, t=t, spindle_rpm=rpm)
    # "ideal" = what the program intends: its tool tip (clx, cly, clz) and axis (i, j, k) when the
    # file has them (a compensated program commands X, Y, Z away from the nominal kinematics on
    # purpose), else the nominal kinematics of the commanded axes.
    ideal_tip, ideal_axis = pred.ideal_tip, pred.ideal_axis
    if all(k in cols for k in ("clx", "cly", "clz")):
        ideal_tip = np.column_stack([cols["clx"], cols["cly"], cols["clz"]])
    if all(k in cols for k in ("i", "j", "k")):
        ideal_axis = np.column_stack([cols["i"], cols["j"], cols["k"]])
        ideal_axis = ideal_axis / np.linalg.norm(ideal_axis, axis=1, keepdims=True)
    out = {"real_clx": pred.tip[:, 0], "real_cly": pred.tip[:, 1], "real_clz": pred.tip[:, 2],
           "real_i": pred.axis[:, 0], "real_j": pred.axis[:, 1], "real_k": pred.axis[:, 2],
           "tip_dev_um": 1e3 * np.linalg.norm(pred.tip - ideal_tip, axis=1),
           "axis_dev_urad": 1e6 * np.arccos(np.clip(np.sum(pred.axis * ideal_axis, axis=1), -1.0, 1.0))}
    need = ("x", "y", "z", "nx", "ny", "nz", "lead", "tilt")
    if all(k in cols for k in need):
        from camsmooth.smoothing.orientation import lead_tilt_from_axis, local_frames

        cc = np.column_stack([cols["x"], cols["y"], cols["z"]])
        n = np.column_stack([cols["nx"], cols["ny"], cols["nz"]])
        rows = cols.get("row", np.zeros(len(cc), dtype=int))
        if all(k in cols for k in ("fx", "fy", "fz")):
            feed = np.column_stack([cols["fx"], cols["fy"], cols["fz"]])
        else:  # older files: the feed direction from the CC points along each row
            feed = np.full_like(cc, np.nan)
            for r in np.unique(rows):
                idx = np.flatnonzero(rows == r)
                if len(idx) >= 2:
                    feed[idx] = np.gradient(cc[idx], axis=0)
        ok = np.all(np.isfinite(feed), axis=1) & (np.linalg.norm(np.cross(feed, n), axis=1) > 1e-12)
        real_lead = np.full(len(cc), np.nan)
        real_tilt = np.full(len(cc), np.nan)
        if ok.any():
            frames = local_frames(n[ok], feed[ok])
            l0, t0 = lead_tilt_from_axis(ideal_axis[ok], frames)
            l1, t1 = lead_tilt_from_axis(pred.axis[ok], frames)
            dtilt = np.angle(np.exp(1j * (t1 - t0)))
            # the file's lead/tilt plus the change from the intended to the real axis (equal to
            # evaluating the real axis directly when the file's frame is the same)
            real_lead[ok] = cols["lead"][ok] + np.degrees(l1 - l0)
            real_tilt[ok] = cols["tilt"][ok] + np.degrees(dtilt)
        out["real_lead"], out["real_tilt"] = real_lead, real_tilt
        if "delta" in cols:
            omega = np.cross(ideal_axis, pred.axis)  # small rotation: intended axis -> real axis
            disp = (pred.tip - ideal_tip) + np.cross(omega, cc - ideal_tip)
            out["real_delta_est"] = cols["delta"] + np.sum(disp * n, axis=1)
    return out


def _program_time(t: np.ndarray, rows: np.ndarray | None) -> np.ndarray:
    """Absolute time when the file's t restarts at 0 on each row: rows run one after another."""
    t = np.asarray(t, float)
    if rows is None:
        return t
    out = t.copy()
    offset = 0.0
    for r in dict.fromkeys(rows.tolist()):  # rows in file order
        idx = np.flatnonzero(rows == r)
        out[idx] = t[idx] - t[idx[0]] + offset
        offset = out[idx[-1]]
    return out
