"""The interactive 3D view's budget (camsmooth.report.view3d) and the headline's facts
(camsmooth.report.headline) against figures worked out by hand. The view in a real browser:
tests/test_report_browser.py."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
import trimesh

from camsmooth.machine.axes import PerAxis
from camsmooth.report.headline import baseline_method, headline
from camsmooth.report.view3d import MAX_TRIANGLES, PathLayer, Scene, browser_mesh, view3d_html


def test_browser_mesh_decimates_a_sphere_and_keeps_its_shape():
    sphere = trimesh.creation.icosphere(subdivisions=6, radius=50.0)  # 81,920 triangles
    assert len(sphere.faces) > MAX_TRIANGLES
    v, f, note = browser_mesh(sphere.vertices, sphere.faces)
    assert 0.5 * MAX_TRIANGLES < len(f) <= MAX_TRIANGLES
    assert f"{len(sphere.faces):,}" in note and f"{len(f):,}" in note
    # still the sphere: every kept vertex on it, the faces' centroids close to it (the chord sag of
    # an edge of length a on radius R is a^2 / 8R: a few um here)
    np.testing.assert_allclose(np.linalg.norm(v, axis=1), 50.0, rtol=1e-3)
    centroid_r = np.linalg.norm(v[f].mean(axis=1), axis=1)
    assert centroid_r.min() > 49.0 and centroid_r.max() <= 50.0 + 1e-6
    # closed: a decimated sphere keeps its area within a few percent of 4 pi R^2
    area = 0.5 * np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1).sum()
    assert area == pytest.approx(4 * np.pi * 50.0 ** 2, rel=0.02)
    small = trimesh.creation.icosphere(subdivisions=2)
    v2, f2, note2 = browser_mesh(small.vertices, small.faces)
    assert note2 == "" and len(f2) == len(small.faces) and v2 is not None


def test_view_fragment_carries_plotly_the_traces_and_no_network():
    t = np.linspace(0.0, 2 * np.pi, 50)
    cl = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    rows = np.repeat([0, 1], 25)
    layers = [PathLayer("cam", "#2ca02c", cl, np.tile([0.0, 0.0, 1.0], (50, 1)), rows, np.zeros(50, bool)),
              PathLayer("nlp", "#d62728", cl, np.tile([0.0, 0.0, 1.0], (50, 1)), rows, np.arange(50) == 7,
                        visible=False)]
    frag = view3d_html(Scene(None, None, layers, cl[:3], ["p"] * 3))
    assert "Plotly.newPlot" in frag and "camsmooth-view3d" in frag
    assert "cdn.plot.ly" not in frag.split("</script>")[-2][-2000:]  # the call, not a link: plotly.js inline
    assert '<script src="http' not in frag
    for name in ("cam: tool-tip path", "cam: tool axes", "nlp: tool-tip path", "nlp: lifted points (1)",
                 "pole passages"):
        assert name in frag
    assert '"visible":"legendonly"' in frag  # nlp not shown at first, one click away
    assert '"label":"cam"' in frag and '"label":"all methods"' in frag


def _metrics(rotary=("A", "B"), peak=(0.0, 0.0), peak_plan=(float("nan"), float("nan")), **kw):
    """Metrics as the headline reads them; peaks (deg/s^2) on the rotary axes ``rotary``, in that order."""
    base = dict(controller="", cycle_time_s=float("nan"), cycle_time_optimal_s=float("nan"),
                peak_acc=PerAxis(rotary, peak), peak_acc_plan=PerAxis(rotary, peak_plan), violations={},
                violations_programmed={}, scallop_max_um=None, min_delta=0.0, tolerance_mm=0.005)
    base.update(kw)
    return SimpleNamespace(**base)


def test_headline_against_the_cam_program_worked_by_hand():
    cam = SimpleNamespace(plan=object(), metrics=_metrics(
        controller="linuxcnc", cycle_time_s=155.8, cycle_time_optimal_s=92.1, rotary=("A", "C"),
        peak_plan=(69.9, 506.2), violations={"B acceleration": 120, "interference": 0}, scallop_max_um=24.4,
        min_delta=-0.0123))
    none = SimpleNamespace(plan=object(), metrics=_metrics(cycle_time_s=1.0, cycle_time_optimal_s=1.0,
                                                           rotary=("A", "C")))
    nlp = SimpleNamespace(plan=object(), metrics=_metrics(
        controller="linuxcnc", cycle_time_s=130.0, cycle_time_optimal_s=76.0, rotary=("A", "C"),
        peak_plan=(38.25, 300.1), violations={"B acceleration": 0}, scallop_max_um=42.3, min_delta=-0.0002))
    res = SimpleNamespace(methods={"none": none, "cam": cam, "nlp": nlp}, primary="nlp", result=nlp,
                          machine=SimpleNamespace(rotary=("A", "C")))
    assert baseline_method(res.methods) == "cam"  # the CAM's own axes before the unsmoothed path
    h = headline(res)
    # 130 / 155.8 - 1 = -16.6%; 76 / 92.1 - 1 = -17.5%; 300.1 / 506.2 - 1 = -40.7%; 38.25 / 69.9 - 1 = -45.3%
    assert h.lines() == [
        "cycle time on the linuxcnc controller 155.8 s -> 130 s (-17%)",
        "cycle time time-optimal 92.1 s -> 76 s (-17%)",
        "peak C'' 506.2 deg/s\u00b2 -> 300.1 deg/s\u00b2 (-41%)",
        "peak A'' 69.9 deg/s\u00b2 -> 38.25 deg/s\u00b2 (-45%)",
        "limit violations 120 -> 0 (B acceleration 120 -> none)",
        "largest scallop 24.4 \u00b5m -> 42.3 \u00b5m",
        "worst clearance -12.3 \u00b5m -> -0.2 \u00b5m",
    ]
    assert [f.better for f in h.facts] == [True, True, True, True, True, False, True]
    assert "against the CAM program's own tool axes ('cam')" in h.title()
    assert "under the planned time law" in h.text()
    # the program as brought is the primary: nothing to compare
    assert headline(SimpleNamespace(methods={"none": none}, primary="none", result=none, machine=None)) is None


def test_headline_at_the_programmed_feed_without_a_controller_model():
    none = SimpleNamespace(plan=None, metrics=_metrics(cycle_time_optimal_s=10.0, peak=(10.0, 400.0),
                                                       violations_programmed={"B acceleration": 3},
                                                       violations={"B acceleration": 9}, min_delta=0.001))
    spline = SimpleNamespace(plan=None, metrics=_metrics(cycle_time_optimal_s=10.0, peak=(20.0, 100.0),
                                                         min_delta=0.002))
    h = headline(SimpleNamespace(methods={"none": none, "spline": spline}, primary="spline", result=spline,
                                 machine=SimpleNamespace(rotary=("A", "B"))))
    assert h.before == "none" and h.law == "at the programmed feed"
    assert h.lines() == ["cycle time time-optimal 10 s -> 10 s (+0%)",
                         "peak B'' 400 deg/s\u00b2 -> 100 deg/s\u00b2 (-75%)",
                         "peak A'' 10 deg/s\u00b2 -> 20 deg/s\u00b2 (+100%)",
                         "limit violations 3 -> 0 (B acceleration 3 -> none)",
                         "worst clearance 1 \u00b5m -> 2 \u00b5m"]
    assert [f.better for f in h.facts] == [None, True, False, True, None]  # clear either way: neither


def test_analyzed_program_in_3d_one_layer_per_tool_path_without_rapids():
    """surfaces/dome.cls as analyze reads it: its FINISH tool path's cutting points, each row's
    rapid approach left out, every point's tool axis from the file's GOTO i, j, k."""
    from pathlib import Path

    from camsmooth.post import load_program
    from camsmooth.report.view3d import scene_of_program

    cls = Path(__file__).resolve().parents[1] / "surfaces" / "dome.cls"
    prog = load_program(cls)
    scene = scene_of_program(prog)
    assert [la.name for la in scene.layers] == [tp.name for tp in prog.toolpaths] == ["FINISH"]
    assert scene.layer_kind == "tool path" and scene.vertices is None
    cut, after_rapid = [], False  # a GOTO right after RAPID is reached by a rapid move: not a cut
    for ln in cls.read_text().splitlines():
        if ln.startswith("GOTO/") and not after_rapid:
            cut.append([float(v) for v in ln.split("/")[1].split(",")[:6]])
        after_rapid = ln.strip() == "RAPID"
    cut = np.array(cut)
    la = scene.layers[0]
    np.testing.assert_allclose(la.cl, cut[:, :3], atol=1e-9)
    np.testing.assert_allclose(la.axis, cut[:, 3:] / np.linalg.norm(cut[:, 3:], axis=1, keepdims=True), atol=1e-6)
    frag = view3d_html(scene)
    assert "FINISH: tool-tip path" in frag and "the buttons show" not in frag  # one tool path: no buttons
