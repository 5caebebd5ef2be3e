"""Issue 20: misses of `camsmooth diagnose`, each fixed as a class - internal failures are exit 70
(not bad input), per-channel resolution from the data's own grid, significance judged on the
channels a term acts on, lag told from clock offset by the response shape, significance that does
not depend on what else is unexplained, and an effect outside the library left unexplained."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.synthetic import coloured_noise, make_program, make_special_program, null_case, record
from camsmooth.cli.main import main as cli_main
from camsmooth.diagnosis.engine import diagnose
from camsmooth.diagnosis.recordings import write_program_csv, write_recording_csv
from camsmooth.errors import InputError, InternalError


# ---- 5. a NaN inside a fit is an internal error (exit 70), never bad input (exit 2) ------------------
@pytest.fixture
def lag_files(tmp_path):
    prog = make_program("lines", duration=3.0, rate=200.0, seed=1)
    rec = record(prog, {"Kv_X": 40.0}, channels=("axes",), noise={"axes": 1e-3}, seed=2)
    write_program_csv(tmp_path / "p.csv", prog)
    write_recording_csv(tmp_path / "r.csv", rec)
    return prog, rec, tmp_path


def _argv(d):
    return ["diagnose", "--program", str(d / "p.csv"), "--recording", str(d / "r.csv"), "--out", str(d / "f.json"),
            "--quiet"]


def test_nan_parameters_from_a_fit_are_an_internal_error(lag_files, monkeypatch, capsys):
    """A fit that ends on NaN parameters must stop the run as a bug (exit 70), not be judged (a
    'nan%' verdict) nor reported as bad input."""
    from camsmooth.machine import fitting

    real = fitting.levenberg_marquardt

    def broken(*a, **k):
        res = real(*a, **k)
        res.x = np.full_like(res.x, np.nan)
        return res

    monkeypatch.setattr(fitting, "levenberg_marquardt", broken)
    prog, rec, d = lag_files
    with pytest.raises(InternalError, match="non-finite"):
        diagnose(prog, rec)
    assert cli_main(_argv(d)) == 70
    err = capsys.readouterr().err
    assert "internal error" in err and "bug" in err
    assert not (d / "f.json").exists()


def test_a_model_constructor_refusing_a_computed_value_is_an_internal_error(lag_files, monkeypatch, capsys):
    """The issue's message: 'geometric error EXX must be a finite number, got nan' raised while the
    findings are put together is InputError from the model's constructor - after the inputs were
    read it is a bug: exit 70."""
    from camsmooth.diagnosis.terms.servo_lag import ServoLag
    from camsmooth.machine.model import ErrorModel

    def report(self, names, x, sd):
        ErrorModel(geometric={"EXX": float("nan")})  # what a NaN parameter reaching a model does

    monkeypatch.setattr(ServoLag, "report", report)
    prog, rec, d = lag_files
    with pytest.raises(InternalError) as e:
        diagnose(prog, rec)
    assert not isinstance(e.value, InputError) and "EXX must be a finite number" in str(e.value)
    assert cli_main(_argv(d)) == 70
    assert "internal error" in capsys.readouterr().err


# ---- 1. resolution per channel from the data's own grid --------------------------------------------
def test_a_channel_within_a_hundredth_of_a_mm_keeps_its_own_step():
    """Values within +-0.01 mm written to 4 decimals have step 1e-4 mm (not 10^4 mm: zero is a
    multiple of every power of ten, a value smaller than 10^k is not)."""
    from camsmooth.diagnosis.recordings import quantisation_steps

    rng = np.random.default_rng(0)
    for decimals in (4, 5, 6):
        v = np.round(rng.uniform(-0.0099, 0.0099, 2000), decimals)
        assert np.allclose(quantisation_steps(v), 10.0 ** -decimals), decimals


def test_a_non_decimal_grid_is_found_from_the_data():
    """Encoder counts of 1/2048 mm, written exactly or rounded to 6 decimals: the step is the
    grid's, not the file's decimals; full-precision values have none."""
    from camsmooth.diagnosis.recordings import quantisation_steps

    rng = np.random.default_rng(1)
    counts = np.round(rng.normal(0, 3.0, 5000) * 2048)
    assert np.allclose(quantisation_steps(counts / 2048), 1 / 2048, rtol=1e-6)
    assert np.allclose(quantisation_steps(np.round(counts / 2048, 6)), 1 / 2048, rtol=1e-3)
    small = np.round(rng.uniform(-0.009, 0.009, 2000) * 2048) / 2048
    assert np.allclose(quantisation_steps(small), 1 / 2048, rtol=1e-6)
    assert not np.any(quantisation_steps(np.array([float(f"{x:.10g}") for x in rng.normal(0, 0.003, 2000)])))


def test_a_small_range_channel_keeps_its_weight(tmp_path):
    """Through the CSV reader and prepare: Y_act held at 0 with 3 um noise, written to 4 decimals,
    gets a floor of about its noise, not one of thousands of mm."""
    from camsmooth.diagnosis.problem import prepare
    from camsmooth.diagnosis.recordings import Program, Recording, read_recording_csv

    prog = make_program("lines", duration=4.0, rate=200.0, seed=3)
    prog = Program(t=prog.t, axes={"X": prog.axes["X"], "Y": np.zeros(len(prog.t))}, S=prog.S)
    rng = np.random.default_rng(4)
    rec = Recording(t=prog.t.copy(), channels={"X_act": np.round(prog.axes["X"] + rng.normal(0, 3e-3, len(prog.t)), 4),
                                               "Y_act": np.round(np.clip(rng.normal(0, 3e-3, len(prog.t)),
                                                                         -0.0099, 0.0099), 4)})
    write_recording_csv(tmp_path / "r.csv", rec)
    back = read_recording_csv(tmp_path / "r.csv")
    assert np.allclose(back.quantum["Y_act"], 1e-4)
    P = prepare(prog, back)
    assert P.floor_info["Y_act"]["quantisation_rms"] < 1e-4
    assert P.floor_info["Y_act"]["rms"] < 5e-3


# ---- 2. a term's resolution is judged on the channels it acts on ------------------------------------
def test_an_x_scale_error_is_not_refused_for_the_resolution_of_tip_y():
    """EXX = 3.3 um/mm on a grid program, X_act and tip_x recorded at full precision and tip_y in
    whole micrometres: EXX does not move tip_y, so tip_y's resolution says nothing about it."""
    prog = make_special_program("grid", rate=50.0, seed=1)
    rec = record(prog, {"EXX": 3.3e-3}, channels=("axes", "tip"), noise={"axes": 1e-3, "tip": 1e-3}, seed=5)
    rec.channels["tip_y"] = np.round(rec.channels["tip_y"] / 1e-3) * 1e-3
    rec.quantum["tip_y"] = np.full(len(rec.t), 1e-3)
    f = diagnose(prog, rec).findings
    assert f["named"] == ["linear_positioning"], {r["name"]: r["reason"] for r in f["rejected"]}
    assert f["effects"][0]["parameters"]["EXX"] == pytest.approx(3.3e-3, rel=0.01)


