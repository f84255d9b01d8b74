"""BrushEnv behaviour: determinism, bounds, reward terms, episode end, actions, config errors."""

import math

import gymnasium as gym
import numpy as np
import pytest

from brush_env.engine import ConfigError, SimulationDivergence
from brush_env.envs import BrushEnv
from brush_env.envs.flat_plate import REWARD_TERMS

from .conftest import ENV_ID, NO_CONTACT, TINY

ZERO = np.zeros(6, np.float32)
#: the full chain (level "coarse"), whose env step is frame_skip calls of Simulator.step: the
#: tests that recompute or inject per engine step (the default level "fast" rolls an env step out
#: in one compiled call: its protective stop is checked at the end of this module)
STEPWISE = {"fidelity": "coarse"}


def _stepwise(sim):
    """The full chain's rollout step by step through ``Simulator.step`` (instead of one
    ``follow`` call; tests/engine/test_follow.py: the same bits), so that a wrapped ``step``
    sees, or fakes, every engine step."""
    sim.bristles.follow = None


def _actions(n, dim=6, seed=0, z_bias=0.0):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-1, 1, (n, dim)).astype(np.float32)
    a[:, 2] = np.clip(a[:, 2] + z_bias, -1, 1)
    return a


def _rollout(env, seed, actions, options=None):
    obs, info = env.reset(seed=seed, options=options)
    out = [(obs, 0.0, False, False, info)]
    for a in actions:
        step = env.step(a)
        out.append(step)
        if step[2] or step[3]:
            break
    return out


# ---------------------------------------------------------------- determinism
def test_seeded_episode_is_bit_for_bit_reproducible(make_env):
    acts = _actions(25, z_bias=-0.6)  # presses towards the plate: contact if the engine has it
    a = _rollout(make_env(), 7, acts)
    b = _rollout(make_env(), 7, acts)
    env = make_env()
    _rollout(env, 3, acts[:5])  # a different episode first: reset must clear everything
    c = _rollout(env, 7, acts)
    for run in (b, c):
        assert len(run) == len(a)
        for (o1, r1, t1, u1, i1), (o2, r2, t2, u2, i2) in zip(a, run, strict=True):
            assert o1.tobytes() == o2.tobytes()
            assert r1 == r2 and t1 == t2 and u1 == u2
            assert i1.get("reward_terms") == i2.get("reward_terms")
            assert np.array_equal(i1["tcp_position"], i2["tcp_position"])


def test_seeds_randomise_start_pose_and_plate_offset_within_ranges(make_env):
    env = make_env()
    cfg = env.unwrapped.config
    z_t = env.unwrapped.touch_height
    starts, offsets, yaws = [], [], []
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        starts.append(info["tcp_position"])
        offsets.append(info["plate_offset"])
        _, R = env.unwrapped.layout.tcp_pose(obs)
        yaws.append(math.degrees(math.atan2(R[1, 0], R[0, 0])))
    starts, offsets = np.array(starts), np.array(offsets)
    assert len({tuple(s) for s in starts}) == 20
    assert np.all(np.abs(starts[:, :2] - cfg.start_center) <= cfg.start_xy_range)
    h = starts[:, 2] - z_t
    assert np.all((h >= cfg.start_height[0]) & (h <= cfg.start_height[1]))
    assert np.all(np.abs(offsets) <= np.array(cfg.plate_offset_range))
    assert np.all(np.abs(yaws) <= cfg.start_yaw_range_deg + 1e-4)


# ---------------------------------------------------------------- bounds, rewards
@pytest.mark.parametrize("mode", ["box", "dict"])
def test_observations_within_bounds_over_random_episode(make_env, mode):
    env = make_env(observation_mode=mode, max_episode_steps=40)
    space = env.observation_space
    for seed in (0, 1):
        for obs, *_ in _rollout(env, seed, _actions(40, seed=seed, z_bias=-0.3)):
            assert space.contains(obs)
            values = obs.values() if mode == "dict" else [obs]
            assert all(v.dtype == np.float32 and np.all(np.isfinite(v)) for v in values)


