"""Identification of the error model from measurements: reference-sphere probing (rotary-axis
location and orientation errors), spindle-error-analyser data (spindle screw parameters) and the
ballbar cone test (spindle thermal elements). METHODS.md sections 2-5; model definitions in
camsmooth.machine.model.

Every calibration returns a CalibrationReport: fitted parameters with standard uncertainties
(from the Jacobian J at the solution and the residual variance s^2 = |r|^2 / (m - n):
cov = s^2 (J^T J)^-1), residual RMS before (errors at their base values) and after, the singular
values and condition number of the identification Jacobian (columns in um per um or um per urad),
and the parameters the data cannot determine. Those are found by a rank analysis before fitting
(greedy column selection in a stated priority on the column-normalised Jacobian: a parameter
whose column lies in the span of the ones already kept, to a relative singular value of 1e-7, is
not fitted but held at its base value, and the report names the combination it is confounded
with). Degenerate inputs (missing columns, NaN, duplicate poses, too few poses, an axis that
never turns, one ballbar angle, one ball height) raise InputError naming what cannot be
determined and why.

Measurement files (CSV, one header row, comma separated; units as in the whole project: mm, s,
degrees):

* probe: ``A, B`` (deg) and ``X, Y, Z`` (mm) the commanded axes at which the reference sphere was
  probed (the pivot placed so that the nominal tool tip sits at the sphere centre), ``sx, sy, sz``
  (mm) the sphere centre as the control computes it from the probed points with its NOMINAL
  kinematics. With the real tool tip at f(q) + g(A, B), the computed centre is c - g(A, B), c the
  true centre (an unknown, identified with the errors).
* spindle: ``theta`` (deg) spindle angle, ``ext`` (mm) the ball's distance beyond the collet's
  lower centre O4 (two or more distinct values: the two heights), ``x, y, z`` (mm) the measured
  ball centre in the spindle frame CS1 (SpindleScrew).
* ballbar: ``t`` (s) time of the measurement set, ``rpm`` spindle speed held from this set until
  the next one, ``angle`` (deg) bar elevation above the XY plane, ``dir`` +1 (counter-clockwise)
  or -1, ``phi`` (deg) position on the circle, ``L0`` (mm) bar length, ``dL`` (mm) reading minus
  L0. The first set (smallest t) is the cold reference (all thermal elements 0).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from camsmooth.errors import InputError
from camsmooth.io.atomic import atomic_path
from camsmooth.io.table import read_table as _read_table
from camsmooth.machine import fitting
from camsmooth.machine.kinematics import Machine, load_machine
from camsmooth.machine.model import (
    GEOMETRIC_PARAMETERS,
    ROTARY_BY_KIND,
    SPINDLE_THERMAL,
    ErrorModel,
    SpindleScrew,
    chain_axis_errors,
    first_order_response,
    machine_parameters,
    spindle_forward,
    spoken_machine,
)

RANK_TOL = fitting.RANK_TOL

PROBE_COLUMNS = ("A", "B", "X", "Y", "Z", "sx", "sy", "sz")
SPINDLE_COLUMNS = ("theta", "ext", "x", "y", "z")
BALLBAR_COLUMNS = ("t", "rpm", "angle", "dir", "phi", "L0", "dL")

# Priority of the probing parameters when some are confounded (kept first = fitted): the rotary
# axis lines first, as a probing kinematics cycle identifies them; spindle offsets, tilts and the
# tool length are the ones a single probe cannot separate from them.
PROBE_PRIORITY = ("EY0A", "EZ0A", "EB0A", "EC0A", "EX0B", "EZ0B", "EA0B", "EC0B", "EZ0T", "EX0S", "EY0S",
                  "EA0S", "EB0S")


# ----------------------------------------------------------------------------------------------
# data and files
@dataclass
class ProbeData:
    """Reference-sphere probing: A, B (rad), X, Y, Z (mm) commanded, centre (N,3) mm measured."""

    A: np.ndarray
    B: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray
    centre: np.ndarray
    source: str | None = None


@dataclass
class SpindleData:
    """Spindle-analyser data: theta (rad), ext (mm), ball (N,3) mm in CS1."""

    theta: np.ndarray
    ext: np.ndarray
    ball: np.ndarray
    source: str | None = None


@dataclass
class BallbarData:
    """Ballbar cone test: t (s), rpm, angle (rad), direction (+1/-1), phi (rad), L0 (mm), dL (mm)."""

    t: np.ndarray
    rpm: np.ndarray
    angle: np.ndarray
    direction: np.ndarray
    phi: np.ndarray
    L0: np.ndarray
    dL: np.ndarray
    source: str | None = None


def read_table(path: str | os.PathLike, columns: Sequence[str]) -> dict[str, np.ndarray]:
    """Read a numeric CSV with a header row; every listed column must be present and every cell
    a finite number (InputError naming file, row and column otherwise). Other columns are kept
    (as floats). Parsing and row numbering: camsmooth.io.table.read_table."""
    return dict(_read_table(path, columns, others="float", what="measurement file").columns)


def _write_csv(path: str | os.PathLike, columns: Sequence[str], data: Sequence[np.ndarray],
               formats: Sequence[str]) -> Path:
    path = Path(path)
    with atomic_path(path) as tmp:
        with open(tmp, "w", newline="") as fh:
            fh.write(",".join(columns) + "\n")
            rows = np.column_stack([np.asarray(d, float) for d in data])
            fmt = ",".join(formats)
            fh.writelines(fmt % tuple(r) + "\n" for r in rows)
    return path


def read_probe_csv(path: str | os.PathLike) -> ProbeData:
    """Read a probing file (module docstring); degrees are converted to radians."""
    d = read_table(path, PROBE_COLUMNS)
    return ProbeData(np.radians(d["A"]), np.radians(d["B"]), d["X"], d["Y"], d["Z"],
                     np.column_stack([d["sx"], d["sy"], d["sz"]]), str(path))


def write_probe_csv(path: str | os.PathLike, data: ProbeData) -> Path:
    return _write_csv(path, PROBE_COLUMNS, [np.degrees(data.A), np.degrees(data.B), data.X, data.Y, data.Z,
                                            *data.centre.T], ["%.9f"] * 2 + ["%.7f"] * 6)


def read_spindle_csv(path: str | os.PathLike) -> SpindleData:
    d = read_table(path, SPINDLE_COLUMNS)
    return SpindleData(np.radians(d["theta"]), d["ext"], np.column_stack([d["x"], d["y"], d["z"]]), str(path))


def write_spindle_csv(path: str | os.PathLike, data: SpindleData) -> Path:
    return _write_csv(path, SPINDLE_COLUMNS, [np.degrees(data.theta), data.ext, *data.ball.T],
                      ["%.9f", "%.6f", "%.8f", "%.8f", "%.8f"])


def read_ballbar_csv(path: str | os.PathLike) -> BallbarData:
    d = read_table(path, BALLBAR_COLUMNS)
    bad = np.flatnonzero(np.abs(d["dir"]) != 1.0)
    if bad.size:
        raise InputError("dir must be +1 or -1", file=str(path), row=int(bad[0]) + 1, column="dir")
    return BallbarData(d["t"], d["rpm"], np.radians(d["angle"]), d["dir"].astype(int), np.radians(d["phi"]),
                       d["L0"], d["dL"], str(path))


def write_ballbar_csv(path: str | os.PathLike, data: BallbarData) -> Path:
    return _write_csv(path, BALLBAR_COLUMNS, [data.t, data.rpm, np.degrees(data.angle), data.direction,
                                              np.degrees(data.phi), data.L0, data.dL],
                      ["%.3f", "%.1f", "%.6f", "%d", "%.6f", "%.6f", "%.7f"])


# ----------------------------------------------------------------------------------------------
# report
@dataclass
class CalibrationReport:
    """What a calibration found. parameters / uncertainties: fitted values and standard
    uncertainties in the code's units (``units``: mm, rad, s, 1). unidentifiable: parameter ->
    why the data cannot determine it (held at its base value). rms_before / rms_after: residual
    RMS (``residual_unit``) with the calibrated errors at their base values / fitted.
    singular_values, condition_number: of the identification Jacobian of the fitted parameters
    (columns scaled to um and urad). model: the base model updated with the fit. details:
    kind-specific extras (nuisance parameters, PSO comparison, per-time thermal tables, ...)."""

    kind: str
    model: ErrorModel
    parameters: dict[str, float]
    uncertainties: dict[str, float]
    units: dict[str, str]
    unidentifiable: dict[str, str]
    rms_before: float
    rms_after: float
    singular_values: np.ndarray
    condition_number: float
    n_observations: int
    residual_unit: str = "mm"
    details: dict[str, Any] = field(default_factory=dict)

    def summary(self) -> str:
        """Human-readable multi-line summary (small lengths in um, small angles in urad, phases
        in deg)."""
        lines = [f"calibration: {self.kind}  ({self.n_observations} observations)"]
        lines.append(f"  residual RMS before {_fmt_res(self.rms_before, self.residual_unit)}, "
                     f"after {_fmt_res(self.rms_after, self.residual_unit)}")
        lines.append(f"  {'parameter':<12} {'value':>14} {'':<10}   std. uncertainty")
        for k, v in self.parameters.items():
            u = self.uncertainties.get(k, float("nan"))
            val, unc, unit = _display(v, u, self.units.get(k, ""), k)
            lines.append(f"  {k:<12} {val:>14.6g} {unit:<10} +- {unc:.3g}")
        s = self.singular_values
        if len(s) <= 12:
            sv = "[" + ", ".join(f"{x:.3g}" for x in s) + "]"
        else:
            sv = f"({len(s)} values, {s[0]:.3g} ... {s[-1]:.3g})"
        lines.append(f"  identification Jacobian (um per um / urad): singular values {sv}, condition number "
                     f"{self.condition_number:.3g}")
        if self.unidentifiable:
            lines.append("  not determinable from these data (not fitted):")
            for k, why in self.unidentifiable.items():
                lines.append(f"    {k}: {why}")
        return "\n".join(lines)


def _display(v: float, u: float, unit: str, name: str = "") -> tuple[float, float, str]:
    """Value and uncertainty in display units: um, urad, deg for phases, ppm for direction cosines."""
    if name.startswith("theta"):
        return math.degrees(v), math.degrees(u), "deg"
    if unit == "mm":
        return v * 1e3, u * 1e3, "um"
    if unit == "rad":
        return v * 1e6, u * 1e6, "urad"
    if unit == "1":
        return v * 1e6, u * 1e6, "ppm"
    if unit == "mm/1000rpm":
        return v * 1e3, u * 1e3, "um/krpm"
    if unit == "rad/1000rpm":
        return v * 1e6, u * 1e6, "urad/krpm"
    return v, u, unit


def _fmt_res(v: float, unit: str) -> str:
    return f"{v * 1e3:.4f} um" if unit == "mm" else f"{v:.4g} {unit}"


# ----------------------------------------------------------------------------------------------
# shared numerics (camsmooth.machine.fitting)
def _central_jacobian(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, h: float | np.ndarray
                      ) -> np.ndarray:
    return fitting.jacobian_t(fun, x, h, central=True).T


@dataclass
class _Fit:
    x: np.ndarray
    cov: np.ndarray
    rms: float
    J: np.ndarray
    nfev: int


def _lsq(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, h: float = 1e-3) -> _Fit:
    """Least squares by the shared Levenberg-Marquardt (central-difference Jacobian); covariance
    s^2 (J^T J)^-1. _Fit.nfev counts every model evaluation, the Jacobian's included."""
    calls = [0]

    def counted(x: np.ndarray) -> np.ndarray:
        calls[0] += 1
        return fun(x)

    res = fitting.levenberg_marquardt(counted, x0, step=h, central=True, rtol=1e-15, xtol=1e-12, max_iter=100,
                                      scale=np.ones(len(x0)))
    J = res.Jt.T
    m, n = J.shape
    cov = fitting.covariance(res.H, res.cost, m)
    return _Fit(res.x, cov, float(np.sqrt(res.cost / m)), J, calls[0])


