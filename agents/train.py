"""Train PPO or SAC (stable-baselines3) on BrushEnv.

    python -m agents.train --algo ppo --config configs/agents/ppo.toml --timesteps 200000 \\
        --n-envs 2 --out runs/ppo [--env-kw brush=\\"tiny_env\\"] [--seed 0]

* Environments (``--vec-env``): ``batched`` -- the id's batched env
  (``gym.make_vec(id, N, vectorization_mode="vector_entry_point")``, brush_env/envs/vector.py:
  the N envs in this process, today a Python loop over N single-env cores) behind the SB3
  adapter ``brush_env.envs.sb3.SB3VecEnv``, in ``VecMonitor``; ``subproc`` -- ``make_vec_env``
  from the ``brush_env:brush_env/FlatPlate-v0`` id (the module prefix makes every
  ``SubprocVecEnv`` worker import brush_env, which registers the id), a ``DummyVecEnv`` for
  ``--n-envs 1``, each env in ``Monitor``.  ``auto`` (default): ``batched`` for FlatPlate-v0 and
  ToothRow-v0 at the ``fast`` and ``reduced`` fidelity levels (``BATCHED_LEVELS``: an
  env step costs about a millisecond or less, so worker processes cost more than they give, and
  in one process the envs of a brush share its tip tables), ``subproc`` otherwise.  The
  evaluation env is made the same way with one env.
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

import functools
import importlib.util
import inspect
import json
import sys
import time
from pathlib import Path

from brush_env.engine.checks import ConfigError, check_keys, did_you_mean
from brush_env.engine.config_files import read_toml
from brush_env.user_errors import OneLineParser, add_env_kw, add_flag, run_main

AGENT_KEYS = {"algo", "policy", "env", "normalize", "hyperparameters", "train"}
ENV_KEYS = {"id", "config", "kwargs"}
NORMALIZE_KEYS = {"obs", "reward", "clip_obs"}
TRAIN_KEYS = {"eval_freq", "eval_episodes", "checkpoint_freq", "seed"}
ALGOS = ("ppo", "sac")
VEC_ENVS = ("auto", "batched", "subproc")
#: fidelity levels at which ``--vec-env auto`` trains on the batched env
BATCHED_LEVELS = ("fast", "reduced")


def load_agent_config(path: str | Path) -> dict:
    """Read and check an agent TOML (keys named in the errors)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"--config {str(path)!r}: no such file (e.g. configs/agents/ppo.toml)")
    data = read_toml(path)
    for keys, allowed, where in (
        (data, AGENT_KEYS, "top level"),
        (data.get("env", {}), ENV_KEYS, "[env]"),
        (data.get("normalize", {}), NORMALIZE_KEYS, "[normalize]"),
        (data.get("train", {}), TRAIN_KEYS, "[train]"),
    ):
        check_keys(f"{path} {where}", keys, sorted(allowed))
    if data.get("algo") not in ALGOS:
        raise ConfigError(
            f"{path}: algo = {data.get('algo')!r} is not allowed: must be one of {ALGOS}"
        )
    for key in ("eval_freq", "eval_episodes", "checkpoint_freq"):
        v = data.get("train", {}).get(key, 1)
        if not isinstance(v, int) or v < 1:
            raise ConfigError(
                f"{path}: [train] {key} = {v!r} is out of range: must be an integer >= 1"
            )
    return data


def _say(msg: str) -> None:
    print(msg, flush=True)


