"""Every module of the package imports on its own in a fresh interpreter (no import order a user
must know): e.g. ``from brush_env.geometry.sdf_bake import bake_mesh`` before anything else once
met its own half-initialised module through the engine's package init."""

from __future__ import annotations

import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _import_alone(module: str) -> str | None:
    """None if ``module`` imports first in a fresh interpreter, else its last error line."""
    r = subprocess.run(
        [sys.executable, "-c", f"import {module}"],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=300,
    )
    return None if r.returncode == 0 else module + ": " + r.stderr.strip().splitlines()[-1]


@pytest.mark.slow  # ~60 s of interpreters, one per module, run two at a time
def test_every_module_imports_first_in_a_fresh_interpreter():
    mods = sorted(
        ".".join(p.relative_to(ROOT).with_suffix("").parts)
        for p in (ROOT / "brush_env").rglob("*.py")
        if p.name != "__init__.py" and "__pycache__" not in p.parts
    )
    with ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 1)) as pool:
        bad = [b for b in pool.map(_import_alone, mods) if b]
    assert bad == []
