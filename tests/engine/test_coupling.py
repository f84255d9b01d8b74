"""Coupled tip-tip contact (coupling.py, SimSettings.tip_tip_sweeps / tip_tip_tol).

Reference: Newton's third law.  The Table 3 force between two touching tips is one interaction,
so at the end of every step the force on one tip equals the force on the other (same magnitude,
opposite direction along the line of centres).  A solver that holds the partner where it was
(one Gauss-Seidel sweep) breaks it; the coupled solve must keep it within what its tolerance
allows: |F_a - F_b| <= 2 k_t tol, k_t = dF/d(delta) of the Table 3 law at the contact.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from brush_env.engine import BrushConfig, Scene, SimSettings, Simulator

from .kernel_args import contact_scene, sweeps_scratch, whole_lists
from .test_contact import R0, one_bristle

K_TT, M1_TT = 100.0, 1.3  # paper Table 3 (the scene default)
DT = 1e-3
P = 0.01  # [N] mean load pushing the two tips together (head-on contact stays stable)


def _pair_run(
    sweeps: int, tol: float = 1e-6, steps: int = 1200, load=P, amp=2.0, kernel=None, full=False
):
    """Two facing bristles (tips 0.12 mm apart when straight) pushed together by tip loads that
    swing +-50 % at 10 Hz, while the head oscillates 2 mm along the line of centres at 5 Hz (tip
    speeds up to ~90 mm/s).  Returns per step after the 0.5 s ramp: the two tip-tip forces [N],
    the overlap delta [mm] and the sweeps used.  kernel: the step kernel to run instead of the
    one the settings choose; full: every step's tip states, forces and settled flags (a list)."""
    a = one_bristle(root=(-0.6, 0.0, 0.0), tip=0.44).bristles[0]
    b = dataclasses.replace(a, root=(0.6, 0.0, 0.0))
    brush = BrushConfig(name="pair", head_offset=(0, 0, 0), head_rpy=(0, 0, 0), bristles=(a, b))
    sim = Simulator(
        Scene(brush, (), tip_tip=True),
        SimSettings(dt=DT, gravity=(0, 0, 0), tip_tip_sweeps=sweeps, tip_tip_tol=tol),
    )
    sim.reset(np.array([0.0, 0.0, 30.0]), R0)
    if kernel is not None:
        sim.bristles._step_kernel = kernel  # private: the kernel the settings would not choose
    rows = []
    for k in range(1, steps + 1):
        t = k * DT
        s = min(k / 500.0, 1.0) * (1.0 + 0.5 * np.sin(2 * np.pi * 10 * t))
        sim.set_tip_forces(s * np.array([[load, 0.0, 0.0], [-load, 0.0, 0.0]]))
        out = sim.step(np.array([amp * np.sin(2 * np.pi * 5 * t), 0.0, 30.0]), R0)
        if full:
            e = out.extra
            rows.append((out.tip_pos.copy(), e["tip_tip_force"].copy(), e["tip_tip_settled"]))
        elif k > 600:
            ftt = out.extra["tip_tip_force"]
            delta = 0.88 - np.linalg.norm(out.tip_pos[0] - out.tip_pos[1])
            rows.append((ftt[0], ftt[1], delta, out.extra["sweeps"]))
    return rows if full else np.array(rows)


@pytest.mark.parametrize("tol", [1e-5, 1e-6])
def test_touching_tips_push_each_other_equally_at_every_step(tol):
    r = _pair_run(sweeps=8, tol=tol)
    fa, fb, delta = r[:, 0], r[:, 1], r[:, 2]
    assert np.all(delta > 0) and np.all(fa > 0)  # in contact throughout
    # the Table 3 law's slope at each step's overlap: a partner off by tol changes F by k_t tol
    k_t = K_TT * M1_TT * delta ** (M1_TT - 1.0)
    assert np.all(np.abs(fa - fb) <= 2.0 * k_t * tol + 1e-9)
    # and the force is the Table 3 law of the common overlap (both tips see the same delta)
    assert fa == pytest.approx(K_TT * delta**M1_TT, rel=1e-3, abs=2.0 * k_t.max() * tol)
    assert r[:, 3].max() <= 8


def test_one_sweep_lags_and_breaks_action_reaction():
    """The same run solved in one sweep (the partner held where it was): the two tips feel
    different forces -- what the coupled solve removes (this is why the test above can fail)."""
    r = _pair_run(sweeps=1)
    fa, fb = r[:, 0], r[:, 1]
    assert np.max(np.abs(fa - fb)) > 0.2 * P


