"""The README's STEP walkthrough inputs: the dome sample as a CAD part and its NX CLSF in a machine
coordinate system.

Writes into OUT (default ``walkthrough/``):

* ``dome_inch.step``: the dome of ``surfaces/dome.toml`` (z = 10 - 0.005 x^2 - 0.005 y^2 mm over
  [-30, 30]^2) as an exact biquadratic Bezier face (a quadratic height field is a degree-2 Bezier
  patch: control net x, y in {-30, 0, 30}, z = 10 + a X_i - b Y_j with X = (900, -900, 900)),
  written by OpenCASCADE in inch as a US supplier would send it;
* ``dome_mcs.cls``: ``surfaces/dome.cls`` with its points in a machine coordinate system whose
  origin is (100, 50, -20) mm in the part's frame, and the ``MSYS/`` record NX writes for it;
* ``dome_mcs_no_msys.cls``: the same points without the MSYS record (the trap: points in the
  MCS, part in the CAD frame).

Needs OpenCASCADE: ``pip install 'camsmooth[cad]'``. Run: ``python examples/dome_step.py [OUT]``.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MCS_ORIGIN = (100.0, 50.0, -20.0)  # mm, part frame


def dome_face(a: float = -0.005, b: float = 0.005, half: float = 30.0, z0: float = 10.0):
    """The saddle/dome z = z0 + a x^2 - b y^2 on [-half, half]^2 as an exact Bezier face (OCP)."""
    from OCP.BRepBuilderAPI import BRepBuilderAPI_MakeFace
    from OCP.Geom import Geom_BezierSurface
    from OCP.gp import gp_Pnt
    from OCP.OCP.collections import Array2_gp_Pnt

    xs = (-half, 0.0, half)
    sq = (half * half, -half * half, half * half)  # Bernstein coefficients of x^2 on [-half, half]
    net = Array2_gp_Pnt(1, 3, 1, 3)
    for i in range(3):
        for j in range(3):
            net.SetValue(i + 1, j + 1, gp_Pnt(xs[i], xs[j], z0 + a * sq[i] - b * sq[j]))
    return BRepBuilderAPI_MakeFace(Geom_BezierSurface(net), 1e-7).Face()


def write_step_inch(shape, path: Path) -> None:
    from OCP.Interface import Interface_Static
    from OCP.Message import Message, Message_Gravity
    from OCP.STEPControl import STEPControl_AsIs, STEPControl_Writer

    for printer in Message.DefaultMessenger_s().Printers():  # OpenCASCADE's transfer statistics: failures only
        printer.SetTraceLevel(Message_Gravity.Message_Fail)
    w = STEPControl_Writer()  # first: it sets the STEP parameters to their defaults
    Interface_Static.SetIVal_s("write.step.unit", 1)  # 1 = inch
    w.Transfer(shape, STEPControl_AsIs)
    w.Write(str(path))


def to_mcs(text: str, origin: tuple[float, float, float], msys: bool) -> str:
    """The CLSF with every GOTO's point moved into the MCS at ``origin`` (axes parallel)."""
    out = []
    for line in text.splitlines():
        m = re.match(r"GOTO/([^,]+),([^,]+),([^,]+)(.*)", line)
        if m:
            x, y, z = (float(m.group(k + 1)) - origin[k] for k in range(3))
            line = f"GOTO/{x:.4f},{y:.4f},{z:.4f}{m.group(4)}"
        out.append(line)
        if msys and line.startswith("TOOL PATH/"):
            out.append(f"MSYS/{origin[0]:.4f},{origin[1]:.4f},{origin[2]:.4f},1.0,0.0,0.0,0.0,1.0,0.0")
    return "\n".join(out) + "\n"


def main(out: str = "walkthrough") -> None:
    folder = Path(out)
    folder.mkdir(parents=True, exist_ok=True)
    write_step_inch(dome_face(), folder / "dome_inch.step")
    cls = (ROOT / "surfaces" / "dome.cls").read_text()
    (folder / "dome_mcs.cls").write_text(to_mcs(cls, MCS_ORIGIN, msys=True))
    (folder / "dome_mcs_no_msys.cls").write_text(to_mcs(cls, MCS_ORIGIN, msys=False))
    print(f"wrote {folder}/dome_inch.step, dome_mcs.cls, dome_mcs_no_msys.cls")


if __name__ == "__main__":
    main(*sys.argv[1:2])
