"""numba's inlining without its defensive IR copies (``engine/numba_inline.py``) gives the same
machine code as numba as shipped: the set-up group's kernels (surface gaps, the shaft's capsule
clearance with its ``inline="always"`` helpers) compiled in two fresh caches, with the patch and
with ``BRUSH_ENV_NUMBA_COPY_IR=1``, hold the same object code and bitcode byte for byte."""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from pathlib import Path

import pytest

from brush_env.engine import numba_inline
from brush_env.engine.numba_patching import switched_off

_COMPILE = """
from brush_env.engine import numba_inline, warmup
print("installed" if numba_inline.installed() else "numba as shipped")
warmup.SETUP.run(warmup._Tiny())
"""


def _compile(cache: Path, copy_ir: bool) -> str:
    env = dict(os.environ, NUMBA_CACHE_DIR=str(cache))
    env.pop("BRUSH_ENV_NUMBA_COPY_IR", None)
    if copy_ir:
        env["BRUSH_ENV_NUMBA_COPY_IR"] = "1"
    out = subprocess.run(
        [sys.executable, "-c", _COMPILE], env=env, capture_output=True, text=True, check=True
    )
    return out.stdout.strip()


def _machine_code(cache: Path) -> dict[str, tuple[bytes, bytes]]:
    """{kernel file: (object code, bitcode)} of every kernel numba cached under ``cache``."""
    code = {}
    for f in sorted(cache.rglob("*.nbc")):
        libdata = pickle.loads(f.read_bytes())[0]  # CompileResult._reduce: (name, kind, data)
        obj, bitcode = libdata[2]
        code[f.name] = (obj, bitcode)
    return code


def test_patch_applies_to_this_numba():
    """The pinned numba is the code the patch was written against (else it stays off: the
    first start's compile doubles, and this test says so)."""
    if switched_off("BRUSH_ENV_NUMBA_COPY_IR"):
        pytest.skip("switched off by BRUSH_ENV_NUMBA_COPY_IR")
    assert numba_inline.installed()


def test_same_machine_code_with_and_without_the_copies(tmp_path):
    patched, shipped = tmp_path / "patched", tmp_path / "shipped"
    assert _compile(patched, copy_ir=False) == "installed"
    assert _compile(shipped, copy_ir=True) == "numba as shipped"
    a, b = _machine_code(patched), _machine_code(shipped)
    assert len(a) >= 10  # the set-up group's kernels (12 on 2026-12-07)
    assert a.keys() == b.keys()
    differ = [k for k in a if a[k] != b[k]]
    assert not differ, f"machine code differs for {differ}"
