"""R-test calibration (issue 18): a sphere on the table, read by a nest in the spindle at many
(tilt, C) poses, identifies the location errors of a table's axis lines through the one fitting
toolkit; the nest's offset is reported as confounded; degenerate pose sets and mismatched kinds
are InputErrors; the R-test file round trip."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine import calibration as cal
from camsmooth.machine import simulate as sim
from camsmooth.machine.kinematics import load_machine, machine_from_dict
from camsmooth.machine.model import GEOMETRIC_PARAMETERS, ErrorModel

TRUTH = {
    "AC-table": {"EX0C": 0.015, "EY0C": -0.010, "EA0C": 30e-6, "EB0C": -20e-6, "EY0A": 0.012, "EZ0A": -0.008,
                 "EB0A": 25e-6, "EC0A": -15e-6},
    "BC-table": {"EX0C": 0.015, "EY0C": -0.010, "EA0C": 30e-6, "EB0C": -20e-6, "EX0B": 0.012, "EZ0B": -0.008,
                 "EA0B": 25e-6, "EC0B": -15e-6},
}


def table_machine(kind: str):
    tilt = "A" if kind == "AC-table" else "B"
    return machine_from_dict({"machine": {"kind": kind, "table_centre": [12.0, -25.0, -60.0]},
                              "axis": {tilt: {"min": -120.0, "max": 120.0, "vmax": 60.0, "amax": 300.0},
                                       "C": {"vmax": 180.0, "amax": 900.0}}})


def _display(name: str, v: float) -> float:
    """um for lengths, urad for angles."""
    return v * (1e3 if GEOMETRIC_PARAMETERS[name][0] == "mm" else 1e6)


@pytest.mark.parametrize("kind", ["AC-table", "BC-table"])
def test_rtest_recovers_the_table_location_errors(kind):
    machine = table_machine(kind)
    truth = ErrorModel(dict(TRUTH[kind]), kind=kind)
    data = sim.simulate_rtest(truth, machine, noise=0.0005, seed=3)
    assert len(data.q1) == 84  # 7 tilt angles x 12 C angles
    rep = cal.calibrate_rtest(data, machine)
    assert set(rep.parameters) == set(TRUTH[kind])  # all eight location errors are identifiable
    for k, v in TRUTH[kind].items():
        err, sd = rep.parameters[k] - v, rep.uncertainties[k]
        assert abs(err) < 4 * sd, (k, err, sd)
        assert abs(_display(k, err)) < max(0.05 * abs(_display(k, v)), 1.0), (k, err)  # 5 % or 1 um / urad
        assert 0.02 < _display(k, sd) < 1.5  # an honest uncertainty for 0.5 um noise
    # the nest's offset is confounded with the sphere and the axis offsets, and is named so
    assert set(rep.unidentifiable) == {"EX0S", "EY0S", "EZ0T"}
    assert "sphere_x" in rep.unidentifiable["EX0S"] and "EX0C" in rep.unidentifiable["EX0S"]
    assert 0.45e-3 < rep.rms_after < 0.55e-3 and rep.rms_before > 5e-3
    # the sphere's real place (nominal + sphere_error of the simulator) is found alongside
    real_sphere = np.asarray(machine.table_centre) + sim.RTEST_SPHERE_OFFSET + np.array([0.012, -0.008, 0.005])
    assert np.max(np.abs(rep.details["sphere"] - real_sphere)) < 1e-3
    # the model states its kind and predicts the measurement
    assert rep.model.kind == kind
    again = cal.rtest_displacement(rep.model, machine, data, rep.details["sphere"])
    assert np.sqrt(np.mean((again - data.d) ** 2)) < 0.6e-3
    assert "rtest" in rep.summary()


def test_rtest_on_heads_too():
    """The same measurement and fit on the AB head (and a BC head-table): the spindle tilt about the
    pivot is named as confounded with the sphere and the axis offsets."""
    ab = load_machine()
    g = {"EY0A": 0.020, "EZ0A": -0.035, "EB0A": 30e-6, "EC0A": -45e-6, "EX0B": 0.015, "EZ0B": -0.025,
         "EA0B": 40e-6, "EC0B": -20e-6}
    rep = cal.calibrate_rtest(sim.simulate_rtest(ErrorModel(g), ab, sphere=(50.0, 20.0, -200.0), seed=1), ab)
    for k, v in g.items():
        assert abs(rep.parameters[k] - v) < 4 * rep.uncertainties[k], k
    assert set(rep.unidentifiable) == {"EX0S", "EY0S", "EZ0T", "EA0S", "EB0S"}


def test_rtest_file_round_trip(tmp_path):
    machine = table_machine("AC-table")
    data = sim.simulate_rtest(ErrorModel(dict(TRUTH["AC-table"]), kind="AC-table"), machine, seed=2)
    path = cal.write_rtest_csv(tmp_path / "r.csv", data, machine)
    assert path.read_text().splitlines()[0] == "A,C,X,Y,Z,dx,dy,dz"
    back = cal.read_rtest_csv(path, machine)
    assert np.allclose(back.q1, data.q1, atol=1e-10) and np.allclose(back.d, data.d, atol=1e-8)
    rep = cal.calibrate_rtest(path, machine)
    assert rep.model.meta["rtest"]["source"] == str(path)


def test_rtest_bad_inputs():
    machine = table_machine("AC-table")
    model = ErrorModel(dict(TRUTH["AC-table"]), kind="AC-table")
    # C at two angles only: the C axis line cannot be located
    A, C = np.meshgrid(np.radians([-90, -60, -30, 0]), np.radians([0, 90]), indexing="ij")
    with pytest.raises(InputError, match="C axis is at fewer than three distinct angles.*EX0C, EY0C, EA0C, EB0C"):
        cal.calibrate_rtest(sim.simulate_rtest(model, machine, poses=(A.ravel(), C.ravel())), machine)
    # the tilt never moves
    C = np.radians(np.arange(0, 360, 30))
    with pytest.raises(InputError, match="A axis is at fewer than three"):
        cal.calibrate_rtest(sim.simulate_rtest(model, machine, poses=(np.zeros_like(C), C)), machine)
    # too few poses for the unknowns
    with pytest.raises(InputError, match="too few poses"):
        cal.calibrate_rtest(sim.simulate_rtest(model, machine, poses=(np.radians([-60, -30, 0]),
                                                                      np.radians([0, 120, 240]))), machine)
    # duplicate poses
    data = sim.simulate_rtest(model, machine)
    data.q1[1], data.q2[1], data.X[1], data.Y[1], data.Z[1] = data.q1[0], data.q2[0], data.X[0], data.Y[0], data.Z[0]
    with pytest.raises(InputError, match="duplicate poses"):
        cal.calibrate_rtest(data, machine)
    # a base model of another kind, a parameter of another kind
    with pytest.raises(InputError, match="AB-head machine.*machine is AC-table"):
        cal.calibrate_rtest(sim.simulate_rtest(model, machine), machine, base=ErrorModel({"EY0A": 0.01}))
    with pytest.raises(InputError, match="EX0B are not errors of an AC-table"):
        cal.calibrate_rtest(sim.simulate_rtest(model, machine), machine, parameters=["EX0C", "EX0B"])
    # the probe calibration (columns A, B) is the AB head's
    with pytest.raises(InputError, match="R-test"):
        cal.calibrate_probe(cal.ProbeData(*(np.zeros(3),) * 5, np.zeros((3, 3))), machine)


def test_cli_simulate_and_calibrate_rtest_on_a_table(tmp_path, capsys):
    from camsmooth.cli.main import main
    from tests.conftest import ROOT

    machine = str(ROOT / "surfaces" / "dome_machine.toml")  # an A/C trunnion table
    ErrorModel(dict(TRUTH["AC-table"]), kind="AC-table").to_json(tmp_path / "m.json")
    r, out = str(tmp_path / "r.csv"), str(tmp_path / "cal.json")
    assert main(["simulate", "rtest", "--model", str(tmp_path / "m.json"), "--machine", machine, "--seed", "4",
                 "-o", r]) == 0
    assert main(["calibrate", "rtest", r, "--machine", machine, "-o", out]) == 0
    text = capsys.readouterr().out
    assert "EX0C" in text and "not determinable" in text
    fitted = ErrorModel.from_json(out)
    assert fitted.kind == "AC-table"
    assert abs(fitted.get("EX0C") - 0.015) < 0.5e-3
    # a table model on the default AB head is refused, naming both kinds
    assert main(["simulate", "rtest", "--model", str(tmp_path / "m.json"), "-o", str(tmp_path / "x.csv")]) == 2
    assert "for an AC-table machine, but the machine is AB-head" in capsys.readouterr().err


def test_cli_predict_reads_the_table_machines_axes(tmp_path, capsys):
    from camsmooth.cli.main import main
    from tests.conftest import ROOT

    machine_path = str(ROOT / "surfaces" / "dome_machine.toml")
    model = ErrorModel(dict(TRUTH["AC-table"]), kind="AC-table")
    model.to_json(tmp_path / "m.json")
    (tmp_path / "out.csv").write_text("A,C,X,Y,Z\n-30,45,10,20,30\n-60,90,0,0,0\n")
    assert main(["predict", str(tmp_path / "out.csv"), "--model", str(tmp_path / "m.json"), "--machine",
                 machine_path, "-o", str(tmp_path / "p.csv")]) == 0
    got = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1)
    from camsmooth.machine.kinematics import load_machine as load

    m = load(machine_path)
    pred = model.predict(m, np.radians([-30.0, -60.0]), np.radians([45.0, 90.0]), [10.0, 0.0], [20.0, 0.0],
                         [30.0, 0.0])
    assert np.allclose(got[:, 5:8], pred.tip, atol=1e-7) and np.allclose(got[:, 11], pred.tip_dev_um, atol=1e-6)
