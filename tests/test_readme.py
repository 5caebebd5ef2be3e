"""The README's Python snippets run as written (from the repository root, as the README says)."""

import re

import pytest

from tests.conftest import ROOT

SNIPPETS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(encoding="utf-8"), flags=re.S)


def test_readme_has_python_snippets():
    assert SNIPPETS, "README.md has no ```python block"


@pytest.mark.parametrize("k", range(len(SNIPPETS)))
def test_readme_snippet_runs(k, monkeypatch, capsys):
    monkeypatch.chdir(ROOT)
    namespace: dict = {"__name__": "__readme__"}
    exec(compile(SNIPPETS[k], f"README.md python block {k + 1}", "exec"), namespace)
    out = capsys.readouterr().out
    assert out.strip(), "the snippet prints its results"
    if "drop" in namespace:  # the axial drop hits the mesh from above: finite contacts on it
        import numpy as np

        drop = namespace["drop"]
        assert drop.hit.any() and np.isfinite(drop.contact[drop.hit]).all()
