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

from camsmooth.controller import EXECUTED_TOLERANCE_SHARE, decimate, place, planner_for, predict, vertex_shift
from camsmooth.controller.blocks import (
    BLOCK_TOLERANCE_SHARE,
    VERTEX_SHIFT_SHARE,
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


def _brute_floor(m, q, tip, ok, feed_mm_s, slack: float = 0.0):
    """The floor's definition, by every choice of block ends of one row: each block lasts at least
    its tip chord over the feed, its largest joint move over that joint's speed, and (when it turns
    a rotary axis) sqrt(2 max_i |d_i| / a_i), the parabolic blend at half the acceleration; with
    block ends up to ``slack`` mm off the points, the chord and the linear moves 2 slack shorter."""
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
            d[:3] = np.maximum(d[:3] - 2 * slack, 0.0)
            rest = np.sqrt(2 * np.max(d / amax)) if d[3:].max() > 0 else 0.0
            total += max((np.linalg.norm(tip[j] - tip[i]) - 2 * slack) / feed_mm_s, np.max(d / vmax), rest)
        best = min(best, total)
    return best


def test_the_floor_is_the_least_time_over_every_choice_of_block_ends_and_below_the_prediction():
    """The controller plan's floor (what ``smooth`` prints) on two short rows: per row the least
    floor cost over all 2^(n-2) choices of block ends (brute force of the definition, the blocks
    the tolerance plus the program's end offset allows), below the time the planner model predicts
    for the program camsmooth writes; with no offset, the same by brute force through the points."""
    from camsmooth.smoothing.evaluate import time_law

    m = _machine()
    rows, q, tip = _short_rows(m)
    law = time_law(m, rows, q, tip, np.full(len(rows), FEED), tolerance=TOL)
    ctrl = law.controller
    assert ctrl is not None and ctrl.row_floor is not None
    e = ctrl.end_offset
    assert 0 < e <= VERTEX_SHIFT_SHARE * TOL + 1e-12
    through = planner_for(m, TOL, rows, q).row_floor(m, rows, q, tip, np.full(len(rows), FEED), TOL)
    for r in range(2):
        sel = rows == r
        one = np.zeros(sel.sum(), int)
        ok = block_reach(m, one, q[sel], tip[sel], TOL + e, 64)
        assert ctrl.row_floor[r] == pytest.approx(_brute_floor(m, q[sel], tip[sel], ok, FEED / 60.0, e), rel=1e-12)
        assert ctrl.row_floor[r] < ctrl.row_cycle_time[r]
        ok = block_reach(m, one, q[sel], tip[sel], TOL, 64)
        assert through[r] == pytest.approx(_brute_floor(m, q[sel], tip[sel], ok, FEED / 60.0), rel=1e-12)
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
    tolerance (the placement before), through the points as with their ends moved off them
    (vertex_shift, which the pipeline writes: fewer blocks, run sooner), and the model's tool tip,
    recomputed here from the written blocks and times at every servo cycle, stays within
    EXECUTED_TOLERANCE_SHARE of the tolerance of the path the full-density program commands
    (through the points)."""
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
        kw = dict(entry_height=ENTRY_MM, entry_feed=entry_feed)
        through = predict(p, m, r.rows, q, r.cl, r.plan.t_plan, place(p, m, r.rows, q, r.cl, r.plan.t_plan, TOL, **kw),
                          tolerance=TOL, **kw)
        sh = vertex_shift(m, r.rows, q, r.cl, TOL)
        new = predict(p, m, r.rows, q, r.cl, r.plan.t_plan,
                      place(p, m, r.rows, q, r.cl, r.plan.t_plan, TOL, shift=sh, **kw), tolerance=TOL, shift=sh, **kw)
        assert np.allclose(new.row_cycle_time, c.row_cycle_time)  # the pipeline's blocks are these
        assert np.all(new.row_cycle_time <= old.row_cycle_time + 1e-9), (name, new.row_cycle_time, old.row_cycle_time)
        assert np.all(through.row_cycle_time <= old.row_cycle_time + 1e-9)
        # the ends off the points: fewer blocks, sooner than the best placement through the points
        assert new.blocks < through.blocks and new.cycle_time < through.cycle_time, name
        written = q + c.joint_shift
        for rid in c.row_ids:
            sel = np.flatnonzero(r.rows == rid)
            k = sel[c.keep[sel]]
            entry_q, entry_time = row_entry(m, q[sel[0]], ENTRY_MM, FEED)
            path = programmed_tip_path(m, q[sel], fk_tips(m, entry_q[None])[0])
            _, joints = p.row_run(m, written[k], c.block_time[k[1:]], entry_q, entry_time)
            assert tip_deviation(fk_tips(m, joints), path).max() <= EXECUTED_TOLERANCE_SHARE * TOL + 1e-6, name


def test_smooth_prints_the_floor_beside_the_prediction(blade_rows, capsys):
    """``smooth``'s summary line per method: 'LinuxCNC cannot run straight blocks with their ends
    within E um of these points in less than X s; this program: Y s', E the largest distance of a
    written block end's tip from its point (recomputed by forward kinematics), X the floor for
    such programs recomputed here (least_row_times with that end offset, at the programmed feed),
    Y the predicted time, X <= Y; the floor through the points (no offset) is above X, and the
    report's row table carries the floor per row."""
    from camsmooth.cli.main import _print_floor
    from camsmooth.controller.linuxcnc import least_row_times
    from camsmooth.report.smoothing import _rows_html

    _print_floor(blade_rows)
    out = capsys.readouterr().out
    m = blade_rows.machine
    for name, r in blade_rows.methods.items():
        got = re.search(rf"^{name}: LinuxCNC cannot run straight blocks with their ends within ([\d.]+) um of these "
                        r"points in less than ([\d.e+-]+) s; this program: ([\d.e+-]+) s", out, re.M)
        assert got, out
        off_um, floor, program = (float(got.group(i)) for i in (1, 2, 3))
        q, keep = _joints(r), r.controller.keep
        moved = np.linalg.norm(fk_tips(m, (q + r.controller.joint_shift)[keep]) - fk_tips(m, q[keep]), axis=1).max()
        assert off_um == pytest.approx(1e3 * moved, abs=0.051) and 0 < moved <= VERTEX_SHIFT_SHARE * TOL + 1e-9
        want = least_row_times(m, r.rows, q, r.cl, np.full(len(r.rows), FEED), TOL, end_offset=moved)
        assert floor == pytest.approx(want.sum(), rel=1e-3)
        assert program == pytest.approx(r.metrics.cycle_time_s, rel=1e-3)
        assert floor <= program
        assert least_row_times(m, r.rows, q, r.cl, np.full(len(r.rows), FEED), TOL).sum() > floor
        assert np.allclose(r.metrics.row_controller_floor_s, want)
    html = _rows_html(blade_rows.methods["nlp"], tuple(m.rotary))
    off = blade_rows.methods["nlp"].metrics.controller_end_offset_mm
    assert f"least time on linuxcnc, any straight blocks, ends within {1e3 * off:.2g} \u00b5m of the points" in html
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
    said = [ln for ln in lines[:40] if "block ends up to" in ln]
    assert said == [f"(block ends up to {1e3 * plan.end_offset:.2g} um off the path's points, to the outside of its "
                    "curve and inside the tolerance [the tool axes as planned])"]


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
            run, joints = p.row_run(m, (q + plan.joint_shift)[k], plan.block_time[k[1:]], entry_q, entry_time)
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


def _arc_row(m, radius: float, step: float, n: int, rot: tuple[float, float]):
    """One row whose tool tips lie on a circle of ``radius`` mm in the XZ plane (centre below the
    first tip), ``step`` rad apart, the rotary axes held at ``rot`` (rad): every block's tip curve
    is then a straight chord."""
    phi = step * (np.arange(n) - (n - 1) / 2)
    tip = np.column_stack([radius * np.sin(phi), np.zeros(n), radius * np.cos(phi) - radius])
    A, B = np.full(n, rot[0]), np.full(n, rot[1])
    return np.zeros(n, int), np.column_stack([m.linear_axes(tip, A, B), A, B]), tip, phi


@pytest.mark.parametrize("machine_file", [None, "dome_machine.toml"])
def test_block_ends_move_out_by_half_the_sagitta_up_to_their_share_of_the_tolerance(machine_file):
    """vertex_shift on a circular tip path with the rotary axes held (head and A/C table): each
    inner point's tip moves radially outward by min(VERTEX_SHIFT_SHARE x T, half the sagitta of the
    chord from h points before it to h after, h = min(4, points to the row's ends)), the closed form
    R (1 - cos(h step)) / 2, checked by forward kinematics of the shifted joints; the rotary axes
    and the row's ends do not move."""
    from camsmooth.machine.kinematics import load_machine

    root = Path(__file__).resolve().parent.parent / "surfaces"
    m = _machine() if machine_file is None else load_machine(str(root / machine_file))
    R, step, n = 200.0, 0.002, 30
    rows, q, tip, phi = _arc_row(m, R, step, n, (np.radians(-20.0), np.radians(35.0)))
    sh = vertex_shift(m, rows, q, tip, TOL)
    assert np.all(sh[:, 3:] == 0) and np.all(sh[[0, -1]] == 0)
    h = np.minimum(4, np.minimum(np.arange(n), n - 1 - np.arange(n)))[1:-1]
    size = np.minimum(VERTEX_SHIFT_SHARE * TOL, 0.5 * R * (1 - np.cos(h * step)))
    assert size.min() < VERTEX_SHIFT_SHARE * TOL == size.max()  # both branches
    outward = np.column_stack([np.sin(phi), np.zeros(n), np.cos(phi)])[1:-1]
    moved = fk_tips(m, q + sh)[1:-1] - tip[1:-1]
    assert np.allclose(moved, size[:, None] * outward, atol=1e-9)


def test_with_the_ends_moved_out_a_block_spans_what_the_closed_form_allows():
    """block_reach on the circular tip path, every block's ends moved out by d (vertex_shift, the
    whole share) or not at all: the longest block from each inner point is the largest k for
    which every skipped tip (radius R, at angles i step from the block's start) and every skipped
    interval's middle (radius R cos(step / 2)) lies within the tolerance of the chord between the
    moved ends, whose line is (R + d) cos(k step / 2) from the centre: |rho cos(angle from the
    block's middle) - (R + d) cos(k step / 2)|. With the ends moved out the blocks are longer."""
    m = _machine()
    R, step, n = 200.0, 0.002, 40
    rows, q, tip, _ = _arc_row(m, R, step, n, (0.0, np.radians(10.0)))
    tol = BLOCK_TOLERANCE_SHARE * TOL
    sh = vertex_shift(m, rows, q, tip, TOL)
    d = VERTEX_SHIFT_SHARE * TOL

    def closed_form(dd: float) -> int:
        best = 1
        for k in range(2, 17):
            ang = np.r_[np.arange(1, k), np.arange(k) + 0.5] * step - k * step / 2
            rho = np.r_[np.full(k - 1, R), np.full(k, R * np.cos(step / 2))]
            if np.abs(rho * np.cos(ang) - (R + dd) * np.cos(k * step / 2)).max() > tol:
                break
            best = k
        return best

    inner = np.arange(8, 16)  # blocks whose ends all move by the whole share (4 points from the row's ends)
    for shift, dd in ((None, 0.0), (sh, d)):
        reach = block_reach(m, rows, q, tip, tol, shift=shift).sum(axis=1)
        assert np.all(reach[inner] == closed_form(dd)), (dd, reach[inner], closed_form(dd))
    assert closed_form(d) > closed_form(0.0)


@pytest.mark.parametrize("last_deg, step_s", [(10.5, 0.05), (9.0, 0.3)])
def test_the_blend_into_a_rows_last_block_is_held_within_the_joints_amax(last_deg, step_s):
    """LinuxCNC blends a row's last block at its whole acceleration into the block before's
    deceleration at half of it, so B can go past its amax there (B turning 2 deg per block, then
    0.5 deg more or 1 deg back). The plan's block times, run here through the planner model from
    the row's entry at rest, keep every joint's acceleration (second differences over 5 servo
    cycles, as the plan's row_joint_peak) within 0.5% of its amax, and the plan says so; the
    time-optimal law's block times, run the same way, do not (the hold does work)."""
    m = _machine()
    n = 7
    tip = np.column_stack([np.linspace(0.0, 6.0, n), np.zeros(n), np.zeros(n)])
    rot = np.column_stack([np.zeros(n), np.radians([0, 2, 4, 6, 8, 10, last_deg])])
    q = np.column_stack([m.linear_axes(tip, rot[:, 0], rot[:, 1]), rot])
    rows, t = np.zeros(n, int), np.arange(n) * step_s
    p = planner_for(m, TOL, rows, q)
    c = predict(p, m, rows, q, tip, t, np.ones(n, bool), entry_height=ENTRY_MM, entry_feed=np.array([FEED]),
                tolerance=TOL)
    amax = axis_limits(m)[1]
    entry_q, entry_time = row_entry(m, q[0], ENTRY_MM, FEED)

    def peak(block_time: np.ndarray) -> float:
        _, joints = p.row_run(m, q, block_time, entry_q, entry_time)
        w = np.vstack([np.repeat(entry_q[None], 5, axis=0), joints, np.repeat(joints[-1:], 5, axis=0)])
        return float((np.abs(w[10:] - 2 * w[5:-5] + w[:-10]) / (5 * p.servo_period) ** 2 / amax).max())

    assert peak(c.block_time[1:]) <= 1.005
    assert c.row_joint_peak.max() <= 1.005
    assert peak(np.diff(t)) > 1.01


def test_each_row_takes_the_sooner_of_its_blocks_off_and_through_the_points():
    """through_points_where_sooner on two plans of the same three rows, by hand: the row the plan
    through the points runs sooner (row 1) takes its blocks and no shift, the others keep the
    blocks and the shift off the points; a tie keeps the ends off; None where no row is sooner."""
    from types import SimpleNamespace

    from camsmooth.controller.blocks import through_points_where_sooner

    rows = np.repeat([4, 7, 9], 3)
    shift = np.zeros((9, 5))
    shift[:, 0] = np.arange(1, 10)
    off = SimpleNamespace(row_cycle_time=np.array([1.0, 2.0, 3.0]), keep=np.array([1, 0, 1, 1, 0, 1, 1, 0, 1], bool))
    through = SimpleNamespace(row_cycle_time=np.array([1.5, 1.9, 3.0]), keep=np.ones(9, bool))
    keep, used = through_points_where_sooner(rows, shift, off, through)
    assert keep.tolist() == [1, 0, 1, 1, 1, 1, 1, 0, 1]
    assert used[:, 0].tolist() == [1, 2, 3, 0, 0, 0, 7, 8, 9] and not used[:, 1:].any()
    slower = SimpleNamespace(row_cycle_time=np.array([1.5, 2.5, 3.5]), keep=through.keep)
    assert through_points_where_sooner(rows, shift, off, slower) is None


def test_the_written_rows_run_no_later_than_their_blocks_off_or_through_the_points(blade_rows):
    """The pipeline's plan of the nlp blade rows (plan_blocks): per row no later on the model than
    the blocks placed off the points and the blocks placed through them, each timed here."""
    r, m = blade_rows.methods["nlp"], blade_rows.machine
    q = _joints(r)
    p = planner_for(m, TOL, r.rows, q)
    kw = dict(entry_height=ENTRY_MM, entry_feed=np.full(len(r.controller.row_ids), FEED))
    feed = np.full(len(q), FEED)
    for s in (vertex_shift(m, r.rows, q, r.cl, TOL), None):
        keep = place(p, m, r.rows, q, r.cl, r.plan.t_plan, TOL, shift=s, **kw)
        alone = predict(p, m, r.rows, q, r.cl, r.plan.t_plan, keep, tolerance=TOL, feed=feed, shift=s, **kw)
        assert np.all(r.controller.row_cycle_time <= alone.row_cycle_time + 1e-9)


@pytest.mark.parametrize("machine_file", [None, "dome_machine.toml"])
def test_a_rows_entry_starts_where_the_writer_puts_it(machine_file):
    """row_entry on the AB head and the A/C table, the table tilted by 70 deg: the entry's tool tip
    is the row's first tip 10 mm up its tool axis (the writer's retract pose, the angles held), by
    forward kinematics, and the move takes 10 mm over the feed."""
    from camsmooth.machine.kinematics import load_machine

    root = Path(__file__).resolve().parent.parent / "surfaces"
    m = _machine() if machine_file is None else load_machine(str(root / machine_file))
    q = np.array([6.3, -11.5, 27.7, np.radians(-70.0), np.radians(35.0)])
    entry, t = row_entry(m, q, ENTRY_MM, FEED)
    tip, axis = m.tool_pose_np(q[3], q[4], q[0], q[1], q[2])
    want = np.asarray(tip, float).ravel() + ENTRY_MM * np.asarray(axis, float).ravel()
    assert np.allclose(fk_tips(m, entry[None])[0], want, atol=1e-9)
    assert np.array_equal(entry[3:], q[3:]) and t == pytest.approx(60.0 * ENTRY_MM / FEED)
