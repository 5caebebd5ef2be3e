"""Plot of the planned feed (camsmooth.smoothing.feed) against path length, one panel per method.

Like camsmooth.report.smoothing (whose helpers it uses): matplotlib's object API and the Agg
canvas, never pyplot; rows concatenated along x (row starts marked by faint vertical lines); series
longer than ``max_plot_points`` drawn as a min/max envelope per bin.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from camsmooth.report.smoothing import _METHOD_ORDER, _colour, _figure, _line_xy, _row_starts
from camsmooth.smoothing.feed import FeedPlan

#: file name the report gives this plot
FEED_PLOT_FILE = "planned_feed.png"
_PROGRAMMED_COLOUR = "#000000"


def path_length(tip: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Tool-tip path length (mm) over the program, rows concatenated: 0 at the first point, each
    row continuing from where the previous one ended (the moves between rows not counted)."""
    tip = np.asarray(tip, float)
    if len(tip) == 0:
        return np.zeros(0)
    step = np.r_[0.0, np.linalg.norm(np.diff(tip, axis=0), axis=1)]
    step[_row_starts(rows)] = 0.0
    return np.cumsum(step)


def plot_planned_feed(tips: Mapping[str, np.ndarray], rows: np.ndarray, plans: Mapping[str, FeedPlan],
                      programmed_feed: np.ndarray, *, primary: str | None = None,
                      max_plot_points: int = 8000) -> Any:
    """A matplotlib Figure: per method (one panel each, in the order none, spline, nlp, others),
    the planned tool-tip feed ``plans[m].feed_plan`` (mm/min) against that method's tool-tip path
    length (mm; ``tips[m]``: (N, 3) CL points, workpiece frame), with the programmed feed (mm/min,
    per point: the block ending there, drawn as steps) and the method's cycle time and limiting
    constraint in the panel title. rows: (N,) row id per point, shared by every method."""
    names = [m for m in _METHOD_ORDER if m in plans] + [m for m in plans if m not in _METHOD_ORDER]
    if not names:
        raise ValueError("no feed plans to plot")
    rows = np.asarray(rows)
    starts = _row_starts(rows)
    programmed = np.asarray(programmed_feed, float)
    fig, axes = _figure(len(names), 1, "Planned tool-tip feed against path length (mm/min)", width=10.0)
    for ax, name in zip(axes[:, 0], names, strict=True):
        plan = plans[name]
        s = path_length(tips[name], rows)
        x, y = _line_xy(s, np.asarray(plan.feed_plan, float), starts, max(int(max_plot_points), 4))
        ax.plot(x, y, color=_colour(name, names), linewidth=0.9, label=f"{name}: planned")
        xp, yp = _line_xy(s, programmed, starts, max(int(max_plot_points), 4))
        ax.plot(xp, yp, color=_PROGRAMMED_COLOUR, linestyle="--", linewidth=0.8, drawstyle="steps-pre",
                label="programmed")
        if len(starts) > 1:
            ax.vlines(s[starts[1:]], 0, 1, transform=ax.get_xaxis_transform(), colors="0.6", linewidths=0.5,
                      alpha=0.35, zorder=0)
        ax.set_ylim(bottom=0.0)
        ax.grid(True, alpha=0.3)
        ax.set_ylabel("feed (mm/min)")
        tag = " (primary)" if name == primary else ""
        ax.set_title(f"{name}{tag}: cycle time {plan.cycle_time:.4g} s, limited mostly by {plan.limiting}",
                     fontsize=10)
        ax.legend(loc="lower right", fontsize=8)
    axes[-1, 0].set_xlabel("tool-tip path length (mm, rows concatenated)")
    return fig

