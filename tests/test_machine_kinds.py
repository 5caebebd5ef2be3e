"""Machine kinds (issue 18): every kind's chain against the pinned closed forms, the one inverse
(Paden-Kahan subproblem 2) against the forward map and against brute force, both branches,
continuous C beyond a turn, and a path through the pole of the C axis on a machine and surface
the pole code was not tuned on (a B/C table under the saddle sample)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from camsmooth.machine.kinematics import MACHINE_KINDS, machine_from_dict

KINDS = tuple(MACHINE_KINDS)
CENTRE = (12.0, -7.0, -35.0)
PIVOT = 150.0


def _rx(a: float) -> np.ndarray:
    return np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])


def _ry(b: float) -> np.ndarray:
    return np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])


def _rz(c: float) -> np.ndarray:
    return np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])


def machine(kind: str, c_limits: tuple[float, float] | None = None, tilt: tuple[float, float] = (-360.0, 360.0)):
    data = {"machine": {"kind": kind}, "axis": {}}
    if kind in ("AB-head", "BC-head-table"):
        data["machine"]["pivot"] = PIVOT
    if kind != "AB-head":
        data["machine"]["table_centre"] = list(CENTRE)
    for ax in MACHINE_KINDS[kind]:
        t = {"vmax": 60.0, "amax": 300.0}
        if ax != "C":
            t.update(min=tilt[0], max=tilt[1])
        elif c_limits is not None:
            t.update(min=c_limits[0], max=c_limits[1])
        data["axis"][ax] = t
    return machine_from_dict(data)


def closed_form(kind: str, q1: float, q2: float, cl: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pinned interface of issue 18, written with plain rotation matrices: the tool axis T and
    the linear axes X, Y, Z that put the tip at cl."""
    c = np.asarray(CENTRE)
    ez = np.array([0.0, 0.0, 1.0])
    if kind == "AB-head":
        T = _rx(q1) @ _ry(q2) @ ez
        return T, cl + PIVOT * T
    if kind == "AC-table":
        A, C = q1, q2
        return _rz(C) @ _rx(A) @ ez, c + _rx(-A) @ _rz(-C) @ (cl - c)
    B, C = q1, q2
    T = _rz(C) @ _ry(B) @ ez
    if kind == "BC-table":
        return T, c + _ry(-B) @ _rz(-C) @ (cl - c)
    return T, c + _rz(-C) @ (cl - c) + PIVOT * _ry(B) @ ez


@pytest.mark.parametrize("kind", KINDS)
def test_chain_matches_the_pinned_closed_forms(kind):
    m = machine(kind)
    rng = np.random.default_rng(7)
    q = rng.uniform(-np.pi, np.pi, (40, 2))
    cl = rng.uniform(-80, 80, (40, 3))
    T = m.tool_axis_np(q[:, 0], q[:, 1])
    xyz = m.linear_axes(cl, q[:, 0], q[:, 1])
    for k in range(40):
        T_ref, xyz_ref = closed_form(kind, q[k, 0], q[k, 1], cl[k])
        np.testing.assert_allclose(T[k], T_ref, atol=1e-13)
        np.testing.assert_allclose(xyz[k], xyz_ref, atol=1e-10)
    tip, axis = m.tool_pose_np(q[:, 0], q[:, 1], *xyz.T)  # and the forward chain puts the tip back
    np.testing.assert_allclose(tip, cl, atol=1e-10)


def _brute_force(m, T: np.ndarray) -> np.ndarray:
    """Every (q1, q2) in (-pi, pi]^2 with tool_axis = T: minima of the misfit on a 2-degree grid,
    refined by least squares (scipy), duplicates removed. Independent of the subproblem-2 code."""
    g = np.radians(np.arange(-180.0, 180.0, 2.0))
    Q1, Q2 = np.meshgrid(g, g, indexing="ij")
    err = np.linalg.norm(m.tool_axis_np(Q1.ravel(), Q2.ravel()) - T, axis=1).reshape(Q1.shape)
    found: list[np.ndarray] = []
    for i, j in zip(*np.nonzero(err < 0.08), strict=True):
        sol = least_squares(lambda x: m.tool_axis_np(x[:1], x[1:])[0] - T, [g[i], g[j]], xtol=1e-15, ftol=1e-15)
        if np.linalg.norm(m.tool_axis_np(sol.x[:1], sol.x[1:])[0] - T) < 1e-10:
            x = (sol.x + np.pi) % (2 * np.pi) - np.pi
            if not any(np.allclose(_wrapdiff(x, f), 0.0, atol=1e-6) for f in found):
                found.append(x)
    return np.array(found)


