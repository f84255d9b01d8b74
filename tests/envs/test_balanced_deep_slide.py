"""A reproducer from the RL campaign of 2026-12-04 (session 21, docs/rl.md): a trained PPO policy
(``ppo_limit`` seed 0, ``workspace_edge = "stop"``) presses the TCP to the workspace floor, 5 mm
below touching (half the bristle length), and slides the brush at up to 50 mm/s there; at
``balanced`` (the accurate full model) bristle 18's Newton fails on the smallest halving of the
solver step at t = 1.196 s, in 6 of the campaign's 60 `balanced` episodes in this regime.  The
policy's 30 actions of episode 1018 are kept (``tests/data/balanced_deep_slide_actions_1018.npy``):
replayed, the episode is the same bit for bit (the env is deterministic), so the failure stays
reproducible after the policy is gone.  The same actions run to the end with the solver step at
0.25 ms, at 1 ms without tip-tip contact, or with one plain sweep: the coupled tip-tip solve at
1 ms failed, and now falls back to the plain sweep when a bristle fails or the re-solves run
over their budget (docs/model.md, "Coupled tip-tip solve", item 4)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import brush_env  # noqa: F401  (registers the ids)

from .replay import replay_on_the_floor

ACTIONS = Path(__file__).parents[1] / "data" / "balanced_deep_slide_actions_1018.npy"


@pytest.mark.slow  # 30 control steps of the default brush at `balanced` (~20 s)
def test_balanced_slides_on_the_workspace_floor_without_diverging():
    env = gym.make(
        "brush_env/FlatPlate-v0", fidelity="balanced", action_mode="3d", workspace_edge="stop"
    )
    replay_on_the_floor(env, 1018, np.load(ACTIONS))
