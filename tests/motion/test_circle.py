"""Tests of the exact circle (motion.circle)."""

import math

import numpy as np
import pytest

from brush_env.motion import R0

from .conftest import A, V, make_circle


def test_circle_radius_plane_and_speed():
    circ = make_circle()
    c = circ.center
    t = np.linspace(0, circ.duration, 20001)
    P, R, Vv, W = circ.sample(t)
    np.testing.assert_allclose(np.linalg.norm(P - c, axis=1), 20.0, atol=1e-12)
    np.testing.assert_allclose(P[:, 2], c[2], atol=1e-12)
    np.testing.assert_array_equal(R, np.tile(R0, (t.size, 1, 1)))
    assert not W.any()
    speed = np.linalg.norm(Vv, axis=1)
    ta = V / A
    cruise = (t > ta + 1e-9) & (t < circ.duration - ta - 1e-9)
    np.testing.assert_allclose(speed[cruise], V, rtol=1e-12)
    ramp = t <= ta
    np.testing.assert_allclose(speed[ramp], A * t[ramp], atol=1e-9)
    assert speed[0] == 0.0 and speed[-1] == pytest.approx(0.0, abs=1e-9)
    # velocity is tangent: perpendicular to the radius
    np.testing.assert_allclose(np.sum((P - c) * Vv, axis=1), 0.0, atol=1e-9)
    # duration of a trapezoid: L / v + v / a
    assert circ.duration == pytest.approx(2 * math.pi * 20 * 4 / V + V / A)


def test_circle_start_point_direction_and_angle():
    circ = make_circle()
    c = circ.center
    np.testing.assert_allclose(circ.start_pose[0], c + [-20.0, 0.0, 0.0], atol=1e-12)
    # counter-clockwise about +z from P0 = (-r, 0): first moves in -y
    v = circ.twist(0.5)[0]
    assert v[1] < 0 and abs(v[0]) < 1e-9 * V + abs(v[1])
    assert circ.angle(0.0) == 0.0
    assert circ.angle(circ.duration) == pytest.approx(8 * math.pi)
    t = np.linspace(0, circ.duration, 5001)
    th = circ.angle(t)
    assert np.all(np.diff(th) >= 0)
    # angle is consistent with position: polar angle of p equals start_angle + theta (mod 2pi)
    P = circ.sample(t)[0]
    phi = np.arctan2(P[:, 1] - c[1], P[:, 0] - c[0])
    d = np.angle(np.exp(1j * (phi - (math.pi + th))))
    np.testing.assert_allclose(d, 0.0, atol=1e-12)
    # 9pi/4 lies in the lower-left quarter, 13pi/4 in the upper-right one (section 5.1)
    pll = circ.point_at_angle(9 * math.pi / 4) - c
    pur = circ.point_at_angle(13 * math.pi / 4) - c
    assert pll[0] < 0 and pll[1] < 0 and pur[0] > 0 and pur[1] > 0
    # inverse, and rate
    for theta in (0.1, 2 * math.pi, 2 * math.pi + math.pi / 4, 7.9 * math.pi):
        assert circ.angle(circ.time_at_angle(theta)) == pytest.approx(theta, abs=1e-12)
    tt = np.linspace(0.01, circ.duration - 0.01, 97)
    num = (circ.angle(tt + 1e-6) - circ.angle(tt - 1e-6)) / 2e-6
    np.testing.assert_allclose(circ.angle_rate(tt), num, atol=1e-4)
    assert circ.angle_rate(-1.0) == 0.0 and circ.angle(-1.0) == 0.0


def test_circle_clockwise_and_triangular_profile():
    cw = make_circle(clockwise=True, turns=0.05)
    v = cw.twist(0.1)[0]
    assert v[1] > 0  # clockwise from (-r, 0) goes up
    assert cw.angle(cw.duration) == pytest.approx(0.1 * math.pi)
    # arc 2*pi*20*0.05 = 6.28 mm < v^2/a = 4 mm? no: 6.28 > 4 -> trapezoid; use a short arc
    short = make_circle(turns=0.02, accel=10.0)  # arc 2.51 mm < v^2/a = 40 mm: triangular
    arc = 2 * math.pi * 20 * 0.02
    assert short.duration == pytest.approx(2 * math.sqrt(arc / 10.0))
    speeds = np.linalg.norm(short.sample(np.linspace(0, short.duration, 1001))[2], axis=1)
    assert speeds.max() == pytest.approx(math.sqrt(10.0 * arc), rel=1e-3)
    assert speeds.max() < V
