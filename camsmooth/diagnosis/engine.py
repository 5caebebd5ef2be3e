"""Simulation versus recordings (METHODS.md section 6): locate the mismatch, name the missing
physics, fit it, show the fit improve on held-out data, and write the extended model.

Pipeline (``diagnose``):

1. Simulate the recorded channels from the program and the current model (``Simulator``);
   residual = recorded - simulated, per channel.
2. Noise floor per channel and sample: the larger of a white-noise estimate (robust scale of the
   residual's second differences, 1.4826 MAD / sqrt(6)) and the quantisation of the recording and
   of a logged command (sqrt(q_rec^2 + q_cmd^2) / sqrt(12)). Isolated spikes (|r - median5(r)| >
   20 floors) are reported as outliers and kept out of fits. Locate: intervals where |r| > 3
   floors, with the axis states there.
3. Explain: a library of candidate physics (``CANDIDATES``), each a parametric addition to the
   simulation (``Candidate``: parameters, how they enter Physics, a starting guess, a report),
   fitted by least squares on floor-weighted residuals and scored on blocked time folds.
   Least squares: a bounded Levenberg-Marquardt on the normal equations (``_lm``; with a few
   parameters and up to a million residuals this is much cheaper than
   scipy.optimize.least_squares' per-iteration SVD). Held-out: each fold predicted by the fit
   without it (one Gauss-Newton step from the full fit on the other folds' Jacobian rows, then
   simulated exactly). Greedy forward selection with a backward check (``Selector``): each round
   every remaining candidate is screened jointly with the chosen terms (those linearised); the
   best is refitted exactly and joins when the pooled held-out RMS falls by a clear margin, it
   falls in most folds, and BIC (sample count reduced for the residual's lag-1 autocorrelation)
   falls by a clear margin; an earlier term that would no longer pass as the last one is dropped.
   Rejected candidates are recorded with the reason. Candidates that explain the residual
   equally well are reported as equivalent with the measurement that would separate them; the
   one named is the first in METHODS.md section 6's order (the more common cause).
4. Show: residual RMS per channel before and after (fit and held-out), parameters with
   uncertainties, one sentence per effect.
5. Update: ``model_json`` writes the extended model (ErrorModel JSON + a ``servo`` section).

Physics models (all in ``Simulator``; internal units mm, s, rad):

- servo_lag: each axis follows its command through a first-order lag with time constant
  tau = 1/Kv: dy/dt = Kv (u - y). The command is piecewise linear between program rows, so the
  response is integrated exactly: on a row interval with slope s the following error e = u - y
  obeys e(t) = s tau + (e_k - s tau) exp(-(t - t_k)/tau), i.e. v/Kv in steady motion.
- time_offset: the recording clock runs offset_s behind the program clock: sim(t) = model(t - d).
- backlash: a direction-dependent error of the axis, -(b/2) sign(last commanded direction);
  the recorded axis actual is taken as the position of the axis itself (a scale at the load).
- rotary_location, rotary_squareness, spindle_tilt, tool_length: ErrorModel geometric
  parameters through the machine's product-of-exponentials chain (camsmooth.machine.model).
- spindle_runout: a tip displacement of radius r rotating once per spindle revolution, phase phi
  at spindle angle 0 (angle = integral of S since the program start), in the tool frame's xy.
- thermal_drift: element e in dx, dy, dz (tip, mm, tool frame), exz, eyz (tool-axis tilt, rad)
  follows tau_e de/dt = gain_e S/1000 - e from a cold start, S in rpm.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.diagnosis.recordings import (
    AXES,
    AXIS_CHANNELS,
    CHANNELS,
    DIR_CHANNELS,
    ROTARY_AXES,
    TIP_CHANNELS,
    Aligned,
    Program,
    Recording,
    align,
    channel_unit,
    rms_step,
)
from camsmooth.errors import InputError
from camsmooth.io.atomic import write_text_atomic
from camsmooth.machine.kinematics import Machine, load_machine

CANDIDATES = ("servo_lag", "time_offset", "backlash", "rotary_location", "rotary_squareness", "spindle_tilt",
              "spindle_runout", "tool_length", "thermal_drift")
THERMAL_ELEMENTS = ("dx", "dy", "dz", "exz", "eyz")
GEOMETRIC_NAMES = ("EY0A", "EZ0A", "EB0A", "EC0A", "EX0B", "EZ0B", "EA0B", "EC0B", "EX0S", "EY0S", "EA0S",
                   "EB0S", "EZ0T")
_GEO_ANGLES = {"EB0A", "EC0A", "EA0B", "EC0B", "EA0S", "EB0S"}


# ==============================================================================================
# the physics of one simulation
@dataclass
class Physics:
    """Parameters of every modelled effect (internal units). tau: servo time constant per axis
    (s, 1/Kv; absent or 0 = follows its command exactly); offset_s: recording clock behind the
    program (s); backlash: reversal error per axis (mm; rad for A, B); geometric: ErrorModel
    parameters (mm, rad); thermal: element -> (gain per 1000 rpm, tau s); runout: (r cos phi,
    r sin phi) mm. Geometric and thermal follow camsmooth.machine.model (ErrorModel) exactly."""

    tau: dict[str, float] = field(default_factory=dict)
    offset_s: float = 0.0
    backlash: dict[str, float] = field(default_factory=dict)
    geometric: dict[str, float] = field(default_factory=dict)
    thermal: dict[str, tuple[float, float]] = field(default_factory=dict)
    runout: tuple[float, float] = (0.0, 0.0)
    spindle: Any = None  # an ErrorModel SpindleScrew carried over from a base model (not fitted)
    meta: dict[str, Any] = field(default_factory=dict)

    def copy(self) -> Physics:
        return Physics(dict(self.tau), float(self.offset_s), dict(self.backlash), dict(self.geometric),
                       dict(self.thermal), tuple(self.runout), self.spindle, dict(self.meta))

    @property
    def Kv(self) -> dict[str, float]:
        return {a: (1.0 / t if t > 0 else math.inf) for a, t in self.tau.items()}


def physics_from_settings(settings: Mapping[str, float], base: Physics | None = None) -> Physics:
    """Physics from flat user settings (file units): Kv_<axis> (1/s), offset_s (s),
    backlash_<axis> (mm; deg for A, B), ErrorModel names (mm, rad), thermal_<element>_gain
    (mm or rad per 1000 rpm), thermal_<element>_tau (s), runout_radius (mm), runout_phase_deg."""
    ph = base.copy() if base is not None else Physics()
    r, phi = math.hypot(*ph.runout), math.degrees(math.atan2(ph.runout[1], ph.runout[0]))
    for key, value in settings.items():
        value = float(value)
        if key.startswith("Kv_") and key[3:] in AXES:
            if value <= 0:
                raise InputError(f"{key} must be > 0 1/s, got {value}", column=key)
            ph.tau[key[3:]] = 1.0 / value
        elif key == "offset_s":
            ph.offset_s = value
        elif key.startswith("backlash_") and key[9:] in AXES:
            ph.backlash[key[9:]] = math.radians(value) if key[9:] in ROTARY_AXES else value
        elif key in GEOMETRIC_NAMES:
            ph.geometric[key] = value
        elif key.startswith("thermal_") and key.rsplit("_", 1)[-1] in ("gain", "tau") and \
                key[8:].rsplit("_", 1)[0] in THERMAL_ELEMENTS:
            el, what = key[8:].rsplit("_", 1)
            g, tau = ph.thermal.get(el, (0.0, 60.0))
            ph.thermal[el] = (value, tau) if what == "gain" else (g, value)
        elif key == "runout_radius":
            r = value
        elif key == "runout_phase_deg":
            phi = value
        else:
            raise InputError(f"unknown setting {key!r}", column=key)
    ph.runout = (r * math.cos(math.radians(phi)), r * math.sin(math.radians(phi)))
    for el, (_, tau) in ph.thermal.items():
        if tau <= 0:
            raise InputError(f"thermal_{el}_tau must be > 0 s", column=f"thermal_{el}_tau")
    return ph


# ----------------------------------------------------------------------------------------------
# model files: ErrorModel JSON + servo section
def physics_from_model(data: Mapping[str, Any], source: str = "<model>") -> Physics:
    """Physics from a model JSON document: the ErrorModel document (``ErrorModel.from_dict``:
    geometric, spindle screw, thermal) plus the sections ``model_json`` adds: ``servo`` (Kv per
    axis 1/s, backlash mm or deg, time_offset_s) and ``spindle_runout`` (radius mm, phase_deg).
    A document with only ``servo`` / ``spindle_runout`` (no ErrorModel part) is accepted too."""
    from camsmooth.machine.model import ErrorModel

    if not isinstance(data, Mapping):
        raise InputError("a model file holds a JSON object", file=source)
    ph = Physics()
    if "format" in data or "geometric" in data or "thermal" in data:
        em = ErrorModel.from_dict(data, source)
        ph.geometric = {k: float(v) for k, v in em.geometric.items()}
        ph.thermal = {k: (float(d["gain"]), float(d["tau"])) for k, d in em.thermal.items()}
        ph.spindle = em.spindle
        ph.meta = dict(em.meta)
    servo = data.get("servo") or {}
    if not isinstance(servo, Mapping):
        raise InputError("'servo' must be an object", file=source, column="servo")
    for a, kv in (servo.get("Kv") or {}).items():
        kv = _finite(kv, source, f"servo.Kv.{a}")
        if a not in AXES or kv <= 0:
            raise InputError(f"servo Kv needs an axis of {AXES} and a value > 0", file=source, column=f"servo.Kv.{a}")
        ph.tau[a] = 1.0 / kv
    for a, b in (servo.get("backlash") or {}).items():
        if a not in AXES:
            raise InputError(f"backlash axis {a!r} is not one of {AXES}", file=source, column=f"servo.backlash.{a}")
        b = _finite(b, source, f"servo.backlash.{a}")
        ph.backlash[a] = math.radians(b) if a in ROTARY_AXES else b
    ph.offset_s = _finite(servo.get("time_offset_s", 0.0), source, "servo.time_offset_s")
    ro = data.get("spindle_runout") or {}
    if ro:
        r = _finite(ro.get("radius", 0.0), source, "spindle_runout.radius")
        phi = math.radians(_finite(ro.get("phase_deg", 0.0), source, "spindle_runout.phase_deg"))
        ph.runout = (r * math.cos(phi), r * math.sin(phi))
    return ph


def _finite(v: Any, source: str, column: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(f"must be a finite number, got {v!r}", file=source, column=column)
    return float(v)


def load_model(path: str | None) -> Physics:
    """Read a model JSON (``physics_from_model``); None gives the ideal model."""
    if path is None:
        return Physics()
    try:
        with open(path) as fh:
            data = json.load(fh)
    except FileNotFoundError:
        raise InputError("model file not found", file=str(path)) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc}", file=str(path), row=exc.lineno) from None
    return physics_from_model(data, str(path))


def model_json(ph: Physics, note: str = "") -> dict[str, Any]:
    """The extended model as a JSON document: ``ErrorModel.to_dict()`` (geometric mm/rad, the
    spindle screw carried over, thermal gain per 1000 rpm and tau s, each value with its unit)
    plus ``servo`` (Kv per axis 1/s, backlash mm or deg, time_offset_s) and, when fitted,
    ``spindle_runout`` (radius mm, phase_deg). ``ErrorModel.from_dict`` reads it back (it
    ignores the extra sections); ``physics_from_model`` reads all of it."""
    from camsmooth.machine.model import ErrorModel

    meta = dict(ph.meta)
    if note:
        meta["diagnose"] = note
    em = ErrorModel(geometric={k: float(v) for k, v in ph.geometric.items() if v != 0.0}, spindle=ph.spindle,
                    thermal={k: {"gain": float(g), "tau": float(t)} for k, (g, t) in ph.thermal.items() if g != 0.0},
                    meta=meta)
    out = em.to_dict()
    out["servo"] = {
        "Kv": {a: 1.0 / t for a, t in ph.tau.items() if t > 0},
        "backlash": {a: (math.degrees(b) if a in ROTARY_AXES else b) for a, b in ph.backlash.items() if b != 0.0},
        "time_offset_s": float(ph.offset_s),
        "units": {"Kv": "1/s", "backlash": "mm (deg for A, B)", "time_offset_s": "s"},
    }
    if ph.runout != (0.0, 0.0):
        out["spindle_runout"] = {"radius": float(math.hypot(*ph.runout)),
                                 "phase_deg": float(math.degrees(math.atan2(ph.runout[1], ph.runout[0]))),
                                 "units": {"radius": "mm", "phase_deg": "deg at spindle angle 0"}}
    return out


# ==============================================================================================
# exact first-order responses on a piecewise-linear input
def _scan(alpha: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x[0] = 0, x[k+1] = alpha[k] x[k] + b[k] for k < n; returns x (n + 1,).

    Blocked sequential scan: the n steps are cut into about sqrt(n) blocks; one pass runs all
    blocks side by side (zero start), a short pass carries the block start values, a last
    vectorised step adds them. Pure multiply-adds, so no loss of precision for small alpha.
    """
    n = len(alpha)
    if n == 0:
        return np.zeros(1)
    L = max(1, int(math.sqrt(n)))
    nb = -(-n // L)
    pad = nb * L - n
    A = np.concatenate([alpha, np.ones(pad)]).reshape(nb, L).T.copy()
    B = np.concatenate([b, np.zeros(pad)]).reshape(nb, L).T.copy()
    X = np.empty((L + 1, nb))
    P = np.empty((L + 1, nb))
    X[0] = 0.0
    P[0] = 1.0
    for j in range(L):
        np.multiply(A[j], X[j], out=X[j + 1])
        X[j + 1] += B[j]
        np.multiply(A[j], P[j], out=P[j + 1])
    starts = np.empty(nb)
    c = 0.0
    pl, xl = P[L].tolist(), X[L].tolist()
    for m in range(nb):
        starts[m] = c
        c = pl[m] * c + xl[m]
    full = X[:L] + P[:L] * starts[None, :]
    out = np.empty(n + 1)
    out[:n] = full.T.reshape(-1)[:n]
    out[n] = c if pad == 0 else full.T.reshape(-1)[n]
    return out


class _Knots:
    """The program as knots of a piecewise-linear command, with per-interval slopes (0 across a
    segment break and after the last row) and the segment spans."""

    def __init__(self, program: Program) -> None:
        self.program = program
        self.t = program.t
        self.seg = program.segment
        n = len(self.t)
        self.n = n
        same = np.r_[self.seg[1:] == self.seg[:-1], False]
        self.same = same  # interval k (k -> k + 1) lies inside one segment
        self.h = np.zeros(n)
        self.h[:-1] = np.diff(self.t)
        self.starts = np.flatnonzero(np.r_[True, ~same[:-1]])
        self.ends = np.r_[self.starts[1:] - 1, n - 1]
        self.first_of = np.repeat(self.starts, self.ends - self.starts + 1)
        self.last_of = np.repeat(self.ends, self.ends - self.starts + 1)
        self.u: dict[str, np.ndarray] = {a: np.asarray(v, float) for a, v in program.axes.items()}
        self.slope = {a: self._slope(u) for a, u in self.u.items()}
        self.S = None if program.S is None else np.asarray(program.S, float)
        if self.S is not None:
            # the spindle and thermal states run on through segment breaks (the clock does)
            hS = np.r_[np.diff(self.t), 0.0]
            self.S_slope = np.zeros(n)
            self.S_slope[:-1] = np.diff(self.S) / hS[:-1]
            self.S_angle = np.r_[0.0, np.cumsum(0.5 * (self.S[1:] + self.S[:-1]) * hS[:-1])] * (2 * np.pi / 60.0)
        self._dir: dict[str, np.ndarray] = {}
        # equal steps inside every segment let scipy's IIR filter do the recursion
        hin = self.h[:-1][same[:-1]]
        self.h0 = float(np.median(hin)) if len(hin) else 0.0
        self.uniform = bool(len(hin) and np.max(np.abs(hin - self.h0)) <= 1e-9 * self.h0
                            and len(self.starts) <= 5000)
        hall = np.diff(self.t)
        self.uniform_all = bool(len(hall) and np.max(np.abs(hall - self.h0)) <= 1e-9 * self.h0)

    def scan(self, tau: float, slope: np.ndarray, reset: bool = True, e0: float = 0.0) -> np.ndarray:
        """Following error e at the knots of tau de/dt = s - e, i.e. e_(k+1) = alpha_k e_k +
        (1 - alpha_k) tau s_k, alpha_k = exp(-h_k / tau); reset: e = 0 at each segment start
        (else the recursion runs through the breaks from e0 at the first row)."""
        from scipy.signal import lfilter

        n = self.n
        if reset and self.uniform or not reset and self.uniform_all:
            al = math.exp(-self.h0 / tau)
            coef = (1.0 - al) * tau
            e = np.empty(n)
            spans = zip(self.starts, self.ends, strict=True) if reset else [(0, n - 1)]
            for i0, i1 in spans:
                e[i0] = e0 if not reset else 0.0
                if i1 > i0:
                    zi = np.array([al * e[i0]])
                    e[i0 + 1:i1 + 1] = lfilter([coef], [1.0, -al], slope[i0:i1], zi=zi)[0]
            return e
        h = self.h[:-1] if reset else np.diff(self.t)
        with np.errstate(over="ignore", under="ignore"):
            alpha = np.exp(-h / tau)
        b = (1.0 - alpha) * slope[:-1] * tau
        if reset:
            alpha = np.where(self.same[:-1], alpha, 0.0)
            b = np.where(self.same[:-1], b, 0.0)
            return _scan(alpha, b)
        return _scan(alpha, b) + np.r_[1.0, np.cumprod(alpha)] * e0

    def _slope(self, u: np.ndarray) -> np.ndarray:
        s = np.zeros(self.n)
        ok = self.same[:-1]
        s[:-1][ok] = np.diff(u)[ok] / self.h[:-1][ok]
        return s

    def moves(self, a: str) -> bool:
        return a in self.u and float(np.ptp(self.u[a])) > 1e-9

    def direction(self, a: str) -> np.ndarray:
        """Sign of the last commanded direction per interval, held through stops; before the first
        move of a segment, the direction of that move."""
        if a in self._dir:
            return self._dir[a]
        s = self.slope[a]
        scale = max(1e-12, 1e-12 * float(np.max(np.abs(self.u[a]))))
        nz = np.abs(s * self.h) > scale
        idx = np.arange(self.n)
        f = np.maximum.accumulate(np.where(nz, idx, -1))
        f_ok = f >= self.first_of
        bk = np.minimum.accumulate(np.where(nz, idx, self.n)[::-1])[::-1]
        b_ok = bk <= self.last_of
        pick = np.where(f_ok, f, np.where(b_ok, bk, -1))
        d = np.where(pick >= 0, np.sign(s[np.clip(pick, 0, None)]), 0.0)
        self._dir[a] = d
        return d

    def locate(self, te: np.ndarray, seg_e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Interval index k and offset x = te - t_k of evaluation times, clamped into the span of
        their own segment (held at rest before its first and after its last row)."""
        sid = np.searchsorted(self.seg[self.starts], seg_e)
        sid = np.clip(sid, 0, len(self.starts) - 1)
        s0, s1 = self.starts[sid], self.ends[sid]
        tc = np.clip(te, self.t[s0], self.t[s1])
        k = np.searchsorted(self.t, tc, side="right") - 1
        k = np.clip(k, s0, s1)
        return k, tc - self.t[k]

    def follow(self, a: str, tau: float, k: np.ndarray, x: np.ndarray) -> np.ndarray:
        """Axis `a` at the evaluation points through a first-order lag of time constant tau (exact
        for the piecewise-linear command; the lag restarts at rest at each segment start)."""
        u, s = self.u[a], self.slope[a]
        cmd = u[k] + s[k] * x
        if tau <= 0.0:
            return cmd
        e = self.scan(tau, s)
        a_x = np.exp(-x / tau)
        return cmd - (a_x * e[k] + (1.0 - a_x) * s[k] * tau)

    def spindle_response(self, tau: float, k: np.ndarray, x: np.ndarray) -> np.ndarray:
        """y with tau dy/dt = S/1000 - y, y = 0 at the program start (cold), at the points."""
        S = self.S / 1000.0
        sl = self.S_slope / 1000.0
        # y = 0 at the start means the error e = u - y starts at u(0)
        e = self.scan(tau, sl, reset=False, e0=float(S[0]))
        a_x = np.exp(-x / tau)
        u = S[k] + sl[k] * x
        return u - (a_x * e[k] + (1.0 - a_x) * sl[k] * tau)

    def spindle_angle(self, k: np.ndarray, x: np.ndarray) -> np.ndarray:
        return self.S_angle[k] + (self.S[k] * x + 0.5 * self.S_slope[k] * x * x) * (2 * np.pi / 60.0)


# ==============================================================================================
# geometric errors through the chain
def geometric_machine(machine: Machine, geometric: Mapping[str, float], spindle: Any = None) -> Machine:
    """The machine with ErrorModel geometric parameters (and a spindle screw) applied:
    ``ErrorModel(geometric, spindle).apply(machine)`` (camsmooth.machine.model has the definitions)."""
    from camsmooth.machine.model import ErrorModel

    geo = {k: float(v) for k, v in geometric.items() if v != 0.0}
    if not geo and spindle is None:
        return machine
    return ErrorModel(geometric=geo, spindle=spindle).apply(machine)


# ==============================================================================================
# the simulator
class _Cache(dict):
    def put(self, key: Any, value: Any, limit: int = 6) -> Any:
        if len(self) >= limit:
            self.pop(next(iter(self)))
        self[key] = value
        return value


class Simulator:
    """Simulates recorded channels at given times from a program, a machine and Physics.

    Evaluation times are clamped into their program segment (the machine rests before and
    after). Parts are cached by the parameters they depend on, so a finite-difference Jacobian
    only recomputes what a parameter touches.
    """

    def __init__(self, program: Program, machine: Machine, t: np.ndarray, segment: np.ndarray,
                 channels: Sequence[str], knots: _Knots | None = None) -> None:
        self.program = program
        self.machine = machine
        self.kn = knots if knots is not None else _Knots(program)
        self.t = np.asarray(t, float)
        self.segment = np.asarray(segment)
        self.channels = list(channels)
        self.need_pose = any(c in TIP_CHANNELS or c in DIR_CHANNELS for c in self.channels)
        self._loc, self._axis, self._pose, self._therm, self._angle = (_Cache() for _ in range(5))

    def loc(self, offset: float) -> tuple[np.ndarray, np.ndarray]:
        if offset not in self._loc:
            self._loc.put(offset, self.kn.locate(self.t - offset, self.segment))
        return self._loc[offset]

    def axis(self, a: str, ph: Physics) -> np.ndarray | float:
        """Actual position of axis a (mm or rad) at the evaluation times."""
        if a not in self.kn.u:
            return 0.0
        tau = float(ph.tau.get(a, 0.0))
        b = float(ph.backlash.get(a, 0.0))
        key = (a, tau, ph.offset_s, b)
        if key not in self._axis:
            k, x = self.loc(ph.offset_s)
            y = self.kn.follow(a, tau, k, x)
            if b != 0.0:
                y = y - 0.5 * b * self.kn.direction(a)[k]
            self._axis.put(key, y, limit=16)
        return self._axis[key]

    def _pose_of(self, ph: Physics) -> tuple[list[np.ndarray], list[list[np.ndarray]]]:
        axes = {a: self.axis(a, ph) for a in AXES}
        key = (tuple((a, ph.tau.get(a, 0.0), ph.backlash.get(a, 0.0)) for a in AXES), ph.offset_s,
               tuple(sorted((k, v) for k, v in ph.geometric.items() if v != 0.0)))
        if key not in self._pose:
            m = geometric_machine(self.machine, ph.geometric, ph.spindle)
            n = len(self.t)
            # idle axes stay scalar zeros: the chain then skips their joints
            q = {a: (float(v) if np.ndim(v) == 0 else v) for a, v in axes.items()}
            f = m.chain.forward(q)
            p = [np.broadcast_to(np.asarray(f.p[i], float), (n,)) for i in range(3)]
            R = [[np.broadcast_to(np.asarray(f.R[i][j], float), (n,)) for j in range(3)] for i in range(3)]
            self._pose.put(key, (p, R), limit=4)
        return self._pose[key]

    def thermal_unit(self, tau: float, offset: float) -> np.ndarray:
        key = (tau, offset)
        if key not in self._therm:
            k, x = self.loc(offset)
            self._therm.put(key, self.kn.spindle_response(tau, k, x), limit=24)
        return self._therm[key]

    def spindle_angle(self, offset: float) -> np.ndarray:
        if offset not in self._angle:
            k, x = self.loc(offset)
            self._angle.put(offset, self.kn.spindle_angle(k, x))
        return self._angle[offset]

    def run(self, ph: Physics) -> np.ndarray:
        """(M, C) simulated channels in ``self.channels`` order (internal units)."""
        n = len(self.t)
        out = np.empty((n, len(self.channels)))
        for j, c in enumerate(self.channels):
            if c in AXIS_CHANNELS:
                out[:, j] = self.axis(c[0], ph)
        if not self.need_pose:
            return out
        p, R = self._pose_of(ph)
        tip = [p[0], p[1], p[2]]
        ax = [R[0][2], R[1][2], R[2][2]]
        has_S = self.kn.S is not None
        local_tip: list[Any] = [0.0, 0.0, 0.0]
        tilt: dict[str, np.ndarray] = {}
        if has_S:
            for el, (g, tau) in ph.thermal.items():
                if g == 0.0:
                    continue
                d = g * self.thermal_unit(float(tau), ph.offset_s)
                if el in ("dx", "dy", "dz"):
                    i = "xyz".index(el[1])
                    local_tip[i] = local_tip[i] + d
                else:
                    tilt[el] = d
            rc, rs = ph.runout
            if rc != 0.0 or rs != 0.0:
                th = self.spindle_angle(ph.offset_s)
                c, s = np.cos(th), np.sin(th)
                local_tip[0] = local_tip[0] + rc * c - rs * s
                local_tip[1] = local_tip[1] + rc * s + rs * c
        if any(np.ndim(v) > 0 or v != 0.0 for v in local_tip):
            tip = [tip[i] + R[i][0] * local_tip[0] + R[i][1] * local_tip[1] + R[i][2] * local_tip[2]
                   for i in range(3)]
        if tilt:
            # the tilt convention of ErrorModel.thermal_frame: rotation by (eyz, -exz, 0) about the tip
            from camsmooth.machine.model import thermal_frame

            Rt = thermal_frame(tilt).R
            loc = [Rt[0][2], Rt[1][2], Rt[2][2]]
            ax = [R[i][0] * loc[0] + R[i][1] * loc[1] + R[i][2] * loc[2] for i in range(3)]
        for j, c in enumerate(self.channels):
            if c in TIP_CHANNELS:
                out[:, j] = tip[TIP_CHANNELS.index(c)]
            elif c in DIR_CHANNELS:
                out[:, j] = ax[DIR_CHANNELS.index(c)]
        return out

    # ---- states at the evaluation times (for locate, plots and initial estimates) -------------
    def states(self) -> dict[str, np.ndarray]:
        """Commanded states at the evaluation times (no offset): per axis position ``pos_<a>``,
        velocity ``v_<a>`` (slope of the row interval), acceleration ``acc_<a>`` (change of
        slope between intervals over the mean interval), direction ``dir_<a>``; ``S`` (rpm),
        ``spindle_angle`` (rad), ``elapsed`` (s since the program start), ``row`` (program row)."""
        k, x = self.loc(0.0)
        kn = self.kn
        st: dict[str, np.ndarray] = {"row": k, "elapsed": self.t - kn.t[0]}
        hm = np.maximum(0.5 * (kn.h + np.r_[kn.h[:1], kn.h[:-1]]), 1e-12)
        for a, u in kn.u.items():
            s = kn.slope[a]
            st[f"pos_{a}"] = u[k] + s[k] * x
            st[f"v_{a}"] = s[k]
            sp = np.r_[0.0, s[:-1]]
            sp[kn.starts] = 0.0
            acc = (s - sp) / hm
            # the slope change at knot k belongs to the interval on either side; take the larger
            acc_n = np.r_[acc[1:], 0.0]
            st[f"acc_{a}"] = np.where(np.abs(acc[k]) > np.abs(acc_n[k]), acc[k], acc_n[k])
            st[f"dir_{a}"] = kn.direction(a)[k]
        if kn.S is not None:
            st["S"] = kn.S[k] + kn.S_slope[k] * x
            st["spindle_angle"] = kn.spindle_angle(k, x)
        return st


# ==============================================================================================
# noise floor, outliers, intervals
def _mad(x: np.ndarray) -> float:
    if len(x) == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


def white_noise(residual: np.ndarray, segment: np.ndarray) -> float:
    """Robust white-noise sigma of a residual: 1.4826 MAD of its second differences (inside one
    segment) / sqrt(6); smooth structure cancels, sparse events are ignored by the median."""
    r = residual
    same = (segment[2:] == segment[:-2])
    d2 = (r[2:] - 2 * r[1:-1] + r[:-2])[same]
    return _mad(d2) / math.sqrt(6.0)


def noise_floor(residual: np.ndarray, segment: np.ndarray, q_rec: np.ndarray, q_cmd: np.ndarray,
                white: float | None = None) -> tuple[np.ndarray, dict[str, float]]:
    """Per-sample noise floor of one channel: max(white, quantisation); white from
    ``white_noise`` unless given, quantisation = sqrt(q_rec^2 + q_cmd^2) / sqrt(12) per sample
    (q_cmd: the step of a logged command, 0 for an exact program)."""
    if white is None:
        white = white_noise(residual, segment)
    quant = np.sqrt(q_rec ** 2 + q_cmd ** 2) / math.sqrt(12.0)
    floor = np.maximum(white, quant)
    info = {"white": white, "quantisation_rms": float(np.sqrt(np.mean(quant ** 2))),
            "q_recording_rms": rms_step(q_rec), "q_command_rms": rms_step(q_cmd),
            "rms": float(np.sqrt(np.mean(floor ** 2)))}
    return floor, info


def _median5(r: np.ndarray) -> np.ndarray:
    from scipy.ndimage import median_filter

    return median_filter(r, size=5, mode="nearest")


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(start, stop) index pairs of True runs."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist(), strict=True))


def locate_intervals(t: np.ndarray, resid: np.ndarray, floor: np.ndarray, valid: np.ndarray,
                     channels: Sequence[str], states: Mapping[str, np.ndarray], segment: np.ndarray,
                     k_sigma: float = 3.0, max_intervals: int = 20) -> dict[str, Any]:
    """Intervals where |residual| > k_sigma floors on some channel (runs of at least 3 samples
    or single peaks above 2 k_sigma; runs closer than 5 sample periods merge), ranked by the peak
    |r|/floor, with the states there and the largest deviations."""
    z = np.where(valid, np.abs(resid) / floor, 0.0)
    above = (z > k_sigma).any(axis=1)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    runs = _runs(above)
    merged: list[list[int]] = []
    for s, e in runs:
        if merged and t[s] - t[merged[-1][1] - 1] <= 5 * dt and segment[s] == segment[merged[-1][0]]:
            merged[-1][1] = e
        else:
            merged.append([s, e])
    zmax = z.max(axis=1)
    keep = [(s, e) for s, e in merged if (e - s >= 3 or zmax[s:e].max() > 2 * k_sigma)]
    peaks = [float(zmax[s:e].max()) for s, e in keep]
    order = np.argsort(peaks)[::-1][:max_intervals]
    axes = [k[2:] for k in states if k.startswith("v_")]
    vscale = {a: max(1e-12, float(np.percentile(np.abs(states[f"v_{a}"]), 95))) for a in axes}
    ascale = {a: max(1e-12, float(np.percentile(np.abs(states[f"acc_{a}"]), 95))) for a in axes}
    out = []
    for i in order:
        s, e = keep[i]
        item: dict[str, Any] = {"t_start": float(t[s]), "t_end": float(t[e - 1]), "samples": int(e - s),
                                "segment": int(segment[s]),
                                "program_rows": [int(states["row"][s]) + 1, int(states["row"][e - 1]) + 1],
                                "elapsed_s": float(states["elapsed"][s]),
                                "peak_sigma": float(zmax[s:e].max())}
        chans = {}
        for j, c in enumerate(channels):
            zz = z[s:e, j]
            if zz.max() > k_sigma:
                m = int(np.argmax(zz))
                chans[c] = {"peak": float(resid[s + m, j]), "t_peak": float(t[s + m]),
                            "rms": float(np.sqrt(np.mean(resid[s:e, j][valid[s:e, j]] ** 2)))
                            if valid[s:e, j].any() else None,
                            "unit": channel_unit(c)}
        item["channels"] = chans
        ax_states = {}
        for a in axes:
            v = states[f"v_{a}"][s:e]
            acc = states[f"acc_{a}"][s:e]
            d = states[f"dir_{a}"][max(s - 1, 0):e + 1]
            pos = states[f"pos_{a}"][s:e]
            st = {"moving": bool(np.mean(np.abs(v) > 0.02 * vscale[a]) > 0.5),
                  "mean_speed": float(np.mean(np.abs(v))) * (180 / np.pi if a in ROTARY_AXES else 1.0),
                  "reversing": bool(np.any(d[1:] * d[:-1] < 0)),
                  "accelerating": bool(np.any(np.abs(acc) > 0.1 * ascale[a]))}
            if a in ROTARY_AXES:
                st["position_deg"] = [float(np.degrees(pos.min())), float(np.degrees(pos.max()))]
            ax_states[a] = st
        item["axes"] = ax_states
        if "S" in states:
            item["spindle_on"] = bool(np.any(states["S"][s:e] > 0))
            item["spindle_mean"] = float(np.mean(states["S"][s:e]))
        out.append(item)
    # largest single deviations
    zf = z.reshape(-1)
    top = np.argpartition(zf, -10)[-10:] if zf.size > 10 else np.arange(zf.size)
    flat = top[np.argsort(zf[top])[::-1]]
    largest = []
    for f in flat:
        i, j = np.unravel_index(f, z.shape)
        if z[i, j] <= 0:
            break
        largest.append({"t": float(t[i]), "channel": channels[j], "residual": float(resid[i, j]),
                        "sigma": float(z[i, j]), "program_row": int(states["row"][i]) + 1})
    return {"count": len(keep), "fraction_of_time_above": float(np.mean(above)), "threshold_sigma": k_sigma,
            "intervals": out, "largest": largest}


# ==============================================================================================
# candidate library
@dataclass
class Param:
    name: str
    lo: float
    hi: float
    scale: float


class Candidate:
    """One candidate physics: parameters, how they enter Physics, an initial guess, and how its
    fitted values are reported. Fit and score are done by ``Selector`` through the simulator."""

    name = ""
    needs = ""  # plain words for reports

    def applicable(self, P: Problem) -> str | None:
        """None when the data can show this effect, else the reason it cannot."""
        return None

    def params(self, P: Problem) -> list[Param]:
        raise NotImplementedError

    def write(self, ph: Physics, names: Sequence[str], x: np.ndarray) -> None:
        raise NotImplementedError

    def read(self, ph: Physics, names: Sequence[str]) -> np.ndarray:
        raise NotImplementedError

    def initial(self, P: Problem, ph: Physics, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        """A starting point; default: one Gauss-Newton step from the base values."""
        return _gn_initial(P, self, ph, names, self.read(ph, names))

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        """(parameters, uncertainties, units) in report units."""
        return ({n: float(v) for n, v in zip(names, x, strict=True)},
                {n: float(s) for n, s in zip(names, sd, strict=True)}, {n: "" for n in names})

    def veto(self, P: Problem, names: Sequence[str], x: np.ndarray) -> str | None:
        """A reason to refuse a fitted value that makes the term something else, or None."""
        return None

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        """(label, values at the fit samples, unit) of the state this effect depends on."""
        return "elapsed time (s)", P.states["elapsed"], "s"


def _gn_initial(P: Problem, cand: Candidate, ph: Physics, names: Sequence[str], x0: np.ndarray) -> np.ndarray:
    """One Gauss-Newton step from x0 on the fit samples (finite-difference columns)."""
    params = cand.params(P)
    scale = np.array([p.scale for p in params])
    base = ph.copy()
    cand.write(base, names, x0)
    s0 = P.sim_fit.run(base)
    r0 = ((P.data_fit - s0) * P.w_fit)[P.valid_fit]
    cols = []
    for j in range(len(names)):
        x = x0.copy()
        x[j] += scale[j]
        trial = base.copy()
        cand.write(trial, names, x)
        cols.append(((P.sim_fit.run(trial) - s0) * P.w_fit)[P.valid_fit] / scale[j])
    H, g = _gram(np.stack(cols), r0)
    step = np.linalg.pinv(H) @ g
    lo = np.array([p.lo for p in params])
    hi = np.array([p.hi for p in params])
    return np.clip(x0 + step, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))


class ServoLag(Candidate):
    name = "servo_lag"
    needs = "moving axes"

    def _axes(self, P: Problem) -> list[str]:
        return [a for a in AXES if P.knots.moves(a)]

    def applicable(self, P: Problem) -> str | None:
        return None if self._axes(P) else "no axis moves in the program"

    def params(self, P: Problem) -> list[Param]:
        return [Param(f"tau_{a}", 0.0, 2.0, 1e-3) for a in self._axes(P)]

    def write(self, ph: Physics, names: Sequence[str], x: np.ndarray) -> None:
        for n, v in zip(names, x, strict=True):
            ph.tau[n[4:]] = float(v)

    def read(self, ph: Physics, names: Sequence[str]) -> np.ndarray:
        return np.array([ph.tau.get(n[4:], 0.0) for n in names])

    def initial(self, P: Problem, ph: Physics, names: Sequence[str], resid: np.ndarray) -> np.ndarray:
        x = self.read(ph, names)
        for i, n in enumerate(names):
            a = n[4:]
            c = f"{a}_act"
            if c in P.channels and x[i] == 0.0:
                j = P.channels.index(c)
                v = P.states[f"v_{a}"]
                ok = P.valid_fit[:, j]
                den = float(np.sum(v[ok] ** 2))
                x[i] = float(np.clip(-np.sum(resid[ok, j] * v[ok]) / den, 0.0, 1.0)) if den > 0 else 0.01
            elif x[i] == 0.0:
                x[i] = 0.01
        return x

    def report(self, names, x, sd):
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            a = n[4:]
            key = f"Kv_{a}"
            par[key] = float(1.0 / v) if v > 0 else None
            unc[key] = float(s / v ** 2) if v > 0 and np.isfinite(s) else None
            unit[key] = "1/s"
        return par, unc, unit

    def state(self, P, names):
        a = max(names, key=lambda n: np.std(P.states[f"v_{n[4:]}"]))[4:]
        unit = "deg/s" if a in ROTARY_AXES else "mm/s"
        f = np.degrees(1.0) if a in ROTARY_AXES else 1.0
        return f"commanded velocity {a} ({unit})", P.states[f"v_{a}"] * f, unit


class TimeOffset(Candidate):
    name = "time_offset"
    needs = "moving axes"

    def applicable(self, P):
        return None if any(P.knots.moves(a) for a in AXES) or P.knots.S is not None else "nothing moves"

    def params(self, P):
        span = float(P.t[-1] - P.t[0])
        b = min(5.0, 0.25 * span)
        return [Param("offset_s", -b, b, 1e-3)]

    def write(self, ph, names, x):
        ph.offset_s = float(x[0])

    def read(self, ph, names):
        return np.array([ph.offset_s])

    def initial(self, P, ph, names, resid):
        num = den = 0.0
        for a in AXES:
            c = f"{a}_act"
            if c in P.channels and P.knots.moves(a):
                j = P.channels.index(c)
                ok = P.valid_fit[:, j]
                v = P.states[f"v_{a}"][ok] * P.w_fit[ok, j]
                num += float(np.sum(resid[ok, j] * P.w_fit[ok, j] * v))
                den += float(np.sum(v * v))
        x0 = ph.offset_s + (-num / den if den > 0 else 0.0)
        p = self.params(P)[0]
        return np.array([float(np.clip(x0, p.lo, p.hi))])

    def report(self, names, x, sd):
        return {"offset_s": float(x[0])}, {"offset_s": float(sd[0])}, {"offset_s": "s"}

    def state(self, P, names):
        a = max((a for a in AXES if f"v_{a}" in P.states), key=lambda a: np.std(P.states[f"v_{a}"]))
        return f"commanded velocity {a}", P.states[f"v_{a}"], "mm/s"


class Backlash(Candidate):
    name = "backlash"
    needs = "axis reversals"

    def _axes(self, P):
        out = []
        for a in AXES:
            if P.knots.moves(a):
                d = P.knots.direction(a)
                if np.any(d[1:] * d[:-1] < 0):
                    out.append(a)
        return out

    def applicable(self, P):
        return None if self._axes(P) else "no axis reverses in the program"

    def params(self, P):
        return [Param(f"b_{a}", -0.2 if a in ROTARY_AXES else -10.0, 0.2 if a in ROTARY_AXES else 10.0,
                      1e-5 if a in ROTARY_AXES else 1e-3) for a in self._axes(P)]

    def write(self, ph, names, x):
        for n, v in zip(names, x, strict=True):
            ph.backlash[n[2:]] = float(v)

    def read(self, ph, names):
        return np.array([ph.backlash.get(n[2:], 0.0) for n in names])

    def report(self, names, x, sd):
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            a = n[2:]
            f = math.degrees(1.0) if a in ROTARY_AXES else 1.0
            par[f"backlash_{a}"] = float(v * f)
            unc[f"backlash_{a}"] = float(s * f)
            unit[f"backlash_{a}"] = "deg" if a in ROTARY_AXES else "mm"
        return par, unc, unit

    def state(self, P, names):
        a = names[0][2:]
        return f"last direction of {a} (-1/+1)", P.states[f"dir_{a}"], "1"


class _Geometric(Candidate):
    """Geometric ErrorModel parameters through the chain; only the parameters the program's
    motion can show (checked by the rank of their columns) are fitted."""

    keys: tuple[str, ...] = ()
    channels_seen: tuple[str, ...] = TIP_CHANNELS + DIR_CHANNELS

    def _present(self, P):
        return [c for c in P.channels if c in self.channels_seen]

    def candidates_for(self, P):
        return list(self.keys)

    def applicable(self, P):
        if not self._present(P):
            return "needs measured tool-tip or tool-axis channels"
        if not self.params(P):
            return "the program's motion does not show these parameters"
        return None

    def params(self, P):
        key = self.name
        if key not in P.identifiable:
            P.identifiable[key] = _identifiable(P, self, self.candidates_for(P))
        return [Param(n, -5.0 if n not in _GEO_ANGLES else -0.05, 5.0 if n not in _GEO_ANGLES else 0.05,
                      1e-6 if n in _GEO_ANGLES else 1e-3) for n in P.identifiable[key]]

    def write(self, ph, names, x):
        for n, v in zip(names, x, strict=True):
            ph.geometric[n] = float(v)

    def read(self, ph, names):
        return np.array([ph.geometric.get(n, 0.0) for n in names])

    def report(self, names, x, sd):
        unit = {n: ("rad" if n in _GEO_ANGLES else "mm") for n in names}
        return ({n: float(v) for n, v in zip(names, x, strict=True)},
                {n: float(s) for n, s in zip(names, sd, strict=True)}, unit)


def _identifiable(P: Problem, cand: Candidate, names: Sequence[str]) -> list[str]:
    """Parameters whose weighted-residual columns are not negligible and not linear combinations
    of earlier ones (pivoted QR at the base model)."""
    if not names:
        return []
    base = P.base.copy()
    scale = np.array([1e-6 if n in _GEO_ANGLES else 1e-3 for n in names])
    s0 = P.sim_fit.run(base)
    cols = []
    for j, n in enumerate(names):
        trial = base.copy()
        trial.geometric[n] = trial.geometric.get(n, 0.0) + scale[j]
        cols.append(((P.sim_fit.run(trial) - s0) * P.w_fit)[P.valid_fit])
    J = np.stack(cols, axis=1)
    norms = np.linalg.norm(J, axis=0)
    # a parameter the motion cannot show moves the simulation by round-off only
    ok = norms > max(1e-8, 1e-6 * float(norms.max()))
    if not ok.any():
        return []
    from scipy.linalg import qr

    idx = np.flatnonzero(ok)
    Jn = J[:, idx] / norms[idx]
    _, Rm, piv = qr(Jn, mode="economic", pivoting=True)
    d = np.abs(np.diag(Rm))
    keep = sorted(idx[piv[d > 1e-3 * d[0]]].tolist())
    return [names[i] for i in keep]


class RotaryLocation(_Geometric):
    name = "rotary_location"
    channels_seen = TIP_CHANNELS

    def candidates_for(self, P):
        out = []
        if P.knots.moves("A"):
            out += ["EY0A", "EZ0A"]
        if P.knots.moves("B"):
            out += ["EX0B", "EZ0B"]
        return out

    def state(self, P, names):
        a = "A" if any(n.endswith("A") for n in names) else "B"
        return f"rotary axis {a} (deg)", np.degrees(P.states[f"pos_{a}"]), "deg"


class RotarySquareness(_Geometric):
    name = "rotary_squareness"

    def candidates_for(self, P):
        out = []
        if P.knots.moves("A"):
            out += ["EB0A", "EC0A"]
        if P.knots.moves("B"):
            out += ["EA0B", "EC0B"]
        return out

    state = RotaryLocation.state


class SpindleTilt(_Geometric):
    name = "spindle_tilt"
    keys = ("EA0S", "EB0S")

    def state(self, P, names):
        if "pos_B" in P.states and P.knots.moves("B"):
            return "rotary axis B (deg)", np.degrees(P.states["pos_B"]), "deg"
        return RotaryLocation.state(self, P, ["EA"])


class ToolLength(_Geometric):
    name = "tool_length"
    keys = ("EZ0T",)
    channels_seen = TIP_CHANNELS

    def state(self, P, names):
        if P.knots.moves("A") or P.knots.moves("B"):
            a = "A" if P.knots.moves("A") else "B"
            return f"rotary axis {a} (deg)", np.degrees(P.states[f"pos_{a}"]), "deg"
        return "elapsed time (s)", P.states["elapsed"], "s"


class SpindleRunout(Candidate):
    name = "spindle_runout"

    def applicable(self, P):
        if not any(c in P.channels for c in TIP_CHANNELS):
            return "needs measured tool-tip channels"
        if P.knots.S is None or not np.any(P.knots.S != 0):
            return "the spindle does not turn in the program"
        return None

    def params(self, P):
        return [Param("rc", -5.0, 5.0, 1e-3), Param("rs", -5.0, 5.0, 1e-3)]

    def write(self, ph, names, x):
        ph.runout = (float(x[0]), float(x[1]))

    def read(self, ph, names):
        return np.array(ph.runout, float)

    def report(self, names, x, sd):
        r = float(math.hypot(x[0], x[1]))
        phi = float(math.degrees(math.atan2(x[1], x[0])))
        sr = float(math.sqrt((x[0] * sd[0]) ** 2 + (x[1] * sd[1]) ** 2) / r) if r > 0 else float(max(sd))
        sphi = float(math.degrees(sr / r)) if r > 0 else None
        return ({"radius": r, "phase_deg": phi}, {"radius": sr, "phase_deg": sphi},
                {"radius": "mm", "phase_deg": "deg"})

    def state(self, P, names):
        return "spindle angle (deg, mod 360)", np.degrees(np.mod(P.states["spindle_angle"], 2 * np.pi)), "deg"


class ThermalDrift(Candidate):
    name = "thermal_drift"

    def _elements(self, P):
        out = []
        if any(c in P.channels for c in TIP_CHANNELS):
            out += ["dx", "dy", "dz"]
        if "axis_i" in P.channels or "axis_j" in P.channels:
            out += ["exz", "eyz"]
        return out

    def applicable(self, P):
        if not self._elements(P):
            return "needs measured tool-tip or tool-axis channels"
        if P.knots.S is None or not np.any(P.knots.S > 0):
            return "the spindle does not turn in the program"
        return None

    def params(self, P):
        if "thermal" not in P.identifiable:
            P.identifiable["thermal"] = self.select_elements(P, P.base)
        span = float(P.t[-1] - P.t[0])
        out = []
        for el in P.identifiable["thermal"]:
            ang = el.startswith("e")
            out.append(Param(f"gain_{el}", -1.0 if ang else -100.0, 1.0 if ang else 100.0, 1e-6 if ang else 1e-3))
            # a time constant far below the record cannot be told from a constant offset
            out.append(Param(f"tau_{el}", max(1e-3, 2 * P.dt, 0.05 * span), 20.0 * span, 1.0))
        return out

    def _tau_grid(self, P):
        span = float(P.t[-1] - P.t[0])
        return [span * f for f in (0.06, 0.1, 0.2, 0.4, 0.8, 1.6, 3.2)]

    def _element_fit(self, P, el, resid, base):
        """Best (gain, tau, fraction of the residual's sum of squares removed, z) for one element
        alone, by linear regression of the residual on its unit response over a tau grid."""
        base = base.copy()
        base.thermal.pop(el, None)
        s0 = P.sim_fit.run(base)
        r = (resid * P.w_fit)[P.valid_fit]
        rss0 = _dot(r, r)
        best = (0.0, 1.0, 0.0, 0.0)
        for tau in self._tau_grid(P):
            trial = base.copy()
            g0 = 1.0 if not el.startswith("e") else 1e-3
            trial.thermal[el] = (g0, tau)
            col = ((P.sim_fit.run(trial) - s0) * P.w_fit)[P.valid_fit] / g0
            den = _dot(col, col)
            if den <= 0:
                continue
            g = _dot(col, r) / den
            drop = g * g * den / max(rss0, 1e-300)
            sd = math.sqrt(max(rss0 - g * g * den, 0.0) / max(len(r) - 1, 1) / den)
            if drop > best[2]:
                best = (g, tau, drop, abs(g) / max(sd, 1e-300))
        return best

    def select_elements(self, P, base):
        """The elements with a clear signal in the residual left by ``base`` (at least the
        strongest one, so the candidate can be scored); sets their starting values."""
        resid = P.data_fit - P.sim_fit.run(base)
        fits = {el: self._element_fit(P, el, resid, base) for el in self._elements(P)}
        P.thermal_init = {el: (f[0], f[1]) for el, f in fits.items()}
        strong = [el for el, f in fits.items() if f[2] > 1e-3 and f[3] > 8.0]
        if not strong and fits:
            strong = [max(fits, key=lambda e: fits[e][2])]
        return strong

    def write(self, ph, names, x):
        vals = dict(zip(names, x, strict=True))
        for n in names:
            if n.startswith("gain_"):
                el = n[5:]
                ph.thermal[el] = (float(vals[n]), float(vals[f"tau_{el}"]))

    def read(self, ph, names):
        out = []
        for n in names:
            el = n.split("_", 1)[1]
            g, tau = ph.thermal.get(el, (0.0, math.nan))
            out.append(g if n.startswith("gain_") else tau)
        return np.array(out, float)

    def initial(self, P, ph, names, resid):
        x = self.read(ph, names)
        init = getattr(P, "thermal_init", {})
        for i, n in enumerate(names):
            el = n.split("_", 1)[1]
            g, tau = init.get(el, (0.0, float(P.t[-1] - P.t[0]) * 0.2))
            if n.startswith("gain_") and x[i] == 0.0:
                x[i] = g
            if n.startswith("tau_") and not np.isfinite(x[i]):
                x[i] = tau
        lo = np.array([p.lo for p in self.params(P)])
        hi = np.array([p.hi for p in self.params(P)])
        return np.clip(x, lo, hi)

    def report(self, names, x, sd):
        par, unc, unit = {}, {}, {}
        for n, v, s in zip(names, x, sd, strict=True):
            el = n.split("_", 1)[1]
            key = f"{el}_{n.split('_', 1)[0]}"
            par[key], unc[key] = float(v), float(s)
            unit[key] = "s" if n.startswith("tau_") else ("rad per 1000 rpm" if el.startswith("e")
                                                         else "mm per 1000 rpm")
        return par, unc, unit

    def state(self, P, names):
        return "elapsed time (s)", P.states["elapsed"], "s"

    def veto(self, P, names, x):
        lo = {p.name: p.lo for p in self.params(P)}
        fast = [n[4:] for n, v in zip(names, x, strict=True) if n.startswith("tau_") and v <= 1.01 * lo[n]]
        if fast:
            bound = lo["tau_" + fast[0]]
            return (f"the fitted time constant of {', '.join(fast)} sits on its lower bound ({bound:.3g} s, "
                    "5% of the record): a step, not a drift; it cannot be told from a constant offset")
        return None


LIBRARY: tuple[Candidate, ...] = (ServoLag(), TimeOffset(), Backlash(), RotaryLocation(), RotarySquareness(),
                                  SpindleTilt(), SpindleRunout(), ToolLength(), ThermalDrift())

#: what separates two candidates that explain a residual equally well
SEPARATING = {
    frozenset({"servo_lag", "time_offset"}):
        "a move whose speed changes (an acceleration, a start or a reversal), recorded with a sampling "
        "period well below 1/Kv, separates them: a lag rounds the velocity corners with time constant 1/Kv, "
        "a clock offset only shifts them; and one clock offset gives every axis the same delay",
    frozenset({"servo_lag", "backlash"}):
        "moves of the same axis at two clearly different speeds, with a dwell after each reversal, separate "
        "them: lag grows with speed and vanishes at rest, backlash does not",
    frozenset({"time_offset", "backlash"}):
        "a dwell after each reversal separates them: an offset error vanishes at rest, backlash does not",
    frozenset({"rotary_location", "spindle_tilt"}):
        "measuring the tool axis as well as the tip, or sweeping the other rotary axis, separates them",
    frozenset({"rotary_location", "tool_length"}):
        "sweeping each rotary axis over a wider range separates them",
    frozenset({"rotary_squareness", "spindle_tilt"}):
        "sweeping each rotary axis separately over its range separates them",
    frozenset({"thermal_drift", "servo_lag"}):
        "a longer recording with the spindle stopped for a cool-down separates them",
}


def separating_measurement(a: str, b: str) -> str:
    return SEPARATING.get(frozenset({a, b}),
                          "a program that moves the machine through states where the two predictions differ "
                          "(other speeds, rotary positions or spindle speeds) separates them")


# ==============================================================================================
# the prepared problem
@dataclass
class Options:
    """Diagnosis settings. folds: blocked time folds for held-out scoring; margin: the relative
    fall of the pooled held-out RMS a term must bring; bic_margin: the fall of BIC it must bring;
    equivalent, equivalent_floor2: when two candidates explain the residual equally
    (``Selector._equivalent``); max_fit_samples: fits and scores
    use at most this many samples (an even random subset, seeded) - final figures use all."""

    folds: int = 5
    margin: float = 0.02
    bic_margin: float = 6.0
    equivalent: float = 0.01
    equivalent_floor2: float = 0.05
    max_fit_samples: int = 120_000
    max_terms: int = 6
    seed: int = 0
    candidates: tuple[str, ...] = CANDIDATES


@dataclass
class Problem:
    """Program, recording and everything the fits share: channels, data, floors, weights,
    validity (outliers out), folds and the fit subset (``*_fit`` arrays)."""

    program: Program
    machine: Machine
    aligned: Aligned
    base: Physics
    channels: list[str]
    knots: _Knots
    t: np.ndarray
    segment: np.ndarray
    data: np.ndarray
    floor: np.ndarray
    floor_info: dict[str, dict[str, float]]
    valid: np.ndarray
    outliers: list[dict[str, Any]]
    fit_idx: np.ndarray
    folds: np.ndarray
    sim_fit: Simulator
    states: dict[str, np.ndarray]
    dt: float
    identifiable: dict[str, list[str]] = field(default_factory=dict)
    thermal_init: dict[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def data_fit(self) -> np.ndarray:
        return self._data_fit

    def finish(self) -> None:
        self._data_fit = self.data[self.fit_idx]
        self.w_fit = 1.0 / self.floor[self.fit_idx]
        self.valid_fit = self.valid[self.fit_idx]


def _command_quantum(program: Program, channel: str, knots: _Knots, k: np.ndarray) -> np.ndarray:
    q = program.quantum
    if channel in AXIS_CHANNELS:
        a = channel[0]
        v = q.get(a)
        return np.zeros(len(k)) if v is None else np.broadcast_to(np.asarray(v, float), (knots.n,))[k]
    names = ("X", "Y", "Z") if channel in TIP_CHANNELS else ROTARY_AXES
    parts = [np.broadcast_to(np.asarray(q[a], float), (knots.n,))[k] for a in names if a in q]
    return np.sqrt(np.sum(np.square(parts), axis=0)) if parts else np.zeros(len(k))


def prepare(program: Program, recording: Recording, machine: Machine | None = None,
            base: Physics | None = None, options: Options | None = None,
            white: Mapping[str, float] | None = None, valid: np.ndarray | None = None) -> Problem:
    """Align, simulate the baseline, estimate floors, mark outliers, make folds and the fit
    subset (module docstring). white / valid: white-noise sigmas and the outlier mask to use
    instead of estimating them (the second pass of ``diagnose``)."""
    opt = options or Options()
    machine = machine or load_machine(None)
    base = base or Physics()
    al = align(program, recording)
    channels = [c for c in CHANNELS if c in al.channels]
    knots = _Knots(program)
    sim_all = Simulator(program, machine, al.t, al.segment, channels, knots)
    data = np.column_stack([al.channels[c] for c in channels])
    sim0 = sim_all.run(base)
    resid = data - sim0
    k_all, _ = sim_all.loc(0.0)
    floor = np.empty_like(data)
    info = {}
    for j, c in enumerate(channels):
        q_rec = np.broadcast_to(np.asarray(al.quantum.get(c, 0.0), float), (len(al.t),))
        q_cmd = _command_quantum(program, c, knots, k_all)
        f, inf = noise_floor(resid[:, j], al.segment, q_rec, q_cmd, None if white is None else white[c])
        inf["white_from"] = "baseline residual" if white is None else "residual after the named effects"
        # a floor of exactly zero (noise-free synthetic data) would make weights infinite
        tiny = 1e-9 * max(1.0, float(np.max(np.abs(data[:, j])))) if c not in DIR_CHANNELS else 1e-12
        floor[:, j] = np.maximum(f, tiny)
        inf["unit"] = channel_unit(c)
        info[c] = inf
    outliers = []
    given_valid = valid
    valid = np.ones_like(data, dtype=bool) if given_valid is None else given_valid
    for j, c in enumerate(channels if given_valid is None else ()):
        dev = np.abs(resid[:, j] - _median5(resid[:, j]))
        bad = dev > 20.0 * floor[:, j] + 1e-12
        valid[:, j] = ~bad
        for i in np.flatnonzero(bad)[:50]:
            outliers.append({"channel": c, "t": float(al.t[i]), "recorded": float(data[i, j]),
                             "simulated": float(sim0[i, j]), "residual": float(resid[i, j]),
                             "row": int(al.kept[i]) + 1})
        if bad.sum() > 50:
            outliers.append({"channel": c, "more": int(bad.sum() - 50)})
    M = len(al.t)
    if M > opt.max_fit_samples:
        rng = np.random.default_rng(opt.seed)
        fit_idx = np.sort(rng.choice(M, opt.max_fit_samples, replace=False))
    else:
        fit_idx = np.arange(M)
    nf = len(fit_idx)
    K = max(2, min(opt.folds, nf // 20))
    folds = np.minimum((np.arange(nf) * K) // nf, K - 1)
    sim_fit = Simulator(program, machine, al.t[fit_idx], al.segment[fit_idx], channels, knots)
    states = sim_fit.states()
    dt = float(np.median(np.diff(al.t))) if M > 1 else 1.0
    P = Problem(program=program, machine=machine, aligned=al, base=base, channels=channels, knots=knots,
                t=al.t, segment=al.segment, data=data, floor=floor, floor_info=info, valid=valid,
                outliers=outliers, fit_idx=fit_idx, folds=folds, sim_fit=sim_fit, states=states, dt=dt)
    P.sim_all = sim_all
    P.finish()
    return P


# ==============================================================================================
# fitting and scoring
def _dot(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product without BLAS: threaded BLAS dots of long vectors stall on a busy machine."""
    return float(np.einsum("i,i->", a, b))


def _gram(Jt: np.ndarray, r: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """J^T J (and J^T r) from the transposed Jacobian Jt (p, m), by ``_dot``."""
    p = len(Jt)
    H = np.empty((p, p))
    for i in range(p):
        for j in range(i, p):
            H[i, j] = H[j, i] = _dot(Jt[i], Jt[j])
    g = None if r is None else np.array([_dot(Jt[i], r) for i in range(p)])
    return H, g


def _lm(resid_fn: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, lo: np.ndarray, hi: np.ndarray,
        scale: np.ndarray, mask: np.ndarray, max_iter: int = 40, jac_at_end: bool = True,
        fixed_jt: np.ndarray | None = None
        ) -> tuple[np.ndarray, np.ndarray, float, int, np.ndarray | None, np.ndarray]:
    """Levenberg-Marquardt with box bounds for a few parameters and many residuals.

    resid_fn(x) returns the (n, C) floor-weighted residual; ``mask`` picks the entries that
    count. Forward-difference Jacobian (step 1e-4 of each parameter's scale, away from a bound);
    normal equations with Marquardt's diagonal scaling; parameters at a bound whose gradient
    pushes outward are frozen for the step. Returns (x, J^T J at x, cost = sum r^2, iterations,
    the transposed Jacobian at x (when ``jac_at_end``), the masked residual at x).
    With p parameters and m residuals each iteration costs p + 1 simulations and O(m p^2).
    fixed_jt: known Jacobian rows (transposed) for the first len(fixed_jt) parameters, reused as
    they are (the linearised part of a screening fit, ``Selector.screen``).
    """
    x = np.clip(np.asarray(x0, float).copy(), lo, hi)
    p = len(x)
    r = resid_fn(x)[mask]
    cost = _dot(r, r)

    def jac(x: np.ndarray, r: np.ndarray) -> np.ndarray:
        Jt = np.empty((p, len(r)))
        nf = 0 if fixed_jt is None else len(fixed_jt)
        if nf:
            Jt[:nf] = fixed_jt
        for j in range(nf, p):
            d = 1e-4 * scale[j]
            if x[j] + d > hi[j]:
                d = -d
            xj = x.copy()
            xj[j] += d
            Jt[j] = (resid_fn(xj)[mask] - r) / d
        return Jt

    lam = 1e-3
    it = 0
    H = None
    for it in range(1, max_iter + 1):  # noqa: B007
        H, g = _gram(jac(x, r), r)
        free = ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        if not free.any():
            break
        Hf = H[np.ix_(free, free)]
        dg = np.maximum(np.diag(Hf), 1e-30 * max(1.0, float(np.max(np.diag(Hf)))))
        accepted = small = False
        drop = 0.0
        for _ in range(12):
            try:
                step = -np.linalg.solve(Hf + lam * np.diag(dg), g[free])
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            dx = np.zeros(p)
            dx[free] = step
            xn = np.clip(x + dx, lo, hi)
            rn = resid_fn(xn)[mask]
            cn = _dot(rn, rn)
            if cn < cost or not np.isfinite(cost):
                small = bool(np.all(np.abs(xn - x) <= 1e-5 * np.maximum(np.abs(x), scale)))
                drop = (cost - cn) / max(cost, 1e-300)
                x, r, cost = xn, rn, cn
                lam = max(lam / 10.0, 1e-12)
                accepted = True
                break
            lam *= 10.0
        if not accepted or small or drop < 1e-8:
            break
    Jt = None
    if jac_at_end or H is None:
        Jt = jac(x, r)
        H, _ = _gram(Jt)
    return x, H, cost, it, Jt, r


@dataclass
class Fit:
    """A fitted set of candidates: names, parameter names and values, the physics, the
    covariance (internal units), full-data weighted RSS and per-channel RMS, held-out figures."""

    active: tuple[str, ...]
    pnames: dict[str, list[str]]
    x: np.ndarray
    physics: Physics
    cov: np.ndarray
    rss: float
    n: int
    n_eff: float
    bic: float
    rms_fit: dict[str, float]
    heldout_rss: float
    heldout_rms: dict[str, float]
    fold_rss: np.ndarray
    fold_n: np.ndarray
    heldout_resid: np.ndarray | None = None
    Jt: np.ndarray | None = None
    approximate: bool = False


def _cands(names: Sequence[str]) -> list[Candidate]:
    lib = {c.name: c for c in LIBRARY}
    return [lib[n] for n in names]


class Selector:
    """Greedy forward selection over the candidate library (module docstring)."""

    def __init__(self, P: Problem, opt: Options) -> None:
        self.P = P
        self.opt = opt
        self.cache: dict[tuple[str, ...], Fit] = {}
        self.elements: dict[tuple[str, ...], list[str]] = {}
        self.thermal_init: dict[tuple[str, ...], dict[str, tuple[float, float]]] = {}

    # ---- parameter vector <-> physics -------------------------------------------------------
    def _thermal_elements(self, key: tuple[str, ...]) -> list[str]:
        """Thermal elements for a candidate set: chosen on the residual left by the terms before
        thermal_drift in the set (the active set when it was added)."""
        key = key[:key.index("thermal_drift") + 1]  # later terms inherit the choice
        if key not in self.elements:
            base = self.fit(key[:-1]).physics
            self.elements[key] = ThermalDrift().select_elements(self.P, base)
            self.thermal_init[key] = dict(self.P.thermal_init)
        self.P.thermal_init = dict(self.thermal_init[key])
        return self.elements[key]

    def _layout(self, active: Sequence[str]) -> tuple[list[Candidate], dict[str, list[str]], list[Param]]:
        if "thermal_drift" in active:
            self.P.identifiable["thermal"] = self._thermal_elements(tuple(active))
        cands = _cands(active)
        pnames, params = {}, []
        for c in cands:
            ps = c.params(self.P)
            pnames[c.name] = [p.name for p in ps]
            params += ps
        return cands, pnames, params

    def _physics(self, cands, pnames, x) -> Physics:
        ph = self.P.base.copy()
        i = 0
        for c in cands:
            n = len(pnames[c.name])
            c.write(ph, pnames[c.name], x[i:i + n])
            i += n
        return ph

    def _resid(self, ph: Physics) -> np.ndarray:
        P = self.P
        return (P.data_fit - P.sim_fit.run(ph)) * P.w_fit

    def fit(self, active: Sequence[str], x0: np.ndarray | None = None) -> Fit:
        key = tuple(active)
        if key in self.cache:
            return self.cache[key]
        P = self.P
        cands, pnames, params = self._layout(active)
        folds = P.folds
        K = int(folds.max()) + 1
        valid = P.valid_fit
        if not params:
            r = self._resid(P.base)
            rr = np.where(valid, r, 0.0)
            fold_rss = np.array([float(np.sum(rr[folds == k] ** 2)) for k in range(K)])
            fold_n = np.array([int(valid[folds == k].sum()) for k in range(K)])
            n = int(valid.sum())
            rss = float(fold_rss.sum())
            rho = _lag1(rr)
            n_eff = max(2.0, n * (1 - rho) / (1 + rho))
            resid_phys = r / P.w_fit
            rms = _channel_rms(resid_phys, valid, P.channels)
            f = Fit(key, pnames, np.zeros(0), P.base.copy(), np.zeros((0, 0)), rss, n, n_eff,
                    n_eff * math.log(max(rss, 1e-300) / n), rms, rss, dict(rms), fold_rss, fold_n,
                    resid_phys)
            self.cache[key] = f
            return f
        lo = np.array([p.lo for p in params])
        hi = np.array([p.hi for p in params])
        scale = np.array([p.scale for p in params])
        if x0 is None:
            x0 = self._start(active, cands, pnames, params)
        x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))

        def rfun(x: np.ndarray) -> np.ndarray:
            return self._resid(self._physics(cands, pnames, x))

        f = self._fit_core(key, pnames, rfun, x0, lo, hi, scale, lambda x: self._physics(cands, pnames, x))
        self.cache[key] = f
        return f

    def _fit_core(self, key, pnames, rfun, x0, lo, hi, scale, physics_of, fixed_jt=None,
                  approximate: bool = False) -> Fit:
        """LM fit, covariance, blocked held-out scores. Held-out: for each fold, the parameters
        fitted without it, as one Gauss-Newton step from the full fit using only the other folds'
        rows of the Jacobian (exact for parameters that enter linearly, the first step of an exact
        refit otherwise); the held-out residual is then simulated at those parameters."""
        P = self.P
        folds = P.folds
        K = int(folds.max()) + 1
        valid = P.valid_fit
        x, H, rss, _, Jt, r_valid = _lm(rfun, x0, lo, hi, scale, valid, fixed_jt=fixed_jt)
        r = rfun(x)
        rr = np.where(valid, r, 0.0)
        n = int(valid.sum())
        rho = _lag1(rr)
        n_eff = max(len(x) + 2.0, n * (1 - rho) / (1 + rho))
        cov = np.linalg.pinv(H) * rss / max(n - len(x), 1) * (n / n_eff)
        entry_fold = np.broadcast_to(folds[:, None], valid.shape)[valid]
        _, g_all = _gram(Jt, r_valid)
        held = np.zeros_like(r)
        fold_rss = np.zeros(K)
        fold_n = np.zeros(K, dtype=int)
        for k in range(K):
            te_e = entry_fold == k
            H_te, g_te = _gram(Jt[:, te_e], r_valid[te_e])
            H_tr, g_tr = H - H_te, g_all - g_te
            free = ~(((x <= lo) & (g_tr > 0)) | ((x >= hi) & (g_tr < 0)))
            dx = np.zeros(len(x))
            if free.any():
                dx[free] = -np.linalg.pinv(H_tr[np.ix_(free, free)]) @ g_tr[free]
            xk = np.clip(x + dx, lo, hi)
            rk = rfun(xk)
            sel = folds == k
            test = valid & sel[:, None]
            held[sel] = rk[sel]
            fold_rss[k] = float(np.sum(np.where(test, rk, 0.0) ** 2))
            fold_n[k] = int(test.sum())
        resid_phys = held / P.w_fit
        return Fit(key, pnames, x, physics_of(x), cov, rss, n, n_eff,
                   n_eff * math.log(max(rss, 1e-300) / n) + len(x) * math.log(n_eff),
                   _channel_rms(r / P.w_fit, valid, P.channels), float(fold_rss.sum()),
                   _channel_rms(resid_phys, valid, P.channels), fold_rss, fold_n, resid_phys, Jt, approximate)

    def screen(self, current: Fit, name: str) -> Fit:
        """A cheap joint fit of ``current`` plus candidate ``name``: the new parameters are
        simulated exactly, the already-fitted ones enter linearly through their Jacobian at the
        current fit (r(x_old + d) = r(x_old) + J_old d). Used to rank candidates; the one chosen
        is then fitted exactly."""
        key = current.active + (name,)
        if not current.active or current.Jt is None:
            return self.fit(key)
        P = self.P
        cands, pnames, params = self._layout(key)
        p_old = len(current.x)
        x_old = current.x
        new = cands[-1]
        new_names = pnames[name]
        lo = np.array([p.lo for p in params])
        hi = np.array([p.hi for p in params])
        scale = np.array([p.scale for p in params])
        valid = P.valid_fit
        Jt_old = current.Jt
        base = current.physics

        def physics_of(z: np.ndarray) -> Physics:
            ph = self._physics(cands[:-1], pnames, z[:p_old])
            new.write(ph, new_names, z[p_old:])
            return ph

        def rfun(z: np.ndarray) -> np.ndarray:
            ph = base.copy()
            new.write(ph, new_names, z[p_old:])
            R = self._resid(ph)
            d = z[:p_old] - x_old
            if np.any(d != 0.0):
                R = R.copy()
                R[valid] += np.einsum("pm,p->m", Jt_old, d)
            return R

        resid = P.data_fit - P.sim_fit.run(base)
        x0 = np.concatenate([x_old, np.asarray(new.initial(P, base, new_names, resid), float)])
        x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))
        return self._fit_core(key, pnames, rfun, x0, lo, hi, scale, physics_of, fixed_jt=Jt_old, approximate=True)

    def _x_from(self, key: tuple[str, ...], ph: Physics) -> np.ndarray:
        """The parameter vector of a candidate set read from a physics (a warm start)."""
        cands, pnames, _ = self._layout(key)
        return np.concatenate([np.asarray(c.read(ph, pnames[c.name]), float) for c in cands])

    def _start(self, active, cands, pnames, params) -> np.ndarray:
        """Starting point: values of the already-fitted subset, initial guesses for the newcomer."""
        P = self.P
        prev = self.cache.get(tuple(active[:-1]))
        ph = prev.physics.copy() if prev is not None else P.base.copy()
        resid = P.data_fit - P.sim_fit.run(ph)
        xs = []
        for c in cands:
            names = pnames[c.name]
            if prev is not None and c.name in prev.active:
                xs.append(c.read(ph, names))
            else:
                xs.append(np.asarray(c.initial(P, ph, names, resid), float))
        return np.concatenate(xs)

    # ---- selection ----------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        P, opt = self.P, self.opt
        lib = [c for c in LIBRARY if c.name in opt.candidates]
        applicable, not_applicable = [], []
        for c in lib:
            why = c.applicable(P)
            (not_applicable.append({"name": c.name, "reason": f"not applicable: {why}"}) if why
             else applicable.append(c.name))
        active: list[str] = []
        current = self.fit(())
        steps = []
        rejected: dict[str, dict[str, Any]] = {}
        equivalences = []
        t_start = time.perf_counter()
        while len(active) < opt.max_terms:
            trials = {}
            for name in applicable:
                if name in active:
                    continue
                try:
                    trials[name] = self._screen_pruned(current, name)
                except (ValueError, np.linalg.LinAlgError) as exc:
                    rejected[name] = {"name": name, "reason": f"fit failed: {exc}"}
            if not trials:
                break
            verdicts = {n: self._vetoed(n, f, self._judge(current, f)) for n, f in trials.items()}
            passing = [n for n, v in verdicts.items() if v["ok"]]
            for n, v in verdicts.items():
                if not v["ok"]:
                    rejected[n] = {"name": n, "reason": v["reason"], "round": len(active) + 1,
                                   "fit_rms_change_pct": v["fit_change_pct"],
                                   "heldout_rms_change_pct": v["heldout_change_pct"], "delta_bic": v["delta_bic"]}
            best = exact = None
            while passing:
                lowest = min(passing, key=lambda n: trials[n].heldout_rss)
                group = [lowest] + [o for o in passing if o != lowest and self._equivalent(trials[lowest], trials[o])]
                # equal within the noise: name the more common cause (library order = METHODS
                # section 6 order of the usual suspects) and report the other as equivalent
                cand = min(group, key=CANDIDATES.index)
                key = tuple(active) + (cand,)
                exact = self.fit(key, x0=trials[cand].x) if trials[cand].approximate else trials[cand]
                v = self._vetoed(cand, exact, self._judge(current, exact))
                if v["ok"]:
                    best = cand
                    for other in group:
                        if other != best:
                            equivalences.append({
                                "chosen": best, "alternative": other, "round": len(active) + 1,
                                "heldout_rms_chosen": _pooled(trials[best]),
                                "heldout_rms_alternative": _pooled(trials[other]),
                                "chosen_because": "equal within the noise; named first as the more common cause "
                                                  "(METHODS.md section 6 order)",
                                "separating_measurement": separating_measurement(best, other)})
                    break
                rejected[cand] = {"name": cand, "reason": v["reason"] + " (refitted jointly)",
                                  "round": len(active) + 1, "heldout_rms_change_pct": v["heldout_change_pct"]}
                passing.remove(cand)
            if best is None:
                break
            active.append(best)
            rejected.pop(best, None)
            current = exact
            # backward step: a term added earlier as a stand-in may be redundant now; it stays only
            # if it would still pass the test for joining last
            changed = True
            while changed and len(active) >= 2:
                changed = False
                for old in active[:-1]:
                    reduced = tuple(a for a in active if a != old)
                    f_red = self.fit(reduced, x0=self._x_from(reduced, current.physics))
                    v = self._judge(f_red, current)
                    if not v["ok"]:
                        active.remove(old)
                        steps = [st for st in steps if st["added"] != old]
                        rejected[old] = {"name": old, "reason": f"dropped once {', '.join(active)} had joined: as "
                                         f"the last term it {v['reason']}", "dropped": True,
                                         "heldout_rms_change_pct": v["heldout_change_pct"]}
                        current = f_red
                        changed = True
                        break
        # the chain of fits in the final order (a dropped term leaves the recorded steps stale)
        chain = [self.fit(())]
        steps = []
        for i, name in enumerate(active):
            f = self.fit(tuple(active[:i + 1]))
            steps.append({"added": name, "before": chain[-1], "after": f, "verdict": self._judge(chain[-1], f)})
            chain.append(f)
        current = chain[-1]
        # candidates that were equivalent to a chosen one: say so instead of a plain rejection
        for e in equivalences:
            alt = e["alternative"]
            if alt not in active:
                rejected[alt] = {"name": alt, "reason": f"explains the residual as well as {e['chosen']} "
                                 f"(held-out {e['heldout_rms_alternative']:.4g} vs {e['heldout_rms_chosen']:.4g} "
                                 f"floors); {e['separating_measurement']}", "equivalent_to": e["chosen"]}
        for name in applicable:
            if name not in active and name not in rejected:
                rejected[name] = {"name": name, "reason": "not tried (term limit reached)"}
        return {"active": active, "final": current, "baseline": self.fit(()), "steps": steps,
                "rejected": list(rejected.values()) + not_applicable, "equivalences": equivalences,
                "applicable": applicable, "selection_time_s": time.perf_counter() - t_start}

    def _screen_pruned(self, current: Fit, name: str) -> Fit:
        """``screen``; for thermal_drift, elements whose time constant runs onto its lower bound
        (steps, not drifts: usually picked up from another effect's residual) are dropped and
        the rest refitted."""
        f = self.screen(current, name)
        if name != "thermal_drift":
            return f
        key = current.active + (name,)
        for _ in range(4):
            names = f.pnames[name]
            i0 = sum(len(f.pnames[n]) for n in f.active[:-1])
            lo = {p.name: p.lo for p in ThermalDrift().params(self.P)}
            fast = [n[4:] for n, v in zip(names, f.x[i0:i0 + len(names)], strict=True)
                    if n.startswith("tau_") and v <= 1.01 * lo[n]]
            keep = [e for e in self.elements[key] if e not in fast]
            if not fast or not keep:
                break
            self.elements[key] = keep
            self.cache.pop(key, None)
            f = self.screen(current, name)
        return f

    def _vetoed(self, name: str, f: Fit, verdict: dict[str, Any]) -> dict[str, Any]:
        """The verdict, turned into a refusal when the candidate vetoes its own fitted values."""
        if not verdict["ok"]:
            return verdict
        names = f.pnames[name]
        i0 = sum(len(f.pnames[n]) for n in f.active[:f.active.index(name)])
        why = _cands([name])[0].veto(self.P, names, f.x[i0:i0 + len(names)])
        return verdict if why is None else {**verdict, "ok": False, "reason": why}

    def _judge(self, before: Fit, after: Fit) -> dict[str, Any]:
        opt = self.opt
        fit_change = math.sqrt(after.rss / max(before.rss, 1e-300)) - 1.0
        held_change = math.sqrt(after.heldout_rss / max(before.heldout_rss, 1e-300)) - 1.0
        per_fold_better = int(np.sum(after.fold_rss < before.fold_rss))
        K = len(after.fold_rss)
        n_eff = before.n_eff
        dp = len(after.x) - len(before.x)
        dbic = n_eff * math.log(max(after.rss, 1e-300) / max(before.rss, 1e-300)) + dp * math.log(max(n_eff, 2.0))
        out = {"fit_change_pct": 100 * fit_change, "heldout_change_pct": 100 * held_change, "delta_bic": dbic,
               "folds_better": per_fold_better, "folds": K}
        if held_change >= 0:
            out.update(ok=False, reason=f"improves the fit RMS by {-100 * fit_change:.2g}% but the held-out RMS "
                       f"rises by {100 * held_change:.2g}%" if fit_change < 0 else
                       "does not lower the fit RMS")
        elif held_change > -opt.margin:
            out.update(ok=False, reason=f"lowers the held-out RMS by only {-100 * held_change:.2g}% "
                       f"(a clear margin is {100 * opt.margin:.3g}%)")
        elif per_fold_better <= K // 2:
            out.update(ok=False, reason=f"lowers the pooled held-out RMS by {-100 * held_change:.2g}% but only in "
                       f"{per_fold_better} of {K} folds")
        elif dbic > -opt.bic_margin:
            out.update(ok=False, reason=f"BIC does not fall clearly (change {dbic:+.3g}, effective n "
                       f"{n_eff:.0f})")
        else:
            out.update(ok=True, reason="accepted")
        return out

    def _equivalent(self, a: Fit, b: Fit) -> bool:
        """Two fits explain the residual equally when their held-out mean squares (in floors^2)
        differ by less than ``equivalent_floor2`` (their predictions differ by well under the
        noise), or when the difference is within both the fold-to-fold scatter (paired, 2 SE) and
        ``equivalent`` of the held-out mean square."""
        ma = a.heldout_rss / max(int(a.fold_n.sum()), 1)
        mb = b.heldout_rss / max(int(b.fold_n.sum()), 1)
        if abs(mb - ma) < self.opt.equivalent_floor2:
            return True
        da = a.fold_rss / np.maximum(a.fold_n, 1)
        db = b.fold_rss / np.maximum(b.fold_n, 1)
        d = db - da
        se = float(np.std(d, ddof=1) / math.sqrt(len(d))) if len(d) > 1 else math.inf
        return abs(float(np.mean(d))) < 2 * se and abs(mb - ma) < self.opt.equivalent * ma


