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


def test_against_compares_coverage_and_gum_force_over_the_steps_both_ran():
    """``--against``: the coverage difference in points and the gum force's pooled RMS error,
    sqrt(sum (g - g_ref)^2 / sum g_ref^2), over the steps both episodes reached."""
    runs = [
        {"env": "ToothRow-v0", "fidelity": "reduced", "coverage": 0.20, "gum_force": [0.1, 0.3]},
        {"env": "ToothRow-v0", "fidelity": "reduced", "coverage": 0.15, "gum_force": [0.2]},
    ]
    refs = [
        {"env": "ToothRow-v0", "fidelity": "balanced", "coverage": 0.19, "gum_force": [0.1, 0.4]},
        {"env": "ToothRow-v0", "fidelity": "balanced", "coverage": 0.18, "gum_force": [0.2, 9.9]},
    ]
    c = E.compare(runs, refs)
    assert c["coverage_diff_mean_abs"] == pytest.approx(2.0)  # |+1| and |-3| points
    assert c["coverage_diff_max_abs"] == pytest.approx(3.0)
    assert c["coverage_diff_mean"] == pytest.approx(-1.0)
    # the second pair stops at the shorter run's one step: 9.9 never enters
    assert c["gum_force_rms_error"] == pytest.approx((0.01 / (0.01 + 0.16 + 0.04)) ** 0.5)
