"""numba's loading of a cached kernel without installing its compiler's lowering registries.

Where a warm start's time went (issue 32, docs/benchmarks.md, session 37): numba's
``Cache.load_overload`` calls ``target_context.refresh()`` before it reads a kernel from the
cache, and the first refresh of a process imports and installs every lowering registry numba
has -- numpy's array and linear-algebra implementations, random generators, typed containers,
jitclass, polynomials -- 0.37 s of every ``brush-env`` command and every ``gym.make`` process
that only loads its kernels.  Loading needs none of them: ``CompileResult._rebuild`` hands the
cached object code to the JIT, looks up its wrapper and sets its environment; lowering is what
the registries are for, and a compile refreshes both contexts itself (``CompilerBase.__init__``:
``typingctx.refresh(); targetctx.refresh()``) before it lowers anything.

:func:`install` makes ``Cache.load_overload`` initialise numba's runtime (its ``NRT_*`` symbols,
which a cached kernel compiled with NRT links against; 0.02 s) and load third-party extensions'
entry points, as the refresh would, and then load without the registries.  A cache miss goes on
to numba's compile as before, which refreshes.  Applies only where numba's code is the code it
was written against (``_recognised``); ``BRUSH_ENV_NUMBA_REFRESH=1`` switches it off (numba as
shipped: an A/B).  The machine code is the cache's either way: results are the same to the bit.
"""

from __future__ import annotations

from .numba_patching import apply, sources

#: what numba's methods must say for the patch to apply (numba 0.68.1's text, the one checked)
_LOAD_TEXT = ("target_context.refresh()", "self._load_overload(sig, target_context)")
_COMPILER_TEXT = ("typingctx.refresh()", "targetctx.refresh()")
_REFRESH_TEXT = ("rtsys.initialize(self)", "numba.core.entrypoints.init_all()")
#: numba's own methods
_ORIGINAL: dict[str, object] = {}


def _recognised(caching, compiler, cpu) -> bool:
    """True if numba loads, compiles and refreshes the way this patch was written against: the
    load refreshes, a compile refreshes before it lowers, and the refresh's only parts a loaded
    kernel needs are the runtime's initialisation and the extensions' entry points."""
    src = sources(
        caching.Cache.load_overload,
        caching.Cache._load_overload,
        compiler.CompilerBase.__init__,
        cpu.CPUContext.load_additional_registries,
    )
    if src is None:
        return False
    load, inner, init, registries = src
    return (
        all(t in load for t in _LOAD_TEXT)
        and "self._impl.rebuild(target_context, data)" in inner
        and all(t in init for t in _COMPILER_TEXT)
        and all(t in registries for t in _REFRESH_TEXT)
    )


def _load_overload(self, sig, target_context):
    """``Cache.load_overload`` without the refresh: numba's runtime and extensions initialised,
    the kernel loaded (None on a miss, and numba's compile, which refreshes, goes on)."""
    import numba.core.entrypoints
    from numba.core.runtime import rtsys

    rtsys.initialize(target_context)
    numba.core.entrypoints.init_all()
    with self._guard_against_spurious_io_errors():
        return self._load_overload(sig, target_context)
    # None returned if the `with` block swallows an exception (numba's own comment's case)


def install() -> bool:
    """Apply the patch once (idempotent); returns True if it is in place."""
    from numba.core import caching, compiler, cpu

    return apply(
        caching.Cache,
        {"load_overload": _load_overload},
        "BRUSH_ENV_NUMBA_REFRESH",
        lambda: _recognised(caching, compiler, cpu),
        _ORIGINAL,
    )


def installed() -> bool:
    """True if numba loads cached kernels through the patched ``load_overload``."""
    from numba.core import caching

    return caching.Cache.load_overload is _load_overload
