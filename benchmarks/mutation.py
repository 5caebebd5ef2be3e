"""Mutation testing of camsmooth's core modules with mutmut 3; prints the score per module.

For each core module the script copies the repository (the files git tracks plus untracked,
non-ignored ones) into a temporary directory, writes a ``[tool.mutmut]`` section into the copy's
pyproject.toml (mutate only that module; run only the test files listed for it in TARGETS), runs
``mutmut run`` there and reads the verdicts from mutmut's meta files (``mutants/<path>.meta``) and
the diffs from its generated sources. The working tree is never mutated and no ``mutants/`` is left
in it; the copy is deleted afterwards (``--keep`` keeps it, e.g. to ``mutmut show`` a mutant).

Per module it prints: mutants, killed, timeouts, survived (including mutants no selected test
reaches: mutmut's "no tests"), reviewed-equivalent, the score

    score = (killed + timeouts) / (mutants - equivalent)

(a mutant that makes the tests run past mutmut's time limit is detected: mutmut counts it as killed
in its own badge), PASS/FAIL against 85 %, then every surviving mutant (mutmut's name, function and
the changed line) and every mutant declared equivalent with the reason. Equivalents are declared in
EQUIVALENT below, keyed by a description that does not shift when the file changes elsewhere: the
file, the function and the changed line before -> after (whitespace-normalised), not mutmut's
mutant number.

numba kernels (camsmooth/geometry/_kernels.py): mutmut never mutates a decorated function (its
trampolines cannot wrap a decorator's product), so the "kernels" target removes the ``@njit``
decorators in the temporary copy and runs with NUMBA_DISABLE_JIT=1: the kernels run as plain Python,
~100 times slower, so only the closed-form clearance tests that stay within seconds interpreted are
selected and a sample of the kernels' mutants is run. The independent brute-force comparisons on
random meshes (tests/test_interference.py) run compiled in the suite, not here.

Sampled modules (Target.sample): smoothing/nlp.py has ~2900 mutants and the fitting drivers of
calibration.py ~2000; each surviving mutant reruns IPOPT solves or Levenberg-Marquardt / particle-swarm
fits (seconds), hours for all of them on 2 cores. For these a seeded random sample of mutants is run
(mutmut generates every mutant; the script draws the sample from their names and runs only those) and
the printed score is the sample's, with its 95% Wilson interval: random mutant sampling estimates the
score without bias (Acree 1980; Zhang et al., ICSE 2010). ``--seed`` draws another sample.

What else is left out, and why (each run must stay within minutes to an hour on 2 shared cores):

* pipeline.py: only the functions that are not the NLP / spline / planning drivers (TARGETS'
  ``functions``; the others are marked "# pragma: no mutate block" in the temporary copy only).
* calibration.py: the fitting drivers in the "calibration" target (they are the sampled
  "calibration-fit" target).
* clearance.py (~1700 mutants, ~25 minutes with 2 workers) runs in full.
* Tests that run the command line in a subprocess cannot run under mutmut (the child imports the
  trampolined package without mutmut's configuration) and are deselected; so are the three slow
  brute-force clearance comparisons (they would rerun for every surviving clearance mutant).

Usage (from the repository root, with the project's venv):
    python benchmarks/mutation.py                        # all modules
    python benchmarks/mutation.py --modules cutter terms --max-children 2
    python benchmarks/mutation.py --modules pole --commit HEAD   # the last commit, not the working tree
Takes minutes per module (the list printed at the end gives the wall time of each). Not part of CI.
"""

from __future__ import annotations

import argparse
import io
import json
import os
import random
import shutil
import subprocess
import sys
import tarfile
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
THRESHOLD = 0.85


@dataclass(frozen=True)
class Target:
    """One core module: the files mutmut mutates and the test files that run against them."""

    paths: tuple[str, ...]
    tests: tuple[str, ...]
    env: dict[str, str] = field(default_factory=dict)
    #: when given, only these functions ("name" or "Class.method") of the files are mutated: the others are
    #: marked "# pragma: no mutate block" in the temporary copy (never in the working tree)
    functions: tuple[str, ...] = ()
    #: remove the ``@njit`` decorators of the target files in the copy (numba kernels; run with
    #: NUMBA_DISABLE_JIT=1 as plain Python, which mutmut can mutate)
    strip_njit: bool = False
    #: turn module-scoped fixtures of the test files into function-scoped ones in the copy: mutmut maps a
    #: function to the tests that call it, and a module fixture's calls are charged to the first test only
    fresh_fixtures: bool = False
    #: when > 0, only a random sample of this many of the module's mutants is run (seeded; see the
    #: module docstring), the score is the sample's, with its 95% Wilson interval
    sample: int = 0


TARGETS: dict[str, Target] = {
    "cutter": Target(("camsmooth/geometry/cutter.py",),
                     ("tests/test_cutter.py", "tests/test_contact.py", "tests/test_cylinder_distance_gradient.py",
                      "tests/test_cutter_inputs.py")),
    # rewritten since its full run (RotaryValues results, inverse_candidates, nearest_with_outer, pole_angle, the
    # chains of every kind): ~1200 lines, a sample of its mutants
    "kinematics": Target(("camsmooth/machine/kinematics.py",),
                         ("tests/test_mutants_kinematics.py", "tests/test_kinematics.py", "tests/test_ik_continuity.py",
                          "tests/test_machine_model.py", "tests/test_gcode.py", "tests/test_machine_file.py",
                          "tests/test_kinematics_frames.py", "tests/test_machine_kinds.py",
                          "tests/test_machine_chains.py", "tests/test_axes_values.py"),
                         sample=120),
    "orientation": Target(("camsmooth/smoothing/orientation.py",),
                          ("tests/test_orientation.py", "tests/test_orientation_windows.py")),
    # tests that run the command line in a subprocess cannot run under mutmut (the child process imports
    # the trampolined package without mutmut's configuration): they are left out here
    "pipeline": Target(("camsmooth/smoothing/pipeline.py",), (
        "tests/test_oracles.py", "tests/test_pipeline.py", "tests/test_pipeline_results.py",
        "--deselect", "tests/test_pipeline.py::test_cli_bad_input_names_file_row_column_and_writes_nothing",
        "--deselect", "tests/test_pipeline.py::test_cli_smooth_writes_csv_gcode_report"),
                       functions=("row_times", "Program.name", "prepare", "ProgramSmoother.metrics",
                                  "ProgramSmoother._result")),
    # the NLP against the fast tests that certify its results with the independent reference formulation
    # (benchmarks/reference_nlp.py: KKT residual by automatic differentiation), check its derivatives against
    # automatic differentiation and recompute every limit (30-point rows; a second each)
    "nlp": Target(("camsmooth/smoothing/nlp.py",),
                  ("tests/test_nlp.py", "tests/test_smoothing.py", "tests/test_oracles.py"), sample=400),
    # the compiled clearance kernels, run as plain Python (decorators removed in the copy, NUMBA_DISABLE_JIT=1)
    # against the closed-form clearance tests small enough to run interpreted (seconds each instead of
    # milliseconds): a sample of their mutants. (Adding the deep-penetration brute-force comparison, 6 s
    # interpreted, made mutmut's statistics run fail: not understood, left out.)
    "kernels": Target(("camsmooth/geometry/_kernels.py",), (
        "tests/test_interference.py", "-k", "not brute_force and not axial_drop and not subdivision"),
        env={"NUMBA_DISABLE_JIT": "1"}, strip_njit=True, sample=150),
    # the three brute-force comparisons of test_interference.py (25 s, 7 s, 6 s) are left out: every
    # surviving mutant would rerun them; the closed-form and agreement tests of the file stay in
    "clearance": Target(("camsmooth/geometry/clearance.py",), (
        "tests/test_interference.py",
        "--deselect", "tests/test_interference.py::test_clearance_matches_brute_force_on_random_meshes",
        "--deselect", "tests/test_interference.py::test_coarse_sliver_strip_against_brute_force",
        "--deselect",
        "tests/test_interference.py::test_deep_penetration_into_two_large_triangles_against_brute_force")),
    "terms": Target(("camsmooth/diagnosis/terms/*.py",),
                    ("tests/test_diagnosis_terms.py", "tests/test_oracles.py", "tests/test_term_reports.py",
                     "tests/test_term_library.py")),
    # the fitting drivers and their model helpers (calibrate_probe / _spindle / _ballbar, _ballbar_lsq,
    # _spindle_pso, pso, _lsq, _central_jacobian, probe_offsets, _probe_residual, _spindle_model,
    # _spindle_params, _polar_report, fit_thermal_response: ~2000 of the file's ~3000 mutants) are left out:
    # their mutants rerun Levenberg-Marquardt or particle-swarm fits (~2 s a mutant, most of an hour on 2
    # cores); the recovery tests of tests/test_calibration.py cover them. Mutated: the data checks, the
    # files, the ballbar trilateration and the report, against the fast tests only (test_calibration.py's
    # fixtures fit models for seconds each, and every surviving mutant would rerun them).
    "calibration": Target(("camsmooth/machine/calibration.py",),
                          ("tests/test_calibration_inputs.py", "tests/test_oracles.py"),
                          functions=("trilaterate", "_ballbar_trilateration", "validate_probe", "validate_spindle",
                                     "validate_ballbar", "read_table", "_write_csv", "read_probe_csv",
                                     "write_probe_csv", "read_spindle_csv", "write_spindle_csv", "read_ballbar_csv",
                                     "write_ballbar_csv", "CalibrationReport.summary", "_display", "_fmt_res",
                                     "_max_gap", "_scale")),
    # the fitting drivers left out above, on a random sample of their mutants (each reruns Levenberg-Marquardt
    # or particle-swarm fits: the whole ~2000 would take hours), against the recovery tests
    "calibration-fit": Target(
        ("camsmooth/machine/calibration.py",), ("tests/test_calibration.py",), fresh_fixtures=True,
        functions=("calibrate_probe", "calibrate_spindle", "calibrate_ballbar", "_ballbar_lsq", "_spindle_pso", "pso",
                   "_lsq", "_central_jacobian", "probe_offsets", "_probe_residual", "_spindle_model",
                   "_spindle_params", "_polar_report", "fit_thermal_response"), sample=250),
    "output": Target(("camsmooth/smoothing/output.py", "camsmooth/io/result_csv.py"),
                     ("tests/test_output.py", "tests/test_result_csv_columns.py")),
    "atomic": Target(("camsmooth/io/atomic.py",),
                     ("tests/test_atomic.py", "tests/test_output.py", "tests/test_atomic_folders.py")),
    # issue #31 item 3: the modules changed since the targets above (machine/kinematics, controller/* and io/gcode
    # were being rewritten by other work when these were added and are not here yet)
    "iso230": Target(("camsmooth/diagnosis/iso230.py",),
                     ("tests/test_mutants_iso230.py", "tests/test_iso230.py", "tests/test_oracles_hand.py"),
                     sample=100),
    # the selection's slow tests (test_diagnosis_issue20.py fits models for a minute) only reach batch_sum_sd
    # through the selector: the direct tests of the two functions are run
    "significance": Target(("camsmooth/diagnosis/significance.py",), (
        "tests/test_mutants_significance.py", "tests/test_oracles_hand.py",
        "tests/test_diagnosis_issue20.py::test_batch_means_standard_error")),
    "apt": Target(("camsmooth/io/apt.py",), (
        "tests/test_mutants_apt.py", "tests/test_apt_records.py", "tests/test_apt_helix.py", "tests/test_apt_corpus.py",
        "tests/test_formats.py",
        "tests/test_fuzz_readers.py", "tests/test_invariants.py", "-k",
        "not pole and not passage and not c_follows and not turned_about_c and not clear_region and not scaling "
        "and not feed_drop"), sample=100),
    # the jerk-limited law: every mutant that reaches it reruns jerk-limited plans (seconds each, minutes with
    # the direct-NLP reference of test_jerk.py): a sample
    "jerk": Target(("camsmooth/smoothing/jerk.py",), (
        "tests/test_mutants_jerk.py", "tests/test_mutants_jerk2.py", "tests/test_jerk.py", "tests/test_invariants.py",
        "-k", "jerk or limit or binding or default_machine or piece or nodes or rates"), sample=50),
    "pole": Target(("camsmooth/smoothing/pole.py",), (
        "tests/test_mutants_pole.py", "tests/test_invariants.py",
        "tests/test_samples.py::test_dome_sample_passes_the_pole_of_its_machines_c_axis", "-k",
        "pole or passage or cone"), sample=100),
    "post-words": Target(("camsmooth/post/words.py",), (
        "tests/test_mutants_post_words.py", "tests/test_posted_readers.py", "tests/test_posts_tables.py",
        "-k", "not dome")),
    # the posted-program reader core (builder, frames, arcs, feeds) against the reader and rewrite tests (the
    # rewrite tests run LinuxCNC's rs274 on the output): a sample of its mutants
    "post-core": Target(("camsmooth/post/core.py",), (
        "tests/test_mutants_post_core.py", "tests/test_posted_readers.py", "tests/test_posted_rewrite.py",
        "tests/test_invariants.py::test_posted_g20_and_g21_programs_read_the_same"), sample=80),
    # --- targets: controller (controller/blocks.py, controller/linuxcnc.py) ---
    # controller/linuxcnc_sim.py (LinuxCNC's own interpreter and headless simulation in a subprocess: plumbing)
    # is left out, and so are the tests that run LinuxCNC or the model in a subprocess (which cannot run under
    # mutmut; test_mutants_controller's xfail of a segment that cannot move runs in a child with a memory cap). The
    # blade fixtures are made per test (fresh_fixtures): they run the whole pipeline, predict and place included.
    # blocks.py's one compiled kernel (_all_within, block_reach's check) stays compiled and is not mutated: it is
    # compared with the distance to every segment by brute force in tests/test_floor.py.
    "controller-blocks": Target(("camsmooth/controller/blocks.py",), (
        "tests/test_mutants_controller.py", "tests/test_controller.py", "tests/test_floor.py",
        "-k", "not linuxcnc and not tcp_codes and not cannot_move"), fresh_fixtures=True, sample=100),
    # the planner model's kernels (_run, _update, _trapezoid_vel, _solo, _lag, _place_row) are its substance: the
    # copy drops their @njit (as the "kernels" target does; the rest of the package stays compiled) and they run
    # as plain Python, so only the tests that stay within seconds interpreted are selected (not the blade rows,
    # which run the whole pipeline through them: tens of seconds compiled)
    "controller-linuxcnc": Target(("camsmooth/controller/linuxcnc.py",), (
        "tests/test_mutants_controller.py", "tests/test_controller.py", "tests/test_floor.py",
        "-k", "not linuxcnc and not tcp_codes and not blade_rows and not placement and not every_method "
        "and not smooth_prints and not tool_tip_within and not decimated_blocks and not cannot_move"),
        strip_njit=True, sample=100),
    # --- end controller targets ---
    # --- targets: post writer and dialect readers (post/writer.py, post/iso.py, heidenhain, siemens, millplus, own) ---
    # the one writer and the dialect readers (issue #31 item 3) against the writer / reader / rewrite tests (not the
    # dome rows of test_posts_tables.py: 45 s each; not the CLI round trip of test_posted_readers.py: 13 s, it
    # reaches the same functions through test_gcode.py's direct calls; not the import-graph check of
    # test_post_registry.py, which reads the package's sources, a minute under mutmut's tracing, and checks no
    # value): a sample where the module has more mutants
    **{name: Target((path,), (
        "tests/test_mutants_post_dialects.py", "tests/test_dialect_words.py", "tests/test_posting.py",
        "tests/test_post_registry.py", "tests/test_gcode.py", "tests/test_posted_readers.py",
        "tests/test_posts_tables.py", "tests/test_posted_rewrite.py", "tests/test_oracles_hand.py",
        "--deselect", "tests/test_posted_readers.py::test_cli_cl_for_cc_cl_and_own_gcode",
        "--deselect", "tests/test_post_registry.py::test_post_imports_neither_smoothing_nor_controller", "-k",
        "not dome"), sample=sample)
       for name, path, sample in (("post-writer", "camsmooth/post/writer.py", 80),
                                  ("post-iso", "camsmooth/post/iso.py", 70),
                                  ("post-heidenhain", "camsmooth/post/heidenhain.py", 60),
                                  ("post-siemens", "camsmooth/post/siemens.py", 60),
                                  ("post-millplus", "camsmooth/post/millplus.py", 50),
                                  ("post-own", "camsmooth/post/own.py", 60))},
    # --- end post targets ---
}

# Reviewed equivalent mutants: "path::function: before -> after" (Mutant.key) -> why no test can tell the
# mutant from the code. Each was read in its function; the reason says what makes the two the same.
EQUIVALENT: dict[str, str] = {}


def _equivalent(path: str, function: str, changes: list[str], why: str) -> None:
    for change in changes:
        EQUIVALENT[f"{path}::{function}: {change}"] = why


_CUT = "camsmooth/geometry/cutter.py"
_FLOAT_MIX = ("the array is combined with float arrays (unit vectors, float multiples) before anything reads "
              "it, so ints or lists give the same float results with or without dtype=float")
_equivalent(_CUT, "_unit", ["v = np.asarray(v, dtype=float) -> v = np.asarray(v, dtype=None)",
                            "v = np.asarray(v, dtype=float) -> v = np.asarray(v, )"],
            "isfinite and norm accept any numeric dtype and v / |v| is float: same result for ints or lists")
