"""`diagnose` and its findings (METHODS.md section 6): simulate, locate, select the terms that
explain the residual (camsmooth.diagnosis.selector), and report them as typed findings,
serialised to FINDINGS.json (``Findings.to_dict``), plus the extended model (``model_json``).

Every named effect is physics the user can act on (the selector's rule, stated in each
rejection); two terms that explain the same residual on this program are reported as 'cannot
tell apart' with the measurement that would separate them; the joint covariance of the named
terms gives the parameter correlations reported with each effect.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.diagnosis.model_io import model_json
from camsmooth.diagnosis.problem import Options, Problem, locate_intervals, prepare, white_noise
from camsmooth.diagnosis.recordings import AXES, ROTARY_AXES, Program, Recording, channel_unit
from camsmooth.diagnosis.selector import Fit, Selector, channel_rms, pooled
from camsmooth.diagnosis.terms import separating_measurement, term
from camsmooth.diagnosis.terms.base import fmt
from camsmooth.errors import InputError, InternalError
from camsmooth.io.atomic import write_text_atomic
from camsmooth.machine import fitting
from camsmooth.machine.kinematics import Machine
from camsmooth.machine.model import ErrorModel


# ==============================================================================================
# typed findings
@dataclass
class Effect:
    """One named effect (or the 'unexplained' remainder): fitted parameters, uncertainties and
    units in report units, RMS per channel before and after it (fit subset; held-out), the
    selection verdict, the terms it cannot be told apart from, the groups (axes, elements) with
    no measurable share, parameter correlations with the other named terms, one sentence."""

    name: str
    parameters: dict[str, Any]
    uncertainties: dict[str, Any]
    units: dict[str, str]
    rms_before: dict[str, float]
    rms_after: dict[str, float]
    heldout_rms_before: dict[str, float]
    heldout_rms_after: dict[str, float]
    sentence: str
    verdict: dict[str, Any] = field(default_factory=dict)
    equivalent_to: list[dict[str, Any]] = field(default_factory=list)
    none_measurable: list[str] = field(default_factory=list)
    correlations: list[dict[str, Any]] = field(default_factory=list)
    model_had: dict[str, Any] | None = None
    channels: list[str] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "parameters": self.parameters,
                               "uncertainties": self.uncertainties, "units": self.units,
                               "rms_before": self.rms_before, "rms_after": self.rms_after,
                               "heldout_rms_before": self.heldout_rms_before,
                               "heldout_rms_after": self.heldout_rms_after}
        if self.name != "unexplained":
            out.update(verdict=self.verdict, equivalent_to=self.equivalent_to,
                       none_measurable=self.none_measurable, correlations=self.correlations)
        if self.model_had is not None:
            out["model_had"] = self.model_had
        if self.channels is not None:
            out["channels"] = self.channels
        out["sentence"] = self.sentence
        return out


@dataclass
class Rejection:
    """A term not named and why (the rule it failed, in words), with the figures behind it."""

    name: str
    reason: str
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, "reason": self.reason, **self.details}


@dataclass
class Findings:
    """Everything ``diagnose`` found; ``to_dict`` gives FINDINGS.json (the keys of earlier
    versions, unchanged)."""

    program: str
    recording: str
    channels: dict[str, dict[str, Any]]
    resampling: str
    notes: list[str]
    noise_floor: dict[str, dict[str, float]]
    outliers: list[dict[str, Any]]
    baseline_rms: dict[str, dict[str, float]]
    intervals: list[dict[str, Any]]
    located: dict[str, Any]
    intervals_after: list[dict[str, Any]]
    effects: list[Effect]
    final_rms: dict[str, dict[str, float]]
    rejected: list[Rejection]
    equivalences: list[dict[str, Any]]
    lag_vs_offset: dict[str, Any] | None
    verdict: str
    selection: dict[str, Any]
    runtime_s: float
    validation: list[dict[str, Any]] | None = None

    @property
    def named(self) -> list[str]:
        return [e.name for e in self.effects if e.name != "unexplained"]

    def to_dict(self) -> dict[str, Any]:
        out = {"program": self.program, "recording": self.recording, "channels": self.channels,
               "resampling": self.resampling, "notes": self.notes, "noise_floor": self.noise_floor,
               "outliers": self.outliers, "baseline_rms": self.baseline_rms, "intervals": self.intervals,
               "located": self.located, "intervals_after": self.intervals_after,
               "effects": [e.to_dict() for e in self.effects], "named": self.named, "final_rms": self.final_rms,
               "rejected": [r.to_dict() for r in self.rejected], "equivalences": self.equivalences,
               "lag_vs_offset": self.lag_vs_offset, "verdict": self.verdict, "selection": self.selection,
               "runtime_s": self.runtime_s}
        if self.validation is not None:
            out["validation"] = self.validation
        return jsonable(out)


@dataclass
class Diagnosis:
    """What ``diagnose`` returns: the typed findings (``result``; ``findings`` is their JSON
    form), the fitted model, the problem (for plots), the baseline and final residuals on all
    samples, and per named effect the residual at the fit samples without and with it and the
    states it depends on (what the report plots; it re-runs nothing)."""

    result: Findings
    physics: ErrorModel
    problem: Problem
    resid_before: np.ndarray
    resid_after: np.ndarray
    selection: dict[str, Any]
    effect_residuals: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    effect_states: dict[str, list[tuple[str, str, np.ndarray]]] = field(default_factory=dict)

    @property
    def findings(self) -> dict[str, Any]:
        return self.result.to_dict()

    def model_json(self) -> dict[str, Any]:
        return model_json(self.physics, note=f"camsmooth diagnose: {', '.join(self.result.named) or 'no change'}")


# ==============================================================================================
# sentences
def _rms_unit_text(before: Mapping[str, float], after: Mapping[str, float], chans: Sequence[str]) -> str:
    """'from A to B mm' on the channel with the largest fall, plus the others in brackets."""
    if not chans:
        return ""
    best = max(chans, key=lambda c: before[c] - after[c])

    def f(c: str) -> tuple[float, str]:
        u = channel_unit(c)
        return (180 / np.pi, "deg") if u == "rad" else (1.0, "" if u == "1" else u)

    fb, u = f(best)
    main = f"from {fmt(before[best] * fb)} to {fmt(after[best] * fb, u)} on {best}"
    others = [f"{c} {fmt(before[c] * f(c)[0])} -> {fmt(after[c] * f(c)[0])}" for c in chans if c != best]
    return main + (f" ({'; '.join(others)})" if others else "")


def _affected(before: Mapping[str, float], after: Mapping[str, float]) -> list[str]:
    return [c for c in before if np.isfinite(before[c]) and before[c] - after[c] > 0.01 * max(before[c], 1e-300)]


def sentence_for(name: str, params: Mapping[str, Any], unc: Mapping[str, Any], hb: Mapping[str, float],
                 ha: Mapping[str, float], equivalent: Sequence[Mapping[str, Any]] = (),
                 model_had: Mapping[str, Any] | None = None, none: Sequence[str] = ()) -> str:
    """One plain sentence per effect, e.g. "Z lags its command by v/Kv with Kv = 124 1/s, left
    out of the simulation; adding it cuts the held-out RMS from 0.22 to 0.045 mm"."""
    if name == "unexplained":
        return "No candidate in the library explains the residual: " + params.get("detail", "")
    chans = _affected(hb, ha) or list(hb)
    if model_had:
        had = ", ".join(f"{k} = {fmt(v) if isinstance(v, float) else v}" for k, v in model_had.items())
        tail = f"mis-set in the simulation; refitting it cuts the held-out RMS {_rms_unit_text(hb, ha, chans)} " \
               f"(the model had {had})"
    else:
        tail = f"left out of the simulation; adding it cuts the held-out RMS {_rms_unit_text(hb, ha, chans)}"
    s = f"{term(name).sentence(dict(params), dict(unc), list(none))}, {tail}"
    for e in equivalent:
        s += (f". Cannot tell it apart from {e['alternative']} on this recording (held-out "
              f"{e['heldout_rms_alternative']:.3g} vs {e['heldout_rms_chosen']:.3g} floors): "
              f"{e['separating_measurement']}")
    return s


