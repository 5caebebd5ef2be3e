"""The machine error model: geometric axis errors, the spindle screw model and spindle thermal
drift, expressed as a perturbed product-of-exponentials chain (camsmooth.machine.kinematics.Chain), so
that the NLP smoother (CasADi symbols) and the simulators (numpy) evaluate the same machine.

Geometric errors (ISO 230-1 style names; METHODS.md sections 3 and 4)
---------------------------------------------------------------------
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
and thermal errors change only the home pose M:

    M = [R_S, p0 + (EX0S, EY0S, 0) - R_S p0] M_nominal Trans(0, 0, -EZ0T) T_screw T_thermal,

where T_screw (the static part of the spindle screw model, see SpindleScrew) and T_thermal (see
below) act in the tool-tip frame. So an axis-line error alone does not move the tool at the home
pose; its effect grows as the axis turns (the usual convention of kinematic calibration).

Sign convention of the first-order error vectors (METHODS section 3, verified in
tests/test_errormodel.py): the error matrix T_e = T_i^-1 T_r is a BODY-frame error. The stated B
and C rows agree with the exact POE error to O(S^2) as written. The stated A row does not agree in
any frame: its e_y term must read -S_az + S_az cos a - S_ay sin a (the sign of the S_ay sin a
term is flipped in the source); e_z is as stated.

Spindle thermal drift (METHODS section 5)
-----------------------------------------
Five elements, in the spindle (tool) frame at the tool tip: dx, dy, dz (mm) the displacement of
the tool tip, exz, eyz (rad) the tilt of the spindle in the xz and yz planes, such that a point
of the spindle a height h above the tip (along the tool axis T) moves by
(dx - exz h, dy - eyz h, dz), i.e. a rotation by (eyz, -exz, 0) about the tip and the real axis
is ~ (-exz, -eyz, 1). Each element e follows tau de/dt = gain * rpm / 1000 - e from a cold start
(e = 0); see ``ErrorModel.thermal_state``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.atomic import write_text_atomic
from camsmooth.machine.kinematics import Chain, Frame, Machine

# ----------------------------------------------------------------------------------------------
# parameter tables
GEOMETRIC_PARAMETERS: dict[str, tuple[str, str]] = {
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
GEOMETRIC_NAMES: tuple[str, ...] = tuple(GEOMETRIC_PARAMETERS)

THERMAL_ELEMENTS: dict[str, str] = {"dx": "mm", "dy": "mm", "dz": "mm", "exz": "rad", "eyz": "rad"}

FORMAT = "camsmooth-error-model"
FORMAT_VERSION = 1

# unit -> factor to the code's unit
_LENGTH_UNITS = {"mm": 1.0, "um": 1e-3, "m": 1e3}
_ANGLE_UNITS = {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "deg": math.pi / 180.0}
_TIME_UNITS = {"s": 1.0, "min": 60.0, "h": 3600.0}
_UNITLESS = {"1": 1.0, "": 1.0}


def _units_for(unit: str) -> dict[str, float]:
    return {"mm": _LENGTH_UNITS, "rad": _ANGLE_UNITS, "s": _TIME_UNITS, "1": _UNITLESS}[unit]


# ----------------------------------------------------------------------------------------------
# small rigid-body helpers (numpy, constant)
def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
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
# the error model
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


@dataclass
class ErrorModel:
    """A machine error model (see the module docstring for every definition).

    geometric: name -> value (GEOMETRIC_PARAMETERS: mm or rad; missing names are 0).
    spindle: the spindle screw model, or None (no spindle screw errors).
    thermal: element (dx, dy, dz, exz, eyz) -> {"gain": value at steady state per 1000 rpm
    (mm or rad), "tau": time constant (s)}; missing elements do not drift.
    meta: free-form provenance (strings/numbers), stored in the JSON file as is.
    """

    geometric: dict[str, float] = field(default_factory=dict)
    spindle: SpindleScrew | None = None
    thermal: dict[str, dict] = field(default_factory=dict)
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        unknown = sorted(set(self.geometric) - set(GEOMETRIC_NAMES))
        if unknown:
            raise InputError(f"unknown geometric error parameter(s) {unknown}; "
                             f"known: {list(GEOMETRIC_NAMES)}")
        for k, v in self.geometric.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise InputError(f"geometric error {k} must be a finite number, got {v!r}")
        unknown = sorted(set(self.thermal) - set(THERMAL_ELEMENTS))
        if unknown:
            raise InputError(f"unknown thermal element(s) {unknown}; known: {list(THERMAL_ELEMENTS)}")
        for k, d in self.thermal.items():
            if not isinstance(d, Mapping) or set(d) != {"gain", "tau"}:
                raise InputError(f"thermal element {k} must be {{'gain': ..., 'tau': ...}}, got {d!r}")
            if not (math.isfinite(d["gain"]) and math.isfinite(d["tau"]) and d["tau"] > 0):
                raise InputError(f"thermal element {k}: gain must be finite and tau > 0 s, got {dict(d)}")

    def get(self, name: str) -> float:
        """Geometric parameter value (0 when missing)."""
        if name not in GEOMETRIC_PARAMETERS:
            raise KeyError(name)
        return float(self.geometric.get(name, 0.0))

    # ---- JSON ------------------------------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        """The JSON document: every value with its unit beside it."""
        doc: dict[str, Any] = {"format": FORMAT, "version": FORMAT_VERSION}
        doc["geometric"] = {k: {"value": float(v), "unit": GEOMETRIC_PARAMETERS[k][0]}
                            for k, v in self.geometric.items()}
        doc["spindle"] = None if self.spindle is None else {
            k: {"value": v, "unit": SpindleScrew.UNITS[k]} for k, v in self.spindle.as_dict().items()}
        doc["thermal"] = {k: {"gain": {"value": float(d["gain"]), "unit": f"{THERMAL_ELEMENTS[k]}/1000rpm"},
                              "tau": {"value": float(d["tau"]), "unit": "s"}}
                          for k, d in self.thermal.items()}
        doc["meta"] = self.meta
        return doc

    @staticmethod
    def from_dict(doc: Mapping[str, Any], source: str = "<model>") -> ErrorModel:
        """Inverse of ``to_dict``; accepts other units (um, urad, mrad, deg, min, h) and converts."""
        if not isinstance(doc, Mapping) or doc.get("format") != FORMAT:
            raise InputError(f"not a camsmooth error model (expected \"format\": \"{FORMAT}\")", file=source)
        if doc.get("version") != FORMAT_VERSION:
            raise InputError(f"unsupported model version {doc.get('version')!r} "
                             f"(supported: {FORMAT_VERSION})", file=source)
        geo = {}
        for k, item in (doc.get("geometric") or {}).items():
            if k not in GEOMETRIC_PARAMETERS:
                raise InputError(f"unknown geometric error parameter {k!r}", file=source)
            geo[k] = _value(item, GEOMETRIC_PARAMETERS[k][0], f"geometric.{k}", source)
        spindle = None
        sp = doc.get("spindle")
        if sp is not None:
            if not isinstance(sp, Mapping):
                raise InputError("spindle must be an object or null", file=source)
            unknown = sorted(set(sp) - set(SpindleScrew.UNITS))
            if unknown:
                raise InputError(f"unknown spindle screw parameter(s) {unknown}", file=source)
            spindle = SpindleScrew(**{k: _value(v, SpindleScrew.UNITS[k], f"spindle.{k}", source)
                                      for k, v in sp.items()})
        thermal = {}
        for k, item in (doc.get("thermal") or {}).items():
            if k not in THERMAL_ELEMENTS:
                raise InputError(f"unknown thermal element {k!r}", file=source)
            if not isinstance(item, Mapping) or set(item) != {"gain", "tau"}:
                raise InputError(f"thermal.{k} must hold 'gain' and 'tau'", file=source)
            gain = item["gain"]
            unit = gain.get("unit", "") if isinstance(gain, Mapping) else ""
            base = unit.split("/")[0] if unit.endswith("/1000rpm") else None
            if base is None:
                raise InputError(f"thermal.{k}.gain: unit must be '<unit>/1000rpm', got {unit!r}",
                                 file=source)
            g = _value({"value": gain.get("value"), "unit": base}, THERMAL_ELEMENTS[k], f"thermal.{k}.gain",
                       source)
            thermal[k] = {"gain": g, "tau": _value(item["tau"], "s", f"thermal.{k}.tau", source)}
        meta = doc.get("meta") or {}
        try:
            return ErrorModel(geo, spindle, thermal, dict(meta))
        except InputError as exc:
            raise InputError(str(exc), file=source) from None

    def to_json(self, path: str | os.PathLike) -> Path:
        """Write the model as JSON (atomically). Floats are written with repr, so ``from_json``
        gives back exactly the same numbers."""
        write_text_atomic(path, json.dumps(self.to_dict(), indent=2) + "\n")
        return Path(path)

    @staticmethod
    def from_json(path: str | os.PathLike) -> ErrorModel:
        """Read a model written by ``to_json`` (InputError on a missing or malformed file)."""
        try:
            text = Path(path).read_text()
        except FileNotFoundError:
            raise InputError("model file not found", file=str(path)) from None
        try:
            doc = json.loads(text)
        except json.JSONDecodeError as exc:
            raise InputError(f"not valid JSON: {exc}", file=str(path)) from None
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
        fixed) thermal state: Trans(0, 0, -EZ0T) T_screw T_thermal."""
        T = homogeneous(p=[0.0, 0.0, -self.get("EZ0T")])
        if self.spindle is not None:
            T = T @ self.spindle.static_tip_transform()
        if thermal_state:
            T = T @ thermal_frame({k: float(v) for k, v in thermal_state.items()}).to_numpy()
        return T

    def chain(self, machine: Machine, thermal_state: Mapping[str, float] | None = None) -> Chain:
        """The machine's chain perturbed by this model: screws of A and B replaced by the real
        axis lines, home pose M with the spindle, tool, static spindle-screw and (when given, a
        fixed) thermal errors. Works for numpy and CasADi evaluation alike (it is a Chain)."""
        chain = machine.chain
        if chain.screws is not None:
            raise ValueError("apply the error model to the nominal machine (its chain is already perturbed)")
        names = chain.names
        if names != ("X", "Y", "Z", "A", "B"):
            raise ValueError(f"the error model needs an AB head chain X, Y, Z, A, B; got {names}")
        jA, jB = chain.joints[3], chain.joints[4]
        if not (np.allclose(jA.direction, (1, 0, 0)) and np.allclose(jB.direction, (0, 1, 0))
                and np.allclose(jA.point, jB.point)):
            raise ValueError("the error model needs nominal A about x and B about y through one pivot point")
        F_A, F_B, S = self.axis_frames(jA.point)
        w_A = F_A[:3, 0]
        w_B = F_B[:3, 1]
        screws = list(chain.joint_screws())
        screws[3] = (w_A, -np.cross(w_A, F_A[:3, 3]))
        screws[4] = (w_B, -np.cross(w_B, F_B[:3, 3]))
        home = S @ chain.home @ self.tip_transform(thermal_state)
        return chain.with_screws(screws, home)

    def apply(self, machine: Machine, thermal_state: Mapping[str, float] | None = None) -> Machine:
        """A Machine (same name, limits, pivot) whose chain is ``self.chain(machine)``."""
        return Machine(machine.name, machine.kind, machine.pivot, self.chain(machine, thermal_state),
                       machine.limits)

    # ---- thermal -----------------------------------------------------------------------------
    def thermal_state(self, t: np.ndarray, spindle_rpm: float | np.ndarray) -> dict[str, np.ndarray]:
        """Thermal elements (dx, dy, dz mm; exz, eyz rad) at times t (N,) s, nondecreasing, for a
        spindle speed held piecewise constant: spindle_rpm[k] holds on [t[k], t[k+1]) (a scalar
        holds throughout). Cold start: every element is 0 at t[0]. Exact discrete solution of
        tau de/dt = gain rpm / 1000 - e:  e[k+1] = e_ss + (e[k] - e_ss) exp(-(t[k+1]-t[k]) / tau),
        e_ss = gain rpm[k] / 1000. Elements without a thermal entry are 0."""
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
            if d is None:
                out[name] = np.zeros_like(t)
                continue
            out[name] = first_order_response(t, rpm / 1000.0, float(d["gain"]), float(d["tau"]))
        return out

    # ---- prediction -----------------------------------------------------------------------
    def predict(self, machine: Machine, A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray,
                Z: np.ndarray, t: np.ndarray | None = None, spindle_rpm: float | np.ndarray | None = None
                ) -> Prediction:
        """Real tool tip and axis for commanded axes (A, B rad; X, Y, Z mm; arrays (N,)):
        geometric errors, static spindle screw and, when t (s) and spindle_rpm are given, the
        thermal state at those times (``thermal_state``). Compared with the nominal machine."""
        A, B, X, Y, Z = np.broadcast_arrays(*(np.atleast_1d(np.asarray(v, dtype=float))
                                              for v in (A, B, X, Y, Z)))
        ideal_tip, ideal_axis = machine.tool_pose_np(A, B, X, Y, Z)
        tip, axis = self._real_pose(machine, A, B, X, Y, Z, self._thermal(t, spindle_rpm, len(A)))
        return _prediction(tip, axis, ideal_tip, ideal_axis)

    def _thermal(self, t: np.ndarray | None, spindle_rpm: Any, n: int) -> dict[str, np.ndarray] | None:
        if t is None and spindle_rpm is None:
            return None
        if t is None or spindle_rpm is None:
            raise InputError("thermal prediction needs both t and spindle_rpm")
        state = self.thermal_state(np.broadcast_to(np.asarray(t, float), (n,)), spindle_rpm)
        return state if any(np.any(v) for v in state.values()) else None

    def _real_pose(self, machine: Machine, A: np.ndarray, B: np.ndarray, X: np.ndarray, Y: np.ndarray,
                   Z: np.ndarray, thermal: Mapping[str, np.ndarray] | None
                   ) -> tuple[np.ndarray, np.ndarray]:
        f = self.chain(machine).forward({"X": X, "Y": Y, "Z": Z, "A": A, "B": B})
        if thermal is not None:
            f = f @ thermal_frame(thermal)
        n = len(A)
        tip = np.stack([np.broadcast_to(f.p[i], (n,)) for i in range(3)], axis=-1)
        axis = np.stack([np.broadcast_to(f.R[i][2], (n,)) for i in range(3)], axis=-1)
        return tip, axis


