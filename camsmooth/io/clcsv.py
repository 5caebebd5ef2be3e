"""Cutter-location (CL) tables as CSV -> CLProgram.

Format: one header row, one data row per tool pose in machining order, read by
``camsmooth.io.table.read_table`` (case-insensitive names, BOM accepted, other delimiters named,
blank lines skipped; rows are 1-based data rows, header = row 0). Extra columns are ignored.

- required: ``x, y, z``: tool tip (centre of the cutter's bottom face), mm, workpiece frame;
  ``i, j, k``: unit tool axis from the tip toward the spindle (a length off 1 by more than
  ``UNIT_TOL`` is an error, within it the axis is normalised)
- optional: ``row`` (integer row id, rows are contiguous runs; default one row 0), ``feed``
  (mm/min, > 0; default unknown = NaN)

Every point is a cutting move (a CL table has no rapids); one tool path, named after the file,
with no tool.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from camsmooth.io.atomic import write_text_atomic
from camsmooth.io.ccpath import integer_row_ids, positive_feed, unit_columns
from camsmooth.io.program import CLProgram, ToolPath
from camsmooth.io.table import read_table

__all__ = ["read_cl_csv", "write_cl_csv", "CL_REQUIRED", "CL_OPTIONAL"]

CL_REQUIRED = ("x", "y", "z", "i", "j", "k")
CL_OPTIONAL = ("row", "feed")


def read_cl_csv(path: str | os.PathLike) -> CLProgram:
    """Read a CL CSV (module docstring); InputError naming file, row and column on bad input."""
    t = read_table(path, CL_REQUIRED, CL_OPTIONAL, integer=("row",), what="CL program")
    tip = np.stack([t["x"], t["y"], t["z"]], axis=1)
    axis = unit_columns(t, ("i", "j", "k"), "tool axis")
    rows = integer_row_ids(t)
    feed = positive_feed(t)
    n = len(t)
    tp = ToolPath(name=Path(t.file).stem, tool=None, start=0, stop=n, line=None)
    return CLProgram(tip=tip, axis=axis, rows=rows, feed=np.full(n, np.nan) if feed is None else feed,
                     rapid=np.zeros(n, dtype=bool), line=t.rows, toolpaths=[tp], source=t.file, format="cl-csv")


def write_cl_csv(path: str | os.PathLike, program: CLProgram) -> Path:
    """Write the cutting points of ``program`` as a CL CSV, atomically, '%.17g' floats (exact round
    trip with ``read_cl_csv``). Columns x,y,z,i,j,k,row[,feed] (feed when every point has one)."""
    p = program.cutting()
    axis = p.require_axis()
    cols = ["x", "y", "z", "i", "j", "k", "row"]
    parts = [np.char.mod("%.17g", p.tip), np.char.mod("%.17g", axis), np.char.mod("%d", p.rows.reshape(-1, 1))]
    if len(p) and np.all(np.isfinite(p.feed)):
        cols.append("feed")
        parts.append(np.char.mod("%.17g", p.feed.reshape(-1, 1)))
    table = np.concatenate(parts, axis=1) if len(p) else np.zeros((0, len(cols)), dtype=str)
    body = "\n".join(",".join(r) for r in table.tolist())
    write_text_atomic(path, ",".join(cols) + "\n" + body + ("\n" if body else ""))
    return Path(path)
