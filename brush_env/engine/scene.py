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

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import tomllib

from .checks import Limit, check_keys, check_real
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
        a, b, c, d = (
            idx[:-1, :-1].ravel(),
            idx[1:, :-1].ravel(),
            idx[1:, 1:].ravel(),
            idx[:-1, 1:].ravel(),
        )
        T = np.vstack([np.column_stack([a, b, c]), np.column_stack([a, c, d])])  # normals +z
        return V, T


@dataclass(frozen=True)
class ContactParams:
    """Contact parameters of the paper's Table 2 (tip sphere - surface: normal law eq 6 and
    stick-slip friction eqs 7-10) and Table 3 (tip - tip: normal law, no friction).

    Units: k [N/mm^m1], c [N s/mm^(m2) / mm^(m3)], exponents [-], v [mm/s], delta_max [mm].
    Defaults are the tables' values.  In a scene file: the ``[contact]`` table, same keys."""

    k: float = 100.0  # Table 2 k_con: normal stiffness [N/mm^m1]
    m1: float = 1.3  # Table 2 m1: stiffness exponent [-]
    c: float = 0.2  # Table 2 c_con: damping coefficient [N s/mm]
    m2: float = 1.0  # Table 2 m2: damping (velocity) exponent [-]
    m3: float = 2.0  # Table 2 m3: indentation exponent of the damping [-]
    mu_s: float = 0.8  # Table 2 mu_s: static (stiction) friction coefficient [-]
    mu_d: float = 0.76  # Table 2 mu_d: dynamic (sliding) friction coefficient [-]
    v_s: float = 1.2  # Table 2 v_s: stiction transition speed [mm/s]
    v_d: float = 1.5  # Table 2 v_d: sliding transition speed [mm/s]
    delta_max: float = 0.1  # Table 2 Delta: largest stiction deformation [mm]
    k_tt: float = 100.0  # Table 3 k_con: tip-tip normal stiffness [N/mm^m1]
    m1_tt: float = 1.3  # Table 3 m1 [-]
    c_tt: float = 0.2  # Table 3 c_con: tip-tip damping [N s/mm]
    m2_tt: float = 1.0  # Table 3 m2 [-]
    m3_tt: float = 2.0  # Table 3 m3 [-]

    def __post_init__(self):
        for f in fields(self):
            check_real(f"contact.{f.name}", getattr(self, f.name), CONTACT_LIMITS[f.name])

    def as_array(self) -> np.ndarray:
        """The kernels' parameter vector (contact.C_* columns), in the order of the fields."""
        return np.array([getattr(self, f.name) for f in fields(self)], dtype=float)


_STIFF = Limit("N/mm^m1", gt=0, le=1e7)
_EXP = Limit("dimensionless exponent", ge=0.5, le=4)
_DAMP = Limit("N s/mm", ge=0, le=1e4)
CONTACT_LIMITS = dict(
    k=_STIFF,
    m1=Limit("dimensionless exponent", ge=1, le=4),
    c=_DAMP,
    m2=_EXP,
    m3=Limit("dimensionless exponent", ge=0, le=4),
    mu_s=Limit("dimensionless", ge=0, le=5),
    mu_d=Limit("dimensionless", ge=0, le=5),
    v_s=Limit("mm/s", gt=0, le=1e3),
    v_d=Limit("mm/s", gt=0, le=1e3),
    delta_max=Limit("mm", gt=0, le=10),
    k_tt=_STIFF,
    m1_tt=Limit("dimensionless exponent", ge=1, le=4),
    c_tt=_DAMP,
    m2_tt=_EXP,
    m3_tt=Limit("dimensionless exponent", ge=0, le=4),
)


@dataclass(frozen=True)
class Scene:
    """A brush and its environment.  ``surfaces`` empty means a free brush (no contact);
    ``contact`` the parameters of Tables 2-3."""

    brush: BrushConfig
    surfaces: tuple = field(default_factory=tuple)
    tip_tip: bool = True
    name: str = ""
    tip_travel_fraction: float = 0.6
    contact: ContactParams = field(default_factory=ContactParams)


def load_scene(path_or_name=None, *, brush=None) -> Scene:
    """Load ``configs/scenes/<name>.toml`` (default ``flat_plate``); ``brush`` overrides the
    file's."""
    p = (
        Path(path_or_name)
        if path_or_name and ("/" in str(path_or_name) or str(path_or_name).endswith(".toml"))
        else configs_dir() / "scenes" / f"{path_or_name or 'flat_plate'}.toml"
    )
    if not p.exists():
        raise ConfigError(f"scene {str(path_or_name)!r}: no such file {p}")
    data = tomllib.loads(p.read_text())
    check_keys(str(p), data, ("name", "brush", "tip_tip", "surface", "contact"))
    table = data.get("contact", {})
    check_keys(f"{p} [contact]", table, [f.name for f in fields(ContactParams)])
    try:
        contact = ContactParams(**table)
    except ConfigError as e:
        raise ConfigError(f"{p}: {e}") from None
    if brush is None:
        brush = load_brush(data.get("brush", "default"))
    elif not isinstance(brush, BrushConfig):
        brush = load_brush(brush)
    surfaces = []
    for j, s in enumerate(data.get("surface", [])):
        kind = s.get("kind", "plane")
        if kind == "plane":
            surfaces.append(
                Plane(tuple(s.get("point_mm", (0, 0, 0))), tuple(s.get("normal", (0, 0, 1))))
            )
        elif kind == "mesh_plate":
            surfaces.append(
                MeshPlate(
                    tuple(s.get("point_mm", (0, 0, 0))),
                    float(s.get("size_mm", 80.0)),
                    int(s.get("divisions", 16)),
                )
            )
        elif kind == "cylinder":
            surfaces.append(
                Cylinder(
                    tuple(s.get("point_mm", (0, 0, -5))),
                    tuple(s.get("axis", (1, 0, 0))),
                    float(s.get("radius_mm", 5.0)),
                )
            )
        else:
            raise ConfigError(
                f"{p}: surface[{j}].kind = {kind!r}: must be one of "
                "['plane', 'mesh_plate', 'cylinder']"
            )
    return Scene(
        brush,
        tuple(surfaces),
        bool(data.get("tip_tip", True)),
        data.get("name", p.stem),
        contact=contact,
    )
