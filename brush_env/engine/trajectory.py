"""TCP trajectories: base (TCP) pose and twist over time.

Engine-side utilities that know nothing of Gymnasium.  They reproduce the robot motions of
Cirelli et al. (Machines 2023), §4-§5: the press of the brush onto the plate, the circular path the
UR5 builds from four ``MoveL`` control points with blend radius (Algorithm 1, Figures 5-6), the
MoveJ approach, and the 1° pitch perturbation of eq 12 (§5.2).

Conventions
-----------
* Units: mm, s, rad.
* World frame = robot base frame, z up; the plate is the plane z = 0 with normal +z.
* A *pose* is ``(p, R)``: ``p`` (3,) TCP position in mm, ``R`` (3, 3) rotation matrix TCP -> world.
* A *twist* is ``(v, w)``: linear velocity of the TCP origin (mm/s) and angular velocity (rad/s),
  both expressed in the world frame, so ``dp/dt = v`` and ``dR/dt = [w]x R``.
* The brush's default TCP orientation is ``R0 = diag(1, -1, -1)`` (tool z pointing down onto the
  plate); the bristle tips sit at TCP z-offset ``L`` (longest bristle), so "touching" is ``p_z = L``.

Every trajectory has ``duration``, ``pose(t)``, ``twist(t)``, ``state(t)`` and the vectorised
``sample(times) -> (P (N,3), R (N,3,3), V (N,3), W (N,3))``.  Times are clamped to
``[0, duration]``: before the start the start pose is held, after the end the end pose is held, and
the twist outside ``[0, duration]`` is zero.  Scalar queries cost ~40-350 µs (Python overhead);
for long runs sample the whole time grid once with ``sample`` (~2 µs per time).

Overview: ``Hold``, ``Press`` (along the bristle axis), ``Approach`` (MoveJ stand-in), ``Circle``
(exact circle, trapezoidal speed, ``angle(t)`` = θ of the paper's Figure 7), ``MoveL`` (UR-style
linear moves with blend radius; ``paper_circle_movel`` builds Algorithm 1), ``PitchPerturbation``
(eq 12), ``Sequence``; ``paper_circle_waypoints`` and ``movel_circle_deviation`` quantify how far
the four-point MoveL path is from the exact circle.

Validation: bad input raises ``ValueError`` naming the parameter, the value and the allowed range.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from collections.abc import Sequence as _SequenceABC

import numpy as np

__all__ = [
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

#: Default TCP orientation of the brush: tool x = world x, tool y = -world y, tool z = -world z
#: (bristles pointing down onto the plate z = 0).
R0 = np.diag([1.0, -1.0, -1.0])
R0.setflags(write=False)

_POSE_TOL = 1e-9  # continuity tolerance of Sequence (mm for positions, 1 for matrix entries)


def _clip(x, lo, hi):
    """np.clip without its per-call overhead (hot in scalar pose queries)."""
    return np.minimum(np.maximum(x, lo), hi)


# --------------------------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------------------------
def _number(name: str, value, what: str, rng: str, ok) -> float:
    """float(value), or ValueError naming the parameter, the value and the allowed range."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        kind = "a finite number" if what == "finite" else f"a number {what}"
        raise ValueError(f"{name} must be {kind} (allowed range {rng}), got {value!r}")
    if not (math.isfinite(x) and ok(x)):
        raise ValueError(f"{name} must be {what} (allowed range {rng}), got {value!r}")
    return x


def _positive(name: str, value) -> float:
    return _number(name, value, "> 0", "(0, inf)", lambda x: x > 0.0)


def _nonneg(name: str, value) -> float:
    return _number(name, value, ">= 0", "[0, inf)", lambda x: x >= 0.0)


def _finite(name: str, value) -> float:
    return _number(name, value, "finite", "(-inf, inf)", lambda x: True)


def _vec3(name: str, value) -> np.ndarray:
    try:
        v = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite 3-vector (mm), got {value!r}")
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ValueError(f"{name} must be a finite 3-vector (shape (3,)), got {value!r}")
    return v


