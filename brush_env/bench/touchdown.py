"""``bench touchdown``: one bristle landing on the plate while its root is dragged, as the
reference circle's brush lands (issue 29: where the fast model's force peaks come from).

The reference circle at ``fast`` peaked at 5.36 N on seed 1019 (2.26 N at ``balanced``): its
brush comes down at 7.5 mm/s while moving along the circle at 30 mm/s, and every tip sticks
where it lands while its root travels on.  This bench lands one bristle of each type of the
default brush (the validation scene of ``validate buckling``: the wide side along x, the 1 deg
lean toward +y, Table 2's friction, no gravity) the same way: its root moves at DOWN mm/s toward
the plate and LATERAL mm/s along each direction of DIRECTIONS, from the moment the tip touches,
for DURATION s; and once straight down at PRESS_SPEED (no drag).  Models: the full chain with
``calibration.FULL_BODIES`` mid-element bodies at ``FULL_DT`` (the calibration's converged
chain) against ``reduced`` (the reduced chain, 4 ms) and ``fast`` (the tip table over it, 4 ms).

Columns: the tip's normal force after the first ONSET mm of press (the first 4 ms step of the
landing), its peak, and its value at 1, 2 and 3 mm of lateral travel; for the straight press the
force-press slope below buckling against the column's axial stiffness E A / L (closed form: the
tip stuck, the load along the axis, the column straight below its buckling load).

    brush-env bench touchdown [--quick] [--json]
"""

from __future__ import annotations

import math
import time

import numpy as np

from .drag import bristle_scene
from .harness import emit, markdown_table, open_log

#: the landing's root velocity: toward the plate and along it [mm/s] (the reference circle's
#: touch-down on seed 1019: 7.5 mm/s down, 30 mm/s along the circle)
DOWN = 7.5
LATERAL = 30.0
#: how long the landing runs [s] (3.6 mm of lateral travel, 0.9 mm of press)
DURATION = 0.12
#: directions of the drag [deg from head x, the section's wide side]; the lean is toward +y
DIRECTIONS = (0.0, 45.0, 90.0, 180.0, -45.0, -90.0)
#: the straight press: speed [mm/s] and depth [mm] (past the buckling load of both default types)
PRESS_SPEED = 0.5
PRESS_DEPTH = 0.3
#: the onset's press [mm]: one 4 ms step of the landing
ONSET = DOWN * 0.004
#: lateral travels at which the force is read [mm]
AT = (1.0, 2.0, 3.0)
#: the models against the full chain: label -> (bristle model, solver step [s])
MODELS = {"reduced": ("prb", 4e-3), "fast": ("table", 4e-3)}


def landing(sim, angle_deg: float | None) -> np.ndarray:
    """(n, 3): press [mm], lateral travel [mm] and the tip's normal force [N] per step of the
    one-bristle ``sim``, its root moving from touch at (DOWN, LATERAL along ``angle_deg``) for
    DURATION s, or straight down at PRESS_SPEED to PRESS_DEPTH for ``angle_deg`` None."""
    from ..validation.buckling import R_DOWN

    dt = sim.settings.dt
    z0 = sim.touch_height(R_DOWN, 0.0)
    sim.reset(np.array([0.0, 0.0, z0]), R_DOWN)
    if angle_deg is None:
        vz, vl, d, n = PRESS_SPEED, 0.0, (0.0, 0.0), int(round(PRESS_DEPTH / PRESS_SPEED / dt))
    else:
        a = math.radians(angle_deg)
        vz, vl, d, n = DOWN, LATERAL, (math.cos(a), math.sin(a)), int(round(DURATION / dt))
    out = np.zeros((n, 3))
    for k in range(1, n + 1):
        t = k * dt
        res = sim.step(np.array([vl * t * d[0], vl * t * d[1], z0 - vz * t]), R_DOWN)
        out[k - 1] = (vz * t, vl * t, res.tip_normal_force[0])
    return out


