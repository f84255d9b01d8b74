"""The bristle-model seam: ``Simulator`` steps "the bristles" through this one interface.

Behind it today: the full discrete flexible multibody chain (``chain.DFMChain``, eq 1-11, the
paper's model and the mid element), registered as ``"dfm"``.  A second model (the reduced model
for training, or a toy in the tests) registers itself with :func:`register_bristle_model` and is
chosen by ``SimSettings.model`` -- a fidelity level's ``model = "..."`` -- with no change to the
simulator, the envs, the experiments or their outputs.

The contract (also in docs/architecture.md, "The bristle-model seam"):

Takes
    ``factory(scene, settings)``: a ``Scene`` whose brush is already discretised into
    ``settings.bodies_per_bristle`` bodies, and the ``SimSettings``.  Per call: the TCP pose
    (tcp_p [mm], tcp_R) at the end of the solver step and the step's end time (the step length is
    ``settings.dt / settings.substeps``); dead tip loads [N] (``set_tip_forces``).
Holds
    ``model``: the brush geometry -- ``bstart`` (nb+1,) the bodies of bristle j are
    ``bstart[j]:bstart[j+1]``, ``n_bristles``, ``n_bodies``, ``root_p`` (nb,3) [mm] and ``root_R``
    (nb,3,3) the roots in the TCP frame, ``length`` (nb,) [mm], ``tip_radius`` (nb,) [mm],
    ``seg_len`` (N,) [mm].  ``state``: ``pos`` (N,3) [mm] body centres, ``rot`` (N,3,3),
    ``tcp_p`` (4,3) / ``tcp_R`` (4,3,3) the drive (row 1: now, row 0: one step before),
    ``time`` [s], ``steps``, and ``copy()``; restoring a copy (``set_state``) continues bit for
    bit.
Returns
    ``advance`` -> (Newton iterations or 0, solver steps taken); a failed step restores the given
    rollback state and raises ``SimulationDivergence`` (never NaN).  After every call: ``tips``
    (nb,6) tip-node position [mm] and velocity [mm/s], world; ``root_wrench`` (nb,6) the force
    [N] and moment [N mm] about the root node with which each bristle pushes on the head, world
    (the TCP wrench is minus their sum, moments carried to the TCP: ``step.tcp_wrench``);
    ``contact()`` a :class:`TipContact`; ``solver_info()``
    a dict of the model's own counters (may be empty); optionally ``shaft_contact()`` a
    :class:`ShaftContact` (per body) and ``head_clearance()`` [mm] (None by default).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from .checks import ConfigError, did_you_mean


class TipContact(NamedTuple):
    """Per-tip contact after a step, world frame (zeros where a tip does not touch)."""

    normal_force: np.ndarray  # (nb,) [N] eq 6 (summed over surfaces)
    tangential_force: np.ndarray  # (nb, 3) [N] friction, eq 7-10
    sliding: np.ndarray  # (nb,) bool
    penetration: np.ndarray  # (nb,) [mm]
    contact_point: np.ndarray  # (nb, 3) [mm]
    tip_tip_force: np.ndarray  # (nb,) [N] Table 3, summed over partners
    surface: np.ndarray  # (nb,) int64: index into Scene.surfaces of the deepest surface, -1 none


class ShaftContact(NamedTuple):
    """Per-body shaft contact after a solver step, world frame (zeros where a body does not
    touch): each body's capsule against the surfaces (shaft.py)."""

    normal_force: np.ndarray  # (N,) [N] eq 6, summed over surfaces
    tangential_force: np.ndarray  # (N, 3) [N] friction, eq 7-10
    penetration: np.ndarray  # (N,) [mm] of the deepest contact sphere
    contact_point: np.ndarray  # (N, 3) [mm] on the deepest surface
    surface: np.ndarray  # (N,) int64: index into Scene.surfaces of the deepest surface, -1 none


