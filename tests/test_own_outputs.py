"""Issue 19, part 1: one reading of a program. ``analyze`` of every program ``smooth`` wrote (each
method, result CSV and G-code) reproduces the figures smooth reported for it: Gamma and cycle
times within 0.1 %, violation counts (under the planned time law and at the programmed feed)
equal. camsmooth's G-code carries its tool, so ``smooth`` of it needs no --cutter-radius."""

from __future__ import annotations

import dataclasses
import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from camsmooth.cli.main import _write_outputs, main
from camsmooth.geometry.cutter import ToroidalCutter
from camsmooth.geometry.paths import CCPath
from camsmooth.io.program import detect_format
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, machine_from_dict
from camsmooth.post import load_program

ROOT = Path(__file__).resolve().parent.parent / "surfaces"
AXES = [f"{a} {k}" for a in "XYZAB" for k in ("travel", "velocity", "acceleration")]


def _machine(dialect: str):
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["post"] = {"dialect": dialect, "mode": "machine"}
    return machine_from_dict(data, "<test machine>")


def _smooth(dialect: str):
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import smooth

    path = read_cc_csv(ROOT / "blade_path.csv")
    k = np.isin(path.rows, np.unique(path.rows)[12:16])  # four rows, 800 points
    path = CCPath(points=path.points[k], normals=path.normals[k], rows=path.rows[k], feed_dirs=path.feed_dirs[k],
                  feed=path.feed[k], source=str(ROOT / "blade_path.csv"))
    return smooth(path, load_surface(ROOT / "blade.ply"), _machine(dialect), ToroidalCutter(R=4.0, r=1.0),
                  lead_range=tuple(np.radians([2.0, 20.0])), tilt_range=tuple(np.radians([-15.0, 15.0])),
                  method="nlp", tolerance=0.005)


@pytest.fixture(scope="module")
def generic():
    return _smooth("generic")


@pytest.fixture(scope="module")
def linuxcnc():
    return _smooth("linuxcnc")


def _write(res, method: str, folder: Path) -> tuple[Path, Path]:
    """The outputs ``smooth --method METHOD -o CSV --gcode NC`` writes (the CLI's own writer)."""
    one = dataclasses.replace(res, primary=method)
    csv, nc = folder / f"{method}.csv", folder / f"{method}.nc"
    _write_outputs(one, csv, nc, None, None)
    return csv, nc


def _analyze(file: Path, tmp_path: Path, *extra: str) -> dict:
    out = tmp_path / (file.name + ".json")
    assert main(["analyze", str(file), "--json", str(out), "--quiet", *extra]) == 0
    (tp,) = json.loads(out.read_text())["toolpaths"]
    return tp


@pytest.mark.parametrize("method", ["none", "spline", "nlp"])
def test_analyze_of_every_output_reproduces_what_smooth_reported(generic, method, tmp_path):
    m = generic.methods[method].metrics
    csv, nc = _write(generic, method, tmp_path)
    assert detect_format(csv) == "result-csv"
    for file in (csv, nc):
        tp = _analyze(file, tmp_path)
        assert tp["method"] == (method if file == nc else None)
        assert tp["gamma"] == pytest.approx(m.gamma, rel=1e-3), file.name
        assert tp["cycle_time_optimal_s"] == pytest.approx(m.cycle_time_optimal_s, rel=1e-3), file.name
        assert tp["cycle_time_s"] == pytest.approx(m.cycle_time_s, rel=1e-3), file.name
        assert {k: tp["violations"][k] for k in AXES} == {k: m.violations[k] for k in AXES}, file.name
        assert ({k: tp["violations_programmed"][k] for k in AXES}
                == {k: m.violations_programmed[k] for k in AXES}), file.name
        assert tp["rows"] == [int(r) for r in np.unique(generic.result.rows)]
    # the result CSV carries the clearance and status smooth wrote: the gouges are counted as smooth did
    tp = _analyze(csv, tmp_path)
    assert tp["violations"]["interference"] == m.violations["interference"]
    assert tp["clearance"]["min_mm"] == pytest.approx(m.min_delta)


def test_the_baseline_is_not_what_a_smoothed_csv_reports(generic, tmp_path):
    """Before: analyze of a smoothed result CSV read it as a CC path and reported the unsmoothed
    baseline (a constant lead), and --format cl-csv took the CC points for tool tips."""
    csv, _ = _write(generic, "nlp", tmp_path)
    nlp, none = generic.methods["nlp"].metrics, generic.methods["none"].metrics
    assert abs(nlp.gamma / none.gamma - 1) > 0.5  # the check below can tell them apart
    for extra in ((), ("--format", "cl-csv")):
        tp = _analyze(csv, tmp_path, *extra)
        assert tp["gamma"] == pytest.approx(nlp.gamma, rel=1e-3)
    prog = load_program(csv, "cl-csv")
    np.testing.assert_allclose(prog.tip, generic.result.cl)


