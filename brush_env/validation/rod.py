"""Reference for one bristle pressed onto a flat plate: the planar geometrically exact rod.

numpy/scipy only; nothing here imports the engine (same rule as :mod:`.references`).
Units: mm, N, s; E in MPa (= N/mm^2); forces in N, moments in N*mm, angles in rad unless ``_deg``.

The case
--------
A straight bristle of length ``L`` and rectangular section ``width x thickness`` bends about its
thin direction (``EI = E width thickness^3 / 12``).  Its base is clamped with the base tangent at
the lean angle ``theta0`` from the plate normal; the bristle hangs from the clamp down toward the
plate.  A tip sphere of radius ``R`` is centred on the rod's end point.  Penetration is neglected,
so once the sphere touches the plate the end point stays at height ``R`` above it.

Coordinates and signs (planar): ``x`` horizontal, positive in the lean direction; ``z`` vertical,
up (away from the plate).  The section angle ``theta(s)`` is measured from the downward vertical
and is positive toward ``+x``: the tangent of the unstrained rod is ``d1 = (sin theta, -cos
theta)``, the section normal ``d2 = (cos theta, sin theta)``; ``theta(0) = theta0`` (clamp).
``s`` is the arc length of the undeformed rod, ``0 <= s <= L``.

* touch: the straight leaning bristle's sphere just touches; the end is then at
  ``(L sin theta0, -L cos theta0)`` relative to the clamp;
* compression ``delta`` [mm]: the clamp's descent after touch, so the end's height relative to the
  clamp is ``z(L) = -L cos theta0 + delta``;
* ``tip="free"`` (frictionless contact, mu = 0): the plate force on the end is vertical,
  ``(0, V)``, and there is no end moment (the contact force passes through the sphere's centre);
* ``tip="pinned"`` (sticking contact): the end's horizontal position is held at its touch position
  ``x(L) = L sin theta0``; the plate force is ``(H, V)``; no end moment.  As the brief for the
  reference states, the friction force is taken at the sphere's centre (its moment ``H R`` about
  the centre, and rolling of the sphere, are not modelled).

Outputs: ``force_N = V`` (plate normal force, > 0 pushing the bristle up), ``horizontal_N = H``
(force of the plate on the end along ``+x``; 0 for the free tip), ``tip_shift_mm = x(L) -
L sin theta0`` (0 for the pinned tip).

The model (Reissner 1972, "On one-dimensional finite-strain beam theory: the plane problem",
ZAMP 23; Antman, *Nonlinear Problems of Elasticity*, 2nd ed. 2005, ch. 4): the internal force
``n`` is constant along the rod (no distributed load) and equals the end load ``(H, V)``; with
``N = n . d1``, ``Q = n . d2`` (rod frame) and the linear laws ``N = EA (nu - 1)``, ``Q = GA_s
eta``, ``m = EI theta'``::

    x' = nu sin(theta) + eta cos(theta),   z' = -nu cos(theta) + eta sin(theta),
    theta' = m / EI,                       m' = H z' - V x'.

``EA``, ``GA_s = k G A`` (``G = E / (2 (1 + nu))``, ``k`` = the shear coefficient; by default
Cowper's rectangle value ``10 (1 + nu) / (12 + 11 nu)``) and ``EI`` are those the engine builds
its Timoshenko elements from (``brush_env.engine.beam.timoshenko_stiffness`` with
``Section.shear_coeff``).  ``model="elastica"`` is the same system with ``EA, GA_s -> inf``
(``nu = 1``, ``eta = 0``): Euler's inextensible, unshearable elastica.

Solution: shooting from the clamp (``scipy.integrate.solve_ivp``, DOP853, rtol 1e-11, with the
exact variational equations for the Jacobian) on the unknowns ``(m(0), V)`` (free) or ``(m(0),
V, H)`` (pinned), Newton's method (``scipy.optimize.root`` as fallback) on the end conditions, and
continuation along the physical branch.  The branch is followed in the end rotation ``alpha =
theta(L) - theta0`` from 0+, which rises monotonically along it (checked at every step; a step
that would lower ``delta`` is refused), then each requested ``delta`` is solved with the end
height prescribed, starting from the branch, and accepted only if its end rotation lies between
its bracketing branch points.  ``alpha > 0`` is bending toward the lean.  Following ``alpha``
rather than ``delta`` also covers a perfectly straight bristle (``lean_deg = 0``): it stays
straight (``V = EA delta / L``) up to its bifurcation and then follows the buckled branch,
buckling toward ``+x`` by convention, the limit of a vanishing lean.  Continuation in ``delta``
itself jumps off the branch at the sharp turn a small lean gives (tried: the pinned bristle at
1 deg then lands on the compressed, unbuckled branch).
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Sequence

import numpy as np

__all__ = ["buckled_bristle", "section_stiffness", "cowper_rect", "TIPS", "MODELS"]

TIPS = ("free", "pinned")
MODELS = ("reissner", "elastica")

#: ODE tolerances of the shooting (dimensionless states, all O(1)).
RTOL, ATOL = 1e-11, 1e-13
#: Newton's stopping tolerance on the dimensionless end conditions.
RES_TOL = 1e-11
#: The trace starts at this end rotation [rad] and grows geometrically from there (smaller
#: starts lose the load to round-off: near a bifurcation it is fixed by O(alpha) end terms).
ALPHA0 = 1e-4
#: Points along the rod in the returned shape.
SHAPE_POINTS = 101


# --------------------------------------------------------------------------- checks
def _check_real(name, value, *, gt=None, ge=None, lt=None, le=None, unit=""):
    """A real number within the bounds, else ValueError naming parameter, value and range.

    Same message style as ``brush_env.engine.checks.check_real`` (not imported: importing that
    module loads the engine package and its numba kernels).
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    u = f" ({unit})" if unit else ""
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        raise ValueError(
            f"buckled_bristle: {name} = {value!r} has the wrong type: expected a number{u}, "
            f"got {type(value).__name__}"
        )
    x = float(value)
    ops = (
        (">", gt, x > (gt or 0)),
        (">=", ge, x >= (ge or 0)),
        ("<", lt, x < (lt or 0)),
        ("<=", le, x <= (le or 0)),
    )
    ok = math.isfinite(x) and all(b is None or good for _, b, good in ops)
    if not ok:
        parts = [f"{op} {b:g}" for op, b, _ in ops if b is not None] or ["finite"]
        raise ValueError(
            f"buckled_bristle: {name} = {value!r} is out of range: must be {' and '.join(parts)}{u}"
        )
    return x


