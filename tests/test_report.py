"""HTML report: files, valid images, embedding, metrics table, notices, atomic write, 3D fallback."""

from __future__ import annotations

import base64
import re
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import trimesh
from matplotlib.image import imread

from camsmooth.machine.axes import PerAxis, RotaryValues
from camsmooth.machine.kinematics import load_machine
from camsmooth.report import smoothing as report
from camsmooth.report.smoothing import HTML_FILE, PLOT_FILES, SCENE_FILE, cumulative_time, write_report
from camsmooth.smoothing.result import MethodResult, Metrics, SmoothResult

MACHINE = load_machine(None)
CUTTER = SimpleNamespace(R=3.0, r=1.0, shank_length=40.0, diameter=8.0)


def _per_row_gradient(y: np.ndarray, t: np.ndarray, rows: np.ndarray) -> np.ndarray:
    out = np.empty_like(y)
    for r in np.unique(rows):
        s = rows == r
        out[s] = np.gradient(y[s], t[s])
    return out


def make_method(name: str, n_rows: int = 2, n_pts: int = 50, seed: int = 0) -> MethodResult:
    """A plane-milling program: rows along x at y = 5 row, tool axis swinging about the normal."""
    rng = np.random.default_rng(seed)
    rows = np.repeat(np.arange(n_rows), n_pts)
    idx = np.tile(np.arange(n_pts), n_rows)
    t = idx * 0.1
    cc = np.column_stack([idx * 1.0, rows * 5.0, np.zeros(len(t))])
    lead = 0.1 * np.sin(idx / 8.0) + (rng.normal(0, 0.01, len(t)) if name == "none" else 0.0)
    tilt = 0.05 * np.cos(idx / 5.0)
    T = np.column_stack([np.sin(lead) * np.cos(tilt), np.sin(lead) * np.sin(tilt), np.cos(lead)])
    A, B = np.arctan2(-T[:, 1], T[:, 2]), np.arcsin(T[:, 0])
    Av, Bv = _per_row_gradient(A, t, rows), _per_row_gradient(B, t, rows)
    Aa, Ba = _per_row_gradient(Av, t, rows), _per_row_gradient(Bv, t, rows)
    delta = 0.05 + 0.02 * np.sin(idx / 3.0)
    if name == "none":
        delta[10] = -0.01
    metrics = Metrics(gamma=12.3456 / (seed + 1),
                      peak_acc=PerAxis(("A", "B"), np.degrees([np.abs(Aa).max(), np.abs(Ba).max()])),
                      peak_acc_plan=PerAxis.nan(("A", "B")), min_delta=float(delta.min()),
                      violations={"B_acc": 4 - seed, "lead": 0}, runtime_s=0.25 * (seed + 1), lifted_points=0,
                      max_lift_mm=0.0, lifted_beyond_tolerance=0, unclean_rows=[1] if name == "none" else [],
                      unreachable=[(1, 7), (0, 3)] if name == "nlp" else [], tolerance_mm=1e-3)
    normals = np.tile([0.0, 0.0, 1.0], (len(t), 1))
    lead_w, tilt_w = np.column_stack([lead - 0.05, lead + 0.05]), np.column_stack([tilt - 0.1, tilt + 0.1])
    return MethodResult(method=name, rows=rows, idx=idx, t=t, cc=cc, normals=normals, cl=cc.copy(), axis=T,
                        lead=lead, tilt=tilt, rotary=RotaryValues.of(("A", "B"), A, B),
                        rotary_vel=RotaryValues.of(("A", "B"), Av, Bv), rotary_acc=RotaryValues.of(("A", "B"), Aa, Ba),
                        xyz=MACHINE.linear_axes(cc, A, B), delta=delta, lift=np.zeros(len(t)), lead_window=lead_w,
                        tilt_window=tilt_w, compound_acc=np.abs(Aa) + np.abs(Ba) + 1e-3, metrics=metrics)


