"""The machine TOML file (camsmooth.machine.kinematics: load_machine, machine_from_dict,
post_from_dict): what a good file means (degrees in, radians out; the documented defaults) and the
exact message and file of every refusal -- one message per mistake, naming the table and the key."""

from __future__ import annotations

import copy
import math
import tomllib

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, load_machine, machine_from_dict

BASE = {"machine": {"kind": "AB-head", "pivot": 120.0},
        "axis": {"A": {"min": -90.0, "max": 45.0, "vmax": 30.0, "amax": 200.0},
                 "B": {"min": -30.0, "max": 60.0, "vmax": 40.0, "amax": 100.0, "jmax": 900.0}}}


def _with(path: str, value):
    """BASE with the dotted key set to value (None deletes it)."""
    data = copy.deepcopy(BASE)
    *parents, last = path.split(".")
    t = data
    for p in parents:
        t = t.setdefault(p, {})
    if value is None:
        del t[last]
    else:
        t[last] = value
    return data


def test_degrees_in_the_file_are_radians_in_the_machine_and_defaults_fill_the_rest():
    m = machine_from_dict(BASE, "m.toml")
    assert (m.name, m.kind, m.pivot) == ("AB head", "AB-head", 120.0)
    a, b = m.limits["A"], m.limits["B"]
    assert (a.min, a.max, a.vmax, a.amax) == pytest.approx(
        (-math.pi / 2, math.pi / 4, math.pi / 6, 200 * math.pi / 180), rel=1e-15)
    assert a.jmax == pytest.approx(5000.0 * math.pi / 180, rel=1e-15)   # rotary jmax default, deg/s^3
    assert b.jmax == pytest.approx(900.0 * math.pi / 180, rel=1e-15)
    for ax in "XYZ":   # no table: unlimited travel, the documented linear dynamics (mm/s, mm/s^2, mm/s^3)
        lim = m.limits[ax]
        assert (lim.min, lim.max, lim.vmax, lim.amax, lim.jmax) == (-math.inf, math.inf, 500.0, 3000.0, 50000.0)
    # a linear table gives travel in mm as written and overrides only the dynamics it names
    m = machine_from_dict(_with("axis.Y", {"min": -5.0, "max": 7.0, "amax": 10.0}))
    y = m.limits["Y"]
    assert (y.min, y.max, y.vmax, y.amax, y.jmax) == (-5.0, 7.0, 500.0, 10.0, 50000.0)
    assert type(m.pivot) is float and machine_from_dict(_with("machine.pivot", 0)).pivot == 0.0
    # the nominal chain: tip at (0, 0, -pivot) when every axis is at 0 (METHODS section 1)
    tip, axis = m.tool_pose_np(0.0, 0.0, 0.0, 0.0, 0.0)
    np.testing.assert_array_equal(tip, [0.0, 0.0, -120.0])
    np.testing.assert_array_equal(axis, [0.0, 0.0, 1.0])


def test_post_table_values_and_defaults():
    assert machine_from_dict(BASE).post == type(machine_from_dict(BASE).post)("generic", "machine", 1, None, None)
    p = machine_from_dict(_with("post", {"dialect": "heidenhain", "mode": "tcp", "tool": 0,
                                         "tcp_on": "  M128 ", "tcp_off": "M129"})).post
    assert (p.dialect, p.mode, p.tool, p.tcp_on, p.tcp_off) == ("heidenhain", "tcp", 0, "M128", "M129")


MACHINE_KEYS = "name, kind, pivot, table_centre, table, head, gauge)"
KINDS = '"AB-head", "AC-table", "BC-table", "BC-head-table"; or describe the chain with table, head and gauge)'


