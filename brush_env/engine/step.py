"""Implicit time stepping of the brush (eq 1-11): ``step_bristles`` lists the stages in order.

Scheme: the momentum balance of eq 11 for every body, discretised with the two-step formula
``y'(t_{n+1}) ~ (c0 y_{n+1} + c1 y_n + c2 y_{n-1}) / h`` applied to positions, velocities, angular
momenta and the element strains of the damping term (eq 4-5): backward Euler ``(1, -1, 0)``
(L-stable, first order) or BDF2 ``(3/2, -2, 1/2)`` (L-stable, second order), chosen in
``advance.scheme_coefficients``.  Rotations are updated multiplicatively, ``R <- exp([dtheta]) R``,
and enter the rates through rotation vectors relative to ``R_n``.

Each bristle is an open chain, so its Newton matrix is block tridiagonal (6x6 blocks) and is solved
by block Thomas in O(n).  The stages, one module each:

- ``residual.py``: the residual of eq 11 (inertia, elements eq 1-5, tip load eq 6-10 / Table 3)
  and its Newton matrix;
- ``predict.py``: the (sub)step's constants and Newton's starting point (predictors);
- ``newton.py``: direction, step cap, line search, the Newton loop, commit;
- ``advance.py``: the scheme's coefficients, one bristle over one step with sub-step halving;
- ``sweeps.py``: the Gauss-Seidel sweeps over the bristles and their tip-tip partners (Table 3);
- ``coupling.py``: where touching partners are held between sweeps.

The kernels take the named records of ``records.py`` (model, chain state, drive, contact scene,
Newton cache, scratch), never position-indexed tuples or columns.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT
from .near import close
from .sweeps import (
    SWEEP_FIRST,
    note_one_sweep,
    settle_tip_tip,
    start_sweeps,
    sweep_bristles,
    tip_node_state,
)


# inline: a call from Python (``Simulator.step``) compiles it as a kernel of its own; inside the
# compiled rollout (``chain_rollout.follow_*``) it is three calls, and not a kernel of its own
# that numba would link, optimise and generate code for again with the whole step below it
# (docs/benchmarks.md, "... one kernel layer fewer")
@njit(**HOT, inline="always")
def step_bristles(model, chain, drive, prm, con, jc, ws, out):
    """Advance every bristle by one step h = prm.h (in place) in one sweep (prm.sweeps == 1);
    ``step_bristles_coupled`` is the step with more.  Two kernels, so that a run with one sweep
    (the default, levels ``coarse``, ``fast``, ``reduced``) compiles none of the coupled solve.

    prm: ``records.StepParams``; drive: TCP pose at t_{n-1}, t_n, t_{n+1}, t_{n-2} (rows 0, 1,
    2, 3) and hist_ok (whole steps behind each bristle's history, 0, 1 or 2; after a sub-stepped
    step the history is not on the step grid: 0).  con: surfaces, contact laws (Tables 2-3),
    every tip's node, velocity and radius, the tip-tip partner lists (CSR), the scene's mesh, tip
    arguments and per-contact state.

    Bristles are coupled only through tip-tip contact (Table 3).  Each is solved with its
    partners' tips held (``con.tips``), in order (a Gauss-Seidel sweep): a partner solved earlier
    in the sweep at its new tip, one solved later at its start-of-step tip.  Outputs per bristle
    in ``out``: rootw (force, moment of the root element on the head, at the root node, world),
    iters (Newton iterations), nsub (sub-steps used), status (OK / NEWTON_FAILED); ws.sw.count =
    [1, 0, 1 if a touching partner moved by more than prm.tttol after its bristle was solved].
    """
    start_sweeps(model, chain, drive, prm, con, ws, out)  # outputs zeroed, start state kept
    sweep_bristles(model, chain, drive, prm, con, jc, ws, out, SWEEP_FIRST)  # every bristle
    note_one_sweep(model, prm, con, ws)
    close(ws.sw.near)  # the near lists hold for this step only (``near.py``)


@njit(**HOT, inline="always")  # as step_bristles
def step_bristles_coupled(model, chain, drive, prm, con, jc, ws, out):
    """``step_bristles`` with up to prm.sweeps > 1 sweeps (arguments and outputs as there).

    While some bristle's touching partners have moved by more than prm.tttol since it was
    solved, the partners are placed where the linearised coupled problem puts them
    (``coupling.place_partners``) and those bristles are solved again from the step's start,
    warm-started at their last solution: at convergence both sides of every tip-tip contact see
    the end-of-step tips (no lag).  ws.sw.count = [sweeps run, re-solves, 0 settled (after a
    restart from the plain sweep too, ``sweeps.settle_tip_tip``) / 1 out of sweeps with partners
    still moving by less than FALLBACK_MOVE / 2 fell back to the plain sweep]; out.iters counts
    all sweeps.
    """
    start_sweeps(model, chain, drive, prm, con, ws, out)  # outputs zeroed, start state kept
    sweep_bristles(model, chain, drive, prm, con, jc, ws, out, SWEEP_FIRST)  # every bristle
    settle_tip_tip(model, chain, drive, prm, con, jc, ws, out)  # re-solves with placed partners
    close(ws.sw.near)  # the near lists hold for this step only (``near.py``)


@njit(**HOT)
def tip_states(bstart, bp, pos, rot, vel, omg, out):
    """Tip node position and velocity of every bristle into out (nb, >= 6), see tip_node_state."""
    for b in range(bstart.shape[0] - 1):
        tip_node_state(b, bstart[b + 1] - 1, bp, pos, rot, vel, omg, out)


@njit(**HOT)
def tcp_wrench(R_tcp, root_p, rootw, out):
    """Wrench the TCP applies to the brush, out = (F [N], M [N mm] about the TCP), world.

    The (massless) head carries every root element's reaction: the elements push on the head with
    rootw (force, moment at the root node); the root node sits at R_tcp root_p from the TCP."""
    for a in range(6):
        out[a] = 0.0
    for b in range(root_p.shape[0]):
        x0 = R_tcp[0, 0] * root_p[b, 0] + R_tcp[0, 1] * root_p[b, 1] + R_tcp[0, 2] * root_p[b, 2]
        x1 = R_tcp[1, 0] * root_p[b, 0] + R_tcp[1, 1] * root_p[b, 1] + R_tcp[1, 2] * root_p[b, 2]
        x2 = R_tcp[2, 0] * root_p[b, 0] + R_tcp[2, 1] * root_p[b, 1] + R_tcp[2, 2] * root_p[b, 2]
        f0 = rootw[b, 0]
        f1 = rootw[b, 1]
        f2 = rootw[b, 2]
        out[0] -= f0
        out[1] -= f1
        out[2] -= f2
        out[3] -= rootw[b, 3] + x1 * f2 - x2 * f1
        out[4] -= rootw[b, 4] + x2 * f0 - x0 * f2
        out[5] -= rootw[b, 5] + x0 * f1 - x1 * f0


@njit(**HOT)
def all_finite(x):
    """True if every entry of the 2-D array x is finite."""
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            if not np.isfinite(x[i, j]):
                return False
    return True
