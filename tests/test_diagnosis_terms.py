"""The term library's interface: analytic Jacobians against finite differences, every term's
parameters within their bounds and written/read back, and the selector's physics rule."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.synthetic import make_special_program, record
from camsmooth.diagnosis.problem import prepare
from camsmooth.diagnosis.terms import LIBRARY, term
from camsmooth.diagnosis.terms.linear import linear_jacobian
from camsmooth.machine.model import ErrorModel


@pytest.fixture(scope="module")
def problem():
    prog = make_special_program("grid", rate=20.0, seed=3, duration=20.0)
    truth = {"EXX": 1e-3, "EYX2": 1e-6, "EC0Y": 5e-5, "Kv_X": 50.0, "backlash_Y": 0.01}
    rec = record(prog, truth, channels=("axes", "tip"), noise={"axes": 1e-3, "tip": 1e-3}, seed=4)
    return prepare(prog, rec)


def test_linear_jacobian_matches_finite_differences(problem):
    P = problem
    model = ErrorModel({"EXX": 1e-3, "EYY2": 2e-6, "EZX3": 1e-9, "EC0Y": 5e-5, "EB0Z": -3e-5, "EA0Z": 2e-5},
                       tau={"X": 0.02}, backlash={"Y": 0.01})
    names = ["EXX", "EYY2", "EZZ3", "EYX2", "EZX3", "EC0Y", "EB0Z", "EA0Z"]
    J = linear_jacobian(P, model, names)

    def resid(m):
        return ((P.data_fit - P.sim_fit.run(m)) * P.w_fit)[P.valid_fit]

    for i, n in enumerate(names):
        h = 1e-9 if n.endswith("3") else (1e-8 if n.endswith("2") else 1e-7)
        mp, mm = model.copy(), model.copy()
        mp.geometric[n] = model.get(n) + h
        mm.geometric[n] = model.get(n) - h
        fd = (resid(mp) - resid(mm)) / (2 * h)
        assert np.allclose(J[i], fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(fd))), n


@pytest.mark.parametrize("t", LIBRARY, ids=lambda t: t.name)
def test_every_term_writes_and_reads_its_parameters(problem, t):
    P = problem
    if t.applicable(P):
        pytest.skip(f"{t.name}: {t.applicable(P)}")
    params = t.params(P)
    assert params and all(p.lo < p.hi and p.scale > 0 and p.group for p in params)
    names = [p.name for p in params]
    x = np.array([p.lo + 0.3 * (p.hi - p.lo) for p in params])
    m = ErrorModel()
    t.write(m, names, x)
    assert np.allclose(t.read(m, names), x)
    par, unc, units = t.report(names, x, np.full(len(x), 1e-3))
    assert set(par) == set(unc) == set(units)
    assert isinstance(t.sentence(par, unc, ["Q"]), str)


def test_term_lookup():
    assert term("linear_squareness").name == "linear_squareness"
    with pytest.raises(KeyError):
        term("magic")


def test_correlations_between_named_terms_come_from_the_joint_covariance():
    from camsmooth.diagnosis.findings import _correlations
    from camsmooth.diagnosis.selector import Fit

    cov = np.array([[4.0, 0.0, 1.9], [0.0, 1.0, 0.1], [1.9, 0.1, 1.0]])  # corr(tau_X, b_X) = 0.95
    z = np.zeros(3)
    f = Fit(("servo_lag", "backlash"), {"servo_lag": ["tau_X", "tau_Y"], "backlash": ["b_X"]}, z, ErrorModel(), cov,
            1.0, 10, 10.0, 0.0, {}, 1.0, {}, z, z)
    out = _correlations(f, "servo_lag", 0.9)
    assert [(c["parameter"], c["other_parameter"], c["strong"]) for c in out] == [("tau_X", "b_X", True)]
    assert out[0]["correlation"] == pytest.approx(0.95)
    assert _correlations(f, "backlash", 0.9)[0]["other_parameter"] == "tau_X"


def test_backlash_jacobian_from_the_screws_matches_finite_differences():
    """Tool tip, tool axis and axis channels on a five-axis program with geometric errors: the
    backlash columns built from the chain's space Jacobian equal central differences."""
    from benchmarks.synthetic import make_program

    prog = make_program("rotary", duration=4.0, rate=50.0, seed=2, spindle=6000.0)
    rec = record(prog, {}, channels=("axes", "tip", "axis"), noise={"axes": 1e-3, "tip": 1e-3, "rotary": 1e-6,
                                                                    "axis": 1e-6}, seed=1)
    P = prepare(prog, rec)
    t = term("backlash")
    names = [p.name for p in t.params(P)]
    model = ErrorModel({"EY0A": 0.02, "EC0B": 1e-4, "EXX": 1e-3, "EYX2": 1e-5, "EC0Y": 1e-4},
                       tau={"X": 0.02, "A": 0.03}, backlash={"X": 0.01, "B": 2e-4},
                       thermal={"dz": {"gain": 0.01, "tau": 2.0}})
    J = t.jacobian(P, model, names)

    def resid(m):
        return ((P.data_fit - P.sim_fit.run(m)) * P.w_fit)[P.valid_fit]

    for i, n in enumerate(names):
        h = 1e-6
        mp, mm = model.copy(), model.copy()
        t.write(mp, [n], [model.backlash.get(n[2:], 0.0) + h])
        t.write(mm, [n], [model.backlash.get(n[2:], 0.0) - h])
        fd = (resid(mp) - resid(mm)) / (2 * h)
        assert np.allclose(J[i], fd, rtol=1e-5, atol=1e-6 * np.max(np.abs(fd))), n
