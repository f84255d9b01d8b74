"""The RL campaign in one command: train, evaluate at two fidelities, tabulate, plot.

    python -m agents.campaign --config configs/agents/campaign.toml [--jobs 2] [--dry-run]

Stages (each prints its wall time; the whole run prints its total):

1. **train** -- every ``[[train]]`` entry at every one of its seeds, with ``agents/train.py``
   (``python -m agents.train ... --no-progress`` in a worker process, its output in
   ``OUT/<name>/seed_<k>.log``; ``name`` defaults to ``algo``), ``jobs`` runs at a time.  An
   entry with ``init = "<name>"`` starts each seed from that earlier entry's policy
   (``--init-model``) with its own ``train_env_kwargs`` on top of the campaign's: entries
   are trained and selected in waves, each after the one it starts from (stages 1-2 per
   wave).  ``evaluate = false`` leaves an entry out of stage 3 and the table.
2. **select** (with a ``[select]`` table) -- each run's checkpoints (``OUT/<name>/seed_<k>/
   checkpoints/``, each with its own VecNormalize statistics) and its final model are evaluated
   on validation episodes (``[select] seed`` + i at ``[select] level``: seeds that are neither
   the evaluation's nor the training's) and the one with the best mean ``[select] metric`` is
   the run's policy (``OUT/<name>/seed_<k>/selected.zip`` with its statistics and
   ``selected.json``), as the RL Zoo keeps its best evaluated model: PPO's evaluation return
   swings by tens of points between checkpoints (docs/rl.md), and the last one is not the best.
   Without ``[select]`` every run's policy is its final ``model.zip``.
3. **evaluate** -- the baselines (``reference``, ``random``) and every run's policy with
   ``agents/evaluate.py`` on the same fixed-seed episodes (``[evaluate] seed`` + i), at each level
   of ``[evaluate] levels`` (level -> number of episodes), in ``OUT/eval/<level>/<name>/``.
   With ``[evaluate] chunk = K`` an evaluation runs as tasks of at most K episodes
   (``OUT/eval/<level>/<name>/parts/seed_<first>/``), ``jobs`` at a time, joined into the
   evaluation's ``summary.json`` (``agents.evaluate.join_summaries``: the episodes are the single
   run's, each resets with its own seed and the policies act deterministically).
   ``[evaluate] env_kwargs``: gym.make keywords of the evaluations alone, on top of
   ``[env_kwargs]`` (neither the training's nor the selection's), e.g. the robot's force guard.
4. **report** -- ``OUT/results.md`` and ``OUT/results.json``: per level, each policy's coverage,
   time above the force limit, peak and mean total force, peak tip force and return; for trained
   policies the mean +- std over training seeds of each seed's episode mean, for the baselines the
   mean +- std over episodes.  ``OUT/learning_curves.png``: the evaluation return during training,
   mean over seeds with a min-max band, the reference's return as a line.

**Resumable**: a run whose folder holds ``meta.json`` (agents/train.py writes it last) and an
evaluation whose folder holds ``summary.json`` are kept; an unfinished run is started again from
its beginning (its folder is cleared first); an evaluation of another model than the run's policy
now is made again.  Re-running after a crash or Ctrl-C continues.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import textwrap
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from brush_env.engine.checks import ConfigError, check_keys
from brush_env.engine.config_files import read_toml
from brush_env.user_errors import OneLineParser, UserError, add_flag, run_main

TOP_KEYS = {
    "out",
    "env_id",
    "jobs",
    "env_kwargs",
    "train_env_kwargs",
    "train",
    "select",
    "evaluate",
}
SELECT_KEYS = {"episodes", "seed", "level", "metric"}
SELECT_METRICS = ("return", "coverage")
TRAIN_KEYS = {
    "algo",
    "config",
    "timesteps",
    "n_envs",
    "seeds",
    "name",
    "init",
    "train_env_kwargs",
    "evaluate",
}
EVAL_KEYS = {"seed", "baselines", "levels", "chunk", "env_kwargs"}
BASELINES = ("reference", "random")
#: metrics of agents/evaluate.py's summary shown in the table: key -> (header, scale, format)
METRICS = {
    "coverage": ("coverage [%]", 100.0, "{:.1f}"),
    "time_above_force_limit": ("time above limit [s]", 1.0, "{:.4f}"),  # one engine step: 0.001
    "peak_normal_force": ("peak force [N]", 1.0, "{:.2f}"),
    "mean_normal_force": ("mean force [N]", 1.0, "{:.2f}"),
    "peak_tip_force": ("peak tip force [N]", 1.0, "{:.3f}"),
    "return": ("return", 1.0, "{:.1f}"),
}


def _int(path: str, value, low: int = 1) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < low:
        raise ConfigError(f"{path} = {value!r} is out of range: must be an integer >= {low}")
    return value


def load_campaign(path: str | Path) -> dict:
    """Read and check a campaign TOML (every key and value named in the errors)."""
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"--config {str(path)!r}: no such file (configs/agents/campaign.toml)")
    c = read_toml(path)
    check_keys(f"{path} top level", c, sorted(TOP_KEYS))
    for key in ("out", "train", "evaluate"):
        if key not in c:
            raise ConfigError(f"{path}: missing key {key!r}")
    c.setdefault("env_id", "brush_env/FlatPlate-v0")
    c.setdefault("env_kwargs", {})
    c.setdefault("train_env_kwargs", {})
    if not isinstance(c["env_kwargs"], dict):
        raise ConfigError(f"{path}: [env_kwargs] must be a table of gym.make keywords")
    _own_keywords(f"{path} [train_env_kwargs]", c["train_env_kwargs"])
    c["jobs"] = _int(f"{path}: jobs", c.get("jobs", 1))
    _check_train(path, c["train"])
    _check_evaluate(path, c["evaluate"])
    if "select" in c:
        _check_select(path, c)
    return c


def _check_train(path: Path, train) -> None:
    if not isinstance(train, list) or not train:
        raise ConfigError(f"{path}: [[train]] must be one or more tables")
    seen: dict = {}
    for i, t in enumerate(train):
        where = f"{path} [[train]] #{i + 1}"
        check_keys(where, t, sorted(TRAIN_KEYS))
        for key in ("algo", "config", "timesteps", "seeds"):
            if key not in t:
                raise ConfigError(f"{where}: missing key {key!r}")
        t.setdefault("name", t["algo"])
        if t["name"] in seen:
            raise ConfigError(
                f"{where}: name = {t['name']!r} appears twice (name defaults to algo)"
            )
        _check_stage(where, t, seen)
        seen[t["name"]] = t
        _int(f"{where} timesteps", t["timesteps"])
        t["n_envs"] = _int(f"{where} n_envs", t.get("n_envs", 1))
        if not isinstance(t["seeds"], list) or not t["seeds"]:
            raise ConfigError(f"{where}: seeds = {t['seeds']!r} must be a non-empty list")
        for s in t["seeds"]:
            _int(f"{where} seeds", s, 0)
        if not Path(t["config"]).is_file():
            raise ConfigError(f"{where}: config = {t['config']!r}: no such file")


def _own_keywords(where: str, kw) -> None:
    """A table of gym.make keywords of one stage alone (training, an entry's training, the
    evaluations), on top of [env_kwargs]: fidelity and config are the campaign's, set once there
    (the levels of selection and evaluation in [select] / [evaluate])."""
    if not isinstance(kw, dict):
        raise ConfigError(f"{where} must be a table of gym.make keywords")
    if "fidelity" in kw or "config" in kw:
        raise ConfigError(
            f"{where}: fidelity and config belong in [env_kwargs] (the selection and evaluation "
            "levels are set there and in [select] / [evaluate])"
        )


def _check_evaluate(path: Path, ev: dict) -> None:
    from brush_env.engine.fidelity import LEVELS

    if "episodes" in ev:  # an earlier key, read by nothing: say where the counts are given
        raise ConfigError(
            f"{path} [evaluate] episodes = {ev['episodes']!r} is not read: give each level's "
            "number of episodes in levels = {{ <level> = <episodes>, ... }}"
        )
    check_keys(f"{path} [evaluate]", ev, sorted(EVAL_KEYS))
    ev.setdefault("seed", 1000)
    ev.setdefault("baselines", list(BASELINES))
    _int(f"{path} [evaluate] seed", ev["seed"], 0)
    ev.setdefault("env_kwargs", {})
    _own_keywords(f"{path} [evaluate] env_kwargs", ev["env_kwargs"])
    if "chunk" in ev:
        _int(f"{path} [evaluate] chunk", ev["chunk"])
    for b in ev["baselines"]:
        if b not in BASELINES:
            raise ConfigError(
                f"{path} [evaluate] baselines: {b!r} is not allowed: must be one of {BASELINES}"
            )
    levels = ev.get("levels") or {}
    if not isinstance(levels, dict) or not levels:
        raise ConfigError(f"{path} [evaluate] levels must map a fidelity level to episodes")
    for level, n in levels.items():
        if level not in LEVELS:
            raise ConfigError(
                f"{path} [evaluate] levels: {level!r} is not a fidelity level (known: "
                f"{', '.join(LEVELS)})"
            )
        _int(f"{path} [evaluate] levels.{level}", n)


def _check_stage(where: str, t: dict, earlier: dict) -> None:
    """A [[train]] entry's stage keys: ``init`` names an earlier entry of the same algorithm that
    trains every seed of this one; ``train_env_kwargs`` is a table without fidelity or config;
    ``evaluate`` is a bool."""
    t.setdefault("train_env_kwargs", {})
    t.setdefault("evaluate", True)
    if not isinstance(t["evaluate"], bool):
        raise ConfigError(f"{where}: evaluate = {t['evaluate']!r} must be true or false")
    _own_keywords(f"{where} train_env_kwargs", t["train_env_kwargs"])
    if "init" not in t:
        return
    first = earlier.get(t["init"])
    if first is None:
        raise ConfigError(
            f"{where}: init = {t['init']!r} is not the name of an earlier [[train]] entry "
            f"(earlier: {sorted(earlier) or 'none'})"
        )
    if first["algo"] != t["algo"]:
        raise ConfigError(
            f"{where}: init = {t['init']!r} trains {first['algo']!r}, not algo = {t['algo']!r}"
        )
    missing = sorted(set(t["seeds"]) - set(first["seeds"]))
    if missing:
        raise ConfigError(f"{where}: seeds {missing} are not trained by init = {t['init']!r}")


def _waves(c: dict) -> list[list[dict]]:
    """The [[train]] entries in the order they can run: an entry after the one it starts from
    (``init``)."""
    depth: dict = {}
    for t in c["train"]:  # an init names an earlier entry (_check_stage)
        depth[t["name"]] = depth[t["init"]] + 1 if "init" in t else 0
    return [
        [t for t in c["train"] if depth[t["name"]] == d] for d in range(max(depth.values()) + 1)
    ]


def _check_select(path: Path, c: dict) -> None:
    from brush_env.engine.fidelity import LEVELS

    sel = c["select"]
    where = f"{path} [select]"
    check_keys(where, sel, sorted(SELECT_KEYS))
    sel["episodes"] = _int(f"{where} episodes", sel.get("episodes", 10))
    sel["seed"] = _int(f"{where} seed", sel.get("seed", 2000), 0)
    sel.setdefault("level", c["env_kwargs"].get("fidelity", "fast"))
    sel.setdefault("metric", "return")
    if sel["level"] not in LEVELS:
        raise ConfigError(
            f"{where} level = {sel['level']!r} is not a fidelity level (known: {', '.join(LEVELS)})"
        )
    if sel["metric"] not in SELECT_METRICS:
        raise ConfigError(
            f"{where} metric = {sel['metric']!r} is not allowed: must be one of {SELECT_METRICS}"
        )
    ev = c["evaluate"]
    lo, hi = ev["seed"], ev["seed"] + max(ev["levels"].values())
    if sel["seed"] < hi and lo < sel["seed"] + sel["episodes"]:
        raise ConfigError(
            f"{where} seed = {sel['seed']}: its {sel['episodes']} validation seeds overlap the "
            f"evaluation's ({lo}..{hi - 1}); a checkpoint chosen on the test episodes would be "
            "scored on them"
        )


def _runs(c: dict, entries: list[dict] | None = None) -> list[tuple[str, int, dict]]:
    """(entry name, seed, the entry with its run folder "dir") of every run (of ``entries``)."""
    return [
        (t["name"], s, _run(c, t, s))
        for t in (c["train"] if entries is None else entries)
        for s in t["seeds"]
    ]


def _run(c: dict, t: dict, seed: int) -> dict:
    """The entry ``t`` with the run folder of its seed ``seed`` ("dir": OUT/<name>/seed_<k>)."""
    return {**t, "dir": Path(c["out"]) / t["name"] / f"seed_{seed}"}


def _entry(c: dict, name: str) -> dict:
    return next(t for t in c["train"] if t["name"] == name)


def _train_cmd(c: dict, t: dict, seed: int) -> list[str]:
    cmd = [
        sys.executable,
        "-W",
        "ignore",
        "-m",
        "agents.train",
        "--algo",
        t["algo"],
        "--config",
        t["config"],
        "--timesteps",
        str(t["timesteps"]),
        "--n-envs",
        str(t["n_envs"]),
        "--out",
        str(t["dir"]),
        "--seed",
        str(seed),
        "--no-progress",
        "--env",
        c["env_id"],
    ]
    for k, v in c["env_kwargs"].items():
        cmd += ["--env-kw", f"{k}={json.dumps(v)}"]
    for k, v in {**c.get("train_env_kwargs", {}), **t.get("train_env_kwargs", {})}.items():
        cmd += ["--train-env-kw", f"{k}={json.dumps(v)}"]
    if "init" in t:
        first = _entry(c, t["init"])
        cmd += ["--init-model", str(policy_of(c, _run(c, first, seed)))]
    return cmd


def _run_logged(cmd: list[str], log: Path, threads: int | None) -> tuple[int, float]:
    env = dict(os.environ)
    if threads is not None:
        # one thread per worker when workers share the cores: torch's own pool of one thread per
        # core would otherwise fight the other worker (and numba's, if a kernel is parallel)
        for k in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
            env.setdefault(k, str(threads))
    t0 = time.perf_counter()
    with log.open("w") as fh:
        rc = subprocess.call(cmd, stdout=fh, stderr=subprocess.STDOUT, env=env)
    return rc, time.perf_counter() - t0


def policy_of(c: dict, t: dict) -> Path:
    """The run's policy: its selected checkpoint (``select`` stage) if the campaign selects,
    else its final model."""
    sel = t["dir"] / "selected.zip"
    return sel if "select" in c else t["dir"] / "model.zip"


def _candidates(t: dict) -> list[tuple[str, Path, Path]]:
    """(name, model, VecNormalize statistics) of a run's checkpoints and its final model."""
    d, algo = t["dir"], t["algo"]
    out = []
    for z in (d / "checkpoints").glob(f"{algo}_*_steps.zip"):
        steps = int(z.stem.split("_")[-2])
        vn = z.with_name(f"{algo}_vecnormalize_{steps}_steps.pkl")
        out.append((steps, f"steps_{steps}", z, vn))
    meta = json.loads((d / "meta.json").read_text())
    out.append((meta.get("timesteps", 0) + 1, "final", d / "model.zip", d / "vecnormalize.pkl"))
    return [(name, z, vn) for _, name, z, vn in sorted(out)]


