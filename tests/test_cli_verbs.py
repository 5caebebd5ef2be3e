"""Command-line verbs without a test of their own before issue 12: ``smooth --strict``, the stderr
naming of unclean rows, ``demo`` and ``path``.

The CLI runs in process (camsmooth.cli.main.main). Expected values come from geometry written
here: a roof plate 3 mm above a plane (a tool touching the plane under it must rise above the
plate), the wave sample's closed form z = cz + a sin(kx (x - cx)) sin(ky (y - cy)) read from its
TOML, the toroidal CC -> CL formula of CONVENTIONS.md, and the demo's limits recomputed from its
CSV with the test's own finite differences (tests/test_limits_bind.py's helpers).
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
import re
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest
import trimesh

from camsmooth.cli.main import main
from camsmooth.geometry.paths import CCPath
from camsmooth.geometry.surfaces import Plane, tessellate_to_tolerance
from camsmooth.io.ccpath import write_cc_csv
from tests.conftest import ROOT, snapshot
from tests.test_limits_bind import own_axis, own_lead_tilt, own_times, usage, violated

SAMPLES = ROOT / "surfaces"


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """Columns of a CSV by name (numbers as float, anything else as str), read with the csv module."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    cols = {}
    for k, name in enumerate(rows[0]):
        values = [r[k] for r in rows[1:]]
        try:
            cols[name] = np.array([float(v) for v in values])
        except ValueError:
            cols[name] = np.array(values)
    return cols


def run(capsys, argv) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ----------------------------------------------------------------------------------------------
# a row that cannot be made clean: a roof plate 3 mm above the plane over x in [19.5, 20.5],
# |y| <= 0.5. Row 4 runs under it (y = 0); rows 3 and 5 (y = 10, 14) pass beside it, further from
# it than the tool's radius R + r = 5 mm plus what a 15 deg tilt adds 3 mm up (0.8 mm).
ROOF_X, ROOF_Z = 20.0, 3.0
TOL = 1e-3  # mm


