"""brush_env: toothbrush DFM dynamics engine and Gymnasium environments.

Importing the package registers the Gymnasium ids (idempotently; the env modules themselves load
on the first ``gym.make``), so ``gym.make("brush_env:brush_env/FlatPlate-v0")`` also works in
subprocess workers.  It does so without importing gymnasium (``import brush_env.engine`` must
not need it): if gymnasium is already loaded the ids are registered at once, otherwise a one-shot
import hook registers them right after gymnasium's own ``__init__`` has run.  Gymnasium >= 1.0
has no env plugin entry points any more, hence the hook.
"""

import importlib.abc
import importlib.util
import sys

__version__ = "0.1.0"

#: Registered ids -> (entry point, max_episode_steps). 300 steps = 12 s at the default 25 Hz;
#: it equals ``[episode] max_episode_steps`` of configs/envs/flat_plate.toml (a test pins it).
#: ``gym.make`` wraps the env in a ``TimeLimit`` of that many steps and then in
#: ``brush_env.envs.horizon:TimeLimitHorizon``, which hands the TimeLimit's number to the env
#: (``BrushEnv.set_horizon``), so ``gym.make(id, max_episode_steps=N)`` sets both.
ENV_IDS = {
    "brush_env/FlatPlate-v0": ("brush_env.envs.flat_plate:BrushEnv", 300),
    "brush_env/ToothRow-v0": ("brush_env.envs.tooth_row:ToothRowEnv", 300),
    "brush_env/PlanarStroke-v0": ("brush_env.envs.planar_stroke:PlanarStrokeEnv", 200),
}

#: The wrapper ``gym.make`` adds outside the TimeLimit of every registered id.
HORIZON_WRAPPER = ("TimeLimitHorizon", "brush_env.envs.horizon:TimeLimitHorizon")

#: Registered ids -> the vector entry point of ``gym.make_vec(id, num_envs=N,
#: vectorization_mode="vector_entry_point")`` (brush_env/envs/vector.py: N envs in one
#: ``VectorEnv``); their specs are ``brush_env.gym_registration.BrushEnvSpec``, which lets
#: ``make_vec`` past the horizon wrapper that ``gym.make`` still applies.
VECTOR_ENTRY_POINTS = {
    "brush_env/FlatPlate-v0": "brush_env.envs.vector:FlatPlateVectorEnv",
    "brush_env/ToothRow-v0": "brush_env.envs.vector:ToothRowVectorEnv",
}


def _register() -> None:
    """Register ``ENV_IDS`` with gymnasium (skipping ids already registered)."""
    try:
        from gymnasium.envs.registration import WrapperSpec, register, registry
    except ImportError:  # the engine alone does not need gymnasium
        return
    name, entry = HORIZON_WRAPPER
    for env_id, (entry_point, steps) in ENV_IDS.items():
        if env_id not in registry:
            vector = VECTOR_ENTRY_POINTS.get(env_id)
            register(
                id=env_id,
                entry_point=entry_point,
                max_episode_steps=steps,
                additional_wrappers=(WrapperSpec(name, entry, {}),),
                vector_entry_point=vector,
            )
    # the ids with a vector entry point get their BrushEnvSpec; if this runs while
    # gym_registration itself is being imported (it imports gymnasium, whose import ran this
    # hook), that module does it at its end instead
    mod = sys.modules.get("brush_env.gym_registration")
    if mod is not None and not hasattr(mod, "adopt_vector_specs"):
        return
    from .gym_registration import adopt_vector_specs

    adopt_vector_specs()


class _RegisterAfterGymnasium(importlib.abc.MetaPathFinder):
    """Finds nothing itself: on the first ``import gymnasium`` it removes itself, lets the other
    finders locate gymnasium and wraps the loader so that the ids are registered right after
    gymnasium's ``__init__`` has run."""

    brush_env_hook = True  # marker: one hook at a time, also across importlib.reload(brush_env)

    def find_spec(self, fullname, path=None, target=None):
        if fullname != "gymnasium":
            return None
        if self in sys.meta_path:
            sys.meta_path.remove(self)
        spec = importlib.util.find_spec(fullname)  # the remaining finders (may raise ImportError)
        if spec is not None and spec.loader is not None:
            spec.loader = _RegisteringLoader(spec.loader)
        return spec


class _RegisteringLoader(importlib.abc.Loader):
    """Delegates to gymnasium's own loader, restores it on the module and then registers."""

    def __init__(self, loader):
        self._loader = loader

    def create_module(self, spec):
        return self._loader.create_module(spec)

    def exec_module(self, module):
        module.__loader__ = self._loader
        if module.__spec__ is not None:
            module.__spec__.loader = self._loader
        self._loader.exec_module(module)
        _register()

    def __getattr__(self, name):
        return getattr(self._loader, name)


def _install() -> None:
    if "gymnasium" in sys.modules:
        _register()
    elif not any(getattr(f, "brush_env_hook", False) for f in sys.meta_path):
        sys.meta_path.insert(0, _RegisterAfterGymnasium())


_install()