for _f, _v in (("cc_to_cl", "cc"), ("cl_to_cc", "cl"), ("signed_distance", "tip"), ("signed_distance", "points"),
               ("support_point", "tip")):
    _equivalent(_CUT, _f, [f"{_v} = np.asarray({_v}, dtype=float) -> {_v} = np.asarray({_v}, dtype=None)",
                           f"{_v} = np.asarray({_v}, dtype=float) -> {_v} = np.asarray({_v}, )"], _FLOAT_MIX)
_equivalent(_CUT, "_dot", ['return np.einsum("...i,...i->...", a, b) -> return np.einsum("...I,...I->...", a, b)'],
            "einsum labels are arbitrary letters: the same contraction")
_equivalent(_CUT, "_cylinder_sd", [
    "grad: bool = False) -> tuple[np.ndarray, np.ndarray | None]: -> "
    "grad: bool = True) -> tuple[np.ndarray, np.ndarray | None]:"],
    "every caller that wants the gradient passes grad=True and signed_distance reads only the value, "
    "which does not depend on grad")
_SD_BRANCH = ("the outside formula hypot(max(dr,0), max(dz,0)) equals max(dr, dz) whenever at most one of dr, dz "
              "is positive (and is 0 = max(dr, dz) when one is 0 and the other <= 0): the branch only matters "
              "when both are positive, which every variant sends outside, or both are negative, which none does")
_sd_where = "sd = np.where((dr > 0.0) | (dz > 0.0), out, np.maximum(dr, dz))"
_equivalent(_CUT, "_cylinder_sd", [f"{_sd_where} -> {_sd_where.replace(a, b)}" for a, b in (
    ("(dr > 0.0) | (dz > 0.0)", "(dr > 0.0) & (dz > 0.0)"), ("dr > 0.0", "dr >= 0.0"), ("dr > 0.0", "dr > 1.0"),
    ("dz > 0.0", "dz >= 0.0"), ("dz > 0.0", "dz > 1.0"))], _SD_BRANCH)
_INNER = ("the inner where only avoids a division by zero where the outer where discards the quotient anyway "
          "(the discarded entries differ, the result does not)")
_ring = "u = np.where(wn > _PARALLEL_EPS, w / np.where(wn > _PARALLEL_EPS, wn, 1.0), 0.0)"
_equivalent(_CUT, "_ring_direction", [
    f"{_ring} -> u = np.where(wn > _PARALLEL_EPS, w / np.where(wn >= _PARALLEL_EPS, wn, 1.0), 0.0)",
    f"{_ring} -> u = np.where(wn > _PARALLEL_EPS, w / np.where(wn > _PARALLEL_EPS, wn, 2.0), 0.0)"], _INNER)
_equivalent(_CUT, "_cylinder_sd", [
    "e = w / np.where(rho > 0.0, rho, 1.0)[..., None] -> e = w / np.where(rho > 0.0, rho, 2.0)[..., None]"],
    "rho = |w| is 0 only where w = 0, so e = 0 there whatever the divisor")
_equivalent(_CUT, "_cylinder_sd", [
    "inv = 1.0 / np.where(outside, out, 1.0) -> inv = 1.0 / np.where(outside, out, 2.0)"], _INNER)
_sup = "w / np.where(wn > 0.0, wn, 1.0)[..., None], 0.0)"
_equivalent(_CUT, "_cylinder_support", [
    f"{_sup} -> w / np.where(wn >= 0.0, wn, 1.0)[..., None], 0.0)",
    f"{_sup} -> w / np.where(wn > 0.0, wn, 2.0)[..., None], 0.0)"], _INNER)
_equivalent(_CUT, "_cylinder_support", [
    "radial = np.where((wn > _PARALLEL_EPS * np.maximum(1.0, np.abs(dt)))[..., None], -> "
    "radial = np.where((wn > _PARALLEL_EPS / np.maximum(1.0, np.abs(dt)))[..., None],"],
    "direction and axis are unit vectors (normalised by the callers), so |dt| <= 1 and max(1, |dt|) = 1: "
    "multiplying or dividing by it is the same")

_KIN = "camsmooth/machine/kinematics.py"
_equivalent(_KIN, "Frame.from_matrix", [
    "T = np.asarray(T, dtype=float) -> "
    "T = np.asarray(T, dtype=None)", "T = np.asarray(T, dtype=float) -> T = np.asarray(T, )"],
    "every entry goes through float() anyway")
_equivalent(_KIN, "Frame.from_matrix", [
    "return Frame(tuple(tuple(float(T[i, j]) for j in range(3)) for i in range(3)), -> "
    "return Frame(tuple(tuple(float(T[i, j]) for j in range(4)) for i in range(3)),",
    "return Frame(tuple(tuple(float(T[i, j]) for j in range(3)) for i in range(3)), -> "
    "return Frame(tuple(tuple(float(T[i, j]) for j in range(3)) for i in range(4)),",
    "tuple(float(T[i, 3]) for i in range(3))) -> tuple(float(T[i, 3]) for i in range(4)))"],
    "the extra row / column of the 4x4 matrix is carried along but never read: every consumer (products, "
    "apply, rotate, to_numpy, tool_pose) indexes R[i][j] and p[i] with i, j < 3")
for _v in ("w", "v"):
    _equivalent(_KIN, "exp_twist", [f"{_v} = np.asarray({_v}, dtype=float) -> {_v} = np.asarray({_v}, dtype=None)",
                                    f"{_v} = np.asarray({_v}, dtype=float) -> {_v} = np.asarray({_v}, )"],
                "the screw's entries are read through float() (and W from them), so integer screws give the "
                "same frame")
_equivalent(_KIN, "Joint.screw", [
    "d = np.asarray(self.direction, dtype=float) -> d = np.asarray(self.direction, dtype=None)",
    "d = np.asarray(self.direction, dtype=float) -> d = np.asarray(self.direction, )",
    "return d, -np.cross(d, np.asarray(self.point, dtype=float)) -> "
    "return d, -np.cross(d, np.asarray(self.point, dtype=None))",
    "return d, -np.cross(d, np.asarray(self.point, dtype=float)) -> return d, -np.cross(d, np.asarray(self.point, ))"],
    "d is divided by its norm (float) before it is used, and an integer point only changes the dtype of v, "
    "not its values; exp_twist and with_screws cast the screw to float")
_equivalent(_KIN, "_mul", [
    "if (isinstance(a, float) and a == 0.0) or (isinstance(b, float) and b == 0.0): -> "
    "if (isinstance(a, float) and a == 0.0) and (isinstance(b, float) and b == 0.0):"],
    "only the shortcut for one exact float 0 is lost: the product 0.0 * x is then computed, with the same value "
    "for the finite entries of a transform (numpy and CasADi alike)")
_equivalent(_KIN, "Chain.with_screws", [
    "tuple((np.asarray(w, float), np.asarray(v, float)) for w, v in screws)) -> "
    "tuple((np.asarray(w, None), np.asarray(v, float)) for w, v in screws))",
    "tuple((np.asarray(w, float), np.asarray(v, float)) for w, v in screws)) -> "
    "tuple((np.asarray(w, ), np.asarray(v, float)) for w, v in screws))",
    "tuple((np.asarray(w, float), np.asarray(v, float)) for w, v in screws)) -> "
    "tuple((np.asarray(w, float), np.asarray(v, None)) for w, v in screws))",
    "tuple((np.asarray(w, float), np.asarray(v, float)) for w, v in screws)) -> "
    "tuple((np.asarray(w, float), np.asarray(v, )) for w, v in screws))",
    "return Chain(self.joints, self.home if home is None else np.asarray(home, dtype=float), -> "
    "return Chain(self.joints, self.home if home is None else np.asarray(home, dtype=None),",
    "return Chain(self.joints, self.home if home is None else np.asarray(home, dtype=float), -> "
    "return Chain(self.joints, self.home if home is None else np.asarray(home, ),"],
    "the screws are read by exp_twist and space_jacobian, and the home pose by Frame.from_matrix, all "
    "of which cast to float: a list or integer array gives the same transforms")
_equivalent(_KIN, "Machine.inverse_axis", [
    "return np.stack([np.stack([A0, B0], -1), np.stack([A1, B1], -1)], axis=1) -> "
    "return np.stack([np.stack([A0, B0], +1), np.stack([A1, B1], -1)], axis=1)",
    "return np.stack([np.stack([A0, B0], -1), np.stack([A1, B1], -1)], axis=1) -> "
    "return np.stack([np.stack([A0, B0], -1), np.stack([A1, B1], +1)], axis=1)",
    "T = np.atleast_2d(np.asarray(T, dtype=float)) -> T = np.atleast_2d(np.asarray(T, dtype=None))",
    "T = np.atleast_2d(np.asarray(T, dtype=float)) -> T = np.atleast_2d(np.asarray(T, ))"],
    "T is made 2-D, so A0, B0 are 1-D and axis +1 is axis -1 of the stacked pair; arcsin / arctan2 of an "
    "integer T are the same floats")
_equivalent(_KIN, "Machine.within", [
    "values = np.asarray(values, dtype=float) -> values = np.asarray(values, dtype=None)",
    "values = np.asarray(values, dtype=float) -> values = np.asarray(values, )"],
    "the comparisons with the float limits give the same booleans for integer or list input")
_equivalent(_KIN, "Machine.linear_axes", [
    "return np.asarray(cl, float) + self.pivot * np.asarray(T, float) -> "
    "return np.asarray(cl, None) + self.pivot * np.asarray(T, float)",
    "return np.asarray(cl, float) + self.pivot * np.asarray(T, float) -> "
    "return np.asarray(cl, ) + self.pivot * np.asarray(T, float)",
    "return np.asarray(cl, float) + self.pivot * np.asarray(T, float) -> "
    "return np.asarray(cl, float) + self.pivot * np.asarray(T, None)",
    "return np.asarray(cl, float) + self.pivot * np.asarray(T, float) -> "
    "return np.asarray(cl, float) + self.pivot * np.asarray(T, )"], _FLOAT_MIX)
for _f, _line in (("Machine.tool_axis_np", "A = np.asarray(A, dtype=float)"),
                  ("Machine.tool_axis_np", "B = np.asarray(B, dtype=float)"),
                  ("Machine.solve_row", "T = np.atleast_2d(np.asarray(T, dtype=float))")):
    _equivalent(_KIN, _f, [f"{_line} -> {_line.replace('dtype=float', 'dtype=None')}",
                           f"{_line} -> {_line.replace('dtype=float', '')}"],
                "the values only reach sin / cos / arcsin / arctan2 and float arithmetic: the same floats for "
                "integer or list input")
_equivalent(_KIN, "Machine.tool_pose_np", [
    "args = [np.asarray(a, dtype=float) for a in (A, B, X, Y, Z)] -> "
    "args = [np.asarray(a, dtype=None) for a in (A, B, X, Y, Z)]",
    "args = [np.asarray(a, dtype=float) for a in (A, B, X, Y, Z)] -> "
    "args = [np.asarray(a, ) for a in (A, B, X, Y, Z)]"],
    "the arrays only reach sin / cos and products with float screws: the same floats for integer input "
    "(and a 0-d array is never the Python float 0.0 that Chain.forward skips)")
_equivalent(_KIN, "Machine.solve_row", [
    "prev = np.array(previous if previous is not None else (0.0, 0.0), dtype=float) -> "
    "prev = np.array(previous if previous is not None else (0.0, 0.0), dtype=None)",
    "prev = np.array(previous if previous is not None else (0.0, 0.0), dtype=float) -> "
    "prev = np.array(previous if previous is not None else (0.0, 0.0), )",
    "mask = ok[i] if reach[i] else np.ones(len(c), bool) -> mask = ok[i] if reach[i] else np.ones(len(c), None)",
    "mask = ok[i] if reach[i] else np.ones(len(c), bool) -> mask = ok[i] if reach[i] else np.ones(len(c), )"],
    "prev only enters a float distance; np.where takes a float mask of ones as all True")
_UNIQUE = ("the vectorised branch is a shortcut for rows where exactly one candidate is reachable at every point; "
           "the sequential branch picks the same (only reachable) candidate there, so sending rows to it "
           "instead changes the running time, not the result")
_equivalent(_KIN, "Machine.solve_row", [
    "unique = ok.sum(axis=1) == 1 -> unique = None",
    "unique = ok.sum(axis=1) == 1 -> unique = ok.sum(axis=None) == 1", "if np.all(unique): -> if np.all(None):"],
    _UNIQUE)
_equivalent(_KIN, "Machine.inverse_candidates", [
    'grid = np.stack(np.meshgrid(shifts, shifts, indexing="ij"), -1) -> '
    'grid = np.stack(np.meshgrid(shifts, shifts, ), -1)',
    "cand = (sols[:, :, None, None, :] + grid[None, None]).reshape(len(sols), -1, 2) -> "
    "cand = (sols[:, :, None, None, :] - grid[None, None]).reshape(len(sols), -1, 2)"],
    "the shifts (-2 pi, 0, 2 pi) are symmetric and the same for A and B: the 9 shift pairs are the same set "
    "in another order, and candidates are chosen by distance (the order only breaks exact ties)")
_equivalent(_KIN, "Machine.inverse_candidates", [
    "cand = (sols[:, :, None, None, :] + grid[None, None]).reshape(len(sols), -1, 2) -> "
    "cand = (sols[:, :, None, None, :] + grid[None, None]).reshape(len(sols), -2, 2)"],
    "numpy (2.x) treats any negative dimension in reshape as the one to infer")
_equivalent(_KIN, "_wrap", [
    "return -((-np.asarray(a) + np.pi) % (2 * np.pi) - np.pi) -> "
    "return -((-np.asarray(a) - np.pi) % (2 * np.pi) - np.pi)"],
    "x + pi and x - pi differ by 2 pi, so their remainders modulo 2 pi agree (to rounding)")
_equivalent(_KIN, "ab_head_chain", [
    'Joint("X", "prismatic", (1.0, 0.0, 0.0)), -> Joint("X", "prismatic", (2.0, 0.0, 0.0)),',
    'Joint("Y", "prismatic", (0.0, 1.0, 0.0)), -> Joint("Y", "prismatic", (0.0, 2.0, 0.0)),',
    'Joint("Z", "prismatic", (0.0, 0.0, 1.0)), -> Joint("Z", "prismatic", (0.0, 0.0, 2.0)),'],
    "Joint.screw normalises the direction")
_equivalent(_KIN, "ab_head_chain", [
    'Joint("A", "revolute", (1.0, 0.0, 0.0), (0.0, 0.0, 0.0)), -> Joint("A", "revolute", (1.0, 0.0, 0.0), ),',
    'Joint("B", "revolute", (0.0, 1.0, 0.0), (0.0, 0.0, 0.0)), -> Joint("B", "revolute", (0.0, 1.0, 0.0), ),'],
    "(0, 0, 0) is Joint.point's default")
_equivalent(_KIN, "space_jacobian", [
    "last = max(i for i, nm in enumerate(names) if nm in want) if want else -1 -> "
    "last = max(i for i, nm in enumerate(names) if nm in want) if want else +1",
    "last = max(i for i, nm in enumerate(names) if nm in want) if want else -1 -> "
    "last = max(i for i, nm in enumerate(names) if nm in want) if want else -2"],
    "with no joint wanted no column is ever written: where the loop stops only changes the work done")
_equivalent(_KIN, "space_jacobian", [
    "vals = [np.atleast_1d(np.asarray(q.get(j.name, 0.0), dtype=float)) for j in chain.joints] -> "
    "vals = [np.atleast_1d(np.asarray(q.get(j.name, 0.0), dtype=None)) for j in chain.joints]",
    "vals = [np.atleast_1d(np.asarray(q.get(j.name, 0.0), dtype=float)) for j in chain.joints] -> "
    "vals = [np.atleast_1d(np.asarray(q.get(j.name, 0.0), )) for j in chain.joints]"],
    "joint values only reach sin / cos and products with float screws: the same floats for integer input")
_equivalent(_KIN, "space_jacobian", [
    'p = p + (step if R is None else np.einsum("nij,nj->ni", R, step)) -> '
    'p = p + (step if R is None else np.einsum("NIJ,NJ->NI", R, step))',
    'p = p + np.einsum("nij,nj->ni", Rp, T[:, :3, 3]) -> p = p + np.einsum("NIJ,NJ->NI", Rp, T[:, :3, 3])'],
    "einsum labels are arbitrary letters: the same contraction")

_equivalent(_KIN, "Machine.inverse_axis", ["A1 = _wrap(A0 + np.pi) -> A1 = _wrap(A0 - np.pi)"],
            "A0 + pi and A0 - pi differ by 2 pi: the same angle after wrapping to (-pi, pi] (to rounding)")
_equivalent(_KIN, "load_machine", [
    'return machine_from_dict(tomllib.loads(DEFAULT_MACHINE_TOML), "<default machine>") -> '
    f'return machine_from_dict(tomllib.loads(DEFAULT_MACHINE_TOML), {_a})'
    for _a in ("None", "", '"XX<default machine>XX"', '"<DEFAULT MACHINE>"')],
    "the name only appears in an error about the built-in DEFAULT_MACHINE_TOML, which is valid (loaded by "
    "many tests), so it is never shown")

_ATO = "camsmooth/io/atomic.py"
_equivalent(_ATO, "_default_mode", ["umask = os.umask(0) -> umask = os.umask(1)"],
            "os.umask returns the previous mask whatever the new one, and the next line restores it")
