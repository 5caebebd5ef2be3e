"""Machines described by their chain (``[machine] table``, ``head``, ``gauge``; per rotary axis
``direction`` and ``point``): the four kinds expand to the pinned chain and give the same results;
a nutating head-table machine (B inclined at 45 deg) and a fork head against the pinned formulas
written here with plain rotation matrices (scipy's Rotation, not the chain code); the inverse
against brute force; points outside a nutating cone named; a program through the nutating
machine's pole within every limit; and no machine-kind string tested outside the machine package."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import MACHINE_KINDS, load_machine, machine_from_dict

ROOT = Path(__file__).resolve().parents[1]
CENTRE = [12.0, -7.0, -35.0]
PIVOT = 150.0
LIMITS = {"min": -170.0, "max": 170.0, "vmax": 60.0, "amax": 300.0}
X, Y, Z = [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]

#: each kind spelt as the pinned chain keys (issue text: "the presets")
PINNED = {
    "AB-head": ({"head": ["A", "B"], "table": [], "gauge": [0, 0, PIVOT]},
                {"A": (X, [0, 0, PIVOT]), "B": (Y, [0, 0, PIVOT])}),
    "AC-table": ({"table": ["A", "C"], "head": [], "gauge": [0, 0, 0]}, {"A": (X, CENTRE), "C": (Z, CENTRE)}),
    "BC-table": ({"table": ["B", "C"], "head": [], "gauge": [0, 0, 0]}, {"B": (Y, CENTRE), "C": (Z, CENTRE)}),
    "BC-head-table": ({"table": ["C"], "head": ["B"], "gauge": [0, 0, PIVOT]},
                      {"C": (Z, CENTRE), "B": (Y, [0, 0, PIVOT])}),
}


def _preset(kind: str):
    m = {"kind": kind}
    if PINNED[kind][0]["head"]:
        m["pivot"] = PIVOT
    if PINNED[kind][0]["table"]:
        m["table_centre"] = CENTRE
    return machine_from_dict({"machine": m, "axis": {a: dict(LIMITS) for a in MACHINE_KINDS[kind]}})


def _chain(machine: dict, axes: dict, limits: dict | None = None):
    return machine_from_dict({"machine": dict(machine),
                              "axis": {a: {"direction": list(d), "point": list(p), **(limits or LIMITS)}
                                       for a, (d, p) in axes.items()}})


def _rot(d, q: float, p=(0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4: rotation by q (rad) about the line through p with direction d, right-handed."""
    d = np.asarray(d, float) / np.linalg.norm(d)
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(q * d).as_matrix()
    T[:3, 3] = np.asarray(p, float) - T[:3, :3] @ np.asarray(p, float)
    return T


def _pinned_pose(table, head, gauge, q: dict, xyz) -> tuple[np.ndarray, np.ndarray]:
    """The pinned formulas: T = R(t_n)..R(t_1) R(h_1)..R(h_m) e_z; machine mode
    tip_m = XYZ + rot(h_1)..rot(h_m)(-gauge) about the head's points taken from the gauge point;
    CL = rot(t_n)..rot(t_1) tip_m about the table's points. table/head: [(name, d, p)]."""
    g = np.asarray(gauge, float)
    H = np.eye(4)
    for name, d, p in head:
        H = H @ _rot(d, q[name], np.asarray(p, float) - g)
    tip_m = np.asarray(xyz, float) + (H @ np.append(-g, 1.0))[:3]
    Tb = np.eye(4)
    for name, d, p in reversed(table):
        Tb = Tb @ _rot(d, q[name], p)
    cl = (Tb @ np.append(tip_m, 1.0))[:3]
    axis = Tb[:3, :3] @ H[:3, :3] @ np.array([0.0, 0.0, 1.0])
    return cl, axis


