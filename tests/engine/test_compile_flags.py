"""Every numba kernel of the package states its ``fastmath`` flag, so no kernel's arithmetic
depends on which caller compiled it first.

numba gives a kernel that does not set a flag the flag of the first caller that compiles it
(numba issue 7168) and caches that version without the flag in its key.  The reduced model's
kernels are fast-math (``prb_kernels.PRB``) and call the full model's strict ones (``tip_load``,
``surface_gap``, ...): before the flag was explicit, a process that ran the reduced level first
compiled those fast-math for the full chain too, and two processes could disagree in the last
digits (the pool-vs-Ray sweep test failed in the 14th digit after the full suite, which is the
end-to-end check: tests/sweeps/test_sweep.py).
"""

from __future__ import annotations

import importlib
import pkgutil

from numba.core.registry import CPUDispatcher

import brush_env


def _dispatchers():
    for info in pkgutil.walk_packages(brush_env.__path__, "brush_env."):
        if info.name.startswith("brush_env.cli"):
            continue
        mod = importlib.import_module(info.name)
        for name, obj in vars(mod).items():
            if isinstance(obj, CPUDispatcher) and obj.py_func.__module__ == info.name:
                yield f"{info.name}.{name}", obj


def test_every_kernel_sets_fastmath_explicitly():
    found = dict(_dispatchers())
    assert len(found) > 50  # the walk reached the engine's kernels
    missing = sorted(n for n, d in found.items() if "fastmath" not in d.targetoptions)
    assert not missing, f"kernels without an explicit fastmath flag (inheritable): {missing}"
