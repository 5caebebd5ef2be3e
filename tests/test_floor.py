"""LinuxCNC at its limit (camsmooth.controller): the floor ``smooth`` prints beside the prediction
(the least time any program of straight blocks through the points can take on LinuxCNC 2.9) and
the block placement chosen against the planner model's executed time.

Checked against independent computations: the floor against every choice of block ends of a
short row, the placement against every choice of block ends run through the planner model, and
against the longest blocks within the tolerance (``decimate``, the placement before) on the model.
No LinuxCNC needed (benchmarks/bench_controller.py runs the programs on it).
"""

from __future__ import annotations

import itertools
import re
from pathlib import Path

import numpy as np
import pytest

from camsmooth.controller import EXECUTED_TOLERANCE_SHARE, decimate, place, planner_for, predict
from camsmooth.controller.blocks import (
    BLOCK_TOLERANCE_SHARE,
    block_reach,
    programmed_tip_path,
    row_entry,
    tip_deviation,
)
from camsmooth.controller.blocks import tool_tips as fk_tips
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, axis_limits, machine_from_dict

TOL = 0.005
FEED = 2000.0
ENTRY_MM = 10.0


def _machine():
    import tomllib

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["post"] = {"dialect": "linuxcnc", "mode": "machine"}
    return machine_from_dict(data, "<test machine>")


def _joints(r) -> np.ndarray:
    """(N, 5) X Y Z mm and the rotary axes rad of a method's program."""
    return np.column_stack([r.xyz, r.rotary.values])


def _short_rows(m, n: int = 12):
    """Two short rows: a tip arc of rising curvature with B turning unevenly (the blocks the
    tolerance allows vary along it, 1 to 5 points), and a straight one with A and B turning."""
    s = np.linspace(0.0, 1.0, n)
    th = np.radians(s + s ** 2)
    tip1 = np.column_stack([400 * np.sin(th), np.zeros(n), 400 * (1 - np.cos(th))])
    rot1 = np.column_stack([np.zeros(n), np.radians(np.sin(2.5 * s))])
    tip2 = np.column_stack([np.linspace(0, 9, n), np.full(n, 5.0), np.zeros(n)])
    rot2 = np.column_stack([np.radians(np.linspace(0, 3, n)), np.radians(2.0 * s ** 2)])
    tip, rot = np.vstack([tip1, tip2]), np.vstack([rot1, rot2])
    q = np.column_stack([m.linear_axes(tip, rot[:, 0], rot[:, 1]), rot])
    return np.repeat([0, 1], n), q, tip


def _brute_floor(m, q, tip, ok, feed_mm_s):
    """The floor's definition, by every choice of block ends of one row: each block lasts at least
    its tip chord over the feed, its largest joint move over that joint's speed, and (when it turns
    a rotary axis) sqrt(2 max_i |d_i| / a_i), the parabolic blend at half the acceleration."""
    vmax, amax, _ = axis_limits(m)
    n = len(q)
    best = np.inf
    for mask in itertools.product([False, True], repeat=n - 2):
        ends = [0] + [i + 1 for i, on in enumerate(mask) if on] + [n - 1]
        total = 0.0
        for i, j in zip(ends[:-1], ends[1:], strict=True):
            if not ok[i, j - i - 1]:
                total = np.inf
                break
            d = np.abs(q[j] - q[i])
            rest = np.sqrt(2 * np.max(d / amax)) if d[3:].max() > 0 else 0.0
            total += max(np.linalg.norm(tip[j] - tip[i]) / feed_mm_s, np.max(d / vmax), rest)
        best = min(best, total)
    return best


def test_the_floor_is_the_least_time_over_every_choice_of_block_ends_and_below_the_prediction():
    """The controller plan's floor (what ``smooth`` prints) on two short rows: per row the least
    floor cost over all 2^(n-2) choices of block ends (brute force of the definition), and below
    the time the planner model predicts for the program camsmooth writes."""
    from camsmooth.smoothing.evaluate import time_law

    m = _machine()
    rows, q, tip = _short_rows(m)
    law = time_law(m, rows, q, tip, np.full(len(rows), FEED), tolerance=TOL)
    ctrl = law.controller
    assert ctrl is not None and ctrl.row_floor is not None
    for r in range(2):
        sel = rows == r
        ok = block_reach(m, np.zeros(sel.sum(), int), q[sel], tip[sel], TOL, 64)
        want = _brute_floor(m, q[sel], tip[sel], ok, FEED / 60.0)
        assert ctrl.row_floor[r] == pytest.approx(want, rel=1e-12)
        assert ctrl.row_floor[r] < ctrl.row_cycle_time[r]
    assert ctrl.floor == pytest.approx(ctrl.row_floor.sum())


