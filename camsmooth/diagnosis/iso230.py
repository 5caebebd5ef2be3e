"""Linear axes as the standards measure them: the ISO 230-2 positioning figures of a bidirectional
run, and the pitch-error (screw) compensation table a controller loads (LinuxCNC's COMP_FILE).

The run
-------
For each target position P_j (j = 1..m targets) the axis approaches the target n times from
below (direction +1, "up") and n times from above (direction -1, "down"); each approach gives a
measured deviation x_ij = (measured position - target) in mm (a laser interferometer reading).
The CSV (``read_run``) has the columns ``target`` (mm), ``direction`` (+1 / -1), ``run`` (int)
and ``deviation`` (mm), one row per approach.

The figures (``evaluate``), as ISO 230-2 defines them
-----------------------------------------------------
Per target and direction the mean unidirectional positional deviation x̄_j↑ (x̄_j↓) is the mean
of the n deviations; its estimator of the unidirectional standard uncertainty s_j↑ (s_j↓) is the
sample standard deviation (divisor n - 1). The reversal value at a target is the signed
difference of the two means, B_j = x̄_j↑ - x̄_j↓; the axis reversal value B is the largest |B_j|
and the mean reversal value B̄ the mean of the signed B_j. Repeatability is a 4-sigma band:
unidirectional R_j↑ = 4 s_j↑, R_j↓ = 4 s_j↓; bidirectional at a target R_j = max(2 s_j↑ +
2 s_j↓ + |B_j|, R_j↑, R_j↓) (the two 2-sigma half bands plus the gap between them), and the
axis repeatability R the largest R_j. The mean bidirectional positional deviation at a target
is x̄_j = (x̄_j↑ + x̄_j↓) / 2. Over the axis: the systematic positional deviation E is the span
of all the unidirectional means (largest of x̄↑ and x̄↓ minus the smallest); the mean
bidirectional positional deviation M the span of the x̄_j; the accuracy A the span of the
2-sigma bands, max(x̄↑ + 2 s↑, x̄↓ + 2 s↓) - min(x̄↑ - 2 s↑, x̄↓ - 2 s↓).

What the sources say: a search of the stored public pages (query "ISO 230-2 reversal value
repeatability bidirectional accuracy formula") found only summaries (a CNC guide naming the
standard's three headline figures: accuracy A, repeatability R, reversal B, measured from
repeated bidirectional approaches with a laser interferometer) and no page with the formulas;
the standard itself is not public. The formulas above are those of the issue (20, item 3),
which match the 2014 edition's definitions as we know them (coverage factor 2 for A, 4 s for
R, sample standard deviation); the test suite checks them against a hand-computed example.

The compensation table (``compensation_table``, ``write_comp_file``)
-------------------------------------------------------------------
LinuxCNC reads, per joint, ``[JOINT_n] COMP_FILE = name`` and ``COMP_FILE_TYPE = 0 | 1``: a
text file of one triplet a line, ``nominal second third``, separated by blanks, ascending in
nominal, at most 256 lines, in machine units, linearly interpolated between nominals (the
LinuxCNC INI documentation, docs/src/config/ini-config.adoc). With type 0 the second and third
values are the *actual* positions reached moving in the positive / negative direction; with
type 1 they are trims. The sign of a trim is settled by LinuxCNC's loader
(src/emc/motion/usrmotintf.cc): a type-0 line is converted to trims as
``forward = nominal - actual_forward``, ``reverse = nominal - actual_reverse``, and the trim is
added to the motor position command. So a trim is **the amount to add to the command when
moving in that direction**, i.e. minus the deviation: forward-trim = -x̄↑(P), reverse-trim =
-x̄↓(P). camsmooth writes type 1 (set ``COMP_FILE_TYPE = 1``) in mm (the joint's units must be
mm). The loader stops at the first line that is not three numbers, so the file holds no header
or comment lines. With a COMP_FILE LinuxCNC ignores ``BACKLASH``: the reversal is in the table.

The table from fitted terms (``fit_terms``, ``compensation_from_terms``, ``crossvalidate``)
-------------------------------------------------------------------------------------------
The means at the targets carry each target's noise and any error between the targets into the
table. The default table is built instead from two fitted terms, the ones the diagnosis library
names for a linear axis: a linear positioning error (offset e0 and scale error k, mm/mm) and a
reversal B, fitted by least squares to every approach,

    deviation = e0 + k P + direction B / 2        (so B = x̄↑ - x̄↓, as ISO 230-2 signs it),

with standard uncertainties from the residual's scatter. The trims are minus the fitted
deviation at each nominal in each direction. What such a table leaves is measured on approaches
it was not built from: leave-one-run-out (run r of the cycle, up and down, is held out; the terms
are fitted on the other runs, the table is applied to run r), pooled over the runs - the
held-out RMS the table leaves, beside the run's RMS without a table and the noise (the pooled
within-target scatter s). Only the LinuxCNC format is written; other controllers (a Fanuc pitch
error table in parameters, a Siemens or Heidenhain compensation table) are not.

``apply_compensation`` applies a table to another run the way the controller does (trim
interpolated linearly between nominals, held at the ends, chosen by the approach direction) and
``heldout_rms`` gives the RMS deviation of that run before and after. ``simulate_run`` makes a
run with a known pitch error, periodic screw error, reversal and noise (tests, README figures).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from camsmooth.errors import InputError

__all__ = ["Run", "Iso230Result", "CompTable", "FittedTerms", "read_run", "evaluate", "compensation_table",
           "fit_terms", "compensation_from_terms", "crossvalidate", "comp_text",
           "write_comp_file", "read_comp_file", "apply_compensation", "heldout_rms", "simulate_run",
           "result_json", "LINUXCNC_MAX_LINES"]

LINUXCNC_MAX_LINES = 256  # LinuxCNC's limit of triplets per joint


@dataclass(frozen=True)
class Run:
    """One bidirectional positioning run: per approach its target (mm), direction (+1 / -1), run
    number and measured deviation (mm, measured - target). ``file`` names the source (messages)."""

    target: np.ndarray
    direction: np.ndarray
    run: np.ndarray
    deviation: np.ndarray
    file: str | None = None


@dataclass(frozen=True)
class Iso230Result:
    """ISO 230-2 figures of one axis (all mm; per-target tuples in ascending target order)."""

    axis: str
    targets: tuple[float, ...]
    n_up: tuple[int, ...]
    n_down: tuple[int, ...]
    mean_up: tuple[float, ...]           # x̄_j↑
    mean_down: tuple[float, ...]         # x̄_j↓
    s_up: tuple[float, ...]              # s_j↑
    s_down: tuple[float, ...]            # s_j↓
    reversal: tuple[float, ...]          # B_j = x̄_j↑ - x̄_j↓ (signed)
    repeat_up: tuple[float, ...]         # R_j↑ = 4 s_j↑
    repeat_down: tuple[float, ...]       # R_j↓ = 4 s_j↓
    repeat_bi: tuple[float, ...]         # R_j
    mean_bi: tuple[float, ...]           # x̄_j
    B: float                             # axis reversal value, max |B_j|
    B_mean: float                        # mean reversal value (signed mean of B_j)
    R_up: float                          # max R_j↑
    R_down: float                        # max R_j↓
    R: float                             # axis bidirectional repeatability, max R_j
    E_up: float                          # unidirectional systematic positional deviation ↑
    E_down: float
    E: float                             # bidirectional systematic positional deviation
    M: float                             # mean bidirectional positional deviation
    A_up: float                          # unidirectional accuracy ↑
    A_down: float
    A: float                             # bidirectional accuracy


@dataclass(frozen=True)
class CompTable:
    """A pitch-error compensation table (LinuxCNC COMP_FILE_TYPE 1, mm): per nominal position the
    trim added to the command moving in the positive (forward) and negative (reverse) direction."""

    nominal: tuple[float, ...]
    forward: tuple[float, ...]
    reverse: tuple[float, ...]


# ----------------------------------------------------------------------------------------------
# input
def read_run(path: str | os.PathLike) -> Run:
    """A run CSV (module docstring); InputError naming the file, row and column for a bad file: a
    direction not +1 / -1, an approach given twice (same target, direction and run)."""
    from camsmooth.io.table import read_table

    t = read_table(path, ("target", "direction", "run", "deviation"), integer=("direction", "run"),
                   what="positioning run")
    d = t["direction"]
    bad = np.flatnonzero((d != 1) & (d != -1))
    if bad.size:
        raise t.error(f"direction must be +1 or -1, got {int(d[bad[0]])}", bad[0], "direction")
    seen: dict[tuple[float, int, int], int] = {}
    for i, key in enumerate(zip(t["target"].tolist(), d.tolist(), t["run"].tolist(), strict=True)):
        if key in seen:
            raise t.error(f"approach given twice (target {key[0]:g}, direction {key[1]:+d}, run {key[2]}; "
                          f"first on row {int(t.rows[seen[key]])})", i, "run")
        seen[key] = i
    run = Run(t["target"].astype(float), d.astype(int), t["run"].astype(int), t["deviation"].astype(float), t.file)
    _check_run(run, t)
    return run


def _check_run(run: Run, table: object | None = None) -> None:
    """Each target needs >= 2 approaches in each direction, and there must be >= 2 targets."""
    file = run.file
    targets = np.unique(run.target)
    if targets.size < 2:
        raise InputError("a positioning run needs at least 2 target positions", file=file, column="target")
    for p in targets:
        for sgn, name in ((1, "+1"), (-1, "-1")):
            k = int(np.count_nonzero((run.target == p) & (run.direction == sgn)))
            if k < 2:
                msg = (f"target {p:g} has {k} approach(es) in direction {name}; ISO 230-2 needs at least 2 "
                       "in each direction (5 recommended)")
                if table is not None:
                    idx = int(np.flatnonzero(run.target == p)[0])
                    raise table.error(msg, idx, "direction")  # type: ignore[attr-defined]
                raise InputError(msg, file=file, column="direction")


# ----------------------------------------------------------------------------------------------
# the figures
def evaluate(run: Run, axis: str = "X") -> Iso230Result:
    """The ISO 230-2 figures of ``run`` (module docstring)."""
    _check_run(run)
    targets = np.unique(run.target)
    cols: dict[str, list[float]] = {k: [] for k in ("mu", "md", "su", "sd")}
    n_up, n_down = [], []
    for p in targets:
        at = run.target == p
        up = run.deviation[at & (run.direction == 1)]
        dn = run.deviation[at & (run.direction == -1)]
        n_up.append(int(up.size))
        n_down.append(int(dn.size))
        cols["mu"].append(float(up.mean()))
        cols["md"].append(float(dn.mean()))
        cols["su"].append(float(up.std(ddof=1)))
        cols["sd"].append(float(dn.std(ddof=1)))
    mu, md, su, sd = (np.array(cols[k]) for k in ("mu", "md", "su", "sd"))
    b = mu - md
    ru, rd = 4 * su, 4 * sd
    rbi = np.maximum.reduce([2 * su + 2 * sd + np.abs(b), ru, rd])
    mbi = (mu + md) / 2

    def tup(a: np.ndarray) -> tuple[float, ...]:
        return tuple(float(v) for v in a)

    return Iso230Result(
        axis=axis, targets=tup(targets), n_up=tuple(n_up), n_down=tuple(n_down),
        mean_up=tup(mu), mean_down=tup(md), s_up=tup(su), s_down=tup(sd), reversal=tup(b),
        repeat_up=tup(ru), repeat_down=tup(rd), repeat_bi=tup(rbi), mean_bi=tup(mbi),
        B=float(np.max(np.abs(b))), B_mean=float(np.mean(b)),
        R_up=float(ru.max()), R_down=float(rd.max()), R=float(rbi.max()),
        E_up=float(mu.max() - mu.min()), E_down=float(md.max() - md.min()),
        E=float(max(mu.max(), md.max()) - min(mu.min(), md.min())),
        M=float(mbi.max() - mbi.min()),
        A_up=float((mu + 2 * su).max() - (mu - 2 * su).min()),
        A_down=float((md + 2 * sd).max() - (md - 2 * sd).min()),
        A=float(max((mu + 2 * su).max(), (md + 2 * sd).max()) - min((mu - 2 * su).min(), (md - 2 * sd).min())),
    )


def result_json(result: Iso230Result, comp: CompTable | None = None,
                heldout: tuple[float, float] | None = None, terms: FittedTerms | None = None,
                crossval: dict[str, float | int] | None = None, table_from: str = "means") -> str:
    """The figures as JSON (units mm), with the table (and what it was built from), the fitted
    terms, the cross-validated held-out RMS and a held-out run's RMS when given."""
    doc: dict[str, object] = {"units": "mm", "standard": "ISO 230-2", **asdict(result)}
    if terms is not None:
        doc["fitted_terms"] = {"model": "deviation = offset + scale * P + direction * reversal / 2", **asdict(terms)}
    if crossval is not None:
        doc["crossvalidated_rms"] = {"method": "leave one run out: terms fitted on the other runs, table applied "
                                               "to the held-out run", **crossval}
    if comp is not None:
        doc["compensation"] = {"format": "LinuxCNC COMP_FILE_TYPE 1 (nominal forward-trim reverse-trim; "
                                         "trim = amount added to the command)", "built_from": table_from,
                               **asdict(comp)}
    if heldout is not None:
        doc["heldout_rms"] = {"before": heldout[0], "after": heldout[1]}
    return json.dumps(doc, indent=2) + "\n"


