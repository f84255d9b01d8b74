"""Tests of Hold, Press, Approach and Sequence (motion.primitives)."""

import math

import numpy as np
import pytest

from brush_env.motion import R0, Approach, Hold, PitchPerturbation, Press, Sequence

from .conftest import L_BRISTLE, make_circle, press_circle_sequence, rot_y


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


@pytest.mark.parametrize("angle", [3.0, math.pi - 1e-4, math.pi - 1e-7])
def test_approach_near_half_turn_follows_the_geodesic(angle):
    # relative rotation close to pi (logmap's axis branch): the path is the rotation about TCP y
    # by sigma * angle, with the exact angle; the end pose is reached
    R1 = R0 @ rot_y(angle)
    ap = Approach(([0, 0, 0], R0), ([0, 0, 0], R1), 1.0)
    np.testing.assert_allclose(ap.end_pose[1], R1, atol=1e-14)
    for t in (0.25, 0.5, 0.9):
        sigma = t**3 * (10.0 - 15.0 * t + 6.0 * t * t)  # quintic, written out
        np.testing.assert_allclose(ap.pose(t)[1], R0 @ rot_y(sigma * angle), atol=1e-14)
