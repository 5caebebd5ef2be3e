"""The benchmark and example scripts docs/benchmarks.md lists still import against today's package.

A script that names a moved function fails here (at import) instead of when a user runs it; the
scripts themselves are too slow for the suite and run by hand (docs/benchmarks.md, The scripts).
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
SCRIPTS = sorted([*ROOT.glob("benchmarks/*.py"), *ROOT.glob("examples/*.py")])


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_script_imports(path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.syspath_prepend(str(path.parent))
    spec = importlib.util.spec_from_file_location(f"_script_{path.stem}", path)
    module = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, spec.name, module)
    spec.loader.exec_module(module)  # top level only: every script keeps its work under a main guard
    assert module.__doc__, f"{path.name} has no docstring saying what it measures"


def test_docs_list_every_runnable_script() -> None:
    """docs/benchmarks.md (linked from the README) lists every script a user can run."""
    listed = (ROOT / "docs" / "benchmarks.md").read_text()
    runnable = [p for p in SCRIPTS if '__name__ == "__main__"' in p.read_text()]
    missing = [f"{p.parent.name}/{p.name}" for p in runnable if f"{p.parent.name}/{p.name}" not in listed]
    assert not missing, f"scripts not in docs/benchmarks.md: {missing}"


def test_planted_bugs_still_apply() -> None:
    """Every planted bug of benchmarks/planted_bugs.py still finds its code (exactly once): a
    refactor that moves the code must move the bug with it, or the self-check tests nothing."""
    import subprocess

    out = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "planted_bugs.py"), "--check"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stdout + out.stderr
