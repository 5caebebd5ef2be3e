"""What the mutation run of camsmooth/diagnosis/significance.py (benchmarks/mutation.py, target
"significance") found untested: the per-sample sums the selection builds its series with, and the
edges of batch_sum_sd (too few samples for the batches, a single batch). Expected values are
written out by hand or computed with plain loops here."""

from __future__ import annotations

import math

import numpy as np
import pytest

from camsmooth.diagnosis.significance import BATCHES, MIN_BATCH, batch_sum_sd, per_sample


def test_per_sample_adds_the_channels_of_one_sample():
    """Entries 0..4 belong to samples 2, 0, 2, 3, 0 of a 5-sample series: sample 0 holds 2 + 5,
    sample 2 holds 1 + 3, sample 3 holds 4, samples 1 and 4 nothing."""
    rows = np.array([2, 0, 2, 3, 0])
    out = per_sample(np.array([1.0, 2.0, 3.0, 4.0, 5.0]), rows, 5)
    assert out.shape == (5,)
    assert out.tolist() == [7.0, 0.0, 4.0, 4.0, 0.0]


def test_per_sample_of_several_parameters_is_one_column_each():
    """(p, m) values give an (n, p) series: column j is parameter j's per-sample sum (a plain loop)."""
    rng = np.random.default_rng(3)
    rows = rng.integers(0, 6, size=20)
    values = rng.normal(size=(3, 20))
    out = per_sample(values, rows, 7)
    ref = np.zeros((7, 3))
    for j in range(3):
        for k in range(20):
            ref[rows[k], j] += values[j, k]
    assert out.shape == (7, 3)
    np.testing.assert_allclose(out, ref, rtol=0, atol=1e-12)


def test_too_few_samples_for_the_batches_give_an_infinite_error():
    """A batch must hold MIN_BATCH (4) samples: 39 samples cannot make 10 batches (inf), 40 can
    (finite); one batch has no spread to measure (inf); 2-D input gives one inf per column."""
    assert (BATCHES, MIN_BATCH) == (10, 4)
    y = np.sin(np.arange(40.0))
    assert batch_sum_sd(y[:39]) == math.inf
    assert math.isfinite(batch_sum_sd(y))
    assert batch_sum_sd(y, 1) == math.inf
    assert batch_sum_sd(y[:7], 2) == math.inf and math.isfinite(batch_sum_sd(y[:8], 2))
    both = batch_sum_sd(np.column_stack([y[:39], y[:39]]))
    assert isinstance(both, np.ndarray) and both.shape == (2,) and np.all(np.isinf(both))


def test_two_batches_worked_by_hand():
    """y = 1..8 in two batches of 4: sums 10 and 26, mean 4.5 so each batch 'should' hold 18;
    deviations -8 and +8: Var = 2 / 1 * (64 + 64) = 256, sd 16."""
    y = np.arange(1.0, 9.0)
    assert batch_sum_sd(y, 2) == pytest.approx(16.0, rel=1e-12)
    assert isinstance(batch_sum_sd(y, 2), float)
