"""Tests of the eq 12 pitch perturbation (motion.pitch)."""

import math

import numpy as np
import pytest

from brush_env.motion import R0, Hold, PitchPerturbation, pitch_profile, pitch_profile_dot

from .conftest import all_trajectories, make_circle, numeric_twist, rot_y


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
