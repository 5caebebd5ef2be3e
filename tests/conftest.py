"""Shared test fixtures and locations."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent


def umich_dir() -> Path:
    """The Michigan recordings: $CAMSMOOTH_UMICH, else shared/ beside the repository (as CI and
    the development machines lay it out)."""
    env = os.environ.get("CAMSMOOTH_UMICH")
    return Path(env) if env else ROOT.parent / "shared" / "data" / "umich-cnc-mill"


UMICH = umich_dir()
needs_umich = pytest.mark.skipif(not (UMICH / "experiment_01.csv").exists(),
                                 reason=f"Michigan data not found at {UMICH} (set CAMSMOOTH_UMICH)")
