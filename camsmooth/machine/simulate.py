"""Measurement simulators: realistic probing, spindle-analyser and ballbar files from a given
error model, with seeded Gaussian noise, for examples and tests (file formats in
camsmooth.machine.calibration). Each simulator evaluates the machine through ErrorModel.apply /
SpindleScrew / ErrorModel.thermal_state / ErrorModel.real_frame (the one function for the real
pose), i.e. the same chain the calibration fits.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from camsmooth.errors import InputError
from camsmooth.machine.calibration import (
    BallbarData,
    ProbeData,
    RTestData,
    SpindleData,
    probe_offsets,
    reference_rtest_poses,
    rtest_displacement,
)
from camsmooth.machine.kinematics import Machine, load_machine
from camsmooth.machine.model import ErrorModel, SpindleScrew

DEFAULT_NOISE = {"probe": 0.0005, "spindle": 0.0001, "ballbar": 0.001, "rtest": 0.0005}  # mm, one std. dev.
#: default R-test sphere, relative to the table centre (mm, workpiece frame): off the C axis and
#: above the tilt axis, as an R-test sphere is usually set, so both axes carry it round
RTEST_SPHERE_OFFSET = (120.0, 60.0, 80.0)


def default_probe_poses(machine: Machine, n: int = 11, max_deg: float = 100.0
                        ) -> tuple[np.ndarray, np.ndarray]:
    """An n x n grid of (A, B) in radians over +-max_deg, clipped to the machine's travel."""
    lim = np.radians(max_deg)
    a = np.linspace(-lim, lim, n)
    A, B = (v.ravel() for v in np.meshgrid(a, a, indexing="ij"))
    ok = machine.within("A", A) & machine.within("B", B)
    return A[ok], B[ok]


def require_probe_machine(machine: Machine, what: str = "probing") -> None:
    """InputError unless ``machine`` is the AB head that reference-sphere probing (columns A, B)
    simulates and calibrates: its rotary errors are the AB head's (ErrorModel, module docstring)."""
    if machine.description.preset != "AB-head":
        raise InputError(f"{what} (columns A, B) is for an AB-head machine; the machine is {machine.describe()}: "
                         "simulate its rotary axes' R-test instead (simulate_rtest, `camsmooth simulate rtest`)")


def simulate_probe(model: ErrorModel, machine: Machine | None = None, *, poses: tuple[np.ndarray, np.ndarray]
                   | None = None, sphere: Sequence[float] = (0.0, 0.0, 0.0),
                   sphere_error: Sequence[float] = (0.012, -0.008, 0.005),
                   noise: float = DEFAULT_NOISE["probe"], seed: int = 0) -> ProbeData:
    """Reference-sphere probing at the poses (A, B rad; default ``default_probe_poses``). The
    sphere is nominally at ``sphere`` (mm) and really at sphere + sphere_error; at each pose the
    pivot is commanded so that the nominal tool tip sits at the nominal centre, and the control
    reports the centre computed with its nominal kinematics: c - g(A, B) + N(0, noise^2) per
    coordinate (g = real minus nominal tool tip; calibration module docstring)."""
    machine = machine or load_machine()
    require_probe_machine(machine)
    A, B = poses if poses is not None else default_probe_poses(machine)
    A, B = np.asarray(A, float), np.asarray(B, float)
    c0 = np.asarray(sphere, float)
    T = machine.tool_axis_np(A, B)
    xyz = machine.linear_axes(np.broadcast_to(c0, T.shape), A, B)
    data = ProbeData(A, B, xyz[:, 0], xyz[:, 1], xyz[:, 2], np.zeros((len(A), 3)))
    g = probe_offsets(model, machine, data)
    rng = np.random.default_rng(seed)
    data.centre = c0 + np.asarray(sphere_error, float) - g + rng.normal(0.0, noise, g.shape)
    return data


