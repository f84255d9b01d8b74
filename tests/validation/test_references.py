"""Checks of the independent reference solutions in brush_env.validation.references."""

import math

import numpy as np
import pytest

from brush_env.validation.references import (
    axial_tip,
    cantilever_frequency_roots,
    elastica_cantilever,
    elastica_cantilever_profile,
    euler_bernoulli_cantilever_frequencies,
    timoshenko_cantilever_tip,
    torsion_tip,
)

# (alpha, v/L, x_tip/L = 1 - h/L, tip angle [rad]); Bisshopp & Drucker (1945), Mattiasson (1981),
# recomputed here to 10 digits and cross-checked by the shooting method below.
ELASTICA_TABLE = [
    (1.0, 0.30172, 0.94357, 0.46135),
    (2.0, 0.49346, 0.83936, 0.78175),
    (5.0, 0.71379, 0.61237, 1.21537),
    (10.0, 0.81061, 0.44500, 1.43029),
]


def _shoot(alpha, nsteps=1000):
    """Independent solution: RK4 shooting on theta'' = -alpha cos(theta), theta'(1) = 0.

    Returns (s, theta, x, y) on a uniform grid of nsteps + 1 points.
    """
    h = 1.0 / nsteps

    def rhs(z):
        th, om = z[0], z[1]
        return np.array([om, -alpha * math.cos(th), math.cos(th), math.sin(th)])

    def integrate(m, keep=False):
        z = np.array([0.0, m, 0.0, 0.0])
        out = [z]
        for _ in range(nsteps):
            k1 = rhs(z)
            k2 = rhs(z + 0.5 * h * k1)
            k3 = rhs(z + 0.5 * h * k2)
            k4 = rhs(z + h * k3)
            z = z + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
            if keep:
                out.append(z)
        return np.array(out) if keep else z

    # theta'(0) = alpha x_tip lies in (0, alpha); Illinois (regula falsi) on theta'(1) = 0
    a, b = 0.0, alpha
    fa, fb = integrate(a)[1], integrate(b)[1]
    assert fa < 0.0 < fb
    side = 0
    for _ in range(100):
        c = (a * fb - b * fa) / (fb - fa)
        fc = integrate(c)[1]
        if abs(fc) < 1e-13 * alpha:
            break
        if fc * fb > 0.0:
            b, fb = c, fc
            fa = 0.5 * fa if side == -1 else fa
            side = -1
        else:
            a, fa = c, fc
            fb = 0.5 * fb if side == 1 else fb
            side = 1
    else:
        raise AssertionError("shooting did not converge")
    z = integrate(c, keep=True)
    return np.linspace(0.0, 1.0, nsteps + 1), z[:, 0], z[:, 2], z[:, 3]


# --------------------------------------------------------------------------- closed forms
def test_timoshenko_cantilever_hand_values():
    r = timoshenko_cantilever_tip(P=1.0, L=10.0, E=1000.0, G=400.0, I=2.0, A=3.0, kappa=5 / 6)
    # bending 1*1000/(3*1000*2) = 1/6, shear 1*10/(5/6*400*3) = 0.01
    assert r["v"] == pytest.approx(1.0 / 6.0 + 0.01, rel=1e-14)
    assert r["theta"] == pytest.approx(100.0 / 4000.0, rel=1e-14)
    # shear-rigid limit -> Euler-Bernoulli
    r = timoshenko_cantilever_tip(P=2.0, L=5.0, E=200.0, G=1e300, I=1.5, A=1.0, kappa=1.0)
    assert r["v"] == pytest.approx(2.0 * 125.0 / (3 * 200.0 * 1.5), rel=1e-14)


def test_axial_and_torsion_hand_values():
    assert axial_tip(P=2.0, L=10.0, E=100.0, A=4.0) == pytest.approx(0.05, rel=1e-14)
    assert torsion_tip(T=3.0, L=10.0, G=50.0, J=6.0) == pytest.approx(0.1, rel=1e-14)


# --------------------------------------------------------------------------- elastica
@pytest.mark.parametrize("alpha, v, x, th", ELASTICA_TABLE)
def test_elastica_table(alpha, v, x, th):
    r = elastica_cantilever(alpha)
    assert r["v_over_L"] == pytest.approx(v, abs=1e-4)
    assert 1.0 - r["h_over_L"] == pytest.approx(x, abs=1e-4)
    assert r["tip_angle_rad"] == pytest.approx(th, abs=1e-4)


@pytest.mark.parametrize("alpha", [0.1, 1.0, 5.0, 20.0])
def test_elastica_internal_consistency(alpha):
    r = elastica_cantilever(alpha)
    th0 = r["tip_angle_rad"]
    # clamped moment: EI theta'(0) = P x_tip with theta'(0)^2 = 2 alpha sin(th0)
    assert 1.0 - r["h_over_L"] == pytest.approx(math.sqrt(2.0 * math.sin(th0) / alpha), rel=1e-12)
    # quadrature converged
    r2 = elastica_cantilever(alpha, n=160)
    for key in r:
        assert r[key] == pytest.approx(r2[key], rel=1e-12, abs=1e-15)


