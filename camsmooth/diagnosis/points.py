"""Static measurements: nominal against measured points (a CMM report of drilled holes, a probed
plate), fitted with the setup of the part and the geometric errors of the machine's linear axes.

Input (``read_points``): a CSV read by camsmooth.io.table with ``x_nom, y_nom, x_meas, y_meas``
and optionally ``z_nom, z_meas`` (mm); other columns are left as they are (listed as ignored).

Model (mm, rad inside; ``predict``): measured = R(theta) @ [[1 + s_x, k], [0, 1 + s_y]] @ nominal +
offset in the XY plane, z_meas = (1 + s_z) z_nom + offset_z. The setup (offset, rotation theta,
positive counter-clockwise seen from +Z) is always fitted; the linear-axis terms are candidates:
``linear_positioning`` (the scale error s of each axis, reported in ppm: +100 ppm = the axis
travels 0.1 mm more per metre) and ``linear_squareness`` (k: the measured x grows by k * y,
reported as the out-of-squareness of X and Y in urad; positive = the Y axis leans towards +X).

Selection (``diagnose_points``): forward, one parameter at a time; a parameter joins when it is
resolved (beyond ``RESOLVE_SIGMA`` standard uncertainties, from the residual's scatter) and the
held-out RMS of the radial residual falls, pooled and in most of the spatial folds (the points
split into quadrants about the median nominal x and y: each quadrant is predicted by the fit on
the other three). What the fit leaves is located: the points whose radial residual exceeds
``LOCATE_SIGMA`` robust standard deviations, with where they are.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from camsmooth.io.table import read_table

RESOLVE_SIGMA = 3.0
LOCATE_SIGMA = 3.0
SETUP = ("offset_x", "offset_y", "rotation")
CANDIDATES = ("scale_x", "scale_y", "squareness_xy")
TERM_OF = {"scale_x": "linear_positioning", "scale_y": "linear_positioning", "scale_z": "linear_positioning",
           "squareness_xy": "linear_squareness"}


@dataclass(frozen=True)
class Points:
    """Nominal (n, 2 or 3) and measured (n, 2 or 3) points (mm) and the data row of each."""

    file: str
    nominal: np.ndarray
    measured: np.ndarray
    rows: np.ndarray
    ignored: tuple[str, ...] = ()

    @property
    def has_z(self) -> bool:
        return self.nominal.shape[1] == 3

    def describe(self) -> dict[str, Any]:
        ext = np.ptp(self.nominal, axis=0)
        return {"file": self.file, "points": int(len(self.rows)), "z": self.has_z,
                "extent_mm": [float(e) for e in ext], "ignored_columns": list(self.ignored)}

    def summary(self) -> str:
        d = self.describe()
        ext = " x ".join(f"{e:.4g}" for e in d["extent_mm"])
        return (f"read {self.file}: {d['points']} points{' with z' if self.has_z else ''} over {ext} mm"
                + (f"; ignored columns {', '.join(self.ignored)}" if self.ignored else ""))


def read_points(path: str) -> Points:
    """Read and validate a points file (module docstring); InputError names file, row, column."""
    tab = read_table(path, required=["x_nom", "y_nom", "x_meas", "y_meas"], optional=["z_nom", "z_meas"],
                     min_rows=4, what="points file")
    if ("z_nom" in tab) != ("z_meas" in tab):
        have, miss = ("z_nom", "z_meas") if "z_nom" in tab else ("z_meas", "z_nom")
        raise tab.header_error(f"{have} is given without {miss} (give both or neither)", miss)
    ax = ("x", "y", "z") if "z_nom" in tab else ("x", "y")
    nom = np.column_stack([tab[f"{a}_nom"] for a in ax])
    meas = np.column_stack([tab[f"{a}_meas"] for a in ax])
    for j in (0, 1):
        if np.ptp(nom[:, j]) <= 0:
            raise tab.error(f"every nominal {ax[j]} is the same: the points must spread in x and y", None,
                            f"{ax[j]}_nom")
    return Points(str(path), nom, meas, tab.rows, tab.ignored)


def predict(nom: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    """Measured points predicted from nominal ones (module docstring; p in mm and rad)."""
    x, y = nom[:, 0], nom[:, 1]
    sx, sy, k = p.get("scale_x", 0.0), p.get("scale_y", 0.0), p.get("squareness_xy", 0.0)
    u = (1.0 + sx) * x + k * y
    v = (1.0 + sy) * y
    c, s = math.cos(p.get("rotation", 0.0)), math.sin(p.get("rotation", 0.0))
    out = [c * u - s * v + p.get("offset_x", 0.0), s * u + c * v + p.get("offset_y", 0.0)]
    if nom.shape[1] == 3:
        out.append((1.0 + p.get("scale_z", 0.0)) * nom[:, 2] + p.get("offset_z", 0.0))
    return np.column_stack(out)


def _fit(nom: np.ndarray, meas: np.ndarray, names: Sequence[str]) -> tuple[dict[str, float], np.ndarray]:
    """Least squares of the parameters ``names`` (others 0): (values, covariance) in mm / rad,
    the covariance scaled by the residual variance."""
    from scipy.optimize import least_squares

    def f(x: np.ndarray) -> np.ndarray:
        return (predict(nom, dict(zip(names, x, strict=True))) - meas).ravel()

    x0 = np.zeros(len(names))
    res = least_squares(f, x0, method="lm", x_scale=np.where([n.startswith("offset") for n in names], 1.0, 1e-4))
    J = res.jac
    dof = max(len(res.fun) - len(names), 1)
    s2 = float(res.fun @ res.fun) / dof
    cov = np.linalg.pinv(J.T @ J) * s2
    return dict(zip(names, res.x, strict=True)), cov


def _radial(nom: np.ndarray, meas: np.ndarray, p: Mapping[str, float]) -> np.ndarray:
    return np.sqrt(np.sum((meas - predict(nom, p)) ** 2, axis=1))


def spatial_folds(nom: np.ndarray) -> np.ndarray:
    """Quadrant of each point about the median nominal x and y (0..3); quadrants with fewer than
    2 points are merged into their neighbour in x; when a fold would leave fewer than 3 points to
    fit, each point is its own fold (leave one out)."""
    qx = nom[:, 0] > np.median(nom[:, 0])
    qy = nom[:, 1] > np.median(nom[:, 1])
    f = qx.astype(int) + 2 * qy.astype(int)
    for k in range(4):
        if 0 < np.sum(f == k) < 2:
            f[f == k] = k ^ 1
    _, f = np.unique(f, return_inverse=True)
    if len(np.unique(f)) < 2 or np.bincount(f).max() > len(nom) - 3:
        return np.arange(len(nom))  # too few points for quadrants: leave one point out at a time
    return f


def heldout(nom: np.ndarray, meas: np.ndarray, names: Sequence[str], folds: np.ndarray
            ) -> tuple[float, np.ndarray]:
    """Pooled held-out RMS of the radial residual (mm) and the held-out RMS per fold."""
    K = int(folds.max()) + 1
    sq = np.zeros(len(nom))
    per = np.zeros(K)
    for k in range(K):
        te = folds == k
        p, _ = _fit(nom[~te], meas[~te], names)
        r = _radial(nom[te], meas[te], p)
        sq[te] = r * r
        per[k] = math.sqrt(float(np.mean(r * r)))
    return math.sqrt(float(np.mean(sq))), per


_REPORT = {"offset_x": ("offset_x_mm", 1.0, "mm"), "offset_y": ("offset_y_mm", 1.0, "mm"),
           "offset_z": ("offset_z_mm", 1.0, "mm"), "rotation": ("rotation_deg", math.degrees(1.0), "deg"),
           "scale_x": ("scale_x_ppm", 1e6, "ppm"), "scale_y": ("scale_y_ppm", 1e6, "ppm"),
           "scale_z": ("scale_z_ppm", 1e6, "ppm"), "squareness_xy": ("squareness_xy_urad", 1e6, "urad")}


def diagnose_points(pts: Points) -> dict[str, Any]:
    """The setup and the named linear-axis terms with uncertainties, held-out figures by a spatial
    split, the residual left and where it is (module docstring); the FINDINGS.json content."""
    nom, meas = pts.nominal, pts.measured
    folds = spatial_folds(nom)
    setup = list(SETUP) + (["offset_z"] if pts.has_z else [])
    cands = list(CANDIDATES) + (["scale_z"] if pts.has_z else [])
    active = list(setup)
    h_cur, per_cur = heldout(nom, meas, active, folds)
    h0 = h_cur
    steps, rejected = [], []
    while cands:
        trials = {}
        for c in cands:
            if len(nom) - len(active) - 1 < 2:
                break
            p, cov = _fit(nom, meas, active + [c])
            sd = math.sqrt(max(float(cov[-1, -1]), 0.0))
            h, per = heldout(nom, meas, active + [c], folds)
            trials[c] = (p[c], sd, h, per)
        if not trials:
            break
        best = min(trials, key=lambda c: trials[c][2])
        v, sd, h, per = trials[best]
        better = int(np.sum(per < per_cur))
        if abs(v) > RESOLVE_SIGMA * sd and h < h_cur and better > len(per) // 2:
            steps.append({"parameter": best, "heldout_before": h_cur, "heldout_after": h,
                          "folds_better": better, "folds": len(per)})
            active.append(best)
            cands.remove(best)
            h_cur, per_cur = h, per
            continue
        for c, (v, sd, h, per) in trials.items():
            f, unit = _REPORT[c][1], _REPORT[c][2]
            why = (f"{v * f:.4g} ± {sd * f:.2g} {unit}: within {RESOLVE_SIGMA:g} standard uncertainties"
                   if abs(v) <= RESOLVE_SIGMA * sd else
                   f"the held-out RMS {'rises' if h >= h_cur else 'falls only in'} "
                   + (f"({h_cur * 1e3:.4g} -> {h * 1e3:.4g} um)" if h >= h_cur else
                      f"{int(np.sum(per < per_cur))} of {len(per)} spatial folds"))
            rejected.append({"name": TERM_OF[c], "parameter": _REPORT[c][0], "reason": why})
        break
    p, cov = _fit(nom, meas, active)
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    val = {n: float(p[n]) * _REPORT[n][1] for n in active}
    unc = {n: float(s) * _REPORT[n][1] for n, s in zip(active, sd, strict=True)}
    setup_out = {_REPORT[n][0]: val[n] for n in setup}
    effects = []
    for term in ("linear_positioning", "linear_squareness"):
        ps = [s["parameter"] for s in steps if TERM_OF[s["parameter"]] == term]
        if not ps:
            continue
        first = next(s for s in steps if s["parameter"] in ps)
        last = [s for s in steps if s["parameter"] in ps][-1]
        effects.append({"name": term, "parameters": {_REPORT[n][0]: val[n] for n in ps},
                        "uncertainties": {_REPORT[n][0]: unc[n] for n in ps},
                        "units": {_REPORT[n][0]: _REPORT[n][2] for n in ps},
                        "heldout_rms_before": {"radial_mm": first["heldout_before"]},
                        "heldout_rms_after": {"radial_mm": last["heldout_after"]},
                        "sentence": _sentence(term, {n: val[n] for n in ps}, {n: unc[n] for n in ps})})
    r = meas - predict(nom, p)
    rad = np.sqrt(np.sum(r * r, axis=1))
    comp = r[:, :2].ravel()
    sigma = max(1.4826 * float(np.median(np.abs(comp - np.median(comp)))), 1e-12)
    far = np.flatnonzero(rad > LOCATE_SIGMA * sigma * math.sqrt(2.0))
    located = [{"row": int(pts.rows[i]), "nominal_mm": [float(v) for v in nom[i]],
                "residual_mm": [float(v) for v in r[i]], "radial_mm": float(rad[i])}
               for i in far[np.argsort(-rad[far])][:20]]
    quad = {f"quadrant_{k}": float(np.sqrt(np.mean(rad[folds == k] ** 2))) for k in range(int(folds.max()) + 1)}
    named = [e["name"] for e in effects]
    return {"input": pts.describe(), "setup": setup_out,
            "setup_uncertainty": {_REPORT[n][0]: unc[n] for n in setup}, "named": named, "effects": effects,
            "rejected": rejected, "residual_rms_mm": float(np.sqrt(np.mean(rad * rad))),
            "heldout": {"scheme": ("each point predicted by the fit on the others (too few points for quadrants)"
                                   if int(folds.max()) + 1 == len(nom) else
                                   f"{int(folds.max()) + 1} spatial folds (quadrants about the median nominal x, y): "
                                   "each predicted by the fit on the others"),
                        "rms_setup_only_mm": h0, "rms_final_mm": h_cur},
            "unexplained": {"robust_sigma_mm": sigma, "points_beyond": located, "rms_by_fold_mm": quad},
            "verdict": f"named {', '.join(named)}" if named else "nothing named beyond the setup"}


def _sentence(term: str, val: Mapping[str, float], unc: Mapping[str, float]) -> str:
    parts = [f"{_REPORT[n][0]} = {v:.4g} ± {unc[n]:.2g} {_REPORT[n][2]}" for n, v in val.items()]
    what = "The axes scale the part" if term == "linear_positioning" else "X and Y are out of square"
    return f"{what} ({', '.join(parts)})"


def summary_text(f: Mapping[str, Any]) -> str:
    """The setup, the named terms, the residual left."""
    s = f["setup"]
    lines = [f"setup: offset x {s['offset_x_mm']:.4g} mm, y {s['offset_y_mm']:.4g} mm, rotation "
             f"{s['rotation_deg']:.4g} deg", f"verdict: {f['verdict']}"]
    lines += [f"- {e['sentence']}" for e in f["effects"]]
    lines.append(f"residual RMS {f['residual_rms_mm'] * 1e3:.4g} um (held-out {f['heldout']['rms_final_mm'] * 1e3:.4g}"
                 f" um); {len(f['unexplained']['points_beyond'])} point(s) beyond {LOCATE_SIGMA:g} sigma")
    return "\n".join(lines)
