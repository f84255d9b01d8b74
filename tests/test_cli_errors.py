"""User mistakes through the real command lines: one stderr line, exit code 2, no traceback, and
nothing written (issue: the first hour of a new user)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PPO_TYPO = """
algo = "ppo"
[env]
config = "flat_plate"
[hyperparameters]
n_step = 64
"""


MISTAKES = {
    "missing brush file": (
        ["-m", "brush_env.cli", "reference", "--brush", "nonexistent.toml", "--out", "OUT"],
        "does not exist",
    ),
    "misspelled brush name": (
        ["-m", "brush_env.cli", "reference", "--brush", "defualt", "--out", "OUT"],
        "did you mean default",
    ),
    "unknown subcommand": (["-m", "brush_env.cli", "referense"], "invalid choice"),
    "missing agent config": (
        [
            "-m",
            "agents.train",
            "--algo",
            "ppo",
            "--config",
            "missing.toml",
            "--timesteps",
            "10",
            "--out",
            "OUT",
        ],
        "no such file",
    ),
    "misspelled hyperparameter": (
        [
            "-m",
            "agents.train",
            "--algo",
            "ppo",
            "--config",
            "ppo.toml",
            "--timesteps",
            "10",
            "--n-envs",
            "2",
            "--out",
            "OUT",
        ],
        "did you mean n_steps",
    ),
    "env key typo": (
        [
            "-m",
            "agents.train",
            "--algo",
            "ppo",
            "--config",
            str(ROOT / "configs/agents/ppo.toml"),
            "--timesteps",
            "10",
            "--n-envs",
            "2",
            "--env-kw",
            "max_episode_step=5",
            "--out",
            "OUT",
        ],
        "did you mean max_episode_steps",
    ),
    "missing policy": (
        ["-m", "agents.evaluate", "--policy", "missing.zip", "--episodes", "1", "--out", "OUT"],
        "not 'reference', 'random'",
    ),
}


@pytest.mark.parametrize("name", list(MISTAKES))
def test_user_mistake_gives_one_line_and_exit_code_2(name, tmp_path):
    args, expected = MISTAKES[name]
    (tmp_path / "ppo.toml").write_text(PPO_TYPO)
    args = [a.replace("OUT", str(tmp_path / "out")) for a in args]
    r = subprocess.run(
        [sys.executable, *args],
        cwd=tmp_path,
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
    )
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert r.returncode == 2, r.stderr
    assert len(lines) == 1, r.stderr
    assert "Traceback" not in r.stderr and expected in lines[0], lines[0]
    assert not (tmp_path / "out").exists()  # nothing written before the inputs are valid


def test_debug_shows_the_traceback(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "brush_env.cli", "reference", "--brush", "defualt", "--debug"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode != 0 and "Traceback" in r.stderr
