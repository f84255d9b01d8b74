"""Scenes: a brush plus the surfaces it can touch and which contact groups exist.

Scene files live in ``configs/scenes/*.toml``::

    name = "flat_plate"
    brush = "default"                 # name in configs/brushes or a path
    tip_tip = true                    # tip-tip contact between neighbouring bristles (Table 3)
    [[surface]]
    kind = "plane"                    # "plane" | "mesh_plate" | "cylinder"
    point_mm = [0, 0, 0]
    normal = [0, 0, 1]

Contact laws default to the paper's Tables 2 and 3 (see ``contact.py``).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .config import BrushConfig, ConfigError, configs_dir, load_brush


@dataclass(frozen=True)
class Plane:
    """Infinite plane through ``point`` [mm] with unit outward ``normal`` (world)."""

    point: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)

    def kernel_row(self):
        n = np.asarray(self.normal, float)
        return np.r_[0.0, self.point, n / np.linalg.norm(n), 0.0]


@dataclass(frozen=True)
class Cylinder:
    """Outer surface of an infinite cylinder (a tooth-like convex patch): a point on its axis
    [mm], the axis direction and the radius [mm]."""

    point: tuple = (0.0, 0.0, -5.0)
    axis: tuple = (1.0, 0.0, 0.0)
    radius: float = 5.0

    def kernel_row(self):
        a = np.asarray(self.axis, float)
        return np.r_[1.0, self.point, a / np.linalg.norm(a), self.radius]


@dataclass(frozen=True)
class MeshPlate:
    """A flat square plate as a triangle mesh (the paper meshed its plate, Sec. 3): centre
    ``point`` [mm], normal +z, side ``size`` [mm], ``divisions`` squares per side (2 triangles
    each).  Contact uses the closest point on the triangles near the tip (uniform-grid index)."""

    point: tuple = (0.0, 0.0, 0.0)
    size: float = 80.0
    divisions: int = 16

    def __post_init__(self):
        if not (self.size > 0 and np.isfinite(self.size)):
            raise ConfigError(f"mesh_plate.size_mm = {self.size!r}: must be > 0 (mm)")
        if not (1 <= int(self.divisions) <= 1000):
            raise ConfigError(f"mesh_plate.divisions = {self.divisions!r}: must be in [1, 1000]")

    def kernel_row(self):
        return np.r_[2.0, 2.0, np.zeros(6)]  # kind, search radius [mm] (> tip radius)

    def triangles(self):
        n = int(self.divisions)
        g = np.linspace(-0.5 * self.size, 0.5 * self.size, n + 1)
        X, Y = np.meshgrid(g, g, indexing="ij")
        V = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)]) + np.asarray(self.point)
        idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
        a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), \
            idx[:-1, 1:].ravel()
        T = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])  # normals +z
        return V, T


@dataclass(frozen=True)
class Scene:
    """A brush and its environment.  ``surfaces`` empty means a free brush (no contact)."""

    brush: BrushConfig
    surfaces: tuple = field(default_factory=tuple)
    tip_tip: bool = True
    name: str = ""
    tip_travel_fraction: float = 0.6


def load_scene(path_or_name=None, *, brush=None) -> Scene:
    """Load ``configs/scenes/<name>.toml`` (default ``flat_plate``); ``brush`` overrides the file's."""
    p = Path(path_or_name) if path_or_name and ("/" in str(path_or_name) or
                                                 str(path_or_name).endswith(".toml")) \
        else configs_dir() / "scenes" / f"{path_or_name or 'flat_plate'}.toml"
    if not p.exists():
        raise ConfigError(f"scene {str(path_or_name)!r}: no such file {p}")
    data = tomllib.loads(p.read_text())
    allowed = {"name", "brush", "tip_tip", "surface"}
    for k in data:
        if k not in allowed:
            raise ConfigError(f"{p}: unknown key {k!r} (allowed: {', '.join(sorted(allowed))})")
    if brush is None:
        brush = load_brush(data.get("brush", "default"))
    elif not isinstance(brush, BrushConfig):
        brush = load_brush(brush)
    surfaces = []
    for j, s in enumerate(data.get("surface", [])):
        kind = s.get("kind", "plane")
        if kind == "plane":
            surfaces.append(Plane(tuple(s.get("point_mm", (0, 0, 0))), tuple(s.get("normal", (0, 0, 1)))))
        elif kind == "mesh_plate":
            surfaces.append(MeshPlate(tuple(s.get("point_mm", (0, 0, 0))),
                                      float(s.get("size_mm", 80.0)), int(s.get("divisions", 16))))
        elif kind == "cylinder":
            surfaces.append(Cylinder(tuple(s.get("point_mm", (0, 0, -5))),
                                     tuple(s.get("axis", (1, 0, 0))), float(s.get("radius_mm", 5.0))))
        else:
            raise ConfigError(f"{p}: surface[{j}].kind = {kind!r}: must be one of "
                              "['plane', 'mesh_plate', 'cylinder']")
    return Scene(brush, tuple(surfaces), bool(data.get("tip_tip", True)), data.get("name", p.stem))
