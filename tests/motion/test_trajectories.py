"""Tests for brush_env.motion (TCP motions: pose and twist over time)."""

import math

import numpy as np
import pytest

from brush_env.motion import (
    R0,
    Approach,
    Circle,
    Hold,
    MoveL,
    PitchPerturbation,
    Press,
    Sequence,
    Trajectory,
    movel_circle_deviation,
    paper_circle_movel,
    paper_circle_waypoints,
    pitch_profile,
    pitch_profile_dot,
    smoothstep,
    smoothstep_dot,
)

L_BRISTLE = 10.0  # TCP height at which the tips touch the plate
V, A = 20.0, 100.0  # tool speed (mm/s) and acceleration (mm/s^2) used throughout


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
def log_so3(R):
    """Independent small-angle-safe rotation vector (angles well below pi)."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = math.acos(c)
    vee = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-8:
        return 0.5 * vee
    return th / (2.0 * math.sin(th)) * vee


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def numeric_twist(traj, t, e=1e-6):
    pp, Rp = traj.pose(t + e)
    pm, Rm = traj.pose(t - e)
    v = (pp - pm) / (2 * e)
    w = log_so3(Rp @ Rm.T) / (2 * e)
    return v, w


def paper_center(depth=3.0):
    return np.array([50.0, -20.0, L_BRISTLE - depth])


def make_circle(**kw):
    args = {"center": paper_center(), "radius": 20.0, "speed": V, "accel": A, "turns": 4}
    args["start_angle"] = math.pi
    args.update(kw)
    return Circle(**args)


def press_circle_sequence():
    circ = make_circle()
    p_touch = circ.start_pose[0] + np.array([0.0, 0.0, 3.0])
    press = Press((p_touch, R0), depth=3.0, duration=0.5)
    return Sequence([Hold((p_touch, R0), 0.2), press, circ, Hold(circ.end_pose, 0.3)]), circ


def all_trajectories():
    c = paper_center()
    circ = make_circle(turns=1.5)
    seq, _ = press_circle_sequence()
    R_tilted = (
        R0
        @ rot_y(0.3)
        @ np.array(
            [[math.cos(0.2), -math.sin(0.2), 0], [math.sin(0.2), math.cos(0.2), 0], [0, 0, 1]]
        )
    )
    mv = paper_circle_movel(c, 20.0, V, A, turns=2)
    return {
        "hold": Hold((c, R0), 1.0),
        "press": Press((c + [0, 0, 3], R0), 3.0, 0.5),
        "press_cubic": Press((c, R0), -2.0, 0.4, axis=(1, 1, 0), profile="cubic"),
        "approach": Approach((c + [0, 0, 40], R_tilted), (c, R0), 1.2),
        "circle": circ,
        "circle_cw_tilted": make_circle(turns=0.8, clockwise=True, normal=(0.1, 0.2, 1.0)),
        "movel_paper": mv,
        "movel_stops": MoveL([[0, 0, 0], [10, 0, 0], [10, 10, 5]], V, A, 0.0),
        "pitch_circle": PitchPerturbation(make_circle(turns=3), np.deg2rad(1.0)),
        "pitch_circle_pivot": PitchPerturbation(
            make_circle(turns=3), np.deg2rad(5.0), pivot=(0.0, 0.0, -30.0)
        ),
        "pitch_movel": PitchPerturbation(mv, np.deg2rad(2.0)),
        "pitch_fn_numeric_rate": PitchPerturbation(
            make_circle(turns=3), np.deg2rad(3.0), angle_fn=make_circle(turns=3).angle
        ),
        "sequence": seq,
        "pitch_sequence": PitchPerturbation(seq, np.deg2rad(1.0), pivot=(1.0, 2.0, -20.0)),
    }


# ------------------------------------------------------------------------------------------
# eq 10 step
# ------------------------------------------------------------------------------------------
def test_smoothstep_values_and_vectorised():
    assert smoothstep(-1.0, 0.0, 2.0, 1.0, 5.0) == 2.0
    assert smoothstep(2.0, 0.0, 2.0, 1.0, 5.0) == 5.0
    assert smoothstep(0.5, 0.0, 2.0, 1.0, 5.0) == pytest.approx(3.5)
    x = np.linspace(-1, 2, 31)
    y = smoothstep(x, 0.0, 0.0, 1.0, 1.0)
    assert y.shape == x.shape
    u = np.clip(x, 0, 1)
    np.testing.assert_allclose(y, 3 * u**2 - 2 * u**3)
    assert np.all(np.diff(y) >= 0)


def test_smoothstep_dot_matches_finite_difference():
    x = np.linspace(-0.5, 2.5, 301)
    e = 1e-6
    num = (smoothstep(x + e, 0.2, -1.0, 2.0, 3.0) - smoothstep(x - e, 0.2, -1.0, 2.0, 3.0)) / (
        2 * e
    )
    # at x0, x1 the second derivative jumps: central differences are off by O(e) there
    np.testing.assert_allclose(smoothstep_dot(x, 0.2, -1.0, 2.0, 3.0), num, atol=1e-5)
    assert smoothstep_dot(0.2, 0.2, -1.0, 2.0, 3.0) == 0.0
    assert smoothstep_dot(2.0, 0.2, -1.0, 2.0, 3.0) == 0.0


def test_smoothstep_reversed_interval_and_error():
    # x1 < x0: mirrored step, h1 at the low side
    assert smoothstep(-1.0, 1.0, 0.0, 0.0, 1.0) == 1.0
    assert smoothstep(2.0, 1.0, 0.0, 0.0, 1.0) == 0.0
    with pytest.raises(ValueError, match="x1"):
        smoothstep(0.3, 1.0, 0.0, 1.0, 1.0)


# ------------------------------------------------------------------------------------------
# Hold, Press, Approach
# ------------------------------------------------------------------------------------------
def test_hold_is_constant():
    p = np.array([1.0, 2.0, 3.0])
    h = Hold((p, R0), 2.0)
    P, R, Vv, W = h.sample(np.linspace(-1, 3, 9))
    np.testing.assert_array_equal(P, np.tile(p, (9, 1)))
    np.testing.assert_array_equal(R, np.tile(R0, (9, 1, 1)))
    assert not Vv.any() and not W.any()
    assert h.duration == 2.0


def test_press_depth_direction_and_zero_end_velocity():
    p_touch = np.array([0.0, 0.0, L_BRISTLE])
    pr = Press((p_touch, R0), depth=3.0, duration=0.5)
    p_end, R_end = pr.end_pose
    # default axis = TCP z = R0[:, 2] = -z: pressing 3 mm into the plate
    np.testing.assert_allclose(p_end, [0.0, 0.0, L_BRISTLE - 3.0], atol=1e-12)
    np.testing.assert_array_equal(R_end, R0)
    for t in (0.0, 0.5):
        v, w = pr.twist(t)
        assert np.linalg.norm(v) < 1e-12 and not w.any()
    # quintic peak speed 1.875 depth / T at mid-time
    v_mid, _ = pr.twist(0.25)
    assert np.linalg.norm(v_mid) == pytest.approx(1.875 * 3.0 / 0.5)
    np.testing.assert_allclose(v_mid / np.linalg.norm(v_mid), [0, 0, -1])
    # depth is monotonic
    z = pr.sample(np.linspace(0, 0.5, 101))[0][:, 2]
    assert np.all(np.diff(z) <= 1e-15)


def test_press_cubic_profile_and_axis():
    pr = Press(([0, 0, 0], R0), depth=2.0, duration=1.0, axis=(0, 3, 4), profile="cubic")
    np.testing.assert_allclose(pr.end_pose[0], [0, 1.2, 1.6])
    assert np.linalg.norm(pr.twist(0.5)[0]) == pytest.approx(1.5 * 2.0)
    assert np.linalg.norm(pr.twist(1.0)[0]) == 0.0


def test_approach_reaches_end_pose_with_zero_end_twist():
    R1 = R0 @ rot_y(0.4)
    ap = Approach(([0, 0, 50], R1), ([10, 5, L_BRISTLE], R0), 2.0)
    p, R = ap.end_pose
    np.testing.assert_allclose(p, [10, 5, L_BRISTLE], atol=1e-12)
    np.testing.assert_allclose(R, R0, atol=1e-12)
    np.testing.assert_allclose(ap.start_pose[1], R1, atol=1e-12)
    for t in (0.0, 2.0):
        v, w = ap.twist(t)
        assert np.linalg.norm(v) < 1e-12 and np.linalg.norm(w) < 1e-12


# ------------------------------------------------------------------------------------------
# Circle
# ------------------------------------------------------------------------------------------
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


# ------------------------------------------------------------------------------------------
# MoveL
# ------------------------------------------------------------------------------------------
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


# ------------------------------------------------------------------------------------------
# eq 12 pitch perturbation
# ------------------------------------------------------------------------------------------
def test_pitch_profile_peak_and_support():
    assert pitch_profile(2 * math.pi + math.pi / 4) == pytest.approx(1.0)
    th = np.linspace(0, 10 * math.pi, 100001)
    s = pitch_profile(th)
    assert s.max() == pytest.approx(1.0, abs=1e-8)
    assert th[np.argmax(s)] == pytest.approx(2 * math.pi + math.pi / 4, abs=1e-3)
    outside = (th <= 2 * math.pi) | (th >= 2.5 * math.pi)
    assert not s[outside].any()
    assert np.all(s[~outside] > 0)
    assert pitch_profile(2 * math.pi + math.pi / 8) == pytest.approx(0.5)
    e = 1e-7
    x = np.linspace(6.0, 8.2, 301)
    np.testing.assert_allclose(
        pitch_profile_dot(x), (pitch_profile(x + e) - pitch_profile(x - e)) / (2 * e), atol=1e-6
    )


def test_pitch_perturbation_on_circle():
    circ = make_circle()
    alpha = np.deg2rad(1.0)
    pp = PitchPerturbation(circ, alpha)
    t_peak = circ.time_at_angle(2 * math.pi + math.pi / 4)
    assert pp.pitch(t_peak) == pytest.approx(alpha)
    p, R = pp.pose(t_peak)
    pb, Rb = circ.pose(t_peak)
    np.testing.assert_allclose(p, pb)  # pivot at the TCP: position unchanged
    np.testing.assert_allclose(Rb.T @ R, rot_y(alpha), atol=1e-14)  # about the TCP y axis
    # zero outside [2pi, 5pi/2]
    for th in (0.5, 2 * math.pi - 1e-3, 2.5 * math.pi + 1e-3, 7 * math.pi):
        t = circ.time_at_angle(th)
        np.testing.assert_allclose(pp.pose(t)[1], circ.pose(t)[1], atol=1e-15)
        np.testing.assert_allclose(pp.twist(t)[1], 0.0, atol=1e-15)
    # extra angular velocity alpha * ds/dtheta * dtheta/dt about the TCP y axis (world -y)
    t = circ.time_at_angle(2 * math.pi + math.pi / 16)
    w = pp.twist(t)[1]
    expect = alpha * pitch_profile_dot(circ.angle(t)) * circ.angle_rate(t) * (Rb @ [0, 1, 0])
    np.testing.assert_allclose(w, expect, rtol=1e-12)
    assert w[1] < 0  # R0 maps TCP y to world -y
    # pivot above the TCP moves the TCP
    pv = PitchPerturbation(circ, alpha, pivot=(0.0, 0.0, -30.0))
    shift = pv.pose(t_peak)[0] - pb
    assert np.linalg.norm(shift) == pytest.approx(2 * 30 * math.sin(alpha / 2), rel=1e-9)


def test_pitch_perturbation_needs_angle():
    with pytest.raises(ValueError, match="angle_fn"):
        PitchPerturbation(Hold(([0, 0, 0], R0), 1.0))
    with pytest.raises(ValueError, match="pivot"):
        PitchPerturbation(make_circle(), pivot="wrist")


# ------------------------------------------------------------------------------------------
# Sequence
# ------------------------------------------------------------------------------------------
def test_sequence_concatenation_and_angle():
    seq, circ = press_circle_sequence()
    t0 = seq.start_times[2]
    assert seq.duration == pytest.approx(0.2 + 0.5 + circ.duration + 0.3)
    for tl in (0.0, 1.0, circ.duration / 3, circ.duration):
        p, R = seq.pose(t0 + tl)
        np.testing.assert_allclose(p, circ.pose(tl)[0], atol=1e-12)
        np.testing.assert_array_equal(R, R0)
    assert seq.angle(0.1) == 0.0
    assert seq.angle(t0 + 2.0) == pytest.approx(circ.angle(2.0))
    assert seq.angle(seq.duration) == pytest.approx(8 * math.pi)
    assert seq.angle_rate(t0 + 2.0) == pytest.approx(circ.angle_rate(2.0))
    # pitch over the whole sequence peaks at the right time
    pp = PitchPerturbation(seq)
    tp = t0 + circ.time_at_angle(2 * math.pi + math.pi / 4)
    assert pp.pitch(tp) == pytest.approx(np.deg2rad(1.0))
    # press ends at the circle's start, bristles 3 mm into the plate
    assert seq.pose(t0)[0][2] == pytest.approx(L_BRISTLE - 3.0)


def test_sequence_discontinuity_names_segment():
    circ = make_circle()
    press = Press(([0, 0, L_BRISTLE], R0), 3.0, 0.5)
    with pytest.raises(ValueError, match=r"segment 1 \(Circle\)"):
        Sequence([press, circ])
    with pytest.raises(ValueError, match="segment 2"):
        Sequence([Hold(circ.start_pose, 1.0), circ, Hold(([0.0, 0.0, 0.0], R0), 1.0)])
    tilted = Hold((circ.end_pose[0], R0 @ rot_y(1e-6)), 1.0)
    with pytest.raises(ValueError, match="rotation gap"):
        Sequence([circ, tilted])


# ------------------------------------------------------------------------------------------
# twist = d pose / dt for every trajectory type
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", list(all_trajectories().keys()))
def test_twist_is_time_derivative_of_pose(name):
    traj = all_trajectories()[name]
    assert isinstance(traj, Trajectory)
    rng = np.random.default_rng(0)
    T = traj.duration
    times = np.concatenate([rng.uniform(1e-4, T - 1e-4, 150), np.linspace(1e-4, T - 1e-4, 50)])
    for t in times:
        v_num, w_num = numeric_twist(traj, t)
        v, w = traj.twist(t)
        np.testing.assert_allclose(v, v_num, atol=1e-4, err_msg=f"{name} v at t={t}")
        np.testing.assert_allclose(w, w_num, atol=1e-8, err_msg=f"{name} w at t={t}")


@pytest.mark.parametrize(
    "name",
    [
        "pitch_circle",
        "pitch_circle_pivot",
        "pitch_movel",
        "pitch_sequence",
        "pitch_fn_numeric_rate",
    ],
)
def test_twist_derivative_inside_pitch_window(name):
    traj = all_trajectories()[name]
    th = np.linspace(2 * math.pi + 1e-3, 2.5 * math.pi - 1e-3, 41)
    # times inside the window by bisection on the angle (works for every angle source)
    tt = np.linspace(0, traj.duration, 200001)
    ang = traj.angle(tt)
    times = np.interp(th, ang, tt)
    saw_rotation = False
    for t in times:
        v_num, w_num = numeric_twist(traj, t)
        v, w = traj.twist(t)
        np.testing.assert_allclose(v, v_num, atol=1e-4)
        np.testing.assert_allclose(w, w_num, atol=1e-8)
        saw_rotation |= np.linalg.norm(w) > 1e-3
    assert saw_rotation


def test_sample_matches_pose_and_twist():
    for name, traj in all_trajectories().items():
        t = np.linspace(-0.5, traj.duration + 0.5, 23)
        P, R, Vv, W = traj.sample(t)
        assert P.shape == (23, 3) and R.shape == (23, 3, 3) and Vv.shape == W.shape == (23, 3)
        for i in (0, 5, 11, 22):
            p, Ri = traj.pose(t[i])
            v, w = traj.twist(t[i])
            np.testing.assert_allclose(P[i], p, err_msg=name)
            np.testing.assert_allclose(R[i], Ri, err_msg=name)
            np.testing.assert_allclose(Vv[i], v, err_msg=name)
            np.testing.assert_allclose(W[i], w, err_msg=name)
        # outside [0, T]: end poses held, zero twist
        assert not Vv[0].any() and not W[-1].any()
        np.testing.assert_allclose(P[0], traj.start_pose[0])
        np.testing.assert_allclose(P[-1], traj.end_pose[0])
        # rotations stay orthonormal
        np.testing.assert_allclose(
            R @ np.swapaxes(R, 1, 2), np.tile(np.eye(3), (23, 1, 1)), atol=1e-12
        )


# ------------------------------------------------------------------------------------------
# validation
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: make_circle(radius=0.0), r"radius = 0\.0 .*> 0"),
        (lambda: make_circle(speed=-1.0), r"speed.*> 0"),
        (lambda: make_circle(accel=0), r"accel.*> 0"),
        (lambda: make_circle(turns=0), r"turns.*> 0"),
        (lambda: make_circle(normal=(0, 0, 0)), r"normal"),
        (lambda: make_circle(R=np.ones((3, 3))), r"R must be a rotation"),
        (lambda: make_circle(center=[1, 2]), r"center"),
        (lambda: Hold(([0, 0, 0], R0), 0.0), r"duration.*> 0"),
        (lambda: Press(([0, 0, 0], R0), float("nan"), 1.0), r"depth"),
        (lambda: Press(([0, 0, 0], R0), 1.0, -1.0), r"duration.*> 0"),
        (lambda: Press(([0, 0, 0], R0), 1.0, 1.0, profile="linear"), r"profile"),
        (lambda: Approach(([0, 0, 0], R0), ([1, 0, 0], R0), 0.0), r"duration.*> 0"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, A, -1.0), r"blend_radius = -1\.0 .*>= 0"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], 0.0, A), r"speed.*> 0"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, float("inf")), r"accel.*> 0"),
        (lambda: MoveL([[0, 0, 0], [0, 0, 0]], V, A), r"non-zero length"),
        (lambda: MoveL([[0, 0], [1, 0]], V, A), r"waypoints"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, A).angle(0.0), r"center"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, A).path_points(1), r"n must be"),
        (lambda: PitchPerturbation(make_circle(), alpha_rad=3.0), r"alpha_rad"),
        (lambda: Sequence([]), r"segments"),
        (lambda: paper_circle_waypoints([0, 0, 0], -2.0), r"radius.*> 0"),
        (lambda: paper_circle_waypoints([0, 0, 0], 2.0, placement="x"), r"placement"),
        (lambda: movel_circle_deviation([0, 0, 0], 20.0, -1.0), r"blend_radius"),
        (lambda: paper_circle_movel([0, 0, 0], 20.0, V, A, turns=0), r"turns.*>= 1"),
        (lambda: make_circle().sample([[0.0, 1.0]]), r"times"),
    ],
)
def test_validation_errors(build, match):
    with pytest.raises(ValueError, match=match):
        build()