@pytest.mark.parametrize("kind", tuple(MACHINE_KINDS))
def test_each_preset_expands_to_the_pinned_chain_and_gives_the_same_results(kind):
    keys, axes = PINNED[kind]
    preset, chained = _preset(kind), _chain(keys, axes)
    assert preset.rotary == chained.rotary == MACHINE_KINDS[kind]
    assert preset.description.table == chained.description.table
    assert preset.description.head == chained.description.head
    assert preset.description.gauge == chained.description.gauge
    rng = np.random.default_rng(3)
    q1, q2 = rng.uniform(-3, 3, (2, 200))
    xyz = rng.uniform(-200, 200, (3, 200))
    for a, b in zip(preset.tool_pose_np(q1, q2, *xyz), chained.tool_pose_np(q1, q2, *xyz), strict=True):
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    T = preset.tool_axis_np(q1, q2)
    np.testing.assert_allclose(preset.inverse_axis(T), chained.inverse_axis(T), rtol=0, atol=1e-12)
    cl = rng.uniform(-100, 100, (200, 3))
    np.testing.assert_allclose(preset.linear_axes(cl, q1, q2), chained.linear_axes(cl, q1, q2), rtol=0, atol=1e-9)
    # the words a kind decided stay with the preset; the explicit chain writes its axes as described
    assert preset.branch_words() == chained.branch_words()
    assert chained.linuxcnc_sense.tolist() == [1.0, 1.0]


NUTATING = ({"table": ["C"], "head": ["B"], "gauge": [0, 0, 300.0]},
            {"B": ([0, 1, 1], [0, 0, 200.0]), "C": (Z, [40.0, 30.0, 0.0])})
#: a fork head on a gantry: C on the ram (vertical), A in the fork, carrying the spindle
FORK = ({"table": [], "head": ["C", "A"], "gauge": [0, 0, 420.0]},
        {"C": (Z, [0, 0, 420.0]), "A": (X, [0, 0, 180.0])})
#: a trunnion whose tilt is A and whose platter is B (negated directions: a LinuxCNC-style table)
TRUNNION = ({"table": ["A", "B"], "head": []},
            {"A": ([-1, 0, 0], [0, 30.0, -50.0]), "B": ([0, 0, -1], [40.0, 30.0, 0.0])})


@pytest.mark.parametrize("spec", [NUTATING, FORK, TRUNNION], ids=["nutating", "fork", "trunnion"])
def test_chain_forward_against_the_pinned_formulas(spec):
    keys, axes = spec
    m = _chain(keys, axes)
    table = [(n, axes[n][0], axes[n][1]) for n in keys["table"]]
    head = [(n, axes[n][0], axes[n][1]) for n in keys["head"]]
    rng = np.random.default_rng(7)
    for _ in range(25):
        q = dict(zip(m.rotary, rng.uniform(-3, 3, 2), strict=True))
        xyz = rng.uniform(-300, 300, 3)
        cl, axis = _pinned_pose(table, head, keys.get("gauge", [0, 0, 0]), q, xyz)
        tip, T = m.tool_pose_np(*(np.array([v]) for v in (q[m.rotary[0]], q[m.rotary[1]], *xyz)))
        np.testing.assert_allclose(tip[0], cl, atol=1e-9)
        np.testing.assert_allclose(T[0], axis, atol=1e-12)
        # the linear axes that put the tip at cl are the X Y Z we started from
        np.testing.assert_allclose(m.linear_axes(cl[None], q[m.rotary[0]], q[m.rotary[1]])[0], xyz, atol=1e-9)


def _brute(m, T: np.ndarray, step_deg: float = 1.0) -> np.ndarray:
    """Every local minimum of the angle between the pinned tool axis and T on a grid of the two
    rotary angles, refined by a 3x3 neighbourhood: (K, 2) rad in ``rotary`` order."""
    g = np.radians(np.arange(-180.0, 180.0, step_deg))
    q1, q2 = np.meshgrid(g, g, indexing="ij")
    desc = m.description
    table = [(ax.name, ax.direction, ax.point) for ax in desc.table]
    head = [(ax.name, ax.direction, ax.point) for ax in desc.head]
    rots = {}
    for name, d, _ in table + head:
        rots[name] = Rotation.from_rotvec(np.outer((q1 if name == m.rotary[0] else q2).ravel(),
                                                   np.asarray(d) / np.linalg.norm(d))).as_matrix()
    R = np.broadcast_to(np.eye(3), (q1.size, 3, 3))
    for name, _, _ in list(reversed(table)) + head:
        R = R @ rots[name]
    err = np.linalg.norm(R[:, :, 2] - T, axis=1).reshape(q1.shape)
    padded = np.pad(err, 1, mode="wrap")
    neigh = np.min([np.roll(np.roll(padded, i, 0), j, 1)[1:-1, 1:-1] for i in (-1, 0, 1) for j in (-1, 0, 1)
                    if (i, j) != (0, 0)], axis=0)
    found = (err <= neigh) & (err < np.radians(2.5 * step_deg))
    return np.column_stack([q1[found], q2[found]])


