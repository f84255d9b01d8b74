"""``bench contact``: the ``flat_plate`` scene (default brush, 40 bristles, plate at z = 0) with the
tips touching the plate at t = 0, pressed 3 mm along the bristle axis (0.5 s, minimum jerk), held
0.25 s, then driven once round the paper's 20 mm circle at 20 mm/s (exact circle, 100 mm/s^2
ramps; ``arc`` = "turn": 6.484 s, 7.234 s in all, a multiple of every dt).
Grid: bodies {3, 6} x dt {1, 2, 4} ms
x {euler, bdf2} x tip_tip {off, on}
(``dataclasses.replace(scene, tip_tip=...)``; the scene file has it on).  Each tip_tip setting
has its own reference (12 bodies, dt = 2.5e-4 s, BDF2, same tip_tip); the TCP force is
interpolated onto a common 5 ms grid and

    rms_force_error = RMS_t |F - F_ref| / RMS_t |F_ref|

over the whole run (and ``rms_force_error_circle`` over the circle part only), and
``rms_force_error_same_bodies``: the same measure against a reference with the row's own bodies
(dt = 2.5e-4 s, BDF2): the solver's error alone, without the discretisation's.  Rows whose run
raises ``SimulationDivergence`` are kept with status "diverged at t=..." and NaN errors; if a
reference diverges, its rows are compared over the span it reached (``error_window_s``).
Also per row: rtf, Newton iterations per step per bristle, extra sub-steps (sub-steps beyond one
per bristle and step, summed over the run).  Wall times (both targets) are the fastest of
``--repeats`` identical runs (default 3; the results are deterministic, only the timing varies).
Cold start as for ``engine``, on the plate scene.
"""

from __future__ import annotations

import math
import sys
import time
from dataclasses import dataclass

import numpy as np

from ..motion import R0
from .harness import (
    COLD_CONTACT,
    best_of,
    cold_start,
    emit,
    markdown_table,
    print_cold_start,
    print_machine,
)


@dataclass
class ContactRun:
    """One press + arc run: times [s] and TCP force [N] up to the last completed step, wall time
    [s] of the stepping loop, Newton iterations and sub-steps (summed over bristles and steps),
    steps taken, bristles, status ("ok" or "diverged at t=... s"), the circle's start [s], the
    angle reached [rad] and the CPU time [s] of the ``Simulator.follow`` calls alone (the
    engine's: not the observer's, not the set-up's)."""

    t: np.ndarray
    F: np.ndarray
    wall: float
    newton: int
    substeps: int
    steps: int
    n_bristles: int
    status: str
    t_circle: float
    theta_end: float
    cpu: float


#: Contact grid.  ``press``/``hold``: the paper's 3 mm minimum-jerk press in 0.5 s and 0.25 s
#: settling (experiments.plan.DEFAULTS); ``arc``: simulated seconds of the circle after the hold.
CONTACT_GRID_FULL = dict(
    bodies=(3, 6),
    dts=(1e-3, 2e-3, 4e-3),
    integrators=("euler", "bdf2"),
    tip_tip=(False, True),
    press=0.5,
    hold=0.25,
    arc="turn",
    ref=(12, 2.5e-4),
    sample=5e-3,
)
#: quick: the pipeline in seconds, at steps that stay on the small-step branch (a 4 ms step of
#: this fast press buckles another way and the penalty law warns, docs/benchmarks.md "bench press")
CONTACT_GRID_QUICK = dict(
    bodies=(3,),
    dts=(1e-3,),
    integrators=("bdf2",),
    tip_tip=(False, True),
    press=0.1,
    hold=0.0,
    arc=0.06,
    ref=(3, 5e-4),
    sample=1e-2,
)


#: poses per ``Simulator.follow`` call in ``simulate_contact``
CHUNK = 1000


class StepRow:
    """Row j of a ``Simulator.follow`` record with the ``StepResult`` fields the benches'
    observers read (tcp_force [N], tip_normal_force [N], tip_tangential_force [N], tip_pos [mm],
    tip_sliding, tip_in_contact, iterations, substeps, extra: the sweep counters)."""

    def __init__(self, rec, j: int):
        self.tcp_force = rec.FM[j, 0:3]
        self.tip_normal_force = rec.fn[j]
        self.tip_tangential_force = rec.ft[j]
        self.tip_pos = rec.tips[j, :, 0:3]
        self.tip_sliding = rec.slide[j] != 0
        self.tip_in_contact = rec.fn[j] > 0.0
        self.iterations = int(rec.iters[j])
        self.substeps = int(rec.nsub[j])
        sweeps, resolves, settled = (int(x) for x in rec.sweeps[j])
        self.extra = {
            "sweeps": sweeps,
            "resolves": resolves,
            "tip_tip_settled": settled == 0,
            "tip_tip_fallback": settled == 2,
        }


