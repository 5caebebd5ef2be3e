"""Tests of camsmooth.geometry.paths: CSV round trip and errors, feed-direction estimate, normal check
against a mesh, zig-zag paths on parametric surfaces and raster paths on meshes."""

from __future__ import annotations

import numpy as np
import pytest

from camsmooth.errors import InputError
from camsmooth.geometry.paths import (
    CCPath,
    check_normals_against_mesh,
    estimate_feed_dirs,
    raster_path_on_mesh,
    zigzag_extents,
    zigzag_path,
)
from camsmooth.geometry.surfaces import BSplineSurface, Cylinder, Plane, Saddle, SpherePatch, tessellate
from camsmooth.io.ccpath import read_cc_csv, write_cc_csv


def _arc_path(n_rows=3, n=12, R=30.0, seed=0):
    """Points on a concave cylinder (axis along x, centre z = R), rows along the circle."""
    rng = np.random.default_rng(seed)
    pts, nrm, fd, rows = [], [], [], []
    for k in range(n_rows):
        th = np.linspace(-0.4, 0.4, n) + rng.normal(0, 1e-3, n)
        th = th if k % 2 == 0 else th[::-1]
        p = np.stack([np.full(n, 2.0 * k), R * np.sin(th), R - R * np.cos(th)], 1)
        nv = np.stack([np.zeros(n), -np.sin(th), np.cos(th)], 1)
        t = np.stack([np.zeros(n), np.cos(th), np.sin(th)], 1) * (1 if k % 2 == 0 else -1)
        pts.append(p)
        nrm.append(nv)
        fd.append(t)
        rows.append(np.full(n, k + 5))
    return CCPath(np.concatenate(pts), np.concatenate(nrm), np.concatenate(rows), np.concatenate(fd),
                  np.linspace(1000.0, 2000.0, n_rows * n))


def test_csv_round_trip_exact(tmp_path):
    path = _arc_path()
    path.points[0] = [1e-300, -123456.78901234567, 1 / 3]
    write_cc_csv(tmp_path / "p.csv", path)
    back = read_cc_csv(tmp_path / "p.csv")
    for name in ("points", "normals", "feed_dirs", "feed"):
        np.testing.assert_allclose(getattr(back, name), getattr(path, name), rtol=1e-12, atol=1e-300)
    assert np.array_equal(back.points, path.points)  # '%.17g' is exact
    assert np.array_equal(back.rows, path.rows) and back.source == str(tmp_path / "p.csv")
    # without the optional columns
    bare = CCPath(path.points, path.normals, path.rows)
    write_cc_csv(tmp_path / "bare.csv", bare)
    back = read_cc_csv(tmp_path / "bare.csv")
    assert back.feed is None and back.feed_dirs is None
    assert (tmp_path / "bare.csv").read_text().splitlines()[0] == "x,y,z,nx,ny,nz,row"


def test_csv_reader_flexibility(tmp_path):
    text = ("Z, X ,y,comment,NX,ny,nz\n"
            "5,0,0,a,0,0,1.0004\n5,1,0,b,0,0,1\n\n5,2,0,c,0,0,1\n")
    (tmp_path / "p.csv").write_text(text)
    p = read_cc_csv(tmp_path / "p.csv")
    np.testing.assert_array_equal(p.points, [[0, 0, 5], [1, 0, 5], [2, 0, 5]])
    np.testing.assert_allclose(np.linalg.norm(p.normals, axis=1), 1.0, rtol=1e-15)  # normalised silently
    assert np.array_equal(p.rows, [0, 0, 0]) and p.feed is None and p.feed_dirs is None
    np.testing.assert_allclose(p.feed_dirs_or_estimate(), [[1, 0, 0]] * 3, atol=1e-15)
    # a blank line keeps its line number: the error on the 4th line names data row 4
    (tmp_path / "q.csv").write_text(text.replace("\n5,2,0,c,0,0,1", "\n5,2,0,c,0,0,x"))
    with pytest.raises(InputError, match="row 4, column 'nz'"):
        read_cc_csv(tmp_path / "q.csv")


