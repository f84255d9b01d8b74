"""Tests of UR MoveL with blend radius (motion.movel)."""

import math

import numpy as np
import pytest

from brush_env.motion import R0, MoveL, paper_circle_movel

from .conftest import A, V, paper_center


def test_movel_velocity_continuous_through_blends():
    mv = paper_circle_movel(paper_center(), 20.0, V, A, turns=2)
    dt = 1e-3
    t = np.arange(0.0, mv.duration + dt, dt)
    Vv = mv.sample(t)[2]
    jumps = np.linalg.norm(np.diff(Vv, axis=0), axis=1)
    # tangential a = 100 mm/s^2 on the ramps, centripetal v^2/rho <= 400/14.1 = 28 in the blends
    assert jumps.max() <= A * dt * (1 + 1e-6)
    # exactly at every element junction, left and right velocities agree
    S0 = mv._elem_S0[1:-1]
    for S in S0:
        tj = mv._pieces[0].t_at_s(S)
        vl, vr = mv.twist(tj - 1e-9)[0], mv.twist(tj + 1e-9)[0]
        assert np.linalg.norm(vl - vr) < 1e-5


def test_movel_blend_shape_and_stops():
    pts = [[0, 0, 0], [40, 0, 0], [40, 40, 0]]
    mv = MoveL(pts, V, A, blend_radius=8.0)
    # parabolic blend: mid point at r*sqrt(2)/4 from the corner, on the bisector
    path = mv.path_points(40001)
    d = np.linalg.norm(path - [40, 0, 0], axis=1)
    assert d.min() == pytest.approx(8 * math.sqrt(2) / 4, rel=1e-6)
    # path stays on the segments outside the blend zone
    far = d > 8.0 + 1e-6
    on_seg = (np.abs(path[:, 1]) < 1e-9) | (np.abs(path[:, 0] - 40) < 1e-9)
    assert np.all(on_seg[far])
    np.testing.assert_allclose(path[0], [0, 0, 0])
    np.testing.assert_allclose(path[-1], [40, 40, 0], atol=1e-9)
    # r = 0: stop at the corner (UR default without blend)
    stop = MoveL(pts, V, A, blend_radius=0.0)
    assert stop.duration == pytest.approx(2 * (40 / V + V / A))
    p_mid, _ = stop.pose(stop.duration / 2)
    np.testing.assert_allclose(p_mid, [40, 0, 0], atol=1e-9)
    assert np.linalg.norm(stop.twist(stop.duration / 2)[0]) < 1e-9


def test_movel_blend_radius_reduced_when_zones_overlap():
    pts = [[0, 0, 0], [20, 0, 0], [20, 4, 0], [40, 4, 0]]
    mv = MoveL(pts, V, A, blend_radius=5.0)
    np.testing.assert_allclose(mv.blend_radii, [2.0, 2.0])  # half of the 4 mm middle segment
    assert mv.blend_reduced.all()
    ok = MoveL(pts, V, A, blend_radius=1.5)
    np.testing.assert_allclose(ok.blend_radii, [1.5, 1.5])
    assert not ok.blend_reduced.any()
    # the reduced path is still tangent-continuous and never leaves the corners' zones
    Vv = mv.sample(np.linspace(0, mv.duration, 20001))[2]
    assert np.linalg.norm(np.diff(Vv, axis=0), axis=1).max() < 1.0


def test_movel_repeat_end_and_start_pose():
    sq = [[10, 0, 0], [10, 10, 0], [0, 10, 0], [0, 0, 0]]
    mv = MoveL(sq, V, A, 2.0, start_pose=([0, 0, 0], R0), repeat=3, end=[10, 0, 0])
    assert len(mv.points) == 1 + 12 + 1
    # 13 sides of 10 mm; each of the 12 blends replaces 4 mm of polyline by a shorter arc that is
    # longer than its 2.83 mm chord
    assert 130.0 > mv.length > 130.0 - 12 * (4.0 - 2.0 * math.sqrt(2.0))
    np.testing.assert_allclose(mv.end_pose[0], [10, 0, 0], atol=1e-9)
    # the orientation must match the start pose
    with pytest.raises(ValueError, match="orientation"):
        MoveL(sq, V, A, 2.0, start_pose=([0, 0, 0], R0), orientation=np.eye(3))
    with pytest.raises(ValueError, match="repeat"):
        MoveL(sq, V, A, 2.0, repeat=0)