def _stage(run: Path, model: Path, vn: Path, dest: Path, extra: dict | None = None) -> Path:
    """Copy a model to ``dest``.zip with ``dest``.meta.json (the run's, plus ``extra``) and
    ``dest``.vecnormalize.pkl (its own statistics), as agents/evaluate.py finds them."""
    dest.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(model, f"{dest}.zip")
    meta = json.loads((run / "meta.json").read_text())
    meta.update(extra or {})
    Path(f"{dest}.meta.json").write_text(json.dumps(meta, indent=2))
    if vn.is_file():
        shutil.copyfile(vn, f"{dest}.vecnormalize.pkl")
    return Path(f"{dest}.zip")


def select_stage(c: dict, jobs: int, dry: bool, entries: list[dict] | None = None) -> list[str]:
    """Evaluate every run's candidates (``_candidates``) on the validation episodes and keep the
    best as ``selected.zip`` (module docstring)."""
    if "select" not in c:
        print("  no [select]: every run's policy is its final model")
        return []
    sel = c["select"]
    tasks, pending = [], []
    for algo, seed, t in _runs(c, entries):
        d = t["dir"]
        if (d / "selected.json").is_file():
            print(f"  kept {algo} seed {seed}'s choice ({d}/selected.json)")
            continue
        if not (d / "meta.json").is_file():
            print(f"  skip {algo} seed {seed}: not trained")
            continue
        pending.append((algo, seed, t))
        for name, z, vn in _candidates(t):
            out = d / "select" / name
            if (out / "summary.json").is_file():
                continue
            spec = z if dry else _stage(d, z, vn, d / "select" / "models" / name)
            cmd = _eval_cmd(
                c, sel["level"], str(spec), sel["episodes"], out, sel["seed"], own=False
            )
            tasks.append((f"validate {algo} seed {seed} {name}", cmd, d / "select" / f"{name}.log"))
    failed = _launch(tasks, jobs, dry)
    if dry:
        return failed
    for algo, seed, t in pending:
        d = t["dir"]
        scores = {}
        for name, z, vn in _candidates(t):
            f = d / "select" / name / "summary.json"
            if f.is_file():
                scores[name] = (json.loads(f.read_text())["mean"][sel["metric"]], z, vn)
        if len(scores) < len(_candidates(t)):
            continue  # a validation failed: chosen on the next run
        best = max(scores, key=lambda k: scores[k][0])
        _, z, vn = scores[best]
        choice = {
            "checkpoint": best,
            "metric": sel["metric"],
            "level": sel["level"],
            "validation_seeds": [sel["seed"], sel["seed"] + sel["episodes"] - 1],
            "scores": {k: v[0] for k, v in scores.items()},
        }
        _stage(d, z, vn, d / "selected", {"selected": choice})
        (d / "selected.json").write_text(json.dumps(choice, indent=2))
        print(f"  {algo} seed {seed}: {best} ({sel['metric']} {scores[best][0]:.3f} on validation)")
    return failed


