"""Signed distance fields (SDF) for tip contact with curved surfaces: analytic primitives and
triangle meshes baked into narrow-band grids.

The contact law (eq 6-10) needs, at the tip-sphere centre ``p``, the signed distance ``d`` to the
surface (> 0 outside), the outward normal ``n`` and the closest point ``p - d n``; the tip touches
where ``d < R`` (penetration ``R - d``).  Each surface kind supplies those three:

* analytic, exact: sphere, capsule (a segment swept by a radius), axis-aligned ellipsoid (the
  closest point by the Lagrange-multiplier root, solved by bisection: exact to round-off);
  plane and cylinder stay in ``contact.py``.  Several surfaces in one scene form their *union*:
  the kernel takes the deepest contact (the smallest distance), which is the union's SDF wherever
  the tip touches one surface at a time.
* a closed triangle mesh, baked once into a grid of node distances and normals (``bake_mesh``)
  and queried by trilinear interpolation (``grid_gap``).  Outside nodes farther than ``band``
  from the mesh are clamped to +band (a narrow band: contact only needs the surface's
  neighbourhood); inside nodes beyond the band get -(band + their distance to the band) and its
  gradient as normal, so a tip that lands deep inside (a snap-through step) is still pushed out.
  Distance at the nodes is exact (closest triangle), its sign from the angle-weighted
  pseudonormal of the closest feature (Baerentzen & Aanaes, IEEE TVCG 11(3), 2005), which is
  correct for any closed, consistently oriented mesh.  Interpolation error: trilinear weights
  form a convex combination and the distance is 1-Lipschitz, so ``|d_grid - d| <= sqrt(3) h``
  for cell ``h`` everywhere in the band, and O(h^2 curvature) on smooth surfaces
  (tests/engine/test_sdf.py measures both).  The exact closest-triangle query
  (``contact._mesh_gap``) stays as the validation path.

Kernel data: ``sdf = (hdr, vals)`` with ``hdr`` (ng, 8) float64 rows ``origin x, y, z [mm], cell
h [mm], nx, ny, nz, offset`` and ``vals`` (N, 4) float32 node rows ``d [mm], n_x, n_y, n_z``
(node (i, j, k) of grid g at ``offset + (i ny + j) nz + k``).  Baked grids are cached on disk
(``cache_dir()``) under the SHA-256 of the mesh, cell, band and ``BAKE_VERSION``.  Units: mm.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numba import njit

from ._kernels import HOT

BAKE_VERSION = 2  # bump when the baking changes: cached grids of older versions are not used
FAR = 1e300  # "no surface near": larger than any tip radius


# ------------------------------------------------------------------ analytic primitives
@njit(**HOT)
def sphere_gap(row, pt, nrm, cpt):
    """Sphere, row: kind, centre (3) [mm], -, -, -, radius [mm]."""
    r0 = pt[0] - row[1]
    r1 = pt[1] - row[2]
    r2 = pt[2] - row[3]
    rr = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if rr < 1e-12:  # at the centre: any direction is as close; pick +z
        nrm[0], nrm[1], nrm[2] = 0.0, 0.0, 1.0
    else:
        nrm[0], nrm[1], nrm[2] = r0 / rr, r1 / rr, r2 / rr
    for a in range(3):
        cpt[a] = row[1 + a] + row[7] * nrm[a]
    return rr - row[7]


@njit(**HOT)
def capsule_gap(row, pt, nrm, cpt):
    """Capsule, row: kind, end a (3) [mm], end b (3) [mm], radius [mm]: the points within radius
    of the segment ab."""
    ab0 = row[4] - row[1]
    ab1 = row[5] - row[2]
    ab2 = row[6] - row[3]
    L2 = ab0 * ab0 + ab1 * ab1 + ab2 * ab2
    s = 0.0
    if L2 > 0.0:
        s = ((pt[0] - row[1]) * ab0 + (pt[1] - row[2]) * ab1 + (pt[2] - row[3]) * ab2) / L2
        s = min(1.0, max(0.0, s))
    q0 = row[1] + s * ab0
    q1 = row[2] + s * ab1
    q2 = row[3] + s * ab2
    r0 = pt[0] - q0
    r1 = pt[1] - q1
    r2 = pt[2] - q2
    rr = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if rr < 1e-12:
        nrm[0], nrm[1], nrm[2] = 0.0, 0.0, 1.0
    else:
        nrm[0], nrm[1], nrm[2] = r0 / rr, r1 / rr, r2 / rr
    cpt[0] = q0 + row[7] * nrm[0]
    cpt[1] = q1 + row[7] * nrm[1]
    cpt[2] = q2 + row[7] * nrm[2]
    return rr - row[7]


@njit(**HOT)
def ellipsoid_gap(row, pt, nrm, cpt):
    """Axis-aligned ellipsoid, row: kind, centre (3) [mm], semi-axes (3) [mm], -.

    The closest point is ``x_i = a_i^2 p_i / (a_i^2 + t)`` with t the root of
    ``sum (a_i p_i / (a_i^2 + t))^2 = 1`` in ``(-min a_i^2, inf)`` (F decreasing there), found by
    bisection to round-off.  Exact but for the measure-zero set of inside points on a symmetry
    plane of the smallest axis, where it returns the nearer of the two axis caps."""
    p0 = pt[0] - row[1]
    p1 = pt[1] - row[2]
    p2 = pt[2] - row[3]
    a0, a1, a2 = row[4], row[5], row[6]
    s0, s1, s2 = a0 * a0, a1 * a1, a2 * a2
    inside = (p0 / a0) ** 2 + (p1 / a1) ** 2 + (p2 / a2) ** 2 < 1.0
    amin2 = min(s0, min(s1, s2))
    lo = -amin2
    pn = np.sqrt(p0 * p0 + p1 * p1 + p2 * p2)
    hi = max(a0, max(a1, a2)) * pn + 1e-300
    if inside:
        hi = 0.0
    for _ in range(200):
        t = 0.5 * (lo + hi)
        if t <= lo or t >= hi:
            break
        f = (a0 * p0 / (s0 + t)) ** 2 + (a1 * p1 / (s1 + t)) ** 2 + (a2 * p2 / (s2 + t)) ** 2
        if f > 1.0:
            lo = t
        else:
            hi = t
    t = 0.5 * (lo + hi)
    x0 = s0 * p0 / (s0 + t) if s0 + t > 0.0 else 0.0
    x1 = s1 * p1 / (s1 + t) if s1 + t > 0.0 else 0.0
    x2 = s2 * p2 / (s2 + t) if s2 + t > 0.0 else 0.0
    # project the (possibly degenerate) point back onto the surface along its own ray
    k = np.sqrt((x0 / a0) ** 2 + (x1 / a1) ** 2 + (x2 / a2) ** 2)
    if k > 0.0:
        x0, x1, x2 = x0 / k, x1 / k, x2 / k
    else:
        x0, x1, x2 = 0.0, 0.0, a2
    g0, g1, g2 = x0 / s0, x1 / s1, x2 / s2  # outward surface normal (unnormalised)
    gn = np.sqrt(g0 * g0 + g1 * g1 + g2 * g2)
    nrm[0], nrm[1], nrm[2] = g0 / gn, g1 / gn, g2 / gn
    d = np.sqrt((p0 - x0) ** 2 + (p1 - x1) ** 2 + (p2 - x2) ** 2)
    cpt[0], cpt[1], cpt[2] = row[1] + x0, row[2] + x1, row[3] + x2
    return -d if inside else d


@njit(**HOT, inline="always")
def _tangent_projector(nrm, J, scale):
    """J <- (I - n n^T) * scale."""
    for a in range(3):
        for b in range(3):
            J[a, b] = ((1.0 if a == b else 0.0) - nrm[a] * nrm[b]) * scale


@njit(**HOT)
def round_rate(row, kind_axis, pt, nrm, gap, J):
    """dn/dpt [1/mm] of a sphere (kind_axis 0), capsule (1) or infinite cylinder (2; row as in
    ``contact``: point on the axis, unit axis, radius): the normal turns by 1 / (radius + gap) per
    mm across the surface, and not at all along a cylinder's axis."""
    rr = gap + row[7]
    if rr < 1e-12:
        rr = 1e-12
    _tangent_projector(nrm, J, 1.0 / rr)
    if kind_axis == 0:
        return
    if kind_axis == 1:
        a0, a1, a2 = row[4] - row[1], row[5] - row[2], row[6] - row[3]
        L2 = a0 * a0 + a1 * a1 + a2 * a2
        if L2 <= 0.0:
            return
        s = ((pt[0] - row[1]) * a0 + (pt[1] - row[2]) * a1 + (pt[2] - row[3]) * a2) / L2
        if s <= 0.0 or s >= 1.0:  # on an end cap: a sphere
            return
        L = np.sqrt(L2)
        a0, a1, a2 = a0 / L, a1 / L, a2 / L
    else:
        a0, a1, a2 = row[4], row[5], row[6]
    ax = (a0, a1, a2)
    for a in range(3):
        for b in range(3):
            J[a, b] -= ax[a] * ax[b] / rr


