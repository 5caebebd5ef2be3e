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


def test_make_demo_writes_what_the_readme_says():
    """README's `make demo` outputs are the files `camsmooth demo --out demo_out` (the Makefile's
    command, default sample blade) writes."""
    from camsmooth.cli.main import build_parser, demo_outputs

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    said = re.search(r"`make demo` writes (.*?)\(plots", readme, flags=re.S).group(1)
    promised = set(re.findall(r"`(demo_out/[^`]+)`", said))
    make = re.search(r"^demo:.*\n\t(.*)$", (ROOT / "Makefile").read_text(), flags=re.M).group(1)
    argv = make.split("camsmooth", 1)[1].split()
    args = build_parser().parse_args(argv)
    assert (args.out, args.sample) == ("demo_out", "blade")
    csv, nc, report = demo_outputs(args.out, args.sample)
    assert promised == {csv.as_posix(), nc.as_posix(), (report / "report.html").as_posix()}

