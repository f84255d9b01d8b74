"""The trajectory protocol and its primitives: ``Trajectory`` (pose, twist and vectorised
``sample`` over time), ``Hold``, ``Press`` (the 3 mm press along the bristle axis, §4),
``Approach`` (MoveJ stand-in) and ``Sequence`` (segments joined end to end, continuity checked)."""

from __future__ import annotations

from collections.abc import Sequence as _SequenceABC

import numpy as np

from ..engine.checks import (
    POSITIVE,
    check_real,
    check_rotation,
    check_unit,
    check_vec,
)
from ..engine.rotation import expmap, logmap
from .profiles import _clip, _unit_profile

#: Default TCP orientation of the brush: tool x = world x, tool y = -world y, tool z = -world z
#: (bristles pointing down onto the plate z = 0).
R0 = np.diag([1.0, -1.0, -1.0])
R0.setflags(write=False)

_POSE_TOL = 1e-9  # continuity tolerance of Sequence (mm for positions, 1 for matrix entries)


def _pose(name: str, value) -> tuple[np.ndarray, np.ndarray]:
    """Accept ``(p, R)`` or a bare position ``p`` (orientation then R0)."""
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return np.array(check_vec(f"{name}[0] (position)", value[0], 3)), check_rotation(
            f"{name}[1] (rotation)", value[1]
        )
    return np.array(check_vec(name, value, 3)), np.array(R0)


def _profile_name(value) -> str:
    if value not in ("quintic", "cubic"):
        raise ValueError(f"profile must be one of 'quintic', 'cubic', got {value!r}")
    return value


