"""LinuxCNC as the reference controller: its interpreter (``rs274``) and a headless simulation.

Two tools for tests and benchmarks, both optional (they need the Debian package
``linuxcnc-uspace``; ``linuxcnc_missing()`` says what is missing):

- ``interpret(program)``: LinuxCNC's stand-alone RS274NGC interpreter reads a program and returns
  its canonical motion calls (STRAIGHT_FEED / STRAIGHT_TRAVERSE with X Y Z A B, the inverse-time
  feed of each block, the auxiliary outputs the switchkins M-codes set), so the positions and
  block times of a written program can be compared with what camsmooth planned.
- ``simulate(program, machine)``: a headless LinuxCNC (trivkins with the machine's axes,
  ``coordinates=XYZAB`` on the AB head, ``XYZAC`` on an A/C table, ``XYZBC`` on a B/C machine: a
  machine-mode program's joints; the machine file's axis limits in LinuxCNC's sense, a 1 ms servo
  period, the motion-controller's position commands looped back)
  runs the program; the ``sampler`` HAL component records the commanded joint positions and the
  program line at every servo cycle. ``rtapi_app`` refuses to run as root, so the simulation runs
  as an unprivileged user (``LINUXCNC_USER``, created when missing and we are root). The
  simulation runs in real time: keep programs short.

One LinuxCNC per machine is what LinuxCNC expects: its start script treats ``/tmp/linuxcnc.lock``
as "LinuxCNC is still running" and, without a terminal, cleans the other instance up (kills its
``milltask`` and ``linuxcncsvr`` by name, unloads its HAL); HAL and RTAPI share SysV memory under
fixed keys, the NML buffers too, ``linuxcncsvr`` listens on TCP port 5005 and ``rtapi_app`` on a
socket in $HOME. So each run gets its own instance of all of these (``isolation_missing``): new
IPC, PID, mount and network namespaces (``unshare``, as root) with a private /tmp and /dev/shm,
and $HOME in the run's folder. Where that is not possible, a run waits (bounded) until no other
LinuxCNC holds /tmp/linuxcnc.lock rather than clean it up. Either way camsmooth's own runs on a
machine take turns (an ``flock`` on ``RUN_LOCK``, bounded wait), so two test sessions on two
cores do not share them. A failed run's RuntimeError carries LinuxCNC's own output and logs.

The configuration follows LinuxCNC's sample configurations (``core_sim.hal``); a ``[DISPLAY]``
program in Python resets the e-stop, switches the machine on, homes (immediate homing: no
search), runs the program in auto mode and waits for it.
"""

from __future__ import annotations

import contextlib
import fcntl
import functools
import os
import pwd
import re
import shutil
import subprocess
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.controller.blocks import programmed_tip_path, tip_deviation
from camsmooth.controller.linuxcnc import linuxcnc_sense
from camsmooth.controller.tcp import trt_kinematics
from camsmooth.machine.kinematics import Machine

__all__ = ["linuxcnc_missing", "isolation_missing", "interpret", "Canon", "simulate", "SimRun", "LINUXCNC_USER",
           "ISOLATED_USER", "row_samples", "camsmooth_joints", "RUN_LOCK", "LINUXCNC_LOCK", "TRT_CONFIGS",
           "trt_missing", "trt_config"]

#: the unprivileged user the simulation runs as when we are root
LINUXCNC_USER = "camsmooth-lcnc"
#: the user an isolated simulation runs as: one no other LinuxCNC runs as, so that another
#: instance's clean-up (``kill`` of every ``milltask`` and ``linuxcncsvr`` it sees) cannot end it
ISOLATED_USER = "camsmooth-lcnc-ns"
#: the servo period of the simulated machine (s), LinuxCNC's usual 1 ms
SERVO_PERIOD_S = 0.001
#: LinuxCNC's own "an instance is up" lock (its start script, scripts/linuxcnc)
LINUXCNC_LOCK = Path("/tmp/linuxcnc.lock")
#: camsmooth's simulations on this machine take turns on this file (fcntl.flock)
RUN_LOCK = Path("/tmp/camsmooth-linuxcnc-sim.lock")
#: characters of the end of LinuxCNC's output and of each of its logs a failure message carries
MESSAGE_CHARS = 600
#: LinuxCNC's sample configurations of table-rotary-tilting machines (``xyzac-trt.ini``,
#: ``xyzbc-trt.ini``, their ``M428`` / ``M429`` remap subroutines), as the Debian package installs them
TRT_CONFIGS = Path("/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/5axis/table-rotary-tilting")


