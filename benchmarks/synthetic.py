"""Synthetic programs and recordings for the diagnosis benchmarks and tests, made with physics
written out here, independently of camsmooth's own simulator (issue 11): a bug in the library's
simulator cannot hide in a recording made by the same code.

* ``make_program``: rest-to-rest moves with trapezoidal speed ('lines'), circles, A/B sweeps
  ('rotary'), spindle-speed steps ('spindle'), a pose grid repeated while the spindle switches on
  and off ('thermal'), an ISO 230-2 style bidirectional positioning run of X ('laser') and X, Y, Z
  moves over a larger volume ('grid').
* ``record``: the recorded channels from closed forms: the servo lag by scipy.signal.lsim (a
  state-space first-order system, linear interpolation of the command on a grid 4x finer than the
  program), backlash by the play (hysteresis) operator on the lagged motor position, the clock
  offset by evaluating everything at t - d, positioning/straightness/squareness as polynomials
  and directions of the carriage, the AB head as rotations about the (displaced, tilted) axis
  lines (multi-body form, METHODS section 4, with scipy's Rotation), thermal growth by lsim of
  the first-order response to the spindle speed, runout from the integrated spindle angle.
* ``CASES`` / ``concealed_cases``: the seeded concealed-effect catalogue; ``check``: named exactly,
  parameters within tolerance.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import lfilter, lsim
from scipy.spatial.transform import Rotation

from camsmooth.diagnosis.recordings import Program, Recording


# ----------------------------------------------------------------------------------------------
# programs
def _trapezoid(d: float, vmax: float, amax: float) -> tuple[float, Callable[[np.ndarray], np.ndarray]]:
    """Duration and position profile s(t) of a rest-to-rest move over distance d."""
    d_abs = abs(d)
    if d_abs == 0:
        return 0.0, lambda t: np.zeros_like(t)
    ta = vmax / amax
    if amax * ta * ta >= d_abs:
        ta = math.sqrt(d_abs / amax)
        vmax = amax * ta
    tc = (d_abs - amax * ta * ta) / vmax
    T = 2 * ta + tc
    sg = math.copysign(1.0, d)

    def s(t: np.ndarray) -> np.ndarray:
        t = np.clip(t, 0.0, T)
        a1 = 0.5 * amax * np.minimum(t, ta) ** 2
        c = vmax * np.clip(t - ta, 0.0, tc)
        t3 = np.clip(t - ta - tc, 0.0, ta)
        a3 = vmax * t3 - 0.5 * amax * t3 ** 2
        return sg * (a1 + c + a3)

    return T, s


def _moves(arr: np.ndarray, t: np.ndarray, rng: np.random.Generator, t0: float,
           target: Callable[[np.random.Generator], float], speed: Callable[[np.random.Generator], float],
           amax: float, dwell: tuple[float, float]) -> None:
    """Fill arr with rest-to-rest trapezoidal moves to random targets, each followed by a dwell."""
    duration = float(t[-1]) + (t[1] - t[0] if len(t) > 1 else 0.0)
    tcur, pos = t0, 0.0
    i_prev = 0
    while tcur < duration:
        goal = target(rng)
        v = speed(rng)
        T, prof = _trapezoid(goal - pos, v, amax)
        i0, i1 = np.searchsorted(t, [tcur, tcur + T])
        arr[i_prev:i0] = pos
        arr[i0:i1] = pos + prof(t[i0:i1] - tcur)
        pos = goal
        i_prev = i1
        tcur += T + float(rng.uniform(*dwell))
    arr[i_prev:] = pos


def make_program(kind: str, duration: float = 20.0, rate: float = 500.0, seed: int = 0,
                 spindle: float = 6000.0) -> Program:
    """Synthetic test programs (times at ``rate`` Hz):

    'lines': rest-to-rest linear moves of X, Y, Z with trapezoidal speed, reversals, different
    speeds and dwells; 'circles': XY circles at several feeds with Z steps; 'rotary': A and B
    sweeps (+-30 deg) with small XYZ moves; 'spindle': spindle speed steps (0 to 12000 rpm) with
    slow XY moves, for thermal drift and runout. S is on at ``spindle`` rpm except in 'spindle'.
    """
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration, 1.0 / rate)
    n = len(t)
    X, Y, Z = np.zeros(n), np.zeros(n), np.zeros(n)
    A, B = None, None
    S = np.full(n, float(spindle))
    if kind in ("lines", "rotary", "spindle"):
        for arr, amp, vmx in ((X, 40.0, 60.0), (Y, 30.0, 45.0), (Z, 10.0, 25.0)):
            if kind != "lines":
                amp, vmx = amp / 4, vmx / 3
            _moves(arr, t, rng, 0.2 * rng.random(), lambda r, a=amp: float(r.uniform(-a, a)),
                   lambda r, v=vmx: float(r.uniform(0.3, 1.0)) * v, 800.0, (0.05, 0.6))
    if kind == "circles":
        R = 20.0
        tcur = 0.0
        while tcur < duration:
            f = float(rng.uniform(15.0, 60.0))
            Tc = 2 * np.pi * R / f
            i0, i1 = np.searchsorted(t, [tcur, tcur + Tc])
            ph = (t[i0:i1] - tcur) * f / R
            X[i0:i1] = R * np.sin(ph)
            Y[i0:i1] = R * (1 - np.cos(ph))
            Z[i0:] = float(rng.uniform(-5, 5))
            tcur += Tc + 0.3
        # smooth the Z steps so no axis jumps
        from scipy.ndimage import uniform_filter1d

        Z = uniform_filter1d(Z, max(1, int(0.1 * rate)))
    if kind == "rotary":
        A = np.zeros(n)
        B = np.zeros(n)
        for arr in (A, B):
            amp = np.radians(30.0)
            _moves(arr, t, rng, 0.1 * rng.random(), lambda r, a=amp: float(r.uniform(-a, a)),
                   lambda r: np.radians(float(r.uniform(10, 30))), np.radians(200.0), (0.05, 0.5))
    if kind == "spindle":
        levels = rng.permutation([0.0, 3000.0, 6000.0, 9000.0, 12000.0])
        edges = np.linspace(0.0, duration, len(levels) + 1)
        for lv, e0 in zip(levels, edges[:-1], strict=True):
            S[t >= e0] = lv
        from scipy.ndimage import uniform_filter1d

        S = uniform_filter1d(S, max(1, int(1.0 * rate)))
    if kind not in ("lines", "circles", "rotary", "spindle"):
        raise ValueError(f"unknown program kind {kind!r} (lines, circles, rotary, spindle)")
    axes = {"X": X, "Y": Y, "Z": Z}
    if A is not None:
        axes["A"], axes["B"] = A, B
    return Program(t=t, axes=axes, S=S, source=f"<{kind} program, seed {seed}>")




def _hold_moves(t: np.ndarray, targets: Sequence[Sequence[float]], speed: float, amax: float, dwell: float,
                t0: float = 0.5) -> np.ndarray:
    """Rest-to-rest moves of several axes together through a list of target points (each row
    one point), trapezoidal along the straight line, with a dwell at each point: (N, k)."""
    out = np.zeros((len(t), len(targets[0])))
    pos = np.zeros(len(targets[0]))
    tcur = t0
    i_prev = 0
    for goal in targets:
        goal = np.asarray(goal, float)
        d = goal - pos
        L = float(np.linalg.norm(d))
        T, prof = _trapezoid(L, speed, amax)
        i0, i1 = np.searchsorted(t, [tcur, tcur + T])
        out[i_prev:i0] = pos
        if L > 0:
            out[i0:i1] = pos + np.outer(prof(t[i0:i1] - tcur) / L, d)
        pos = goal
        i_prev = i1
        tcur += T + dwell
        if tcur >= t[-1]:
            break
    out[i_prev:] = pos
    return out


def make_special_program(kind: str, rate: float = 100.0, seed: int = 0, duration: float | None = None) -> Program:
    """'thermal': a 3 x 3 A/B pose grid (+-30 deg) visited again and again with dwells, the
    spindle switching between 0 and 12000 rpm in long blocks (thermal runs; the poses tell the
    spindle frame from the machine frame). 'thermal_flat': the same timing at A = B = 0 with small
    X, Y moves (no rotary motion: the two frames cannot be told apart). 'laser': X to targets
    0..40 mm every 5 mm, up and down with dwells, repeated (ISO 230-2); Y, Z still. 'grid': X, Y, Z
    rest-to-rest over +-100 mm (linear-axis geometry on the tool tip)."""
    rng = np.random.default_rng(seed)
    if kind in ("thermal", "thermal_flat"):
        duration = duration or 240.0
        t = np.arange(0.0, duration, 1.0 / rate)
        n = len(t)
        poses = [(a, b) for a in (-30.0, 0.0, 30.0) for b in (-30.0, 0.0, 30.0)]
        targets = [poses[i % 9] for i in range(400)] if kind == "thermal" else \
            [(float(rng.uniform(-20, 20)), float(rng.uniform(-20, 20))) for _ in range(400)]
        if kind == "thermal":
            AB = _hold_moves(t, targets, 40.0, 300.0, 1.0)
            axes = {"X": np.zeros(n), "Y": np.zeros(n), "Z": np.zeros(n), "A": np.radians(AB[:, 0]),
                    "B": np.radians(AB[:, 1])}
        else:
            XY = _hold_moves(t, targets, 40.0, 300.0, 1.0)
            axes = {"X": XY[:, 0], "Y": XY[:, 1], "Z": np.zeros(n)}
        block = duration / 6
        S = np.where((t // block) % 2 == 0, 12000.0, 0.0)
        S[t < 0.6 * block] = 0.0
        from scipy.ndimage import uniform_filter1d

        S = uniform_filter1d(S, max(1, int(2.0 * rate)))
        return Program(t=t, axes=axes, S=S, source=f"<{kind} program, seed {seed}>")
    if kind == "laser":
        duration = duration or 120.0
        t = np.arange(0.0, duration, 1.0 / rate)
        run = [float(x) for x in np.arange(0.0, 40.1, 5.0)]
        targets = [(x,) for _ in range(20) for x in run + run[::-1]]
        X = _hold_moves(t, targets, 20.0, 200.0, 0.8)[:, 0]
        n = len(t)
        return Program(t=t, axes={"X": X, "Y": np.full(n, 10.0), "Z": np.full(n, -5.0)}, S=np.zeros(n),
                       source=f"<laser program, seed {seed}>")
    if kind == "grid":
        duration = duration or 60.0
        t = np.arange(0.0, duration, 1.0 / rate)
        targets = [tuple(float(v) for v in rng.uniform(-100, 100, 3)) for _ in range(200)]
        XYZ = _hold_moves(t, targets, 60.0, 500.0, 0.3)
        n = len(t)
        return Program(t=t, axes={"X": XYZ[:, 0], "Y": XYZ[:, 1], "Z": XYZ[:, 2]}, S=np.full(n, 3000.0),
                       source=f"<grid program, seed {seed}>")
    return make_program(kind, duration=duration or 20.0, rate=rate, seed=seed, spindle=6100.0)


# ----------------------------------------------------------------------------------------------
# recordings from closed forms (independent of camsmooth.diagnosis.simulator)
LINEAR = ("X", "Y", "Z")


def _lag(tf: np.ndarray, u: np.ndarray, kv: float | None) -> np.ndarray:
    """First-order lag 1 / (s / Kv + 1) by scipy's state-space simulation (linear input between
    the grid points), starting at rest on the command."""
    if not kv:
        return u.copy()
    tau = 1.0 / kv
    _, y, _ = lsim((np.array([[-1.0 / tau]]), np.array([[1.0 / tau]]), np.array([[1.0]]), np.array([[0.0]])),
                   u, tf - tf[0], X0=[u[0]])
    return np.asarray(y, float)


def _play(x: np.ndarray, b: float, first_dir: float) -> np.ndarray:
    """The play (backlash) operator of width b: the output follows x at b/2 behind it and stands
    still while x reverses within the play."""
    z = np.empty_like(x)
    h = 0.5 * b
    cur = x[0] - h * first_dir
    for i, v in enumerate(x.tolist()):
        if v - h > cur:
            cur = v - h
        elif v + h < cur:
            cur = v + h
        z[i] = cur
    return z


def _first_dir(u: np.ndarray) -> float:
    d = np.diff(u)
    nz = np.flatnonzero(np.abs(d) > 1e-12)
    return float(np.sign(d[nz[0]])) if len(nz) else 1.0


def _rot(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotations by angle (N,) about the unit axis (3,)."""
    return Rotation.from_rotvec(np.outer(angle, axis)).as_matrix()