def _prediction(tip: np.ndarray, axis: np.ndarray, ideal_tip: np.ndarray, ideal_axis: np.ndarray
                ) -> Prediction:
    dev = np.linalg.norm(tip - ideal_tip, axis=1) * 1e3
    ang = np.arctan2(np.linalg.norm(np.cross(axis, ideal_axis), axis=1), np.sum(axis * ideal_axis, axis=1))
    ang = ang * 1e6
    return Prediction(tip, axis, ideal_tip, ideal_axis, dev, ang)


def first_order_response(t: np.ndarray, u: np.ndarray, gain: float, tau: float) -> np.ndarray:
    """Exact response e(t) of tau de/dt = gain u - e, e(t[0]) = 0, for u piecewise constant
    (u[k] on [t[k], t[k+1])): e[k+1] = d_k e[k] + (1 - d_k) gain u[k], d_k = exp(-dt_k / tau)."""
    t = np.asarray(t, float)
    u = np.asarray(u, float)
    n = len(t)
    e = np.zeros_like(t)
    if n < 2 or gain == 0.0:
        return e
    decay = np.exp(-np.diff(t) / tau)
    b = (1.0 - decay) * gain * u[:-1]
    logd = np.cumsum(np.log(np.maximum(decay, 1e-300)))
    # The linear recurrence in closed form, e[k+1] = Q_k (e[s] + sum_{j=s..k} b_j / Q_j) with
    # Q_k = prod_{i=s..k} d_i, evaluated in chunks over which Q stays above exp(-500) so the
    # division cannot overflow; this keeps it vectorised for long recordings.
    start, e_start = 0, 0.0
    while start < n - 1:
        base = logd[start - 1] if start > 0 else 0.0
        end = int(np.searchsorted(base - logd[start:], 500.0, side="right")) + start
        end = min(max(end, start + 1), n - 1)
        Q = np.exp(logd[start:end] - base)
        e[start + 1:end + 1] = Q * (e_start + np.cumsum(b[start:end] / Q))
        start, e_start = end, e[end]
    return e