@pytest.mark.parametrize("spec", [NUTATING, FORK, TRUNNION], ids=["nutating", "fork", "trunnion"])
def test_inverse_against_brute_force(spec):
    m = _chain(*spec, limits={"min": -180.0, "max": 180.0, "vmax": 60.0, "amax": 300.0})
    rng = np.random.default_rng(11)
    q = rng.uniform(-2.8, 2.8, (12, 2))
    T = m.tool_axis_np(q[:, 0], q[:, 1])
    sols = m.inverse_axis(T)
    for k in range(len(T)):
        brute = _brute(m, T[k])
        assert len(brute) >= 2
        for s in sols[k]:
            np.testing.assert_allclose(m.tool_axis_np(s[:1], s[1:])[0], T[k], atol=1e-9)
            d = np.abs((brute - s + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
            assert d.min() < np.radians(1.5), (k, np.degrees(s), np.degrees(brute))
        # and every solution the grid finds is one of the two branches (none missed)
        for b in brute:
            d = np.abs((sols[k] - b + np.pi) % (2 * np.pi) - np.pi).max(axis=1)
            assert d.min() < np.radians(1.5)


def test_nutating_cone_names_the_axes_it_cannot_reach():
    m = load_machine(ROOT / "surfaces" / "nutating_machine.toml")
    off = np.radians([0.0, 30.0, 89.0, 91.0, 120.0, 180.0])  # angle from the table's axis
    T = np.column_stack([np.sin(off), np.zeros_like(off), np.cos(off)])
    np.testing.assert_array_equal(m.reachable(T), off <= np.radians(90.0))
    ik = m.solve_row(T)
    assert ik.unreachable.tolist() == [3, 4, 5]
    # every reachable point is reached exactly (B within its travel of -5..185 deg)
    ok = m.reachable(T)
    np.testing.assert_allclose(m.tool_axis_np(*ik.rotary.take(ok).pair), T[ok], atol=1e-12)


@pytest.mark.parametrize("bad,message", [
    ({"kind": "AC-table", "table": ["A", "C"]}, "a machine is a preset kind or a chain"),
    ({"table": ["A", "B", "C"]}, "must name exactly two different rotary axes"),
    ({"table": ["A"], "head": ["A"]}, "must name exactly two different rotary axes"),
    ({"table": ["A", "D"]}, "'D' is not a rotary axis name"),
    ({"table": [], "head": ["A", "B"]}, "gauge is required when head is not empty"),
    ({"table": "AC"}, "must be a list of axis names"),
    ({"table": ["A", "C"], "gauge": [0, 0]}, "gauge must be three finite numbers"),
])
def test_chain_file_mistakes_are_named(bad, message):
    axes = {"A": {"direction": X, "point": [0, 0, 0], **LIMITS}, "C": {"direction": Z, "point": [0, 0, 0], **LIMITS},
            "B": {"direction": Y, "point": [0, 0, 0], **LIMITS}}
    with pytest.raises(InputError, match=re.escape(message)):
        machine_from_dict({"machine": bad, "axis": axes}, "m.toml")


def test_parallel_axes_and_an_axis_along_the_tool_are_refused():
    par = {"A": {"direction": X, "point": [0, 0, 0], **LIMITS}, "C": {"direction": [-2, 0, 0], "point": [0, 0, 0],
                                                                      **LIMITS}}
    with pytest.raises(InputError, match="directions are parallel"):
        machine_from_dict({"machine": {"table": ["A", "C"]}, "axis": par})
    along = {"A": {"direction": X, "point": [0, 0, 0], **LIMITS}, "C": {"direction": Z, "point": [0, 0, 0], **LIMITS}}
    with pytest.raises(InputError, match="cannot turn it"):
        machine_from_dict({"machine": {"table": ["A"], "head": ["C"], "gauge": [0, 0, 100]}, "axis": along})
    missing = {"A": {"point": [0, 0, 0], **LIMITS}, "C": {"direction": Z, "point": [0, 0, 0], **LIMITS}}
    with pytest.raises(InputError, match=r"missing key 'direction' in \[axis.A\]"):
        machine_from_dict({"machine": {"table": ["A", "C"]}, "axis": missing})


def test_shipped_chain_machines_read_and_a_table_axis_may_be_continuous():
    nut = load_machine(ROOT / "surfaces" / "nutating_machine.toml")
    ab = load_machine(ROOT / "surfaces" / "trunnion_ab_machine.toml")
    assert nut.rotary == ("B", "C") and ab.rotary == ("A", "B")
    assert not np.isfinite(nut.limits["C"].max) and not np.isfinite(ab.limits["B"].max)
    assert ab.description.axis_formula() == "T = Rz(B) Rx(A) e_z"
    assert nut.description.axis_formula() == "T = Rz(C) R[0,0.7071,0.7071](B) e_z"


def test_no_machine_kind_string_is_tested_outside_the_machine_package():
    """The kind is decided in camsmooth/machine: elsewhere no comparison with a kind's name, no
    ``.kind ==``/``kind[0]``/``"head" in kind`` test, no table keyed by kind."""
    kinds = "|".join(re.escape(k) for k in MACHINE_KINDS)
    patterns = [re.compile(rf"""["']({kinds})["']"""), re.compile(r"machine\.kind\s*(==|!=|\bin\b)"),
                re.compile(r"\bkind\[0\]"), re.compile(r"""["']head["']\s+in\s+kind"""),
                re.compile(r"MACHINE_KINDS\[")]
    offenders = []
    for path in sorted((ROOT / "camsmooth").rglob("*.py")):
        if "machine" in path.relative_to(ROOT / "camsmooth").parts[:1]:
            continue
        for n, line in enumerate(path.read_text().splitlines(), 1):
            code = line.split("#", 1)[0]
            if any(p.search(code) for p in patterns):
                offenders.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


def _skew(u) -> np.ndarray:
    return np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])