def _check_choice(name, value, allowed):
    if value not in allowed:
        raise ValueError(
            f"buckled_bristle: {name} = {value!r} is not allowed (allowed: {', '.join(allowed)})"
        )
    return value


# --------------------------------------------------------------------------- stiffness
def cowper_rect(nu: float) -> float:
    """Cowper's shear coefficient of a rectangle, ``10 (1 + nu) / (12 + 11 nu)`` [-].

    The value the engine uses (``brush_env.engine.config.Section.shear_coeff`` for
    ``kind="rect"``); Cowper, J. Appl. Mech. 33 (1966) 335-340.
    """
    return 10.0 * (1.0 + nu) / (12.0 + 11.0 * nu)


def section_stiffness(width, thickness, E, nu, shear_coef=None):
    """``(EA [N], GA_s [N], EI [N mm^2])`` of a rectangle bent about its thin direction.

    ``EA = E b h``, ``GA_s = k G b h`` with ``G = E / (2 (1 + nu))`` and ``k = shear_coef``
    (default: :func:`cowper_rect`), ``EI = E b h^3 / 12`` with ``b = width``, ``h = thickness``
    [mm], ``E`` [MPa] — the engine's ``E A``, ``kappa G A`` and ``E I_y``.
    """
    k = cowper_rect(nu) if shear_coef is None else shear_coef
    A = width * thickness
    return E * A, k * E / (2.0 * (1.0 + nu)) * A, E * width * thickness**3 / 12.0


