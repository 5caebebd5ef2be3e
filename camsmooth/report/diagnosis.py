"""Plots and an HTML page for `camsmooth diagnose --report DIR`.

Figures (PNG, matplotlib object API with the Agg canvas, no global pyplot state):

- ``residual_time.png``: residual per channel against time, before (current model) and after
  (with the named effects), with the +-3 floor band;
- ``effect_<name>.png``: per named effect, the residual against the state that explains it
  (commanded velocity for a lag or an offset, last direction for backlash, rotary angle for the
  rotary and spindle terms, spindle angle for runout, elapsed time for drift), before (the final
  model without this effect) and after (the final model), as ``diagnose`` computed them (the
  report reads the findings and re-runs nothing);
- ``report.html``: verdict, sentences, tables of RMS, parameters, rejected candidates, noise
  floors, located intervals, and the figures.

Long recordings are thinned for plotting only (an even stride for lines, a seeded random subset
for scatter plots); the page says so. Units: mm, s, degrees (radians converted).
"""

from __future__ import annotations

import html
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.diagnosis.recordings import channel_unit
from camsmooth.io.atomic import atomic_dir

MAX_LINE_POINTS = 20000
MAX_SCATTER_POINTS = 15000


def _figure(nrows: int, ncols: int = 1, width: float = 10.0, height_per_row: float = 2.3) -> Any:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, max(2.5, height_per_row * nrows + 0.6)), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def _save(fig: Any, path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    FigureCanvasAgg(fig)
    fig.savefig(path, dpi=100)


def _display(channel: str, values: np.ndarray) -> tuple[np.ndarray, str]:
    """Values in display units: rad -> deg, mm stays, unit vector components in urad-like 1e-6."""
    u = channel_unit(channel)
    if u == "rad":
        return np.degrees(values), "deg"
    if u == "1":
        return values * 1e6, "1e-6"
    return values, "mm"


def _stride(n: int, limit: int) -> np.ndarray:
    return np.arange(0, n, max(1, -(-n // limit)))


def plot_residual_time(diag: Any, path: Path) -> None:
    """Residual against time per channel, before and after, with the +-3 floor band."""
    P = diag.problem
    chans = P.channels
    fig, axes = _figure(len(chans))
    idx = _stride(len(P.t), MAX_LINE_POINTS)
    for j, c in enumerate(chans):
        ax = axes[j, 0]
        ok = P.valid[idx, j]
        rb, unit = _display(c, diag.resid_before[idx, j])
        ra, _ = _display(c, diag.resid_after[idx, j])
        fl, _ = _display(c, 3 * P.floor[idx, j])
        t = P.t[idx]
        ax.fill_between(t, -fl, fl, color="0.85", lw=0, label="±3 floor")
        ax.plot(t[ok], rb[ok], lw=0.6, color="tab:red", label="before")
        ax.plot(t[ok], ra[ok], lw=0.6, color="tab:blue", label="after")
        ax.set_ylabel(f"{c} ({unit})")
        if j == 0:
            ax.legend(loc="upper right", fontsize=8, ncol=3)
    axes[-1, 0].set_xlabel("time (s)")
    fig.suptitle("residual = recorded - simulated")
    _save(fig, path)


def plot_effect(diag: Any, name: str, names: Sequence[str], path: Path) -> None:
    """Residual against the explaining state, before (final model without this effect) and after."""
    P = diag.problem
    before, after = diag.effect_residuals[name]
    pairs = diag.effect_states[name]
    fig, axes = _figure(len(pairs), 2, width=10.0, height_per_row=2.6)
    rng = np.random.default_rng(0)
    n = len(P.fit_idx)
    sel = np.sort(rng.choice(n, MAX_SCATTER_POINTS, replace=False)) if n > MAX_SCATTER_POINTS else np.arange(n)
    for i, (c, label, state) in enumerate(pairs):
        j = P.channels.index(c)
        ok = P.valid_fit[sel, j]
        for k, (res, title) in enumerate(((before, "without it"), (after, "with it"))):
            ax = axes[i, k]
            y, unit = _display(c, res[sel, j])
            ax.plot(state[sel][ok], y[ok], ".", ms=1.5, alpha=0.5, color="tab:red" if k == 0 else "tab:blue")
            ax.set_ylabel(f"{c} residual ({unit})")
            ax.set_xlabel(label)
            if i == 0:
                ax.set_title(f"{name}: {title}")
    _save(fig, path)


def _table(rows: Sequence[Sequence[Any]], header: Sequence[str]) -> str:
    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.4g}"
        return html.escape(str(v))

    head = "".join(f"<th>{html.escape(h)}</th>" for h in header)
    body = "".join("<tr>" + "".join(f"<td>{cell(v)}</td>" for v in r) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def report_html(f: dict[str, Any], figures: Sequence[tuple[str, str]], thinned: bool) -> str:
    """The report page from the findings and the figure files."""
    esc = html.escape
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>camsmooth diagnose</title>",
             "<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;"
             "margin:0.5em 0}td,th{border:1px solid #bbb;padding:2px 6px;font-size:90%}img{max-width:100%}</style>",
             "</head><body><h1>Simulation versus recording</h1>",
             f"<p>program: {esc(str(f['program']))}<br>recording: {esc(str(f['recording']))}<br>"
             f"resampling: {esc(f['resampling'])}</p>",
             f"<h2>Verdict</h2><p><b>{esc(f['verdict'])}</b></p><ul>"]
    parts += [f"<li>{esc(e['sentence'])}</li>" for e in f["effects"]]
    parts.append("</ul>")
    if f.get("lag_vs_offset"):
        parts.append(f"<p><b>Servo lag or clock offset?</b> {esc(f['lag_vs_offset']['verdict'])}</p>")
    rows = [[c, f["baseline_rms"][c]["fit"], f["final_rms"][c]["fit"], f["baseline_rms"][c]["heldout"],
             f["final_rms"][c]["heldout"], f["noise_floor"][c]["rms"], f["channels"][c]["unit"]]
            for c in f["channels"]]
    parts.append("<h2>Residual RMS per channel</h2>" + _table(
        rows, ["channel", "before (all)", "after (all)", "before (held-out)", "after (held-out)", "noise floor",
               "unit"]))
    for e in f["effects"]:
        if e["name"] == "unexplained":
            continue
        prow = [[k, v, e["uncertainties"].get(k), e.get("units", {}).get(k, "")] for k, v in e["parameters"].items()]
        parts.append(f"<h3>{esc(e['name'])}</h3>" + _table(prow, ["parameter", "value", "± 1 sigma", "unit"]))
    parts.append("<h2>Rejected candidates</h2>" + _table([[r["name"], r["reason"]] for r in f["rejected"]],
                                                          ["candidate", "reason"]))
    iv = [[i["t_start"], i["t_end"], i["samples"], ", ".join(i["channels"]), i["peak_sigma"],
           "; ".join(f"{a}: {'moving' if s['moving'] else 'at rest'}{', reversing' if s['reversing'] else ''}"
                     f"{', accelerating' if s['accelerating'] else ''}" for a, s in i["axes"].items())]
          for i in f["intervals"]]
    parts.append(f"<h2>Located intervals (before)</h2><p>{f['located']['count']} intervals where the residual "
                 f"stands above {f['located']['threshold_sigma']} floors; "
                 f"{100 * f['located']['fraction_of_time_above']:.3g}% of the samples.</p>"
                 + _table(iv, ["t start (s)", "t end (s)", "samples", "channels", "peak (floors)", "axis states"]))
    for fname, caption in figures:
        parts.append(f"<h3>{esc(caption)}</h3><img src='{esc(fname)}' alt='{esc(caption)}'>")
    if thinned:
        parts.append("<p><i>Plots thin long recordings (an even stride for lines, a random subset for scatter "
                     "plots); every figure in the tables uses all samples.</i></p>")
    parts.append("<h2>Findings (JSON)</h2><pre>" + esc(json.dumps({k: f[k] for k in ("noise_floor", "selection")},
                                                                   indent=1)) + "</pre></body></html>")
    return "".join(parts)


def write_report(diag: Any, directory: str | Path, *, replace: bool = False) -> Path:
    """Write the figures and report.html into ``directory``: each file replaced atomically, other
    files left alone; ``replace=True`` replaces the whole folder (``camsmooth.io.atomic.atomic_dir``)."""
    directory = Path(directory)
    final = diag.selection["final"]
    with atomic_dir(directory, replace=replace) as tmp:
        figures = []
        plot_residual_time(diag, tmp / "residual_time.png")
        figures.append(("residual_time.png", "Residual against time, before and after"))
        for name in final.active:
            fn = f"effect_{name}.png"
            plot_effect(diag, name, final.pnames[name], tmp / fn)
            figures.append((fn, f"{name}: residual against the state that explains it"))
        thinned = len(diag.problem.t) > MAX_LINE_POINTS or len(diag.problem.fit_idx) > MAX_SCATTER_POINTS
        (tmp / "report.html").write_text(report_html(diag.findings, figures, thinned), encoding="utf-8")
    return directory