def _floor_stats(resid: np.ndarray, floor: np.ndarray, valid: np.ndarray, channels: Sequence[str]
                 ) -> dict[str, dict[str, float]]:
    """Per channel: RMS of residual / floor, and the fraction of samples above 3 floors."""
    out = {}
    for j, c in enumerate(channels):
        z = np.abs(resid[valid[:, j], j]) / floor[valid[:, j], j]
        out[c] = {"floors_rms": float(np.sqrt(np.mean(z * z))) if len(z) else math.nan,
                  "fraction_above_3_floors": float(np.mean(z > 3.0)) if len(z) else math.nan}
    return out


def _above_floor(st: Mapping[str, float]) -> bool:
    """A residual stands above the floor when its RMS exceeds 1.3 floors or more than 2% of the
    samples exceed 3 floors (white noise at the floor: 1 floor and 0.27%)."""
    return st["floors_rms"] > 1.3 or st["fraction_above_3_floors"] > 0.02


def _pooled(f: Fit) -> float:
    return math.sqrt(f.heldout_rss / max(int(f.fold_n.sum()), 1))


def _lag1(rr: np.ndarray) -> float:
    """Lag-1 autocorrelation of the weighted residual, pooled over channels (0..0.999)."""
    x = rr - rr.mean(axis=0)
    den = float(np.sum(x * x))
    if den <= 0:
        return 0.0
    return float(np.clip(np.sum(x[1:] * x[:-1]) / den, 0.0, 0.999))


