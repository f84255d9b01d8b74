"""Run a script in a fresh interpreter and cache, with one of the engine's numba patches on or
switched off (numba as shipped): what the ``test_numba_*`` patch tests compare."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path


def run_script(script: str, switch: str, shipped: bool, tmp_path: Path) -> dict:
    """The JSON object the script prints last, run with the environment variable ``switch`` set
    to 1 (``shipped``: numba as shipped) or unset, in its own ``NUMBA_CACHE_DIR``."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / ("shipped" if shipped else "patched")))
    env.pop(switch, None)
    if shipped:
        env[switch] = "1"
    out = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])
