"""LinuxCNC 2.9 as the reference controller of the trace diagnosis (issue 29, item 5).

A headless LinuxCNC simulation (camsmooth.controller.linuxcnc_sim.simulate: trivkins, 1 ms servo
period) runs a short X-only program (moves at 20, 50 and 80 mm/s between 0 and 10 mm with 0.4 s
dwells). HAL records, with ``sampler``/``halsampler`` at every servo cycle, the motion controller's
``joint.0.motor-pos-cmd`` as ``X_cmd`` and, as ``X_act``, that command passed through one of HAL's
own components, whose parameter is the truth the diagnosis must find (computed by HAL, not by
camsmooth's simulator):

- ``clean``: no component (X_act is the command): nothing may be named;
- ``lowpass``: ``lowpass`` with gain = 1 - exp(-T/tau), T = 1 ms, tau = 25 ms (its man page:
  a first-order lag behind a zero-order hold): ``servo_lag`` Kv_X = 40 1/s and, from the
  discretisation, ``time_offset`` -T/2 (``TRUTH``);
- ``limit2``: ``limit2`` with maxv = 35 mm/s (the output moves at most maxv T a cycle):
  ``velocity_limit`` vmax_X = 35 mm/s;
- ``accel``: ``ddt`` -> ``limit2`` (maxv = amax = 1000 mm/s^2 on the velocity) -> ``integ``: the
  velocity chases the commanded one changing by at most amax a second: ``acceleration_limit``
  amax_X = 1000 mm/s^2 (and time_offset -T/2, below);
- ``limit3``: ``limit3`` with maxa = 1000 mm/s^2 (and a maxv the program never reaches): a
  planner that catches up with its input and stops on it, outside the library (no term models
  the catch-up): expected nothing named and the rest left unexplained;
- ``delay``: a chain of 13 ``scale`` components (gain 1) run in the servo thread in the reverse
  of their signal order, each reading the previous cycle's output of the one before: X_act(n) =
  X_cmd(n - 12), a pure delay of 12 ms: ``time_offset`` offset_s = 0.012 s;
- ``quantise``: ``scale`` (gain 1/q, offset 0.5) -> ``conv_float_s32`` -> ``conv_s32_float`` ->
  ``scale`` (gain q), q = 5/2048 mm (conv_float_s32 truncates; the offset makes it round):
  ``quantisation`` q_X = 2.44 um;
- ``backlash``: the INI's ``BACKLASH = 0.05`` (mm) and, as X_cmd, the motor's command (motion's
  backlash compensation adds b/2 in the direction of motion) against, as X_act, the joint's own
  ``joint.0.pos-cmd``: the table of a mechanism with that backlash: ``backlash`` backlash_X = 0.05 mm;
- ``delay_y``: X and Y move together (Y to 0.7 of X's targets); X_act is X's command, Y_act Y's
  through the delay chain: one axis's own delay, ``transport_delay`` delay_Y = 0.012 s.

Each trace is written in the pinned layout (``t,X_cmd,X_act``, s and mm, values as halsampler
prints them) and diagnosed with ``camsmooth diagnose --trace FILE --out FINDINGS.json``; the
script prints what is named, its value against the component's and the held-out RMS.

    .venv/bin/python benchmarks/hal_reference.py [--out DIR] [--keep-tests] [CASE ...]

``--keep-tests`` copies the clean, lowpass, quantise and backlash traces to tests/data/hal/ (the recorded
traces tests/test_hal_reference.py diagnoses). Needs linuxcnc-uspace; runs as root through the
simulation's own isolation (each run about 10 s of real time).
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from camsmooth.controller.linuxcnc_sim import SERVO_PERIOD_S, linuxcnc_missing, simulate  # noqa: E402
from camsmooth.machine.kinematics import load_machine  # noqa: E402

TAU_S = 0.025
VMAX = 35.0
AMAX = 1000.0
DELAY_CYCLES = 12
BACKLASH_MM = 0.05
#: an encoder of 2048 counts a turn (512 lines, x4) on a 5 mm lead; a step such as 3 um, of which the
#: planner's positions (multiples of 0.5 um: 0.5 a T^2 = 1.5 um at 3000 mm/s^2) hit half-steps, rounds
#: ties one way or the other by the last bit of the command: a coin no model predicts
Q_MM = 5.0 / 2048.0

#: the measurement noise (mm, white, seeded) added to X_act for the noisy variant of each case, as an
#: encoder and its electronics add it; HAL's own output is exact to the 1e-6 mm halsampler prints
NOISE_MM = 0.001
#: case -> (expected named terms, [(term, parameter, truth)]). HAL's lowpass computes
#: out(k) = out(k-1) + gain (in(k) - out(k-1)) from this cycle's command: with the zero-order hold
#: of its man page, a continuous lag that runs T/2 ahead of the command, hence time_offset = -T/2;
#: the ddt -> limit2 -> integ chain likewise moves at this cycle's limited velocity over the whole
#: cycle (the velocity steps at the cycle's start, where the term's ramps across it): -T/2 as well.
TRUTH: dict[str, tuple[list[str], list[tuple[str, str, float]]]] = {
    "clean": ([], []),
    "lowpass": (["servo_lag", "time_offset"], [("servo_lag", "Kv_X", 1.0 / TAU_S),
                                               ("time_offset", "offset_s", -0.5 * SERVO_PERIOD_S)]),
    "limit2": (["velocity_limit"], [("velocity_limit", "vmax_X", VMAX)]),
    "accel": (["acceleration_limit", "time_offset"], [("acceleration_limit", "amax_X", AMAX),
                                                      ("time_offset", "offset_s", -0.5 * SERVO_PERIOD_S)]),
    "limit3": ([], []),
    "delay": (["time_offset"], [("time_offset", "offset_s", DELAY_CYCLES * SERVO_PERIOD_S)]),
    "quantise": (["quantisation"], [("quantisation", "q_X", Q_MM)]),
    "backlash": (["backlash"], [("backlash", "backlash_X", BACKLASH_MM)]),
    "delay_y": (["transport_delay"], [("transport_delay", "delay_Y", DELAY_CYCLES * SERVO_PERIOD_S)]),
}
#: lines added to every [JOINT_n] section of the INI, per case
JOINT_INI = {"backlash": f"BACKLASH = {BACKLASH_MM}\n"}
#: the quantiser is the measurement: noise after it would not be an encoder's, so it runs raw only
RAW_ONLY = ("quantise",)
KEEP = ("clean", "lowpass", "quantise", "backlash")

_HEAD = """\
loadrt [KINS]KINEMATICS
loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
loadrt sampler depth=200000 cfg=fffffs
{load}
addf motion-command-handler servo-thread
addf motion-controller servo-thread
{addf}
addf sampler.0 servo-thread
{setp}
net j0 joint.0.motor-pos-cmd => joint.0.motor-pos-fb sampler.0.pin.0 {first_in}
net xact {act_out} => sampler.0.pin.1
net j1 joint.1.motor-pos-cmd => joint.1.motor-pos-fb
net j2 joint.2.motor-pos-cmd => joint.2.motor-pos-fb sampler.0.pin.2
net j3 joint.3.motor-pos-cmd => joint.3.motor-pos-fb sampler.0.pin.3
net j4 joint.4.motor-pos-cmd => joint.4.motor-pos-fb sampler.0.pin.4
net line motion.program-line => sampler.0.pin.5
net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed
{nets}
"""


def hal_text(case: str) -> str:
    """The HAL file of ``case`` (module docstring): the component between motor-pos-cmd and X_act."""
    load, addf, setp, nets = [], [], [], []
    if case == "clean":
        # the command itself on both pins: one net may not feed the same pin twice, so a unit gain
        load.append("loadrt scale names=same")
        addf.append("addf same servo-thread")
        setp.append("setp same.gain 1.0")
        first_in, act_out = "same.in", "same.out"
    elif case == "lowpass":
        load.append("loadrt lowpass count=1")
        addf.append("addf lowpass.0 servo-thread")
        setp.append(f"setp lowpass.0.gain {1.0 - math.exp(-SERVO_PERIOD_S / TAU_S):.12f}")
        first_in, act_out = "lowpass.0.in", "lowpass.0.out"
    elif case == "limit2":
        load.append("loadrt limit2 count=1")
        addf.append("addf limit2.0 servo-thread")
        setp.append(f"setp limit2.0.maxv {VMAX}")
        first_in, act_out = "limit2.0.in", "limit2.0.out"
    elif case == "accel":
        # the velocity chases the commanded one changing by at most amax a second: ddt, then a rate
        # limit of amax on the velocity, then the integral back to a position
        load += ["loadrt ddt count=1", "loadrt limit2 count=1", "loadrt integ count=1"]
        addf += ["addf ddt.0 servo-thread", "addf limit2.0 servo-thread", "addf integ.0 servo-thread"]
        setp.append(f"setp limit2.0.maxv {AMAX}")
        nets += ["net xvel ddt.0.out => limit2.0.in", "net xvel-lim limit2.0.out => integ.0.in"]
        first_in, act_out = "ddt.0.in", "integ.0.out"
    elif case == "limit3":
        load.append("loadrt limit3 count=1")
        addf.append("addf limit3.0 servo-thread")
        setp += [f"setp limit3.0.maxa {AMAX}", "setp limit3.0.maxv 1e6"]
        first_in, act_out = "limit3.0.in", "limit3.0.out"
    elif case == "delay":
        n = DELAY_CYCLES + 1
        load.append(f"loadrt scale count={n}")
        addf += [f"addf scale.{k} servo-thread" for k in reversed(range(n))]
        setp += [f"setp scale.{k}.gain 1.0" for k in range(n)]
        nets += [f"net d{k} scale.{k - 1}.out => scale.{k}.in" for k in range(1, n)]
        first_in, act_out = "scale.0.in", f"scale.{n - 1}.out"
    elif case == "backlash":
        # the motion controller's backlash compensation: motor-pos-cmd = pos-cmd + b/2 in the direction
        # of motion. A mechanism with that backlash puts the table at pos-cmd while the motor is at
        # motor-pos-cmd: act = cmd - (b/2) sign(direction), the backlash term exactly
        first_in, act_out = "", "joint.0.pos-cmd"
    elif case == "quantise":
        load += ["loadrt scale names=qin,qout", "loadrt conv_float_s32 count=1", "loadrt conv_s32_float count=1"]
        addf += ["addf qin servo-thread", "addf conv-float-s32.0 servo-thread", "addf conv-s32-float.0 servo-thread",
                 "addf qout servo-thread"]
        setp += [f"setp qin.gain {1.0 / Q_MM:.12g}", "setp qin.offset 0.5", f"setp qout.gain {Q_MM:.12g}"]
        nets += ["net qcounts-f qin.out => conv-float-s32.0.in",
                 "net qcounts conv-float-s32.0.out => conv-s32-float.0.in",
                 "net qcounts-back conv-s32-float.0.out => qout.in"]
        first_in, act_out = "qin.in", "qout.out"
    else:
        raise ValueError(case)
    return _HEAD.format(load="\n".join(load), addf="\n".join(addf), setp="\n".join(setp), first_in=first_in,
                        act_out=act_out, nets="\n".join(nets))


def program(two_axes: bool = False) -> str:
    """X-only moves at 20, 50 and 80 mm/s between 0 and 10 mm (and 10.5 mm) with 0.4 s dwells;
    ``two_axes``: Y moves with X to 0.7 of its targets."""
    lines = ["G21 G90 G94 G17", "G64", "G4 P0.4"]
    for i in range(6):
        v = (20.0, 50.0, 80.0)[i % 3]
        tgt = (10.0 if i % 2 == 0 else 0.0) + (0.5 * i if i % 4 == 0 else 0.0)
        y = f" Y{0.7 * tgt:.3f}" if two_axes else ""
        lines += [f"G1 X{tgt:.3f}{y} F{v * 60:.0f}", "G4 P0.4"]
    return "\n".join(lines + ["M2"]) + "\n"


def two_axis_hal(delay_cycles: int) -> str:
    """X and Y sampled (pins 0-3: X_cmd, X_act, Y_cmd, Y_act), X_act the command itself, Y_act the
    command through the delay chain of the ``delay`` case (``hal_text``)."""
    n = delay_cycles + 1
    return "\n".join([
        "loadrt [KINS]KINEMATICS",
        "loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS",
        "loadrt sampler depth=200000 cfg=fffffs", f"loadrt scale count={n}",
        "addf motion-command-handler servo-thread", "addf motion-controller servo-thread",
        *[f"addf scale.{k} servo-thread" for k in reversed(range(n))], "addf sampler.0 servo-thread",
        *[f"setp scale.{k}.gain 1.0" for k in range(n)],
        *[f"net d{k} scale.{k - 1}.out => scale.{k}.in" for k in range(1, n)],
        "net j0 joint.0.motor-pos-cmd => joint.0.motor-pos-fb sampler.0.pin.0 sampler.0.pin.1",
        "net j1 joint.1.motor-pos-cmd => joint.1.motor-pos-fb sampler.0.pin.2 scale.0.in",
        f"net yact scale.{n - 1}.out => sampler.0.pin.3",
        "net j2 joint.2.motor-pos-cmd => joint.2.motor-pos-fb sampler.0.pin.4",
        "net j3 joint.3.motor-pos-cmd => joint.3.motor-pos-fb",
        "net j4 joint.4.motor-pos-cmd => joint.4.motor-pos-fb",
        "net line motion.program-line => sampler.0.pin.5",
        "net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in",
        "net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared",
        "net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed", ""])


def record(case: str, out: Path) -> Path:
    """Run the program on the simulation with ``case``'s HAL and write its trace CSV (t, X_cmd,
    X_act[, Y_cmd, Y_act]), from the first servo cycle the program runs to the last."""
    two = case == "delay_y"
    prog = out / "program.ngc"
    prog.write_text(program(two))
    hal = two_axis_hal(DELAY_CYCLES) if two else hal_text(case)
    run = simulate(prog, load_machine(None), timeout=60, hal=hal, joint_ini=JOINT_INI.get(case, ""))
    on = np.flatnonzero(run.line > 0)
    k0, k1 = int(on[0]), int(on[-1]) + 1
    t = run.t[k0:k1] - run.t[k0]
    return write(out / f"{case}.csv", t, run.joints[k0:k1, :4 if two else 2])


def write(path: Path, t: np.ndarray, cols: np.ndarray) -> Path:
    """t (s) and the columns X_cmd, X_act[, Y_cmd, Y_act] (mm, 6 decimals as halsampler prints them)."""
    head = ["t", "X_cmd", "X_act", "Y_cmd", "Y_act"][:1 + cols.shape[1]]
    with open(path, "w", encoding="utf-8") as f:
        f.write(",".join(head) + "\n")
        for i in range(len(t)):
            f.write(f"{t[i]:.3f}," + ",".join(f"{v:.6f}" for v in cols[i]) + "\n")
    return path


def noisy(path: Path, sd: float, seed: int = 0) -> Path:
    """The trace with white noise of ``sd`` mm added to each actual (written to 6 decimals, as recorded)."""
    d = np.loadtxt(path, delimiter=",", skiprows=1)
    cols = d[:, 1:].copy()
    cols[:, 1::2] += np.random.default_rng(seed).normal(0.0, sd, (len(d), cols.shape[1] // 2))
    return write(path.with_name(path.stem + "_noise.csv"), d[:, 0], cols)


def judge(case: str, f: dict) -> tuple[bool, str]:
    """(as expected, the line printed): the named set against the case's, each value against its truth."""
    want, checks = TRUTH[case]
    named = f["named"]
    ok = sorted(named) == sorted(want)
    text = f"named {', '.join(named) or 'nothing'}"
    for name, key, truth in checks:
        e = next((e for e in f["effects"] if e["name"] == name), None)
        if e is None:
            continue
        v = e["parameters"][key]
        err = abs(v / truth - 1.0)
        ok &= err <= 0.10
        ch = f"{key.rsplit('_', 1)[-1]}_act" if key.endswith(("_X", "_Y")) else "X_act"
        hb, ha = e["heldout_rms_before"][ch], e["heldout_rms_after"][ch]
        text += f"; {key} = {v:.5g} (truth {truth:.5g}, {100 * err:.1f}%; held-out {hb:.3g} -> {ha:.3g} mm)"
    if not named and f["unexplained"]["count"]:
        text += f"; {f['unexplained']['count']} interval(s) left unexplained"
    return ok, text


