"""How far points lie from a scene's surfaces, for checks before a run starts (issue 28): a start
pose whose tip spheres would begin inside a surface is refused instead of stepped.

``surface_gaps(surfaces, points)`` is the signed distance [mm] of each point from each surface
(> 0 outside), by the same geometry the contact kernels use: planes and cylinders exactly,
spheres and capsules exactly, ellipsoids by a bound with the right sign, baked meshes through
their grid (``SdfGrid.query``), a mesh plate by its closest-triangle search.
``deepest_tip(scene, tips, radii)`` is the deepest tip sphere's penetration.  Units: mm.
"""

from __future__ import annotations

import numpy as np

from .mesh_contact import build_mesh, mesh_query
from .scene import Capsule, Cylinder, Ellipsoid, MeshPlate, Plane, Sphere

__all__ = ["deepest_tip", "surface_gaps"]

#: [mm] a point farther than this from a triangle-mesh plate counts as far outside
_MESH_SEARCH = 20.0


def _gap(srf, P: np.ndarray) -> np.ndarray:
    """Signed distance (n,) [mm] of the points P (n, 3) from one surface (> 0 outside)."""
    if isinstance(srf, Plane):
        n = np.asarray(srf.normal, float)
        return (P - np.asarray(srf.point, float)) @ (n / np.linalg.norm(n))
    if isinstance(srf, Cylinder):
        a = np.asarray(srf.axis, float)
        a = a / np.linalg.norm(a)
        rel = P - np.asarray(srf.point, float)
        return np.linalg.norm(rel - np.outer(rel @ a, a), axis=1) - srf.radius
    if isinstance(srf, Sphere):
        return np.linalg.norm(P - np.asarray(srf.center, float), axis=1) - srf.radius
    if isinstance(srf, Capsule):
        a, b = np.asarray(srf.a, float), np.asarray(srf.b, float)
        ab = b - a
        s = np.clip((P - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
        return np.linalg.norm(P - (a + s[:, None] * ab), axis=1) - srf.radius
    if isinstance(srf, Ellipsoid):  # (|q| - 1) min(semi-axes): the sign is exact
        ax = np.asarray(srf.semi_axes, float)
        q = np.linalg.norm((P - np.asarray(srf.center, float)) / ax, axis=1)
        return (q - 1.0) * float(ax.min())
    if isinstance(srf, MeshPlate):
        d, _ = mesh_query(build_mesh(*srf.triangles()), P, _MESH_SEARCH)
        return np.minimum(d, 1e300)
    if hasattr(srf, "sdf_grid"):
        return srf.sdf_grid().query(P)[0]
    return np.full(len(P), np.inf)


def surface_gaps(surfaces, points) -> np.ndarray:
    """(n, ns) signed distance [mm] of each point (n, 3) from each surface (> 0 outside)."""
    P = np.atleast_2d(np.asarray(points, float))
    if not surfaces:
        return np.full((len(P), 0), np.inf)
    return np.stack([_gap(s, P) for s in surfaces], axis=1)


def deepest_tip(scene, tips, radii) -> tuple[float, int, int]:
    """(depth [mm], tip, surface): how deep the deepest tip sphere (centres ``tips`` (n, 3),
    ``radii`` (n,)) sinks into a surface of ``scene`` (<= 0: every tip is clear), which tip and
    which surface (-1, -1 without surfaces)."""
    gaps = surface_gaps(scene.surfaces, tips)
    if gaps.shape[1] == 0:
        return -np.inf, -1, -1
    pen = np.asarray(radii, float)[:, None] - gaps
    i, j = np.unravel_index(int(np.argmax(pen)), pen.shape)
    return float(pen[i, j]), int(i), int(j)