# ----------------------------------------------------------------------------------------------
# compensation
def compensation_table(result: Iso230Result) -> CompTable:
    """The LinuxCNC type-1 table of ``result``: at each target, trim = -(mean deviation) in that
    direction, so that the commanded position plus the trim lands on the target."""
    if len(result.targets) > LINUXCNC_MAX_LINES:
        raise InputError(f"{len(result.targets)} targets; a LinuxCNC compensation file holds at most "
                         f"{LINUXCNC_MAX_LINES} lines")
    return CompTable(nominal=result.targets, forward=tuple(-v for v in result.mean_up),
                     reverse=tuple(-v for v in result.mean_down))


@dataclass(frozen=True)
class FittedTerms:
    """The terms fitted to a run (mm, mm/mm): deviation = offset + scale P + direction reversal / 2;
    their standard uncertainties, the residual RMS and the number of approaches used."""

    offset: float
    scale: float
    reversal: float
    sd_offset: float
    sd_scale: float
    sd_reversal: float
    residual_rms: float
    n: int

    def deviation(self, position: np.ndarray, direction: np.ndarray) -> np.ndarray:
        """The fitted deviation (mm) at ``position`` approached in ``direction`` (+1 / -1)."""
        p = np.asarray(position, float)
        return self.offset + self.scale * p + np.asarray(direction, float) * self.reversal / 2


