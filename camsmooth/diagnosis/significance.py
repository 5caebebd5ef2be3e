"""Standard errors of sums over a time-ordered, autocorrelated series (METHODS.md section 6).

The selection asks two questions of a term that do not depend on what else is left unexplained:
is its fitted size beyond its uncertainty, and does it lower the held-out chi-square by more than
the noise could? Both are sums over the samples (of the parameter's influence, of the per-sample
chi-square change) whose terms are correlated in time. Their standard error comes from batch
means: the series is cut into M contiguous batches, the batch sums are treated as independent,
and Var(sum) = M / (M - 1) sum_m (B_m - mean)^2 (with B_m the sum over batch m and the mean
scaled to the batch's length). The batches are the longest that still give ``BATCHES`` = 10 of
them (a tenth of the recording each): a batch much longer than the series' correlation time makes
the batch sums nearly independent, and a long batch also spans whole cycles of a program that
repeats (a positioning run's up-and-down cycle), over which an oscillating product cancels.
Shorter batches were tried and refused: cut inside one cycle, the part-cycle sums of a periodic
series look like independent noise and the error is overstated many times (a laser run's
reversal, resolved at 4 uncertainties with a tenth of the run a batch, fell to 2 with a
eightieth). With 9 degrees of freedom the estimate is itself uncertain (about +-25%), which the
rules cover by asking for ``resolvable_sigma`` (3) uncertainties, one sign in every fold and a
held-out fall as well.

Unlike an effective sample count from the residual's lag-1 correlation, this measures the
correlation of the quantity summed: a reversal's influence changes sign at every reversal, so a
smooth unexplained rest beside it adds little to its uncertainty, while a term that follows
coloured noise shows the noise's full long-run variance.
"""

from __future__ import annotations

import math

import numpy as np

BATCHES = 10
MIN_BATCH = 4


def batch_sum_sd(y: np.ndarray, batches: int = BATCHES) -> np.ndarray | float:
    """Standard error of the sum over axis 0 of ``y`` ((n,) or (n, p), time-ordered) by batch means
    over ``batches`` contiguous batches (module docstring); inf when a batch would hold fewer than
    ``MIN_BATCH`` samples."""
    y = np.asarray(y, float)
    one = y.ndim == 1
    Y = y[:, None] if one else y
    n = len(Y)
    if batches < 2 or n < batches * MIN_BATCH:
        sd = np.full(Y.shape[1], math.inf)
    else:
        edges = np.linspace(0, n, batches + 1).astype(int)
        sums = np.add.reduceat(Y, edges[:-1], axis=0)
        dev = sums - np.diff(edges)[:, None] * Y.mean(axis=0)
        sd = np.sqrt(batches / (batches - 1) * np.sum(dev * dev, axis=0))
    return float(sd[0]) if one else sd


def per_sample(values: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """Sum entries ``values`` ((m,) or (p, m)) that belong to sample ``rows`` (m,) into an (n,) or
    (n, p) time-ordered series (several channels of one sample add up)."""
    v = np.asarray(values, float)
    if v.ndim == 1:
        return np.bincount(rows, weights=v, minlength=n)
    return np.stack([np.bincount(rows, weights=vi, minlength=n) for vi in v], axis=1)
