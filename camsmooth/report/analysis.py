"""The report of ``camsmooth analyze``: the program as it is, in the style of ``smooth``'s report.

Sections: the verdict (one line per tool path: cycle time, what binds, the limits it breaks),
the per-tool-path table (full operation names; the machine's rotary axes by name: A and B on the
AB head, A and C on an A/C table, B and C on a B/C machine; each violation named by the limit it
breaks, '107 Y travel'), the machine's limits, the rotary axes over the program against those
limits (program_axes.png, embedded) and the setup. Units: mm, s, deg.
"""

from __future__ import annotations

import html
import os
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.io.atomic import atomic_dir
from camsmooth.report.smoothing import _CSS, HTML_FILE, _img_tag, _save_png
from camsmooth.smoothing.analysis import named_violations

__all__ = ["AXES_FILE", "axes_figure", "write_analysis_report"]

AXES_FILE = "program_axes.png"
_COLOURS = ("#1f77b4", "#d62728")


def axes_figure(series: dict[str, np.ndarray], machine: Any) -> Any:
    """The rotary axes of ``machine`` (``machine.rotary``) over the program: angle (deg), velocity
    (deg/s) and acceleration (deg/s^2) against program time at the programmed feed (s, rows
    concatenated); dashed: travel, +-vmax and +-amax from the machine's limits (a continuous axis
    has no travel lines). ``series``: as ProgramAnalysis.series. Returns a matplotlib Figure."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(10, 8), dpi=100)
    axs = fig.subplots(3, 1, sharex=True)
    t = series["t"]
    for ax, key, unit in ((axs[0], "angle", "deg"), (axs[1], "velocity", "deg/s"),
                          (axs[2], "acceleration", "deg/s\u00b2")):
        for name, colour in zip(machine.rotary, _COLOURS, strict=True):
            ax.plot(t, series[f"{name} {key}"], color=colour, linewidth=0.8, label=name)
            lim = machine.limits.get(name)
            if lim is None:
                continue
            lines = {"angle": (lim.min, lim.max), "velocity": (-lim.vmax, lim.vmax),
                     "acceleration": (-lim.amax, lim.amax)}[key]
            for v in lines:
                if np.isfinite(v):
                    ax.axhline(np.degrees(v), color=colour, linestyle="--", linewidth=0.7)
        ax.set_ylabel(f"{key} ({unit})")
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    axs[2].set_xlabel("program time at the programmed feed (s, rows concatenated)")
    fig.suptitle(f"The program as it is: rotary axes {' and '.join(machine.rotary)}; dashed: the machine's limits")
    return fig


def _cell(text: Any, bad: bool = False) -> str:
    cls = " class='bad'" if bad else ""
    return f"<td{cls}>{html.escape(str(text))}</td>"


def _range(r: list[float], spec: str = ".3f") -> str:
    return f"{r[0]:{spec}} .. {r[1]:{spec}}"


def _verdict(doc: dict[str, Any]) -> str:
    """One line per tool path: its cycle time, what binds, and the limits it breaks."""
    items = []
    for tp in doc["toolpaths"]:
        planned = named_violations(tp["violations"])
        at_feed = named_violations(tp.get("violations_programmed", {}))
        cyc = f"cycle time {tp['cycle_time_optimal_s']:.4g} s time-optimal"
        if tp["controller"]:
            cyc += f", {tp['cycle_time_s']:.4g} s on the {tp['controller']} controller"
        binds = f"binds most: {tp['limiting']}" if tp["limiting"] else ""
        viol = ("breaks no limit under the planned law" if planned == "none"
                else f"breaks {planned} under the planned law")
        viol += f"; at the programmed feed: {at_feed}"
        bad = planned != "none"
        text = "; ".join(p for p in (cyc, binds, viol) if p)
        items.append(f"<li class='{'badline' if bad else ''}'><b>{html.escape(tp['name'])}</b>: "
                     f"{html.escape(text)}.</li>")
    return "<ul class='verdict'>" + "".join(items) + "</ul>"


def _toolpath_table(doc: dict[str, Any]) -> str:
    rotary = doc["rotary"]
    head = ["tool path", "tool (mm)", "points", "feed (mm/min)", *(f"{r} (deg)" for r in rotary), "branch", "\u0393",
            "violations, planned law", "violations at the programmed feed", "near the pole", "cycle time (s)",
            "binds most", "min clearance (mm)"]
    out = ["<table class='summary'>", "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    for tp in doc["toolpaths"]:
        tool = tp["tool"] or {}
        planned = named_violations(tp["violations"])
        tool_text = f"D {tool.get('diameter')} r {tool.get('corner_radius')}" if tool else "\u2014"
        cells = [_cell(tp["name"]), _cell(tool_text),
                 _cell(tp["points"]), _cell(_range(tp["feed"], "g")),
                 *(_cell(_range(tp[f"{r}_range_deg"])) for r in rotary), _cell(tp["branch"]),
                 _cell(f"{tp['gamma']:.4g}"), _cell(planned, planned != "none"),
                 _cell(named_violations(tp.get("violations_programmed", {}))),
                 _cell(f"{tp['singular']['points']} points, {tp['singular']['passes']} passes"),
                 _cell(f"{tp['cycle_time_optimal_s']:.2f}" + (f" ({tp['controller']} {tp['cycle_time_s']:.2f})"
                                                               if tp["controller"] else "")),
                 _cell(tp["limiting"] or "\u2014"),
                 _cell("\u2014" if tp["clearance"] is None else f"{tp['clearance']['min_mm']:.4g}",
                       tp["clearance"] is not None and tp["clearance"]["gouges"] > 0)]
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "".join(out)


def _limits_table(doc: dict[str, Any]) -> str:
    """The machine's limits, with the range each tool path reaches beside each travel."""
    def fmt(v: float | None, unit: str) -> str:
        return "none (continuous)" if v is None else f"{v:g} {unit}"

    head = ["axis", "min", "max", "vmax", "amax", "the program reaches", "samples over a limit, planned law"]
    out = ["<table class='summary'>", "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    for axis, lim in doc["limits"].items():
        unit = lim["unit"]
        key = f"{axis}_range_{'deg' if unit == 'deg' else 'mm'}"
        reach = [tp[key] for tp in doc["toolpaths"] if key in tp]
        span = _range([min(r[0] for r in reach), max(r[1] for r in reach)], ".4g") if reach else "\u2014"
        broken = {q: sum(tp["violations"].get(f"{axis} {q}", 0) for tp in doc["toolpaths"])
                  for q in ("travel", "velocity", "acceleration")}
        text = ", ".join(f"{v} {q}" for q, v in broken.items() if v) or "none"
        units = {"min": unit, "max": unit, "vmax": f"{unit}/s", "amax": f"{unit}/s\u00b2"}
        cells = [_cell(axis), *(_cell(fmt(lim[k], units[k])) for k in ("min", "max", "vmax", "amax")),
                 _cell(f"{span} {unit}"), _cell(text, text != "none")]
        out.append("<tr>" + "".join(cells) + "</tr>")
    out.append("</table>")
    return "".join(out)


def write_analysis_report(analysis: Any, series: dict[str, np.ndarray], machine: Any, out_dir: str | os.PathLike,
                          *, replace: bool = False, scene: Any = None) -> Path:
    """Write report.html and its figure into ``out_dir`` (its own files replaced atomically,
    others left alone; ``replace`` replaces the folder). ``analysis``: a ProgramAnalysis;
    ``series``: per point of the program, 't' (s) and '<rotary axis> angle|velocity|acceleration'
    (deg, deg/s, deg/s^2) for the axes of ``machine.rotary``; ``scene``: the program in 3D
    (camsmooth.report.view3d.Scene, interactive in the page), None for none."""
    with atomic_dir(out_dir, replace=replace) as tmp:
        if series:
            _save_png(axes_figure(series, machine), tmp / AXES_FILE)
        doc = analysis.to_json()
        doc.setdefault("rotary", list(machine.rotary))
        names = " and ".join(machine.rotary)
        title = f"camsmooth analyze \u2014 {doc['source']} ({doc['format']}), {doc['points']} points"
        warn = "".join(f"<li>{html.escape(w)}</li>" for w in doc["warnings"])
        sections = [
            ("Verdict", _verdict(doc)),
            ("Tool paths", _toolpath_table(doc)
             + "<p class='small'>Violations are samples over a limit, named by the limit they break (axis and "
               "quantity: travel, velocity, acceleration; interference: a gouge beyond the tolerance). The "
               "planned law is the time-optimal time law under every axis's limits that the program's F words "
               "command; 'at the programmed feed' is the motion before planning. Red cells need attention.</p>"),
            ("Machine limits", _limits_table(doc)),
        ]
        if (tmp / AXES_FILE).exists():
            cap = (f"{names}: angle, velocity and acceleration over the program at the programmed feed; dashed: "
                   "the machine's limits.")
            sections.append((f"Rotary axes {names}", f"<figure>{_img_tag(tmp / AXES_FILE, f'rotary axes {names}')}"
                             f"<figcaption>{html.escape(cap)}</figcaption></figure>"))
        if scene is not None and scene.layers:
            from camsmooth.report.view3d import view3d_html

            sections.append(("Tool paths in 3D", view3d_html(scene)))
        setup = [("program", f"{doc['source']} ({doc['format']})"),
                 ("machine", f"{machine.name} ({machine.kind}; rotary axes {names})")]
        sections.append(("Setup", "<table class='setup'>" + "".join(
            f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>" for k, v in setup) + "</table>"))
        parts = ["<!DOCTYPE html><html lang='en'><head><meta charset='utf-8'>",
                 f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
                 f"<h1>{html.escape(title)}</h1>"]
        if warn:
            parts.append(f"<div class='warn'><ul>{warn}</ul></div>")
        parts += [f"<h2>{k}. {html.escape(head)}</h2>{body}" for k, (head, body) in enumerate(sections, start=1)]
        parts.append("</body></html>")
        (tmp / HTML_FILE).write_text("".join(parts), encoding="utf-8")
    return Path(out_dir)
