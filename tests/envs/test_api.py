"""Gymnasium / SB3 API conformance of every registered id, registration, vector envs."""

import subprocess
import sys
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import brush_env
from brush_env.engine.fidelity import LEVELS

from .conftest import ENV_ID, TINY

VARIANTS = [{}, {"observation_mode": "dict"}, {"action_mode": "3d"}]


@pytest.mark.parametrize("env_id", sorted(brush_env.ENV_IDS))
@pytest.mark.parametrize("variant", VARIANTS, ids=["box-6d", "dict", "3d"])
def test_gymnasium_check_env(env_id, variant):
    env = gym.make(env_id, **TINY, **variant)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # any checker warning fails the test
        check_env(env.unwrapped)  # unwrapped: the checker warns about wrappers otherwise
    env.close()


@pytest.mark.parametrize("env_id", sorted(brush_env.ENV_IDS))
@pytest.mark.parametrize("variant", VARIANTS, ids=["box-6d", "dict", "3d"])
def test_sb3_check_env(env_id, variant):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(env_id, **TINY, **variant)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        # Justified: the Dict variant keeps the per-tip blocks as (nb, 3) and the coverage map as
        # (m, m) on purpose (that is what a Dict is for); SB3's MultiInputPolicy flattens every
        # non-image Box (CombinedExtractor -> nn.Flatten), so the shapes are handled.  The Box
        # variant (the registered default) raises no warning at all.
        warnings.filterwarnings(
            "ignore",
            message=r"Your observation \w+ has an unconventional "
            "shape",
            category=UserWarning,
        )
        sb3_check_env(env.unwrapped, warn=True)
    env.close()


@pytest.mark.slow  # ~85 s: a fresh interpreter imports and steps the env
def test_make_with_module_prefix_in_fresh_subprocess():
    code = (
        "import sys, gymnasium as gym\n"
        "assert 'brush_env' not in sys.modules\n"
        "env = gym.make('brush_env:brush_env/FlatPlate-v0', brush='tiny_env')\n"
        "obs, info = env.reset(seed=0)\n"
        "obs, r, term, trunc, info = env.step(env.action_space.sample())\n"
        "assert obs.shape == env.observation_space.shape\n"
        "print('OK', env.spec.max_episode_steps)\n"
    )
    # a guard against a hang, not a timing: a worker that finds the numba cache cold compiles
    # every kernel (~1.5-2.5 min on a busy 2-core machine, docs/benchmarks.md)
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "OK 300"


def test_import_registers_without_loading_envs():
    code = (
        "import sys, brush_env, gymnasium as gym\n"
        "assert 'brush_env/FlatPlate-v0' in gym.registry\n"
        "assert 'brush_env.envs.flat_plate' not in sys.modules\n"
        "print('OK')\n"
    )
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert res.returncode == 0 and res.stdout.strip() == "OK", res.stderr


def test_registration_is_idempotent():
    import importlib

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # re-registering would warn "Overriding environment"
        importlib.reload(brush_env)
        brush_env._register()
    assert gym.spec(ENV_ID).entry_point == "brush_env.envs.flat_plate:BrushEnv"


@pytest.mark.slow  # worker subprocesses (~4 s)
def test_subproc_vec_env_steps():
    from stable_baselines3.common.env_util import make_vec_env
    from stable_baselines3.common.vec_env import SubprocVecEnv

    venv = make_vec_env(
        "brush_env:brush_env/FlatPlate-v0",
        n_envs=2,
        seed=0,
        vec_env_cls=SubprocVecEnv,
        env_kwargs=TINY,
    )
    try:
        obs = venv.reset()
        assert obs.shape == (2,) + venv.observation_space.shape
        for _ in range(3):
            obs, rew, done, infos = venv.step(np.zeros((2, 6), np.float32))
        assert obs.shape[0] == 2 and rew.shape == (2,) and len(infos) == 2
        assert not np.array_equal(obs[0], obs[1])  # different seeds, different start poses
        assert set(infos[0]["reward_terms"]) == {
            "coverage",
            "total_force",
            "tip_force",
            "termination",
        }
    finally:
        venv.close()


