"""`camsmooth diagnose --trace` and `--points` (camsmooth.diagnosis.trace, .points): every new
term named with its value within 10% on a trace whose truth is a closed form written here (not
camsmooth's simulator), nothing new named on nulls, the setup and the linear-axis terms of a
drilled pattern recovered, bad inputs refused with one message and exit status 2."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from camsmooth.cli.main import main
from camsmooth.diagnosis.points import diagnose_points, read_points
from camsmooth.diagnosis.trace import diagnose_trace, read_trace

NEW = {"servo_second_order", "velocity_limit", "acceleration_limit", "thermal_temperature", "backlash_load",
       "thermal_time", "quantisation", "transport_delay"}
Q = 0.003  # mm, the scale step of the quantisation cases
DT = 0.002
NOISE = 1e-3  # mm


# ---- closed forms -------------------------------------------------------------------------------
def moves() -> tuple[np.ndarray, np.ndarray]:
    """Knots (s, mm) of a piecewise-linear command: moves at about 20, 50 and 80 mm/s with dwells,
    every knot on the sample grid (a corner between samples is not what the log states)."""
    T, P, pos = [0.0], [0.0], 0.0
    for i in range(6):
        v = (20.0, 50.0, 80.0)[i % 3]
        tgt = (10.0 if i % 2 == 0 else 0.0) + (0.5 * i if i % 4 == 0 else 0.0)
        T += [T[-1] + 0.4, T[-1] + 0.4 + round(abs(tgt - pos) / v, 2)]
        P += [pos, tgt]
        pos = tgt
    T.append(T[-1] + 0.4)
    P.append(pos)
    return np.array(T), np.array(P)


def superpose(t: np.ndarray, T: np.ndarray, P: np.ndarray, ramp) -> np.ndarray:
    """Response of a linear system to the piecewise-linear command: sum over the knots of the
    change of slope times the system's response to a unit ramp starting there."""
    ds = np.diff(np.r_[0.0, np.diff(P) / np.diff(T), 0.0])
    y = np.full_like(t, P[0])
    for Tk, d in zip(T, ds, strict=True):
        y += d * ramp(np.maximum(t - Tk, 0.0))
    return y


def ramp_first_order(tau: float):
    return lambda x: x - tau * (1.0 - np.exp(-x / tau))


def ramp_second_order(wn: float, z: float):
    wd = wn * np.sqrt(1.0 - z * z)
    return lambda x: (x - 2 * z / wn + np.exp(-z * wn * x) * ((2 * z / wn) * np.cos(wd * x)
                                                             + ((2 * z * z - 1) / wd) * np.sin(wd * x)))


def write_csv(path, t: np.ndarray, cols: dict[str, np.ndarray]) -> str:
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t", *cols])
        for i in range(len(t)):
            w.writerow([repr(float(t[i]))] + [repr(float(c[i])) for c in cols.values()])
    return str(path)


