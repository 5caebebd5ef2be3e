"""The controller in the loop (camsmooth.controller): LinuxCNC's own interpreter reads every
program of the linuxcnc dialect, the TCP M-codes follow LinuxCNC's shipped switchkins
configurations, the block structure keeps the tips within its share of the tolerance, and the
planner model agrees with a headless LinuxCNC simulation.

The LinuxCNC tests need the Debian package linuxcnc-uspace (``make test`` installs it where
apt-get runs as root); without it they skip and say so.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from camsmooth.constants import NAIVE_CAM_TOLERANCE_SHARE
from camsmooth.controller import LinuxCNCPlanner, decimate, planner_for
from camsmooth.controller.blocks import BLOCK_TOLERANCE_SHARE
from camsmooth.controller.linuxcnc_sim import interpret, linuxcnc_missing, simulate
from camsmooth.geometry.cutter import ToroidalCutter
from camsmooth.geometry.paths import CCPath
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, machine_from_dict
from camsmooth.smoothing.posting import write_gcode

MISSING = linuxcnc_missing()
needs_linuxcnc = pytest.mark.skipif(MISSING is not None, reason=f"LinuxCNC not installed: {MISSING}")
TRT = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/table-rotary-tilting")


def _machine(mode: str = "machine"):
    import tomllib

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["post"] = {"dialect": "linuxcnc", "mode": mode}
    return machine_from_dict(data, "<test machine>")


@pytest.fixture(scope="module")
def blade_rows():
    """Three rows of the shipped blade, smoothed (nlp) for a LinuxCNC machine."""
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import smooth

    root = Path(__file__).resolve().parent.parent / "surfaces"
    path = read_cc_csv(root / "blade_path.csv")
    k = np.isin(path.rows, np.unique(path.rows)[10:13])
    path = CCPath(points=path.points[k], normals=path.normals[k], rows=path.rows[k], source=path.source)
    res = smooth(path, load_surface(root / "blade.toml"), _machine(), ToroidalCutter(R=4.0, r=1.0), feed=2000.0,
                 method="nlp", tolerance=0.005)
    return res


@pytest.fixture(scope="module")
def simulation_runs(tmp_path_factory) -> None:
    """Skip (with LinuxCNC's message) where the headless simulation cannot start here at all: a
    one-block program must run. A simulation that runs and disagrees still fails its test."""
    prog = tmp_path_factory.mktemp("probe") / "probe.ngc"
    prog.write_text("G21 G90\nG01 X1 F600\nM30\n")
    try:
        simulate(prog, _machine(), timeout=30)
    except (RuntimeError, OSError, subprocess.SubprocessError) as exc:
        pytest.skip(f"the LinuxCNC simulation does not start on this machine: {exc}")


def _trt_config(tmp_path: Path) -> Path:
    """An interpreter configuration with the M428/M429 remaps of LinuxCNC's shipped trt
    switchkins configuration (xyzac-trt.ini): the shipped remap subroutines, less their checks
    of the running HAL (the stand-alone interpreter has none: they would end the program), and
    the REMAP lines of the shipped INI."""
    cfg = tmp_path / "trt"
    if not cfg.exists():
        (cfg / "remap_subs").mkdir(parents=True)
        for code in ("428", "429"):
            sub = (TRT / "remap_subs" / f"{code}remap.ngc").read_text()
            sub = re.sub(r"\n\s*o(\d) if.*?o\1 endif", "", sub, flags=re.S)
            (cfg / "remap_subs" / f"{code}remap.ngc").write_text(sub)
        remaps = [ln.strip() for ln in (TRT / "xyzac-trt.ini").read_text().splitlines()
                  if ln.strip().startswith("REMAP") and ("M428" in ln or "M429" in ln)]
        (cfg / "xyzac-trt.ini").write_text("[RS274NGC]\nSUBROUTINE_PATH = ./remap_subs\n" + "\n".join(remaps) + "\n")
    return cfg


def _blocks(text: str) -> list[str]:
    return [ln for ln in text.split("\n") if re.match(r"(G53 )?G0[01]", ln)]


def test_decimated_blocks_keep_every_dropped_tip_within_their_share(blade_rows):
    """Independent check: each written block's tip curve (forward kinematics of the linearly
    interpolated joints as written, the points' joints moved by the plan's joint_shift, 200 steps)
    passes every dropped point's tip within the block share of the tolerance; fewer blocks than
    points."""
    r = blade_rows.methods["nlp"]
    m = blade_rows.machine
    q = np.column_stack([r.xyz, r.rotary.values]) + r.controller.joint_shift
    keep = r.controller.keep
    assert keep.sum() < 0.9 * len(keep)
    k = np.flatnonzero(keep)
    s = np.linspace(0, 1, 201)
    worst = 0.0
    for a, b in zip(k[:-1], k[1:], strict=True):
        if r.rows[a] != r.rows[b] or b == a + 1:
            continue
        qq = q[a] + s[:, None] * (q[b] - q[a])
        curve, _ = m.tool_pose_np(qq[:, 3], qq[:, 4], qq[:, 0], qq[:, 1], qq[:, 2])
        d = np.diff(curve, axis=0)
        for j in range(a + 1, b):  # projection on every chord of the 200-step curve
            rel = r.cl[j] - curve[:-1]
            t = np.clip((rel * d).sum(axis=1) / (d * d).sum(axis=1), 0.0, 1.0)
            worst = max(worst, np.linalg.norm(rel - t[:, None] * d, axis=1).min())
    assert worst <= BLOCK_TOLERANCE_SHARE * 0.005 + 1e-7


def test_decimate_keeps_every_point_of_a_sharply_curved_path():
    """A tip path that turns by 10 degrees per point cannot lose a point within 5 um."""
    m = _machine()
    th = np.radians(np.arange(8) * 10.0)
    tip = np.column_stack([5.0 * np.cos(th), 5.0 * np.sin(th), np.zeros(8)])
    q = np.column_stack([tip + [0, 0, m.pivot], np.zeros(8), np.zeros(8)])
    assert decimate(m, np.zeros(8, int), q, tip, 0.005).all()


def test_decimate_merges_a_straight_row_and_keeps_row_ends():
    m = _machine()
    x = np.linspace(0, 10, 41)
    tip = np.column_stack([x, np.zeros(41), np.zeros(41)])
    q = np.column_stack([tip + [0, 0, m.pivot], np.zeros(41), np.zeros(41)])
    rows = np.repeat([0, 1], [20, 21])
    keep = decimate(m, rows, q, tip, 0.005)
    assert keep[[0, 19, 20, 40]].all()
    assert keep.sum() < 10


def test_planner_for_follows_the_post():
    assert isinstance(planner_for(_machine(), 0.005), LinuxCNCPlanner)
    import tomllib

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    assert planner_for(machine_from_dict(data, "<m>"), 0.005) is None


def test_model_of_a_long_straight_move_is_the_trapezoid():
    """One 100 mm X move from rest to rest at 50 mm/s, 3000 mm/s^2: LinuxCNC's trapezoid
    (the segment is the last, so it has its full acceleration) takes L/v + v/a."""
    m = _machine()
    p = LinuxCNCPlanner()
    seg = p.segments(m, np.zeros(5), np.array([[100.0, 0, 0, 0, 0]]), np.array([False]), np.array([3000.0]),
                     np.array([False]))
    t = p.run(seg).end[0]
    assert t == pytest.approx(100 / 50 + 50 / 3000, abs=2e-3)


def test_model_of_short_rotary_blocks_is_limited_by_half_the_acceleration():
    """Parabolic blends: 0.5 mm blocks that turn B run at about sqrt(a/2 L), not at their feed."""
    m = _machine()
    n = 200
    x = 0.5 * np.arange(1, n + 1)
    joints = np.column_stack([x, np.zeros(n), np.zeros(n), np.zeros(n), 0.01 * np.arange(1, n + 1)])
    p = LinuxCNCPlanner()
    seg = p.segments(m, np.zeros(5), joints, np.zeros(n, bool), np.full(n, 60 / 0.005), np.ones(n, bool))
    t = p.run(seg).end[-1]
    v = np.sqrt(seg.acc[0] / 2 * 0.5)
    assert seg.reqvel[0] == pytest.approx(100.0)
    assert t == pytest.approx(n * 0.5 / v, rel=0.03)


@needs_linuxcnc
@pytest.mark.parametrize("mode", ["machine", "tcp"])
def test_linuxcnc_interpreter_reads_the_program_and_its_positions_and_times(blade_rows, tmp_path, mode):
    """rs274 reads every block; its canonical X Y Z A B equal the written blocks' joints (machine
    mode: the points' joints moved by the plan's joint_shift, its block ends off the points) or tips
    (tcp mode: moved by its tip_shift) to the written precision, and in machine mode its inverse-time
    feed gives each cut block the controller plan's block time."""
    m = _machine(mode)
    r = blade_rows.methods["nlp"]
    ngc = tmp_path / f"p_{mode}.ngc"
    write_gcode(ngc, r, m, blade_rows.cutter, 2000.0)
    if mode == "tcp" and not TRT.is_dir():
        pytest.skip("TCP mode needs the M428/M429 remaps of LinuxCNC's sample configurations")
    canon = interpret(ngc, ini=_trt_config(tmp_path) / "xyzac-trt.ini" if mode == "tcp" else None)
    keep = r.controller.keep
    shift = r.controller.joint_shift
    assert shift is not None and np.abs(shift[keep]).max() > 1e-3  # machine mode's ends sit off the points
    xyz = r.xyz + shift[:, :3] if mode == "machine" else r.cl + r.controller.tip_shift
    pts = np.column_stack([xyz, np.degrees(r.rotary.values)])[keep]
    cut = ~canon.rapid
    cut &= np.abs(canon.joints[:, 2]) < 1e3  # not the final G53 retract
    # each row: the entry feed move (onto the first point) and the row's blocks
    got = canon.joints[cut]
    assert len(got) == len(pts)
    assert np.abs(got - pts).max() < 1e-4 + 1e-9
    if mode == "machine":
        text = ngc.read_text()
        fw = np.array([float(re.search(r"F([\d.]+)", ln).group(1)) for ln in _blocks(text) if ln.startswith("G01")])
        bt = r.controller.block_time[keep]
        first = np.r_[True, r.rows[keep][1:] != r.rows[keep][:-1]]
        assert np.allclose(60.0 / fw[~first], bt[~first], rtol=1e-6, atol=1e-7)
        assert canon.inverse_time[cut].all()
        p, q = f"{r.controller.blend_tolerance:.4f}", f"{NAIVE_CAM_TOLERANCE_SHARE * 0.005:.4f}"
        assert f"G64 P{p} Q{q}" in text and float(q) < 0.005  # the naive-CAM detector kept within the tolerance