def _tip_and_axis(q: Mapping[str, np.ndarray], g: Mapping[str, float], pivot: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """AB head (METHODS section 1) in multi-body form: carriage (positioning, straightness,
    squareness), then the spindle about the pivot, B about its (displaced, tilted) line, A about
    its line. Returns (tip (N,3), axis (N,3), tool-frame rotation (N,3,3))."""
    G = {k: float(g.get(k, 0.0)) for k in ("EY0A", "EZ0A", "EB0A", "EC0A", "EX0B", "EZ0B", "EA0B", "EC0B", "EX0S",
                                           "EY0S", "EA0S", "EB0S", "EZ0T", "EC0Y", "EB0Z", "EA0Z")}
    real = {}
    for a in LINEAR:
        v = q[a]
        real[a] = v + g.get(f"E{a}{a}", 0.0) * v + g.get(f"E{a}{a}2", 0.0) * v ** 2 + g.get(f"E{a}{a}3", 0.0) * v ** 3
    dY = np.array([-math.sin(G["EC0Y"]), math.cos(G["EC0Y"]), 0.0])
    dZ = Rotation.from_euler("XY", [G["EA0Z"], G["EB0Z"]]).as_matrix() @ np.array([0.0, 0.0, 1.0])
    carriage = np.outer(real["X"], [1.0, 0, 0]) + np.outer(real["Y"], dY) + np.outer(real["Z"], dZ)
    for a in LINEAR:
        for i, b in enumerate(LINEAR):
            if b != a:
                v = q[a]
                carriage[:, i] += g.get(f"E{b}{a}2", 0.0) * v ** 2 + g.get(f"E{b}{a}3", 0.0) * v ** 3
    RS = Rotation.from_euler("XY", [G["EA0S"], G["EB0S"]]).as_matrix()
    tip_s = RS @ np.array([0.0, 0.0, -(pivot + G["EZ0T"])]) + np.array([G["EX0S"], G["EY0S"], 0.0])
    RA0 = Rotation.from_euler("ZY", [G["EC0A"], G["EB0A"]]).as_matrix()
    pA = np.array([0.0, G["EY0A"], G["EZ0A"]])
    wA = RA0 @ np.array([1.0, 0.0, 0.0])
    wB = RA0 @ Rotation.from_euler("XZ", [G["EA0B"], G["EC0B"]]).as_matrix() @ np.array([0.0, 1.0, 0.0])
    cB = pA + RA0 @ np.array([G["EX0B"], 0.0, G["EZ0B"]])
    RBq = _rot(wB, q["B"])
    RAq = _rot(wA, q["A"])
    p = cB + np.einsum("nij,j->ni", RBq, tip_s - cB)
    p = pA + np.einsum("nij,nj->ni", RAq, p - pA)
    R = RAq @ RBq @ RS
    return carriage + p, R[:, :, 2], R


def record(program: Program, truth: Mapping[str, float], channels: Sequence[str] = ("axes",),
           noise: Mapping[str, float] | None = None, seed: int = 0, pivot: float = 150.0, refine: int = 4
           ) -> Recording:
    """A recording of ``program`` (uniform rows) with the effects ``truth`` (the flat settings of
    `camsmooth simulate recording --set`: Kv_<axis> 1/s, offset_s s, backlash_<axis> mm or deg,
    geometric names, thermal_<element>_gain / _tau, runout_radius mm, runout_phase_deg), at the
    program's own times, from the closed forms of the module docstring. channels: 'axes'
    (X_act.. as an external measurement of each carriage sees it), 'tip', 'axis'. noise: white
    sigma per group ('axes' mm, 'rotary' rad, 'tip' mm, 'axis' 1)."""
    t = program.t
    n = len(t)
    tf = np.linspace(t[0], t[-1], (n - 1) * refine + 1)
    te = t - float(truth.get("offset_s", 0.0))
    noise = dict(noise or {})
    rng = np.random.default_rng(seed)
    actual: dict[str, np.ndarray] = {}
    for a, u in program.axes.items():
        y = np.interp(te, tf, _lag(tf, np.interp(tf, t, u), truth.get(f"Kv_{a}")))
        b = float(truth.get(f"backlash_{a}", 0.0))
        if b:
            y = _play(y, math.radians(b) if a in ("A", "B") else b, _first_dir(u))
        actual[a] = y
    q = {a: actual.get(a, np.zeros(n)) for a in ("X", "Y", "Z", "A", "B")}
    chans: dict[str, np.ndarray] = {}
    if "axes" in channels:
        for a in program.axes:
            v = q[a]
            if a in LINEAR:
                v = v + truth.get(f"E{a}{a}", 0.0) * v + truth.get(f"E{a}{a}2", 0.0) * v ** 2 \
                    + truth.get(f"E{a}{a}3", 0.0) * v ** 3
            sig = noise.get("rotary" if a in ("A", "B") else "axes", 0.0)
            chans[f"{a}_act"] = v + rng.normal(0.0, sig, n) if sig else v
    if "tip" in channels or "axis" in channels:
        tip, axis, R = _tip_and_axis(q, truth, pivot)
        S = program.S if program.S is not None else np.zeros(n)
        Sf = np.interp(tf, t, S)
        elems = {}
        for el in ("dx", "dy", "dz", "exz", "eyz", "mx", "my", "mz"):
            gain = truth.get(f"thermal_{el}_gain", 0.0)
            if gain:
                kv = 1.0 / truth[f"thermal_{el}_tau"]
                yth = _lag(tf, Sf / 1000.0 - Sf[0] / 1000.0, kv) + Sf[0] / 1000.0 * (1 - np.exp(-kv * (tf - tf[0])))
                elems[el] = gain * np.interp(te, tf, yth)
        local = np.zeros((n, 3))
        for i, el in enumerate(("dx", "dy", "dz")):
            local[:, i] += elems.get(el, 0.0)
        r = truth.get("runout_radius", 0.0)
        if r:
            theta_f = np.r_[0.0, np.cumsum(0.5 * (Sf[1:] + Sf[:-1]) * np.diff(tf))] * (2 * math.pi / 60.0)
            th = np.interp(te, tf, theta_f) + math.radians(truth.get("runout_phase_deg", 0.0))
            local[:, 0] += r * np.cos(th)
            local[:, 1] += r * np.sin(th)
        tip = tip + np.einsum("nij,nj->ni", R, local)
        if "exz" in elems or "eyz" in elems:
            rv = np.column_stack([elems.get("eyz", np.zeros(n)), -elems.get("exz", np.zeros(n)), np.zeros(n)])
            axis = np.einsum("nij,nj->ni", R, Rotation.from_rotvec(rv).as_matrix()[:, :, 2])
        for i, el in enumerate(("mx", "my", "mz")):
            tip[:, i] += elems.get(el, 0.0)
        if "tip" in channels:
            for i, c in enumerate(("tip_x", "tip_y", "tip_z")):
                sig = noise.get("tip", 0.0)
                chans[c] = tip[:, i] + (rng.normal(0.0, sig, n) if sig else 0.0)
        if "axis" in channels:
            for i, c in enumerate(("axis_i", "axis_j", "axis_k")):
                sig = noise.get("axis", 0.0)
                chans[c] = axis[:, i] + (rng.normal(0.0, sig, n) if sig else 0.0)
    return Recording(t=t.copy(), channels=chans, source="<closed-form recording>",
                     notes=["recorded by benchmarks/synthetic.py (closed forms, not camsmooth's simulator)"])


# ----------------------------------------------------------------------------------------------
# the concealed-effect catalogue
#: one setting per term (file units, see ``record``)
EFFECTS: dict[str, dict[str, float]] = {
    "servo_lag": {"Kv_X": 40.0, "Kv_Y": 60.0, "Kv_Z": 80.0, "Kv_A": 50.0, "Kv_B": 70.0},
    "time_offset": {"offset_s": 0.005},
    "backlash": {"backlash_X": 0.012, "backlash_Y": 0.020, "backlash_Z": 0.030, "backlash_A": 0.010,
                 "backlash_B": 0.012},
    "rotary_location": {"EY0A": 0.020, "EZ0A": -0.015, "EX0B": 0.010, "EZ0B": 0.020},
    "rotary_squareness": {"EB0A": 1e-4, "EC0A": -8e-5, "EA0B": 6e-5, "EC0B": 1e-4},
    "spindle_tilt": {"EA0S": 1e-4, "EB0S": -1.5e-4},
    "spindle_runout": {"runout_radius": 0.005, "runout_phase_deg": 30.0},
    "tool_length": {"EZ0T": 0.05},
    "thermal_drift": {"thermal_dz_gain": 0.010, "thermal_dz_tau": 40.0, "thermal_dx_gain": 0.004,
                      "thermal_dx_tau": 25.0},
    "thermal_machine": {"thermal_mz_gain": 0.012, "thermal_mz_tau": 35.0},
    "linear_positioning": {"EXX": 3.3e-3, "EYY": -1.5e-4, "EZZ": 2e-4},
    "linear_straightness": {"EYX2": 2e-6, "EZY2": -1.5e-6},
    "linear_squareness": {"EC0Y": 1e-4, "EB0Z": -8e-5},
}
#: program kind -> (channels, default rate Hz, default noise mm)
PROGRAMS: dict[str, tuple[tuple[str, ...], float, float]] = {
    "lines": (("axes",), 500.0, 0.0003),
    "p2p": (("axes",), 500.0, 0.0003),
    "lines_tip": (("axes", "tip"), 250.0, 0.001),
    "circles": (("axes",), 250.0, 0.001),
    "rotary": (("axes", "tip", "axis"), 250.0, 0.001),
    "spindle": (("tip", "axis"), 100.0, 0.001),
    "thermal": (("tip",), 20.0, 0.001),
    "thermal_flat": (("tip",), 20.0, 0.001),
    "laser": (("axes",), 50.0, 0.0005),
    "grid": (("tip",), 50.0, 0.001),
}


@dataclass(frozen=True)
class Case:
    """One concealed case: program kind, hidden settings, the terms that must be named, terms
    that may stand in a 'cannot tell apart' pair with them, noise (mm; rad channels get 1e-3 of it),
    rate and seed."""

    kind: str
    truth: dict[str, float]
    named: tuple[str, ...]
    label: str
    noise: float | None = None
    rate: float | None = None
    seed: int = 1
    apart: tuple[str, ...] = field(default_factory=tuple)
    quantum: float = 0.0  # rounding step of the mm channels (a recording's resolution)


def _settings(*names: str, axes: Sequence[str] | None = None, **override: float) -> dict[str, float]:
    out: dict[str, float] = {}
    for n in names:
        for k, v in EFFECTS[n].items():
            ax = k.split("_")[-1] if k.startswith(("Kv_", "backlash_")) else None
            if axes is not None and ax is not None and ax not in axes:
                continue
            out[k] = v
    out.update(override)
    return out


def concealed_cases(seeds: Sequence[int] = (1, 2)) -> list[Case]:
    """The catalogue (every term alone, the common pairs, nulls; axis channels at several rates
    and noise levels, tool-tip channels, thermal runs in both frames, linear-axis geometry), per
    seed."""
    out: list[Case] = []
    xyz = ("X", "Y", "Z")
    for s in seeds:
        out += [
            # nulls
            Case("lines", {}, (), "null, axes 500 Hz", seed=s),
            Case("lines_tip", {}, (), "null, axes and tip", seed=s),
            Case("rotary", {}, (), "null, rotary with tip and axis", seed=s),
            Case("thermal", {}, (), "null, thermal run", seed=s),
            Case("laser", {}, (), "null, ISO 230-2 run", seed=s),
            # servo, clock, reversal on the axes
            Case("lines", _settings("servo_lag", axes=xyz), ("servo_lag",), "lag X, Y, Z 500 Hz", seed=s),
            Case("lines", {"Kv_X": 40.0}, ("servo_lag",), "lag on X only", seed=s),
            Case("circles", _settings("servo_lag", axes=("X", "Y")), ("servo_lag",), "lag, circles 250 Hz, 1 um",
                 seed=s),
            Case("lines", _settings("time_offset"), ("time_offset",), "clock offset 5 ms", seed=s),
            Case("lines", _settings("backlash", axes=xyz), ("backlash",), "backlash X, Y, Z", seed=s),
            Case("lines", {"backlash_X": 0.012, "backlash_Y": 0.030}, ("backlash",), "backlash X, Y only", seed=s,
                 noise=0.0003),
            Case("lines", _settings("servo_lag", "backlash", axes=xyz), ("servo_lag", "backlash"), "lag + backlash",
                 seed=s, noise=0.001, rate=250.0),
            Case("rotary", _settings("backlash"), ("backlash",), "backlash with A, B", seed=s),
            # the recordings: 500 Hz point-to-point moves of X, Y, Z, A, B, 0.3 um noise
            Case("p2p", {"backlash_X": 0.012}, ("backlash",), "backlash X only, p2p 500 Hz", seed=s),
            Case("p2p", {"backlash_X": 0.030, "backlash_Y": 0.015}, ("backlash",), "backlash X, Y, p2p 500 Hz",
                 seed=s),
            Case("p2p", {}, (), "null, p2p 500 Hz", seed=s),
            Case("rotary", _settings("servo_lag"), ("servo_lag",), "lag with A, B", seed=s),
            Case("rotary", {"Kv_X": 40.0}, ("servo_lag",), "lag on X only, with A, B", seed=s, noise=0.0003),
            # rotary head geometry on the tip
            Case("rotary", _settings("rotary_location"), ("rotary_location",), "rotary location", seed=s),
            Case("rotary", _settings("rotary_squareness"), ("rotary_squareness",), "rotary squareness", seed=s),
            Case("rotary", _settings("spindle_tilt"), ("spindle_tilt",), "spindle tilt", seed=s),
            Case("rotary", _settings("tool_length"), ("tool_length",), "tool length", seed=s),
            Case("spindle", _settings("spindle_runout"), ("spindle_runout",), "runout", seed=s),
            # thermal runs in both frames
            Case("thermal", _settings("thermal_machine"), ("thermal_machine",), "machine-frame growth", seed=s),
            Case("thermal", _settings("thermal_drift"), ("thermal_drift",), "spindle-frame growth", seed=s),
            Case("thermal", _settings("thermal_machine", "rotary_location"), ("thermal_machine", "rotary_location"),
                 "machine growth + rotary location", seed=s),
            Case("thermal_flat", _settings("thermal_machine"), ("thermal_machine",),
                 "machine growth, no rotary motion", seed=s, apart=("thermal_drift",)),
            # linear-axis geometry
            Case("laser", {"EXX": 3.3e-3}, ("linear_positioning",), "positioning 3.3 um/mm (laser)", seed=s),
            Case("laser", {"EXX": 3.3e-3, "backlash_X": 0.011}, ("linear_positioning", "backlash"),
                 "positioning + reversal (laser)", seed=s),
            Case("grid", _settings("linear_positioning"), ("linear_positioning",), "positioning on the tip", seed=s),
            Case("grid", _settings("linear_straightness"), ("linear_straightness",), "straightness", seed=s),
            Case("grid", _settings("linear_squareness"), ("linear_squareness",), "squareness", seed=s),
            # harder: coarse sampling, more noise and a quantised recording; pairs on one program
            Case("lines", _settings("servo_lag", axes=xyz), ("servo_lag",), "lag, 100 Hz, 2 um noise, 1 um steps",
                 seed=s, noise=0.002, rate=100.0, quantum=0.001),
            Case("spindle", _settings("spindle_runout", "thermal_drift"), ("spindle_runout", "thermal_drift"),
                 "runout + spindle growth", seed=s),
            Case("grid", _settings("linear_positioning", "backlash", axes=xyz), ("linear_positioning", "backlash"),
                 "positioning + backlash on the tip", seed=s),
        ]
    return out


def program_for(case: Case) -> Program:
    chans, rate, _ = PROGRAMS[case.kind]
    kind = {"lines_tip": "lines", "p2p": "rotary"}.get(case.kind, case.kind)
    duration = 40.0 if case.kind == "p2p" else (8.0 if kind in ("lines", "circles", "rotary") else None)
    return make_special_program(kind, rate=case.rate or rate, seed=case.seed, duration=duration)


def recording_for(case: Case, program: Program) -> Recording:
    chans, _, noise = PROGRAMS[case.kind]
    sig = case.noise if case.noise is not None else noise
    rec = record(program, case.truth, channels=chans,
                 noise={"axes": sig, "tip": sig, "rotary": sig * 1e-3, "axis": sig * 1e-3}, seed=case.seed + 1000)
    if case.quantum:
        for c in rec.channels:
            if c in ("X_act", "Y_act", "Z_act", "tip_x", "tip_y", "tip_z"):
                rec.channels[c] = np.round(rec.channels[c] / case.quantum) * case.quantum
                rec.quantum[c] = np.full(len(rec.t), case.quantum)
    return rec


def _got(par: Mapping[str, Mapping[str, Any]], k: str) -> float | None:
    """The fitted value of a truth setting from the findings' effect parameters (file units)."""
    if k.startswith("Kv_"):
        return par.get("servo_lag", {}).get(k)
    if k == "offset_s":
        return par.get("time_offset", {}).get("offset_s")
    if k.startswith("backlash_"):
        return par.get("backlash", {}).get(k)
    if k.startswith("thermal_"):
        el, what = k[8:].rsplit("_", 1)
        for p in par.values():
            if f"{el}_{what}" in p:
                return p[f"{el}_{what}"]
        return None
    for p in par.values():
        if k in p:
            return p[k]
    return None


def check(findings: Mapping[str, Any], case: Case, tol: float = 0.10) -> dict[str, Any]:
    """named exactly / told apart: whether exactly ``case.named`` was named (or, for a term in
    ``case.apart``, the pair was reported as 'cannot tell apart'); parameter errors (relative)."""
    named = list(findings["named"])
    exact = set(named) == set(case.named)
    apart = False
    if not exact and case.apart:
        pairs = {frozenset((e["chosen"], e["alternative"])) for e in findings.get("equivalences", [])}
        swapped = [n for n in named if n not in case.named]
        apart = len(named) == len(case.named) and all(
            any(frozenset((s, t)) in pairs for t in case.named) for s in swapped)
    errors: dict[str, float | None] = {}
    par = {e["name"]: e["parameters"] for e in findings["effects"]}
    if exact:
        for k, v in case.truth.items():
            if k in ("runout_phase_deg",) or k.endswith("_tau"):
                continue
            if k == "runout_radius":
                p = par.get("spindle_runout", {})
                if p:
                    z = p["radius"] * np.exp(1j * np.radians(p["phase_deg"]))
                    zt = v * np.exp(1j * np.radians(case.truth["runout_phase_deg"]))
                    errors[k] = float(abs(z - zt) / v)
                continue
            got = _got(par, k)
            errors[k] = None if got is None else float(abs(got - v) / abs(v))
    bad = [k for k, e in errors.items() if e is None or e > tol]
    return {"exact": exact, "apart": apart, "errors": errors, "bad": bad, "named": named}


def run_case(case: Case, diagnose: Callable[..., Any], options: Any = None) -> dict[str, Any]:
    """Make the program and the recording, diagnose them (program and recording only), check."""
    program = program_for(case)
    rec = recording_for(case, program)
    t0 = time.perf_counter()
    diag = diagnose(program, rec, options=options)
    dt = time.perf_counter() - t0
    f = diag.findings
    out = check(f, case)
    none = {e["name"]: e.get("none_measurable", []) for e in f["effects"]}
    out.update(case=case, seconds=dt, samples=len(rec.t), none_measurable=none,
               apart_pairs=[(e["chosen"], e["alternative"]) for e in f.get("equivalences", [])])
    return out


def coloured_noise(n: int, sigma: float, rho: float, rng: np.random.Generator) -> np.ndarray:
    """AR(1) noise (n,) of stationary standard deviation sigma and lag-1 correlation rho (white for
    rho 0)."""
    if not rho:
        return rng.normal(0.0, sigma, n)
    return lfilter([1.0], [1.0, -rho], rng.normal(0.0, sigma * np.sqrt(1 - rho ** 2), n))


def null_case(kind: str, rho: float, seed: int) -> tuple[Program, Recording]:
    """A recording with no effect at all (issue 20's nulls): the program ``kind`` ('lines', or a
    special program: 'laser', 'grid', 'rotary'), its axis channels (tip channels for grid and
    rotary) with 1 um of AR(1) noise of correlation rho plus 0.3 um white."""
    prog = make_program("lines", duration=8.0, rate=250.0, seed=seed) if kind == "lines" else \
        make_special_program(kind, rate=50.0, seed=seed)
    rec = record(prog, {}, channels=("tip",) if kind in ("grid", "rotary") else ("axes",), noise={}, seed=seed)
    rng = np.random.default_rng(seed + 100)
    for c in rec.channels:
        n = len(rec.t)
        rec.channels[c] = rec.channels[c] + coloured_noise(n, 1e-3, rho, rng) + rng.normal(0, 3e-4, n)
    return prog, rec