# ==============================================================================================
# servo lag or clock offset?
def discriminate_lag_offset(sel: Selector, result: Mapping[str, Any]) -> dict[str, Any] | None:
    """Whether the data tell a servo lag from a clock offset (on top of the other chosen terms):
    by shape (one common lag vs one offset: both one parameter) and by the per-axis spread of
    the fitted delays (one clock offset delays every axis alike). On the screening subset of a
    long recording (``Selector.screener``)."""
    sel = sel.screener()
    P = sel.P
    axes = [a for a in AXES if P.knots.moves(a)]
    if not axes:
        return None
    others = tuple(n for n in result["active"] if n not in ("servo_lag", "time_offset"))
    f_lag = sel.fit_set(others + ("servo_lag",))
    f_off = sel.fit_set(others + ("time_offset",))
    if "servo_lag" not in f_lag.pnames or not f_lag.pnames["servo_lag"]:
        return None
    base = f_lag.physics.copy()

    def physics_common(x: np.ndarray) -> ErrorModel:
        out = base.copy()
        for a in axes:
            out.tau[a] = float(x[0])
        return out

    tau0 = float(np.mean([f_lag.physics.tau.get(a, 0.0) for a in axes]))
    f_common = sel._fit_core(("common_lag",), {"common_lag": ["tau"]}, lambda x: sel.resid(physics_common(x)),
                             np.array([max(tau0, 1e-4)]), np.array([0.0]), np.array([2.0]), np.array([1e-3]),
                             physics_common)
    h_common, h_off, h_lag = pooled(f_common), pooled(f_off), pooled(f_lag)
    # by shape: one common lag against one offset (one parameter each), told apart when their
    # held-out chi-square difference is beyond the noise (Selector.compare)
    shape = sel.compare(f_common, f_off)
    shape_same = not shape["resolved"]
    names = f_lag.pnames["servo_lag"]
    sl = f_lag.slice("servo_lag")
    taus, sds = f_lag.x[sl], f_lag.sd()[sl]
    delays = {n[4:]: {"delay_ms": float(1000 * t), "sd_ms": float(1000 * s)}
              for n, t, s in zip(names, taus, sds, strict=True)}
    w = 1.0 / np.maximum(sds, 1e-12) ** 2
    mean = float(np.sum(w * taus) / np.sum(w))
    chi2 = float(np.sum(w * (taus - mean) ** 2))
    dof = max(len(taus) - 1, 1)
    spread = len(taus) > 1 and chi2 / dof > 4.0 and h_lag < h_common * (1 - 0.5 * sel.opt.margin)
    tau_ms = 1000 * mean
    delay_text = ", ".join(f"{a} {d['delay_ms']:.3g} ± {d['sd_ms']:.2g} ms" for a, d in delays.items())
    if spread:
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
                   f"offset {h_off:.4g} floors (held-out chi-square difference {abs(shape['delta_chi2']):.4g} floors^2,"
                   f" standard error {shape['se']:.3g}), favouring a {better}; the per-axis delays ({delay_text})"
                   " agree within their uncertainties.")
    return {"heldout_common_lag": h_common, "heldout_offset": h_off, "heldout_per_axis_lag": h_lag,
            "shape_distinguishes": not shape_same, "shape_chi2_difference": shape["delta_chi2"],
            "shape_chi2_se": shape["se"], "per_axis_delays": delays, "delays_differ": bool(spread),
            "chi2_per_dof": chi2 / dof, "verdict": verdict, "units": "held-out RMS in noise floors"}