def _evals(c: dict) -> list[tuple[str, str, str, int]]:
    """(level, name, policy spec, episodes) of every evaluation."""
    ev = c["evaluate"]
    # the trained policies first: they are what the campaign is for, and their episodes are the
    # longest (a baseline's rows can come from a run beside the training, on a core it leaves idle)
    policies = [(f"{a}_seed_{s}", str(policy_of(c, t))) for a, s, t in _runs(c) if t["evaluate"]]
    policies += [(b, b) for b in ev["baselines"]]
    # the most accurate level first: its episodes are the long ones, and two workers finish
    # together when the long tasks start first
    levels = list(ev["levels"].items())[::-1]
    return [(level, name, spec, n) for level, n in levels for name, spec in policies]


def _eval_cmd(
    c: dict, level: str, spec: str, n: int, out: Path, seed: int | None = None, own: bool = True
) -> list[str]:
    """agents/evaluate.py's command; ``own``: with ``[evaluate] env_kwargs`` (the evaluations',
    not the selection's)."""
    seed = c["evaluate"]["seed"] if seed is None else seed
    extra = c["evaluate"]["env_kwargs"] if own else {}
    cmd = [sys.executable, "-W", "ignore", "-m", "agents.evaluate", "--policy", spec]
    cmd += ["--episodes", str(n), "--seed", str(seed), "--out", str(out)]
    cmd += ["--env", c["env_id"]]
    for k, v in {**c["env_kwargs"], **extra, "fidelity": level}.items():
        cmd += ["--env-kw", f"{k}={json.dumps(v)}"]
    return cmd