HEADER = "x,y,z,nx,ny,nz,row,fx,fy,fz,feed"


def _line(x, y=0.0, z=0.0, n=(0.0, 0.0, 1.0), row=0, f=(1.0, 0.0, 0.0), feed=1000.0):
    return ",".join(str(v) for v in (x, y, z, *n, row, *f, feed))


def _good_lines():
    return [_line(i) for i in range(4)] + [_line(10 - i, 2.0, row=1, f=(-1, 0, 0)) for i in range(4)]


def _csv(tmp_path, lines, header=HEADER):
    p = tmp_path / "path.csv"
    p.write_text("\n".join([header] + lines) + "\n")
    return p


def _replace(lines, k, **kw):
    out = list(lines)
    fields = out[k].split(",")
    cols = HEADER.split(",")
    for key, val in kw.items():
        fields[cols.index(key)] = str(val)
    out[k] = ",".join(fields)
    return out


@pytest.mark.parametrize("edit, row, column, text", [
    (lambda L: _replace(L, 2, y="abc"), 3, "y", "unparsable value 'abc'"),
    (lambda L: _replace(L, 5, z=""), 6, "z", "empty value"),
    (lambda L: _replace(L, 1, x="nan"), 2, "x", "non-finite"),
    (lambda L: _replace(L, 6, feed="inf"), 7, "feed", "non-finite"),
    (lambda L: _replace(L, 3, nx=0, ny=0, nz=0), 4, "nx,ny,nz", "zero normal"),
    (lambda L: _replace(L, 4, nz=1.01), 5, "nx,ny,nz", "not a unit vector"),
    (lambda L: _replace(L, 4, row=1.5), 5, "row", "not an integer"),
    (lambda L: _replace(L, 7, row=0), 8, "row", "reappears"),
    (lambda L: _replace(L, 2, x=1), 3, "x,y,z", "repeats the previous point"),
    (lambda L: L[:6], 5, "row", "has 2 point(s)"),
    (lambda L: _replace(L, 0, feed=0), 1, "feed", "feed must be > 0"),
    (lambda L: _replace(L, 5, feed=-5), 6, "feed", "feed must be > 0"),
    (lambda L: _replace(L, 1, fx=0.9, fz=0.43588989435406733), 2, "fx,fy,fz", "not tangent"),
    (lambda L: _replace(L, 1, fx=0, fy=0, fz=0), 2, "fx,fy,fz", "zero feed direction"),
    (lambda L: L[:3] + ["1,2,3"] + L[4:], 4, "nx", "missing value"),
])
def test_csv_errors_name_row_and_column(tmp_path, edit, row, column, text):
    p = _csv(tmp_path, edit(_good_lines()))
    with pytest.raises(InputError) as exc:
        read_cc_csv(p)
    msg = str(exc.value)
    assert str(p) in msg and f"row {row}" in msg and f"column '{column}'" in msg and text in msg, msg
    assert exc.value.row == row and exc.value.column == column


def test_csv_good_file_reads(tmp_path):
    p = read_cc_csv(_csv(tmp_path, _good_lines()))
    assert [s.stop - s.start for s in p.row_slices()] == [4, 4] and list(p.rows) == [0] * 4 + [1] * 4


@pytest.mark.parametrize("header, missing, hint", [
    ("x,y,z,nx,ny,nzz", "nz", "found 'nzz': misspelt?"),
    ("x,y,z,nx,ny", "nz", None),
    ("x,y,z,nx,ny,nz,fx,fy", "fz", None),
    ("xx,y,z,nx,ny,nz", "x", "found 'xx'"),
])
def test_csv_missing_column(tmp_path, header, missing, hint):
    n = len(header.split(","))
    p = _csv(tmp_path, [",".join(["0"] * n)], header=header)
    with pytest.raises(InputError) as exc:
        read_cc_csv(p)
    msg = str(exc.value)
    assert f"missing column '{missing}'" in msg and f"column '{missing}'" in msg and "row 0" in msg, msg
    if hint:
        assert hint in msg


