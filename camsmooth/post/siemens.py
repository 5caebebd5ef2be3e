"""Siemens Sinumerik 840D programs (dialect 'siemens'): the ISO interpreter of camsmooth.post.iso
with the 840D words turned into it, block by block.

Sources: SINUMERIK 840D sl Programming Manual, Fundamentals (6FC5398-1BP40): "Comments" (``;``
to the end of the block), "Assignments" (``X=10``, ``X=R1+5``, R parameters ``R1=5``, ``DEF REAL
name=value``), "Frames" (TRANS / ATRANS translation, ROT / AROT rotation by RPY Z, Y, X with the
absolute word replacing the programmable frame and the additive one chained onto it, a word
without values resetting it), "G70/G71/G700/G710" (inch and metric), "SUPA / G153" (machine
coordinates, non-modal), "G500, G54..G57, G505..G599" (settable frames: recorded); Job Planning
(6FC5398-2BP40) "TRAORI / TRAFOOF" (five-axis transformation: X Y Z the tool tip, the rotary
positions or the vector A3 B3 C3 the orientation); Cycles manual, "CYCLE800 swivel" (_MODE bits
0-5 the axis order of an axis-by-axis swivel, bits 6-7 the kind: 00 axis by axis; the reference
point X0 Y0 Z0 before and the zero point X1 Y1 Z1 after the rotation) and "CYCLE832" (high-speed
settings, no motion); "MCALL" (a drilling cycle called at every position until MCALL alone).

Read: TRAORI/TRAFOOF, CYCLE800 axis by axis (other kinds named), TRANS/ATRANS/ROT/AROT, CYCLE832,
G70/G71/G700/G710, SUPA/G153, G500-G599, R and DEF assignments, CR= radius arcs, MCALL CYCLE81-89
holes, T=/T, M6, D, MSG and the path-control words (G64, G642, FFWON, SOFT, COMPCAD, ORIWKS ...)
without effect. Named, costing the operation: IC()/AC() per-word incremental, CIP, CT, control
flow (GOTO, IF, LOOP, WHILE), other cycles.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from camsmooth.io.program import CLProgram
from camsmooth.post.core import Frame3, Skip, rot_x, rot_y, rot_z
from camsmooth.post.iso import IsoInterpreter
from camsmooth.post.model import PostDialect
from camsmooth.post.words import evaluate
from camsmooth.post.writer import Words, semicolon

__all__ = ["read_siemens", "SIEMENS", "DIALECTS"]

_NOTE = {"G64", "G641", "G642", "G643", "G644", "G645", "G60", "G601", "G602", "G603", "FFWON", "FFWOF", "SOFT",
         "BRISK", "COMPCAD", "COMPCURV", "COMPOF", "COMPON", "ORIWKS", "ORIMKS", "ORIAXES", "ORIVECT", "ORICONO",
         "UPATH", "SPATH", "STOPRE", "G90", "G91", "G17", "G18", "G19", "G40", "CFC", "CFTCP", "CFIN", "DIAMOF",
         "G94", "G95", "G93", "G0", "G1", "G2", "G3", "G00", "G01", "G02", "G03", "WORKPIECE", "ORISON", "ORISOF",
         "FGROUP", "G331", "G332", "SPOS", "M3", "M4", "M5", "M8", "M9"}
#: settings written as NAME=value or plain words that change no position (path control, feeds, look-ahead)
_SETTINGS = {"FNORM", "FLIN", "FCUB", "ADIS", "ADISPOS", "CTOL", "OTOL", "CTOLG0", "OTOLG0", "STOPFIFO", "STARTFIFO",
             "FIFOCTRL", "CFC", "CFTCP", "CFIN", "ORIEULER", "ORIRPY", "ORIVIRT1", "ORIVIRT2", "ORIPATH", "ORIPATHS",
             "OST", "DRIVE", "COMPSURF", "G60", "G601", "G602", "G603", "G641", "G642", "G643", "G644", "G645",
             "G64", "G9", "G09", "FGREF", "M17", "RET", "SPOF", "DIAMON", "G450", "G451", "G40", "WALIMON",
             "WALIMOF", "SUPD", "G190", "G291", "G290", "FB", "SAVE"}
_FLOW = re.compile(r"^\s*(GOTO[FBC]?|IF|ELSE|ENDIF|LOOP|ENDLOOP|WHILE|ENDWHILE|FOR|ENDFOR|REPEAT|UNTIL)\b", re.I)


class _Siemens(IsoInterpreter):
    def __init__(self, file: str, text: str, chord_tol: float | None) -> None:
        super().__init__(file, text, "siemens", chord_tol)
        self.keyword = self._keyword
        self.paren = False
        self.prog_frame = Frame3()
        self.swivel = Frame3()
        self.mcall: tuple[str, float] | None = None

    def _refs(self, expr: str, names: bool = False) -> str:
        """R parameters as ``#<rN>`` for the ISO words' evaluator; with ``names`` (the value of a
        ``NAME=value`` word) the variables a DEF or an assignment gave a value (``X=XX``) too."""
        def ref(m: re.Match[str]) -> str:
            word = m.group(0)
            if re.fullmatch(r"R\d+", word, re.I):
                return f"#<r{word[1:]}>"
            return f"#<{word.lower()}>" if names and word.lower() in self.vars else word

        return re.sub(r"(?<![<\w])[A-Z_][A-Z0-9_]*\b", ref, expr, flags=re.I)  # not inside a '#<name>' made here

    def _num(self, expr: str) -> float:
        lookup = {f"v_{k}": v for k, v in self.vars.items()}
        e = re.sub(r"\bR(\d+)\b", lambda m: f"v_r{m.group(1)}", expr)
        e = re.sub(r"\b([A-Za-z_]\w*)\b", lambda m: m.group(1) if m.group(1).upper() in ("SIN", "COS", "TAN", "SQRT",
                                                                                          "ABS", "ATAN2")
                   or m.group(1).startswith("v_") else f"v_{m.group(1).lower()}", e)
        return evaluate(e, lookup)

    def _set(self) -> None:
        self.tilt = self.prog_frame.then(self.swivel) if not self.swivel.identity else self.prog_frame
        self._set_frame()

    def _keyword(self, number: int, code: str, comments: list[str]) -> str:
        s = code.strip()
        if _FLOW.match(s):
            raise Skip(f"control flow {s.split()[0]} is not executed by this reader")
        m = re.match(r"^\s*DEF\s+(REAL|INT|BOOL|CHAR|STRING\[\d+\]|AXIS|FRAME)\s+(.*)$", s, re.I)
        if m:
            for part in m.group(2).split(","):
                if "=" in part:
                    name, _, val = part.partition("=")
                    self.vars[name.strip().lower()] = self._num(val)
            return ""
        # assignments of R parameters and variables: 'R1=5 R2=R1*2', '_X0=10'
        while True:
            m = re.match(r"^\s*(R\d+|_?[A-Z][A-Z0-9_]{2,})\s*=\s*([^\s=]+)(?=\s|$)", s, re.I)
            if not m or m.group(1).upper() in ("CYCLE832",) or m.group(1).upper().startswith(("CR", "AR")) \
                    and len(m.group(1)) == 2:
                break
            name = m.group(1).lower()
            self.vars[name] = self._num(m.group(2))
            s = s[m.end():]
        out: list[str] = []
        tokens = re.findall(r"[A-Z_][A-Z0-9_]*\s*\([^()]*\)|[A-Z_][A-Z0-9_]*\s*=\s*\"[^\"]*\"|"
                            r"[A-Z][A-Z0-9]*\s*=\s*[^\s]+|\S+", s, re.I)
        for tok in tokens:
            up = tok.upper().replace(" ", "")
            head = re.match(r"[A-Z_][A-Z0-9_]*", up)
            word = head.group(0) if head else up
            if word.startswith("TRAORI"):
                self.b.tcp = True
                self.b.note("TRAORI (five-axis transformation on)", number)
            elif word == "TRAFOOF":
                self.b.tcp = False
                self.tcp_vector = False
            elif word == "CYCLE800":
                self._cycle800(number, tok)
            elif word == "CYCLE832" or word in ("MSG", "WORKPIECE"):
                self.b.note(f"{word}", number)
            elif word in ("G4", "G04"):  # dwell: its F or S word is the time, not a feed
                self.b.note("G4 (dwell)", number)
                return ""
            elif word == "MCALL":
                if up == "MCALL":
                    self.mcall = None
                    self.b.end_cycle()
                else:
                    continue
            elif re.match(r"CYCLE8[1-9]$", word) or word == "CYCLE73":
                self._drill(number, tok, "MCALL" in up or (tokens[0].upper() == "MCALL"), code)
            elif word in ("TRANS", "ATRANS", "ROT", "AROT"):
                self._frame(number, word, tokens[tokens.index(tok) + 1:])
                return ""
            elif word in ("SUPA", "G153"):
                out.append("G53")
            elif word in ("G70", "G700"):
                out.append("G20")
            elif word in ("G71", "G710"):
                out.append("G21")
            elif word == "G500":
                self.b.offset("G500 (settable frames off)", number)
            elif re.match(r"G5[0-9][0-9]$", word) and 505 <= int(word[1:]) <= 599:
                self.b.offset(word, number)
            elif word in ("G54", "G55", "G56", "G57"):
                self.b.offset(word, number)
            elif word == "T" and "=" in up:
                out.append("T0")
                self.next_name = up.split("=", 1)[1].strip('"')
            elif word in ("D", "H") or re.match(r"D\d+$", up):
                continue
            elif word in _NOTE and "=" not in up:
                if word in ("G90", "G91", "G17", "G18", "G19", "G94", "G95", "G93", "G0", "G1", "G2", "G3", "G00",
                            "G01", "G02", "G03", "G40", "M3", "M4", "M5", "M8", "M9"):
                    out.append(word)
                else:
                    self.b.note(word, number)
            elif word in ("CIP", "CT", "CT2"):
                raise Skip(f"{word} (arc through an intermediate point / tangential arc) is not read")
            elif word in _SETTINGS or (word in _NOTE and "=" in up):
                self.b.note(word, number)
            elif word in ("TOFRAME", "TOROT", "PAROT", "MIRROR", "AMIRROR", "SCALE", "ASCALE"):
                raise Skip(f"{word} (a frame from the tool, a mirror or a scale) is not read")
            elif "=" in up:
                name, _, val = up.partition("=")
                mode = re.match(r"(IC|AC|DC|ACP|ACN)\((.*)\)$", val)
                if mode:
                    val = mode.group(2)
                    val = self._per_word(name, mode.group(1), val, tok)
                if name == "TURN":  # helix: full turns beyond the end point's angle
                    out.append(f"P[{self._refs(val, True)}+1]")
                    continue
                if name in ("A3", "B3", "C3"):
                    self.tcp_vector = True
                    name = {"A3": "I", "B3": "J", "C3": "K"}[name]
                elif name == "CR":
                    name = "R"
                elif len(name) != 1:
                    raise Skip(f"{tok} is not read")
                out.append(f"{name}[{self._refs(val, True)}]")
            else:
                out.append(self._refs(tok))
        return " ".join(out)

    def _per_word(self, name: str, mode: str, val: str, tok: str) -> str:
        """The value of ``name=IC(v)`` / ``AC(v)`` / ``DC(v)`` as the block's modal G90/G91 reads it
        (840D Fundamentals, "Absolute and incremental dimensions"): IC on X Y Z A B C is the current
        position plus v; AC on the centre words I J K is absolute, turned into the offset from the
        start point that G2/G3 expect; DC/ACP/ACN (the rotary approach direction) and AC on a
        position are the value itself."""
        scale = 1.0 / 25.4 if self.inch else 1.0  # self.pos is mm; the words are in program units
        if mode == "IC" and name in ("X", "Y", "Z", "A", "B", "C"):
            base = self.pos[name] * scale if name in "XYZ" else self.rot.get(name, 0.0)
            if math.isnan(base):
                raise Skip(f"{tok}: incremental from an unknown position")
            return f"{base!r}+({self._refs(val, True)})"
        if mode == "AC" and name in ("I", "J", "K"):
            base = self.pos["XYZ"["IJK".index(name)]] * scale
            if math.isnan(base):
                raise Skip(f"{tok}: an arc centre from an unknown start point")
            return f"({self._refs(val, True)})-{base!r}"
        if mode == "IC":
            raise Skip(f"{tok} (IC on {name}) is not read")
        return val

    def _cycle800(self, number: int, tok: str) -> None:
        """CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1, _Z1, _DIR, ...): the
        swivel frame; axis by axis (_MODE bits 6-7 = 00) with the order of bits 0-5 (two bits per
        rotation: 01 X, 10 Y, 11 Z), each rotation about the frame's axis as turned so far."""
        if "(" not in tok:
            raise Skip("CYCLE800 without its arguments")
        args = [a.strip() for a in tok[tok.index("(") + 1:-1].split(",")]
        if len(args) < 13:
            if len(args) == 0 or all(not a for a in args) or tok.replace(" ", "").upper() == "CYCLE800()":
                self.swivel = Frame3()
                self._set()
                return
            raise Skip("CYCLE800 with fewer than 13 arguments")
        mode = int(self._num(args[3])) if args[3] else 0
        v = [self._num(a) if a and not a.startswith('"') else 0.0 for a in args[4:13]]
        x0, a, x1 = np.array(v[0:3]), v[3:6], np.array(v[6:9])
        if (mode >> 6) & 3:
            raise Skip(f"CYCLE800 mode {mode} (projection, solid or direct angles are not read; axis by axis only)")
        R = np.eye(3)
        for k in range(3):
            ax = (mode >> (2 * k)) & 3
            if ax == 0:
                continue
            R = R @ {1: rot_x, 2: rot_y, 3: rot_z}[ax](math.radians(a[ax - 1]))
        # p_W = x0 + R (x1 + p): translated to the reference point, turned, translated to the new zero point
        self.swivel = Frame3(R, x0 + R @ x1) if np.any(R != np.eye(3)) or np.any(x0) or np.any(x1) else Frame3()
        self._set()
        self.b.note("CYCLE800 (swivel plane)", number)

    def _frame(self, number: int, word: str, rest: list[str]) -> None:
        vals = {}
        for t in rest:
            m = re.match(r"([XYZ])\s*=?\s*(.+)$", t, re.I)
            if m:
                vals[m.group(1).upper()] = self._num(m.group(2))
        if word in ("TRANS", "ATRANS"):
            fr = Frame3(o=np.array([self._len(vals.get(a, 0.0)) for a in "XYZ"]))
        else:  # rotation: Z, then Y, then X (RPY)
            fr = Frame3(rot_z(math.radians(vals.get("Z", 0.0))) @ rot_y(math.radians(vals.get("Y", 0.0)))
                        @ rot_x(math.radians(vals.get("X", 0.0))))
        self.prog_frame = self.prog_frame.then(fr) if word.startswith("A") else fr
        self._set()
        self.b.note(word, number)

    def _drill(self, number: int, tok: str, modal: bool, text: str) -> None:
        """CYCLE81..89(RTP, RFP, SDIS, DP, DPR, ...): the hole's bottom DP (absolute) or RFP - DPR."""
        if "(" not in tok:
            raise Skip(f"{tok} without its arguments")
        args = [a.strip() for a in tok[tok.index("(") + 1:-1].split(",")]
        try:
            rfp = self._num(args[1]) if len(args) > 1 and args[1] else 0.0
            dp = self._num(args[3]) if len(args) > 3 and args[3] else None
            dpr = self._num(args[4]) if len(args) > 4 and args[4] else None
        except Skip:
            raise
        z = dp if dp is not None else rfp - (dpr or 0.0)
        code = tok[:tok.index("(")].strip().upper()
        self.cycle_z = self._len(z)
        if modal:
            self.mcall = (code, self.cycle_z)
            self.motion = None
            return
        x, y = self.pos["X"], self.pos["Y"]
        if math.isnan(x) or math.isnan(y):
            raise Skip(f"{code} at an unknown position")
        self.b.cycle(code, number, np.array([x, y, self.cycle_z]), text)

    def _motion(self, blk: Any, vals: dict[str, float], motion_now: float | None) -> None:
        super()._motion(blk, vals, motion_now)
        if self.mcall is not None and any(a in vals for a in ("X", "Y")):
            code, z = self.mcall
            self.b.cycle(code, blk.line, np.array([self.pos["X"], self.pos["Y"], z]), blk.text)


def read_siemens(path: str, text: str, machine: Any = None, chord_tol: float | None = None) -> CLProgram:
    """Read a Sinumerik 840D program as a CLProgram (module docstring)."""
    return _Siemens(str(path), text, chord_tol).run(machine)


# ----------------------------------------------------------------------------------------------
# the writer's words (camsmooth.post.writer) and this module's entry of camsmooth.post.DIALECTS

#: Sinumerik 840D: metric G71, ';' comments, TCP ``TRAORI`` ... ``TRAFOOF``, the high-speed settings
#: ``CYCLE832(<tolerance mm>, _FINISH, 1)`` (840D sl programming manual, "High Speed Settings")
SIEMENS = Words("siemens", semicolon, ("G71", "G90", "G17", "G40"), tcp_on="TRAORI", tcp_off="TRAFOOF",
                path_tolerance=("CYCLE832({tol}, _FINISH, 1)",))


def _read(path: str, text: str, machine: Any = None, dialect: str = "siemens",
          chord_tol: float | None = None) -> CLProgram:
    return read_siemens(path, text, machine, chord_tol)


DIALECTS = (PostDialect("siemens", _read, SIEMENS),)