def simulate_contact(
    bodies: int,
    dt: float,
    integrator: str,
    tip_tip: bool,
    press: float,
    hold: float,
    arc: float,
    element: str | None = None,
    max_substep: float | None = None,
    observe=None,
    sim_settings=None,
    shift: float = 0.0,
    **settings,
) -> ContactRun:
    """The default ``flat_plate`` scene with ``bodies`` per bristle and ``tip_tip`` on/off: tips
    touching the plate at t = 0, pressed 3 mm along the bristle axis (``press`` s, minimum jerk),
    held ``hold`` s, then driven ``arc`` s along the 20 mm circle at 20 mm/s (100 mm/s^2 ramp),
    as ``brush-env reference --path circle``, with the beam element ``element`` (None: the
    SimSettings default) and SimSettings.max_substep ``max_substep`` [s] (None: dt, i.e. no
    internal split: the benches time the solver at the step they name); ``observe(t, out)``,
    if given, sees every step's outputs (a ``StepRow``, inside the timed loop).  A
    ``SimulationDivergence`` ends the run early; the samples up to the last completed step are
    kept and ``status`` says when it diverged.  Further keywords are SimSettings fields
    (e.g. ``tip_tip_sweeps``); ``sim_settings``, if given, is the whole ``SimSettings`` (a
    fidelity level's, ``fidelity.level_settings``), used unchanged (its bodies per bristle and
    step win over ``bodies``, ``dt``, ``integrator``, ``element`` and ``max_substep``).
    ``shift`` [mm] moves the whole path along the plate (x): physically nothing on the infinite
    plate, but every position rounds differently -- a last-place perturbation for ensembles
    (``bench coupled --ensemble``)."""
    from dataclasses import replace

    from ..engine import SimSettings, Simulator, load_scene
    from ..experiments.plan import plate_height

    if sim_settings is None:
        extra = {} if element is None else {"element": element}
        extra["max_substep"] = dt if max_substep is None else max_substep
        extra.update(settings)
        sim_settings = SimSettings(dt=dt, integrator=integrator, **extra)
    else:
        bodies, dt = sim_settings.bodies_per_bristle or bodies, sim_settings.dt
    scene = load_scene("flat_plate")
    scene = replace(scene, brush=scene.brush.with_bodies(bodies), tip_tip=tip_tip)
    sim = Simulator(scene, sim_settings)
    touch_z = sim.touch_height(R0, plate_height(scene))
    traj, starts = press_and_circle(touch_z, press, hold)
    t_circle = starts[-1]
    n = int(round((t_circle + arc) / dt))
    times = np.arange(n + 1) * dt
    P, R, _, _ = traj.sample(times)
    P[:, 0] += shift
    theta_end = float(traj.angle(times[-1]))
    F = np.zeros((n + 1, 3))
    F[0] = sim.reset(P[0], R[0]).tcp_force
    newton = subs = 0
    status = "ok"
    k = 1  # rows done (row 0: the reset)
    cpu = 0.0
    t0 = time.perf_counter()
    # the steps in ``Simulator.follow`` calls of CHUNK poses (compiled, no Python between
    # steps); the observer sees each step's row of the record
    for i in range(1, n + 1, CHUNK):
        c0 = time.process_time()
        run = sim.follow(P[i : i + CHUNK], R[i : i + CHUNK])
        cpu += time.process_time() - c0
        rec, done = run.record, run.done
        F[i : i + done] = rec.FM[:done, 0:3]
        newton += int(rec.iters[:done].sum())
        subs += int(rec.nsub[:done].sum())
        if observe is not None:
            for j in range(done):
                observe(times[i + j], StepRow(rec, j))
        k = i + done
        if run.error is not None:
            status = f"diverged at t={run.error.time:.4g} s"
            break
    wall = time.perf_counter() - t0
    return ContactRun(
        times[:k],
        F[:k],
        wall,
        newton,
        subs,
        k - 1,
        sim.model.n_bristles,
        status,
        t_circle,
        theta_end,
        cpu,
    )


def warm_kernels() -> None:
    """Compile (or load) every kernel a contact run uses, before the timed rows: a 3 mm press of
    3 bodies in 0.1 s at 1 ms (a gentle one: a violent or long-stepped press leaves the penalty
    law's range and warns)."""
    simulate_contact(3, 1e-3, "bdf2", True, 0.1, 0.0, 0.0)