def _progress_callback(total: int, announce: bool):
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm import tqdm

    class TqdmCallback(BaseCallback):
        """A tqdm bar over the env steps, and one line with the ETA once the rate is measured."""

        def _on_training_start(self) -> None:
            todo = self.locals.get("total_timesteps", total) - self.model.num_timesteps
            self.bar = tqdm(
                total=todo, unit="step", desc="train", dynamic_ncols=True, disable=not announce
            )
            self.t0, self.todo, self.told = time.perf_counter(), todo, False

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            wall = time.perf_counter() - self.t0
            done = self.bar.n
            if announce and not self.told and (wall > 45.0 or done >= 0.1 * self.todo):
                rate = done / max(wall, 1e-9)
                eta = (self.todo - done) / max(rate, 1e-9)
                self.bar.write(
                    f"measured {rate:.1f} env steps/s: about {eta / 60:.1f} min for "
                    f"the remaining {self.todo - done} steps"
                )
                self.told = True
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
            self.logger.record("eval/gap_to_reference", float(ev.last_mean_reward) - reference_mean)
            return True

    return ReferenceGap()


def check_hyperparameters(algo: str, hyper: dict, source: str) -> None:
    """Every ``[hyperparameters]`` key is an argument of the algorithm's constructor
    (did-you-mean otherwise), checked before any worker starts."""
    from stable_baselines3 import PPO, SAC

    cls = {"ppo": PPO, "sac": SAC}[algo]
    params = inspect.signature(cls.__init__).parameters
    allowed = [
        k
        for k in params
        if k
        not in (
            "self",
            "policy",
            "env",
            "seed",
            "device",
            "tensorboard_log",
            "verbose",
            "_init_setup_model",
        )
    ]
    for key in hyper:
        if key not in allowed:
            raise ConfigError(
                f"{source}: [hyperparameters] {key!r} is not an argument of "
                f"{cls.__name__}{did_you_mean(key, allowed)} (allowed: "
                f"{', '.join(allowed)})"
            )


def _is_brush_env(env_id: str) -> bool:
    """True for the ids whose env is a BrushEnv (FlatPlate-v0, ToothRow-v0: env config files and
    a reference policy); False for the others (PlanarStroke-v0)."""
    import brush_env

    entry = brush_env.ENV_IDS.get(env_id.split(":")[-1], ("",))[0]
    return entry.startswith(("brush_env.envs.flat_plate", "brush_env.envs.tooth_row"))


def _default_env_config(env_id: str) -> str | None:
    """The ``config`` keyword's default of the env class registered as ``env_id`` (None if it
    has none, or the id is not registered: its own error comes from gym.make later)."""
    import importlib
    import inspect

    import gymnasium as gym

    import brush_env  # noqa: F401  (registers the ids)

    spec = gym.registry.get(env_id)
    if spec is None or not isinstance(spec.entry_point, str):
        return None
    module, _, name = spec.entry_point.partition(":")
    cls = getattr(importlib.import_module(module), name)
    par = inspect.signature(cls.__init__).parameters.get("config")
    if par is None or not isinstance(par.default, str):
        return None
    return par.default


