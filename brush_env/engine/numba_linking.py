"""numba's linking of a kernel's callees as internal copies, so LLVM can drop what a call passes.

Where the step's instructions went (issue 32, docs/benchmarks.md, session 36): a kernel that
calls another (``newton_solve`` -> ``tip_load``, ``shaft_load``, the elements; ``sweep_bristles``
-> ``newton_solve``) passes its records by value, and numba passes a record as every field of
every array in it -- pointers, sizes, shapes, strides, hundreds of words for ``ContactScene`` or
the workspace's parts -- most of which the callee never reads.  numba links the callee's module
into the caller's with the callee's functions as ``linkonce_odr`` (numba PR #890: any module may
define them), and LLVM may not change the signature or the calling convention of such a
function, since another definition could replace it; so every call stores all those words, and
the callee loads them.

:func:`install` makes numba's ``CPUCodeLibrary.finalize`` give the functions it links in from
other libraries (numba-compiled ones: mangled ``_ZN`` names) **internal** linkage in the caller's
module, before LLVM optimises it.  Each caller then holds private copies of its callees (it did
already: numba's cache keeps a kernel with all the code it calls, and the executed copy is the
caller's), and LLVM's interprocedural passes may remove unused arguments, propagate constants and
inline where its cost model says.  The library's own functions (the kernel and its wrappers, the
names the JIT looks up) keep their linkage; so do global variables.  Measured: the one-sweep
bristle-step on the paper turn 51,178 -> 43,988 instructions (-14 %), coupled 66,289 -> 57,994;
the reference's simulation -20 to -25 % wall; its cold compile 122.9 -> 130.4 s CPU (not back to
back: LLVM optimises each caller's private copies).  The results differ from numba as linked
before in the last bits (LLVM inlines and contracts across the old call boundaries).  It applies
only where numba's code is the code it was written against (``_recognised``), and
``BRUSH_ENV_NUMBA_LINKONCE=1`` switches it off (numba as shipped: an A/B).
"""

from __future__ import annotations

from llvmlite import binding as ll

from .numba_patching import apply, sources

#: what numba's methods must say for the patch to apply (numba 0.68.1's text, the one checked)
_FINALIZE_TEXT = (
    "self._final_module.link_in(",
    "library._get_module_for_linking(), preserve=True,",
    "self._optimize_final_module()",
)
_LINKING_TEXT = ("mod.get_function(name).linkage = 'linkonce_odr'",)
#: numba's own methods
_ORIGINAL: dict[str, object] = {}
#: the prefix of numba's mangled names: the functions numba compiled from Python (and their
#: wrappers), the only ones internalised (the runtime's ``NRT_*`` helpers keep their linkage)
_MANGLED = "_ZN"


def _recognised(codegen) -> bool:
    """True if numba's ``CPUCodeLibrary`` links libraries the way this patch was written against."""
    src = sources(
        codegen.CPUCodeLibrary.finalize,
        codegen.CPUCodeLibrary._get_module_for_linking,
        codegen.CPUCodeLibrary._optimize_final_module,
    )
    if src is None:
        return False
    fin, link, opt = src
    return (
        all(t in fin for t in _FINALIZE_TEXT)
        and all(t in link for t in _LINKING_TEXT)
        and "self._final_module" in opt
    )


def _finalize(self):
    """``CPUCodeLibrary.finalize``, remembering which functions are the library's own."""
    self._brush_env_own = {f.name for f in self._final_module.functions if not f.is_declaration}
    return _ORIGINAL["finalize"](self)


def _optimize_final_module(self):
    """``CPUCodeLibrary._optimize_final_module`` with the linked-in functions made internal."""
    own = getattr(self, "_brush_env_own", None)
    if own is not None:
        for f in self._final_module.functions:
            if not f.is_declaration and f.name not in own and f.name.startswith(_MANGLED):
                f.linkage = ll.Linkage.internal
    return _ORIGINAL["_optimize_final_module"](self)


def install() -> bool:
    """Apply the patch once (idempotent); returns True if it is in place."""
    from numba.core import codegen

    return apply(
        codegen.CPUCodeLibrary,
        {"finalize": _finalize, "_optimize_final_module": _optimize_final_module},
        "BRUSH_ENV_NUMBA_LINKONCE",
        lambda: _recognised(codegen),
        _ORIGINAL,
    )


def installed() -> bool:
    """True if numba links through the patched ``finalize``."""
    from numba.core import codegen

    return codegen.CPUCodeLibrary.finalize is _finalize
