"""``Simulator.follow``: many steps along prescribed poses in one compiled call (chain_rollout).

Reference: ``Simulator.step``, the engine's one-step path, itself pinned against the closed-form
and paper references elsewhere.  The compiled follow runs the same step kernels with no Python
between steps, so it must give the same states, TCP wrenches and tip contacts to the bit --
through a press, stick and slip on the plate with shaft and head contact on, the coupled tip-tip
solve, a divergence (the state restored to the failed step's start, as ``step`` leaves it) and
the stop limits of ``rollout``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from brush_env.engine import SimSettings, SimulationDivergence, Simulator
from brush_env.engine.config import load_brush
from brush_env.engine.scene import load_scene

R_DOWN = np.diag([1.0, -1.0, -1.0])  # bristles pointing down
N_STEPS = 90


def _sim(sweeps: int = 1, dt: float = 1e-3, **kw):
    """The tiny brush over the plate; dt [s] in solver steps of 1 ms (dt 4 ms: four, as the
    envs step)."""
    brush = load_brush("tiny")
    scene = load_scene("flat_plate", brush=brush)
    top = max(b.length for b in brush.bristles) + brush.bristles[0].tip_radius
    sim = Simulator(scene, SimSettings(dt=dt, tip_tip_sweeps=sweeps, max_substep=1e-3, **kw))
    sim.reset(np.array([0.0, 0.0, top + 0.02]), R_DOWN)
    return sim, top


def _poses(top: float, n: int = N_STEPS):
    """Press 0.6 mm at 40 mm/s, then a drag at 40 mm/s with a slow yaw (rotation in the drive)."""
    P = np.zeros((n, 3))
    R = np.zeros((n, 3, 3))
    for k in range(n):
        z = top + 0.02 - min(k + 1, 16) * 0.04
        x = 0.04 * max(k - 25, 0)
        a = 0.002 * max(k - 25, 0)
        c, s = math.cos(a), math.sin(a)
        P[k] = [x, 0.0, z]
        R[k] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ R_DOWN
    return P, R


def _state(sim):
    st = sim.state
    parts = [st.pos, st.rot, st.vel, st.omg, st.ppos, st.prot, st.tcp_p, st.tcp_R, st.hist_ok]
    return np.concatenate([np.asarray(a, float).ravel() for a in parts] + [[st.time, st.steps]])


def _by_steps(sim, P, R):
    """Every pose through step: the rows follow writes, from the StepResults."""
    rows = []
    for k in range(len(P)):
        out = sim.step(P[k], R[k])
        ex = out.extra
        rows.append(
            dict(
                t=out.time,
                FM=np.concatenate([out.tcp_force, out.tcp_moment]),
                iters=out.iterations,
                tips=np.hstack([out.tip_pos, out.tip_vel]),
                fn=out.tip_normal_force,
                ft=out.tip_tangential_force,
                pen=out.tip_penetration,
                slide=out.tip_sliding,
                ftt=ex["tip_tip_force"],
                surf=ex["tip_surface"],
                head=ex["head_clearance"],
                sweeps=ex["sweeps"],
            )
        )
    return rows


@pytest.mark.parametrize("sweeps,dt", [(1, 1e-3), (8, 1e-3), (1, 4e-3), (8, 4e-3)])
def test_follow_is_step_to_the_bit(sweeps, dt):
    sim_a, top = _sim(sweeps, dt)
    sim_b, _ = _sim(sweeps, dt)
    P, R = _poses(top)
    rows = _by_steps(sim_a, P, R)
    run = sim_b.follow(P, R)
    assert run.done == N_STEPS and run.stop is None and run.error is None
    assert np.array_equal(_state(sim_a), _state(sim_b))
    rec = run.record
    touched = 0
    for k, row in enumerate(rows):
        assert rec.t[k] == row["t"]
        assert np.array_equal(rec.FM[k], row["FM"]), k
        assert rec.iters[k] == row["iters"]
        assert rec.sweeps[k, 0] == row["sweeps"]
        for name in ("tips", "fn", "ft", "pen", "ftt", "surf"):
            assert np.array_equal(getattr(rec, name)[k], row[name]), (k, name)
        assert np.array_equal(rec.slide[k].astype(bool), row["slide"])
        # the head's outline carried to the pose: the same points up to the sum's rounding
        assert rec.head[k] == pytest.approx(row["head"], abs=1e-12)
        touched += int(np.count_nonzero(row["fn"]))
    assert touched > N_STEPS  # the run pressed tips onto the plate
    if dt > 1e-3:  # four solver steps per engine step: their peaks and iterations summed
        assert sim_b.settings.substeps == 4
        assert (rec.nsub >= 4 * sim_b.model.n_bristles).all()
    # and the next step after a follow continues as after the steps
    nxt = P[-1] + np.array([0.04, 0.0, 0.0])
    a, b = sim_a.step(nxt, R[-1]), sim_b.step(nxt, R[-1])
    assert np.array_equal(a.tcp_force, b.tcp_force)


def test_follow_in_pieces_is_one_follow():
    sim_a, top = _sim()
    sim_b, _ = _sim()
    P, R = _poses(top)
    whole = sim_a.follow(P, R).record
    parts = [sim_b.follow(P[i : i + 17], R[i : i + 17]).record for i in range(0, N_STEPS, 17)]
    assert np.array_equal(whole.FM, np.concatenate([p.FM for p in parts]))
    assert np.array_equal(_state(sim_a), _state(sim_b))


def test_follow_through_step_fills_the_same_record():
    """The path of models without a compiled follow (``_follow_steps``) fills every field as the
    kernel does."""
    sim_a, top = _sim()
    sim_b, _ = _sim()
    P, R = _poses(top)
    keep = np.full(N_STEPS, -1, np.int64)
    keep[[3, 40, 89]] = [0, 1, 2]
    fast = sim_a.follow(P, R, keep_bodies=[3, 40, 89]).record
    limits = np.array([np.inf, np.inf, -np.inf, 0.1])
    slow = sim_b._follow_steps(P, R, limits, _empty(sim_b, 3), keep)
    for name in fast._fields:
        a, b = getattr(fast, name), getattr(slow.record, name)
        if name == "head":
            np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
        elif name == "shaft_fn":  # numpy's reduceat and the kernel's loop: the same sums
            np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)
        else:
            assert np.array_equal(a, b), name


def _empty(sim, kept=0):
    from brush_env.engine.chain_rollout import make_follow_record

    return make_follow_record(N_STEPS, sim.model.n_bristles, kept, sim.model.n_bodies)


@pytest.mark.parametrize("sweeps", [1, 8])
def test_follow_keeps_the_body_centres_of_the_steps_asked(sweeps):
    """``keep_bodies``: every body's centre after the steps named, as ``State.pos`` is after
    stepping to them one by one (and a follow without it keeps none)."""
    sim_a, top = _sim(sweeps)
    sim_b, _ = _sim(sweeps)
    P, R = _poses(top)
    rows = [0, 16, 17, 60, N_STEPS - 1]
    want = []
    for k in range(N_STEPS):
        sim_a.step(P[k], R[k])
        if k in rows:
            want.append(sim_a.state.pos.copy())
    run = sim_b.follow(P, R, keep_bodies=rows)
    assert run.record.body.shape == (len(rows), sim_b.model.n_bodies, 3)
    assert np.array_equal(run.record.body, np.stack(want))
    assert np.array_equal(_state(sim_a), _state(sim_b))
    assert sim_b.follow(P[-1:], R[-1:]).record.body.shape[0] == 0  # (held at the last pose)


@pytest.mark.parametrize("rows", [[5, 5], [7, 3], [-1], [N_STEPS]])
def test_follow_refuses_bad_kept_steps(rows):
    sim, top = _sim()
    P, R = _poses(top)
    with pytest.raises(ValueError, match="keep_bodies"):
        sim.follow(P, R, keep_bodies=rows)


@pytest.mark.parametrize("dt", [1e-3, 4e-3])
def test_follow_divergence_restores_the_failed_steps_start(dt):
    """One Newton iteration and no halving cannot press the tips: the step that fails leaves the
    state at its start (with solver steps: the engine step's start), in follow as in step."""
    kw = dict(newton_max_iter=1, max_halvings=0)
    sim_a, top = _sim(dt=dt, **kw)
    sim_b, _ = _sim(dt=dt, **kw)
    P, R = _poses(top)
    done = 0
    with pytest.raises(SimulationDivergence) as err:
        for k in range(N_STEPS):
            sim_a.step(P[k], R[k])
            done = k + 1
    run = sim_b.follow(P, R)
    assert run.stop == "divergence" and run.done == done < N_STEPS
    assert run.error.time == err.value.time and run.error.bristles == err.value.bristles
    assert np.array_equal(_state(sim_a), _state(sim_b))
    assert not sim_b.state.jac.key.any()  # the failed step's factors marked stale


def test_follow_stops_at_the_force_limit():
    sim, top = _sim()
    P, R = _poses(top)
    run = sim.follow(P, R, force_stop=0.05)
    rec = run.record
    k = run.done - 1
    assert run.stop == "force_limit"
    assert rec.fn[k].sum() + rec.shaft_fn[k].sum() > 0.05
    assert (rec.fn[:k].sum(axis=1) + rec.shaft_fn[:k].sum(axis=1) <= 0.05).all()
    assert sim.state.steps == run.done


def test_follow_refuses_a_bad_pose_before_moving():
    sim, top = _sim()
    P, R = _poses(top)
    before = _state(sim)
    P[40, 2] = np.nan
    with pytest.raises(ValueError, match="pose 40: tcp_p"):
        sim.follow(P, R)
    P, R = _poses(top)
    P[30:, 0] += 5.0  # a 5 mm jump within one step of 1 ms
    with pytest.raises(ValueError, match="pose 30: .*max_tcp_speed"):
        sim.follow(P, R)
    assert np.array_equal(before, _state(sim))


@pytest.mark.parametrize("dt", [1e-3, 4e-3])
def test_the_chains_rollout_is_its_steps(dt):
    """``Simulator.rollout`` of the full chain (the envs' path) goes through ``follow``: the same
    as stepping the constant twist's poses one by one."""
    from brush_env.engine.rotation import expmap

    sim_a, top = _sim(dt=dt)
    sim_b, _ = _sim(dt=dt)
    v, w = np.array([20.0, 0.0, -40.0]) * (1e-3 / dt), np.array([0.0, 0.0, 0.5])
    n = 30
    ro = sim_a.rollout(v, w, n)
    p, R = sim_b.state.tcp_p[1].copy(), sim_b.state.tcp_R[1].copy()
    dR = expmap(w * dt)
    for k in range(n):
        p, R = p + v * dt, dR @ R
        out = sim_b.step(p, R)
        assert np.array_equal(ro.record.fn[k], out.tip_normal_force)
    assert ro.done == n and ro.stop is None
    assert np.array_equal(ro.record.p[-1], p) and np.array_equal(ro.record.R[-1], R)
    assert np.array_equal(ro.last.tcp_force, out.tcp_force)
    assert ro.last.extra["max_tip_penetration"] == out.extra["max_tip_penetration"]
    assert np.array_equal(_state(sim_a), _state(sim_b))
    assert ro.record.fn[-1].sum() > 0.0  # the tips were pressed
