"""agents/train.py: a short PPO run trains, saves, reloads and evaluates; config errors."""

import json

import pytest

from agents.evaluate import evaluate
from agents.train import load_agent_config, train

PPO_TOML = """
algo = "ppo"
policy = "MlpPolicy"
[env]
id = "brush_env:brush_env/FlatPlate-v0"
config = "flat_plate"
[env.kwargs]
brush = "tiny_env"
max_episode_steps = 16
[normalize]
obs = true
reward = true
[hyperparameters]
n_steps = 64
batch_size = 32
n_epochs = 2
[hyperparameters.policy_kwargs]
net_arch = [32, 32]
[train]
eval_freq = 64
eval_episodes = 1
checkpoint_freq = 128
seed = 0
"""


def test_short_ppo_run_trains_saves_reloads_and_evaluates(tmp_path):
    cfg = tmp_path / "ppo.toml"
    cfg.write_text(PPO_TOML)
    out = tmp_path / "run"
    model = train("ppo", cfg, 192, 1, out, progress=False)
    assert model == out / "model.zip" and model.exists()
    for name in ("vecnormalize.pkl", "meta.json", "reference.json", "progress.csv",
                 "eval/evaluations.npz", "best/best_model.zip"):
        assert (out / name).exists(), name
    assert list((out / "checkpoints").glob("ppo_*_steps.zip"))
    assert list((out / "checkpoints").glob("ppo_vecnormalize_*_steps.pkl"))
    meta = json.loads((out / "meta.json").read_text())
    assert meta["algo"] == "ppo" and meta["env_kwargs"]["brush"] == "tiny_env"
    assert "eval/gap_to_reference" in (out / "progress.csv").read_text().splitlines()[0]
    s = evaluate(str(model), 1, tmp_path / "eval", quiet=True)  # env settings from meta.json
    assert s["per_episode"][0]["steps"] <= 16
    assert s["env_settings"]["brush"] == "tiny_env"


def test_short_sac_run(tmp_path):
    cfg = tmp_path / "sac.toml"
    cfg.write_text(PPO_TOML.replace('algo = "ppo"', 'algo = "sac"').replace(
        "n_steps = 64\nbatch_size = 32\nn_epochs = 2", "learning_starts = 32\nbatch_size = 32")
        .replace("reward = true", "reward = false"))
    model = train("sac", cfg, 96, 1, tmp_path / "run", progress=False)
    s = evaluate(str(model), 1, tmp_path / "eval", quiet=True)
    assert s["episodes"] == 1


def test_agent_config_errors(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(PPO_TOML + "\n[extra]\nx = 1\n")
    with pytest.raises(ValueError, match=r"unknown key\(s\) \['extra'\] in top level"):
        load_agent_config(cfg)
    cfg.write_text(PPO_TOML.replace("eval_freq = 64", "eval_freq = 0"))
    with pytest.raises(ValueError, match=r"\[train\] eval_freq = 0 is out of range"):
        load_agent_config(cfg)
    cfg.write_text(PPO_TOML)
    with pytest.raises(ValueError, match="does not match algo = 'ppo'"):
        train("sac", cfg, 10, 1, tmp_path / "x")


def test_shipped_agent_configs_load():
    from brush_env.engine import configs_dir

    for algo in ("ppo", "sac"):
        assert load_agent_config(configs_dir() / "agents" / f"{algo}.toml")["algo"] == algo