# ==============================================================================================
# diagnose
def floor_stats(resid: np.ndarray, floor: np.ndarray, valid: np.ndarray, channels: Sequence[str]
                ) -> dict[str, dict[str, float]]:
    """Per channel: RMS of residual / floor, and the fraction of samples above 3 floors."""
    out = {}
    for j, c in enumerate(channels):
        z = np.abs(resid[valid[:, j], j]) / floor[valid[:, j], j]
        out[c] = {"floors_rms": float(np.sqrt(np.mean(z * z))) if len(z) else math.nan,
                  "fraction_above_3_floors": float(np.mean(z > 3.0)) if len(z) else math.nan}
    return out


def above_floor(st: Mapping[str, float]) -> bool:
    """A residual stands above the floor when its RMS exceeds 1.3 floors or more than 2% of the
    samples exceed 3 floors (white noise at the floor: 1 floor and 0.27%)."""
    return st["floors_rms"] > 1.3 or st["fraction_above_3_floors"] > 0.02


def _correlations(final: Fit, name: str, limit: float) -> list[dict[str, Any]]:
    """Correlations (joint covariance of the final fit) between the parameters of ``name`` and
    those of the other named terms, beyond half the reporting limit."""
    if final.cov.size == 0:
        return []
    c = fitting.correlations(final.cov)
    out = []
    sl = final.slice(name)
    for other in final.active:
        if other == name:
            continue
        so = final.slice(other)
        for i, pn in zip(range(sl.start, sl.stop), final.pnames[name], strict=True):
            for j, po in zip(range(so.start, so.stop), final.pnames[other], strict=True):
                if abs(c[i, j]) >= 0.5 * limit:
                    out.append({"parameter": pn, "term": other, "other_parameter": po, "correlation": float(c[i, j]),
                                "strong": bool(abs(c[i, j]) >= limit)})
    return out


