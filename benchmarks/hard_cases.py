"""Harder concealed-effect cases (issue 20.7), scored by ``bench_concealed.py --set hard``: built on
the closed-form recordings of benchmarks/synthetic.py (independent of camsmooth's simulator).

* mixtures: two or three library effects at once on one program;
* weak: one effect whose RMS on its strongest channel is only 3, 4.5 or 6 times the white noise
  (the noise is set from the noise-free effect, ``snr``); parameters checked within 25%;
* coloured nulls: no effect, AR(1) noise (lag-1 correlation ``colour``) plus a little white noise;
* outside the library: an effect no term describes (a periodic pitch error of X on a laser run, a
  Z sag of the tip growing with X and the A tilt, a pitch error beside a real reversal). Right
  when exactly ``named`` is named (often nothing) and the rest is reported as 'unexplained'.

A case is right under the rule of ``synthetic.check`` (exactly the hidden terms, or the pair
reported as 'cannot tell apart'; parameters within ``tol``), and for the outside cases the
findings must also hold an 'unexplained' effect.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import lfilter

from benchmarks.synthetic import (
    EFFECTS,
    PROGRAMS,
    Case,
    _settings,
    check,
    program_for,
    record,
)
from camsmooth.diagnosis.recordings import Program, Recording


@dataclass(frozen=True)
class HardCase:
    """A harder case: the base ``Case`` (program kind, truth, expected names, label, seed), and
    snr (noise sigma = strongest channel's effect RMS / snr; None keeps the case's noise),
    colour (AR(1) lag-1 correlation of the noise, 0 for white), outside (the name of an effect
    outside the library added to the recording, '' for none), tol (relative parameter
    tolerance)."""

    case: Case
    snr: float | None = None
    colour: float = 0.0
    outside: str = ""
    tol: float = 0.10
    group: str = "mixture"
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        return self.case.label

    @property
    def seed(self) -> int:
        return self.case.seed

    @property
    def kind(self) -> str:
        return self.case.kind


def _outside(name: str, program: Program, rec: Recording) -> None:
    """Add the effect ``name`` (outside the library; mm) to the recording in place."""
    X = program.axes["X"]
    if name == "pitch":  # a periodic pitch error of X: 20 um at 13 mm and 10 um at 7.3 mm
        x = rec.channels["X_act"]
        rec.channels["X_act"] = x + 0.02 * np.sin(2 * np.pi * x / 13.0) + 0.01 * np.sin(2 * np.pi * x / 7.3 + 1.0)
    elif name == "big pitch":  # the laser log: the rest dwarfs the reversal
        x = rec.channels["X_act"]
        rec.channels["X_act"] = x + 0.1 * np.sin(2 * np.pi * x / 13.0) + 0.05 * np.sin(2 * np.pi * x / 7.3 + 1.0)
    elif name == "sag":  # the tip sags in Z with X and with the A tilt
        rec.channels["tip_z"] = rec.channels["tip_z"] - 0.01 * (1 + 2 * X / 10.0) * np.sin(program.axes["A"])
    elif name == "screw":  # a screw pitch error of X seen on the axis (period 5 mm)
        x = rec.channels["X_act"]
        rec.channels["X_act"] = x + 0.02 * np.sin(2 * np.pi * x / 5.0)
    else:
        raise ValueError(f"unknown outside effect {name!r}")


def _noise_sigma(case: Case, program: Program, snr: float) -> float:
    """The white-noise sigma (mm) that puts the effect's RMS on its strongest length channel at
    ``snr`` sigmas."""
    chans, _, _ = PROGRAMS[case.kind]
    clean = record(program, case.truth, channels=chans, seed=0)
    base = record(program, {}, channels=chans, seed=0)
    rms = [float(np.sqrt(np.mean((clean.channels[c] - base.channels[c]) ** 2)))
           for c in clean.channels if c in ("X_act", "Y_act", "Z_act", "tip_x", "tip_y", "tip_z")]
    return max(rms) / snr


def recording_for_hard(h: HardCase, program: Program) -> Recording:
    """The recording of a hard case (module docstring)."""
    case = h.case
    chans, _, noise = PROGRAMS[case.kind]
    sig = _noise_sigma(case, program, h.snr) if h.snr else (case.noise if case.noise is not None else noise)
    rng = np.random.default_rng(case.seed + 2000)
    white = sig if not h.colour else 0.3 * sig
    rec = record(program, case.truth, channels=chans,
                 noise={"axes": white, "tip": white, "rotary": white * 1e-3, "axis": white * 1e-3},
                 seed=case.seed + 1000)
    if h.colour:
        rho = h.colour
        for c in rec.channels:
            s = sig * (1e-3 if c in ("A_act", "B_act", "axis_i", "axis_j", "axis_k") else 1.0)
            rec.channels[c] = rec.channels[c] + lfilter([1.0], [1.0, -rho],
                                                        rng.normal(0.0, s * math.sqrt(1 - rho * rho), len(rec.t)))
    if h.outside:
        _outside(h.outside, program, rec)
    return rec


def hard_cases(seeds: Sequence[int] = (1, 2)) -> list[HardCase]:
    """The harder catalogue (module docstring), per seed."""
    out: list[HardCase] = []
    xyz = ("X", "Y", "Z")
    for s in seeds:
        out += [
            # mixtures of two or three effects
            HardCase(Case("lines", _settings("servo_lag", "backlash", axes=xyz), ("servo_lag", "backlash"),
                          "mix: lag + backlash, 500 Hz", seed=s)),
            HardCase(Case("rotary", {**_settings("servo_lag"), **EFFECTS["spindle_tilt"]},
                          ("servo_lag", "spindle_tilt"), "mix: lag + spindle tilt", seed=s)),
            HardCase(Case("grid", {**EFFECTS["linear_positioning"], **EFFECTS["linear_squareness"],
                                   **_settings("backlash", axes=xyz)},
                          ("linear_positioning", "linear_squareness", "backlash"),
                          "mix: positioning + squareness + backlash", seed=s)),
            HardCase(Case("thermal", {**EFFECTS["thermal_machine"], **EFFECTS["rotary_squareness"]},
                          ("thermal_machine", "rotary_squareness"), "mix: machine growth + rotary squareness",
                          seed=s)),
            # weak effects: 3 to 6 noise sigmas RMS on the strongest channel
            *[HardCase(Case("lines", {"Kv_X": 40.0}, ("servo_lag",), f"weak: lag X at {k:g} sigma", seed=s),
                       snr=k, tol=0.25, group="weak") for k in (3.0, 6.0)],
            *[HardCase(Case("lines", {"backlash_X": 0.012}, ("backlash",), f"weak: backlash X at {k:g} sigma", seed=s),
                       snr=k, tol=0.25, group="weak") for k in (3.0, 6.0)],
            *[HardCase(Case("lines", {"offset_s": 0.005}, ("time_offset",), f"weak: offset at {k:g} sigma", seed=s),
                       snr=k, tol=0.25, group="weak") for k in (4.5, 6.0)],
            *[HardCase(Case("rotary", EFFECTS["tool_length"], ("tool_length",), f"weak: tool length at {k:g} sigma",
                            seed=s), snr=k, tol=0.25, group="weak") for k in (3.0, 6.0)],
            *[HardCase(Case("laser", {"EXX": 3.3e-3}, ("linear_positioning",), f"weak: positioning at {k:g} sigma",
                            seed=s), snr=k, tol=0.25, group="weak") for k in (3.0, 6.0)],
            # coloured-noise nulls
            *[HardCase(Case(kind, {}, (), f"coloured null: {kind}, rho {rho:g}", seed=s), colour=rho, group="null")
              for kind, rho in (("lines", 0.9), ("lines", 0.99), ("laser", 0.95), ("grid", 0.9), ("rotary", 0.9))],
            # outside the library: right answer 'unexplained' (beside the named ones)
            HardCase(Case("laser", {}, (), "outside: pitch error, laser run", seed=s), outside="pitch",
                     group="outside"),
            HardCase(Case("laser", {"backlash_X": 0.01865}, ("backlash",), "outside: large pitch + reversal 18.65 um",
                          seed=s), outside="big pitch", tol=0.25, group="outside"),
            HardCase(Case("rotary", {}, (), "outside: Z sag with X and tilt", seed=s), outside="sag", group="outside"),
            HardCase(Case("lines", {}, (), "outside: screw pitch of X", seed=s), outside="screw", group="outside"),
        ]
    return out


def run_hard_case(h: HardCase, diagnose: Callable[..., Any], options: Any = None) -> dict[str, Any]:
    """Make the program and recording, diagnose them, check (module docstring)."""
    program = program_for(h.case)
    rec = recording_for_hard(h, program)
    t0 = time.perf_counter()
    f = diagnose(program, rec, options=options).findings
    dt = time.perf_counter() - t0
    out = check(f, h.case, tol=h.tol)
    if h.outside:
        out["exact"] = out["exact"] and any(e["name"] == "unexplained" for e in f["effects"])
    out.update(case=h.case, hard=h, seconds=dt, samples=len(rec.t),
               none_measurable={e["name"]: e.get("none_measurable", []) for e in f["effects"]},
               apart_pairs=[(e["chosen"], e["alternative"]) for e in f.get("equivalences", [])])
    return out
