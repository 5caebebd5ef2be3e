"""Selection of the terms that explain a residual (METHODS.md section 6).

Each term is fitted by least squares on floor-weighted residuals (camsmooth.machine.fitting:
bounded Levenberg-Marquardt, covariance with the effective sample count) and scored on blocked
time folds: each fold is predicted by the fit without it (one Gauss-Newton step from the full
fit on the other folds' Jacobian rows, then simulated exactly). Greedy forward selection with a
backward check: each round every remaining term is screened jointly with the chosen ones (those
linearised); the best is refitted exactly and joins when

* (``Options.rule`` 'absolute', the default; ``Selector._judge_absolute``) its size is resolved
  whatever else is left unexplained: a main parameter differs from its base value by
  ``Options.resolvable_sigma`` long-run standard uncertainties (``Fit.long_run_sd``: the
  batch-means variance of the parameter's influence over time, camsmooth.diagnosis.significance,
  so an autocorrelated residual counts through the correlation of what is summed) with one sign
  in every fit that leaves a fold out; and the pooled held-out chi-square falls, in most folds, by
  at least ``Options.absolute_floor2`` noise floors^2 a sample and by resolvable_sigma / 2 of its
  long-run standard errors. The relative fall of the held-out RMS and BIC are reported, not used:
  a margin that is a share of everything else left unexplained refuses real effects exactly when
  the recording is rich. (Rules 'standalone' and 'margin' are the earlier ones, ``judge``.)
* it is physics the user can act on (``Selector.measurable``): its effect on some channel reaches
  ``Options.min_effect_floors`` noise floors RMS (the floor is the larger of the white noise and
  the channel's resolution, q / sqrt(12)), its
  parameters differ from their base values by ``Options.resolvable_sigma`` uncertainties, and
  the term's own rule holds (a clock offset must reach a fraction of the sample period). The same
  rule per axis or element inside a term: a group that fails is held at its base value and
  reported as 'none measurable';
* it survives a joint refit with the other kept terms (checked again at the end).

An earlier term that would no longer pass as the last one is dropped. Terms that explain the
residual equally well are reported as 'cannot tell apart' with the measurement that would
separate them; the one named is the first in the library's order (the more common cause).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from camsmooth.diagnosis import significance
from camsmooth.diagnosis.problem import Options, Problem
from camsmooth.diagnosis.terms import CANDIDATES, LIBRARY, Param, Term, separating_measurement, term
from camsmooth.diagnosis.terms.thermal import ThermalDrift
from camsmooth.errors import InputError, InternalError
from camsmooth.machine import fitting
from camsmooth.machine.model import ErrorModel

#: a term refused at screening whose fit RMS still falls by more than this (%) is judged on its exact
#: fit: the screening's held-out score is predicted from the Jacobian, which a nonlinear parameter
#: (the runout's phase) can defeat
SCREEN_RECHECK_PCT = 10.0


@dataclass
class Fit:
    """A fitted set of terms: names, parameter names and values, the model, the covariance
    (internal units), weighted RSS and per-channel RMS on the fit subset, held-out figures."""

    active: tuple[str, ...]
    pnames: dict[str, list[str]]
    x: np.ndarray
    physics: ErrorModel
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
    fold_x: np.ndarray | None = None  # (K, p): the parameters fitted without each fold
    lr_sd: np.ndarray | None = None  # (p,): long-run (batch-means) standard uncertainty, internal units

    def long_run_sd(self) -> np.ndarray:
        """Standard uncertainty of each parameter from the batch-means variance of its influence
        (camsmooth.diagnosis.significance): a sandwich H^-1 S H^-1 whose middle S is the long-run
        covariance of the per-sample scores, so autocorrelated residuals are accounted for by the
        correlation of what is summed, not by how much else is left unexplained."""
        return np.full(len(self.x), np.inf) if self.lr_sd is None else self.lr_sd

    def jackknife_sd(self) -> np.ndarray:
        """Blocked jackknife standard uncertainty of each parameter from the fits that leave one
        fold out (sqrt((K - 1) / K sum (x_k - mean)^2), internal units): contiguous folds in time
        carry the residual's autocorrelation, so this holds for coloured noise as well."""
        if self.fold_x is None or len(self.fold_x) < 2:
            return np.full(len(self.x), np.inf)
        K = len(self.fold_x)
        return np.sqrt((K - 1) / K * np.sum((self.fold_x - self.fold_x.mean(axis=0)) ** 2, axis=0))

    def slice(self, name: str) -> slice:
        i0 = sum(len(self.pnames[n]) for n in self.active[:self.active.index(name)])
        return slice(i0, i0 + len(self.pnames[name]))

    def sd(self) -> np.ndarray:
        return np.sqrt(np.clip(np.diag(self.cov), 0, None)) if self.cov.size else np.zeros(0)


def channel_rms(resid: np.ndarray, valid: np.ndarray, channels: Sequence[str]) -> dict[str, float]:
    out = {}
    for j, c in enumerate(channels):
        v = resid[valid[:, j], j]
        out[c] = float(np.sqrt(np.mean(v * v))) if len(v) else math.nan
    return out


def finite_check(key: Sequence[str], pnames: dict[str, list[str]], x: np.ndarray, rss: float) -> None:
    """Raise InternalError when a fit of the terms ``key`` ended on non-finite parameters or a
    non-finite weighted RSS: a numerical breakdown inside the fit, never bad input (the CLI exits
    70), and never a verdict computed from NaN."""
    bad = [n for n, v in zip([n for k in key for n in pnames.get(k, [])], x, strict=False) if not np.isfinite(v)]
    if bad or not np.all(np.isfinite(x)) or not math.isfinite(rss):
        raise InternalError(f"the fit of {', '.join(key) or 'no term'} broke down: non-finite "
                            + (f"parameter(s) {', '.join(bad)}" if bad else f"weighted RSS {rss!r}"))


def pooled(f: Fit) -> float:
    return math.sqrt(f.heldout_rss / max(int(f.fold_n.sum()), 1))


