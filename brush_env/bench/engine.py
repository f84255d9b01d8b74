"""``bench engine``: the default brush (``load_brush()``, 40 bristles) on a TCP at
R0 = diag(1,-1,-1), p = (0, 0, 10) mm (bristles hang toward -z), gravity on, no surfaces.  The TCP
starts from the
static equilibrium and follows a horizontal circle (radius 2 mm, 2 Hz) plus a vertical oscillation
(1 mm, 5 Hz), both faded in by a C^2 quintic ramp over the first 50 ms, for 0.5 s.  Every
(bodies, dt, integrator) of the grid is compared with a converged reference (24 bodies,
dt = 2e-5 s, BDF2): the TCP force [N] and moment [N mm] are interpolated linearly onto a common
5 ms grid and

    rms_force_error = RMS_t |F - F_ref| / RMS_t |F_ref - F_ref(0)|

(and the same for the moment; ``*_steady``: the same over t >= STEADY_FROM = 0.1 s, after the
start ramp's ring-down of the bristle modes), i.e. relative to the *dynamic* part of the
reference wrench: the
constant weight F_ref(0) is left out of the denominator, since every scheme reproduces it exactly
and it would otherwise hide the errors (it is ~30x the dynamic force here).  Wall time covers the
stepping loop only (after a warm-up; cold start is measured apart in a fresh ``python -c``
process, once with an empty numba cache, i.e. compiling, and once loading the cache).
rtf = simulated time / wall time.  Run on one core: ``taskset -c 0 brush-env bench engine``.
"""

from __future__ import annotations

import json
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..motion import R0
from .harness import REF_RTOL, best_of, cold_start, markdown_table, open_log, print_cold_start

P0 = np.array([0.0, 0.0, 10.0])  # [mm]


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


def simulate(
    bodies: int, dt: float, integrator: str, duration: float, newton_rtol: float | None = None
) -> Run:
    """Drive the default brush (``bodies`` per bristle) along :func:`tcp_position`."""
    from ..engine import SimSettings, Simulator, load_brush

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


#: [s] start of the "steady" error window: the 50 ms start ramp rings the bristles' first bending
#: mode (~100-125 Hz, damping ratio 0.1: decay time ~15 ms); by 0.1 s the ring-down is below
#: 1e-3 of the dynamic wrench, and what is left is the response to the 2-5 Hz drive itself.
STEADY_FROM = 0.1


def _rel_rms(run: Run, ref: Run, grid: np.ndarray, t0: float = 0.0) -> tuple[float, float]:
    """(force, moment) RMS error over grid >= t0, relative to the reference's dynamic part."""

    def on_grid(t, Y):
        return np.stack([np.interp(grid, t, Y[:, c]) for c in range(3)], axis=1)

    m = grid >= t0 - 1e-12
    errs = []
    for Y, Yr in ((run.F, ref.F), (run.M, ref.M)):
        yr = on_grid(ref.t, Yr)[m]
        num = np.sqrt(np.mean(np.sum((on_grid(run.t, Y)[m] - yr) ** 2, axis=1)))
        den = np.sqrt(np.mean(np.sum((yr - Yr[0]) ** 2, axis=1)))
        errs.append(float(num / den))
    return errs[0], errs[1]


#: Newton tolerance of the reference run.  At 24 bodies and dt = 2e-5 s the default 1e-8 is below
#: the round-off floor of the scaled residual (world-coordinate round-off times the stiff axial
#: term and the damping factor 1 + beta c0 / dt): Newton stagnates at 1.008e-8 and the run stops
#: with SimulationDivergence at t ~ 0.21 s (docs/benchmarks.md).  1e-7 is far below the errors
#: measured.


GRID_FULL = dict(
    bodies=(3, 6, 12),
    dts=(1e-4, 5e-4, 1e-3, 2e-3, 3e-3, 4e-3, 5e-3),
    duration=0.5,
    ref=(24, 2e-5),
    sample=5e-3,
)
GRID_QUICK = dict(bodies=(3,), dts=(2e-3, 5e-3), duration=0.1, ref=(6, 2e-4), sample=1e-2)


