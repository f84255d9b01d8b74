"""Many brushes per call (issue 29 item 3): N FlatPlate-v0 / ToothRow-v0 envs as one Gymnasium 1.x
``VectorEnv``, and an SB3 ``VecEnv`` adapter of it.

    envs = gym.make_vec(
        "brush_env/FlatPlate-v0", num_envs=16, vectorization_mode="vector_entry_point"
    )
    obs, infos = envs.reset(seed=0)  # obs: (16, 407) float32; env i is seeded with 0 + i
    obs, rewards, terminated, truncated, infos = envs.step(envs.action_space.sample())

**What it is today: a loop.**  The N brushes are N independent single-env cores
(:class:`~brush_env.envs.flat_plate.BrushEnv` or ``ToothRowEnv``, each with its own
``Simulator``), stepped one after another in a Python loop in one method,
:meth:`BrushCores.step`; with ``fidelity="reduced"`` each core's env step is one compiled
``Simulator.rollout`` call, so a batch of N is N compiled calls plus N times the Python of one env
step.  Its env steps/s is therefore the single env's (docs/env.md, "Vectorised envs"); what it
buys is the interface.  Replacing :meth:`BrushCores.step` (and :meth:`BrushCores.reset`) by one
batched kernel call over all N brushes changes nothing above them.

**The same numbers as the single env.**  Each core is exactly what ``gym.make`` builds under its
wrappers: its horizon (``time_remaining``) is the time limit, and ``truncated`` is set when a
core's episode reaches ``max_episode_steps`` control steps, as gymnasium's ``TimeLimit`` does.
Observations, rewards, ``terminated``, ``truncated`` and infos equal those of
``gym.make_vec(id, N, vectorization_mode="sync")`` bit for bit for the same seeds and actions
(tested): ``reset(seed=s)`` seeds env i with ``s + i`` (a list seeds each env), an autoreset
continues the env's own random stream (``reset()`` without a seed), and infos are batched by
gymnasium's ``VectorEnv._add_info`` (key -> array over envs, plus the ``_key`` mask).

**Autoreset** (``metadata["autoreset_mode"]``): ``AutoresetMode.NEXT_STEP`` by default
(Gymnasium 1.x's): the step after an env's episode ends resets that env and returns its first
observation with reward 0, ``terminated = truncated = False`` and the reset's info; the action
given for it is ignored.  ``SAME_STEP`` resets within the ending step (the final observation and
info in ``infos["final_obs"]``, ``infos["final_info"]``); ``DISABLED`` never resets by itself
(``reset(options={"reset_mask": mask})`` resets the envs in ``mask``).

Arguments (``gym.make_vec`` passes its keywords on): ``num_envs`` (>= 1), ``max_episode_steps``
(the time limit in control steps, as ``gym.make``'s: ``make_vec`` passes the id's 300 unless
given; ``None``: the config's ``max_episode_steps``; ``-1``: no time limit, the horizon is the
config's), ``autoreset_mode``, ``render_mode`` (``"rgb_array"``: ``render()`` returns one frame
per env) and every env setting (``config``, ``brush``, ``fidelity``, ...; docs/env.md).

:class:`brush_env.envs.sb3.SB3VecEnv` adapts it to stable-baselines3's ``VecEnv`` (auto-reset
within the step, ``info["terminal_observation"]`` and ``info["TimeLimit.truncated"]``), with the
numbers of an SB3 ``DummyVecEnv`` of ``gym.make`` envs (tested); ``agents/train.py`` trains on it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from copy import deepcopy
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space, concatenate, create_empty_array

from .flat_plate import BrushEnv
from .tooth_row import ToothRowEnv

__all__ = [
    "BrushCores",
    "BrushVectorEnv",
    "FlatPlateVectorEnv",
    "ToothRowVectorEnv",
    "check_num_envs",
]

#: one core's step: (observation, reward, terminated, truncated, info)
StepResult = tuple[Any, float, bool, bool, dict]


def check_num_envs(num_envs) -> int:
    """``num_envs`` as an int >= 1, else a ValueError naming it."""
    if isinstance(num_envs, bool) or not isinstance(num_envs, int | np.integer) or num_envs < 1:
        raise ValueError(f"num_envs = {num_envs!r} is out of range: must be an integer >= 1")
    return int(num_envs)


def _time_limit(max_episode_steps, config_steps: int) -> int | None:
    """The time limit [control steps] or None (no limit), as ``gym.make`` reads it."""
    if max_episode_steps is None:
        return int(config_steps)
    if (
        isinstance(max_episode_steps, bool)
        or not isinstance(max_episode_steps, int | np.integer)
        or (max_episode_steps < 1 and max_episode_steps != -1)
    ):
        raise ValueError(
            f"max_episode_steps = {max_episode_steps!r} is out of range: must be an integer >= 1 "
            "(control steps), -1 (no time limit) or None (the config's)"
        )
    return None if max_episode_steps == -1 else int(max_episode_steps)


class BrushCores:
    """N independent single-env cores with their time limit: the layer that steps the brushes.

    ``reset(i, seed, options)`` and ``step(actions, which)`` are the only places that touch the
    engine.  Today :meth:`step` loops over the cores in Python (one ``BrushEnv.step`` each);
    it is the method to replace by one batched kernel call over all N brushes.
    """

    def __init__(self, env_class: type[BrushEnv], num_envs: int, max_episode_steps, **env_kwargs):
        self.num_envs = check_num_envs(num_envs)
        self.envs: list[BrushEnv] = [env_class(**env_kwargs) for _ in range(self.num_envs)]
        self.max_episode_steps = _time_limit(
            max_episode_steps, self.envs[0].config.max_episode_steps
        )
        if self.max_episode_steps is not None:
            for env in self.envs:
                env.set_horizon(self.max_episode_steps)  # what gym.make's TimeLimitHorizon does
        self.elapsed = np.zeros(self.num_envs, dtype=np.int64)

    def reset(self, i: int, seed: int | None = None, options: dict | None = None):
        """Reset core ``i``: (observation, info)."""
        self.elapsed[i] = 0
        return self.envs[i].reset(seed=seed, options=options)

    def step(self, actions, which: Sequence[int]) -> list[StepResult]:
        """One control step of the cores ``which`` with ``actions[i]`` each (a Python loop over
        the cores today); ``truncated`` from the time limit, as gymnasium's ``TimeLimit``."""
        results = []
        for i in which:
            obs, reward, terminated, truncated, info = self.envs[i].step(actions[i])
            self.elapsed[i] += 1
            if self.max_episode_steps is not None and self.elapsed[i] >= self.max_episode_steps:
                truncated = True
            results.append((obs, reward, terminated, truncated, info))
        return results

    def close(self) -> None:
        for env in self.envs:
            env.close()


