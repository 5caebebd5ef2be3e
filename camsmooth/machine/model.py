"""The machine model: every modelled deviation of the real machine from the nominal one, in one
class (``ErrorModel``) with one JSON reader/writer and one function for the real pose
(``ErrorModel.real_frame``), used by the smoother (CasADi), ``predict``, the calibration
simulators and the diagnosis simulator (numpy).

Geometric errors of the rotary axes, spindle and tool (ISO 230-1 style names; METHODS.md sections 3, 4)
-------------------------------------------------------------------------------------------------------
All at the home configuration (all axes at 0), workpiece frame W, right-hand rule.

* A axis (nominal: the x axis through the head pivot p0): the real A axis is the line through
  p0 + (0, EY0A, EZ0A) with direction w_A = Rz(EC0A) Ry(EB0A) e_x. This is exactly the METHODS
  section 3 direction (cos S_az cos S_ay, -cos S_az sin S_ay, -sin S_az) with S_az = EB0A and
  S_ay = -EC0A.
* B axis, relative to the real A axis: with F_A = [R_A, p_A] the frame of the real A axis
  (R_A = Rz(EC0A) Ry(EB0A), p_A its point above), the B axis is the line through
  F_A (EX0B, 0, EZ0B) with direction R_A Rx(EA0B) Rz(EC0B) e_y. Without A errors this is the
  METHODS section 3 direction (-sin S_bx, cos S_bx cos S_bz, -cos S_bx sin S_bz) with
  S_bx = EC0B, S_bz = -EA0B. EZ0B is therefore the distance between the A and B lines, EC0B the
  out-of-squareness of B to A, EA0B a tilt of B about A (equivalent to an A zero offset).
* Spindle relative to the (nominal) head: the spindle is rotated about the pivot by
  R_S = Rx(EA0S) Ry(EB0S) (so its axis is (sin EB0S, -sin EA0S cos EB0S, cos EA0S cos EB0S), like
  extra A/B angles) and shifted by (EX0S, EY0S, 0).
* EZ0T: tool-length error, positive = tool longer than nominal (tip further from the spindle).

Axis-line errors change only the joint screws (S = (w, -w x p)); spindle, tool, spindle-screw
and spindle-frame thermal errors change only the home pose M:

    M = [R_S, p0 + (EX0S, EY0S, 0) - R_S p0] M_nominal Trans(0, 0, -EZ0T) T_screw T_thermal,

where T_screw (the static part of the spindle screw model, see SpindleScrew) and T_thermal (see
below) act in the tool-tip frame. So an axis-line error alone does not move the tool at the home
pose; its effect grows as the axis turns (the usual convention of kinematic calibration).

Sign convention of the first-order error vectors (METHODS section 3, verified in
tests/test_errormodel.py): the error matrix T_e = T_i^-1 T_r is a BODY-frame error. The stated B
and C rows agree with the exact POE error to O(S^2) as written. The stated A row does not agree in
any frame: its e_y term must read -S_az + S_az cos a - S_ay sin a (the sign of the S_ay sin a
term is flipped in the source); e_z is as stated.

Table machines (AC-table, BC-table, BC-head-table; METHODS.md section 3.1)
-------------------------------------------------------------------------
The same parameters describe the axis lines of a rotary table, located at the home
configuration in the machine frame (which is the workpiece frame at C = tilt = 0), relative to
the nominal lines through the table centre c (``Machine.table_centre``), ISO 230-1 / ISO 230-7
style. Each axis line is given on its own (not relative to the other rotary axis):

* C (nominal: the z axis through c): the line through c + (EX0C, EY0C, 0) with direction
  w_C = Rx(EA0C) Ry(EB0C) e_z = (sin EB0C, -sin EA0C cos EB0C, cos EA0C cos EB0C). This is the
  METHODS section 3 direction (-sin S_cx, -cos S_cx sin S_cy, cos S_cx cos S_cy) with
  S_cx = -EB0C, S_cy = EA0C.
* A tilt axis of an AC table (nominal: the x axis through c): the line through
  c + (0, EY0A, EZ0A) with direction Rz(EC0A) Ry(EB0A) e_x (the head's A convention).
* B tilt axis of a BC table (nominal: the y axis through c): the line through c + (EX0B, 0, EZ0B)
  with direction Rx(EA0B) Rz(EC0B) e_y (the head's B convention without A errors).
* B head axis of a BC-head-table (nominal: the y axis through the pivot): the line through
  pivot + (EX0B, 0, EZ0B), direction Rx(EA0B) Rz(EC0B) e_y; C as on a table.

A line has no location error along itself (no EZ0C, EX0A, EY0B) and an angular zero offset of
an axis is not one of these parameters. The names of the tilt axis are those of the AB head's A
or B, with another meaning, so a model states the machine kind it was made for
(``ErrorModel.kind``, JSON ``machine_kind``); ROTARY_BY_KIND lists each kind's parameters. The
spindle and tool errors and the linear-axis errors below mean the same on every kind (the
spindle tilt turns about the pivot of a head, about the home tool tip on a table-table machine).
Straightness and the machine-frame thermal growth are translations of the carriage in the
machine frame; on a table machine they reach the workpiece frame turned by the table
(``carriage_rotation``).

Geometric errors of the linear axes (ISO 230-1: positioning, straightness, squareness)
--------------------------------------------------------------------------------------
For the linear axes X, Y, Z (positions q in mm, measured from the machine zero):

* positioning E_AA(q) = EAA q + EAA2 q^2 + EAA3 q^3 (mm; EAA the scale error in mm per mm of
  travel, EAA2, EAA3 the smooth pitch error of the screw): the carriage of axis A really moves
  to q + E_AA(q). Seen by an external measurement of the axis (a laser on the carriage) and by
  the tool tip; not by the axis's own encoder.
* straightness E_BA(q) = EBA2 q^2 + EBA3 q^3 (mm): the carriage of axis A moves off its line
  in direction B (B another linear axis). Its linear part is the squareness below, so
  straightness starts with q^2 (ISO 230-1 takes straightness about the reference line).
* squareness, the real directions of Y and Z relative to X (the reference axis): Y along
  Rz(EC0Y) e_y = (-sin EC0Y, cos EC0Y, 0), Z along Rx(EA0Z) Ry(EB0Z) e_z (the convention of the
  spindle tilt above). EC0Y > 0: the angle between +X and +Y is 90 deg + EC0Y.

Squareness changes the screws of Y and Z; positioning changes the joint values the chain sees;
straightness is a translation of the head carriage (``RealChain``). These work in numpy and
CasADi alike.

Servo, reversal and clock (the controller side; used by the diagnosis, METHODS section 6)
---------------------------------------------------------------------------------------
``tau[a]``: axis a follows its command through a first-order lag of time constant 1/Kv (s);
``backlash[a]``: reversal error (mm; rad for A, B): the axis stands -(b/2) sign(last commanded
direction) off its command; ``offset_s``: the recording clock runs this far behind the
program's. ``runout = (r cos phi, r sin phi)`` (mm): the tool tip runs out once per spindle
revolution, (r cos(theta + phi), r sin(theta + phi)) in the tool frame's xy at spindle angle theta.

Thermal growth (METHODS section 5): one first-order model in two frames
------------------------------------------------------------------------
Spindle frame (moves with the head): dx, dy, dz (mm) the displacement of the tool tip in the
tool frame, exz, eyz (rad) the tilt of the spindle in the xz and yz planes, such that a point of
the spindle a height h above the tip (along the tool axis T) moves by (dx - exz h, dy - eyz h,
dz), i.e. a rotation by (eyz, -exz, 0) about the tip and the real axis is ~ (-exz, -eyz, 1).
Machine frame (the axes, column and ram growing; independent of the head's pose): mx, my, mz
(mm) the displacement of the tool tip along the workpiece frame's x, y, z.
Each element e follows tau de/dt = gain * rpm / 1000 - e from a cold start (e = 0), integrated
exactly by ``first_order_knots`` (the one first-order integrator of the project, also used for
the servo lag): the speed is held between samples (``hold='step'``) or linear between program
rows (``hold='linear'``); see ``ErrorModel.thermal_state``.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numba import njit

from camsmooth.errors import InputError
from camsmooth.io.atomic import write_text_atomic
from camsmooth.io.table import read_text_file
from camsmooth.machine.kinematics import IDENTITY, MACHINE_KINDS, Chain, Frame, Machine, exp_twist

# ----------------------------------------------------------------------------------------------
# parameter tables
ROTARY_GEOMETRIC: dict[str, tuple[str, str]] = {
    "EY0A": ("mm", "A axis line offset in y"),
    "EZ0A": ("mm", "A axis line offset in z"),
    "EB0A": ("rad", "A axis squareness, rotation about y"),
    "EC0A": ("rad", "A axis squareness, rotation about z"),
    "EX0B": ("mm", "B axis line offset in x, relative to A"),
    "EZ0B": ("mm", "B axis line offset in z, relative to A (distance A-B)"),
    "EA0B": ("rad", "B axis tilt about x (about A)"),
    "EC0B": ("rad", "B axis squareness to A, rotation about z"),
    "EX0S": ("mm", "spindle axis offset in x, relative to the head"),
    "EY0S": ("mm", "spindle axis offset in y, relative to the head"),
    "EA0S": ("rad", "spindle axis tilt about x, about the pivot"),
    "EB0S": ("rad", "spindle axis tilt about y, about the pivot"),
    "EZ0T": ("mm", "tool length error, positive = longer"),
}
LINEAR_AXES = ("X", "Y", "Z")
#: positioning: name -> (axis, power of q); straightness: name -> (axis, direction, power)
POSITIONING: dict[str, tuple[str, int]] = {f"E{a}{a}{'' if k == 1 else k}": (a, k) for a in LINEAR_AXES
                                           for k in (1, 2, 3)}
STRAIGHTNESS: dict[str, tuple[str, str, int]] = {f"E{b}{a}{k}": (a, b, k) for a in LINEAR_AXES
                                                 for b in LINEAR_AXES if b != a for k in (2, 3)}
SQUARENESS: dict[str, str] = {"EC0Y": "Y", "EB0Z": "Z", "EA0Z": "Z"}
_POWER_UNIT = {1: "1", 2: "1/mm", 3: "1/mm2"}
LINEAR_GEOMETRIC: dict[str, tuple[str, str]] = {
    **{n: (_POWER_UNIT[k], f"{a} positioning error, coefficient of {a}^{k}"
           + (" (scale)" if k == 1 else " (pitch)")) for n, (a, k) in POSITIONING.items()},
    **{n: (_POWER_UNIT[k], f"straightness of {a} in {b}, coefficient of {a}^{k}")
       for n, (a, b, k) in STRAIGHTNESS.items()},
    "EC0Y": ("rad", "squareness of Y to X, rotation about z"),
    "EB0Z": ("rad", "squareness of Z to X, rotation about y"),
    "EA0Z": ("rad", "squareness of Z to Y, rotation about x"),
}
#: location and orientation errors of the C axis of a rotary table (AC-table, BC-table,
#: BC-head-table; module docstring "Table machines"): ISO 230-1 names, machine frame at home
TABLE_GEOMETRIC: dict[str, tuple[str, str]] = {
    "EX0C": ("mm", "C axis line offset in x from the table centre"),
    "EY0C": ("mm", "C axis line offset in y from the table centre"),
    "EA0C": ("rad", "C axis squareness to Y, rotation about x"),
    "EB0C": ("rad", "C axis squareness to X, rotation about y"),
}
#: the location and orientation errors a rotary axis of a machine given by its chain can have
#: (``chain_axis_errors``): E<P>0<L> the line's offset along the coordinate direction P (made
#: perpendicular to the axis), E<R>0<L> its tilt about that direction (R the rotation about P: A
#: about x, B about y, C about z); on an axis along a coordinate direction the ISO 230-1 names
#: and meanings of the kinds (EX0C, EY0C, EA0C, EB0C for C along z)
CHAIN_GEOMETRIC: dict[str, tuple[str, str]] = {
    **{f"E{p}0{a}": ("mm", f"{a} axis line offset along {p.lower()} (a machine given by its chain)")
       for a in "ABC" for p in "XYZ"},
    **{f"E{r}0{a}": ("rad", f"{a} axis tilt about {'xyz'['ABC'.index(r)]} (a machine given by its chain)")
       for a in "ABC" for r in "ABC"},
}
GEOMETRIC_PARAMETERS: dict[str, tuple[str, str]] = {
    **ROTARY_GEOMETRIC, **TABLE_GEOMETRIC, **LINEAR_GEOMETRIC,
    **{k: v for k, v in CHAIN_GEOMETRIC.items() if k not in ROTARY_GEOMETRIC and k not in TABLE_GEOMETRIC}}
GEOMETRIC_NAMES: tuple[str, ...] = tuple(GEOMETRIC_PARAMETERS)
#: spindle and tool errors: the same meaning on every machine kind (relative to the ram or head
#: that carries the spindle)
SPINDLE_TOOL_GEOMETRIC = ("EX0S", "EY0S", "EA0S", "EB0S", "EZ0T")
_A_TABLE = {
    "EY0A": ("mm", "A (tilt) axis line offset in y from the table centre"),
    "EZ0A": ("mm", "A (tilt) axis line offset in z from the table centre"),
    "EB0A": ("rad", "A axis squareness to Z, rotation about y"),
    "EC0A": ("rad", "A axis squareness to Y, rotation about z"),
}
_B_TABLE = {
    "EX0B": ("mm", "B (tilt) axis line offset in x from the table centre"),
    "EZ0B": ("mm", "B (tilt) axis line offset in z from the table centre"),
    "EA0B": ("rad", "B axis squareness to Z, rotation about x"),
    "EC0B": ("rad", "B axis squareness to X, rotation about z"),
}
_B_HEAD = {
    "EX0B": ("mm", "B (head) axis line offset in x from the pivot"),
    "EZ0B": ("mm", "B (head) axis line offset in z from the pivot"),
    "EA0B": ("rad", "B axis squareness to Z, rotation about x"),
    "EC0B": ("rad", "B axis squareness to X, rotation about z"),
}
#: the rotary-axis parameters of each machine kind (MACHINE_KINDS) with their meaning there: the
#: same ISO 230-1 name means the same error of the same axis, located from that kind's nominal line
#: (module docstring). A parameter of another kind is an InputError (``ErrorModel.kind``).
ROTARY_BY_KIND: dict[str, dict[str, tuple[str, str]]] = {
    "AB-head": {k: ROTARY_GEOMETRIC[k] for k in ("EY0A", "EZ0A", "EB0A", "EC0A", "EX0B", "EZ0B", "EA0B",
                                                  "EC0B")},
    "AC-table": {**TABLE_GEOMETRIC, **_A_TABLE},
    "BC-table": {**TABLE_GEOMETRIC, **_B_TABLE},
    "BC-head-table": {**TABLE_GEOMETRIC, **_B_HEAD},
}
_PRESET_ROTARY_NAMES = frozenset(n for d in ROTARY_BY_KIND.values() for n in d)
_ROTARY_NAMES = _PRESET_ROTARY_NAMES | frozenset(CHAIN_GEOMETRIC)


@dataclass(frozen=True)
class AxisError:
    """One geometric error a rotary axis of a machine given by its chain can have: the axis'
    name, 'location' (mm: the line moved along ``u``) or 'orientation' (rad: the direction turned
    about ``u``, right-handed), and ``u`` the unit direction (machine frame at home, perpendicular
    to the axis)."""

    axis: str
    what: str
    u: tuple[float, float, float]


def chain_axis_errors(machine: Machine) -> dict[str, AxisError]:
    """The rotary-axis errors of a machine given by its chain, by name (CHAIN_GEOMETRIC): for each
    rotary axis with nominal direction d, the two coordinate directions other than the one d lies
    most along, each made perpendicular to d (Gram-Schmidt), give a location error along it,
    E<P>0<L>, and an orientation error about it, E<R>0<L>. On an axis along x, y or z these are
    the ISO 230-1 errors of the kinds: C along z has EX0C, EY0C (offsets in x, y), EA0C, EB0C
    (tilts about x, y). A line has no location error along itself and no zero offset here."""
    out: dict[str, AxisError] = {}
    for ax in machine.description.axes:
        d = np.asarray(ax.direction, float)
        k = int(np.argmax(np.abs(d)))
        for i in (j for j in range(3) if j != k):
            e = np.eye(3)[i]
            u = e - (e @ d) * d
            u = tuple(float(v) for v in u / np.linalg.norm(u))
            out[f"E{'XYZ'[i]}0{ax.name}"] = AxisError(ax.name, "location", u)
            out[f"E{'ABC'[i]}0{ax.name}"] = AxisError(ax.name, "orientation", u)
    return out


def spoken_kind(kind: str) -> str:
    """The kind with its article, as spoken ("an AB-head", "a BC-table")."""
    return ("an " if kind[0] in "AEFHILMNORSX" else "a ") + kind


def machine_parameters(machine: Machine) -> tuple[str, ...]:
    """The geometric parameters that apply to ``machine``: those of its preset kind
    (``kind_parameters``); on a chain given explicitly its rotary axes' location and orientation
    errors (``chain_axis_errors``) and the spindle, tool and linear-axis errors."""
    preset = machine.description.preset
    if preset is None:
        own = set(chain_axis_errors(machine)) | set(SPINDLE_TOOL_GEOMETRIC) | set(LINEAR_GEOMETRIC)
        return tuple(n for n in GEOMETRIC_NAMES if n in own)
    return kind_parameters(preset)


def rotary_errors(machine: Machine, what: str) -> dict[str, tuple[str, ...]]:
    """The machine's rotary-axis errors of one sort per axis: ``what`` 'location' (the lines'
    offsets, mm) or 'orientation' (their tilts, rad); axis name -> parameter names, e.g. on an
    AC table {'A': ('EY0A', 'EZ0A'), 'C': ('EX0C', 'EY0C')} for 'location'."""
    preset = machine.description.preset
    if preset is None:
        found = [(e.axis, n) for n, e in chain_axis_errors(machine).items() if e.what == what]
    else:
        unit = {"location": "mm", "orientation": "rad"}[what]
        found = [(n[-1], n) for n, (u, _) in ROTARY_BY_KIND[preset].items() if u == unit]
    return {a: tuple(n for b, n in found if b == a) for a in machine.rotary if any(b == a for b, _ in found)}


def spoken_machine(machine: Machine) -> str:
    """The machine as spoken: "an AC-table machine", or "the machine given by its chain (...)"."""
    preset = machine.description.preset
    return f"{spoken_kind(preset)} machine" if preset else f"the machine given by its chain ({machine.describe()})"


def kind_parameters(kind: str) -> tuple[str, ...]:
    """The geometric parameters that apply to a machine kind (MACHINE_KINDS): its rotary-axis
    errors (ROTARY_BY_KIND), the spindle and tool errors and the linear-axis errors, in
    GEOMETRIC_NAMES order."""
    if kind not in ROTARY_BY_KIND:
        raise InputError(f"unknown machine kind {kind!r} (known: {', '.join(ROTARY_BY_KIND)})")
    own = set(ROTARY_BY_KIND[kind]) | set(SPINDLE_TOOL_GEOMETRIC) | set(LINEAR_GEOMETRIC)
    return tuple(n for n in GEOMETRIC_NAMES if n in own)

SPINDLE_THERMAL: dict[str, str] = {"dx": "mm", "dy": "mm", "dz": "mm", "exz": "rad", "eyz": "rad"}
MACHINE_THERMAL: dict[str, str] = {"mx": "mm", "my": "mm", "mz": "mm"}
THERMAL_ELEMENTS: dict[str, str] = {**SPINDLE_THERMAL, **MACHINE_THERMAL}
SERVO_AXES = ("X", "Y", "Z", "A", "B", "C")

FORMAT = "camsmooth-error-model"
FORMAT_VERSION = 1

# unit -> factor to the code's unit
_LENGTH_UNITS = {"mm": 1.0, "um": 1e-3, "m": 1e3}
_ANGLE_UNITS = {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": math.pi / 180.0}
_TIME_UNITS = {"s": 1.0, "min": 60.0, "h": 3600.0}
_UNITLESS = {"1": 1.0, "": 1.0, "mm/mm": 1.0, "um/mm": 1e-3, "um/m": 1e-6, "ppm": 1e-6}
_PER_MM = {"1/mm": 1.0, "mm/mm2": 1.0, "um/mm2": 1e-3}
_PER_MM2 = {"1/mm2": 1.0, "mm/mm3": 1.0, "um/mm3": 1e-3}


def _units_for(unit: str) -> dict[str, float]:
    return {"mm": _LENGTH_UNITS, "rad": _ANGLE_UNITS, "s": _TIME_UNITS, "1": _UNITLESS, "1/mm": _PER_MM,
            "1/mm2": _PER_MM2}[unit]


# ----------------------------------------------------------------------------------------------
# small rigid-body helpers (numpy, constant)
def rot_x(a: float) -> np.ndarray:
    """Rotation by ``a`` rad about +X (right-hand rule)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    """Rotation by ``a`` rad about +Y (right-hand rule)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    """Rotation by ``a`` rad about +Z (right-hand rule)."""
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def homogeneous(R: np.ndarray | None = None, p: Sequence[float] | None = None) -> np.ndarray:
    """4x4 homogeneous matrix [R p; 0 1] (identity / zero when omitted)."""
    T = np.eye(4)
    if R is not None:
        T[:3, :3] = R
    if p is not None:
        T[:3, 3] = p
    return T


def _rotation_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The minimal rotation taking unit vector a to unit vector b (Rodrigues)."""
    v = np.cross(a, b)
    c = float(np.dot(a, b))
    s = float(np.linalg.norm(v))
    if s < 1e-300:
        return np.eye(3)
    k = v / s
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + s * K + (1.0 - c) * (K @ K)