def _parallel(jobs: int, tasks: list[tuple[str, list[str], Path]]) -> list[str]:
    """Run (label, command, log) tasks ``jobs`` at a time; returns the labels that failed."""
    failed = []

    def one(task):
        label, cmd, log = task
        print(f"  start {label}", flush=True)
        rc, wall = _run_logged(cmd, log, 1 if jobs > 1 else None)
        state = "done" if rc == 0 else f"FAILED (exit {rc}, see {log})"
        print(f"  {state}: {label} in {wall / 60:.1f} min", flush=True)
        if rc != 0:
            failed.append(label)

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        list(pool.map(one, tasks))
    return failed


def _launch(tasks: list[tuple[str, list[str], Path]], jobs: int, dry: bool) -> list[str]:
    """Run the tasks (``_parallel``), or with ``dry`` print their commands; returns failures."""
    if dry:
        for label, cmd, _ in tasks:
            print(f"  would run {label}: {' '.join(cmd)}")
        return []
    for _, _, log in tasks:
        log.parent.mkdir(parents=True, exist_ok=True)
    return _parallel(jobs, tasks)


def train_stage(c: dict, jobs: int, dry: bool, entries: list[dict] | None = None) -> list[str]:
    tasks = []
    for algo, seed, t in _runs(c, entries):
        d = t["dir"]
        if (d / "meta.json").is_file():
            print(f"  kept {algo} seed {seed} ({d}/meta.json exists)")
            continue
        if d.exists() and not dry:
            print(f"  {algo} seed {seed}: unfinished run in {d}, starting it again")
            shutil.rmtree(d)
        tasks.append(
            (f"train {algo} seed {seed}", _train_cmd(c, t, seed), d.parent / f"{d.name}.log")
        )
    return _launch(tasks, jobs, dry)


