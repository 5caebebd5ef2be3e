"""Inverse kinematics along long sweeps: the nearest-branch choice must follow the previous point
(issue 12's planted bug held the reference at the row's seed, and A jumped 175 deg on a 0 -> 300
deg sweep). The expected angles are the sweeps themselves (the test's own A(s), B(s)); the tool
axes fed to the solver come from METHODS section 1's closed form T = (sin B, -sin A cos B,
cos A cos B), not from the machine's chain."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, machine_from_dict


def _machine(a_travel: float = 360.0, b_travel: float = 180.0):
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["axis"]["A"].update(min=-a_travel, max=a_travel)
    data["axis"]["B"].update(min=-b_travel, max=b_travel)
    return machine_from_dict(data)


def _axis(A: np.ndarray, B: np.ndarray) -> np.ndarray:
    return np.column_stack([np.sin(B), -np.sin(A) * np.cos(B), np.cos(A) * np.cos(B)])


@pytest.mark.parametrize("a0, a1", [(0.0, 300.0), (0.0, -300.0), (150.0, 210.0), (-170.0, -190.0),
                                    (-350.0, 350.0), (300.0, -40.0)])
def test_a_sweep_is_continuous_and_exact(a0, a1):
    """A swept over hundreds of degrees (through the +-180 deg wrap of atan2, and beyond +-360 deg
    shifts) at B = 17 deg: every point is the sweep's own A, B (no 360 deg or branch jump)."""
    m = _machine()
    A = np.radians(np.linspace(a0, a1, 601))
    B = np.full_like(A, np.radians(17.0))
    r = m.solve_row(_axis(A, B), previous=(A[0], B[0]))
    np.testing.assert_allclose(r.rotary["A"], A, atol=1e-9)
    np.testing.assert_allclose(r.rotary["B"], B, atol=1e-9)
    assert np.max(np.abs(np.diff(r.rotary["A"]))) <= 1.001 * np.radians(abs(a1 - a0) / 600)
    assert r.unreachable.size == 0


def test_zero_to_three_hundred_from_the_default_seed():
    """The issue's case: no ``previous`` (seed (0, 0)), A from 0 to 300 deg."""
    m = _machine()
    A = np.radians(np.linspace(0.0, 300.0, 301))
    B = np.full_like(A, np.radians(5.0))
    r = m.solve_row(_axis(A, B))
    np.testing.assert_allclose(r.rotary["A"], A, atol=1e-9)
    assert np.degrees(np.max(np.abs(np.diff(r.rotary["A"])))) < 1.01


def test_b_sweep_through_ninety_degrees_stays_on_its_branch():
    """B from 0 to 150 deg at A = 20 deg (never exactly 90 deg, where A is undefined): past 90 deg
    the continuous solution is the second branch (B' = 180 - B, A' = A + 180 of asin/atan2),
    which the nearest-branch rule must take."""
    m = _machine()
    B = np.radians(np.linspace(0.0, 150.0, 400))  # step 0.376 deg: no point at 90
    A = np.full_like(B, np.radians(20.0))
    r = m.solve_row(_axis(A, B), previous=(A[0], B[0]))
    np.testing.assert_allclose(r.rotary["B"], B, atol=1e-8)
    np.testing.assert_allclose(r.rotary["A"], A, atol=1e-6)


def test_rows_chained_from_the_previous_end():
    """Two rows of one long sweep solved one after the other, the second seeded with the first's
    end (as the pipeline does): the pair is one continuous 0 -> 340 deg sweep."""
    m = _machine()
    A = np.radians(np.linspace(0.0, 340.0, 341))
    B = np.radians(10.0 + 5.0 * np.sin(np.linspace(0.0, 6.0, 341)))
    T = _axis(A, B)
    r1 = m.solve_row(T[:170], previous=(0.0, B[0]))
    r2 = m.solve_row(T[170:], previous=(r1.rotary["A"][-1], r1.rotary["B"][-1]))
    np.testing.assert_allclose(np.concatenate([r1.rotary["A"], r2.rotary["A"]]), A, atol=1e-9)
    np.testing.assert_allclose(np.concatenate([r1.rotary["B"], r2.rotary["B"]]), B, atol=1e-9)


def test_wrap_with_a_single_reachable_branch():
    """A within [-200, 200] deg, B within [-80, 80]: a sweep 100 -> 200 deg has one reachable
    solution per point (the vectorised path): it is the sweep, across 180 deg."""
    m = _machine(a_travel=200.0, b_travel=80.0)
    A = np.radians(np.linspace(100.0, 199.0, 200))
    B = np.full_like(A, np.radians(-30.0))
    r = m.solve_row(_axis(A, B), previous=(A[0], B[0]))
    np.testing.assert_allclose(r.rotary["A"], A, atol=1e-9)
    np.testing.assert_allclose(r.rotary["B"], B, atol=1e-9)


def test_unreachable_stretch_keeps_the_row_continuous():
    """A sweep 0 -> 120 deg on a machine whose A stops at 100 deg: the points beyond are named
    unreachable, carry the continuing (out-of-travel) solution, and A does not jump."""
    m = _machine(a_travel=100.0, b_travel=100.0)
    A = np.radians(np.linspace(0.0, 120.0, 241))
    B = np.full_like(A, np.radians(12.0))
    r = m.solve_row(_axis(A, B))
    expected = np.flatnonzero(np.degrees(A) > 100.0 + 1e-7)
    np.testing.assert_array_equal(r.unreachable, expected)
    np.testing.assert_allclose(r.rotary["A"], A, atol=1e-9)
    assert np.max(np.abs(np.diff(r.rotary["A"]))) < np.radians(0.6)