def _effect_states(P: Problem, name: str, names: Sequence[str], before: np.ndarray, after: np.ndarray
                   ) -> list[tuple[str, str, np.ndarray]]:
    """(channel, state label, state values at the fit samples) to plot for one effect."""
    pairs = []
    if name in ("servo_lag", "time_offset", "backlash"):
        for a in AXES:
            c = f"{a}_act"
            if c in P.channels and f"v_{a}" in P.states:
                f = np.degrees(1.0) if a in ROTARY_AXES else 1.0
                if name == "backlash":
                    pairs.append((c, f"last direction of {a}", P.states[f"dir_{a}"]))
                else:
                    pairs.append((c, f"commanded velocity {a} ({'deg/s' if a in ROTARY_AXES else 'mm/s'})",
                                  P.states[f"v_{a}"] * f))
    if not pairs:
        label, values, _ = term(name).state(P, names)
        change = np.sqrt(np.mean(before ** 2, axis=0)) - np.sqrt(np.mean(after ** 2, axis=0))
        pairs = [(P.channels[j], label, values) for j in np.argsort(change)[::-1][:3]]
    return pairs[:5]


def diagnose(program: Program, recording: Recording, machine: Machine | None = None, base: ErrorModel | None = None,
             options: Options | None = None) -> Diagnosis:
    """Run the whole diagnosis (module docstring; camsmooth.diagnosis.selector for the rules).

    Bad input raises InputError from ``prepare`` (alignment, floors); an InputError raised after
    that comes from a value computed here (a fit's NaN reaching a model constructor, say) and is
    re-raised as InternalError: a bug, exit 70 from the CLI, never 'bad input'."""
    t0 = time.perf_counter()
    opt = options or Options()
    P = prepare(program, recording, machine, base, opt)
    try:
        return _diagnose(program, recording, machine, base, opt, P, t0)
    except InputError as exc:
        raise InternalError(f"diagnosis failed after its inputs were read: {exc}") from exc