class _Recorder:
    """Wraps the engine's step and keeps a copy of the outputs the reward is defined on."""

    def __init__(self, sim):
        _stepwise(sim)
        self.step, self.rows = sim.step, []
        sim.step = self

    def __call__(self, p, R):
        out = self.step(p, R)
        shaft = out.extra.get("shaft_normal_force")
        self.rows.append(
            (
                out.tip_normal_force.copy(),
                out.tip_in_contact.copy(),
                out.tip_contact_point[:, :2].copy(),
                0.0 if shaft is None else float(shaft.sum()),
            )
        )
        return out


def _segment_distance(q, a, b):
    """Distances of points q (n, 2) to the segment [a, b]."""
    d = b - a
    t = np.clip((q - a) @ d / max(float(d @ d), 1e-300), 0.0, 1.0)
    return np.linalg.norm(q - (a + t[:, None] * d), axis=1)


@pytest.mark.slow  # a whole episode, recomputed (~4 s)
def test_reward_terms_recomputed_from_the_engine_outputs(make_env):
    """Each reward term against its definition (docs/env.md "Reward"), recomputed here from the
    engine's per-step outputs (tip normal forces, contact flags, contact points): the force
    integrals as sums over engine steps, the coverage term from the cells within clean_radius of
    the effective contact points (bounded below by the points themselves and the segment shrunk
    by the quarter-cell sampling tolerance, above by the swept segments)."""
    # non-default weights and limits (they must come from the config); the tiny brush's total is
    # 0.1-0.7 N, its tips carry up to ~0.15 N (mid element), so both limits are crossed
    kw = dict(
        total_force_limit=0.3,
        tip_force_limit=0.1,
        tip_force_window=(0.01, 0.1),
        coverage_weight=50.0,
        tip_force_weight=90.0,
        total_force_weight=7.0,
        termination_penalty=3.0,
        max_episode_steps=40,
    )
    env = make_env(**kw, **STEPWISE)
    u = env.unwrapped
    cfg = u.config
    lo, hi = cfg.tip_force_window
    dte, r = cfg.engine_dt, cfg.clean_radius
    n = int(round(cfg.patch_size / cfg.cell_size))
    c = cfg.patch_size / n
    centres = -cfg.patch_size / 2 + (np.arange(n) + 0.5) * c
    cx, cy = np.meshgrid(centres, centres)  # cleaned[i, j]: x = centres[j], y = centres[i]
    q = np.stack([cx.ravel(), cy.ravel()], axis=1)
    seen = dict.fromkeys(REWARD_TERMS, False)
    for seed in (0, 1, 2):
        rec = _Recorder(u.sim)
        env.reset(seed=seed)
        lower, upper = np.zeros(n * n, bool), np.zeros(n * n, bool)
        prev_eff, prev_pt, cleaned_before = np.zeros(u.n_bristles, bool), None, 0
        for a in _actions(40, seed=seed, z_bias=-0.5):
            k0 = len(rec.rows)
            _, reward, term, trunc, info = env.step(a)
            total_int = tip_int = 0.0
            for f, touching, pt, shaft in rec.rows[k0:]:
                # the total normal force is every eq 6 contact's: the tips' and the shafts'
                total_int += dte * max(0.0, f.sum() + shaft - cfg.total_force_limit)
                tip_int += dte * np.maximum(f - cfg.tip_force_limit, 0.0).sum()
                eff = touching & (f >= lo) & (f <= hi)
                for i in np.flatnonzero(eff):
                    start = prev_pt[i] if prev_eff[i] else pt[i]
                    lower |= np.linalg.norm(q - pt[i], axis=1) <= r
                    dist = _segment_distance(q, start, pt[i])
                    lower |= dist <= r - c / 4
                    upper |= dist <= r
                prev_eff, prev_pt = eff, pt
            terms = info["reward_terms"]
            assert tuple(terms) == REWARD_TERMS
            assert terms["total_force"] == pytest.approx(
                -cfg.total_force_weight * total_int, rel=1e-12, abs=1e-15
            )
            assert terms["tip_force"] == pytest.approx(
                -cfg.tip_force_weight * tip_int, rel=1e-12, abs=1e-15
            )
            assert terms["termination"] == (-cfg.termination_penalty if term else 0.0)
            new = terms["coverage"] * n * n / cfg.coverage_weight
            assert new == pytest.approx(round(new), abs=1e-9)  # a whole number of cells
            cleaned = u.coverage.cleaned.ravel()
            assert np.all(cleaned[lower]) and not np.any(cleaned & ~upper)
            assert round(new) == cleaned.sum() - cleaned_before
            cleaned_before = cleaned.sum()
            assert reward == pytest.approx(sum(terms.values()), abs=1e-12)
            for key, value in terms.items():
                seen[key] |= value != 0.0
            if term or trunc:
                break
    assert all(seen.values()), seen  # every term was exercised


