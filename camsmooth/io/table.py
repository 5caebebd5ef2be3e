"""The one validated CSV table reader: every CSV camsmooth reads (CC paths, CL tables, result
CSVs, calibration measurements, recordings) goes through ``read_table``.

What a file may be
------------------
- UTF-8 text, with or without a byte-order mark; line ends LF, CRLF or CR.
- Comma-separated, one header line first (line 1), then one record per line. Fields may be
  quoted with '"'. A file whose header uses ';', a tab or '|' instead of ',' is refused with a
  message naming the delimiter it uses.
- Header names are matched case-insensitively after stripping blanks; a missing required column
  is named, with the closest header name offered as a likely misspelling. A name may appear once.
- Blank lines are skipped.

Rows
----
Every error names the file, the **row** and, where it applies, the column. A row is a 1-based
data row, the header being row 0 (CONVENTIONS.md): row = line number in the file - 1, so that
row k is the k-th record of a file without blank lines, and blank lines, which are skipped, still
count (row + 1 is always the line an editor shows). ``Table.rows`` gives each record's row, for
callers that validate further (unit vectors, monotonic time ...) and report with
``Table.error``.

Values
------
Numeric columns are parsed by polars' CSV reader (Rust, multi-threaded: a million 11-column
rows in well under a second, see benchmarks/bench_io.py), falling back to ``numpy.loadtxt`` (C
parser) for anything polars does not take as plain numbers, never by a Python loop per cell.
The per-cell scan runs only on the error path, to name the first bad cell. NaN and inf are
refused unless the column is listed in ``nonfinite``. Integer columns must hold integral
values. Messages show values as written in the file or as plain Python numbers (no numpy
reprs).
"""

from __future__ import annotations

import csv
import difflib
import io
import math
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from camsmooth.errors import InputError

__all__ = ["Table", "read_table", "number_text", "read_text_file", "write_table"]

_OTHER_DELIMITERS = ((";", "';'"), ("\t", "a tab"), ("|", "'|'"))


def number_text(value: float) -> str:
    """A float as plain text for messages: Python's shortest repr ('nan', 'inf', '-inf' as such),
    never a numpy repr such as 'np.float64(1.0)'."""
    v = float(value)
    if math.isnan(v):
        return "nan"
    if math.isinf(v):
        return "inf" if v > 0 else "-inf"
    return repr(v)


@dataclass
class Table:
    """A parsed CSV table.

    file: the path as given (str). header: the names in the file, stripped, in file order.
    columns: canonical name (the spelling the caller asked for, or the file's own spelling for
    undeclared columns read with ``others='float'``) -> (N,) array: float64, int64 for integer
    columns, str for text columns. rows: (N,) int64 data row of each record (header = row 0; see
    the module docstring). ignored: header names that were not read.
    """

    file: str
    header: tuple[str, ...]
    columns: dict[str, np.ndarray]
    rows: np.ndarray
    ignored: tuple[str, ...] = field(default_factory=tuple)

    def __len__(self) -> int:
        return len(self.rows)

    def __contains__(self, name: object) -> bool:
        return name in self.columns

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def error(self, message: str, index: int | None = None, column: str | None = None) -> InputError:
        """An InputError naming this file, the row of record ``index`` (0-based record index;
        None for a whole-file error) and ``column``."""
        row = None if index is None else int(self.rows[int(index)])
        return InputError(message, file=self.file, row=row, column=column)

    def header_error(self, message: str, column: str | None = None) -> InputError:
        """An InputError about the header (row 0) of this file."""
        return InputError(message, file=self.file, row=0, column=column)


