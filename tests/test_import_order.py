"""Every module of the package imports on its own in a fresh interpreter (no import order a user
must know): e.g. ``from brush_env.geometry.sdf_bake import bake_mesh`` before anything else once
met its own half-initialised module through the engine's package init."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow  # ~40 s: one fresh interpreter per module
def test_every_module_imports_first_in_a_fresh_interpreter():
    mods = sorted(
        ".".join(p.relative_to(ROOT).with_suffix("").parts)
        for p in (ROOT / "brush_env").rglob("*.py")
        if p.name != "__init__.py" and "__pycache__" not in p.parts
    )
    code = (
        "import importlib, subprocess, sys\n"
        "bad = []\n"
        "for m in sys.argv[1:]:\n"
        "    r = subprocess.run([sys.executable, '-c', f'import {m}'], capture_output=True,"
        " text=True)\n"
        "    if r.returncode:\n"
        "        bad.append(m + ': ' + r.stderr.strip().splitlines()[-1])\n"
        "print('\\n'.join(bad))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, *mods], capture_output=True, text=True, cwd=ROOT, timeout=900
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "", out.stdout