# ---------------------------------------------------------------- kinematics of the actions
def test_twist_is_integrated_exactly(make_env):
    env = make_env(max_episode_steps=50)
    u = env.unwrapped
    obs, info = env.reset(seed=0, options={**NO_CONTACT, "yaw_deg": 0.0})
    p0 = info["tcp_position"].copy()
    a = np.array([0.4, -0.2, 0.5, 0.0, 0.0, 0.3], np.float32)
    n = 10
    for _ in range(n):
        obs, _, term, _, info = env.step(a)
        assert not term
    v = a[:3].astype(float) * np.array(u.config.max_linear_speed)
    assert np.allclose(info["tcp_position"], p0 + v * u.dt * n, atol=1e-9)
    _, R = u.layout.tcp_pose(obs)
    yaw = math.atan2(R[1, 0], R[0, 0])
    assert yaw == pytest.approx(0.3 * u.config.max_angular_speed[2] * u.dt * n, abs=1e-5)
    assert np.allclose(u.layout.block(obs, "tcp_twist"), a, atol=1e-6)


def test_translational_mode_keeps_orientation(make_env):
    env = make_env(action_mode="3d")
    assert env.action_space.shape == (3,)
    obs0, _ = env.reset(seed=4, options=NO_CONTACT)
    for _ in range(5):
        obs, *_ = env.step(np.array([0.5, 0.5, 0.2], np.float32))
    lay = env.unwrapped.layout
    assert np.array_equal(lay.block(obs, "tcp_orientation"), lay.block(obs0, "tcp_orientation"))


# ---------------------------------------------------------------- bad actions, API misuse
def test_bad_actions_raise_with_shape_and_value(make_env):
    env = make_env()
    u = env.unwrapped
    with pytest.raises(RuntimeError, match="reset"):
        u.step(ZERO)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(5,\).*\(6,\)"):
        u.step(np.zeros(5, np.float32))
    with pytest.raises(ValueError, match="not finite"):
        u.step(np.array([0, np.nan, 0, 0, 0, 0], np.float32))
    with pytest.raises(ValueError, match="not finite"):
        u.step(np.array([0, 0, np.inf, 0, 0, 0]))
    with pytest.raises(ValueError, match="not real numbers"):
        u.step("up")
    # complex, boolean and None actions are refused, not cast (issue 15)
    with pytest.raises(ValueError, match=r"not real numbers \(dtype complex128\)"):
        u.step(np.array([0.1 + 1j, 0, 0, 0, 0, 0]))
    with pytest.raises(ValueError, match=r"not real numbers \(dtype bool\)"):
        u.step(np.array([True, False, False, False, False, False]))
    with pytest.raises(ValueError, match=r"action = None is not real numbers \(None\)"):
        u.step(None)
    # finite values outside [-1, 1] are clipped, as the docs say
    _, _, _, _, info = u.step(np.array([5.0, 0, 0, 0, 0, 0]))
    obs, *_ = u.step(ZERO)
    assert u.layout.block(obs, "tcp_twist")[0] == 0.0


