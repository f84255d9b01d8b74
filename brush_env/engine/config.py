"""Brush and material configs: TOML data files -> validated, frozen dataclasses.

Units everywhere: mm, N, s, tonne. Young's modulus E in MPa (= N/mm^2), density in t/mm^3, lengths
in mm, angles in rad inside the dataclasses (degrees in the TOML files, keys ending ``_deg``).

Frames: the *head frame* has its origin on the head plane (z = 0, where bristle roots sit), +x along
the handle (long axis of the head) and +z along the bristles, i.e. from the robot flange toward the
plate. The head frame is placed in the TCP frame by ``head_offset`` and the fixed-axis
roll/pitch/yaw ``head_rpy`` (R = Rz(yaw) Ry(pitch) Rx(roll)).

Every bad value raises :class:`ConfigError` naming the key path, the value and the allowed range,
e.g. ``brush.grid[1].length_mm = -2.0 is out of range: must be > 0 and <= 100 (mm)``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any, cast

import numpy as np

from ..geometry.footprints import min_root_gap
from .checks import (
    ConfigError,
    Limit,
    check_int,
    check_real,
    check_unit,
    check_vec,
    type_error,
)
from .config_files import (
    REQUIRED,
    Table,
    apply_overrides,
    configs_dir,
    in_file,
    materials_path,
    read_toml,
    resolve_config,
)

__all__ = [
    "ConfigError",
    "Limit",
    "LIMITS",
    "Material",
    "Section",
    "BristleConfig",
    "BrushConfig",
    "configs_dir",
    "load_materials",
    "load_brush",
]


#: The allowed ranges, one place for both the loaders and the dataclass constructors.
#: [deg] default imperfection of a "straight" bristle (BrushConfig.imperfection): 0.01 deg, a tip
#: offset of L/5700 -- well inside a manufactured bristle's straightness, large enough to pick
#: the buckling direction within a few growth times of the mode
IMPERFECTION_DEG = 0.01

LIMITS: dict[str, Limit] = {
    "E": Limit("MPa", gt=0, le=1e6),
    "nu": Limit("dimensionless", gt=-1, lt=0.5),
    "density": Limit("t/mm^3", gt=0, le=1e-7),
    "damping_ratio": Limit("dimensionless", ge=0, le=2),
    "section": Limit("mm", gt=0, le=20),
    "length": Limit("mm", gt=0, le=100),
    "bodies": Limit("count", ge=1, le=200),
    "tip_radius": Limit("mm; at most min(5 mm, bristle length)", gt=0, le=5),
    "pitch": Limit("mm", gt=0, le=50),
    "count": Limit("count", ge=1, le=1000),
    "position": Limit("mm, head frame", ge=-100, le=100),
    "offset": Limit("mm, TCP frame", ge=-1000, le=1000),
    "angle_deg": Limit("deg", ge=-360, le=360),
    "lean_deg": Limit("deg", ge=-10, le=10),
    "lean": Limit("rad", ge=-math.radians(10), le=math.radians(10)),
    "imperfection_deg": Limit("deg", ge=0, le=1),
    "imperfection": Limit("rad", ge=0, le=math.radians(1)),
    "angle": Limit("rad", ge=-2 * math.pi, le=2 * math.pi),
    "direction": Limit("dimensionless direction, head frame"),
}

_PARALLEL_TOL = 1e-6


Vec3 = tuple[float, float, float]


def _frame(path: str, axis: Any, width_dir: Any) -> tuple[Vec3, Vec3]:
    """Unit bristle axis and width direction (Gram-Schmidt against the axis)."""
    a = check_unit(f"{path}.axis", axis)
    w = check_unit(f"{path}.width_dir", width_dir)
    w = w - a * float(a @ w)
    if np.linalg.norm(w) < _PARALLEL_TOL:
        raise ConfigError(
            f"{path}.width_dir = {list(width_dir)!r} is invalid: must not be parallel to "
            f"axis = {list(axis)!r} (need |sin(angle)| > {_PARALLEL_TOL:g})"
        )
    return cast(Vec3, tuple(a.tolist())), cast(Vec3, tuple((w / np.linalg.norm(w)).tolist()))


def _set(obj: Any, **fields: Any) -> None:
    for k, v in fields.items():
        object.__setattr__(obj, k, v)


# ------------------------------------------------------------------------------------- dataclasses
@dataclass(frozen=True)
class Material:
    """Isotropic linear-elastic bristle material.

    E [MPa = N/mm^2], nu [-], density [t/mm^3], damping_ratio [-] (ratio of critical damping used
    for the stiffness-proportional beam damping).
    """

    name: str
    E: float
    nu: float
    density: float
    damping_ratio: float
    description: str = field(default="", repr=False)

    def __post_init__(self) -> None:
        p = f"Material({self.name!r})"
        _set(
            self,
            **{
                k: check_real(f"{p}.{k}", getattr(self, k), LIMITS[k])
                for k in ("E", "nu", "density", "damping_ratio")
            },
        )

    @property
    def G(self) -> float:
        """Shear modulus [MPa] = E / (2 (1 + nu))."""
        return self.E / (2.0 * (1.0 + self.nu))


SECTION_KINDS = ("rect", "circle")


@dataclass(frozen=True)
class Section:
    """Constant bristle cross-section [mm].

    rect: ``width`` b along the bristle's local y axis (its ``width_dir``), ``thickness`` h along
    local z (axis x width_dir). circle: width == thickness == diameter.
    """

    kind: str
    width: float
    thickness: float

    def __post_init__(self) -> None:
        if self.kind not in SECTION_KINDS:
            raise ConfigError(
                f"Section.kind = {self.kind!r} is not allowed (allowed: {', '.join(SECTION_KINDS)})"
            )
        b = check_real("Section.width", self.width, LIMITS["section"])
        h = check_real("Section.thickness", self.thickness, LIMITS["section"])
        if self.kind == "circle" and b != h:
            raise ConfigError(f"Section.thickness = {h!r} must equal width = {b!r} for a circle")
        _set(self, width=b, thickness=h)

    @classmethod
    def rect(cls, b: float, h: float) -> Section:
        """Rectangle b [mm] (local y) x h [mm] (local z)."""
        return cls("rect", b, h)

    @classmethod
    def circle(cls, d: float) -> Section:
        """Circle of diameter d [mm]."""
        return cls("circle", d, d)

    @property
    def area(self) -> float:
        """Area [mm^2]."""
        b, h = self.width, self.thickness
        return b * h if self.kind == "rect" else math.pi * b * b / 4.0

    @property
    def I_y(self) -> float:
        """Second moment about local y, ∫z² dA [mm^4] (bending that deflects along local z)."""
        b, h = self.width, self.thickness
        return b * h**3 / 12.0 if self.kind == "rect" else math.pi * b**4 / 64.0

    @property
    def I_z(self) -> float:
        """Second moment about local z, ∫y² dA [mm^4] (bending that deflects along local y)."""
        b, h = self.width, self.thickness
        return h * b**3 / 12.0 if self.kind == "rect" else math.pi * b**4 / 64.0

    @property
    def J(self) -> float:
        """Saint-Venant torsion constant [mm^4]: circle π d⁴/32; rectangle by Roark's formula."""
        if self.kind == "circle":
            return math.pi * self.width**4 / 32.0
        a, c = max(self.width, self.thickness) / 2.0, min(self.width, self.thickness) / 2.0
        return a * c**3 * (16.0 / 3.0 - 3.36 * (c / a) * (1.0 - c**4 / (12.0 * a**4)))

    def shear_coeff(self, nu: float) -> float:
        """Cowper's shear coefficient κ [-] for Poisson ratio ``nu`` (shear area = κ A)."""
        if self.kind == "rect":
            return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)
        return 6.0 * (1.0 + nu) / (7.0 + 6.0 * nu)

    @property
    def polar_radius_sq(self) -> float:
        """(I_y + I_z) / A [mm^2]: axial mass moment of inertia per unit mass."""
        b, h = self.width, self.thickness
        return (b * b + h * h) / 12.0 if self.kind == "rect" else b * b / 8.0


