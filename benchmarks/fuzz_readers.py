"""Fuzzing the file readers (issue 21): valid files mutated byte by byte and line by line must
either read or raise ``camsmooth.errors.InputError`` (or a subclass) -- never another exception,
never hang.

Readers: the APT reader (``read_apt``, seeds: the corpus of tests/data/apt and a short NX file
with a helix), the CL CSV reader (``read_cl_csv``), the G-code reader (``read_gcode``, seeds
written by ``write_gcode`` in three dialects) and the machine TOML reader (``load_machine``, the
default machine file). Mutations (1 to 8 per example): delete, duplicate or overwrite a run of
bytes, insert bytes (digits, separators, '$', '/', NaN and infinity spellings, non-UTF-8 bytes,
CR, NUL), delete, duplicate or swap lines, insert a line from a pool of troublesome records. A
floating-point RuntimeWarning (overflow, invalid value) counts as a finding too.

A fifth pass ("apt-gen") generates APT files record by record instead (consistent arcs and
helices, MSYS frames, tool paths and tool changes, feeds, '$' continuations) and checks the
program read too: finite points, unit axes, tool paths in order, rows where the moves are not
rapid.

tests/test_fuzz_readers.py runs a short pass of this in the suite; this script runs a longer one
and prints what it ran. Usage: python benchmarks/fuzz_readers.py [EXAMPLES_PER_READER] [SEED]
"""

from __future__ import annotations

import sys
import tempfile
import time
import warnings
from collections import Counter
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import HealthCheck, given, seed, settings
from hypothesis import strategies as st

from camsmooth.errors import InputError

__all__ = ["READERS", "seed_files", "mutations", "mutate", "read_or_input_error", "apt_programs", "check_apt_program"]

ROOT = Path(__file__).resolve().parent.parent

#: bytes the mutations insert or write over
ALPHABET = (b"0123456789.,-+eE/$ \t\n\r\x00\xff\xfe\xc3()[]=\"'#;%:_" + b"GOTOCIRCLEnaninfINFNaNXYZABFGMLTIMES")

#: whole lines the mutations insert: records and values that took readers down before or may
LINE_POOL = [
    b"CIRCLE/0,0,0,0,0,1,5,0.01,0.5,6,1,TIMES,3", b"CIRCLE/0,0,0,0,0,1,1e308,0.01,0.5,6,1", b"RAPID",
    b"END-OF-PATH", b"TOOL PATH/X,TOOL,T", b"TOOL PATH/", b"MSYS/0,0,0,1,0,0,0,1,0", b"UNITS/INCHES", b"UNITS/",
    b"FEDRAT/IPR,1", b"FEDRAT/MMPM,nan", b"SPINDL/RPM,1e308", b"MOVARC/0,0,0,0,0,1,5,ANGLE,360",
    b"MOVARC/0,0,0,0,0,1,5,ANGLE", b"GOTO/1e308,1e308,1e308", b"GOTO/nan,0,0", b"GOTO/", b"GOTO/1,2,3,0,0,1,7",
    b"TLDATA/MILL", b"TLDATA/", b"CUTTER/", b"LOADTL/1e400", b"LOAD/TOOL,nan", b"TLAXIS/0,0,0", b"TLAXIS/",
    b"CYCLE/", b"MULTAX/OFF", b"$", b"$$", b"1,2,3", b"/", b",,,", b"x,y,z,i,j,k", b"1,2,3,0,0,1,5,9",
    b"[axis.A]", b"[axis.Q]", b"[post]", b"max = 1e400", b"min = nan", b"vmax = -1", b"pivot = \"a\"", b"kind = 1",
    b"[machine]", b"G93", b"G94", b"G20", b"G0 X1 Y2 Z3 A4 B5", b"G1 X1e400 F0", b"G1 X1 Y1 Z1 A1 B1 F-1",
    b"(camsmooth post: dialect=generic mode=machine pivot=abc)", b"(camsmooth post: pivot=-5)",
    b"1 L X1 Y2 Z3 A4 B5 FMAX", b"BEGIN PGM X MM", b"FUNCTION TCPM F TCP AXIS POS", b"TRAORI", b"M128", b"%",
]


def _apt_seeds() -> list[tuple[str, bytes]]:
    out = [(p.name, p.read_bytes()) for p in sorted((ROOT / "tests" / "data" / "apt").glob("*"))]
    small = (b"UNITS/MM\nTOOL PATH/A,TOOL,T1\nTLDATA/MILL,10,1,50,0,0\nFEDRAT/MMPM,500\nGOTO/5,0,2,0,0,1\n"
             b"CIRCLE/0,0,0,0,0,-1,5,0.01,0.5,10,1,TIMES,1\nGOTO/0,5,0\nGOTO/0,6,0,$\n0.6,0,0.8\n2,2,2\nEND-OF-PATH\n"
             b"TOOL PATH/B\nMSYS/1,2,3,0,1,0,-1,0,0\nGOTO/0,0,0\nMOVARC/0,1,0,0,0,1,1,ANGLE,90\nGOTO/1,1,0\n"
             b"END-OF-PATH\n")
    return out + [("small.cls", small)]


