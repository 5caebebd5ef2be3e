"""Tool orientation at CC points: local frames, lead/tilt <-> tool axis, curvature-based
admissible windows and the initial (gouge-free) orientation.

Frames and signs (METHODS.md section 1): at a CC point with unit normal n (material -> tool)
and feed direction f, X_L = f, Z_L = n, Y_L = Z_L x X_L (right-handed). Lead theta rotates the
tool axis about Y_L, tilt phi about Z_L:

    T_L = (sin theta cos phi, sin theta sin phi, cos theta),  T_W = [X_L Y_L Z_L] T_L.

Lead is in [0, pi/2) (positive lead puts the contact on the leading side of the cutter), tilt in
(-pi/2, pi/2). All angles in radians.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from camsmooth.errors import InfeasibleError, InputError
from camsmooth.geometry.curvature import surface_curvature_tensors
from camsmooth.geometry.frames import axis_from_lead_tilt, lead_tilt_from_axis, local_frames

__all__ = ["axis_from_lead_tilt", "lead_tilt_from_axis", "local_frames", "initial_orientation",
           "surface_curvature_tensors", "min_gouge_free_lead", "Orientation"]


# ----------------------------------------------------------------------------------------------
# curvature of the cutter, in the local tangent basis (X_L, Y_L)
def cutter_curvature_tensors(R: float, r: float, lead: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Curvature tensors (..., 2, 2) of a toroidal cutter at its contact, in the basis (X_L, Y_L).

    At a contact whose normal makes the angle lead with the tool axis, the torus has principal
    curvature 1/r in the meridian plane (tangent direction m = (cos tilt, sin tilt)) and
    sin(lead) / (R + r sin(lead)) across it (effective radius R / sin(lead) + r, METHODS
    section 1). Positive = the cutter bends away from the part, toward n (same convention as the
    surface: no local gouge iff K_cutter - K_surface is positive semidefinite).
    """
    lead, tilt = np.broadcast_arrays(np.asarray(lead, float), np.asarray(tilt, float))
    sl = np.sin(lead)
    k_cross = sl / (R + r * sl) if R > 0 else np.full_like(sl, 1.0 / r)
    m = np.stack([np.cos(tilt), np.sin(tilt)], -1)
    p = np.stack([-np.sin(tilt), np.cos(tilt)], -1)
    mm = m[..., :, None] * m[..., None, :]
    # flat end (r = 0): the sharp rim, infinite curvature in the meridian plane (0 where mm is 0)
    k_mm = mm / r if r > 0 else np.where(mm == 0.0, 0.0, np.copysign(np.inf, mm))
    return k_mm + k_cross[..., None, None] * p[..., :, None] * p[..., None, :]


def min_gouge_free_lead(R: float, r: float, K_surface: np.ndarray, tilt: np.ndarray,
                        lead_max: float, margin: float = 1e-4) -> np.ndarray:
    """Smallest lead (rad) in [0, lead_max] with K_cutter(lead, tilt) - K_surface >= margin * I
    (no local gouge, METHODS section 1), for each point and tilt (arrays broadcast with
    K_surface[..., 0, 0]). NaN where even lead_max gouges.

    Closed form: K_cutter = k_m m m^T + k p p^T with the meridian direction m, p perpendicular to
    it, k_m = 1/r and k = sin(lead) / (R + r sin(lead)) (``cutter_curvature_tensors``), so
    D(k) = C + k p p^T with C = k_m m m^T - K_surface - margin I fixed. For a 2 x 2 matrix
    det(C + k p p^T) = det(C) + k m^T C m (the matrix determinant lemma; adj(C) acts as C on the
    perpendicular direction m), and D(k) is positive semidefinite iff m^T C m >= 0 and
    det(D(k)) >= 0 (the direction m keeps a non-negative Rayleigh quotient whatever k). So the
    smallest k is max(0, -det(C) / m^T C m) when m^T C m > 0, and none otherwise; the lead
    follows from sin(lead) = k R / (1 - k r) (k grows with the lead).
    """
    tilt = np.asarray(tilt, float)
    shape = np.broadcast_shapes(K_surface.shape[:-2], tilt.shape)
    K = np.broadcast_to(K_surface, shape + (2, 2))
    c, s_ = np.cos(tilt), np.sin(tilt)
    if r == 0:  # flat end: k_m infinite, the condition is k >= p^T K p + margin; sin(lead) = k R
        k_need = np.maximum(0.0, s_ * s_ * K[..., 0, 0] - 2 * c * s_ * K[..., 0, 1] + c * c * K[..., 1, 1] + margin)
        sin_lead = k_need * R
        lead = np.where(sin_lead <= 1.0, np.arcsin(np.clip(sin_lead, 0.0, 1.0)), np.inf)
        return np.where(lead <= lead_max, lead, np.nan)
    km = 1.0 / r
    # C = km m m^T - K - margin I, m = (c, s)
    c11 = km * c * c - K[..., 0, 0] - margin
    c12 = km * c * s_ - K[..., 0, 1]
    c22 = km * s_ * s_ - K[..., 1, 1] - margin
    det = c11 * c22 - c12 * c12
    mcm = c11 * c * c + 2 * c12 * c * s_ + c22 * s_ * s_
    with np.errstate(divide="ignore", invalid="ignore"):
        k_need = np.where(mcm > 0, np.maximum(0.0, -det / mcm), np.inf)
    if R > 0:
        with np.errstate(divide="ignore", invalid="ignore"):
            sin_lead = np.where(k_need * r < 1.0, k_need * R / (1.0 - k_need * r), np.inf)
        lead = np.arcsin(np.clip(sin_lead, 0.0, 1.0))
        lead = np.where(sin_lead > 1.0, np.inf, lead)
    else:  # ball nose: the cross curvature is 1/r at every lead
        lead = np.where(k_need <= km, 0.0, np.inf)
    return np.where(lead <= lead_max, lead, np.nan)


