"""``bench drag``: a pressed brush dragged along the plate, toward the bristles' wide and thin
sides, at each fidelity level against the converged chain (issue 29: what the reduced model's
sliding-phase error comes from).

Two parts, both with the paper's friction (Table 2) and no gravity:

(a) **One bristle** of each type of the default brush (the validation scene of ``validate
    buckling``: the wide side along x, the 1 deg lean toward +y), pressed DRAG_PRESS of its
    length in 0.25 s (minimum jerk), held 0.05 s, then dragged 12 mm at 10 mm/s along x (toward
    the wide side) or y (the thin side): the mean normal and tangential tip force over the last
    3 mm, and the travel at which the tip first slides.  The full chain with 12 mid-element
    bodies at 0.5 ms (within 0.1 % of 24 bodies here) against the reduced model.
(b) **The default brush** (40 bristles, tip-tip on) pressed 2.5 mm in 0.5 s, held 0.2 s,
    dragged 1 s at 10 mm/s along x or y, at each level (its own solver step): the mean total
    tip normal force and the mean lateral TCP force over the last 0.5 s, against the first
    level given (``reference`` by default; ~100 s per direction on one core).

    brush-env bench drag [--levels reference balanced fast reduced] [--quick] [--json]
"""

from __future__ import annotations

import dataclasses
import time

import numpy as np

from .harness import emit, markdown_table, open_log

#: (a) the drag's travel [mm] and the stretch at its end over which the forces are averaged
#: [mm]; the press (L / 4) and the speed (10 mm/s, also (b)'s) are the calibration's
#: (``calibration.DRAG_PRESS``, ``DRAG_SPEED``)
TRAVEL = 12.0
MEASURE = 3.0
#: (b) the brush's press [mm] and drag time [s], averaged over its last AVERAGE [s]
BRUSH_PRESS = 2.5
BRUSH_DRAG = 1.0
AVERAGE = 0.5
DIRECTIONS = {"wide (x)": (1.0, 0.0), "thin (y)": (0.0, 1.0)}