def motion_trace(tmp_path, case: str, seed: int = 0):
    """A one-axis trace of the moves above, X_act from the closed form of ``case`` plus white noise."""
    rng = np.random.default_rng(seed)
    T, P = moves()
    t = np.arange(0.0, T[-1] + DT / 2, DT)
    u = np.interp(t, T, P)
    extra = {}
    if case == "white":
        y = u.copy()
    elif case == "coloured":
        e = np.convolve(np.cumsum(rng.normal(size=len(t))), np.ones(25) / 25, "same")
        y = u + 3 * NOISE * (e - e.mean()) / e.std()
    elif case in ("lag", "lag_ar1"):
        y = superpose(t, T, P, ramp_first_order(1 / 40.0))
        if case == "lag_ar1":  # plus AR(1) noise, rho 0.99, 5 um stationary sd
            e = np.zeros(len(t))
            for i in range(1, len(t)):
                e[i] = 0.99 * e[i - 1] + rng.normal(0.0, 5 * NOISE * np.sqrt(1 - 0.99 ** 2))
            y = y + e
    elif case == "pitch":  # outside the library: a lead-screw error of 10 um with a 5 mm period
        y = u + 0.010 * np.sin(2 * np.pi * u / 5.0)
    elif case == "second_order_delay":  # the ringing servo behind a 12 ms transport delay
        y = superpose(t - 0.012, T, P, ramp_second_order(120.0, 0.3))
    elif case == "second_order":
        y = superpose(t, T, P, ramp_second_order(120.0, 0.3))
    elif case == "velocity_limit":
        vmax, y = 35.0, u.copy()
        for k in range(1, len(T) - 1, 2):  # the move from knot k to k + 1, until the next one starts
            A, B = P[k], P[k + 1]
            m = (t >= T[k]) & (t < (T[k + 2] if k + 2 < len(T) else np.inf))
            y[m] = A + np.sign(B - A) * np.minimum(np.abs(u[m] - A), vmax * (t[m] - T[k]))
    elif case == "acceleration_limit":
        # each step dv of the commanded velocity is taken at amax: a parabola, then the line
        amax = 2000.0
        dv = np.diff(np.r_[0.0, np.diff(P) / np.diff(T), 0.0])
        y = np.full_like(t, P[0])
        for Tk, d in zip(T, dv, strict=True):
            D = abs(d) / amax
            x = np.maximum(t - Tk, 0.0)
            y += d * (np.where(x < D, x * x / (2 * D), x - D / 2) if D > 0 else x)
    elif case == "delay":  # a pure transport delay of 12 ms
        y = np.interp(t - 0.012, T, P)
    elif case in ("staircase", "staircase_lag", "rounded_noise"):
        # the measured channel rounded to a 3 um scale, written as the scale's counts times Q; the
        # noise is before the rounding: 0.15 um (the steps fall where the position puts them) or,
        # for the null, 3 um (a logger's last digit under noise: where each step falls is hidden)
        y = superpose(t, T, P, ramp_first_order(1 / 40.0)) if case == "staircase_lag" else u
        sd = Q if case == "rounded_noise" else 0.05 * Q
        counts = np.round((y + rng.normal(0.0, sd, len(t))) / Q)
        return write_csv(tmp_path / f"{case}.csv", t, {"X_cmd": u, "X_act": counts * Q})
    elif case == "backlash_load":
        load = np.sin(2 * np.pi * t / 0.7 + 0.3)
        y = u - 0.5 * 0.02 * np.sign(load)
        extra["X_load"] = load
    else:
        raise ValueError(case)
    y = y + rng.normal(0.0, NOISE, len(t))
    return write_csv(tmp_path / f"{case}.csv", t, {"X_cmd": u, "X_act": y, **extra})


