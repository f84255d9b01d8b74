"""Where the runs of a sweep go: a local process pool (default) or a Ray cluster (issue 16).

Both take the same jobs (``run.prepare``) and the same function (``run.execute``), which writes
each run's files itself, so the results do not depend on the executor: a run's ``summary.json``
is byte-identical on either (tests/sweeps).

* ``local``: ``concurrent.futures.ProcessPoolExecutor`` with ``workers`` processes (default all
  cores).  Each worker loads the numba kernels once, from the disk cache that the first
  ``ensure_compiled`` filled (``init_worker``).  A worker stops when the sweep dies, even by
  SIGKILL (``safety.watch_parent``: ``PR_SET_PDEATHSIG`` on Linux plus a watchdog thread on
  ``os.getppid()``), so no orphan keeps writing into ``--out``.
* ``ray``: ``ray.init(address)``, where address is ``"auto"`` for a running cluster,
  ``"HOST:PORT"``, or ``"local"`` for a fresh local instance.  One remote task per run, with the
  numba cache warmed in each task; results are gathered with ``ray.wait``.  Ray is the optional
  extra ``[cluster]``, pinned in pyproject.toml.

Progress: a tqdm bar with ETA over the runs still to do; ``on_result`` is called as each run
finishes (the table is rewritten then, so an interrupted sweep keeps what it finished).
"""

from __future__ import annotations

import os
from collections.abc import Callable

from .run import execute


def init_worker(sweep_pid: int | None = None) -> None:
    """Load (or compile once) the numba kernels in a worker before its first run.  In a pool
    worker (``sweep_pid`` given), first arrange for the worker to stop when the sweep dies
    (``safety.watch_parent``: PR_SET_PDEATHSIG and a watchdog thread)."""
    if sweep_pid is not None:
        import warnings

        from ..user_errors import one_line_show
        from .safety import watch_parent

        watch_parent(sweep_pid)
        # a warning in a worker is one plain line on the shared stderr: no source line, and no
        # tqdm.write, which would redraw the copy of the sweep's bar this forked worker holds
        warnings.showwarning = one_line_show(lambda text, file: print(text, file=file, flush=True))
    from ..engine.warmup import ensure_compiled

    ensure_compiled()


def _bar(total: int, progress: bool):
    from tqdm import tqdm

    return tqdm(total=total, unit="run", desc="sweep", disable=not progress, smoothing=0.1)


def run_local(jobs: list, workers: int | None, on_result: Callable, progress: bool = True) -> None:
    from concurrent.futures import ProcessPoolExecutor, as_completed

    workers = workers or os.cpu_count() or 1
    if not jobs:
        return
    from ..engine.warmup import ensure_compiled

    # a first compile here, once, with its progress lines, before the bar and the workers (which
    # then load the kernels from the cache instead of each compiling them at once)
    ensure_compiled(notice=print if progress else None)
    with _bar(len(jobs), progress) as bar:
        if workers == 1:
            init_worker()
            for job in jobs:
                on_result(execute(job))
                bar.update(1)
            return
        with ProcessPoolExecutor(
            max_workers=workers, initializer=init_worker, initargs=(os.getpid(),)
        ) as pool:
            futures = [pool.submit(execute, job) for job in jobs]
            for f in as_completed(futures):
                on_result(f.result())
                bar.update(1)


def run_ray(jobs: list, address: str, on_result: Callable, progress: bool = True) -> None:
    try:
        import ray
    except ImportError:
        raise RuntimeError(
            "--ray-address needs Ray: pip install -e '.[cluster]' (ray is an optional extra)"
        ) from None
    if not jobs:
        return
    started = False
    if not ray.is_initialized():
        if address == "local":
            ray.init(include_dashboard=False, log_to_driver=False)
        else:
            ray.init(address=address, log_to_driver=False)
        started = True

    remote = ray.remote(_ray_task)
    try:
        pending = [remote.remote(job) for job in jobs]
        with _bar(len(jobs), progress) as bar:
            while pending:
                ready, pending = ray.wait(pending, num_returns=1)
                for ref in ready:
                    on_result(ray.get(ref))
                    bar.update(1)
    finally:
        if started:
            ray.shutdown()


def _ray_task(job: dict) -> dict:
    init_worker()
    return execute(job)
