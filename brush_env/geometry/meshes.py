"""Triangle meshes from files (STL, OBJ, PLY, ... through trimesh) for SDF surfaces (issue 13).

``load_mesh_file(path, units)`` returns the vertices [mm] and triangles of a *closed* (watertight),
consistently oriented mesh, turned outward if it was inside out.  Errors name the file and say
what is wrong: not a mesh, not closed (with the number of open edges), inconsistent winding, a
surface that intersects itself (two triangles without a common vertex crossing), or a size that
does not look like a brushing surface in the stated units (e.g. a file in metres read as mm).

The size rules (units plausibility): every mesh's largest extent lies in ``EXTENT_MM`` (a tooth up
to a dental arch); a *tooth* mesh (``tooth=True``: one that replaces the tooth row's crowns,
``--mesh``) also has its smallest extent in ``TOOTH_THINNEST_MM``: a crown is 5-12 mm in every
direction, and a row or an arch model is at least one crown thick, so a crown mesh ~10x too small
or too large (a file in cm read as mm) is refused with the units that would fit.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numba import njit

from brush_env.engine.checks import ConfigError

#: length of one unit in mm
UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "um": 1e-3, "in": 25.4}
#: plausible largest extent of a brushing surface [mm]: a tooth (~7 mm) up to a dental arch
EXTENT_MM = (1.0, 200.0)
#: plausible smallest extent of a tooth mesh [mm]: a thin lower incisor crown (~5 mm) up to a
#: jaw model's height
TOOTH_THINNEST_MM = (4.0, 40.0)


def load_mesh_file(path, units: str = "mm", tooth: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(V (nv, 3) [mm], T (nt, 3)) of the closed mesh in ``path`` whose coordinates are in
    ``units`` (one of UNITS); ``tooth``: the mesh stands for teeth (the size rules of the module
    docstring)."""
    import trimesh

    p = Path(path)
    if units not in UNITS:
        raise ConfigError(f"mesh units = {units!r}: must be one of {sorted(UNITS)}")
    if not p.is_file():
        raise ConfigError(f"mesh = {str(path)!r}: no such file")
    try:
        mesh = trimesh.load(p, force="mesh", process=True)
    except Exception as e:  # trimesh raises many types for unreadable files
        raise ConfigError(
            f"mesh = {str(path)!r}: cannot be read as a triangle mesh ({e})"
        ) from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise ConfigError(f"mesh = {str(path)!r}: holds no triangles")
    if not mesh.is_watertight:
        edges = trimesh.grouping.group_rows(mesh.edges_sorted, require_count=1)
        raise ConfigError(
            f"mesh = {str(path)!r}: not closed ({len(edges)} open edges): the contact needs "
            "an inside and an outside (fill the holes, e.g. trimesh.repair.fill_holes)"
        )
    if not mesh.is_winding_consistent:
        raise ConfigError(
            f"mesh = {str(path)!r}: triangle winding is inconsistent (fix with "
            "trimesh.repair.fix_winding)"
        )
    V = np.asarray(mesh.vertices, float) * UNITS[units]
    T = np.asarray(mesh.faces, np.int64)
    ext = float(np.ptp(V, axis=0).max())
    if not EXTENT_MM[0] <= ext <= EXTENT_MM[1]:
        hint = ""
        for u, f in UNITS.items():
            if u != units and EXTENT_MM[0] <= ext / UNITS[units] * f <= EXTENT_MM[1]:
                size = ext / UNITS[units] * f
                hint = f"; read as {u!r} it would be {size:.3g} mm (--mesh-units {u})"
                break
        raise ConfigError(
            f"mesh = {str(path)!r}: largest extent {ext:.4g} mm with units = {units!r} is outside "
            f"[{EXTENT_MM[0]:g}, {EXTENT_MM[1]:g}] mm, the size of a tooth up to an arch{hint}"
        )
    if tooth:
        _check_tooth_size(path, units, np.ptp(V, axis=0))
    a, b = first_crossing(V, T)
    if a >= 0:
        at = ", ".join(f"{x:.4g}" for x in V[T[a]].mean(axis=0))
        raise ConfigError(
            f"mesh = {str(path)!r}: the surface intersects itself (triangles {a} and {b} cross "
            f"near ({at}) mm): the contact needs one closed surface without overlapping parts "
            "(merge them with a boolean union)"
        )
    if mesh.volume < 0:  # inside out: the SDF's sign needs outward triangles
        T = T[:, ::-1].copy()
    return V, T


