"""Reward and task sanity (issue 30 item 1, docs/rl.md "Exploits and the tests that cover them").

The reference policy brushes within the force limit it is scored against, with a positive
return; no scripted exploit (doing nothing, hovering, leaving the workspace, pressing hard,
brushing above the limit, random actions) scores above it.  On the env's default fidelity
(``fast``) and the default brush: the facts are about the physics and the reward, so the tiny
test brush would not do.  The ``balanced`` runs (the accurate full model) are slow.
"""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import brush_env  # noqa: F401  (registers the ids)
from agents.campaign import load_campaign
from agents.probe_reward import make_probe
from agents.reference import ReferencePolicy

ENV_ID = "brush_env/FlatPlate-v0"
#: the plate at the top / bottom of its z offset range (configs/envs/flat_plate.toml:
#: plate_offset_range z = 0.5 mm): the reference's press is then 0.5 mm deeper / shallower
HIGH_PLATE = {"plate_offset": [0.0, 0.0, 0.5]}
LOW_PLATE = {"plate_offset": [0.0, 0.0, -0.5]}


def episode(env, policy, seed: int = 0, options=None) -> dict:
    """Return, coverage, time above the total-force limit [s], peak total force [N], end."""
    obs, info = env.reset(seed=seed, options=options)
    ret, above, peak = 0.0, 0.0, 0.0
    while True:
        action, _ = policy.predict(obs)
        obs, reward, term, trunc, info = env.step(action)
        ret += reward
        above += info["time_above_force_limit"]
        peak = max(peak, info["peak_normal_force"])
        if term or trunc:
            return {
                "return": ret,
                "coverage": info["coverage"],
                "time_above": above,
                "peak": peak,
                "termination": info["termination"],
            }


#: 6 s episodes keep the quick tier quick: the approach (1.5 s), the press (1 s) and half a turn
#: of the circle -- every force event of the 12 s episode (contact, press, break-away at the
#: circle's start) happens in the first 3 s; the slow ``balanced`` test runs the full 300 steps.
QUICK_STEPS = 150


@pytest.fixture(scope="module")
def fast_env():
    # the defaults (fidelity "fast", the default brush) on a shorter time limit
    env = gym.make(ENV_ID, max_episode_steps=QUICK_STEPS)
    yield env
    env.close()


@pytest.fixture(scope="module")
def reference_fast(fast_env):
    """The reference on seed 0 with the plate at the top of its range (the deepest press)."""
    return episode(fast_env, ReferencePolicy.for_env(fast_env), 0, HIGH_PLATE)


def test_reference_stays_within_the_force_limit_with_a_positive_return(fast_env, reference_fast):
    limit = fast_env.unwrapped.config.total_force_limit
    r = reference_fast
    assert r["termination"] is None, r
    assert r["time_above"] == 0.0 and r["peak"] < limit, r
    assert r["return"] > 0.0 and r["coverage"] > 0.05, r


def test_reference_touches_and_cleans_on_the_lowest_plate(fast_env):
    """The press is measured from the nominal plate: on the lowest plate it is 0.5 mm shallower
    and must still brush (a positive return), not skim above the plate."""
    r = episode(fast_env, ReferencePolicy.for_env(fast_env), 0, LOW_PLATE)
    assert r["termination"] is None and r["time_above"] == 0.0, r
    assert r["return"] > 0.0 and r["coverage"] > 0.05, r


def test_the_papers_static_press_breaks_the_limit_and_scores_below_the_reference(
    fast_env, reference_fast
):
    """The paper's order (press 3 mm at rest, then circle) holds the brush on the post-buckled
    plateau of all four rows (> 4 N): it must pay for it and score below the sliding press."""
    r = episode(fast_env, ReferencePolicy.for_env(fast_env, press="static"), 0, HIGH_PLATE)
    assert r["time_above"] > 0.0 and r["peak"] > fast_env.unwrapped.config.total_force_limit, r
    assert r["return"] < reference_fast["return"], (r, reference_fast)


@pytest.mark.parametrize("name", ["nothing", "hover", "leave (up)", "leave (side)"])
def test_idling_or_leaving_scores_below_the_reference(fast_env, reference_fast, name):
    r = episode(fast_env, make_probe(name, fast_env), 0, HIGH_PLATE)
    assert r["return"] < reference_fast["return"], (name, r, reference_fast)
    assert r["time_above"] == 0.0, (name, r)
    if name.startswith("leave"):
        # ended by the workspace, before touching: exactly the termination penalty
        cfg = fast_env.unwrapped.config
        assert r["termination"] == "workspace" and r["coverage"] == 0.0, (name, r)
        assert r["return"] == pytest.approx(-cfg.termination_penalty), (name, r)
    else:
        assert r["return"] <= 0.5 * reference_fast["return"], (name, r)


