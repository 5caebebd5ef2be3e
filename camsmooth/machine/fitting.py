"""Least squares shared by calibration and diagnosis: Jacobians, a bounded Levenberg-Marquardt
with fixed parameters, the covariance with the effective sample count, and identifiability.

One implementation for both users (issue 11): calibration fits a few hundred residuals with
central-difference Jacobians, the diagnosis up to millions of floor-weighted residuals with
forward differences or analytic columns; both need bounds, parameters held fixed, an honest
covariance and the parameters the data cannot determine.

Conventions: ``fun(x)`` returns a residual array (any shape; ``mask`` picks the entries that
count); the Jacobian is kept transposed, Jt (p, m), so its rows are contiguous per parameter;
dot products use einsum (no threaded BLAS: long BLAS dots stall on a busy machine).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

RANK_TOL = 1e-7


def dot(a: np.ndarray, b: np.ndarray) -> float:
    """Dot product of two 1-d arrays without BLAS."""
    return float(np.einsum("i,i->", a, b))


def gram(Jt: np.ndarray, r: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """J^T J (and J^T r) from the transposed Jacobian Jt (p, m)."""
    p = len(Jt)
    H = np.empty((p, p))
    for i in range(p):
        for j in range(i, p):
            H[i, j] = H[j, i] = dot(Jt[i], Jt[j])
    g = None if r is None else np.array([dot(Jt[i], r) for i in range(p)])
    return H, g


def jacobian_t(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, step: np.ndarray | float, *,
               r0: np.ndarray | None = None, central: bool = False, lo: np.ndarray | None = None,
               hi: np.ndarray | None = None, mask: np.ndarray | None = None, free: np.ndarray | None = None,
               known: Sequence[np.ndarray | None] | None = None) -> np.ndarray:
    """Transposed finite-difference Jacobian (p, m) of the (masked, flattened) residual.

    step: per-parameter step; forward differences from r0 (computed when None) unless
    ``central``; a forward step that would leave [lo, hi] is taken backwards. free: columns to
    compute (others are 0); known: columns given analytically (None where not), used as they are."""
    x = np.asarray(x, float)
    p = len(x)
    step = np.broadcast_to(np.asarray(step, float), (p,))

    def f(z: np.ndarray) -> np.ndarray:
        out = fun(z)
        return (out[mask] if mask is not None else out).ravel()

    if r0 is None and not central:
        r0 = f(x)
    m = len(r0) if r0 is not None else len(f(x))
    Jt = np.zeros((p, m))
    for j in range(p):
        if free is not None and not free[j]:
            continue
        if known is not None and j < len(known) and known[j] is not None:
            Jt[j] = known[j]
            continue
        d = step[j]
        if central:
            e = np.zeros(p)
            e[j] = d
            Jt[j] = (f(x + e) - f(x - e)) / (2 * d)
            continue
        if hi is not None and x[j] + d > hi[j]:
            d = -d
        xj = x.copy()
        xj[j] += d
        Jt[j] = (f(xj) - r0) / d
    return Jt


@dataclass
class LMResult:
    """x: solution; H: J^T J at x (free and fixed parameters); cost: sum r^2 at x; iterations;
    Jt: transposed Jacobian at x (p, m) (None when not asked); r: masked residual at x;
    fixed: the parameters held at their start values."""

    x: np.ndarray
    H: np.ndarray
    cost: float
    iterations: int
    Jt: np.ndarray | None
    r: np.ndarray
    fixed: np.ndarray


def levenberg_marquardt(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, *,
                        lo: np.ndarray | None = None, hi: np.ndarray | None = None,
                        step: np.ndarray | float = 1e-6, mask: np.ndarray | None = None,
                        fixed: np.ndarray | None = None, central: bool = False,
                        jac: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                        known_jt: np.ndarray | None = None, max_iter: int = 40, rtol: float = 1e-8,
                        xtol: float = 1e-5, scale: np.ndarray | None = None, jac_at_end: bool = True
                        ) -> LMResult:
    """Levenberg-Marquardt with box bounds for a few parameters and many residuals.

    Normal equations with Marquardt's diagonal scaling; parameters at a bound whose gradient
    pushes outward are held for the step; ``fixed`` parameters are never moved (their Jacobian
    columns are still returned, for covariances and screening). Jacobian: ``jac(x, r)`` giving
    Jt, else finite differences (``jacobian_t``; step per parameter, forward or central);
    known_jt: transposed columns for the first len(known_jt) parameters, reused as they are (a
    linearised part). Stops when a step lowers the cost by less than ``rtol`` relatively or
    moves no parameter by more than xtol * max(|x|, scale). Each iteration costs p + 1
    evaluations and O(m p^2).
    """
    x = np.asarray(x0, float).copy()
    p = len(x)
    lo = np.full(p, -np.inf) if lo is None else np.asarray(lo, float)
    hi = np.full(p, np.inf) if hi is None else np.asarray(hi, float)
    x = np.clip(x, lo, hi)
    fixed = np.zeros(p, bool) if fixed is None else np.asarray(fixed, bool)
    stepv = np.broadcast_to(np.asarray(step, float), (p,))
    scale = stepv * 1e4 if scale is None else np.asarray(scale, float)

    def f(z: np.ndarray) -> np.ndarray:
        out = fun(z)
        return (out[mask] if mask is not None else out).ravel()

    known = None if known_jt is None else list(known_jt)

    def J(z: np.ndarray, r: np.ndarray) -> np.ndarray:
        if jac is not None:
            return jac(z, r)
        return jacobian_t(fun, z, stepv, r0=None if central else r, central=central, lo=lo, hi=hi, mask=mask,
                          known=known)

    r = f(x)
    cost = dot(r, r)
    lam = 1e-3
    it = 0
    H = None
    Jt = None
    for it in range(1, max_iter + 1):  # noqa: B007 - reported
        Jt = J(x, r)
        H, g = gram(Jt, r)
        free = ~fixed & ~(((x <= lo) & (g > 0)) | ((x >= hi) & (g < 0)))
        if not free.any():
            break
        Hf = H[np.ix_(free, free)]
        dg = np.maximum(np.diag(Hf), 1e-30 * max(1.0, float(np.max(np.diag(Hf)))))
        accepted = small = False
        drop = 0.0
        for _ in range(12):
            try:
                dx_free = -np.linalg.solve(Hf + lam * np.diag(dg), g[free])
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            dx = np.zeros(p)
            dx[free] = dx_free
            xn = np.clip(x + dx, lo, hi)
            rn = f(xn)
            cn = dot(rn, rn)
            if cn < cost or not np.isfinite(cost):
                small = bool(np.all(np.abs(xn - x) <= xtol * np.maximum(np.abs(x), scale)))
                drop = (cost - cn) / max(cost, 1e-300)
                x, r, cost = xn, rn, cn
                lam = max(lam / 10.0, 1e-12)
                accepted = True
                break
            lam *= 10.0
        Jt = None
        if not accepted or small or drop < rtol:
            break
    if Jt is None and (jac_at_end or H is None):
        Jt = J(x, r)
        H, _ = gram(Jt)
    return LMResult(x, H, cost, it, Jt, r, fixed)


def lag1_autocorrelation(r: np.ndarray) -> float:
    """Lag-1 autocorrelation of a residual (n,) or (n, C) pooled over columns, clipped to 0..0.999."""
    rr = np.asarray(r, float)
    if rr.ndim == 1:
        rr = rr[:, None]
    x = rr - rr.mean(axis=0)
    den = float(np.sum(x * x))
    if den <= 0 or len(x) < 2:
        return 0.0
    return float(np.clip(np.sum(x[1:] * x[:-1]) / den, 0.0, 0.999))


def effective_sample_count(r: np.ndarray, n: int | None = None, minimum: float = 2.0) -> float:
    """Effective number of independent residuals, n (1 - rho) / (1 + rho), rho the lag-1
    autocorrelation (an AR(1) model of the residual; the usual variance-inflation factor)."""
    rho = lag1_autocorrelation(r)
    n = int(np.size(r)) if n is None else n
    return max(minimum, n * (1 - rho) / (1 + rho))


def covariance(H: np.ndarray, rss: float, n: int, n_eff: float | None = None) -> np.ndarray:
    """Parameter covariance s^2 (J^T J)^+ with s^2 = rss / (n - p), inflated by n / n_eff for a
    correlated residual (pseudo-inverse: an unidentifiable direction gets no finite variance
    claim beyond round-off)."""
    p = len(H)
    cov = np.linalg.pinv(H) * rss / max(n - p, 1)
    if n_eff is not None:
        cov = cov * (n / max(n_eff, 1.0))
    return cov


def correlations(cov: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance (0 where a variance is 0)."""
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        c = cov / np.outer(sd, sd)
    return np.nan_to_num(c)