def thermal_frame(state: Mapping[str, Any]) -> Frame:
    """The tool-tip-frame transform of a thermal state (module docstring): translation
    (dx, dy, dz) and rotation by the vector (eyz, -exz, 0) (exact Rodrigues). Entries may be
    floats or numpy arrays (N,)."""
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
# compensation
class Compensation(tuple):
    """(A, B, X, Y, Z) commanded axes (rad, mm; arrays (N,)); unpacks as a 5-tuple. Attributes:
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
    inverse kinematics (start and branch choice). Undamped Gauss-Newton on all points at once
    (each point an independent 6 x 5 least-squares problem, the axis residual weighted by the
    pivot length so both are in mm); Jacobian by central differences on the vectorised model.
    Converges quadratically for small errors; the remaining residual is reported on the result.
    At B = +-90 deg A only turns the tool about itself, so A is not determined there (steps use
    the pseudo-inverse and A may move along that direction).
    """
    tip = np.atleast_2d(np.asarray(tip, float))
    axis = np.atleast_2d(np.asarray(axis, float))
    axis = axis / np.linalg.norm(axis, axis=1, keepdims=True)
    n = len(tip)
    q = np.column_stack([np.broadcast_to(np.asarray(A0, float), (n,)),
                         np.broadcast_to(np.asarray(B0, float), (n,)), machine.linear_axes(tip, axis)])
    thermal = model._thermal(t, spindle_rpm, n)
    chain = model.chain(machine)
    w = max(machine.pivot, 1.0)

    def residual(qq: np.ndarray) -> np.ndarray:
        f = chain.forward({"A": qq[:, 0], "B": qq[:, 1], "X": qq[:, 2], "Y": qq[:, 3], "Z": qq[:, 4]})
        if thermal is not None:
            f = f @ thermal_frame(thermal)
        p = np.stack([np.broadcast_to(f.p[i], (n,)) for i in range(3)], axis=-1)
        a = np.stack([np.broadcast_to(f.R[i][2], (n,)) for i in range(3)], axis=-1)
        return np.concatenate([p - tip, w * (a - axis)], axis=1)

    h = 1e-6
    it = 0
    for it in range(1, max_iter + 1):  # noqa: B007 - iteration count reported
        r = residual(q)
        J = np.empty((n, 6, 5))
        for k in range(5):
            dq = np.zeros(5)
            dq[k] = h
            J[:, :, k] = (residual(q + dq) - residual(q - dq)) / (2 * h)
        # pseudo-inverse: at B = +-90 deg the A column vanishes (A turns the tool about itself)
        step = -(np.linalg.pinv(J, rcond=1e-10) @ r[:, :, None])[:, :, 0]
        q = q + step
        if np.max(np.abs(step)) < tol:
            break
    r = residual(q)
    out = Compensation((q[:, 0], q[:, 1], q[:, 2], q[:, 3], q[:, 4]))
    out.tip_residual_um = np.linalg.norm(r[:, :3], axis=1) * 1e3
    out.axis_residual_urad = np.linalg.norm(r[:, 3:], axis=1) / w * 1e6
    out.iterations = it
    return out


# ----------------------------------------------------------------------------------------------
def _value(item: Any, unit: str, where: str, source: str) -> float:
    """A {"value": v, "unit": u} item converted to the code's ``unit`` (mm, rad, s, 1)."""
    if not isinstance(item, Mapping) or "value" not in item:
        raise InputError(f"{where}: expected {{\"value\": ..., \"unit\": ...}}", file=source)
    v = item["value"]
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InputError(f"{where}: value must be a finite number, got {v!r}", file=source)
    u = item.get("unit", unit)
    table = _units_for(unit)
    if u not in table:
        raise InputError(f"{where}: unit {u!r} is not a {unit} unit (use one of {sorted(table)})",
                         file=source)
    factor = table[u]
    return float(v) if factor == 1.0 else float(v) * factor


__all__ = ["GEOMETRIC_NAMES", "GEOMETRIC_PARAMETERS", "THERMAL_ELEMENTS", "Compensation", "ErrorModel",
           "Prediction", "SpindleScrew", "compensate", "first_order_response", "spindle_forward",
           "thermal_frame", "homogeneous", "rot_x", "rot_y", "rot_z"]