@dataclass
class Orientation:
    """Initial orientation and admissible windows per CC point (rad).

    lead, tilt: the initial (gouge-free) orientation; axis: the tool axes (N, 3);
    lead_window, tilt_window: (N, 2) [min, max] after tightening by local curvature;
    lead_required: the curvature's lower bound on lead (rad) per point (max over the tilt window).
    """

    lead: np.ndarray
    tilt: np.ndarray
    axis: np.ndarray
    lead_window: np.ndarray
    tilt_window: np.ndarray
    lead_required: np.ndarray


def initial_orientation(frames: np.ndarray, K_surface: np.ndarray, R: float, r: float,
                        lead_range: tuple[float, float], tilt_range: tuple[float, float],
                        prefer_lead: float | None = None, prefer_tilt: float | None = None,
                        n_tilt: int = 9, point_name: Callable[[int], str] | None = None) -> Orientation:
    """Initial orientation avoiding local gouging (METHODS section 1).

    Per point, the admissible lead window is [max(lead_min, lead_required), lead_max], where
    lead_required is the smallest gouge-free lead over ``n_tilt`` tilts spanning the tilt window
    (conservative: any tilt in the window is then safe). The initial orientation is the user's
    preferred lead and tilt (default: the window midpoints), with the lead raised to the
    curvature's requirement where needed. Raises InfeasibleError naming the first point where no
    lead in the window avoids gouging (e.g. a corner radius larger than the concave radius of the
    surface along the feed); ``point_name(i)`` names point i in that message.
    """
    lmin, lmax = map(float, lead_range)
    tmin, tmax = map(float, tilt_range)
    if not (0.0 <= lmin < lmax < np.pi / 2):
        raise InputError(f"lead window [{np.degrees(lmin):g}, {np.degrees(lmax):g}] deg must satisfy "
                         "0 <= min < max < 90")
    if not (-np.pi / 2 < tmin <= tmax < np.pi / 2):
        raise InputError(f"tilt window [{np.degrees(tmin):g}, {np.degrees(tmax):g}] deg must satisfy "
                         "-90 < min <= max < 90")
    n = len(frames)
    pl = 0.5 * (lmin + lmax) if prefer_lead is None else float(prefer_lead)
    pt = 0.5 * (tmin + tmax) if prefer_tilt is None else float(prefer_tilt)
    if not (lmin <= pl <= lmax and tmin <= pt <= tmax):
        raise InputError("the preferred lead/tilt must lie inside the lead/tilt windows")
    tilts = np.linspace(tmin, tmax, n_tilt) if tmax > tmin else np.array([tmin])
    req = min_gouge_free_lead(R, r, K_surface[:, None], tilts[None, :], lmax)  # (N, n_tilt)
    req_all = np.max(np.where(np.isnan(req), np.inf, req), axis=1)
    tilt_window = np.tile([tmin, tmax], (n, 1)).astype(float)
    # Where some tilts of the window gouge at every lead, keep the contiguous feasible tilt span
    # around the preferred tilt.
    partial = ~np.isfinite(req_all)
    if partial.any():
        feas = np.isfinite(req[partial])
        any_feas = feas.any(axis=1)
        if not any_feas.all():
            i = int(np.flatnonzero(partial)[np.flatnonzero(~any_feas)[0]])
            name = point_name(i) if point_name else f"point {i}"
            kmax = float(np.max(np.linalg.eigvalsh(K_surface[i])))
            raise InfeasibleError(
                f"{name}: no lead in [{np.degrees(lmin):g}, {np.degrees(lmax):g}] deg avoids local gouging "
                f"(surface curvature {kmax:.4g} 1/mm, concave radius {1 / kmax if kmax > 0 else np.inf:.4g} mm; "
                f"cutter corner radius r = {r:g} mm, ring radius R = {R:g} mm): widen the lead window or use "
                "a smaller corner radius")
        rows = np.flatnonzero(partial)
        lo_t = np.empty(len(rows))
        hi_t = np.empty(len(rows))
        j_pref = np.argmin(np.abs(tilts - pt))
        for k, f in enumerate(feas):  # loop over the few partial points only
            j = j_pref if f[j_pref] else int(np.argmax(f))
            a = j
            while a > 0 and f[a - 1]:
                a -= 1
            b = j
            while b < len(f) - 1 and f[b + 1]:
                b += 1
            lo_t[k], hi_t[k] = tilts[a], tilts[b]
            req_all[rows[k]] = np.max(req[rows[k], a:b + 1])
        tilt_window[rows] = np.stack([lo_t, hi_t], -1)
    lead_window = np.stack([np.maximum(lmin, req_all), np.full(n, lmax)], -1)
    lead = np.clip(np.full(n, pl), lead_window[:, 0], lead_window[:, 1])
    tilt = np.clip(np.full(n, pt), tilt_window[:, 0], tilt_window[:, 1])
    axis = axis_from_lead_tilt(lead, tilt, frames)
    return Orientation(lead, tilt, axis, lead_window, tilt_window, req_all)