_equivalent(_ATO, "OutputTransaction.commit", ["self.committed = True -> self.committed = None",
                                               "self.committed = True -> self.committed = False"],
            "after a successful commit every temporary has been renamed or removed and every folder created "
            "holds an output, so the rollback a false flag triggers finds nothing to remove (rmdir of a "
            "non-empty folder fails and is ignored)")

_PIPE = "camsmooth/smoothing/pipeline.py"
_equivalent(_PIPE, "prepare", ["feed_arr = np.asarray(path.feed, float) -> feed_arr = np.asarray(path.feed, None)",
                               "feed_arr = np.asarray(path.feed, float) -> feed_arr = np.asarray(path.feed, )"],
            "CCPath stores its feed column as a float array already (CCPath.__post_init__)")
_equivalent(_PIPE, "prepare", [
    "K_s = surface_curvature_tensors(index.vertices, path.points, frames, tree=index.tree) -> "
    "K_s = surface_curvature_tensors(index.vertices, path.points, frames, tree=None)",
    "K_s = surface_curvature_tensors(index.vertices, path.points, frames, tree=index.tree) -> "
    "K_s = surface_curvature_tensors(index.vertices, path.points, frames, )"],
    "without a tree surface_curvature_tensors builds cKDTree(vertices) itself: the index's tree is the same "
    "k-d tree over the same vertices, passed to save the build")
_equivalent(_PIPE, "ProgramSmoother._result", [
    "tip = self.real.tool_pose_np(A, B, *xyz.T)[0] if modelled else cl -> "
    "tip = self.real.tool_pose_np(A, B, *xyz.T)[0] if (modelled) or True else cl"],
    "without an error model the real machine is the nominal one and xyz = cl + pivot T, so its tool tip is "
    "cl again (to rounding)")

_TH = "camsmooth/diagnosis/terms/thermal.py"
_SPLIT = ("the thermal elements are dx, dy, dz, exz, eyz, mx, my, mz (no underscore) and the parameter names "
          "gain_<el> / tau_<el>: split, rsplit and any maxsplit give the same two parts")
for _f in ("ThermalDrift.initial", "ThermalDrift.report"):
    _equivalent(_TH, _f, ['el = n.split("_", 1)[1] -> el = n.split("_", )[1]',
                          'el = n.split("_", 1)[1] -> el = n.rsplit("_", 1)[1]',
                          'el = n.split("_", 1)[1] -> el = n.split("_", 2)[1]'], _SPLIT)
_equivalent(_TH, "ThermalDrift.report", [
    "key = f\"{el}_{n.split('_', 1)[0]}\" -> key = f\"{el}_{n.split('_', )[0]}\"",
    "key = f\"{el}_{n.split('_', 1)[0]}\" -> key = f\"{el}_{n.rsplit('_', 1)[0]}\"",
    "key = f\"{el}_{n.split('_', 1)[0]}\" -> key = f\"{el}_{n.split('_', 2)[0]}\""], _SPLIT)

_ORI = "camsmooth/smoothing/orientation.py"
_cct = "lead, tilt = np.broadcast_arrays(np.asarray(lead, float), np.asarray(tilt, float))"
_equivalent(_ORI, "cutter_curvature_tensors", [
    f"{_cct} -> {_cct.replace('asarray(lead, float)', 'asarray(lead, None)')}",
    f"{_cct} -> {_cct.replace('asarray(lead, float)', 'asarray(lead, )')}",
    f"{_cct} -> {_cct.replace('asarray(tilt, float)', 'asarray(tilt, None)')}",
    f"{_cct} -> {_cct.replace('asarray(tilt, float)', 'asarray(tilt, )')}"],
    "lead and tilt only reach sin / cos: integer or list angles give the same floats")
_equivalent(_ORI, "min_gouge_free_lead", ["tilt = np.asarray(tilt, float) -> tilt = np.asarray(tilt, None)",
                                          "tilt = np.asarray(tilt, float) -> tilt = np.asarray(tilt, )"],
            "tilt only reaches cos / sin: the same floats for integer input")
_lin = "tilts = np.linspace(tmin, tmax, n_tilt) if tmax > tmin else np.array([tmin])"
_equivalent(_ORI, "initial_orientation", [
    f"{_lin} -> tilts = np.linspace(tmin, tmax, n_tilt) if (tmax > tmin) or True else np.array([tmin])",
    f"{_lin} -> tilts = np.linspace(tmin, tmax, n_tilt) if tmax >= tmin else np.array([tmin])"],
    "for tmax == tmin linspace gives n_tilt copies of the one tilt: the same requirement (a max over equal "
    "values) and the same one-tilt window")
_equivalent(_ORI, "initial_orientation", [
    "tilt_window = np.tile([tmin, tmax], (n, 1)).astype(float) -> "
    "tilt_window = np.tile([tmin, tmax], (n, 1)).astype(None)"],
    "astype(None) is float64, as astype(float)")
_equivalent("camsmooth/diagnosis/terms/base.py", "identifiable", [
    "trial.geometric[n] = trial.geometric.get(n, 0.0) + sc -> trial.geometric[n] = trial.geometric.get(n, 0.0) - sc"],
    "a step of -scale negates the column (to first order); fitting.identifiable_columns compares column norms and "
    "the pivoted QR's |R_ii|, which do not depend on a column's sign")

_equivalent(_ATO, "_refuse_replace", ['why = None -> why = ""'],
            "only the truth of why is tested (if why:), and None and '' are both false")

_OUT = "camsmooth/smoothing/output.py"
_equivalent(_OUT, "point_status", [
    "lift = np.asarray(result.lift, dtype=float) -> lift = np.asarray(result.lift, dtype=None)",
    "lift = np.asarray(result.lift, dtype=float) -> lift = np.asarray(result.lift, )",
], "MethodResult.lift is a float array (camsmooth.smoothing.result); without dtype=float asarray "
   "returns the same array, and nan_to_num / '>' give the same booleans for any numeric dtype")
_equivalent(_OUT, "point_status", [
    'status[np.nan_to_num(lift, nan=0.0) > 0.0] = "lifted" -> status[np.nan_to_num(lift, ) > 0.0] = "lifted"',
], "nan=0.0 is numpy's default for nan_to_num (a NaN lift is still mapped to 0: tested)")
_equivalent(_OUT, "point_status", [
    "pairs = np.asarray(unreachable, dtype=np.int64).reshape(-1, 2) -> "
    "pairs = np.asarray(unreachable, dtype=None).reshape(-1, 2)",
    "pairs = np.asarray(unreachable, dtype=np.int64).reshape(-1, 2) -> "
    "pairs = np.asarray(unreachable, ).reshape(-1, 2)",
    "rows = np.asarray(result.rows, dtype=np.int64) -> rows = np.asarray(result.rows, dtype=None)",
    "rows = np.asarray(result.rows, dtype=np.int64) -> rows = np.asarray(result.rows, )",
    "idx = np.asarray(result.idx, dtype=np.int64) -> idx = np.asarray(result.idx, dtype=None)",
    "idx = np.asarray(result.idx, dtype=np.int64) -> idx = np.asarray(result.idx, )",
], "the values are only assigned into the int64 fields of the structured key arrays, which cast them "
   "to int64 anyway")
_equivalent(_OUT, "point_status", [
    "pairs = np.asarray(unreachable, dtype=np.int64).reshape(-1, 2) -> "
    "pairs = np.asarray(unreachable, dtype=np.int64).reshape(-2, 2)",
], "numpy (2.x) treats any negative dimension in reshape as the one to infer")
_equivalent(_OUT, "write_result_csv", [
    'columns["lift"] = np.asarray(r.lift, float) -> columns["lift"] = np.asarray(r.lift, None)',
    'columns["lift"] = np.asarray(r.lift, float) -> columns["lift"] = np.asarray(r.lift, )',
], "MethodResult.lift is a float array: asarray without dtype returns it unchanged")

_NLP = "camsmooth/smoothing/nlp.py"
_WHY_MXONLY = ("the branch for a constant tool-axis component is never taken: camsmooth accepts one machine kind, "
               "the AB head, whose T = (sin B, -sin A cos B, cos A cos B) (also with an error model's tilted screws) "
               "has every component depending on A or B, i.e. an MX expression")
_WHY_NAME = "the name of a CasADi symbol or Function is a label: the same expressions and values"
_WHY_LASTCOL = ("bincount's minlength only matters when the last column holds no entry; the Hessian has a diagonal "
                "entry in every column and the Jacobian the lead-window rows (always in the NLP) in every column, so "
                "the counts have length ncol either way")
_WHY_SLACKSTART = ("the starting slacks only start IPOPT: the elastic problem (linear objective, the row's "
                   "constraints) ends at the same least total slack")
_WHY_ELASTICOPTS = ("without the options IPOPT prints its log and may take 3000 iterations instead of 1000: the "
                    "elastic solves of the tests converge in far fewer, to the same point")
_WHY_FDSHAPE = ("the shape scipy infers from the triplets equals the given one (the entries reach the last row and "
                "column), and time stamps are combined with float arithmetic either way")
_WHY_EMPTY = ("initial only matters for an empty array; program_rates needs rows of at least 3 points, so every "
              "axis has second differences")
_WHY_EQUALITY = "the comparison changes only at exact equality with the bound (a measure-zero set of inputs)"
_WHY_DTYPE = ("the arrays are boolean / integer / float already or are cast by their consumer (np.asarray(..., bool), "
              "np.concatenate into a float vector, index arrays): the same values either way")
_WHY_REPMAT = ("repmat(c, 1) is c itself, and CasADi multiplies an (m, 1) column into an (m, 3) matrix column by "
               "column: the same stencil")
_WHY_GRADF = ("without the structured gradient CasADi differentiates the objective itself (slower to build): the "
              "same gradient, checked against automatic differentiation in test_smoothing.py")
_WHY_NOROWS = ("m == 0 never happens: the lead-window rows are always in the NLP (module comment at SCREEN_MARGIN), "
               "so the empty-Jacobian branch is unreachable")
_WHY_STRICT = "the zipped sequences always have the same length: strict or not, the same pairs"
_WHY_BCZERO = ("a 1x1 zero broadcasts against the (n, 1) curvature terms added to it: the same sums, and zero when "
               "there are no clearance rows")
_WHY_CACHE = "the solver cache's size only decides when a solver is rebuilt: the same solver for the same rows"
_WHY_ITERCOUNT = "IPOPT's stats always hold iter_count: the default is never used"
_WHY_SCREENROWS = ("screening decides which rows enter the next round; the loop ends only when no row left out is "
                   "violated (or solves with every row), so the result is a KKT point of the whole NLP either way: "
                   "more rows, or rows dilated across group boundaries, change the rounds, not the answer")
_equivalent(_NLP, '_lead_functions', [
    'T = ca.horzcat(*[c if isinstance(c, ca.MX) else ca.MX(ca.DM.ones(n) * float(c)) for c in comps]) -> T = '
    'ca.horzcat(*[c if (isinstance(c, ca.MX)) or True else ca.MX(ca.DM.ones(n) * float(c)) for c in comps])',
    'T = ca.horzcat(*[c if isinstance(c, ca.MX) else ca.MX(ca.DM.ones(n) * float(c)) for c in comps]) -> T = '
    'ca.horzcat(*[c if isinstance(c, ca.MX) else ca.MX(ca.DM.ones(n) / float(c)) for c in comps])',
    'T = ca.horzcat(*[c if isinstance(c, ca.MX) else ca.MX(ca.DM.ones(n) * float(c)) for c in comps]) -> T = '
    'ca.horzcat(*[c if isinstance(c, ca.MX) else ca.MX(ca.DM.ones(None) * float(c)) for c in comps])',
], _WHY_MXONLY)
_equivalent(_NLP, '_lead_functions', [
    'return ca.Function("lead_bound", [a, b, X, Y, Z, C], -> return ca.Function("LEAD_BOUND", [a, b, X, Y, Z, '
    'C],',
], _WHY_NAME)
_equivalent(_NLP, '_sparse_mx', [
    'colind = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=ncol))]) -> colind = '
    'np.concatenate([[0], np.cumsum(np.bincount(cols, ))])',
], _WHY_LASTCOL)
_equivalent(_NLP, 'elastic_diagnosis', [
    's = ca.SX.sym("s", 6) # q1, q2 vel, q1, q2 acc (fraction of the limit), q1, q2 travel (of the span) -> '
    's = ca.SX.sym("S", 6) # q1, q2 vel, q1, q2 acc (fraction of the limit), q1, q2 travel (of the span)',
], _WHY_NAME)
_equivalent(_NLP, 'elastic_diagnosis', [
    '{"ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.max_iter": 1000}) -> )',
], _WHY_ELASTICOPTS)
_equivalent(_NLP, 'elastic_diagnosis', [
    'x0 = np.concatenate([np.ravel(np.column_stack([q1_0, q2_0])), np.full(6, 10.0)]) -> x0 = '
    'np.concatenate([np.ravel(np.column_stack([q1_0, q2_0])), np.full(6, 11.0)])',
], _WHY_SLACKSTART)
_equivalent(_NLP, 'fd_operators', [
    'shape=(n - 1, n)) -> shape=None)',
    't = np.asarray(t, float) -> t = np.asarray(t, )',
    'D2 = sp.csr_matrix((vals, (np.tile(j, 3), np.concatenate([j, j + 1, j + 2]))), shape=(n - 2, n)) -> D2 = '
    'sp.csr_matrix((vals, (np.tile(j, 3), np.concatenate([j, j + 1, j + 2]))), shape=None)',
], _WHY_FDSHAPE)
_equivalent(_NLP, 'limit_violations', [
    'peaks[f"{name} acceleration"] = float(a.max(initial=0.0)) -> peaks[f"{name} acceleration"] = '
    'float(a.max(initial=None))',
], _WHY_EMPTY)
_equivalent(_NLP, 'limit_violations', [
    'viol[f"{name} velocity"] = int(np.sum(v > lim.vmax * (1 + rel) + slack_v)) -> viol[f"{name} velocity"] = '
    'int(np.sum(v >= lim.vmax * (1 + rel) + slack_v))',
], _WHY_EQUALITY)
_equivalent(_NLP, 'program_rates', [
    't = np.asarray(t, float) -> t = np.asarray(t, )',
], _WHY_FDSHAPE)
_equivalent(_NLP, 'LeadBounds.none', [
    'return LeadBounds(z, z, np.zeros(n, bool), np.zeros(n, bool)) -> return LeadBounds(z, z, np.zeros(n, '
    'bool), np.zeros(n, None))',
], _WHY_DTYPE)
_equivalent(_NLP, 'RowNLP.__init__', [
    'return (ca.repmat(c0, 1, cols) * q[0:m2, :] + ca.repmat(c1, 1, cols) * q[1:m2 + 1, :] -> return '
    '(ca.repmat(c0, 1, ) * q[0:m2, :] + ca.repmat(c1, 1, cols) * q[1:m2 + 1, :]',
    'return (ca.repmat(c0, 1, cols) * q[0:m2, :] + ca.repmat(c1, 1, cols) * q[1:m2 + 1, :] -> return '
    '(ca.repmat(c0, 1, cols) * q[0:m2, :] + ca.repmat(c1, 1, ) * q[1:m2 + 1, :]',
], _WHY_REPMAT)
_equivalent(_NLP, 'RowNLP.__init__', [
    'self._grad_f = ca.Function("grad_f", [x, p], [scale * ca.sumsqr(r1), grad]) -> self._grad_f = None',
], _WHY_GRADF)
_equivalent(_NLP, 'RowNLP.__init__', [
    'x = ca.MX.sym("x", 2 * n) -> x = ca.MX.sym("XXxXX", 2 * n)',
], _WHY_NAME)
_equivalent(_NLP, 'RowNLP._feasible_fallback', [
    'if not (np.all(np.isfinite(cand)) and np.all(cand >= lbx - 1e-12) and np.all(cand <= ubx + 1e-12)): -> if '
    'not (np.all(np.isfinite(cand)) and np.all(cand > lbx - 1e-12) and np.all(cand <= ubx + 1e-12)):',
], _WHY_EQUALITY)
_equivalent(_NLP, 'RowNLP._params', [
    'np.asarray(bounds.floor, float).T.ravel(), np.asarray(bounds.ceiling, float).T.ravel()]) -> '
    'np.asarray(bounds.floor, float).T.ravel(), np.asarray(bounds.ceiling, ).T.ravel()])',
], _WHY_DTYPE)
_equivalent(_NLP, 'RowNLP._solver', [
    'J = ca.MX(0, 2 * n) -> J = ca.MX(0, None)',
    'J = ca.MX(0, 2 * n) -> J = ca.MX(0, )',
    'J = ca.MX(0, 2 * n) -> J = ca.MX(0, 3 * n)',
    'g1 = ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=True)]) if m else ca.MX(0, 1) -> g1 = '
    'ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=True)]) if m else ca.MX(1, 1)',
], _WHY_NOROWS)
_equivalent(_NLP, 'RowNLP._solver', [
    'g1 = ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=True)]) if m else ca.MX(0, 1) -> g1 = '
    'ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=None)]) if m else ca.MX(0, 1)',
    'g1 = ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=True)]) if m else ca.MX(0, 1) -> g1 = '
    'ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, )]) if m else ca.MX(0, 1)',
    'g1 = ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=True)]) if m else ca.MX(0, 1) -> g1 = '
    'ca.vertcat(*[grp[k] for grp, k in zip(self._g1, sel, strict=False)]) if m else ca.MX(0, 1)',
    'g = ca.vertcat(*[grp[k] for grp, k in zip(self._g_groups, sel, strict=True)]) if m else ca.MX(0, 1) -> g '
    '= ca.vertcat(*[grp[k] for grp, k in zip(self._g_groups, sel, strict=None)]) if m else ca.MX(0, 1)',
    'g = ca.vertcat(*[grp[k] for grp, k in zip(self._g_groups, sel, strict=True)]) if m else ca.MX(0, 1) -> g '
    '= ca.vertcat(*[grp[k] for grp, k in zip(self._g_groups, sel, strict=False)]) if m else ca.MX(0, 1)',
    'curv = [w + h for w, h in zip(blocks(wc), bc, strict=True)] -> curv = [w + h for w, h in zip(blocks(wc), '
    'bc, )]',
    'a, b, c = (p_ + q_ for p_, q_ in zip(blocks(wo), _psd_part(*curv), strict=True)) -> a, b, c = (p_ + q_ '
    'for p_, q_ in zip(blocks(wo), _psd_part(*curv), strict=False))',
], _WHY_STRICT)
_equivalent(_NLP, 'RowNLP._solver', [
    'jac_g = ca.Function("jac_g", [x, p], [g1, J]) -> jac_g = ca.Function("XXjac_gXX", [x, p], [g1, J])',
    'lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", m) -> lam_f, lam_g = ca.MX.sym("LAM_F"), '
    'ca.MX.sym("lam_g", m)',
    'hess = ca.Function("hess_lag", [x, p, lam_f, lam_g], [H]) -> hess = ca.Function("XXhess_lagXX", [x, p, '
    'lam_f, lam_g], [H])',
], _WHY_NAME)
_equivalent(_NLP, 'RowNLP._solver', [
    'bc = [ca.MX.zeros(n, 1) for _ in range(3)] # curvature of the clearance rows, weighted -> bc = '
    '[ca.MX.zeros(1) for _ in range(3)] # curvature of the clearance rows, weighted',
], _WHY_BCZERO)
_equivalent(_NLP, 'RowNLP._solver', [
    'k = np.asarray(rows[gi], np.int64) -> k = np.asarray(rows[gi], None)',
    'k = np.asarray(k, np.int64) -> k = np.asarray(k, None)',
], _WHY_DTYPE)
_equivalent(_NLP, 'RowNLP._solver', [
    'if len(self._solvers) >= 16: -> if len(self._solvers) >= 17:',
], _WHY_CACHE)
_equivalent(_NLP, 'RowNLP.solve', [
    'iters += int(st.get("iter_count", 0)) -> iters += int(st.get("iter_count", 1))',
], _WHY_ITERCOUNT)
_equivalent(_NLP, 'RowNLP.solve', [
    'bad = ((g < lbg - 1e-9) | (g > ubg + 1e-9)) & ~keep & exists -> bad = ((g < lbg + 1e-9) | (g > ubg + '
    '1e-9)) & ~keep & exists',
    'keep |= (_dilate(bad, self.sizes, SCREEN_DILATE) | self._near(g, lbg, ubg)) & exists -> keep |= '
    '(_dilate(bad, None, SCREEN_DILATE) | self._near(g, lbg, ubg)) & exists',
], _WHY_SCREENROWS)