def test_csv_empty_and_header_only(tmp_path):
    (tmp_path / "empty.csv").write_text("")
    with pytest.raises(InputError, match="empty file"):
        read_cc_csv(tmp_path / "empty.csv")
    (tmp_path / "header.csv").write_text(HEADER + "\n\n")
    with pytest.raises(InputError, match="no data rows"):
        read_cc_csv(tmp_path / "header.csv")
    with pytest.raises(InputError, match="cannot read"):
        read_cc_csv(tmp_path / "missing.csv")
    p = _csv(tmp_path, [_line(0) + ",7"] + _good_lines()[1:])
    with pytest.raises(InputError, match="row 1: 12 fields"):
        read_cc_csv(p)


def test_row_slices_and_non_contiguous_rows():
    p = CCPath(np.zeros((7, 3)), np.tile([0, 0, 1.0], (7, 1)), [3, 3, 1, 1, 1, 2, 2])
    assert p.row_slices() == [slice(0, 2), slice(2, 5), slice(5, 7)]
    bad = CCPath(np.zeros((5, 3)), np.tile([0, 0, 1.0], (5, 1)), [0, 0, 1, 1, 0], source="f.csv")
    with pytest.raises(InputError, match="f.csv, row 5, column 'row': row id 0 reappears"):
        bad.row_slices()
    with pytest.raises(ValueError, match="normals"):
        CCPath(np.zeros((5, 3)), np.zeros((4, 3)), np.zeros(5))


def test_estimate_feed_dirs_on_arc():
    path = _arc_path(n=40)
    f = estimate_feed_dirs(path.points, path.normals, path.rows)
    assert f.shape == path.points.shape
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), 1, atol=1e-14)
    assert np.abs(np.sum(f * path.normals, 1)).max() < 1e-14  # in the tangent plane
    # close to the exact tangent (central differences inside, one-sided at the row ends)
    err = np.degrees(np.arccos(np.clip(np.sum(f * path.feed_dirs, 1), -1, 1)))
    ends = np.r_[np.flatnonzero(np.diff(path.rows)) + 1, 0, np.flatnonzero(np.diff(path.rows)), len(f) - 1]
    inner = np.setdiff1d(np.arange(len(f)), ends)
    assert err[inner].max() < 0.2 and err.max() < 1.0
    # a straight row: exact
    pts = np.array([[0, 0, 0], [1, 1, 0], [3, 3, 0.0]])
    np.testing.assert_allclose(estimate_feed_dirs(pts, [[0, 0, 1.0]] * 3, [0, 0, 0]),
                               [[2**-0.5, 2**-0.5, 0]] * 3, atol=1e-15)
    with pytest.raises(InputError, match="single point"):
        estimate_feed_dirs(pts, [[0, 0, 1.0]] * 3, [0, 1, 1])


def test_check_normals_against_mesh():
    s = SpherePatch(40.0, (-15, 15), (-15, 15))
    mesh = tessellate(s, 40, 40)
    u = np.linspace(-12, 12, 9)
    path = CCPath(s.point(u, 0 * u), s.normal(u, 0 * u), np.zeros(9), source="p.csv")
    check_normals_against_mesh(path, mesh)  # fine
    path.normals[6] *= -1
    with pytest.raises(InputError, match="p.csv, row 7, column 'nx,ny,nz': normal points into the material"):
        check_normals_against_mesh(path, mesh)


# ---------------------------------------------------------------------------------------------
# zig-zag on parametric surfaces


def _bspline():
    x, y = np.linspace(0, 50, 6), np.linspace(0, 40, 5)
    X, Y = np.meshgrid(x, y, indexing="ij")
    ctrl = np.stack([X, Y, 3 * np.sin(X / 10) + 0.05 * Y], -1)
    return BSplineSurface(ctrl, u_range=(0, 50), v_range=(0, 40))


