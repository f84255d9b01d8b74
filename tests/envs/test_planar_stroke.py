"""PlanarStroke-v0: coverage along the profile, clear errors for a bad pymunk setting,
determinism, rendering (both checkers run in test_api.py over every registered id)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from brush_env.engine import ConfigError

ID = "brush_env/PlanarStroke-v0"


def test_a_stroke_cleans_cells_along_the_profile_and_the_reward_counts_them():
    env = gym.make(ID, brush="tiny_env", max_episode_steps=60)
    env.reset(seed=0)
    infos = []
    for k in range(60):
        a = np.array([0.4, -0.25 if k < 12 else 0.0, 0.0], np.float32)  # press ~2.4 mm, drag
        _, r, term, trunc, info = env.step(a)
        infos.append(info)
        if term or trunc:
            break
    u = env.unwrapped
    assert infos[-1]["coverage"] > 0.02
    total = sum(i["reward_terms"]["coverage"] for i in infos)
    assert total == pytest.approx(u.w["coverage"] * infos[-1]["coverage"])
    env.close()


def test_bad_pymunk_settings_give_a_clear_error():
    with pytest.raises(ConfigError, match=r"planar.dt = 0.01 s is too large"):
        gym.make(ID, pymunk_dt=0.01)
    with pytest.raises(ConfigError, match=r"profile = 'wavy': must be one of"):
        gym.make(ID, profile="wavy")


def test_same_seed_and_actions_give_identical_episodes():
    runs = []
    for _ in range(2):
        env = gym.make(ID, brush="tiny_env")
        env.action_space.seed(3)
        obs, _ = env.reset(seed=4)
        seq = [obs]
        for _ in range(10):
            obs, r, *_ = env.step(env.action_space.sample())
            seq += [obs, np.array([r])]
        runs.append(np.concatenate([np.ravel(x) for x in seq]))
        env.close()
    np.testing.assert_array_equal(runs[0], runs[1])


def test_render_rgb_array():
    env = gym.make(ID, brush="tiny_env", render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.ndim == 3 and img.shape[2] == 3 and img.dtype == np.uint8
    env.close()