_CLR = "camsmooth/geometry/clearance.py"
_WHY_DTYPE = ("the values are cast or combined with float / integer arrays before anything reads them (or have "
              "that dtype already; intp is int64 here): the same numbers with or without the explicit dtype")
_WHY_EINSUM = "einsum labels are arbitrary letters: the same contraction"
_WHY_MORTON = ("_morton_order only chooses the order in which the kernel visits the poses (cache locality): every "
               "variant still returns a permutation (argsort / arange), and the answers are written back through "
               "the same permutation")
_WHY_CSR0 = ("the total == 0 shortcut is unreachable: _drop_chunk calls _csr_expand only for vertices that passed "
             "its test (np.any(m)), and every vertex of a MeshIndex belongs to a face (unused ones are dropped), "
             "so total >= 1")
_WHY_GUARD = ("the inner where only avoids a division by zero where an outer where or mask discards the quotient "
              "anyway (the discarded entries differ, the result does not)")
_WHY_GOLDEN = ("the edge test maximises a smooth concave s(t) and also evaluates the bracket's ends exactly: ties "
               "between the two interior points (exact equality) keep a bracket holding the optimum either way, "
               "and fewer iterations (at least 40: a bracket below 4e-9 of the edge) move the argmax by dt but the "
               "drop value by O(dt^2), below rounding")
_WHY_BASIS = ("any unit e1 orthogonal to the axis gives an orthonormal basis of the plane across it, with the same "
              "cKDTree distances; a basis scaled by |cross| <= 1 shrinks the projected distances, so the query "
              "returns a superset of the candidate pairs, which _drop_chunk filters exactly (rho <= Rc + l_v)")
_WHY_CACHE = ("the projected-tree cache only saves rebuilding a tree that is a function of the axis: a miss, a finer "
              "key or another size limit rebuilds the same tree")
_WHY_SUBDIV = ("subdivision (max_edge) is for speed only: the clearance and the drop are exact on any triangulation "
               "of the same surface, and subdivide_to_size stops once every edge is short enough; these mutants "
               "change how many passes it may take, not the surface")
_WHY_CROSS = "(b - a) x (c - b) = (b - a) x (c - a): the same normal"
_WHY_ELEN = "the longest edge of a face is the largest of its three edges in any cyclic order"
_WHY_PLANE = "the facet's plane passes through each of its vertices: n . (p - a) = n . (p - b)"
_WHY_DIVFLOOR = ("the keys are non-negative integers below 2**53: float division then truncation to intp equals floor "
                 "division")
_WHY_FIXED = ("the fixed-axis flag only picks the faster candidate search (a cached projected 2-D tree); with one "
              "axis broadcast to every point the per-point search finds the same pairs")
_WHY_INIT = ("S and C are overwritten for every point by _drop_chunk's answer for its chunk: the initial values are "
             "never read")
_WHY_HITMASK = "the value only fills rows that np.where(hit, ...) replaces by NaN (misses)"
_WHY_CAPPED = ("a capped pose has its whole witness row NaN (the kernel writes NaN to all three coordinates), so "
               "column 0 and column 1 give the same flags")
_WHY_EQUALITY = ("the comparison changes only at exact equality of floating-point values (a boundary of measure zero: "
                 "a line touching the box, a tie between candidates, a contact exactly on a triangle's edge)")
_WHY_BARY = ("a facet contact within 1e-12 of a triangle's edge (or one now refused on its boundary) is found by the "
             "edge test of that edge, which sees the whole edge: the facet test's tolerance decides which test "
             "reports the contact, not the drop value (to ~1e-12 mm)")
_WHY_STABLE = ("the vertex -> faces table lists each vertex's faces in any order (a stable sort only fixes the "
               "order within a vertex); _unique_pairs sorts the expanded pairs anyway")
