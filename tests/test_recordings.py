"""Program/recording readers, the Michigan adapter, quantisation detection and alignment."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import UMICH, needs_umich  # noqa: E402

from camsmooth.diagnosis.recordings import (
    Program,
    Recording,
    align,
    concatenate,
    quantisation_steps,
    read_program_csv,
    read_recording_csv,
    read_umich,
    write_program_csv,
    write_recording_csv,
)
from camsmooth.errors import InputError


# ---- quantisation ----------------------------------------------------------------------------
def test_quantisation_fixed_decimals():
    rng = np.random.default_rng(0)
    v = np.round(rng.uniform(-50, 50, 500), 3)
    q = quantisation_steps(v)
    assert np.allclose(q, 1e-3)


def test_quantisation_significant_figures_like_michigan():
    # three significant figures: 158 has step 1, 72.4 step 0.1, 5.43 step 0.01
    rng = np.random.default_rng(1)
    raw = np.concatenate([rng.uniform(100, 199, 200), rng.uniform(10, 99, 200), rng.uniform(1, 9.9, 200)])
    v = np.array([float(f"{x:.3g}") for x in raw])
    q = quantisation_steps(v)
    assert np.allclose(q[:200], 1.0)
    assert np.allclose(q[200:400], 0.1)
    assert np.allclose(q[400:], 0.01)


def test_quantisation_absent_for_full_precision_and_few_values():
    rng = np.random.default_rng(2)
    assert not np.any(quantisation_steps(rng.normal(size=300)))
    assert not np.any(quantisation_steps(np.array([1.0, 2.0, 3.0] * 50)))  # 3 distinct values: no evidence


# ---- CSV round trips and errors ------------------------------------------------------------------
def test_program_round_trip_degrees(tmp_path):
    t = np.linspace(0, 1, 11)
    p = Program(t=t, axes={"X": np.sin(t), "A": np.radians(10 * t)}, S=np.full(11, 5000.0))
    write_program_csv(tmp_path / "p.csv", p)
    text = (tmp_path / "p.csv").read_text().splitlines()
    assert text[0] == "t,X,A,S"
    assert math.isclose(float(text[-1].split(",")[2]), 10.0)  # degrees in the file
    q = read_program_csv(tmp_path / "p.csv")
    assert np.allclose(q.axes["A"], p.axes["A"]) and np.allclose(q.axes["X"], p.axes["X"])
    assert np.allclose(q.S, 5000.0)


def test_recording_round_trip(tmp_path):
    t = np.arange(100) * 0.01
    r = Recording(t=t, channels={"X_act": t * 2, "B_act": np.radians(t), "tip_z": t * 0.5})
    write_recording_csv(tmp_path / "r.csv", r)
    q = read_recording_csv(tmp_path / "r.csv")
    assert set(q.channels) == {"X_act", "B_act", "tip_z"}
    assert np.allclose(q.channels["B_act"], r.channels["B_act"])


@pytest.mark.parametrize("reader, text, row, column", [
    (read_recording_csv, "t,X_act\n0,1\n0.1,abc\n0.2,3\n", 2, "X_act"),  # a bad cell
    (read_program_csv, "t,X\n0,1\n0.2,2\n0.1,3\n", 3, "t"),  # time must increase
])
def test_bad_input_names_row_and_column(tmp_path, reader, text, row, column):
    f = tmp_path / "in.csv"
    f.write_text(text)
    with pytest.raises(InputError) as e:
        reader(f)
    assert e.value.row == row and e.value.column == column


def test_missing_columns(tmp_path):
    f = tmp_path / "p.csv"
    f.write_text("time,X\n0,1\n1,2\n")
    with pytest.raises(InputError, match="missing column 't'"):
        read_program_csv(f)
    g = tmp_path / "r.csv"
    g.write_text("t,foo\n0,1\n1,2\n")
    with pytest.raises(InputError, match="no recorded channel"):
        read_recording_csv(g)
    with pytest.raises(InputError, match="not found"):
        read_program_csv(tmp_path / "nope.csv")


def test_nonfinite_value(tmp_path):
    f = tmp_path / "r.csv"
    f.write_text("t,tip_x\n0,1\n1,nan\n")
    with pytest.raises(InputError) as e:
        read_recording_csv(f)
    assert e.value.row == 2 and e.value.column == "tip_x"


# ---- alignment ---------------------------------------------------------------------------------
def test_align_evaluates_at_recording_times_and_drops_outside():
    t = np.linspace(0.0, 1.0, 11)
    p = Program(t=t, axes={"X": 10 * t})
    tr = np.linspace(-0.05, 1.05, 111)
    r = Recording(t=tr, channels={"X_act": 10 * tr})
    al = align(p, r)
    assert al.dropped == int(np.sum((tr < 0) | (tr > 1.0 + 1e-12)))
    assert al.t.min() >= 0.0 and al.t.max() <= 1.0
    assert "no extrapolation" in al.method


def test_concatenate_keeps_files_apart():
    t = np.linspace(0, 1, 11)
    pairs = [(Program(t=t, axes={"X": t}), Recording(t=t, channels={"X_act": t})) for _ in range(3)]
    p, r = concatenate(pairs, gap_s=2.0)
    assert len(p.t) == 33 and np.all(np.diff(p.t) > 0)
    assert list(np.unique(p.segment)) == [0, 1, 2]
    assert np.array_equal(np.unique(r.segment), np.unique(p.segment))


# ---- Michigan adapter --------------------------------------------------------------------------
@needs_umich
def test_umich_reads_command_and_actual():
    p, r = read_umich(UMICH / "experiment_01.csv")
    assert len(p) == 1055 and len(r) == 1055
    assert np.allclose(np.diff(p.t), 0.1)
    assert set(p.axes) == {"X", "Y", "Z"} and set(r.channels) == {"X_act", "Y_act", "Z_act"}
    # X (141-198 mm) is stored to whole millimetres: step 1 everywhere
    assert np.allclose(r.quantum["X_act"], 1.0)
    assert p.S is not None and p.S.max() > 0


@needs_umich
def test_umich_logging_gap_starts_a_segment():
    p, _ = read_umich(UMICH / "experiment_02.csv")
    # rows 104 -> 105 (0-based): X jumps 198 -> 141 mm with zero commanded velocity
    assert p.axes["X"][104] == 198.0 and p.axes["X"][105] == 141.0
    assert p.segment[105] == p.segment[104] + 1
    assert p.segment.max() > 50


def test_umich_bad_file(tmp_path):
    f = tmp_path / "x.csv"
    f.write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="X1_CommandPosition"):
        read_umich(f)
