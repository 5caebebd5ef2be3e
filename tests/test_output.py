"""Result CSV and G-code: round trips, statuses, header, retracts, limit and input errors."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from camsmooth.errors import InfeasibleError, InputError
from camsmooth.io.result_csv import OUTPUT_COLUMNS, RESULT_CSV_COLUMNS, read_result_csv
from camsmooth.machine.axes import PerAxis, RotaryValues
from camsmooth.machine.kinematics import load_machine
from camsmooth.smoothing import output
from camsmooth.smoothing.output import point_status, write_gcode, write_result_csv
from camsmooth.smoothing.result import MethodResult, Metrics, SmoothResult

MACHINE = load_machine(None)
CUTTER = SimpleNamespace(R=3.0, r=1.0, shank_length=40.0, diameter=8.0)


def _per_row_gradient(y: np.ndarray, t: np.ndarray, rows: np.ndarray) -> np.ndarray:
    out = np.empty_like(y)
    for r in np.unique(rows):
        s = rows == r
        out[s] = np.gradient(y[s], t[s])
    return out


def make_method(name: str, n_rows: int = 2, n_pts: int = 50, amp: float = 0.3, seed: int = 0) -> MethodResult:
    """A plane-milling program: rows along x at y = 5 row, tool axis swinging about the normal."""
    rng = np.random.default_rng(seed)
    rows = np.repeat(np.arange(n_rows), n_pts)
    idx = np.tile(np.arange(n_pts), n_rows)
    t = idx * 0.1
    cc = np.column_stack([idx * 1.0, rows * 5.0, np.zeros(len(t))])
    normals = np.tile([0.0, 0.0, 1.0], (len(t), 1))
    lead = amp * np.sin(idx / 8.0) + (rng.normal(0, 0.02, len(t)) if name == "none" else 0.0)
    tilt = 0.5 * amp * np.cos(idx / 5.0 + rows)
    T = np.column_stack([np.sin(lead) * np.cos(tilt), np.sin(lead) * np.sin(tilt), np.cos(lead)])
    A, B = np.arctan2(-T[:, 1], T[:, 2]), np.arcsin(T[:, 0])
    cl = cc + np.array([0.0, 0.0, 0.25]) * np.arange(len(t))[:, None] / len(t)
    Av, Bv = _per_row_gradient(A, t, rows), _per_row_gradient(B, t, rows)
    Aa, Ba = _per_row_gradient(Av, t, rows), _per_row_gradient(Bv, t, rows)
    delta = 0.05 + 0.02 * np.sin(idx / 3.0 + seed)
    lift = np.zeros(len(t))
    metrics = Metrics(gamma=1.5 + seed, peak_acc=PerAxis(("A", "B"), (np.abs(Aa).max(), np.abs(Ba).max())),
                      peak_acc_plan=PerAxis.nan(("A", "B")),
                      min_delta=float(delta.min()), violations={"A_acc": 0}, lifted_points=0, max_lift_mm=0.0,
                      lifted_beyond_tolerance=0, unclean_rows=[], unreachable=[], tolerance_mm=1e-3, runtime_s=0.1)
    return MethodResult(method=name, rows=rows, idx=idx, t=t, cc=cc, normals=normals, cl=cl, axis=T, lead=lead,
                        tilt=tilt, rotary=RotaryValues.of(("A", "B"), A, B),
                        rotary_vel=RotaryValues.of(("A", "B"), Av, Bv), rotary_acc=RotaryValues.of(("A", "B"), Aa, Ba),
                        xyz=MACHINE.linear_axes(cl, A, B),
                        delta=delta, lift=lift, lead_window=np.column_stack([lead - 0.1, lead + 0.1]),
                        tilt_window=np.column_stack([tilt - 0.1, tilt + 0.1]), compound_acc=np.abs(Aa) + np.abs(Ba),
                        metrics=metrics)


def make_result(n_rows: int = 2, n_pts: int = 50, primary: str = "nlp") -> SmoothResult:
    methods = {m: make_method(m, n_rows, n_pts, seed=k) for k, m in enumerate(("none", "spline", "nlp"))}
    x1, y1 = n_pts + 5, 5 * n_rows
    mesh = trimesh.Trimesh(vertices=[[-5, -5, 0], [x1, -5, 0], [x1, y1, 0], [-5, y1, 0]],
                           faces=[[0, 1, 2], [0, 2, 3]])
    return SmoothResult(methods, primary, MACHINE, CUTTER, mesh, {"surface": "plane.stl", "path": "rows.csv"})


def _no_temp_files(folder: Path) -> bool:
    return not [p for p in folder.iterdir() if p.name.startswith(".")]


# ----------------------------------------------------------------------------------------------
# status
def test_point_status_priorities():
    m = make_method("nlp")
    m.lift[[3, 4, 60]] = 0.02              # lifted
    m.delta[[4, 20]] = -0.002              # 4: lifted but still gouging -> interference
    m.delta[21] = -0.0005                  # within the -1e-3 mm tolerance -> ok
    m.delta[22] = np.nan                   # unknown clearance is not interference
    m.metrics.unreachable = [(1, 10), (0, 20)]  # (0, 20) also gouges: unreachable wins
    st = point_status(m)
    expect = np.full(len(m), "ok", dtype=object)
    expect[[3, 60]] = "lifted"
    expect[4] = "interference"
    expect[[60, 20]] = ["unreachable", "unreachable"]  # (1, 10) is flat index 60
    assert st.tolist() == expect.tolist()


# ----------------------------------------------------------------------------------------------
# result CSV
def test_result_csv_round_trip(tmp_path):
    res = make_result()
    r = res.result
    r.lift[5] = 0.0123
    r.delta[7] = -0.01
    r.delta[8] = np.nan
    r.metrics.unreachable = [(1, 2)]
    path = write_result_csv(tmp_path / "out" / "result.csv", res)
    assert _no_temp_files(path.parent)
    header = path.read_text().splitlines()[0].split(",")
    assert tuple(header) == RESULT_CSV_COLUMNS
    back = read_result_csv(path)
    assert set(back) == set(RESULT_CSV_COLUMNS)
    table = res.table()
    for k, name in enumerate(OUTPUT_COLUMNS):
        np.testing.assert_array_equal(back[name], table[:, k], err_msg=name)  # repr: exact round trip
    assert back["row"].dtype == np.int64 and back["idx"].dtype == np.int64
    np.testing.assert_array_equal(back["lift"], r.lift)
    np.testing.assert_array_equal(np.degrees(r.rotary["A"]), back["A"])
    assert back["status"][5] == "lifted" and back["status"][7] == "interference" and back["status"][8] == "ok"
    assert back["status"][50 + 2] == "unreachable"
    assert (back["status"] == "ok").sum() == len(r) - 3
    # integers are written as integers
    first = path.read_text().splitlines()[1].split(",")
    assert first[0] == "0" and first[1] == "0"


def test_result_csv_missing_column_names_file_and_column(tmp_path):
    path = write_result_csv(tmp_path / "r.csv", make_result())
    lines = path.read_text().splitlines()
    k = RESULT_CSV_COLUMNS.index("tilt")
    cut = [",".join(f for j, f in enumerate(line.split(",")) if j != k) for line in lines]
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(cut) + "\n")
    with pytest.raises(InputError) as exc:
        read_result_csv(bad)
    assert exc.value.column == "tilt" and "bad.csv" in str(exc.value) and "tilt" in str(exc.value)
    # a reader that needs fewer columns accepts the file
    assert "tilt" not in read_result_csv(bad, required=("row", "idx", "A", "B"))


def test_result_csv_bad_values(tmp_path):
    path = write_result_csv(tmp_path / "r.csv", make_result())
    lines = path.read_text().splitlines()
    f = lines[3].split(",")
    f[RESULT_CSV_COLUMNS.index("x")] = "abc"
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines[:3] + [",".join(f)] + lines[4:]) + "\n")
    with pytest.raises(InputError) as exc:
        read_result_csv(bad)
    assert (exc.value.row, exc.value.column) == (3, "x")
    f = lines[2].split(",")
    f[1] = "1.5"
    bad.write_text("\n".join(lines[:2] + [",".join(f)] + lines[3:]) + "\n")
    with pytest.raises(InputError) as exc:
        read_result_csv(bad)
    assert (exc.value.row, exc.value.column) == (2, "idx")
    bad.write_text("\n".join(lines[:2] + [lines[2] + ",9"]) + "\n")
    with pytest.raises(InputError) as exc:
        read_result_csv(bad)
    assert exc.value.row == 2
    with pytest.raises(InputError, match="not found"):
        read_result_csv(tmp_path / "missing.csv")
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(InputError, match="empty"):
        read_result_csv(tmp_path / "empty.csv")


def test_result_csv_write_is_atomic(tmp_path, monkeypatch):
    target = tmp_path / "r.csv"
    target.write_text("previous\n")

    def boom(_m):
        raise RuntimeError("boom")

    monkeypatch.setattr(output, "point_status", boom)
    with pytest.raises(RuntimeError):
        write_result_csv(target, make_result())
    assert target.read_text() == "previous\n"
    assert _no_temp_files(tmp_path)


# ----------------------------------------------------------------------------------------------
# G-code
_WORD = re.compile(r"([A-Z])(-?\d+(?:\.\d+)?)")


def parse_gcode(text: str) -> list[tuple[str, dict[str, float]]]:
    """(code, words) per motion line, comments stripped."""
    moves = []
    for line in text.splitlines():
        line = re.sub(r"\(.*?\)", "", line).strip()
        if line.startswith(("G00", "G01")):
            words = {k: float(v) for k, v in _WORD.findall(line[3:])}
            moves.append((line[:3], words))
    return moves


def _xyzab(words: dict[str, float]) -> np.ndarray:
    return np.array([words[k] for k in "XYZAB"])


def test_gcode_round_trip_and_structure(tmp_path):
    res = make_result(n_rows=3, n_pts=40)
    r = res.result
    h = 12.5
    path = write_gcode(tmp_path / "prog.nc", res, MACHINE, CUTTER, 1500.0, safe_height=h)
    text = path.read_text()
    lines = text.splitlines()
    moves = parse_gcode(text)
    cut = np.array([_xyzab(w) for c, w in moves if c == "G01"])
    feeds = np.array([w["F"] for c, w in moves if c == "G01"])
    assert cut.shape == (len(r), 5)
    np.testing.assert_allclose(cut[:, :3], r.xyz, atol=0.5e-4 + 1e-12)
    np.testing.assert_allclose(cut[:, 3], np.degrees(r.rotary["A"]), atol=0.5e-4 + 1e-12)
    np.testing.assert_allclose(cut[:, 4], np.degrees(r.rotary["B"]), atol=0.5e-4 + 1e-12)
    # G93 inverse time: F = 1 / block time, block time = tip path length / 1500 mm/min; the tip path of
    # each block is sampled finely here (256 steps) with the machine chain, independently of the writer
    moves_all = np.array([_xyzab(w) for _, w in moves])
    is_cut = np.array([c == "G01" for c, _ in moves])
    prev = moves_all[np.flatnonzero(is_cut) - 1]
    s = np.linspace(0, 1, 257)[None, :, None]
    q = prev[:, None, :] + s * (cut - prev)[:, None, :]
    tips, _ = MACHINE.tool_pose_np(*np.radians(q[..., 3:]).reshape(-1, 2).T, *q[..., :3].reshape(-1, 3).T)
    length = np.linalg.norm(np.diff(tips.reshape(len(cut), 257, 3), axis=1), axis=2).sum(axis=1)
    np.testing.assert_allclose(feeds * length, 1500.0, rtol=1e-3)
    assert "G93" in lines and lines.index("G93") < lines.index(next(ln for ln in lines if ln.startswith("G01")))
    # independent check through the machine chain (POE): the commanded axes put the tool tip on
    # the CL point with the planned tool axis
    tip, axis = MACHINE.tool_pose_np(np.radians(cut[:, 3]), np.radians(cut[:, 4]), *cut[:, :3].T)
    np.testing.assert_allclose(tip, r.cl, atol=1e-3)
    np.testing.assert_allclose(axis, r.axis, atol=1e-5)
    # per row: G00 above the first point, G01 x n, G00 above the last point, along the tool axis
    codes = "".join("r" if c == "G00" else "c" for c, _ in moves)
    assert codes == ("r" + "c" * 40 + "r") * 3
    rapids = np.array([_xyzab(w) for c, w in moves if c == "G00"])
    ends = np.array([[0, 39], [40, 79], [80, 119]]).ravel()
    np.testing.assert_allclose(rapids[:, :3], r.xyz[ends] + h * r.axis[ends], atol=1e-4)
    np.testing.assert_allclose(rapids[:, 3], np.degrees(r.rotary["A"][ends]), atol=1e-4)
    tip_r, _ = MACHINE.tool_pose_np(np.radians(rapids[:, 3]), np.radians(rapids[:, 4]), *rapids[:, :3].T)
    np.testing.assert_allclose(tip_r - r.cl[ends], h * r.axis[ends], atol=1e-3)
    # header and program frame
    head = "\n".join(lines[:12])
    for needle in ("generic AB head", "AB-head", "pivot 150.0000", "R 3.0000", "r 1.0000", "diameter 8.0000",
                   "shank 40.0000", "method: nlp", "camsmooth", "plane.stl"):
        assert needle in head, needle
    first_move = next(i for i, ln in enumerate(lines) if ln.startswith("G0"))
    assert lines.index("G21") < lines.index("G90") < first_move
    assert lines[-1] == "M30"
    # every comment line is a single balanced (...) group
    for ln in lines:
        if ln.startswith("("):
            assert ln.endswith(")") and ln.count("(") == 1 and ln.count(")") == 1


def test_gcode_sanitises_comment_text(tmp_path):
    machine = dataclasses.replace(MACHINE, name="mill (left) bay 2")
    text = write_gcode(tmp_path / "p.nc", make_result(), machine, CUTTER, 800).read_text()
    assert "(machine: mill [left] bay 2" in text


def test_gcode_limit_and_input_errors(tmp_path):
    res = make_result()
    res.result.rotary["A"][17] = np.radians(120.0)  # beyond the +-100 deg travel of the default machine
    with pytest.raises(InfeasibleError, match=r"axis A .*row 0, point 17"):
        write_gcode(tmp_path / "p.nc", res, MACHINE, CUTTER, 1000.0)
    assert not (tmp_path / "p.nc").exists()
    write_gcode(tmp_path / "p.nc", res, MACHINE, CUTTER, 1000.0, check_limits=False)
    assert "A120.0000" in (tmp_path / "p.nc").read_text()

    res = make_result()
    with pytest.raises(InfeasibleError, match="retract"):  # Z + 2000 mm is beyond Z travel
        write_gcode(tmp_path / "q.nc", res, MACHINE, CUTTER, 1000.0, safe_height=2000.0)
    for feed in (0.0, -5.0, float("nan")):
        with pytest.raises(InputError, match="feed"):
            write_gcode(tmp_path / "q.nc", res, MACHINE, CUTTER, feed)
    res.result.xyz[3, 1] = np.nan
    with pytest.raises(InputError, match="non-finite"):
        write_gcode(tmp_path / "q.nc", res, MACHINE, CUTTER, 1000.0)
    assert not (tmp_path / "q.nc").exists()
    assert _no_temp_files(tmp_path)
