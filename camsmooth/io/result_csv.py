"""camsmooth's result CSV, the format: its columns and its reader (the writer of a smoothing
result is camsmooth.smoothing.output.write_result_csv; ``analyze`` and ``predict`` read the file
back through here, below the smoothing layer).

One row per CC point of the written method; units in the file: mm, s, degrees (radians inside the
code; docs/CONVENTIONS.md).
"""

from __future__ import annotations

import os
from collections.abc import Sequence

import numpy as np

from camsmooth.io.table import read_table, read_text_file
from camsmooth.machine.kinematics import ROTARY_NAMES

__all__ = ["OUTPUT_COLUMNS", "RESULT_CSV_COLUMNS", "STATUSES", "INT_COLUMNS", "output_columns", "read_result_csv",
           "result_rotary"]

#: columns of the output CSV on an AB head; on another machine the rotary columns carry its axes'
#: names (``output_columns``)
OUTPUT_COLUMNS = ("row", "idx", "t", "x", "y", "z", "nx", "ny", "nz", "clx", "cly", "clz", "i", "j", "k",
                  "lead", "tilt", "A", "B", "X", "Y", "Z", "delta")
#: where the two rotary columns sit in OUTPUT_COLUMNS
_ROTARY_AT = OUTPUT_COLUMNS.index("A")
#: Columns of the result CSV: OUTPUT_COLUMNS, then ``lift`` (mm) and ``status``.
RESULT_CSV_COLUMNS: tuple[str, ...] = OUTPUT_COLUMNS + ("lift", "status")
#: Per-point status values, least to most severe; a point gets the most severe that applies.
STATUSES: tuple[str, ...] = ("ok", "lifted", "interference", "unreachable")
#: the columns written and read as integers
INT_COLUMNS = ("row", "idx")
_STR_COLUMNS = ("status",)


def output_columns(rotary: Sequence[str] = ("A", "B")) -> tuple[str, ...]:
    """The output CSV's columns for a machine with rotary axes ``rotary`` (``Machine.rotary``:
    ("A", "C") on an AC table): OUTPUT_COLUMNS with its rotary columns named by the machine."""
    return OUTPUT_COLUMNS[:_ROTARY_AT] + tuple(rotary) + OUTPUT_COLUMNS[_ROTARY_AT + 2:]


def read_result_csv(path: str | os.PathLike, required: Sequence[str] | None = None
                    ) -> dict[str, np.ndarray]:
    """Read a result CSV (as written by camsmooth.smoothing.output.write_result_csv) into column
    arrays.

    Returns name -> array for every column in the file: ``row`` and ``idx`` int64, ``status``
    str, all others float (NaN allowed: an unknown clearance is written as nan; units as in the
    file: mm, s, degrees). Read by ``camsmooth.io.table.read_table``: InputError naming the file,
    row and column when the file is missing or empty, a ``required`` column is absent, a row has
    the wrong number of fields or a value is not a number / not an integer. required: None for
    the output columns of any machine kind (``output_columns`` with the rotary pair the header
    names: A,B or A,C or B,C).
    """
    if required is None:
        required = output_columns(result_rotary(path))
    declared = tuple(dict.fromkeys(list(required) + list(INT_COLUMNS) + list(_STR_COLUMNS)))
    table = read_table(path, required, [c for c in declared if c not in required], integer=INT_COLUMNS,
                       text=_STR_COLUMNS, nonfinite=[c for c in declared if c not in INT_COLUMNS],
                       others="float", min_rows=0, what="result file")
    return dict(table.columns)


def result_rotary(path: str | os.PathLike) -> tuple[str, str]:
    """The rotary columns a result CSV's header names (("A", "B") on an AB head, ("A", "C") on an
    AC table, ...): the two of A, B, C that are columns, in alphabetical order (the order of
    ``Machine.rotary``); ("A", "B") when not exactly two are (the reader then names the missing
    columns)."""
    text = read_text_file(path, "result file")
    first = next((ln for ln in text.splitlines() if ln.strip()), "")
    names = {h.strip().strip('"') for h in first.split(",")}
    present = [n for n in ROTARY_NAMES if n in names]
    return (present[0], present[1]) if len(present) == 2 else ("A", "B")
