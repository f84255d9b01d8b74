"""agents/side_by_side.py: the same episode as agents/evaluate.py, drawn for two policies."""

import pytest

from agents.evaluate import evaluate
from agents.side_by_side import episode, figure, main

KW = {"brush": "tiny_env", "max_episode_steps": 12}


def test_episode_is_evaluates_episode_and_the_figure_is_written(tmp_path):
    ref = episode("reference", 3, env_kwargs=KW)
    s = evaluate("reference", 1, tmp_path / "ev", seed=3, env_kwargs=KW, quiet=True)
    assert ref["metrics"]["coverage"] == s["per_episode"][0]["coverage"]
    assert ref["metrics"]["return"] == pytest.approx(s["per_episode"][0]["return"], abs=0)
    # the path has one point per step plus the start; the map's count is the coverage
    assert len(ref["series"]["tcp_x"]) == ref["metrics"]["steps"] + 1
    assert ref["cleaned"].mean() == pytest.approx(ref["metrics"]["coverage"])
    rnd = episode("random", 3, env_kwargs=KW)
    out = tmp_path / "sbs.png"
    figure([("reference", ref), ("random", rnd)], 3, out)
    assert out.stat().st_size > 10_000


def test_one_policy_is_refused_in_one_line(capsys):
    assert main(["--policy", "reference", "--out", "x.png"]) == 2
    err = capsys.readouterr().err.strip()
    assert "--policy given 1 time(s): give two or more" in err and "\n" not in err
