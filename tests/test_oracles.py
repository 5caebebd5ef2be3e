"""Independent oracles where the code used to check itself (issue 12).

- Servo lag: the diagnosis simulator's axis channel against the closed-form response of
  tau dy/dt = u - y to a piecewise-linear command, written here as a superposition of ramp
  responses (not the simulator's recurrence).
- Backlash: the simulator against a play operator (hysteresis of width b) written here, on the
  samples where the play operator's carriage is driven; alone and after a servo lag.
- The pipeline's violation counter (ProgramSmoother.metrics) against a hand-made program that
  violates each limit exactly once, the expected counts worked out here.
- Ballbar trilateration against closed-form geometry with known signs (METHODS section 5).
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest
import trimesh

from camsmooth.diagnosis.recordings import Program
from camsmooth.diagnosis.simulator import physics_from_settings, simulate_recording
from camsmooth.machine.axes import RotaryValues
from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML
from camsmooth.machine.model import ErrorModel


# ----------------------------------------------------------------------------------------------
# commands: piecewise-linear, irregular knots (no recording sample falls on a knot after the first)
def _command(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Knot times (s) and values: moves of random length and speed, reversals, two dwells."""
    rng = np.random.default_rng(seed)
    t = np.concatenate([[0.0], np.cumsum(rng.uniform(0.013, 0.047, 260))])
    slope = np.repeat(rng.choice([-1.0, 1.0], 26) * rng.uniform(5.0, 40.0, 26), 10)  # mm/s, 10 intervals each
    slope[60:70] = 0.0
    slope[150:160] = 0.0
    u = np.concatenate([[1.0], 1.0 + np.cumsum(slope * np.diff(t))])
    return t, u


def _lag_closed_form(tk: np.ndarray, uk: np.ndarray, tau: float, ts: np.ndarray) -> np.ndarray:
    """y(ts) of tau y' = u - y, y(0) = u(0), u linear between knots and held after the last: the
    following error e = u - y obeys tau e' = tau u' - e, so each change ds of the slope at t_k adds
    ds tau (1 - exp(-(t - t_k) / tau)) for t >= t_k (superposition of ramp responses)."""
    s = np.diff(uk) / np.diff(tk)
    ds = np.diff(np.concatenate([[0.0], s, [0.0]]))  # slope changes at every knot (held after the last)
    dt = ts[:, None] - tk[None, :]
    e = np.sum(np.where(dt >= 0, ds[None, :] * tau * (1.0 - np.exp(-np.clip(dt, 0.0, None) / tau)), 0.0), axis=1)
    return np.interp(ts, tk, uk) - e


def _play(u: np.ndarray, b: float, first_dir: float) -> tuple[np.ndarray, np.ndarray]:
    """Play (backlash) operator of width b on the sequence u (dense enough that u is monotone
    between entries): the carriage y stays put until the drive u pulls it, y in [u - b/2, u + b/2].
    Starts engaged after a move in ``first_dir``. Returns y and, per entry, +1 / -1 where the
    carriage is held against the side of the last motion (driven or resting against it) or 0
    while the play is being taken up."""
    y = np.empty_like(u)
    side = np.zeros_like(u)
    cur, last = u[0] - 0.5 * b * first_dir, first_dir
    for i, ui in enumerate(u):
        new = min(max(cur, ui - 0.5 * b), ui + 0.5 * b)
        if new != cur:
            last = 1.0 if new > cur else -1.0
        cur = new
        y[i] = cur
        side[i] = last if abs(cur - (ui - 0.5 * b * last)) <= 1e-12 * max(1.0, abs(ui)) else 0.0
    return y, side


def _recording(tk, axes, physics, rate, channel):
    rec = simulate_recording(Program(t=tk, axes=axes), None, physics, rate=rate, channels=[channel])
    return rec.t, rec.channels[channel]


