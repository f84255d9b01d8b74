"""``bench episodes``: each scene's episode runs under its policy and reports how it ended (no
timing asserted)."""

from __future__ import annotations

import pytest

from brush_env.bench import episodes as E


@pytest.mark.parametrize("env_id", E.SCENES)
def test_episode_rows_report_steps_and_ending(env_id):
    r = E.run_episode(env_id, "reduced", seed=0, steps=3)
    # the first three control steps of either policy are an approach above the surface: the
    # episode runs to the step limit, which is a truncation, not a termination
    assert r["steps"] == 3
    assert r["termination"] is None
    assert r["env"] == env_id.split("/")[-1]