def _cl_seeds() -> list[tuple[str, bytes]]:
    rows = ["x,y,z,i,j,k,row,feed"]
    for k in range(8):
        a = 0.05 * k
        rows.append(f"{k * 0.5:.4f},{0.1 * k:.4f},{0.01 * k * k:.4f},{np.sin(a):.7f},0.0000000,{np.cos(a):.7f},"
                    f"{k // 4},{900 + 10 * k}")
    other = "\ufeffRow,X,Y,Z,I,J,K,note\n" + "".join(f"{k // 3},{k},0,0,0,0,1,\"a, b\"\n" for k in range(6))
    return [("cl.csv", ("\n".join(rows) + "\n").encode()), ("cl_bom.csv", other.encode())]


def _gcode_seeds(folder: Path) -> list[tuple[str, bytes]]:
    from camsmooth.machine.axes import RotaryValues
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.smoothing.posting import write_gcode
    from camsmooth.smoothing.result import MethodResult

    machine = load_machine(None)
    m = 10
    k = np.arange(m)
    tip = np.column_stack([k * 0.5, np.zeros(m), np.zeros(m)])
    a, b = np.radians(5 * np.cos(k / 3)), np.radians(10 * np.sin(k / 4))
    T = machine.tool_axis_np(a, b)
    z0 = np.zeros(m)
    res = MethodResult(method="nlp", rows=k // 5, idx=k % 5, t=z0, cc=tip, normals=T, cl=tip, axis=T, lead=z0,
                       tilt=z0, rotary=RotaryValues.of(machine.rotary, a, b),
                       rotary_vel=RotaryValues.zeros(machine.rotary, m),
                       rotary_acc=RotaryValues.zeros(machine.rotary, m),
                       xyz=machine.linear_axes(tip, a, b),
                       delta=z0, lift=z0, lead_window=np.zeros((m, 2)), tilt_window=np.zeros((m, 2)),
                       compound_acc=z0)
    cutter = type("C", (), {"R": 3.0, "r": 1.0})()
    out = []
    for dialect, mode in (("generic", "machine"), ("heidenhain", "tcp"), ("siemens", "tcp")):
        p = write_gcode(folder / f"{dialect}_{mode}.nc", res, machine, cutter, np.full(m, 1500.0), dialect=dialect,
                        mode=mode)
        out.append((p.name, p.read_bytes()))
    return out


def _machine_seeds() -> list[tuple[str, bytes]]:
    from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML

    minimal = (b'[machine]\nkind = "AB-head"\npivot = 200.0\n[axis.A]\nmin = -90\nmax = 90\nvmax = 30\namax = 100\n'
               b'[axis.B]\nmin = -120\nmax = 120\nvmax = 30.5\namax = 1e2\n[post]\ndialect = "siemens"\nmode = "tcp"\n')
    return [("machine.toml", DEFAULT_MACHINE_TOML.encode()), ("minimal.toml", minimal)]


def seed_files(folder: Path) -> dict[str, list[tuple[str, bytes]]]:
    """Valid files per reader name: (file name, bytes)."""
    return {"apt": _apt_seeds(), "cl-csv": _cl_seeds(), "gcode": _gcode_seeds(folder), "machine": _machine_seeds()}


def _readers() -> dict[str, Callable[[Path], Any]]:
    from camsmooth.io.apt import read_apt
    from camsmooth.io.clcsv import read_cl_csv
    from camsmooth.machine.kinematics import load_machine
    from camsmooth.post.own import read_gcode

    return {"apt": read_apt, "cl-csv": read_cl_csv, "gcode": read_gcode, "machine": lambda p: load_machine(str(p))}


READERS = ("apt", "cl-csv", "gcode", "machine")

_OP = st.sampled_from(["del", "dup", "put", "ins", "del_line", "dup_line", "swap_lines", "ins_line"])
#: one mutation: (operation, position in [0, 1), length 1..40, inserted bytes, a pool line index)
mutations = st.lists(st.tuples(_OP, st.floats(0, 1, exclude_max=True), st.integers(1, 40),
                               st.binary(min_size=1, max_size=12).map(lambda b: bytes(ALPHABET[x % len(ALPHABET)]
                                                                                       for x in b)),
                               st.integers(0, len(LINE_POOL) - 1)), min_size=1, max_size=8)