def _unit3(name: str, value) -> np.ndarray:
    v = _vec3(name, value)
    n = float(np.linalg.norm(v))
    if n < 1e-12:
        raise ValueError(f"{name} must be a non-zero 3-vector (norm > 0), got {value!r}")
    return v / n


def _rotation(name: str, value) -> np.ndarray:
    try:
        R = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a 3x3 rotation matrix, got {value!r}")
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ValueError(f"{name} must be a finite 3x3 rotation matrix, got shape {R.shape}")
    err = float(np.max(np.abs(R.T @ R - np.eye(3))))
    if err > 1e-6 or np.linalg.det(R) <= 0.0:
        raise ValueError(
            f"{name} must be a rotation matrix (R^T R = I within 1e-6, det = +1); "
            f"got |R^T R - I|max = {err:.3g}, det = {np.linalg.det(R):.6g}"
        )
    return R


def _pose(name: str, value) -> tuple[np.ndarray, np.ndarray]:
    """Accept ``(p, R)`` or a bare position ``p`` (orientation then R0)."""
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return _vec3(f"{name}[0] (position)", value[0]), _rotation(
            f"{name}[1] (rotation)", value[1]
        )
    return _vec3(name, value), np.array(R0)


def _profile_name(value) -> str:
    if value not in ("quintic", "cubic"):
        raise ValueError(f"profile must be one of 'quintic', 'cubic', got {value!r}")
    return value


# --------------------------------------------------------------------------------------------
# eq 10: cubic step
# --------------------------------------------------------------------------------------------
def _step_u(x, x0, x1):
    """Checked (x0, x1) and the step's normalised coordinate u = (x - x0)/(x1 - x0) in [0, 1]."""
    x0 = _finite("x0", x0)
    x1 = _finite("x1", x1)
    if x0 == x1:
        raise ValueError(f"x1 must differ from x0 (allowed: x1 != x0), got x0 = x1 = {x0!r}")
    x = np.asarray(x, dtype=float)
    return x0, x1, _clip((x - x0) / (x1 - x0), 0.0, 1.0)


def smoothstep(x, x0, h0, x1, h1):
    """Cubic step of eq 10 (the ``step`` function of ADAMS-like multibody codes).

    ``h0`` for ``x <= x0``, ``h1`` for ``x >= x1`` and
    ``h0 + (h1 - h0) * u**2 * (3 - 2 u)`` with ``u = (x - x0) / (x1 - x0)`` in between.
    The printed eq 10 shows ``x0 <= |x| <= x1`` for the middle branch; the intended (and used) form
    is ``x0 <= x <= x1``.  ``x1 < x0`` is allowed and gives the mirrored step (``h1`` for
    ``x <= x1``, ``h0`` for ``x >= x0``).  Vectorised over ``x``; returns a float for scalar input.
    """
    x0, x1, u = _step_u(x, x0, x1)
    out = h0 + (h1 - h0) * u * u * (3.0 - 2.0 * u)
    return float(out) if out.ndim == 0 else out


def smoothstep_dot(x, x0, h0, x1, h1):
    """Derivative d smoothstep / dx: ``(h1 - h0) * 6 u (1 - u) / (x1 - x0)``, zero outside."""
    x0, x1, u = _step_u(x, x0, x1)
    out = (h1 - h0) * 6.0 * u * (1.0 - u) / (x1 - x0)
    return float(out) if out.ndim == 0 else out


def _unit_profile(tau: np.ndarray, profile: str) -> tuple[np.ndarray, np.ndarray]:
    """Rest-to-rest unit profile sigma(tau), dsigma/dtau on tau in [0, 1]."""
    tau = _clip(tau, 0.0, 1.0)
    if profile == "quintic":  # minimum jerk: zero velocity and acceleration at both ends
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        ds = 30.0 * tau * tau * (1.0 - tau) ** 2
    else:  # eq-10 cubic step: zero velocity at both ends, acceleration jumps to +-6/T^2
        s = tau * tau * (3.0 - 2.0 * tau)
        ds = 6.0 * tau * (1.0 - tau)
    return s, ds


