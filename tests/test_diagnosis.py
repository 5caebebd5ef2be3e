"""camsmooth diagnose: exact responses, noise floor, locate, the Michigan recordings, concealed
effects in recordings made by closed forms independent of the library's simulator
(benchmarks/synthetic.py; the full sweep is benchmarks/bench_concealed.py), the CLI and the model
update."""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
from conftest import UMICH, needs_umich  # noqa: E402
from scipy.integrate import solve_ivp

from benchmarks.synthetic import concealed_cases, make_program, run_case
from camsmooth.cli.main import main as cli_main
from camsmooth.diagnosis.engine import (
    Knots,
    Physics,
    Simulator,
    add_simulate_recording_arguments,
    diagnose,
    load_model,
    locate_intervals,
    model_json,
    noise_floor,
    physics_from_model,
    physics_from_settings,
    simulate_recording,
    simulate_recording_cli,
    validate,
)
from camsmooth.diagnosis.recordings import (
    Program,
    read_recording_csv,
    read_umich,
    write_program_csv,
    write_recording_csv,
)
from camsmooth.errors import InputError
from camsmooth.machine.kinematics import load_machine
from camsmooth.machine.model import ErrorModel


# ---- exact responses -------------------------------------------------------------------------
def _ode_lag(t_knots, u_knots, tau, t_eval):
    """Independent reference: integrate dy/dt = (u - y)/tau for the piecewise-linear u."""
    def rhs(t, y):
        return [(np.interp(t, t_knots, u_knots) - y[0]) / tau]

    sol = solve_ivp(rhs, (t_knots[0], t_eval[-1]), [u_knots[0]], t_eval=t_eval, rtol=1e-10, atol=1e-12,
                    max_step=(t_knots[1] - t_knots[0]) / 4)
    return sol.y[0]


@pytest.mark.parametrize("uniform", [True, False])
def test_servo_lag_is_exact_for_piecewise_linear_command(uniform):
    rng = np.random.default_rng(1)
    n = 60
    t = np.arange(n) * 0.01 if uniform else np.cumsum(np.r_[0.0, rng.uniform(0.005, 0.015, n - 1)])
    u = np.cumsum(rng.normal(0, 0.2, n))
    p = Program(t=t, axes={"X": u})
    te = np.sort(rng.uniform(t[0], t[-1], 200))
    sim = Simulator(p, load_machine(None), te, np.zeros(len(te), int), ["X_act"])
    tau = 0.02
    got = sim.run(Physics(tau={"X": tau}))[:, 0]
    ref = _ode_lag(t, u, tau, te)
    assert np.max(np.abs(got - ref)) < 1e-6


def test_steady_lag_is_v_over_kv():
    t = np.linspace(0, 2, 2001)
    v = 30.0
    p = Program(t=t, axes={"Y": v * t})
    kv = 50.0
    sim = Simulator(p, load_machine(None), t, np.zeros(len(t), int), ["Y_act"])
    y = sim.run(physics_from_settings({"Kv_Y": kv}))[:, 0]
    assert abs((v * t[-1] - y[-1]) - v / kv) < 1e-9


def test_segments_restart_at_rest():
    t = np.arange(20) * 0.1
    seg = np.r_[np.zeros(10, int), np.ones(10, int)]
    u = np.r_[np.linspace(0, 9, 10), np.full(10, 100.0)]
    p = Program(t=t, axes={"X": u}, segment=seg)
    sim = Simulator(p, load_machine(None), t, seg, ["X_act"])
    y = sim.run(physics_from_settings({"Kv_X": 20}))[:, 0]
    assert np.allclose(y[10:], 100.0)  # no lag carried across the break