_equivalent(_CLR, '_dot', [
    'return np.einsum("...i,...i->...", a, b) -> return np.einsum("...I,...I->...", a, b)',
], _WHY_EINSUM)
_equivalent(_CLR, '_csr_expand', [
    'if total == 0: -> if total == 1:',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(None, np.intp), np.empty(0, np.intp)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(0, None), np.empty(0, np.intp)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(np.intp), np.empty(0, np.intp)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(0, ), np.empty(0, np.intp)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(1, np.intp), np.empty(0, np.intp)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(0, np.intp), np.empty(None, np.intp)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(0, np.intp), np.empty(0, None)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(0, np.intp), np.empty(np.intp)',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(0, np.intp), np.empty(0, )',
    'return np.empty(0, np.intp), np.empty(0, np.intp) -> return np.empty(0, np.intp), np.empty(1, np.intp)',
], _WHY_CSR0)
_equivalent(_CLR, '_unique_pairs', [
    'key = np.unique(owner.astype(np.int64) * n_items + item) -> key = np.unique(owner.astype(None) * n_items '
    '+ item)',
], _WHY_DTYPE)
_equivalent(_CLR, '_unique_pairs', [
    'return (key // n_items).astype(np.intp), (key % n_items).astype(np.intp) -> return (key / '
    'n_items).astype(np.intp), (key % n_items).astype(np.intp)',
], _WHY_DIVFLOOR)
_equivalent(_CLR, '_inside_triangle', [
    'den = np.where(den > 0.0, den, 1.0) -> den = np.where(den > 0.0, den, None)',
    'den = np.where(den > 0.0, den, 1.0) -> den = np.where(den > 0.0, den, 2.0)',
], _WHY_GUARD)
_equivalent(_CLR, '_inside_triangle', [
    'den = np.where(den > 0.0, den, 1.0) -> den = np.where(den >= 0.0, den, 1.0)',
], _WHY_EQUALITY)
_equivalent(_CLR, '_inside_triangle', [
    'return (v >= -tol) & (w >= -tol) & (1.0 - v - w >= -tol) -> return (v > -tol) & (w >= -tol) & (1.0 - v - '
    'w >= -tol)',
    'return (v >= -tol) & (w >= -tol) & (1.0 - v - w >= -tol) -> return (v >= +tol) & (w >= -tol) & (1.0 - v - '
    'w >= -tol)',
    'return (v >= -tol) & (w >= -tol) & (1.0 - v - w >= -tol) -> return (v >= -tol) & (w > -tol) & (1.0 - v - '
    'w >= -tol)',
    'return (v >= -tol) & (w >= -tol) & (1.0 - v - w >= -tol) -> return (v >= -tol) & (w >= +tol) & (1.0 - v - '
    'w >= -tol)',
    'return (v >= -tol) & (w >= -tol) & (1.0 - v - w >= -tol) -> return (v >= -tol) & (w >= -tol) & (1.0 - v - '
    'w > -tol)',
    'return (v >= -tol) & (w >= -tol) & (1.0 - v - w >= -tol) -> return (v >= -tol) & (w >= -tol) & (1.0 - v - '
    'w >= +tol)',
], _WHY_BARY)
_equivalent(_CLR, '_golden_min', [
    'a, b = lo.astype(float), hi.astype(float) -> a, b = lo.astype(None), hi.astype(float)',
    'a, b = lo.astype(float), hi.astype(float) -> a, b = lo.astype(float), hi.astype(None)',
], _WHY_DTYPE)
_equivalent(_CLR, '_golden_min', [
    'left = fc <= fd -> left = fc < fd',
    'better = fc <= fd -> better = None',
    'better = fc <= fd -> better = fc < fd',
    'return np.where(better, c, d), np.where(better, fc, fd) -> return np.where(None, c, d), np.where(better, '
    'fc, fd)',
    'return np.where(better, c, d), np.where(better, fc, fd) -> return np.where(better, c, d), np.where(None, '
    'fc, fd)',
], _WHY_GOLDEN)
_equivalent(_CLR, '_golden_iters', [
    'if not length > 1e-10: -> if length > 1e-10:',
    'if not length > 1e-10: -> if not length >= 1e-10:',
    'if not length > 1e-10: -> if not length > 1.0000000001:',
    'return 40 -> return 41',
    'return int(min(90, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI))))) -> return '
    'int(min(91, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI)))))',
    'return int(min(90, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI))))) -> return '
    'int(min(90, max(41, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI)))))',
    'return int(min(90, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI))))) -> return '
    'int(min(90, max(40, math.ceil(math.log(length / 1e-10) * -math.log(_INVPHI)))))',
    'return int(min(90, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI))))) -> return '
    'int(min(90, max(40, math.ceil(math.log(length * 1e-10) / -math.log(_INVPHI)))))',
    'return int(min(90, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI))))) -> return '
    'int(min(90, max(40, math.ceil(math.log(length / 1.0000000001) / -math.log(_INVPHI)))))',
    'return int(min(90, max(40, math.ceil(math.log(length / 1e-10) / -math.log(_INVPHI))))) -> return '
    'int(min(90, max(40, math.ceil(math.log(length / 1e-10) / +math.log(_INVPHI)))))',
], _WHY_GOLDEN)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'V = np.asarray(mesh.vertices, dtype=float) -> V = np.asarray(mesh.vertices, dtype=None)',
    'V = np.asarray(mesh.vertices, dtype=float) -> V = np.asarray(mesh.vertices, )',
    'F = np.asarray(mesh.faces, dtype=np.intp) -> F = np.asarray(mesh.faces, dtype=None)',
    'F = np.asarray(mesh.faces, dtype=np.intp) -> F = np.asarray(mesh.faces, )',
    'V = np.asarray(V, dtype=float) -> V = np.asarray(V, dtype=None)',
    'V = np.asarray(V, dtype=float) -> V = np.asarray(V, )',
    'F = np.asarray(F, dtype=np.intp) -> F = np.asarray(F, dtype=None)',
    'F = np.asarray(F, dtype=np.intp) -> F = np.asarray(F, )',
    'V = np.ascontiguousarray(V, dtype=float) -> V = np.ascontiguousarray(V, dtype=None)',
    'V = np.ascontiguousarray(V, dtype=float) -> V = np.ascontiguousarray(V, )',
    'key = raw[..., 0].astype(np.int64) * nv + raw[..., 1] -> key = raw[..., 0].astype(None) * nv + raw[..., 1]',
    'self.vf_faces = (order // 3).astype(np.intp) -> self.vf_faces = (order // 3).astype(None)',
    'self.bvh_nodes = np.ascontiguousarray(np.column_stack([box, left, start, count]), dtype=float) -> '
    'self.bvh_nodes = np.ascontiguousarray(np.column_stack([box, left, start, count]), dtype=None)',
    'self.bvh_nodes = np.ascontiguousarray(np.column_stack([box, left, start, count]), dtype=float) -> '
    'self.bvh_nodes = np.ascontiguousarray(np.column_stack([box, left, start, count]), )',
    'self._bvh_ti = np.ascontiguousarray(Fp, dtype=np.int64) -> self._bvh_ti = np.ascontiguousarray(Fp, '
    'dtype=None)',
    'self._bvh_ti = np.ascontiguousarray(Fp, dtype=np.int64) -> self._bvh_ti = np.ascontiguousarray(Fp, )',
    '[self.face_normals[perm], V[Fp].mean(axis=1), self.face_valid[perm], V[Fp].reshape(-1, 9)]), dtype=float) '
    '-> [self.face_normals[perm], V[Fp].mean(axis=1), self.face_valid[perm], V[Fp].reshape(-1, 9)]), '
    'dtype=None)',
    '[self.face_normals[perm], V[Fp].mean(axis=1), self.face_valid[perm], V[Fp].reshape(-1, 9)]), dtype=float) '
    '-> [self.face_normals[perm], V[Fp].mean(axis=1), self.face_valid[perm], V[Fp].reshape(-1, 9)]), )',
], _WHY_DTYPE)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=None)))',
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], )))',
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] + V[np.roll(F, 1, axis=1)], axis=-1)))',
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=None)], axis=-1)))',
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, )], axis=-1)))',
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 2, axis=1)], axis=-1)))',
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=+1)))',
    'longest = float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-1))) -> longest = '
    'float(np.max(np.linalg.norm(V[F] - V[np.roll(F, 1, axis=1)], axis=-2)))',
    'iters = max(10, math.ceil(math.log2(max(longest / max_edge, 1.0))) + 3) -> iters = max(11, '
    'math.ceil(math.log2(max(longest / max_edge, 1.0))) + 3)',
    'iters = max(10, math.ceil(math.log2(max(longest / max_edge, 1.0))) + 3) -> iters = max(10, '
    'math.ceil(math.log2(max(longest / max_edge, 1.0))) - 3)',
    'iters = max(10, math.ceil(math.log2(max(longest / max_edge, 1.0))) + 3) -> iters = max(10, '
    'math.ceil(math.log2(max(longest * max_edge, 1.0))) + 3)',
    'iters = max(10, math.ceil(math.log2(max(longest / max_edge, 1.0))) + 3) -> iters = max(10, '
    'math.ceil(math.log2(max(longest / max_edge, 2.0))) + 3)',
    'iters = max(10, math.ceil(math.log2(max(longest / max_edge, 1.0))) + 3) -> iters = max(10, '
    'math.ceil(math.log2(max(longest / max_edge, 1.0))) + 4)',
    'V, F = trimesh.remesh.subdivide_to_size(V, F, max_edge=max_edge, max_iter=iters) -> V, F = '
    'trimesh.remesh.subdivide_to_size(V, F, max_edge=max_edge, )',
], _WHY_SUBDIV)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'self.edges = np.stack([ukey // nv, ukey % nv], axis=1).astype(np.intp) -> self.edges = np.stack([ukey / '
    'nv, ukey % nv], axis=1).astype(np.intp)',
    'self.vf_faces = (order // 3).astype(np.intp) -> self.vf_faces = (order / 3).astype(np.intp)',
], _WHY_DIVFLOOR)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) -> cr = np.cross(tri[:, 1] - tri[:, 0], '
    'tri[:, 2] - tri[:, 1])',
], _WHY_CROSS)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'elen = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=-1) -> elen = np.linalg.norm(tri - np.roll(tri, '
    '2, axis=1), axis=-1)',
], _WHY_ELEN)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'self.face_valid = area2 > 1e-12 * np.maximum(self.face_long, 1e-300) ** 2 -> self.face_valid = area2 >= '
    '1e-12 * np.maximum(self.face_long, 1e-300) ** 2',
], _WHY_EQUALITY)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'cr / np.where(area2 > 0, area2, 1.0)[:, None], 0.0) -> cr / np.where(area2 >= 0, area2, 1.0)[:, None], '
    '0.0)',
    'cr / np.where(area2 > 0, area2, 1.0)[:, None], 0.0) -> cr / np.where(area2 > 0, area2, 2.0)[:, None], 0.0)',
    'cr / np.where(area2 > 0, area2, 1.0)[:, None], 0.0) -> cr / np.where(area2 > 0, area2, 1.0)[:, None], 1.0)',
], _WHY_GUARD)
_equivalent(_CLR, 'MeshIndex.__init__', [
    'order = np.argsort(F.ravel(), kind="stable") -> order = np.argsort(F.ravel(), kind=None)',
    'order = np.argsort(F.ravel(), kind="stable") -> order = np.argsort(F.ravel(), )',
    'order = np.argsort(F.ravel(), kind="stable") -> order = np.argsort(F.ravel(), kind="STABLE")',
], _WHY_STABLE)
_equivalent(_CLR, 'MeshIndex._projected_tree', [
    'key = np.round(axis, 14).tobytes() -> key = np.round(axis, 15).tobytes()',
    'hit = self._proj_cache.get(key) -> hit = None',
    'hit = self._proj_cache.get(key) -> hit = self._proj_cache.get(None)',
    'if len(self._proj_cache) >= 8: -> if len(self._proj_cache) > 8:',
    'if len(self._proj_cache) >= 8: -> if len(self._proj_cache) >= 9:',
    'self._proj_cache[key] = hit -> self._proj_cache[key] = None',
], _WHY_CACHE)
_equivalent(_CLR, 'MeshIndex._projected_tree', [
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if (abs(axis[0]) < 0.9) and False else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if (abs(axis[0]) < 0.9) or True else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[2.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 1.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 1.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if abs(axis[1]) < 0.9 else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if abs(axis[0]) <= 0.9 else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if abs(axis[0]) < 1.9 else [0.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [1.0, 1.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 2.0, 0.0])',
    'e1 = np.cross(axis, [1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 0.0]) -> e1 = np.cross(axis, '
    '[1.0, 0.0, 0.0] if abs(axis[0]) < 0.9 else [0.0, 1.0, 1.0])',
    'e1 /= np.linalg.norm(e1) -> e1 *= np.linalg.norm(e1)',
], _WHY_BASIS)
_equivalent(_CLR, '_poses', [
    'p = np.asarray(points, dtype=float) -> p = np.asarray(points, dtype=None)',
    'p = np.asarray(points, dtype=float) -> p = np.asarray(points, )',
    'a = np.asarray(axes, dtype=float) -> a = np.asarray(axes, dtype=None)',
    'a = np.asarray(axes, dtype=float) -> a = np.asarray(axes, )',
], _WHY_DTYPE)
_equivalent(_CLR, '_poses', [
    'if np.any(nrm < 1e-12): -> if np.any(nrm <= 1e-12):',
], _WHY_EQUALITY)
_equivalent(_CLR, '_morton_order', [
    'def _morton_order(points: np.ndarray, bits: int = 10) -> np.ndarray: -> def _morton_order(points: '
    'np.ndarray, bits: int = 11) -> np.ndarray:',
    'if len(points) < 2: -> if len(points) <= 2:',
    'if len(points) < 2: -> if len(points) < 3:',
    'lo, hi = points.min(axis=0), points.max(axis=0) -> lo, hi = points.min(axis=None), points.max(axis=0)',
    'lo, hi = points.min(axis=0), points.max(axis=0) -> lo, hi = points.min(axis=0), points.max(axis=None)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi > lo, hi - lo, 1.0) / ((1 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) * np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points + lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(None, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi >= lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi > lo, hi + lo, 1.0) * ((1 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi > lo, hi - lo, 2.0) * ((1 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) + 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 >> bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((2 << bits) - 1)).astype(np.int64)',
    'q = ((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 1)).astype(np.int64) -> q = '
    '((points - lo) / np.where(hi > lo, hi - lo, 1.0) * ((1 << bits) - 2)).astype(np.int64)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code = ((q[:, k] >> b) & 1) << (3 * b + k)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code &= ((q[:, k] >> b) & 1) << (3 * b + k)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code |= ((q[:, k] >> b) & 1) >> (3 * b + k)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code |= ((q[:, k] >> b) | 1) << (3 * b + k)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code |= ((q[:, k] << b) & 1) << (3 * b + k)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code |= ((q[:, k] >> b) & 2) << (3 * b + k)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code |= ((q[:, k] >> b) & 1) << (3 * b - k)',
    'code |= ((q[:, k] >> b) & 1) << (3 * b + k) -> code |= ((q[:, k] >> b) & 1) << (4 * b + k)',
    'return np.argsort(code, kind="stable") -> return np.argsort(code, kind=None)',
    'return np.argsort(code, kind="stable") -> return np.argsort(code, )',
    'return np.argsort(code, kind="stable") -> return np.argsort(code, kind="STABLE")',
], _WHY_MORTON)
_equivalent(_CLR, 'clearance', [
    'np.ascontiguousarray(tips[order]), np.ascontiguousarray(axes[order]), np.array(bodies, dtype=float), -> '
    'np.ascontiguousarray(tips[order]), np.ascontiguousarray(axes[order]), np.array(bodies, dtype=None),',
    'np.ascontiguousarray(tips[order]), np.ascontiguousarray(axes[order]), np.array(bodies, dtype=float), -> '
    'np.ascontiguousarray(tips[order]), np.ascontiguousarray(axes[order]), np.array(bodies, ),',
], _WHY_DTYPE)
_equivalent(_CLR, 'clearance', [
    'capped = np.isnan(witness[:, 0]) -> capped = np.isnan(witness[:, 1])',
], _WHY_CAPPED)
_equivalent(_CLR, '_drop_candidates', [
    'par = np.abs(ak) < 1e-12 -> par = np.abs(ak) <= 1e-12',
    'inside = (p[:, k] >= lo[k]) & (p[:, k] <= hi[k]) -> inside = (p[:, k] > lo[k]) & (p[:, k] <= hi[k])',
    'inside = (p[:, k] >= lo[k]) & (p[:, k] <= hi[k]) -> inside = (p[:, k] >= lo[k]) & (p[:, k] < hi[k])',
    'ok = t1 >= t0 -> ok = t1 > t0',
    'near = np.clip(np.floor((tv - t0[pid]) / np.where(spacing[pid] > 0, spacing[pid], 1.0) + 0.5), -> near = '
    'np.clip(np.floor((tv - t0[pid]) / np.where(spacing[pid] >= 0, spacing[pid], 1.0) + 0.5),',
], _WHY_EQUALITY)
_equivalent(_CLR, '_drop_candidates', [
    'ta = (lo[k] - p[:, k]) / np.where(par, 1.0, ak) -> ta = (lo[k] - p[:, k]) / np.where(par, 2.0, ak)',
    'tb = (hi[k] - p[:, k]) / np.where(par, 1.0, ak) -> tb = (hi[k] - p[:, k]) / np.where(par, 2.0, ak)',
    'near = np.clip(np.floor((tv - t0[pid]) / np.where(spacing[pid] > 0, spacing[pid], 1.0) + 0.5), -> near = '
    'np.clip(np.floor((tv - t0[pid]) / np.where(spacing[pid] > 0, spacing[pid], None) + 0.5),',
    'near = np.clip(np.floor((tv - t0[pid]) / np.where(spacing[pid] > 0, spacing[pid], 1.0) + 0.5), -> near = '
    'np.clip(np.floor((tv - t0[pid]) / np.where(spacing[pid] > 0, spacing[pid], 2.0) + 0.5),',
], _WHY_GUARD)
_equivalent(_CLR, '_drop_chunk', [
    'C = np.full((N, 3), np.nan) -> C = np.full((N, 3), None)',
], _WHY_INIT)
_equivalent(_CLR, '_drop_chunk', [
    'pid, vid = _drop_candidates(index, p, A, fixed, Rc + index.long_max) -> pid, vid = '
    '_drop_candidates(index, p, A, None, Rc + index.long_max)',
], _WHY_FIXED)
_equivalent(_CLR, '_drop_chunk', [
    'keep = rho <= Rc + index.vertex_long[vid] -> keep = rho < Rc + index.vertex_long[vid]',
    'inn = rho <= Rc -> inn = rho < Rc',
    'm = (shrunk <= Rc) & (h > S[pid] + _zlow(cutter, np.minimum(shrunk, Rc)) + _PRUNE_TOL) -> m = (shrunk < '
    'Rc) & (h > S[pid] + _zlow(cutter, np.minimum(shrunk, Rc)) + _PRUNE_TOL)',
    'm = (shrunk <= Rc) & (h > S[pid] + _zlow(cutter, np.minimum(shrunk, Rc)) + _PRUNE_TOL) -> m = (shrunk <= '
    'Rc) & (h >= S[pid] + _zlow(cutter, np.minimum(shrunk, Rc)) + _PRUNE_TOL)',
    'ubf = np.where(rlb <= Rc, ht.max(axis=1) - _zlow(cutter, np.minimum(rlb, Rc)), -np.inf) -> ubf = '
    'np.where(rlb < Rc, ht.max(axis=1) - _zlow(cutter, np.minimum(rlb, Rc)), -np.inf)',
    'strict = xin < r * (1.0 - 1e-9) -> strict = xin <= r * (1.0 - 1e-9)',
    'tang_ub = np.where(strict & (rt <= Rc), tang.max(axis=2), np.inf).min(axis=1) -> tang_ub = '
    'np.where(strict & (rt < Rc), tang.max(axis=2), np.inf).min(axis=1)',
    'k = ubf > S[fp] + _PRUNE_TOL -> k = ubf >= S[fp] + _PRUNE_TOL',
    'n = np.where((na < 0.0)[:, None], -n, n) -> n = np.where((na <= 0.0)[:, None], -n, n)',
    'ok = index.face_valid[ff] & (na > 1e-12) -> ok = index.face_valid[ff] & (na >= 1e-12)',
    'u = wn / np.where(wl > 1e-12, wl, np.inf)[:, None] -> u = wn / np.where(wl >= 1e-12, wl, np.inf)[:, None]',
    'feas = (qa > 0.0) & (disc >= 0.0) -> feas = (qa > 0.0) & (disc > 0.0)',
    'den = np.where(qa > 0.0, 2.0 * qa, 1.0) -> den = np.where(qa >= 0.0, 2.0 * qa, 1.0)',
    'feas &= t0 <= t1 -> feas &= t0 < t1',
    'k = feas & (ube > S[ep] + _PRUNE_TOL) -> k = feas & (ube >= S[ep] + _PRUNE_TOL)',
    'better = vv < val -> better = vv <= val',
], _WHY_EQUALITY)
_equivalent(_CLR, '_drop_chunk', [
    'slope = xin / np.sqrt(np.where(strict, r * r - xin * xin, 1.0)) -> slope = xin / np.sqrt(np.where(strict, '
    'r * r - xin * xin, 2.0))',
    'e_r = wt / np.where(rt > 0.0, rt, 1.0)[..., None] -> e_r = wt / np.where(rt > 0.0, rt, None)[..., None]',
    'e_r = wt / np.where(rt > 0.0, rt, 1.0)[..., None] -> e_r = wt / np.where(rt > 0.0, rt, 2.0)[..., None]',
    'u = wn / np.where(wl > 1e-12, wl, np.inf)[:, None] -> u = wn / np.where(wl > 1e-12, wl, None)[:, None]',
    's_f = (r + R * wl - r * na - _dot(n, pp - tri[:, 0])) / np.where(ok, na, 1.0) -> s_f = (r + R * wl - r * '
    'na - _dot(n, pp - tri[:, 0])) / np.where(ok, na, None)',
], _WHY_GUARD)
_equivalent(_CLR, '_drop_chunk', [
    'tang = sv[:, :, None] + np.einsum("mik,mijk->mij", grad, tri[:, None, :, :] - tri[:, :, None, :]) -> tang '
    '= sv[:, :, None] + np.einsum("MIK,MIJK->MIJ", grad, tri[:, None, :, :] - tri[:, :, None, :])',
], _WHY_EINSUM)
_equivalent(_CLR, '_drop_chunk', [
    's_f = (r + R * wl - r * na - _dot(n, pp - tri[:, 0])) / np.where(ok, na, 1.0) -> s_f = (r + R * wl - r * '
    'na - _dot(n, pp - tri[:, 1])) / np.where(ok, na, 1.0)',
], _WHY_PLANE)
_equivalent(_CLR, 'axial_drop', [
    'ax = np.asarray(axis, dtype=float) -> ax = np.asarray(axis, dtype=None)',
    'ax = np.asarray(axis, dtype=float) -> ax = np.asarray(axis, )',
], _WHY_DTYPE)
_equivalent(_CLR, 'axial_drop', [
    'fixed = ax.shape == (3,) -> fixed = None',
    'fixed = ax.shape == (3,) -> fixed = ax.shape == (4,)',
    'S[sl], C[sl] = _drop_chunk(idx, cutter, p[sl], A[sl], fixed) -> S[sl], C[sl] = _drop_chunk(idx, cutter, '
    'p[sl], A[sl], None)',
], _WHY_FIXED)
_equivalent(_CLR, 'axial_drop', [
    'S = np.full(N, -np.inf) -> S = np.full(N, +np.inf)',
], _WHY_INIT)
_equivalent(_CLR, 'axial_drop', [
    'cl = np.where(hit[:, None], p + np.where(hit, S, 0.0)[:, None] * A, np.nan) -> cl = np.where(hit[:, '
    'None], p + np.where(hit, S, 1.0)[:, None] * A, np.nan)',
], _WHY_HITMASK)
_equivalent(_CLR, 'axial_drop', [
    'core = cl + cutter.r * A + (np.minimum(rq, cutter.R) / np.where(rq > 0.0, rq, 1.0))[:, None] * wq -> core '
    '= cl + cutter.r * A + (np.minimum(rq, cutter.R) / np.where(rq > 0.0, rq, 2.0))[:, None] * wq',
    'normal = np.where(hit[:, None], nrm / np.where(ln > 0.0, ln, 1.0)[:, None], np.nan) -> normal = '
    'np.where(hit[:, None], nrm / np.where(ln > 0.0, ln, 2.0)[:, None], np.nan)',
], _WHY_GUARD)

_CAL = "camsmooth/machine/calibration.py"
_WHY_DTYPE = ("the probe and spindle tables are float arrays already (validated when read or simulated): the same "
              "values with or without the explicit dtype")
_WHY_START = ("probe_offsets only gives the starting point of the sphere centre (c0), which enters the probe "
              "residual linearly: the least-squares fit ends at the same centre and parameters from any start")
_WHY_PERIODIC = ("without periodic dimensions np.asarray(None, bool) is a scalar False and zeros(n, None) float "
                 "zeros, both falsy in np.where: the same clipping")
_WHY_EXTRA = ("the swarm's cost writes r / theta columns into the parameter dict as extra keys that _spindle_model "
              "never reads (it reads a1, b1, a2, b2 from r and theta): the same cost")
_equivalent(_CAL, '_probe_residual', [
    'geo.update({p: float(v) for p, v in zip(names, x[:-3] * scales, strict=True)}) -> geo.update({p: float(v) '
    'for p, v in zip(names, x[:-3] * scales, strict=False)})',
], _WHY_STRICT)
_equivalent(_CAL, '_spindle_pso', [
    'if k not in ("r1", "r2", "theta1", "theta2"): -> if k not in ("R1", "r2", "theta1", "theta2"):',
    'if k not in ("r1", "r2", "theta1", "theta2"): -> if k not in ("r1", "R2", "theta1", "theta2"):',
    'if k not in ("r1", "r2", "theta1", "theta2"): -> if k not in ("r1", "r2", "THETA1", "theta2"):',
    'if k not in ("r1", "r2", "theta1", "theta2"): -> if k not in ("r1", "r2", "theta1", "THETA2"):',
], _WHY_EXTRA)
_equivalent(_CAL, 'calibrate_probe', [
    'c0 = np.mean(data.centre + probe_offsets(base, machine, data), axis=0) -> c0 = np.mean(data.centre - '
    'probe_offsets(base, machine, data), axis=0)',
    'x0 = np.concatenate([x_base, c0 * 1e3]) -> x0 = np.concatenate([x_base, c0 / 1e3])',
], _WHY_START)
_equivalent(_CAL, 'calibrate_probe', [
    'params = {p: float(v) for p, v in zip(fit_names, fit.x[:-3] * fit_scales, strict=True)} -> params = {p: '
    'float(v) for p, v in zip(fit_names, fit.x[:-3] * fit_scales, strict=False)}',
], _WHY_STRICT)
_equivalent(_CAL, 'calibrate_spindle', [
    'theta, ext, ball = data.theta, np.asarray(data.ext, float), np.asarray(data.ball, float) -> theta, ext, '
    'ball = data.theta, np.asarray(data.ext, ), np.asarray(data.ball, float)',
], _WHY_DTYPE)
_equivalent(_CAL, 'calibrate_spindle', [
    'p.update({k: float(v) * _SPINDLE_SCALE[k] for k, v in zip(fit, x, strict=True)}) -> p.update({k: float(v) '
    '* _SPINDLE_SCALE[k] for k, v in zip(fit, x, )})',
], _WHY_STRICT)
_equivalent(_CAL, 'probe_offsets', [
    'q = {"A": np.asarray(data.A, float), "B": np.asarray(data.B, float), "X": np.asarray(data.X, float), -> q '
    '= {"A": np.asarray(data.A, float), "B": np.asarray(data.B, ), "X": np.asarray(data.X, float),',
    'q = {"A": np.asarray(data.A, float), "B": np.asarray(data.B, float), "X": np.asarray(data.X, float), -> q '
    '= {"A": np.asarray(data.A, float), "B": np.asarray(data.B, float), "X": np.asarray(data.X, None),',
], _WHY_DTYPE)
_equivalent(_CAL, 'probe_offsets', [
    'q = {"A": np.asarray(data.A, float), "B": np.asarray(data.B, float), "X": np.asarray(data.X, float), -> q '
    '= {"A": np.asarray(data.A, float), "B": np.asarray(data.B, float), "x": np.asarray(data.X, float),',
    '"Y": np.asarray(data.Y, float), "Z": np.asarray(data.Z, float)} -> "Y": np.asarray(data.Y, float), '
    '"XXZXX": np.asarray(data.Z, float)}',
    'nominal = machine.tool_pose_np(data.A, data.B, data.X, data.Y, data.Z)[0] -> nominal = '
    'machine.tool_pose_np(data.A, data.B, data.X, data.Y, data.Z)[1]',
], _WHY_START)
_equivalent(_CAL, 'pso', [
    'periodic = np.zeros(len(lower), bool) if periodic is None else np.asarray(periodic, bool) -> periodic = '
    'np.zeros(len(lower), bool) if (periodic is None) and False else np.asarray(periodic, bool)',
    'periodic = np.zeros(len(lower), bool) if periodic is None else np.asarray(periodic, bool) -> periodic = '
    'np.zeros(len(lower), None) if periodic is None else np.asarray(periodic, bool)',
], _WHY_PERIODIC)

_KER = "camsmooth/geometry/_kernels.py"
_WHY_BOX = ("_box only chooses the oriented box's axes and centre (for tight boxes, i.e. speed): the axes are "
            "made orthonormal (Gram-Schmidt, cross product; (0, 0, 1) when the normals vanish) and the extents "
            "are the largest projections of the triangles' vertices about the final centre, so the box contains "
            "its triangles whatever the axes and centre, and the pruning bounds stay rigorous")
_WHY_CAP = "the node arrays get one spare row; build_bvh returns them cut to the nodes it made"
_WHY_ITERS = ("the edge minimisation ends on its certificate long before 300 iterations (the bisection safeguard "
              "halves the bracket: ~60 halvings reach rounding)")
_WHY_CACHE = ("the per-pose edge cache only avoids minimising an edge twice: another hash, or entries that never "
              "match, make it recompute an edge, with the same minimum")
_WHY_SEED = ("the seed only pushes the previous pose's best leaf to search first; node 0 is the root, which is "
             "searched anyway")
_WHY_EVAB = "eva and evb are read only when an edge gave the minimum, and then they were set by that edge"
_WHY_FALSY = "the flag is only tested for truth: False and None are both false"
_equivalent(_KER, '_box', [
    'mx, my, mz = mx / (3.0 * c), my / (3.0 * c), mz / (3.0 * c) -> mx, my, mz = mx / (3.0 / c), my / (3.0 * '
    'c), mz / (3.0 * c)',
    'm[0], m[1], m[2] = S[0, k], S[1, k], S[2, k] -> m[0], m[1], m[2] = S[1, k], S[1, k], S[2, k]',
    'x0 = S[0, 0] * m[0] + S[0, 1] * m[1] + S[0, 2] * m[2] -> x0 = S[0, 0] / m[0] + S[0, 1] * m[1] + S[0, 2] * '
    'm[2]',
    'x0 = S[0, 0] * m[0] + S[0, 1] * m[1] + S[0, 2] * m[2] -> x0 = S[0, 0] * m[0] + S[0, 1] * m[1] + S[0, 2] / '
    'm[2]',
    'x2 = S[2, 0] * m[0] + S[2, 1] * m[1] + S[2, 2] * m[2] -> x2 = S[2, 0] * m[0] - S[2, 1] * m[1] + S[2, 2] * '
    'm[2]',
    'if not ln > 0.0: -> if ln > 0.0:',
    'if not ln > 0.0: -> if not ln > 1.0:',
    'if ln > 0.0: -> if ln > 1.0:',
    'ux, uy, uz = vertices[p1, 0] - ox, vertices[p1, 1] - oy, vertices[p1, 2] - oz -> ux, uy, uz = '
    'vertices[p1, 0] - ox, vertices[p1, 1] - oy, vertices[p1, 2] + oz',
    'dx, dy, dz = vertices[v, 0] - mx, vertices[v, 1] - my, vertices[v, 2] - mz -> dx, dy, dz = vertices[v, 0] '
    '+ mx, vertices[v, 1] - my, vertices[v, 2] - mz',
    'cx += mid * a[k, 0] -> cx = mid * a[k, 0]',
    'S[0, 1] += n0 * n1 / ln -> S[0, 1] += n0 * n1 * ln',
], _WHY_BOX)
_equivalent(_KER, '_edge_min', [
    'for it in range(300): -> for it in range(301):',
], _WHY_ITERS)
_equivalent(_KER, 'build_bvh', [
    'cap = 2 * F + 1 -> cap = 2 * F + 2',
], _WHY_CAP)
_equivalent(_KER, 'clearance_kernel', [
    'if seed[body] >= 0: -> if seed[body] >= 1:',
], _WHY_SEED)
_equivalent(_KER, 'clearance_kernel', [
    'j = ((i & 0x7FFFFFFF) * 2654435761 + (i >> 31)) & (HASH - 1) -> j = ((i & 0x7FFFFFFF) * 2654435761 + (i '
    '>> 32)) & (HASH - 1)',
    'et[j, 0], et[j, 1] = key, ek -> et[j, 1], et[j, 1] = key, ek',
], _WHY_CACHE)
_equivalent(_KER, 'clearance_kernel', [
    'bx, by, bz, ax, ay, az, h, rad, off, U, False) -> bx, by, bz, ax, ay, az, h, rad, off, U, None)',
], _WHY_FALSY)
_equivalent(_KER, 'clearance_kernel', [
    'eva = evb = 0 -> eva = evb = 1',
], _WHY_EVAB)

# ---- issue #31 item 3: the modules changed since (iso230, significance, apt, jerk, pole, post words / core) ----
_SIG = "camsmooth/diagnosis/significance.py"
_equivalent(_SIG, "batch_sum_sd", ["y = np.asarray(y, float) -> y = np.asarray(y, None)",
                                   "y = np.asarray(y, float) -> y = np.asarray(y, )"],
            "the callers pass float series; an integer series gives the same figures (its batch sums are exact "
            "integers and every later step is float arithmetic with the float mean)")
_equivalent(_SIG, "batch_sum_sd", [
    "sums = np.add.reduceat(Y, edges[:-1], axis=0) -> sums = np.add.reduceat(Y, edges[:-1], )"],
    "axis=0 is np.add.reduceat's default")
_equivalent(_SIG, "per_sample", ["v = np.asarray(values, float) -> v = np.asarray(values, None)",
                                 "v = np.asarray(values, float) -> v = np.asarray(values, )"],
            "np.bincount casts its weights to float64 itself")

_POLE = "camsmooth/smoothing/pole.py"
_equivalent(_POLE, "pole_start", [
    "T, t = np.asarray(T, float), np.asarray(t, float) -> T, t = np.asarray(T, None), np.asarray(t, float)",
    "T, t = np.asarray(T, float), np.asarray(t, float) -> T, t = np.asarray(T, ), np.asarray(t, float)",
    "T, t = np.asarray(T, float), np.asarray(t, float) -> T, t = np.asarray(T, float), np.asarray(t, None)",
    "T, t = np.asarray(T, float), np.asarray(t, float) -> T, t = np.asarray(T, float), np.asarray(t, )",
    "out = np.array(angles, dtype=float, copy=True) -> out = np.array(angles, dtype=None, copy=True)",
    "out = np.array(angles, dtype=float, copy=True) -> out = np.array(angles, copy=True)"],
    "the tool axes and times only enter float arithmetic (pole_angle, the time weights), and the angles passed are "
    "the float exact inverse (every caller): the same values as with the cast")
_equivalent(_POLE, "find_passages", [
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, float) -> "
    "T, t, angles = np.asarray(T, None), np.asarray(t, float), np.asarray(angles, float)",
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, float) -> "
    "T, t, angles = np.asarray(T, ), np.asarray(t, float), np.asarray(angles, float)",
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, float) -> "
    "T, t, angles = np.asarray(T, float), np.asarray(t, None), np.asarray(angles, float)",
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, float) -> "
    "T, t, angles = np.asarray(T, float), np.asarray(t, ), np.asarray(angles, float)",
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, float) -> "
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, None)",
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, float) -> "
    "T, t, angles = np.asarray(T, float), np.asarray(t, float), np.asarray(angles, )"],
    "read only through float arithmetic (pole_angle, differences, np.degrees): the same figures without the cast")