def test_reset_options_are_validated(make_env):
    env = make_env()
    with pytest.raises(ValueError, match="unknown"):
        env.reset(seed=0, options={"tcp_pos": [0, 0, 12]})
    with pytest.raises(ValueError, match="plate_offset"):
        env.reset(seed=0, options={"plate_offset": [0, 0]})
    _, info = env.reset(
        seed=0, options={"tcp_position": [1.0, 2.0, 12.0], "plate_offset": [0.0, 0.0, 0.0]}
    )
    assert np.allclose(info["tcp_position"], [1.0, 2.0, 12.0])


# ---------------------------------------------------------------- episode end
def test_leaving_the_workspace_terminates(make_env):
    env = make_env()
    env.reset(seed=0, options=NO_CONTACT)
    for _ in range(500):
        _, r, term, trunc, info = env.step(np.array([0, 0, 1, 0, 0, 0], np.float32))
        if term:
            break
    assert term and not trunc and info["termination"] == "workspace"
    height = info["tcp_position"][2] - env.unwrapped.touch_height
    assert height > env.unwrapped.config.workspace_height[1]
    assert info["reward_terms"]["termination"] == -env.unwrapped.config.termination_penalty
    with pytest.raises(RuntimeError, match="terminated"):
        env.unwrapped.step(ZERO)


@pytest.mark.parametrize(
    "axis, sign", [(0, 1.0), (0, -1.0), (1, 1.0), (2, 1.0)], ids=["+x", "-x", "+y", "up"]
)
def test_stop_at_the_workspace_edge_holds_the_tcp_there(make_env, axis, sign):
    """``workspace_edge = "stop"``: full speed towards an edge ends on it, exactly, and the episode
    goes on (a robot's Cartesian limit); the way back in is free."""
    env = make_env(workspace_edge="stop", workspace_xy=6.0, max_episode_steps=1000)
    cfg, u = env.unwrapped.config, env.unwrapped
    _, info = env.reset(seed=0, options=NO_CONTACT)
    p0 = info["tcp_position"].copy()
    edge = cfg.workspace_xy * sign if axis < 2 else cfg.workspace_height[1] + u.touch_height
    a = np.zeros(6, np.float32)
    a[axis] = sign
    for _ in range(40):  # 40 steps of 0.04 s at 20-50 mm/s: 32-80 mm, past every edge
        *_, term, trunc, info = env.step(a)
        assert not term and not trunc, info["termination"]
    p = info["tcp_position"]
    assert p[axis] == pytest.approx(edge, abs=1e-9)
    others = [k for k in range(3) if k != axis]
    assert np.allclose(p[others], p0[others], atol=1e-9)  # the other components held
    *_, info = env.step(-a)
    step = cfg.engine_dt * cfg.frame_skip * cfg.max_linear_speed[axis]
    assert info["tcp_position"][axis] == pytest.approx(edge - sign * step, abs=1e-9)


def test_stop_xy_stops_the_tcp_in_x_and_y_and_ends_below_the_floor(make_env):
    """``workspace_edge = "stop_xy"``: x and y held on their edge, the height range still ends
    the episode (the floor is not a press depth the controller holds)."""
    env = make_env(workspace_edge="stop_xy", workspace_xy=6.0, max_episode_steps=1000)
    cfg = env.unwrapped.config
    env.reset(seed=0, options=NO_CONTACT)
    for _ in range(20):  # 20 steps of 2 mm (50 mm/s, 0.04 s) along +x: held at 6 mm
        *_, term, _, info = env.step(np.array([1, 0, 0, 0, 0, 0], np.float32))
        assert not term, info["termination"]
    assert info["tcp_position"][0] == pytest.approx(cfg.workspace_xy, abs=1e-9)
    for _ in range(100):  # down at 20 mm/s: past the floor (5 mm below touching) within 1 s
        *_, term, _, info = env.step(np.array([0, 0, -1, 0, 0, 0], np.float32))
        if term:
            break
    assert term and info["termination"] == "workspace"
    h = info["tcp_position"][2] - env.unwrapped.touch_height
    assert h < cfg.workspace_height[0]


