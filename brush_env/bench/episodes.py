"""``bench episodes``: how far whole env episodes run at one fidelity level before they end, and
why (issue 29: the reduced model's Newton failures on a tooth row; issue 30: training needs
episodes that end for the policy's reasons, not the solver's).

Two runs, each over ``--seeds`` (reset seed = the seed), ``action_mode = "3d"``, up to
``--steps`` env steps per episode:

* ``ToothRow-v0`` under its scrub reference (``envs.reference.ScrubReference``, tracked as
  ``agents.reference.ReferencePolicy`` tracks it; the policy the tooth row's reward is judged
  against): it never leaves the workspace, so an episode ends early only on the engine
  (divergence) or the force limits;
* ``FlatPlate-v0`` under uniform random actions in [-1, 1]^3 (``numpy.random.default_rng(seed)``):
  the guard that a change for the tooth row costs the plate nothing.

Per episode: the env steps run and ``info["termination"]`` (None: it ran to ``--steps``); per
scene: the steps in all, the episodes that ended on divergence, CPU time.

``--against LEVEL`` also runs the tooth row's episodes at LEVEL (e.g. ``balanced``, the full
chain) and measures the level against it, as issue 29 asks of a fast model on the tooth row:
per episode the coverage at its end (points, ``info["coverage"]``) and the gum force
(``info["gum_force"]`` [N], the normal force the gum takes, per env step); over the episodes the
mean and largest |coverage difference| and the gum force's pooled RMS error,
``sqrt(sum (g - g_ref)^2 / sum g_ref^2)`` over the env steps both runs reached.  The scrub
reference steers by the TCP pose it observes, so both levels brush the same strokes.  The
plate's random episodes are not compared here (``bench fidelity`` does, with its own seeds).

    brush-env bench episodes [--fidelity reduced] [--seeds 0 1 ... 9] [--steps 300]
                             [--against balanced] [--json]
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from .harness import emit, markdown_table, open_log

SCENES = ("brush_env/ToothRow-v0", "brush_env/FlatPlate-v0")


def run_episode(env_id: str, fidelity: str, seed: int, steps: int) -> dict:
    """One episode of ``env_id`` at ``fidelity`` (see module): steps run, termination reason."""
    import gymnasium as gym

    import brush_env  # noqa: F401  (registers the env ids)

    from ..envs.action import make_action_type
    from ..envs.reference import ScrubReference

    env = gym.make(env_id, fidelity=fidelity, action_mode="3d", max_episode_steps=steps)
    obs, _ = env.reset(seed=seed)
    u = env.unwrapped
    if "ToothRow" in env_id:
        # the scrub reference as agents.reference.ReferencePolicy runs it (one plan per episode)
        scrub = ScrubReference(u.layout, make_action_type(u.config), u.dt, steps)

        def act(o):
            p, R = u.layout.tcp_pose(o[None])
            return scrub.act(u.layout.elapsed_steps(o[None], steps)[0], p[0], R[0])
    else:
        rng = np.random.default_rng(seed)

        def act(o):
            return rng.uniform(-1.0, 1.0, 3).astype(np.float32)

    info: dict = {}
    n = 0
    gum = []
    t0 = time.process_time()
    while n < steps:
        obs, _r, terminated, truncated, info = env.step(act(obs))
        n += 1
        gum.append(float(info.get("gum_force", np.nan)))
        if terminated or truncated:
            break
    solver = u.sim.bristles.solver_info()
    env.close()
    return {
        "env": env_id.split("/")[-1],
        "fidelity": fidelity,
        "seed": seed,
        "steps": n,
        "termination": info.get("termination"),
        "cpu_s": time.process_time() - t0,
        "coverage": float(info.get("coverage", np.nan)),
        "rough_steps": solver.get("rough_steps", 0),
        "gum_force": gum,
    }


def compare(runs: list[dict], refs: list[dict]) -> dict:
    """Tooth-row episodes at one level against the same seeds at another (module docstring):
    coverage difference [points] (mean of |d|, largest |d|, mean signed), the gum force's
    pooled RMS error [-] over the steps both reached, and the mean gum force of each [N]."""
    from .fidelity_metrics import pooled_rms_error

    dcov = [100.0 * (r["coverage"] - f["coverage"]) for r, f in zip(runs, refs, strict=True)]
    pairs = []
    for r, f in zip(runs, refs, strict=True):
        n = min(len(r["gum_force"]), len(f["gum_force"]))
        pairs.append((np.asarray(r["gum_force"][:n]), np.asarray(f["gum_force"][:n])))
    return {
        "env": runs[0]["env"],
        "fidelity": runs[0]["fidelity"],
        "against": refs[0]["fidelity"],
        "episodes": len(runs),
        "coverage_diff_mean_abs": float(np.mean(np.abs(dcov))),
        "coverage_diff_max_abs": float(np.max(np.abs(dcov))),
        "coverage_diff_mean": float(np.mean(dcov)),
        "gum_force_rms_error": pooled_rms_error(pairs),
        "gum_force_mean": float(np.mean(np.concatenate([p[0] for p in pairs]))),
        "gum_force_mean_ref": float(np.mean(np.concatenate([p[1] for p in pairs]))),
    }


def bench_episodes(args) -> int:
    """``brush-env bench episodes``: see the module docstring."""
    log = open_log(args)
    warnings.simplefilter("ignore")
    totals = []
    tooth: list[dict] = []
    for env_id in SCENES:
        rows = []
        for seed in args.seeds:
            r = run_episode(env_id, args.fidelity, seed, args.steps)
            emit(args, {k: v for k, v in r.items() if k != "gum_force"})
            rows.append(r)
            print(
                f"{r['env']} seed {seed}: {r['steps']} steps, {r['termination']}, "
                f"{r['rough_steps']} rough bristle sub-steps",
                file=log,
            )
        if "ToothRow" in env_id:
            tooth = rows
        totals.append(
            {
                "env": env_id.split("/")[-1],
                "fidelity": args.fidelity,
                "episodes": len(rows),
                "steps": sum(r["steps"] for r in rows),
                "divergences": sum(r["termination"] == "divergence" for r in rows),
                "cpu_s": sum(r["cpu_s"] for r in rows),
            }
        )
    if not args.json:
        cols = [
            ("scene", lambda r: r["env"]),
            ("level", lambda r: r["fidelity"]),
            ("episodes", lambda r: str(r["episodes"])),
            (f"env steps (of {args.steps} each)", lambda r: str(r["steps"])),
            ("ended on divergence", lambda r: str(r["divergences"])),
            ("CPU [s]", lambda r: f"{r['cpu_s']:.1f}"),
        ]
        print(markdown_table(totals, cols))
    if args.against:
        refs = []
        for seed in args.seeds:
            r = run_episode(SCENES[0], args.against, seed, args.steps)
            emit(args, {k: v for k, v in r.items() if k != "gum_force"})
            refs.append(r)
            print(f"{r['env']} at {args.against}, seed {seed}: {r['steps']} steps", file=log)
        c = emit(args, compare(tooth, refs))
        if not args.json:
            cols = [
                ("scene", lambda r: r["env"]),
                ("level", lambda r: r["fidelity"]),
                ("against", lambda r: r["against"]),
                ("episodes", lambda r: str(r["episodes"])),
                (
                    "coverage diff, mean / largest [points]",
                    lambda r: (
                        f"{r['coverage_diff_mean_abs']:.1f} / {r['coverage_diff_max_abs']:.1f}"
                    ),
                ),
                ("mean signed [points]", lambda r: f"{r['coverage_diff_mean']:+.1f}"),
                ("gum force RMS err", lambda r: f"{100 * r['gum_force_rms_error']:.1f} %"),
                (
                    "mean gum force [N]",
                    lambda r: f"{r['gum_force_mean']:.3f} / {r['gum_force_mean_ref']:.3f}",
                ),
            ]
            print(markdown_table([c], cols))
    return 0


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    p.add_argument("--fidelity", default="reduced", help="fidelity level (default reduced)")
    p.add_argument(
        "--seeds", type=int, nargs="+", default=list(range(10)), help="reset seeds (default 0-9)"
    )
    p.add_argument("--steps", type=int, default=300, help="env steps per episode at most (300)")
    p.add_argument(
        "--against",
        default=None,
        help="also run the tooth row's episodes at this level and compare (e.g. balanced)",
    )
    add_flag(p, "--json", "one JSON object per episode on stdout (machine info on stderr)")
