"""Programs and recordings for `camsmooth diagnose`: CSV readers and writers, the University of
Michigan CNC-mill adapter, quantisation detection and the honest alignment of the two time bases.

Files: mm, s, degrees (A, B, A_act, B_act), rpm (S); inside the code mm, s, radians
(CONVENTIONS.md).

Program CSV: ``t`` and any of ``X, Y, Z`` (mm) and ``A, B`` (deg); optional ``S`` (spindle rpm)
and ``segment`` (integer; the program restarts at rest at the first row of a new segment, used
for traces with logging gaps). Recording CSV: ``t`` and any of ``X_act .. B_act`` (axis
actuals, encoder positions), ``tip_x, tip_y, tip_z`` (measured tool tip, mm, workpiece frame),
``axis_i, axis_j, axis_k`` (measured unit tool axis) and ``temp_*`` (temperatures, kept as
states only). Other columns are ignored and listed in the notes.

Alignment (``align``): the program is a piecewise-linear command between its rows (a first-order
hold, what a controller's linear interpolator executes); it is evaluated *exactly* at the
recording's own sample times, never resampled onto a common grid, and the servo and thermal
responses are integrated exactly for that piecewise-linear input (camsmooth.diagnosis.simulator). Recording
samples outside the time span of the program's segment are dropped, never extrapolated.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.atomic import atomic_path
from camsmooth.io.table import number_text, read_table

LINEAR_AXES = ("X", "Y", "Z")
#: the rotary axes a program or recording may carry: two of them on any machine kind (A B on an AB
#: head, A C or B C on a table-table machine; camsmooth.machine.kinematics.MACHINE_KINDS)
ROTARY_AXES = ("A", "B", "C")
AXES = LINEAR_AXES + ROTARY_AXES
AXIS_CHANNELS = tuple(f"{a}_act" for a in AXES)
TIP_CHANNELS = ("tip_x", "tip_y", "tip_z")
DIR_CHANNELS = ("axis_i", "axis_j", "axis_k")
#: every simulated channel, in the order findings list them
CHANNELS = AXIS_CHANNELS + TIP_CHANNELS + DIR_CHANNELS
PROGRAM_COLUMNS = ("t",) + AXES + ("S", "segment")
#: channels whose file unit is degrees
DEGREE_COLUMNS = ROTARY_AXES + tuple(f"{a}_act" for a in ROTARY_AXES)

UMICH_PERIOD_S = 0.1


def channel_unit(name: str) -> str:
    """Unit of a channel inside the code: 'mm', 'rad' or '1' (unit vector component)."""
    if name in ("A_act", "B_act"):
        return "rad"
    if name in DIR_CHANNELS:
        return "1"
    return "mm"


@dataclass
class Program:
    """A commanded axis program. t: (N,) s, strictly increasing. axes: name -> (N,) commanded
    positions (X, Y, Z mm; A, B rad). S: spindle speed (rpm) or None. segment: (N,) int, non
    decreasing; each segment starts at rest. quantum: per-row quantisation step per axis (internal
    units, arrays or scalars; absent or 0 for exact commands; only logged commands such as the
    Michigan traces have one)."""

    t: np.ndarray
    axes: dict[str, np.ndarray]
    S: np.ndarray | None = None
    segment: np.ndarray | None = None
    quantum: dict[str, np.ndarray] = field(default_factory=dict)
    source: str = "<program>"
    notes: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.t = np.asarray(self.t, dtype=float)
        if self.segment is None:
            self.segment = np.zeros(len(self.t), dtype=np.int64)
        self.segment = np.asarray(self.segment, dtype=np.int64)

    def __len__(self) -> int:
        return len(self.t)


@dataclass
class Recording:
    """Recorded channels. t: (M,) s strictly increasing; channels: name -> (M,) values in
    internal units (see ``channel_unit``); temps: temp_* columns (file units); quantum: per-sample
    quantisation step per channel (internal units, 0 when none was found); segment: optional
    (M,) int (set by adapters whose program and recording share rows)."""

    t: np.ndarray
    channels: dict[str, np.ndarray]
    temps: dict[str, np.ndarray] = field(default_factory=dict)
    quantum: dict[str, np.ndarray] = field(default_factory=dict)
    segment: np.ndarray | None = None
    source: str = "<recording>"
    notes: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.t)


# ----------------------------------------------------------------------------------------------
# quantisation
def quantisation_steps(values: np.ndarray, min_distinct: int = 10) -> np.ndarray:
    """Quantisation step of each logged value (file units); zeros when none is evident.

    Values written with a fixed number of decimals (step 10^-d) or of significant figures (step
    10^(e - s + 1) for a value of exponent e: the Michigan traces keep 3 figures, so 158 has step 1
    and 72.4 step 0.1) are both recognised: per value the largest power of ten it is a non-zero
    multiple of is found (relative to the value: a value smaller than 10^k is never a multiple of
    it, so a channel that stays within +-0.01 mm is not given a step of 10^4 mm); d is the most
    decimals any value needs and s the most significant figures; each value's step is the coarser
    of the two models (zero values take 10^-d). The data's own grid is then checked
    (``uniform_grid``): when every distinct value lies on a uniform grid coarser than the written
    decimals (encoder counts of 1/2048 mm written to 6 decimals, say), that grid is the step. The
    RMS rounding error of a value with step q is q/sqrt(12). Fewer than ``min_distinct`` distinct
    values are no evidence of quantisation (steps 0), nor are values that need more than 9
    decimals and lie on no uniform grid.
    """
    x = np.asarray(values, dtype=float)
    out = np.zeros(len(x))
    nz = np.isfinite(x) & (x != 0.0)
    xs = x[nz]
    if len(xs) == 0 or len(np.unique(xs[:200000])) < min_distinct:
        return out
    kmax = np.full(len(xs), -100, dtype=np.int64)
    for k in range(-9, 5):
        s = 10.0 ** k
        quo = xs / s
        m = np.round(quo)
        kmax[(m != 0.0) & (np.abs(quo - m) <= 1e-6 + 1e-12 * np.abs(quo))] = k
    q_dec = 0.0
    if not np.any(kmax == -100):
        expo = np.floor(np.log10(np.abs(xs))).astype(np.int64)
        figures = int(np.max(expo - kmax + 1))
        q_dec = 10.0 ** int(np.min(kmax))
        out[:] = q_dec
        out[nz] = np.maximum(q_dec, 10.0 ** (expo - figures + 1).astype(float))
    grid = uniform_grid(x, min_distinct, written=q_dec)
    if grid > 0.0:
        out = np.maximum(out, grid)
    return out


def uniform_grid(values: np.ndarray, min_distinct: int = 10, written: float = 0.0) -> float:
    """The step q of a uniform grid v0 + k q that holds every distinct finite value (file units),
    or 0 when there is none: q is the smallest gap between distinct values and every value must
    lie within 1e-3 q (plus half the written step ``written``, the rounding of the file) of a grid
    point. The step is refined over the whole span (total span / total grid steps), so rounding
    of the written values does not accumulate. Relative to the data, so a channel of small range
    is judged on its own gaps. Where the values never take neighbouring grid points (a fast axis
    sampled slowly: the smallest gap is 2 or 3 steps), the smallest gap divided by 2 .. ``DIVISORS``
    is tried as well, the coarsest grid that holds the values being the step; a divided step must
    stay above twice the written step (else any written value would lie on it)."""
    v = np.asarray(values, float)
    u = np.unique(v[np.isfinite(v)][:200000])
    if len(u) < min_distinct:
        return 0.0
    gaps = np.diff(u)
    q0 = float(np.min(gaps))
    span = float(u[-1] - u[0])
    if not q0 > 0.0 or span / q0 > 1e8 or q0 < 1e-12 * max(float(np.max(np.abs(u))), 1e-300):
        return 0.0
    for k in range(1, DIVISORS + 1):
        if k > 1 and (q0 / k <= 2.0 * written or span * k / q0 > 1e8):
            break
        q = _grid_of(u, gaps, q0 / k, written)
        if q > 0.0:
            return q
    return 0.0


#: the largest divisor of the smallest gap between values ``uniform_grid`` tries as the step
DIVISORS = 6


def _grid_of(u: np.ndarray, gaps: np.ndarray, q0: float, written: float) -> float:
    """The step near q0 of a uniform grid holding the sorted distinct values u (``uniform_grid``), or 0."""
    q = q0
    for lim in (4.0, 16.0, 64.0, 256.0, 1024.0, math.inf):
        # refine q on the gaps of up to lim steps (their step counts are unambiguous), then wider
        steps = np.round(gaps / q)
        sel = steps <= lim
        if not sel.any():  # a divided step: the smallest gap is more steps than lim
            continue
        q = float(np.sum(gaps[sel]) / np.sum(steps[sel]))
    steps = np.round(gaps / q)
    k = np.concatenate([[0.0], np.cumsum(steps)])
    tol = 1e-3 * q + 0.5 * written + 1e-12 * float(np.max(np.abs(u)))
    return q if float(np.max(np.abs(u - u[0] - k * q))) <= tol else 0.0


def rms_step(q: np.ndarray | float) -> float:
    """RMS of per-sample quantisation steps (a summary for reports)."""
    q = np.asarray(q, dtype=float)
    return float(np.sqrt(np.mean(q * q))) if q.size else 0.0


# ----------------------------------------------------------------------------------------------
# CSV reading
def _read_table(path: str | Path) -> tuple[list[str], np.ndarray]:
    """Header and float table of a CSV (camsmooth.io.table.read_table: every column numeric and
    finite); bad cells raise InputError with row and column."""
    t = read_table(path, others="float", what="CSV file")
    for name in t.header:
        bad = ~np.isfinite(t[name])
        if bad.any():
            k = int(np.argmax(bad))
            raise t.error(f"value is not finite ({number_text(t[name][k])})", k, name)
    return list(t.header), np.column_stack([t[h] for h in t.header])


def _canonical(header: list[str], known: Sequence[str]) -> dict[str, int]:
    lower = {k.lower(): k for k in known}
    out = {}
    for j, h in enumerate(header):
        k = lower.get(h.lower())
        if k is not None:
            out[k] = j
    return out


def _check_time(t: np.ndarray, file: str) -> None:
    d = np.diff(t)
    bad = np.flatnonzero(~(d > 0))
    if len(bad):
        i = int(bad[0]) + 2
        raise InputError(f"t must increase strictly (t = {t[i - 1]} after {t[i - 2]})", file=file, row=i,
                         column="t")


def read_program_csv(path: str | Path) -> Program:
    """Read a program CSV (module docstring). Values are taken as exact commands (quantum 0)."""
    path = str(path)
    header, data = _read_table(path)
    cols = _canonical(header, PROGRAM_COLUMNS)
    if "t" not in cols:
        raise InputError("missing column 't' (time, s)", file=path, row=0, column="t")
    axes_present = [a for a in AXES if a in cols]
    if not axes_present:
        raise InputError("no commanded axis: expected any of X, Y, Z (mm), A, B (deg)", file=path, row=0)
    t = data[:, cols["t"]]
    _check_time(t, path)
    axes = {a: np.radians(data[:, cols[a]]) if a in ROTARY_AXES else data[:, cols[a]].copy() for a in axes_present}
    S = data[:, cols["S"]].copy() if "S" in cols else None
    seg = None
    notes = []
    if "segment" in cols:
        sv = data[:, cols["segment"]]
        if np.any(sv != np.round(sv)):
            i = int(np.flatnonzero(sv != np.round(sv))[0])
            raise InputError("segment must be an integer", file=path, row=i + 1, column="segment")
        if np.any(np.diff(sv) < 0):
            i = int(np.flatnonzero(np.diff(sv) < 0)[0]) + 2
            raise InputError("segment must not decrease", file=path, row=i, column="segment")
        seg = np.unique(sv, return_inverse=True)[1].astype(np.int64)
    ignored = [h for h in header if h not in {header[j] for j in cols.values()}]
    if ignored:
        notes.append(f"program columns ignored: {', '.join(ignored)}")
    return Program(t=t.copy(), axes=axes, S=S, segment=seg, source=path, notes=notes)


def read_recording_csv(path: str | Path) -> Recording:
    """Read a recording CSV (module docstring); detects each channel's quantisation step."""
    path = str(path)
    header, data = _read_table(path)
    cols = _canonical(header, ("t", "segment") + CHANNELS)
    if "t" not in cols:
        raise InputError("missing column 't' (time, s)", file=path, row=0, column="t")
    t = data[:, cols["t"]]
    _check_time(t, path)
    channels, quantum = {}, {}
    for name in CHANNELS:
        if name in cols:
            v = data[:, cols[name]]
            q = quantisation_steps(v)
            if name in DEGREE_COLUMNS:
                v, q = np.radians(v), np.radians(q)
            channels[name] = v.copy()
            quantum[name] = q
    temps = {h: data[:, j].copy() for j, h in enumerate(header) if h.lower().startswith("temp_")}
    if not channels:
        raise InputError("no recorded channel: expected any of " + ", ".join(CHANNELS), file=path, row=0)
    used = set(cols) | set(temps)
    ignored = [h for h in header if h not in used and h.lower() not in {c.lower() for c in cols}]
    notes = [f"recording columns ignored: {', '.join(ignored)}"] if ignored else []
    seg = None
    if "segment" in cols:
        seg = np.unique(data[:, cols["segment"]], return_inverse=True)[1].astype(np.int64)
    return Recording(t=t.copy(), channels=channels, temps=temps, quantum=quantum, segment=seg, source=path,
                     notes=notes)


