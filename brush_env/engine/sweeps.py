"""The Gauss-Seidel sweeps over the bristles and their tip-tip partners (Table 3).

Bristles are coupled only through tip-tip contact (Table 3, no friction).  ``sweep_bristles`` solves
each bristle (``advance.py``) with its partners' tips held at their latest positions; a later
sweep re-solves, warm-started, the bristles whose touching partners moved by more than the
tolerance (``_partners_moved``), after ``coupling.place_partners`` placed them.  ``_save_all``
and ``_restore_bristle`` keep every bristle's start-of-step state for those re-solves.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT
from .advance import OK, advance_bristle, scheme_coefficients
from .coupling import PLACE_OVERLAP, place_partners, store_tip_load
from .near import build, entry, moved, span
from .predict import chain_rows, save_chain
from .records import Bristle

#: modes of ``sweep_bristles``.  numpy integers, not Python ints: numba types a Python int
#: constant as a literal and compiles the callee once per value (three ``sweep_bristles``, each
#: with the whole bristle step inlined; docs/benchmarks.md, "First start"); an int64 is one type
SWEEP_FIRST = np.int64(0)  # every bristle, from the step's start
SWEEP_AGAIN = np.int64(1)  # the bristles whose partners moved (or were placed), warm-started
SWEEP_PLAIN = np.int64(2)  # every bristle again from the step's start, partners back at their start
#: [mm] partners still moving by more than this when the sweeps run out: the coupled iteration
#: went astray (contact onset, a stick-slip switch); the step falls back to the plain sweep
FALLBACK_MOVE = 1e-4
#: a step whose sweeps have run more Newton iterations than this many times the first sweep's
#: falls back to the plain sweep: never reached on the paper turn (its re-solves cost a fraction
#: of a sweep), reached early where packed tips make every re-solve sub-step (the deep-slide
#: reproducer's hardest env step: 1.7 s of CPU instead of 67 s; docs/benchmarks.md)
ITER_BUDGET = 10
#: halvings of a tip's lead before it is held at its start (``lead_partners``)
LEAD_HALVINGS = 6
#: the longest lead, in tip radii: the penalty law's range (eq 6 is fitted to 10 % of the radius);
#: the paper turn's tips move ~5 % of theirs per 1 ms step, a 300 mm/s press ~70 %
LEAD_MAX = 0.1


@njit(**HOT)
def sweep_bristles(model, chain, drive, prm, con, jc, ws, out, mode):
    """One pass over the bristles in order (``step_bristles``); ``mode``: SWEEP_*."""
    bstart = model.bstart
    nb = bstart.shape[0] - 1
    sw = ws.sw
    npair = con.pair_idx.shape[0]
    coupled = prm.sweeps > 1 and npair > 0
    if mode == SWEEP_PLAIN:
        for b in range(nb):
            for a in range(6):
                con.tips[b, a] = sw.tips0[b, a]
    for b in range(nb):
        b0 = bstart[b]
        n = bstart[b + 1] - b0
        br = Bristle(b, b0, n, b0 + n - 1)
        if mode == SWEEP_AGAIN:
            if not _partners_moved(b, con, sw.used, sw.near, prm.tttol):
                if sw.grouped[b] != 0:  # placed but held as it is: back to its solution
                    for a in range(6):
                        con.tips[b, a] = sw.xs[b, a]
                    moved(con, sw.near, b)
                continue
            sw.count[1] += 1
            save_chain(br, chain.pos, chain.rot, sw.warm_pos[b0:], sw.warm_rot[b0:])
        if mode != SWEEP_FIRST:
            _restore_bristle(br, chain, con, drive, sw)
        for q in range(con.pair_ptr[b], con.pair_ptr[b + 1]):
            j = con.pair_idx[q]
            for a in range(3):
                sw.used[q, a] = con.tips[j, a]
        prev = out.iters[b]
        advance_bristle(br, model, chain, drive, prm, con, jc, ws, out, mode == SWEEP_AGAIN)
        out.iters[b] += prev
        tip_node_state(b, br.il, model.bp, chain.pos, chain.rot, chain.vel, chain.omg, con.tips)
        moved(con, sw.near, b)
        if coupled:
            store_tip_load(b, ws.it, sw)


@njit(**HOT, inline="always")
def _max_partner_move(nb, con, used, near):
    """The largest move [mm] of a partner within contact reach of a bristle since that bristle
    was solved (``_partners_moved``), over all bristles."""
    m = 0.0
    for b in range(nb):
        m = max(m, _partner_move(b, con, used, near))
    return m


@njit(**HOT, inline="always")
def note_one_sweep(model, prm, con, ws):
    """The one-sweep step's record (``step.step_bristles``; ``settle_tip_tip`` with one sweep):
    sw.count[2] = 1 if a touching partner moved by more than prm.tttol after its bristle was
    solved (that bristle saw the partner's start-of-step tip: the tip-tip force lags)."""
    if _max_partner_move(model.bstart.shape[0] - 1, con, ws.sw.used, ws.sw.near) > prm.tttol:
        ws.sw.count[2] = 1


@njit(**HOT, inline="always")
def _iterations(out, nb):
    """Newton iterations of the step so far, all bristles and sweeps."""
    n = 0
    for b in range(nb):
        n += out.iters[b]
    return n


@njit(**HOT, inline="always")
def _any_failed(status, nb):
    """True if some bristle's last solve failed (``advance.NEWTON_FAILED``: restored to its
    start)."""
    for b in range(nb):
        if status[b] != OK:
            return True
    return False


@njit(**HOT, inline="always")
def _partners_moved(b, con, used, near, tol):
    """True if a partner of bristle b that is (or was, when b was solved) within contact reach
    of b's tip has moved by more than ``tol`` [mm] since b was solved."""
    return _partner_move(b, con, used, near) > tol


@njit(**HOT)
def _partner_move(b, con, used, near):
    """The largest move [mm] since bristle b was solved of a partner that is (or was, when b was
    solved) within contact reach of b's tip.  A partner is tested for reach only if it moved
    further than the largest so far (compared squared: sqrt is monotone, so the result is the
    same number): most partners have not moved since b was solved (a later sweep re-solves a
    few bristles), and this runs for every bristle after every sweep.  Over the near list while
    no held tip moved by a quarter of its margin (a partner's move and distance are each within
    2 D of their start: ``near.py``)."""
    tips = con.tips
    rb = tips[b, 6]
    m2 = 0.0
    k0, k1, on = span(con, near, b, 4.0 * near.d[0])
    for k in range(k0, k1):
        q, j = entry(con, near, k, on)
        m0 = tips[j, 0] - used[q, 0]
        m1 = tips[j, 1] - used[q, 1]
        m2j = tips[j, 2] - used[q, 2]
        mm = m0 * m0 + m1 * m1 + m2j * m2j
        if mm <= m2:
            continue
        mv = np.sqrt(mm)
        reach = rb + tips[j, 6]
        dn0 = tips[b, 0] - tips[j, 0]
        dn1 = tips[b, 1] - tips[j, 1]
        dn2 = tips[b, 2] - tips[j, 2]
        du0 = tips[b, 0] - used[q, 0]
        du1 = tips[b, 1] - used[q, 1]
        du2 = tips[b, 2] - used[q, 2]
        r2 = (reach + mv) * (reach + mv)
        if dn0 * dn0 + dn1 * dn1 + dn2 * dn2 > r2 and du0 * du0 + du1 * du1 + du2 * du2 > r2:
            continue
        m2 = mm
    return np.sqrt(m2)


@njit(**HOT, inline="always")
def _save_all(chain, con, drive, sw):
    """sw <- every bristle's state at the step's start (chain, contact state, hist_ok)."""
    chain_rows(chain, 0, sw.v3, sw.R, 0, chain.pos.shape[0], True)
    for b in range(con.tip_state.shape[0]):
        sw.tip_state[b] = con.tip_state[b]
        sw.hist_ok[b] = drive.hist_ok[b]
    for i in range(con.shaft.shape[0]):
        sw.shaft[i] = con.shaft[i]


@njit(**HOT, inline="always")
def _restore_bristle(br, chain, con, drive, sw):
    """One bristle <- its state at the step's start (``_save_all``)."""
    chain_rows(chain, br.b0, sw.v3, sw.R, br.b0, br.n, False)
    con.tip_state[br.b] = sw.tip_state[br.b]
    drive.hist_ok[br.b] = sw.hist_ok[br.b]
    if con.shaft.shape[0] > 0:
        for k in range(br.b0, br.b0 + br.n):
            con.shaft[k] = sw.shaft[k]


@njit(**HOT, inline="always")
def tip_node_state(b, il, bp, pos, rot, vel, omg, out):
    """out[b, 0:3] <- tip node (sphere centre) [mm], out[b, 3:6] <- its velocity [mm/s] (world):
    p = c + r, v = v_c + omega x r with r = half R e_x of the last body ``il``."""
    hl = bp[il].half
    r0 = hl * rot[il, 0, 0]
    r1 = hl * rot[il, 1, 0]
    r2 = hl * rot[il, 2, 0]
    out[b, 0] = pos[il, 0] + r0
    out[b, 1] = pos[il, 1] + r1
    out[b, 2] = pos[il, 2] + r2
    out[b, 3] = vel[il, 0] + omg[il, 1] * r2 - omg[il, 2] * r1
    out[b, 4] = vel[il, 1] + omg[il, 2] * r0 - omg[il, 0] * r2
    out[b, 5] = vel[il, 2] + omg[il, 0] * r1 - omg[il, 1] * r0


@njit(**HOT)
def extrapolate_tips(model, chain, drive, prm, con, ext):
    """ext[b] <- where tip b heads over the step, for the coupled solve's first guess
    (``lead_partners``): its move p_{n+1} - p_n [mm] extrapolated from the tip's own history as
    each bristle's predictor extrapolates its bodies (``predict.py``: quadratic with two whole
    steps behind, linear with one, h v_n without), and the change of its velocity [mm/s] that the
    scheme's formula gives for that move (``scheme_coefficients``).  Only tips with partners."""
    tips = con.tips
    bp = model.bp
    bstart = model.bstart
    h = prm.h
    c0, c1, c2 = scheme_coefficients(prm, True)
    for b in range(tips.shape[0]):
        for a in range(6):
            ext[b, a] = 0.0
        if con.pair_ptr[b + 1] == con.pair_ptr[b]:
            continue
        k = drive.hist_ok[b]
        if k == 0 or prm.static:
            for a in range(3):
                ext[b, a] = h * tips[b, 3 + a]
            continue
        il = bstart[b + 1] - 1
        hl = bp[il].half
        for a in range(3):
            p0 = tips[b, a]
            p1 = chain.ppos[il, a] + hl * chain.prot[il, a, 0]
            if k >= 2:
                p2 = chain.pppos[il, a] + hl * chain.pprot[il, a, 0]
                p = 3.0 * p0 - 3.0 * p1 + p2
            else:
                p = 2.0 * p0 - p1
            ext[b, a] = p - p0
            ext[b, 3 + a] = (c0 * p + c1 * p0 + c2 * p1) / h - tips[b, 3 + a]


@njit(**HOT)
def lead_partners(con, sw):
    """The coupled solve's first guess: every tip with tip-tip partners is held, for the first
    sweep, where it is heading, con.tips[b] <- tips[b] + lead_b sw.ext[b] (position and velocity;
    ``extrapolate_tips``: the tip's own history extrapolated as each bristle's predictor does, so
    that the partners a bristle is solved against are as close to their end-of-step tips as its
    own first guess is to its own; lead_b |ext_b| at most LEAD_MAX tip radii), so that a bristle
    solved before its partners sees them near their end-of-step tips rather than a step behind:
    on the paper turn the brush carries every tip ~20 um per 1 ms step, and a partner held at its
    start sends the first placement (``coupling``) 20 um off, more than its safe fraction lets it
    take.  lead_b starts at 1 and is halved (both tips of a pair, up to LEAD_HALVINGS times, then
    0: held at the start) while a pair of tips within contact reach would, both moved on,
    reverse its line of centres (pass through each other) or overlap by more than it does now
    plus ``coupling.PLACE_OVERLAP``: the guess may not create the deep overlaps that made the
    unclipped h v_n guess push tips through each other under random actions (docs/model.md).  It
    only steers the sweeps: every bristle is then solved against its partners' own solutions."""
    tips = con.tips
    ext = sw.ext
    nb = tips.shape[0]
    lead = sw.lead
    for b in range(nb):
        lead[b] = 0.0
        if con.pair_ptr[b + 1] > con.pair_ptr[b]:
            move = np.sqrt(ext[b, 0] ** 2 + ext[b, 1] ** 2 + ext[b, 2] ** 2)
            lead[b] = min(1.0, LEAD_MAX * tips[b, 6] / move) if move > 0.0 else 0.0
    # a pair off the near lists cannot come within reach: each tip moves by at most LEAD_MAX of
    # its radius (``near.py``)
    near = sw.near
    rmax = 0.0
    for b in range(nb):
        rmax = max(rmax, tips[b, 6])
    need = 2.0 * near.d[0] + 2.0 * LEAD_MAX * rmax
    for _round in range(LEAD_HALVINGS + 1):
        bad = False
        for b in range(nb):
            k0, k1, on = span(con, near, b, need)
            for k in range(k0, k1):
                _q, j = entry(con, near, k, on)
                if j < b or (lead[b] == 0.0 and lead[j] == 0.0):
                    continue  # each pair once (the lists are symmetric)
                if _lead_unsafe(b, j, lead[b], lead[j], tips, ext):
                    bad = True
                    for t in (b, j):
                        lead[t] = 0.0 if _round == LEAD_HALVINGS else 0.5 * lead[t]
        if not bad:
            break
    for b in range(nb):
        for a in range(6):
            tips[b, a] += lead[b] * ext[b, a]
        moved(con, near, b)


@njit(**HOT, inline="always")
def _lead_unsafe(b, j, fb, fj, tips, ext):
    """True if moving tip b by fb ext_b and tip j by fj ext_j (``lead_partners``) reverses their
    line of centres or overlaps them by more than now plus PLACE_OVERLAP [mm]."""
    reach = tips[b, 6] + tips[j, 6]
    d2 = 0.0
    dot = 0.0
    e2 = 0.0
    for a in range(3):
        d0 = tips[b, a] - tips[j, a]
        d1 = d0 + fb * ext[b, a] - fj * ext[j, a]
        d2 += d0 * d0
        dot += d0 * d1
        e2 += d1 * d1
    now = reach - np.sqrt(d2)
    return dot <= 0.0 or reach - np.sqrt(e2) > max(now, 0.0) + PLACE_OVERLAP


@njit(**HOT, inline="always")
def start_sweeps(model, chain, drive, prm, con, ws, out):
    """Before the first sweep: no Newton iterations yet, every tip's start (sw.tips0) and, if
    more than one sweep may run, every bristle's start-of-step state (``_save_all``)."""
    nb = model.bstart.shape[0] - 1
    sw = ws.sw
    sweeps = prm.sweeps if con.pair_idx.shape[0] > 0 else 1
    for b in range(nb):
        out.iters[b] = 0
        for a in range(6):
            sw.tips0[b, a] = con.tips[b, a]
    build(con, sw.near, sw.tips0)  # the step's near lists of partners (``near.py``)
    if sweeps > 1:
        _save_all(chain, con, drive, sw)
        if not prm.static:
            extrapolate_tips(model, chain, drive, prm, con, sw.ext)
            lead_partners(con, sw)
    sw.count[0] = 1
    sw.count[1] = 0
    sw.count[2] = 0


@njit(**HOT, inline="always")
def settle_tip_tip(model, chain, drive, prm, con, jc, ws, out):
    """After the first sweep: while touching partners moved by more than prm.tttol since a
    bristle was solved, place them (``coupling.place_partners``) and sweep again (SWEEP_AGAIN).
    Out of sweeps far from settled (the first guess overshot, e.g. at a stick-slip switch): the
    plain sweep (SWEEP_PLAIN, partners at their start), then once more up to prm.sweeps sweeps
    from its solution, and the plain sweep again if those run out too.  A bristle failed against
    led or placed partners, or the budget spent: the plain sweep, and the step ends there.  Sets
    sw.count (sweeps run, the plain ones included)."""
    nb = model.bstart.shape[0] - 1
    sw = ws.sw
    sweeps = prm.sweeps if con.pair_idx.shape[0] > 0 else 1
    # the coupling's tip-tip damping weight c0 / h: the scheme's c0 on a whole step with history
    # (it only steers the placement of partners; each bristle's own step uses its own c0)
    c0 = scheme_coefficients(prm, True)[0]
    c0_inv_h = 0.0 if prm.static else c0 / prm.h
    # after the first sweep; only a coupled step has a budget (one sweep never falls back)
    budget = ITER_BUDGET * max(_iterations(out, nb), nb) if sweeps > 1 else 0
    run = 1  # sweeps of this round (a second round starts from the plain sweep, once)
    restarted = False
    for _sweep in range(2 * sweeps):
        if sweeps > 1 and (_any_failed(out.status, nb) or _iterations(out, nb) > budget):
            # a bristle's Newton failed on its smallest sub-step against led or placed partners,
            # or the re-solves cost more than ITER_BUDGET first sweeps (tips packed under a brush
            # bent over, docs/model.md): the plain sweep instead, whose partners sit at their
            # start; a bristle failing there fails the step
            sw.count[2] = 2
            sweep_bristles(model, chain, drive, prm, con, jc, ws, out, SWEEP_PLAIN)
            sw.count[0] += 1
            break
        move = _max_partner_move(nb, con, sw.used, sw.near)
        if move <= prm.tttol:
            break
        if run == sweeps:
            sw.count[2] = 1  # out of sweeps with partners still moving
            if sweeps > 1 and move > FALLBACK_MOVE:
                # far from settled (the coupled step went astray): the plain sweep instead,
                # then once more the coupled sweeps from its solution
                sw.count[2] = 2
                sweep_bristles(model, chain, drive, prm, con, jc, ws, out, SWEEP_PLAIN)
                sw.count[0] += 1
                if not restarted:
                    restarted = True
                    run = 1
                    sw.count[2] = 0
                    continue
            break
        run += 1
        sw.count[0] += 1
        place_partners(model, chain, con, jc, ws, c0_inv_h)
        sweep_bristles(model, chain, drive, prm, con, jc, ws, out, SWEEP_AGAIN)