@pytest.mark.parametrize("name", ["leave (up)", "leave (side)"])
def test_running_into_the_edge_that_stops_scores_below_the_reference(reference_fast, name):
    """``workspace_edge = "stop"`` (the campaign's): leaving is held at the edge instead of ended;
    holding there, above the plate or beside the patch, cleans nothing and scores 0."""
    env = gym.make(ENV_ID, max_episode_steps=QUICK_STEPS, workspace_edge="stop")
    try:
        r = episode(env, make_probe(name, env), 0, HIGH_PLATE)
    finally:
        env.close()
    assert r["termination"] is None and r["coverage"] == 0.0 and r["return"] == 0.0, (name, r)
    assert r["return"] < reference_fast["return"], (name, r, reference_fast)


def test_the_reference_never_meets_the_edge(reference_fast):
    """The reference circle stays inside the campaign's workspace (its floor 0.5 mm below the
    reference's press): with ``workspace_edge = "stop"`` there its episode is the same bit for
    bit (so its rows do not depend on the setting)."""
    ws = load_campaign("configs/agents/campaign.toml")["env_kwargs"]
    env = gym.make(
        ENV_ID,
        max_episode_steps=QUICK_STEPS,
        workspace_edge=ws["workspace_edge"],
        workspace_height=tuple(ws["workspace_height"]),
    )
    try:
        r = episode(env, ReferencePolicy.for_env(env), 0, HIGH_PLATE)
    finally:
        env.close()
    assert r == reference_fast


def test_pressing_hard_scores_below_the_reference(fast_env, reference_fast):
    """Pressing down to the workspace floor and holding: above the limit, below the reference."""
    r = episode(fast_env, make_probe("press hard", fast_env), 0, HIGH_PLATE)
    assert r["time_above"] > 0.0, r
    assert r["return"] < 0.0 < reference_fast["return"], (r, reference_fast)


@pytest.mark.slow  # 150 random steps of the default brush
def test_random_actions_score_below_the_reference(fast_env, reference_fast):
    r = episode(fast_env, make_probe("random", fast_env, seed=0), 0, HIGH_PLATE)
    assert r["return"] < reference_fast["return"], (r, reference_fast)


@pytest.mark.slow  # two default-brush episodes of the full chain at "balanced" (~1 min)
def test_reference_within_limits_and_static_press_below_it_at_balanced():
    # QUICK_STEPS: every force event of the episode (contact, press, break-away) and half a turn;
    # the deepest press (the highest plate), as the quick tests at ``fast``
    env = gym.make(ENV_ID, fidelity="balanced", max_episode_steps=QUICK_STEPS)
    try:
        limit = env.unwrapped.config.total_force_limit
        ref = episode(env, ReferencePolicy.for_env(env), 0, HIGH_PLATE)
        assert ref["termination"] is None and ref["time_above"] == 0.0, ref
        assert ref["peak"] < limit and ref["return"] > 0.0, ref
        static = episode(env, ReferencePolicy.for_env(env, press="static"), 0, HIGH_PLATE)
        assert static["time_above"] > 0.0 and static["return"] < ref["return"], (static, ref)
    finally:
        env.close()


@pytest.fixture(scope="module")
def tooth_row():
    """(env, the scrub reference's episode on the highest row): ToothRow-v0 at its defaults,
    QUICK_STEPS long (the approach, the press and the first strokes)."""
    env = gym.make("brush_env/ToothRow-v0", max_episode_steps=QUICK_STEPS)
    yield env, episode(env, ReferencePolicy.for_env(env), 0, HIGH_PLATE)
    env.close()


@pytest.mark.slow  # ToothRow-v0 episodes of the default brush on the SDF crowns (~10 s each)
def test_tooth_row_scrub_stays_within_the_limits_with_a_positive_return(tooth_row):
    env, ref = tooth_row
    cfg = env.unwrapped.config
    assert ref["termination"] is None and ref["time_above"] == 0.0, ref
    assert ref["peak"] < cfg.total_force_limit and ref["return"] > 0.0, ref


@pytest.mark.slow  # ToothRow-v0 episodes of the default brush on the SDF crowns (~10 s each)
@pytest.mark.parametrize("name", ["nothing", "hover", "leave (up)", "press hard"])
def test_tooth_row_exploits_score_below_the_scrub(tooth_row, name):
    env, ref = tooth_row
    r = episode(env, make_probe(name, env), 0, HIGH_PLATE)
    assert r["return"] < ref["return"], (name, r, ref)


def test_probe_names_are_checked(fast_env):
    with pytest.raises(ValueError, match="probe = 'idle' is unknown: must be one of"):
        make_probe("idle", fast_env)
    assert np.all(make_probe("nothing", fast_env).predict(None)[0] == 0.0)
