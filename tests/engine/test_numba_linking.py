"""numba's linking of a kernel's callees as internal copies (``engine/numba_linking.py``).

A kernel that calls another with a record of arrays (the engine's argument bundles): with numba
as shipped (``BRUSH_ENV_NUMBA_LINKONCE=1``) the callee sits in the caller's optimised module as a
``linkonce_odr`` function taking every field of the record; with the patch no copy of it keeps
that linkage (LLVM inlined it or holds it as an internal function), the caller's own entry
points keep theirs, and the kernel computes the same numbers, bit for bit (no fast-math here:
nothing may be contracted across the old call)."""

from __future__ import annotations

import pytest

from brush_env.engine import numba_linking
from brush_env.engine.numba_patching import switched_off

from .numba_patch_script import run_script

_KERNEL = r"""
import json
from collections import namedtuple
import numpy as np
from numba import njit
from numba.core import codegen
from brush_env.engine import numba_linking

# the linkage of the callee's copy in the caller's module as LLVM's optimisation starts
SEEN = {}
def _spy(orig):
    def optimize(self):
        for f in self._final_module.functions:
            if "caller" in self.name and "6callee" in f.name and not f.is_declaration:
                SEEN[f.name] = f.linkage.name
        return orig(self)
    return optimize
if numba_linking.installed():
    numba_linking._ORIGINAL["_optimize_final_module"] = _spy(
        numba_linking._ORIGINAL["_optimize_final_module"])
else:
    codegen.CPUCodeLibrary._optimize_final_module = _spy(
        codegen.CPUCodeLibrary._optimize_final_module)

Rec = namedtuple("Rec", ["a", "b", "c", "d"])

@njit(_nrt=False)
def callee(rec, i):
    # reads two of the record's four arrays
    return rec.a[i] * rec.b[i] - np.sqrt(abs(rec.a[i]))

@njit(_nrt=False)
def caller(rec, n):
    s = 0.0
    for i in range(n):
        s += callee(rec, i)
    return s

rng = np.random.default_rng(3)
rec = Rec(*(rng.standard_normal(50) for _ in range(4)))
value = caller(rec, 50)
own = [f.linkage.name for f in caller.overloads[next(iter(caller.overloads))].library
       ._final_module.functions if "6caller" in f.name and not f.is_declaration]
print(json.dumps({"installed": numba_linking.installed(), "value": value.hex(),
                  "callee": sorted(SEEN.values()), "own": own}))
"""


def _run(shipped: bool, tmp_path) -> dict:
    return run_script(_KERNEL, "BRUSH_ENV_NUMBA_LINKONCE", shipped, tmp_path)


def test_patch_applies_to_this_numba():
    """The pinned numba is the code the patch was written against (else it stays off: the step
    takes ~14 % more instructions, and this test says so)."""
    if switched_off("BRUSH_ENV_NUMBA_LINKONCE"):
        pytest.skip("switched off by BRUSH_ENV_NUMBA_LINKONCE")
    assert numba_linking.installed()


def test_callee_internal_and_the_same_result(tmp_path):
    patched, shipped = _run(False, tmp_path), _run(True, tmp_path)
    assert patched["installed"] and not shipped["installed"]
    # numba as shipped: the callee's functions linked in as linkonce_odr (every field of the
    # record an argument that LLVM may not remove); patched: internal copies
    assert shipped["callee"] and set(shipped["callee"]) == {"linkonce_odr"}
    assert patched["callee"] and set(patched["callee"]) == {"internal"}
    # the caller's own functions keep their linkage (the JIT looks them up by name)
    assert patched["own"] and "internal" not in patched["own"]
    assert patched["value"] == shipped["value"]  # the same double, bit for bit