@needs_linuxcnc
@pytest.mark.skipif(not TRT.is_dir(), reason="LinuxCNC's sample configurations are not installed")
def test_tcp_codes_switch_to_the_five_axis_kinematics_of_the_shipped_configs(blade_rows, tmp_path):
    """With the remaps of LinuxCNC's own xyzac-trt configuration, the writer's TCP-on code sets
    the switchkins type to the five-axis kinematics (the value the configuration's M428 remap
    writes) and its TCP-off code back to identity (M429's): swapped codes fail."""
    cfg = _trt_config(tmp_path)
    kins = {}
    for code in ("428", "429"):
        sub = (cfg / "remap_subs" / f"{code}remap.ngc").read_text()
        kins[f"M{code}"] = float(re.search(r"#<kinstype>\s*=\s*(\d+)", sub).group(1))
    assert kins["M428"] != kins["M429"]
    five_axis = 1.0  # the remap comments: "kinstype==1 (xyzac,xyzbc)"; 0 is identity
    m = _machine("tcp")
    r = blade_rows.methods["nlp"]
    ngc = tmp_path / "tcp.ngc"
    write_gcode(ngc, r, m, blade_rows.cutter, 2000.0)
    canon = interpret(ngc, ini=cfg / "xyzac-trt.ini")
    values = [v for _, k, v in canon.aux if k == 3]  # SWITCHKINS_PIN = 3 in the remaps
    assert values, "the TCP codes did not run the configuration's switchkins remaps"
    assert values[0] == five_axis  # TCP on before the first move
    assert values[-1] == kins["M429"] != five_axis  # identity at the end
    first_motion = min(i for i, _, _ in canon.aux)
    assert first_motion == 0


