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

#: SAC on the same tiny env: 32 steps of warm-up, evaluations and checkpoints only at the end
SAC_TOML = (
    PPO_TOML.replace('algo = "ppo"', 'algo = "sac"')
    .replace("n_steps = 64\nbatch_size = 32\nn_epochs = 2", "learning_starts = 32\nbatch_size = 32")
    .replace("reward = true", "reward = false")
    .replace("eval_freq = 64", "eval_freq = 5000")
    .replace("checkpoint_freq = 128", "checkpoint_freq = 5000")
)


@pytest.mark.slow  # training (~7 s)
def test_short_ppo_run_trains_saves_reloads_and_evaluates(tmp_path):
    cfg = tmp_path / "ppo.toml"
    cfg.write_text(PPO_TOML)
    out = tmp_path / "run"
    model = train("ppo", cfg, 192, 1, out, progress=False)
    assert model == out / "model.zip" and model.exists()
    for name in (
        "vecnormalize.pkl",
        "meta.json",
        "reference.json",
        "progress.csv",
        "eval/evaluations.npz",
        "best/best_model.zip",
    ):
        assert (out / name).exists(), name
    assert list((out / "checkpoints").glob("ppo_*_steps.zip"))
    assert list((out / "checkpoints").glob("ppo_vecnormalize_*_steps.pkl"))
    meta = json.loads((out / "meta.json").read_text())
    assert meta["algo"] == "ppo" and meta["env_kwargs"]["brush"] == "tiny_env"
    assert "eval/gap_to_reference" in (out / "progress.csv").read_text().splitlines()[0]
    s = evaluate(str(model), 1, tmp_path / "eval", quiet=True)  # env settings from meta.json
    assert s["per_episode"][0]["steps"] <= 16
    assert s["env_settings"]["brush"] == "tiny_env"


@pytest.mark.slow  # training
def test_short_sac_run(tmp_path):
    cfg = tmp_path / "sac.toml"
    cfg.write_text(SAC_TOML)
    model = train("sac", cfg, 96, 1, tmp_path / "run", progress=False)
    s = evaluate(str(model), 1, tmp_path / "eval", quiet=True)
    assert s["episodes"] == 1
    # shorter than eval_freq and checkpoint_freq: one final evaluation and checkpoint all the same
    assert (tmp_path / "run" / "best" / "best_model.zip").exists()
    assert (tmp_path / "run" / "eval" / "evaluations.npz").exists()
    assert list((tmp_path / "run" / "checkpoints").glob("sac_*_steps.zip"))


@pytest.mark.slow  # two short trainings
def test_sac_init_model_warms_up_with_its_own_policy(tmp_path):
    """``--init-model`` for SAC: the continued run's warm-up (``learning_starts`` steps before
    the first update, its replay buffer empty) acts with the loaded policy, not uniformly at
    random as SAC's warm-up for a policy that knows nothing; the updates wait for it as in a
    new run (the actor's optimiser: one step per env step past learning_starts, in each run)."""
    import numpy as np
    import torch
    from stable_baselines3 import SAC

    cfg = tmp_path / "sac.toml"
    cfg.write_text(SAC_TOML)
    first = train("sac", cfg, 96, 1, tmp_path / "a", progress=False)
    second = train("sac", cfg, 64, 1, tmp_path / "b", progress=False, init_model=first)

    def actor_steps(path):
        state = SAC.load(path, device="cpu").actor.optimizer.state_dict()["state"]
        return int(next(iter(state.values()))["step"])

    # train_freq = 1, gradient_steps = 1 (SB3's defaults)
    assert actor_steps(first) == 96 - 32
    assert actor_steps(second) == actor_steps(first) + 64 - 32
    # in the warm-up (num_timesteps < learning_starts) the continued SAC samples its policy:
    # the same action as the policy's own sample under the same torch seed; SAC's own takes a
    # uniform sample of the action space, which the torch seed does not fix
    from agents.train import continued_sac

    model = continued_sac().load(second, device="cpu")
    model._last_obs = np.zeros((1, *model.observation_space.shape), np.float32)
    model.num_timesteps = 0
    torch.manual_seed(0)
    warm = model._sample_action(model.learning_starts, None, 1)[0]
    torch.manual_seed(0)
    own = model.predict(model._last_obs, deterministic=False)[0]
    assert np.array_equal(warm, own)
    plain = SAC.load(second, device="cpu")
    plain._last_obs = model._last_obs
    plain.num_timesteps = 0
    plain.action_space.seed(1)
    torch.manual_seed(0)
    assert not np.array_equal(plain._sample_action(plain.learning_starts, None, 1)[0], own)


