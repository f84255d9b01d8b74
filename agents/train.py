"""Train PPO or SAC (stable-baselines3) on BrushEnv.

    python -m agents.train --algo ppo --config configs/agents/ppo.toml --timesteps 200000 \\
        --n-envs 2 --out runs/ppo [--env-kw brush=\\"tiny_env\\"] [--seed 0]

* Environments: ``make_vec_env`` from the ``brush_env:brush_env/FlatPlate-v0`` id (the module
  prefix makes every ``SubprocVecEnv`` worker import brush_env, which registers the id); a
  ``DummyVecEnv`` for ``--n-envs 1``.  Each env is wrapped in ``Monitor``.
* ``VecNormalize`` as the config's ``[normalize]`` says (PPO: observations and rewards; SAC:
  observations only); its statistics are saved with every checkpoint and at the end.
* ``EvalCallback`` every ``[train] eval_freq`` env steps on a separate env (observations
  normalised with the training statistics, raw rewards), best model kept; before training the
  reference policy (agents/reference.py) is evaluated on the same number of episodes and its mean
  return is logged next to each evaluation (``eval/reference_mean_reward``,
  ``eval/gap_to_reference`` = policy - reference) and written to ``reference.json``.
* ``CheckpointCallback`` every ``[train] checkpoint_freq`` env steps.
* TensorBoard logs in ``OUT/tb`` when ``tensorboard`` is importable (else a note and CSV/stdout
  logs only); a tqdm progress bar (SB3's own bar also needs ``rich``).

Writes ``OUT/model.zip``, ``OUT/vecnormalize.pkl`` (if normalising), ``OUT/meta.json`` (what
``agents/evaluate.py`` needs to reload it), ``OUT/checkpoints/``, ``OUT/best/``, ``OUT/eval/``,
``OUT/progress.csv``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import sys
import time
import tomllib
from pathlib import Path

AGENT_KEYS = {"algo", "policy", "env", "normalize", "hyperparameters", "train"}
ENV_KEYS = {"id", "config", "kwargs"}
NORMALIZE_KEYS = {"obs", "reward", "clip_obs"}
TRAIN_KEYS = {"eval_freq", "eval_episodes", "checkpoint_freq", "seed"}
ALGOS = ("ppo", "sac")


def load_agent_config(path: str | Path) -> dict:
    """Read and check an agent TOML (keys named in the errors)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"--config {str(path)!r}: no such file")
    data = tomllib.loads(path.read_text())
    for key, allowed, where in ((set(data), AGENT_KEYS, "top level"),
                                (set(data.get("env", {})), ENV_KEYS, "[env]"),
                                (set(data.get("normalize", {})), NORMALIZE_KEYS, "[normalize]"),
                                (set(data.get("train", {})), TRAIN_KEYS, "[train]")):
        bad = key - allowed
        if bad:
            raise ValueError(f"{path}: unknown key(s) {sorted(bad)} in {where} (allowed: "
                             f"{sorted(allowed)})")
    if data.get("algo") not in ALGOS:
        raise ValueError(f"{path}: algo = {data.get('algo')!r} is not allowed: must be one of "
                         f"{ALGOS}")
    for key in ("eval_freq", "eval_episodes", "checkpoint_freq"):
        v = data.get("train", {}).get(key, 1)
        if not isinstance(v, int) or v < 1:
            raise ValueError(f"{path}: [train] {key} = {v!r} is out of range: must be an integer "
                             ">= 1")
    return data


def _progress_callback(total: int):
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class TqdmCallback(BaseCallback):
        """A plain tqdm bar over the env steps (SB3's ProgressBarCallback also needs rich)."""

        def _on_training_start(self) -> None:
            todo = self.locals.get("total_timesteps", total) - self.model.num_timesteps
            self.bar = tqdm(total=todo, unit="step", desc="train", dynamic_ncols=True)

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    return TqdmCallback()


def _reference_gap_callback(reference_mean: float):
    from stable_baselines3.common.callbacks import BaseCallback

    class ReferenceGap(BaseCallback):
        """After each evaluation: log the reference's mean return and the policy's gap to it."""

        def _on_step(self) -> bool:
            ev = self.parent
            self.logger.record("eval/reference_mean_reward", reference_mean)
            self.logger.record("eval/gap_to_reference", float(ev.last_mean_reward) -
                               reference_mean)
            return True

    return ReferenceGap()