def summary(tr: np.ndarray, straight: bool) -> dict:
    """The row of one ``landing`` trace: the force after ONSET mm of press and the peak [N];
    for the straight press (``straight``) the slope below buckling [N/mm], else the force at
    each lateral travel of AT [N]."""
    press, lat, fn = tr[:, 0], tr[:, 1], tr[:, 2]
    row = {"onset_N": float(np.interp(ONSET, press, fn)), "peak_N": float(fn.max())}
    if straight:
        # the slope below buckling: the force at a quarter of the peak over its press
        q = 0.25 * fn.max()
        k = int(np.argmax(fn >= q))
        row["slope_N_per_mm"] = float(fn[k] / press[k]) if k > 0 else float("nan")
    else:
        row.update({f"at_{a:g}mm_N": float(np.interp(a, lat, fn)) for a in AT})
    return row


def bristle_rows(quick: bool, log) -> list[dict]:
    """Every bristle type of the default brush, every direction and the straight press; the
    full chain and each model of MODELS."""
    from ..calibration import FULL_BODIES, FULL_DT
    from ..engine import SimSettings, Simulator, load_brush
    from ..engine import prb_calibration as pc

    no_g = (0.0, 0.0, 0.0)
    rows = []
    dirs: tuple = (None, *DIRECTIONS) if not quick else (None, -90.0)
    for _key, (br, lean) in pc.bristle_types(load_brush("default")).items():
        if quick and br.group != "outer":
            continue
        ea_l = br.material.E * br.section.area / br.length
        for ang in dirs:
            what = "straight press" if ang is None else f"landing toward {ang:+.0f} deg"
            print(f"  one {br.group} bristle, {what} ...", file=log)
            t0 = time.perf_counter()
            full = Simulator(
                bristle_scene(br, lean, FULL_BODIES), SimSettings(dt=FULL_DT, gravity=no_g)
            )
            row = {
                "bristle": br.group,
                "motion": what,
                "EA_over_L_N_per_mm": ea_l,
                "full": summary(landing(full, ang), ang is None),
            }
            for label, (model, dt) in MODELS.items():
                # one solver step per engine step, as the levels run (``max_substep`` = dt;
                # SimSettings' default would cut it into 1 ms sub-steps, where a landing took
                # the full chain's branch even when the env's 4 ms step did not)
                sim = Simulator(
                    bristle_scene(br, lean, 2),
                    SimSettings(dt=dt, max_substep=dt, model=model, gravity=no_g),
                )
                row[label] = summary(landing(sim, ang), ang is None)
            row["wall_s"] = time.perf_counter() - t0
            rows.append(row)
    return rows


def _n(x: float) -> str:
    return f"{x:.4f}"


def format_table(rows: list[dict]) -> str:
    def trio(key):
        return lambda r: " / ".join(
            _n(r[m][key]) if key in r[m] else "-" for m in ("full", *MODELS)
        )

    cols = [
        ("bristle", lambda r: r["bristle"]),
        ("root motion", lambda r: r["motion"]),
        (f"normal force after {ONSET:g} mm [N]", trio("onset_N")),
        ("peak [N]", trio("peak_N")),
    ]
    cols += [(f"at {a:g} mm lateral [N]", trio(f"at_{a:g}mm_N")) for a in AT]
    cols.append(
        (
            "slope below buckling [N/mm] (E A / L)",
            lambda r: (
                " / ".join(_n(r[m]["slope_N_per_mm"]) for m in ("full", *MODELS))
                + f" ({r['EA_over_L_N_per_mm']:.3f})"
                if "slope_N_per_mm" in r["full"]
                else "-"
            ),
        )
    )
    head = "every cell: full chain / " + " / ".join(MODELS) + "\n\n"
    return head + markdown_table(rows, cols)


def bench_touchdown(args) -> int:
    """``brush-env bench touchdown``: see the module docstring."""
    log = open_log(args)
    rows = [emit(args, r) for r in bristle_rows(args.quick, log)]
    if not args.json:
        print(format_table(rows))
    return 0


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "the outer type only, the straight press and one landing (for tests)")