def test_elastica_small_alpha_limit():
    a = 1e-3
    r = elastica_cantilever(a)
    assert r["v_over_L"] == pytest.approx(a / 3.0, rel=1e-6)
    assert r["h_over_L"] == pytest.approx(a**2 / 15.0, rel=1e-6)
    assert r["tip_angle_rad"] == pytest.approx(a / 2.0, rel=1e-6)
    # second-order perturbation: th0 = alpha/2 - 11 alpha^3/240 + O(alpha^5)
    a = 1e-2
    assert elastica_cantilever(a)["tip_angle_rad"] == pytest.approx(
        a / 2 - 11 * a**3 / 240, abs=1e-11
    )
    assert elastica_cantilever(0.0) == {"v_over_L": 0.0, "h_over_L": 0.0, "tip_angle_rad": 0.0}
    for a in (1e-14, 1e-9):  # both sides of the linear shortcut
        assert elastica_cantilever(a)["v_over_L"] == pytest.approx(a / 3.0, rel=1e-12)


@pytest.mark.slow  # ~7 s: 42 elastica solves
def test_elastica_monotone_and_bounded():
    alphas = np.linspace(0.0, 20.0, 41)
    res = [elastica_cantilever(a) for a in alphas]
    for key in ("v_over_L", "h_over_L", "tip_angle_rad"):
        vals = np.array([r[key] for r in res])
        assert np.all(np.diff(vals) > 0.0)
    assert res[-1]["tip_angle_rad"] < 0.5 * np.pi
    assert elastica_cantilever(500.0)["tip_angle_rad"] < 0.5 * np.pi
    with pytest.raises(ValueError):
        elastica_cantilever(-1.0)


@pytest.mark.parametrize("alpha", [0.1, 1.0, 2.0, 5.0, 10.0])
def test_elastica_matches_shooting(alpha):
    s, th, x, y = _shoot(alpha)
    r = elastica_cantilever(alpha)
    assert r["v_over_L"] == pytest.approx(y[-1], abs=1e-6)
    assert r["h_over_L"] == pytest.approx(1.0 - x[-1], abs=1e-6)
    assert r["tip_angle_rad"] == pytest.approx(th[-1], abs=1e-6)
    prof = elastica_cantilever_profile(alpha, npts=21)
    idx = np.rint(prof["s"] * (len(s) - 1)).astype(int)
    for key, ref in (("x", x), ("y", y), ("theta", th)):
        assert np.allclose(prof[key], ref[idx], atol=1e-6)


def test_elastica_matches_scipy_bvp():
    scipy_integrate = pytest.importorskip("scipy.integrate")
    for alpha in (1.0, 5.0, 10.0):

        def fun(s, z, alpha=alpha):
            return np.vstack([z[1], -alpha * np.cos(z[0]), np.cos(z[0]), np.sin(z[0])])

        def bc(za, zb):
            return np.array([za[0], zb[1], za[2], za[3]])

        s = np.linspace(0.0, 1.0, 50)
        guess = np.vstack([alpha / 2 * s * (2 - s) / 2, alpha * (1 - s), s, 0 * s])
        sol = scipy_integrate.solve_bvp(fun, bc, s, guess, tol=1e-10, max_nodes=100000)
        assert sol.success
        r = elastica_cantilever(alpha)
        zb = sol.y[:, -1]
        assert r["tip_angle_rad"] == pytest.approx(zb[0], abs=1e-6)
        assert 1.0 - r["h_over_L"] == pytest.approx(zb[2], abs=1e-6)
        assert r["v_over_L"] == pytest.approx(zb[3], abs=1e-6)


def test_elastica_profile_endpoints():
    for alpha in (0.0, 1e-13, 3.0):
        p = elastica_cantilever_profile(alpha, npts=11)
        r = elastica_cantilever(alpha)
        assert p["x"][0] == 0.0 and p["y"][0] == 0.0 and p["theta"][0] == pytest.approx(0.0)
        assert p["y"][-1] == pytest.approx(r["v_over_L"], rel=1e-12, abs=1e-300)
        assert p["x"][-1] == pytest.approx(1.0 - r["h_over_L"], rel=1e-12)
        assert p["theta"][-1] == pytest.approx(r["tip_angle_rad"], rel=1e-12, abs=1e-300)
        # inextensible: unit tangent, so the chord between samples is shorter than ds
        seg = np.hypot(np.diff(p["x"]), np.diff(p["y"]))
        assert np.all(seg <= np.diff(p["s"]) * (1 + 1e-12))


# --------------------------------------------------------------------------- vibration
def test_cantilever_frequency_roots():
    x = cantilever_frequency_roots(5)
    assert np.allclose(x[:3], [1.8751040687, 4.6940911330, 7.8547574382], atol=1e-9)
    assert np.all(np.abs(1.0 + np.cos(x) * np.cosh(x)) < 1e-12 * np.cosh(x))
    # asymptotically (2k - 1) pi / 2
    assert x[-1] == pytest.approx(4.5 * np.pi, abs=1e-5)


def test_euler_bernoulli_frequency_steel():
    # steel bar, 1 mm x 1 mm section, L = 100 mm: E = 210 GPa, rho = 7850 kg/m^3
    L, E, rho, b = 100.0, 210000.0, 7.85e-9, 1.0
    f = euler_bernoulli_cantilever_frequencies(L, E, b**4 / 12, rho, b * b, n_modes=3)
    # hand: 1.8751040687^2/(2 pi) * sqrt(210000/12 / (7.85e-9 * 1e8)) = 0.559593 * 149.3084
    assert f[0] == pytest.approx(83.5517, rel=1e-5)
    assert f[1] / f[0] == pytest.approx((4.6940911330 / 1.8751040687) ** 2, rel=1e-9)
    assert f.shape == (3,)
