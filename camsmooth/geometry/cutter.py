"""Cutters of the toroid family (bull nose, ball end, flat end): CC <-> CL placement, exact
signed distance, support points.

Frames and signs (docs/CONVENTIONS.md): the tool axis ``T`` is the unit vector from the tool tip
toward the spindle; the tool tip (CL point) is the centre of the cutter's flat bottom face (the
lowest point of a ball end); a surface normal ``n`` points from the material toward the tool.

The family. Ring radius ``R`` (of the circle the corner's centres lie on) and corner radius
``r``, cutter radius ``R + r``: a bull nose has ``R > 0, r > 0``, a ball end ``R = 0`` (a
hemisphere of radius ``r``), a flat end ``r = 0`` (a disc of radius ``R`` on a cylinder: the
torus with a zero tube).  ``R = r = 0`` is no cutter and is refused.

Solid model. The cutter with its shank is the set of points within ``r`` of the solid core
cylinder ``C`` of radius ``R`` whose axis runs from ``c0 = tip + r T`` to
``c1 = tip + max(shank_length - r, r) T`` (a Minkowski sum of ``C`` with a ball of radius ``r``).
This gives exactly the flat bottom (radius ``R``), the torus corner and the cylindrical shank of
radius ``R + r`` up to height ``shank_length - r``.  Its top is rounded (a second torus) where
the real shank continues as a plain cylinder; the rounded top is irrelevant because it lies at
least ``shank_length - r`` above the tip, is covered by the holder when one is given, and the
body is only used for gouge checks near the surface.  When ``shank_length < 2 r`` the core
degenerates to the disc at ``c0`` and the body is ``2 r`` tall.  For ``R = 0`` (ball end) the
core is a segment and the body a capsule; for ``r = 0`` (flat end) the offset vanishes and the
body is the core itself, the solid cylinder of radius ``R`` from the tip to
``tip + shank_length T`` (bottom disc, sharp rim, cylindrical side).  Keeping the body convex is
what makes the signed distance exact and the mesh clearance test (camsmooth.geometry.clearance)
exact.

The optional holder is the solid cylinder of radius ``holder_radius`` from
``tip + shank_length T`` to ``tip + (shank_length + holder_length) T``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from camsmooth.errors import InputError

__all__ = [
    "ToroidalCutter",
    "cc_to_cl",
    "cl_to_cc",
    "signed_distance",
    "support_point",
]

_PARALLEL_EPS = 1e-12


@dataclass(frozen=True)
class ToroidalCutter:
    """End mill of the toroid family (module docstring); all lengths in mm.

    Attributes
    ----------
    R : ring radius (radius of the centre circle of the corner), >= 0; ``R = 0`` is a ball end.
    r : corner radius, >= 0; ``r = 0`` is a flat end.  ``R + r`` must be > 0.
    shank_length : length from the tip of the cylindrical part of radius ``R + r``
        (default ``4 (R + r)``); must be >= ``r`` and > 0.
    holder_radius : radius of the cylindrical holder above the shank, or None for no holder;
        must exceed ``R + r``.
    holder_length : axial length of the holder (default 0 = no holder).
    """

    R: float
    r: float
    shank_length: float | None = None
    holder_radius: float | None = None
    holder_length: float = 0.0

    def __post_init__(self) -> None:
        def num(name: str, value: object) -> float:
            try:
                v = float(value)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                raise InputError(f"cutter {name} must be a number, got {value!r}") from None
            if not math.isfinite(v):
                raise InputError(f"cutter {name} must be finite, got {value!r}")
            return v

        R = num("R (ring radius, mm)", self.R)
        r = num("r (corner radius, mm)", self.r)
        if R < 0:
            raise InputError(f"cutter ring radius R must be >= 0 mm (R = 0 is a ball end), got {R}")
        if r < 0:
            raise InputError(f"cutter corner radius r must be >= 0 mm (r = 0 is a flat end), got {r}")
        if R + r <= 0:
            raise InputError("cutter radius R + r must be > 0 mm (R = 0 is a ball end, r = 0 a flat end), "
                             f"got R = {R}, r = {r}")
        L = 4.0 * (R + r) if self.shank_length is None else num("shank_length (mm)", self.shank_length)
        if L < r or L <= 0:
            raise InputError(f"cutter shank_length ({L} mm) must be > 0 and >= the corner radius r ({r} mm)")
        hl = num("holder_length (mm)", self.holder_length)
        if hl < 0:
            raise InputError(f"cutter holder_length must be >= 0 mm, got {hl}")
        hr = None
        if self.holder_radius is not None:
            hr = num("holder_radius (mm)", self.holder_radius)
            if hr <= R + r:
                raise InputError(f"cutter holder_radius ({hr} mm) must exceed the cutter radius "
                                 f"R + r = {R + r} mm")
        object.__setattr__(self, "R", R)
        object.__setattr__(self, "r", r)
        object.__setattr__(self, "shank_length", L)
        object.__setattr__(self, "holder_radius", hr)
        object.__setattr__(self, "holder_length", hl)

    @property
    def diameter(self) -> float:
        """Cutter diameter 2 (R + r), mm."""
        return 2.0 * (self.R + self.r)

    @property
    def radius(self) -> float:
        """Cutter (and shank) radius R + r, mm."""
        return self.R + self.r

    @property
    def kind(self) -> str:
        """'ball' (R = 0), 'flat' (r = 0) or 'bull' (both > 0)."""
        return "ball" if self.R == 0.0 else ("flat" if self.r == 0.0 else "bull")

    @property
    def core_height(self) -> float:
        """Axial length of the core cylinder C (from ``tip + r T`` upward), mm."""
        return max(float(self.shank_length) - 2.0 * self.r, 0.0)

    @property
    def has_holder(self) -> bool:
        """True when a holder of positive length is modelled."""
        return self.holder_radius is not None and self.holder_length > 0.0


# ---------------------------------------------------------------------------------------------
# helpers

def _unit(v: np.ndarray, what: str) -> np.ndarray:
    v = np.asarray(v, dtype=float)
    if v.shape[-1:] != (3,):
        raise InputError(f"{what} must have shape (..., 3), got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InputError(f"{what} must be finite")
    nrm = np.linalg.norm(v, axis=-1, keepdims=True)
    if np.any(nrm < 1e-12):
        raise InputError(f"{what} contains a zero-length vector")
    return v / nrm


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _ring_direction(n: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """u = (n - (n.T) T) / |n - (n.T) T| (zero where n is parallel to T) and n.T."""
    nt = _dot(n, T)
    w = n - nt[..., None] * T
    wn = np.linalg.norm(w, axis=-1, keepdims=True)
    u = np.where(wn > _PARALLEL_EPS, w / np.where(wn > _PARALLEL_EPS, wn, 1.0), 0.0)
    return u, nt


def _check_normal_side(nt: np.ndarray) -> None:
    if np.any(nt < -1e-9):
        i = int(np.flatnonzero(np.ravel(nt) < -1e-9)[0])
        raise InputError(f"tool axis points into the material at point {i + 1} (n.T = {np.ravel(nt)[i]:.6g} "
                         "< 0): the contact would lie on the rounded top, not on the cutting end")


# ---------------------------------------------------------------------------------------------
# CC <-> CL (METHODS.md section 1)

def cc_to_cl(cutter: ToroidalCutter, cc: np.ndarray, n: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Cutter-location (tool tip) points from cutter-contact points (METHODS.md section 1).

    ``u = (n - (n.T) T) / |n - (n.T) T|``, ``CL = CC + r n + R u - r T``; where ``n`` is parallel
    to ``T`` the flat bottom touches and ``CL = CC``.  Per kind: a ball end (R = 0) has
    ``CL = CC + r (n - T)``, its centre ``CC + r n`` independent of the axis; a flat end (r = 0)
    touches with the point of its bottom rim lowest along ``n``, ``CL = CC + R u`` (no offset along
    the normal).  Face contact (``n`` parallel to ``T``, within 1e-12): every point of the bottom
    disc touches and the contact is taken at its centre, ``CL = CC``; so CC -> CL jumps by ``R``
    between lead 0 and any lead > 0 for the flat end and the bull nose, and their lead windows
    should exclude 0 (camsmooth.geometry.accessibility).

    Parameters
    ----------
    cc : (..., 3) CC points, mm, workpiece frame.
    n : (..., 3) unit surface normals at CC, pointing from the material toward the tool.
    T : (..., 3) unit tool axes (tip -> spindle); broadcast against ``cc``.

    ``n`` and ``T`` are normalised; ``n.T < 0`` (axis pointing into the material) raises
    InputError.  Returns (..., 3) CL points, mm.
    """
    cc = np.asarray(cc, dtype=float)
    n = _unit(n, "surface normal n")
    T = _unit(T, "tool axis T")
    u, nt = _ring_direction(n, T)
    _check_normal_side(nt)
    return cc + cutter.r * (n - T) + cutter.R * u