def _diagnose(program: Program, recording: Recording, machine: Machine | None, base: ErrorModel | None,
              opt: Options, P: Problem, t0: float) -> Diagnosis:
    """The selection and the findings of ``diagnose`` on a prepared problem P."""
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
            P = prepare(program, recording, machine, base, opt, white={c: min(w_new[c], w_old[c]) for c in w_new},
                        valid=P.valid, outliers=P.outliers)
            sel = Selector(P, opt)
            res = sel.run()
    baseline, final = res["baseline"], res["final"]
    rb = P.resid0
    ra = P.data - P.sim_all.run(final.physics)
    rms_b_all = channel_rms(rb, P.valid, P.channels)
    rms_a_all = channel_rms(ra, P.valid, P.channels)
    effects: list[Effect] = []
    after_fit = P.data_fit - P.sim_fit.run(final.physics)
    effect_residuals, effect_states = {}, {}
    for step in res["steps"]:
        name = step["added"]
        t = term(name)
        names = final.pnames[name]
        sl = final.slice(name)
        x, sd = final.x[sl], final.sd()[sl]
        par, unc, units = t.report(names, x, sd)
        eq = [e for e in res["equivalences"] if e["chosen"] == name]
        x_base = np.nan_to_num(np.asarray(t.read(P.base, names), float))
        had = None
        if np.any(x_base != 0.0):
            had = {k: v for k, v in t.report(names, x_base, np.zeros(len(names)))[0].items() if v}
        none = res["none_measurable"].get(name, [])
        before, after = step["before"], step["after"]
        effects.append(Effect(
            name=name, parameters=par, uncertainties=unc, units=units, rms_before=before.rms_fit,
            rms_after=after.rms_fit, heldout_rms_before=before.heldout_rms, heldout_rms_after=after.heldout_rms,
            verdict={k: v for k, v in step["verdict"].items() if k != "ok"},
            equivalent_to=[{k: v for k, v in e.items() if k != "chosen"} for e in eq], none_measurable=list(none),
            correlations=_correlations(final, name, opt.correlation_limit), model_had=had,
            sentence=sentence_for(name, par, unc, before.heldout_rms, after.heldout_rms, eq, had, none)))
        ph = final.physics.copy()
        if name in ("thermal_drift", "thermal_machine"):
            els = {n.split("_", 1)[1] for n in names}
            ph.thermal = {k: d for k, d in ph.thermal.items() if k not in els} | \
                {k: d for k, d in P.base.thermal.items() if k in els}
        else:
            t.write(ph, names, x_base if names else x_base)
        without = P.data_fit - P.sim_fit.run(ph)
        effect_residuals[name] = (without, after_fit)
        effect_states[name] = _effect_states(P, name, names, without, after_fit)
    z_b, z_a = floor_stats(rb, P.floor, P.valid, P.channels), floor_stats(ra, P.floor, P.valid, P.channels)
    at_floor_before = not any(above_floor(z_b[c]) for c in P.channels)
    at_floor_after = not any(above_floor(z_a[c]) for c in P.channels)
    states_all = P.sim_all.states()
    loc_before = locate_intervals(P.t, rb, P.floor, P.valid, P.channels, states_all, P.segment)
    loc_after = locate_intervals(P.t, ra, P.floor, P.valid, P.channels, states_all, P.segment)
    if not effects and at_floor_before:
        verdict = "nothing to explain: the residual is at the noise floor"
    elif not at_floor_after:
        above = [c for c in P.channels if above_floor(z_a[c])]
        detail = (", ".join(f"{c}: {fmt(rms_a_all[c])} RMS ({z_a[c]['floors_rms']:.3g} floors; "
                            f"{100 * z_a[c]['fraction_above_3_floors']:.2g}% of samples above 3 floors)" for c in above)
                  + f" remains, in {loc_after['count']} located interval(s)")
        effects.append(Effect(name="unexplained", parameters={"detail": detail}, uncertainties={}, units={},
                              rms_before=final.rms_fit, rms_after=final.rms_fit,
                              heldout_rms_before=final.heldout_rms, heldout_rms_after=final.heldout_rms,
                              channels=above, sentence=sentence_for("unexplained", {"detail": detail}, {},
                                                                    final.heldout_rms, final.heldout_rms)))
        verdict = ("explained in part; " if res["active"] else "") + "unexplained residual remains above the floor"
    else:
        verdict = "explained: the residual is at the noise floor after the named effects"
    discrimination = None
    if any(n in res["active"] for n in ("servo_lag", "time_offset")) and "time_offset" in res["applicable"] and \
            "servo_lag" in res["applicable"]:
        discrimination = discriminate_lag_offset(sel, res)
    if opt.rule == "absolute":
        share = (f"a main parameter of it is beyond {opt.resolvable_sigma:g} long-run standard uncertainties (batch "
                 "means over time, for autocorrelated residuals) with one sign in every fold fit, and the held-out "
                 f"chi-square falls in most folds by at least {opt.absolute_floor2:g} floors^2 a sample and "
                 f"{0.5 * opt.resolvable_sigma:g} long-run standard errors - whatever else is left unexplained (the "
                 "relative held-out change and BIC are reported, not used)")
    else:
        share = (f"it lowers the held-out RMS by {100 * opt.margin:.3g}% in most folds and BIC by {opt.bic_margin:g}"
                 + (f" with the held-out chi-square fall beyond {opt.separate_z:g} standard errors, or it is an effect "
                    f"on its own (at least {opt.standalone_floors:g} noise floors RMS, lowering the held-out mean "
                    f"square by {opt.margin_floor2:g} floors^2 in most folds, beyond the noise or consistent across "
                    "the folds, whatever else is left unexplained)" if opt.rule == "standalone" else ""))
    rule = (f"a term is named only when {share}; its effect on some channel reaches {opt.min_effect_floors:g} noise "
            "floors RMS (a floor holds the channel's white noise and resolution), its parameters differ from their "
            f"base values by {opt.resolvable_sigma:g} standard uncertainties (a clock offset by "
            f"{opt.min_offset_periods:g} of the sample period as well), and it survives the joint refit; an axis or "
            "element inside a term that fails is reported as 'none measurable'")
    result = Findings(
        program=program.source, recording=recording.source,
        channels={c: {"unit": channel_unit(c), "samples": int(P.valid[:, j].sum())} for j, c in enumerate(P.channels)},
        resampling=P.aligned.method, notes=list(dict.fromkeys(program.notes + recording.notes)),
        noise_floor=P.floor_info, outliers=P.outliers,
        baseline_rms={c: {"fit": rms_b_all[c], "heldout": baseline.heldout_rms[c], **z_b[c]} for c in P.channels},
        intervals=loc_before["intervals"], located={k: v for k, v in loc_before.items() if k != "intervals"},
        intervals_after=loc_after["intervals"][:10], effects=effects,
        final_rms={c: {"fit": rms_a_all[c], "heldout": final.heldout_rms[c], **z_a[c]} for c in P.channels},
        rejected=[Rejection(r["name"], r["reason"], {k: v for k, v in r.items() if k not in ("name", "reason")})
                  for r in res["rejected"]],
        equivalences=res["equivalences"], lag_vs_offset=discrimination, verdict=verdict,
        selection={"folds": int(P.folds.max()) + 1, "fold_kind": "contiguous blocks in time",
                   "margin_pct": 100 * opt.margin, "bic_margin": opt.bic_margin, "rule": rule,
                   "fit_samples": int(len(P.fit_idx)), "samples": int(len(P.t)),
                   "subset": ("all samples" if len(P.fit_idx) == len(P.t) else
                              f"an even random subset of {len(P.fit_idx)} of {len(P.t)} samples (seed "
                              f"{opt.seed}); final RMS on all samples"),
                   "rms_note": "baseline_rms.fit / final_rms.fit: all samples; heldout: each sample "
                               "predicted by the fit that left its fold out; effects' rms_*: fit subset"},
        runtime_s=time.perf_counter() - t0)
    return Diagnosis(result=result, physics=final.physics, problem=P, resid_before=rb, resid_after=ra,
                     selection=res, effect_residuals=effect_residuals, effect_states=effect_states)


