"""LinuxCNC's TCP mode (camsmooth.controller.tcp): M428 with the trt kinematics of LinuxCNC's
shipped table-rotary-tilting configurations (``xyzac-trt.ini``, ``xyzbc-trt.ini``), where the
planner limits the world coordinates (the tool tip, the rotary axes), not the joints.

Model tests check the world-coordinate planner against a hand-worked trapezoid, the chord rule and
the floor against brute force, the held F words against the joints of LinuxCNC's own trt
formula (joints = r + Rx(a) Rz(c) (pos - r), its kinematics' documentation) at every servo
cycle. One test runs a TCP program camsmooth writes on the headless LinuxCNC with the shipped
xyzac-trt switchkins kinematics (skips without LinuxCNC or its sample configurations).
"""

from __future__ import annotations

import dataclasses
import itertools
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM
from camsmooth.controller import mode_text
from camsmooth.controller.blocks import BLOCK_TOLERANCE_SHARE, EXECUTED_TOLERANCE_SHARE, _hold_row, decimate
from camsmooth.controller.tcp import (
    TCPPlan,
    TCPPlanner,
    chord_reach,
    tcp_planner_for,
    trt_kinematics,
    world_coordinates,
    world_joints,
)
from camsmooth.geometry.cutter import ToroidalCutter
from camsmooth.geometry.paths import CCPath
from camsmooth.machine.kinematics import PostConfig, load_machine, preset_machine

ROOT = Path(__file__).resolve().parent.parent
TOL = 0.005


def _dome_machine(mode: str = "tcp"):
    m = load_machine(str(ROOT / "surfaces" / "dome_machine.toml"))
    return dataclasses.replace(m, post=PostConfig(dialect="linuxcnc", mode=mode))