# --------------------------------------------------------------------------------------------
# SO(3) helpers (private; vectorised)
# --------------------------------------------------------------------------------------------
def _skew(w: np.ndarray) -> np.ndarray:
    w = np.asarray(w, dtype=float)
    S = np.zeros(w.shape[:-1] + (3, 3))
    S[..., 0, 1] = -w[..., 2]
    S[..., 0, 2] = w[..., 1]
    S[..., 1, 0] = w[..., 2]
    S[..., 1, 2] = -w[..., 0]
    S[..., 2, 0] = -w[..., 1]
    S[..., 2, 1] = w[..., 0]
    return S


def _exp_so3(w: np.ndarray) -> np.ndarray:
    """Rodrigues: rotation vector(s) (..., 3) -> rotation matrices (..., 3, 3)."""
    w = np.asarray(w, dtype=float)
    th2 = np.sum(w * w, axis=-1)
    th = np.sqrt(th2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0 + th2 * th2 / 120.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th2 / 24.0 + th2 * th2 / 720.0, (1.0 - np.cos(ths)) / (ths * ths))
    K = _skew(w)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def _log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vector of one rotation matrix (robust up to and including pi)."""
    R = np.asarray(R, dtype=float)
    c = _clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = math.acos(c)
    vee = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-6:
        return 0.5 * vee
    if th < math.pi - 1e-4:
        return th / (2.0 * math.sin(th)) * vee
    # near pi: the rotation axis from the symmetric part;
    # R = c I + sin(th) [n]x + (1 - c) n n^T: the symmetric part gives n n^T
    M = (0.5 * (R + R.T) - c * np.eye(3)) / (1.0 - c)
    k = int(np.argmax(np.diag(M)))
    n = M[:, k] / math.sqrt(max(M[k, k], 1e-300))
    n /= np.linalg.norm(n)
    if np.dot(n, vee) < 0.0:
        n = -n
    return th * n


def _rot_axis(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rotations about a fixed unit axis by angles (N,) -> (N, 3, 3)."""
    angle = np.asarray(angle, dtype=float)
    return _exp_so3(angle[..., None] * axis)