select_identifiable = fitting.select_identifiable
_sv = fitting.singular_values


# ----------------------------------------------------------------------------------------------
# probing: rotary-axis location and orientation errors
def _scale(name: str) -> float:
    """Internal parameter scale: um for mm, urad for rad (keeps the problem well conditioned)."""
    return 1e-3 if GEOMETRIC_PARAMETERS[name][0] == "mm" else 1e-6


def validate_probe(data: ProbeData) -> None:
    """Bad-input checks on probing data (InputError naming rows and what cannot be determined)."""
    src = data.source
    arrays = [data.A, data.B, data.X, data.Y, data.Z, *np.asarray(data.centre).T]
    for name, a in zip(PROBE_COLUMNS, arrays, strict=True):
        bad = ~np.isfinite(np.asarray(a, float))
        if bad.any():
            raise InputError("not a finite number", file=src, row=int(np.argmax(bad)) + 1, column=name)
    n = len(data.A)
    poses = np.round(np.column_stack([np.degrees(data.A), np.degrees(data.B), data.X, data.Y, data.Z]), 9)
    _, first, inverse, counts = np.unique(poses, axis=0, return_index=True, return_inverse=True,
                                          return_counts=True)
    if np.any(counts > 1):
        rows = np.flatnonzero(counts[inverse.ravel()] > 1) + 1
        raise InputError(f"duplicate poses: rows {rows[:6].tolist()} repeat the same A, B, X, Y, Z (each "
                         "pose must be probed once; average repeated probings first)", file=src)
    for ax, vals, params in (("A", data.A, "EY0A, EZ0A, EB0A, EC0A"),
                             ("B", data.B, "EX0B, EZ0B, EA0B, EC0B")):
        if np.ptp(vals) < 1e-9:
            raise InputError(f"all {n} poses at {ax} = {np.degrees(vals[0]):.4g} deg: the {ax}-axis errors "
                             f"{params} cannot be determined (the {ax} axis never turns, so its errors "
                             "look like a shift of the sphere); probe at three or more distinct "
                             f"{ax} angles", file=src)


def probe_offsets(model: ErrorModel, machine: Machine, data: ProbeData) -> np.ndarray:
    """g = real tool tip - nominal tool tip (N,3) mm at the probing poses."""
    from camsmooth.machine.model import frame_tip_axis

    q = {"A": np.asarray(data.A, float), "B": np.asarray(data.B, float), "X": np.asarray(data.X, float),
         "Y": np.asarray(data.Y, float), "Z": np.asarray(data.Z, float)}
    real = frame_tip_axis(model.real_frame(machine, q), len(data.A))[0]
    nominal = machine.tool_pose_np(data.A, data.B, data.X, data.Y, data.Z)[0]
    return real - nominal


def _probe_residual(x: np.ndarray, names: Sequence[str], scales: np.ndarray, base: ErrorModel,
                    machine: Machine, data: ProbeData) -> np.ndarray:
    """Residual (um) of measured minus modelled sphere centres; x = parameters in um / urad, then
    the sphere centre in um."""
    geo = dict(base.geometric)
    geo.update({p: float(v) for p, v in zip(names, x[:-3] * scales, strict=True)})
    g = probe_offsets(replace(base, geometric=geo), machine, data)
    return ((data.centre - (x[-3:] * 1e-3 - g)) * 1e3).ravel()


@dataclass(frozen=True)
class _SphereFit:
    """What ``_fit_with_sphere`` found: the fitted parameters' names, the fit (scaled; the
    sphere's three coordinates last, um), its standard deviations, the residual with only the
    sphere fitted (um), the Jacobian on the given poses, every candidate's name, the fitted values
    and uncertainties in the parameters' units, and the parameters no run of this kind can
    separate (name -> why, and the value they are held at)."""

    names: list[str]
    fit: _Fit
    sd: np.ndarray
    r_before: np.ndarray
    J_all: np.ndarray
    all_names: list[str]
    params: dict[str, float]
    unc: dict[str, float]
    unidentifiable: dict[str, str]