def thermal_trace(tmp_path, null: bool = False, seed: int = 1, clock: bool = False):
    """An axis held at 0 for 8 h beside four temperatures; the spindle heats for 4 h then cools.
    Growth = 0.012 mm/degC times the spindle temperature through a 600 s first-order lag (closed
    form of a lag driven by 1 - exp(-t / 1800)), or, for the null, a random walk."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 8 * 3600.0, 20.0)
    th, tl, t1, A = 1800.0, 600.0, 4 * 3600.0, 8.0

    def lagged(x):
        x = np.maximum(x, 0.0)
        return 1.0 - (th * np.exp(-x / th) - tl * np.exp(-x / tl)) / (th - tl)

    on = t > t1
    T1 = A * (1 - np.exp(-t / th)) - A * np.where(on, 1 - np.exp(-(t - t1) / th), 0.0)
    L1 = A * lagged(t) - A * np.where(on, lagged(t - t1), 0.0)
    if clock:  # growth that follows time alone: 0.05 mm with a 3000 s time constant, no cool-down
        y = 0.05 * (1 - np.exp(-t / 3000.0))
    elif null:
        e = np.cumsum(rng.normal(size=len(t)))
        y = 0.002 * (e - e.mean()) / e.std()
    else:
        y = 0.012 * L1
    y = y + rng.normal(0.0, NOISE, len(t))
    temps = {"temp_spindle": 20 + T1, "temp_ambient": 20 + np.sin(2 * np.pi * t / 10800),
             "temp_column": 20 + 3 * (1 - np.exp(-t / 5000)),
             "temp_bed": 20 + 0.01 * np.cumsum(rng.normal(size=len(t)))}
    return write_csv(tmp_path / f"thermal{'_null' if null else ''}.csv", t,
                     {"Z_cmd": np.zeros_like(t), "Z_act": y, **temps})


def effect(f: dict, name: str) -> dict:
    return next(e for e in f["effects"] if e["name"] == name)


# ---- every new term named with its value ---------------------------------------------------------
@pytest.mark.parametrize("case, key, truth", [
    ("second_order", "wn_X", 120.0), ("velocity_limit", "vmax_X", 35.0),
    ("acceleration_limit", "amax_X", 2000.0), ("backlash_load", "backlash_load_X", 0.02)])
def test_a_new_term_is_named_with_its_value(tmp_path, case, key, truth):
    f = diagnose_trace(read_trace(motion_trace(tmp_path, case))).findings
    name = "servo_second_order" if case == "second_order" else case
    assert set(f["named"]) & NEW == {name}, f["named"]
    e = effect(f, name)
    assert e["parameters"][key] == pytest.approx(truth, rel=0.10)
    if case == "second_order":
        assert e["parameters"]["zeta_X"] == pytest.approx(0.3, rel=0.10)
    assert e["heldout_rms_after"]["X_act"] < 0.5 * e["heldout_rms_before"]["X_act"]


def test_a_pure_delay_is_told_apart_from_a_lag(tmp_path):
    f = diagnose_trace(read_trace(motion_trace(tmp_path, "delay"))).findings
    assert f["named"] == ["time_offset"], f["named"]
    assert effect(f, "time_offset")["parameters"]["offset_s"] == pytest.approx(0.012, rel=0.10)


def two_axis_trace(tmp_path, x_case: str, y_delay: float, seed: int = 8) -> str:
    """X: the moves above, its actual the command (``white``) or its first-order lag (``lag``, Kv 40);
    Y: the same moves at 0.7 scale 0.3 s later, its actual the command delayed by y_delay s; 1 um noise."""
    rng = np.random.default_rng(seed)
    T, P = moves()
    t = np.arange(0.0, T[-1] + DT / 2, DT)
    u = np.interp(t, T, P)
    x = {"white": u, "lag": superpose(t, T, P, ramp_first_order(1 / 40.0)),
         "same_delay": np.interp(t - y_delay, T, P)}[x_case]
    v = np.interp(t, T + 0.3, 0.7 * P)
    y = np.interp(t - y_delay, T + 0.3, 0.7 * P)
    n = len(t)
    cols = {"X_cmd": u, "X_act": x + rng.normal(0, NOISE, n), "Y_cmd": v, "Y_act": y + rng.normal(0, NOISE, n)}
    return write_csv(tmp_path / f"two_{x_case}_{y_delay}.csv", t, cols)


@pytest.mark.parametrize("x_case, want", [("white", ["transport_delay"]),
                                          ("lag", ["servo_lag", "transport_delay"]),
                                          ("same_delay", ["time_offset"])])
def test_one_axis_delay_is_a_transport_delay(tmp_path, x_case, want):
    """A 12 ms delay on Y alone is Y's transport delay (beside X's lag, told apart by the shape); the
    same delay on both axes is the clock offset."""
    f = diagnose_trace(read_trace(two_axis_trace(tmp_path, x_case, 0.012))).findings
    assert sorted(f["named"]) == want, f["named"]
    if x_case == "same_delay":
        assert effect(f, "time_offset")["parameters"]["offset_s"] == pytest.approx(0.012, rel=0.10)
        return
    p = effect(f, "transport_delay")["parameters"]
    assert set(p) == {"delay_Y"} and p["delay_Y"] == pytest.approx(0.012, rel=0.10)
    if x_case == "lag":
        assert set(effect(f, "servo_lag")["parameters"]) == {"Kv_X"}
        assert effect(f, "servo_lag")["parameters"]["Kv_X"] == pytest.approx(40.0, rel=0.10)


def test_two_axes_without_a_delay_name_none(tmp_path):
    f = diagnose_trace(read_trace(two_axis_trace(tmp_path, "white", 0.0))).findings
    assert f["named"] == [], f["named"]


def test_a_ringing_servo_behind_a_delay_is_named_as_both(tmp_path):
    f = diagnose_trace(read_trace(motion_trace(tmp_path, "second_order_delay"))).findings
    assert sorted(f["named"]) == ["servo_second_order", "time_offset"], f["named"]
    assert effect(f, "time_offset")["parameters"]["offset_s"] == pytest.approx(0.012, rel=0.10)
    assert effect(f, "servo_second_order")["parameters"]["wn_X"] == pytest.approx(120.0, rel=0.10)


def test_a_servo_loop_that_saturates_is_named_as_lag_and_velocity_limit(tmp_path):
    """A first-order loop whose velocity Kv (u - y) is clipped to vmax (Kv 40 1/s, vmax 35 mm/s),
    integrated here by explicit Euler at 10 us (not camsmooth's discretisation) and logged at 2 ms."""
    T, P = moves()
    h, step = 1e-5, 200
    uf = np.interp(np.arange(0.0, T[-1], h), T, P).tolist()
    y, yk = [], 0.0
    for k, uk in enumerate(uf):
        yk += h * min(35.0, max(-35.0, 40.0 * (uk - yk)))
        if k % step == 0:
            y.append(yk)
    t = np.arange(len(y)) * h * step
    act = np.array(y) + np.random.default_rng(4).normal(0, NOISE, len(y))
    f = diagnose_trace(read_trace(write_csv(tmp_path / "sat.csv", t, {"X_cmd": np.interp(t, T, P), "X_act": act})))
    f = f.findings
    assert sorted(f["named"]) == ["servo_lag", "velocity_limit"], f["named"]
    assert effect(f, "servo_lag")["parameters"]["Kv_X"] == pytest.approx(40.0, rel=0.10)
    assert effect(f, "velocity_limit")["parameters"]["vmax_X"] == pytest.approx(35.0, rel=0.10)


def test_growth_that_follows_a_temperature_is_named_on_that_channel(tmp_path):
    f = diagnose_trace(read_trace(thermal_trace(tmp_path))).findings
    assert f["named"] == ["thermal_temperature"]
    p = effect(f, "thermal_temperature")["parameters"]
    assert set(p) == {"gain_spindle", "tau_spindle"}
    assert p["gain_spindle"] == pytest.approx(0.012, rel=0.10)
    assert p["tau_spindle"] == pytest.approx(600.0, rel=0.10)


# ---- nulls ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("case", ["white", "coloured", "lag", "lag_ar1", "pitch"])
def test_nothing_new_is_named_on_a_null(tmp_path, case):
    """White and coloured noise, a clean first-order servo (alone and under AR(1) noise of rho
    0.99), a lead-screw error outside the library: no new term."""
    f = diagnose_trace(read_trace(motion_trace(tmp_path, case, seed=5))).findings
    assert not set(f["named"]) & NEW, f["named"]
    if case.startswith("lag"):  # a first-order servo: its lag, and only that
        assert f["named"] == ["servo_lag"]
        assert effect(f, "servo_lag")["parameters"]["Kv_X"] == pytest.approx(40.0, rel=0.10)
    else:
        assert f["named"] == []
    if case == "pitch":  # left unexplained, and located
        assert f["unexplained"]["count"] > 0


# ---- quantisation of the measured channel ------------------------------------------------------------
def test_a_staircase_is_named_as_quantisation_with_its_step(tmp_path):
    """X_act = Q round(X_cmd / Q) (noise 0.05 Q before the rounding): the step within 10% and the
    whole staircase (share 1)."""
    f = diagnose_trace(read_trace(motion_trace(tmp_path, "staircase"))).findings
    assert f["named"] == ["quantisation"], f["named"]
    e = effect(f, "quantisation")
    assert e["parameters"]["q_X"] == pytest.approx(Q, rel=0.10)
    assert e["parameters"]["share_X"] == pytest.approx(1.0, rel=0.10)
    assert e["units"]["q_X"] == "mm" and "steps of 0.003 mm" in e["sentence"]
    assert e["heldout_rms_after"]["X_act"] < 0.5 * e["heldout_rms_before"]["X_act"]


def test_a_staircase_behind_a_lag_is_named_as_both(tmp_path):
    f = diagnose_trace(read_trace(motion_trace(tmp_path, "staircase_lag"))).findings
    assert sorted(f["named"]) == ["quantisation", "servo_lag"], f["named"]
    assert effect(f, "servo_lag")["parameters"]["Kv_X"] == pytest.approx(40.0, rel=0.10)
    assert effect(f, "quantisation")["parameters"]["q_X"] == pytest.approx(Q, rel=0.10)


def test_rounding_that_noise_hides_is_not_named(tmp_path):
    """The channel lies on the grid, but 1 step of noise before the rounding hides where each step
    falls: the staircase is not a deterministic effect and nothing is named."""
    f = diagnose_trace(read_trace(motion_trace(tmp_path, "rounded_noise"))).findings
    assert f["named"] == [], f["named"]


@pytest.mark.parametrize("case", ["white", "coloured", "lag"])
def test_a_logger_that_rounds_noisy_data_is_not_quantisation(tmp_path, case):
    """The nulls with X_act written to 3 decimals (1 um, the noise's size): the channel lies on a
    grid, the term is tried, and nothing new is named (the lag stays the lag)."""
    path = motion_trace(tmp_path, case, seed=6)
    d = np.loadtxt(path, delimiter=",", skiprows=1)
    path = write_csv(tmp_path / f"{case}_3dp.csv", d[:, 0], {"X_cmd": d[:, 1], "X_act": np.round(d[:, 2], 3)})
    f = diagnose_trace(read_trace(path)).findings
    assert "quantisation" not in {r["name"] for r in f["rejected"] if "not applicable" in r["reason"]}
    assert f["named"] == (["servo_lag"] if case == "lag" else []), f["named"]


def test_growth_that_follows_time_is_not_put_down_to_a_temperature(tmp_path):
    f = diagnose_trace(read_trace(thermal_trace(tmp_path, clock=True))).findings
    assert f["named"] == ["thermal_time"], f["named"]
    p = effect(f, "thermal_time")["parameters"]
    assert p["gain_time"] == pytest.approx(0.05, rel=0.10) and p["tau_time"] == pytest.approx(3000.0, rel=0.10)


def test_a_random_walk_beside_temperatures_is_not_growth(tmp_path):
    assert diagnose_trace(read_trace(thermal_trace(tmp_path, null=True))).findings["named"] == []


def test_irregular_sampling_with_a_gap_keeps_the_lag(tmp_path):
    rng = np.random.default_rng(7)
    T, P = moves()
    t = np.sort(rng.uniform(0.0, T[-1], 2000))
    t = t[(t < 1.0) | (t > 1.25)]  # a 0.25 s gap in a dwell: the simulation restarts at rest after it
    u = np.interp(t, T, P)
    y = superpose(t, T, P, ramp_first_order(1 / 40.0)) + rng.normal(0, NOISE, len(t))
    tr = read_trace(write_csv(tmp_path / "irr.csv", t, {"X_cmd": u, "X_act": y}))
    assert tr.describe()["irregular"] and tr.gaps >= 1
    f = diagnose_trace(tr).findings
    assert f["named"] == ["servo_lag"]
    assert effect(f, "servo_lag")["parameters"]["Kv_X"] == pytest.approx(40.0, rel=0.10)


# ---- a real recording ------------------------------------------------------------------------------
def test_a_real_mill_trace_names_its_lag_as_the_data_show_it():
    """University of Michigan CNC mill, experiment 01 (CC0; tests/data/traces/SOURCES.md), in the
    trace layout: the lag fitted by the trace diagnosis against a regression written here (the
    following error cmd - act on the commanded velocity: steady lag v / Kv)."""
    from pathlib import Path

    path = Path(__file__).parent / "data" / "traces" / "umich_exp01_trace.csv"
    tr = read_trace(str(path))
    d = tr.describe()
    assert d["axes"] == ["X", "Y", "Z"] and d["samples"] == 1055 and d["rate_hz"] == pytest.approx(10.0)
    assert d["optional"]["X"] == ["current", "vel_act", "vel_cmd"] and d["optional"]["Z"] == ["vel_cmd"]
    f = diagnose_trace(tr).findings
    assert f["named"] == ["servo_lag"]  # 10 Hz cannot show ringing, a delay or a limit apart from it
    kv = effect(f, "servo_lag")["parameters"]
    for a in ("Y", "Z"):
        v = np.gradient(tr.cmd[a], tr.t)
        kv_regression = float(np.sum(v * v) / np.sum((tr.cmd[a] - tr.act[a]) * v))
        assert kv[f"Kv_{a}"] == pytest.approx(kv_regression, rel=0.15)
    h = f["heldout"]
    assert all(h["rms_after"][c] < h["rms_before"][c] for c in ("Y_act", "Z_act"))


# ---- command line ----------------------------------------------------------------------------------
def test_a_plain_log_read_through_a_column_map(tmp_path, capsys):
    T, P = moves()
    t = np.arange(0.0, T[-1], DT)
    u = np.interp(t, T, P)
    y = superpose(t, T, P, ramp_first_order(1 / 40.0)) + np.random.default_rng(3).normal(0, NOISE, len(t))
    log = tmp_path / "scope.txt"  # a blank-separated log without a header: sample, time, cmd, act
    log.write_text("".join(f"{i} {float(t[i])!r} {float(u[i])!r} {float(y[i])!r}\n" for i in range(len(t))))
    out = tmp_path / "f.json"
    # halsampler -t style: the first field counts samples; --sample-period makes it seconds
    assert main(["diagnose", "--trace", str(log), "--columns", "t=1,X_cmd=3,X_act=4", "--sample-period", "0.002",
                 "--out", str(out), "--report", str(tmp_path / "rep")]) == 0
    text = capsys.readouterr().out
    assert f"axes X; {len(t)} samples at 500 Hz" in text and "units mm" in text
    f = json.loads(out.read_text())
    assert f["named"] == ["servo_lag"] and f["input"]["samples"] == len(t)
    assert f["input"]["span_s"] == pytest.approx(t[-1] - t[0])
    assert (tmp_path / "rep" / "report.html").exists() and (tmp_path / "rep" / "trace_X.png").exists()


@pytest.mark.parametrize("body, where", [
    ("t,X_cmd,Y_cmd,Y_act\n0,0,0,0\n1,1,1,1\n2,2,2,2\n", ["row 0", "column 'X_act'"]),
    ("t,X_cmd,X_act\n0,0,0\n1,1,nan\n2,2,2\n", ["row 2", "column 'X_act'"]),
    ("t,X_cmd,X_act\n0,0,0\n1,1,1\n0.5,2,2\n3,3,3\n", ["row 3", "column 't'", "does not increase"]),
])
def test_bad_traces_give_one_message_and_exit_2(tmp_path, capsys, body, where):
    p = tmp_path / "bad.csv"
    p.write_text(body)
    out = tmp_path / "f.json"
    assert main(["diagnose", "--trace", str(p), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert str(p) in err and all(w in err for w in where), err
    assert not out.exists()


@pytest.mark.parametrize("body, where", [
    ("x_nom,y_nom,x_meas\n0,0,0\n1,0,1\n0,1,0\n1,1,1\n", ["row 0", "column 'y_meas'"]),
    ("x_nom,y_nom,x_meas,y_meas\n0,0,0,0\n1,0,1,0\n0,1,0,1\n1,1,1,inf\n", ["row 4", "column 'y_meas'"]),
])
def test_bad_points_give_one_message_and_exit_2(tmp_path, capsys, body, where):
    p = tmp_path / "bad.csv"
    p.write_text(body)
    assert main(["diagnose", "--points", str(p), "--out", str(tmp_path / "f.json")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    assert str(p) in err and all(w in err for w in where), err
    assert not (tmp_path / "f.json").exists()


def test_degrees_and_a_candidate_list_that_fits_no_trace(tmp_path, capsys):
    path = motion_trace(tmp_path, "velocity_limit")
    out = tmp_path / "f.json"
    assert main(["diagnose", "--trace", path, "--units", "deg", "--candidates", "velocity_limit", "--out",
                 str(out)]) == 0
    assert "units deg" in capsys.readouterr().out
    e = effect(json.loads(out.read_text()), "velocity_limit")
    assert e["units"] == {"vmax_X": "deg/s"} and "deg/s" in e["sentence"]
    assert main(["diagnose", "--trace", path, "--candidates", "rotary_location", "--out", str(out)]) == 2
    assert "applies to a trace" in capsys.readouterr().err


# ---- points --------------------------------------------------------------------------------------
def pattern(tmp_path, sx=150e-6, sy=-80e-6, k=120e-6, seed=3) -> str:
    """A 7 x 5 hole pattern (200 x 120 mm) measured on a machine with these scale and squareness
    errors, set up 0.3 / -0.2 mm off and turned by 0.05 deg; 1 um noise."""
    rng = np.random.default_rng(seed)
    gx, gy = np.meshgrid(np.linspace(-100, 100, 7), np.linspace(-60, 60, 5))
    x, y = gx.ravel(), gy.ravel()
    th = np.radians(0.05)
    u, v = (1 + sx) * x + k * y, (1 + sy) * y
    xm = np.cos(th) * u - np.sin(th) * v + 0.3 + rng.normal(0, 0.001, len(x))
    ym = np.sin(th) * u + np.cos(th) * v - 0.2 + rng.normal(0, 0.001, len(x))
    p = tmp_path / "holes.csv"
    with open(p, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["hole", "x_nom", "y_nom", "x_meas", "y_meas"])
        for i in range(len(x)):
            w.writerow([f"H{i}", x[i], y[i], xm[i], ym[i]])
    return str(p)


def test_points_recover_setup_scale_and_squareness(tmp_path, capsys):
    out = tmp_path / "f.json"
    assert main(["diagnose", "--points", pattern(tmp_path), "--out", str(out)]) == 0
    assert "35 points" in capsys.readouterr().out
    f = json.loads(out.read_text())
    s = f["setup"]
    assert s["offset_x_mm"] == pytest.approx(0.3, abs=0.002) and s["offset_y_mm"] == pytest.approx(-0.2, abs=0.002)
    assert s["rotation_deg"] == pytest.approx(0.05, abs=0.002)
    assert set(f["named"]) == {"linear_positioning", "linear_squareness"}
    pos, sq = effect(f, "linear_positioning"), effect(f, "linear_squareness")
    for key, truth in (("scale_x_ppm", 150.0), ("scale_y_ppm", -80.0)):
        assert abs(pos["parameters"][key] - truth) < max(0.1 * abs(truth), 3 * pos["uncertainties"][key])
    k, sd = sq["parameters"]["squareness_xy_urad"], sq["uncertainties"]["squareness_xy_urad"]
    assert abs(k - 120.0) < max(12.0, 3 * sd)
    assert f["residual_rms_mm"] < 0.002 and f["heldout"]["rms_final_mm"] < f["heldout"]["rms_setup_only_mm"]


def test_points_of_a_true_machine_name_only_the_setup(tmp_path):
    f = diagnose_points(read_points(pattern(tmp_path, 0.0, 0.0, 0.0, seed=11)))
    assert f["named"] == [] and f["setup"]["rotation_deg"] == pytest.approx(0.05, abs=0.002)
    few = tmp_path / "four.csv"  # four holes: the setup alone, each hole predicted from the other three
    lines = open(pattern(tmp_path, seed=12)).read().splitlines()
    few.write_text("\n".join([lines[0], lines[1], lines[7], lines[29], lines[35]]) + "\n")
    f = diagnose_points(read_points(str(few)))
    assert f["named"] == [] and f["setup"]["offset_x_mm"] == pytest.approx(0.3, abs=0.01)
    assert f["heldout"]["scheme"].startswith("each point")