def linuxcnc_missing() -> str | None:
    """None when ``rs274``, ``linuxcnc`` and ``halsampler`` are on the PATH, else what is missing
    (with the install command)."""
    missing = [p for p in ("rs274", "linuxcnc", "halsampler") if shutil.which(p) is None]
    if missing:
        return f"{', '.join(missing)} not found: apt-get install linuxcnc-uspace"
    return None


def trt_missing(machine: Machine) -> str | None:
    """None when ``simulate(..., trt=True)`` can run ``machine``: LinuxCNC is installed, its sample
    trt configuration for the machine is (TRT_CONFIGS) and LinuxCNC's trt kinematics describes the
    machine (camsmooth.controller.tcp.trt_kinematics); else what is missing."""
    kins = trt_kinematics(machine)
    if kins is None:
        return f"LinuxCNC's trt kinematics does not describe {machine.describe()}"
    ini = TRT_CONFIGS / f"{kins.removesuffix('-kins')}.ini"
    return linuxcnc_missing() or (None if ini.is_file() else f"{ini} missing (LinuxCNC's sample configurations)")


def trt_config(machine: Machine) -> dict[str, str]:
    """``simulate`` keywords (kins, rs274ngc, hal) for LinuxCNC's trt switchkins kinematics of an
    A/C or B/C table (``xyzac-trt-kins`` / ``xyzbc-trt-kins``), configured as its sample
    configuration does: ``sparm=identityfirst`` (type 0 identity, machine mode, at start), the
    shipped ``M428`` / ``M429`` remaps (``HAL_PIN_VARS = 1``, the subroutines of TRT_CONFIGS),
    ``motion.analog-out-03`` netted to ``motion.switchkins-type``; the rotation point at the
    machine file's table centre, no offsets between the axes nor a tool offset."""
    missing = trt_missing(machine)
    if missing:
        raise RuntimeError(missing)
    kins = str(trt_kinematics(machine))
    cx, cy, cz = machine.table_centre
    hal = _HAL + "net kinstype motion.analog-out-03 => motion.switchkins-type\n" + "".join(
        f"setp {kins}.{pin} {value}\n" for pin, value in (("x-rot-point", cx), ("y-rot-point", cy), ("z-rot-point", cz),
                                                          ("x-offset", 0), ("y-offset", 0), ("z-offset", 0),
                                                          ("tool-offset", 0)))
    ini = TRT_CONFIGS / f"{kins.removesuffix('-kins')}.ini"
    remaps = [ln.strip() for ln in ini.read_text().splitlines()
              if ln.strip().startswith("REMAP") and ("M428" in ln or "M429" in ln)]
    rs274 = f"SUBROUTINE_PATH = {TRT_CONFIGS / 'remap_subs'}\nHAL_PIN_VARS = 1\n" + "".join(f"{r}\n" for r in remaps)
    return dict(kins=f"{kins} sparm=identityfirst", rs274ngc=rs274, hal=hal)


# ----------------------------------------------------------------------------------------------
# the interpreter
@dataclass(frozen=True, kw_only=True)
class Canon:
    """The canonical motion of a program as LinuxCNC's interpreter emits it.

    joints: (M, 5) X Y Z (mm) A B (deg) at the end of each motion call; positions: (M, 6) X Y Z
    (mm) A B C (deg), all of the interpreter's axes (``axes`` picks a machine's); rapid: (M,) bool;
    feed: (M,) the feed rate in force (SET_FEED_RATE; in inverse-time mode LinuxCNC reports the
    block's F as given); inverse_time: (M,) bool, G93 in force; aux: list of (call index, output
    index, value) from SET_AUX_OUTPUT_VALUE (M68), in program order (call index = number of motion
    calls before it); comments: the program's comments in order.
    """

    joints: np.ndarray
    rapid: np.ndarray
    feed: np.ndarray
    inverse_time: np.ndarray
    aux: list[tuple[int, int, float]]
    comments: list[str]
    positions: np.ndarray | None = None

    def axes(self, names: str | tuple[str, ...]) -> np.ndarray:
        """(M, len(names)) the positions of the named axes (letters of X Y Z A B C), e.g.
        ``machine.joint_names``: X Y Z mm and the rotary axes in degrees, as the program gives them."""
        pos = self.positions
        if pos is None:
            pos = np.column_stack([self.joints, np.zeros(len(self.joints))])
        return pos[:, ["XYZABC".index(n) for n in names]]