# ----------------------------------------------------------------------------------------------
# CSV writing
def _write_columns(path: str | Path, names: Sequence[str], cols: Sequence[np.ndarray]) -> None:
    table = np.column_stack([np.asarray(c, dtype=float) for c in cols])
    with atomic_path(path) as tmp:
        np.savetxt(tmp, table, delimiter=",", header=",".join(names), comments="", fmt="%.10g")


def write_program_csv(path: str | Path, program: Program) -> None:
    """Write a program CSV atomically (degrees for A, B)."""
    names, cols = ["t"], [program.t]
    for a in AXES:
        if a in program.axes:
            names.append(a)
            cols.append(np.degrees(program.axes[a]) if a in ROTARY_AXES else program.axes[a])
    if program.S is not None:
        names.append("S")
        cols.append(program.S)
    if program.segment is not None and np.any(program.segment != program.segment[0]):
        names.append("segment")
        cols.append(program.segment)
    _write_columns(path, names, cols)


def write_recording_csv(path: str | Path, recording: Recording) -> None:
    """Write a recording CSV atomically (degrees for A_act, B_act)."""
    names, cols = ["t"], [recording.t]
    for c in CHANNELS:
        if c in recording.channels:
            names.append(c)
            v = recording.channels[c]
            cols.append(np.degrees(v) if c in DEGREE_COLUMNS else v)
    for k, v in recording.temps.items():
        names.append(k)
        cols.append(v)
    _write_columns(path, names, cols)


