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
from numba import njit

from camsmooth.machine.axes import RotaryValues

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


#: controller dialects camsmooth writes whole programs in (camsmooth.post.DIALECTS entries with ``own``;
#: tests/test_post_registry.py checks the two agree)
POST_DIALECTS = ("generic", "linuxcnc", "fanuc", "heidenhain", "siemens")
#: "machine": joint positions (X Y Z = pivot, A B) with inverse-time feed; "tcp": tool-tip
#: coordinates and A B under the controller's tool-centre-point command
POST_MODES = ("machine", "tcp")


@dataclass(frozen=True)
class PostConfig:
    """How G-code is written for this machine (``[post]`` table of the machine file).

    dialect: one of POST_DIALECTS; mode: one of POST_MODES (camsmooth.post.writer documents both);
    tool: the tool number the program calls / whose length offset TCP uses (default 1);
    tcp_on, tcp_off: override the dialect's tool-centre-point commands (e.g. a LinuxCNC
    configuration's own M-codes), None for the dialect's default.
    """

    dialect: str = "generic"
    mode: str = "machine"
    tool: int = 1
    tcp_on: str | None = None
    tcp_off: str | None = None


#: the preset kinds (``[machine] kind``): each expands to a MachineChain (``preset_chain``); the rotary
#: axes of each, in the order of the output columns
MACHINE_KINDS: dict[str, tuple[str, str]] = {
    "AB-head": ("A", "B"),
    "AC-table": ("A", "C"),
    "BC-table": ("B", "C"),
    "BC-head-table": ("B", "C"),
}
#: the names a rotary axis of a machine file may have (ISO 841: rotations about X, Y, Z)
ROTARY_NAMES = ("A", "B", "C")
#: angle (rad) from the pole below which the outer rotary angle is undefined (held at its previous
#: value by ``solve_row``): far below any angle a program resolves (1e-9 rad = 2e-7 deg)
POLE_EPS = 1e-9
#: |g|^2 of Paden-Kahan subproblem 2 below -REACH_EPS: the tool axis is outside the cone the two
#: rotary axes sweep (a nutating chain), so no angles reach it
REACH_EPS = 1e-9


@dataclass(frozen=True)
class RotaryAxis:
    """One rotary axis of a machine description: its name (A, B or C), unit direction (machine frame
    with every axis at zero; a positive value turns the tool relative to the workpiece right-handed
    about it) and a point on it (mm): a table axis in the workpiece frame, a head axis from the tool
    tip, both with every axis at zero."""

    name: str
    direction: tuple[float, float, float]
    point: tuple[float, float, float]


@dataclass(frozen=True)
class MachineChain:
    """What a machine is, as its file describes it: the rotary axes that carry the workpiece
    (``table``, from the bed to the workpiece) and those that carry the spindle (``head``, from the
    ram to the spindle), exactly two in all, and the gauge point (mm, from the tool tip with every
    axis at zero: the point of the ram that X Y Z command in machine mode). ``preset`` names the kind
    it was expanded from (MACHINE_KINDS) or is None for a chain given explicitly.

    Formulas (rot(d, q, p): rotation by q about the line through p with direction d, right-handed):
    tool axis T = R(t_n) ... R(t_1) R(h_1) ... R(h_m) e_z (workpiece frame); machine mode: the tip in
    the machine frame tip_m = XYZ + rot(h_1) ... rot(h_m) (-gauge), the head's points taken from the
    gauge point, and the tip in the workpiece frame CL = rot(t_n) ... rot(t_1) tip_m; TCP mode: X Y Z
    = CL. As a POE chain from the workpiece to the tip: t_n ... t_1, X, Y, Z, h_1 ... h_m, home pose a
    translation by -gauge (``chain``)."""

    table: tuple[RotaryAxis, ...]
    head: tuple[RotaryAxis, ...]
    gauge: tuple[float, float, float] = (0.0, 0.0, 0.0)
    preset: str | None = None

    @property
    def axes(self) -> tuple[RotaryAxis, ...]:
        """The rotary axes from the workpiece to the spindle: t_n ... t_1, h_1 ... h_m."""
        return tuple(reversed(self.table)) + self.head

    @property
    def rotary(self) -> tuple[str, str]:
        """The two rotary axis names in column order (alphabetical: A B, A C, B C)."""
        a, b = sorted(ax.name for ax in self.axes)
        return a, b

    def axis(self, name: str) -> RotaryAxis:
        """The rotary axis called ``name``."""
        return next(ax for ax in self.axes if ax.name == name)

    def on_table(self, name: str) -> bool:
        """True when axis ``name`` carries the workpiece, False when it carries the spindle."""
        return any(ax.name == name for ax in self.table)

    def chain(self) -> Chain:
        """The POE chain from the workpiece frame to the tool tip (class docstring)."""
        g = np.asarray(self.gauge, float)
        joints = [Joint(ax.name, "revolute", ax.direction, ax.point) for ax in reversed(self.table)]
        joints += [Joint(n, "prismatic", d) for n, d in zip("XYZ", np.eye(3).tolist(), strict=True)]
        joints += [Joint(ax.name, "revolute", ax.direction, tuple((np.asarray(ax.point) - g).tolist()))
                   for ax in self.head]
        home = np.eye(4)
        home[:3, 3] = -g
        return Chain(tuple(Joint(j.name, j.kind, tuple(float(v) for v in j.direction),
                                 tuple(float(v) for v in j.point)) for j in joints), home)

    # ---- the words a machine kind decided before chains: derived here, in one place ---------
    def axis_formula(self) -> str:
        """The tool axis as a formula of the rotary axes: "T = Rz(C) Rx(A) e_z" (AC table);
        R<d>(q) for an axis along -d, R[dx,dy,dz](q) for an inclined one."""
        def rot(ax: RotaryAxis) -> str:
            d = np.asarray(ax.direction, float)
            k = int(np.argmax(np.abs(d)))
            if abs(abs(d[k]) - 1.0) < 1e-12:
                return f"R{'xyz'[k]}({'-' if d[k] < 0 else ''}{ax.name})"
            return "R[" + ",".join(f"{v:.4g}" for v in d) + f"]({ax.name})"
        return "T = " + " ".join(rot(ax) for ax in self.axes) + " e_z"

    def about(self, name: str) -> str:
        """The direction of axis ``name`` in words: "+X", "-Z", or "[0, -0.7071, 0.7071]"."""
        d = np.asarray(self.axis(name).direction, float)
        k = int(np.argmax(np.abs(d)))
        if abs(abs(d[k]) - 1.0) < 1e-12:
            return ("-" if d[k] < 0 else "+") + "XYZ"[k]
        return "[" + ", ".join(f"{v:.4g}" for v in d) + "]"

    def summary(self) -> str:
        """One line on the chain: the preset, or the table and head axes with directions and the gauge."""
        def one(ax: RotaryAxis) -> str:
            d = ", ".join(f"{v:g}" for v in ax.direction)
            p = ", ".join(f"{v:g}" for v in ax.point)
            return f"{ax.name} about [{d}] through [{p}] mm"
        table = "; ".join(one(ax) for ax in self.table) or "none"
        head = "; ".join(one(ax) for ax in self.head) or "none"
        kind = f"kind {self.preset}: " if self.preset else ""
        gauge = ", ".join(f"{v:g}" for v in self.gauge)
        return f"{kind}table {table}; head {head}; gauge [{gauge}] mm"


