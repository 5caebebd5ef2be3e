"""A smoothing result handed to the post layer (camsmooth.smoothing.posting): the points a controller
plan keeps are the blocks, the header counts the method's points (so that ``read_gcode`` tells a
decimated program from a whole one), the plan's block times are the G93 F words (F = 60 / block time
in 1/min, written with 7 significant digits)."""

from __future__ import annotations

import re
from types import SimpleNamespace

import numpy as np

from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import machine_from_dict
from camsmooth.post.own import read_gcode
from camsmooth.smoothing.posting import post_program, write_gcode

CUTTER = SimpleNamespace(R=0.0, r=3.0, kind="ball", diameter=6.0)
BLOCK_S = 0.0731


def _machine():
    axes = {a: {"min": -110.0, "max": 110.0, "vmax": 60.0, "amax": 300.0} for a in ("A", "B")}
    return machine_from_dict({"machine": {"name": "posting AB head", "kind": "AB-head", "pivot": 150.0},
                              "axis": axes, "post": {"dialect": "fanuc", "mode": "machine"}}, "<posting>")


def _result(machine, controller: bool):
    """Two rows of 12 points; A, B from the closed form of the AB head's axis T = (sin B, -sin A cos B,
    cos A cos B); with ``controller`` a plan that keeps every third point and each row's ends."""
    rows = np.repeat([0, 1], 12)
    idx = np.r_[np.arange(12), np.arange(12)]
    s = np.r_[np.linspace(0, 1, 12), np.linspace(0, 1, 12)]
    A = np.radians(5.0 + 10.0 * s + 2.0 * rows)
    B = np.radians(-8.0 + 16.0 * s)
    T = np.column_stack([np.sin(B), -np.sin(A) * np.cos(B), np.cos(A) * np.cos(B)])
    cl = np.column_stack([-15.0 + 30.0 * s, 6.0 * rows - 3.0, 0.2 * np.sin(3 * s)])
    xyz = cl + 150.0 * T  # pivot = CL + L_p T (METHODS section 1)
    t = 0.05 * idx
    r = SimpleNamespace(rows=rows, idx=idx, cl=cl, axis=T, rotary=RotaryValues.of(("A", "B"), A, B), xyz=xyz, t=t,
                        method="nlp", metrics=None,
                        plan=SimpleNamespace(t_plan=0.04 * idx), controller=None)
    if controller:
        ends = np.r_[True, rows[1:] != rows[:-1]] | np.r_[rows[1:] != rows[:-1], True]
        keep = (idx % 3 == 0) | ends
        r.controller = SimpleNamespace(keep=keep, block_time=np.full(len(rows), BLOCK_S))
    return r


def test_controller_plan_blocks_and_header(tmp_path):
    machine = _machine()
    r = _result(machine, controller=True)
    keep = r.controller.keep
    prog = post_program(r, CUTTER, 600.0)
    assert len(prog) == int(keep.sum()) == 10 and prog.n_points == 24
    assert np.array_equal(prog.idx, r.idx[keep]) and np.allclose(prog.tips, r.cl[keep])
    assert np.allclose(prog.t_opt, 0.04 * r.idx[keep]) and np.allclose(prog.block_time, BLOCK_S)
    path = write_gcode(tmp_path / "c.nc", r, machine, CUTTER, 600.0)
    text = path.read_text()
    assert "(method: nlp, 24 points)" in text
    back = read_gcode(path, machine)
    assert back.written is not None and back.written.every_point is False
    # G93 F words: 60 / the plan's block time on every cut block but each row's entry (its feed decides)
    f_words = [float(m.group(1)) for m in re.finditer(r"^G01 .* F(\d+\.\d+)", text, re.M)]
    assert len(f_words) == 10
    entry = [0, 5]  # rows of 5 kept points each
    assert all(abs(f - 60.0 / BLOCK_S) < 5e-5 * (60.0 / BLOCK_S) for k, f in enumerate(f_words) if k not in entry)
    assert not np.isclose(f_words[0], 60.0 / BLOCK_S, rtol=1e-3)


def test_every_point_without_a_controller(tmp_path):
    machine = _machine()
    r = _result(machine, controller=False)
    prog = post_program(r, CUTTER, 600.0)
    assert len(prog) == prog.n_points == 24
    # the planned law's step between consecutive points of a row, nan at a row's start
    expect = np.where(np.r_[False, r.rows[1:] == r.rows[:-1]], 0.04, np.nan)
    assert np.allclose(prog.block_time, expect, equal_nan=True)
    path = write_gcode(tmp_path / "w.nc", r, machine, CUTTER, 600.0)
    assert "(method: nlp, 24 points)" in path.read_text()
    assert read_gcode(path, machine).written.every_point is True
