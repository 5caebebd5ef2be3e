"""The subpackages are the architecture, imported in one direction: geometry, machine, the post
layer (G-code dialects), the controller's planner models, smoothing, diagnosis, report, cli. A
module may import its own package and those below it, never one above (imports inside functions
count: a lazy import is still a dependency). camsmooth.io (the file formats below the post layer
and the atomic writer) sits under the post layer: its table codec and atomic writer, used by every
layer, import no other subpackage; its readers may use geometry and machine. The leaf modules
(errors, constants, progress) stand outside the order."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PKG = Path(__file__).resolve().parents[1] / "camsmooth"
ORDER = ("geometry", "machine", "post", "controller", "smoothing", "diagnosis", "report", "cli")


def imported_packages(path: Path) -> set[str]:
    """The camsmooth subpackages a module imports, at module level or inside functions."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            mods = [node.module]
        elif isinstance(node, ast.Import):
            mods = [a.name for a in node.names]
        else:
            continue
        names |= {m.split(".")[1] for m in mods if m.startswith("camsmooth.") and m.count(".") >= 1}
    return names


@pytest.mark.parametrize("layer", ORDER)
def test_a_layer_imports_only_the_layers_below_it(layer):
    above = set(ORDER[ORDER.index(layer) + 1:])
    bad = {str(f.relative_to(PKG.parent)): sorted(imported_packages(f) & above)
           for f in sorted((PKG / layer).rglob("*.py"))}
    assert not {f: b for f, b in bad.items() if b}, f"{layer} imports a layer above it"


def test_io_sits_below_the_post_layer():
    """camsmooth.io imports neither the post layer nor anything above it (the program loader that
    reaches the G-code readers is camsmooth.post.load; the smoothing result's writer is
    camsmooth.smoothing.output), and its table codec and atomic writer, which geometry and machine
    use, import no other subpackage."""
    above = set(ORDER[ORDER.index("post"):])
    bad = {f.name: sorted(imported_packages(f) & above) for f in sorted((PKG / "io").glob("*.py"))}
    assert not {f: b for f, b in bad.items() if b}, "camsmooth.io imports the post layer or one above it"
    for base in ("table.py", "atomic.py"):
        assert imported_packages(PKG / "io" / base) <= {"io", "errors", "constants"}, base


def test_the_check_sees_an_upward_import(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("def f():\n    from camsmooth.smoothing.feed import plan_row\n    return plan_row\n")
    assert imported_packages(f) == {"smoothing"}
