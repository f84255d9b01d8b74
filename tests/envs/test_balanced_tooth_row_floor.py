"""A reproducer from the ToothRow-v0 campaign of 2026-12-05 (session 24, docs/rl.md): a trained
PPO policy (``ppo_limit`` seed 0, the plate campaign's settings: ``workspace_edge = "stop"``, the
press floor 3.5 mm below touching, the evaluations' 3.5 N force guard) brushes the crowns on the
floor at 0.4-1.4 N; at ``balanced`` (the accurate full model) bristle 36's Newton fails on the
smallest halving of the solver step at t = 5.3 s (env step 133 of episode 1001).  The episode
ends with the divergence in ``info`` (nothing is returned as NaN), but the accurate model should
not fail there.  The policy's 133 actions are kept
(``tests/data/tooth_row_balanced_actions_1001.npy``): the env is deterministic, so the replay
is the same episode after the policy is gone.

What failed (session 25, docs/model.md "Newton's iteration cap at the smallest halving"): not the
coupled tip-tip solve (one plain sweep from the state before the failing step fails too), but
``balanced``'s cap of 30 Newton iterations per attempt on every halving, the smallest included:
bristle 36's tip sticks on one crown while its fifth body's capsule slides on another surface and
flips between stick and slip from one iteration to the next, so the line search cuts each step
to ~0.1 and Newton needs 17-30 iterations even at h / 256.  The smallest halving is now allowed
100 (``advance.LAST_LEVEL_MAXIT``)."""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import brush_env  # noqa: F401  (registers the ids)

from .replay import replay_on_the_floor

ACTIONS = Path(__file__).parents[1] / "data" / "tooth_row_balanced_actions_1001.npy"


@pytest.mark.slow  # 133 control steps of the default brush on the tooth row at `balanced`
def test_balanced_brushes_the_tooth_row_on_the_press_floor_without_diverging():
    env = gym.make(
        "brush_env/ToothRow-v0",
        fidelity="balanced",
        action_mode="3d",
        workspace_edge="stop",
        workspace_height=(-3.5, 15.0),
        force_guard=3.5,
    )
    replay_on_the_floor(env, 1001, np.load(ACTIONS))