def _fit_with_sphere(residual: Callable[[np.ndarray, Sequence[str], np.ndarray, Any], np.ndarray],
                     names: Sequence[str], scales: np.ndarray, x_base: np.ndarray, c0: np.ndarray, ref: Any,
                     data: Any, n_pose: int, sphere: str, spread: str, axes: str, base: ErrorModel) -> _SphereFit:
    """The fit of a run that measures one sphere (probing, R-test): candidate parameters ``names``
    (scaled by ``scales``, starting at ``x_base``) and the sphere's three coordinates (um, from
    ``c0``) as a nuisance. Rank analysis (camsmooth.machine.fitting.select_identifiable) on the
    rich reference run ``ref`` names what no such run can separate (reported, held at the base);
    a further loss on the given poses is an InputError naming it and the poses' ``spread``; then
    bounded Levenberg-Marquardt (central differences) and the covariance. residual(x, names,
    scales, data) -> residual (um)."""
    names = list(names)
    x0 = np.concatenate([x_base, c0])
    all_names = names + ["sphere_x", "sphere_y", "sphere_z"]
    units = [{"mm": "um", "rad": "urad"}[GEOMETRIC_PARAMETERS[p][0]] for p in names] + ["um"] * 3
    nuisance = [len(names), len(names) + 1, len(names) + 2]
    # Structural analysis on a rich reference pose set: what no run of one sphere can separate
    # (reported, not fitted). Then the same analysis on the given poses: any further loss is the
    # data's fault and is an error, never a silently reduced fit.
    J_ref = _central_jacobian(lambda x: residual(x, names, scales, ref), x0, 1e-3)
    kept_ref, dropped = select_identifiable(J_ref, all_names, keep=nuisance, units=units)
    candidates = [names[i] for i in sorted(kept_ref) if i < len(names)]
    n_unknown = len(candidates) + 3
    if 3 * n_pose <= n_unknown:
        raise InputError(f"too few poses: {n_pose} poses give {3 * n_pose} equations for {n_unknown} "
                         f"unknowns ({', '.join(candidates)} and the {sphere}); at least "
                         f"{n_unknown // 3 + 1} distinct poses are needed", file=data.source)
    J_all = _central_jacobian(lambda x: residual(x, names, scales, data), x0, 1e-3)
    kept, dropped_data = select_identifiable(J_all, all_names, keep=nuisance, units=units)
    extra = {all_names[i]: why for i, why in dropped_data.items() if i not in dropped}
    if extra:
        why = "; ".join(f"{k}: {v}" for k, v in extra.items())
        raise InputError(f"these {n_pose} poses ({spread}) cannot determine {', '.join(extra)} ({why}); measure at "
                         f"more, and more varied, {axes} angles", file=data.source)
    idx = sorted(i for i in kept if i < len(names))
    fit_names = [names[i] for i in idx]
    fit_scales = scales[idx]

    def fun(x: np.ndarray) -> np.ndarray:
        return residual(x, fit_names, fit_scales, data)

    r_before = fitting.levenberg_marquardt(
        lambda c: fun(np.concatenate([x_base[idx], c])), c0, step=1e-3, central=True, rtol=1e-15, xtol=1e-12,
        scale=np.ones(3)).r
    fit = _lsq(fun, np.concatenate([x_base[idx], c0]))
    sd = np.sqrt(np.diag(fit.cov))
    unident = {}
    for i, why in sorted(dropped.items()):
        if i < len(names):
            held, _, unit = _display(base.get(names[i]), 0.0, GEOMETRIC_PARAMETERS[names[i]][0])
            unident[names[i]] = f"{why}; held at {held:g} {unit}"
    return _SphereFit(fit_names, fit, sd, r_before, J_all, all_names,
                      {p: float(v) for p, v in zip(fit_names, fit.x[:-3] * fit_scales, strict=True)},
                      {p: float(v) for p, v in zip(fit_names, sd[:-3] * fit_scales, strict=True)}, unident)


def calibrate_probe(data: ProbeData | str | os.PathLike, machine: Machine | None = None,
                    base: ErrorModel | None = None, parameters: Sequence[str] | None = None
                    ) -> CalibrationReport:
    """Identify geometric errors from reference-sphere probing (module docstring for the data).

    parameters: the geometric parameters to try (default: all, in PROBE_PRIORITY order, which is
    also the order in which confounded parameters are resolved: later ones are dropped). The
    sphere centre c is identified alongside (details['sphere_centre'], mm). base: model whose
    other parts (spindle screw, thermal, parameters not fitted) are kept; None = no errors.
    """
    if not isinstance(data, ProbeData):
        data = read_probe_csv(data)
    machine = machine or load_machine()
    if machine.description.preset != "AB-head":
        raise InputError(f"probe calibration (columns A, B) is for an AB-head machine; the machine is "
                         f"{machine.describe()}: calibrate its rotary axes from an R-test (calibrate_rtest, "
                         f"`camsmooth calibrate rtest`)", file=data.source)
    base = base or ErrorModel()
    validate_probe(data)
    names = [p for p in (parameters or PROBE_PRIORITY)]
    unknown = [p for p in names if p not in GEOMETRIC_PARAMETERS]
    if unknown:
        raise InputError(f"unknown geometric parameter(s) {unknown}")
    scales = np.array([_scale(p) for p in names])
    n_pose = len(data.A)

    x_base = np.array([base.get(p) for p in names]) / scales
    c0 = np.mean(data.centre + probe_offsets(base, machine, data), axis=0)
    grid = np.radians(np.linspace(-90.0, 90.0, 7))
    rA, rB = (v.ravel() for v in np.meshgrid(grid, grid, indexing="ij"))
    zero = np.zeros_like(rA)
    ref = ProbeData(rA, rB, zero, zero, zero, np.zeros((len(rA), 3)))
    nA, nB = len(np.unique(np.round(data.A, 9))), len(np.unique(np.round(data.B, 9)))
    sf = _fit_with_sphere(lambda x, nm, sc, d: _probe_residual(x, nm, sc, base, machine, d), names, scales, x_base,
                          c0 * 1e3, ref, data, n_pose, "sphere centre",
                          f"A at {nA} and B at {nB} distinct angles", "A and B", base)
    fit_names, fit, sd, r_before, J_all, all_names = sf.names, sf.fit, sf.sd, sf.r_before, sf.J_all, sf.all_names
    params, unc, unident = sf.params, sf.unc, sf.unidentifiable
    geo = dict(base.geometric)
    geo.update(params)
    sv, cond = _sv(fit.J)
    meta = dict(base.meta)
    meta["probe"] = {"source": data.source, "poses": n_pose, "fitted": fit_names,
                     "unidentifiable": sorted(unident)}
    model = replace(base, geometric=geo, meta=meta)
    return CalibrationReport(
        "probe", model, params, unc, {p: GEOMETRIC_PARAMETERS[p][0] for p in fit_names}, unident,
        float(np.sqrt(np.mean(r_before ** 2))) * 1e-3, fit.rms * 1e-3, sv, cond, 3 * n_pose,
        details={"sphere_centre": fit.x[-3:] * 1e-3, "sphere_centre_uncertainty": sd[-3:] * 1e-3,
                 "singular_values_all": _sv(J_all)[0], "candidates": all_names})


# ----------------------------------------------------------------------------------------------
# R-test: rotary-axis location errors of any machine kind (tables included)
#: the R-test file's columns after the two rotary axes (named by the machine: A, C on an AC table)
RTEST_TAIL = ("X", "Y", "Z", "dx", "dy", "dz")
#: Priority of the R-test parameters per machine kind (kept first = fitted): the rotary axis lines
#: of the kind (ROTARY_BY_KIND), then the nest's offset from the nominal tool tip (EX0S, EY0S,
#: EZ0T: a constant displacement in the spindle frame) and, on a machine with a head, the spindle
#: tilt about the pivot (EA0S, EB0S: at the tip a displacement of pivot x angle). With one sphere
#: these are confounded with the sphere position and the axis offsets (the rank analysis names
#: the combinations). On a table-table machine the spindle tilt turns the spindle about the tool
#: tip and has no first-order effect on a point measurement, so it is not tried there.
def rtest_priority(machine: Machine) -> tuple[str, ...]:
    """The R-test parameters of ``machine`` in priority order (the comment above): its rotary axis
    lines (ROTARY_BY_KIND of its preset), the nest's offset, and the spindle tilt where a head
    carries the spindle."""
    preset = machine.description.preset
    own = tuple(ROTARY_BY_KIND[preset]) if preset is not None else tuple(
        n for n, e in chain_axis_errors(machine).items() if e.what == "location") + tuple(
        n for n, e in chain_axis_errors(machine).items() if e.what == "orientation")
    return own + ("EX0S", "EY0S", "EZ0T") + (("EA0S", "EB0S") if machine.has_head else ())


@dataclass
class RTestData:
    """R-test measurement (a precision sphere fixed on the table, a nest of three displacement
    sensors in the spindle): q1, q2 (rad) the commanded rotary axes in ``Machine.rotary`` order
    (A, C on an AC table), X, Y, Z (mm) the commanded linear axes (the nominal tool tip, the
    nest's reference point, kept on the nominal sphere centre: tool-centre-point motion),
    d (N,3) mm the measured displacement of the sphere centre from the nest's reference point,
    in the spindle frame (the machine's X, Y, Z directions on a table machine)."""

    q1: np.ndarray
    q2: np.ndarray
    X: np.ndarray
    Y: np.ndarray
    Z: np.ndarray
    d: np.ndarray
    source: str | None = None


def rtest_columns(machine: Machine) -> tuple[str, ...]:
    """The R-test CSV columns for a machine: its two rotary axes (deg), X, Y, Z (mm) and the
    measured displacement dx, dy, dz (mm, spindle frame)."""
    return (*machine.rotary, *RTEST_TAIL)