def test_acted_channels_are_the_ones_the_term_moves():
    from camsmooth.diagnosis.problem import prepare
    from camsmooth.diagnosis.terms import term
    from camsmooth.diagnosis.terms.base import acted_channels

    prog = make_special_program("grid", rate=20.0, seed=1, duration=20.0)
    rec = record(prog, {}, channels=("axes", "tip"), noise={"axes": 1e-3, "tip": 1e-3}, seed=5)
    P = prepare(prog, rec)
    assert set(acted_channels(P, term("linear_positioning"), ["EXX"], np.array([1e-3]))) == {"X_act", "tip_x"}


# ---- 3. lag and clock offset told apart by the response shape where the data resolve it -------------
@pytest.mark.parametrize("truth, noise, named", [
    ({"offset_s": 0.005}, 0.02, "time_offset"),  # the offset's effect about 5 noise sigmas RMS
    ({"offset_s": 0.003}, 0.01, "time_offset"),
    ({"Kv_X": 100.0, "Kv_Y": 100.0, "Kv_Z": 100.0}, 0.05, "servo_lag"),
])
def test_lag_and_offset_are_told_apart_when_the_shape_resolves_them(truth, noise, named):
    """500 Hz samples on trapezoidal moves: the rounded corners of a lag and the pure shift of an
    offset differ by a held-out chi-square of hundreds, far beyond its standard error, so the
    better one is named alone - not the library's first as 'cannot tell apart'."""
    prog = make_program("lines", duration=8.0, rate=500.0, seed=2)
    rec = record(prog, truth, channels=("axes",), noise={"axes": noise}, seed=5)
    f = diagnose(prog, rec).findings
    assert f["named"] == [named]
    assert f["equivalences"] == []
    lv = f["lag_vs_offset"]
    assert lv["shape_distinguishes"] is True
    assert abs(lv["shape_chi2_difference"]) > 3 * lv["shape_chi2_se"]


