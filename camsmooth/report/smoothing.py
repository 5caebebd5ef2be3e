"""HTML report of a smoothing run: plots per method and a summary table.

``write_report`` writes its files into a folder (``camsmooth.io.atomic.atomic_dir``: each file
replaced atomically, other files in the folder left alone) with one PNG per
plot and a self-contained ``report.html`` that embeds the same PNGs as base64 data URIs, so
the HTML alone still shows everything when moved.

Plots use matplotlib's object API (``matplotlib.figure.Figure`` and the Agg canvas), never
pyplot, so the report neither needs a display nor changes the caller's backend. Multi-row
programs are plotted against cumulative program time (rows concatenated, row starts marked by
faint vertical lines). Series longer than ``max_plot_points`` are decimated to a min/max
envelope per bin (peaks kept); the figure says so.

The 3D view is rendered with pyvista in a child process: VTK aborts the whole process when it
finds no OpenGL context (no X server, no EGL, no OSMesa), so rendering in-process could kill the
caller. If the child fails the report carries a note instead of the image. Headless Linux works
without a virtual framebuffer when VTK >= 9.4 (runtime OpenGL selection: X, then EGL, then
OSMesa) finds an EGL (e.g. Mesa surfaceless/llvmpipe) or OSMesa library.
"""

from __future__ import annotations

import base64
import html
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth import __version__
from camsmooth.io.atomic import atomic_dir
from camsmooth.machine.axes import PerAxis
from camsmooth.smoothing.finish import effective_radius
from camsmooth.smoothing.result import MethodResult, Metrics, SmoothResult

#: PNG files of a report, in display order (``scene_3d.png`` only when rendering worked).
PLOT_FILES: tuple[str, ...] = ("axes_angles.png", "axes_velocity.png", "axes_acceleration.png",
                               "compound_acceleration.png", "lead_tilt.png", "clearance.png")
SCENE_FILE = "scene_3d.png"
FEED_PLOT = "planned_feed.png"  # camsmooth.report.feed, when the methods carry a planned time law
HTML_FILE = "report.html"
#: Clearance drawn as the gouge line when the result names no tolerance (mm, negative).
CLEARANCE_TOL_MM = -1e-3


def _gouge_line(result_or_metrics: SmoothResult | Metrics | None) -> float:
    """-tolerance (mm) of the smoothing that made the result, CLEARANCE_TOL_MM if unknown."""
    if isinstance(result_or_metrics, Metrics):
        tol = result_or_metrics.tolerance_mm
    else:
        tol = getattr(result_or_metrics, "inputs", {}).get("tolerance")
    return -float(tol) if tol else CLEARANCE_TOL_MM

_METHOD_ORDER = ("cam", "none", "spline", "nlp")
_METHOD_COLOURS = {"cam": "#2ca02c", "none": "#7f7f7f", "spline": "#1f77b4", "nlp": "#d62728"}
_EXTRA_COLOURS = ("#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22")
_LIMIT_COLOUR = "#ff7f0e"
_DPI = 100
_RENDER_TIMEOUT_S = 120.0


# ----------------------------------------------------------------------------------------------
# series preparation
@dataclass
class _Series:
    """One method's data laid out for plotting: cumulative time (the planned time law t_plan when
    the method has one, else the programmed-feed time), row breaks, decimation, and the rates of
    a quantity under that time law."""

    m: MethodResult
    t: np.ndarray          # cumulative program time (s)
    starts: np.ndarray     # index of each row's first point
    max_points: int
    primary: bool = False
    row_t: np.ndarray | None = None  # s from each row's start under the time law plotted

    @property
    def planned(self) -> bool:
        return self.m.plan is not None

    def rates(self, q: np.ndarray) -> Any:
        """Velocity and acceleration of q (N or (N, k)) under the plotted time law
        (camsmooth.smoothing.nlp.program_rates)."""
        from camsmooth.smoothing.nlp import program_rates

        return program_rates(np.asarray(q, float), self.row_t if self.row_t is not None else self.m.t, self.m.rows)

    @property
    def decimated(self) -> bool:
        return len(self.t) > self.max_points

    def row_start_times(self) -> np.ndarray:
        return self.t[self.starts]

    def line(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) for a line plot: NaN-broken between rows, min/max envelope when decimated."""
        return _line_xy(self.t, _finite(y), self.starts, self.max_points)

    def band(self, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(x, lo, hi) for fill_between: per bin the lowest lo and highest hi when decimated."""
        return _band_xy(self.t, _finite(lo), _finite(hi), self.starts, self.max_points)


def _finite(y: np.ndarray) -> np.ndarray:
    """Float copy with inf (e.g. an unbounded window, no mesh in reach) as NaN: a gap, not a
    broken autoscale."""
    y = np.array(y, dtype=float)
    y[~np.isfinite(y)] = np.nan
    return y


def _row_starts(rows: np.ndarray) -> np.ndarray:
    rows = np.asarray(rows)
    if len(rows) == 0:
        return np.zeros(0, dtype=int)
    return np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])