def read_rtest_csv(path: str | os.PathLike, machine: Machine) -> RTestData:
    """Read an R-test file (``rtest_columns``); degrees are converted to radians."""
    r1, r2 = machine.rotary
    d = read_table(path, rtest_columns(machine))
    return RTestData(np.radians(d[r1]), np.radians(d[r2]), d["X"], d["Y"], d["Z"],
                     np.column_stack([d["dx"], d["dy"], d["dz"]]), str(path))


def write_rtest_csv(path: str | os.PathLike, data: RTestData, machine: Machine) -> Path:
    """Write an R-test file (``rtest_columns`` of the machine)."""
    return _write_csv(path, rtest_columns(machine), [np.degrees(data.q1), np.degrees(data.q2), data.X, data.Y,
                                                     data.Z, *data.d.T], ["%.9f"] * 2 + ["%.7f"] * 3 + ["%.8f"] * 3)


def rtest_displacement(model: ErrorModel, machine: Machine, data: RTestData, sphere: Sequence[float]
                       ) -> np.ndarray:
    """What an R-test reads (N,3) mm: the sphere centre ``sphere`` (mm, workpiece frame, i.e. on
    the table) in the real tool frame at the data's commanded poses, d = R^T (s - p) with (R, p)
    the real tool-tip frame (``ErrorModel.real_frame``): the sphere seen from the nest, along the
    spindle's x, y, z."""
    r1, r2 = machine.rotary
    n = len(data.q1)
    q = {r1: np.asarray(data.q1, float), r2: np.asarray(data.q2, float), "X": np.asarray(data.X, float),
         "Y": np.asarray(data.Y, float), "Z": np.asarray(data.Z, float)}
    T = model.real_frame(machine, q).to_numpy(n)
    rel = np.asarray(sphere, float)[None, :] - T[:, :3, 3]
    return np.einsum("nji,nj->ni", T[:, :3, :3], rel)


def validate_rtest(data: RTestData, machine: Machine) -> None:
    """Bad-input checks on R-test data (InputError naming rows and what cannot be determined)."""
    src = data.source
    cols = rtest_columns(machine)
    arrays = [data.q1, data.q2, data.X, data.Y, data.Z, *np.asarray(data.d).T]
    for name, a in zip(cols, arrays, strict=True):
        bad = ~np.isfinite(np.asarray(a, float))
        if bad.any():
            raise InputError("not a finite number", file=src, row=int(np.argmax(bad)) + 1, column=name)
    poses = np.round(np.column_stack([np.degrees(data.q1), np.degrees(data.q2), data.X, data.Y, data.Z]), 9)
    _, inverse, counts = np.unique(poses, axis=0, return_inverse=True, return_counts=True)
    if np.any(counts > 1):
        rows = np.flatnonzero(counts[inverse.ravel()] > 1) + 1
        raise InputError(f"duplicate poses: rows {rows[:6].tolist()} repeat the same {', '.join(cols[:5])} (each "
                         "pose must be measured once; average repeated readings first)", file=src)
    own = rtest_priority(machine)
    for k, (ax, vals) in enumerate(zip(machine.rotary, (data.q1, data.q2), strict=True)):
        if len(np.unique(np.round(vals, 9))) < 3:
            params = ", ".join(n for n in own if n.endswith(ax))
            seen = ", ".join(f"{v:g}" for v in np.unique(np.round(np.degrees(vals), 6)))
            raise InputError(f"the {ax} axis is at fewer than three distinct angles ({seen} deg): "
                             f"the {ax}-axis errors {params} cannot be determined (a line needs the axis to "
                             f"turn through three or more angles); measure at more {ax} angles", file=src,
                             column=cols[k])


def reference_rtest_poses(machine: Machine, n_tilt: int = 7, n_outer: int = 8, max_deg: float = 90.0
                          ) -> tuple[np.ndarray, np.ndarray]:
    """A rich grid of (q1, q2) rad in ``machine.rotary`` order within the travel: the tilt (or A
    on the AB head) at n_tilt angles over +-max_deg clipped to its travel, the other axis at
    n_outer angles (a full turn for a C axis, +-max_deg otherwise). Used for the structural
    identifiability analysis and as the default R-test poses."""
    lims = machine.rotary_limits()
    axes = []
    for name, lim, n in zip(machine.rotary, lims, (n_tilt, n_outer), strict=True):
        if name == "C":
            lo, hi = max(lim.min, -np.pi), min(lim.max, np.pi)
            full = hi - lo >= 2 * np.pi - 1e-9
            axes.append(np.linspace(lo, hi, n, endpoint=not full))
        else:
            lo, hi = max(lim.min, -np.radians(max_deg)), min(lim.max, np.radians(max_deg))
            axes.append(np.linspace(lo, hi, n))
    q1, q2 = (v.ravel() for v in np.meshgrid(*axes, indexing="ij"))
    return q1, q2


def _rtest_residual(x: np.ndarray, names: Sequence[str], scales: np.ndarray, base: ErrorModel,
                    machine: Machine, data: RTestData, sphere0: np.ndarray) -> np.ndarray:
    """Residual (um) of measured minus modelled R-test readings; x = parameters in um / urad,
    then the sphere's offset from sphere0 in um."""
    geo = dict(base.geometric)
    geo.update({p: float(v) for p, v in zip(names, x[:-3] * scales, strict=True)})
    model = replace(base, geometric=geo, kind=machine.description.preset)
    return ((data.d - rtest_displacement(model, machine, data, sphere0 + x[-3:] * 1e-3)) * 1e3).ravel()


def calibrate_rtest(data: RTestData | str | os.PathLike, machine: Machine | None = None,
                    base: ErrorModel | None = None, parameters: Sequence[str] | None = None
                    ) -> CalibrationReport:
    """Identify the rotary-axis location errors of any machine kind from an R-test (RTestData;
    METHODS section 3.1): the axis lines of the kind (ROTARY_BY_KIND) and the nest's offset, with
    the sphere's position on the table (details['sphere'], mm, workpiece frame; nominally the
    commanded tool tip) as a nuisance. The shared toolkit (camsmooth.machine.fitting): rank
    analysis on a rich reference pose set (``reference_rtest_poses``) names what no R-test on
    one sphere can separate (reported, held at the base value); a further loss on the given poses
    is an InputError; then bounded Levenberg-Marquardt (central differences) with the covariance
    s^2 (J^T J)^-1. parameters: the ones to try (default ``rtest_priority(machine)``, also the order in
    which confounded parameters are resolved: later ones are dropped). The result model states
    the machine kind (ErrorModel.kind)."""
    machine = machine or load_machine()
    if not isinstance(data, RTestData):
        data = read_rtest_csv(data, machine)
    base = (base or ErrorModel())
    base.check_machine(machine)
    base = replace(base, kind=machine.description.preset)
    validate_rtest(data, machine)
    names = list(parameters or rtest_priority(machine))
    allowed = machine_parameters(machine)
    wrong = [p for p in names if p not in allowed]
    if wrong:
        raise InputError(f"parameter(s) {', '.join(wrong)} are not errors of {spoken_machine(machine)} "
                         f"(its parameters: {', '.join(allowed)})")
    scales = np.array([_scale(p) for p in names])
    n_pose = len(data.q1)
    nominal_tip = machine.tool_pose_np(data.q1, data.q2, data.X, data.Y, data.Z)[0]
    sphere0 = nominal_tip.mean(axis=0)
    x_base = np.array([base.get(p) for p in names]) / scales
    rq1, rq2 = reference_rtest_poses(machine)
    rxyz = machine.linear_axes(np.broadcast_to(sphere0, (len(rq1), 3)), rq1, rq2)
    ref = RTestData(rq1, rq2, rxyz[:, 0], rxyz[:, 1], rxyz[:, 2], np.zeros((len(rq1), 3)))
    spread = " and ".join(f"{ax} at {len(np.unique(np.round(v, 9)))}"
                          for ax, v in zip(machine.rotary, (data.q1, data.q2), strict=True))
    sf = _fit_with_sphere(lambda x, nm, sc, d: _rtest_residual(x, nm, sc, base, machine, d, sphere0), names, scales,
                          x_base, np.zeros(3), ref, data, n_pose, "sphere position", f"{spread} distinct angles",
                          " and ".join(machine.rotary), base)
    fit_names, fit, sd, r_before, J_all, all_names = sf.names, sf.fit, sf.sd, sf.r_before, sf.J_all, sf.all_names
    params, unc, unident = sf.params, sf.unc, sf.unidentifiable
    geo = dict(base.geometric)
    geo.update(params)
    sv, cond = _sv(fit.J)
    meta = dict(base.meta)
    meta["rtest"] = {"source": data.source, "poses": n_pose, "machine_kind": machine.kind, "fitted": fit_names,
                     "unidentifiable": sorted(unident)}
    model = replace(base, geometric=geo, meta=meta)
    return CalibrationReport(
        "rtest", model, params, unc, {p: GEOMETRIC_PARAMETERS[p][0] for p in fit_names}, unident,
        float(np.sqrt(np.mean(r_before ** 2))) * 1e-3, fit.rms * 1e-3, sv, cond, 3 * n_pose,
        details={"sphere": sphere0 + fit.x[-3:] * 1e-3, "sphere_uncertainty": sd[-3:] * 1e-3,
                 "sphere_nominal": sphere0, "singular_values_all": _sv(J_all)[0], "candidates": all_names,
                 "machine_kind": machine.kind})