# --------------------------------------------------------------------------------------------
# trapezoidal speed profile (used by Circle and MoveL)
# --------------------------------------------------------------------------------------------
class _Trapezoid:
    """Rest-to-rest path-length profile: accelerate at ``a`` to ``v``, cruise, decelerate at ``a``.

    If the path is too short to reach ``v`` (``v**2 / a > length``) the profile is triangular with
    peak speed ``sqrt(a * length)``.
    """

    def __init__(self, length: float, vmax: float, accel: float):
        self.length = float(length)
        self.accel = float(accel)
        ta = vmax / accel
        if vmax * ta >= self.length:  # 2 * (v^2 / 2a) >= L: triangular
            self.vpeak = math.sqrt(accel * self.length)
            self.ta = self.vpeak / accel
            self.tc = 0.0
        else:
            self.vpeak = float(vmax)
            self.ta = ta
            self.tc = (self.length - vmax * ta) / vmax
        self.sa = 0.5 * self.vpeak * self.ta
        self.duration = 2.0 * self.ta + self.tc

    def s(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Path length and speed at times t (clamped to [0, duration])."""
        t = _clip(np.asarray(t, dtype=float), 0.0, self.duration)
        a, ta, tc, T = self.accel, self.ta, self.tc, self.duration
        tau = T - t
        s = np.where(
            t <= ta,
            0.5 * a * t * t,
            np.where(
                t <= ta + tc, self.sa + self.vpeak * (t - ta), self.length - 0.5 * a * tau * tau
            ),
        )
        sd = np.where(t <= ta, a * t, np.where(t <= ta + tc, self.vpeak, a * tau))
        return s, sd

    def t_at_s(self, s: np.ndarray) -> np.ndarray:
        s = _clip(np.asarray(s, dtype=float), 0.0, self.length)
        a = self.accel
        t_acc = np.sqrt(np.maximum(2.0 * s / a, 0.0))
        t_cru = self.ta + (s - self.sa) / self.vpeak
        t_dec = self.duration - np.sqrt(np.maximum(2.0 * (self.length - s) / a, 0.0))
        return np.where(s <= self.sa, t_acc, np.where(s <= self.length - self.sa, t_cru, t_dec))


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
        self.duration = _positive("duration", duration)

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
        self.depth = _finite("depth", depth)
        self.duration = _positive("duration", duration)
        self.axis = self.R[:, 2].copy() if axis is None else _unit3("axis", axis)
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
        self.duration = _positive("duration", duration)
        self.profile = _profile_name(profile)
        self.rotvec = _log_so3(self.R0.T @ self.R1)  # in the start TCP frame

    def _eval(self, t):
        s, ds = _unit_profile(t / self.duration, self.profile)
        sd = ds / self.duration
        P = self.p0 + s[:, None] * (self.p1 - self.p0)
        V = sd[:, None] * (self.p1 - self.p0)
        R = self.R0 @ _exp_so3(s[:, None] * self.rotvec)
        # body rate sd * rotvec; exp(s k) k = k, so the world rate is R_0 (sd * rotvec)
        W = sd[:, None] * (self.R0 @ self.rotvec)
        return P, R, V, W


# --------------------------------------------------------------------------------------------
# Circle
# --------------------------------------------------------------------------------------------
def _plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """In-plane basis (e1, e2) with e1 x e2 = normal; e1 = world x projected (or y if parallel)."""
    ref = np.array([1.0, 0.0, 0.0])
    if np.linalg.norm(np.cross(ref, normal)) < 1e-6:
        ref = np.array([0.0, 1.0, 0.0])
    e1 = ref - np.dot(ref, normal) * normal
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    return e1, e2


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
        self.center = _vec3("center", center)
        self.radius = _positive("radius", radius)
        self.speed = _positive("speed", speed)
        self.accel = _positive("accel", accel)
        self.turns = _positive("turns", turns)
        self.start_angle = _finite("start_angle", start_angle)
        self.normal = _unit3("normal", normal)
        self.R = _rotation("R", R)
        self.clockwise = bool(clockwise)
        self.e1, self.e2 = _plane_basis(self.normal)
        self.sign = -1.0 if self.clockwise else 1.0
        self.arc_length = 2.0 * math.pi * self.radius * self.turns
        self._prof = _Trapezoid(self.arc_length, self.speed, self.accel)
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


# --------------------------------------------------------------------------------------------
# MoveL with blend radius
# --------------------------------------------------------------------------------------------
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


class _Line:
    def __init__(self, start: np.ndarray, direction: np.ndarray, length: float):
        self.start, self.dir, self.length = start, direction, float(length)

    def eval(self, s: np.ndarray):
        return self.start + s[:, None] * self.dir, np.broadcast_to(self.dir, (s.shape[0], 3))


class _QuadBlend:
    """Quadratic Bézier A -> (control Q) -> B traversed by arc length.

    ``B(u) = (1-u)² A + 2u(1-u) Q + u² B``; ``B'(u) = 2 (a + u b)`` with ``a = Q - A``,
    ``b = A - 2Q + B``.  Arc length is tabulated on 256 sub-intervals with 8-point Gauss-Legendre
    (machine precision for this smooth integrand) and inverted by cubic Hermite interpolation plus
    two Newton steps (residual ~1e-15 mm for turns up to ~175°).
    """

    _NTAB = 256

    def __init__(self, A: np.ndarray, Q: np.ndarray, B: np.ndarray):
        self.A, self.Q, self.B = A, Q, B
        self.a = Q - A
        self.b = A - 2.0 * Q + B
        u = np.linspace(0.0, 1.0, self._NTAB + 1)
        seg = self._integral(u[:-1], u[1:])
        self.u_tab = u
        self.s_tab = np.concatenate([[0.0], np.cumsum(seg)])
        self.length = float(self.s_tab[-1])
        self._speed_tab = self._speed(u)

    def _speed(self, u: np.ndarray) -> np.ndarray:
        d = self.a + u[..., None] * self.b
        return 2.0 * np.sqrt(np.sum(d * d, axis=-1))

    def _integral(self, u0: np.ndarray, u1: np.ndarray) -> np.ndarray:
        h = 0.5 * (u1 - u0)
        m = 0.5 * (u1 + u0)
        nodes = m[:, None] + h[:, None] * _GL_X[None, :]
        return h * (self._speed(nodes) @ _GL_W)

    def u_of_s(self, s: np.ndarray, newton: int = 2) -> np.ndarray:
        """Inverse arc length: cubic Hermite guess from the table (du/ds = 1/|B'| known at the
        nodes, error ~1e-10 of the sub-interval), then Newton step(s) on the exact arc length."""
        s = _clip(s, 0.0, self.length)
        j = _clip(np.searchsorted(self.s_tab, s, side="right") - 1, 0, self._NTAB - 1)
        u0, u1 = self.u_tab[j], self.u_tab[j + 1]
        s0, s1 = self.s_tab[j], self.s_tab[j + 1]
        h = s1 - s0
        x = (s - s0) / h
        m0, m1 = h / self._speed_tab[j], h / self._speed_tab[j + 1]
        x2, x3 = x * x, x * x * x
        u = (
            (2 * x3 - 3 * x2 + 1) * u0
            + (x3 - 2 * x2 + x) * m0
            + (-2 * x3 + 3 * x2) * u1
            + (x3 - x2) * m1
        )
        u = _clip(u, u0, u1)
        for _ in range(newton):
            f = s0 + self._integral(u0, u) - s
            u = _clip(u - f / self._speed(u), u0, u1)
        return u

    def eval(self, s: np.ndarray):
        u = self.u_of_s(s)[:, None]
        P = (1.0 - u) ** 2 * self.A + 2.0 * u * (1.0 - u) * self.Q + u * u * self.B
        d = self.a + u * self.b
        T = d / np.linalg.norm(d, axis=1, keepdims=True)
        return P, T


_COS_MAX_TURN = math.cos(math.radians(179.0))

BLEND_RULE = (
    "blend radius at corner i: r_i = min(r, L_(i-1)/2, L_i/2) — a blend may use at most half of "
    "each adjacent segment, so neighbouring blend zones never overlap (they may touch); corners "
    "with r_i = 0 or a turn of more than 179° (near reversal) are stop points"
)


class MoveL(Trajectory):
    """UR-style linear moves through waypoints with blend radius, at constant orientation.

    Path: ``start`` (``start_pose`` position, or ``waypoints[0]`` if no ``start_pose``), then the
    waypoints ``repeat`` times (the paper's loop P1 -> P2 -> P3 -> P4 of Algorithm 1), then ``end``
    if given.  Consecutive duplicate points (closer than 1e-9 mm) are merged.

    Blends (UR semantics, Figure 5): the tool starts blending when it comes within ``r_i`` of
    corner ``i`` (measured along the incoming segment) and leaves the blend ``r_i`` along the
    outgoing segment.  Blend shape: the quadratic Bézier with end points ``Q_i - r_i d_in``,
    ``Q_i + r_i d_out`` and control point ``Q_i`` (the corner) — a parabolic blend, tangent to both
    segments, so the velocity is continuous (the curvature jumps from 0 to the parabola's).
    Overlap rule (see ``BLEND_RULE``): ``r_i = min(blend_radius, L_(i-1)/2, L_i/2)``; the effective
    radii are in ``blend_radii`` (one per interior corner), requested ones that were cut are flagged
    in ``blend_reduced``.  ``blend_radius = 0`` gives UR's default: stop at every waypoint; a corner
    turning by more than 179° is also a stop point (a constant-speed blend would need a vanishing
    radius of curvature).

    Timing: the tool moves at constant path speed ``speed`` with a trapezoidal profile of
    acceleration ``accel`` at the start and end of every rest-to-rest piece (between stop points).
    (A controller that blends the two segment velocities linearly in time would trace the same
    kind of parabola but dip to ``v cos(φ/2)`` mid-corner for a turn angle φ; UR does not publish
    its exact blend, and the brief asks for a constant tool speed, so the speed stays at ``v``.)

    Orientation: constant, ``orientation`` (default: the ``start_pose`` rotation, else ``R0``);
    the twist's ``w`` is zero.

    ``center`` (optional, with ``normal``) makes the trajectory carry a rotation angle:
    ``angle(t)`` is the unwrapped polar angle of ``p(t)`` about the axis through ``center`` along
    ``normal``, 0 at the start and oriented so it increases along the path (the θ of Figure 7 for
    the four-point circle); ``angle_rate(t)`` its exact derivative.
    """

    def __init__(
        self,
        waypoints,
        speed: float,
        accel: float,
        blend_radius: float = 0.0,
        start_pose=None,
        orientation=None,
        *,
        repeat: int = 1,
        end=None,
        center=None,
        normal=(0.0, 0.0, 1.0),
    ):
        self.speed = _positive("speed", speed)
        self.accel = _positive("accel", accel)
        self.blend_radius = _nonneg("blend_radius", blend_radius)
        if isinstance(repeat, bool) or not isinstance(repeat, (int, np.integer)) or repeat < 1:
            raise ValueError(
                f"repeat must be an integer >= 1 (allowed range [1, inf)), got {repeat!r}"
            )
        self.repeat = int(repeat)
        try:
            W = np.array(waypoints, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"waypoints must be an (N, 3) array of positions (mm), got {waypoints!r}"
            )
        if W.ndim != 2 or W.shape[1] != 3 or W.shape[0] < 1 or not np.all(np.isfinite(W)):
            raise ValueError(
                f"waypoints must be a finite (N, 3) array with N >= 1, got shape {W.shape}"
            )
        R_start = None
        if start_pose is not None:
            p_start, R_start = _pose("start_pose", start_pose)
            if not (isinstance(start_pose, (tuple, list)) and len(start_pose) == 2):
                R_start = None  # bare position: no orientation constraint
        if orientation is not None:
            self.R = _rotation("orientation", orientation)
            if R_start is not None and np.max(np.abs(R_start - self.R)) > 1e-9:
                raise ValueError(
                    "orientation must equal the start_pose rotation (MoveL keeps a constant "
                    "orientation), got a difference of "
                    f"{float(np.max(np.abs(R_start - self.R))):.3g}"
                )
        else:
            self.R = R_start.copy() if R_start is not None else np.array(R0)

        pts = [p_start] if start_pose is not None else []
        pts += [w for _ in range(self.repeat) for w in W]
        if end is not None:
            pts.append(_vec3("end", end))
        merged = [pts[0]]
        for q in pts[1:]:
            if np.linalg.norm(q - merged[-1]) > 1e-9:
                merged.append(q)
        if len(merged) < 2:
            raise ValueError(
                "waypoints must define a path of non-zero length (all points coincide)"
            )
        self.points = np.array(merged)
        self._build()
        self.duration = float(self._piece_t0[-1])

        self.has_angle = False
        if center is not None:
            self._setup_angle(_vec3("center", center), _unit3("normal", normal))

    # -- construction ---------------------------------------------------------------------
    def _build(self):
        Q = self.points
        seg = np.diff(Q, axis=0)
        L = np.linalg.norm(seg, axis=1)
        D = seg / L[:, None]
        M = len(L)
        r_eff = np.zeros(M + 1)  # per point; endpoints 0 (stop)
        reduced = np.zeros(M + 1, dtype=bool)
        for i in range(1, M):
            r = min(self.blend_radius, 0.5 * L[i - 1], 0.5 * L[i])
            reduced[i] = r < self.blend_radius - 1e-9  # not flagged for round-off
            if float(np.dot(D[i - 1], D[i])) < _COS_MAX_TURN:  # (near) reversal: stop instead
                r = 0.0
            r_eff[i] = r
        self.segment_lengths = L
        self.blend_radii = r_eff[1:M].copy()
        self.blend_reduced = reduced[1:M].copy()

        elements: list = []
        stops = [0]  # element index where each rest-to-rest piece starts
        for i in range(M):
            a0 = Q[i] + r_eff[i] * D[i]
            ln = L[i] - r_eff[i] - r_eff[i + 1]
            if ln > 1e-12:
                elements.append(_Line(a0, D[i], ln))
            if i + 1 < M:
                if r_eff[i + 1] > 0.0:
                    r = r_eff[i + 1]
                    elements.append(
                        _QuadBlend(Q[i + 1] - r * D[i], Q[i + 1], Q[i + 1] + r * D[i + 1])
                    )
                else:
                    stops.append(len(elements))
        stops.append(len(elements))
        stops = sorted(set(stops))
        self._elements = elements
        lens = np.array([e.length for e in elements])
        self._elem_S0 = np.concatenate([[0.0], np.cumsum(lens)])
        self.length = float(self._elem_S0[-1])
        self._pieces = []
        piece_S0, piece_t0 = [0.0], [0.0]
        for k in range(len(stops) - 1):
            plen = float(self._elem_S0[stops[k + 1]] - self._elem_S0[stops[k]])
            prof = _Trapezoid(plen, self.speed, self.accel)
            self._pieces.append(prof)
            piece_S0.append(piece_S0[-1] + plen)
            piece_t0.append(piece_t0[-1] + prof.duration)
        self._piece_S0 = np.array(piece_S0)
        self._piece_t0 = np.array(piece_t0)

    # -- geometry -------------------------------------------------------------------------
    def _geom(self, S: np.ndarray):
        """Position and unit tangent at global arc lengths S (clamped)."""
        S = _clip(S, 0.0, self.length)
        nE = len(self._elements)
        e = _clip(np.searchsorted(self._elem_S0, S, side="right") - 1, 0, nE - 1)
        if e.min() == e.max():  # fast path (scalar queries)
            k = int(e[0])
            el = self._elements[k]
            return el.eval(_clip(S - self._elem_S0[k], 0.0, el.length))
        P = np.empty((S.shape[0], 3))
        T = np.empty((S.shape[0], 3))
        for k in np.unique(e):
            m = e == k
            el = self._elements[k]
            sl = _clip(S[m] - self._elem_S0[k], 0.0, el.length)
            P[m], T[m] = el.eval(sl)
        return P, T

    def _arc(self, t: np.ndarray):
        """Global arc length and path speed at clamped times."""
        k = _clip(np.searchsorted(self._piece_t0, t, side="right") - 1, 0, len(self._pieces) - 1)
        if k.min() == k.max():  # fast path (scalar queries)
            j = int(k[0])
            s, sd = self._pieces[j].s(t - self._piece_t0[j])
            return self._piece_S0[j] + s, sd
        S = np.empty_like(t)
        Sd = np.empty_like(t)
        for j in np.unique(k):
            m = k == j
            s, sd = self._pieces[j].s(t[m] - self._piece_t0[j])
            S[m] = self._piece_S0[j] + s
            Sd[m] = sd
        return S, Sd

    def path_points(self, n: int) -> np.ndarray:
        """``n`` points (n, 3) equally spaced in arc length from start to end."""
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
            raise ValueError(f"n must be an integer >= 2 (allowed range [2, inf)), got {n!r}")
        P, _ = self._geom(np.linspace(0.0, self.length, int(n)))
        return P

    def _eval(self, t):
        S, Sd = self._arc(t)
        P, T = self._geom(S)
        n = t.shape[0]
        return P, np.broadcast_to(self.R, (n, 3, 3)).copy(), Sd[:, None] * T, np.zeros((n, 3))

    # -- polar angle ----------------------------------------------------------------------
    def _setup_angle(self, center: np.ndarray, normal: np.ndarray):
        S = np.linspace(0.0, self.length, max(4001, int(self.length / 0.05) + 1))
        P, _ = self._geom(S)
        rel = P - center
        rel -= np.outer(rel @ normal, normal)
        rmin = float(np.min(np.linalg.norm(rel, axis=1)))
        if rmin < 1e-6:
            raise ValueError(
                f"center must not lie on the path (distance > 1e-6 mm), got min distance {rmin:.3g}"
            )
        e1, e2 = _plane_basis(normal)
        phi = np.unwrap(np.arctan2(rel @ e2, rel @ e1))
        if phi[-1] < phi[0]:  # make θ increase along the path
            normal = -normal
            e1, e2 = _plane_basis(normal)
            phi = np.unwrap(np.arctan2(rel @ e2, rel @ e1))
        self._ang_center, self._ang_normal, self._ang_e = center, normal, (e1, e2)
        self._ang_phi0 = float(phi[0])
        self._ang_S, self._ang_tab = S, phi - phi[0]
        self.has_angle = True

    def _require_angle(self):
        if not self.has_angle:
            raise ValueError("MoveL has no rotation angle: pass center=... to the constructor")

    def angle(self, t):
        """Unwrapped polar angle θ(t) of the TCP about ``center`` (0 at the start, increasing)."""
        th, _ = self._angle_and_rate(np.atleast_1d(np.asarray(t, dtype=float)))
        return float(th[0]) if np.ndim(t) == 0 else th

    def angle_rate(self, t):
        """dθ/dt = n · ((p - c) x v) / |p - c|⊥² (zero outside [0, duration])."""
        _, rate = self._angle_and_rate(np.atleast_1d(np.asarray(t, dtype=float)))
        return float(rate[0]) if np.ndim(t) == 0 else rate

    def _angle_and_rate(self, t):
        self._require_angle()
        tc = _clip(t, 0.0, self.duration)
        S, Sd = self._arc(tc)
        P, T = self._geom(S)
        V = Sd[:, None] * T
        rel = P - self._ang_center
        n = self._ang_normal
        rel -= np.outer(rel @ n, n)
        e1, e2 = self._ang_e
        wrapped = np.arctan2(rel @ e2, rel @ e1) - self._ang_phi0
        ref = np.interp(S, self._ang_S, self._ang_tab)
        theta = wrapped + 2.0 * np.pi * np.round((ref - wrapped) / (2.0 * np.pi))
        rate = (np.cross(rel, V) @ n) / np.sum(rel * rel, axis=1)
        rate = np.where((t < 0.0) | (t > self.duration), 0.0, rate)
        return theta, rate


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
    c = _vec3("center", center)
    r = _positive("radius", radius)
    phi0 = _finite("start_angle", start_angle)
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
    ``max_inward_mm``, both >= 0; RMS weighted by arc length) are for the steady loop — the middle turn
    θ ∈ [2π, 4π], where every corner has its steady blend.  ``first_quarter_max_abs_mm`` covers
    the excluded first move (θ ∈ [0, π/2]) and ``whole_path_max_abs_mm`` everything.
    The report also gives the requested and effective blend radii (steady corners and the first
    corner P1), whether the overlap rule cut them (``reduced``) and the rule itself.

    Measured for radius = blend radius = 20 mm: circumscribed control points (default) — blend
    zones exactly touch at the tangent points (no cut, first corner cut to 10 mm), max 1.213 mm
    (= r (3/(2√2) - 1), outward, at the 45° diagonals; 0 at the tangent points), RMS 0.741 mm,
    first quarter up to 4.75 mm; control points on the circle (``'inscribed'``) — zones overlap,
    cut to 14.14 mm, the path lies inside the circle by up to 5.86 mm (RMS 5.44 mm).
    """
    r = _positive("radius", radius)
    br = _nonneg("blend_radius", blend_radius)
    if (
        isinstance(samples_per_turn, bool)
        or not isinstance(samples_per_turn, (int, np.integer))
        or samples_per_turn < 100
    ):
        raise ValueError(
            f"samples_per_turn must be an integer >= 100 (allowed range [100, inf)), "
            f"got {samples_per_turn!r}"
        )
    c = _vec3("center", center)
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
        self.alpha = _finite("alpha_rad", alpha_rad)
        if abs(self.alpha) > math.pi / 2:
            raise ValueError(f"alpha_rad must be in [-pi/2, pi/2], got {alpha_rad!r}")
        self.axis = _unit3("axis", axis)
        self.theta_start = _finite("theta_start", theta_start)
        self.theta_end = _finite("theta_end", theta_end)
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
            self.pivot = _vec3("pivot", pivot)
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
        Rp = _rot_axis(self.axis, phi)
        R = Rb @ Rp
        W = Wb + phid[:, None] * (Rb @ self.axis)
        if self.pivot is not None:
            c = self.pivot
            off = np.einsum("nij,nj->ni", Rb, c - Rp @ c)  # (N, 3)
            P = P + off
            V = V + np.cross(Wb, off) - phid[:, None] * (R @ np.cross(self.axis, c))
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