# ----------------------------------------------------------------------------------------------
# University of Michigan CNC mill adapter
def _sigfig_step(x: np.ndarray, figures: int = 3) -> np.ndarray:
    ax = np.abs(x)
    expo = np.floor(np.log10(np.where(ax > 0, ax, 1.0)))
    return 10.0 ** (expo - figures + 1)


def read_umich(path: str | Path) -> tuple[Program, Recording]:
    """Read one University of Michigan CNC-mill experiment CSV as (program, recording).

    Program: ``X1/Y1/Z1_CommandPosition`` (mm) as X, Y, Z; ``S1_CommandVelocity`` as S (the data
    give no unit; it serves as the spindle-on state). Recording: ``*_ActualPosition`` as X_act,
    Y_act, Z_act. Time: the sample index (first column) times 100 ms.

    Logging gaps: where a commanded axis jumps further in one sample than its commanded velocity
    allows (|dX| > 1.5 h max(|v_k|, |v_k+1|) + 2 q, q the value's rounding step), rows are
    missing from the log; a new segment starts there and the simulation restarts at rest on the
    command (the machine was at rest on both sides in every such case in experiments 01-12).
    Both command and actual are stored to about 3 significant figures; their quantisation steps
    go to ``quantum`` (README of the data set).
    """
    path = str(path)
    need = [f"{a}1_{k}" for a in LINEAR_AXES for k in ("CommandPosition", "ActualPosition", "CommandVelocity")]
    try:
        table = read_table(path, need, ["", "S1_CommandVelocity"], what="Michigan CNC-mill experiment file")
    except InputError as exc:
        if exc.row == 0 and exc.column in need:
            raise InputError(f"missing column '{exc.column}' (not a Michigan CNC-mill experiment file?)",
                             file=path, row=0, column=exc.column) from None
        raise
    n = len(table)
    # the unnamed first column is the sample index (the files were written with pandas' index)
    sample = table[""] if "" in table else np.arange(n, dtype=float)
    cols = {k: table[k] for k in need + ["S1_CommandVelocity"] if k in table}
    t = sample * UMICH_PERIOD_S
    _check_time(t, path)
    h = np.diff(t)
    brk = np.zeros(n - 1, dtype=bool)
    for a in LINEAR_AXES:
        c, v = cols[f"{a}1_CommandPosition"], cols[f"{a}1_CommandVelocity"]
        q = _sigfig_step(c)
        allow = 1.5 * h * np.maximum(np.abs(v[1:]), np.abs(v[:-1])) + 2.0 * np.maximum(q[1:], q[:-1])
        brk |= np.abs(np.diff(c)) > allow
    seg = np.concatenate([[0], np.cumsum(brk)]).astype(np.int64)
    axes = {a: cols[f"{a}1_CommandPosition"].copy() for a in LINEAR_AXES}
    channels = {f"{a}_act": cols[f"{a}1_ActualPosition"].copy() for a in LINEAR_AXES}
    notes = [f"Michigan CNC-mill trace: t = sample index x {UMICH_PERIOD_S} s; "
             f"{int(brk.sum())} logging gap(s) found (commanded jump beyond the commanded velocity), "
             f"the simulation restarts at rest after each"]
    S = cols.get("S1_CommandVelocity")
    if S is not None:
        notes.append("S = S1_CommandVelocity as logged (unit not given by the data; used as the spindle state)")
    program = Program(t=t, axes=axes, S=None if S is None else S.copy(), segment=seg,
                      quantum={a: quantisation_steps(axes[a]) for a in LINEAR_AXES}, source=path, notes=notes)
    recording = Recording(t=t.copy(), channels=channels,
                          quantum={c: quantisation_steps(v) for c, v in channels.items()}, segment=seg.copy(),
                          source=path, notes=list(notes))
    return program, recording