def test_servo_lag_matches_the_closed_form_response():
    tk, uk = _command(1)
    for tau in (0.004, 0.025, 0.11):
        ts, y = _recording(tk, {"X": uk}, ErrorModel(tau={"X": tau}), 397.0, "X_act")
        ref = _lag_closed_form(tk, uk, tau, ts)
        assert np.max(np.abs(ref - np.interp(ts, tk, uk))) > 100 * 1e-9  # the lag is really there
        np.testing.assert_allclose(y, ref, atol=1e-9, rtol=0)


def test_servo_lag_given_as_gain_in_file_units():
    """Kv_X (1/s) as the settings file gives it: tau = 1 / Kv."""
    tk, uk = _command(2)
    ts, y = _recording(tk, {"X": uk}, physics_from_settings({"Kv_X": 40.0}), 311.0, "X_act")
    np.testing.assert_allclose(y, _lag_closed_form(tk, uk, 1.0 / 40.0, ts), atol=1e-9, rtol=0)


@pytest.mark.parametrize("axis, setting, b", [("X", {"backlash_X": 0.04}, 0.04),
                                              ("A", {"backlash_A": 0.05}, math.radians(0.05))])
def test_backlash_matches_a_play_operator(axis, setting, b):
    """Backlash b (mm; deg in the settings for A): where the play operator's carriage is held
    against the side it last moved to, the simulator gives the same position; within the
    take-up travel b after a reversal the simulator's step model and the play differ by at most
    b (the simulator switches sides at the reversal itself)."""
    tk, uk = _command(3)
    if axis == "A":
        uk = np.radians(uk)  # the same moves in degrees
    ts, y = _recording(tk, {axis: uk}, physics_from_settings(setting), 503.0, f"{axis}_act")
    merged = np.union1d(tk, ts)
    first = float(np.sign(uk[np.flatnonzero(np.diff(uk))[0] + 1] - uk[0]))
    yp, side = _play(np.interp(merged, tk, uk), b, first)
    at = np.searchsorted(merged, ts)
    yp, side = yp[at], side[at]
    held = side != 0
    assert held.mean() > 0.8 and (~held).sum() >= 5  # both regimes are sampled
    np.testing.assert_allclose(y[held], yp[held], atol=1e-12 * max(1.0, float(np.max(np.abs(uk)))), rtol=0)
    assert np.all(np.abs(y[~held] - yp[~held]) <= b * (1 + 1e-9))
    # the size and the sign of the half play: the carriage trails its drive by b/2
    u = np.interp(ts, tk, uk)
    np.testing.assert_allclose(np.abs(y[held] - u[held]), 0.5 * b, rtol=1e-9)


def test_backlash_after_servo_lag_matches_play_of_the_lagged_drive():
    """Lag then backlash: the carriage is the play operator applied to the lagged drive, where the
    drive has turned with the command (outside the few samples after a reversal where the lagged
    drive still runs the old way and the play is being taken up)."""
    tk, uk = _command(4)
    tau, b = 0.02, 0.02
    ts, y = _recording(tk, {"X": uk}, ErrorModel(tau={"X": tau}, backlash={"X": b}), 401.0, "X_act")
    fine = np.union1d(ts, np.linspace(tk[0], tk[-1], 40 * len(tk)))  # the lagged drive turns between knots
    first = float(np.sign(uk[np.flatnonzero(np.diff(uk))[0] + 1] - uk[0]))
    yp, side = _play(_lag_closed_form(tk, uk, tau, fine), b, first)
    at = np.searchsorted(fine, ts)
    yp, side = yp[at], side[at]
    # commanded direction at each sample: the slope of its interval, held through dwells
    s = np.sign(np.diff(uk))
    for i in range(1, len(s)):
        s[i] = s[i] if s[i] != 0 else s[i - 1]
    cmd = s[np.clip(np.searchsorted(tk, ts, side="right") - 1, 0, len(s) - 1)]
    ok = (side != 0) & (side == cmd)
    assert ok.mean() > 0.7
    np.testing.assert_allclose(y[ok], yp[ok], atol=1e-7, rtol=0)


