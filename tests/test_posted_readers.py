"""Posted programs (camsmooth.post): each dialect on programs written the way its controller manual
documents them, against closed forms written here, LinuxCNC's own interpreter (rs274) where it is
installed, and the public corpus of tests/data/posted (SOURCES.md)."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from camsmooth.cli.main import main
from camsmooth.controller.linuxcnc_sim import parse_canon
from camsmooth.errors import InputError
from camsmooth.io.program import CL_COLUMNS
from camsmooth.io.table import read_table
from camsmooth.post import detect_dialect, load_program, read_posted
from camsmooth.post.core import nominal_machine

DATA = Path(__file__).parent / "data" / "posted"


def _write(tmp_path: Path, name: str, text: str) -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


def _rs274(tmp_path: Path, program: Path) -> str:
    """LinuxCNC's canonical calls for ``program`` (M428/M429, the trt remaps, dropped: they switch
    the kinematics, not the words)."""
    text = re.sub(r"\bM42[89]\b", "", program.read_text())
    src = tmp_path / ("rs_" + program.name)
    src.write_text(text)
    tbl = tmp_path / "tool.tbl"
    tbl.write_text("T1 P1 Z0 D10 ;\n")
    out = tmp_path / "canon.txt"
    subprocess.run(["rs274", "-t", str(tbl), "-g", str(src), str(out)], capture_output=True, text=True,
                   stdin=subprocess.DEVNULL, timeout=120, check=False)
    return out.read_text()


needs_rs274 = pytest.mark.skipif(shutil.which("rs274") is None, reason="LinuxCNC's rs274 not installed (make linuxcnc)")


# ---- ISO / Fanuc -----------------------------------------------------------------------------
def test_helix_ijk_against_closed_form(tmp_path):
    # Fanuc 30i operator's manual, "Helical interpolation": G17 G03 with I J, Z moving linearly with the angle
    p = _write(tmp_path, "h.nc", "%\nO1000\nG21 G90 G17\nG0 X10. Y0 Z0\nG1 Z0 F300.\n"
                                 "G3 X-10. Y0 Z-4. I-10. J0\nM30\n%\n")
    prog = read_posted(p, chord_tol=1e-4)
    arc = prog.tip[prog.line == 6]
    r = np.hypot(arc[:, 0], arc[:, 1])
    assert np.allclose(r[:-1], 10.0, atol=1e-9) and np.allclose(arc[-1], [-10, 0, -4])
    ang = np.unwrap(np.arctan2(arc[:, 1], arc[:, 0]))
    assert np.all(np.diff(ang) > 0)  # counter-clockwise about +Z
    assert np.allclose(arc[:, 2], -4.0 * ang / math.pi, atol=1e-9)  # z linear in the angle, -4 over pi
    chord = np.max(10 - 10 * np.cos(np.diff(ang) / 2))
    assert chord <= 1e-4 + 1e-12


def test_r_word_arcs_and_planes(tmp_path):
    # G02 with R < 0: the arc over 180 deg (Fanuc "Circular interpolation"); G18: ZX plane, normal +Y
    p = _write(tmp_path, "r.nc", "G21 G90 G17\nG0 X0 Y0 Z0\nG2 X10 Y0 R-5.5 F100\n"
                                 "G18\nG0 X0 Y0 Z0\nG3 X10 Z0 R5 F100\nM30\n")
    prog = read_posted(p)
    a = prog.tip[prog.line == 3]
    h = math.sqrt(5.5 ** 2 - 25)
    c = np.array([5.0, h, 0.0])  # G2 with R < 0: centre to the left of the chord, long way round
    assert np.allclose(np.linalg.norm(a - c, axis=1), 5.5, atol=1e-9)
    assert a[:, 1].max() > 5.5 + h - 1e-3 and a[:, 1].min() >= -1e-9 or a[:, 1].min() < 0
    b = prog.tip[prog.line == 6]
    assert np.allclose(b[:, 1], 0) and np.allclose(np.hypot(b[:, 0] - 5, b[:, 2]), 5, atol=1e-9)
    # G3 in G18 turns by the right-hand rule about +Y: from X0 (centre X5) through Z > 0
    assert b[:, 2].max() > 4.9


def test_inch_program_converted(tmp_path):
    p = _write(tmp_path, "i.nc", "G20 G90 G94\nG0 X1. Y2. Z3.\nG1 X2. F10.\nM30\n")
    prog = read_posted(p)
    assert np.allclose(prog.tip[-1], [50.8, 50.8, 76.2]) and prog.feed[-1] == pytest.approx(254.0)


def test_tcp_against_machine_mode_on_an_ac_table(tmp_path):
    # TCP (G43.4): X Y Z is the tip; machine mode: the joints of a table machine, whose tip in the
    # workpiece frame is Rz(C) Rx(A) X (camsmooth's AC table with its centre at the origin)
    A, C = 25.0, -130.0
    X = np.array([12.0, -7.0, 30.0])
    words = f"X{X[0]} Y{X[1]} Z{X[2]} A{A} C{C}"
    tcp = read_posted(_write(tmp_path, "t.nc", f"G21 G90\nG43.4 H1\nG0 {words}\nG1 X13 F500\nG49\nM30\n"))
    mach = read_posted(_write(tmp_path, "m.nc", f"G21 G90\nG0 {words}\nG1 X13 F500\nM30\n"))
    R = Rotation.from_euler("xz", [A, C], degrees=True).as_matrix()  # extrinsic: Rz(C) @ Rx(A)
    assert np.allclose(tcp.tip[0], X)
    assert np.allclose(mach.tip[0], R @ X, atol=1e-9)
    assert np.allclose(tcp.axis[0], R[:, 2]) and np.allclose(mach.axis[0], R[:, 2])
    assert tcp.rotary == ("A", "C") and np.allclose(np.degrees(tcp.angles[0]), [A, C])


def test_g68_2_tilted_plane(tmp_path):
    # Fanuc "Tilted working plane indexing", Eulerian angles: G68.2 X Y Z I J K, R = Rz(I) Rx(J) Rz(K)
    o, eul = np.array([10.0, 5.0, -2.0]), (30.0, 45.0, -20.0)
    p = _write(tmp_path, "g68.nc", f"G21 G90 G54\nG68.2 X{o[0]} Y{o[1]} Z{o[2]} I{eul[0]} J{eul[1]} K{eul[2]}\n"
                                   "G53.1\nG0 X1 Y2 Z5\nG1 Z0 F200\nX4\nG69\nM30\n")
    prog = read_posted(p)
    R = Rotation.from_euler("ZXZ", eul, degrees=True).as_matrix()
    assert np.allclose(prog.tip[-1], o + R @ [4, 2, 0], atol=1e-9)
    assert np.allclose(prog.axis[-1], R[:, 2]) and prog.toolpaths[0].kind == "3+2"
    assert any("G54" in w for w in prog.warnings)


def test_cycles_named_subprogram_variables_and_robust_text(tmp_path):
    text = ("\ufefflisting banner, not G-code: page 1\r\n%\r\nO0001 (MAIN)\r\n"
            "(Operation Name: DRILL_HOLES)\r\nT2 M6\r\nG21 G90 G17 G54.1 P3\r\n#100 = 12.5\r\n"
            "G0 X0 Y0 Z20.\r\nG99 G81 X10. Y10. Z-5. R2. F100.\r\nX[#100+2.5] Y10.\r\nG80\r\n"
            "(Operation Name: CONTOUR)\r\nT3 M6\r\nG0 X0 Y0 Z5\r\nM98 P1000 L2\r\n/ G1 Z-1 F100\r\nM30\r\n"
            "O1000\r\nG1 G91 X 1 . 5 F200\r\nG90\r\nM99\r\n%\r\n")
    p = tmp_path / "c.nc"
    p.write_bytes(text.encode())
    prog = load_program(p)
    assert [t.name for t in prog.toolpaths] == ["DRILL_HOLES", "CONTOUR"]
    (cyc,) = prog.cycles
    assert cyc.code == "G81" and np.allclose(cyc.holes, [[10, 10, -5], [15, 10, -5]]) and cyc.lines == [9, 10]
    assert any("canned cycle G81" in w and "DRILL_HOLES" in w for w in prog.warnings)
    cut = prog.tip[~prog.rapid]
    assert np.allclose(cut[:, 0], [1.5, 3.0, 3.0]) and np.allclose(cut[-1], [3.0, 0, -1])  # two calls, block delete
    assert prog.toolpaths[0].kind == "cycle"


def test_unknown_construct_costs_its_operation(tmp_path):
    p = _write(tmp_path, "u.nc", "(Operation Name: A)\nG21 G90\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\n"
                                 "(Operation Name: B)\nG0 X0 Y0 Z5\nG41 D1\nG1 X5 F100\nM30\n")
    prog = read_posted(p)
    assert [t.name for t in prog.toolpaths] == ["A"]
    assert any("operation 'B'" in w and "line 8" in w and "G41" in w for w in prog.warnings)
    bad = _write(tmp_path, "v.nc", "G21\nG0 X0 Y0 Z0\nG1 X1 F100 Q#<undefined>\nG41\nG1 X2\nM30\n")
    with pytest.raises(InputError):
        read_posted(bad)


@needs_rs274
def test_linuxcnc_words_against_rs274(tmp_path):
    # LinuxCNC G-code overview: named parameters, spaces inside words, G91, N numbers, comments
    p = _write(tmp_path, "lc.ngc", "%\n(test)\nM428\nG21 G90 G94\n#<feed> = 250\n#<dx> = [3 * 2]\n"
                                   "N10 G0 X0 Y0 Z5 A0 C0\nG1 Z 0 F#<feed> ; plunge\nG1 X#<dx> Y1.25 A10 C-20\n"
                                   "G91 G1 X-1 Y2 C30\nG90\nG1 X 1 0 . 5 Y0\nM2\n%\n")
    prog = read_posted(p, machine=nominal_machine(("A", "C")), dialect="linuxcnc")
    canon = parse_canon(_rs274(tmp_path, p))
    feed = ~canon.rapid
    assert np.allclose(canon.positions[feed][:, :3], prog.tip[~prog.rapid], atol=1e-9)  # M428: TCP, tip = X Y Z
    assert np.allclose(canon.positions[feed][:, [3, 5]], -np.degrees(prog.angles[~prog.rapid]), atol=1e-9)
    assert np.allclose(canon.feed[feed], prog.feed[~prog.rapid])


def _canon_feeds(text: str) -> tuple[np.ndarray, list[tuple[int, np.ndarray]]]:
    """The end of every feed motion (X Y Z A B C) of rs274's canonical calls, STRAIGHT_FEED and
    ARC_FEED (G17: first, second end, centre, rotation, axis end, a, b, c), and the arcs' (index,
    centre)."""
    ends, arcs = [], []
    for ln in text.splitlines():
        m = re.search(r"(STRAIGHT_FEED|ARC_FEED)\((.*)\)\s*$", ln)
        if not m:
            continue
        v = [float(x) for x in m.group(2).split(",")]
        if m.group(1) == "STRAIGHT_FEED":
            ends.append(v[:6])
        else:
            arcs.append((len(ends), np.array(v[2:4])))
            ends.append([v[0], v[1], v[5], v[6], v[7], v[8]])
    return np.asarray(ends), arcs


@needs_rs274
@pytest.mark.parametrize("name", ["boat-xyzac.ngc", "boat-xyzbc.ngc", "impeller-7bl-xyzac.ngc",
                                  "xyzac_switchkins_test_2.ngc"])
def test_corpus_linuxcnc_against_rs274(tmp_path, name):
    """LinuxCNC's shipped trt demos: the end of every feed block (X Y Z and the rotary words) as
    rs274 reads it, and every interpolated arc point on the circle about rs274's centre (M428 turns
    TCP on: the tip is X Y Z in the workpiece frame; the trt kinematics' table sense is -1)."""
    prog = read_posted(DATA / name)
    ends, arcs = _canon_feeds(_rs274(tmp_path, DATA / name))
    cut = np.flatnonzero(~prog.rapid)
    last = cut[np.r_[prog.line[cut][1:] != prog.line[cut][:-1], True]]  # the last point of each feed block
    assert len(last) == len(ends)
    cols = [3, 5] if "xyzac" in name else [4, 5]
    assert np.allclose(ends[:, cols], -np.degrees(prog.angles[last]), atol=1e-9)
    if name != "xyzac_switchkins_test_2.ngc":  # its first moves run under M429 (machine mode)
        assert np.allclose(ends[:, :3], prog.tip[last], atol=1e-9)
        for k, centre in arcs:
            pts = prog.tip[cut][prog.line[cut] == prog.line[last[k]]]
            r = np.hypot(*(pts[:, :2] - centre).T)
            assert np.ptp(r) < 2e-3  # the posts' rounding of the centre (3 decimals)