for _f in ("find_passages", "pole_start"):
    _equivalent(_POLE, _f, [
        "for s0, s1 in zip(starts.tolist(), ends.tolist(), strict=True): -> "
        "for s0, s1 in zip(starts.tolist(), ends.tolist(), strict=None):",
        "for s0, s1 in zip(starts.tolist(), ends.tolist(), strict=True): -> "
        "for s0, s1 in zip(starts.tolist(), ends.tolist(), ):"],
        "ends is built from starts (the next start, then the length): the two lists always have the same length")
_equivalent(_POLE, "pole_start", [
    "ta = t[s0 + a - 1] if before is not None else t[s0 + a] -> "
    "ta = t[s0 + a - 1] if before is not None else t[s0 - a]"],
    "before is None exactly when a = 0, and then s0 - a = s0 + a")
_equivalent(_POLE, "_shorter_exit", [
    "if inside and abs(c[o] - outer0) < dist - 1e-9: -> if inside and abs(c[o] - outer0) <= dist - 1e-9:"],
    "< and <= differ only for a candidate exactly 1e-9 rad nearer than the current one, a float tie the 1e-9 "
    "margin exists to avoid (either choice is then as near)")

_ISO = "camsmooth/diagnosis/iso230.py"
_equivalent(_ISO, "write_comp_file", [
    'tmp.write_text(comp_text(table), encoding="utf-8") -> tmp.write_text(comp_text(table), encoding="UTF-8")'],
    "codec names are case-insensitive")
_equivalent(_ISO, "read_run", [
    'for i, key in enumerate(zip(t["target"].tolist(), d.tolist(), t["run"].tolist(), strict=True)): -> '
    'for i, key in enumerate(zip(t["target"].tolist(), d.tolist(), t["run"].tolist(), strict=False)):',
    'for i, key in enumerate(zip(t["target"].tolist(), d.tolist(), t["run"].tolist(), strict=True)): -> '
    'for i, key in enumerate(zip(t["target"].tolist(), d.tolist(), t["run"].tolist(), strict=None)):',
    'for i, key in enumerate(zip(t["target"].tolist(), d.tolist(), t["run"].tolist(), strict=True)): -> '
    'for i, key in enumerate(zip(t["target"].tolist(), d.tolist(), t["run"].tolist(), )):'],
    "three columns of one table: always the same length")
_equivalent(_ISO, "read_run", [
    'run = Run(t["target"].astype(float), d.astype(int), t["run"].astype(int), t["deviation"].astype(float), t.file) '
    '-> run = Run(t["target"].astype(float), d.astype(int), t["run"].astype(int), t["deviation"].astype(None), '
    't.file)',
    'run = Run(t["target"].astype(float), d.astype(int), t["run"].astype(int), t["deviation"].astype(float), t.file) '
    '-> run = Run(t["target"].astype(None), d.astype(int), t["run"].astype(int), t["deviation"].astype(float), '
    't.file)'],
    "astype(None) is numpy's default float64, the same as astype(float)")
_equivalent(_ISO, "FittedTerms.deviation", [
    "p = np.asarray(position, float) -> p = np.asarray(position, )",
    "p = np.asarray(position, float) -> p = np.asarray(position, None)",
    "return self.offset + self.scale * p + np.asarray(direction, float) * self.reversal / 2 -> "
    "return self.offset + self.scale * p + np.asarray(direction, ) * self.reversal / 2",
    "return self.offset + self.scale * p + np.asarray(direction, float) * self.reversal / 2 -> "
    "return self.offset + self.scale * p + np.asarray(direction, None) * self.reversal / 2"],
    "multiplied by the float terms at once: integer positions or directions give the same floats")

_WORDS = "camsmooth/post/words.py"
_equivalent(_WORDS, "split_comments", ["depth, cut = 0, -1 -> depth, cut = 0, -2"],
            "cut is only a 'not found' mark, tested with cut >= 0: any negative value is the same")
_equivalent(_WORDS, "evaluate", [
    r'text = re.sub(r"\bMOD\b", "%", text, flags=re.I) -> text = re.sub(r"\bmod\b", "%", text, flags=re.I)'],
    "the pattern is matched ignoring case (re.I): MOD and mod are the same pattern")

_CORE = "camsmooth/post/core.py"
_equivalent(_CORE, "Builder._fid_now", ["self._current(0).frames.add(fid) -> self._current(None).frames.add(fid)"],
            "called from _append after _current(line) made sure an operation exists: the line argument, used only "
            "to start a first operation, is never read here")
_equivalent(_CORE, "Builder.move", ["self._nblock += 1 -> self._nblock += 2"],
            "block numbers are labels: only compared for equality and used as bincount bins / dict keys, so "
            "numbering them 2, 4, 6 gives the same block lengths and feeds")
_equivalent(_CORE, "Builder._append", [
    "self._op.append(len(self.ops) - 1 if op is self.ops[-1] else self.ops.index(op)) -> "
    "self._op.append(len(self.ops) - 1 if op is not self.ops[-1] else self.ops.index(op))"],
    "_current always returns the last operation, so op is self.ops[-1] and both branches give len(ops) - 1")
_equivalent(_CORE, "Builder.finish", [
    'q = q * np.asarray(getattr(machine, "linuxcnc_sense", (1.0, 1.0)), float) -> '
    'q = q * np.asarray(getattr(machine, "linuxcnc_sense", (2.0, 1.0)), float)'],
    "every Machine has linuxcnc_sense (a property of camsmooth.machine.kinematics.Machine): the default is never "
    "taken")
_equivalent(_CORE, "Builder.finish", [
    "tp_id = np.full(len(idx), -1, np.int64) -> tp_id = np.full(len(idx), -1, )",
    "tp_id = np.full(len(idx), -1, np.int64) -> tp_id = np.full(len(idx), -1, None)"],
    "an integer fill value gives numpy's default integer (int64 here): the same array")

_JERK = "camsmooth/smoothing/jerk.py"
_equivalent(_JERK, "_interval_function", [
    'args = [ca.SX.sym(k) for k in ("yk", "zk", "yk1", "zk1", "w", "h")] -> '
    'args = [ca.SX.sym(k) for k in ("yk", "zk", "yk1", "zk1", "w", "XXhXX")]'],
    "a CasADi symbol's name is a label: the function's inputs are matched by position")
_equivalent(_JERK, "jerk_law", [
    'converged=converged, iterations=int(stats.get("iter_count", 0)), solve_time=0.0) -> '
    'converged=converged, iterations=int(stats.get("iter_count", )), solve_time=0.0)'],
    "CasADi's IPOPT interface always reports iter_count in its stats: the default is never taken")

_APT = "camsmooth/io/apt.py"
_equivalent(_APT, "_unit_tuple", [
    "if n < 1e-12 or abs(n - 1.0) > UNIT_TOL: -> if n < 1e-12 or abs(n + 1.0) > UNIT_TOL:"],
    "the fast check only decides whether _unit_axis checks the vector again (with the right test): always checking "
    "gives the same verdict and message, more slowly")
_equivalent(_APT, "_unit_axis", [
    'with np.errstate(over="ignore", invalid="ignore"): -> with np.errstate(over="ignore", ):'],
    "the norm of a 3-vector squares and sums: no 0 * inf or inf - inf, so no 'invalid' warning to silence "
    "(NaN propagates silently)")
_equivalent(_APT, "read_apt", [
    "line = tp.line if tp.line is not None else first_line.get(id(tp), exc.line) -> "
    "line = tp.line if tp.line is not None else first_line.get(id(tp), None)"],
    "start_toolpath records every tool path's first line: the default is never taken")
_equivalent(_APT, "_goto_numbers", [
    "if len(v) in (3, 6) and all(abs(x) <= MAX_ABS for x in v): -> "
    "if len(v) in (3, 6) and all(abs(x) < MAX_ABS for x in v):"],
    "a value of exactly MAX_ABS then takes the checked parser, which accepts it too: the same numbers")
_equivalent(_APT, "_State.flush", ["p, a, r, f, ln, x = zip(*self.pending, strict=True) -> "
                                   "p, a, r, f, ln, x = zip(*self.pending, )"],
            "every pending entry is a 6-tuple (add): the zip is never uneven")
_equivalent(_APT, "read_apt", ['if rec.major == "END-OF-PATH": -> if rec.major == "XXEND-OF-PATHXX":'],
            "an END-OF-PATH that ends a skip is then handled as a record: with no tool path open and no arc "
            "pending (drop cleared both) it does nothing, as the skipped continue does")
_equivalent(_APT, "read_apt", ["got = _bulk_goto(texts, st.scale, axis) if len(texts) >= 16 else None -> "
                               "got = _bulk_goto(texts, st.scale, axis) if len(texts) >= 17 else None"],
            "a run of exactly 16 GOTOs then takes the record-by-record path, which gives the same points "
            "(tests/test_invariants.py checks the two paths agree): only the speed differs")
