"""The pole of the outer rotary axis: where a program passes it, and a start the NLP can leave.

Where the tool axis T comes near the outer rotary axis (the C axis of a table-table machine;
``Machine.pole_angle``), the exact inverse kinematics turns C by up to 180 deg within a few points:
a path that passes the pole at an angle d turns C by about pi over the time the tool axis needs to
travel 2 d, far beyond any C axis' limits when d is small (docs/METHODS.md section 1.5). A path
through the pole itself is easy: C stands still and the tilt axis changes sign (the other
inverse branch). camsmooth lets the NLP decide how to pass: it moves the tool axis within the
lead/tilt windows so that C meets its velocity and acceleration limits.

- ``find_passages`` names every passage: a run of points of one row whose programmed tool axis is
  within ``POLE_CONE_DEG`` of the pole, with the closest angle, the turn of the outer axis the
  exact inverse makes across it and its peak speed at the programmed feed.
- ``pole_start`` is the NLP's warm start across each passage: the outer axis turns linearly in
  time from its value before the passage to its value after it (held where it starts when the whole
  row lies in the cone), on whichever inverse branch after the passage makes that turn the smaller
  (within the travel), and the inner axis points the tool
  as near the programmed axis as that outer angle allows (``Machine.nearest_with_outer``). This is
  the "singularity cone" of CAM systems, as a start: the NLP then meets every limit and window.
Angles rad inside, degrees in PolePassage; times s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from camsmooth.geometry.paths import _row_runs
from camsmooth.machine.kinematics import Machine

__all__ = ["POLE_CONE_DEG", "PolePassage", "find_passages", "pole_start", "passage_mask"]

#: half-angle (deg) of the cone about the pole inside which a row's points form a passage: where
#: the exact inverse turns the outer axis fast (it turns at v / d rad/s for a tool axis moving at v
#: rad/s at an angle d from the pole: 6 times the tool axis' own rate at 10 deg)
POLE_CONE_DEG = 10.0


@dataclass(frozen=True, kw_only=True)
class PolePassage:
    """One passage of a row near the pole (module docstring). row: the row id; first, last: the
    point indices within the row (inclusive); closest_deg: the smallest angle between the
    programmed tool axis and the pole (deg) and closest_point its index; outer: the axis whose
    pole it is ("C" on a table); outer_turn_deg: how far the exact inverse turns it across the
    passage (deg); outer_peak_speed: its peak |velocity| there at the programmed feed (deg/s)
    against its limit outer_vmax (deg/s); gamma_cost: what the smoothed program's passage costs in
    Gamma over the programmed orientation's (sum of |T''|^2 over the passage's points, 1/s^4; None
    until a smoothed program is known)."""

    row: int
    first: int
    last: int
    closest_deg: float
    closest_point: int
    outer: str
    outer_turn_deg: float
    outer_peak_speed: float
    outer_vmax: float
    gamma_cost: float | None = None

    @property
    def points(self) -> int:
        return self.last - self.first + 1


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """(first, last) inclusive of every run of True in a 1-D mask."""
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(d == 1).tolist(), (np.flatnonzero(d == -1) - 1).tolist(), strict=True))


def passage_mask(machine: Machine, T: np.ndarray, cone_deg: float = POLE_CONE_DEG) -> np.ndarray:
    """Points whose tool axis T (N, 3, unit, workpiece frame) is within cone_deg of the pole."""
    return machine.pole_angle(T) < np.radians(cone_deg)


def find_passages(machine: Machine, T: np.ndarray, rows: np.ndarray, t: np.ndarray, angles: np.ndarray,
                  cone_deg: float = POLE_CONE_DEG) -> list[PolePassage]:
    """Every passage of the program near the pole (module docstring). T: (N, 3) the programmed
    tool axes (unit, workpiece frame); rows: (N,) row ids (rows contiguous); t: (N,) s from each
    row's start at the programmed feed; angles: (N, 2) rad, the exact inverse (``rotary`` order)."""
    T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, float)
    rows = np.asarray(rows)
    near = passage_mask(machine, T, cone_deg)
    pole = np.degrees(machine.pole_angle(T))
    o = machine.outer_index
    lim = machine.rotary_limits()[o]
    out: list[PolePassage] = []
    starts, _ = _row_runs(rows)
    ends = np.r_[starts[1:], len(rows)]
    for s0, s1 in zip(starts.tolist(), ends.tolist(), strict=True):
        q = angles[s0:s1, o]
        tt = t[s0:s1]
        for a, b in _runs(near[s0:s1]):
            lo, hi = max(a - 1, 0), min(b + 1, s1 - s0 - 1)
            seg = slice(lo, hi + 1)
            with np.errstate(divide="ignore", invalid="ignore"):
                v = np.abs(np.diff(q[seg]) / np.diff(tt[seg]))
            k = a + int(np.argmin(pole[s0 + a:s0 + b + 1]))
            out.append(PolePassage(row=int(rows[s0]), first=a, last=b, closest_deg=float(pole[s0 + k]),
                                   closest_point=k, outer=machine.rotary[o],
                                   outer_turn_deg=float(np.degrees(abs(q[hi] - q[lo]))),
                                   outer_peak_speed=float(np.degrees(np.nanmax(v, initial=0.0))),
                                   outer_vmax=float(np.degrees(lim.vmax))))
    return out


