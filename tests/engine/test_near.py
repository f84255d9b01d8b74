"""The step's near lists of tip-tip partners (engine/near.py): the lists are what their definition
says, every loop that takes them gives what the whole list gives, and a run is the same to the
bit with and without them."""

from __future__ import annotations

import numpy as np
import pytest

from brush_env.engine import near

from .kernel_args import contact_scene, whole_lists


def _all_pairs(nb):
    """Every tip a partner of every other (CSR), as the pair list of a dense brush."""
    ptr, idx = [0], []
    for b in range(nb):
        idx += [j for j in range(nb) if j != b]
        ptr.append(len(idx))
    return np.array(ptr, np.int64), np.array(idx, np.int64)


def _scene(rng, nb=9, spread=1.5):
    tips = np.zeros((nb, 7))
    tips[:, 0:3] = rng.uniform(-spread, spread, (nb, 3))
    tips[:, 3:6] = rng.normal(0.0, 5.0, (nb, 3))
    tips[:, 6] = rng.uniform(0.08, 0.15, nb)  # radii [mm]
    ptr, idx = _all_pairs(nb)
    return contact_scene(tips, ptr, idx)


def test_near_lists_hold_the_partners_within_reach_plus_margin_in_list_order():
    rng = np.random.default_rng(3)
    for _trial in range(20):
        con = _scene(rng)
        nb = con.tips.shape[0]
        tips0 = con.tips[:, 0:6].copy()
        lists = whole_lists(nb, len(con.pair_idx), 0.4)
        near.build(con, lists, tips0)
        assert lists.d[0] == 0.0
        for b in range(nb):
            want = [
                (q, con.pair_idx[q])
                for q in range(con.pair_ptr[b], con.pair_ptr[b + 1])
                if np.linalg.norm(tips0[b, 0:3] - tips0[con.pair_idx[q], 0:3])
                < con.tips[b, 6] + con.tips[con.pair_idx[q], 6] + 0.4
            ]
            k0, k1 = lists.ptr[b], lists.ptr[b + 1]
            assert list(zip(lists.q[k0:k1], lists.idx[k0:k1])) == want


def test_a_negative_margin_builds_no_lists_and_every_loop_takes_the_whole_list():
    con = _scene(np.random.default_rng(4))
    nb = con.tips.shape[0]
    lists = whole_lists(nb, len(con.pair_idx), -1.0)
    near.build(con, lists, con.tips[:, 0:6].copy())
    assert lists.d[0] == np.inf and not lists.ptr.any()
    for b in range(nb):
        assert near.span(con, lists, b, 0.0) == (con.pair_ptr[b], con.pair_ptr[b + 1], False)


def test_a_held_tip_moved_beyond_the_margin_sends_the_loops_to_the_whole_list():
    con = _scene(np.random.default_rng(5))
    nb = con.tips.shape[0]
    tips0 = con.tips[:, 0:6].copy()
    lists = whole_lists(nb, len(con.pair_idx), 0.4)
    near.build(con, lists, tips0)
    assert near.span(con, lists, 0, 4.0 * lists.d[0])[2]
    con.tips[2, 0] += 0.15  # 4 D = 0.6 mm > the margin: the moved-partner test needs all
    near.moved(con, lists, 2)
    assert lists.d[0] == pytest.approx(0.15)
    assert near.span(con, lists, 0, 2.0 * lists.d[0])[2]
    assert not near.span(con, lists, 0, 4.0 * lists.d[0])[2]
    near.close(lists)  # after the step: D = inf, no test fits
    assert not near.span(con, lists, 0, 2.0 * lists.d[0])[2]


def test_lists_are_kept_while_every_tip_stays_near_its_anchor_and_rebuilt_past_it():
    """``build`` at the next step's start: tips within ANCHOR_MOVE x M of where the lists were
    built keep them (D starts at the farthest tip's distance, so every loop's test still
    bounds what is off the lists); one tip past it, or lists never built (NaN anchors),
    rebuild them at the new positions."""
    rng = np.random.default_rng(8)
    margin = 0.4
    con = _scene(rng)
    nb = con.tips.shape[0]
    lists = whole_lists(nb, len(con.pair_idx), margin)
    assert np.isnan(lists.anc).all()
    tips0 = con.tips[:, 0:6].copy()
    near.build(con, lists, tips0)
    assert lists.d[0] == 0.0 and np.array_equal(lists.anc, tips0[:, 0:3])
    built = (lists.ptr.copy(), lists.q.copy(), lists.idx.copy())
    near.close(lists)
    # the next step's start: every tip moved a little, the farthest 0.9 x ANCHOR_MOVE x M
    move = rng.normal(0.0, 1.0, (nb, 3))
    move *= (0.9 * near.ANCHOR_MOVE * margin) / np.linalg.norm(move, axis=1).max()
    tips1 = tips0.copy()
    tips1[:, 0:3] += move
    near.build(con, lists, tips1)
    assert lists.d[0] == pytest.approx(np.linalg.norm(move, axis=1).max(), rel=1e-12)
    assert np.array_equal(lists.anc, tips0[:, 0:3])  # anchors and lists as built
    for a, b in zip(built, (lists.ptr, lists.q, lists.idx)):
        assert np.array_equal(a, b)
    # what the kept lists promise: no partner off them within r_b + r_j + M - 2 D
    for b in range(nb):
        on = set(lists.idx[lists.ptr[b] : lists.ptr[b + 1]])
        for q in range(con.pair_ptr[b], con.pair_ptr[b + 1]):
            j = con.pair_idx[q]
            gap = np.linalg.norm(tips1[b, 0:3] - tips1[j, 0:3]) - con.tips[b, 6] - con.tips[j, 6]
            assert j in on or gap >= margin - 2.0 * lists.d[0]
    # one tip past ANCHOR_MOVE x M: rebuilt where the tips are now
    tips2 = tips1.copy()
    tips2[4, 0] = tips0[4, 0] + 1.1 * near.ANCHOR_MOVE * margin
    near.close(lists)
    near.build(con, lists, tips2)
    assert lists.d[0] == 0.0 and np.array_equal(lists.anc, tips2[:, 0:3])
    fresh = whole_lists(nb, len(con.pair_idx), margin)
    near.build(con, fresh, tips2)
    for a, b in zip((fresh.ptr, fresh.q, fresh.idx), (lists.ptr, lists.q, lists.idx)):
        assert np.array_equal(a, b)