def test_tip_and_thermal_match_the_error_model():
    """Geometric and thermal terms through the simulator agree with ErrorModel.predict (constant
    spindle speed, where the piecewise-constant and piecewise-linear spindle inputs coincide)."""
    prog = make_program("rotary", duration=4.0, rate=100.0, seed=2, spindle=6000.0)
    geo = {"EY0A": 0.02, "EB0A": 1e-4, "EZ0B": 0.01, "EC0B": -5e-5, "EA0S": 8e-5, "EZ0T": 0.03}
    th = {"dz": {"gain": 0.01, "tau": 2.0}, "exz": {"gain": 1e-4, "tau": 1.5}, "my": {"gain": 0.003, "tau": 1.0}}
    ph = Physics(geometric=geo, thermal=th)
    rec = simulate_recording(prog, physics=ph, channels=["tip", "axis"])
    em = ErrorModel(geometric=geo, thermal=th)
    a = prog.axes
    pred = em.predict(load_machine(None), a["A"], a["B"], a["X"], a["Y"], a["Z"], t=prog.t, spindle_rpm=6000.0)
    tip = np.column_stack([rec.channels[c] for c in ("tip_x", "tip_y", "tip_z")])
    ax = np.column_stack([rec.channels[c] for c in ("axis_i", "axis_j", "axis_k")])
    assert np.max(np.abs(tip - pred.tip)) < 1e-9
    assert np.max(np.abs(ax - pred.axis)) < 1e-12


def test_runout_turns_once_per_revolution():
    t = np.arange(0, 0.1, 1e-4)
    p = Program(t=t, axes={"X": np.zeros_like(t)}, S=np.full(len(t), 600.0))  # 10 rev/s
    rec = simulate_recording(p, physics=physics_from_settings({"runout_radius": 0.01, "runout_phase_deg": 90}),
                             channels=["tip"])
    dx = rec.channels["tip_x"]  # X = Y = 0: the tip is the pivot - L e_z plus the runout
    r = np.hypot(dx, rec.channels["tip_y"])
    assert np.allclose(r, 0.01)
    ang = np.unwrap(np.arctan2(rec.channels["tip_y"], dx))
    assert math.isclose(ang[0], math.pi / 2, abs_tol=1e-9)
    assert math.isclose((ang[-1] - ang[0]) / (t[-1] - t[0]), 2 * math.pi * 10, rel_tol=1e-6)


# ---- noise floor and locate ------------------------------------------------------------------------
def test_noise_floor_white_and_quantised():
    rng = np.random.default_rng(3)
    n = 20000
    r = rng.normal(0, 0.01, n) + np.sin(np.linspace(0, 20, n))  # smooth structure does not count
    floor, info = noise_floor(r, np.zeros(n, int), np.zeros(n), np.zeros(n))
    assert abs(info["white"] - 0.01) < 0.0006
    q = np.full(n, 0.1)
    floor, info = noise_floor(np.zeros(n), np.zeros(n, int), q, q)
    assert math.isclose(info["rms"], 0.1 * math.sqrt(2) / math.sqrt(12))


def test_locate_finds_the_bump_and_the_states():
    prog = make_program("lines", duration=6.0, rate=200.0, seed=4)
    t = prog.t
    sim = Simulator(prog, load_machine(None), t, np.zeros(len(t), int), ["X_act"])
    rng = np.random.default_rng(5)
    resid = rng.normal(0, 1e-3, (len(t), 1))
    resid[(t > 2.0) & (t < 2.5), 0] += 0.02
    out = locate_intervals(t, resid, np.full_like(resid, 1e-3), np.ones_like(resid, bool), ["X_act"],
                           sim.states(), np.zeros(len(t), int))
    top = out["intervals"][0]
    assert 1.98 <= top["t_start"] <= 2.02 and 2.47 <= top["t_end"] <= 2.52
    assert set(top["axes"]["X"]) >= {"moving", "reversing", "accelerating", "mean_speed"}
    assert out["largest"][0]["channel"] == "X_act"