def test_a_warm_start_with_missing_values_starts_those_from_their_initial_guess(lag_files):
    """A warm start read from a model that lacks a parameter (a thermal element it does not hold
    reads tau = NaN) must not carry the NaN into the fit."""
    from camsmooth.diagnosis.problem import Options, prepare
    from camsmooth.diagnosis.selector import Selector

    prog, rec, _ = lag_files
    sel = Selector(prepare(prog, rec), Options())
    n = len(sel.fit(("servo_lag",)).x)
    sel.cache.clear()
    f = sel.fit(("servo_lag",), x0=np.full(n, np.nan))
    assert np.all(np.isfinite(f.x)) and 1 / f.x[0] == pytest.approx(40.0, rel=0.05)


# ---- 6. significance that does not depend on what else is unexplained ---------------------------------
def test_a_clear_reversal_is_named_beside_a_large_unexplained_rest():
    """The issue's ISO 230-2 case: a bidirectional laser run of X with an 18.65 um reversal and a
    pitch error outside the library (0.1 mm at 13 mm and 0.05 mm at 7.3 mm periods) dwarfing it.
    Backlash lowers the held-out RMS by under 1% of that rest - the old fixed margin refused it;
    as an effect on its own (tens of noise floors, one sign in every fold) it is named, and the
    pitch error stays unexplained."""
    prog = make_special_program("laser", rate=50.0, seed=1)
    rec = record(prog, {"backlash_X": 0.01865}, channels=("axes",), noise={"axes": 5e-4}, seed=3)
    x = rec.channels["X_act"]
    rec.channels["X_act"] = x + 0.1 * np.sin(2 * np.pi * x / 13.0) + 0.05 * np.sin(2 * np.pi * x / 7.3 + 1)
    f = diagnose(prog, rec).findings
    assert f["named"] == ["backlash"]
    e = f["effects"][0]
    assert 0.015 < e["parameters"]["backlash_X"] < 0.025
    assert e["verdict"]["heldout_change_pct"] > -2.0  # below the old margin
    assert "whatever else is left unexplained" in e["verdict"]["reason"]
    assert f["effects"][-1]["name"] == "unexplained"


def _vibrating_laser_run(backlash: float, seed: int):
    """The laser run of X with a reversal and, outside the library, a vibration of X in time
    (10 um at 0.37 Hz and 5 um at 1.13 Hz: about 15 noise floors RMS)."""
    prog = make_special_program("laser", rate=50.0, seed=1)
    rec = record(prog, {"backlash_X": backlash}, channels=("axes",), noise={"axes": 5e-4}, seed=seed)
    t = rec.t
    rec.channels["X_act"] = rec.channels["X_act"] + 0.01 * np.sin(2 * np.pi * 0.37 * t) + \
        0.005 * np.sin(2 * np.pi * 1.13 * t + 1)
    return prog, rec


@pytest.mark.parametrize("seed", [3, 4])
def test_a_weak_reversal_beside_a_large_unexplained_rest_is_named(seed):
    """Issue 20 item 2: a 2 um reversal (2 noise floors RMS, below the 3 floors of the earlier
    'effect on its own' path) beside a vibration 8 times its size. It lowers the held-out RMS by
    under 1% of that rest, so the earlier rules (relative margin, 'standalone') refuse it; the
    absolute rule - its size against its long-run uncertainty, one sign in every fold, a held-out
    chi-square fall in floors - names it, within 10%, and leaves the vibration unexplained."""
    from camsmooth.diagnosis.problem import Options

    prog, rec = _vibrating_laser_run(0.002, seed)
    f = diagnose(prog, rec).findings
    assert f["named"] == ["backlash"], {r["name"]: r["reason"] for r in f["rejected"]}
    e = f["effects"][0]
    assert e["parameters"]["backlash_X"] == pytest.approx(0.002, rel=0.10)
    v = e["verdict"]
    assert -2.0 < v["heldout_change_pct"] < 0 and v["rule"] == "absolute"
    assert v["size_sigma"] > 3 and v["effect_floors"] < 3
    assert f["effects"][-1]["name"] == "unexplained"
    old = diagnose(prog, rec, options=Options(rule="standalone")).findings
    assert old["named"] == []
    assert "below the 3 floors" in {r["name"]: r["reason"] for r in old["rejected"]}["backlash"]


