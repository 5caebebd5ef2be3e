"""What the mutation run of camsmooth/machine/kinematics.py (benchmarks/mutation.py, target
"kinematics") showed the kinematics tests leave open, each against a value written here: the words
a chain is described by (an inclined axis' direction, the one-line summary), the machine a program
header names when a machine is given, and the file, line and key every machine-file error names."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.machine.kinematics import (
    MachineChain,
    RotaryAxis,
    chain_from_dict,
    load_machine,
    machine_from_dict,
    machine_from_header,
    preset_machine,
)

LIMITS = {"min": -170.0, "max": 170.0, "vmax": 60.0, "amax": 300.0}
#: a nutating head-table machine: C on the table (vertical), B in the head inclined at 45 deg in the YZ plane
NUTATING_M = {"table": ["C"], "head": ["B"], "gauge": [0, 0, 300.0]}
NUTATING_AXES = {"B": {"direction": [0, 1, 1], "point": [0, 0, 200.0], **LIMITS},
                 "C": {"direction": [0, 0, 1], "point": [40.0, 30.0, 0.0], **LIMITS}}


def test_about_names_an_axis_by_its_sign_and_letter_or_its_unit_direction():
    """A preset's axes are along +X / +Y; a chain's axis along -Z reads "-Z"; an inclined one its
    unit direction to 4 significant digits: (0, 1, 1) / sqrt(2) = (0, 0.7071, 0.7071)."""
    m = machine_from_dict({"machine": dict(NUTATING_M), "axis": NUTATING_AXES}, "nutating.toml")
    assert m.description.about("B") == "[0, 0.7071, 0.7071]"
    assert m.description.about("C") == "+Z"
    table = MachineChain((RotaryAxis("A", (-1.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
                          RotaryAxis("C", (0.0, 0.0, -1.0), (0.0, 0.0, 0.0))), ())
    assert (table.about("A"), table.about("C")) == ("-X", "-Z")
    assert load_machine(None).description.about("B") == "+Y"


def test_summary_spells_the_kind_the_axes_their_lines_and_the_gauge():
    """The preset AB head of pivot 150: both axes through (0, 0, 150), gauge there; the nutating chain
    without a kind, its directions as given in the file after normalising."""
    head = preset_machine("AB-head", 150.0).description.summary()
    assert head == ("kind AB-head: table none; head A about [1, 0, 0] through [0, 0, 150] mm; "
                    "B about [0, 1, 0] through [0, 0, 150] mm; gauge [0, 0, 150] mm")
    m = machine_from_dict({"machine": dict(NUTATING_M), "axis": NUTATING_AXES}, "nutating.toml")
    r = 1 / np.sqrt(2)
    assert m.description.summary() == (f"table C about [0, 0, 1] through [40, 30, 0] mm; head B about [0, {r:g}, "
                                       f"{r:g}] through [0, 0, 200] mm; gauge [0, 0, 300] mm")
    assert m.describe() == f"five-axis machine (B C) ({m.description.summary()})"


def test_a_header_without_letters_is_checked_against_the_given_machine_by_its_kind():
    """An AC-table header and an AC-table machine: that machine. An AB-head header and the same
    machine: InputError naming the file and line of the header and both sets of rotary axes. A "chain"
    header without a machine: InputError naming the file and line."""
    m = preset_machine("AC-table", 0.0, (1.0, 2.0, 3.0), "my trunnion")
    assert machine_from_header("AC-table", None, (0.0, 0.0, 0.0), m, None, "prog.ngc", 3) is m
    with pytest.raises(InputError, match=r"an AB-head machine \(rotary axes A,B\) but the machine is an AC-table "
                                         r"\(my trunnion, rotary axes A,C\)") as err:
        machine_from_header("AB-head", None, (0.0, 0.0, 0.0), m, None, "prog.ngc", 3)
    assert (err.value.file, err.value.line) == ("prog.ngc", 3)
    # a header of a machine given by its chain cannot be rebuilt without its file
    with pytest.raises(InputError, match="written for a machine described by its chain: give its machine file") as err:
        machine_from_header("chain", None, (0.0, 0.0, 0.0), None, None, "prog.ngc", 5)
    assert (err.value.file, err.value.line) == ("prog.ngc", 5)


@pytest.mark.parametrize(("machine", "axes", "words"), [
    ({"table": ["C"], "head": ["D"], "gauge": [0, 0, 1.0]}, {}, r"'D' is not a rotary axis name \(A, B, C\)"),
    ({"table": ["C", "B", "A"]}, {}, "must name exactly two different rotary axes in all"),
    (NUTATING_M, {**NUTATING_AXES, "B": {**NUTATING_AXES["B"], "point": [0, 0]}},
     r"\[axis.B\] point must be three finite numbers"),
], ids=["name", "count", "point"])
def test_chain_errors_name_the_file(machine, axes, words):
    """Each wrong chain (a letter that is not A B C, three axes, a point of two numbers) names the file
    it came from."""
    with pytest.raises(InputError, match=words) as err:
        chain_from_dict(machine, axes, "bad.toml")
    assert err.value.file == "bad.toml"


def test_a_preset_kind_refuses_an_axis_direction_or_point():
    """A kind fixes its axes' lines: a direction (or point) given for one of its axes is refused,
    naming the axis, the kind and the file."""
    data = {"machine": {"kind": "AC-table"}, "axis": {"A": {**LIMITS, "direction": [1, 0, 0]}, "C": dict(LIMITS)}}
    with pytest.raises(InputError, match=r"\[axis.A\] direction/point: the kind AC-table fixes its axes' lines") as err:
        machine_from_dict(data, "ac.toml")
    assert err.value.file == "ac.toml"


def test_nominal_machines_of_rotary_letters():
    """A B: the default AB head. A C and B C: the preset trunnion of those axes at the origin, named
    "nominal <kind>", travel +-1e6 deg and 3600 deg/s, deg/s^2 on both rotary axes (binding nothing),
    the linear axes unlimited in travel with the default dynamics. Other letters: InputError."""
    from camsmooth.machine.kinematics import LINEAR_DEFAULTS, ROTARY_JMAX_DEFAULT, nominal_machine

    assert nominal_machine(("A", "B")).name == load_machine(None).name
    for letters, kind in ((("A", "C"), "AC-table"), (("B", "C"), "BC-table")):
        m = nominal_machine(letters)
        assert (m.name, m.kind, m.rotary, m.table_centre) == (f"nominal {kind}", kind, letters, (0.0, 0.0, 0.0))
        for ax in letters:
            lim = m.limits[ax]
            assert np.degrees([lim.min, lim.max, lim.vmax, lim.amax, lim.jmax]) == pytest.approx(
                [-1e6, 1e6, 3600.0, 3600.0, ROTARY_JMAX_DEFAULT], rel=1e-12)
        for ax in "XYZ":
            lim = m.limits[ax]
            assert (lim.min, lim.max) == (-np.inf, np.inf)
            assert (lim.vmax, lim.amax, lim.jmax) == tuple(LINEAR_DEFAULTS[k] for k in ("vmax", "amax", "jmax"))
    with pytest.raises(InputError, match="no nominal machine has the rotary axes A, C, B"):
        nominal_machine(("A", "C", "B"))


def test_a_kind_with_a_chain_is_refused_naming_the_file():
    """[machine] gives both a preset kind and chain keys: refused, naming the kind, the chain keys and the file."""
    data = {"machine": {"kind": "AC-table", "table": ["A", "C"]}, "axis": {"A": dict(LIMITS), "C": dict(LIMITS)}}
    with pytest.raises(InputError, match=r'kind = "AC-table" and table: a machine is a preset kind or a chain') as err:
        machine_from_dict(data, "both.toml")
    assert err.value.file == "both.toml"
