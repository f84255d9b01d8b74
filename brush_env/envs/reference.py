"""The paper's press-then-circle motion as a tracking controller on BrushEnv observations.

Pure numpy, no SB3: ``agents/reference.py`` wraps it as an SB3-style policy, and ``brush-env
bench env`` drives the env with it.  The plan (engine-side trajectories of
``brush_env.motion``), built from the TCP pose of the first observation:

1. **Approach** (quintic, MoveJ stand-in) from the start pose to ``hover`` mm above P0, the
   circle's start point ``center + radius * (cos start_angle, sin start_angle)``, turning to the
   paper's orientation ``R_START`` (yaw 0) in 6-D mode (3-D mode keeps the start orientation).
   Its duration is at least ``approach_time`` and long enough that the quintic's peak speed stays
   under 80 % of the action limits.
2. **Press** (quintic) ``hover + press_depth`` mm along the bristle axis in ``press_time``: the
   paper's 3 mm press "from contact", measured from the TCP height at which the tip spheres touch
   the *nominal* plate (the plate offset is not observed).  ``press="sliding"`` (the default)
   presses *while* the circle starts: the quintic descent is added to the first ``press_time``
   seconds of the circle, so the bristles meet the plate already sliding.  ``press="static"`` is
   the paper's order (§4-5): press at rest above P0, then start the circle.
3. **Circle** of ``radius`` (paper: 20 mm) about the nominal patch centre at ``speed`` with a
   trapezoidal profile of acceleration ``accel``, counter-clockwise from P0 (Figure 6), for as
   many turns as the episode allows; the exact circle (not the four-point MoveL path).

Why the sliding press is the default (docs/rl.md, "The reference's press"; measured with
``python -m agents.probe_reward --press-curve``): with the default brush the static press reaches
the plateau of the post-buckled bristles, ~1.6 N while only the 10 mm outer rows touch and
~4.4-4.9 N once the 9 mm inner rows touch too (past ~1.1 mm), so any static press deeper than
~1.1 mm holds the brush above the env's 4 N limit, and starting the circle from it adds a
break-away peak (6.2-6.7 N at 3 mm).  Pressed while sliding, the same 3 mm peaks at ~2.3 N and
holds ~0.3-1.3 N: within the limit, with the same coverage and twice the return.  The paper's
motion stays available as ``press="static"`` (``press_depth`` 3 mm).

Tracking law at step k (time t_k = k dt, pose (p, R) from the observation):
``v = (P(t_k+1) - P(t_k)) / dt + kp (P(t_k) - p)`` and
``w = log(R(t_k+1) R(t_k)^T) / dt + kr log(R(t_k) R^T)`` — the feed-forward is the exact mean
velocity over the step, the proportional term removes drift (float32 observations, clipping).
The action is the twist divided by the env's limits, clipped to [-1, 1].
"""

from __future__ import annotations

import math

import numpy as np

from brush_env.engine.rotation import logmap
from brush_env.motion import R0 as R_START
from brush_env.motion import Approach, Circle, Press, Sequence, Trajectory
from brush_env.motion.profiles import unit_profile

from .action import TcpVelocityAction
from .observation import ObservationLayout

__all__ = ["CircleReference", "ScrubReference", "SlidingPress", "PRESS_PROFILES"]

#: How the reference presses: "sliding" (descend while the stroke has begun; the default) or
#: "static" (the paper's: press at rest, then move).
PRESS_PROFILES = ("sliding", "static")


def _check_positive(**values) -> None:
    for name, val in values.items():
        if not (math.isfinite(val) and val > 0):
            raise ValueError(f"{name} = {val!r} is out of range: must be > 0")


def _check_nonnegative(**values) -> None:
    for name, val in values.items():
        if not (math.isfinite(val) and val >= 0):
            raise ValueError(f"{name} = {val!r} is out of range: must be >= 0")


def _check_press(press: str) -> None:
    if press not in PRESS_PROFILES:
        raise ValueError(f"press = {press!r} is not allowed: must be one of {list(PRESS_PROFILES)}")


