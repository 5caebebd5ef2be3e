"""APT records beyond the geometry: a record that cannot be read costs only its tool path (issue 21),
harmless records are skipped, continuation lines and records without '/' read as the module says.

Expected points are written into the files by the tests (whole millimetres), not taken from the
reader."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.io.apt import read_apt


def _write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def _nx_path(name: str, x0: int, body: str = "", tail: str = "") -> str:
    """An NX tool path of three points at x = x0, x0 + 1, x0 + 2 (y = 0, z = 0), with ``body``
    inserted after the first point and ``tail`` after the last."""
    return (f"TOOL PATH/{name},TOOL,T1\nTLDATA/MILL,10,1,50,0,0\nFEDRAT/MMPM,1000\n"
            f"GOTO/{x0},0,0,0,0,1\n{body}GOTO/{x0 + 1},0,0\nGOTO/{x0 + 2},0,0\n{tail}END-OF-PATH\n")


def _line(text: str, needle: str) -> int:
    return next(k for k, ln in enumerate(text.splitlines(), start=1) if needle in ln)


@pytest.mark.parametrize("bad, needle", [
    ("GOTO/1,2\n", "malformed GOTO"),
    ("GOTO/1,0,0,0,0,3\n", "not a unit vector"),
    ("CIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1\n", "not followed by a GOTO"),
    ("MSYS/0,0,0,1,0,0,1,0,0\n", "not perpendicular"),
    ("FEDRAT/IPR,0.1\n", "without a spindle speed"),
    ("TLDATA/MILL,10,8,50\n", "corner radius"),
    ("MOVARC/0,0,0,0,0,1,30,90\n", "malformed MOVARC"),
])
def test_a_bad_record_costs_only_its_tool_path(tmp_path, bad, needle):
    where = {"tail": bad} if bad.startswith("CIRCLE") else {"body": bad}
    text = "UNITS/MM\n" + _nx_path("A", 0) + _nx_path("B", 10, **where) + _nx_path("C", 20)
    p = _write(tmp_path, "three.cls", text)
    prog = read_apt(p)
    assert [tp.name for tp in prog.toolpaths] == ["A", "C"]
    np.testing.assert_array_equal(prog.tip[:, 0], [0, 1, 2, 20, 21, 22])
    assert [(tp.start, tp.stop) for tp in prog.toolpaths] == [(0, 3), (3, 6)]
    assert prog.rows.tolist() == [0, 0, 0, 1, 1, 1] and np.all(prog.feed == 1000)
    dropped = [w for w in prog.warnings if "dropped" in w]
    bad_line = _line(text, bad.splitlines()[0])
    assert len(dropped) == 1, prog.warnings
    w = dropped[0]
    assert w.startswith(f"tool path 'B' (line {_line(text, 'TOOL PATH/B')}) dropped: ")
    assert str(p) in w and f"line {bad_line}" in w and needle in w, w


def test_the_last_tool_path_bad_and_an_arc_without_end_at_the_end(tmp_path):
    text = "UNITS/MM\n" + _nx_path("A", 0) + "TOOL PATH/B,TOOL,T1\nGOTO/5,0,0\nCIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1\n"
    prog = read_apt(_write(tmp_path, "end.cls", text))
    assert [tp.name for tp in prog.toolpaths] == ["A"] and len(prog) == 3
    assert any("tool path 'B'" in w and "not followed by a GOTO" in w for w in prog.warnings)


def test_no_tool_path_readable_is_an_input_error(tmp_path):
    # one bad tool path: its own error, as before
    one = _write(tmp_path, "one.cls", "UNITS/MM\n" + _nx_path("A", 0, "GOTO/1,2\n"))
    with pytest.raises(InputError, match="malformed GOTO") as exc:
        read_apt(one)
    assert exc.value.line == 6
    # several, all bad: named together, with the first
    two = _write(tmp_path, "two.cls", "UNITS/MM\n" + _nx_path("A", 0, "GOTO/1,2\n") + _nx_path("B", 5, "GOTO/x,0,0\n"))
    with pytest.raises(InputError) as exc:
        read_apt(two)
    msg = str(exc.value)
    assert "no tool path could be read: all 2 were dropped" in msg and "malformed GOTO" in msg and str(two) in msg


def test_fusion_tool_change_is_the_cut(tmp_path):
    """Without TOOL PATH/ records a tool change (CUTTER/) cuts the file into tool paths: a bad
    record drops the points since the last tool change, a bad CUTTER/ the points after it."""
    head = "UNITS/MM\nMULTAX/ON\nFEDRAT/500,MMPM\n"
    t1 = "CUTTER/10,2,0,2,0,0,25\nLOADTL/1\nGOTO/0,0,0,0,0,1\nGOTO/1,0,0\n"
    t2 = "CUTTER/6,3,0,3,0,0,20\nLOADTL/2\nGOTO/10,0,0\nGOTO/10,0\nGOTO/11,0,0\n"
    t3 = "CUTTER/8,1,0,1,0,0,20\nLOADTL/3\nGOTO/20,0,0\nGOTO/21,0,0\n"
    prog = read_apt(_write(tmp_path, "f.apt", head + t1 + t2 + t3 + "END\nFINI\n"))
    assert [tp.tool.number for tp in prog.toolpaths] == [1, 3]
    np.testing.assert_array_equal(prog.tip[:, 0], [0, 1, 20, 21])
    w = [w for w in prog.warnings if "dropped" in w]
    assert len(w) == 1 and "(unnamed, from line 8)" in w[0] and "line 11" in w[0], w
    bad_cutter = t2.replace("CUTTER/6,3,", "CUTTER/6,4,").replace("GOTO/10,0\n", "")
    prog = read_apt(_write(tmp_path, "g.apt", head + t1 + bad_cutter + t3))
    assert [tp.tool.number for tp in prog.toolpaths] == [1, 3]
    np.testing.assert_array_equal(prog.tip[:, 0], [0, 1, 20, 21])
    assert any("line 8" in w and "corner radius" in w for w in prog.warnings), prog.warnings


# ----------------------------------------------------------------------------------------------
# record syntax: '/', continuation, harmless and not-applied records
HARMLESS = """PARTNO BLADE 7
PARTNO/'blade / 7, finish'
MACHIN/MILL,1
PPRINT/'op: finish / lead 10, tilt 0'
PPRINT finish without a slash
INSERT M08
SPINDL/RPM,9000,CLW
SPINDL/OFF
COOLNT/flood
COOLNT/OFF
SELECT/TOOL,3
TOOLNO/3
SEQNO/ON
OPSKIP/ON
OPSTOP
DELAY/1.5
INTOL/0.01
OUTTOL/0.01
AUTOPS
INDIRV/1,0,0
CLRSRF/Z,50
CLEARP/XYPLAN,50
AUXFUN/99,NOW
PAINT/COLOR,186
DISPLY/ON
REMARK this is a remark
CYCLE/OFF
MULTAX/ON
MULTAX
MODE/MILL
END
FINI
"""


def test_harmless_records_give_no_warning(tmp_path):
    text = "UNITS/MM\nFEDRAT/MMPM,100\nGOTO/0,0,0\n" + HARMLESS + "GOTO/1,0,0\n"
    prog = read_apt(_write(tmp_path, "h.apt", text))
    assert prog.warnings == [] and len(prog) == 2


def test_records_not_applied_are_one_warning(tmp_path):
    text = ("UNITS/MM\nFEDRAT/MMPM,100\nCUTCOM/LEFT\nGOTO/0,0,0\nCYCLE/DRILL,5,MMPM,100,2\nGOTO/1,0,0\n"
            "CUTCOM/OFF\nGODLTA/0,0,5\nTLAXIS/NORMPS\nCYCLE/OFF\nWHATEVER/1,2\nGOTO/2,0,0\n")
    prog = read_apt(_write(tmp_path, "n.apt", text))
    assert prog.warnings == ["records ignored (not applied): CUTCOM (lines 3, 7); CYCLE (line 5); GODLTA (line 8); "
                             "TLAXIS (line 9); WHATEVER (line 11)"], prog.warnings
    assert len(prog) == 3


def test_slash_spacing_case_and_continuations(tmp_path):
    text = ("UNITS/MM\nfedrat / mmpm , 100\n"
            "GOTO / 1.0 , 2.0 , 3.0\n"
            "  goto/\t4,5,6,0,0,1\n"
            "GOTO/7,$\n8,$   \n 9 $$ a comment after the last part\n"
            "GOTO/10,11,12,$ $$ a comment after the continuation mark\n"
            "0.6,0,0.8\n"
            "GOTO/13,14,15\n16,17,18\n19,20,21,0,0.6,0.8\n"
            "$$ GOTO/99,99,99 a comment line\n"
            "GOTO/22,23,$\n")  # a continuation at the end of the file: the record is read as it stands
    p = _write(tmp_path, "s.cls", text)
    with pytest.raises(InputError, match="malformed GOTO: '' is not a number") as exc:
        read_apt(p)  # 'GOTO/22,23,' has an empty third number
    assert exc.value.line == 14
    prog = read_apt(_write(tmp_path, "t.cls", text.replace("GOTO/22,23,$\n", "GOTO/22,23,$\n24\n")))
    np.testing.assert_allclose(prog.tip, [[1, 2, 3], [4, 5, 6], [7, 8, 9], [10, 11, 12], [13, 14, 15], [16, 17, 18],
                                          [19, 20, 21], [22, 23, 24]])
    np.testing.assert_allclose(prog.axis, [[0, 0, 1]] * 3 + [[0.6, 0, 0.8]] * 3 + [[0, 0.6, 0.8]] * 2)
    assert prog.line.tolist() == [3, 4, 5, 8, 10, 11, 12, 14] and np.all(prog.feed == 100) and not prog.warnings


def test_tlaxis_sets_the_modal_axis(tmp_path):
    text = "UNITS/MM\nFEDRAT/MMPM,100\nGOTO/0,0,0\nTLAXIS/0,0.6,0.8\nGOTO/1,0,0\nGOTO/2,0,0,1,0,0\nGOTO/3,0,0\n"
    prog = read_apt(_write(tmp_path, "a.apt", text))
    np.testing.assert_allclose(prog.axis, [[0, 0, 1], [0, 0.6, 0.8], [1, 0, 0], [1, 0, 0]])
    with pytest.raises(InputError, match=r"tool axis \(i, j, k\) \(0, 0, 2\) is not a unit vector") as exc:
        read_apt(_write(tmp_path, "b.apt", text.replace("TLAXIS/0,0.6,0.8", "TLAXIS/0,0,2")))
    assert exc.value.line == 4


def test_latin1_text_records_do_not_cost_the_file(tmp_path):
    """A Windows CAM system's PPRINT in its code page ('Fräser Ø10' in cp1252): read, with a warning."""
    text = "UNITS/MM\nPPRINT/'Fräser Ø10'\nFEDRAT/MMPM,100\nGOTO/0,0,0\nGOTO/1,0,0\n"
    p = tmp_path / "latin.apt"
    p.write_bytes(text.encode("cp1252"))
    prog = read_apt(p)
    assert len(prog) == 2
    assert prog.warnings == ["the APT file is not UTF-8 text (byte 0xe4 on line 2): read as Latin-1 (only text "
                             "records such as PPRINT should hold such bytes)"], prog.warnings
    # with a byte-order mark in front the byte named is still the file's 'ä' on line 2 (the decoder
    # counts after the mark: 0x27, the quote three bytes before, was named)
    (tmp_path / "bom.apt").write_bytes(b"\xef\xbb\xbf" + text.encode("cp1252"))
    assert read_apt(tmp_path / "bom.apt").warnings == prog.warnings
    with pytest.raises(InputError, match="UTF-16"):
        q = tmp_path / "u16.apt"
        q.write_bytes(text.encode("utf-16"))
        read_apt(q)