@njit(**HOT)
def ellipsoid_rate(row, nrm, gap, J):
    """dn/dpt [1/mm] of ``ellipsoid_gap``'s field at a point ``gap`` [mm] off the surface along
    ``nrm``: W (I + gap W)^-1 with W = P diag(1/a^2) P / |diag(1/a^2) x| the shape operator at the
    closest point x (P = I - n n^T; W n = 0).  Zero where I + gap W is singular (a focal point
    inside)."""
    # on the surface x_i = lam a_i^2 n_i with sum (x_i / a_i)^2 = 1, and |diag(1/a^2) x| = lam
    s0, s1, s2 = row[4] * row[4], row[5] * row[5], row[6] * row[6]
    lam = 1.0 / np.sqrt(s0 * nrm[0] ** 2 + s1 * nrm[1] ** 2 + s2 * nrm[2] ** 2)
    inv = (1.0 / s0, 1.0 / s1, 1.0 / s2)
    for a in range(3):  # J <- W
        for b in range(3):
            acc = 0.0
            for c in range(3):
                pac = (1.0 if a == c else 0.0) - nrm[a] * nrm[c]
                pcb = (1.0 if c == b else 0.0) - nrm[c] * nrm[b]
                acc += pac * inv[c] * pcb
            J[a, b] = acc / lam
    m00, m01, m02 = 1.0 + gap * J[0, 0], gap * J[0, 1], gap * J[0, 2]
    m10, m11, m12 = gap * J[1, 0], 1.0 + gap * J[1, 1], gap * J[1, 2]
    m20, m21, m22 = gap * J[2, 0], gap * J[2, 1], 1.0 + gap * J[2, 2]
    det = m00 * (m11 * m22 - m12 * m21) - m01 * (m10 * m22 - m12 * m20)
    det += m02 * (m10 * m21 - m11 * m20)
    if abs(det) < 1e-9:
        for a in range(3):
            for b in range(3):
                J[a, b] = 0.0
        return
    i00, i01, i02 = (m11 * m22 - m12 * m21), (m02 * m21 - m01 * m22), (m01 * m12 - m02 * m11)
    i10, i11, i12 = (m12 * m20 - m10 * m22), (m00 * m22 - m02 * m20), (m02 * m10 - m00 * m12)
    i20, i21, i22 = (m10 * m21 - m11 * m20), (m01 * m20 - m00 * m21), (m00 * m11 - m01 * m10)
    for a in range(3):  # J <- W M^-1, row by row
        w0, w1, w2 = J[a, 0], J[a, 1], J[a, 2]
        J[a, 0] = (w0 * i00 + w1 * i10 + w2 * i20) / det
        J[a, 1] = (w0 * i01 + w1 * i11 + w2 * i21) / det
        J[a, 2] = (w0 * i02 + w1 * i12 + w2 * i22) / det