def test_agent_config_errors(tmp_path):
    cfg = tmp_path / "bad.toml"
    cfg.write_text(PPO_TOML + "\n[extra]\nx = 1\n")
    with pytest.raises(ValueError, match=r"top level: unknown key 'extra'"):
        load_agent_config(cfg)
    cfg.write_text(PPO_TOML.replace("eval_freq = 64", "eval_freq = 0"))
    with pytest.raises(ValueError, match=r"\[train\] eval_freq = 0 is out of range"):
        load_agent_config(cfg)
    cfg.write_text(PPO_TOML)
    with pytest.raises(ValueError, match="does not match algo = 'ppo'"):
        train("sac", cfg, 10, 1, tmp_path / "x")
    assert not (tmp_path / "x").exists()  # nothing written before the inputs are valid


def test_misspelled_hyperparameter_and_env_key_fail_before_any_worker(tmp_path):
    """Checked in the main process against PPO's signature / the env's settings, with a hint."""
    cfg = tmp_path / "ppo.toml"
    cfg.write_text(PPO_TOML.replace("n_epochs = 2", "n_epoch = 2"))
    with pytest.raises(
        ValueError,
        match=r"'n_epoch' is not an argument of PPO; did you mean "
        r"n_epochs",
    ):
        train("ppo", cfg, 10, 2, tmp_path / "x")
    cfg.write_text(PPO_TOML.replace("max_episode_steps = 16", "max_episode_step = 16"))
    with pytest.raises(ValueError, match=r"max_episode_step.*did you mean max_episode_steps"):
        train("ppo", cfg, 10, 2, tmp_path / "x")
    assert not (tmp_path / "x").exists()


def test_shipped_agent_configs_load():
    from brush_env.engine import configs_dir

    for algo in ("ppo", "sac"):
        assert load_agent_config(configs_dir() / "agents" / f"{algo}.toml")["algo"] == algo


# the same run on PlanarStroke-v0: no env config file (only BrushEnv ids have one)
PLANAR_TOML = PPO_TOML.replace("FlatPlate-v0", "PlanarStroke-v0").replace(
    'config = "flat_plate"\n', ""
)


@pytest.mark.slow  # training
def test_planar_stroke_trains_with_agents_train(tmp_path):
    """PlanarStroke-v0 (pymunk) trains through the same script: a short PPO run saves a model
    that reloads and acts (no score asserted)."""
    from stable_baselines3 import PPO

    cfg = tmp_path / "planar.toml"
    cfg.write_text(PLANAR_TOML)
    out = tmp_path / "run"
    model_path = train("ppo", cfg, 128, 1, out, progress=False)
    meta = json.loads((out / "meta.json").read_text())
    assert meta["env_id"].endswith("PlanarStroke-v0") and meta["reference_mean_reward"] is None
    model = PPO.load(model_path)
    import gymnasium as gym

    env = gym.make("brush_env/PlanarStroke-v0", brush="tiny_env")
    obs, _ = env.reset(seed=0)
    action, _ = model.predict(obs, deterministic=True)
    assert env.action_space.contains(action)
    env.close()