def identifiable_columns(J: np.ndarray, rel_norm: float = 1e-6, tol: float = 1e-3) -> list[int]:
    """Columns of J (m, p) whose effect is not negligible (norm above rel_norm of the largest) and
    not a linear combination of the others (pivoted QR of the column-normalised matrix, |R_ii|
    above tol of the first), in their original order."""
    from scipy.linalg import qr

    if J.size == 0:
        return []
    norms = np.linalg.norm(J, axis=0)
    ok = norms > max(1e-300, rel_norm * float(norms.max()))
    if not ok.any():
        return []
    idx = np.flatnonzero(ok)
    _, Rm, piv = qr(J[:, idx] / norms[idx], mode="economic", pivoting=True)
    d = np.abs(np.diag(Rm))
    return sorted(idx[piv[d > tol * d[0]]].tolist())


def select_identifiable(J: np.ndarray, names: Sequence[str], groups: Sequence[Sequence[int]] | None = None,
                        keep: Sequence[int] = (), tol: float = RANK_TOL, units: Sequence[str] | None = None
                        ) -> tuple[list[int], dict[int, str]]:
    """Greedy rank analysis in a stated priority. J: (m, n) Jacobian; groups: column index groups
    in priority order (a group, e.g. a runout's two Cartesian components, is kept or dropped
    together); keep: columns always kept (nuisance parameters); units: the unit of each column's
    parameter (for the messages). A group is kept when adding it keeps the column-normalised
    matrix at full rank (smallest/largest singular value > tol). Returns the kept columns and,
    for each dropped column, the combination of kept columns that has the same effect."""
    norms = np.linalg.norm(J, axis=0)
    Jn = J / np.where(norms > 0, norms, 1.0)
    units = list(units) if units is not None else [""] * len(names)
    kept = list(keep)
    dropped: dict[int, str] = {}
    groups = [[i] for i in range(J.shape[1]) if i not in keep] if groups is None else groups
    for grp in groups:
        if all(norms[i] == 0 for i in grp):
            for i in grp:
                dropped[i] = "no effect on the measurement (at the base values of the others)"
            continue
        trial = kept + list(grp)
        s = np.linalg.svd(Jn[:, trial], compute_uv=False)
        if s[-1] > tol * s[0]:
            kept = trial
            continue
        for i in grp:
            if norms[i] == 0:
                dropped[i] = "no effect on the measurement (at the base values of the others)"
                continue
            coef, *_ = np.linalg.lstsq(J[:, kept], J[:, i], rcond=None)
            big = np.max(np.abs(coef)) if len(coef) else 0.0
            terms = [f"{c:+.4g} {units[k]} of {names[k]}".replace("  ", " ")
                     for c, k in zip(coef, kept, strict=True) if abs(c) > 1e-3 * big]
            dropped[i] = (f"1 {units[i]} of it has the same effect as " + ", ".join(terms)) if terms else \
                "not separable from the others"
    return kept, dropped


def singular_values(J: np.ndarray) -> tuple[np.ndarray, float]:
    """Singular values of J and its condition number (inf when singular)."""
    s = np.linalg.svd(J, compute_uv=False)
    return s, float(s[0] / s[-1]) if s[-1] > 0 else math.inf
