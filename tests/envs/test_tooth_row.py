"""ToothRow-v0: coverage on the crowns by region and tooth, the gum-force term, the scrub
reference policy, determinism and rendering (the checkers run in test_api.py over every id)."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

from agents.reference import ReferencePolicy
from brush_env.coverage import SurfaceCoverage
from brush_env.geometry.teeth import BUCCAL, INTERPROXIMAL, LINGUAL, OCCLUSAL

ID = "brush_env/ToothRow-v0"
TINY = {"brush": "tiny_env"}


def test_surface_coverage_cleans_exactly_the_samples_within_the_radius_of_a_segment():
    """A flat 0.1 mm sample lattice; a stroke from (-2, 0) to (2, 0) with radius 0.5 cleans the
    samples within 0.5 mm of that segment (a stadium of area 4 x 1 + pi 0.25) and no other."""
    g = np.arange(-4.0, 4.0001, 0.1) + 0.0137  # no sample exactly on the stadium's edge
    X, Y = np.meshgrid(g, g)
    pts = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    n = len(pts)
    region = np.where(pts[:, 1] > 0, BUCCAL, OCCLUSAL)
    cov = SurfaceCoverage(pts, np.full(n, 0.01), region, np.zeros(n, int), ["T"], 0.5, 4)
    new = cov.stamp(np.array([[-2.0, 0.0, 0.0]]), np.array([[2.0, 0.0, 0.0]]))
    d = np.where(
        np.abs(pts[:, 0]) <= 2.0, np.abs(pts[:, 1]), np.hypot(np.abs(pts[:, 0]) - 2.0, pts[:, 1])
    )
    np.testing.assert_array_equal(cov.cleaned, d <= 0.5)
    assert new == pytest.approx(0.01 * np.sum(d <= 0.5))
    assert new == pytest.approx(4.0 + np.pi * 0.25, rel=0.05)  # the stadium's area
    assert cov.stamp(np.array([[-2.0, 0.0, 0.0]]), np.array([[2.0, 0.0, 0.0]])) == 0.0


def test_surface_coverage_tallies_are_the_cleaned_samples_areas():
    """``coarse``, ``by_region`` and ``by_tooth`` (kept as ``stamp`` cleans) equal their
    definitions over the cleaned samples -- area cleaned over area, per block of the buccal view
    and per tooth of the reachable samples, per region of all -- after 40 random strokes, and
    are 0 again after ``reset``."""
    rng = np.random.default_rng(5)
    n = 4000
    pts = np.column_stack([rng.uniform(-6, 6, n), rng.uniform(-3, 3, n), rng.uniform(-1, 1, n)])
    region = rng.integers(0, 4, n)  # BUCCAL .. LINGUAL (lingual: not reachable)
    tooth = rng.integers(0, 3, n)
    areas = rng.uniform(0.005, 0.02, n)
    cov = SurfaceCoverage(pts, areas, region, tooth, ["A", "B", "C"], 0.5, 4)
    for _ in range(40):
        a = rng.uniform([-6, -3, -1], [6, 3, 1], (3, 3))
        cov.stamp(a, a + rng.normal(size=(3, 3)))
    c, r = cov.cleaned, cov.reach
    assert 0 < c.sum() < n
    lo, hi = pts[:, :2].min(axis=0), pts[:, :2].max(axis=0)  # the buccal view's 4 x 4 blocks
    ij = np.clip(((pts[:, :2] - lo) / (hi - lo + 1e-9) * 4).astype(int), 0, 3)
    blk = ij[:, 1] * 4 + ij[:, 0]
    w = np.where(c & r, areas, 0.0)
    blocks = np.bincount(blk, w, 16) / np.bincount(blk, np.where(r, areas, 0.0), 16)
    np.testing.assert_allclose(cov.coarse().ravel(), blocks, rtol=1e-12)
    for k, name in enumerate(cov.region_names):
        sel = region == k
        assert cov.by_region()[name] == pytest.approx(areas[sel & c].sum() / areas[sel].sum())
    for k, name in enumerate(["A", "B", "C"]):
        sel = (tooth == k) & r
        assert cov.by_tooth()[name] == pytest.approx(areas[sel & c].sum() / areas[sel].sum())
    cov.reset()
    assert not cov.coarse().any() and not any(cov.by_region().values())


@pytest.fixture(scope="module")
def reference_episode():
    env = gym.make(ID, **TINY, max_episode_steps=120)
    obs, info0 = env.reset(seed=3)
    pol = ReferencePolicy.for_env(env)
    infos, ret = [], 0.0
    done = False
    while not done:
        a, _ = pol.predict(obs)
        obs, r, term, trunc, info = env.step(a)
        ret += r
        infos.append(info)
        done = term or trunc
    yield env, info0, infos, ret
    env.close()


def test_reference_scrub_cleans_buccal_surfaces_and_never_the_lingual(reference_episode):
    env, info0, infos, ret = reference_episode
    last = infos[-1]
    assert last["termination"] is None
    assert info0["coverage"] == 0.0
    reg = last["coverage_regions"]
    assert reg["buccal"] > 0.05 and reg["lingual"] == 0.0
    # the coverage is the cleaned share of the reachable (buccal + occlusal + interproximal) area
    cov = env.unwrapped.coverage
    reach = np.isin(cov.region, [BUCCAL, OCCLUSAL, INTERPROXIMAL])
    area = cov.areas
    assert last["coverage"] == pytest.approx(area[cov.cleaned & reach].sum() / area[reach].sum())
    assert not cov.cleaned[cov.region == LINGUAL].any()
    # the coverage terms sum to coverage_weight x the coverage reached
    total = sum(i["reward_terms"]["coverage"] for i in infos)
    assert total == pytest.approx(env.unwrapped.config.coverage_weight * last["coverage"])
    assert set(last["reward_terms"]) == {
        "coverage",
        "total_force",
        "tip_force",
        "gum_force",
        "termination",
    }
    assert sum(last["reward_terms"].values()) == pytest.approx(
        ret - sum(sum(i["reward_terms"].values()) for i in infos[:-1])
    )


def _press_on_gum(**kw):
    """Hold the tiny brush pressed 2 mm at the gum line (TCP y = -1.5 mm) for 25 steps."""
    env = gym.make(ID, **TINY, **kw)
    u = env.unwrapped
    obs, _ = env.reset(
        seed=0,
        options={
            "tcp_position": [0.0, -1.5, u.touch_height + 0.5],
            "plate_offset": [0.0, 0.0, 0.0],
        },
    )
    infos = []
    for k in range(25):
        a = np.zeros(env.action_space.shape, np.float32)
        a[2] = -0.15 if k < 16 else 0.0  # 0.12 mm per step down: 2.5 mm
        obs, r, term, trunc, info = env.step(a)
        infos.append(info)
    env.close()
    return infos


def test_gum_force_is_penalised_above_its_limit_only():
    hurt = _press_on_gum(gum_force_limit=0.01)
    assert max(i["peak_gum_force"] for i in hurt) > 0.05
    assert min(i["reward_terms"]["gum_force"] for i in hurt) < 0.0
    soft = _press_on_gum(gum_force_limit=100.0)
    assert all(i["reward_terms"]["gum_force"] == 0.0 for i in soft)
    # the same motion: the gum forces are the same, only the limit differs
    assert [i["gum_force"] for i in hurt] == [i["gum_force"] for i in soft]


def test_same_seed_and_actions_give_bit_identical_episodes():
    runs = []
    for _ in range(2):
        env = gym.make(ID, **TINY)
        env.action_space.seed(5)
        obs, _ = env.reset(seed=11)
        seq = [obs]
        for _ in range(15):
            a = env.action_space.sample()
            a[2] = -abs(a[2])
            obs, r, *_ = env.step(a)
            seq.append(obs)
            seq.append(np.array([r]))
        runs.append(np.concatenate([np.ravel(x) for x in seq]))
        env.close()
    np.testing.assert_array_equal(runs[0], runs[1])


def test_render_rgb_array_frame():
    env = gym.make(ID, **TINY, render_mode="rgb_array", render_height=128)
    env.reset(seed=0)
    frame = env.render()
    assert frame.shape == (128, 256, 3) and frame.dtype == np.uint8
    assert frame.std() > 5  # something is drawn
    env.close()


def test_flat_plate_scene_is_refused_with_the_reason():
    from brush_env.engine import ConfigError

    with pytest.raises(ConfigError, match="no tooth surface"):
        gym.make(ID, **TINY, scene="flat_plate")