def _channel_rms(resid: np.ndarray, valid: np.ndarray, channels: Sequence[str]) -> dict[str, float]:
    out = {}
    for j, c in enumerate(channels):
        v = resid[valid[:, j], j]
        out[c] = float(np.sqrt(np.mean(v * v))) if len(v) else math.nan
    return out


# ==============================================================================================
# findings
def _fmt(v: float, unit: str = "") -> str:
    if v is None or not np.isfinite(v):
        return "n/a"
    a = abs(v)
    s = f"{v:.3g}" if (a >= 1e-3 or a == 0) else f"{v:.2e}"
    return f"{s} {unit}".strip()


def _rms_unit_text(before: Mapping[str, float], after: Mapping[str, float], chans: Sequence[str]) -> str:
    """'from A to B mm' on the channel with the largest fall, plus the others in brackets."""
    if not chans:
        return ""
    best = max(chans, key=lambda c: before[c] - after[c])
    u = channel_unit(best)
    f = 1.0
    if u == "rad":
        f, u = 180 / np.pi, "deg"
    elif u == "1":
        u = ""
    main = f"from {_fmt(before[best] * f)} to {_fmt(after[best] * f, u)} on {best}"
    others = [f"{c} {_fmt(before[c] * (180 / np.pi if channel_unit(c) == 'rad' else 1))} -> "
              f"{_fmt(after[c] * (180 / np.pi if channel_unit(c) == 'rad' else 1))}" for c in chans if c != best]
    return main + (f" ({'; '.join(others)})" if others else "")