def press_and_circle(touch_z: float, press: float, hold: float):
    """(trajectory, phase start times): the experiment's press (``press`` s) from tips touching
    at ``touch_z`` [mm], hold (``hold`` s) and one turn of the exact circle, its other numbers
    the experiment's defaults."""
    from ..experiments.plan import DEFAULTS, build_trajectory

    traj, starts, _ = build_trajectory(
        start_xy=(0.0, 0.0),
        touch_z=touch_z,
        radius=DEFAULTS["radius"],
        speed=DEFAULTS["speed"],
        accel=DEFAULTS["accel"],
        turns=1.0,
        press_depth=DEFAULTS["press_depth"],
        press_time=press,
        hold_time=hold,
        path="circle",
    )
    return traj, starts


def _on_grid(grid: np.ndarray, t: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """The three columns of ``Y`` (sampled at ``t``) interpolated onto ``grid``."""
    return np.stack([np.interp(grid, t, Y[:, c]) for c in range(3)], axis=1)


def contact_errors(run: ContactRun, ref: ContactRun, grid: np.ndarray) -> tuple[float, float]:
    """(whole run, circle only): RMS_t |F - F_ref| / RMS_t |F_ref| on ``grid``; NaN if ``run``
    diverged (even after the end of the grid, when the reference itself stopped earlier)."""
    if run.status != "ok" or run.t[-1] < grid[-1] - 1e-9:
        return math.nan, math.nan
    d2 = np.sum((_on_grid(grid, run.t, run.F) - _on_grid(grid, ref.t, ref.F)) ** 2, axis=1)
    r2 = np.sum(_on_grid(grid, ref.t, ref.F) ** 2, axis=1)
    arc = grid >= run.t_circle - 1e-12
    whole = math.sqrt(d2.mean() / r2.mean())
    circ = math.sqrt(d2[arc].mean() / r2[arc].mean()) if arc.any() else math.nan
    return whole, circ


def _contact_row(run: ContactRun, bodies, dt, integ, tip_tip, errs, reference=False) -> dict:
    steps = max(run.steps, 1)
    sim_t = float(run.t[-1])
    return {
        "bodies": bodies,
        "dt": dt,
        "integrator": integ,
        "tip_tip": tip_tip,
        "reference": reference,
        "rms_force_error": errs[0],
        "rms_force_error_circle": errs[1],
        "status": run.status,
        "simulated_s": sim_t,
        "wall_s": run.wall,
        "rtf": sim_t / run.wall if run.wall > 0 else math.nan,
        "newton_per_step_per_bristle": run.newton / steps / run.n_bristles,
        "substeps_extra": run.substeps - run.steps * run.n_bristles,
        "steps": run.steps,
    }


def arc_seconds(g: dict) -> float:
    """``g['arc']`` [s], or for "turn" the whole circle (ramps included) rounded up to a multiple
    of 4 ms, so that every dt of the grid ends on the same time."""
    if g["arc"] != "turn":
        return float(g["arc"])
    traj, starts = press_and_circle(0.0, g["press"], g["hold"])
    return math.ceil((traj.duration - starts[-1]) / 4e-3 - 1e-9) * 4e-3


def bench_contact(args) -> int:
    """``brush-env bench contact``: the references, then the grid against them (rows as JSON
    lines with ``--json``, else a table); see the module docstring."""
    g = CONTACT_GRID_QUICK if args.quick else CONTACT_GRID_FULL
    g = dict(g, arc=arc_seconds(g))
    log = sys.stderr if args.json else sys.stdout
    cold = _warm_up(args, log)
    motion = (g["press"], g["hold"], g["arc"])
    refs = _references(g, motion)
    _print_motion(g, refs, log)
    rows = []
    for tt, ref in refs.items():
        rows += _tip_tip_rows(args, g, tt, ref, motion, log)
    print_cold_start(cold, log, " (flat_plate scene)")
    if not args.json:
        print(format_contact_table(rows))
    return 0


def _warm_up(args, log) -> dict:
    """Machine line, a tiny run that compiles (or loads) the kernels, and the cold-start
    measurements unless ``--quick`` or ``--no-cold-start`` (returned, printed at the end)."""
    print_machine(log)
    warm_kernels()
    if args.quick or args.no_cold_start:
        return {}
    return {
        "compile (empty numba cache)": cold_start(True, COLD_CONTACT),
        "cache load": cold_start(False, COLD_CONTACT),
    }


def _references(g: dict, motion) -> dict:
    """tip_tip -> the reference run (``g['ref']`` = bodies, dt; BDF2) of that setting."""
    rb, rdt = g["ref"]
    refs = {}
    for tt in g["tip_tip"]:
        print(
            f"reference: {rb} bodies, dt={rdt:g} s, bdf2, tip_tip={tt} ...",
            file=sys.stderr,
            flush=True,
        )
        refs[tt] = simulate_contact(rb, rdt, "bdf2", tt, *motion)
    return refs


def _print_motion(g: dict, refs: dict, log) -> None:
    """One line: the scene, the motion and how far the circle gets."""
    ref0 = refs[g["tip_tip"][0]]
    deg = math.degrees(ref0.theta_end)
    print(
        f"motion: flat_plate scene (default brush, 40 bristles), tips touching the plate at t=0, "
        f"3 mm press in {g['press']} s (minimum jerk), {g['hold']} s hold, then the first "
        f"{g['arc']:g} s of the 20 mm circle at 20 mm/s (0.2 s ramp; theta reaches {deg:.1f} deg "
        f"of the 360 deg turn), {ref0.t_circle + g['arc']:g} s in all; force error on a "
        f"{g['sample']:g} s grid relative to the reference's RMS |F|",
        file=log,
    )


def _tip_tip_rows(args, g: dict, tt: bool, ref: ContactRun, motion, log) -> list[dict]:
    """The rows of one tip_tip setting: its reference, then bodies x dt x integrator against it
    on the ``g['sample']`` grid (up to where the reference got)."""
    rb, rdt = g["ref"]
    T_ref = float(ref.t[-1])
    rows = [emit(args, _contact_row(ref, rb, rdt, "bdf2", tt, (0.0, 0.0), reference=True))]
    grid = np.arange(0.0, T_ref + 1e-12, g["sample"])
    rms = math.sqrt(np.mean(np.sum(_on_grid(grid, ref.t, ref.F) ** 2, axis=1)))
    print(
        f"reference tip_tip={'on' if tt else 'off'} ({rb} bodies, dt={rdt:g} s, bdf2): "
        f"{ref.status}, wall {ref.wall:.1f} s, RMS |F_ref| = {rms:.3g} N"
        + (
            ""
            if ref.status == "ok"
            else f"; rows of this tip_tip setting are compared over [0, {T_ref:.4g}] s only"
        ),
        file=log,
        flush=True,
    )
    for bodies in g["bodies"]:
        # the same discretisation, time-converged: separates the solver's error (dt,
        # integrator, coupling) from the discretisation's (bodies); the paper's model is 6
        # bodies, so this is the error of a fast setting against the paper's model itself
        print(
            f"  same-bodies reference: {bodies} bodies, dt={rdt:g}, bdf2, tip_tip={tt} ...",
            file=sys.stderr,
            flush=True,
        )
        same = ref if bodies == rb else simulate_contact(bodies, rdt, "bdf2", tt, *motion)
        for dt in g["dts"]:
            for integ in g["integrators"]:
                row = _grid_row(args, (bodies, dt, integ, tt), motion, (ref, same), grid)
                rows.append(emit(args, row))
    return rows


def _grid_row(args, setting, motion, refs, grid: np.ndarray) -> dict:
    """One grid row (``setting`` = bodies, dt, integrator, tip_tip), fastest of ``--repeats``:
    its errors against the reference and the same-bodies reference (``refs``) on ``grid``."""
    bodies, dt, integ, tt = setting
    ref, same = refs
    print(f"  {bodies} bodies, dt={dt:g}, {integ}, tip_tip={tt} ...", file=sys.stderr, flush=True)
    run = best_of(args, lambda: simulate_contact(bodies, dt, integ, tt, *motion))
    row = _contact_row(run, bodies, dt, integ, tt, contact_errors(run, ref, grid))
    ok_same = same.status == "ok" and same.t[-1] >= grid[-1] - 1e-9
    row["rms_force_error_same_bodies"] = contact_errors(run, same, grid)[0] if ok_same else math.nan
    if ref.status != "ok":
        row["error_window_s"] = float(ref.t[-1])
    return row


def format_contact_table(rows: list[dict]) -> str:
    """Markdown table of the contact rows (references first, marked "ref")."""

    def err(key):
        return lambda r: (
            "—" if r["reference"] else ("NaN" if not math.isfinite(r[key]) else f"{r[key]:.2e}")
        )

    return markdown_table(
        rows,
        [
            ("bodies", lambda r: f"{r['bodies']}{' (ref)' if r['reference'] else ''}"),
            ("dt [s]", lambda r: f"{r['dt']:g}"),
            ("integrator", lambda r: r["integrator"]),
            ("tip_tip", lambda r: "on" if r["tip_tip"] else "off"),
            ("RMS F err", err("rms_force_error")),
            ("RMS F err (circle)", err("rms_force_error_circle")),
            ("RMS F err vs same bodies", err("rms_force_error_same_bodies")),
            ("wall [s]", lambda r: f"{r['wall_s']:.1f}"),
            ("RTF", lambda r: f"{r['rtf']:.3g}"),
            ("Newton/step/bristle", lambda r: f"{r['newton_per_step_per_bristle']:.2f}"),
            ("extra substeps", lambda r: f"{r['substeps_extra']}"),
            ("status", lambda r: r["status"]),
        ],
    )
