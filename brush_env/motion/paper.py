"""The paper's four-point circle (§4, Algorithm 1, Figures 5-6) built from UR ``MoveL`` moves.

``paper_circle_waypoints`` places P0 and the control points P1..P4, ``paper_circle_movel`` runs
Algorithm 1 as a ``MoveL`` with blend radius, and ``movel_circle_deviation`` measures how far that
path lies from the exact circle (``motion.circle.Circle``) that the paper's model followed.  The
paper gives this motion as robot commands (Algorithm 1), not as a numbered equation.
"""

from __future__ import annotations

import math

import numpy as np

from brush_env.engine.checks import Limit, check_choice, check_int, check_real

from .base import ANGLE, LENGTH, R0, check_point
from .movel import BLEND_RULE, MoveL

__all__ = ["paper_circle_waypoints", "paper_circle_movel", "movel_circle_deviation", "PLACEMENTS"]

#: Where the four control points sit: corners of the square about the circle, or on the circle.
PLACEMENTS = ("circumscribed", "inscribed")


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
    c = check_point("center", center)
    r = check_real("radius", radius, LENGTH)
    phi0 = check_real("start_angle", start_angle, ANGLE)
    check_choice("placement", placement, PLACEMENTS, "placement")
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
    check_int("turns", turns, Limit("turns", ge=1))
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

    Builds ``paper_circle_movel`` with 3 turns and measures ``|p - c|⊥ - radius`` on points
    equally spaced in arc length.  The headline numbers (``max_abs_mm``, ``rms_mm``,
    ``max_outward_mm``, ``max_inward_mm``, both >= 0; RMS weighted by arc length) are for the steady
    loop — the middle turn θ ∈ [2π, 4π], where every corner has its steady blend.
    ``first_quarter_max_abs_mm`` covers the excluded first move (θ ∈ [0, π/2]) and
    ``whole_path_max_abs_mm`` everything.
    The report also gives the requested and effective blend radii (steady corners and the first
    corner P1), whether the overlap rule cut them (``reduced``) and the rule itself.

    Measured for radius = blend radius = 20 mm: circumscribed control points (default) — blend
    zones exactly touch at the tangent points (no cut, first corner cut to 10 mm), max 1.213 mm
    (= r (3/(2√2) - 1), outward, at the 45° diagonals; 0 at the tangent points), RMS 0.741 mm,
    first quarter up to 4.75 mm; control points on the circle (``'inscribed'``) — zones overlap,
    cut to 14.14 mm, the path lies inside the circle by up to 5.86 mm (RMS 5.44 mm).
    """
    r = check_real("radius", radius, LENGTH)
    br = check_real("blend_radius", blend_radius, Limit("mm", ge=0))
    check_int("samples_per_turn", samples_per_turn, Limit("samples", ge=100))
    c = check_point("center", center)
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
