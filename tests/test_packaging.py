"""pyproject.toml: the install prints no setuptools deprecation warning (issue 19).

setuptools (>= 77) warns on the table form ``license = { text = ... }`` and refuses License
classifiers beside an SPDX expression; the string form needs setuptools >= 77 to build.
"""

from __future__ import annotations

import re
import tomllib

from tests.conftest import ROOT

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))


def test_license_is_an_spdx_string_and_no_license_classifier():
    project = PYPROJECT["project"]
    assert project["license"] == "MIT"
    assert not [c for c in project.get("classifiers", []) if c.startswith("License ::")]


def test_build_requires_a_setuptools_that_reads_spdx_licenses():
    reqs = PYPROJECT["build-system"]["requires"]
    setuptools = [r for r in reqs if re.match(r"setuptools\b", r)]
    assert len(setuptools) == 1
    m = re.fullmatch(r"setuptools\s*>=\s*(\d+)(\.\d+)*", setuptools[0])
    assert m and int(m.group(1)) >= 77, setuptools[0]