def read_text_file(path: str | os.PathLike, what: str = "file") -> str:
    """The text of a UTF-8 file (a byte-order mark is dropped; CRLF and CR become LF).

    InputError naming the file when it cannot be read, is UTF-16 (a common spreadsheet export) or
    is not UTF-8.
    """
    file = str(path)
    try:
        raw = Path(path).read_bytes()
    except FileNotFoundError:
        raise InputError(f"cannot read the {what}: file not found", file=file) from None
    except IsADirectoryError:
        raise InputError(f"cannot read the {what}: it is a folder, not a file", file=file) from None
    except OSError as exc:
        raise InputError(f"cannot read the {what}: {exc.strerror or exc}", file=file) from None
    if raw.startswith((b"\xff\xfe", b"\xfe\xff")):
        raise InputError(f"the {what} is UTF-16 text; save it as UTF-8", file=file)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        # exc.start counts in exc.object, which is the file's bytes after a byte-order mark
        bad = bytes(exc.object)
        line = bad[:exc.start].count(b"\n") + 1
        raise InputError(f"the {what} is not UTF-8 text (byte 0x{bad[exc.start]:02x} on line {line})",
                         file=file) from None
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    return text


def _header_fields(line: str, file: str) -> list[str]:
    try:
        return [h.strip() for h in next(csv.reader([line]))]
    except (csv.Error, StopIteration) as exc:  # pragma: no cover - csv accepts almost anything
        raise InputError(f"cannot read the header row: {exc}", file=file, row=0) from None


def _check_delimiter(line: str, file: str) -> None:
    if "," in line:
        return
    for d, name in _OTHER_DELIMITERS:
        if d in line:
            raise InputError(f"the file uses {name} as delimiter; camsmooth reads comma-separated files "
                             "(export with ',' between fields and '.' as the decimal mark)", file=file, row=0)


def _cell_problem(cell: str) -> str | None:
    """Why a cell is not a number as numpy.loadtxt reads it (None when it is one)."""
    s = cell.strip()
    if not s:
        return "empty value (expected a number)"
    try:
        if "_" in s:  # Python's float() accepts '1_0'; the C parser does not
            raise ValueError
        float(s)
    except ValueError:
        return f"unparsable value {s!r} (expected a number)"
    return None


def _fast_columns(data: bytes, usecols: Sequence[int], n: int, dtype: str = "float") -> list[np.ndarray] | None:
    """The columns ``usecols`` of a headerless CSV body (UTF-8 bytes, ``n`` records) by polars, one
    array each: floats (dtype 'float') or stripped strings ('text'); None when polars does not read every
    cell as a plain value (the caller's slower parser then decides, and names the bad cell)."""
    import polars as pl

    kind = pl.Float64 if dtype == "float" else pl.Utf8
    try:
        df = pl.read_csv(data, has_header=False, columns=list(usecols),
                         schema_overrides={f"column_{j + 1}": kind for j in usecols}, infer_schema=False,
                         quote_char='"', truncate_ragged_lines=False)
    except Exception:  # any parse failure: the slower parser decides
        return None
    if df.height != n or df.null_count().sum_horizontal().item():
        return None
    if dtype == "float":  # column by column: a 2-D copy of a multi-chunk frame costs seconds at 1M rows
        return [df[c].to_numpy().astype(float, copy=False) for c in df.columns]
    return [df[c].str.strip_chars().to_numpy().astype(str) for c in df.columns]


def write_table(path: str | os.PathLike, columns: dict[str, np.ndarray]) -> Path:
    """Write columns (name -> array, all the same length) as a CSV table at ``path``, atomically:
    header line, then one record per row; floats in their shortest exact round-trip form ('NaN',
    'inf' as such), integers as integers, strings as written. By polars (a million rows of 25
    columns in about 2 s, where Python's csv module takes ~20 s)."""
    import polars as pl

    from camsmooth.io.atomic import atomic_path

    df = pl.DataFrame({name: np.asarray(v) for name, v in columns.items()})
    with atomic_path(Path(path)) as tmp:
        df.write_csv(tmp, line_terminator="\n")
    return Path(path)