_NUM = r"([-+]?\d+(?:\.\d*)?(?:[eE][-+]?\d+)?)"


def interpret(program: Path | str, *, ini: Path | str | None = None, workdir: Path | str | None = None,
              tool_table: str = "T1 P1 Z0 D10 ;\n") -> Canon:
    """Run LinuxCNC's ``rs274`` on ``program`` (with ``ini``'s remaps when given) and parse its
    canonical calls. RuntimeError with the interpreter's message when it stops on an error."""
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        tbl = Path(tmp) / "tool.tbl"
        tbl.write_text(tool_table)
        out = Path(tmp) / "canon.txt"
        cmd = ["rs274"]
        if ini is not None:
            cmd += ["-i", str(ini)]
        cmd += ["-t", str(tbl), "-g", str(program), str(out)]
        proc = subprocess.run(cmd, capture_output=True, text=True, stdin=subprocess.DEVNULL,
                              cwd=Path(ini).parent if ini else tmp, timeout=600)
        text = out.read_text() if out.exists() else ""
        errors = [ln for ln in (proc.stdout + proc.stderr).splitlines()
                  if ln.strip() and ln.strip() not in ("executing",) and "interp_init" not in ln]
        if proc.returncode != 0 or any("error" in ln.lower() for ln in errors):
            raise RuntimeError(f"rs274 failed on {program}: {' | '.join(errors) or proc.returncode}")
    return parse_canon(text)


def parse_canon(text: str) -> Canon:
    """Parse the canonical-call text ``rs274 -g`` writes (trivkins order X Y Z A B C; one call
    per line)."""
    joints, rapid, feed, inv, aux, comments = [], [], [], [], [], []
    f_now, inverse = float("nan"), False
    for ln in text.splitlines():
        m = re.search(r"N\.+\s+(\w+)\((.*)\)\s*$", ln)
        if not m:
            continue
        name, args = m.group(1), m.group(2)
        if name in ("STRAIGHT_FEED", "STRAIGHT_TRAVERSE"):
            v = [float(x) for x in re.findall(_NUM, args)]
            joints.append((v + [0.0] * 6)[:6])
            rapid.append(name == "STRAIGHT_TRAVERSE")
            feed.append(f_now)
            inv.append(inverse)
        elif name == "SET_FEED_RATE":
            f_now = float(args)
        elif name == "COMMENT":
            c = args.strip().strip('"')
            comments.append(c)
            if c.startswith("interpreter: feed mode set to"):
                inverse = "inverse time" in c
        elif name == "SET_AUX_OUTPUT_VALUE":
            k, val = (float(x) for x in re.findall(_NUM, args)[:2])
            aux.append((len(joints), int(k), val))
    pos = np.asarray(joints, float).reshape(-1, 6)
    return Canon(joints=pos[:, :5].copy(), rapid=np.asarray(rapid, bool), feed=np.asarray(feed, float),
                 inverse_time=np.asarray(inv, bool), aux=aux, comments=comments, positions=pos)


# ----------------------------------------------------------------------------------------------
# the simulation
@dataclass(frozen=True, kw_only=True)
class SimRun:
    """What the simulated controller commanded, one sample per servo cycle.

    t: (K,) s from the first sample; joints: (K, 5) X Y Z (mm) and the machine's rotary axes
    (deg, ``Machine.rotary``, in LinuxCNC's sense: ``camsmooth_joints`` turns them into camsmooth's),
    the motion controller's commanded joint positions; line: (K,) the program line being executed
    (0 when none); servo_period: s.
    """

    t: np.ndarray
    joints: np.ndarray
    line: np.ndarray
    servo_period: float


def _fmt(x: float) -> str:
    return f"{x:.6g}" if np.isfinite(x) else ("-1e9" if x < 0 else "1e9")