class SlidingPress(Trajectory):
    """A stroke (``base``) with a press added over its first ``duration_press`` seconds: the
    quintic rest-to-rest descent of ``depth`` mm along ``axis`` (world frame, default the TCP z
    axis of the stroke's start pose: the bristle axis) is superposed on the stroke, so the brush
    is lowered onto the surface while it already moves.  Orientation and angle are the stroke's.
    Units: mm, s."""

    def __init__(self, base: Trajectory, depth: float, duration_press: float, axis=None):
        _check_positive(duration_press=duration_press)
        if not math.isfinite(depth):
            raise ValueError(f"depth = {depth!r} is out of range: must be finite (mm)")
        if duration_press > base.duration:
            raise ValueError(
                f"duration_press = {duration_press!r} s is out of range: must be <= the "
                f"stroke's duration ({base.duration:g} s)"
            )
        self.base, self.depth, self.duration_press = base, float(depth), float(duration_press)
        _, R = base.start_pose
        self.axis = R[:, 2].copy() if axis is None else np.asarray(axis, float)
        self.duration = base.duration
        self.has_angle = base.has_angle

    def _eval(self, t):
        P, R, V, W = self.base.sample(t)
        s, ds = unit_profile(np.minimum(t / self.duration_press, 1.0), "quintic")
        ds = np.where(t < self.duration_press, ds, 0.0)
        d = self.depth * self.axis
        return P + s[:, None] * d, R, V + (ds / self.duration_press)[:, None] * d, W

    def angle(self, t):
        return self.base.angle(t)

    def angle_rate(self, t):
        return self.base.angle_rate(t)


