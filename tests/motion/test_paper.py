"""Tests of the paper's four-point circle, Algorithm 1 (motion.paper)."""

import math

import numpy as np
import pytest

from brush_env.motion import (
    R0,
    movel_circle_deviation,
    paper_circle_movel,
    paper_circle_waypoints,
)

from .conftest import A, V, paper_center


def test_paper_waypoints_layout():
    c = paper_center()
    P0, P = paper_circle_waypoints(c, 20.0)
    np.testing.assert_allclose(P0, c + [-20, 0, 0], atol=1e-12)
    assert P.shape == (4, 3)
    np.testing.assert_allclose(np.linalg.norm(P - c, axis=1), 20 * math.sqrt(2))
    # one per quarter, counter-clockwise from P0: lower-left, lower-right, upper-right, upper-left
    np.testing.assert_allclose(np.sign(P[:, :2] - c[:2]), [[-1, -1], [1, -1], [1, 1], [-1, 1]])
    _, Pi = paper_circle_waypoints(c, 20.0, placement="inscribed")
    np.testing.assert_allclose(np.linalg.norm(Pi - c, axis=1), 20.0)


def test_movel_paper_loop_geometry_and_angle():
    c = paper_center()
    mv = paper_circle_movel(c, 20.0, V, A, turns=4)
    P0, _ = paper_circle_waypoints(c, 20.0)
    np.testing.assert_allclose(mv.start_pose[0], P0, atol=1e-12)
    np.testing.assert_allclose(mv.end_pose[0], P0, atol=1e-9)
    # steady corners keep r = 20 (zones exactly touch); first and last corner are cut to r/2
    r = mv.blend_radii
    assert r.size == 16
    np.testing.assert_allclose(r[1:-1], 20.0)
    assert r[0] == pytest.approx(10.0) and r[-1] == pytest.approx(10.0)
    assert mv.blend_reduced[0] and mv.blend_reduced[-1] and not mv.blend_reduced[1:-1].any()
    # one piece (no stops): speed v everywhere but the two ramps
    t = np.linspace(0, mv.duration, 20001)
    P, R, Vv, W = mv.sample(t)
    np.testing.assert_array_equal(R, np.tile(R0, (t.size, 1, 1)))
    speed = np.linalg.norm(Vv, axis=1)
    ta = V / A
    cruise = (t > ta + 1e-9) & (t < mv.duration - ta - 1e-9)
    np.testing.assert_allclose(speed[cruise], V, rtol=1e-9)
    assert mv.duration == pytest.approx(mv.length / V + V / A)
    assert not W.any()
    np.testing.assert_allclose(P[:, 2], c[2], atol=1e-12)
    # angle: 0 at P0, 8 pi at the end, monotonic, rate consistent
    assert mv.angle(0.0) == pytest.approx(0.0, abs=1e-12)
    assert mv.angle(mv.duration) == pytest.approx(8 * math.pi, abs=1e-9)
    th = mv.angle(t)
    assert np.all(np.diff(th) >= -1e-12)
    tt = np.linspace(0.01, mv.duration - 0.01, 101)
    num = (mv.angle(tt + 1e-6) - mv.angle(tt - 1e-6)) / 2e-6
    np.testing.assert_allclose(mv.angle_rate(tt), num, atol=1e-4)


def test_movel_circle_deviation_report():
    c = paper_center()
    rep = movel_circle_deviation(c, 20.0, 20.0)
    # steady loop: parabolic quarter from tangent point to tangent point; max at the diagonal
    expected = 20.0 * (3.0 / (2.0 * math.sqrt(2.0)) - 1.0)  # 1.2132 mm
    assert rep["max_abs_mm"] == pytest.approx(expected, rel=1e-6)
    assert rep["max_outward_mm"] == pytest.approx(expected, rel=1e-6)
    assert rep["max_inward_mm"] < 1e-9
    assert 0.5 < rep["rms_mm"] < expected
    assert rep["blend_radius_effective_mm"] == pytest.approx(20.0)
    assert rep["reduced"] is False
    assert rep["blend_radius_first_corner_mm"] == pytest.approx(10.0)
    assert rep["first_corner_reduced"] is True
    assert rep["first_quarter_max_abs_mm"] > rep["max_abs_mm"]
    assert "half" in rep["rule"]
    # control points on the circle: r = 20 overlaps (side 28.3 mm) and is cut to 14.14 mm
    ins = movel_circle_deviation(c, 20.0, 20.0, placement="inscribed")
    assert ins["reduced"] is True
    assert ins["blend_radius_effective_mm"] == pytest.approx(20.0 / math.sqrt(2.0))
    assert ins["max_abs_mm"] == pytest.approx(20.0 * (1 - math.sqrt(0.5)), rel=1e-6)
    assert ins["max_outward_mm"] == 0.0
    # a larger radius is cut to the half-segment (20 mm), a smaller one deviates more
    assert movel_circle_deviation(c, 20.0, 35.0)["max_abs_mm"] == pytest.approx(expected, rel=1e-6)
    assert movel_circle_deviation(c, 20.0, 10.0)["max_abs_mm"] > 3.0
