"""A planar cut through a brush in the stroke plane, built on pymunk (issue 14).

Side view: the in-plane coordinate (called x here) runs along the stroke, z points up, and
pymunk's y is the world z.  Each bristle of the chosen cut of a brush config
(``configs/brushes``, ``row_bristles``) is a chain of ``n`` rigid segments.  There are two cuts:
across the rows (``"y"``: the plane the 3-D bristles lean and buckle in) and along a row
(``"x"``).

* **Joints.** Pivot joints with rotary springs (``pymunk.DampedRotarySpring``).  The springs are
  the 3-D element's in-plane bending stiffness: ``k = E I / l`` between segments (l = L / n), and
  ``2 E I / l`` at the root (a half segment clamped there).  The chain's tip deflection under a
  tip load is then ``(P l^3 / EI) (n^2/2 + (n-1) n (2n-1)/6)``: 1.4 % off the cantilever's
  ``P L^3 / 3EI`` at 6 segments.  ``I`` is the second moment for bending in the stroke plane:
  the weak axis (``Section.I_y``) across the rows, the strong one (``I_z``) along a row.
* **Damping.** Stiffness-proportional, ``c = 2 zeta k / omega_1``, with the material's
  ``damping_ratio`` at the first cantilever mode (as the 3-D engine's eq 4).
* **Mass.** ``rho A l`` per segment and rotary inertia ``m l^2 / 12``, both times
  ``mass_scale``.  pymunk integrates the springs explicitly: the stable step is ~2/omega_max,
  ~30 us at the real mass.  Brushing is slow next to the bristle's ~130 Hz first mode, so the
  default scales the mass by 100 (first mode ~13 Hz): steps of 0.1 ms.  ``bench planar``
  measures what it costs.
* **Tips.** A circle of the tip radius at the end of the last segment.
* **Imperfection.** The brush's lean (1 deg toward the thickness, +head y) in the ``"y"`` cut,
  as in 3-D.  The ``"x"`` cut gets ``lean_deg`` in its plane so that a press buckles it there,
  while the 3-D bristles of a row buckle *out* of that plane, which a planar model cannot do
  (docs/planar.md).

**Contact is pymunk's own**: rigid, iterative impulses with Coulomb friction ``mu``, not the
paper's penalty law (eq 6) and stick-slip law (eq 7-10).  Why:

* The penalty law's penetration is ~5 um on a 9 mm bristle: a rigid contact changes the
  geometry by < 0.1 %.
* Applying eq 6 as an explicit force would need steps far below pymunk's stable spring step
  (k_con delta^0.3 ~ 30 N/mm on a 2.5e-9 t tip).
* Table 2's mu_s = 0.8 and mu_d = 0.76 differ by 5 %.  pymunk has one coefficient; mu_d is used,
  since a stroke slides.
* Tip-tip contact (Table 3) is frictionless: a collision handler zeroes the friction between tips.

**Surface profiles** (``Profile``): a flat line, or a tooth cross-section (two rounded crowns
with a gap), as static segments.

Units: mm, s, tonne, N (pymunk is unit-free; these are the engine's).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..engine.checks import ConfigError, Limit, check_real
from ..engine.config import BrushConfig

TIP, SURFACE = 1, 2  # pymunk collision types


@dataclass(frozen=True)
class PlanarSettings:
    """pymunk settings: ``dt`` [s] step; ``mass_scale`` [-] on segment mass and inertia;
    ``iterations`` of pymunk's solver; ``friction`` [-] Coulomb mu tip-surface (Table 2's mu_d);
    ``gravity`` on the bristles; ``lean_deg`` [deg] in-plane imperfection; ``safety`` [-]:
    ``dt`` must be <= safety x 2 / omega_max (checked at build)."""

    dt: float = 1e-4
    mass_scale: float = 100.0
    iterations: int = 30
    friction: float = 0.76
    gravity: bool = True
    lean_deg: float = 1.0
    safety: float = 0.5

    def __post_init__(self):
        check_real("planar.dt", self.dt, Limit("s", gt=0, le=0.01))
        check_real("planar.mass_scale", self.mass_scale, Limit("-", ge=1, le=1e6))
        check_real("planar.iterations", self.iterations, Limit("count", ge=1, le=1000))
        check_real("planar.friction", self.friction, Limit("-", ge=0, le=5))
        check_real("planar.lean_deg", self.lean_deg, Limit("deg", ge=-10, le=10))
        check_real("planar.safety", self.safety, Limit("-", gt=0, le=1))


@dataclass(frozen=True)
class Profile:
    """A surface profile z(x) as a polyline of points (x, z) [mm], material below it."""

    points: tuple
    name: str = "profile"

    @classmethod
    def flat(cls, z: float = 0.0, half_width: float = 60.0) -> Profile:
        return cls(((-half_width, z), (half_width, z)), "flat")

    @classmethod
    def tooth_section(
        cls, crown_width: float = 7.0, gap: float = 0.7, height: float = 2.0, n: int = 24
    ) -> Profile:
        """Two crowns side by side, cut along the row at the buccal bulge: each a half-ellipse
        of width ``crown_width`` and height ``height`` whose top is at z = 0, ``gap`` apart at
        their base; flat land beyond (mm)."""
        pts = [(-crown_width - 0.5 * gap - 10.0, -height)]
        for c in (-(0.5 * crown_width + 0.5 * gap), 0.5 * crown_width + 0.5 * gap):
            t = np.linspace(math.pi, 0.0, n)
            pts += [
                (c + 0.5 * crown_width * math.cos(a), -height + height * math.sin(a)) for a in t
            ]
        pts.append((crown_width + 0.5 * gap + 10.0, -height))
        return cls(tuple((float(x), float(z)) for x, z in pts), "tooth_section")


def row_bristles(brush: BrushConfig, cut: str = "y", at: float | None = None):
    """The bristles of one planar cut through the head, sorted along it, and where the cut lies:

    * ``cut="y"``: the bristles at one head x (nearest ``at``, default 0), across the rows; the
      stroke runs along head y, the thickness direction.  The 3-D bristles lean and buckle in
      this plane, and bend about their weak axis (``Section.I_y``).
    * ``cut="x"``: one row, the bristles at one head y (nearest ``at``, default 0: an inner row);
      the stroke runs along head x, the width direction, which bends the strong axis
      (``Section.I_z``), while the 3-D bristles buckle out of the plane."""
    if cut not in ("x", "y"):
        raise ConfigError(f"planar cut = {cut!r}: must be 'x' (a row) or 'y' (across the rows)")
    k = 1 if cut == "x" else 0  # the root coordinate that is constant along the cut
    vals = np.array([b.root[k] for b in brush.bristles])
    levels = np.unique(np.round(vals, 6))
    target = 0.0 if at is None else float(at)
    v = levels[np.argmin(np.abs(levels - target))]
    sel = [b for b, vv in zip(brush.bristles, vals, strict=True) if abs(vv - v) < 1e-6]
    along = 0 if cut == "x" else 1
    return sorted(sel, key=lambda b: b.root[along]), float(v)


class PlanarBrush:
    """One bristle row of ``brush`` over ``profile``, in pymunk (module docstring)."""

    def __init__(
        self,
        brush: BrushConfig,
        profile: Profile | None = None,
        settings: PlanarSettings | None = None,
        cut: str = "y",
        at: float | None = None,
        bodies: int | None = None,
    ):
        import pymunk

        self.settings = s = settings or PlanarSettings()
        self.profile = profile or Profile.flat()
        self.cut = cut
        self.bristles, self.at = row_bristles(brush, cut, at)
        along = 0 if cut == "x" else 1
        self.n = int(bodies or self.bristles[0].bodies)
        space = pymunk.Space()
        space.iterations = int(s.iterations)
        space.gravity = (0.0, -9810.0 if s.gravity else 0.0)
        space.collision_slop = 1e-4  # [mm] default 0.1 mm would be 20x the paper's penetration
        self.space = space
        self.head = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        space.add(self.head)
        self.chains, self.tips, self.root_joints = [], [], []
        self.omega_max = 0.0
        # the 3-D lean lies in the "y" cut (toward +thickness = +head y); the "x" cut gets the
        # settings' in-plane imperfection instead
        lean = brush.effective_lean if cut == "y" else math.radians(s.lean_deg)
        self.lean = lean
        for b in self.bristles:
            L, n = b.length, self.n
            seg = L / n
            m_ = b.material
            EI = m_.E * (b.section.I_z if cut == "x" else b.section.I_y)
            k = EI / seg
            m = m_.density * b.section.area * seg * s.mass_scale
            inertia = m * seg * seg / 12.0
            # first cantilever mode (real mass), for the damping (eq 4's stiffness-proportional c)
            w1 = 1.875**2 * math.sqrt(EI / (m_.density * b.section.area * L**4))
            c = 2.0 * m_.damping_ratio * k / w1
            # stiffest local mode of the (scaled) chain: a joint between two segments
            self.omega_max = max(self.omega_max, math.sqrt(4.0 * k / (inertia + m * seg**2 / 4)))
            bodies_, prev = [], self.head
            x0 = b.root[along]
            for j in range(n):
                body = pymunk.Body(m, inertia)
                s0 = j * seg
                body.position = (
                    x0 + (s0 + 0.5 * seg) * math.sin(lean),
                    -(s0 + 0.5 * seg) * math.cos(lean),
                )
                body.angle = lean
                anchor = (x0 + s0 * math.sin(lean), -s0 * math.cos(lean))
                pivot = pymunk.PivotJoint(prev, body, anchor)
                spring = pymunk.DampedRotarySpring(
                    prev, body, lean if j == 0 else 0.0, 2 * k if j == 0 else k, c
                )
                space.add(body, pivot, spring)
                if j == 0:
                    self.root_joints.append((pivot, spring))
                bodies_.append(body)
                prev = body
            tip = pymunk.Circle(prev, b.tip_radius, (0.0, -0.5 * seg))
            tip.collision_type = TIP
            tip.friction = 1.0
            tip.elasticity = 0.0
            space.add(tip)
            self.chains.append(bodies_)
            self.tips.append(tip)
        limit = s.safety * 2.0 / self.omega_max
        if s.dt > limit:
            raise ConfigError(
                f"planar.dt = {s.dt:g} s is too large for the bristles' stiffness: pymunk's "
                f"springs are explicit and need dt <= {limit:.3g} s (safety {s.safety:g} x "
                f"2/omega_max, omega_max = {self.omega_max:.4g} rad/s at mass_scale = "
                f"{s.mass_scale:g}); use a smaller dt or a larger mass_scale"
            )
        self.max_stable_dt = 2.0 / self.omega_max
        pts = self.profile.points
        for a, bb in zip(pts[:-1], pts[1:], strict=True):
            seg_shape = pymunk.Segment(space.static_body, a, bb, 0.0)
            seg_shape.collision_type = SURFACE
            seg_shape.friction = s.friction
            seg_shape.elasticity = 0.0
            space.add(seg_shape)

        def _no_tip_friction(arbiter, space_, data):
            arbiter.friction = 0.0  # Table 3: tip-tip contact has no friction

        space.on_collision(TIP, TIP, pre_solve=_no_tip_friction)
        self.rest_tip_offset = np.array(
            [
                [b.root[0] + b.length * math.sin(lean), -b.length * math.cos(lean)]
                for b in self.bristles
            ]
        )
        self.time = 0.0

    # ------------------------------------------------------------------ driving
    def place(self, x: float, z: float) -> None:
        """Put the head (TCP) at (x, z) [mm] with the bristles straight (at rest)."""
        dx = np.array([x, z]) - np.asarray(self.head.position)
        self.head.position = (x, z)
        for chain in self.chains:
            for body in chain:
                body.position = tuple(np.asarray(body.position) + dx)
                body.velocity = (0.0, 0.0)
                body.angular_velocity = 0.0
        self.space.reindex_shapes_for_body(self.head)
        for chain in self.chains:
            self.space.reindex_shapes_for_body(chain[-1])

    def step(self, x: float, z: float, angle: float | None = None) -> None:
        """Drive the head to (x, z) [mm] and, if given, ``angle`` [rad] (counter-clockwise in the
        plane) over one step ``settings.dt`` (constant velocity)."""
        dt = self.settings.dt
        p = np.asarray(self.head.position)
        self.head.velocity = tuple((np.array([x, z]) - p) / dt)
        self.head.angular_velocity = 0.0 if angle is None else (angle - self.head.angle) / dt
        self.space.step(dt)
        self.time += dt
        if not np.all(np.isfinite(self.tip_positions())):
            raise FloatingPointError(
                f"t = {self.time:.6g} s: the pymunk model blew up (non-finite tip positions); "
                f"dt = {dt:g} s is unstable here (largest stable ~{self.max_stable_dt:.3g} s)"
            )

    # ------------------------------------------------------------------ outputs
    def tip_positions(self) -> np.ndarray:
        """(nb, 2) tip-circle centres (x, z) [mm]."""
        return np.array([tip.body.local_to_world(tip.offset) for tip in self.tips])

    def root_force(self) -> np.ndarray:
        """(Fx, Fz) [N] and moment [N mm] (about the head, counter-clockwise) the head applies to
        the bristles, quasi-statically: minus the contact forces and the bristles' real weight
        (pymunk reports only the magnitudes of joint impulses; the scaled inertia is left out)."""
        F = -self.contact_forces().sum(axis=0)
        if self.settings.gravity:
            m = sum(b.mass for chain in self.chains for b in chain) / self.settings.mass_scale
            F = F + np.array([0.0, 9810.0 * m])
        tips = self.tip_positions() - np.asarray(self.head.position)
        cf = self.contact_forces()
        M = -float(np.sum(tips[:, 0] * cf[:, 1] - tips[:, 1] * cf[:, 0]))
        return np.array([F[0], F[1], M])

    def contact_forces(self) -> np.ndarray:
        """(nb, 2) force [N] the surface exerts on each tip over the last step (x, z): the
        contact impulses / dt."""
        out = np.zeros((len(self.tips), 2))
        dt = self.settings.dt
        for i, tip in enumerate(self.tips):
            acc = np.zeros(2)

            def _sum(arb, acc=acc, tip=tip):
                a, b = arb.shapes
                if a.collision_type == SURFACE or b.collision_type == SURFACE:
                    imp = np.asarray(arb.total_impulse)
                    # total_impulse is on the arbiter's first shape
                    acc += imp if a is tip else -imp

            tip.body.each_arbiter(_sum)
            out[i] = acc / dt
        return out
