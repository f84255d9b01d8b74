"""UR ``MoveL`` emulation: linear moves through waypoints with blend radius (§4, Figure 5).

The UR5 builds the paper's circle from four ``MoveL`` control points with blend radius
(Algorithm 1, ``motion.paper``).  Here each blend is a quadratic Bézier traversed at constant
tool speed (``_QuadBlend``), straight parts are ``_Line`` s, and every rest-to-rest piece between
stop points follows a ``motion.profiles.Trapezoid``.  The paper gives this motion as robot
commands, not as a numbered equation.
"""

from __future__ import annotations

import math

import numpy as np

from brush_env.engine.checks import (
    ConfigError,
    Limit,
    check_int,
    check_real,
    check_rotation,
    check_unit,
)

from .base import ACCEL, R0, SPEED, Trajectory, check_point, check_pose, plane_basis
from .profiles import Trapezoid, clip

__all__ = ["MoveL", "BLEND_RULE"]

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
        s = clip(s, 0.0, self.length)
        j = clip(np.searchsorted(self.s_tab, s, side="right") - 1, 0, self._NTAB - 1)
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
        u = clip(u, u0, u1)
        for _ in range(newton):
            f = s0 + self._integral(u0, u) - s
            u = clip(u - f / self._speed(u), u0, u1)
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


def _check_waypoints(waypoints) -> np.ndarray:
    """A finite (N, 3) array of positions [mm], N >= 1."""
    try:
        W = np.array(waypoints, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(
            f"waypoints must be an (N, 3) array of positions (mm), got {waypoints!r}"
        ) from None
    if W.ndim != 2 or W.shape[1] != 3 or W.shape[0] < 1 or not np.all(np.isfinite(W)):
        raise ConfigError(
            f"waypoints must be a finite (N, 3) array with N >= 1, got shape {W.shape}"
        )
    return W


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
        self.speed = check_real("speed", speed, SPEED)
        self.accel = check_real("accel", accel, ACCEL)
        self.blend_radius = check_real("blend_radius", blend_radius, Limit("mm", ge=0))
        self.repeat = check_int("repeat", repeat, Limit("repeats", ge=1))
        W = _check_waypoints(waypoints)
        R_start = None
        if start_pose is not None:
            p_start, R_start = check_pose("start_pose", start_pose)
            if not (isinstance(start_pose, (tuple, list)) and len(start_pose) == 2):
                R_start = None  # bare position: no orientation constraint
        if orientation is not None:
            self.R = check_rotation("orientation", orientation)
            if R_start is not None and np.max(np.abs(R_start - self.R)) > 1e-9:
                raise ConfigError(
                    "orientation must equal the start_pose rotation (MoveL keeps a constant "
                    "orientation), got a difference of "
                    f"{float(np.max(np.abs(R_start - self.R))):.3g}"
                )
        else:
            self.R = R_start.copy() if R_start is not None else np.array(R0)

        pts = [p_start] if start_pose is not None else []
        pts += [w for _ in range(self.repeat) for w in W]
        if end is not None:
            pts.append(check_point("end", end))
        merged = [pts[0]]
        for q in pts[1:]:
            if np.linalg.norm(q - merged[-1]) > 1e-9:
                merged.append(q)
        if len(merged) < 2:
            raise ConfigError(
                "waypoints must define a path of non-zero length (all points coincide)"
            )
        self.points = np.array(merged)
        self._build()
        self.duration = float(self._piece_t0[-1])

        self.has_angle = False
        if center is not None:
            self._setup_angle(check_point("center", center), check_unit("normal", normal))

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
            prof = Trapezoid(plen, self.speed, self.accel)
            self._pieces.append(prof)
            piece_S0.append(piece_S0[-1] + plen)
            piece_t0.append(piece_t0[-1] + prof.duration)
        self._piece_S0 = np.array(piece_S0)
        self._piece_t0 = np.array(piece_t0)

    # -- geometry -------------------------------------------------------------------------
    def _geom(self, S: np.ndarray):
        """Position and unit tangent at global arc lengths S (clamped)."""
        S = clip(S, 0.0, self.length)
        nE = len(self._elements)
        e = clip(np.searchsorted(self._elem_S0, S, side="right") - 1, 0, nE - 1)
        if e.min() == e.max():  # fast path (scalar queries)
            k = int(e[0])
            el = self._elements[k]
            return el.eval(clip(S - self._elem_S0[k], 0.0, el.length))
        P = np.empty((S.shape[0], 3))
        T = np.empty((S.shape[0], 3))
        for k in np.unique(e):
            m = e == k
            el = self._elements[k]
            sl = clip(S[m] - self._elem_S0[k], 0.0, el.length)
            P[m], T[m] = el.eval(sl)
        return P, T

    def _arc(self, t: np.ndarray):
        """Global arc length and path speed at clamped times."""
        k = clip(np.searchsorted(self._piece_t0, t, side="right") - 1, 0, len(self._pieces) - 1)
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
        n = check_int("n", n, Limit("points", ge=2))
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
            raise ConfigError(
                f"center must not lie on the path (distance > 1e-6 mm), got min distance {rmin:.3g}"
            )
        e1, e2 = plane_basis(normal)
        phi = np.unwrap(np.arctan2(rel @ e2, rel @ e1))
        if phi[-1] < phi[0]:  # make θ increase along the path
            normal = -normal
            e1, e2 = plane_basis(normal)
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
        tc = clip(t, 0.0, self.duration)
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
