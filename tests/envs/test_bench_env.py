"""``brush-env bench env``: rows for one env and a vector of envs; argument errors."""

import argparse
import json

import pytest

from brush_env.envs.bench_env import add_arguments, bench_env, run

KEYS = {
    "mode",
    "n_envs",
    "steps",
    "wall_s",
    "steps_per_s",
    "steps_per_s_per_env",
    "real_time_factor",
    "engine_steps_per_s",
    "cold_start_s",
    "terminations",
    "brush",
    "n_bristles",
    "bodies_per_bristle",
    "engine_dt",
    "frame_skip",
    "control_hz",
}


def test_bench_env_rows():
    rows = bench_env({"steps": 12, "n_envs": [1, 2], "brush": "tiny_env"})
    assert [r["mode"] for r in rows] == ["single", "vector"]
    for r in rows:
        assert set(r) == KEYS and r["steps_per_s"] > 0 and r["n_bristles"] == 4
        assert r["real_time_factor"] == pytest.approx(r["steps_per_s"] * 0.04)
    assert rows[1]["steps"] == 24  # 12 per env: each env runs the same stretch as the single one


def test_bench_env_cli_json(capsys):
    p = argparse.ArgumentParser()
    add_arguments(p)
    assert (
        run(p.parse_args(["--steps", "5", "--n-envs", "1", "--brush", "tiny_env", "--json"])) == 0
    )
    rows = [json.loads(ln) for ln in capsys.readouterr().out.splitlines()]
    assert len(rows) == 1 and rows[0]["steps"] == 5 and rows[0]["frame_skip"] == 10


def test_bench_env_options_join_a_parent_parser():
    p = argparse.ArgumentParser()
    p.add_argument("--json", action="store_true")  # the parent's own --json
    add_arguments(p)
    args = p.parse_args(["--steps", "7"])
    assert args.steps == 7 and args.n_envs == [1, 2] and args.json is False


def test_bench_env_rejects_bad_arguments():
    with pytest.raises(ValueError, match="unknown argument"):
        bench_env({"stepz": 3})
    with pytest.raises(ValueError, match="n_envs = 0 is out of range"):
        bench_env({"steps": 3, "n_envs": [0], "brush": "tiny_env"})