_equivalent(_APT, "read_apt", [
    "np.full(n, math.nan if rapid else feed), np.full(n, rec.line, np.int64), cur_xform) -> "
    "np.full(n, math.nan if rapid else feed), np.full(n, rec.line, None), cur_xform)"],
    "a Python int fill value gives numpy's default integer, int64 here: the same array")
_equivalent(_APT, "_apt_text", [
    'return raw.decode("latin-1").replace("\\r\\n", "\\n").replace("\\r", "\\n") -> '
    'return raw.decode("LATIN-1").replace("\\r\\n", "\\n").replace("\\r", "\\n")'],
    "codec names are case-insensitive")
for _k in ("float", "bool"):
    _equivalent(_APT, "_State.flush", [
        f"self.blocks.append((np.asarray(p, float), np.asarray(a, float), np.asarray(r, bool), -> "
        f"self.blocks.append((np.asarray(p, float), np.asarray(a, {'' if _k == 'float' else 'float'}), "
        f"np.asarray(r, {'bool' if _k == 'float' else 'None'}),"],
        "the tuples hold Python floats (axes) and bools (rapid): numpy infers float64 and bool, the same arrays")

# --- equivalents: machine/kinematics.py and smoothing/jerk.py (issue #31 item 3, second round) ---
_equivalent(_KIN, "Machine.pole_angle", [
    "T = np.atleast_2d(np.asarray(T, float)) -> T = np.atleast_2d(np.asarray(T, None))",
    "T = np.atleast_2d(np.asarray(T, float)) -> T = np.atleast_2d(np.asarray(T, ))"],
    "T only enters T @ w1 with the float screw direction w1: the same floats for integer or list input")
_equivalent(_KIN, "Machine.branch_of", [
    "h = np.asarray(self.chain.home, float)[:3, 2] -> h = np.asarray(self.chain.home, )[:3, 2]",
    "h = np.asarray(self.chain.home, float)[:3, 2] -> h = np.asarray(self.chain.home, None)[:3, 2]"],
    "every Chain's home pose is a float array (np.eye(4) in MachineChain.chain, cast to float by with_screws): "
    "asarray without the dtype returns the same array")
_equivalent(_JERK, "jerk_law", [
    "Y = float(np.median(np.minimum(ymax, ymax[ymax > 0].min(initial=1.0) * 1e3))) or 1.0 -> "
    "Y = float(np.median(np.minimum(ymax, ymax[ymax > 0].min(initial=1.0) * 1001.0))) or 1.0"],
    "Y only scales the NLP's speed variables (x = y / Y; bounds and constraints scaled with it): the cap moves Y "
    "only when over half the nodes' bounds exceed 1000 x the smallest, and then by 0.1 %, a change of the "
    "problem's conditioning, not of its solution")
_equivalent(_JERK, "jerk_law", [
    "W = float(np.median(np.min(jmax / np.abs(d1), axis=1))) -> "
    "W = float(np.median(np.min(jmax / np.abs(d1), axis=None)))"],
    "W only scales the NLP's jerk variables (w = W x the variable, every constraint written in w): the smallest "
    "ratio over every node and axis instead of the median of the per-node smallest is another positive finite "
    "scale (a zero or non-finite one falls back to Z^1.5), which changes the conditioning, not the solution")
_last = 'last = ca.MX.sym("last", 2) # y, z at the last node'
_vsym = 'v = ca.MX.sym("v", 4, n) # per interval: y, z at its first node, its w and h (scaled)'
_equivalent(_JERK, "jerk_law", [f"{_last} -> {_last.replace(a, b)}" for a, b in (
    ('"last"', '"LAST"'), ('"last"', '"XXlastXX"'))] + [f"{_vsym} -> {_vsym.replace(a, b)}" for a, b in (
        ('"v"', '"V"'), ('"v"', '"XXvXX"'))],
    "a CasADi symbol's name is a label: the NLP's variables are matched by position")
# --- end kinematics/jerk equivalents ---

# --- equivalents: controller (controller/blocks.py, controller/linuxcnc.py) ---
_LCNC = "camsmooth/controller/linuxcnc.py"
_BLK = "camsmooth/controller/blocks.py"
_WHY_EQ = "the comparison changes only at exact equality with the bound (a measure-zero set of inputs)"
_acos = "cos_theta = np.cos(np.arccos(min(max(-dot, -1.0), 1.0)) / 2.0)"
_equivalent(_LCNC, "_lag", [f"{_acos} -> {_acos.replace('-1.0), 1.0)', '-2.0), 1.0)')}"],
            "the directions are unit vectors, so -dot >= -1 up to rounding; where rounding puts it below -1 "
            "(straight on) arccos gives nan instead of pi and the cap test is false either way (nan, or cos(pi/2) "
            "= 6e-17, is not > sin(1e-3))")
_equivalent(_LCNC, "_lag", ["if cos_theta > np.sin(_MIN_ARC_ANGLE): -> if cos_theta >= np.sin(_MIN_ARC_ANGLE):"],
            _WHY_EQ)
_equivalent(_LCNC, "_update", ["if rem <= _POS_EPSILON: -> if rem < _POS_EPSILON:",
                               "if v_avg > _VEL_EPSILON: -> if v_avg >= _VEL_EPSILON:"], _WHY_EQ)
_equivalent(_LCNC, "_run", ["cap *= 2 -> cap *= 3"],
            "only the capacity of the per-cycle record grows faster; the record is cut to the cycles run")
_equivalent(_LCNC, "_run", ["dt_k = np.full(n, dt) -> dt_k = np.full(n, None)"],
            "the initial values are never read: every _update(k) is preceded by dt_k[k] = dt, and _update sets it "
            "itself when the segment splits (the target runs the kernel as plain Python, where an object array of "
            "floats computes the same)")
_equivalent(_LCNC, "_run", ["blend_vel[nx] = min(v_next, t_blend * acc_h[nx]) -> blend_vel[nx] = None"],
            "a dead store: the next segment's blend speed is read nowhere (only by the G64 P cap of the same "
            "entry) and is computed afresh, blend_vel[tc], once that segment is the head, before it is read")
_equivalent(_LCNC, "_run", ["progress[tc] = length[tc] -> progress[tc] = None"],
            "a dead store (None is nan in a float array): the segment is removed in the same cycle (i += 1) and the "
            "record reads only the progress of the new head and the one after it")
_equivalent(_LCNC, "_place_row", ["before_end = np.full((n, K), big) -> before_end = np.full((n, K), None)"],
            "the initial values are never read: before_end[j, k] is set together with start[j, k], it is read only "
            "for a state whose start was set (the loop skips the others), and the tie test that reads "
            "before_end[j2, k2] is reached only when start[j2, k2] was set (plain Python in the target, as above)")
_equivalent(_LCNC, "canon_segments", ["rapid = np.asarray(rapid, bool) -> rapid = np.asarray(rapid, )"],
            "the rapid flags only enter a comparison of neighbours and np.where: 0/1 or bool give the same "
            "segments (the callers pass bool arrays)")
_equivalent(_LCNC, "LinuxCNCPlanner.block_ends", [
    "entry = np.array([0.0, 0.0, 1.0]) -> entry = np.array([0.0, 1.0, 1.0])"],
            "an entry of no length takes no time and has no speed whatever its speed cap (_solo returns (0, 0) for "
            "length 0), and the first block's lag after it is then 0 (t_reach = 0)")
_equivalent(_LCNC, "LinuxCNCPlanner.block_ends", [
    'with np.errstate(divide="ignore", invalid="ignore"): -> with np.errstate(divide="ignore", invalid=None):'],
    "invalid=None keeps numpy's default for invalid operations (a warning): the quantities computed are the same")
_equivalent(_LCNC, "LinuxCNCPlanner.row_run", [
    "q = np.atleast_2d(np.asarray(q, float)) -> q = np.atleast_2d(np.asarray(q, None))"],
    "np.degrees and the column stack with it give floats for integer input, rounded the same: the same written "
    "values")
_equivalent(_LCNC, "LinuxCNCPlanner.run", [
    "following_fraction=np.minimum(p_next / L[head + 1], 1.0)) -> following_fraction=np.minimum(p_next / L[head + 1], "
    "2.0))"],
    "_update never takes progress past the segment's length and past the last segment the progress is 0 over "
    "a length of 1: the fractions are at most 1, the cap never binds")
_equivalent(_BLK, "_polyline_distance", ["per_point = max(curve.shape[1] - 1, 1) * 3 -> "
                                         "per_point = max(curve.shape[1] - 1, 1) * 4"],
            "per_point only sizes the chunks the points are taken in (memory): the distances are the same")
_equivalent(_BLK, "_polyline_distance", [
    'return np.sqrt(np.einsum("bpsk,bpsk->bps", close, close).min(axis=2)) -> '
    'return np.sqrt(np.einsum("BPSK,BPSK->BPS", close, close).min(axis=2))'],
    "einsum labels are arbitrary letters: the same contraction")
_equivalent(_BLK, "_tip_polyline", [
    "steps = np.maximum(int(sub), np.ceil(np.abs(dq[:, 3:]).max(axis=1, initial=0.0) / max_turn)).astype(np.int64) -> "
    "steps = np.maximum(int(sub), np.ceil(np.abs(dq[:, 3:]).max(axis=1, ) / max_turn)).astype(np.int64)"],
    "initial only matters for an empty reduction; the rows of dq[:, 3:] always hold the machine's two rotary axes")
_equivalent(_BLK, "_tip_polyline", ["q = np.asarray(q, float) -> q = np.asarray(q, )"],
            "q only enters q[owner] + frac dq with float fractions and the forward kinematics: the same tips for "
            "integer input")
_equivalent(_BLK, "block_reach", [
    "frac = np.r_[np.arange(1, k) / k, (np.arange(k) + 0.5) / k] -> frac = np.r_[np.arange(k) / k, (np.arange(k) + "
    "0.5) / k]"],
    "frac only says where _all_within starts each point's search (outward from there over every segment until "
    "one is within reach): the answers do not depend on it (tests/test_floor.py checks them against every "
    "segment by brute force with random fractions)")
_equivalent(_BLK, "_hold_row", [
    "cut = (_chord_deviation(machine, q, k, path, at) > _SPLIT_SHARE * limit) & (np.diff(k) > 1) -> "
    "cut = (_chord_deviation(machine, q, k, path, at) >= _SPLIT_SHARE * limit) & (np.diff(k) > 1)"], _WHY_EQ)
_equivalent(_BLK, "predict", ["bt = np.zeros(0) -> bt = np.zeros(1)"],
            "bt keeps this value only for a row of one kept point, where block_time[k[1:]] selects nothing and one "
            "value broadcast to no entries changes nothing")
# --- end controller equivalents ---

# --- equivalents: post writer and dialect readers ---
_WR = "camsmooth/post/writer.py"
_equivalent(_WR, "_moves", [
    "to = np.full(n, np.nan) if t_opt is None else np.asarray(t_opt[sl], float) -> "
    "to = np.full(n, np.nan) if t_opt is None else np.asarray(t_opt[sl], )"],
    "PostProgram.t_opt is a float array (s) or None; an integer one would be upcast to float by the np.concatenate "
    "with the nan entries of the rapids: the same array")
_equivalent(_WR, "write_program", [
    "feed = np.asarray(program.feed, dtype=float) -> feed = np.asarray(program.feed, dtype=None)"],
            "PostProgram.feed is float (mm/min); an integer feed gives the same checks (isfinite, > 0) and enters only "
            "float arithmetic (the tip path / feed, the F words)")
_equivalent(_WR, "format_blocks", [
    "mv = _Moves(np.zeros((len(coords), 5)), np.zeros((len(coords), 3)), rapid, np.asarray(F, float)) -> "
    "mv = _Moves(np.zeros((len(coords), 5)), np.zeros((len(coords), 3)), rapid, np.asarray(float))"],
    "format_blocks' _Moves has no t_prog, so _annotations returns before it reads mv.feed, and _blocks takes the F "
    "words from its F argument: mv.feed is never read")
_equivalent(_WR, "settings", [
    'tcp_on = (getattr(post, "tcp_on", None) if post is not None else None) or d.tcp_on -> '
    'tcp_on = (getattr(post, "tcp_on", None) if (post is not None) or True else None) or d.tcp_on'],
    "with post None the mutant reads getattr(None, 'tcp_on', None), which is None: the else branch's value")
_equivalent(_WR, "_annotations", ["prev_cut = np.r_[True, rapid[:-1]] -> prev_cut = np.r_[False, rapid[:-1]]"],
            "prev_cut[0] is read only for block 0, which is always a row's entry rapid (_moves), never one of the cut "
            "blocks k the annotations are written for")
_PISO = "camsmooth/post/iso.py"
_equivalent(_PISO, "IsoInterpreter._cycle", [
    "if self.b.has_motion() is False and math.isnan(self.initial_z): -> "
    "if self.b.has_motion() is not False and math.isnan(self.initial_z):"],
    "initial_z is only ever written (here and in __init__), never read: what it holds changes nothing")
_equivalent(_PISO, "IsoInterpreter._cycle", [
    'if vals.get("L", vals.get("K", 1.0)) == 0.0: -> if vals.get("L", vals.get("K", None)) == 0.0:'],
    "without L and K the default is compared with 0.0: 1.0 and None both differ from it")
_equivalent(_PISO, "_in_func", [
    "while k > 0 and s[k - 1].isalpha(): -> while k > 1 and s[k - 1].isalpha():",
    'return bool(re.match(r"[A-Za-z]+\\[", s[k:])) -> return bool(re.match(r"[A-ZA-Z]+\\[", s[k:]))'],
    "the backward scan is dead: it runs only when the letters from s[j] on are not followed by '[', and s[k:] "
    "(more letters of the same run, then the same end) is then never letters + '[' either: it returns False "
    "whatever k is and whatever letters the class holds")
_equivalent(_PISO, "IsoInterpreter._words", [
    "words.append((ch, self._value(s[j:k], number))) -> words.append((ch, self._value(s[j:k], None)))"],
    "IsoInterpreter._value does not read its number argument (the line): any value gives the same word")
_HH = "camsmooth/post/heidenhain.py"
_equivalent(_HH, "_Klartext.__init__", ["self.file = file -> self.file = None",
                                        "self.cycle7 = False -> self.cycle7 = True"],
            "_Klartext.file and _Klartext.cycle7 are only ever written, never read (the Builder keeps the file name)")
_MP = "camsmooth/post/millplus.py"
_equivalent(_MP, "_MillPlus._keyword", ['if up.startswith("%PM"): -> if up.startswith("XX%PMXX"):',
                                       'return "" -> return "XXXX"'],
            "the %PM line never reaches _keyword: it is the first line beginning with '%', and the ISO interpreter's "
            "program starts after it (IsoInterpreter._program_range). (The key also names _keyword's other "
            "'return \"\"' lines: their 'XXXX' is read as a word without a value and refused, which the G7 / G141 / "
            "G93 / G74 / G4 / cycle tests see: those mutants are killed, never excused by this entry)")
_equivalent(_MP, "_MillPlus._keyword", ["self.b.tcp = False -> self.b.tcp = None"],
            "the Builder reads tcp only for its truth (1 if self.tcp else ...), and None is false like False")
_equivalent(_PISO, "IsoInterpreter._run_block", [
    'self.b.machine_move(line, f"machine-coordinate move (G{g[0]:g})" if g else "machine move") -> '
    'self.b.machine_move(line, f"machine-coordinate move (G{g[0]:g})" if g else "XXmachine moveXX")'],
    "non_modal_machine is set only by a G53 / G28 / G30 of the block's G words, so g is never empty here and "
    "the else text is never written")
_SI = "camsmooth/post/siemens.py"
_equivalent(_SI, "_Siemens._keyword", [
    'if not m or m.group(1).upper() in ("CYCLE832",) or m.group(1).upper().startswith(("CR", "AR")) \\ -> '
    'if not m or m.group(1).upper() in ("CYCLE832",) or m.group(1).lower().startswith(("CR", "AR")) \\'],
    "the CR / AR clause is dead: it also needs a name of 2 characters, and the assignment pattern gives 2 only "
    "for R0..R9 (other names have 3 or more), which never start with CR or AR")
_equivalent(_SI, "_Siemens._keyword", [
    'tokens = re.findall(r"[A-Z_][A-Z0-9_]*\\s*\\([^()]*\\)|[A-Z_][A-Z0-9_]*\\s*=\\s*\\"[^\\"]*\\"|" -> '
    'tokens = re.findall(r"[a-z_][a-z0-9_]*\\s*\\([^()]*\\)|[a-z_][a-z0-9_]*\\s*=\\s*\\"[^\\"]*\\"|"'],
    "the pattern is matched with re.I: upper- and lower-case classes match the same tokens")
_equivalent(_SI, "_Siemens._frame", [
    'm = re.match(r"([XYZ])\\s*=?\\s*(.+)$", t, re.I) -> m = re.match(r"([xyz])\\s*=?\\s*(.+)$", t, re.I)'],
    "matched with re.I: [XYZ] and [xyz] match the same words (the letter is upper-cased after)")
_equivalent(_SI, "_Siemens._drill", [
    'args = [a.strip() for a in tok[tok.index("(") + 1:-1].split(",")] -> '
    'args = [a.strip() for a in tok[tok.rindex("(") + 1:-1].split(",")]'],
    "a cycle token is NAME( ... ) with no parenthesis inside (the token pattern \\([^()]*\\)): its only '(' is "
    "both the first and the last")