# --------------------------------------------------------------------------------------------
# base class
# --------------------------------------------------------------------------------------------
class Trajectory:
    """Base class: a TCP motion over ``[0, duration]``.

    Subclasses implement ``_eval(t)`` for a 1-D array of times already clamped to
    ``[0, duration]``, returning ``(P (N,3), R (N,3,3), V (N,3), W (N,3))``.

    Trajectories that carry a rotation angle (the circle: θ of the paper's Figure 7 axis) set
    ``has_angle = True`` and implement ``angle(t)`` / ``angle_rate(t)``.
    """

    duration: float
    has_angle: bool = False

    # -- public API -----------------------------------------------------------------------
    def sample(self, times):
        """Vectorised evaluation: ``(P (N,3), R (N,3,3), V (N,3), W (N,3))`` at ``times`` (N,)."""
        t = np.atleast_1d(np.asarray(times, dtype=float))
        if t.ndim != 1:
            raise ValueError(f"times must be a scalar or a 1-D array, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise ValueError("times must be finite (allowed range (-inf, inf))")
        tc = _clip(t, 0.0, self.duration)
        P, R, V, W = self._eval(tc)
        outside = (t < 0.0) | (t > self.duration)
        if np.any(outside):
            V = V.copy()
            W = W.copy()
            V[outside] = 0.0
            W[outside] = 0.0
        return P, R, V, W

    def pose(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(p (3,), R (3,3))`` at time ``t``."""
        P, R, _, _ = self.sample(np.array([t], dtype=float))
        return P[0], R[0]

    def twist(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """``(v (3,) mm/s, w (3,) rad/s)`` in the world frame at time ``t``."""
        _, _, V, W = self.sample(np.array([t], dtype=float))
        return V[0], W[0]

    def state(self, t: float):
        """``(p, R, v, w)`` at time ``t`` in one evaluation."""
        P, R, V, W = self.sample(np.array([t], dtype=float))
        return P[0], R[0], V[0], W[0]

    @property
    def start_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self.pose(0.0)

    @property
    def end_pose(self) -> tuple[np.ndarray, np.ndarray]:
        return self.pose(self.duration)

    def angle(self, t):
        raise ValueError(f"{type(self).__name__} has no rotation angle (has_angle is False)")

    def angle_rate(self, t):
        raise ValueError(f"{type(self).__name__} has no rotation angle (has_angle is False)")

    def _angle_and_rate(self, t: np.ndarray):
        """(θ, dθ/dt) at a 1-D array of times; subclasses may share work between the two."""
        return self.angle(t), self.angle_rate(t)

    # -- to implement ---------------------------------------------------------------------
    def _eval(self, t: np.ndarray):  # pragma: no cover - abstract
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"{type(self).__name__}(duration={self.duration:.6g} s)"


def _const_pose(p: np.ndarray, R: np.ndarray, n: int):
    P = np.broadcast_to(p, (n, 3)).copy()
    Rs = np.broadcast_to(R, (n, 3, 3)).copy()
    return P, Rs, np.zeros((n, 3)), np.zeros((n, 3))


# --------------------------------------------------------------------------------------------
# Hold, Press, Approach
# --------------------------------------------------------------------------------------------
class Hold(Trajectory):
    """Stay at ``pose = (p, R)`` for ``duration`` seconds (zero twist)."""

    def __init__(self, pose, duration: float):
        self.p, self.R = _pose("pose", pose)
        self.duration = check_real("duration", duration, POSITIVE)

    def _eval(self, t):
        return _const_pose(self.p, self.R, t.shape[0])


class Press(Trajectory):
    """Translate by ``depth`` mm along the bristle axis, rest to rest, orientation fixed.

    ``axis`` (world frame) defaults to the TCP z axis ``R[:, 2]`` of ``start_pose`` — the bristle
    axis, pointing from the head to the tips; with ``R0`` it is ``-z``, so a positive depth presses
    the brush onto the plate (the paper's 3 mm press, §5.1) and a negative depth lifts it.

    Velocity profile ``p(t) = p0 + depth * axis * sigma(t / duration)``:
    ``profile='quintic'`` (default) is the minimum-jerk ``10τ³ - 15τ⁴ + 6τ⁵`` — zero velocity *and*
    acceleration at both ends, so the press does not jolt the bristles; ``profile='cubic'`` is the
    eq-10 cubic step ``3τ² - 2τ³`` (zero velocity, acceleration jumps at the ends).
    Peak speed: ``1.875 |depth| / duration`` (quintic), ``1.5 |depth| / duration`` (cubic).
    """

    def __init__(self, start_pose, depth: float, duration: float, axis=None, profile="quintic"):
        self.p0, self.R = _pose("start_pose", start_pose)
        self.depth = check_real("depth", depth)
        self.duration = check_real("duration", duration, POSITIVE)
        self.axis = self.R[:, 2].copy() if axis is None else check_unit("axis", axis)
        self.profile = _profile_name(profile)

    def _eval(self, t):
        s, ds = _unit_profile(t / self.duration, self.profile)
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
    ``sigma(t / duration)`` (``'quintic'`` minimum jerk by default, or the eq-10 ``'cubic'``):
    ``p = p0 + (p1 - p0) sigma``, ``R = R_0 exp(sigma log(R_0^T R_1))``.  Velocity is zero at both
    ends, so it chains smoothly with Press / Hold / Circle in a ``Sequence``.
    """

    def __init__(self, start_pose, end_pose, duration: float, profile="quintic"):
        self.p0, self.R0 = _pose("start_pose", start_pose)
        self.p1, self.R1 = _pose("end_pose", end_pose)
        self.duration = check_real("duration", duration, POSITIVE)
        self.profile = _profile_name(profile)
        self.rotvec = logmap(self.R0.T @ self.R1)  # in the start TCP frame

    def _eval(self, t):
        s, ds = _unit_profile(t / self.duration, self.profile)
        sd = ds / self.duration
        P = self.p0 + s[:, None] * (self.p1 - self.p0)
        V = sd[:, None] * (self.p1 - self.p0)
        R = self.R0 @ expmap(s[:, None] * self.rotvec)
        # body rate sd * rotvec; exp(s k) k = k, so the world rate is R_0 (sd * rotvec)
        W = sd[:, None] * (self.R0 @ self.rotvec)
        return P, R, V, W


# --------------------------------------------------------------------------------------------
# Sequence
# --------------------------------------------------------------------------------------------
class Sequence(Trajectory):
    """Trajectories concatenated in time; each must start where the previous one ended.

    Pose continuity is checked at construction (position within 1e-9 mm, rotation-matrix entries
    within 1e-9); a gap raises ``ValueError`` naming the segment.  (Velocity continuity is not
    enforced; all rest-to-rest motions here start and end at zero twist.)

    At a boundary time the later segment is evaluated.  ``angle(t)`` is the sum of the angles of
    the segments that carry one (each 0 before it starts and its final value after it ends), so a
    ``Sequence(Press, Circle, ...)`` exposes the circle's θ for ``PitchPerturbation``.
    """

    def __init__(self, segments: _SequenceABC[Trajectory]):
        segs = list(segments)
        if len(segs) == 0:
            raise ValueError("segments must contain at least one Trajectory, got an empty list")
        for k, s in enumerate(segs):
            if not isinstance(s, Trajectory):
                raise ValueError(  # noqa: TRY004 - the project reports bad input as ValueError
                    f"segment {k} must be a Trajectory, got {type(s).__name__}"
                )
        for k in range(1, len(segs)):
            pe, Re = segs[k - 1].end_pose
            ps, Rs = segs[k].start_pose
            dp = float(np.max(np.abs(pe - ps)))
            dR = float(np.max(np.abs(Re - Rs)))
            if dp > _POSE_TOL or dR > _POSE_TOL:
                raise ValueError(
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
        return _clip(
            np.searchsorted(self.start_times, t, side="right") - 1, 0, len(self.segments) - 1
        )

    def _eval(self, t):
        k = self._index(t)
        if k.min() == k.max():  # fast path (scalar queries)
            j = int(k[0])
            seg = self.segments[j]
            return seg._eval(_clip(t - self.start_times[j], 0.0, seg.duration))
        n = t.shape[0]
        P, R, V, W = np.empty((n, 3)), np.empty((n, 3, 3)), np.empty((n, 3)), np.empty((n, 3))
        for j in np.unique(k):
            m = k == j
            seg = self.segments[j]
            tl = _clip(t[m] - self.start_times[j], 0.0, seg.duration)
            P[m], R[m], V[m], W[m] = seg._eval(tl)
        return P, R, V, W

    def angle(self, t):
        if not self.has_angle:
            return super().angle(t)
        tt = np.asarray(t, dtype=float)
        out = np.zeros(tt.shape)
        for j, seg in enumerate(self.segments):
            if seg.has_angle:
                tl = _clip(tt - self.start_times[j], 0.0, seg.duration)
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