def fit_terms(run: Run, keep: np.ndarray | None = None) -> FittedTerms:
    """Least-squares fit of the linear positioning error and the reversal (module docstring) to the
    approaches of ``run`` (those where ``keep`` is True when given)."""
    sel = np.ones(run.target.size, bool) if keep is None else np.asarray(keep, bool)
    p, d, y = run.target[sel], run.direction[sel].astype(float), run.deviation[sel]
    A = np.column_stack([np.ones(p.size), p, d / 2])
    if p.size < 4 or np.linalg.matrix_rank(A) < 3:
        raise InputError("fitting the positioning error and the reversal needs approaches at 2 or more targets "
                         "in both directions", file=run.file)
    coef, *_ = np.linalg.lstsq(A, y, rcond=None)
    r = y - A @ coef
    s2 = float(r @ r) / max(p.size - 3, 1)
    sd = np.sqrt(np.clip(np.diag(np.linalg.pinv(A.T @ A)) * s2, 0.0, None))
    return FittedTerms(float(coef[0]), float(coef[1]), float(coef[2]), float(sd[0]), float(sd[1]), float(sd[2]),
                       float(np.sqrt(np.mean(r * r))), int(p.size))


def compensation_from_terms(terms: FittedTerms, nominal: Sequence[float]) -> CompTable:
    """The LinuxCNC type-1 table of fitted ``terms`` at ``nominal`` positions (ascending, mm):
    trim = minus the fitted deviation moving in that direction."""
    nom = np.asarray(sorted(float(v) for v in nominal))
    if nom.size > LINUXCNC_MAX_LINES:
        raise InputError(f"{nom.size} nominal positions; a LinuxCNC compensation file holds at most "
                         f"{LINUXCNC_MAX_LINES} lines")
    fwd = -terms.deviation(nom, np.ones(nom.size))
    rev = -terms.deviation(nom, -np.ones(nom.size))
    return CompTable(tuple(float(v) for v in nom), tuple(float(v) for v in fwd), tuple(float(v) for v in rev))


