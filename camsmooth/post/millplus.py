"""Heidenhain / Philips MillPlus (MillPlus IT) ISO programs (dialect 'millplus'): the ISO
interpreter of camsmooth.post.iso with MillPlus's own meanings turned into it, block by block.

What MillPlus means differently from Fanuc, as Autodesk's "MillPlus" post (millplus.cps, the
generic Heidenhain MillPlus post) writes it (no MillPlus programming manual was found among the
references searched; each meaning below is the one that post's output needs to run):

- ``%PM`` starts the program and ``N9000``..``N9999`` names it.
- ``G7 A5=a B5=b C5=c L1=t``: the tilted working plane, spatial angles (the post writes the work
  plane's Euler XYZ angles, as its Heidenhain post writes PLANE SPATIAL SPA SPB SPC): R = Rz(c)
  Ry(b) Rx(a); ``G7 L1=t`` without angles resets it. ``L1`` (turn the head or not) does not change
  the frame.
- ``G141`` alone: tool-centre-point mode (X Y Z the tool tip, A B C the rotary axes); ``G141 R..
  R1=.. L2=..``: the 3D tool correction's data (no motion); ``G40`` ends both.
- ``G93 X Y Z``: the absolute datum shift (not inverse-time feed); ``G92 X Y Z`` the incremental one.
- ``G2``/``G3``: I J K are the absolute centre; ``B5=360`` marks a full circle; a helix's pitch word
  does not change the path (its end Z does).
- ``G81``..``G86 Z.. Y.. B..``: a drilling cycle's definition (Z the depth below the hole's surface,
  negative); ``G79 X Y Z``: a hole at X Y, its surface at Z, so its bottom at Z + the depth.
- ``G74 ... L1``: a move in machine coordinates (not a point of the program). ``G4 X``: dwell.
Other words with ``=`` (``F2=``, ``I1=``) are named and do not move the tool.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from camsmooth.io.program import CLProgram
from camsmooth.post.core import Frame3, Skip, rot_x, rot_y, rot_z
from camsmooth.post.iso import GENERIC, IsoInterpreter
from camsmooth.post.model import PostDialect

__all__ = ["read_millplus", "DIALECTS"]

_NUMW = r"([-+]?(?:\d+\.?\d*|\.\d+))"


class _MillPlus(IsoInterpreter):
    def __init__(self, file: str, text: str, chord_tol: float | None) -> None:
        super().__init__(file, text, "millplus", chord_tol)
        self.keyword = self._keyword
        self.arc_abs = True  # I J K are the absolute centre
        self.depth: tuple[str, float] | None = None

    def _words_eq(self, code: str) -> dict[str, float]:
        return {k.upper(): float(v) for k, v in re.findall(r"\b([A-Z]\d?)\s*=\s*" + _NUMW, code, re.I)}

    def _plain(self, code: str) -> dict[str, float]:
        stripped = re.sub(r"\b[A-Z]\d\s*=\s*[-+]?[\d.]+", " ", code, flags=re.I)
        return {k.upper(): float(v) for k, v in re.findall(r"\b([A-Z])\s*" + _NUMW, stripped, re.I)}

    def _keyword(self, number: int, code: str, comments: list[str]) -> str:
        up = code.upper().strip()
        if up.startswith("%PM"):
            return ""
        g = [float(v) for v in re.findall(r"\bG\s*(\d+(?:\.\d+)?)", up)]
        eq = self._words_eq(up)
        plain = self._plain(up)
        if 7.0 in g:  # the tilted working plane
            a, b, c = (eq.get(k, 0.0) for k in ("A5", "B5", "C5"))
            self.tilt = Frame3(rot_z(math.radians(c)) @ rot_y(math.radians(b)) @ rot_x(math.radians(a))) \
                if any((a, b, c)) else Frame3()
            self._set_frame()
            self.b.note("G7 (tilted working plane)", number)
            return ""
        if 141.0 in g:
            if "R" in plain or eq:
                self.b.note("G141 R R1= L2= (3D tool correction data)", number)
            else:
                self.b.tcp = True
                self.b.note("G141 (tool centre point)", number)
            return ""
        if 40.0 in g:
            self.b.tcp = False
        if 93.0 in g or 92.0 in g:
            o = np.array([self._len(plain.get(k, 0.0)) for k in "XYZ"])
            self.local = Frame3(o=o) if 93.0 in g else Frame3(o=self.local.o + o)
            self._set_frame()
            self.b.note("G93/G92 (datum shift)", number)
            return ""
        if 74.0 in g:
            self.b.machine_move(number, "G74 (machine-coordinate move)")
            return ""
        if 4.0 in g:
            self.b.note("G4 (dwell)", number)
            return ""
        cyc = [x for x in g if x in (81.0, 83.0, 84.0, 85.0, 86.0)]
        if cyc:
            if "Z" not in plain:
                raise Skip(f"G{cyc[0]:g} without its depth Z")
            self.depth = (f"G{cyc[0]:g}", self._len(plain["Z"]))
            self.b.end_cycle()
            return ""
        if 79.0 in g:
            if self.depth is None:
                raise Skip("G79 (cycle call) without a cycle definition")
            x = self._len(plain["X"]) if "X" in plain else self.pos["X"]
            y = self._len(plain["Y"]) if "Y" in plain else self.pos["Y"]
            z = self._len(plain["Z"]) if "Z" in plain else self.pos["Z"]
            if any(map(math.isnan, (x, y, z))):
                raise Skip("G79 at an unknown position")
            self.b.cycle(self.depth[0], number, np.array([x, y, z + self.depth[1]]), code)
            return ""
        if eq:
            for k in eq:
                if k != "B5":
                    self.b.note(f"{k}= (not applied)", number)
            code = re.sub(r"\b[A-Z]\d\s*=\s*[-+]?[\d.]+", " ", code, flags=re.I)
        return code


def read_millplus(path: str, text: str, machine: Any = None, chord_tol: float | None = None) -> CLProgram:
    """Read a MillPlus program as a CLProgram (module docstring)."""
    return _MillPlus(str(path), text, chord_tol).run(machine)


def _read(path: str, text: str, machine: Any = None, dialect: str = "millplus",
          chord_tol: float | None = None) -> CLProgram:
    return read_millplus(path, text, machine, chord_tol)


#: MillPlus programs are read here; a rewrite writes the generic ISO blocks (G01 X Y Z with the
#: rotary words, G93 F where the input's block was) into them, camsmooth writes no whole MillPlus
#: program
DIALECTS = (PostDialect("millplus", _read, GENERIC, own=False),)
