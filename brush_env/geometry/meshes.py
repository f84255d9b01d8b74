"""Triangle meshes from files (STL, OBJ, PLY, ... through trimesh) for SDF surfaces (issue 13).

``load_mesh_file(path, units)`` returns the vertices [mm] and triangles of a *closed* (watertight),
consistently oriented mesh, turned outward if it was inside out.  Errors name the file and say
what is wrong: not a mesh, not closed (with the number of open edges), inconsistent winding, or a
size that does not look like a tooth in the stated units (e.g. a file in metres read as mm).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from brush_env.engine.checks import ConfigError

#: length of one unit in mm
UNITS = {"mm": 1.0, "cm": 10.0, "m": 1000.0, "um": 1e-3, "in": 25.4}
#: plausible largest extent of a brushing surface [mm]: a tooth (~7 mm) up to a dental arch
EXTENT_MM = (1.0, 200.0)


def load_mesh_file(path, units: str = "mm") -> tuple[np.ndarray, np.ndarray]:
    """(V (nv, 3) [mm], T (nt, 3)) of the closed mesh in ``path`` whose coordinates are in
    ``units`` (one of UNITS)."""
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
    if mesh.volume < 0:  # inside out: the SDF's sign needs outward triangles
        T = T[:, ::-1].copy()
    return V, T
