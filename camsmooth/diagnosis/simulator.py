"""The diagnosis simulator: the recorded channels at the recording's own times from a program and
a machine model (camsmooth.machine.model.ErrorModel), and simulated recordings.

The program is a piecewise-linear command between its rows (``Knots``). Each axis follows its
command through the model's first-order servo lag (exact for that input:
camsmooth.machine.model.first_order_knots / first_order_between, the integrator the thermal
model uses too), stands -(b/2) sign(last commanded direction) off it (backlash) and, as an
external measurement of the carriage sees it, moves by the positioning error E_AA. The recording
clock runs ``offset_s`` behind the program's. Tool tip and axis come from
``ErrorModel.real_frame`` (geometric chain, thermal growth in both frames, runout) at the actual
axis positions. Internal units mm, s, rad.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from camsmooth.diagnosis.recordings import (
    AXES,
    AXIS_CHANNELS,
    CHANNELS,
    DIR_CHANNELS,
    LINEAR_AXES,
    ROTARY_AXES,
    TIP_CHANNELS,
    Program,
    Recording,
)
from camsmooth.errors import InputError
from camsmooth.machine.kinematics import Machine, load_machine
from camsmooth.machine.model import (
    GEOMETRIC_NAMES,
    POSITIONING,
    THERMAL_ELEMENTS,
    ErrorModel,
    first_order_between,
    first_order_knots,
    interval_slopes,
)

#: the machine model of the diagnosis (one class: camsmooth.machine.model.ErrorModel)
Physics = ErrorModel


class Knots:
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
        self.restart = np.zeros(n, bool)
        self.restart[self.starts] = True
        self.u: dict[str, np.ndarray] = {a: np.asarray(v, float) for a, v in program.axes.items()}
        self.slope = {a: self._slope(u) for a, u in self.u.items()}
        # kept for the many lag time constants a fit tries (camsmooth.machine.model.first_order_knots)
        self.dt: np.ndarray | float = np.diff(self.t)
        self.jump: dict[str, np.ndarray | None] = {}
        for a, u in self.u.items():
            j = np.diff(u) - self.slope[a][:-1] * self.dt
            j[self.restart[1:]] = 0.0
            self.jump[a] = j if np.any(j) else None
        if n > 1:
            h0 = float(self.dt[0])
            if h0 > 0 and float(np.max(np.abs(self.dt - h0))) <= 1e-9 * h0:
                self.dt = h0
        self.S = None if program.S is None else np.asarray(program.S, float)
        if self.S is not None:
            # the spindle and thermal states run on through segment breaks (the clock does)
            self.S_slope = interval_slopes(self.t, self.S)
            hS = np.r_[np.diff(self.t), 0.0]
            self.S_angle = np.r_[0.0, np.cumsum(0.5 * (self.S[1:] + self.S[:-1]) * hS[:-1])] * (2 * np.pi / 60.0)
        self._dir: dict[str, np.ndarray] = {}

    def _slope(self, u: np.ndarray) -> np.ndarray:
        s = np.zeros(self.n)
        ok = self.same[:-1]
        s[:-1][ok] = np.diff(u)[ok] / self.h[:-1][ok]
        return s

    def moves(self, a: str) -> bool:
        return a in self.u and float(np.ptp(self.u[a])) > 1e-9

    def reverses(self, a: str) -> bool:
        if not self.moves(a):
            return False
        d = self.direction(a)
        return bool(np.any(d[1:] * d[:-1] < 0))

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

    def lag_error(self, a: str, tau: float) -> np.ndarray:
        """Following error of axis a at the knots for time constant tau (restarts at rest at each
        segment start)."""
        return first_order_knots(self.t, self.u[a], tau, slope=self.slope[a], restart=self.restart, h=self.dt,
                                 jump=self.jump[a])

    def follow(self, a: str, tau: float, k: np.ndarray, x: np.ndarray, e: np.ndarray | None = None) -> np.ndarray:
        """Axis a at the evaluation points through a first-order lag of time constant tau."""
        u, s = self.u[a], self.slope[a]
        if tau <= 0.0:
            return u[k] + s[k] * x
        return first_order_between(u, s, self.lag_error(a, tau) if e is None else e, tau, k, x)

    def spindle_response(self, tau: float, k: np.ndarray, x: np.ndarray) -> np.ndarray:
        """y with tau dy/dt = S/1000 - y, y = 0 at the program start (cold), S linear between rows,
        at the points (the model's one first-order integrator)."""
        S = self.S / 1000.0
        sl = self.S_slope / 1000.0
        e = first_order_knots(self.t, S, tau, slope=sl)
        return first_order_between(S, sl, e, tau, k, x)

    def spindle_angle(self, k: np.ndarray, x: np.ndarray) -> np.ndarray:
        return self.S_angle[k] + (self.S[k] * x + 0.5 * self.S_slope[k] * x * x) * (2 * np.pi / 60.0)


class _Cache(dict):
    def put(self, key: Any, value: Any, limit: int = 6) -> Any:
        if len(self) >= limit:
            self.pop(next(iter(self)))
        self[key] = value
        return value


def _positioning(model: ErrorModel, a: str) -> tuple[tuple[int, float], ...]:
    return tuple((k, model.geometric[n]) for n, (b, k) in POSITIONING.items()
                 if b == a and model.geometric.get(n, 0.0) != 0.0)


class Simulator:
    """Simulates recorded channels at given times from a program, a machine and a model.

    Evaluation times are clamped into their program segment (the machine rests before and
    after). Parts are cached by the parameters they depend on, so a finite-difference Jacobian
    only recomputes what a parameter touches.
    """

    def __init__(self, program: Program, machine: Machine, t: np.ndarray, segment: np.ndarray,
                 channels: Sequence[str], knots: Knots | None = None) -> None:
        self.program = program
        self.machine = machine
        self.kn = knots if knots is not None else Knots(program)
        self.t = np.asarray(t, float)
        self.segment = np.asarray(segment)
        self.channels = list(channels)
        self.need_pose = any(c in TIP_CHANNELS or c in DIR_CHANNELS for c in self.channels)
        self._loc, self._err, self._follow, self._pose, self._therm, self._angle = (_Cache() for _ in range(6))

    def loc(self, offset: float) -> tuple[np.ndarray, np.ndarray]:
        if offset not in self._loc:
            self._loc.put(offset, self.kn.locate(self.t - offset, self.segment))
        return self._loc[offset]

    def lagged(self, a: str, tau: float, offset: float) -> np.ndarray:
        """Axis a through its servo lag (no backlash, no positioning error) at the evaluation times."""
        key = (a, tau, offset)
        if key not in self._follow:
            k, x = self.loc(offset)
            e = None
            if tau > 0.0:
                if (a, tau) not in self._err:
                    self._err.put((a, tau), self.kn.lag_error(a, tau), limit=12)
                e = self._err[(a, tau)]
            self._follow.put(key, self.kn.follow(a, tau, k, x, e), limit=16)
        return self._follow[key]

    def axis(self, a: str, ph: ErrorModel, encoder: bool = True) -> np.ndarray | float:
        """Actual position of axis a (mm or rad) at the evaluation times: lag and backlash and,
        for an external measurement (encoder False), the positioning error."""
        if a not in self.kn.u:
            return 0.0
        y = self.lagged(a, float(ph.tau.get(a, 0.0)), ph.offset_s)
        b = float(ph.backlash.get(a, 0.0))
        if b != 0.0:
            k, _ = self.loc(ph.offset_s)
            y = y - 0.5 * b * self.kn.direction(a)[k]
        if not encoder and a in LINEAR_AXES:
            coef = _positioning(ph, a)
            if coef:
                y = y + sum(c * y ** p if p > 1 else c * y for p, c in coef)
        return y

    def _frame(self, ph: ErrorModel) -> Any:
        axes = {a: self.axis(a, ph) for a in AXES}
        geo = tuple(sorted((k, v) for k, v in ph.geometric.items() if v != 0.0))
        key = (tuple((a, ph.tau.get(a, 0.0), ph.backlash.get(a, 0.0)) for a in AXES), ph.offset_s, geo,
               id(ph.spindle))
        if key not in self._pose:
            # idle axes stay scalar zeros: the chain then skips their joints
            q = {a: (float(v) if np.ndim(v) == 0 else v) for a, v in axes.items()}
            chain = ErrorModel(dict(ph.geometric), ph.spindle, kind=ph.kind).chain(self.machine)
            self._pose.put(key, chain.forward(q), limit=4)
        return self._pose[key]

    def joint_derivatives(self, ph: ErrorModel, axes: Sequence[str]) -> dict[str, np.ndarray]:
        """d channels / d q_a (n, C) for the actual position q_a of each axis in ``axes`` (after lag
        and backlash), at the evaluation times: on the axis's own external channel 1 + E_AA'(q),
        on the tool tip v_a + w_a x tip and on the tool axis w_a x T, (w_a, v_a) the space Jacobian
        column of the model's chain (camsmooth.machine.kinematics.space_jacobian, from the screws;
        Modern Robotics' JacobianSpace), scaled by the positioning error's slope and plus the
        straightness slope for a linear axis."""
        from camsmooth.machine.kinematics import space_jacobian
        from camsmooth.machine.model import RealChain, frame_tip_axis

        n, C = len(self.t), len(self.channels)
        q = {a: np.broadcast_to(np.asarray(self.axis(a, ph), float), (n,)) for a in AXES}
        out = {a: np.zeros((n, C)) for a in axes}
        dpos = {}
        for a in axes:
            coef = _positioning(ph, a) if a in LINEAR_AXES else ()
            dpos[a] = 1.0 + sum(k * c * (q[a] ** (k - 1) if k > 1 else 1.0) for k, c in coef)
            if f"{a}_act" in self.channels:
                out[a][:, self.channels.index(f"{a}_act")] = dpos[a]
        if not self.need_pose:
            return out
        chain = ErrorModel(dict(ph.geometric), ph.spindle, kind=ph.kind).chain(self.machine)
        qj = chain.joint_values(q) if isinstance(chain, RealChain) else q
        J = space_jacobian(chain, qj, axes)
        angle = self.spindle_angle(ph.offset_s) if self.kn.S is not None and ph.runout != (0.0, 0.0) else None
        tip, ax = frame_tip_axis(ph.real_frame(self.machine, {}, self.thermal_state(ph), angle,
                                               frame=self._frame(ph)), n)
        for a in axes:
            i = chain.names.index(a)
            w, v = J[:, :3, i], J[:, 3:, i]
            dtip = (v + np.cross(w, tip)) * np.asarray(dpos[a]).reshape(-1, 1)
            dax = np.cross(w, ax) * np.asarray(dpos[a]).reshape(-1, 1)
            if isinstance(chain, RealChain):
                for name, terms in chain.straightness:
                    if name == a:
                        for d, k, c in terms:
                            dtip[:, d] += k * c * (q[a] ** (k - 1) if k > 1 else 1.0)
            for j, c in enumerate(self.channels):
                if c in TIP_CHANNELS:
                    out[a][:, j] = dtip[:, TIP_CHANNELS.index(c)]
                elif c in DIR_CHANNELS:
                    out[a][:, j] = dax[:, DIR_CHANNELS.index(c)]
        return out

    def thermal_unit(self, tau: float, offset: float) -> np.ndarray:
        key = (tau, offset)
        if key not in self._therm:
            k, x = self.loc(offset)
            self._therm.put(key, self.kn.spindle_response(tau, k, x), limit=24)
        return self._therm[key]

    def thermal_state(self, ph: ErrorModel) -> dict[str, np.ndarray]:
        """The thermal elements at the evaluation times (spindle speed linear between rows)."""
        out = {}
        if self.kn.S is None:
            return out
        for el, d in ph.thermal.items():
            if d["gain"] != 0.0:
                out[el] = d["gain"] * self.thermal_unit(float(d["tau"]), ph.offset_s)
        return out

    def spindle_angle(self, offset: float) -> np.ndarray:
        if offset not in self._angle:
            k, x = self.loc(offset)
            self._angle.put(offset, self.kn.spindle_angle(k, x))
        return self._angle[offset]

    def run(self, ph: ErrorModel) -> np.ndarray:
        """(M, C) simulated channels in ``self.channels`` order (internal units)."""
        n = len(self.t)
        out = np.empty((n, len(self.channels)))
        for j, c in enumerate(self.channels):
            if c in AXIS_CHANNELS:
                out[:, j] = self.axis(c[0], ph, encoder=False)
        if not self.need_pose:
            return out
        angle = self.spindle_angle(ph.offset_s) if self.kn.S is not None and ph.runout != (0.0, 0.0) else None
        f = ph.real_frame(self.machine, {}, self.thermal_state(ph), angle, frame=self._frame(ph))
        for j, c in enumerate(self.channels):
            if c in TIP_CHANNELS:
                out[:, j] = f.p[TIP_CHANNELS.index(c)]
            elif c in DIR_CHANNELS:
                out[:, j] = f.R[DIR_CHANNELS.index(c)][2]
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


# ----------------------------------------------------------------------------------------------
# settings and simulated recordings (`camsmooth simulate recording`)
def physics_from_settings(settings: Mapping[str, float], base: ErrorModel | None = None) -> ErrorModel:
    """A model from flat user settings (file units): Kv_<axis> (1/s), offset_s (s),
    backlash_<axis> (mm; deg for A, B), geometric names (GEOMETRIC_PARAMETERS units: mm, rad,
    1, 1/mm, 1/mm2), thermal_<element>_gain (mm or rad per 1000 rpm), thermal_<element>_tau (s),
    runout_radius (mm), runout_phase_deg."""
    ph = base.copy() if base is not None else ErrorModel()
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
            d = ph.thermal.setdefault(el, {"gain": 0.0, "tau": 60.0})
            d[what] = value
        elif key == "runout_radius":
            r = value
        elif key == "runout_phase_deg":
            phi = value
        else:
            raise InputError(f"unknown setting {key!r}", column=key)
    ph.runout = (r * math.cos(math.radians(phi)), r * math.sin(math.radians(phi)))
    for el, d in ph.thermal.items():
        if d["tau"] <= 0:
            raise InputError(f"thermal_{el}_tau must be > 0 s", column=f"thermal_{el}_tau")
    return ph


def simulate_recording(program: Program, machine: Machine | None = None, physics: ErrorModel | None = None,
                       rate: float | None = None, channels: Sequence[str] = ("axes",),
                       noise: Mapping[str, float] | None = None, quantum: Mapping[str, float] | None = None,
                       seed: int = 0) -> Recording:
    """A recording simulated from a program with the given model.

    rate: sampling rate (Hz) of the recording over each segment's span (None: the program's
    own times). channels: channel names or groups 'axes' (X_act.. for the program's axes),
    'tip', 'axis'. noise: white Gaussian sigma per group ('axes' mm, 'rotary' rad, 'tip' mm,
    'axis' unit) or per channel name; quantum: rounding step per group or channel (internal
    units). Noise is drawn from numpy's default_rng(seed). Axis channels are the carriage as an
    external measurement sees it (positioning error included)."""
    machine = machine or load_machine(None)
    physics = physics or ErrorModel()
    physics = physics.for_machine(machine)  # settings name the machine's own rotary errors
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
        kn = Knots(program)
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
        if c in tuple(f"{a}_act" for a in ROTARY_AXES):
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


def add_simulate_recording_arguments(parser: Any) -> None:
    """Arguments of `camsmooth simulate recording` (argparse parser)."""
    parser.add_argument("--program", required=True, help="program CSV (t, X, Y, Z mm, A, B deg, S rpm)")
    parser.add_argument("-o", "--out", required=True, help="recording CSV to write")
    parser.add_argument("--machine", help="machine TOML (default: the ideal AB head)")
    parser.add_argument("--model", help="model JSON with the physics to simulate (ErrorModel + servo section)")
    parser.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="a physics setting on top of --model: Kv_X (1/s), offset_s, backlash_X (mm, deg "
                             "for A/B), geometric names (mm, rad, 1, 1/mm, 1/mm2), thermal_dz_gain, "
                             "thermal_mz_tau, runout_radius (mm), runout_phase_deg")
    parser.add_argument("--rate", type=float, help="sampling rate Hz (default: the program's rows)")
    parser.add_argument("--channels", default="axes",
                        help="comma list of groups (axes, tip, axis) or channel names (default: axes)")
    parser.add_argument("--noise", "--noise-mm", dest="noise_mm", type=float, default=0.0,
                        help="white noise sigma on mm channels (mm)")
    parser.add_argument("--noise-deg", type=float, default=0.0,
                        help="white noise sigma on the rotary axes (A_act, B_act, C_act; deg)")
    parser.add_argument("--noise-axis", type=float, default=0.0, help="white noise sigma on axis_i/j/k")
    parser.add_argument("--quantise-mm", type=float, default=0.0, help="rounding step of mm channels")
    parser.add_argument("--seed", type=int, default=0)


def simulate_recording_cli(args: Any) -> int:
    """`camsmooth simulate recording`: write a recording CSV simulated from a program."""
    from camsmooth.diagnosis.model_io import load_model
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
