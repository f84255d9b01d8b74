"""Progress of the first-start numba compile: the kernel group, k of n, the elapsed time and an
estimate from this machine's own speed, on one line at least every ``interval`` seconds.

Why an estimate needs a profile: numba compiles a kernel (with every kernel it calls) on its
first call, so one warm-up group may take two minutes while the next takes none; a fixed figure
was off by 2.5x on a loaded machine (issue 31).  numba announces every kernel it compiles
(``numba.core.event``, kind ``"numba:compile"``: on cache misses only).  A *profile* records,
for each group of a warm-up, its seconds and the second (into the group) at which each kernel
finished compiling.  While a compile runs, each finished kernel that the profile knows is a
milestone: the actual seconds to reach it over the profile's seconds is this machine's speed now,
and the estimate is the profile's total times that speed.  The profile shipped with the package
(``compile_profile.json``, measured on the project's machine) serves until a compile here has
measured this machine's own (``kernel_cache.write_stamp`` stores it beside numba's cache).

Units: seconds.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Sequence

__all__ = ["CompileProgress", "KernelListener", "format_seconds"]

#: kernels numba compiles for itself (overloads of builtins) are no milestone of ours
_NUMBA_INTERNAL = "numba."


def format_seconds(s: float) -> str:
    """``45 s`` below two minutes, ``2.5 min`` above (the user reads a figure, not a timestamp)."""
    return f"{s:.0f} s" if s < 120 else f"{s / 60:.1f} min"


class CompileProgress:
    """Tracks a warm-up: which group runs, which kernels finished compiling, and the estimate.

    ``groups``: the names of the warm-up's groups, in order; ``profile``: ``{"groups": {name:
    {"seconds": s, "kernels": {milestone: seconds into the group}}}}`` (None or {}: no estimate
    until this machine's own figures exist); ``notice``: where a line goes (None: nowhere);
    ``clock``: seconds (a fake one in tests).  :meth:`measured` returns the profile this run
    measured, to be stored for the next compile on this machine.
    """

    def __init__(
        self,
        groups: Sequence[str],
        profile: dict | None,
        notice: Callable[[str], None] | None,
        clock: Callable[[], float] = time.perf_counter,
    ) -> None:
        self.groups = list(groups)
        self.notice = notice
        self.clock = clock
        known = (profile or {}).get("groups", {})
        self._profile = {g: known[g] for g in self.groups if g in known}
        # the ticker thread reads what the compiling thread writes (re-entrant: status -> estimate)
        self._lock = threading.RLock()
        self._t0 = clock()
        self._k = -1  # index of the running group
        self._t_group = self._t0
        self._done_actual = 0.0  # seconds of the finished groups (those the profile knows)
        self._done_profile = 0.0  # ... and what the profile gave them
        self._last: tuple[float, float] | None = None  # (actual, profile) s into the group
        self._counts: dict[str, int] = {}
        self._kernels_done = 0
        self._compiled_in_group = 0
        self._stack: list[str] = []  # kernels being compiled, innermost last (nested calls)
        self._measured: dict[str, dict] = {}

    # ---------------------------------------------------------------- events
    def start_group(self, k: int) -> None:
        """Group ``k`` (0-based) starts."""
        with self._lock:
            self._k = k
            self._t_group = self.clock()
            self._last = None
            self._counts = {}
            self._compiled_in_group = 0
            self._measured[self.groups[k]] = {"seconds": 0.0, "kernels": {}}

    def end_group(self) -> None:
        """The running group ended; says so if it compiled anything."""
        with self._lock:
            name = self.groups[self._k]
            took = self.clock() - self._t_group
            self._measured[name]["seconds"] = took
            if name in self._profile:
                self._done_actual += took
                self._done_profile += float(self._profile[name]["seconds"])
            self._last = None  # the whole group now counts, not its last milestone
            compiled = self._compiled_in_group
        if compiled and self.notice is not None:
            self.notice(
                f"  compile {self._k + 1}/{len(self.groups)} done: {name} "
                f"({compiled} kernels in {format_seconds(took)})"
            )

    def kernel_started(self, name: str) -> None:
        """numba starts compiling kernel ``name`` (module.qualname)."""
        if not name.startswith(_NUMBA_INTERNAL):
            with self._lock:
                self._stack.append(name)

    def kernel_done(self, name: str) -> None:
        """numba finished compiling kernel ``name``: a milestone if the profile knows it."""
        if name.startswith(_NUMBA_INTERNAL) or self._k < 0:
            return
        with self._lock:
            if self._stack and self._stack[-1] == name:
                self._stack.pop()
            n = self._counts.get(name, 0) + 1  # a kernel compiled for a second signature
            self._counts[name] = n
            key = f"{name}#{n}"
            now = self.clock() - self._t_group
            group = self.groups[self._k]
            self._measured[group]["kernels"][key] = now
            self._kernels_done += 1
            self._compiled_in_group += 1
            ref = self._profile.get(group, {}).get("kernels", {}).get(key)
            if ref is not None:
                self._last = (now, float(ref))

    # ---------------------------------------------------------------- figures
    def estimate(self) -> float | None:
        """Estimated seconds of the whole warm-up on this machine, or None (nothing to go by:
        no profile, or no milestone reached yet)."""
        with self._lock:
            actual, prof = self._done_actual, self._done_profile
            if self._last is not None:
                actual += self._last[0]
                prof += self._last[1]
            total = sum(float(p["seconds"]) for p in self._profile.values())
        if prof < 0.2 or total <= 0:  # too little done to measure a speed
            return None
        return total * actual / prof

    def kernels_expected(self) -> int | None:
        n = sum(len(p.get("kernels", {})) for p in self._profile.values())
        return n or None

    def status(self) -> str:
        """One line: group k/n and its name, elapsed, kernels done (of those expected), the
        kernel being compiled, and the estimate."""
        with self._lock:
            elapsed = self.clock() - self._t0
            k, current = max(self._k, 0), (self._stack[-1] if self._stack else "")
            done = f"{self._kernels_done}"
            est = self.estimate()
        expected = self.kernels_expected()
        done += f" of ~{expected}" if expected else ""
        if est is None:
            guess = "estimate after the first kernels"
        elif est > elapsed:
            guess = f"about {format_seconds(est - elapsed)} left of ~{format_seconds(est)}"
        else:
            guess = f"taking longer than the ~{format_seconds(est)} estimated"
        now = f"; now {current.removeprefix('brush_env.')}" if current else ""
        return (
            f"  compile {k + 1}/{len(self.groups)}: {self.groups[k]}; "
            f"{format_seconds(elapsed)} elapsed, {done} kernels{now}; {guess}"
        )

    def measured(self) -> dict:
        """The profile this run measured ({"groups": ...}), for the next compile here."""
        with self._lock:
            return {"groups": {g: dict(v) for g, v in self._measured.items()}}

    # ---------------------------------------------------------------- ticker
    def ticker(self, interval: float) -> _Ticker:
        """A context manager: prints :meth:`status` every ``interval`` s from a thread."""
        return _Ticker(self, interval)


class _Ticker:
    def __init__(self, progress: CompileProgress, interval: float) -> None:
        self.progress = progress
        self.interval = float(interval)
        self._stop = threading.Event()
        # a daemon thread: an interrupted compile (Ctrl-C) must not wait for it
        self._thread = threading.Thread(target=self._run, name="compile-ticker", daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            if self.progress.notice is not None:
                self.progress.notice(self.progress.status())

    def __enter__(self) -> _Ticker:
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()


class KernelListener:
    """numba's ``"numba:compile"`` events forwarded to a :class:`CompileProgress`."""

    def __init__(self, progress: CompileProgress) -> None:
        from numba.core import event

        class _Listener(event.Listener):
            def on_start(self, ev) -> None:
                progress.kernel_started(_kernel_name(ev))

            def on_end(self, ev) -> None:
                progress.kernel_done(_kernel_name(ev))

        self._event = event
        self._listener = _Listener()

    def __enter__(self) -> KernelListener:
        self._event.register("numba:compile", self._listener)
        return self

    def __exit__(self, *exc) -> None:
        self._event.unregister("numba:compile", self._listener)


def _kernel_name(ev) -> str:
    fn = getattr(ev.data.get("dispatcher"), "py_func", None)
    if fn is None:
        return _NUMBA_INTERNAL + "?"
    return f"{fn.__module__}.{fn.__qualname__}"
