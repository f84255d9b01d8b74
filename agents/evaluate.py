"""Evaluate a policy on BrushEnv: returns, coverage, force-limit violations, per-term rewards.

    python -m agents.evaluate --policy reference --episodes 5 --out runs/eval_reference
    python -m agents.evaluate --policy random --episodes 5 --out runs/eval_random
    python -m agents.evaluate --env brush_env/ToothRow-v0 --policy reference --episodes 20 \
        --out runs/eval_teeth_reference
    python -m agents.evaluate --policy runs/ppo/model.zip --episodes 5 --out runs/eval_ppo --video

``--policy`` is ``reference`` (agents/reference.py, the env's reference as shipped),
``reference-static`` / ``reference-sliding`` (the same with the press at rest first -- the paper's
order -- or made while moving; docs/rl.md), ``random`` (uniform actions) or the path of
a stable-baselines3 model saved by ``agents/train.py`` (its ``meta.json`` names the algorithm and
the env settings it was trained on, which ``--env-kw`` may override; a ``vecnormalize.pkl`` beside
it normalises the observations as in training).
Episode i is reset with seed ``--seed + i``, so two policies see the same start poses and plate
offsets.  Writes to ``--out``:

* ``summary.json``: every setting, per-episode metrics and their mean/std;
* ``table.md``: the per-episode table (also printed);
* ``forces.png``: total plate normal force over time per episode, with the safe and hard limits;
* ``coverage.png``: fraction of the patch cleaned over time per episode;
* ``episode_000.gif`` with ``--video``: the first episode's ``rgb_array`` frames.

Metrics per episode: ``return``, ``coverage`` (final fraction), ``steps``, ``termination``,
``time_above_force_limit`` [s] (total normal force above ``total_force_limit``),
``peak_normal_force`` [N], ``mean_normal_force`` [N] (the total normal force at the end of each
step, averaged over the episode's steps), ``peak_tip_force`` [N], ``hard_limit_hit`` (bool) and
``reward_<term>`` sums.
"""

from __future__ import annotations

import difflib
import json
import subprocess
import sys
import time
from dataclasses import fields
from pathlib import Path

import gymnasium as gym
import numpy as np
import tomllib

import brush_env  # noqa: F401  (registers the ids)
from agents.reference import RandomPolicy, ReferencePolicy
from brush_env.engine.checks import ConfigError
from brush_env.user_errors import OneLineParser, add_env_kw, add_flag, run_main

ENV_ID = "brush_env/FlatPlate-v0"
REWARD_TERMS = ("coverage", "total_force", "tip_force", "termination")


def parse_env_kw(items) -> dict:
    """``KEY=VALUE`` strings -> dict; values parsed as TOML (``3``, ``0.5``, ``"tiny_env"``,
    ``[1, 2]``, ``true``), falling back to the raw string."""
    out = {}
    for item in items or []:
        if "=" not in item:
            raise ConfigError(f"--env-kw {item!r}: expected KEY=VALUE")
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = tomllib.loads(f"x = {v}")["x"]
        except tomllib.TOMLDecodeError:
            out[k.strip()] = v
    return out


#: ``--policy`` names of the reference policy -> its keyword arguments (the press profile)
REFERENCES = {
    "reference": {},
    "reference-static": {"press": "static"},
    "reference-sliding": {"press": "sliding"},
}


def companions(model: str | Path) -> tuple[Path, Path]:
    """(meta.json, vecnormalize.pkl) of a saved model: ``<stem>.meta.json`` and
    ``<stem>.vecnormalize.pkl`` beside it (a shipped model, agents/models/), else the run folder's
    ``meta.json`` and ``vecnormalize.pkl`` (agents/train.py's output)."""
    path = Path(model)
    stem = path.with_suffix("")
    own = (Path(f"{stem}.meta.json"), Path(f"{stem}.vecnormalize.pkl"))
    if own[0].is_file():
        return own
    return path.parent / "meta.json", path.parent / "vecnormalize.pkl"