# ----------------------------------------------------------------------------------------------
# spindle screw
SPINDLE_GROUPS = (("cos_alpha",), ("cos_beta",), ("delta3",), ("a1", "b1"), ("a2", "b2"), ("rho1",),
                  ("rho2",), ("h1",))
_SPINDLE_SCALE = {"cos_alpha": 1e-6, "cos_beta": 1e-6, "delta3": 1e-3, "a1": 1e-3, "b1": 1e-3, "a2": 1e-3,
                  "b2": 1e-3, "rho1": 1e-3, "rho2": 1e-3, "h1": 1.0}
_SPINDLE_UNITS = {"r1": "mm", "theta1": "rad", "r2": "mm", "theta2": "rad", "cos_alpha": "1", "cos_beta": "1",
                  "delta3": "mm", "rho1": "mm", "rho2": "mm", "h1": "mm"}


def validate_spindle(data: SpindleData) -> None:
    src = data.source
    columns = (("theta", data.theta), ("ext", data.ext), *zip("xyz", np.asarray(data.ball).T, strict=True))
    for name, a in columns:
        bad = ~np.isfinite(np.asarray(a, float))
        if bad.any():
            raise InputError("not a finite number", file=src, row=int(np.argmax(bad)) + 1, column=name)
    exts = np.unique(np.round(data.ext, 9))
    if len(exts) < 2:
        raise InputError(f"all samples at one ball height (ext = {exts[0]:g} mm): the upper and lower "
                         "bearing runouts r1, theta1, r2, theta2 cannot be separated (one circle shows only "
                         "their combined effect); measure the ball at two heights", file=src)
    key = np.round(np.column_stack([np.degrees(data.theta), data.ext]), 9)
    _, inverse, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    if np.any(counts > 1):
        rows = np.flatnonzero(counts[inverse.ravel()] > 1) + 1
        raise InputError(f"duplicate samples: rows {rows[:6].tolist()} repeat the same theta and ext",
                         file=src)
    for e in exts:
        th = np.mod(data.theta[np.isclose(data.ext, e, atol=1e-9)], 2 * np.pi)
        if len(th) < 4 or _max_gap(th) > np.pi:
            raise InputError(f"ball height ext = {e:g} mm: the samples do not go round the spindle (at "
                             "least 4 angles, no gap above 180 deg): the runout phase cannot be determined",
                             file=src)


def _max_gap(angles: np.ndarray) -> float:
    a = np.sort(angles)
    return float(np.max(np.diff(np.concatenate([a, [a[0] + 2 * np.pi]]))))


def _spindle_params(base: SpindleScrew) -> dict[str, float]:
    return {"cos_alpha": base.cos_alpha, "cos_beta": base.cos_beta, "delta3": base.delta3,
            "a1": base.r1 * math.cos(base.theta1), "b1": base.r1 * math.sin(base.theta1),
            "a2": base.r2 * math.cos(base.theta2), "b2": base.r2 * math.sin(base.theta2),
            "rho1": base.rho1, "rho2": base.rho2, "h1": base.h1}


def _spindle_model(p: Mapping[str, Any], geo: SpindleScrew, theta: np.ndarray, ext: np.ndarray) -> np.ndarray:
    return spindle_forward(p["a1"], p["b1"], p["a2"], p["b2"], p["cos_alpha"], p["cos_beta"], p["rho1"],
                           p["rho2"], p["delta3"], theta, ext, geo.h, geo.nose, geo.l3, p["h1"])[0]


def pso(fun: Callable[[np.ndarray], np.ndarray], lower: np.ndarray, upper: np.ndarray, *, particles: int = 40,
        iterations: int = 600, seed: int = 0, w: float = 0.6, c1: float = 1.49, c2: float = 1.49,
        periodic: np.ndarray | None = None) -> tuple[np.ndarray, float, int]:
    """A compact global-best particle swarm optimiser (inertia w, cognitive c1, social c2,
    velocities clamped to half the box). The defaults were tuned on the spindle problem (all of
    8 seeds reach the least-squares minimum; w = 0.72 with 60 x 400 failed 2 in 8). fun maps
    (P, n) positions to (P,) costs; positions are
    kept within [lower, upper] (``periodic`` dimensions wrap instead). Seeded, deterministic.
    Returns (best position, best cost, number of function evaluations)."""
    rng = np.random.default_rng(seed)
    lower, upper = np.asarray(lower, float), np.asarray(upper, float)
    span = upper - lower
    periodic = np.zeros(len(lower), bool) if periodic is None else np.asarray(periodic, bool)
    x = lower + rng.random((particles, len(lower))) * span
    v = (rng.random(x.shape) - 0.5) * span * 0.2
    cost = fun(x)
    pbest, pcost = x.copy(), cost.copy()
    g = int(np.argmin(pcost))
    for _ in range(iterations):
        r1, r2 = rng.random(x.shape), rng.random(x.shape)
        v = w * v + c1 * r1 * (pbest - x) + c2 * r2 * (pbest[g] - x)
        v = np.clip(v, -0.5 * span, 0.5 * span)
        x = x + v
        x = np.where(periodic, lower + np.mod(x - lower, span), np.clip(x, lower, upper))
        cost = fun(x)
        better = cost < pcost
        pbest[better], pcost[better] = x[better], cost[better]
        g = int(np.argmin(pcost))
    return pbest[g], float(pcost[g]), particles * (iterations + 1)


