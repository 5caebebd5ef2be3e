"""Results named by the machine's axes (issue #28, item 2): RotaryValues and PerAxis, the IK result,
the NLP's symbols and a smoothing result on a table machine, each against values written here."""

import numpy as np
import pytest

from camsmooth.machine.axes import AxisNameError, PerAxis, RotaryValues
from camsmooth.machine.kinematics import load_machine
from camsmooth.smoothing import nlp as nlp_mod


def _rx(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([o, z, z], -1), np.stack([z, c, -s], -1), np.stack([z, s, c], -1)], -2)


def _rz(a: np.ndarray) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    o, z = np.ones_like(a), np.zeros_like(a)
    return np.stack([np.stack([c, -s, z], -1), np.stack([s, c, z], -1), np.stack([z, z, o], -1)], -2)


def test_rotary_values_read_by_name_and_position():
    v = np.array([[0.1, 1.0], [0.2, 2.0], [0.3, 3.0]])
    q = RotaryValues(("A", "C"), v)
    assert q.names == ("A", "C") and len(q) == 3 and "C" in q and "B" not in q
    np.testing.assert_array_equal(q["A"], [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(q["C"], [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(q[1], q["C"])
    np.testing.assert_array_equal(q.first, q["A"])
    np.testing.assert_array_equal(q.second, q["C"])
    assert q.index("C") == 1
    a, c = q.pair
    np.testing.assert_array_equal(c, [1.0, 2.0, 3.0])
    assert q["A"].flags["C_CONTIGUOUS"] and q["C"].flags["C_CONTIGUOUS"]  # each column one block
    part = q.take(slice(1, 3))
    assert part.names == ("A", "C")
    np.testing.assert_array_equal(part["C"], [2.0, 3.0])
    np.testing.assert_array_equal(q.take(np.array([True, False, True]))["A"], [0.1, 0.3])
    assert [n for n, _ in q.items()] == ["A", "C"]
    built = RotaryValues.of(("B", "C"), [1.0, 2.0], [3.0, 4.0])
    np.testing.assert_array_equal(built.values, [[1.0, 3.0], [2.0, 4.0]])
    np.testing.assert_array_equal(RotaryValues.zeros(("A", "B"), 4).values, np.zeros((4, 2)))


def test_an_axis_the_values_lack_is_named_with_the_axes_they_have():
    q = RotaryValues(("A", "C"), np.zeros((2, 2)))
    with pytest.raises(AxisNameError) as exc:
        q["B"]
    assert str(exc.value) == "the rotary values carry the axes A, C: no axis 'B'"
    assert not isinstance(exc.value, KeyError)
    with pytest.raises(AxisNameError, match=r"carry 2 axes \(A, C\): no position 2"):
        q[2]
    p = PerAxis(("A", "C"), (1.0, 2.0))
    with pytest.raises(AxisNameError, match="the per-axis values carry the axes A, C: no axis 'B'"):
        p["B"]


@pytest.mark.parametrize("names, values", [(("A",), np.zeros((2, 2))), (("A", "A"), np.zeros((2, 2))),
                                           (("A", "C"), np.zeros((2, 3))), (("A", "C"), np.zeros(4))])
def test_rotary_values_refuse_a_wrong_shape_or_names(names, values):
    with pytest.raises(ValueError, match="RotaryValues needs"):
        RotaryValues(names, values)


def test_per_axis_values():
    p = PerAxis(("A", "C"), (12.5, 300))
    assert p["C"] == 300.0 and p[0] == 12.5 and isinstance(p["C"], float)
    assert list(p.items()) == [("A", 12.5), ("C", 300.0)] and len(p) == 2 and "C" in p
    nan = PerAxis.nan(("B", "C"))
    assert nan.names == ("B", "C") and all(np.isnan(v) for v in nan.values)
    with pytest.raises(ValueError, match="one value per distinct axis"):
        PerAxis(("A", "C"), (1.0,))


def test_the_ik_of_an_ac_table_names_its_columns_a_and_c():
    """T = Rz(C) Rx(A) e_z (the AC table, docs/CONVENTIONS.md) with plain rotation matrices: the IK
    gives back A and C under their own names, and asking for B says the machine has none."""
    m = load_machine("surfaces/dome_machine.toml")
    assert m.rotary == ("A", "C")
    a = np.radians(np.linspace(-30.0, -10.0, 40))
    c = np.radians(np.linspace(10.0, 170.0, 40))
    T = (_rz(c) @ _rx(a) @ np.array([0.0, 0.0, 1.0]))
    r = m.solve_row(T, previous=(float(a[0]), float(c[0])))
    assert r.rotary.names == ("A", "C")
    np.testing.assert_allclose(r.rotary["A"], a, atol=1e-12)
    np.testing.assert_allclose(r.rotary["C"], c, atol=1e-12)
    with pytest.raises(AxisNameError, match="no axis 'B'"):
        r.rotary["B"]


def test_the_nlp_symbols_are_named_by_the_machine_axes():
    ac = load_machine("surfaces/dome_machine.toml")
    ab = load_machine(None)
    assert nlp_mod._axis_functions(ac, 5)[0].name_in() == ["q_A", "q_C"]
    assert nlp_mod._axis_functions(ab, 5)[2].name_in() == ["q_A", "q_B"]
    assert nlp_mod._lead_functions(ac, 5).name_in()[:2] == ["q_A", "q_C"]


def test_a_row_solve_on_an_ac_table_returns_a_and_c():
    """RowNLP on a short gentle row of an A/C table: the solution carries the names of the start,
    and its tool axis T(A, C) = Rz(C) Rx(A) e_z keeps the lead inside the window."""
    m = load_machine("surfaces/dome_machine.toml")
    n = 12
    t = np.linspace(0.0, 1.1, n)
    a = np.radians(np.full(n, -20.0))
    c = np.radians(np.linspace(30.0, 40.0, n))
    T = _rz(c) @ _rx(a) @ np.array([0.0, 0.0, 1.0])
    # local frames: X_L along the row's feed, n = the start's axis turned back by the lead (10 deg)
    frames = np.zeros((n, 3, 3))
    for i in range(n):
        x = np.cross([0.0, 0.0, 1.0], T[i])
        x /= np.linalg.norm(x)
        y = np.cross(T[i], x)
        nrm = np.cos(np.radians(10.0)) * T[i] - np.sin(np.radians(10.0)) * y
        xl = np.cross(y, nrm)
        frames[i] = np.column_stack([xl, y, nrm])
    lead = np.tile(np.radians([2.0, 20.0]), (n, 1))
    tilt = np.tile(np.radians([-15.0, 15.0]), (n, 1))
    q, st = nlp_mod.RowNLP(m, n).solve(t, frames, RotaryValues.of(m.rotary, a, c), lead, tilt)
    assert st.success, st.status
    assert q.names == ("A", "C")
    Tq = _rz(q["C"]) @ _rx(q["A"]) @ np.array([0.0, 0.0, 1.0])
    lead_q = np.arccos(np.clip(np.einsum("ij,ij->i", Tq, frames[:, :, 2]), -1.0, 1.0))
    assert np.all(lead_q >= np.radians(2.0) - 1e-6) and np.all(lead_q <= np.radians(20.0) + 1e-6)