def test_the_one_sweep_kernel_is_the_coupled_kernels_first_sweep():
    """One sweep and the coupled solve are two kernels (``step.step_bristles`` and
    ``step_bristles_coupled``, so that a run compiles only the one it uses): at one sweep they
    must be the same step, to the bit, with the same record of unsettled partners."""
    from brush_env.engine.step import step_bristles, step_bristles_coupled

    plain = _pair_run(sweeps=1, steps=700, kernel=step_bristles, full=True)
    coupled = _pair_run(sweeps=1, steps=700, kernel=step_bristles_coupled, full=True)
    assert any(not settled for *_, settled in plain)  # the lag is recorded (the flag is used)
    assert any(settled for *_, settled in plain)
    for (p, f, ok), (q, g, ok2) in zip(plain, coupled, strict=True):
        assert np.array_equal(p, q) and np.array_equal(f, g) and ok == ok2
    # the settings choose: one sweep the plain kernel, more the coupled one
    for sweeps, kernel in ((1, step_bristles), (8, step_bristles_coupled)):
        sim = Simulator(Scene(one_bristle(), ()), SimSettings(tip_tip_sweeps=sweeps))
        assert sim.bristles._step_kernel is kernel


def _lead(tips, pairs, h=DT):
    """sweeps.lead_partners on the tips (nb, 7: position [mm], velocity [mm/s], radius [mm]) with
    the symmetric pair lists of ``pairs``; returns (the moved tips, each tip's lead)."""
    from brush_env.engine.sweeps import lead_partners

    nb = len(tips)
    lists = [[j for a, b in pairs for i, j in ((a, b), (b, a)) if i == k] for k in range(nb)]
    ptr = np.cumsum([0] + [len(x) for x in lists]).astype(np.int64)
    idx = np.array([j for x in lists for j in x], np.int64)
    con = contact_scene(np.array(tips, float), ptr, idx)
    sw = sweeps_scratch(nb, len(idx))
    sw.ext[:, 0:3] = h * con.tips[:, 3:6]  # the move h v_n (no history: ``extrapolate_tips``)
    sw.tips0[:] = con.tips[:, 0:6]
    lead_partners(con, sw)
    return con.tips, sw.lead


def _extrapolated(hist, h, p, v):
    """sweeps.extrapolate_tips for one tip with a partner: its node at t_n, t_{n-1}, t_{n-2}
    (``p``, rows; the tip body's centre with half length 0) and velocity v at t_n, ``hist`` whole
    steps of history, BDF2; returns its row of ext (move [mm], velocity change [mm/s]).  A second
    tip without partners must stay unmoved."""
    from brush_env.engine import records as rec
    from brush_env.engine.sweeps import extrapolate_tips

    R = np.broadcast_to(np.eye(3), (2, 3, 3)).copy()
    tips = np.zeros((2, 7))
    tips[:, 0:3] = p[0]
    tips[:, 3:6] = v
    ext = np.full((2, 6), np.nan)
    z = np.zeros((2, 3))
    extrapolate_tips(
        rec.ModelArrays(
            np.array([0, 1, 2]), np.zeros(2, rec.BODY), np.zeros((2, 6, 6)), z, R, np.zeros(2)
        ),
        rec.Chain(z, R, z, z, np.array([p[1], p[1]]), R, z, z, np.array([p[2], p[2]]), R),
        rec.Drive(np.array([hist, hist]), np.zeros((4, 3)), np.zeros((4, 3, 3))),
        rec.StepParams(h, rec.METHOD_BDF2, False, 1e-9, 10, 3, np.zeros(3), 0, 8, 1e-6),
        contact_scene(tips, np.array([0, 1, 1]), np.array([1])),
        ext,
    )
    assert np.all(ext[1] == 0.0)
    return ext[0]


def test_first_guess_extrapolates_a_curving_tip_as_the_predictor_does():
    """A tip in uniform circular motion (radius a, rate w: the paper turn carries tips on a 20 mm
    circle) is led to the quadratic extrapolation of its last three nodes, whose error at
    t_{n+1} is the Taylor remainder h^3 |d3p/dt3| = a w^3 h^3 (the order of each bristle's own
    predictor), where p + h v_n misses by h^2 |d2p/dt2| / 2 = a w^2 h^2 / 2; its velocity is
    BDF2's for that move, within (1/3 + 3/2) a w^3 h^2 of the true one.  With one step of
    history the guess is linear (error h^2 |d2p/dt2|), without it h v_n."""
    a, w, h = 10.0, 30.0, 1e-3

    def p(t):
        return a * np.array([np.cos(w * t), np.sin(w * t), 0.0])

    def v(t):
        return a * w * np.array([-np.sin(w * t), np.cos(w * t), 0.0])

    nodes = np.array([p(0.0), p(-h), p(-2 * h)])
    e = _extrapolated(2, h, nodes, v(0.0))
    err = np.linalg.norm(nodes[0] + e[:3] - p(h))
    assert err <= 1.01 * a * w**3 * h**3
    assert np.linalg.norm(h * v(0.0) - (p(h) - p(0.0))) >= 0.99 * a * w**2 * h**2 / 2 > 10 * err
    assert np.linalg.norm(v(0.0) + e[3:] - v(h)) <= 1.01 * (1 / 3 + 3 / 2) * a * w**3 * h**2
    lin = _extrapolated(1, h, nodes, v(0.0))
    assert np.allclose(lin[:3], nodes[0] - nodes[1])
    assert np.linalg.norm(nodes[0] + lin[:3] - p(h)) <= 1.01 * a * w**2 * h**2
    none = _extrapolated(0, h, nodes, v(0.0))
    assert np.array_equal(none[:3], h * v(0.0)) and np.all(none[3:] == 0.0)