def make_result(n_rows: int = 2, n_pts: int = 50) -> SmoothResult:
    methods = {m: make_method(m, n_rows, n_pts, seed=k) for k, m in enumerate(("none", "spline", "nlp"))}
    x1, y1 = n_pts + 5, 5 * n_rows
    mesh = trimesh.Trimesh(vertices=[[-5, -5, 0], [x1, -5, 0], [x1, y1, 0], [-5, y1, 0]],
                           faces=[[0, 1, 2], [0, 2, 3]])
    return SmoothResult(methods, "nlp", MACHINE, CUTTER, mesh, {"surface": "plane.stl"})


def _check_png(path: Path) -> np.ndarray:
    assert path.stat().st_size > 0
    img = imread(path)
    assert img.ndim == 3 and img.shape[0] > 200 and img.shape[1] > 300 and img.shape[2] in (3, 4)
    assert np.ptp(img[..., :3]) > 0  # not a blank canvas
    return img


def _summary_row(text: str, method: str) -> list[str]:
    table = re.search(r"<table class='summary'>(.*?)</table>", text, re.S).group(1)
    for tr in re.findall(r"<tr>(.*?)</tr>", table, re.S):
        cells = [re.sub(r"<.*?>", "", c) for c in re.findall(r"<td[^>]*>(.*?)</td>", tr, re.S)]
        if cells and cells[0].split(" ")[0] == method:
            return cells
    raise AssertionError(f"no summary row for {method}")


@pytest.fixture(scope="module")
def full_report(tmp_path_factory):
    """One report with the 3D view requested (rendered, or a note when this machine cannot)."""
    res = make_result()
    out = write_report(res, tmp_path_factory.mktemp("rep") / "report", title="Plane <test> & rows")
    return res, out


def test_report_files_and_images(full_report):
    _, out = full_report
    names = {p.name for p in out.iterdir()}
    assert set(PLOT_FILES) | {HTML_FILE} <= names
    assert names <= set(PLOT_FILES) | {HTML_FILE, SCENE_FILE}  # no leftovers (scene npz, temp files)
    for name in PLOT_FILES:
        _check_png(out / name)
    html_text = (out / HTML_FILE).read_text(encoding="utf-8")
    for name in PLOT_FILES:
        b64 = base64.b64encode((out / name).read_bytes()).decode("ascii")
        assert f"data:image/png;base64,{b64}" in html_text, name
    assert "<title>Plane &lt;test&gt; &amp; rows</title>" in html_text
    if (out / SCENE_FILE).exists():
        _check_png(out / SCENE_FILE)
        assert base64.b64encode((out / SCENE_FILE).read_bytes()).decode("ascii") in html_text
    else:
        assert "3D view unavailable" in html_text


def test_report_lists_metrics_and_notices(full_report):
    res, out = full_report
    text = (out / HTML_FILE).read_text(encoding="utf-8")
    for name, m in res.methods.items():
        cells = _summary_row(text, name)
        mt = m.metrics
        # method, points / rows, gamma, cycle time, binds most, peak A'' / B'' (deg/s^2), violations (the
        # total, the non-zero ones named), at the programmed feed, min delta (um), run time: ten columns
        assert len(cells) <= 10
        assert cells[1] == f"{len(m)} / 2"
        assert cells[2] == format(mt.gamma, ".4g")
        assert cells[5] == f"{format(mt.peak_acc['A'], '.4g')} / {format(mt.peak_acc['B'], '.4g')}"  # no plan: as given
        total = mt.violations["B_acc"]
        assert cells[6] == (f"{total} (B_acc {total})" if total else "0")
        assert cells[8] == format(1e3 * mt.min_delta, ".3g")
        assert cells[9] == format(mt.runtime_s, ".3g")
    assert "(primary)" in _summary_row(text, "nlp")[0]
    notice = re.search(r"<div class='notice'>(.*?)</div>", text, re.S).group(1)
    assert "rows that could not be made clean: 1" in notice
    assert "(row 1, point 7)" in notice and "(row 0, point 3)" in notice
    assert re.search(r"\.notice \{[^}]*color: #9", text)  # styled red
    assert "generic AB head" in text and "R 3 mm" in text