@needs_linuxcnc
@pytest.mark.skipif(os.geteuid() != 0 and shutil.which("sudo") is None, reason="the simulation needs a user to run as")
def test_planner_model_predicts_the_linuxcnc_simulation(tmp_path, simulation_runs):
    """A short five-axis program of 120 blocks (0.4 mm, B turning, G93) on the headless LinuxCNC
    simulation: the model's time of the cut blocks is within 1% of the executed one (measured
    +0.36%)."""
    m = _machine()
    n = 120
    x = 0.4 * np.arange(n + 1)
    b = 5.0 * np.sin(np.linspace(0, 3, n + 1))
    lines = ["G21 G90 G17 G40 G49", "G64 P0.0025 Q0.0025", "G00 X0 Y0 Z150 A0 B0", "G93"]
    lines += [f"G01 X{x[i]:.4f} Y0 Z150 A0 B{b[i]:.4f} F{60 / 0.012:.3f}" for i in range(1, n + 1)]
    lines += ["G94", "G00 Z160", "M30"]
    prog = tmp_path / "short.ngc"
    prog.write_text("\n".join(lines) + "\n")
    run = simulate(prog, m, timeout=60)
    cut = np.flatnonzero((run.line >= 5) & (run.line <= 4 + n))
    executed = (cut[-1] - cut[0] + 1) * run.servo_period
    planner = LinuxCNCPlanner(tolerance=0.0025)
    joints = np.column_stack([x[1:], np.zeros(n), np.full(n, 150.0), np.zeros(n), b[1:]])
    seg = planner.segments(m, np.array([0, 0, 150.0, 0, 0]), joints, np.zeros(n, bool), np.full(n, 60 / 0.012),
                           np.ones(n, bool))
    bt = planner.run(seg)
    predicted = bt.end[-1] - bt.start[0]
    assert predicted == pytest.approx(executed, rel=0.01)
    assert executed > 1.5 * n * 0.012  # the short blocks really are slower than their feed


