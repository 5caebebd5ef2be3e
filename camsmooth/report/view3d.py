"""The interactive 3D view of a report: the part, each method's tool-tip path and tool axes,
pole passages and lifted points, rotatable and zoomable in the browser.

Drawn with plotly (``plotly.graph_objects``): ``view3d_html`` returns an HTML fragment (a div and
its script) with plotly.js inlined, so the report stays one self-contained file that needs no
server and no network. plotly.js costs about 4.8 MB per report (the full bundle is the only one
the pip package ships); a WebGL view written by hand would be smaller but is a second renderer to
keep working, and plotly's Mesh3d/Scatter3d give rotation, zoom, hover and per-trace toggling
as they are. The static pyvista render (camsmooth.report.smoothing) stays for print.

Browser budget: the mesh is decimated to at most ``MAX_TRIANGLES`` triangles (VTK's quadric
decimation through pyvista, in process: decimation needs no OpenGL context), each method's path
to at most ``MAX_PATH_POINTS`` points and ``MAX_AXES`` tool axes (every k-th point); the view
says what it decimated. Coordinates in the part's frame (mm), as in the result CSV.
"""

from __future__ import annotations

import html
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["DIV_ID", "MAX_AXES", "MAX_PATH_POINTS", "MAX_TRIANGLES", "Scene", "browser_mesh", "scene_of",
           "scene_of_program", "view3d_html"]

MAX_TRIANGLES = 50_000
MAX_PATH_POINTS = 20_000
MAX_AXES = 250
MAX_BUTTONS = 8  # more layers (an analyzed program's tool paths): the legend alone toggles them
DIV_ID = "camsmooth-view3d"
_POLE_COLOUR = "#ff7f0e"
_LIFT_COLOUR = "#000000"


@dataclass(frozen=True)
class PathLayer:
    """One method's drawing. cl: (N, 3) tool tip (mm); axis: (N, 3) unit tool axis; rows: (N,)
    row id; lifted: (N,) bool, points lifted along the normal; hover: (N,) text per point."""

    name: str
    colour: str
    cl: np.ndarray
    axis: np.ndarray
    rows: np.ndarray
    lifted: np.ndarray
    hover: Sequence[str] = ()
    visible: bool = True


@dataclass(frozen=True)
class Scene:
    """What the view draws: the part (vertices (V, 3) mm, triangles (F, 3)) or None, the layers
    in legend order, the points to mark as pole passages ((K, 3) mm with a label each) and what
    a layer is."""

    vertices: np.ndarray | None
    faces: np.ndarray | None
    layers: list[PathLayer]
    pole_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pole_labels: Sequence[str] = ()
    layer_kind: str = "method"  # what a layer is, for the caption: 'method' or 'tool path'


def browser_mesh(vertices: np.ndarray, faces: np.ndarray, max_triangles: int = MAX_TRIANGLES
                 ) -> tuple[np.ndarray, np.ndarray, str]:
    """(vertices, faces, note): the mesh as it is when it has at most ``max_triangles`` triangles,
    else decimated (VTK quadric decimation) to about that many; the note says so ('' when not)."""
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    if len(f) <= max_triangles:
        return v, f, ""
    import pyvista as pv

    poly = pv.PolyData(v, np.column_stack([np.full(len(f), 3), f]).ravel())
    # ask a little more reduction than the ratio: quadric decimation may keep a few more faces
    target = 1.0 - 0.97 * max_triangles / len(f)
    dec = poly.decimate(target).triangulate()
    fv = np.asarray(dec.regular_faces, np.int64)
    if len(fv) > max_triangles or len(fv) == 0:  # refuse to return more than asked: keep every k-th face
        keep = f[:: int(np.ceil(len(f) / max_triangles))]
        return v, keep, (f"part drawn with {len(keep):,} of its {len(f):,} triangles (every "
                         f"{int(np.ceil(len(f) / max_triangles))}th)")
    return (np.asarray(dec.points, float), fv,
            f"part decimated from {len(f):,} to {len(fv):,} triangles for the browser")


