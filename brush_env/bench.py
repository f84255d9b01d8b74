"""``brush-env bench TARGET``: speed-versus-error benchmarks.

Targets live in :data:`TARGETS` (name -> function(args) -> exit code); ``engine`` is the free
brush driven by a moving TCP.  Further targets (contact, env) are added by registering a function
there (and, if needed, their options in :func:`add_arguments`).

``bench engine``: the default brush (``load_brush()``, 40 bristles) on a TCP at R0 = diag(1,-1,-1),
p = (0, 0, 10) mm (bristles hang toward -z), gravity on, no surfaces.  The TCP starts from the
static equilibrium and follows a horizontal circle (radius 2 mm, 2 Hz) plus a vertical oscillation
(1 mm, 5 Hz), both faded in by a C^2 quintic ramp over the first 50 ms, for 0.5 s.  Every
(bodies, dt, integrator) of the grid is compared with a converged reference (24 bodies,
dt = 2e-5 s, BDF2): the TCP force [N] and moment [N mm] are interpolated linearly onto a common
5 ms grid and

    rms_force_error = RMS_t |F - F_ref| / RMS_t |F_ref - F_ref(0)|

(and the same for the moment), i.e. relative to the *dynamic* part of the reference wrench: the
constant weight F_ref(0) is left out of the denominator, since every scheme reproduces it exactly
and it would otherwise hide the errors (it is ~30x the dynamic force here).  Wall time covers the
stepping loop only (after a warm-up; cold start is measured apart in a fresh ``python -c``
process, once with an empty numba cache, i.e. compiling, and once loading the cache).
rtf = simulated time / wall time.  Run on one core: ``taskset -c 0 brush-env bench engine``.
"""

from __future__ import annotations

import json
import math
import os
import platform
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

R0 = np.diag([1.0, -1.0, -1.0])
P0 = np.array([0.0, 0.0, 10.0])  # [mm]


# --------------------------------------------------------------------------- machine
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
    root = Path(__file__).resolve().parents[1]

    def git(*a):
        try:
            return subprocess.run(["git", *a], cwd=root, capture_output=True, text=True,
                                  timeout=10).stdout.strip()
        except (OSError, subprocess.SubprocessError):
            return ""

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--untracked-files=no", "brush_env"):
        commit += " (+ uncommitted changes in brush_env/)"
    return {"platform": platform.platform(), "cpu": cpu, "cores": os.cpu_count(),
            "cores_usable": usable, "python": platform.python_version(),
            "numpy": np.__version__, "numba": numba.__version__, "commit": commit,
            "date": time.strftime("%Y-%m-%d %H:%M:%S %Z")}


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


def cold_start(fresh_cache: bool) -> dict:
    """Seconds to import the engine and to build + take the first step of the default brush in a
    new interpreter; ``fresh_cache``: with an empty numba cache (full compile)."""
    env = dict(os.environ)
    with tempfile.TemporaryDirectory() as tmp:
        if fresh_cache:
            env["NUMBA_CACHE_DIR"] = tmp
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", _COLD], env=env, capture_output=True,
                             text=True, check=True)
        total = time.perf_counter() - t0
    imp, first = (float(x) for x in out.stdout.split())
    return {"import_s": imp, "first_step_s": first, "process_s": total}


# --------------------------------------------------------------------------- engine target
def _ramp(t: float, t_ramp: float = 0.05) -> float:
    x = min(max(t / t_ramp, 0.0), 1.0)
    return x**3 * (10.0 - 15.0 * x + 6.0 * x * x)


def tcp_position(t: float) -> np.ndarray:
    """TCP position [mm] at time t [s]: circle r = 2 mm at 2 Hz + vertical 1 mm at 5 Hz, ramped."""
    wc, wv = 2.0 * math.pi * 2.0, 2.0 * math.pi * 5.0
    d = np.array([2.0 * (math.cos(wc * t) - 1.0), 2.0 * math.sin(wc * t), math.sin(wv * t)])
    return P0 + _ramp(t) * d


@dataclass
class Run:
    """One simulated time series: times [s], TCP force [N] and moment [N mm] (world), wall time
    [s] of the stepping loop, Newton iterations (all bristles), bristles."""

    t: np.ndarray
    F: np.ndarray
    M: np.ndarray
    wall: float
    newton: int
    n_bristles: int


def simulate(bodies: int, dt: float, integrator: str, duration: float,
             newton_rtol: float | None = None) -> Run:
    """Drive the default brush (``bodies`` per bristle) along :func:`tcp_position`."""
    from .engine import SimSettings, Simulator, load_brush

    brush = load_brush(overrides={"bodies_per_bristle": bodies})
    extra = {} if newton_rtol is None else {"newton_rtol": newton_rtol}
    sim = Simulator(brush, SimSettings(dt=dt, integrator=integrator, **extra))
    sim.reset(tcp_position(0.0), R0)
    out = sim.solve_static()  # start from the gravity equilibrium
    n = int(round(duration / dt))
    poses = [tcp_position(k * dt) for k in range(n + 1)]
    F, M = np.zeros((n + 1, 3)), np.zeros((n + 1, 3))
    F[0], M[0] = out.tcp_force, out.tcp_moment
    newton = 0
    t0 = time.perf_counter()
    for k in range(1, n + 1):
        out = sim.step(poses[k], R0)
        F[k], M[k] = out.tcp_force, out.tcp_moment
        newton += out.iterations
    wall = time.perf_counter() - t0
    return Run(np.arange(n + 1) * dt, F, M, wall, newton, brush.n_bristles)


