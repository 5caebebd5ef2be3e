"""CLI verbs of the error model: ``calibrate``, ``simulate`` and ``predict``.

``register(subparsers)`` adds them to the main parser's subparsers; each sub-command sets
``func`` to a handler taking the parsed args and returning an exit code (0), and the handlers
are thin calls into camsmooth.machine.calibration / simulate / errormodel. Bad input raises
camsmooth.errors.InputError (the main CLI prints it). Units on the command line: mm, s, deg.

    camsmooth calibrate probe|spindle|ballbar MEASUREMENT.csv [--machine M.toml] [--base MODEL.json]
                        -o MODEL.json [--report REPORT.json]
    camsmooth simulate probe|spindle|ballbar|recording --model MODEL.json [--machine M.toml]
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

from camsmooth.errors import InputError


def register(subparsers: Any) -> None:
    """Add the ``calibrate``, ``simulate`` and ``predict`` sub-commands."""
    cal = subparsers.add_parser("calibrate", help="identify the error model from measurements",
                                description="Fit error-model parameters to a measurement file and write the "
                                "model JSON (prints parameters, uncertainties, residuals, Jacobian singular "
                                "values and the parameters the data cannot determine).")
    csub = cal.add_subparsers(dest="calibrate_kind", metavar="KIND", required=True)
    helps = {"probe": "rotary-axis errors from reference-sphere probing (columns A,B,X,Y,Z,sx,sy,sz)",
             "spindle": "spindle screw from analyser data (columns theta,ext,x,y,z)",
             "ballbar": "spindle thermal drift from a ballbar cone test (columns t,rpm,angle,dir,phi,L0,dL)"}
    for kind, text in helps.items():
        p = csub.add_parser(kind, help=text, description=text)
        p.add_argument("measurement", help="measurement CSV file")
        p.add_argument("--machine", help="machine TOML (default: the built-in AB head)")
        p.add_argument("--base", help="model JSON to start from; its other parts are kept")
        p.add_argument("-o", "--output", required=True, help="model JSON to write")
        p.add_argument("--report", help="also write the calibration report as JSON")
        if kind == "spindle":
            p.add_argument("--no-pso", action="store_true", help="skip the particle-swarm comparison")
            p.add_argument("--seed", type=int, default=0, help="PSO seed (default 0)")
        p.set_defaults(func=calibrate_cli, calibrate_kind=kind)

    sim = subparsers.add_parser("simulate", help="write simulated measurement files from an error model")
    ssub = sim.add_subparsers(dest="simulate_kind", metavar="KIND", required=True)
    for kind, text in (("probe", "reference-sphere probing"), ("spindle", "spindle-analyser data"),
                       ("ballbar", "ballbar cone test")):
        p = ssub.add_parser(kind, help=text, description=f"Simulate {text} from an error model.")
        p.add_argument("--model", required=True, help="error model JSON")
        p.add_argument("--machine", help="machine TOML (default: the built-in AB head)")
        p.add_argument("--noise", type=float, default=None,
                       help="measurement noise, mm (one standard deviation)")
        p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
        p.add_argument("-o", "--output", required=True, help="CSV file to write")
        if kind == "probe":
            p.add_argument("--grid", type=int, default=11, help="N x N grid of A, B poses (default 11)")
            p.add_argument("--max-angle", type=float, default=100.0, help="grid extent, +-deg (default 100)")
        elif kind == "spindle":
            p.add_argument("--exts", default="50,150",
                           help="ball extensions beyond the collet, mm (default 50,150)")
            p.add_argument("--revolutions", type=int, default=3)
            p.add_argument("--samples", type=int, default=72, help="samples per revolution (default 72)")
        elif kind == "ballbar":
            p.add_argument("--bar-length", type=float, default=150.0, help="mm (default 150)")
            p.add_argument("--angles", default="30,60", help="bar angles, deg (default 30,60)")
            p.add_argument("--step", type=float, default=0.1,
                           help="sample spacing on the circle, deg (default 0.1)")
            p.add_argument("--interval", type=float, default=900.0, help="time between sets, s (default 900)")
            p.add_argument("--duration", type=float, default=14400.0, help="s (default 14400)")
            p.add_argument("--heat", type=float, default=10800.0, help="spindle runs until this time, s")
            p.add_argument("--rpm", type=float, default=5000.0,
                           help="spindle speed while running (default 5000)")
        p.set_defaults(func=simulate_cli, simulate_kind=kind)
    # `simulate recording` belongs to camsmooth.diagnosis.engine: its arguments come from there, the
    # handler is imported only when the sub-command runs.
    p = ssub.add_parser("recording", help="a machine recording (diagnosis)",
                        description="Simulate a machine recording from a program and a model "
                        "(camsmooth.diagnosis.engine).")
    from camsmooth.diagnosis.engine import add_simulate_recording_arguments

    add_simulate_recording_arguments(p)
    p.set_defaults(func=simulate_cli, simulate_kind="recording")

    pred = subparsers.add_parser("predict", help="predict the real tool tip and axis of a tool program",
                                 description="Real tool tip and axis for every commanded pose of a "
                                 "smoothing output CSV (columns A, B in deg and X, Y, Z in mm at least), "
                                 "their deviation from the ideal, and lead/tilt (and a first-order "
                                 "clearance estimate) re-evaluated on the real axis.")
    pred.add_argument("input", help="smoothing output CSV (camsmooth smooth -o)")
    pred.add_argument("--model", required=True, help="error model JSON")
    pred.add_argument("--machine", help="machine TOML (default: the built-in AB head)")
    pred.add_argument("-o", "--output", help="CSV to write (default: INPUT_predicted.csv beside the input)")
    pred.add_argument("--rpm", type=float, default=None,
                      help="spindle speed from the program start, for thermal drift (time = the file's t, "
                      "rows run one after another)")
    pred.set_defaults(func=predict_cli)


def _floats(text: str, what: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise InputError(f"{what}: expected comma-separated numbers, got {text!r}") from None


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
    from camsmooth.io.atomic import write_text_atomic
    from camsmooth.machine import calibration
    from camsmooth.machine.model import ErrorModel

    base = ErrorModel.from_json(args.base) if args.base else None
    kind = args.calibrate_kind
    if kind == "probe":
        report = calibration.calibrate_probe(args.measurement, _machine(args), base)
    elif kind == "spindle":
        report = calibration.calibrate_spindle(args.measurement, base, pso_compare=not args.no_pso,
                                               seed=args.seed)
    else:
        report = calibration.calibrate_ballbar(args.measurement, base)
    print(report.summary())
    report.model.to_json(args.output)
    if args.report:
        write_text_atomic(args.report, json.dumps(_report_json(report), indent=1, default=str) + "\n")
    print(f"wrote {args.output}")
    return 0


def simulate_cli(args: argparse.Namespace) -> int:
    """`camsmooth simulate KIND`: write a simulated measurement file."""
    kind = args.simulate_kind
    if kind == "recording":
        from camsmooth.diagnosis.engine import simulate_recording_cli

        return simulate_recording_cli(args)
    from camsmooth.machine import calibration, simulate
    from camsmooth.machine.model import ErrorModel

    model = ErrorModel.from_json(args.model)
    noise = simulate.DEFAULT_NOISE[kind] if args.noise is None else args.noise
    if noise < 0:
        raise InputError(f"--noise must be >= 0 mm, got {noise}")
    if kind == "probe":
        machine = _machine(args)
        poses = simulate.default_probe_poses(machine, args.grid, args.max_angle)
        data = simulate.simulate_probe(model, machine, poses=poses, noise=noise, seed=args.seed)
        calibration.write_probe_csv(args.output, data)
    elif kind == "spindle":
        data = simulate.simulate_spindle(model, exts=_floats(args.exts, "--exts"),
                                         revolutions=args.revolutions, samples_per_rev=args.samples,
                                         noise=noise, seed=args.seed)
        calibration.write_spindle_csv(args.output, data)
    else:
        times, rpm = simulate.default_ballbar_schedule(args.duration, args.interval, args.heat, args.rpm)
        data = simulate.simulate_ballbar(model, _machine(args), times=times, rpm=rpm,
                                         bar_length=args.bar_length,
                                         angles_deg=_floats(args.angles, "--angles"), step_deg=args.step,
                                         noise=noise, seed=args.seed)
        calibration.write_ballbar_csv(args.output, data)
    print(f"wrote {args.output}")
    return 0


def predict_cli(args: argparse.Namespace) -> int:
    """`camsmooth predict`: real tool pose per commanded pose, written as CSV, summary printed."""
    from camsmooth.io.atomic import atomic_path
    from camsmooth.io.output import read_result_csv
    from camsmooth.machine.model import ErrorModel

    model = ErrorModel.from_json(args.model)
    machine = _machine(args)
    cols = read_result_csv(args.input, required=("A", "B", "X", "Y", "Z"))
    table = predict_table(model, machine, cols, args.rpm, source=args.input)
    src = Path(args.input)
    out = Path(args.output) if args.output else src.with_name(src.stem + "_predicted.csv")
    names = list(cols) + [k for k in table if k not in cols]
    data = {**cols, **table}
    with atomic_path(out) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(names)
            for i in range(len(data["A"])):
                w.writerow([_cell(data[k][i]) for k in names])
    dev, ang = table["tip_dev_um"], table["axis_dev_urad"]
    print(f"{len(dev)} poses: tool-tip deviation max {dev.max():.3f} um, mean {dev.mean():.3f} um; "
          f"tool-axis deviation max {ang.max():.3f} urad, mean {ang.mean():.3f} urad")
    if "real_lead" in table:
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
    """Prediction columns for a result table (angles in deg as in the file): real tip (real_clx,
    real_cly, real_clz, mm), real axis (real_i, real_j, real_k), tip_dev_um, axis_dev_urad and,
    when the table has CC points, normals, lead and tilt: real_lead, real_tilt (deg) = the file's
    value plus the change of lead/tilt from the ideal to the real axis in the local frame
    (METHODS section 1; feed direction from the CC points along each row), and, with a
    ``delta`` column, real_delta_est = delta + (displacement of the cutter at the CC point) . n,
    a first-order clearance estimate valid where the closest approach is at the contact."""
    A, B = np.radians(cols["A"]), np.radians(cols["B"])
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