def test_block_ends_are_within_a_percent_of_the_best_choice_on_the_model():
    """The placement's dynamic programme (``LinuxCNCPlanner.block_ends``) on a short row: its
    blocks, run through the planner model, take at most 1% longer than the best of every choice of
    block ends the tolerance allows (each run through the model), and no longer than the longest
    blocks (``decimate``)."""
    m = _machine()
    rows, q, tip = _short_rows(m)
    p = planner_for(m, TOL)
    sel = rows == 0
    q, tip = q[sel], tip[sel]
    n = len(q)
    t = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(tip, axis=0), axis=1))] / (FEED / 60.0)
    ok = block_reach(m, np.zeros(n, int), q, tip, BLOCK_TOLERANCE_SHARE * TOL)
    entry_q, entry_time = row_entry(m, q[0], ENTRY_MM, FEED)

    def run(ends: np.ndarray) -> float:
        return float(p.row_run(m, q[ends], np.diff(t[ends]), entry_q, entry_time)[0].end[-1])

    best = np.inf
    choices = 0
    for mask in itertools.product([False, True], repeat=n - 2):
        ends = np.r_[0, 1 + np.flatnonzero(mask), n - 1]
        if all(ok[i, j - i - 1] for i, j in zip(ends[:-1], ends[1:], strict=True) if j - i <= ok.shape[1]) \
                and np.diff(ends).max() <= ok.shape[1]:
            best = min(best, run(ends))
            choices += 1
    assert choices > 20  # the tolerance leaves a real choice
    dp = p.block_ends(m, q, t, ok, entry_q, entry_time)
    assert dp[0] == 0 and dp[-1] == n - 1 and np.all(np.diff(dp) > 0)
    assert all(ok[i, j - i - 1] for i, j in zip(dp[:-1], dp[1:], strict=True))
    greedy = np.flatnonzero(decimate(m, np.zeros(n, int), q, tip, TOL))
    assert run(dp) <= best * 1.01
    assert run(dp) <= run(greedy) + 1e-9


@pytest.fixture(scope="module")
def blade_rows():
    """Two rows of the shipped blade, smoothed (nlp) for a LinuxCNC machine."""
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.paths import CCPath
    from camsmooth.geometry.surfaces import load_surface
    from camsmooth.io.ccpath import read_cc_csv
    from camsmooth.smoothing.pipeline import smooth

    root = Path(__file__).resolve().parent.parent / "surfaces"
    path = read_cc_csv(root / "blade_path.csv")
    k = np.isin(path.rows, np.unique(path.rows)[20:22])
    path = CCPath(points=path.points[k], normals=path.normals[k], rows=path.rows[k], source=path.source)
    return smooth(path, load_surface(root / "blade.toml"), _machine(), ToroidalCutter(R=4.0, r=1.0), feed=FEED,
                  method="nlp", tolerance=TOL)


def test_placement_is_never_slower_than_the_longest_blocks_and_keeps_the_tip_within_the_tolerance(blade_rows):
    """The nlp and none programs of two blade rows: per row, the planner model's time of the placed
    blocks (what the pipeline writes) is no longer than that of the longest blocks within the
    tolerance (the placement before), and the model's tool tip, recomputed here from the written
    blocks and times at every servo cycle, stays within EXECUTED_TOLERANCE_SHARE of the tolerance
    of the path the full-density program commands."""
    m = blade_rows.machine
    for name in ("nlp", "none"):
        r = blade_rows.methods[name]
        q = _joints(r)
        c = r.controller
        p = planner_for(m, TOL, r.rows, q)  # with the blend tolerance the program is written with
        assert p.tolerance == c.blend_tolerance
        entry_feed = np.full(len(c.row_ids), FEED)
        old = predict(p, m, r.rows, q, r.cl, r.plan.t_plan, decimate(m, r.rows, q, r.cl, TOL),
                      entry_height=ENTRY_MM, entry_feed=entry_feed, tolerance=TOL)
        new = predict(p, m, r.rows, q, r.cl, r.plan.t_plan,
                      place(p, m, r.rows, q, r.cl, r.plan.t_plan, TOL, entry_height=ENTRY_MM, entry_feed=entry_feed),
                      entry_height=ENTRY_MM, entry_feed=entry_feed, tolerance=TOL)
        assert np.allclose(new.row_cycle_time, c.row_cycle_time)  # the pipeline's blocks are these
        assert np.all(new.row_cycle_time <= old.row_cycle_time + 1e-9), (name, new.row_cycle_time, old.row_cycle_time)
        for rid in c.row_ids:
            sel = np.flatnonzero(r.rows == rid)
            k = sel[c.keep[sel]]
            entry_q, entry_time = row_entry(m, q[sel[0]], ENTRY_MM, FEED)
            path = programmed_tip_path(m, q[sel], fk_tips(m, entry_q[None])[0])
            _, joints = p.row_run(m, q[k], c.block_time[k[1:]], entry_q, entry_time)
            assert tip_deviation(fk_tips(m, joints), path).max() <= EXECUTED_TOLERANCE_SHARE * TOL + 1e-6, name


