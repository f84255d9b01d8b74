"""brush_env.motion: TCP trajectories of the robot that holds the brush (§4-§5 of the paper).

A trajectory maps time t [s] to the pose and twist of the brush base (the robot's TCP), which the
engine's base motion follows: position ``p`` (3,) [mm], rotation ``R`` (3, 3) TCP -> world,
linear velocity ``v`` (3,) [mm/s] and angular velocity ``w`` (3,) [rad/s], both in the world
frame, so ``dp/dt = v`` and ``dR/dt = [w]x R``.  Every ``Trajectory`` has ``duration``,
``pose(t)``, ``twist(t)``, ``state(t)`` and the vectorised
``sample(times) -> (P (N,3), R (N,3,3), V (N,3), W (N,3))``.  Times are clamped to
``[0, duration]``: the start pose is held before the start, the end pose after the end, and the
twist outside ``[0, duration]`` is zero.  Scalar queries cost ~40-350 µs (Python overhead); for
long runs sample the whole time grid once with ``sample`` (~2 µs per time).

Conventions: mm, s, rad; world frame = robot base frame, z up; the plate is the plane z = 0 with
normal +z.  The brush's default TCP orientation is ``R0 = diag(1, -1, -1)`` (tool z pointing down
onto the plate); the bristle tips sit at TCP z-offset ``L`` (longest bristle), so "touching" is
``p_z = L``.

Modules (and what of the paper each implements):

* ``profiles`` — the cubic step of eq 10 (``smoothstep``) and its derivative, the quintic/cubic
  rest-to-rest unit profiles and the trapezoidal speed profile.
* ``base`` — the ``Trajectory`` base class, ``R0`` and the pose/vector checks.
* ``primitives`` — ``Hold``, ``Press`` (the 3 mm press of §5.1), ``Approach`` (MoveJ stand-in,
  §4) and ``Sequence``.
* ``circle`` — ``Circle``: the exact circle with θ(t), the angle of Figure 7 (§5.1).
* ``movel`` — ``MoveL``: UR linear moves with blend radius (§4, Figure 5).
* ``paper`` — the four-point circle of Algorithm 1 (Figure 6) and its deviation from the circle.
* ``pitch`` — eq 12: the pitch profile (a product of two eq 10 steps) and ``PitchPerturbation``
  (§5.2).

This package sits above the engine (it uses ``engine.checks`` and ``engine.rotation``); the engine
never imports it.  Bad input raises ``ConfigError`` (a ``ValueError``) naming the parameter, the
value and the allowed range.
"""

from .base import R0, Trajectory
from .circle import Circle
from .movel import BLEND_RULE, MoveL
from .paper import movel_circle_deviation, paper_circle_movel, paper_circle_waypoints
from .pitch import PitchPerturbation, pitch_profile, pitch_profile_dot
from .primitives import Approach, Hold, Press, Sequence
from .profiles import smoothstep, smoothstep_dot

__all__ = [
    "R0",
    "BLEND_RULE",
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
