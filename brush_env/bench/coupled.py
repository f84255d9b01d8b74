"""``brush-env bench coupled``: what the coupled tip-tip solve costs and how close it lands, on
the paper turn (issue 32, items 3 and the first done-line).

The motion is ``bench element``'s flat-plate turn (default brush, 40 bristles, tips touching the
plate at t = 0, 3 mm press in 0.5 s, 0.25 s hold, one turn of the 20 mm circle: 7.234 s) at
``--bodies`` mid-element bodies, BDF2.  Every row runs it at a step (``--dt``) with a number of
tip-tip sweeps (1: one sweep, partners lagged; more: the coupled solve) and a partner tolerance
(``tip_tip_tol``), against the same bodies at 0.125 ms, coupled (the done-line's "same bodies
at 0.125 ms"; computed first, or read back from ``--reference FILE`` when that file holds a run
of the same bodies).  Per row, by the measures of ``fidelity_metrics`` (docs/benchmarks.md):

* CPU time of the stepping loop [s] (``time.process_time`` of the ``Simulator.follow`` calls,
  after a short run that compiles) and its real-time factor (simulated seconds per CPU second);
  beside it the CPU of the whole run with the set-up (scene, simulator, trajectory) and the
  bench's per-step observer (until session 37 the only figure, though this said "stepping
  loop": 2-4 % more);
* Newton iterations per bristle-step; sweeps and bristle re-solves per step (``solver_info``),
  and the share of steps that ran out of sweeps or fell back to the plain sweep;
* the TCP force's pooled RMS error on the 5 ms grid, the same outside +-10 ms of the reference's
  stick->slip events, its phase means (press, hold, sliding) and the event-time error (median and
  largest |dt| of the matched events, matched / reference events).

    brush-env bench coupled [--bodies 6] [--dt 0.001] [--sweeps 1 8] [--tol 1e-6]
        [--reference FILE] [--write-reference FILE] [--json]

With ``--ensemble K`` every setting runs K times, its path moved along the plate by k x
ENSEMBLE_SHIFT (k = 0 .. K-1; 1e-9 mm: nothing physically, but every position rounds
differently), and a summary row per setting gives each measure's mean and range.  On this turn a
single run's RMS and CPU are samples: marginal stick-slip releases go one way or the other on
last-place differences (docs/benchmarks.md, session 32), so a change is judged on the ensemble.

The reference at 0.125 ms takes ~3 min of one core at 6 bodies; a row at 1 ms 10-45 s.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np

from . import fidelity_metrics as fm
from .harness import emit, markdown_table, open_log, print_machine

REFERENCE_DT = 1.25e-4  # [s] the done-line's "same bodies at 0.125 ms"
REFERENCE_SWEEPS = 8
REFERENCE_TOL = 1e-6  # [mm]
SAMPLE = 5e-3  # [s] comparison grid (bench element's)
#: [mm] the path's shift between two members of an ensemble (``--ensemble``): 1 pm, ~1e-10 of
#: the positions, far above their last place and far below anything physical
ENSEMBLE_SHIFT = 1e-9
#: measures an ensemble's summary row averages (mean, min, max)
ENSEMBLE_KEYS = (
    "cpu_s",
    "rtf_cpu",
    "newton_per_bristle_step",
    "sweeps_per_step",
    "resolves_per_step",
    "fallback_share",
    "rms",
    "rms_outside_events",
    "phase_press",
    "phase_hold",
    "phase_sliding",
    "event_median_ms",
    "event_max_ms",
    "events_matched",
)


def turn_run(bodies: int, dt: float, sweeps: int, tol: float, shift: float = 0.0) -> dict:
    """One turn (module docstring), its path moved ``shift`` [mm] along the plate: times [s],
    TCP force [N] (n, 3), per engine step the tips' sliding and in-contact flags (n, 40), the CPU
    time of the loop [s], Newton iterations, sweeps, re-solves, unsettled and fallen-back steps,
    and the status."""
    from .contact import CONTACT_GRID_FULL as G
    from .contact import arc_seconds, simulate_contact

    extra = dict(tip_tip_sweeps=sweeps, tip_tip_tol=tol)
    simulate_contact(bodies, dt, "bdf2", True, 0.01, 0.0, 0.0, **extra)  # compile outside
    flags: dict[str, list] = {"sl": [], "ic": []}
    solver = np.zeros(4)
    sims = []

    def observe(t, out):
        flags["sl"].append(out.tip_sliding.copy())
        flags["ic"].append(out.tip_in_contact.copy())
        e = out.extra
        solver[:] += [
            e.get("sweeps", 1),
            e.get("resolves", 0),
            not e.get("tip_tip_settled", True),
            e.get("tip_tip_fallback", False),
        ]
        sims.append(t)

    t0 = time.process_time()  # the whole run (set-up and observer too): cpu_total_s
    run = simulate_contact(
        bodies,
        dt,
        "bdf2",
        True,
        G["press"],
        G["hold"],
        arc_seconds(G),
        observe=observe,
        shift=shift,
        **extra,
    )
    cpu = time.process_time() - t0
    n = max(len(sims), 1)
    return {
        "bodies": bodies,
        "dt": dt,
        "sweeps": sweeps,
        "tol": tol,
        "shift_mm": shift,
        "t": run.t,
        "F": run.F,
        "event_t": np.asarray(sims),
        "sliding": np.asarray(flags["sl"]),
        "in_contact": np.asarray(flags["ic"]),
        "cpu_s": run.cpu,
        "cpu_total_s": cpu,
        "newton_per_bristle_step": run.newton / max(run.steps, 1) / run.n_bristles,
        "sweeps_per_step": solver[0] / n,
        "resolves_per_step": solver[1] / n,
        "unsettled_share": solver[2] / n,
        "fallback_share": solver[3] / n,
        "status": run.status,
    }


def save_reference(path: Path, ref: dict) -> None:
    np.savez_compressed(
        path,
        **{k: np.asarray(ref[k]) for k in ("t", "F", "event_t", "sliding", "in_contact")},
        bodies=ref["bodies"],
        dt=ref["dt"],
        cpu_s=ref["cpu_s"],
    )


def load_reference(path: Path, bodies: int) -> dict | None:
    """The reference stored at ``path`` if it is a run of ``bodies`` bodies, else None."""
    if not path.exists():
        return None
    z = np.load(path)
    if int(z["bodies"]) != bodies:
        return None
    return {k: z[k] for k in z.files}


def compare(run: dict, ref: dict) -> dict:
    """The row's errors against the reference (module docstring)."""
    from .contact import CONTACT_GRID_FULL as G
    from .fidelity import turn_phases

    if run["status"] != "ok":
        return {"status": run["status"]}
    grid = np.arange(0.0, float(ref["t"][-1]) + 1e-12, SAMPLE)
    Fr = fm.on_grid(grid, ref["t"], ref["F"])
    F = fm.on_grid(grid, run["t"], run["F"])
    phases = turn_phases(G["press"], G["hold"], float(grid[-1]))
    pe = fm.phase_mean_errors(fm.phase_means(grid, F, phases), fm.phase_means(grid, Fr, phases))
    rev = fm.long_stick_events(
        fm.stick_slip_events(ref["event_t"], ref["sliding"], ref["in_contact"])
    )
    ev = fm.long_stick_events(
        fm.stick_slip_events(run["event_t"], run["sliding"], run["in_contact"])
    )
    m = fm.match_events(rev, ev)
    mask = fm.event_mask(grid, rev[1], fm.EVENT_HALF_WIDTH)
    return {
        "rms": fm.pooled_rms_error([(F, Fr)]),
        "rms_outside_events": fm.rms_error_outside(F, Fr, mask),
        "phase_press": pe["press"],
        "phase_hold": pe["hold"],
        "phase_sliding": pe["sliding"],
        "event_median_ms": m["median_abs_ms"],
        "event_max_ms": m["max_abs_ms"],
        "events_matched": m["n_matched"],
        "events_ref": m["n_ref"],
    }


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    p.add_argument("--bodies", type=int, default=6, help="bodies per bristle (default 6)")
    p.add_argument("--dt", type=float, nargs="+", default=[1e-3], help="steps [s] (1e-3)")
    p.add_argument("--sweeps", type=int, nargs="+", default=[1, 8], help="tip-tip sweeps (1 8)")
    p.add_argument("--tol", type=float, nargs="+", default=[1e-6], help="tip_tip_tol [mm]")
    p.add_argument(
        "--ensemble",
        type=int,
        default=1,
        help="runs per setting, each path moved 1e-9 mm more along the plate; a summary row "
        "per setting (mean and range) (1)",
    )
    p.add_argument(
        "--reference",
        default=None,
        help="read the 0.125 ms reference from this .npz (computed and not kept if absent)",
    )
    p.add_argument(
        "--write-reference", default=None, help="compute the reference and store it here (.npz)"
    )