def diagnose(path: Path) -> dict:
    """``camsmooth diagnose --trace`` on the file, as a user runs it; its FINDINGS.json."""
    js = path.with_suffix(".json")
    proc = subprocess.run([sys.executable, "-m", "camsmooth", "diagnose", "--trace", str(path), "--out", str(js)],
                          capture_output=True, text=True, cwd=ROOT)
    if proc.returncode != 0:
        raise RuntimeError(f"camsmooth diagnose failed on {path} (exit {proc.returncode}): {proc.stderr.strip()}")
    return json.loads(js.read_text())


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("cases", nargs="*", default=list(TRUTH), help=f"of {', '.join(TRUTH)}")
    ap.add_argument("--out", type=Path, help="folder for the traces and findings (default: a temporary one)")
    ap.add_argument("--keep-tests", action="store_true", help=f"copy {', '.join(KEEP)} to tests/data/hal/")
    args = ap.parse_args(argv)
    missing = linuxcnc_missing()
    if missing:
        print(f"skipped: {missing}")
        return 0
    out = args.out or Path(tempfile.mkdtemp(prefix="hal-reference-"))
    out.mkdir(parents=True, exist_ok=True)
    print(f"{'case':9s} {'trace':5s} {'samples':>7s} {'record s':>8s} {'diag s':>6s}  named, value (truth)")
    ok_all = True
    for case in args.cases:
        t0 = time.perf_counter()
        path = record(case, out)
        t1 = time.perf_counter()
        variants = [("raw", path)] if case in RAW_ONLY else [("raw", path), ("noise", noisy(path, NOISE_MM))]
        n = len(np.loadtxt(path, delimiter=",", skiprows=1))
        for label, p in variants:
            t2 = time.perf_counter()
            ok, text = judge(case, diagnose(p))
            # the verdict is the noisy trace's (a noise-free trace also shows the model's discretisation)
            ok_all &= ok or (label == "raw" and case not in RAW_ONLY)
            print(f"{case:9s} {label:5s} {n:7d} {t1 - t0:8.1f} {time.perf_counter() - t2:6.1f}  "
                  f"{'ok  ' if ok else 'MISS'} {text}")
        if args.keep_tests and case in KEEP:
            dst = ROOT / "tests" / "data" / "hal"
            dst.mkdir(parents=True, exist_ok=True)
            shutil.copy(path, dst / path.name)
    print(f"traces and findings in {out}")
    return 0 if ok_all else 1


if __name__ == "__main__":
    raise SystemExit(main())
