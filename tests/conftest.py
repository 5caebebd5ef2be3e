"""Shared test fixtures and locations."""

from __future__ import annotations

import hashlib
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


def snapshot(folder: Path) -> dict[str, tuple]:
    """Every file (size, mtime, SHA-1) and folder under ``folder``: equal snapshots mean nothing was
    written, removed or touched."""
    out = {}
    for root, dirs, files in os.walk(folder):
        for name in dirs:
            out[os.path.relpath(os.path.join(root, name), folder) + "/"] = ()
        for name in files:
            p = os.path.join(root, name)
            st = os.stat(p)
            out[os.path.relpath(p, folder)] = (st.st_size, st.st_mtime_ns,
                                              hashlib.sha1(Path(p).read_bytes()).hexdigest())
    return out


def user_workspace(inputs: Path, folder: Path) -> Path:
    """Fill ``folder`` as a user's working folder for the CLI fault tests: the input files and the
    ``samples`` folder of ``inputs``, plus a file (user.txt) and a folder (keep/notes.txt) of the
    user's own that no failure may touch."""
    import shutil

    for f in inputs.iterdir():
        if f.is_file():
            shutil.copy(f, folder / f.name)
    shutil.copytree(inputs / "samples", folder / "samples")
    (folder / "user.txt").write_text("the user's own file\n")
    (folder / "keep").mkdir()
    (folder / "keep" / "notes.txt").write_text("keep me\n")
    return folder