def test_smooth_prints_the_floor_beside_the_prediction(blade_rows, capsys):
    """``smooth``'s summary line per method: 'LinuxCNC cannot run straight blocks through these
    points in less than X s; this program: Y s', X the floor of the program's points recomputed
    here (least_row_times at the whole tolerance and the programmed feed), Y the predicted time,
    X <= Y; the report's row table carries the floor per row."""
    from camsmooth.cli.main import _print_floor
    from camsmooth.controller.linuxcnc import least_row_times
    from camsmooth.report.smoothing import _rows_html

    _print_floor(blade_rows)
    out = capsys.readouterr().out
    m = blade_rows.machine
    for name, r in blade_rows.methods.items():
        got = re.search(rf"^{name}: LinuxCNC cannot run straight blocks through these points in less than "
                        r"([\d.e+-]+) s; this program: ([\d.e+-]+) s", out, re.M)
        assert got, out
        floor, program = float(got.group(1)), float(got.group(2))
        want = least_row_times(m, r.rows, _joints(r), r.cl, np.full(len(r.rows), FEED), TOL)
        assert floor == pytest.approx(want.sum(), rel=1e-3)
        assert program == pytest.approx(r.metrics.cycle_time_s, rel=1e-3)
        assert floor <= program
        assert np.allclose(r.metrics.row_controller_floor_s, want)
    html = _rows_html(blade_rows.methods["nlp"], tuple(m.rotary))
    assert "least time on linuxcnc" in html
    for v in blade_rows.methods["nlp"].metrics.row_controller_floor_s:
        assert f"<td>{v:.4g}</td>" in html


def test_the_block_check_answers_as_the_distance_to_every_segment():
    """block_reach's compiled check (each point stops at the first segment within reach) against the
    distance of every point to every segment by brute force: random polylines and points around
    them, tolerances around the largest distance."""
    from camsmooth.controller.blocks import _all_within

    rng = np.random.default_rng(7)
    curve = np.cumsum(rng.normal(0, 1.0, (400, 17, 3)), axis=1)
    s = rng.integers(0, 16, (400, 9))
    f = rng.uniform(0, 1, (400, 9, 1))
    a = np.take_along_axis(curve, s[..., None], axis=1)
    b = np.take_along_axis(curve, s[..., None] + 1, axis=1)
    pts = a + f * (b - a) + rng.normal(0, 0.05, (400, 9, 3))
    rel = pts[:, :, None, :] - curve[:, None, :-1, :]
    d = np.diff(curve, axis=1)[:, None]
    t = np.clip((rel * d).sum(-1) / (d * d).sum(-1), 0, 1)
    worst = np.linalg.norm(rel - t[..., None] * d, axis=-1).min(axis=2).max(axis=1)
    frac = rng.uniform(0, 1, 9)  # where the search starts does not change the answer
    for tol in np.quantile(worst, [0.1, 0.5, 0.9]):
        assert np.array_equal(_all_within(pts, curve, frac, tol), worst <= tol)


def test_past_the_tolerance_p_every_block_turns_a_rotary_axis_as_written():
    """Where ``G64 P`` exceeds the tolerance (every move of the program turns a rotary axis),
    LinuxCNC would join a block that turns none by a blend arc as far off as P. A row whose A
    turns back and forth by 0.001 deg (every move turns it, every pair of moves brings it back):
    the tolerance alone lets blocks span several points (checked), but the placement keeps every
    point, so every written block turns A (4 decimals of a degree, as written)."""
    m = _machine()
    n = 30
    tip = np.column_stack([np.linspace(0.0, 6.0, n), np.zeros(n), np.zeros(n)])
    rot = np.column_stack([np.radians(0.001 * (np.arange(n) % 2)), np.zeros(n)])
    q = np.column_stack([m.linear_axes(tip, rot[:, 0], rot[:, 1]), rot])
    rows = np.zeros(n, int)
    p = planner_for(m, TOL, rows, q)
    assert p.tolerance > TOL and p.entry_stop
    assert block_reach(m, rows, q, tip, BLOCK_TOLERANCE_SHARE * TOL)[:-2, 1].all()  # two moves would pass
    t = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(tip, axis=0), axis=1))] / (FEED / 60.0)
    keep = place(p, m, rows, q, tip, t, TOL, entry_height=ENTRY_MM, entry_feed=np.array([FEED]))
    deg = np.round(np.degrees(q[keep, 3:]), 4)
    assert np.all(np.any(deg[1:] != deg[:-1], axis=1))
    assert keep.all()


