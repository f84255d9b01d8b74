"""The small-angle series of ``_kernels`` (sin x / x, (1 - cos x) / x^2, the arc's q, asin s / s,
the mid element's J_l^-T and T factors) against their closed forms evaluated at 40 digits
(mpmath), over the whole range each is used in, and the rotation maps built on them against
Rodrigues' formula and its inverse across the series' bounds."""

from __future__ import annotations

import math

import mpmath as mp
import numpy as np
import pytest

from brush_env.engine import _kernels as K

mp.mp.dps = 40
ULP = 2.0**-52

CASES = [
    ("SINC", K.SINC, K.TRIG_SERIES_MAX, lambda x: mp.sin(x) / x),
    ("VERS", K.VERS, K.TRIG_SERIES_MAX, lambda x: (1 - mp.cos(x)) / x**2),
    ("QARC", K.QARC, K.TRIG_SERIES_MAX, lambda x: (mp.sin(x) - x * mp.cos(x)) / (4 * x**3)),
    ("ASIN", K.ASIN, K.ASIN_SERIES_MAX, lambda x: mp.asin(x) / x),
    ("JL_C", K.JL_C, K.JL_SERIES_MAX, lambda x: (1 - (x / 2) * mp.cot(x / 2)) / x**2),
    ("JL_T", K.JL_T, K.JL_SERIES_MAX, lambda x: mp.tan(x / 4) / x),
]


@pytest.mark.parametrize("name,coefs,bound,exact", CASES, ids=[c[0] for c in CASES])
def test_series_matches_closed_form_to_the_last_bits(name, coefs, bound, exact):
    # up to the bound (its last point just below it, where the truncation error is largest)
    x2s = np.concatenate([np.geomspace(1e-12, bound, 300), [np.nextafter(bound, 0.0)]])
    worst = 0.0
    for x2 in x2s:
        ref = exact(mp.sqrt(mp.mpf(float(x2))))
        got = K.series(float(x2), coefs)
        worst = max(worst, float(abs(mp.mpf(got) / ref - 1)))
    # Horner's rounding (~1 ulp) plus the truncation (< 1e-17 by construction)
    assert worst <= 3 * ULP, f"{name}: worst relative error {worst:.3g}"


#: every coefficient from its textbook closed form (Abramowitz & Stegun 4.3.65, 4.3.67, 4.3.70,
#: 4.4.40; B_n the Bernoulli numbers), k = 0, 1, ...
COEF_FORMULAS = {
    "SINC": lambda k: mp.mpf(-1) ** k / mp.factorial(2 * k + 1),
    "VERS": lambda k: mp.mpf(-1) ** k / mp.factorial(2 * k + 2),
    "QARC": lambda k: mp.mpf(-1) ** k * (2 * k + 2) / (4 * mp.factorial(2 * k + 3)),
    "ASIN": lambda k: mp.binomial(2 * k, k) / (mp.mpf(4) ** k * (2 * k + 1)),
    # (1 - y cot y) / (4 y^2), y = x / 2: y cot y = sum (-1)^n B_2n (2y)^2n / (2n)!
    "JL_C": lambda k: mp.mpf(-1) ** k * mp.bernoulli(2 * k + 2) / mp.factorial(2 * k + 2),
    # tan z / (4 z), z = x / 4: tan z = sum (-1)^(n-1) 2^2n (2^2n - 1) B_2n z^(2n-1) / (2n)!
    "JL_T": lambda k: (
        mp.mpf(-1) ** k
        * mp.mpf(2) ** (2 * k + 2)
        * (mp.mpf(2) ** (2 * k + 2) - 1)
        * mp.bernoulli(2 * k + 2)
        / (mp.factorial(2 * k + 2) * mp.mpf(4) ** (2 * k + 1))
    ),
}


@pytest.mark.parametrize("name,coefs,bound,exact", CASES, ids=[c[0] for c in CASES])
def test_series_coefficients_are_the_taylor_coefficients(name, coefs, bound, exact):
    """Each coefficient, the last ones included (whose terms are below the rounding at the
    bound, so the test above cannot see them), is its closed form rounded to a double."""
    for k, c in enumerate(coefs):
        assert c == pytest.approx(float(COEF_FORMULAS[name](k)), rel=2 * ULP), (name, k)


def _rodrigues(v):
    """exp([v]) at 40 digits."""
    th = mp.sqrt(sum(mp.mpf(float(a)) ** 2 for a in v))
    k = mp.matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    a = mp.sin(th) / th
    b = (1 - mp.cos(th)) / th**2
    return mp.eye(3) + a * k + b * (k * k)


@pytest.mark.parametrize(
    "angle", [1e-9, 1e-4, 0.05, 0.2, 0.2014, 0.2015, 0.4999, 0.5001, 1.0, 2.9, 3.1]
)
def test_rotation_log_and_exp_across_the_series_bounds(angle):
    rng = np.random.default_rng(int(angle * 1e4) + 7)
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    v = angle * axis
    # exp: rotate_left(v, I) against Rodrigues at 40 digits
    out = np.empty((3, 3))
    K.rotate_left(v[0], v[1], v[2], np.eye(3), out)
    exact = _rodrigues([mp.mpf(float(a)) for a in v])
    err = max(abs(out[i, j] - float(exact[i, j])) for i in range(3) for j in range(3))
    assert err <= 4 * ULP
    # log: of the exact rotation rounded to doubles, back to v
    R = np.array([[float(exact[i, j]) for j in range(3)] for i in range(3)])
    w = np.empty(3)
    K.log3s(*R.ravel(), w)
    # a rotation matrix rounded to doubles fixes its angle to ~1 ulp / sin(theta) near pi
    tol = 8 * ULP * max(1.0, angle / max(math.sin(angle), 1e-300))
    assert np.max(np.abs(w - v)) <= tol * max(angle, 1.0)
