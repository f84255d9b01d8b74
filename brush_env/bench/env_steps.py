"""``brush-env bench env``: BrushEnv steps per second (FlatPlate-v0, or ToothRow-v0 with
``--env tooth_row``) under the env's reference policy (or random actions: ``--policy random``,
episode k seeded with k, ``--episode-steps`` long; or zero actions, the brush hovering:
``--policy zero``).

One env in this process, and a vector of envs (``gymnasium.vector.AsyncVectorEnv``, one process
per env).  The reference policy is the env's own (``brush_env.envs.reference``: FlatPlate-v0's
press-then-circle, ToothRow-v0's scrub), so the steps include contact once the brush is
pressed.  Episodes restart when they end (the time limit,
or a termination, counted in ``terminations``).  Cold start (env construction, first reset and
first step: numba's cache load or JIT compile) is timed apart and excluded from the rates.

Row fields: ``mode`` ("single" / "vector"), ``n_envs``, ``steps`` (env steps, all envs),
``wall_s``, ``steps_per_s`` (all envs together), ``steps_per_s_per_env``,
``real_time_factor`` (simulated seconds per wall-clock second, all envs together),
``engine_steps_per_s``, ``cold_start_s``, ``terminations``, ``table_fallbacks_per_step`` (level
``fast``, single env: the bristle-steps per env step that the tip table left to the reduced
chain's Newton, ``solver_info()["table_fallbacks"]``; nan otherwise), and the settings (``brush``,
``n_bristles``, ``bodies_per_bristle``, ``model``, ``engine_dt``, ``max_substep``, ``frame_skip``,
``control_hz``, ``policy``).

    brush-env bench env [--steps 300] [--n-envs 1 2] [--brush default] [--bodies N]
                        [--engine-dt 0.004] [--max-substep S] [--frame-skip 10]
                        [--fidelity LEVEL] [--policy reference|random|zero] [--episode-steps 100]
                        [--env flat_plate|tooth_row] [--json]

The engine runs the env config's fidelity level (``fast`` by default) or ``--fidelity``'s;
``--bodies`` and ``--max-substep``, where given, replace that level's settings (``engine_settings``
of ``gym.make``; the reduced models of ``fast`` and ``reduced`` take 2 bodies only).

Wiring: ``add_arguments(parser)`` adds the options (a parent parser may add its own ``--json``
first: ``add_arguments`` skips options the parser already has); ``run(args)`` prints and returns
0; ``bench_env(dict) -> list[dict]`` is the function behind both.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np

__all__ = ["bench_env", "add_arguments", "run"]

ENV_ID = "brush_env/FlatPlate-v0"
#: --env: the env ids, and the env config each runs by default
ENVS = {"flat_plate": "brush_env/FlatPlate-v0", "tooth_row": "brush_env/ToothRow-v0"}
DEFAULTS = {
    "steps": 300,
    "n_envs": [1, 2],
    "brush": "default",
    "bodies": None,
    "engine_dt": 0.004,
    "max_substep": None,
    "frame_skip": 10,
    "config": None,
    "env": "flat_plate",
    "fidelity": None,
    "policy": "reference",
    "episode_steps": 100,
}
POLICIES = ("reference", "random", "zero")


def _env_kwargs(a: dict) -> dict:
    a = {**a, "config": a["config"] or a["env"]}  # the env's own config unless one is named
    kw = {
        "config": a["config"],
        "brush": a["brush"],
        "engine_dt": a["engine_dt"],
        "frame_skip": a["frame_skip"],
    }
    if a.get("fidelity"):
        kw["fidelity"] = a["fidelity"]
    given = (("bodies_per_bristle", a.get("bodies")), ("max_substep", a.get("max_substep")))
    settings = {k: v for k, v in given if v is not None}
    if settings:  # they replace the level's
        kw["engine_settings"] = settings
    return kw


class _Reference:
    """Reference controllers for a batch of envs, planned per env at k = 0."""

    def __init__(self, env):
        from brush_env.envs.action import make_action_type
        from brush_env.envs.reference import CircleReference, ScrubReference

        u = env.unwrapped
        self.layout, self.horizon = u.layout, u.horizon
        # the env's own reference: FlatPlate-v0's circle, ToothRow-v0's scrub
        ref = (
            ScrubReference
            if getattr(u, "reference_motion", "circle") == "scrub"
            else CircleReference
        )
        self.make = lambda: ref(u.layout, make_action_type(u.config), u.dt, u.horizon)
        self.ctrl = []

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        obs = np.atleast_2d(obs)
        while len(self.ctrl) < len(obs):
            self.ctrl.append(self.make())
        k = self.layout.elapsed_steps(obs, self.horizon)
        p, R = self.layout.tcp_pose(obs)
        return np.stack([c.act(int(k[i]), p[i], R[i]) for i, c in enumerate(self.ctrl)])


class _Random:
    """Uniform random actions (``action_space.sample()``), the space seeded with each episode's
    seed at its reset (``_single``); a batch of them for a vector env."""

    def __init__(self, env):
        self.space = env.action_space
        self.lead = () if hasattr(env, "num_envs") else (1,)  # one env's action as a batch of 1

    def seed(self, seed: int) -> None:
        self.space.seed(seed)

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return self.space.sample().reshape(self.lead + self.space.shape)


class _Zero(_Random):
    """Zero actions: the brush stays where the reset put it, 1-2 mm above the plate (no contact:
    the env's cost around a brush that touches nothing)."""

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        return np.zeros(self.lead + self.space.shape, self.space.dtype)


def _policy(a: dict, env):
    return {"reference": _Reference, "random": _Random, "zero": _Zero}[a["policy"]](env)


def _single(a: dict) -> dict:
    import gymnasium as gym

    import brush_env  # noqa: F401

    t0 = time.perf_counter()
    env = gym.make(ENVS[a["env"]], **_env_kwargs(a))
    policy = _policy(a, env)
    obs, _ = env.reset(seed=0)
    obs, *_ = env.step(policy(obs)[0])
    cold = time.perf_counter() - t0
    # random actions: episode k (seed k, the action space seeded with k) ends after
    # episode_steps or at a termination; the reference: at its time limit or a termination
    random = isinstance(policy, _Random)
    terminations, seed, k = 0, 0, 0
    obs, _ = env.reset(seed=0)
    if random:
        policy.seed(0)
    fallbacks = 0  # the tip table's bristle-steps the chain took, summed before each reset
    t0 = time.perf_counter()
    for _ in range(a["steps"]):
        obs, _, term, trunc, _ = env.step(policy(obs)[0])
        k += 1
        if term or trunc or (random and k >= a["episode_steps"]):
            terminations += int(term)
            seed, k = seed + 1, 0
            fallbacks += _table_fallbacks(env)
            obs, _ = env.reset(seed=seed)
            if random:
                policy.seed(seed)
    wall = time.perf_counter() - t0
    fallbacks += _table_fallbacks(env)
    row = _row("single", 1, a["steps"], wall, cold, terminations, env.unwrapped, a)
    row["table_fallbacks_per_step"] = fallbacks / a["steps"] if _tabled(env) else float("nan")
    env.close()
    return row


def _tabled(env) -> bool:
    return "table_fallbacks" in env.unwrapped.sim.bristles.solver_info()


def _table_fallbacks(env) -> int:
    """The bristle-steps since reset that the tip table left to the chain's Newton (level
    ``fast``; 0 for another model)."""
    return int(env.unwrapped.sim.bristles.solver_info().get("table_fallbacks", 0))


def _vector(a: dict, n: int) -> dict:
    import gymnasium as gym

    import brush_env  # noqa: F401

    kw = _env_kwargs(a)
    t0 = time.perf_counter()
    env_id = ENVS[a["env"]]
    venv = gym.vector.AsyncVectorEnv([lambda: gym.make(env_id, **kw) for _ in range(n)])
    probe = gym.make(env_id, **kw)
    policy = _policy(a, probe if a["policy"] == "reference" else venv)
    obs, _ = venv.reset(seed=list(range(n)))
    obs, *_ = venv.step(policy(obs))
    cold = time.perf_counter() - t0
    obs, _ = venv.reset(seed=list(range(n)))
    steps = int(a["steps"])  # per env, as the single env: the same stretch of each episode
    terminations = 0
    t0 = time.perf_counter()
    for _ in range(steps):
        obs, _, term, trunc, _ = venv.step(policy(obs))
        terminations += int(np.sum(term))
    wall = time.perf_counter() - t0
    row = _row("vector", n, steps * n, wall, cold, terminations, probe.unwrapped, a)
    row["table_fallbacks_per_step"] = float("nan")  # in the worker processes
    venv.close()
    probe.close()
    return row


def _row(mode, n, steps, wall, cold, terminations, u, a) -> dict:
    return {
        "mode": mode,
        "n_envs": n,
        "steps": steps,
        "wall_s": wall,
        "steps_per_s": steps / wall,
        "steps_per_s_per_env": steps / wall / n,
        "real_time_factor": steps * u.dt / wall,
        "engine_steps_per_s": steps * u.config.frame_skip / wall,
        "cold_start_s": cold,
        "terminations": terminations,
        "brush": a["brush"],
        "n_bristles": u.n_bristles,
        "bodies_per_bristle": int(np.diff(u.sim.model.bstart).max()),
        "model": u.sim.settings.model,
        "engine_dt": u.config.engine_dt,
        "max_substep": u.sim.settings.max_substep,
        "frame_skip": u.config.frame_skip,
        "control_hz": 1.0 / u.dt,
        "policy": a["policy"],
    }


def bench_env(args: dict) -> list[dict]:
    """Run the benchmark; ``args`` keys as ``DEFAULTS`` (missing keys take the defaults).
    ``n_envs`` lists the vector sizes: 1 means the single in-process env."""
    a = {**DEFAULTS, **{k: v for k, v in args.items() if v is not None}}
    unknown = set(a) - set(DEFAULTS) - {"json", "command", "bench", "func", "which"}
    if unknown:
        raise ValueError(
            f"bench env: unknown argument(s) {sorted(unknown)} (known: {sorted(DEFAULTS)})"
        )
    if int(a["steps"]) < 1:
        raise ValueError(f"steps = {a['steps']!r} is out of range: must be >= 1")
    if a["env"] not in ENVS:
        raise ValueError(f"env = {a['env']!r} is not allowed: must be one of {tuple(ENVS)}")
    if a["policy"] not in POLICIES:
        raise ValueError(f"policy = {a['policy']!r} is not allowed: must be one of {POLICIES}")
    if int(a["episode_steps"]) < 1:
        raise ValueError(
            f"episode_steps = {a['episode_steps']!r} is out of range: must be >= 1 (env steps)"
        )
    rows = []
    for n in a["n_envs"]:
        if int(n) < 1:
            raise ValueError(f"n_envs = {n!r} is out of range: must be >= 1")
        rows.append(_single(a) if int(n) == 1 else _vector(a, int(n)))
    return rows


_OPTIONS = (
    (
        "--steps",
        dict(
            type=int,
            default=DEFAULTS["steps"],
            help="env steps per measurement and env (a vector runs n x steps); with --policy "
            "random use >= 3000 (30 episodes): episodes 0-9 are light ones and read ~2x faster",
        ),
    ),
    (
        "--n-envs",
        dict(
            type=int,
            nargs="+",
            default=DEFAULTS["n_envs"],
            help="vector sizes to measure; 1 = one in-process env",
        ),
    ),
    ("--brush", dict(default=DEFAULTS["brush"])),
    (
        "--bodies",
        dict(
            type=int,
            default=DEFAULTS["bodies"],
            help="bodies per bristle (0: the brush file's; default: the fidelity level's)",
        ),
    ),
    ("--engine-dt", dict(type=float, default=DEFAULTS["engine_dt"], help="engine step [s]")),
    (
        "--max-substep",
        dict(
            type=float,
            default=DEFAULTS["max_substep"],
            help="longest internal solver step [s] (engine_dt: no split; default: the level's)",
        ),
    ),
    ("--frame-skip", dict(type=int, default=DEFAULTS["frame_skip"])),
    (
        "--fidelity",
        dict(
            default=None,
            help="a fidelity level (configs/fidelity; default: the env config's, fast); "
            "--bodies and --max-substep, where given, replace its settings",
        ),
    ),
    (
        "--env",
        dict(
            default=DEFAULTS["env"],
            choices=tuple(ENVS),
            help="FlatPlate-v0 or ToothRow-v0 (the reference policy: its circle or its scrub)",
        ),
    ),
    (
        "--config",
        dict(default=DEFAULTS["config"], help="env config name or TOML path (default: --env's)"),
    ),
    (
        "--policy",
        dict(
            default=DEFAULTS["policy"],
            choices=POLICIES,
            help="the press-then-circle reference, uniform random actions, or zero actions (the "
            "brush hovering where it starts)",
        ),
    ),
    (
        "--episode-steps",
        dict(
            type=int,
            default=DEFAULTS["episode_steps"],
            help="random and zero policies, single env: env steps per episode (seed k for "
            "episode k)",
        ),
    ),
    ("--json", dict(action="store_true", help="one JSON object per row on stdout")),
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    """Add the options, skipping any the parser already has (e.g. a parent's ``--json``)."""
    have = {s for a in p._actions for s in a.option_strings}
    for flag, kw in _OPTIONS:
        if flag not in have:
            p.add_argument(flag, **kw)


def run(args: argparse.Namespace) -> int:
    """Print the table (or, with ``--json``, one JSON object per row, as ``bench engine``).
    Options missing from ``args`` take the defaults, so a parent parser need not add them all."""
    rows = bench_env({k: getattr(args, k, None) for k in DEFAULTS})
    if getattr(args, "json", False):
        for r in rows:
            print(json.dumps(r))
        return 0
    print(
        "| mode | envs | steps/s | steps/s/env | real-time x | engine steps/s | cold start s "
        "| terminations | table fallbacks / step |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['mode']} | {r['n_envs']} | {r['steps_per_s']:.1f} | "
            f"{r['steps_per_s_per_env']:.1f} | {r['real_time_factor']:.2f} | "
            f"{r['engine_steps_per_s']:.0f} | {r['cold_start_s']:.2f} | {r['terminations']} | "
            f"{r['table_fallbacks_per_step']:.3f} |"
        )
    r = rows[0]
    print(
        f"brush {r['brush']} ({r['n_bristles']} bristles x {r['bodies_per_bristle']} bodies), "
        f"engine dt {r['engine_dt']} s (solver steps <= {r['max_substep']} s) "
        f"x frame_skip {r['frame_skip']} = "
        f"{r['control_hz']:.4g} Hz control; model {r['model']}, policy {r['policy']}"
    )
    from .harness import machine_info

    print("machine: " + ", ".join(f"{k} {v}" for k, v in machine_info().items()))
    return 0


def main(argv=None) -> int:  # standalone: python -m brush_env.bench.env_steps
    p = argparse.ArgumentParser(
        prog="python -m brush_env.bench.env_steps", description=__doc__.split("\n")[0]
    )
    add_arguments(p)
    return run(p.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