def calibrate_spindle(data: SpindleData | str | os.PathLike, base: ErrorModel | None = None, *,
                      pso_compare: bool = True, seed: int = 0) -> CalibrationReport:
    """Identify the spindle screw parameters (SpindleScrew) from analyser data (ball centres over
    spindle revolutions at two or more ball heights). Least squares (camsmooth.machine.fitting)
    on the identifiable parameters (runouts in Cartesian form internally, reported as r, theta);
    the collet offsets rho1, rho2 and collet length h1 are confounded with the bearing runouts
    (the data show only the tool line relative to the rotation axis) and are reported as such.
    With pso_compare, the same parameters are also fitted by a particle swarm (as in the
    source patent) and compared in details['pso'] (values, RMS, time, evaluations).
    The fixed geometry (h, nose, l3 and the starting values) comes from base.spindle (defaults
    of SpindleScrew when None)."""
    if not isinstance(data, SpindleData):
        data = read_spindle_csv(data)
    validate_spindle(data)
    base = base or ErrorModel()
    geo = base.spindle or SpindleScrew()
    p0 = _spindle_params(geo)
    names = list(_SPINDLE_SCALE)
    scales = np.array([_SPINDLE_SCALE[k] for k in names])
    theta, ext, ball = data.theta, np.asarray(data.ext, float), np.asarray(data.ball, float)

    def residual(x: np.ndarray, fit: Sequence[str]) -> np.ndarray:
        p = dict(p0)
        p.update({k: float(v) * _SPINDLE_SCALE[k] for k, v in zip(fit, x, strict=True)})
        return ((ball - _spindle_model(p, geo, theta, ext)) * 1e3).ravel()

    x_all = np.array([p0[k] for k in names]) / scales
    J_all = _central_jacobian(lambda x: residual(x, names), x_all, 1e-3)
    groups = [[names.index(k) for k in g] for g in SPINDLE_GROUPS]
    sp_units = {"cos_alpha": "ppm", "cos_beta": "ppm", "h1": "mm"}
    kept, dropped = select_identifiable(J_all, names, groups, units=[sp_units.get(k, "um") for k in names])
    fit_names = [names[i] for i in sorted(kept)]
    if ball.size <= len(fit_names):
        raise InputError(f"too few samples: {len(theta)} ball centres for {len(fit_names)} unknowns",
                         file=data.source)
    x0 = np.array([p0[k] for k in fit_names]) / np.array([_SPINDLE_SCALE[k] for k in fit_names])
    t0 = time.perf_counter()
    fit = _lsq(lambda x: residual(x, fit_names), x0)
    t_ls = time.perf_counter() - t0
    rms_before = float(np.sqrt(np.mean(residual(x0, fit_names) ** 2))) * 1e-3
    values = {k: float(v) * _SPINDLE_SCALE[k] for k, v in zip(fit_names, fit.x, strict=True)}
    cov = fit.cov * np.outer([_SPINDLE_SCALE[k] for k in fit_names], [_SPINDLE_SCALE[k] for k in fit_names])
    params, unc = _polar_report(values, cov, fit_names)
    new = dict(geo.as_dict())
    for k in ("r1", "theta1", "r2", "theta2", "cos_alpha", "cos_beta", "delta3", "rho1", "rho2", "h1"):
        if k in params:
            new[k] = params[k]
    spindle = SpindleScrew(**new)
    reasons = {}
    for i, why in sorted(dropped.items()):
        k = names[i]
        label = {"a1": "r1/theta1", "b1": "r1/theta1", "a2": "r2/theta2", "b2": "r2/theta2"}.get(k, k)
        text = why
        for short, long in (("a1", "r1 cos(theta1)"), ("b1", "r1 sin(theta1)"), ("a2", "r2 cos(theta2)"),
                            ("b2", "r2 sin(theta2)")):
            text = text.replace(f"of {short}", f"of {long}")
        held = (f"{getattr(geo, label):g} {SpindleScrew.UNITS[label]}" if hasattr(geo, label)
                else "its base value")
        reasons[label] = f"{text}; held at {held}"
    sv, cond = _sv(fit.J)
    details: dict[str, Any] = {"time_s": t_ls, "nfev": fit.nfev}
    if pso_compare:
        details["pso"] = _spindle_pso(p0, geo, theta, ext, ball, fit_names, seed, rms_scale=ball.size)
        details["ls"] = {"time_s": t_ls, "rms": fit.rms * 1e-3, "nfev": fit.nfev}
    meta = dict(base.meta)
    meta["spindle"] = {"source": data.source, "samples": len(theta), "fitted": list(params),
                       "unidentifiable": sorted(reasons)}
    model = replace(base, spindle=spindle, meta=meta)
    return CalibrationReport("spindle", model, params, unc, {k: _SPINDLE_UNITS[k] for k in params}, reasons,
                             rms_before, fit.rms * 1e-3, sv, cond, ball.size, details=details)


def _polar_report(values: Mapping[str, float], cov: np.ndarray, names: Sequence[str]
                  ) -> tuple[dict[str, float], dict[str, float]]:
    """Convert (a_i, b_i) runouts to (r_i, theta_i) with first-order propagated uncertainties."""
    idx = {k: i for i, k in enumerate(names)}
    params: dict[str, float] = {}
    unc: dict[str, float] = {}
    for k in ("cos_alpha", "cos_beta", "delta3", "rho1", "rho2", "h1"):
        if k in idx:
            params[k] = values[k]
            unc[k] = float(np.sqrt(cov[idx[k], idx[k]]))
    for n in ("1", "2"):
        a, b = f"a{n}", f"b{n}"
        if a not in idx:
            continue
        av, bv = values[a], values[b]
        r = math.hypot(av, bv)
        sub = cov[np.ix_([idx[a], idx[b]], [idx[a], idx[b]])]
        gr = np.array([av, bv]) / r if r > 0 else np.zeros(2)
        gt = np.array([-bv, av]) / r ** 2 if r > 0 else np.zeros(2)
        params[f"r{n}"], unc[f"r{n}"] = r, float(np.sqrt(gr @ sub @ gr))
        params[f"theta{n}"] = math.atan2(bv, av)
        unc[f"theta{n}"] = float(np.sqrt(gt @ sub @ gt)) if r > 0 else math.inf
    order = ("r1", "theta1", "r2", "theta2", "cos_alpha", "cos_beta", "delta3", "rho1", "rho2", "h1")
    return ({k: params[k] for k in order if k in params}, {k: unc[k] for k in order if k in unc})


def _spindle_pso(p0: Mapping[str, float], geo: SpindleScrew, theta: np.ndarray, ext: np.ndarray,
                 ball: np.ndarray, fit_names: Sequence[str], seed: int, rms_scale: int) -> dict[str, Any]:
    """The patent's PSO on the same identifiable parameters, in polar form (r, theta)."""
    polar = []
    for k in fit_names:
        if k in ("a1", "a2"):
            polar += [f"r{k[1]}", f"theta{k[1]}"]
        elif k not in ("b1", "b2"):
            polar.append(k)
    span = max(float(np.max(np.ptp(ball[:, :2], axis=0))), 1e-3)
    # r may go negative inside the swarm (= r at theta + pi): a hard bound at r = 0 traps particles
    bounds = {"r1": (-span, span), "r2": (-span, span), "theta1": (-math.pi, math.pi),
              "theta2": (-math.pi, math.pi), "cos_alpha": (-2e-3, 2e-3), "cos_beta": (-2e-3, 2e-3),
              "delta3": (-0.5, 0.5), "rho1": (-span, span), "rho2": (-span, span),
              "h1": (0.5 * geo.h1, 1.5 * geo.h1)}
    lo = np.array([bounds[k][0] for k in polar])
    hi = np.array([bounds[k][1] for k in polar])
    periodic = np.array([k.startswith("theta") for k in polar])

    def cost(X: np.ndarray) -> np.ndarray:
        p: dict[str, Any] = {k: np.full((len(X), 1), v) for k, v in p0.items()}
        cols = {k: X[:, i:i + 1] for i, k in enumerate(polar)}
        for n in ("1", "2"):
            if f"r{n}" in cols:
                p[f"a{n}"] = (cols[f"r{n}"] * np.cos(cols[f"theta{n}"]))[:, 0]
                p[f"b{n}"] = (cols[f"r{n}"] * np.sin(cols[f"theta{n}"]))[:, 0]
        for k in polar:
            if k not in ("r1", "r2", "theta1", "theta2"):
                p[k] = cols[k][:, 0]
        p = {k: (np.ravel(v) if np.ndim(v) else v) for k, v in p.items()}
        model = _spindle_model(p, geo, theta, ext)  # (P, M, 3)
        return np.sum((model - ball) ** 2, axis=(1, 2))

    t0 = time.perf_counter()
    best, best_cost, nfev = pso(cost, lo, hi, seed=seed, periodic=periodic)
    elapsed = time.perf_counter() - t0
    values = {k: float(v) for k, v in zip(polar, best, strict=True)}
    for n in ("1", "2"):
        if f"theta{n}" in values:
            r, th = values[f"r{n}"], values[f"theta{n}"]
            values[f"r{n}"] = abs(r)
            th = th + math.pi if r < 0 else th
            values[f"theta{n}"] = math.atan2(math.sin(th), math.cos(th))
    return {"parameters": values, "rms": math.sqrt(best_cost / rms_scale), "time_s": elapsed, "nfev": nfev}


# ----------------------------------------------------------------------------------------------
# ballbar cone test: spindle thermal elements
@dataclass
class _Circles:
    """Ballbar samples sorted by (set, cone, direction, phi) so that every circle is a contiguous
    block; geometry per cone."""

    times: np.ndarray       # (K,) set times, ascending
    rpm: np.ndarray         # (K,)
    set_idx: np.ndarray     # (M,)
    cone_idx: np.ndarray    # (M,)
    direction: np.ndarray   # (M,)
    phi_deg: np.ndarray     # (M,) in [0, 360)
    angles: np.ndarray      # (C,) rad, ascending
    heights: np.ndarray     # (C,) ball height above the reference (lowest) ball, mm
    P: np.ndarray           # (M, 3) commanded spindle-ball centre relative to the table ball
    L0: float
    dL: np.ndarray
    blocks: list[tuple[int, int, int, int]]  # (set, cone, start, end) of each (set, cone) block