def train(algo: str, config: str | Path, timesteps: int, n_envs: int, out: str | Path, *,
          seed: int | None = None, env_kwargs: dict | None = None, progress: bool = True,
          verbose: int = 0) -> Path:
    """Train and save; returns the path of ``model.zip`` (see the module docstring)."""
    from stable_baselines3 import PPO, SAC
    from stable_baselines3.common.callbacks import (CallbackList, CheckpointCallback,
                                                    EvalCallback)
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy
    from stable_baselines3.common.logger import configure
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    from agents.reference import ReferencePolicy

    if algo not in ALGOS:
        raise ValueError(f"--algo {algo!r} is not allowed: must be one of {ALGOS}")
    if timesteps < 1 or n_envs < 1:
        raise ValueError(f"--timesteps = {timesteps!r} and --n-envs = {n_envs!r} must be >= 1")
    cfg = load_agent_config(config)
    if cfg["algo"] != algo:
        raise ValueError(f"--algo {algo!r} does not match algo = {cfg['algo']!r} in {config}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    envc = cfg.get("env", {})
    env_id = envc.get("id", "brush_env:brush_env/FlatPlate-v0")
    kwargs = {"config": envc.get("config", "flat_plate"), **envc.get("kwargs", {}),
              **(env_kwargs or {})}
    tr = cfg.get("train", {})
    seed = tr.get("seed", 0) if seed is None else seed
    norm = cfg.get("normalize", {})
    hyper = dict(cfg.get("hyperparameters", {}))

    vec_cls = SubprocVecEnv if n_envs > 1 else DummyVecEnv
    venv = make_vec_env(env_id, n_envs=n_envs, seed=seed, vec_env_cls=vec_cls,
                        env_kwargs=kwargs)
    eval_env = make_vec_env(env_id, n_envs=1, seed=seed + 10_000, env_kwargs=kwargs)
    normalize = bool(norm.get("obs", False) or norm.get("reward", False))
    if normalize:
        gamma = float(hyper.get("gamma", 0.99))
        clip = float(norm.get("clip_obs", 10.0))
        venv = VecNormalize(venv, norm_obs=bool(norm.get("obs")),
                            norm_reward=bool(norm.get("reward")), clip_obs=clip, gamma=gamma)
        eval_env = VecNormalize(eval_env, training=False, norm_obs=bool(norm.get("obs")),
                                norm_reward=False, clip_obs=clip, gamma=gamma)

    # the reference policy on raw observations, same seeds and episode count as the evaluations
    ref_env = make_vec_env(env_id, n_envs=1, seed=seed + 10_000, env_kwargs=kwargs)
    n_eval = tr.get("eval_episodes", 3)
    ref_mean, ref_std = evaluate_policy(ReferencePolicy.for_env(ref_env), ref_env,
                                        n_eval_episodes=n_eval, deterministic=True)
    ref_env.close()
    (out / "reference.json").write_text(json.dumps(
        {"mean_reward": float(ref_mean), "std_reward": float(ref_std), "episodes": n_eval}))

    policy = cfg.get("policy", "MlpPolicy")
    if kwargs.get("observation_mode") == "dict":
        policy = "MultiInputPolicy"
    tb = str(out / "tb") if importlib.util.find_spec("tensorboard") else None
    if tb is None and verbose:
        print("tensorboard is not installed: logging to stdout/CSV only")
    cls = {"ppo": PPO, "sac": SAC}[algo]
    model = cls(policy, venv, seed=seed, verbose=verbose, tensorboard_log=tb, device="cpu",
                **hyper)
    formats = ["csv"] + (["stdout"] if verbose else []) + (["tensorboard"] if tb else [])
    model.set_logger(configure(str(out), formats))

    eval_cb = EvalCallback(eval_env, n_eval_episodes=n_eval,
                           eval_freq=max(tr.get("eval_freq", 10_000) // n_envs, 1),
                           best_model_save_path=str(out / "best"), log_path=str(out / "eval"),
                           deterministic=True, callback_after_eval=_reference_gap_callback(
                               float(ref_mean)), verbose=verbose)
    ckpt_cb = CheckpointCallback(save_freq=max(tr.get("checkpoint_freq", 50_000) // n_envs, 1),
                                 save_path=str(out / "checkpoints"), name_prefix=algo,
                                 save_vecnormalize=normalize)
    callbacks = [eval_cb, ckpt_cb] + ([_progress_callback(timesteps)] if progress else [])
    t0 = time.perf_counter()
    model.learn(total_timesteps=timesteps, callback=CallbackList(callbacks))
    wall = time.perf_counter() - t0
    model_path = out / "model.zip"
    model.save(model_path)
    if normalize:
        venv.save(str(out / "vecnormalize.pkl"))
    import stable_baselines3

    meta = {"algo": algo, "env_id": env_id, "env_kwargs": kwargs, "timesteps": timesteps,
            "n_envs": n_envs, "seed": seed, "config": str(config), "normalize": norm,
            "hyperparameters": hyper, "policy": policy, "wall_time_s": wall,
            "env_steps_per_s": timesteps / wall, "reference_mean_reward": float(ref_mean),
            "stable_baselines3": stable_baselines3.__version__}
    (out / "meta.json").write_text(json.dumps(meta, indent=2, default=str))
    venv.close()
    eval_env.close()
    return model_path


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m agents.train", description=__doc__.split("\n")[0])
    p.add_argument("--algo", required=True, choices=ALGOS)
    p.add_argument("--config", required=True, help="agent TOML, e.g. configs/agents/ppo.toml")
    p.add_argument("--timesteps", type=int, required=True)
    p.add_argument("--n-envs", type=int, default=1)
    p.add_argument("--out", required=True)
    p.add_argument("--seed", type=int, default=None, help="default: [train] seed of the config")
    p.add_argument("--env-kw", action="append", metavar="KEY=VALUE",
                   help="env setting override, repeatable (TOML values)")
    p.add_argument("--no-progress", action="store_true")
    p.add_argument("--verbose", type=int, default=1)
    return p


def main(argv=None) -> int:
    from agents.evaluate import parse_env_kw

    args = build_parser().parse_args(argv)
    path = train(args.algo, args.config, args.timesteps, args.n_envs, args.out, seed=args.seed,
                 env_kwargs=parse_env_kw(args.env_kw), progress=not args.no_progress,
                 verbose=args.verbose)
    print(f"saved {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