def test_vec_env_auto_is_the_batched_env_at_fast_reduced_and_table(tmp_path):
    """--vec-env auto: the batched env (gym.make_vec, vector_entry_point) at fast, reduced and
    table, SubprocVecEnv at the full-chain levels; a bad choice is named."""
    from agents.train import check_inputs

    cfg = tmp_path / "ppo.toml"
    cfg.write_text(PPO_TOML)
    assert check_inputs("ppo", cfg, 10, 2, None)["vec_env"] == "batched"  # the default: fast
    levels = {"reduced": "batched", "fast": "batched", "coarse": "subproc", "balanced": "subproc"}
    for level, want in levels.items():
        assert check_inputs("ppo", cfg, 10, 2, {"fidelity": level})["vec_env"] == want
    assert check_inputs("ppo", cfg, 10, 2, None, "subproc")["vec_env"] == "subproc"
    with pytest.raises(ValueError, match=r"--vec-env 'threads' is not allowed: must be one of"):
        check_inputs("ppo", cfg, 10, 2, None, "threads")


@pytest.mark.slow  # training
def test_batched_two_env_ppo_run(tmp_path):
    """Two envs on the batched env: trains, saves, records the choice."""
    cfg = tmp_path / "ppo.toml"
    cfg.write_text(PPO_TOML)
    model = train("ppo", cfg, 128, 2, tmp_path / "run", progress=False)
    meta = json.loads((tmp_path / "run" / "meta.json").read_text())
    assert model.exists() and meta["vec_env"] == "batched" and meta["n_envs"] == 2


def test_train_env_kwargs_reach_the_learning_envs_only(tmp_path):
    """``--train-env-kw`` (the campaign's margin on the force limit) sets the envs the policy
    learns on; the evaluation env and the settings saved for agents/evaluate.py keep the
    task's.  A bad key or value is named; the env file is not the training envs' own."""
    from agents.train import check_inputs, make_envs
    from brush_env.envs.config import load_env_config

    cfg = tmp_path / "ppo.toml"
    cfg.write_text(PPO_TOML)
    task = load_env_config("flat_plate").total_force_limit
    run = check_inputs("ppo", cfg, 10, 2, None, train_env_kwargs={"total_force_limit": 3.0})
    assert "total_force_limit" not in run["kwargs"] and task != 3.0
    for vec_env in ("batched", "subproc"):
        venv, eval_env = make_envs({**run, "vec_env": vec_env}, 2, 0)
        try:
            assert [c.total_force_limit for c in venv.get_attr("config")] == [3.0, 3.0]
            assert [c.total_force_limit for c in eval_env.get_attr("config")] == [task]
        finally:
            venv.close()
            eval_env.close()
    with pytest.raises(ValueError, match="total_force_limit"):
        check_inputs("ppo", cfg, 10, 2, None, train_env_kwargs={"total_force_limit": -1.0})
    with pytest.raises(ValueError, match="total_forse_limit"):
        check_inputs("ppo", cfg, 10, 2, None, train_env_kwargs={"total_forse_limit": 3.0})
    with pytest.raises(ValueError, match=r"--train-env-kw config=\.\.\.: the training envs"):
        check_inputs("ppo", cfg, 10, 2, None, train_env_kwargs={"config": "tooth_row"})