def concatenate(pairs: Sequence[tuple[Program, Recording]], gap_s: float = 1.0
                ) -> tuple[Program, Recording]:
    """Join several (program, recording) pairs into one, for fitting on several files: each pair
    is shifted in time to start ``gap_s`` after the previous one ends, and its segments are
    renumbered after the previous pair's (so nothing is interpolated across files)."""
    if not pairs:
        raise InputError("nothing to concatenate")
    axes = sorted({a for p, _ in pairs for a in p.axes}, key=AXES.index)
    chans = [c for c in CHANNELS if all(c in r.channels for _, r in pairs)]
    if not chans:
        raise InputError("the recordings share no channel")
    pt, pseg, rt, rseg = [], [], [], []
    pax = {a: [] for a in axes}
    rch = {c: [] for c in chans}
    S = [] if all(p.S is not None for p, _ in pairs) else None
    shift, seg0 = 0.0, 0
    for p, r in pairs:
        t0 = min(p.t[0], r.t[0])
        pt.append(p.t - t0 + shift)
        rt.append(r.t - t0 + shift)
        pseg.append(p.segment + seg0)
        rs = r.segment if r.segment is not None else _segment_of(p, r.t)
        rseg.append(rs + seg0)
        for a in axes:
            pax[a].append(p.axes.get(a, np.zeros(len(p.t))))
        for c in chans:
            rch[c].append(r.channels[c])
        if S is not None:
            S.append(p.S)
        shift = max(pt[-1][-1], rt[-1][-1]) + gap_s
        seg0 = int(max(pseg[-1].max(), rseg[-1].max())) + 1

    def joined_q(objs: Sequence[tuple[dict[str, np.ndarray], int]], key: str) -> np.ndarray:
        return np.concatenate([np.broadcast_to(np.asarray(q.get(key, 0.0), float), (n,)) for q, n in objs])

    progs = [p for p, _ in pairs]
    recs = [r for _, r in pairs]
    program = Program(t=np.concatenate(pt), axes={a: np.concatenate(v) for a, v in pax.items()},
                      S=None if S is None else np.concatenate(S), segment=np.concatenate(pseg),
                      quantum={a: joined_q([(p.quantum, len(p)) for p in progs], a) for a in axes},
                      source=" + ".join(p.source for p in progs),
                      notes=[f"{len(pairs)} files joined, {gap_s} s apart, segments kept separate"])
    recording = Recording(t=np.concatenate(rt), channels={c: np.concatenate(v) for c, v in rch.items()},
                          quantum={c: joined_q([(r.quantum, len(r)) for r in recs], c) for c in chans},
                          segment=np.concatenate(rseg), source=" + ".join(r.source for r in recs),
                          notes=list(program.notes))
    return program, recording