@pytest.mark.parametrize("n", [5, 40])
def test_inches_on_the_record_path_and_the_bulk_path(tmp_path, n):
    """UNITS/INCHES converts every point to mm whether the GOTO run is short (record by record) or
    long (the bulk parser takes runs of 16 and more): issue 21 item 5 (b). Points 0.1 in apart along
    x, at y = 2 in, z = 0.5 in, the axis (0, 0.6, 0.8) on every fourth point, else the modal one;
    expected values worked out here (1 in = 25.4 mm), the feed 20 in/min = 508 mm/min."""
    k = np.arange(n)
    recs = [f"GOTO/{0.1 * i:.1f},2,0.5" + (",0,0.6,0.8" if i % 4 == 0 else "") for i in k]
    text = "UNITS/INCHES\nMULTAX/ON\nFEDRAT/20\n" + "\n".join(recs) + "\n"
    prog = read_apt(_write(tmp_path, "inch.apt", text))
    np.testing.assert_allclose(prog.tip, np.column_stack([2.54 * k, np.full(n, 50.8), np.full(n, 12.7)]),
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(prog.axis, np.tile([0.0, 0.6, 0.8], (n, 1)), atol=1e-12)
    np.testing.assert_allclose(prog.feed, 508.0, rtol=1e-12)
