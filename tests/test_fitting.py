"""camsmooth.machine.fitting, the least squares shared by calibration and diagnosis: against
scipy.optimize.least_squares, bounds and fixed parameters, the effective sample count of an AR(1)
residual, identifiability."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from camsmooth.machine import fitting


def _problem(seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 4, 400)
    y = 2.0 * np.exp(-t / 0.7) + 0.3 * np.sin(3 * t) + rng.normal(0, 0.01, len(t))

    def resid(x):
        return y - (x[0] * np.exp(-t / x[1]) + x[2] * np.sin(3 * t))

    return resid


def test_lm_matches_scipy_least_squares():
    resid = _problem()
    x0 = np.array([1.0, 1.5, 0.0])
    ref = least_squares(resid, x0, method="lm", xtol=1e-14, ftol=1e-14).x
    for central in (False, True):
        res = fitting.levenberg_marquardt(resid, x0, step=1e-7, central=central, rtol=1e-15, xtol=1e-13,
                                          scale=np.ones(3), max_iter=100)
        assert np.allclose(res.x, ref, rtol=1e-6, atol=1e-8)
        assert res.cost == pytest.approx(float(resid(ref) @ resid(ref)), rel=1e-9)


def test_lm_bounds_and_fixed_parameters():
    resid = _problem()
    x0 = np.array([1.0, 1.5, 0.0])
    res = fitting.levenberg_marquardt(resid, x0, lo=np.array([-10, 0.1, -10]), hi=np.array([1.5, 10, 10]),
                                      step=1e-7, scale=np.ones(3), rtol=1e-15)
    assert res.x[0] == pytest.approx(1.5)  # the unconstrained optimum (2.0) is beyond the bound
    ref = least_squares(resid, x0, bounds=([-10, 0.1, -10], [1.5, 10, 10]), xtol=1e-14, ftol=1e-14).x
    assert np.allclose(res.x, ref, atol=1e-6)
    held = fitting.levenberg_marquardt(resid, x0, fixed=np.array([False, True, False]), step=1e-7,
                                       scale=np.ones(3), rtol=1e-15)
    assert held.x[1] == 1.5 and held.Jt.shape == (3, 400)
    ref = least_squares(lambda z: resid(np.array([z[0], 1.5, z[1]])), [1.0, 0.0], method="lm").x
    assert np.allclose(held.x[[0, 2]], ref, atol=1e-6)


def test_effective_sample_count_of_an_ar1_residual():
    rng = np.random.default_rng(1)
    rho, n = 0.8, 200_000
    e = rng.normal(size=n)
    r = np.empty(n)
    r[0] = e[0]
    for i in range(1, n):
        r[i] = rho * r[i - 1] + e[i]
    assert fitting.effective_sample_count(r) == pytest.approx(n * (1 - rho) / (1 + rho), rel=0.05)
    assert fitting.effective_sample_count(rng.normal(size=n)) == pytest.approx(n, rel=0.02)


def test_covariance_matches_the_textbook_formula():
    rng = np.random.default_rng(2)
    J = rng.normal(size=(50, 3))
    r = rng.normal(size=50)
    H = J.T @ J
    cov = fitting.covariance(H, float(r @ r), 50)
    assert np.allclose(cov, np.linalg.inv(H) * float(r @ r) / 47)
    assert np.allclose(fitting.covariance(H, float(r @ r), 50, n_eff=25.0), 2 * cov)
    c = fitting.correlations(np.array([[4.0, 1.0], [1.0, 1.0]]))
    assert c[0, 1] == pytest.approx(0.5)


def test_identifiability_drops_a_combination_and_says_which():
    rng = np.random.default_rng(3)
    J = rng.normal(size=(40, 3))
    J = np.column_stack([J, 2 * J[:, 0] - J[:, 2], np.zeros(40)])
    assert fitting.identifiable_columns(J) == [0, 1, 2]
    kept, dropped = fitting.select_identifiable(J, ["a", "b", "c", "d", "e"], units=["mm"] * 5)
    assert kept == [0, 1, 2]
    assert "+2 mm of a" in dropped[3] and "-1 mm of c" in dropped[3]
    assert "no effect" in dropped[4]