def preset_chain(kind: str, pivot: float = 0.0, centre: Sequence[float] = (0.0, 0.0, 0.0)) -> MachineChain:
    """The chain a preset kind expands to (MACHINE_KINDS): AB-head = head [A, B], A along x, B along y,
    both through (0, 0, pivot), gauge (0, 0, pivot); AC-table = table [A, C] through the table
    centre, along x and z, gauge 0; BC-table = table [B, C], along y and z; BC-head-table = table [C]
    through the centre, head [B] through (0, 0, pivot), gauge (0, 0, pivot)."""
    c = tuple(float(v) for v in centre)
    top = (0.0, 0.0, float(pivot))
    x, y, z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
    if kind == "AB-head":
        return MachineChain((), (RotaryAxis("A", x, top), RotaryAxis("B", y, top)), top, kind)
    if kind == "AC-table":
        return MachineChain((RotaryAxis("A", x, c), RotaryAxis("C", z, c)), (), (0.0, 0.0, 0.0), kind)
    if kind == "BC-table":
        return MachineChain((RotaryAxis("B", y, c), RotaryAxis("C", z, c)), (), (0.0, 0.0, 0.0), kind)
    if kind == "BC-head-table":
        return MachineChain((RotaryAxis("C", z, c),), (RotaryAxis("B", y, top),), top, kind)
    raise ValueError(f"unknown machine kind {kind!r}")


