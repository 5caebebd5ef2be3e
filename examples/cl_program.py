"""From a CAM system's CL program to a smoothed one (issue 10), on the blade sample.

A CAM system exports the blade finishing pass as NX CLSF (APT CLDATA): tool tip and tool axis per
point, a constant 11 deg lead and 0 deg tilt as CAM "lead/tilt" axis control gives, a TLDATA
record for the D10 R1 toroidal cutter, a feed, and rapids between rows. This script writes that
file, then runs what a user would:

    camsmooth analyze blade_finish.cls --surface surfaces/blade.ply --json analysis.json
    camsmooth smooth blade_finish.cls --surface surfaces/blade.ply --lead 2:20 --tilt -15:15 \\
        -o blade_smoothed.csv --gcode blade_smoothed.nc --report report

(the cutter comes from the file's TLDATA) and prints the comparison: the CAM's own program ('cam')
against none, spline and nlp, as the report shows it.

    python examples/cl_program.py [OUT_DIR]      (default: examples_out/cl_program)
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camsmooth.cli.main import main  # noqa: E402
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl  # noqa: E402
from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames  # noqa: E402
from camsmooth.io.ccpath import read_cc_csv  # noqa: E402
from camsmooth.io.result_csv import read_result_csv  # noqa: E402


def write_clsf(path: Path, lead_deg: float = 11.0, tilt_deg: float = 0.0) -> int:
    """The blade's CC path as the CL program a CAM system would write (module docstring)."""
    cc = read_cc_csv(ROOT / "surfaces" / "blade_path.csv")
    cutter = ToroidalCutter(R=4.0, r=1.0)
    fr = local_frames(cc.normals, cc.feed_dirs)
    T = axis_from_lead_tilt(np.full(len(fr), np.radians(lead_deg)), np.full(len(fr), np.radians(tilt_deg)), fr)
    tip = cc_to_cl(cutter, cc.points, cc.normals, T)
    lines = ["TOOL PATH/BLADE_FINISH,TOOL,MILL_D10R1", "TLDATA/MILL,10.0000,1.0000,60.0000,0.0000,0.0000",
             "LOAD/TOOL,1", "$$ the blade sample's finishing pass, lead 11 deg, tilt 0 deg", "FEDRAT/MMPM,2000.0000"]
    for s in cc.row_slices():
        p, a = tip[s], T[s]
        up = p[0] + 10.0 * a[0]
        lines += ["RAPID", f"GOTO/{up[0]:.4f},{up[1]:.4f},{up[2]:.4f},{a[0, 0]:.7f},{a[0, 1]:.7f},{a[0, 2]:.7f}"]
        lines += [f"GOTO/{q[0]:.4f},{q[1]:.4f},{q[2]:.4f},{t[0]:.7f},{t[1]:.7f},{t[2]:.7f}" for q, t in zip(p, a,
                                                                                                         strict=True)]
        away = p[-1] + 10.0 * a[-1]
        lines += ["RAPID", f"GOTO/{away[0]:.4f},{away[1]:.4f},{away[2]:.4f}"]
    lines.append("END-OF-PATH")
    path.write_text("\n".join(lines) + "\n")
    return len(cc.points)


def run(out: Path) -> int:
    out.mkdir(parents=True, exist_ok=True)
    cls = out / "blade_finish.cls"
    n = write_clsf(cls)
    print(f"wrote {cls}: {n} CL points (NX CLSF), as a CAM system would")
    mesh = str(ROOT / "surfaces" / "blade.ply")
    rc = main(["analyze", str(cls), "--surface", mesh, "--json", str(out / "analysis.json")])
    if rc:
        return rc
    rc = main(["smooth", str(cls), "--surface", mesh, "--lead", "2:20", "--tilt", "-15:15", "-o",
               str(out / "blade_smoothed.csv"), "--gcode", str(out / "blade_smoothed.nc"), "--report",
               str(out / "report")])
    if rc:
        return rc
    res = read_result_csv(out / "blade_smoothed.csv")
    print(f"wrote {out / 'blade_smoothed.csv'} ({len(res['x'])} points), {out / 'blade_smoothed.nc'} and "
          f"{out / 'report' / 'report.html'} (cam, none, spline and nlp compared)")
    return 0


if __name__ == "__main__":
    sys.exit(run(Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "examples_out" / "cl_program"))
