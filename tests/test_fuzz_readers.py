"""A short fuzz pass over the file readers (issue 21; the longer run is benchmarks/fuzz_readers.py):
valid files, mutated byte by byte and line by line, either read or raise InputError -- never
another exception, never hang (a deadline per example). Each finding of the fuzzer is kept below
as a plain regression test."""

from __future__ import annotations

import re

import numpy as np
import pytest

pytest.importorskip("hypothesis")

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from benchmarks.fuzz_readers import (  # noqa: E402
    READERS,
    _readers,
    apt_programs,
    check_apt_program,
    mutate,
    mutations,
    read_or_input_error,
    seed_files,
)
from camsmooth.errors import InputError  # noqa: E402
from camsmooth.io.apt import read_apt  # noqa: E402
from camsmooth.post.own import read_gcode  # noqa: E402


@pytest.fixture(scope="module")
def fuzz_folder(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz")
    return folder, seed_files(folder), _readers()


@pytest.mark.parametrize("name", READERS)
def test_seeds_read(fuzz_folder, name):
    folder, seeds, readers = fuzz_folder
    for file, data in seeds[name]:
        path = folder / f"seed_{file}"
        path.write_bytes(data)
        readers[name](path)  # every seed is a valid file


@pytest.mark.parametrize("name", READERS)
@settings(max_examples=120, deadline=3000, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(which=st.integers(0, 9), ops=mutations)
def test_mutated_files_read_or_raise_input_error(fuzz_folder, name, which, ops):
    folder, seeds, readers = fuzz_folder
    file, data = seeds[name][which % len(seeds[name])]
    path = folder / f"fuzz_{name}_{file}"
    path.write_bytes(mutate(data, ops))
    assert read_or_input_error(readers[name], path) in ("ok", "InputError")


@settings(max_examples=120, deadline=3000, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(data=apt_programs())
def test_generated_apt_programs_read_to_finite_points_or_raise_input_error(fuzz_folder, data):
    folder, _, _ = fuzz_folder
    path = folder / "generated.apt"
    path.write_bytes(data)
    assert check_apt_program(path) in ("ok", "InputError")


# ----------------------------------------------------------------------------------------------
# findings, as plain regression tests
def test_gcode_header_pivot_not_a_number_is_an_input_error(fuzz_folder):
    folder, seeds, _ = fuzz_folder
    name, data = seeds["gcode"][0]
    text = data.decode()
    assert "pivot=150.000000" in text
    for bad in ("150.00G000", "nan", "-5", "inf"):
        p = folder / "pivot.nc"
        p.write_text(text.replace("pivot=150.000000", f"pivot={bad}"))
        with pytest.raises(InputError, match=f"pivot={bad}: not a length") as exc:
            read_gcode(p)
        assert exc.value.line == next(k for k, ln in enumerate(text.splitlines(), 1) if "camsmooth post:" in ln)


def test_apt_huge_arc_is_an_input_error(tmp_path):
    p = tmp_path / "huge.cls"
    p.write_text("UNITS/MM\nFEDRAT/MMPM,100\nGOTO/1e8,0,0\nCIRCLE/0,0,0,0,0,1,1e8,0.01,0.5,6,1\nGOTO/0,1e8,0\n")
    with pytest.raises(InputError, match="points would be needed") as exc:
        read_apt(p, chord_tol=1e-5)
    assert exc.value.line == 4


def test_apt_record_of_commas_or_a_bare_slash_is_named_not_a_crash(tmp_path):
    p = tmp_path / "commas.cls"
    p.write_text("UNITS/MM\nFEDRAT/MMPM,100\n,,,\nGOTO/0,0,0\n/\nGOTO/1,0,0\n")
    prog = read_apt(p)
    assert len(prog) == 2 and prog.warnings == ["records ignored (not applied): ,,, (line 3); / (line 5)"]


@pytest.mark.parametrize("load", ["LOAD/TOOL,nan", "LOADTL/1e400", "LOADTL/2.5,0,50,0"])
def test_apt_tool_number_not_whole_is_an_input_error(tmp_path, load):
    p = tmp_path / "load.cls"
    p.write_text(f"UNITS/MM\nTLDATA/MILL,10,1,50\n{load}\nFEDRAT/MMPM,100\nGOTO/0,0,0\n")
    with pytest.raises(InputError, match="is not a whole number") as exc:
        read_apt(p)
    assert exc.value.line == 3


@pytest.mark.parametrize("body, needle, line", [
    ("GOTO/1e308,1e308,1e308\n", "'1e308' is beyond", 2),
    ("MSYS/1e308,0,0,1,0,0,0,1,0\nGOTO/1,1,1\n", "malformed MSYS: '1e308' is beyond", 2),
    ("GOTO/1,0,0\nCIRCLE/1e308,1e308,0,0,0,1,1,0.01,0.5,6,1\nGOTO/0,1,0\n", "malformed CIRCLE", 3),
    ("FEDRAT/IPM,1e308\nGOTO/1,1,1\n", "FEDRAT must be > 0 and at most 1e+09", 2),
    ("SPINDL/RPM,1e308\nGOTO/1,1,1\n", "the speed 1e+308", 2),
    ("".join(f"GOTO/{'1e300' if k == 20 else k},0,0\n" for k in range(40)), "'1e300' is beyond", 22),
])
def test_apt_huge_numbers_are_input_errors_not_overflows(tmp_path, body, needle, line):
    """Numbers beyond 1e9 overflowed to infinity (inch scaling, norms) with numpy RuntimeWarnings."""
    import warnings

    p = tmp_path / "huge.apt"
    p.write_text("UNITS/INCHES\n" + body)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(InputError, match=re.escape(needle)) as exc:
            read_apt(p)
    assert exc.value.line == line


def test_cl_csv_huge_axis_is_an_input_error_without_overflow_warning(tmp_path):
    import warnings

    from camsmooth.io.clcsv import read_cl_csv

    p = tmp_path / "huge.csv"
    p.write_text("x,y,z,i,j,k\n1,2,3,0,0,1\n1e308,1e308,1e308,1e308,1e308,1e308\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(InputError, match="not a unit vector") as exc:
            read_cl_csv(p)
    assert (exc.value.row, exc.value.column) == (2, "i,j,k")


def test_gcode_axis_word_beyond_any_machine_is_an_input_error(fuzz_folder):
    folder, seeds, _ = fuzz_folder
    text = seeds["gcode"][0][1].decode()
    lines = text.splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("G00 X"))
    lines[k] = lines[k].replace("X0.0000", "X" + "9" * 40)
    p = folder / "big.nc"
    p.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"X1e\+40 is beyond \+-1e\+09") as exc:
        read_gcode(p)
    assert exc.value.line == k + 1
    p.write_text(text.replace("pivot=150.000000", "pivot=1e308"))
    with pytest.raises(InputError, match="pivot=1e308: not a length of 0 to 1e"):
        read_gcode(p)


@pytest.mark.parametrize("arc", ["CIRCLE/0,0,0,0,0,1,0.00001,0.01,0.5,6,1", "MOVARC/0,0,0,0,0,1,0.00001,ANGLE,90"])
def test_apt_arc_point_on_the_axis_is_an_input_error_not_nan(tmp_path, arc):
    """A tiny radius let a start point on the axis pass the radius check: NaN points (0 / 0)."""
    import warnings

    p = tmp_path / "axis.apt"
    p.write_text(f"UNITS/MM\nGOTO/0,0,0\n{arc}\nGOTO/0,0,0\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(InputError, match="start point lies on the axis") as exc:
            read_apt(p)
    assert exc.value.line == 3


def test_apt_movarc_of_no_sweep_is_no_arc(tmp_path):
    """Start = end with a sweep within the tolerance of 0 (found by the generated programs): no arc,
    not a full circle contradicting the sweep."""
    p = tmp_path / "zero.apt"
    p.write_text("UNITS/MM\nGOTO/81.5951,120.6399,60.0627\n"
                 "MOVARC/81.5451,120.6399,60.0627,0,1,0,0.05,ANGLE,0.005730\nGOTO/81.5951,120.6399,60.0627\n")
    prog = read_apt(p)
    assert len(prog) == 2


def test_apt_movarc_full_turn_with_end_a_hair_before_the_start(tmp_path):
    """ANGLE 360 with the end point a hair short of the start (rounding; found by the generated
    programs) is the full circle the record says, not a contradiction."""
    p = tmp_path / "full.apt"
    p.write_text("UNITS/MM\nGOTO/10,0,0\nMOVARC/0,0,0,0,0,1,10,ANGLE,360\nGOTO/10,-0.00001,0\n")
    prog = read_apt(p, chord_tol=0.01)
    ang = np.unwrap(np.arctan2(prog.tip[:, 1], prog.tip[:, 0]))
    assert np.all(np.diff(ang[:-1]) > 0) and ang[-2] > 2 * np.pi - 0.1
