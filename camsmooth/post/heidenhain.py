"""Heidenhain Klartext (conversational) programs, iTNC 530 / TNC 640 (dialect 'heidenhain').

Sources: HEIDENHAIN TNC 640 User's Manual for Klartext programming (ID 892903): "Program
structure" (``BEGIN PGM name MM|INCH`` ... ``END PGM``, block numbers, ``;`` comments, ``*``
structure blocks), "Path functions" (``L`` straight line with X Y Z A B C, ``IX`` incremental,
``R0/RL/RR`` radius compensation, ``F``/``FMAX``/``F MAX``, M words; ``CC`` circle centre
(pole), ``C`` arc about it to X Y with ``DR+`` counter-clockwise / ``DR-`` clockwise, ``CR`` arc of
radius ``R+`` (<= 180 deg) or ``R-``; ``LN`` with the tool vector ``TX TY TZ``), "Feed rate": in
inch programs F is in 0.1 inch/min; "Miscellaneous functions for rotary axes" (M128 / M129 TCPM
on/off, M91/M92 machine-referenced blocks, M126/M127 shortest path); "FUNCTION TCPM" (with
``AXIS SPAT`` the A B C words are spatial angles: T = Rz(C) Ry(B) Rx(A) e_z, whatever the machine)
and "FUNCTION RESET TCPM"; "Tilting the working plane: PLANE function" (PLANE SPATIAL SPA SPB SPC:
rotations about the machine-fixed X, then Y, then Z, R = Rz(SPC) Ry(SPB) Rx(SPA); PLANE EULER
EULPR EULNU EULROT: R = Rz(PR) Rx(NU) Rz(ROT); PLANE VECTOR BX BY BZ NX NY NZ: Z along N, X along
the base vector; PLANE RELATIV SPA|SPB|SPC: one more rotation about an axis of the tilted plane;
PLANE RESET; TURN / STAY / MOVE and SEQ words not changing the frame), "Cycles
for coordinate transformation" (CYCL DEF 7 DATUM SHIFT 7.1 X / 7.2 Y / 7.3 Z, CYCL DEF 247 DATUM
SETTING Q339), "Fixed cycles" (CYCL DEF 200-209 with Q201 depth and Q203 surface coordinate,
called by CYCL CALL or M99), "Subprograms" (LBL n ... LBL 0, CALL LBL n REP m), "Q parameters"
(FN 0: Qn = value, Qn = expression).

What is not applied is named and costs its operation: RL/RR radius compensation, CT/CP/RND/CHF,
PLANE PROJECTED/AXIAL/POINTS, CYCL DEF 19, datum tables (``#``), FN jumps, CALL PGM.
"""

from __future__ import annotations

import math
import re
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.program import CLProgram, Tool
from camsmooth.post.core import INCH_MM, Builder, Frame3, Skip, rot_x, rot_y, rot_z
from camsmooth.post.model import PostDialect
from camsmooth.post.words import evaluate, operation_name, tool_comment
from camsmooth.post.writer import Words, semicolon

__all__ = ["read_heidenhain", "HEIDENHAIN", "DIALECTS"]

_VAL = r"[+-]?\s*(?:Q\d+|\d+\.?\d*|\.\d+)"


