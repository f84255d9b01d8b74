"""agents/evaluate.py writes its table, JSON, plots and video."""

import json

import pytest

from agents.evaluate import evaluate, main, parse_env_kw

SHORT = {"brush": "tiny_env", "max_episode_steps": 12}


def test_evaluate_reference_writes_every_output(tmp_path):
    evaluate("reference", 2, tmp_path, env_kwargs=SHORT, video=True, quiet=True)
    for name in ("summary.json", "table.md", "forces.png", "coverage.png", "episode_000.gif"):
        assert (tmp_path / name).stat().st_size > 0, name
    data = json.loads((tmp_path / "summary.json").read_text())
    assert data["episodes"] == 2 and len(data["per_episode"]) == 2
    ep = data["per_episode"][0]
    for key in (
        "return",
        "coverage",
        "steps",
        "termination",
        "time_above_force_limit",
        "peak_normal_force",
        "peak_tip_force",
        "reward_coverage",
        "reward_total_force",
        "reward_tip_force",
        "reward_termination",
    ):
        assert key in ep
    terms = sum(ep[f"reward_{k}"] for k in ("coverage", "total_force", "tip_force", "termination"))
    assert ep["return"] == pytest.approx(terms)
    assert data["mean"]["return"] == pytest.approx(
        sum(e["return"] for e in data["per_episode"]) / 2
    )
    assert data["env_settings"]["brush"] == "tiny_env"
    assert [e["seed"] for e in data["per_episode"]] == [0, 1]


def test_evaluate_cli_random(tmp_path, capsys):
    assert (
        main(
            [
                "--policy",
                "random",
                "--episodes",
                "1",
                "--out",
                str(tmp_path),
                "--env-kw",
                'brush="tiny_env"',
                "--env-kw",
                "max_episode_steps=5",
            ]
        )
        == 0
    )
    assert "| seed | return |" in capsys.readouterr().out
    assert (tmp_path / "table.md").exists()


def test_parse_env_kw_and_bad_policy(tmp_path):
    assert parse_env_kw(["a=3", "b=0.5", 'c="x"', "d=[1, 2]", "e=true", "f=tiny_env"]) == {
        "a": 3,
        "b": 0.5,
        "c": "x",
        "d": [1, 2],
        "e": True,
        "f": "tiny_env",
    }
    with pytest.raises(ValueError, match="KEY=VALUE"):
        parse_env_kw(["novalue"])
    with pytest.raises(ValueError, match="not one of reference, reference-static, reference-sl"):
        evaluate(str(tmp_path / "missing.zip"), 1, tmp_path / "out", env_kwargs=SHORT)
    assert not (tmp_path / "out").exists()  # nothing written before the inputs are valid


def test_reference_press_variants_by_name():
    """``--policy reference-static`` is the paper's press at rest, ``reference`` the shipped one."""
    import gymnasium as gym

    from agents.evaluate import load_policy

    env = gym.make("brush_env/FlatPlate-v0", **SHORT)
    try:
        press = {
            name: load_policy(name, env)[0].controller(0).press
            for name in ("reference", "reference-static", "reference-sliding")
        }
    finally:
        env.close()
    assert press == {
        "reference": "sliding",
        "reference-static": "static",
        "reference-sliding": "sliding",
    }


def test_random_episode_depends_on_its_own_seed_alone():
    """Random actions are reseeded per episode, so episode 101 is the same whether it follows
    episode 100 in one evaluation or starts an evaluation of its own (the campaign's chunks)."""
    import gymnasium as gym
    import numpy as np

    from agents.evaluate import load_policy, run_episode

    env = gym.make("brush_env/FlatPlate-v0", **SHORT)
    try:
        after, _ = load_policy("random", env, seed=100)
        run_episode(env, after, 100)
        _, s_after, _ = run_episode(env, after, 101)
        alone, _ = load_policy("random", env, seed=101)
        _, s_alone, _ = run_episode(env, alone, 101)
        _, s_other, _ = run_episode(env, alone, 102)
    finally:
        env.close()
    assert s_after["tcp_x"] == s_alone["tcp_x"] and s_after["tcp_y"] == s_alone["tcp_y"]
    n = min(len(s_after["tcp_x"]), len(s_other["tcp_x"]))
    assert not np.allclose(s_after["tcp_x"][1:n], s_other["tcp_x"][1:n])  # the actions matter
