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
* a closed triangle mesh, baked once into a grid of node distances and normals
  (``brush_env.geometry.sdf_bake.bake_mesh``) and queried by trilinear interpolation
  (``grid_gap``).  Outside nodes farther than ``band``
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
(node (i, j, k) of grid g at ``offset + (i ny + j) nz + k``).  Baking and its disk cache live in
``brush_env.geometry.sdf_bake``; this module holds the query kernels.  Units: mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from ._kernels import HOT

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


# ------------------------------------------------------------------ a baked grid
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


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def _query_many(g, sdf, P):
    d = np.empty(P.shape[0])
    N = np.zeros((P.shape[0], 3))
    nrm = np.zeros(3)
    cpt = np.zeros(3)
    for i in range(P.shape[0]):
        d[i] = grid_gap(g, sdf, P[i], nrm, cpt)
        N[i] = nrm
    return d, N
