"""Parametric surfaces, their tessellation, surface-definition files and mesh loading.

Frames, units and signs
-----------------------
Workpiece frame W (right-handed), lengths in mm. A surface is a map S(u, v) -> W on the rectangle
``u_range x v_range``. Its unit normal is n = (Su x Sv) / |Su x Sv|; every surface shipped with
camsmooth is parametrised so that n points out of the material toward the tool (CONVENTIONS.md).

Curvature sign: k > 0 where the surface bends toward n (concave as seen from the tool, e.g. the
inside of a bowl), k < 0 where it bends away (convex, e.g. the top of a dome). This is the
classical second fundamental form with L = Suu.n, M = Suv.n, N = Svv.n and normal curvature
k(w) = II(w, w) / I(w, w) (do Carmo, "Differential Geometry of Curves and Surfaces", sections 3-2
and 3-3). METHODS.md section 1 (local gouging) compares this tensor with the cutter's, in the same
sign convention.

Definition files (TOML, mm) are read with ``tomllib`` and written by the small writer in this
module; see surfaces/README.md for the format.
"""

from __future__ import annotations

import difflib
import json
import math
import tomllib
import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import trimesh
from scipy.interpolate import NdBSpline

from camsmooth.errors import InputError
from camsmooth.io.atomic import atomic_path, write_text_atomic

__all__ = [
    "SurfaceDerivatives",
    "FundamentalForms",
    "ParametricSurface",
    "Plane",
    "Cylinder",
    "SpherePatch",
    "Saddle",
    "Sinusoid",
    "BSplineSurface",
    "SURFACE_KINDS",
    "clamped_knots",
    "surface_from_definition",
    "tessellate",
    "tessellate_to_tolerance",
    "grid_chord_error",
    "load_definition",
    "save_definition",
    "definition_text",
    "Surface",
    "load_surface",
    "load_mesh",
    "save_mesh",
    "check_mesh_orientation",
    "surface_normals_at",
]

MESH_SUFFIXES = (".stl", ".obj", ".ply")


# ---------------------------------------------------------------------------------------------
# small vector helpers


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.einsum("...i,...i->...", a, b)


def _unit(a: np.ndarray) -> np.ndarray:
    norm = np.linalg.norm(a, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return a / norm


def _uv(u: Any, v: Any) -> tuple[np.ndarray, np.ndarray]:
    u, v = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
    return u, v


def _stack3(x: Any, y: Any, z: Any, shape: tuple[int, ...]) -> np.ndarray:
    out = np.empty(shape + (3,))
    out[..., 0], out[..., 1], out[..., 2] = x, y, z
    return out


def _array(x: Any, name: str) -> np.ndarray:
    try:
        return np.array(x, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"'{name}' must be numbers in a regular (nested) list, got {str(x)[:80]}") from None


def _vec3(x: Any, name: str) -> np.ndarray:
    a = _array(x, name)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"'{name}' must be 3 finite numbers, got {x!r}")
    return a


def _range(x: Any, name: str) -> tuple[float, float]:
    a = _array(x, name)
    if a.shape != (2,) or not np.all(np.isfinite(a)) or not a[0] < a[1]:
        raise ValueError(f"'{name}' must be [lo, hi] with finite lo < hi, got {x!r}")
    return float(a[0]), float(a[1])


def _positive(x: Any, name: str) -> float:
    x = float(x)
    if not (math.isfinite(x) and x > 0):
        raise ValueError(f"'{name}' must be a positive finite number, got {x!r}")
    return x


def _finite(x: Any, name: str) -> float:
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"'{name}' must be a finite number, got {x!r}")
    return x


# ---------------------------------------------------------------------------------------------
# interface


@dataclass(frozen=True)
class SurfaceDerivatives:
    """First and second partial derivatives of S(u, v), each (..., 3), mm per parameter unit."""

    Su: np.ndarray
    Sv: np.ndarray
    Suu: np.ndarray
    Suv: np.ndarray
    Svv: np.ndarray


@dataclass(frozen=True)
class FundamentalForms:
    """First (E, F, G) and second (L, M, N) fundamental forms and the unit normal n.

    L = Suu.n, M = Suv.n, N = Svv.n with n = Su x Sv / |Su x Sv| (module sign convention).
    """

    E: np.ndarray
    F: np.ndarray
    G: np.ndarray
    L: np.ndarray
    M: np.ndarray
    N: np.ndarray
    n: np.ndarray


