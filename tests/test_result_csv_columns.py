"""Result CSV (camsmooth.io.output): the optional columns (feed directions, planned time law), the
status boundaries, header spellings and empty files -- cases the round trip in test_output.py
does not reach. Expected values are built by hand here, not read from the writer."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.io.output import INTERFERENCE_TOL_MM, RESULT_CSV_COLUMNS, point_status, read_result_csv, write_result_csv
from camsmooth.smoothing.feed import FeedPlan
from camsmooth.smoothing.result import OUTPUT_COLUMNS, SmoothResult
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
    m.delta[:] = 0.1
    m.delta[1] = INTERFERENCE_TOL_MM          # exactly at the gouge tolerance: not interference ("delta < tol")
    m.delta[2] = INTERFERENCE_TOL_MM - 1e-9   # just below: interference
    m.lift[3] = np.nan                        # unknown lift is not a lift
    m.lift[4] = 1e-6                          # any positive lift is
    assert point_status(m).tolist() == ["ok", "ok", "interference", "ok", "lifted", "ok"]
    assert point_status(m, tol=0.2).tolist() == ["interference"] * 6


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
