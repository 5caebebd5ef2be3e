"""The surfaces of benchmarks/data that nobody tuned camsmooth on (bench_controller.py runs them).

teapot.toml is the upper body patch of Newell's Utah teapot: its control grid must be the published
vertices (typed here from the data set as Crow printed it) under the transform its header states,
and the surface a Bezier patch through its corner vertices, facing up.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from camsmooth.geometry.surfaces import BSplineSurface, load_definition, load_surface

DATA = Path(__file__).resolve().parent.parent / "benchmarks" / "data"

#: the body patch's 16 vertices (indices 12-15, 48-59 of the data set), rows from the rim down
NEWELL_BODY = [
    [(1.5, 0.0, 2.4), (1.5, -0.84, 2.4), (0.84, -1.5, 2.4), (0.0, -1.5, 2.4)],
    [(1.75, 0.0, 1.875), (1.75, -0.98, 1.875), (0.98, -1.75, 1.875), (0.0, -1.75, 1.875)],
    [(2.0, 0.0, 1.35), (2.0, -1.12, 1.35), (1.12, -2.0, 1.35), (0.0, -2.0, 1.35)],
    [(2.0, 0.0, 0.9), (2.0, -1.12, 0.9), (1.12, -2.0, 0.9), (0.0, -2.0, 0.9)],
]


@pytest.mark.parametrize("name", ["ridge", "teapot"])
def test_the_bench_surfaces_load_as_meshes(name):
    surf = load_surface(DATA / f"{name}.toml")
    assert surf.parametric is not None and len(surf.mesh.faces) > 100


def test_teapot_is_newells_body_patch_under_the_stated_transform():
    p = np.array(NEWELL_BODY) * 25.0                      # scaled by 25 (mm)
    c, s = np.cos(np.pi / 4), np.sin(np.pi / 4)
    p = p @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]).T   # +45 deg about Z: middle faces +X
    p = np.stack([-p[..., 2], p[..., 1], p[..., 0]], axis=-1)          # laid down: +X up
    p[..., :2] -= p[..., :2].reshape(-1, 2).mean(axis=0)
    p[..., 2] += 5.0 - p[..., 2].min()                                   # lowest point at z = 5 mm
    surf = load_definition(DATA / "teapot.toml")
    assert isinstance(surf, BSplineSurface)
    np.testing.assert_allclose(surf.control, np.transpose(p, (1, 0, 2)), atol=1e-4)
    # a Bezier patch (clamped cubic, 4 x 4) passes through its corner vertices and faces up
    corners = surf.point(np.array([0.0, 1.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0, 1.0]))
    np.testing.assert_allclose(corners, surf.control[[0, -1, 0, -1], [0, 0, -1, -1]], atol=1e-9)
    assert surf.normal(np.array([0.5]), np.array([0.5]))[0, 2] > 0.9
    # around the body (u) the normal turns through about 90 deg, as the rows' tool axis must
    n0, n1 = surf.normal(np.array([0.0, 1.0]), np.array([0.5, 0.5]))
    assert 80.0 < np.degrees(np.arccos(n0 @ n1)) < 100.0
