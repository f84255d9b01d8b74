"""Registration of the gym ids without importing gymnasium from the engine (issue 10 item 4).

Each case runs in a fresh interpreter, since what is tested is the import order itself."""

import subprocess
import sys

import pytest

from .conftest import ENV_ID

#: a meta-path finder that refuses gymnasium, as if it were not installed
BLOCK_GYMNASIUM = (
    "import sys\n"
    "class Block:\n"
    "    def find_spec(self, name, path=None, target=None):\n"
    "        if name == 'gymnasium' or name.startswith('gymnasium.'):\n"
    "            raise ImportError('gymnasium is blocked')\n"
    "sys.meta_path.insert(0, Block())\n"
)


def _run(code: str) -> str:
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    return res.stdout.strip()


def test_engine_import_loads_no_gymnasium():
    assert (
        _run(
            "import sys\nimport brush_env.engine\nimport brush_env\n"
            "print('gymnasium' in sys.modules)"
        )
        == "False"
    )


@pytest.mark.slow  # a fresh interpreter
def test_engine_runs_with_gymnasium_blocked():
    code = BLOCK_GYMNASIUM + (
        "try:\n"
        "    import gymnasium\n"
        "    raise SystemExit('the block did not work')\n"
        "except ImportError:\n"
        "    pass\n"
        "import numpy as np\n"
        "import brush_env\n"
        "from brush_env.engine import SimSettings, Simulator, load_brush, load_scene\n"
        "sim = Simulator(load_scene('flat_plate', brush=load_brush('tiny_env')), SimSettings())\n"
        "R = np.diag([1.0, -1.0, -1.0])\n"
        "sim.reset(np.array([0.0, 0.0, 20.0]), R)\n"
        "out = sim.step(np.array([0.0, 0.0, 20.0]), R)\n"
        "assert np.all(np.isfinite(out.tip_pos))\n"
        "print('gymnasium' in sys.modules)\n"
    )
    assert _run(code) == "False"


@pytest.mark.slow  # a fresh interpreter per import order (~7 s in all)
@pytest.mark.parametrize(
    "imports",
    [
        "import gymnasium as gym\nimport brush_env\n",
        "import brush_env\nimport gymnasium as gym\n",
        "import brush_env.engine\nimport gymnasium as gym\n",
        "import brush_env\nfrom gymnasium.envs.registration import registry\n"
        "import gymnasium as gym\n",
        "import brush_env, importlib\nimportlib.reload(brush_env)\nimport gymnasium as gym\n",
    ],
    ids=["gym-first", "brush-first", "engine-first", "submodule-first", "reload"],
)
def test_every_import_order_registers_the_ids(imports):
    code = imports + (
        "import sys, warnings\n"
        "warnings.simplefilter('error')  # registering twice would warn\n"
        f"env = gym.make({ENV_ID!r}, brush='tiny_env')\n"
        "env.reset(seed=0)\n"
        "import brush_env as b\n"
        "assert not any(getattr(f, 'brush_env_hook', False) for f in sys.meta_path)\n"
        "assert type(gym.__loader__).__name__ != '_RegisteringLoader'\n"
        "print(env.spec.max_episode_steps, env.unwrapped.horizon)\n"
    )
    assert _run(code) == "300 300"