def cumulative_time(t: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """Program time (s) over all rows: each row's time ``t`` (0 at its first point) is shifted
    so the row starts where the previous row ended (rows contiguous, in path order)."""
    t = np.asarray(t, dtype=float)
    starts = _row_starts(rows)
    if len(t) == 0:
        return t.copy()
    ends = np.r_[starts[1:], len(t)] - 1
    t0 = t[starts]
    duration = np.nan_to_num(t[ends] - t0)
    offset = np.r_[0.0, np.cumsum(duration)[:-1]] - t0
    return t + np.repeat(offset, np.diff(np.r_[starts, len(t)]))


def _bins(starts: np.ndarray, n: int, max_points: int) -> np.ndarray:
    """Start index of each decimation bin; bins never cross a row start."""
    width = max(1, int(np.ceil(2 * n / max(max_points, 2))))
    local = np.arange(n) - np.repeat(starts, np.diff(np.r_[starts, n]))
    return np.flatnonzero(local % width == 0)


def _break_rows(x: np.ndarray, ys: Sequence[np.ndarray], breaks: np.ndarray) -> list[np.ndarray]:
    """Insert NaN before each break index so lines are not drawn across row starts."""
    return [np.insert(np.asarray(a, float), breaks, np.nan) for a in (x, *ys)]


def _line_xy(t: np.ndarray, y: np.ndarray, starts: np.ndarray, max_points: int
             ) -> tuple[np.ndarray, np.ndarray]:
    n = len(t)
    if n <= max_points:
        x, yy = _break_rows(t, [y], starts[1:])
        return x, yy
    b = _bins(starts, n, max_points)
    ymin = np.fmin.reduceat(y, b)
    ymax = np.fmax.reduceat(y, b)
    tmid = 0.5 * (t[b] + t[np.r_[b[1:], n] - 1])
    x = np.repeat(tmid, 2)
    yy = np.column_stack([ymin, ymax]).ravel()
    row_break = np.flatnonzero(np.isin(b, starts[1:]))
    x, yy = _break_rows(x, [yy], 2 * row_break)
    return x, yy


def _band_xy(t: np.ndarray, lo: np.ndarray, hi: np.ndarray, starts: np.ndarray, max_points: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    n = len(t)
    if n <= max_points:
        return tuple(_break_rows(t, [lo, hi], starts[1:]))  # type: ignore[return-value]
    b = _bins(starts, n, max_points)
    stop = np.r_[b[1:], n] - 1
    x = np.column_stack([t[b], t[stop]]).ravel()
    lo_b = np.repeat(np.fmin.reduceat(lo, b), 2)
    hi_b = np.repeat(np.fmax.reduceat(hi, b), 2)
    row_break = np.flatnonzero(np.isin(b, starts[1:]))
    return tuple(_break_rows(x, [lo_b, hi_b], 2 * row_break))  # type: ignore[return-value]


def _ordered_methods(result: SmoothResult) -> list[str]:
    known = [m for m in _METHOD_ORDER if m in result.methods]
    return known + [m for m in result.methods if m not in known]


def _colour(method: str, order: list[str]) -> str:
    if method in _METHOD_COLOURS:
        return _METHOD_COLOURS[method]
    extras = [m for m in order if m not in _METHOD_COLOURS]
    return _EXTRA_COLOURS[extras.index(method) % len(_EXTRA_COLOURS)]


# ----------------------------------------------------------------------------------------------
# figures
def _figure(nrows: int, ncols: int, title: str, height_per_row: float = 2.6, width: float | None = None,
            sharey: bool | str = False):
    from matplotlib.figure import Figure

    width = width or max(6.0, 4.6 * ncols)
    fig = Figure(figsize=(width, 0.6 + height_per_row * nrows), dpi=_DPI, layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False, sharex="col", sharey=sharey)
    fig.suptitle(title, fontsize=11)
    return fig, axes


def _mark_rows(ax, s: _Series) -> None:
    starts = s.row_start_times()
    if len(starts) > 1:
        ax.vlines(starts[1:], 0, 1, transform=ax.get_xaxis_transform(), colors="0.6", linewidths=0.5,
                  alpha=0.35, zorder=0)


def _limit_lines(ax, values: Sequence[float], label: str, data: np.ndarray, always: bool) -> None:
    """Horizontal limit lines. ``always``: widen the view to show them. Otherwise (travel limits
    far from the data) they are drawn only when near the data and named in a corner note, so a
    few degrees of motion are not flattened against a +-100 deg travel."""
    values = [float(v) for v in values if np.isfinite(v)]
    if not values:
        return
    finite = data[np.isfinite(data)]
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 0.0)
    span = max(hi - lo, 1e-9)
    near = [v for v in values if lo - 1.5 * span <= v <= hi + 1.5 * span]
    shown = values if always else near
    for v in shown:
        ax.axhline(v, color=_LIMIT_COLOUR, linestyle="--", linewidth=1.0, zorder=1)
    if len(shown) < len(values):
        ax.text(0.99, 0.02, f"{label} {', '.join(f'{v:g}' for v in values)} (off scale)",
                transform=ax.transAxes, ha="right", va="bottom", fontsize=7, color=_LIMIT_COLOUR)
    elif shown:
        ax.plot([], [], color=_LIMIT_COLOUR, linestyle="--", linewidth=1.0, label=label)


def _axis_limits(machine: Any, name: str) -> Any:
    limits = getattr(machine, "limits", None) or {}
    return limits.get(name)


def _decimation_note(series: Sequence[_Series]) -> str:
    dec = [s for s in series if s.decimated]
    if not dec:
        return ""
    n = max(len(s.t) for s in dec)
    return f" [decimated: {n} points shown as min/max per bin, about {dec[0].max_points} drawn]"


def _plot_axes(series: list[_Series], colours: dict[str, str], machine: Any, quantity: str) -> Any:
    """The two rotary axes per method (columns): angle, velocity or acceleration with its limits,
    labelled and limited by the names the results carry (the machine's: A and C on an AC table)."""
    r1, r2 = series[0].m.rotary.names
    spec = {
        "angle": (r1, r2, "deg", "travel", lambda m, ax: m.rotary[ax]),
        "velocity": (f"{r1}'", f"{r2}'", "deg/s", "\u00b1vmax", lambda m, ax: m.rotary_vel[ax]),
        "acceleration": (f"{r1}''", f"{r2}''", "deg/s\u00b2", "\u00b1amax", lambda m, ax: m.rotary_acc[ax]),
    }[quantity]
    lab_a, lab_b, unit, limit_label, get = spec
    title = f"Rotary axes: {quantity} per method ({unit}){_decimation_note(series)}"
    fig, axes = _figure(2, len(series), title, sharey="row")
    # one scale per axis across the methods: the travel lines are drawn for all or for none
    union = {ax_: np.degrees(np.concatenate([np.asarray(s.m.rotary[ax_], float) for s in series]))
             for ax_ in (r1, r2)}
    for c, s in enumerate(series):
        for r_, (axis_name, lab) in enumerate(((r1, lab_a), (r2, lab_b))):
            ax = axes[r_, c]
            q = np.asarray(s.m.rotary[axis_name], dtype=float)
            if quantity == "angle":
                y = np.degrees(q)
            elif s.planned:  # under the planned time law, the one the program's F words command
                rq = s.rates(q)
                y = np.degrees(rq.vel if quantity == "velocity" else rq.acc)
            else:
                y = np.degrees(np.asarray(get(s.m, axis_name), dtype=float))
            x, yy = s.line(y)
            ax.plot(x, yy, color=colours[s.m.method], linewidth=0.9, label=s.m.method)
            lim = _axis_limits(machine, axis_name)
            if lim is not None:
                if quantity == "angle":
                    if np.isfinite(lim.max - lim.min):  # a continuous C has no travel to draw
                        _limit_lines(ax, np.degrees([lim.min, lim.max]), "travel", union[axis_name],
                                     always=False)
                else:
                    vmax = lim.vmax if quantity == "velocity" else lim.amax
                    if np.isfinite(vmax):
                        v = float(np.degrees(vmax))
                        _limit_lines(ax, [-v, v], limit_label, y, always=True)
            _mark_rows(ax, s)
            ax.grid(True, alpha=0.3)
            ax.set_ylabel(f"{lab} ({unit})")
            if r_ == 0:
                ax.set_title(s.m.method + (" (primary)" if s.primary else ""), fontsize=10)
            if r_ == 1:
                ax.set_xlabel(_time_label(s))
            ax.legend(loc="upper right", fontsize=7)
    return fig


def _time_label(s: _Series) -> str:
    return "planned time t_plan (s)" if s.planned else "time at the programmed feed (s)"


def _plot_compound(series: list[_Series], colours: dict[str, str]) -> Any:
    fig, axes = _figure(1, 1, "Compound angular acceleration |T''| of the tool axis (1/s\u00b2, log scale)"
                        + _decimation_note(series), height_per_row=3.6, width=max(9.0, 4.6 * len(series)))
    ax = axes[0, 0]
    positive = False
    for s in series:
        y = (np.linalg.norm(s.rates(s.m.axis).acc, axis=1) if s.planned
             else np.abs(np.asarray(s.m.compound_acc, dtype=float)))
        any_positive = bool(np.any(y > 0))
        positive |= any_positive
        x, yy = s.line(np.where(y > 0, y, np.nan))
        label = s.m.method if any_positive else f"{s.m.method} (zero everywhere, not drawn)"
        ax.plot(x, yy, color=colours[s.m.method], linewidth=0.9, label=label)
    if positive:
        ax.set_yscale("log")
    else:
        ax.text(0.5, 0.5, "|T''| is zero everywhere", transform=ax.transAxes, ha="center")
    if series:
        _mark_rows(ax, series[0])
    ax.grid(True, which="both", alpha=0.3)
    ax.set_xlabel(_time_label(series[0]) if series else "time (s)")
    ax.set_ylabel("|T''| (1/s\u00b2)")
    ax.legend(loc="upper right", fontsize=8)
    return fig


def _plot_lead_tilt(series: list[_Series], colours: dict[str, str]) -> Any:
    fig, axes = _figure(2, len(series), "Lead and tilt (deg) within their per-point windows (shaded)"
                        + _decimation_note(series), sharey="row")
    for c, s in enumerate(series):
        for r_, (name, window) in enumerate((("lead", s.m.lead_window), ("tilt", s.m.tilt_window))):
            ax = axes[r_, c]
            w = np.degrees(np.asarray(window, dtype=float).reshape(-1, 2))
            xb, lo, hi = s.band(w[:, 0], w[:, 1])
            ax.fill_between(xb, lo, hi, color="0.75", alpha=0.6, linewidth=0, label="window")
            y = np.degrees(np.asarray(getattr(s.m, name), dtype=float))
            x, yy = s.line(y)
            ax.plot(x, yy, color=colours[s.m.method], linewidth=0.9, label=name)
            clear = getattr(s.m, "lead_clear", None)
            if name == "lead" and clear is not None and np.isfinite(clear[:, 0]).any():
                xf, yf = s.line(np.degrees(clear[:, 0]))
                ax.plot(xf, yf, color=_LIMIT_COLOUR, linewidth=0.8, linestyle="--",
                        label="clear floor (accessibility map)")
            with np.errstate(invalid="ignore"):
                out = (y < w[:, 0] - 1e-9) | (y > w[:, 1] + 1e-9)
            if out.any():
                ax.plot(s.t[out], y[out], "x", color="k", markersize=3, label=f"outside ({int(out.sum())})")
            _mark_rows(ax, s)
            ax.grid(True, alpha=0.3)
            ax.set_ylabel(f"{name} (deg)")
            if r_ == 0:
                ax.set_title(s.m.method, fontsize=10)
            else:
                ax.set_xlabel(_time_label(s))
            ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12 if r_ == 0 else -0.28), ncol=3, fontsize=7,
                      frameon=False)
    return fig