@pytest.fixture(scope="module")
def roof(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("roof")
    plane = tessellate_to_tolerance(Plane(u_range=(-5.0, 45.0), v_range=(-10.0, 20.0)), 1e-3)
    plate = trimesh.Trimesh(vertices=[[ROOF_X - 0.5, -0.5, ROOF_Z], [ROOF_X + 0.5, -0.5, ROOF_Z],
                                      [ROOF_X + 0.5, 0.5, ROOF_Z], [ROOF_X - 0.5, 0.5, ROOF_Z]],
                            faces=[[0, 1, 2], [0, 2, 3]])
    trimesh.util.concatenate([plane, plate]).export(d / "roof.ply")
    x = np.arange(0.0, 40.01, 1.0)
    rows = {3: 10.0, 4: 0.0, 5: 14.0}
    pts, ids = [], []
    for k, (row, y) in enumerate(rows.items()):
        xs = x if k % 2 == 0 else x[::-1]
        pts.append(np.column_stack([xs, np.full_like(xs, y), np.zeros_like(xs)]))
        ids += [row] * len(xs)
    pts = np.concatenate(pts)
    ids = np.array(ids)
    for name, sel in (("roof_path.csv", np.ones(len(ids), bool)), ("clear_path.csv", ids != 4)):
        write_cc_csv(d / name, CCPath(pts[sel], np.tile([0.0, 0.0, 1.0], (sel.sum(), 1)), ids[sel],
                                      feed=np.full(sel.sum(), 1000.0)))
    return d


def _smooth_argv(folder: Path, path: str, *extra: str) -> list[str]:
    return ["smooth", str(folder / path), "--surface", str(folder / "roof.ply"), "--cutter-radius", "4",
            "--corner-radius", "1", "--lead", "2:20", "--tilt", "-15:15", "--tolerance", str(TOL), *extra]


@pytest.fixture(scope="module")
def roof_run(roof, tmp_path_factory):
    """The roof program smoothed without --strict (not quiet): exit status, its CSV and stderr."""
    out = tmp_path_factory.mktemp("roof_out") / "out.csv"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(_smooth_argv(roof, "roof_path.csv", "-o", str(out)))
    return code, out, err.getvalue()


def test_strict_refuses_a_row_that_cannot_be_made_clean(roof, roof_run, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out.csv").write_text("an earlier run's output\n")  # a user file at the output's name
    before = snapshot(tmp_path)
    code, _, err = run(capsys, _smooth_argv(roof, "roof_path.csv", "-o", "out.csv", "--gcode", "out.nc",
                                            "--strict", "--quiet"))
    assert code == 1, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in err, err
    msg = lines[0]
    assert snapshot(tmp_path) == before, "--strict wrote or removed something"
    # the message names row 4 (and no other row) and the largest lift of that row
    assert re.findall(r"\brow (\d+)", msg) == ["4"], msg
    res = read_csv(roof_run[1])
    row4 = res["row"] == 4
    assert set(res["row"][res["lift"] > TOL].astype(int)) == {4}
    largest = res["lift"][row4].max()
    m = re.search(r"largest lift ([0-9.eE+-]+) mm at point (\d+)", msg)
    assert m, msg
    assert float(m.group(1)) == pytest.approx(largest, rel=1e-3)
    assert res["idx"][row4][np.argmax(res["lift"][row4])] == int(m.group(2))
    # physics: a tool touching the plane under the plate must rise above it (3 mm)
    assert ROOF_Z - 0.1 <= largest <= ROOF_Z + 1.0
    assert "tolerance" in msg and f"{TOL:g}" in msg


def test_strict_passes_a_clean_program(roof, tmp_path, capsys):
    out = tmp_path / "out.csv"
    code, _, err = run(capsys, _smooth_argv(roof, "clear_path.csv", "-o", out, "--strict", "--quiet"))
    assert code == 0, err
    assert err == ""
    res = read_csv(out)
    assert set(res["row"].astype(int)) == {3, 5} and np.all(res["lift"] == 0) and set(res["status"]) == {"ok"}


def test_unclean_rows_are_named_on_stderr_with_the_lift(roof_run):
    code, out, err = roof_run
    assert code == 0, err
    res = read_csv(out)
    tol_rows = sorted(set(res["row"][(res["lift"] > 0) | (res["delta"] < -TOL)].astype(int)))
    assert tol_rows == [4]
    m = re.search(r"rows not clean without lifting along the normal: \[([0-9, ]*)\]", err)
    assert m, err
    assert [int(v) for v in m.group(1).split(",")] == tol_rows
    # the lifted points are named with their row and the largest lift, as the CSV has them
    m = re.search(r"largest lift ([0-9.eE+-]+) mm at row (\d+), point (\d+)", err)
    assert m, err
    k = int(np.argmax(res["lift"]))
    assert float(m.group(1)) == pytest.approx(res["lift"][k], rel=1e-3)
    assert (int(m.group(2)), int(m.group(3))) == (int(res["row"][k]), int(res["idx"][k]))


def test_spline_method_names_the_lift_of_unclean_rows(roof, tmp_path, capsys):
    """The published spline method lifts too (no accessibility map): the rows and the size are named."""
    out = tmp_path / "out.csv"
    code, _, err = run(capsys, _smooth_argv(roof, "roof_path.csv", "-o", out, "--method", "spline"))
    assert code == 0, err
    res = read_csv(out)
    k = int(np.argmax(res["lift"]))
    assert res["lift"][k] > TOL
    m = re.search(r"rows not clean without lifting along the normal: \[([0-9, ]*)\]; largest lift ([0-9.eE+-]+) mm "
                  r"at row (\d+), point (\d+)", err)
    assert m, err
    assert [int(v) for v in m.group(1).split(",")] == sorted(set(res["row"][res["lift"] > 0].astype(int)))
    assert float(m.group(2)) == pytest.approx(res["lift"][k], rel=1e-3)
    assert (int(m.group(3)), int(m.group(4))) == (int(res["row"][k]), int(res["idx"][k]))


# ----------------------------------------------------------------------------------------------
# demo: the blade sample cut to its first two rows (400 points), in a samples folder of its own
@pytest.fixture
def quick_report(monkeypatch):
    """No 3D render child process and no PNG rasterising (the report itself is tested in
    test_report.py); the report's files and folders are the real ones."""
    import camsmooth.report.smoothing as rs

    real = rs.write_report
    monkeypatch.setattr(rs, "write_report", lambda result, out, **kw: real(result, out, render_3d=False, **kw))
    monkeypatch.setattr(rs, "_save_png", lambda fig, path: Path(path).write_bytes(b"\x89PNG stand-in"))


def test_demo_writes_its_outputs_and_meets_its_limits(tmp_path, capsys, monkeypatch, quick_report):
    samples = tmp_path / "samples"
    samples.mkdir()
    shutil.copy(SAMPLES / "blade.ply", samples / "blade.ply")
    lines = (SAMPLES / "blade_path.csv").read_text().splitlines()
    head = lines[0].split(",")
    keep = [ln for ln in lines[1:] if ln.split(",")[head.index("row")] in ("0", "1")]
    (samples / "blade_path.csv").write_text("\n".join([lines[0], *keep]) + "\n")
    monkeypatch.chdir(tmp_path)
    code, out, err = run(capsys, ["demo", "--samples", samples, "--sample", "blade", "--out", "demo"])
    assert code == 0, err
    demo = tmp_path / "demo"
    assert {p.name for p in demo.iterdir()} == {"blade_smoothed.csv", "blade_smoothed.nc", "blade_report"}
    assert (demo / "blade_report" / "report.html").stat().st_size > 0
    assert "blade_smoothed.csv" in out
    res = read_csv(demo / "blade_smoothed.csv")
    inp = read_csv(samples / "blade_path.csv")
    assert len(res["row"]) == len(inp["row"]) == 400
    pts = np.column_stack([inp["x"], inp["y"], inp["z"]])
    rows = inp["row"].astype(int)
    # the demo's limits: the default AB head and the windows it prints (lead 2:20, tilt -15:15 deg)
    limits = {ax: {"min": -100.0, "max": 100.0, "vmax": 60.0, "amax": 300.0} for ax in "AB"}
    assert "lead 2:20" in out and "tilt -15:15" in out and "default AB head" in out
    t = own_times(pts, rows, 2000.0)
    np.testing.assert_allclose(res["t"], t, rtol=1e-12, atol=1e-12)
    A, B = np.radians(res["A"]), np.radians(res["B"])
    assert violated(usage(rows, t, A, B), limits) == []
    n = np.column_stack([inp["nx"], inp["ny"], inp["nz"]])
    f = np.column_stack([inp["fx"], inp["fy"], inp["fz"]])
    lead, tilt = own_lead_tilt(own_axis(A, B), n, f)
    assert np.all(lead >= np.radians(2.0) - 1e-5) and np.all(lead <= np.radians(20.0) + 1e-5)
    assert np.all(np.abs(tilt) <= np.radians(15.0) + 1e-5)
    assert np.all(res["delta"] >= -0.005) and set(res["status"]) == {"ok"}
    # the G-code: one cutting block per point, with the CSV's A and B (deg, 4 decimals) in order
    cut = [ln for ln in (demo / "blade_smoothed.nc").read_text().splitlines() if ln.startswith("G01")]
    ab = np.array([[float(re.search(rf"\b{w}(-?[0-9.]+)", ln).group(1)) for w in "AB"] for ln in cut])
    assert ab.shape == (len(A), 2)
    np.testing.assert_allclose(ab, np.column_stack([res["A"], res["B"]]), atol=0.5e-4 + 1e-9)


# ----------------------------------------------------------------------------------------------
# path: a zig-zag on the wave's definition, and a raster by axial drop on its mesh
@pytest.fixture(scope="module")
def wave() -> dict:
    return tomllib.loads((SAMPLES / "wave.toml").read_text())["surface"]


def _wave_z(w: dict, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """z, z_x, z_y of z = cz + a sin(kx (x - cx)) sin(ky (y - cy))."""
    a, kx, ky = w["amplitude"], w["kx"], w["ky"]
    cx, cy, cz = w["center"]
    sx, sy = np.sin(kx * (x - cx)), np.sin(ky * (y - cy))
    cxx, cyy = np.cos(kx * (x - cx)), np.cos(ky * (y - cy))
    return cz + a * sx * sy, a * kx * cxx * sy, a * ky * sx * cyy


def _wave_normal(w: dict, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    _, zx, zy = _wave_z(w, x, y)
    n = np.column_stack([-zx, -zy, np.ones_like(x)])
    return n / np.linalg.norm(n, axis=1)[:, None]


def _row_runs(rows: np.ndarray) -> list[np.ndarray]:
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    return np.split(np.arange(len(rows)), starts[1:])


def test_path_on_a_definition_lies_on_the_surface_with_stepover_and_spacing(wave, tmp_path, capsys):
    stepover, spacing = 7.0, 1.5
    out = tmp_path / "cc.csv"
    code, _, err = run(capsys, ["path", "--surface", SAMPLES / "wave.toml", "--stepover", stepover, "--spacing",
                                spacing, "--feed", "1800", "-o", out, "--quiet"])
    assert code == 0, err
    c = read_csv(out)
    x, y, z = c["x"], c["y"], c["z"]
    n = np.column_stack([c["nx"], c["ny"], c["nz"]])
    f = np.column_stack([c["fx"], c["fy"], c["fz"]])
    rows = c["row"].astype(int)
    # on the surface and its normal, out of the material (+z side), unit
    np.testing.assert_allclose(z, _wave_z(wave, x, y)[0], atol=1e-9)
    np.testing.assert_allclose(n, _wave_normal(wave, x, y), atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-12)
    np.testing.assert_allclose(c["feed"], 1800.0)
    (u0, u1), (v0, v1) = wave["u_range"], wave["v_range"]
    runs = _row_runs(rows)
    assert [int(rows[r[0]]) for r in runs] == list(range(len(runs)))
    # rows along u = x at constant y, alternating direction, covering u from end to end
    ys = np.array([y[r].mean() for r in runs])
    for k, r in enumerate(runs):
        np.testing.assert_allclose(y[r], ys[k], atol=1e-9)
        xs = x[r] if k % 2 == 0 else x[r][::-1]
        assert xs[0] == pytest.approx(u0, abs=1e-9) and xs[-1] == pytest.approx(u1, abs=1e-9)
        assert np.all(np.diff(xs) > 0)
        # the feed direction: the unit tangent (1, 0, z_x) along travel
        _, zx, _ = _wave_z(wave, x[r], y[r])
        tang = np.column_stack([np.ones(len(r)), np.zeros(len(r)), zx]) * (1 if k % 2 == 0 else -1)
        np.testing.assert_allclose(f[r], tang / np.linalg.norm(tang, axis=1)[:, None], atol=1e-9)
        # spacing: chords no longer than it, and no more points than the arc length needs
        P = np.column_stack([x[r], y[r], z[r]])
        chords = np.linalg.norm(np.diff(P, axis=0), axis=1)
        assert chords.max() <= spacing + 1e-9
        xx = np.linspace(u0, u1, 20001)
        arc = np.trapezoid(np.sqrt(1 + _wave_z(wave, xx, np.full_like(xx, ys[k]))[1] ** 2), xx)
        assert len(r) == math.ceil(arc / spacing - 1e-9) + 1
    assert ys[0] == pytest.approx(v0, abs=1e-9) and ys[-1] == pytest.approx(v1, abs=1e-9)
    # stepover: the across-row distance on the surface, int sqrt(1 + z_y^2) dy, at most the
    # stepover between neighbouring rows wherever along x; and no more rows than that needs
    xx = np.linspace(u0, u1, 401)
    yy = np.linspace(v0, v1, 4001)
    X, Y = np.meshgrid(xx, yy, indexing="ij")
    dist = np.sqrt(1 + _wave_z(wave, X.ravel(), Y.ravel())[2] ** 2).reshape(X.shape)
    across = np.concatenate([np.zeros((len(xx), 1)),
                             np.cumsum(0.5 * (dist[:, 1:] + dist[:, :-1]) * np.diff(yy), axis=1)], axis=1)
    at_rows = np.stack([np.interp(ys, yy, across[i]) for i in range(len(xx))])  # (x samples, rows)
    assert np.diff(at_rows, axis=1).max() <= stepover * (1 + 1e-3)
    assert len(runs) == math.ceil(across[:, -1].max() / stepover - 1e-9) + 1


def test_raster_path_on_a_mesh_touches_it_from_a_grid_of_tool_positions(wave, tmp_path, capsys):
    """Raster by axial drop on the wave's mesh: the CC points lie on the mesh (and the exact
    surface within the mesh's chord error), normals are unit, up and the surface's; the tool
    tips recomputed from them (CL = CC + r n + R u - r T, T = +z) sit on the raster grid:
    rows stepover apart, points spacing apart."""
    R, r_c, stepover, spacing = 4.0, 1.0, 8.0, 2.5
    out = tmp_path / "cc.csv"
    code, _, err = run(capsys, ["path", "--surface", SAMPLES / "wave.stl", "--raster", "--axis", "0,0,1",
                                "--cutter-radius", R, "--corner-radius", r_c, "--stepover", stepover, "--spacing",
                                spacing, "-o", out, "--quiet"])
    assert code == 0, err
    c = read_csv(out)
    P = np.column_stack([c["x"], c["y"], c["z"]])
    n = np.column_stack([c["nx"], c["ny"], c["nz"]])
    rows = c["row"].astype(int)
    assert len(P) > 150  # 5 raster lines of ~32 points
    mesh = trimesh.load(SAMPLES / "wave.stl")
    _, dist, _ = trimesh.proximity.closest_point(mesh, P)
    assert dist.max() < 1e-6
    z, _, _ = _wave_z(wave, P[:, 0], P[:, 1])
    assert np.abs(P[:, 2] - z).max() < 0.02  # the mesh's chord error (surfaces/README.md: ~0.01 mm)
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-9)
    assert np.all(n[:, 2] > 0)
    inner = (P[:, 0] > 2) & (P[:, 0] < 78) & (P[:, 1] > 22) & (P[:, 1] < 58)
    cos = np.sum(n[inner] * _wave_normal(wave, P[inner, 0], P[inner, 1]), axis=1)
    assert cos.min() > np.cos(np.radians(2.0))
    # tool tips from the CC points (CONVENTIONS.md), T = +z. Where the normal is T itself the
    # tool rests on a level facet with its flat bottom (radius R): the contact is anywhere under
    # it, the formula's CL = CC names the disk's centre, so those points are only checked to lie
    # within R of their raster line
    T = np.array([0.0, 0.0, 1.0])
    u = n - (n @ T)[:, None] * T
    norm_u = np.linalg.norm(u, axis=1)
    flat = norm_u < 1e-12
    u = np.where(flat[:, None], 0.0, u / np.where(flat, 1.0, norm_u)[:, None])
    cl = P + r_c * n + R * u - r_c * T
    runs = _row_runs(rows)
    line_y = np.array([np.median(cl[rr[~flat[rr]], 1]) for rr in runs])
    for k, rr in enumerate(runs):
        on = rr[~flat[rr]]
        np.testing.assert_allclose(cl[on, 1], line_y[k], atol=1e-6)  # one raster line per row
        steps = np.abs(np.diff(cl[on, 0])) / spacing
        np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)  # on the grid along x
        assert np.all(np.round(steps) >= 1)
        assert np.all(np.abs(P[rr[flat[rr]], 1] - line_y[k]) <= R + 1e-9)
    assert flat.sum() < 0.05 * len(P)
    gaps = np.diff(np.unique(np.round(line_y, 6))) / stepover
    np.testing.assert_allclose(gaps, np.round(gaps), atol=1e-6)
    assert np.min(np.round(gaps)) == 1


def _all_parsers(parser, prog: str = "camsmooth"):
    """(prog, parser) for the top-level parser and every subparser under it, depth first."""
    import argparse

    yield prog, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _all_parsers(sub, f"{prog} {name}")


def test_every_option_of_every_verb_has_help_text():
    """README: 'Every verb has --help'; an option without help text shows in it as a bare flag."""
    import argparse

    from camsmooth.cli.main import build_parser

    bare = []
    verbs = 0
    for prog, parser in _all_parsers(build_parser()):
        verbs += 1
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._SubParsersAction)):
                continue
            if not (action.help or "").strip() or action.help == argparse.SUPPRESS:
                bare.append(f"{prog} {'/'.join(action.option_strings) or action.dest}")
    assert verbs >= 12   # camsmooth, smooth, path, analyze, demo, calibrate x3, simulate x4, predict, diagnose
    assert not bare, "options without help text: " + ", ".join(bare)