# ------------------------------------------------------------------ grid query
@njit(**HOT, inline="always")
def _grid_cell(g, hdr, pt):
    """The cell of grid g that holds pt: (node index of its corner (0, 0, 0) in ``vals``, ny, nz,
    the local coordinates tx, ty, tz in [0, 1), cell h [mm]); corner index -1 outside the grid
    (also for NaN).  Corner (di, dj, dk) is at index + (di ny + dj) nz + dk."""
    h = hdr[g, 3]
    nx, ny, nz = int(hdr[g, 4]), int(hdr[g, 5]), int(hdr[g, 6])
    fx = (pt[0] - hdr[g, 0]) / h
    fy = (pt[1] - hdr[g, 1]) / h
    fz = (pt[2] - hdr[g, 2]) / h
    if not (fx >= 0.0 and fy >= 0.0 and fz >= 0.0):  # also catches NaN
        return -1, ny, nz, 0.0, 0.0, 0.0, h
    ix, iy, iz = int(fx), int(fy), int(fz)
    if ix >= nx - 1 or iy >= ny - 1 or iz >= nz - 1:
        return -1, ny, nz, 0.0, 0.0, 0.0, h
    return int(hdr[g, 7]) + (ix * ny + iy) * nz + iz, ny, nz, fx - ix, fy - iy, fz - iz, h


