"""What a program needs around its motion to run as is: the tool call, the spindle, the coolant
and the work offset, as the CAM input names them (APT/CLSF ``LOAD/TOOL,n`` / ``LOADTL/n``,
``SPINDL/[RPM,]n[,CLW|CCLW]``, ``COOLNT/ON|FLOOD|MIST|THRU``) or the command line gives them
(``--work-offset G54``), and the blocks each dialect spells them with (camsmooth.post.writer writes
them after its program start and before the tool-centre-point command; M9 M5 before the end).

Blocks: ISO dialects (generic, fanuc, linuxcnc) ``G54``, ``T1 M6``, ``S12000 M3``, ``M8``;
Siemens ``G54``, ``T1``, ``M6``, ``D1``, ``S12000 M3``, ``M8``; Heidenhain ``TOOL CALL 1 Z S12000``,
``M3``, ``M8`` (its presets are set on the control, not by a G code: the work offset is written as
a comment). Coolant: flood and ON M8, mist M7, through-spindle M8 (the through-coolant M code is the
machine builder's). CLW M3, CCLW M4.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass
from typing import Any

from camsmooth.errors import InputError

__all__ = ["ShopSetup", "shop_setup", "parse_work_offset"]

_WORK_OFFSET = re.compile(r"^(G5[4-9](\.1\s*P\d{1,3})?|G5\d\d)$")
_SPINDL = re.compile(r"^\s*SPINDL\s*/\s*(?:RPM\s*,\s*)?([-+]?\d+\.?\d*)\s*(?:,\s*(CLW|CCLW))?", re.I | re.M)
_COOLNT = re.compile(r"^\s*COOLNT\s*/\s*(ON|FLOOD|MIST|THRU|TAP)\b", re.I | re.M)


@dataclass(frozen=True)
class ShopSetup:
    """Tool number, spindle speed (rev/min) and direction ('M3' / 'M4'), coolant M code, work offset;
    None where nothing names it."""

    tool: int | None = None
    spindle_rpm: float | None = None
    spindle_dir: str = "M3"
    coolant: str | None = None
    work_offset: str | None = None

    @property
    def empty(self) -> bool:
        return self.tool is None and self.spindle_rpm is None and self.coolant is None and self.work_offset is None

    def start_blocks(self, dialect: str) -> list[str]:
        """The blocks after the program start (module docstring)."""
        out: list[str] = []
        s = None if self.spindle_rpm is None else f"S{self.spindle_rpm:g}"
        if dialect == "heidenhain":
            if self.work_offset:
                out.append(f"; work offset {self.work_offset}: set the preset on the control")
            if self.tool is not None:  # the speed is a word of the TOOL CALL: without a tool number, none
                out.append(f"TOOL CALL {self.tool} Z" + (f" {s}" if s else ""))
                if s:
                    out.append(self.spindle_dir)
        else:
            if self.work_offset:
                out.append(self.work_offset)
            if self.tool is not None:
                out += [f"T{self.tool}", "M6", "D1"] if dialect == "siemens" else [f"T{self.tool} M6"]
            if s:
                out.append(f"{s} {self.spindle_dir}")
        if self.coolant:
            out.append(self.coolant)
        return out

    def end_blocks(self) -> list[str]:
        """Coolant and spindle off, before the program's end."""
        return (["M9"] if self.coolant else []) + (["M5"] if self.spindle_rpm is not None else [])


def parse_work_offset(text: str | None) -> str | None:
    """``--work-offset``: G54 ... G59, G54.1 P1 ... (Fanuc's extended offsets) or G500 ... G599
    (Siemens settable frames); InputError otherwise."""
    if text is None:
        return None
    t = " ".join(text.upper().split())
    if not _WORK_OFFSET.match(t):
        raise InputError(f"--work-offset {text!r}: not a work offset (G54 ... G59, G54.1 P<n>, G500 ... G599)")
    return t


def shop_setup(program: Any, path: str | os.PathLike | None, work_offset: str | None) -> ShopSetup:
    """The setup the CAM input names: the tool number of its first cutting tool path
    (``Tool.number``), from an APT/CLSF file the first ``SPINDL`` with a speed and the first
    ``COOLNT`` that turns it on; ``work_offset`` (``--work-offset``) where the input names none.
    program: a CLProgram (or None for a CC path)."""
    tool = None
    for tp in getattr(program, "toolpaths", None) or []:
        if tp.tool is not None and tp.tool.number is not None:
            tool = int(tp.tool.number)
            break
    rpm, direction, coolant = None, "M3", None
    if program is not None and getattr(program, "format", None) in ("apt", "clsf", "cldata") and path is not None:
        from camsmooth.io.table import read_text_file

        text = read_text_file(path, "APT file")
        m = _SPINDL.search(text)
        if m and float(m.group(1)) > 0:
            rpm = float(m.group(1))
            direction = "M4" if (m.group(2) or "").upper() == "CCLW" else "M3"
        c = _COOLNT.search(text)
        if c:
            coolant = "M7" if c.group(1).upper() == "MIST" else "M8"
    return ShopSetup(tool=tool, spindle_rpm=rpm, spindle_dir=direction, coolant=coolant,
                     work_offset=parse_work_offset(work_offset))
