"""A compiled kernel's entry point for one fixed set of argument types: the call without numba's
per-call type dispatch.

Calling a numba dispatcher types every argument first (``numba.typeof``, done again at every
call) to pick the compiled overload.  The reduced model's rollout takes ten records that hold
~100 arrays between them, and that dispatch cost ~28 us of every env step (the kernel call from
Python: 43.6 us for a rollout of zero steps, 15.6 us through the overload's entry point, measured
2026-11-27, docs/benchmarks.md) -- ~3 % of an env step at `fast`.  A caller whose arguments keep
their types from call to call (the same records, fresh arrays of the same dtype, dimensions and
layout) looks the overload up once and calls its entry point after; the entry point still unboxes
every argument, it only skips choosing.  A caller whose argument types may change must not use it:
the entry point reads its arguments as the types it was compiled for.
"""

from __future__ import annotations

from collections.abc import Callable

from numba import typeof
from numba.core.typing.typeof import Purpose

__all__ = ["entry_point"]


def entry_point(kernel, args: tuple) -> Callable | None:
    """The entry point of ``kernel``'s compiled overload for the types of ``args`` (as the
    dispatcher types them), or None if the kernel has no such overload yet (call the kernel
    itself once first: that compiles it or loads it from the cache)."""
    key = tuple(typeof(a, Purpose.argument) for a in args)
    cres = kernel.overloads.get(key)
    return None if cres is None else cres.entry_point
