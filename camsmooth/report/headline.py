"""The headline of a smoothing run: what smoothing bought and what it cost, against the program
the user brought, computed once (``headline``) and printed by the report and by ``smooth``'s
summary alike, so the figures are the same everywhere.

The program the user brought: method 'cam' (the CAM's own tool axes) where the input has them,
else 'none' (the axes the path gives without smoothing). The facts, each "before -> after" from
the methods' ``Metrics``: the cycle time on the machine's controller where camsmooth models it
(``Metrics.controller``, e.g. the LinuxCNC planner) and under the time-optimal law (s), the peak
rotary accelerations (deg/s^2) and the limit violations under the planned time law (at the
programmed feed when either program is not planned), the largest scallop between adjacent passes
(um, where known) and the worst clearance tool to surface (um; < 0: a gouge).
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass
from typing import Any

__all__ = ["Fact", "Headline", "baseline_method", "headline"]


@dataclass(frozen=True)
class Fact:
    """One figure before and after. name: what it is ('cycle time on the linuxcnc controller');
    unit: 's', 'deg/s²', 'µm' or '' for a count; spec: the number format; sense: the direction in
    which smoothing helps ('lower', or 'clearance': higher is better only below ``gouge_below``, a
    gouge beyond the tolerance; above it the program is clean either way); percent: show the relative
    change; detail_before / detail_after: what a count is made of ('B acceleration 3')."""

    name: str
    unit: str
    before: float
    after: float
    spec: str = ".4g"
    sense: str = "lower"
    percent: bool = False
    detail_before: str = ""
    detail_after: str = ""
    gouge_below: float = 0.0

    @property
    def change(self) -> float:
        """Relative change after / before - 1 (NaN where before is zero or not finite)."""
        if not (math.isfinite(self.before) and math.isfinite(self.after)) or self.before == 0:
            return float("nan")
        return self.after / self.before - 1.0

    @property
    def better(self) -> bool | None:
        """True where smoothing helped, False where it cost, None where it is the same."""
        if self.after == self.before:
            return None
        if self.sense == "clearance":
            if min(self.before, self.after) >= self.gouge_below:
                return None
            return self.after > self.before
        return self.after < self.before

    def _value(self, v: float) -> str:
        if self.unit == "":
            return str(int(v))
        return f"{format(v, self.spec)} {self.unit}"

    def text(self) -> str:
        """'cycle time on the linuxcnc controller 155.8 s -> 130.1 s (-17%)' (plain text)."""
        out = f"{self.name} {self._value(self.before)} -> {self._value(self.after)}"
        if self.percent and math.isfinite(self.change):
            out += f" ({100 * self.change:+.0f}%)"
        if self.detail_before or self.detail_after:
            out += f" ({self.detail_before or 'none'} -> {self.detail_after or 'none'})"
        return out


@dataclass(frozen=True)
class Headline:
    """The facts of ``after`` (the primary method) against ``before`` (the program as brought),
    ``before_label`` saying what that is, ``law`` the time law the peaks and violations are under."""

    before: str
    after: str
    before_label: str
    law: str
    facts: tuple[Fact, ...]

    def title(self) -> str:
        return f"What {self.after} bought and cost against {self.before_label} ('{self.before}')"

    def lines(self) -> list[str]:
        """The facts, one plain-text line each."""
        return [f.text() for f in self.facts]

    def text(self) -> str:
        """The title and a line per fact, plain text (the ``smooth`` summary)."""
        return "\n".join([self.title() + f" (peaks and violations {self.law}):", *("  " + x for x in self.lines())])

    def html(self) -> str:
        """A box for the top of the report: the title and a line per fact, green where smoothing
        helped, red where it cost."""
        colour = {True: "#176317", False: "#b00", None: "#222"}
        items = "".join(f"<li style='color:{colour[f.better]}'>{html.escape(f.text())}</li>" for f in self.facts)
        return (f"<div class='headline' style='border:2px solid #446;background:#f4f6fb;padding:0.4em 1em;"
                f"margin:0.8em 0;font-size:1.05em'><b>{html.escape(self.title())}</b>"
                f"<ul style='margin:0.3em 0'>{items}</ul><span style='font-size:0.85em;color:#555'>"
                f"Peaks and violations {html.escape(self.law)}; green: better, red: worse.</span></div>")


def baseline_method(methods: Any) -> str | None:
    """The program the user brought: 'cam' where the input has its own axes, else 'none'."""
    for name in ("cam", "none"):
        if name in methods:
            return name
    return None


def _named_counts(counts: dict[str, int]) -> tuple[int, str]:
    return int(sum(counts.values())), ", ".join(f"{k} {v}" for k, v in counts.items() if v)


def headline(result: Any) -> Headline | None:
    """The Headline of a ``SmoothResult``: its primary method against the program the user
    brought; None when there is no such program or it is the primary method itself."""
    base = baseline_method(result.methods)
    if base is None or base == result.primary:
        return None
    b, a = result.methods[base], result.result
    mb, ma = b.metrics, a.metrics
    if mb is None or ma is None:
        return None
    rotary = ma.peak_acc.names  # the machine's rotary axes, as the result names them
    facts: list[Fact] = []
    if ma.controller and mb.controller == ma.controller and math.isfinite(mb.cycle_time_s) \
            and math.isfinite(ma.cycle_time_s):
        facts.append(Fact(f"cycle time on the {ma.controller} controller", "s", mb.cycle_time_s, ma.cycle_time_s,
                          ".4g", percent=True))
    if math.isfinite(mb.cycle_time_optimal_s) and math.isfinite(ma.cycle_time_optimal_s):
        facts.append(Fact("cycle time time-optimal", "s", mb.cycle_time_optimal_s, ma.cycle_time_optimal_s, ".4g",
                          percent=True))
    planned = b.plan is not None and a.plan is not None
    law = "under the planned time law" if planned else "at the programmed feed"
    pb, pa = (mb.peak_acc_plan, ma.peak_acc_plan) if planned else (mb.peak_acc, ma.peak_acc)
    for axis in (rotary[1], rotary[0]):
        vb, va = float(pb[axis]), float(pa[axis])
        if math.isfinite(vb) and math.isfinite(va):
            facts.append(Fact(f"peak {axis}''", "deg/s\u00b2", vb, va, ".4g", percent=True))
    cb = mb.violations if planned else mb.violations_programmed
    ca = ma.violations if planned else ma.violations_programmed
    (nb, db), (na, da) = _named_counts(cb), _named_counts(ca)
    facts.append(Fact("limit violations", "", nb, na, detail_before=db, detail_after=da))
    if mb.scallop_max_um is not None and ma.scallop_max_um is not None:
        facts.append(Fact("largest scallop", "\u00b5m", float(mb.scallop_max_um), float(ma.scallop_max_um), ".3g"))
    if math.isfinite(mb.min_delta) and math.isfinite(ma.min_delta):
        facts.append(Fact("worst clearance", "\u00b5m", 1e3 * mb.min_delta, 1e3 * ma.min_delta, ".3g",
                          sense="clearance", gouge_below=-1e3 * float(ma.tolerance_mm)))
    label = "the CAM program's own tool axes" if base == "cam" else "the path without smoothing"
    return Headline(base, result.primary, label, law, tuple(facts))