# ----------------------------------------------------------------------------------------------
# the pipeline's violation counter on a hand-made program
H = 0.01  # s between points: 1 mm at 6000 mm/min


def _counter_setup(linear: dict | None = None):
    from camsmooth.geometry.clearance import MeshIndex
    from camsmooth.geometry.cutter import ToroidalCutter
    from camsmooth.geometry.paths import CCPath
    from camsmooth.machine.kinematics import DEFAULT_MACHINE_TOML, machine_from_dict
    from camsmooth.smoothing.pipeline import ProgramSmoother, SmoothOptions, prepare

    data = tomllib.loads(DEFAULT_MACHINE_TOML)
    data["axis"]["A"].update(min=-3.0, max=10.0, vmax=20.0, amax=1000.0)
    data["axis"]["B"].update(min=-10.0, max=20.0, vmax=20.0, amax=1000.0)
    for name in "XYZ":  # the pivot's axes out of the way unless a test sets them
        data["axis"].setdefault(name, {}).update(linear or {"vmax": 1e6, "amax": 1e9})
    machine = machine_from_dict(data)
    rows = _violating_rows()
    pts, row_id = [], []
    for k, (A, _) in enumerate(rows):
        pts += [[float(i), 10.0 * k, 0.0] for i in range(len(A))]
        row_id += [k] * len(A)
    pts = np.array(pts)
    n = len(pts)
    path = CCPath(pts, np.tile([0.0, 0.0, 1.0], (n, 1)), np.array(row_id), np.tile([1.0, 0.0, 0.0], (n, 1)),
                  np.full(n, 6000.0), "hand-made")
    xs, ys = np.meshgrid(np.linspace(-10, 20, 4), np.linspace(-10, 10 * len(rows) + 10, 4), indexing="ij")
    V = np.column_stack([xs.ravel(), ys.ravel(), np.zeros(16)])
    F = [[4 * i + j, 4 * (i + 1) + j, 4 * (i + 1) + j + 1] for i in range(3) for j in range(3)]
    F += [[4 * i + j, 4 * (i + 1) + j + 1, 4 * i + j + 1] for i in range(3) for j in range(3)]
    index = MeshIndex(trimesh.Trimesh(V, np.array(F), process=False))
    cutter = ToroidalCutter(R=4.0, r=1.0)
    program = prepare(path, index, cutter, None, (np.radians(2.0), np.radians(25.0)),
                      (np.radians(-15.0), np.radians(15.0)))
    sm = ProgramSmoother(program, index, machine, machine, cutter, 1e-3, SmoothOptions(), workers=1)
    A = np.radians(np.concatenate([r[0] for r in rows]))
    B = np.radians(np.concatenate([r[1] for r in rows]))
    return sm, program, A, B


def _parabola(peak: float, c: float, n: int = 7, sign: float = -1.0) -> np.ndarray:
    """peak + sign c (i - i0)^2 (deg), i0 the middle point: only the middle reaches the peak."""
    i = np.arange(n) - n // 2
    return peak + sign * c * i ** 2


def _from_velocities(start: float, v: list[float]) -> np.ndarray:
    """Positions (deg) with these segment velocities (deg/s), H apart."""
    return start + np.concatenate([[0.0], np.cumsum(np.asarray(v) * H)])


