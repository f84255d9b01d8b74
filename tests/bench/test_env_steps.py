"""``brush-env bench env``: rows for one env and a vector of envs; argument errors."""

import argparse
import json
import time

import pytest

from brush_env.bench.env_steps import add_arguments, bench_env, run
from brush_env.engine import Simulator

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
    "table_fallbacks_per_step",
    "brush",
    "n_bristles",
    "bodies_per_bristle",
    "model",
    "engine_dt",
    "max_substep",
    "frame_skip",
    "control_hz",
    "policy",
}


def test_bench_env_rows():
    rows = bench_env({"steps": 12, "n_envs": [1, 2], "brush": "tiny_env"})
    assert [r["mode"] for r in rows] == ["single", "vector"]
    for r in rows:
        assert set(r) == KEYS and r["steps_per_s"] > 0 and r["n_bristles"] == 4
        assert r["control_hz"] == pytest.approx(1.0 / (r["engine_dt"] * r["frame_skip"]))
    assert rows[1]["steps"] == 24  # 12 per env: each env runs the same stretch as the single one


def test_bench_env_rates_are_what_ran_over_its_wall_time(monkeypatch):
    """The single-env row's rates, against the engine steps counted here and a clock outside:
    real-time factor = simulated seconds / wall seconds, engine steps/s = engine steps / wall."""
    calls = []
    follow = Simulator.follow

    def counting(self, *args, **kwargs):
        run = follow(self, *args, **kwargs)
        calls.extend([self.settings.dt] * run.done)
        return run

    monkeypatch.setattr(Simulator, "follow", counting)
    t0 = time.perf_counter()
    # at "coarse" (the full chain) an env step's engine steps are one Simulator.follow; "fast"
    # rolls an env step out in prb_rollout's compiled call
    args = {"steps": 15, "n_envs": [1], "brush": "tiny_env", "frame_skip": 4, "fidelity": "coarse"}
    (row,) = bench_env(args)
    outside = time.perf_counter() - t0
    timed = calls[row["frame_skip"] :]  # the first control step is the cold start, not timed
    assert len(timed) == row["steps"] * row["frame_skip"] == 60  # no episode ended early here
    assert 0.0 < row["wall_s"] < outside - row["cold_start_s"]
    assert row["real_time_factor"] * row["wall_s"] == pytest.approx(sum(timed), rel=1e-12)
    assert row["engine_steps_per_s"] * row["wall_s"] == pytest.approx(len(timed), rel=1e-12)
    assert row["steps_per_s"] * row["wall_s"] == pytest.approx(row["steps"], rel=1e-12)


def test_bench_env_random_and_zero_policies_restart_episodes_with_the_next_seed(monkeypatch):
    """``--policy random`` / ``zero``: episode k is reset with seed k after ``episode_steps``
    (12 steps of 5-step episodes: seeds 0 (cold start), 0, 1, 2); a vector of envs runs too."""
    import gymnasium as gym

    seeds = []
    reset = gym.Wrapper.reset

    def spy(self, *, seed=None, options=None):
        if isinstance(self, gym.wrappers.TimeLimit):
            seeds.append(seed)
        return reset(self, seed=seed, options=options)

    monkeypatch.setattr(gym.Wrapper, "reset", spy)
    for policy in ("random", "zero"):
        seeds.clear()
        args = {"steps": 12, "n_envs": [1], "brush": "tiny_env", "policy": policy}
        (row,) = bench_env({**args, "episode_steps": 5})
        assert row["policy"] == policy and row["steps"] == 12
        assert seeds == [0, 0, 1, 2]
    (row,) = bench_env({"steps": 3, "n_envs": [2], "brush": "tiny_env", "policy": "random"})
    assert row["mode"] == "vector" and row["steps"] == 6


def test_bench_env_counts_the_tip_tables_fallbacks_of_every_timed_episode(monkeypatch):
    """At ``fast`` (the tip table) the single row's fallbacks per step are the
    ``solver_info()["table_fallbacks"]`` of each timed episode (counted since its reset) summed,
    over the steps; not the cold start's; nan for the chain (``coarse``) and a vector row."""
    import gymnasium as gym

    seen = []
    reset = gym.Wrapper.reset

    def spy(self, *, seed=None, options=None):
        if isinstance(self, gym.wrappers.TimeLimit) and hasattr(self.unwrapped, "sim"):
            sim = self.unwrapped.sim
            if sim.state is not None:
                seen.append(sim.bristles.solver_info().get("table_fallbacks", 0))
        return reset(self, seed=seed, options=options)

    monkeypatch.setattr(gym.Wrapper, "reset", spy)
    last = []
    step = gym.Wrapper.step

    def step_spy(self, action):
        out = step(self, action)
        if isinstance(self, gym.wrappers.TimeLimit):
            last[:] = [self.unwrapped.sim.bristles.solver_info().get("table_fallbacks", 0)]
        return out

    monkeypatch.setattr(gym.Wrapper, "step", step_spy)
    args = {"steps": 40, "n_envs": [1], "policy": "random", "episode_steps": 20}
    (row,) = bench_env({**args, "fidelity": "fast"})
    # resets: the cold start's second (after its one step), then after each timed episode but
    # the last, whose count is read at the end
    timed = seen[1:] + last
    assert len(timed) == 2
    assert sum(timed) > 0  # the random brush touches the plate within 20 steps
    assert row["table_fallbacks_per_step"] == sum(timed) / 40
    (row,) = bench_env({**args, "steps": 4, "brush": "tiny_env", "fidelity": "coarse"})
    assert row["table_fallbacks_per_step"] != row["table_fallbacks_per_step"]  # nan


def test_bench_env_runs_tooth_row_with_its_scrub(monkeypatch):
    """``--env tooth_row``: ToothRow-v0 with its own config, the reference policy its scrub."""
    from brush_env.envs import reference

    made = []
    init = reference.ScrubReference.__init__

    def spy(self, *args, **kwargs):
        made.append(type(self).__name__)
        init(self, *args, **kwargs)

    monkeypatch.setattr(reference.ScrubReference, "__init__", spy)
    (row,) = bench_env({"steps": 3, "n_envs": [1], "env": "tooth_row", "fidelity": "reduced"})
    assert made == ["ScrubReference"] and row["steps"] == 3 and row["model"] == "prb"


def test_bench_env_rejects_an_unknown_policy():
    with pytest.raises(ValueError, match=r"policy = 'greedy' is not allowed: .*'random'"):
        bench_env({"steps": 2, "n_envs": [1], "brush": "tiny_env", "policy": "greedy"})
    with pytest.raises(ValueError, match=r"env = 'moon' is not allowed: .*'tooth_row'"):
        bench_env({"steps": 2, "n_envs": [1], "brush": "tiny_env", "env": "moon"})


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