def check_inputs(
    algo: str,
    config,
    timesteps: int,
    n_envs: int,
    env_kwargs: dict | None,
    vec_env: str = "auto",
    env_id: str | None = None,
    train_env_kwargs: dict | None = None,
) -> dict:
    """Validate everything the run needs in this process (nothing written, no worker started);
    returns the resolved settings: cfg, env_id, kwargs (gym.make), train_kwargs (the training
    envs' own overrides, ``--train-env-kw``), hyper, seed, norm, train, vec_env (``batched`` or
    ``subproc``, ``auto`` resolved).

    ``train_env_kwargs`` change the envs the policy learns on and nothing else: the evaluations
    during training, the saved ``env_kwargs`` (what agents/evaluate.py scores the model on) and
    the reference's baseline keep the task's own settings.  The campaign uses it to tighten
    the force limit in training (docs/rl.md, "Training: the campaign").

    ``env_id`` (``--env``) trains on another id than the config's ``[env] id``; the config's
    ``[env] config`` names that id's env file, so the other id gets its own default (ToothRow-v0:
    ``tooth_row``) unless ``env_kwargs`` names one.  (The campaign passes its ``env_id`` here:
    before, a tooth-row campaign trained on the plate of configs/agents/ppo.toml.)"""
    from brush_env.envs.config import load_env_config

    if algo not in ALGOS:
        raise ConfigError(f"--algo {algo!r} is not allowed: must be one of {ALGOS}")
    if vec_env not in VEC_ENVS:
        raise ConfigError(f"--vec-env {vec_env!r} is not allowed: must be one of {VEC_ENVS}")
    for flag, value, unit in (
        ("--timesteps", timesteps, "env steps"),
        ("--n-envs", n_envs, "envs"),
    ):
        if value < 1:  # each flag on its own: a good value is never blamed with a bad one
            raise ConfigError(f"{flag} = {value!r} is out of range: must be >= 1 ({unit})")
    cfg = load_agent_config(config)
    if cfg["algo"] != algo:
        raise ConfigError(f"--algo {algo!r} does not match algo = {cfg['algo']!r} in {config}")
    envc = dict(cfg.get("env", {}))
    toml_id = envc.get("id", "brush_env:brush_env/FlatPlate-v0")
    if env_id is None:
        env_id = toml_id
    elif env_id.split(":", 1)[-1] != toml_id.split(":", 1)[-1]:
        envc.pop("config", None)  # the config's env file is for its own id
    if env_id.startswith("brush_env/"):  # SubprocVecEnv workers import the package by the prefix
        env_id = "brush_env:" + env_id
    if env_id.split(":", 1)[-1].startswith("brush_env/"):  # ours: a misspelt id gets a hint
        from agents.evaluate import check_env_id

        check_env_id(env_id, f"{config}: [env] id")
    if _is_brush_env(env_id):
        own = envc.get("config") or _default_env_config(env_id.split(":", 1)[-1])
        kwargs = {
            "config": own or "flat_plate",
            **envc.get("kwargs", {}),
            **(env_kwargs or {}),
        }
        env_settings = {k: v for k, v in kwargs.items() if k not in ("config", "render_mode")}
        env_cfg = load_env_config(kwargs["config"], **env_settings)  # names a bad key or value
        if vec_env == "auto":
            vec_env = "batched" if env_cfg.fidelity in BATCHED_LEVELS else "subproc"
    else:  # e.g. PlanarStroke-v0: its keywords are checked when it is made, before training
        if "config" in envc:
            raise ConfigError(f"{config}: [env] config is only for BrushEnv ids, not {env_id!r}")
        kwargs = {**envc.get("kwargs", {}), **(env_kwargs or {})}
        import gymnasium as gym

        gym.make(env_id.split(":")[-1] if ":" in env_id else env_id, **kwargs).close()
        if vec_env == "batched":
            raise ConfigError(f"--vec-env batched: {env_id!r} has no batched env (a BrushEnv id)")
        vec_env = "subproc"
    _check_train_env_kwargs(env_id, kwargs, train_env_kwargs)
    hyper = dict(cfg.get("hyperparameters", {}))
    check_hyperparameters(algo, hyper, str(config))
    return {
        "cfg": cfg,
        "env_id": env_id,
        "kwargs": kwargs,
        "train_kwargs": dict(train_env_kwargs or {}),
        "hyper": hyper,
        "norm": cfg.get("normalize", {}),
        "train": cfg.get("train", {}),
        "vec_env": vec_env,
    }


def _check_train_env_kwargs(env_id: str, kwargs: dict, train_env_kwargs: dict | None) -> None:
    """The training envs' own settings (``--train-env-kw``) on top of the task's ``kwargs``:
    known keys with allowed values, never another env file."""
    if not train_env_kwargs:
        return
    if not _is_brush_env(env_id):
        raise ConfigError(f"--train-env-kw is only for BrushEnv ids, not {env_id!r}")
    if "config" in train_env_kwargs:
        raise ConfigError(
            "--train-env-kw config=...: the training envs take the task's env file; give it "
            "with --env-kw config=..."
        )
    from brush_env.envs.config import load_env_config

    both = {**kwargs, **train_env_kwargs}
    load_env_config(both.pop("config"), **{k: v for k, v in both.items() if k != "render_mode"})