class _Klartext:
    def __init__(self, file: str, text: str, chord_tol: float | None) -> None:
        self.file = file
        self.b = Builder(file, "heidenhain")
        if chord_tol is not None:
            self.b.chord_tol = chord_tol
        self.blocks = self._join(text.split("\n"))
        self.q: dict[str, float] = {}
        self.pos = {a: math.nan for a in "XYZ"}
        self.rot: dict[str, float] = {}
        self.inch = False
        self.F = math.nan
        self.tool_F = math.nan
        self.pole = np.array([math.nan, math.nan])
        self.shift = np.zeros(3)
        self.plane = np.eye(3)
        self.rotation = np.eye(3)
        self.spatial = False  # FUNCTION TCPM ... AXIS SPAT
        self.sp: dict[str, float] = {}  # the modal spatial angles under AXIS SPAT (deg)
        self.cycle: tuple[str, float, float] | None = None
        self.cycle7 = False
        self.pending: list[str] = []
        self.labels: dict[str, int] = {}
        for k, (_, s, _) in enumerate(self.blocks):
            m = re.match(r"^LBL\s+(\"?[\w ]+\"?)\s*$", s, re.I)
            if m and m.group(1).strip('" ') != "0":
                self.labels.setdefault(m.group(1).strip('" ').upper(), k)

    @staticmethod
    def _join(lines: list[str]) -> list[tuple[int, str, str]]:
        """(line, code, comment) per block: '~' continuations joined, block numbers dropped."""
        out: list[tuple[int, str, str]] = []
        acc, start = "", 0
        for k, raw in enumerate(lines, start=1):
            text = raw.rstrip()
            if not acc:
                start = k
            if text.endswith("~"):
                acc += text[:-1] + " "
                continue
            full = acc + text
            acc = ""
            full = re.sub(r"^\s*/?\s*\d+\s+", "", full)  # the block number (after a block-delete '/')
            if full.lstrip().startswith("*"):
                out.append((start, "*", full.lstrip()[1:].strip()))
                continue
            # ';' starts a comment, except inside the Q=value ;TEXT pairs of cycles (kept: values first)
            code, _, comment = full.partition(";") if not re.match(r"^\s*CYCL\s+DEF", full, re.I) else (full, "", "")
            out.append((start, code.strip(), comment.strip()))
        return out

    # ---------------------------------------------------------------------------------------
    def run(self, machine: Any) -> CLProgram:
        self._execute(0, depth=0)
        return self.b.finish(machine)

    def _execute(self, k: int, depth: int, until_label: bool = False) -> str | None:
        while k < len(self.blocks):
            line, code, comment = self.blocks[k]
            k += 1
            if code == "*":
                name = operation_name(comment, star=True)
                if name:
                    self.b.operation(name, line)
                continue
            if comment and not code:
                if not tool_comment(comment) and not set(comment) <= set("-=*_ ."):
                    self.pending = (self.pending + [" ".join(comment.split())])[-3:]
                continue
            if not code:
                continue
            up = code.upper()
            if until_label and (re.match(r"^LBL\s+0\b", up) or up.startswith("LBL")):
                return "return"
            try:
                flow = self._block(line, code, up, depth)
            except InputError:
                raise
            except Skip as exc:
                self.b.skip(line, code, exc.reason)
                continue
            except (ValueError, IndexError, ArithmeticError) as exc:  # a block this reader cannot read
                self.b.skip(line, code, f"the block cannot be read ({exc})")
                continue
            if flow == "end":
                return flow
            if isinstance(flow, tuple):  # FN 9..12: a jump taken to a label
                k = self.labels[flow[1]] + 1
        return None

    def _num(self, text: str) -> float:
        t = text.replace(" ", "")
        lookup = {f"v_q{m}": v for m, v in ((k[1:], v) for k, v in self.q.items())}
        e = re.sub(r"Q(\d+)", lambda m: f"v_q{m.group(1)}", t, flags=re.I)
        return evaluate(e, lookup)

    def _len(self, v: float) -> float:
        return v * INCH_MM if self.inch else v

    def _frame(self) -> None:
        R, o = self.plane @ self.rotation, self.shift.copy()  # the frame keeps its own values
        fr = Frame3(R, o) if not np.allclose(R, np.eye(3)) else Frame3(o=o)
        self.b.set_frame(fr if not fr.identity else Frame3())

    def _block(self, line: int, code: str, up: str, depth: int) -> str | None:
        if up.startswith("BEGIN PGM"):
            self.inch = up.rstrip().endswith("INCH")
            return None
        if up.startswith("END PGM"):
            return "end"
        if up.startswith(("BLK FORM", "TOOL DEF", "FUNCTION MODE", "FUNCTION PARAX")):
            self.b.note(up.split()[0] + " " + up.split()[1], line)
            return None
        m = re.match(r"^FN\s*(9|10|11|12)\s*:\s*IF\s+(.+?)\s+(EQU|NE|GT|LT)\s+(.+?)\s+GOTO\s+LBL\s+\"?([\w ]+?)\"?\s*$",
                     up)
        if m:  # a conditional jump between values: taken or not, as the control does
            a, b, lab = self._num(m.group(2)), self._num(m.group(4)), m.group(5).strip()
            if lab not in self.labels:
                raise Skip(f"jump to label {lab}, which is not in this program")
            taken = {"EQU": a == b, "NE": a != b, "GT": a > b, "LT": a < b}[m.group(3)]
            return ("jump", lab) if taken else None  # type: ignore[return-value]
        m = re.match(r"^(?:FN\s*\d+\s*:\s*)?(Q\d+)\s*=\s*(.+)$", code, re.I)
        if m:
            if re.match(r"^FN\s*(9|1[0-2]|1[4-9]|2\d)\b", up):
                raise Skip(f"{up.split(':')[0]} (jump, error, print or table functions) is not executed")
            self.q[m.group(1).upper()] = self._num(m.group(2))
            return None
        if up.startswith("TOOL CALL"):
            m = re.search(r"TOOL CALL\s+(\d+|\"[^\"]*\")", code, re.I)
            name = m.group(1).strip('"') if m else None
            fm = re.search(r"\bF\s*(" + _VAL + ")", code[9:], re.I)
            if fm:
                self.tool_F = self._len(self._num(fm.group(1)))
            self.b.tool(Tool(name=name, kind="mill", diameter=None, corner_radius=None,
                             number=int(name) if name and name.isdigit() else None, line=line), line)
            if self.pending:
                self.b.name_operation(self.pending[-1], line)
            self.pending = []
            return None
        if up.startswith("FUNCTION RESET TCPM"):
            self.b.tcp = self.spatial = False
            return None
        if up.startswith("FUNCTION TCPM"):
            self.b.tcp = True
            self.spatial = bool(re.search(r"\bAXIS\s+SPAT", up))
            self.b.note("FUNCTION TCPM AXIS SPAT (A B C spatial angles)" if self.spatial else "FUNCTION TCPM", line)
            return None
        if up.startswith("PLANE"):
            self._plane(line, up)
            return None
        if up.startswith("CYCL DEF"):
            return self._cycl_def(line, up)
        if up.startswith("CYCL CALL"):
            if "PAT" in up:
                raise Skip("CYCL CALL PAT (point tables) is not read")
            self._hole(line, code)
            return None
        if up.startswith("CALL LBL"):
            m = re.match(r"CALL LBL\s+(\"?[\w ]+?\"?)(?:\s+REP\s*(\d+))?\s*$", up)
            if not m:
                raise Skip("CALL LBL without a label")
            lab = m.group(1).strip('" ')
            if lab not in self.labels:
                raise Skip(f"label {lab} is not in this program")
            if depth >= 8:
                raise Skip("subprograms nested deeper than 8")
            for _ in range(1 + int(m.group(2) or 0)):
                self._execute(self.labels[lab] + 1, depth + 1, until_label=True)
            return None
        if up.startswith("LBL"):  # a label met in the program's flow: nothing happens
            return None
        if up.startswith("CALL PGM"):
            raise Skip("CALL PGM (another program file) is not read")
        if re.match(r"^(CT|CP|RND|CHF|CTP|APPR|DEP)\b", up):
            raise Skip(f"{up.split()[0]} is not read")
        if re.match(r"^CC\b", up):
            w = self._words(up[2:])
            base = [self.pos["X"], self.pos["Y"]]
            self.pole = np.array([self._len(w["X"]) if "X" in w else base[0],
                                  self._len(w["Y"]) if "Y" in w else base[1]])
            return None
        if re.match(r"^(L|LN|C|CR)\b", up):
            return self._path(line, up, code)
        m = re.match(r"^M(\d+)", up)
        if m:
            return self._m(line, [int(x) for x in re.findall(r"\bM(\d+)", up)])
        if up.startswith("STOP"):
            return None
        raise Skip(f"{up.split()[0]} is not read by the heidenhain reader")

    def _words(self, text: str) -> dict[str, float]:
        out: dict[str, float] = {}
        for name, val in re.findall(r"\b(I?[XYZABC]|[NT][XYZ]|DR|R|F)\s*(" + _VAL + ")", text):
            out[name] = self._num(val)
        return out

    def _m(self, line: int, ms: list[int]) -> str | None:
        flow = None
        for m in ms:
            if m == 128:
                self.b.tcp = True
                self.b.note("M128 (TCPM on)", line)
            elif m == 129:
                self.b.tcp = False
            elif m in (2, 30):
                flow = "end"
            elif m == 99:
                self._hole(line, "M99")
        return flow

    def _path(self, line: int, up: str, code: str) -> str | None:
        head = up.split()[0]
        body = up[len(head):]
        rapid = bool(re.search(r"F\s*MAX", body))
        body_v = re.sub(r"F\s*MAX", " ", body)
        if re.search(r"\bR[LR]\b", body_v):
            raise Skip("radius compensation RL/RR: the programmed path is not the tool's")
        w = self._words(re.sub(r"\bR0\b", " ", re.sub(r"\bM\d+", " ", body_v)))
        ms = [int(x) for x in re.findall(r"\bM(\d+)", body)]
        if "F" in w and not rapid:
            self.F = self._len(w.pop("F")) * (0.1 if self.inch else 1.0)
        elif re.search(r"F\s*AUTO", body):
            self.F = self.tool_F
        if 140 in ms:  # M140 MB: retract along the tool axis (to the travel limit): not a point of the program
            self.b.machine_move(line, "M140 (retract along the tool axis)")
            return self._m(line, [m for m in ms if m != 140])
        if 91 in ms or 92 in ms:
            self.b.machine_move(line, "M91/M92 (machine-referenced block)")
            self.rot = {**self.rot, **{a: w[a] for a in "ABC" if a in w}}  # a new dict: points keep theirs
            return self._m(line, [m for m in ms if m not in (91, 92)])
        if any(m in (128, 129) for m in ms):
            self._m(line, [m for m in ms if m in (128, 129)])
        start = np.array([self.pos[a] for a in "XYZ"])
        end = start.copy()
        for k, a in enumerate("XYZ"):
            if a in w:
                end[k] = self._len(w[a])
            if "I" + a in w:
                end[k] = (0.0 if math.isnan(end[k]) else end[k]) + self._len(w["I" + a])
        spatial = self.b.tcp and self.spatial
        rot = dict(self.sp if spatial else self.rot)  # AXIS SPAT: the words are spatial angles, not axes
        for a in "ABC":
            if a in w:
                rot[a] = w[a]
            if "I" + a in w:
                rot[a] = rot.get(a, 0.0) + w["I" + a]
        if spatial:
            self.sp, rot = rot, self.rot
        self.b.F = self.F
        if head in ("C", "CR"):
            if np.isnan(start).any():
                raise Skip("an arc whose start point is not known")
            if "DR" not in w and not re.search(r"DR[+-]", body):
                raise Skip(f"{head} without DR+ or DR-")
            ccw = bool(re.search(r"DR\s*\+", body))
            if head == "C":
                if np.isnan(self.pole).any():
                    raise Skip("C without a circle centre CC")
                centre = np.array([self.pole[0], self.pole[1], start[2]])
            else:
                r = self._len(w.get("R", math.nan))
                d = end - start
                d[2] = 0.0
                chord = float(np.linalg.norm(d))
                if not (chord > 1e-9 and abs(r) >= chord / 2 - 1e-6):
                    raise Skip(f"CR radius {r:g} does not fit the chord {chord:.6g} mm")
                h = math.sqrt(max(r * r - chord * chord / 4, 0.0))
                side = (1.0 if ccw else -1.0) * (1.0 if r > 0 else -1.0)
                centre = start + d / 2 + side * h * np.cross([0.0, 0.0, 1.0], d) / chord
            r0 = math.hypot(*(start - centre)[:2])
            r1 = math.hypot(*(end - centre)[:2])
            if abs(r0 - r1) > max(0.002, 1e-3 * r0):
                raise Skip(f"arc end point radius {r1:.6g} mm differs from the start radius {r0:.6g} mm")
            self.b.arc(line, start, end, centre, np.array([0.0, 0.0, 1.0]), ccw, self.rot, rot)
        else:
            if np.isnan(end).any():
                for k, a in enumerate("XYZ"):
                    self.pos[a] = float(end[k])
                self.rot = rot
                self.b.machine_move(line, "move before X, Y and Z are all known (not a point)")
                return self._m(line, [m for m in ms if m not in (128, 129)])
            vec = None
            if head == "LN" and all(t in w for t in ("TX", "TY", "TZ")):
                vec = (w["TX"], w["TY"], w["TZ"])
            elif spatial:  # AXIS SPAT: A B C are the spatial angles of the tool axis
                a, b, c = (math.radians(self.sp.get(k, 0.0)) for k in "ABC")
                vec = tuple((rot_z(c) @ rot_y(b) @ rot_x(a))[:, 2].tolist())
            if any(a in w for a in ("X", "Y", "Z", "A", "B", "C", "IX", "IY", "IZ", "IA", "IB", "IC")):
                self.b.move(line, rapid, (float(end[0]), float(end[1]), float(end[2])), rot, vec)
        for k, a in enumerate("XYZ"):
            self.pos[a] = float(end[k])
        self.rot = rot
        return self._m(line, [m for m in ms if m not in (128, 129)])

    def _plane(self, line: int, up: str) -> None:
        if up.startswith("PLANE RESET"):
            self.plane = np.eye(3)
        else:
            w = {k: self._num(v) for k, v in re.findall(r"\b(SPA|SPB|SPC|EULPR|EULNU|EULROT|BX|BY|BZ|NX|NY|NZ)\s*("
                                                        + _VAL + ")", up)}
            if up.startswith("PLANE SPATIAL"):
                self.plane = rot_z(math.radians(w.get("SPC", 0.0))) @ rot_y(math.radians(w.get("SPB", 0.0))) \
                    @ rot_x(math.radians(w.get("SPA", 0.0)))
            elif up.startswith("PLANE EULER"):
                self.plane = rot_z(math.radians(w.get("EULPR", 0.0))) @ rot_x(math.radians(w.get("EULNU", 0.0))) \
                    @ rot_z(math.radians(w.get("EULROT", 0.0)))
            elif up.startswith("PLANE VECTOR"):
                n = np.array([w.get("NX", 0.0), w.get("NY", 0.0), w.get("NZ", 0.0)])
                bvec = np.array([w.get("BX", 0.0), w.get("BY", 0.0), w.get("BZ", 0.0)])
                if np.linalg.norm(n) < 1e-9:
                    raise Skip("PLANE VECTOR with a zero normal")
                z = n / np.linalg.norm(n)
                x = bvec - z * (bvec @ z)
                if np.linalg.norm(x) < 1e-9:
                    raise Skip("PLANE VECTOR whose base vector is along the normal")
                x /= np.linalg.norm(x)
                self.plane = np.column_stack([x, np.cross(z, x), z])
            elif up.startswith("PLANE RELATIV"):  # one rotation about an axis of the plane already tilted
                m = re.search(r"\b(SPA|SPB|SPC)\s*(" + _VAL + ")", up)
                if not m:
                    raise Skip("PLANE RELATIV without SPA, SPB or SPC")
                turn = {"SPA": rot_x, "SPB": rot_y, "SPC": rot_z}[m.group(1)](math.radians(self._num(m.group(2))))
                self.plane = self.plane @ turn
            else:
                raise Skip(f"{' '.join(up.split()[:2])} is not read (SPATIAL, EULER, VECTOR, RELATIV and RESET are)")
        self._frame()
        self.b.note("PLANE", line)
        for k in ("Q120", "Q121", "Q122"):  # the rotary positions the control computes for the plane: the
            self.q.setdefault(k, 0.0)  # frame gives tip and axis, so their values only label the angles
        if not up.startswith("PLANE RESET"):
            self.b.note("Q120-Q122 (rotary positions the control computes for PLANE) read as 0: the plane gives "
                        "the tool axis", line)

    def _cycl_def(self, line: int, up: str) -> str | None:
        m = re.match(r"CYCL DEF\s*(\d+)\s*(?:\.\s*(\d+))?\s*(.*)$", up)
        if not m:
            raise Skip("CYCL DEF without a cycle number")
        num, sub, rest = int(m.group(1)), m.group(2), m.group(3)
        q = {k.upper(): self._num(v) for k, v in re.findall(r"\b(Q\d+)\s*=\s*(" + _VAL + ")", rest)}
        if num == 7:
            if sub in (None, "0"):
                return None
            if "#" in rest:
                raise Skip("CYCL DEF 7 from a datum table (#) is not read")
            w = self._words(rest)
            for k, a in enumerate("XYZ"):
                if a in w:
                    self.shift[k] = self._len(w[a])
            self._frame()
            self.b.note("CYCL DEF 7 (datum shift)", line)
            return None
        if num == 247:
            self.b.offset(f"preset {q.get('Q339', 0):g} (CYCL DEF 247)", line)
            return None
        if num in (32, 332, 9, 13, 392, 397):
            self.b.note({32: "CYCL DEF 32 (tolerance)", 332: "CYCL DEF 332 (tolerance)", 9: "CYCL DEF 9 (dwell)",
                         13: "CYCL DEF 13 (oriented spindle stop)", 392: "CYCL DEF 392 (ATC)",
                         397: "CYCL DEF 397"}[num], line)
            return None
        if num == 10:  # ROTATION in the working plane: 10.1 ROT+angle about the tool axis
            if sub in (None, "0"):
                return None
            mr = re.search(r"ROT\s*(" + _VAL + ")", rest)
            if not mr:
                raise Skip("CYCL DEF 10 without ROT")
            self.rotation = rot_z(math.radians(self._num(mr.group(1))))
            self._frame()
            self.b.note("CYCL DEF 10 (rotation)", line)
            return None
        if num == 19:
            raise Skip("CYCL DEF 19 (tilted plane by cycle) is not read; PLANE is")
        if 200 <= num <= 209 or num in (240, 241):
            self.b.end_cycle()  # the holes of one CYCL DEF are one cycle
            self.cycle = (f"CYCL DEF {num}", q.get("Q201", 0.0), q.get("Q203", 0.0))
            return None
        raise Skip(f"CYCL DEF {num} is not read")

    def _hole(self, line: int, text: str) -> None:
        if self.cycle is None:
            raise Skip("cycle call without a CYCL DEF")
        code, depth, surface = self.cycle
        x, y = self.pos["X"], self.pos["Y"]
        if math.isnan(x) or math.isnan(y):
            raise Skip("cycle call at an unknown position")
        self.b.cycle(code, line, np.array([x, y, self._len(surface + depth)]), text)


