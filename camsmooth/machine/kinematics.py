"""Machine kinematics as a product of exponentials (POE) over a declared chain of axes.

One implementation serves numpy arrays (vectorised over N poses) and CasADi symbols (SX/MX),
so the NLP smoother, the error model and the simulators share one machine.

Convention (Lynch & Park, *Modern Robotics*, space form): the tool-tip pose in the workpiece
frame W is

    T(q) = exp([S_1] q_1) exp([S_2] q_2) ... exp([S_n] q_n) M,

with S_i = (w_i, v_i) the spatial screw of joint i at the home configuration (v = -w x p for a
revolute joint through point p; w = 0, |v| = 1 for a prismatic one) and M the home pose of the
tool-tip frame, whose z axis is the tool axis (from tip toward spindle). Rotations follow the
right-hand rule about w. Angles are radians, lengths mm.

Transforms are kept as "structure of arrays": a 3x3 nested list of entries R and a 3-list p,
where each entry is a Python float, a numpy array of shape (N,) or a CasADi expression. Products
skip float zeros, so constant structure costs nothing in either backend.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

try:  # casadi is a hard dependency, but keep import errors readable
    import casadi as ca
except ImportError:  # pragma: no cover
    ca = None

Entry = Any  # float | np.ndarray | casadi.SX | casadi.MX


# ----------------------------------------------------------------------------------------------
# backend dispatch: the only place that knows numpy from CasADi
def _is_casadi(x: Entry) -> bool:
    return ca is not None and isinstance(x, (ca.SX, ca.MX, ca.DM))


def _sin(x: Entry) -> Entry:
    return ca.sin(x) if _is_casadi(x) else np.sin(x)


def _cos(x: Entry) -> Entry:
    return ca.cos(x) if _is_casadi(x) else np.cos(x)


def _add(a: Entry, b: Entry) -> Entry:
    if isinstance(a, float) and a == 0.0:
        return b
    if isinstance(b, float) and b == 0.0:
        return a
    return a + b


def _mul(a: Entry, b: Entry) -> Entry:
    if (isinstance(a, float) and a == 0.0) or (isinstance(b, float) and b == 0.0):
        return 0.0
    if isinstance(a, float) and a == 1.0:
        return b
    if isinstance(b, float) and b == 1.0:
        return a
    return a * b


@dataclass(frozen=True)
class Frame:
    """A rigid transform (R, p) in structure-of-arrays form; see the module docstring."""

    R: tuple[tuple[Entry, Entry, Entry], ...]
    p: tuple[Entry, Entry, Entry]

    @staticmethod
    def from_matrix(T: np.ndarray) -> Frame:
        """A constant frame from a 4x4 homogeneous matrix."""
        T = np.asarray(T, dtype=float)
        return Frame(tuple(tuple(float(T[i, j]) for j in range(3)) for i in range(3)),
                     tuple(float(T[i, 3]) for i in range(3)))

    def __matmul__(self, other: Frame) -> Frame:
        R = tuple(tuple(_add(_add(_mul(self.R[i][0], other.R[0][j]), _mul(self.R[i][1], other.R[1][j])),
                             _mul(self.R[i][2], other.R[2][j])) for j in range(3)) for i in range(3))
        p = tuple(_add(_add(_add(_mul(self.R[i][0], other.p[0]), _mul(self.R[i][1], other.p[1])),
                            _mul(self.R[i][2], other.p[2])), self.p[i]) for i in range(3))
        return Frame(R, p)

    def apply(self, x: Sequence[Entry]) -> tuple[Entry, Entry, Entry]:
        """R x + p for a point x (3 entries)."""
        return tuple(_add(_add(_add(_mul(self.R[i][0], x[0]), _mul(self.R[i][1], x[1])),
                               _mul(self.R[i][2], x[2])), self.p[i]) for i in range(3))

    def rotate(self, x: Sequence[Entry]) -> tuple[Entry, Entry, Entry]:
        """R x for a direction x (3 entries)."""
        return tuple(_add(_add(_mul(self.R[i][0], x[0]), _mul(self.R[i][1], x[1])), _mul(self.R[i][2], x[2]))
                     for i in range(3))

    def to_numpy(self, n: int | None = None) -> np.ndarray:
        """(n, 4, 4) array (or (4, 4) when n is None) for numpy-valued frames."""
        shape = () if n is None else (n,)
        out = np.zeros(shape + (4, 4))
        for i in range(3):
            for j in range(3):
                out[..., i, j] = self.R[i][j]
            out[..., i, 3] = self.p[i]
        out[..., 3, 3] = 1.0
        return out


IDENTITY = Frame(((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)), (0.0, 0.0, 0.0))


def exp_twist(w: Sequence[float], v: Sequence[float], theta: Entry) -> Frame:
    """exp([S] theta) for a screw S = (w, v) with |w| = 1 (revolute) or w = 0, |v| = 1
    (prismatic); Modern Robotics eq. (3.51) (Rodrigues for R, closed form for p).

    w and v are numeric constants; theta may be a float, a numpy array or a CasADi expression.
    """
    w = np.asarray(w, dtype=float)
    v = np.asarray(v, dtype=float)
    if not np.any(w):
        return Frame(IDENTITY.R, tuple(_mul(float(v[i]), theta) for i in range(3)))
    W = np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])
    W2 = W @ W
    s, c = _sin(theta), _cos(theta)
    omc = 1.0 - c
    tms = theta - s
    R = tuple(tuple(_add(_add(float(i == j), _mul(float(W[i, j]), s)), _mul(float(W2[i, j]), omc))
                    for j in range(3)) for i in range(3))
    # G(theta) v = (I theta + (1 - cos) W + (theta - sin) W^2) v
    Wv, W2v = W @ v, W2 @ v
    p = tuple(_add(_add(_mul(float(v[i]), theta), _mul(float(Wv[i]), omc)), _mul(float(W2v[i]), tms))
              for i in range(3))
    return Frame(R, p)


@dataclass(frozen=True)
class Joint:
    """One axis of the chain. kind: 'revolute' (w unit direction, point on the axis, mm) or
    'prismatic' (w = direction of travel, unit). Directions and points in the workpiece frame at
    the home configuration (all joint values 0)."""

    name: str
    kind: str
    direction: tuple[float, float, float]
    point: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def screw(self) -> tuple[np.ndarray, np.ndarray]:
        """The spatial screw (w, v) of this joint, Modern Robotics section 3.3.2."""
        d = np.asarray(self.direction, dtype=float)
        d = d / np.linalg.norm(d)
        if self.kind == "prismatic":
            return np.zeros(3), d
        if self.kind == "revolute":
            return d, -np.cross(d, np.asarray(self.point, dtype=float))
        raise ValueError(f"joint {self.name}: unknown kind {self.kind!r}")


@dataclass(frozen=True)
class Chain:
    """A serial chain of joints from the workpiece (base) to the tool tip, and the home pose M
    of the tool-tip frame (4x4, workpiece frame). ``screws`` may override the joints' nominal
    screws (used by the error model: perturbed directions and locations)."""

    joints: tuple[Joint, ...]
    home: np.ndarray
    screws: tuple[tuple[np.ndarray, np.ndarray], ...] | None = None

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    def joint_screws(self) -> tuple[tuple[np.ndarray, np.ndarray], ...]:
        return self.screws if self.screws is not None else tuple(j.screw() for j in self.joints)

    def with_screws(self, screws: Sequence[tuple[np.ndarray, np.ndarray]], home: np.ndarray | None = None
                    ) -> Chain:
        """A copy with other screws (and home pose): how an error model perturbs the machine."""
        return Chain(self.joints, self.home if home is None else np.asarray(home, dtype=float),
                     tuple((np.asarray(w, float), np.asarray(v, float)) for w, v in screws))

    def forward(self, q: Mapping[str, Entry]) -> Frame:
        """Tool-tip frame in the workpiece frame for joint values q (name -> value; missing
        joints are at 0). Values: floats, numpy arrays (N,) or CasADi expressions."""
        frame = IDENTITY
        for joint, (w, v) in zip(self.joints, self.joint_screws(), strict=True):
            value = q.get(joint.name, 0.0)
            if isinstance(value, float) and value == 0.0:
                continue
            frame = frame @ exp_twist(w, v, value)
        return frame @ Frame.from_matrix(self.home)


# ----------------------------------------------------------------------------------------------
# machine file and the AB head
@dataclass(frozen=True)
class AxisLimits:
    """Travel (min, max), velocity vmax, acceleration amax and jerk jmax of one axis. Rotary axes:
    rad, rad/s, rad/s^2, rad/s^3; linear axes: mm, mm/s, mm/s^2, mm/s^3. inf = no limit (travel
    of a linear axis whose machine file has no table; jmax when none is given)."""

    min: float
    max: float
    vmax: float = float("inf")
    amax: float = float("inf")
    jmax: float = float("inf")


#: controller dialects of the G-code writer (camsmooth.io.gcode)
POST_DIALECTS = ("generic", "linuxcnc", "fanuc", "heidenhain", "siemens")
#: "machine": joint positions (X Y Z = pivot, A B) with inverse-time feed; "tcp": tool-tip
#: coordinates and A B under the controller's tool-centre-point command
POST_MODES = ("machine", "tcp")


@dataclass(frozen=True)
class PostConfig:
    """How G-code is written for this machine (``[post]`` table of the machine file).

    dialect: one of POST_DIALECTS; mode: one of POST_MODES (camsmooth.io.gcode documents both);
    tool: the tool number the program calls / whose length offset TCP uses (default 1);
    tcp_on, tcp_off: override the dialect's tool-centre-point commands (e.g. a LinuxCNC
    configuration's own M-codes), None for the dialect's default.
    """

    dialect: str = "generic"
    mode: str = "machine"
    tool: int = 1
    tcp_on: str | None = None
    tcp_off: str | None = None


@dataclass(frozen=True)
class Machine:
    """A five-axis machine: its name, kind, pivot length (mm, head pivot to tool tip), the
    chain, the limits per axis (radians inside the code) and the G-code post settings."""

    name: str
    kind: str
    pivot: float
    chain: Chain
    limits: Mapping[str, AxisLimits] = field(default_factory=dict)
    post: PostConfig = field(default_factory=PostConfig)
    #: the machine file gives jmax for an axis: the planned time law meets every axis's jmax
    #: (camsmooth.smoothing.jerk); else jmax (a default) is only reported
    jerk_limited: bool = False

    # ---- forward kinematics ----------------------------------------------------------------
    def tool_pose(self, A: Entry, B: Entry, X: Entry = 0.0, Y: Entry = 0.0, Z: Entry = 0.0
                  ) -> tuple[tuple[Entry, Entry, Entry], tuple[Entry, Entry, Entry]]:
        """(tip, axis) in the workpiece frame for commanded axes (A, B rad; X, Y, Z mm).
        tip: the tool tip (CL point), axis: unit tool axis T (tip toward spindle). Entries are
        numpy arrays or CasADi expressions, as given."""
        f = self.chain.forward({"X": X, "Y": Y, "Z": Z, "A": A, "B": B})
        return f.p, (f.R[0][2], f.R[1][2], f.R[2][2])

    def tool_axis(self, A: Entry, B: Entry) -> tuple[Entry, Entry, Entry]:
        """Unit tool axis T(A, B) in the workpiece frame (METHODS section 1 for the nominal AB
        head: (sin B, -sin A cos B, cos A cos B))."""
        return self.tool_pose(A, B)[1]

    def tool_axis_np(self, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        """tool_axis for numpy arrays, as an (N, 3) array."""
        A = np.asarray(A, dtype=float)
        B = np.asarray(B, dtype=float)
        return np.stack(np.broadcast_arrays(*self.tool_axis(A, B)), axis=-1)

    def tool_pose_np(self, A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray, Z: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """tool_pose for numpy arrays: (tip (N,3) mm, axis (N,3))."""
        args = [np.asarray(a, dtype=float) for a in (A, B, X, Y, Z)]
        tip, axis = self.tool_pose(*args)
        return (np.stack(np.broadcast_arrays(*tip), axis=-1), np.stack(np.broadcast_arrays(*axis), axis=-1))

    def linear_axes(self, cl: np.ndarray, T: np.ndarray) -> np.ndarray:
        """(X, Y, Z) mm that put the tool tip at cl with axis T on the nominal AB head:
        pivot = CL + L_p T (METHODS section 1)."""
        return np.asarray(cl, float) + self.pivot * np.asarray(T, float)

    # ---- inverse kinematics ----------------------------------------------------------------
    def inverse_axis(self, T: np.ndarray) -> np.ndarray:
        """Both inverse branches of the nominal AB head for unit axes T (N,3): (N, 2, 2) array
        [point, branch, (A, B)] in radians. Branch 0: B = asin(i), A = atan2(-j, k); branch 1:
        B' = pi - B, A' = A + pi (METHODS section 1). Angles wrapped to (-pi, pi]."""
        T = np.atleast_2d(np.asarray(T, dtype=float))
        B0 = np.arcsin(np.clip(T[:, 0], -1.0, 1.0))
        A0 = np.arctan2(-T[:, 1], T[:, 2])
        B1 = _wrap(np.pi - B0)
        A1 = _wrap(A0 + np.pi)
        return np.stack([np.stack([A0, B0], -1), np.stack([A1, B1], -1)], axis=1)

    def within(self, name: str, values: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Mask of values within the travel of axis `name` (True when the axis has no limits)."""
        lim = self.limits.get(name)
        values = np.asarray(values, dtype=float)
        if lim is None:
            return np.ones(values.shape, dtype=bool)
        return (values >= lim.min - tol) & (values <= lim.max + tol)

    def inverse_candidates(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every (A, B) reaching unit axes T (N, 3): both branches of ``inverse_axis`` with A and
        B shifted by -2 pi, 0 and +2 pi. Returns candidates (N, 18, 2) rad and a mask (N, 18) of
        those within the A and B travel: every solution within limits, per point."""
        sols = self.inverse_axis(T)
        shifts = np.array([-2 * np.pi, 0.0, 2 * np.pi])
        grid = np.stack(np.meshgrid(shifts, shifts, indexing="ij"), -1)
        cand = (sols[:, :, None, None, :] + grid[None, None]).reshape(len(sols), -1, 2)
        return cand, self.within("A", cand[..., 0]) & self.within("B", cand[..., 1])

    def solve_row(self, T: np.ndarray, cl: np.ndarray | None = None,
                  previous: tuple[float, float] | None = None) -> IKResult:
        """Inverse kinematics along one row: for every point the (A, B) solution within the
        travel limits nearest the previous point's solution, with A and B unwrapped by 2 pi to
        stay continuous; the first point takes the solution nearest ``previous`` (default
        (0, 0)). Points with no solution in limits are listed in ``unreachable`` (indices) and
        carry the nearest out-of-limit branch so the row stays continuous.

        T: (N,3) unit tool axes, workpiece frame; cl: (N,3) tool tips, mm (for X, Y, Z).
        """
        T = np.atleast_2d(np.asarray(T, dtype=float))
        n = len(T)
        prev = np.array(previous if previous is not None else (0.0, 0.0), dtype=float)
        cand, ok = self.inverse_candidates(T)
        out = np.empty((n, 2))
        reach = ok.any(axis=1)
        # A sequential choice is needed only where the reachable set is ambiguous; the usual case
        # (exactly one reachable candidate at every point) is vectorised.
        unique = ok.sum(axis=1) == 1
        if np.all(unique):
            out[:] = cand[np.arange(n), ok.argmax(axis=1)]
        else:
            ref = prev
            for i in range(n):
                c = cand[i]
                mask = ok[i] if reach[i] else np.ones(len(c), bool)
                d = np.where(mask, np.linalg.norm(c - ref, axis=1), np.inf)
                out[i] = c[int(np.argmin(d))]
                ref = out[i]
        xyz = None
        if cl is not None:
            xyz = self.linear_axes(cl, T)
            for k, name in enumerate("XYZ"):
                reach &= self.within(name, xyz[:, k])
        return IKResult(A=out[:, 0], B=out[:, 1], xyz=xyz, unreachable=np.flatnonzero(~reach))


@dataclass(frozen=True)
class IKResult:
    """Inverse-kinematics result along a row: A, B (rad), xyz (N,3) mm or None, and the
    indices of the points with no solution within the limits."""

    A: np.ndarray
    B: np.ndarray
    xyz: np.ndarray | None
    unreachable: np.ndarray


def _wrap(a: np.ndarray) -> np.ndarray:
    """Wrap angles to (-pi, pi]."""
    return -((-np.asarray(a) + np.pi) % (2 * np.pi) - np.pi)


def ab_head_chain(pivot: float) -> Chain:
    """The AB swivel head of METHODS section 1: linear axes X, Y, Z carry the pivot; A rotates
    about X (outer), B about Y (inner, carried by A); both axes pass through the pivot, which is
    at the workpiece origin when X = Y = Z = 0. Home: tool tip at (0, 0, -pivot), tool axis +z."""
    joints = (
        Joint("X", "prismatic", (1.0, 0.0, 0.0)),
        Joint("Y", "prismatic", (0.0, 1.0, 0.0)),
        Joint("Z", "prismatic", (0.0, 0.0, 1.0)),
        Joint("A", "revolute", (1.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        Joint("B", "revolute", (0.0, 1.0, 0.0), (0.0, 0.0, 0.0)),
    )
    home = np.eye(4)
    home[2, 3] = -pivot
    return Chain(joints, home)


#: dynamics of the linear axes when a machine file does not give them (mm/s, mm/s^2, mm/s^3): a
#: mid-size five-axis machining centre, not a datasheet. 500 mm/s = 30 m/min, the low end of the
#: 30-60 m/min rapid traverse such machines list; 3000 mm/s^2 (about 0.3 g), below the 5-10 m/s^2
#: axis accelerations listed for rapids, as a contouring value; 50 m/s^3, the order of a CNC's
#: path jerk setting (e.g. Siemens MD32431 MAX_AX_JERK is set in m/s^3). Give your machine's values.
LINEAR_DEFAULTS = {"vmax": 500.0, "amax": 3000.0, "jmax": 50000.0}
#: jerk of the rotary axes when not given (deg/s^3): reaches the default amax of 300 deg/s^2 in
#: 0.06 s, the same ramp as the linear default (3000 / 50000 s)
ROTARY_JMAX_DEFAULT = 5000.0

DEFAULT_MACHINE_TOML = """\
# camsmooth default machine: AB swivel head (METHODS.md section 1).
# Angles in degrees, velocities deg/s, accelerations deg/s^2, jerks deg/s^3; lengths mm, mm/s,
# mm/s^2, mm/s^3. Linear axes: vmax, amax, jmax optional (defaults as below); rotary axes: jmax
# optional. The feed planner (camsmooth.smoothing.feed) keeps every axis within vmax and amax; a
# jmax given for any axis makes the planned time law meet every axis's jmax (camsmooth.smoothing.jerk),
# otherwise jmax (defaults: the values shown) is only reported.
[machine]
name = "generic AB head"
kind = "AB-head"
pivot = 150.0

[axis.A]
min = -100.0
max = 100.0
vmax = 60.0
amax = 300.0
# jmax = 5000.0

[axis.B]
min = -100.0
max = 100.0
vmax = 60.0
amax = 300.0
# jmax = 5000.0

# X Y Z carry the head's pivot (pivot = tool tip + pivot length * tool axis)
[axis.X]
min = -1000.0
max = 1000.0
vmax = 500.0
amax = 3000.0
# jmax = 50000.0

[axis.Y]
min = -1000.0
max = 1000.0
vmax = 500.0
amax = 3000.0
# jmax = 50000.0

[axis.Z]
min = -1000.0
max = 1000.0
vmax = 500.0
amax = 3000.0
# jmax = 50000.0

# G-code post (camsmooth.io.gcode): dialect = "generic" | "linuxcnc" | "fanuc" | "heidenhain" |
# "siemens"; mode = "machine" (joint positions, inverse-time feed G93) | "tcp" (tool tip and A B
# under the controller's tool-centre-point command, F = tip feed).
[post]
dialect = "generic"
mode = "machine"
"""


def _number(table: Mapping[str, Any], key: str, where: str, file: str) -> float:
    from camsmooth.errors import InputError

    if key not in table:
        raise InputError(f"missing key '{key}' in [{where}]", file=file)
    value = table[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise InputError(f"[{where}] {key} must be a finite number, got {_toml_repr(value)}", file=file)
    return float(value)


def _toml_repr(value: Any) -> str:
    """A value as the TOML file spells it (strings quoted, tables as tables), for messages."""
    if isinstance(value, Mapping):
        return "a table"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    return str(value)


def _table(parent: Mapping[str, Any], key: str, where: str, file: str,
           required: bool = True) -> Mapping[str, Any] | None:
    """The sub-table ``parent[key]``; InputError naming ``where`` when it is missing or not a table."""
    from camsmooth.errors import InputError

    if key not in parent:
        if required:
            raise InputError(f"missing [{where}] table", file=file)
        return None
    t = parent[key]
    if not isinstance(t, Mapping):
        head, _, last = where.rpartition(".")
        spelled = f"[{head}] {last} = {_toml_repr(t)}" if head else f"{where} = {_toml_repr(t)}"
        raise InputError(f"{spelled}: [{where}] must be a table, not a value", file=file)
    return t


def machine_from_dict(data: Mapping[str, Any], source: str = "<machine>") -> Machine:
    """A Machine from the parsed machine TOML (degrees in the file, radians in the result).

    InputError naming ``source`` and the key for: a missing or wrongly typed table or key (a value
    where a table belongs, a string or boolean where a number belongs), non-finite numbers, an
    unsupported kind, pivot < 0, min >= max, vmax, amax or jmax <= 0, unknown tables (top level or axis)
    or keys.
    X, Y, Z: vmax, amax, jmax default to LINEAR_DEFAULTS and a missing table to unlimited travel
    with those dynamics; A, B: jmax defaults to ROTARY_JMAX_DEFAULT.
    """
    from camsmooth.errors import InputError

    _known_tables(data, source)
    m = _table(data, "machine", "machine", source)
    unknown = sorted(set(m) - set(_MACHINE_KEYS))
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)} in [machine] (known: {', '.join(_MACHINE_KEYS)})",
                         file=source)
    kind = m.get("kind")
    if kind != "AB-head":
        shown = _toml_repr(kind) if kind is not None else "missing"
        raise InputError(f"[machine] kind = {shown} is not supported (supported: \"AB-head\")", file=source)
    pivot = _number(m, "pivot", "machine", source)
    if pivot < 0:
        raise InputError(f"[machine] pivot must be >= 0 mm, got {pivot:g}", file=source)
    name = m.get("name", "AB head")
    if not isinstance(name, str):
        raise InputError(f"[machine] name must be a string, got {_toml_repr(name)}", file=source)
    axes = _table(data, "axis", "axis", source, required=False) or {}
    unknown = set(axes) - {"A", "B", "X", "Y", "Z"}
    if unknown:
        raise InputError(f"unknown axis table(s) {', '.join(sorted(unknown))} (an AB head has A, B, X, Y, Z)",
                         file=source)
    limits: dict[str, AxisLimits] = {}
    for ax in ("A", "B"):
        t = _table(axes, ax, f"axis.{ax}", source)
        _known_keys(t, ax, source)
        vals = {k: _number(t, k, f"axis.{ax}", source) for k in ("min", "max", "vmax", "amax")}
        vals["jmax"] = _number(t, "jmax", f"axis.{ax}", source) if "jmax" in t else ROTARY_JMAX_DEFAULT
        if vals["min"] >= vals["max"]:
            raise InputError(f"[axis.{ax}] min {vals['min']:g} must be below max {vals['max']:g}", file=source)
        _positive(vals, ax, source)
        limits[ax] = AxisLimits(*(float(np.radians(vals[k])) for k in ("min", "max", "vmax", "amax", "jmax")))
    for ax in ("X", "Y", "Z"):
        t = _table(axes, ax, f"axis.{ax}", source, required=False)
        if t is None:
            limits[ax] = AxisLimits(-np.inf, np.inf, **LINEAR_DEFAULTS)
            continue
        _known_keys(t, ax, source)
        lo, hi = _number(t, "min", f"axis.{ax}", source), _number(t, "max", f"axis.{ax}", source)
        if lo >= hi:
            raise InputError(f"[axis.{ax}] min {lo:g} must be below max {hi:g}", file=source)
        vals = {k: _number(t, k, f"axis.{ax}", source) if k in t else d for k, d in LINEAR_DEFAULTS.items()}
        _positive(vals, ax, source)
        limits[ax] = AxisLimits(lo, hi, **vals)
    return Machine(name, kind, pivot, ab_head_chain(pivot), limits,
                   post_from_dict(data.get("post", {}), source),
                   jerk_limited=any(isinstance(t, dict) and "jmax" in t for t in axes.values()))


_AXIS_KEYS = ("min", "max", "vmax", "amax", "jmax")
_TOP_TABLES = ("machine", "axis", "post")
_MACHINE_KEYS = ("name", "kind", "pivot")


def _known_tables(data: Mapping[str, Any], source: str) -> None:
    """InputError for a top-level table or key the machine file does not know (a misspelt ``[post]``
    would otherwise be ignored and its settings silently replaced by the defaults)."""
    from camsmooth.errors import InputError

    unknown = sorted(set(data) - set(_TOP_TABLES))
    if unknown:
        spelled = ", ".join(f"[{k}]" if isinstance(data[k], Mapping) else f"{k} = {_toml_repr(data[k])}"
                            for k in unknown)
        raise InputError(f"unknown table(s) {spelled} (known: {', '.join(f'[{k}]' for k in _TOP_TABLES)})",
                         file=source)


def _known_keys(table: Mapping[str, Any], ax: str, source: str) -> None:
    """InputError for a key an [axis.*] table does not know (a misspelt limit would be ignored)."""
    from camsmooth.errors import InputError

    unknown = sorted(set(table) - set(_AXIS_KEYS))
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)} in [axis.{ax}] (known: {', '.join(_AXIS_KEYS)})",
                         file=source)


def _positive(vals: Mapping[str, float], ax: str, source: str) -> None:
    from camsmooth.errors import InputError

    for k in ("vmax", "amax", "jmax"):
        if k in vals and vals[k] <= 0:
            raise InputError(f"[axis.{ax}] {k} must be > 0, got {vals[k]:g}", file=source)


def post_from_dict(table: Any, source: str = "<machine>") -> PostConfig:
    """The ``[post]`` table of a machine file as a PostConfig (defaults: generic, machine)."""
    from camsmooth.errors import InputError

    if not isinstance(table, Mapping):
        raise InputError("[post] must be a table", file=source)
    unknown = sorted(set(table) - {"dialect", "mode", "tool", "tcp_on", "tcp_off"})
    if unknown:
        raise InputError(f"unknown key(s) {unknown} in [post] (known: dialect, mode, tool, tcp_on, tcp_off)",
                         file=source)
    dialect = table.get("dialect", "generic")
    if dialect not in POST_DIALECTS:
        raise InputError(f"[post] dialect = {dialect!r} is not supported (supported: "
                         f"{', '.join(repr(d) for d in POST_DIALECTS)})", file=source)
    mode = table.get("mode", "machine")
    if mode not in POST_MODES:
        raise InputError(f"[post] mode = {mode!r} is not supported (supported: 'machine', 'tcp')", file=source)
    tool = table.get("tool", 1)
    if isinstance(tool, bool) or not isinstance(tool, int) or tool < 0:
        raise InputError(f"[post] tool must be an integer >= 0, got {tool!r}", file=source)
    cmds = {}
    for key in ("tcp_on", "tcp_off"):
        v = table.get(key)
        if v is not None and (not isinstance(v, str) or not v.strip() or "\n" in v):
            raise InputError(f"[post] {key} must be one line of text, got {v!r}", file=source)
        cmds[key] = None if v is None else v.strip()
    return PostConfig(dialect=dialect, mode=mode, tool=tool, **cmds)


def load_machine(path: str | None = None) -> Machine:
    """Read a machine TOML file (see DEFAULT_MACHINE_TOML); None gives the default machine.

    InputError naming the file when it is missing, a folder, unreadable, not UTF-8 text (a binary
    file), not valid TOML, or has wrong contents (``machine_from_dict``). A UTF-8 byte-order mark
    is accepted.
    """
    import tomllib

    from camsmooth.errors import InputError

    if path is None:
        return machine_from_dict(tomllib.loads(DEFAULT_MACHINE_TOML), "<default machine>")
    from camsmooth.io.table import read_text_file

    text = read_text_file(path, "machine file")
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"not valid TOML: {exc}", file=str(path)) from None
    return machine_from_dict(data, str(path))


def space_jacobian(chain: Chain, q: Mapping[str, Any], joints: Sequence[str] | None = None) -> np.ndarray:
    """The space Jacobian J_s(q) of the chain (Modern Robotics eq. (5.11), JacobianSpace):
    column i is the spatial twist of joint i at q, J_si = Ad(exp([S_1] q_1) ... exp([S_i-1] q_i-1)) S_i,
    as (w, v) with w the angular and v the linear part, workpiece frame. q: joint name -> float or
    numpy array (N,) (missing joints at 0); joints: the columns wanted (default all; others are
    left 0 and the product stops after the last one wanted). Returns (N, 6, n_joints) (N = 1 for
    scalars), rows (w_x, w_y, w_z, v_x, v_y, v_z). The velocity of a point p carried by the tool
    frame is v + w x p, so d tip / d q_i = v_i + w_i x tip and d T / d q_i = w_i x T (T the tool
    axis)."""
    screws = chain.joint_screws()
    names = chain.names
    want = set(names if joints is None else joints)
    last = max(i for i, nm in enumerate(names) if nm in want) if want else -1
    vals = [np.atleast_1d(np.asarray(q.get(j.name, 0.0), dtype=float)) for j in chain.joints]
    n = max(len(v) for v in vals)
    J = np.zeros((n, 6, len(screws)))
    R: np.ndarray | None = None  # None while the prefix is a pure translation (prismatic joints)
    p = np.zeros((n, 3))
    for i, ((w, v), qi) in enumerate(zip(screws, vals, strict=True)):
        if i > last:
            break
        if names[i] in want:
            ws = np.broadcast_to(w, (n, 3)) if R is None else R @ w
            J[:, :3, i] = ws
            J[:, 3:, i] = (np.broadcast_to(v, (n, 3)) if R is None else R @ v) + np.cross(p, ws)
        if not np.any(w):  # prismatic: the prefix moves by R v q
            step = np.outer(np.broadcast_to(qi, (n,)), v)
            p = p + (step if R is None else np.einsum("nij,nj->ni", R, step))
            continue
        T = exp_twist(w, v, np.broadcast_to(qi, (n,))).to_numpy(n)
        Rp = np.broadcast_to(np.eye(3), (n, 3, 3)) if R is None else R
        p = p + np.einsum("nij,nj->ni", Rp, T[:, :3, 3])
        R = Rp @ T[:, :3, :3]
    return J
