"""Planted bugs (issues 12, 21, 31): does the test suite catch small plausible bugs?

The last 14 (issue 31) are the slips that passed the whole suite when the issue was filed; each is
now caught by an invariant (tests/test_invariants.py: inch = mm, bulk = record by record, rows
with blank lines, a part turned about C, mirrored poles, cone points in a passage, bounds a
margin inside the samples, a feed drop) or a hand-worked oracle (tests/test_oracles_hand.py:
ISO 230-2 by hand, batch means by a plain loop, CYCLE832 against the Siemens manual), and its
``tests`` name the test that catches it (a node id: the run is seconds, not minutes).

    python benchmarks/planted_bugs.py              # every bug (about 5-10 minutes on 2 cores)
    python benchmarks/planted_bugs.py --only facet,backlash-sign
    python benchmarks/planted_bugs.py --list       # the bugs and their targeted tests, nothing run
    python benchmarks/planted_bugs.py --only row-times --tests tests/test_pipeline.py  # other tests

For each bug: the repository (its tracked and untracked-but-not-ignored files, and the numba
caches under camsmooth/, with their modification times, so unchanged kernels are not compiled
again) is copied to a temporary folder, the bug's textual change applied there (each pattern must
occur exactly once, so the script fails loudly when the code has moved), and the bug's targeted
tests run in the copy (``python -m pytest -x -q <tests>`` with the copy first on PYTHONPATH). A
bug is caught when a test FAILS; the first failing test is printed. First, the targeted tests of
every bug run once on an unchanged copy, which must pass (otherwise "caught" would mean nothing).

Prints a table: where | planted bug | caught (by which test) | seconds. Exit status 1 if any bug
is not caught (or the unchanged copy fails), 0 otherwise. Not part of the test suite (slow).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


@dataclass(frozen=True)
class Bug:
    """A planted bug: ``changes`` are (file, old text, new text), each old text found exactly once
    in its file; ``tests`` the pytest arguments (files, ``-k`` expressions) that should catch it."""

    key: str
    where: str
    what: str
    changes: tuple[tuple[str, str, str], ...]
    tests: tuple[str, ...]


BUGS: tuple[Bug, ...] = (
    # ---- the table of issue 12 ------------------------------------------------------------------
    Bug("cc-to-cl", "`cutter.cc_to_cl`", "`+ R*u` -> `- R*u`",
        (("camsmooth/geometry/cutter.py", "    return cc + cutter.r * (n - T) + cutter.R * u",
          "    return cc + cutter.r * (n - T) - cutter.R * u"),),
        ("tests/test_cutter.py",)),
    Bug("ik-atan2", "`kinematics.inverse_axis` (subproblem 1)", "sign in atan2: the angle turns the wrong way",
        (("camsmooth/machine/kinematics.py", "return np.arctan2(np.cross(up, vp) @ w,",
          "return np.arctan2(-np.cross(up, vp) @ w,"),),
        ("tests/test_kinematics.py", "tests/test_ik_continuity.py", "tests/test_machine_kinds.py")),
    Bug("ik-branch", "`kinematics.inverse_axis` (subproblem 2)", "wrong second branch: the same sign of g twice",
        (("camsmooth/machine/kinematics.py", "for branch, sign in enumerate((1.0, -1.0)):",
          "for branch, sign in enumerate((1.0, 1.0)):"),),
        ("tests/test_kinematics.py", "tests/test_ik_continuity.py", "tests/test_machine_kinds.py")),
    Bug("ik-seed", "`kinematics.solve_row`",
        "reference for the nearest branch held at the row's seed instead of following the previous point",
        (("camsmooth/machine/kinematics.py",
          "        out[i, 0], out[i, 1] = b0, b1\n        ref0, ref1 = b0, b1\n",
          "        out[i, 0], out[i, 1] = b0, b1\n"),),
        ("tests/test_kinematics.py", "tests/test_ik_continuity.py")),
    Bug("metrics-vmax", "`pipeline` metrics (`nlp.limit_violations`)",
        "velocity violations counted against amax instead of vmax",
        (("camsmooth/smoothing/nlp.py", "np.sum(v > lim.vmax * (1 + rel) + slack_v)",
          "np.sum(v > lim.amax * (1 + rel) + slack_v)"),),
        ("tests/test_oracles.py", "tests/test_pipeline.py")),
    Bug("backlash-sign", "diagnosis simulator, backlash", "sign of the half play flipped",
        (("camsmooth/diagnosis/simulator.py", "y = y - 0.5 * b * self.kn.direction(a)[k]",
          "y = y + 0.5 * b * self.kn.direction(a)[k]"),),
        ("tests/test_oracles.py", "tests/test_diagnosis_terms.py")),
    Bug("backlash-size", "diagnosis simulator, backlash", "size scaled by 1.1",
        (("camsmooth/diagnosis/simulator.py", "y = y - 0.5 * b * self.kn.direction(a)[k]",
          "y = y - 0.55 * b * self.kn.direction(a)[k]"),),
        ("tests/test_oracles.py", "tests/test_diagnosis_terms.py")),
    Bug("trilateration-D", "calibration, ballbar trilateration", "sign of the two-height separation D",
        (("camsmooth/machine/calibration.py", "D = cir.L0 * (math.sin(cir.angles[lo]) - math.sin(cir.angles[hi]))",
          "D = cir.L0 * (math.sin(cir.angles[hi]) - math.sin(cir.angles[lo]))"),),
        ("tests/test_oracles.py", "tests/test_calibration.py")),
    Bug("csv-in-place", "`output.write_result_csv`", "writes in place instead of atomically",
        (("camsmooth/smoothing/output.py", "    return write_table(path, columns)\n",
          "    import polars as pl\n\n"
          "    Path(path).parent.mkdir(parents=True, exist_ok=True)\n"
          "    pl.DataFrame({k: np.asarray(v) for k, v in columns.items()}).write_csv(path, line_terminator='\\n')\n"
          "    return Path(path)\n"),),
        ("tests/test_output.py", "tests/test_failure_injection.py")),
    Bug("facet", "clearance facet test (`geometry/_kernels.py`, numba)", "sign flip of the facet distance",
        (("camsmooth/geometry/_kernels.py", "val = side * hh - off", "val = -side * hh - off"),),
        ("tests/test_interference.py",)),
    # ---- modules the table misses ----------------------------------------------------------
    Bug("feed-vmax", "feed planner `_xmax`", "axis velocity bound taken from amax",
        (("camsmooth/smoothing/feed.py", "np.min((rp.vmax / np.abs(rp.dq)) ** 2, axis=1)",
          "np.min((rp.amax / np.abs(rp.dq)) ** 2, axis=1)"),),
        ("tests/test_feed.py",)),
    Bug("map-bisection", "accessibility map", "bisection keeps the wrong half of the bracket",
        (("camsmooth/geometry/accessibility.py", "good, bad = np.where(ok, mid, good), np.where(ok, bad, mid)",
          "good, bad = np.where(ok, good, mid), np.where(ok, mid, bad)"),),
        ("tests/test_accessibility.py",)),
    Bug("gcode-minutes", "G-code writer, inverse-time feed", "block time in seconds instead of minutes (F 60x low)",
        (("camsmooth/post/writer.py", "t = L / mv.feed[cut]  # minutes", "t = 60.0 * L / mv.feed[cut]  # minutes"),),
        ("tests/test_gcode.py", "tests/test_output.py")),
    Bug("table-blank-rows", "table reader", "data rows numbered from 0 when the file has blank lines",
        (("camsmooth/io/table.py", "rows = np.asarray(keep, dtype=np.int64) + 1",
          "rows = np.asarray(keep, dtype=np.int64)"),),
        ("tests/test_formats.py",)),
    Bug("nlp-B-velocity", "row NLP bounds", "B velocity bounded by A's vmax (copy-paste)",
        (("camsmooth/smoothing/nlp.py", "np.full(n - 1, -lb.vmax)", "np.full(n - 1, -la.vmax)"),
         ("camsmooth/smoothing/nlp.py", "np.full(n - 1, lb.vmax)", "np.full(n - 1, la.vmax)")),
        ("tests/test_limits_bind.py",)),
    Bug("nlp-B-travel", "row NLP bounds", "B travel bounded by A's travel (copy-paste)",
        (("camsmooth/smoothing/nlp.py", "la.min, la.max, lb.min, lb.max", "la.min, la.max, la.min, la.max"),),
        ("tests/test_limits_bind.py",)),
    Bug("row-times", "`pipeline.row_times`", "feed taken as mm/s (the /60 forgotten)",
        (("camsmooth/smoothing/pipeline.py", "seg / (feed_mm_min[1:] / 60.0)", "seg / feed_mm_min[1:]"),),
        ("tests/test_limits_bind.py", "tests/test_pipeline.py")),
    Bug("atomic-temp", "`atomic.atomic_path`", "the temporary is not removed when the writer fails",
        (("camsmooth/io/atomic.py", "    finally:\n        if tmp_path.exists():\n            tmp_path.unlink()\n",
          "    finally:\n        pass\n"),),
        ("tests/test_atomic.py", "tests/test_failure_injection.py")),
    Bug("commit-undo", "`atomic.OutputTransaction.commit`", "a failed commit does not put the first outputs back",
        (("camsmooth/io/atomic.py", "                for u in reversed(undo):\n", "                for u in []:\n"),),
        ("tests/test_failure_injection.py",)),
    Bug("strict-writes", "`cli smooth --strict`", "the refusal comes after the outputs are written",
        (("camsmooth/cli/main.py",
          "            raise StrictFailure(failure)\n",
          "            pass\n"),
         ("camsmooth/cli/main.py",
          "                       setup=None if posted is not None else _shop_setup(args, program))\n"
          "    if not args.quiet:\n",
          "                       setup=None if posted is not None else _shop_setup(args, program))\n"
          "    if failure:  # after the transaction: the outputs are in place\n"
          "        raise StrictFailure(failure)\n    if not args.quiet:\n")),
        ("tests/test_cli_verbs.py",)),
    # ---- issue 21 item 5: the classes the whole suite missed ----------------------------------------
    Bug("branch-count-side", "`analysis` branch label (class c)",
        "points on the branch boundary (|B| = 90 deg) counted on the second branch",
        (("camsmooth/machine/kinematics.py", "return (z @ np.cross(w1, w2) < -1e-12).astype(int)",
          "return (z @ np.cross(w1, w2) < 1e-12).astype(int)"),),
        ("tests/test_analysis.py",)),
    Bug("gcode-end-g94", "G-code writer, program end (class e)",
        "machine mode leaves the controller in G93 (the G94 back put in TCP mode's end instead)",
        (("camsmooth/post/writer.py", '    if mode == "machine" and d.per_minute:\n',
          '    if mode == "tcp" and d.per_minute:\n'),),
        ("tests/test_gcode.py",)),
    Bug("analysis-times-feed", "`analysis._times` (class d)",
        "each block timed at the feed of the block before it (the feed that starts at the point)",
        (("camsmooth/smoothing/analysis.py", "/ (feed[1:] / 60.0)]", "/ (feed[:-1] / 60.0)]"),),
        ("tests/test_analysis.py",)),
    Bug("apt-bulk-inches", "APT reader, the bulk GOTO path (class b)", "runs of 16+ GOTOs not converted from inches",
        (("camsmooth/io/apt.py", "    return P * scale, T\n", "    return P, T\n"),),
        ("tests/test_apt_records.py",)),
    Bug("travel-max-slack", "`nlp.limit_violations` travel (class a)",
        "the resolution slack subtracted at the travel max (copied from the min side)",
        (("camsmooth/smoothing/nlp.py", "(q > lim.max + 1e-9 + e)", "(q > lim.max - 1e-9 - e)"),),
        ("tests/test_nlp.py",)),
    Bug("ceiling-shift-up", "accessibility `_fit_bound` (class a)",
        "the fitted lead ceiling shifted up onto its samples like the floor, so it cuts below them",
        (("camsmooth/geometry/accessibility.py", "c[:, 0] += -shift if upper else shift", "c[:, 0] += shift"),),
        ("tests/test_accessibility.py",)),
    Bug("row-times-shift", "`pipeline.row_times` (class d)", "each block timed at the feed of the block before it",
        (("camsmooth/smoothing/pipeline.py", "seg / (feed_mm_min[1:] / 60.0)", "seg / (feed_mm_min[:-1] / 60.0)"),),
        ("tests/test_pipeline.py",)),
    # ---- issue 31: the slips the whole suite missed, each caught by an invariant or a hand oracle -----
    Bug("ceiling-margin", "accessibility `clear_region`", "the lead ceiling moved up by its margin instead of down",
        (("camsmooth/geometry/accessibility.py", "    ceiling[:, 0] -= margin\n", "    ceiling[:, 0] += margin\n"),),
        ("tests/test_invariants.py::test_clear_region_bounds_sit_a_margin_inside_every_sample",)),
    Bug("apt-bulk-axis", "APT reader, the bulk GOTO path",
        "a run of 16+ six-number GOTOs does not leave its last tool axis modal for the 3-number GOTOs after it",
        (("camsmooth/io/apt.py", "                axis = tuple(Tm[-1].tolist())\n", ""),),
        ("tests/test_invariants.py::test_apt_bulk_run_and_record_by_record_agree",)),
    Bug("movarc-inches", "APT reader, MOVARC", "centre and radius not converted from inches",
        (("camsmooth/io/apt.py", 'arc = _Arc(np.array(v[:3]) * st.scale, normal, v[6] * st.scale, rec.line, "MOVARC",',
          'arc = _Arc(np.array(v[:3]), normal, v[6], rec.line, "MOVARC",'),),
        ("tests/test_invariants.py::test_apt_inch_and_mm_programs_read_the_same",)),
    Bug("table-error-row", "`Table.error`", "the row of a record taken as its index + 1 (wrong after a blank line)",
        (("camsmooth/io/table.py", "row = None if index is None else int(self.rows[int(index)])",
          "row = None if index is None else int(index) + 1"),),
        ("tests/test_invariants.py::test_error_rows_are_the_file_lines_minus_one",)),
    Bug("c-unwind-one-turn", "`Machine.inverse_candidates`", "candidates searched one turn either way instead of two",
        (("camsmooth/machine/kinematics.py", "shifts = 2 * np.pi * np.arange(-2, 3)",
          "shifts = 2 * np.pi * np.arange(-1, 2)"),),
        ("tests/test_invariants.py::test_c_follows_a_part_turned_several_times_both_ways",)),
    Bug("outer-turn-sign", "`Machine.nearest_with_outer`", "the tool axis turned back by +outer instead of -outer",
        (("camsmooth/machine/kinematics.py", "back = exp_twist(w1, np.zeros(3), -outer)",
          "back = exp_twist(w1, np.zeros(3), outer)"),),
        ("tests/test_invariants.py::test_pole_start_keeps_the_tool_axis_within_the_pole_angle",)),
    Bug("pole-angle-abs", "`Machine.pole_angle`", "no absolute value: the far pole (T toward -w) is missed",
        (("camsmooth/machine/kinematics.py", "return np.arccos(np.clip(np.abs(T @ w1), 0.0, 1.0))",
          "return np.arccos(np.clip(T @ w1, 0.0, 1.0))"),),
        ("tests/test_invariants.py::test_mirrored_pole_passages_give_mirrored_tilts",)),
    Bug("passage-short", "`pole._runs`", "a passage ends one point before the last point inside the cone",
        (("camsmooth/smoothing/pole.py", "(np.flatnonzero(d == -1) - 1).tolist()",
          "(np.flatnonzero(d == -1) - 2).tolist()"),),
        ("tests/test_invariants.py::test_every_point_inside_the_cone_is_in_a_passage",)),
    Bug("cycle832-blend", "G-code writer, Siemens", "CYCLE832 written with the blend share instead of the tolerance",
        (("camsmooth/post/siemens.py", 'path_tolerance=("CYCLE832({tol}, _FINISH, 1)",)',
          'path_tolerance=("CYCLE832({blend}, _FINISH, 1)",)'),),
        ("tests/test_oracles_hand.py::test_siemens_cycle832_carries_the_tolerance",)),
    Bug("iso-R-max", "ISO 230-2 `evaluate`", "bidirectional repeatability without the max over the unidirectional ones",
        (("camsmooth/diagnosis/iso230.py", "rbi = np.maximum.reduce([2 * su + 2 * sd + np.abs(b), ru, rd])",
          "rbi = 2 * su + 2 * sd + np.abs(b)"),),
        ("tests/test_oracles_hand.py::test_iso230_figures_match_the_hand_worked_example",)),
    Bug("iso-B-abs", "ISO 230-2 `evaluate`", "axis reversal B the largest signed B_j (a negative reversal lost)",
        (("camsmooth/diagnosis/iso230.py", "B=float(np.max(np.abs(b)))", "B=float(np.max(b))"),),
        ("tests/test_oracles_hand.py::test_iso230_figures_match_the_hand_worked_example",)),
    Bug("batch-weight", "`significance.batch_sum_sd`", "batch sums compared with their mean, not weighted by length",
        (("camsmooth/diagnosis/significance.py", "dev = sums - np.diff(edges)[:, None] * Y.mean(axis=0)",
          "dev = sums - sums.mean(axis=0)"),),
        ("tests/test_oracles_hand.py::test_batch_sum_sd_matches_a_plain_reference",)),
    Bug("apt-mmpr", "APT reader, FEDRAT", "MMPR (mm per revolution) read as mm per minute",
        (("camsmooth/io/apt.py", '"MMPR": ("mm", True)', '"MMPR": ("mm", False)'),),
        ("tests/test_invariants.py::test_apt_feed_units_give_the_same_feed",)),
    Bug("jerk-piece-feed", "`jerk._piece_feed`", "a piece's feed bound the smaller of its ends (min for max)",
        (("camsmooth/smoothing/jerk.py", "return np.maximum(rp.feed_bound[:-1], rp.feed_bound[1:])",
          "return np.minimum(rp.feed_bound[:-1], rp.feed_bound[1:])"),),
        ("tests/test_invariants.py::test_a_feed_drop_mid_row_costs_no_more_than_the_lower_feed",)),
)


def _copy_repo(dst: Path) -> None:
    """Tracked and untracked-but-not-ignored files of the repository, and the numba caches (with
    their modification times, so unchanged kernels load from the cache)."""
    out = subprocess.run(["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard"], cwd=ROOT,
                         capture_output=True, check=True).stdout.decode()
    names = [n for n in out.split("\0") if n]
    for cache in (ROOT / "camsmooth").rglob("__pycache__"):
        names += [str(p.relative_to(ROOT)) for p in cache.iterdir() if p.suffix in (".nbi", ".nbc")]
    for name in names:
        src = ROOT / name
        if not src.is_file():
            continue  # deleted in the working tree
        target = dst / name
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, target)


def _apply(copy: Path, bug: Bug) -> None:
    """Apply the bug's changes in ``copy``; SystemExit when a pattern does not occur exactly once."""
    for file, old, new in bug.changes:
        p = copy / file
        text = p.read_text()
        count = text.count(old)
        if count != 1:
            raise SystemExit(f"planted bug {bug.key}: the pattern occurs {count} times in {file} (expected once; "
                             f"has the code moved?):\n{old}")
        p.write_text(text.replace(old, new))