# --------------------------------------------------------------------------- shooting
def _rhs(_xi, y, v, h, cA, cG, nsens):
    """Dimensionless rod equations plus their variational equations (``nsens`` unknowns).

    Lengths in L, forces in EI/L^2, moments in EI/L; ``cA = EI/(EA L^2)``, ``cG = EI/(GA_s
    L^2)`` (0 for the elastica).  State ``(X, Z, theta, M)``; sensitivity columns for
    ``(M0, v, h)``.
    """
    th, M = y[2], y[3]
    s, c = math.sin(th), math.cos(th)
    N = h * s - v * c
    Q = h * c + v * s
    nu = 1.0 + cA * N
    eta = cG * Q
    Xp = nu * s + eta * c
    Zp = -nu * c + eta * s
    out = np.empty_like(y)
    out[0], out[1], out[2], out[3] = Xp, Zp, M, h * Zp - v * Xp
    if nsens:
        dX = cA * Q * s + nu * c - cG * N * c - eta * s  # d/dtheta (dN/dth = Q, dQ/dth = -N)
        dZ = -cA * Q * c + nu * s - cG * N * s + eta * c
        dM = h * dZ - v * dX
        Xv, Zv = (cG - cA) * s * c, cA * c * c + cG * s * s
        Xh, Zh = cA * s * s + cG * c * c, (cG - cA) * s * c
        forcing = ((0.0, 0.0, 0.0), (Xv, Zv, h * Zv - Xp - v * Xv), (Xh, Zh, Zp + h * Zh - v * Xh))
        for j in range(nsens):
            b = 4 + 4 * j
            sth = y[b + 2]
            px, pz, pm = forcing[j]
            out[b] = dX * sth + px
            out[b + 1] = dZ * sth + pz
            out[b + 2] = y[b + 3]
            out[b + 3] = dM * sth + pm
    return out


class _Rod:
    """One dimensionless BVP: lean ``th0`` [rad], compliances, tip kind."""

    def __init__(self, th0, cA, cG, pinned):
        self.th0, self.cA, self.cG, self.pinned = th0, cA, cG, pinned
        self.n = 3 if pinned else 2

    def shoot(self, u, sens=True, t_eval=None):
        # scipy is imported where it is used: the CLI builds every subcommand's parser, and
        # importing scipy.integrate at module level cost every command ~0.4 s (issue 32)
        from scipy.integrate import solve_ivp

        h = u[2] if self.pinned else 0.0
        ns = self.n if sens else 0
        y0 = np.zeros(4 + 4 * ns)
        y0[2], y0[3] = self.th0, u[0]
        if sens:
            y0[4 + 3] = 1.0  # d M(0) / d M0
        sol = solve_ivp(
            _rhs,
            (0.0, 1.0),
            y0,
            method="DOP853",
            rtol=RTOL,
            atol=ATOL,
            args=(u[1], h, self.cA, self.cG, ns),
            t_eval=t_eval,
        )
        if not sol.success:
            raise RuntimeError(f"rod shooting failed: {sol.message}")
        yL = sol.y[:, -1]
        return yL[:4], (yL[4:].reshape(ns, 4).T if sens else None), sol

    def residual(self, u, alpha=None, D=None):
        """End conditions: M(1) = 0, then theta(1) - th0 = alpha or Z(1) = -cos th0 + D, then
        (pinned) X(1) = sin th0.  Returns (r, J, end state)."""
        y, S, _ = self.shoot(u)
        if alpha is not None:
            r, J = [y[3], y[2] - self.th0 - alpha], [S[3], S[2]]
        else:
            r, J = [y[3], y[1] + math.cos(self.th0) - D], [S[3], S[1]]
        if self.pinned:
            r.append(y[0] - math.sin(self.th0))
            J.append(S[0])
        return np.array(r), np.array(J), y

    def solve(self, u0, alpha=None, D=None, maxit=12):
        """Newton with backtracking from ``u0``; scipy's hybrid method as fallback.

        Returns (u, end state) or None if neither converges."""
        u = np.array(u0, float)
        try:
            r, J, y = self.residual(u, alpha, D)
            for _ in range(maxit):
                nr = np.max(np.abs(r))
                if nr < RES_TOL:
                    return u, y
                du = np.linalg.solve(J, -r)
                t = 1.0
                while t > 1e-3:
                    r2, J2, y2 = self.residual(u + t * du, alpha, D)
                    if np.max(np.abs(r2)) < nr:
                        break
                    t *= 0.5
                u, r, J, y = u + t * du, r2, J2, y2
        except (np.linalg.LinAlgError, RuntimeError):
            pass
        from scipy.optimize import root  # (see ``shoot``)

        sol = root(
            lambda w: self.residual(w, alpha, D)[:2],
            np.asarray(u0, float),
            jac=True,
            method="hybr",
            options={"xtol": 1e-13},
        )
        r, _, y = self.residual(sol.x, alpha, D)
        return (sol.x, y) if np.max(np.abs(r)) < RES_TOL else None

    # ------------------------------------------------------------------ first point
    def mode_guess(self, a):
        """Small-rotation guess: linear theory of the leaning column (free tip) or the
        clamped-pinned Euler mode in the rod's frame (pinned tip), scaled to end rotation a."""
        th0 = self.th0
        if not self.pinned:
            # EI phi'' = -V sin(th0) - V cos(th0) phi, phi(0) = 0, phi'(L) = 0:
            # alpha = tan(th0) (sec(kL) - 1), k^2 = V cos(th0) / EI.
            k = math.acos(1.0 / (1.0 + a / math.tan(th0))) if th0 > 0 else 0.5 * math.pi
            return np.array([k * (math.tan(th0) + a) * math.sin(k), k * k / math.cos(th0)])
        k = 4.493409457909064  # tan k = k (clamped-pinned)
        v = k * k
        h = a * v / (1.0 / math.cos(k) - 1.0)
        M0 = h / v * k * math.tan(k)
        c, s = math.cos(th0), math.sin(th0)
        return np.array([M0, h * s + v * c, h * c - v * s])