def mesh_arrays(mesh: Any) -> tuple[np.ndarray, np.ndarray] | None:
    """(vertices (V,3), triangles (F,3)) of a trimesh-like or pyvista surface, or None."""
    if mesh is None:
        return None
    if hasattr(mesh, "vertices") and hasattr(mesh, "faces"):
        v = np.asarray(mesh.vertices, dtype=float)
        f = np.asarray(mesh.faces, dtype=np.int64)
        if f.ndim == 2 and f.shape[1] == 3 and len(f):
            return v, f
    if hasattr(mesh, "points") and hasattr(mesh, "triangulate"):
        surf = (mesh.extract_surface() if hasattr(mesh, "extract_surface") else mesh).triangulate()
        return np.asarray(surf.points, dtype=float), np.asarray(surf.regular_faces, dtype=np.int64)
    return None


def scene_of(result: Any, colours: Mapping[str, str], order: Sequence[str], shown: Sequence[str] = ()) -> Scene:
    """The Scene of a ``camsmooth.smoothing.result.SmoothResult``: its surface mesh, one layer per
    method in ``order`` (colour from ``colours``; visible at first: ``shown``, or every method when
    empty), the primary method's pole passages (metrics.pole) marked at their closest point."""
    mesh = mesh_arrays(getattr(result, "surface_mesh", None))
    layers = []
    for name in order:
        m = result.methods[name]
        lift = np.asarray(m.lift, float) if m.lift is not None else np.zeros(len(m))
        lifted = np.nan_to_num(lift) > 0.0
        hover = [f"{name}: row {int(r)}, point {int(i)}" for r, i in zip(m.rows, m.idx, strict=True)]
        layers.append(PathLayer(name, colours[name], np.asarray(m.cl, float).reshape(-1, 3),
                                np.asarray(m.axis, float).reshape(-1, 3), np.asarray(m.rows), lifted, hover,
                                visible=not shown or name in shown))
    pts, labels = [], []
    prim = result.result
    passages = prim.metrics.pole if prim.metrics is not None else []
    for q in passages:
        sel = np.flatnonzero((prim.rows == q.row) & (prim.idx >= q.first) & (prim.idx <= q.last))
        if not len(sel):
            continue
        pts.append(np.asarray(prim.cl, float)[sel])
        labels += [f"pole passage: row {q.row}, points {q.first}..{q.last}, closest {q.closest_deg:.3g} deg "
                   f"to the {q.outer} axis"] * len(sel)
    return Scene(mesh[0] if mesh else None, mesh[1] if mesh else None, layers,
                 np.concatenate(pts) if pts else np.zeros((0, 3)), labels)


_PALETTE = ("#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#8c564b", "#e377c2", "#17becf", "#bcbd22", "#7f7f7f",
            "#ff7f0e")


def scene_of_program(program: Any, mesh: Any = None) -> Scene:
    """The Scene of a ``camsmooth.io.program.CLProgram`` as ``analyze`` reads it: one layer per tool
    path (its cutting points, rapid moves left out; named by the operation), the part ``mesh``
    (trimesh-like) when given. Points without a tool axis (a 3-axis file) draw their path only."""
    m = mesh_arrays(mesh)
    tip = np.asarray(program.tip, float).reshape(-1, 3)
    axis = (np.asarray(program.axis, float).reshape(-1, 3) if program.axis is not None
            else np.full_like(tip, np.nan))
    rows = np.asarray(program.rows)
    layers, seen = [], set()
    for k, tp in enumerate(program.toolpaths):
        sel = np.arange(tp.start, tp.stop)
        sel = sel[rows[sel] >= 0]
        if not len(sel):
            continue
        name = tp.name or f"tool path {k + 1}"
        while name in seen:
            name += "'"
        seen.add(name)
        layers.append(PathLayer(name, _PALETTE[len(layers) % len(_PALETTE)], tip[sel], axis[sel], rows[sel],
                                np.zeros(len(sel), bool)))
    return Scene(m[0] if m else None, m[1] if m else None, layers, layer_kind="tool path")


def _every(n: int, limit: int) -> int:
    return max(1, int(np.ceil(n / max(limit, 1))))