def camsmooth_joints(machine: Machine, joints: np.ndarray) -> np.ndarray:
    """(K, 5) joints as LinuxCNC commands them (X Y Z mm, the rotary axes deg in LinuxCNC's sense)
    as camsmooth's (X Y Z mm, the rotary axes rad, the tool's rotation: LINUXCNC_SENSE undone)."""
    q = np.array(joints, float).reshape(-1, 5)
    q[:, 3:] = np.radians(q[:, 3:]) * linuxcnc_sense(machine)
    return q


def _axis_limits_deg(machine: Machine) -> dict[str, tuple[float, float, float, float]]:
    """(min, max, vmax, amax) per axis of ``machine.joint_names`` in the INI's units (mm, deg) and
    LinuxCNC's sense (a table axis negated: its travel mirrored)."""
    out = {}
    sense = dict(zip(machine.rotary, linuxcnc_sense(machine), strict=True))
    for name in machine.joint_names:
        lim = machine.limits.get(name)
        if lim is None:
            out[name] = (-1e4, 1e4, 1e3, 1e4)
            continue
        if name in sense:
            lo, hi = sorted((float(np.degrees(lim.min)) * sense[name], float(np.degrees(lim.max)) * sense[name]))
            out[name] = (lo, hi, float(np.degrees(lim.vmax)), float(np.degrees(lim.amax)))
        else:
            out[name] = (float(lim.min), float(lim.max), float(lim.vmax), float(lim.amax))
    return out


_DRIVER = '''\
#!/usr/bin/python3
import subprocess, sys, time
import linuxcnc
program, samples, timeout = sys.argv[sys.argv.index("--run") + 1:][:3]
s, c = linuxcnc.stat(), linuxcnc.command()
def wait(cond, limit=30.0):
    end = time.time() + limit
    while time.time() < end:
        s.poll()
        if cond():
            return True
        time.sleep(0.01)
    return False
wait(lambda: s.task_state == linuxcnc.STATE_ESTOP)
c.state(linuxcnc.STATE_ESTOP_RESET); c.wait_complete()
c.state(linuxcnc.STATE_ON); c.wait_complete()
c.mode(linuxcnc.MODE_MANUAL); c.wait_complete()
c.home(-1); c.wait_complete()
if not wait(lambda: all(s.homed[:5])):
    sys.exit("homing did not finish")
c.teleop_enable(1); c.wait_complete()
rec = subprocess.Popen(["halsampler", "-t", samples])
time.sleep(0.2)
c.mode(linuxcnc.MODE_AUTO); c.wait_complete()
c.program_open(program); c.wait_complete()
c.auto(linuxcnc.AUTO_RUN, 0)
wait(lambda: s.interp_state != linuxcnc.INTERP_IDLE, 5.0)
ok = wait(lambda: s.interp_state == linuxcnc.INTERP_IDLE and s.queue == 0, float(timeout))
time.sleep(0.3)
subprocess.run(["halcmd", "setp", "sampler.0.enable", "0"])
time.sleep(0.5)
rec.terminate(); rec.wait()
err = linuxcnc.error_channel().poll()
if err:
    print("linuxcnc error:", err[1], file=sys.stderr)
c.state(linuxcnc.STATE_OFF)
sys.exit(0 if ok and not err else "program did not finish: " + str(err))
'''