@pytest.mark.parametrize("surface, along", [
    (Saddle(1 / 90, 1 / 90, (-30, 30), (-30, 30), center=(0, 0, 10)), "u"),
    (SpherePatch(50, (-20, 20), (-25, 20), concave=True), "v"),
    (Cylinder(30, (-10, 15), (-25, 25)), "v"),
    (_bspline(), "u"),
])
def test_zigzag_path(surface, along):
    stepover, spacing = 2.5, 0.4
    p = zigzag_path(surface, stepover, spacing, along=along, feed=2000.0)
    slices = p.row_slices()
    assert [int(p.rows[s.start]) for s in slices] == list(range(len(slices)))
    assert np.all(p.feed == 2000.0)
    length, width = zigzag_extents(surface, along)
    assert len(slices) == int(np.ceil(width / stepover - 1e-9)) + 1
    # spacing within 5 % (and never above the request)
    for s in slices:
        step = np.linalg.norm(np.diff(p.points[s], axis=0), axis=1)
        assert step.max() <= spacing * 1.0001 and step.min() >= 0.95 * spacing
    # rows alternate: each row starts where the previous one ended, and travels the other way
    for a, b in zip(slices[:-1], slices[1:], strict=True):
        assert np.linalg.norm(p.points[b.start] - p.points[a.stop - 1]) < 1.5 * stepover
        assert np.linalg.norm(p.points[b.start] - p.points[a.start]) > 0.5 * length
        assert p.feed_dirs[a.stop - 1] @ p.feed_dirs[b.start] < -0.5
    # adjacent rows at most stepover apart, and not much closer on the widest part
    gaps = []
    for a, b in zip(slices[:-1], slices[1:], strict=True):
        d = np.linalg.norm(p.points[a][:, None, :] - p.points[b][None, :, :], axis=-1).min(axis=1)
        gaps.append(d.max())
    assert max(gaps) <= stepover * 1.01 and max(gaps) >= 0.9 * stepover
    # points on the surface, normals unit and up, feed dirs unit, tangent and along travel
    if isinstance(surface, SpherePatch):
        np.testing.assert_allclose(np.linalg.norm(p.points, axis=1), 50, rtol=1e-12)
    elif isinstance(surface, Saddle):
        np.testing.assert_allclose(p.points[:, 2], 10 + (p.points[:, 0] ** 2 - p.points[:, 1] ** 2) / 90,
                                   atol=1e-12)
    elif isinstance(surface, Cylinder):
        np.testing.assert_allclose(np.hypot(p.points[:, 1], p.points[:, 2]), 30, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(p.normals, axis=1), 1, atol=1e-12)
    assert np.all(p.normals[:, 2] > 0)
    np.testing.assert_allclose(np.linalg.norm(p.feed_dirs, axis=1), 1, atol=1e-12)
    assert np.abs(np.sum(p.feed_dirs * p.normals, 1)).max() < 1e-12
    for s in slices:
        chord = np.diff(p.points[s], axis=0)
        assert np.all(np.sum(chord * p.feed_dirs[s][:-1], 1) > 0)


def test_zigzag_margin_and_round_trip(tmp_path):
    s = Plane((0, 20), (0, 10))
    p = zigzag_path(s, 1.0, 0.5, margin=1.0)
    assert p.points[:, 0].min() == pytest.approx(1.0) and p.points[:, 0].max() == pytest.approx(19.0)
    assert p.points[:, 1].min() == pytest.approx(1.0) and p.points[:, 1].max() == pytest.approx(9.0)
    assert len(p.row_slices()) == 9 and len(p) == 9 * 37
    write_cc_csv(tmp_path / "z.csv", p)
    back = read_cc_csv(tmp_path / "z.csv")
    np.testing.assert_allclose(back.feed_dirs, p.feed_dirs, rtol=1e-12, atol=1e-15)
    with pytest.raises(ValueError, match="margin"):
        zigzag_path(s, 1.0, 0.5, margin=6.0)


# ---------------------------------------------------------------------------------------------
# raster on a mesh with a stand-in drop


