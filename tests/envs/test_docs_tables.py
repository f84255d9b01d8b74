"""The tables of the env module docstring (and docs/env.md) are pinned to the code."""

import re
from dataclasses import MISSING
from pathlib import Path

import numpy as np
import pytest
import tomllib

import brush_env
from brush_env.engine import configs_dir
from brush_env.envs import flat_plate
from brush_env.envs.config import FIELDS, EnvConfig, arguments_table
from brush_env.envs.observation import ObservationLayout

DOC = flat_plate.__doc__
ROOT = Path(__file__).resolve().parents[2]


def _table(title: str) -> list[list[str]]:
    """Rows (cells stripped) of the first Markdown table after the heading ``title``."""
    part = DOC.split(f"\n{title}\n")[1]
    rows = [ln for ln in part.splitlines() if ln.startswith("|")]
    start = part.splitlines().index(rows[0])
    lines = part.splitlines()[start:]
    table = []
    for ln in lines:
        if not ln.startswith("|"):
            break
        table.append([c.strip() for c in ln.strip("|").split("|")])
    return table[2:]  # drop header and rule


@pytest.mark.parametrize("nb,m", [(40, 8), (4, 8), (7, 3)])
def test_observation_table_matches_layout(nb, m):
    lay = ObservationLayout(EnvConfig(coarse_map_size=m), nb, 10.0)
    rows = _table("Observation Space\n-----------------")
    assert [r[1] for r in rows] == [b.name for b in lay.blocks]
    env = {"nb": nb, "m": m}
    for (idx, name, shape, bounds, *_), b in zip(rows, lay.blocks, strict=True):
        lo, hi = (eval(x, env) for x in idx.split(".."))  # noqa: S307 - our own docstring
        assert (lo, hi + 1) == (lay.slices[name].start, lay.slices[name].stop), name
        assert eval(shape, env) == b.shape, name  # noqa: S307
        assert [float(x) for x in bounds.strip("[]").split(",")] == [b.low, b.high], name
    assert lay.size == 8 * nb + 23 + m * m
    assert "8 nb + 23 + m^2" in DOC and "407 for the default brush" in DOC
    assert ObservationLayout(EnvConfig(), 40, 10.0).size == 407


def test_action_table_matches_action_type_and_defaults():
    rows = _table("Action Space\n------------")
    assert [int(r[0]) for r in rows] == list(range(6))
    cfg = EnvConfig()
    scales = list(cfg.max_linear_speed) + list(cfg.max_angular_speed)
    for r, s in zip(rows, scales, strict=True):
        assert float(r[3].split("=")[1]) == s
        assert ("3d" in r[4]) == (int(r[0]) < 3)


def test_reward_table_matches_terms():
    rows = _table("Rewards\n-------")
    assert tuple(r[0] for r in rows) == flat_plate.REWARD_TERMS
    cfg = EnvConfig()
    for r in rows:
        for key, default in re.findall(r"(\w+) \(([\d.]+)", r[2]):
            assert getattr(cfg, key) == float(default), key


def _default(name: str):
    f = FIELDS[name]
    return f.default_factory() if f.default is MISSING else f.default


def test_arguments_table_matches_config_fields():
    rows = _table("Arguments\n---------")
    assert [r[0] for r in rows] == list(FIELDS)
    for r in rows:
        default = _default(r[0])
        doc = eval(r[1])  # noqa: S307 - our own docstring
        assert doc == default, r[0]
        assert r[2] == FIELDS[r[0]].metadata["unit"].replace("*", " "), r[0]


def test_config_file_defaults_equal_dataclass_defaults_and_registration():
    data = tomllib.loads((configs_dir() / "envs" / "flat_plate.toml").read_text())
    flat = {k: v for sec in data.values() for k, v in sec.items()}
    assert set(flat) == set(FIELDS)
    for k, v in flat.items():
        assert (tuple(v) if isinstance(v, list) else v) == _default(k), k
    steps = {eid: s for eid, (_, s) in brush_env.ENV_IDS.items()}
    assert steps["brush_env/FlatPlate-v0"] == flat["max_episode_steps"]
    teeth = tomllib.loads((configs_dir() / "envs" / "tooth_row.toml").read_text())
    teeth = {k: v for sec in teeth.values() for k, v in sec.items()}
    assert set(teeth) == set(FIELDS)
    assert steps["brush_env/ToothRow-v0"] == teeth["max_episode_steps"]


def test_docs_env_md_lists_every_block_setting_and_term():
    text = (ROOT / "docs" / "env.md").read_text()
    lay = ObservationLayout(EnvConfig(), 40, 10.0)
    assert lay.table() in text  # the default layout table, as generated
    assert arguments_table() in text
    for term in flat_plate.REWARD_TERMS:
        assert f"`{term}`" in text
    assert np.all(lay.low < lay.high)
