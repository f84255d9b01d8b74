"""One bristle over one step: the time scheme's coefficients, sub-step halving and backup.

Scheme (eq 11 in time): ``y'(t_{n+1}) ~ (c0 y_{n+1} + c1 y_n + c2 y_{n-1}) / h``, backward Euler
``(1, -1, 0)`` or BDF2 ``(3/2, -2, 1/2)``; ``scheme_coefficients`` is the one place that chooses
them.  ``advance_bristle``: Newton (``newton.py``) on the whole step, halved recursively on
failure (down to h / 2**max_levels) with the base pose interpolated (linear position, geodesic
rotation), regrown when aligned; a bristle that still fails is restored to its state at the start
of the step and flagged NEWTON_FAILED.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT, local_rot_into, rotate_left
from .newton import newton_solve
from .predict import WARM, chain_rows
from .records import METHOD_BDF2, Attempt, Substep

# status codes per bristle (step_bristles' ``out.status``)
OK = 0
NEWTON_FAILED = 1  # Newton failed on the smallest sub-step; the bristle is restored
#: Newton iterations allowed an attempt on the smallest halving when ``newton_max_iter`` is
#: lower.  The cap makes a long attempt give way to a halving (long attempts on stale factors
#: wandered to other roots: docs/benchmarks.md, "Newton's iteration cap"); the smallest halving
#: has nothing to give way to but the bristle's failure.  There a shaft body sliding on one
#: surface while the tip sticks on another can flip its stick-slip state between iterations:
#: the line search then cuts each step to ~0.1 and Newton needs 17-30 iterations even at
#: h / 256 (the tooth-row reproducer, docs/model.md "Newton's iteration cap at the smallest
#: halving").  100 was the cap of every level before 2026-11-28.  Runs that never fail on their
#: smallest halving are unchanged to the bit.  Without halvings (``max_halvings = 0``, and the
#: static solve) nothing gives way: ``newton_max_iter`` stays the attempt's only bound, as set.
LAST_LEVEL_MAXIT = np.int64(100)


@njit(**HOT)
def _base_pose(p0, R0, p1, R1, s, pout, Rout, tmp):
    """Base pose at fraction s of the step: linear in position, geodesic in rotation (at s = 0
    and 1, a whole step's ends, the poses themselves: no log and exp of their rotation)."""
    if s == 0.0 or s == 1.0:
        p = p0 if s == 0.0 else p1
        R = R0 if s == 0.0 else R1
        for a in range(3):
            pout[a] = p[a]
            for b in range(3):
                Rout[a, b] = R[a, b]
        return
    for a in range(3):
        pout[a] = (1.0 - s) * p0[a] + s * p1[a]
    local_rot_into(R1, R0, tmp)  # tmp = log(R1 R0^T)
    rotate_left(s * tmp[0], s * tmp[1], s * tmp[2], R0, Rout)


@njit(**HOT)
def _tcp_to_base(tp, tR, rp, rR, pout, Rout):
    """Root node pose in the world: p = p_tcp + R_tcp r, R = R_tcp R_root."""
    for a in range(3):
        pout[a] = tp[a] + tR[a, 0] * rp[0] + tR[a, 1] * rp[1] + tR[a, 2] * rp[2]
        for b in range(3):
            Rout[a, b] = tR[a, 0] * rR[0, b] + tR[a, 1] * rR[1, b] + tR[a, 2] * rR[2, b]


@njit(**HOT, inline="always")
def _base_of_substep(br, model, drive, s, ds, ws):
    """ws.base <- the root node's poses of one bristle for the sub-step [s, s + ds] of the step
    (fractions; the TCP pose interpolated by ``_base_pose``), and at t_{n-1}, t_{n-2}."""
    base = ws.base
    tp = ws.tp
    tR = ws.tR
    tmp = ws.mot.tmp
    rp = model.root_p[br.b]
    rR = model.root_R[br.b]
    tcp_p = drive.tcp_p
    tcp_R = drive.tcp_R
    _tcp_to_base(tcp_p[0], tcp_R[0], rp, rR, base.pAp, base.RAp)
    _tcp_to_base(tcp_p[3], tcp_R[3], rp, rR, base.pAq, base.RAq)
    _base_pose(tcp_p[1], tcp_R[1], tcp_p[2], tcp_R[2], s, tp, tR, tmp)
    _tcp_to_base(tp, tR, rp, rR, base.pAs, base.RAs)
    _base_pose(tcp_p[1], tcp_R[1], tcp_p[2], tcp_R[2], s + ds, tp, tR, tmp)
    _tcp_to_base(tp, tR, rp, rR, base.pAe, base.RAe)


@njit(**HOT, inline="always")
def scheme_coefficients(prm, history):
    """(c0, c1, c2) of the two-step formula, the one place that chooses them: BDF2
    ``(3/2, -2, 1/2)`` if the settings ask for it (prm.method) and ``history`` (a whole step with
    the previous step's state behind it), else backward Euler ``(1, -1, 0)``; c1 = c2 = 0 for
    statics (no history)."""
    if prm.method == METHOD_BDF2 and history:
        c0, c1, c2 = 1.5, -2.0, 0.5
    else:
        c0, c1, c2 = 1.0, -1.0, 0.0
    if prm.static:
        c1 = 0.0
        c2 = 0.0
    return c0, c1, c2


@njit(**HOT, inline="always")
def _substep(prm, whole, hist_ok, h, last):
    """The (sub)step's ``Substep`` (``scheme_coefficients``: BDF2 on a whole step with history);
    ``last``: the smallest of at least one halving, allowed at least LAST_LEVEL_MAXIT Newton
    iterations."""
    c0, c1, c2 = scheme_coefficients(prm, whole and hist_ok != 0)
    maxit = max(prm.maxit, LAST_LEVEL_MAXIT) if last else prm.maxit
    return Substep(c0, c1, c2, h, 1.0 / h, prm.static, prm.g, prm.rtol, maxit, prm.jage)


@njit(**HOT, inline="always")
def _backup(br, chain, con, bk, save):
    """save: bk <- the bristle's state at the start of the step (``advance_bristle`` saves it
    when the whole step has failed, which leaves the bristle there); else the bristle <- bk
    (every sub-step level failed)."""
    b0 = br.b0
    chain_rows(chain, b0, bk.v3, bk.R, 0, br.n, save)
    if save:
        bk.tip_state[0] = con.tip_state[br.b]
    else:
        con.tip_state[br.b] = bk.tip_state[0]
    if con.shaft.shape[0] > 0:  # the bodies' stiction states (shaft.py)
        for k in range(br.n):
            if save:
                bk.shaft[k] = con.shaft[b0 + k]
            else:
                con.shaft[b0 + k] = bk.shaft[k]


@njit(**HOT, inline="always")
def advance_bristle(br, model, chain, drive, prm, con, jc, ws, out, warm):
    """One bristle over one step h = prm.h: Newton on the whole step, halved recursively on
    failure (down to h / 2**max_levels) and regrown when aligned; restored and flagged
    NEWTON_FAILED if the smallest sub-step fails.  warm: Newton on the whole step starts from
    ``ws.sw.warm_pos/warm_rot`` (a re-solve in a later sweep) instead of the predictors."""
    b = br.b
    h = prm.h
    maxlev = prm.maxlev
    hist_ok = drive.hist_ok[b]
    s = 0.0
    level = 0
    tot = 0
    nsteps = 0
    out.status[b] = OK
    while s < 1.0 - 1e-12:
        ds = 0.5**level
        if s + ds > 1.0:
            ds = 1.0 - s
        whole = level == 0 and s == 0.0
        sub = _substep(prm, whole, hist_ok, h * ds, level == maxlev > 0)
        _base_of_substep(br, model, drive, s, ds, ws)
        # predictor order: 3 with two whole steps of history, 2 with one, none otherwise
        extrap = 0
        if whole and warm:
            extrap = WARM
        elif whole and not sub.static and hist_ok > 0:
            extrap = 3 if hist_ok >= 2 else 2
        # a tip that meets a surface within the (sub)step has it halved, down to the smallest
        split = level < maxlev and not sub.static
        attempt = Attempt(extrap, split)
        ok, it = newton_solve(br, model, chain, sub, ws.base, con, jc, ws, out.rootw[b], attempt)
        tot += it
        if ok:
            s += ds
            nsteps += 1
            # after a success, try a larger sub-step again when aligned
            if level > 0 and abs(s / (2.0 * ds) - np.floor(s / (2.0 * ds) + 0.5)) < 1e-9:
                level -= 1
        else:
            if level == 0 and s == 0.0:
                # the whole step failed: Newton left the bristle at the step's start (nothing
                # committed yet), which a later failure returns to.  Saved here, not before the
                # step: ~99 % of steps succeed whole, and the copy (chain rows, tip and shaft
                # records) cost ~2 % of a bristle-step (docs/benchmarks.md, session 33)
                _backup(br, chain, con, ws.backup, True)
            level += 1
            if level > maxlev:
                out.status[b] = NEWTON_FAILED
                _backup(br, chain, con, ws.backup, False)  # restore
                break
    out.iters[b] = tot
    out.nsub[b] = nsteps
    drive.hist_ok[b] = min(hist_ok + 1, 2) if (nsteps == 1 and out.status[b] == OK) else 0