class BrushVectorEnv(VectorEnv):
    """N brushes as one Gymnasium ``VectorEnv`` (module docstring); ``env_class`` is the
    single env (FlatPlate-v0's ``BrushEnv`` here, ``ToothRowEnv`` in the subclass)."""

    env_class: type[BrushEnv] = BrushEnv

    def __init__(
        self,
        num_envs: int = 1,
        *,
        max_episode_steps: int | None = None,
        autoreset_mode: AutoresetMode | str = AutoresetMode.NEXT_STEP,
        render_mode: str | None = None,
        **env_kwargs,
    ):
        try:
            mode = AutoresetMode(autoreset_mode)
        except ValueError:
            raise ValueError(
                f"autoreset_mode = {autoreset_mode!r} is not allowed: must be one of "
                f"{[m.value for m in AutoresetMode]} (or gymnasium.vector.AutoresetMode)"
            ) from None
        self.cores = BrushCores(
            self.env_class, num_envs, max_episode_steps, render_mode=render_mode, **env_kwargs
        )
        first = self.cores.envs[0]
        self.num_envs = self.cores.num_envs
        self.autoreset_mode = mode
        self.render_mode = render_mode
        self.metadata = {**first.metadata, "autoreset_mode": mode}
        self.single_observation_space = first.observation_space
        self.single_action_space = first.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._obs: Any = create_empty_array(self.single_observation_space, n=self.num_envs)
        self._env_obs: list[Any] = [None] * self.num_envs
        self._rewards = np.zeros(self.num_envs, dtype=np.float64)
        self._terminations = np.zeros(self.num_envs, dtype=np.bool_)
        self._truncations = np.zeros(self.num_envs, dtype=np.bool_)
        self._autoreset = np.zeros(self.num_envs, dtype=np.bool_)

    # ------------------------------------------------------------------ properties
    @property
    def envs(self) -> list[BrushEnv]:
        """The N single-env cores (unwrapped ``BrushEnv``s)."""
        return self.cores.envs

    @property
    def max_episode_steps(self) -> int | None:
        """The time limit [control steps], None without one."""
        return self.cores.max_episode_steps

    def single_spec(self):
        """The ``EnvSpec`` one of the N envs would have from ``gym.make`` (its
        ``max_episode_steps`` is the time limit); None if this env was not made from an id."""
        if self.spec is None:
            return None
        kwargs = {
            k: v
            for k, v in self.spec.kwargs.items()
            if k not in ("num_envs", "vectorization_mode", "max_episode_steps")
        }
        return dataclasses.replace(
            self.spec, kwargs=kwargs, max_episode_steps=self.max_episode_steps
        )

    # ------------------------------------------------------------------ reset / step
    def _seeds(self, seed) -> list[int | None]:
        if seed is None:
            return [None] * self.num_envs
        if isinstance(seed, int | np.integer) and not isinstance(seed, bool):
            return [int(seed) + i for i in range(self.num_envs)]
        seeds = list(seed)
        if len(seeds) != self.num_envs:
            raise ValueError(
                f"seed has {len(seeds)} entries: a list of seeds must have num_envs = "
                f"{self.num_envs} entries (or pass one int, or None)"
            )
        return seeds

    def reset(self, *, seed: int | list[int | None] | None = None, options: dict | None = None):
        """Reset every env (or those of ``options["reset_mask"]``); ``seed``: None, an int s
        (env i gets s + i) or a list of num_envs seeds."""
        seeds = self._seeds(seed)
        options = None if options is None else dict(options)
        mask = np.ones(self.num_envs, dtype=np.bool_)
        if options is not None and "reset_mask" in options:
            mask = options.pop("reset_mask")
            if not isinstance(mask, np.ndarray) or mask.dtype != np.bool_:
                raise TypeError("options['reset_mask'] must be a numpy array of dtype bool")
            if mask.shape != (self.num_envs,):
                raise ValueError(
                    f"options['reset_mask'] has shape {mask.shape}: must be ({self.num_envs},)"
                )
            if not mask.any():
                raise ValueError("options['reset_mask'] must have at least one True entry")
        infos: dict = {}
        for i in np.flatnonzero(mask):
            self._env_obs[i], info = self.cores.reset(int(i), seeds[i], options)
            infos = self._add_info(infos, info, int(i))
        self._terminations[mask] = False
        self._truncations[mask] = False
        self._autoreset[mask] = False
        self._obs = concatenate(self.single_observation_space, self._env_obs, self._obs)
        return deepcopy(self._obs), infos

    def _check_actions(self, actions):
        if self._env_obs[0] is None:
            raise RuntimeError("call reset() before step()")
        shape = getattr(self.action_space, "shape", None)
        arr = np.asarray(actions)
        if shape is not None and arr.shape != shape:
            raise ValueError(
                f"actions have shape {arr.shape}: must be {shape} (num_envs = {self.num_envs} "
                f"rows of the single action space's {self.single_action_space.shape})"
            )
        return actions

    def step(self, actions):
        """One control step of every env (autoreset as ``metadata["autoreset_mode"]``)."""
        actions = self._check_actions(actions)
        mode = self.autoreset_mode
        if mode == AutoresetMode.DISABLED and self._autoreset.any():
            done = np.flatnonzero(self._autoreset).tolist()
            raise RuntimeError(
                f"envs {done} have ended their episodes: with autoreset_mode DISABLED reset "
                "them (reset(options={'reset_mask': mask})) before stepping"
            )
        if mode == AutoresetMode.NEXT_STEP:
            resetting = self._autoreset.copy()
        else:
            resetting = np.zeros(self.num_envs, dtype=np.bool_)
        stepping = np.flatnonzero(~resetting).tolist()
        results = dict(zip(stepping, self.cores.step(actions, stepping), strict=True))
        infos: dict = {}
        for i in range(self.num_envs):
            if resetting[i]:
                self._env_obs[i], info = self.cores.reset(i)
                self._rewards[i] = 0.0
                self._terminations[i] = False
                self._truncations[i] = False
            else:
                obs, reward, term, trunc, info = results[i]
                self._env_obs[i], self._rewards[i] = obs, reward
                self._terminations[i], self._truncations[i] = term, trunc
                if mode == AutoresetMode.SAME_STEP and (term or trunc):
                    infos = self._add_info(infos, {"final_obs": obs, "final_info": info}, i)
                    self._env_obs[i], info = self.cores.reset(i)
            infos = self._add_info(infos, info, i)
        self._obs = concatenate(self.single_observation_space, self._env_obs, self._obs)
        self._autoreset = np.logical_or(self._terminations, self._truncations)
        return (
            deepcopy(self._obs),
            np.copy(self._rewards),
            np.copy(self._terminations),
            np.copy(self._truncations),
            infos,
        )

    # ------------------------------------------------------------------ the rest
    def render(self) -> tuple | None:
        """One frame per env (``render_mode="rgb_array"``), or None."""
        if self.render_mode is None:
            gym.logger.warn("render() called with render_mode=None: pass render_mode='rgb_array'")
            return None
        return tuple(env.render() for env in self.envs)

    def call(self, name: str, *args, **kwargs) -> tuple:
        """``getattr(env, name)`` of every core, called with the arguments if callable."""
        out = []
        for env in self.envs:
            attr = getattr(env, name)
            out.append(attr(*args, **kwargs) if callable(attr) else attr)
        return tuple(out)

    def get_attr(self, name: str) -> tuple:
        """``getattr(env, name)`` of every core."""
        return tuple(getattr(env, name) for env in self.envs)

    def set_attr(self, name: str, values) -> None:
        """Set ``name`` on every core: one value for all, or a list of num_envs values."""
        if not isinstance(values, list | tuple):
            values = [values] * self.num_envs
        if len(values) != self.num_envs:
            raise ValueError(f"set_attr: {len(values)} values for num_envs = {self.num_envs}")
        for env, v in zip(self.envs, values, strict=True):
            setattr(env, name, v)

    def close_extras(self, **kwargs) -> None:
        self.cores.close()


class FlatPlateVectorEnv(BrushVectorEnv):
    """``brush_env/FlatPlate-v0`` batched (the vector entry point of the id)."""

    env_class = BrushEnv


class ToothRowVectorEnv(BrushVectorEnv):
    """``brush_env/ToothRow-v0`` batched (the vector entry point of the id)."""

    env_class = ToothRowEnv