def cl_to_cc(cutter: ToroidalCutter, cl: np.ndarray, n: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Inverse of :func:`cc_to_cl`: the point of the cutter with surface normal ``n``.

    ``CC = CL - r n - R u + r T`` (METHODS.md section 1); for ``n`` parallel to ``T`` the contact
    is the tip itself (any point of the flat bottom touches; the tip is returned).  Units mm;
    shapes as in :func:`cc_to_cl`.
    """
    cl = np.asarray(cl, dtype=float)
    n = _unit(n, "surface normal n")
    T = _unit(T, "tool axis T")
    u, nt = _ring_direction(n, T)
    _check_normal_side(nt)
    return cl - cutter.r * (n - T) - cutter.R * u


# ---------------------------------------------------------------------------------------------
# exact signed distance of capped cylinders offset by a ball

def _cylinder_sd(base: np.ndarray, axis: np.ndarray, height: float, radius: float, points: np.ndarray,
                 grad: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """Exact signed distance (mm, negative inside) from ``points`` to the solid capped cylinder
    with axis from ``base`` to ``base + height * axis`` and the given radius (0 = segment);
    optionally a (sub)gradient, which is exact where the distance is differentiable.

    Formula: with axial coordinate a and radial distance rho, dz = |a - h/2| - h/2,
    dr = rho - radius: sd = |(max(dr,0), max(dz,0))| outside, max(dr, dz) inside.
    """
    p = points - base
    a = _dot(p, axis)
    w = p - a[..., None] * axis
    rho = np.sqrt(_dot(w, w))
    half = 0.5 * height
    dz = np.abs(a - half) - half
    dr = rho - radius
    drp = np.maximum(dr, 0.0)
    dzp = np.maximum(dz, 0.0)
    out = np.hypot(drp, dzp)
    sd = np.where((dr > 0.0) | (dz > 0.0), out, np.maximum(dr, dz))
    if not grad:
        return sd, None
    # A zero radial direction on the axis is a valid subgradient choice there.
    e = w / np.where(rho > 0.0, rho, 1.0)[..., None]
    sgn = np.where(a >= half, 1.0, -1.0)[..., None] * axis
    outside = out > 0.0
    inv = 1.0 / np.where(outside, out, 1.0)
    g_out = (drp * inv)[..., None] * e + (dzp * inv)[..., None] * sgn
    g_in = np.where((dr >= dz)[..., None], e, sgn)
    g = np.where(outside[..., None], g_out, g_in)
    return sd, g


def _cylinder_support(base: np.ndarray, axis: np.ndarray, height: float, radius: float,
                      direction: np.ndarray) -> np.ndarray:
    """Point of the solid capped cylinder extreme in ``direction`` (ties: the lower end, the
    axis point for a direction parallel to the axis)."""
    dt = _dot(direction, axis)
    w = direction - dt[..., None] * axis
    wn = np.sqrt(_dot(w, w))
    radial = np.where((wn > _PARALLEL_EPS * np.maximum(1.0, np.abs(dt)))[..., None],
                      w / np.where(wn > 0.0, wn, 1.0)[..., None], 0.0)
    up = np.where(dt > 0.0, height, 0.0)[..., None]
    return base + up * axis + radius * radial


def _bodies(cutter: ToroidalCutter, tip: np.ndarray, axis: np.ndarray) -> list[tuple]:
    """Convex bodies of the tool as (base, axis, height, radius, offset) tuples: the cutter +
    shank (core cylinder offset by r) and, if present, the holder (offset 0)."""
    bodies = [(tip + cutter.r * axis, axis, cutter.core_height, cutter.R, cutter.r)]
    if cutter.has_holder:
        bodies.append((tip + float(cutter.shank_length) * axis, axis, float(cutter.holder_length),
                       float(cutter.holder_radius), 0.0))
    return bodies


def signed_distance(cutter: ToroidalCutter, tip: np.ndarray, axis: np.ndarray,
                    points: np.ndarray) -> np.ndarray:
    """Signed distance (mm; negative inside) from points to the tool solid.

    The tool solid is cutter + shank (the core cylinder C offset by r, see the module docstring)
    united with the holder.  For the convex cutter + shank, ``sd = sd_C - r`` is exact inside
    and outside; the union with the holder is taken by ``min``, which is exact outside and on
    the boundary, and inside gives the depth within the deeper of the two bodies.

    ``tip`` (..., 3) tool tips (CL), ``axis`` (..., 3) tool axes (normalised here), ``points``
    (..., 3); all broadcast together.  Returns (...) array, mm.
    """
    tip = np.asarray(tip, dtype=float)
    axis = _unit(axis, "tool axis")
    points = np.asarray(points, dtype=float)
    sd = None
    for base, ax, h, rad, off in _bodies(cutter, tip, axis):
        d = _cylinder_sd(base, ax, h, rad, points)[0] - off
        sd = d if sd is None else np.minimum(sd, d)
    return sd


def support_point(cutter: ToroidalCutter, tip: np.ndarray, axis: np.ndarray,
                  direction: np.ndarray) -> np.ndarray:
    """The point of the cutter + shank solid (holder excluded) extreme in ``direction``.

    Closed form for the offset cylinder: support of the core cylinder C in ``direction`` plus
    ``r * direction / |direction|``.  Ties (direction parallel to the axis or perpendicular to
    it) pick the axis point / the lower end of C.  Shapes (..., 3), broadcast; mm.
    """
    tip = np.asarray(tip, dtype=float)
    axis = _unit(axis, "tool axis")
    d = _unit(direction, "direction")
    base = tip + cutter.r * axis
    return _cylinder_support(base, axis, cutter.core_height, cutter.R, d) + cutter.r * d
