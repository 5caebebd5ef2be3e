"""Diagnosis on a table-table machine (issue 18): a recording of an A/C trunnion whose C axis line
is displaced and whose C servo lags, made here by closed forms written for this test (the
table's rotations about its displaced axis lines, a first-order lag by scipy), is diagnosed with
the machine file: the C location error and the C servo lag are named and sized."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.synthetic import _lag
from camsmooth.diagnosis.findings import diagnose
from camsmooth.diagnosis.recordings import Program, Recording
from camsmooth.machine.kinematics import machine_from_dict

CENTRE = np.array([0.0, 0.0, -20.0])
AC = {"machine": {"kind": "AC-table", "table_centre": CENTRE.tolist()}, "axis": {
    "A": {"min": -110.0, "max": 30.0, "vmax": 60.0, "amax": 300.0}, "C": {"vmax": 180.0, "amax": 900.0}}}


def _rx(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def _rz(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def _program(rate: float = 100.0, duration: float = 24.0) -> Program:
    """C turning back and forth over 300 deg at varying speed, A tilting, X Y Z small moves."""
    t = np.arange(0.0, duration, 1.0 / rate)
    C = np.radians(150.0) * np.sin(2 * np.pi * t / 8.0) + np.radians(20.0) * np.sin(2 * np.pi * t / 1.7)
    A = np.radians(-35.0) + np.radians(25.0) * np.sin(2 * np.pi * t / 6.0)
    X = 20.0 * np.sin(2 * np.pi * t / 5.0)
    Y = 15.0 * np.cos(2 * np.pi * t / 7.0)
    Z = 5.0 * np.sin(2 * np.pi * t / 3.0)
    return Program(t=t, axes={"X": X, "Y": Y, "Z": Z, "A": A, "C": C})


def _record(prog: Program, ex: float, ey: float, kv_c: float, seed: int) -> Recording:
    """Tool tip in the workpiece frame: tip = c_C + Rz(C)(c + Rx(A)(P - c) - c_C), with the C axis
    line through c_C = c + (ex, ey, 0) (the table seen from the workpiece; the tip P carried by X,
    Y, Z); C lags its command by 1 / (s / Kv + 1). Axis channels: the carriages' positions."""
    rng = np.random.default_rng(seed)
    t = prog.t
    ax = {k: v.copy() for k, v in prog.axes.items()}
    ax["C"] = _lag(t, prog.axes["C"], kv_c)
    P = np.column_stack([ax["X"], ax["Y"], ax["Z"]])
    cC = CENTRE + np.array([ex, ey, 0.0])
    inner = CENTRE + np.einsum("nij,nj->ni", _rx(ax["A"]), P - CENTRE)
    tip = cC + np.einsum("nij,nj->ni", _rz(ax["C"]), inner - cC)
    ch = {f"tip_{k}": tip[:, i] + rng.normal(0, 5e-4, len(t)) for i, k in enumerate("xyz")}
    ch.update({f"{a}_act": ax[a] + rng.normal(0, 5e-4 if a in "XYZ" else 5e-6, len(t)) for a in ax})
    return Recording(t=t, channels=ch)


def test_the_c_axis_line_and_c_lag_of_an_ac_table_are_named_and_sized():
    m = machine_from_dict(AC)
    prog = _program()
    rec = _record(prog, ex=0.03, ey=-0.02, kv_c=40.0, seed=4)
    f = diagnose(prog, rec, machine=m).findings
    named = set(f["named"])
    assert {"rotary_location", "servo_lag"} <= named, {r["name"]: r["reason"] for r in f["rejected"]}
    eff = {e["name"]: e for e in f["effects"]}
    loc = eff["rotary_location"]["parameters"]
    assert loc["EX0C"] == pytest.approx(0.03, rel=0.1) and loc["EY0C"] == pytest.approx(-0.02, rel=0.1)
    lag = eff["servo_lag"]["parameters"]
    assert lag["Kv_C"] == pytest.approx(40.0, rel=0.1)


def test_a_clean_ac_table_recording_names_nothing():
    m = machine_from_dict(AC)
    prog = _program()
    f = diagnose(prog, _record(prog, ex=0.0, ey=0.0, kv_c=0.0, seed=5), machine=m).findings
    assert f["named"] == [], f["named"]


def test_the_command_line_simulates_and_diagnoses_a_table_machine(tmp_path, capsys):
    """`camsmooth simulate recording` and `camsmooth diagnose` with the dome's A/C machine file:
    the C location error and lag set on the command line are what diagnose names; probing (an
    AB-head measurement) on that machine is refused as bad input, naming the R-test."""
    import json
    from pathlib import Path

    from camsmooth.cli.main import main as cli_main
    from camsmooth.diagnosis.recordings import write_program_csv

    machine = str(Path(__file__).resolve().parents[1] / "surfaces" / "dome_machine.toml")
    write_program_csv(tmp_path / "p.csv", _program(rate=50.0, duration=12.0))
    assert cli_main(["simulate", "recording", "--program", str(tmp_path / "p.csv"), "--machine", machine,
                     "--set", "EX0C=0.03", "--set", "Kv_C=40", "--channels", "axes,tip", "--noise", "0.0005",
                     "--noise-deg", "0.0003", "-o", str(tmp_path / "r.csv")]) == 0
    assert cli_main(["diagnose", "--program", str(tmp_path / "p.csv"), "--recording", str(tmp_path / "r.csv"),
                     "--machine", machine, "--out", str(tmp_path / "f.json"), "--quiet"]) == 0
    f = json.loads((tmp_path / "f.json").read_text())
    eff = {e["name"]: e for e in f["effects"]}
    assert eff["rotary_location"]["parameters"]["EX0C"] == pytest.approx(0.03, rel=0.1)
    capsys.readouterr()
    assert cli_main(["simulate", "probe", "--model", str(tmp_path / "f.json"), "--machine", machine,
                     "-o", str(tmp_path / "probe.csv")]) == 2
    assert "simulate rtest" in capsys.readouterr().err and not (tmp_path / "probe.csv").exists()
