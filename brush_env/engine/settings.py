"""The engine's settings: one ``SimSettings`` value carries everything a fidelity level, an env
or an experiment sets for the engine -- the bristle model, its bodies, the step and the solver --
from the TOML file to the kernels under one name each (docs/architecture.md, "Settings").

``dt`` is the caller's step (``Simulator.step``); it is split into ``substeps`` equal solver steps
of at most ``max_substep`` (the kernels' ``h``), and a solver step that fails is retried as halves
down to ``h / 2**max_halvings`` inside the kernel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import records as rec
from ._kernels import ELEMENTS
from .checks import ConfigError, Limit, check_choice, check_int, check_real

G_EARTH = 9810.0  # [mm/s^2]
INTEGRATORS = {"euler": rec.METHOD_EULER, "bdf2": rec.METHOD_BDF2}


class SimulationDivergence(RuntimeError):
    """Raised when Newton fails on the smallest halving of a solver step; the state is left as
    before the step."""

    def __init__(self, time: float, bristles, reason: str):
        self.time = time
        self.bristles = list(int(b) for b in bristles)
        self.reason = reason
        super().__init__(
            f"simulation diverged at t = {time:.6g} s in bristle(s) {self.bristles[:10]}: {reason}"
        )


@dataclass(frozen=True)
class SimSettings:
    """Numerical settings of the engine.

    dt [s] time step (the interval of ``step``); bodies_per_bristle [count]: every bristle
    discretised into this many rigid bodies (0: the brush file's own counts); model: the bristle
    model behind the seam (``bristles.py``): "dfm" the full discrete flexible multibody chain (eq
    1-11), or a model registered with ``bristles.register_bristle_model``; max_substep [s] the
    longest step the solver takes: a longer ``dt`` is split into ceil(dt / max_substep) equal
    internal steps with the TCP pose interpolated between the two commanded poses (linear position,
    geodesic rotation), so that a large control step does not hold an unstable (buckling)
    equilibrium or jump across a stick-slip transition (default 1 ms: the 3 mm press's hold force is
    within 3 % of a 0.125 ms run, docs/model.md); integrator "euler" (backward Euler) or "bdf2";
    newton_rtol: Newton tolerance on the residual relative to each bristle's force scale E I / L^2
    [-] (default 1e-5: the paper turn's every error measure within 0.01 points of 1e-7's at 35 %
    fewer iterations, docs/benchmarks.md "Newton's tolerance"; for steps well below 1 ms take
    1e-7 or less, as the level ``reference`` does: at 1e-5 Newton's error, ~3e-4 of a driven
    bristle's force, is as large as BDF2's below 0.1 ms); newton_max_iter per attempt;
    max_halvings: a failing solver step is retried as halves, down to its length /
    2**max_halvings (the in-kernel halving; not the split of ``dt`` into solver steps);
    jacobian_max_age: steps a bristle's factored Newton matrix may be reused (0: rebuild at every
    step; reuse changes iteration counts only, the converged state is set by the residual);
    gravity [mm/s^2] as a world vector (default (0, 0, -9810); (0, 0, 0) switches it off);
    max_tcp_speed [mm/s], max_tcp_angular_speed [rad/s]: the fastest TCP motion ``step`` accepts
    (default 1000 mm/s, a UR5's tool speed limit, and 10 turns/s): a faster command is a jump, not a
    motion, and is refused with an error naming the speed; element: the beam element formulation,
    "paper" (the paper's Adams-FIELD element, strain in the proximal body's frame) or "mid"
    (co-rotational Timoshenko element in the mid-frame, accurate with few bodies in buckled contact;
    docs/model.md); tip_tip_sweeps: most sweeps over the bristles per (internal) step for tip-tip
    contact (Table 3).  1 (default): one sweep, the partners solved later in the sweep held at their
    start-of-step tips (the tip-tip force lags: 6 % on the flat-plate turn even at 0.125 ms). > 1:
    after the first sweep the touching tips are placed by the coupled solve (``coupling.py``) and
    the bristles whose partners moved by more than tip_tip_tol [mm] since they were solved are
    solved again, so both sides of every tip-tip contact see the end-of-step tips (action = reaction
    within 2 k tol); +50 % wall on the flat-plate turn at 1 ms, but up to ~7x on the four-turn
    reference experiment (docs/model.md); the fidelity levels reference, paper and balanced use 8.
    """

    dt: float = 1e-3
    bodies_per_bristle: int = 0
    model: str = "dfm"
    integrator: str = "bdf2"
    max_substep: float = 1e-3
    max_tcp_speed: float = 1000.0
    max_tcp_angular_speed: float = 20.0 * np.pi
    newton_rtol: float = 1e-5
    newton_max_iter: int = 100
    max_halvings: int = 8
    gravity: tuple = (0.0, 0.0, -G_EARTH)
    jacobian_max_age: int = 25
    element: str = "mid"
    tip_tip_sweeps: int = 1
    tip_tip_tol: float = 1e-6

    @property
    def substeps(self) -> int:
        """Internal steps per ``step``: ceil(dt / max_substep)."""
        return max(1, int(np.ceil(self.dt / self.max_substep - 1e-9)))

    def __post_init__(self):
        check_real("settings.dt", self.dt, Limit("s", gt=0, le=0.1))
        check_int(
            "settings.bodies_per_bristle", self.bodies_per_bristle, Limit("count", ge=0, le=64)
        )
        if not isinstance(self.model, str) or not self.model:
            raise ConfigError(
                f"settings.model = {self.model!r}: must be the name of a bristle model "
                "(e.g. 'dfm', the full chain)"
            )
        check_real("settings.max_substep", self.max_substep, Limit("s", gt=0, le=0.1))
        check_real("settings.max_tcp_speed", self.max_tcp_speed, Limit("mm/s", gt=0, le=1e5))
        check_real(
            "settings.max_tcp_angular_speed",
            self.max_tcp_angular_speed,
            Limit("rad/s", gt=0, le=1e3),
        )
        check_choice("settings.integrator", self.integrator, sorted(INTEGRATORS), "integrator")
        check_choice("settings.element", self.element, sorted(ELEMENTS), "element")
        check_real("settings.newton_rtol", self.newton_rtol, Limit("relative", gt=0, le=1e-2))
        check_int("settings.newton_max_iter", self.newton_max_iter, Limit("", ge=1, le=1000))
        check_int("settings.max_halvings", self.max_halvings, Limit("", ge=0, le=30))
        check_int(
            "settings.jacobian_max_age", self.jacobian_max_age, Limit("steps", ge=0, le=10000)
        )
        check_int("settings.tip_tip_sweeps", self.tip_tip_sweeps, Limit("", ge=1, le=1000))
        check_real("settings.tip_tip_tol", self.tip_tip_tol, Limit("mm", gt=0, le=1.0))
        if len(self.gravity) != 3 or not np.all(np.isfinite(self.gravity)):
            raise ConfigError(
                f"settings.gravity = {self.gravity!r}: must be 3 finite numbers (mm/s^2)"
            )


def engine_keys() -> tuple[str, ...]:
    """The names ``SimSettings`` takes (a fidelity level's [settings] and the env's
    ``engine_overrides`` use exactly these)."""
    return tuple(SimSettings.__dataclass_fields__)
