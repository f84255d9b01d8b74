"""Is numba's kernel cache warm for these engine sources?  (No numba, no engine import: a command
can ask within milliseconds of starting and announce the first-start compile before anything
else.)  ``brush_env.engine.warmup`` compiles and writes the stamp this module reads."""

from __future__ import annotations

import hashlib
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

ENGINE = Path(__file__).resolve().parent / "engine"
STAMP = ENGINE / "__pycache__" / "brush_env_kernels.stamp"

#: Shown before the first compile; the figure is the measured first start (docs/benchmarks.md).
COMPILE_NOTICE = (
    "compiling numba kernels, first run only (~1.5 min; `brush-env warmup` does it ahead)"
)

_announced = False


def sources_key() -> str:
    """Hash of the engine sources, their timestamps (numba's cache is keyed on them) and the
    numba/numpy/python versions."""
    h = hashlib.sha256()
    for p in sorted(ENGINE.glob("*.py")):
        h.update(p.name.encode())
        h.update(p.read_bytes())
        h.update(str(p.stat().st_mtime_ns).encode())
    for pkg in ("numba", "numpy"):
        try:
            h.update(version(pkg).encode())
        except PackageNotFoundError:
            pass
    h.update(sys.version.encode())
    return h.hexdigest()


def kernels_compiled() -> bool:
    """True if the warm-up ran on these exact sources (the numba cache is then warm)."""
    try:
        return STAMP.read_text().strip() == sources_key()
    except OSError:
        return False


def _to_stderr(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def announce(notice=_to_stderr) -> None:
    """Print the compile notice once per process if the kernels are not compiled yet (to stderr
    by default, so that a command's --json output on stdout stays parseable)."""
    global _announced
    if not _announced and notice is not None and not kernels_compiled():
        notice(COMPILE_NOTICE)
        sys.stdout.flush()
        _announced = True


def write_stamp() -> None:
    """Record that the kernels are compiled for the current sources."""
    try:
        STAMP.parent.mkdir(exist_ok=True)
        STAMP.write_text(sources_key())
    except OSError:  # a read-only install still works, it only compiles again next time
        pass