def make_envs(run: dict, n_envs: int, seed: int):
    """Training vector env (``run["vec_env"]``: the batched env, or Subproc for n_envs > 1) and
    evaluation env, VecNormalize'd as the config's [normalize] says (evaluation: training
    statistics, raw rewards)."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecNormalize

    env_id, kwargs, norm = run["env_id"], run["kwargs"], run["norm"]
    learn_kwargs = {**kwargs, **run["train_kwargs"]}  # the task's settings, as trained on
    if run["vec_env"] == "batched":
        from stable_baselines3.common.vec_env import VecMonitor

        from brush_env.envs.sb3 import make_sb3_vec_env

        venv = VecMonitor(make_sb3_vec_env(env_id, n_envs, seed=seed, **learn_kwargs))
        eval_env = VecMonitor(make_sb3_vec_env(env_id, 1, seed=seed + 10_000, **kwargs))
    else:
        vec_cls = SubprocVecEnv if n_envs > 1 else DummyVecEnv
        venv = make_vec_env(
            env_id, n_envs=n_envs, seed=seed, vec_env_cls=vec_cls, env_kwargs=learn_kwargs
        )
        eval_env = make_vec_env(env_id, n_envs=1, seed=seed + 10_000, env_kwargs=kwargs)
    if norm.get("obs", False) or norm.get("reward", False):
        gamma = float(run["hyper"].get("gamma", 0.99))
        clip = float(norm.get("clip_obs", 10.0))
        venv = VecNormalize(
            venv,
            norm_obs=bool(norm.get("obs")),
            norm_reward=bool(norm.get("reward")),
            clip_obs=clip,
            gamma=gamma,
        )
        eval_env = VecNormalize(
            eval_env,
            training=False,
            norm_obs=bool(norm.get("obs")),
            norm_reward=False,
            clip_obs=clip,
            gamma=gamma,
        )
    return venv, eval_env


def _evaluate_reference(run: dict, seed: int, n_eval: int, out: Path) -> float:
    """The reference policy on raw observations, same seeds and episodes as the evaluations."""
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.evaluation import evaluate_policy

    from agents.reference import ReferencePolicy

    ref_env = make_vec_env(run["env_id"], n_envs=1, seed=seed + 10_000, env_kwargs=run["kwargs"])
    ref_mean, ref_std = evaluate_policy(
        ReferencePolicy.for_env(ref_env), ref_env, n_eval_episodes=n_eval, deterministic=True
    )
    ref_env.close()
    (out / "reference.json").write_text(
        json.dumps(
            {"mean_reward": float(ref_mean), "std_reward": float(ref_std), "episodes": n_eval}
        )
    )
    return float(ref_mean)


def _tensorboard_dir(out: Path, verbose: int) -> str | None:
    """OUT/tb when tensorboard is importable, else None (said once when verbose)."""
    tb = str(out / "tb") if importlib.util.find_spec("tensorboard") else None
    if tb is None and verbose:
        _say("tensorboard is not installed: logging to stdout/CSV only")
    return tb


def _set_logger(model, out: Path, verbose: int, tb: str | None) -> None:
    """CSV (progress.csv) always, stdout at verbose > 1, TensorBoard when ``tb``."""
    from stable_baselines3.common.logger import configure

    formats = ["csv"] + (["stdout"] if verbose > 1 else []) + (["tensorboard"] if tb else [])
    model.set_logger(configure(str(out), formats))


def _make_model(algo: str, run: dict, venv, seed: int, out: Path, verbose: int):
    from stable_baselines3 import PPO, SAC

    policy = run["cfg"].get("policy", "MlpPolicy")
    if run["kwargs"].get("observation_mode") == "dict":
        policy = "MultiInputPolicy"
    tb = _tensorboard_dir(out, verbose)
    cls = {"ppo": PPO, "sac": SAC}[algo]
    model = cls(
        policy, venv, seed=seed, verbose=verbose, tensorboard_log=tb, device="cpu", **run["hyper"]
    )
    _set_logger(model, out, verbose, tb)
    return model, policy


def check_init_model(path: str | Path, algo: str, env_id: str) -> dict:
    """The model ``--init-model`` names: a file saved by this script for the same algorithm and
    env id (its meta.json beside it, agents.evaluate.companions).  Returns {"model", "meta",
    "vecnormalize"} (vecnormalize: the statistics' path, or None)."""
    from agents.evaluate import companions

    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"--init-model {str(path)!r}: no such file (a model.zip of agents/train)")
    meta_path, vn = companions(path)
    if not meta_path.is_file():
        raise ConfigError(
            f"--init-model {str(path)!r}: no meta.json beside it (saved by agents/train.py?)"
        )
    meta = json.loads(meta_path.read_text())
    if meta.get("algo") != algo:
        raise ConfigError(
            f"--init-model {str(path)!r} is a {meta.get('algo')!r} model: must be --algo {algo!r}"
        )
    if meta.get("env_id", "").split(":")[-1] != env_id.split(":")[-1]:
        raise ConfigError(
            f"--init-model {str(path)!r} was trained on {meta.get('env_id')!r}, not {env_id!r}"
        )
    return {"model": path, "meta": meta, "vecnormalize": vn if vn.is_file() else None}


