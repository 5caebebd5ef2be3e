"""The library of physics terms of the diagnosis, one module per term (``base.Term`` is the
interface). ``LIBRARY`` is in METHODS.md section 6's order of the usual suspects (the order in
which two terms that explain a residual equally are named), followed by the linear-axis errors."""

from __future__ import annotations

from camsmooth.diagnosis.terms.backlash import Backlash
from camsmooth.diagnosis.terms.backlash_load import BacklashLoad
from camsmooth.diagnosis.terms.base import Param, Term
from camsmooth.diagnosis.terms.linear import LinearPositioning, LinearSquareness, LinearStraightness
from camsmooth.diagnosis.terms.quantisation import Quantisation
from camsmooth.diagnosis.terms.rotary_location import RotaryLocation
from camsmooth.diagnosis.terms.rotary_squareness import RotarySquareness
from camsmooth.diagnosis.terms.servo_lag import ServoLag
from camsmooth.diagnosis.terms.servo_second_order import ServoSecondOrder
from camsmooth.diagnosis.terms.spindle_runout import SpindleRunout
from camsmooth.diagnosis.terms.spindle_tilt import SpindleTilt
from camsmooth.diagnosis.terms.thermal import ThermalDrift, ThermalMachine
from camsmooth.diagnosis.terms.thermal_temperature import ThermalTemperature
from camsmooth.diagnosis.terms.thermal_time import ThermalTime
from camsmooth.diagnosis.terms.time_offset import TimeOffset
from camsmooth.diagnosis.terms.tool_length import ToolLength
from camsmooth.diagnosis.terms.transport_delay import TransportDelay
from camsmooth.diagnosis.terms.velocity_limit import AccelerationLimit, VelocityLimit

LIBRARY: tuple[Term, ...] = (ServoLag(), TimeOffset(), Backlash(), RotaryLocation(), RotarySquareness(),
                             SpindleTilt(), SpindleRunout(), ToolLength(), ThermalDrift(), ThermalMachine(),
                             LinearPositioning(), LinearStraightness(), LinearSquareness(),
                             # controller traces only (camsmooth.diagnosis.trace)
                             ServoSecondOrder(), VelocityLimit(), AccelerationLimit(), BacklashLoad(),
                             ThermalTemperature(), ThermalTime(), Quantisation(), TransportDelay())
CANDIDATES: tuple[str, ...] = tuple(t.name for t in LIBRARY)
#: the terms only a controller trace can show (not applicable to a program and its recording)
TRACE_ONLY: tuple[str, ...] = ("servo_second_order", "velocity_limit", "acceleration_limit", "backlash_load",
                               "thermal_temperature", "thermal_time", "quantisation", "transport_delay")


def term(name: str) -> Term:
    """The library term of this name."""
    for t in LIBRARY:
        if t.name == name:
            return t
    raise KeyError(name)


#: what separates two terms that explain a residual equally well
SEPARATING = {
    frozenset({"servo_lag", "time_offset"}):
        "a move whose speed changes (an acceleration, a start or a reversal), recorded with a sampling "
        "period well below 1/Kv, separates them: a lag rounds the velocity corners with time constant 1/Kv, "
        "a clock offset only shifts them; and one clock offset gives every axis the same delay",
    frozenset({"servo_lag", "servo_second_order"}):
        "a step or a sharp start of the command, sampled well below 1/wn, separates them: a second-order servo "
        "starts slowly and overshoots, a first-order lag starts at once and never overshoots",
    frozenset({"servo_lag", "velocity_limit"}):
        "moves at two clearly different speeds separate them: a lag grows with speed, a velocity limit clips "
        "only the fast one",
    frozenset({"servo_lag", "acceleration_limit"}):
        "a long move at constant speed separates them: a lag stays behind by v/Kv all along, an acceleration "
        "limit catches up once the speed is reached",
    frozenset({"servo_lag", "transport_delay"}):
        "a move whose speed changes (an acceleration, a start or a reversal), recorded with a sampling "
        "period well below 1/Kv, separates them: a lag rounds the velocity corners with time constant 1/Kv, "
        "a delay only shifts them",
    frozenset({"time_offset", "transport_delay"}):
        "axes whose delays differ separate them: one clock offset gives every axis the same delay",
    frozenset({"thermal_temperature", "thermal_time"}):
        "a recording through a cool-down (or a change of ambient) with the temperatures logged separates them: "
        "growth that follows the temperatures turns with them, growth that follows time does not",
    frozenset({"backlash", "backlash_load"}):
        "reversing the motion under a load of one sign (or changing the load while the axis holds still) "
        "separates them",
    frozenset({"servo_lag", "backlash"}):
        "moves of the same axis at two clearly different speeds, with a dwell after each reversal, separate "
        "them: lag grows with speed and vanishes at rest, backlash does not",
    frozenset({"time_offset", "backlash"}):
        "a dwell after each reversal separates them: an offset error vanishes at rest, backlash does not",
    frozenset({"rotary_location", "spindle_tilt"}):
        "measuring the tool axis as well as the tip, or sweeping the other rotary axis, separates them",
    frozenset({"rotary_location", "tool_length"}):
        "sweeping each rotary axis over a wider range separates them",
    frozenset({"rotary_squareness", "spindle_tilt"}):
        "sweeping each rotary axis separately over its range separates them",
    frozenset({"thermal_drift", "servo_lag"}):
        "a longer recording with the spindle stopped for a cool-down separates them",
    frozenset({"thermal_drift", "thermal_machine"}):
        "repeating the measurement at several A and B poses while the machine warms separates them: growth in "
        "the spindle frame turns with the head, growth of the axes and column does not",
    frozenset({"linear_positioning", "backlash"}):
        "approaching the same targets from both directions separates them (ISO 230-2 bidirectional run)",
    frozenset({"linear_positioning", "linear_squareness"}):
        "measuring the tip along the axis of motion and across it separates them",
    frozenset({"linear_straightness", "linear_squareness"}):
        "a longer stroke of the moving axis separates them: squareness grows linearly, straightness does not",
    frozenset({"thermal_machine", "linear_positioning"}):
        "returning to the same positions at several times while the machine warms separates them",
}


def separating_measurement(a: str, b: str) -> str:
    return SEPARATING.get(frozenset({a, b}),
                          "a program that moves the machine through states where the two predictions differ "
                          "(other speeds, rotary positions or spindle speeds) separates them")


__all__ = ["CANDIDATES", "LIBRARY", "SEPARATING", "TRACE_ONLY", "Param", "Term", "separating_measurement", "term"]
