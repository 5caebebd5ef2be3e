"""The repository stands on its own (issue 19): no file points outside it for its methods, and
every "METHODS section N" a docstring, comment, output or document cites is a section of
docs/METHODS.md."""

from __future__ import annotations

import os
import re
from pathlib import Path

from tests.conftest import ROOT

METHODS = ROOT / "docs" / "METHODS.md"
SKIP_DIRS = {"__pycache__", "build", "demo_out", "out"}
OUTSIDE = (".." + "/shared", "shared/" + "METHODS")   # spelled in two parts so this file does not match
CITE = re.compile(r"METHODS(?:\.md)?[ \t\n#*]+sections?\s+(\d+(?:\.\d+)?)(?:\s*(-|,|and)\s*(\d+(?:\.\d+)?))?")


def _repository_files() -> list[Path]:
    """Every file of the working tree except hidden folders (.git, .venv, caches) and build output."""
    files = []
    for root, dirs, names in os.walk(ROOT):
        dirs[:] = [d for d in dirs if not d.startswith(".") and d not in SKIP_DIRS and not d.endswith(".egg-info")]
        files += [Path(root) / n for n in names if not n.startswith(".")]
    return files


def _sections() -> set[str]:
    heads = re.findall(r"^#{2,3} (\d+(?:\.\d+)?)\.? ", METHODS.read_text(encoding="utf-8"), flags=re.M)
    return set(heads)


def test_no_file_points_outside_the_repository():
    pointing = [p.relative_to(ROOT).as_posix() for p in _repository_files()
                if any(s.encode() in p.read_bytes() for s in OUTSIDE)]
    assert not pointing, f"files referring to {' or '.join(OUTSIDE)}: {pointing}"


def test_readme_names_the_methods_document():
    assert METHODS.is_file()
    assert "`docs/METHODS.md`" in (ROOT / "README.md").read_text(encoding="utf-8")


def test_methods_has_the_sections_the_code_cites():
    sections = _sections()
    assert {str(n) for n in range(1, 8)} <= sections, sorted(sections)
    missing = []
    cited = 0
    for path in _repository_files():
        if path.suffix not in (".py", ".md", ".toml", ".txt") or path == METHODS:
            continue
        for m in CITE.finditer(path.read_text(encoding="utf-8", errors="replace")):
            first, sep, last = m.groups()
            numbers = [first] if sep is None else (
                [str(n) for n in range(int(float(first)), int(float(last)) + 1)] if sep == "-" else [first, last])
            cited += 1
            missing += [f"{path.relative_to(ROOT)}: section {n}" for n in numbers if n not in sections]
    assert cited > 50   # the code cites the document throughout
    assert not missing, missing


def test_the_steps_the_code_cites_are_in_section_1():
    text = METHODS.read_text(encoding="utf-8")
    section1 = text[text.index("## 1."):text.index("## 2.")]
    for step in ("- A.", "- B.", "- C.", "- D.", "- E.", "(1)", "(2)", "(3)"):
        assert step in section1, step
