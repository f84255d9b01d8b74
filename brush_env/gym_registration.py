"""The registered ids' ``EnvSpec``: ``gym.make`` keeps its horizon wrapper, and
``gym.make_vec(..., vectorization_mode="vector_entry_point")`` reaches the batched env.

Gymnasium (1.x) cannot have both on one plain spec: ``gym.make(id, max_episode_steps=N)`` hands
``N`` only to its ``TimeLimit``, so the env learns it through a wrapper applied *outside* the
``TimeLimit`` -- an ``additional_wrappers`` entry of the spec
(``brush_env.envs.horizon.TimeLimitHorizon``); and ``gym.make_vec`` refuses the vector entry
point of any spec whose ``additional_wrappers`` is not empty ("Cannot use `vector_entry_point`
vectorization mode with the additional_wrappers parameter in spec being not empty"), because a
vector env cannot apply single-env wrappers.  The batched env needs no such wrapper: it is
given ``max_episode_steps`` (``make_vec`` passes the id's, or the caller's) and sets each core's
horizon and truncation itself.

:class:`BrushEnvSpec` is therefore an ``EnvSpec`` whose ``additional_wrappers`` read as empty to
exactly one reader, the vector-entry-point check in ``gymnasium.envs.registration.make_vec``
(recognised by its code object; the only place ``make_vec`` reads the field).  Everywhere else
-- ``gym.make``, ``make_vec``'s sync and async modes (which call ``gym.make``), ``repr``,
``to_json`` -- the spec holds the wrapper.  If a later gymnasium moves that check, the shim
stops matching and ``make_vec`` raises its own error again (a test catches it); it never hides
the wrapper from ``gym.make``.  Imports gymnasium: loaded by ``brush_env._register`` only once
gymnasium is.
"""

from __future__ import annotations

import sys

import gymnasium.envs.registration as _reg
from gymnasium.envs.registration import EnvSpec, WrapperSpec

__all__ = ["BrushEnvSpec", "adopt_vector_specs"]

_MAKE_VEC_CODE = _reg.make_vec.__code__
#: the module of the batched envs (brush_env.VECTOR_ENTRY_POINTS's entry points)
_VECTOR_MODULE = "brush_env.envs.vector"


class BrushEnvSpec(EnvSpec):
    """``EnvSpec`` of a brush_env id with a vector entry point (module docstring)."""

    @property  # type: ignore[override]
    def additional_wrappers(self) -> tuple[WrapperSpec, ...]:
        if sys._getframe(1).f_code is _MAKE_VEC_CODE and self.vector_entry_point is not None:
            return ()  # make_vec's vector-entry-point check: the batched env takes the horizon
        return self.__dict__["_brush_wrappers"]

    @additional_wrappers.setter
    def additional_wrappers(self, value: tuple[WrapperSpec, ...]) -> None:
        self.__dict__["_brush_wrappers"] = tuple(value)


def adopt_vector_specs() -> None:
    """Make the spec of every registered id whose vector entry point is brush_env's batched env
    (``brush_env.VECTOR_ENTRY_POINTS``) a :class:`BrushEnvSpec` (idempotent)."""
    import dataclasses

    for env_id, plain in list(_reg.registry.items()):
        vector = plain.vector_entry_point
        if isinstance(plain, BrushEnvSpec) or not (
            isinstance(vector, str) and vector.startswith(_VECTOR_MODULE + ":")
        ):
            continue
        _reg.registry[env_id] = BrushEnvSpec(
            **{f.name: getattr(plain, f.name) for f in dataclasses.fields(plain) if f.init}
        )


# imported first (before gymnasium), this module's own ``import gymnasium`` ran the package's
# registration hook while the class above did not exist yet
adopt_vector_specs()