class CircleReference:
    """Plans and tracks the press-then-circle motion for one episode at a time.

    ``layout``/``action_type``/``dt``/``horizon`` come from the env (``BrushEnv.layout``,
    ``.action_type``, ``.dt``, ``.horizon``).  Geometry in mm about the nominal patch centre,
    speeds in mm/s, times in s, gains in 1/s.  ``press``: ``"sliding"`` (default: the press
    descends during the circle's first ``press_time`` s) or ``"static"`` (the paper's: press at
    rest, then the circle); ``press_depth`` [mm] past the nominal touch height (paper: 3).
    ``circle_start`` is the time [s] the circle begins, ``pressed_at`` the time the press ends.
    """

    def __init__(
        self,
        layout: ObservationLayout,
        action_type: TcpVelocityAction,
        dt: float,
        horizon: int,
        *,
        radius: float = 20.0,
        speed: float = 30.0,
        accel: float = 100.0,
        press_depth: float = 3.0,
        hover: float = 1.0,
        approach_time: float = 1.5,
        press_time: float = 1.0,
        center=(0.0, 0.0),
        start_angle: float = math.pi,
        clockwise: bool = False,
        kp: float = 5.0,
        kr: float = 5.0,
        press: str = "sliding",
    ):
        _check_positive(
            radius=radius, speed=speed, accel=accel, approach_time=approach_time,
            press_time=press_time, dt=dt,
        )  # fmt: skip
        _check_nonnegative(press_depth=press_depth, hover=hover, kp=kp, kr=kr)
        _check_press(press)
        self.press = press
        if speed > 0.8 * float(min(action_type.v_max[:2])):
            raise ValueError(
                f"speed = {speed!r} mm/s is out of range: must be <= 80 % of the "
                f"env's max_linear_speed in x, y ({list(action_type.v_max[:2])})"
            )
        self.layout, self.action_type = layout, action_type
        self.dt, self.horizon = float(dt), int(horizon)
        self.radius, self.speed, self.accel = radius, speed, accel
        self.press_depth, self.hover = press_depth, hover
        self.approach_time, self.press_time = approach_time, press_time
        self.center = np.array([center[0], center[1]], float)
        self.start_angle, self.clockwise = start_angle, clockwise
        self.kp, self.kr = kp, kr
        self.z_touch = layout.touch_height
        self.trajectory = None
        self.circle = None

    @property
    def rotates(self) -> bool:
        return self.action_type.dim == 6

    def _approach(self, p0, R0, P0, R_goal) -> Approach:
        """Quintic approach from the start pose to (P0, R_goal): at least ``approach_time``, and
        long enough that its peak speed (1.875 x the mean) stays under 80 % of the action
        limits."""
        d = np.abs(P0 - p0)
        rot = np.abs(logmap(R_goal @ R0.T))
        t_app = max(
            self.approach_time,
            float(np.max(1.875 * d / (0.8 * self.action_type.v_max))),
            float(np.max(1.875 * rot / (0.8 * self.action_type.w_max))) if self.rotates else 0.0,
        )
        return Approach((p0, R0), (P0, R_goal), t_app)

    def plan(self, p0: np.ndarray, R0: np.ndarray) -> None:
        """Build the trajectory from the start pose (base frame) and sample it on the step grid."""
        R_goal = R_START if self.rotates else R0
        ang = self.start_angle
        P0 = np.array(
            [
                self.center[0] + self.radius * math.cos(ang),
                self.center[1] + self.radius * math.sin(ang),
                self.z_touch + self.hover,
            ]
        )
        approach = self._approach(p0, R0, P0, R_goal)
        t_app = approach.duration
        static = self.press == "static"
        depth = self.hover + self.press_depth
        # static: the circle runs pressed, after the press; sliding: at hover, the press added
        z_c = self.z_touch - self.press_depth if static else P0[2]
        t_left = max(self.horizon * self.dt - t_app - (self.press_time if static else 0.0), 1.0)
        turns = max(0.25, t_left * self.speed / (2.0 * math.pi * self.radius) + 0.25)
        self.circle = Circle(
            (self.center[0], self.center[1], z_c),
            self.radius,
            self.speed,
            self.accel,
            turns=turns,
            start_angle=ang,
            R=R_goal,
            clockwise=self.clockwise,
        )
        if static:
            press = Press((P0, R_goal), depth, self.press_time)
            self.trajectory = Sequence([approach, press, self.circle])
            self.circle_start = t_app + self.press_time
            self.pressed_at = self.circle_start
        else:
            stroke = SlidingPress(self.circle, depth, min(self.press_time, self.circle.duration))
            self.trajectory = Sequence([approach, stroke])
            self.circle_start = t_app
            self.pressed_at = t_app + self.press_time
        times = np.arange(self.horizon + 2) * self.dt
        self._P, self._R, _, _ = self.trajectory.sample(times)

    def desired(self, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Planned pose at step k (held at the last sample beyond the horizon)."""
        k = min(max(int(k), 0), len(self._P) - 1)
        return self._P[k], self._R[k]

    def act(self, k: int, p: np.ndarray, R: np.ndarray) -> np.ndarray:
        """Action at step k for the observed pose (p [mm], R); plans first at k == 0."""
        if k == 0 or self.trajectory is None:
            self.plan(p, R)
        k0 = min(max(int(k), 0), len(self._P) - 2)
        P0, P1 = self._P[k0], self._P[k0 + 1]
        R0, R1 = self._R[k0], self._R[k0 + 1]
        v = (P1 - P0) / self.dt + self.kp * (P0 - p)
        w = (
            logmap(R1 @ R0.T) / self.dt + self.kr * logmap(R0 @ R.T)
            if self.rotates
            else np.zeros(3)
        )
        return self.action_type.normalise(v, w)


class ScrubReference(CircleReference):
    """The horizontal scrub on a tooth row (ToothRow-v0's reference policy): approach to ``hover``
    mm above the first stroke's start, press ``press_depth`` mm past the crowns' buccal plane
    (the touch height, as on the plate), then strokes along the row (x) between ``x_range`` at
    ``speed`` (quintic rest-to-rest: peak ``speed``), the stroke's height on the crowns (y)
    cycling through ``y_levels`` so that the cervical third, the middle and the occlusal third
    are each scrubbed.  The horizontal scrub is the stroke most uninstructed adults use (Ganss et
    al., Clin Oral Investig 13, 2009, 203-208); docs/env.md ("ToothRow-v0").  Tracking law and
    action as :class:`CircleReference`; ``press`` as there (``"static"``, the default here:
    press at rest, then scrub; ``"sliding"``: the press descends during the first stroke's first
    ``press_time`` s).  The scrub keeps the static press: its 2 mm press stays within the 4 N
    limit (peak ~2.4 N) and scores higher than the sliding one (``python -m agents.probe_reward
    --env brush_env/ToothRow-v0``, docs/rl.md).  Units: mm, mm/s, s, 1/s.
    """

    def __init__(
        self,
        layout: ObservationLayout,
        action_type: TcpVelocityAction,
        dt: float,
        horizon: int,
        *,
        x_range=(-9.0, 9.0),
        y_levels=(3.5, 1.5, 5.5),
        speed: float = 30.0,
        press_depth: float = 2.0,
        hover: float = 1.0,
        approach_time: float = 1.5,
        press_time: float = 1.0,
        kp: float = 5.0,
        kr: float = 5.0,
        press: str = "static",
    ):
        _check_positive(speed=speed, approach_time=approach_time, press_time=press_time, dt=dt)
        _check_nonnegative(press_depth=press_depth, hover=hover, kp=kp, kr=kr)
        _check_press(press)
        self.press = press
        if not (len(x_range) == 2 and x_range[1] > x_range[0]):
            raise ValueError(f"x_range = {x_range!r}: must be [x_min, x_max] with x_min < x_max")
        if not y_levels:
            raise ValueError("y_levels must name at least one stroke height (mm)")
        if speed > 0.8 * float(action_type.v_max[0]):
            raise ValueError(
                f"speed = {speed!r} mm/s is out of range: must be <= 80 % of the env's "
                f"max_linear_speed in x ({float(action_type.v_max[0])})"
            )
        self.layout, self.action_type = layout, action_type
        self.dt, self.horizon = float(dt), int(horizon)
        self.x_range, self.y_levels = tuple(map(float, x_range)), tuple(map(float, y_levels))
        self.speed, self.press_depth, self.hover = speed, press_depth, hover
        self.approach_time, self.press_time = approach_time, press_time
        self.kp, self.kr = kp, kr
        self.z_touch = layout.touch_height
        self.trajectory = None
        self.circle = None

    def plan(self, p0: np.ndarray, R0: np.ndarray) -> None:
        R_goal = R_START if self.rotates else R0
        x0, x1 = self.x_range
        ys = self.y_levels
        static = self.press == "static"
        depth = self.hover + self.press_depth
        P0 = np.array([x0, ys[0], self.z_touch + self.hover])
        # static: the strokes run pressed, after the press; sliding: at hover, the press added
        z_c = self.z_touch - self.press_depth if static else P0[2]
        approach = self._approach(p0, R0, P0, R_goal)
        t_app = approach.duration
        t_left = self.horizon * self.dt - t_app - (self.press_time if static else 0.0)
        strokes: list[Trajectory] = []
        p = np.array([x0, ys[0], z_c])
        k = 0
        while t_left > 0 or not strokes:
            k += 1
            q = np.array([x1 if k % 2 else x0, ys[(k // 2) % len(ys)], z_c])
            T = 1.875 * float(np.linalg.norm(q - p)) / self.speed
            strokes.append(Approach((p, R_goal), (q, R_goal), T))
            t_left -= T
            p = q
        scrub = Sequence(strokes)
        if static:
            press = Press((P0, R_goal), depth, self.press_time)
            self.trajectory = Sequence([approach, press, scrub])
            self.circle_start = t_app + self.press_time
            self.pressed_at = self.circle_start
        else:
            t_press = min(self.press_time, scrub.duration)
            self.trajectory = Sequence([approach, SlidingPress(scrub, depth, t_press)])
            self.circle_start = t_app
            self.pressed_at = t_app + t_press
        times = np.arange(self.horizon + 2) * self.dt
        self._P, self._R, _, _ = self.trajectory.sample(times)
