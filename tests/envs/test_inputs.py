"""Issue 28 through ``gym.make`` and ``reset``: the same scene-file rules as the CLI, and a start
pose inside a surface refused (ConfigError naming the option, the value and the surface)."""

from __future__ import annotations

import gymnasium as gym
import pytest

from brush_env.engine import ConfigError

from ..test_cli_errors import FILES
from .conftest import ENV_ID, TINY


@pytest.mark.parametrize(
    ("fname", "expected"),
    [
        ("dup.toml", r"dup.toml: invalid TOML: Cannot overwrite a value"),
        ("nobrush.toml", r"nobrush.toml: brush = 'nosuchbrush': brush 'nosuchbrush' is not"),
        ("mu.toml", r"mu.toml: contact.mu_s = 0.3 is out of range: must be >= contact.mu_d"),
        ("normal.toml", r"normal.toml: surface\[0\].normal = \[0.0, 0.0, 0.0\] is invalid"),
    ],
)
def test_gym_make_refuses_the_scene_files_the_cli_refuses(tmp_path, fname, expected):
    p = tmp_path / fname
    p.write_text(FILES[fname])
    with pytest.raises(ConfigError, match=expected):
        gym.make(ENV_ID, scene=str(p), **TINY)


def test_reset_refuses_a_start_inside_the_plate(make_env):
    env = make_env()
    u = env.unwrapped
    z_t = u.touch_height
    with pytest.raises(ConfigError) as e:
        env.reset(seed=0, options={"tcp_position": [0.0, 0.0, z_t - 2.0]})
    msg = str(e.value)
    assert f"reset option tcp_position = [0.0, 0.0, {z_t - 2.0!r}]" in msg
    assert "mm inside surface 0 ('plane')" in msg and "lift the TCP by >= " in msg
    with pytest.raises(ConfigError, match=r"plate_offset = \[0.0, 0.0, 1.0\] starts the tip"):
        env.reset(seed=0, options={"tcp_position": [0.0, 0.0, z_t], "plate_offset": [0, 0, 1]})
    touching = {"tcp_position": [0.0, 0.0, z_t], "plate_offset": [0.0, 0.0, 0.0]}
    _, info = env.reset(seed=0, options=touching)  # touching the plate: allowed
    assert info["tcp_position"][2] == pytest.approx(z_t)