@dataclass(frozen=True)
class Machine:
    """A five-axis machine: its name, its description (MachineChain: the table and head axes and
    the gauge point), the chain (the description's POE chain, or an error model's perturbed one),
    the limits per axis (radians inside the code), the G-code post settings, and whether the file
    gives jerk limits.

    The two rotary axes are ``rotary`` (e.g. ("A", "C")); every method that takes two angles
    (q1, q2) takes them in that order, in radians, as the tool's rotation relative to the
    workpiece (ISO 841 sense; a table turns the workpiece the opposite way), right-hand rule:
    T = R(t_n) ... R(t_1) R(h_1) ... R(h_m) e_z (MachineChain), e.g. AB-head T = Rx(A) Ry(B) e_z;
    AC-table T = Rz(C) Rx(A) e_z; BC-table and BC-head-table T = Rz(C) Ry(B) e_z
    (docs/CONVENTIONS.md)."""

    name: str
    description: MachineChain
    chain: Chain
    limits: Mapping[str, AxisLimits] = field(default_factory=dict)
    post: PostConfig = field(default_factory=PostConfig)
    #: the machine file gives jmax for an axis: the planned time law meets every axis's jmax
    #: (camsmooth.smoothing.jerk); else jmax (a default) is only reported
    jerk_limited: bool = False

    # ---- what the description says ------------------------------------------------------------
    @property
    def kind(self) -> str:
        """The preset kind (MACHINE_KINDS) the machine was described by, or "chain" for a chain
        given explicitly. Words only: code outside this package asks the description, not this."""
        return self.description.preset or "chain"

    @property
    def pivot(self) -> float:
        """Distance (mm) from the tool tip to the gauge point at every axis zero: the head's pivot
        length on a preset head; 0 on a table-table machine, whose tool length the controller applies."""
        return float(np.linalg.norm(self.description.gauge))

    @property
    def table_centre(self) -> tuple[float, float, float]:
        """A point (mm, workpiece frame at zero angles) on the table axis that carries the workpiece
        (where a trunnion's C axis crosses its tilt axis on the presets); the origin without a table."""
        table = self.description.table
        return table[-1].point if table else (0.0, 0.0, 0.0)

    @property
    def has_head(self) -> bool:
        """A rotary axis carries the spindle (the head's pivot lever moves the tip as it turns)."""
        return bool(self.description.head)

    @property
    def has_table(self) -> bool:
        """A rotary axis carries the workpiece."""
        return bool(self.description.table)

    @property
    def linuxcnc_sense(self) -> np.ndarray:
        """(2,) the sign each rotary value carries in a LinuxCNC program, ``rotary`` order. A preset's
        table axis is written as the table's own rotation (LinuxCNC's xyzac-trt / xyzbc-trt
        kinematics: a = -A, c = -C), -1; a head axis +1. A chain given explicitly is written as
        described (a LinuxCNC trt table is described with its own directions): +1."""
        if self.description.preset is None:
            return np.ones(2)
        return np.array([-1.0 if self.description.on_table(n) else 1.0 for n in self.rotary])

    def branch_words(self) -> tuple[str, str]:
        """The two inverse branches (``branch_of`` 0 and 1) in words, by the inner axis' angle:
        e.g. ("A in [-180, 0] deg", "A in (0, 180) deg") on an AC table, ("B in [-90, 90] deg",
        "B beyond +-90 deg") on the AB head. Branch 0 is where
        (exp([w2] th2) h) . (w1 x w2) = a + r cos(th2 - phi) >= 0 (``branch_of``)."""
        nominal = self.description.chain()  # the words of the nominal machine, not of an error model's
        i1, i2 = [i for i, j in enumerate(nominal.joints) if j.kind == "revolute"]
        screws = nominal.joint_screws()
        w1, w2 = (np.asarray(screws[i][0], float) for i in (i1, i2))
        h = np.asarray(nominal.home, float)[:3, 2]
        name = nominal.joints[i2].name
        n = np.cross(w1, w2)
        # f(th) = (h.w2)(w2.n) + cos th (h - (h.w2) w2).n + sin th (w2 x h).n  (Rodrigues)
        a = float((h @ w2) * (w2 @ n))
        b = float((h - (h @ w2) * w2) @ n)
        c = float(np.cross(w2, h) @ n)
        r = float(np.hypot(b, c))
        if r <= abs(a):
            return (f"{name} anywhere", "none") if a >= 0 else ("none", f"{name} anywhere")
        phi = np.degrees(np.arctan2(c, b))
        half = np.degrees(np.arccos(np.clip(-a / r, -1.0, 1.0)))
        lo, hi = (float(np.round(v, 6)) + 0.0 for v in (phi - half, phi + half))
        first = f"{name} in [{lo:g}, {hi:g}] deg"
        if abs(lo + hi) < 1e-9:
            return first, f"{name} beyond +-{hi:g} deg"
        lo2, hi2 = hi, lo + 360.0
        if hi2 > 180.0 + 1e-9:
            lo2, hi2 = lo2 - 360.0, hi2 - 360.0
        return first, f"{name} in ({lo2:g}, {hi2:g}) deg"

    def describe(self) -> str:
        """The machine in a phrase for messages: its name and what it is (the preset or the chain)."""
        return f"{self.name} ({self.description.summary()})"

    # ---- the rotary axes -------------------------------------------------------------------
    @property
    def rotary(self) -> tuple[str, str]:
        """Names of the two rotary axes, in the order every two-angle method takes them."""
        return self.description.rotary

    @property
    def joint_names(self) -> tuple[str, str, str, str, str]:
        """X, Y, Z and the rotary axes: the order of a joint row ``q`` (N, 5) everywhere."""
        return ("X", "Y", "Z") + self.rotary

    def rotary_limits(self) -> tuple[AxisLimits, AxisLimits]:
        """The limits of the two rotary axes (rad), in ``rotary`` order."""
        return self.limits[self.rotary[0]], self.limits[self.rotary[1]]

    @property
    def outer_index(self) -> int:
        """Position (0 or 1) in ``rotary`` of the outer rotary axis: the one whose pole it is (C on
        a table machine, A on the AB head)."""
        return 0 if self._outer_inner()[2].name == self.rotary[0] else 1

    def _outer_inner(self) -> tuple[int, int, Joint, Joint]:
        """Chain indices and joints of the outer (nearer the workpiece) and inner rotary joint."""
        idx = [i for i, j in enumerate(self.chain.joints) if j.kind == "revolute"]
        return idx[0], idx[1], self.chain.joints[idx[0]], self.chain.joints[idx[1]]

    # ---- forward kinematics ----------------------------------------------------------------
    def tool_pose(self, q1: Entry, q2: Entry, X: Entry = 0.0, Y: Entry = 0.0, Z: Entry = 0.0
                  ) -> tuple[tuple[Entry, Entry, Entry], tuple[Entry, Entry, Entry]]:
        """(tip, axis) in the workpiece frame for commanded axes (q1, q2 rad in ``rotary`` order;
        X, Y, Z mm). tip: the tool tip (CL point), axis: unit tool axis T (tip toward spindle).
        Entries are numpy arrays or CasADi expressions, as given."""
        r1, r2 = self.rotary
        f = self.chain.forward({"X": X, "Y": Y, "Z": Z, r1: q1, r2: q2})
        return f.p, (f.R[0][2], f.R[1][2], f.R[2][2])

    def tool_axis(self, q1: Entry, q2: Entry) -> tuple[Entry, Entry, Entry]:
        """Unit tool axis T(q1, q2) in the workpiece frame (class docstring; METHODS section 1 for
        the AB head: (sin B, -sin A cos B, cos A cos B))."""
        return self.tool_pose(q1, q2)[1]

    def tool_axis_np(self, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
        """tool_axis for numpy arrays, as an (N, 3) array."""
        q1 = np.asarray(q1, dtype=float)
        q2 = np.asarray(q2, dtype=float)
        return np.stack(np.broadcast_arrays(*self.tool_axis(q1, q2)), axis=-1)

    def tool_pose_np(self, q1: np.ndarray, q2: np.ndarray, X: np.ndarray, Y: np.ndarray, Z: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray]:
        """tool_pose for numpy arrays: (tip (N,3) mm, axis (N,3))."""
        args = [np.asarray(a, dtype=float) for a in (q1, q2, X, Y, Z)]
        tip, axis = self.tool_pose(*args)
        return (np.stack(np.broadcast_arrays(*tip), axis=-1), np.stack(np.broadcast_arrays(*axis), axis=-1))

    def linear_axes(self, cl: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
        """(X, Y, Z) mm that put the tool tip at cl (N, 3, workpiece frame) at rotary angles
        (q1, q2) rad. The linear axes enter the chain as prismatic joints, so at fixed angles the
        tip is affine in them: tip = tip0 + J (X, Y, Z), with J's columns the tip's unit steps
        from the chain itself; solved per point (J is a rotation on the nominal machine: identity
        on a head, the table's rotation on a table; near one on an error model's, whose linear axes
        may be out of square). Nominal closed forms (issue 18): AB head pivot = CL + L_p T; table
        c + R_wp (CL - c); BC head-table c + Rz(-C)(CL - c) + L_p Ry(B) e_z."""
        cl = np.atleast_2d(np.asarray(cl, float))
        n = len(cl)
        q1 = np.broadcast_to(np.asarray(q1, float), (n,))
        q2 = np.broadcast_to(np.asarray(q2, float), (n,))
        zero = np.zeros(n)
        tip0 = self.tool_pose_np(q1, q2, zero, zero, zero)[0]
        cols = [self.tool_pose_np(q1, q2, *(np.full(n, float(k == j)) for k in range(3)))[0] - tip0
                for j in range(3)]
        J = np.stack(cols, axis=-1)  # (n, 3, 3): columns d tip / d (X, Y, Z)
        return np.linalg.solve(J, (cl - tip0)[..., None])[..., 0]

    # ---- inverse kinematics ----------------------------------------------------------------
    def pole_angle(self, T: np.ndarray) -> np.ndarray:
        """Angle (rad) between unit tool axes T (N, 3, workpiece frame) and the nearest pole: the
        directions where the outer rotary axis is parallel to the tool axis and its angle is
        undefined (the C axis of a table machine at tilt 0; B = +-90 deg on the AB head). Measured
        at the home configuration, where the outer axis has its nominal direction."""
        T = np.atleast_2d(np.asarray(T, float))
        w1, _ = self.chain.joint_screws()[self._outer_inner()[0]]
        return np.arccos(np.clip(np.abs(T @ w1), 0.0, 1.0))

    def inverse_axis(self, T: np.ndarray) -> np.ndarray:
        """Both inverse branches for unit tool axes T (N, 3, workpiece frame): (N, 2, 2) array
        [point, branch, (q1, q2) in ``rotary`` order], radians wrapped to (-pi, pi].

        Paden-Kahan subproblem 2 (Murray, Li & Sastry 1994, section 3.2.3; docs/METHODS.md
        section 1) on the chain's own rotary screws: exp([w1] th1) exp([w2] th2) h = T with w1
        the outer and w2 the inner rotary axis and h the home tool axis; the intermediate
        direction z = a w1 + b w2 + g (w1 x w2) has two solutions +-g, the two branches (AB head:
        B = asin(i), A = atan2(-j, k) and B' = pi - B, A' = A + pi; tables: tilt' = -tilt,
        C' = C + pi). At the pole the outer angle is undefined; it is returned as 0."""
        T = np.atleast_2d(np.asarray(T, dtype=float))
        _, _, j1, j2 = self._outer_inner()
        w1, w2, h, alpha, beta, g2 = self._subproblem2(T)
        c12 = np.cross(w1, w2)
        gam = np.sqrt(np.clip(g2, 0.0, None))
        out = np.empty((len(T), 2, 2))
        order = (0, 1) if (j1.name, j2.name) == self.rotary else (1, 0)
        for branch, sign in enumerate((1.0, -1.0)):
            z = alpha[:, None] * w1 + beta[:, None] * w2 + (sign * gam)[:, None] * c12
            th2 = _subproblem1(w2, np.broadcast_to(h, z.shape), z)
            th1 = _subproblem1(w1, z, T)
            pair = (th1, th2)
            out[:, branch, 0] = _wrap(pair[order[0]])
            out[:, branch, 1] = _wrap(pair[order[1]])
        return out

    def _subproblem2(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                                   np.ndarray]:
        """Paden-Kahan subproblem 2's coefficients for unit axes T (N, 3): the outer and inner
        rotary directions w1, w2, the home tool axis h, and alpha, beta, g^2 (N,) of the
        intermediate direction z = alpha w1 + beta w2 +- g (w1 x w2); g^2 < 0 where T is outside
        the cone the two axes sweep."""
        i1, i2, _, _ = self._outer_inner()
        screws = self.chain.joint_screws()
        w1, w2 = (np.asarray(screws[i][0], float) for i in (i1, i2))
        h = np.asarray(self.chain.home, float)[:3, 2]
        a = float(w1 @ w2)
        c12 = np.cross(w1, w2)
        den = a * a - 1.0
        alpha = (a * (w2 @ h) - T @ w1) / den
        beta = (a * (T @ w1) - w2 @ h) / den
        g2 = (h @ h - alpha ** 2 - beta ** 2 - 2 * alpha * beta * a) / (c12 @ c12)
        return w1, w2, h, alpha, beta, g2

    def reachable(self, T: np.ndarray) -> np.ndarray:
        """Mask (N,) of the unit tool axes T (N, 3, workpiece frame) that some rotary angles reach,
        travel aside: all of them on an orthogonal chain; on a nutating one (an inclined axis)
        those inside the cone its axes sweep (subproblem 2's g^2 >= -REACH_EPS)."""
        T = np.atleast_2d(np.asarray(T, dtype=float))
        return self._subproblem2(T)[5] >= -REACH_EPS

    def nearest_with_outer(self, T: np.ndarray, outer: np.ndarray) -> np.ndarray:
        """The angles (N, 2) rad in ``rotary`` order with the outer rotary axis (the C axis of a
        table) held at ``outer`` (N,) rad whose tool axis is nearest T (N, 3, unit, workpiece
        frame): the inner angle turns the home axis h to the projection of exp(-[w1] outer) T on
        the inner axis' circle (Paden-Kahan subproblem 1). The tool axis then leaves T by at most
        the angle between T and the inner axis' circle: near the pole, at most the pole angle.
        How the singularity cone of a CAM system linearises the pole (camsmooth.smoothing.pole)."""
        T = np.atleast_2d(np.asarray(T, float))
        outer = np.broadcast_to(np.asarray(outer, float), (len(T),))
        i1, i2, j1, _ = self._outer_inner()
        screws = self.chain.joint_screws()
        w1, w2 = (np.asarray(screws[i][0], float) for i in (i1, i2))
        h = np.asarray(self.chain.home, float)[:3, 2]
        back = exp_twist(w1, np.zeros(3), -outer).to_numpy(len(T))[:, :3, :3] @ T[:, :, None]
        inner = _subproblem1(w2, np.broadcast_to(h, T.shape), back[:, :, 0])
        return np.column_stack([outer, inner] if j1.name == self.rotary[0] else [inner, outer])

    def branch_of(self, q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
        """Which inverse branch (0 or 1, as ``inverse_axis`` numbers them) the angles (q1, q2) rad
        are on: the sign of the +-g component of subproblem 2, read from the inner axis alone
        (exp([w2] th2) h . (w1 x w2) >= 0: branch 0). Branch 0 is ``branch_words()[0]``; points
        within 1e-12 of the boundary count as branch 0."""
        i1, i2, _, j2 = self._outer_inner()
        screws = self.chain.joint_screws()
        w1, w2 = (np.asarray(screws[i][0], float) for i in (i1, i2))
        h = np.asarray(self.chain.home, float)[:3, 2]
        inner = np.atleast_1d(np.asarray(q1 if j2.name == self.rotary[0] else q2, float))
        z = exp_twist(w2, np.zeros(3), inner).to_numpy(len(inner))[:, :3, :3] @ h
        return (z @ np.cross(w1, w2) < -1e-12).astype(int)

    def within(self, name: str, values: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        """Mask of values within the travel of axis `name` (True when the axis has no limits)."""
        lim = self.limits.get(name)
        values = np.asarray(values, dtype=float)
        if lim is None:
            return np.ones(values.shape, dtype=bool)
        return (values >= lim.min - tol) & (values <= lim.max + tol)

    def inverse_candidates(self, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every (q1, q2) reaching unit axes T (N, 3) within +-2 turns: both branches of
        ``inverse_axis`` with each angle shifted by -4 pi ... +4 pi. Returns candidates (N, 50, 2)
        rad and a mask (N, 50) of those within the travel: every solution within limits, per point
        (an axis without travel limits, a continuous C, is unwound by ``solve_row`` instead)."""
        sols = self.inverse_axis(T)
        shifts = 2 * np.pi * np.arange(-2, 3)
        grid = np.stack(np.meshgrid(shifts, shifts, indexing="ij"), -1).reshape(-1, 2)
        cand = (sols[:, :, None, :] + grid[None, None]).reshape(len(sols), -1, 2)
        r1, r2 = self.rotary
        ok = self.within(r1, cand[..., 0]) & self.within(r2, cand[..., 1]) & self.reachable(T)[:, None]
        return cand, ok

    def solve_row(self, T: np.ndarray, cl: np.ndarray | None = None,
                  previous: tuple[float, float] | None = None) -> IKResult:
        """Inverse kinematics along one row: for every point the (q1, q2) solution within the
        travel limits nearest the previous point's solution (both branches, every turn within
        the travel; an axis without travel limits, a continuous C, is unwound to the turn nearest
        the previous point, so it may pass any number of turns); the first point takes the
        solution nearest ``previous`` (default (0, 0)). At the pole (``pole_angle`` < POLE_EPS)
        the outer angle is held at the previous point's. Points with no solution in limits are
        listed in ``unreachable`` (indices) and carry the nearest out-of-limit branch so the row
        stays continuous.

        T: (N,3) unit tool axes, workpiece frame; cl: (N,3) tool tips, mm (for X, Y, Z).
        Returns the angles named by the machine's rotary axes (IKResult.rotary: ``r.rotary["C"]``)."""
        T = np.atleast_2d(np.asarray(T, dtype=float))
        n = len(T)
        prev = np.array(previous if previous is not None else (0.0, 0.0), dtype=float)
        cand, ok = self.inverse_candidates(T)
        free = np.array([not np.isfinite(lim.max - lim.min) for lim in self.rotary_limits()])
        pole = self.pole_angle(T) < POLE_EPS
        outer = self.outer_index
        out = np.empty((n, 2))
        reach = ok.any(axis=1)
        # A sequential choice is needed only where the reachable set is ambiguous; the usual case
        # on a machine with limited travel (exactly one reachable candidate at every point, no
        # pole) is vectorised.
        unique = ok.sum(axis=1) == 1
        if np.all(unique) and not free.any() and not pole.any():
            out[:] = cand[np.arange(n), ok.argmax(axis=1)]
        else:
            out[:] = _nearest_sequence(cand, ok, reach, free, pole, outer, prev)
        xyz = None
        if cl is not None:
            xyz = self.linear_axes(cl, out[:, 0], out[:, 1])
            for k, name in enumerate("XYZ"):
                reach &= self.within(name, xyz[:, k])
        return IKResult(rotary=RotaryValues(self.rotary, out), xyz=xyz, unreachable=np.flatnonzero(~reach))


@njit(cache=True)
def _nearest_sequence(cand: np.ndarray, ok: np.ndarray, reach: np.ndarray, free: np.ndarray, pole: np.ndarray,
                      outer: int, prev: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    """``Machine.solve_row``'s sequential choice: per point, of the candidates (N, K, 2) within
    travel (``ok``; all of them where none is, ``reach`` False), the one nearest the previous
    point's choice (the first point: ``prev``), an axis without travel limits (``free``) unwound to
    the turn nearest it, and the outer angle held at the pole (``pole``)."""
    n, m = ok.shape
    out = np.empty((n, 2))
    two_pi = 2.0 * np.pi
    ref0, ref1 = prev[0], prev[1]
    for i in range(n):
        best, b0, b1 = np.inf, 0.0, 0.0
        for j in range(m):
            if reach[i] and not ok[i, j]:
                continue
            c0, c1 = cand[i, j, 0], cand[i, j, 1]
            if pole[i]:
                if outer == 0:
                    c0 = ref0
                else:
                    c1 = ref1
            if free[0]:
                c0 += two_pi * np.floor((ref0 - c0) / two_pi + 0.5)
            if free[1]:
                c1 += two_pi * np.floor((ref1 - c1) / two_pi + 0.5)
            d = (c0 - ref0) ** 2 + (c1 - ref1) ** 2
            if d < best:
                best, b0, b1 = d, c0, c1
        out[i, 0], out[i, 1] = b0, b1
        ref0, ref1 = b0, b1
    return out


def _subproblem1(w: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Paden-Kahan subproblem 1 for directions: the angle th (rad, right-hand about the unit axis
    w) with exp([w] th) u = v, for rows of u, v (N, 3); 0 where u or v is parallel to w."""
    up = u - np.outer(u @ w, w)
    vp = v - np.outer(v @ w, w)
    return np.arctan2(np.cross(up, vp) @ w, np.einsum("ij,ij->i", up, vp))


@dataclass(frozen=True)
class IKResult:
    """Inverse-kinematics result along a row: ``rotary`` the angles (N, 2) rad named by the
    machine's rotary axes (``Machine.rotary``: ``r.rotary["A"]``, ``r.rotary["C"]`` on an AC table;
    machine sign convention), xyz (N,3) mm or None (linear axes, machine frame), and the indices of
    the points with no solution within the limits."""

    rotary: RotaryValues
    xyz: np.ndarray | None
    unreachable: np.ndarray


def _wrap(a: np.ndarray) -> np.ndarray:
    """Wrap angles to (-pi, pi]."""
    return -((-np.asarray(a) + np.pi) % (2 * np.pi) - np.pi)


def kind_chain(kind: str, pivot: float, centre: Sequence[float] = (0.0, 0.0, 0.0)) -> Chain:
    """The nominal POE chain of a preset kind (MACHINE_KINDS; ``preset_chain``)."""
    return preset_chain(kind, pivot, centre).chain()


def machine_from_header(kind: str | None, pivot: float | None, centre: Sequence[float], machine: Machine | None,
                        rotary: Sequence[str] | None = None, file: str | None = None, line: int | None = None
                        ) -> Machine:
    """The machine a program of camsmooth's was written for, from its header's words: ``kind``
    (a preset, "chain", or None for older headers), the pivot (mm) and table centre (mm) and the
    rotary letters it commands. With ``machine`` given, that machine, after checking it has those
    rotary axes; without, the nominal preset machine of the header (the AB head without a kind).
    InputError naming the file and line for an unknown kind, a chain machine not given, or rotary
    axes the machine does not have."""
    from camsmooth.errors import InputError

    if kind is not None and kind not in MACHINE_KINDS and kind != "chain":
        raise InputError(f"the camsmooth post header gives kind={kind}: not a machine kind "
                         f"({', '.join(MACHINE_KINDS)}, chain)", file=file, line=line)
    if machine is not None:
        letters = tuple(rotary) if rotary else (MACHINE_KINDS[kind] if kind in MACHINE_KINDS else machine.rotary)
        if letters != machine.rotary:
            written = (f"an {kind} machine" if kind in MACHINE_KINDS else "a machine given by its chain"
                       if kind == "chain" else "a machine")
            own = f"an {machine.kind}" if machine.description.preset else "a machine given by its chain"
            raise InputError(f"the program was written for {written} (rotary axes {','.join(letters)}) but the "
                             f"machine is {own} ({machine.name}, rotary axes {','.join(machine.rotary)}): give the "
                             "machine file it was written for (--machine)", file=file, line=line)
        return machine
    if kind == "chain":
        raise InputError("the program was written for a machine described by its chain: give its machine file "
                         "(--machine)", file=file, line=line)
    kind = kind or "AB-head"
    desc = preset_chain(kind)
    base = load_machine(None)
    pivot = (base.pivot if pivot is None else pivot) if desc.head else 0.0
    if not desc.table:  # the default machine's name and post with the header's pivot
        return preset_machine(kind, pivot, centre, base.name, post=base.post)
    return preset_machine(kind, pivot, centre, f"{kind} from the program header", post=base.post)


def axis_limits(machine: Machine) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vmax, amax, jmax) per joint in ``machine.joint_names`` order (X Y Z: mm/s, mm/s^2, mm/s^3;
    the rotary axes: rad/s, rad/s^2, rad/s^3); inf where the machine gives no limit."""
    lims = [machine.limits.get(a) for a in machine.joint_names]
    out = [np.array([getattr(lim, k, np.inf) if lim is not None else np.inf for lim in lims], float)
           for k in ("vmax", "amax", "jmax")]
    return out[0], out[1], out[2]


def nominal_machine(letters: Sequence[str]) -> Machine:
    """The nominal machine a program that names only its rotary letters is read on: A B the default
    AB head; A C and B C the preset trunnion of those axes, centred at the origin, with travel and
    dynamics that bind nothing (1e6 deg, 3600 deg/s and deg/s^2). InputError for other letters."""
    from camsmooth.errors import InputError

    letters = tuple(letters)
    if letters == ("A", "B"):
        return load_machine(None)
    kind = next((k for k, v in MACHINE_KINDS.items() if v == letters and not preset_chain(k).head), None)
    if kind is None:
        raise InputError(f"no nominal machine has the rotary axes {', '.join(letters)}: give the machine file "
                         "(--machine)")
    free = AxisLimits(-np.radians(1e6), np.radians(1e6), np.radians(3600.0), np.radians(3600.0),
                      np.radians(ROTARY_JMAX_DEFAULT))
    linear = AxisLimits(-np.inf, np.inf, **LINEAR_DEFAULTS)
    return preset_machine(kind, 0.0, (0.0, 0.0, 0.0), f"nominal {kind}",
                          {letters[0]: free, letters[1]: free, "X": linear, "Y": linear, "Z": linear})


def preset_machine(kind: str, pivot: float = 0.0, centre: Sequence[float] = (0.0, 0.0, 0.0), name: str | None = None,
                   limits: Mapping[str, AxisLimits] | None = None, post: PostConfig | None = None) -> Machine:
    """A machine of a preset kind with the given pivot (mm, head kinds) and table centre (mm,
    table kinds), limits (rad) and post settings (default: none given, the generic post)."""
    desc = preset_chain(kind, pivot, centre)
    return Machine(name or kind.replace("-", " "), desc, desc.chain(), dict(limits or {}), post or PostConfig())


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

# G-code post (camsmooth.post): dialect = "generic" | "linuxcnc" | "fanuc" | "heidenhain" |
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

    ``[machine]`` gives either a preset ``kind`` (MACHINE_KINDS, with ``pivot`` on a head and
    ``table_centre`` on a table: ``preset_chain``) or the chain itself: ``table`` and ``head`` (the
    rotary axis names from the bed to the workpiece and from the ram to the spindle, two in all),
    ``gauge`` (mm, required with a head) and per rotary axis ``direction`` and ``point``
    (``chain_from_dict``). InputError naming ``source`` and the key for: a missing or wrongly typed
    table or key (a value where a table belongs, a string or boolean where a number belongs),
    non-finite numbers, an unsupported kind, a kind given with a chain, pivot < 0 (or a pivot on a
    table-table machine), min >= max, vmax, amax or jmax <= 0, an axis with only one of min and max,
    unknown tables (top level or axis) or keys. The rotary axes ``[axis.*]`` are those of the
    description; the table's last axis (the one carrying the workpiece) without min and max is
    continuous. X, Y, Z: vmax, amax, jmax default to LINEAR_DEFAULTS and a missing table to
    unlimited travel with those dynamics; rotary axes: jmax defaults to ROTARY_JMAX_DEFAULT.
    """
    from camsmooth.errors import InputError

    _known_tables(data, source)
    m = _table(data, "machine", "machine", source)
    unknown = sorted(set(m) - set(_MACHINE_KEYS))
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)} in [machine] (known: {', '.join(_MACHINE_KEYS)})",
                         file=source)
    axes = _table(data, "axis", "axis", source, required=False) or {}
    for ax in axes:
        _table(axes, ax, f"axis.{ax}", source)
    chained = [k for k in _CHAIN_KEYS if k in m]
    if chained and "kind" in m:
        raise InputError(f"[machine] gives kind = {_toml_repr(m['kind'])} and {', '.join(chained)}: a machine is "
                         "a preset kind or a chain (table, head, gauge), not both", file=source)
    if chained:
        desc = chain_from_dict(m, axes, source)
        default_name = "five-axis machine (" + " ".join(desc.rotary) + ")"
    else:
        desc = _preset_from_dict(m, axes, source)
        default_name = str(desc.preset).replace("-", " ")
    rotary = desc.rotary
    name = m.get("name", default_name)
    if not isinstance(name, str):
        raise InputError(f"[machine] name must be a string, got {_toml_repr(name)}", file=source)
    allowed = set(rotary) | {"X", "Y", "Z"}
    unknown = set(axes) - allowed
    if unknown:
        which = f"an {desc.preset} machine" if desc.preset else "the machine"
        raise InputError(f"unknown axis table(s) {', '.join(sorted(unknown))} ({which} has "
                         f"{', '.join(rotary)}, X, Y, Z)", file=source)
    carrier = desc.table[-1].name if desc.table else None  # the table axis that may turn without end
    limits: dict[str, AxisLimits] = {}
    for ax in rotary:
        t = _table(axes, ax, f"axis.{ax}", source)
        _known_keys(t, ax, source, _AXIS_KEYS + (("direction", "point") if chained else ()))
        travel = ("min", "max")
        given = [k for k in travel if k in t]
        if ax == carrier and not given:
            travel = ()  # a continuous table axis: no travel limits
        elif ax == carrier and len(given) == 1:
            raise InputError(f"[axis.{ax}] gives {given[0]} but not {'max' if given[0] == 'min' else 'min'}: give "
                             "both or neither (a continuous axis)", file=source)
        vals = {k: _number(t, k, f"axis.{ax}", source) for k in travel + ("vmax", "amax")}
        vals.setdefault("min", -np.inf)
        vals.setdefault("max", np.inf)
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
    return Machine(name, desc, desc.chain(), limits, post_from_dict(data.get("post", {}), source),
                   jerk_limited=any(isinstance(t, dict) and "jmax" in t for t in axes.values()))


def _preset_from_dict(m: Mapping[str, Any], axes: Mapping[str, Any], source: str) -> MachineChain:
    """The MachineChain of ``[machine] kind`` with its pivot and table centre (machine_from_dict)."""
    from camsmooth.errors import InputError

    kind = m.get("kind")
    if kind not in MACHINE_KINDS:
        shown = _toml_repr(kind) if kind is not None else "missing"
        known = ", ".join(f'"{k}"' for k in MACHINE_KINDS)
        raise InputError(f"[machine] kind = {shown} is not supported (supported: {known}; or describe the chain "
                         "with table, head and gauge)", file=source)
    head = bool(preset_chain(kind).head)
    if head:
        pivot = _number(m, "pivot", "machine", source)
        if pivot < 0:
            raise InputError(f"[machine] pivot must be >= 0 mm, got {pivot:g}", file=source)
    else:
        if "pivot" in m:
            raise InputError(f"[machine] pivot: a table-table machine ({kind}) has no head pivot (its tool length is "
                             "the controller's); remove the key", file=source)
        pivot = 0.0
    centre = (0.0, 0.0, 0.0)
    if "table_centre" in m:
        if not preset_chain(kind).table:
            raise InputError(f"[machine] table_centre: an {kind} machine has no rotary table; remove the key",
                             file=source)
        centre = _vector(m["table_centre"], "[machine] table_centre", source)
    for ax in MACHINE_KINDS[kind]:
        t = axes.get(ax)
        if isinstance(t, Mapping) and ("direction" in t or "point" in t):
            raise InputError(f"[axis.{ax}] direction/point: the kind {kind} fixes its axes' lines; describe the "
                             "machine by its chain (table, head, gauge) instead of kind to give them", file=source)
    return preset_chain(kind, pivot, centre)


def chain_from_dict(m: Mapping[str, Any], axes: Mapping[str, Any], source: str = "<machine>") -> MachineChain:
    """The MachineChain of a machine file that gives its chain: ``[machine] table`` and ``head``
    (rotary axis names, A B or C, two in all), ``gauge`` (mm; required when ``head`` is not empty,
    else default 0) and per rotary axis ``direction`` (normalised; machine frame at every axis zero)
    and ``point`` (mm: a table axis in the workpiece frame, a head axis from the tool tip).
    InputError naming the key for a wrong name, count or vector, parallel axes, or an axis nearest
    the tool that lies along the tool (it could not turn it)."""
    from camsmooth.errors import InputError

    names: dict[str, list[str]] = {}
    for key in ("table", "head"):
        v = m.get(key, [])
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            raise InputError(f"[machine] {key} must be a list of axis names (e.g. [\"A\", \"C\"]), got {_toml_repr(v)}",
                             file=source)
        bad = [x for x in v if x not in ROTARY_NAMES]
        if bad:
            raise InputError(f"[machine] {key}: {', '.join(repr(x) for x in bad)} is not a rotary axis name "
                             f"({', '.join(ROTARY_NAMES)})", file=source)
        names[key] = list(v)
    every = names["table"] + names["head"]
    if len(every) != 2 or len(set(every)) != 2:
        raise InputError(f"[machine] table = {names['table']} and head = {names['head']} must name exactly two "
                         "different rotary axes in all", file=source)
    if names["head"] and "gauge" not in m:
        raise InputError("[machine] gauge is required when head is not empty: the point of the ram that X Y Z "
                         "command, from the tool tip with every axis at zero (mm)", file=source)
    gauge = _vector(m.get("gauge", [0.0, 0.0, 0.0]), "[machine] gauge", source)

    def one(name: str) -> RotaryAxis:
        t = _table(axes, name, f"axis.{name}", source)
        for key in ("direction", "point"):
            if key not in t:
                raise InputError(f"missing key '{key}' in [axis.{name}] (a machine given by its chain gives each "
                                 "rotary axis' direction and point)", file=source)
        d = np.asarray(_vector(t["direction"], f"[axis.{name}] direction", source))
        if np.linalg.norm(d) < 1e-9:
            raise InputError(f"[axis.{name}] direction must not be zero", file=source)
        d = d / np.linalg.norm(d)
        return RotaryAxis(name, tuple(float(x) for x in d), _vector(t["point"], f"[axis.{name}] point", source))

    desc = MachineChain(tuple(one(n) for n in names["table"]), tuple(one(n) for n in names["head"]), gauge)
    outer, inner = desc.axes
    if abs(float(np.dot(outer.direction, inner.direction))) > 1.0 - 1e-9:
        raise InputError(f"[axis.{outer.name}] and [axis.{inner.name}] directions are parallel: two parallel rotary "
                         "axes cannot point the tool", file=source)
    if abs(inner.direction[2]) > 1.0 - 1e-9:
        raise InputError(f"[axis.{inner.name}] direction is along the tool (z with every axis at zero): the axis "
                         "nearest the tool cannot turn it", file=source)
    return desc


def _vector(v: Any, where: str, source: str) -> tuple[float, float, float]:
    """Three finite numbers [x, y, z] of a machine file; InputError naming ``where`` otherwise."""
    from camsmooth.errors import InputError

    if (not isinstance(v, list) or len(v) != 3
            or any(isinstance(x, bool) or not isinstance(x, (int, float)) or not np.isfinite(x) for x in v)):
        raise InputError(f"{where} must be three finite numbers [x, y, z], got {_toml_repr(v)}", file=source)
    return (float(v[0]), float(v[1]), float(v[2]))


_AXIS_KEYS = ("min", "max", "vmax", "amax", "jmax")
_TOP_TABLES = ("machine", "axis", "post")
_CHAIN_KEYS = ("table", "head", "gauge")
_MACHINE_KEYS = ("name", "kind", "pivot", "table_centre") + _CHAIN_KEYS


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


def _known_keys(table: Mapping[str, Any], ax: str, source: str, known: Sequence[str] = _AXIS_KEYS) -> None:
    """InputError for a key an [axis.*] table does not know (a misspelt limit would be ignored)."""
    from camsmooth.errors import InputError

    unknown = sorted(set(table) - set(known))
    if unknown:
        raise InputError(f"unknown key(s) {', '.join(unknown)} in [axis.{ax}] (known: {', '.join(known)})",
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
