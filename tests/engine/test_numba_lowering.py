"""numba's lowering without NRT's dead loads and zero-fills (``engine/numba_lowering.py``).

A kernel compiled without NRT that keeps a record of arrays (the engine's argument bundles) in a
variable across blocks: with numba as shipped (``BRUSH_ENV_NUMBA_NRT_STORES=1``) its IR, before
LLVM optimises it, zero-fills the record's slot at the entry block and at every ``del`` and loads
the whole record before each store (for a ``decref`` that does nothing without NRT); with the
patch none of that is emitted, and the kernel computes the same numbers, bit for bit."""

from __future__ import annotations

import pytest

from brush_env.engine import numba_lowering
from brush_env.engine.numba_patching import switched_off

from .numba_patch_script import run_script

_KERNEL = r"""
import json, re
from collections import namedtuple
import numpy as np
from numba import njit
from numba.core import codegen
from brush_env.engine import numba_lowering

IR = []
_orig = codegen.CPUCodeLibrary._optimize_functions
def _capture(self, mod):
    IR.append(str(mod))
    return _orig(self, mod)
codegen.CPUCodeLibrary._optimize_functions = _capture

Rec = namedtuple("Rec", ["a", "b", "c"])

@njit(_nrt=False)
def kernel(rec, n):
    s = 0.0
    for i in range(n):
        r = rec if i % 3 else Rec(rec.c, rec.b, rec.a)  # a record variable set in two blocks
        if i % 2:
            s += r.a[i] * r.b[i] + r.c[i]
        else:
            s -= np.sqrt(abs(r.c[i] * r.a[i])) / (1.0 + r.b[i])
    return s

rng = np.random.default_rng(7)
rec = Rec(rng.standard_normal(64), rng.standard_normal(64), rng.standard_normal(64))
value = kernel(rec, 64)
ir = next(t for t in IR if "kernel" in t and "define" in t)
body = ir[ir.index("define"):]
# whole-record zero stores and loads: of an aggregate of array structs (the record of three arrays,
# [3 x {...}]; numba's own temporaries -- an array, a range iterator -- are flat structs)
RECORD = r"(\{ \{|\[\d+ x \{)"
zero = len(re.findall(r"store " + RECORD + r"[^\n]*zeroinitializer", body))
loads = len(re.findall(r"= load " + RECORD, body))
print(json.dumps({"installed": numba_lowering.installed(), "value": value.hex(),
                  "record_zero_stores": zero, "record_loads": loads}))
"""


def _run(shipped: bool, tmp_path) -> dict:
    return run_script(_KERNEL, "BRUSH_ENV_NUMBA_NRT_STORES", shipped, tmp_path)


def test_patch_applies_to_this_numba():
    """The pinned numba is the code the patch was written against (else it stays off: LLVM's
    share of the first start's compile grows by half, and this test says so)."""
    if switched_off("BRUSH_ENV_NUMBA_NRT_STORES"):
        pytest.skip("switched off by BRUSH_ENV_NUMBA_NRT_STORES")
    assert numba_lowering.installed()


def test_no_record_zero_fills_and_the_same_result(tmp_path):
    patched, shipped = _run(False, tmp_path), _run(True, tmp_path)
    assert patched["installed"] and not shipped["installed"]
    # numba as shipped: the record's slot zero-filled (entry, each del) and loaded whole
    assert shipped["record_zero_stores"] >= 2
    assert patched["record_zero_stores"] == 0
    assert patched["record_loads"] < shipped["record_loads"]
    assert patched["value"] == shipped["value"]  # the same double, bit for bit
