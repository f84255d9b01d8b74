"""The episode horizon handed to the env explicitly, not guessed.

``BrushEnv.horizon`` (the number of control steps that the ``time_remaining`` observation counts
down) is the env setting ``max_episode_steps`` by default.  ``gym.make(id, max_episode_steps=N)``
consumes N for gymnasium's ``TimeLimit`` wrapper and never passes it to the env, so registration
adds :class:`HorizonFromTimeLimit` as an *additional wrapper*: gymnasium applies it right after
``TimeLimit``, and it hands the limit it finds in the wrapper chain to ``BrushEnv.set_horizon``.
"""

from __future__ import annotations

import gymnasium as gym
from gymnasium.wrappers import TimeLimit


class HorizonFromTimeLimit(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Tells the env the ``max_episode_steps`` of the ``TimeLimit`` it is wrapped in (if any)."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        inner = env
        while isinstance(inner, gym.Wrapper):
            if isinstance(inner, TimeLimit):
                env.unwrapped.set_horizon(int(inner._max_episode_steps))
                break
            inner = inner.env