def test_linuxcnc_program_reproduces_both_cycle_times(linuxcnc, tmp_path):
    """A LinuxCNC program is written in longer blocks: its analysis times those blocks with the
    same controller model (cycle times reproduce); the result CSV has every point (all figures)."""
    for method in ("none", "nlp"):
        m = linuxcnc.methods[method].metrics
        assert m.controller == "linuxcnc"
        csv, nc = _write(linuxcnc, method, tmp_path)
        toml = DEFAULT_MACHINE_TOML.replace('dialect = "generic"', 'dialect = "linuxcnc"')
        (tmp_path / "m.toml").write_text(toml)
        for file, extra in ((csv, ("--machine", str(tmp_path / "m.toml"))), (nc, ())):
            tp = _analyze(file, tmp_path, *extra)
            assert tp["controller"] == "linuxcnc"
            assert tp["cycle_time_optimal_s"] == pytest.approx(m.cycle_time_optimal_s, rel=1e-3), file.name
            assert tp["cycle_time_s"] == pytest.approx(m.cycle_time_s, rel=1e-3), file.name
        tp = _analyze(csv, tmp_path, "--machine", str(tmp_path / "m.toml"))
        assert tp["gamma"] == pytest.approx(m.gamma, rel=1e-3)
        assert {k: tp["violations"][k] for k in AXES} == {k: m.violations[k] for k in AXES}


def test_written_rounding_is_not_a_violation(generic, tmp_path):
    """The G-code's 4-decimal angles move a second difference by up to 4 e / (h_l h_r): a program
    smooth found clean under its planned law is not made to violate by its own rounding."""
    m = generic.methods["nlp"].metrics
    assert sum(m.violations[k] for k in AXES) == 0
    _, nc = _write(generic, "nlp", tmp_path)
    tp = _analyze(nc, tmp_path)
    assert sum(tp["violations"][k] for k in AXES) == 0
    assert tp["peaks"]["B acceleration"] > 0.99 * 300.0  # the limit binds: rounding is what the rule allows for


def test_smooth_of_camsmooth_gcode_takes_the_tool_from_its_header(generic, tmp_path, capsys):
    _, nc = _write(generic, "nlp", tmp_path)
    prog = load_program(nc)
    tool = prog.toolpaths[0].tool
    assert (tool.diameter, tool.corner_radius, tool.ring_radius) == (10.0, 1.0, 4.0)
    assert prog.written.method == "nlp" and prog.written.tolerance == 0.005
    rc = main(["smooth", str(nc), "--surface", str(ROOT / "blade.ply"), "--lead", "2:20", "--tilt=-15:15",
               "--method", "none", "-o", str(tmp_path / "again.csv"), "--quiet"])
    assert rc == 0, capsys.readouterr().err
    assert (tmp_path / "again.csv").exists()


def test_gcode_header_has_no_python_reprs(generic, tmp_path):
    _, nc = _write(generic, "nlp", tmp_path)
    head = "\n".join(ln for ln in nc.read_text().splitlines()[:40] if ln.startswith("("))
    for bad in ("array(", "np.float64", "Machine(", "nan", "(0.0349"):
        assert bad not in head, bad
    assert "lead window: 2 to 20 deg" in head and "tolerance: 0.005 mm" in head


@pytest.mark.parametrize(("dialect", "mode"), [("siemens", "tcp"), ("heidenhain", "tcp"), ("fanuc", "machine"),
                                               ("linuxcnc", "tcp")])
def test_every_dialect_carries_the_programmed_time_and_the_planned_law(generic, dialect, mode, tmp_path):
    from camsmooth.smoothing.feed import block_feeds
    from camsmooth.smoothing.posting import write_gcode

    r = generic.result
    feed = block_feeds(r.plan, r.cl, r.rows, np.asarray(generic.inputs["feed"], float))
    nc = write_gcode(tmp_path / f"{dialect}.nc", generic, generic.machine, generic.cutter, feed, dialect=dialect,
                     mode=mode)
    prog = load_program(nc).cutting()
    w = prog.written
    assert w.method == "nlp" and w.tolerance == 0.005 and w.dialect == dialect
    np.testing.assert_allclose(w.t, r.t, atol=1e-9)
    np.testing.assert_allclose(w.feed, generic.inputs["feed"])
    np.testing.assert_array_equal(w.row_id, r.rows)
    ends = np.r_[np.flatnonzero(np.diff(prog.rows)), len(prog.rows) - 1]
    assert float(w.t_plan[ends].sum()) == pytest.approx(r.metrics.cycle_time_optimal_s, rel=1e-3)


def test_times_that_do_not_increase_are_not_a_time_base(generic, tmp_path):
    """A program written from times that do not increase along a row (no programmed-feed time)
    is read without one: analyze then times it from the tips at the feed."""
    from camsmooth.smoothing.posting import write_gcode

    r = dataclasses.replace(generic.result, t=np.zeros(len(generic.result)), plan=None)
    nc = write_gcode(tmp_path / "z.nc", r, generic.machine, generic.cutter, 2000.0)
    assert load_program(nc).written.t is None