def test_clean_result_has_no_red_notice(tmp_path):
    res = make_result()
    for m in res.methods.values():
        m.metrics.unclean_rows, m.metrics.unreachable = [], []
    text = (write_report(res, tmp_path / "r", render_3d=False) / HTML_FILE).read_text(encoding="utf-8")
    assert "<div class='notice'>" not in text and "All rows clean" in text
    assert "3D view not requested" in text


def test_report_write_is_atomic(tmp_path, monkeypatch):
    out = tmp_path / "rep"

    def boom(*_a, **_k):
        raise RuntimeError("plot failed")

    monkeypatch.setattr(report, "_plot_clearance", boom)
    with pytest.raises(RuntimeError, match="plot failed"):
        write_report(make_result(), out, render_3d=False)
    assert list(tmp_path.iterdir()) == []
    out.mkdir()
    (out / "keep.txt").write_text("old")
    monkeypatch.setattr(report, "_plot_axes", boom)  # fail early: this case needs no plots
    with pytest.raises(RuntimeError):
        write_report(make_result(), out, render_3d=False)
    assert [p.name for p in tmp_path.iterdir()] == ["rep"] and (out / "keep.txt").read_text() == "old"


def _child(code: str) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)


def test_render_failure_degrades_to_note(tmp_path, monkeypatch):
    """A renderer that aborts (as VTK does without an OpenGL context) leaves a note, not a crash."""

    def fake_start(npz, png):
        assert Path(npz).exists()
        return _child("import os; os.abort()")

    monkeypatch.setattr(report, "_start_render", fake_start)
    out = write_report(make_result(), tmp_path / "r")
    text = (out / HTML_FILE).read_text(encoding="utf-8")
    assert "3D view unavailable" in text and "killed by signal" in text
    assert not (out / SCENE_FILE).exists()
    assert {p.name for p in out.iterdir()} == set(PLOT_FILES) | {HTML_FILE}


def test_render_outcomes(tmp_path):
    png = tmp_path / "s.png"
    failing = _child("import sys; print('no EGL', file=sys.stderr); sys.exit(3)")
    reason = report._finish_render(failing, png, 30)
    assert "exit code 3" in reason and "no EGL" in reason
    assert "wrote no image" in report._finish_render(_child("pass"), png, 30)
    blank = ("import sys, numpy as np; from matplotlib.image import imsave; "
             "imsave(sys.argv[1], np.ones((20, 20, 3)))")
    proc = subprocess.Popen([sys.executable, "-c", blank, str(png)], stderr=subprocess.PIPE, text=True)
    assert "blank" in report._finish_render(proc, png, 60) and not png.exists()
    assert "did not finish" in report._finish_render(_child("import time; time.sleep(30)"), png, 0.5)


def test_cumulative_time_and_decimation(tmp_path):
    t = np.array([0.0, 1.0, 2.0, 0.0, 1.5, 0.0, 0.5])
    rows = np.array([4, 4, 4, 7, 7, 9, 9])
    np.testing.assert_allclose(cumulative_time(t, rows), [0, 1, 2, 2, 3.5, 3.5, 4.0])
    # the min/max envelope keeps a one-point spike and breaks lines between rows
    n = 1000
    y = np.zeros(n)
    y[333], y[777] = 50.0, -20.0
    starts = np.array([0, 500])
    x, yy = report._line_xy(np.arange(n, dtype=float), y, starts, 100)
    assert len(x) <= 110 and np.nanmax(yy) == 50.0 and np.nanmin(yy) == -20.0
    assert np.isnan(yy).sum() == 1
    # a report with decimated plots says so
    res = make_result(n_rows=2, n_pts=50)
    out = write_report(res, tmp_path / "r", render_3d=False, max_plot_points=30)
    assert "decimated" in (out / HTML_FILE).read_text(encoding="utf-8")
    _check_png(out / "axes_acceleration.png")