def _wrapdiff(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (np.asarray(a) - np.asarray(b) + np.pi) % (2 * np.pi) - np.pi


@pytest.mark.parametrize("kind", KINDS)
def test_inverse_gives_both_branches_and_brute_force_finds_no_other(kind):
    m = machine(kind)
    rng = np.random.default_rng(11)
    T = rng.normal(size=(6, 3))
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    sols = m.inverse_axis(T)
    for b in (0, 1):
        np.testing.assert_allclose(m.tool_axis_np(sols[:, b, 0], sols[:, b, 1]), T, atol=1e-12)
        np.testing.assert_array_equal(m.branch_of(sols[:, b, 0], sols[:, b, 1]), b)
    for k in range(len(T)):
        brute = _brute_force(m, T[k])
        assert len(brute) == 2, (kind, brute)
        for s in sols[k]:
            assert min(np.abs(_wrapdiff(s, x)).max() for x in brute) < 1e-6


def test_first_branch_words_match_branch_of():
    """branch_words() names the branch 0 of every kind in words; check the words on samples."""
    for kind in KINDS:
        m = machine(kind)
        tilt = np.radians(np.linspace(-179.0, 179.0, 37))
        other = np.full_like(tilt, 0.3)
        q1, q2 = (tilt, other) if m.outer_index == 1 else (other, tilt)
        branch = m.branch_of(q1, q2)
        if kind == "AB-head":
            expect = np.abs(tilt) <= np.pi / 2
        else:  # "A in [-180, 0] deg" / "B in [-180, 0] deg"
            expect = tilt <= 0
        first, second = m.branch_words()
        assert first == ("B in [-90, 90] deg" if kind == "AB-head" else f"{m.rotary[0]} in [-180, 0] deg")
        assert second == ("B beyond +-90 deg" if kind == "AB-head" else f"{m.rotary[0]} in (0, 180) deg")
        np.testing.assert_array_equal(branch == 0, expect)


def test_continuous_c_follows_more_than_a_turn_and_limited_c_does_not():
    """A tool axis circling the C axis at 25 deg three times: a continuous C unwinds to 1080 deg
    at the programmed direction; with C limited to +-360 deg the row runs out of travel and C
    jumps (here to the other branch, A changing sign)."""
    m = machine("AC-table", tilt=(-110.0, 30.0))
    phi = np.radians(np.linspace(0.0, 1080.0, 721))
    tilt = np.radians(25.0)
    T = np.column_stack([np.sin(tilt) * np.sin(phi), -np.sin(tilt) * np.cos(phi), np.full_like(phi, np.cos(tilt))])
    r = m.solve_row(T)
    np.testing.assert_allclose(m.tool_axis_np(*r.rotary.pair), T, atol=1e-12)
    assert r.unreachable.size == 0
    assert np.all(np.abs(np.diff(r.rotary["C"])) < np.radians(2.0))  # continuous
    assert np.degrees(np.ptp(r.rotary["C"])) == pytest.approx(1080.0, abs=1e-6)
    limited = machine("AC-table", c_limits=(-360.0, 360.0), tilt=(-110.0, 30.0))
    rl = limited.solve_row(T)
    assert np.all(np.abs(rl.rotary["C"]) <= 2 * np.pi + 1e-9)
    assert np.abs(np.diff(rl.rotary["C"])).max() > np.radians(150.0)  # it has to turn back or change branch somewhere


def test_pole_holds_c_and_the_tilt_changes_sign_through_it():
    """A path straight through the pole: C stands still, the tilt axis passes zero (the branch
    changes there), and no angle jumps."""
    m = machine("BC-table")
    b = np.radians(np.linspace(-20.0, 20.0, 81))  # passes b = 0 exactly at the middle point
    T = m.tool_axis_np(b, np.full_like(b, np.radians(40.0)))
    r = m.solve_row(T, previous=(b[0], np.radians(40.0)))
    np.testing.assert_allclose(r.rotary["B"], b, atol=1e-12)
    np.testing.assert_allclose(r.rotary["C"], np.radians(40.0), atol=1e-12)


def test_machine_file_errors_for_the_new_keys():
    from camsmooth.errors import InputError

    with pytest.raises(InputError, match="give both or neither"):
        machine_from_dict({"machine": {"kind": "AC-table"}, "axis": {
            "A": {"min": -100.0, "max": 30.0, "vmax": 60.0, "amax": 300.0},
            "C": {"min": -100.0, "vmax": 60.0, "amax": 300.0}}})
    with pytest.raises(InputError, match="table_centre must be three finite numbers"):
        machine_from_dict({"machine": {"kind": "BC-table", "table_centre": [0.0, 1.0]}, "axis": {
            "B": {"min": -100.0, "max": 30.0, "vmax": 60.0, "amax": 300.0}, "C": {"vmax": 60.0, "amax": 300.0}}})
    with pytest.raises(InputError, match=r"missing \[axis.C\]"):
        machine_from_dict({"machine": {"kind": "BC-table"}, "axis": {
            "B": {"min": -100.0, "max": 30.0, "vmax": 60.0, "amax": 300.0}}})
    with pytest.raises(InputError, match="unknown axis table"):
        machine_from_dict({"machine": {"kind": "AC-table"}, "axis": {
            "A": {"min": -100.0, "max": 30.0, "vmax": 60.0, "amax": 300.0}, "C": {"vmax": 60.0, "amax": 300.0},
            "B": {"min": -1.0, "max": 1.0, "vmax": 1.0, "amax": 1.0}}})


def _saddle_rows(tmp_path, rows):
    from pathlib import Path

    samples = Path(__file__).resolve().parents[1] / "surfaces"
    lines = (samples / "saddle_path.csv").read_text().splitlines()
    col = lines[0].split(",").index("row")
    keep = [ln for ln in lines[1:] if int(float(ln.split(",")[col])) in rows]
    path = tmp_path / "rows.csv"
    path.write_text("\n".join([lines[0], *keep]) + "\n")
    return path, samples / "saddle.ply"


BC_TABLE = {"machine": {"kind": "BC-table", "table_centre": [5.0, -3.0, -50.0]}, "axis": {
    "B": {"min": -30.0, "max": 110.0, "vmax": 50.0, "amax": 250.0}, "C": {"vmax": 120.0, "amax": 600.0}}}


def test_a_pole_passage_the_windows_cannot_contain_is_named_with_its_size(tmp_path):
    """Narrow windows (lead 9:13, tilt -2:2 deg) keep the tool axis 1.4 deg from the pole: no
    program meets C's limits; the error names C's binding limit with the need, and the passage."""
    from camsmooth.errors import InfeasibleError
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import SmoothOptions, smooth

    path, mesh = _saddle_rows(tmp_path, (13,))
    with pytest.raises(InfeasibleError) as exc:
        smooth(read_cc_csv(path), load_surface(mesh), machine_from_dict(BC_TABLE), ToroidalCutter(R=4.0, r=1.0),
               feed=2000.0, lead_range=tuple(np.radians([9.0, 13.0])), tilt_range=tuple(np.radians([-2.0, 2.0])),
               method="nlp", options=SmoothOptions(workers=1), progress=False)
    msg = str(exc.value)
    assert "row id 13" in msg and "binding constraint: C " in msg and "pole passage" in msg, msg
    need = float(msg.split("need at least ")[1].split()[0])
    limit = float(msg.split(" limit ")[1].split()[0])
    assert need > 10 * limit


def test_nlp_passes_the_pole_within_every_limit_on_an_untuned_case(tmp_path):
    """Two middle rows of the saddle sample on a B/C trunnion (not the dome sample the pole code was
    built on): the exact inverse turns C more than ten times faster than its limit at the
    programmed feed; the NLP program meets C's and B's velocity, acceleration and travel limits and
    the lead/tilt windows at every sample, recomputed here from the output arrays by plain finite
    differences, and the passages are named."""
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import SmoothOptions, smooth

    path, mesh = _saddle_rows(tmp_path, (14, 15))
    m = machine_from_dict(BC_TABLE)
    res = smooth(read_cc_csv(path), load_surface(mesh), m, ToroidalCutter(R=4.0, r=1.0),
                 feed=2000.0, lead_range=tuple(np.radians([2.0, 20.0])), tilt_range=tuple(np.radians([-15.0, 15.0])),
                 method="nlp", options=SmoothOptions(workers=1), progress=False)
    none, nlp = res.methods["none"], res.methods["nlp"]

    def rates(r, q):
        same = r.rows[1:] == r.rows[:-1]
        h = np.diff(r.t)
        v = np.diff(q)[same] / h[same]
        mid = same[:-1] & same[1:]
        hl, hr = h[:-1][mid], h[1:][mid]
        a = 2 * ((q[2:] - q[1:-1])[mid] / hr - (q[1:-1] - q[:-2])[mid] / hl) / (hl + hr)
        return np.abs(v), np.abs(a)

    limC, limB = m.limits["C"], m.limits["B"]
    assert rates(none, none.rotary["C"])[0].max() > 10 * limC.vmax
    for q, lim in ((nlp.rotary["B"], limB), (nlp.rotary["C"], limC)):
        v, a = rates(nlp, q)
        assert v.max() <= lim.vmax * (1 + 1e-6) and a.max() <= lim.amax * (1 + 1e-6)
        assert np.all((q >= lim.min - 1e-9) & (q <= lim.max + 1e-9))
    tol = 1e-6
    assert np.all((nlp.lead >= nlp.lead_window[:, 0] - tol) & (nlp.lead <= nlp.lead_window[:, 1] + tol))
    assert np.all((nlp.tilt >= nlp.tilt_window[:, 0] - tol) & (nlp.tilt <= nlp.tilt_window[:, 1] + tol))
    np.testing.assert_allclose(m.tool_axis_np(*nlp.rotary.pair), nlp.axis, atol=1e-12)
    passages = nlp.metrics.pole
    assert sorted({p.row for p in passages}) == [14, 15]
    assert min(p.closest_deg for p in passages) < 1.0 and all(p.gamma_cost is not None for p in passages)
    assert sum(nlp.metrics.violations.values()) == 0
