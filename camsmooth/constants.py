"""Defaults shared across the package, each written once here and imported where used.

Plain Python numbers only (no numpy), so the command line can import them without loading the
numerical stack.
"""

from __future__ import annotations

__all__ = ["DEFAULT_TOLERANCE_MM"]

#: The part's allowed deviation (mm) when the user gives none (``--tolerance``; ``smooth``,
#: ``analyze_program``): a finishing tolerance. It decides every clearance question: a pose whose
#: signed clearance delta (mm, negative = gouge) is below -tolerance interferes
#: (camsmooth.smoothing.result.interferes), a lift along the normal beyond it is reported.
DEFAULT_TOLERANCE_MM: float = 0.005
