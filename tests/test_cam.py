"""A CAM system's CL program through the pipeline (issue 10): an NX CLSF file written here, on an
exact tilted plane: the contacts recovered from the CL poses are the CC points the poses were made
from, the method 'cam' is the program's own axes and tips, air moves are named and split the rows,
and the command line takes the file (cutter from its TLDATA) and reports cam beside the others."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from camsmooth.cli.main import main
from camsmooth.geometry.clearance import MeshIndex
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames
from camsmooth.geometry.surfaces import Surface
from camsmooth.io.result_csv import read_result_csv
from camsmooth.post import load_program
from camsmooth.smoothing.cam import cam_program
from camsmooth.smoothing.pipeline import smooth

SLOPE = np.radians(12.0)  # the plane z = x tan(SLOPE)
CUT = ToroidalCutter(R=4.0, r=1.0)  # D 10, r 1
N = np.array([-np.sin(SLOPE), 0.0, np.cos(SLOPE)])


def _plane() -> trimesh.Trimesh:
    x0, x1, y0, y1 = -20.0, 120.0, -30.0, 40.0
    V = np.array([[x, y, x * np.tan(SLOPE)] for x, y in ((x0, y0), (x1, y0), (x1, y1), (x0, y1))])
    return trimesh.Trimesh(V, [[0, 1, 2], [0, 2, 3]], process=False)


def _rows() -> tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]]:
    """Two rows along +x (zig-zag) on the plane, 0.5 mm apart in x, lead 8 deg, tilt -3/+4 deg."""
    ccs, tips, axes = [], [], []
    for k, (y, tilt) in enumerate(((0.0, -3.0), (6.0, 4.0))):
        x = np.linspace(0.0, 100.0, 201)[:: 1 if k == 0 else -1]
        cc = np.column_stack([x, np.full_like(x, y), x * np.tan(SLOPE)])
        f = np.tile([np.cos(SLOPE), 0.0, np.sin(SLOPE)] if k == 0 else [-np.cos(SLOPE), 0.0, -np.sin(SLOPE)],
                    (len(x), 1))
        fr = local_frames(np.tile(N, (len(x), 1)), f)
        T = axis_from_lead_tilt(np.full(len(x), np.radians(8.0)), np.full(len(x), np.radians(tilt)), fr)
        ccs.append(cc)
        axes.append(T)
        tips.append(cc_to_cl(CUT, cc, np.tile(N, (len(x), 1)), T))
    return ccs, tips, axes


def _clsf(tips, axes) -> str:
    """NX CLSF text: tool path, TLDATA (mm), feed, an approach in the air (rapid to 5 mm above the
    row start along the axis, then a feed move down: it touches nothing), the row, a rapid away."""
    lines = ["TOOL PATH/FINISH_PLANE,TOOL,MILL_D10R1", "TLDATA/MILL,10.0000,1.0000,75.0000,0.0000,0.0000",
             "LOAD/TOOL,1", "$$ written by tests/test_cam.py", "FEDRAT/MMPM,1500.0000"]
    for tip, ax in zip(tips, axes, strict=True):
        above = tip[0] + 5.0 * ax[0]
        lines += ["RAPID", f"GOTO/{above[0]:.6f},{above[1]:.6f},{above[2]:.6f},{ax[0, 0]:.9f},{ax[0, 1]:.9f},"
                  f"{ax[0, 2]:.9f}"]
        mid = tip[0] + 2.5 * ax[0]
        lines.append(f"GOTO/{mid[0]:.6f},{mid[1]:.6f},{mid[2]:.6f}")  # still in the air, at feed
        for p, a in zip(tip, ax, strict=True):
            lines.append(f"GOTO/{p[0]:.6f},{p[1]:.6f},{p[2]:.6f},{a[0]:.9f},{a[1]:.9f},{a[2]:.9f}")
        up = tip[-1] + 5.0 * ax[-1]
        lines += ["RAPID", f"GOTO/{up[0]:.6f},{up[1]:.6f},{up[2]:.6f}"]
    lines.append("END-OF-PATH")
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cam")
    ccs, tips, axes = _rows()
    (d / "finish.cls").write_text(_clsf(tips, axes))
    _plane().export(d / "plane.stl")
    return d, ccs, tips, axes


def test_cl_program_becomes_the_cc_points_it_was_made_from(files):
    d, ccs, tips, axes = files
    program = load_program(d / "finish.cls")
    cam = cam_program(program, MeshIndex(_plane()), CUT, tolerance=1e-3)
    # 6 decimals in the file: the contacts within that rounding of the exact CC points
    np.testing.assert_allclose(cam.path.points, np.concatenate(ccs), atol=5e-6)
    ang = np.arccos(np.clip(cam.path.normals @ N, -1, 1))
    assert ang.max() < 1e-6
    assert len(cam.path.row_slices()) == 2 and np.allclose(cam.path.feed, 1500.0)
    # the approach points in the air are named, with their file lines, and split nothing else
    assert [o.why for o in cam.off_contact] == ["air", "air"]
    assert all(o.clearance[0] > 1.0 - 1e-9 for o in cam.off_contact)  # the clearance is capped at 1 mm
    text = (d / "finish.cls").read_text().splitlines()
    for o in cam.off_contact:
        assert text[o.lines[0] - 1].startswith("GOTO/") and o.lines[0] == o.lines[1]


def test_cam_method_is_the_input_program(files):
    d, ccs, tips, axes = files
    program = load_program(d / "finish.cls")
    cam = cam_program(program, MeshIndex(_plane()), CUT, tolerance=1e-3)
    surf = Surface(mesh=_plane(), parametric=None, source="plane.stl")
    res = smooth(cam, surf, None, CUT, lead_range=tuple(np.radians([2.0, 20.0])),
                 tilt_range=tuple(np.radians([-10.0, 10.0])), method="nlp", tolerance=1e-3)
    assert set(res.methods) == {"cam", "none", "spline", "nlp"}
    c = res.methods["cam"]
    np.testing.assert_allclose(c.axis, np.concatenate(axes), atol=5e-9)
    np.testing.assert_allclose(c.cl, np.concatenate(tips), atol=5e-6)
    np.testing.assert_allclose(np.degrees(c.lead), 8.0, atol=1e-5)
    assert abs(c.metrics.min_delta) < 1e-5  # the CAM's poses touch the plane
    assert any("lines" in w and "does not touch" in w for w in res.warnings)


def test_cli_smooths_an_apt_file_with_its_own_cutter(files, tmp_path, capsys):
    d, *_ = files
    rc = main(["smooth", str(d / "finish.cls"), "--surface", str(d / "plane.stl"), "--lead", "2:20", "--tilt",
               "-10:10", "--tolerance", "0.001", "-o", str(tmp_path / "out.csv"), "--gcode", str(tmp_path / "o.nc"),
               "--quiet"])
    assert rc == 0
    out = read_result_csv(tmp_path / "out.csv")
    assert len(out["x"]) == 402 and np.all(out["delta"] > -1e-3)
    rc = main(["smooth", str(d / "finish.cls"), "--surface", str(d / "plane.stl"), "--lead", "2:20", "--tilt",
               "-10:10", "--tolerance", "0.001", "-o", str(tmp_path / "out2.csv")])
    text = capsys.readouterr()
    table = text.out.split("\nmethod ", 1)[1].splitlines()  # the table after the headline
    assert rc == 0 and table[1].startswith("cam ")  # the program as it came, listed first
    assert "does not touch the mesh" in text.err


def _run(argv, capsys):
    rc = main(argv)
    return rc, capsys.readouterr().err


def test_cl_program_far_from_the_mesh_is_one_message_and_writes_nothing(files, tmp_path, capsys):
    d, ccs, tips, axes = files
    far = [t + np.array([0.0, 0.0, 50.0]) for t in tips]
    (tmp_path / "far.cls").write_text(_clsf(far, axes))
    rc, err = _run(["smooth", str(tmp_path / "far.cls"), "--surface", str(d / "plane.stl"), "--lead", "2:20",
                    "--tilt", "-10:10", "-o", str(tmp_path / "o.csv"), "--gcode", str(tmp_path / "o.nc")], capsys)
    # named as a frame mismatch, with the offset that would put the program on the part (about 50 mm up)
    assert rc == 2 and "far.cls" in err and "not in the same frame" in err and len(err.strip().splitlines()) == 1
    offset = [float(v) for v in err.rsplit("--part-frame", 1)[1].split()[0].split(",")]
    assert abs(offset[2] - 50.0) < 6.0  # within the cutter's size: the tips are not on the surface
    assert sorted(p.name for p in tmp_path.iterdir()) == ["far.cls"]


def test_cl_program_without_tldata_needs_a_cutter(files, tmp_path, capsys):
    d, ccs, tips, axes = files
    text = "\n".join(ln for ln in _clsf(tips, axes).splitlines() if not ln.startswith("TLDATA"))
    (tmp_path / "notool.cls").write_text(text + "\n")
    rc, err = _run(["smooth", str(tmp_path / "notool.cls"), "--surface", str(d / "plane.stl"), "--lead", "2:20",
                    "--tilt", "-10:10", "-o", str(tmp_path / "o.csv")], capsys)
    assert rc == 2 and "notool.cls" in err and "line 1" in err and "TLDATA" in err
    assert not (tmp_path / "o.csv").exists()
    rc, _ = _run(["smooth", str(tmp_path / "notool.cls"), "--surface", str(d / "plane.stl"), "--lead", "2:20",
                  "--tilt", "-10:10", "--cutter-radius", "4", "--corner-radius", "1", "-o", str(tmp_path / "o.csv"),
                  "--quiet"], capsys)
    assert rc == 0 and (tmp_path / "o.csv").exists()


@pytest.mark.parametrize("bad,needle", [
    ("GOTO/1.0,2.0", "GOTO"),
    ("GOTO/0.0,0.0,0.0,0.0,0.0,2.0", "unit"),
    ("UNITS/FURLONGS", "UNITS"),
])
def test_bad_apt_records_name_the_line(files, tmp_path, capsys, bad, needle):
    d, ccs, tips, axes = files
    lines = _clsf(tips, axes).splitlines()
    lines.insert(6, bad)
    (tmp_path / "bad.cls").write_text("\n".join(lines) + "\n")
    for verb in (["smooth", "--lead", "2:20", "--tilt", "-10:10", "-o", str(tmp_path / "o.csv")],
                 ["analyze", "--json", str(tmp_path / "a.json")]):
        rc, err = _run([verb[0], str(tmp_path / "bad.cls"), "--surface", str(d / "plane.stl"), *verb[1:]], capsys)
        assert rc == 2 and "bad.cls" in err and "line 7" in err and needle.lower() in err.lower(), err
        assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.cls"]


def test_a_bad_tool_path_is_dropped_and_named_on_stderr(files, tmp_path, capsys):
    """A record that cannot be read costs only its tool path: the good one is smoothed, the bad one
    is named (file, line, reason) among the warnings on stderr, for smooth and analyze."""
    d, ccs, tips, axes = files
    good = _clsf(tips, axes)
    bad = ("TOOL PATH/BROKEN,TOOL,MILL_D10R1\nTLDATA/MILL,10.0000,1.0000,75.0000,0.0000,0.0000\n"
           "FEDRAT/MMPM,1500\nGOTO/1.0,2.0,3.0\nGOTO/1.0,2.0\nGOTO/1.0,3.0,3.0\nEND-OF-PATH\n")
    path = tmp_path / "two.cls"
    path.write_text(bad + good)
    prog = load_program(path)
    assert [tp.name for tp in prog.toolpaths] == ["FINISH_PLANE"]
    np.testing.assert_array_equal(prog.tip, load_program(d / "finish.cls").tip)
    dropped = [w for w in prog.warnings if "dropped" in w]
    assert len(dropped) == 1 and "'BROKEN' (line 1)" in dropped[0] and str(path) in dropped[0]
    assert "line 5" in dropped[0] and "malformed GOTO" in dropped[0]
    rc, err = _run(["smooth", str(path), "--surface", str(d / "plane.stl"), "--lead", "2:20", "--tilt", "-10:10",
                    "-o", str(tmp_path / "o.csv")], capsys)
    assert rc == 0, err
    assert any(ln.startswith("camsmooth: warning: tool path 'BROKEN' (line 1) dropped") and "line 5" in ln
               for ln in err.splitlines()), err
    assert len(read_result_csv(tmp_path / "o.csv")["x"]) == 402
    rc, err = _run(["analyze", str(path), "--quiet"], capsys)
    assert rc == 0 and err == ""
    rc, err = _run(["analyze", str(path)], capsys)
    assert rc == 0 and "tool path 'BROKEN' (line 1) dropped" in err, err