def _plot_clearance(series: list[_Series], colours: dict[str, str], line: float = CLEARANCE_TOL_MM) -> Any:
    """Clearance per method in micrometres, scaled to the data (the same scale for every method);
    the gouge line -tolerance drawn when it lies near the data, else named in a corner note;
    legends below the panels, never over the line."""
    fig, axes = _figure(1, len(series), "Clearance \u03b4 tool to surface (\u00b5m); gouge below "
                        f"{1e3 * line:.4g} \u00b5m" + _decimation_note(series), height_per_row=3.4, sharey="row")
    um = [1e3 * np.asarray(s.m.delta, dtype=float) for s in series]
    finite = np.concatenate([d[np.isfinite(d)] for d in um]) if um else np.zeros(0)
    lo, hi = (float(finite.min()), float(finite.max())) if finite.size else (-1.0, 1.0)
    span = max(hi - lo, 1e-3)
    tol_um = 1e3 * line
    show_line = lo - 0.5 * span <= tol_um
    for c, (s, d) in enumerate(zip(series, um, strict=True)):
        ax = axes[0, c]
        x, yy = s.line(d)
        ax.plot(x, yy, color=colours[s.m.method], linewidth=0.9, label="\u03b4")
        ax.axhline(0.0, color="k", linewidth=0.6, alpha=0.6)
        if show_line:
            ax.axhline(tol_um, color="#d62728", linestyle="--", linewidth=0.9, label=f"-tolerance {tol_um:.4g} \u00b5m")
        else:
            ax.text(0.99, 0.02, f"gouge line {tol_um:.4g} \u00b5m (off scale, below)", transform=ax.transAxes,
                    ha="right", va="bottom", fontsize=7, color="#d62728")
        with np.errstate(invalid="ignore"):
            bad = d < tol_um
        if bad.any():
            ax.plot(s.t[bad], d[bad], ".", color="#d62728", markersize=3, label=f"gouge ({int(bad.sum())})")
        k = int(np.nanargmin(d)) if np.isfinite(d).any() else None
        if k is not None:
            ax.plot([s.t[k]], [d[k]], "v", color="k", markersize=5,
                    label=f"worst {d[k]:.3g} \u00b5m (row {int(s.m.rows[k])}, point {int(s.m.idx[k])})")
        _mark_rows(ax, s)
        ax.grid(True, alpha=0.3)
        ax.set_ylim(lo - 0.1 * span if not show_line else min(lo, tol_um) - 0.1 * span, hi + 0.1 * span)
        ax.set_title(s.m.method, fontsize=10)
        ax.set_xlabel(_time_label(s))
        ax.set_ylabel("\u03b4 (\u00b5m)")
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.22), ncol=2, fontsize=7, frameon=False)
    return fig


