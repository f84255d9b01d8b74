"""First-start compilation of the numba kernels, made visible and done once.

numba compiles every kernel on its first call (one to a few minutes for the whole set) and caches
the machine code beside the sources (``cache=True``), so later starts load it in about a second.
:func:`warm_up` runs a tiny brush through a list of kernel groups (:data:`GROUPS`: the set-up's
surface and pose kernels, dynamic steps with both integrators -- contact with stick-slip friction
and tip-tip pairs --, a static solve) and records a stamp of the sources it compiled;
:func:`kernels_compiled` tells a command whether it is about to compile, so it can say so before
any progress bar (``brush-env warmup`` calls it on purpose).  While it compiles, a line every
10 s names the group (k of n), the elapsed time and an estimate from this machine's speed
(``engine.compile_progress``).  A caller may pass only the groups it needs.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from ..kernel_cache import announce, kernels_compiled, read_profile, write_stamp
from .compile_progress import CompileProgress, KernelListener

_HERE = Path(__file__).resolve().parent

__all__ = [
    "GROUPS",
    "KernelGroup",
    "ensure_compiled",
    "groups_for",
    "kernels_compiled",
    "warm_up",
]

#: seconds between two progress lines while a group compiles
TICK_S = 10.0


@dataclass(frozen=True)
class KernelGroup:
    """One step of the warm-up: ``run(tiny)`` drives the engine so that numba compiles a set of
    kernels; ``name`` says which, in words (the progress lines show it)."""

    name: str
    run: Callable[[_Tiny], None]
    #: names of groups whose kernels this one compiles too (``STEP`` steps by ``follow`` as
    #: well): a warm-up of this group counts as theirs (``kernels_compiled``)
    covers: tuple[str, ...] = ()


class _Tiny:
    """The tiny brush on the plate z = 0 that every group drives (bristles pointing down)."""

    def __init__(self) -> None:
        from .config import load_brush
        from .scene import load_scene

        brush = load_brush("tiny")
        self.scene = load_scene("flat_plate", brush=brush)
        self.R = np.diag([1.0, -1.0, -1.0])
        self.top = max(b.length for b in brush.bristles) + brush.bristles[0].tip_radius


def _setup(t: _Tiny) -> None:
    """Simulator set-up and reset: pose checks, surface gaps, the TCP wrench."""
    from .simulator import SimSettings, Simulator

    sim = Simulator(t.scene, SimSettings(dt=2e-3))
    sim.reset(np.array([0.0, 0.0, t.top + 0.05]), t.R)


def _steps(integrator: str, t: _Tiny, sweeps: int = 1, by_step: bool = True) -> None:
    """Press 0.5 mm into the plate, then slide: contact, stick and slip, the Newton solve (with
    ``sweeps`` > 1 the coupled tip-tip solve's kernel, ``step.step_bristles_coupled``), through
    the compiled pose rollout (``Simulator.follow``: the experiments) and, with ``by_step``, by
    ``step`` (the envs, designers' scripts): two kernels, each with the whole step inside."""
    from .simulator import SimSettings, Simulator

    settings = SimSettings(dt=2e-3, integrator=integrator, tip_tip_sweeps=sweeps)
    sim = Simulator(t.scene, settings)
    sim.reset(np.array([0.0, 0.0, t.top + 0.05]), t.R)
    k = np.arange(1, 26)
    z = t.top + 0.05 - np.minimum(k, 10) * 0.05
    P = np.stack([0.02 * np.maximum(k - 10, 0), 0.0 * k, z], axis=1)
    if by_step:
        for p in P:
            sim.step(p, t.R)
        P = sim.state.tcp_p[1] + np.outer(np.arange(1, 6), [0.02, 0.0, 0.0])
    sim.follow(P, np.broadcast_to(t.R, (P.shape[0], 3, 3)))


def _static(t: _Tiny) -> None:
    """The static solve of a small press (tips sticking)."""
    from .simulator import SimSettings, Simulator

    sim = Simulator(t.scene, SimSettings())
    sim.reset(np.array([0.0, 0.0, t.top]), t.R)
    sim.solve_static(np.array([0.0, 0.0, t.top - 0.1]), t.R, increments=2)


def _reduced(model: str, t: _Tiny) -> None:
    """The reduced model (``model`` "prb": level ``reduced``; "table": its tabulated tip law,
    level ``fast``, on the tiny brush's shipped tables): a press and a slide through
    ``Simulator.rollout`` and through ``Simulator.step`` (its kernels, the rollout's, the static
    solve)."""
    from .simulator import SimSettings, Simulator

    sim = Simulator(t.scene, SimSettings(dt=4e-3, model=model, bodies_per_bristle=2))
    sim.reset(np.array([0.0, 0.0, t.top + 0.05]), t.R)
    sim.rollout(np.array([5.0, 0.0, -20.0]), np.zeros(3), 10)
    sim.step(sim.state.tcp_p[1] + np.array([0.02, 0.0, 0.0]), t.R)
    sim.solve_static()


def _tip_table(t: _Tiny) -> None:
    """The tabulated tip law's builder (a new brush's tables at level ``fast``) on a 5 x 5 x 3
    table of the tiny brush's first bristle: its kernels compile once here, not on a user's first
    table."""
    from .prb import build_geometry
    from .tip_table import build_table

    build_table(build_geometry(t.scene.brush).prm[0], shape=(5, 5, 3))


SETUP = KernelGroup("set-up (surface gaps, pose checks, TCP wrench)", _setup)
#: the experiments' (``brush-env reference``, the tooth row) step groups: they step only by
#: ``follow``, so their first start compiles no ``step`` kernel (``groups_for(..., follow=True)``)
FOLLOW = {
    "bdf2": KernelGroup(
        "bristle step, BDF2, by the compiled rollout (beam elements, contact and friction, "
        "Newton solve, tip-tip pairs)",
        partial(_steps, "bdf2", by_step=False),
    ),
    "euler": KernelGroup(
        "bristle step, backward Euler, by the compiled rollout",
        partial(_steps, "euler", by_step=False),
    ),
}
FOLLOW_COUPLED = KernelGroup(
    "coupled tip-tip solve by the compiled rollout (levels 'balanced', 'paper', 'reference')",
    partial(_steps, "bdf2", sweeps=8, by_step=False),
)
STEP = {
    "bdf2": KernelGroup(
        "bristle step, BDF2 (beam elements, contact and friction, Newton solve, tip-tip pairs)",
        partial(_steps, "bdf2"),
        covers=(FOLLOW["bdf2"].name,),
    ),
    "euler": KernelGroup(
        "bristle step, backward Euler", partial(_steps, "euler"), covers=(FOLLOW["euler"].name,)
    ),
}
COUPLED = KernelGroup(
    "coupled tip-tip solve (levels 'balanced', 'paper', 'reference')",
    partial(_steps, "bdf2", sweeps=8),
    covers=(FOLLOW_COUPLED.name,),
)
REDUCED = {
    "prb": KernelGroup(
        "reduced model (fidelity level 'reduced': quasi-static joints, rollout)",
        partial(_reduced, "prb"),
    ),
    "table": KernelGroup(
        "tabulated tip law's step (fidelity level 'fast', the envs' default)",
        partial(_reduced, "table"),
    ),
}

#: The full warm-up (``brush-env warmup``), in order.  Nearly all the time goes to the first
#: dynamic steps: numba compiles a step kernel with every kernel it calls; the later groups
#: reuse them (the Euler step and the static solve compile next to nothing after BDF2).
GROUPS: tuple[KernelGroup, ...] = (
    SETUP,
    STEP["bdf2"],
    STEP["euler"],
    COUPLED,
    KernelGroup("static solve", _static),
    REDUCED["prb"],
    REDUCED["table"],
    KernelGroup("tabulated tip law's builder (a new brush's tables at level 'fast')", _tip_table),
)


def groups_for(settings, follow: bool = False) -> tuple[KernelGroup, ...]:
    """The kernel groups a run with these ``SimSettings`` uses, so that its first start compiles
    only those (issue 32: the reference experiment's first start compiled the reduced model and
    the tip table's builder too): the set-up, then the full chain's step in its integrator (and
    the coupled tip-tip solve with more than one sweep), or the reduced model's step (``prb``,
    ``table``).  ``follow``: a run that steps the full chain only by ``Simulator.follow`` (the
    experiments) compiles no ``step`` kernel.  A coupled level compiles no one-sweep kernel:
    its Simulator steps only by the coupled ones (``chain.DFMChain``; their first sweep is the
    one-sweep step's), and a one-sweep rollout is a second copy of the whole step (~20 s of
    LLVM).  A bristle model registered elsewhere: every group."""
    if settings.model == "dfm":
        if settings.tip_tip_sweeps > 1:
            return (SETUP, FOLLOW_COUPLED if follow else COUPLED)
        return (SETUP, (FOLLOW if follow else STEP)[settings.integrator])
    if settings.model in REDUCED:
        return (SETUP, REDUCED[settings.model])
    return GROUPS


def warm_up(
    groups: Sequence[KernelGroup] = GROUPS,
    notice: Callable[[str], None] | None = None,
    interval: float = TICK_S,
) -> float:
    """Compile (or load from cache) the kernels of ``groups`` on a tiny brush; returns the
    seconds taken.  ``notice``: where the progress lines go (None: nowhere), one every
    ``interval`` s while a compile runs and one per group that compiled."""
    t0 = time.perf_counter()
    if not kernels_compiled():  # the sources changed since the last warm-up (or there was none)
        # numba's cache checks only the timestamp of a kernel's own file: a kernel that inlines
        # code from another engine module would load stale machine code after that module changed
        for f in (_HERE / "__pycache__").glob("*.nb[ic]"):
            f.unlink(missing_ok=True)
    old, where = read_profile()
    progress = CompileProgress([g.name for g in groups], old, notice)
    tiny = _Tiny()
    with KernelListener(progress), progress.ticker(interval):
        for k, g in enumerate(groups):
            progress.start_group(k)
            g.run(tiny)
            progress.end_group()
    seconds = time.perf_counter() - t0
    mine = old if where == "this machine" else {}
    done = [name for g in groups for name in (g.name, *g.covers)]
    write_stamp(done, merged_profile(mine, progress.measured()))
    return seconds


def merged_profile(old: dict, new: dict) -> dict:
    """``old`` with the groups that compiled in ``new`` replaced (a group loaded from the cache
    measured nothing; one that a partial warm-up skipped keeps its old figures)."""
    groups = dict((old or {}).get("groups", {}))
    for name, g in new.get("groups", {}).items():
        if g.get("kernels"):
            groups[name] = g
    return {"groups": groups} if groups else {}


def ensure_compiled(notice=print, groups: Sequence[KernelGroup] = GROUPS) -> float:
    """Warm the kernels if needed, announcing it first (once per process) and showing the
    compile's progress through ``notice``; returns the seconds spent (0 if warm)."""
    names = [g.name for g in groups]
    if kernels_compiled(names):
        return 0.0
    announce(notice, names)
    return warm_up(groups, notice)
