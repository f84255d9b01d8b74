"""``bench convergence``: the ``bench contact`` motion (BDF2, tip-tip on) at 6 bodies for
dt = 1, 0.5, 0.25, 0.125 ms, each against the finest, and at dt = 0.25 ms for 6, 12, 24 bodies,
each against 24: how far from converged the contact run is in time step and in bodies
(self-convergence).  A third series, "lag", repeats the time-step series with one sweep per step
(``tip_tip_sweeps = 1``: the partner tips held, not solved with) against the same finest coupled
run: the floor the tip-tip lag leaves.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from .contact import (
    CONTACT_GRID_FULL,
    CONTACT_GRID_QUICK,
    arc_seconds,
    contact_errors,
    simulate_contact,
)
from .harness import markdown_table, open_log

#: ``bench convergence``: how far the contact run (``bench contact``'s motion, BDF2, tip-tip on) is
#: from converged, in time step (6 bodies) and in bodies per bristle (dt = 2.5e-4 s).
CONVERGENCE_GRID_FULL = dict(dts=(1e-3, 5e-4, 2.5e-4, 1.25e-4), bodies=(6, 12, 24), body_dt=2.5e-4)
CONVERGENCE_GRID_QUICK = dict(dts=(1e-3, 5e-4, 2.5e-4, 1.25e-4), bodies=(3, 6), body_dt=1e-3)


def bench_convergence(args) -> int:
    """Self-convergence of the contact benchmark: each row's RMS TCP-force error (as in ``bench
    contact``, whole run and circle) against the finest run of its series -- the smallest dt at 6
    bodies, and the most bodies at a fixed small dt.  It bounds what any setting can reach: the
    time-step series shows the solver's own floor (stick-slip branches), the body series the
    discretisation's."""
    g = CONVERGENCE_GRID_QUICK if args.quick else CONVERGENCE_GRID_FULL
    c = CONTACT_GRID_QUICK if args.quick else CONTACT_GRID_FULL
    c = dict(c, arc=arc_seconds(c))
    motion = (c["press"], c["hold"], c["arc"])
    open_log(args)
    rows = []
    nb_dt = 6 if not args.quick else 3
    series = (
        [("dt", nb_dt, dt) for dt in g["dts"]]
        + [("bodies", b, g["body_dt"]) for b in g["bodies"]]
        + [("lag", nb_dt, dt) for dt in g["dts"]]
    )
    runs = {}
    for kind, bodies, dt in series:
        print(f"  {kind}: {bodies} bodies, dt={dt:g} ...", file=sys.stderr, flush=True)
        extra = {"tip_tip_sweeps": 1 if kind == "lag" else 8}
        runs[(kind, bodies, dt)] = simulate_contact(bodies, dt, "bdf2", True, *motion, **extra)
    for kind in ("dt", "bodies", "lag"):
        keys = [k for k in runs if k[0] == kind]
        # the lag series is measured against the coupled series' finest run
        finest = [k for k in runs if k[0] == "dt"][-1] if kind == "lag" else keys[-1]
        ref = runs[finest]
        grid = np.arange(0.0, ref.t[-1] + 1e-12, c["sample"])
        for k in keys:
            run = runs[k]
            whole, circ = contact_errors(run, ref, grid) if k != finest else (0.0, 0.0)
            row = {
                "series": kind,
                "bodies": k[1],
                "dt": k[2],
                "integrator": "bdf2",
                "tip_tip": True,
                "tip_tip_sweeps": 1 if kind == "lag" else "coupled",
                "against": f"{finest[1]} bodies, dt={finest[2]:g}",
                "rms_force_error": whole,
                "rms_force_error_circle": circ,
                "wall_s": run.wall,
                "rtf": run.t[-1] / run.wall,
                "status": run.status,
            }
            rows.append(row)
            if args.json:
                print(json.dumps(row), flush=True)
    if not args.json:
        print(
            markdown_table(
                rows,
                [
                    ("series", lambda r: r["series"]),
                    ("bodies", lambda r: str(r["bodies"])),
                    ("dt [s]", lambda r: f"{r['dt']:g}"),
                    ("tip-tip", lambda r: str(r["tip_tip_sweeps"])),
                    ("against", lambda r: r["against"]),
                    ("RMS F err", lambda r: f"{r['rms_force_error']:.2e}"),
                    ("RMS F err (circle)", lambda r: f"{r['rms_force_error_circle']:.2e}"),
                    ("wall [s]", lambda r: f"{r['wall_s']:.1f}"),
                    ("RTF", lambda r: f"{r['rtf']:.3g}"),
                    ("status", lambda r: r["status"]),
                ],
            )
        )
    return 0
