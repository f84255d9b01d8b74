"""Primitive TCP motions and their concatenation: ``Hold``, ``Press``, ``Approach``, ``Sequence``.

``Press`` is the paper's press of the brush onto the plate (§5.1, 3 mm along the bristle axis) and
``Approach`` stands in for the UR5's MoveJ (§4); both are rest-to-rest, driven by the quintic
(minimum jerk) or the eq 10 cubic unit profile of ``motion.profiles``.
"""

from __future__ import annotations

from collections.abc import Sequence as _SequenceABC

import numpy as np

from brush_env.engine.checks import ConfigError, check_choice, check_real, check_unit
from brush_env.engine.rotation import expmap, logmap

from .base import DURATION, MM, Trajectory, check_pose, const_pose
from .profiles import PROFILES, clip, unit_profile

__all__ = ["Hold", "Press", "Approach", "Sequence"]

_POSE_TOL = 1e-9  # continuity tolerance of Sequence (mm for positions, 1 for matrix entries)


class Hold(Trajectory):
    """Stay at ``pose = (p, R)`` for ``duration`` seconds (zero twist)."""

    def __init__(self, pose, duration: float):
        self.p, self.R = check_pose("pose", pose)
        self.duration = check_real("duration", duration, DURATION)

    def _eval(self, t):
        return const_pose(self.p, self.R, t.shape[0])


class Press(Trajectory):
    """Translate by ``depth`` mm along the bristle axis, rest to rest, orientation fixed.

    ``axis`` (world frame) defaults to the TCP z axis ``R[:, 2]`` of ``start_pose`` — the bristle
    axis, pointing from the head to the tips; with ``R0`` it is ``-z``, so a positive depth presses
    the brush onto the plate (the paper's 3 mm press, §5.1) and a negative depth lifts it.

    Velocity profile ``p(t) = p0 + depth * axis * sigma(t / duration)``:
    ``profile='quintic'`` (default) is the minimum-jerk ``10τ³ - 15τ⁴ + 6τ⁵`` — zero velocity *and*
    acceleration at both ends, so the press does not jolt the bristles; ``profile='cubic'`` is the
    eq 10 cubic step ``3τ² - 2τ³`` (zero velocity, acceleration jumps at the ends).
    Peak speed: ``1.875 |depth| / duration`` (quintic), ``1.5 |depth| / duration`` (cubic).
    """

    def __init__(self, start_pose, depth: float, duration: float, axis=None, profile="quintic"):
        self.p0, self.R = check_pose("start_pose", start_pose)
        self.depth = check_real("depth", depth, MM)
        self.duration = check_real("duration", duration, DURATION)
        self.axis = self.R[:, 2].copy() if axis is None else check_unit("axis", axis)
        self.profile = check_choice("profile", profile, PROFILES, "profile")

    def _eval(self, t):
        s, ds = unit_profile(t / self.duration, self.profile)
        d = self.depth * self.axis
        n = t.shape[0]
        P = self.p0 + s[:, None] * d
        V = (ds / self.duration)[:, None] * d
        return P, np.broadcast_to(self.R, (n, 3, 3)).copy(), V, np.zeros((n, 3))


class Approach(Trajectory):
    """MoveJ-like approach from ``start_pose`` to ``end_pose`` in ``duration`` seconds.

    The UR5's MoveJ interpolates in joint space (a curved tool path, §4).  Without a robot model we
    use a documented stand-in: the straight line between the two positions and the geodesic (slerp)
    between the two orientations, both driven by the same rest-to-rest profile
    ``sigma(t / duration)`` (``'quintic'`` minimum jerk by default, or the eq 10 ``'cubic'``):
    ``p = p0 + (p1 - p0) sigma``, ``R = R_0 exp(sigma log(R_0^T R_1))``.  Velocity is zero at both
    ends, so it chains smoothly with Press / Hold / Circle in a ``Sequence``.
    """

    def __init__(self, start_pose, end_pose, duration: float, profile="quintic"):
        self.p0, self.R0 = check_pose("start_pose", start_pose)
        self.p1, self.R1 = check_pose("end_pose", end_pose)
        self.duration = check_real("duration", duration, DURATION)
        self.profile = check_choice("profile", profile, PROFILES, "profile")
        self.rotvec = logmap(self.R0.T @ self.R1)  # in the start TCP frame

    def _eval(self, t):
        s, ds = unit_profile(t / self.duration, self.profile)
        sd = ds / self.duration
        P = self.p0 + s[:, None] * (self.p1 - self.p0)
        V = sd[:, None] * (self.p1 - self.p0)
        R = self.R0 @ expmap(s[:, None] * self.rotvec)
        # body rate sd * rotvec; exp(s k) k = k, so the world rate is R_0 (sd * rotvec)
        W = sd[:, None] * (self.R0 @ self.rotvec)
        return P, R, V, W


