"""Scenes: a brush plus the surfaces it can touch and which contact groups exist.

Scene files live in ``configs/scenes/*.toml``::

    name = "flat_plate"
    brush = "default"                 # name in configs/brushes or a path
    tip_tip = true                    # tip-tip contact between neighbouring bristles (Table 3)
    shaft_contact = true              # every body's capsule touches the surfaces (shaft.py)
    head_contact = true               # report the head's clearance (the env stops at contact)
    [[surface]]
    kind = "plane"                    # see SURFACE_KINDS
    point_mm = [0, 0, 0]
    normal = [0, 0, 1]

Surface kinds and their keys (mm):

* ``plane`` point_mm, normal; ``cylinder`` point_mm, axis, radius_mm (a normal or an axis is a
  direction: any non-zero length is normalised, zero or non-finite is refused); ``mesh_plate``
  point_mm, size_mm, divisions (an exact closest-triangle query);
* signed distance fields (``sdf.py``): ``sphere`` center_mm, radius_mm; ``capsule`` a_mm, b_mm,
  radius_mm; ``ellipsoid`` center_mm, semi_axes_mm; ``mesh`` file (relative to the scene file),
  units ("mm"), cell_mm (0.15), band_mm (1.0), place ("auto": bounding box centred in x, y and
  its top at z = 0; "as_is"), baked into a grid;
* ``tooth_row`` (``teeth.py``): teeth (["PM1", "PM2", "M1", "M2"]), gap_mm (0.7), cell_mm, band_mm,
  gum (true), gum_radius_mm (8): one baked crown per tooth and a gum capsule.

Several surfaces form their union (the tip touches the deepest).  Each surface has a ``label``
(``StepResult.extra["tip_surface"]`` gives the index of the surface each tip touches).
Contact laws default to the paper's Tables 2 and 3 (see ``contact.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np

from ..geometry.sdf_bake import bake_mesh_cached, check_grid_size
from .checks import Limit, check_keys, check_real, type_error
from .config import BrushConfig, ConfigError, load_brush
from .config_files import read_toml, resolve_config
from .records import (
    CONTACT_LAW,
    SURF_CAPSULE,
    SURF_CYLINDER,
    SURF_ELLIPSOID,
    SURF_MESH,
    SURF_PLANE,
    SURF_SPHERE,
    surface_row,
)


@dataclass(frozen=True)
class Plane:
    """Infinite plane through ``point`` [mm] with unit outward ``normal`` (world)."""

    point: tuple = (0.0, 0.0, 0.0)
    normal: tuple = (0.0, 0.0, 1.0)

    def __post_init__(self):
        check_direction("plane.normal", self.normal)

    def kernel_row(self):
        n = np.asarray(self.normal, float)
        return surface_row(SURF_PLANE, self.point, n / np.linalg.norm(n))


@dataclass(frozen=True)
class Cylinder:
    """Outer surface of an infinite cylinder (a tooth-like convex patch): a point on its axis
    [mm], the axis direction and the radius [mm]."""

    point: tuple = (0.0, 0.0, -5.0)
    axis: tuple = (1.0, 0.0, 0.0)
    radius: float = 5.0

    def __post_init__(self):
        check_direction("cylinder.axis", self.axis)

    def kernel_row(self):
        a = np.asarray(self.axis, float)
        return surface_row(SURF_CYLINDER, self.point, a / np.linalg.norm(a), self.radius)


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
        return surface_row(SURF_MESH, radius=2.0)  # search radius [mm] (> tip radius)

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
class Sphere:
    """Outside of a sphere: ``center`` [mm], ``radius`` [mm] (analytic SDF)."""

    center: tuple = (0.0, 0.0, -5.0)
    radius: float = 5.0
    label: str = "sphere"

    def kernel_row(self):
        return surface_row(SURF_SPHERE, self.center, radius=self.radius)


@dataclass(frozen=True)
class Capsule:
    """Points within ``radius`` [mm] of the segment ``a``-``b`` [mm] (analytic SDF)."""

    a: tuple = (-10.0, 0.0, -5.0)
    b: tuple = (10.0, 0.0, -5.0)
    radius: float = 5.0
    label: str = "capsule"

    def kernel_row(self):
        return surface_row(SURF_CAPSULE, self.a, self.b, self.radius)


@dataclass(frozen=True)
class Ellipsoid:
    """Axis-aligned ellipsoid: ``center`` [mm], ``semi_axes`` [mm] (exact distance, sdf.py)."""

    center: tuple = (0.0, 0.0, -5.0)
    semi_axes: tuple = (8.0, 6.0, 5.0)
    label: str = "ellipsoid"

    def kernel_row(self):
        return surface_row(SURF_ELLIPSOID, self.center, self.semi_axes)


@dataclass(frozen=True, eq=False)
class MeshSurface:
    """A closed triangle mesh (``vertices`` [mm], ``triangles``), baked into a narrow-band SDF grid
    of cell ``cell`` [mm] and half-width ``band`` [mm] (sdf.py; cached on disk)."""

    vertices: np.ndarray
    triangles: np.ndarray
    cell: float = 0.15
    band: float = 1.0
    label: str = "mesh"

    def __post_init__(self):
        if not (0.01 <= self.cell <= 2.0):
            raise ConfigError(f"{self.label}: cell_mm = {self.cell!r}: must be in [0.01, 2] (mm)")
        if not (2 * self.cell <= self.band <= 10.0):
            raise ConfigError(
                f"{self.label}: band_mm = {self.band!r}: must be in [2 cell_mm, 10] (mm)"
            )
        check_grid_size(self.vertices, self.cell, self.band, self.label)

    def sdf_grid(self):
        return bake_mesh_cached(self.vertices, self.triangles, self.cell, self.band)

    def exact_query(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(d (n,), normal (n, 3)) at points (n, 3) [mm] by the exact closest-triangle search
        (``mesh_contact.mesh_gap``): the validation path of the baked grid."""
        from .mesh_contact import build_mesh, mesh_query

        return mesh_query(build_mesh(self.vertices, self.triangles), points, self.band)