def test_corpus_reads_and_counts(tmp_path):
    """Every corpus file reads (no exit 70), its operations named as its comments give them, and the
    cutting points equal an independent count of its feed blocks."""
    imp = read_posted(DATA / "impeller-7bl-xyzac.ngc")
    n_g1 = sum(1 for ln in (DATA / "impeller-7bl-xyzac.ngc").read_text().splitlines() if ln.startswith("G1 "))
    assert (~imp.rapid).sum() == n_g1
    assert [t.name for t in imp.toolpaths] == ["Operation 1", "Operation 2", "Operation 3"]
    boat = read_posted(DATA / "boat-xyzac.ngc")
    assert [t.name for t in boat.toolpaths] == ["ROUGH7 Z LEVEL SRF_MILL1", "FINISH1 FLOWLINE SRF_MILL1",
                                               "FINISH2 FLOWLINE SRF_MILL1"]
    assert detect_dialect((DATA / "boat-xyzbc.ngc").read_text()) == "linuxcnc"
    for f in sorted(DATA.glob("*.ngc")):
        out = tmp_path / (f.stem + ".csv")
        assert main(["analyze", str(f), "--cl", str(out), "--quiet"]) == 0
        t = read_table(out, required=("x", "y", "z", "i", "j", "k"), text=("operation",))
        assert tuple(t.header) == CL_COLUMNS
        assert np.allclose(np.linalg.norm(np.column_stack([t["i"], t["j"], t["k"]]), axis=1), 1.0)


