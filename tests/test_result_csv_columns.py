"""Result CSV (camsmooth.io.result_csv, written by camsmooth.smoothing.output): the optional
columns (feed directions, planned time law), the status boundaries, header spellings and empty
files -- cases the round trip in test_output.py does not reach. Expected values are built by hand
here, not read from the writer."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.constants import DEFAULT_TOLERANCE_MM
from camsmooth.errors import InputError
from camsmooth.io.result_csv import OUTPUT_COLUMNS, RESULT_CSV_COLUMNS, read_result_csv
from camsmooth.smoothing.feed import FeedPlan
from camsmooth.smoothing.output import point_status, write_result_csv
from camsmooth.smoothing.result import SmoothResult
from tests.test_output import make_method, make_result


def _plan(n: int) -> FeedPlan:
    t = np.arange(n) * 0.25
    z = np.zeros(0)
    return FeedPlan(t_plan=t, feed_plan=1000.0 + 10.0 * np.arange(n), limit=np.zeros(n, dtype=np.int64),
                    row_ids=z, row_cycle_time=z, row_limit_time=z, cycle_time=float(t[-1]), limit_time=z,
                    jerk_peak=np.zeros(5), jerk_over=np.zeros(5))


def test_feed_directions_and_planned_time_law_are_written_after_the_fixed_columns(tmp_path):
    res = make_result()
    r = res.result
    n = len(r)
    ang = np.linspace(0.0, 2.0, n)  # unit feed directions in the workpiece frame, turning about z
    r.feed_dirs = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n)])
    r.plan = _plan(n)
    back = read_result_csv(write_result_csv(tmp_path / "r.csv", res))
    header = (tmp_path / "r.csv").read_text().splitlines()[0].split(",")
    assert tuple(header) == RESULT_CSV_COLUMNS + ("fx", "fy", "fz", "t_plan", "feed_plan", "t_opt", "feed_opt")
    np.testing.assert_array_equal(back["fx"], np.cos(ang))
    np.testing.assert_array_equal(back["fy"], np.sin(ang))
    np.testing.assert_array_equal(back["fz"], 0.0)
    np.testing.assert_array_equal(back["t_plan"], np.arange(n) * 0.25)
    np.testing.assert_array_equal(back["feed_plan"], 1000.0 + 10.0 * np.arange(n))


def test_status_boundaries_tolerance_and_unknown_lift():
    m = make_method("nlp", n_rows=1, n_pts=6)
    tol = m.metrics.tolerance_mm
    m.delta[:] = 0.1
    m.delta[1] = -tol          # exactly at the gouge tolerance: not interference ("delta < -tolerance")
    m.delta[2] = -tol - 1e-9   # just below: interference
    m.lift[3] = np.nan         # unknown lift is not a lift
    m.lift[4] = 1e-6           # any positive lift is
    assert point_status(m).tolist() == ["ok", "ok", "interference", "ok", "lifted", "ok"]
    assert point_status(m, tolerance=-0.2).tolist() == ["interference"] * 6
    assert point_status(m, tolerance=2 * tol).tolist() == ["ok", "ok", "ok", "ok", "lifted", "ok"]
    m.metrics = None           # no metrics: the package's default tolerance
    m.delta[1], m.delta[2] = -DEFAULT_TOLERANCE_MM, -DEFAULT_TOLERANCE_MM - 1e-9
    assert point_status(m).tolist() == ["ok", "ok", "interference", "ok", "lifted", "ok"]


def test_status_uses_the_users_tolerance_like_the_metrics(tmp_path):
    """Issue 19: the CSV's status called a pose 'interference' at a fixed -1e-3 mm while the
    metrics counted with the user's tolerance. A straight row on the plane z = 0 with three CC
    points pushed into it (a toroidal cutter touching a plane at its CC point, the lowest point
    of the tool: delta = the CC point's z), smoothed with --tolerance 0.01 mm."""
    import trimesh

    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.paths import CCPath
    from camsmooth.geometry.surfaces import Surface
    from camsmooth.smoothing.pipeline import smooth

    V = np.array([[-20.0, -20.0, 0.0], [80.0, -20.0, 0.0], [80.0, 40.0, 0.0], [-20.0, 40.0, 0.0]])
    plane = Surface(trimesh.Trimesh(vertices=V, faces=[[0, 1, 2], [0, 2, 3]], process=False), None, "plane")
    n = 21
    z = np.zeros(n)
    z[[5, 10, 15]] = [-0.005, -0.02, -0.012]   # within the tolerance, beyond it, beyond it
    path = CCPath(points=np.column_stack([np.linspace(0.0, 40.0, n), np.full(n, 10.0), z]),
                  normals=np.tile([0.0, 0.0, 1.0], (n, 1)), rows=np.zeros(n, dtype=int), feed=np.full(n, 1000.0))
    res = smooth(path, plane, None, ToroidalCutter(R=4.0, r=1.0), lead_range=tuple(np.radians([2.0, 20.0])),
                 tilt_range=tuple(np.radians([-15.0, 15.0])), method="none", tolerance=0.01)
    np.testing.assert_allclose(res.result.delta[[5, 10, 15]], [-0.005, -0.02, -0.012], atol=1e-9)
    status = read_result_csv(write_result_csv(tmp_path / "r.csv", res))["status"]
    assert status[5] == "ok" and status[10] == "interference" and status[15] == "interference"
    assert set(np.delete(status, [10, 15])) == {"ok"}
    assert np.sum(status == "interference") == res.result.metrics.violations["interference"] == 2


def test_header_spelled_in_other_case_reads_under_the_declared_names(tmp_path):
    # predict reads result CSVs asking only for A, B, X, Y, Z: row / idx / status still come back
    # under their own names and types when a spreadsheet re-capitalised the header
    p = tmp_path / "r.csv"
    p.write_text("ROW,Idx,A,B,X,Y,Z,Status\n0,0,1.5,2.5,1,2,3,ok\n0,1,1.5,2.5,1,2,3,lifted\n")
    back = read_result_csv(p, required=("A", "B", "X", "Y", "Z"))
    assert set(back) == {"row", "idx", "A", "B", "X", "Y", "Z", "status"}
    assert back["row"].dtype == np.int64 and back["idx"].tolist() == [0, 1]
    assert back["status"].tolist() == ["ok", "lifted"]


def test_header_only_result_file_reads_as_zero_points_and_errors_name_the_result_file(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text(",".join(RESULT_CSV_COLUMNS) + "\n")
    back = read_result_csv(p)
    assert set(back) == set(RESULT_CSV_COLUMNS) and all(len(v) == 0 for v in back.values())
    p.write_text("")
    with pytest.raises(InputError, match=r"\(the result file has no header"):
        read_result_csv(p)


def test_table_with_a_wrong_column_count_is_refused_before_writing(tmp_path):
    class Broken(SmoothResult):
        def table(self):
            return np.zeros((3, len(OUTPUT_COLUMNS) + 1))

    good = make_result()
    bad = Broken(good.methods, good.primary, good.machine, good.cutter, good.surface_mesh, good.inputs)
    with pytest.raises(ValueError, match=f"has {len(OUTPUT_COLUMNS) + 1} columns, expected {len(OUTPUT_COLUMNS)}"):
        write_result_csv(tmp_path / "r.csv", bad)
    assert not (tmp_path / "r.csv").exists()


def test_the_default_tolerance_has_one_home():
    """camsmooth.constants.DEFAULT_TOLERANCE_MM is the default of smooth, analyze_program and the
    command line's --tolerance; no other module writes the number."""
    import inspect
    import re

    from camsmooth.cli.main import build_parser
    from camsmooth.smoothing.analysis import analyze_program
    from camsmooth.smoothing.pipeline import smooth
    from tests.conftest import ROOT

    assert DEFAULT_TOLERANCE_MM == 0.005   # README: "--tolerance (default 0.005 mm)"
    assert inspect.signature(smooth).parameters["tolerance"].default is DEFAULT_TOLERANCE_MM
    # analyze: None is the tolerance a camsmooth program was written with, else DEFAULT_TOLERANCE_MM
    assert inspect.signature(analyze_program).parameters["tolerance"].default is None
    parser = build_parser()
    smooth_args = parser.parse_args(["smooth", "p.csv", "--surface", "s.stl", "--lead", "2:20", "--tilt", "0:0",
                                     "-o", "o.csv"])
    assert smooth_args.tolerance is DEFAULT_TOLERANCE_MM
    assert parser.parse_args(["analyze", "p.csv"]).tolerance is None
    homes = [p.relative_to(ROOT).as_posix() for p in sorted((ROOT / "camsmooth").rglob("*.py"))
             if re.search(r"(?i)tol\w*\s*[:=][^\n]*\b0\.005\b", p.read_text(encoding="utf-8"))]
    assert homes == ["camsmooth/constants.py"]
