"""Tip contact with a triangle mesh: the exact closest-point query behind ``SURF_MESH`` surfaces.

The distance from a tip sphere's centre to the mesh is the smallest distance to its triangles
(``closest_on_triangle``, Ericson, Real-Time Collision Detection 5.1.5) over the triangles of the
uniform-grid cells near the centre (``build_mesh``); signed by the triangle normals.  The contact
normal (eq 6's normal direction) is the face normal in a face's interior and the direction from
the closest point otherwise.  ``mesh_query`` is the validation path of the baked SDF grids
(sdf.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT


@njit(**HOT, inline="always")
def dot3(x0, x1, x2, y0, y1, y2):
    """x . y of two 3-vectors given by their components."""
    return x0 * y0 + x1 * y1 + x2 * y2


@njit(**HOT)
def closest_feature(p0, p1, p2, a, b, c):
    """Closest point (q0, q1, q2) on triangle abc to p and its feature: 0 face, 1/2/3 vertex
    a/b/c, 4/5/6 edge ab/bc/ca (Ericson, Real-Time Collision Detection, 2005, §5.1.5).  The one
    implementation: the mesh contact (``closest_on_triangle``) and the SDF baking's signs
    (``geometry.sdf_bake``, the feature's pseudonormal) both use it."""
    ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
    ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
    d1 = dot3(ab0, ab1, ab2, p0 - a[0], p1 - a[1], p2 - a[2])
    d2 = dot3(ac0, ac1, ac2, p0 - a[0], p1 - a[1], p2 - a[2])
    if d1 <= 0.0 and d2 <= 0.0:
        return a[0], a[1], a[2], 1
    d3 = dot3(ab0, ab1, ab2, p0 - b[0], p1 - b[1], p2 - b[2])
    d4 = dot3(ac0, ac1, ac2, p0 - b[0], p1 - b[1], p2 - b[2])
    if d3 >= 0.0 and d4 <= d3:
        return b[0], b[1], b[2], 2
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        v = d1 / (d1 - d3)
        return a[0] + v * ab0, a[1] + v * ab1, a[2] + v * ab2, 4
    d5 = dot3(ab0, ab1, ab2, p0 - c[0], p1 - c[1], p2 - c[2])
    d6 = dot3(ac0, ac1, ac2, p0 - c[0], p1 - c[1], p2 - c[2])
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


@njit(**HOT)
def closest_on_triangle(p, a, b, c):
    """Closest point (x, y, z) to p on triangle abc: ``closest_feature`` without the feature."""
    q0, q1, q2, _ = closest_feature(p[0], p[1], p[2], a, b, c)
    return q0, q1, q2


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def mesh_gap(pt, search, mesh, nrm, cpt):
    """Signed distance from pt to the mesh (>0 on the side the triangle normals point to), the
    contact normal and the closest point, over the triangles of the grid cells within ``search``
    of pt (uniform-grid spatial index).  Returns 1e300 if no triangle is that close."""
    verts, tris, tnrm, gf, cell_start, cell_tris = mesh
    if tris.shape[0] == 0:
        return 1e300
    cell = gf[3]
    nx, ny, nz = int(gf[4]), int(gf[5]), int(gf[6])
    lo0 = max(int(np.floor((pt[0] - search - gf[0]) / cell)), 0)
    lo1 = max(int(np.floor((pt[1] - search - gf[1]) / cell)), 0)
    lo2 = max(int(np.floor((pt[2] - search - gf[2]) / cell)), 0)
    hi0 = min(int(np.floor((pt[0] + search - gf[0]) / cell)), nx - 1)
    hi1 = min(int(np.floor((pt[1] + search - gf[1]) / cell)), ny - 1)
    hi2 = min(int(np.floor((pt[2] + search - gf[2]) / cell)), nz - 1)
    if lo0 > hi0 or lo1 > hi1 or lo2 > hi2:
        return 1e300
    best = 1e300
    bestd = 1e300
    for ix in range(lo0, hi0 + 1):
        for iy in range(lo1, hi1 + 1):
            for iz in range(lo2, hi2 + 1):
                c = (ix * ny + iy) * nz + iz
                for k in range(cell_start[c], cell_start[c + 1]):
                    t = cell_tris[k]
                    q0, q1, q2 = closest_on_triangle(
                        pt, verts[tris[t, 0]], verts[tris[t, 1]], verts[tris[t, 2]]
                    )
                    d0 = pt[0] - q0
                    d1 = pt[1] - q1
                    d2 = pt[2] - q2
                    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
                    if dist < bestd:
                        bestd = dist
                        side = d0 * tnrm[t, 0] + d1 * tnrm[t, 1] + d2 * tnrm[t, 2]
                        if (
                            dist > 1e-12 * (1.0 + abs(pt[0]) + abs(pt[1]) + abs(pt[2]))
                            and abs(side) < (1.0 - 1e-12) * dist
                        ):
                            # closest point on an edge or vertex: normal along p - q
                            sg = 1.0 if side >= 0.0 else -1.0
                            nrm[0] = sg * d0 / dist
                            nrm[1] = sg * d1 / dist
                            nrm[2] = sg * d2 / dist
                            best = sg * dist
                        else:  # face interior: the face normal, exactly as for a plane
                            for a in range(3):
                                nrm[a] = tnrm[t, a]
                            best = side
                        cpt[0] = q0
                        cpt[1] = q1
                        cpt[2] = q2
    return best


def empty_mesh():
    """The mesh arrays of a scene without a triangle mesh (numba needs fixed types)."""
    return (
        np.zeros((0, 3)),
        np.zeros((0, 3), np.int64),
        np.zeros((0, 3)),
        np.zeros(7),
        np.zeros(1, np.int64),
        np.zeros(0, np.int64),
    )


def build_mesh(vertices, triangles, cell: float | None = None):
    """Mesh arrays with a uniform-grid index: every triangle is listed in each cell its bounding
    box overlaps.  ``cell`` [mm] defaults to twice the mean edge length."""
    V = np.ascontiguousarray(vertices, dtype=float)
    T = np.ascontiguousarray(triangles, dtype=np.int64)
    e1 = V[T[:, 1]] - V[T[:, 0]]
    e2 = V[T[:, 2]] - V[T[:, 0]]
    n = np.cross(e1, e2)
    area2 = np.linalg.norm(n, axis=1)
    if np.any(area2 <= 0):
        raise ValueError("mesh has degenerate triangles (zero area)")
    n = n / area2[:, None]
    if cell is None:
        cell = 2.0 * float(np.mean(np.linalg.norm(e1, axis=1)))
    lo = V.min(axis=0) - 1e-9
    dims = np.maximum(np.ceil((V.max(axis=0) + 1e-9 - lo) / cell).astype(np.int64), 1)
    tlo = np.floor((V[T].min(axis=1) - lo) / cell).astype(np.int64)
    thi = np.floor((V[T].max(axis=1) - lo) / cell).astype(np.int64)
    thi = np.minimum(thi, dims - 1)
    buckets = [[] for _ in range(int(np.prod(dims)))]
    for t in range(len(T)):
        for ix in range(tlo[t, 0], thi[t, 0] + 1):
            for iy in range(tlo[t, 1], thi[t, 1] + 1):
                for iz in range(tlo[t, 2], thi[t, 2] + 1):
                    buckets[(ix * dims[1] + iy) * dims[2] + iz].append(t)
    start = np.zeros(len(buckets) + 1, np.int64)
    start[1:] = np.cumsum([len(bk) for bk in buckets])
    flat = np.array([t for bk in buckets for t in bk], np.int64)
    gf = np.array([lo[0], lo[1], lo[2], cell, dims[0], dims[1], dims[2]], float)
    return (V, T, n, gf, start, flat)


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def _mesh_query_many(mesh, P, search):
    d = np.empty(P.shape[0])
    N = np.zeros((P.shape[0], 3))
    nrm = np.zeros(3)
    cpt = np.zeros(3)
    for i in range(P.shape[0]):
        d[i] = mesh_gap(P[i], search, mesh, nrm, cpt)
        N[i] = nrm
    return d, N


def mesh_query(mesh, points, search: float = 1.0):
    """(d (n,), normal (n, 3)) at points (n, 3) [mm] by the exact closest-triangle search over
    the triangles within ``search`` [mm] (1e300 beyond): the validation path of sdf grids."""
    P = np.ascontiguousarray(np.atleast_2d(points), dtype=float)
    return _mesh_query_many(mesh, P, float(search))