SDF_KINDS = (Sphere, Capsule, Ellipsoid, MeshSurface)


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
        if self.mu_s < self.mu_d:  # stiction holds at least what sliding does (eqs 7-10)
            raise ConfigError(
                f"contact.mu_s = {self.mu_s!r} is out of range: must be >= contact.mu_d = "
                f"{self.mu_d!r} (static friction is at least the dynamic one; dimensionless)"
            )

    def as_array(self) -> np.ndarray:
        """The kernels' contact laws: one ``records.CONTACT_LAW`` record (shape (1,)), whose fields
        are this class's fields."""
        return np.array([tuple(float(getattr(self, f.name)) for f in fields(self))], CONTACT_LAW)


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
    ``contact`` the parameters of Tables 2-3.  ``shaft_contact``: every body of a bristle is a
    capsule in contact with the surfaces (``shaft.py``), not only the tip spheres;
    ``head_contact``: the engine reports the head's clearance to the surfaces
    (``StepResult.extra["head_clearance"]``).  Both off for a scene built in code, on by default
    in a scene file (``load_scene``)."""

    brush: BrushConfig
    surfaces: tuple = field(default_factory=tuple)
    tip_tip: bool = True
    name: str = ""
    tip_travel_fraction: float = 0.6
    contact: ContactParams = field(default_factory=ContactParams)
    shaft_contact: bool = False
    head_contact: bool = False


def _check_scene_keys(p: Path, data: dict) -> None:
    """The scene file's brush, tip_tip and name keys, checked whether or not the caller
    overrides the brush (the CLI and ``gym.make`` refuse the same files)."""
    if "brush" in data:
        if not isinstance(data["brush"], str):
            raise ConfigError(f"{p}: {type_error('brush', data['brush'], 'a brush name or path')}")
        try:
            resolve_config("brush", data["brush"])
        except ConfigError as e:
            raise ConfigError(f"{p}: brush = {data['brush']!r}: {e}") from None
    if not isinstance(data.get("tip_tip", True), bool):
        raise ConfigError(f"{p}: {type_error('tip_tip', data['tip_tip'], 'true or false')}")
    if not isinstance(data.get("name", ""), str):
        raise ConfigError(f"{p}: {type_error('name', data['name'], 'a string')}")


def load_scene(path_or_name=None, *, brush=None) -> Scene:
    """Load ``configs/scenes/<name>.toml`` (default ``flat_plate``); ``brush`` overrides the
    file's."""
    p = resolve_config("scene", path_or_name)
    data = read_toml(p)  # a syntax error (a duplicated key, ...) names the file
    check_keys(
        str(p),
        data,
        ("name", "brush", "tip_tip", "surface", "contact", "shaft_contact", "head_contact"),
    )
    _check_scene_keys(p, data)
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
    for j, srf in enumerate(data.get("surface", [])):
        try:
            surfaces.extend(surfaces_from_table(srf, p.parent, f"surface[{j}]"))
        except (ConfigError, ValueError, TypeError) as e:
            raise ConfigError(f"{p}: {e}") from None
    return Scene(
        brush,
        tuple(surfaces),
        bool(data.get("tip_tip", True)),
        data.get("name", p.stem),
        contact=contact,
        shaft_contact=bool(data.get("shaft_contact", True)),
        head_contact=bool(data.get("head_contact", True)),
    )


