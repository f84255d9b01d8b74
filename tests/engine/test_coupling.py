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

from .test_contact import R0, one_bristle

K_TT, M1_TT = 100.0, 1.3  # paper Table 3 (the scene default)
DT = 1e-3
P = 0.01  # [N] mean load pushing the two tips together (head-on contact stays stable)


def _pair_run(sweeps: int, tol: float = 1e-6, steps: int = 1200, load=P, amp=2.0):
    """Two facing bristles (tips 0.12 mm apart when straight) pushed together by tip loads that
    swing +-50 % at 10 Hz, while the head oscillates 2 mm along the line of centres at 5 Hz (tip
    speeds up to ~90 mm/s).  Returns per step after the 0.5 s ramp: the two tip-tip forces [N],
    the overlap delta [mm] and the sweeps used."""
    a = one_bristle(root=(-0.6, 0.0, 0.0), tip=0.44).bristles[0]
    b = dataclasses.replace(a, root=(0.6, 0.0, 0.0))
    brush = BrushConfig(name="pair", head_offset=(0, 0, 0), head_rpy=(0, 0, 0), bristles=(a, b))
    sim = Simulator(
        Scene(brush, (), tip_tip=True),
        SimSettings(dt=DT, gravity=(0, 0, 0), tip_tip_sweeps=sweeps, tip_tip_tol=tol),
    )
    sim.reset(np.array([0.0, 0.0, 30.0]), R0)
    rows = []
    for k in range(1, steps + 1):
        t = k * DT
        s = min(k / 500.0, 1.0) * (1.0 + 0.5 * np.sin(2 * np.pi * 10 * t))
        sim.set_tip_forces(s * np.array([[load, 0.0, 0.0], [-load, 0.0, 0.0]]))
        out = sim.step(np.array([amp * np.sin(2 * np.pi * 5 * t), 0.0, 30.0]), R0)
        if k > 600:
            ftt = out.extra["tip_tip_force"]
            delta = 0.88 - np.linalg.norm(out.tip_pos[0] - out.tip_pos[1])
            rows.append((ftt[0], ftt[1], delta, out.extra["sweeps"]))
    return np.array(rows)


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
