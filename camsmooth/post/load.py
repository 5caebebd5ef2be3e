"""``load_program``: the one entry point to every program reader, the format picked from the
file's content (camsmooth.io.program.detect_format); trimesh.exchange.load style, one loader per
format in ``LOADERS``. It sits in the post layer because the G-code readers are here; the other
readers are camsmooth.io's.

=========  =====================================  ==========================================
format     reader                                 gives
=========  =====================================  ==========================================
apt        camsmooth.io.apt.read_apt              CLProgram (APT CLDATA: NX CLSF, ISO 4343 of Fusion/HSM)
cl-csv     camsmooth.io.clcsv.read_cl_csv         CLProgram (x,y,z,i,j,k[,row][,feed])
gcode      camsmooth.post.own.read_gcode          CLProgram (camsmooth's own G-code, any dialect)
gcode      camsmooth.post.read_posted             CLProgram (posted programs: ISO/Fanuc/Haas/LinuxCNC,
                                                  Heidenhain Klartext, Siemens 840D, MillPlus; no
                                                  camsmooth header)
cc-csv     camsmooth.io.ccpath.read_cc_csv        CCPath (contact points and normals)
result-csv camsmooth.io.program.read_result_program  CLProgram (camsmooth's result CSV)
=========  =====================================  ==========================================
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any

from camsmooth.errors import InputError
from camsmooth.geometry.paths import CCPath
from camsmooth.io.program import FORMATS, CLProgram, detect_format, read_result_program

__all__ = ["load_program", "LOADERS"]

_ALIASES = {"cls": "apt", "clsf": "apt", "cldata": "apt", "apt": "apt", "cl": "cl-csv", "cl-csv": "cl-csv",
            "cc": "cc-csv", "cc-csv": "cc-csv", "gcode": "gcode", "nc": "gcode", "g-code": "gcode",
            "result": "result-csv", "result-csv": "result-csv"}


def _read_cc(path: str | os.PathLike, **_: Any) -> CCPath:
    from camsmooth.io.ccpath import read_cc_csv

    return read_cc_csv(path)


def _read_apt(path: str | os.PathLike, **kw: Any) -> CLProgram:
    from camsmooth.io.apt import read_apt

    return read_apt(path, **{k: v for k, v in kw.items() if k in ("chord_tol", "units")})


def _read_cl(path: str | os.PathLike, **_: Any) -> CLProgram:
    from camsmooth.io.clcsv import read_cl_csv

    return read_cl_csv(path)


def _read_gcode(path: str | os.PathLike, **kw: Any) -> CLProgram:
    """camsmooth's own G-code (its ``camsmooth post:`` header) by camsmooth.post.own, any other
    (a posted program) by camsmooth.post, the dialect detected from the content."""
    from camsmooth.post import posted_text, read_posted
    from camsmooth.post.own import POST_TAG, read_gcode

    notes: list[str] = []
    text = posted_text(path, notes)
    if POST_TAG in "\n".join(text.split("\n", 60)[:60]):
        return read_gcode(path, **{k: v for k, v in kw.items() if k in ("machine",)})
    opts = {k: v for k, v in kw.items() if k in ("machine", "dialect", "chord_tol")}
    if kw.get("machine_given") is False:
        opts["machine"] = None  # the default machine was not chosen for this program: the letters it uses decide
    program = read_posted(path, text=text, **opts)
    program.warnings[:0] = notes
    return program


def _read_result(path: str | os.PathLike, **_: Any) -> CLProgram:
    return read_result_program(path)


#: format name -> loader(path, **options); options a loader does not take are ignored
LOADERS: dict[str, Callable[..., CLProgram | CCPath]] = {
    "apt": _read_apt, "cl-csv": _read_cl, "cc-csv": _read_cc, "gcode": _read_gcode, "result-csv": _read_result}


def load_program(source: str | os.PathLike, format: str | None = None, **options: Any) -> CLProgram | CCPath:
    """Read a program file: APT/CLSF, CL CSV or camsmooth's own G-code give a CLProgram, a CC CSV
    a CCPath.

    format: None (detected from the content, ``detect_format``) or one of FORMATS (aliases: cls,
    clsf, cldata, cl, cc, nc). options: ``chord_tol`` (mm, APT and posted arc interpolation),
    ``units`` ('mm' or 'inch', APT files without UNITS/ or feed units), ``machine`` (camsmooth
    Machine, G-code in machine mode), ``machine_given`` (False: ``machine`` is only the default
    one, and a posted program is read with the nominal machine of its rotary letters), ``dialect``
    (a posted program's, camsmooth.post.DIALECTS); a reader ignores options it does not take.
    """
    if format is None:
        fmt = detect_format(source)
    else:
        fmt = _ALIASES.get(str(format).lower())
        if fmt is None:
            raise InputError(f"unknown program format {format!r} (known: {', '.join(FORMATS)})", file=str(source))
        if fmt == "cl-csv" and detect_format(source) == "result-csv":
            # its x,y,z are the CC points, not tool tips: read it as the program it describes
            program = LOADERS["result-csv"](source, **options)
            program.warnings.append("a camsmooth result CSV: read as the program it describes (tool tips clx,cly,clz, "
                                    "axes i,j,k), not as a CL CSV whose x,y,z would be the CC points")
            return program
    return LOADERS[fmt](source, **options)