@dataclass(frozen=True)
class BristleConfig:
    """One bristle, in the head frame.

    root [mm] on the head, axis (unit, root -> tip), width_dir (unit, ⟂ axis: the section's width
    direction, local y), length [mm], bodies (rigid bodies of the discrete flexible model),
    tip_radius [mm] of the contact sphere, group (name of the layout entry it came from).
    """

    root: tuple[float, float, float]
    axis: tuple[float, float, float]
    width_dir: tuple[float, float, float]
    length: float
    section: Section
    material: Material
    bodies: int
    tip_radius: float
    group: str = ""

    def __post_init__(self) -> None:
        p = "BristleConfig"
        if not isinstance(self.section, Section):
            raise type_error(f"{p}.section", self.section, "a Section")
        if not isinstance(self.material, Material):
            raise type_error(f"{p}.material", self.material, "a Material")
        axis, width_dir = _frame(p, self.axis, self.width_dir)
        length = check_real(f"{p}.length", self.length, LIMITS["length"])
        _set(
            self,
            root=check_vec(f"{p}.root", self.root, 3, LIMITS["position"]),
            axis=axis,
            width_dir=width_dir,
            length=length,
            bodies=check_int(f"{p}.bodies", self.bodies, LIMITS["bodies"]),
            tip_radius=check_real(f"{p}.tip_radius", self.tip_radius, _tip_limit(length)),
        )

    @property
    def thickness_dir(self) -> tuple[float, float, float]:
        """Unit local z = axis × width_dir (the section's thickness direction), head frame."""
        return tuple(np.cross(self.axis, self.width_dir).tolist())