def bench_coupled(args) -> int:
    """``brush-env bench coupled``: see the module docstring."""
    from ..user_errors import UserError

    if args.bodies < 1:
        raise UserError(f"--bodies = {args.bodies}: must be >= 1")
    for dt in args.dt:
        if not 0.0 < dt <= 4e-3:
            raise UserError(f"--dt {dt}: must be in (0, 0.004] s")
    if not 1 <= args.ensemble <= 100:
        raise UserError(f"--ensemble = {args.ensemble}: must be in [1, 100]")
    log = open_log(args)
    ref = load_reference(Path(args.reference), args.bodies) if args.reference else None
    if ref is None:
        print(f"reference: {args.bodies} bodies at 0.125 ms, coupled ...", file=log, flush=True)
        ref = turn_run(args.bodies, REFERENCE_DT, REFERENCE_SWEEPS, REFERENCE_TOL)
        if ref["status"] != "ok":
            raise RuntimeError(f"the reference run did not finish: {ref['status']}")
        out = args.write_reference or args.reference
        if out:
            save_reference(Path(out), ref)
    rows = []
    summaries = []
    for dt in args.dt:
        for sweeps in args.sweeps:
            for tol in args.tol if sweeps > 1 else args.tol[:1]:
                members = []
                for member in range(args.ensemble):
                    shift = member * ENSEMBLE_SHIFT
                    print(
                        f"  dt {dt:g} s, {sweeps} sweep(s), tol {tol:g} mm, shift {shift:g} mm ...",
                        file=log,
                        flush=True,
                    )
                    run = turn_run(args.bodies, dt, sweeps, tol, shift)
                    row = {k: v for k, v in run.items() if not isinstance(v, np.ndarray)} | compare(
                        run, ref
                    )
                    row["rtf_cpu"] = (
                        float(run["t"][-1]) / row["cpu_s"] if row["cpu_s"] > 0 else math.nan
                    )
                    members.append(emit(args, row))
                rows += members
                if args.ensemble > 1:
                    summaries.append(emit(args, ensemble_summary(members)))
    if not args.json:
        print_machine(log)
        print(_table(rows), file=log)
        if summaries:
            print(f"\nensembles of {args.ensemble} (mean, [min, max]):", file=log)
            print(_summary_table(summaries), file=log)
    return 0