# ---- the Michigan recordings ---------------------------------------------------------------------
@needs_umich
def test_michigan_servo_lag_named_with_kv_per_axis():
    p, r = read_umich(UMICH / "experiment_01.csv")
    d = diagnose(p, r)
    f = d.findings
    assert f["named"] == ["servo_lag"]
    e = f["effects"][0]
    kv = e["parameters"]
    assert set(kv) == {"Kv_X", "Kv_Y", "Kv_Z"}
    for a in "YZ":
        assert 100 < kv[f"Kv_{a}"] < 160
        assert e["uncertainties"][f"Kv_{a}"] < 0.05 * kv[f"Kv_{a}"]
    # held-out RMS falls clearly on Z (Z has the finest quantisation)
    assert e["heldout_rms_after"]["Z_act"] < 0.7 * e["heldout_rms_before"]["Z_act"]
    rej = {x["name"]: x["reason"] for x in f["rejected"]}
    assert "backlash" in rej and "time_offset" in rej
    # the lag/offset question is answered, not assumed: on 100 ms samples the shapes agree
    assert f["lag_vs_offset"]["shape_distinguishes"] is False
    assert any(q["alternative"] == "time_offset" for q in f["equivalences"])
    assert "Kv =" in e["sentence"] and "held-out RMS" in e["sentence"]


@needs_umich
def test_michigan_fit_on_some_files_validates_on_others():
    from camsmooth.diagnosis.recordings import concatenate

    p, r = concatenate([read_umich(UMICH / f"experiment_{i:02d}.csv") for i in (1, 2)])
    d = diagnose(p, r)
    assert d.findings["named"] == ["servo_lag"]
    v = validate(*read_umich(UMICH / "experiment_07.csv"), d)
    z = v["channels"]["Z_act"]
    assert z["rms_after"] < 0.75 * z["rms_before"]


# ---- concealed effects (closed-form recordings) -------------------------------------------------
CASES = {c.label: c for c in concealed_cases((1,))}
QUICK = ["null, axes 500 Hz", "null, rotary with tip and axis", "lag on X only", "backlash X, Y only",
         "lag + backlash", "clock offset 5 ms", "rotary location", "rotary squareness", "spindle tilt", "tool length",
         "runout", "spindle-frame growth", "machine growth + rotary location", "machine growth, no rotary motion",
         "positioning + reversal (laser)", "straightness", "squareness"]


def test_the_quick_cases_cover_every_term():
    from camsmooth.diagnosis.terms import CANDIDATES, TRACE_ONLY

    named = {n for label in QUICK for n in CASES[label].named}
    assert named == set(CANDIDATES) - set(TRACE_ONLY)  # those: tests/test_trace_diagnosis.py


@pytest.mark.parametrize("label", QUICK)
def test_concealed_effects_named_exactly(label):
    """diagnose sees only the program and a recording made by closed forms (play operator,
    lsim lag, multi-body head): it names exactly the hidden terms, within 10% (or reports the
    pair it cannot tell apart), and nothing on a null recording."""
    r = run_case(CASES[label], diagnose)
    assert r["exact"] or r["apart"], (label, r["named"], r["apart_pairs"])
    assert not r["bad"], (label, r["errors"])


@pytest.mark.parametrize("label, others", [("lag on X only", ["Y", "Z"]),
                                           ("lag on X only, with A, B", ["Y", "Z", "A", "B"])])
def test_lag_on_one_axis_reports_the_others_as_not_measurable(label, others):
    """The issue's case: a lag on X only is named with Kv_X and 'none measurable' on the other
    axes, never with a gain at its bound."""
    r = run_case(CASES[label], diagnose)
    assert r["exact"] and not r["bad"]
    assert r["none_measurable"]["servo_lag"] == others


def test_sub_period_clock_offset_is_not_a_finding():
    """Backlash only on X and Y, 500 Hz point-to-point moves of X, Y, Z, A, B, 0.3 um noise (the
    issue's case, recorded with the play operator): only backlash is named, with 'none
    measurable' on the other axes; the clock offset is refused with the rule stated."""
    case = CASES["backlash X, Y, p2p 500 Hz"]
    from benchmarks.synthetic import program_for, recording_for

    prog = program_for(case)
    f = diagnose(prog, recording_for(case, prog)).findings
    assert f["named"] == ["backlash"]
    assert set(f["effects"][0]["parameters"]) == {"backlash_X", "backlash_Y"}
    assert f["effects"][0]["none_measurable"] == ["Z", "A", "B"]
    assert "reaches" in f["selection"]["rule"]
    rej = {x["name"]: x["reason"] for x in f["rejected"]}
    assert "time_offset" in rej


