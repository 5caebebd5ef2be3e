"""Error types. Every bad input raises one of these with a message that names the file,
row, column or binding constraint; the CLI prints the message and exits non-zero."""

from __future__ import annotations


class CamsmoothError(Exception):
    """Base class of all errors camsmooth raises on purpose (bad input, infeasible limits)."""


class InputError(CamsmoothError, ValueError):
    """Bad input: a file, a column, a value or an option that cannot be used.

    The message names where: ``file``, 1-based data ``row`` (the header is row 0) and ``column``
    when they are known; for files read line by line (APT/CLSF, G-code) the 1-based ``line``; for
    JSON and TOML files the ``key`` (dotted: "servo.Kv.X").
    """

    def __init__(self, message: str, *, file: str | None = None, row: int | None = None,
                 column: str | None = None, line: int | None = None, key: str | None = None) -> None:
        self.message, self.file, self.row, self.column, self.line, self.key = message, file, row, column, line, key
        where = []
        if file is not None:
            where.append(str(file))
        if line is not None:
            where.append(f"line {line}")
        if row is not None:
            where.append(f"row {row}")
        if column is not None:
            where.append(f"column '{column}'")
        if key is not None:
            where.append(f"key '{key}'")
        super().__init__((": ".join([", ".join(where), message])) if where else message)

    def about(self, option: str) -> InputError:
        """The same error, its message prefixed with the command-line option that named the file."""
        return InputError(f"{option}: {self.message}", file=self.file, row=self.row, column=self.column,
                          line=self.line, key=self.key)


class InfeasibleError(CamsmoothError):
    """A problem that has no solution under the stated limits; the message names the binding
    constraint (axis, limit, row, point)."""


class InternalError(RuntimeError):
    """A failure inside camsmooth that no input explains (a fit that broke down numerically, a
    value computed here that a constructor refuses): a bug to report, never bad input. Not a
    CamsmoothError, so the CLI exits 70 (internal error) on it, not 2."""