def validate_ballbar(data: BallbarData) -> _Circles:
    """Bad-input checks on ballbar data and grouping into circles (InputError naming what cannot
    be determined and why)."""
    src = data.source
    cols = (data.t, data.rpm, data.angle, data.direction, data.phi, data.L0, data.dL)
    for name, a in zip(BALLBAR_COLUMNS, cols, strict=True):
        bad = ~np.isfinite(np.asarray(a, float))
        if bad.any():
            raise InputError("not a finite number", file=src, row=int(np.argmax(bad)) + 1, column=name)
    L0 = np.unique(np.round(data.L0, 9))
    if len(L0) != 1 or L0[0] <= 0:
        raise InputError(f"the bar length L0 must be one positive value, got {L0[:4].tolist()}", file=src,
                         column="L0")
    phi_deg = np.mod(np.round(np.degrees(data.phi), 7), 360.0)
    ang_deg = np.round(np.degrees(data.angle), 7)
    key = np.column_stack([data.t, ang_deg, data.direction, phi_deg])
    order = np.lexsort(key.T[::-1])
    key = key[order]
    dup = np.flatnonzero(np.all(key[1:] == key[:-1], axis=1))
    if dup.size:
        rows = sorted({int(order[dup[0]]) + 1, int(order[dup[0] + 1]) + 1})
        raise InputError(f"duplicate samples: rows {rows} repeat the same t, angle, dir, phi", file=src)
    angles_deg = np.unique(ang_deg)
    if len(angles_deg) < 2:
        raise InputError(f"all circles at one bar angle ({angles_deg[0]:g} deg): the spindle tilts exz, eyz "
                         "cannot be determined (they need two cone heights, METHODS section 5)", file=src)
    if np.any((angles_deg <= 0) | (angles_deg >= 90)):
        raise InputError(f"bar angles must be between 0 and 90 deg, got {angles_deg.tolist()}", file=src,
                         column="angle")
    times = np.unique(data.t)
    if len(times) < 2:
        raise InputError("only one measurement set: the thermal drift needs the cold reference set and at "
                         "least one later set", file=src, column="t")
    t, ang_s, dirs, phis = (key[:, i] for i in range(4))
    set_idx = np.searchsorted(times, t)
    cone_idx = np.searchsorted(angles_deg, ang_s)
    rpm_sorted = np.asarray(data.rpm, float)[order]
    rpm = np.zeros(len(times))
    blocks = []
    n_cones = len(angles_deg)
    starts = np.searchsorted(set_idx * n_cones + cone_idx, np.arange(len(times) * n_cones + 1))
    for k in range(len(times)):
        r = np.unique(rpm_sorted[starts[k * len(angles_deg)]:starts[(k + 1) * len(angles_deg)]])
        if len(r) != 1:
            raise InputError(f"set at t = {times[k]:g} s has several spindle speeds {r.tolist()} (the speed "
                             "holds per set)", file=src, column="rpm")
        rpm[k] = r[0]
        for c in range(len(angles_deg)):
            i0, i1 = starts[k * len(angles_deg) + c], starts[k * len(angles_deg) + c + 1]
            if i1 - i0 < 3 or _max_gap(np.radians(phis[i0:i1])) > 2 * np.pi / 3 + 1e-9:
                raise InputError(f"set at t = {times[k]:g} s: the circle at {angles_deg[c]:g} deg is "
                                 "missing or does not go round (needs samples with no gap above 120 deg), so "
                                 "the drift of that set cannot be determined", file=src)
            blocks.append((k, c, int(i0), int(i1)))
    ang = np.radians(angles_deg)
    L = float(L0[0])
    a = np.radians(ang_s)
    ph = np.radians(phis)
    P = np.column_stack([L * np.cos(a) * np.cos(ph), L * np.cos(a) * np.sin(ph), L * np.sin(a)])
    heights = L * (np.sin(ang) - np.sin(ang[0]))
    return _Circles(times, rpm, set_idx, cone_idx, dirs.astype(int), phis, ang, heights, P, L,
                    np.asarray(data.dL, float)[order], blocks)


_EL_SCALE = np.array([1e-3, 1e-3, 1e-3, 1e-6, 1e-6])  # internal units um, urad -> mm, rad