def test_stop_at_the_workspace_edge_still_ends_on_tilt(make_env):
    env = make_env(workspace_edge="stop", max_tilt_deg=5.0)
    env.reset(seed=0, options=NO_CONTACT)
    for _ in range(50):
        *_, term, _, info = env.step(np.array([0, 0, 0, 1, 0, 0], np.float32))
        if term:
            break
    assert info["termination"] == "workspace"


def test_tilting_too_far_terminates(make_env):
    env = make_env(max_tilt_deg=5.0)
    env.reset(seed=0, options=NO_CONTACT)
    for _ in range(50):
        *_, term, _, info = env.step(np.array([0, 0, 0, 1, 0, 0], np.float32))
        if term:
            break
    assert info["termination"] == "workspace"


class _Faulty:
    """Wraps the engine: raises SimulationDivergence on call ``fail_at`` or scales the tip
    forces from call ``force_from`` on (to exercise the env's logic without real contact)."""

    def __init__(self, sim, fail_at=None, force_from=None, force=1.0):
        self.sim, self.calls = sim, 0
        self.fail_at, self.force_from, self.force = fail_at, force_from, force

    def __call__(self, p, R):
        self.calls += 1
        if self.fail_at is not None and self.calls >= self.fail_at:
            raise SimulationDivergence(self.sim.state.time, [0], "injected for the test")
        out = self._step(p, R)
        if self.force_from is not None and self.calls >= self.force_from:
            out.tip_normal_force = np.full_like(out.tip_normal_force, self.force)
            out.tip_in_contact = np.ones_like(out.tip_in_contact)
            out.tip_contact_point = out.tip_pos.copy()
        return out


def _inject(env, **kw):
    sim = env.unwrapped.sim
    _stepwise(sim)
    fault = _Faulty(sim, **kw)
    fault._step = sim.step
    sim.step = fault
    return fault


def test_divergence_terminates_and_keeps_the_last_converged_state(make_env):
    env = make_env(**STEPWISE)
    u = env.unwrapped
    env.reset(seed=0)
    obs0, *_ = env.step(ZERO)
    state = u.sim.get_state()
    _inject(env, fail_at=4)  # fails on the 4th engine step of the next control step
    obs, r, term, trunc, info = env.step(np.array([0.5, 0, 0, 0, 0, 0], np.float32))
    assert term and not trunc
    assert info["termination"] == "divergence" and "injected" in info["divergence"]
    assert info["reward_terms"]["termination"] == -u.config.termination_penalty
    # three engine steps went through: the state is theirs, consistent with the observation
    assert u.sim.state.steps == state.steps + 3
    assert np.allclose(u.sim.state.tcp_p[1], u._p)
    assert info["time"] == pytest.approx(state.time + 3 * u.config.engine_dt)
    assert env.observation_space.contains(obs)


def test_hard_force_limit_terminates_within_the_step(make_env):
    env = make_env(hard_force_limit=2.0, **STEPWISE)
    env.reset(seed=0)
    fault = _inject(env, force_from=3, force=1.0)  # 4 tips x 1 N = 4 N > 2 N from call 3 on
    _, r, term, _, info = env.step(ZERO)
    assert term and info["termination"] == "force_limit"
    assert fault.calls == 3  # the protective stop ends the control step at once
    assert info["peak_normal_force"] == pytest.approx(4.0)