def default_rtest_poses(machine: Machine, n_tilt: int = 7, n_outer: int = 12, max_deg: float = 90.0
                        ) -> tuple[np.ndarray, np.ndarray]:
    """An R-test pose grid (q1, q2) rad in ``machine.rotary`` order within the travel
    (``calibration.reference_rtest_poses``): on a table the tilt at n_tilt angles over +-max_deg
    (clipped to its travel) and C at n_outer angles round a full turn."""
    return reference_rtest_poses(machine, n_tilt, n_outer, max_deg)


def simulate_rtest(model: ErrorModel, machine: Machine, *, poses: tuple[np.ndarray, np.ndarray] | None = None,
                   sphere: Sequence[float] | None = None, sphere_error: Sequence[float] = (0.012, -0.008, 0.005),
                   noise: float = DEFAULT_NOISE["rtest"], seed: int = 0) -> RTestData:
    """An R-test run: a sphere fixed on the table, nominally at ``sphere`` (mm, workpiece frame;
    default table_centre + RTEST_SPHERE_OFFSET), really at sphere + sphere_error; at every pose
    (q1, q2 rad in ``machine.rotary`` order; default ``default_rtest_poses``) the linear axes keep
    the nominal tool tip (the nest's reference point) on the nominal centre, and the nest reads the
    real sphere centre in the real tool frame (``calibration.rtest_displacement``, through
    ErrorModel.real_frame) plus N(0, noise^2) per coordinate (mm)."""
    q1, q2 = poses if poses is not None else default_rtest_poses(machine)
    q1, q2 = np.asarray(q1, float), np.asarray(q2, float)
    s0 = (np.asarray(machine.table_centre, float) + RTEST_SPHERE_OFFSET if sphere is None
          else np.asarray(sphere, float))
    xyz = machine.linear_axes(np.broadcast_to(s0, (len(q1), 3)), q1, q2)
    data = RTestData(q1, q2, xyz[:, 0], xyz[:, 1], xyz[:, 2], np.zeros((len(q1), 3)))
    d = rtest_displacement(model, machine, data, s0 + np.asarray(sphere_error, float))
    rng = np.random.default_rng(seed)
    data.d = d + rng.normal(0.0, noise, d.shape)
    return data


def simulate_spindle(model: ErrorModel, *, exts: Sequence[float] = (50.0, 150.0), revolutions: int = 3,
                     samples_per_rev: int = 72, noise: float = DEFAULT_NOISE["spindle"], seed: int = 0
                     ) -> SpindleData:
    """Spindle-error-analyser data: the reference-ball centre in CS1 over ``revolutions`` spindle
    turns (samples_per_rev per turn, spindle angle accumulating) at each ball extension ``exts``
    (mm beyond the collet centre O4: the ball heights), from model.spindle (no errors when None),
    plus N(0, noise^2) per coordinate."""
    spindle = model.spindle or SpindleScrew()
    if samples_per_rev < 4 or revolutions < 1:
        raise InputError("simulate spindle: needs at least 4 samples per revolution and one revolution")
    theta = np.arange(revolutions * samples_per_rev) * (2 * np.pi / samples_per_rev)
    rng = np.random.default_rng(seed)
    th_all, ext_all, balls = [], [], []
    for e in exts:
        balls.append(spindle.tip(theta, float(e)))
        th_all.append(theta)
        ext_all.append(np.full_like(theta, float(e)))
    ball = np.concatenate(balls)
    return SpindleData(np.concatenate(th_all), np.concatenate(ext_all),
                       ball + rng.normal(0.0, noise, ball.shape))


def default_ballbar_schedule(duration: float = 14400.0, interval: float = 900.0, heat: float = 10800.0,
                             rpm: float = 5000.0) -> tuple[np.ndarray, np.ndarray]:
    """Set times (s) every ``interval`` over ``duration`` and the spindle speed held from each set
    to the next: ``rpm`` while t < heat (warm-up), then stopped (cool-down)."""
    t = np.arange(0.0, duration + 0.5 * interval, interval)
    return t, np.where(t < heat, rpm, 0.0)