def crossvalidate(run: Run) -> dict[str, float | int]:
    """The held-out RMS a table from fitted terms leaves (module docstring): each run number held
    out in turn (the terms fitted on the others, the table at the run's targets applied to it),
    pooled. Returns before / after (mm RMS over all held-out approaches), noise (pooled
    within-target, within-direction sample standard deviation) and folds (runs held out)."""
    runs = np.unique(run.run)
    if runs.size < 2:
        raise InputError("a held-out check needs at least 2 runs", file=run.file, column="run")
    nominal = np.unique(run.target)
    after = np.empty(run.deviation.size)
    for k in runs:
        out = run.run == k
        table = compensation_from_terms(fit_terms(run, ~out), nominal)
        after[out] = run.deviation[out] + trim(table, run.target[out], run.direction[out])
    dev2, dof = 0.0, 0
    for p in nominal:
        for sgn in (1, -1):
            v = run.deviation[(run.target == p) & (run.direction == sgn)]
            if v.size > 1:
                dev2 += float(np.sum((v - v.mean()) ** 2))
                dof += v.size - 1
    return {"before": float(np.sqrt(np.mean(run.deviation ** 2))), "after": float(np.sqrt(np.mean(after ** 2))),
            "noise": math.sqrt(dev2 / dof) if dof else math.nan, "folds": int(runs.size)}