class ParametricSurface(ABC):
    """A regular parametric surface S(u, v) in the workpiece frame (mm).

    Methods take arrays ``u``, ``v`` of any equal (or broadcastable) shape ``s`` and return arrays
    of shape ``s`` (scalars per point) or ``s + (3,)`` (vectors per point).
    """

    kind: ClassVar[str] = ""
    u_range: tuple[float, float]
    v_range: tuple[float, float]

    @abstractmethod
    def point(self, u: Any, v: Any) -> np.ndarray:
        """Surface point S(u, v), shape (..., 3), mm."""

    @abstractmethod
    def derivatives(self, u: Any, v: Any) -> SurfaceDerivatives:
        """Partial derivatives Su, Sv, Suu, Suv, Svv, each (..., 3)."""

    @abstractmethod
    def parameters(self) -> dict[str, Any]:
        """The definition-file keys of this surface (everything but ``kind``), in file order."""

    # -- derived geometry ---------------------------------------------------------------------

    def normal(self, u: Any, v: Any) -> np.ndarray:
        """Unit normal n = Su x Sv / |Su x Sv|, (..., 3), out of the material (toward the tool)."""
        d = self.derivatives(u, v)
        return _unit(np.cross(d.Su, d.Sv))

    def fundamental_forms(self, u: Any, v: Any) -> FundamentalForms:
        """First and second fundamental forms at (u, v) (do Carmo 3-2, 3-3; sign as module doc)."""
        d = self.derivatives(u, v)
        n = _unit(np.cross(d.Su, d.Sv))
        return FundamentalForms(
            E=_dot(d.Su, d.Su), F=_dot(d.Su, d.Sv), G=_dot(d.Sv, d.Sv),
            L=_dot(d.Suu, n), M=_dot(d.Suv, n), N=_dot(d.Svv, n), n=n,
        )

    def curvature_tensor(self, u: Any, v: Any, e1: Any, e2: Any) -> np.ndarray:
        """Second fundamental form as a 2x2 tensor in the tangent basis (e1, e2), shape (..., 2, 2).

        ``e1``, ``e2`` (..., 3) should be an orthonormal basis of the tangent plane at (u, v); any
        normal component is discarded (each vector is expressed in (Su, Sv) by least squares).
        Entry [i, j] = II(e_i, e_j) in 1/mm: the normal curvature along e1 is [0, 0]. Sign: positive
        where the surface bends toward its normal (concave seen from the tool), as in the module
        doc; this is the tensor that METHODS.md section 1 compares with the cutter's.
        """
        d = self.derivatives(u, v)
        n = _unit(np.cross(d.Su, d.Sv))
        E, F, G = _dot(d.Su, d.Su), _dot(d.Su, d.Sv), _dot(d.Sv, d.Sv)
        L, M, N = _dot(d.Suu, n), _dot(d.Suv, n), _dot(d.Svv, n)
        det = E * G - F * F

        def coords(e: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            # solve I [a, b]^T = [e.Su, e.Sv]^T: e's components along Su and Sv
            p, q = _dot(e, d.Su), _dot(e, d.Sv)
            return (G * p - F * q) / det, (E * q - F * p) / det

        a1, b1 = coords(np.asarray(e1, dtype=float))
        a2, b2 = coords(np.asarray(e2, dtype=float))
        t11 = L * a1 * a1 + 2 * M * a1 * b1 + N * b1 * b1
        t12 = L * a1 * a2 + M * (a1 * b2 + b1 * a2) + N * b1 * b2
        t22 = L * a2 * a2 + 2 * M * a2 * b2 + N * b2 * b2
        return np.stack([np.stack([t11, t12], -1), np.stack([t12, t22], -1)], -2)

    def principal_curvatures(self, u: Any, v: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Principal curvatures and directions: (k1, k2, d1, d2) with k1 >= k2 (1/mm).

        d1, d2 (..., 3) are unit tangent vectors with (d1, d2, n) right-handed. Sign: k > 0 where
        the surface bends toward n (concave seen from the tool). Eigen-decomposition of the
        second fundamental form in the orthonormal basis e1 = Su/|Su|, e2 = n x e1; at umbilics
        (sphere, plane) the directions are that basis.
        """
        d = self.derivatives(u, v)
        n = _unit(np.cross(d.Su, d.Sv))
        e1 = _unit(d.Su)
        e2 = np.cross(n, e1)
        t = self.curvature_tensor(u, v, e1, e2)
        w, vec = np.linalg.eigh(t)  # ascending eigenvalues
        k1, k2 = w[..., 1], w[..., 0]
        d1 = _unit(vec[..., 0, 1, None] * e1 + vec[..., 1, 1, None] * e2)
        d2 = np.cross(n, d1)
        return k1, k2, d1, d2

    def grid(self, nu: int, nv: int) -> tuple[np.ndarray, np.ndarray]:
        """Uniform parameter grid (U, V) of shape (nu, nv), 'ij' indexing, covering the ranges."""
        us = np.linspace(*self.u_range, int(nu))
        vs = np.linspace(*self.v_range, int(nv))
        return np.meshgrid(us, vs, indexing="ij")

    def __repr__(self) -> str:
        return f"{type(self).__name__}(u_range={self.u_range}, v_range={self.v_range})"


# ---------------------------------------------------------------------------------------------
# analytic surfaces


class Plane(ParametricSurface):
    """Plane S = origin + u a + v b with a = unit(u_dir), b = unit component of v_dir normal to a.

    Normal a x b; the default (u_dir = x, v_dir = y) gives n = +z. u, v are in mm.
    """

    kind = "plane"

    def __init__(self, u_range: Any, v_range: Any, origin: Any = (0.0, 0.0, 0.0),
                 u_dir: Any = (1.0, 0.0, 0.0), v_dir: Any = (0.0, 1.0, 0.0)) -> None:
        self.u_range, self.v_range = _range(u_range, "u_range"), _range(v_range, "v_range")
        self.origin = _vec3(origin, "origin")
        self.u_dir, self.v_dir = _vec3(u_dir, "u_dir"), _vec3(v_dir, "v_dir")
        if not np.linalg.norm(self.u_dir) > 0:
            raise ValueError("'u_dir' must be non-zero")
        a = self.u_dir / np.linalg.norm(self.u_dir)
        b = self.v_dir - (self.v_dir @ a) * a
        if not np.linalg.norm(b) > 1e-9 * np.linalg.norm(self.v_dir):
            raise ValueError("'v_dir' must be non-zero and not parallel to 'u_dir'")
        self._a, self._b = a, b / np.linalg.norm(b)

    def point(self, u: Any, v: Any) -> np.ndarray:
        u, v = _uv(u, v)
        return self.origin + u[..., None] * self._a + v[..., None] * self._b

    def derivatives(self, u: Any, v: Any) -> SurfaceDerivatives:
        u, _ = _uv(u, v)
        z = np.zeros(u.shape + (3,))
        return SurfaceDerivatives(Su=z + self._a, Sv=z + self._b, Suu=z, Suv=z.copy(), Svv=z.copy())

    def parameters(self) -> dict[str, Any]:
        return {"u_range": list(self.u_range), "v_range": list(self.v_range), "origin": list(self.origin),
                "u_dir": list(self.u_dir), "v_dir": list(self.v_dir)}


class Cylinder(ParametricSurface):
    """Circular cylinder strip about a non-vertical axis, convex (outside) or concave (inside).

    The axis passes through ``center`` along a = unit(``axis``); ``up`` is the unit component of
    +z normal to a and w = up x a. u = position along the axis (mm), v = arc length (mm) around
    the circle measured from the top line (convex) or the bottom line (concave), theta = v / R:

        S = center + u a + R (s cos(theta) up + sin(theta) w),   s = +1 convex, -1 concave

    so Su x Sv = R n with n = s sin(theta) w + cos(theta) up: outward (convex) or toward the axis
    (concave), in both cases +up on the line v = 0. Curvatures: 0 along the axis, -s/R around.
    """

    kind = "cylinder"

    def __init__(self, radius: float, u_range: Any, v_range: Any, axis: Any = (1.0, 0.0, 0.0),
                 center: Any = (0.0, 0.0, 0.0), concave: bool = False) -> None:
        self.radius = _positive(radius, "radius")
        self.u_range, self.v_range = _range(u_range, "u_range"), _range(v_range, "v_range")
        self.axis, self.center = _vec3(axis, "axis"), _vec3(center, "center")
        self.concave = bool(concave)
        if not np.linalg.norm(self.axis) > 0:
            raise ValueError("'axis' must be non-zero")
        a = self.axis / np.linalg.norm(self.axis)
        up = np.array([0.0, 0.0, 1.0]) - a[2] * a
        if np.linalg.norm(up) < 1e-6:
            raise ValueError("'axis' must not be vertical (the cylinder needs an upper side)")
        up /= np.linalg.norm(up)
        self._a, self._up, self._w = a, up, np.cross(up, a)
        self._s = -1.0 if self.concave else 1.0

    def point(self, u: Any, v: Any) -> np.ndarray:
        u, v = _uv(u, v)
        th = v / self.radius
        radial = self._s * np.cos(th)[..., None] * self._up + np.sin(th)[..., None] * self._w
        return self.center + u[..., None] * self._a + self.radius * radial

    def derivatives(self, u: Any, v: Any) -> SurfaceDerivatives:
        u, v = _uv(u, v)
        th = v / self.radius
        c, s = np.cos(th)[..., None], np.sin(th)[..., None]
        z = np.zeros(u.shape + (3,))
        return SurfaceDerivatives(
            Su=z + self._a,
            Sv=-self._s * s * self._up + c * self._w,
            Suu=z, Suv=z.copy(),
            Svv=-(self._s * c * self._up + s * self._w) / self.radius,
        )

    def parameters(self) -> dict[str, Any]:
        return {"radius": self.radius, "u_range": list(self.u_range), "v_range": list(self.v_range),
                "axis": list(self.axis), "center": list(self.center), "concave": self.concave}


class _MongePatch(ParametricSurface):
    """Height-field patch S = (u, v, center_z + f(u - center_x, v - center_y)); u = x, v = y (mm).

    Su x Sv = (-f_u, -f_v, 1): the normal always points up (+z side is out of the material).
    """

    center: np.ndarray

    @abstractmethod
    def _height(self, x: np.ndarray, y: np.ndarray, order: int) -> tuple[np.ndarray, ...]:
        """f, and for order 2 also f_x, f_y, f_xx, f_xy, f_yy, at local coordinates (x, y)."""

    def point(self, u: Any, v: Any) -> np.ndarray:
        u, v = _uv(u, v)
        (f,) = self._height(u - self.center[0], v - self.center[1], 0)
        return _stack3(u, v, self.center[2] + f, u.shape)

    def derivatives(self, u: Any, v: Any) -> SurfaceDerivatives:
        u, v = _uv(u, v)
        _, fx, fy, fxx, fxy, fyy = self._height(u - self.center[0], v - self.center[1], 2)
        zero, one = np.zeros(u.shape), np.ones(u.shape)
        return SurfaceDerivatives(
            Su=_stack3(one, zero, fx, u.shape), Sv=_stack3(zero, one, fy, u.shape),
            Suu=_stack3(zero, zero, fxx, u.shape), Suv=_stack3(zero, zero, fxy, u.shape),
            Svv=_stack3(zero, zero, fyy, u.shape),
        )


class SpherePatch(_MongePatch):
    """Patch of a sphere of radius R about ``center``, as a height field over u = x, v = y (mm).

    Convex (dome): z = cz + sqrt(R^2 - rho^2), n outward, principal curvatures -1/R.
    Concave (bowl): z = cz - sqrt(R^2 - rho^2), n toward the centre, principal curvatures +1/R.
    The whole parameter rectangle must lie strictly inside the sphere's footprint rho < R.
    """

    kind = "sphere"

    def __init__(self, radius: float, u_range: Any, v_range: Any, center: Any = (0.0, 0.0, 0.0),
                 concave: bool = False) -> None:
        self.radius = _positive(radius, "radius")
        self.u_range, self.v_range = _range(u_range, "u_range"), _range(v_range, "v_range")
        self.center = _vec3(center, "center")
        self.concave = bool(concave)
        dx = max(abs(self.u_range[0] - self.center[0]), abs(self.u_range[1] - self.center[0]))
        dy = max(abs(self.v_range[0] - self.center[1]), abs(self.v_range[1] - self.center[1]))
        if not dx * dx + dy * dy < self.radius**2:
            raise ValueError("'u_range' x 'v_range' must lie inside the sphere's footprint "
                             f"(farthest corner {math.hypot(dx, dy):.6g} mm from the centre, radius "
                             f"{self.radius:.6g} mm)")

    def _height(self, x: np.ndarray, y: np.ndarray, order: int) -> tuple[np.ndarray, ...]:
        sgn = -1.0 if self.concave else 1.0
        r2 = self.radius**2
        w = np.sqrt(r2 - x * x - y * y)
        if order == 0:
            return (sgn * w,)
        w3 = w**3
        return (sgn * w, -sgn * x / w, -sgn * y / w, -sgn * (r2 - y * y) / w3, -sgn * x * y / w3,
                -sgn * (r2 - x * x) / w3)

    def parameters(self) -> dict[str, Any]:
        return {"radius": self.radius, "u_range": list(self.u_range), "v_range": list(self.v_range),
                "center": list(self.center), "concave": self.concave}


class Saddle(_MongePatch):
    """Saddle z = cz + a (x - cx)^2 - b (y - cy)^2 over u = x, v = y (mm); a, b in 1/mm.

    At the centre the principal curvatures are 2a (along x) and -2b (along y): with a, b > 0 it
    is concave along x and convex along y. Gaussian curvature
    K = -4ab / (1 + 4a^2 (x-cx)^2 + 4b^2 (y-cy)^2)^2.
    """

    kind = "saddle"

    def __init__(self, a: float, b: float, u_range: Any, v_range: Any, center: Any = (0.0, 0.0, 0.0)) -> None:
        self.a, self.b = _finite(a, "a"), _finite(b, "b")
        self.u_range, self.v_range = _range(u_range, "u_range"), _range(v_range, "v_range")
        self.center = _vec3(center, "center")

    def _height(self, x: np.ndarray, y: np.ndarray, order: int) -> tuple[np.ndarray, ...]:
        f = self.a * x * x - self.b * y * y
        if order == 0:
            return (f,)
        c = np.ones_like(x)
        return f, 2 * self.a * x, -2 * self.b * y, 2 * self.a * c, 0 * c, -2 * self.b * c

    def gaussian_curvature(self, u: Any, v: Any) -> np.ndarray:
        """Closed-form Gaussian curvature (1/mm^2) of the height field (do Carmo 3-3, ex. 5)."""
        u, v = _uv(u, v)
        x, y = u - self.center[0], v - self.center[1]
        return -4 * self.a * self.b / (1 + 4 * self.a**2 * x * x + 4 * self.b**2 * y * y) ** 2

    def parameters(self) -> dict[str, Any]:
        return {"a": self.a, "b": self.b, "u_range": list(self.u_range), "v_range": list(self.v_range),
                "center": list(self.center)}


class Sinusoid(_MongePatch):
    """Free-form egg-box z = cz + A sin(kx (x - cx)) sin(ky (y - cy)) over u = x, v = y (mm).

    amplitude A in mm, wavenumbers kx, ky in rad/mm. The largest |curvature| is about A max(kx, ky)^2.
    """

    kind = "sinusoid"

    def __init__(self, amplitude: float, kx: float, ky: float, u_range: Any, v_range: Any,
                 center: Any = (0.0, 0.0, 0.0)) -> None:
        self.amplitude = _finite(amplitude, "amplitude")
        self.kx, self.ky = _finite(kx, "kx"), _finite(ky, "ky")
        self.u_range, self.v_range = _range(u_range, "u_range"), _range(v_range, "v_range")
        self.center = _vec3(center, "center")

    def _height(self, x: np.ndarray, y: np.ndarray, order: int) -> tuple[np.ndarray, ...]:
        A, kx, ky = self.amplitude, self.kx, self.ky
        sx, sy = np.sin(kx * x), np.sin(ky * y)
        if order == 0:
            return (A * sx * sy,)
        cx, cy = np.cos(kx * x), np.cos(ky * y)
        return (A * sx * sy, A * kx * cx * sy, A * ky * sx * cy, -A * kx * kx * sx * sy,
                A * kx * ky * cx * cy, -A * ky * ky * sx * sy)

    def parameters(self) -> dict[str, Any]:
        return {"amplitude": self.amplitude, "kx": self.kx, "ky": self.ky, "u_range": list(self.u_range),
                "v_range": list(self.v_range), "center": list(self.center)}


# ---------------------------------------------------------------------------------------------
# B-spline surface


def clamped_knots(n_ctrl: int, degree: int, lo: float, hi: float) -> np.ndarray:
    """Clamped uniform knot vector: degree+1 repeated end knots, uniform interior knots on [lo, hi]."""
    interior = np.linspace(lo, hi, n_ctrl - degree + 1)[1:-1]
    return np.concatenate([np.full(degree + 1, float(lo)), interior, np.full(degree + 1, float(hi))])


class BSplineSurface(ParametricSurface):
    """Tensor-product B-spline surface from a control grid ``control[i][j] = (x, y, z)``.

    Evaluated with ``scipy.interpolate.NdBSpline`` (vector-valued coefficients); derivatives come
    from its ``nu`` argument. Without knots, clamped uniform knots over ``u_range`` / ``v_range``
    (default [0, 1]) are used; with knots the ranges are [t[k], t[-k-1]] of each knot vector.
    The normal is Su x Sv: order the control grid so that it points out of the material (for
    i along +x and j along +y it points up).
    """

    kind = "bspline"

    def __init__(self, control: Any, degree: Any = (3, 3), knots_u: Any = None, knots_v: Any = None,
                 u_range: Any = None, v_range: Any = None) -> None:
        c = _array(control, "control")
        if c.ndim != 3 or c.shape[2] != 3 or not np.all(np.isfinite(c)):
            raise ValueError(f"'control' must be a finite [nu][nv][3] grid, got shape {c.shape}")
        deg = (int(degree), int(degree)) if np.ndim(degree) == 0 else tuple(int(k) for k in degree)
        if len(deg) != 2 or not all(1 <= k <= 5 for k in deg):
            raise ValueError(f"'degree' must be an integer or a pair of integers in 1..5, got {degree!r}")
        for n, k, name in ((c.shape[0], deg[0], "u"), (c.shape[1], deg[1], "v")):
            if n < k + 1:
                raise ValueError(f"'control' needs at least degree+1 = {k + 1} points along {name}, got {n}")
        self.control, self.degree = c, deg
        self._custom_knots = (knots_u is not None, knots_v is not None)
        knots = []
        ranges = []
        for t, rng, n, k, name in ((knots_u, u_range, c.shape[0], deg[0], "u"),
                                   (knots_v, v_range, c.shape[1], deg[1], "v")):
            if t is None:
                lo, hi = _range((0.0, 1.0) if rng is None else rng, f"{name}_range")
                t = clamped_knots(n, k, lo, hi)
            else:
                t = _array(t, f"knots_{name}")
                if t.ndim != 1 or t.size != n + k + 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
                    raise ValueError(f"'knots_{name}' must be {n + k + 1} finite non-decreasing numbers "
                                     f"(control points + degree + 1)")
                if not t[k] < t[-k - 1]:
                    raise ValueError(f"'knots_{name}' has an empty domain")
                if rng is not None and _range(rng, f"{name}_range") != (t[k], t[-k - 1]):
                    raise ValueError(f"'{name}_range' {list(rng)} disagrees with 'knots_{name}' domain "
                                     f"[{t[k]!r}, {t[-k - 1]!r}]")
            knots.append(t)
            ranges.append((float(t[k]), float(t[-k - 1])))
        self.knots_u, self.knots_v = knots
        self.u_range, self.v_range = ranges
        self._spline = NdBSpline((self.knots_u, self.knots_v), c, deg, extrapolate=True)

    def _eval(self, u: Any, v: Any, nu: tuple[int, int]) -> np.ndarray:
        u, v = _uv(u, v)
        if nu[0] > self.degree[0] or nu[1] > self.degree[1]:
            return np.zeros(u.shape + (3,))
        xi = np.stack([u.ravel(), v.ravel()], axis=-1)
        return self._spline(xi, nu=nu).reshape(u.shape + (3,))

    def point(self, u: Any, v: Any) -> np.ndarray:
        return self._eval(u, v, (0, 0))

    def derivatives(self, u: Any, v: Any) -> SurfaceDerivatives:
        return SurfaceDerivatives(Su=self._eval(u, v, (1, 0)), Sv=self._eval(u, v, (0, 1)),
                                  Suu=self._eval(u, v, (2, 0)), Suv=self._eval(u, v, (1, 1)),
                                  Svv=self._eval(u, v, (0, 2)))

    def parameters(self) -> dict[str, Any]:
        p: dict[str, Any] = {"u_range": list(self.u_range), "v_range": list(self.v_range),
                             "degree": list(self.degree)}
        if self._custom_knots[0]:
            p["knots_u"] = list(self.knots_u)
        if self._custom_knots[1]:
            p["knots_v"] = list(self.knots_v)
        p["control"] = self.control.tolist()
        return p


SURFACE_KINDS: dict[str, type[ParametricSurface]] = {
    cls.kind: cls for cls in (Plane, Cylinder, SpherePatch, Saddle, Sinusoid, BSplineSurface)
}

# accepted keys per kind: (required, optional)
_KEYS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "plane": (("u_range", "v_range"), ("origin", "u_dir", "v_dir")),
    "cylinder": (("radius", "u_range", "v_range"), ("axis", "center", "concave")),
    "sphere": (("radius", "u_range", "v_range"), ("center", "concave")),
    "saddle": (("a", "b", "u_range", "v_range"), ("center",)),
    "sinusoid": (("amplitude", "kx", "ky", "u_range", "v_range"), ("center",)),
    "bspline": (("control",), ("degree", "knots_u", "knots_v", "u_range", "v_range")),
}
_BOOL_KEYS = {"concave"}
_INT_KEYS = {"degree"}


# ---------------------------------------------------------------------------------------------
# tessellation


def _grid_faces(nu: int, nv: int) -> np.ndarray:
    """Two triangles per grid cell, wound so that face normals follow Su x Sv.

    Vertex (i, j) has index i*nv + j. Triangles (i,j),(i+1,j),(i+1,j+1) and (i,j),(i+1,j+1),(i,j+1):
    their edge cross products are du dv Su x Sv to first order.
    """
    i, j = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1), indexing="ij")
    a = (i * nv + j).ravel()
    b, c, d = a + nv, a + nv + 1, a + 1
    return np.stack([np.stack([a, b, c], -1), np.stack([a, c, d], -1)], 1).reshape(-1, 3)


def _grid_mesh(surface: ParametricSurface, us: np.ndarray, vs: np.ndarray) -> trimesh.Trimesh:
    U, V = np.meshgrid(us, vs, indexing="ij")
    verts = surface.point(U, V).reshape(-1, 3)
    normals = surface.normal(U, V).reshape(-1, 3)
    if not np.all(np.isfinite(verts)) or not np.all(np.isfinite(normals)):
        raise ValueError("surface has non-finite points or a singular normal on the tessellation grid")
    mesh = trimesh.Trimesh(vertices=verts, faces=_grid_faces(len(us), len(vs)), vertex_normals=normals,
                           process=False)
    mesh.metadata["grid"] = (len(us), len(vs))
    return mesh


def tessellate(surface: ParametricSurface, nu: int, nv: int) -> trimesh.Trimesh:
    """Triangulate ``surface`` on a uniform nu x nv parameter grid (vertex (i, j) = index i*nv + j).

    Face winding makes trimesh's face normals agree with ``surface.normal`` (out of the material).
    Vertex normals are the exact surface normals.
    """
    nu, nv = int(nu), int(nv)
    if nu < 2 or nv < 2:
        raise ValueError("tessellate needs nu >= 2 and nv >= 2")
    return _grid_mesh(surface, np.linspace(*surface.u_range, nu), np.linspace(*surface.v_range, nv))


def _triangle_max_error(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Largest |deviation| over a triangle from its three signed edge-midpoint deviations.

    For a locally quadratic surface the normal deviation of the flat triangle at barycentric
    lambda is e(lambda) = 4 (a l1 l2 + b l1 l3 + c l2 l3) with a = e12, b = e13, c = e23 the
    deviations at the edge midpoints (interpolation error of a quadratic on a simplex). Its
    extremes lie at the edge midpoints or at the interior stationary point lambda ~ adj(B) 1,
    B = [[0,a,b],[a,0,c],[b,c,0]], where e = 4abc / (2(ab+bc+ca) - a^2 - b^2 - c^2).
    """
    err = np.maximum(np.maximum(np.abs(a), np.abs(b)), np.abs(c))
    y = np.stack([c * (a + b - c), b * (a + c - b), a * (b + c - a)], -1)
    s = y.sum(-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = y / s[..., None]
        interior = np.all(lam >= 0, axis=-1) & (s != 0)
        e_int = np.where(interior, np.abs(4 * a * b * c / s), 0.0)
    return np.maximum(err, np.nan_to_num(e_int))


def grid_chord_error(surface: ParametricSurface, us: np.ndarray, vs: np.ndarray) -> float:
    """Estimated max chord error (mm) of the grid tessellation on parameter lines ``us`` x ``vs``.

    The surface is evaluated at every edge midpoint (u-edges, v-edges and cell diagonals) and the
    normal deviation from the chord midpoint is combined per triangle by ``_triangle_max_error``
    (exact for quadratic patches, second-order accurate otherwise).
    """
    U, V = np.meshgrid(us, vs, indexing="ij")
    P = surface.point(U, V)
    um, vm = 0.5 * (us[:-1] + us[1:]), 0.5 * (vs[:-1] + vs[1:])

    def dev(uu: np.ndarray, vv: np.ndarray, A: np.ndarray, B: np.ndarray) -> np.ndarray:
        uu, vv = np.broadcast_arrays(uu, vv)
        return _dot(surface.point(uu, vv) - 0.5 * (A + B), surface.normal(uu, vv))

    eu = dev(um[:, None], vs[None, :], P[:-1, :], P[1:, :])  # (nu-1, nv)
    ev = dev(us[:, None], vm[None, :], P[:, :-1], P[:, 1:])  # (nu, nv-1)
    ed = dev(um[:, None], vm[None, :], P[:-1, :-1], P[1:, 1:])  # (nu-1, nv-1)
    # triangle (i,j),(i+1,j),(i+1,j+1): e12 = u-edge at j, e13 = diagonal, e23 = v-edge at i+1
    t1 = _triangle_max_error(eu[:, :-1], ed, ev[1:, :])
    # triangle (i,j),(i+1,j+1),(i,j+1): e12 = diagonal, e13 = v-edge at i, e23 = u-edge at j+1
    t2 = _triangle_max_error(ed, ev[:-1, :], eu[:, 1:])
    return float(max(t1.max(initial=0.0), t2.max(initial=0.0)))


def tessellate_to_tolerance(surface: ParametricSurface, chord_tol: float = 2e-4,
                            max_points: int = 250_000, n_sample: int = 65) -> trimesh.Trimesh:
    """Uniform-grid tessellation whose chord error is <= ``chord_tol`` (mm) where possible.

    The grid spacing (du, dv) is first chosen from the second fundamental form sampled on an
    ``n_sample`` x ``n_sample`` grid: the deviation of a cell's edges and diagonal is bounded by
    (|L| du^2 + 2|M| du dv + |N| dv^2) / 8, and the aspect du/dv minimising the vertex count under
    that bound is taken. The chord error of that grid is then measured (``grid_chord_error``) and
    both counts are rescaled (error ~ spacing^2) until it lies in [0.85, 1] x ``chord_tol``; the
    coarsest grid measured within the tolerance is returned.

    When the cap binds (the grid needed exceeds ``max_points`` vertices) the finest grid of that
    aspect within the cap is returned, a ``RuntimeWarning`` names the achieved error, and
    ``mesh.metadata['chord_error']`` holds it. ``mesh.metadata`` always holds 'chord_error' (mm),
    'chord_tol' (mm) and 'grid' (nu, nv).
    """
    if not chord_tol > 0:
        raise ValueError("chord_tol must be positive")
    if max_points < 4:
        raise ValueError("max_points must be at least 4")
    (u0, u1), (v0, v1) = surface.u_range, surface.v_range
    U, V = surface.grid(n_sample, n_sample)
    ff = surface.fundamental_forms(U, V)
    L, M, N = (np.abs(x).ravel() for x in (ff.L, ff.M, ff.N))
    span_u, span_v = u1 - u0, v1 - v0

    def counts(du: float, dv: float) -> tuple[int, int]:
        return (max(2, math.ceil(span_u / du - 1e-9) + 1) if du > 0 else 2,
                max(2, math.ceil(span_v / dv - 1e-9) + 1) if dv > 0 else 2)

    best = (2, 2)
    if np.max(L + M + N) > 0:
        best_cost = math.inf
        for aspect in np.geomspace(1e-3, 1e3, 241) * (span_u / span_v):
            m = float(np.max(L * aspect * aspect + 2 * M * aspect + N))
            dv = math.sqrt(8 * chord_tol / m)
            nu, nv = counts(aspect * dv, dv)
            if nu * nv < best_cost:
                best_cost, best = nu * nv, (nu, nv)
    nu, nv = best
    tried: dict[tuple[int, int], float] = {}
    feasible: tuple[int, int] | None = None
    for _ in range(16):
        if nu * nv > max_points:
            f = math.sqrt(max_points / (nu * nv))
            nu, nv = max(2, int((nu - 1) * f) + 1), max(2, int((nv - 1) * f) + 1)
            while nu * nv > max_points:
                nu, nv = max(2, nu - 1), max(2, nv - 1)
        if (nu, nv) in tried:
            break
        err = tried[nu, nv] = grid_chord_error(surface, np.linspace(u0, u1, nu), np.linspace(v0, v1, nv))
        if err <= chord_tol and (feasible is None or nu * nv < feasible[0] * feasible[1]):
            feasible = (nu, nv)
        if 0.85 * chord_tol <= err <= chord_tol:
            break
        # the error scales with the square of the spacing: aim just under the tolerance
        f = math.sqrt(err / chord_tol) * 1.02 if err > chord_tol else math.sqrt(err / (0.95 * chord_tol))
        nu, nv = max(2, math.ceil((nu - 1) * f - 1e-9) + 1), max(2, math.ceil((nv - 1) * f - 1e-9) + 1)
    if feasible is None:
        nu, nv = max(tried, key=lambda k: k[0] * k[1])
        err = tried[nu, nv]
        warnings.warn(f"tessellation capped at {nu} x {nv} = {nu * nv} points (max_points={max_points}): "
                      f"chord error {err:.3g} mm exceeds the tolerance {chord_tol:.3g} mm",
                      RuntimeWarning, stacklevel=2)
    else:
        nu, nv = feasible
        err = tried[nu, nv]
    us, vs = np.linspace(u0, u1, nu), np.linspace(v0, v1, nv)
    mesh = _grid_mesh(surface, us, vs)
    mesh.metadata.update(chord_error=err, chord_tol=chord_tol)
    return mesh


# ---------------------------------------------------------------------------------------------
# definition files (TOML)


def _toml_string(s: str) -> str:
    # JSON basic strings are TOML basic strings except that TOML also wants DEL escaped.
    return json.dumps(s, ensure_ascii=False).replace("\x7f", "\\u007F")


def _toml_value(x: Any) -> str:
    if isinstance(x, bool | np.bool_):
        return "true" if x else "false"
    if isinstance(x, int | np.integer):
        return str(int(x))
    if isinstance(x, float | np.floating):
        x = float(x)
        if not math.isfinite(x):
            raise ValueError(f"cannot write non-finite number {x!r}")
        return repr(x)  # shortest repr round-trips exactly and is valid TOML
    if isinstance(x, str):
        return _toml_string(x)
    if isinstance(x, list | tuple | np.ndarray):
        return "[" + ", ".join(_toml_value(e) for e in x) + "]"
    raise TypeError(f"cannot write {type(x).__name__} to TOML")


def definition_text(surface: ParametricSurface) -> str:
    """The TOML text of ``surface``'s definition (what ``save_definition`` writes)."""
    lines = ["# camsmooth surface definition; lengths in mm (see surfaces/README.md)", "[surface]",
             f"kind = {_toml_string(surface.kind)}"]
    for key, value in surface.parameters().items():
        if key == "control":
            rows = ",\n".join("  " + _toml_value(row) for row in value)
            lines.append(f"control = [\n{rows},\n]")
        else:
            lines.append(f"{key} = {_toml_value(value)}")
    return "\n".join(lines) + "\n"


def save_definition(surface: ParametricSurface, path: str | Path) -> None:
    """Write ``surface`` as a TOML definition file, atomically. ``load_definition`` reads it back
    to an identical surface (floats are written with their shortest round-tripping repr)."""
    write_text_atomic(path, definition_text(surface))


def _check_value(key: str, value: Any, file: str) -> Any:
    """Type-check one definition value (numbers, vectors, nested grids, booleans)."""

    def bad(msg: str) -> InputError:
        return InputError(f"[surface] key '{key}': {msg}", file=file)

    if key in _BOOL_KEYS:
        if not isinstance(value, bool):
            raise bad(f"must be true or false, got {value!r}")
        return value
    if key in _INT_KEYS:
        ok = (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, list) and all(isinstance(e, int) and not isinstance(e, bool) for e in value))
        if not ok:
            raise bad(f"must be an integer or a list of integers, got {value!r}")
        return value

    def numbers(x: Any) -> bool:
        if isinstance(x, list):
            return all(numbers(e) for e in x)
        return isinstance(x, int | float) and not isinstance(x, bool)

    if not numbers(value):
        raise bad(f"must be a number or a (nested) list of numbers, got {str(value)[:80]}")
    if not np.all(np.isfinite(np.array(_flatten(value), dtype=float))):
        raise bad("contains a non-finite number")
    return value


def _flatten(x: Any) -> list[Any]:
    if isinstance(x, list):
        return [e for item in x for e in _flatten(item)]
    return [x]


def surface_from_definition(table: dict[str, Any], file: str = "<definition>") -> ParametricSurface:
    """Build a surface from the ``[surface]`` table of a definition (dict as parsed by tomllib)."""
    if "kind" not in table:
        raise InputError("[surface] key 'kind' is missing (one of " + ", ".join(SURFACE_KINDS) + ")",
                         file=file)
    kind = table["kind"]
    if kind not in SURFACE_KINDS:
        close = difflib.get_close_matches(str(kind), list(SURFACE_KINDS), n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        raise InputError(f"[surface] key 'kind': unknown kind {kind!r}{hint}; expected one of "
                         + ", ".join(SURFACE_KINDS), file=file)
    required, optional = _KEYS[kind]
    allowed = ("kind",) + required + optional
    for key in table:
        if key not in allowed:
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise InputError(f"[surface] key '{key}': not a parameter of kind '{kind}'{hint}", file=file)
    for key in required:
        if key not in table:
            raise InputError(f"[surface] key '{key}' is missing (required for kind '{kind}')", file=file)
    kwargs = {key: _check_value(key, table[key], file) for key in required + optional if key in table}
    try:
        return SURFACE_KINDS[kind](**kwargs)
    except ValueError as exc:
        raise InputError(f"[surface]: {exc}", file=file) from exc


def load_definition(path: str | Path) -> ParametricSurface:
    """Read a TOML surface definition (``[surface] kind = ...``, lengths in mm).

    Raises InputError naming the file and the offending key for unreadable files, TOML syntax
    errors, a missing ``[surface]`` table, unknown kinds or keys, missing keys and bad values.
    """
    file = str(path)
    try:
        data = tomllib.loads(Path(path).read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read surface definition: {exc.strerror or exc}", file=file) from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid TOML: {exc}", file=file) from exc
    extra = [k for k in data if k != "surface"]
    if extra:
        raise InputError(f"key '{extra[0]}': unexpected top-level key (only the [surface] table is read)",
                         file=file)
    if not isinstance(data.get("surface"), dict):
        raise InputError("missing the [surface] table", file=file)
    return surface_from_definition(data["surface"], file)


# ---------------------------------------------------------------------------------------------
# meshes


@dataclass
class Surface:
    """A workpiece surface: triangle mesh (mm, face normals out of the material), optional exact
    parametric form, the file it came from, and notes about repairs made while loading. brep: the
    exact CAD part behind the mesh (camsmooth.geometry.step.BRepPart) when read from STEP/IGES."""

    mesh: trimesh.Trimesh
    parametric: ParametricSurface | None
    source: str
    notes: list[str] = field(default_factory=list)
    brep: Any = None


def check_mesh_orientation(mesh: trimesh.Trimesh, file: str | None = None) -> str | None:
    """Make the face winding consistent, in place, when that is safe; else raise InputError.

    Returns None if the winding was already consistent, else a note saying what was repaired.
    Edges shared by more than two faces (non-manifold) are always an error. Safe means: either the
    mesh is watertight (``trimesh.repair.fix_normals`` then orients it outward by the sign of its
    volume) or, for an open surface, each connected piece has a clear majority orientation (at
    least 60 % of its area agrees), which is kept: the minority faces are flipped. The overall side
    (which way is out of the material) of a consistently wound mesh is never changed.
    """
    if len(mesh.faces) == 0:
        return None
    counts = np.unique(mesh.edges_sorted, axis=0, return_counts=True)[1]
    if np.any(counts > 2):
        # trimesh's winding test ignores such edges: the orientation cannot be checked
        raise InputError(f"{int(np.sum(counts > 2))} edges are shared by more than two faces (non-manifold): "
                         "not a surface whose orientation can be checked", file=file)
    if mesh.is_winding_consistent:
        return None
    before = mesh.face_normals.copy()
    area = mesh.area_faces.copy()
    if mesh.is_watertight:
        trimesh.repair.fix_normals(mesh)
    else:
        trimesh.repair.fix_winding(mesh)
        agree = np.sign(_dot(mesh.face_normals, before))
        labels = trimesh.graph.connected_component_labels(mesh.face_adjacency, node_count=len(mesh.faces))
        for lab in np.unique(labels):
            sel = labels == lab
            score = float(np.sum(agree[sel] * area[sel]) / max(np.sum(area[sel]), 1e-300))
            if abs(score) < 0.2:
                raise InputError("face normals are not consistently oriented and there is no clear majority "
                                 f"orientation to keep ({(1 + abs(score)) / 2:.0%} of a piece's area): "
                                 "cannot orient safely", file=file)
            if score < 0:
                _flip_faces(mesh, sel)
    if not mesh.is_winding_consistent:
        raise InputError("face normals are not consistently oriented and could not be repaired", file=file)
    flipped = int(np.sum(_dot(mesh.face_normals, before) < 0))
    return f"{file or 'mesh'}: face winding was inconsistent; {flipped} of {len(mesh.faces)} faces flipped"


def _flip_faces(mesh: trimesh.Trimesh, sel: np.ndarray) -> None:
    faces = mesh.faces.copy()
    faces[sel] = faces[sel][:, ::-1]
    mesh.faces = faces


def load_mesh(path: str | Path) -> tuple[trimesh.Trimesh, list[str]]:
    """Load a triangle-mesh surface (.stl, .obj, .ply) and check that it is one.

    Raises InputError naming the file and the reason for: unreadable files, empty meshes, no
    faces (a point cloud), non-finite vertices, zero-area faces making up more than half of the
    faces, scenes that do not merge into one triangle mesh, and inconsistent face orientation
    that cannot be repaired safely (``check_mesh_orientation``). A minority of zero-area faces
    is removed. Returns (mesh, notes), the notes saying what was repaired.
    """
    file = str(path)
    try:
        loaded = trimesh.load(file, process=False)
    except Exception as exc:  # trimesh raises many types for bad files
        raise InputError(f"cannot read mesh: {exc}", file=file) from exc
    if isinstance(loaded, trimesh.Scene):
        geoms = loaded.geometry.values()
        kinds = sorted({type(g).__name__ for g in geoms if not isinstance(g, trimesh.Trimesh)})
        if kinds:
            raise InputError(f"the file is a scene holding non-mesh geometry ({', '.join(kinds)}) that "
                             "cannot be merged into one surface mesh", file=file)
        if not loaded.geometry:
            raise InputError("mesh is empty (a scene with no geometry)", file=file)
        try:
            loaded = loaded.to_mesh()
        except Exception as exc:  # merging can fail in many ways
            raise InputError(f"the scene could not be merged into one mesh: {exc}", file=file) from exc
    if isinstance(loaded, trimesh.PointCloud):
        raise InputError(f"a point cloud ({len(loaded.vertices)} points) with no faces: not a surface",
                         file=file)
    if not isinstance(loaded, trimesh.Trimesh):
        raise InputError(f"not a triangle mesh ({type(loaded).__name__})", file=file)
    mesh = loaded
    if len(mesh.vertices) == 0:
        raise InputError("mesh is empty (no vertices)", file=file)
    if len(mesh.faces) == 0:
        raise InputError(f"mesh has {len(mesh.vertices)} vertices and no faces: a point cloud, not a surface",
                         file=file)
    finite = np.all(np.isfinite(mesh.vertices), axis=1)
    if not np.all(finite):
        k = int(np.flatnonzero(~finite)[0])
        raise InputError(f"{int(np.sum(~finite))} vertices have non-finite coordinates (first: vertex {k})",
                         file=file)
    notes: list[str] = []
    diag = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    degenerate = mesh.area_faces <= 1e-12 * max(diag, 1e-300) ** 2
    if np.sum(degenerate) * 2 > len(mesh.faces):
        raise InputError(f"{int(np.sum(degenerate))} of {len(mesh.faces)} faces have zero area: "
                         "not a surface", file=file)
    if np.any(degenerate):
        mesh.update_faces(~degenerate)
        notes.append(f"{file}: removed {int(np.sum(degenerate))} zero-area faces")
    mesh.merge_vertices()
    mesh.remove_unreferenced_vertices()
    note = check_mesh_orientation(mesh, file)
    if note:
        warnings.warn(note, RuntimeWarning, stacklevel=2)
        notes.append(note)
    return mesh, notes


def save_mesh(mesh: trimesh.Trimesh, path: str | Path) -> None:
    """Export ``mesh`` atomically; the format follows the suffix (.ply is written binary)."""
    path = Path(path)
    with atomic_path(path) as tmp:
        mesh.export(str(tmp), file_type=path.suffix.lower().lstrip("."))


def load_surface(path: str | Path, chord_tol: float = 2e-4, max_points: int = 250_000) -> Surface:
    """Load a workpiece surface from a TOML definition, a mesh file (.stl, .obj, .ply) or a CAD part
    (.step/.stp, .iges/.igs).

    A definition is tessellated with ``tessellate_to_tolerance(chord_tol, max_points)`` and kept
    as ``Surface.parametric``; a mesh file is checked by ``load_mesh`` (parametric is None); a CAD
    part is meshed by OpenCASCADE to the linear deflection ``chord_tol`` mm and measured against
    its exact faces (camsmooth.geometry.step.load_cad; the exact part is ``Surface.brep``).
    """
    p = Path(path)
    if not p.is_file():
        raise InputError("no such file", file=str(path))
    suffix = p.suffix.lower()
    from camsmooth.geometry.step import CAD_SUFFIXES, load_cad

    if suffix in CAD_SUFFIXES:
        return load_cad(p, deflection=chord_tol)
    if suffix == ".toml":
        param = load_definition(p)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                mesh = tessellate_to_tolerance(param, chord_tol=chord_tol, max_points=max_points)
            except ValueError as exc:  # a definition whose surface degenerates (a singular normal)
                raise InputError(f"[surface]: the definition gives no proper surface to tessellate ({exc}): check "
                                 "its parameters (coinciding control points, a range past the surface's end)",
                                 file=str(path)) from None
        notes = [f"{path}: {w.message}" for w in caught]
        for note in notes:
            warnings.warn(note, RuntimeWarning, stacklevel=2)
        return Surface(mesh=mesh, parametric=param, source=str(path), notes=notes)
    if suffix in MESH_SUFFIXES:
        mesh, notes = load_mesh(p)
        return Surface(mesh=mesh, parametric=None, source=str(path), notes=notes)
    raise InputError(f"unknown surface file type '{p.suffix}' (expected .toml, .stl, .obj, .ply, .step/.stp or "
                     ".iges/.igs)",
                     file=str(path))


def surface_normals_at(mesh: trimesh.Trimesh, points: Any) -> np.ndarray:
    """Unit face normal of ``mesh`` at the closest point to each of ``points`` (N, 3) -> (N, 3).

    Used to detect CC-path normals that point into the material (n . mesh normal < 0). At an edge
    or vertex the normal of one of the adjacent faces is returned.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 3)
    _, _, tri = trimesh.proximity.closest_point(mesh, pts)
    return np.asarray(mesh.face_normals)[tri]


SHARP_EDGE = math.radians(30.0)  # dihedral angles above this are features of the part, not chords


def chord_deviation(surface: Surface) -> float:
    """Estimated largest deviation (mm) between the mesh and the smooth surface it stands for.

    With a CAD part, the deviation measured against its exact faces (camsmooth.geometry.step).
    With a definition, the tessellation's measured chord error (``grid_chord_error``). From a mesh
    alone: where two faces meet at the dihedral angle theta, a smooth surface through both bends
    by theta over about the distance w between the faces' centroids, so its curvature is
    theta / w, and a chord of length c sags by c^2 theta / (8 w). Chords across a face are
    between w and about 2 w long (equilateral to right-angled faces); c^2 = 2 w^2 gives
    w theta / 4, whose 99.9th percentile over the edges is the estimate (edges sharper than
    SHARP_EDGE are the part's own edges and are left out). Measured against the exact chord error
    of grid tessellations (1.4x over) and icospheres (2x under): within a factor of 2. Exact meshes of planes give 0.
    """
    mesh = surface.mesh
    if getattr(surface, "brep", None) is not None:  # a CAD part: measured against its exact faces
        return float(surface.brep.deviation)
    if surface.parametric is not None and "chord_error" in mesh.metadata:
        return float(mesh.metadata["chord_error"])
    pairs = np.asarray(mesh.face_adjacency)
    if len(pairs) == 0:
        return 0.0
    theta = np.asarray(mesh.face_adjacency_angles)
    c = np.asarray(mesh.triangles_center)
    w = np.linalg.norm(c[pairs[:, 0]] - c[pairs[:, 1]], axis=1)
    smooth = theta < SHARP_EDGE
    return float(np.percentile(w[smooth] * theta[smooth] / 4.0, 99.9)) if smooth.any() else 0.0