def _affected(before: Mapping[str, float], after: Mapping[str, float]) -> list[str]:
    return [c for c in before if np.isfinite(before[c]) and before[c] - after[c] > 0.01 * max(before[c], 1e-300)]


def sentence_for(name: str, params: Mapping[str, Any], unc: Mapping[str, Any], hb: Mapping[str, float],
                 ha: Mapping[str, float], equivalent: Sequence[Mapping[str, Any]] = (),
                 model_had: Mapping[str, Any] | None = None) -> str:
    """One plain sentence per effect, e.g. "Z lags its command by v/Kv with Kv = 124 1/s, left
    out of the simulation; adding it cuts the held-out RMS from 0.22 to 0.045 mm"."""
    chans = _affected(hb, ha) or list(hb)
    cut = f"adding it cuts the held-out RMS {_rms_unit_text(hb, ha, chans)}"
    gap = "left out of the simulation"
    if model_had:
        had = ", ".join(f"{k} = {_fmt(v) if isinstance(v, float) else v}" for k, v in model_had.items())
        cut = f"refitting it cuts the held-out RMS {_rms_unit_text(hb, ha, chans)} (the model had {had})"
    gap = "mis-set in the simulation" if model_had else "left out of the simulation"
    if name == "servo_lag":
        ax = [k[3:] for k, v in params.items() if v is not None]
        kv = ", ".join(f"{_fmt(params[f'Kv_{a}'])} ± {_fmt(unc.get(f'Kv_{a}'))}" for a in ax)
        who = ", ".join(ax)
        verb = "lags its" if len(ax) == 1 else "lag their"
        s = f"{who} {verb} command by v/Kv with Kv = {kv} 1/s, {gap}; {cut}"
    elif name == "time_offset":
        s = (f"The recording runs {_fmt(params['offset_s'] * 1000)} ± {_fmt(unc['offset_s'] * 1000)} ms "
             f"{'behind' if params['offset_s'] >= 0 else 'ahead of'} the program's clock, left out of the "
             f"simulation; {cut}")
    elif name == "backlash":
        sig = {k: v for k, v in params.items() if abs(v) > 3 * (unc.get(k) or 0.0)}
        parts = [f"{k[9:]} {_fmt(v, 'deg' if k[9:] in ROTARY_AXES else 'mm')} ± "
                 f"{_fmt(unc.get(k), 'deg' if k[9:] in ROTARY_AXES else 'mm')}" for k, v in (sig or params).items()]
        rest = [k[9:] for k in params if sig and k not in sig]
        none = f"; none measurable on {', '.join(rest)}" if rest else ""
        s = f"The axes lose motion at each reversal (backlash {', '.join(parts)}{none}), {gap}; {cut}"
    elif name == "spindle_runout":
        s = (f"The tool tip runs out at 1x spindle revolution with radius {_fmt(params['radius'], 'mm')} at phase "
             f"{_fmt(params['phase_deg'], 'deg')}, {gap}; {cut}")
    elif name == "thermal_drift":
        els = sorted({k.rsplit("_", 1)[0] for k in params})
        parts = [f"{e} gain {_fmt(params[e + '_gain'])} per 1000 rpm, tau {_fmt(params[e + '_tau'], 's')}" for e in els]
        s = f"The spindle grows thermally ({'; '.join(parts)}), {gap}; {cut}"
    elif name == "unexplained":
        s = "No candidate in the library explains the residual: " + params.get("detail", "")
    else:
        what = {"rotary_location": "The rotary axes are displaced from their nominal lines",
                "rotary_squareness": "The rotary axes are tilted from their nominal directions",
                "spindle_tilt": "The spindle axis is tilted", "tool_length": "The tool length is off"}[name]
        parts = [f"{k} = {_fmt(v, 'rad' if k in _GEO_ANGLES else 'mm')}" for k, v in params.items()]
        s = f"{what} ({', '.join(parts)}), {gap}; {cut}"
    for e in equivalent:
        s += (f". The data cannot tell it from {e['alternative']} (held-out {e['heldout_rms_alternative']:.3g} "
              f"vs {e['heldout_rms_chosen']:.3g} floors): {e['separating_measurement']}")
    return s


