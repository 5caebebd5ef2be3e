"""Inputs at the edges (issue 21, part 2): a failure the user causes by input is exit 2 with one
message saying what to change, never the internal error's 'This is a bug'."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import trimesh

from camsmooth.cli.main import main
from camsmooth.geometry.surfaces import Sinusoid, tessellate_to_tolerance

RASTER = ["--raster", "--axis", "0,0,1", "--cutter-radius", "4", "--corner-radius", "1", "--stepover", "2",
          "--spacing", "0.5"]


@pytest.fixture()
def inch_part(tmp_path: Path) -> Path:
    """An 80 x 40 mm wave part written in inches (25.4x smaller than the cutter expects)."""
    s = Sinusoid(amplitude=2.5, kx=2 * np.pi / 44.4, ky=2 * np.pi / 160.0, u_range=(0.0, 80.0), v_range=(0.0, 40.0))
    mesh = tessellate_to_tolerance(s, chord_tol=1e-2)
    mesh.apply_scale(1 / 25.4)
    out = tmp_path / "part_in.stl"
    mesh.export(out)
    return out


def test_raster_on_a_part_in_inches_names_the_units(inch_part, tmp_path, capsys):
    """Before: exit 70 'internal error: ValueError: the cutter missed the mesh everywhere: no raster
    rows. This is a bug'."""
    rc = main(["path", "--surface", str(inch_part), *RASTER, "-o", str(tmp_path / "p.csv")])
    err = capsys.readouterr().err
    assert rc == 2, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and "bug" not in err
    assert str(inch_part) in err and "25.4x smaller" in err and "inches" in err
    assert "scale the mesh to mm" in err and "--cutter-radius" in err
    assert not (tmp_path / "p.csv").exists()


def test_raster_with_steps_too_coarse_says_what_to_change(tmp_path, capsys):
    """A part wider than the cutter but narrower than three --spacing steps: no row of three
    points. Before: exit 70 (the same ValueError)."""
    mesh = trimesh.creation.box(extents=(12.0, 12.0, 2.0))
    part = tmp_path / "block.stl"
    mesh.export(part)
    rc = main(["path", "--surface", str(part), "--raster", "--axis", "0,0,1", "--cutter-radius", "2",
               "--corner-radius", "1", "--stepover", "2", "--spacing", "8", "-o", str(tmp_path / "p.csv")])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "bug" not in err and "--spacing" in err and "12 x 12 mm" in err


def test_a_degenerate_definition_is_an_input_error(tmp_path, capsys):
    """A B-spline whose control points all coincide has no normal: exit 2 naming the file (before:
    exit 70, 'ValueError: surface has non-finite points or a singular normal')."""
    ctrl = ",\n".join("  [" + ", ".join("[1.0, 2.0, 3.0]" for _ in range(4)) + "]" for _ in range(4))
    definition = tmp_path / "flat.toml"
    definition.write_text('[surface]\nkind = "bspline"\nu_range = [0.0, 1.0]\nv_range = [0.0, 1.0]\n'
                          f"degree = [3, 3]\ncontrol = [\n{ctrl}\n]\n")
    rc = main(["path", "--surface", str(definition), "--stepover", "0.2", "--spacing", "0.1",
               "-o", str(tmp_path / "p.csv")])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert "bug" not in err and str(definition) in err