def comp_text(table: CompTable) -> str:
    """The COMP_FILE text: one ``nominal forward-trim reverse-trim`` line per nominal, ascending,
    no header (LinuxCNC stops reading at the first line that is not three numbers)."""
    rows = zip(table.nominal, table.forward, table.reverse, strict=True)
    return "".join(f"{n:.6f} {f:.6f} {r:.6f}\n" for n, f, r in rows)


def write_comp_file(path: str | os.PathLike, table: CompTable) -> Path:
    """Write ``table`` as a LinuxCNC COMP_FILE (type 1) at ``path``, atomically."""
    from camsmooth.io.atomic import atomic_path

    with atomic_path(path) as tmp:
        tmp.write_text(comp_text(table), encoding="utf-8")
    return Path(path)


def read_comp_file(path: str | os.PathLike) -> CompTable:
    """Read a type-1 COMP_FILE back; InputError naming the line for a line that is not three
    numbers, or nominals not strictly ascending."""
    from camsmooth.io.table import read_text_file

    file = str(path)
    rows: list[tuple[float, float, float]] = []
    for k, line in enumerate(read_text_file(path, "compensation file").split("\n"), start=1):
        if not line.strip():
            continue
        parts = line.split()
        try:
            vals = tuple(float(v) for v in parts)
        except ValueError:
            vals = ()
        if len(vals) != 3 or not all(math.isfinite(v) for v in vals):
            raise InputError("expected three numbers: nominal forward-trim reverse-trim", file=file, line=k)
        if rows and vals[0] <= rows[-1][0]:
            raise InputError("nominal positions must be strictly ascending", file=file, line=k)
        rows.append(vals)  # type: ignore[arg-type]
    if not rows:
        raise InputError("empty compensation file", file=file)
    n, f, r = zip(*rows, strict=True)
    return CompTable(tuple(n), tuple(f), tuple(r))