def ensemble_summary(members: list[dict]) -> dict:
    """One setting's ensemble: for each of ENSEMBLE_KEYS its mean, min and max over the members
    that finished (``<key>``, ``<key>_min``, ``<key>_max``), and how many finished."""
    ok = [m for m in members if m["status"] == "ok"]
    head = members[0]
    out: dict = {k: head[k] for k in ("bodies", "dt", "sweeps", "tol")}
    out |= {"ensemble": len(members), "finished": len(ok), "status": "ok" if ok else "failed"}
    for key in ENSEMBLE_KEYS:
        vals = np.array([float(m[key]) for m in ok if key in m])
        if vals.size:
            out[key] = float(vals.mean())
            out[key + "_min"] = float(vals.min())
            out[key + "_max"] = float(vals.max())
    return out


#: the columns that name a row's setting (both tables)
_SETTING_COLUMNS = [
    ("dt [ms]", lambda r: f"{1e3 * r['dt']:g}"),
    ("sweeps", lambda r: str(r["sweeps"])),
    ("tol [mm]", lambda r: f"{r['tol']:g}" if r["sweeps"] > 1 else "—"),
]


def _summary_table(rows: list[dict]) -> str:
    def rng(key, scale, fmt):
        def cell(r):
            if key not in r:
                return "—"
            v, lo, hi = (scale * r[key + s] for s in ("", "_min", "_max"))
            return f"{v:{fmt}} [{lo:{fmt}}, {hi:{fmt}}]"

        return cell

    return markdown_table(
        rows,
        [
            *_SETTING_COLUMNS,
            ("runs", lambda r: f"{r['finished']}/{r['ensemble']}"),
            ("CPU [s]", rng("cpu_s", 1.0, ".2f")),
            ("sim s / CPU s", rng("rtf_cpu", 1.0, ".2f")),
            ("Newton it. / bristle-step", rng("newton_per_bristle_step", 1.0, ".2f")),
            ("re-solves / step", rng("resolves_per_step", 1.0, ".1f")),
            ("RMS F [%]", rng("rms", 100.0, ".2f")),
            ("RMS outside events [%]", rng("rms_outside_events", 100.0, ".2f")),
            ("sliding phase [%]", rng("phase_sliding", 100.0, "+.2f")),
            ("event |dt| max [ms]", rng("event_max_ms", 1.0, ".1f")),
            ("events matched", rng("events_matched", 1.0, ".1f")),
        ],
    )


def _table(rows: list[dict]) -> str:
    def pct(k):
        return lambda r: "—" if k not in r else f"{100 * r[k]:.2f} %"

    return markdown_table(
        rows,
        [
            *_SETTING_COLUMNS,
            ("CPU [s]", lambda r: f"{r['cpu_s']:.2f}"),
            ("with set-up [s]", lambda r: f"{r['cpu_total_s']:.2f}"),
            ("sim s / CPU s", lambda r: f"{r['rtf_cpu']:.2f}"),
            ("Newton it. / bristle-step", lambda r: f"{r['newton_per_bristle_step']:.2f}"),
            ("sweeps / step", lambda r: f"{r['sweeps_per_step']:.2f}"),
            ("re-solves / step", lambda r: f"{r['resolves_per_step']:.1f}"),
            ("fallback", pct("fallback_share")),
            ("RMS F", pct("rms")),
            ("RMS outside events", pct("rms_outside_events")),
            (
                "press / hold / sliding",
                lambda r: (
                    "—"
                    if "rms" not in r
                    else (
                        f"{100 * r['phase_press']:+.2f} / {100 * r['phase_hold']:+.2f} / "
                        f"{100 * r['phase_sliding']:+.2f} %"
                    )
                ),
            ),
            (
                "event |dt| median / max [ms]",
                lambda r: (
                    "—"
                    if "rms" not in r
                    else (f"{r['event_median_ms']:.2f} / {r['event_max_ms']:.2f}")
                ),
            ),
            (
                "events matched",
                lambda r: "—" if "rms" not in r else (f"{r['events_matched']}/{r['events_ref']}"),
            ),
            ("status", lambda r: r["status"]),
        ],
    )
