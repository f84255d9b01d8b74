"""The reduced model does not hold a pressed bristle on the straight saddle.

A column of rigid links pressed along its axis holds any load where it is straight: the
equilibrium is a saddle, and past the buckling load the full chain (and the rod) bends away.
``prb_kernels.solve_bristle`` steps off it along the negative curvature, at most MAX_ESCAPES
times per bristle-step.  With 4, a trained policy's episode (the shipped PPO model, seed 1000)
ended at step 206 on the hard force limit: five bristles whose tips were stuck on the plate,
bent in an S, were straightened within one 4 ms step when the TCP turned from rising to
descending at 40 mm/s, and each held 3.58 N on its tip (0.077 mm into the plate; 34 N in all),
where the full model's peak over the whole episode is 3.6 N (docs/rl.md).  The actions are
stored, so the replay does not depend on the policy.
"""

from __future__ import annotations

from pathlib import Path

import gymnasium as gym
import numpy as np

import brush_env  # noqa: F401  (registers the ids)

ACTIONS = Path(__file__).parents[1] / "data" / "reduced_saddle_actions.npy"


def test_pressed_s_bent_bristles_buckle_instead_of_holding_the_penalty_load():
    env = gym.make(
        "brush_env/FlatPlate-v0", config="flat_plate", fidelity="reduced", action_mode="3d"
    )
    env.reset(seed=1000)
    limit = env.unwrapped.config.hard_force_limit
    peak = 0.0
    for a in np.load(ACTIONS):
        _, _, terminated, truncated, info = env.step(a)
        peak = max(peak, info["peak_normal_force"])
        assert info["termination"] != "force_limit", f"peak {peak:.1f} N"
        if terminated or truncated:
            break
    assert peak < limit / 2  # [N] the full model's peak on this episode is 3.6 N


def test_straight_bristles_are_not_taken_loose_far_past_their_euler_load():
    """The reference circle at `reduced`, seed 1019: at step 51 twenty bristles whose Newton
    ran out were taken at their best iterate, nearly straight with 0.93 N on each tip -- five
    times the fixed-pinned Euler load of the inner type, 19 N for the brush, where `balanced`
    gives 1.5 N on that step.  A straight column of rigid links holds any load along them with
    no residual; ``prb_kernels._take_best`` refuses such an iterate (SADDLE_LOAD).  Bound: no
    tip above 3 x its bristle's Euler load pi^2 E I_min / (0.699 L)^2 (fixed root, pinned tip)
    over the first 55 steps."""
    from agents.reference import ReferencePolicy

    env = gym.make("brush_env/FlatPlate-v0", fidelity="reduced", action_mode="3d")
    obs, _ = env.reset(seed=1019)
    u = env.unwrapped
    brush = u.scene.brush
    euler = np.array(
        [
            np.pi**2 * b.material.E * min(b.section.I_y, b.section.I_z) / (0.699 * b.length) ** 2
            for b in brush.bristles
        ]
    )
    policy = ReferencePolicy.for_env(u)
    worst = 0.0
    for _ in range(55):
        obs, _, terminated, truncated, info = env.step(policy.predict(obs)[0])
        assert info["termination"] != "force_limit", f"{info['peak_normal_force']:.1f} N"
        worst = max(worst, float(np.max(u._last.tip_normal_force / euler)))
        if terminated or truncated:
            break
    assert worst < 3.0


def test_bent_column_far_past_its_euler_load_is_checked_for_stability():
    """The shipped PPO policy at `reduced`, seed 1019 (actions stored): at step 154 nine bristles
    converged bent 0.1 rad at joint 1, just past the straight-saddle window (SADDLE_TURN), with
    up to 1.7 N on a tip -- nine times the inner type's Euler load -- and the brush read 15.5 N,
    ending the episode on the hard limit; the next 4 ms step they had buckled (0.28 N).  A
    converged equilibrium that carries more than SADDLE_LOAD is now checked for stability
    whatever its bend."""
    env = gym.make(
        "brush_env/FlatPlate-v0", config="flat_plate", fidelity="reduced", action_mode="3d"
    )
    env.reset(seed=1019)
    limit = env.unwrapped.config.hard_force_limit
    peak = 0.0
    for a in np.load(Path(__file__).parents[1] / "data" / "reduced_saddle_actions_1019.npy"):
        _, _, terminated, truncated, info = env.step(a)
        peak = max(peak, info["peak_normal_force"])
        assert info["termination"] != "force_limit", f"peak {peak:.1f} N"
        if terminated or truncated:
            break
    assert peak < limit / 2
