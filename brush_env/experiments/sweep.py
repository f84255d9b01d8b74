"""The reference experiment over the set-ups the paper leaves open (issue 17).

The head's yaw on the flange, the circle's direction and P0's polar angle are not printed in the
paper (docs/reference_experiment.md, "Set-up"); each run here changes them and records both
jamming angles (mean over turns 2-4, modulo 2π) and their peak forces.

    python -m brush_env.experiments.sweep [--out runs/setup_sweep] [--element mid] [--json]

prints a Markdown table (``--json``: one object per set-up).  Each set-up is one
``run_reference`` (four turns, ~1 min on one core at the defaults), its files in its own folder
under ``--out``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from .run import run_reference

#: (head yaw [deg], P0 polar angle [deg], clockwise): the yaws the flange allows at right angles,
#: both directions, and P0 a quarter turn on (the same physics as a 90 deg yaw, rigidly rotated)
SETUPS = (
    (0.0, 180.0, False),
    (0.0, 180.0, True),
    (90.0, 180.0, False),
    (90.0, 180.0, True),
    (180.0, 180.0, False),
    (270.0, 180.0, False),
    (0.0, 90.0, False),
)


def sweep(out_dir="runs/setup_sweep", setups=SETUPS, **run_kwargs) -> list[dict]:
    """One reference run per set-up; rows with both jamming events (angle, offset from the
    paper's, |F_h|, Fx, Fy) and the run's status."""
    rows = []
    for yaw, p0, cw in setups:
        tag = f"yaw{yaw:g}_p0{p0:g}_{'cw' if cw else 'ccw'}"
        s = run_reference(
            out_dir=Path(out_dir) / tag,
            head_yaw_deg=yaw,
            p0_angle_deg=p0,
            clockwise=cw,
            progress=False,
            plots=False,
            **run_kwargs,
        )
        jam = (s["analysis"]["baseline"].get("jamming") or {}).get("events", {})
        row = dict(head_yaw_deg=yaw, p0_angle_deg=p0, clockwise=cw, status=s["status"])
        for name in ("9π/4", "13π/4"):
            ev = jam.get(name) or {}
            row[name] = {
                k: ev.get(k)
                for k in (
                    "count",
                    "mean_angle_mod_2pi_deg",
                    "mean_offset_from_paper_deg",
                    "angle_std_deg",
                    "mean_Fh_N",
                    "mean_Fx_N",
                    "mean_Fy_N",
                )
            }
        rows.append(row)
    return rows


def format_table(rows) -> str:
    def ev(r, name):
        e = r[name]
        if not e.get("count"):
            return "— | — | —"
        return (
            f"{e['mean_angle_mod_2pi_deg']:.1f}° ({e['mean_offset_from_paper_deg']:+.1f}°) | "
            f"{e['mean_Fh_N']:.3f} | {e['mean_Fx_N']:+.3f} / {e['mean_Fy_N']:+.3f}"
        )

    head = (
        "| head yaw [deg] | P0 [deg] | direction | 9π/4 event: angle (offset) | F_h [N] | "
        "Fx / Fy [N] | 13π/4 event: angle (offset) | F_h [N] | Fx / Fy [N] | status |\n"
        "|---|---|---|---|---|---|---|---|---|---|"
    )
    lines = [head]
    for r in rows:
        d = "clockwise" if r["clockwise"] else "counter-clockwise"
        lines.append(
            f"| {r['head_yaw_deg']:g} | {r['p0_angle_deg']:g} | {d} | {ev(r, '9π/4')} | "
            f"{ev(r, '13π/4')} | {r['status']} |"
        )
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m brush_env.experiments.sweep", description=__doc__)
    p.add_argument("--out", default="runs/setup_sweep", help="output folder (one per set-up)")
    p.add_argument("--element", choices=("mid", "paper"), default="mid", help="beam element")
    p.add_argument("--json", action="store_true", help="one JSON object per set-up")
    a = p.parse_args(argv)
    rows = sweep(a.out, element=a.element)
    if a.json:
        for r in rows:
            print(json.dumps(r, ensure_ascii=False))
    else:
        print(format_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