def _ini(machine: Machine, folder: Path, extra_traj: dict[str, str] | None, joint_extra: str = "",
         kins: str | None = None, rs274ngc: str = "") -> Path:
    lims = _axis_limits_deg(machine)
    names = machine.joint_names
    coords = "".join(names)
    lin = [lims[a] for a in "XYZ"]
    rot = [lims[a] for a in machine.rotary]
    traj = {
        "COORDINATES": coords, "LINEAR_UNITS": "mm", "ANGULAR_UNITS": "degree",
        "MAX_LINEAR_VELOCITY": _fmt(max(v[2] for v in lin)),
        "MAX_LINEAR_ACCELERATION": _fmt(max(v[3] for v in lin)),
        "MAX_ANGULAR_VELOCITY": _fmt(max(v[2] for v in rot)),
        "MAX_ANGULAR_ACCELERATION": _fmt(max(v[3] for v in rot)),
        "DEFAULT_LINEAR_VELOCITY": _fmt(max(v[2] for v in lin)),
        "POSITION_FILE": "position.txt",
    }
    traj.update(extra_traj or {})
    parts = [
        "[EMC]\nVERSION = 1.1\nMACHINE = camsmooth-sim\n",
        f"[DISPLAY]\nDISPLAY = {folder / 'driver.py'}\nCYCLE_TIME = 0.1\n",
        f"[KINS]\nKINEMATICS = {kins or f'trivkins coordinates={coords}'}\nJOINTS = 5\n",
        f"[RS274NGC]\nPARAMETER_FILE = sim.var\n{rs274ngc}",
        f"[EMCMOT]\nEMCMOT = motmod\nCOMM_TIMEOUT = 1.0\nSERVO_PERIOD = {int(SERVO_PERIOD_S * 1e9)}\n",
        "[TASK]\nTASK = milltask\nCYCLE_TIME = 0.001\n",
        "[HAL]\nHALFILE = sim.hal\n",
        "[TRAJ]\n" + "".join(f"{k} = {v}\n" for k, v in traj.items()),
        "[EMCIO]\nEMCIO = io\nCYCLE_TIME = 0.100\nTOOL_TABLE = tool.tbl\n",
    ]
    for j, name in enumerate(names):
        lo, hi, v, a = lims[name]
        body = (f"MIN_LIMIT = {_fmt(lo - 1.0)}\nMAX_LIMIT = {_fmt(hi + 1.0)}\nMAX_VELOCITY = {_fmt(v)}\n"
                f"MAX_ACCELERATION = {_fmt(a)}\n")
        parts.append(f"[AXIS_{name}]\n{body}")
        kind = "ANGULAR" if name in machine.rotary else "LINEAR"
        parts.append(f"[JOINT_{j}]\nTYPE = {kind}\nHOME = 0\nHOME_SEARCH_VEL = 0\nHOME_SEQUENCE = 0\n"
                     f"FERROR = 1e9\nMIN_FERROR = 1e9\n{body}{joint_extra}")
    ini = folder / "sim.ini"
    ini.write_text("\n".join(parts))
    return ini


_HAL = """\
loadrt [KINS]KINEMATICS
loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
loadrt sampler depth=200000 cfg=fffffs
addf motion-command-handler servo-thread
addf motion-controller servo-thread
addf sampler.0 servo-thread
net j0 joint.0.motor-pos-cmd => joint.0.motor-pos-fb sampler.0.pin.0
net j1 joint.1.motor-pos-cmd => joint.1.motor-pos-fb sampler.0.pin.1
net j2 joint.2.motor-pos-cmd => joint.2.motor-pos-fb sampler.0.pin.2
net j3 joint.3.motor-pos-cmd => joint.3.motor-pos-fb sampler.0.pin.3
net j4 joint.4.motor-pos-cmd => joint.4.motor-pos-fb sampler.0.pin.4
net line motion.program-line => sampler.0.pin.5
net estop-loop iocontrol.0.user-enable-out iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change iocontrol.0.tool-changed
"""


def _user(name: str = LINUXCNC_USER) -> tuple[int, int] | None:
    """(uid, gid) to run the simulation as: None when we are not root; the user ``name``
    (created with useradd when missing) when we are."""
    if os.geteuid() != 0:
        return None
    try:
        pw = pwd.getpwnam(name)
    except KeyError:
        subprocess.run(["useradd", "--system", "--no-create-home", name], check=True)
        pw = pwd.getpwnam(name)
    return pw.pw_uid, pw.pw_gid


#: new IPC (HAL, RTAPI and NML shared memory), PID (LinuxCNC's clean-up kills by name), mount
#: (a private /tmp for its lock and logs, /dev/shm) and network (linuxcncsvr's TCP port) namespaces;
#: the forked child dies with unshare
_UNSHARE = ["unshare", "--ipc", "--pid", "--mount-proc", "--mount", "--net", "--propagation", "private",
            "--kill-child"]