def _rel_rms(run: Run, ref: Run, grid: np.ndarray) -> tuple[float, float]:
    def on_grid(t, Y):
        return np.stack([np.interp(grid, t, Y[:, c]) for c in range(3)], axis=1)

    errs = []
    for Y, Yr in ((run.F, ref.F), (run.M, ref.M)):
        yr = on_grid(ref.t, Yr)
        num = np.sqrt(np.mean(np.sum((on_grid(run.t, Y) - yr) ** 2, axis=1)))
        den = np.sqrt(np.mean(np.sum((yr - Yr[0]) ** 2, axis=1)))
        errs.append(float(num / den))
    return errs[0], errs[1]


#: Newton tolerance of the reference run.  At 24 bodies and dt = 2e-5 s the default 1e-8 is below
#: the round-off floor of the scaled residual (world-coordinate round-off times the stiff axial
#: term and the damping factor 1 + beta c0 / dt): Newton stagnates at 1.008e-8 and the run stops
#: with SimulationDivergence at t ~ 0.21 s (docs/benchmarks.md).  1e-7 is far below the errors
#: measured.
REF_RTOL = 1e-7

GRID_FULL = dict(bodies=(3, 6, 12), dts=(1e-4, 5e-4, 1e-3, 2e-3, 5e-3), duration=0.5,
                 ref=(24, 2e-5), sample=5e-3)
GRID_QUICK = dict(bodies=(3,), dts=(2e-3, 5e-3), duration=0.1, ref=(6, 2e-4), sample=1e-2)


def bench_engine(args) -> int:
    g = GRID_QUICK if args.quick else GRID_FULL
    info = machine_info()
    log = sys.stderr if args.json else sys.stdout
    print("machine: " + "; ".join(f"{k}={v}" for k, v in info.items()), file=log)
    print(f"motion: default brush, R0 = diag(1,-1,-1), p0 = {P0.tolist()} mm, gravity on, "
          f"circle r=2 mm @ 2 Hz + vertical 1 mm @ 5 Hz (50 ms ramp), {g['duration']} s", file=log)
    simulate(3, 1e-3, "bdf2", 2e-3)  # warm-up: numba compile / cache load
    cold = {}
    if not args.quick and not args.no_cold_start:
        cold = {"compile (empty numba cache)": cold_start(True),
                "cache load": cold_start(False)}
    rb, rdt = g["ref"]
    print(f"reference: {rb} bodies, dt={rdt:g} s, bdf2 ...", file=sys.stderr, flush=True)
    ref = simulate(rb, rdt, "bdf2", g["duration"], newton_rtol=REF_RTOL)
    grid = np.arange(0.0, g["duration"] + 1e-12, g["sample"])
    rows = []
    for bodies in g["bodies"]:
        for dt in g["dts"]:
            for integ in ("euler", "bdf2"):
                run = simulate(bodies, dt, integ, g["duration"])
                ef, em = _rel_rms(run, ref, grid)
                steps = len(run.t) - 1
                row = {"bodies": bodies, "dt": dt, "integrator": integ, "rms_force_error": ef,
                       "rms_moment_error": em, "wall_s": run.wall,
                       "rtf": g["duration"] / run.wall,
                       "newton_per_step_per_bristle": run.newton / steps / run.n_bristles}
                rows.append(row)
                if args.json:
                    print(json.dumps(row), flush=True)
    yr = np.stack([np.interp(grid, ref.t, ref.F[:, c]) for c in range(3)], axis=1)
    summary = (f"reference ({rb} bodies, dt={rdt:g} s, bdf2, newton_rtol={REF_RTOL:g}): wall "
               f"{ref.wall:.1f} s; static "
               f"|F(0)| = {np.linalg.norm(ref.F[0]):.3e} N, dynamic RMS |F - F(0)| = "
               f"{np.sqrt(np.mean(np.sum((yr - ref.F[0])**2, axis=1))):.3e} N")
    print(summary, file=log)
    for name, c in cold.items():
        print(f"cold start, {name}: import {c['import_s']:.2f} s, build + first step "
              f"{c['first_step_s']:.2f} s, whole process {c['process_s']:.2f} s", file=log)
    if not args.json:
        print(format_table(rows))
    return 0


def format_table(rows: list[dict]) -> str:
    """Markdown table of the engine rows."""
    head = ("| bodies | dt [s] | integrator | RMS F err | RMS M err | wall [s] | RTF "
            "| Newton/step/bristle |")
    lines = [head, "|" + "---|" * 8]
    for r in rows:
        lines.append(f"| {r['bodies']} | {r['dt']:g} | {r['integrator']} | "
                     f"{r['rms_force_error']:.2e} | {r['rms_moment_error']:.2e} | "
                     f"{r['wall_s']:.2f} | {r['rtf']:.3g} | "
                     f"{r['newton_per_step_per_bristle']:.2f} |")
    return "\n".join(lines)


def _bench_env(args) -> int:
    from brush_env.envs import bench_env  # gymnasium only when the env is benchmarked

    return bench_env.run(args)


TARGETS = {"engine": bench_engine, "env": _bench_env}


def add_arguments(parser) -> None:
    parser.add_argument("target", choices=sorted(TARGETS), help="what to benchmark")
    parser.add_argument("--json", action="store_true",
                        help="one JSON object per row on stdout (machine info on stderr)")
    parser.add_argument("--quick", action="store_true", help="reduced grid (for tests)")
    parser.add_argument("--no-cold-start", action="store_true",
                        help="skip the cold-start measurement (fresh numba compile)")
    from brush_env.envs import bench_env  # env options (skips the shared --json)

    bench_env.add_arguments(parser)


def run(args) -> int:
    return TARGETS[args.target](args)