def _check_tooth_size(path, units: str, ext: np.ndarray) -> None:
    """A tooth mesh's smallest extent [mm] in TOOTH_THINNEST_MM (module docstring)."""
    lo, hi = TOOTH_THINNEST_MM
    thin = float(ext.min())
    if lo <= thin <= hi:
        return
    hint = ""
    for u, f in UNITS.items():
        scaled = ext / UNITS[units] * f
        if u != units and lo <= scaled.min() <= hi and EXTENT_MM[0] <= scaled.max() <= EXTENT_MM[1]:
            hint = f"; read as {u!r} it would be {scaled.min():.3g} mm (--mesh-units {u})"
            break
    raise ConfigError(
        f"mesh = {str(path)!r}: as a tooth mesh its smallest extent is {thin:.4g} mm with "
        f"units = {units!r}, outside [{lo:g}, {hi:g}] mm (a crown is 5-12 mm thick in every "
        f"direction; a row or an arch at least one crown){hint}"
    )


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def _segment_hits(p, q, a, b, c) -> bool:
    """Whether the segment p-q meets the triangle abc (Moeller-Trumbore; parallel: no)."""
    e1 = b - a
    e2 = c - a
    d = q - p
    h = np.cross(d, e2)
    det = e1 @ h
    if abs(det) < 1e-14 * (1.0 + (e1 @ e1) * (d @ d)):
        return False
    f = 1.0 / det
    s = p - a
    u = f * (s @ h)
    if u < 0.0 or u > 1.0:
        return False
    qv = np.cross(s, e1)
    v = f * (d @ qv)
    if v < 0.0 or u + v > 1.0:
        return False
    t = f * (e2 @ qv)
    return 0.0 <= t <= 1.0


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def first_crossing(V, T):
    """(a, b): two triangles without a common vertex that cross (an edge of one through the
    other), or (-1, -1).  Sweep and prune along x, then bounding boxes, then the edge tests."""
    nt = T.shape[0]
    P = np.empty((nt, 3, 3))
    for t in range(nt):
        for k in range(3):
            P[t, k] = V[T[t, k]]
    lo = np.empty((nt, 3))
    hi = np.empty((nt, 3))
    for t in range(nt):
        for a in range(3):
            lo[t, a] = min(P[t, 0, a], min(P[t, 1, a], P[t, 2, a]))
            hi[t, a] = max(P[t, 0, a], max(P[t, 1, a], P[t, 2, a]))
    order = np.argsort(lo[:, 0])
    for ii in range(nt):
        i = order[ii]
        for jj in range(ii + 1, nt):
            j = order[jj]
            if lo[j, 0] > hi[i, 0]:
                break
            if lo[j, 1] > hi[i, 1] or lo[i, 1] > hi[j, 1]:
                continue
            if lo[j, 2] > hi[i, 2] or lo[i, 2] > hi[j, 2]:
                continue
            if _pair_crosses(T, P, i, j):
                return min(i, j), max(i, j)
    return -1, -1


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def _pair_crosses(T, P, i, j) -> bool:
    """Triangles i and j share no vertex and an edge of one passes through the other."""
    for k in range(3):
        for m in range(3):
            if T[i, k] == T[j, m]:
                return False
    for k in range(3):
        k2 = (k + 1) % 3
        if _segment_hits(P[i, k], P[i, k2], P[j, 0], P[j, 1], P[j, 2]):
            return True
        if _segment_hits(P[j, k], P[j, k2], P[i, 0], P[i, 1], P[i, 2]):
            return True
    return False