def _ballbar_lsq(cir: _Circles, thermal: bool = True, iterations: int = 10
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Newton over all samples at once. Unknowns: the table-ball setup offset of every cone
    (3 each, mm; absorbs bar-length and setup errors) and, for every set after the cold one, the
    five elements (dx, dy, dz mm at the reference ball, exz, eyz rad). Reading model:
    dL = |P + d_c - C_c| - L0 with d_c = (dx - exz h_c, dy - eyz h_c, dz). The normal equations
    are accumulated per (set, cone) block, so memory stays O(samples).
    Returns (setup (C,3) mm, elements (K,5) with row 0 = 0, covariance of [setup, elements(1:)]
    in um / urad, residual (M,) mm, singular values of the Jacobian in um per um / urad)."""
    C, K = len(cir.angles), len(cir.times)
    n_setup = 3 * C
    n = n_setup + (5 * (K - 1) if thermal else 0)
    x = np.zeros(n)  # um and urad
    h = cir.heights[cir.cone_idx]

    def evaluate(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        setup = x[:n_setup].reshape(C, 3) * 1e-3
        el = np.zeros((K, 5))
        if thermal:
            el[1:] = x[n_setup:].reshape(K - 1, 5) * _EL_SCALE
        e = el[cir.set_idx]
        d = np.column_stack([e[:, 0] - e[:, 3] * h, e[:, 1] - e[:, 4] * h, e[:, 2]])
        return cir.P + d - setup[cir.cone_idx], el

    for _ in range(iterations):
        v, _ = evaluate(x)
        dist = np.linalg.norm(v, axis=1)
        r = (dist - cir.L0 - cir.dL) * 1e3  # um
        u = v / dist[:, None]
        # per-sample Jacobian: setup (3, um/um), elements (5, um/um and um/urad)
        Jl = np.column_stack([-u, u, -u[:, 0] * h * 1e-3, -u[:, 1] * h * 1e-3])
        N = np.zeros((n, n))
        g = np.zeros(n)
        for k, c, i0, i1 in cir.blocks:
            cols = list(range(3 * c, 3 * c + 3))
            loc = [0, 1, 2]
            if thermal and k > 0:
                cols += list(range(n_setup + 5 * (k - 1), n_setup + 5 * k))
                loc += [3, 4, 5, 6, 7]
            Js = Jl[i0:i1][:, loc]
            N[np.ix_(cols, cols)] += Js.T @ Js
            g[cols] += Js.T @ r[i0:i1]
        step = np.linalg.solve(N, -g)
        x += step
        if np.max(np.abs(step)) < 1e-7:
            break
    v, el = evaluate(x)
    res = np.linalg.norm(v, axis=1) - cir.L0 - cir.dL
    s2 = float(res @ res) * 1e6 / max(len(res) - n, 1)
    cov = s2 * np.linalg.inv(N)
    sv = np.sqrt(np.clip(np.linalg.eigvalsh(N), 0, None))[::-1]
    return x[:n_setup].reshape(C, 3) * 1e-3, el, cov, res, sv


def trilaterate(P1: np.ndarray, P2: np.ndarray, P3: np.ndarray, L1: np.ndarray, L2: np.ndarray, L3: np.ndarray
                ) -> np.ndarray:
    """The point Q at distances L1, L2, L3 (mm) from P1, P2, P3 ((M,3) each), on the side of
    their plane with the smaller z (the table ball below the spindle ball), vectorised: the frame
    X'Y'Z' on the triangle P1 P2 P3 of METHODS section 5."""
    d21 = P2 - P1
    dd = np.linalg.norm(d21, axis=1)
    ex = d21 / dd[:, None]
    d31 = P3 - P1
    i = np.sum(ex * d31, axis=1)
    ey = d31 - i[:, None] * ex
    jn = np.linalg.norm(ey, axis=1)
    ey /= jn[:, None]
    ez = np.cross(ex, ey)
    x = (L1 ** 2 - L2 ** 2 + dd ** 2) / (2 * dd)
    y = (L1 ** 2 - L3 ** 2 + i ** 2 + jn ** 2) / (2 * jn) - i / jn * x
    z = np.sqrt(np.clip(L1 ** 2 - x ** 2 - y ** 2, 0.0, None))
    z = np.where(ez[:, 2] > 0, -z, z)
    return P1 + x[:, None] * ex + y[:, None] * ey + z[:, None] * ez


def _ballbar_trilateration(cir: _Circles, triples: int | None = None) -> np.ndarray:
    """The paper's method: per set and cone, trilaterate the table ball from triples of samples
    120 deg apart on one circle (either direction; ``triples`` evenly spaced start angles per
    circle, as "several triples" in the paper, or every available triple when None), average,
    and take the change from the cold set; then dx, dy from the lowest (reference) cone, dz the
    mean over the cones,
    exz = (dx2 - dx1) / D, eyz = (dy2 - dy1) / D with D = L0 (sin th1 - sin th2) (lowest and
    highest cone). Returns (K, 5) in mm and rad."""
    K, C = len(cir.times), len(cir.angles)
    Q = np.full((K, C, 3), np.nan)
    L = cir.L0 + cir.dL
    for k, c, i0, i1 in cir.blocks:
        qs = []
        for dr in (-1, 1):
            sel = i0 + np.flatnonzero(cir.direction[i0:i1] == dr)  # sorted by phi within the block
            kp = cir.phi_deg[sel]
            first = sel[kp < 120.0]
            if triples is not None and len(first) > triples:
                first = first[np.round(np.linspace(0, len(first), triples, endpoint=False)).astype(int)]
            p1 = cir.phi_deg[first]
            j2 = np.minimum(np.searchsorted(kp, p1 + 120.0 - 1e-6), len(kp) - 1)
            j3 = np.minimum(np.searchsorted(kp, p1 + 240.0 - 1e-6), len(kp) - 1)
            ok = (np.abs(kp[j2] - (p1 + 120.0)) < 1e-5) & (np.abs(kp[j3] - (p1 + 240.0)) < 1e-5)
            if ok.any():
                a, b, cc = first[ok], sel[j2[ok]], sel[j3[ok]]
                qs.append(trilaterate(cir.P[a], cir.P[b], cir.P[cc], L[a], L[b], L[cc]))
        if qs:
            Q[k, c] = np.mean(np.concatenate(qs), axis=0)
    if np.isnan(Q).any():
        raise InputError("trilateration needs samples exactly 120 deg apart on every circle")
    d = Q[0][None] - Q  # (K, C, 3): displacement of the spindle ball relative to the cold set
    lo, hi = 0, C - 1
    D = cir.L0 * (math.sin(cir.angles[lo]) - math.sin(cir.angles[hi]))
    return np.column_stack([d[:, lo, 0], d[:, lo, 1], d[:, :, 2].mean(axis=1),
                            (d[:, hi, 0] - d[:, lo, 0]) / D, (d[:, hi, 1] - d[:, lo, 1]) / D])


def fit_thermal_response(times: np.ndarray, rpm: np.ndarray, values: np.ndarray, cov: np.ndarray,
                         tau0: float = 1800.0) -> tuple[float, float, float, float, str | None]:
    """Fit gain (per 1000 rpm) and tau (s) of the first-order response (ErrorModel.thermal_state)
    to one element's per-set values (K,) by generalised least squares with the covariance
    ``cov`` ((K-1, K-1): the sets after the cold one; the estimates are correlated because all
    are referred to the same cold set). Set 0 is the cold reference (0 by definition); the
    response starts cold at times[0] with rpm[k] held on [times[k], times[k+1]). Returns (gain,
    tau, u_gain, u_tau, reason): reason is not None when tau cannot be determined (no significant
    drift, or a speed history that does not show the time response); then tau = tau0 and only
    the gain is fitted."""
    t = np.asarray(times, float)
    u = np.asarray(rpm, float) / 1000.0
    v = np.asarray(values, float)[1:]
    W = np.linalg.inv(np.linalg.cholesky(np.asarray(cov, float)))  # whitening: W v has unit covariance
    wv = W @ v

    def resp(tau: float) -> np.ndarray:
        return W @ first_order_response(t, u, 1.0, tau)[1:]

    def gain_for(tau: float) -> tuple[float, float]:
        y = resp(tau)
        yy = float(y @ y)
        return (float(y @ wv) / yy, 1.0 / math.sqrt(yy)) if yy > 0 else (0.0, math.inf)

    # the gain is linear given tau: scan log tau for a start, then least squares on (gain, log tau)
    span = max(t[-1] - t[0], 1.0)
    taus = np.geomspace(span / 200, span * 5, 80)
    costs = [float(np.sum((wv - gain_for(tau)[0] * resp(tau)) ** 2)) for tau in taus]
    tau_s = float(taus[int(np.argmin(costs))])
    g_s, ug_s = gain_for(tau_s)
    if not abs(g_s) > 3 * ug_s:
        g, ug = gain_for(tau0)
        return g, tau0, ug, math.inf, ("no significant drift of this element, so its time constant cannot be "
                                       "seen; tau held at the base value")

    def fun(x: np.ndarray) -> np.ndarray:
        return wv - x[0] * resp(math.exp(x[1]))

    res = fitting.levenberg_marquardt(fun, np.array([g_s, math.log(tau_s)]), step=1e-7, central=True,
                                      rtol=1e-15, xtol=1e-12, scale=np.ones(2), max_iter=100)
    J = res.Jt.T
    Jn = J / np.maximum(np.linalg.norm(J, axis=0), 1e-300)
    s = np.linalg.svd(Jn, compute_uv=False)
    if len(v) < 3 or s[-1] < 1e-4 * s[0]:
        g, ug = gain_for(tau0)
        return g, tau0, ug, math.inf, ("the speed history does not show the time response, so tau cannot be "
                                       "determined; held at the base value")
    c = np.linalg.inv(J.T @ J)  # whitened residuals: the covariance is known, no s^2 rescaling
    tau = math.exp(res.x[1])
    return float(res.x[0]), tau, float(np.sqrt(c[0, 0])), tau * float(np.sqrt(c[1, 1])), None


def calibrate_ballbar(data: BallbarData | str | os.PathLike, base: ErrorModel | None = None, *,
                      trilateration: bool = True, triples: int = 8) -> CalibrationReport:
    """Spindle thermal elements from a ballbar cone test (METHODS section 5).

    Least squares over all samples of all sets (``_ballbar_lsq``): per set after the cold one
    the five elements dx, dy, dz (mm) and exz, eyz (rad) at the reference (lowest) ball, which the
    model takes as the tool tip; then, per element, the first-order response (gain per 1000 rpm,
    tau) to the spindle-speed history (``fit_thermal_response``), written into the model.
    details['times'], details['elements'] (K,5) and details['element_uncertainty'] (K,5) hold the
    per-set result; details['trilateration'] (K,5) the paper's three-point method for comparison
    with ``triples`` triples per circle and direction, details['trilateration_all'] with every
    triple (which, on uniformly sampled circles, is nearly the least-squares estimate).
    """
    if not isinstance(data, BallbarData):
        data = read_ballbar_csv(data)
    cir = validate_ballbar(data)
    base = base or ErrorModel()
    _, _, _, res0, _ = _ballbar_lsq(cir, thermal=False)
    setup, el, cov, res, sv = _ballbar_lsq(cir, thermal=True)
    K = len(cir.times)
    n_setup = 3 * len(cir.angles)
    sd = np.sqrt(np.diag(cov))
    el_sd = np.zeros((K, 5))
    el_sd[1:] = sd[n_setup:].reshape(K - 1, 5) * _EL_SCALE
    thermal: dict[str, dict] = {}
    params: dict[str, float] = {}
    unc: dict[str, float] = {}
    units: dict[str, str] = {}
    reasons: dict[str, str] = {}
    for j, name in enumerate(SPINDLE_THERMAL):
        idx = n_setup + 5 * np.arange(K - 1) + j
        cov_j = cov[np.ix_(idx, idx)] * _EL_SCALE[j] ** 2
        tau0 = float(base.thermal.get(name, {}).get("tau", 1800.0))
        g, tau, ug, ut, why = fit_thermal_response(cir.times, cir.rpm, el[:, j], cov_j, tau0)
        thermal[name] = {"gain": g, "tau": tau}
        unit = SPINDLE_THERMAL[name]
        params[f"{name}.gain"], unc[f"{name}.gain"], units[f"{name}.gain"] = g, ug, f"{unit}/1000rpm"
        params[f"{name}.tau"], unc[f"{name}.tau"], units[f"{name}.tau"] = tau, ut, "s"
        if why:
            reasons[f"{name}.tau"] = why
    details: dict[str, Any] = {"times": cir.times, "rpm": cir.rpm, "elements": el,
                               "element_uncertainty": el_sd, "setup": setup, "angles": cir.angles,
                               "heights": cir.heights, "L0": cir.L0}
    if trilateration:
        details["trilateration"] = _ballbar_trilateration(cir, triples)
        details["trilateration_triples"] = triples
        details["trilateration_all"] = _ballbar_trilateration(cir, None)
    meta = dict(base.meta)
    meta["ballbar"] = {"source": data.source, "sets": K, "samples": len(cir.dL)}
    model = replace(base, thermal=thermal, meta=meta)
    return CalibrationReport("ballbar", model, params, unc, units, reasons,
                             float(np.sqrt(np.mean(res0 ** 2))), float(np.sqrt(np.mean(res ** 2))),
                             sv, float(sv[0] / sv[-1]), len(cir.dL), details=details)