def _discriminate_lag_offset(sel: Selector, result: Mapping[str, Any]) -> dict[str, Any] | None:
    """Whether the data tell a servo lag from a clock offset (on top of the other chosen terms):
    by shape (one common lag vs one offset: both one parameter) and by the per-axis spread of
    the fitted delays (one clock offset delays every axis alike)."""
    P = sel.P
    axes = [a for a in AXES if P.knots.moves(a)]
    if not axes:
        return None
    others = tuple(n for n in result["active"] if n not in ("servo_lag", "time_offset"))
    f_lag = sel.fit(others + ("servo_lag",))
    f_off = sel.fit(others + ("time_offset",))
    # one lag shared by all axes
    base = f_lag.physics.copy()

    def resid_common(x: np.ndarray) -> np.ndarray:
        return sel._resid(_with_tau(base, axes, float(x[0])))

    tau0 = float(np.mean([f_lag.physics.tau.get(a, 0.0) for a in axes]))
    valid = P.valid_fit
    K = int(P.folds.max()) + 1
    one = (np.array([0.0]), np.array([2.0]), np.array([1e-3]))
    x_c = _lm(lambda x: resid_common(x), np.array([max(tau0, 1e-4)]), *one, valid)[0]
    fold_rss = np.zeros(K)
    for k in range(K):
        tr = valid & (P.folds != k)[:, None]
        te = valid & (P.folds == k)[:, None]
        xk = _lm(lambda x: resid_common(x), x_c, *one, tr, max_iter=8, jac_at_end=False)[0]
        fold_rss[k] = float(np.sum(np.where(te, resid_common(xk), 0.0) ** 2))
    n_test = int(valid.sum())
    h_common = math.sqrt(fold_rss.sum() / n_test)
    h_off, h_lag = _pooled(f_off), _pooled(f_lag)
    shape_same = abs(h_common - h_off) <= sel.opt.equivalent * min(h_common, h_off) + 1e-12 or \
        abs(h_common - h_off) < 0.5 * abs(h_lag - min(h_common, h_off)) and abs(h_common - h_off) < 0.02 * h_off
    # per-axis delays with uncertainty
    names = f_lag.pnames["servo_lag"]
    i0 = sum(len(f_lag.pnames[n]) for n in f_lag.active[:f_lag.active.index("servo_lag")])
    taus = f_lag.x[i0:i0 + len(names)]
    sds = np.sqrt(np.clip(np.diag(f_lag.cov)[i0:i0 + len(names)], 0, None))
    delays = {n[4:]: {"delay_ms": float(1000 * t), "sd_ms": float(1000 * s)} for n, t, s in zip(names, taus, sds,
                                                                                                   strict=True)}
    w = 1.0 / np.maximum(sds, 1e-12) ** 2
    mean = float(np.sum(w * taus) / np.sum(w))
    chi2 = float(np.sum(w * (taus - mean) ** 2))
    dof = max(len(taus) - 1, 1)
    spread = len(taus) > 1 and chi2 / dof > 4.0 and h_lag < h_common * (1 - 0.5 * sel.opt.margin)
    tau_ms = 1000 * mean
    delay_text = ", ".join(f"{a} {d['delay_ms']:.3g} ± {d['sd_ms']:.2g} ms" for a, d in delays.items())
    if spread:
        # one offset for every axis cannot fit then; comparing one common lag with one offset
        # would compare two wrong models, so the shape test is not the argument here
        verdict = (f"The fitted delays differ between axes beyond their uncertainties ({delay_text}; chi2/dof = "
                   f"{chi2 / dof:.3g}): one clock offset between program and recording cannot produce that, "
                   f"per-axis servo lags can (held-out {h_lag:.4g} floors against {h_off:.4g} for one offset).")
    elif shape_same:
        verdict = (f"By the shape of the response the data cannot tell a servo lag from a clock offset: one common "
                   f"lag and one offset fit equally (held-out {h_common:.4g} vs {h_off:.4g} floors); with samples "
                   f"every {1000 * P.dt:.3g} ms against a lag time constant of about {tau_ms:.3g} ms the "
                   "exponential corners of a lag are not sampled.")
        if len(taus) > 1:
            verdict += (f" The per-axis delays ({delay_text}) agree within their uncertainties, as a single clock "
                        "offset would also give.")
        sep = separating_measurement("servo_lag", "time_offset")
        verdict += " " + sep[0].upper() + sep[1:] + "."
    else:
        better = "servo lag" if h_common < h_off else "clock offset"
        verdict = (f"The shape of the response separates them: one common lag gives held-out {h_common:.4g} and one "
                   f"offset {h_off:.4g} floors, favouring a {better}; the per-axis delays ({delay_text}) agree within "
                   "their uncertainties.")
    return {"heldout_common_lag": h_common, "heldout_offset": h_off, "heldout_per_axis_lag": h_lag,
            "shape_distinguishes": not shape_same, "per_axis_delays": delays, "delays_differ": bool(spread),
            "chi2_per_dof": chi2 / dof, "verdict": verdict, "units": "held-out RMS in noise floors"}


