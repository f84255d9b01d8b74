"""brush_env: toothbrush DFM dynamics engine and Gymnasium environments.

``import brush_env`` (or ``import brush_env.engine``) never imports gymnasium: the engine runs
without it.  The Gymnasium ids are registered as soon as gymnasium is importable *and* imported:
at once if it already is, otherwise by a one-shot import hook that registers them right after
gymnasium's own import finishes.  So ``gym.make("brush_env/FlatPlate-v0")`` works whatever the
import order, and ``gym.make("brush_env:brush_env/FlatPlate-v0")`` also in subprocess workers.
"""

from __future__ import annotations

import importlib.abc
import sys

__version__ = "0.1.0"

#: Registered ids -> (entry point, max_episode_steps). 300 steps = 12 s at the default 25 Hz;
#: it equals ``[episode] max_episode_steps`` of configs/envs/flat_plate.toml (a test pins it).
ENV_IDS = {
    "brush_env/FlatPlate-v0": ("brush_env.envs.flat_plate:BrushEnv", 300),
}


def _register() -> None:
    """Register every id (idempotent).  The horizon wrapper hands gymnasium's TimeLimit to the
    env (brush_env/envs/horizon.py)."""
    from gymnasium.envs.registration import WrapperSpec, register, registry

    horizon = WrapperSpec(
        name="HorizonFromTimeLimit",
        entry_point="brush_env.envs.horizon:HorizonFromTimeLimit",
        kwargs={},
    )
    for env_id, (entry_point, steps) in ENV_IDS.items():
        if env_id not in registry:
            register(
                id=env_id,
                entry_point=entry_point,
                max_episode_steps=steps,
                additional_wrappers=(horizon,),
            )


class _RegisterAfterGymnasium(importlib.abc.MetaPathFinder):
    """Finds nothing itself; when ``gymnasium`` is about to be imported it wraps that module's
    loader so that our ids are registered right after gymnasium has finished importing."""

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "gymnasium":
            return None
        sys.meta_path.remove(self)  # one shot; the other finders locate gymnasium
        import importlib.util

        spec = importlib.util.find_spec("gymnasium")
        if spec is None or spec.loader is None:
            return spec
        exec_module = spec.loader.exec_module

        def exec_then_register(module):
            exec_module(module)
            _register()

        spec.loader.exec_module = exec_then_register
        return spec


if "gymnasium" in sys.modules:
    _register()
elif not any(isinstance(f, _RegisterAfterGymnasium) for f in sys.meta_path):
    sys.meta_path.insert(0, _RegisterAfterGymnasium())
