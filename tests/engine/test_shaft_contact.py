"""Shaft and head contact (issue 28): every body's capsule touches the surfaces, the head's
clearance is reported, and the in-step penetration peaks reach the caller.

Geometry is checked outside the engine: body centres and head corners are recomputed here from
the state's poses and the scene's surface definitions with numpy, never with the engine's gap
kernels.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from brush_env.engine import Simulator, load_fidelity, load_scene
from brush_env.engine.simulator import PENETRATION_WARN_FRACTION

R_DOWN = np.diag([1.0, -1.0, -1.0])


def _sim(shaft: bool = True, head: bool = True) -> Simulator:
    scene = dataclasses.replace(load_scene("flat_plate"), shaft_contact=shaft, head_contact=head)
    return Simulator(scene, load_fidelity("coarse").settings(dt=4e-3))


def _press(sim: Simulator, depth: float, speed: float = 20.0):
    """Press straight down from 0.2 mm above touching by ``depth`` [mm] at ``speed`` [mm/s];
    returns the lowest body centre z [mm] over every solver step and the step results."""
    z0 = sim.touch_height(R_DOWN) + 0.2
    sim.reset(np.array([0.0, 0.0, z0]), R_DOWN)
    lowest = [np.inf]
    advance = sim.bristles.advance

    def hooked(*a, **k):
        out = advance(*a, **k)
        lowest[0] = min(lowest[0], float(sim.state.pos[:, 2].min()))  # the plate is z = 0
        return out

    sim.bristles.advance = hooked
    n = int(round(depth / (speed * sim.settings.dt)))
    res = [
        sim.step(np.array([0.0, 0.0, z0 - speed * sim.settings.dt * k]), R_DOWN)
        for k in range(1, n + 1)
    ]
    return lowest[0], res


def test_capsules_from_the_sections():
    sim = _sim()
    sim.reset(np.array([0.0, 0.0, 30.0]), R_DOWN)
    sh, m = sim.state.shaft, sim.model
    assert sh.shape == (m.n_bodies,)
    # default brush: 1.8 x 0.8 and 1.3 x 0.8 mm sections -> radius 0.4 mm
    np.testing.assert_allclose(sh["radius"], 0.4)
    np.testing.assert_allclose(sh["lo"], -0.5 * m.seg_len)
    last = m.bstart[1:] - 1
    np.testing.assert_allclose(sh["hi"][last], 0.5 * m.seg_len[last] - m.tip_radius)


def test_switched_off_is_the_tip_only_model():
    sim = _sim(shaft=False, head=False)
    out = sim.reset(np.array([0.0, 0.0, 20.0]), R_DOWN)
    assert sim.state.shaft.size == 0
    assert "shaft_normal_force" not in out.extra and "head_clearance" not in out.extra


def test_pressed_bristles_lie_on_the_plate_and_push_harder():
    """A 6 mm press (beyond the buckling plateau): with shaft contact no body centre sinks into
    the plate and the TCP force rises at the end; tip-only, body centres go through the plate."""
    low_on, res_on = _press(_sim(shaft=True), 6.0)
    assert low_on > -0.1, low_on
    fz = np.array([-r.tcp_force[2] for r in res_on])
    assert fz[-1] >= 0.98 * fz[:-1].max(), (fz[-1], fz.max())
    shaft = np.array([r.extra["shaft_normal_force"].sum() for r in res_on])
    assert shaft[-1] > 0.5  # the shafts carry part of the load
    low_off, _ = _press(_sim(shaft=False), 6.0)
    assert low_off < -0.1  # the tip-only model (issue 28)


def test_head_clearance_is_the_outline_corner_height():
    sim = _sim()
    m, brush = sim.model, sim.brush
    R = (
        np.array(
            [[np.cos(0.3), 0.0, np.sin(0.3)], [0.0, 1.0, 0.0], [-np.sin(0.3), 0.0, np.cos(0.3)]]
        )
        @ R_DOWN
    )
    p = np.array([1.0, 2.0, 25.0])
    out = sim.reset(p, R)
    # the roots' bounding rectangle in the head plane, 1 mm wider, its corners in the world
    n = brush.head_rotation()[:, 2]
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    o = m.root_p.mean(axis=0)
    a, b = (m.root_p - o) @ e1, (m.root_p - o) @ e2
    corners = [
        o + x * e1 + y * e2
        for x in (a.min() - 1.0, a.max() + 1.0)
        for y in (b.min() - 1.0, b.max() + 1.0)
    ]
    z = min(float((p + R @ c)[2]) for c in corners)  # the plate z = 0
    assert out.extra["head_clearance"] == pytest.approx(z, abs=1e-9)


def test_in_step_peaks_and_rearmed_warning():
    sim = _sim()
    sim._pen_warned = True
    out = sim.reset(np.array([0.0, 0.0, 30.0]), R_DOWN)
    assert not sim._pen_warned  # re-armed by every reset
    assert out.extra["max_tip_penetration"] == 0.0
    assert out.extra["steps_beyond_penalty_range"] == 0
    _, res = _press(sim, 1.0)
    for r in res:
        assert r.extra["max_tip_penetration"] >= r.tip_penetration.max() - 1e-15
        beyond = r.tip_penetration / sim.model.tip_radius > PENETRATION_WARN_FRACTION
        assert r.extra["steps_beyond_penalty_range"] >= int(beyond.any())


def test_broad_phase_per_body_changes_no_force(monkeypatch):
    """The broad phase (``shaft.broad_phase``) passes on only the bodies whose own capsule can
    reach the plate within the step.  Deep enough that shafts carry load (the 6 mm press above),
    every force is the same as with every body checked in every residual: a body it leaves out
    could not have touched.  And it is per body: bodies of one bristle differ."""
    from brush_env.engine import chain as chain_mod

    marked = []

    def press(all_near: bool):
        sim = _sim()
        original = chain_mod.shf.broad_phase

        def hooked(*args):
            original(*args)
            con = args[4]  # (bstart, root_p, chain, drive, con, h, g)
            near = con.shaft["near"].copy()
            if all_near:
                con.shaft["near"] = 1
            else:
                marked.append(near)

        monkeypatch.setattr(chain_mod.shf, "broad_phase", hooked)
        try:
            return _press(sim, 6.0)[1], sim.model.bstart
        finally:
            monkeypatch.setattr(chain_mod.shf, "broad_phase", original)

    res, bstart = press(False)
    ref, _ = press(True)
    shaft = np.array([r.extra["shaft_normal_force"].sum() for r in res])
    assert shaft[-1] > 0.5  # the shafts carry load at the end
    for a, b in zip(res, ref):
        np.testing.assert_allclose(a.tcp_force, b.tcp_force, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(a.tip_normal_force, b.tip_normal_force, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(
            a.extra["shaft_normal_force"], b.extra["shaft_normal_force"], rtol=1e-9, atol=1e-12
        )
    # per body: some solver step has a bristle with one body passed on and another left out
    mixed = [
        np.any(np.maximum.reduceat(n, bstart[:-1]) != np.minimum.reduceat(n, bstart[:-1]))
        for n in marked
    ]
    assert any(mixed)