def _trace(rod, D_max, alpha_step):
    """Branch points (alpha, D, u) from alpha = ALPHA0 until D >= D_max (dimensionless)."""
    # below the lean's own scale, where the leaning column still responds linearly
    a = ALPHA0 if rod.th0 == 0.0 else min(ALPHA0, 0.05 * rod.th0)
    # free tip: the linear leaning-column solution is a good start for any lean; pinned tip of
    # an extensible rod with a lean: the unloaded state (Jacobian regular there); otherwise the
    # Euler mode.
    first = None
    if rod.pinned and rod.th0 > 0.0 and rod.cA > 0.0:
        first = rod.solve(np.zeros(rod.n), alpha=a)
    if first is None:
        first = rod.solve(rod.mode_guess(a), alpha=a)
    if first is None:
        raise RuntimeError("buckled_bristle: no solution at the start of the branch")
    u, y = first
    pts = [(a, y[1] + math.cos(rod.th0), u)]
    da = 0.5 * a
    while pts[-1][1] < D_max:
        a0, D0, u0 = pts[-1]
        if a0 > math.pi:
            raise RuntimeError(
                f"buckled_bristle: end rotation exceeds pi before delta reaches {D_max:g} L"
            )
        an = a0 + da
        g = u0
        if len(pts) >= 2:  # secant predictor
            a1, _, u1 = pts[-2]
            g = u0 + (u0 - u1) * (an - a0) / (a0 - a1)
        got = rod.solve(g, alpha=an)
        ok = got is not None
        if ok:
            un, y = got
            Dn = y[1] + math.cos(rod.th0)
            # stay on the branch: D does not fall (beyond ODE noise, ~1e-12) and the corrector
            # lands near the secant prediction, or the step itself is small (the secant of a
            # long previous interval can miss by a fixed fraction on a sharp turn)
            step = np.linalg.norm(un - u0)
            ok = Dn > D0 - 1e-10 and (
                len(pts) < 2
                or np.linalg.norm(un - g) <= 0.3 * step + 1e-12
                or step <= 0.02 * np.linalg.norm(u0)
            )
        if not ok:
            da *= 0.5
            if da < 1e-10:
                raise RuntimeError(
                    "buckled_bristle: continuation stalled at end rotation "
                    f"{a0:.6g} rad (delta = {D0:.6g} L): delta is not monotone in the end "
                    "rotation there (limit point / snap-through), not supported"
                )
            continue
        pts.append((an, Dn, un))
        da = min(1.6 * da, alpha_step)
    return pts


