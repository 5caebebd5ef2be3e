"""`camsmooth analyze` (camsmooth.smoothing.analysis): the pinned JSON, violations counted on a
hand-made program whose expected counts are worked out here, and the clearance of a CAM file."""

from __future__ import annotations

import json

import numpy as np

from camsmooth.cli.main import main
from camsmooth.machine.kinematics import load_machine
from camsmooth.post import load_program
from camsmooth.smoothing.analysis import analyze_program


def _cl_csv(path, B_deg, feed=600.0):
    """A straight row along +x, 1 mm apart, tool tip on z = 0, axis from A = 0 and the given B; feed
    (mm/min) one value or one per point (of the block that ends there)."""
    B = np.radians(np.asarray(B_deg, float))
    T = np.column_stack([np.sin(B), np.zeros_like(B), np.cos(B)])
    x = np.arange(len(B), dtype=float)
    feed = np.broadcast_to(np.asarray(feed, float), B.shape)
    rows = ["x,y,z,i,j,k,feed"] + [f"{xi},0,0,{t[0]:.17g},{t[1]:.17g},{t[2]:.17g},{f:g}"
                                   for xi, t, f in zip(x, T, feed, strict=True)]
    path.write_text("\n".join(rows) + "\n")


def test_violation_counts_of_a_hand_made_program(tmp_path):
    """B jumps 7 deg in one 0.1 s block (600 mm/min over 1 mm): one segment at 70 deg/s (> 60) and
    two second differences of +-700 deg/s^2 (> 300): B velocity 1, B acceleration 2, nothing else
    (the pivot's X moves 150 mm x 0.122 rad in 0.1 s: 183 mm/s, under the 500 mm/s default)."""
    B = [0.0] * 6 + [7.0] * 6
    _cl_csv(tmp_path / "p.csv", B)
    a = analyze_program(load_program(tmp_path / "p.csv"), load_machine())
    (tp,) = a.toolpaths
    viol = {k: v for k, v in tp.violations_programmed.items() if v}  # at the programmed feed
    assert viol == {"B velocity": 1, "B acceleration": 2}
    np.testing.assert_allclose(tp.peaks_programmed["B velocity"], 70.0, rtol=1e-9)
    np.testing.assert_allclose(tp.peaks_programmed["B acceleration"], 700.0, rtol=1e-9)
    # the planned time law slows the jump down to the limits: no velocity violation under it
    assert tp.violations["B velocity"] == 0 and tp.peaks["B velocity"] <= 60.0 * (1 + 1e-6)
    np.testing.assert_allclose(tp.range_deg["B"], [0.0, 7.0], atol=1e-9)
    assert tp.singular == {"points": 0, "passes": 0}


def test_programmed_time_takes_each_block_at_its_own_feed(tmp_path):
    """A varying feed (issue 21 item 5 (d): at a constant feed every block's feed is the same): the
    7 deg B jump is the block to point 6, programmed at 300 mm/min (5 mm/s), its neighbours at
    600. Worked out here: the jump takes 1 mm / 5 mm/s = 0.2 s, B velocity 35 deg/s (< 60, no
    violation); the program 10 blocks x 0.1 s + 0.2 s = 1.2 s."""
    B = [0.0] * 6 + [7.0] * 6
    feed = [600.0] * 6 + [300.0] + [600.0] * 5
    _cl_csv(tmp_path / "p.csv", B, feed=feed)
    a = analyze_program(load_program(tmp_path / "p.csv"), load_machine())
    (tp,) = a.toolpaths
    np.testing.assert_allclose(tp.peaks_programmed["B velocity"], 35.0, rtol=1e-9)
    assert tp.violations_programmed["B velocity"] == 0
    np.testing.assert_allclose(np.diff(a.series["t"]), [0.1] * 5 + [0.2] + [0.1] * 5, rtol=1e-9)
    assert tp.feed == [300.0, 600.0]


def test_singular_passes_are_counted(tmp_path):
    B = [80.0, 84.0, 86.0, 88.0, 86.0, 84.0, 80.0, 84.0, 86.0, 84.0]
    _cl_csv(tmp_path / "s.csv", B, feed=60.0)
    (tp,) = analyze_program(load_program(tmp_path / "s.csv"), load_machine()).toolpaths
    assert tp.singular == {"points": 4, "passes": 2}  # |B| > 85: 86, 88, 86 and later 86


def test_cli_json_is_pinned_and_names_the_air_moves(tmp_path, capsys):
    from tests.test_cam import _clsf, _plane, _rows

    _, tips, axes = _rows()
    (tmp_path / "f.cls").write_text(_clsf(tips, axes))
    _plane().export(tmp_path / "plane.stl")
    rc = main(["analyze", str(tmp_path / "f.cls"), "--surface", str(tmp_path / "plane.stl"), "--tolerance", "0.001",
               "--json", str(tmp_path / "a.json"), "--report", str(tmp_path / "rep"), "--quiet"])
    assert rc == 0
    doc = json.loads((tmp_path / "a.json").read_text())
    assert doc["units"] == "mm" and doc["points"] == 404 and isinstance(doc["warnings"], list)
    (tp,) = doc["toolpaths"]
    for key in ("name", "tool", "points", "feed", "A_range_deg", "B_range_deg", "violations", "gamma"):
        assert key in tp, key
    assert tp["name"] == "FINISH_PLANE" and tp["tool"]["diameter"] == 10.0 and tp["tool"]["corner_radius"] == 1.0
    assert tp["tool"]["kind"] == "mill" and tp["feed"] == [1500.0, 1500.0]
    # the poses touch the plane (the CAM's own program) except the two approach points in the air
    assert tp["clearance"]["air"] == 2 and tp["clearance"]["gouges"] == 0 and tp["cycle_time_s"] > 0
    assert (tmp_path / "rep" / "report.html").exists()


def _angles_program(B_deg):
    """A row along +x with the commanded angles A = 0 and the given B (as a G-code reader gives them)."""
    from camsmooth.io.program import CLProgram, ToolPath

    m = load_machine()
    B = np.radians(np.asarray(B_deg, float))
    A = np.zeros_like(B)
    n = len(B)
    tip = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])
    prog = CLProgram(tip=tip, axis=m.tool_axis_np(A, B), rows=np.zeros(n), feed=np.full(n, 60.0),
                     rapid=np.zeros(n, bool), line=np.arange(1, n + 1), toolpaths=[ToolPath(None, None, 0, n)],
                     angles=np.column_stack([A, B]))
    return m, prog


def test_branch_text_counts_both_sides_past_90_deg():
    """The branch label past |B| = 90 deg: counted by hand on each side (issue 21 item 5 (c)). The
    negative side: -92, -96, -92 are beyond (3 points); the positive side: 91, 95 (2 points); a
    program within +-90 (-90 itself included) is the first branch."""
    for B, beyond in (([-84.0, -88.0, -92.0, -96.0, -92.0, -88.0], 3), ([88.0, 91.0, 95.0, 89.0], 2),
                      ([-91.0, 85.0, 92.0, -93.0], 3)):
        m, prog = _angles_program(B)
        (tp,) = analyze_program(prog, m).toolpaths
        assert tp.branch == f"B beyond +-90 deg at {beyond} points (the second branch)", (B, tp.branch)
    m, prog = _angles_program([-90.0, -80.0, 0.0, 90.0])
    (tp,) = analyze_program(prog, m).toolpaths
    assert tp.branch.startswith("B in [-90, 90] deg"), tp.branch