def _violating_rows() -> list[tuple[np.ndarray, np.ndarray]]:
    """Rows (A, B in deg) of the hand-made program. Limits: A in [-3, 10] deg, B in [-10, 20] deg,
    both 20 deg/s and 1000 deg/s^2; lead window [2, 25] deg, tilt [-15, 15] deg. With the normal
    +z and the feed +x, the local frame is the workpiece frame, so the tool axis
    (sin B, -sin A cos B, cos A cos B) has lead = acos(cos A cos B) and
    tilt = atan2(-sin A cos B, sin B).

    The parabolas (c = 0.02 deg a step^2) peak 0.01 deg past a bound at their middle point only,
    their neighbours 0.01 deg inside; their second differences are 2c / H^2 = 400 deg/s^2 and
    segment velocities at most 5c / H = 10 deg/s, within the limits."""
    c, eps = 0.02, 0.01
    tilt_bound = -math.degrees(math.asin(math.tan(math.radians(15.0)) * math.tan(math.radians(5.0))))
    z = np.zeros(7)
    return [
        # 0: A travel: A dips to -3.01 deg at B = 15 deg (tilt 11.1 deg, lead 15.3 deg: inside)
        (_parabola(-3.0 - eps, c, sign=1.0), z + 15.0),
        # 1: B travel: B peaks at 20.01 deg at A = 0 (lead 20 deg, tilt 0)
        (z, _parabola(20.0 + eps, c)),
        # 2: A velocity: segment velocities 0, 7, 14, 21, 14, 7, 0 deg/s (steps of 700 deg/s^2) at
        #    B = 5 deg: one segment over 20 deg/s; A reaches 0.63 deg, tilt down to -7 deg
        (_from_velocities(0.0, [0, 7, 14, 21, 14, 7, 0]), np.full(8, 5.0)),
        # 3: A acceleration: velocities 0, 0, 0, 15, 15, 15 deg/s: one second difference of
        #    1500 deg/s^2 (> 1000) at the kink
        (_from_velocities(0.0, [0, 0, 0, 15, 15, 15]), np.full(7, 5.0)),
        # 4, 5: the same for B at A = 0 from B = 10 deg
        (np.zeros(8), _from_velocities(10.0, [0, 7, 14, 21, 14, 7, 0])),
        (np.zeros(7), _from_velocities(10.0, [0, 0, 0, 15, 15, 15])),
        # 6: lead window: B dips to 1.99 deg at A = 0 (lead = B), tilt 0
        (z, _parabola(2.0 - eps, c, sign=1.0)),
        # 7: tilt window: at B = 5 deg, A dips past the A where tilt = 15 deg
        (_parabola(tilt_bound - eps, c, sign=1.0), z + 5.0),
    ]


def test_violation_counter_counts_each_limit_once():
    sm, program, A, B = _counter_setup()
    n = len(A)
    delta = np.full(n, 0.5)
    delta[3] = -2e-3  # one gouge beyond the 1e-3 mm tolerance
    with sm:
        q = RotaryValues.of(sm.nominal.rotary, A, B)
        r = sm._result("none", q, delta=delta, lift=np.zeros(n), unreachable=np.zeros(0, int), runtime=0.0)
    # the program is what was built: the lead and tilt the code derived agree with the closed form
    lead = np.arccos(np.cos(A) * np.cos(B))
    tilt = np.arctan2(-np.sin(A) * np.cos(B), np.sin(B))
    np.testing.assert_allclose(r.lead, lead, atol=1e-12)
    np.testing.assert_allclose(r.tilt, tilt, atol=1e-12)
    np.testing.assert_allclose(np.diff(program.t[program.path.rows == 0]), H, rtol=1e-12)
    assert r.metrics.violations == {
        "X travel": 0, "X velocity": 0, "X acceleration": 0, "Y travel": 0, "Y velocity": 0, "Y acceleration": 0,
        "Z travel": 0, "Z velocity": 0, "Z acceleration": 0,
        "A travel": 1, "A velocity": 1, "A acceleration": 1,
        "B travel": 1, "B velocity": 1, "B acceleration": 1,
        "lead window": 1, "tilt window": 1, "interference": 1,
    }


