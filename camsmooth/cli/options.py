"""Option parsing shared by the CLI verbs: a parser whose errors are one line, and argparse
``type=`` functions that check ranges at parse time (units in the message: mm, s, deg, mm/min).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import Any, NoReturn


class CliParser(argparse.ArgumentParser):
    """ArgumentParser whose errors print one line (no usage block) and exit with status 2."""

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: error: {message} (see '{self.prog} --help')", file=sys.stderr)
        raise SystemExit(2)


def _bounds_text(gt: float | None, ge: float | None, lt: float | None, le: float | None, unit: str) -> str:
    parts = []
    if gt is not None:
        parts.append(f"> {gt:g}")
    if ge is not None:
        parts.append(f">= {ge:g}")
    if lt is not None:
        parts.append(f"< {lt:g}")
    if le is not None:
        parts.append(f"<= {le:g}")
    u = f" {unit}" if unit else ""
    if not parts:
        return f"a finite number{u}"
    texts = [f"positive (> 0{u})" if p == "> 0" else f"{p}{u}" for p in parts]
    return " and ".join(texts)


def number(*, gt: float | None = None, ge: float | None = None, lt: float | None = None, le: float | None = None,
           unit: str = "", integer: bool = False) -> Callable[[str], Any]:
    """An argparse type: a finite float (or an int with ``integer``) within the given bounds."""
    what = "a whole number" if integer else "a number"

    def parse(text: str) -> float | int:
        try:
            value: float | int = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        bad = not math.isfinite(value) or (gt is not None and value <= gt) or (ge is not None and value < ge) \
            or (lt is not None and value >= lt) or (le is not None and value > le)
        if bad:
            raise argparse.ArgumentTypeError(f"must be {_bounds_text(gt, ge, lt, le, unit)}, got {text}")
        return value

    parse.__name__ = "integer" if integer else "number"  # argparse names the type in some messages
    return parse


def angle_range(lo: float, hi: float, *, lo_open: bool = False, strict: bool = False
                ) -> Callable[[str], tuple[float, float]]:
    """An argparse type for MIN:MAX in degrees: lo <= MIN (lo < MIN with ``lo_open``), MIN <= MAX
    (MIN < MAX with ``strict``), MAX < hi."""

    def parse(text: str) -> tuple[float, float]:
        try:
            a, b = (float(v) for v in text.split(":"))
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected MIN:MAX in degrees, got {text!r}") from None
        ok = (math.isfinite(a) and math.isfinite(b) and ((a > lo) if lo_open else (a >= lo))
              and ((a < b) if strict else (a <= b)) and b < hi)
        if not ok:
            raise argparse.ArgumentTypeError(f"expected MIN:MAX in degrees with {lo:g} {'<' if lo_open else '<='} "
                                             f"MIN {'<' if strict else '<='} MAX < {hi:g}, got {text!r}")
        return a, b

    parse.__name__ = "range"
    return parse


def vector3(text: str) -> tuple[float, float, float]:
    """An argparse type: three finite numbers i,j,k, not all zero."""
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v) or not any(v):
        raise argparse.ArgumentTypeError(f"expected three numbers i,j,k, not all zero, got {text!r}")
    return v  # type: ignore[return-value]


def number_list(*, gt: float | None = None, ge: float | None = None, lt: float | None = None,
                le: float | None = None, unit: str = "") -> Callable[[str], list[float]]:
    """An argparse type: a non-empty comma list of numbers, each within the bounds."""
    one = number(gt=gt, ge=ge, lt=lt, le=le, unit=unit)

    def parse(text: str) -> list[float]:
        items = [s for s in text.split(",") if s.strip()]
        if not items:
            raise argparse.ArgumentTypeError(f"expected comma-separated numbers, got {text!r}")
        try:
            return [float(one(s.strip())) for s in items]
        except argparse.ArgumentTypeError as exc:
            raise argparse.ArgumentTypeError(f"each value {exc}") from None

    parse.__name__ = "list"
    return parse


def tighten(parser: argparse.ArgumentParser, types: dict[str, tuple[Callable[[str], Any], str]]) -> None:
    """Give arguments of a parser built elsewhere a checking type: ``types`` maps dest -> (argparse
    type, range text appended to the help). For sub-commands whose arguments another module defines."""
    for action in parser._actions:  # argparse has no public way to change an added argument
        if action.dest in types:
            action.type, text = types[action.dest]
            action.help = f"{action.help or ''}; {text}".lstrip("; ")
