"""Shared benchmark harness: machine line, cold-start measurement (first-start numba compile in a
fresh process), best-of-repeats timing and Markdown tables.  Every target prints its table with
the machine line (time, error, settings, machine); timings never enter pass/fail tests.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def open_log(args):
    """The stream for progress and the machine line (stderr with ``--json``, so that stdout holds
    only the JSON rows; else stdout), with the machine line printed on it."""
    log = sys.stderr if args.json else sys.stdout
    print_machine(log)
    return log


def print_machine(log) -> None:
    """One line of ``machine_info``, on ``log``."""
    print("machine: " + "; ".join(f"{k}={v}" for k, v in machine_info().items()), file=log)


def emit(args, row: dict) -> dict:
    """``row`` as a JSON line on stdout with ``--json``; returns it."""
    if args.json:
        print(json.dumps(row), flush=True)
    return row


def machine_info() -> dict:
    """Platform, CPU model, cores (total and usable by this process), versions, git commit."""
    import numba

    cpu = platform.processor() or "unknown"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    root = Path(__file__).resolve().parents[2]

    def git(*a):
        try:
            return subprocess.run(
                ["git", *a], cwd=root, capture_output=True, text=True, timeout=10
            ).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--untracked-files=no", "brush_env"):
        commit += " (+ uncommitted changes in brush_env/)"
    return {
        "platform": platform.platform(),
        "cpu": cpu,
        "cores": os.cpu_count(),
        "cores_usable": usable,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "commit": commit,
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
    }


_COLD = """
import time, numpy as np
t0 = time.perf_counter()
from brush_env.engine import Simulator, SimSettings, load_brush
t1 = time.perf_counter()
sim = Simulator(load_brush(), SimSettings())
sim.reset(np.array([0.0, 0.0, 10.0]), np.diag([1.0, -1.0, -1.0]))
sim.step(np.array([0.0, 0.0, 10.0]), np.diag([1.0, -1.0, -1.0]))
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


COLD_CONTACT = """
import time, numpy as np
t0 = time.perf_counter()
from brush_env.engine import Simulator, SimSettings, load_scene
t1 = time.perf_counter()
sim = Simulator(load_scene("flat_plate"), SimSettings())
sim.reset(np.array([0.0, 0.0, 12.0]), np.diag([1.0, -1.0, -1.0]))
sim.step(np.array([0.0, 0.0, 12.0]), np.diag([1.0, -1.0, -1.0]))
t2 = time.perf_counter()
print(t1 - t0, t2 - t1)
"""


def cold_start(fresh_cache: bool, script: str = _COLD) -> dict:
    """Seconds to import the engine and to build + take the first step of the default brush in a
    new interpreter; ``fresh_cache``: with an empty numba cache (full compile).  ``script``:
    ``_COLD`` (free brush) or ``COLD_CONTACT`` (the ``flat_plate`` scene)."""
    env = dict(os.environ)
    with tempfile.TemporaryDirectory() as tmp:
        if fresh_cache:
            env["NUMBA_CACHE_DIR"] = tmp
        t0 = time.perf_counter()
        out = subprocess.run(
            [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
        )
        total = time.perf_counter() - t0
    imp, first = (float(x) for x in out.stdout.split())
    return {"import_s": imp, "first_step_s": first, "process_s": total}


REF_RTOL = 1e-7


def best_of(args, make_run):
    """Run ``make_run()`` ``--repeats`` times and keep the fastest wall time: the runs are
    deterministic (same results bit for bit), so repeating only filters the machine's timing
    noise (other processes, frequency changes; ~30 % run to run on the shared VM measured)."""
    best = make_run()
    for _ in range(max(int(getattr(args, "repeats", 1) or 1), 1) - 1):
        again = make_run()
        if again.wall < best.wall:
            best.wall = again.wall
    return best


def markdown_table(rows: list[dict], columns) -> str:
    """Markdown table: ``columns`` is a list of (header, row -> cell text)."""
    lines = ["| " + " | ".join(h for h, _ in columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(f(r) for _, f in columns) + " |" for r in rows]
    return "\n".join(lines)


def print_cold_start(cold: dict, log, what: str = "") -> None:
    for name, c in cold.items():
        print(
            f"cold start{what}, {name}: import {c['import_s']:.2f} s, build + first step "
            f"{c['first_step_s']:.2f} s, whole process {c['process_s']:.2f} s",
            file=log,
        )