def trim(table: CompTable, position: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """The trim the controller adds at ``position`` moving in ``direction`` (+1 / -1): linear
    between nominals, held at the end values outside them."""
    pos = np.asarray(position, float)
    fwd = np.interp(pos, table.nominal, table.forward)
    rev = np.interp(pos, table.nominal, table.reverse)
    return np.where(np.asarray(direction) > 0, fwd, rev)


def apply_compensation(run: Run, table: CompTable) -> Run:
    """``run`` as it would have been measured with ``table`` loaded: the trim moves the carriage
    by itself, so each deviation becomes deviation + trim (first order: the error at P + trim is
    taken as the error at P, the trims being micrometres)."""
    dev = run.deviation + trim(table, run.target, run.direction)
    return Run(run.target, run.direction, run.run, dev, run.file)


def heldout_rms(run: Run, table: CompTable) -> tuple[float, float]:
    """RMS deviation (mm) of ``run`` without and with ``table``."""
    after = apply_compensation(run, table).deviation
    return float(np.sqrt(np.mean(run.deviation ** 2))), float(np.sqrt(np.mean(after ** 2)))


# ----------------------------------------------------------------------------------------------
# simulation
def simulate_run(targets: np.ndarray, runs: int = 5, *, pitch_um_per_m: float = 20.0,
                 periodic_um: float = 5.0, period_mm: float = 10.0, reversal_um: float = 18.0,
                 noise_um: float = 1.0, seed: int = 0) -> Run:
    """A bidirectional run at ``targets`` (mm), ``runs`` approaches per direction: deviation =
    pitch * P + periodic * sin(2 pi P / period) - direction * reversal / 2 + white noise (so
    B_j = -reversal: the carriage stops short of the target on each approach, as backlash does)."""
    rng = np.random.default_rng(seed)
    p = np.asarray(targets, float)
    tg, dr, rn = [], [], []
    for r in range(1, runs + 1):  # ISO 230-2 standard test cycle: up through all targets, then down
        tg += [p, p[::-1]]
        dr += [np.ones(p.size, int), -np.ones(p.size, int)]
        rn += [np.full(p.size, r), np.full(p.size, r)]
    target, direction, run = np.concatenate(tg), np.concatenate(dr), np.concatenate(rn)
    dev = systematic(target, direction, pitch_um_per_m=pitch_um_per_m, periodic_um=periodic_um,
                     period_mm=period_mm, reversal_um=reversal_um)
    dev = dev + rng.normal(0.0, noise_um * 1e-3, dev.size)
    return Run(target, direction, run, dev)


def systematic(target: np.ndarray, direction: np.ndarray, *, pitch_um_per_m: float = 20.0,
               periodic_um: float = 5.0, period_mm: float = 10.0, reversal_um: float = 18.0) -> np.ndarray:
    """The noise-free deviation (mm) of ``simulate_run``."""
    p = np.asarray(target, float)
    return 1e-3 * (pitch_um_per_m * 1e-3 * p + periodic_um * np.sin(2 * np.pi * p / period_mm)
                   - np.asarray(direction) * reversal_um / 2)


def write_run_csv(path: str | os.PathLike, run: Run) -> Path:
    """Write ``run`` as a run CSV (``read_run``), atomically."""
    from camsmooth.io.table import write_table

    return write_table(path, {"target": run.target, "direction": run.direction.astype(np.int64),
                              "run": run.run.astype(np.int64), "deviation": run.deviation})