def _plane_drop(z0=2.0, half=(20.0, 15.0), hole=None):
    """Stand-in for interference.axial_drop on the plane z = z0 within |x|, |y| <= half, with an
    optional circular hole (cx, cy, r): contact right below the point, normal +z, NaN on a miss."""
    def drop(mesh, cutter, points, axis):
        assert np.allclose(axis, [0, 0, 1]) and cutter == "ball"
        p = np.asarray(points, dtype=float)
        miss = (np.abs(p[:, 0]) > half[0]) | (np.abs(p[:, 1]) > half[1])
        if hole is not None:
            miss |= np.hypot(p[:, 0] - hole[0], p[:, 1] - hole[1]) < hole[2]
        contact = np.c_[p[:, :2], np.full(len(p), z0)]
        normal = np.tile([0.0, 0.0, 1.0], (len(p), 1))
        contact[miss] = np.nan
        normal[miss] = np.nan
        return contact.copy(), contact, normal
    return drop


def test_raster_path_on_plane():
    mesh = tessellate(Plane((-25, 25), (-15, 15), origin=(0, 0, 2.0)), 5, 5)
    p = raster_path_on_mesh(mesh, "ball", (0, 0, 1), stepover=3.0, spacing=0.5, drop=_plane_drop())
    slices = p.row_slices()
    assert len(slices) == 11  # 30 mm across / 3 mm + 1
    assert np.all(np.abs(p.points[:, 0]) <= 20) and np.allclose(p.points[:, 2], 2.0)
    for k, s in enumerate(slices):
        assert np.allclose(p.feed_dirs[s], [1, 0, 0] if k % 2 == 0 else [-1, 0, 0])
        assert np.allclose(np.diff(p.points[s, 0]), 0.5 if k % 2 == 0 else -0.5)
        assert np.ptp(p.points[s, 1]) == 0
    ys = [p.points[s.start, 1] for s in slices]
    np.testing.assert_allclose(np.diff(ys), 3.0)
    assert ys[0] == pytest.approx(-15.0)


def test_raster_path_splits_rows_at_misses():
    mesh = tessellate(Plane((-25, 25), (-15, 15), origin=(0, 0, 2.0)), 5, 5)
    p = raster_path_on_mesh(mesh, "ball", (0, 0, 1), 3.0, 0.5, drop=_plane_drop(hole=(0.0, 0.0, 4.0)),
                            feed=1500.0)
    slices = p.row_slices()
    assert len(slices) == 11 + 3  # the lines y = -3, 0, 3 cross the hole
    assert np.all(np.hypot(p.points[:, 0], p.points[:, 1]) >= 4.0) and np.all(p.feed == 1500.0)
    for s in slices:
        assert np.all(np.abs(np.diff(p.points[s, 0])) == pytest.approx(0.5))


def test_raster_path_tilted_axis_feed_dirs_tangent():
    s = SpherePatch(40.0, (-15, 15), (-15, 15))
    mesh = tessellate(s, 30, 30)
    axis = np.array([0.0, 0.0, 1.0])

    def sphere_drop(mesh, cutter, points, ax):  # ball of radius 3 onto the sphere, exact
        r, R = 3.0, 40.0
        p = np.asarray(points)
        rho2 = p[:, 0] ** 2 + p[:, 1] ** 2
        centre = np.c_[p[:, :2], np.sqrt(np.maximum((R + r) ** 2 - rho2, 0))]
        n = centre / (R + r)
        contact = R * n
        bad = (np.abs(contact[:, 0]) > 15) | (np.abs(contact[:, 1]) > 15)
        contact[bad] = np.nan
        return centre - r * ax, contact, n

    p = raster_path_on_mesh(mesh, "ball", axis, 2.0, 0.5, drop=sphere_drop)
    np.testing.assert_allclose(np.linalg.norm(p.points, axis=1), 40.0, rtol=1e-12)
    assert np.abs(np.sum(p.feed_dirs * p.normals, 1)).max() < 1e-12
    np.testing.assert_allclose(np.linalg.norm(p.feed_dirs, axis=1), 1, atol=1e-12)
    for k, sl in enumerate(p.row_slices()):
        assert np.all(np.sign(p.feed_dirs[sl, 0]) == (1 if k % 2 == 0 else -1))