class BristleModel(ABC):
    """One bristle model behind the seam (module docstring: what it takes, holds, returns)."""

    model: object
    state: object
    tips: np.ndarray
    root_wrench: np.ndarray

    @abstractmethod
    def reset(self, tcp_p: np.ndarray, tcp_R: np.ndarray, time: float) -> None:
        """Straight, unloaded bristles at rest on the TCP pose (tcp_p [mm], tcp_R) at ``time``."""

    @abstractmethod
    def snapshot(self):
        """A rollback point: the current state (buffers may be reused between calls)."""

    @abstractmethod
    def advance(self, tcp_p, tcp_R, t_new: float, rollback) -> tuple[int, int]:
        """One solver step to the TCP pose at ``t_new`` [s]; on failure restore ``rollback`` and
        raise ``SimulationDivergence``."""

    @abstractmethod
    def solve_static(self, tcp_p, tcp_R) -> tuple[int, int]:
        """Static equilibrium at the TCP pose under the current tip loads (velocities zero)."""

    @abstractmethod
    def set_state(self, state) -> None:
        """Restore a state made by ``state.copy()``."""

    @abstractmethod
    def set_tip_forces(self, forces: np.ndarray) -> None:
        """Dead external loads on the tips [N, world], shape (nb, 3)."""

    @property
    @abstractmethod
    def tip_forces(self) -> np.ndarray:
        """The current dead tip loads [N, world], (nb, 3)."""

    @abstractmethod
    def contact(self) -> TipContact:
        """Per-tip contact of the last step."""

    def tip_penetration(self) -> np.ndarray:
        """(nb,) [mm] each tip's penetration after the last solver step (the simulator checks it
        after every solver step; a model may answer it more cheaply than ``contact()``)."""
        return self.contact().penetration

    def tip_states(self) -> np.ndarray:
        """(nb, 6) tip position [mm] and velocity [mm/s] of the current state (a model whose
        state can be edited between steps computes them afresh)."""
        return np.array(self.tips[:, 0:6])

    def solver_info(self) -> dict:
        """The model's own counters of the last step (e.g. sweeps); empty by default."""
        return {}

    def shaft_contact(self) -> ShaftContact | None:
        """Per-body contact of the bristles' shafts with the surfaces after the last solver step
        (``Scene.shaft_contact``); None for a model without shafts or with it off."""
        return None

    def shaft_penetration_max(self) -> float:
        """The deepest shaft penetration [mm] after the last solver step (0: none or no shafts);
        the simulator reads it after every solver step."""
        sc = self.shaft_contact()
        if sc is None or sc.penetration.size == 0:
            return 0.0
        return float(sc.penetration.max())

    def head_clearance(self) -> float | None:
        """Smallest distance [mm] of the head's outline to the surfaces at the current TCP pose
        (< 0: inside; ``Scene.head_contact``); None when the model does not report it."""
        return None


#: name -> factory(scene, settings) of the bristle models ``SimSettings.model`` may name
_MODELS: dict[str, Callable] = {}


def register_bristle_model(name: str, factory: Callable) -> None:
    """Make ``SimSettings(model=name)`` build ``factory(scene, settings)`` (a BristleModel)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"bristle model name = {name!r}: must be a non-empty string")
    _MODELS[name] = factory


def bristle_models() -> tuple[str, ...]:
    """The registered bristle model names ("dfm" registers itself in ``chain.py``, which the
    engine's ``__init__`` imports)."""
    return tuple(sorted(_MODELS))


def make_bristle_model(scene, settings) -> BristleModel:
    """The bristle model ``settings.model`` for ``scene`` (ConfigError if none has that name)."""
    factory = _MODELS.get(settings.model)
    if factory is None:
        known = sorted(_MODELS)
        raise ConfigError(
            f"settings.model = {settings.model!r} is not a bristle model"
            f"{did_you_mean(settings.model, known)} (known: {', '.join(known)})"
        )
    return factory(scene, settings)
