"""The policy shipped in agents/models loads with its statistics and runs an episode (no score is
asserted: the campaign's table in agents/models/README.md holds the scores)."""

import json
from pathlib import Path

import pytest

from agents.evaluate import companions, evaluate

MODELS = Path(__file__).resolve().parents[2] / "agents" / "models"


def test_a_flat_plate_model_ships_with_its_statistics_and_card():
    zips = sorted(MODELS.glob("flat_plate_*.zip"))
    assert zips, f"no flat_plate_<algo>.zip in {MODELS}"
    for z in zips:
        meta, vn = companions(z)
        assert meta.name == f"{z.stem}.meta.json" and meta.is_file()
        assert json.loads(meta.read_text())["algo"] in z.stem
        assert z.stat().st_size < 5_000_000  # a few MB at most
        assert z.stem in (MODELS / "README.md").read_text()
        if json.loads(meta.read_text())["normalize"].get("obs"):
            assert vn.is_file()


@pytest.mark.parametrize("z", sorted(MODELS.glob("flat_plate_*.zip")), ids=lambda z: z.stem)
def test_the_shipped_model_runs_one_episode(tmp_path, z):
    s = evaluate(str(z), 1, tmp_path, seed=0, quiet=True, env_kwargs={"max_episode_steps": 50})
    trained = json.loads(companions(z)[0].read_text())["env_kwargs"]
    assert s["env_kwargs"]["fidelity"] == trained["fidelity"]  # the settings it was trained on
    ep = s["per_episode"][0]
    assert ep["steps"] >= 1 and ep["termination"] != "divergence"
