"""The integrators on a damped linear oscillator, against closed forms (issue 10 item 4).

A one-body bristle along x (root fixed at the TCP, gravity off) has two exactly linear modes:
the body sliding along the axis (the element's axial strain e_0 = u, stiffness K_00 = E A / L,
mass m = rho A L) and twisting about it (e_3 = phi, K_33 = G J / L, inertia J_x = m (b^2 + h^2)
/ 12).  With the stiffness-proportional damping C = beta K, beta = 2 zeta_mat / omega_1 (omega_1
the Euler-Bernoulli cantilever frequency), each mode obeys q'' + beta w^2 q' + w^2 q = 0 with
w^2 = K / inertia: here written as y' = A y, y = (q, q').  Everything below is derived from the
section, the material and the length, not from a measured value.

* The engine's trajectory after releasing a displacement equals the exact discrete solution of
  its scheme: backward Euler y_{n+1} = (I - h A)^-1 y_n; BDF2 (after one backward Euler start
  step) y_{n+1} = (I - 2/3 h A)^-1 (4/3 y_n - 1/3 y_{n-1}).
* Against the continuous solution, the per-period amplitude and phase errors of the measured
  one-step root and the error of the state after two periods shrink at the scheme's order:
  x2 (backward Euler) and x4 (BDF2) when h halves.
"""

import math

import numpy as np
import pytest

from brush_env.engine import BristleConfig, BrushConfig, Material, Section, SimSettings, Simulator
from brush_env.engine.rotation import expmap, logmap

E, NU, RHO, L = 7.0, 0.48, 1.15e-9, 10.0  # silicone [MPa, -, t/mm^3], bristle length [mm]
B, H = 1.8, 0.8  # rectangular section [mm]
BETA1L = 1.875104068711961  # first root of cos x cosh x = -1 (cantilever)
ZETA_AXIAL = 0.05  # chosen damping ratio of the axial mode

A_SEC = B * H
I_MIN = B * H**3 / 12.0
MASS = RHO * A_SEC * L
OMEGA_1 = BETA1L**2 * math.sqrt(E * I_MIN / (RHO * A_SEC * L**4))
K_AXIAL = E * A_SEC / L
# material damping ratio that gives the axial mode ZETA_AXIAL: beta w_a / 2 = zeta
ZETA_MAT = ZETA_AXIAL * OMEGA_1 / math.sqrt(K_AXIAL / MASS)
BETA = 2.0 * ZETA_MAT / OMEGA_1
# torsion: G J / L with Roark's J of a rectangle (half sides a >= c), J_x about the axis
_a, _c = B / 2.0, H / 2.0
J_TORSION = _a * _c**3 * (16.0 / 3.0 - 3.36 * (_c / _a) * (1.0 - _c**4 / (12.0 * _a**4)))
K_TORSION = E / (2.0 * (1.0 + NU)) * J_TORSION / L
J_X = MASS * (B * B + H * H) / 12.0

MODES = {"axial": (K_AXIAL, MASS), "torsion": (K_TORSION, J_X)}
Q0 = 1e-2  # released displacement: 10 um axial, 10 mrad torsion (both modes are linear)


def _system(mode):
    k, inertia = MODES[mode]
    w2 = k / inertia
    return np.array([[0.0, 1.0], [-w2, -BETA * w2]]), math.sqrt(w2), 0.5 * BETA * math.sqrt(w2)


def _release(mode, integrator, h, n):
    """States (q, q') at steps 0..n of the engine after releasing Q0 from rest."""
    mat = Material(name="osc", E=E, nu=NU, density=RHO, damping_ratio=ZETA_MAT)
    br = BristleConfig(
        root=(0.0, 0.0, 0.0),
        axis=(1.0, 0.0, 0.0),
        width_dir=(0.0, 1.0, 0.0),
        length=L,
        section=Section.rect(B, H),
        material=mat,
        bodies=1,
        tip_radius=0.2,
    )
    brush = BrushConfig(
        name="osc", head_offset=(0.0, 0.0, 0.0), head_rpy=(0.0, 0.0, 0.0), bristles=(br,)
    )
    sim = Simulator(
        brush,
        SimSettings(
            dt=h,
            integrator=integrator,
            gravity=(0.0, 0.0, 0.0),
            newton_rtol=1e-10,
            jacobian_max_age=0,
        ),
    )
    sim.reset()
    st = sim.get_state()  # at rest, displaced (the history too: no step lies behind it)
    for pos, rot in ((st.pos, st.rot), (st.ppos, st.prot), (st.pppos, st.pprot)):
        if mode == "axial":
            pos[0, 0] += Q0
        else:
            rot[0] = expmap([Q0, 0.0, 0.0]) @ rot[0]
    sim.set_state(st)
    out = [(Q0, 0.0)]
    for _ in range(n):
        sim.step(np.zeros(3), np.eye(3))
        s = sim.state
        assert np.allclose(s.pos[0, 1:], 0.0, atol=1e-12)  # the mode stays isolated
        out.append(
            (s.pos[0, 0] - L / 2, s.vel[0, 0])
            if mode == "axial"
            else (logmap(s.rot[0])[0], s.omg[0, 0])
        )
    return np.array(out)


