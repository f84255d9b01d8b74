"""What keeps a sweep's output directory whole when processes die or collide (issue 28).

* ``OutLock``: one sweep per ``--out`` at a time.  ``fcntl.flock`` on ``OUT/.lock``, which holds
  the holder's PID.  A second sweep on the directory raises ``SweepLocked`` (a ``UserError``:
  one line naming the holder's PID, exit code 2 on the command line).  The kernel drops a flock
  when the last descriptor of it closes, so a sweep that dies (even by SIGKILL) releases it;
  forked pool workers inherit the descriptor, so the lock is free only once they are gone too.
* ``write_text`` / ``write_bytes``: every file a sweep writes goes through a unique temp file in
  the same directory (``tempfile.mkstemp``), flushed and ``fsync``-ed, then ``os.replace``-d
  over the target: a reader (or a resume after a crash) sees the old file or the new one, never
  a part of one, and two writers never share a temp file.
* ``move_aside``: a damaged file is renamed to ``<name>.damaged-<UTC timestamp>`` (kept for a
  look, out of the way of the resume).
* ``watch_parent``: the pool workers' initializer; a worker stops when the sweep that started it
  dies (``PR_SET_PDEATHSIG`` and a watchdog thread, see its docstring).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os
import signal
import sys
import tempfile
import threading
import time
from pathlib import Path

from ..user_errors import UserError

LOCK_NAME = ".lock"
TMP_PREFIX = ".tmp-"


class SweepLocked(UserError):
    """Another sweep holds the output directory's lock."""


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


class OutLock:
    """``with OutLock(out):`` holds ``out/.lock`` (flock, exclusive, non-blocking) or raises
    ``SweepLocked`` naming the holder's PID."""

    def __init__(self, out, grace_s: float = 5.0) -> None:
        self.path = Path(out) / LOCK_NAME
        self.grace_s = grace_s  # how long to wait for the workers of a holder that died
        self.fd: int | None = None

    def acquire(self) -> None:
        import fcntl

        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        t_end = time.monotonic() + self.grace_s
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                holder = os.pread(fd, 64, 0).decode(errors="replace").strip() or "?"
                dead = holder.isdigit() and not _pid_alive(int(holder))
                if dead and time.monotonic() < t_end:
                    time.sleep(0.1)  # the holder died: its workers are stopping (PDEATHSIG)
                    continue
                os.close(fd)
                state = ", which has exited while its workers are still stopping" if dead else ""
                raise SweepLocked(
                    f"{self.path.parent} is in use by another sweep (pid {holder}{state}; lock "
                    f"{self.path}): wait for it to finish or stop it, then rerun to resume"
                ) from None
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        self.fd = fd

    def release(self) -> None:
        if self.fd is not None:
            os.close(self.fd)  # closing the descriptor drops the flock
            self.fd = None

    def __enter__(self) -> OutLock:
        self.acquire()
        return self

    def __exit__(self, *exc) -> None:
        self.release()


def write_bytes(path, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically: a unique temp file beside it, then os.replace."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f"{TMP_PREFIX}{path.name}.")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def write_text(path, text: str) -> None:
    write_bytes(path, text.encode())


def remove_stale_temps(out) -> int:
    """Delete temp files that a killed writer left in ``out`` and ``out/runs/*`` (call while
    holding the lock); returns how many."""
    out = Path(out)
    n = 0
    for p in [*out.glob(f"{TMP_PREFIX}*"), *out.glob(f"runs/*/{TMP_PREFIX}*")]:
        try:
            p.unlink()
            n += 1
        except FileNotFoundError:
            pass
    return n


def move_aside(path) -> Path:
    """Rename a damaged file to ``<name>.damaged-<UTC timestamp>``; returns the new path."""
    path = Path(path)
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    new = path.with_name(f"{path.name}.damaged-{stamp}")
    i = 1
    while new.exists():
        new = path.with_name(f"{path.name}.damaged-{stamp}-{i}")
        i += 1
    os.replace(path, new)
    return new


def _set_pdeathsig(sig: int) -> bool:
    """Ask Linux to send ``sig`` to this process when its parent dies (prctl PR_SET_PDEATHSIG)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6", use_errno=True)
        PR_SET_PDEATHSIG = 1
        return libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def watch_parent(sweep_pid: int, interval_s: float = 0.5) -> None:
    """Make this pool worker stop when the sweep that started it dies.

    * Linux: ``prctl(PR_SET_PDEATHSIG, SIGTERM)``: the kernel sends SIGTERM the moment the
      parent exits, even while the worker is deep in a numba kernel (SIGTERM's default action
      ends the process; nothing here catches it).  With the fork start method the parent is the
      sweep; with forkserver it is the fork server, which exits when the sweep does.
    * Everywhere: a daemon watchdog thread that checks ``os.getppid()`` every ``interval_s`` and
      ends the worker (``os._exit``) once it has been re-parented.  It needs the GIL, so it acts
      between kernel calls; it covers systems without prctl and the moment between the fork and
      the prctl call (checked once right after it as well).

    The kernel's "parent" is the thread that forked the worker: ``ProcessPoolExecutor`` forks
    from the thread that calls ``submit``, which outlives the pool in ``run_local``.
    """
    parent = os.getppid()
    _set_pdeathsig(signal.SIGTERM)
    orphaned = parent == 1 and sweep_pid != 1  # re-parented to init (a sweep may be PID 1)
    if os.getppid() != parent or orphaned or not _pid_alive(sweep_pid):
        os._exit(1)  # the sweep died before we could ask to be told

    def watch() -> None:
        while True:
            time.sleep(interval_s)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="sweep-parent-watchdog", daemon=True).start()