# ----------------------------------------------------------------------------------------------
# alignment of the two time bases
def _segment_of(program: Program, t: np.ndarray) -> np.ndarray:
    """Program segment containing each time (-1 when outside every segment's span)."""
    seg = program.segment
    starts = np.flatnonzero(np.r_[True, seg[1:] != seg[:-1]])
    ends = np.r_[starts[1:] - 1, len(seg) - 1]
    t0, t1 = program.t[starts], program.t[ends]
    k = np.searchsorted(t0, t, side="right") - 1
    ok = (k >= 0)
    kk = np.clip(k, 0, len(starts) - 1)
    ok &= t <= t1[kk] + 1e-12 * max(1.0, abs(float(program.t[-1])))
    return np.where(ok, seg[starts[kk]], -1)


@dataclass
class Aligned:
    """A recording matched to its program: the kept samples (indices into the recording), their
    program segment, and a plain description of how the time bases were matched."""

    t: np.ndarray
    segment: np.ndarray
    channels: dict[str, np.ndarray]
    quantum: dict[str, np.ndarray]
    kept: np.ndarray
    dropped: int
    method: str


def align(program: Program, recording: Recording) -> Aligned:
    """Match a recording to a program without resampling either (module docstring)."""
    if recording.segment is not None and len(recording.segment) == len(recording.t) and \
            len(program.t) == len(recording.t) and np.array_equal(program.t, recording.t):
        seg = recording.segment
    else:
        seg = _segment_of(program, recording.t)
    keep = np.flatnonzero(seg >= 0)
    dropped = len(recording.t) - len(keep)
    if len(keep) < 10:
        raise InputError(f"only {len(keep)} recording samples fall inside the program's time span "
                         f"[{program.t[0]:g}, {program.t[-1]:g}] s", file=recording.source, column="t")
    same = len(program.t) == len(recording.t) and np.allclose(program.t, recording.t, rtol=0, atol=1e-9)
    if same:
        method = ("program and recording share their sample times; the program is taken as piecewise "
                  "linear between its rows")
    else:
        method = (f"program ({len(program.t)} rows) evaluated at the {len(keep)} recording times as a "
                  f"piecewise-linear command between its rows (no resampling of the recording)")
    if dropped:
        method += f"; {dropped} recording samples outside the program's time span dropped (no extrapolation)"
    return Aligned(t=recording.t[keep], segment=seg[keep],
                   channels={c: v[keep] for c, v in recording.channels.items()},
                   quantum={c: np.broadcast_to(np.asarray(q, float), (len(recording.t),))[keep]
                            for c, q in recording.quantum.items()}, kept=keep, dropped=dropped, method=method)