def test_a_stopped_entry_is_written_with_g61_and_the_g64_line_again(blade_rows, tmp_path):
    """The nlp plan of two blade rows stops each row's entry move (its G64 P is over the
    tolerance): the LinuxCNC program has, per row, G61 right before the entry move (the row's first
    G01) and the program's G64 line right after it, and the header says so."""
    from camsmooth.smoothing.posting import write_gcode

    r = blade_rows.methods["nlp"]
    plan = r.controller
    assert plan.entry_stop and plan.blend_tolerance > TOL
    ngc = tmp_path / "blade.ngc"
    write_gcode(ngc, r, blade_rows.machine, blade_rows.cutter, FEED, tolerance=TOL)
    lines = ngc.read_text().splitlines()
    g64 = [ln for ln in lines if ln.startswith("G64 ")]
    assert g64[0] == f"G64 P{plan.blend_tolerance:.4f} Q0.0030"
    rows = [i for i, ln in enumerate(lines) if re.match(r"\(row \d+:", ln)]
    assert len(rows) == len(np.unique(r.rows)) == lines.count("G61")
    for i in rows:
        first = next(j for j in range(i, len(lines)) if lines[j].startswith("G01"))
        assert lines[first - 1] == "G61" and lines[first + 1] == g64[0], lines[i:first + 2]
    assert any("entry move ends at rest: G61 before it" in ln for ln in lines[:40])


def test_the_tip_past_the_programmed_feed_is_reported_and_held_on_request(blade_rows, capsys):
    """In a parabolic blend both blocks move, so LinuxCNC can take the tool tip faster than the
    programmed feed. For the two blade rows: the plan's row_feed_peak equals the tip's largest speed
    over the feed recomputed here (forward kinematics of the model's joints at every servo cycle
    after the entry, finite differences) and is past 1.01 somewhere; smooth's summary warns with it
    and the report's verdict line says it.
    With hold_feed every row's tip stays within the feed (0.1% for a rest stop's one-cycle step), at
    a longer cycle time."""
    from camsmooth.cli.main import _print_summary
    from camsmooth.smoothing.evaluate import time_law

    m, r = blade_rows.machine, blade_rows.methods["nlp"]
    q = _joints(r)
    feed = np.full(len(q), FEED)

    def tip_speeds(plan) -> np.ndarray:
        p = planner_for(m, TOL, r.rows, q)
        out = []
        for row in np.unique(r.rows):
            sel = np.flatnonzero(r.rows == row)
            k = sel[plan.keep[sel]]
            entry_q, entry_time = row_entry(m, q[sel[0]], ENTRY_MM, FEED)
            run, joints = p.row_run(m, q[k], plan.block_time[k[1:]], entry_q, entry_time)
            tips = fk_tips(m, np.vstack([entry_q[None, :], joints]))
            v = np.linalg.norm(np.diff(tips, axis=0), axis=1) / 1e-3 * 60.0 / FEED
            out.append(v[run.head >= 1].max())
        return np.array(out)

    free = time_law(m, r.rows, q, r.cl, feed, tolerance=TOL, plan=r.plan)
    got = tip_speeds(free.controller)
    assert got.max() > 1.01
    assert np.allclose(free.controller.row_feed_peak, np.where(got > 1.0, got, 0.0), rtol=1e-9, atol=1e-9)
    held = time_law(m, r.rows, q, r.cl, feed, tolerance=TOL, plan=r.plan, hold_feed=True)
    assert tip_speeds(held.controller).max() <= 1.001
    assert held.controller.cycle_time > free.controller.cycle_time
    _print_summary(blade_rows)
    err = capsys.readouterr().err
    fp = r.metrics.controller_feed_peak
    assert fp is not None and fp.ratio == pytest.approx(got.max(), rel=1e-6)
    assert f"take the tool tip to {fp.ratio:.3g} of the programmed feed (row {fp.row};" in err
    from camsmooth.report.smoothing import _verdict_html, method_summary

    verdict = _verdict_html(["nlp"], {"nlp": method_summary(r)}, "nlp")
    assert f"take the tool tip to {fp.ratio:.3g} of the programmed feed (row {fp.row};" in verdict
