"""Scalar motion profiles: the eq 10 cubic step, rest-to-rest unit profiles and the trapezoid.

* ``smoothstep`` / ``smoothstep_dot`` — the cubic ``step`` of eq 10 and its derivative (also the
  building block of the eq 12 pitch profile, see ``motion.pitch``).
* ``unit_profile`` — rest-to-rest sigma(tau) on tau in [0, 1]: quintic (minimum jerk) or the eq 10
  cubic; drives ``Press`` and ``Approach``.
* ``Trapezoid`` — path length over time at bounded speed and acceleration; drives ``Circle`` and
  each rest-to-rest piece of ``MoveL`` (the UR5's linear moves, §4).
"""

from __future__ import annotations

import math

import numpy as np

from brush_env.engine.checks import ConfigError, check_real

__all__ = ["smoothstep", "smoothstep_dot", "unit_profile", "Trapezoid", "PROFILES", "clip"]

#: Names of the rest-to-rest unit profiles accepted by ``Press`` and ``Approach``.
PROFILES = ("quintic", "cubic")


def clip(x, lo, hi):
    """np.clip without its per-call overhead (hot in scalar pose queries)."""
    return np.minimum(np.maximum(x, lo), hi)


# --------------------------------------------------------------------------------------------
# eq 10: cubic step
# --------------------------------------------------------------------------------------------
def _step_u(x, x0, x1):
    """Checked (x0, x1) and the step's normalised coordinate u = (x - x0)/(x1 - x0) in [0, 1]."""
    x0 = check_real("x0", x0)
    x1 = check_real("x1", x1)
    if x0 == x1:
        raise ConfigError(f"x1 = {x1!r} is out of range: must differ from x0 = {x0!r}")
    x = np.asarray(x, dtype=float)
    return x0, x1, clip((x - x0) / (x1 - x0), 0.0, 1.0)


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


def unit_profile(tau: np.ndarray, profile: str) -> tuple[np.ndarray, np.ndarray]:
    """Rest-to-rest unit profile sigma(tau), dsigma/dtau on tau in [0, 1] (``profile`` one of
    ``PROFILES``, already checked)."""
    tau = clip(tau, 0.0, 1.0)
    if profile == "quintic":  # minimum jerk: zero velocity and acceleration at both ends
        s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau * tau)
        ds = 30.0 * tau * tau * (1.0 - tau) ** 2
    else:  # eq 10 cubic step: zero velocity at both ends, acceleration jumps to +-6/T^2
        s = tau * tau * (3.0 - 2.0 * tau)
        ds = 6.0 * tau * (1.0 - tau)
    return s, ds


# --------------------------------------------------------------------------------------------
# trapezoidal speed profile (used by Circle and MoveL)
# --------------------------------------------------------------------------------------------
class Trapezoid:
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
        t = clip(np.asarray(t, dtype=float), 0.0, self.duration)
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
        """Inverse of ``s``: the time at which path length s (clamped to [0, length]) is reached."""
        s = clip(np.asarray(s, dtype=float), 0.0, self.length)
        a = self.accel
        t_acc = np.sqrt(np.maximum(2.0 * s / a, 0.0))
        t_cru = self.ta + (s - self.sa) / self.vpeak
        t_dec = self.duration - np.sqrt(np.maximum(2.0 * (self.length - s) / a, 0.0))
        return np.where(s <= self.sa, t_acc, np.where(s <= self.length - self.sa, t_cru, t_dec))