def read_heidenhain(path: str, text: str, machine: Any = None, chord_tol: float | None = None) -> CLProgram:
    """Read a Heidenhain Klartext program as a CLProgram (module docstring)."""
    return _Klartext(str(path), text, chord_tol).run(machine)


# ----------------------------------------------------------------------------------------------
# the writer's words (camsmooth.post.writer) and this module's entry of camsmooth.post.DIALECTS

#: Klartext (iTNC 530, TNC 640 user's manuals): ``L`` blocks numbered from 0 between BEGIN PGM and
#: END PGM, ``TOOL CALL <tool> Z``, no inverse-time feed (machine mode refused: M116 is for rotary
#: tables only), TCP ``FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS`` ... ``FUNCTION RESET TCPM`` (the
#: successor of M128), cycle 32 TOLERANCE, home ``M140 MB MAX``
HEIDENHAIN = Words("heidenhain", semicolon, (), end=("M30",), home=("M140 MB MAX",),
                   tcp_on="FUNCTION TCPM F TCP AXIS POS PATHCTRL AXIS", tcp_off="FUNCTION RESET TCPM",
                   inverse_time=None, per_minute="", klartext=True,
                   path_tolerance=("CYCL DEF 32.0 TOLERANCE", "CYCL DEF 32.1 T{tol}", "CYCL DEF 32.2 HSC-MODE:0"))


def _read(path: str, text: str, machine: Any = None, dialect: str = "heidenhain",
          chord_tol: float | None = None) -> CLProgram:
    return read_heidenhain(path, text, machine, chord_tol)


DIALECTS = (PostDialect("heidenhain", _read, HEIDENHAIN),)