@pytest.mark.slow  # two short trainings
def test_init_model_goes_on_from_the_saved_weights_optimiser_and_statistics(tmp_path):
    """``--init-model``: the second run continues the first -- its optimiser has taken the
    first run's updates plus its own, and its observation statistics hold both runs' samples
    -- while its envs take the new training settings; a model of another algorithm or without
    its meta.json is refused by name."""
    import pickle
    import shutil

    from stable_baselines3 import PPO

    from agents.train import check_init_model

    cfg = tmp_path / "ppo.toml"
    cfg.write_text(PPO_TOML)
    first = train("ppo", cfg, 128, 1, tmp_path / "a", progress=False)
    second = train(
        "ppo",
        cfg,
        128,
        1,
        tmp_path / "b",
        progress=False,
        init_model=first,
        train_env_kwargs={"hard_force_limit": 4.0},
    )

    def adam_steps(path):
        state = PPO.load(path, device="cpu").policy.optimizer.state_dict()["state"]
        return int(next(iter(state.values()))["step"])

    # PPO_TOML: 64 steps per rollout, 2 epochs of 2 minibatches -> 4 Adam steps per rollout
    assert adam_steps(first) == 2 * 4
    assert adam_steps(second) == adam_steps(first) + 2 * 4
    a, b = (pickle.loads((tmp_path / d / "vecnormalize.pkl").read_bytes()) for d in "ab")
    # a run counts its first reset and its 128 steps (RunningMeanStd starts at count 1e-4); the
    # second run's statistics go on from the first's
    assert a.obs_rms.count == pytest.approx(1e-4 + 1 + 128)
    assert b.obs_rms.count == pytest.approx(a.obs_rms.count + 1 + 128)
    meta = json.loads((tmp_path / "b" / "meta.json").read_text())
    assert meta["init_model"] == str(first)
    assert meta["train_env_kwargs"] == {"hard_force_limit": 4.0}
    with pytest.raises(ValueError, match="is a 'ppo' model: must be --algo 'sac'"):
        check_init_model(first, "sac", "brush_env/FlatPlate-v0")
    with pytest.raises(
        ValueError, match="was trained on .*FlatPlate-v0.*, not 'brush_env/ToothRow"
    ):
        check_init_model(first, "ppo", "brush_env/ToothRow-v0")
    lone = tmp_path / "lone" / "model.zip"
    lone.parent.mkdir()
    shutil.copyfile(first, lone)
    with pytest.raises(ValueError, match="no meta.json beside it"):
        check_init_model(lone, "ppo", "brush_env/FlatPlate-v0")
    with pytest.raises(ValueError, match="no such file"):
        check_init_model(tmp_path / "none.zip", "ppo", "brush_env/FlatPlate-v0")


def test_env_flag_trains_on_that_id_with_its_own_env_file():
    """``--env`` (the campaign's env_id) overrides the agent config's ``[env] id``; the config's
    ``[env] config`` ("flat_plate") names the plate's env file, so the tooth row gets its own
    ("tooth_row").  Before, a tooth-row campaign trained on the plate without a word."""
    from agents.train import check_inputs

    cfg = "configs/agents/ppo.toml"
    run = check_inputs("ppo", cfg, 10, 2, None, env_id="brush_env/ToothRow-v0")
    assert run["env_id"] == "brush_env:brush_env/ToothRow-v0"
    assert run["kwargs"]["config"] == "tooth_row"
    # the config's own id keeps its env file; an explicit config keyword wins over both
    assert check_inputs("ppo", cfg, 10, 2, None)["kwargs"]["config"] == "flat_plate"
    same = check_inputs("ppo", cfg, 10, 2, None, env_id="brush_env/FlatPlate-v0")
    assert same["kwargs"]["config"] == "flat_plate"
    kw = {"config": "tooth_row", "fidelity": "reduced"}
    assert check_inputs("ppo", cfg, 10, 2, kw, env_id="brush_env/ToothRow-v0")["kwargs"] == kw


def test_campaign_trains_on_its_env_id():
    from agents.campaign import _train_cmd

    c = {"env_id": "brush_env/ToothRow-v0", "env_kwargs": {"fidelity": "reduced"}}
    t = {"algo": "ppo", "config": "configs/agents/ppo.toml", "timesteps": 10, "n_envs": 2}
    cmd = _train_cmd(c, {**t, "dir": "runs/x"}, 0)
    assert cmd[cmd.index("--env") + 1] == "brush_env/ToothRow-v0"
    assert "--train-env-kw" not in cmd
    c["train_env_kwargs"] = {"total_force_limit": 3.0}
    cmd = _train_cmd(c, {**t, "dir": "runs/x"}, 0)
    assert cmd[cmd.index("--train-env-kw") + 1] == "total_force_limit=3.0"
