"""The finish a tool program leaves: the scallop between adjacent passes, per point.

Across the feed (the plane spanned by Y_L and the normal n of the local frame, METHODS section
1) the tool swept along the path is replaced by the osculating circle of its envelope at the
contact, and the surface by its normal section across the feed, curvature ``k`` = K_surface[1, 1]
(camsmooth.geometry.curvature; positive where the surface bends toward the tool, i.e. concave
as seen from it). The envelope (``swept_curvature``): near the contact the tool lies above the
surface by z = (D_xx a^2 + 2 D_xy a b + D_yy b^2) / 2 with D = K_cutter - K_surface (a along the
feed, b across it; K_cutter from camsmooth.smoothing.orientation.cutter_curvature_tensors, the
lead and tilt's Euler formula); sweeping along a leaves the minimum over a, (D_yy - D_xy^2 / D_xx)
b^2 / 2 = det(D) / D_xx b^2 / 2, so the envelope's curvature across the feed is
kappa = k + det(D) / D_xx. On a plane at zero tilt that is the cutter's own R / sin(lead) + r
(K_cutter[1, 1]); with tilt the cutter's effective radius is
(R / sin(lead) + r) cos^2(tilt) + r sin^2(tilt), not 1 / K_cutter[1, 1] (the normal section is not
the swept profile when D_xy != 0). ``effective_radius`` (the report's) is this one formula on a
plane. The stepover ``c`` (mm) is the chord between the contact points of two adjacent passes,
measured on the path: the distance of each CC point from the polyline of the previous and of the
next row (``neighbour_stepover``).

Scallop on a curved surface (``scallop_height``). Put the cusp's foot at the origin with the
normal along +z (toward the tool). The surface circle has its centre at (0, 1/k); the two contact
points sit at the half-chord c/2 on either side, at the angle beta from the foot seen from the
surface centre, sin(beta) = c k / 2. The tool circles (radius rho = 1 / kappa) touch the surface
there, their centres on the normals at a distance rho: C = O + (1/k - rho)(sin beta, -cos beta).
The material left is under the lower arcs of both circles, which meet on the symmetry axis at
the cusp; its height above the surface along the normal is

    h = (1 - cos beta) / k + rho cos beta - sqrt(rho^2 - (1 - rho k)^2 c^2 / 4),

which, rationalised so that it holds for k = 0 and for a flat cutter section (kappa = 0), is

    h = (c^2 / 4) [ k / (1 + cb) + (kappa - 2 k) / (cb + sqrt(1 - (kappa - k)^2 c^2 / 4)) ],
    cb = cos beta = sqrt(1 - (c k / 2)^2).

At k = 0 it is the flat-plane h = rho - sqrt(rho^2 - (c/2)^2) (docs/METHODS.md section 1.3;
Machinery's Handbook, ball-nose cusp height); for small c it is h ~ c^2 (kappa - k) / 8, the
relative curvature of tool and surface across the feed. Source: derived here (the construction
above: two circles tangent to a circle), the construction of the convex/concave ball-end cusp
formulas of the tool-path planning literature (e.g. R.-S. Lin and Y. Koren, "Efficient tool-path
planning for machining free-form surfaces", ASME J. Eng. Ind. 118(1), 1996) with the effective
radius in place of the ball's and the chord measured on the path in place of the arc; the paper's
own equations were not at hand to compare term by term. It is exact for circles; the tool's
section is its osculating circle, so the error is of the next order in c (tests/test_scallop.py
compares it with the sampled lower envelope of two swept tool solids on a plane and on convex and
concave cylinders). Inverting it for the cutter's
curvature that leaves a given h is linear (``curvature_for_scallop``):

    kappa_max = (k c^2 / 2 + 2 cb g) / (g^2 + c^2 / 4),   g = h - c^2 k / (4 (1 + cb)).

A larger kappa (smaller effective radius) never lowers the scallop, so h <= h_max at a point iff
kappa(lead, tilt) <= kappa_max there, i.e. det(D - d e_y e_y^T) <= 0 with d = kappa_max - k. With
K_cutter = k_m m m^T + k_x p p^T (meridian direction m = (cos tilt, sin tilt), k_m = 1 / r, p
perpendicular to m, k_x = sin(lead) / (R + r sin(lead)) growing with the lead) the matrix
determinant lemma gives det(C + k_x p p^T) = det(C) + k_x m^T C m, C = k_m m m^T - K_surface -
d e_y e_y^T (as camsmooth.smoothing.orientation.min_gouge_free_lead), so k_x <= -det(C) / m^T C m:
an upper bound on the lead as a function of the tilt (``lead_ceiling``), which the NLP takes like
the accessibility map's clearance ceiling (camsmooth.smoothing.rows). Where two passes of different radii meet, each
point's own h (its radius on both sides) bounds the cusp: bounding every point bounds every cusp.

Units: mm, 1/mm, rad. NaN where a point has no neighbouring pass (the first and last row, a
neighbour further than a cutter's width away); inf where the two sections do not overlap.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["ScallopBudget", "curvature_for_scallop", "effective_radius", "lead_ceiling", "merge_ceilings",
           "neighbour_stepover", "point_scallop", "scallop_height", "swept_curvature"]

CAP_TILTS = 15  # tilts sampled over the tilt window when a lead ceiling is fitted
CAP_MARGIN = np.radians(0.02)  # rad: the fitted ceiling is kept this far below the exact one
SHORT_ROOM = 0.1  # where no lead meets the budget, the lead stays in this lowest fraction of its window


def _k_cross(R: float, r: float, lead: np.ndarray) -> np.ndarray:
    """The torus' curvature (1/mm) perpendicular to its meridian at a contact whose normal makes
    the angle lead (rad) with the axis: sin(lead) / (R + r sin(lead)); 1 / r for a ball end."""
    sl = np.sin(lead)
    return sl / (R + r * sl) if R > 0 else np.full_like(sl, 1.0 / r)


def swept_curvature(cutter: Any, lead: np.ndarray, tilt: np.ndarray, K_surface: np.ndarray | None = None
                    ) -> np.ndarray:
    """Curvature across the feed (1/mm) of the envelope of the cutter swept along the feed at
    lead and tilt (rad), over a surface with curvature tensors K_surface (..., 2, 2) 1/mm in the
    basis (X_L, Y_L) (None: a plane): kappa = k + det(D) / D_xx, D = K_cutter - K_surface (module
    docstring). inf for a flat end's rim turned across the feed (tilt of 90 deg), NaN where
    D_xx <= 0 (the cutter gouges along the feed)."""
    R, r = float(cutter.R), float(cutter.r)
    lead, tilt = np.broadcast_arrays(np.asarray(lead, float), np.asarray(tilt, float))
    Ks = np.zeros(lead.shape + (2, 2)) if K_surface is None else np.asarray(K_surface, float)
    kx = _k_cross(R, r, lead)
    c, s_ = np.cos(tilt), np.sin(tilt)
    # G = k_x p p^T - K_surface, p = (-sin, cos)
    g11 = kx * s_ * s_ - Ks[..., 0, 0]
    g12 = -kx * s_ * c - Ks[..., 0, 1]
    g22 = kx * c * c - Ks[..., 1, 1]
    pgp = g11 * s_ * s_ - 2 * g12 * s_ * c + g22 * c * c  # p^T G p
    with np.errstate(divide="ignore", invalid="ignore"):
        if r > 0:  # D = G + k_m m m^T: det(D) = det(G) + k_m p^T G p, D_xx = G_xx + k_m cos^2
            km = 1.0 / r
            dxx = g11 + km * c * c
            rel = np.where(dxx > 0, (g11 * g22 - g12 * g12 + km * pgp) / dxx, np.nan)
        else:  # k_m -> inf: det(D) / D_xx -> p^T G p / cos^2(tilt)
            rel = np.where(c * c > 0, pgp / (c * c), np.inf)
    return Ks[..., 1, 1] + rel


def effective_radius(cutter: Any, lead: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """The cutter's effective cutting radius across the feed (mm) at lead and tilt (rad): 1 over
    ``swept_curvature`` on a plane, (R / sin(lead) + r) cos^2(tilt) + r sin^2(tilt); inf for a
    flat end at zero lead and tilt."""
    with np.errstate(divide="ignore"):
        return 1.0 / swept_curvature(cutter, lead, tilt)


def scallop_height(kappa: np.ndarray, k_surface: np.ndarray, stepover: np.ndarray) -> np.ndarray:
    """Scallop height (mm, along the normal) between two passes a chord ``stepover`` (mm) apart
    of a cutter section of curvature ``kappa`` (1/mm) on a surface of normal curvature
    ``k_surface`` (1/mm, positive concave) across the feed (module docstring). inf where the
    sections do not overlap (or kappa is infinite), NaN where the stepover is NaN; clipped at 0
    where the cutter is flatter than the surface (it gouges there, the windows' concern)."""
    kappa, k, c = np.broadcast_arrays(np.asarray(kappa, float), np.asarray(k_surface, float),
                                      np.asarray(stepover, float))
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        q = 0.25 * c * c
        cb = np.sqrt(1.0 - q * k * k)
        rel = kappa - k
        root = np.sqrt(1.0 - q * rel * rel)
        h = q * (k / (1.0 + cb) + (kappa - 2.0 * k) / (cb + root))
        bad = ~(np.isfinite(root) & np.isfinite(cb)) | ~np.isfinite(kappa)
        h = np.where(bad, np.inf, np.maximum(h, 0.0))
    return np.where(np.isnan(c) | np.isnan(k), np.nan, h)


def curvature_for_scallop(h: np.ndarray, k_surface: np.ndarray, stepover: np.ndarray) -> np.ndarray:
    """The largest cutter curvature across the feed (1/mm) that leaves at most the scallop ``h``
    (mm) at the stepover (mm) on a surface of curvature ``k_surface`` (1/mm): the inverse of
    ``scallop_height`` (module docstring). inf where the stepover is 0, NaN where it is NaN."""
    h, k, c = np.broadcast_arrays(np.asarray(h, float), np.asarray(k_surface, float), np.asarray(stepover, float))
    with np.errstate(invalid="ignore", divide="ignore"):
        q = 0.25 * c * c
        cb = np.sqrt(1.0 - q * k * k)
        g = h - q * k / (1.0 + cb)
        kap = (2.0 * q * k + 2.0 * cb * g) / (g * g + q)
    return np.where(c == 0, np.inf, kap)


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Distance (mm) of points p from segments [a, b] (all (M, 3))."""
    ab = b - a
    L2 = np.sum(ab * ab, axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.clip(np.where(L2 > 0, np.sum((p - a) * ab, axis=1) / L2, 0.0), 0.0, 1.0)
    return np.linalg.norm(p - (a + s[:, None] * ab), axis=1)


def neighbour_stepover(cc: np.ndarray, rows: np.ndarray, reach: float = np.inf) -> np.ndarray:
    """Per CC point (N, 3) mm, the distance (mm) to the previous row's and to the next row's
    polyline in program order, (N, 2): the nearest CC point of that row, refined to the nearer of
    its two segments. NaN where there is no such row or it is further than ``reach`` mm (not a
    neighbouring pass: a cutter's width, say)."""
    from scipy.spatial import cKDTree

    cc = np.asarray(cc, float)
    rows = np.asarray(rows)
    n = len(cc)
    out = np.full((n, 2), np.nan)
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    ends = np.r_[starts[1:], n]
    trees = [cKDTree(cc[a:b]) for a, b in zip(starts, ends, strict=True)]
    for j, (a, b) in enumerate(zip(starts, ends, strict=True)):
        p = cc[a:b]
        for side, nb in ((0, j - 1), (1, j + 1)):
            if not 0 <= nb < len(starts):
                continue
            a1, b1 = starts[nb], ends[nb]
            d, i = trees[nb].query(p)
            q = cc[a1:b1]
            if len(q) > 1:
                lo, hi = np.maximum(i - 1, 0), np.minimum(i + 1, len(q) - 1)
                d = np.minimum(d, np.minimum(_segment_distance(p, q[lo], q[i]), _segment_distance(p, q[i], q[hi])))
            out[a:b, side] = np.where(d <= reach, d, np.nan)
    return out


def point_scallop(cutter: Any, lead: np.ndarray, tilt: np.ndarray, K_surface: np.ndarray,
                  stepover: np.ndarray) -> np.ndarray:
    """The scallop (mm) each point's pass leaves toward its neighbouring passes: the larger of
    ``scallop_height`` at the two stepovers (N, 2) mm (NaN sides ignored; NaN with no neighbour),
    with the swept cutter's curvature at the point's lead and tilt (rad) over the surface's
    curvature tensors K_surface (N, 2, 2) 1/mm (basis X_L, Y_L)."""
    K_surface = np.asarray(K_surface, float)
    kap = swept_curvature(cutter, lead, tilt, K_surface)
    h = scallop_height(kap[:, None], K_surface[:, None, 1, 1], stepover)
    return np.where(np.all(np.isnan(h), axis=1), np.nan, np.nanmax(np.where(np.isnan(h), -np.inf, h), axis=1))


@dataclass(frozen=True)
class ScallopBudget:
    """A finish budget per point and what it asks of the lead: ``limit`` (N,) the allowed scallop
    (mm; inf where unbounded), ``ceiling`` (N, 3) the lead ceiling c0 + c1 tilt + c2 tilt^2 (rad)
    where ``has`` (N,), ``short`` (N,) points where no lead of the window meets it at any tilt of
    the tilt window (their ceiling keeps the lead in the lowest SHORT_ROOM of its window, near
    the least scallop the window allows)."""

    limit: np.ndarray
    ceiling: np.ndarray
    has: np.ndarray
    short: np.ndarray


def lead_ceiling(cutter: Any, limit: np.ndarray, K_surface: np.ndarray, stepover: np.ndarray,
                 lead_window: np.ndarray, tilt_window: np.ndarray) -> ScallopBudget:
    """The lead ceiling (rad, quadratic in tilt) that keeps each point's scallop within ``limit``
    (N,) mm (module docstring), on a surface with curvature tensors K_surface (N, 2, 2) 1/mm at
    the stepovers (N, 2) mm: the exact ceiling sampled at CAP_TILTS tilts of the tilt window
    (N, 2) rad, a least-squares quadratic lowered below every sample and by CAP_MARGIN. Points
    whose ceiling lies above the lead window (N, 2) at every tilt get none."""
    limit = np.asarray(limit, float)
    K_surface = np.asarray(K_surface, float)
    n = len(limit)
    R, r = float(cutter.R), float(cutter.r)
    k = K_surface[:, 1, 1]
    with np.errstate(invalid="ignore"):
        kap = curvature_for_scallop(limit[:, None], k[:, None], stepover)
    kap_max = np.min(np.where(np.isnan(kap), np.inf, kap), axis=1)
    kap_max = np.where(np.isfinite(limit), kap_max, np.inf)
    d = (kap_max - k)[:, None]
    u = np.linspace(0.0, 1.0, CAP_TILTS)
    tilts = tilt_window[:, :1] + u[None, :] * (tilt_window[:, 1:2] - tilt_window[:, :1])  # (N, S)
    c, s_ = np.cos(tilts), np.sin(tilts)
    K = K_surface[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        if r > 0:  # C = k_m m m^T - K - d e_y e_y^T; k_x <= -det(C) / m^T C m
            km = 1.0 / r
            c11 = km * c * c - K[..., 0, 0]
            c12 = km * c * s_ - K[..., 0, 1]
            c22 = km * s_ * s_ - K[..., 1, 1] - d
            mcm = c11 * c * c + 2 * c12 * c * s_ + c22 * s_ * s_
            k_allowed = np.where(mcm > 0, -(c11 * c22 - c12 * c12) / mcm, -np.inf)
        else:  # flat end, k_m -> inf: k_x <= p^T (K + d e_y e_y^T) p = p^T K p + d cos^2(tilt)
            pkp = K[..., 0, 0] * s_ * s_ - 2 * K[..., 0, 1] * s_ * c + K[..., 1, 1] * c * c
            k_allowed = pkp + d * c * c
        k_allowed = np.where(np.isnan(k_allowed), np.inf, k_allowed)  # no budget (d infinite)
        if R > 0:
            sin_lead = np.where(k_allowed * r < 1.0, k_allowed * R / (1.0 - k_allowed * r), np.inf)
            cap = np.where(k_allowed < 0, -np.inf, np.arcsin(np.clip(sin_lead, 0.0, 1.0)))
            cap = np.where(sin_lead >= 1.0, np.pi / 2, cap)
        else:  # ball end: no lead dependence
            cap = np.where(k_allowed >= 1.0 / r, np.pi / 2, -np.inf)
    lo, hi = lead_window[:, :1], lead_window[:, 1:2]
    has = np.any(cap < hi, axis=1) & np.isfinite(kap_max)
    short = has & np.all(cap < lo + CAP_MARGIN, axis=1)
    samples = np.clip(cap, lo, hi + CAP_MARGIN)
    coef = np.zeros((n, 3))
    x = tilts - tilts.mean(axis=1, keepdims=True)
    span = np.ptp(tilts, axis=1) > 1e-9
    for deg, sel in ((2, has & span & ~short), (0, has & (~span | short))):
        k = np.flatnonzero(sel)
        if not len(k):
            continue
        V = np.stack([x[k] ** j for j in range(3)], -1)[..., :deg + 1]  # (M, S, deg+1)
        VtV = np.einsum("msi,msj->mij", V, V)
        Vty = np.einsum("msi,ms->mi", V, samples[k])
        c = np.linalg.solve(VtV, Vty[..., None])[..., 0]
        fit = np.einsum("msi,mi->ms", V, c)
        c[:, 0] -= np.max(fit - samples[k], axis=1) + CAP_MARGIN
        # back from x = tilt - mean to tilt
        m = tilts[k].mean(axis=1)
        c = np.column_stack([c, np.zeros((len(k), 3 - c.shape[1]))])
        coef[k, 0] = c[:, 0] - c[:, 1] * m + c[:, 2] * m * m
        coef[k, 1] = c[:, 1] - 2 * c[:, 2] * m
        coef[k, 2] = c[:, 2]
    # points short of their budget: the lead kept near the window's floor (the least scallop it
    # allows), with SHORT_ROOM of the window's width for the machine's limits
    ks = np.flatnonzero(short)
    room = np.maximum(CAP_MARGIN, SHORT_ROOM * (hi[ks, 0] - lo[ks, 0]))
    coef[ks] = np.column_stack([lo[ks, 0] + room, np.zeros((len(ks), 2))])
    return ScallopBudget(limit=limit, ceiling=coef, has=has, short=short)


def merge_ceilings(c1: np.ndarray, has1: np.ndarray, c2: np.ndarray, has2: np.ndarray,
                   tilt_window: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One quadratic lead ceiling (N, 3) per point below both given ones over the tilt window
    (N, 2) rad: where both exist, whichever of the two, lowered until it lies under the other at
    CAP_TILTS tilts, is higher on average. Returns (coefficients, has)."""
    has = has1 | has2
    out = np.where(has1[:, None], c1, c2)
    both = np.flatnonzero(has1 & has2)
    if len(both):
        u = np.linspace(0.0, 1.0, CAP_TILTS)
        tw = tilt_window[both]
        t = tw[:, :1] + u[None, :] * (tw[:, 1:2] - tw[:, :1])
        P = np.stack([np.ones_like(t), t, t * t], -1)
        v1, v2 = np.einsum("msi,mi->ms", P, c1[both]), np.einsum("msi,mi->ms", P, c2[both])
        d1, d2 = np.max(v1 - v2, axis=1).clip(0), np.max(v2 - v1, axis=1).clip(0)
        a = c1[both].copy()
        a[:, 0] -= d1
        b = c2[both].copy()
        b[:, 0] -= d2
        out[both] = np.where(((v1.mean(1) - d1) >= (v2.mean(1) - d2))[:, None], a, b)
    return out, has