def _solve_targets(rod, Ds, pts):
    """Solve each prescribed D from the branch; returns list of (u, straight flag)."""
    a_arr = np.array([p[0] for p in pts])
    D_arr = np.array([p[1] for p in pts])
    out = []
    for D in Ds:
        if D == 0.0:
            out.append(np.zeros(rod.n))
            continue
        if D <= D_arr[0]:
            if rod.th0 == 0.0:
                # straight bristle below its bifurcation: pure compression (elastica: D = 0 only)
                u = np.zeros(rod.n)
                u[1] = D / rod.cA if rod.cA > 0 else pts[0][2][1]
                if rod.cA > 0:
                    out.append(u)
                    continue
                out.append(pts[0][2])
                continue
            i = 0
            lo_a, hi_a, guess = 0.0, a_arr[0], pts[0][2] * (D / D_arr[0])
            if rod.pinned and rod.cA == 0.0:
                guess = pts[0][2]
        else:
            i = int(np.searchsorted(D_arr, D)) - 1
            w = (D - D_arr[i]) / (D_arr[i + 1] - D_arr[i])
            lo_a, hi_a = a_arr[i], a_arr[i + 1]
            guess = (1 - w) * pts[i][2] + w * pts[i + 1][2]
        got = rod.solve(guess, D=D)
        tol = 1e-9 + 1e-6 * (hi_a - lo_a)
        if got is not None and lo_a - tol <= got[1][2] - rod.th0 <= hi_a + tol:
            out.append(got[0])
            continue
        # fallback: bisect the end rotation inside the bracket (alpha-controlled solves)
        ul, uh = (pts[i][2] if D > D_arr[0] else guess), pts[i + 1 if D > D_arr[0] else 0][2]
        lo, hi = lo_a, hi_a
        u_mid = ul
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            got = rod.solve(0.5 * (ul + uh), alpha=mid)
            if got is None:
                raise RuntimeError(f"buckled_bristle: no solution at delta = {D:g} L")
            u_mid, y = got
            if y[1] + math.cos(rod.th0) < D:
                lo, ul = mid, u_mid
            else:
                hi, uh = mid, u_mid
            if hi - lo < 1e-13:
                break
        got = rod.solve(u_mid, D=D)
        out.append(got[0] if got is not None else u_mid)
    return out


