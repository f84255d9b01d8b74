"""``bench env`` and ``bench random``: the CLI wiring of the two env benchmarks, importing
gymnasium only when one of them runs (the measurements: ``brush_env.bench.env_steps``, env steps
per second, and ``brush_env.bench.random_actions``, random actions at several step limits).
"""

from __future__ import annotations

from ..user_errors import add_flag


def bench_env_target(args) -> int:
    """Run the env benchmark (brush_env.bench.env_steps) with the parsed options."""
    from brush_env.bench import env_steps as bench_env  # gymnasium only when it runs

    return bench_env.run(args)


def add_arguments(p) -> None:
    """The env benchmark's options (brush_env.bench.env_steps)."""
    from brush_env.bench import env_steps as bench_env

    add_flag(p, "--json", "one JSON object per row on stdout")
    bench_env.add_arguments(p)


def bench_random_target(args) -> int:
    """Run the random-action env benchmark (brush_env.bench.random_actions)."""
    from brush_env.bench import random_actions as bench_random

    return bench_random.run(args)


def add_random_arguments(p) -> None:
    """The random-action benchmark's options (brush_env.bench.random_actions)."""
    from brush_env.bench import random_actions as bench_random

    add_flag(p, "--json", "one JSON object per row on stdout")
    bench_random.add_arguments(p)
