"""The report of ``camsmooth analyze``: the program's rotary axes, their rates against the
machine's limits, the planned feed, and the per-tool-path figures as a table (report.html)."""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.io.atomic import atomic_dir
from camsmooth.report.smoothing import HTML_FILE, _img_tag, _save_png

__all__ = ["write_analysis_report"]

AXES_FILE = "program_axes.png"


def _plot(series: dict[str, np.ndarray], machine: Any) -> Any:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 8), dpi=100)
    axs = fig.subplots(3, 1, sharex=True)
    t = series["t"]
    for ax, key, unit, lim in ((axs[0], "angle", "deg", None), (axs[1], "velocity", "deg/s", "vmax"),
                               (axs[2], "acceleration", "deg/s\u00b2", "amax")):
        for name, colour in zip(machine.rotary, ("#1f77b4", "#d62728"), strict=True):
            ax.plot(t, series[f"{name} {key}"], color=colour, linewidth=0.8, label=name)
            if lim is not None:
                v = np.degrees(getattr(machine.limits[name], lim))
                ax.axhline(v, color=colour, linestyle="--", linewidth=0.7)
                ax.axhline(-v, color=colour, linestyle="--", linewidth=0.7)
        ax.set_ylabel(f"{key} ({unit})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    axs[2].set_xlabel("program time at the programmed feed (s, rows concatenated)")
    fig.suptitle(f"The program as it is: rotary axes {' and '.join(machine.rotary)}; dashed: the machine's limits")
    return fig


def write_analysis_report(analysis: Any, series: dict[str, np.ndarray], machine: Any, out_dir: str | os.PathLike,
                          *, replace: bool = False) -> Path:
    """Write report.html and its figure into ``out_dir`` (its own files replaced atomically,
    others left alone; ``replace`` replaces the folder). ``series``: per point of the program, 't'
    (s) and 'A|B angle|velocity|acceleration' (deg, deg/s, deg/s^2)."""
    with atomic_dir(out_dir, replace=replace) as tmp:
        _save_png(_plot(series, machine), tmp / AXES_FILE)
        doc = analysis.to_json()
        rows = []
        for tp in doc["toolpaths"]:
            viol = ", ".join(f"{k}: {v}" for k, v in tp["violations"].items() if v) or "none"
            viol_p = ", ".join(f"{k}: {v}" for k, v in tp.get("violations_programmed", {}).items() if v) or "none"
            tool = tp["tool"] or {}
            rows.append("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in (
                tp["name"], f"D {tool.get('diameter')} r {tool.get('corner_radius')}", tp["points"],
                f"{tp['feed'][0]:g}..{tp['feed'][1]:g}", f"{tp['A_range_deg'][0]:.3f}..{tp['A_range_deg'][1]:.3f}",
                f"{tp['B_range_deg'][0]:.3f}..{tp['B_range_deg'][1]:.3f}", f"{tp['gamma']:.4g}", viol, viol_p,
                tp["singular"]["points"], f"{tp['cycle_time_s']:.2f} ({tp['limiting']})",
                "\u2014" if tp["clearance"] is None else f"{tp['clearance']['min_mm']:.4g}")) + "</tr>")
        head = ("tool path", "tool (mm)", "points", "feed (mm/min)", "A (deg)", "B (deg)", "\u0393",
                "violations, planned law", "violations at the programmed feed", "near singular", "cycle time (s)",
                "min clearance (mm)")
        warn = "".join(f"<li>{html.escape(w)}</li>" for w in doc["warnings"])
        text = ("<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'><title>camsmooth analyze</title></head>"
                f"<body><h1>{html.escape(str(doc['source']))} ({html.escape(doc['format'])}), {doc['points']} "
                "points</h1>" + (f"<ul>{warn}</ul>" if warn else "")
                + "<table border='1' cellpadding='4' style='border-collapse:collapse'><tr>"
                + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>" + "".join(rows) + "</table>"
                + f"<figure>{_img_tag(tmp / AXES_FILE, 'axes')}</figure></body></html>")
        (tmp / HTML_FILE).write_text(text, encoding="utf-8")
    return Path(out_dir)