def _save_png(fig: Any, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.savefig(path, format="png", dpi=_DPI)


# ----------------------------------------------------------------------------------------------
# 3D scene (child process)
def _axis_segments(m: MethodResult, length: float, max_segments: int) -> np.ndarray:
    """(K, 2, 3) segments from the CL point along the tool axis, every step-th point."""
    cl = np.asarray(m.cl, dtype=float).reshape(-1, 3)
    T = np.asarray(m.axis, dtype=float).reshape(-1, 3)
    step = max(1, int(np.ceil(len(cl) / max(max_segments, 1))))
    keep = np.arange(0, len(cl), step)
    ok = np.isfinite(cl[keep]).all(axis=1) & np.isfinite(T[keep]).all(axis=1)
    keep = keep[ok]
    return np.stack([cl[keep], cl[keep] + length * T[keep]], axis=1)


def _scene_inputs(result: SmoothResult, max_segments: int) -> tuple[dict[str, np.ndarray], str]:
    before = result.methods.get("none")
    after = result.result
    pts = [np.asarray(after.cl, float).reshape(-1, 3)]
    from camsmooth.report.view3d import mesh_arrays  # the one mesh converter of the reports

    mesh = mesh_arrays(result.surface_mesh)
    if mesh is not None:
        pts.append(mesh[0])
    allp = np.concatenate(pts)
    allp = allp[np.isfinite(allp).all(axis=1)]
    diag = float(np.linalg.norm(np.ptp(allp, axis=0))) if len(allp) else 1.0
    length = 0.08 * diag if diag > 0 else 1.0
    data: dict[str, np.ndarray] = {
        "after": _axis_segments(after, length, max_segments),
        "after_label": np.array(f"after: {after.method}"),
        "path": np.asarray(after.cl, float).reshape(-1, 3),
        "path_breaks": _row_starts(after.rows),
    }
    if before is not None and before is not after:
        data["before"] = _axis_segments(before, length, max_segments)
        data["before_label"] = np.array("before: none")
    if mesh is not None:
        data["vertices"], data["faces"] = mesh
    step = max(1, int(np.ceil(len(after) / max(max_segments, 1))))
    which = "at every point" if step == 1 else f"at every {step}th point (subsampled)"
    note = f"Tool axes drawn as {length:.3g} mm segments from the tool tip {which}."
    if mesh is None:
        note += " No surface mesh in the result: axes only."
    return data, note


def render_scene_main(argv: Sequence[str]) -> int:
    """Child-process entry: render ``argv[0]`` (npz from ``_scene_inputs``) to PNG ``argv[1]``.

    Kept importable and separate so a VTK abort cannot take the caller down with it.
    """
    import pyvista as pv

    pv.OFF_SCREEN = True
    src, dst = argv[0], argv[1]
    with np.load(src) as z:
        d = {k: z[k] for k in z.files}
    width, height = 1200, 900
    pl = pv.Plotter(off_screen=True, window_size=(width, height))
    pl.set_background("white")
    if "vertices" in d:
        faces = np.column_stack([np.full(len(d["faces"]), 3), d["faces"]]).ravel()
        pl.add_mesh(pv.PolyData(d["vertices"], faces), color="#d9d9d9", smooth_shading=True, specular=0.2)
    path = d["path"]
    legend = []
    if len(path) > 1:
        seg = np.stack([path[:-1], path[1:]], axis=1)
        seg = np.delete(seg, d["path_breaks"][1:] - 1, axis=0)
        seg = seg[np.isfinite(seg).all(axis=(1, 2))]
        if len(seg):
            pl.add_mesh(pv.line_segments_from_points(seg.reshape(-1, 3)), color="#555555", line_width=1)
            legend.append(("tool-tip path", "#555555"))
    for key, colour, width in (("before", "#7f7f7f", 2), ("after", "#d62728", 3)):
        if key in d and len(d[key]):
            pl.add_mesh(pv.line_segments_from_points(d[key].reshape(-1, 3)), color=colour, line_width=width)
            legend.append((f"{d[f'{key}_label']} (tool axes)", colour))
    # legend as coloured text lines: VTK's legend box scales text to its height and overflows
    # the window sideways for longer labels
    for k, (label, colour) in enumerate(legend):
        pl.add_text(f"\u2014 {label}", position=(20, height - 40 - 30 * k), font_size=14, color=colour)
    pl.view_isometric()
    pl.camera.zoom(1.25)
    pl.add_axes()
    pl.screenshot(dst)
    pl.close()
    return 0


def _start_render(npz: Path, png: Path) -> subprocess.Popen:
    pkg_parent = str(Path(__file__).resolve().parents[2])
    env = dict(os.environ)
    env["PYTHONPATH"] = pkg_parent + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    code = ("import sys; from camsmooth.report.smoothing import render_scene_main; "
            "sys.exit(render_scene_main(sys.argv[1:]))")
    return subprocess.Popen([sys.executable, "-c", code, str(npz), str(png)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish_render(proc: subprocess.Popen, png: Path, timeout: float) -> str | None:
    """None when ``png`` holds a real image, else the reason it does not."""
    try:
        _, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return f"the renderer did not finish within {timeout:g} s"
    if proc.returncode != 0:
        tail = [ln for ln in (err or "").strip().splitlines() if ln.strip()][-4:]
        rc = proc.returncode
        how = f"killed by signal {-rc}" if rc < 0 else f"exit code {rc}"
        return f"the pyvista/VTK renderer failed ({how}): " + (" | ".join(tail) or "no message")
    if not png.exists() or png.stat().st_size == 0:
        return "the renderer wrote no image"
    from matplotlib.image import imread

    img = imread(png)
    if img.ndim < 2 or float(np.ptp(img[..., :3])) == 0.0:
        png.unlink()
        return "the renderer produced a blank image (OpenGL context without working rasteriser)"
    return None


# ----------------------------------------------------------------------------------------------
# HTML
def _fmt(v: Any, spec: str = ".4g") -> str:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return "\u2014"
    return "\u2014" if np.isnan(f) else format(f, spec)


def method_summary(m: MethodResult) -> dict[str, Any]:
    """Table values for one method, in report units: gamma, the peak |q''| of each rotary axis
    (deg/s^2; "peak_acc_deg" at the programmed feed, "peak_acc_plan" under the planned law, PerAxis
    named by the machine's axes), min delta (mm), violations (name -> count), unclean rows (list), unreachable (list of
    (row, idx)), runtime (s). Taken from ``m.metrics`` (peak accelerations there are deg/s^2);
    what the metrics lack is computed from the arrays (gamma and runtime become NaN)."""
    mt = m.metrics

    def peak(arr: np.ndarray) -> float:
        a = np.abs(np.asarray(arr, dtype=float))
        return float(np.degrees(np.nanmax(a))) if a.size and np.isfinite(a).any() else float("nan")

    d = np.asarray(m.delta, dtype=float)
    min_delta = mt.min_delta if mt is not None else None
    if min_delta is None:
        min_delta = float(np.nanmin(d)) if d.size and np.isfinite(d).any() else float("nan")
    nan = float("nan")
    return {
        "gamma": float(mt.gamma) if mt is not None else nan,
        "peak_acc_deg": (mt.peak_acc if mt is not None
                         else PerAxis(m.rotary_acc.names, tuple(peak(a) for _, a in m.rotary_acc.items()))),
        "min_delta": float(min_delta),
        "violations": dict(mt.violations) if mt is not None else {},
        "unclean_rows": [int(r) for r in mt.unclean_rows] if mt is not None else [],
        "unreachable": [tuple(int(v) for v in p) for p in mt.unreachable] if mt is not None else [],
        "runtime_s": float(mt.runtime_s) if mt is not None else nan,
        "cycle_time_s": float(mt.cycle_time_s) if mt is not None else nan,
        "cycle_time_optimal_s": float(mt.cycle_time_optimal_s) if mt is not None else nan,
        "controller": mt.controller if mt is not None else "",
        "controller_deviation_mm": (float(mt.controller_deviation_mm) if mt is not None
                                    and mt.controller_deviation_mm is not None else nan),
        "controller_floor_s": (float(mt.controller_floor_s) if mt is not None
                               and mt.controller_floor_s is not None else nan),
        "end_offset_mm": float(getattr(mt, "controller_end_offset_mm", 0.0) or 0.0) if mt is not None else 0.0,
        "modes_line": _modes_line(mt),
        "feed_peak": getattr(mt, "controller_feed_peak", None) if mt is not None else None,
        "violations_programmed": dict(mt.violations_programmed) if mt is not None else {},
        "peak_acc_plan": mt.peak_acc_plan if mt is not None else PerAxis.nan(m.rotary.names),
        "planned": m.plan is not None,
        "binding_share": _binding_share(m),
        "worst": _worst_point(m),
        "gouge_line": _gouge_line(mt),
        "limiting": mt.limiting if mt is not None else "",
        "mapped_points": mt.mapped_points if mt is not None else None,
        "scallop_max_um": mt.scallop_max_um if mt is not None else None,
        "scallop_budget_um": mt.scallop_budget_um if mt is not None else None,
        "scallop_missed": list(mt.scallop_missed) if mt is not None else [],
        "lifted_beyond_tolerance": mt.lifted_beyond_tolerance if mt is not None else 0,
        "blocked": list(mt.blocked) if mt is not None else [],
        "unreachable_clear": list(mt.unreachable_clear) if mt is not None else [],
        "points": len(m),
        "rows": int(len(_row_starts(m.rows))),
        "model": {k: getattr(mt, k) for k in ("tip_error_um_max", "tip_error_um_max_uncompensated",
                                               "axis_error_urad_max") if mt is not None and getattr(mt, k) is not None},
    }


def _short_list(items: Sequence[Any], limit: int = 60) -> str:
    txt = ", ".join(str(i) for i in items[:limit])
    return txt + (f", \u2026 and {len(items) - limit} more" if len(items) > limit else "")


def _binding_share(m: MethodResult) -> float:
    """Share (0-1) of the planned law's time during which its most binding constraint binds."""
    plan = m.plan
    if plan is None:
        return float("nan")
    lt = np.asarray(plan.limit_time, float)
    return float(lt.max() / lt.sum()) if lt.size and lt.sum() > 0 else float("nan")


def _worst_point(m: MethodResult) -> tuple[float, int, int] | None:
    """(clearance mm, row, point) of the smallest clearance, None when none is known."""
    d = np.asarray(m.delta, float)
    if not d.size or not np.isfinite(d).any():
        return None
    k = int(np.nanargmin(d))
    return float(d[k]), int(m.rows[k]), int(m.idx[k])


def _total(counts: dict[str, int]) -> tuple[int, str]:
    """Total of the counts and the non-zero ones named ('B acceleration 3, interference 1')."""
    named = [f"{k} {v}" for k, v in counts.items() if v]
    return int(sum(counts.values())), ", ".join(named)


def _clearance_text(worst: tuple[float, int, int] | None) -> str:
    if worst is None:
        return "clearance not known"
    d, row, idx = worst
    return f"worst clearance {1e3 * d:.3g} \u00b5m at row {row}, point {idx}"


def _named(text: str, rotary: Sequence[str]) -> str:
    """Text about "A and B" (the results' first and second rotary axis) with the machine's names."""
    r1, r2 = rotary
    for a, b in (("A'' and B''", f"{r1}'' and {r2}''"), ("A' and B'", f"{r1}' and {r2}'"),
                 ("A and B", f"{r1} and {r2}"), ("|A''| / |B''|", f"|{r1}''| / |{r2}''|")):
        text = text.replace(a, b)
    return text


def _modes_line(mt: Any) -> str:
    """Both LinuxCNC modes and which runs the program faster (camsmooth.controller.mode_text), ''
    where only one mode is modelled."""
    from camsmooth.controller import mode_text

    if mt is None or getattr(mt, "tcp_cycle_time_s", None) is None or mt.machine_cycle_time_s is None:
        return ""
    return mode_text(mt.tcp_cycle_time_s, mt.tcp_floor_s, mt.machine_cycle_time_s, mt.machine_floor_s,
                     bool(mt.tcp_within_limits))


def _verdict_html(order: list[str], summaries: dict[str, dict[str, Any]], primary: str,
                  rotary: Sequence[str] = ("A", "B")) -> str:
    """One line per method, primary first: the answers a CAM programmer looks for first."""
    from camsmooth.controller import floor_text

    items = []
    for name in sorted(order, key=lambda n: n != primary):
        s = summaries[name]
        tag = html.escape(name) + (" (primary)" if name == primary else "")
        cyc = f"cycle time {_fmt(s['cycle_time_optimal_s'], '.4g')} s time-optimal"
        if s["controller"]:
            cyc += f", {_fmt(s['cycle_time_s'], '.4g')} s on the {html.escape(s['controller'])} controller"
            if np.isfinite(s["controller_deviation_mm"]):
                cyc += f" (tool tip within {_fmt(1e3 * s['controller_deviation_mm'], '.3g')} \u00b5m of the path)"
            fp = s.get("feed_peak")
            if fp is not None:
                cyc += (f"; its blends take the tool tip to {_fmt(fp.ratio, '.3g')} of the programmed feed (row "
                        f"{fp.row}; {fp.rows} row{'s' * (fp.rows > 1)} past it; smooth --hold-feed holds it)")
            if np.isfinite(s["controller_floor_s"]):
                floor = floor_text(s['controller'], s['controller_floor_s'], s['cycle_time_s'], s['end_offset_mm'])
                cyc += f"; {html.escape(floor)}"
            if s.get("modes_line"):
                cyc += f"; {html.escape(s['modes_line'])}"
        share = s["binding_share"]
        where = " in the time-optimal law" if s["controller"] else ""
        binds = (f"binds most{where}: {html.escape(s['limiting'])}"
                 + (f" ({100 * share:.0f}% of the time)" if np.isfinite(share) else "")) if s["limiting"] else ""
        law = "under the planned law" if s["planned"] else "at the programmed feed"
        pk = s["peak_acc_plan"] if s["planned"] else s["peak_acc_deg"]
        peaks = f"peak {pk.names[1]}'' {_fmt(pk[1], '.4g')} and {pk.names[0]}'' {_fmt(pk[0], '.4g')} deg/s\u00b2 {law}"
        total, named = _total(s["violations"])
        viol = f"{total} violation{'s' * (total != 1)} {law}" + (f" ({html.escape(named)})" if named else "")
        if s["planned"]:
            tp, _ = _total(s["violations_programmed"])
            viol += f"; {tp} at the programmed feed"
        bad = total > 0 or (s["worst"] is not None and s["worst"][0] < s["gouge_line"])
        finish = ""
        if s["scallop_max_um"] is not None:
            finish = (f"largest scallop {_fmt(s['scallop_max_um'], '.3g')} \u00b5m" if np.isfinite(s["scallop_max_um"])
                      else "adjacent passes that do not overlap somewhere (the effective radius below half the "
                      "stepover: no finite scallop)")
            if s["scallop_missed"]:
                k = len(s["scallop_missed"])
                finish += f" (finish budget missed on {k} row{'s' * (k > 1)})"
                bad = True
            elif s["scallop_budget_um"] is not None:
                finish += " (within the finish budget)"
        parts = [p for p in (cyc, binds, peaks, finish, viol, html.escape(_clearance_text(s["worst"]))) if p]
        items.append(f"<li class='{'badline' if bad else ''}'><b>{tag}</b>: " + "; ".join(parts) + ".</li>")
    return "<ul class='verdict'>" + "".join(items) + "</ul>"


def _summary_table(order: list[str], summaries: dict[str, dict[str, Any]], primary: str,
                   rotary: Sequence[str] = ("A", "B")) -> str:
    """At most ten columns: the per-axis violation counts collapsed into one total with the
    non-zero ones named."""
    any_ctrl = any(summaries[n]["controller"] for n in order)
    ctrl_name = next((summaries[n]["controller"] for n in order if summaries[n]["controller"]), "")
    head = ["method", "points / rows", "\u0393 (1/s\u2074)", "cycle time optimal (s)"]
    if any_ctrl:
        head.append(f"cycle time {ctrl_name} (s)")
    head += ["binds most (time-optimal law)" if any_ctrl else "binds most",
             _named("peak |A''| / |B''| (deg/s\u00b2)", rotary),
             "violations, planned law",
             "violations at the programmed feed", "min \u03b4 (\u00b5m)"]
    if not any_ctrl:
        head.append("run time (s)")
    with_model = any(summaries[n].get("model") for n in order)
    if with_model:  # ideal against predicted-real (error model given)
        head += ["real tip error, as commanded (\u00b5m)", "real tip error, uncompensated (\u00b5m)",
                 "real axis vs ideal (\u00b5rad)"]
    out = ["<table class='summary'>", "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    for name in order:
        s = summaries[name]
        bad_delta = bool(np.isfinite(s["min_delta"]) and s["min_delta"] < s["gouge_line"])
        planned = s["planned"]
        pa, pb = (s["peak_acc_plan"] if planned else s["peak_acc_deg"]).values
        total, named = _total(s["violations"])
        total_p, named_p = _total(s["violations_programmed"] or s["violations"])
        cells = [(html.escape(name) + (" <b>(primary)</b>" if name == primary else ""), False),
                 (f"{s['points']} / {s['rows']}", False), (_fmt(s["gamma"]), False),
                 (_fmt(s["cycle_time_optimal_s"] if planned else s["cycle_time_s"], ".5g"), False)]
        if any_ctrl:
            cells.append((_fmt(s["cycle_time_s"], ".5g") if s["controller"] else "\u2014", False))
        cells += [(html.escape(s["limiting"] or "\u2014"), False), (f"{_fmt(pa)} / {_fmt(pb)}", False),
                  (str(total) + (f" <small>({html.escape(named)})</small>" if named else ""), bool(total)),
                  (str(total_p) + (f" <small>({html.escape(named_p)})</small>" if named_p else ""), False),
                  (_fmt(1e3 * s["min_delta"], ".3g"), bad_delta)]
        if not any_ctrl:
            cells.append((_fmt(s["runtime_s"], ".3g"), False))
        if with_model:
            md = s.get("model") or {}
            cells += [(_fmt(md.get(k, float("nan")), ".3g"), False)
                      for k in ("tip_error_um_max", "tip_error_um_max_uncompensated", "axis_error_urad_max")]
        tds = "".join(f"<td class='{'bad' if bad else ''}'>{c}</td>" for c, bad in cells)
        out.append(f"<tr>{tds}</tr>")
    out.append("</table>")
    return "\n".join(out)


#: most rows the per-row table lists (the slowest are kept beyond it)
MAX_TABLE_ROWS = 60


def _ends_within(mt: Any) -> str:
    """', ends within E um of the points' where the program's block ends sit off them (E: Metrics.
    controller_end_offset_mm), '' where they end on them."""
    off = float(getattr(mt, "controller_end_offset_mm", 0.0) or 0.0)
    return f", ends within {1e3 * off:.2g} \u00b5m of the points" if off > 0 else ""


def _rows_html(m: MethodResult, rotary: Sequence[str] = ("A", "B")) -> str:
    """Per row of one method: points, cycle time (time-optimal, controller's), peak rates of the
    rotary axes (named ``rotary``) under the planned law (deg/s, deg/s^2) and the smallest
    clearance (um) with its point."""
    from camsmooth.smoothing.nlp import program_rates

    starts = _row_starts(m.rows)
    ends = np.r_[starts[1:], len(m.rows)]
    mt = m.metrics
    t = np.asarray(m.plan.t_plan if m.plan is not None else m.t, float)
    law = "planned law" if m.plan is not None else "programmed feed"
    ra, rb = (program_rates(q, t, m.rows) for q in m.rotary.pair)
    opt = list(getattr(mt, "row_cycle_time_optimal_s", []) or []) if mt is not None else []
    ctl = list(mt.row_cycle_time_s) if mt is not None and mt.controller else []
    floor = list(getattr(mt, "row_controller_floor_s", []) or []) if ctl else []
    n = len(starts)
    if len(opt) != n:
        opt = [float(t[b - 1] - t[a]) for a, b in zip(starts, ends, strict=True)]
    if len(floor) != n:
        floor = []
    keep = np.arange(n)
    note = ""
    if n > MAX_TABLE_ROWS:
        keep = np.sort(np.argsort(opt)[::-1][:MAX_TABLE_ROWS])
        note = f"<p class='small'>{n} rows: the {MAX_TABLE_ROWS} slowest are listed.</p>"
    head = ["row", "points", "cycle time optimal (s)"] + (
        [f"cycle time {mt.controller} (s)"] if ctl else []) + (
        [f"least time on {mt.controller}, any straight blocks{_ends_within(mt)} (s)"] if floor else []) + [
        f"peak |{rotary[0]}'| / |{rotary[1]}'| (deg/s), {law}",
        f"peak |{rotary[0]}''| / |{rotary[1]}''| (deg/s\u00b2), {law}",
        "min \u03b4 (\u00b5m) at point"]
    out = ["<table class='rows'>", "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    deg = np.degrees
    for k in keep:
        a, b = int(starts[k]), int(ends[k])
        d = np.asarray(m.delta[a:b], float)
        dk = int(np.nanargmin(d)) if np.isfinite(d).any() else None
        dtxt = "\u2014" if dk is None else f"{1e3 * d[dk]:.3g} at {int(m.idx[a + dk])}"
        cells = [str(int(m.rows[a])), str(b - a), _fmt(opt[k], ".4g")] + ([_fmt(ctl[k], ".4g")] if ctl else []) + (
            [_fmt(floor[k], ".4g")] if floor else []) + [
            f"{_fmt(deg(np.abs(ra.vel[a:b]).max()), '.3g')} / {_fmt(deg(np.abs(rb.vel[a:b]).max()), '.3g')}",
            f"{_fmt(deg(np.abs(ra.acc[a:b]).max()), '.4g')} / {_fmt(deg(np.abs(rb.acc[a:b]).max()), '.4g')}", dtxt]
        out.append("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>")
    out.append("</table>")
    return note + "\n".join(out)


def _pole_html(result: SmoothResult) -> str:
    """Every passage of the primary method near the pole of the outer rotary axis
    (camsmooth.smoothing.pole.PolePassage)."""
    from camsmooth.smoothing.pole import POLE_CONE_DEG

    passages = result.result.metrics.pole
    ax = passages[0].outer
    head = ["row", "points", "closest to the pole (deg)", f"{ax} turn, exact inverse (deg)",
            f"peak |{ax}'|, exact inverse (deg/s)", f"Gamma cost of {result.primary} (1/s\u2074)"]
    out = ["<table class='rows'>", "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    for q in passages[:MAX_TABLE_ROWS]:
        over = q.outer_peak_speed > q.outer_vmax
        cells = [str(q.row), f"{q.first}..{q.last}", _fmt(q.closest_deg, ".3g"), _fmt(q.outer_turn_deg, ".4g"),
                 _fmt(q.outer_peak_speed, ".4g"), "\u2014" if q.gamma_cost is None else f"{q.gamma_cost:+.4g}"]
        tds = [f"<td{' class=bad' if (i == 4 and over) else ''}>{html.escape(c)}</td>" for i, c in enumerate(cells)]
        out.append("<tr>" + "".join(tds) + "</tr>")
    out.append("</table>")
    more = f" ({len(passages) - MAX_TABLE_ROWS} more not listed)" if len(passages) > MAX_TABLE_ROWS else ""
    nviol = sum(result.result.metrics.violations.values())
    verdict = ("passes them within every limit" if nviol == 0
               else f"keeps {nviol} violations (the summary names them)")
    return (f"<p>{len(passages)} passages{more} of the tool axis within {POLE_CONE_DEG:g} deg of the {ax} axis, where "
            f"the exact inverse kinematics turns {ax} fast (red: beyond its limit of "
            f"{_fmt(passages[0].outer_vmax, '.4g')} deg/s at the programmed feed). The {html.escape(result.primary)} "
            f"program {verdict}; the Gamma cost is the sum of |T''|\u00b2 over the passage, "
            f"{html.escape(result.primary)} minus the programmed orientation (docs/METHODS.md section 1.4).</p>"
            + "\n".join(out))


def stepover_mm(cc: np.ndarray, rows: np.ndarray) -> float:
    """The path's stepover (mm): the median over rows of the median distance from a row's CC
    points to the row before it (camsmooth.smoothing.finish.neighbour_stepover; NaN for a single
    row)."""
    from camsmooth.smoothing.finish import neighbour_stepover

    d = neighbour_stepover(cc, rows)[:, 0]
    rows = np.asarray(rows)
    per = [float(np.median(d[rows == row])) for row in np.unique(rows) if np.isfinite(d[rows == row]).any()]
    return float(np.median(per)) if per else float("nan")


def scallop_um(r_eff: np.ndarray, stepover: float) -> np.ndarray:
    """Scallop height (um) of a cutter section of radius r_eff (mm) at the stepover (mm) on a flat:
    camsmooth.smoothing.finish.scallop_height with no surface curvature, h = r_eff - sqrt(r_eff^2
    - (s/2)^2) (docs/METHODS.md section 1.3); inf where r_eff < s/2."""
    from camsmooth.smoothing.finish import scallop_height

    with np.errstate(divide="ignore"):
        return 1e3 * scallop_height(1.0 / np.asarray(r_eff, float), 0.0, stepover)


def _geometry_html(result: SmoothResult, order: list[str]) -> str:
    """Per method: lead and tilt, the effective cutting radius across the feed and the scallop
    height at the path's stepover."""
    c = result.cutter
    if c is None or not hasattr(c, "R") or not hasattr(c, "r"):
        return "<p class='small'>No cutter in the result: no cutting geometry.</p>"
    ref = result.result
    s_over = stepover_mm(ref.cc, ref.rows)
    head = ["method", "lead (deg) median [min, max]", "tilt (deg) median [min, max]",
            "effective radius across the feed (mm) median [min]",
            f"scallop at stepover {_fmt(s_over, '.3g')} mm (\u00b5m) median [max]"]
    budgets = [result.methods[n].metrics.scallop_budget_um for n in order
               if result.methods[n].metrics is not None and result.methods[n].metrics.scallop_budget_um is not None]
    out = ["<table class='geometry'>", "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr>"]
    for name in order:
        m = result.methods[name]
        lead, tilt = np.degrees(np.asarray(m.lead, float)), np.degrees(np.asarray(m.tilt, float))
        r_eff = effective_radius(c, m.lead, m.tilt)
        ok = np.isfinite(r_eff)
        if m.scallop is not None:  # per point: its curvature and its neighbours (camsmooth.smoothing.finish)
            h = 1e3 * np.asarray(m.scallop, float)
        else:
            h = scallop_um(r_eff[ok], s_over) if np.isfinite(s_over) else np.full(int(ok.sum()), np.nan)

        def stat(v: np.ndarray, worst: Any, spec: str = ".3g") -> str:
            v = v[np.isfinite(v)]
            return "\u2014" if not v.size else f"{format(float(np.median(v)), spec)} [{format(float(worst(v)), spec)}]"

        def span(v: np.ndarray) -> str:
            v = np.round(v[np.isfinite(v)], 2) + 0.0  # to 0.01 deg, no '-0'
            return "\u2014" if not v.size else f"{np.median(v):.4g} [{v.min():.4g}, {v.max():.4g}]"

        cells = [name, span(lead), span(tilt), stat(r_eff[ok], np.min), stat(h, np.max)]
        out.append("<tr>" + "".join(f"<td>{html.escape(x)}</td>" for x in cells) + "</tr>")
    out.append("</table>")
    if budgets:
        out.append(f"<p class='small'>Finish budget: at most {min(budgets):.4g} \u00b5m of scallop at the tightest "
                   "point (--max-scallop, or the CAM program's own scallop plus the tolerance).</p>")
    return "\n".join(out)


def _notice(order: list[str], summaries: dict[str, dict[str, Any]], primary: str,
            warnings: Sequence[str] = ()) -> str:
    items = [f"<li>{html.escape(w)}</li>" for w in warnings]
    for name in sorted(order, key=lambda n: n != primary):
        s = summaries[name]
        tag = html.escape(name) + (" (primary)" if name == primary else "")
        if s["unclean_rows"]:
            items.append(f"<li><b>{tag}</b>: rows that could not be made clean: "
                         f"{html.escape(_short_list(s['unclean_rows']))}</li>")
        for key, why in (("blocked", "no orientation of its lead/tilt window clears the mesh"),
                         ("unreachable_clear", "the machine's limits kept the axis out of its clear region")):
            for b in s[key][:20]:
                items.append(f"<li><b>{tag}</b>: {html.escape(b.point)} lifted along the normal by "
                             f"{b.lift_mm:.4g} mm: {why}"
                             + (f" (best clearance found {b.best_clearance_mm:.4g} mm)"
                                if b.best_clearance_mm is not None else "") + "</li>")
            if len(s[key]) > 20:
                items.append(f"<li><b>{tag}</b>: \u2026 and {len(s[key]) - 20} more such points</li>")
        for miss in s["scallop_missed"][:20]:
            items.append(f"<li><b>{tag}</b>: row {miss.row}: finish budget missed at {miss.points} point"
                         f"{'s' * (miss.points > 1)}: scallop {miss.scallop_um:.4g} \u00b5m against "
                         f"{miss.budget_um:.4g} \u00b5m at point {miss.idx}</li>")
        if len(s["scallop_missed"]) > 20:
            items.append(f"<li><b>{tag}</b>: \u2026 and {len(s['scallop_missed']) - 20} more rows missing the finish "
                         "budget</li>")
        if s["unreachable"]:
            pts = [f"(row {r}, point {i})" for r, i in s["unreachable"]]
            items.append(f"<li><b>{tag}</b>: unreachable points (no axis solution within the travel): "
                         f"{html.escape(_short_list(pts))}</li>")
    if not items:
        return "<p class='ok'>All rows clean; all points reachable.</p>"
    return "<div class='notice'><b>Attention:</b><ul>" + "".join(items) + "</ul></div>"


def _setup_html(result: SmoothResult) -> str:
    """Machine, axes, post, cutter and the run's inputs in mm, mm/min, degrees and s, rounded."""
    from camsmooth.smoothing.result import describe_inputs

    m, c = result.machine, result.cutter
    rows: list[tuple[str, str]] = []
    if m is not None:
        if m.description.preset is not None:
            where = [f"pivot {_fmt(m.pivot)} mm"] if m.has_head else []
            if m.has_table:
                where.append("table centre [" + ", ".join(_fmt(v) for v in m.table_centre) + "] mm")
            rows.append(("machine", f"{m.name} (kind {m.kind}, {', '.join(where)})"))
        else:
            rows.append(("machine", f"{m.name} ({m.description.summary()})"))
        rotary = tuple(getattr(m, "rotary", ("A", "B")))
        for ax in (*rotary, "X", "Y", "Z"):
            lim = _axis_limits(m, ax)
            if lim is None:
                continue
            rot = ax in rotary
            conv = np.degrees if rot else float
            u = "deg" if rot else "mm"
            travel = (f"travel {_fmt(conv(lim.min))} to {_fmt(conv(lim.max))} {u}" if np.isfinite(lim.max - lim.min)
                      else "continuous" if rot else "travel not given")
            rows.append((f"axis {ax}", f"{travel}, "
                                       f"vmax {_fmt(conv(lim.vmax))} {u}/s, amax {_fmt(conv(lim.amax))} {u}/s\u00b2"))
        post = getattr(m, "post", None)
        if post is not None:
            rows.append(("G-code post", f"{post.dialect}, {post.mode} mode"))
    if c is not None:
        txt = (f"toroidal: R {_fmt(getattr(c, 'R', None))} mm, r {_fmt(getattr(c, 'r', None))} mm, "
               f"diameter {_fmt(getattr(c, 'diameter', None))} mm, shank {_fmt(getattr(c, 'shank_length', None))} mm")
        hr = getattr(c, "holder_radius", None)
        if hr:
            txt += f", holder radius {_fmt(hr)} mm, length {_fmt(getattr(c, 'holder_length', None))} mm"
        rows.append(("cutter", txt))
    rows += describe_inputs(result.inputs or {})
    return ("<table class='setup'>" + "".join(f"<tr><th>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
                                              for k, v in rows) + "</table>")


_CSS = """
body { font-family: sans-serif; margin: 1.5em; color: #222; max-width: 1500px; }
h1 { font-size: 1.5em; } h2 { font-size: 1.15em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 0.6em 0; font-size: 0.9em; }
th, td { border: 1px solid #bbb; padding: 3px 8px; text-align: left; }
table.summary td { text-align: right; } table.summary td:first-child { text-align: left; }
th { background: #f0f0f0; }
td.bad { color: #b00; font-weight: bold; background: #fdecec; }
.notice { border: 2px solid #c00; background: #fdecec; color: #900; padding: 0.5em 1em; margin: 1em 0; }
.ok { color: #176317; }
.warn { border: 1px dashed #c60; background: #fff6e5; padding: 0.5em 1em; }
figure { margin: 0.5em 0 1.5em 0; } figure img { max-width: 100%; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; }
.small { font-size: 0.85em; color: #555; }
ul.verdict li { margin: 0.3em 0; } ul.verdict li.badline { color: #b00; }
table.rows td, table.geometry td { text-align: right; } table.rows td:first-child { text-align: left; }
"""

_CAPTIONS = {
    "axes_angles.png": ("Rotary axes A and B",
                        "Commanded A and B (deg) per method, on one scale per axis across the methods; dashed: "
                        "travel limits (named in the corner when far off scale)."),
    "axes_velocity.png": ("Axis velocities", "A' and B' (deg/s) per method under the planned time law; dashed: "
                          "\u00b1vmax."),
    "axes_acceleration.png": ("Axis accelerations",
                              "A'' and B'' (deg/s\u00b2) per method under the planned time law (three-point second "
                              "differences of the commanded angles); dashed: \u00b1amax."),
    "compound_acceleration.png": ("Compound angular acceleration",
                                  "|d\u00b2T/dt\u00b2| of the unit tool axis per method under the planned time law "
                                  "(log scale). \u0393 in the tables is the same quantity at the programmed feed, "
                                  "the objective the nlp method minimises."),
    "lead_tilt.png": ("Lead and tilt",
                      "Lead and tilt (deg) per method; shaded: admissible window per point after gouge "
                      "tightening; dashed: the lead floor below which the tool's heel gouges the mesh, from "
                      "the accessibility map at the points where one was needed; x: outside the window."),
    "clearance.png": ("Clearance",
                      "Minimum signed clearance \u03b4 tool to surface (\u00b5m), on the scale of the data; "
                      "dashed: -tolerance (the run's --tolerance), drawn when near the data, else named; "
                      "triangle: the worst point."),
    FEED_PLOT: ("Planned feed",
                "The tool-tip feed (mm/min) of the time-optimal time law under every axis's velocity and "
                "acceleration limits, against the path length (mm), per method; the programmed feed drawn; "
                "cycle time and the constraint that binds longest in each title."),
}


def _headline_html(result: SmoothResult) -> str:
    """What smoothing bought and cost against the program as brought (camsmooth.report.headline)."""
    from camsmooth.report.headline import headline

    h = headline(result)
    return "" if h is None else h.html()


def _view3d_section(result: SmoothResult, order: list[str]) -> str:
    """The interactive 3D view (camsmooth.report.view3d): the primary method and the program as
    brought shown at first, the other methods one click away."""
    from camsmooth.report.headline import baseline_method
    from camsmooth.report.view3d import scene_of, view3d_html

    shown = [result.primary] + [b for b in (baseline_method(result.methods),) if b is not None]
    scene = scene_of(result, {m: _colour(m, order) for m in order}, order, shown)
    return ("<h3>Interactive view</h3>" + view3d_html(scene))


def _img_tag(png: Path, alt: str) -> str:
    b64 = base64.b64encode(png.read_bytes()).decode("ascii")
    return f"<img src='data:image/png;base64,{b64}' alt='{html.escape(alt)}'>"


# ----------------------------------------------------------------------------------------------
# entry point
def write_report(result: SmoothResult, out_dir: str | os.PathLike, *, title: str | None = None,
                 render_3d: bool = True, max_plot_points: int = 8000, max_axis_segments: int = 300,
                 replace: bool = False) -> Path:
    """Write the report's files into the folder ``out_dir`` and return its path.

    Each file is replaced atomically and other files in ``out_dir`` are left alone; with
    ``replace=True`` the whole folder is replaced (``camsmooth.io.atomic.atomic_dir``).

    Contents: PLOT_FILES (matplotlib PNGs, cumulative program time on x), ``scene_3d.png``
    (pyvista, surface with tool axes before ('none') and after (primary method); absent with a
    note in the HTML when rendering is unavailable or ``render_3d`` is False) and ``report.html``
    (self-contained, PNGs embedded as base64 data URIs; the headline of what the primary method
    bought and cost against the program as brought, camsmooth.report.headline; an interactive 3D
    view with plotly.js inlined, camsmooth.report.view3d; summary table per method and a red notice
    of unclean rows and unreachable points). Angles in degrees, lengths in mm. Series longer than
    ``max_plot_points`` are drawn as a min/max envelope per bin; at most ``max_axis_segments``
    tool axes per method are drawn in 3D. An exception leaves no (partial) folder behind and an
    existing ``out_dir`` untouched. OSError (naming ``out_dir``) when it cannot be written.
    """
    if not result.methods:
        raise ValueError("SmoothResult has no methods to report")
    if result.primary not in result.methods:
        raise ValueError(f"primary method {result.primary!r} not among {sorted(result.methods)}")
    order = _ordered_methods(result)
    colours = {m: _colour(m, order) for m in order}
    series = []
    for name in order:
        m = result.methods[name]
        row_t = np.asarray(m.plan.t_plan, float) if m.plan is not None else np.asarray(m.t, float)
        series.append(_Series(m, cumulative_time(row_t, m.rows), _row_starts(m.rows),
                              max(int(max_plot_points), 4), primary=name == result.primary, row_t=row_t))
    t_start = time.perf_counter()
    with atomic_dir(out_dir, replace=replace) as tmp:
        proc = None
        scene_note = "3D view not requested (render_3d=False)."
        scene_detail = ""
        if render_3d:
            npz = tmp / "_scene.npz"
            data, scene_detail = _scene_inputs(result, max_axis_segments)
            np.savez(npz, **data)
            proc = _start_render(npz, tmp / SCENE_FILE)
        try:
            figures = {
                "axes_angles.png": lambda: _plot_axes(series, colours, result.machine, "angle"),
                "axes_velocity.png": lambda: _plot_axes(series, colours, result.machine, "velocity"),
                "axes_acceleration.png": lambda: _plot_axes(series, colours, result.machine, "acceleration"),
                "compound_acceleration.png": lambda: _plot_compound(series, colours),
                "lead_tilt.png": lambda: _plot_lead_tilt(series, colours),
                "clearance.png": lambda: _plot_clearance(series, colours, _gouge_line(result)),
            }
            plans = {n: result.methods[n].plan for n in order if result.methods[n].plan is not None}
            if plans:
                from camsmooth.report.feed import plot_planned_feed

                figures[FEED_PLOT] = lambda: plot_planned_feed(
                    {n: result.methods[n].cl for n in plans}, result.result.rows, plans,
                    np.asarray(result.inputs.get("feed", np.full(len(result.result), np.nan)), float),
                    primary=result.primary, max_plot_points=max_plot_points)
            for name in figures:
                _save_png(figures[name](), tmp / name)
            if proc is not None:
                reason = _finish_render(proc, tmp / SCENE_FILE, _RENDER_TIMEOUT_S)
                scene_note = "" if reason is None else (
                    f"3D view unavailable: {reason}. Off-screen rendering needs an OpenGL context: on a "
                    "headless machine VTK >= 9.4 uses EGL or OSMesa (e.g. Mesa's libEGL / libOSMesa), "
                    "otherwise run under a virtual framebuffer (xvfb-run).")
        finally:
            if proc is not None and proc.poll() is None:
                proc.kill()
                proc.communicate()
        (tmp / "_scene.npz").unlink(missing_ok=True)
        html_text = _html(result, order, tmp, title, scene_note, scene_detail, series,
                          time.perf_counter() - t_start)
        (tmp / HTML_FILE).write_text(html_text, encoding="utf-8")
    return Path(out_dir)


def _html(result: SmoothResult, order: list[str], folder: Path, title: str | None, scene_note: str,
          scene_detail: str, series: list[_Series], elapsed: float) -> str:
    summaries = {name: method_summary(result.methods[name]) for name in order}
    primary = result.primary
    rotary = tuple(getattr(result.machine, "rotary", ("A", "B")))
    n = len(result.result)
    title = title or f"camsmooth report \u2014 {primary}, {n} points, {summaries[primary]['rows']} rows"
    planned = any(s.planned for s in series)
    law = ("Rates, peaks and the headline violations are under the planned time law t_plan (the time-optimal "
           "law the program's F words command); counts at the programmed feed are the motion before planning. "
           if planned else "")
    sections: list[tuple[str, str]] = [
        ("Verdict", _headline_html(result) + _verdict_html(order, summaries, primary, rotary)),
        ("Summary", _summary_table(order, summaries, primary, rotary)
         + f"<p class='small'>{law}Red cells need attention (a gouge below {1e3 * _gouge_line(result):.4g} "
           "\u00b5m, a violation under the planned law).</p>"),
        (f"Per row ({html.escape(primary)})", _rows_html(result.result, rotary)),
        *([("Pole passages", _pole_html(result))] if result.result.metrics.pole else []),
        ("Cutting geometry: effective radius and scallop",
         _geometry_html(result, order)
         + "<p class='small'>What lead and tilt do across the feed: a toroidal cutter (ring radius R, corner "
           "radius r) tilted forward by the lead and sideways by the tilt sweeps a profile of radius "
           "(R / sin(lead) + r) cos\u00b2(tilt) + r sin\u00b2(tilt) across the feed, and leaves scallops "
           "h = r_eff - sqrt(r_eff\u00b2 - (s/2)\u00b2) between passes a stepover s apart on a flat "
           "(docs/METHODS.md section 1.3). The scallop column is per point: the surface's curvature across the "
           "feed and the distance to the neighbouring rows at that point (camsmooth.smoothing.finish); the "
           "stepover in its heading is the median distance between neighbouring rows' CC points.</p>"),
        ("Setup", _setup_html(result)),
    ]
    parts = [
        "<!DOCTYPE html>", "<html lang='en'><head><meta charset='utf-8'>",
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        _notice(order, summaries, primary, result.warnings),
    ]
    k = 0
    for head, body in sections:
        k += 1
        parts.append(f"<h2>{k}. {head}</h2>{body}")
    note = _decimation_note(series)
    for name in PLOT_FILES + ((FEED_PLOT,) if (folder / FEED_PLOT).exists() else ()):
        head, cap = (_named(x, rotary) for x in _CAPTIONS[name])
        k += 1
        if name != FEED_PLOT:
            cap += (" Time is cumulative over the program (rows concatenated; faint vertical lines at row starts)"
                    + (", under the planned time law." if planned else ", at the programmed feed."))
        if note:
            cap += " Long series are drawn decimated:" + note
        parts.append(f"<h2>{k}. {html.escape(head)}</h2><figure>{_img_tag(folder / name, head)}"
                     f"<figcaption>{html.escape(cap)}</figcaption></figure>")
    parts.append(f"<h2>{k + 1}. Tool axes on the surface (3D)</h2>")
    scene = folder / SCENE_FILE
    if not scene_note and scene.exists():
        before = "grey: before (method 'none'), " if "none" in result.methods and primary != "none" else ""
        cap = f"{before}red: after (method '{primary}'); dark line: tool-tip path. {scene_detail}"
        parts.append(f"<figure>{_img_tag(scene, '3D view')}"
                     f"<figcaption>{html.escape(cap)}</figcaption></figure>")
    else:
        parts.append(f"<p class='warn'>{html.escape(scene_note or '3D view unavailable.')}</p>")
    parts.append(_view3d_section(result, order))
    parts.append(f"<p style='font-size:0.8em;color:#777'>Generated by camsmooth {html.escape(__version__)} "
                 f"in {elapsed:.1f} s.</p></body></html>")
    return "\n".join(parts)


__all__ = ["CLEARANCE_TOL_MM", "HTML_FILE", "PLOT_FILES", "SCENE_FILE", "cumulative_time", "method_summary",
           "render_scene_main", "write_report"]