# ---- Siemens 840D --------------------------------------------------------------------------
def test_siemens_cycle800_traori_and_r_parameters(tmp_path):
    # 840D cycles manual, CYCLE800 axis by axis (_MODE 57: X, then Y, then Z, each about the turned
    # frame); Fundamentals: R parameters, '=' words, CR= radius, ';' comments
    p = _write(tmp_path, "s.mpf", "; header\nN10 G71 G90 G17\n;(ROUGH_1)\nT=\"EM10\" M6\nR1=7\n"
                                  "CYCLE800(1,\"TC1\",200000,57,0,0,0,30,-20,10,0,0,0,1,100,1)\n"
                                  "G0 X10 Y0 Z5\nG1 Z0 F=500\nG1 X20 Y=R1\nCYCLE800()\nTRAORI\n"
                                  "G0 X0 Y0 Z50 A0 C0\nG1 X1 A10 C20\nTRAFOOF\nM30\n")
    prog = read_posted(p, machine=nominal_machine(("A", "C")))
    assert prog.dialect == "siemens" and prog.toolpaths[0].name == "ROUGH_1"
    R = Rotation.from_euler("XYZ", [30, -20, 10], degrees=True).as_matrix()  # intrinsic X, Y', Z''
    assert np.allclose(prog.tip[prog.line == 9][0], R @ [20, 7, 0], atol=1e-9)
    assert np.allclose(prog.axis[prog.line == 9][0], R[:, 2])
    last = prog.line == 13
    assert np.allclose(prog.tip[last][0], [1, 0, 50])
    assert np.allclose(prog.axis[last][0], Rotation.from_euler("xz", [10, 20], degrees=True).as_matrix()[:, 2])


def test_cli_cl_for_apt_and_cc(tmp_path):
    apt = Path(__file__).parent / "data" / "apt" / "fusion_iso4343.apt"
    out = tmp_path / "a.csv"
    assert main(["analyze", str(apt), "--cl", str(out), "--quiet"]) == 0
    t = read_table(out, required=("x", "y", "z"), text=("operation",))
    assert tuple(t.header) == CL_COLUMNS
    prog = load_program(apt)
    assert len(t) == int((~prog.rapid).sum())