def _check_patterns(root: Path, scratch: Path, bug: Bug) -> None:
    """Apply the bug to a scratch copy of the files it changes (SystemExit when a pattern does not
    occur exactly once), then remove the copy."""
    for file, _, _ in bug.changes:
        (scratch / file).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(root / file, scratch / file)
    _apply(scratch, bug)
    shutil.rmtree(scratch)


def _pytest(copy: Path, tests: tuple[str, ...], timeout: float) -> tuple[int, str, float]:
    env = dict(os.environ, PYTHONPATH=str(copy), PYTHONDONTWRITEBYTECODE="1")
    t0 = time.perf_counter()
    p = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-rfE", "-p", "no:cacheprovider", *tests],
                       cwd=copy, env=env, capture_output=True, text=True, timeout=timeout)
    return p.returncode, p.stdout + p.stderr, time.perf_counter() - t0


def _first_failure(output: str) -> str:
    m = re.search(r"^(FAILED|ERROR) (.+?)(?: - |$)", output, re.M)
    if not m:
        return "?"
    return m.group(2) if m.group(1) == "FAILED" else f"{m.group(2)} (error in its set-up)"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--only", default=None, help="comma-separated bug keys (see --list)")
    ap.add_argument("--list", action="store_true", help="list the bugs and their tests, run nothing")
    ap.add_argument("--check", action="store_true", help="check that every pattern occurs once, run nothing")
    ap.add_argument("--tests", nargs="+", default=None,
                    help="run these pytest arguments instead of each bug's targeted tests (which tests miss a bug?)")
    ap.add_argument("--no-baseline", action="store_true", help="skip the run on the unchanged copy")
    ap.add_argument("--timeout", type=float, default=1800.0, help="seconds per pytest run")
    args = ap.parse_args(argv)
    bugs = BUGS
    if args.only:
        keys = args.only.split(",")
        unknown = set(keys) - {b.key for b in BUGS}
        if unknown:
            ap.error(f"unknown bug(s): {', '.join(sorted(unknown))}")
        bugs = tuple(b for b in BUGS if b.key in keys)
    if args.tests:
        bugs = tuple(Bug(b.key, b.where, b.what, b.changes, tuple(args.tests)) for b in bugs)
    if args.list:
        for b in bugs:
            print(f"{b.key:18s} {b.where}: {b.what}  [{' '.join(b.tests)}]")
        return 0
    if args.check:
        with tempfile.TemporaryDirectory(prefix="camsmooth-planted-") as tmp:
            for b in bugs:
                _check_patterns(ROOT, Path(tmp) / b.key, b)
        print(f"every pattern of {len(bugs)} planted bugs occurs exactly once")
        return 0

    failed = False
    with tempfile.TemporaryDirectory(prefix="camsmooth-planted-") as tmp:
        base = Path(tmp) / "base"
        _copy_repo(base)
        for b in bugs:  # every pattern is checked before anything runs
            _check_patterns(base, Path(tmp) / "check", b)
        if not args.no_baseline:
            tests = tuple(dict.fromkeys(t for b in bugs for t in b.tests))
            rc, out, dt = _pytest(base, tests, args.timeout)
            print(f"unchanged copy: {' '.join(tests)}: {'pass' if rc == 0 else 'FAIL'} ({dt:.0f} s)", flush=True)
            if rc != 0:
                print(out[-3000:])
                return 1
        rows = []
        for b in bugs:
            copy = Path(tmp) / b.key
            shutil.copytree(base, copy)
            _apply(copy, b)
            rc, out, dt = _pytest(copy, b.tests, args.timeout)
            if rc == 1:
                caught = f"yes: {_first_failure(out)}"
            elif rc == 0:
                caught, failed = "**no**", True
            else:  # collection error, usage error, interrupted: not a clean catch
                caught, failed = f"**error** (pytest exit {rc})", True
                print(out[-2000:])
            rows.append((b.where, b.what, caught, dt))
            print(f"  {b.key}: {caught} ({dt:.0f} s)", flush=True)
            shutil.rmtree(copy, ignore_errors=True)
    print()
    print("| where | planted bug | caught (by which test) | s |")
    print("|---|---|---|---|")
    for where, what, caught, dt in rows:
        print(f"| {where} | {what} | {caught} | {dt:.0f} |")
    n_caught = sum(r[2].startswith("yes") for r in rows)
    print(f"\n{n_caught} of {len(rows)} planted bugs caught")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
