"""Values named by the machine's axes: the two rotary columns of a program and per-axis figures.

A machine's two rotary axes are ``Machine.rotary`` (("A", "B") on the AB head, ("A", "C") on an
A/C trunnion, ("B", "C") on a B/C table): results carry those names with their values, so a
column is asked for by the axis it belongs to (``q["C"]``), never by its position under a fixed
letter. Values are the tool's rotation relative to the workpiece in the machine's sign convention
(camsmooth.machine.kinematics.Machine; radians inside the code, right-hand rule).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np


class AxisNameError(LookupError):
    """An axis name (or position) a value does not carry; the message names the axes it has."""

    def __str__(self) -> str:  # LookupError would quote the message like a KeyError's key
        return str(self.args[0]) if self.args else ""


def _position(names: tuple[str, ...], key: str | int, what: str) -> int:
    """Position of ``key`` (an axis name, or a position 0 ... len(names) - 1) in ``names``."""
    if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
        if 0 <= int(key) < len(names):
            return int(key)
        raise AxisNameError(f"{what} carry {len(names)} axes ({', '.join(names)}): no position {int(key)}")
    if isinstance(key, str) and key in names:
        return names.index(key)
    raise AxisNameError(f"{what} carry the axes {', '.join(names)}: no axis {key!r}")


@dataclass(frozen=True, eq=False)
class RotaryValues:
    """Per point values of a machine's two rotary axes, named by them.

    names: the two axis names (``Machine.rotary``, e.g. ("A", "C")); values: (N, 2), column k
    belongs to names[k] (angles rad, velocities rad/s or accelerations rad/s^2, as the field that
    holds them says; machine sign convention). ``q["C"]`` or ``q[1]`` is a column (N,);
    ``q.first`` / ``q.second`` the columns in ``names`` order. The values are stored column-major
    so each column is a contiguous array; they are not copied when already so (not frozen in
    memory: do not write into a column others hold)."""

    names: tuple[str, str]
    values: np.ndarray

    def __post_init__(self) -> None:
        names = tuple(self.names)
        if len(names) != 2 or len(set(names)) != 2 or not all(isinstance(n, str) for n in names):
            raise ValueError(f"RotaryValues needs two different axis names, got {names!r}")
        values = np.asfortranarray(np.asarray(self.values, dtype=float))
        if values.ndim != 2 or values.shape[1] != 2:
            raise ValueError(f"RotaryValues needs values of shape (N, 2), got {values.shape}")
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "values", values)

    @classmethod
    def of(cls, names: Sequence[str], first: np.ndarray, second: np.ndarray) -> RotaryValues:
        """From the two columns (N,) each, in ``names`` order."""
        a, b = (np.asarray(v, dtype=float) for v in (first, second))
        values = np.empty((len(a), 2), order="F")
        values[:, 0], values[:, 1] = a, b
        return cls(tuple(names), values)  # type: ignore[arg-type]

    @classmethod
    def zeros(cls, names: Sequence[str], n: int) -> RotaryValues:
        """N points of zeros (rad, rad/s or rad/s^2) on the axes ``names``."""
        return cls(tuple(names), np.zeros((n, 2), order="F"))  # type: ignore[arg-type]

    def __getitem__(self, key: str | int) -> np.ndarray:
        """The column (N,) of the axis ``key``: its name (e.g. "C") or position (0 or 1)."""
        return self.values[:, _position(self.names, key, "the rotary values")]

    def index(self, name: str) -> int:
        """Position (0 or 1) of the axis ``name``; AxisNameError naming the axes when absent."""
        return _position(self.names, name, "the rotary values")

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __len__(self) -> int:
        return int(self.values.shape[0])

    @property
    def first(self) -> np.ndarray:
        """The column (N,) of names[0]."""
        return self.values[:, 0]

    @property
    def second(self) -> np.ndarray:
        """The column (N,) of names[1]."""
        return self.values[:, 1]

    @property
    def pair(self) -> tuple[np.ndarray, np.ndarray]:
        """(first, second): the two columns in ``names`` order, for the two-angle methods of
        camsmooth.machine.kinematics.Machine (``machine.tool_axis_np(*q.pair)``)."""
        return self.values[:, 0], self.values[:, 1]

    def take(self, index: slice | np.ndarray | Sequence[int]) -> RotaryValues:
        """The points ``index`` (a slice, integer indices or a boolean mask) on the same axes."""
        return RotaryValues(self.names, self.values[index])

    def items(self) -> Iterator[tuple[str, np.ndarray]]:
        """(name, column) for both axes, in ``names`` order."""
        return iter(((n, self.values[:, k]) for k, n in enumerate(self.names)))

    def __repr__(self) -> str:
        return f"RotaryValues(names={self.names!r}, points={len(self)})"


@dataclass(frozen=True)
class PerAxis:
    """One figure per axis, named by the axis: e.g. the peak acceleration (deg/s^2) of each
    rotary axis, ``peak_acc["C"]``. names and values in the same order (values float; NaN where
    not known); ``[name]`` or ``[position]`` reads one."""

    names: tuple[str, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        names, values = tuple(self.names), tuple(float(v) for v in self.values)
        if len(names) != len(values) or len(set(names)) != len(names):
            raise ValueError(f"PerAxis needs one value per distinct axis name, got {names!r} and {values!r}")
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "values", values)

    @classmethod
    def nan(cls, names: Sequence[str]) -> PerAxis:
        """Every axis ``names`` not known (NaN)."""
        return cls(tuple(names), (float("nan"),) * len(names))

    def __getitem__(self, key: str | int) -> float:
        return self.values[_position(self.names, key, "the per-axis values")]

    def __contains__(self, name: object) -> bool:
        return name in self.names

    def __len__(self) -> int:
        return len(self.names)

    def items(self) -> Iterator[tuple[str, float]]:
        """(name, value) in ``names`` order."""
        return iter(zip(self.names, self.values, strict=True))