#: run inside the namespaces as root: loopback up, a private /tmp (the run's folder, under /tmp,
#: bound back at its own path) and /dev/shm, then LinuxCNC as the unprivileged user.
#: Arguments: folder, its path below /tmp ('' when it is elsewhere), uid, gid ('' '': stay), command.
_ISOLATE = r"""set -e
F=$1; REL=$2; U=$3; G=$4; shift 4
ip link set lo up 2>/dev/null || true
mount -t tmpfs -o mode=1777 tmpfs /dev/shm
if [ -n "$REL" ]; then mkdir -p "$F/tmp/$REL"; mount --bind "$F" "$F/tmp/$REL"; fi
mount --rbind "$F/tmp" /tmp
cd "$F"
if [ -n "$U" ]; then exec setpriv --reuid="$U" --regid="$G" --clear-groups "$@"; fi
exec "$@"
"""


@functools.lru_cache(maxsize=1)
def isolation_missing() -> str | None:
    """None when each simulation can run in namespaces of its own (root, ``unshare``, ``setpriv``
    and the kernel allowing them: probed once), else why not."""
    if os.geteuid() != 0:
        return "not root: unshare needs CAP_SYS_ADMIN"
    missing = [p for p in ("unshare", "setpriv", "mount") if shutil.which(p) is None]
    if missing:
        return f"{', '.join(missing)} not found"
    try:
        proc = subprocess.run([*_UNSHARE, "sh", "-c", "mount -t tmpfs tmpfs /dev/shm"], capture_output=True,
                              text=True, stdin=subprocess.DEVNULL, timeout=30)
    except (OSError, subprocess.SubprocessError) as exc:
        return f"unshare failed: {exc}"
    if proc.returncode != 0:
        return f"unshare failed (exit {proc.returncode}): {proc.stderr.strip()}"
    return None


@contextlib.contextmanager
def _turn(wait: float) -> Iterator[None]:
    """Hold RUN_LOCK (fcntl.flock, exclusive) for one simulation; wait at most ``wait`` s for it.
    RuntimeError naming the holder (its pid, written in the file) when the wait runs out."""
    fd = os.open(RUN_LOCK, os.O_RDWR | os.O_CREAT, 0o666)
    try:
        end = time.monotonic() + wait
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() >= end:
                    holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "unknown"
                    raise RuntimeError(f"another camsmooth LinuxCNC simulation (pid {holder}) held {RUN_LOCK} for "
                                       f"{wait:.0f} s: gave up waiting") from None
                time.sleep(0.5)
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)  # releases the lock


def _wait_for_other_linuxcnc(wait: float) -> None:
    """Without isolation: wait at most ``wait`` s until no LinuxCNC holds LINUXCNC_LOCK (its start
    script would kill that one), else RuntimeError saying so."""
    end = time.monotonic() + wait
    while LINUXCNC_LOCK.exists():
        if time.monotonic() >= end:
            raise RuntimeError(f"another LinuxCNC runs on this machine ({LINUXCNC_LOCK} exists) and this simulation "
                               f"cannot run beside it ({isolation_missing()}): gave up after {wait:.0f} s")
        time.sleep(0.5)


def _tail(text: str, n: int = MESSAGE_CHARS) -> str:
    text = text.strip()
    return text if len(text) <= n else "..." + text[-n:]


_ERROR_LINE = re.compile(r"error|did not finish|failed|cannot|can't|not found|refus|denied|no such|abort",
                         re.IGNORECASE)


def _failure(what: str, proc: subprocess.CompletedProcess, folder: Path, kept: bool) -> str:
    """A failed run in words: ``what`` and LinuxCNC's exit status, first the lines of its output
    and logs that say what went wrong, then the end of each (its output, and the start script's
    linuxcnc_print.txt / linuxcnc_debug.txt in $HOME, the run's folder). ``kept``: the folder
    stays (``simulate(keep=...)``) and is named."""
    texts = {"stderr": proc.stderr or "", "stdout": proc.stdout or ""}
    for log in (folder / "linuxcnc_print.txt", folder / "linuxcnc_debug.txt"):
        try:
            texts[log.name] = log.read_text(errors="replace")
        except OSError:
            pass
    why: list[str] = []
    for text in texts.values():
        for ln in text.splitlines():
            ln = " ".join(ln.split())
            benign = "You can find more information" in ln or "updating variable file" in ln
            if _ERROR_LINE.search(ln) and not benign and ln not in why:
                why.append(ln)
    head = f"{what} (exit {proc.returncode})" + (": " + "; ".join(why[:6]) if why else "")
    tails = [f"{name}: {_tail(' '.join(text.split()))}" for name, text in texts.items() if text.strip()]
    if not tails:
        tails = ["LinuxCNC wrote nothing"]
    return " | ".join([head, *tails]) + (f" (configuration and logs in {folder})" if kept else "")