def simulate_ballbar(model: ErrorModel, machine: Machine | None = None, *, times: np.ndarray | None = None,
                     rpm: np.ndarray | None = None, bar_length: float = 150.0,
                     angles_deg: Sequence[float] = (30.0, 60.0), step_deg: float = 0.1,
                     setup_error: float = 0.005, noise: float = DEFAULT_NOISE["ballbar"], seed: int = 0
                     ) -> BallbarData:
    """Ballbar cone test (METHODS section 5): at every set time the spindle ball runs a full
    circle counter-clockwise and clockwise (``step_deg`` apart) at each bar angle, radius
    L0 cos(angle), L0 sin(angle) above the table ball. The real spindle-ball centre is the
    commanded one plus the displacement, at A = B = 0, of the point h = L0 (sin angle -
    sin angle_min) above the tool tip (the reference, lowest, ball) through
    ``ErrorModel.real_frame`` (geometric errors, spindle screw and the thermal state at the set's
    time, both frames). Simulation assumptions: the thermal state is constant during a set, and,
    as in the paper, the two cones sample the spindle at two heights. The table ball of each
    cone is off its nominal place by N(0, setup_error^2) per coordinate (absorbed by the fit).
    Readings dL = |S - C| - L0 + N(0, noise^2) (mm)."""
    machine = machine or load_machine()
    if times is None:
        times, default_rpm = default_ballbar_schedule()
        rpm = default_rpm if rpm is None else rpm
    times = np.asarray(times, float)
    rpm = np.broadcast_to(np.asarray(5000.0 if rpm is None else rpm, float), times.shape)
    n_circle = int(round(360.0 / step_deg))
    if abs(n_circle * step_deg - 360.0) > 1e-9 or n_circle < 3:
        raise InputError(f"simulate ballbar: step {step_deg} deg must divide 360 deg")
    rng = np.random.default_rng(seed)
    angles = np.radians(np.sort(np.asarray(angles_deg, float)))
    setup = rng.normal(0.0, setup_error, (len(angles), 3))
    zero = {a: 0.0 for a in ("A", "B", "X", "Y", "Z")}
    nominal = machine.chain.forward(zero)
    state = model.thermal_state(times, rpm)
    phi1 = np.arange(n_circle) * np.radians(step_deg)
    cols: dict[str, list[np.ndarray]] = {k: [] for k in ("t", "rpm", "angle", "dir", "phi", "dL")}
    for k, tk in enumerate(times):
        for c, ang in enumerate(angles):
            h = bar_length * (np.sin(ang) - np.sin(angles[0]))
            # the ball h above the tool tip, through the model's one real pose at A = B = 0
            f = model.real_frame(machine, zero, {e: float(v[k]) for e, v in state.items()})
            d = np.asarray(f.apply((0.0, 0.0, h))) - np.asarray(nominal.apply((0.0, 0.0, h)))
            for direction in (1, -1):
                phi = phi1 if direction == 1 else np.mod(-phi1, 2 * np.pi)
                radius = bar_length * np.cos(ang)
                P = np.column_stack([radius * np.cos(phi), radius * np.sin(phi),
                                     np.full_like(phi, bar_length * np.sin(ang))])
                S = P + d
                dL = np.linalg.norm(S - setup[c], axis=1) - bar_length + rng.normal(0.0, noise, len(phi))
                cols["t"].append(np.full_like(phi, tk))
                cols["rpm"].append(np.full_like(phi, rpm[k]))
                cols["angle"].append(np.full_like(phi, ang))
                cols["dir"].append(np.full(len(phi), direction))
                cols["phi"].append(phi)
                cols["dL"].append(dL)
    cat = {k: np.concatenate(v) for k, v in cols.items()}
    return BallbarData(cat["t"], cat["rpm"], cat["angle"], cat["dir"].astype(int), cat["phi"],
                       np.full_like(cat["t"], bar_length), cat["dL"])