def _with_tau(ph: Physics, axes: Sequence[str], tau: float) -> Physics:
    out = ph.copy()
    for a in axes:
        out.tau[a] = float(tau)
    return out


@dataclass
class Diagnosis:
    """Everything ``diagnose`` found: the findings dict (FINDINGS.json), the fitted physics, the
    problem (for plots) and the baseline/final residuals on all samples."""

    findings: dict[str, Any]
    physics: Physics
    problem: Problem
    resid_before: np.ndarray
    resid_after: np.ndarray
    selection: dict[str, Any]

    def model_json(self) -> dict[str, Any]:
        return model_json(self.physics, note=f"camsmooth diagnose: {', '.join(self.findings['named']) or 'no change'}")


def diagnose(program: Program, recording: Recording, machine: Machine | None = None, base: Physics | None = None,
             options: Options | None = None) -> Diagnosis:
    """Run the whole diagnosis (module docstring) and return the findings."""
    t0 = time.perf_counter()
    opt = options or Options()
    P = prepare(program, recording, machine, base, opt)
    sel = Selector(P, opt)
    res = sel.run()
    if res["active"]:
        # a dense structured residual (runout at many samples per revolution, say) inflates the
        # white-noise estimate of the baseline; estimate it again on what the named effects leave
        # and, where it is clearly lower, select again with the corrected floors
        ra = P.data - P.sim_all.run(res["final"].physics)
        w_new = {c: white_noise(ra[:, j], P.segment) for j, c in enumerate(P.channels)}
        w_old = {c: P.floor_info[c]["white"] for c in P.channels}
        if any(w_new[c] < 0.8 * w_old[c] and w_old[c] > P.floor_info[c]["quantisation_rms"] for c in P.channels):
            outliers = P.outliers
            P = prepare(program, recording, machine, base, opt, white={c: min(w_new[c], w_old[c]) for c in w_new},
                        valid=P.valid)
            P.outliers = outliers
            sel = Selector(P, opt)
            res = sel.run()
    baseline, final = res["baseline"], res["final"]
    # all-sample figures
    sim_before = P.sim_all.run(P.base)
    sim_after = P.sim_all.run(final.physics)
    rb = P.data - sim_before
    ra = P.data - sim_after
    rms_b_all = _channel_rms(rb, P.valid, P.channels)
    rms_a_all = _channel_rms(ra, P.valid, P.channels)
    effects = []
    for step in res["steps"]:
        name = step["added"]
        after = step["after"]
        before = step["before"]
        cand = _cands([name])[0]
        # parameters from the final joint fit; the RMS figures from the step that added the term
        names = final.pnames[name]
        i0 = sum(len(final.pnames[n]) for n in final.active[:final.active.index(name)])
        x = final.x[i0:i0 + len(names)]
        sd = np.sqrt(np.clip(np.diag(final.cov)[i0:i0 + len(names)], 0, None)) if final.cov.size else np.zeros(0)
        par, unc, units = cand.report(names, x, sd)
        eq = [e for e in res["equivalences"] if e["chosen"] == name]
        eff = {"name": name, "parameters": par, "uncertainties": unc, "units": units,
               "rms_before": before.rms_fit, "rms_after": after.rms_fit,
               "heldout_rms_before": before.heldout_rms, "heldout_rms_after": after.heldout_rms,
               "verdict": {k: v for k, v in step["verdict"].items() if k != "ok"},
               "equivalent_to": [{k: v for k, v in e.items() if k != "chosen"} for e in eq]}
        x_base = np.nan_to_num(np.asarray(cand.read(P.base, names), float))
        had = None
        if np.any(x_base != 0.0):
            had = {k: v for k, v in cand.report(names, x_base, np.zeros(len(names)))[0].items() if v}
            eff["model_had"] = had
        eff["sentence"] = sentence_for(name, par, unc, before.heldout_rms, after.heldout_rms, eq, had)
        effects.append(eff)
    z_b, z_a = _floor_stats(rb, P.floor, P.valid, P.channels), _floor_stats(ra, P.floor, P.valid, P.channels)
    at_floor_before = not any(_above_floor(z_b[c]) for c in P.channels)
    at_floor_after = not any(_above_floor(z_a[c]) for c in P.channels)
    states_all = P.sim_all.states()
    loc_before = locate_intervals(P.t, rb, P.floor, P.valid, P.channels, states_all, P.segment)
    loc_after = locate_intervals(P.t, ra, P.floor, P.valid, P.channels, states_all, P.segment)
    if not effects and at_floor_before:
        verdict = "nothing to explain: the residual is at the noise floor"
    elif not at_floor_after:
        above = [c for c in P.channels if _above_floor(z_a[c])]
        detail = (", ".join(f"{c}: {_fmt(rms_a_all[c])} RMS ({z_a[c]['floors_rms']:.3g} floors; "
                            f"{100 * z_a[c]['fraction_above_3_floors']:.2g}% of samples above 3 floors)" for c in above)
                  + f" remains, in {loc_after['count']} located interval(s)")
        effects.append({"name": "unexplained", "parameters": {"detail": detail}, "uncertainties": {},
                        "rms_before": final.rms_fit, "rms_after": final.rms_fit,
                        "heldout_rms_before": final.heldout_rms, "heldout_rms_after": final.heldout_rms,
                        "channels": above,
                        "sentence": sentence_for("unexplained", {"detail": detail}, {}, final.heldout_rms,
                                                 final.heldout_rms)})
        verdict = ("explained in part; " if res["active"] else "") + "unexplained residual remains above the floor"
    else:
        verdict = "explained: the residual is at the noise floor after the named effects"
    discrimination = None
    if any(n in res["active"] for n in ("servo_lag", "time_offset")) and "time_offset" in res["applicable"] and \
            "servo_lag" in res["applicable"]:
        discrimination = _discriminate_lag_offset(sel, res)
    findings: dict[str, Any] = {
        "program": program.source, "recording": recording.source,
        "channels": {c: {"unit": channel_unit(c), "samples": int(P.valid[:, j].sum())}
                     for j, c in enumerate(P.channels)},
        "resampling": P.aligned.method,
        "notes": list(dict.fromkeys(program.notes + recording.notes)),
        "noise_floor": P.floor_info,
        "outliers": P.outliers,
        "baseline_rms": {c: {"fit": rms_b_all[c], "heldout": baseline.heldout_rms[c], **z_b[c]} for c in P.channels},
        "intervals": loc_before["intervals"],
        "located": {k: v for k, v in loc_before.items() if k != "intervals"},
        "intervals_after": loc_after["intervals"][:10],
        "effects": effects,
        "named": [e["name"] for e in effects if e["name"] != "unexplained"],
        "final_rms": {c: {"fit": rms_a_all[c], "heldout": final.heldout_rms[c], **z_a[c]} for c in P.channels},
        "rejected": res["rejected"],
        "equivalences": res["equivalences"],
        "lag_vs_offset": discrimination,
        "verdict": verdict,
        "selection": {"folds": int(P.folds.max()) + 1, "fold_kind": "contiguous blocks in time",
                      "margin_pct": 100 * opt.margin, "bic_margin": opt.bic_margin,
                      "fit_samples": int(len(P.fit_idx)), "samples": int(len(P.t)),
                      "subset": ("all samples" if len(P.fit_idx) == len(P.t) else
                                 f"an even random subset of {len(P.fit_idx)} of {len(P.t)} samples (seed "
                                 f"{opt.seed}); final RMS on all samples"),
                      "rms_note": "baseline_rms.fit / final_rms.fit: all samples; heldout: each sample "
                                  "predicted by the fit that left its fold out; effects' rms_*: fit subset"},
        "runtime_s": time.perf_counter() - t0,
    }
    return Diagnosis(findings=_jsonable(findings), physics=final.physics, problem=P, resid_before=rb,
                     resid_after=ra, selection=res)