# --------------------------------------------------------------------------- public API
def buckled_bristle(
    delta_mm,
    *,
    length: float = 10.0,
    width: float = 1.8,
    thickness: float = 0.8,
    E: float = 7.0,
    nu: float = 0.48,
    shear_coef: float | None = None,
    lean_deg: float = 1.0,
    tip: str = "free",
    radius: float = 0.44,
    model: str = "reissner",
    steps: int | None = None,
) -> dict:
    """Plate force of one bristle pressed by ``delta_mm`` onto a flat plate (planar, static).

    Solves the clamped-base / sphere-tip boundary-value problem of the module docstring for the
    geometrically exact rod with shear and extension (Reissner 1972) or the elastica, by
    shooting and continuation along the branch that bends toward the lean.

    Parameters (units): ``delta_mm`` [mm] compression after first touch, a number or a sequence
    (one continuation pass serves them all), each ``0 <= delta <= 0.4 length``; ``length`` [mm];
    ``width``, ``thickness`` [mm] (bending about the thickness: ``I = width thickness^3 / 12``);
    ``E`` [MPa]; ``nu`` [-]; ``shear_coef`` [-] (shear area ``shear_coef * A``; None: Cowper's
    rectangle value, as the engine); ``lean_deg`` [deg] base tangent from the plate normal,
    ``-10..10`` like the engine's ``lean_deg`` (a negative lean mirrors x); ``tip`` "free" (mu =
    0) or "pinned" (sticking); ``radius`` [mm] tip sphere (only places the plate in ``shape``);
    ``model`` "reissner" or "elastica"; ``steps`` continuation resolution: the end-rotation step
    is capped at 90 deg / steps (default 30).

    Returns a dict (arrays of ``len(delta)`` when ``delta_mm`` is a sequence): ``force_N``
    [N] plate normal force on the bristle; ``horizontal_N`` [N] plate force along +x (lean
    direction; 0 for "free"); ``tip_shift_mm`` [mm] horizontal end displacement from its touch
    position (0 for "pinned"); ``end_rotation_rad`` [rad] ``theta(L) - theta0``;
    ``base_moment_Nmm`` [N mm] ``m(0)`` (positive bends toward +x); ``delta_mm``; ``shape``:
    ``(x, z)`` arrays [mm] of the rod's axis, x from the clamp, z above the plate (a list of
    them for a sequence); ``stiffness``: ``(EA, GA_s, EI)`` [N, N, N mm^2] used.
    """
    L = _check_real("length", length, gt=0, le=100, unit="mm")
    b = _check_real("width", width, gt=0, le=20, unit="mm")
    hth = _check_real("thickness", thickness, gt=0, le=20, unit="mm")
    E = _check_real("E", E, gt=0, le=1e6, unit="MPa")
    nu = _check_real("nu", nu, gt=-1, lt=0.5, unit="dimensionless")
    if shear_coef is not None:
        shear_coef = _check_real("shear_coef", shear_coef, gt=0, le=2, unit="dimensionless")
    lean = _check_real("lean_deg", lean_deg, ge=-10, le=10, unit="deg")
    _check_choice("tip", tip, TIPS)
    _check_choice("model", model, MODELS)
    R = _check_real("radius", radius, gt=0, le=min(5.0, L), unit="mm; at most min(5 mm, length)")
    if steps is None:
        steps = 30
    elif (
        not isinstance(steps, numbers.Integral)
        or isinstance(steps, bool)
        or not (5 <= steps <= 10000)
    ):
        raise ValueError(
            f"buckled_bristle: steps = {steps!r} is out of range: must be an integer >= 5 and "
            "<= 10000 (count)"
        )
    scalar = not isinstance(delta_mm, (Sequence, np.ndarray)) or (
        isinstance(delta_mm, np.ndarray) and delta_mm.ndim == 0
    )
    dl = [delta_mm] if scalar else list(np.asarray(delta_mm, dtype=object).ravel())
    if not dl:
        raise ValueError("buckled_bristle: delta_mm = [] is empty: give at least one value (mm)")
    deltas = [
        _check_real(
            f"delta_mm[{i}]" if not scalar else "delta_mm",
            d,
            ge=0,
            le=0.4 * L,
            unit="mm; at most 0.4 length",
        )
        for i, d in enumerate(dl)
    ]

    EA, GA, EI = section_stiffness(b, hth, E, nu, shear_coef)
    cA, cG = (EI / (EA * L * L), EI / (GA * L * L)) if model == "reissner" else (0.0, 0.0)
    th0 = math.radians(abs(lean))
    sign = -1.0 if lean < 0 else 1.0
    rod = _Rod(th0, cA, cG, tip == "pinned")
    Ds = [d / L for d in deltas]
    pts = _trace(rod, max(Ds), 0.5 * math.pi / steps) if max(Ds) > 0 else [(0.0, 0.0, None)]
    us = _solve_targets(rod, Ds, pts) if max(Ds) > 0 else [np.zeros(rod.n) for _ in Ds]

    fs, hs, shifts, rots, m0s, shapes = [], [], [], [], [], []
    xi = np.linspace(0.0, 1.0, SHAPE_POINTS)
    for D, u in zip(Ds, us):
        _, _, sol = rod.shoot(u, sens=False, t_eval=xi)
        X, Z, th = sol.y[0], sol.y[1], sol.y[2]
        fs.append(u[1] * EI / L**2)
        hs.append(sign * (u[2] if rod.pinned else 0.0) * EI / L**2)
        shifts.append(0.0 if rod.pinned else sign * (X[-1] - math.sin(th0)) * L)
        rots.append(sign * (th[-1] - th0))
        m0s.append(sign * u[0] * EI / L)
        # plate at z = 0: the end sits R above it, i.e. the clamp is L cos th0 - D L + R up
        shapes.append((sign * X * L, Z * L + (L * math.cos(th0) - D * L + R)))
    res = {
        "delta_mm": deltas,
        "force_N": fs,
        "horizontal_N": hs,
        "tip_shift_mm": shifts,
        "end_rotation_rad": rots,
        "base_moment_Nmm": m0s,
        "shape": shapes,
    }
    if scalar:
        res = {k: v[0] for k, v in res.items()}
    else:
        res = {k: (v if k == "shape" else np.array(v)) for k, v in res.items()}
    res["stiffness"] = (EA, GA, EI)
    return res