@needs_linuxcnc
@pytest.mark.skipif(os.geteuid() != 0 and shutil.which("sudo") is None, reason="the simulation needs a user to run as")
def test_blade_rows_on_linuxcnc_take_the_predicted_time_and_stay_within_the_tolerance(blade_rows, tmp_path,
                                                                                       simulation_runs):
    """Three smoothed blade rows written for LinuxCNC and run on its headless simulation: each
    row's executed cut time is within 1% of camsmooth's prediction (the model that ramped the
    next segment of a blend was 1.3% slow), the tool tip (forward kinematics of the joints
    LinuxCNC commanded at every servo cycle) stays within the tolerance of the path the
    full-density program commands and within 1 um of where the model puts it, and no row beats
    the lower bound of least_row_times for block ends as far off the points as the program's
    (the floor at the tolerance plus that distance, ``test_floor``)."""
    from camsmooth.controller.linuxcnc import least_row_times
    from camsmooth.controller.linuxcnc_sim import row_runs

    m = blade_rows.machine
    r = blade_rows.methods["nlp"]
    ngc = tmp_path / "rows.ngc"
    write_gcode(ngc, r, m, blade_rows.cutter, 2000.0)
    run = simulate(ngc, m, timeout=120)
    rows = row_runs(m, r, ngc.read_text(), run)
    assert sorted(x.row for x in rows) == sorted(int(x) for x in np.unique(r.rows))
    bound = least_row_times(m, r.rows, np.column_stack([r.xyz, r.rotary.values]), r.cl, np.full(len(r.rows), 2000.0),
                            0.005 + r.controller.end_offset)
    model_dev = dict(zip(r.controller.row_ids, r.controller.row_deviation, strict=True))
    least = dict(zip(r.controller.row_ids, bound, strict=True))
    for x in rows:
        assert x.predicted == pytest.approx(x.executed, rel=0.01), x
        assert x.deviation <= 0.005, x
        assert abs(x.deviation - model_dev[x.row]) <= 0.001, (x, model_dev[x.row])
        assert least[x.row] < x.executed