def test_force_penalties_integrate_the_excess(make_env):
    cfg_kw = dict(
        total_force_limit=1.0,
        total_force_weight=2.0,
        tip_force_limit=0.1,
        tip_force_weight=3.0,
        hard_force_limit=100.0,
        tip_force_window=(0.0, 10.0),
    )
    env = make_env(**cfg_kw, **STEPWISE)
    u = env.unwrapped
    env.reset(seed=0, options={"tcp_position": [0.0, 0.0, 12.0]})
    _inject(env, force_from=1, force=0.5)  # total 2 N, 0.4 N above each tip limit in total
    _, r, term, _, info = env.step(ZERO)
    T = u.dt
    assert not term
    assert info["reward_terms"]["total_force"] == pytest.approx(-2.0 * (2.0 - 1.0) * T)
    assert info["reward_terms"]["tip_force"] == pytest.approx(-3.0 * 4 * (0.5 - 0.1) * T)
    assert info["time_above_force_limit"] == pytest.approx(T)
    assert info["reward_terms"]["coverage"] > 0.0  # effective tips clean under themselves
    assert r == pytest.approx(sum(info["reward_terms"].values()))


# ---------------------------------------------------------------- config validation
@pytest.mark.parametrize(
    "kw,match",
    [
        ({"frame_skip": 0}, r"frame_skip = 0 is out of range: must be in \[1, 1000\]"),
        ({"engine_dt": -1e-3}, r"engine_dt = -0.001 is out of range: must be in \(0, 0.02\]"),
        ({"action_mode": "7d"}, r"action_mode = '7d' is not allowed: must be one of '6d', '3d'"),
        ({"max_linear_speed": [10, 10]}, r"max_linear_speed = \[10, 10\].*list of 3 numbers"),
        ({"tip_force_window": [0.3, 0.1]}, r"tip_force_window = \[0.3, 0.1\] is invalid"),
        ({"frame_skp": 3}, r"unknown env override 'frame_skp'; did you mean frame_skip"),
        ({"gravity": 1}, r"gravity = 1 has the wrong type"),
        ({"start_height": [0.2, 1.0]}, r"plate_offset_range\[2\] = 0.5 is out of range"),
        ({"brush": "no_such_brush"}, r"no_such_brush"),
        (
            {"tip_tip": "yes"},
            r"tip_tip = 'yes' is not allowed: must be one of 'scene', 'on', 'off'",
        ),
    ],
)
def test_config_errors_name_parameter_value_and_range(kw, match):
    with pytest.raises(ConfigError, match=match):
        gym.make(ENV_ID, **kw)


def test_tip_tip_option_switches_the_scenes_pair_list(make_env):
    """flat_plate.toml has tip-tip contact on: "scene" and "on" keep the pairs its geometry can
    bring together (all 6 of the 2 x 2 tiny brush, whose roots are 1.6-2.7 mm apart against a
    reach of 2 x (0.6 x 10 + 0.44) mm), "off" keeps none."""
    pairs = {o: make_env(tip_tip=o).unwrapped.sim.n_tip_pairs for o in ("scene", "on", "off")}
    assert pairs == {"scene": 6, "on": 6, "off": 0}


def test_bad_render_mode_and_config_file(tmp_path):
    with pytest.raises(ValueError, match="render_mode = 'video'"):
        BrushEnv(render_mode="video", **TINY)
    bad = tmp_path / "bad.toml"
    bad.write_text("[engine]\nframe_skip = 4\n[reward]\nframe_skip = 5\n")
    with pytest.raises(ConfigError, match=r"'frame_skip' is in section \[reward\].*\[engine\]"):
        BrushEnv(config=bad)
    bad.write_text("[physics]\nframe_skip = 4\n")
    with pytest.raises(ConfigError, match="unknown section .*'physics'"):
        BrushEnv(config=bad)
    good = tmp_path / "good.toml"
    good.write_text('[engine]\nbrush = "tiny_env"\nframe_skip = 4\n')
    assert BrushEnv(config=good).dt == pytest.approx(0.016)