def pole_start(machine: Machine, T: np.ndarray, rows: np.ndarray, t: np.ndarray, angles: np.ndarray,
               cone_deg: float = POLE_CONE_DEG) -> np.ndarray:
    """The NLP's warm start (N, 2) rad across the passages (module docstring); ``angles`` (the
    exact inverse, ``rotary`` order) elsewhere, except that a row whose passage changes branch
    continues on the new branch (``Machine.solve_row`` from the passage's exit). T, rows, t as in
    ``find_passages``."""
    T, t = np.asarray(T, float), np.asarray(t, float)
    out = np.array(angles, dtype=float, copy=True)
    rows = np.asarray(rows)
    near = passage_mask(machine, T, cone_deg)
    o = machine.outer_index
    starts, _ = _row_runs(rows)
    ends = np.r_[starts[1:], len(rows)]
    for s0, s1 in zip(starts.tolist(), ends.tolist(), strict=True):
        n = s1 - s0
        for a, b in _runs(near[s0:s1]):
            q = out[s0:s1]  # a view: a passage sees the branch the one before it left
            before = q[a - 1] if a > 0 else None
            after = q[b + 1] if b + 1 < n else None
            if after is not None and before is not None:
                after = _shorter_exit(machine, T[s0 + b + 1], before[o], after)
                if not np.allclose(after, q[b + 1]):  # the other branch: the rest of the row follows it
                    q[b + 1:] = _continue(machine, T[s0 + b + 1:s1], after)
            ref0 = before if before is not None else after
            ref1 = after if after is not None else before
            if ref0 is None:  # a whole row inside the cone: the outer axis held where it starts
                ref0 = ref1 = q[a].copy()
            ta = t[s0 + a - 1] if before is not None else t[s0 + a]
            tb = t[s0 + b + 1] if after is not None else t[s0 + b]
            w = np.clip((t[s0 + a:s0 + b + 1] - ta) / max(tb - ta, 1e-12), 0.0, 1.0)
            outer = ref0[o] + w * (ref1[o] - ref0[o])
            q[a:b + 1] = machine.nearest_with_outer(T[s0 + a:s0 + b + 1], outer)
    return out


def _shorter_exit(machine: Machine, T: np.ndarray, outer0: float, current: np.ndarray) -> np.ndarray:
    """Of the two inverse branches at the passage's exit (tool axis T), the one within the travel
    whose outer angle is nearest outer0 (unwound by whole turns)."""
    o = machine.outer_index
    best, dist = current, abs(current[o] - outer0)
    for cand in machine.inverse_axis(T[None])[0]:
        c = cand.copy()
        c[o] += 2 * np.pi * np.round((outer0 - c[o]) / (2 * np.pi))
        inside = all(bool(machine.within(name, c[k])) for k, name in enumerate(machine.rotary))
        if inside and abs(c[o] - outer0) < dist - 1e-9:
            best, dist = c, abs(c[o] - outer0)
    return best


def _continue(machine: Machine, T: np.ndarray, first: np.ndarray) -> np.ndarray:
    """The exact inverse along T (M, 3) starting at the angles ``first`` (its first point)."""
    r = machine.solve_row(T, previous=(float(first[0]), float(first[1])))
    return r.rotary.values