def read_table(path: str | os.PathLike, required: Sequence[str] = (), optional: Sequence[str] = (), *,
               integer: Iterable[str] = (), text: Iterable[str] = (), nonfinite: Iterable[str] = (),
               others: str = "ignore", min_rows: int = 1, what: str = "file") -> Table:
    """Read a CSV table (module docstring for the accepted format and the row numbering).

    required / optional: column names (matched case-insensitively; the result uses these
    spellings). integer: columns that must hold integers (int64). text: columns kept as stripped
    strings. nonfinite: float columns where NaN / inf are allowed (refused elsewhere). others:
    'ignore' (undeclared columns are listed in ``Table.ignored``) or 'float' (they are read as
    floats, NaN / inf allowed, under their own spelling). min_rows: fewest records accepted.
    what: how messages name the file ("CC path", "result file" ...).

    Raises InputError naming the file, the row and the column for: a file that cannot be read or
    is not UTF-8, an empty file, another delimiter than ',', an empty or duplicated header name, a
    missing required column (with the closest name as a hint), a record with more or fewer fields
    than the header, an empty or unparsable cell, a non-finite value where none is allowed, a
    non-integer in an integer column, fewer than ``min_rows`` records.
    """
    if others not in ("ignore", "float"):
        raise ValueError("others must be 'ignore' or 'float'")
    file = str(path)
    content = read_text_file(path, what)
    if not content.strip():
        raise InputError(f"empty file (the {what} has no header row and no data rows)", file=file)
    head, _, body = content.partition("\n")
    del content  # a large file is held once (the body), not twice
    if not head.strip():
        raise InputError("the first line (header row) is empty", file=file, row=0)
    _check_delimiter(head, file)
    header = _header_fields(head, file)
    ncol = len(header)

    # ---- header: declared columns, duplicates, missing ones -------------------------------------
    exact: dict[str, int] = {}
    for j, h in enumerate(header):
        if h in exact and h:
            raise InputError("column appears twice in the header", file=file, row=0, column=h)
        exact[h] = j
    integer, text, nonfinite = set(integer), set(text), set(nonfinite)
    declared_names = list(dict.fromkeys(list(required) + list(optional)))
    index: dict[str, int] = {}
    # exact spelling first (the result CSV has both 'x' and 'X'), then case-insensitively
    for name in declared_names:
        if name in exact:
            index[name] = exact[name]
    taken = set(index.values())
    for name in declared_names:
        if name in index:
            continue
        hits = [j for j, h in enumerate(header) if h.lower() == name.lower() and j not in taken]
        if len(hits) > 1:
            raise InputError(f"column '{name}' appears twice in the header (as "
                             f"{' and '.join(repr(header[j]) for j in hits)})", file=file, row=0, column=name)
        if hits:
            index[name] = hits[0]
            taken.add(hits[0])
    for name in required:
        if name not in index:
            declared = {n.lower() for n in list(required) + list(optional)}
            candidates = [h for h in header if h and h.lower() not in declared]
            close = difflib.get_close_matches(name.lower(), [c.lower() for c in candidates], n=1, cutoff=0.6)
            hint = ""
            if close:
                hint = f" (found '{candidates[[c.lower() for c in candidates].index(close[0])]}': misspelt?)"
            raise InputError(f"missing column '{name}'{hint}", file=file, row=0, column=name)
    used = set(index.values())
    if others == "float":
        for j, h in enumerate(header):
            if j not in used:
                if not h:
                    raise InputError(f"empty column name in the header (field {j + 1})", file=file, row=0)
                index[h] = j
        used = set(index.values())
    ignored = tuple(h for j, h in enumerate(header) if j not in used)

    # ---- records and their rows ---------------------------------------------------------------
    body = body.rstrip(" \t\n")  # trailing blank lines (and blanks after the last field) are nothing
    if not body:
        rows = np.zeros(0, dtype=np.int64)
    elif body[0] in "\n \t" or "\n\n" in body or "\n " in body or "\n\t" in body:
        # maybe blank lines: sort them out line by line
        lines = body.split("\n")
        keep = [k for k, ln in enumerate(lines) if ln.strip()]
        rows = np.asarray(keep, dtype=np.int64) + 1
        body = "\n".join(lines[k] for k in keep)
    else:
        rows = np.arange(1, body.count("\n") + 2, dtype=np.int64)
    n = len(rows)
    if n < min_rows:
        raise InputError("no data rows after the header" if n == 0 else
                         f"{n} data row(s); at least {min_rows} are needed", file=file, row=n + 1 if n else None)

    def locate(cols: Sequence[int] | None) -> None:
        """Error path: name the first record with a wrong field count or (in ``cols``) a bad cell."""
        for k, rec in enumerate(csv.reader(io.StringIO(body))):
            row = int(rows[k]) if k < n else None
            if len(rec) > ncol:
                raise InputError(f"{len(rec)} fields but the header has {ncol} (a decimal comma?)",
                                 file=file, row=row)
            if len(rec) < ncol:
                short = [j for j in sorted(used) if j >= len(rec)]
                col = header[short[0]] if short else header[len(rec)]
                name = next((c for c, j in index.items() if header[j] == col), col)
                raise InputError(f"missing value ({len(rec)} fields, header has {ncol})", file=file, row=row,
                                 column=name)
            for j in cols or ():
                why = _cell_problem(rec[j])
                if why:
                    name = next(c for c, jj in index.items() if jj == j)
                    raise InputError(why, file=file, row=row, column=name)

    if n and '"' not in body and body.count(",") != n * (ncol - 1):
        locate(None)  # a record has more or fewer fields than the header (commas cannot hide in quotes)

    # ---- values --------------------------------------------------------------------------------
    columns: dict[str, np.ndarray] = {}
    data = body.encode() if n else b""
    numeric = [(name, j) for name, j in index.items() if name not in text]
    if numeric:
        usecols = [j for _, j in numeric]
        if n:
            try:
                values = _fast_columns(data, usecols, n)
                if values is None:
                    values = list(np.loadtxt(io.StringIO(body), delimiter=",", usecols=usecols, dtype=float,
                                             ndmin=2, comments=None, quotechar='"').T)
            except ValueError as exc:
                locate(usecols)
                raise InputError(f"cannot parse the table: {exc}", file=file) from None
            if len(values) != len(usecols) or any(v.shape != (n,) for v in values):
                locate(usecols)
                raise InputError("cannot parse the table (record count changed)", file=file)
        else:
            values = [np.zeros(0) for _ in usecols]
        for (name, _), v in zip(numeric, values, strict=True):
            columns[name] = np.ascontiguousarray(v)
    strings = [(name, j) for name, j in index.items() if name in text]
    if strings:
        if n:
            cells = _fast_columns(data, [j for _, j in strings], n, dtype="text")
            if cells is None:
                cells = [np.char.strip(c.astype(str)) for c in
                         np.loadtxt(io.StringIO(body), delimiter=",", usecols=[j for _, j in strings], dtype=str,
                                    ndmin=2, comments=None, quotechar='"').T]
        else:
            cells = [np.zeros(0, dtype=str) for _ in strings]
        for (name, _), c in zip(strings, cells, strict=True):
            columns[name] = c

    # ---- finiteness and integers, column by column in file order --------------------------------
    for name in sorted(index, key=lambda c: index[c]):
        if name in text:
            continue
        a = columns[name]
        free = name in nonfinite or (others == "float" and name not in required and name not in optional)
        if name in integer or not free:
            bad = ~np.isfinite(a)
            if bad.any():
                k = int(np.argmax(bad))
                raise InputError(f"non-finite value {number_text(a[k])}", file=file, row=int(rows[k]), column=name)
        if name in integer:
            frac = (a != np.round(a)) | (np.abs(a) > 2.0**53)
            if frac.any():
                k = int(np.argmax(frac))
                raise InputError(f"not an integer: {number_text(a[k])}", file=file, row=int(rows[k]),
                                 column=name)
            columns[name] = a.astype(np.int64)
    order = sorted(index, key=lambda c: index[c])
    return Table(file=file, header=tuple(header), columns={c: columns[c] for c in order}, rows=rows,
                 ignored=ignored)