def evaluate_stage(c: dict, jobs: int, dry: bool) -> list[str]:
    tasks, joins = [], []
    root = Path(c["out"]) / "eval"
    for level, name, spec, n in _evals(c):
        d = root / level / name
        if _summary(d, spec, n) is not None:
            print(f"  kept {level}/{name}")
            continue
        if (d / "summary.json").is_file():
            print(f"  {level}/{name}: another model or episode count than asked, evaluating again")
        if spec not in BASELINES and not Path(spec).is_file():
            print(f"  skip {level}/{name}: no model {spec} (its training failed?)")
            continue
        parts = eval_parts(c["evaluate"], n)
        if len(parts) == 1:
            label, log = f"evaluate {name} at {level}", root / level / f"{name}.log"
            tasks.append((label, _eval_cmd(c, level, spec, n, d), log))
            continue
        for s, k in parts:
            part = d / "parts" / f"seed_{s}"
            if _summary(part, spec, k, s) is not None:
                print(f"  kept {level}/{name} episodes {s}..{s + k - 1}")
                continue
            label = f"evaluate {name} at {level}, episodes {s}..{s + k - 1}"
            log = root / level / f"{name}_{s}.log"
            tasks.append((label, _eval_cmd(c, level, spec, k, part, s), log))
        joins.append((d, spec, parts))
    failed = _launch(tasks, jobs, dry)
    for d, spec, parts in [] if dry else joins:
        if not _join_parts(d, spec, parts):
            print(f"  {d}: a part is missing, not joined (running the command again retries it)")
    return failed


def _cell(values: list[float], key: str) -> str:
    _, scale, fmt = METRICS[key]
    v = np.asarray(values, float) * scale
    if len(v) == 1:
        return fmt.format(v[0])
    return f"{fmt.format(v.mean())} ± {fmt.format(v.std())}"


def _summary(d: Path, spec: str, n: int, seed: int | None = None) -> dict | None:
    """The evaluation in ``d`` if it is of the policy ``spec`` over ``n`` episodes (from reset
    seed ``seed``, if given) -- a table never mixes in an evaluation of another checkpoint or
    episode count -- else None."""
    f = d / "summary.json"
    if not f.is_file():
        return None
    done = json.loads(f.read_text())
    if seed is not None and done.get("seed") != seed:
        return None
    return done if done.get("policy") == spec and done.get("episodes") == n else None


def eval_parts(ev: dict, n: int) -> list[tuple[int, int]]:
    """(first reset seed, episodes) of the tasks an evaluation of ``n`` episodes runs as: one
    task, or with ``[evaluate] chunk`` tasks of at most ``chunk`` episodes, so that one long
    evaluation (a trained policy at `balanced`: 1-4 min an episode) keeps every worker busy."""
    chunk = ev.get("chunk") or n
    return [(ev["seed"] + i, min(chunk, n - i)) for i in range(0, n, chunk)]


