"""Compiled (numba) kernels of camsmooth.geometry.clearance: a bounding-volume hierarchy over the
mesh triangles and the exact clearance of the tool's convex bodies, pose by pose.

Single-threaded scalar code (the pipeline parallelises with processes).  ``cache=True``: the
first call in a fresh environment compiles (seconds), later imports load the machine code from
``__pycache__``.  Scratch memory per call is a few fixed-size tables, whatever the number of
poses or the size of the mesh.

Body model (camsmooth.geometry.cutter): a solid capped cylinder C (axis from ``base`` to
``base + height * axis``, radius ``radius``; a segment when ``radius = 0``, a disc when
``height = 0``) offset by ``off`` (the Minkowski sum with a ball of radius ``off``): a ball end is
the segment offset by r, a flat end the cylinder itself (``off = 0``: the torus with r = 0 is
the bottom disc and the side wall, with a sharp rim), the holder too.  Its signed
distance ``sd_C(x) - off`` is convex and 1-Lipschitz in x; ``sd_C`` is the formula of
``camsmooth.geometry.cutter._cylinder_sd`` with the same branches and subgradient choices
(scalar code here for the hot loops; the vectorised numpy version there is what the tests'
brute force uses).

Bounding volumes.  Every node of the hierarchy holds its triangles in an oriented box: centre
c, orthonormal axes a_k (the first along the node's dominant normal direction: the normal of a
sheet), half-extents e_k.  As sd is convex, for any subgradient g at c,
sd(x) >= sd(c) + g.(x - c) >= sd(c) - sum_k |g.a_k| e_k on the box: a lower bound that is
second-order tight where the surface is tangent to the tool (a ball's sd(c) - radius is only
first-order).  Triangles use the exact minimum of the same linear function over their three
vertices (tangent plane at the centroid), then the tangent planes at the vertices.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

PRUNE_TOL = 1e-10     # mm: an element whose lower bound is within this of the best value is skipped
GAP_TOL = 1e-12       # mm: an edge minimum is accepted once certified within this of the true minimum
PARALLEL_EPS = 1e-12  # as camsmooth.geometry.cutter._PARALLEL_EPS (support-point tie rule)
BARY_TOL = 1e-12      # barycentric tolerance of the facet test
TOUCH_TOL = 1e-12     # mm: a body this little across a facet's plane touches it (facet test, not deep)
STACK = 256           # BVH traversal stack; the tree depth is <= log2(F) + 2

# What attains a pose's minimum (to report the contact normal and polish the witness).
K_POINT = 0   # vertex or deep minimum: normal = -gradient of the body's sd at the witness
K_FACET = 1   # facet: normal = the facet normal, on the side of the tool
K_EDGE = 2    # edge: the witness is refined to full precision along the edge first

# Columns of the per-triangle float table (leaf order): unit normal, centroid, validity (1 or 0),
# the three vertices (stored in place: the hot loop reads them contiguously).
T_N, T_C, T_VALID, T_P = 0, 3, 6, 7
# Columns of the per-node table: the oriented box (centre, three orthonormal axes, the
# half-extents along them), then first child (-1: leaf), first triangle, triangle count.
B_C, B_A, B_E = 0, 3, 12
N_LEFT, N_START, N_COUNT = 15, 16, 17
HASH = 1024           # slots of the per-pose vertex and edge caches (a power of two)
PROBES = 32           # linear-probing limit of those caches


# ---------------------------------------------------------------------------------------------
# bounding-volume hierarchy

@njit(cache=True)
def _box(vertices, faces, perm, s, c, out):
    """Oriented box of the triangles perm[s:s + c] into out[0:15] (module docstring).  First
    axis: the dominant direction of their normals (power iteration on the area-weighted scatter
    of the normals; the normal of a sheet, whatever the faces' orientation); second: the
    principal direction of the vertices across it.  Any orthonormal axes give a valid box;
    these make it thin on a sheet."""
    S = np.zeros((3, 3))
    mx = my = mz = 0.0
    for i in range(s, s + c):
        f = perm[i]
        p0, p1, p2 = faces[f, 0], faces[f, 1], faces[f, 2]
        ox, oy, oz = vertices[p0, 0], vertices[p0, 1], vertices[p0, 2]
        ux, uy, uz = vertices[p1, 0] - ox, vertices[p1, 1] - oy, vertices[p1, 2] - oz
        vx, vy, vz = vertices[p2, 0] - ox, vertices[p2, 1] - oy, vertices[p2, 2] - oz
        n0, n1, n2 = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx
        ln = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if ln > 0.0:
            S[0, 0] += n0 * n0 / ln
            S[0, 1] += n0 * n1 / ln
            S[0, 2] += n0 * n2 / ln
            S[1, 1] += n1 * n1 / ln
            S[1, 2] += n1 * n2 / ln
            S[2, 2] += n2 * n2 / ln
        for j in range(3):
            v = faces[f, j]
            mx += vertices[v, 0]
            my += vertices[v, 1]
            mz += vertices[v, 2]
    mx, my, mz = mx / (3.0 * c), my / (3.0 * c), mz / (3.0 * c)
    S[1, 0], S[2, 0], S[2, 1] = S[0, 1], S[0, 2], S[1, 2]
    k = 0
    if S[1, 1] > S[k, k]:
        k = 1
    if S[2, 2] > S[k, k]:
        k = 2
    m = np.empty(3)
    m[0], m[1], m[2] = S[0, k], S[1, k], S[2, k]
    for _ in range(12):
        x0 = S[0, 0] * m[0] + S[0, 1] * m[1] + S[0, 2] * m[2]
        x1 = S[1, 0] * m[0] + S[1, 1] * m[1] + S[1, 2] * m[2]
        x2 = S[2, 0] * m[0] + S[2, 1] * m[1] + S[2, 2] * m[2]
        ln = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if not ln > 0.0:
            break
        m[0], m[1], m[2] = x0 / ln, x1 / ln, x2 / ln
    ln = math.sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2])
    if ln > 0.0:
        m /= ln
    else:
        m[0], m[1], m[2] = 0.0, 0.0, 1.0
    # e1, e2 span the plane across m; the vertices' principal direction in it (closed form)
    if abs(m[0]) < 0.9:
        e1 = np.array([0.0, -m[2], m[1]])
    else:
        e1 = np.array([-m[2], 0.0, m[0]])
    e1 /= math.sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2])
    e2 = np.array([m[1] * e1[2] - m[2] * e1[1], m[2] * e1[0] - m[0] * e1[2], m[0] * e1[1] - m[1] * e1[0]])
    caa = cab = cbb = 0.0
    for i in range(s, s + c):
        for j in range(3):
            v = faces[perm[i], j]
            dx, dy, dz = vertices[v, 0] - mx, vertices[v, 1] - my, vertices[v, 2] - mz
            pa = dx * e1[0] + dy * e1[1] + dz * e1[2]
            pb = dx * e2[0] + dy * e2[1] + dz * e2[2]
            caa += pa * pa
            cab += pa * pb
            cbb += pb * pb
    th = 0.5 * math.atan2(2.0 * cab, caa - cbb)
    a = np.empty((3, 3))
    for j in range(3):
        a[0, j] = m[j]
        a[1, j] = math.cos(th) * e1[j] + math.sin(th) * e2[j]
    # re-orthonormalise (Gram-Schmidt) and complete with the cross product
    d = a[1, 0] * a[0, 0] + a[1, 1] * a[0, 1] + a[1, 2] * a[0, 2]
    for j in range(3):
        a[1, j] -= d * a[0, j]
    ln = math.sqrt(a[1, 0] ** 2 + a[1, 1] ** 2 + a[1, 2] ** 2)
    for j in range(3):
        a[1, j] /= ln
    a[2, 0] = a[0, 1] * a[1, 2] - a[0, 2] * a[1, 1]
    a[2, 1] = a[0, 2] * a[1, 0] - a[0, 0] * a[1, 2]
    a[2, 2] = a[0, 0] * a[1, 1] - a[0, 1] * a[1, 0]
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    for i in range(s, s + c):
        for j in range(3):
            v = faces[perm[i], j]
            dx, dy, dz = vertices[v, 0] - mx, vertices[v, 1] - my, vertices[v, 2] - mz
            for k in range(3):
                x = dx * a[k, 0] + dy * a[k, 1] + dz * a[k, 2]
                lo[k] = min(lo[k], x)
                hi[k] = max(hi[k], x)
    cx, cy, cz = mx, my, mz
    for k in range(3):
        mid = 0.5 * (lo[k] + hi[k])
        cx += mid * a[k, 0]
        cy += mid * a[k, 1]
        cz += mid * a[k, 2]
    ext = np.zeros(3)
    for i in range(s, s + c):
        for j in range(3):
            v = faces[perm[i], j]
            dx, dy, dz = vertices[v, 0] - cx, vertices[v, 1] - cy, vertices[v, 2] - cz
            for k in range(3):
                ext[k] = max(ext[k], abs(dx * a[k, 0] + dy * a[k, 1] + dz * a[k, 2]))
    # grown by a few ulps of the coordinates so that rounding cannot make the box too small
    scale = max(abs(cx), abs(cy), abs(cz), ext[0], ext[1], ext[2])
    out[B_C], out[B_C + 1], out[B_C + 2] = cx, cy, cz
    for k in range(3):
        for j in range(3):
            out[B_A + 3 * k + j] = a[k, j]
        out[B_E + k] = ext[k] * (1.0 + 1e-12) + 1e-14 * scale


@njit(cache=True)
def _select(perm, key, lo, hi, k):
    """Reorder perm[lo:hi + 1] so that key[perm[k]] is its k-th smallest, smaller or equal keys
    before k and larger or equal after (quickselect, median-of-three pivots)."""
    while hi > lo:
        mid = (lo + hi) // 2
        a, b, c = key[perm[lo]], key[perm[mid]], key[perm[hi]]
        pivot = max(min(a, b), min(max(a, b), c))
        i, j = lo, hi
        while i <= j:
            while key[perm[i]] < pivot:
                i += 1
            while key[perm[j]] > pivot:
                j -= 1
            if i <= j:
                perm[i], perm[j] = perm[j], perm[i]
                i += 1
                j -= 1
        if k <= j:
            hi = j
        elif k >= i:
            lo = i
        else:
            return


@njit(cache=True)
def build_bvh(vertices, faces, leaf_size):
    """Top-down median split (quickselect) of the triangles on the longest axis of their
    centroids' box.

    Returns ``perm`` (F,) triangle order (each node owns the contiguous range
    ``perm[start:start + count]``), ``left`` (M,) first child (the second is ``left + 1``; -1 for
    leaves), ``start``, ``count`` (M,) and ``box`` (M, 15), the nodes' oriented boxes.
    """
    F = faces.shape[0]
    cent = np.empty((F, 3))
    for f in range(F):
        for k in range(3):
            cent[f, k] = (vertices[faces[f, 0], k] + vertices[faces[f, 1], k] + vertices[faces[f, 2], k]) / 3.0
    perm = np.arange(F)
    cap = 2 * F + 1
    left = np.full(cap, -1, np.int64)
    start = np.zeros(cap, np.int64)
    count = np.zeros(cap, np.int64)
    todo = np.empty(cap, np.int64)
    start[0], count[0] = 0, F
    todo[0] = 0
    n_todo, n_nodes = 1, 1
    while n_todo > 0:
        n_todo -= 1
        node = todo[n_todo]
        s, c = start[node], count[node]
        if c <= leaf_size:
            continue
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for i in range(s, s + c):
            for k in range(3):
                x = cent[perm[i], k]
                lo[k] = min(lo[k], x)
                hi[k] = max(hi[k], x)
        ax = int(np.argmax(hi - lo))
        half = c // 2
        _select(perm, cent[:, ax], s, s + c - 1, s + half)
        left[node] = n_nodes
        start[n_nodes], count[n_nodes] = s, half
        start[n_nodes + 1], count[n_nodes + 1] = s + half, c - half
        todo[n_todo], todo[n_todo + 1] = n_nodes, n_nodes + 1
        n_todo += 2
        n_nodes += 2
    box = np.empty((n_nodes, 15))
    for node in range(n_nodes):
        _box(vertices, faces, perm, start[node], count[node], box[node])
    return perm, left[:n_nodes].copy(), start[:n_nodes].copy(), count[:n_nodes].copy(), box


# ---------------------------------------------------------------------------------------------
# the capped cylinder: signed distance, subgradient, support point

@njit(cache=True, inline="always")
def _sd(px, py, pz, bx, by, bz, ax, ay, az, height, radius):
    qx, qy, qz = px - bx, py - by, pz - bz
    a = qx * ax + qy * ay + qz * az
    wx, wy, wz = qx - a * ax, qy - a * ay, qz - a * az
    rho = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * height
    dz = abs(a - half) - half
    dr = rho - radius
    if dr > 0.0 or dz > 0.0:
        drp, dzp = max(dr, 0.0), max(dz, 0.0)
        return math.sqrt(drp * drp + dzp * dzp)
    return max(dr, dz)


@njit(cache=True, inline="always")
def _sd_grad(px, py, pz, bx, by, bz, ax, ay, az, height, radius):
    """Signed distance of the capped cylinder and a subgradient (the gradient where it exists);
    the same branches as camsmooth.geometry.cutter._cylinder_sd."""
    qx, qy, qz = px - bx, py - by, pz - bz
    a = qx * ax + qy * ay + qz * az
    wx, wy, wz = qx - a * ax, qy - a * ay, qz - a * az
    rho = math.sqrt(wx * wx + wy * wy + wz * wz)
    half = 0.5 * height
    dz = abs(a - half) - half
    dr = rho - radius
    inv_rho = 1.0 / rho if rho > 0.0 else 0.0
    ex, ey, ez = wx * inv_rho, wy * inv_rho, wz * inv_rho
    sg = 1.0 if a >= half else -1.0
    sx, sy, sz = sg * ax, sg * ay, sg * az
    if dr > 0.0 or dz > 0.0:
        drp, dzp = max(dr, 0.0), max(dz, 0.0)
        out = math.sqrt(drp * drp + dzp * dzp)
        i = 1.0 / out
        return out, (drp * ex + dzp * sx) * i, (drp * ey + dzp * sy) * i, (drp * ez + dzp * sz) * i
    if dr >= dz:
        return dr, ex, ey, ez
    return dz, sx, sy, sz


@njit(cache=True, inline="always")
def _support(bx, by, bz, ax, ay, az, height, radius, dx, dy, dz):
    """Point of the capped cylinder extreme in direction d (ties as _cylinder_support: the lower
    end, the axis point for d parallel to the axis)."""
    dt = dx * ax + dy * ay + dz * az
    wx, wy, wz = dx - dt * ax, dy - dt * ay, dz - dt * az
    wn = math.sqrt(wx * wx + wy * wy + wz * wz)
    if wn > PARALLEL_EPS * max(1.0, abs(dt)):
        s = radius / wn
        rx, ry, rz = wx * s, wy * s, wz * s
    else:
        rx, ry, rz = 0.0, 0.0, 0.0
    up = height if dt > 0.0 else 0.0
    return bx + up * ax + rx, by + up * ay + ry, bz + up * az + rz


@njit(cache=True, inline="always")
def _box_bound(NT, k, bx, by, bz, ax, ay, az, h, rad):
    """Lower bound of sd_C over node k's oriented box (module docstring)."""
    s, g0, g1, g2 = _sd_grad(NT[k, B_C], NT[k, B_C + 1], NT[k, B_C + 2], bx, by, bz, ax, ay, az, h, rad)
    for j in range(3):
        s -= abs(g0 * NT[k, B_A + 3 * j] + g1 * NT[k, B_A + 3 * j + 1] + g2 * NT[k, B_A + 3 * j + 2]) * NT[k, B_E + j]
    return s


# ---------------------------------------------------------------------------------------------
# minimisation along an edge and over a plane

@njit(cache=True)
def _edge_min(px, py, pz, dx, dy, dz, fa, ga, fb, gb, bx, by, bz, ax, ay, az, h, rad, off,
              U, polish):
    """Minimum of the convex f(t) = sd_C(p + t d) - off on [0, 1], given f and a subgradient
    (along d) at both ends.

    Steps: Illinois (regula falsi) on the slope, with a bisection whenever the bracket fails to
    halve over two steps.  Certificate: f is at least the upper envelope of the tangent lines at
    the bracket ends, so their crossing value ``low`` bounds the minimum from below.  Search
    mode (``polish`` False): stops once ``low`` >= U - PRUNE_TOL (the edge cannot improve the
    pose's best value U) or best - low <= GAP_TOL, and returns (t, f(t)) of the best point
    evaluated (t = -1 if no interior point beat both ends).  Polish mode: runs until the slope
    changes sign within rounding and returns that point: near a smooth minimum f is flat to
    rounding over ~1e-8 mm, so the best value does not place the witness, the slope does.
    """
    bt, bv = -1.0, min(fa, fb)
    if ga >= 0.0 or gb <= 0.0:
        return bt, bv  # the minimum is at an end
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    lo, hi = 0.0, 1.0
    flo, glo, fhi, ghi = fa, ga, fb, gb
    wlo, whi = glo, ghi          # Illinois working slopes
    side = 0
    width_ref = 1.0
    for it in range(300):
        if not polish:
            if (hi - lo) * length <= 1e-13:
                break
            tx = (fhi - flo + glo * lo - ghi * hi) / (glo - ghi)
            low = flo + glo * (tx - lo)
            if low >= U - PRUNE_TOL or bv - low <= GAP_TOL:
                break
        if it % 2 == 0:
            if it > 0 and (hi - lo) > 0.5 * width_ref:
                t = 0.5 * (lo + hi)
            else:
                t = (lo * whi - hi * wlo) / (whi - wlo)
            width_ref = hi - lo
        else:
            t = (lo * whi - hi * wlo) / (whi - wlo)
        if not (lo < t < hi):
            t = 0.5 * (lo + hi)
            if not (lo < t < hi):
                break  # lo and hi are neighbouring floats
        s, g0, g1, g2 = _sd_grad(px + t * dx, py + t * dy, pz + t * dz, bx, by, bz, ax, ay, az, h, rad)
        f = s - off
        g = g0 * dx + g1 * dy + g2 * dz
        if f < bv:
            bt, bv = t, f
        if g > 0.0:
            hi, fhi, ghi, whi = t, f, g, g
            if side == 1:
                wlo *= 0.5
            side = 1
        elif g < 0.0:
            lo, flo, glo, wlo = t, f, g, g
            if side == -1:
                whi *= 0.5
            side = -1
        else:
            return (t, f) if polish else (bt, bv)  # a zero subgradient: t is a minimum
    if polish:
        return (lo, flo) if flo <= fhi else (hi, fhi)
    return bt, bv


@njit(cache=True, inline="always")
def _inside(TF, f, x, y, z):
    """Barycentric test: is the point (in the plane of triangle f) inside it (BARY_TOL)?"""
    p0x, p0y, p0z = TF[f, T_P], TF[f, T_P + 1], TF[f, T_P + 2]
    e0x, e0y, e0z = TF[f, T_P + 3] - p0x, TF[f, T_P + 4] - p0y, TF[f, T_P + 5] - p0z
    e1x, e1y, e1z = TF[f, T_P + 6] - p0x, TF[f, T_P + 7] - p0y, TF[f, T_P + 8] - p0z
    e2x, e2y, e2z = x - p0x, y - p0y, z - p0z
    d00 = e0x * e0x + e0y * e0y + e0z * e0z
    d01 = e0x * e1x + e0y * e1y + e0z * e1z
    d11 = e1x * e1x + e1y * e1y + e1z * e1z
    d20 = e2x * e0x + e2y * e0y + e2z * e0z
    d21 = e2x * e1x + e2y * e1y + e2z * e1z
    den = d00 * d11 - d01 * d01
    if den <= 0.0:
        den = 1.0
    bv = (d11 * d20 - d01 * d21) / den
    bw = (d00 * d21 - d01 * d20) / den
    return bv >= -BARY_TOL and bw >= -BARY_TOL and 1.0 - bv - bw >= -BARY_TOL


@njit(cache=True, inline="always")
def _plane_min(nx, ny, nz, px, py, pz, bx, by, bz, ax, ay, az, h, rad):
    """Deepest point of the plane n.(x - p) = 0 (n unit) in the capped cylinder C, which the
    plane cuts: (sd_C there, x, y, z), a minimiser of sd_C over the plane.

    Inside C, sd_C = max(rho - rad, -a, a - h) (rho: distance to the axis line, a: axial
    coordinate), and everywhere sd_C >= that maximum, so its minimiser over the plane (<= 0
    when the plane cuts C) minimises sd_C too.  With e1 the unit projection of the axis on the
    plane, c = axis.e1, k = axis.n, delta = n.(base - p) and q = base - delta n, a point
    q + s e1 + t e2 of the plane (e2 across the axis) has rho^2 = (k s + c delta)^2 + t^2 and
    a = c s - k delta, so the minimum is on t = 0 and is the minimum of the maximum of four lines
    in s, at one of their crossings (closed form).
    """
    k = ax * nx + ay * ny + az * nz
    e0, e1, e2 = ax - k * nx, ay - k * ny, az - k * nz
    c = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
    if c > 1e-12:
        e0, e1, e2 = e0 / c, e1 / c, e2 / c
        c = ax * e0 + ay * e1 + az * e2
    else:  # the plane is across the axis: any direction in it (rho is symmetric)
        if abs(nx) < 0.9:
            e0, e1, e2 = 0.0, -nz, ny
        else:
            e0, e1, e2 = -nz, 0.0, nx
        ln = math.sqrt(e0 * e0 + e1 * e1 + e2 * e2)
        e0, e1, e2 = e0 / ln, e1 / ln, e2 / ln
        c = 0.0
    delta = nx * (bx - px) + ny * (by - py) + nz * (bz - pz)
    # the four lines (slope, intercept): +-(k s + c delta) - rad, -(c s - k delta), c s - k delta - h
    sl0, sl1, sl2, sl3 = k, -k, -c, c
    ic0, ic1, ic2, ic3 = c * delta - rad, -c * delta - rad, k * delta, -k * delta - h
    best_s, best_f = 0.0, np.inf
    for i in range(4):
        si = sl0 if i == 0 else (sl1 if i == 1 else (sl2 if i == 2 else sl3))
        ci = ic0 if i == 0 else (ic1 if i == 1 else (ic2 if i == 2 else ic3))
        for j in range(i + 1, 4):
            sj = sl0 if j == 0 else (sl1 if j == 1 else (sl2 if j == 2 else sl3))
            cj = ic0 if j == 0 else (ic1 if j == 1 else (ic2 if j == 2 else ic3))
            if si == sj:
                continue
            s = (cj - ci) / (si - sj)
            f = max(sl0 * s + ic0, sl1 * s + ic1, sl2 * s + ic2, sl3 * s + ic3)
            if f < best_f:
                best_s, best_f = s, f
    x = bx - delta * nx + best_s * e0
    y = by - delta * ny + best_s * e1
    z = bz - delta * nz + best_s * e2
    return _sd(x, y, z, bx, by, bz, ax, ay, az, h, rad), x, y, z


# ---------------------------------------------------------------------------------------------
# the clearance kernel

@njit(cache=True)
def clearance_kernel(tips, axes, bodies, margin, V, TI, TF, NT):
    """Exact clearance of N poses against the mesh (camsmooth.geometry.clearance.clearance).

    tips, axes : (N, 3) tool tips and unit axes.  bodies : (B, 4) per convex body: base offset
    along the axis from the tip, height, radius, offset.  V (nv, 3) vertices; TI (F, 3) vertex
    ids and TF (F, 16) normal, centroid, validity and vertices of the triangles in leaf order;
    NT (M, 18) the hierarchy's nodes: oriented box (15), first child (-1 for a leaf), first
    triangle, triangle count.

    Returns delta (N,) (margin where nothing is below it), witness (N, 3) and normal (N, 3)
    (NaN where nothing is below the margin).
    """
    N = tips.shape[0]
    nv = V.shape[0]
    delta = np.full(N, margin)
    witness = np.full((N, 3), np.nan)
    normal = np.full((N, 3), np.nan)
    # Per (pose, body) caches in small hash tables (stay in L1/L2 cache; entries of another
    # (pose, body) count as empty): vertex id, key, sd - off, subgradient; examined edges.
    # When a table is crowded the work is simply not cached (rows HASH.. are spare slots).
    vt = np.empty((HASH + 3, 6))
    vt[:, 1] = -1.0
    et = np.full((HASH, 2), -1, np.int64)
    slots = np.empty(3, np.int64)
    stack_n = np.empty(STACK, np.int64)
    stack_lb = np.empty(STACK)
    NB = bodies.shape[0]
    # Per body, the leaf that held the previous pose's minimum: searched first, it gives the
    # bound U a good value at once (consecutive poses are close: the caller sorts them).
    seed = np.full(NB, -1, np.int64)
    for p in range(N):
        # best value U, its witness, kind, body, facet normal, edge (local scalars: registers)
        U = margin
        wx = wy = wz = np.nan
        kind, best_body = K_POINT, -1
        fnx = fny = fnz = 0.0
        eva = evb = 0
        ax, ay, az = axes[p, 0], axes[p, 1], axes[p, 2]
        for body in range(NB):
            key = p * NB + body
            fkey = float(key)
            o = bodies[body, 0]
            bx, by, bz = tips[p, 0] + o * ax, tips[p, 1] + o * ay, tips[p, 2] + o * az
            h, rad, off = bodies[body, 1], bodies[body, 2], bodies[body, 3]
            stack_n[0], stack_lb[0] = 0, -np.inf
            sp = 1
            if seed[body] >= 0:
                stack_n[1], stack_lb[1] = seed[body], -np.inf
                sp = 2
            best_leaf = -1
            while sp > 0:
                sp -= 1
                node = stack_n[sp]
                if stack_lb[sp] >= U - PRUNE_TOL:
                    continue
                c = int(NT[node, N_LEFT])
                if c >= 0:
                    # children's box bounds; the nearer child is searched first
                    l0 = _box_bound(NT, c, bx, by, bz, ax, ay, az, h, rad) - off
                    l1 = _box_bound(NT, c + 1, bx, by, bz, ax, ay, az, h, rad) - off
                    if l0 > l1:
                        far, lf, near, ln = c, l0, c + 1, l1
                    else:
                        far, lf, near, ln = c + 1, l1, c, l0
                    if lf < U - PRUNE_TOL:
                        stack_n[sp], stack_lb[sp] = far, lf
                        sp += 1
                    if ln < U - PRUNE_TOL:
                        stack_n[sp], stack_lb[sp] = near, ln
                        sp += 1
                    continue
                U_before = U
                f0 = int(NT[node, N_START])
                for f in range(f0, f0 + int(NT[node, N_COUNT])):
                    # 1. linear bound at the centroid: min over the vertices of sd(c) + g.(v - c)
                    cx, cy, cz = TF[f, T_C], TF[f, T_C + 1], TF[f, T_C + 2]
                    s, g0, g1, g2 = _sd_grad(cx, cy, cz, bx, by, bz, ax, ay, az, h, rad)
                    lin = np.inf
                    for q in range(T_P, T_P + 9, 3):
                        lin = min(lin, g0 * (TF[f, q] - cx) + g1 * (TF[f, q + 1] - cy) + g2 * (TF[f, q + 2] - cz))
                    if s - off + lin >= U - PRUNE_TOL:
                        continue
                    # 2. vertex values (once per pose and body; each is a candidate)
                    for q in range(3):
                        i = TI[f, q]
                        j = ((i & 0x7FFFFFFF) * 2654435761 + (i >> 31)) & (HASH - 1)
                        slot = -1
                        for _ in range(PROBES):
                            if vt[j, 1] != fkey:
                                slot = j
                                break
                            if vt[j, 0] == i:
                                slot = -2 - j  # cached
                                break
                            j = (j + 1) & (HASH - 1)
                        if slot <= -2:
                            slots[q] = -2 - slot
                            continue
                        if slot < 0:
                            slot = HASH + q
                        x, y, z = TF[f, T_P + 3 * q], TF[f, T_P + 3 * q + 1], TF[f, T_P + 3 * q + 2]
                        s, g0, g1, g2 = _sd_grad(x, y, z, bx, by, bz, ax, ay, az, h, rad)
                        vt[slot, 0], vt[slot, 1], vt[slot, 2] = i, fkey, s - off
                        vt[slot, 3], vt[slot, 4], vt[slot, 5] = g0, g1, g2
                        slots[q] = slot
                        if s - off < U:
                            U, wx, wy, wz = s - off, x, y, z
                            kind, best_body = K_POINT, body
                    # 3. the tangent planes at the vertices (each smallest at a vertex); best of three
                    lower = -np.inf
                    for q in range(3):
                        sq, i = slots[q], T_P + 3 * q
                        m = np.inf
                        for j in range(T_P, T_P + 9, 3):
                            m = min(m, vt[sq, 2] + vt[sq, 3] * (TF[f, j] - TF[f, i])
                                    + vt[sq, 4] * (TF[f, j + 1] - TF[f, i + 1])
                                    + vt[sq, 5] * (TF[f, j + 2] - TF[f, i + 2]))
                        lower = max(lower, m)
                    if lower >= U - PRUNE_TOL:
                        continue
                    p0x, p0y, p0z = TF[f, T_P], TF[f, T_P + 1], TF[f, T_P + 2]
                    # 4. facet test: if C lies on one side of the plane, the plane's closest point
                    #    to C is the foot of C's support point toward the plane; inside the
                    #    triangle it is the triangle's minimum.
                    cuts = False
                    nx = ny = nz = 0.0
                    if TF[f, T_VALID] > 0.0:
                        nx, ny, nz = TF[f, T_N], TF[f, T_N + 1], TF[f, T_N + 2]
                        sx, sy, sz = _support(bx, by, bz, ax, ay, az, h, rad, -nx, -ny, -nz)
                        hh = nx * (sx - p0x) + ny * (sy - p0y) + nz * (sz - p0z)
                        side = 1.0
                        # (a touching flat end, off = 0, has its rim on the plane: hh = 0 up to
                        # rounding, a facet contact, not a cut)
                        if hh < -TOUCH_TOL:
                            sx, sy, sz = _support(bx, by, bz, ax, ay, az, h, rad, nx, ny, nz)
                            hh = nx * (sx - p0x) + ny * (sy - p0y) + nz * (sz - p0z)
                            side = -1.0
                            cuts = hh > 0.0
                        if not cuts:
                            fx, fy, fz = sx - hh * nx, sy - hh * ny, sz - hh * nz
                            if _inside(TF, f, fx, fy, fz):
                                val = side * hh - off
                                if val < U:
                                    U, wx, wy, wz = val, fx, fy, fz
                                    kind, best_body = K_FACET, body
                                    fnx, fny, fnz = side * nx, side * ny, side * nz
                                continue
                    # 5. edges (each once per pose and body): exact 1-D convex minimisation, from
                    #    the lower vertex id to the higher (the same for both faces of an edge)
                    for q in range(3):
                        qa, qb = q, (q + 1) % 3
                        if TI[f, qa] > TI[f, qb]:
                            qa, qb = qb, qa
                        va, vb = TI[f, qa], TI[f, qb]
                        ek = va * nv + vb
                        j = ((ek & 0x7FFFFFFF) * 2654435761 + (ek >> 31)) & (HASH - 1)  # no int64 overflow
                        seen = False
                        for _ in range(PROBES):
                            if et[j, 0] != key:
                                et[j, 0], et[j, 1] = key, ek
                                break
                            if et[j, 1] == ek:
                                seen = True
                                break
                            j = (j + 1) & (HASH - 1)
                        if seen:
                            continue
                        sa, sb = slots[qa], slots[qb]
                        px, py, pz = TF[f, T_P + 3 * qa], TF[f, T_P + 3 * qa + 1], TF[f, T_P + 3 * qa + 2]
                        dx, dy, dz = (TF[f, T_P + 3 * qb] - px, TF[f, T_P + 3 * qb + 1] - py,
                                      TF[f, T_P + 3 * qb + 2] - pz)
                        ga = vt[sa, 3] * dx + vt[sa, 4] * dy + vt[sa, 5] * dz
                        gb = vt[sb, 3] * dx + vt[sb, 4] * dy + vt[sb, 5] * dz
                        t, val = _edge_min(px, py, pz, dx, dy, dz, vt[sa, 2], ga, vt[sb, 2], gb,
                                           bx, by, bz, ax, ay, az, h, rad, off, U, False)
                        if t >= 0.0 and val < U:
                            U, wx, wy, wz = val, px + t * dx, py + t * dy, pz + t * dz
                            kind, best_body, eva, evb = K_EDGE, body, va, vb
                    # 6. deep: the plane cuts C and the triangle may reach into it (sd < -off).
                    #    sd is convex on the plane: if its minimiser over the plane lies in the
                    #    triangle it is the triangle's minimum; if not, a minimiser lies on the
                    #    boundary, which the edges covered.
                    if cuts and lower < min(U - PRUNE_TOL, -off):
                        val, x, y, z = _plane_min(nx, ny, nz, p0x, p0y, p0z, bx, by, bz, ax, ay, az, h, rad)
                        if _inside(TF, f, x, y, z) and val - off < U:
                            U, wx, wy, wz = val - off, x, y, z
                            kind, best_body = K_POINT, body
                if U < U_before:
                    best_leaf = node
            if best_leaf >= 0:
                seed[body] = best_leaf
        if best_body < 0:
            continue
        # the witness and the normal of the minimum found
        body = best_body
        o = bodies[body, 0]
        bx, by, bz = tips[p, 0] + o * ax, tips[p, 1] + o * ay, tips[p, 2] + o * az
        h, rad, off = bodies[body, 1], bodies[body, 2], bodies[body, 3]
        if kind == K_EDGE:
            # place the edge minimum to full precision (the search stopped at a value gap)
            va, vb = eva, evb
            px, py, pz = V[va, 0], V[va, 1], V[va, 2]
            dx, dy, dz = V[vb, 0] - px, V[vb, 1] - py, V[vb, 2] - pz
            fa, g0, g1, g2 = _sd_grad(px, py, pz, bx, by, bz, ax, ay, az, h, rad)
            ga = g0 * dx + g1 * dy + g2 * dz
            fb, g0, g1, g2 = _sd_grad(V[vb, 0], V[vb, 1], V[vb, 2], bx, by, bz, ax, ay, az, h, rad)
            gb = g0 * dx + g1 * dy + g2 * dz
            t, val = _edge_min(px, py, pz, dx, dy, dz, fa - off, ga, fb - off, gb,
                               bx, by, bz, ax, ay, az, h, rad, off, U, True)
            # (val may exceed the best value found by rounding, ~1e-16 mm)
            U, wx, wy, wz = val, px + t * dx, py + t * dy, pz + t * dz
        delta[p] = U
        witness[p, 0], witness[p, 1], witness[p, 2] = wx, wy, wz
        if kind == K_FACET:
            normal[p, 0], normal[p, 1], normal[p, 2] = fnx, fny, fnz
            continue
        s, g0, g1, g2 = _sd_grad(wx, wy, wz, bx, by, bz, ax, ay, az, h, rad)
        gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        if gn == 0.0:
            # On the core axis, deeper from the wall than from the ends: every direction across
            # the axis separates equally; take the least-aligned coordinate axis, made orthogonal.
            k = 0
            if abs(ay) < abs(ax) and abs(ay) <= abs(az):
                k = 1
            elif abs(az) < abs(ax) and abs(az) < abs(ay):
                k = 2
            ak = ax if k == 0 else (ay if k == 1 else az)
            g0 = (1.0 if k == 0 else 0.0) - ak * ax
            g1 = (1.0 if k == 1 else 0.0) - ak * ay
            g2 = (1.0 if k == 2 else 0.0) - ak * az
            gn = math.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
        normal[p, 0], normal[p, 1], normal[p, 2] = -g0 / gn, -g1 / gn, -g2 / gn
    return delta, witness, normal
