"""Program outputs: the per-point result CSV and the five-axis G-code.

Files are written atomically (``camsmooth.io.atomic.atomic_path``): a failed write never leaves a
partial file. Units in files: mm, s, degrees (radians inside the code; CONVENTIONS.md).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth import __version__
from camsmooth.errors import InfeasibleError, InputError
from camsmooth.io.atomic import atomic_path
from camsmooth.io.table import read_table
from camsmooth.smoothing.result import OUTPUT_COLUMNS, MethodResult, SmoothResult

#: Columns of the result CSV: OUTPUT_COLUMNS, then ``lift`` (mm) and ``status``.
RESULT_CSV_COLUMNS: tuple[str, ...] = OUTPUT_COLUMNS + ("lift", "status")
#: Per-point status values, least to most severe; a point gets the most severe that applies.
STATUSES: tuple[str, ...] = ("ok", "lifted", "interference", "unreachable")
#: Clearance below which a point counts as interfering (mm): gouge tolerance of the pipeline.
INTERFERENCE_TOL_MM = -1e-3
#: Default retract height between rows, along the tool axis (mm).
DEFAULT_SAFE_HEIGHT_MM = 10.0

_INT_COLUMNS = ("row", "idx")
_STR_COLUMNS = ("status",)


# ----------------------------------------------------------------------------------------------
# per-point status
def point_status(result: MethodResult, tol: float = INTERFERENCE_TOL_MM) -> np.ndarray:
    """Status string per point of one method (array of str, values in STATUSES).

    'unreachable': (row, idx) is listed in ``metrics['unreachable']`` (no inverse-kinematics
    solution within the travel limits); else 'interference': clearance ``delta`` < ``tol`` mm
    (gouge left after smoothing and any lift); else 'lifted': the fallback lift along the normal
    was applied (``lift`` > 0); else 'ok'. A NaN delta is not counted as interference.
    """
    n = len(result)
    status = np.full(n, "ok", dtype=object)
    lift = np.asarray(result.lift, dtype=float)
    status[np.nan_to_num(lift, nan=0.0) > 0.0] = "lifted"
    delta = np.asarray(result.delta, dtype=float)
    with np.errstate(invalid="ignore"):
        status[delta < tol] = "interference"
    unreachable = result.metrics.get("unreachable") or []
    if len(unreachable):
        pairs = np.asarray(unreachable, dtype=np.int64).reshape(-1, 2)
        rows = np.asarray(result.rows, dtype=np.int64)
        idx = np.asarray(result.idx, dtype=np.int64)
        # structured view compares (row, idx) pairs as one key without a Python loop per point
        key_dtype = np.dtype([("r", np.int64), ("i", np.int64)])
        points = np.empty(n, key_dtype)
        points["r"], points["i"] = rows, idx
        listed = np.empty(len(pairs), key_dtype)
        listed["r"], listed["i"] = pairs[:, 0], pairs[:, 1]
        status[np.isin(points, listed)] = "unreachable"
    return status.astype(str)


# ----------------------------------------------------------------------------------------------
# result CSV
def _format_float_column(values: np.ndarray) -> list[str]:
    """Shortest strings that read back to the same float (Python repr), 'nan', 'inf', '-inf'."""
    return [repr(v) for v in np.asarray(values, dtype=float).tolist()]


def write_result_csv(path: str | os.PathLike, result: SmoothResult) -> Path:
    """Write the primary method's per-point table to ``path`` atomically; return the path.

    Columns: RESULT_CSV_COLUMNS = OUTPUT_COLUMNS (mm, s, degrees; see camsmooth.smoothing.result) then
    ``lift`` (mm, fallback lift along the normal, 0 where none) and ``status`` (see
    ``point_status``), then ``fx,fy,fz`` (unit feed direction, the local frame's X_L) when the
    result carries them. Floats are written as Python ``repr`` (shortest exact round-trip); ``row``
    and ``idx`` as integers.
    """
    r = result.result
    table = result.table()
    if table.shape[1] != len(OUTPUT_COLUMNS):
        raise ValueError(f"SmoothResult.table() has {table.shape[1]} columns, expected {len(OUTPUT_COLUMNS)}")
    columns: list[list[str]] = []
    for k, name in enumerate(OUTPUT_COLUMNS):
        if name in _INT_COLUMNS:
            columns.append([str(v) for v in np.asarray(table[:, k]).astype(np.int64).tolist()])
        else:
            columns.append(_format_float_column(table[:, k]))
    columns.append(_format_float_column(r.lift))
    columns.append(point_status(r).tolist())
    header = list(RESULT_CSV_COLUMNS)
    if r.feed_dirs is not None:  # the local frame's X_L, so predict can re-evaluate lead/tilt exactly
        header += ["fx", "fy", "fz"]
        columns += [_format_float_column(r.feed_dirs[:, k]) for k in range(3)]
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            w = csv.writer(fh, lineterminator="\n")
            w.writerow(header)
            w.writerows(zip(*columns, strict=True))
    return path


def read_result_csv(path: str | os.PathLike, required: Sequence[str] = OUTPUT_COLUMNS
                    ) -> dict[str, np.ndarray]:
    """Read a result CSV (as written by ``write_result_csv``) into column arrays.

    Returns name -> array for every column in the file: ``row`` and ``idx`` int64, ``status``
    str, all others float (NaN allowed: an unknown clearance is written as nan; units as in the
    file: mm, s, degrees). Read by ``camsmooth.io.table.read_table``: InputError naming the file,
    row and column when the file is missing or empty, a ``required`` column is absent, a row has
    the wrong number of fields or a value is not a number / not an integer.
    """
    declared = tuple(dict.fromkeys(list(required) + list(_INT_COLUMNS) + list(_STR_COLUMNS)))
    table = read_table(path, required, [c for c in declared if c not in required], integer=_INT_COLUMNS,
                       text=_STR_COLUMNS, nonfinite=[c for c in declared if c not in _INT_COLUMNS],
                       others="float", min_rows=0, what="result file")
    return dict(table.columns)


# ----------------------------------------------------------------------------------------------
# G-code
def _comment(text: str) -> str:
    """An ISO/Fanuc comment line; parentheses inside a comment end it, so they are replaced."""
    return "(" + text.replace("(", "[").replace(")", "]").replace("\n", " ") + ")"


def _fmt(value: float, decimals: int = 4) -> str:
    s = f"{value:.{decimals}f}"
    return "0." + "0" * decimals if s == "-0." + "0" * decimals else s


def _move(code: str, xyz: np.ndarray, a_deg: float, b_deg: float, feed: float | None) -> str:
    words = [code, "X" + _fmt(xyz[0]), "Y" + _fmt(xyz[1]), "Z" + _fmt(xyz[2]),
             "A" + _fmt(a_deg), "B" + _fmt(b_deg)]
    if feed is not None:
        words.append("F" + _fmt(feed, 1))
    return " ".join(words)


def _row_slices(rows: np.ndarray) -> list[slice]:
    """Contiguous runs of equal row id (rows are contiguous in path order)."""
    rows = np.asarray(rows)
    if len(rows) == 0:
        return []
    starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]])
    ends = np.r_[starts[1:], len(rows)]
    return [slice(int(s), int(e)) for s, e in zip(starts, ends, strict=True)]


def _check_travel(machine: Any, r: MethodResult, A: np.ndarray, B: np.ndarray, xyz: np.ndarray,
                  what: str) -> None:
    """InfeasibleError naming axis, limit, row and point when a commanded value is out of travel."""
    limits = getattr(machine, "limits", {}) or {}
    for name, values in (("A", A), ("B", B), ("X", xyz[:, 0]), ("Y", xyz[:, 1]), ("Z", xyz[:, 2])):
        lim = limits.get(name)
        if lim is None:
            continue
        bad = (values < lim.min - 1e-9) | (values > lim.max + 1e-9)
        if bad.any():
            i = int(np.argmax(bad))
            rotary = name in "AB"
            conv = math.degrees if rotary else float
            unit = "deg" if rotary else "mm"
            raise InfeasibleError(
                f"G-code {what}: axis {name} = {conv(values[i]):.4f} {unit} outside travel "
                f"[{conv(lim.min):.4f}, {conv(lim.max):.4f}] {unit} "
                f"at row {int(r.rows[i])}, point {int(r.idx[i])}")


def write_gcode(path: str | os.PathLike, result: SmoothResult, machine: Any, cutter: Any, feed_mm_min: float,
                *, safe_height: float = DEFAULT_SAFE_HEIGHT_MM, check_limits: bool = True) -> Path:
    """Write the primary method's program as five-axis G-code to ``path`` atomically.

    Layout: a header of comments (machine name, kind, pivot; tool R, r, diameter, shank; method;
    generating program; inputs), ``G21`` (mm), ``G90`` (absolute), ``G94`` (feed per minute), then
    per CC point ``G01 X Y Z A B F`` with X, Y, Z = ``result.xyz`` (pivot position, mm, 4
    decimals; METHODS section 1: pivot = CL + L_p T), A, B in degrees (4 decimals, unwrapped as
    in the result, not reduced to +-180) and F = ``feed_mm_min``. Each row is entered and left
    through rapid moves (G00) ``safe_height`` mm up along the tool axis T of that row's first /
    last point, with A and B held: moving the pivot by h T moves the tool tip by the same h T, so
    the tool backs out of the surface along its own axis. Between rows the rapid goes from above
    the last point of one row to above the first point of the next (A, B may turn during this
    rapid, at the safe height). The program ends with ``M30``.

    With ``check_limits`` (default) every commanded value, including the retract moves, is
    checked against ``machine.limits`` and an InfeasibleError names the axis, travel, row and
    point instead of writing a program the controller would reject. Non-finite values raise
    InputError.
    """
    feed = float(feed_mm_min)
    if not math.isfinite(feed) or feed <= 0:
        raise InputError(f"feed must be a finite number > 0 mm/min, got {feed_mm_min!r}", column="feed")
    h = float(safe_height)
    if not math.isfinite(h) or h < 0:
        raise InputError(f"safe height must be a finite number >= 0 mm, got {safe_height!r}")
    r = result.result
    xyz = np.asarray(r.xyz, dtype=float).reshape(-1, 3)
    A = np.asarray(r.A, dtype=float)
    B = np.asarray(r.B, dtype=float)
    T = np.asarray(r.axis, dtype=float).reshape(-1, 3)
    finite = np.isfinite(xyz).all(axis=1) & np.isfinite(A) & np.isfinite(B) & np.isfinite(T).all(axis=1)
    if not finite.all():
        i = int(np.argmin(finite))
        raise InputError(f"non-finite axis value at row {int(r.rows[i])}, point {int(r.idx[i])}; "
                         "cannot write G-code")
    if check_limits:
        _check_travel(machine, r, A, B, xyz, "point")
        _check_travel(machine, r, A, B, xyz + h * T, f"retract ({h:g} mm along the tool axis)")

    lines = _gcode_header(result, machine, cutter, feed, h)
    a_deg, b_deg = np.degrees(A), np.degrees(B)
    for sl in _row_slices(r.rows):
        first, last = sl.start, sl.stop - 1
        lines.append(_comment(f"row {int(r.rows[first])}: {sl.stop - sl.start} points"))
        lines.append(_move("G00", xyz[first] + h * T[first], a_deg[first], b_deg[first], None))
        lines.extend(_move("G01", xyz[i], a_deg[i], b_deg[i], feed) for i in range(sl.start, sl.stop))
        lines.append(_move("G00", xyz[last] + h * T[last], a_deg[last], b_deg[last], None))
    lines.append("M30")
    path = Path(path)
    with atomic_path(path) as tmp:
        tmp.write_text("\n".join(lines) + "\n")
    return path


def _gcode_header(result: SmoothResult, machine: Any, cutter: Any, feed: float, h: float) -> list[str]:
    R, r_c = float(cutter.R), float(cutter.r)
    diameter = float(getattr(cutter, "diameter", 2.0 * (R + r_c)))
    shank = getattr(cutter, "shank_length", None)
    shank_txt = "n/a" if shank is None else f"{float(shank):.4f} mm"
    head = [
        _comment(f"generated by camsmooth {__version__} - five-axis tool-axis smoothing"),
        _comment(f"machine: {getattr(machine, 'name', '?')}, kind {getattr(machine, 'kind', '?')}, "
                 f"pivot {float(getattr(machine, 'pivot', float('nan'))):.4f} mm"),
        _comment(f"tool: toroidal R {R:.4f} mm, r {r_c:.4f} mm, diameter {diameter:.4f} mm, "
                 f"shank {shank_txt}"),
        _comment(f"method: {result.primary}; {len(result.result)} points"),
    ]
    head.extend(_comment(f"input {k}: {v}") for k, v in _simple_items(result.inputs))
    head += [
        _comment("X Y Z: pivot position mm; A B: degrees; F: mm/min"),
        _comment(f"rows are entered and left by G00 {h:.4f} mm up along the tool axis"),
        "G21",
        "G90",
        "G94",
    ]
    return head


def _simple_items(inputs: dict[str, Any]) -> Iterable[tuple[str, Any]]:
    for k, v in inputs.items():
        if isinstance(v, (str, int, float, os.PathLike)) and not isinstance(v, bool):
            yield str(k), v