def _smooth_cli(argv: list[str]):
    """What ``camsmooth smooth ARGV`` computes (its parser, input loader and pipeline), and the
    outputs it writes (-o, --gcode)."""
    from camsmooth.cli.main import build_parser, load_error_model, load_input
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.smoothing.pipeline import smooth

    args = build_parser().parse_args(["smooth", *argv])
    surface, machine = load_surface(args.surface), load_machine(args.machine)
    program, cutter = load_input(args, surface, machine)
    res = smooth(program, surface, machine, cutter, feed=args.feed, lead_range=tuple(np.radians(args.lead)),
                 tilt_range=tuple(np.radians(args.tilt)), model=load_error_model(args.model),
                 compensate=args.compensate, tolerance=args.tolerance)
    _write_outputs(res, Path(args.output), Path(args.gcode), None, args.feed)
    return res


@pytest.fixture(scope="module")
def cam_inputs(tmp_path_factory):
    """Two blade rows as a CAM system writes them: NX CLSF (constant 11 deg lead), the same as a CL
    CSV, and camsmooth's own G-code of them."""
    from camsmooth.geometry.cutter import cc_to_cl
    from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames
    from camsmooth.io.ccpath import read_cc_csv

    folder = tmp_path_factory.mktemp("cam")
    path = read_cc_csv(ROOT / "blade_path.csv")
    k = np.isin(path.rows, np.unique(path.rows)[12:14])
    pts, nrm, fd, rows = path.points[k], path.normals[k], path.feed_dirs[k], path.rows[k]
    cutter = ToroidalCutter(R=4.0, r=1.0)
    T = axis_from_lead_tilt(np.full(len(pts), np.radians(11.0)), np.zeros(len(pts)), local_frames(nrm, fd))
    tip = cc_to_cl(cutter, pts, nrm, T)
    lines = ["TOOL PATH/FINISH,TOOL,MILL", "TLDATA/MILL,10.0000,1.0000,60.0000,0.0000,0.0000", "LOAD/TOOL,1",
             "FEDRAT/MMPM,2000.0000"]
    csv = ["x,y,z,i,j,k,row,feed"]
    for r in np.unique(rows):
        s = rows == r
        up = tip[s][0] + 10 * T[s][0]
        lines += ["RAPID", "GOTO/" + ",".join(f"{v:.6f}" for v in (*up, *T[s][0]))]
        lines += ["GOTO/" + ",".join(f"{v:.6f}" for v in (*p, *a)) for p, a in zip(tip[s], T[s], strict=True)]
        csv += [",".join(f"{v:.6f}" for v in (*p, *a)) + f",{int(r)},2000" for p, a in zip(tip[s], T[s], strict=True)]
    (folder / "p.cls").write_text("\n".join(lines + ["END-OF-PATH"]) + "\n")
    (folder / "p_cl.csv").write_text("\n".join(csv) + "\n")
    _smooth_cli([str(folder / "p.cls"), "--surface", str(ROOT / "blade.ply"), "--lead", "2:20", "--tilt=-15:15",
                 "-o", str(folder / "first.csv"), "--gcode", str(folder / "p.nc")])
    return folder


MODEL = Path(__file__).resolve().parent.parent / "examples" / "data" / "demo_model.json"


@pytest.mark.parametrize("model", [None, MODEL], ids=["nominal", "error-model"])
@pytest.mark.parametrize("source", ["p.cls", "p_cl.csv", "p.nc"])
def test_analyze_reproduces_smooth_for_every_input_format_with_and_without_the_error_model(cam_inputs, source,
                                                                                          model, tmp_path):
    """smooth of an APT/CLSF program, a CL CSV and camsmooth's own G-code, nominal and with an
    error model (the program as the real machine executes it): analyze of the nlp result CSV and
    G-code (with the same model and the surface) reproduces Gamma, the cycle time, the violation
    counts and the worst clearance smooth computed."""
    extra = ["--model", str(model)] if model else []
    tool = ["--cutter-radius", "4", "--corner-radius", "1"] if source.endswith(".csv") else []  # a CL CSV has none
    out_csv, out_nc = tmp_path / "o.csv", tmp_path / "o.nc"
    res = _smooth_cli([str(cam_inputs / source), "--surface", str(ROOT / "blade.ply"), "--lead", "2:20",
                       "--tilt=-15:15", "-o", str(out_csv), "--gcode", str(out_nc), *tool, *extra])
    assert "cam" in res.methods  # a CL program is also analysed as it is
    m = res.result.metrics
    for file in (out_csv, out_nc):
        tp = _analyze(file, tmp_path, "--surface", str(ROOT / "blade.ply"), *extra)
        assert tp["gamma"] == pytest.approx(m.gamma, rel=1e-3), file.name
        assert tp["cycle_time_s"] == pytest.approx(m.cycle_time_s, rel=1e-3), file.name
        assert {k: tp["violations"][k] for k in AXES} == {k: m.violations[k] for k in AXES}, file.name
        assert tp["violations"]["interference"] == m.violations["interference"], file.name
        assert tp["clearance"]["min_mm"] == pytest.approx(m.min_delta, abs=1e-4), file.name
