"""The surfaces a tip touches: signed distance, normal and closest point of each kind, and how
the normal turns with the tip (the geometry of eq 6's penetration and normal direction).

Plane and cylinder here; the triangle mesh in ``mesh_contact.py``; sphere, capsule, ellipsoid and
baked grids in ``sdf.py`` (which reads a surface as its float64 row, ``records.surface_floats``).
A surface is a ``records.SURFACE`` record, its kind one of ``records.SURF_*``.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT
from .mesh_contact import mesh_gap
from .records import (
    SURF_CAPSULE,
    SURF_CYLINDER,
    SURF_ELLIPSOID,
    SURF_FLOATS,
    SURF_GRID,
    SURF_MESH,
    SURF_PLANE,
    SURF_SPHERE,
)
from .sdf import (
    capsule_gap,
    ellipsoid_gap,
    ellipsoid_rate,
    grid_gap,
    grid_rate,
    round_rate,
    sphere_gap,
)


@njit(**HOT, inline="always")
def _floats(surf, s):
    """Surface s as the float64 row sdf.py's kernels read (kind's slot, a, b, radius)."""
    return surf.view(np.float64)[SURF_FLOATS * s : SURF_FLOATS * (s + 1)]


@njit(**HOT)
def surface_gap(surf, s, pt, nrm, cpt, mesh, sdf):
    """Signed distance from the sphere centre to the surface (>0 outside), normal, closest point
    (plane, cylinder, triangle mesh here; the SDF kinds in ``sdf.py``)."""
    srf = surf[s]
    kind = srf.kind
    if kind == SURF_MESH:
        return mesh_gap(pt, srf.radius, mesh, nrm, cpt)
    if kind == SURF_GRID:
        return grid_gap(srf.grid, sdf, pt, nrm, cpt)
    if kind == SURF_SPHERE:
        return sphere_gap(_floats(surf, s), pt, nrm, cpt)
    if kind == SURF_CAPSULE:
        return capsule_gap(_floats(surf, s), pt, nrm, cpt)
    if kind == SURF_ELLIPSOID:
        return ellipsoid_gap(_floats(surf, s), pt, nrm, cpt)
    if kind == SURF_PLANE:
        for a in range(3):
            nrm[a] = srf.b[a]
        d = 0.0
        for a in range(3):
            d += (pt[a] - srf.a[a]) * nrm[a]
        for a in range(3):
            cpt[a] = pt[a] - d * nrm[a]
        return d
    # cylinder (outer surface)
    rel0 = pt[0] - srf.a[0]
    rel1 = pt[1] - srf.a[1]
    rel2 = pt[2] - srf.a[2]
    ax = rel0 * srf.b[0] + rel1 * srf.b[1] + rel2 * srf.b[2]
    r0 = rel0 - ax * srf.b[0]
    r1 = rel1 - ax * srf.b[1]
    r2 = rel2 - ax * srf.b[2]
    rr = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if rr < 1e-12:
        rr = 1e-12
    nrm[0] = r0 / rr
    nrm[1] = r1 / rr
    nrm[2] = r2 / rr
    for a in range(3):
        cpt[a] = srf.a[a] + ax * srf.b[a] + srf.radius * nrm[a]
    return rr - srf.radius


@njit(**HOT)
def normal_rate(surf, s, pt, nrm, gap, sdf, J, gd):
    """How the contact geometry moves with the sphere centre, after ``_surface_gap`` gave
    (gap, nrm) at pt: gd <- d gap / d pt [-] and J <- d nrm / d pt [1/mm].

    J carries the curvature term Fn dn/dpt of the contact force Fn n: a tip pressed on a crown of
    radius r has a tangential stiffness of ~Fn / r (0.03 N/mm at 0.1 N on 3 mm), tens of times
    the bristle's own bending stiffness at its tip, so a Newton tangent without it turns the
    normal force against the bristle at each iterate.  Exact for the analytic kinds; the grid's
    is the derivative of its interpolation (what the residual sees).  Plane and triangle mesh:
    J = 0 (flat faces; a mesh's edges and vertices are left out) and gd = n."""
    kind = surf[s].kind
    if kind == SURF_GRID:  # sets both
        grid_rate(surf[s].grid, sdf, pt, J, gd)
        return
    for a in range(3):  # exact distances: their gradient is the normal
        gd[a] = nrm[a]
    if kind == SURF_SPHERE:
        round_rate(_floats(surf, s), 0, pt, nrm, gap, J)
    elif kind == SURF_CAPSULE:
        round_rate(_floats(surf, s), 1, pt, nrm, gap, J)
    elif kind == SURF_CYLINDER:
        round_rate(_floats(surf, s), 2, pt, nrm, gap, J)
    elif kind == SURF_ELLIPSOID:
        ellipsoid_rate(_floats(surf, s), nrm, gap, J)
    else:
        for a in range(3):
            for b in range(3):
                J[a, b] = 0.0