def test_a_block_that_does_not_move_takes_no_time_as_linuxcnc_drops_it():
    """A repeated point (zero length, dropped by LinuxCNC's planner) ends when the block before
    it ends, and the program takes as long as without it."""
    m = _machine()
    p = LinuxCNCPlanner()
    joints = np.array([[1.0, 0, 0, 0, 0.5], [1.0, 0, 0, 0, 0.5], [2.0, 0, 0, 0, 1.0]])
    seg = p.segments(m, np.zeros(5), joints, np.zeros(3, bool), np.full(3, 600.0), np.ones(3, bool))
    assert seg.length[1] == 0
    t = p.run(seg)
    without = p.run(p.segments(m, np.zeros(5), joints[[0, 2]], np.zeros(2, bool), np.full(2, 600.0),
                               np.ones(2, bool)))
    assert t.end[1] == t.end[0] and t.end[2] == pytest.approx(without.end[1])
    assert np.all(np.diff(t.end) >= 0)


# ---- the planner model's servo cycles, the tolerance check, and the lower bound ----------------


def test_tip_deviation_is_the_distance_to_the_nearest_segment_by_brute_force():
    """The k-d tree search against every segment: a fine helix after a long entry segment (a row's
    entry move), points scattered up to 0.3 mm around it."""
    from camsmooth.controller.blocks import tip_deviation

    rng = np.random.default_rng(3)
    th = np.linspace(0, 4 * np.pi, 2000)
    helix = np.column_stack([20 * np.cos(th), 20 * np.sin(th), 0.5 * th])
    path = np.vstack([helix[0] + [0, 0, 10.0], helix])
    idx = rng.integers(0, len(path) - 1, 3000)
    pts = path[idx] + rng.uniform(0, 1, (3000, 1)) * (path[idx + 1] - path[idx]) + rng.normal(0, 0.1, (3000, 3))
    a, d = path[:-1], np.diff(path, axis=0)
    rel = pts[:, None, :] - a[None]
    t = np.clip((rel * d).sum(-1) / (d * d).sum(-1), 0, 1)
    brute = np.linalg.norm(rel - t[..., None] * d, axis=-1).min(axis=1)
    assert np.allclose(tip_deviation(pts, path), brute, atol=1e-12)