def _join_parts(d: Path, spec: str, parts: list[tuple[int, int]]) -> bool:
    """Write ``d/summary.json`` (and ``table.md``) from the finished parts in ``d/parts/``;
    False if a part is missing."""
    from agents.evaluate import episode_table, join_summaries

    done = [_summary(d / "parts" / f"seed_{s}", spec, k, s) for s, k in parts]
    if any(p is None for p in done):
        return False
    joined = join_summaries([p for p in done if p is not None])
    (d / "summary.json").write_text(json.dumps(joined, indent=2))
    (d / "table.md").write_text(episode_table(joined["per_episode"]) + "\n")
    return True


def report(c: dict) -> dict:
    """Collect the evaluations into results.json / results.md (module docstring)."""
    out = Path(c["out"])
    results: dict = {"levels": {}, "runs": {}}
    lines = [
        "# Campaign results",
        "",
        f"Config: env {c['env_id']}, env keywords {json.dumps(c['env_kwargs'])}"
        + (
            f", the training envs' own {json.dumps(c['train_env_kwargs'])}"
            if c["train_env_kwargs"]
            else ""
        )
        + (
            f", the evaluations' own {json.dumps(c['evaluate']['env_kwargs'])}."
            if c["evaluate"]["env_kwargs"]
            else "."
        ),
        "Baselines: mean ± std over episodes; trained: mean ± std over training seeds of each "
        "seed's episode mean.",
    ]
    for algo, seed, t in _runs(c):
        meta = t["dir"] / "meta.json"
        if meta.is_file():
            m = json.loads(meta.read_text())
            results["runs"][f"{algo}_seed_{seed}"] = {
                k: m.get(k) for k in ("timesteps", "wall_time_s", "env_steps_per_s", "seed")
            }
            chosen = t["dir"] / "selected.json"
            if "select" in c and chosen.is_file():
                results["runs"][f"{algo}_seed_{seed}"]["selected"] = json.loads(chosen.read_text())
    picked = {k: r["selected"] for k, r in results["runs"].items() if "selected" in r}
    if picked:
        sel = c["select"]
        lines.append(
            f"Each run's policy is its checkpoint with the best mean {sel['metric']} over "
            f"{sel['episodes']} validation episodes (seeds {sel['seed']}..) at `{sel['level']}`: "
            + ", ".join(f"{k} {v['checkpoint']}" for k, v in picked.items())
            + "."
        )
    for level, n in c["evaluate"]["levels"].items():
        rows: dict = {}
        for b in c["evaluate"]["baselines"]:
            done = _summary(out / "eval" / level / b, b, n)
            if done is not None:
                per = done["per_episode"]
                rows[b] = {k: [r[k] for r in per if k in r] for k in METRICS}
        for t in c["train"]:
            seeds = []
            for s in t["seeds"] if t["evaluate"] else ():
                run = _run(c, t, s)
                done = _summary(
                    out / "eval" / level / f"{t['name']}_seed_{s}", str(policy_of(c, run)), n
                )
                if done is not None:
                    seeds.append(done["mean"])
            if seeds:
                rows[f"{t['name']} ({len(seeds)} seeds)"] = {
                    k: [m[k] for m in seeds if k in m] for k in METRICS
                }
        results["levels"][level] = {
            name: {
                k: {"mean": float(np.mean(v)), "std": float(np.std(v)), "n": len(v)}
                for k, v in r.items()
                if v
            }
            for name, r in rows.items()
        }
        lines += ["", f"## Level `{level}`, {n} episodes (seeds {c['evaluate']['seed']}..)", ""]
        lines.append("| policy | " + " | ".join(h for h, _, _ in METRICS.values()) + " |")
        lines.append("|---" * (len(METRICS) + 1) + "|")
        for name, r in rows.items():
            cells = [_cell(r[k], k) if r.get(k) else "" for k in METRICS]
            lines.append(f"| {name} | " + " | ".join(cells) + " |")
    (out / "results.json").write_text(json.dumps(results, indent=2))
    (out / "results.md").write_text("\n".join(lines) + "\n")
    learning_curves(c, out / "learning_curves.png")
    return results


