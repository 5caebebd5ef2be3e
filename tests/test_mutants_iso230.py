"""What the mutation run of camsmooth/diagnosis/iso230.py (benchmarks/mutation.py, target "iso230")
showed the ISO 230-2 tests leave open, checked against values worked by hand: the fitted terms and
the table from them on a noise-free run (exact), the leave-one-run-out figures, the controller's trim
(interpolated, held at the ends, chosen by direction), the COMP_FILE text and its reader's refusals,
the simulated run's cycle and the limits of a LinuxCNC table."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from camsmooth.diagnosis import iso230 as I
from camsmooth.errors import InputError

UM = 1e-3


def _run(rows: list[tuple[float, int, int, float]]) -> I.Run:
    t, d, r, x = zip(*rows, strict=True)
    return I.Run(np.array(t, float), np.array(d, int), np.array(r, int), np.array(x, float), "run.csv")


def _linear_run(e0: float, k: float, b: float, targets=(0.0, 100.0, 250.0), runs: int = 3) -> I.Run:
    """deviation = e0 + k P + d b / 2 exactly (no noise)."""
    rows = [(p, d, r, e0 + k * p + d * b / 2) for r in range(1, runs + 1) for d in (1, -1) for p in targets]
    return _run(rows)


def test_fitted_terms_of_a_noise_free_run_are_exact():
    """e0 = 4 um, k = 20 um/m, B = -18 um: the least-squares fit returns them with zero scatter;
    the table's trims are minus the deviation moving each way: at 100 mm up -(4 + 2 - 9) = 3 um,
    down -(4 + 2 + 9) = -15 um (nominals sorted)."""
    run = _linear_run(4 * UM, 20e-6, -18 * UM)
    f = I.fit_terms(run)
    assert (f.offset, f.scale, f.reversal) == pytest.approx((4 * UM, 20e-6, -18 * UM), abs=1e-12)
    assert (f.sd_offset, f.sd_scale, f.sd_reversal, f.residual_rms) == pytest.approx((0, 0, 0, 0), abs=1e-9)
    assert f.n == 18
    np.testing.assert_allclose(f.deviation(np.array([100.0, 100.0]), np.array([1, -1])), [-3 * UM, 15 * UM],
                               atol=1e-12)
    table = I.compensation_from_terms(f, [250.0, 0.0, 100.0])
    assert table.nominal == (0.0, 100.0, 250.0)
    assert table.forward == pytest.approx((5 * UM, 3 * UM, 0.0), abs=1e-12)
    assert table.reverse == pytest.approx((-13 * UM, -15 * UM, -18 * UM), abs=1e-12)


def test_fit_terms_uses_only_the_approaches_kept_and_gives_plain_scatter():
    """Two targets (0, 10 mm), two runs each way, worked by hand below; run 1 alone (``keep``) fits
    without scatter. Fewer than 4 approaches, or one direction only, cannot give the three terms."""
    rows = [(0.0, 1, 1, 1 * UM), (0.0, -1, 1, -1 * UM), (10.0, 1, 1, 1 * UM), (10.0, -1, 1, -1 * UM),
            (0.0, 1, 2, 2 * UM), (0.0, -1, 2, -2 * UM), (10.0, 1, 2, 0.0), (10.0, -1, 2, 0.0)]
    run = _run(rows)
    f = I.fit_terms(run)
    assert f.reversal == pytest.approx(2 * UM, abs=1e-12) and f.n == 8
    # by hand: means at P=0: up 1.5, down -1.5; at P=10: up 0.5, down -0.5 (um); e0 + k P fits the
    # bidirectional means 0 and 0 -> e0 = k = 0; B/2 fits 1.5, 0.5 -> B/2 = 1 um; residuals
    # (up, P=0): 1-1 = 0, 2-1 = 1; (down, 0): 0, -1; (up, 10): 0, -1; (down, 10): 0, 1 -> RMS sqrt(4/8)
    assert (f.offset, f.scale) == pytest.approx((0.0, 0.0), abs=1e-12)
    assert f.residual_rms == pytest.approx(math.sqrt(0.5) * UM, rel=1e-9)
    # s^2 = 4 um^2 / (8 - 3); sd(B) = 2 * sqrt(s^2 / 8) (d / 2 is +-1/2 on every approach, orthogonal to the rest)
    assert f.sd_reversal == pytest.approx(2 * math.sqrt(4 / 5 / 8) * UM, rel=1e-9)
    one = I.fit_terms(run, run.run == 1)
    assert one.n == 4 and one.residual_rms == pytest.approx(0.0, abs=1e-12)
    with pytest.raises(InputError, match="2 or more targets in both directions"):
        I.fit_terms(run, np.array([1, 1, 1, 0, 0, 0, 0, 0], bool))
    with pytest.raises(InputError, match="both directions"):
        I.fit_terms(run, run.direction == 1)


def test_crossvalidation_of_a_noise_free_linear_run_leaves_nothing():
    """Every fold refits the same line exactly: after = 0; noise = 0 (no scatter within a target and
    direction); before = RMS of all deviations; folds = the number of runs. Fewer than 2 runs: refused."""
    run = _linear_run(4 * UM, 20e-6, -18 * UM, runs=4)
    cv = I.crossvalidate(run)
    assert cv["folds"] == 4
    assert cv["after"] == pytest.approx(0.0, abs=1e-12) and cv["noise"] == pytest.approx(0.0, abs=1e-12)
    assert cv["before"] == pytest.approx(math.sqrt(np.mean(run.deviation ** 2)), rel=1e-12)
    with pytest.raises(InputError, match="at least 2 runs"):
        I.crossvalidate(_linear_run(0.0, 0.0, 1 * UM, runs=1))


def test_crossvalidation_noise_is_the_pooled_within_target_scatter():
    """Two targets, 3 runs each way; within each (target, direction) the deviations are base + (-1, 0,
    +1) um or base + (0, 0, 3) um: sums of squares 2 and 6 um^2 on 2 degrees of freedom each; pooled
    over the four cells (2 + 6 + 2 + 6) / 8 = 2 um^2: noise sqrt(2) um."""
    rows = []
    for p, d, extra in ((0.0, 1, (-1, 0, 1)), (0.0, -1, (0, 0, 3)), (50.0, 1, (-1, 0, 1)), (50.0, -1, (0, 0, 3))):
        for r, e in enumerate(extra, start=1):
            rows.append((p, d, r, (5.0 * d + e) * UM))
    cv = I.crossvalidate(_run(rows))
    assert cv["noise"] == pytest.approx(math.sqrt(2.0) * UM, rel=1e-12)
    assert cv["folds"] == 3


def test_trim_interpolates_holds_and_follows_the_direction():
    table = I.CompTable(nominal=(0.0, 10.0, 30.0), forward=(0.0, 0.010, 0.030), reverse=(-0.001, -0.002, -0.004))
    got = I.trim(table, np.array([5.0, 20.0, -7.0, 40.0, 5.0, 20.0, 45.0]), np.array([1, 1, 1, 1, -1, -1, -1]))
    np.testing.assert_allclose(got, [0.005, 0.020, 0.0, 0.030, -0.0015, -0.003, -0.004], atol=1e-15)
    run = _run([(5.0, 1, 1, 0.001), (20.0, -1, 1, 0.002)])
    after = I.apply_compensation(run, table)
    np.testing.assert_allclose(after.deviation, [0.006, -0.001], atol=1e-15)
    assert (after.file, after.run.tolist()) == ("run.csv", [1, 1])
    before, rms = I.heldout_rms(run, table)
    assert before == pytest.approx(math.sqrt((0.001 ** 2 + 0.002 ** 2) / 2))
    assert rms == pytest.approx(math.sqrt((0.006 ** 2 + 0.001 ** 2) / 2))


def test_comp_text_and_its_reader(tmp_path):
    table = I.CompTable(nominal=(-5.0, 12.5), forward=(0.001, -0.0025), reverse=(0.0, 1.0))
    assert I.comp_text(table) == "-5.000000 0.001000 0.000000\n12.500000 -0.002500 1.000000\n"
    path = I.write_comp_file(tmp_path / "x.comp", table)
    assert path == tmp_path / "x.comp"
    (tmp_path / "blank.comp").write_text("\n0 1 2\n\n3 4 5\n")
    back = I.read_comp_file(tmp_path / "blank.comp")
    assert (back.nominal, back.forward, back.reverse) == ((0.0, 3.0), (1.0, 4.0), (2.0, 5.0))
    for text, msg in (("0 1 2\n0 1 2\n", "line 2: nominal positions must be strictly ascending"),
                      ("0 1 2\n-1 0 0\n", "line 2: nominal positions must be strictly ascending"),
                      ("0 1\n", "line 1: expected three numbers"), ("0 1 2 3\n", "line 1: expected three numbers"),
                      ("0 nan 2\n", "line 1: expected three numbers"), ("\n\n", "empty compensation file")):
        (tmp_path / "bad.comp").write_text(text)
        with pytest.raises(InputError) as exc:
            I.read_comp_file(tmp_path / "bad.comp")
        assert msg in str(exc.value) and "bad.comp" in str(exc.value)


def test_a_linuxcnc_table_holds_at_most_256_lines():
    many = [float(p) for p in range(257)]
    terms = I.fit_terms(_linear_run(0.0, 1e-6, 1 * UM))
    assert len(I.compensation_from_terms(terms, many[:256]).nominal) == 256
    with pytest.raises(InputError, match="257 nominal positions.*at most 256"):
        I.compensation_from_terms(terms, many)
    r = I.evaluate(_linear_run(0.0, 0.0, 1 * UM, targets=tuple(many[:256]), runs=2))
    assert len(I.compensation_table(r).nominal) == 256
    r257 = I.evaluate(_linear_run(0.0, 0.0, 1 * UM, targets=tuple(many), runs=2))
    with pytest.raises(InputError, match="257 targets.*at most 256"):
        I.compensation_table(r257)


def test_simulated_run_follows_the_standard_cycle_and_its_formula():
    """Without noise: run r goes up through the targets then down; deviation = pitch P + periodic
    sin(2 pi P / period) - direction reversal / 2 (um -> mm)."""
    p = np.array([0.0, 2.5, 40.0])
    run = I.simulate_run(p, 2, pitch_um_per_m=100.0, periodic_um=3.0, period_mm=10.0, reversal_um=8.0, noise_um=0.0)
    assert run.target.tolist() == [0.0, 2.5, 40.0, 40.0, 2.5, 0.0] * 2
    assert run.direction.tolist() == [1, 1, 1, -1, -1, -1] * 2
    assert run.run.tolist() == [1] * 6 + [2] * 6
    want = [1e-3 * (0.1 * x + 3.0 * math.sin(2 * math.pi * x / 10.0) - d * 4.0)
            for x, d in zip(run.target, run.direction, strict=True)]
    np.testing.assert_allclose(run.deviation, want, atol=1e-15)
    noisy = I.simulate_run(p, 50, noise_um=2.0, seed=4)
    resid = noisy.deviation - I.systematic(noisy.target, noisy.direction)
    assert np.std(resid) == pytest.approx(0.002, rel=0.15)


def test_result_json_carries_what_it_is_given():
    run = _linear_run(4 * UM, 20e-6, -18 * UM)
    r = I.evaluate(run, axis="Y")
    doc = json.loads(I.result_json(r))
    assert (doc["axis"], doc["units"], doc["standard"]) == ("Y", "mm", "ISO 230-2")
    assert doc["B"] == pytest.approx(0.018) and not {"compensation", "heldout_rms", "fitted_terms"} & set(doc)
    terms = I.fit_terms(run)
    full = json.loads(I.result_json(r, I.compensation_from_terms(terms, r.targets), (0.02, 0.001), terms,
                                    I.crossvalidate(run), table_from="fitted terms"))
    assert full["heldout_rms"] == {"before": 0.02, "after": 0.001}
    assert full["compensation"]["built_from"] == "fitted terms"
    assert full["compensation"]["forward"] == pytest.approx([5 * UM, 3 * UM, 0.0], abs=1e-12)
    assert full["fitted_terms"]["reversal"] == pytest.approx(-18 * UM)
    # the model as the module docstring writes it: P the position, the reversal halved per direction
    assert full["fitted_terms"]["model"] == "deviation = offset + scale * P + direction * reversal / 2"
    assert full["crossvalidated_rms"]["folds"] == 3


def test_run_csv_round_trip_and_too_few_approaches(tmp_path):
    run = I.simulate_run(np.array([0.0, 10.0]), 2, noise_um=0.5, seed=1)
    back = I.read_run(I.write_run_csv(tmp_path / "r.csv", run))
    np.testing.assert_allclose(back.deviation, run.deviation, rtol=0, atol=1e-15)
    assert back.direction.tolist() == run.direction.tolist() and back.run.tolist() == run.run.tolist()
    one_down = _run([(0.0, 1, 1, 0.0), (0.0, 1, 2, 0.0), (0.0, -1, 1, 0.0),
                     (5.0, 1, 1, 0.0), (5.0, 1, 2, 0.0), (5.0, -1, 1, 0.0), (5.0, -1, 2, 0.0)])
    with pytest.raises(InputError, match=r"target 0 has 1 approach\(es\) in direction -1"):
        I.evaluate(one_down)


def test_refusals_name_the_column_and_the_approach(tmp_path):
    """A run at one target names the 'target' column; a cross-validation of one run the 'run'
    column; an approach given twice names its target, direction and run and the row it was first
    given on (rows counted from 1 below the header)."""
    with pytest.raises(InputError, match="column 'target'") as exc:
        I.evaluate(_run([(0.0, 1, 1, 0.0), (0.0, 1, 2, 0.0), (0.0, -1, 1, 0.0), (0.0, -1, 2, 0.0)]))
    assert "at least 2 target positions" in str(exc.value)
    with pytest.raises(InputError, match="column 'run'"):
        I.crossvalidate(_linear_run(0.0, 0.0, 1 * UM, runs=1))
    path = tmp_path / "dup.csv"
    path.write_text("target,direction,run,deviation\n5,1,1,0\n7,-1,2,0\n5,1,1,0.001\n")
    with pytest.raises(InputError, match=r"approach given twice \(target 5, direction \+1, run 1; first on row 1\)"):
        I.read_run(path)


def test_the_run_file_has_the_documented_columns(tmp_path):
    """write_run_csv writes the columns of the module docstring, in that order."""
    run = I.simulate_run(np.array([0.0, 10.0]), 2, noise_um=0.0)
    path = I.write_run_csv(tmp_path / "r.csv", run)
    assert path.read_text().splitlines()[0] == "target,direction,run,deviation"


def test_the_default_simulated_axis_is_the_one_the_benchmarks_describe():
    """docs/benchmarks.md (ISO 230-2): pitch 20 um/m, a 5 um screw term of 10 mm period, 18 um
    reversal (the carriage stopping short), 1 um noise: the defaults of simulate_run / systematic."""
    p = np.array([0.0, 2.5, 7.5, 400.0])
    d = np.array([1, -1, 1, -1])
    want = 1e-3 * (20e-3 * p + 5.0 * np.sin(2 * np.pi * p / 10.0) - d * 9.0)
    np.testing.assert_allclose(I.systematic(p, d), want, atol=1e-15)
    run = I.simulate_run(p, 200, seed=7)
    resid = run.deviation - I.systematic(run.target, run.direction)
    assert np.std(resid) == pytest.approx(0.001, rel=0.1)
    exact = I.simulate_run(p, 1, noise_um=0.0)
    np.testing.assert_allclose(exact.deviation, I.systematic(exact.target, exact.direction), atol=0)