@pytest.mark.parametrize("path,value,message", [
    ("machine", None, "missing [machine] table"),
    ("machine", 3, "machine = 3: [machine] must be a table, not a value"),
    ("machine.kind", None, '[machine] kind = missing is not supported (supported: ' + KINDS),
    ("machine.kind", "AC-trunnion", '[machine] kind = "AC-trunnion" is not supported (supported: ' + KINDS),
    ("machine.kind", True, '[machine] kind = true is not supported (supported: ' + KINDS),
    ("machine.kind", False, '[machine] kind = false is not supported (supported: ' + KINDS),
    ("machine.pivot", None, "missing key 'pivot' in [machine]"),
    ("machine.pivot", "150", '[machine] pivot must be a finite number, got "150"'),
    ("machine.pivot", True, "[machine] pivot must be a finite number, got true"),
    ("machine.pivot", [1.0], "[machine] pivot must be a finite number, got an array"),
    ("machine.pivot", {"mm": 1.0}, "[machine] pivot must be a finite number, got a table"),
    ("machine.pivot", math.inf, "[machine] pivot must be a finite number, got inf"),
    ("machine.pivot", -0.5, "[machine] pivot must be >= 0 mm, got -0.5"),
    ("machine.name", 7, "[machine] name must be a string, got 7"),
    ("axis", "none", "axis = \"none\": [axis] must be a table, not a value"),
    ("axis", None, "missing [axis.A] table"),
    ("axis.C", {"min": 0.0}, "unknown axis table(s) C (an AB-head machine has A, B, X, Y, Z)"),
    ("axis.W", {"min": 0.0}, "unknown axis table(s) C, W (an AB-head machine has A, B, X, Y, Z)"),
    ("axis.A", None, "missing [axis.A] table"),
    ("axis.B", 1.5, "[axis] B = 1.5: [axis.B] must be a table, not a value"),
    ("axis.A.speed", 1.0, "unknown key(s) speed in [axis.A] (known: min, max, vmax, amax, jmax)"),
    ("axis.A", {"min": 0.0, "max": 1.0, "vmax": 1.0, "amax": 1.0, "v": 1, "a": 2},
     "unknown key(s) a, v in [axis.A] (known: min, max, vmax, amax, jmax)"),
    ("axis.A.vmax", None, "missing key 'vmax' in [axis.A]"),
    ("axis.A.jmax", "fast", '[axis.A] jmax must be a finite number, got "fast"'),
    ("axis.A.min", 45.0, "[axis.A] min 45 must be below max 45"),
    ("axis.B.amax", 0.0, "[axis.B] amax must be > 0, got 0"),
    ("axis.B.jmax", -1.0, "[axis.B] jmax must be > 0, got -1"),
    ("axis.Z", {"min": 0.0, "max": -1.0}, "[axis.Z] min 0 must be below max -1"),
    ("axis.Z", {"min": 2.0, "max": 2.0}, "[axis.Z] min 2 must be below max 2"),
    ("axis.X", {"min": 0.0}, "missing key 'max' in [axis.X]"),
    ("axis.X", {"max": 0.0}, "missing key 'min' in [axis.X]"),
    ("axis.X", 5.0, "[axis] X = 5.0: [axis.X] must be a table, not a value"),
    ("axis.X", {"min": 0.0, "max": 1.0, "vmax": "fast"}, '[axis.X] vmax must be a finite number, got "fast"'),
    ("axis.Y", {"min": 0.0, "max": 1.0, "vmax": -2.0}, "[axis.Y] vmax must be > 0, got -2"),
    ("axis.Y", {"min": 0.0, "max": 1.0, "accel": 2.0},
     "unknown key(s) accel in [axis.Y] (known: min, max, vmax, amax, jmax)"),
    ("posts", {"dialect": "fanuc"}, "unknown table(s) [posts] (known: [machine], [axis], [post])"),
    ("machin", {"kind": "AB-head"}, "unknown table(s) [machin] (known: [machine], [axis], [post])"),
    ("pivot", 150.0, "unknown table(s) pivot = 150.0 (known: [machine], [axis], [post])"),
    ("machine.pivto", 150.0, "unknown key(s) pivto in [machine] (known: " + MACHINE_KEYS),
    ("machine.post", {"dialect": "fanuc"}, "unknown key(s) post in [machine] (known: " + MACHINE_KEYS),
    ("axis.Q", {"min": 0.0}, "unknown axis table(s) Q (an AB-head machine has A, B, X, Y, Z)"),
    ("post", "fanuc", "[post] must be a table"),
    ("post", {"dialect": "fanuc", "colour": 1, "brand": 2},
     "unknown key(s) ['brand', 'colour'] in [post] (known: dialect, mode, tool, tcp_on, tcp_off)"),
    ("post", {"dialect": "mazak"}, "[post] dialect = 'mazak' is not supported (supported: 'generic', "
                                   "'linuxcnc', 'fanuc', 'heidenhain', 'siemens')"),
    ("post", {"mode": "rtcp"}, "[post] mode = 'rtcp' is not supported (supported: 'machine', 'tcp')"),
    ("post", {"tool": True}, "[post] tool must be an integer >= 0, got True"),
    ("post", {"tool": 1.0}, "[post] tool must be an integer >= 0, got 1.0"),
    ("post", {"tool": -1}, "[post] tool must be an integer >= 0, got -1"),
    ("post", {"tcp_on": "   "}, "[post] tcp_on must be one line of text, got '   '"),
    ("post", {"tcp_off": "M1\nM2"}, "[post] tcp_off must be one line of text, got 'M1\\nM2'"),
    ("post", {"tcp_off": 129}, "[post] tcp_off must be one line of text, got 129"),
])
def test_every_mistake_has_one_message_naming_table_and_key(path, value, message):
    data = _with(path, value)
    if path == "axis.W":
        data["axis"]["C"] = {}
    with pytest.raises(InputError) as exc:
        machine_from_dict(data, "m.toml")
    assert exc.value.message == message
    assert exc.value.file == "m.toml"
    with pytest.raises(InputError) as exc:   # without a file name: the dictionary is named as such
        machine_from_dict(data)
    assert exc.value.file == "<machine>"


