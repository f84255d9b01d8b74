"""numba's inlining of ``inline="always"`` kernels without its two defensive IR copies.

Where the first start's compile went (issue 32, docs/benchmarks.md, session 35): numba inlines an
``inline="always"`` callee by running its front end on the callee afresh at every call site
(``InlineWorker.inline_function`` -> ``run_untyped_passes``) and then, in ``inline_ir``, deep-copies
that fresh IR twice, block by block: once to mutate it and once as an unmutated original that the
inlining pass (``InlineInlinables``) throws away.  A block's deep copy re-copies the function's
whole variable scope (every ``ir.Var`` holds it), so one copy costs blocks x variables: on the
engine's large inlined stages (the residual inside the line search, the predictors) it was a
third of the reference's cold compile, 64 of 203 s CPU (numba issue #8989, open; numba-cuda PR
#689 removes the same copies).

:func:`install` makes ``inline_function`` -- and only it: the typed pass that inlines
``@overload`` implementations from a shared IR keeps its copies -- hand ``inline_ir`` the fresh IR
uncopied.  It is process-wide (any ``inline="always"`` kernel compiled after ``brush_env.engine``'s
import, a user's own too), and safe there: the IR it no longer copies was built for that one call
site and is dropped after it, so nothing shared is mutated.  The inlined IR, and so the machine
code, is the same (checked byte for byte on the cached kernels,
``tests/engine/test_numba_inline.py``).  It is applied only where numba's code is the code it was
written against (``_recognised``), and ``BRUSH_ENV_NUMBA_COPY_IR=1`` switches it off (numba as
shipped: an A/B of the compile).
"""

from __future__ import annotations

import copy
import re
import threading

from .numba_patching import apply, sources

#: numba's own ``inline_function``
_ORIGINAL: dict[str, object] = {}
#: set while ``inline_ir`` runs on a callee IR built for this call site alone (its copies skipped)
_FRESH = threading.local()

#: what numba's two functions must say for the patch to apply (numba 0.68.1's text, the one checked)
_INLINE_FUNCTION_TEXT = ("callee_ir = self.run_untyped_passes(function)", "return self.inline_ir(")
_INLINE_IR_TEXT = (
    "new_block = copy.deepcopy(the_ir.blocks[block_label])",
    "callee_ir_original = copy_ir(callee_ir)",
)


class _CopyModule:
    """Stands in for the ``copy`` module in ``numba.core.inline_closurecall`` (whose only use of
    it is ``inline_ir``'s block copies): ``deepcopy`` returns its argument while ``_FRESH.on``."""

    def __getattr__(self, name):
        return getattr(copy, name)

    @staticmethod
    def deepcopy(x, memo=None):
        if getattr(_FRESH, "on", False):
            return x
        return copy.deepcopy(x, memo)


def _recognised(icc) -> bool:
    """True if numba's ``InlineWorker`` is the code this patch was written against."""
    src = sources(icc.InlineWorker.inline_function, icc.InlineWorker.inline_ir, icc)
    if src is None:
        return False
    f_src, ir_src, mod_src = src
    return (
        all(t in f_src for t in _INLINE_FUNCTION_TEXT)
        and all(t in ir_src for t in _INLINE_IR_TEXT)
        and len(re.findall(r"\bcopy\.", mod_src)) == 1  # the block copy: its only use of ``copy``
        and icc.copy is copy
    )


def _inline_function(self, caller_ir, block, i, function, arg_typs=None):
    """``InlineWorker.inline_function`` with the callee's fresh IR passed on uncopied."""
    callee_ir = self.run_untyped_passes(function)
    freevars = function.__code__.co_freevars
    _FRESH.on = True
    try:
        return self.inline_ir(caller_ir, block, i, callee_ir, freevars, arg_typs=arg_typs)
    finally:
        _FRESH.on = False


def install() -> bool:
    """Apply the patch once (idempotent); returns True if it is in place."""
    from numba.core import inline_closurecall as icc

    ok = apply(
        icc.InlineWorker,
        {"inline_function": _inline_function},
        "BRUSH_ENV_NUMBA_COPY_IR",
        lambda: _recognised(icc),
        _ORIGINAL,
    )
    if ok and not isinstance(icc.copy, _CopyModule):
        icc.copy = _CopyModule()  # the block copies of ``inline_ir`` (its only use of ``copy``)
    return ok


def installed() -> bool:
    """True if numba inlines through the patched ``inline_function``."""
    from numba.core import inline_closurecall as icc

    return icc.InlineWorker.inline_function is _inline_function