def _tip_limit(length: float) -> Limit:
    return replace(LIMITS["tip_radius"], le=min(cast(float, LIMITS["tip_radius"].le), length))


def _rotation(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) (fixed-axis x-y-z) [rad]."""
    cr, sr, cp, sp, cy, sy = (
        math.cos(roll),
        math.sin(roll),
        math.cos(pitch),
        math.sin(pitch),
        math.cos(yaw),
        math.sin(yaw),
    )
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


@dataclass(frozen=True)
class BrushConfig:
    """A brush head: its bristles (head frame) and the head's pose in the TCP frame.

    head_offset [mm, TCP frame], head_rpy [rad, fixed-axis roll/pitch/yaw of the head relative to
    the TCP], bristles, source (file the config came from, plus any overrides).
    """

    name: str
    head_offset: tuple[float, float, float]
    head_rpy: tuple[float, float, float]
    bristles: tuple[BristleConfig, ...]
    source: str = ""
    lean: float = 0.0  # [rad] initial lean of every bristle toward its thickness direction
    #: [rad] the smallest lean a bristle is modelled with (a straight bristle is never perfectly
    #: straight): a |lean| below it becomes this imperfection, toward +thickness (or the lean's
    #: sign), so that a pressed "straight" bristle buckles as a real one does instead of holding
    #: the unstable straight column (docs/model.md).  Brush files default to IMPERFECTION_DEG
    #: (key imperfection_deg); a BrushConfig built in code is the geometry as given (0: the
    #: perfect column, as the closed-form validations need)
    imperfection: float = 0.0

    def __post_init__(self) -> None:
        LIMITS["lean"].check("BrushConfig.lean", self.lean)
        LIMITS["imperfection"].check("BrushConfig.imperfection", self.imperfection)
        bristles = tuple(self.bristles)
        if not bristles:
            raise ConfigError("BrushConfig.bristles is empty: need at least 1 bristle")
        for i, b in enumerate(bristles):
            if not isinstance(b, BristleConfig):
                raise type_error(f"BrushConfig.bristles[{i}]", b, "a BristleConfig")
        _set(
            self,
            head_offset=check_vec("BrushConfig.head_offset", self.head_offset, 3, LIMITS["offset"]),
            head_rpy=check_vec("BrushConfig.head_rpy", self.head_rpy, 3, LIMITS["angle"]),
            bristles=bristles,
        )

    @property
    def n_bristles(self) -> int:
        return len(self.bristles)

    @property
    def max_length(self) -> float:
        """Longest bristle [mm]."""
        return max(b.length for b in self.bristles)

    @property
    def effective_lean(self) -> float:
        """The lean [rad] the model uses: ``lean``, or the imperfection if |lean| is smaller."""
        if abs(self.lean) >= self.imperfection:
            return self.lean
        return math.copysign(self.imperfection, self.lean if self.lean != 0.0 else 1.0)

    def with_bodies(self, n: int) -> BrushConfig:
        """Copy with every bristle discretised into ``n`` bodies."""
        return replace(self, bristles=tuple(replace(b, bodies=n) for b in self.bristles))

    def with_material(self, material: Material) -> BrushConfig:
        """Copy with every bristle made of ``material``."""
        return replace(self, bristles=tuple(replace(b, material=material) for b in self.bristles))

    def head_rotation(self) -> np.ndarray:
        """3x3 rotation of the head frame in the TCP frame, Rz(yaw) Ry(pitch) Rx(roll)."""
        return _rotation(*self.head_rpy)

    def roots_tcp(self) -> np.ndarray:
        """(n, 3) bristle root positions [mm] in the TCP frame."""
        roots = np.array([b.root for b in self.bristles])
        return np.asarray(self.head_offset) + roots @ self.head_rotation().T

    def axes_tcp(self) -> np.ndarray:
        """(n, 3) unit bristle axes in the TCP frame."""
        return np.array([b.axis for b in self.bristles]) @ self.head_rotation().T

    def width_dirs_tcp(self) -> np.ndarray:
        """(n, 3) unit section width directions in the TCP frame."""
        return np.array([b.width_dir for b in self.bristles]) @ self.head_rotation().T

    def min_root_gap(self) -> tuple[float, int, int]:
        """Smallest clearance [mm] between two bristles' root cross-sections, and that pair.

        Footprints are the root cross-sections projected along head z onto the head plane (circles
        as discs of their diameter). The clearance is the separating-axis gap over the footprints'
        edge normals and the centre line: exact for rectangles sharing their edge directions,
        conservative otherwise; <= 0 means the sections overlap. (inf, -1, -1) for one bristle.
        """
        return min_root_gap(self.bristles)

    def min_tip_gap(self) -> tuple[float, int, int]:
        """Smallest clearance [mm] between two tip spheres of the straight brush at rest (centre
        distance minus both radii, head frame), and that pair; < 0 means they overlap.
        (inf, -1, -1) when no two tips are within reach of each other (or one bristle).  Ties:
        the first pair in (i, j) order."""
        tips = np.array([np.add(b.root, np.multiply(b.length, b.axis)) for b in self.bristles])
        r = np.array([b.tip_radius for b in self.bristles])
        reach = 2.0 * float(r.max())
        if len(tips) <= TIP_PAIRS_DIRECT:
            # every pair at once: importing scipy.spatial for its k-d tree cost ~0.5 s of every
            # start (a brush loads on every run), more than a few thousand distances
            d = np.linalg.norm(tips[:, None, :] - tips[None, :, :], axis=2)
            i, j = np.nonzero(np.triu(d <= reach, k=1))
        else:
            from scipy.spatial import cKDTree

            pairs = cKDTree(tips).query_pairs(reach, output_type="ndarray").reshape(-1, 2)
            pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]  # (i, j) order, as above
            i, j = pairs[:, 0], pairs[:, 1]
        if len(i) == 0:
            return math.inf, -1, -1
        gap = np.linalg.norm(tips[i] - tips[j], axis=1) - r[i] - r[j]
        k = int(np.argmin(gap))
        return float(gap[k]), int(min(i[k], j[k])), int(max(i[k], j[k]))


#: brushes of at most this many bristles find their nearest tips from every pair's distance
#: (``BrushConfig.min_tip_gap``; 512 bristles: 0.26 M distances, a 6 MB temporary); larger ones by
#: a k-d tree
TIP_PAIRS_DIRECT = 512

# ------------------------------------------ TOML -> configs (files and tables: config_files.py)
_read_toml = read_toml  # fidelity.py's name for it (it cannot import config_files on this branch)

MATERIAL_KEYS = ("E_MPa", "nu", "density_t_per_mm3", "damping_ratio", "description")


def load_materials(path: str | os.PathLike | None = None) -> dict[str, Material]:
    """Materials by name from a TOML file (default ``configs/materials.toml``).

    Each table ``[<name>]`` has E_MPa [MPa], nu [-], density_t_per_mm3 [t/mm^3], damping_ratio [-]
    and an optional description.
    """
    path = materials_path(path)
    data = read_toml(path)
    try:
        return {name: _material(name, table) for name, table in data.items()}
    except ConfigError as e:
        raise in_file(path, e) from None


def _material(name: str, data: Any) -> Material:
    t = Table(data, f"material {name!r}", MATERIAL_KEYS)
    return Material(
        name=name,
        E=t.num("E_MPa", LIMITS["E"]),
        nu=t.num("nu", LIMITS["nu"]),
        density=t.num("density_t_per_mm3", LIMITS["density"]),
        damping_ratio=t.num("damping_ratio", LIMITS["damping_ratio"]),
        description=t.str("description", ""),
    )


BRUSH_KEYS = (
    "name",
    "material",
    "materials_file",
    "bodies_per_bristle",
    "tip_radius_mm",
    "head_offset_mm",
    "head_rpy_deg",
    "lean_deg",
    "imperfection_deg",
    "sections",
    "grid",
    "row",
    "bristle",
)
_EXTRAS = ("axis", "width_dir", "material", "bodies", "tip_radius_mm", "name")
GROUP_KEYS = {
    "grid": ("section", "length_mm", "nx", "ny", "pitch_x_mm", "pitch_y_mm", "center_mm") + _EXTRAS,
    "row": ("section", "length_mm", "n", "start_mm", "step_mm") + _EXTRAS,
    "bristle": ("section", "length_mm", "root_mm") + _EXTRAS,
}
SECTION_KEYS = {"rect": ("kind", "width_mm", "thickness_mm"), "circle": ("kind", "diameter_mm")}


def load_brush(
    path_or_name: str | os.PathLike | None = None,
    *,
    materials: Mapping[str, Material] | None = None,
    overrides: Mapping[str, Any] | None = None,
) -> BrushConfig:
    """Load and validate a brush config.

    ``path_or_name``: a path to a TOML file, or a bare name such as ``"default"`` meaning
    ``configs/brushes/<name>.toml`` (default: ``"default"``). ``materials``: materials by name
    (default: the file's ``materials_file``, relative to the brush file, else
    ``configs/materials.toml``). ``overrides``: values merged into the TOML data before validation,
    as nested tables and/or dotted keys, e.g. ``{"bodies_per_bristle": 3,
    "sections.outer.thickness_mm": 1.0, "grid[1].length_mm": 11.0}``.
    """
    path = resolve_config("brush", path_or_name)
    data = read_toml(path)
    source = str(path)
    try:
        if overrides:
            apply_overrides(data, overrides)
            source += f" with overrides {dict(overrides)!r}"
        t = Table(data, "brush", BRUSH_KEYS)
        mfile = t.str("materials_file", None, what="path relative to the brush file")
        if materials is None:
            materials = load_materials(path.parent / mfile if mfile else None)
        brush = _brush(t, dict(materials), source)
    except ConfigError as e:
        raise in_file(path, e) from None
    gap, i, j = brush.min_root_gap()
    if gap <= 0:
        bi, bj = brush.bristles[i], brush.bristles[j]
        raise ConfigError(
            f"{path}: brush layout: bristle {i} (group {bi.group!r}) at {bi.root} and bristle {j} "
            f"(group {bj.group!r}) at {bj.root} overlap at the root: clearance = {gap:.4g}, "
            f"must be > 0 (mm); check pitch/step/root positions against the section sizes"
        )
    gap, i, j = brush.min_tip_gap()
    if gap < 0:
        bi, bj = brush.bristles[i], brush.bristles[j]
        dist = gap + bi.tip_radius + bj.tip_radius
        raise ConfigError(
            f"{path}: brush layout: the tip spheres of bristle {i} (group {bi.group!r}, "
            f"tip_radius_mm = {bi.tip_radius:g}) and bristle {j} (group {bj.group!r}, "
            f"tip_radius_mm = {bj.tip_radius:g}) overlap by {-gap:.4g} mm at rest (tips "
            f"{dist:.4g} mm apart): the two radii must sum to <= {dist:.4g} mm (equal tips: "
            f"tip_radius_mm <= {dist / 2:.4g} mm); tip spheres must not overlap at rest"
        )
    return brush


def _brush(t: Table, materials: dict[str, Material], source: str) -> BrushConfig:
    name = t.str("name")
    default_material = t.str("material", choices=materials, what="material")
    bodies = t.int("bodies_per_bristle", LIMITS["bodies"])
    tip_radius = t.num("tip_radius_mm", LIMITS["tip_radius"])
    head_offset = t.vec("head_offset_mm", 3, LIMITS["offset"], (0.0, 0.0, 0.0))
    head_rpy = t.vec("head_rpy_deg", 3, LIMITS["angle_deg"], (0.0, 0.0, 0.0))
    lean = t.num("lean_deg", LIMITS["lean_deg"], 0.0)
    imperfection = t.num("imperfection_deg", LIMITS["imperfection_deg"], IMPERFECTION_DEG)
    secs = t.get("sections", REQUIRED, "[sections.<name>] tables")
    if not isinstance(secs, dict):
        raise type_error(t.key("sections"), secs, "a table of [sections.<name>] tables")
    sections = {k: _section(t.key(f"sections.{k}"), v) for k, v in secs.items()}
    if not sections:
        raise ConfigError(f"{t.key('sections')}: no sections defined (need at least one)")

    defaults = dict(material=default_material, bodies=bodies, tip_radius=tip_radius)
    bristles: list[BristleConfig] = []
    for kind in GROUP_KEYS:
        entries = t.get(kind, [], f"an array of [[{kind}]] tables")
        if not isinstance(entries, list):
            raise type_error(t.key(kind), entries, f"an array of [[{kind}]] tables")
        for idx, entry in enumerate(entries):
            g = Table(entry, t.key(f"{kind}[{idx}]"), GROUP_KEYS[kind])
            bristles += _group(kind, idx, g, sections, materials, defaults)
    if not bristles:
        raise ConfigError("brush: no bristles: add at least one [[grid]], [[row]] or [[bristle]]")
    return BrushConfig(
        name,
        head_offset,
        cast(Vec3, tuple(math.radians(a) for a in head_rpy)),
        tuple(bristles),
        source,
        math.radians(lean),
        math.radians(imperfection),
    )


def _section(path: str, data: Any) -> Section:
    kind = Table(data, path, ("kind", "width_mm", "thickness_mm", "diameter_mm")).str(
        "kind", choices=SECTION_KINDS, what="section kind"
    )
    t = Table(data, path, SECTION_KEYS[kind])
    if kind == "circle":
        return Section.circle(t.num("diameter_mm", LIMITS["section"]))
    return Section.rect(
        t.num("width_mm", LIMITS["section"]), t.num("thickness_mm", LIMITS["section"])
    )


def _group(
    kind: str,
    idx: int,
    g: Table,
    sections: dict[str, Section],
    materials: dict[str, Material],
    defaults: dict,
) -> list[BristleConfig]:
    """The bristles of one [[grid]], [[row]] or [[bristle]] entry."""
    section = sections[g.str("section", choices=sections, what="section")]
    length = g.num("length_mm", LIMITS["length"])
    material = g.str("material", defaults["material"], choices=materials, what="material")
    bodies = g.int("bodies", LIMITS["bodies"], defaults["bodies"])
    if "tip_radius_mm" in g.data:
        tip = g.num("tip_radius_mm", _tip_limit(length))
    else:
        tip = check_real(
            f"brush.tip_radius_mm (used by {g.path})", defaults["tip_radius"], _tip_limit(length)
        )
    axis, width_dir = _frame(
        g.path,
        g.vec("axis", 3, LIMITS["direction"], (0.0, 0.0, 1.0)),
        g.vec("width_dir", 3, LIMITS["direction"], (1.0, 0.0, 0.0)),
    )
    pos = LIMITS["position"]
    if kind == "grid":
        nx, ny = g.int("nx", LIMITS["count"]), g.int("ny", LIMITS["count"])
        px = g.num("pitch_x_mm", LIMITS["pitch"], None if nx == 1 else REQUIRED) or 0.0
        py = g.num("pitch_y_mm", LIMITS["pitch"], None if ny == 1 else REQUIRED) or 0.0
        cx, cy = g.vec("center_mm", 2, pos)
        roots = [
            (cx + (ix - (nx - 1) / 2) * px, cy + (iy - (ny - 1) / 2) * py, 0.0)
            for iy in range(ny)
            for ix in range(nx)
        ]
    elif kind == "row":
        n = g.int("n", LIMITS["count"])
        sx, sy = g.vec("start_mm", 2, pos)
        dx, dy = g.vec("step_mm", 2, pos, None if n == 1 else REQUIRED) or (0.0, 0.0)
        roots = [(sx + k * dx, sy + k * dy, 0.0) for k in range(n)]
    else:
        roots = [g.vec("root_mm", 3, pos)]
    for k, r in enumerate(roots):
        for c, v in zip("xyz", r):
            pos.check(f"{g.path} bristle {k} root {c}", v)
    group = g.str("name", f"{kind}[{idx}]")
    return [
        BristleConfig(r, axis, width_dir, length, section, materials[material], bodies, tip, group)
        for r in roots
    ]
