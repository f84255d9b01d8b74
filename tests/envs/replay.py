"""Replaying a trained policy's recorded actions (the reproducers of the RL campaigns)."""

from __future__ import annotations

import numpy as np
import pytest


def replay_on_the_floor(env, seed: int, actions: np.ndarray) -> None:
    """Reset ``env`` with ``seed`` and take ``actions``: every step must run (else the
    divergence's message), and the replay must be the regime its test names -- the TCP on the
    workspace floor at some step, tips touching at the end.  Closes ``env``."""
    try:
        env.reset(seed=seed)
        u, deepest = env.unwrapped, 0.0
        for a in actions:
            *_, info = env.step(a)
            deepest = min(deepest, info["tcp_position"][2] - u.touch_height)
            assert info["termination"] is None, info["divergence"]
        assert deepest == pytest.approx(u.config.workspace_height[0])
        assert info["tips_in_contact"] > 0
    finally:
        env.close()
