"""``brush-env bench random``: FlatPlate-v0 under uniform random actions, at several solver-step
limits (issue 15: "random-action env steps over fixed seeds: no SimulationDivergence, no
single-step tip force above 1 N or penetration above 20 um that the small-step run does not
show").

For each ``max_substep`` [s] and each seed: ``--steps`` env steps of actions drawn
uniformly from [-1, 1]^6 (``numpy.random.default_rng(seed)``), the episode reset (seed + 100 k)
when it ends.  Per row: divergences, episode ends, the largest per-step peak tip normal force
(``info["peak_tip_force"]``) [N], the steps whose peak exceeds 1 N, the largest penetration of
the last engine step of each env step [um], wall time.  Runs with the same seed see the same
actions, so the rows of the smallest limit are the small-step run the others are held to.

    brush-env bench random [--steps 500] [--seeds 0 1 2] [--substeps 0.004 0.001 0.00025]
        [--fidelity balanced] [--json]
"""

from __future__ import annotations

import json
import time
import warnings

import numpy as np

ENV_ID = "brush_env/FlatPlate-v0"
DEFAULTS = {"steps": 500, "seeds": [0, 1, 2], "substeps": [0.004, 0.001, 0.00025]}


def random_run(max_substep: float, seed: int, steps: int, fidelity: str | None = None) -> dict:
    """One seed's random-action run at ``max_substep = max_substep`` (see module), at the env's
    default fidelity level or ``fidelity``."""
    import gymnasium as gym

    import brush_env  # noqa: F401  (registers the env ids)

    kw = {} if fidelity is None else {"fidelity": fidelity}
    env = gym.make(ENV_ID, engine_settings={"max_substep": max_substep}, **kw)
    u = env.unwrapped
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    peaks, pen = [], 0.0
    divergences = ends = 0
    t0 = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the penetration warning: its depth is in the row
        for _ in range(steps):
            a = rng.uniform(-1.0, 1.0, 6).astype(np.float32)
            _, _, term, trunc, info = env.step(a)
            peaks.append(float(info["peak_tip_force"]))
            pen = max(pen, float(u._last.tip_penetration.max()))
            if term or trunc:
                divergences += info.get("termination") == "divergence"
                ends += 1
                env.reset(seed=seed + 100 * ends)
    wall = time.perf_counter() - t0
    env.close()
    peaks = np.asarray(peaks)
    return {
        "fidelity": u.config.fidelity,
        "max_substep": max_substep,
        "seed": seed,
        "steps": steps,
        "divergences": int(divergences),
        "episode_ends": ends,
        "peak_tip_force_N": float(peaks.max()),
        "steps_above_1N": int((peaks > 1.0).sum()),
        "max_penetration_um": 1e3 * pen,
        "wall_s": wall,
        "peaks": peaks.tolist(),
    }


def run(args) -> int:
    """Print the table (or one JSON object per row, without the per-step peaks)."""
    rows = []
    for sub in args.substeps:
        for seed in args.seeds:
            row = random_run(sub, seed, args.steps, args.fidelity)
            rows.append(row)
            if args.json:
                print(json.dumps({k: v for k, v in row.items() if k != "peaks"}), flush=True)
    if not args.json:
        print(format_table(rows))
    return 0


def format_table(rows) -> str:
    smallest = min(r["max_substep"] for r in rows)  # the small-step run of each seed
    ref = {r["seed"]: np.asarray(r["peaks"]) for r in rows if r["max_substep"] == smallest}
    lines = [
        "| max_substep [s] | seed | divergences | episode ends | peak tip force [N] | "
        "steps > 1 N | of them not > 1 N in the smallest-limit run | max penetration [um] | "
        "wall [s] |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        p, q = np.asarray(r["peaks"]), ref[r["seed"]]
        n = min(len(p), len(q))
        extra = int(((p[:n] > 1.0) & ~(q[:n] > 1.0)).sum())
        lines.append(
            f"| {r['max_substep']:g} | {r['seed']} | {r['divergences']} | "
            f"{r['episode_ends']} | {r['peak_tip_force_N']:.3f} | {r['steps_above_1N']} | "
            f"{extra} | {r['max_penetration_um']:.1f} | {r['wall_s']:.1f} |"
        )
    return "\n".join(lines)


def add_arguments(p) -> None:
    p.add_argument("--steps", type=int, default=DEFAULTS["steps"], help="env steps per seed")
    p.add_argument(
        "--seeds", type=int, nargs="+", default=DEFAULTS["seeds"], help="action/env seeds"
    )
    p.add_argument(
        "--substeps",
        type=float,
        nargs="+",
        default=DEFAULTS["substeps"],
        help="max_substep values [s]; the smallest is the small-step reference",
    )
    p.add_argument(
        "--fidelity",
        default=None,
        help="fidelity level (configs/fidelity; default: the env's, `fast`); its other settings "
        "stay, max_substep is the row's",
    )
