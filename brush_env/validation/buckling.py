"""``validate buckling``: one bristle pressed onto a flat plate, the engine against the rod.

The case (issue 11): a straight bristle of rectangular section ``width`` x ``thickness`` [mm],
length ``length`` [mm], Young's modulus ``E`` [MPa], Poisson ratio ``nu``, clamped at a lean
``lean_deg`` from the plate normal (bending about the thin direction), tip sphere of radius
``radius`` [mm] touching the plate z = 0.  The clamp descends slowly (``speed`` mm/s, BDF2 at
``dt``) and holds at each target until the bristle has settled (``hold`` s, many times the first
mode's decay time): a quasi-static press that follows the stable branch, as a real press does
(a static Newton solve from the straight bristle may converge to the unstable straight column).
The compression is

    delta = descent of the clamp after touch - tip penetration  [mm],

the shortening of the sphere centre's height.  ``tip = "free"``: frictionless plate (the tip
slides freely); ``"pinned"``: a sticking tip (Table 2's friction law with mu_s = mu_d = 5 and
Delta_max = 1 um, so the tip moves about 1 um sideways at most).  Computed: the plate's normal force
[N] and the tip's sideways shift [mm] from its touch point.  Reference: the planar geometrically
exact rod with shear and extension (``validation.rod``), at the engine's delta.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from functools import lru_cache

import numpy as np

from ..engine import (
    BristleConfig,
    BrushConfig,
    Material,
    Plane,
    Scene,
    Section,
    SimSettings,
    Simulator,
)
from ..engine.checks import Limit, check_choice, check_int, check_real
from ..engine.config import IMPERFECTION_DEG
from ..engine.scene import ContactParams
from .rod import buckled_bristle

R_DOWN = np.diag([1.0, -1.0, -1.0])  # TCP pointing the bristle down onto the plate
TIPS = ("free", "pinned")
#: contact tables of the two tip conditions (Table 2 otherwise)
TIP_CONTACT = {
    "free": dict(mu_s=0.0, mu_d=0.0),
    "pinned": dict(mu_s=5.0, mu_d=5.0, delta_max=1e-3),
}


@dataclass(frozen=True)
class BucklingCase:
    """One pressed bristle: geometry [mm], material [MPa, -], lean [deg], tip condition, bodies,
    element formulation, the imperfection of a straight bristle [deg] (BrushConfig.imperfection);
    the press: clamp speed [mm/s], settling time at each target [s], time step [s]."""

    length: float = 10.0
    width: float = 1.8
    thickness: float = 0.8
    E: float = 7.0
    nu: float = 0.48
    radius: float = 0.44
    lean_deg: float = 1.0
    tip: str = "free"
    bodies: int = 6
    element: str = "mid"
    imperfection_deg: float = IMPERFECTION_DEG
    speed: float = 2.0
    hold: float = 0.15
    dt: float = 1e-3

    def __post_init__(self):
        for k, lim in (
            ("length", Limit("mm", gt=0, le=100)),
            ("width", Limit("mm", gt=0, le=10)),
            ("thickness", Limit("mm", gt=0, le=10)),
            ("E", Limit("MPa", gt=0, le=1e6)),
            ("nu", Limit("", ge=0, lt=0.5)),
            ("radius", Limit("mm", gt=0, le=5)),
            ("lean_deg", Limit("deg", ge=0, le=10)),
            ("imperfection_deg", Limit("deg", ge=0, le=1)),
            ("speed", Limit("mm/s", gt=0, le=100)),
            ("hold", Limit("s", gt=0, le=10)),
            ("dt", Limit("s", gt=0, le=5e-3)),
        ):
            check_real(f"buckling.{k}", getattr(self, k), lim)
        check_int("buckling.bodies", self.bodies, Limit("", ge=1, le=200))
        check_choice("buckling.tip", self.tip, TIPS, "tip condition")

    def scene(self) -> Scene:
        section = Section.rect(self.width, self.thickness)
        material = Material(
            name="validation", E=self.E, nu=self.nu, density=1.15e-9, damping_ratio=0.1
        )
        br = BristleConfig(
            root=(0.0, 0.0, 0.0),
            axis=(0, 0, 1),
            width_dir=(1, 0, 0),
            length=self.length,
            section=section,
            material=material,
            bodies=self.bodies,
            tip_radius=self.radius,
        )
        brush = BrushConfig(
            name="buckling",
            head_offset=(0, 0, 0),
            head_rpy=(0, 0, 0),
            bristles=(br,),
            lean=math.radians(self.lean_deg),
            imperfection=math.radians(self.imperfection_deg),
        )
        plate = Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0))
        return Scene(brush, (plate,), contact=ContactParams(**TIP_CONTACT[self.tip]))


def press(case: BucklingCase, compressions) -> dict:
    """Quasi-static press of ``case`` to each compression in ``compressions`` [mm] (ascending).

    For each target the clamp moves to descent = target + penetration (of the last settled
    state) at ``case.speed`` and holds ``case.hold`` s, twice (the second pass corrects for the
    change of penetration).  Returns arrays: delta [mm] (the compression reached, descent minus
    penetration, within ~1e-4 mm of the target), force_N, tip_shift_mm, penetration_mm, descent_mm,
    newton (iterations spent on the target)."""
    targets = np.asarray(compressions, float)
    if targets.ndim != 1 or np.any(np.diff(targets) <= 0) or targets[0] <= 0:
        raise ValueError(f"compressions = {compressions!r}: must be positive and ascending (mm)")
    settings = SimSettings(dt=case.dt, element=case.element, gravity=(0.0, 0.0, 0.0))
    sim = Simulator(case.scene(), settings)
    z0 = sim.touch_height(R_DOWN, 0.0)
    res = sim.reset(np.array([0.0, 0.0, z0]), R_DOWN)
    x_touch = res.tip_pos[0, :2].copy()
    rows = []
    descent = 0.0
    vstep = case.speed * case.dt
    nhold = int(round(case.hold / case.dt))
    for target in targets:
        iters = 0
        for _ in range(2):
            goal = target + _pen(res)
            nmove = max(1, int(math.ceil(abs(goal - descent) / vstep)))
            path = np.concatenate(
                [descent + (goal - descent) * np.arange(1, nmove + 1) / nmove, np.full(nhold, goal)]
            )
            for d in path:
                res = sim.step(np.array([0.0, 0.0, z0 - d]), R_DOWN)
                iters += res.iterations
            descent = goal
        shift = np.linalg.norm(res.tip_pos[0, :2] - x_touch)
        rows.append(
            (descent - _pen(res), res.tip_normal_force[0], shift, _pen(res), descent, iters)
        )
    a = np.array(rows)
    keys = ("delta", "force_N", "tip_shift_mm", "penetration_mm", "descent_mm", "newton")
    return {k: a[:, j] for j, k in enumerate(keys)}


def _pen(res) -> float:
    return float(res.tip_penetration[0]) if res.tip_in_contact[0] else 0.0


#: compressions [mm] of the acceptance cases (issue 11: 0.25-3 mm)
COMPRESSIONS = (0.25, 0.5, 1.0, 2.0, 3.0)
_H = 2e-3  # [mm] spacing of the reference's interpolation stencil around each compression


@lru_cache(maxsize=64)
def _reference_stencil(geometry: tuple, lean_deg: float, tip: str, model: str, targets: tuple):
    """The rod's force and tip shift at target - h, target, target + h (for each target): one
    continuation pass, reused by every run of the same bristle, tip and lean."""
    length, width, thickness, E, nu, radius = geometry
    pts = np.sort(np.concatenate([np.asarray(targets) + k * _H for k in (-1, 0, 1)]))
    r = buckled_bristle(
        pts,
        length=length,
        width=width,
        thickness=thickness,
        E=E,
        nu=nu,
        lean_deg=lean_deg,
        tip=tip,
        radius=radius,
        model=model,
    )
    return pts, np.asarray(r["force_N"], float), np.asarray(r["tip_shift_mm"], float)


def _reference_at(case: BucklingCase, model: str, targets, deltas) -> dict:
    """The rod (``model`` "reissner" or "elastica") at the engine's compressions ``deltas``
    (each within ``_H`` of its target): quadratic interpolation on the stencil (error ~1e-9)."""
    geometry = (case.length, case.width, case.thickness, case.E, case.nu, case.radius)
    lean = math.degrees(case.scene().brush.effective_lean)
    pts, F, X = _reference_stencil(geometry, lean, case.tip, model, tuple(targets))
    out = {"force_N": [], "tip_shift_mm": []}
    for t, d in zip(targets, deltas, strict=True):
        if abs(d - t) > _H:
            raise RuntimeError(f"compression {d:.6f} mm is not within {_H} mm of {t} mm")
        j = int(np.argmin(np.abs(pts - t)))
        u = (d - pts[j]) / _H
        for key, y in (("force_N", F), ("tip_shift_mm", X)):
            y0, y1, y2 = y[j - 1], y[j], y[j + 1]
            out[key].append(float(y1 + 0.5 * u * (y2 - y0) + 0.5 * u * u * (y2 - 2 * y1 + y0)))
    return out


def buckling(case: BucklingCase, compressions=COMPRESSIONS) -> dict:
    """The engine's pressed bristle against the rod reference (Reissner; the elastica as a second
    column): JSON-able dict with settings, computed / reference / elastica / rel_error, each
    holding force_N and tip_shift_mm per compression (rel_error of the shift only for the free
    tip; a pinned tip's reference shift is 0, its computed shift is reported in mm)."""
    comp = press(case, compressions)
    targets = tuple(float(c) for c in compressions)
    ref = _reference_at(case, "reissner", targets, comp["delta"])
    ela = _reference_at(case, "elastica", targets, comp["delta"])
    computed = {
        "force_N": comp["force_N"].tolist(),
        "tip_shift_mm": comp["tip_shift_mm"].tolist(),
    }
    rel = {
        "force_N": [c / r - 1.0 for c, r in zip(computed["force_N"], ref["force_N"], strict=True)]
    }
    if case.tip == "free":
        rel["tip_shift_mm"] = [
            c / r - 1.0 for c, r in zip(computed["tip_shift_mm"], ref["tip_shift_mm"], strict=True)
        ]
    return {
        "check": "buckling",
        "settings": {
            **asdict(case),
            "lean_modelled_deg": math.degrees(case.scene().brush.effective_lean),
            "compression_mm": comp["delta"].tolist(),
            "penetration_mm": comp["penetration_mm"].tolist(),
        },
        "reference_kind": "reissner",
        "reference_note": (
            "planar geometrically exact rod with shear and extension (validation.rod), clamped "
            "at the lean, end held at the sphere's height; elastica: inextensible, unshearable"
        ),
        "computed": computed,
        "reference": ref,
        "elastica": ela,
        "rel_error": rel,
    }
