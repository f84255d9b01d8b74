"""numba's loading of a cached kernel without the compiler's lowering registries
(``engine/numba_loading.py``).

Two fresh interpreters share one cache: the first compiles a kernel and writes it, the second
loads it.  With the patch the load installs none of numba's lowering registries (numpy's
``arraymath``, the polynomial and linear-algebra implementations are not even imported), the
loaded kernel gives the same double as the compiled one, and a kernel compiled afterwards in the
same process (a cache miss, using ``np.sort`` from those registries) still compiles and runs:
numba's compile refreshes the registries itself.  With numba as shipped
(``BRUSH_ENV_NUMBA_REFRESH=1``) the load imports them."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

from brush_env.engine import numba_loading
from brush_env.engine.numba_patching import switched_off

_SCRIPT = r"""
import json, sys
import numpy as np
from numba import njit
from brush_env.engine import numba_loading

@njit(cache=True, _nrt=False)
def cached(x):
    s = 0.0
    for i in range(x.shape[0]):
        s += x[i] * x[i] - np.sqrt(abs(x[i]))
    return s

value = cached(np.linspace(-1.0, 2.0, 7))
hit = sum(cached.stats.cache_hits.values()) > 0
registries = [m for m in ("numba.np.arraymath", "numba.np.linalg",
                          "numba.np.polynomial.polynomial_functions") if m in sys.modules]

@njit
def compiled_after(x):
    return np.sort(x)[0]

after = compiled_after(np.array([3.0, -1.5, 2.0]))
print(json.dumps({"installed": numba_loading.installed(), "value": value.hex(), "hit": hit,
                  "registries": registries, "after": after}))
"""


def _twice(shipped: bool, tmp_path) -> tuple[dict, dict]:
    """The script's report from its first run (compiles, writes the cache) and its second
    (loads), both in one fresh cache."""
    script = tmp_path / "kernel.py"
    script.write_text(_SCRIPT)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    env.pop("BRUSH_ENV_NUMBA_REFRESH", None)
    if shipped:
        env["BRUSH_ENV_NUMBA_REFRESH"] = "1"
    runs = []
    for _ in range(2):
        out = subprocess.run(
            [sys.executable, str(script)], env=env, capture_output=True, text=True, check=True
        )
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    return runs[0], runs[1]


def test_patch_applies_to_this_numba():
    """The pinned numba is the code the patch was written against (else it stays off: every warm
    start pays ~0.37 s more, and this test says so)."""
    if switched_off("BRUSH_ENV_NUMBA_REFRESH"):
        pytest.skip("switched off by BRUSH_ENV_NUMBA_REFRESH")
    assert numba_loading.installed()


@pytest.mark.parametrize("shipped", [False, True], ids=["patched", "shipped"])
def test_load_without_registries_then_compile(shipped, tmp_path):
    first, second = _twice(shipped, tmp_path)
    assert second["installed"] is not shipped
    assert not first["hit"] and second["hit"]  # the second run loaded the kernel
    assert second["value"] == first["value"]
    # a kernel compiled after the load, in the same process, from the registries' code
    assert first["after"] == second["after"] == -1.5
    if shipped:
        assert "numba.np.arraymath" in second["registries"]
    else:
        assert second["registries"] == []
