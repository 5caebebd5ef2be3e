"""Programs on the real controller: camsmooth's G-code run by a headless LinuxCNC simulation.

For each sample and method: smooth a few rows (the simulation runs in real time), write the
LinuxCNC program (machine mode, G93, the blocks of camsmooth.controller.blocks), run it on
LinuxCNC (camsmooth.controller.linuxcnc_sim.simulate: trivkins with the machine's axes, XYZAB on
the AB head, XYZAC on the dome's A/C trunnion; the machine file's limits, 1 ms servo period) and
print per row: the executed cut time (first to last servo sample of the row's cut blocks),
camsmooth's prediction (camsmooth.controller.linuxcnc, the controller's t_plan), the
time-optimal law (t_opt), and the tool tip's largest distance, over every servo sample of the
row, from the path the method commands (the tips of the full-density program, each block's tip
curve sampled at 16 steps), by the machine's forward kinematics of the recorded joints
(LinuxCNC's sense of a table axis undone; the programmed path includes the entry feed move onto
the row, which LinuxCNC blends into the row's first block), beside the same distance for the
tip camsmooth's model commands ("model um"); and the lower bound of
camsmooth.controller.linuxcnc.least_row_times over the time-optimal law ("bound/opt"): no
program of straight blocks through the row's points runs faster on LinuxCNC 2.9 within the
tolerance (the floor; "exec/floor" is the executed time over it). camsmooth's blocks end off the
points, inside the tolerance (camsmooth.controller.vertex_shift, "off um" the farthest block end's
tip): "exec/own" is the executed time over the floor for block ends that far off the points, the
one ``smooth`` prints beside the prediction.

    .venv/bin/python benchmarks/bench_controller.py [--samples blade,wave] [--rows 3] [--methods none,spline,nlp]
    .venv/bin/python benchmarks/bench_controller.py --sample dome    (the A/C trunnion of surfaces/dome_machine.toml)
    .venv/bin/python benchmarks/bench_controller.py --sample dome --machine surfaces/nutating_machine.toml
    .venv/bin/python benchmarks/bench_controller.py --mode tcp --samples dome,wave --rows 3

``--mode tcp``: on table machines LinuxCNC's trt kinematics describes (the dome's A/C trunnion; the
other samples on a B/C trunnion with the dome machine's limits), the nlp program written and run in
both LinuxCNC modes: TCP (``M428``, camsmooth.controller.tcp: its blocks, F words held so that the
joints stay within their limits, run on the simulation's xyzac-trt / xyzbc-trt switchkins
kinematics) and machine mode (G93, trivkins); per row executed / predicted / floor, the F factor
the TCP row was held down by, the tip's largest distance and the linear joints' peaks.

A sample with a machine file beside it (``surfaces/<sample>_machine.toml``) runs on that machine
(its post set to linuxcnc, machine mode); the others on the default AB head.

Needs linuxcnc-uspace (apt-get install linuxcnc-uspace); run as root it creates an unprivileged
user for the simulation.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM  # noqa: E402
from camsmooth.controller.blocks import tip_deviation  # noqa: E402
from camsmooth.controller.linuxcnc import least_row_times  # noqa: E402
from camsmooth.controller.linuxcnc_sim import (  # noqa: E402
    camsmooth_joints,
    linuxcnc_missing,
    row_runs,
    row_samples,
    simulate,
    trt_missing,
)
from camsmooth.controller.tcp import TCPPlanner  # noqa: E402
from camsmooth.geometry.clearance import MeshIndex  # noqa: E402
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl  # noqa: E402
from camsmooth.geometry.frames import axis_from_lead_tilt, local_frames  # noqa: E402
from camsmooth.geometry.paths import CCPath, zigzag_path  # noqa: E402
from camsmooth.geometry.surfaces import load_surface  # noqa: E402
from camsmooth.io.ccpath import read_cc_csv  # noqa: E402
from camsmooth.machine.kinematics import (  # noqa: E402
    DEFAULT_MACHINE_TOML,
    PostConfig,
    load_machine,
    machine_from_dict,
    preset_machine,
)
from camsmooth.post import load_program  # noqa: E402
from camsmooth.smoothing.cam import cam_program  # noqa: E402
from camsmooth.smoothing.evaluate import time_law  # noqa: E402
from camsmooth.smoothing.pipeline import SmoothOptions, smooth  # noqa: E402
from camsmooth.smoothing.posting import write_gcode  # noqa: E402

TOLERANCE = 0.005


def linuxcnc_machine(sample: str | None = None, machine_file: Path | None = None, mode: str = "machine"):
    """``machine_file`` when given, else the sample's own machine (``surfaces/<sample>_machine.toml``)
    when it has one, else the default AB head; the post LinuxCNC's, in ``mode``."""
    import tomllib

    own = machine_file or ROOT / "surfaces" / f"{sample}_machine.toml"
    if (sample is not None or machine_file is not None) and own.is_file():
        return dataclasses.replace(load_machine(str(own)), post=PostConfig(dialect="linuxcnc", mode=mode))
    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["post"] = {"dialect": "linuxcnc", "mode": mode}
    return machine_from_dict(data, "<bench machine>")


