"""FlatPlate-v0 at a fidelity level (configs/fidelity): the level sets the engine's settings,
``engine_settings`` of the same gym.make call still win, an unknown level is refused with the
known ones."""

from __future__ import annotations

import pytest

from brush_env.engine import ConfigError, load_fidelity


def test_env_takes_a_level_and_keywords_still_win():
    import gymnasium as gym

    env = gym.make("brush_env/FlatPlate-v0", brush="tiny_env", fidelity="balanced")
    u = env.unwrapped
    bal = load_fidelity("balanced")
    assert u.sim.settings.bodies_per_bristle == bal.bodies_per_bristle
    assert u.sim.settings.tip_tip_sweeps == bal.tip_tip_sweeps
    assert {b.bodies for b in u.sim.brush.bristles} == {bal.bodies_per_bristle}
    env.close()
    env = gym.make(
        "brush_env/FlatPlate-v0",
        brush="tiny_env",
        fidelity="balanced",
        engine_settings={"bodies_per_bristle": 4},
    )
    assert {b.bodies for b in env.unwrapped.sim.brush.bristles} == {4}
    assert env.unwrapped.sim.settings.tip_tip_sweeps == bal.tip_tip_sweeps
    env.close()
    with pytest.raises(ConfigError, match="fidelity = 'quick'"):
        gym.make("brush_env/FlatPlate-v0", fidelity="quick")
