"""``bench env``: env steps per second of the Gymnasium env, one env and vectorised (the
measurement itself lives in ``brush_env.envs.bench_env``, beside the env).
"""

from __future__ import annotations

from ..user_errors import add_flag


def bench_env_target(args) -> int:
    """Run the env benchmark (brush_env.envs.bench_env) with the parsed options."""
    from brush_env.envs import bench_env  # gymnasium only when the env is benchmarked

    return bench_env.run(args)


def add_arguments(p) -> None:
    """The env benchmark's options (they live beside the env, in brush_env.envs.bench_env)."""
    from brush_env.envs import bench_env

    add_flag(p, "--json", "one JSON object per row on stdout")
    bench_env.add_arguments(p)


def bench_random_target(args) -> int:
    """Run the random-action env benchmark (brush_env.envs.bench_random)."""
    from brush_env.envs import bench_random

    return bench_random.run(args)


def add_random_arguments(p) -> None:
    """The random-action benchmark's options (beside the env, in brush_env.envs.bench_random)."""
    from brush_env.envs import bench_random

    add_flag(p, "--json", "one JSON object per row on stdout")
    bench_random.add_arguments(p)