def _min_jerk(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return 10 * s**3 - 15 * s**4 + 6 * s**5


def bristle_scene(br, lean: float, bodies: int):
    """One bristle of ``br``'s type alone on the plate, friction on (Table 2)."""
    from ..calibration import bristle_case
    from ..engine.scene import ContactParams

    case = bristle_case(br, lean, "free", bodies)
    return dataclasses.replace(case.scene(), contact=ContactParams())


def drag_bristle(sim, length: float, direction) -> dict:
    """(a) on the one-bristle ``sim``: mean normal and tangential tip force [N] over the drag's
    last MEASURE mm, the travel [mm] at which the tip first slides (NaN: it never did); the
    protocol is the calibration's drag (``calibration.drag_trace``)."""
    from ..calibration import drag_trace

    tr = drag_trace(sim, length, direction, TRAVEL)
    u = tr[:, 0]
    slid = np.flatnonzero((u > 0.0) & (tr[:, 3] > 0.0))
    last = u >= TRAVEL - MEASURE
    return {
        "fn_N": float(np.mean(tr[last, 1])),
        "ft_N": float(np.mean(tr[last, 2])),
        "slides_at_mm": float(u[slid[0]]) if slid.size else float("nan"),
    }


def bristle_rows(quick: bool, log) -> list[dict]:
    """(a) for every bristle type of the default brush, both directions, the full chain (the
    calibration's converged one: ``calibration.FULL_BODIES`` bodies at ``FULL_DT``) and reduced."""
    from ..calibration import FULL_BODIES, FULL_DT
    from ..engine import SimSettings, Simulator, load_brush
    from ..engine import prb_calibration as pc

    rows = []
    no_g = (0.0, 0.0, 0.0)
    for _key, (br, lean) in pc.bristle_types(load_brush("default")).items():
        for dname, d in DIRECTIONS.items():
            if quick and dname != "wide (x)":
                continue
            print(f"  one {br.group} bristle, drag toward the {dname} side ...", file=log)
            full = Simulator(
                bristle_scene(br, lean, FULL_BODIES), SimSettings(dt=FULL_DT, gravity=no_g)
            )
            red = Simulator(
                bristle_scene(br, lean, 2), SimSettings(dt=4e-3, model="prb", gravity=no_g)
            )
            ref = drag_bristle(full, br.length, d)
            got = drag_bristle(red, br.length, d)
            rows.append(
                {
                    "part": "bristle",
                    "bristle": br.group,
                    "direction": dname,
                    "full": ref,
                    "reduced": got,
                    "fn_error": got["fn_N"] / ref["fn_N"] - 1.0,
                    "ft_error": got["ft_N"] / ref["ft_N"] - 1.0,
                }
            )
    return rows


def drag_brush(level: str, direction) -> dict:
    """(b) at ``level``: the default brush pressed BRUSH_PRESS and dragged; mean total tip normal
    force and lateral TCP force [N] over the last AVERAGE s, wall [s]."""
    from ..calibration import DRAG_SPEED
    from ..engine import Simulator, load_scene
    from ..engine.fidelity import level_settings, load_fidelity
    from ..experiments.plan import plate_height
    from ..motion import R0

    fid = load_fidelity(level)
    settings = dataclasses.replace(level_settings(fid, dt=fid.max_substep), gravity=(0.0, 0.0, 0.0))
    scene = load_scene("flat_plate")
    sim = Simulator(scene, settings)
    z0 = sim.touch_height(R0, plate_height(scene))
    dt = settings.dt
    t_press, t_hold = 0.5, 0.2
    n = int(round((t_press + t_hold + BRUSH_DRAG) / dt))
    sim.reset(np.array([0.0, 0.0, z0]), R0)
    fn, lat = [], []
    t0 = time.perf_counter()
    for k in range(1, n + 1):
        t = k * dt
        u = max(t - t_press - t_hold, 0.0) * DRAG_SPEED
        p = np.array(
            [u * direction[0], u * direction[1], z0 - BRUSH_PRESS * _min_jerk(t / t_press)]
        )
        out = sim.step(p, R0)
        if t >= t_press + t_hold + BRUSH_DRAG - AVERAGE:
            fn.append(float(out.tip_normal_force.sum()))
            lat.append(float(np.linalg.norm(out.tcp_force[:2])))
    return {
        "fn_N": float(np.mean(fn)),
        "lateral_N": float(np.mean(lat)),
        "wall_s": time.perf_counter() - t0,
    }


def brush_rows(levels, quick: bool, log) -> list[dict]:
    """(b) for every level and direction, against the first level."""
    rows = []
    for dname, d in DIRECTIONS.items():
        if quick and dname != "wide (x)":
            continue
        ref = None
        for level in levels:
            print(f"  the brush at {level}, drag toward the {dname} side ...", file=log)
            got = drag_brush(level, d)
            ref = ref or got
            rows.append(
                {
                    "part": "brush",
                    "level": level,
                    "against": levels[0],
                    "direction": dname,
                    **got,
                    "fn_error": got["fn_N"] / ref["fn_N"] - 1.0,
                    "lateral_error": got["lateral_N"] / ref["lateral_N"] - 1.0,
                }
            )
    return rows


def _pct(x: float) -> str:
    return f"{100 * x:+.1f} %"


def format_tables(bristles, brush) -> str:
    def slide(r):
        return f"{r['full']['slides_at_mm']:.2f} / {r['reduced']['slides_at_mm']:.2f}"

    a = markdown_table(
        bristles,
        [
            ("bristle", lambda r: r["bristle"]),
            ("drag toward", lambda r: r["direction"]),
            (
                "normal force: full / reduced [N]",
                lambda r: f"{r['full']['fn_N']:.4f} / {r['reduced']['fn_N']:.4f}",
            ),
            ("error", lambda r: _pct(r["fn_error"])),
            (
                "tangential force: full / reduced [N]",
                lambda r: f"{r['full']['ft_N']:.4f} / {r['reduced']['ft_N']:.4f}",
            ),
            ("error", lambda r: _pct(r["ft_error"])),
            ("tip first slides after [mm]: full / reduced", slide),
        ],
    )
    b = markdown_table(
        brush,
        [
            ("drag toward", lambda r: r["direction"]),
            ("level", lambda r: r["level"]),
            ("tip normal force [N]", lambda r: f"{r['fn_N']:.3f}"),
            ("error", lambda r: _pct(r["fn_error"]) if r["level"] != r["against"] else "-"),
            ("lateral TCP force [N]", lambda r: f"{r['lateral_N']:.3f}"),
            ("error", lambda r: _pct(r["lateral_error"]) if r["level"] != r["against"] else "-"),
            ("wall [s]", lambda r: f"{r['wall_s']:.1f}"),
        ],
    )
    return "(a) one bristle\n\n" + a + "\n\n(b) the default brush\n\n" + b


def bench_drag(args) -> int:
    """``brush-env bench drag``: see the module docstring."""
    log = open_log(args)
    levels = list(args.levels) if args.levels else ["reference", "balanced", "fast", "reduced"]
    if args.quick:
        levels = levels[-2:] if len(levels) > 1 else levels
    bristles = [emit(args, r) for r in bristle_rows(args.quick, log)]
    brush = [emit(args, r) for r in brush_rows(levels, args.quick, log)]
    if not args.json:
        print(format_tables(bristles, brush))
    return 0


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    p.add_argument(
        "--levels",
        nargs="+",
        default=None,
        help="fidelity levels of part (b), the first the reference (default: reference "
        "balanced fast reduced)",
    )
    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "the wide side only, the last two levels (for tests)")