def simulate(program: Path | str, machine: Machine, *, timeout: float = 600.0,
             traj: dict[str, str] | None = None, keep: Path | None = None, wait: float | None = None,
             hal: str | None = None, joint_ini: str = "", kins: str | None = None, rs274ngc: str = "",
             trt: bool = False) -> SimRun:
    """Run ``program`` on a headless LinuxCNC simulation of ``machine`` (module docstring) and
    return the commanded joints per servo cycle. traj: extra ``[TRAJ]`` settings (e.g.
    ``ARC_BLEND_ENABLE``). keep: a folder to leave the configuration and logs in. wait: the most
    seconds to wait for another simulation (default timeout + 180). hal: the HAL file's text instead
    of the loop-back one (it must feed ``sampler.0``, cfg ``fffffs``, whose pins 0-4 land in
    ``SimRun.joints``, as benchmarks/hal_reference.py does); joint_ini: lines added to every
    ``[JOINT_n]`` section (each line ending in a newline, e.g. ``BACKLASH = 0.05``); kins: the
    ``[KINS] KINEMATICS`` line instead of trivkins (e.g. ``xyzac-trt-kins sparm=identityfirst`` with
    the HAL that nets its switchkins pins); rs274ngc: lines added to ``[RS274NGC]`` (remaps, each
    ending in a newline). trt: run on LinuxCNC's trt switchkins kinematics of the machine's table
    (``trt_config``: a TCP-mode program's ``M428`` switches it on; hal, kins and rs274ngc are then
    that configuration's). RuntimeError naming LinuxCNC's output and logs when the run fails."""
    missing = linuxcnc_missing()
    if missing:
        raise RuntimeError(missing)
    if trt:
        cfg = trt_config(machine)
        hal, kins, rs274ngc = cfg["hal"], cfg["kins"], cfg["rs274ngc"]
    wait = timeout + 180.0 if wait is None else float(wait)
    folder = Path(keep) if keep is not None else Path(tempfile.mkdtemp(prefix="camsmooth-lcnc-", dir="/tmp"))
    folder = folder.resolve()
    folder.mkdir(parents=True, exist_ok=True)
    try:
        ini = _ini(machine, folder, traj, joint_ini, kins, rs274ngc)
        (folder / "sim.hal").write_text(_HAL if hal is None else hal)
        (folder / "driver.py").write_text(_DRIVER)
        os.chmod(folder / "driver.py", 0o755)
        (folder / "tool.tbl").write_text("T1 P1 Z0 D10 ;\n")
        shutil.copy(program, folder / "program.ngc")
        (folder / "tmp").mkdir(exist_ok=True)
        os.chmod(folder / "tmp", 0o1777)
        isolated = isolation_missing() is None
        user = _user(ISOLATED_USER if isolated else LINUXCNC_USER)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "VIRTUAL_ENV"))}
        env["PATH"] = "/usr/bin:/bin:/usr/sbin:/sbin"
        env["HOME"] = str(folder)  # rtapi_app's socket and the start script's logs: the run's own
        if user is not None:
            os.chmod(folder, 0o777)
            for p in folder.iterdir():
                os.chown(p, *user)
            os.chown(folder, *user)
        samples = folder / "samples.txt"
        # -r: LinuxCNC's output to us, not to its logs; the arguments after the INI go to the DISPLAY program
        cmd = ["linuxcnc", "-r", str(ini), "--run", str(folder / "program.ngc"), str(samples), str(timeout)]
        if isolated:
            rel = str(folder.relative_to("/tmp")) if folder.is_relative_to("/tmp") else ""
            uid, gid = (str(user[0]), str(user[1])) if user is not None else ("", "")
            cmd = [*_UNSHARE, "sh", "-c", _ISOLATE, "sh", str(folder), rel, uid, gid, *cmd]
        as_user = {} if isolated or user is None else {"user": user[0], "group": user[1]}
        with _turn(wait):
            if not isolated:
                _wait_for_other_linuxcnc(wait)
            for _attempt in range(2):  # a start right after another LinuxCNC's shutdown can fail at once: retry once
                proc = subprocess.run(cmd, cwd=folder, env=env, capture_output=True, text=True,
                                      timeout=timeout + 120, stdin=subprocess.DEVNULL, **as_user)
                if samples.exists() and samples.stat().st_size > 0:
                    break
        (folder / "linuxcnc.log").write_text(proc.stdout + "\n--- stderr ---\n" + proc.stderr)
        if not samples.exists() or samples.stat().st_size == 0:
            raise RuntimeError(_failure("LinuxCNC simulation recorded nothing", proc, folder, keep is not None))
        data = np.loadtxt(samples, ndmin=2)
        if proc.returncode != 0 or "program did not finish" in proc.stderr:
            raise RuntimeError(_failure("LinuxCNC simulation failed", proc, folder, keep is not None))
        n = data[:, 0]
        return SimRun(t=(n - n[0]) * SERVO_PERIOD_S, joints=data[:, 1:6], line=data[:, 6].astype(np.int64),
                      servo_period=SERVO_PERIOD_S)
    finally:
        if keep is None:
            shutil.rmtree(folder, ignore_errors=True)


