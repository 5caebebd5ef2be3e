"""Simulation versus recordings (METHODS.md section 6): the public entry points of the
diagnosis, gathered from its modules (kept so that ``camsmooth.diagnosis.engine`` imports go on
working):

- camsmooth.diagnosis.simulator: the program's knots, the simulator, simulated recordings;
- camsmooth.diagnosis.problem: noise floors, outliers, located intervals, ``Options``, ``Problem``;
- camsmooth.diagnosis.terms: the library of physics terms, one module per term;
- camsmooth.diagnosis.selector: fitting, held-out scoring and selection of the terms;
- camsmooth.diagnosis.findings: ``diagnose``, ``validate`` and the typed findings;
- camsmooth.diagnosis.model_io: the model JSON (camsmooth.machine.model.ErrorModel).
"""

from __future__ import annotations

from camsmooth.diagnosis.findings import (
    Diagnosis,
    Effect,
    Findings,
    Rejection,
    diagnose,
    sentence_for,
    validate,
    write_findings,
    write_model,
)
from camsmooth.diagnosis.model_io import load_model, model_json, physics_from_model
from camsmooth.diagnosis.problem import Options, Problem, locate_intervals, noise_floor, prepare, white_noise
from camsmooth.diagnosis.selector import Fit, Selector
from camsmooth.diagnosis.simulator import (
    Knots,
    Physics,
    Simulator,
    add_simulate_recording_arguments,
    physics_from_settings,
    simulate_recording,
    simulate_recording_cli,
)
from camsmooth.diagnosis.terms import CANDIDATES, LIBRARY, SEPARATING, separating_measurement

__all__ = ["CANDIDATES", "LIBRARY", "SEPARATING", "Diagnosis", "Effect", "Findings", "Fit", "Knots", "Options",
           "Physics", "Problem", "Rejection", "Selector", "Simulator", "add_simulate_recording_arguments", "diagnose",
           "load_model", "locate_intervals", "model_json", "noise_floor", "physics_from_model",
           "physics_from_settings", "prepare", "sentence_for", "separating_measurement", "simulate_recording",
           "simulate_recording_cli", "validate", "white_noise", "write_findings", "write_model"]
