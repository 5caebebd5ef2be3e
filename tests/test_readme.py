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



def test_the_figures_the_readme_states_are_what_the_code_does():
    """The README's figures are the code's: the default machine's travel, speed, acceleration and
    pivot (`load_machine(None)`), the default tolerance (`smooth --help`) and the preset kinds."""
    import numpy as np

    from camsmooth.cli.main import build_parser
    from camsmooth.machine.kinematics import MACHINE_KINDS, load_machine

    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    said = re.search(r"an AB swivel head \(A, B in \[(-?\d+), (\d+)\] deg, (\d+) deg/s, (\d+) deg/s\^2, pivot\s+"
                     r"(\d+) mm\)", readme)
    assert said, "the README states the default machine"
    lo, hi, v, a, pivot = (float(x) for x in said.groups())
    m = load_machine(None)
    for ax in ("A", "B"):
        lim = m.limits[ax]
        assert np.allclose(np.degrees([lim.min, lim.max, lim.vmax, lim.amax]), [lo, hi, v, a])
    assert m.pivot == pivot and m.rotary == ("A", "B")
    tol = float(re.search(r"`--tolerance` \(default ([\d.]+) mm\)", readme).group(1))
    smooth = build_parser()._subparsers._group_actions[0].choices["smooth"]
    assert next(a.default for a in smooth._actions if a.dest == "tolerance") == tol
    kinds = re.search(r"a preset kind \((.*?)\)", readme.replace("\n", " ")).group(1)
    assert re.findall(r"`([A-Z-]+[a-z-]*)`", kinds) == list(MACHINE_KINDS)
