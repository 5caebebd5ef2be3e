"""Calibration from simulated measurements (issue 3, "what must be shown"): probing, spindle
screw (least squares vs particle swarm), ballbar thermal (least squares vs trilateration), bad
input, and the CLI simulate -> calibrate round trip."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from camsmooth.cli.model import predict_table, register
from camsmooth.errors import InputError
from camsmooth.machine import calibration as cal
from camsmooth.machine import simulate as sim
from camsmooth.machine.kinematics import load_machine
from camsmooth.machine.model import GEOMETRIC_PARAMETERS, SPINDLE_THERMAL, ErrorModel, SpindleScrew

AXIS_ERRORS = {"EY0A": 0.020, "EZ0A": -0.035, "EB0A": 30e-6, "EC0A": -45e-6, "EX0B": 0.015, "EZ0B": -0.025,
               "EA0B": 40e-6, "EC0B": -20e-6}
SPINDLE = SpindleScrew(r1=0.004, theta1=0.7, r2=0.006, theta2=-2.1, cos_alpha=1.5e-5, cos_beta=-2.5e-5,
                       delta3=0.012)
THERMAL = {"dx": {"gain": 0.002, "tau": 1200.0}, "dy": {"gain": -0.003, "tau": 1500.0},
           "dz": {"gain": -0.006, "tau": 900.0}, "exz": {"gain": 4e-6, "tau": 1800.0},
           "eyz": {"gain": -3e-6, "tau": 1400.0}}


@pytest.fixture(scope="module")
def machine():
    return load_machine()


def _um(name: str, v: float) -> float:
    return v * (1e3 if GEOMETRIC_PARAMETERS[name][0] == "mm" else 1e6)


# ----------------------------------------------------------------------------------------------
# probing
@pytest.fixture(scope="module")
def probe_report(machine):
    data = sim.simulate_probe(ErrorModel(dict(AXIS_ERRORS)), machine, noise=0.0005, seed=11)
    return cal.calibrate_probe(data, machine)


def test_probe_recovers_axis_errors(probe_report):
    rep = probe_report
    assert set(rep.parameters) == set(AXIS_ERRORS)
    for k, true in AXIS_ERRORS.items():
        err = abs(_um(k, rep.parameters[k] - true))
        limit = 1.0 if GEOMETRIC_PARAMETERS[k][0] == "mm" else 2.0  # um / urad
        assert err < limit, (k, err)
        assert err < 4 * _um(k, rep.uncertainties[k]), (k, err)
    assert rep.rms_after < 0.0006 < 0.01 < rep.rms_before
    assert rep.condition_number < 100 and len(rep.singular_values) == len(AXIS_ERRORS) + 3
    assert np.allclose(rep.details["sphere_centre"], [0.012, -0.008, 0.005], atol=0.001)


def test_probe_reports_the_unobservable_parameters(probe_report):
    un = probe_report.unidentifiable
    assert set(un) == {"EZ0T", "EX0S", "EY0S", "EA0S", "EB0S"}
    assert "EY0A" in un["EA0S"] and "-0.15 um" in un["EA0S"]  # a tilt is an offset of L_p x tilt at the tip
    assert "EZ0A" in un["EZ0T"]
    assert "EA0S" in probe_report.summary()


def test_probe_confounded_truth_still_predicts_the_tips(machine):
    """With spindle tilt and tool-length errors in the truth, the fit absorbs them into the
    confounded combinations: the fitted model predicts the same tool tips up to the sphere shift."""
    truth = ErrorModel({**AXIS_ERRORS, "EZ0T": 0.030, "EB0S": 20e-6, "EY0S": 0.01})
    rep = cal.calibrate_probe(sim.simulate_probe(truth, machine, noise=0.0005, seed=4), machine)
    assert rep.parameters["EZ0A"] == pytest.approx(AXIS_ERRORS["EZ0A"] + 0.030, abs=0.001)
    rng = np.random.default_rng(0)
    z = np.zeros(30)
    q = (np.radians(rng.uniform(-90, 90, 30)), np.radians(rng.uniform(-90, 90, 30)), z, z, z)
    d = rep.model.predict(machine, *q).tip - truth.predict(machine, *q).tip
    assert np.max(np.ptp(d, axis=0)) < 0.002  # a constant shift (the sphere) within noise


def _probe_csv(tmp_path, data, name="probe.csv"):
    return cal.write_probe_csv(tmp_path / name, data)


def test_probe_bad_input(tmp_path, machine):
    data = sim.simulate_probe(ErrorModel(dict(AXIS_ERRORS)), machine, seed=1)
    path = _probe_csv(tmp_path, data)
    lines = path.read_text().splitlines()
    # missing column
    (tmp_path / "m.csv").write_text("\n".join(",".join(r.split(",")[:-1]) for r in lines) + "\n")
    with pytest.raises(InputError, match="column 'sz'"):
        cal.calibrate_probe(tmp_path / "m.csv", machine)
    # NaN
    bad = lines.copy()
    bad[3] = bad[3].rsplit(",", 1)[0] + ",nan"
    (tmp_path / "n.csv").write_text("\n".join(bad) + "\n")
    with pytest.raises(InputError, match="row 3.*column 'sz'.*finite"):
        cal.calibrate_probe(tmp_path / "n.csv", machine)
    # duplicate poses
    (tmp_path / "d.csv").write_text("\n".join(lines + [lines[5]]) + "\n")
    with pytest.raises(InputError, match="duplicate poses"):
        cal.calibrate_probe(tmp_path / "d.csv", machine)
    # all probing at one A angle
    one = sim.simulate_probe(ErrorModel(dict(AXIS_ERRORS)), machine,
                             poses=(np.zeros(9), np.radians(np.linspace(-80, 80, 9))))
    with pytest.raises(InputError, match="A = 0 deg.*EY0A, EZ0A, EB0A, EC0A cannot be determined"):
        cal.calibrate_probe(one, machine)
    # too few poses
    few = sim.simulate_probe(ErrorModel(), machine, poses=(np.radians([0, 30, 60]), np.radians([0, 45, -30])))
    with pytest.raises(InputError, match="too few poses: 3 poses give 9 equations for 11 unknowns.*at least "
                                         "4 distinct poses are needed"):
        cal.calibrate_probe(few, machine)
    # enough equations, too little variety: a parameter the poses cannot separate
    A, B = (v.ravel() for v in np.meshgrid(np.radians([0, 40, 80]), np.radians([0, 40])))
    poor = sim.simulate_probe(ErrorModel(), machine, poses=(A, B))
    with pytest.raises(InputError, match="these 6 poses .* cannot determine EC0B .*same effect as .* EA0B"):
        cal.calibrate_probe(poor, machine)
    with pytest.raises(InputError, match="not found"):
        cal.calibrate_probe(tmp_path / "none.csv", machine)


# ----------------------------------------------------------------------------------------------
# spindle screw
@pytest.fixture(scope="module")
def spindle_report():
    data = sim.simulate_spindle(ErrorModel(spindle=SPINDLE), noise=0.0001, seed=3)
    return cal.calibrate_spindle(data, seed=0)


def test_spindle_parameters_within_their_uncertainty(spindle_report):
    rep = spindle_report
    for k, v in rep.parameters.items():
        true = getattr(SPINDLE, k)
        assert abs(v - true) < 3 * rep.uncertainties[k], (k, v, true, rep.uncertainties[k])
    assert set(rep.unidentifiable) == {"rho1", "rho2", "h1"}
    assert rep.model.spindle.r1 == rep.parameters["r1"] and rep.model.spindle.h == SPINDLE.h


def test_spindle_least_squares_at_least_as_accurate_as_pso(spindle_report):
    rep = spindle_report
    pso = rep.details["pso"]
    assert rep.rms_after <= pso["rms"] * (1 + 1e-9)
    # parameter error in units of the LS uncertainty: LS no worse than the swarm overall
    ls_err = [(rep.parameters[k] - getattr(SPINDLE, k)) / rep.uncertainties[k] for k in rep.parameters]
    pso_err = [(pso["parameters"][k] - getattr(SPINDLE, k)) / rep.uncertainties[k] for k in rep.parameters]
    assert np.sqrt(np.mean(np.square(ls_err))) <= np.sqrt(np.mean(np.square(pso_err))) + 0.05
    assert pso["nfev"] > 50 * rep.details["ls"]["nfev"]  # the timing itself is printed by the example


def test_spindle_bad_input():
    data = sim.simulate_spindle(ErrorModel(spindle=SPINDLE), exts=(80.0,))
    with pytest.raises(InputError, match="one ball height.*r1, theta1, r2, theta2 cannot be separated"):
        cal.calibrate_spindle(data, pso_compare=False)
    data = sim.simulate_spindle(ErrorModel(spindle=SPINDLE))
    half = data.theta < 2.5
    part = cal.SpindleData(data.theta[half], data.ext[half], data.ball[half])
    with pytest.raises(InputError, match="do not go round"):
        cal.calibrate_spindle(part, pso_compare=False)
    dup = cal.SpindleData(np.r_[data.theta, data.theta[:1]], np.r_[data.ext, data.ext[:1]],
                          np.vstack([data.ball, data.ball[:1]]))
    with pytest.raises(InputError, match="duplicate"):
        cal.calibrate_spindle(dup, pso_compare=False)


# ----------------------------------------------------------------------------------------------
# ballbar thermal
@pytest.fixture(scope="module")
def ballbar(machine):
    truth = ErrorModel({"EY0A": 0.02, "EB0S": 20e-6}, SPINDLE, {k: dict(v) for k, v in THERMAL.items()})
    times = np.arange(0.0, 3 * 3600 + 1, 1800.0)
    rpm = np.where(times < 7200, 5000.0, 0.0)
    data = sim.simulate_ballbar(truth, machine, times=times, rpm=rpm, step_deg=0.02, noise=0.001, seed=1)
    rep = cal.calibrate_ballbar(data)
    state = truth.thermal_state(times, rpm)
    return rep, np.column_stack([state[k] for k in SPINDLE_THERMAL]), data


def test_ballbar_least_squares_recovers_the_drift(ballbar):
    rep, true, _ = ballbar
    assert np.max(np.abs(true[:, 2])) > 0.029  # drift up to 30 um
    err = np.abs(rep.details["elements"] - true)
    assert np.max(err[:, :3]) < 0.0005          # dx, dy, dz within 0.5 um
    assert np.max(err[:, 3:]) < 2e-6            # exz, eyz within 2 urad
    tri = np.abs(rep.details["trilateration"] - true)
    assert np.max(tri[:, 3:]) > np.max(err[:, 3:])  # the paper's few triples are noisier
    tri_all = rep.details["trilateration_all"]
    assert np.max(np.abs(tri_all - rep.details["elements"])[:, [0, 1]]) < 1e-4  # every triple ~ LS
    assert rep.rms_after == pytest.approx(0.001, rel=0.02)


def test_ballbar_model_gains_and_time_constants(ballbar):
    rep, _, _ = ballbar
    for k, d in THERMAL.items():
        assert abs(rep.parameters[f"{k}.gain"] - d["gain"]) < 4 * rep.uncertainties[f"{k}.gain"], k
        assert abs(rep.parameters[f"{k}.tau"] - d["tau"]) < 4 * rep.uncertainties[f"{k}.tau"], k
    assert rep.model.thermal["dz"]["tau"] == rep.parameters["dz.tau"]
    assert rep.model.spindle is None  # base parts kept (none given)


def _subset(data, sel):
    fields = ("t", "rpm", "angle", "direction", "phi", "L0", "dL")
    return cal.BallbarData(*(getattr(data, f)[sel] for f in fields))


def test_ballbar_bad_input(ballbar):
    _, _, data = ballbar
    one_angle = data.angle == data.angle[0]
    sub = _subset(data, one_angle)
    with pytest.raises(InputError, match="one bar angle.*exz, eyz cannot be determined"):
        cal.calibrate_ballbar(sub)
    first = data.t == data.t[0]
    sub = _subset(data, first)
    with pytest.raises(InputError, match="only one measurement set"):
        cal.calibrate_ballbar(sub)
    gap = ~((data.t == data.t[2]) & (data.phi > 3.0))
    sub = _subset(data, gap)
    with pytest.raises(InputError, match="does not go round"):
        cal.calibrate_ballbar(sub)
    idx = np.r_[np.arange(len(data.t)), 7]
    sub = _subset(data, idx)
    with pytest.raises(InputError, match="duplicate samples"):
        cal.calibrate_ballbar(sub)


# ----------------------------------------------------------------------------------------------
# CLI: simulate -> calibrate round trip, predict
def _cli(argv):
    parser = argparse.ArgumentParser(prog="camsmooth")
    register(parser.add_subparsers(dest="cmd", required=True))
    args = parser.parse_args([str(a) for a in argv])
    return args.func(args)


def test_cli_simulate_calibrate_round_trip(tmp_path, capsys):
    truth = ErrorModel(dict(AXIS_ERRORS), SPINDLE, {k: dict(v) for k, v in THERMAL.items()})
    truth.to_json(tmp_path / "truth.json")
    assert _cli(["simulate", "spindle", "--model", tmp_path / "truth.json", "--seed", "2", "-o",
                 tmp_path / "spindle.csv"]) == 0
    assert _cli(["calibrate", "spindle", tmp_path / "spindle.csv", "--no-pso", "-o",
                 tmp_path / "m1.json"]) == 0
    assert _cli(["simulate", "probe", "--model", tmp_path / "truth.json", "--noise", "0.0005", "-o",
                 tmp_path / "probe.csv"]) == 0
    assert _cli(["calibrate", "probe", tmp_path / "probe.csv", "--base", tmp_path / "m1.json", "-o",
                 tmp_path / "m2.json", "--report", tmp_path / "r2.json"]) == 0
    assert _cli(["simulate", "ballbar", "--model", tmp_path / "truth.json", "--step", "0.5", "--interval",
                 "1800", "-o", tmp_path / "bb.csv"]) == 0
    assert _cli(["calibrate", "ballbar", tmp_path / "bb.csv", "--base", tmp_path / "m2.json", "-o",
                 tmp_path / "model.json", "--report", tmp_path / "r3.json"]) == 0
    out = capsys.readouterr().out
    assert "not determinable" in out and "EB0S" in out
    back = ErrorModel.from_json(tmp_path / "model.json")
    assert set(back.geometric) == set(truth.geometric)  # the unobservable ones were not written
    for k, v in truth.geometric.items():  # key by key
        assert abs(_um(k, back.geometric[k] - v)) < (1.0 if GEOMETRIC_PARAMETERS[k][0] == "mm" else 2.0), k
    for k in ("r1", "r2", "delta3"):
        assert getattr(back.spindle, k) == pytest.approx(getattr(SPINDLE, k), abs=2e-4)
    for k in ("cos_alpha", "cos_beta"):
        assert getattr(back.spindle, k) == pytest.approx(getattr(SPINDLE, k), abs=2e-7)
    unc = json.loads((tmp_path / "r3.json").read_text())["uncertainties"]
    for k, d in truth.thermal.items():
        for q in ("gain", "tau"):
            assert abs(back.thermal[k][q] - d[q]) < 4 * unc[f"{k}.{q}"], (k, q)
    assert set(back.meta) >= {"spindle", "probe", "ballbar"}
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # atomic writes


def test_cli_predict(tmp_path, machine, capsys):
    model = ErrorModel({"EC0A": 50e-6, "EZ0A": 0.02})
    model.to_json(tmp_path / "m.json")
    # a straight row over a flat plate, lead 10 deg, as a smoothing output would have it
    n = 20
    cc = np.column_stack([np.linspace(0, 50, n), np.full(n, 5.0), np.zeros(n)])
    normals = np.tile([0.0, 0.0, 1.0], (n, 1))
    lead = np.radians(10.0)
    axis = np.tile([np.sin(lead), 0.0, np.cos(lead)], (n, 1))
    ik = machine.solve_row(axis, cc)
    cols = ["row", "idx", "t", "x", "y", "z", "nx", "ny", "nz", "lead", "tilt", "A", "B", "X", "Y", "Z",
            "delta"]
    table = np.column_stack([np.zeros(n), np.arange(n), np.linspace(0, 5, n), cc, normals, np.full(n, 10.0),
                             np.zeros(n), np.degrees(ik.rotary["A"]), np.degrees(ik.rotary["B"]), ik.xyz, np.zeros(n)])
    path = tmp_path / "out.csv"
    path.write_text(",".join(cols) + "\n" + "\n".join(",".join(f"{v:.12g}" for v in r) for r in table) + "\n")
    assert _cli(["predict", path, "--model", tmp_path / "m.json", "-o", tmp_path / "pred.csv"]) == 0
    out = capsys.readouterr().out
    assert "tool-tip deviation max" in out
    got = cal.read_table(tmp_path / "pred.csv", ("real_clx", "tip_dev_um", "real_lead", "real_tilt"))
    pred = model.predict(machine, *ik.rotary.pair, *ik.xyz.T)
    assert np.allclose(got["tip_dev_um"], pred.tip_dev_um, rtol=1e-6)
    # an A squareness error about z turns the axis about z: at B != 0 that shows up as tilt
    assert np.max(np.abs(got["real_tilt"])) > 1e-4 and np.allclose(got["real_lead"], 10.0, atol=0.01)
    direct = predict_table(model, machine, {k: table[:, i] for i, k in enumerate(cols)})
    assert np.allclose(direct["real_delta_est"], 0.0, atol=0.1) and np.any(direct["real_delta_est"] != 0)


# ----------------------------------------------------------------------------------------------
# what the reports say (every field a user or the model file reads), against the simulated truth
def _sv_check(rep):
    sv = np.asarray(rep.singular_values)
    assert np.all(np.diff(sv) <= 0) and sv[-1] > 0
    assert rep.condition_number == pytest.approx(sv[0] / sv[-1], rel=1e-12)


def test_probe_report_fields(probe_report, machine):
    rep = probe_report
    data = sim.simulate_probe(ErrorModel(dict(AXIS_ERRORS)), machine, noise=0.0005, seed=11)
    assert rep.kind == "probe" and rep.n_observations == 3 * len(data.A)
    # 20-45 um of axis errors before, the 0.5 um probing noise after (mm)
    assert 0.005 < rep.rms_before < 0.2 and rep.rms_after == pytest.approx(0.0005, rel=0.3)
    # the sphere's real centre, simulate_probe's sphere_error (mm), to a few noise levels
    np.testing.assert_allclose(rep.details["sphere_centre"], [0.012, -0.008, 0.005], atol=0.002)
    assert np.all(rep.details["sphere_centre_uncertainty"] < 0.001)
    meta = rep.model.meta["probe"]
    assert meta["poses"] == len(data.A) and meta["fitted"] == list(rep.parameters)
    assert meta["unidentifiable"] == sorted(rep.unidentifiable) and meta["source"] == data.source
    assert all("held at" in why for why in rep.unidentifiable.values())
    assert rep.units == {k: GEOMETRIC_PARAMETERS[k][0] for k in rep.parameters}
    _sv_check(rep)


def test_spindle_report_fields(spindle_report):
    rep = spindle_report
    assert rep.kind == "spindle"
    assert rep.units == {k: cal._SPINDLE_UNITS[k] for k in rep.parameters}
    assert set(rep.details) == {"time_s", "nfev", "pso", "ls"}
    assert set(rep.details["pso"]) == {"parameters", "rms", "time_s", "nfev"}
    assert set(rep.details["pso"]["parameters"]) == set(rep.parameters)
    assert rep.details["ls"]["rms"] == rep.rms_after and rep.details["ls"]["nfev"] == rep.details["nfev"]
    meta = rep.model.meta["spindle"]
    assert set(meta) == {"source", "samples", "fitted", "unidentifiable"}
    assert meta["fitted"] == list(rep.parameters) and meta["unidentifiable"] == sorted(rep.unidentifiable)
    assert meta["samples"] * 3 == rep.n_observations  # three ball coordinates per sample
    assert all("held at" in why for why in rep.unidentifiable.values())
    assert rep.rms_after < rep.rms_before
    # central differences: a Jacobian alone costs two evaluations per fitted parameter
    assert rep.details["nfev"] >= 2 * len(rep.details["pso"]["parameters"])
    _sv_check(rep)


def test_ballbar_report_fields(ballbar):
    rep, true, data = ballbar
    assert rep.kind == "ballbar" and rep.details["trilateration_triples"] == 8
    assert rep.rms_before > 3 * rep.rms_after  # the drift, not explained before the fit
    err = np.abs(rep.details["elements"] - true)[1:]
    sd = rep.details["element_uncertainty"][1:]
    assert np.all(err < 5 * sd)
    assert np.all(sd[:, :3] < 0.002) and np.all(sd[:, 3:] < 5e-6)  # um and urad scale, not mm and rad
    for k, d in THERMAL.items():
        assert rep.uncertainties[f"{k}.tau"] < 0.5 * d["tau"], k
        assert rep.uncertainties[f"{k}.gain"] < 0.5 * abs(d["gain"]), k
    assert "setup" in rep.details and rep.model.meta["ballbar"]["sets"] == len(rep.details["times"])
    _sv_check(rep)


def test_pso_on_known_minima():
    """A shifted quadratic (interior minimum) and a minimum on a bound of a clipped dimension beside a
    periodic one whose minimum is across the wrap: the swarm reaches each to 1e-6."""
    c = np.array([1.2, -3.4, 0.5])
    x, cost, nfev = cal.pso(lambda X: np.sum((X - c) ** 2, axis=1), -5 * np.ones(3), 5 * np.ones(3))
    np.testing.assert_allclose(x, c, atol=1e-6)
    assert cost < 1e-10 and nfev == 40 * 601

    def f(X):
        return 1.0 - np.cos(X[:, 0] - 3.1) + (X[:, 1] - 6.0) ** 2

    x, cost, _ = cal.pso(f, np.array([-np.pi, -5.0]), np.array([np.pi, 5.0]), periodic=np.array([True, False]))
    assert x[1] == 5.0  # clipped onto the bound, not wrapped
    assert abs(np.angle(np.exp(1j * (x[0] - 3.1)))) < 1e-4 and -np.pi <= x[0] < np.pi


def test_fit_thermal_response_recovers_gain_and_tau_or_says_why_not():
    """Noise-free per-set values of a first-order response: gain and tau recovered; a drift at 3.5
    standard uncertainties is fitted, one at 2.5 holds tau at tau0 and says so."""
    from camsmooth.machine.model import first_order_response

    t = np.arange(0.0, 4 * 3600 + 1, 900.0)
    rpm = np.where(t < 7200, 6000.0, 0.0)
    resp = first_order_response(t, rpm / 1000.0, 1.0, 1300.0)
    values = 0.004 * resp
    g, tau, ug, utau, why = cal.fit_thermal_response(t, rpm, values, np.eye(len(t) - 1) * 1e-8)
    assert why is None and g == pytest.approx(0.004, rel=1e-6) and tau == pytest.approx(1300.0, rel=1e-6)
    assert 0 < ug < 1e-4 and 0 < utau < 10
    size = 0.004 * np.linalg.norm(resp[1:])
    for sigmas, fitted in ((3.5, True), (2.5, False)):
        cov = np.eye(len(t) - 1) * (size / sigmas) ** 2
        g, tau, ug, utau, why = cal.fit_thermal_response(t, rpm, values, cov)
        assert (why is None) == fitted, sigmas
        if not fitted:  # held at the documented default, 1800 s
            assert tau == 1800.0 and utau == np.inf and "no significant drift" in why
    # three sets (two after the cold one): a gain and a time constant from two values cannot be told apart
    t = np.array([0.0, 1800.0, 3600.0])
    rpm = np.full(3, 6000.0)
    values = 0.004 * first_order_response(t, rpm / 1000.0, 1.0, 1300.0)
    g, tau, ug, utau, why = cal.fit_thermal_response(t, rpm, values, np.eye(2) * 1e-8, tau0=900.0)
    assert tau == 900.0 and utau == np.inf and "does not show the time response" in why
