"""``Circle``: the exact circular TCP path at constant orientation (§4-§5, the θ of Figure 7).

The reference the four-point MoveL loop of the paper (``motion.paper``) approximates; a
trapezoidal tangential speed profile (``motion.profiles.Trapezoid``) starts and ends it at rest.
No numbered equation of the paper: §5.1 states the path in words.
"""

from __future__ import annotations

import math

import numpy as np

from brush_env.engine.checks import Limit, check_real, check_rotation, check_unit

from .base import ACCEL, ANGLE, LENGTH, R0, SPEED, Trajectory, check_point, plane_basis
from .profiles import Trapezoid

__all__ = ["Circle"]


class Circle(Trajectory):
    """Exact circle at constant orientation with a trapezoidal tangential speed profile.

    Position ``p = center + radius (cos φ e1 + sin φ e2)`` with ``φ = start_angle ± θ(t)``: ``e1``
    is world x projected into the plane of ``normal`` (world y if x is parallel to the normal) and
    ``e2 = normal x e1``; with the default ``normal = +z`` these are world x and y, so
    ``start_angle = π`` puts the start point P0 at ``center - radius * x``.  ``clockwise=False``
    turns counter-clockwise about ``normal`` (``+θ``), ``True`` clockwise (``-θ``).

    ``θ(t) = s(t) / radius`` (``angle(t)``) is the unwrapped rotation angle: 0 at P0 and increasing
    through the turns in either direction, so θ in [2π, 8π] covers turns 2-4 (the analysis range of
    the paper's Figure 7).  ``s(t)`` is trapezoidal: accelerate at ``accel`` from rest to ``speed``,
    cruise, and decelerate to rest at the end of ``turns`` turns (triangular if the arc is too short
    to reach ``speed``).  The orientation stays ``R`` (default ``R0``): the UR5 MoveL keeps the tool
    orientation when all control points share it, so the twist has ``w = 0``.
    ``center`` is the TCP centre (its z is the TCP height: ``L - press depth`` after the press).
    """

    has_angle = True

    def __init__(
        self,
        center,
        radius: float,
        speed: float,
        accel: float,
        turns: float = 1.0,
        start_angle: float = math.pi,
        normal=(0.0, 0.0, 1.0),
        R=R0,
        clockwise: bool = False,
    ):
        self.center = check_point("center", center)
        self.radius = check_real("radius", radius, LENGTH)
        self.speed = check_real("speed", speed, SPEED)
        self.accel = check_real("accel", accel, ACCEL)
        self.turns = check_real("turns", turns, Limit("turns", gt=0))
        self.start_angle = check_real("start_angle", start_angle, ANGLE)
        self.normal = check_unit("normal", normal)
        self.R = check_rotation("R", R)
        self.clockwise = bool(clockwise)
        self.e1, self.e2 = plane_basis(self.normal)
        self.sign = -1.0 if self.clockwise else 1.0
        self.arc_length = 2.0 * math.pi * self.radius * self.turns
        self._prof = Trapezoid(self.arc_length, self.speed, self.accel)
        self.duration = self._prof.duration

    @property
    def total_angle(self) -> float:
        return 2.0 * math.pi * self.turns

    def angle(self, t):
        """Unwrapped rotation angle θ(t) in rad: 0 at P0, ``2π turns`` at the end (clamped)."""
        s, _ = self._prof.s(t)
        out = s / self.radius
        return float(out) if np.ndim(out) == 0 else out

    def angle_rate(self, t):
        """dθ/dt in rad/s (zero outside [0, duration])."""
        t = np.asarray(t, dtype=float)
        _, sd = self._prof.s(t)
        out = np.where((t < 0.0) | (t > self.duration), 0.0, sd / self.radius)
        return float(out) if out.ndim == 0 else out

    def time_at_angle(self, theta):
        """Inverse of ``angle``: the time at which θ is reached (θ clamped to the covered range)."""
        out = self._prof.t_at_s(np.asarray(theta, dtype=float) * self.radius)
        return float(out) if np.ndim(out) == 0 else out

    def point_at_angle(self, theta) -> np.ndarray:
        """Position(s) on the circle at rotation angle θ (from P0, in the direction of travel)."""
        th = np.asarray(theta, dtype=float)
        phi = self.start_angle + self.sign * th
        return (
            self.center
            + self.radius * np.cos(phi)[..., None] * self.e1
            + self.radius * np.sin(phi)[..., None] * self.e2
        )

    def _eval(self, t):
        s, sd = self._prof.s(t)
        th = s / self.radius
        phi = self.start_angle + self.sign * th
        c, sn = np.cos(phi)[:, None], np.sin(phi)[:, None]
        P = self.center + self.radius * (c * self.e1 + sn * self.e2)
        V = (self.sign * sd)[:, None] * (-sn * self.e1 + c * self.e2)
        n = t.shape[0]
        return P, np.broadcast_to(self.R, (n, 3, 3)).copy(), V, np.zeros((n, 3))