@njit(**HOT)
def grid_gap(g, sdf, pt, nrm, cpt):
    """Signed distance [mm] at pt from grid ``g`` of ``sdf`` by trilinear interpolation of the
    node distances and normals; FAR outside the grid (no surface within the band there)."""
    hdr, vals = sdf
    q0, ny, nz, tx, ty, tz, h = _grid_cell(g, hdr, pt)
    if q0 < 0:
        return FAR
    d = 0.0
    n0 = 0.0
    n1 = 0.0
    n2 = 0.0
    for c in range(8):
        di, dj, dk = c >> 2, (c >> 1) & 1, c & 1
        w = (tx if di else 1.0 - tx) * (ty if dj else 1.0 - ty) * (tz if dk else 1.0 - tz)
        q = q0 + (di * ny + dj) * nz + dk
        d += w * vals[q, 0]
        n0 += w * vals[q, 1]
        n1 += w * vals[q, 2]
        n2 += w * vals[q, 3]
    nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if nn < 1e-12:  # on a medial surface far inside: no meaningful normal
        return FAR
    nrm[0], nrm[1], nrm[2] = n0 / nn, n1 / nn, n2 / nn
    for a in range(3):
        cpt[a] = pt[a] - d * nrm[a]
    return d


@njit(**HOT)
def grid_rate(g, sdf, pt, J, gd):
    """Derivatives of ``grid_gap``'s interpolation at pt: gd <- the gradient of the trilinear
    distance [-] (what the penetration follows; within O(h curvature) of the normal), and
    J <- dn/dpt [1/mm] of the interpolated normal n = N/|N|, N = sum_c w_c n_c:
    J = (I - n n^T) (sum_c n_c grad w_c^T) / |N|.  Both zero outside the grid."""
    hdr, vals = sdf
    for a in range(3):
        gd[a] = 0.0
        for b in range(3):
            J[a, b] = 0.0
    q0, ny, nz, tx, ty, tz, h = _grid_cell(g, hdr, pt)
    if q0 < 0:
        return
    n0 = n1 = n2 = 0.0
    for c in range(8):
        di, dj, dk = c >> 2, (c >> 1) & 1, c & 1
        wx = tx if di else 1.0 - tx
        wy = ty if dj else 1.0 - ty
        wz = tz if dk else 1.0 - tz
        sx = (1.0 if di else -1.0) / h
        sy = (1.0 if dj else -1.0) / h
        sz = (1.0 if dk else -1.0) / h
        gw = (sx * wy * wz, wx * sy * wz, wx * wy * sz)  # grad of this node's weight
        q = q0 + (di * ny + dj) * nz + dk
        w = wx * wy * wz
        n0 += w * vals[q, 1]
        n1 += w * vals[q, 2]
        n2 += w * vals[q, 3]
        for b in range(3):
            gd[b] += vals[q, 0] * gw[b]
            for a in range(3):
                J[a, b] += vals[q, 1 + a] * gw[b]
    nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if nn < 1e-12:
        for a in range(3):
            for b in range(3):
                J[a, b] = 0.0
        return
    N = (n0 / nn, n1 / nn, n2 / nn)
    # J <- (I - n n^T) J / |N|, column by column
    for b in range(3):
        dot = N[0] * J[0, b] + N[1] * J[1, b] + N[2] * J[2, b]
        for a in range(3):
            J[a, b] = (J[a, b] - N[a] * dot) / nn


