"""Independent reference solutions used to validate the discrete beam model (numpy only).

Units follow the engine: mm, N, s, tonne (so E, G in N/mm^2 = MPa, density in t/mm^3,
frequencies in Hz).  Nothing here imports the engine: these are closed forms and an exact
elastica solution "written down by someone else".

Sources
-------
* Timoshenko & Gere, *Mechanics of Materials*; Timoshenko (1921) shear-deformable beam.
* Bisshopp & Drucker, "Large deflection of cantilever beams", Q. Appl. Math. 3 (1945) 272-275;
  Mattiasson, "Numerical results from large deflection beam and frame problems analysed by means
  of elliptic integrals", IJNME 17 (1981) 145-153.
* Meirovitch, *Elements of Vibration Analysis* (1986), cantilever frequency equation.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "timoshenko_cantilever_tip",
    "axial_tip",
    "torsion_tip",
    "elastica_cantilever",
    "elastica_cantilever_profile",
    "cantilever_frequency_roots",
    "euler_bernoulli_cantilever_frequencies",
]


# --------------------------------------------------------------------------- closed forms
def timoshenko_cantilever_tip(P, L, E, G, I, A, kappa):
    """Tip of a clamped-free Timoshenko beam under a transverse tip force (linear theory).

    P [N], L [mm], E, G [N/mm^2], I [mm^4], A [mm^2], kappa [-] shear correction factor.
    Returns ``dict(v=[mm], theta=[rad])`` with
    v = P L^3/(3 E I) + P L/(kappa G A)  (bending + shear) and
    theta = P L^2/(2 E I), the cross-section rotation (shear does not change it).
    """
    v = P * L**3 / (3.0 * E * I) + P * L / (kappa * G * A)
    theta = P * L**2 / (2.0 * E * I)
    return {"v": v, "theta": theta}


def axial_tip(P, L, E, A):
    """Tip elongation [mm] of a bar under an axial force P [N]: u = P L / (E A)."""
    return P * L / (E * A)


def torsion_tip(T, L, G, J):
    """Tip twist [rad] of a shaft under a torque T [N mm]: phi = T L / (G J), J [mm^4]."""
    return T * L / (G * J)


# --------------------------------------------------------------------------- root finder
def _brent(f, a, b, rtol=4e-16, atol=0.0, maxiter=200):
    """Brent's method (Brent 1973 / zeroin) for a sign-changing bracket [a, b]."""
    fa, fb = f(a), f(b)
    if fa == 0.0:
        return a
    if fb == 0.0:
        return b
    if fa * fb > 0.0:
        raise ValueError("root not bracketed")
    c, fc, d = a, fa, b - a
    e = d
    for _ in range(maxiter):
        if fb * fc > 0.0:
            c, fc, d = a, fa, b - a
            e = d
        if abs(fc) < abs(fb):
            a, b, c = b, c, b
            fa, fb, fc = fb, fc, fb
        tol = 2.0 * rtol * abs(b) + 0.5 * atol
        m = 0.5 * (c - b)
        if abs(m) <= tol or fb == 0.0:
            return b
        if abs(e) >= tol and abs(fa) > abs(fb):
            s = fb / fa
            if a == c:  # secant
                p, q = 2.0 * m * s, 1.0 - s
            else:  # inverse quadratic interpolation
                q, r = fa / fc, fb / fc
                p = s * (2.0 * m * q * (q - r) - (b - a) * (r - 1.0))
                q = (q - 1.0) * (r - 1.0) * (s - 1.0)
            if p > 0.0:
                q = -q
            p = abs(p)
            if 2.0 * p < min(3.0 * m * q - abs(tol * q), abs(e * q)):
                e, d = d, p / q
            else:
                d = e = m
        else:
            d = e = m
        a, fa = b, fb
        b += d if abs(d) > tol else math.copysign(tol, m)
        fb = f(b)
    raise RuntimeError("Brent's method did not converge")