def load_policy(spec: str, env: gym.Env, seed: int = 0):
    """(policy with SB3-style predict, obs_transform) for a name of :data:`REFERENCES`,
    'random' or a model path."""
    if spec in REFERENCES:
        return ReferencePolicy.for_env(env, **REFERENCES[spec]), None
    if spec == "random":
        return RandomPolicy(env.action_space, seed=seed), None
    path = Path(spec)
    if not path.exists() and path.with_suffix(".zip").exists():
        path = path.with_suffix(".zip")
    if not path.exists():
        raise ConfigError(
            f"--policy {spec!r}: not one of {', '.join(REFERENCES)}, 'random' or an existing "
            "model file"
        )
    from stable_baselines3 import PPO, SAC

    meta_path, vn_path = companions(path)
    algo = json.loads(meta_path.read_text()).get("algo") if meta_path.exists() else None
    classes = {"ppo": PPO, "sac": SAC}
    model = None
    for name in [algo] if algo in classes else list(classes):
        try:
            model = classes[name].load(path, device="cpu")
            break
        except Exception:  # noqa: BLE001 - try the next algorithm class
            continue
    if model is None:
        raise ValueError(f"{path}: not a PPO or SAC model saved by stable-baselines3")
    transform = None
    if vn_path.exists():
        from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

        vn = VecNormalize.load(str(vn_path), DummyVecEnv([lambda: env]))
        vn.training = False
        transform = vn.normalize_obs
    return model, transform


def check_env_id(env_id: str, where: str = "--env") -> None:
    """``env_id`` is one of brush_env's registered ids (``brush_env:`` prefix allowed);
    ConfigError with a did-you-mean otherwise (``where``: how the user gave it)."""
    short = env_id.split(":", 1)[-1]
    if short not in brush_env.ENV_IDS:
        # compared without the common "brush_env/" (with it, every id looks close to any typo)
        names = {i.split("/", 1)[-1]: i for i in brush_env.ENV_IDS}
        close = difflib.get_close_matches(short.split("/", 1)[-1], list(names), n=3)
        hint = f"; did you mean {', '.join(names[c] for c in close)}?" if close else ""
        raise ConfigError(
            f"{where} = {env_id!r} is not a registered env{hint}"
            f" (registered: {', '.join(sorted(brush_env.ENV_IDS))})"
        )


def run_episode(
    env, policy, seed: int, transform=None, video: bool = False, deterministic: bool = True
) -> tuple[dict, dict, list]:
    """One episode; returns (metrics, time series, frames).  A policy with ``seed_episode``
    (random actions) is reseeded for it: episode ``seed`` is the same in any evaluation."""
    obs, info = env.reset(seed=seed)
    if hasattr(policy, "seed_episode"):
        policy.seed_episode(seed)
    u = env.unwrapped
    cfg = u.config
    p0 = np.asarray(info["tcp_position"], float)
    series = {
        "time": [0.0],
        "total_normal_force": [0.0],
        "peak_normal_force": [0.0],
        "coverage": [0.0],
        "tcp_x": [float(p0[0])],  # [mm] TCP in the plate's frame (info["tcp_position"])
        "tcp_y": [float(p0[1])],
    }
    frames = [env.render()] if video else []
    terms = dict.fromkeys(REWARD_TERMS, 0.0)
    peak_gum = 0.0
    ret, steps, above, peak_f, peak_tip = 0.0, 0, 0.0, 0.0, 0.0
    termination = None
    episode_start = np.ones(1, bool)
    while True:
        o = transform(obs) if transform is not None else obs
        action, _ = policy.predict(o, episode_start=episode_start, deterministic=deterministic)
        episode_start[:] = False
        obs, reward, terminated, truncated, info = env.step(action)
        ret += reward
        steps += 1
        for k, v in info["reward_terms"].items():
            terms[k] = terms.get(k, 0.0) + v
        peak_gum = max(peak_gum, info.get("peak_gum_force", 0.0))
        above += info["time_above_force_limit"]
        peak_f = max(peak_f, info["peak_normal_force"])
        peak_tip = max(peak_tip, info["peak_tip_force"])
        series["time"].append(info["time"])
        series["total_normal_force"].append(info["total_normal_force"])
        series["peak_normal_force"].append(info["peak_normal_force"])
        series["coverage"].append(info["coverage"])
        series["tcp_x"].append(float(info["tcp_position"][0]))
        series["tcp_y"].append(float(info["tcp_position"][1]))
        if video:
            frames.append(env.render())
        if terminated or truncated:
            termination = info["termination"]
            break
    metrics = {
        "seed": seed,
        "return": ret,
        "coverage": info["coverage"],
        "steps": steps,
        "termination": termination,
        "time_above_force_limit": above,
        "peak_normal_force": peak_f,
        "mean_normal_force": float(np.mean(series["total_normal_force"][1:])),
        "peak_tip_force": peak_tip,
        "hard_limit_hit": bool(peak_f > cfg.hard_force_limit),
    }
    metrics.update({f"reward_{k}": v for k, v in terms.items()})
    if "coverage_regions" in info:  # ToothRow-v0: per-region coverage and the gum's peak force
        metrics["peak_gum_force"] = peak_gum
        metrics.update({f"coverage_{k}": v for k, v in info["coverage_regions"].items()})
    return metrics, series, frames


