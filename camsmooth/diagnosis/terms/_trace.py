"""Helpers shared by the terms that only a controller trace can show (camsmooth.diagnosis.trace):
whether a problem is a trace, the trace's axes, and a start chosen from a small grid."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

NOT_TRACE = "needs a controller trace of command and actual per axis (camsmooth diagnose --trace)"


def trace_of(P: Any) -> Any:
    """The problem's trace (camsmooth.diagnosis.trace.Trace), or None for a program-and-recording
    problem."""
    return getattr(P, "trace", None)


def moving_axes(P: Any) -> list[str]:
    return [a for a in P.axes if P.knots.moves(a)]


def weighted_rss(P: Any, model: Any) -> float:
    r = (P.data_fit - P.sim_fit.run(model)) * P.w_fit
    return float(np.sum(np.where(P.valid_fit, r, 0.0) ** 2))


def grid_start(P: Any, term: Any, model: Any, names: Sequence[str], grid: Iterable[np.ndarray]) -> np.ndarray:
    """The candidate parameter vector (over ``model``) with the lowest floor-weighted RSS."""
    best, best_x = np.inf, None
    for x in grid:
        m = model.copy()
        term.write(m, names, np.asarray(x, float))
        r = weighted_rss(P, m)
        if r < best:
            best, best_x = r, np.asarray(x, float)
    return best_x if best_x is not None else term.read(model, names)


def smooth_speed(t: np.ndarray, x: np.ndarray, width: int = 5) -> np.ndarray:
    """|dx/dt| after a centred moving average over ``width`` samples (s, file units)."""
    k = np.ones(width) / width
    xs = np.convolve(x, k, mode="same") if len(x) > width else x
    v = np.abs(np.gradient(xs, t))
    return v[width:-width] if len(v) > 2 * width + 2 else v
