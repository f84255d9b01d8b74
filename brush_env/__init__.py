"""brush_env: toothbrush DFM dynamics engine and Gymnasium environments.

Importing the package registers the Gymnasium ids (idempotently; the env modules themselves load
on the first ``gym.make``), so ``gym.make("brush_env:brush_env/FlatPlate-v0")`` also works in
subprocess workers.
"""

__version__ = "0.1.0"

#: Registered ids -> (entry point, max_episode_steps). 300 steps = 12 s at the default 25 Hz;
#: it equals ``[episode] max_episode_steps`` of configs/envs/flat_plate.toml (a test pins it).
ENV_IDS = {
    "brush_env/FlatPlate-v0": ("brush_env.envs.flat_plate:BrushEnv", 300),
}


def _register() -> None:
    try:
        from gymnasium.envs.registration import register, registry
    except ImportError:  # the engine alone does not need gymnasium
        return
    for env_id, (entry_point, steps) in ENV_IDS.items():
        if env_id not in registry:
            register(id=env_id, entry_point=entry_point, max_episode_steps=steps)


_register()
