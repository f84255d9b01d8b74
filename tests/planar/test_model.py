"""The pymunk planar chain (brush_env.planar) against closed forms: a cantilever's tip
deflection under a small tip load (the chain's own formula and Euler-Bernoulli's PL^3/3EI), the
explicit-step limit refused with a clear error, and the tips' rigid contact with a plate."""

from __future__ import annotations

import math

import numpy as np
import pytest

from brush_env.engine import ConfigError
from brush_env.planar import PlanarBrush, PlanarSettings, Profile, row_bristles
from tests.engine.test_contact import one_bristle


def _settle_under_tip_load(P, n=6, steps=20000):
    brush = one_bristle(bodies=n)
    pb = PlanarBrush(brush, Profile.flat(z=-100.0), PlanarSettings(gravity=False), cut="y")
    pb.space.damping = 0.02  # velocity kept per second: settles the static test quickly
    pb.place(0.0, 50.0)
    tip_body = pb.tips[0].body
    for _ in range(steps):
        tip_body.apply_force_at_world_point(
            (P, 0.0), pb.tips[0].body.local_to_world(pb.tips[0].offset)
        )
        pb.step(0.0, 50.0)
    return pb, brush.bristles[0]


@pytest.mark.parametrize("n", [3, 6])
def test_cantilever_tip_deflection_matches_the_chain_formula_and_euler_bernoulli(n):
    """Small lateral tip load P (deflection ~1 % of L): the chain of n segments with root spring
    2EI/l and joint springs EI/l deflects (P l^3/EI)(n^2/2 + (n-1)n(2n-1)/6) -- within 1.5 % of
    PL^3/3EI at n = 6 -- measured to 1 %."""
    P = 2e-4  # [N]
    pb, b = _settle_under_tip_load(P, n)
    EI = b.material.E * b.section.I_y  # cut "y": bending about the thickness (weak) axis
    L = b.length
    seg = L / n
    chain = P * seg**3 / EI * (n * n / 2 + (n - 1) * n * (2 * n - 1) / 6)
    euler = P * L**3 / (3 * EI)
    lean_x = L * math.sin(pb.lean)
    dx = pb.tip_positions()[0, 0] - lean_x
    assert dx == pytest.approx(chain, rel=0.01)
    if n == 6:
        assert chain == pytest.approx(euler, rel=0.015)


def test_a_step_too_large_for_the_stiffness_is_refused_with_the_limit():
    brush = one_bristle(bodies=6)
    with pytest.raises(ConfigError, match=r"planar.dt = 0.005 s is too large .* need dt <= "):
        PlanarBrush(brush, Profile.flat(), PlanarSettings(dt=0.005))
    with pytest.raises(ConfigError, match=r"planar.mass_scale = 0.5 is out of range"):
        PlanarSettings(mass_scale=0.5)


def test_pressed_tips_rest_on_the_plate_and_cuts_pick_the_right_bristles():
    from brush_env.engine import load_brush

    brush = load_brush("default")
    across, at = row_bristles(brush, "y")
    assert len(across) == 4 and abs(at) == pytest.approx(1.1)
    along, y = row_bristles(brush, "x")
    assert len(along) == 10
    pb = PlanarBrush(brush, Profile.flat(), cut="y")
    z_touch = max(b.length for b in across) + across[0].tip_radius
    pb.place(0.0, z_touch + 0.2)
    for k in range(3000):  # 1 mm down in 0.3 s
        pb.step(0.0, z_touch + 0.2 - 1.2 * (k + 1) / 3000)
    tips = pb.tip_positions()
    touching = np.linalg.norm(pb.contact_forces(), axis=1) > 0
    assert touching.any()
    # rigid contact: touching tip centres sit one radius above the plate (within the slop)
    np.testing.assert_allclose(tips[touching, 1], across[0].tip_radius, atol=2e-3)