class Selector:
    """Greedy forward selection over the term library (module docstring)."""

    def __init__(self, P: Problem, opt: Options, parent: Selector | None = None) -> None:
        self.P = P
        self.opt = opt
        self.cache: dict[tuple[str, ...], Fit] = {}
        self.elements: dict[tuple[str, ...], list[str]] = {}
        self.thermal_init: dict[tuple[str, ...], dict[str, tuple[float, float]]] = {}
        # term -> parameter names held at base ('none measurable'), shared with a screening selector
        self.excluded: dict[str, set[str]] = parent.excluded if parent else {}
        self.none: dict[str, list[str]] = parent.none if parent else {}  # term -> groups 'none measurable'
        self.linked: list[Selector] = [self]
        self._screener: Selector | None = None

    def screener(self) -> Selector:
        """The selector that ranks terms each round: on an even random subset of
        ``Options.screen_samples`` of the fit samples (seeded; folds kept) when the fit subset is
        larger, else this one. Choices are always refitted and judged on the whole fit subset."""
        if self._screener is not None:
            return self._screener
        P, opt = self.P, self.opt
        nf = len(P.fit_idx)
        if nf <= opt.screen_samples:
            self._screener = self
            return self
        from dataclasses import replace

        from camsmooth.diagnosis.simulator import Simulator

        idx = np.sort(np.random.default_rng(opt.seed + 1).choice(nf, opt.screen_samples, replace=False))
        fit_idx = P.fit_idx[idx]
        sim = Simulator(P.program, P.machine, P.t[fit_idx], P.segment[fit_idx], P.channels, P.knots)
        Ps = replace(P, fit_idx=fit_idx, folds=P.folds[idx], sim_fit=sim, states=sim.states(),
                     data_fit=P.data_fit[idx], w_fit=P.w_fit[idx], valid_fit=P.valid_fit[idx])
        self._screener = Selector(Ps, opt, parent=self)
        self.linked.append(self._screener)
        self._screener.linked = self.linked
        return self._screener

    # ---- parameter vector <-> model -----------------------------------------------------------
    def _thermal_elements(self, key: tuple[str, ...], name: str) -> list[str]:
        """Thermal elements of term ``name`` for a set: chosen on the residual left by the terms
        before it in the set (the active set when it was added)."""
        key = key[:key.index(name) + 1]
        if key not in self.elements:
            base = self.fit(key[:-1]).physics
            self.elements[key] = term(name).select_elements(self.P, base)
            self.thermal_init[key] = dict(self.P.memo[f"thermal_init:{name}"])
        self.P.memo[f"thermal_init:{name}"] = dict(self.thermal_init[key])
        return self.elements[key]

    def _layout(self, active: Sequence[str]) -> tuple[list[Term], dict[str, list[str]], list[Param]]:
        for name in active:
            if isinstance(term(name), ThermalDrift):
                self.P.memo[f"thermal:{name}"] = self._thermal_elements(tuple(active), name)
        terms = [term(n) for n in active]
        pnames, params = {}, []
        for t in terms:
            ps = [p for p in t.params(self.P) if p.name not in self.excluded.get(t.name, ())]
            pnames[t.name] = [p.name for p in ps]
            params += ps
        return terms, pnames, params

    def _physics(self, terms: Sequence[Term], pnames: dict[str, list[str]], x: np.ndarray) -> ErrorModel:
        ph = self.P.base.copy()
        i = 0
        for t in terms:
            n = len(pnames[t.name])
            t.write(ph, pnames[t.name], x[i:i + n])
            i += n
        return ph

    def resid(self, ph: ErrorModel) -> np.ndarray:
        P = self.P
        return (P.data_fit - P.sim_fit.run(ph)) * P.w_fit

    # ---- fitting ------------------------------------------------------------------------------
    def fit(self, active: Sequence[str], x0: np.ndarray | None = None) -> Fit:
        key = tuple(active)
        if key in self.cache:
            return self.cache[key]
        terms, pnames, params = self._layout(active)
        if not params:
            f = self._empty_fit(key, pnames)
            self.cache[key] = f
            return f
        lo = np.array([p.lo for p in params])
        hi = np.array([p.hi for p in params])
        scale = np.array([p.scale for p in params])
        if x0 is None or len(x0) != len(params):
            x0 = self._start(active, terms, pnames)
        elif not np.all(np.isfinite(x0)):
            # a warm start read from a model that lacks some parameters (a thermal element it
            # does not hold reads tau = NaN): those start from their initial values
            x0 = np.where(np.isfinite(x0), x0, self._start(active, terms, pnames))
        x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))

        def rfun(x: np.ndarray) -> np.ndarray:
            return self.resid(self._physics(terms, pnames, x))

        f = self._fit_core(key, pnames, rfun, x0, lo, hi, scale, lambda x: self._physics(terms, pnames, x),
                           analytic=self._analytic(terms, pnames))
        self.cache[key] = f
        return f

    def _analytic(self, terms: Sequence[Term], pnames: dict[str, list[str]], skip: int = 0
                  ) -> Any:
        """A function x -> per-parameter analytic Jacobian rows (None where a term has none), for
        the terms after the first ``skip`` parameters; None when no term has analytic columns."""
        P = self.P
        probe = [t for t in terms if type(t).jacobian is not Term.jacobian]
        if not probe:
            return None

        def rows(x: np.ndarray) -> list[np.ndarray | None]:
            ph = self._physics(terms, pnames, x)
            out: list[np.ndarray | None] = []
            for t in terms:
                names = pnames[t.name]
                J = t.jacobian(P, ph, names) if names else None
                out += [None] * len(names) if J is None else list(J)
            return [None] * skip + out[skip:]

        return rows

    def fit_set(self, names: Sequence[str]) -> Fit:
        """A fit of this set of terms in any order (a cached one when there is one)."""
        want = set(names)
        for k, f in self.cache.items():
            if set(k) == want and len(k) == len(want):
                return f
        return self.fit(tuple(names))

    def _empty_fit(self, key: tuple[str, ...], pnames: dict[str, list[str]]) -> Fit:
        P = self.P
        folds, valid = P.folds, P.valid_fit
        K = int(folds.max()) + 1
        r = self.resid(P.base)
        rr = np.where(valid, r, 0.0)
        fold_rss = np.array([float(np.sum(rr[folds == k] ** 2)) for k in range(K)])
        fold_n = np.array([int(valid[folds == k].sum()) for k in range(K)])
        n = int(valid.sum())
        rss = float(fold_rss.sum())
        n_eff = fitting.effective_sample_count(rr, n)
        resid_phys = r / P.w_fit
        rms = channel_rms(resid_phys, valid, P.channels)
        return Fit(key, pnames, np.zeros(0), P.base.copy(), np.zeros((0, 0)), rss, n, n_eff,
                   n_eff * math.log(max(rss, 1e-300) / n), rms, rss, dict(rms), fold_rss, fold_n, resid_phys)

    def _fit_core(self, key, pnames, rfun, x0, lo, hi, scale, physics_of, known_jt=None,
                  approximate: bool = False, analytic: Any = None) -> Fit:
        """LM fit, covariance, blocked held-out scores. Held-out: for each fold, the parameters
        fitted without it, as one Gauss-Newton step from the full fit using only the other folds'
        rows of the Jacobian (exact for parameters that enter linearly, the first step of an exact
        refit otherwise); the held-out residual is then simulated at those parameters (for a
        screening fit, ``approximate``, predicted from the Jacobian too)."""
        P = self.P
        folds = P.folds
        K = int(folds.max()) + 1
        valid = P.valid_fit
        jac = None
        if analytic is not None:
            def jac(z: np.ndarray, r: np.ndarray) -> np.ndarray:
                known = analytic(z)
                if known_jt is not None:
                    known[:len(known_jt)] = list(known_jt)
                return fitting.jacobian_t(rfun, z, 1e-4 * scale, r0=r, lo=lo, hi=hi, mask=valid, known=known)
        res = fitting.levenberg_marquardt(rfun, x0, lo=lo, hi=hi, step=1e-4 * scale, scale=scale, mask=valid,
                                          known_jt=known_jt, jac=jac, rtol=1e-7)
        x, H, rss, Jt, r_valid = res.x, res.H, res.cost, res.Jt, res.r
        finite_check(key, pnames, x, rss)
        r = rfun(x)
        rr = np.where(valid, r, 0.0)
        n = int(valid.sum())
        n_eff = fitting.effective_sample_count(rr, n, minimum=len(x) + 2.0)
        cov = fitting.covariance(H, rss, n, n_eff)
        entry_fold = np.broadcast_to(folds[:, None], valid.shape)[valid]
        _, g_all = fitting.gram(Jt, r_valid)
        held = np.zeros_like(r)
        fold_rss = np.zeros(K)
        fold_n = np.zeros(K, dtype=int)
        fold_x = np.zeros((K, len(x)))
        for k in range(K):
            te_e = entry_fold == k
            H_te, g_te = fitting.gram(Jt[:, te_e], r_valid[te_e])
            H_tr, g_tr = H - H_te, g_all - g_te
            free = ~(((x <= lo) & (g_tr > 0)) | ((x >= hi) & (g_tr < 0)))
            dx = np.zeros(len(x))
            if free.any():
                dx[free] = -np.linalg.pinv(H_tr[np.ix_(free, free)]) @ g_tr[free]
            xk = np.clip(x + dx, lo, hi)
            fold_x[k] = xk
            if approximate:
                # a screening fit: the held-out prediction linearised as well (r + J dx)
                rk = r.copy()
                rk[valid] += np.einsum("pm,p->m", Jt, xk - x)
            else:
                rk = rfun(xk)
            sel = folds == k
            test = valid & sel[:, None]
            held[sel] = rk[sel]
            fold_rss[k] = float(np.sum(np.where(test, rk, 0.0) ** 2))
            fold_n[k] = int(test.sum())
        resid_phys = held / P.w_fit
        # influence of each sample on the parameters, H^+ J^T r summed over its channels
        rows = np.nonzero(valid)[0]
        u = significance.per_sample(Jt * r_valid, rows, len(valid)) @ np.linalg.pinv(H)
        lr_sd = np.asarray(significance.batch_sum_sd(u), float).reshape(len(x))
        if not np.all(np.isfinite(fold_rss)):
            raise InternalError(f"the held-out scores of {', '.join(key) or 'no term'} are not finite "
                                f"(fold RSS {fold_rss.tolist()})")
        return Fit(key, pnames, x, physics_of(x), cov, rss, n, n_eff,
                   n_eff * math.log(max(rss, 1e-300) / n) + len(x) * math.log(n_eff),
                   channel_rms(r / P.w_fit, valid, P.channels), float(fold_rss.sum()),
                   channel_rms(resid_phys, valid, P.channels), fold_rss, fold_n, resid_phys, Jt, approximate,
                   fold_x, lr_sd)

    def screen(self, current: Fit, name: str) -> Fit:
        """A cheap joint fit of ``current`` plus term ``name``: the new parameters are simulated
        exactly, the already-fitted ones enter linearly through their Jacobian at the current fit
        (r(x_old + d) = r(x_old) + J_old d). Used to rank terms; the one chosen is then fitted
        exactly."""
        key = current.active + (name,)
        if not current.active or current.Jt is None:
            return self.fit(key)
        P = self.P
        terms, pnames, params = self._layout(key)
        p_old = len(current.x)
        x_old = current.x
        new = terms[-1]
        new_names = pnames[name]
        if not new_names:
            raise ValueError("no parameter the data can show")
        lo = np.array([p.lo for p in params])
        hi = np.array([p.hi for p in params])
        scale = np.array([p.scale for p in params])
        valid = P.valid_fit
        Jt_old = current.Jt
        base = current.physics

        def physics_of(z: np.ndarray) -> ErrorModel:
            ph = self._physics(terms[:-1], pnames, z[:p_old])
            new.write(ph, new_names, z[p_old:])
            return ph

        def rfun(z: np.ndarray) -> np.ndarray:
            ph = base.copy()
            new.write(ph, new_names, z[p_old:])
            R = self.resid(ph)
            d = z[:p_old] - x_old
            if np.any(d != 0.0):
                R = R.copy()
                R[valid] += np.einsum("pm,p->m", Jt_old, d)
            return R

        resid = P.data_fit - P.sim_fit.run(base)
        x0 = np.concatenate([x_old, np.asarray(new.initial(P, base, new_names, resid), float)])
        x0 = np.clip(x0, lo + 1e-12 * (hi - lo), hi - 1e-12 * (hi - lo))
        return self._fit_core(key, pnames, rfun, x0, lo, hi, scale, physics_of, known_jt=Jt_old, approximate=True,
                              analytic=self._analytic(terms, pnames, skip=p_old))

    def x_from(self, key: tuple[str, ...], ph: ErrorModel) -> np.ndarray:
        """The parameter vector of a term set read from a model (a warm start)."""
        terms, pnames, _ = self._layout(key)
        return np.concatenate([np.asarray(t.read(ph, pnames[t.name]), float) for t in terms])

    def _start(self, active, terms, pnames) -> np.ndarray:
        """Starting point: values of the already-fitted subset, initial guesses for the newcomer."""
        P = self.P
        prev = self.cache.get(tuple(active[:-1]))
        ph = prev.physics.copy() if prev is not None else P.base.copy()
        resid = P.data_fit - P.sim_fit.run(ph)
        xs = []
        for t in terms:
            names = pnames[t.name]
            if prev is not None and t.name in prev.active:
                xs.append(t.read(ph, names))
            else:
                xs.append(np.asarray(t.initial(P, ph, names, resid), float))
        return np.concatenate(xs)

    # ---- is it physics? -----------------------------------------------------------------------
    def effect(self, f: Fit, names: Sequence[str], name: str) -> tuple[float, str]:
        """The effect on the recording of parameters ``names`` of term ``name`` in fit f: the
        largest RMS over channels in noise floors (the floor holds the channel's resolution,
        q / sqrt(12), as well as its white noise) and that channel."""
        P = self.P
        t = term(name)
        ph = f.physics.copy()
        t.write(ph, list(names), t.read(P.base, list(names)))
        d = P.sim_fit.run(f.physics) - P.sim_fit.run(ph)
        best, chan = 0.0, ""
        for j, c in enumerate(P.channels):
            ok = P.valid_fit[:, j]
            if ok.any():
                z = float(np.sqrt(np.mean((d[ok, j] * P.w_fit[ok, j]) ** 2)))
                if z > best:
                    best, chan = z, c
        return best, chan

    def measurable(self, f: Fit, name: str) -> tuple[dict[str, str], list[str], str | None]:
        """Resolvability of term ``name`` in fit f (module docstring). Returns (groups that fail
        -> reason, optional parameters that fail, a reason the whole term fails or None)."""
        P, opt = self.P, self.opt
        t = term(name)
        names = f.pnames[name]
        if not names:
            return {}, [], "no parameter the data can show"
        sl = f.slice(name)
        x, sd = f.x[sl], f.sd()[sl]
        base = np.nan_to_num(np.asarray(t.read(P.base, names), float))
        params = {p.name: p for p in t.params(P)}
        sig = np.abs(x - base) > opt.resolvable_sigma * np.maximum(sd, 1e-300)
        if opt.rule == "absolute" and f.fold_x is not None:
            # or resolved against the long-run uncertainty (batch means: the autocorrelation of
            # the parameter's own influence) with one sign in every fold; main parameters only
            lr = f.long_run_sd()[sl]
            same = np.all(np.sign(f.fold_x[:, sl] - base) == np.sign(x - base), axis=0)
            main = np.array([not params[n].optional for n in names])
            sig |= main & same & (np.abs(x - base) > opt.resolvable_sigma * np.maximum(lr, 1e-300))
        if opt.rule == "standalone" and f.fold_x is not None:
            # or resolved by the blocked jackknife with one sign in every fold (the covariance
            # inflated for a strongly autocorrelated rest can hide a clear, consistent effect);
            # main parameters only - a higher-order part still needs the covariance test
            jk = f.jackknife_sd()[sl]
            same = np.all(np.sign(f.fold_x[:, sl] - base) == np.sign(x - base), axis=0)
            main = np.array([not params[n].optional for n in names])
            sig |= main & same & (np.abs(x - base) > opt.resolvable_sigma * np.maximum(jk, 1e-300))
        groups: dict[str, list[int]] = {}
        for i, n in enumerate(names):
            groups.setdefault(params[n].group, []).append(i)
        bad: dict[str, str] = {}
        for g, idx in groups.items():
            mains = [i for i in idx if not params[names[i]].optional] or idx
            z, chan = self.effect(f, [names[i] for i in idx], name)
            if not any(sig[i] for i in mains):
                ref = "its base value" if np.any(base[mains]) else "zero"
                bad[g] = f"within {opt.resolvable_sigma:g} standard uncertainties of {ref}"
            elif z < opt.min_effect_floors:
                bad[g] = (f"its effect is {z:.2g} noise floors RMS on {chan or 'every channel'} (below "
                          f"{opt.min_effect_floors:g}; the floor holds the channel's resolution)")
        optional = [names[i] for i in range(len(names)) if params[names[i]].optional and not sig[i]
                    and params[names[i]].group not in bad]
        whole = None
        if len(bad) == len(groups):
            whole = "not measurable on this recording: " + "; ".join(f"{g}: {why}" for g, why in bad.items())
        else:
            why = t.unresolvable(P, names, x, sd)
            if why:
                whole = why
        return bad, optional, whole

    def _exclude(self, name: str, params: Sequence[str], groups: Sequence[str]) -> None:
        self.excluded.setdefault(name, set()).update(params)
        self.none.setdefault(name, [])
        self.none[name] += [g for g in groups if g not in self.none[name]]
        for sel in self.linked:
            for k in [k for k in sel.cache if name in k]:
                del sel.cache[k]

    def prune(self, key: tuple[str, ...], f: Fit, name: str) -> tuple[Fit | None, str | None]:
        """Apply the resolvability rule to term ``name`` in the exact fit f of ``key``: groups and
        optional parameters that fail are held at base and the set refitted; (fit, None) when the
        term stands, (None, reason) when it is not physics on this recording."""
        for _ in range(4):
            bad, optional, whole = self.measurable(f, name)
            if whole:
                return None, whole
            if not bad and not optional:
                return f, None
            t = term(name)
            drop = [p.name for p in t.params(self.P) if p.group in bad] + optional
            self._exclude(name, drop, [g for g in bad if g])
            f = self.fit(key, x0=None)
        return f, None

    def _forget(self, name: str) -> None:
        """Undo the exclusions of a term that was refused (another set may resolve it)."""
        self.excluded.pop(name, None)
        self.none.pop(name, None)
        for sel in self.linked:
            for k in [k for k in sel.cache if name in k]:
                del sel.cache[k]

    # ---- selection ----------------------------------------------------------------------------
    def run(self) -> dict[str, Any]:
        P, opt = self.P, self.opt
        allowed = opt.candidates or CANDIDATES
        lib = [t for t in LIBRARY if t.name in allowed]
        applicable, not_applicable = [], []
        for t in lib:
            why = t.applicable(P)
            (not_applicable.append({"name": t.name, "reason": f"not applicable: {why}"}) if why
             else applicable.append(t.name))
        active: list[str] = []
        current = self.fit(())
        rejected: dict[str, dict[str, Any]] = {}
        equivalences: list[dict[str, Any]] = []
        t_start = time.perf_counter()
        scr = self.screener()
        seen: set[frozenset[str]] = {frozenset()}
        while len(active) < opt.max_terms:
            trials = {}
            cur_s = scr.fit(tuple(active))
            for name in applicable:
                if name in active:
                    continue
                try:
                    trials[name] = scr._screen_pruned(cur_s, name)
                except InputError as exc:
                    # every input was checked by prepare: a value computed here was refused
                    raise InternalError(f"screening fit of {name}: {exc}") from exc
                except (ValueError, np.linalg.LinAlgError) as exc:
                    rejected[name] = {"name": name, "reason": f"fit failed: {exc}"}
            if not trials:
                break
            verdicts = {n: scr._vetoed(n, f, scr.judge(cur_s, f)) for n, f in trials.items()}
            # a term refused only for making another channel worse gets its exact fit: pruning may
            # hold the axes it cannot measure (a lag on an axis that does not lag, taking up the
            # tip structure of an effect not yet named) and the exact judgement, channels included,
            # then decides
            # and so does one whose fit improves clearly while its held-out score, predicted from the
            # Jacobian of a screening fit, says otherwise (a phase or frequency enters nonlinearly:
            # the prediction, not the term, can fail)
            passing = [n for n, v in verdicts.items() if v["ok"] or v.get("worse_channels")
                       or (trials[n].approximate and v.get("fit_change_pct", 0.0) < -SCREEN_RECHECK_PCT)]
            for n, v in verdicts.items():
                if not v["ok"]:
                    rejected[n] = {"name": n, "reason": v["reason"], "round": len(active) + 1,
                                   "fit_rms_change_pct": v["fit_change_pct"],
                                   "heldout_rms_change_pct": v["heldout_change_pct"], "delta_bic": v["delta_bic"]}
            best = exact = None
            while passing:
                lowest = min(passing, key=lambda n: trials[n].heldout_rss)
                group = [lowest] + [o for o in passing if o != lowest and scr.equivalent(trials[lowest], trials[o])]
                # equal within the noise: name the more common cause (library order) and report the
                # pair as 'cannot tell apart'
                cand = min(group, key=CANDIDATES.index)
                key = tuple(active) + (cand,)
                exact = trials[cand] if scr is self and not trials[cand].approximate else \
                    self.fit(key, x0=trials[cand].x)
                exact, why = self.prune(key, exact, cand)
                worse = verdicts[cand].get("worse_channels")
                if not why and worse and not any(w.split("_")[0] in self.none.get(cand, ()) for w in worse):
                    # refused for an axis's own channel, and that axis (the one it cannot measure)
                    # was not held: the screening's refusal stands
                    why = verdicts[cand]["reason"]
                v = {"ok": False, "reason": why, "heldout_change_pct": None} if why else \
                    self._vetoed(cand, exact, self.judge(current, exact))
                if v["ok"]:
                    best = cand
                    for other in group:
                        if other != best:
                            equivalences.append(self._equivalence(best, other, trials, len(active) + 1))
                    break
                self._forget(cand)
                rejected[cand] = {"name": cand, "reason": v["reason"] + ("" if why else " (refitted jointly)"),
                                  "round": len(active) + 1, "heldout_rms_change_pct": v["heldout_change_pct"]}
                passing.remove(cand)
            if best is None:
                break
            active.append(best)
            rejected.pop(best, None)
            current = exact
            active, current = self._backward(active, current, rejected)
            if frozenset(active) in seen:
                break  # back to a set already held: the search would go round in a cycle
            seen.add(frozenset(active))
        # survives the joint refit: every kept term is checked again in the final joint fit, with the
        # axes or elements held back while other terms were missing given another chance
        for name in active:
            if self.excluded.get(name):
                self._forget(name)
        changed = True
        while changed and active:
            changed = False
            final = self.fit(tuple(active))
            for name in list(active):
                f2, why = self.prune(tuple(active), final, name)
                if why:
                    active.remove(name)
                    rejected[name] = {"name": name, "reason": f"did not survive the joint refit with "
                                      f"{', '.join(active) or 'nothing'}: {why}", "dropped": True}
                    changed = True
                    break
                if f2 is not final:
                    changed = True
                    break
            if not changed and len(active) >= 2:
                # and each would still join last: a term taken in as a stand-in for one that joined
                # after it (or whose pruning changed since) is dropped
                for name in list(active):
                    reduced = tuple(a for a in active if a != name)
                    v = self.judge(self.fit(reduced, x0=self.x_from(reduced, final.physics)), final, channels=False)
                    if not v["ok"]:
                        active.remove(name)
                        rejected[name] = {"name": name, "reason": f"dropped in the final joint fit with "
                                          f"{', '.join(active)}: as the last term it {v['reason']}", "dropped": True,
                                          "heldout_rms_change_pct": v["heldout_change_pct"]}
                        changed = True
                        break
        chain = [self.fit(())]
        steps = []
        for i, name in enumerate(active):
            f = self.fit(tuple(active[:i + 1]))
            steps.append({"added": name, "before": chain[-1], "after": f,
                          "verdict": self.judge(chain[-1], f, channels=False)})
            chain.append(f)
        current = chain[-1]
        for e in equivalences:
            alt = e["alternative"]
            if alt not in active:
                rejected[alt] = {"name": alt, "reason": f"cannot tell apart from {e['chosen']} on this recording "
                                 f"(held-out {e['heldout_rms_alternative']:.4g} vs {e['heldout_rms_chosen']:.4g} "
                                 f"floors); {e['separating_measurement']}", "equivalent_to": e["chosen"]}
        equivalences = [e for e in equivalences if e["chosen"] in active and e["alternative"] not in active]
        for name in applicable:
            if name not in active and name not in rejected:
                rejected[name] = {"name": name, "reason": "not tried (term limit reached)"}
        return {"active": active, "final": current, "baseline": self.fit(()), "steps": steps,
                "rejected": list(rejected.values()) + not_applicable, "equivalences": equivalences,
                "applicable": applicable, "none_measurable": {k: list(v) for k, v in self.none.items() if k in active},
                "selection_time_s": time.perf_counter() - t_start}

    def _equivalence(self, best: str, other: str, trials: dict[str, Fit], rnd: int) -> dict[str, Any]:
        return {"chosen": best, "alternative": other, "round": rnd, "verdict": "cannot tell apart",
                "heldout_rms_chosen": pooled(trials[best]), "heldout_rms_alternative": pooled(trials[other]),
                "chosen_because": "equal within the noise; named first as the more common cause "
                                  "(docs/METHODS.md section 6 order)",
                "separating_measurement": separating_measurement(best, other)}

    def _backward(self, active: list[str], current: Fit, rejected: dict[str, dict[str, Any]]
                  ) -> tuple[list[str], Fit]:
        """A term added earlier as a stand-in may be redundant now; it stays only if it would
        still pass the test for joining last."""
        changed = True
        while changed and len(active) >= 2:
            changed = False
            for old in active[:-1]:
                reduced = tuple(a for a in active if a != old)
                f_red = self.fit(reduced, x0=self.x_from(reduced, current.physics))
                v = self.judge(f_red, current, channels=False)
                if not v["ok"]:
                    active.remove(old)
                    rejected[old] = {"name": old, "reason": f"dropped once {', '.join(active)} had joined: as "
                                     f"the last term it {v['reason']}", "dropped": True,
                                     "heldout_rms_change_pct": v["heldout_change_pct"]}
                    current = f_red
                    changed = True
                    break
        return active, current

    def _screen_pruned(self, current: Fit, name: str) -> Fit:
        """``screen``; for the thermal terms, elements whose time constant runs onto its lower
        bound (steps, not drifts: usually picked up from another effect's residual) are dropped
        and the rest refitted."""
        f = self.screen(current, name)
        t = term(name)
        if not isinstance(t, ThermalDrift):
            return f
        key = current.active + (name,)
        for _ in range(4):
            names = f.pnames[name]
            x = f.x[f.slice(name)]
            lo = {p.name: p.lo for p in t.params(self.P)}
            fast = [n[4:] for n, v in zip(names, x, strict=True) if n.startswith("tau_") and v <= 1.01 * lo[n]]
            keep = [e for e in self.elements[key] if e not in fast]
            if not fast or not keep:
                break
            self.elements[key] = keep
            self.cache.pop(key, None)
            f = self.screen(current, name)
        return f

    def _vetoed(self, name: str, f: Fit, verdict: dict[str, Any]) -> dict[str, Any]:
        """The verdict, turned into a refusal when the term vetoes its own fitted values."""
        if not verdict["ok"]:
            return verdict
        why = term(name).veto(self.P, f.pnames[name], f.x[f.slice(name)])
        return verdict if why is None else {**verdict, "ok": False, "reason": why}

    def judge(self, before: Fit, after: Fit, channels: bool = True) -> dict[str, Any]:
        """Whether ``after`` (one more term) explains clearly more than ``before``: the held-out
        RMS falls, in most folds, and either

        * (share) by ``Options.margin`` of itself, BIC falls by ``bic_margin`` and - with
          ``Options.rule`` 'standalone' - the held-out chi-square fall is beyond the
          noise (``compare``: ``separate_z`` standard errors under the residual's
          autocorrelation), or
        * (an effect on its own, rule 'standalone' only) the new term's effect reaches
          ``standalone_floors`` noise floors RMS on some channel, the held-out mean square falls by
          ``margin_floor2`` floors^2, and the fall is beyond the noise or a parameter of the term
          keeps one sign and size across the folds (``consistent``). None of this depends on how
          much else is left unexplained: a clear reversal on a laser log with a large unexplained
          pitch error is named.

        With ``channels`` (a term joining, rule 'standalone'), it must not make the held-out residual
        clearly worse on any channel (``worse_channels``); not asked when an earlier term is checked
        again beside later ones, where correlated terms trade channels between them.

        Rule 'margin' is the earlier rule (the share alone, without the chi-square test). Rule
        'absolute', the default, is ``_judge_absolute``."""
        opt = self.opt
        fit_change = math.sqrt(after.rss / max(before.rss, 1e-300)) - 1.0
        held_change = math.sqrt(after.heldout_rss / max(before.heldout_rss, 1e-300)) - 1.0
        per_fold_better = int(np.sum(after.fold_rss < before.fold_rss))
        K = len(after.fold_rss)
        # the noise shows best in the residual of the better model: the larger effective count
        n_eff = max(before.n_eff, after.n_eff)
        dp = len(after.x) - len(before.x)
        dbic = n_eff * math.log(max(after.rss, 1e-300) / max(before.rss, 1e-300)) + dp * math.log(max(n_eff, 2.0))
        cmp = self.compare(after, before)
        n_held = max(int(after.fold_n.sum()), 1)
        out = {"fit_change_pct": 100 * fit_change, "heldout_change_pct": 100 * held_change, "delta_bic": dbic,
               "folds_better": per_fold_better, "folds": K, "heldout_chi2_fall": cmp["delta_chi2"],
               "heldout_chi2_se": cmp["se"], "heldout_chi2_se_long_run": cmp["se_lr"], "rule": opt.rule}
        if opt.rule == "absolute":
            return self._judge_absolute(before, after, out, channels)
        margin_why = None
        if held_change > -opt.margin:
            margin_why = (f"lowers the held-out RMS by only {-100 * held_change:.2g}% "
                          f"(a clear margin is {100 * opt.margin:.3g}%)")
        elif dbic > -opt.bic_margin:
            margin_why = f"BIC does not fall clearly (change {dbic:+.3g}, effective n {n_eff:.0f})"
        elif opt.rule == "standalone" and not cmp["resolved"]:
            margin_why = (f"its held-out chi-square fall ({cmp['delta_chi2']:.3g} floors^2) is within "
                          f"{opt.separate_z:g} standard errors ({cmp['se']:.3g}) under the residual's autocorrelation")
        standalone_why = None
        if opt.rule == "standalone" and margin_why is not None:
            z = self.new_effect(before, after)
            out["effect_floors"] = z
            if z < opt.standalone_floors:
                standalone_why = (f"its effect ({z:.2g} noise floors RMS) is below the {opt.standalone_floors:g} "
                                  "floors of an effect named on its own")
            elif cmp["delta_chi2"] < opt.margin_floor2 * n_held:
                standalone_why = (f"it lowers the held-out mean square by only {cmp['delta_chi2'] / n_held:.2g} "
                                  f"floors^2 (at least {opt.margin_floor2:g})")
            elif not cmp["resolved"] and not (cmp["delta_chi2"] > opt.separate_chi2 and
                                              self.consistent(before, after)):
                standalone_why = (f"its held-out chi-square fall ({cmp['delta_chi2']:.3g} floors^2) is within "
                                  f"{opt.separate_z:g} standard errors ({cmp['se']:.3g}) and its parameters do not "
                                  f"keep one sign and size across the {K} folds")
        worse = self.worse_channels(before, after) if opt.rule == "standalone" and channels else []
        if held_change >= 0:
            out.update(ok=False, reason=f"improves the fit RMS by {-100 * fit_change:.2g}% but the held-out RMS "
                       f"rises by {100 * held_change:.2g}%" if fit_change < 0 else
                       "does not lower the fit RMS")
        elif per_fold_better <= K // 2:
            out.update(ok=False, reason=f"lowers the pooled held-out RMS by {-100 * held_change:.2g}% but only in "
                       f"{per_fold_better} of {K} folds")
        elif worse:
            c, dc, se = worse[0]
            out.update(ok=False, reason=f"lowers the held-out RMS by {-100 * held_change:.2g}% but makes it worse on "
                       f"{c} (held-out chi-square up {-dc:.3g} floors^2, {-dc / max(se, 1e-300):.2g} standard errors): "
                       "it does not explain its share consistently across the channels it moves - a stand-in for an "
                       "effect outside the library")
            out["worse_channels"] = [w[0] for w in worse]
        elif margin_why is not None and (opt.rule != "standalone" or standalone_why is not None):
            out.update(ok=False, reason=margin_why + ("" if standalone_why is None else
                                                      f"; nor is it an effect on its own: {standalone_why}"))
        else:
            out.update(ok=True, reason="accepted" if margin_why is None else
                       "accepted as an effect on its own (clear, consistent across the folds, whatever else is "
                       f"left unexplained; {margin_why})")
        return out

    def _judge_absolute(self, before: Fit, after: Fit, out: dict[str, Any], channels: bool) -> dict[str, Any]:
        """Rule 'absolute' (the default; ``judge``): every test is in noise floors or standard
        uncertainties, none a share of what else is left unexplained. The term joins when

        * the pooled held-out chi-square falls, and in most folds;
        * it falls by at least ``separate_chi2`` floors^2 and ``absolute_floor2`` floors^2 a held-out
          sample (an absolute size: about absolute_floor2^0.5 floors RMS of effect), and by more
          than resolvable_sigma / 2 of its long-run standard errors (batch means of the per-sample
          chi-square change, camsmooth.diagnosis.significance; for one added parameter the
          held-out fall is about b^2 / sd^2 with a standard error of about 2 b / sd, so a
          parameter resolved at resolvable_sigma uncertainties brings a fall of about half as
          many standard errors);
        * a main parameter of the term is resolved and consistent (``resolved_consistent``): it
          keeps the sign of its change from the base value in every fit that leaves a fold out,
          and the change exceeds ``resolvable_sigma`` long-run standard uncertainties (a parameter
          on a bound, such as a time constant run onto its limit, does not count);
        * with ``channels``, the held-out residual gets clearly worse on no channel.

        The relative held-out change (against ``Options.margin``) and BIC are reported, not used."""
        opt = self.opt
        K = out["folds"]
        fall, se_lr = out["heldout_chi2_fall"], out["heldout_chi2_se_long_run"]
        n_held = max(int(after.fold_n.sum()), 1)
        held = -out["heldout_change_pct"]
        fit = -out["fit_change_pct"]
        out["heldout_chi2_z"] = fall / se_lr if se_lr > 0 and math.isfinite(se_lr) else 0.0
        out["heldout_fall_per_sample"] = fall / n_held
        out["effect_floors"] = self.new_effect(before, after)
        size = self.resolved_consistent(before, after)
        out["size_sigma"] = size[1] if size else 0.0
        out["size_parameter"] = size[0] if size else None
        worse = self.worse_channels(before, after) if channels else []
        if held <= 0:
            why = (f"improves the fit RMS by {fit:.2g}% but the held-out RMS rises by {-held:.2g}%" if fit > 0 else
                   "does not lower the fit RMS")
        elif out["folds_better"] <= K // 2:
            why = f"lowers the pooled held-out RMS by {held:.2g}% but only in {out['folds_better']} of {K} folds"
        elif worse:
            c, dc, se = worse[0]
            out["worse_channels"] = [w[0] for w in worse]
            why = (f"lowers the held-out RMS by {held:.2g}% but makes it worse on {c} (held-out chi-square up "
                   f"{-dc:.3g} floors^2, {-dc / max(se, 1e-300):.2g} standard errors): it does not explain its share "
                   "consistently across the channels it moves - a stand-in for an effect outside the library")
        elif fall < max(opt.separate_chi2, opt.absolute_floor2 * n_held):
            why = (f"it lowers the held-out chi-square by only {fall:.3g} floors^2 ({fall / n_held:.2g} a sample; at "
                   f"least {opt.separate_chi2:g} and {opt.absolute_floor2:g} a sample)")
        elif not fall > 0.5 * opt.resolvable_sigma * se_lr:
            why = (f"its held-out chi-square fall ({fall:.3g} floors^2) is within {0.5 * opt.resolvable_sigma:g} "
                   f"long-run standard errors ({se_lr:.3g}, batch means over time): less than a term resolved at "
                   f"{opt.resolvable_sigma:g} uncertainties brings")
        elif size is None:
            why = (f"no parameter of it keeps one sign in all {K} fold fits with a size beyond "
                   f"{opt.resolvable_sigma:g} long-run standard uncertainties")
        else:
            why = None
        if why is not None:
            return {**out, "ok": False, "reason": why}
        return {**out, "ok": True,
                "reason": f"accepted: the held-out chi-square falls by {fall:.3g} floors^2 "
                          f"({out['heldout_chi2_z']:.3g} long-run standard errors, in {out['folds_better']} of {K} "
                          f"folds); {size[0]} is {size[1]:.3g} standard uncertainties from its base value with one "
                          f"sign in every fold, whatever else is left unexplained (held-out RMS {-held:+.2g}%)"}

    def resolved_consistent(self, before: Fit, after: Fit) -> tuple[str, float] | None:
        """The main parameter of a term ``after`` adds to ``before`` that is furthest from its base
        value in long-run standard uncertainties (``Fit.long_run_sd``), among those that keep the
        sign of that change in every fit leaving a fold out and exceed ``resolvable_sigma``
        of them: (name, size in uncertainties); None when there is none."""
        if after.fold_x is None:
            return None
        lr = after.long_run_sd()
        best: tuple[str, float] | None = None
        for n, k, dx, dk, p in self._added_parameters(before, after):
            if dx == 0:
                continue
            if p is not None and min(after.x[k] - p.lo, p.hi - after.x[k]) <= 1e-3 * (p.hi - p.lo):
                continue  # on (or at) a bound: no uncertainty to measure it against
            z = abs(dx) / max(float(lr[k]), 1e-300)
            if np.all(np.sign(dk) == np.sign(dx)) and z > self.opt.resolvable_sigma and (best is None or z > best[1]):
                best = (n, z)
        return best

    def _added_parameters(self, before: Fit, after: Fit) -> Iterator[tuple[str, int, float, np.ndarray, Any]]:
        """The main (not optional) parameters of the terms ``after`` adds to ``before``: (name, its
        index in after.x, its change from the base value, that change in every fit leaving a fold
        out (K,), its Param or None)."""
        for name in after.active:
            if name in before.active or not after.pnames[name]:
                continue
            t = term(name)
            sl = after.slice(name)
            names = after.pnames[name]
            base = np.nan_to_num(np.asarray(t.read(self.P.base, names), float))
            params = {p.name: p for p in t.params(self.P)}
            for i, n in enumerate(names):
                if n in params and params[n].optional:
                    continue
                k = sl.start + i
                yield n, k, float(after.x[k] - base[i]), after.fold_x[:, k] - base[i], params.get(n)

    def worse_channels(self, before: Fit, after: Fit) -> list[tuple[str, float, float]]:
        """Channels on which ``after`` predicts the held-out samples clearly worse than ``before``:
        (channel, chi-square fall in floors^2 - negative - and its standard error), for falls
        below -``separate_z`` standard errors (the per-entry spread, inflated by n / n_eff for the
        channel's residual autocorrelation) and -``separate_chi2``. A physical term explains its
        share on every channel it moves; one that buys a fall on one channel with a rise on another
        stands in for something else."""
        P, opt = self.P, self.opt
        if before.heldout_resid is None or after.heldout_resid is None:
            return []
        out = []
        for j, c in enumerate(P.channels):
            v = P.valid_fit[:, j]
            if not v.any():
                continue
            ea = before.heldout_resid[v, j] * P.w_fit[v, j]
            eb = after.heldout_resid[v, j] * P.w_fit[v, j]
            d = ea * ea - eb * eb
            dc = float(d.sum())
            if dc >= -opt.separate_chi2:
                continue
            n = len(d)
            n_eff = fitting.effective_sample_count(eb, n)
            se = math.sqrt(n * float(np.var(d)) * n / max(n_eff, 1.0))
            if dc < -opt.separate_z * se:
                out.append((c, dc, se))
        return sorted(out, key=lambda w: w[1] / max(w[2], 1e-300))

    def new_effect(self, before: Fit, after: Fit) -> float:
        """The effect of the terms ``after`` adds to ``before`` (at their values in ``after``): the
        largest RMS over channels in noise floors (``effect``); an absolute size, whatever else
        is left unexplained."""
        z = 0.0
        for name in after.active:
            if name not in before.active and after.pnames[name]:
                z = max(z, self.effect(after, after.pnames[name], name)[0])
        return z

    def consistent(self, before: Fit, after: Fit) -> bool:
        """Whether a term ``after`` adds to ``before`` has a parameter of one sign and size across
        the folds: every fit that leaves a fold out keeps the sign of its change from the base
        value, and that change exceeds ``resolvable_sigma`` blocked-jackknife uncertainties
        (``Fit.jackknife_sd``: contiguous folds, so autocorrelated residuals are accounted for).
        The significance of the term itself, not of how much else is left unexplained."""
        if after.fold_x is None:
            return False
        jk = after.jackknife_sd()
        return any(np.all(np.sign(dk) == np.sign(dx)) and dx != 0
                   and abs(dx) > self.opt.resolvable_sigma * max(float(jk[k]), 1e-300)
                   for _, k, dx, dk, _ in self._added_parameters(before, after))

    def compare(self, a: Fit, b: Fit) -> dict[str, Any]:
        """Whether the data tell fit a from fit b by their held-out residuals (a Vuong-type test on
        the chi-square difference): delta = chi2(b) - chi2(a) summed over the valid fit entries in
        noise floors^2, its standard error from the per-entry differences (sqrt(n var(d)),
        inflated by n / n_eff for the autocorrelation of the better fit's residual), the number of
        folds where the better fit is better. ``resolved`` when |delta| exceeds
        ``Options.separate_z`` standard errors and ``Options.separate_chi2``, and the better fit
        wins in most folds: the two predictions differ by more than the noise can hide, however
        small that is against the rest of the residual."""
        P, opt = self.P, self.opt
        valid = P.valid_fit
        if a.heldout_resid is None or b.heldout_resid is None:
            return {"delta_chi2": 0.0, "se": math.inf, "se_lr": math.inf, "resolved": False, "better": None,
                    "folds_better": 0}
        ea = np.where(valid, a.heldout_resid * P.w_fit, 0.0)
        eb = np.where(valid, b.heldout_resid * P.w_fit, 0.0)
        d = (eb * eb - ea * ea)[valid]
        n = int(d.size)
        delta = float(d.sum())
        best = ea if delta > 0 else eb
        n_eff = fitting.effective_sample_count(best, n)
        se = math.sqrt(max(n * float(np.var(d)), 0.0) * n / max(n_eff, 1.0)) if n > 1 else math.inf
        K = len(a.fold_rss)
        if delta > 0:
            folds_better = int(np.sum(a.fold_rss < b.fold_rss))
        else:
            folds_better = int(np.sum(b.fold_rss < a.fold_rss))
        resolved = abs(delta) > max(opt.separate_z * se, opt.separate_chi2) and folds_better > K // 2
        # the same sum's standard error from the correlation of the per-sample differences
        # themselves (batch means over time), not from the residual's lag-1 correlation
        se_lr = significance.batch_sum_sd((eb * eb - ea * ea).sum(axis=1)) if n > 1 else math.inf
        return {"delta_chi2": delta, "se": se, "se_lr": float(se_lr), "resolved": bool(resolved),
                "better": (a.active if delta > 0 else b.active), "folds_better": folds_better, "folds": K}

    def equivalent(self, a: Fit, b: Fit) -> bool:
        """Two fits explain the residual equally when the data do not tell them apart
        (``compare``: their held-out chi-square difference is within the noise)."""
        return not self.compare(a, b)["resolved"]