@pytest.mark.parametrize("seed", [3, 4])
def test_the_same_rest_without_a_reversal_names_nothing(seed):
    """The null beside the same large rest: nothing named, the vibration unexplained."""
    prog, rec = _vibrating_laser_run(0.0, seed)
    f = diagnose(prog, rec).findings
    assert f["named"] == [] and f["effects"][-1]["name"] == "unexplained"


@pytest.mark.parametrize("kind, rho, seed", [("lines", 0.0, 11), ("laser", 0.0, 12), ("grid", 0.0, 13),
                                             ("lines", 0.95, 14), ("laser", 0.99, 15), ("rotary", 0.9, 16)])
def test_white_and_coloured_nulls_name_nothing(kind, rho, seed):
    """Nulls, white (rho 0) and AR(1)-coloured, on axis and tool-tip channels: nothing named under
    the absolute rule (96 such nulls measured in the report of issue 20 item 2)."""
    prog, rec = null_case(kind, rho, seed)
    assert diagnose(prog, rec).findings["named"] == []


def test_batch_means_standard_error():
    """The long-run standard error of a sum: sqrt(n) sigma for white noise; for AR(1) noise the
    long-run factor sqrt((1 + rho) / (1 - rho)); for a periodic series summed over whole cycles,
    far below what the lag-1 correlation would claim."""
    from camsmooth.diagnosis.significance import batch_sum_sd

    rng = np.random.default_rng(0)
    n = 40_000
    sds = [batch_sum_sd(rng.normal(0, 1, n)) for _ in range(20)]
    assert np.mean(sds) == pytest.approx(np.sqrt(n), rel=0.15)
    ar = [batch_sum_sd(coloured_noise(n, 1.0, 0.9, rng)) for _ in range(20)]
    assert np.mean(ar) == pytest.approx(np.sqrt(n * 1.9 / 0.1), rel=0.25)
    periodic = np.sin(2 * np.pi * np.arange(n) / 400)
    assert batch_sum_sd(periodic) < 0.01 * np.sqrt(n * 1.99 / 0.01)
    assert batch_sum_sd(np.ones(30)) == float("inf")


def test_coloured_noise_is_not_a_reversal():
    """A null recording with strongly coloured (AR(1), rho 0.9 then 0.99) noise on the axes: the
    old rule named a backlash of -1 um (3% of the held-out RMS, BIC -29) whose held-out
    chi-square fall is within 3 standard errors once the autocorrelation is counted."""
    prog = make_program("lines", duration=8.0, rate=250.0, seed=2)
    rec = record(prog, {}, channels=("axes",), noise={}, seed=2)
    rng = np.random.default_rng(2)
    for rho in (0.9, 0.99):
        for c in rec.channels:
            n = len(rec.t)
            rec.channels[c] = rec.channels[c] + coloured_noise(n, 1e-3, rho, rng) + rng.normal(0, 3e-4, n)
    assert diagnose(prog, rec).findings["named"] == []


@pytest.mark.parametrize("kind, seed", [("laser", 4), ("grid", 5), ("lines", 6)])
def test_coloured_noise_nulls_name_nothing(kind, seed):
    """Coloured-noise nulls on axis and tool-tip channels: nothing named (a guard for the rule's
    'effect on its own' path; these pass on the old rule too)."""
    prog = make_special_program(kind, rate=50.0, seed=seed) if kind != "lines" else \
        make_program("lines", duration=8.0, rate=250.0, seed=seed)
    chans = ("tip",) if kind == "grid" else ("axes",)
    rec = record(prog, {}, channels=chans, noise={}, seed=seed)
    rng = np.random.default_rng(seed)
    for c in rec.channels:
        n = len(rec.t)
        rec.channels[c] = rec.channels[c] + coloured_noise(n, 1e-3, 0.95, rng) + rng.normal(0, 3e-4, n)
    assert diagnose(prog, rec).findings["named"] == []