def mutate(data: bytes, ops: list[tuple[str, float, int, bytes, int]]) -> bytes:
    """``data`` with the mutations applied in order."""
    for op, pos, n, payload, pool in ops:
        if op in ("del", "dup", "put", "ins"):
            i = int(pos * (len(data) + 1))
            if op == "del":
                data = data[:i] + data[i + n:]
            elif op == "dup":
                data = data[:i + n] + data[i:i + n] + data[i + n:]
            elif op == "put":
                data = data[:i] + payload + data[i + len(payload):]
            else:
                data = data[:i] + payload + data[i:]
            continue
        lines = data.split(b"\n")
        i = int(pos * len(lines))
        j = (i + n) % len(lines)
        if op == "del_line":
            del lines[i]
        elif op == "dup_line":
            lines.insert(i, lines[i])
        elif op == "swap_lines":
            lines[i], lines[j] = lines[j], lines[i]
        else:
            lines.insert(i, LINE_POOL[pool])
        data = b"\n".join(lines)
    return data


# ----------------------------------------------------------------------------------------------
# APT programs generated record by record (not mutated): consistent arcs and helices among tool
# paths, tool changes, MSYS frames, feeds, continuations; the reader must give finite points and
# unit axes, or an InputError
def _f(v: float) -> str:
    return f"{v:.4f}"


def _unit(v: tuple[float, float, float]) -> np.ndarray:
    a = np.asarray(v, float)
    return a / np.linalg.norm(a)


_coord = st.floats(-200, 200, allow_nan=False)
_vec = st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(lambda v: sum(x * x for x in v) > 0.05)


@st.composite
def _arc_block(draw: st.DrawFn) -> str:
    """Start GOTO, CIRCLE (NX, clockwise about its axis, optional TIMES) or MOVARC, end GOTO."""
    c = np.array([draw(_coord), draw(_coord), draw(_coord)])
    a = _unit(draw(_vec))
    t = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = _unit(tuple(t - (t @ a) * a))
    e2 = np.cross(a, e1)
    r = draw(st.floats(0.05, 50))
    th0, th1 = draw(st.floats(0, 6.3)), draw(st.floats(0, 6.3))
    h0, h1 = draw(st.floats(-20, 20)), draw(st.floats(-20, 20))
    p0 = c + r * (np.cos(th0) * e1 + np.sin(th0) * e2) + h0 * a
    p1 = c + r * (np.cos(th1) * e1 + np.sin(th1) * e2) + h1 * a
    vec = ",".join(f"{x:.9f}" for x in a)
    if draw(st.booleans()):
        times = draw(st.sampled_from(["", ",TIMES,0", ",TIMES,1", ",TIMES,3"]))
        rec = f"CIRCLE/{','.join(map(_f, c))},{vec},{r:.6f},0.01,0.5,10,1{times}"
    else:
        sweep = ((th1 - th0) % (2 * np.pi)) or 2 * np.pi
        rec = f"MOVARC/{','.join(map(_f, c))},{vec},{r:.6f},ANGLE,{np.degrees(sweep):.6f}"
    return f"GOTO/{','.join(map(_f, p0))}\n{rec}\nGOTO/{','.join(map(_f, p1))}"