def test_model_positions_follow_each_segment_and_its_blend():
    """The model's joints at every servo cycle: on the first move's line before the blend, on
    the second's after it, never past the corner by more than the blend, ending at the last
    point. Speeds: 10 mm along X then 10 mm along Y at v = 50 mm/s; each axis moves in one segment
    only, so at most v; in the blend the first falls at a/2 = 1500 mm/s^2 (parabolic end) while the
    last rises at the whole a = 3000 (it ends at rest): |(v - a t/2, a t)| is convex in t, largest at
    the ends of the ramp t in [0, v/a], at t = v/a: |(v/2, v)| = v sqrt(5)/2 = 55.9 mm/s."""
    m = _machine()
    p = LinuxCNCPlanner()
    joints = np.array([[10.0, 0, 0, 0, 0], [10.0, 10.0, 0, 0, 0]])
    seg = p.segments(m, np.zeros(5), joints, np.zeros(2, bool), np.full(2, 3000.0), np.zeros(2, bool))
    bt = p.run(seg)
    pos = bt.positions(np.zeros(5), joints)
    assert np.allclose(pos[-1], joints[-1])
    first = bt.head == 0
    assert np.allclose(pos[first & (bt.following_fraction == 0), 1], 0.0)
    assert np.all(pos[:, 0] <= 10.0 + 1e-12) and np.all(np.diff(pos[:, 0]) >= -1e-12)
    step = np.diff(pos[:, :3], axis=0) / p.servo_period
    assert np.abs(step).max() <= 50.0 * (1 + 1e-9)
    speed = np.linalg.norm(step, axis=1)
    # one-cycle averages see the peak at most one cycle's change of the X speed (1500 DT) low
    assert 50.0 * np.sqrt(5) / 2 - 1500 * p.servo_period <= speed.max() <= 50.0 * np.sqrt(5) / 2 * (1 + 1e-9)


def test_the_blocks_keep_the_models_tool_tip_within_the_tolerance_at_every_servo_cycle(blade_rows):
    """The nlp rows' program: the model's tool tip over every servo cycle stays within
    EXECUTED_TOLERANCE_SHARE of the tolerance of the path through the points, checked here by
    running the planner model on the written blocks (their ends off the points by the plan's
    joint_shift); at the time-optimal law's block times it does not (the check does work)."""
    from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM
    from camsmooth.controller import EXECUTED_TOLERANCE_SHARE
    from camsmooth.controller.blocks import programmed_tip_path, tip_deviation, tool_tips

    r, m = blade_rows.methods["nlp"], blade_rows.machine
    q = np.column_stack([r.xyz, r.rotary.values])
    written = q + r.controller.joint_shift
    p = planner_for(m, 0.005, r.rows, q)  # the blend tolerance the program is written with
    assert p.tolerance == r.controller.blend_tolerance
    worst_written, worst_optimal = 0.0, 0.0
    for rid in np.unique(r.rows):
        sel = np.flatnonzero(r.rows == rid)
        k = sel[r.controller.keep[sel]]
        entry = q[sel[0]].copy()
        entry[:3] += DEFAULT_SAFE_HEIGHT_MM * r.axis[sel[0]]
        path = programmed_tip_path(m, q[sel], tool_tips(m, entry[None])[0])
        for bt, is_written in ((r.controller.block_time[k[1:]], True), (np.diff(r.plan.t_plan[k]), False)):
            _, joints = p.row_run(m, written[k], bt, entry, 60 * DEFAULT_SAFE_HEIGHT_MM / 2000.0)
            dev = float(tip_deviation(tool_tips(m, joints), path).max())
            if is_written:
                worst_written = max(worst_written, dev)
            else:
                worst_optimal = max(worst_optimal, dev)
    assert worst_written <= EXECUTED_TOLERANCE_SHARE * 0.005 + 1e-6
    assert np.isclose(worst_written, r.controller.row_deviation.max(), rtol=0.05)
    assert worst_optimal > EXECUTED_TOLERANCE_SHARE * 0.005


