"""brush_env.motion: TCP trajectories — the robot's motion, not dynamics (numpy only).

A trajectory gives the base (TCP) pose ``(p [mm], R)`` and twist ``(v [mm/s], w [rad/s])`` over
time, in the world frame (robot base, z up; the plate is z = 0).  They reproduce the motions of
the paper's bench (§4–5): the press along the bristle axis, the UR5 circle built from four MoveL
points with blend radius (Algorithm 1, Figures 5–6), and the 1° pitch perturbation (eq 12, §5.2).
The engine never imports this package; experiments, benches, envs and agents do.

Modules: ``profiles`` (eq 10 step, quintic/cubic, trapezoid), ``base`` (Trajectory, Hold, Press,
Approach, Sequence), ``circle`` (Circle), ``movel`` (MoveL), ``paper`` (the paper's circle and
pitch perturbation).  Bad input raises ``ConfigError`` (a ``ValueError``) naming the parameter,
the value and the allowed range.
"""

from .base import R0, Approach, Hold, Press, Sequence, Trajectory
from .circle import Circle
from .movel import BLEND_RULE, MoveL
from .paper import (
    PitchPerturbation,
    movel_circle_deviation,
    paper_circle_movel,
    paper_circle_waypoints,
    pitch_profile,
    pitch_profile_dot,
)
from .profiles import smoothstep, smoothstep_dot

__all__ = [
    "BLEND_RULE",
    "R0",
    "Approach",
    "Circle",
    "Hold",
    "MoveL",
    "PitchPerturbation",
    "Press",
    "Sequence",
    "Trajectory",
    "movel_circle_deviation",
    "paper_circle_movel",
    "paper_circle_waypoints",
    "pitch_profile",
    "pitch_profile_dot",
    "smoothstep",
    "smoothstep_dot",
]