def _broken(points: np.ndarray, rows: np.ndarray, step: int) -> np.ndarray:
    """Every step-th point (and each row's last) with a NaN row between rows: a polyline per row."""
    n = len(points)
    if n == 0:
        return np.zeros((0, 3))
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    ends = np.r_[starts[1:], n]
    parts = []
    for a, b in zip(starts, ends, strict=True):
        k = np.r_[np.arange(a, b, step), b - 1] if step > 1 else np.arange(a, b)
        parts += [points[np.unique(k)], np.full((1, 3), np.nan)]
    return np.concatenate(parts)


def _segments(cl: np.ndarray, axis: np.ndarray, length: float, step: int) -> np.ndarray:
    """Tool-axis segments from the tip along the axis (every step-th point), NaN-separated."""
    k = np.arange(0, len(cl), step)
    ok = np.isfinite(cl[k]).all(axis=1) & np.isfinite(axis[k]).all(axis=1)
    k = k[ok]
    seg = np.stack([cl[k], cl[k] + length * axis[k], np.full((len(k), 3), np.nan)], axis=1)
    return seg.reshape(-1, 3)


def _xyz(p: np.ndarray) -> dict[str, np.ndarray]:
    p = np.asarray(p, np.float32)  # half the bytes of float64; 0.1 um at a metre: finer than the view
    return {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2]}


