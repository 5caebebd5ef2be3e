"""The benchmark and example scripts the README lists still import against today's package.

A script that names a moved function fails here (at import) instead of when a user runs it; the
scripts themselves are too slow for the suite and run by hand (README, Examples and benchmarks).
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


def test_readme_lists_every_runnable_script() -> None:
    readme = (ROOT / "README.md").read_text()
    runnable = [p for p in SCRIPTS if '__name__ == "__main__"' in p.read_text()]
    missing = [f"{p.parent.name}/{p.name}" for p in runnable if f"{p.parent.name}/{p.name}" not in readme]
    assert not missing, f"scripts not in the README: {missing}"