def _least_time_brute_force(m, q, tip, feed_mm_s, ok):
    """Every choice of block ends of a short row, the same block cost as least_row_times."""
    import itertools

    from camsmooth.machine.kinematics import axis_limits

    vmax, amax, _ = axis_limits(m)
    n = len(q)
    best = np.inf
    for mask in itertools.product([False, True], repeat=n - 2):
        ends = [0] + [i + 1 for i, on in enumerate(mask) if on] + [n - 1]
        total = 0.0
        for i, j in zip(ends[:-1], ends[1:], strict=True):
            if j - i > ok.shape[1] or not ok[i, j - i - 1]:
                total = np.inf
                break
            d = np.abs(q[j] - q[i])
            rest = np.sqrt(2 * (d / amax).max()) if d[3:].max() > 0 else 0.0
            total += max(np.linalg.norm(tip[j] - tip[i]) / feed_mm_s, (d / vmax).max(), rest)
        best = min(best, total)
    return best


def test_least_row_times_is_the_best_choice_of_block_ends_by_brute_force():
    """A short curved row with B turning: the dynamic programme equals the best of all 2^(n-2)
    choices of block ends. With a tolerance every block meets, one block is best (chords add up
    to at least the whole chord, square roots of parts to at least the root of the whole): X 20
    mm and B 10 deg give max(L / v, sqrt(2 max(X / a_X, B / a_B))); with no rotary motion there
    is no parabolic blend and the bound is max(L / v, L / vmax_X)."""
    from camsmooth.controller.blocks import block_reach
    from camsmooth.controller.linuxcnc import least_row_times

    m = _machine()
    n = 11
    th = np.radians(np.linspace(0, 6, n))
    tip = np.column_stack([60 * np.sin(th), np.zeros(n), 60 * (1 - np.cos(th))])
    B = np.radians(np.linspace(0, 4, n))
    q = np.column_stack([m.linear_axes(tip, np.zeros(n), B), np.zeros(n), B])
    for tol in (0.002, 0.005, 0.05):
        ok = block_reach(m, np.zeros(n, int), q, tip, tol, 16)
        got = least_row_times(m, np.zeros(n, int), q, tip, np.full(n, 2000.0), tol)[0]
        assert got == pytest.approx(_least_time_brute_force(m, q, tip, 2000.0 / 60, ok), rel=1e-12)
    x = np.linspace(0, 20, 21)
    for b_deg in (10.0, 0.0):
        B = np.radians(np.linspace(0, b_deg, 21))
        q = np.column_stack([x, np.zeros(21), np.full(21, m.pivot), np.zeros(21), B])
        tip = m.tool_pose_np(np.zeros(21), B, q[:, 0], q[:, 1], q[:, 2])[0]
        chord = np.linalg.norm(tip[-1] - tip[0])
        for feed in (2000.0, 1e6):
            got = least_row_times(m, np.zeros(21, int), q, tip, np.full(21, feed), 10.0)[0]
            rest = np.sqrt(2 * max(20 / 3000.0, b_deg / 300.0)) if b_deg else 0.0
            want = max(chord / (feed / 60), 20 / 500.0, np.radians(b_deg) / np.radians(60.0), rest)
            assert got == pytest.approx(want, rel=1e-12)


def test_least_row_times_is_below_what_the_model_predicts_for_every_method(blade_rows):
    """No program camsmooth writes beats the bound: per row and method, the bound at the
    tolerance for block ends as far off the points as the program's is below the controller's
    predicted row time, and a looser tolerance or a larger offset lowers it."""
    from camsmooth.controller.linuxcnc import least_row_times

    m = blade_rows.machine
    for r in blade_rows.methods.values():
        q = np.column_stack([r.xyz, r.rotary.values])
        feed = np.full(len(q), 2000.0)
        e = r.controller.end_offset
        assert e > 0
        bound = least_row_times(m, r.rows, q, r.cl, feed, 0.005, end_offset=e)
        assert np.all(bound < r.controller.row_cycle_time)
        assert np.all(bound >= np.asarray(r.plan.row_cycle_time) * 0.9)
        assert np.all(least_row_times(m, r.rows, q, r.cl, feed, 0.01, end_offset=e) <= bound + 1e-12)
        assert np.all(least_row_times(m, r.rows, q, r.cl, feed, 0.005, end_offset=2 * e) <= bound + 1e-12)