# --------------------------------------------------------------------------- elastica
# Clamped at s = 0 along +x, dead tip force P along +y, alpha = P L^2/(E I), s in [0, 1].
# EI theta' = P (x_tip - x)  =>  theta'' = -alpha cos(theta), theta(0) = 0, theta'(1) = 0,
# first integral theta'^2 = 2 alpha (sin th0 - sin theta), th0 = tip angle.
# Bisshopp-Drucker substitution 1 + sin theta = 2 k^2 sin^2 phi, k^2 = (1 + sin th0)/2, gives
# ds = dphi / (sqrt(alpha) sqrt(1 - k^2 sin^2 phi)), i.e. sqrt(alpha) = K(k) - F(phi_1, k).
# For quadrature the endpoint behaviour is removed with psi = pi/2 - phi and
# sinh(u) = k sin(psi) / a, a = sqrt(1 - k^2) = sin(pi/4 - th0/2):
#   ds = w(u) du / sqrt(alpha),  w = 1 / (k cos psi),  u in [0, u1] (u = 0 at the tip),
#   sin theta = sin th0 - 2 a^2 sinh^2 u,  cos theta = 2 a k cos(psi) cosh(u),
#   u1 = asinh(k sin(psi_1) / a),  sin^2 psi_1 = sin th0 / (1 + sin th0)  (theta = 0 there).
# w is analytic and cos(psi) >= 1/sqrt(2), so Gauss-Legendre converges geometrically for
# every alpha (no cancellation as alpha -> 0 or near-singularity as th0 -> pi/2).
_ALPHA_MAX = 500.0  # th0 = pi/2 - 1e-12 (upper bracket below) corresponds to alpha ~ 830


def _elastica_terms(th0, u):
    """(w, sin theta, cos theta) at parameters u (any shape) for tip angle th0."""
    beta = 0.25 * np.pi - 0.5 * th0
    a, k, s0 = math.sin(beta), math.cos(beta), math.sin(th0)
    sin_psi = (a / k) * np.sinh(u)
    cos_psi = np.sqrt(1.0 - sin_psi**2)
    w = 1.0 / (k * cos_psi)
    return w, s0 - 2.0 * a**2 * np.sinh(u) ** 2, 2.0 * a * k * cos_psi * np.cosh(u)


def _u1(th0):
    beta = 0.25 * np.pi - 0.5 * th0
    s0 = math.sin(th0)
    return math.asinh(math.cos(beta) * math.sqrt(s0 / (1.0 + s0)) / math.sin(beta))


def _quad(th0, upper, n):
    """Integrals over [0, upper] (upper: array) of w, w sin(theta), w (1 - cos theta)."""
    xi, wi = np.polynomial.legendre.leggauss(n)
    upper = np.asarray(upper, dtype=float)[..., None]
    u = 0.5 * upper * (xi + 1.0)
    w, sn, cs = _elastica_terms(th0, u)
    jac = 0.5 * upper[..., 0]
    one_minus_cos = sn**2 / (1.0 + cs)  # = 1 - cos theta without cancellation
    return jac * (w @ wi), jac * ((w * sn) @ wi), jac * ((w * one_minus_cos) @ wi)


def _tip_angle(alpha, n):
    """Tip angle th0 in (0, pi/2) solving (int_0^u1 w du)^2 = alpha."""

    def resid(th0):
        return _quad(th0, _u1(th0), n)[0] ** 2 - alpha if th0 > 0.0 else -alpha

    hi = 0.5 * alpha if alpha < 3.0 else 0.5 * np.pi - 1e-12  # th0 <= alpha/2 (linear theory)
    return _brent(resid, 0.0, hi)


