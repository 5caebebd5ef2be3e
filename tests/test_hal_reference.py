"""The trace diagnosis on traces LinuxCNC 2.9 recorded (benchmarks/hal_reference.py, tests/data/hal/
SOURCES.md): the motion controller's X command and, as X_act, that command through one of HAL's own
components. Each recording is first checked against the component's documented equation written
here (so the truth is HAL's, not camsmooth's simulator); then the diagnosis names the component's
effect with its value within 10%, and nothing on the clean recording."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from camsmooth.diagnosis.trace import diagnose_trace, read_trace

DATA = Path(__file__).parent / "data" / "hal"
T = 0.001  # s, the simulation's servo period
TAU = 0.025  # s, the lowpass's time constant: gain = 1 - exp(-T / TAU)
Q = 5.0 / 2048.0  # mm, the quantiser's step (2048 counts on a 5 mm lead)
NOISE = 0.001  # mm, the measurement noise added to the lowpass recording (an encoder's)
BACKLASH = 0.05  # mm, the INI's BACKLASH


def load(name: str) -> np.ndarray:
    return np.loadtxt(DATA / f"{name}.csv", delimiter=",", skiprows=1)


def effect(f: dict, name: str) -> dict:
    return next(e for e in f["effects"] if e["name"] == name)


def test_the_recordings_are_what_the_hal_components_compute():
    """lowpass: out(k) = out(k-1) + gain (in(k) - out(k-1)) (its man page); the quantiser: in rounded
    to the nearest multiple of Q; clean: act = cmd. To the 1e-6 mm halsampler prints."""
    t, u, y = load("lowpass").T
    assert np.allclose(np.diff(t), T) and np.ptp(u) > 10.0
    g = 1.0 - math.exp(-T / TAU)
    z = np.empty_like(u)
    z[0] = y[0]
    for k in range(1, len(u)):
        z[k] = z[k - 1] + g * (u[k] - z[k - 1])
    assert np.max(np.abs(y - z)) < 2e-6
    _, u, y = load("quantise").T
    assert np.max(np.abs(y - Q * np.round(u / Q))) < 1.5e-6  # rounds (not truncates)
    assert len(np.unique(y)) > 100
    _, u, y = load("clean").T
    assert np.array_equal(u, y)
    # backlash compensation: motor (X_cmd) = joint (X_act) + b/2 in the direction of motion, held at rest
    _, u, y = load("backlash").T
    assert np.max(np.abs(u - y)) == pytest.approx(BACKLASH / 2, abs=2e-6)
    rest = np.r_[False, np.diff(u) == 0.0]
    assert np.all(np.isclose(np.abs(u - y)[rest], BACKLASH / 2, atol=2e-6) | (np.abs(u - y)[rest] < 2e-6))


def test_a_clean_recording_names_nothing():
    f = diagnose_trace(read_trace(str(DATA / "clean.csv"))).findings
    assert f["named"] == []


def test_the_hal_lowpass_is_named_as_its_lag(tmp_path):
    """With 1 um of measurement noise (seeded): servo_lag Kv = 1/TAU, and the discrete filter's
    half-period lead (it uses this cycle's command) as a clock offset of -T/2."""
    t, u, y = load("lowpass").T
    y = y + np.random.default_rng(0).normal(0.0, NOISE, len(y))
    path = tmp_path / "lowpass_noise.csv"
    np.savetxt(path, np.column_stack([t, u, y]), delimiter=",", header="t,X_cmd,X_act", comments="", fmt="%.6f")
    f = diagnose_trace(read_trace(str(path))).findings
    assert sorted(f["named"]) == ["servo_lag", "time_offset"], f["named"]
    assert effect(f, "servo_lag")["parameters"]["Kv_X"] == pytest.approx(1.0 / TAU, rel=0.10)
    assert effect(f, "time_offset")["parameters"]["offset_s"] == pytest.approx(-0.5 * T, rel=0.10)
    assert f["heldout"]["rms_after"]["X_act"] < 1.5 * NOISE


def test_the_joint_backlash_is_named_with_its_size():
    f = diagnose_trace(read_trace(str(DATA / "backlash.csv"))).findings
    assert f["named"] == ["backlash"], f["named"]
    assert effect(f, "backlash")["parameters"]["backlash_X"] == pytest.approx(BACKLASH, rel=0.10)


def test_the_hal_quantiser_is_named_with_its_step():
    f = diagnose_trace(read_trace(str(DATA / "quantise.csv"))).findings
    assert f["named"] == ["quantisation"], f["named"]
    p = effect(f, "quantisation")["parameters"]
    assert p["q_X"] == pytest.approx(Q, rel=0.10) and p["share_X"] == pytest.approx(1.0, rel=0.10)
