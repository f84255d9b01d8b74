"""Is numba's kernel cache warm for these engine sources?  (No numba, no engine import: a command
can ask within milliseconds of starting and announce the first-start compile before anything
else.)  ``brush_env.engine.warmup`` compiles and writes the stamp this module reads."""

from __future__ import annotations

import hashlib
import json
import os
import sys
from collections.abc import Iterable
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

ENGINE = Path(__file__).resolve().parent / "engine"
STAMP_NAME = "brush_env_kernels.stamp"
#: the stamp of the cache beside the sources; a ``NUMBA_CACHE_DIR`` cache has its own, in it
STAMP = ENGINE / "__pycache__" / STAMP_NAME
#: The compile profile this machine measured (``engine.compile_progress``), beside numba's cache
MACHINE_PROFILE = ENGINE / "__pycache__" / "brush_env_compile_profile.json"
#: ... and the one measured on the project's machine, shipped, until this machine has its own
SHIPPED_PROFILE = ENGINE / "compile_profile.json"

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


def _stamp_path(cache_dir: Path | None = None) -> Path:
    """The stamp of the engine's cache in ``cache_dir`` (one of ``engine_cache_dirs``; None: the
    one numba uses now, under ``NUMBA_CACHE_DIR`` when it is set).  Each cache directory has its
    own: a process with another ``NUMBA_CACHE_DIR`` must not take this one's stamp for its
    own (it did: the stamp beside the sources said "current" for a cache under
    NUMBA_CACHE_DIR that no process had purged after an edit, which then ran stale code)."""
    d = cache_dir if cache_dir is not None else engine_cache_dirs()[-1]
    return STAMP if d == ENGINE / "__pycache__" else d / STAMP_NAME


def _stamp(cache_dir: Path | None = None) -> tuple[str, set[str]]:
    """(sources key, names of the kernel groups compiled for it) of the stamp of the cache in
    ``cache_dir`` (None: the one in use); ("", set())."""
    try:
        key, *groups = _stamp_path(cache_dir).read_text().splitlines()
    except (OSError, ValueError):
        return "", set()
    return key.strip(), {g for g in groups if g}


def kernels_compiled(groups: Iterable[str] | None = None) -> bool:
    """True if a warm-up ran on these exact sources (the numba cache is then warm) and, when
    ``groups`` (names of ``engine.warmup`` kernel groups) are given, compiled every one of them."""
    key, done = _stamp()
    return key == sources_key() and (groups is None or set(groups) <= done)


def engine_cache_dirs() -> list[Path]:
    """Where numba keeps the engine's cached kernels: beside the sources, and under
    ``NUMBA_CACHE_DIR`` when it is set (numba's user-provided locator names the directory
    ``<parent dir name>_<sha1 of the source directory's absolute path>``)."""
    dirs = [ENGINE / "__pycache__"]
    user = os.environ.get("NUMBA_CACHE_DIR")
    if user:
        src = os.path.abspath(ENGINE)
        dirs.append(Path(user) / f"{ENGINE.name}_{hashlib.sha1(src.encode()).hexdigest()}")
    return dirs


def purge_stale_kernels() -> int:
    """Delete the engine's cached kernels (``*.nbi``, ``*.nbc``) in each of
    ``engine_cache_dirs`` whose stamp is not of the sources as they are now, then stamp it;
    returns the number of files deleted.

    numba checks a cached kernel against its own source file's timestamp only.  A kernel that
    calls into another module carries the callee's machine code in its own cache entry
    (``prb_rollout.rollout`` -> ``prb_kernels``, ``sweeps`` -> ``newton`` -> ``_kernels``), so
    after the callee's module alone changed, a cached caller kept running the old physics, with
    nothing said (found twice while editing the reduced model; a ``git pull`` into an editable
    install does the same).  The price: any change to the engine's sources compiles every
    engine kernel again."""
    key_now = sources_key()
    removed = 0
    for d in engine_cache_dirs():
        if _stamp(d)[0] == key_now:
            continue
        for p in sorted(d.glob("*.nb[ic]")):
            try:
                p.unlink()
                removed += 1
            except OSError:  # another process deleted it, or a read-only install
                pass
        _write(_stamp_path(d), [key_now])
    return removed


def read_profile() -> tuple[dict, str]:
    """(profile, where it was measured: "this machine" or "the project's machine"); ({}, "")
    when neither file can be read."""
    for path, where in (
        (MACHINE_PROFILE, "this machine"),
        (SHIPPED_PROFILE, "the project's machine"),
    ):
        try:
            prof = json.loads(path.read_text())
        except (OSError, ValueError):
            continue
        if isinstance(prof, dict) and isinstance(prof.get("groups"), dict):
            return prof, where
    return {}, ""


def compile_notice() -> str:
    """The line shown before a compile: the last compile's time when this machine measured one;
    otherwise a promise of the progress lines (whose estimate is measured as they go)."""
    prof, where = read_profile()
    total = sum(float(g.get("seconds", 0.0)) for g in prof.get("groups", {}).values())
    if where == "this machine" and total > 0:
        took = (
            f"{total:.0f} s here last time"
            if total < 120
            else f"{total / 60:.1f} min here last time"
        )
        what = f"{took}; progress every 10 s"
    else:
        what = "progress and an estimate from this machine's speed every 10 s"
    return f"compiling numba kernels, first run only ({what}; `brush-env warmup` does it ahead)"


def to_stderr(text: str) -> None:
    """Print ``text`` on stderr at once (a command's --json stdout stays parseable)."""
    print(text, file=sys.stderr, flush=True)


def announce(notice=to_stderr, groups: Iterable[str] | None = None) -> None:
    """Print the compile notice once per process if the kernels (of ``groups``) are not compiled
    yet (to stderr by default, so that a command's --json output on stdout stays parseable)."""
    global _announced
    if not _announced and notice is not None and not kernels_compiled(groups):
        notice(compile_notice())
        sys.stdout.flush()
        _announced = True


def write_stamp(groups: Iterable[str] = (), profile: dict | None = None) -> None:
    """Record that the kernel ``groups`` are compiled for the current sources (with those the
    stamp already holds for them), and the compile's ``profile`` (``engine.compile_progress``:
    the next compile's estimate on this machine)."""
    key, done = _stamp()
    key_now = sources_key()
    names = (done if key == key_now else set()) | set(groups)
    _write(_stamp_path(), [key_now, *sorted(names)])
    if profile:
        _write(MACHINE_PROFILE, [json.dumps(profile, indent=1)])


def _write(path: Path, lines: list[str]) -> None:
    """Write the lines to ``path`` (its directory made); a read-only install still works, it
    only compiles again next time."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("\n".join(lines) + "\n")
    except OSError:
        pass
