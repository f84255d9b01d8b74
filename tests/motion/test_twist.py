"""Tests of twist = d pose / dt and sample = pose/twist, for every trajectory type."""

import numpy as np
import pytest

from brush_env.motion import Trajectory

from .conftest import all_trajectories, numeric_twist


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
