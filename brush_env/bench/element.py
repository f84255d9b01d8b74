"""``bench element``: the flat-plate turn against its converged reference, for both beam elements.

The motion and scene of ``bench contact`` (default brush, 40 bristles, tip-tip on, BDF2: 3 mm press
in 0.5 s, 0.25 s hold, one turn of the 20 mm circle at 20 mm/s; 7.234 s).  Each row runs one
element ("paper" | "mid") at one bodies-per-bristle and time step and reports

    rms_force_error = RMS_t |F - F_conv| / RMS_t |F_conv|   (whole run and circle only)

against the **converged reference**: the mid element at 24 bodies and dt = 0.125 ms, stored in
``tests/data/flat_plate_turn_reference.npz`` (TCP force sampled every 1 ms, with its settings and
commit; ``--write-reference`` recomputes it, ~4 min on one core).  24 bodies are converged in
bodies: 48 bodies at 0.25 ms sit 0.78 % from it and 24 bodies at 0.25 ms 0.80 % (the time step's
share), so "converged" here means the continuum, not the same bodies at a small step.  The rows
at dt = 0.25 ms show the discretisation's error, the rows at 1 ms add the time step's (the
stick-slip transitions of issue 15).  The reference and every row solve tip-tip contact coupled
(SimSettings.tip_tip_sweeps, docs/model.md); the reference before 2026-11-24 held the partners
one sweep behind and sat 5.8 % from the coupled one.
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np

from .contact import (
    CONTACT_GRID_FULL,
    CONTACT_GRID_QUICK,
    arc_seconds,
    simulate_contact,
    warm_kernels,
)
from .harness import best_of, emit, machine_info, markdown_table, open_log

REFERENCE_FILE = (
    Path(__file__).resolve().parents[2] / "tests" / "data" / "flat_plate_turn_reference.npz"
)
REFERENCE_SETTINGS = dict(
    element="mid", bodies=24, dt=1.25e-4, integrator="bdf2", tip_tip=True, tip_tip_sweeps=8
)
#: every row solves tip-tip contact coupled, as the reference (docs/model.md)
COUPLED = dict(tip_tip_sweeps=REFERENCE_SETTINGS["tip_tip_sweeps"])
ELEMENT_GRID_FULL = dict(elements=("paper", "mid"), bodies=(3, 6), dts=(1e-3, 2.5e-4))
ELEMENT_GRID_QUICK = dict(elements=("paper", "mid"), bodies=(3,), dts=(1e-3,))
SAMPLE = 5e-3  # [s] comparison grid


def _motion(quick: bool):
    g = dict(CONTACT_GRID_QUICK if quick else CONTACT_GRID_FULL)
    return g["press"], g["hold"], arc_seconds(g)


def load_reference(path: Path = REFERENCE_FILE) -> dict:
    """The stored converged reference: t [s], F [N] (TCP force, world), t_circle [s], settings."""
    if not path.exists():
        raise FileNotFoundError(
            f"{path}: no converged reference; `brush-env bench element --write-reference` makes it"
        )
    d = np.load(path, allow_pickle=False)
    return {
        "t": d["t"],
        "F": d["F"],
        "t_circle": float(d["t_circle"]),
        "settings": json.loads(str(d["settings"])),
    }


def write_reference(path: Path = REFERENCE_FILE) -> dict:
    """Run the converged reference (REFERENCE_SETTINGS, the full motion) and store its TCP force
    every 1 ms (compressed), with its settings, machine and commit."""
    s = REFERENCE_SETTINGS
    run = simulate_contact(
        s["bodies"],
        s["dt"],
        s["integrator"],
        s["tip_tip"],
        *_motion(False),
        element=s["element"],
        **COUPLED,
    )
    if run.status != "ok":
        raise RuntimeError(f"the converged reference did not finish: {run.status}")
    every = int(round(1e-3 / s["dt"]))
    from ..engine import SimSettings

    meta = dict(
        s,
        tip_tip_tol_mm=SimSettings().tip_tip_tol,
        motion="bench contact (full): press 0.5 s, hold 0.25 s, one turn",
        **machine_info(),
    )
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path,
        t=run.t[::every],
        F=run.F[::every],
        t_circle=run.t_circle,
        wall_s=run.wall,
        settings=json.dumps(meta),
    )
    return load_reference(path)


def errors_against(t, F, ref: dict, t_circle: float) -> tuple[float, float]:
    """(whole run, circle only) RMS force error of (t, F) against ``ref`` on the 5 ms grid."""
    grid = np.arange(0.0, min(ref["t"][-1], t[-1]) + 1e-12, SAMPLE)

    def on(tt, Y):
        return np.stack([np.interp(grid, tt, Y[:, c]) for c in range(3)], axis=1)

    Fr = on(ref["t"], ref["F"])
    d2 = np.sum((on(t, F) - Fr) ** 2, axis=1)
    r2 = np.sum(Fr**2, axis=1)
    arc = grid >= t_circle - 1e-12
    return math.sqrt(d2.mean() / r2.mean()), math.sqrt(d2[arc].mean() / r2[arc].mean())


def bench_element(args) -> int:
    """``brush-env bench element``: see the module docstring."""
    if args.events:
        return bench_events(args)
    log = open_log(args)
    if args.write_reference:
        print("writing the converged reference (mid, 24 bodies, dt 0.125 ms) ...", file=log)
        write_reference()
    g = ELEMENT_GRID_QUICK if args.quick else ELEMENT_GRID_FULL
    motion = _motion(args.quick)
    warm_kernels()
    ref = None if args.quick else load_reference()
    rows = []
    for element in g["elements"]:
        for bodies in g["bodies"]:
            for dt in g["dts"]:
                print(f"  {element}, {bodies} bodies, dt={dt:g} ...", file=sys.stderr, flush=True)
                run = best_of(
                    args,
                    lambda e=element, b=bodies, h=dt: simulate_contact(
                        b, h, "bdf2", True, *motion, element=e, **COUPLED
                    ),
                )
                whole = circ = math.nan
                if ref is not None and run.status == "ok":
                    whole, circ = errors_against(run.t, run.F, ref, ref["t_circle"])
                row = {
                    "element": element,
                    "bodies": bodies,
                    "dt": dt,
                    "rms_force_error_converged": whole,
                    "rms_force_error_converged_circle": circ,
                    "wall_s": run.wall,
                    "rtf": float(run.t[-1]) / run.wall if run.wall > 0 else math.nan,
                    "newton_per_step_per_bristle": run.newton / max(run.steps, 1) / 40,
                    "status": run.status,
                }
                rows.append(emit(args, row))
    if not args.json:
        print(format_element_table(rows))
    return 0


#: the slip events of the circle's start: bodies per bristle of the rows (mid element, 0.25 ms)
EVENT_BODIES = (3, 6, 12, 24)
EVENT_END = 1.12  # [s] after the second group's break-away in every row


def slip_events(bodies: int, dt: float = 2.5e-4, element: str = "mid") -> dict:
    """The break-away at the start of the circle (the flat-plate turn's motion up to EVENT_END):
    each bristle's first sliding step after the hold, grouped by time.  Returns ``groups``
    [(t_ms, n_bristles), ...] and the TCP force [N] every 5 ms from 1.05 s (``t``, ``F``)."""
    press, hold, _ = _motion(False)
    first: dict[int, float] = {}
    samples: list[tuple[float, np.ndarray]] = []

    def observe(t, out):
        if t <= press + hold:
            return
        for b in np.flatnonzero(out.tip_sliding):
            first.setdefault(int(b), round(1e3 * t, 3))
        if t >= 1.05 - 1e-9 and abs(t * 200.0 - round(t * 200.0)) < 1e-6:
            samples.append((t, out.tcp_force.copy()))

    run = simulate_contact(
        bodies,
        dt,
        "bdf2",
        True,
        press,
        hold,
        EVENT_END - press - hold,
        element,
        observe=observe,
        **COUPLED,
    )
    times = sorted(set(first.values()))
    groups = [(t, sum(1 for v in first.values() if v == t)) for t in times]
    return {
        "bodies": bodies,
        "dt": dt,
        "element": element,
        "groups": groups,
        "t": [t for t, _ in samples],
        "F": [f.tolist() for _, f in samples],
        "status": run.status,
    }


def bench_events(args) -> int:
    """``brush-env bench element --events``: the break-away times over bodies (see slip_events)."""
    open_log(args)
    rows = []
    for bodies in (3,) if args.quick else EVENT_BODIES:
        print(f"  slip events, mid, {bodies} bodies, dt=0.25 ms ...", file=sys.stderr, flush=True)
        rows.append(emit(args, slip_events(bodies)))
    if not args.json:
        print(format_events_table(rows))
    return 0


def format_events_table(rows) -> str:
    def group(k):
        return lambda r: (
            f"{r['groups'][k][0]:.2f} ms ({r['groups'][k][1]})" if len(r["groups"]) > k else "—"
        )

    def force_at(t_s):
        def f(r):
            for t, F in zip(r["t"], r["F"]):
                if abs(t - t_s) < 1e-6:
                    return f"{F[2]:.2f}"
            return "—"

        return f

    return markdown_table(
        rows,
        [
            ("bodies", lambda r: str(r["bodies"])),
            ("first break-away (bristles)", group(0)),
            ("second break-away (bristles)", group(1)),
            ("third", group(2)),
            ("Fz at 1.070 s [N]", force_at(1.07)),
            ("Fz at 1.090 s [N]", force_at(1.09)),
            ("Fz at 1.100 s [N]", force_at(1.10)),
            ("status", lambda r: r["status"]),
        ],
    )


def format_element_table(rows) -> str:
    def pct(key):
        return lambda r: "—" if not math.isfinite(r[key]) else f"{100 * r[key]:.1f} %"

    return markdown_table(
        rows,
        [
            ("element", lambda r: r["element"]),
            ("bodies", lambda r: str(r["bodies"])),
            ("dt [ms]", lambda r: f"{1e3 * r['dt']:g}"),
            ("RMS F err vs converged", pct("rms_force_error_converged")),
            ("(circle)", pct("rms_force_error_converged_circle")),
            ("wall [s]", lambda r: f"{r['wall_s']:.1f}"),
            ("RTF", lambda r: f"{r['rtf']:.2f}"),
            ("Newton/step/bristle", lambda r: f"{r['newton_per_step_per_bristle']:.2f}"),
            ("status", lambda r: r["status"]),
        ],
    )


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "reduced grid and motion, no reference (for tests)")
    add_flag(p, "--write-reference", "recompute tests/data/flat_plate_turn_reference.npz first")
    add_flag(
        p,
        "--events",
        "instead of the table: the break-away (first sliding step of each bristle) at the "
        "circle's start, mid element at 3/6/12/24 bodies, 0.25 ms",
    )
    p.add_argument(
        "--repeats", type=int, default=1, help="runs per row; the fastest wall time is reported"
    )
