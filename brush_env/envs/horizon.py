"""The registered ids' outermost wrapper: it hands the ``TimeLimit``'s horizon to the env.

``time_remaining`` (an observation block) counts down the time limit, so the env must know it.
``gym.make(id, max_episode_steps=N)`` consumes ``N`` for its ``TimeLimit`` wrapper and never
passes it to the env; the registration (``brush_env.ENV_IDS``) therefore adds this wrapper
outside the ``TimeLimit``, and it passes ``N`` (the wrapped env's ``spec.max_episode_steps``)
explicitly to :meth:`BrushEnv.set_horizon` once, when the env is made.  Without a ``TimeLimit``
(``max_episode_steps=-1``, or ``BrushEnv(...)`` built directly) the horizon stays the config's
``max_episode_steps``.  The wrapper changes nothing else: reset, step and render pass through.
"""

from __future__ import annotations

import gymnasium as gym

__all__ = ["TimeLimitHorizon"]


class TimeLimitHorizon(gym.Wrapper, gym.utils.RecordConstructorArgs):
    """Sets ``env.unwrapped``'s horizon to the time limit of the wrapped stack, if it has one."""

    def __init__(self, env: gym.Env):
        gym.utils.RecordConstructorArgs.__init__(self)
        gym.Wrapper.__init__(self, env)
        steps = env.spec.max_episode_steps if env.spec is not None else None
        if steps is not None:
            env.unwrapped.set_horizon(int(steps))
