"""``bench branch``: does a faster step keep the small-step buckling branch? (issue 15)

The reference experiment (``run_reference``: 3 mm press, hold, the MoveL circle, the default
set-up) over two turns, for bodies {3, 6} x lean {0.5, 1, 2} deg x integrator {bdf2, euler} x dt
{1, 2, 4, 5} ms (``SimSettings.max_substep`` at its default, 1 ms: steps above it run as internal
1 ms steps), each against the same bodies, lean and integrator at dt = 0.25 ms.  A row agrees
when the horizontal force of the hold points the same way (the sign of every component whose
small-step value exceeds 0.1 N) and both jamming events are found within 5 deg of the small-step
run's (the 9pi/4 event in turn 2, the 13pi/4 event in turns 1-2).  ``--no-split`` runs the same
grid with the split off (max_substep = dt): the solver at the step it names.

    brush-env bench branch [--json] [--quick] [--no-split]
"""

from __future__ import annotations

import math
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from .harness import emit, markdown_table, open_log
from .press import MAX_SUBSTEP

BRANCH_GRID_FULL = dict(
    bodies=(3, 6),
    leans=(0.5, 1.0, 2.0),
    integrators=("bdf2", "euler"),
    dts=(1e-3, 2e-3, 4e-3, 5e-3),
    ref_dt=2.5e-4,
    turns=2.0,
)
BRANCH_GRID_QUICK = dict(
    bodies=(3,), leans=(1.0,), integrators=("bdf2",), dts=(4e-3,), ref_dt=1e-3, turns=0.3
)
ANGLE_TOL_DEG = 5.0
HOLD_FORCE_MIN = 0.1  # [N] hold-force components below this carry no branch sign


def run_case(bodies: int, lean_deg: float, integrator: str, dt: float, split: bool, turns: float):
    """One reference run (no figures): the hold's mean (Fx, Fy) over its last 0.1 s [N] and the
    two jamming events' mean angles mod 2pi [deg] (None where not found)."""
    from ..engine import load_brush
    from ..experiments.run import run_reference

    brush = load_brush("default").with_bodies(bodies)
    brush = replace(brush, lean=math.radians(lean_deg))
    with tempfile.TemporaryDirectory() as tmp:
        s = run_reference(
            brush=brush,
            out_dir=tmp,
            turns=turns,
            dt=dt,
            integrator=integrator,
            max_substep=None if split else dt,
            progress=False,
            plots=False,
        )
        data = np.genfromtxt(Path(tmp) / "timeseries.csv", delimiter=",", names=True)
    hold = data["phase"] == 1
    t_hold = data["time_s"][hold]
    last = hold & (data["time_s"] >= t_hold.max() - 0.1) if hold.any() else hold
    F_hold = [float(np.mean(data["Fx_N"][last])), float(np.mean(data["Fy_N"][last]))]
    jam = (s["analysis"]["baseline"].get("jamming") or {}).get("events", {})
    angles = {k: (jam.get(k) or {}).get("mean_angle_mod_2pi_deg") for k in ("9π/4", "13π/4")}
    return {"status": s["status"], "hold_F_N": F_hold, "jam_deg": angles}


def _agrees(row: dict, ref: dict) -> tuple[bool, str]:
    """(agrees, why not) of a row against its small-step run."""
    if row["status"] != "ok":
        return False, row["status"]
    for c, (a, b) in enumerate(zip(row["hold_F_N"], ref["hold_F_N"])):
        if abs(b) > HOLD_FORCE_MIN and np.sign(a) != np.sign(b):
            return False, f"hold F{'xy'[c]} {a:+.2f} N vs {b:+.2f} N"
    for k, b in ref["jam_deg"].items():
        a = row["jam_deg"][k]
        if (a is None) != (b is None):
            return False, f"{k} event {'missing' if a is None else 'extra'}"
        if a is not None and abs((a - b + 180.0) % 360.0 - 180.0) > ANGLE_TOL_DEG:
            return False, f"{k} at {a:.1f} deg vs {b:.1f} deg"
    return True, ""


def bench_branch(args) -> int:
    """``brush-env bench branch``: see the module docstring."""
    open_log(args)
    g = BRANCH_GRID_QUICK if args.quick else BRANCH_GRID_FULL
    split = not args.no_split
    rows = []
    for bodies in g["bodies"]:
        for lean in g["leans"]:
            for integ in g["integrators"]:
                print(f"  {bodies} bodies, lean {lean:g} deg, {integ} ...", file=sys.stderr)
                ref = run_case(bodies, lean, integ, g["ref_dt"], True, g["turns"])
                for dt in g["dts"]:
                    run = run_case(bodies, lean, integ, dt, split, g["turns"])
                    ok, why = _agrees(run, ref)
                    row = dict(
                        bodies=bodies,
                        lean_deg=lean,
                        integrator=integ,
                        dt=dt,
                        max_substep=min(dt, MAX_SUBSTEP) if split else dt,
                        ref_dt=g["ref_dt"],
                        hold_F_N=run["hold_F_N"],
                        ref_hold_F_N=ref["hold_F_N"],
                        jam_deg=run["jam_deg"],
                        ref_jam_deg=ref["jam_deg"],
                        agrees=ok,
                        why=why,
                        status=run["status"],
                    )
                    rows.append(emit(args, row))
    if not args.json:
        print(format_branch_table(rows))
    return 0


def format_branch_table(rows) -> str:
    def ang(d):
        return " / ".join("—" if d[k] is None else f"{d[k]:.1f}" for k in ("9π/4", "13π/4"))

    return markdown_table(
        rows,
        [
            ("bodies", lambda r: str(r["bodies"])),
            ("lean [deg]", lambda r: f"{r['lean_deg']:g}"),
            ("integrator", lambda r: r["integrator"]),
            ("dt [ms]", lambda r: f"{1e3 * r['dt']:g}"),
            ("solver step [ms]", lambda r: f"{1e3 * r['max_substep']:g}"),
            ("hold Fx, Fy [N]", lambda r: "{:+.2f}, {:+.2f}".format(*r["hold_F_N"])),
            ("small-step", lambda r: "{:+.2f}, {:+.2f}".format(*r["ref_hold_F_N"])),
            ("jams [deg]", lambda r: ang(r["jam_deg"])),
            ("small-step jams", lambda r: ang(r["ref_jam_deg"])),
            ("agrees", lambda r: "yes" if r["agrees"] else f"**no**: {r['why']}"),
        ],
    )


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "one row, a third of a turn (for the tests)")
    add_flag(p, "--no-split", "run each dt as one solver step (max_substep = dt)")
