"""The fixed circular-trajectory reference policy: the paper's 3 mm press, then the 20 mm circle.

An SB3-style policy (``predict(obs, state=None, episode_start=None, deterministic=True) ->
(actions, state)``) so ``stable_baselines3.common.evaluation.evaluate_policy`` and
``agents/evaluate.py`` take it like a trained model::

    env = gym.make("brush_env/FlatPlate-v0")
    policy = ReferencePolicy.for_env(env)           # a gym.Env or an SB3 VecEnv
    mean, std = evaluate_policy(policy, env, n_eval_episodes=3)

How it knows time and pose: **from the observation alone**.  The elapsed step k is recovered from
``time_remaining`` (k = round((1 - r) H) with the env's horizon H), the TCP pose from
``tcp_position`` and ``tcp_orientation`` (see ``ObservationLayout.tcp_pose``).  ``for_env`` reads
only static facts from the env once: the observation layout (scales), the action limits, the
control step ``dt`` and the horizon.  So it needs *raw* observations — evaluate it on an env
without ``VecNormalize`` — and it plans each episode at k = 0 from the first observation, one plan
per vector-env index.  The motion and the control law are in ``brush_env/envs/reference.py``
(``CircleReference``): quintic approach to 1 mm above P0 = (-20, 0) mm, quintic press of the
bristles 3 mm past the nominal plate, counter-clockwise circle of radius 20 mm about the nominal
patch centre at 30 mm/s (100 mm/s^2); feed-forward velocity plus a proportional correction
(5 1/s) of the pose error.  The press runs during the circle's first second (``press="sliding"``,
the default), which keeps the total force within the env's 4 N limit; ``press="static"`` is the
paper's order (press at rest, then circle), which holds the brush above it (docs/rl.md).
"""

from __future__ import annotations

import numpy as np

from brush_env.envs.action import make_action_type
from brush_env.envs.reference import CircleReference, ScrubReference

#: the env's ``reference_motion`` -> its reference controller (FlatPlate-v0: the paper's circle)
CONTROLLERS = {"circle": CircleReference, "scrub": ScrubReference}

__all__ = ["ReferencePolicy", "RandomPolicy"]


def _env_facts(env):
    """(layout, config, dt, horizon) of a gym.Env (any wrappers) or an SB3 VecEnv.

    The horizon is the time limit of the env as made (``spec.max_episode_steps`` of the outer
    wrapper, which ``gym.make(..., max_episode_steps=N)`` sets), else the config's: the same
    number ``BrushEnv.horizon`` finds at reset."""
    if hasattr(env, "get_attr") and hasattr(env, "num_envs"):  # SB3 VecEnv
        layout, config, dt, spec, motion = (
            env.get_attr(k, [0])[0] for k in ("layout", "config", "dt", "spec", "reference_motion")
        )
    else:
        u = env.unwrapped
        layout, config, dt, spec = u.layout, u.config, u.dt, env.spec
        motion = getattr(u, "reference_motion", "circle")
    steps = spec.max_episode_steps if spec is not None else None
    return layout, config, dt, int(steps or config.max_episode_steps), motion


class ReferencePolicy:
    """The env's reference tracking policy (see the module docstring): ``motion="circle"``
    (FlatPlate-v0) plans :class:`~brush_env.envs.reference.CircleReference` (``**kwargs``: radius,
    speed, accel, press_depth, hover, approach_time, press_time, center, start_angle, clockwise,
    kp, kr, press = "sliding" | "static"); ``"scrub"`` (ToothRow-v0)
    :class:`~brush_env.envs.reference.ScrubReference` (x_range, y_levels, speed, press_depth,
    hover, approach_time, press_time, kp, kr, press; "static" by default there).
    ``for_env`` takes the env's ``reference_motion``."""

    def __init__(self, layout, config, dt: float, horizon: int, motion: str = "circle", **kwargs):
        if motion not in CONTROLLERS:
            raise ValueError(f"motion = {motion!r}: must be one of {sorted(CONTROLLERS)}")
        self.layout = layout
        self.action_type = make_action_type(config)
        self.dt, self.horizon = float(dt), int(horizon)
        self.kwargs = kwargs
        self._make = CONTROLLERS[motion]
        self._controllers: list[CircleReference] = []
        self._make(layout, self.action_type, dt, horizon, **kwargs)  # validate now

    @classmethod
    def for_env(cls, env, **kwargs) -> ReferencePolicy:
        return cls(*_env_facts(env), **kwargs)

    def _controller(self, i: int) -> CircleReference:
        while len(self._controllers) <= i:
            self._controllers.append(
                self._make(self.layout, self.action_type, self.dt, self.horizon, **self.kwargs)
            )
        return self._controllers[i]

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        """Actions for one observation or a batch (VecEnv); ``state`` is passed through."""
        tr = self.layout.block(observation, "time_remaining")
        batched = tr.ndim == 2
        if not batched:
            observation = (
                observation
                if not isinstance(observation, dict)
                else {k: np.asarray(v)[None] for k, v in observation.items()}
            )
            if not isinstance(observation, dict):
                observation = np.asarray(observation)[None]
        k = self.layout.elapsed_steps(observation, self.horizon)
        p, R = self.layout.tcp_pose(observation)
        actions = np.stack([self._controller(i).act(int(k[i]), p[i], R[i]) for i in range(len(k))])
        return (actions if batched else actions[0]), state

    def controller(self, i: int = 0) -> CircleReference:
        """The planner/tracker of vector-env index ``i`` (its ``trajectory`` and ``circle``)."""
        return self._controller(i)


class RandomPolicy:
    """Uniform random actions in the action space (seeded), SB3-style ``predict``."""

    def __init__(self, action_space, seed: int | None = 0):
        self.action_space = action_space
        self.action_space.seed(seed)

    def seed_episode(self, seed: int) -> None:
        """Reseed for the episode the env resets with ``seed`` (agents/evaluate.run_episode):
        an episode's actions then depend on its own seed alone, not on the episodes before it,
        so an evaluation split into parts (the campaign's ``chunk``) runs the same episodes.
        The stream is derived from the seed, not the seed itself, which the env's own
        generator already uses."""
        self.action_space.seed(int(np.random.SeedSequence([seed, 0x5EED]).generate_state(1)[0]))

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if isinstance(observation, dict):
            n = np.asarray(next(iter(observation.values()))).shape[0]
            batched = np.asarray(observation["time_remaining"]).ndim == 2
        else:
            obs = np.asarray(observation)
            batched, n = obs.ndim == 2, obs.shape[0]
        if not batched:
            return self.action_space.sample(), state
        return np.stack([self.action_space.sample() for _ in range(n)]), state
