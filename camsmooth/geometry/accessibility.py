"""Accessibility map: where in its lead/tilt window the tool clears the mesh at a CC point.

This is the configuration-space (C-space) view of tool orientation of the five-axis literature:
Jun, Cha & Lee (2003, "Optimal tool orientation for five-axis machining by configuration-space
search", Computer-Aided Design 35) sample the orientation space of each CC point, test each
orientation for interference and search the free space; Wang & Tang (2007, "Five-axis NC
machining of sculptured surfaces", and their accessibility-cone work) build per-point accessible
sets and smooth the tool path within them. We take the sampled C-space of Jun et al. because it
works with the exact clearance of any tool solid against any mesh (camsmooth.geometry.clearance),
restricted to the user's lead/tilt window (METHODS section 1, local frame X_L = feed, Z_L = n),
and we hand the smoothing NLP not the samples but smooth constraints that bound them, as Wang &
Tang hand their optimiser the accessible set:

1. Sample: clearance on an n_lead x n_tilt grid over the window (lead rad about Y_L, tilt rad
   about Z_L, as in camsmooth.smoothing.orientation). An orientation is clear when its clearance
   is at least ``-threshold`` (mm).
2. Per tilt column keep the largest run of clear leads; refine its ends by bisection in lead
   (its lower end is a *lead floor*: the heel of the cutter gouging a concave region at low lead,
   the common case; its upper end a *lead ceiling*: the shank or holder meeting a wall at high
   lead). Columns with no clear lead narrow the tilt range to the largest run of clear columns.
3. Fit the floor and the ceiling as quadratics in tilt and shift each onto the safe side of every
   refined sample (the floor up, the ceiling down), so the constraints the NLP receives,
   ``floor(tilt) <= lead <= ceiling(tilt)`` with tilt in the clear range, are smooth in the tool
   axis and exclude every blocked sample. Between samples the map is an approximation: the
   pipeline verifies the final poses with the exact clearance and refines where needed.

A point none of whose samples clears is *blocked*: the lift along the normal is then the only
fallback, and the map's best clearance (and where it was found) says how close it came.
Angles are radians, lengths mm, workpiece frame.

What the windows mean for each cutter of the toroid family (camsmooth.geometry.cutter; lead
rotates the axis in the plane of the feed and the normal, so the meridian plane through the
contact runs along the feed and the ring's curvature acts across it):

* Bull nose (R, r > 0): the contact moves round the ring with the lead; the effective radius
  across the feed is R / sin(lead) + r, so the lead sets the finish and, where the part is
  concave, the floor against local gouging (camsmooth.smoothing.orientation) and against the heel
  (this map).  Lead 0 is a face contact where CC -> CL jumps by R: keep the lead window above 0.
* Ball end (R = 0): the contact point and the ball's centre CC + r n do not depend on lead or
  tilt, and the cut surface is the same at every orientation (effective radius r).  The windows
  then bound no cutting geometry: they are where the shank and holder may stand (this map's floors
  and ceilings come only from them meeting the part) and the machine's motion; practice keeps the
  lead off 0 because the ball's tip cuts at zero speed.
* Flat end (r = 0): the contact is the point of the sharp bottom rim lowest along n,
  CL = CC + R u; across the feed the rim's ellipse has radius R / sin(lead); along the feed the
  bottom is a straight line rising at the lead behind the contact, so on a surface concave along
  the feed with curvature k the heel (2 R behind) gouges unless tan(lead) >= k R about; this
  global condition is found here, by the exact clearance, not by the local curvature test.  Lead
  0 is a face contact (the whole bottom on a plane, CL = CC) that gouges any concave region: a
  flat end needs lead > 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsmooth.geometry.clearance import MeshIndex, clearance
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl
from camsmooth.geometry.frames import axis_from_lead_tilt

__all__ = ["AccessibilityMap", "ClearRegion", "accessibility_map", "clear_region", "pose_clearance"]

DEGREE = 2  # floor and ceiling: quadratics in tilt


def pose_clearance(index: MeshIndex, cutter: ToroidalCutter, cc: np.ndarray, normals: np.ndarray,
                   frames: np.ndarray, lead: np.ndarray, tilt: np.ndarray) -> np.ndarray:
    """Exact clearance (mm, negative = gouge) of the tool touching CC points ``cc`` (N, 3) with
    unit normals (N, 3) at lead/tilt (rad, local frames (N, 3, 3) of
    camsmooth.smoothing.orientation; N poses, broadcast)."""
    T = axis_from_lead_tilt(lead, tilt, frames)
    return clearance(index, cutter, cc_to_cl(cutter, cc, normals, T), T).delta


@dataclass(frozen=True)
class AccessibilityMap:
    """Sampled clearance of M CC points over their windows.

    lead: (M, nl) and tilt: (M, nt) sample values (rad); delta: (M, nl, nt) clearance (mm);
    threshold: an orientation is clear when delta >= -threshold (mm); floor, ceiling: (M, nt)
    refined ends (rad) of the largest run of clear leads per tilt column (NaN where the column
    has no clear lead); floor_active, ceiling_active: (M, nt) the end lies inside the window (the
    window's own bound is not a clearance constraint).
    """

    lead: np.ndarray
    tilt: np.ndarray
    delta: np.ndarray
    threshold: float
    floor: np.ndarray
    ceiling: np.ndarray
    floor_active: np.ndarray
    ceiling_active: np.ndarray

    @property
    def column_clear(self) -> np.ndarray:
        """(M, nt) tilt columns with some clear lead."""
        return np.isfinite(self.floor)


def _largest_run(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Start and end (inclusive) index of the largest run of True along the last axis (ties: the
    run at the higher index); (-1, -1) where there is none."""
    m = mask.shape[-1]
    flat = mask.reshape(-1, m)
    best_len = np.zeros(len(flat), int)
    best_end = np.full(len(flat), -1)
    run = np.zeros(len(flat), int)
    for k in range(m):  # loops over the few samples of a column, vectorised over points
        run = np.where(flat[:, k], run + 1, 0)
        better = run >= np.maximum(best_len, 1)
        best_len = np.where(better, run, best_len)
        best_end = np.where(better, k, best_end)
    start = np.where(best_end >= 0, best_end - best_len + 1, -1)
    return start.reshape(mask.shape[:-1]), best_end.reshape(mask.shape[:-1])


def accessibility_map(index: MeshIndex, cutter: ToroidalCutter, cc: np.ndarray, normals: np.ndarray,
                      frames: np.ndarray, lead_window: np.ndarray, tilt_window: np.ndarray, threshold: float,
                      n_lead: int = 9, n_tilt: int = 7, refine: int = 6) -> AccessibilityMap:
    """The sampled map (module docstring, steps 1 and 2) of M CC points (cc, normals (M, 3), frames
    (M, 3, 3)) over their windows (M, 2) [min, max] rad; ``threshold`` mm; ``refine`` bisection
    steps at each end of a clear run (each halves the lead bracket)."""
    M = len(cc)
    lead = lead_window[:, :1] + (lead_window[:, 1:] - lead_window[:, :1]) * np.linspace(0, 1, n_lead)[None]
    tilt = tilt_window[:, :1] + (tilt_window[:, 1:] - tilt_window[:, :1]) * np.linspace(0, 1, n_tilt)[None]
    pid = np.repeat(np.arange(M), n_lead * n_tilt)
    L = np.repeat(lead, n_tilt, axis=1).ravel()
    P = np.tile(tilt, (1, n_lead)).ravel()
    delta = pose_clearance(index, cutter, cc[pid], normals[pid], frames[pid], L, P).reshape(M, n_lead, n_tilt)
    clear = delta >= -threshold
    start, end = _largest_run(np.moveaxis(clear, 1, 2))  # (M, nt) along lead
    has = start >= 0
    floor = np.full((M, n_tilt), np.nan)
    ceiling = np.full((M, n_tilt), np.nan)
    rows, cols = np.nonzero(has)
    s, e = start[rows, cols], end[rows, cols]
    floor[rows, cols] = lead[rows, s]
    ceiling[rows, cols] = lead[rows, e]
    floor_active = has & (start > 0)
    ceiling_active = has & (end < n_lead - 1)
    # bisection: the floor between the last blocked lead below the run and its first clear lead,
    # the ceiling between its last clear lead and the first blocked lead above it
    for active, ends, inside, outside in ((floor_active, start, 0, -1), (ceiling_active, end, 0, 1)):
        r, c = np.nonzero(active)
        if r.size == 0:
            continue
        k = ends[r, c]
        good, bad = lead[r, k + inside], lead[r, k + outside]
        for _ in range(refine):
            mid = 0.5 * (good + bad)
            ok = pose_clearance(index, cutter, cc[r], normals[r], frames[r], mid, tilt[r, c]) >= -threshold
            good, bad = np.where(ok, mid, good), np.where(ok, bad, mid)
        (floor if outside < 0 else ceiling)[r, c] = good
    return AccessibilityMap(lead, tilt, delta, float(threshold), floor, ceiling, floor_active, ceiling_active)


@dataclass(frozen=True)
class ClearRegion:
    """Smooth constraints bounding the clear part of the window of M CC points (module
    docstring, step 3); what the NLP receives.

    floor, ceiling: (M, 3) coefficients (c0, c1, c2) of lead = c0 + c1 tilt + c2 tilt^2 (rad);
    has_floor, has_ceiling: (M,) whether the constraint applies (the window's own lead bounds
    apply everywhere anyway); tilt_window: (M, 2) the clear tilt range (rad) within the window;
    blocked: (M,) no sampled orientation clears; best_delta (mm), best_lead, best_tilt (rad): the
    largest clearance the map found and where.
    """

    floor: np.ndarray
    ceiling: np.ndarray
    has_floor: np.ndarray
    has_ceiling: np.ndarray
    tilt_window: np.ndarray
    blocked: np.ndarray
    best_delta: np.ndarray
    best_lead: np.ndarray
    best_tilt: np.ndarray

    def lead_bounds(self, tilt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(floor, ceiling) lead (rad) at the given tilts (M,); -inf / +inf where absent."""
        p = np.stack([np.ones_like(tilt), tilt, tilt ** 2], -1)
        lo = np.where(self.has_floor, np.sum(self.floor * p, -1), -np.inf)
        hi = np.where(self.has_ceiling, np.sum(self.ceiling * p, -1), np.inf)
        return lo, hi


def _fit_bound(tilt: np.ndarray, values: np.ndarray, use: np.ndarray, upper: bool) -> np.ndarray:
    """Per point, the least-squares polynomial (degree <= DEGREE, fewer with fewer columns) in
    tilt through the used samples, shifted so it is >= (floor) or <= (ceiling, ``upper``) every
    used sample. Returns (M, 3) coefficients; rows without used samples are zero."""
    M, nt = values.shape
    cnt = use.sum(axis=1)
    mid = np.where(cnt > 0, np.sum(np.where(use, tilt, 0), 1) / np.maximum(cnt, 1), 0.0)
    u = tilt - mid[:, None]  # centred for conditioning
    V = np.stack([np.ones_like(u), u, u ** 2], -1) * use[..., None]  # (M, nt, 3)
    y = np.where(use, values, 0.0)
    G = np.einsum("mki,mkj->mij", V, V)
    b = np.einsum("mki,mk->mi", V, y)
    # degree min(DEGREE, cnt - 1): the unused coefficients are pinned to zero
    deg = np.minimum(DEGREE, np.maximum(cnt - 1, 0))
    pin = np.arange(3)[None, :] > deg[:, None]
    G = G + np.eye(3)[None] * (pin[:, :, None] * 1e12 + 1e-12)
    c = np.linalg.solve(G, b[..., None])[..., 0]
    fit = np.einsum("mki,mi->mk", np.stack([np.ones_like(u), u, u ** 2], -1), c)
    gap = np.where(use, (values - fit) if not upper else (fit - values), -np.inf)
    shift = np.max(gap, axis=1)
    shift = np.where(np.isfinite(shift), shift, 0.0)
    c[:, 0] += -shift if upper else shift
    # back to powers of tilt: c0 + c1 (t - m) + c2 (t - m)^2
    c0, c1, c2 = c[:, 0], c[:, 1], c[:, 2]
    out = np.stack([c0 - c1 * mid + c2 * mid ** 2, c1 - 2 * c2 * mid, c2], -1)
    return np.where(cnt[:, None] > 0, out, 0.0)


def clear_region(amap: AccessibilityMap, lead_window: np.ndarray, margin: float = np.radians(0.02)) -> ClearRegion:
    """Smooth floor/ceiling constraints and the clear tilt range from a map (module docstring,
    step 3); ``margin`` (rad) moves the fitted floor up and the ceiling down a little further, so
    that the NLP's solution on the bound is clear between the samples too."""
    M, nt = amap.floor.shape
    col = amap.column_clear
    t0, t1 = _largest_run(col)
    blocked = t0 < 0
    k = np.arange(nt)[None, :]
    use = (k >= t0[:, None]) & (k <= t1[:, None]) & col
    ar = np.arange(M)
    tilt_window = np.stack([amap.tilt[ar, np.maximum(t0, 0)], amap.tilt[ar, np.maximum(t1, 0)]], -1)
    has_floor = np.any(use & amap.floor_active, axis=1)
    has_ceiling = np.any(use & amap.ceiling_active, axis=1)
    # columns whose end is the window's bound carry that bound as a sample: a floor rising inside
    # the window is fitted against the flat part too, which is conservative
    floor = _fit_bound(amap.tilt, np.where(use, amap.floor, np.nan), use, upper=False)
    ceiling = _fit_bound(amap.tilt, np.where(use, amap.ceiling, np.nan), use, upper=True)
    floor[:, 0] += margin
    ceiling[:, 0] -= margin
    # a floor that meets the ceiling leaves no clear lead: cut the tilt range to where it is open
    fine = tilt_window[:, :1] + (tilt_window[:, 1:] - tilt_window[:, :1]) * np.linspace(0, 1, 4 * nt)[None]
    pw = np.stack([np.ones_like(fine), fine, fine ** 2], -1)
    lo = np.where(has_floor[:, None], np.einsum("mki,mi->mk", pw, floor), lead_window[:, :1])
    hi = np.where(has_ceiling[:, None], np.einsum("mki,mi->mk", pw, ceiling), lead_window[:, 1:])
    lo, hi = np.maximum(lo, lead_window[:, :1]), np.minimum(hi, lead_window[:, 1:])
    s0, s1 = _largest_run(lo < hi)
    closed = s0 < 0
    blocked = blocked | closed
    fa = np.arange(M)
    narrowed = np.stack([fine[fa, np.maximum(s0, 0)], fine[fa, np.maximum(s1, 0)]], -1)
    tilt_window = np.where(closed[:, None], tilt_window, narrowed)
    flat = amap.delta.reshape(M, -1)
    best = np.argmax(flat, axis=1)
    bl, bt = np.unravel_index(best, amap.delta.shape[1:])
    return ClearRegion(floor=floor, ceiling=ceiling, has_floor=has_floor & ~blocked, has_ceiling=has_ceiling & ~blocked,
                       tilt_window=tilt_window, blocked=blocked, best_delta=flat[fa, best],
                       best_lead=amap.lead[fa, bl], best_tilt=amap.tilt[fa, bt])