def validate(program: Program, recording: Recording, diag: Diagnosis, machine: Machine | None = None
             ) -> dict[str, Any]:
    """Predict a recording the fit never saw with the current and the fitted model: RMS per
    channel before and after (isolated spikes left out as in ``prepare``)."""
    P = prepare(program, recording, machine or diag.problem.machine, diag.problem.base)
    rb = P.data - P.sim_all.run(P.base)
    ra = P.data - P.sim_all.run(diag.physics)
    before = channel_rms(rb, P.valid, P.channels)
    after = channel_rms(ra, P.valid, P.channels)
    return jsonable({"program": program.source, "recording": recording.source,
                     "channels": {c: {"rms_before": before[c], "rms_after": after[c], "unit": channel_unit(c),
                                      "floor": P.floor_info[c]["rms"], "samples": int(P.valid[:, j].sum())}
                                  for j, c in enumerate(P.channels)},
                     "outliers": len([o for o in P.outliers if "more" not in o])})


def jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        v = float(x)
        return v if math.isfinite(v) else None
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    if isinstance(x, np.ndarray):
        return jsonable(x.tolist())
    return x


def write_findings(path: str, diag: Diagnosis) -> None:
    """FINDINGS.json, atomically."""
    write_text_atomic(path, json.dumps(diag.findings, indent=2) + "\n")


def write_model(path: str, diag: Diagnosis) -> None:
    """The extended model JSON (``model_json``), atomically."""
    write_text_atomic(path, json.dumps(jsonable(diag.model_json()), indent=2) + "\n")