def validate(program: Program, recording: Recording, diag: Diagnosis, machine: Machine | None = None
             ) -> dict[str, Any]:
    """Predict a recording the fit never saw with the current and the fitted model: RMS per
    channel before and after (isolated spikes left out as in ``prepare``)."""
    P = prepare(program, recording, machine or diag.problem.machine, diag.problem.base)
    rb = P.data - P.sim_all.run(P.base)
    ra = P.data - P.sim_all.run(diag.physics)
    before = _channel_rms(rb, P.valid, P.channels)
    after = _channel_rms(ra, P.valid, P.channels)
    return _jsonable({"program": program.source, "recording": recording.source,
                      "channels": {c: {"rms_before": before[c], "rms_after": after[c], "unit": channel_unit(c),
                                       "floor": P.floor_info[c]["rms"], "samples": int(P.valid[:, j].sum())}
                                   for j, c in enumerate(P.channels)},
                      "outliers": len([o for o in P.outliers if "more" not in o])})


def _jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    return x


def write_findings(path: str, diag: Diagnosis) -> None:
    """FINDINGS.json, atomically."""
    write_text_atomic(path, json.dumps(diag.findings, indent=2) + "\n")


def write_model(path: str, diag: Diagnosis) -> None:
    """The extended model JSON (``model_json``), atomically."""
    write_text_atomic(path, json.dumps(_jsonable(diag.model_json()), indent=2) + "\n")


