"""The cutter's inputs (camsmooth.geometry.cutter): the message of every bad input names the
argument and the constraint, numbers given as strings are converted, the boundaries the
docstrings state (shank_length >= r, n.T >= 0) are accepted, and any leading shape broadcasts."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.geometry.cutter import ToroidalCutter, cc_to_cl, cl_to_cc, signed_distance, support_point

CUT = ToroidalCutter(R=1.0, r=1.0)
Z = np.array([0.0, 0.0, 1.0])


@pytest.mark.parametrize("kwargs,words", [
    (dict(R="wide", r=1.0), r"^cutter R \(ring radius, mm\) must be a number, got 'wide'$"),
    (dict(R=1.0, r=None), r"^cutter r \(corner radius, mm\) must be a number, got None$"),
    (dict(R=1.0, r=1.0, shank_length="long"), r"^cutter shank_length \(mm\) must be a number"),
    (dict(R=1.0, r=1.0, holder_length=float("inf")), r"^cutter holder_length \(mm\) must be finite"),
    (dict(R=1.0, r=1.0, holder_radius="big"), r"^cutter holder_radius \(mm\) must be a number"),
    (dict(R=2.0, r=0.5, holder_radius=2.5), r"must exceed the cutter radius R \+ r = 2.5 mm$"),
])
def test_bad_cutter_messages_name_the_parameter(kwargs, words):
    with pytest.raises(InputError, match=words):
        ToroidalCutter(**kwargs)


def test_numbers_from_text_are_stored_as_floats_and_shank_length_may_equal_r():
    c = ToroidalCutter(R="2.5", r="1", shank_length="1", holder_radius="5", holder_length="7")
    assert (c.R, c.r, c.shank_length, c.holder_radius, c.holder_length) == (2.5, 1.0, 1.0, 5.0, 7.0)
    assert all(type(v) is float for v in (c.R, c.r, c.shank_length, c.holder_radius, c.holder_length))
    assert c.diameter == 7.0 and c.has_holder


@pytest.mark.parametrize("call,words", [
    (lambda: cl_to_cc(CUT, np.zeros(3), np.zeros(3), Z), "^surface normal n contains a zero-length vector$"),
    (lambda: cc_to_cl(CUT, np.zeros(3), [0, 0, np.inf], Z), "^surface normal n must be finite$"),
    (lambda: cl_to_cc(CUT, np.zeros(3), Z, np.zeros(3)), "^tool axis T contains a zero-length vector$"),
    (lambda: cc_to_cl(CUT, np.zeros(3), Z, [0, np.nan, 1]), "^tool axis T must be finite$"),
    (lambda: signed_distance(CUT, np.zeros(3), np.zeros(3), np.ones(3)), "^tool axis contains a zero-length"),
    (lambda: support_point(CUT, np.zeros(3), [0, 0, 1.0, 0], [1.0, 0, 0]), r"^tool axis must have shape \(\.\.\., 3\)"),
    (lambda: support_point(CUT, np.zeros(3), Z, np.zeros(3)), "^direction contains a zero-length vector$"),
])
def test_bad_vector_messages_name_the_argument(call, words):
    with pytest.raises(InputError, match=words):
        call()


def test_axis_into_the_material_names_the_first_such_point_and_the_reason():
    # point 2 is tangent (n.T = 0, allowed), points 3 and 5 point into the material
    n = np.tile(Z, (5, 1))
    T = np.array([[0, 0, 1.0], [1.0, 0, 0], [0, 0.6, -0.8], [0, 0, 1.0], [0, -0.6, -0.8]])
    for f in (cc_to_cl, cl_to_cc):
        with pytest.raises(InputError, match=r"^tool axis points into the material at point 3 \(n\.T = -0\.8 < 0\): "
                                             "the contact would lie on the rounded top, not on the cutting end$"):
            f(CUT, np.zeros((5, 3)), n, T)


def test_axis_tangent_to_the_surface_contacts_the_equator_of_the_corner():
    # n.T = 0 is allowed (only n.T < 0 is refused): the contact is on the corner's equator,
    # CL = CC + r n + R u - r T with u = n (closed form)
    cutter = ToroidalCutter(R=2.0, r=0.5)
    n, T, cc = np.array([1.0, 0.0, 0.0]), Z, np.array([3.0, -1.0, 2.0])
    cl = cc_to_cl(cutter, cc, n, T)
    np.testing.assert_allclose(cl, cc + 0.5 * n + 2.0 * n - 0.5 * T, atol=1e-15)
    np.testing.assert_allclose(cl_to_cc(cutter, cl, n, T), cc, atol=1e-15)


def test_single_points_and_stacked_shapes_give_the_per_point_answer():
    rng = np.random.default_rng(3)
    cutter = ToroidalCutter(R=2.0, r=0.75)
    n = rng.normal(size=(2, 4, 3)) + [0, 0, 3.0]
    T = rng.normal(size=(2, 4, 3)) * 0.3 + [0, 0, 1.0]
    cc = rng.normal(size=(2, 4, 3))
    cl = cc_to_cl(cutter, cc, n, T)
    pts = rng.normal(size=(2, 4, 3))
    sd = signed_distance(cutter, cl, T, pts)
    assert cl.shape == (2, 4, 3) and sd.shape == (2, 4)
    for i in range(2):
        for j in range(4):
            one = cc_to_cl(cutter, cc[i, j], n[i, j], T[i, j])
            assert one.shape == (3,)
            np.testing.assert_allclose(cl[i, j], one, atol=1e-14)
            np.testing.assert_allclose(cl_to_cc(cutter, one, n[i, j], T[i, j]), cc[i, j], atol=1e-14)
            assert sd[i, j] == pytest.approx(float(signed_distance(cutter, cl[i, j], T[i, j], pts[i, j])), abs=1e-14)