def test_thermal_frames_cannot_be_told_apart_without_rotary_motion():
    r = run_case(CASES["machine growth, no rotary motion"], diagnose)
    pairs = {frozenset(p) for p in r["apart_pairs"]}
    assert frozenset({"thermal_drift", "thermal_machine"}) in pairs


# ---- model files -----------------------------------------------------------------------------------
def test_model_json_round_trip_and_errormodel_reads_it(tmp_path):
    ph = physics_from_settings({"Kv_X": 50, "Kv_A": 30, "backlash_B": 0.01, "offset_s": 0.002, "EZ0T": 0.04,
                                "EB0A": 1e-4, "thermal_dz_gain": 0.01, "thermal_dz_tau": 60.0,
                                "runout_radius": 0.003, "runout_phase_deg": -40})
    doc = model_json(ph)
    path = tmp_path / "m.json"
    path.write_text(json.dumps(doc))
    em = ErrorModel.from_json(path)
    assert em.geometric == {"EZ0T": 0.04, "EB0A": 1e-4}
    assert em.thermal["dz"] == {"gain": 0.01, "tau": 60.0}
    back = load_model(str(path))
    assert math.isclose(1 / back.tau["X"], 50) and math.isclose(1 / back.tau["A"], 30)
    assert math.isclose(back.backlash["B"], math.radians(0.01)) and math.isclose(back.offset_s, 0.002)
    assert np.allclose(back.runout, ph.runout)


def test_bad_model_file(tmp_path):
    path = tmp_path / "m.json"
    path.write_text('{"servo": {"Kv": {"Q": 3}}}')
    with pytest.raises(InputError, match="servo Kv"):
        load_model(str(path))
    with pytest.raises(InputError):
        physics_from_model({"format": "other"})


# ---- CLI, the update loop, simulate recording --------------------------------------------------------
def _write_case(tmp_path, settings, kind="lines", channels="axes,tip"):
    prog = make_program(kind, duration=8.0, rate=250.0, seed=6)
    pp = tmp_path / "program.csv"
    write_program_csv(pp, prog)
    parser = argparse.ArgumentParser()
    add_simulate_recording_arguments(parser)
    rp = tmp_path / "recording.csv"
    args = parser.parse_args(["--program", str(pp), "--out", str(rp), "--channels", channels, "--noise-mm", "0.001",
                              "--seed", "2"] + [x for k, v in settings.items() for x in ("--set", f"{k}={v}")])
    assert simulate_recording_cli(args) == 0
    return pp, rp


def test_cli_diagnose_writes_findings_report_and_model(tmp_path, capsys):
    pp, rp = _write_case(tmp_path, {"Kv_X": 45, "Kv_Y": 55, "Kv_Z": 65, "EZ0T": 0.03})
    out, rep, mod = tmp_path / "f.json", tmp_path / "rep", tmp_path / "new.json"
    assert cli_main(["diagnose", "--program", str(pp), "--recording", str(rp), "--out", str(out),
                     "--report", str(rep), "--model-out", str(mod)]) == 0
    f = json.loads(out.read_text())
    for key in ("channels", "noise_floor", "baseline_rms", "intervals", "effects", "final_rms", "rejected"):
        assert key in f
    assert sorted(f["named"]) == ["servo_lag", "tool_length"]
    for e in f["effects"]:
        assert {"name", "parameters", "uncertainties", "rms_before", "rms_after", "heldout_rms_before",
                "heldout_rms_after", "sentence"} <= set(e)
    assert {"report.html", "residual_time.png", "effect_servo_lag.png"} <= {p.name for p in rep.iterdir()}
    assert "lag their command" in capsys.readouterr().out
    # the update: with the written model, the same recording leaves nothing to explain
    assert cli_main(["diagnose", "--program", str(pp), "--recording", str(rp), "--model", str(mod),
                     "--out", str(tmp_path / "g.json"), "--quiet"]) == 0
    g = json.loads((tmp_path / "g.json").read_text())
    assert g["named"] == [] and g["verdict"].startswith("nothing to explain")
    assert ErrorModel.from_json(mod).geometric["EZ0T"] == pytest.approx(0.03, rel=0.02)


