"""ISO G-code as CAM posts write it for Fanuc, Haas, Mori Seiki, Okuma-style controls and
LinuxCNC (dialects 'fanuc', 'haas', 'linuxcnc'; all read by ``read_iso``).

Sources: the Fanuc Series 30i/31i-B operator's manual (B-63944EN) sections "Interpolation
functions" (G02/G03 with I J K or R, helical interpolation: the axis normal to the plane moves
linearly), "Plane selection" (G17 XY normal +Z, G18 ZX normal +Y, G19 YZ normal +X; G03 counter
clockwise seen from the positive end of that normal), "Tool center point control" (G43.4 type 1
with rotary positions, G43.5 type 2 with the tool vector I J K, cancelled by G49), "Tilted
working plane indexing" (G68.2 X Y Z I J K: origin and Euler angles Z-X-Z, G53.1 turns the tool
along the plane's Z, G69 cancels), "Coordinate system rotation" (G68 X Y R in the plane; G68 X Y Z
I J K R three-dimensional about the vector IJK), "Canned cycles for drilling" (G73, G74, G76,
G81-G89, G98/G99 return level, R point, G80 cancels), "Subprogram call" (M98 P, M99) and
"Custom macro" (#i = expression); the Haas mill operator's manual, "G-codes": G234 (tool centre
point control), G254/G255 (dynamic work offset), G154 P / G110-G129 (extra work offsets), G187
(smoothness, no motion); the LinuxCNC G-code reference (G-code overview: numbered and named
parameters ``#<name>``, comments ``( )`` and ``;``, spaces allowed inside words, block delete
``/``, G90.1/G91.1 arc centre mode with IJK incremental by default, the P word of G2/G3 = turns,
the M428/M429 remaps of the xyzac-trt / xyzbc-trt configurations switching to and from the trt
kinematics). A block of this dialect is letters with values: ``X-1.5``, ``X 1 .5``, ``X#101``,
``X[#1+2]``; several G and M words per block.

Applied: G0 G1 G2 G3 (helices and full circles, I J K or R, every plane, P turns), G4 (dwell, no
motion), G17-G19, G20/G21, G90/G91, G90.1/G91.1, G93/G94/G95, G43/G44/G49, G43.4/G43.5/G234
(TCP), G68.2/G68.3 off/G68.4/G68/G69 and G254/G255, G52 (local shift), G54-G59, G54.1 P, G154 P,
G110-G129 (recorded), G53/G28/G30 (machine moves), canned cycles, M98/M99 (subprograms in the same
file, L repeats), Haas M97 P (the block N<P> up to M99), M6/T, M428/M429 (LinuxCNC TCP), ``#``
assignments. Read without effect: G5.1,
G05 P, G8, G15/G16 off, G40, G61/G64, G80, G98/G99, G187, G10 (data), spindle, coolant and the
other M words. Named and costing their operation: cutter radius compensation G41/G42 (the path
is not the tool's), polar / scaling / mirror words, G92, LinuxCNC o-word control flow, words this
reader does not know.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.program import CLProgram, Tool
from camsmooth.post.core import INCH_MM, Builder, Frame3, Skip, rot_x, rot_z
from camsmooth.post.model import PostDialect
from camsmooth.post.words import evaluate, operation_name, split_comments, tool_comment
from camsmooth.post.writer import Words, paren

__all__ = ["read_iso", "IsoInterpreter", "DIALECTS", "GENERIC", "FANUC"]

_LINEAR = ("X", "Y", "Z")
_ROTARY = ("A", "B", "C")
_NUM = r"[-+]?(?:\d+\.?\d*|\.\d+)"  # no exponent: E is a word (Haas G187 E0.01)
_NUM_RE = re.compile(_NUM)
#: a block of plain words only (no parameters or expressions): read with one findall
_PLAIN = re.compile(r"(?:[A-Za-z][-+]?(?:\d+\.?\d*|\.\d+))+")
_PAIR = re.compile(r"([A-Za-z])([-+]?(?:\d+\.?\d*|\.\d+))")
_SPACE = re.compile(r"\s+")
_BLOCK_NUMBER = re.compile(r"^\s*N\s*\d+\s*", re.I)
_PROGRAM_NUMBER = re.compile(r"^\s*[O:]\s*\d+\s*$", re.I)
_O_WORD = re.compile(r"^\s*[oO]\s*(\d+|<[^>]*>)\s*(\w+)")
_AXES = ("X", "Y", "Z", "A", "B", "C")
_MOTION_WORDS = frozenset(("X", "Y", "Z", "A", "B", "C", "I", "J", "K", "R", "P", "Q", "L", "E"))
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}  # (first, second, normal) axis indices
_CYCLES = {73, 74, 76, 81, 82, 83, 84, 85, 86, 87, 88, 89}
_NO_MOTION = {4.0, 10.0, 11.0, 92.0}
_NOTED_G = {5.1: "G05.1 (look-ahead)", 5.0: "G05 (high-speed)", 8.0: "G08 (look-ahead)", 15.0: "G15", 40.0: "G40",
            61.0: "G61", 61.1: "G61.1", 64.0: "G64", 80.0: "G80", 98.0: "G98", 99.0: "G99", 187.0: "G187",
            53.1: "G53.1 (tool along the tilted plane's Z)", 49.0: "G49", 43.0: "G43", 44.0: "G44",
            103.0: "G103 (Haas look-ahead)", 64.1: "G64.1", 8.1: "G08.1",
            90.1: "G90.1", 91.1: "G91.1", 69.0: "G69", 50.0: "G50", 13.1: "G13.1", 7.1: "G7.1"}
_SKIP_G = {41.0: "cutter radius compensation (G41): the programmed path is not the tool's",
           42.0: "cutter radius compensation (G42): the programmed path is not the tool's",
           16.0: "polar coordinates (G16)", 51.0: "scaling (G51)", 51.1: "mirror image (G51.1)",
           92.0: "G92 coordinate system setting", 12.1: "polar interpolation (G12.1)",
           68.3: "tool-axis-direction tilted plane (G68.3)", 5.2: "G05.2", 6.2: "NURBS interpolation (G06.2)"}
_OFFSETS = {54.0: "G54", 55.0: "G55", 56.0: "G56", 57.0: "G57", 58.0: "G58", 59.0: "G59"}


@dataclass
class _Block:
    line: int
    text: str
    words: list[tuple[str, float]]
    comments: list[str]
    raw_words: list[tuple[str, str]] = field(default_factory=list)


class IsoInterpreter:
    """Runs an ISO program through a Builder (module docstring). ``keyword`` is called with the
    code text of blocks that hold a word of more than one letter (Siemens), before the ISO words
    are read; it returns the text left for them."""

    def __init__(self, file: str, text: str, dialect: str, chord_tol: float | None = None) -> None:
        self.file = file
        self.b = Builder(file, dialect)
        if chord_tol is not None:
            self.b.chord_tol = chord_tol
        self.dialect = dialect
        self.lines = text.split("\n")
        self.vars: dict[str, float] = {}
        self.pos = {a: math.nan for a in _LINEAR}
        self.rot: dict[str, float] = {}
        self.motion: float | None = None
        self.plane = 17
        self.absolute = True
        self.arc_abs = False
        self.inch = False
        self.tilt = Frame3()
        self.local = Frame3()
        self.cycle_z: float | None = None
        self.cycle_r: float | None = None
        self.cycle_return = 98
        self.initial_z = math.nan
        self.next_tool: int | None = None
        self.pending_names: list[str] = []
        self.vec: tuple[float, float, float] | None = None
        self.tcp_vector = False
        self.block_delete: list[int] = []
        self.keyword: Callable[[int, str, list[str]], str] | None = None
        self.paren = True  # '( ... )' are comments (not in Siemens, whose parentheses are syntax)

    # ------------------------------------------------------------------------------------------
    def run(self, machine: Any = None) -> CLProgram:
        starts = self._program_range()
        labels = self._labels(starts)
        self._execute(starts[0], starts[1], labels, depth=0)
        for ln in self.block_delete:
            self.b.note("block delete '/' (read as executed: block-delete switch off)", ln)
        return self.b.finish(machine)

    def _program_range(self) -> tuple[int, int]:
        """[first, last) line index of the program: after a listing banner ending at the first
        ``%`` line, up to the second ``%``."""
        pct = [i for i, ln in enumerate(self.lines) if ln.strip().startswith("%")]
        if not pct:
            return 0, len(self.lines)
        first = pct[0] + 1
        end = next((i for i in pct[1:] if i > pct[0]), len(self.lines))
        return first, end

    def _labels(self, rng: tuple[int, int]) -> dict[int, int]:
        """Fanuc program numbers ``O1234`` / ``:1234`` -> line index (subprograms in the file)."""
        out: dict[int, int] = {}
        for i in range(rng[0], rng[1]):
            m = re.match(r"^\s*[O:]\s*(\d+)\b", self.lines[i], re.I)
            if m and not re.match(r"^\s*O\s*\d+\s*(sub|endsub|call|if|else|elseif|endif|while|endwhile|do|repeat|"
                                  r"endrepeat|return|break|continue)\b", self.lines[i], re.I):
                out.setdefault(int(m.group(1)), i)
        return out

    def _execute(self, first: int, last: int, labels: dict[int, int], depth: int) -> str | None:
        i = first
        while i < last:
            raw = self.lines[i]
            number = i + 1
            i += 1
            try:
                blk = self._block(number, raw)
            except InputError:
                raise
            except Skip as exc:
                self.b.skip(number, raw, exc.reason)
                continue
            except (ValueError, IndexError, ArithmeticError) as exc:  # a block this reader cannot read
                self.b.skip(number, raw, f"the block cannot be read ({exc})")
                continue
            if blk is None:
                continue
            try:
                flow = self._run_block(blk, labels, depth)
            except InputError:
                raise
            except Skip as exc:
                self.b.skip(number, raw, exc.reason)
                continue
            except (ValueError, IndexError, ArithmeticError) as exc:  # a block this reader cannot read
                self.b.skip(number, raw, f"the block cannot be read ({exc})")
                continue
            if flow in ("end", "return"):
                return flow
        return None

    # ---- one line ----------------------------------------------------------------------------
    def _block(self, number: int, raw: str) -> _Block | None:
        code, comments = split_comments(raw, paren=self.paren)
        after_blank = number >= 2 and not self.lines[number - 2].strip()
        for c in comments:
            self._comment(number, c, heading=after_blank and not code.strip() and len(comments) == 1)
        code = code.strip()
        if not code:
            return None
        if code.startswith("/"):
            self.block_delete.append(number)
            code = code.lstrip("/").lstrip("0123456789")
        if code[0] in "Nn":
            code = _BLOCK_NUMBER.sub("", code)
        if not code.strip() or code.strip() == "%":
            return None
        if code[0] in "Oo:" and _PROGRAM_NUMBER.match(code):
            return None  # a program number
        m = _O_WORD.match(code) if code[0] in "Oo" else None
        if m and m.group(2).lower() in ("sub", "endsub", "call", "if", "else", "elseif", "endif", "while",
                                        "endwhile", "do", "repeat", "endrepeat", "return", "break", "continue"):
            raise Skip(f"LinuxCNC o-word {m.group(2).lower()} (control flow and subroutines of o-words are not "
                       "executed by this reader)")
        if self.keyword is not None:
            code = self.keyword(number, code, comments)
            if not code.strip():
                return None
        return _Block(number, raw, self._words(number, code), comments)

    def _comment(self, number: int, text: str, heading: bool = False) -> None:
        """An operation name: explicit (words.operation_name), or a comment standing alone on the
        line after a blank line once the current operation has moved (NX's "( NAME )" heading)."""
        t = text.strip()
        if not t or t[:3].upper() in ("MSG", "DEB", "PRI", "LOG"):
            return
        name = operation_name(t)
        if name is None and heading and self.b.has_motion() and not tool_comment(t) and re.search(r"[A-Za-z]", t):
            name = " ".join(t.split())
        if name is not None:
            self.b.operation(name, number)
            self.pending_names = []
            return
        if not tool_comment(t) and not set(t) <= set("-=*_ .#"):
            self.pending_names.append(" ".join(t.split()))
            if len(self.pending_names) > 3:
                self.pending_names.pop(0)

    def _value(self, text: str, number: int) -> float:
        """A word's value: a number, ``#n`` / ``#<name>``, or ``[expression]``."""
        try:
            return float(text)
        except ValueError:
            pass
        lookup: dict[str, float] = {}

        def sub(m: re.Match[str]) -> str:
            key = m.group(1) or m.group(2)
            key = key.lower()
            ident = "v_" + re.sub(r"\W", "_", key)
            if key in self.vars:
                lookup[ident] = self.vars[key]
            return ident

        expr = re.sub(r"#\s*(?:<([^>]*)>|(\d+))", sub, text)
        return evaluate(expr, lookup)

    def _words(self, number: int, code: str) -> list[tuple[str, float]]:
        """The (letter, value) words of a block's code; ``#`` assignments are done here."""
        s = _SPACE.sub("", code)
        if _PLAIN.fullmatch(s):  # the common block: letters and numbers only
            return [(w.upper(), float(v)) for w, v in _PAIR.findall(s)]
        # assignments: '#100=2.5', '#<name>=[#1*2]' (one or several per line)
        while s.startswith("#"):
            m = re.match(r"#(?:<([^>]*)>|(\d+))=(.*)$", s)
            if not m:
                raise Skip("a '#' word that is not an assignment")
            rest = m.group(3)
            # the value runs to the next assignment or word letter outside brackets
            depth, j = 0, 0
            while j < len(rest):
                ch = rest[j]
                if ch == "[":
                    depth += 1
                elif ch == "]":
                    depth -= 1
                elif depth == 0 and j > 0 and (ch == "#" or (ch.isalpha() and not _in_func(rest, j))):
                    break
                j += 1
            self.vars[(m.group(1) or m.group(2)).lower()] = self._value(rest[:j], number)
            s = rest[j:]
        words: list[tuple[str, float]] = []
        j = 0
        while j < len(s):
            ch = s[j].upper()
            if not ch.isalpha():
                raise Skip(f"{s[j:j + 12]!r} is not a word (a letter and its value)")
            j += 1
            if j < len(s) and s[j] == "[":
                depth, k = 0, j
                while k < len(s):
                    depth += s[k] == "["
                    depth -= s[k] == "]"
                    k += 1
                    if depth == 0:
                        break
                words.append((ch, self._value(s[j:k], number)))
                j = k
                continue
            m = re.match(r"#(?:<[^>]*>|\d+)", s[j:])
            if m:
                words.append((ch, self._value(m.group(0), number)))
                j += m.end()
                continue
            m = _NUM_RE.match(s, j)
            if not m:
                raise Skip(f"word {ch} has no value ({s[j - 1:j + 10]!r})")
            words.append((ch, float(m.group(0))))
            j = m.end()
        return words

    # ---- one block ---------------------------------------------------------------------------
    def _run_block(self, blk: _Block, labels: dict[int, int], depth: int) -> str | None:
        line = blk.line
        g = [v for w, v in blk.words if w == "G"]
        mcodes = [v for w, v in blk.words if w == "M"]
        vals: dict[str, float] = {}
        for w, v in blk.words:
            if w in ("G", "M"):
                continue
            if w in vals and w not in ("P",):
                raise Skip(f"word {w} twice in one block")
            vals[w] = v
        non_modal_machine = False
        motion_now: float | None = None
        no_motion = False
        for code in g:
            c = round(code, 1)
            if c in (0.0, 1.0, 2.0, 3.0):
                motion_now = c
                self.motion = c
                self.b.end_cycle()
            elif c in _CYCLES:
                motion_now = c
                self.motion = c
            elif c == 80.0:
                self.motion = None
                self.b.end_cycle()
                self.cycle_z = self.cycle_r = None
            elif c in (17.0, 18.0, 19.0):
                self.plane = int(c)
            elif c == 20.0:
                self.inch = True
            elif c == 21.0:
                self.inch = False
            elif c == 90.0:
                self.absolute = True
            elif c == 91.0:
                self.absolute = False
            elif c == 90.1:
                self.arc_abs = True
            elif c == 91.1:
                self.arc_abs = False
            elif c in (93.0, 94.0, 95.0):
                self.b.feed_mode = int(c)
            elif c in (98.0, 99.0):
                self.cycle_return = int(c)
            elif c in (43.4, 43.5) or (c == 234.0 and self.dialect in ("haas", "iso", "fanuc")):
                self.b.tcp = True
                self.tcp_vector = c == 43.5
                self.b.note({43.4: "G43.4 (TCP on)", 43.5: "G43.5 (TCP, tool vector I J K)",
                             234.0: "G234 (Haas TCPC on)"}[c], line)
            elif c in (43.0, 44.0, 49.0):
                if self.dialect not in ("linuxcnc", "millplus"):  # LinuxCNC: TCP is M428/M429; MillPlus: G141
                    self.b.tcp = False
                self.tcp_vector = False
                self.b.note(_NOTED_G[c], line)
            elif c == 254.0:
                self.b.dwo = True
                self.b.note("G254 (Haas dynamic work offset)", line)
            elif c == 255.0:
                self.b.dwo = False
            elif c == 68.2 or c == 68.4:
                self._g68_2(vals, line, incremental=c == 68.4)
                no_motion = True
            elif c == 68.0:
                self._g68(vals, line)
                no_motion = True
            elif c == 69.0:
                self.tilt = Frame3()
                self._set_frame()
            elif c == 52.0:
                o = np.array([self._len(vals.get(a, 0.0)) for a in _LINEAR])
                self.local = Frame3(o=o)
                self._set_frame()
                no_motion = True
            elif c in _OFFSETS:
                self.b.offset(_OFFSETS[c], line)
            elif c == 54.1 or (c == 154.0 and self.dialect != "linuxcnc"):
                p = vals.pop("P", None)
                self.b.offset(f"G{c:g} P{p:g}" if p is not None else f"G{c:g}", line)
            elif 110.0 <= c <= 129.0 and c == int(c):
                self.b.offset(f"G{c:g}", line)
            elif c in (53.0, 28.0, 30.0, 28.1, 30.1):
                non_modal_machine = True
            elif c == 4.0:
                no_motion = True
            elif c == 10.0:
                no_motion = True
                self.b.note("G10 (offset data)", line)
            elif c in _SKIP_G:
                raise Skip(_SKIP_G[c])
            elif c in _NOTED_G:
                self.b.note(_NOTED_G[c], line)
            elif c == 53.1:
                self.b.note(_NOTED_G[c], line)
            else:
                raise Skip(f"G{c:g} is not read by the {self.dialect} reader")
        flow = self._m_words(mcodes, vals, line, labels, depth)
        if "T" in vals:
            self.next_tool = int(vals.pop("T"))
            if self.dialect == "linuxcnc" or 6.0 not in mcodes:
                pass
        if 6.0 in mcodes:
            self._tool_change(line)
        for w in ("S",):
            if w in vals:
                self.b.S = vals.pop(w)
        if "F" in vals:
            f = vals.pop("F")
            if not (abs(f) <= 1e9):
                raise InputError(f"F{f:g} is not a feed", file=self.file, line=line)
            if self.b.feed_mode == 93 and not f > 0:
                raise Skip(f"F{f:g} in inverse time (G93) is not a block time")
            self.b.F = f * INCH_MM if (self.inch and self.b.feed_mode != 93) else f
        for w in ("H", "D"):
            vals.pop(w, None)
        if non_modal_machine:
            if any(a in vals for a in (*_LINEAR, *_ROTARY)):
                self.b.machine_move(line, f"machine-coordinate move (G{g[0]:g})" if g else "machine move")
                for a in _ROTARY:  # a rotary axis of G53 ends at its value (a new dict: points keep theirs)
                    if a in vals and any(round(c, 1) == 53.0 for c in g):
                        self.rot = {**self.rot, a: vals[a]}
            return flow
        if no_motion:
            return flow
        if flow == "return" or flow == "end":
            self._motion(blk, vals, motion_now)
            return flow
        self._motion(blk, vals, motion_now)
        return flow

    def _m_words(self, mcodes: list[float], vals: dict[str, float], line: int, labels: dict[int, int],
                 depth: int) -> str | None:
        flow = None
        for m in mcodes:
            if m in (30.0, 2.0):
                flow = "end"
            elif m == 99.0:
                flow = "return"
            elif m == 98.0:
                p = vals.pop("P", None)
                reps = int(vals.pop("L", vals.pop("K", 1)))
                if p is None:
                    raise Skip("M98 without P")
                prog = int(p)
                if prog not in labels and prog > 9999 and (prog % 10000) in labels:
                    reps, prog = prog // 10000, prog % 10000  # Fanuc P: repeats and number in one word
                if prog not in labels:
                    raise Skip(f"M98 P{p:g}: subprogram O{prog} is not in this file")
                if depth >= 8:
                    raise Skip("subprograms nested deeper than 8")
                for _ in range(max(reps, 0)):
                    self._execute(labels[prog] + 1, len(self.lines), labels, depth + 1)
            elif m == 97.0:  # Haas local subprogram: the block numbered N<P> of this program, up to M99
                p = vals.pop("P", None)
                reps = int(vals.pop("L", 1))
                start = None if p is None else next(
                    (i for i, ln in enumerate(self.lines) if re.match(rf"^\s*N0*{int(p)}(?!\d)", ln, re.I)), None)
                if start is None:
                    label = "" if p is None else f"{int(p)}"
                    raise Skip(f"M97 P{label}: no block N{label} in this file")
                if depth >= 8:
                    raise Skip("subprograms nested deeper than 8")
                for _ in range(max(reps, 0)):
                    self._execute(start, len(self.lines), labels, depth + 1)
            elif m == 428.0 and self.dialect in ("linuxcnc", "iso"):
                self.b.tcp = True
                self.b.note("M428 (LinuxCNC trt kinematics: TCP on)", line)
            elif m == 429.0 and self.dialect in ("linuxcnc", "iso"):
                self.b.tcp = False
                self.b.note("M429 (LinuxCNC identity kinematics: TCP off)", line)
        return flow

    def _tool_change(self, line: int) -> None:
        n = self.next_tool
        name = self.pending_names[-1] if self.pending_names else None
        self.b.tool(Tool(name=f"T{n}" if n is not None else None, kind="mill", diameter=None, corner_radius=None,
                         number=n, line=line), line)
        if name is not None:
            self.b.name_operation(name, line)
        self.pending_names = []

    def _len(self, v: float) -> float:
        return v * INCH_MM if self.inch else v

    def _set_frame(self) -> None:
        self.b.set_frame(self.local.then(self.tilt) if not self.local.identity else self.tilt)

    def _g68_2(self, vals: dict[str, float], line: int, incremental: bool) -> None:
        """G68.2 X Y Z I J K: origin (X, Y, Z) and Euler angles I (about Z), J (about the new X), K
        (about the newest Z): R = Rz(I) Rx(J) Rz(K) (Fanuc 30i "Tilted working plane indexing",
        Eulerian angle method, P0)."""
        p = vals.pop("P", 0.0)
        if p != 0.0:
            raise Skip(f"G68.2 P{p:g} (a tilted plane given by roll-pitch-yaw, three points or a vector is not read)")
        o = np.array([self._len(vals.pop(a, 0.0)) for a in _LINEAR])
        ii, jj, kk = (math.radians(vals.pop(a, 0.0)) for a in ("I", "J", "K"))
        fr = Frame3(rot_z(ii) @ rot_x(jj) @ rot_z(kk), o)
        self.tilt = self.tilt.then(fr) if incremental else fr
        self._set_frame()
        self.b.note("G68.2 (tilted working plane)", line)

    def _g68(self, vals: dict[str, float], line: int) -> None:
        """G68: rotation in the plane (G17: X Y R about Z) or, with I J K, about the vector (I, J, K)
        through (X, Y, Z) by R degrees (Fanuc "Three-dimensional coordinate conversion")."""
        r = math.radians(vals.pop("R", 0.0))
        if any(a in vals for a in ("I", "J", "K")):
            axis = np.array([vals.pop(a, 0.0) for a in ("I", "J", "K")])
            n = np.linalg.norm(axis)
            if n < 1e-12:
                raise Skip("G68 with a zero rotation vector")
            u = axis / n
            K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
            R = np.eye(3) + math.sin(r) * K + (1 - math.cos(r)) * K @ K
            c = np.array([self._len(vals.pop(a, 0.0)) for a in _LINEAR])
        else:
            i1, i2, i3 = _PLANES[self.plane]
            u = np.zeros(3)
            u[i3] = 1.0
            K = np.array([[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]])
            R = np.eye(3) + math.sin(r) * K + (1 - math.cos(r)) * K @ K
            c = np.zeros(3)
            for a in _LINEAR:
                if a in vals:
                    c["XYZ".index(a)] = self._len(vals.pop(a))
        self.tilt = Frame3(R, c - R @ c)
        self._set_frame()
        self.b.note("G68 (coordinate rotation)", line)

    # ---- motion ------------------------------------------------------------------------------
    def _target(self, vals: dict[str, float]) -> tuple[list[float], dict[str, float]]:
        p = [self.pos["X"], self.pos["Y"], self.pos["Z"]]
        for k, a in enumerate(_LINEAR):
            if a in vals:
                v = self._len(vals[a])
                p[k] = v if self.absolute else (0.0 if math.isnan(p[k]) else p[k]) + v
        rot = self.rot
        if any(a in vals for a in _ROTARY):
            rot = dict(self.rot)
            for a in _ROTARY:
                if a in vals:
                    rot[a] = vals[a] if self.absolute else rot.get(a, 0.0) + vals[a]
        return p, rot

    def _motion(self, blk: _Block, vals: dict[str, float], motion_now: float | None) -> None:
        axes = [a for a in _AXES if a in vals]
        extra = [w for w in vals if w not in _MOTION_WORDS]
        if extra:
            raise Skip(f"word{'s' if len(extra) > 1 else ''} {', '.join(extra)} not read by this reader")
        for w in ("U", "V", "W"):
            if w in vals:
                raise Skip(f"axis {w} is not read")
        mot = self.motion
        if mot is None:
            if axes:
                raise Skip("a position without a motion mode (G0/G1/G2/G3)")
            return
        if mot in _CYCLES:
            if motion_now is not None or axes:
                self._cycle(blk, vals, mot)
            return
        if not axes and not (mot in (2.0, 3.0) and any(w in vals for w in ("I", "J", "K", "R"))):
            return
        target, rot = self._target(vals)
        if mot in (2.0, 3.0):
            self._arc(blk, vals, np.array(target), rot, ccw=mot == 3.0)
        else:
            if target[0] != target[0] or target[1] != target[1] or target[2] != target[2]:  # an axis not yet known
                for k, a in enumerate(_LINEAR):
                    self.pos[a] = float(target[k])
                self.rot = rot
                self.b.machine_move(blk.line, "move before X, Y and Z are all known (not a point)")
                return
            vec = None
            if self.tcp_vector and any(w in vals for w in ("I", "J", "K")):
                vec = tuple(vals.get(w, 0.0) for w in ("I", "J", "K"))
                self.vec = vec  # type: ignore[assignment]
            elif self.tcp_vector:
                vec = self.vec
            self.b.move(blk.line, mot == 0.0, (float(target[0]), float(target[1]), float(target[2])), rot, vec)
        for k, a in enumerate(_LINEAR):
            self.pos[a] = float(target[k])
        self.rot = rot

    def _arc(self, blk: _Block, vals: dict[str, float], end: np.ndarray, rot: dict[str, float], ccw: bool) -> None:
        start = np.array([self.pos[a] for a in _LINEAR])
        if np.isnan(start).any() or np.isnan(end).any():
            raise Skip("an arc whose start point is not known")
        i1, i2, i3 = _PLANES[self.plane]
        normal = np.zeros(3)
        normal[i3] = 1.0
        letters = "IJK"
        if "R" in vals:
            r = self._len(vals["R"])
            d = end - start
            d[i3] = 0.0
            chord = float(np.linalg.norm(d))
            if chord < 1e-9:
                raise Skip("a full circle given by R (the centre is not defined)")
            if abs(r) < chord / 2 - max(1e-4, 1e-6 * abs(r)):
                raise Skip(f"arc radius R{vals['R']:g} is smaller than half the chord ({chord / 2:.6g} mm)")
            h = math.sqrt(max(r * r - chord * chord / 4, 0.0))
            left = np.cross(normal, d) / chord
            side = 1.0 if ccw else -1.0
            if r < 0:
                side = -side
            centre = start + d / 2 + side * h * left
        else:
            off = np.zeros(3)
            for k in (i1, i2):
                w = letters[k]
                if w in vals:
                    off[k] = self._len(vals[w])
                elif self.arc_abs:
                    off[k] = start[k]
            if self.arc_abs:
                centre = off.copy()
                centre[i3] = start[i3]
            else:
                centre = start + off
        r0 = math.hypot(*(start - centre)[[i1, i2]])
        r1 = math.hypot(*(end - centre)[[i1, i2]])
        if abs(r1 - r0) > max(0.002 if not self.inch else 0.0002 * INCH_MM, 1e-3 * r0):
            raise Skip(f"arc end point radius {r1:.6g} mm differs from the start radius {r0:.6g} mm")
        turns = 0
        if "P" in vals and self.dialect in ("linuxcnc", "iso", "siemens"):
            turns = max(int(vals["P"]) - 1, 0)
        self.b.arc(blk.line, start, end, centre, normal, ccw, self.rot, rot, turns)

    def _cycle(self, blk: _Block, vals: dict[str, float], mot: float) -> None:
        if self.plane != 17:
            raise Skip(f"canned cycle G{mot:g} in plane G{self.plane} (only G17 cycles are read)")
        if not self.absolute:
            raise Skip(f"canned cycle G{mot:g} in incremental mode (G91)")
        if "Z" in vals:
            self.cycle_z = self._len(vals["Z"])
        if "R" in vals:
            self.cycle_r = self._len(vals["R"])
        if self.cycle_z is None:
            raise Skip(f"canned cycle G{mot:g} without a depth Z")
        if self.b.has_motion() is False and math.isnan(self.initial_z):
            self.initial_z = self.pos["Z"]
        if vals.get("L", vals.get("K", 1.0)) == 0.0:
            return  # L0 / K0: positions only
        x = self._len(vals["X"]) if "X" in vals else self.pos["X"]
        y = self._len(vals["Y"]) if "Y" in vals else self.pos["Y"]
        if math.isnan(x) or math.isnan(y):
            raise Skip(f"canned cycle G{mot:g} at an unknown position")
        self.b.cycle(f"G{mot:g}", blk.line, np.array([x, y, self.cycle_z]), blk.text)
        self.pos["X"], self.pos["Y"] = x, y
        if self.cycle_return == 99 and self.cycle_r is not None:
            self.pos["Z"] = self.cycle_r
        self.b.machine_move(blk.line, f"canned cycle G{mot:g}")
        self.b.notes.pop(f"canned cycle G{mot:g}", None)


def _in_func(s: str, j: int) -> bool:
    """Whether the letters at s[j] belong to a function name inside an expression (SIN[...])."""
    m = re.match(r"[A-Za-z]+\[", s[j:])
    if m:
        return True
    k = j
    while k > 0 and s[k - 1].isalpha():
        k -= 1
    return bool(re.match(r"[A-Za-z]+\[", s[k:]))


def read_iso(path: str, text: str, machine: Any = None, dialect: str = "iso",
             chord_tol: float | None = None) -> CLProgram:
    """Read an ISO / Fanuc / Haas / LinuxCNC posted program as a CLProgram (module docstring;
    camsmooth.post.core for what a point means)."""
    return IsoInterpreter(str(path), text, dialect, chord_tol).run(machine)


# ----------------------------------------------------------------------------------------------
# the writer's words (camsmooth.post.writer) and this module's entries of camsmooth.post.DIALECTS

#: ISO G-code as RS274NGC / ISO 6983 spell it: mm, absolute, XY plane; inverse time G93; no
#: tool-centre-point command (tcp mode is refused)
GENERIC = Words("generic", paren, ("G21", "G90", "G17"))
#: Fanuc 30i/31i-B: tape start '%' and program number, offsets cancelled (G40 G49 G80), TCP
#: ``G43.4 H<tool>`` (type 1, rotary positions) ... ``G49``, AI contour control ``G05.1 Q1`` (its
#: tolerance is a machine parameter, not a program word), home ``G91 G28 Z0.``
FANUC = Words("fanuc", paren, ("G21", "G90", "G17", "G40", "G49", "G80"), home=("G91 G28 Z0.", "G90"),
              tcp_on="G43.4 H{tool}", tcp_off="G49", percent=True, path_tolerance=("G05.1 Q1",))


def _read_generic(path: str, text: str, machine: Any = None, dialect: str = "iso",
                  chord_tol: float | None = None) -> CLProgram:
    """A generic ISO program, read as ISO."""
    return read_iso(path, text, machine, "iso", chord_tol)


#: generic and Fanuc programs camsmooth writes whole; ISO and Haas programs are read by the same
#: reader and a rewrite writes Fanuc's blocks into them (camsmooth.post.rewrite)
DIALECTS = (PostDialect("generic", _read_generic, GENERIC), PostDialect("fanuc", read_iso, FANUC),
            PostDialect("iso", read_iso, FANUC, own=False), PostDialect("haas", read_iso, FANUC, own=False))
