"""spindle_runout: a tip displacement of radius r turning once per spindle revolution, phase phi
at spindle angle 0 (angle = integral of S since the program start), in the tool frame's xy."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from camsmooth.diagnosis.recordings import TIP_CHANNELS
from camsmooth.diagnosis.terms.base import Param, Term, fmt
from camsmooth.machine.model import ErrorModel

if TYPE_CHECKING:
    from camsmooth.diagnosis.problem import Problem


class SpindleRunout(Term):
    name = "spindle_runout"

    def applicable(self, P: Problem) -> str | None:
        if not any(c in P.channels for c in TIP_CHANNELS):
            return "needs measured tool-tip channels"
        if P.knots.S is None or not np.any(P.knots.S != 0):
            return "the spindle does not turn in the program"
        return None

    def params(self, P: Problem) -> list[Param]:
        return [Param("rc", -5.0, 5.0, 1e-3, "mm", "runout"), Param("rs", -5.0, 5.0, 1e-3, "mm", "runout")]

    def write(self, model: ErrorModel, names: Sequence[str], x: np.ndarray) -> None:
        model.runout = (float(x[0]), float(x[1]))

    def read(self, model: ErrorModel, names: Sequence[str]) -> np.ndarray:
        return np.array(model.runout, float)

    def report(self, names: Sequence[str], x: np.ndarray, sd: np.ndarray
               ) -> tuple[dict[str, float | None], dict[str, float | None], dict[str, str]]:
        r = float(math.hypot(x[0], x[1]))
        phi = float(math.degrees(math.atan2(x[1], x[0])))
        sr = float(math.sqrt((x[0] * sd[0]) ** 2 + (x[1] * sd[1]) ** 2) / r) if r > 0 else float(max(sd))
        sphi = float(math.degrees(sr / r)) if r > 0 else None
        return ({"radius": r, "phase_deg": phi}, {"radius": sr, "phase_deg": sphi},
                {"radius": "mm", "phase_deg": "deg"})

    def sentence(self, params: dict[str, Any], unc: dict[str, Any], none: Sequence[str]) -> str:
        return (f"The tool tip runs out at 1x spindle revolution with radius {fmt(params['radius'], 'mm')} at "
                f"phase {fmt(params['phase_deg'], 'deg')}")

    def state(self, P: Problem, names: Sequence[str]) -> tuple[str, np.ndarray, str]:
        return "spindle angle (deg, mod 360)", np.degrees(np.mod(P.states["spindle_angle"], 2 * np.pi)), "deg"
