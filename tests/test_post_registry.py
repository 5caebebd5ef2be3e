"""The post layer as one place per dialect (issue #27, item 5 of "What to build").

- The import graph: no module under camsmooth/post imports camsmooth.smoothing, camsmooth.controller,
  camsmooth.report or camsmooth.cli, at module level or inside a function (read with ``ast``), and
  neither does any camsmooth module those import at module level, transitively.
- Every dialect of the registry (camsmooth.post.DIALECTS) has a reader and writer words; a small
  program written in it (a whole program for the dialects camsmooth writes whole; the blocks of a
  rewrite inside the dialect's program frame for ISO, Haas and MillPlus) and read back by its own
  reader gives the tool tips and axes of the model written, within the written rounding
  (4 decimals of mm and of a degree). The model is built here from closed forms (the AC-table
  tool axis T = Rz(C) Rx(A) e_z, ISO 841), not from the writer's output.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pytest

import camsmooth.post as post
from camsmooth.errors import InputError
from camsmooth.machine.kinematics import machine_from_dict
from camsmooth.post.model import PostProgram
from camsmooth.post.writer import format_blocks, write_program

PACKAGE = Path(post.__file__).resolve().parent.parent
FORBIDDEN = ("camsmooth.smoothing", "camsmooth.controller", "camsmooth.report", "camsmooth.cli")


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def _imports(path: Path, top_level_only: bool) -> set[str]:
    """The camsmooth modules ``path`` imports (``import x`` and ``from x import y``: x, and x.y where
    that is a module), at module level only or anywhere in the file."""
    tree = ast.parse(path.read_text(), filename=str(path))
    nodes = tree.body if top_level_only else list(ast.walk(tree))
    if top_level_only:  # module level includes `if TYPE_CHECKING:`-free blocks such as try/if bodies
        nodes = [n for stmt in tree.body for n in ast.walk(stmt)
                 if not isinstance(stmt, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef)]
    out: set[str] = set()
    for node in nodes:
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
            out.update(f"{node.module}.{a.name}" for a in node.names)
    return {m for m in out if m == "camsmooth" or m.startswith("camsmooth.")}


def _files() -> dict[str, Path]:
    return {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _forbidden(name: str) -> bool:
    return any(name == f or name.startswith(f + ".") for f in FORBIDDEN)


def test_post_imports_neither_smoothing_nor_controller():
    files = _files()
    post_modules = sorted(m for m in files if m == "camsmooth.post" or m.startswith("camsmooth.post."))
    assert {"camsmooth.post.iso", "camsmooth.post.linuxcnc", "camsmooth.post.writer", "camsmooth.post.model",
            "camsmooth.post.own"} <= set(post_modules)
    direct = {m: sorted(i for i in _imports(files[m], top_level_only=False) if _forbidden(i)) for m in post_modules}
    assert not any(direct.values()), {m: v for m, v in direct.items() if v}
    # transitively through what they import at module level
    seen: dict[str, str] = {}
    todo = [(m, m) for m in post_modules]
    while todo:
        mod, via = todo.pop()
        if mod in seen or mod not in files:
            continue
        seen[mod] = via
        todo += [(i, f"{via} -> {i}") for i in _imports(files[mod], top_level_only=True)]
    bad = {m: v for m, v in seen.items() if _forbidden(m)}
    assert not bad, bad


def test_import_check_can_fail(tmp_path):
    """The checker sees an import inside a function and a module-level one."""
    f = tmp_path / "x.py"
    f.write_text("import numpy\n\ndef g():\n    from camsmooth.controller import predict\n    return predict\n")
    assert any(_forbidden(i) for i in _imports(f, top_level_only=False))
    assert not any(_forbidden(i) for i in _imports(f, top_level_only=True))


def test_registry_entries():
    d = post.DIALECTS
    assert {"iso", "generic", "fanuc", "haas", "linuxcnc", "heidenhain", "siemens", "millplus"} <= set(d)
    for name, e in d.items():
        assert e.name == name and callable(e.reader) and e.words is not None, name
    # the dialects a machine file's [post] names are the ones written whole
    from camsmooth.machine.kinematics import POST_DIALECTS

    assert {n for n, e in d.items() if e.own} == set(POST_DIALECTS)
    assert post.READERS == {n: e.reader for n, e in d.items()}


# ------------------------------------------------------------------------------------------------
# round trips
CENTRE = (2.0, -1.0, -15.0)


def _machine(dialect: str, mode: str):
    data = {"machine": {"name": "round trip AC table", "kind": "AC-table", "table_centre": list(CENTRE)},
            "axis": {"A": {"min": -110.0, "max": 110.0, "vmax": 60.0, "amax": 300.0},
                     "C": {"vmax": 180.0, "amax": 900.0}},
            "post": {"dialect": dialect, "mode": mode}}
    return machine_from_dict(data, "<round trip>")


def _model(machine) -> PostProgram:
    """Two rows on a saddle, the tool axis swept through A and C (closed forms, ISO 841)."""
    rows, tips, A, C = [], [], [], []
    for k in range(2):
        s = np.linspace(0.0, 1.0, 9)
        x = -20.0 + 40.0 * s ** 1.3 + 0.123456789  # not on the written grid
        y = np.full_like(s, -6.0 + 12.0 * k) + 0.3 * np.sin(3.1 * s)
        tips.append(np.column_stack([x, y, 0.01 * (x ** 2 - y ** 2)]))
        A.append(np.radians(10.0 + 15.0 * s ** 1.2 + 3.0 * k + 0.0123456789))
        C.append(np.radians(-30.0 + 70.0 * s - 5.0 * k + math.pi / 7.0))
        rows.append(np.full(len(s), k))
    A_, C_ = np.concatenate(A), np.concatenate(C)
    tip = np.concatenate(tips)
    axis = np.column_stack([np.sin(C_) * np.sin(A_), -np.cos(C_) * np.sin(A_), np.cos(A_)])  # Rz(C) Rx(A) e_z
    # the linear axes of the AC table: c + Rx(-A) Rz(-C) (tip - c), written out
    d = tip - np.asarray(CENTRE)
    cz, sz = np.cos(-C_), np.sin(-C_)
    d1 = np.column_stack([cz * d[:, 0] - sz * d[:, 1], sz * d[:, 0] + cz * d[:, 1], d[:, 2]])
    cx, sx = np.cos(-A_), np.sin(-A_)
    xyz = np.asarray(CENTRE) + np.column_stack([d1[:, 0], cx * d1[:, 1] - sx * d1[:, 2], sx * d1[:, 1] + cx * d1[:, 2]])
    assert np.allclose(machine.tool_axis_np(A_, C_), axis, atol=1e-12)  # the machine agrees with the closed form
    assert np.allclose(machine.linear_axes(tip, A_, C_), xyz, atol=1e-9)
    rows_ = np.concatenate(rows)
    idx = np.concatenate([np.arange(9), np.arange(9)])
    return PostProgram(rows=rows_, idx=idx, joints=np.column_stack([xyz, A_, C_]), tips=tip, axis=axis,
                       feed=np.full(len(rows_), 800.0), method="roundtrip", tool_text="ball end R 0.0000 mm, "
                       "r 3.0000 mm, diameter 6.0000 mm, shank n/a", n_points=len(rows_), tolerance=0.01)


#: the written rounding: 0.5e-4 mm on X Y Z and 0.5e-4 deg (8.7e-7 rad) on each angle; through the
#: table's kinematics (tips within 30 mm of the table centre) a tip component moves by at most
#: 0.5e-4 + 2 * 30 * 8.7e-7 = 1.02e-4 mm, a unit axis component by at most 2 * 8.7e-7
TIP_TOL_MM = 1.05e-4
AXIS_TOL = 1.8e-6


def _compare(prog, model: PostProgram, label: str) -> None:
    cut = ~np.asarray(prog.rapid, bool)
    assert int(cut.sum()) == len(model), (label, int(cut.sum()), len(model))
    tip_err = np.abs(prog.tip[cut] - model.tips).max()
    axis_err = np.abs(prog.axis[cut] - model.axis).max()
    assert tip_err < TIP_TOL_MM, (label, tip_err)
    assert axis_err < AXIS_TOL, (label, axis_err)
    rows = np.asarray(prog.rows)[cut]
    assert len(np.unique(rows)) == 2 and np.all(np.diff(rows) >= 0), label


COMBOS = [(n, m) for n, e in post.DIALECTS.items() for m in ("machine", "tcp")
          if e.own and not (e.words.inverse_time is None and m == "machine")
          and not (e.words.tcp_on is None and m == "tcp")]


@pytest.mark.parametrize(("dialect", "mode"), COMBOS)
def test_whole_program_round_trip(tmp_path, dialect, mode):
    """write_program in the dialect, then the dialect's own reader (and every other reader that
    shares its words, e.g. iso and haas for fanuc)."""
    machine = _machine(dialect, mode)
    model = _model(machine)
    path = post.DIALECTS[dialect].write(tmp_path / f"p_{dialect}_{mode}.nc", model, machine, mode=mode)
    text = path.read_text()
    assert text == write_program(tmp_path / "same.nc", model, machine).read_text()  # the machine's [post] the same
    readers = [n for n, e in post.DIALECTS.items() if e.words is post.DIALECTS[dialect].words]
    assert dialect in readers
    for name in readers:
        prog = post.read_posted(path, text=text, machine=machine, dialect=name)
        _compare(prog, model, f"{dialect}/{mode} read as {name}")
    assert post.detect_dialect(text) in readers or dialect == "generic"


@pytest.mark.parametrize("mode", ["machine", "tcp"])
def test_millplus_blocks_round_trip(tmp_path, mode):
    """MillPlus is written only as blocks in a MillPlus program (a rewrite): its words are the
    generic ones, F in mm/min (G93 is MillPlus's datum shift), G141 the tool-centre-point mode."""
    entry = post.DIALECTS["millplus"]
    assert not entry.own
    machine = _machine("generic", mode)
    model = _model(machine)
    q = np.degrees(model.joints[:, 3:])
    lines = ["%PM", "N9001", "G17", "T1 M6"] + (["G141"] if mode == "tcp" else [])
    for k in range(2):
        sel = model.rows == k
        pos = model.tips[sel] if mode == "tcp" else model.joints[sel, :3]
        lift = model.tips[sel][:1] + 10.0 * model.axis[sel][:1] if mode == "tcp" else \
            machine.linear_axes(model.tips[sel][:1] + 10.0 * model.axis[sel][:1], model.joints[sel, 3][:1],
                                model.joints[sel, 4][:1])
        coords = np.vstack([np.column_stack([lift, q[sel][:1]]), np.column_stack([pos, q[sel]])])
        rapid = np.r_[True, np.zeros(int(sel.sum()), bool)]
        F = np.r_[np.nan, np.full(int(sel.sum()), 800.0)]
        lines += format_blocks("millplus", coords, F, rapid, "XYZAC", inverse_time=False)
    lines += (["G40"] if mode == "tcp" else []) + ["M30"]
    text = "\n".join(lines) + "\n"
    assert all(not ln.startswith("G93") for ln in lines)
    path = tmp_path / "mp.nc"
    path.write_text(text)
    assert post.detect_dialect(text) == "millplus"
    prog = post.read_posted(path, text=text, machine=machine)
    _compare(prog, model, f"millplus/{mode}")


def test_blocks_only_dialects_refuse_whole_programs(tmp_path):
    machine = _machine("generic", "machine")
    for name in ("iso", "haas", "millplus"):
        with pytest.raises(InputError, match=f"unknown G-code dialect '{name}'"):
            post.DIALECTS[name].write(tmp_path / "x.nc", _model(machine), machine)
    assert not (tmp_path / "x.nc").exists()


def test_round_trip_can_fail(tmp_path):
    """A model moved by 3e-4 mm (beyond the written rounding) is told apart."""
    machine = _machine("fanuc", "tcp")
    model = _model(machine)
    path = write_program(tmp_path / "p.nc", model, machine)
    prog = post.read_posted(path, machine=machine, dialect="fanuc")
    shifted = PostProgram(rows=model.rows, idx=model.idx, joints=model.joints, tips=model.tips + [3e-4, 0, 0],
                          axis=model.axis, feed=model.feed)
    with pytest.raises(AssertionError):
        _compare(prog, shifted, "shifted")
    assert math.isclose(float(np.abs(prog.tip[~prog.rapid] - model.tips).max()), 0.0, abs_tol=TIP_TOL_MM)


@pytest.mark.parametrize("dialect", ["linuxcnc", "fanuc"])
def test_tcp_block_turning_about_a_standing_tip_gets_the_rotary_feed(tmp_path, dialect):
    """In TCP mode (G94) a block of given time whose tip does not move takes F as degrees per minute
    over D = sqrt(dA^2 + dC^2) (the machining-centre overview of LinuxCNC, "Feed Rate", after RS274/NGC
    3 section 2.1.2.5), not the tip's 0 mm/min, which a controller refuses; a moving tip keeps the tip
    feed chord / time. By hand: the third block turns A by 3 deg and C by 4 deg in 0.5 s:
    D = 5 deg -> F600.0; the second moves the tip 6 mm in 0.2 s -> F1800.0."""
    machine = _machine(dialect, "tcp")
    tips = np.array([[0.0, 0.0, 0.0], [6.0, 0.0, 0.0], [6.0, 0.0, 0.0], [9.0, 4.0, 0.0]])
    A = np.radians([10.0, 10.0, 13.0, 13.0])
    C = np.radians([20.0, 20.0, 24.0, 24.0])
    axis = machine.tool_axis_np(A, C)
    prog = PostProgram(rows=np.zeros(4, int), idx=np.arange(4),
                       joints=np.column_stack([machine.linear_axes(tips, A, C), A, C]), tips=tips, axis=axis,
                       feed=np.full(4, 1000.0), block_time=np.array([np.nan, 0.2, 0.5, 0.25]), tolerance=0.01)
    text = write_program(tmp_path / f"t.{dialect}.nc", prog, machine).read_text()
    cut = [ln for ln in text.splitlines() if ln.startswith("G01")][-3:]  # the row's three blocks
    fs = [float(ln.split(" F")[1].split()[0]) if " F" in ln else None for ln in cut]
    assert fs[0] == pytest.approx(1800.0)
    assert fs[1] == pytest.approx(600.0)  # 5 deg in 0.5 s, never F0
    assert fs[2] == pytest.approx(60.0 * 5.0 / 0.25)  # the tip moves 5 mm in 0.25 s
    assert all(f is None or f > 0 for f in fs)
