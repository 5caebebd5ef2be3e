"""Command line: a thin layer over the Python API (degrees and mm/min here, radians inside).

Verbs: smooth, path, demo (this module); calibrate, simulate, predict (camsmooth.cli.model);
diagnose (camsmooth.cli.diagnose). Errors from bad input print one message and exit 2.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from camsmooth.errors import CamsmoothError, InputError

DEFAULT_TOLERANCE_MM = 0.005  # camsmooth.smoothing.pipeline.DEFAULT_TOLERANCE (not imported: keep --help light)
SAMPLES_DIR = Path(__file__).resolve().parents[2] / "surfaces"


def _range(text: str, option: str) -> tuple[float, float]:
    try:
        lo, hi = (float(v) for v in text.split(":"))
    except ValueError:
        raise InputError(f"{option} expects MIN:MAX in degrees, got {text!r}") from None
    if not (np.isfinite(lo) and np.isfinite(hi)) or lo > hi:
        raise InputError(f"{option} expects MIN:MAX with MIN <= MAX, got {text!r}")
    return lo, hi


def _cutter(args: argparse.Namespace):
    from camsmooth.geometry.cutter import ToroidalCutter

    kw = {}
    if args.shank_length is not None:
        kw["shank_length"] = args.shank_length
    if args.holder_radius is not None:
        kw["holder_radius"] = args.holder_radius
        kw["holder_length"] = args.holder_length
    return ToroidalCutter(R=args.cutter_radius, r=args.corner_radius, **kw)


def _add_cutter_args(p: argparse.ArgumentParser, required: bool = True) -> None:
    p.add_argument("--cutter-radius", type=float, required=required, metavar="R",
                   help="ring radius R (mm); the cutter diameter is 2(R + r)")
    p.add_argument("--corner-radius", type=float, required=required, metavar="r", help="corner radius r (mm)")
    p.add_argument("--shank-length", type=float, default=None, metavar="L",
                   help="length of the cylindrical part from the tip (mm, default 4 x (R + r))")
    p.add_argument("--holder-radius", type=float, default=None, help="tool holder radius (mm, optional)")
    p.add_argument("--holder-length", type=float, default=40.0, help="tool holder length (mm, default 40)")


def run_smooth(args: argparse.Namespace) -> int:
    from camsmooth.geometry.paths import read_cc_csv
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.output import write_gcode, write_result_csv
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.smoothing.pipeline import SmoothOptions, smooth

    lead = _range(args.lead, "--lead")
    tilt = _range(args.tilt, "--tilt")
    model = None
    if args.model is not None:
        from camsmooth.machine.model import ErrorModel

        model = ErrorModel.from_json(args.model)
    options = SmoothOptions(workers=args.workers, dask=args.dask)
    result = smooth(read_cc_csv(args.path), load_surface(args.surface), load_machine(args.machine), _cutter(args),
                    feed=args.feed, lead_range=tuple(np.radians(lead)), tilt_range=tuple(np.radians(tilt)),
                    method=args.method, prefer_lead=None if args.prefer_lead is None else np.radians(args.prefer_lead),
                    prefer_tilt=None if args.prefer_tilt is None else np.radians(args.prefer_tilt),
                    model=model, compensate=args.compensate, tolerance=args.tolerance, options=options,
                    progress=not args.quiet)
    _write_outputs(result, args.output, args.gcode, args.report, args.feed, args.quiet, write_result_csv,
                   write_gcode)
    return 1 if (result.result.metrics["unclean_rows"] or result.result.metrics["unreachable"]) and args.strict else 0


def _write_outputs(result, out_csv, gcode, report, feed, quiet, write_result_csv, write_gcode) -> None:
    write_result_csv(out_csv, result)
    if gcode:
        f = float(feed) if feed else float(np.median(result.inputs["feed"]))
        write_gcode(gcode, result, result.machine, result.cutter, f)
    if report:
        from camsmooth.report.smoothing import write_report

        write_report(result, report)
    if not quiet:
        _print_summary(result)


def _print_summary(result) -> None:
    head = ("method", "Gamma", "peak|A''|", "peak|B''|", "min delta", "violations", "time s")
    print("{:8s} {:>12s} {:>10s} {:>10s} {:>10s} {:>10s} {:>8s}".format(*head))
    for name, r in result.methods.items():
        m = r.metrics
        nviol = sum(m["violations"].values())
        print(f"{name:8s} {m['gamma']:12.4g} {m['peak_A_acc']:10.4g} {m['peak_B_acc']:10.4g} "
              f"{m['min_delta']:10.4g} {nviol:10d} {m['runtime_s']:8.2f}")
    m = result.result.metrics
    if m["unclean_rows"]:
        print(f"WARNING: rows not clean without lifting along the normal: {m['unclean_rows']}", file=sys.stderr)
    if m["unreachable"]:
        print(f"WARNING: {len(m['unreachable'])} unreachable points, first {m['unreachable'][:5]}", file=sys.stderr)


def run_path(args: argparse.Namespace) -> int:
    from camsmooth.geometry.paths import raster_path_on_mesh, write_cc_csv, zigzag_path
    from camsmooth.geometry.surfaces import load_surface

    surf = load_surface(args.surface)
    if surf.parametric is not None and not args.raster:
        cc = zigzag_path(surf.parametric, args.stepover, args.spacing, along=args.along)
    else:
        from camsmooth.geometry.clearance import axial_drop

        if args.cutter_radius is None or args.corner_radius is None:
            raise InputError("a raster path on a mesh needs --cutter-radius and --corner-radius")
        axis = np.array([float(v) for v in args.axis.split(",")])
        if axis.shape != (3,) or not np.isfinite(axis).all() or np.linalg.norm(axis) == 0:
            raise InputError(f"--axis expects three numbers i,j,k, got {args.axis!r}")
        cc = raster_path_on_mesh(surf.mesh, _cutter(args), axis / np.linalg.norm(axis), args.stepover,
                                 args.spacing, axial_drop)
    if args.feed is not None:
        cc.feed = np.full(len(cc.points), float(args.feed))
    write_cc_csv(args.output, cc)
    if not args.quiet:
        print(f"wrote {len(cc.points)} CC points in {len(cc.row_slices())} rows to {args.output}")
    return 0


def run_demo(args: argparse.Namespace) -> int:
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.io.output import write_gcode, write_result_csv
    from camsmooth.smoothing.pipeline import smooth

    samples = Path(args.samples) if args.samples else SAMPLES_DIR
    name = args.sample
    path, mesh = samples / f"{name}_path.csv", samples / f"{name}.ply"
    if not path.exists() or not mesh.exists():
        raise InputError(f"sample {name!r} not found in {samples} (expected {path.name} and {mesh.name})")
    out = Path(args.out)
    cutter = ToroidalCutter(R=4.0, r=1.0)
    if not args.quiet:
        print(f"camsmooth demo: smoothing {path} on {mesh} (toroidal cutter R=4 r=1 mm, lead 2:20, tilt -15:15 deg, "
              f"default AB head) -> {out}/")
    from camsmooth.geometry.paths import read_cc_csv
    from camsmooth.geometry.surfaces import load_surface

    result = smooth(read_cc_csv(path), load_surface(mesh), None, cutter, feed=2000.0,
                    lead_range=tuple(np.radians([2.0, 20.0])),
                    tilt_range=tuple(np.radians([-15.0, 15.0])), method="nlp", progress=not args.quiet)
    _write_outputs(result, out / f"{name}_smoothed.csv", out / f"{name}_smoothed.nc", out / "report", 2000.0,
                   args.quiet, write_result_csv, write_gcode)
    if not args.quiet:
        csv, nc, html = out / f"{name}_smoothed.csv", out / f"{name}_smoothed.nc", out / "report" / "report.html"
        print(f"wrote {csv}, {nc} and {html}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="camsmooth", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="verb", required=True)

    p = sub.add_parser("smooth", help="smooth a CC path: tool axes, A/B angles, interference check")
    p.add_argument("path", help="CC path CSV (x,y,z,nx,ny,nz[,row,fx,fy,fz,feed])")
    p.add_argument("--surface", required=True, help="surface mesh (.stl/.obj/.ply) or definition (.toml)")
    p.add_argument("--machine", default=None, help="machine TOML (default: the built-in AB head)")
    _add_cutter_args(p)
    p.add_argument("--feed", type=float, default=None, help="programmed feed F (mm/min) where the CSV has none")
    p.add_argument("--lead", required=True, help="lead window MIN:MAX (deg), 0 <= MIN < MAX < 90")
    p.add_argument("--tilt", required=True, help="tilt window MIN:MAX (deg), -90 < MIN <= MAX < 90")
    p.add_argument("--prefer-lead", type=float, default=None, help="preferred lead (deg; default window middle)")
    p.add_argument("--prefer-tilt", type=float, default=None, help="preferred tilt (deg; default window middle)")
    p.add_argument("--method", choices=("nlp", "spline", "none"), default="nlp")
    p.add_argument("--tolerance", type=float, default=DEFAULT_TOLERANCE_MM, metavar="MM",
                   help=f"the part's allowed deviation (mm, default {DEFAULT_TOLERANCE_MM:g}): a clearance below "
                   "-MM is a gouge, for every clearance decision")
    p.add_argument("--workers", type=int, default=None, metavar="N",
                   help="processes for the rows (default: all cores for programs of 5000 points or more)")
    p.add_argument("--dask", default=None, metavar="ADDRESS",
                   help="run the rows on a Dask cluster: a scheduler address, or 'local' for a LocalCluster "
                   "(pip install 'camsmooth[dask]')")
    p.add_argument("--model", default=None, help="machine error model JSON: smooth the predicted real axis")
    p.add_argument("--compensate", action="store_true", help="with --model: command the axes so the "
                   "predicted real tool tip is the ideal one")
    p.add_argument("-o", "--output", required=True, help="output CSV")
    p.add_argument("--gcode", default=None, help="also write G-code (G01 X Y Z A B F)")
    p.add_argument("--report", default=None, help="also write a report folder (PNG plots, render, report.html)")
    p.add_argument("--strict", action="store_true", help="exit 1 when a row needed the lift fallback")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=run_smooth)

    p = sub.add_parser("path", help="generate a CC path: zig-zag on a definition, or raster by axial drop on a mesh")
    p.add_argument("--surface", required=True, help="surface definition (.toml) or mesh")
    p.add_argument("--stepover", type=float, required=True, help="distance between rows (mm)")
    p.add_argument("--spacing", type=float, required=True, help="distance between points along a row (mm)")
    p.add_argument("--along", choices=("u", "v"), default="u", help="iso-parametric direction of the rows")
    p.add_argument("--raster", action="store_true", help="raster rows by axial drop even for a definition")
    p.add_argument("--axis", default="0,0,1", help="fixed tool axis i,j,k for the axial drop (default 0,0,1)")
    _add_cutter_args(p, required=False)
    p.add_argument("--feed", type=float, default=None, help="write this feed (mm/min) into the CSV")
    p.add_argument("-o", "--output", required=True)
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run_path)

    p = sub.add_parser("demo", help="smooth a shipped sample and write the CSV, G-code and report")
    p.add_argument("--out", default="demo_out", help="output folder (default demo_out)")
    p.add_argument("--sample", default="blade", help="sample name in surfaces/ (blade, saddle, mould)")
    p.add_argument("--samples", default=None, help="folder of the samples (default: the repository's surfaces/)")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=run_demo)

    for module in ("model", "diagnose"):
        try:
            mod = __import__(f"camsmooth.cli.{module}", fromlist=["register"])
        except ImportError:
            continue
        mod.register(sub)
    return parser


RANGE_OPTIONS = ("--lead", "--tilt")


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


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(_join_ranges(list(sys.argv[1:] if argv is None else argv)))
    try:
        return int(args.func(args) or 0)
    except CamsmoothError as exc:
        print(f"camsmooth: error: {exc}", file=sys.stderr)
        return 2
    except FileNotFoundError as exc:
        print(f"camsmooth: error: {exc.filename}: file not found", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