@functools.cache
def continued_sac():
    """stable-baselines3's SAC for a run that goes on from a trained policy (``--init-model``):
    its warm-up -- the config's ``learning_starts`` env steps collected before the first update
    -- acts with the loaded policy (sampled), where SAC's own warm-up acts uniformly at random.

    Why: the replay buffer is not in model.zip, so the continued run starts with an empty one.
    SAC's own warm-up fills it with random presses instead of the policy's own states; updating
    from the first step instead (session 27, 2026-12-06) fitted the loaded critic to a handful of
    transitions (in one seed an episode ended at 3 N after 4 steps: critic loss 124 at the first
    update).  This warm-up is the continuation that keeps the policy's own data; it did not by
    itself stop SAC's 3 N second stage from collapsing in one seed of three (docs/rl.md)."""
    from stable_baselines3 import SAC

    class ContinuedSAC(SAC):
        def _sample_action(self, learning_starts, action_noise=None, n_envs=1):
            # learning_starts = 0: the policy acts from the first step; self.learning_starts
            # still holds the updates back for the warm-up
            return super()._sample_action(0, action_noise, n_envs)

    return ContinuedSAC


def _load_model(algo: str, init: dict, run: dict, venv, eval_env, seed: int, out: Path, verbose):
    """``_make_model`` from a saved model (``check_init_model``): its weights, hyperparameters
    and optimiser, on the new envs; its observation and return statistics copied into the new
    VecNormalize wrappers (which go on updating them while training)."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    tb = _tensorboard_dir(out, verbose)
    cls = {"ppo": PPO, "sac": continued_sac()}[algo]
    model = cls.load(init["model"], env=venv, device="cpu", seed=seed, tensorboard_log=tb)
    model.verbose = verbose
    if init["vecnormalize"] is not None and isinstance(venv, VecNormalize):
        stats = VecNormalize.load(str(init["vecnormalize"]), venv.venv)
        for w in (venv, eval_env):
            w.obs_rms = stats.obs_rms.copy()
        venv.ret_rms = stats.ret_rms.copy()
    _set_logger(model, out, verbose, tb)
    return model, init["meta"].get("policy", run["cfg"].get("policy", "MlpPolicy"))


def _eval_and_checkpoint(algo, tr: dict, n_envs: int, eval_env, out: Path, ref_mean, normalize):
    """The evaluation callback (``[train] eval_freq``, ``eval_episodes``; logs the gap to the
    reference policy's mean return ``ref_mean``) and the checkpoint callback
    (``checkpoint_freq``, with the VecNormalize statistics when ``normalize``); the frequencies
    are in env steps over all ``n_envs`` envs."""
    from stable_baselines3.common.callbacks import CheckpointCallback, EvalCallback

    eval_cb = EvalCallback(
        eval_env,
        n_eval_episodes=tr.get("eval_episodes", 3),
        eval_freq=max(tr.get("eval_freq", 10_000) // n_envs, 1),
        best_model_save_path=str(out / "best"),
        log_path=str(out / "eval"),
        deterministic=True,
        verbose=0,
        callback_after_eval=None if ref_mean is None else _reference_gap_callback(ref_mean),
    )
    ckpt_cb = CheckpointCallback(
        save_freq=max(tr.get("checkpoint_freq", 50_000) // n_envs, 1),
        save_path=str(out / "checkpoints"),
        name_prefix=algo,
        save_vecnormalize=normalize,
    )
    return eval_cb, ckpt_cb


def train(
    algo: str,
    config: str | Path,
    timesteps: int,
    n_envs: int,
    out: str | Path,
    *,
    seed: int | None = None,
    env_kwargs: dict | None = None,
    progress: bool = True,
    verbose: int = 0,
    vec_env: str = "auto",
    env_id: str | None = None,
    train_env_kwargs: dict | None = None,
    init_model: str | Path | None = None,
) -> Path:
    """Train and save; returns the path of ``model.zip`` (see the module docstring).

    ``init_model`` (``--init-model``): start from a model saved by this script (its weights,
    its hyperparameters and optimiser state, and its VecNormalize statistics beside it) instead
    of a fresh network, e.g. to go on learning under other training settings; ``timesteps`` are
    the steps added.

    Stages: check inputs -> envs -> reference evaluation -> model -> learn (evaluations and
    checkpoints) -> final evaluation/checkpoint if the run was too short for one -> save."""
    from stable_baselines3.common.callbacks import CallbackList
    from stable_baselines3.common.vec_env import VecNormalize

    run = check_inputs(
        algo, config, timesteps, n_envs, env_kwargs, vec_env, env_id, train_env_kwargs
    )
    tr = run["train"]
    seed = tr.get("seed", 0) if seed is None else seed
    init = None if init_model is None else check_init_model(init_model, algo, run["env_id"])
    n_eval = tr.get("eval_episodes", 3)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    say = _say if progress else (lambda msg: None)
    say(
        f"[1/4] starting {n_envs} env(s) of {run['env_id']}, {run['vec_env']} (numba kernels "
        "load or compile)"
    )
    venv, eval_env = make_envs(run, n_envs, seed)
    if _is_brush_env(run["env_id"]):
        say(
            f"[2/4] evaluating the reference policy on {n_eval} episode(s) (its return is the "
            "baseline logged beside every evaluation)"
        )
        ref_mean = _evaluate_reference(run, seed, n_eval, out)
        say(f"      reference mean return {ref_mean:.2f}")
    else:
        ref_mean = None
        say(f"[2/4] {run['env_id']} has no reference policy: evaluations are logged alone")
    normalize = isinstance(venv, VecNormalize)
    if init is None:
        model, policy = _make_model(algo, run, venv, seed, out, verbose)
    else:
        say(f"      starting from {init_model}")
        model, policy = _load_model(algo, init, run, venv, eval_env, seed, out, verbose)
    eval_cb, ckpt_cb = _eval_and_checkpoint(algo, tr, n_envs, eval_env, out, ref_mean, normalize)
    say(f"[3/4] training {algo.upper()} for {timesteps} env steps")
    t0 = time.perf_counter()
    model.learn(
        total_timesteps=timesteps,
        callback=CallbackList([eval_cb, ckpt_cb, _progress_callback(timesteps, progress)]),
    )
    wall = time.perf_counter() - t0
    say("[4/4] final evaluation and checkpoint, saving")
    _finish_short_run(eval_cb, ckpt_cb)
    model_path = out / "model.zip"
    model.save(model_path)
    if normalize:
        venv.save(str(out / "vecnormalize.pkl"))
    import stable_baselines3

    meta = {
        "algo": algo,
        "env_id": run["env_id"],
        "env_kwargs": run["kwargs"],
        "train_env_kwargs": run["train_kwargs"],
        "timesteps": timesteps,
        "n_envs": n_envs,
        "vec_env": run["vec_env"],
        "seed": seed,
        "config": str(config),
        "normalize": run["norm"],
        "hyperparameters": run["hyper"],
        "policy": policy,
        "wall_time_s": wall,
        "env_steps_per_s": timesteps / wall,
        "reference_mean_reward": ref_mean,
        "init_model": None if init_model is None else str(init_model),
        "stable_baselines3": stable_baselines3.__version__,
        "commit": _commit(),
    }
    (out / "meta.json").write_text(json.dumps(meta, indent=2, default=str))
    venv.close()
    eval_env.close()
    return model_path


def _commit() -> str:
    from agents.evaluate import commit_id

    return commit_id()


def _finish_short_run(eval_cb, ckpt_cb) -> None:
    """A run shorter than eval_freq or checkpoint_freq still leaves one evaluation (eval/, best/)
    and one checkpoint: each callback is fired once more with a period of one call."""
    if not eval_cb.evaluations_timesteps:
        eval_cb.eval_freq = 1
        eval_cb.on_step()
    if not any(Path(ckpt_cb.save_path).glob("*.zip")):
        ckpt_cb.save_freq = 1
        ckpt_cb.on_step()


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="python -m agents.train", description=__doc__.split("\n")[0])
    p.add_argument("--algo", required=True, choices=ALGOS, help="algorithm (must match the config)")
    p.add_argument("--config", required=True, help="agent TOML, e.g. configs/agents/ppo.toml")
    p.add_argument("--timesteps", type=int, required=True, help="total env steps to train")
    p.add_argument("--n-envs", type=int, default=1, help="envs stepped together (default 1)")
    p.add_argument(
        "--vec-env",
        choices=VEC_ENVS,
        default="auto",
        help="batched: the id's batched env in this process; subproc: SubprocVecEnv (n > 1); "
        "auto (default): batched at the fast and reduced levels, else subproc",
    )
    p.add_argument("--out", required=True, help="output directory (model, logs, checkpoints)")
    p.add_argument("--seed", type=int, default=None, help="default: [train] seed of the config")
    p.add_argument(
        "--env",
        default=None,
        help="env id to train on (default: the config's [env] id), e.g. brush_env/ToothRow-v0",
    )
    add_env_kw(p, "TOML values")
    p.add_argument(
        "--train-env-kw",
        action="append",
        metavar="KEY=VALUE",
        help="env setting of the training envs only, repeatable (e.g. total_force_limit=3.0: a "
        "margin on the task's limit); evaluations and the saved env settings keep --env-kw's",
    )
    p.add_argument(
        "--init-model",
        default=None,
        metavar="PATH",
        help="start from this saved model (a model.zip or checkpoint of agents/train, with its "
        "statistics) instead of a fresh network; --timesteps are the steps added",
    )
    add_flag(p, "--no-progress", "no phase lines, bar or ETA")
    p.add_argument(
        "--verbose",
        type=int,
        default=1,
        help="0 quiet, 1 phases and progress (default), 2 also SB3's stdout logs",
    )
    return p


def _main(argv) -> int:
    from agents.evaluate import parse_env_kw

    args = build_parser().parse_args(argv)
    path = train(
        args.algo,
        args.config,
        args.timesteps,
        args.n_envs,
        args.out,
        seed=args.seed,
        env_kwargs=parse_env_kw(args.env_kw),
        progress=not args.no_progress,
        verbose=args.verbose,
        vec_env=args.vec_env,
        env_id=args.env,
        train_env_kwargs=parse_env_kw(args.train_env_kw),
        init_model=args.init_model,
    )
    print(f"saved {path}")
    return 0


def main(argv=None) -> int:
    """Entry point: user mistakes in one stderr line, exit code 2 (``--debug``: traceback)."""
    return run_main(_main, argv, prog="python -m agents.train")


if __name__ == "__main__":
    sys.exit(main())
