"""The ``Trajectory`` base class, the brush's default TCP orientation ``R0`` and shared helpers.

A trajectory maps time t [s] to the TCP pose ``(p [mm], R)`` and twist ``(v [mm/s], w [rad/s])``
(world frame, ``dp/dt = v``, ``dR/dt = [w]x R``) that drive the brush base in the engine (§4).
"""

from __future__ import annotations

import numpy as np

from brush_env.engine.checks import ConfigError, Limit, check_rotation, check_vec

from .profiles import clip

__all__ = [
    "R0",
    "Trajectory",
    "check_pose",
    "const_pose",
    "plane_basis",
    "check_point",
    "MM",
    "LENGTH",
    "SPEED",
    "ACCEL",
    "DURATION",
    "ANGLE",
]

#: Default TCP orientation of the brush: tool x = world x, tool y = -world y, tool z = -world z
#: (bristles pointing down onto the plate z = 0).
R0 = np.diag([1.0, -1.0, -1.0])
R0.setflags(write=False)

#: Ranges of the motion parameters, with their units (for the shared checks of engine.checks).
MM = Limit("mm")
LENGTH = Limit("mm", gt=0)
SPEED = Limit("mm/s", gt=0)
ACCEL = Limit("mm/s^2", gt=0)
DURATION = Limit("s", gt=0)
ANGLE = Limit("rad")


def check_point(name: str, value) -> np.ndarray:
    """A finite 3-vector [mm] as a float array (ConfigError naming ``name`` otherwise)."""
    return np.array(check_vec(name, value, 3, MM))


def check_pose(name: str, value) -> tuple[np.ndarray, np.ndarray]:
    """Accept ``(p, R)`` or a bare position ``p`` (orientation then R0)."""
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return (
            check_point(f"{name}[0] (position)", value[0]),
            check_rotation(f"{name}[1] (rotation)", value[1]),
        )
    return check_point(name, value), np.array(R0)


def const_pose(p: np.ndarray, R: np.ndarray, n: int):
    """``n`` samples of the constant pose (p, R) with zero twist."""
    P = np.broadcast_to(p, (n, 3)).copy()
    Rs = np.broadcast_to(R, (n, 3, 3)).copy()
    return P, Rs, np.zeros((n, 3)), np.zeros((n, 3))


def plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane basis (e1, e2) with e1 x e2 = normal; e1 = world x projected (or y if parallel)."""
    ref = np.array([1.0, 0.0, 0.0])
    if np.linalg.norm(np.cross(ref, normal)) < 1e-6:
        ref = np.array([0.0, 1.0, 0.0])
    e1 = ref - np.dot(ref, normal) * normal
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return e1, e2


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
            raise ConfigError(f"times must be a scalar or a 1-D array, got shape {t.shape}")
        if not np.all(np.isfinite(t)):
            raise ConfigError("times must be finite (allowed range (-inf, inf))")
        tc = clip(t, 0.0, self.duration)
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