def view3d_html(scene: Scene, *, height_px: int = 720, max_triangles: int = MAX_TRIANGLES,
                max_path_points: int = MAX_PATH_POINTS, max_axes: int = MAX_AXES, axis_length_mm: float | None = None,
                include_plotlyjs: bool = True) -> str:
    """An HTML fragment: the interactive view of ``scene`` (div id DIV_ID) with plotly.js inlined
    (``include_plotlyjs``), a button per method and 'all methods', the legend toggling each
    trace, and a caption saying what was decimated. Tool axes drawn as segments of
    ``axis_length_mm`` (default 8% of the scene's diagonal) from the tool tip."""
    import plotly.graph_objects as go

    traces: list[Any] = []
    owner: list[str | None] = []  # the method a trace belongs to (None: the part and the pole marks)
    notes: list[str] = []
    if scene.vertices is not None and scene.faces is not None:
        v, f, note = browser_mesh(scene.vertices, scene.faces, max_triangles)
        if note:
            notes.append(note)
        traces.append(go.Mesh3d(**_xyz(v), i=f[:, 0], j=f[:, 1], k=f[:, 2], name="part", color="#c8c8c8",
                                opacity=1.0, flatshading=False, showlegend=True, hoverinfo="skip",
                                lighting={"ambient": 0.55, "diffuse": 0.7, "specular": 0.15, "roughness": 0.6}))
        owner.append(None)
    allp = [la.cl for la in scene.layers] + ([scene.vertices] if scene.vertices is not None else [])
    allp = np.concatenate(allp) if allp else np.zeros((0, 3))
    allp = allp[np.isfinite(allp).all(axis=1)]
    diag = float(np.linalg.norm(np.ptp(allp, axis=0))) if len(allp) else 1.0
    length = axis_length_mm if axis_length_mm is not None else (0.08 * diag if diag > 0 else 1.0)
    # each method is the whole program; tool paths share one budget
    share = scene.layer_kind != "method"
    total = sum(len(la.cl) for la in scene.layers)
    steps: dict[str, set[int]] = {"path": set(), "axes": set()}
    for la in scene.layers:
        vis: bool | str = True if la.visible else "legendonly"
        step = _every(total if share else len(la.cl), max_path_points)
        path = _broken(la.cl, la.rows, step)
        traces.append(go.Scatter3d(**_xyz(path), mode="lines", name=f"{la.name}: tool-tip path",
                                   legendgroup=la.name, visible=vis, connectgaps=False, hoverinfo="name",
                                   line={"color": la.colour, "width": 3}))
        astep = _every(total if share else len(la.cl), max_axes)
        traces.append(go.Scatter3d(**_xyz(_segments(la.cl, la.axis, length, astep)), mode="lines",
                                   name=f"{la.name}: tool axes", legendgroup=la.name, visible=vis, connectgaps=False,
                                   hoverinfo="name", line={"color": la.colour, "width": 2}, opacity=0.8))
        owner += [la.name, la.name]
        steps["path"].add(step)
        steps["axes"].add(astep)
        k = np.flatnonzero(la.lifted)
        if len(k):
            k = k[:: _every(len(k), max_axes)]
            traces.append(go.Scatter3d(**_xyz(la.cl[k]), mode="markers", name=f"{la.name}: lifted points "
                                       f"({int(la.lifted.sum())})", legendgroup=la.name, visible=vis,
                                       text=[la.hover[i] + ": lifted along the normal" for i in k] if la.hover else
                                       None, hoverinfo="text" if la.hover else "name",
                                       marker={"symbol": "circle-open", "size": 5, "color": _LIFT_COLOUR}))
            owner.append(la.name)
    if len(scene.pole_points):
        k = np.arange(0, len(scene.pole_points), _every(len(scene.pole_points), max_axes))
        traces.append(go.Scatter3d(**_xyz(scene.pole_points[k]), mode="markers",
                                   name="pole passages (primary method)",
                                   text=[scene.pole_labels[i] for i in k] if scene.pole_labels else None,
                                   hoverinfo="text", marker={"symbol": "diamond", "size": 4, "color": _POLE_COLOUR}))
        owner.append(None)
    for what, st in (("paths drawn through", steps["path"]), ("tool axes drawn at", steps["axes"])):
        if st and max(st) > 1:
            notes.append(f"{what} every {'/'.join(f'{v}th' for v in sorted(st))} point")
    names = [la.name for la in scene.layers]
    buttons = [{"label": "all methods", "method": "restyle", "args": [{"visible": [True] * len(traces)}]}]
    for name in names:
        buttons.append({"label": name if len(name) <= 24 else name[:23] + "\u2026", "method": "restyle",
                        "args": [{"visible": [o is None or o == name for o in owner]}]})
    fig = go.Figure(traces)
    fig.update_layout(
        height=height_px, margin={"l": 0, "r": 0, "t": 10, "b": 0}, paper_bgcolor="white",
        scene={"aspectmode": "data", "xaxis_title": "X (mm)", "yaxis_title": "Y (mm)", "zaxis_title": "Z (mm)",
               "camera": {"eye": {"x": 1.45, "y": -1.45, "z": 1.05}}},
        legend={"x": 0.0, "y": 0.92, "yanchor": "top", "bgcolor": "rgba(255,255,255,0.8)", "font": {"size": 12}},
        updatemenus=[{"type": "buttons", "direction": "right", "x": 0.0, "xanchor": "left", "y": 1.0,
                      "yanchor": "top", "buttons": buttons, "showactive": True,
                      "pad": {"l": 4, "t": 4}}] if 1 < len(names) <= MAX_BUTTONS else [],
    )
    div = fig.to_html(include_plotlyjs=include_plotlyjs, full_html=False, div_id=DIV_ID,
                      config={"displaylogo": False, "responsive": True,
                              "toImageButtonOptions": {"format": "png", "filename": "camsmooth_view3d"}})
    marks = (["black rings: points lifted along the normal"] if any(la.lifted.any() for la in scene.layers) else []) \
        + (["orange diamonds: the primary method's passages near the pole"] if len(scene.pole_points) else [])
    buttons_say = f"the buttons show one {scene.layer_kind} (or all), " if 1 < len(names) <= MAX_BUTTONS else ""
    cap = (f"Drag to rotate, scroll to zoom, right-drag to pan; {buttons_say}a click on a legend entry hides or shows "
           f"that trace. Tool axes drawn as {length:.3g} mm segments from the tool tip"
           + "".join("; " + m for m in marks) + ". " + "; ".join(notes).capitalize()[:1] + "; ".join(notes)[1:]
           + ("." if notes else ""))
    return f"<figure class='view3d'>{div}<figcaption>{html.escape(cap)}</figcaption></figure>"