def learning_curves(c: dict, path: Path) -> None:
    """Evaluation return against env steps per algorithm: mean over seeds, min-max band; the
    reference policy's return (agents/train.py's reference.json) as a dashed line."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4))
    refs = []
    for t in c["train"]:
        curves = []
        for s in t["seeds"]:
            d = _run(c, t, s)["dir"]
            f = d / "eval" / "evaluations.npz"
            if f.is_file():
                z = np.load(f)
                curves.append((z["timesteps"], z["results"].mean(axis=1)))
            if (d / "reference.json").is_file():
                refs.append(json.loads((d / "reference.json").read_text())["mean_reward"])
        if not curves:
            continue
        n = min(len(x) for x, _ in curves)
        x = curves[0][0][:n]
        y = np.array([r[:n] for _, r in curves])
        stage = f", from {t['init']}: steps added" if "init" in t else ""
        label = f"{t['name']} ({t['algo'].upper()}, {len(curves)} seeds{stage})"
        (line,) = ax.plot(x, y.mean(0), label=label)
        ax.fill_between(x, y.min(0), y.max(0), color=line.get_color(), alpha=0.25)
    if refs:
        ax.axhline(
            float(np.mean(refs)), color="k", ls="--", label="reference policy (circle or scrub)"
        )
    ax.set_xlabel("env steps")
    ax.set_ylabel("evaluation return (mean of episodes)")
    # the env keywords wrapped: on one line they ran past the figure's edge
    title = textwrap.wrap(f"{c['env_id']}, {json.dumps(c['env_kwargs'])}", 95)
    ax.set_title("\n".join(title), fontsize=9)
    ax.legend(loc="best")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def best_run(c: dict, results: dict) -> tuple[str, int]:
    """(entry name, seed) to ship: the evaluated [[train]] entry with the highest mean coverage
    over its seeds at the most accurate evaluated level (the last of ``[evaluate] levels``), then
    its seed with the highest coverage there among those that never spent time above the force
    limit (the task's rule: a model shipped as the env's trained policy keeps it), or the highest
    coverage if every seed did."""
    level, n = list(c["evaluate"]["levels"].items())[-1]
    root = Path(c["out"]) / "eval" / level
    best = None
    for t in c["train"]:
        covs, within = {}, {}
        for s in t["seeds"] if t["evaluate"] else ():
            run = _run(c, t, s)
            done = _summary(root / f"{t['name']}_seed_{s}", str(policy_of(c, run)), n)
            if done is not None:
                covs[s] = done["mean"]["coverage"]
                within[s] = done["mean"]["time_above_force_limit"] == 0.0
        if covs:
            mean = float(np.mean(list(covs.values())))
            seed = max(covs, key=lambda k: (within[k], covs[k]))
            if best is None or mean > best[0]:
                best = (mean, t["name"], seed)
    if best is None:
        raise RuntimeError(f"no trained policy was evaluated at {level}: nothing to ship")
    return best[1], best[2]


def _started_from(meta: dict) -> str:
    """The card's words on the model a run went on from (``init_model``), if any."""
    init = meta.get("init_model")
    if not init:
        return ""
    from agents.evaluate import companions

    first = companions(init)[0]
    if not first.is_file():
        return f", going on from `{init}`"
    m = json.loads(first.read_text())
    chosen = m.get("selected", {}).get("checkpoint", "its final model")
    return (
        f", going on from `{init}` ({chosen} of {m['timesteps']} env steps with the training envs' "
        f"own {json.dumps(m.get('train_env_kwargs', {}))}, {m['wall_time_s'] / 60:.1f} min)"
    )


def compact_model(src: str | Path, dst: str | Path) -> None:
    """Copy the stable-baselines3 model zip ``src`` to ``dst`` without its optimisers' state (the
    Adam moment estimates; their learning rates and settings stay): the networks and everything
    else byte for byte, so the policy acts the same and loads as before; a training continued
    from the copy restarts the moments.  A SAC model's moments (actor and both critics) were 54 %
    of its 7.6 MB zip, past the few MB a shipped model may take (issue 30, item 4)."""
    import io
    import zipfile

    import torch

    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w", zipfile.ZIP_DEFLATED) as zout:
        for info in zin.infolist():
            data = zin.read(info.filename)
            if info.filename.endswith("optimizer.pth"):
                state = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
                state["state"] = {}
                buf = io.BytesIO()
                torch.save(state, buf)
                data = buf.getvalue()
            zout.writestr(info, data)  # the entry's own date and flags: the copy is reproducible