def _discrete(A, integrator, h, n):
    """The scheme's exact solution on y' = A y from (Q0, 0)."""
    eye = np.eye(2)
    ys = [np.array([Q0, 0.0])]
    ys.append(np.linalg.solve(eye - h * A, ys[0]))  # both start with a backward Euler step
    for _ in range(n - 1):
        if integrator == "euler":
            ys.append(np.linalg.solve(eye - h * A, ys[-1]))
        else:
            ys.append(np.linalg.solve(eye - 2.0 / 3.0 * h * A, 4.0 / 3.0 * ys[-1] - ys[-2] / 3.0))
    return np.array(ys)


def _continuous(w, zeta, t):
    wd = w * math.sqrt(1.0 - zeta * zeta)
    env = Q0 * np.exp(-zeta * w * t)
    q = env * (np.cos(wd * t) + zeta * w / wd * np.sin(wd * t))
    return np.stack([q, -env * w * w / wd * np.sin(wd * t)], axis=-1)


def _principal_root(y, integrator):
    """The measured one-step root: fit the engine's linear map (one step for backward Euler, two
    for BDF2) to its own states and take the eigenvalue of positive phase nearest 1."""
    if integrator == "euler":
        M = np.linalg.lstsq(y[1:-1], y[2:], rcond=None)[0].T
    else:
        X = np.hstack([y[2:-1], y[1:-2]])
        PQ = np.linalg.lstsq(X, y[3:], rcond=None)[0].T
        M = np.vstack([PQ, np.hstack([np.eye(2), np.zeros((2, 2))])])
    mu = np.linalg.eigvals(M)
    mu = mu[np.imag(mu) > 0]
    return mu[np.argmin(np.abs(mu - 1.0))]


@pytest.mark.parametrize("mode", sorted(MODES))
@pytest.mark.parametrize("integrator", ["euler", "bdf2"])
def test_release_follows_the_schemes_discrete_solution(mode, integrator):
    A, w, _ = _system(mode)
    h = 2.0 * math.pi / w / 40.0
    y = _release(mode, integrator, h, 120)  # three periods
    ref = _discrete(A, integrator, h, 120)
    scale = np.array([Q0, Q0 * w])
    assert np.max(np.abs(y - ref) / scale) < 1e-8
    # and the schemes differ from each other by far more than that: the check discriminates
    other = _discrete(A, "bdf2" if integrator == "euler" else "euler", h, 120)
    assert np.max(np.abs(other - ref) / scale) > 1e-2


@pytest.mark.parametrize("integrator,order", [("euler", 1), ("bdf2", 2)])
def test_amplitude_and_phase_errors_converge_at_the_schemes_order(integrator, order):
    """Per damped period T, the measured root mu gives the amplitude error
    N (ln|mu| - Re(lambda h)) and the phase error N arg(mu) - 2 pi (N = T / h steps): together
    (as the complex N (log mu - lambda h)) they shrink at the scheme's order, and so does the
    largest state error over two periods.  Of the two parts, the one whose leading term does not
    carry a factor zeta converges at the order on its own: backward Euler's amplitude (its
    numerical damping), BDF2's phase."""
    _, w, zeta = _system("axial")
    wd = w * math.sqrt(1.0 - zeta * zeta)
    period = 2.0 * math.pi / wd
    root_err, main_part, state = [], [], []
    for per_period in (80, 160, 320):
        h = period / per_period
        n = 2 * per_period  # two damped periods
        y = _release("axial", integrator, h, n)
        mu = _principal_root(y, integrator)
        lam_h = complex(-zeta * w, wd) * h
        if integrator == "euler":  # the measured root is the scheme's: 1 / (1 - lambda h)
            assert mu == pytest.approx(1.0 / (1.0 - lam_h), abs=1e-9)
        else:  # the principal root of (3/2 - lambda h) mu^2 - 2 mu + 1/2 = 0
            roots = np.roots([1.5 - lam_h, -2.0, 0.5])
            assert mu == pytest.approx(roots[np.argmin(np.abs(roots - 1.0))], abs=1e-9)
        amplitude = per_period * (math.log(abs(mu)) - lam_h.real)
        phase = per_period * np.angle(mu) - 2.0 * math.pi
        root_err.append(abs(complex(amplitude, phase)))
        main_part.append(abs(amplitude if integrator == "euler" else phase))
        if integrator == "euler":
            assert amplitude < 0.0  # numerical damping: decays faster than the true mode
        exact = _continuous(w, zeta, np.arange(n + 1) * h)
        state.append(np.max(np.abs(y - exact) / np.array([Q0, Q0 * w])))
    for errs in (root_err, main_part, state):
        ratios = np.array(errs[:-1]) / np.array(errs[1:])
        assert np.all(np.abs(ratios / 2.0**order - 1.0) < 0.15), (errs, ratios)
