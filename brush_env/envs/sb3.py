"""stable-baselines3's ``VecEnv`` over the batched brush env (``brush_env.envs.vector``).

    from brush_env.envs.sb3 import SB3VecEnv, make_sb3_vec_env
    venv = make_sb3_vec_env("brush_env/FlatPlate-v0", num_envs=8, seed=0, fidelity="reduced")
    model = PPO("MlpPolicy", venv).learn(10_000)

It steps the same cores as :class:`~brush_env.envs.vector.BrushVectorEnv` (its
:class:`~brush_env.envs.vector.BrushCores`; today a Python loop over N single envs), with SB3's
auto-reset: an env whose episode ends is reset within that step, its final observation in
``info["terminal_observation"]``, ``info["TimeLimit.truncated"] = truncated and not
terminated``; ``seed(s)`` (env i gets s + i) and ``set_options`` apply at the next ``reset()``.
The numbers equal those of SB3's ``DummyVecEnv`` over ``gym.make`` envs of the same id and
settings (tested).  Episode statistics for the logger: wrap it in SB3's ``VecMonitor``.
"""

from __future__ import annotations

from copy import deepcopy
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector.utils import concatenate, create_empty_array
from stable_baselines3.common.vec_env import VecEnv

from .vector import BrushVectorEnv, check_num_envs

__all__ = ["SB3VecEnv", "make_sb3_vec_env"]


class SB3VecEnv(VecEnv):
    """SB3 ``VecEnv`` over a :class:`BrushVectorEnv` (module docstring); the vector env's own
    autoreset is not used, only its cores."""

    def __init__(self, venv: BrushVectorEnv):
        if not isinstance(venv, BrushVectorEnv):
            raise TypeError(
                f"SB3VecEnv wraps a BrushVectorEnv (gym.make_vec(..., vectorization_mode="
                f"'vector_entry_point')), not {type(venv).__name__}"
            )
        self.venv = venv
        self.cores = venv.cores
        self.render_mode = venv.render_mode
        super().__init__(venv.num_envs, venv.single_observation_space, venv.single_action_space)
        self.metadata = dict(venv.metadata)
        self._actions: Any = None
        self._obs: Any = create_empty_array(venv.single_observation_space, n=venv.num_envs)

    def _batch(self, obs_list: list) -> Any:
        self._obs = concatenate(self.venv.single_observation_space, obs_list, self._obs)
        return deepcopy(self._obs)

    def reset(self) -> Any:
        obs = []
        for i in range(self.num_envs):
            o, self.reset_infos[i] = self.cores.reset(i, self._seeds[i], self._options[i] or None)
            obs.append(o)
        self._reset_seeds()
        self._reset_options()
        return self._batch(obs)

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        results = self.cores.step(self._actions, range(self.num_envs))
        obs, infos = [], []
        rewards = np.zeros(self.num_envs, dtype=np.float32)  # as DummyVecEnv's buffer
        dones = np.zeros(self.num_envs, dtype=np.bool_)
        for i, (o, r, term, trunc, info) in enumerate(results):
            rewards[i] = r
            dones[i] = term or trunc
            info["TimeLimit.truncated"] = trunc and not term
            if dones[i]:
                info["terminal_observation"] = o
                o, self.reset_infos[i] = self.cores.reset(i)
            obs.append(o)
            infos.append(info)
        return self._batch(obs), rewards, dones, infos

    def close(self) -> None:
        self.venv.close()

    def get_images(self):
        return [env.render() for env in self.cores.envs]

    def _targets(self, indices) -> list:
        return [self.cores.envs[i] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices=None) -> list:
        """``getattr`` of each core; ``"spec"`` is the spec ``gym.make`` would give one env (its
        ``max_episode_steps`` the time limit), as ``DummyVecEnv`` of ``gym.make`` envs reads."""
        if attr_name == "spec":
            return [self.venv.single_spec() for _ in self._targets(indices)]
        return [getattr(env, attr_name) for env in self._targets(indices)]

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        for env in self._targets(indices):
            setattr(env, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list:
        return [
            getattr(env, method_name)(*method_args, **method_kwargs)
            for env in self._targets(indices)
        ]

    def env_is_wrapped(self, wrapper_class: type[gym.Wrapper], indices=None) -> list[bool]:
        return [False for _ in self._targets(indices)]  # the cores are unwrapped envs


def make_sb3_vec_env(
    env_id: str, num_envs: int = 1, seed: int | None = None, **kwargs
) -> SB3VecEnv:
    """``SB3VecEnv(gym.make_vec(env_id, num_envs, vectorization_mode="vector_entry_point",
    **kwargs))``, seeded like SB3's ``make_vec_env`` (env i gets ``seed + i`` at the first
    reset)."""
    import brush_env  # noqa: F401  (registers the ids)

    venv = gym.make_vec(
        env_id, num_envs=check_num_envs(num_envs), vectorization_mode="vector_entry_point", **kwargs
    )
    if not isinstance(venv, BrushVectorEnv):
        venv.close()
        raise ValueError(
            f"env_id = {env_id!r} has no batched brush env (FlatPlate-v0, ToothRow-v0)"
        )
    out = SB3VecEnv(venv)
    if seed is not None:
        out.seed(seed)
    return out