def episode_table(rows: list[dict]) -> str:
    """The per-episode markdown table (``table.md``)."""
    cols = [
        "seed",
        "return",
        "coverage",
        "steps",
        "termination",
        "time_above_force_limit",
        "peak_normal_force",
        "peak_tip_force",
    ] + [f"reward_{k}" for k in REWARD_TERMS]
    cols += [k for k in rows[0] if k not in cols and k != "reward_gum_force"]
    if "reward_gum_force" in rows[0]:
        cols.insert(cols.index("reward_termination"), "reward_gum_force")
    head = "| " + " | ".join(cols) + " |\n|" + "---|" * len(cols) + "\n"

    def fmt(v):
        return f"{v:.4g}" if isinstance(v, float) else str(v)

    return head + "\n".join("| " + " | ".join(fmt(r[c]) for c in cols) + " |" for r in rows)


def commit_id() -> str:
    """Short git commit of the checkout (``unknown`` outside a git checkout)."""
    try:
        return subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            cwd=Path(__file__).parent,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def _plots(out: Path, all_series: list[dict], cfg, title: str) -> None:
    """forces.png and coverage.png; titled with policy, seeds and commit, legend beside the axes."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for name, key, ylabel, scale in (
        (
            "forces.png",
            "total_normal_force",
            "total plate normal force [N]\n(push on the plate > 0)",
            1,
        ),
        ("coverage.png", "coverage", "patch cleaned [%]", 100),
    ):
        fig, ax = plt.subplots(figsize=(8, 3.6))
        for i, s in enumerate(all_series):
            ax.plot(s["time"], np.asarray(s[key]) * scale, lw=1, label=f"episode {i}")
        if key == "total_normal_force":
            ax.axhline(cfg.total_force_limit, color="orange", ls="--", label="safe limit")
            ax.axhline(cfg.hard_force_limit, color="red", ls=":", label="hard limit")
        ax.set_xlabel("time [s]")
        ax.set_ylabel(ylabel)
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0)
        fig.tight_layout()
        fig.savefig(out / name, dpi=120)
        plt.close(fig)


def _save_gif(path: Path, frames: list, fps: float) -> None:
    from PIL import Image

    imgs = [Image.fromarray(f) for f in frames]
    imgs[0].save(path, save_all=True, append_images=imgs[1:], duration=int(1000 / fps), loop=0)


def evaluate(
    policy: str,
    episodes: int,
    out: str | Path,
    *,
    seed: int = 0,
    video: bool = False,
    config: str | None = None,
    env_kwargs: dict | None = None,
    deterministic: bool = True,
    quiet: bool = False,
    env_id: str = ENV_ID,
) -> dict:
    """Run ``episodes`` episodes of ``policy`` and write the outputs (module docstring)."""
    if episodes < 1:
        raise ConfigError(f"episodes = {episodes!r} is out of range: must be >= 1")
    out = Path(out)
    env_kwargs = dict(env_kwargs or {})
    meta = companions(policy)[0]
    if policy not in (*REFERENCES, "random") and meta.is_file():
        # a trained model is evaluated on the env it was trained on, unless overridden
        trained = dict(json.loads(meta.read_text()).get("env_kwargs", {}))
        config = trained.pop("config", config)
        env_kwargs = {**trained, **env_kwargs}
    check_env_id(env_id)
    if config is not None:
        env_kwargs["config"] = config
    env = gym.make(env_id, render_mode="rgb_array" if video else None, **env_kwargs)
    pol, transform = load_policy(policy, env, seed=seed)
    out.mkdir(parents=True, exist_ok=True)  # only now: every input is valid
    rows, all_series = [], []
    t0 = time.perf_counter()
    from tqdm import tqdm

    for i in tqdm(range(episodes), desc=f"evaluate {policy}", unit="episode", disable=quiet):
        m, s, frames = run_episode(env, pol, seed + i, transform, video and i == 0, deterministic)
        rows.append(m)
        all_series.append(s)
        if frames:
            _save_gif(out / "episode_000.gif", frames, env.unwrapped.metadata["render_fps"])
    wall = time.perf_counter() - t0
    cfg = env.unwrapped.config
    env.close()
    summary = {
        "policy": policy,
        "episodes": episodes,
        "seed": seed,
        "env_id": env_id,
        "config": config,
        "env_kwargs": env_kwargs,
        "env_settings": _jsonable({f.name: getattr(cfg, f.name) for f in fields(cfg)}),
        "wall_time_s": wall,
        "env_steps_per_s": sum(r["steps"] for r in rows) / wall,
        **_aggregate(rows),
        "per_episode": rows,
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    table = episode_table(rows)
    (out / "table.md").write_text(table + "\n")
    _plots(
        out,
        all_series,
        cfg,
        f"policy {policy}, seeds {seed}..{seed + episodes - 1}, commit {commit_id()}",
    )
    if not quiet:
        print(table)
        print(
            f"mean return {summary['mean']['return']:.3f} +- {summary['std']['return']:.3f}, "
            f"coverage {100 * summary['mean']['coverage']:.2f} %, written to {out}"
        )
    return summary


def _aggregate(rows: list[dict]) -> dict:
    """``{"mean": ..., "std": ...}`` over episodes of every numeric per-episode metric."""
    keys = [k for k, v in rows[0].items() if isinstance(v, (int, float)) and k != "seed"]
    return {
        "mean": {k: float(np.mean([r[k] for r in rows])) for k in keys},
        "std": {k: float(np.std([r[k] for r in rows])) for k in keys},
    }


def join_summaries(parts: list[dict]) -> dict:
    """One summary of consecutive evaluations of the same policy and settings (``parts``, e.g.
    episodes 1000-1009 and 1010-1019 run as two tasks): the summary one run over all their
    episodes writes, but for ``wall_time_s`` (the parts' sum) and ``parts``.  Episode i resets
    with seed ``seed + i`` and a trained policy acts deterministically, so the joined episodes are
    the single run's.  Raises ``ConfigError`` if the parts do not follow on or differ in policy,
    env or settings."""
    if not parts:
        raise ConfigError("join_summaries: no parts to join")
    parts = sorted(parts, key=lambda p: p["seed"])
    first = parts[0]
    same = ("policy", "env_id", "config", "env_kwargs", "env_settings")  # kept from the first
    expect = first["seed"]
    for p in parts:
        for k in same:
            if p.get(k) != first.get(k):
                raise ConfigError(
                    f"join_summaries: part at seed {p['seed']} has another {k} than the part at "
                    f"seed {first['seed']}: {p.get(k)!r} against {first.get(k)!r}"
                )
        if p["seed"] != expect:
            raise ConfigError(
                f"join_summaries: the parts do not follow on: a part starts at seed {p['seed']}, "
                f"expected {expect}"
            )
        expect += p["episodes"]
    rows = [r for p in parts for r in p["per_episode"]]
    wall = sum(p["wall_time_s"] for p in parts)
    return {
        **{k: first.get(k) for k in same},
        "episodes": len(rows),
        "seed": first["seed"],
        "wall_time_s": wall,
        "env_steps_per_s": sum(r["steps"] for r in rows) / wall,
        **_aggregate(rows),
        "per_episode": rows,
        "parts": [{"seed": p["seed"], "episodes": p["episodes"]} for p in parts],
    }


def _jsonable(d: dict) -> dict:
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in d.items()}


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="python -m agents.evaluate", description=__doc__.split("\n")[0])
    p.add_argument(
        "--policy",
        required=True,
        help="reference | reference-static | reference-sliding | random | PATH to a SB3 model",
    )
    p.add_argument("--episodes", type=int, default=5, help="number of episodes (default 5)")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--seed", type=int, default=0, help="episode i resets with seed + i")
    add_flag(p, "--video", "write episode_000.gif")
    p.add_argument(
        "--env", default=ENV_ID, help=f"registered env id (default {ENV_ID}; brush_env/ToothRow-v0)"
    )
    p.add_argument(
        "--config", default=None, help="env config name or TOML path (default: the env's own)"
    )
    add_env_kw(p, 'e.g. brush="tiny_env"')
    add_flag(p, "--stochastic", "sample SB3 policy actions")
    return p


def _main(argv) -> int:
    args = build_parser().parse_args(argv)
    evaluate(
        args.policy,
        args.episodes,
        args.out,
        seed=args.seed,
        video=args.video,
        config=args.config,
        env_kwargs=parse_env_kw(args.env_kw),
        deterministic=not args.stochastic,
        env_id=args.env,
    )
    return 0


def main(argv=None) -> int:
    """Entry point: user mistakes in one stderr line, exit code 2 (``--debug``: traceback)."""
    return run_main(_main, argv, prog="python -m agents.evaluate")


if __name__ == "__main__":
    sys.exit(main())