def test_violation_counter_counts_the_pivot_axes():
    """The AB head turns rotary motion into motion of the pivot, X Y Z = CL + pivot T (METHODS
    section 1): with linear limits the kinks of the hand-made program bind on X Y Z too. The
    expected counts come from the test's own X Y Z and differences."""
    lin = {"vmax": 30.0, "amax": 2000.0}
    sm, program, A, B = _counter_setup(lin)
    n = len(A)
    with sm:
        q = RotaryValues.of(sm.nominal.rotary, A, B)
        r = sm._result("none", q, delta=np.full(n, 0.5), lift=np.zeros(n), unreachable=np.zeros(0, int),
                       runtime=0.0)
    T = np.column_stack([np.sin(B), -np.sin(A) * np.cos(B), np.cos(A) * np.cos(B)])
    pivot = tomllib.loads(DEFAULT_MACHINE_TOML)["machine"]["pivot"]
    xyz = r.cl + pivot * T
    rows = program.path.rows
    want = {}
    for k, name in enumerate("XYZ"):
        v_count = a_count = 0
        for row in np.unique(rows):
            q = xyz[rows == row, k]
            v = np.diff(q) / H
            v_count += int(np.sum(np.abs(v) > lin["vmax"] * (1 + 1e-9)))
            a_count += int(np.sum(np.abs(np.diff(v) / H) > lin["amax"] * (1 + 1e-9)))
        want.update({f"{name} travel": 0, f"{name} velocity": v_count, f"{name} acceleration": a_count})
    got = {k: v for k, v in r.metrics.violations.items() if k[0] in "XYZ"}
    assert got == want
    assert sum(want.values()) >= 2  # the limits were chosen to bind: the test counts something


def test_violation_counter_is_zero_just_inside_every_limit():
    """The same program pulled 2% inside every bound (velocities and accelerations scaled, the
    peaks of the parabolas moved inside): nothing is counted."""
    sm, program, _, _ = _counter_setup()
    rows = _violating_rows()
    rows[0] = (rows[0][0] + 0.03, rows[0][1])
    rows[1] = (rows[1][0], rows[1][1] - 0.03)
    rows[2] = (_from_velocities(0.0, [0, 6.5, 13, 19.6, 13, 6.5, 0]), rows[2][1])
    rows[3] = (_from_velocities(0.0, [0, 0, 0, 9.8, 9.8, 9.8]), rows[3][1])
    rows[4] = (rows[4][0], _from_velocities(10.0, [0, 6.5, 13, 19.6, 13, 6.5, 0]))
    rows[5] = (rows[5][0], _from_velocities(10.0, [0, 0, 0, 9.8, 9.8, 9.8]))
    rows[6] = (rows[6][0], rows[6][1] + 0.03)
    rows[7] = (rows[7][0] + 0.03, rows[7][1])
    A = np.radians(np.concatenate([r[0] for r in rows]))
    B = np.radians(np.concatenate([r[1] for r in rows]))
    n = len(A)
    with sm:
        q = RotaryValues.of(sm.nominal.rotary, A, B)
        r = sm._result("none", q, delta=np.full(n, -0.9e-3), lift=np.zeros(n), unreachable=np.zeros(0, int),
                       runtime=0.0)
    assert sum(r.metrics.violations.values()) == 0, r.metrics.violations


# ----------------------------------------------------------------------------------------------
# ballbar trilateration (METHODS section 5)
def test_trilaterate_closed_form_point_below_the_triangle():
    """Three points on a horizontal circle of radius 75 mm, 120 deg apart, 150 sin(30 deg) = 75
    mm above a point Q: the bar length is 150 mm to each; trilateration gives Q (the solution on
    the lower side), also for a tilted, shifted triangle; a Q above the plane comes back mirrored
    below it."""
    from camsmooth.machine.calibration import trilaterate

    L0 = 150.0
    rho, hz = L0 * math.cos(math.radians(30.0)), L0 * math.sin(math.radians(30.0))
    phi = np.radians([10.0, 130.0, 250.0])
    P = np.column_stack([rho * np.cos(phi), rho * np.sin(phi), np.full(3, hz)])
    Q = np.array([[0.0, 0.0, 0.0]])
    L = np.linalg.norm(P - Q, axis=1)
    np.testing.assert_allclose(L, L0, rtol=1e-14)
    got = trilaterate(P[0:1], P[1:2], P[2:3], L[0:1], L[1:2], L[2:3])
    np.testing.assert_allclose(got, Q, atol=1e-9)
    # a rotated (tilt below 90 deg) and shifted triangle, Q below it
    ang = math.radians(25.0)
    R = np.array([[1, 0, 0], [0, math.cos(ang), -math.sin(ang)], [0, math.sin(ang), math.cos(ang)]])
    off = np.array([3.0, -7.0, 11.0])
    P2, Q2 = P @ R.T + off, Q @ R.T + off
    L2 = np.linalg.norm(P2 - Q2, axis=1)
    got = trilaterate(P2[0:1], P2[1:2], P2[2:3], L2[0:1], L2[1:2], L2[2:3])
    np.testing.assert_allclose(got, Q2, atol=1e-9)
    # Q above the triangle's plane: its mirror image in the plane (the lower side) is returned
    Qa = np.array([[0.0, 0.0, 2 * hz]])
    La = np.linalg.norm(P - Qa, axis=1)
    np.testing.assert_allclose(trilaterate(P[0:1], P[1:2], P[2:3], La[0:1], La[1:2], La[2:3]), Q, atol=1e-9)


