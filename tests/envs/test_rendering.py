"""rgb_array frames and the human window (drawn off-screen with matplotlib's Agg backend)."""

import numpy as np

from .conftest import NO_CONTACT


def test_rgb_array_frame_shape_and_motion(make_env):
    env = make_env(render_mode="rgb_array", render_height=128)
    env.reset(seed=0, options=NO_CONTACT)
    f0 = env.render()
    assert f0.shape == (128, 256, 3) and f0.dtype == np.uint8
    for _ in range(5):
        env.step(np.array([1, 0, 0, 0, 0, 0], np.float32))
    f1 = env.render()
    assert f1.shape == f0.shape and not np.array_equal(f0[:, :128], f1[:, :128])
    assert f1 is not env.render()  # a fresh array each call


def test_human_mode_renders_on_step_and_returns_none(make_env):
    env = make_env(render_mode="human")
    env.reset(seed=0)
    env.step(np.zeros(6, np.float32))
    assert env.render() is None
    assert env.unwrapped._renderer._fig is not None
    env.close()
    assert env.unwrapped._renderer._fig is None
