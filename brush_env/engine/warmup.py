"""First-start compilation of the numba kernels, made visible and done once.

numba compiles every kernel on its first call (~40-60 s for the whole set on one core) and caches
the machine code beside the sources (``cache=True``), so later starts load it in about a second.
:func:`warm_up` runs a tiny brush through every kernel set (dynamic steps with both integrators,
contact with stick-slip friction and tip-tip pairs, a static solve) and records a stamp of the
sources it compiled; :func:`kernels_compiled` tells a command whether it is about to compile, so
it can say so before any progress bar (``brush-env warmup`` calls it on purpose).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..kernel_cache import COMPILE_NOTICE, announce, kernels_compiled, write_stamp

_HERE = Path(__file__).resolve().parent

__all__ = ["COMPILE_NOTICE", "ensure_compiled", "kernels_compiled", "warm_up"]


def warm_up() -> float:
    """Compile (or load from cache) every kernel set on a tiny brush; returns the seconds taken."""
    from .config import load_brush
    from .scene import load_scene
    from .simulator import SimSettings, Simulator

    t0 = time.perf_counter()
    if not kernels_compiled():
        # numba's cache checks only the timestamp of a kernel's own file: a kernel that inlines
        # code from another engine module would load stale machine code after that module changed
        for f in (_HERE / "__pycache__").glob("*.nb[ic]"):
            f.unlink(missing_ok=True)
    brush = load_brush("tiny")
    scene = load_scene("flat_plate", brush=brush)
    R = np.diag([1.0, -1.0, -1.0])  # bristles pointing down onto the plate z = 0
    top = max(b.length for b in brush.bristles) + brush.bristles[0].tip_radius
    for integrator in ("bdf2", "euler"):
        sim = Simulator(scene, SimSettings(dt=2e-3, integrator=integrator))
        sim.reset(np.array([0.0, 0.0, top + 0.05]), R)
        for k in range(1, 26):  # press 0.5 mm into the plate, then slide: stick and slip
            z = top + 0.05 - min(k, 10) * 0.05
            sim.step(np.array([0.02 * max(k - 10, 0), 0.0, z]), R)
    sim = Simulator(scene, SimSettings())
    sim.reset(np.array([0.0, 0.0, top]), R)  # static solve of a small press (tips sticking)
    sim.solve_static(np.array([0.0, 0.0, top - 0.1]), R, increments=2)
    seconds = time.perf_counter() - t0
    write_stamp()
    return seconds


def ensure_compiled(notice=print) -> float:
    """Warm the kernels if needed, announcing it first (once per process); returns the seconds
    spent (0 if warm)."""
    if kernels_compiled():
        return 0.0
    announce(notice)
    return warm_up()