def test_partner_move_over_the_near_lists_is_the_whole_lists_to_the_bit():
    """``sweeps._partner_move`` with the near lists (held tips moved by less than a quarter of
    the margin since the step's start, the partners seen where they were at some earlier
    point of the step) against the whole lists: the same double for every bristle."""
    from brush_env.engine.sweeps import _partner_move

    rng = np.random.default_rng(6)
    margin = 0.6
    for _trial in range(30):
        con = _scene(rng, nb=10, spread=1.2)
        nb = con.tips.shape[0]
        tips0 = con.tips[:, 0:6].copy()
        lists = whole_lists(nb, len(con.pair_idx), margin)
        near.build(con, lists, tips0)
        # held tips moved within the step; each bristle saw its partners part of the way there
        step = rng.normal(0.0, 0.03, (nb, 3))
        con.tips[:, 0:3] += step
        for b in range(nb):
            near.moved(con, lists, b)
        frac = rng.uniform(0.0, 1.0, len(con.pair_idx))[:, None]
        used = tips0[con.pair_idx, 0:3] + frac * step[con.pair_idx]
        whole = whole_lists(nb, len(con.pair_idx))
        assert 4.0 * lists.d[0] < margin
        for b in range(nb):
            assert _partner_move(b, con, used, lists) == _partner_move(b, con, used, whole)


def _turn_start(monkeypatch, margin, sweeps):
    """The paper turn's press, hold and first 0.75 s of circle (6 bodies, 1 ms; tips first
    touch each other ~0.32 s into the circle) with the near lists' margin ``margin`` [mm]
    (< 0: off): the follow record (TCP wrench, tips, tip-tip forces, Newton iterations)."""
    import brush_env.engine.chain as chain_module
    from brush_env.bench.contact import press_and_circle
    from brush_env.engine import SimSettings, Simulator, load_scene
    from brush_env.experiments.plan import plate_height

    monkeypatch.setattr(chain_module, "NEAR_MARGIN", margin)
    scene = load_scene("flat_plate")
    sim = Simulator(
        scene, SimSettings(dt=1e-3, max_substep=1e-3, tip_tip_sweeps=sweeps, tip_tip_tol=1e-6)
    )
    assert sim.bristles._ws.sw.near.d[1] == margin
    R0 = np.diag([1.0, -1.0, -1.0])
    traj, starts = press_and_circle(sim.touch_height(R0, plate_height(scene)), 0.5, 0.25)
    times = np.arange(int(round((starts[-1] + 0.75) / 1e-3)) + 1) * 1e-3
    P, R, _, _ = traj.sample(times)
    sim.reset(P[0], R[0])
    run = sim.follow(P[1:], R[1:])
    assert run.error is None and run.done == len(times) - 1
    lists = sim.bristles._ws.sw.near
    return run.record, int(lists.ptr[-1]), len(sim.bristles.pair_idx)


@pytest.mark.parametrize("sweeps", [1, 8])
def test_the_turn_is_the_same_to_the_bit_with_and_without_near_lists(monkeypatch, sweeps):
    """One sweep and the coupled solve (``balanced``'s 8 sweeps) over the start of the paper
    turn, where tips press on each other: the TCP wrench, every tip and every tip-tip force the
    same doubles with the near lists (margin ``near.NEAR_MARGIN``) and without (every partner
    loop over all ~31 listed partners)."""
    on, kept, listed = _turn_start(monkeypatch, near.NEAR_MARGIN, sweeps)
    off, none, _ = _turn_start(monkeypatch, -1.0, sweeps)
    assert (on.ftt > 0.0).any(axis=1).sum() > 100  # tips pressed on each other in >100 steps
    assert 0 < kept < listed / 4 and none == 0  # the last step's near lists: a few partners
    for name in ("FM", "tips", "ftt", "fn", "iters", "sweeps"):
        assert np.array_equal(getattr(on, name), getattr(off, name)), name