def _ballbar_data(elements: np.ndarray, angles_deg=(30.0, 60.0), L0: float = 150.0, step: float = 10.0,
                  noise: float = 1e-7):
    """Ballbar readings from the closed-form geometry of METHODS section 5: the table ball at the
    origin, the commanded spindle ball at L0 (cos a cos phi, cos a sin phi, sin a); per set the
    spindle ball is displaced by (dx - exz H, dy - eyz H, dz), H = L0 (sin a - sin a_1) the height
    above the lowest cone's ball, so that exz = (dx2 - dx1) / D with D = L0 (sin a_1 - sin a_2)
    (METHODS: the drift at the upper ball minus the lower over D). Readings dL = |P + d| - L0."""
    from camsmooth.machine.calibration import BallbarData

    rng = np.random.default_rng(5)
    cols = {k: [] for k in ("t", "rpm", "angle", "direction", "phi", "L0", "dL")}
    a1 = math.radians(angles_deg[0])
    for k, (dx, dy, dz, exz, eyz) in enumerate(elements):
        for a_deg in angles_deg:
            a = math.radians(a_deg)
            Hc = L0 * (math.sin(a) - math.sin(a1))
            d = np.array([dx - exz * Hc, dy - eyz * Hc, dz])
            for direction in (1, -1):
                phi = np.radians(np.arange(0.0, 360.0, step))
                P = L0 * np.column_stack([np.cos(a) * np.cos(phi), np.cos(a) * np.sin(phi),
                                          np.full(len(phi), np.sin(a))])
                dL = np.linalg.norm(P + d, axis=1) - L0 + noise * rng.standard_normal(len(phi))
                m = len(phi)
                cols["t"] += [600.0 * k] * m
                cols["rpm"] += [0.0 if k == 0 else 5000.0] * m
                cols["angle"] += [a] * m
                cols["direction"] += [direction] * m
                cols["phi"] += list(phi)
                cols["L0"] += [L0] * m
                cols["dL"] += list(dL)
    return BallbarData(*(np.asarray(cols[k], float) for k in ("t", "rpm", "angle", "direction", "phi", "L0", "dL")))


def test_ballbar_trilateration_recovers_elements_with_their_signs():
    """Elements with distinct signs (um, urad): both the least squares and the paper's
    trilateration recover them, exz and eyz with the sign of METHODS section 5's definition."""
    from camsmooth.machine.calibration import calibrate_ballbar

    truth = np.array([[0.0, 0.0, 0.0, 0.0, 0.0],
                      [3e-3, -2e-3, 5e-3, 20e-6, -10e-6],
                      [-4e-3, 6e-3, 12e-3, -35e-6, 15e-6]])
    rep = calibrate_ballbar(_ballbar_data(truth))
    for key in ("trilateration", "trilateration_all", "elements"):
        got = rep.details[key]
        np.testing.assert_allclose(got[:, :3], truth[:, :3], atol=2e-6, err_msg=key)  # mm
        np.testing.assert_allclose(got[:, 3:], truth[:, 3:], atol=2e-7, err_msg=key)  # rad