SURFACE_KEYS = {
    "plane": ("point_mm", "normal"),
    "mesh_plate": ("point_mm", "size_mm", "divisions"),
    "cylinder": ("point_mm", "axis", "radius_mm"),
    "sphere": ("center_mm", "radius_mm"),
    "capsule": ("a_mm", "b_mm", "radius_mm"),
    "ellipsoid": ("center_mm", "semi_axes_mm"),
    "mesh": ("file", "units", "cell_mm", "band_mm", "place"),
    "tooth_row": ("teeth", "gap_mm", "cell_mm", "band_mm", "gum", "gum_radius_mm"),
}
_POS = Limit("mm", gt=0, le=1e4)


def check_direction(where: str, value) -> None:
    """A surface's direction (plane normal, cylinder axis): 3 finite numbers, not all zero.  Any
    other length is accepted and normalised (only the direction counts)."""
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ConfigError(f"{where} = {value!r} is invalid: must be 3 finite numbers")
    if float(np.linalg.norm(v)) < 1e-12:
        raise ConfigError(
            f"{where} = {value!r} is invalid: must be a non-zero 3-vector (its direction is "
            "used; any non-zero length is normalised)"
        )


def _vec3(where: str, value) -> tuple:
    v = np.asarray(value, dtype=float)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ConfigError(f"{where} = {value!r}: must be 3 finite numbers")
    return tuple(float(x) for x in v)


def surfaces_from_table(t: dict, base: Path, where: str = "surface") -> list:
    """The surface(s) one ``[[surface]]`` table describes (a tooth row gives several)."""
    kind = t.get("kind", "plane")
    if kind not in SURFACE_KEYS:
        raise ConfigError(f"{where}.kind = {kind!r}: must be one of {sorted(SURFACE_KEYS)}")
    check_keys(where, t, ("kind", "label", *SURFACE_KEYS[kind]))
    label = str(t.get("label", kind))
    for key in ("normal", "axis"):  # a plane's normal, a cylinder's axis: refused if zero
        if key in t:
            check_direction(f"{where}.{key}", t[key])
    if kind == "plane":
        return [
            Plane(
                _vec3(f"{where}.point_mm", t.get("point_mm", (0, 0, 0))),
                _vec3(f"{where}.normal", t.get("normal", (0, 0, 1))),
            )
        ]
    if kind == "mesh_plate":
        return [
            MeshPlate(
                _vec3(f"{where}.point_mm", t.get("point_mm", (0, 0, 0))),
                float(t.get("size_mm", 80.0)),
                int(t.get("divisions", 16)),
            )
        ]
    if kind == "cylinder":
        return [
            Cylinder(
                _vec3(f"{where}.point_mm", t.get("point_mm", (0, 0, -5))),
                _vec3(f"{where}.axis", t.get("axis", (1, 0, 0))),
                check_real(f"{where}.radius_mm", t.get("radius_mm", 5.0), _POS),
            )
        ]
    if kind == "sphere":
        return [
            Sphere(
                _vec3(f"{where}.center_mm", t.get("center_mm", (0, 0, -5))),
                check_real(f"{where}.radius_mm", t.get("radius_mm", 5.0), _POS),
                label,
            )
        ]
    if kind == "capsule":
        return [
            Capsule(
                _vec3(f"{where}.a_mm", t.get("a_mm", (-10, 0, -5))),
                _vec3(f"{where}.b_mm", t.get("b_mm", (10, 0, -5))),
                check_real(f"{where}.radius_mm", t.get("radius_mm", 5.0), _POS),
                label,
            )
        ]
    if kind == "ellipsoid":
        ax = _vec3(f"{where}.semi_axes_mm", t.get("semi_axes_mm", (8, 6, 5)))
        for a in ax:
            check_real(f"{where}.semi_axes_mm", a, _POS)
        return [Ellipsoid(_vec3(f"{where}.center_mm", t.get("center_mm", (0, 0, -5))), ax, label)]
    cell = check_real(f"{where}.cell_mm", t.get("cell_mm", 0.15), Limit("mm", ge=0.01, le=2.0))
    band = check_real(f"{where}.band_mm", t.get("band_mm", 1.0), Limit("mm", ge=2 * cell, le=10))
    if kind == "mesh":
        if "file" not in t:
            raise ConfigError(f"{where}: kind 'mesh' needs file = PATH")
        path = Path(t["file"])
        path = path if path.is_absolute() else base / path
        return [
            mesh_surface(
                path,
                t.get("units", "mm"),
                cell,
                band,
                t.get("place", "auto"),
                label if "label" in t else "mesh",
            )
        ]
    return tooth_row_surfaces(
        teeth=tuple(t.get("teeth", ("PM1", "PM2", "M1", "M2"))),
        gap_mm=check_real(f"{where}.gap_mm", t.get("gap_mm", 0.7), Limit("mm", ge=0.0, le=5.0)),
        cell=cell,
        band=band,
        gum=bool(t.get("gum", True)),
        gum_radius=check_real(
            f"{where}.gum_radius_mm", t.get("gum_radius_mm", 8.0), Limit("mm", ge=2.0, le=50.0)
        ),
    )


