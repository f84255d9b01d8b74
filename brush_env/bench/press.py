"""``bench press``: the 3 mm press's hold force at every step size, against the small-step run.

The default ``flat_plate`` scene (40 bristles, tip–tip on), tips touching at t = 0, pressed 3 mm
along the bristle axis in 0.5 s (minimum jerk) and held 0.25 s: the TCP force at the end of the
hold is an equilibrium, so every step size should give the same value — unless a step is long
enough to hold an unstable column (backward Euler and BDF2 map a buckling mode that grows faster
than ~1/dt onto a decaying one) and the brush settles on another buckling branch.

Rows: bodies {3, 6} x integrator {bdf2, euler} x dt {0.5, 1, 2, 4, 5, 10, 25, 50} ms, each with
the default ``SimSettings.max_substep`` (1 ms: a longer step runs as equal internal steps) and
with the split off (``max_substep = dt``; one row where dt is within the limit), against the
same bodies and integrator at dt = 0.125 ms.  The force is the norm of the TCP force at the
end of the hold [N].

    brush-env bench press [--json] [--quick]
"""

from __future__ import annotations

import math

import numpy as np

from ..engine import SimSettings
from .contact import simulate_contact, warm_kernels
from .harness import emit, markdown_table, open_log

PRESS_GRID_FULL = dict(
    bodies=(3, 6),
    integrators=("bdf2", "euler"),
    dts=(5e-4, 1e-3, 2e-3, 4e-3, 5e-3, 1e-2, 2.5e-2, 5e-2),
    ref_dt=1.25e-4,
)
PRESS_GRID_QUICK = dict(bodies=(3,), integrators=("bdf2",), dts=(4e-3,), ref_dt=1e-3)
PRESS, HOLD = 0.5, 0.25  # [s]
MAX_SUBSTEP = SimSettings().max_substep  # [s] the default internal step limit


def _hold_force(bodies: int, dt: float, integ: str, max_substep: float):
    run = simulate_contact(bodies, dt, integ, True, PRESS, HOLD, 0.0, max_substep=max_substep)
    return run, (float(np.linalg.norm(run.F[-1])) if run.status == "ok" else math.nan)


def bench_press(args) -> int:
    """``brush-env bench press``: see the module docstring."""
    log = open_log(args)
    g = PRESS_GRID_QUICK if args.quick else PRESS_GRID_FULL
    warm_kernels()
    rows = []
    for bodies in g["bodies"]:
        for integ in g["integrators"]:
            print(f"  reference: {bodies} bodies, {integ}, dt={g['ref_dt']:g} ...", file=log)
            _, f_ref = _hold_force(bodies, g["ref_dt"], integ, g["ref_dt"])
            for dt in g["dts"]:
                # a step within the default max_substep is not split: one row
                for split in (True, False) if dt > MAX_SUBSTEP else (True,):
                    run, f = _hold_force(bodies, dt, integ, MAX_SUBSTEP if split else dt)
                    row = {
                        "bodies": bodies,
                        "integrator": integ,
                        "dt": dt,
                        "max_substep": min(dt, MAX_SUBSTEP) if split else dt,
                        "hold_force_N": f,
                        "reference_force_N": f_ref,
                        "rel_error": f / f_ref - 1.0,
                        "wall_s": run.wall,
                        "status": run.status,
                    }
                    rows.append(emit(args, row))
    if not args.json:
        print(format_press_table(rows))
    return 0


def format_press_table(rows) -> str:
    def err(r):
        e = r["rel_error"]
        bad = not math.isfinite(e) or abs(e) > 0.03
        return (
            ("**" if bad else "")
            + (f"{100 * e:+.1f} %" if math.isfinite(e) else "—")
            + ("**" if bad else "")
        )

    return markdown_table(
        rows,
        [
            ("bodies", lambda r: str(r["bodies"])),
            ("integrator", lambda r: r["integrator"]),
            ("dt [ms]", lambda r: f"{1e3 * r['dt']:g}"),
            ("internal step [ms]", lambda r: f"{1e3 * r['max_substep']:g}"),
            ("hold force [N]", lambda r: f"{r['hold_force_N']:.3f}"),
            ("0.125 ms run [N]", lambda r: f"{r['reference_force_N']:.3f}"),
            ("error", err),
            ("wall [s]", lambda r: f"{r['wall_s']:.2f}"),
            ("status", lambda r: r["status"]),
        ],
    )


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "one row against a 1 ms reference (for tests)")