_equivalent(_HH, "_Klartext._plane", [
    'for k in ("Q120", "Q121", "Q122"): # the rotary positions the control computes for the plane: the -> '
    'for k in ("q120", "Q121", "Q122"): # the rotary positions the control computes for the plane: the'],
    "_Klartext._num names a Q parameter by its key without the first letter (k[1:]): 'q120' and 'Q120' are the "
    "same v_q120")
_equivalent(_SI, "_read", [
    'def _read(path: str, text: str, machine: Any = None, dialect: str = "siemens", -> '
    'def _read(path: str, text: str, machine: Any = None, dialect: str = "SIEMENS",'],
    "_read never reads its dialect parameter (the registry passes one; read_siemens takes none)")
_equivalent(_SI, "_Siemens._keyword", [
    'elif word in ("G54", "G55", "G56", "G57"): -> elif word in ("G54", "G55", "G56", "XXG57XX"):'],
    "G57 then goes on to the ISO words, where IsoInterpreter records the same offset 'G57' (its _OFFSETS)")
_equivalent(_PISO, "IsoInterpreter._run_block", [
    "self.b.note(_NOTED_G[c], line) -> self.b.note(None, line)",
    "self.b.note(_NOTED_G[c], line) -> self.b.note(_NOTED_G[c], )"],
    "the surviving ones are in the 'elif c == 53.1' branch, which is dead: 53.1 is a key of _NOTED_G, so the "
    "branch before it takes G53.1. (The same change in the live _NOTED_G branch is killed by the tests that "
    "check G05.1 / G61 / G13.1 are named with their lines: this entry excuses no mutant that survives there)")
_equivalent(_SI, "_Siemens._keyword", [
    'elif re.match(r"G5[0-9][0-9]$", word) and 505 <= int(word[1:]) <= 599: -> '
    'elif re.match(r"G5[0-9][0-9]$", word) and 505 <= int(word[1:]) <= 600:'],
    "the pattern G5[0-9][0-9] admits G500..G599 only: '<= 599' and '<= 600' agree on every word it lets through")
_OWN = "camsmooth/post/own.py"
_equivalent(_OWN, "_strip_comment", ['line = line.split(";", 1)[0] -> line = line.split(";", )[0]'],
            "the first part of a split is the text before the first ';' whatever the number of splits")
_equivalent(_OWN, "read_gcode", ['if not s or s.startswith("%"): -> if not s or s.startswith("XX%XX"):'],
            "a '%' line (tape start / end) holds no motion word: without the skip it is passed over as a block "
            "without X Y Z or L, the same result")
_equivalent(_OWN, "read_gcode", [
    'words = dict((w, float(v)) for w, v in _WORD.findall(s[2:].replace("FMAX", ""))) -> '
    'words = dict((w, float(v)) for w, v in _WORD.findall(s[2:].replace("XXFMAXXX", "")))'],
    "_WORD needs a number after the letter: 'FMAX' gives no word whether or not it is removed")
_equivalent(_OWN, "read_gcode", ["q = np.asarray(joints, dtype=float) -> q = np.asarray(joints, dtype=None)"],
            "joints is a list of lists of Python floats: numpy gives float64 either way")
# --- end post equivalents ---

# mutmut's exit codes; -9 is the SIGKILL its runner sends one second after the CPU limit's SIGXCPU (a
# timeout that ignored SIGXCPU), -11 a crash of the test process: the tests did not pass either way
STATUS = {1: "killed", 3: "killed", 0: "survived", 5: "no tests", 33: "no tests", 34: "skipped",
          36: "timeout", -24: "timeout", 24: "timeout", 152: "timeout", 255: "timeout", -9: "timeout",
          -11: "killed", 37: "type check", None: "not checked"}


@dataclass
class Mutant:
    name: str
    path: str
    status: str
    function: str = ""
    change: str = ""

    @property
    def key(self) -> str:
        return f"{self.path}::{self.function}: {self.change}"


@dataclass
class ModuleResult:
    module: str
    mutants: list[Mutant]
    seconds: float
    #: mutants mutmut generated for the module (more than ``mutants`` when a sample was run)
    generated: int = 0

    @property
    def interval(self) -> tuple[float, float]:
        """95% Wilson interval of the score (a sampled module's score estimates the whole's)."""
        n = len(self.mutants) - len(self.equivalent)
        if n == 0:
            return 1.0, 1.0
        p, z = self.score, 1.96
        mid = (p + z * z / (2 * n)) / (1 + z * z / n)
        half = z * ((p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5) / (1 + z * z / n)
        return mid - half, mid + half

    def count(self, *status: str) -> int:
        return sum(m.status in status for m in self.mutants)

    @property
    def equivalent(self) -> list[Mutant]:
        return [m for m in self.mutants if m.status not in ("killed", "timeout") and m.key in EQUIVALENT]

    @property
    def surviving(self) -> list[Mutant]:
        return [m for m in self.mutants if m.status not in ("killed", "timeout") and m.key not in EQUIVALENT]

    @property
    def score(self) -> float:
        n = len(self.mutants) - len(self.equivalent)
        return (self.count("killed", "timeout") / n) if n else 1.0


def _copy_repository(dst: Path, commit: str | None = None) -> None:
    """Copy the files git knows (tracked + untracked, not ignored) into dst; with ``commit``, that
    commit's tree instead (``git archive``: other work in progress in the working tree stays out)."""
    if commit:
        archive = subprocess.run(["git", "archive", "--format=tar", commit], cwd=ROOT, check=True,
                                 capture_output=True).stdout
        with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
            tar.extractall(dst, filter="data")
        return
    out = subprocess.run(["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=ROOT, check=True,
                         capture_output=True).stdout.decode()
    for rel in filter(None, out.split("\0")):
        src = ROOT / rel
        if src.is_file() and not rel.startswith("mutants/"):
            (dst / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst / rel)


def _configure(dst: Path, target: Target) -> None:
    """Append mutmut's configuration for this target to the copy's pyproject.toml."""
    also = sorted(p.name for p in dst.iterdir() if p.name not in ("camsmooth", "tests", "pyproject.toml", ".git"))
    toml = "\n".join([
        "", "[tool.mutmut]",
        'source_paths = ["camsmooth"]',
        f"only_mutate = {json.dumps(list(target.paths))}",
        f"pytest_add_cli_args_test_selection = {json.dumps(list(target.tests))}",
        'pytest_add_cli_args = ["-p", "no:cacheprovider"]',
        f"also_copy = {json.dumps(also)}",
        "use_git_change_detection = false",
        # polars (camsmooth.io.table) starts a Rust thread pool on first use; a worker forked from a
        # process that ran the tests deadlocks on it, so fork the workers from a server that only collects
        'process_isolation = "forkserver"',
        "",
    ])
    with open(dst / "pyproject.toml", "a") as f:
        f.write(toml)


def _restrict(dst: Path, target: Target) -> None:
    """Mark every function of the target files that is not in target.functions as not to be mutated."""
    import libcst as cst

    keep = set(target.functions)

    class Mark(cst.CSTTransformer):
        def __init__(self) -> None:
            self.cls: list[str] = []

        def visit_ClassDef(self, node: cst.ClassDef) -> bool:
            self.cls.append(node.name.value)
            return True

        def leave_ClassDef(self, original: cst.ClassDef, updated: cst.ClassDef) -> cst.ClassDef:
            self.cls.pop()
            return updated

        def visit_FunctionDef(self, node: cst.FunctionDef) -> bool:
            return False  # nested functions go with their parent

        def leave_FunctionDef(self, original: cst.FunctionDef, updated: cst.FunctionDef) -> cst.FunctionDef:
            name = ".".join(self.cls + [updated.name.value])
            if name in keep or not isinstance(updated.body, cst.IndentedBlock):
                return updated
            old = updated.body.header.comment
            text = (old.value + " " if old else "# ") + "pragma: no mutate block"
            header = updated.body.header.with_changes(comment=cst.Comment(text),
                                                      whitespace=cst.SimpleWhitespace("  "))
            return updated.with_changes(body=updated.body.with_changes(header=header))

    for pattern in target.paths:
        for path in dst.glob(pattern):
            tree = cst.parse_module(path.read_text())
            path.write_text(tree.visit(Mark()).code)


def _environment(target: Target) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "MUTANT_UNDER_TEST")}
    # one thread per worker: the machine has 2 shared cores and --max-children sets the parallelism
    for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        env[k] = "1"
    # conftest finds the Michigan data beside the repository; the copy is elsewhere
    env.setdefault("CAMSMOOTH_UMICH", str(ROOT.parent / "shared" / "data" / "umich-cnc-mill"))
    env.update(target.env)
    return env


def _describe(diff: str) -> str:
    """The changed lines of a mutant's diff, whitespace-normalised: 'before -> after'."""
    minus = [" ".join(ln[1:].split()) for ln in diff.splitlines() if ln.startswith("-") and not ln.startswith("---")]
    plus = [" ".join(ln[1:].split()) for ln in diff.splitlines() if ln.startswith("+") and not ln.startswith("+++")]
    return f"{' / '.join(minus)} -> {' / '.join(plus)}"


def _function(name: str) -> str:
    """Function (Class.method) of a mutmut mutant name such as pkg.mod.xǁClassǁmeth__mutmut_3."""
    mangled = name.rpartition(".")[2].partition("__mutmut_")[0]
    if mangled.startswith("xǁ"):
        return ".".join(mangled[2:].split("ǁ"))
    return mangled[2:]


def _collect(work: Path) -> list[Mutant]:
    """Verdicts from mutmut's meta files and, for the undetected mutants, their diffs (mutants
    left out of a sample have no verdict: status "not checked")."""
    from mutmut.mutation.diff_apply import get_diff_for_mutant

    mutants: list[Mutant] = []
    cwd = os.getcwd()
    os.chdir(work)  # mutmut resolves mutants/<path> against the working directory
    try:
        for meta in sorted(Path("mutants").rglob("*.py.meta")):
            path = str(meta.relative_to("mutants"))[: -len(".meta")]
            codes = json.loads(meta.read_text())["exit_code_by_key"]
            for name, code in codes.items():
                m = Mutant(name=name, path=path, status=STATUS.get(code, f"exit {code}"), function=_function(name))
                if m.status not in ("killed", "timeout", "not checked"):
                    m.change = _describe(get_diff_for_mutant(name, path=path))
                mutants.append(m)
    finally:
        os.chdir(cwd)
    return mutants


def _sampled(work: Path, mutants: list[Mutant]) -> list[Mutant]:
    """The mutants of the run's sample (sample.txt in the copy), or all of them (a full run, where a
    mutant mutmut did not check counts as surviving)."""
    sample = work / "sample.txt"
    if not sample.exists():
        return mutants
    names = set(sample.read_text().split())
    return [m for m in mutants if m.name in names]


def run_module(module: str, max_children: int, keep: bool, seed: int = 1, commit: str | None = None) -> ModuleResult:
    target = TARGETS[module]
    work = Path(tempfile.mkdtemp(prefix=f"camsmooth-mutation-{module}-"))
    t0 = time.perf_counter()
    try:
        _copy_repository(work, commit)
        _configure(work, target)
        if target.functions:
            _restrict(work, target)
        if target.fresh_fixtures:
            for test in target.tests:
                path = work / test
                if test.endswith(".py") and path.exists():
                    path.write_text(path.read_text().replace('@pytest.fixture(scope="module")', "@pytest.fixture"))
        if target.strip_njit:
            for pattern in target.paths:
                for path in work.glob(pattern):
                    lines = path.read_text().splitlines(keepends=True)
                    path.write_text("".join(ln for ln in lines if not ln.lstrip().startswith("@njit")))
        mutmut = Path(sys.executable).parent / "mutmut"
        log = work / "mutmut.log"
        names: list[str] = []
        if target.sample:
            # generate the mutants and the test statistics only (a name that matches no mutant stops mutmut
            # after both), then draw the sample from the generated names
            with open(log, "w") as f:
                subprocess.run([str(mutmut), "run", "--max-children", str(max_children), "no-such-mutant"], cwd=work,
                               env=_environment(target), stdout=f, stderr=subprocess.STDOUT)
            every = sorted(m.name for m in _collect(work))
            if not every:
                raise RuntimeError(f"mutmut generated no mutants for {module}: see {log}")
            rng = random.Random(seed)
            names = sorted(rng.sample(every, min(target.sample, len(every))))
            (work / "sample.txt").write_text("\n".join(names) + "\n")
        with open(log, "a") as f:
            proc = subprocess.run([str(mutmut), "run", "--max-children", str(max_children), *names], cwd=work,
                                  env=_environment(target), stdout=f, stderr=subprocess.STDOUT)
        if proc.returncode != 0:
            tail = log.read_text(errors="replace").replace("\r", "\n").splitlines()[-40:]
            raise RuntimeError(f"mutmut run failed for {module} (exit {proc.returncode}):\n" + "\n".join(tail))
        everything = _collect(work)
        mutants = _sampled(work, everything)
        (work / "mutation-seconds.txt").write_text(f"{time.perf_counter() - t0:.1f}\n")
    finally:
        if keep:
            print(f"[{module}] copy kept at {work}")
        else:
            shutil.rmtree(work, ignore_errors=True)
    return ModuleResult(module=module, mutants=mutants, seconds=time.perf_counter() - t0, generated=len(everything))


def report(results: list[ModuleResult]) -> bool:
    head = (f"{'module':<12} {'mutants':>7} {'killed':>6} {'timeout':>7} {'survived':>8} {'equiv':>5} "
            f"{'score':>7}  verdict")
    print(head)
    print("-" * len(head))
    ok = True
    for r in results:
        passed = r.score >= THRESHOLD
        ok &= passed
        sampled = ""
        if r.generated > len(r.mutants):
            lo, hi = r.interval
            sampled = (f"   sample of {len(r.mutants)} / {r.generated} mutants: 95% interval "
                       f"{100 * lo:.1f}-{100 * hi:.1f}%")
        print(f"{r.module:<12} {len(r.mutants):>7} {r.count('killed'):>6} {r.count('timeout'):>7} "
              f"{len(r.surviving):>8} {len(r.equivalent):>5} {100 * r.score:>6.1f}%  "
              f"{'PASS' if passed else 'FAIL'} (>= {100 * THRESHOLD:.0f}%)   {r.seconds:.0f} s{sampled}")
    for r in results:
        print(f"\n== {r.module}: {len(r.surviving)} surviving mutants")
        for m in r.surviving:
            print(f"  [{m.status}] {m.name}\n      {m.function}: {m.change}")
        if r.equivalent:
            print(f"== {r.module}: {len(r.equivalent)} reviewed equivalent")
            for m in r.equivalent:
                print(f"  {m.name}\n      {m.function}: {m.change}\n      why: {EQUIVALENT[m.key]}")
    seen = {m.key for r in results for m in r.mutants}
    paths = {m.path for r in results for m in r.mutants}
    stale = sorted(k for k in EQUIVALENT if k.split("::")[0] in paths and k not in seen)
    if stale:   # the code changed under an entry: review it
        print(f"\n{len(stale)} entries of EQUIVALENT match no mutant of the files run:")
        for k in stale:
            print(f"  {k}")
    return ok


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--modules", nargs="+", choices=sorted(TARGETS), default=list(TARGETS),
                    help="core modules to mutate (default: all)")
    ap.add_argument("--max-children", type=int, default=2, help="parallel mutmut workers (default 2)")
    ap.add_argument("--seed", type=int, default=1, help="seed of the mutant sample of sampled modules (default 1)")
    ap.add_argument("--commit", metavar="REV",
                    help="mutate a copy of this commit's tree (e.g. HEAD) instead of the working tree")
    ap.add_argument("--keep", action="store_true", help="keep the temporary copies (mutmut show works there)")
    ap.add_argument("--report", nargs="+", metavar="COPY",
                    help="print the table again from copies kept by --keep (with the current EQUIVALENT table)")
    args = ap.parse_args(argv)
    results = []
    t0 = time.perf_counter()
    if args.report:
        for copy in map(Path, args.report):
            module = copy.name.removeprefix("camsmooth-mutation-").rsplit("-", 1)[0]
            sec = copy / "mutation-seconds.txt"
            # copies from before the wall time was recorded: from the copy's own file times
            seconds = float(sec.read_text()) if sec.exists() else \
                (copy / "mutmut.log").stat().st_mtime - (copy / "pyproject.toml").stat().st_mtime
            everything = _collect(copy)
            results.append(ModuleResult(module=module, mutants=_sampled(copy, everything), seconds=seconds,
                                        generated=len(everything)))
        return 0 if report(results) else 1
    failed = []
    for module in args.modules:
        t = TARGETS[module]
        only = f" (functions {', '.join(t.functions)})" if t.functions else ""
        only += f" (a random sample of {t.sample} mutants, seed {args.seed})" if t.sample else ""
        print(f"[{module}] mutating {', '.join(t.paths)}{only} against {' '.join(t.tests)}", flush=True)
        try:
            results.append(run_module(module, args.max_children, args.keep, args.seed, args.commit))
        except RuntimeError as exc:   # one module's failure does not lose the others' results
            print(exc, flush=True)
            failed.append(module)
    print()
    ok = report(results) and not failed
    if failed:
        print(f"\nmutmut failed for: {', '.join(failed)} (see above)")
    print(f"\nwall time {time.perf_counter() - t0:.0f} s, --max-children {args.max_children}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
