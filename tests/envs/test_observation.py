"""ObservationLayout.flat: every block as the env's docstring defines it (scaled, clipped, in
layout order), against the definitions written out here block by block."""

import numpy as np

from brush_env.engine.rotation import expmap
from brush_env.envs.config import EnvConfig
from brush_env.envs.observation import BoxObservation, DictObservation, ObservationLayout


def _physical(rng, nb, m):
    R = expmap(rng.normal(0.0, 1.0, 3))
    p = rng.normal(0.0, 10.0, 3)
    return dict(
        p=p,
        R=R,
        v=rng.uniform(-50, 50, 3),
        w=rng.uniform(-1, 1, 3),
        tip_pos=p + rng.normal(0.0, 8.0, (nb, 3)),
        tip_vel=rng.normal(0.0, 1500.0, (nb, 3)),  # some beyond the velocity block's bounds
        rest_tips=rng.normal(0.0, 8.0, (nb, 3)),
        tip_force=rng.uniform(0.0, 3.0, nb),
        tip_contact=rng.random(nb) < 0.5,
        tcp_force_tcp=rng.normal(0.0, 30.0, 3),
        tcp_moment_tcp=rng.normal(0.0, 500.0, 3),
        p_obs=rng.normal(0.0, 30.0, 3),
        coverage_fraction=0.3,
        coverage_map=rng.random((m, m)),
        time_remaining=0.25,
    )


def _by_definition(lay, cfg, x):
    """The blocks from the docstring's definitions, one by one (float64, then clipped, float32)."""
    rel = x["tip_pos"] - x["p"]
    raw = {
        "tip_deflection": (rel @ x["R"] - x["rest_tips"]) / lay.max_length,
        "tip_velocity": np.array(
            [(vi - x["v"] - np.cross(x["w"], ri)) @ x["R"] for vi, ri in zip(x["tip_vel"], rel)]
        )
        / cfg.tip_velocity_scale,
        "tip_normal_force": x["tip_force"] / cfg.tip_force_limit,
        "tip_contact": x["tip_contact"].astype(float),
        "tcp_force": x["tcp_force_tcp"] / cfg.force_scale,
        "tcp_moment": x["tcp_moment_tcp"] / cfg.moment_scale,
        "tcp_position": (x["p_obs"] - [0.0, 0.0, lay.touch_height]) / lay.position_scale,
        "tcp_orientation": np.r_[x["R"][:, 0], x["R"][:, 1]],
        "tcp_twist": np.r_[x["v"] / lay.v_max, x["w"] / lay.w_max],
        "coverage_fraction": [x["coverage_fraction"]],
        "coverage_map": x["coverage_map"],
        "time_remaining": [x["time_remaining"]],
    }
    return {
        b.name: np.clip(np.asarray(raw[b.name], float).reshape(b.shape), b.low, b.high)
        for b in lay.blocks
    }


def test_flat_observation_is_every_block_by_its_definition():
    rng = np.random.default_rng(11)
    cfg = EnvConfig(coarse_map_size=4)
    lay = ObservationLayout(cfg, 7, 10.0, 10.44)
    clipped = 0
    for _ in range(20):
        x = _physical(rng, 7, 4)
        flat = lay.flat(**x)
        assert flat.dtype == np.float32 and flat.shape == (lay.size,)
        want = _by_definition(lay, cfg, x)
        for name, block in lay.split(flat).items():
            # float32 of the same float64 value, up to the last bits of a reordered sum
            np.testing.assert_allclose(block, want[name], rtol=1e-6, atol=1e-6, err_msg=name)
        clipped += int(np.sum(np.abs(want["tip_velocity"]) == 10.0))
        assert np.all(flat >= lay.low) and np.all(flat <= lay.high)
    assert clipped > 0  # the clip was exercised


def test_box_and_dict_observations_hold_the_same_values():
    rng = np.random.default_rng(2)
    cfg = EnvConfig()
    lay = ObservationLayout(cfg, 40, 10.0, 10.44)
    x = _physical(rng, 40, cfg.coarse_map_size)
    box = BoxObservation(lay).observe(lay.flat(**x))
    d = DictObservation(lay).observe(lay.flat(**x))
    assert BoxObservation(lay).space().contains(box)
    assert DictObservation(lay).space().contains(d)
    for b in lay.blocks:
        assert np.array_equal(d[b.name], lay.block(box, b.name))