def test_hard_force_limit_stops_the_compiled_rollout_at_the_step_that_crosses_it(make_env):
    """At the default level ``fast`` an env step is one compiled ``Simulator.rollout``: pressing
    down, it stops at the first engine step whose total tip normal force exceeds
    ``hard_force_limit`` (the robot's protective stop), not at the control step's end.  The same
    engine steps replayed from the saved state without a limit: the steps before it are at or
    below the limit, the last one carries the force the info reports."""
    env = make_env(hard_force_limit=0.3)
    u = env.unwrapped
    env.reset(seed=0)
    down = np.array([0, 0, -1, 0, 0, 0], np.float32)  # 20 mm/s down (max_linear_speed[2])
    for _ in range(20):
        state = u.sim.get_state()
        _, _, term, _, info = env.step(down)
        if term:
            break
    assert term and info["termination"] == "force_limit"
    done = u.sim.state.steps - state.steps
    assert 1 <= done < u.config.frame_skip  # stopped inside the control step
    u.sim.set_state(state)
    ro = u.sim.rollout(u._v, u._w, done)  # the same engine steps, no limit
    total = ro.record.fn[: ro.done].sum(axis=1)
    assert ro.done == done and np.all(total[:-1] <= 0.3) and total[-1] > 0.3
    assert info["peak_normal_force"] == pytest.approx(total[-1], rel=1e-12)


def test_force_guard_backs_off_after_the_step_that_crosses_it(make_env):
    """``force_guard``: pressing down, the control step goes on after the first engine step whose
    total normal force exceeds the guard with the TCP backing off (up at max_linear_speed[2], a
    force-limited robot retracting the tool), and the episode goes on.  The same engine steps
    replayed from the saved state, moving down until that step and up after it, give the same
    forces, and every step before it is at or below the guard."""
    env = make_env(force_guard=0.3)
    u = env.unwrapped
    env.reset(seed=0)
    down = np.array([0, 0, -1, 0, 0, 0], np.float32)  # 20 mm/s down (max_linear_speed[2])
    for _ in range(20):
        state, p0 = u.sim.get_state(), u._p.copy()
        _, _, term, _, info = env.step(down)
        assert not term
        if info["force_guard"]:
            break
    assert info["force_guard"]
    n, step = u.config.frame_skip, 20.0 * u.config.engine_dt  # [mm] per engine step
    assert u.sim.state.steps - state.steps == n  # the whole control step ran
    # down for `moved` engine steps, up for the rest: p0 - (moved - (n - moved)) step
    moved = int(round(((p0[2] - u._p[2]) / step + n) / 2))
    assert 1 <= moved < n
    assert p0[2] - u._p[2] == pytest.approx((2 * moved - n) * step, abs=1e-9)
    u.sim.set_state(state)
    ro = u.sim.rollout(np.array([0.0, 0.0, -20.0]), np.zeros(3), moved)
    total = ro.record.fn[:moved].sum(axis=1)
    assert np.all(total[:-1] <= 0.3) and total[-1] > 0.3  # it crossed at the last step down
    back = u.sim.rollout(np.array([0.0, 0.0, 20.0]), np.zeros(3), n - moved)
    replay = np.concatenate([total, back.record.fn[: n - moved].sum(axis=1)])
    assert info["peak_normal_force"] == pytest.approx(replay.max(), rel=1e-12)
    # the next action moves it as commanded again: up, by a full control step
    p1 = u._p.copy()
    _, _, _, _, info = env.step(-down)
    assert not info["force_guard"]
    assert u._p[2] - p1[2] == pytest.approx(step * n, rel=1e-9)


def test_force_guard_changes_nothing_below_it(make_env):
    """An episode whose force never reaches the guard is the same bit for bit with it."""
    out = []
    for guard in (0.0, 50.0 - 1e-9, 14.0):
        env = make_env(force_guard=guard, hard_force_limit=50.0)
        env.reset(seed=3)
        rows = []
        for a in _actions(30, seed=3, z_bias=-0.3):
            obs, r, term, _, info = env.step(a)
            rows.append(np.concatenate([obs, [r, info["peak_normal_force"]]]))
            assert not info["force_guard"]
            if term:
                break
        out.append(np.array(rows))
    assert out[0].shape == out[1].shape == out[2].shape
    assert np.array_equal(out[0], out[1]) and np.array_equal(out[0], out[2])