@st.composite
def _msys(draw: st.DrawFn) -> str:
    x = _unit(draw(_vec))
    y = draw(_vec)
    y = np.asarray(y) - (np.asarray(y) @ x) * x
    if np.linalg.norm(y) < 0.1:
        y = np.cross(x, [0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.cross(x, [1.0, 0.0, 0.0])
    y = _unit(tuple(y))
    return "MSYS/" + ",".join([_f(draw(_coord)) for _ in range(3)] + [f"{v:.7f}" for v in (*x, *y)])


_goto = st.builds(lambda p, a, six: "GOTO/" + ",".join(map(_f, p)) + ("," + ",".join(f"{v:.7f}" for v in _unit(a))
                                                                     if six else ""),
                  st.tuples(_coord, _coord, _coord), _vec, st.booleans())
_record = st.one_of(
    _goto, _goto, _goto, _arc_block(), _msys(),
    st.builds(lambda p: ",".join(map(_f, p)), st.tuples(_coord, _coord, _coord)),  # a further point of a GOTO
    st.sampled_from(["RAPID", "END-OF-PATH", "UNITS/MM", "MULTAX/OFF", "MULTAX/ON", "CYCLE/OFF", "CUTCOM/LEFT",
                     "COOLNT/ON", "PPRINT/'a, b / c'", "PPRINT finish", "SPINDL/RPM,12000,CLW", "FEDRAT/MMPR,0.05",
                     "FEDRAT/MMPM,800", "FEDRAT/1500.0, MMPM", "$$ comment", "END", "FINI"]),
    st.builds("TOOL PATH/OP{},TOOL,T{}".format, st.integers(0, 9), st.integers(0, 3)),
    st.builds("TLDATA/MILL,{:.4f},{:.4f},50,0,0".format, st.floats(1, 20), st.floats(0, 0.5)),
    st.builds("CUTTER/{:.4f},{:.4f}".format, st.floats(1, 20), st.floats(0, 0.5)),
    st.builds("LOADTL/{}".format, st.integers(1, 99)),
    st.builds(lambda a: "TLAXIS/" + ",".join(f"{v:.7f}" for v in _unit(a)), _vec),
)


@st.composite
def apt_programs(draw: st.DrawFn) -> bytes:
    """An APT file of 1 to 40 generated records, some continued with '$'."""
    lines = ["SPINDL/RPM,10000", draw(_goto)]
    for rec in draw(st.lists(_record, min_size=1, max_size=40)):
        for part in rec.split("\n"):
            if "," in part and draw(st.integers(0, 9)) == 0:  # an APT continuation after a comma
                k = part.index(",") + 1
                part = part[:k] + "$\n " + part[k:]
            lines.append(part)
    return ("\n".join(lines) + "\n").encode()


def check_apt_program(path: Path) -> str:
    """'ok' (finite points, unit axes, rows and tool paths consistent) or 'InputError'."""
    from camsmooth.io.apt import read_apt

    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        try:
            prog = read_apt(path)
        except InputError:
            return "InputError"
    assert np.isfinite(prog.tip).all(), "non-finite tool tip"
    assert np.allclose(np.linalg.norm(prog.axis, axis=1), 1.0, atol=1e-9), "axis not unit"
    assert all(0 <= tp.start <= tp.stop <= len(prog) for tp in prog.toolpaths), "tool path out of range"
    assert all(a.stop <= b.start for a, b in zip(prog.toolpaths, prog.toolpaths[1:], strict=False)), "overlap"
    assert ((prog.rows >= 0) == ~prog.rapid).all(), "rows and rapids disagree"
    return "ok"


def read_or_input_error(reader: Callable[[Path], Any], path: Path) -> str:
    """'ok' or 'InputError'; any other exception propagates (that is a finding), and so does a
    floating-point RuntimeWarning (overflow, invalid value: the CLI would print it)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        try:
            reader(path)
        except InputError:
            return "InputError"
    return "ok"


def run(reader_name: str, examples: int, folder: Path, deadline_ms: float = 5000.0,
        rng_seed: int | None = None) -> Counter:
    """Fuzz one reader for ``examples`` examples; the outcomes counted ('ok', 'InputError')."""
    counts: Counter = Counter()
    if reader_name == "apt-gen":

        @settings(max_examples=examples, deadline=deadline_ms, database=None,
                  suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
        @given(data=apt_programs())
        def generated(data: bytes) -> None:
            path = folder / "fuzz_generated.apt"
            path.write_bytes(data)
            counts[check_apt_program(path)] += 1

        (seed(rng_seed)(generated) if rng_seed is not None else generated)()
        return counts
    readers = _readers()
    reader = readers[reader_name]
    seeds = seed_files(folder)[reader_name]

    @settings(max_examples=examples, deadline=deadline_ms, database=None,
              suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
    @given(which=st.integers(0, len(seeds) - 1), ops=mutations)
    def fuzz(which: int, ops: list) -> None:
        name, data = seeds[which]
        path = folder / f"fuzz_{reader_name}_{name}"
        path.write_bytes(mutate(data, ops))
        counts[read_or_input_error(reader, path)] += 1

    if rng_seed is not None:
        fuzz = seed(rng_seed)(fuzz)
    fuzz()
    return counts


def main(examples: int = 2000, rng_seed: int | None = None) -> None:
    print(f"fuzz_readers: {examples} examples per reader, deadline 5 s per example, "
          f"seed {'random' if rng_seed is None else rng_seed}")
    with tempfile.TemporaryDirectory() as d:
        for name in (*READERS, "apt-gen"):
            t0 = time.perf_counter()
            counts = run(name, examples, Path(d), rng_seed=rng_seed)
            n = sum(counts.values())
            what = "generated" if name == "apt-gen" else f"seeds {len(seed_files(Path(d))[name])}"
            print(f"  {name:8s} {n:6d} runs ({what}): {counts['ok']} read, "
                  f"{counts['InputError']} InputError, no other exception; {time.perf_counter() - t0:.1f} s")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 2000, int(sys.argv[2]) if len(sys.argv) > 2 else None)