@pytest.mark.parametrize("engine_dt,frame_skip", [(0.004, 10), (0.002, 5), (0.005, 7)])
def test_dt_and_render_fps(make_env, engine_dt, frame_skip):
    env = make_env(engine_dt=engine_dt, frame_skip=frame_skip)
    u = env.unwrapped
    assert u.dt == pytest.approx(engine_dt * frame_skip)
    assert u.metadata["render_fps"] == pytest.approx(1.0 / u.dt)
    assert u.sim.settings.dt == engine_dt
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.zeros(6, np.float32))
    assert info["time"] == pytest.approx(u.dt)


def test_time_limit_from_make_overrides_config(make_env):
    """gym.make's max_episode_steps (the TimeLimit) is what time_remaining counts down."""
    env = make_env(max_episode_steps=4)
    assert env.unwrapped.config.max_episode_steps == 300
    assert env.unwrapped.horizon == 4  # passed by gym.make's TimeLimitHorizon wrapper
    env.reset(seed=0)
    for k in range(4):
        obs, _, term, trunc, _ = env.step(np.zeros(6, np.float32))
        assert not term
        assert trunc == (k == 3)
    assert env.unwrapped.layout.block(obs, "time_remaining")[0] == 0.0


def test_horizon_without_time_limit_is_the_config_value(make_env):
    from brush_env.envs import BrushEnv

    env = BrushEnv(brush="tiny_env", max_episode_steps=7)
    obs, _ = env.reset(seed=0)
    assert env.horizon == 7
    obs, *_ = env.step(np.zeros(6, np.float32))
    assert env.layout.block(obs, "time_remaining")[0] == pytest.approx(6 / 7)
    # gym.make without a TimeLimit: the env's own setting
    made = make_env(max_episode_steps=-1, **{"config": "flat_plate"})
    assert made.unwrapped.horizon == 300
    with pytest.raises(ValueError, match="horizon = 0 is out of range"):
        env.set_horizon(0)


def test_horizon_is_not_found_by_stack_walking():
    """A BrushEnv wrapped in a TimeLimit by hand keeps its config's horizon until told: the
    number is passed explicitly (set_horizon), never read off the call stack."""
    from gymnasium.wrappers import TimeLimit

    from brush_env.envs import BrushEnv

    env = TimeLimit(BrushEnv(brush="tiny_env", max_episode_steps=7), max_episode_steps=3)
    env.reset(seed=0)
    assert env.unwrapped.horizon == 7
    env.unwrapped.set_horizon(3)
    obs, *_ = env.step(np.zeros(6, np.float32))
    assert env.unwrapped.layout.block(obs, "time_remaining")[0] == pytest.approx(2 / 3)


@pytest.mark.parametrize(
    "level",
    # the converged level's steps take ~5 s with the tiny brush, the others ~0.2 s
    [pytest.param(v, marks=pytest.mark.slow) if v == "reference" else v for v in LEVELS],
)
def test_both_checkers_pass_at_every_fidelity_level(level):
    """Gymnasium's and stable-baselines3's env checkers on FlatPlate-v0 at every shipped fidelity
    level (the default ``fast`` is checked above for every id and variant), and the batched env
    of the same level keeps its outputs in its spaces over a few steps."""
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(ENV_ID, **TINY, fidelity=level)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)
        sb3_check_env(env.unwrapped, warn=True)
    env.close()
    venv = gym.make_vec(ENV_ID, 2, vectorization_mode="vector_entry_point", **TINY, fidelity=level)
    obs, _ = venv.reset(seed=0)
    venv.action_space.seed(0)
    for _ in range(3):
        assert venv.observation_space.contains(obs)
        obs, rew, term, trunc, _ = venv.step(venv.action_space.sample())
        assert np.all(np.isfinite(rew)) and rew.shape == term.shape == trunc.shape == (2,)
    venv.close()


def test_a_stepped_env_pickles_and_its_copy_steps_as_the_original():
    """An env at the default level (the compiled rollout, called through its entry point after
    the first step) pickles after stepping, and the copy goes on bit for bit as the original."""
    import pickle

    env = gym.make("brush_env/FlatPlate-v0").unwrapped
    env.reset(seed=3)
    rng = np.random.default_rng(3)
    actions = rng.uniform(-1.0, 1.0, (8, *env.action_space.shape)).astype(np.float32)
    for a in actions[:4]:
        env.step(a)
    copy = pickle.loads(pickle.dumps(env))
    for a in actions[4:]:
        o1, r1, te1, tr1, _ = env.step(a)
        o2, r2, te2, tr2, _ = copy.step(a)
        assert np.array_equal(o1, o2) and r1 == r2 and (te1, tr1) == (te2, tr2)