def mesh_surface(path, units="mm", cell=0.15, band=1.0, place="auto", label="mesh"):
    """A user's closed mesh file as a baked SDF surface; ``place="auto"`` centres its bounding box
    in x, y and puts its highest point at z = 0 (where the brush starts over a plate)."""
    from ..geometry.meshes import load_mesh_file

    if place not in ("auto", "as_is"):
        raise ConfigError(f"mesh place = {place!r}: must be 'auto' or 'as_is'")
    V, T = load_mesh_file(path, units, tooth=label.startswith("tooth"))
    if place == "auto":
        lo, hi = V.min(axis=0), V.max(axis=0)
        V = V - np.array([0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1]), hi[2]])
    try:
        return MeshSurface(V, T, cell, band, label)
    except ConfigError as e:  # the grid's size: name the file
        raise ConfigError(f"mesh = {str(path)!r}: {e}") from None


def tooth_row_surfaces(
    teeth=("PM1", "PM2", "M1", "M2"), gap_mm=0.7, cell=0.15, band=1.0, gum=True, gum_radius=8.0
) -> list:
    """The procedural tooth row of ``teeth.py``: one baked crown per tooth (label
    ``tooth:<name>``) and the gum capsule (label ``gum``)."""
    from ..geometry import teeth as tt

    specs = tt.row_specs(teeth, gap_mm)
    out: list = []
    for s in specs:
        V, T = tt.tooth_mesh(s)
        out.append(MeshSurface(V, T, cell, band, f"tooth:{s.name}"))
    if gum:
        a, b, r = tt.gum_capsule(specs, gum_radius)
        out.append(Capsule(a, b, r, "gum"))
    return out


def surface_labels(scene) -> list[str]:
    """Label of each surface of ``scene`` (its kind where it has none)."""
    return [getattr(s, "label", type(s).__name__.lower()) for s in scene.surfaces]


def tooth_surfaces(scene) -> list:
    """The crowns of a scene: its SDF mesh surfaces labelled ``tooth:...``."""
    return [s for s in scene.surfaces if isinstance(s, MeshSurface) and s.label.startswith("tooth")]


def with_mesh(scene, path, units="mm", cell=0.15, band=1.0) -> Scene:
    """``scene`` with its tooth crowns (labels ``tooth:*``, or every SDF mesh) replaced by the
    user's mesh file, placed as ``mesh_surface(place="auto")`` does; the gum and other surfaces
    stay."""
    from dataclasses import replace

    keep = [s for s in scene.surfaces if not isinstance(s, MeshSurface)]
    user = mesh_surface(path, units, cell, band, "auto", "tooth:user")
    return replace(scene, surfaces=tuple([user, *keep]))