# ==============================================================================================
# simulated recordings (`camsmooth simulate recording`) and test programs
def simulate_recording(program: Program, machine: Machine | None = None, physics: Physics | None = None,
                       rate: float | None = None, channels: Sequence[str] = ("axes",),
                       noise: Mapping[str, float] | None = None, quantum: Mapping[str, float] | None = None,
                       seed: int = 0) -> Recording:
    """A recording simulated from a program with the given physics.

    rate: sampling rate (Hz) of the recording over each segment's span (None: the program's
    own times). channels: channel names or groups 'axes' (X_act.. for the program's axes),
    'tip', 'axis'. noise: white Gaussian sigma per group ('axes' mm, 'rotary' rad, 'tip' mm,
    'axis' unit) or per channel name; quantum: rounding step per group or channel (internal
    units). Noise is drawn from numpy's default_rng(seed)."""
    machine = machine or load_machine(None)
    physics = physics or Physics()
    noise = dict(noise or {})
    quantum = dict(quantum or {})
    names: list[str] = []
    for c in channels:
        if c == "axes":
            names += [f"{a}_act" for a in AXES if a in program.axes]
        elif c == "tip":
            names += list(TIP_CHANNELS)
        elif c == "axis":
            names += list(DIR_CHANNELS)
        elif c in CHANNELS:
            names.append(c)
        else:
            raise InputError(f"unknown channel or group {c!r}", column=c)
    names = [c for c in CHANNELS if c in names]
    if rate is None:
        t, seg = program.t.copy(), program.segment.copy()
    else:
        if rate <= 0:
            raise InputError(f"rate must be > 0 Hz, got {rate}")
        kn = _Knots(program)
        ts, ss = [], []
        for s0, s1 in zip(kn.starts, kn.ends, strict=True):
            tt = np.arange(program.t[s0], program.t[s1] + 0.5 / rate, 1.0 / rate)
            tt = tt[tt <= program.t[s1] + 1e-12]
            ts.append(tt)
            ss.append(np.full(len(tt), program.segment[s0]))
        t, seg = np.concatenate(ts), np.concatenate(ss)
    sim = Simulator(program, machine, t, seg, names)
    out = sim.run(physics)
    rng = np.random.default_rng(seed)

    def group(c: str) -> str:
        if c in ("A_act", "B_act"):
            return "rotary"
        if c in AXIS_CHANNELS:
            return "axes"
        return "tip" if c in TIP_CHANNELS else "axis"

    chans = {}
    qs = {}
    for j, c in enumerate(names):
        v = out[:, j]
        sig = noise.get(c, noise.get(group(c), 0.0))
        if sig > 0:
            v = v + rng.normal(0.0, sig, len(v))
        q = quantum.get(c, quantum.get(group(c), 0.0))
        if q > 0:
            v = np.round(v / q) * q
        chans[c] = v
        qs[c] = np.full(len(v), float(q))
    return Recording(t=t, channels=chans, quantum=qs, segment=None, source="<simulated>",
                     notes=["simulated by camsmooth simulate recording"])


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
        raise InputError(f"unknown program kind {kind!r} (lines, circles, rotary, spindle)")
    axes = {"X": X, "Y": Y, "Z": Z}
    if A is not None:
        axes["A"], axes["B"] = A, B
    return Program(t=t, axes=axes, S=S, source=f"<{kind} program, seed {seed}>")


# ----------------------------------------------------------------------------------------------
# `camsmooth simulate recording`
def add_simulate_recording_arguments(parser: Any) -> None:
    """Arguments of `camsmooth simulate recording` (argparse parser)."""
    parser.add_argument("--program", required=True, help="program CSV (t, X, Y, Z mm, A, B deg, S rpm)")
    parser.add_argument("-o", "--out", required=True, help="recording CSV to write")
    parser.add_argument("--machine", help="machine TOML (default: the ideal AB head)")
    parser.add_argument("--model", help="model JSON with the physics to simulate (ErrorModel + servo section)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a physics setting on top of --model: Kv_X (1/s), offset_s, backlash_X (mm, deg "
                             "for A/B), ErrorModel names (mm, rad), thermal_dz_gain, thermal_dz_tau, "
                             "runout_radius (mm), runout_phase_deg")
    parser.add_argument("--rate", type=float, help="sampling rate Hz (default: the program's rows)")
    parser.add_argument("--channels", default="axes",
                        help="comma list of groups (axes, tip, axis) or channel names (default: axes)")
    parser.add_argument("--noise", "--noise-mm", dest="noise_mm", type=float, default=0.0,
                        help="white noise sigma on mm channels (mm)")
    parser.add_argument("--noise-deg", type=float, default=0.0, help="white noise sigma on A_act, B_act (deg)")
    parser.add_argument("--noise-axis", type=float, default=0.0, help="white noise sigma on axis_i/j/k")
    parser.add_argument("--quantise-mm", type=float, default=0.0, help="rounding step of mm channels")
    parser.add_argument("--seed", type=int, default=0)


def simulate_recording_cli(args: Any) -> int:
    """`camsmooth simulate recording`: write a recording CSV simulated from a program."""
    from camsmooth.diagnosis.recordings import read_program_csv, write_recording_csv

    program = read_program_csv(args.program)
    machine = load_machine(getattr(args, "machine", None))
    ph = load_model(getattr(args, "model", None))
    settings = {}
    for item in getattr(args, "set", []) or []:
        if "=" not in item:
            raise InputError(f"--set expects NAME=VALUE, got {item!r}")
        k, v = item.split("=", 1)
        try:
            settings[k.strip()] = float(v)
        except ValueError:
            raise InputError(f"--set {k}: not a number: {v!r}") from None
    ph = physics_from_settings(settings, ph)
    noise = {"axes": args.noise_mm, "tip": args.noise_mm, "rotary": math.radians(args.noise_deg),
             "axis": args.noise_axis}
    quantum = {"axes": args.quantise_mm, "tip": args.quantise_mm}
    rec = simulate_recording(program, machine, ph, rate=args.rate,
                             channels=[c.strip() for c in args.channels.split(",") if c.strip()],
                             noise=noise, quantum=quantum, seed=args.seed)
    write_recording_csv(args.out, rec)
    print(f"wrote {args.out}: {len(rec.t)} samples, channels {', '.join(rec.channels)}")
    return 0


# ----------------------------------------------------------------------------------------------
# the concealed-effect suite: simulate with hidden physics, hand diagnose only program + recording
#: one setting per candidate (file units, see ``physics_from_settings``)
CONCEALED_EFFECTS: dict[str, dict[str, float]] = {
    "servo_lag": {"Kv_X": 40.0, "Kv_Y": 60.0, "Kv_Z": 80.0, "Kv_A": 50.0, "Kv_B": 70.0},
    "time_offset": {"offset_s": 0.005},
    "backlash": {"backlash_X": 0.010, "backlash_Y": 0.015, "backlash_Z": 0.020, "backlash_A": 0.010,
                 "backlash_B": 0.012},
    "rotary_location": {"EY0A": 0.020, "EZ0A": -0.015, "EX0B": 0.010, "EZ0B": 0.020},
    "rotary_squareness": {"EB0A": 1e-4, "EC0A": -8e-5, "EA0B": 6e-5, "EC0B": 1e-4},
    "spindle_tilt": {"EA0S": 1e-4, "EB0S": -1.5e-4},
    "spindle_runout": {"runout_radius": 0.005, "runout_phase_deg": 30.0},
    "tool_length": {"EZ0T": 0.05},
    "thermal_drift": {"thermal_dz_gain": 0.010, "thermal_dz_tau": 6.0, "thermal_dx_gain": 0.004,
                      "thermal_dx_tau": 3.0},
}
#: recorded channel groups and the effects each test program can show
CONCEALED_PROGRAMS: dict[str, dict[str, Any]] = {
    "lines": {"channels": ("axes", "tip"),
              "effects": ("servo_lag", "time_offset", "backlash", "tool_length", "spindle_runout", "thermal_drift")},
    "circles": {"channels": ("axes", "tip"),
                "effects": ("servo_lag", "time_offset", "backlash", "spindle_runout", "tool_length", "thermal_drift")},
    "rotary": {"channels": ("axes", "tip", "axis"), "effects": CANDIDATES},
    "spindle": {"channels": ("tip", "axis"),
                "effects": ("servo_lag", "spindle_runout", "tool_length", "thermal_drift", "spindle_tilt")},
}
CONCEALED_PAIRS: tuple[tuple[str, str], ...] = (
    ("servo_lag", "backlash"), ("servo_lag", "thermal_drift"), ("time_offset", "tool_length"),
    ("rotary_location", "servo_lag"), ("rotary_squareness", "backlash"), ("spindle_runout", "thermal_drift"),
    ("spindle_tilt", "tool_length"), ("backlash", "spindle_runout"))


def concealed_truth(names: Sequence[str], program: Program) -> dict[str, float]:
    """The settings of the named effects that the program can show (axes it moves; backlash on
    axes it reverses; a backlash without reversal is a constant offset, not backlash)."""
    kn = _Knots(program)
    out: dict[str, float] = {}
    for n in names:
        for k, v in CONCEALED_EFFECTS[n].items():
            ax = k.split("_")[-1] if k.startswith(("Kv_", "backlash_")) else None
            if ax is not None and not kn.moves(ax):
                continue
            if k.startswith("backlash_"):
                d = kn.direction(ax)
                if not np.any(d[1:] * d[:-1] < 0):
                    continue
            out[k] = v
    return out


def concealed_check(findings: Mapping[str, Any], names: Sequence[str], truth: Mapping[str, float],
                    tol: float = 0.10) -> tuple[bool, list[str]]:
    """(named exactly the hidden effects, parameters off by more than tol relative)."""
    ok = set(findings["named"]) == set(names)
    bad: list[str] = []
    if not ok:
        return False, [f"named {findings['named']} for {list(names)}"]
    par = {e["name"]: e["parameters"] for e in findings["effects"]}
    for k, v in truth.items():
        if k.startswith("Kv_"):
            got = par["servo_lag"].get(k)
        elif k == "offset_s":
            got = par["time_offset"]["offset_s"]
        elif k.startswith("backlash_"):
            got = par["backlash"].get(k)
            if k[-1] in ROTARY_AXES and got is not None:
                got = got  # degrees in both
        elif k in GEOMETRIC_NAMES:
            got = next((p[k] for p in par.values() if k in p), None)
        elif k == "runout_radius":
            p = par["spindle_runout"]
            z = p["radius"] * np.exp(1j * np.radians(p["phase_deg"]))
            zt = v * np.exp(1j * np.radians(truth["runout_phase_deg"]))
            if abs(z - zt) > tol * v:
                bad.append(f"runout {p['radius']:.4g} mm at {p['phase_deg']:.4g} deg vs {v} at "
                           f"{truth['runout_phase_deg']}")
            continue
        elif k == "runout_phase_deg":
            continue
        elif k.startswith("thermal_"):
            el, what = k[8:].rsplit("_", 1)
            got = par["thermal_drift"].get(f"{el}_{what}")
        else:  # pragma: no cover
            got = None
        if got is None or abs(got - v) > tol * abs(v):
            bad.append(f"{k}: {got} vs {v}")
    return not bad, bad


def concealed_case(kind: str, names: Sequence[str], noise: float, duration: float | None = None,
                   rate: float | None = None, seed: int = 1, options: Options | None = None) -> dict[str, Any]:
    """Simulate one concealed case and diagnose it from program and recording only; returns the
    case, what was named, whether it was right (names and parameters within 10%) and the time.
    noise: white sigma on mm channels (rotary and tool-axis channels get noise * 1e-3 rad)."""
    spec = CONCEALED_PROGRAMS[kind]
    duration = duration or (30.0 if kind == "spindle" else 20.0)
    rate = rate or (200.0 if kind == "spindle" else 500.0)
    program = make_program(kind, duration=duration, rate=rate, seed=seed, spindle=6100.0)
    truth = concealed_truth(names, program)
    rec = simulate_recording(program, physics=physics_from_settings(truth), channels=spec["channels"],
                             noise={"axes": noise, "tip": noise, "rotary": noise * 1e-3, "axis": noise * 1e-3},
                             seed=seed + 1000)
    t0 = time.perf_counter()
    diag = diagnose(program, rec, options=options)
    dt = time.perf_counter() - t0
    ok, bad = concealed_check(diag.findings, names, truth)
    return {"kind": kind, "effects": list(names), "noise": noise, "named": diag.findings["named"], "ok": ok,
            "problems": bad, "seconds": dt, "samples": len(rec.t)}


def concealed_cases(kinds: Sequence[str] = tuple(CONCEALED_PROGRAMS), pairs: bool = True
                    ) -> list[tuple[str, tuple[str, ...]]]:
    """(program kind, hidden effects) for the null case, each effect alone and the pairs."""
    out = []
    for kind in kinds:
        eff = CONCEALED_PROGRAMS[kind]["effects"]
        out.append((kind, ()))
        out += [(kind, (e,)) for e in eff]
        if pairs:
            out += [(kind, p) for p in CONCEALED_PAIRS if all(e in eff for e in p)]
    return out