# ---- 4. an effect outside the library is left unexplained and located ------------------------------------
@pytest.mark.parametrize("seed", [7, 8])
def test_a_sag_outside_the_library_is_not_named_a_rotary_location_error(seed):
    """A Z sag of the tool tip growing with X and with the A tilt (tip_z -= 10 um (1 + X / 5 mm)
    sin A) is in no term. Rotary location takes the sin A part on tip_z but, as an axis-line offset,
    also moves tip_y by (1 - cos A), which the data do not show: its held-out residual on tip_y gets
    clearly worse. Nothing is named; the rest is unexplained and located on tip_z."""
    from benchmarks.synthetic import concealed_cases, program_for

    case = next(c for c in concealed_cases((1,)) if c.label == "rotary location")
    prog = program_for(case)
    rec = record(prog, {}, channels=("axes", "tip", "axis"),
                 noise={"axes": 1e-3, "tip": 1e-3, "rotary": 1e-6, "axis": 1e-6}, seed=seed)
    X, A = prog.axes["X"], prog.axes["A"]
    rec.channels["tip_z"] = rec.channels["tip_z"] - 0.01 * (1 + 2 * X / 10.0) * np.sin(A)
    f = diagnose(prog, rec).findings
    assert f["named"] == []
    assert f["effects"][-1]["name"] == "unexplained" and f["effects"][-1]["channels"] == ["tip_z"]
    assert "tip_z" in f["intervals"][0]["channels"]
    assert "worse on tip_y" in {r["name"]: r["reason"] for r in f["rejected"]}["rotary_location"]


# ---- 7. the harder catalogue -----------------------------------------------------------------------
def test_a_three_effect_mixture_is_named_without_going_round_in_circles():
    """Positioning + squareness + backlash on the tip (benchmarks/hard_cases.py, seed 2): all three
    named, in a few seconds - the selection stops when it comes back to a set it held before
    (a guard: correlated terms once traded places for ever). Passes on the old code as well."""
    import time

    from benchmarks.hard_cases import hard_cases, run_hard_case

    h = next(h for h in hard_cases((2,)) if h.label.startswith("mix: positioning"))
    t0 = time.perf_counter()
    r = run_hard_case(h, diagnose)
    assert sorted(r["named"]) == ["backlash", "linear_positioning", "linear_squareness"] and not r["bad"]
    assert time.perf_counter() - t0 < 60


def test_a_weak_scale_error_keeps_no_spurious_pitch_terms():
    """A 3.3 um/mm scale error of X at 3 noise sigmas on a laser run (benchmarks/hard_cases.py):
    EXX alone, within 2% - the fold-consistency path that rescues a main parameter does not keep
    higher-order (pitch) parts the covariance does not resolve. Passes on the old code as well."""
    from benchmarks.hard_cases import hard_cases, run_hard_case

    h = next(h for h in hard_cases((1,)) if h.label == "weak: positioning at 3 sigma")
    r = run_hard_case(h, diagnose)
    assert r["named"] == ["linear_positioning"] and r["errors"]["EXX"] < 0.02


def test_a_lag_refused_for_another_channel_gets_its_pruned_exact_fit():
    """A lagging B and a displaced A axis, B_act recorded without noise beside noisy X Y Z and tip
    channels: fitted first, the lag gives Z a small lag that takes up part of the A axis' tip
    structure and makes Z_act worse, so its screening verdict refuses it. Its exact fit, with the
    axes it cannot measure held, is judged again and named; then the displaced axis."""
    prog = make_program("rotary", duration=12.0, rate=50.0, seed=1)
    rec = record(prog, {"Kv_B": 40.0, "EY0A": 0.03}, channels=("axes", "tip"), noise={"axes": 5e-4, "tip": 5e-4},
                 seed=3)
    f = diagnose(prog, rec).findings
    assert set(f["named"]) == {"servo_lag", "rotary_location"}, {r["name"]: r["reason"] for r in f["rejected"]}
    eff = {e["name"]: e["parameters"] for e in f["effects"]}
    assert eff["servo_lag"]["Kv_B"] == pytest.approx(40.0, rel=0.02)
    assert eff["rotary_location"]["EY0A"] == pytest.approx(0.03, rel=0.05)
