"""numba's lowering of kernels compiled without NRT, without NRT's dead loads and zero-fills.

Where the first start's LLVM time went (issue 32, docs/benchmarks.md, session 36): numba lowers a
variable that lives across blocks to a stack slot (``alloca``), zero-fills the slot at the
function's entry (``cgutils.alloca_once``), loads the slot's old value before every store (to
``decref`` it) and, at the variable's ``del``, loads it again (``decref``) and stores zeros over
it ("to avoid double frees").  The engine's kernels are compiled without NRT (``_nrt=False``,
``_kernels.HOT``): every ``decref`` is a no-op, but the loads and zero stores are still emitted,
and they are whole-value -- a variable holding the workspace record (``records.Work``, ~750
scalars: pointers, shapes, strides of ~100 arrays) is zeroed and loaded whole, in every inlined
copy of every stage that takes it.  LLVM's SROA pass then splits and promotes each of them:
``newton_solve``'s function passes took 18.6 s on numba's IR and 1.9 s on the same IR without
those stores and loads (timed by llvmlite on the dumped module), and SROA was 40 % of the
reference's LLVM time.

:func:`install` makes ``Lower.storevar`` and ``Lower.delvar`` skip that load and that zero-fill,
and ``Lower.alloca_lltype`` skip the entry zero-fill of an aggregate slot (a record, a tuple, an
array's struct; scalar slots keep theirs), when the context has NRT and debug info off; with NRT
on -- a kernel of a user's own that allocates -- or with debug info, numba's own methods run.
What a kernel computes is unchanged: a slot is written before any read on every path of a kernel
that runs, and without NRT nothing else reads it (``tests/engine/test_numba_lowering.py``: the
same result, bit for bit, with and without).  The machine code is not byte-identical: LLVM
optimises other IR, and in the step kernels a few operations are fused or ordered differently
(the reference's outputs differ from numba as shipped in the last bits, which the stick-slip
events amplify; the jamming angles are the same).  It applies only where numba's code is the code
it was written against (``_recognised``), and ``BRUSH_ENV_NUMBA_NRT_STORES=1`` switches it off
(numba as shipped: an A/B of the compile).
"""

from __future__ import annotations

from llvmlite import ir as llvmir

from .numba_patching import apply, sources

#: what numba's methods must say for the patch to apply (numba 0.68.1's text, the one checked)
_STOREVAR_TEXT = (
    "old = self.loadvar(name)",
    "self.decref(fetype, old)",
    "self._blk_local_varmap[name] = value",
)
_DELVAR_TEXT = (
    "self.decref(fetype, self.builder.load(ptr))",
    "self.builder.store(Constant(ptr.type.pointee, None), ptr)",
    "self._singly_assigned_vars.discard(name)",
)
#: numba's own methods, kept for kernels compiled with NRT
_ORIGINAL: dict[str, object] = {}


def _recognised(lowering, cgutils) -> bool:
    """True if numba's ``Lower.storevar``/``delvar`` are the code this patch was written against
    and ``decref`` does nothing without NRT."""
    L = lowering.Lower
    src = sources(L.storevar, L.delvar, L.decref, L.alloca_lltype, cgutils.alloca_once)
    if src is None:
        return False
    store, delete, decref, alloca, alloca_once = src
    return (
        all(t in store for t in _STOREVAR_TEXT)
        and all(t in delete for t in _DELVAR_TEXT)
        and "if not self.context.enable_nrt:\n            return" in decref
        and "cgutils.alloca_once(self.builder, lltype" in alloca
        and "builder.store(ty(None), ptr)" in alloca_once
    )


def _plain(lower) -> bool:
    """True where the patch applies: NRT off (``decref`` a no-op) and no debug info (which keeps
    and describes every slot)."""
    ctx = lower.context
    return not ctx.enable_nrt and not ctx.enable_debuginfo and not lower._disable_sroa_like_opt


def _storevar(self, value, name, argidx=None):
    """``Lower.storevar`` without the load of the old value for a no-op ``decref``."""
    if argidx is not None or not _plain(self):
        return _ORIGINAL["storevar"](self, value, name, argidx)
    self._alloca_var(name, self.typeof(name))
    if name in self._singly_assigned_vars:
        self._blk_local_varmap[name] = value
        return None
    ptr = self.getvar(name)
    if value.type != ptr.type.pointee:
        raise AssertionError(
            f"Storing {value.type} to ptr of {ptr.type.pointee} ('{name}'). "
            f"FE type {self.typeof(name)}"
        )
    self.builder.store(value, ptr)
    return None


def _delvar(self, name):
    """``Lower.delvar`` without the load for a no-op ``decref`` and the zero-fill (which guards
    only against a second ``decref``)."""
    if not _plain(self):
        return _ORIGINAL["delvar"](self, name)
    if name not in self._blk_local_varmap and name in self._singly_assigned_vars:
        self._singly_assigned_vars.discard(name)
    # a variable deleted before it is set (at a loop's head) still gets its slot, as in numba
    self._alloca_var(name, self.typeof(name))
    return None


def _alloca_lltype(self, name, lltype, datamodel=None):
    """``Lower.alloca_lltype`` -- a variable's slot -- without the zero store after the
    ``alloca`` for an aggregate (``cgutils.alloca_once`` stores zeros into every slot it makes, at
    the entry block).  Without NRT no ``decref`` reads a slot; a path that reads a variable before
    setting it is an error in Python (UnboundLocalError) whatever the slot holds (the engine's
    results stayed deterministic, bit for bit, run to run); scalar slots keep their zeros."""
    if not _plain(self) or not isinstance(lltype, (llvmir.LiteralStructType, llvmir.ArrayType)):
        return _ORIGINAL["alloca_lltype"](self, name, lltype, datamodel)
    with self.builder.goto_entry_block():
        return self.builder.alloca(lltype, name=name)


def install() -> bool:
    """Apply the patch once (idempotent); returns True if it is in place."""
    from numba.core import cgutils, lowering

    return apply(
        lowering.Lower,
        {"storevar": _storevar, "delvar": _delvar, "alloca_lltype": _alloca_lltype},
        "BRUSH_ENV_NUMBA_NRT_STORES",
        lambda: _recognised(lowering, cgutils),
        _ORIGINAL,
    )


def installed() -> bool:
    """True if numba lowers through the patched ``storevar``/``delvar``."""
    from numba.core import lowering

    return lowering.Lower.storevar is _storevar
