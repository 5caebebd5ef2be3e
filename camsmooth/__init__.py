"""camsmooth: five-axis tool-axis smoothing for toroidal cutters.

The two entry points CAM plug-ins call most are re-exported here: ``smooth`` (the whole
pipeline, camsmooth.smoothing.pipeline) and ``axial_drop`` (drop-cutter along any axis,
camsmooth.geometry.clearance). Imports are lazy so ``import camsmooth`` stays light.
"""

from __future__ import annotations

from typing import Any

__version__ = "0.1.0"
__all__ = ["smooth", "axial_drop", "__version__"]


def __getattr__(name: str) -> Any:
    if name == "smooth":
        from camsmooth.smoothing.pipeline import smooth

        return smooth
    if name == "axial_drop":
        from camsmooth.geometry.clearance import axial_drop

        return axial_drop
    raise AttributeError(f"module 'camsmooth' has no attribute {name!r}")