def empty_sdf():
    """The kernels' sdf data of a scene without grids (numba needs fixed types)."""
    return (np.zeros((0, 8)), np.zeros((1, 4), np.float32))


def pack_grids(grids) -> tuple:
    """Kernel data ``(hdr, vals)`` of a list of :class:`SdfGrid` (grid g = row g of hdr)."""
    if not grids:
        return empty_sdf()
    hdr = np.zeros((len(grids), 8))
    off = 0
    for g, gr in enumerate(grids):
        nx, ny, nz = gr.distance.shape
        hdr[g] = (*gr.origin, gr.cell, nx, ny, nz, off)
        off += nx * ny * nz
    vals = np.empty((off, 4), np.float32)
    for g, gr in enumerate(grids):
        o = int(hdr[g, 7])
        n = gr.distance.size
        vals[o : o + n, 0] = gr.distance.ravel()
        vals[o : o + n, 1:4] = gr.normal.reshape(-1, 3)
    return hdr, vals


# ------------------------------------------------------------------ baking a mesh
@dataclass(frozen=True)
class SdfGrid:
    """A baked narrow-band SDF: node (i, j, k) at ``origin + h (i, j, k)`` [mm]; ``distance``
    (nx, ny, nz) [mm] (> 0 outside, clamped to +-band), ``normal`` (nx, ny, nz, 3)."""

    origin: tuple
    cell: float
    band: float
    distance: np.ndarray
    normal: np.ndarray

    def query(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(d (n,), normal (n, 3)) at world points (n, 3) [mm] (FAR outside the grid)."""
        sdf = pack_grids([self])
        P = np.atleast_2d(np.asarray(points, float))
        return _query_many(0, sdf, P)


@njit(cache=True)
def _query_many(g, sdf, P):
    d = np.empty(P.shape[0])
    N = np.zeros((P.shape[0], 3))
    nrm = np.zeros(3)
    cpt = np.zeros(3)
    for i in range(P.shape[0]):
        d[i] = grid_gap(g, sdf, P[i], nrm, cpt)
        N[i] = nrm
    return d, N


@njit(cache=True, inline="always")
def _dot(x0, x1, x2, y0, y1, y2):
    return x0 * y0 + x1 * y1 + x2 * y2


@njit(cache=True)
def closest_feature(p0, p1, p2, a, b, c):
    """Closest point (q0, q1, q2) on triangle abc to p and its feature: 0 face, 1/2/3 vertex
    a/b/c, 4/5/6 edge ab/bc/ca (Ericson, Real-Time Collision Detection, 2005, §5.1.5)."""
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d1 = _dot(ab0, ab1, ab2, p0 - a[0], p1 - a[1], p2 - a[2])
    d2 = _dot(ac0, ac1, ac2, p0 - a[0], p1 - a[1], p2 - a[2])
    if d1 <= 0.0 and d2 <= 0.0:
        return a[0], a[1], a[2], 1
    d3 = _dot(ab0, ab1, ab2, p0 - b[0], p1 - b[1], p2 - b[2])
    d4 = _dot(ac0, ac1, ac2, p0 - b[0], p1 - b[1], p2 - b[2])
    if d3 >= 0.0 and d4 <= d3:
        return b[0], b[1], b[2], 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return a[0] + v * ab0, a[1] + v * ab1, a[2] + v * ab2, 4
    d5 = _dot(ab0, ab1, ab2, p0 - c[0], p1 - c[1], p2 - c[2])
    d6 = _dot(ac0, ac1, ac2, p0 - c[0], p1 - c[1], p2 - c[2])
    if d6 >= 0.0 and d5 <= d6:
        return c[0], c[1], c[2], 3
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        w = d2 / (d2 - d6)
        return a[0] + w * ac0, a[1] + w * ac1, a[2] + w * ac2, 6
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return b[0] + w * (c[0] - b[0]), b[1] + w * (c[1] - b[1]), b[2] + w * (c[2] - b[2]), 5
    den = 1.0 / (va + vb + vc)
    v = vb * den
    w = vc * den
    return a[0] + ab0 * v + ac0 * w, a[1] + ab1 * v + ac1 * w, a[2] + ab2 * v + ac2 * w, 0


@njit(cache=True)
def _splat(V, T, pseudo, lo, h, band, dist, nrm, known):
    """Exact distance and sign at every node within ``band`` of a triangle (node-by-triangle
    minimum); sign and normal from the closest feature's pseudonormal (``pseudo`` = (face, edge,
    vertex) pseudonormals)."""
    fn, en, vn = pseudo
    i0 = np.empty(3, np.int64)
    i1 = np.empty(3, np.int64)
    for t in range(T.shape[0]):
        a, b, c = V[T[t, 0]], V[T[t, 1]], V[T[t, 2]]
        for k in range(3):
            mn = min(a[k], min(b[k], c[k])) - band
            mx = max(a[k], max(b[k], c[k])) + band
            i0[k] = max(int(np.floor((mn - lo[k]) / h)), 0)
            i1[k] = min(int(np.ceil((mx - lo[k]) / h)), dist.shape[k] - 1)
        for i in range(i0[0], i1[0] + 1):
            p0 = lo[0] + h * i
            for j in range(i0[1], i1[1] + 1):
                p1 = lo[1] + h * j
                for k in range(i0[2], i1[2] + 1):
                    p2 = lo[2] + h * k
                    q0, q1, q2, feat = closest_feature(p0, p1, p2, a, b, c)
                    r0, r1, r2 = p0 - q0, p1 - q1, p2 - q2
                    dd = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
                    if dd > band or dd >= abs(dist[i, j, k]):
                        continue
                    if feat == 0:
                        pn = fn[t]
                    elif feat <= 3:
                        pn = vn[T[t, feat - 1]]
                    else:
                        pn = en[t, feat - 4]
                    s = 1.0 if _dot(r0, r1, r2, pn[0], pn[1], pn[2]) >= 0.0 else -1.0
                    dist[i, j, k] = s * dd
                    if dd > 1e-9:
                        nrm[i, j, k, 0] = s * r0 / dd
                        nrm[i, j, k, 1] = s * r1 / dd
                        nrm[i, j, k, 2] = s * r2 / dd
                    else:
                        nrm[i, j, k, 0] = pn[0]
                        nrm[i, j, k, 1] = pn[1]
                        nrm[i, j, k, 2] = pn[2]
                    known[i, j, k] = True


def pseudonormals(V: np.ndarray, T: np.ndarray):
    """(face (nt, 3), edge (nt, 3, 3) for edges ab, bc, ca, vertex (nv, 3)) unit pseudonormals:
    edges the sum of their two faces' normals, vertices the angle-weighted sum (Baerentzen &
    Aanaes 2005)."""
    P = V[T]  # (nt, 3, 3)
    fn = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    E = np.stack([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]], axis=1).reshape(-1, 2)
    key = np.sort(E, axis=1)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    acc = np.zeros((inv.max() + 1, 3))
    np.add.at(acc, inv, np.repeat(fn, 3, axis=0))
    acc /= np.maximum(np.linalg.norm(acc, axis=1), 1e-300)[:, None]
    en = acc[inv].reshape(-1, 3, 3)
    vn = np.zeros_like(V)
    for k in range(3):
        e1 = P[:, (k + 1) % 3] - P[:, k]
        e2 = P[:, (k + 2) % 3] - P[:, k]
        cosang = np.einsum("ij,ij->i", e1, e2) / (
            np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
        )
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))
        np.add.at(vn, T[:, k], ang[:, None] * fn)
    vn /= np.maximum(np.linalg.norm(vn, axis=1), 1e-300)[:, None]
    return fn, en, vn


def bake_mesh(vertices, triangles, cell: float = 0.2, band: float = 1.0) -> SdfGrid:
    """Bake a closed, outward-oriented triangle mesh (vertices [mm]) into a narrow-band grid of
    cell ``cell`` [mm] reaching ``band`` [mm] beyond the mesh's bounding box."""
    from scipy import ndimage

    V = np.ascontiguousarray(vertices, float)
    T = np.ascontiguousarray(triangles, np.int64)
    if not (cell > 0 and band >= 2 * cell):
        raise ValueError(
            f"sdf cell = {cell!r} mm, band = {band!r} mm: need cell > 0, band >= 2 cell"
        )
    lo = V.min(axis=0) - band - cell
    dims = np.ceil((V.max(axis=0) + band + cell - lo) / cell).astype(np.int64) + 1
    fn, en, vn = pseudonormals(V, T)
    dist = np.full(tuple(dims), np.inf)
    nrm = np.zeros((*dims, 3))
    known = np.zeros(tuple(dims), bool)
    _splat(V, T, (fn, en, vn), lo, float(cell), float(band), dist, nrm, known)
    # nodes beyond the band: outside if connected to the grid's border without crossing the band
    labels, _ = ndimage.label(~known)
    border = np.unique(
        np.concatenate(
            [
                labels[[0, -1], :, :].ravel(),
                labels[:, [0, -1], :].ravel(),
                labels[:, :, [0, -1]].ravel(),
            ]
        )
    )
    outside = np.isin(labels, border[border > 0])
    dist[~known] = np.where(outside[~known], band, -band)
    # inside beyond the band: -(band + distance to the band) with the gradient as normal, so a
    # tip that lands deep inside (a snap-through predictor step) is pushed out, not lost
    deep = ~known & ~outside
    if deep.any():
        dist[deep] = -band - cell * ndimage.distance_transform_edt(deep)[deep]
        g = np.stack(np.gradient(dist, cell), axis=-1)
        gn = np.linalg.norm(g, axis=-1)
        ok = deep & (gn > 1e-12)
        nrm[ok] = g[ok] / gn[ok][:, None]
    return SdfGrid(tuple(float(x) for x in lo), float(cell), float(band), dist, nrm)