class Sequence(Trajectory):
    """Trajectories concatenated in time; each must start where the previous one ended.

    Pose continuity is checked at construction (position within 1e-9 mm, rotation-matrix entries
    within 1e-9); a gap raises ``ConfigError`` (a ValueError) naming the segment.  (Velocity
    continuity is not enforced; all rest-to-rest motions here start and end at zero twist.)

    At a boundary time the later segment is evaluated.  ``angle(t)`` is the sum of the angles of
    the segments that carry one (each 0 before it starts and its final value after it ends), so a
    ``Sequence(Press, Circle, ...)`` exposes the circle's θ for ``PitchPerturbation``.
    """

    def __init__(self, segments: _SequenceABC[Trajectory]):
        segs = list(segments)
        if len(segs) == 0:
            raise ConfigError("segments must contain at least one Trajectory, got an empty list")
        for k, s in enumerate(segs):
            if not isinstance(s, Trajectory):
                raise ConfigError(f"segment {k} must be a Trajectory, got {type(s).__name__}")
        for k in range(1, len(segs)):
            pe, Re = segs[k - 1].end_pose
            ps, Rs = segs[k].start_pose
            dp = float(np.max(np.abs(pe - ps)))
            dR = float(np.max(np.abs(Re - Rs)))
            if dp > _POSE_TOL or dR > _POSE_TOL:
                raise ConfigError(
                    f"segment {k} ({type(segs[k]).__name__}) does not start where segment {k - 1} "
                    f"({type(segs[k - 1]).__name__}) ends: position gap {dp:.3g} mm, rotation gap "
                    f"{dR:.3g} (allowed <= {_POSE_TOL:g}); start p = {ps.tolist()}, previous end "
                    f"p = {pe.tolist()}"
                )
        self.segments = segs
        self.start_times = np.concatenate([[0.0], np.cumsum([s.duration for s in segs])])
        self.duration = float(self.start_times[-1])
        self.has_angle = any(s.has_angle for s in segs)

    def _index(self, t: np.ndarray) -> np.ndarray:
        return clip(
            np.searchsorted(self.start_times, t, side="right") - 1, 0, len(self.segments) - 1
        )

    def _eval(self, t):
        k = self._index(t)
        if k.min() == k.max():  # fast path (scalar queries)
            j = int(k[0])
            seg = self.segments[j]
            return seg._eval(clip(t - self.start_times[j], 0.0, seg.duration))
        n = t.shape[0]
        P, R, V, W = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
        for j in np.unique(k):
            m = k == j
            seg = self.segments[j]
            tl = clip(t[m] - self.start_times[j], 0.0, seg.duration)
            P[m], R[m], V[m], W[m] = seg._eval(tl)
        return P, R, V, W

    def angle(self, t):
        if not self.has_angle:
            return super().angle(t)
        tt = np.asarray(t, dtype=float)
        out = np.zeros(tt.shape)
        for j, seg in enumerate(self.segments):
            if seg.has_angle:
                tl = clip(tt - self.start_times[j], 0.0, seg.duration)
                out = out + np.asarray(seg.angle(tl), dtype=float)
        return float(out) if out.ndim == 0 else out

    def angle_rate(self, t):
        if not self.has_angle:
            return super().angle_rate(t)
        tt = np.asarray(t, dtype=float)
        k = self._index(np.atleast_1d(tt))
        out = np.zeros(np.atleast_1d(tt).shape)
        for j, seg in enumerate(self.segments):
            if seg.has_angle:
                m = k == j
                if np.any(m):
                    out[m] = np.asarray(
                        seg.angle_rate(np.atleast_1d(tt)[m] - self.start_times[j]), dtype=float
                    )
        inside = (np.atleast_1d(tt) >= 0.0) & (np.atleast_1d(tt) <= self.duration)
        out = np.where(inside, out, 0.0)
        return float(out[0]) if tt.ndim == 0 else out