def test_inclined_axis_errors_against_the_exact_poe_error_to_second_order():
    """The nutating machine (B inclined at 45 deg on the head, C on the table) with the error model's
    location and orientation errors of both axes: the real tip and axis equal the pinned formulas
    with the lines moved (exact, scipy rotations), and the first-order error written here in closed
    form (a line moved by delta: the tip moves by R_prefix (I - R_i) delta; a direction turned by e
    about u: by R_prefix e ([u] R_i - R_i [u]) (y_i - p_i)) leaves a residual of O(S^2)."""
    from camsmooth.machine.model import ErrorModel, chain_axis_errors

    m = load_machine(ROOT / "surfaces" / "nutating_machine.toml")
    errors = chain_axis_errors(m)
    assert set(errors) == {"EX0B", "EZ0B", "EA0B", "EC0B", "EX0C", "EY0C", "EA0C", "EB0C"}
    s2 = np.sqrt(0.5)
    np.testing.assert_allclose(errors["EZ0B"].u, [0.0, -s2, s2], atol=1e-15)  # z made perpendicular to B
    rng = np.random.default_rng(5)
    q = {"B": rng.uniform(-0.1, 3.2, 20), "C": rng.uniform(-3, 3, 20)}
    xyz = rng.uniform(-200, 200, (20, 3))
    desc = m.description
    B, C = desc.axis("B"), desc.axis("C")
    g = np.asarray(desc.gauge)
    residual = {}
    for eps in (1e-3, 1e-4):
        geo = {"EX0B": 0.8 * eps, "EZ0B": -1.1 * eps, "EA0B": 0.5 * eps, "EC0B": -0.7 * eps,
               "EX0C": 1.3 * eps, "EY0C": 0.6 * eps, "EA0C": -0.9 * eps, "EB0C": 0.4 * eps}
        real = ErrorModel(geo).apply(m)
        tip, axis = real.tool_pose_np(q["B"], q["C"], *xyz.T)
        nom_tip, _ = m.tool_pose_np(q["B"], q["C"], *xyz.T)
        # the moved lines, written here from the parameters' meaning
        lines = {}
        for ax in (B, C):
            loc = sum(geo[n] * np.asarray(e.u) for n, e in errors.items() if e.axis == ax.name and e.what == "location")
            rot = sum(geo[n] * np.asarray(e.u) for n, e in errors.items()
                      if e.axis == ax.name and e.what == "orientation")
            d = Rotation.from_rotvec(rot).apply(np.asarray(ax.direction) / np.linalg.norm(ax.direction))
            lines[ax.name] = (d, np.asarray(ax.point) + loc, loc, rot)
        first = np.zeros_like(nom_tip)
        for k in range(len(xyz)):
            exact_tip, exact_axis = _pinned_pose([("C", lines["C"][0], lines["C"][1])],
                                                 [("B", lines["B"][0], lines["B"][1])], g,
                                                 {"B": q["B"][k], "C": q["C"][k]}, xyz[k])
            np.testing.assert_allclose(tip[k], exact_tip, atol=1e-9)
            np.testing.assert_allclose(axis[k], exact_axis, atol=1e-12)
            # first order: the head's B (inner), then the table's C (outer, prefix of B's effect)
            RB = Rotation.from_rotvec(q["B"][k] * np.asarray(B.direction)).as_matrix()
            RC = Rotation.from_rotvec(q["C"][k] * np.asarray(C.direction)).as_matrix()
            pB = np.asarray(B.point) - g  # B's point in the machine frame with XYZ at zero
            yB = -g  # the point B turns: the tip below the gauge
            dB = (np.eye(3) - RB) @ lines["B"][2] + (_skew(lines["B"][3]) @ RB - RB @ _skew(lines["B"][3])) @ (yB - pB)
            tip_m = xyz[k] + pB + RB @ (yB - pB)
            pC = np.asarray(C.point)
            uC = _skew(lines["C"][3])
            dC = (np.eye(3) - RC) @ lines["C"][2] + (uC @ RC - RC @ uC) @ (tip_m - pC)
            first[k] = RC @ dB + dC
        residual[eps] = np.abs(tip - nom_tip - first).max()
        assert np.abs(first).max() > 50 * residual[eps]  # the errors move the tip, the first order explains it
    # O(S^2): ten times smaller errors leave a residual about a hundred times smaller
    assert residual[1e-4] < residual[1e-3] / 50


def test_rtest_calibration_identifies_the_nutating_machines_axis_lines():
    """R-test calibration on a chain: the simulated R-test (sphere on the table, noise 0.5 um) of
    known line errors of the inclined B and the C axis gives them back within 4 standard
    uncertainties; the parameters it fits are the chain's own (chain_axis_errors)."""
    from camsmooth.machine import calibration as cal
    from camsmooth.machine import simulate as sim
    from camsmooth.machine.model import ErrorModel

    m = load_machine(ROOT / "surfaces" / "nutating_machine.toml")
    true = {"EX0C": 0.012, "EY0C": -0.008, "EX0B": 0.015, "EZ0B": -0.010, "EA0B": 20e-6, "EA0C": -30e-6}
    rep = cal.calibrate_rtest(sim.simulate_rtest(ErrorModel(true), m), m)
    for name, value in true.items():
        assert abs(rep.parameters[name] - value) < 4 * rep.uncertainties[name] + 1e-9, name
    assert rep.model.kind is None and set(rep.parameters) <= set(cal.machine_parameters(m))