def elastica_cantilever(alpha, n=64):
    """Large-deflection (Euler elastica) tip of a clamped cantilever under a dead tip load.

    The beam is inextensible and unshearable; the tip force P stays perpendicular to the
    undeformed axis.  alpha = P L^2/(E I) [-], 0 <= alpha <= 500.  n: Gauss-Legendre nodes
    (64 gives ~1e-15 for alpha <= 20).  Exact elliptic-integral solution of Bisshopp & Drucker
    (1945), see the derivation above; tabulated by Mattiasson (1981).

    Returns ``dict(v_over_L, h_over_L, tip_angle_rad)``: tip deflection along the load,
    tip shortening along the original axis (h/L = 1 - x_tip/L) and tip tangent rotation.
    Small-alpha limit: v/L -> alpha/3, h/L -> alpha^2/15, angle -> alpha/2.
    """
    alpha = float(alpha)
    if not 0.0 <= alpha <= _ALPHA_MAX:
        raise ValueError(f"alpha must be in [0, {_ALPHA_MAX}], got {alpha}")
    if alpha < 1e-12:  # linear theory is exact to double precision here
        return {"v_over_L": alpha / 3.0, "h_over_L": alpha**2 / 15.0, "tip_angle_rad": alpha / 2.0}
    th0 = _tip_angle(alpha, n)
    _, iy, ih = _quad(th0, _u1(th0), n)
    r = math.sqrt(alpha)
    return {"v_over_L": float(iy) / r, "h_over_L": float(ih) / r, "tip_angle_rad": float(th0)}


def elastica_cantilever_profile(alpha, npts=101, n=64):
    """Deformed centreline of :func:`elastica_cantilever` at npts equally spaced s/L in [0, 1].

    Returns ``dict(s, x, y, theta)`` as arrays; x, y are divided by L (root at the origin,
    undeformed axis along +x, load along +y), theta [rad] is the tangent angle.
    """
    s = np.linspace(0.0, 1.0, npts)
    alpha = float(alpha)
    tip = elastica_cantilever(alpha, n)
    if alpha < 1e-12:  # linear theory: y = alpha (s^2/2 - s^3/6)
        y, theta = alpha * (s**2 / 2 - s**3 / 6), alpha * (s - s**2 / 2)
        return {"s": s, "x": s.copy(), "y": y, "theta": theta}
    th0, r = tip["tip_angle_rad"], math.sqrt(alpha)
    target = (1.0 - s) * r  # int_0^u w du from the tip back to arclength s
    lo, hi = np.zeros(npts), np.full(npts, _u1(th0))
    for _ in range(64):  # vectorised bisection, int_0^u w du increases with u
        mid = 0.5 * (lo + hi)
        below = _quad(th0, mid, n)[0] < target
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    u = 0.5 * (lo + hi)
    u[0], u[-1] = _u1(th0), 0.0  # root and tip exactly
    _, iy, _ = _quad(th0, u, n)
    _, sn, cs = _elastica_terms(th0, u)
    a = math.sin(0.25 * np.pi - 0.5 * th0)
    x_tip = 1.0 - tip["h_over_L"]
    # x from the first integral: x_tip - x = theta'/alpha = 2 a sinh(u)/sqrt(alpha)
    x = x_tip - 2.0 * a * np.sinh(u) / r
    y = tip["v_over_L"] - iy / r
    x[0] = y[0] = 0.0  # clamped root exactly at the origin
    return {"s": s, "x": x, "y": y, "theta": np.arctan2(sn, cs)}


# --------------------------------------------------------------------------- vibration
def cantilever_frequency_roots(n_modes=3):
    """First n_modes roots beta_k L of 1 + cos(x) cosh(x) = 0 (clamped-free beam).

    The k-th root lies in ((k-1) pi, k pi); solved as cos x + 1/cosh x = 0 (well scaled).
    Approx. 1.8751040687, 4.6940911330, 7.8547574382, ...
    """
    f = lambda x: math.cos(x) + 2.0 * math.exp(-x) / (1.0 + math.exp(-2.0 * x))  # noqa: E731
    return np.array([_brent(f, (k - 1) * np.pi, k * np.pi) for k in range(1, n_modes + 1)])


def euler_bernoulli_cantilever_frequencies(L, E, I, rho, A, n_modes=3):
    """Bending natural frequencies [Hz] of a clamped-free Euler-Bernoulli beam.

    L [mm], E [N/mm^2], I [mm^4], rho [t/mm^3], A [mm^2]:
    f_k = (beta_k L)^2 / (2 pi) * sqrt(E I / (rho A L^4)).
    """
    return (
        cantilever_frequency_roots(n_modes) ** 2 / (2.0 * np.pi) * np.sqrt(E * I / (rho * A * L**4))
    )