# ----------------------------------------------------------------------------------------------
# spindle screw model (METHODS section 2)
@dataclass
class SpindleScrew:
    """Screw model of the spindle / tool axis (METHODS section 2).

    Frame CS1: origin at the nominal centre of the upper spindle bearing, z along the nominal
    spindle axis pointing away from the tool (the tool-axis convention T), x, y parallel to the
    head's x, y at A = B = 0. The spindle rotation axis passes through the origin with direction
    s = (cos_alpha, cos_beta, cos_gamma), cos_gamma > 0. Rotating the spindle by theta (rad,
    right-handed about s) carries every spindle point around s.

    * Bearings: the spindle's axis points A1 (upper bearing) and A2 (lower bearing, a distance
      ``h`` below along s) run on circles of radii r1, r2 (mm) with initial phases theta1, theta2
      (rad, measured from e1 = the unit projection of x onto the plane normal to s, toward
      e2 = s x e1). The spindle line is A2 -> A1, direction Z3.
    * Holder: frame CS3 at the holder face O3 = A2 - nose Z3 (X3: the rotating e1 projected
      normal to Z3). The holder is l3 + delta3 long (delta3: holder length error, mm); the
      collet's lower centre O4 = O3 - (l3 + delta3) Z3 + rho1 X3 and upper centre
      O4* = O3 - (l3 + delta3 - h1) Z3 + rho2 X3 (rho1, rho2: collet offsets, mm; h1: collet
      length, mm). The tool line runs through O4 and O4*; the tool tip (or a reference ball
      centre) O5 lies ``ext`` mm beyond O4 on it.

    Fixed geometry (known from drawings, not identified): h, nose, l3, h1, ext. With all
    errors zero, O5 = (0, 0, -(h + nose + l3 + ext)) and the tool line is the z axis.

    The tool line in Plücker coordinates is (l, m) with l the unit direction (tip toward
    spindle) and m = O5 x l; see ``tool_line`` and ``screw_error``. Over a revolution O5 runs
    on a circle about s; its centre (on the rotation axis) and s give the static part used in
    the machine chain (``static_tip_transform``).
    """

    r1: float = 0.0
    theta1: float = 0.0
    r2: float = 0.0
    theta2: float = 0.0
    cos_alpha: float = 0.0
    cos_beta: float = 0.0
    rho1: float = 0.0
    rho2: float = 0.0
    delta3: float = 0.0
    h: float = 200.0
    nose: float = 40.0
    l3: float = 60.0
    h1: float = 30.0
    ext: float = 50.0

    UNITS = {"r1": "mm", "theta1": "rad", "r2": "mm", "theta2": "rad", "cos_alpha": "1", "cos_beta": "1",
             "rho1": "mm", "rho2": "mm", "delta3": "mm", "h": "mm", "nose": "mm", "l3": "mm", "h1": "mm",
             "ext": "mm"}
    ERROR_PARAMETERS = ("r1", "theta1", "r2", "theta2", "cos_alpha", "cos_beta", "rho1", "rho2", "delta3")
    GEOMETRY = ("h", "nose", "l3", "h1", "ext")

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(f"spindle screw parameter {f.name} must be a finite number, got {v!r}")
            setattr(self, f.name, float(v))
        if self.cos_alpha ** 2 + self.cos_beta ** 2 >= 1.0:
            raise InputError("spindle screw: cos_alpha^2 + cos_beta^2 must be < 1")
        for name in ("h", "h1"):
            if getattr(self, name) <= 0:
                raise InputError(f"spindle screw: {name} must be > 0 mm")

    def as_dict(self) -> dict[str, float]:
        return {f.name: getattr(self, f.name) for f in fields(self)}

    # ---- geometry --------------------------------------------------------------------------
    def direction(self) -> np.ndarray:
        """Unit direction s of the spindle rotation axis in CS1."""
        return _axis_direction(np.float64(self.cos_alpha), np.float64(self.cos_beta))

    def nominal_tip(self, ext: float | None = None) -> np.ndarray:
        """Nominal O5 in CS1 (mm)."""
        ext = self.ext if ext is None else ext
        return np.array([0.0, 0.0, -(self.h + self.nose + self.l3 + ext)])

    def tip(self, theta: np.ndarray, ext: float | np.ndarray | None = None) -> np.ndarray:
        """O5 (N, 3) in CS1 (mm) at spindle angles theta (rad); ext (mm) defaults to self.ext."""
        return self.tool_line_points(theta, ext)[0]

    def tool_line_points(self, theta: np.ndarray, ext: float | np.ndarray | None = None
                         ) -> tuple[np.ndarray, np.ndarray]:
        """(O5 (N,3) mm, unit tool direction l (N,3)) in CS1 at spindle angles theta (rad)."""
        p = {k: np.float64(getattr(self, k)) for k in self.ERROR_PARAMETERS}
        a1, b1 = p["r1"] * np.cos(p["theta1"]), p["r1"] * np.sin(p["theta1"])
        a2, b2 = p["r2"] * np.cos(p["theta2"]), p["r2"] * np.sin(p["theta2"])
        theta = np.atleast_1d(np.asarray(theta, dtype=float))
        ext = np.broadcast_to(np.asarray(self.ext if ext is None else ext, dtype=float), theta.shape)
        return spindle_forward(a1, b1, a2, b2, p["cos_alpha"], p["cos_beta"], p["rho1"], p["rho2"],
                               p["delta3"], theta, ext, self.h, self.nose, self.l3, self.h1)

    def tool_line(self, theta: np.ndarray, ext: float | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Plücker coordinates (l, m) of the real tool axis at spindle angles theta (rad):
        l (N,3) the unit direction (tip toward spindle), m = O5 x l (N,3, mm), in CS1."""
        o5, l = self.tool_line_points(theta, ext)
        return l, np.cross(o5, l)

    def screw_error(self, theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Screw error of the real tool axis against the ideal one (the CS1 z axis, l0 = e_z,
        m0 = 0): theta_e (rad), the angle about the common perpendicular, and d_e (mm), the
        distance along it (Plücker reciprocal product |l0.m + l.m0| / |l0 x l|; the distance
        |m| of the parallel line when the two are parallel)."""
        l, m = self.tool_line(theta)
        ez = np.array([0.0, 0.0, 1.0])
        cross = np.cross(ez, l)
        sin_e = np.linalg.norm(cross, axis=1)
        theta_e = np.arctan2(sin_e, l @ ez)
        with np.errstate(divide="ignore", invalid="ignore"):
            d_skew = np.abs(m @ ez) / sin_e
        d_par = np.linalg.norm(np.cross(l, m), axis=1)
        return theta_e, np.where(sin_e > 1e-12, d_skew, d_par)

    def runout(self, ext: float | None = None) -> float:
        """Radius (mm) of the circle O5 runs on over one revolution (1x-rev radial runout)."""
        o5 = self.tip(np.array([0.0]), ext)[0]
        s = self.direction()
        return float(np.linalg.norm(o5 - (o5 @ s) * s))

    def static_tip_transform(self, ext: float | None = None) -> np.ndarray:
        """4x4 transform in the tool-tip frame from the nominal tool to the static real one:
        the tip moves to the centre of O5's circle (on the rotation axis) and the axis turns to
        the rotation axis s. This is what a spinning tool cuts like (its envelope is a body of
        revolution about s); the 1x-rev runout is ``runout``."""
        o5 = self.tip(np.array([0.0]), ext)[0]
        s = self.direction()
        centre = (o5 @ s) * s
        return homogeneous(_rotation_between(np.array([0.0, 0.0, 1.0]), s), centre - self.nominal_tip(ext))


def _axis_direction(ca: Any, cb: Any) -> np.ndarray:
    return np.stack(np.broadcast_arrays(ca, cb, np.sqrt(1.0 - ca * ca - cb * cb)), axis=-1)


def spindle_forward(a1: Any, b1: Any, a2: Any, b2: Any, ca: Any, cb: Any, rho1: Any, rho2: Any, delta3: Any,
                    theta: np.ndarray, ext: np.ndarray, h: float, nose: float, l3: float, h1: Any
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised spindle screw forward model (SpindleScrew docstring): O5 and the unit tool
    direction at spindle angles theta (M,) and extensions ext (M,). The error parameters (and h1)
    may be scalars, giving (M, 3) results, or arrays of shape (P,) (a particle swarm), giving
    (P, M, 3) results. Runout in Cartesian form: (a_i, b_i) = r_i (cos theta_i, sin theta_i).

    Every spindle point is carried rigidly about s by the spindle angle, so the geometry is built
    once at theta = 0 (per distinct ext) and then rotated: O5(theta) = Rot(s, theta) O5(0)."""
    def col(x: Any) -> np.ndarray:
        return np.asarray(x, float)[..., None] if np.ndim(x) else np.asarray(x, float)

    s = _axis_direction(np.asarray(ca, float), np.asarray(cb, float))  # (..., 3)
    e1 = np.array([1.0, 0.0, 0.0]) - s[..., 0:1] * s
    e1 = e1 / np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(s, e1)
    a1, b1, a2, b2, rho1, rho2, delta3, h1 = (col(x) for x in (a1, b1, a2, b2, rho1, rho2, delta3, h1))
    A1 = a1 * e1 + b1 * e2
    A2 = -h * s + a2 * e1 + b2 * e2
    z3 = A1 - A2
    z3 = z3 / np.linalg.norm(z3, axis=-1, keepdims=True)
    x3 = e1 - np.sum(e1 * z3, axis=-1, keepdims=True) * z3
    x3 = x3 / np.linalg.norm(x3, axis=-1, keepdims=True)
    o3 = A2 - nose * z3
    o4 = o3 - (l3 + delta3) * z3 + rho1 * x3
    o4s = o3 - (l3 + delta3 - h1) * z3 + rho2 * x3
    t = o4s - o4
    t = t / np.linalg.norm(t, axis=-1, keepdims=True)
    uniq, inv = np.unique(np.asarray(ext, float), return_inverse=True)
    o5 = o4[..., None, :] - uniq[:, None] * t[..., None, :]  # (..., U, 3) at theta = 0
    c, sn = np.cos(theta), np.sin(theta)
    e1, e2, s = (v[..., None, :] for v in (e1, e2, s))

    def rotate(w1: np.ndarray, w2: np.ndarray, w3: np.ndarray) -> np.ndarray:
        # components along (e1, e2, s) at theta = 0 -> rotated by theta about s, in CS1
        r1 = (c * w1 - sn * w2)[..., None]
        r2 = (sn * w1 + c * w2)[..., None]
        return r1 * e1 + r2 * e2 + w3[..., None] * s

    idx = inv.ravel()
    W = [np.take(np.sum(o5 * b, axis=-1), idx, axis=-1) for b in (e1, e2, s)]  # (..., M)
    T = [np.sum(t[..., None, :] * b, axis=-1) for b in (e1, e2, s)]  # (..., 1)
    return rotate(*W), rotate(*T)


# ----------------------------------------------------------------------------------------------
# the one first-order integrator (thermal growth and servo lag)
@njit(cache=True)
def _first_order_scan(alpha: np.ndarray, tau: float, s: np.ndarray, jump: np.ndarray, e0: float,
                      restart: np.ndarray) -> np.ndarray:  # pragma: no cover (compiled)
    # e_k+1 = a_k e_k + (1 - a_k) tau s_k + jump_k in one sequential pass: the recurrence is
    # serial and numpy has no scan for it. alpha: n - 1 entries or one (equal steps); jump: n - 1
    # entries or none; restart[k]: e_k+1 = 0.
    n = len(restart)
    e = np.empty(n + 1)
    e[0] = e0
    const = len(alpha) == 1
    jumps = len(jump) > 0
    for k in range(n):
        if restart[k]:
            e[k + 1] = 0.0
        else:
            a = alpha[0] if const else alpha[k]
            e[k + 1] = a * e[k] + (1.0 - a) * tau * s[k] + (jump[k] if jumps else 0.0)
    return e


def interval_slopes(t: np.ndarray, u: np.ndarray, hold: str = "linear") -> np.ndarray:
    """Slope of u on each interval [t_k, t_k+1) (n,; the last is 0): (u_k+1 - u_k) / h_k for
    hold 'linear' (0 across zero-length intervals, i.e. jumps), 0 for hold 'step'."""
    n = len(t)
    s = np.zeros(n)
    if hold == "linear" and n > 1:
        h = np.diff(t)
        ok = h > 0
        s[:-1][ok] = np.diff(u)[ok] / h[ok]
    elif hold not in ("linear", "step"):
        raise ValueError(f"hold must be 'linear' or 'step', got {hold!r}")
    return s


def first_order_knots(t: np.ndarray, u: np.ndarray, tau: float, *, slope: np.ndarray | None = None,
                      hold: str = "linear", e0: float | None = None, restart: np.ndarray | None = None,
                      h: np.ndarray | float | None = None, jump: np.ndarray | None = None) -> np.ndarray:
    """The following error e = u - y at the knots t (n,) of tau dy/dt = u - y, exactly.

    u (n,) is the input at the knots; between knots it is linear with ``slope`` (n,; default
    ``interval_slopes(t, u, hold)``; an interval whose slope differs from the knots' difference
    carries a jump at its end) or held (hold 'step', slope 0). Start: e[0] = e0 (default u[0]:
    y starts at 0, a cold start); ``restart`` (n,) bool: at these knots y restarts at rest on
    its input (e = 0, e.g. a new program segment). Recurrence, exact for this input:
    e_k+1 = a_k e_k + (1 - a_k) tau s_k + (u_k+1 - u_k - s_k h_k), a_k = exp(-h_k / tau).
    One compiled sequential pass. tau > 0 (s). h (n-1,)
    and jump (n-1,) (the bracketed term, 0 at restarts) may be passed in when the caller keeps them
    for many time constants (the diagnosis does; a float h: equal steps of that size; jump None
    with a slope given: no jumps)."""
    t = np.asarray(t, float)
    u = np.asarray(u, float)
    n = len(t)
    s = interval_slopes(t, u, hold) if slope is None else np.asarray(slope, float)
    e_start = float(u[0]) if e0 is None else float(e0)
    if n == 1:
        return np.array([0.0 if restart is not None and restart[0] else e_start])
    rs = np.zeros(n, bool) if restart is None else np.asarray(restart, bool)
    if rs[0]:
        e_start = 0.0
    if isinstance(h, float):
        uniform, hmax, hmin = True, h, h
    else:
        h = np.diff(t) if h is None else h
        hmax, hmin = float(h.max()), float(h.min())
        uniform = hmin > 0 and hmax - hmin <= 1e-9 * hmax
    jumps = jump
    if jumps is None and (slope is None and hold == "step" or hmin <= 0):
        # the input's own jumps (across zero-length intervals, a held step)
        jumps = np.diff(u) - s[:-1] * (h if not isinstance(h, float) else np.full(n - 1, h))
        jumps[rs[1:]] = 0.0
        if not np.any(jumps):
            jumps = None
    if uniform:
        alpha = np.array([math.exp(-hmax / tau)])
    else:
        with np.errstate(over="ignore", under="ignore"):
            alpha = np.ascontiguousarray(np.exp(-h / tau))
    jumps = np.empty(0) if jumps is None else np.ascontiguousarray(jumps, dtype=float)
    return _first_order_scan(alpha, float(tau), np.ascontiguousarray(s, dtype=float), jumps, e_start,
                             np.ascontiguousarray(rs[1:]))


def first_order_between(u: np.ndarray, slope: np.ndarray, e: np.ndarray, tau: float, k: np.ndarray,
                        x: np.ndarray) -> np.ndarray:
    """y at t_k + x (0 <= x <= h_k) from the knot values of ``first_order_knots``: the input is
    u_k + s_k x there and e(x) = a e_k + (1 - a) tau s_k, a = exp(-x / tau) (exact)."""
    a = np.exp(-x / tau)
    s = slope[k]
    return u[k] + s * x - (a * e[k] + (1.0 - a) * tau * s)


def first_order_response(t: np.ndarray, u: np.ndarray, gain: float, tau: float, hold: str = "step"
                         ) -> np.ndarray:
    """gain * y(t) at the knots of tau dy/dt = u - y, y(t[0]) = 0, for u held (u[k] on
    [t[k], t[k+1]); hold 'step') or linear between knots (hold 'linear'). ``first_order_knots``."""
    t = np.asarray(t, float)
    u = np.asarray(u, float)
    if len(t) < 2 or gain == 0.0:
        return np.zeros_like(t)
    return gain * (u - first_order_knots(t, u, tau, hold=hold))


def thermal_frame(state: Mapping[str, Any]) -> Frame:
    """The tool-tip-frame transform of a spindle-frame thermal state (module docstring):
    translation (dx, dy, dz) and rotation by the vector (eyz, -exz, 0) (exact Rodrigues). Entries
    may be floats or numpy arrays (N,). Machine-frame elements (mx, my, mz) are not part of it."""
    dx, dy, dz = (state.get(k, 0.0) for k in ("dx", "dy", "dz"))
    wx = np.asarray(state.get("eyz", 0.0), dtype=float)
    wy = -np.asarray(state.get("exz", 0.0), dtype=float)
    ang = np.hypot(wx, wy)
    safe = np.where(ang > 0, ang, 1.0)
    kx, ky = np.where(ang > 0, wx / safe, 1.0), np.where(ang > 0, wy / safe, 0.0)
    s, c = np.sin(ang), np.cos(ang)
    omc = 1.0 - c
    # R = I + s K + (1 - c) K^2 for the unit axis k = (kx, ky, 0)
    R = ((1.0 - omc * ky * ky, omc * kx * ky, s * ky),
         (omc * kx * ky, 1.0 - omc * kx * kx, -s * kx),
         (-s * ky, s * kx, c))
    if all(np.ndim(v) == 0 for v in (dx, dy, dz, wx, wy)):
        return Frame(tuple(tuple(float(x) for x in row) for row in R), (float(dx), float(dy), float(dz)))
    return Frame(R, (dx, dy, dz))


# ----------------------------------------------------------------------------------------------
# the real chain: POE plus the linear axes' positioning and straightness
def _power(q: Any, k: int) -> Any:
    # products, not pow: exact for CasADi and several times faster for numpy arrays
    out = q
    for _ in range(k - 1):
        out = out * q
    return out


def _poly(coef: Sequence[tuple[int, float]], q: Any) -> Any:
    out: Any = 0.0
    for k, c in coef:
        out = out + c * _power(q, k)
    return out


def _dpoly(coef: Sequence[tuple[int, float]], q: Any) -> Any:
    out: Any = 0.0
    for k, c in coef:
        out = out + k * c * (_power(q, k - 1) if k > 1 else 1.0)
    return out


@dataclass(frozen=True)
class RealChain(Chain):
    """A Chain whose linear joints carry positioning errors (the joint value q becomes
    q + E_AA(q)) and straightness (the carriage moves off its line by E_BA(q) along B), a base
    translation ``base`` (machine-frame thermal growth, mm) added to the tip, plus the screws and
    home pose of the rotary and spindle errors (module docstring). numpy and CasADi alike.
    positioning: joint -> ((power, coefficient), ...); straightness: joint -> ((direction
    index, power, coefficient), ...)."""

    positioning: tuple[tuple[str, tuple[tuple[int, float], ...]], ...] = ()
    straightness: tuple[tuple[str, tuple[tuple[int, int, float], ...]], ...] = ()
    base: tuple[Any, Any, Any] = (0.0, 0.0, 0.0)

    def joint_values(self, q: Mapping[str, Any]) -> dict[str, Any]:
        """The joint values the chain's screws see: q + E_AA(q) on the linear axes."""
        out = dict(q)
        for name, coef in self.positioning:
            v = q.get(name, 0.0)
            if not (isinstance(v, float) and v == 0.0):
                out[name] = v + _poly(coef, v)
        return out

    def offset(self, q: Mapping[str, Any]) -> list[Any]:
        """The straightness translation plus ``base`` (mm, workpiece frame) at joint values q."""
        d: list[Any] = list(self.base)
        for name, terms in self.straightness:
            v = q.get(name, 0.0)
            if isinstance(v, float) and v == 0.0:
                continue
            for i, k, c in terms:
                d[i] = d[i] + c * _power(v, k)
        return d

    def forward(self, q: Mapping[str, Any]) -> Frame:
        """Tool-tip frame in the workpiece frame (Chain.forward) with the carriage offset: added
        in the workpiece frame when the linear axes come first (a head), else inserted before the
        first linear joint, i.e. turned by the rotary joints before it (a table)."""
        qj = self.joint_values(q)
        d = self.offset(q)
        if all(isinstance(v, float) and v == 0.0 for v in d):
            return Chain.forward(self, qj)
        k = carriage_index(self)
        if k == 0:
            f = Chain.forward(self, qj)
            return Frame(f.R, tuple(f.p[i] + d[i] for i in range(3)))
        frame = IDENTITY
        for i, (joint, (w, v)) in enumerate(zip(self.joints, self.joint_screws(), strict=True)):
            if i == k:
                frame = frame @ Frame(IDENTITY.R, tuple(d))
            value = qj.get(joint.name, 0.0)
            if isinstance(value, float) and value == 0.0:
                continue
            frame = frame @ exp_twist(w, v, value)
        return frame @ Frame.from_matrix(self.home)


def carriage_index(chain: Chain) -> int:
    """Index of the first linear (prismatic) joint of the chain: 0 on a head machine (X, Y, Z
    first), the number of table axes before it on a table machine."""
    return next(i for i, j in enumerate(chain.joints) if j.kind == "prismatic")


def carriage_rotation(chain: Chain, q: Mapping[str, Any]) -> Frame | None:
    """The frame of the rotary joints before the linear axes (the table's turn, workpiece frame)
    at joint values q, whose rotation takes a machine-frame (carriage) vector to the workpiece
    frame; None when the linear axes come first (a head machine: no turn)."""
    k = carriage_index(chain)
    if k == 0:
        return None
    frame = IDENTITY
    for joint, (w, v) in list(zip(chain.joints, chain.joint_screws(), strict=True))[:k]:
        value = q.get(joint.name, 0.0)
        if isinstance(value, float) and value == 0.0:
            continue
        frame = frame @ exp_twist(w, v, value)
    return frame


def _spindle_pivot(machine: Machine) -> np.ndarray:
    """The point the spindle tilt EA0S, EB0S turns about (mm, workpiece frame at home): the head's
    pivot (where its rotary axis crosses the spindle; the B axis of a BC-head-table), else the
    home tool tip (a table-table machine)."""
    chain = machine.chain
    k = carriage_index(chain)
    head = [j for j in chain.joints[k:] if j.kind == "revolute"]
    if head:
        return np.asarray(head[-1].point, float)
    return np.asarray(chain.home, float)[:3, 3]


# ----------------------------------------------------------------------------------------------
# the machine model
@dataclass
class Prediction:
    """Predicted real tool pose for commanded axes. tip, ideal_tip: (N,3) mm; axis, ideal_axis:
    (N,3) unit tool axes (tip toward spindle), workpiece frame; tip_dev_um: |tip - ideal_tip|
    (um); axis_dev_urad: angle between axis and ideal_axis (urad)."""

    tip: np.ndarray
    axis: np.ndarray
    ideal_tip: np.ndarray
    ideal_axis: np.ndarray
    tip_dev_um: np.ndarray
    axis_dev_urad: np.ndarray


def _finite_number(v: Any) -> bool:
    return not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)


@dataclass
class ErrorModel:
    """The machine model (module docstring for every definition; internal units mm, s, rad).

    geometric: name -> value (GEOMETRIC_PARAMETERS; missing names are 0).
    spindle: the spindle screw model, or None (no spindle screw errors).
    thermal: element (THERMAL_ELEMENTS) -> {"gain": steady value per 1000 rpm (mm or rad),
    "tau": time constant (s)}; missing elements do not drift.
    meta: free-form provenance (strings/numbers), stored in the JSON file as is.
    tau: servo time constant 1/Kv per axis (s; absent or 0: follows its command exactly).
    backlash: reversal error per axis (mm; rad for A, B). offset_s: recording clock behind the
    program (s). runout: (r cos phi, r sin phi) of the 1x-revolution tip runout (mm).
    kind: the machine kind (MACHINE_KINDS) the rotary-axis errors belong to, or None (unstated:
    a model with rotary-axis errors but no kind is an AB-head model, as every model before machine
    kinds was, unless it has C-axis errors, which only a table has; ``machine_kind``).
    """

    geometric: dict[str, float] = field(default_factory=dict)
    spindle: SpindleScrew | None = None
    thermal: dict[str, dict] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)
    tau: dict[str, float] = field(default_factory=dict)
    backlash: dict[str, float] = field(default_factory=dict)
    offset_s: float = 0.0
    runout: tuple[float, float] = (0.0, 0.0)
    kind: str | None = None

    def __post_init__(self) -> None:
        for what, table in (("geometric", self.geometric), ("thermal", self.thermal), ("tau", self.tau),
                            ("backlash", self.backlash), ("meta", self.meta)):
            if not isinstance(table, Mapping):
                raise InputError(f"{what} must be a mapping, got {type(table).__name__}")
        unknown = sorted(set(self.geometric) - set(GEOMETRIC_NAMES))
        if unknown:
            raise InputError(f"unknown geometric error parameter(s) {unknown}; "
                             f"known: {list(GEOMETRIC_NAMES)}")
        for k, v in self.geometric.items():
            if not _finite_number(v):
                raise InputError(f"geometric error {k} must be a finite number, got {v!r}")
        unknown = sorted(set(self.thermal) - set(THERMAL_ELEMENTS))
        if unknown:
            raise InputError(f"unknown thermal element(s) {unknown}; known: {list(THERMAL_ELEMENTS)}")
        for k, d in self.thermal.items():
            if not isinstance(d, Mapping) or set(d) != {"gain", "tau"}:
                raise InputError(f"thermal element {k} must be {{'gain': ..., 'tau': ...}}, got {d!r}")
            if not (_finite_number(d["gain"]) and _finite_number(d["tau"]) and d["tau"] > 0):
                raise InputError(f"thermal element {k}: gain must be finite and tau > 0 s, got {dict(d)}")
        for what, table in (("servo time constant", self.tau), ("backlash", self.backlash)):
            for a, v in table.items():
                if a not in SERVO_AXES:
                    raise InputError(f"{what}: axis {a!r} is not one of {SERVO_AXES}")
                if not _finite_number(v) or (what != "backlash" and v < 0):
                    raise InputError(f"{what} of {a} must be a finite number{' >= 0' if what != 'backlash' else ''}, "
                                     f"got {v!r}")
        if not _finite_number(self.offset_s):
            raise InputError(f"time offset must be a finite number of s, got {self.offset_s!r}")
        if len(self.runout) != 2 or not all(_finite_number(v) for v in self.runout):
            raise InputError(f"runout must be two finite numbers (mm), got {self.runout!r}")
        self.runout = (float(self.runout[0]), float(self.runout[1]))
        if self.kind is not None and (not isinstance(self.kind, str) or self.kind not in MACHINE_KINDS):
            raise InputError(f"machine kind {self.kind!r} is not one of {', '.join(MACHINE_KINDS)}")
        rotary = [n for n in self.geometric if n in _ROTARY_NAMES]
        if self.kind is not None:
            foreign = [n for n in rotary if n not in ROTARY_BY_KIND[self.kind]]
            if foreign:
                raise InputError(f"geometric error(s) {', '.join(foreign)} are not errors of {spoken_kind(self.kind)} "
                                 f"machine (its rotary-axis errors: {', '.join(ROTARY_BY_KIND[self.kind])})")

    def machine_kind(self) -> str | None:
        """The machine kind this model's rotary-axis errors are for: ``kind`` when stated; else
        "AB-head" for a model with rotary-axis errors and no C-axis error (every model file before
        machine kinds), "table" for one with C-axis errors (some table kind, told by its tilt
        parameters), None for a model without rotary-axis errors (it applies to every kind)."""
        if self.kind is not None:
            return self.kind
        rotary = [n for n, v in self.geometric.items() if n in _PRESET_ROTARY_NAMES]
        if not rotary:
            return None
        return "table" if any(n in TABLE_GEOMETRIC for n in rotary) else "AB-head"

    def for_machine(self, machine: Machine) -> ErrorModel:
        """This model with its rotary-axis errors stated to be ``machine``'s (a copy with ``kind`` set)
        when it states none and the machine is a preset other than the AB head (whose models have
        always left the kind unstated); else this model itself."""
        preset = machine.description.preset
        if self.kind is None and preset is not None and preset != "AB-head":
            model = self.copy()
            model.kind = preset
            return model
        return self

    def check_machine(self, machine: Machine) -> None:
        """InputError when this model's rotary-axis errors are not for ``machine``'s kind (an
        AB-head model on a table machine, a table model on an AB head, an AC-table model on a BC
        table, ...), naming both kinds."""
        own = self.machine_kind()
        rotary = [n for n, v in self.geometric.items() if n in _ROTARY_NAMES]
        if machine.description.preset is None:
            own_errors = chain_axis_errors(machine)
            foreign = [n for n in rotary if n not in own_errors]
            if self.kind is not None or foreign:
                what = f"for {spoken_kind(self.kind)} machine" if self.kind else f"with {', '.join(foreign)}"
                raise InputError(f"the error model is {what}, but the machine is given by its chain "
                                 f"({machine.describe()}): its rotary-axis errors are {', '.join(own_errors)}")
            return
        chain_only = [n for n in rotary if n not in _PRESET_ROTARY_NAMES]
        if chain_only:
            raise InputError(f"geometric error(s) {', '.join(chain_only)} are errors of a machine given by its chain, "
                             f"not of {spoken_kind(machine.kind)} machine (its rotary-axis errors: "
                             f"{', '.join(ROTARY_BY_KIND[machine.kind])})")
        if own is None or own == machine.kind:
            return
        rotary = [n for n in self.geometric if n in _ROTARY_NAMES]
        if own == "table":
            foreign = [n for n in rotary if n not in ROTARY_BY_KIND[machine.kind]]
            if not foreign:
                return
            raise InputError(f"the error model's rotary-axis errors ({', '.join(rotary)}) are for a table machine "
                             f"(the model states no machine kind), but the machine is {machine.kind}: "
                             f"{', '.join(foreign)} are not errors of {spoken_kind(machine.kind)} machine (its "
                             f"rotary-axis errors: {', '.join(ROTARY_BY_KIND[machine.kind])})")
        stated = "" if self.kind is not None else " (the model states no machine kind, which means AB-head)"
        raise InputError(f"the error model is for {spoken_kind(own)} machine{stated}, but the machine is "
                         f"{machine.kind}: its rotary-axis errors ({', '.join(rotary)}) describe other axes; use a "
                         f"model made for {spoken_kind(machine.kind)} machine (\"machine_kind\": \"{machine.kind}\")")

    def get(self, name: str) -> float:
        """Geometric parameter value (0 when missing)."""
        if name not in GEOMETRIC_PARAMETERS:
            raise KeyError(name)
        return float(self.geometric.get(name, 0.0))

    def copy(self) -> ErrorModel:
        """An independent copy (the tables copied; the spindle screw and meta values shared)."""
        return ErrorModel(dict(self.geometric), self.spindle, {k: dict(d) for k, d in self.thermal.items()},
                          dict(self.meta), dict(self.tau), dict(self.backlash), float(self.offset_s),
                          tuple(self.runout), self.kind)

    @property
    def Kv(self) -> dict[str, float]:
        """Servo gain per axis (1/s; inf for an axis without lag)."""
        return {a: (1.0 / t if t > 0 else math.inf) for a, t in self.tau.items()}

    # ---- JSON ------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The JSON document: every value with its unit beside it; ``servo`` and
        ``spindle_runout`` only when set (Kv in 1/s, backlash mm or deg, time offset s; runout
        radius mm and phase deg)."""
        doc: dict[str, Any] = {"format": FORMAT, "version": FORMAT_VERSION}
        if self.kind is not None:
            doc["machine_kind"] = self.kind
        doc["geometric"] = {k: {"value": float(v), "unit": GEOMETRIC_PARAMETERS[k][0]}
                            for k, v in self.geometric.items()}
        doc["spindle"] = None if self.spindle is None else {
            k: {"value": v, "unit": SpindleScrew.UNITS[k]} for k, v in self.spindle.as_dict().items()}
        doc["thermal"] = {k: {"gain": {"value": float(d["gain"]), "unit": f"{THERMAL_ELEMENTS[k]}/1000rpm"},
                              "tau": {"value": float(d["tau"]), "unit": "s"}}
                          for k, d in self.thermal.items()}
        doc["meta"] = self.meta
        kv = {a: 1.0 / t for a, t in self.tau.items() if t > 0}
        bl = {a: (math.degrees(b) if a in ("A", "B") else b) for a, b in self.backlash.items() if b != 0.0}
        if kv or bl or self.offset_s != 0.0:
            doc["servo"] = {"Kv": kv, "backlash": bl, "time_offset_s": float(self.offset_s),
                            "units": {"Kv": "1/s", "backlash": "mm (deg for A, B)", "time_offset_s": "s"}}
        if self.runout != (0.0, 0.0):
            doc["spindle_runout"] = {"radius": float(math.hypot(*self.runout)),
                                     "phase_deg": float(math.degrees(math.atan2(self.runout[1], self.runout[0]))),
                                     "units": {"radius": "mm", "phase_deg": "deg at spindle angle 0"}}
        return doc

    @staticmethod
    def from_dict(doc: Any, source: str = "<model>") -> ErrorModel:
        """Inverse of ``to_dict``; accepts other units (um, urad, mrad, deg, min, h) and converts.
        A document holding only ``servo`` / ``spindle_runout`` (no ``format``) is accepted too.
        Every type error raises InputError naming the file and the key."""
        if not isinstance(doc, Mapping):
            raise InputError(f"a model file holds a JSON object {{...}}, got {_json_kind(doc)}", file=source)
        bare = "format" not in doc and not ({"geometric", "thermal", "spindle"} & set(doc))
        if not bare:
            if doc.get("format") != FORMAT:
                raise InputError(f"not a camsmooth error model (expected \"format\": \"{FORMAT}\")", file=source,
                                 key="format")
            if doc.get("version") != FORMAT_VERSION:
                raise InputError(f"unsupported model version {doc.get('version')!r} "
                                 f"(supported: {FORMAT_VERSION})", file=source, key="version")
        kind = doc.get("machine_kind")
        if kind is not None and (not isinstance(kind, str) or kind not in MACHINE_KINDS):
            raise InputError(f"machine_kind {kind!r} is not one of {', '.join(MACHINE_KINDS)}", file=source,
                             key="machine_kind")
        geo = {}
        for k, item in _section(doc, "geometric", source).items():
            if k not in GEOMETRIC_PARAMETERS:
                raise InputError(f"unknown geometric error parameter {k!r}", file=source, key=f"geometric.{k}")
            geo[k] = _value(item, GEOMETRIC_PARAMETERS[k][0], f"geometric.{k}", source)
        spindle = None
        sp = doc.get("spindle")
        if sp is not None:
            if not isinstance(sp, Mapping):
                raise InputError("spindle must be an object or null", file=source, key="spindle")
            unknown = sorted(set(sp) - set(SpindleScrew.UNITS))
            if unknown:
                raise InputError(f"unknown spindle screw parameter(s) {unknown}", file=source,
                                 key=f"spindle.{unknown[0]}")
            try:
                spindle = SpindleScrew(**{k: _value(v, SpindleScrew.UNITS[k], f"spindle.{k}", source)
                                          for k, v in sp.items()})
            except InputError as exc:
                if exc.file:
                    raise
                raise InputError(str(exc), file=source, key="spindle") from None
        thermal = {}
        for k, item in _section(doc, "thermal", source).items():
            where = f"thermal.{k}"
            if k not in THERMAL_ELEMENTS:
                raise InputError(f"unknown thermal element {k!r}", file=source, key=where)
            if not isinstance(item, Mapping) or set(item) != {"gain", "tau"}:
                raise InputError(f"{where} must hold 'gain' and 'tau'", file=source, key=where)
            gain = item["gain"]
            if not isinstance(gain, Mapping):
                raise InputError(f"{where}.gain: expected {{\"value\": ..., \"unit\": ...}}", file=source,
                                 key=f"{where}.gain")
            unit = gain.get("unit", "")
            base = unit.split("/")[0] if isinstance(unit, str) and unit.endswith("/1000rpm") else None
            if base is None:
                raise InputError(f"{where}.gain: unit must be '<unit>/1000rpm', got {unit!r}", file=source,
                                 key=f"{where}.gain")
            g = _value({"value": gain.get("value"), "unit": base}, THERMAL_ELEMENTS[k], f"{where}.gain", source)
            tau = _value(item["tau"], "s", f"{where}.tau", source)
            if tau <= 0:
                raise InputError(f"{where}: tau > 0 s required, got {tau}", file=source, key=f"{where}.tau")
            thermal[k] = {"gain": g, "tau": tau}
        meta = doc.get("meta") or {}
        if not isinstance(meta, Mapping):
            raise InputError("meta must be an object", file=source, key="meta")
        servo = _section(doc, "servo", source)
        tau_s: dict[str, float] = {}
        for a, kv in _section(servo, "Kv", source, "servo.").items():
            kv = _number(kv, source, f"servo.Kv.{a}")
            if a not in SERVO_AXES or kv <= 0:
                raise InputError(f"servo Kv needs an axis of {SERVO_AXES} and a value > 0 1/s", file=source,
                                 key=f"servo.Kv.{a}")
            tau_s[a] = 1.0 / kv
        backlash: dict[str, float] = {}
        for a, b in _section(servo, "backlash", source, "servo.").items():
            if a not in SERVO_AXES:
                raise InputError(f"backlash axis {a!r} is not one of {SERVO_AXES}", file=source,
                                 key=f"servo.backlash.{a}")
            b = _number(b, source, f"servo.backlash.{a}")
            backlash[a] = math.radians(b) if a in ("A", "B") else b
        offset = _number(servo.get("time_offset_s", 0.0), source, "servo.time_offset_s")
        ro = _section(doc, "spindle_runout", source)
        runout = (0.0, 0.0)
        if ro:
            r = _number(ro.get("radius", 0.0), source, "spindle_runout.radius")
            phi = math.radians(_number(ro.get("phase_deg", 0.0), source, "spindle_runout.phase_deg"))
            runout = (r * math.cos(phi), r * math.sin(phi))
        try:
            return ErrorModel(geo, spindle, thermal, dict(meta), tau_s, backlash, offset, runout, kind)
        except InputError as exc:
            raise InputError(str(exc), file=source) from None

    def to_json(self, path: str | os.PathLike) -> Path:
        """Write the model as JSON (atomically). Floats are written with repr, so ``from_json``
        gives back exactly the same numbers."""
        write_text_atomic(path, json.dumps(self.to_dict(), indent=2) + "\n")
        return Path(path)

    @staticmethod
    def from_json(path: str | os.PathLike) -> ErrorModel:
        """Read a model written by ``to_json`` (InputError naming the file, and the key where
        one is at fault, on a missing or malformed file)."""
        text = read_text_file(path, "model file")
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"not valid JSON: {exc}", file=str(path), row=exc.lineno) from None
        return ErrorModel.from_dict(doc, str(path))

    # ---- the perturbed chain ---------------------------------------------------------------
    def axis_frames(self, pivot_point: Sequence[float] = (0.0, 0.0, 0.0)
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(F_A, F_B, S): 4x4 frames of the real A axis (x along the axis), of the real B axis
        (y along the axis) and the spindle transform about the pivot, at the home configuration
        (module docstring). pivot_point: where the nominal A and B axes meet (mm)."""
        g = self.get
        p0 = np.asarray(pivot_point, dtype=float)
        R_A = rot_z(g("EC0A")) @ rot_y(g("EB0A"))
        F_A = homogeneous(R_A, p0 + np.array([0.0, g("EY0A"), g("EZ0A")]))
        F_B = F_A @ homogeneous(rot_x(g("EA0B")) @ rot_z(g("EC0B")), [g("EX0B"), 0.0, g("EZ0B")])
        R_S = rot_x(g("EA0S")) @ rot_y(g("EB0S"))
        S = homogeneous(R_S, p0 + np.array([g("EX0S"), g("EY0S"), 0.0]) - R_S @ p0)
        return F_A, F_B, S

    def tip_transform(self, thermal_state: Mapping[str, float] | None = None) -> np.ndarray:
        """4x4 tool-tip-frame transform of tool length, static spindle screw and (optionally a
        fixed) spindle-frame thermal state: Trans(0, 0, -EZ0T) T_screw T_thermal."""
        T = homogeneous(p=[0.0, 0.0, -self.get("EZ0T")])
        if self.spindle is not None:
            T = T @ self.spindle.static_tip_transform()
        if thermal_state:
            T = T @ thermal_frame({k: float(v) for k, v in thermal_state.items()}).to_numpy()
        return T

    def chain(self, machine: Machine, thermal_state: Mapping[str, float] | None = None) -> Chain:
        """The machine's chain perturbed by this model (a ``RealChain`` when the linear axes
        have errors or a machine-frame thermal state is given): screws of the rotary axes (A, B
        on the AB head; C and the tilt axis on a table, module docstring) and of Y, Z (for
        squareness) replaced by the real axis lines, home pose M with the spindle, tool, static
        spindle-screw and (when given, a fixed) spindle-frame thermal errors. Works for numpy
        and CasADi evaluation alike. InputError when the model is for another machine kind
        (``check_machine``); ValueError for a chain that is not the nominal one of its kind."""
        chain = machine.chain
        if chain.screws is not None:
            raise ValueError("apply the error model to the nominal machine (its chain is already perturbed)")
        self.check_machine(machine)
        names = chain.names
        idx = {n: i for i, n in enumerate(names)}
        screws = list(chain.joint_screws())
        preset = machine.description.preset
        if preset == "AB-head":
            if names != ("X", "Y", "Z", "A", "B"):
                raise ValueError(f"the error model needs an AB head chain X, Y, Z, A, B; got {names}")
            jA, jB = chain.joints[3], chain.joints[4]
            if not (np.allclose(jA.direction, (1, 0, 0)) and np.allclose(jB.direction, (0, 1, 0))
                    and np.allclose(jA.point, jB.point)):
                raise ValueError("the error model needs nominal A about x and B about y through one pivot point")
            F_A, F_B, S = self.axis_frames(jA.point)
            w_A = F_A[:3, 0]
            w_B = F_B[:3, 1]
            screws[3] = (w_A, -np.cross(w_A, F_A[:3, 3]))
            screws[4] = (w_B, -np.cross(w_B, F_B[:3, 3]))
        else:
            lines = self.table_axis_lines(machine) if preset is not None else self.chain_axis_lines(machine)
            for name, (w, point) in lines.items():
                screws[idx[name]] = (w, -np.cross(w, point))
            S = self.spindle_frame(_spindle_pivot(machine))
        g = self.get
        if g("EC0Y"):
            screws[idx["Y"]] = (np.zeros(3), rot_z(g("EC0Y")) @ np.array([0.0, 1.0, 0.0]))
        if g("EA0Z") or g("EB0Z"):
            screws[idx["Z"]] = (np.zeros(3), rot_x(g("EA0Z")) @ rot_y(g("EB0Z")) @ np.array([0.0, 0.0, 1.0]))
        spindle_state = None if not thermal_state else {k: v for k, v in thermal_state.items()
                                                        if k in SPINDLE_THERMAL}
        home = S @ chain.home @ self.tip_transform(spindle_state)
        pos = tuple((a, tuple((k, g(n)) for n, (b, k) in POSITIONING.items() if b == a and g(n)))
                    for a in LINEAR_AXES)
        pos = tuple(p for p in pos if p[1])
        st = tuple((a, tuple(("XYZ".index(d), k, g(n)) for n, (b, d, k) in STRAIGHTNESS.items()
                             if b == a and g(n))) for a in LINEAR_AXES)
        st = tuple(s for s in st if s[1])
        base = tuple(float((thermal_state or {}).get(k, 0.0)) for k in MACHINE_THERMAL)
        if not pos and not st and not any(base):
            return chain.with_screws(screws, home)
        return RealChain(chain.joints, home, tuple((np.asarray(w, float), np.asarray(v, float)) for w, v in screws),
                         positioning=pos, straightness=st, base=base)

    def table_axis_lines(self, machine: Machine) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The real rotary axis lines of a table machine (AC-table, BC-table, BC-head-table) at the
        home configuration, workpiece frame: axis name -> (unit direction w, a point on the line,
        mm); module docstring "Table machines". ValueError when the machine's chain does not have
        the nominal lines of its kind (C about z and the tilt axis through the table centre)."""
        chain = machine.chain
        joints = {j.name: j for j in chain.joints}
        g = self.get
        c = np.asarray(machine.table_centre, float)
        tilt = machine.rotary[0]
        jC, jT = joints.get("C"), joints.get(tilt)
        nominal_tilt = (1, 0, 0) if tilt == "A" else (0, 1, 0)
        head = machine.has_head
        tilt_point = np.zeros(3) if head else c
        if (jC is None or jT is None or not np.allclose(jC.direction, (0, 0, 1)) or not np.allclose(jC.point, c)
                or not np.allclose(jT.direction, nominal_tilt) or not np.allclose(jT.point, tilt_point)):
            raise ValueError(f"the error model needs the nominal {machine.kind} chain: C about z through the table "
                             f"centre and {tilt} about {'xy'[tilt == 'B']} through the "
                             f"{'pivot' if head else 'table centre'}")
        lines = {"C": (rot_x(g("EA0C")) @ rot_y(g("EB0C")) @ np.array([0.0, 0.0, 1.0]),
                       c + np.array([g("EX0C"), g("EY0C"), 0.0]))}
        if tilt == "A":
            lines["A"] = (rot_z(g("EC0A")) @ rot_y(g("EB0A")) @ np.array([1.0, 0.0, 0.0]),
                          tilt_point + np.array([0.0, g("EY0A"), g("EZ0A")]))
        else:
            lines["B"] = (rot_x(g("EA0B")) @ rot_z(g("EC0B")) @ np.array([0.0, 1.0, 0.0]),
                          tilt_point + np.array([g("EX0B"), 0.0, g("EZ0B")]))
        return lines

    def chain_axis_lines(self, machine: Machine) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The real rotary axis lines of a machine given by its chain, at the home configuration in
        the chain's frame (workpiece frame; a head axis' point taken from the gauge point): axis name
        -> (unit direction w, a point on the line, mm). Each nominal line (d, p) becomes the line
        through p + sum of its location errors along their u, with direction exp([r]) d, r = sum of
        its orientation errors times their u (``chain_axis_errors``)."""
        joints = {j.name: j for j in machine.chain.joints if j.kind == "revolute"}
        errors = chain_axis_errors(machine)
        lines = {}
        for name, joint in joints.items():
            d = np.asarray(joint.direction, float) / np.linalg.norm(joint.direction)
            p = np.asarray(joint.point, float)
            r = np.zeros(3)
            for pname, e in errors.items():
                if e.axis != name or not self.get(pname):
                    continue
                if e.what == "location":
                    p = p + self.get(pname) * np.asarray(e.u)
                else:
                    r = r + self.get(pname) * np.asarray(e.u)
            w = exp_twist(r / np.linalg.norm(r), np.zeros(3), float(np.linalg.norm(r))).to_numpy()[:3, :3] @ d \
                if np.any(r) else d
            lines[name] = (w, p)
        return lines

    def spindle_frame(self, pivot_point: Sequence[float]) -> np.ndarray:
        """4x4 spindle transform S = [R_S, p0 + (EX0S, EY0S, 0) - R_S p0] (workpiece frame at
        home): the spindle turned by R_S = Rx(EA0S) Ry(EB0S) about p0 (mm) and shifted."""
        g = self.get
        p0 = np.asarray(pivot_point, dtype=float)
        R_S = rot_x(g("EA0S")) @ rot_y(g("EB0S"))
        return homogeneous(R_S, p0 + np.array([g("EX0S"), g("EY0S"), 0.0]) - R_S @ p0)

    def apply(self, machine: Machine, thermal_state: Mapping[str, float] | None = None) -> Machine:
        """The machine (same name, kind, limits, pivot, post settings, table centre) with the chain
        ``self.chain(machine)``."""
        return dataclasses.replace(machine, chain=self.chain(machine, thermal_state))

    # ---- thermal -----------------------------------------------------------------------------
    def thermal_state(self, t: np.ndarray, spindle_rpm: float | np.ndarray, hold: str = "step"
                      ) -> dict[str, np.ndarray]:
        """Thermal elements (THERMAL_ELEMENTS: mm or rad) at times t (N,) s, nondecreasing, from
        a cold start at t[0], for the spindle speed spindle_rpm (scalar or (N,)) held from each
        time to the next (hold 'step') or linear between them (hold 'linear'); integrated
        exactly by ``first_order_knots``. Elements without a thermal entry are 0."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        rpm = np.broadcast_to(np.asarray(spindle_rpm, dtype=float), t.shape)
        if t.ndim != 1 or not np.all(np.isfinite(t)) or not np.all(np.isfinite(rpm)):
            raise InputError("thermal_state: t and spindle_rpm must be finite 1-d arrays")
        dt = np.diff(t)
        if np.any(dt < 0):
            raise InputError("thermal_state: time must not decrease "
                             f"(at sample {int(np.argmax(dt < 0)) + 1})")
        out = {}
        for name in THERMAL_ELEMENTS:
            d = self.thermal.get(name)
            out[name] = np.zeros_like(t) if d is None else first_order_response(
                t, rpm / 1000.0, float(d["gain"]), float(d["tau"]), hold)
        return out

    # ---- the real pose -----------------------------------------------------------------------
    def real_frame(self, machine: Machine, q: Mapping[str, Any], thermal: Mapping[str, Any] | None = None,
                   spindle_angle: Any = None, frame: Frame | None = None) -> Frame:
        """THE real tool-tip frame (workpiece frame) for actual joint values q (name -> float or
        (N,) array; rotary axes rad, X, Y, Z mm): the geometric chain (``chain``), then the
        machine-frame thermal translation (mx, my, mz; turned by the table on a table machine,
        ``carriage_rotation``), the spindle-frame thermal transform
        (``thermal_frame``) and, when spindle_angle (rad) is given, the 1x-rev runout in the tool
        frame's xy. thermal: element -> value(s) (``thermal_state``). frame: the geometric part
        ``self.chain(machine).forward(q)`` when the caller already has it (a cache)."""
        f = self.chain(machine).forward(q) if frame is None else frame
        if thermal:
            sp = {k: v for k, v in thermal.items() if k in SPINDLE_THERMAL and np.any(v)}
            if sp:
                f = f @ thermal_frame(sp)
            mv = [thermal.get(k, 0.0) for k in MACHINE_THERMAL]
            if any(np.any(v) for v in mv):
                turn = carriage_rotation(machine.chain, q)
                if turn is not None:
                    mv = list(turn.rotate(mv))
                f = Frame(f.R, tuple(f.p[i] + mv[i] for i in range(3)))
        rc, rs = self.runout
        if spindle_angle is not None and (rc or rs):
            c, s = np.cos(spindle_angle), np.sin(spindle_angle)
            f = f @ Frame(IDENTITY.R, (rc * c - rs * s, rc * s + rs * c, 0.0))
        return f

    def predict(self, machine: Machine, A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray,
                Z: np.ndarray, t: np.ndarray | None = None, spindle_rpm: float | np.ndarray | None = None
                ) -> Prediction:
        """Real tool tip and axis for commanded axes (A, B: the two rotary axes in
        ``machine.rotary`` order, e.g. A, C on an AC table, rad; X, Y, Z mm; arrays (N,)):
        geometric errors, static spindle screw and, when t (s) and spindle_rpm are given, the
        thermal state at those times (``thermal_state``, speed held from each time to the next).
        Compared with the nominal machine. (Servo lag, backlash and clock offset describe motion
        in time and enter through the diagnosis simulator, not here.)"""
        A, B, X, Y, Z = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, dtype=float))
                                              for v in (A, B, X, Y, Z)))
        ideal_tip, ideal_axis = machine.tool_pose_np(A, B, X, Y, Z)
        r1, r2 = machine.rotary
        f = self.real_frame(machine, {"X": X, "Y": Y, "Z": Z, r1: A, r2: B},
                            self._thermal(t, spindle_rpm, len(A)))
        tip, axis = frame_tip_axis(f, len(A))
        return _prediction(tip, axis, ideal_tip, ideal_axis)

    def _thermal(self, t: np.ndarray | None, spindle_rpm: Any, n: int) -> dict[str, np.ndarray] | None:
        if t is None and spindle_rpm is None:
            return None
        if t is None or spindle_rpm is None:
            raise InputError("thermal prediction needs both t and spindle_rpm")
        state = self.thermal_state(np.broadcast_to(np.asarray(t, float), (n,)), spindle_rpm)
        return state if any(np.any(v) for v in state.values()) else None


def frame_tip_axis(f: Frame, n: int) -> tuple[np.ndarray, np.ndarray]:
    """(tip (n,3), tool axis (n,3)) of a numpy-valued frame: its origin and its z column."""
    tip = np.stack([np.broadcast_to(np.asarray(f.p[i], float), (n,)) for i in range(3)], axis=-1)
    axis = np.stack([np.broadcast_to(np.asarray(f.R[i][2], float), (n,)) for i in range(3)], axis=-1)
    return tip, axis


def _prediction(tip: np.ndarray, axis: np.ndarray, ideal_tip: np.ndarray, ideal_axis: np.ndarray
                ) -> Prediction:
    dev = np.linalg.norm(tip - ideal_tip, axis=1) * 1e3
    ang = np.arctan2(np.linalg.norm(np.cross(axis, ideal_axis), axis=1), np.sum(axis * ideal_axis, axis=1))
    ang = ang * 1e6
    return Prediction(tip, axis, ideal_tip, ideal_axis, dev, ang)


# ----------------------------------------------------------------------------------------------
# compensation
class Compensation(tuple):
    """(A, B, X, Y, Z) commanded axes (rad, mm; arrays (N,); A, B: the two rotary axes in
    ``Machine.rotary`` order, e.g. A, C on an AC table); unpacks as a 5-tuple. Attributes:
    tip_residual_um, axis_residual_urad (N,) the remaining predicted deviation from the desired
    pose, iterations (Gauss-Newton iterations used)."""

    tip_residual_um: np.ndarray
    axis_residual_urad: np.ndarray
    iterations: int


def compensate(model: ErrorModel, machine: Machine, tip: np.ndarray, axis: np.ndarray, A0: np.ndarray,
               B0: np.ndarray, t: np.ndarray | None = None, spindle_rpm: float | np.ndarray | None = None,
               tol: float = 1e-12, max_iter: int = 20) -> Compensation:
    """Commanded (A, B, X, Y, Z) such that the model's PREDICTED real tool tip and axis equal the
    desired ones: tip (N,3) mm and unit axis (N,3), workpiece frame; A0, B0 (N,) rad the ideal
    inverse kinematics (start and branch choice), the machine's two rotary axes in
    ``machine.rotary`` order (A, C on an AC table). Undamped Gauss-Newton on all points at once
    (each point an independent 6 x 5 least-squares problem, the axis residual weighted by the
    pivot length, 1 mm on a table-table machine, so both are in mm); Jacobian from the chain's
    screws (space Jacobian, Modern Robotics' JacobianSpace: d tip / d q_i = v_i + w_i x tip,
    d axis / d q_i = w_i x axis, with the positioning and straightness derivatives of the linear
    axes).
    Converges quadratically for small errors; the remaining residual is reported on the result.
    At the pole of the outer axis (B = +-90 deg on the AB head, tilt 0 on a table) the outer axis
    only turns the tool about itself, so it is not determined there (steps use the
    pseudo-inverse and it may move along that direction).
    """
    from camsmooth.machine.kinematics import space_jacobian

    tip = np.atleast_2d(np.asarray(tip, float))
    axis = np.atleast_2d(np.asarray(axis, float))
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    n = len(tip)
    A0, B0 = np.broadcast_to(np.asarray(A0, float), (n,)), np.broadcast_to(np.asarray(B0, float), (n,))
    q = np.column_stack([A0, B0, machine.linear_axes(tip, A0, B0)])
    thermal = model._thermal(t, spindle_rpm, n)
    chain = model.chain(machine)
    w = max(machine.pivot, 1.0)
    order = (*machine.rotary, "X", "Y", "Z")

    def evaluate(qq: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        qd = {k: qq[:, i] for i, k in enumerate(order)}
        f = model.real_frame(machine, qd, thermal, frame=chain.forward(qd))
        p, a = frame_tip_axis(f, n)
        r = np.concatenate([p - tip, w * (a - axis)], axis=1)
        qj = chain.joint_values(qd) if isinstance(chain, RealChain) else qd
        Js = space_jacobian(chain, qj)  # (n, 6, 5) in chain joint order
        turn = carriage_rotation(chain, qd) if isinstance(chain, RealChain) and chain.straightness else None
        Rt = None if turn is None else Frame(turn.R, (0.0, 0.0, 0.0)).to_numpy(n)[:, :3, :3]
        J = np.empty((n, 6, 5))
        for i, k in enumerate(order):
            jw, jv = Js[:, :3, chain.names.index(k)], Js[:, 3:, chain.names.index(k)]
            dp = jv + np.cross(jw, p)
            da = np.cross(jw, a)
            if isinstance(chain, RealChain):
                coef = dict(chain.positioning).get(k)
                if coef:
                    scale = 1.0 + _dpoly(coef, qq[:, i])
                    dp, da = dp * scale[:, None], da * scale[:, None]
                for name, terms in chain.straightness:
                    if name == k:
                        for d, kk, c in terms:
                            rate = kk * c * qq[:, i] ** (kk - 1)
                            if Rt is None:
                                dp[:, d] += rate
                            else:  # the carriage offset turned by the table
                                dp += Rt[:, :, d] * rate[:, None]
            J[:, :3, i], J[:, 3:, i] = dp, w * da
        return r, J, p

    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - iteration count reported
        r, J, _ = evaluate(q)
        # pseudo-inverse: at B = +-90 deg the A column vanishes (A turns the tool about itself)
        step = -(np.linalg.pinv(J, rcond=1e-10) @ r[:, :, None])[:, :, 0]
        q = q + step
        if np.max(np.abs(step)) < tol:
            break
    r, _, _ = evaluate(q)
    out = Compensation((q[:, 0], q[:, 1], q[:, 2], q[:, 3], q[:, 4]))
    out.tip_residual_um = np.linalg.norm(r[:, :3], axis=1) * 1e3
    out.axis_residual_urad = np.linalg.norm(r[:, 3:], axis=1) / w * 1e6
    out.iterations = it
    return out


# ----------------------------------------------------------------------------------------------
def _section(doc: Mapping[str, Any], key: str, source: str, prefix: str = "") -> Mapping[str, Any]:
    """doc[key] as a mapping ({} when absent or null); InputError naming the key otherwise."""
    v = doc.get(key)
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise InputError(f"{prefix}{key} must be an object {{...}}, got {_json_kind(v)} {v!r:.60}", file=source,
                         key=f"{prefix}{key}")
    return v


def _json_kind(v: Any) -> str:
    """How JSON names the type of a parsed value."""
    if isinstance(v, bool):
        return "true/false"
    if isinstance(v, (int, float)):
        return "a number"
    return {list: "an array", str: "a string", type(None): "null"}.get(type(v), "an object")


def _number(v: Any, source: str, column: str) -> float:
    if not _finite_number(v):
        raise InputError(f"{column} must be a finite number, got {v!r}", file=source, key=column)
    return float(v)


def _value(item: Any, unit: str, where: str, source: str) -> float:
    """A {"value": v, "unit": u} item converted to the code's ``unit`` (mm, rad, s, 1, 1/mm, 1/mm2)."""
    if not isinstance(item, Mapping) or "value" not in item:
        raise InputError(f"{where}: expected {{\"value\": ..., \"unit\": ...}}, got {item!r:.60}", file=source,
                         key=where)
    v = item["value"]
    if not _finite_number(v):
        raise InputError(f"{where}: value must be a finite number, got {v!r}", file=source, key=where)
    u = item.get("unit", unit)
    table = _units_for(unit)
    if not isinstance(u, str) or u not in table:
        raise InputError(f"{where}: unit {u!r} is not a {unit} unit (use one of {sorted(table)})",
                         file=source, key=where)
    factor = table[u]
    return float(v) if factor == 1.0 else float(v) * factor


__all__ = ["AxisError", "CHAIN_GEOMETRIC", "chain_axis_errors", "machine_parameters", "rotary_errors",
           "GEOMETRIC_NAMES", "GEOMETRIC_PARAMETERS", "LINEAR_GEOMETRIC", "MACHINE_THERMAL", "POSITIONING",
           "ROTARY_BY_KIND", "ROTARY_GEOMETRIC", "SPINDLE_THERMAL", "SPINDLE_TOOL_GEOMETRIC", "SQUARENESS",
           "STRAIGHTNESS", "TABLE_GEOMETRIC", "THERMAL_ELEMENTS", "Compensation", "ErrorModel", "Prediction",
           "RealChain", "SpindleScrew", "carriage_index", "carriage_rotation", "compensate", "first_order_between",
           "first_order_knots", "first_order_response", "frame_tip_axis", "homogeneous", "interval_slopes",
           "rot_x", "rot_y", "rot_z", "spindle_forward", "thermal_frame"]