def test_first_guess_moves_tips_that_travel_together_by_h_v():
    """Two touching tips (overlap 1 um) carried sideways together at 20 mm/s, as the brush carries
    them on the paper turn: each is held where it heads, p + h v (20 um on)."""
    r = 0.44
    tips = [[0, 0, 0, 20, 0, 0, r], [2 * r - 1e-3, 0, 0, 20, 0, 0, r]]
    moved, lead = _lead(tips, [(0, 1)])
    assert np.allclose(lead, 1.0)
    assert np.allclose(moved[:, 0], [0.02, 2 * r - 1e-3 + 0.02])


def test_first_guess_never_pushes_tips_into_each_other():
    """Head-on at 100 mm/s each (a 0.2 mm closing in one step, against a 1 um overlap): the
    guess may deepen an overlap by at most PLACE_OVERLAP, and never moves a tip more than
    LEAD_MAX radii, however fast it moves (a 300 mm/s press)."""
    from brush_env.engine.coupling import PLACE_OVERLAP
    from brush_env.engine.sweeps import LEAD_MAX

    r = 0.44
    tips = [[0, 0, 0, 100, 0, 0, r], [2 * r - 1e-3, 0, 0, -100, 0, 0, r], [5, 0, 0, 0, 0, 300, r]]
    moved, lead = _lead(tips, [(0, 1), (1, 2)])
    overlap = 2 * r - np.linalg.norm(moved[0, :3] - moved[1, :3])
    assert overlap <= 1e-3 + PLACE_OVERLAP + 1e-12
    assert 0.0 < lead[0] < 1.0 and 0.0 < lead[1] < 1.0
    assert np.linalg.norm(moved[2, :3] - np.array(tips[2][:3])) <= LEAD_MAX * r + 1e-12
    # a tip without partners is not moved
    alone, lead = _lead([[0, 0, 0, 50, 0, 0, r]], [])
    assert lead[0] == 0.0 and alone[0, 0] == 0.0


def test_partner_move_is_the_largest_move_of_a_partner_within_reach():
    """``sweeps._partner_move`` (which skips partners that moved no further than the largest so
    far) against its definition evaluated pair by pair: the largest |x_j - u_q| over the partners
    j of b whose tip, now or where b saw it (u_q), is within reach + that move of b's tip."""
    from brush_env.engine.sweeps import _partner_move

    rng = np.random.default_rng(7)
    nb = 7
    for _trial in range(20):
        tips = np.zeros((nb, 7))
        tips[:, 0:3] = rng.uniform(-0.6, 0.6, (nb, 3))
        tips[:, 6] = rng.uniform(0.1, 0.2, nb)  # radii [mm]
        ptr = [0]
        idx = []
        for b in range(nb):
            idx += [j for j in range(nb) if j != b]
            ptr.append(len(idx))
        pair_idx = np.array(idx, dtype=np.int64)
        used = tips[pair_idx, 0:3].copy()
        moved = rng.random(pair_idx.size) < 0.4  # most partners did not move since b was solved
        used[moved] += rng.normal(0.0, 0.05, (int(moved.sum()), 3))
        con = contact_scene(tips, np.array(ptr, dtype=np.int64), pair_idx)
        for b in range(nb):
            want = 0.0
            for q in range(ptr[b], ptr[b + 1]):
                j = pair_idx[q]
                mv = np.linalg.norm(tips[j, 0:3] - used[q])
                reach = tips[b, 6] + tips[j, 6] + mv
                near_now = np.linalg.norm(tips[b, 0:3] - tips[j, 0:3]) <= reach
                near_then = np.linalg.norm(tips[b, 0:3] - used[q]) <= reach
                if near_now or near_then:
                    want = max(want, mv)
            got = _partner_move(b, con, used, whole_lists(nb, len(idx)))
            assert got == pytest.approx(want, rel=1e-15, abs=0.0)
