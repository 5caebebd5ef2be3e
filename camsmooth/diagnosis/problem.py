"""Problem preparation for the diagnosis (METHODS.md section 6): alignment, baseline residual,
noise floor per channel and sample, outliers, located intervals, blocked folds and the fit
subset, frozen in one ``Problem``.

Noise floor per channel and sample: the larger of a white-noise estimate (robust scale of the
residual's second differences, 1.4826 MAD / sqrt(6)) and the quantisation of the recording and
of a logged command (sqrt(q_rec^2 + q_cmd^2) / sqrt(12)). Isolated spikes (|r - median5(r)| >
20 floors) are outliers, kept out of fits. Locate: intervals where |r| > 3 floors, with the axis
states there.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.diagnosis.recordings import (
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
from camsmooth.diagnosis.simulator import Knots, Simulator
from camsmooth.machine.kinematics import Machine, load_machine
from camsmooth.machine.model import ErrorModel


def _mad(x: np.ndarray) -> float:
    if len(x) == 0:
        return 0.0
    return float(1.4826 * np.median(np.abs(x - np.median(x))))


WHITE_SAMPLES = 300_000


def white_noise(residual: np.ndarray, segment: np.ndarray) -> float:
    """Robust white-noise sigma of a residual: 1.4826 MAD of its second differences (inside one
    segment) / sqrt(6); smooth structure cancels, sparse events are ignored by the median. On a
    long recording, from WHITE_SAMPLES samples spread over it (20 contiguous blocks: second
    differences need neighbours)."""
    def d2(r: np.ndarray, seg: np.ndarray) -> np.ndarray:
        same = seg[2:] == seg[:-2]
        return (r[2:] - 2 * r[1:-1] + r[:-2])[same]

    if len(residual) > WHITE_SAMPLES:
        blk = WHITE_SAMPLES // 20
        starts = np.linspace(0, len(residual) - blk, 20).astype(int)
        diffs = np.concatenate([d2(residual[i:i + blk], segment[i:i + blk]) for i in starts])
    else:
        diffs = d2(residual, segment)
    return _mad(diffs) / math.sqrt(6.0)


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


@dataclass(frozen=True)
class Options:
    """Diagnosis settings. folds: blocked time folds for held-out scoring; rule: 'absolute' (the
    default, ``Selector._judge_absolute``: a main parameter beyond resolvable_sigma long-run
    standard uncertainties with one sign in every fold fit, the held-out chi-square falling in
    most folds by absolute_floor2 floors^2 a sample and resolvable_sigma / 2 long-run standard
    errors; nothing relative to what else is unexplained), 'standalone' (the rule of the first
    issue-20 round: the relative margin, BIC and a held-out chi-square test, or an effect of
    standalone_floors noise floors RMS lowering the held-out mean square by margin_floor2
    floors^2, consistent across the folds) or 'margin' (the earlier rule); margin: the relative
    fall of the pooled held-out RMS and bic_margin the fall of BIC the 'standalone' and 'margin'
    rules ask for (reported under 'absolute');
    separate_z, separate_chi2: two candidates are told apart when their held-out chi-square
    difference (floors^2) exceeds separate_z of its standard errors and separate_chi2
    (``Selector.compare``), else they explain the residual equally; min_effect_floors: a term
    (and each axis or element inside it) is named only when its effect on some channel reaches
    this RMS in noise floors (a floor is the larger of the white noise and the resolution,
    q / sqrt(12)); min_offset_periods: a clock offset must reach this fraction of the sample
    period; resolvable_sigma: a parameter must differ from its base value by this many standard
    uncertainties; correlation_limit: parameters of two named terms correlated beyond it are
    reported; max_fit_samples: fits and scores use at most this many samples (an even random
    subset, seeded) - final figures use all; screen_samples: each round ranks the terms on at
    most this many of those (the chosen one is refitted and judged on all of them)."""

    folds: int = 5
    rule: str = "absolute"
    standalone_floors: float = 3.0
    margin: float = 0.02
    margin_floor2: float = 0.04
    absolute_floor2: float = 0.25
    bic_margin: float = 6.0
    separate_z: float = 3.0
    separate_chi2: float = 10.0
    min_effect_floors: float = 0.1
    min_offset_periods: float = 0.1
    resolvable_sigma: float = 3.0
    correlation_limit: float = 0.9
    max_fit_samples: int = 60_000
    screen_samples: int = 15_000
    max_terms: int = 6
    seed: int = 0
    candidates: tuple[str, ...] | None = None


@dataclass(frozen=True)
class Problem:
    """Program, recording and everything the fits share, computed once by ``prepare``:
    channels, data, floors, validity (outliers out), the baseline residual (resid0), folds and the fit
    subset (``*_fit`` arrays, w_fit = 1 / floor), simulators on the fit subset and on all
    samples, the commanded states at the fit samples. ``memo`` holds the data-dependent choices
    terms make once per problem (which parameters the motion shows, starting values)."""

    program: Program
    machine: Machine
    aligned: Aligned
    base: ErrorModel
    channels: tuple[str, ...]
    knots: Knots
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
    sim_all: Simulator
    states: dict[str, np.ndarray]
    dt: float
    resid0: np.ndarray
    data_fit: np.ndarray
    w_fit: np.ndarray
    valid_fit: np.ndarray
    options: Options
    memo: dict[str, Any] = field(default_factory=dict)


def _command_quantum(program: Program, channel: str, knots: Knots, k: np.ndarray) -> np.ndarray:
    q = program.quantum
    if channel in AXIS_CHANNELS:
        a = channel[0]
        v = q.get(a)
        return np.zeros(len(k)) if v is None else np.broadcast_to(np.asarray(v, float), (knots.n,))[k]
    names = ("X", "Y", "Z") if channel in TIP_CHANNELS else ROTARY_AXES
    parts = [np.broadcast_to(np.asarray(q[a], float), (knots.n,))[k] for a in names if a in q]
    return np.sqrt(np.sum(np.square(parts), axis=0)) if parts else np.zeros(len(k))


def prepare(program: Program, recording: Recording, machine: Machine | None = None,
            base: ErrorModel | None = None, options: Options | None = None,
            white: Mapping[str, float] | None = None, valid: np.ndarray | None = None,
            outliers: list[dict[str, Any]] | None = None) -> Problem:
    """Align, simulate the baseline, estimate floors, mark outliers, make folds and the fit
    subset (module docstring). white / valid / outliers: white-noise sigmas, the outlier mask and
    its list to use instead of estimating them (the second pass of ``diagnose``)."""
    opt = options or Options()
    machine = machine or load_machine(None)
    # the fitted rotary errors are those of the machine's kind (unstated on an AB head, as ever)
    base = base or ErrorModel()
    base = base.for_machine(machine)  # settings name the machine's own rotary errors
    al = align(program, recording)
    channels = [c for c in CHANNELS if c in al.channels]
    knots = Knots(program)
    sim_all = Simulator(program, machine, al.t, al.segment, channels, knots)
    data = np.column_stack([al.channels[c] for c in channels])
    sim0 = sim_all.run(base)
    resid = data - sim0
    del sim0
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
    given_outliers = outliers
    outliers = []
    given_valid = valid
    valid = np.ones_like(data, dtype=bool) if given_valid is None else given_valid
    for j, c in enumerate(channels if given_valid is None else ()):
        dev = np.abs(resid[:, j] - _median5(resid[:, j]))
        bad = dev > 20.0 * floor[:, j] + 1e-12
        valid[:, j] = ~bad
        for i in np.flatnonzero(bad)[:50]:
            outliers.append({"channel": c, "t": float(al.t[i]), "recorded": float(data[i, j]),
                             "simulated": float(data[i, j] - resid[i, j]), "residual": float(resid[i, j]),
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
    return Problem(program=program, machine=machine, aligned=al, base=base, channels=tuple(channels), knots=knots,
                   t=al.t, segment=al.segment, data=data, floor=floor, floor_info=info, valid=valid,
                   outliers=outliers if given_outliers is None else list(given_outliers), fit_idx=fit_idx,
                   folds=folds, sim_fit=sim_fit, sim_all=sim_all, states=states,
                   dt=dt, resid0=resid, data_fit=data[fit_idx], w_fit=1.0 / floor[fit_idx],
                   valid_fit=valid[fit_idx], options=opt)