def test_cli_errors(tmp_path):
    pp, rp = _write_case(tmp_path, {})
    with pytest.raises(InputError, match="--recording"):
        _run_raw(["diagnose", "--program", str(pp), "--out", "x.json"])
    with pytest.raises(InputError, match="umich"):
        _run_raw(["diagnose", "--format", "umich", "a.csv", "--program", str(pp), "--out", "x.json"])
    with pytest.raises(InputError, match="unknown"):
        _run_raw(["diagnose", "--program", str(pp), "--recording", str(rp), "--out", "x.json",
                  "--candidates", "servo_lag,magic"])
    bad = tmp_path / "bad.csv"
    bad.write_text("t,X_act\n0,1\n1,x\n")
    with pytest.raises(InputError) as e:
        _run_raw(["diagnose", "--program", str(pp), "--recording", str(bad), "--out", "x.json"])
    assert e.value.row == 2 and e.value.column == "X_act"
    # the CLI turns it into exit status 2, with no output file left behind
    assert cli_main(["diagnose", "--program", str(pp), "--recording", str(bad), "--out",
                     str(tmp_path / "never.json")]) == 2
    assert not (tmp_path / "never.json").exists()


def _run_raw(argv):
    from camsmooth.cli.main import build_parser

    args = build_parser().parse_args(argv)
    return args.func(args)


@needs_umich
def test_cli_umich_format(tmp_path):
    out = tmp_path / "f.json"
    assert cli_main(["diagnose", "--format", "umich", str(UMICH / "experiment_01.csv"), "--out", str(out),
                     "--validate", str(UMICH / "experiment_08.csv"), "--quiet"]) == 0
    f = json.loads(out.read_text())
    assert f["named"] == ["servo_lag"]
    assert f["validation"][0]["channels"]["Z_act"]["rms_after"] < f["validation"][0]["channels"]["Z_act"]["rms_before"]


def test_simulate_recording_rate_and_quantisation(tmp_path):
    prog = make_program("lines", duration=2.0, rate=100.0, seed=1)
    rec = simulate_recording(prog, rate=1000.0, channels=["axes"], quantum={"axes": 0.01})
    assert len(rec.t) == 1991 and np.allclose(np.diff(rec.t), 1e-3)  # 0 .. 1.99 s, the program's span
    assert np.allclose(rec.channels["X_act"] / 0.01, np.round(rec.channels["X_act"] / 0.01))
    write_recording_csv(tmp_path / "r.csv", rec)
    back = read_recording_csv(tmp_path / "r.csv")
    assert np.allclose(back.quantum["X_act"][np.abs(back.channels["X_act"]) > 0.05], 0.01)
    with pytest.raises(InputError):
        simulate_recording(prog, channels=["nonsense"])


def test_program_knots_direction_holds_through_stops():
    t = np.arange(8.0)
    u = np.array([0, 1, 2, 2, 2, 1, 1, 3], float)
    kn = Knots(Program(t=t, axes={"X": u}))
    assert list(kn.direction("X")) == [1, 1, 1, 1, -1, -1, 1, 1]


def test_unexplained_when_no_candidate_helps():
    """A screw pitch error (periodic in position) is in no candidate: nothing is named and the
    verdict says a residual above the floor remains, located on X."""
    prog = make_program("lines", duration=8.0, rate=250.0, seed=2)
    rec = simulate_recording(prog, channels=["axes"], noise={"axes": 0.001}, seed=1)
    rec.channels["X_act"] = rec.channels["X_act"] + 0.02 * np.sin(2 * np.pi * rec.channels["X_act"] / 5.0)
    f = diagnose(prog, rec).findings
    assert f["named"] == []
    assert [e["name"] for e in f["effects"]] == ["unexplained"]
    assert f["effects"][0]["channels"] == ["X_act"]
    assert "X_act" in f["intervals"][0]["channels"]


