"""Shared fixtures of the env tests: a tiny 4-bristle, 3-body brush keeps an env step ~1-4 ms."""

import os

os.environ.setdefault("MPLBACKEND", "Agg")  # human-mode rendering draws off-screen in tests

import gymnasium as gym  # noqa: E402
import pytest  # noqa: E402

import brush_env  # noqa: E402,F401  (registers the ids)

ENV_ID = "brush_env/FlatPlate-v0"
TINY = {"brush": "tiny_env"}
#: the plate 10 mm below nominal: the brush never touches it, the motion is pure kinematics
NO_CONTACT = {"plate_offset": [0.0, 0.0, -10.0]}


@pytest.fixture
def make_env():
    envs = []

    def _make(**kw):
        env = gym.make(ENV_ID, **{**TINY, **kw})
        envs.append(env)
        return env

    yield _make
    for e in envs:
        e.close()
