"""Diagnosis of a controller trace: command against actual per axis, as a controller's scope,
``halsampler``, a drive's commissioning log or a robot's RTDE log records them.

Input (``read_trace``): a CSV read by camsmooth.io.table with a header ``t`` (s), per axis
``<AX>_cmd`` and ``<AX>_act`` (AX: letters and digits; mm, or deg with ``units="deg"``), optional per
axis ``<AX>_load`` (any unit, its sign matters), ``<AX>_vel_cmd``, ``<AX>_vel_act`` (unit/s),
``<AX>_current`` (A), and covariates ``temp_<name>`` (deg C). With a column map
(``columns={"t": 1, "X_cmd": 3, ...}``, 1-based) a plain delimited log (comma, semicolon, tab or
blanks; with or without a header line) is read the same way. Irregular sampling is kept as
recorded; a gap (a step above ``GAP_FACTOR`` median sample periods, or a commanded jump beyond what
``<AX>_vel_cmd`` allows: ``breaks``) starts a new segment, where the simulation restarts at rest on
the command. Each channel's quantisation step (per sample,
camsmooth.diagnosis.recordings.quantisation_steps) enters its noise floor.

Model (``TraceModel``, internal units: the file's length unit, s; ``TraceSimulator``): the
command u(t), linearly interpolated between its samples onto a uniform internal grid, passes
through a first-order lag (tau dy/dt = u - y, servo_lag's tau = 1/Kv) that saturates (its velocity
clipped to vmax and changing by at most amax a second: ``_saturating_loop``), or, without a lag, an
acceleration limit (the commanded velocity changes by at most amax a second) and a velocity limit
(the position moves by at most vmax a second); then a second-order servo (y'' + 2 zeta wn y' + wn^2 y
= wn^2 u). The linear filters are discretised exactly for a piecewise-linear input (first-order
hold); each starts at rest on the first command. The result is read at t - offset_s - delay_<AX>
(time_offset: a pure delay of every axis; transport_delay: one axis's own) and the recording adds
a backlash of -(b/2) sign(last commanded direction), a load backlash of -(b/2) sign(load), and on
the thermal axis sum_ch gain_ch * L_ch(T_ch - T_ch(0)) with L_ch a first-order lag of time constant
tau_ch, and gain (1 - exp(-(t - t0) / tau)) of growth against time. Last, the quantisation of the
measured channel adds g (E[Q(y + n)] - y): Q the rounding to the act channel's own value grid
(``TraceSimulator.quant_grid``), n a jitter of ``QUANT_JITTER`` of the step (a smooth staircase).
A parameter at its base value (0) switches its block off.

Selection (``diagnose_trace``): the same term library, selector and significance rules as the
program-and-recording diagnosis (camsmooth.diagnosis.selector), on a ``TraceProblem`` that offers
the selector what a ``Problem`` offers: blocked time folds give the held-out RMS.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from camsmooth.diagnosis.problem import Options, locate_intervals, noise_floor
from camsmooth.diagnosis.recordings import quantisation_steps, uniform_grid
from camsmooth.errors import InputError
from camsmooth.io.table import Table, read_table, read_text_file

#: a step of more than this many median sample periods is a gap (a new segment)
GAP_FACTOR = 20.0
#: largest internal simulation grid (points); a longer recording is simulated on a coarser grid
GRID_MAX = 400_000
#: terms tried on a trace (the library's order decides between equals)
TRACE_CANDIDATES = ("servo_lag", "time_offset", "backlash", "servo_second_order", "velocity_limit",
                    "acceleration_limit", "backlash_load", "thermal_temperature", "thermal_time", "quantisation",
                    "transport_delay")
#: the jitter (fraction of the step) under which the quantisation term's staircase is averaged: its
#: steps are ramps about 0.1 q wide, so a position term's derivative stays finite across them
QUANT_JITTER = 0.02
KINDS = ("cmd", "act", "load", "vel_cmd", "vel_act", "current")
_AXIS_COLUMN = re.compile(r"^([A-Za-z0-9]+)_(cmd|act|load|vel_cmd|vel_act|current)$", re.IGNORECASE)


# ==============================================================================================
# reading
@dataclass(frozen=True)
class Trace:
    """A validated trace: sample times t (s, strictly increasing), per axis the command and the
    actual position (file units: mm or deg), optional load / velocities / current, temperature
    covariates (deg C), and the data row of each sample (for messages)."""

    file: str
    t: np.ndarray
    axes: tuple[str, ...]
    cmd: dict[str, np.ndarray]
    act: dict[str, np.ndarray]
    extra: dict[str, dict[str, np.ndarray]]
    temps: dict[str, np.ndarray]
    units: str
    rows: np.ndarray
    ignored: tuple[str, ...] = ()
    scale: float = 1.0

    @property
    def dt(self) -> float:
        return float(np.median(np.diff(self.t)))

    @property
    def gaps(self) -> int:
        return int(np.sum(np.diff(self.t) > GAP_FACTOR * self.dt))

    def describe(self) -> dict[str, Any]:
        """What was read (printed by the CLI and stored in FINDINGS.json)."""
        d = np.diff(self.t)
        return {"file": self.file, "axes": list(self.axes), "samples": int(len(self.t)),
                "rate_hz": 1.0 / self.dt, "span_s": float(self.t[-1] - self.t[0]), "units": self.units,
                "scale": self.scale, "irregular": bool(np.max(d) > 1.01 * np.min(d)), "gaps": self.gaps,
                "optional": {a: sorted(self.extra.get(a, {})) for a in self.axes},
                "temperatures": sorted(self.temps), "ignored_columns": list(self.ignored)}

    def summary(self) -> str:
        d = self.describe()
        opt = "; ".join(f"{a}: {', '.join(v)}" for a, v in d["optional"].items() if v)
        return (f"read {self.file}: axes {', '.join(self.axes)}; {d['samples']} samples at "
                f"{d['rate_hz']:.4g} Hz (median), span {d['span_s']:.4g} s; units {self.units}"
                + (f" x {self.scale:g}" if self.scale != 1.0 else "")
                + (f"; {d['gaps']} gap(s)" if d["gaps"] else "") + ("; irregular sampling" if d["irregular"] else "")
                + (f"; optional {opt}" if opt else "")
                + (f"; temperatures {', '.join(d['temperatures'])}" if d["temperatures"] else "")
                + (f"; ignored columns {', '.join(d['ignored_columns'])}" if d["ignored_columns"] else ""))


def parse_columns(text: str) -> dict[str, int]:
    """``t=1,X_cmd=3,X_act=4`` -> {'t': 1, 'X_cmd': 3, 'X_act': 4} (1-based field numbers)."""
    out: dict[str, int] = {}
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        name, eq, num = part.partition("=")
        name = name.strip()
        if not eq or not num.strip().isdigit() or int(num) < 1:
            raise InputError(f"--columns: '{part}' is not NAME=FIELD with FIELD a field number >= 1")
        if name != "t" and not _AXIS_COLUMN.match(name) and not name.lower().startswith("temp_"):
            raise InputError(f"--columns: '{name}' is not t, <AX>_cmd, <AX>_act, <AX>_load, <AX>_vel_act, "
                             "<AX>_vel_cmd, <AX>_current or temp_<name>")
        if name in out:
            raise InputError(f"--columns: '{name}' is given twice")
        out[name] = int(num)
    if "t" not in out:
        raise InputError("--columns must map t (the time column, s), e.g. t=1,X_cmd=3,X_act=4")
    return out


def _split(line: str) -> list[str]:
    for d in (",", ";", "\t", "|"):
        if d in line:
            return [f.strip() for f in line.split(d)]
    return line.split()


def _is_number(s: str) -> bool:
    try:
        float(s)
    except ValueError:
        return False
    return True


def _mapped_csv(path: str, columns: Mapping[str, int], tmpdir: Path) -> tuple[Path, int]:
    """A plain delimited log rewritten as the trace CSV of the mapped fields (in ``tmpdir``);
    returns (that file, how many lines the source has before its first record: 1 with a header)."""
    text = read_text_file(path, "trace")
    lines = text.split("\n")
    first = next((i for i, ln in enumerate(lines) if ln.strip()), None)
    if first is None:
        raise InputError("empty file (no data lines)", file=path)
    fields = _split(lines[first])
    header = not all(_is_number(f) for f in fields if f)
    skip = first + 1 if header else 0
    out = [",".join(columns)]
    need = max(columns.values())
    for i, ln in enumerate(lines[skip:], start=skip):
        if not ln.strip():
            out.append("")
            continue
        f = _split(ln)
        if len(f) < need:
            raise InputError(f"{len(f)} fields but --columns reads field {need}", file=path, row=i + 1 - skip
                             if header else None, line=None if header else i + 1)
        out.append(",".join(f[j - 1] for j in columns.values()))
    tmp = tmpdir / "mapped.csv"
    tmp.write_text("\n".join(out) + "\n", encoding="utf-8")
    return tmp, skip


def read_trace(path: str, units: str = "mm", columns: Mapping[str, int] | None = None, scale: float = 1.0,
               sample_period: float | None = None) -> Trace:
    """Read and validate a trace (module docstring). ``columns``: a 1-based field map for a plain
    delimited log; ``scale``: units per count for positions logged as integer encoder counts;
    ``sample_period`` (s): the t column counts samples (``halsampler -t``, a log's row index) and
    t = count * sample_period.
    Raises InputError naming the file, row and column for a missing column, an axis without its
    command or actual, a non-finite value, a time that does not increase."""
    if units not in ("mm", "deg"):
        raise InputError(f"--units must be mm or deg, got {units!r}")
    if not (math.isfinite(scale) and scale > 0):
        raise InputError(f"--scale must be a positive number (units per count), got {scale!r}")
    if sample_period is not None and not (math.isfinite(sample_period) and sample_period > 0):
        raise InputError(f"--sample-period must be a positive number of s, got {sample_period!r}")
    if columns:
        import tempfile

        with tempfile.TemporaryDirectory() as td:
            tmp, skip = _mapped_csv(path, columns, Path(td))
            try:
                tab = read_table(tmp, required=["t"], others="float", min_rows=3, what="trace")
            except InputError as exc:
                row = exc.row
                raise InputError(exc.message, file=path, row=row, column=exc.column) from None
            tab = Table(path, tab.header, tab.columns, tab.rows + (skip - 1 if skip else 0), tab.ignored)
    else:
        tab = read_table(path, required=["t"], others="float", min_rows=3, what="trace")
    cols: dict[str, dict[str, str]] = {}
    temps: dict[str, np.ndarray] = {}
    ignored = list(tab.ignored)
    for name in tab.columns:
        if name == "t":
            continue
        m = _AXIS_COLUMN.match(name)
        if m:
            cols.setdefault(m.group(1), {})[m.group(2).lower()] = name
        elif name.lower().startswith("temp_") and len(name) > 5:
            temps[name[5:]] = tab[name]
        else:
            ignored.append(name)
    for name in list(tab.columns):
        bad = np.flatnonzero(~np.isfinite(tab[name]))
        if len(bad):
            raise tab.error(f"value is {tab[name][bad[0]]} (not a finite number)", int(bad[0]), name)
    t = tab["t"] * sample_period if sample_period else tab["t"]
    d = np.diff(t)
    bad = np.flatnonzero(~(d > 0))
    if len(bad):
        k = int(bad[0]) + 1
        raise tab.error(f"time {t[k]:g} s does not increase (previous sample at {t[k - 1]:g} s)", k, "t")
    axes = []
    for a, kinds in cols.items():
        for need in ("cmd", "act"):
            if need not in kinds:
                other = kinds.get("act" if need == "cmd" else "cmd") or next(iter(kinds.values()))
                raise tab.header_error(f"axis {a} has {other} but no {a}_{need} column (each axis needs "
                                       f"<AX>_cmd and <AX>_act)", f"{a}_{need}")
        axes.append(a)
    if not axes:
        raise tab.header_error("no axis: a trace needs per axis <AX>_cmd and <AX>_act columns (e.g. X_cmd, X_act)")
    cmd = {a: tab[cols[a]["cmd"]] * scale for a in axes}
    act = {a: tab[cols[a]["act"]] * scale for a in axes}
    extra = {a: {k: tab[c] for k, c in cols[a].items() if k not in ("cmd", "act")} for a in axes}
    return Trace(str(path), t, tuple(axes), cmd, act, extra, temps, units, tab.rows, tuple(ignored), scale)


# ==============================================================================================
# model and simulation
@dataclass
class TraceModel:
    """Parameters of the trace model (module docstring; internal units: the file's unit, s).
    tau: first-order lag 1/Kv per axis; t2: 1/wn of the second-order servo; zeta: its damping
    (1 when unset); iv, ia: 1/vmax, 1/amax (0: no limit); backlash, backlash_load: reversal size b;
    offset_s: pure delay of every axis; thermal: channel -> (gain per deg C, tau s) on
    ``thermal_axis``; drift: (gain, tau s) of growth against time on that axis; quant: the share
    of the act channel's rounding per axis (0: none, 1: all); delay: one axis's own transport delay
    (s), on top of offset_s."""

    tau: dict[str, float] = field(default_factory=dict)
    t2: dict[str, float] = field(default_factory=dict)
    zeta: dict[str, float] = field(default_factory=dict)
    iv: dict[str, float] = field(default_factory=dict)
    ia: dict[str, float] = field(default_factory=dict)
    backlash: dict[str, float] = field(default_factory=dict)
    backlash_load: dict[str, float] = field(default_factory=dict)
    offset_s: float = 0.0
    thermal: dict[str, tuple[float, float]] = field(default_factory=dict)
    thermal_axis: str | None = None
    drift: tuple[float, float] = (0.0, 1.0)
    quant: dict[str, float] = field(default_factory=dict)
    delay: dict[str, float] = field(default_factory=dict)

    def copy(self) -> TraceModel:
        return TraceModel(dict(self.tau), dict(self.t2), dict(self.zeta), dict(self.iv), dict(self.ia),
                          dict(self.backlash), dict(self.backlash_load), self.offset_s, dict(self.thermal),
                          self.thermal_axis, self.drift, dict(self.quant), dict(self.delay))


def _lag1_coeffs(h: float, tau: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of tau y' = u - y, exact for u linear between grid points (first-order hold)."""
    a = math.exp(-h / tau)
    b0 = 1.0 - tau * (1.0 - a) / h
    return np.array([b0, (1.0 - a) - b0, 0.0]), np.array([1.0, -a, 0.0])


@njit(cache=True)
def _iir(u: np.ndarray, b: np.ndarray, a: np.ndarray, start: np.ndarray) -> np.ndarray:  # pragma: no cover
    """A second-order (or first-order: b[2] = a[2] = 0) IIR filter with unit DC gain, direct form II
    transposed, at rest on u at index 0 and at every ``start`` (a restart after a gap)."""
    y = np.empty_like(u)
    base = u[0]
    z1 = 0.0
    z2 = 0.0
    for k in range(len(u)):
        if start[k]:
            base = u[k]
            z1 = 0.0
            z2 = 0.0
        x = u[k] - base
        yk = b[0] * x + z1
        z1 = b[1] * x - a[1] * yk + z2
        z2 = b[2] * x - a[2] * yk
        y[k] = yk + base
    return y


def _lag1(u: np.ndarray, h: float, tau: float, start: np.ndarray | None = None) -> np.ndarray:
    """tau y' = u - y, exact for u linear between grid points, at rest on u(0) (and at ``start``)."""
    b, a = _lag1_coeffs(h, tau)
    return _iir(u, b, a, _starts(u, start))


def _starts(u: np.ndarray, start: np.ndarray | None) -> np.ndarray:
    if start is None:
        start = np.zeros(len(u), dtype=np.bool_)
        start[0] = True
    return start


def _expm(M: np.ndarray) -> np.ndarray:
    """exp(M) of a small matrix: Taylor series of M / 2^s (norm below 1/2), squared s times."""
    nrm = float(np.max(np.sum(np.abs(M), axis=1)))
    s = max(0, int(math.ceil(math.log2(nrm))) + 1) if nrm > 0.5 else 0
    X = M / 2.0 ** s
    E = np.eye(len(M))
    term = np.eye(len(M))
    for k in range(1, 18):
        term = term @ X / k
        E = E + term
    for _ in range(s):
        E = E @ E
    return E


def _lag2_coeffs(h: float, t2: float, zeta: float) -> tuple[np.ndarray, np.ndarray]:
    """(b, a) of y'' + 2 zeta wn y' + wn^2 y = wn^2 u (wn = 1/t2), exact for u linear between grid
    points (first-order hold)."""
    wn = 1.0 / t2
    M = np.zeros((4, 4))
    M[:2, :2] = np.array([[0.0, 1.0], [-wn * wn, -2.0 * zeta * wn]]) * h
    M[1, 2] = wn * wn * h
    M[2, 3] = 1.0
    E = _expm(M)
    Phi, g1 = E[:2, :2], E[:2, 3]
    g0 = E[:2, 2] - g1  # x[k+1] = Phi x[k] + g0 u[k] + g1 u[k+1]
    b = np.array([g1[0], g0[0] - Phi[1, 1] * g1[0] + Phi[0, 1] * g1[1], -Phi[1, 1] * g0[0] + Phi[0, 1] * g0[1]])
    a = np.array([1.0, -np.trace(Phi), Phi[0, 0] * Phi[1, 1] - Phi[0, 1] * Phi[1, 0]])
    return b, a


def _lag2(u: np.ndarray, h: float, t2: float, zeta: float, start: np.ndarray | None = None) -> np.ndarray:
    """The second-order servo (``_lag2_coeffs``), at rest on u(0) (and at ``start``)."""
    b, a = _lag2_coeffs(h, t2, zeta)
    return _iir(u, b, a, _starts(u, start))


@njit(cache=True)
def _rate_limit(u: np.ndarray, step: float, start: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """y follows u moving at most ``step`` per grid point (restarting on u at ``start``)."""
    y = np.empty_like(u)
    yk = u[0]
    for k in range(len(u)):
        if start[k]:
            yk = u[k]
        d = u[k] - yk
        if d > step:
            d = step
        elif d < -step:
            d = -step
        yk += d
        y[k] = yk
    return y


@njit(cache=True)
def _accel_limit(u: np.ndarray, h: float, amax: float, start: np.ndarray) -> np.ndarray:  # pragma: no cover
    """The axis velocity w chases the commanded velocity (constant over each grid interval, u
    being linear there) changing by at most amax a second, from rest (and from rest on u at
    ``start``); the position is its exact integral (w piecewise linear)."""
    y = np.empty_like(u)
    y[0] = yk = u[0]
    w = 0.0
    for k in range(1, len(u)):
        if start[k]:
            yk = u[k]
            w = 0.0
            y[k] = yk
            continue
        v = (u[k] - u[k - 1]) / h
        d = v - w
        tr = abs(d) / amax
        if tr >= h:
            w1 = w + (amax * h if d > 0 else -amax * h)
            yk += 0.5 * (w + w1) * h
        else:
            w1 = v
            yk += 0.5 * (w + v) * tr + v * (h - tr)
        w = w1
        y[k] = yk
    return y


@njit(cache=True)
def _saturating_loop(u: np.ndarray, h: float, tau: float, vmax: float, amax: float, start: np.ndarray
                     ) -> np.ndarray:  # pragma: no cover - compiled
    """A first-order position loop that saturates: the axis velocity is (u - y) / tau, clipped to
    +-vmax, and changes by at most amax a second. Each step takes the exact first-order-hold step
    of the unsaturated loop and limits the velocity it implies; exact while the loop is linear or
    saturated over a whole step. From rest on u(0), and on u at ``start``."""
    a = np.exp(-h / tau)
    b0 = 1.0 - tau * (1.0 - a) / h
    b1 = (1.0 - a) - b0
    y = np.empty_like(u)
    y[0] = yk = u[0]
    w = 0.0
    for k in range(1, len(u)):
        if start[k]:
            yk = u[k]
            w = 0.0
            y[k] = yk
            continue
        v = (a * yk + b0 * u[k] + b1 * u[k - 1] - yk) / h
        if v > vmax:
            v = vmax
        elif v < -vmax:
            v = -vmax
        d = v - w
        if d > amax * h:
            v = w + amax * h
        elif d < -amax * h:
            v = w - amax * h
        yk += v * h
        w = v
        y[k] = yk
    return y


def rounded_mean(y: np.ndarray, q: np.ndarray, v0: float, jitter: float) -> np.ndarray:
    """E[v0 + q round((y + n - v0) / q)] for n ~ N(0, (jitter q)^2), per sample (y where q = 0):
    the rounding, its steps turned into ramps about 2 jitter q wide (only the neighbouring grid
    points are reached: jitter well below 1/2)."""
    from scipy.special import ndtr

    on = q > 0
    qs = np.where(on, q, 1.0)
    m = np.round((y - v0) / qs)
    r = y - v0 - m * qs
    s = jitter * qs
    e = v0 + qs * (m + ndtr((r - 0.5 * qs) / s) - ndtr((-0.5 * qs - r) / s))
    return np.where(on, e, y)


def _direction(u: np.ndarray) -> np.ndarray:
    """Last direction of motion (-1, 0 before the first move, +1) at each grid point."""
    d = np.diff(u, prepend=u[0])
    eps = 1e-12 * max(1.0, float(np.max(np.abs(u))))
    s = np.where(d > eps, 1.0, np.where(d < -eps, -1.0, 0.0))
    idx = np.where(s != 0, np.arange(len(s)), 0)
    np.maximum.accumulate(idx, out=idx)
    return np.where(idx > 0, s[idx], s[0])


def breaks(trace: Trace) -> np.ndarray:
    """(n - 1,) True where a new segment starts after sample i: a time gap (a step above
    ``GAP_FACTOR`` median periods) or, on an axis with ``<AX>_vel_cmd``, a commanded jump further
    than its commanded velocity allows (|du| > 1.5 dt max(|v_i|, |v_i+1|) + 2 q, q the command's
    quantisation step: rows missing from the log, as in the Michigan mill traces)."""
    t = trace.t
    dt = np.diff(t)
    out = dt > GAP_FACTOR * trace.dt
    for a in trace.axes:
        v = trace.extra[a].get("vel_cmd")
        if v is None:
            continue
        q = quantisation_steps(trace.cmd[a])
        allow = 1.5 * dt * np.maximum(np.abs(v[1:]), np.abs(v[:-1])) + 2.0 * np.maximum(q[1:], q[:-1])
        out |= np.abs(np.diff(trace.cmd[a])) > allow
    return out


class TraceKnots:
    """The command on the internal grid (what the terms ask of a program's knots)."""

    S = None

    def __init__(self, trace: Trace) -> None:
        t = trace.t
        span = float(t[-1] - t[0])
        h = trace.dt
        if span / h > GRID_MAX:
            h = span / GRID_MAX
        n = int(math.floor(span / h + 1e-9)) + 1
        self.h = h
        self.tg = t[0] + h * np.arange(n + 1)  # one point beyond the last sample
        self.u = {a: np.interp(self.tg, t, trace.cmd[a]) for a in trace.axes}
        self.dir = {a: _direction(self.u[a]) for a in trace.axes}
        self.n = len(self.tg)
        # a gap ends a segment: the simulation restarts at rest on the command after it
        after = np.flatnonzero(breaks(trace)) + 1
        starts = [0] + sorted({int(np.floor((t[i] - t[0]) / h + 1e-9)) for i in after} - {0})
        self.segments = list(zip(starts, starts[1:] + [self.n], strict=True))
        self.start = np.zeros(self.n, dtype=np.bool_)
        self.start[starts] = True

    def moves(self, a: str) -> bool:
        u = self.u.get(a)
        return u is not None and float(np.ptp(u)) > 0.0

    def reverses(self, a: str) -> bool:
        d = self.dir.get(a)
        return d is not None and bool(np.any(d[1:] * d[:-1] < 0))

    def direction(self, a: str) -> np.ndarray:
        return self.dir[a]


class TraceSimulator:
    """The actual position each axis is predicted to take (module docstring), at the samples
    ``idx`` of the trace: ``run(model)`` -> (len(idx), axes)."""

    def __init__(self, trace: Trace, knots: TraceKnots, idx: np.ndarray) -> None:
        self.trace, self.knots, self.idx = trace, knots, idx
        self.t = trace.t[idx]
        self.channels = tuple(f"{a}_act" for a in trace.axes)
        self.load_sign = {a: np.sign(trace.extra[a]["load"][idx]) for a in trace.axes if "load" in trace.extra[a]}
        self._lowpassed: dict[tuple[str, float], np.ndarray] = {}
        self._grid: dict[str, tuple[np.ndarray, float]] = {}

    def quant_grid(self, a: str) -> tuple[np.ndarray, float]:
        """(step q at each sample, origin v0) of axis a's act channel (file units): a uniform grid
        v0 + k q of its values when there is one, else the written decimals or figures per sample
        (origin 0); q = 0 where none is evident."""
        if a not in self._grid:
            x = self.trace.act[a]
            q = quantisation_steps(x)
            grid = uniform_grid(x, written=float(np.min(q[q > 0], initial=0.0)))
            v0 = 0.0
            if grid > 0.0:
                q = np.full(len(x), grid)
                v0 = float(x[0] + np.median(np.mod(x - x[0] + 0.5 * grid, grid) - 0.5 * grid))
            self._grid[a] = (q[self.idx], v0)
        return self._grid[a]

    def loc(self, offset: float) -> tuple[np.ndarray, np.ndarray]:
        """Grid index and fraction of each sample time minus ``offset`` (s)."""
        kn = self.knots
        x = np.clip((self.t - offset - kn.tg[0]) / kn.h, 0.0, kn.n - 1.000001)
        k = np.floor(x).astype(int)
        return k, x - k

    def temperature(self, ch: str, tau: float) -> np.ndarray:
        """T_ch - T_ch(first sample) through a first-order lag of ``tau`` s, at the samples."""
        key = (ch, round(tau, 12))
        if key not in self._lowpassed:
            tr, kn = self.trace, self.knots
            T = np.interp(kn.tg, tr.t, tr.temps[ch] - tr.temps[ch][0])
            y = _lag1(T, kn.h, tau) if tau > 1e-9 else T
            if len(self._lowpassed) > 64:
                self._lowpassed.clear()
            self._lowpassed[key] = np.interp(self.t, kn.tg, y)
        return self._lowpassed[key]

    def servo(self, model: TraceModel, a: str) -> np.ndarray:
        """The axis position on the grid (restarting at rest on the command after each gap)."""
        kn = self.knots
        u, h, start = kn.u[a], kn.h, kn.start
        ia, iv = model.ia.get(a, 0.0), model.iv.get(a, 0.0)
        tau = model.tau.get(a, 0.0)
        if tau > 0 and (ia > 0 or iv > 0):
            u = _saturating_loop(u, h, tau, 1.0 / iv if iv > 0 else np.inf, 1.0 / ia if ia > 0 else np.inf, start)
        else:
            if ia > 0:
                u = _accel_limit(u, h, 1.0 / ia, start)
            if iv > 0:
                u = _rate_limit(u, h / iv, start)
            if tau > 0:
                u = _lag1(u, h, tau, start)
        t2 = model.t2.get(a, 0.0)
        if t2 > 0:
            u = _lag2(u, h, t2, model.zeta.get(a, 1.0), start)
        return u

    def axis(self, model: TraceModel, a: str) -> np.ndarray:
        kn = self.knots
        u = self.servo(model, a)
        k, f = self.loc(model.offset_s + model.delay.get(a, 0.0))
        y = u[k] * (1.0 - f) + u[k + 1] * f
        b = model.backlash.get(a, 0.0)
        if b:
            y = y - 0.5 * b * kn.dir[a][k]
        bl = model.backlash_load.get(a, 0.0)
        if bl and a in self.load_sign:
            y = y - 0.5 * bl * self.load_sign[a]
        if a == model.thermal_axis:
            for ch, (g, tc) in model.thermal.items():
                if g:
                    y = y + g * self.temperature(ch, tc)
            g, tc = model.drift
            if g:
                y = y + g * (1.0 - np.exp(-(self.t - self.trace.t[0]) / tc))
        g = model.quant.get(a, 0.0)
        if g:
            q, v0 = self.quant_grid(a)
            y = y + g * (rounded_mean(y, q, v0, QUANT_JITTER) - y)
        return y

    def run(self, model: TraceModel) -> np.ndarray:
        return np.column_stack([self.axis(model, a) for a in self.trace.axes])

    def joint_derivatives(self, model: TraceModel, axes: Sequence[str]) -> dict[str, np.ndarray]:
        """d channel / d axis position: each axis moves its own channel one for one."""
        out = {}
        for a in axes:
            d = np.zeros((len(self.idx), len(self.channels)))
            d[:, self.channels.index(f"{a}_act")] = 1.0
            out[a] = d
        return out


# ==============================================================================================
# the problem the selector works on
@dataclass
class TraceProblem:
    """What the selector and the terms use of a ``camsmooth.diagnosis.problem.Problem``, built from
    a trace (``prepare_trace``). ``trace`` marks it for the trace-only terms; ``axes`` are the
    trace's axis names."""

    trace: Trace
    axes: tuple[str, ...]
    base: TraceModel
    channels: tuple[str, ...]
    knots: TraceKnots
    t: np.ndarray
    segment: np.ndarray
    data: np.ndarray
    floor: np.ndarray
    floor_info: dict[str, dict[str, float]]
    valid: np.ndarray
    outliers: list[dict[str, Any]]
    fit_idx: np.ndarray
    folds: np.ndarray
    sim_fit: TraceSimulator
    sim_all: TraceSimulator
    states: dict[str, np.ndarray]
    states_all: dict[str, np.ndarray]
    dt: float
    resid0: np.ndarray
    data_fit: np.ndarray
    w_fit: np.ndarray
    valid_fit: np.ndarray
    options: Options
    memo: dict[str, Any] = field(default_factory=dict)
    program: Any = None
    machine: Any = None


def _states(trace: Trace, knots: TraceKnots, idx: np.ndarray) -> dict[str, np.ndarray]:
    t = trace.t[idx]
    k = np.clip(np.searchsorted(knots.tg, t, side="right") - 1, 0, knots.n - 1)
    out = {"elapsed": t - trace.t[0], "row": trace.rows[idx] - 1}
    for a in trace.axes:
        u = knots.u[a]
        v = np.gradient(u, knots.h)
        out[f"pos_{a}"] = u[k]
        out[f"v_{a}"] = v[k]
        out[f"acc_{a}"] = np.gradient(v, knots.h)[k]
        out[f"dir_{a}"] = knots.dir[a][k]
    return out


def _thermal_axis(trace: Trace) -> str | None:
    """The one axis the temperature terms act on (reported in FINDINGS.json as input.thermal_axis):
    the one whose actual departs most from its command (standard deviation of act - cmd), among
    the axes whose command is constant when any is (a thermal run holds the axis it measures)."""
    if not trace.temps:
        return None

    def spread(a: str) -> float:
        r = trace.act[a] - trace.cmd[a]
        return float(np.std(r))

    held = [a for a in trace.axes
            if float(np.ptp(trace.cmd[a])) <= 1e-9 * max(1.0, float(np.max(np.abs(trace.cmd[a]))))]
    pool = held or list(trace.axes)
    return max(pool, key=spread)


def trace_options(opt: Options | None = None) -> Options:
    """The diagnosis options for a trace: the trace candidates, every fit sample screened."""
    from dataclasses import replace

    opt = opt or Options()
    cands = TRACE_CANDIDATES if opt.candidates is None else tuple(c for c in opt.candidates if c in TRACE_CANDIDATES)
    if not cands:
        raise InputError(f"--candidates: none of {', '.join(opt.candidates or ())} applies to a trace; "
                         f"a trace's candidates are {', '.join(TRACE_CANDIDATES)}")
    return replace(opt, candidates=cands, screen_samples=max(opt.screen_samples, opt.max_fit_samples),
                   max_fit_samples=min(opt.max_fit_samples, 20_000))


def prepare_trace(trace: Trace, options: Options | None = None) -> TraceProblem:
    """Noise floors, outliers, folds and the fit subset of a trace (as ``problem.prepare``)."""
    from scipy.ndimage import median_filter

    opt = trace_options(options)
    knots = TraceKnots(trace)
    n = len(trace.t)
    all_idx = np.arange(n)
    sim_all = TraceSimulator(trace, knots, all_idx)
    base = TraceModel(thermal_axis=_thermal_axis(trace))
    channels = sim_all.channels
    data = np.column_stack([trace.act[a] for a in trace.axes])
    resid = data - sim_all.run(base)
    segment = np.r_[0, np.cumsum(breaks(trace))]
    floor = np.empty_like(data)
    info: dict[str, dict[str, float]] = {}
    valid = np.ones_like(data, dtype=bool)
    outliers: list[dict[str, Any]] = []
    for j, a in enumerate(trace.axes):
        q_rec = quantisation_steps(trace.act[a])
        q_cmd = quantisation_steps(trace.cmd[a])
        f, inf = noise_floor(resid[:, j], segment, q_rec, q_cmd)
        tiny = 1e-9 * max(1.0, float(np.max(np.abs(data[:, j]))))
        floor[:, j] = np.maximum(f, tiny)
        inf["unit"] = trace.units
        info[channels[j]] = inf
        dev = np.abs(resid[:, j] - median_filter(resid[:, j], size=5, mode="nearest"))
        bad = dev > 20.0 * floor[:, j] + 1e-12
        valid[:, j] = ~bad
        for i in np.flatnonzero(bad)[:20]:
            outliers.append({"channel": channels[j], "t": float(trace.t[i]), "row": int(trace.rows[i]),
                             "residual": float(resid[i, j])})
    if n > opt.max_fit_samples:
        rng = np.random.default_rng(opt.seed)
        fit_idx = np.sort(rng.choice(n, opt.max_fit_samples, replace=False))
    else:
        fit_idx = all_idx
    nf = len(fit_idx)
    K = max(2, min(opt.folds, nf // 20))
    folds = np.minimum((np.arange(nf) * K) // nf, K - 1)
    sim_fit = sim_all if nf == n else TraceSimulator(trace, knots, fit_idx)
    return TraceProblem(trace=trace, axes=trace.axes, base=base, channels=channels, knots=knots, t=trace.t,
                        segment=segment, data=data, floor=floor, floor_info=info, valid=valid, outliers=outliers,
                        fit_idx=fit_idx, folds=folds, sim_fit=sim_fit, sim_all=sim_all,
                        states=_states(trace, knots, fit_idx), states_all=_states(trace, knots, all_idx),
                        dt=trace.dt, resid0=resid, data_fit=data[fit_idx], w_fit=1.0 / floor[fit_idx],
                        valid_fit=valid[fit_idx], options=opt)


# ==============================================================================================
# diagnosis and findings
@dataclass
class TraceDiagnosis:
    """The findings (JSON form), the fitted model, the problem and the residuals before and after
    on every sample (what the report plots)."""

    findings: dict[str, Any]
    model: TraceModel
    problem: TraceProblem
    predicted_before: np.ndarray
    predicted_after: np.ndarray


def _report_effect(P: TraceProblem, name: str, names: Sequence[str], x: np.ndarray, sd: np.ndarray
                   ) -> tuple[dict[str, Any], dict[str, Any], dict[str, str]]:
    from camsmooth.diagnosis.terms import term

    par, unc, unit = term(name).report(names, x, sd)
    if name == "quantisation":  # the step is the act channel's own grid (read from the data, not fitted)
        for n in names:
            a = n[3:]
            q = P.sim_all.quant_grid(a)[0]
            par[f"q_{a}"], unc[f"q_{a}"], unit[f"q_{a}"] = float(np.median(q[q > 0])), 0.0, "unit"
    if name == "backlash":  # trace units as read (the library's term assumes rad for A, B, C)
        par = {f"backlash_{n[2:]}": float(v) for n, v in zip(names, x, strict=True)}
        unc = {f"backlash_{n[2:]}": float(s) for n, s in zip(names, sd, strict=True)}
        unit = {k: P.trace.units for k in par}
    for k, u in unit.items():
        unit[k] = u.replace("unit", P.trace.units)
    return par, unc, unit


def diagnose_trace(trace: Trace, options: Options | None = None) -> TraceDiagnosis:
    """Select, fit and report the terms that explain the trace's actual against its command."""
    import time

    from camsmooth.diagnosis.findings import jsonable
    from camsmooth.diagnosis.selector import Selector, pooled
    from camsmooth.diagnosis.terms import term

    t0 = time.perf_counter()
    P = prepare_trace(trace, options)
    sel = Selector(P, P.options).run()  # type: ignore[arg-type]
    final = sel["final"]
    effects = []
    for step in sel["steps"]:
        name, before, after = step["added"], step["before"], step["after"]
        f = final
        sl = f.slice(name)
        names = f.pnames[name]
        sd = np.sqrt(np.maximum(f.sd()[sl] ** 2, f.long_run_sd()[sl] ** 2))
        par, unc, unit = _report_effect(P, name, names, f.x[sl], sd)
        none = sel["none_measurable"].get(name, [])
        same = [e for e in sel["equivalences"] if e["chosen"] == name]
        effects.append({"name": name, "parameters": par, "uncertainties": unc, "units": unit,
                        "equivalent_to": same,
                        "heldout_rms_before": before.heldout_rms, "heldout_rms_after": after.heldout_rms,
                        "rms_before": before.rms_fit, "rms_after": after.rms_fit,
                        "none_measurable": none, "verdict": {k: v for k, v in step["verdict"].items()
                                                             if isinstance(v, (int, float, str, bool))},
                        "sentence": term(name).sentence(par, unc, none).replace(" unit", f" {trace.units}")})
    pred0 = P.sim_all.run(P.base)
    pred1 = P.sim_all.run(final.physics)
    r0, r1 = P.data - pred0, P.data - pred1
    rms = {c: {"before": float(np.sqrt(np.mean(r0[P.valid[:, j], j] ** 2))),
               "after": float(np.sqrt(np.mean(r1[P.valid[:, j], j] ** 2)))} for j, c in enumerate(P.channels)}
    loc = locate_intervals(P.t, r1, P.floor, P.valid, P.channels, P.states_all, P.segment, max_intervals=10)
    named = list(sel["active"])
    base_fit = sel["baseline"]
    heldout = {"scheme": f"{len(final.fold_rss)} blocked time folds: each block predicted by the fit without it",
               "rms_before_floors": pooled(base_fit), "rms_after_floors": pooled(final),
               "rms_before": base_fit.heldout_rms, "rms_after": final.heldout_rms}
    verdict = (f"named {', '.join(named)}" if named else "nothing named: the actual follows its command within the "
               "noise, or no term of the library explains what is left")
    findings = {"input": {**trace.describe(), "thermal_axis": P.base.thermal_axis}, "named": named, "effects": effects,
                "rejected": [{k: v for k, v in r.items()} for r in sel["rejected"]],
                "equivalences": sel["equivalences"], "noise_floor": P.floor_info, "rms": rms, "heldout": heldout,
                "unexplained": {"count": loc["count"], "fraction_of_time_above": loc["fraction_of_time_above"],
                                "intervals": [{k: v for k, v in it.items() if k in
                                               ("t_start", "t_end", "samples", "peak_sigma", "channels")}
                                              for it in loc["intervals"]]},
                "outliers": P.outliers, "verdict": verdict, "runtime_s": time.perf_counter() - t0}
    return TraceDiagnosis(jsonable(findings), final.physics, P, pred0, pred1)


def summary_text(f: Mapping[str, Any]) -> str:
    """A few plain lines: what was named, held-out RMS per channel, what is left."""
    lines = [f"verdict: {f['verdict']}"]
    for e in f["effects"]:
        hb, ha = e["heldout_rms_before"], e["heldout_rms_after"]
        ch = ", ".join(f"{c} {hb[c]:.4g} -> {ha[c]:.4g}" for c in hb if hb[c] is not None and ha[c] is not None)
        lines.append(f"- {e['sentence']} (held-out RMS {ch})")
        for q in e.get("equivalent_to", []):
            lines.append(f"  cannot tell it apart from {q['alternative']} on this trace: {q['separating_measurement']}")
    u = f["unexplained"]
    if u["count"]:
        it = u["intervals"][0]
        lines.append(f"left unexplained: {u['count']} interval(s) above 3 floors; largest at "
                     f"t = {it['t_start']:.4g}..{it['t_end']:.4g} s ({it['peak_sigma']:.3g} floors)")
    return "\n".join(lines)


def write_trace_report(diag: TraceDiagnosis, folder: Path) -> None:
    """Per axis: command, actual and the model before and after; residuals before and after;
    report.html listing the findings."""
    import html
    import json

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    P = diag.problem
    tr = P.trace
    folder.mkdir(parents=True, exist_ok=True)
    figs = []
    step = max(1, len(tr.t) // 20000)
    for j, a in enumerate(tr.axes):
        fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
        s = slice(None, None, step)
        ax1.plot(tr.t[s], tr.cmd[a][s], lw=0.8, label="command")
        ax1.plot(tr.t[s], tr.act[a][s], lw=0.8, label="actual")
        ax1.plot(tr.t[s], diag.predicted_after[s, j], lw=0.8, ls="--", label="model after")
        ax1.set_ylabel(f"{a} ({tr.units})")
        ax1.legend(loc="best", fontsize=8)
        ax2.plot(tr.t[s], (P.data - diag.predicted_before)[s, j], lw=0.6, label="residual before (actual - command)")
        ax2.plot(tr.t[s], (P.data - diag.predicted_after)[s, j], lw=0.6, label="residual after the named terms")
        ax2.set_xlabel("t (s)")
        ax2.set_ylabel(f"residual ({tr.units})")
        ax2.legend(loc="best", fontsize=8)
        fn = f"trace_{a}.png"
        fig.tight_layout()
        fig.savefig(folder / fn, dpi=90)
        plt.close(fig)
        figs.append(fn)
    f = diag.findings
    body = "".join(f"<li>{html.escape(e['sentence'])}</li>" for e in f["effects"]) or "<li>nothing named</li>"
    imgs = "".join(f'<p><img src="{fn}" alt="{fn}"></p>' for fn in figs)
    (folder / "report.html").write_text(
        f"<!doctype html><html><head><meta charset='utf-8'><title>camsmooth trace diagnosis</title></head><body>"
        f"<h1>Trace diagnosis</h1><p>{html.escape(tr.summary())}</p><ul>{body}</ul>{imgs}"
        f"<pre>{html.escape(json.dumps(f['heldout'], indent=1))}</pre></body></html>", encoding="utf-8")