@pytest.fixture(scope="module")
def dome():
    """Three rows from the middle of the dome sample, smoothed (nlp) for its A/C trunnion with
    LinuxCNC's post in TCP mode."""
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import smooth

    path = read_cc_csv(ROOT / "surfaces" / "dome_path.csv")
    ids = np.unique(path.rows)
    k = np.isin(path.rows, ids[len(ids) // 2 - 1:len(ids) // 2 + 2])
    path = CCPath(points=path.points[k], normals=path.normals[k], rows=path.rows[k], source=path.source)
    return smooth(path, load_surface(ROOT / "surfaces" / "dome.toml"), _dome_machine("tcp"),
                  ToroidalCutter(R=4.0, r=1.0), feed=2000.0, lead_range=tuple(np.radians([2.0, 20.0])),
                  tilt_range=tuple(np.radians([-15.0, 15.0])), method="nlp", tolerance=TOL)


def _trt_joints(machine, world: np.ndarray) -> np.ndarray:
    """LinuxCNC's xyzac-trt kinematics, joints = r + Rx(a) Rz(c) (pos - r), r the rotation point
    (the table centre), a = -A and c = -C the values camsmooth writes (LinuxCNC's sense): (K, 5)
    joints X Y Z mm, A C rad (camsmooth's sense) of world positions (K, 5) tip mm, A C rad."""
    r = np.asarray(machine.table_centre, float)
    a, c = -world[:, 3], -world[:, 4]
    p = world[:, :3] - r
    x1 = np.cos(c) * p[:, 0] - np.sin(c) * p[:, 1]
    y1 = np.sin(c) * p[:, 0] + np.cos(c) * p[:, 1]
    z1 = p[:, 2]
    y2 = np.cos(a) * y1 - np.sin(a) * z1
    z2 = np.sin(a) * y1 + np.cos(a) * z1
    return np.column_stack([x1 + r[0], y2 + r[1], z2 + r[2], world[:, 3:]])


def test_the_trt_kinematics_describes_the_ac_and_bc_tables_and_gives_linuxcncs_joints():
    """A/C and B/C tables are LinuxCNC's xyzac-trt / xyzbc-trt; a head is not; the joints of the
    TCP world positions are those of the kinematics' formula."""
    centre = (5.0, -3.0, -20.0)
    ac = preset_machine("AC-table", centre=centre)
    assert trt_kinematics(ac) == "xyzac-trt-kins"
    assert trt_kinematics(preset_machine("BC-table", centre=centre)) == "xyzbc-trt-kins"
    assert trt_kinematics(preset_machine("AB-head", pivot=150.0)) is None
    assert trt_kinematics(preset_machine("BC-head-table", pivot=150.0, centre=centre)) is None
    rng = np.random.default_rng(3)
    w = np.column_stack([rng.uniform(-50, 50, (20, 3)), rng.uniform(-1.5, 0.5, 20), rng.uniform(-3, 3, 20)])
    assert np.allclose(world_joints(ac, w), _trt_joints(ac, w), atol=1e-9)
    assert tcp_planner_for(ac, TOL) is None  # the generic post: no LinuxCNC model
    assert tcp_planner_for(_dome_machine(), TOL) is not None


def test_a_tcp_block_takes_the_trapezoid_of_its_tip_chord_not_of_the_joints():
    """One TCP block from rest to rest: the tip 100 mm along X while C turns 60 deg, F 1200
    mm/min. LinuxCNC plans the world coordinates: length = the tip chord 100 mm, acceleration
    100 / max(100 / 3000, 60 / 900) = 1500 mm/s^2 (C binds), speed 20 mm/s, so it takes
    100 / 20 + 20 / 1500 = 5.0133 s (the joints' chord is 132 mm: 6.6 s at 20 mm/s)."""
    m = _dome_machine()
    planner = TCPPlanner()
    start = np.array([50.0, 0.0, 0.0, 0.0, 0.0])
    end = np.array([150.0, 0.0, 0.0, 0.0, np.radians(60.0)])
    # the row's first point is where the entry move starts: that move has no length (dropped)
    bt, pos = planner.row_run(m, np.vstack([start, end]), np.array([100.0 / 20.0]), start, 1.0)
    expected = 100.0 / 20.0 + 20.0 / 1500.0
    assert bt.end[-1] - bt.start[-1] == pytest.approx(expected, abs=2e-3)
    j = world_joints(m, np.vstack([start, end]))
    assert np.linalg.norm(j[1, :3] - j[0, :3]) == pytest.approx(132.3, abs=0.1)  # what machine mode would plan
    assert np.allclose(pos[-1], end, atol=1e-4)


def test_chord_reach_is_the_brute_force_distance_of_the_skipped_tips_to_the_chord():
    """Every block chord_reach allows keeps its skipped tips within the tolerance of its chord,
    and the first it refuses from a point does not (brute force over the points)."""
    rng = np.random.default_rng(7)
    s = np.linspace(0, 20, 60)
    tip = np.column_stack([s, 0.02 * np.sin(s) + rng.normal(0, 1e-4, 60), 0.001 * s ** 2])
    rows = np.repeat([1, 2], 30)
    ok = chord_reach(rows, tip, 0.003, 12)
    for a in range(60):
        end = 29 if a < 30 else 59
        for k in range(2, 13):
            if a + k > end:
                assert not ok[a, k - 1]
                continue
            p, b = tip[a + 1:a + k], tip[a + k] - tip[a]
            dist = [np.linalg.norm(x - tip[a] - np.clip((x - tip[a]) @ b / (b @ b), 0, 1) * b) for x in p]
            if ok[a, k - 1]:
                assert max(dist) <= 0.003 + 1e-12
            elif ok[a, k - 2]:
                assert max(dist) > 0.003
                break


def test_the_tcp_floor_is_the_best_choice_of_block_ends_by_brute_force():
    """On a row of 8 points the floor is the least, over every choice of block ends whose skipped
    tips stay within the tolerance of their chords, of the sum of max(chord / feed, largest world
    move / vmax, sqrt(2 largest move / amax)) (least_row_times' terms on the world coordinates)."""
    m = _dome_machine()
    n = 8
    s = np.linspace(0, 7, n)
    tip = np.column_stack([s, 0.004 * np.sin(s), np.zeros(n)])
    q = np.column_stack([np.zeros((n, 3)), np.radians(np.linspace(-10, -12, n)), np.radians(np.linspace(0, 3, n))])
    feed = np.full(n, 2000.0)
    got = TCPPlanner().row_floor(m, np.zeros(n, int), q, tip, feed, TOL)
    w = world_coordinates(q, tip)
    vmax = np.array([m.limits[a].vmax for a in m.joint_names])
    amax = np.array([m.limits[a].amax for a in m.joint_names])

    def cost(i: int, j: int) -> float:
        b = tip[j] - tip[i]
        for x in tip[i + 1:j]:
            t = np.clip((x - tip[i]) @ b / (b @ b), 0, 1)
            if np.linalg.norm(x - tip[i] - t * b) > TOL:
                return np.inf
        d = np.abs(w[j] - w[i])
        return max(np.linalg.norm(b) / (2000.0 / 60.0), (d / vmax).max(), np.sqrt(2 * (d / amax).max()))

    best = min(sum(cost(a, b) for a, b in itertools.pairwise((0, *inner, n - 1)))
               for r in range(n - 1) for inner in itertools.combinations(range(1, n - 1), r))
    assert got[0] == pytest.approx(best, rel=1e-12)


def test_placement_is_never_slower_than_the_longest_chord_blocks_and_the_floor_is_below_the_model(dome):
    """Per dome row, the placed TCP blocks run no slower on the model than the longest blocks
    of the chord rule (the same commanded law), every placed block keeps its skipped tips within
    BLOCK_TOLERANCE_SHARE of the tolerance of its chord, and the floor is below the model's time."""
    m, r = dome.machine, dome.methods["nlp"]
    planner = tcp_planner_for(m, TOL)
    q = np.column_stack([r.xyz, r.rotary.values])
    t = r.plan.t_plan
    rows = np.unique(r.rows)
    entry = np.full(len(rows), 2000.0)
    keep = planner.place(m, r.rows, q, r.cl, t, TOL, entry_height=DEFAULT_SAFE_HEIGHT_MM, entry_feed=entry)
    longest = decimate(m, r.rows, q, r.cl, TOL, ok=chord_reach(r.rows, r.cl, BLOCK_TOLERANCE_SHARE * TOL))
    w = world_coordinates(q, r.cl)
    for row in rows:
        sel = np.flatnonzero(r.rows == row)
        ew, et = planner._entry(m, q[sel[0]], r.cl[sel[0]], DEFAULT_SAFE_HEIGHT_MM, 2000.0)
        took = [planner.row_run(m, w[k], np.diff(t[k]), ew, et)[0].end[-1]
                for k in (sel[keep[sel]], sel[longest[sel]])]
        assert took[0] <= took[1] + 1e-12
        ends = sel[keep[sel]]
        for a, b in itertools.pairwise(ends):
            c = r.cl[b] - r.cl[a]
            for x in r.cl[a + 1:b]:
                u = np.clip((x - r.cl[a]) @ c / (c @ c), 0, 1)
                assert np.linalg.norm(x - r.cl[a] - u * c) <= BLOCK_TOLERANCE_SHARE * TOL + 1e-12
    plan = r.controller
    assert isinstance(plan, TCPPlan)
    assert np.all(plan.row_floor < plan.row_cycle_time)


def test_the_held_feeds_keep_every_joint_within_its_limits_at_every_servo_cycle(dome):
    """On the dome's trunnion with X Y Z slowed to 20 mm/s, a law twice as fast as the planned one
    takes a linear joint past its vmax on the model in TCP mode (LinuxCNC limits the tip's world
    coordinates only); the held F words bring every joint (LinuxCNC's trt formula of the model's
    world position at every servo cycle, finite differences at 1 ms) within its vmax and amax."""
    r = dome.methods["nlp"]
    m = dome.machine
    lim = dict(m.limits)
    for n in "XYZ":
        lim[n] = dataclasses.replace(lim[n], vmax=20.0)
    slow = dataclasses.replace(m, limits=lim)
    planner = tcp_planner_for(slow, TOL)
    q = np.column_stack([r.xyz, r.rotary.values])
    t = 0.5 * r.plan.t_plan
    rows = np.unique(r.rows)
    entry = np.full(len(rows), 1000.0)
    plan = planner.plan(slow, r.rows, q, r.cl, t, TOL, entry_height=DEFAULT_SAFE_HEIGHT_MM, entry_feed=entry)
    vmax = np.array([lim[a].vmax for a in slow.joint_names])
    amax = np.array([lim[a].amax for a in slow.joint_names])
    w = world_coordinates(q, r.cl)

    def peaks(k: np.ndarray, bt: np.ndarray, ew: np.ndarray, et: float) -> np.ndarray:
        _, pos = planner.row_run(slow, w[k], bt, ew, et)
        j = _trt_joints(slow, np.vstack([ew, ew, pos, pos[-1:]]))
        return np.maximum(np.abs(np.diff(j, axis=0)).max(axis=0) / 1e-3 / vmax,
                          np.abs(np.diff(j, 2, axis=0)).max(axis=0) / 1e-6 / amax)

    held_somewhere = False
    for i, row in enumerate(rows):
        sel = np.flatnonzero(r.rows == row)
        k = sel[plan.keep[sel]]
        ew, et = planner._entry(slow, q[sel[0]], r.cl[sel[0]], DEFAULT_SAFE_HEIGHT_MM, 1000.0)
        held = peaks(k, plan.block_time[k[1:]], ew, et)
        assert held[:3].max() <= 1.0 + 1e-9, (row, held)
        assert held[3:].max() <= 1.0 + 1e-6, (row, held)  # the planner's own limit of the world A C
        if plan.row_feed_scale[i] < 1.0:
            held_somewhere = True
            assert peaks(k, np.diff(t[k]), ew, et)[:3].max() > 1.0
    assert held_somewhere and plan.within_limits


def test_the_rotary_axes_past_amax_in_the_blend_into_the_last_block_are_held(dome):
    """With G64 P at twice the tolerance (every dome move turns a rotary axis), LinuxCNC's parabolic
    blend into a row's last block overlaps the block before's deceleration at half its
    acceleration with the last block's at its whole one: on the time-optimal law's block times the
    A axis goes past its amax at 1 ms once the blends are held within the tolerance (1.11 on the
    model, 1.08 measured on LinuxCNC without this hold). The plan lengthens the blocks that do it:
    by finite differences of the model's world positions, every rotary axis within amax (0.1% for
    the rest stop's one-cycle step), for at most 1% more row time than the tip hold alone."""
    r = dome.methods["nlp"]
    m = dome.machine
    q = np.column_stack([r.xyz, r.rotary.values])
    planner = tcp_planner_for(m, TOL, r.rows, q)
    assert planner.tolerance == pytest.approx(2.0 * TOL)
    still = q.copy()
    still[np.flatnonzero(r.rows == r.rows[0])[:2], 3:] = q[0, 3:]  # one move of a row turns no rotary axis
    assert tcp_planner_for(m, TOL, r.rows, still).tolerance == pytest.approx(0.6 * TOL)  # the blend arc's bound
    t = r.plan.t_plan
    rows = np.unique(r.rows)
    entry = np.full(len(rows), 2000.0)
    plan = planner.plan(m, r.rows, q, r.cl, t, TOL, entry_height=DEFAULT_SAFE_HEIGHT_MM, entry_feed=entry)
    amax = np.array([m.limits[a].amax for a in m.joint_names])[3:]
    w = world_coordinates(q, r.cl)

    def rotary_acc(k: np.ndarray, bt: np.ndarray, ew: np.ndarray, et: float) -> tuple[float, float]:
        run, pos = planner.row_run(m, w[k], bt, ew, et)
        a = np.abs(np.diff(np.vstack([pos[:1], pos, pos[-1:]])[:, 3:], 2, axis=0)).max(axis=0) / 1e-6 / amax
        return float(a.max()), float(run.end[-1] - run.end[0])

    unheld = []
    for i, row in enumerate(rows):
        sel = np.flatnonzero(r.rows == row)
        k = sel[plan.keep[sel]]
        ew, et = planner._entry(m, q[sel[0]], r.cl[sel[0]], DEFAULT_SAFE_HEIGHT_MM, 2000.0)
        held, took = rotary_acc(k, plan.block_time[k[1:]], ew, et)
        assert held <= 1.001, (row, held)
        assert took == pytest.approx(plan.row_cycle_time[i], abs=2e-3)
        # the same blocks held for the tip alone (camsmooth.controller.blocks._hold_row without the rotary check)
        _, bt_tip, _, _ = _hold_row(planner, m, w[sel], k - sel[0], t[sel], ew, et,
                                    np.vstack([ew[None, :3], r.cl[sel]]), np.arange(len(sel)) + 1,
                                    EXECUTED_TOLERANCE_SHARE * TOL, tips=lambda x: x[:, :3], split=False)
        tip_peak, tip_took = rotary_acc(k, bt_tip, ew, et)
        unheld.append(tip_peak)
        assert took <= 1.01 * tip_took + 2e-3, (row, took, tip_took)
    assert max(unheld) > 1.05, unheld


def test_smooth_says_both_modes_and_writes_the_tcp_program_with_the_held_feeds(dome, tmp_path):
    """smooth on the dome's A/C trunnion with the LinuxCNC post: the metrics carry TCP mode's and
    machine mode's predictions and floors, the program written in TCP mode (the machine file's
    mode) has the TCP plan's blocks with F = the tip chord (between the tips as written: moved off
    the points by the plan's tip_shift, at most half the tolerance) over the held block time and the G64 P
    the plan was timed with (twice the tolerance: every dome move turns a rotary axis, LinuxCNC
    joins them by parabolic blends only), and the summary line says which mode is faster."""
    from camsmooth.smoothing.posting import write_gcode

    r = dome.methods["nlp"]
    mt = r.metrics
    assert mt.controller == "linuxcnc-tcp"
    assert mt.cycle_time_s == pytest.approx(mt.tcp_cycle_time_s)
    assert mt.tcp_floor_s < mt.tcp_cycle_time_s and mt.machine_floor_s < mt.machine_cycle_time_s
    assert len(mt.row_tcp_cycle_time_s) == len(mt.row_tcp_floor_s) == 3
    ngc = tmp_path / "dome.ngc"
    write_gcode(ngc, r, dome.machine, dome.cutter, 2000.0, tolerance=TOL)
    text = ngc.read_text()
    assert "M428" in text and "G94" in text and "G93" not in text
    plan = r.controller
    assert plan.blend_tolerance == pytest.approx(2.0 * TOL)
    assert re.search(rf"^G64 P{plan.blend_tolerance:.4f} Q", text, re.M), text[:2000]
    blocks = [ln for ln in text.splitlines() if ln.startswith("G01")]
    assert len(blocks) == plan.blocks + 3  # and one entry move per row
    f_now, fs = None, []
    for ln in blocks:
        f = re.search(r" F([\d.]+)", ln)
        f_now = float(f.group(1)) if f else f_now
        fs.append(f_now)
    k = np.flatnonzero(plan.keep)
    first = np.r_[True, r.rows[k][1:] != r.rows[k][:-1]]
    cut = k[~first]
    assert 0 < plan.end_offset <= 0.5 * TOL + 1e-12
    tips = r.cl + plan.tip_shift
    chord = np.linalg.norm(np.round(tips[cut], 4) - np.round(tips[k[np.flatnonzero(~first) - 1]], 4), axis=1)
    written = np.asarray(fs, float)[~first]  # the G01 lines are the kept points in order, a row's entry first
    assert np.allclose(written, np.round(60.0 * chord / plan.block_time[cut], 1), atol=0.051)
    line = mode_text(mt.tcp_cycle_time_s, mt.tcp_floor_s, mt.machine_cycle_time_s, mt.machine_floor_s,
                     bool(mt.tcp_within_limits))
    assert line.startswith("TCP mode (M428): ") and "machine mode: " in line and "faster" in line


def test_the_mode_line_names_the_faster_mode():
    """Hand numbers: 2.0 s against 2.5 s is 0.5 s, 20% of the slower time, saved; a TCP program that
    cannot hold the joints is not the one to run."""
    assert mode_text(2.0, 1.8, 2.5, 1.9).endswith("TCP mode is faster by 0.5 s (20%)")
    assert mode_text(2.5, 1.8, 2.0, 1.9).endswith("machine mode is faster by 0.5 s (20%)")
    assert "machine mode is the one to run" in mode_text(2.0, 1.8, 2.2, 1.9, within_limits=False)


@pytest.mark.skipif(os.geteuid() != 0 and shutil.which("sudo") is None, reason="the simulation needs a user to run as")
def test_a_tcp_program_on_linuxcncs_trt_kinematics_runs_as_predicted_within_the_limits(dome, tmp_path):
    """The TCP program camsmooth writes for the three dome rows, run on the headless LinuxCNC with
    the xyzac-trt switchkins kinematics of its sample configuration (M428 on): each row's executed
    cut time within 2% of the TCP prediction (measured: 0.3% over), the tool tip (forward kinematics of
    the recorded joints) within the tolerance of the programmed tips at every servo sample, and
    every joint within the machine file's limits at every servo sample (finite differences at
    1 ms; the rotary axes, which LinuxCNC's planner limits as world coordinates, reach their amax
    at the last block's stop: 1.003 by these differences, so 1% is allowed there)."""
    from camsmooth.controller.blocks import tip_deviation
    from camsmooth.controller.linuxcnc_sim import camsmooth_joints, row_samples, simulate, trt_missing
    from camsmooth.smoothing.posting import write_gcode

    m, r = dome.machine, dome.methods["nlp"]
    missing = trt_missing(m)
    if missing:
        pytest.skip(missing)
    ngc = tmp_path / "dome_tcp.ngc"
    write_gcode(ngc, r, m, dome.cutter, 2000.0, tolerance=TOL)
    try:
        run = simulate(ngc, m, trt=True, timeout=60)
    except (OSError, subprocess.SubprocessError) as exc:
        pytest.skip(f"the LinuxCNC simulation does not start here: {exc}")
    joints = camsmooth_joints(m, run.joints)
    tip = m.tool_pose_np(joints[:, 3], joints[:, 4], joints[:, 0], joints[:, 1], joints[:, 2])[0]
    vmax = np.array([m.limits[a].vmax for a in m.joint_names])
    amax = np.array([m.limits[a].amax for a in m.joint_names])
    plan = r.controller
    samples = row_samples(ngc.read_text(), run)
    assert sorted(samples) == sorted(int(x) for x in np.unique(r.rows))
    for row, idx in samples.items():
        k = np.arange(idx[0], idx[-1] + 1)
        executed = len(k) * run.servo_period
        predicted = plan.row_cycle_time[list(plan.row_ids).index(row)]
        assert predicted == pytest.approx(executed, rel=0.02), row
        sel = np.flatnonzero(r.rows == row)
        path = np.vstack([r.cl[sel[0]] + DEFAULT_SAFE_HEIGHT_MM * r.axis[sel[0]], r.cl[sel]])
        assert tip_deviation(tip[k], path).max() <= TOL, row
        j = joints[k[0] - 2:k[-1] + 3]
        v = np.abs(np.diff(j, axis=0)).max(axis=0) / run.servo_period / vmax
        a = np.abs(np.diff(j, 2, axis=0)).max(axis=0) / run.servo_period ** 2 / amax
        assert v.max() <= 1.0 and a[:3].max() <= 1.0, (row, v, a)
        assert a[3:].max() <= 1.01, (row, a)


def test_smooth_and_the_report_print_both_modes_with_their_floors(dome, capsys):
    """``smooth``'s summary and the report's verdict for a TCP program on the A/C trunnion: the
    floor line names TCP mode (the written one) and the mode line gives both predictions and
    floors, the TCP floor recomputed here (least time on the world coordinates, for block ends as
    far off the points as the program's), and which is faster by the predicted times."""
    from camsmooth.cli.main import _print_floor
    from camsmooth.report.smoothing import _modes_line

    _print_floor(dome)
    out = capsys.readouterr().out
    r = dome.methods["nlp"]
    mt = r.metrics
    assert re.search(r"^nlp: LinuxCNC TCP mode \(M428\) cannot run straight blocks", out, re.M), out
    got = re.search(r"^nlp: TCP mode \(M428\): ([\d.]+) s, floor ([\d.]+) s; machine mode: ([\d.]+) s, floor "
                    r"([\d.]+) s: (TCP mode|machine mode) is faster by ([\d.]+) s \(([\d.]+)%\)$", out, re.M)
    assert got, out
    tcp, tcp_floor, mach, mach_floor = (float(got.group(i)) for i in range(1, 5))
    q = np.column_stack([r.xyz, r.rotary.values])
    want = TCPPlanner().row_floor(dome.machine, r.rows, q, r.cl, np.full(len(q), 2000.0), TOL,
                                  end_offset=r.controller.end_offset)
    assert tcp_floor == pytest.approx(want.sum(), rel=1e-3)
    assert tcp == pytest.approx(mt.tcp_cycle_time_s, rel=1e-3) and mach == pytest.approx(mt.machine_cycle_time_s,
                                                                                         rel=1e-3)
    assert tcp_floor <= tcp and mach_floor <= mach
    faster = "TCP mode" if tcp < mach else "machine mode"
    assert got.group(5) == faster
    assert float(got.group(6)) == pytest.approx(abs(mach - tcp), abs=0.06)  # each printed to 4 digits
    assert float(got.group(7)) == pytest.approx(100 * (1 - min(tcp, mach) / max(tcp, mach)), abs=0.1)
    assert _modes_line(mt) in out


@pytest.mark.parametrize("written, tcp_s, hint", [("machine", 80.0, "tcp"), ("tcp", 120.0, "machine"),
                                                  ("machine", 120.0, None), ("tcp", 80.0, None)])
def test_smooth_says_how_to_write_the_faster_mode(capsys, written, tcp_s, hint):
    """When the mode the machine file writes is the slower one on the controller, the summary says
    which [post] mode writes the faster program; nothing when it already is the faster one."""
    from types import SimpleNamespace

    from camsmooth.cli.main import _print_floor

    mt = SimpleNamespace(controller="linuxcnc", controller_floor_s=None, cycle_time_s=100.0, tcp_cycle_time_s=tcp_s,
                         tcp_floor_s=70.0, machine_cycle_time_s=100.0, machine_floor_s=90.0, tcp_within_limits=True)
    nlp = SimpleNamespace(method="nlp", metrics=mt)
    res = SimpleNamespace(methods={"nlp": nlp}, result=nlp,
                          machine=SimpleNamespace(post=SimpleNamespace(mode=written)))
    _print_floor(res)
    out = capsys.readouterr().out
    said = re.search(r'^nlp is written in (\w+) mode; \[post\] mode = "(\w+)"', out, re.M)
    if hint is None:
        assert said is None, out
    else:
        assert said and said.groups() == (written, hint), out