# ----------------------------------------------------------------------------------------------
# what the tool did
def row_samples(program_text: str, run: SimRun) -> dict[int, np.ndarray]:
    """Per row of a camsmooth program (its ``(row N: ...)`` comments), the indices of the servo
    samples executing the row's cut blocks (the G01 blocks after the entry move)."""
    lines: dict[int, list[int]] = {}
    row, entry = None, False
    for k, ln in enumerate(program_text.split("\n"), start=1):
        if ln.startswith("(row "):
            row, entry = int(ln.split()[1].rstrip(":")), True
        elif ln.startswith("G01") and row is not None:
            if entry:
                entry = False
                continue
            lines.setdefault(row, []).append(k)
        elif ln.startswith("G00") and row is not None and row in lines:
            row = None
    return {r: np.flatnonzero(np.isin(run.line, lns)) for r, lns in lines.items()}


@dataclass(frozen=True, kw_only=True)
class RowRun:
    """One row of a program as the simulation ran it (``row_runs``): row id, executed time of its
    cut blocks (s, servo samples x period), the controller model's prediction and the time-optimal
    law's (s), and the tool tip's largest distance from the programmed path over those samples (mm)."""

    row: int
    executed: float
    predicted: float
    optimal: float
    deviation: float


def row_runs(machine: Machine, result: Any, program_text: str, run: SimRun) -> list[RowRun]:
    """Every row of a smoothing MethodResult ``result`` (with its controller plan and time law)
    written as ``program_text`` and executed as ``run``: what it took and where the tip went.
    The tips come from the recorded joints by the machine's forward kinematics (joints mapped to
    camsmooth's axes and signs, ``camsmooth_joints``); the programmed path is ``programmed_tip_path``
    from the row's entry point, ``DEFAULT_SAFE_HEIGHT_MM`` up the first point's tool axis."""
    from camsmooth.constants import DEFAULT_SAFE_HEIGHT_MM

    joints = camsmooth_joints(machine, run.joints)
    tip, _ = machine.tool_pose_np(joints[:, 3], joints[:, 4], joints[:, 0], joints[:, 1], joints[:, 2])
    q = np.column_stack([result.xyz, result.rotary.values])
    ctrl, plan = result.controller, result.plan
    out = []
    for rid, k in row_samples(program_text, run).items():
        sel = result.rows == rid
        first = np.flatnonzero(sel)[0]
        path = programmed_tip_path(machine, q[sel], result.cl[first] + DEFAULT_SAFE_HEIGHT_MM * result.axis[first])
        out.append(RowRun(row=int(rid), executed=float((k[-1] - k[0] + 1) * run.servo_period),
                          predicted=float(ctrl.row_cycle_time[list(ctrl.row_ids).index(rid)]),
                          optimal=float(plan.row_cycle_time[list(plan.row_ids).index(rid)]),
                          deviation=float(tip_deviation(tip[k[0]:k[-1] + 1], path).max())))
    return out
