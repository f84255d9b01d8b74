"""The paper's reference motion: the four-point circle built from MoveL control points
(Figure 6, Algorithm 1), its deviation from the exact circle, and the 1° pitch perturbation of the
compliant gripper (eq 12, §5.2)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..engine.checks import (
    NONNEG,
    POSITIVE,
    check_real,
    check_unit,
    check_vec,
)
from ..engine.rotation import rot_axis
from .base import R0, Trajectory
from .movel import BLEND_RULE, MoveL
from .profiles import smoothstep, smoothstep_dot


# --------------------------------------------------------------------------------------------
# the paper's four-point circle
# --------------------------------------------------------------------------------------------
def paper_circle_waypoints(
    center,
    radius: float,
    start_angle: float = math.pi,
    clockwise: bool = False,
    placement: str = "circumscribed",
):
    """P0 and the four control points P1..P4 of the paper's circle (Figure 6, Algorithm 1).

    Returns ``(P0 (3,), P (4, 3))`` in the plane z = ``center[2]``.

    * **P0** — the start of the circular path, on the circle at polar angle ``start_angle``
      (default π: ``center - radius * x``).  Motion runs counter-clockwise about +z (or clockwise).
      With P0 at π and counter-clockwise motion, θ = 9π/4 falls in the lower-left quarter and
      13π/4 in the upper-right one — the order in which §5.1 / Figures 8-9 describe the two jamming
      events (lower-left, then upper-right).
    * **P1..P4** (``placement='circumscribed'``, default) — the corners of the square circumscribed
      about the circle, one per quarter, at ``start_angle ± (π/4 + k π/2)`` and distance
      ``√2 radius``: P1 is the first corner after P0.  This is the placement for which "blend
      radius = circle radius" (§4) makes sense: each blend zone starts/ends at the side mid-points,
      which are the circle's tangent points, and a circular fillet of radius r would reproduce the
      circle exactly.  P0 is the mid-point of side P4-P1, so the first move P0 -> P1 (half a side,
      its blend cut to r/2 by the overlap rule) is not circular — as the paper notes.
    * ``placement='inscribed'`` — the control points on the circle itself (same angles, distance
      ``radius``); with r = radius the blend zones would overlap (side = √2 r < 2r) and get cut to
      ``r/√2``.  Provided to quantify that alternative reading.
    """
    c = np.array(check_vec("center", center, 3))
    r = check_real("radius", radius, POSITIVE)
    phi0 = check_real("start_angle", start_angle)
    if placement not in ("circumscribed", "inscribed"):
        raise ValueError(f"placement must be 'circumscribed' or 'inscribed', got {placement!r}")
    sgn = -1.0 if clockwise else 1.0
    P0 = c + r * np.array([math.cos(phi0), math.sin(phi0), 0.0])
    dist = math.sqrt(2.0) * r if placement == "circumscribed" else r
    ang = phi0 + sgn * (math.pi / 4.0 + np.arange(4) * math.pi / 2.0)
    P = c + dist * np.stack([np.cos(ang), np.sin(ang), np.zeros(4)], axis=1)
    return P0, P


def paper_circle_movel(
    center,
    radius: float,
    speed: float,
    accel: float,
    turns: int = 4,
    blend_radius: float | None = None,
    start_angle: float = math.pi,
    clockwise: bool = False,
    orientation=None,
    placement: str = "circumscribed",
) -> MoveL:
    """Algorithm 1 as a ``MoveL``: ``movel(P0)``, then ``turns`` x (P1, P2, P3, P4) with blend
    radius ``blend_radius`` (default: the circle radius), then back to P0 (stop), so the path
    covers exactly ``turns`` full turns.  Carries ``angle(t)`` about ``center`` (0 at P0)."""
    if isinstance(turns, bool) or not isinstance(turns, (int, np.integer)) or turns < 1:
        raise ValueError(f"turns must be an integer >= 1 (allowed range [1, inf)), got {turns!r}")
    P0, P = paper_circle_waypoints(center, radius, start_angle, clockwise, placement)
    r = float(radius) if blend_radius is None else blend_radius
    R = np.array(R0) if orientation is None else orientation
    return MoveL(P, speed, accel, r, start_pose=(P0, R), repeat=turns, end=P0, center=center)


def movel_circle_deviation(
    center,
    radius: float,
    blend_radius: float,
    start_angle: float = math.pi,
    clockwise: bool = False,
    placement: str = "circumscribed",
    samples_per_turn: int = 20000,
) -> dict:
    """Radial deviation of the four-point MoveL path (with blends) from the exact circle.

    Builds ``paper_circle_movel`` with 3 turns and measures ``|p - c|⊥ - radius`` on points equally
    spaced in arc length.  The headline numbers (``max_abs_mm``, ``rms_mm``, ``max_outward_mm``,
    ``max_inward_mm``, both >= 0; RMS weighted by arc length) are for the steady loop — the middle
    turn θ ∈ [2π, 4π], where every corner has its steady blend.  ``first_quarter_max_abs_mm`` covers
    the excluded first move (θ ∈ [0, π/2]) and ``whole_path_max_abs_mm`` everything.
    The report also gives the requested and effective blend radii (steady corners and the first
    corner P1), whether the overlap rule cut them (``reduced``) and the rule itself.

    Measured for radius = blend radius = 20 mm: circumscribed control points (default) — blend
    zones exactly touch at the tangent points (no cut, first corner cut to 10 mm), max 1.213 mm
    (= r (3/(2√2) - 1), outward, at the 45° diagonals; 0 at the tangent points), RMS 0.741 mm,
    first quarter up to 4.75 mm; control points on the circle (``'inscribed'``) — zones overlap,
    cut to 14.14 mm, the path lies inside the circle by up to 5.86 mm (RMS 5.44 mm).
    """
    r = check_real("radius", radius, POSITIVE)
    br = check_real("blend_radius", blend_radius, NONNEG)
    if (
        isinstance(samples_per_turn, bool)
        or not isinstance(samples_per_turn, (int, np.integer))
        or samples_per_turn < 100
    ):
        raise ValueError(
            f"samples_per_turn must be an integer >= 100 (allowed range [100, inf)), "
            f"got {samples_per_turn!r}"
        )
    c = np.array(check_vec("center", center, 3))
    mv = paper_circle_movel(
        c,
        r,
        speed=r,
        accel=r,
        turns=3,
        blend_radius=br,
        start_angle=start_angle,
        clockwise=clockwise,
        placement=placement,
    )
    n = int(samples_per_turn * mv.length / (2.0 * math.pi * r)) + 1
    S = np.linspace(0.0, mv.length, n)
    P, _ = mv._geom(S)
    rel = P - c
    rel[:, 2] = 0.0
    dev = np.linalg.norm(rel, axis=1) - r
    theta = np.interp(S, mv._ang_S, mv._ang_tab)
    steady = (theta >= 2.0 * math.pi) & (theta <= 4.0 * math.pi)
    first = theta <= 0.5 * math.pi
    d = dev[steady]
    radii = mv.blend_radii
    # corners: index 0 is P1 (first), the steady ones are those of the middle turn (4..7)
    steady_r = radii[4:8]
    return {
        "placement": placement,
        "radius_mm": r,
        "blend_radius_requested_mm": br,
        "blend_radius_effective_mm": float(np.min(steady_r)),
        "blend_radius_first_corner_mm": float(radii[0]),
        "reduced": bool(np.any(mv.blend_reduced[4:8])),
        "first_corner_reduced": bool(mv.blend_reduced[0]),
        "rule": BLEND_RULE,
        "max_abs_mm": float(np.max(np.abs(d))),
        "rms_mm": float(np.sqrt(np.mean(d * d))),
        "max_outward_mm": float(max(0.0, np.max(d))),
        "max_inward_mm": float(max(0.0, -np.min(d))),
        "first_quarter_max_abs_mm": float(np.max(np.abs(dev[first]))),
        "whole_path_max_abs_mm": float(np.max(np.abs(dev))),
    }


# --------------------------------------------------------------------------------------------
# eq 12: pitch perturbation
# --------------------------------------------------------------------------------------------
def pitch_profile(theta, theta_start: float = 2.0 * math.pi, theta_end: float = 2.5 * math.pi):
    """Unit profile s(θ) of eq 12: ``step(θ, θs, 0, θm, 1) · step(θ, θm, 1, θe, 0)``, θm the mid.

    Rises with the eq-10 cubic from 0 at θs = 2π to 1 at θm = 2π + π/4, falls back to 0 at
    θe = 5π/2; zero outside [θs, θe].  (The printed second factor ``step(θ, 2π+π/4, 1, 2π, 1)`` is
    garbled; the text — "a peak at the centre of this interval", zero outside — fixes it as the
    falling step used here.)
    """
    tm = 0.5 * (theta_start + theta_end)
    return smoothstep(theta, theta_start, 0.0, tm, 1.0) * smoothstep(theta, tm, 1.0, theta_end, 0.0)


def pitch_profile_dot(theta, theta_start: float = 2.0 * math.pi, theta_end: float = 2.5 * math.pi):
    """ds/dθ of ``pitch_profile`` (product rule)."""
    tm = 0.5 * (theta_start + theta_end)
    a = smoothstep(theta, theta_start, 0.0, tm, 1.0)
    b = smoothstep(theta, tm, 1.0, theta_end, 0.0)
    da = smoothstep_dot(theta, theta_start, 0.0, tm, 1.0)
    db = smoothstep_dot(theta, tm, 1.0, theta_end, 0.0)
    return da * b + a * db


class PitchPerturbation(Trajectory):
    """Eq 12: a pitch rotation of the brush superimposed on a base trajectory (§5.2).

    ``φ(t) = alpha_rad · s(θ(t))`` with ``s = pitch_profile`` (peak 1 at θ = 2π + π/4, support
    [2π, 5π/2]), and the pose ``R(t) = R_base(t) · Rot(axis, φ(t))`` — the rotation is about the
    TCP-frame ``axis`` (default the TCP y axis, the brush's pitch axis for a handle along TCP x;
    with R0 it is world -y) — i.e. a tilt of the brush in its own frame, post-multiplied.

    ``pivot='tcp'`` rotates about the TCP origin (position unchanged).  ``pivot`` may instead be a
    point ``c`` (3,) in the TCP frame (mm), e.g. the compliant clamp above the bristles
    (``(0, 0, -h)`` with R0); then ``p = p_base + R_base (c - Rot c)``.

    Twist: ``w = w_base + R_base · axis · φ'``, with ``φ' = alpha · ds/dθ · dθ/dt``, and for a
    pivot ``v = v_base + w_base x (R_base (c - Rot c)) - R(t) (φ' axis x c)``.

    θ(t) comes from ``angle_fn`` (vectorised callable of t); its rate from ``angle_rate_fn`` or, if
    that is not given, a central difference (step 1e-6 s).  Without ``angle_fn`` the base's own
    ``angle`` / ``angle_rate`` are used (Circle, MoveL with ``center``, or a Sequence containing
    them).
    """

    def __init__(
        self,
        base: Trajectory,
        alpha_rad: float = float(np.deg2rad(1.0)),
        angle_fn: Callable | None = None,
        pivot="tcp",
        *,
        angle_rate_fn: Callable | None = None,
        axis=(0.0, 1.0, 0.0),
        theta_start: float = 2.0 * math.pi,
        theta_end: float = 2.5 * math.pi,
    ):
        if not isinstance(base, Trajectory):
            raise ValueError(f"base must be a Trajectory, got {type(base).__name__}")  # noqa: TRY004
        self.base = base
        self.alpha = check_real("alpha_rad", alpha_rad)
        if abs(self.alpha) > math.pi / 2:
            raise ValueError(f"alpha_rad must be in [-pi/2, pi/2], got {alpha_rad!r}")
        self.axis = check_unit("axis", axis)
        self.theta_start = check_real("theta_start", theta_start)
        self.theta_end = check_real("theta_end", theta_end)
        if not self.theta_end > self.theta_start:
            raise ValueError(
                f"theta_end must be > theta_start ({self.theta_start!r}), got {theta_end!r}"
            )
        if isinstance(pivot, str):
            if pivot != "tcp":
                raise ValueError(
                    f"pivot must be 'tcp' or a 3-vector in the TCP frame, got {pivot!r}"
                )
            self.pivot = None
        else:
            self.pivot = np.array(check_vec("pivot", pivot, 3))
        if angle_fn is None:
            if not base.has_angle:
                raise ValueError(
                    f"angle_fn is required: base {type(base).__name__} has no rotation angle"
                )
            self._angle, self._rate = base.angle, base.angle_rate
            self._pair = base._angle_and_rate
        else:
            if not callable(angle_fn):
                raise ValueError(f"angle_fn must be callable, got {angle_fn!r}")
            self._angle = angle_fn
            if angle_rate_fn is None:
                h = 1e-6
                self._rate = lambda t: (
                    (
                        np.asarray(angle_fn(np.asarray(t) + h), float)
                        - np.asarray(angle_fn(np.asarray(t) - h), float)
                    )
                    / (2 * h)
                )
            else:
                self._rate = angle_rate_fn
            self._pair = None
        self.has_angle = True
        self.duration = base.duration

    def angle(self, t):
        return self._angle(t)

    def angle_rate(self, t):
        return self._rate(t)

    def pitch(self, t):
        """Pitch angle φ(t) = alpha · s(θ(t)) in rad."""
        return self.alpha * pitch_profile(self._angle(t), self.theta_start, self.theta_end)

    def _eval(self, t):
        P, Rb, V, Wb = self.base._eval(t)
        if self._pair is not None:
            th, thd = self._pair(t)
        else:
            th, thd = self._angle(t), self._rate(t)
        th = np.asarray(th, dtype=float).reshape(t.shape)
        thd = np.asarray(thd, dtype=float).reshape(t.shape)
        phi = self.alpha * np.asarray(pitch_profile(th, self.theta_start, self.theta_end))
        phid = (
            self.alpha * np.asarray(pitch_profile_dot(th, self.theta_start, self.theta_end)) * thd
        )
        Rp = rot_axis(self.axis, phi)
        R = Rb @ Rp
        W = Wb + phid[:, None] * (Rb @ self.axis)
        if self.pivot is not None:
            c = self.pivot
            off = np.einsum("nij,nj->ni", Rb, c - Rp @ c)  # (N, 3)
            P = P + off
            V = V + np.cross(Wb, off) - phid[:, None] * (R @ np.cross(self.axis, c))
        return P, R, V, W
