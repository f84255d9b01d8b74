"""Eq 12: the 1° pitch perturbation of §5.2, superimposed on a base trajectory.

``pitch_profile`` is the unit profile of eq 12, a product of two eq 10 cubic steps
(``motion.profiles.smoothstep``); ``PitchPerturbation`` tilts the brush by ``alpha · s(θ(t))``
about a TCP-frame axis while the base trajectory (the paper's circle) runs.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from brush_env.engine.checks import ConfigError, Limit, check_real, check_unit
from brush_env.engine.rotation import rot_axis

from .base import ANGLE, Trajectory, check_point
from .profiles import smoothstep, smoothstep_dot

__all__ = ["pitch_profile", "pitch_profile_dot", "PitchPerturbation"]

_FD_STEP = 1e-6  # s: central-difference step of dθ/dt when only θ(t) is given


def pitch_profile(theta, theta_start: float = 2.0 * math.pi, theta_end: float = 2.5 * math.pi):
    """Unit profile s(θ) of eq 12: ``step(θ, θs, 0, θm, 1) · step(θ, θm, 1, θe, 0)``, θm the mid.

    Rises with the eq 10 cubic from 0 at θs = 2π to 1 at θm = 2π + π/4, falls back to 0 at
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


def _central_difference(fn: Callable) -> Callable:
    """dθ/dt of a vectorised θ(t) by a central difference of step ``_FD_STEP``."""
    h = _FD_STEP

    def rate(t):
        t = np.asarray(t)
        return (np.asarray(fn(t + h), float) - np.asarray(fn(t - h), float)) / (2 * h)

    return rate


def _check_pivot(pivot):
    """None for ``'tcp'`` (rotate about the TCP origin), else the pivot point (3,) [mm]."""
    if isinstance(pivot, str):
        if pivot != "tcp":
            raise ConfigError(
                f"pivot = {pivot!r} is invalid: must be 'tcp' or a 3-vector in the TCP frame (mm)"
            )
        return None
    return check_point("pivot", pivot)


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
            raise ConfigError(f"base must be a Trajectory, got {type(base).__name__}")
        self.base = base
        self.alpha = check_real(
            "alpha_rad", alpha_rad, Limit("rad", ge=-math.pi / 2, le=math.pi / 2)
        )
        self.axis = check_unit("axis", axis)
        self.theta_start = check_real("theta_start", theta_start, ANGLE)
        self.theta_end = check_real("theta_end", theta_end, Limit("rad", gt=self.theta_start))
        self.pivot = _check_pivot(pivot)
        if angle_fn is None:
            if not base.has_angle:
                raise ConfigError(
                    f"angle_fn is required: base {type(base).__name__} has no rotation angle"
                )
            self._angle, self._rate = base.angle, base.angle_rate
            self._pair = base._angle_and_rate
        else:
            if not callable(angle_fn):
                raise ConfigError(f"angle_fn must be callable, got {angle_fn!r}")
            self._angle = angle_fn
            self._rate = _central_difference(angle_fn) if angle_rate_fn is None else angle_rate_fn
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