def test_mis_set_model_parameter_is_refitted():
    prog = make_program("lines", duration=8.0, rate=250.0, seed=2)
    truth = physics_from_settings({"Kv_X": 45, "Kv_Y": 55, "Kv_Z": 65})
    rec = simulate_recording(prog, physics=truth, channels=["axes"], noise={"axes": 0.001}, seed=1)
    f = diagnose(prog, rec, base=physics_from_settings({"Kv_X": 30, "Kv_Y": 55, "Kv_Z": 65})).findings
    e = f["effects"][0]
    assert e["name"] == "servo_lag" and e["parameters"]["Kv_X"] == pytest.approx(45, rel=0.01)
    assert "mis-set" in e["sentence"] and e["model_had"]["Kv_X"] == pytest.approx(30)
    assert diagnose(prog, rec, base=truth).findings["named"] == []


def test_a_length_below_the_recording_resolution_is_not_a_finding():
    """A tool 0.4 um too long, on a tool tip recorded in whole micrometres with 0.2 um of noise:
    clear in the statistics of 2000 samples, below what the channel resolves - not named, and the
    rejection says why; the same error at 40 um is named."""
    from benchmarks.synthetic import make_special_program, record

    prog = make_special_program("rotary", rate=250.0, seed=3, duration=8.0)

    def diagnosed(ez0t):
        rec = record(prog, {"EZ0T": ez0t}, channels=("tip",), noise={"tip": 2e-4}, seed=9)
        for c in rec.channels:
            rec.channels[c] = np.round(rec.channels[c] / 1e-3) * 1e-3
            rec.quantum[c] = np.full(len(rec.t), 1e-3)
        return diagnose(prog, rec).findings

    f = diagnosed(0.0004)
    assert f["named"] == []  # nor does another geometric term pick it up
    assert "below the recording's resolution" in {r["name"]: r["reason"] for r in f["rejected"]}["tool_length"]
    assert diagnosed(0.04)["named"] == ["tool_length"]


def test_simulator_thermal_is_the_models_thermal_state_when_the_speed_changes():
    """One thermal model: with the spindle speed stepping and ramping between program rows, the
    diagnosis simulator's tool tip equals ErrorModel.real_frame with ErrorModel.thermal_state
    (speed linear between rows) - the same integrator, not a second one."""
    from camsmooth.machine.model import frame_tip_axis

    t = np.linspace(0.0, 60.0, 601)
    S = np.interp(t, [0, 10, 10.1, 30, 45, 60], [0, 0, 9000, 9000, 2000, 2000])
    A = np.radians(20 * np.sin(t / 7))
    prog = Program(t=t, axes={"X": np.zeros_like(t), "A": A, "B": 0.5 * A}, S=S)
    th = {"dz": {"gain": 0.01, "tau": 8.0}, "mx": {"gain": -0.004, "tau": 15.0}, "exz": {"gain": 2e-5, "tau": 5.0}}
    model = ErrorModel({"EY0A": 0.01}, thermal=th)
    rec = simulate_recording(prog, physics=model, channels=["tip", "axis"])
    q = {"X": prog.axes["X"], "A": A, "B": 0.5 * A}
    tip, axis = frame_tip_axis(model.real_frame(load_machine(None), q, model.thermal_state(t, S, hold="linear")),
                               len(t))
    assert np.allclose(np.column_stack([rec.channels[c] for c in ("tip_x", "tip_y", "tip_z")]), tip, atol=1e-12)
    assert np.allclose(np.column_stack([rec.channels[c] for c in ("axis_i", "axis_j", "axis_k")]), axis,
                       atol=1e-14)
