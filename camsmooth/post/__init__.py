"""Posted programs: the G-code a CAM post-processor writes for one machine and one controller,
read into the one program model (camsmooth.io.program.CLProgram) and written from the one
writer's model (camsmooth.post.model.PostProgram), one module per dialect (trimesh ``exchange/``
layout: each dialect module ends with its ``DIALECTS`` entries -- name, reader, the writer's
words -- and this package merges them into ``DIALECTS``; a sixth dialect is one module and one
name in ``_MODULES``). Shared: camsmooth.post.core (the readers' program builder),
camsmooth.post.writer (the writer), camsmooth.post.model (its model, the "as written" rounding),
camsmooth.post.own (the reader of camsmooth's own programs), camsmooth.post.rewrite (smoothed
blocks written back into a posted program).

=============  ==============================  =============================================
dialect        module                          controllers
=============  ==============================  =============================================
iso            camsmooth.post.iso              ISO G-code, Fanuc, Haas, Mori Seiki, Okuma-style
generic        camsmooth.post.iso              (written: ISO words only, no TCP command)
fanuc / haas   camsmooth.post.iso              (the same reader, Haas words G234/G254 named)
linuxcnc       camsmooth.post.linuxcnc         LinuxCNC (M428/M429 trt TCP, ``#<name>`` params)
heidenhain     camsmooth.post.heidenhain       Heidenhain Klartext (iTNC 530, TNC 640)
siemens        camsmooth.post.siemens          Siemens Sinumerik 840D
millplus       camsmooth.post.millplus         Heidenhain / Philips MillPlus (``%PM``)
=============  ==============================  =============================================

``load_program`` (camsmooth.post.load) reads any program file, the format from its content (APT,
CL/CC CSV, result CSV, G-code); ``detect_dialect`` tells the dialects apart; ``read_posted`` reads a
posted program; ``write_program``
(camsmooth.post.writer) writes a PostProgram in a dialect whose entry has ``own`` set (generic,
fanuc, linuxcnc, siemens, heidenhain: ``[post] dialect`` of a machine file). This package imports
neither camsmooth.smoothing nor camsmooth.controller (tests/test_post_registry.py checks it).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

from camsmooth.errors import InputError
from camsmooth.io.program import CLProgram
from camsmooth.post import heidenhain, iso, linuxcnc, millplus, siemens
from camsmooth.post.model import PostDialect, PostProgram
from camsmooth.post.writer import write_program

__all__ = ["read_posted", "detect_dialect", "posted_text", "READERS", "DIALECTS", "PostDialect", "PostProgram",
           "write_program", "load_program"]

#: the dialect modules, each ending with its DIALECTS entries
_MODULES = (iso, linuxcnc, siemens, heidenhain, millplus)
#: dialect name -> its entry (reader, writer words, whether camsmooth writes whole programs in it)
DIALECTS: dict[str, PostDialect] = {e.name: e for m in _MODULES for e in m.DIALECTS}
#: dialect -> reader(path, text, machine, dialect, chord_tol)
READERS: dict[str, Callable[..., CLProgram]] = {name: e.reader for name, e in DIALECTS.items()}

_HEIDENHAIN = re.compile(r"^\s*\d*\s*BEGIN\s+PGM\b", re.I | re.M)
#: Siemens words (searched outside '( )' comments) and calls (searched in the text itself: their
#: parentheses are syntax, not comments)
_SIEMENS = re.compile(r"\b(TRAORI|TRAFOOF|CYCLE8\d\d|AROT|ATRANS|SUPA|G153|G500|G700|G710|FNORM|ADIS|"
                      r"DEF\s+(REAL|INT)|ORIWKS|ORIVECT|ORIAXES|COMPCAD|COMPCURV|SOFT|FFWON|G64[12]|EXTCALL|"
                      r"T\s*=\s*\")", re.I)
_SIEMENS_CALL = re.compile(r"(\b(MCALL\s+)?CYCLE\d+\s*\(|\b[A-Z]\w*\s*=\s*(IC|AC|DC|ACP|ACN)\s*\(|\bMSG\s*\(|"
                           r"\bWORKPIECE\s*\(|^%_N_)", re.I | re.M)
#: G70 / G71 as the 840D's inch / metric (a block without the P Q U W words of a turning cycle's G70/G71)
_SIEMENS_UNITS = re.compile(r"^[^\n(]*\bG7[01]\b(?![^\n]*\b[PQUW]\s*[-+.\d])", re.I | re.M)
_LINUXCNC = re.compile(r"(\bM42[89]\b|#<|\bo\d+\s+(sub|call|if|while)\b|\bG64\s*P)", re.I)
_HAAS = re.compile(r"\bG(234|254|255|187|154)\b", re.I)


def detect_dialect(text: str) -> str:
    """The dialect of a posted program from its content: Heidenhain (``BEGIN PGM``), MillPlus (a
    first line ``%PM``), Siemens (its
    keywords: TRAORI, CYCLE800, AROT, ``X=IC(..)`` ...), LinuxCNC (M428/M429, ``#<name>``,
    o-words), Haas (G234, G254, G187, G154), else ISO/Fanuc."""
    head = text[:400_000]
    if _HEIDENHAIN.search(head):
        return "heidenhain"
    first = next((ln.strip() for ln in head.split("\n") if ln.strip()), "")
    if first.upper().startswith("%PM"):
        return "millplus"
    plain = "\n".join(ln.split(";", 1)[0] for ln in head.split("\n"))
    code = re.sub(r"\([^()\n]*\)", "", plain)
    if _SIEMENS.search(code) or _SIEMENS_CALL.search(plain) or _SIEMENS_UNITS.search(code):
        return "siemens"
    if _LINUXCNC.search(head):
        return "linuxcnc"
    if _HAAS.search(code):
        return "haas"
    return "iso"


def read_posted(path: str | os.PathLike, text: str | None = None, machine: Any = None, dialect: str | None = None,
                chord_tol: float | None = None) -> CLProgram:
    """Read a posted program (any dialect of READERS; None: ``detect_dialect``) as a CLProgram:
    tool tip and unit tool axis per point in the program's workpiece frame (mm), feed mm/min,
    rapids apart, operations named from the post's comments, canned cycles listed
    (``CLProgram.cycles``), what was not applied named in ``CLProgram.warnings``.

    machine: a camsmooth Machine (its kinematics in machine mode, its tool axis in TCP mode);
    None: the nominal machine of the rotary letters the program uses, with a warning."""
    file = str(path)
    notes: list[str] = []
    if text is None:
        text = posted_text(path, notes)
    if dialect is None:
        dialect = detect_dialect(text)
    if dialect not in READERS:
        raise InputError(f"unknown dialect {dialect!r} (known: {', '.join(READERS)})", file=file)
    text = text.replace("\t", " ")
    program = READERS[dialect](file, text, machine, dialect, chord_tol)
    program.warnings[:0] = notes
    return program


def posted_text(path: str | os.PathLike, notes: list[str]) -> str:
    """The text of a posted program: UTF-8 (a BOM dropped, CRLF and CR read as LF), else Latin-1 with
    a note (CAM systems on Windows write comments in their code page: '(Fräser Ø10)'; the blocks
    themselves are ASCII). InputError naming the file when it cannot be read or is UTF-16."""
    from camsmooth.io.table import read_text_file

    try:
        return read_text_file(path, "G-code file")
    except InputError as exc:
        if "is not UTF-8 text" not in exc.message:
            raise
        notes.append(f"{exc.message}: read as Latin-1 (only comments should hold such bytes)")
    raw = Path(path).read_bytes()
    return raw.decode("latin-1").replace("\r\n", "\n").replace("\r", "\n")


# last: the loader reads G-code through the functions above
from camsmooth.post.load import load_program  # noqa: E402