# ---- Heidenhain Klartext -------------------------------------------------------------------
def test_heidenhain_plane_datum_arc_tcpm_labels_and_cycle(tmp_path):
    # TNC 640 Klartext manual: CYCL DEF 7 datum shift, PLANE SPATIAL (about the machine-fixed X, Y,
    # Z in that order: R = Rz(SPC) Ry(SPB) Rx(SPA)), CC/C arcs (DR+ counter-clockwise), M128, LBL,
    # CYCL DEF 200 called by M99 (hole bottom Q203 + Q201)
    p = _write(tmp_path, "t.h", "0 BEGIN PGM T MM\n1 * - FACE\n2 TOOL CALL 5 Z S8000\n"
                                "3 CYCL DEF 7.0 DATUM SHIFT\n4 CYCL DEF 7.1 X+10\n5 CYCL DEF 7.2 Y+5\n"
                                "6 PLANE SPATIAL SPA+30 SPB-10 SPC+45 TURN MB MAX FMAX SEQ+ TABLE ROT\n"
                                "7 L X+0 Y+0 Z+5 R0 FMAX\n8 L Z+0 F500\n9 L X+20\n10 CC X+20 Y+10\n"
                                "11 C X+30 Y+10 DR+\n12 PLANE RESET STAY\n13 CYCL DEF 7.0 DATUM SHIFT\n"
                                "14 CYCL DEF 7.1 X+0\n15 CYCL DEF 7.2 Y+0\n16 * - SWARF\n17 M128\n"
                                "18 L X+0 Y+0 Z+50 A+0 C+0 R0 FMAX\n19 Q5 = 4 * 2.5\n20 L X+Q5 A+10 C+20 F800\n"
                                "21 CALL LBL 1 REP 1\n22 M129\n23 * - DRILL\n24 CYCL DEF 200 DRILLING ~\n"
                                "   Q200=2 ;SET-UP CLEARANCE ~\n   Q201=-15 ;DEPTH ~\n   Q203=+0 ;SURFACE COORDINATE\n"
                                "25 L X+5 Y+5 Z+50 A+0 C+0 R0 FMAX M99\n26 M30\n27 LBL 1\n28 L IX+1 F800\n29 LBL 0\n"
                                "30 END PGM T MM\n")
    prog = read_posted(p, machine=nominal_machine(("A", "C")))
    assert prog.dialect == "heidenhain"
    assert [t.name for t in prog.toolpaths] == ["FACE", "SWARF", "DRILL"]
    R = Rotation.from_euler("xyz", [30, -10, 45], degrees=True).as_matrix()  # extrinsic x, y, z
    o = np.array([10.0, 5.0, 0.0])
    assert np.allclose(prog.tip[prog.line == 10][0], o + R @ [20, 0, 0])
    arc = prog.tip[prog.line == 12]
    local = (arc - o) @ R  # back into the plane's frame
    assert np.allclose(np.hypot(local[:, 0] - 20, local[:, 1] - 10), 10, atol=1e-9) and np.allclose(local[:, 2], 0)
    assert local[len(local) // 2, 0] > 20 and np.allclose(local[-1], [30, 10, 0])  # DR+ from (20,0) via x > 20
    assert np.allclose(prog.axis[prog.line == 12], R[:, 2])
    swarf = prog.tip[prog.toolpaths[1].start:prog.toolpaths[1].stop]
    assert np.allclose(swarf[1:, 0], [10, 11, 12]) and np.allclose(swarf[:, 2], 50)  # Q5, then LBL 1 twice
    (cyc,) = prog.cycles
    assert cyc.op_name == "DRILL" and np.allclose(cyc.holes, [[5, 5, -15]])


def test_every_dialect_refuses_cleanly(tmp_path):
    """Bad input in any dialect: InputError naming the file (exit 2), never another exception."""
    for name, text in [("a.h", "0 BEGIN PGM A MM\n1 L X+Q9 R0 F100\n2 END PGM A MM\n"),
                       ("b.mpf", "TRAORI\nG1 X=IC(5) F100\nM30\n"), ("c.nc", "G1 X1 Y2 Z3 F100 W5\nM30\n"),
                       ("d.nc", "%\n%\n")]:
        f = _write(tmp_path, name, text)
        with pytest.raises(InputError) as exc:
            read_posted(f)
        assert str(f) in str(exc.value)
        assert main(["analyze", str(f), "--quiet"]) == 2


def test_g43_5_vector_g93_feed_and_haas_dwo(tmp_path):
    # Fanuc G43.5 (TCP type 2): I J K the tool vector; G93: F = 1 / block time (min), so the tip feed is
    # the block's tip path length times F
    p = _write(tmp_path, "v.nc", "G21 G90\nG43.5 H1\nG0 X0 Y0 Z10 I0 J0 K1\nG93 G1 X3 Y4 Z10 I0 J0.6 K0.8 F20\n"
                                 "G49 G94\nM30\n")
    prog = read_posted(p)
    assert np.allclose(prog.axis[-1], [0, 0.6, 0.8]) and prog.feed[-1] == pytest.approx(5.0 * 20)
    # Haas G254 (dynamic work offset) on an A/C table: the control moves the work offset with the
    # table, tip = Rz(C) Rx(A) X whatever the table centre
    A, C = 20.0, 70.0
    q = _write(tmp_path, "d.nc", f"G21 G90 G54\nG254\nG0 X5 Y6 Z7 A{A} C{C}\nG1 X6 F100\nG255\nM30\n")
    prog = read_posted(q, machine=nominal_machine(("A", "C")))
    R = Rotation.from_euler("xz", [A, C], degrees=True).as_matrix()
    assert np.allclose(prog.tip[-1], R @ [6, 6, 7]) and detect_dialect(q.read_text()) == "haas"


def test_rotary_word_the_machine_lacks_costs_its_operation(tmp_path):
    p = _write(tmp_path, "b.nc", "(Operation Name: AC)\nG21 G90\nG43.4 H1\nG0 X0 Y0 Z5 A0 C0\nG1 X1 A5 F100\n"
                                 "(Operation Name: WITH B)\nG0 X0 Y0 Z5\nG1 X2 B10 F100\nM30\n")
    prog = read_posted(p, machine=nominal_machine(("A", "C")))
    assert [t.name for t in prog.toolpaths] == ["AC"]
    assert any("operation 'WITH B'" in w and "rotary axis B" in w and "line 8" in w for w in prog.warnings)


def test_siemens_mcall_holes_and_frames(tmp_path):
    # 840D: MCALL CYCLE81(RTP, RFP, SDIS, DP) drills at every position until MCALL; TRANS/AROT frames
    p = _write(tmp_path, "m.mpf", "G71 G90\nTRANS X10 Y20\nAROT Z90\nG0 X0 Y0 Z50\nG1 Z0 F100\nX5\n"
                                  "MCALL CYCLE81(10,0,2,-8)\nG0 X1 Y1\nX2 Y1\nMCALL\nG0 X3 Y3\nTRANS\nM30\n")
    prog = read_posted(p)
    assert np.allclose(prog.tip[prog.line == 6][0], [10, 25, 0])  # (5, 0) turned 90 deg about Z, shifted
    (cyc,) = prog.cycles
    assert cyc.code == "CYCLE81" and np.allclose(cyc.holes, [[9, 21, -8], [9, 22, -8]])


def test_heidenhain_jumps_rotation_and_drilling_only(tmp_path):
    # Klartext manual: FN 9 IF ... EQU ... GOTO LBL (a conditional jump), CYCL DEF 10 ROTATION, a
    # block-delete '/' before the block number, '* ---' rules that name nothing, CYCL DEF 207 called by M99
    p = _write(tmp_path, "j.h", "0 BEGIN PGM J MM\n1 * --- HEADER ---\n2 * - ROTATED\n3 TOOL CALL 1 Z S1000\n"
                                "4 FN 0: Q1900=2\n5 CALL LBL \"PICK\"\n6 CYCL DEF 10.0 ROTATION\n"
                                "7 CYCL DEF 10.1 ROT+90\n"
                                "8 L X+0 Y+0 Z+5 R0 FMAX\n9 L Z+0 FQ5\n10 L X+10\n/11 M30\n12 LBL \"PICK\"\n"
                                "13 FN 9: IF +Q1900 EQU +1 GOTO LBL \"ONE\"\n"
                                "14 FN 9: IF +Q1900 EQU +2 GOTO LBL \"TWO\"\n"
                                "15 LBL 0\n16 LBL \"ONE\"\n17 FN 0: Q5=100\n18 LBL 0\n19 LBL \"TWO\"\n20 FN 0: Q5=200\n"
                                "21 LBL 0\n22 END PGM J MM\n")
    prog = read_posted(p)
    assert [t.name for t in prog.toolpaths] == ["ROTATED"]
    assert np.allclose(prog.tip[-1], [0, 10, 0]) and np.allclose(prog.feed[~prog.rapid], 200)
    d = _write(tmp_path, "d.h", "0 BEGIN PGM D MM\n1 TOOL CALL 1 Z S500\n2 L X+0 Y+0 Z+50 R0 FMAX\n"
                                "3 CYCL DEF 207 RIGID TAPPING NEW~\n   Q200=3 ;SET-UP CLEARANCE~\n"
                                "   Q201=-11.5 ;DEPTH~\n"
                                "   Q203=0 ;SURFACE COORDINATE\n4 L X+10 Y+5 R0 FMAX M99\n5 L X-10 R0 FMAX M99\n"
                                "6 M30\n7 END PGM D MM\n")
    with pytest.raises(InputError, match=r"only canned cycles \(CYCL DEF 207 line 8 \(2 holes\)\)"):
        read_posted(d)


def test_solidworks_cam_apt(tmp_path):
    """SOLIDWORKS CAM's APT (tests/data/posted/SOURCES.md): CIRCLE/centre,axis without radius,
    UNIT/MM. The arcs turn counter-clockwise about the axis: every lead-in arc ends tangent to the
    contour arc that follows it and starts tangent to the straight lead-in before it, and the
    contour circles keep their radius (18 mm about (15, 15), 5.5 and 5.75 mm about the bore)."""
    f = DATA / "solidworks_teflon_gasket.apt"
    prog = load_program(f)
    assert not any("CIRCLE" in w for w in prog.warnings)
    cut = ~prog.rapid
    tip, line = prog.tip, prog.line
    text = f.read_text().splitlines()
    for k, ln in enumerate(text, start=1):
        if ln.startswith("CIRCLE/16.055013,-3.970687,-5."):  # a lead-in arc of radius 1 (the first level)
            arc = tip[line == k + 1]
            before = tip[np.flatnonzero(line == k + 1)[0] - 1]
            assert np.allclose(np.hypot(*(arc[:, :2] - [16.055013, -3.970687]).T), 1.0, atol=1e-5)
            d_in = arc[0] - before
            lead = tip[line == k - 1][-1] - tip[np.flatnonzero(line == k - 1)[0] - 1]
            assert np.dot(d_in[:2], lead[:2]) / np.linalg.norm(d_in[:2]) / np.linalg.norm(lead[:2]) > 0.99
            nxt = tip[line == k + 4]  # the contour arc about (15, 15) after FEDRAT
            d_out, d_next = arc[-1] - arc[-2], nxt[0] - arc[-1]
            assert np.dot(d_out[:2], d_next[:2]) / np.linalg.norm(d_out[:2]) / np.linalg.norm(d_next[:2]) > 0.99
            assert np.allclose(np.hypot(*(nxt[:, :2] - 15.0).T), 18.0, atol=1e-5)
    bore = tip[cut & np.isclose(tip[:, 2], -5.0) & (np.hypot(tip[:, 0] - 15, tip[:, 1] - 15) < 6)]
    r = np.hypot(*(bore[:, :2] - 15.0).T)
    assert np.isclose(r.max(), 5.75, atol=1e-5) and np.any(np.isclose(r, 5.5, atol=1e-5))
    out = tmp_path / "g.csv"
    assert main(["analyze", str(f), "--cl", str(out), "--quiet"]) == 0


def test_siemens_per_word_dimensions_helix_inch_and_settings(tmp_path):
    # 840D Fundamentals: X=IC(v) incremental for one word, I=AC(v) an absolute arc centre, TURN=n
    # extra helix turns, G4 F (dwell seconds, not a feed), FNORM / ADIS (no motion), G700 inch
    p = _write(tmp_path, "w.mpf", "G710 G90 G17 FNORM\nADIS=0.05\nG0 X10 Y0 Z0\nG1 X=IC(5) F500\n"
                                  "G4 F2\nG3 X5 Y0 Z-3 I=AC(10) J=AC(0) TURN=1\nG700\nG1 X1 F10\nM30\n")
    prog = read_posted(p, chord_tol=1e-4)
    assert np.allclose(prog.tip[prog.line == 4][0], [15, 0, 0]) and prog.feed[prog.line == 4][0] == 500
    helix = prog.tip[prog.line == 6]
    assert np.allclose(np.hypot(helix[:, 0] - 10, helix[:, 1]), 5, atol=1e-9)
    ang = np.unwrap(np.arctan2(helix[:, 1], helix[:, 0] - 10))
    assert ang[-1] == pytest.approx(3 * np.pi, abs=1e-9) and np.all(np.diff(ang) > 0)  # half a turn + one, CCW
    assert np.allclose(helix[:, 2], -3 * ang / (3 * np.pi), atol=1e-9)
    assert np.allclose(prog.tip[-1], [25.4, 0, -3]) and prog.feed[-1] == pytest.approx(254.0)
    assert prog.toolpaths[0].name == "1" and not any("dropped" in w for w in prog.warnings)


def test_cli_cl_for_cc_cl_and_own_gcode(tmp_path):
    """analyze --cl for the other formats: a CC path (ball end, the tip a closed form of the CC
    point, normal and axis at the default lead of 11 deg), a CL CSV (its own rows back) and
    camsmooth's own G-code (the tips it was written from, within the written rounding)."""
    src = (Path(__file__).parent.parent / "surfaces" / "dome_path.csv").read_text().splitlines()
    cc = tmp_path / "cc.csv"
    cc.write_text("\n".join(src[:121]) + "\n")
    out = tmp_path / "cc_cl.csv"
    assert main(["analyze", str(cc), "--cutter-radius", "0", "--corner-radius", "3", "--cl", str(out),
                 "--quiet"]) == 0
    t = read_table(out, required=("x", "y", "z", "i", "j", "k"), text=("operation",))
    c = read_table(cc, required=("x", "y", "z", "nx", "ny", "nz"))
    p = np.column_stack([c["x"], c["y"], c["z"]])
    n = np.column_stack([c["nx"], c["ny"], c["nz"]])
    ax = np.column_stack([t["i"], t["j"], t["k"]])
    assert np.allclose(np.column_stack([t["x"], t["y"], t["z"]]), p + 3 * n - 3 * ax, atol=1e-9)
    assert np.allclose(np.sum(ax * n, axis=1), np.cos(np.radians(11.0)), atol=1e-9)
    # a CL CSV: its rows back, every one a feed point
    cl = tmp_path / "cl.csv"
    cl.write_text("x,y,z,i,j,k,feed\n0,0,0,0,0,1,500\n1,0,0,0,0.6,0.8,500\n2,0,0.5,0,0,1,700\n")
    out2 = tmp_path / "cl_out.csv"
    assert main(["analyze", str(cl), "--cl", str(out2), "--quiet"]) == 0
    t2 = read_table(out2, required=("x", "y", "z", "i", "j", "k", "feed"), text=("operation",))
    assert np.allclose(np.column_stack([t2["x"], t2["y"], t2["z"], t2["j"], t2["feed"]]),
                       [[0, 0, 0, 0, 500], [1, 0, 0, 0.6, 500], [2, 0, 0.5, 0, 700]])
    # camsmooth's own G-code (its writer, camsmooth.post.writer): the tips it was written from
    from test_gcode import CUTTER, MACHINE, _method

    from camsmooth.smoothing.posting import write_gcode

    m, feed = _method()
    nc = write_gcode(tmp_path / "own.nc", m, MACHINE, CUTTER, feed, safe_height=7.5, dialect="linuxcnc", mode="tcp")
    out3 = tmp_path / "own_cl.csv"
    assert main(["analyze", str(nc), "--cl", str(out3), "--quiet"]) == 0
    t3 = read_table(out3, required=("x", "y", "z", "i", "j", "k", "row"), text=("operation",))
    assert len(t3) == len(m.rows) and np.array_equal(t3["row"], m.rows)
    assert np.allclose(np.column_stack([t3["x"], t3["y"], t3["z"]]), m.cl, atol=1e-3)
    assert np.allclose(np.column_stack([t3["i"], t3["j"], t3["k"]]), m.axis, atol=1e-5)


def _canon_arcs(text: str) -> list[tuple[np.ndarray, np.ndarray | None, int, float]]:
    """Every feed motion of rs274's canonical calls as (end X Y Z mm, arc centre X Y Z mm or None,
    rotation, the mm of its last printed digit), planes (SELECT_PLANE) and units (USE_LENGTH_UNITS:
    inch values times 25.4) followed."""
    out, plane, scale = [], "XY", 1.0
    order = {"XY": (0, 1, 2), "XZ": (2, 0, 1), "YZ": (1, 2, 0)}  # first, second, normal axis of ARC_FEED
    for ln in text.splitlines():
        m = re.search(r"(\w+)\((.*)\)\s*$", ln)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name == "SELECT_PLANE":
            plane = args.replace("CANON_PLANE_", "")
        elif name == "USE_LENGTH_UNITS":
            scale = 25.4 if "INCHES" in args else 1.0
        elif name in ("STRAIGHT_FEED", "ARC_FEED"):
            v = [float(x) for x in args.split(",")]
            if name == "STRAIGHT_FEED":
                out.append((np.array(v[:3]) * scale, None, 0, 5e-5 * scale))
                continue
            a, b, c = order[plane]
            end, centre = np.zeros(3), np.full(3, np.nan)
            end[a], end[b], end[c] = v[0], v[1], v[5]
            centre[a], centre[b] = v[2], v[3]
            out.append((end * scale, centre * scale, int(v[4]), 5e-5 * scale))
    return out


@needs_rs274
def test_arcs_planes_units_against_rs274(tmp_path):
    """Arcs in G17/G18/G19 with I J K and R (R < 0 over 180 deg), G91 arcs, a helix of P3 turns and
    an inch arc, block by block against LinuxCNC's interpreter: every block's end, every arc point
    on the circle about rs274's centre, the turns rs274 counts."""
    p = _write(tmp_path, "arcs.ngc", "G21 G90 G17\nG0 X0 Y0 Z0\nG1 X10 F300\nG3 X0 Y10 I-10 J0\n"
                                     "G2 X-10 Y0 Z-2 R10\nG18 G2 X0 Z-12 I10 K0\nG19 G3 Y0 Z-2 J0 K5\n"
                                     "G17 G91 G1 X5 Y5\nG3 X10 Y0 R-6\nG90 G3 X5 Y5 I-5 J0 Z-5 P3\n"
                                     "G20 G1 X1 Y1\nG2 X2 Y1 I0.5 J0\nM2\n")
    prog = read_posted(p, dialect="linuxcnc")
    canon = _canon_arcs(_rs274(tmp_path, p))
    cut = np.flatnonzero(~prog.rapid)
    blocks = [cut[prog.line[cut] == ln] for ln in dict.fromkeys(prog.line[cut])]
    assert len(blocks) == len(canon)
    for idx, (end, centre, rot, digit) in zip(blocks, canon, strict=True):
        pts = prog.tip[idx]
        assert np.allclose(pts[-1], end, atol=digit + 1e-9)  # rs274 prints 4 decimals (of mm or inch)
        if centre is not None:
            normal = np.isnan(centre)
            rel = (pts - np.where(normal, 0.0, centre))[:, ~normal]
            r = np.hypot(rel[:, 0], rel[:, 1])
            assert np.ptp(r) < 1e-3
            if abs(rot) > 1:  # the helix: |rot| turns begun, the last one partial
                first, second = np.flatnonzero(~normal)
                start = prog.tip[idx[0] - 1]
                ang = np.unwrap(np.arctan2(np.r_[start[second], pts[:, second]] - centre[second],
                                           np.r_[start[first], pts[:, first]] - centre[first]))
                assert 2 * np.pi * (abs(rot) - 1) < abs(ang[-1] - ang[0]) <= 2 * np.pi * abs(rot)


@needs_rs274
def test_canned_cycle_holes_against_rs274(tmp_path):
    """G81 (G99: back to R between the modal X Y blocks) and G83 (pecks) holes against the cycles as
    LinuxCNC expands them: each hole is the deepest feed end rs274 gives at its X Y."""
    text = ("G21 G90 G17\nG0 X0 Y0 Z20\nG99 G81 X10 Y10 Z-5 R2 F100\nX20\nY20\n"
            "G98 G83 X30 Y5 Z-8 R1 Q2\nG80\nG0 Z20\nM2\n")
    with pytest.raises(InputError, match="only canned cycles"):
        read_posted(_write(tmp_path, "cyc.ngc", text), dialect="linuxcnc")
    p = _write(tmp_path, "cyc2.ngc", text.replace("G80\n", "G80\nG1 X0 Y0 Z0 F100\n"))
    prog = read_posted(p, dialect="linuxcnc")
    assert [c.code for c in prog.cycles] == ["G81", "G83"] and [c.lines for c in prog.cycles] == [[3, 4, 5], [6]]
    deepest: dict[tuple[float, float], float] = {}
    for end, _, _, _ in _canon_arcs(_rs274(tmp_path, p)):
        if end[2] < 0:
            key = (round(end[0], 4), round(end[1], 4))
            deepest[key] = min(deepest.get(key, 0.0), end[2])
    holes = np.vstack([c.holes for c in prog.cycles])
    assert {(x, y): z for x, y, z in holes.tolist()} == deepest


def test_haas_program_layout(tmp_path):
    # Haas mill operator's manual, "G-codes": G28 G91 Z0 (home Z, then G90), G43 H, G187 (smoothness),
    # G234 (TCPC), G93 inverse time (F = 1 / block time, min); operations named by the comment before
    # each tool change, the tool comment (T1 D=...) not taken for a name
    text = ("%\nO1001 (PART)\n(T1 D=10. CR=0. - ZMIN=-5. - FLAT END MILL)\nG90 G94 G17 G49 G40 G80\nG21\n"
            "G28 G91 Z0.\nG90\n\n(FACE1)\nT1 M6\nS5000 M3\nG54\nG0 X-10. Y0.\nG43 Z15. H1\nG0 Z5.\nG1 Z0. F500.\n"
            "X50.\nG2 X60. Y10. R10.\nG0 Z15.\nG28 G91 Z0.\nG90\n(SWARF1)\nT2 M6\nG187 P1 E0.01\nG103 P1\n"
            "G0 G90 G54 X0. Y0. A0. C0.\nG234 H2\nG0 X0. Y0. Z50.\nG93 G1 Z10. A10. C5. F120.\n"
            "X5. A12. C8. F300.\nG94\nG49\nM30\n%\n")
    prog = read_posted(_write(tmp_path, "haas.nc", text))
    assert prog.dialect == "haas"
    ops = [(t.name, t.kind, t.tool.number) for t in prog.toolpaths]
    assert ops == [("FACE1", "3-axis", 1), ("SWARF1", "5-axis", 2)]
    arc = prog.tip[prog.line == 18]  # G2 R10 from (50, 0) to (60, 10): clockwise, under 180 deg, centre (60, 0)
    assert np.allclose(np.hypot(arc[:, 0] - 60, arc[:, 1]), 10, atol=1e-9) and np.all(arc[:, 0] < 60 + 1e-9)
    assert prog.feed[-2] == pytest.approx(40 * 120) and prog.feed[-1] == pytest.approx(5 * 300)
    assert not prog.rapid[-1] and prog.rows[-1] == prog.rows[-2]


def test_millplus_as_its_post_writes_it(tmp_path):
    # MillPlus as Autodesk's MillPlus post (millplus.cps) writes it (no MillPlus manual was found):
    # %PM, G7 A5= B5= C5= (spatial angles, R = Rz(C5) Ry(B5) Rx(A5)), absolute arc centres, B5=360
    # full circles, G81 Z (depth) + G79 X Y Z calls, G93 the datum shift (not inverse time), G141 TCP
    p = _write(tmp_path, "mp.nc", "%PM\nN9001\n(GASKET)\nG17\nG74 Z100. L1\nG7 L1=0\nT1 M6\nS5000 M3\nG54 I0\n"
                                  "G7 A5=30. B5=0. C5=90. L1=1\nG90\nG0 X0. Y0.\nG0 Z5.\nG1 Z0. F500.\nG1 X10. Y0.\n"
                                  "G3 X0. Y10. I0. J0.\nG2 I0. J0. B5=360 F600.\nG0 Z5.\nG81 Z-5. Y2. F100.\n"
                                  "G79 X5. Y5. Z0.\nG79 X8. Y5. Z0.\nG7 L1=1\nG93 X10. Y0. Z0.\nG141\n"
                                  "G0 X0. Y0. Z50. A0. C0.\nG1 X5. A10. C20. F800.\nG40\nG74 Z100. L1\nM30\n")
    prog = read_posted(p, machine=nominal_machine(("A", "C")))
    assert prog.dialect == "millplus" and prog.toolpaths[0].name == "GASKET"
    R = Rotation.from_euler("xyz", [30, 0, 90], degrees=True).as_matrix()
    assert np.allclose(prog.tip[prog.line == 15][-1], R @ [10, 0, 0])
    assert np.allclose(prog.axis[prog.line == 15], R[:, 2])
    circle = (prog.tip[prog.line == 17]) @ R  # back into the plane: a full circle of radius 10 about its origin
    assert np.allclose(np.hypot(circle[:, 0], circle[:, 1]), 10, atol=1e-9) and np.allclose(circle[-1], [0, 10, 0])
    (cyc,) = prog.cycles
    assert np.allclose(cyc.holes, [R @ [5, 5, -5], R @ [8, 5, -5]])
    tcp = prog.tip[prog.line == 26]
    assert np.allclose(tcp, [[15, 0, 50]])  # G93 X10: the datum shift, G141: X Y Z the tip
    assert prog.feed[prog.line == 26][0] == 800.0  # not inverse time


def test_latin1_comments(tmp_path):
    p = tmp_path / "lat.nc"
    p.write_bytes(b"G21 G90\n(Fr\xe4ser \xd810)\nG0 X0 Y0 Z5\nG1 Z0 F100\nX10\nM30\n")
    prog = load_program(p)
    assert np.allclose(prog.tip[-1], [10, 0, 0]) and "read as Latin-1" in prog.warnings[0]


def test_haas_m97_local_subprogram(tmp_path):
    # Haas operator's manual, "M97 Local Sub-Program Call": M97 P runs the blocks from N<P> up to M99
    p = _write(tmp_path, "m97.nc", "G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F100\nM97 P100 L2\nM30\nN100 G91 G1 X2.\nG90\nM99\n")
    prog = read_posted(p)
    assert np.allclose(prog.tip[~prog.rapid][:, 0], [0, 2, 4])


def test_heidenhain_tcpm_axis_spat(tmp_path):
    # TNC 640 manual, FUNCTION TCPM: with AXIS SPAT the A B C of an L block are spatial angles (the
    # tool axis Rz(C) Ry(B) Rx(A) e_z whatever the machine), with AXIS POS the machine's axis positions
    p = _write(tmp_path, "s.h", "0 BEGIN PGM S MM\n1 FUNCTION TCPM F TCP AXIS SPAT PATHCTRL AXIS\n"
                                "2 L X+0 Y+0 Z+50 A+0 B+0 C+0 R0 FMAX\n3 L X+5 A+10 B+20 C+30 F500\n"
                                "4 FUNCTION RESET TCPM\n5 END PGM S MM\n")
    prog = read_posted(p, machine=nominal_machine(("A", "C")))
    R = Rotation.from_euler("xyz", [10, 20, 30], degrees=True).as_matrix()
    assert np.allclose(prog.axis[-1], R[:, 2]) and np.allclose(prog.tip[-1], [5, 0, 50])
    assert not any("dropped" in w for w in prog.warnings)


def test_cli_cl_for_a_result_csv(tmp_path):
    """A camsmooth result CSV (camsmooth.io.result_csv): the CL is its clx,cly,clz and i,j,k, its row ids."""
    cols = ("row", "idx", "t", "x", "y", "z", "nx", "ny", "nz", "clx", "cly", "clz", "i", "j", "k", "lead", "tilt",
            "A", "B", "X", "Y", "Z", "delta", "lift", "status")
    rows = [(7, 0, 0.0, 0, 0, 0, 0, 0, 1, 0.0, 0.0, 1.0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 150, 0.1, 0, "ok"),
            (7, 1, 0.1, 1, 0, 0, 0, 0, 1, 1.0, 0.0, 1.0, 0, 0.6, 0.8, 0, 0, -36.87, 0, 1, 0, 150, 0.1, 0, "ok"),
            (9, 0, 0.0, 2, 0, 0, 0, 0, 1, 2.0, 0.5, 1.0, 0, 0, 1, 0, 0, 0, 0, 2, 0.5, 150, 0.1, 0, "ok"),
            (9, 1, 0.2, 3, 0, 0, 0, 0, 1, 3.0, 0.5, 1.0, 0, 0, 1, 0, 0, 0, 0, 3, 0.5, 150, 0.1, 0, "ok")]
    f = tmp_path / "result.csv"
    f.write_text(",".join(cols) + "\n" + "\n".join(",".join(str(v) for v in r) for r in rows) + "\n")
    out = tmp_path / "cl.csv"
    assert main(["analyze", str(f), "--cl", str(out), "--quiet"]) == 0
    t = read_table(out, required=("x", "y", "z", "i", "j", "k", "row"), text=("operation",))
    assert list(t["row"]) == [7, 7, 9, 9]
    assert np.allclose(np.column_stack([t["x"], t["y"], t["z"], t["j"]]), [[0, 0, 1, 0], [1, 0, 1, 0.6],
                                                                            [2, 0.5, 1, 0], [3, 0.5, 1, 0]])


def test_g93_block_whose_tip_stands_still(tmp_path):
    # G93: a block that only turns a rotary axis under TCP moves the tip by 0 mm: its tip feed takes the
    # feed of the move before it; F0 in G93 (no block time) costs its operation
    p = _write(tmp_path, "s.nc", "G21 G90\nG43.4 H1\nG0 X0 Y0 Z5 A0 C0\nG93 G1 Z0 F10\nG1 A5 F20\nG1 X5 F30\nG94\n"
                                 "G49\nM30\n")
    prog = read_posted(p)
    assert np.allclose(prog.feed[~prog.rapid], [50, 50, 150])
    q = _write(tmp_path, "z.nc", "G21 G90\nG0 X0 Y0 Z5\nG93 G1 Z0 F0\nM30\n")
    with pytest.raises(InputError, match="F0 in inverse time"):
        read_posted(q)


def test_heidenhain_plane_relativ(tmp_path):
    # TNC 640 manual, "PLANE RELATIV": a further rotation about an axis of the plane already tilted
    p = _write(tmp_path, "r.h", "0 BEGIN PGM R MM\n1 PLANE SPATIAL SPA+0 SPB+0 SPC+90 TURN FMAX\n"
                                "2 PLANE RELATIV SPA+30 TURN FMAX\n3 L X+0 Y+0 Z+5 R0 FMAX\n4 L X+10 F500\n"
                                "5 END PGM R MM\n")
    prog = read_posted(p)
    R = Rotation.from_euler("ZX", [90, 30], degrees=True).as_matrix()  # intrinsic: about Z, then the new X
    assert np.allclose(prog.tip[-1], R @ [10, 0, 5]) and np.allclose(prog.axis[-1], R[:, 2])


@pytest.mark.parametrize("dialect,mode", [("fanuc", "tcp"), ("fanuc", "machine"), ("siemens", "tcp"),
                                          ("siemens", "machine"), ("heidenhain", "tcp"), ("linuxcnc", "tcp"),
                                          ("linuxcnc", "machine"), ("generic", "machine")])
def test_camsmooth_posts_read_as_posted_programs(tmp_path, dialect, mode):
    """camsmooth's own writer (camsmooth.post.writer) in every dialect and mode, its header tag removed so
    that the posted reader reads it like any program: the tips and axes it was written from (within
    the 4 decimals written) and the feeds its own reader (read_gcode) gives."""
    from test_gcode import CUTTER, MACHINE, _method

    from camsmooth.post.own import read_gcode
    from camsmooth.smoothing.posting import write_gcode

    m, feed = _method()
    nc = write_gcode(tmp_path / "own.nc", m, MACHINE, CUTTER, feed, safe_height=7.5, dialect=dialect, mode=mode)
    plain = _write(tmp_path, "plain.nc", nc.read_text().replace("camsmooth post:", "post:"))
    prog = read_posted(plain, machine=MACHINE)
    own = read_gcode(nc, machine=MACHINE)
    cut = ~prog.rapid
    assert int(cut.sum()) == len(m.rows) and not any("dropped" in w for w in prog.warnings)
    assert np.allclose(prog.tip[cut], m.cl, atol=2e-4) and np.allclose(prog.axis[cut], m.axis, atol=1e-5)
    f_own = own.feed[~own.rapid]
    ok = np.isfinite(f_own)
    assert ok.sum() >= len(m.rows) - 3 and np.allclose(prog.feed[cut][ok], f_own[ok], rtol=1e-9)