def bc_table_machine(mode: str = "tcp"):
    """A B/C trunnion (B about +Y tilting, C about +Z; LinuxCNC's xyzbc-trt) with the dome machine's
    limits (B those of its A) and table centre, the post LinuxCNC's in ``mode``."""
    dome = load_machine(str(ROOT / "surfaces" / "dome_machine.toml"))
    lim = dict(dome.limits)
    lim["B"] = lim.pop("A")
    return preset_machine("BC-table", centre=dome.table_centre, name="B/C trunnion (the dome machine's limits)",
                          limits=lim, post=PostConfig(dialect="linuxcnc", mode=mode))


def cam_clsf(path: CCPath, cutter: ToroidalCutter, lead_deg: float = 11.0) -> str:
    """NX CLSF text of the CC rows with a constant lead and no tilt, as CAM lead/tilt axis
    control writes them: tool tips and axes, rapids between rows, the tool's TLDATA."""
    fr = local_frames(path.normals, path.feed_dirs_or_estimate())
    T = axis_from_lead_tilt(np.full(len(fr), np.radians(lead_deg)), np.zeros(len(fr)), fr)
    tip = cc_to_cl(cutter, path.points, path.normals, T)
    d, r = 2 * (cutter.R + cutter.r), cutter.r
    lines = ["TOOL PATH/FINISH,TOOL,MILL", f"TLDATA/MILL,{d:.4f},{r:.4f},60.0000,0.0000,0.0000", "LOAD/TOOL,1",
             "FEDRAT/MMPM,2000.0000"]
    for sl in path.row_slices():
        p, a = tip[sl], T[sl]
        up = p[0] + 10.0 * a[0]
        lines += ["RAPID", f"GOTO/{up[0]:.4f},{up[1]:.4f},{up[2]:.4f},{a[0, 0]:.7f},{a[0, 1]:.7f},{a[0, 2]:.7f}"]
        lines += [f"GOTO/{x[0]:.4f},{x[1]:.4f},{x[2]:.4f},{t[0]:.7f},{t[1]:.7f},{t[2]:.7f}"
                  for x, t in zip(p, a, strict=True)]
        away = p[-1] + 10.0 * a[-1]
        lines += ["RAPID", f"GOTO/{away[0]:.4f},{away[1]:.4f},{away[2]:.4f}"]
    return "\n".join(lines + ["END-OF-PATH"]) + "\n"


