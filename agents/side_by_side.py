"""One episode of two policies side by side: coverage map with the TCP path, force trace, coverage.

    python -m agents.side_by_side --policy agents/models/flat_plate_sac.zip --policy reference \\
        --seed 1000 --out docs/figures/rl_side_by_side.png [--env-kw fidelity=\\"balanced\\"]

Each policy runs the same episode (``reset(seed=--seed)``: the same start pose and plate offset)
on its own env, made as ``agents/evaluate.py`` makes it (a trained model on the settings in its
``meta.json``; ``--env-kw`` overrides both).  One column per policy: the patch's cleaned cells at
the end with the TCP's path over them (start o, end x), and below the total plate normal force
against time with the env's force limits; the bottom panel overlays both coverage curves.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np

import brush_env  # noqa: F401  (registers the ids)
from agents.evaluate import (
    ENV_ID,
    REFERENCES,
    check_env_id,
    commit_id,
    companions,
    load_policy,
    parse_env_kw,
    run_episode,
)
from brush_env.engine.checks import ConfigError
from brush_env.user_errors import OneLineParser, add_env_kw, run_main


def episode(spec: str, seed: int, env_id: str = ENV_ID, env_kwargs: dict | None = None) -> dict:
    """Run ``spec`` (as ``agents.evaluate``'s ``--policy``) for one episode; returns its
    metrics, time series, final cleaned-cell grid and patch size [mm]."""
    kwargs = dict(env_kwargs or {})
    meta = companions(spec)[0]
    if spec not in (*REFERENCES, "random") and meta.is_file():
        kwargs = {**json.loads(meta.read_text()).get("env_kwargs", {}), **kwargs}
    check_env_id(env_id)
    env = gym.make(env_id, **kwargs)
    pol, transform = load_policy(spec, env, seed=seed)
    metrics, series, _ = run_episode(env, pol, seed, transform)
    cov = env.unwrapped.coverage
    grid = getattr(cov, "cleaned", None)
    out = {
        "metrics": metrics,
        "series": series,
        "cleaned": None if grid is None else np.array(grid),
        "patch_size": float(getattr(cov, "patch_size", 0.0)),
        "limits": (env.unwrapped.config.total_force_limit, env.unwrapped.config.hard_force_limit),
        "fidelity": env.unwrapped.config.fidelity,
    }
    env.close()
    return out


def _label(spec: str) -> str:
    if spec in (*REFERENCES, "random"):
        return spec
    path = Path(spec)
    # agents/train.py's runs all save model.zip: name them by their folder
    return f"{path.parent.name}/{path.stem}" if path.stem == "model" else path.stem


def figure(runs: list[tuple[str, dict]], seed: int, path: str | Path) -> None:
    """The side-by-side figure (module docstring) of ``runs`` = [(label, episode(...))]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(runs)
    fig = plt.figure(figsize=(4.2 * n, 9.5))
    gs = fig.add_gridspec(3, n, height_ratios=[3.2, 1.6, 1.6])
    cov_ax = fig.add_subplot(gs[2, :])
    for j, (label, r) in enumerate(runs):
        m, s = r["metrics"], r["series"]
        ax = fig.add_subplot(gs[0, j])
        half = r["patch_size"] / 2
        if r["cleaned"] is not None:
            ax.imshow(
                r["cleaned"],
                origin="lower",
                extent=(-half, half, -half, half),
                cmap="Greens",
                vmin=0,
                vmax=1.4,
                interpolation="nearest",
            )
        ax.plot(s["tcp_x"], s["tcp_y"], color="k", lw=0.8, label="TCP path")
        ax.plot(s["tcp_x"][0], s["tcp_y"][0], "o", color="C0", label="start")
        ax.plot(s["tcp_x"][-1], s["tcp_y"][-1], "x", color="C3", label="end")
        ax.set_xlim(-half - 8, half + 8)
        ax.set_ylim(-half - 8, half + 8)
        ax.set_aspect("equal")
        ax.set_xlabel("x [mm]")
        ax.set_ylabel("y [mm]")
        ax.set_title(
            f"{label} at {r['fidelity']}\ncoverage {100 * m['coverage']:.1f} %, return "
            f"{m['return']:.1f}",
            fontsize=9,
        )
        ax.legend(fontsize=7, loc="lower right")
        fx = fig.add_subplot(gs[1, j])
        fx.plot(s["time"], s["total_normal_force"], lw=0.9, label="total normal force")
        safe, hard = r["limits"]
        fx.axhline(safe, color="orange", ls="--", lw=1, label=f"limit {safe:g} N")
        fx.set_xlabel("time [s]")
        fx.set_ylabel("force [N]")
        fx.set_title(
            f"{m['time_above_force_limit']:.2f} s above the limit, peak "
            f"{m['peak_normal_force']:.2f} N",
            fontsize=9,
        )
        fx.legend(fontsize=7, loc="upper right")
        cov_ax.plot(s["time"], 100 * np.asarray(s["coverage"]), label=label)
    cov_ax.set_xlabel("time [s]")
    cov_ax.set_ylabel("patch cleaned [%]")
    cov_ax.legend(fontsize=8, loc="upper left")
    cov_ax.grid(alpha=0.3)
    fig.suptitle(f"episode seed {seed}, commit {commit_id()}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="python -m agents.side_by_side", description=__doc__.split("\n")[0])
    p.add_argument(
        "--policy",
        action="append",
        required=True,
        help="reference | random | PATH to a SB3 model (give two or more)",
    )
    p.add_argument("--seed", type=int, default=1000, help="the episode's reset seed")
    p.add_argument("--out", required=True, help="PNG path")
    p.add_argument("--env", default=ENV_ID, help=f"registered env id (default {ENV_ID})")
    add_env_kw(p, 'e.g. fidelity="balanced"')
    return p


def _main(argv) -> int:
    args = build_parser().parse_args(argv)
    if len(args.policy) < 2:
        raise ConfigError(f"--policy given {len(args.policy)} time(s): give two or more")
    kw = parse_env_kw(args.env_kw)
    runs = [(_label(p), episode(p, args.seed, args.env, kw)) for p in args.policy]
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    figure(runs, args.seed, args.out)
    for label, r in runs:
        m = r["metrics"]
        print(
            f"{label}: coverage {100 * m['coverage']:.1f} %, return {m['return']:.2f}, "
            f"{m['time_above_force_limit']:.2f} s above the limit"
        )
    print(f"written {args.out}")
    return 0


def main(argv=None) -> int:
    return run_main(_main, argv, prog="python -m agents.side_by_side")


if __name__ == "__main__":
    sys.exit(main())
