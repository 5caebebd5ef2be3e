"""The pipeline's bookkeeping (camsmooth.smoothing.pipeline, no NLP): feed and time stamps of a
prepared program, how points are named, what a method's result carries (the tool tips with any
lift along the normal, the clearance checked at those tips, the linear axes at the pivot, the
rates of A, B and the tool axis in the right fields), and the linear axes that put a modelled
machine's tip on target, each against an independent computation."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.geometry.clearance import clearance
from camsmooth.geometry.cutter import cc_to_cl
from camsmooth.geometry.paths import CCPath
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import load_machine
from camsmooth.machine.model import ErrorModel
from camsmooth.smoothing.nlp import program_rates
from camsmooth.smoothing.pipeline import prepare
from tests.test_oracles import _counter_setup


@pytest.fixture(scope="module")
def setup():
    return _counter_setup()


def _path_without(program, **drop):
    p = program.path
    kw = dict(points=p.points, normals=p.normals, rows=p.rows, feed_dirs=p.feed_dirs, feed=p.feed, source="p.csv")
    kw.update(drop)
    return CCPath(**kw)


def test_feed_times_and_names_of_a_prepared_program(setup):
    sm, program, _, _ = setup
    lead, tilt = (np.radians(2.0), np.radians(25.0)), (np.radians(-15.0), np.radians(15.0))
    idx = sm.index
    cutter = sm.cutter
    # points 1 mm apart along each row: at 600 mm/min one step is 0.1 s, t restarts at 0 per row
    p = prepare(_path_without(program, feed=None, feed_dirs=None), idx, cutter, 600.0, lead, tilt)
    rows = program.path.rows
    for r in np.unique(rows):
        s = rows == r
        np.testing.assert_allclose(p.t[s], 0.1 * np.arange(s.sum()), rtol=1e-12, atol=1e-15)
        assert p.idx[s].tolist() == list(range(s.sum()))
    assert np.all(p.feed == 600.0)
    # feed directions estimated from the point order: along +x, as given in the original path
    np.testing.assert_allclose(p.frames[:, :, 0], np.tile([1.0, 0.0, 0.0], (len(p), 1)), atol=1e-12)
    k = int(np.flatnonzero(rows == 3)[2])
    assert p.name(k) == "row 3, point 2"
    assert prepare(_path_without(program, feed=None), idx, cutter, 0.5, lead, tilt).feed[0] == 0.5
    for feed, message in ((None, "no feed: give --feed (mm/min) or a 'feed' column in the path CSV"),
                          (0.0, "--feed must be a positive number of mm/min, got 0.0"),
                          (-5.0, "--feed must be a positive number of mm/min, got -5.0"),
                          (float("nan"), "--feed must be a positive number of mm/min, got nan")):
        with pytest.raises(InputError) as exc:
            prepare(_path_without(program, feed=None), idx, cutter, feed, lead, tilt)
        assert str(exc.value) == message
    # the path's own feed column wins over --feed
    assert np.all(prepare(program.path, idx, cutter, 1.0, lead, tilt).feed == 6000.0)


def test_result_carries_lifted_tips_their_clearance_and_the_rates(setup):
    sm, program, A, B = setup
    n = len(A)
    lift = np.zeros(n)
    lift[[2, 9]] = [0.25, 0.5]
    with sm:
        q = RotaryValues.of(sm.nominal.rotary, A, B)
        r = sm._result("spline", q, delta=None, lift=lift, unreachable=np.array([4]), runtime=0.5)
    T = sm.real.tool_axis_np(A, B)
    nrm = program.path.normals
    cl = cc_to_cl(sm.cutter, program.path.points, nrm, T) + lift[:, None] * nrm
    np.testing.assert_allclose(r.cl, cl, atol=1e-12)
    np.testing.assert_allclose(r.delta, clearance(sm.index, sm.cutter, cl, T).delta, atol=1e-9)
    np.testing.assert_allclose(r.xyz, cl + sm.nominal.pivot * T, atol=1e-9)
    assert r.method == "spline" and r.cc is program.path.points and r.normals is nrm
    np.testing.assert_array_equal(r.feed_dirs, program.frames[:, :, 0])
    ra, rb, rt = (program_rates(q, program.t, program.path.rows) for q in (A, B, T))
    np.testing.assert_array_equal(r.rotary_vel["A"], ra.vel)
    np.testing.assert_array_equal(r.rotary_vel["B"], rb.vel)
    np.testing.assert_array_equal(r.rotary_acc["A"], ra.acc)
    np.testing.assert_array_equal(r.rotary_acc["B"], rb.acc)
    np.testing.assert_allclose(r.compound_acc, np.linalg.norm(rt.acc, axis=1), rtol=1e-15)
    assert r.metrics.gamma == pytest.approx(float(np.sum(rt.sec ** 2)), rel=1e-15)
    assert r.metrics.unreachable == [(int(program.path.rows[4]), int(program.idx[4]))]
    assert r.metrics.runtime_s == 0.5
    # given tool tips (a CAM program's own) are used as they are, lifted along the normal
    tips = cl - lift[:, None] * nrm + np.array([0.0, 0.0, 3.0])
    with sm:
        q = RotaryValues.of(sm.nominal.rotary, A, B)
        r2 = sm._result("cam", q, delta=None, lift=lift, unreachable=np.zeros(0, int), runtime=0.0, cl=tips)
    np.testing.assert_allclose(r2.cl, tips + lift[:, None] * nrm, atol=1e-12)


def test_linear_axes_put_a_modelled_tip_on_target():
    machine = load_machine()
    real = ErrorModel({"EC0Y": 2e-3, "EB0Z": -1e-3, "EXX": 5e-4, "EY0A": 0.05}).apply(machine)
    rng = np.random.default_rng(5)
    A, B = rng.uniform(-0.5, 0.5, 6), rng.uniform(-0.5, 0.5, 6)
    tip = rng.uniform(-50, 50, (6, 3))
    xyz = real.linear_axes(tip, A, B)
    np.testing.assert_allclose(real.tool_pose_np(A, B, *xyz.T)[0], tip, atol=1e-9)
    # on the nominal machine it is the pivot placement
    T = machine.tool_axis_np(A, B)
    np.testing.assert_allclose(machine.linear_axes(tip, A, B), tip + machine.pivot * T, atol=1e-9)