def bench_engine(args) -> int:
    g = GRID_QUICK if args.quick else GRID_FULL
    log = open_log(args)
    print(
        f"motion: default brush, R0 = diag(1,-1,-1), p0 = {P0.tolist()} mm, gravity on, "
        f"circle r=2 mm @ 2 Hz + vertical 1 mm @ 5 Hz (50 ms ramp), {g['duration']} s",
        file=log,
    )
    simulate(3, 1e-3, "bdf2", 2e-3)  # warm-up: numba compile / cache load
    cold = {}
    if not args.quick and not args.no_cold_start:
        cold = {"compile (empty numba cache)": cold_start(True), "cache load": cold_start(False)}
    rb, rdt = g["ref"]
    print(f"reference: {rb} bodies, dt={rdt:g} s, bdf2 ...", file=sys.stderr, flush=True)
    ref = simulate(rb, rdt, "bdf2", g["duration"], newton_rtol=REF_RTOL)
    grid = np.arange(0.0, g["duration"] + 1e-12, g["sample"])
    rows = []
    for bodies in g["bodies"]:
        for dt in g["dts"]:
            for integ in ("euler", "bdf2"):
                run = best_of(
                    args, lambda b=bodies, d=dt, i=integ: simulate(b, d, i, g["duration"])
                )
                ef, em = _rel_rms(run, ref, grid)
                sf, sm = _rel_rms(run, ref, grid, STEADY_FROM)
                steps = len(run.t) - 1
                row = {
                    "bodies": bodies,
                    "dt": dt,
                    "integrator": integ,
                    "rms_force_error": ef,
                    "rms_moment_error": em,
                    "rms_force_error_steady": sf,
                    "rms_moment_error_steady": sm,
                    "wall_s": run.wall,
                    "rtf": g["duration"] / run.wall,
                    "newton_per_step_per_bristle": run.newton / steps / run.n_bristles,
                }
                rows.append(row)
                if args.json:
                    print(json.dumps(row), flush=True)
    yr = np.stack([np.interp(grid, ref.t, ref.F[:, c]) for c in range(3)], axis=1)
    summary = (
        f"reference ({rb} bodies, dt={rdt:g} s, bdf2, newton_rtol={REF_RTOL:g}): wall "
        f"{ref.wall:.1f} s; static "
        f"|F(0)| = {np.linalg.norm(ref.F[0]):.3e} N, dynamic RMS |F - F(0)| = "
        f"{np.sqrt(np.mean(np.sum((yr - ref.F[0]) ** 2, axis=1))):.3e} N"
    )
    print(summary, file=log)
    print_cold_start(cold, log)
    if not args.json:
        print(format_table(rows))
    return 0


def format_table(rows: list[dict]) -> str:
    """Markdown table of the engine rows."""
    return markdown_table(
        rows,
        [
            ("bodies", lambda r: f"{r['bodies']}"),
            ("dt [s]", lambda r: f"{r['dt']:g}"),
            ("integrator", lambda r: r["integrator"]),
            ("RMS F err", lambda r: f"{r['rms_force_error']:.2e}"),
            ("RMS M err", lambda r: f"{r['rms_moment_error']:.2e}"),
            (f"F err t≥{STEADY_FROM:g} s", lambda r: f"{r['rms_force_error_steady']:.2e}"),
            (f"M err t≥{STEADY_FROM:g} s", lambda r: f"{r['rms_moment_error_steady']:.2e}"),
            ("wall [s]", lambda r: f"{r['wall_s']:.2f}"),
            ("RTF", lambda r: f"{r['rtf']:.3g}"),
            ("Newton/step/bristle", lambda r: f"{r['newton_per_step_per_bristle']:.2f}"),
        ],
    )
