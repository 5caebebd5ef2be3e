"""The pinned CSV format of a cutter-contact (CC) path (``CCPath``, camsmooth.geometry.paths).

Frames and units: workpiece frame W, mm; feed in mm/min. The CC normal n points from the
material toward the tool (CONVENTIONS.md); the feed direction f is the unit tangent of the path in
the direction of travel (X_L of the local frame, METHODS.md section 1).

CSV format (pinned)
-------------------
One header row, then one data row per CC point, in machining order; read by
``camsmooth.io.table.read_table`` (case-insensitive names, BOM accepted, other delimiters named,
blank lines skipped; rows are 1-based data rows, header = row 0). Extra columns are ignored.

- required: ``x, y, z`` (mm), ``nx, ny, nz`` (unit normal out of the material)
- optional: ``row`` (integer row id; rows are contiguous runs of equal id; without it the file is
  one row, id 0), ``fx, fy, fz`` (unit feed direction, all three or none), ``feed`` (mm/min, > 0)

Errors (InputError naming the file, the row and the column): missing column (with a close
misspelling suggested), unparsable or empty value, NaN or inf, zero normal, normal length off 1 by
more than ``UNIT_TOL`` (within it the normal is normalised), non-integer row id, a row id that
reappears after other rows, a row of fewer than 3 points, consecutive points of a row closer than
``REPEAT_TOL`` mm, feed <= 0, zero or non-unit feed direction (same rule as normals), feed
direction not tangent (|f.n| > ``TANGENT_TOL``; within it f is projected onto the tangent plane).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from camsmooth.geometry.paths import (
    MIN_ROW_POINTS,
    REPEAT_TOL,
    TANGENT_TOL,
    UNIT_TOL,
    CCPath,
    _row_runs,
)
from camsmooth.io.table import Table, number_text, read_table, write_table

__all__ = ["read_cc_csv", "write_cc_csv", "unit_columns", "CC_REQUIRED", "CC_OPTIONAL"]

CC_REQUIRED = ("x", "y", "z", "nx", "ny", "nz")
CC_OPTIONAL = ("row", "fx", "fy", "fz", "feed")


def unit_columns(table: Table, names: Sequence[str], what: str, tol: float = UNIT_TOL) -> np.ndarray:
    """The (N, 3) unit vectors held in three columns of ``table``, normalised.

    InputError naming the row and the columns for a zero vector or a length off 1 by more than
    ``tol`` (a file whose vectors are not unit is more likely wrong than imprecise)."""
    v = np.stack([table[c] for c in names], axis=1)
    with np.errstate(over="ignore"):  # a huge component: an infinite length, named below
        norm = np.linalg.norm(v, axis=1)
    column = ",".join(names)
    zero = norm < 1e-12
    if zero.any():
        raise table.error(f"zero {what}", int(np.argmax(zero)), column)
    off = np.abs(norm - 1.0) > tol
    if off.any():
        k = int(np.argmax(off))
        raise table.error(f"{what} is not a unit vector (length {float(norm[k]):.9g}, allowed 1 +- {tol:g})", k,
                          column)
    return v / norm[:, None]


def integer_row_ids(table: Table) -> np.ndarray:
    """The ``row`` column (int64; contiguous runs checked), or zeros when the file has none."""
    if "row" not in table:
        return np.zeros(len(table), dtype=np.int64)
    rows = table["row"]
    _, again = _row_runs(rows)
    if again is not None:
        raise table.error(f"row id {int(rows[again])} reappears after other rows (rows must be contiguous runs)",
                          again, "row")
    return rows


def positive_feed(table: Table) -> np.ndarray | None:
    """The ``feed`` column (mm/min, every value > 0) or None."""
    if "feed" not in table:
        return None
    feed = table["feed"]
    bad = ~(feed > 0)
    if bad.any():
        k = int(np.argmax(bad))
        raise table.error(f"feed must be > 0 mm/min, got {number_text(feed[k])}", k, "feed")
    return feed


def read_cc_csv(path: str | os.PathLike) -> CCPath:
    """Read a CC path from the pinned CSV format (module docstring); InputError on bad input."""
    t = read_table(path, CC_REQUIRED, CC_OPTIONAL, integer=("row",), what="CC path")
    feed_dir_cols = [c for c in ("fx", "fy", "fz") if c in t]
    if feed_dir_cols and len(feed_dir_cols) < 3:
        missing = next(c for c in ("fx", "fy", "fz") if c not in t)
        raise t.header_error(f"missing column '{missing}' (needed with {', '.join(feed_dir_cols)})", missing)
    points = np.stack([t["x"], t["y"], t["z"]], axis=1)
    normals = unit_columns(t, ("nx", "ny", "nz"), "normal")
    rows = integer_row_ids(t)
    feed = positive_feed(t)
    feed_dirs = None
    if feed_dir_cols:
        f = unit_columns(t, ("fx", "fy", "fz"), "feed direction")
        fn = np.einsum("ij,ij->i", f, normals)
        bad = np.abs(fn) > TANGENT_TOL
        if bad.any():
            k = int(np.argmax(bad))
            raise t.error(f"feed direction is not tangent to the surface (f.n = {float(fn[k]):.6g}, "
                          f"|f.n| allowed <= {TANGENT_TOL:g})", k, "fx,fy,fz")
        f = f - fn[:, None] * normals
        feed_dirs = f / np.linalg.norm(f, axis=1)[:, None]
    cc = CCPath(points=points, normals=normals, rows=rows, feed_dirs=feed_dirs, feed=feed, source=t.file)
    for sl in cc.row_slices():
        if sl.stop - sl.start < MIN_ROW_POINTS:
            raise t.error(f"row id {int(rows[sl.start])} has {sl.stop - sl.start} point(s); at least "
                          f"{MIN_ROW_POINTS} are needed", sl.start, "row")
    step = np.linalg.norm(np.diff(points, axis=0), axis=1)
    repeat = (step < REPEAT_TOL) & (rows[1:] == rows[:-1])
    if repeat.any():
        k = int(np.argmax(repeat)) + 1
        raise t.error(f"point repeats the previous point of row id {int(rows[k])} "
                      f"(distance {float(step[k - 1]):.3g} mm)", k, "x,y,z")
    return cc


def write_cc_csv(path: str | os.PathLike, ccpath: CCPath) -> None:
    """Write ``ccpath`` in the pinned CSV format, atomically, floats in their shortest exact
    round-trip form (camsmooth.io.table.write_table). Columns: x,y,z,nx,ny,nz,row[,fx,fy,fz][,feed]."""
    cols: dict[str, np.ndarray] = {}
    for k, name in enumerate("xyz"):
        cols[name] = ccpath.points[:, k]
    for k, name in enumerate(("nx", "ny", "nz")):
        cols[name] = ccpath.normals[:, k]
    cols["row"] = np.asarray(ccpath.rows, np.int64)
    if ccpath.feed_dirs is not None:
        for k, name in enumerate(("fx", "fy", "fz")):
            cols[name] = ccpath.feed_dirs[:, k]
    if ccpath.feed is not None:
        cols["feed"] = np.asarray(ccpath.feed, float)
    write_table(path, cols)