def test_blend_tolerance_exceeds_the_tolerance_only_where_every_move_turns_a_rotary_axis():
    """LinuxCNC 2.9 joins two moves that turn no rotary axis by a blend arc bounded by G64 P (the
    tolerance's share PATH_TOLERANCE_SHARE < 1), but moves that turn one only by parabolic blends, whose
    path camsmooth's block times hold: then P is PARABOLIC_PATH_TOLERANCE_SHARE of it. A move whose
    rotary axes differ by less than the written 0.0001 deg turns none; the rows' boundaries do not count."""
    from camsmooth.constants import PARABOLIC_PATH_TOLERANCE_SHARE, PATH_TOLERANCE_SHARE
    from camsmooth.controller import blend_tolerance

    n = 6
    q = np.column_stack([np.arange(n, dtype=float), np.zeros((n, 2)), np.zeros(n), np.radians(np.arange(n) * 0.5)])
    rows = np.zeros(n, int)
    assert blend_tolerance(rows, q, 0.005) == pytest.approx(PARABOLIC_PATH_TOLERANCE_SHARE * 0.005)
    assert PATH_TOLERANCE_SHARE < 1.0 < PARABOLIC_PATH_TOLERANCE_SHARE
    flat = q.copy()
    flat[3, 4] = flat[2, 4] + np.radians(0.00004)  # written as the same angle: an XYZ-only move
    assert blend_tolerance(rows, flat, 0.005) == pytest.approx(PATH_TOLERANCE_SHARE * 0.005)
    # the same angle across a row boundary (the retract and rapid between them) is no move of the program
    two = q.copy()
    two[3, 4] = two[2, 4]
    assert blend_tolerance(np.repeat([0, 1], 3), two, 0.005) == pytest.approx(PARABOLIC_PATH_TOLERANCE_SHARE * 0.005)
    m = _machine()
    assert planner_for(m, 0.005, rows, q).tolerance == pytest.approx(PARABOLIC_PATH_TOLERANCE_SHARE * 0.005)
    assert planner_for(m, 0.005).tolerance == pytest.approx(PATH_TOLERANCE_SHARE * 0.005)


def test_predict_names_the_joint_linuxcncs_own_blend_takes_past_its_limit():
    """LinuxCNC runs a row's last block at its whole acceleration while the block before it still
    decelerates at half of its own (camsmooth.controller.linuxcnc, step 4). Where B turns back between
    them, both accelerations point the same way: B reaches a/2 + a = 1.5 of its amax while they
    overlap, by the model's servo cycles (second differences), which ``row_joint_peak`` reports;
    where B goes on the same way they partly cancel and B stays within its amax."""
    from camsmooth.controller import predict

    m = _machine()
    p = LinuxCNCPlanner()
    x = np.array([0.0, 0.2, 0.4])
    for b, turns_back in ((np.array([0.0, 3.0, 0.0]), True), (np.array([0.0, 3.0, 6.0]), False)):
        q = np.column_stack([x, np.zeros(3), np.full(3, 150.0), np.zeros(3), np.radians(b)])
        tip = m.tool_pose_np(q[:, 3], q[:, 4], q[:, 0], q[:, 1], q[:, 2])[0]
        plan = predict(p, m, np.zeros(3, int), q, tip, np.array([0.0, 1e-3, 2e-3]), np.ones(3, bool),
                       entry_height=0.0, entry_feed=np.array([2000.0]))
        B = plan.row_joint_peak[0, 4]
        if turns_back:
            assert 1.45 < B < 1.55, plan.row_joint_peak
        else:
            assert B <= 1.01, plan.row_joint_peak  # the warning threshold (camsmooth.smoothing.pipeline)