def smoothed(sample: str, rows: int, methods: list[str], machine_file: Path | None = None, machine=None,
             hold_feed: bool = False):
    """(machine, cutter, SmoothResult) of ``rows`` rows from the middle of the sample's path,
    smoothed for LinuxCNC (``machine``, default ``linuxcnc_machine``) at 2000 mm/min and TOLERANCE
    (``hold_feed``: SmoothOptions.hold_feed)."""
    machine = machine or linuxcnc_machine(sample, machine_file)
    shipped = ROOT / "surfaces" / f"{sample}.toml"
    if shipped.exists():
        surf = load_surface(shipped)
        path = read_cc_csv(ROOT / "surfaces" / f"{sample}_path.csv")
    else:  # a surface of benchmarks/data (not a shipped sample): a zig-zag path on it
        surf = load_surface(ROOT / "benchmarks" / "data" / f"{sample}.toml")
        path = zigzag_path(surf.parametric, stepover=2.0, spacing=0.4, feed=2000.0)
    ids = np.unique(path.rows)
    mid = ids[len(ids) // 2 - rows // 2: len(ids) // 2 - rows // 2 + rows]  # rows from the middle
    k = np.isin(path.rows, mid)
    path = CCPath(points=path.points[k], normals=path.normals[k], rows=path.rows[k],
                  feed_dirs=None if path.feed_dirs is None else path.feed_dirs[k],
                  feed=None if path.feed is None else path.feed[k], source=path.source)
    cutter = ToroidalCutter(R=4.0, r=1.0)
    program = path
    if "cam" in methods:  # the rows as a CAM system writes them (constant lead 11 deg), read back
        with tempfile.TemporaryDirectory() as tmp:
            cls = Path(tmp) / f"{sample}.cls"
            cls.write_text(cam_clsf(path, cutter))
            program = cam_program(load_program(cls), MeshIndex(surf.mesh), cutter, TOLERANCE)
    res = smooth(program, surf, machine, cutter, feed=2000.0,
                 lead_range=tuple(np.radians([2.0, 20.0])), tilt_range=tuple(np.radians([-15.0, 15.0])),
                 method="nlp", tolerance=TOLERANCE, options=SmoothOptions(hold_feed=hold_feed))
    return machine, cutter, res


def run(sample: str, rows: int, methods: list[str], keep: Path | None, machine_file: Path | None = None,
        hold_feed: bool = False) -> list[dict]:
    machine, cutter, res = smoothed(sample, rows, methods, machine_file, hold_feed=hold_feed)
    out = []
    for m in methods:
        r = res.methods[m]
        q = np.column_stack([r.xyz, r.rotary.values])
        bound = dict(zip(r.controller.row_ids, least_row_times(machine, r.rows, q, r.cl, np.full(len(q), 2000.0),
                                                               TOLERANCE), strict=True))
        model_dev = dict(zip(r.controller.row_ids, r.controller.row_deviation, strict=True))
        with tempfile.TemporaryDirectory() as tmp:
            ngc = Path(tmp) / f"{sample}_{m}.ngc"
            write_gcode(ngc, r, machine, cutter, 2000.0, tolerance=TOLERANCE)
            t0 = time.time()
            sim = simulate(ngc, machine, keep=(keep / f"{sample}_{m}") if keep else None)
            wall = time.time() - t0
            text = ngc.read_text()
        joints = camsmooth_joints(machine, sim.joints)
        tips = machine.tool_pose_np(joints[:, 3], joints[:, 4], joints[:, 0], joints[:, 1], joints[:, 2])[0]
        speed = np.r_[0.0, np.linalg.norm(np.diff(tips, axis=0), axis=1)] * 60.0 / sim.servo_period / 2000.0
        cut = row_samples(text, sim)
        fpk = r.controller.row_feed_peak
        for x in row_runs(machine, r, text, sim):
            sel = r.rows == x.row
            j = list(r.controller.row_ids).index(x.row)
            out.append(dict(sample=sample, method=m, row=x.row, executed=x.executed, predicted=x.predicted,
                            optimal=x.optimal, bound=float(bound[x.row]), deviation_um=1e3 * x.deviation,
                            model_deviation_um=1e3 * float(model_dev[x.row]),
                            own=float(r.controller.row_floor[j]), offset_um=1e3 * r.controller.end_offset,
                            blocks=int(r.controller.keep[sel].sum() - 1), points=int(sel.sum()), wall=wall,
                            tip_feed=float(speed[cut[x.row]].max()),
                            # the model's ratio where past the feed, 0 where within (nan: no feed given)
                            model_tip_feed=float(fpk[j]) if fpk is not None else float("nan")))
    return out


def _joint_peaks(machine, joints: np.ndarray, k: np.ndarray, dt: float) -> tuple[float, float, float, float]:
    """The largest |velocity| / vmax and |acceleration| / amax of the linear joints X Y Z (the ones
    LinuxCNC does not limit in TCP mode), then of the rotary joints, over the servo samples k and
    two either side (finite differences over one sample); joints (K, 5) mm, rad."""
    from camsmooth.machine.kinematics import axis_limits

    vmax, amax, _ = axis_limits(machine)
    q = joints[max(k[0] - 2, 0):k[-1] + 3]
    v = np.abs(np.diff(q, axis=0)).max(axis=0) / dt / vmax
    a = np.abs(np.diff(q, 2, axis=0)).max(axis=0) / dt ** 2 / amax
    return float(v[:3].max()), float(a[:3].max()), float(v[3:].max()), float(a[3:].max())


def run_modes(sample: str, rows: int, keep: Path | None, machine) -> list[dict]:
    """The nlp program of ``sample`` on a table machine LinuxCNC's trt kinematics describes, written
    and run in both modes: TCP (``M428``; the blocks and held F words of camsmooth.controller.tcp,
    on the simulation's trt switchkins kinematics, linuxcnc_sim.trt_config) and machine mode (G93,
    trivkins). Per row and mode: executed, predicted and floor (s: the plan's own, for block ends as
    far off the points as its program's; "pts": the mode's floor through the points themselves,
    least_row_times and TCPPlanner.row_floor), the tip's largest distance (um)
    from the programmed path (TCP: the tips' polyline; machine: the joints' tip curves), the linear
    joints' largest velocity and acceleration over their limits."""
    tcp_machine = dataclasses.replace(machine, post=PostConfig(dialect="linuxcnc", mode="tcp"))
    _, cutter, res = smoothed(sample, rows, ["nlp"], machine=tcp_machine)
    r = res.methods["nlp"]
    mm = dataclasses.replace(machine, post=PostConfig(dialect="linuxcnc", mode="machine"))
    q = np.column_stack([r.xyz, r.rotary.values])
    law = time_law(mm, r.rows, q, r.cl, np.full(len(q), 2000.0), tolerance=TOLERANCE, plan=r.plan)
    out = []
    feed = np.full(len(q), 2000.0)
    through = {"tcp": TCPPlanner().row_floor(tcp_machine, r.rows, q, r.cl, feed, TOLERANCE),
               "machine": least_row_times(mm, r.rows, q, r.cl, feed, TOLERANCE)}
    for mode, m, plan in (("tcp", tcp_machine, r.controller), ("machine", mm, law.controller)):
        rr = dataclasses.replace(r, controller=plan)
        with tempfile.TemporaryDirectory() as tmp:
            ngc = Path(tmp) / f"{sample}_{mode}.ngc"
            write_gcode(ngc, rr, m, cutter, 2000.0, tolerance=TOLERANCE)
            sim = simulate(ngc, m, trt=mode == "tcp", keep=(keep / f"{sample}_{mode}") if keep else None, timeout=300)
            text = ngc.read_text()
        joints = camsmooth_joints(m, sim.joints)
        tips = m.tool_pose_np(joints[:, 3], joints[:, 4], joints[:, 0], joints[:, 1], joints[:, 2])[0]
        dev = {x.row: x.deviation for x in row_runs(m, rr, text, sim)}
        for row, k in row_samples(text, sim).items():
            j = list(plan.row_ids).index(row)
            sel = np.flatnonzero(r.rows == row)
            if mode == "tcp":
                path = np.vstack([r.cl[sel[0]] + DEFAULT_SAFE_HEIGHT_MM * r.axis[sel[0]], r.cl[sel]])
                dev[row] = float(tip_deviation(tips[k[0]:k[-1] + 1], path).max())
            v, a, v_rot, a_rot = _joint_peaks(m, joints, k, sim.servo_period)
            out.append(dict(sample=sample, machine=m.name, mode=mode, row=int(row),
                            executed=float((k[-1] - k[0] + 1) * sim.servo_period),
                            predicted=float(plan.row_cycle_time[j]), floor=float(plan.row_floor[j]),
                            points_floor=float(through[mode][j]),
                            blocks=int(plan.keep[sel].sum() - 1), deviation_um=1e3 * dev[row], v=v, a=a,
                            v_rot=v_rot, a_rot=a_rot,
                            scale=float(getattr(plan, "row_feed_scale", np.ones(len(plan.row_ids)))[j])))
    return out


def main_modes(args: argparse.Namespace) -> None:
    """``--mode tcp``: both modes per row (``run_modes``) for each sample: the dome on its own A/C
    trunnion, the other samples on ``bc_table_machine``."""
    print(f"LinuxCNC simulation, tolerance {TOLERANCE} mm, servo period 1 ms; TCP mode on the trt switchkins "
          "kinematics (M428), machine mode on trivkins; the joints' peaks over their limits at 1 ms (v, a: "
          "linear joints; rot: rotary)")
    print(f"{'sample':7s} {'mode':8s} {'row':>4s} {'blocks':>6s} {'executed s':>10s} {'predicted s':>11s} "
          f"{'pred/exec-1':>11s} {'floor s':>8s} {'exec/floor':>10s} {'exec/pts':>8s} {'F scale':>7s} {'tip um':>7s} "
          f"{'v/vmax':>7s} {'a/amax':>7s} {'rot v':>6s} {'rot a':>6s}")
    totals: dict[tuple[str, str], list[float]] = {}
    for sample in args.samples.split(","):
        machine = linuxcnc_machine(sample, args.machine) if sample == "dome" or args.machine else bc_table_machine()
        missing = trt_missing(machine)
        if missing:
            print(f"{sample}: {missing}")
            continue
        print(f"# {sample} on {machine.name}")
        for x in run_modes(sample, args.rows, args.keep, machine):
            print(f"{x['sample']:7s} {x['mode']:8s} {x['row']:4d} {x['blocks']:6d} {x['executed']:10.3f} "
                  f"{x['predicted']:11.3f} {x['predicted'] / x['executed'] - 1:+11.2%} {x['floor']:8.3f} "
                  f"{x['executed'] / x['floor']:10.3f} {x['executed'] / x['points_floor']:8.3f} {x['scale']:7.3f} "
                  f"{x['deviation_um']:7.2f} {x['v']:7.2f} "
                  f"{x['a']:7.2f} {x['v_rot']:6.3f} {x['a_rot']:6.3f}")
            t = totals.setdefault((x["sample"], x["mode"]), [0.0, 0.0, 0.0])
            t[0] += x["executed"]
            t[1] += x["predicted"]
            t[2] += x["floor"]
    print("\ntotals over the rows")
    for (sample, mode), (ex, pr, fl) in totals.items():
        print(f"{sample:7s} {mode:8s} executed {ex:8.3f} s  predicted {pr:8.3f} s ({pr / ex - 1:+.2%})  "
              f"floor {fl:8.3f} s")
    for sample in {s for s, _ in totals}:
        if (sample, "tcp") in totals and (sample, "machine") in totals:
            tcp, mach = totals[(sample, "tcp")][0], totals[(sample, "machine")][0]
            faster = "TCP mode" if tcp < mach else "machine mode"
            print(f"{sample}: executed TCP {tcp:.3f} s, machine {mach:.3f} s: {faster} "
                  f"{100 * (max(tcp, mach) / min(tcp, mach) - 1):.1f}% faster")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", "--sample", default="blade,wave,ridge",
                    help="comma-separated samples in surfaces/ or surface definitions in benchmarks/data/")
    ap.add_argument("--rows", type=int, default=3, help="rows per sample (from the middle of the path)")
    ap.add_argument("--methods", default="cam,none,spline,nlp",
                    help="comma-separated methods (cam: the rows as a CL program with a constant 11 deg lead)")
    ap.add_argument("--keep", type=Path, default=None, help="folder to keep the simulations' files in")
    ap.add_argument("--machine", type=Path, default=None,
                    help="run every sample on this machine file (e.g. surfaces/nutating_machine.toml)")
    ap.add_argument("--hold-feed", action="store_true",
                    help="smooth with SmoothOptions.hold_feed (machine mode): the tool tip held within the feed")
    ap.add_argument("--mode", choices=("machine", "tcp"), default="machine",
                    help="tcp: TCP mode beside machine mode per row (the dome on its A/C trunnion, the other samples "
                         "on a B/C trunnion with the dome's limits; nlp only)")
    args = ap.parse_args()
    missing = linuxcnc_missing()
    if missing:
        sys.exit(f"bench_controller: {missing}")
    if args.mode == "tcp":
        main_modes(args)
        return
    print(f"LinuxCNC simulation, tolerance {TOLERANCE} mm, servo period 1 ms")
    print(f"{'sample':8s} {'method':7s} {'row':>4s} {'points':>6s} {'blocks':>6s} {'executed s':>10s} "
          f"{'predicted s':>11s} {'pred/exec-1':>11s} {'optimal s':>9s} {'exec/opt':>8s} {'bound/opt':>9s} "
          f"{'exec/floor':>10s} {'exec/own':>8s} {'off um':>6s} {'tip dev um':>10s} {'model um':>8s} {'tip/F':>6s} "
          f"{'model':>6s}")
    totals: dict[tuple[str, str], list[float]] = {}
    for sample in args.samples.split(","):
        for row in run(sample, args.rows, args.methods.split(","), args.keep, args.machine, args.hold_feed):
            print(f"{row['sample']:8s} {row['method']:7s} {row['row']:4d} {row['points']:6d} {row['blocks']:6d} "
                  f"{row['executed']:10.3f} {row['predicted']:11.3f} {row['predicted'] / row['executed'] - 1:+11.2%} "
                  f"{row['optimal']:9.3f} {row['executed'] / row['optimal']:8.2f} {row['bound'] / row['optimal']:9.2f} "
                  f"{row['executed'] / row['bound']:10.3f} {row['executed'] / row['own']:8.3f} {row['offset_um']:6.2f} "
                  f"{row['deviation_um']:10.2f} "
                  f"{row['model_deviation_um']:8.2f} {row['tip_feed']:6.2f} {row['model_tip_feed']:6.2f}")
            t = totals.setdefault((row["sample"], row["method"]), [0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
            t[0] += row["executed"]
            t[1] += row["predicted"]
            t[2] += row["optimal"]
            t[3] += row["bound"]
            t[4] = max(t[4], row["deviation_um"])
            t[5] += row["own"]
    print("\ntotals over the rows (bound: the least time any program of straight blocks through the points can "
          "take on LinuxCNC 2.9 within the tolerance, controller.linuxcnc.least_row_times)")
    for (sample, m), (ex, pr, op, lb, dev, own) in totals.items():
        print(f"{sample:8s} {m:7s} executed {ex:8.3f} s  predicted {pr:8.3f} s ({pr / ex - 1:+.2%})  "
              f"optimal {op:8.3f} s  executed/optimal {ex / op:.2f}  bound/optimal {lb / op:.2f}  "
              f"executed/floor {ex / lb:.3f}  predicted/floor {pr / lb:.3f}  executed/own floor {ex / own:.3f}  "
              f"largest tip deviation {dev:.2f} um (tolerance {1e3 * TOLERANCE:g} um)")


if __name__ == "__main__":
    main()