def ship(c: dict, results: dict, dest: str | Path = "agents/models") -> Path:
    """Copy the best run's model (:func:`best_run`; :func:`compact_model`) to
    ``DEST/<scene>_<algo>.zip`` with its ``.meta.json`` and ``.vecnormalize.pkl``
    (agents/evaluate.py finds them beside it), and write its card section into
    ``DEST/README.md``: command, commit, seeds, wall time and the evaluation table at every
    level."""
    entry, seed = best_run(c, results)
    t = _run(c, _entry(c, entry), seed)
    algo, run = t["algo"], t["dir"]
    scene = c["env_id"].split("/")[-1].split("-")[0]
    stem = "".join("_" + ch.lower() if ch.isupper() else ch for ch in scene).lstrip("_")
    dest = Path(dest)
    dest.mkdir(parents=True, exist_ok=True)
    name = f"{stem}_{algo}"
    from agents.evaluate import commit_id, companions

    model = policy_of(c, t)
    meta_path, vn_path = companions(model)
    compact_model(model, dest / f"{name}.zip")
    meta = json.loads(meta_path.read_text())
    meta["shipped_from"] = {"run": str(run), "model": str(model), "commit": commit_id()}
    (dest / f"{name}.meta.json").write_text(json.dumps(meta, indent=2))
    if vn_path.is_file():
        shutil.copyfile(vn_path, dest / f"{name}.vecnormalize.pkl")
    chosen = meta.get("selected")
    which = (
        f"its checkpoint `{chosen['checkpoint']}`, chosen by mean {chosen['metric']} on "
        f"validation seeds {chosen['validation_seeds'][0]}-{chosen['validation_seeds'][1]} at "
        f"`{chosen['level']}`"
        if chosen
        else "its final model"
    )
    table = (Path(c["out"]) / "results.md").read_text().split("\n", 4)[-1]
    card = [
        f"## `{name}.zip`",
        "",
        f"{algo.upper()} seed {seed} of the campaign's entry `{entry}` (the evaluated entry with "
        f"the best mean coverage at `{list(c['evaluate']['levels'])[-1]}`, then its best "
        "covering seed of those that kept the force limit there), "
        f"trained with the code of commit `{meta.get('commit', 'unknown')}`; {which}.",
        f"Trained {meta['timesteps']} env steps on {c['env_id']} with "
        f"{json.dumps(meta['env_kwargs'])} (the training envs' own "
        f"{json.dumps(meta.get('train_env_kwargs', {}))}), {meta['n_envs']} envs, in "
        f"{meta['wall_time_s'] / 60:.1f} min ({meta['env_steps_per_s']:.0f} env steps/s)"
        + _started_from(meta)
        + ".",
        "",
        "Made by `python -m agents.campaign --config configs/agents/campaign.toml --ship`.",
        f"Run it: `python -m agents.evaluate --policy {dest}/{name}.zip --episodes 20`.",
        "",
        "The campaign's table (all algorithms and seeds, not this model alone):",
        "",
        table.strip(),
        "",
    ]
    (dest / f"{name}.md").write_text("\n".join(card))
    cards = sorted(p.read_text() for p in dest.glob("*.md") if p.name != "README.md")
    (dest / "README.md").write_text(
        "# Shipped policies\n\nEach model below sits beside its `.meta.json` (algorithm, env "
        "settings, training run) and `.vecnormalize.pkl` (observation statistics), which "
        "`agents/evaluate.py` loads with it.  Remade by the command in its card.\n\n"
        + "\n".join(cards)
    )
    print(f"shipped {model} as {dest}/{name}.zip (card {dest}/{name}.md)")
    return dest / f"{name}.zip"


def campaign(
    config: str | Path,
    jobs: int | None = None,
    dry_run: bool = False,
    ship_to: str | None = None,
    report_only: bool = False,
) -> dict | None:
    c = load_campaign(config)
    jobs = c["jobs"] if jobs is None else _int("--jobs", jobs)
    t0 = time.perf_counter()
    failed = []
    # train and select each wave of entries (an entry that starts from another's policy, init,
    # after that one's selection), then evaluate
    waves = _waves(c)
    stages = [
        (f"{name}{f' (stage {k + 1} of {len(waves)})' if len(waves) > 1 else ''}", stage, wave)
        for k, wave in enumerate(waves)
        for name, stage in (("train", train_stage), ("select", select_stage))
    ]
    stages.append(("evaluate", lambda c, jobs, dry, _: evaluate_stage(c, jobs, dry), None))
    for name, stage, wave in [] if report_only else stages:
        t = time.perf_counter()
        print(f"[{name}] {jobs} job(s) at a time", flush=True)
        failed += stage(c, jobs, dry_run, wave)
        print(f"[{name}] {(time.perf_counter() - t) / 60:.1f} min", flush=True)
    if dry_run:
        return None
    results = report(c)
    out = Path(c["out"])
    print((out / "results.md").read_text())
    print(f"campaign wall time {(time.perf_counter() - t0) / 60:.1f} min; {out}/results.md")
    if failed:
        raise UserError(
            f"{len(failed)} task(s) failed: {', '.join(failed)}; the table holds the rest, and "
            "running the command again retries them"
        )
    if ship_to is not None:
        ship(c, results, ship_to)
    return results


def build_parser() -> OneLineParser:
    p = OneLineParser(prog="python -m agents.campaign", description=__doc__.split("\n")[0])
    p.add_argument("--config", required=True, help="campaign TOML (configs/agents/campaign.toml)")
    p.add_argument("--jobs", type=int, default=None, help="tasks at a time (default: the config's)")
    add_flag(p, "--dry-run", "print what would run, run nothing")
    add_flag(
        p,
        "--report-only",
        "tabulate (and --ship) what is evaluated so far, run nothing (a row without its "
        "evaluation at a level is left out there)",
    )
    p.add_argument(
        "--ship",
        nargs="?",
        const="agents/models",
        default=None,
        metavar="DIR",
        help="copy the best model, its statistics and card to DIR (default agents/models)",
    )
    return p


def _main(argv) -> int:
    args = build_parser().parse_args(argv)
    campaign(args.config, args.jobs, args.dry_run, args.ship, args.report_only)
    return 0


def main(argv=None) -> int:
    return run_main(_main, argv, prog="python -m agents.campaign")


if __name__ == "__main__":
    sys.exit(main())