def test_small_positive_dynamics_are_accepted():
    m = machine_from_dict(_with("axis.Y", {"min": 0.0, "max": 1.0, "vmax": 0.5, "amax": 0.25, "jmax": 0.125}))
    assert (m.limits["Y"].vmax, m.limits["Y"].amax, m.limits["Y"].jmax) == (0.5, 0.25, 0.125)


def test_nested_value_where_a_table_belongs_is_spelled_as_in_the_file():
    data = _with("axis.A", None)
    data["axis"]["A"] = [1, 2]
    with pytest.raises(InputError) as exc:
        machine_from_dict(data, "m.toml")
    assert exc.value.message == "[axis] A = an array: [axis.A] must be a table, not a value"


def test_machine_file_on_disk(tmp_path):
    # the default machine, as a file with a byte-order mark, reads like the built-in one
    p = tmp_path / "m.toml"
    p.write_bytes(b"\xef\xbb\xbf" + DEFAULT_MACHINE_TOML.encode())
    m, d = load_machine(str(p)), load_machine(None)
    assert m.limits == d.limits and m.pivot == d.pivot == 150.0 and m.name == "generic AB head"
    assert d.limits["A"].min == pytest.approx(-100.0 * math.pi / 180, rel=1e-15)
    # unreadable files: the project's one text reader (camsmooth.io.table.read_text_file) names the file
    cases = [
        (tmp_path / "missing.toml", None, "cannot read the machine file: file not found"),
        (tmp_path, None, "cannot read the machine file: it is a folder, not a file"),
        (tmp_path / "bin.toml", b"[machine]\nkind = \xff\n",
         "the machine file is not UTF-8 text (byte 0xff on line 2)"),
    ]
    for path, content, message in cases:
        if content is not None:
            path.write_bytes(content)
        with pytest.raises(InputError) as exc:
            load_machine(str(path))
        assert exc.value.message == message and exc.value.file == str(path)
    bad = tmp_path / "bad.toml"
    bad.write_text("[machine\nkind = 1\n")
    with pytest.raises(InputError) as exc:
        load_machine(str(bad))
    assert exc.value.message.startswith("not valid TOML: ") and exc.value.file == str(bad)
    try:
        tomllib.loads("[machine\nkind = 1\n")
    except tomllib.TOMLDecodeError as e:
        assert exc.value.message == f"not valid TOML: {e}"
    # contents errors name the file too
    wrong = tmp_path / "wrong.toml"
    wrong.write_text(DEFAULT_MACHINE_TOML.replace('kind = "AB-head"', 'kind = "AC-table"'))  # pivot, no C
    with pytest.raises(InputError) as exc:
        load_machine(str(wrong))
    assert exc.value.file == str(wrong) and "AC-table" in exc.value.message


@pytest.mark.parametrize("table", ["[posts]", "[machin]", "[axis.Q]"])
def test_unknown_table_in_a_file_is_named_with_the_file(tmp_path, table):
    """A misspelt table would otherwise be ignored (its settings silently replaced by the defaults)."""
    path = tmp_path / "mill.toml"
    path.write_text(DEFAULT_MACHINE_TOML + f"\n{table}\ndialect = \"fanuc\"\n")
    with pytest.raises(InputError) as exc:
        load_machine(str(path))
    assert exc.value.file == str(path)
    name = table.strip("[]").split(".")[-1]
    assert name in exc.value.message and ("known" in exc.value.message or "A, B, X, Y, Z" in exc.value.message)