def cache_dir() -> Path:
    """Where baked grids are kept: $BRUSH_ENV_CACHE/sdf, else ~/.cache/brush_env/sdf."""
    root = os.environ.get("BRUSH_ENV_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "brush_env"
    )
    return Path(root) / "sdf"


def mesh_key(vertices, triangles, cell: float, band: float) -> str:
    """Content hash of a bake: mesh arrays, cell, band and BAKE_VERSION."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, np.float64).tobytes())
    h.update(np.ascontiguousarray(triangles, np.int64).tobytes())
    h.update(f"{cell!r},{band!r},{BAKE_VERSION}".encode())
    return h.hexdigest()[:32]


def bake_mesh_cached(vertices, triangles, cell: float = 0.2, band: float = 1.0) -> SdfGrid:
    """``bake_mesh`` through the disk cache (a corrupt or unwritable cache only costs a bake)."""
    path = cache_dir() / f"{mesh_key(vertices, triangles, cell, band)}.npz"
    try:
        with np.load(path) as z:
            return SdfGrid(
                tuple(z["origin"]), float(z["cell"]), float(z["band"]), z["distance"], z["normal"]
            )
    except (OSError, KeyError, ValueError):
        pass
    grid = bake_mesh(vertices, triangles, cell, band)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez_compressed(
            tmp,
            origin=np.array(grid.origin),
            cell=grid.cell,
            band=grid.band,
            distance=grid.distance.astype(np.float32),
            normal=grid.normal.astype(np.float32),
        )
        os.replace(tmp, path)
    except OSError:
        pass
    return grid
