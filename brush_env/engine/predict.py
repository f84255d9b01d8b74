"""Start of a (sub)step and Newton's starting point (the predictors).

``_prepare``: the constants of the two-step formula of eq 11 (momentum and strain histories,
the damping factors of eq 4-5); ``start_step``: those and the tip node's rate history for contact
(eq 6-10).  ``predict_start``: the start configuration carried rigidly by the base
(``_rigid_predict``), or the recent motion extrapolated in the base frame (``_extrapolate``,
second or third order), whichever has the smaller residual of eq 11 (a tip in contact keeps
the extrapolation without trying the rigid start while its residual is below
``EXTRAP_TRUST`` tolerances).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT, local_rot_into, log3s, reorthonormalize, rodrigues
from .contact import in_contact
from .residual import bristle_residual, strain_at

#: ``extrap`` of ``predict_start`` for a re-solve in a later Gauss-Seidel sweep (warm start)
WARM = -1

#: ``predict_start``'s starting points, one call site each (int64: one type, no literal copies)
_RIGID = np.int64(0)
_EXTRAP = np.int64(1)
_WARM = np.int64(2)
_RELOAD = np.int64(3)

#: a tip in contact keeps the extrapolated start unless its residual of eq 11 exceeds this many
#: times Newton's tolerance.  On the paper turn the rigid carry won only where the extrapolation's
#: residual was >= 1.04e5 tolerances (an overshoot into the plate); trusting the extrapolation
#: whatever its residual (no such test) moved the 6-body turn by 1.97 %, and trusting it below
#: ~1e7 tolerances for every tip made a 6-body 4 ms tip-tip run diverge (docs/benchmarks.md,
#: "The contact predictor's rigid start")
EXTRAP_TRUST = 1.0e5


@njit(**HOT, inline="always")
def _node_key(p, R, key, at, store):
    """A node's pose (centre p (3,), rotation R (3, 3)) against the strain cache's key ``key``
    from entry ``at`` (12 floats); store: write it there instead.  Returns True if it equals the
    key (a NaN key never does)."""
    if store:
        for a in range(3):
            key[at + a] = p[a]
            for b in range(3):
                key[at + 3 + 3 * a + b] = R[a, b]
        return True
    for a in range(3):
        if key[at + a] != p[a]:
            return False
        for b in range(3):
            if key[at + 3 + 3 * a + b] != R[a, b]:
                return False
    return True


@njit(**HOT, inline="always")
def _strain_history(br, model, chain, sub, base, hist, el, jc):
    """hist.ehist[k] <- c1 e_n + c2 e_{n-1} of every element k of the bristle; e_n into the
    strain cache (jc.E), e_{n-1} from it where the element's nodes match their keys
    (``_prepare``); the strains alone (``strain_at``).

    The key of element k is its two nodes' poses, each kept once (jc.EK[i, 0:12]: body i's
    centre and rotation when E[i] was evaluated; jc.EK[b0, 12:24]: the base node's, element 0's
    node A): element k's node A is element k - 1's node B, so 12 floats a body are compared and
    stored instead of 24 an element.  Every element of a bristle is stored in one call, so a key
    pair that matches is one that E[i] was evaluated from.  All look-ups come before the stores
    (a store overwrites the node B key of the element before it)."""
    e = el.e
    c1 = sub.c1
    c2 = sub.c2
    b0 = br.b0
    for k in range(br.n):
        for a in range(6):
            hist.ehist[k, a] = 0.0
    # c2 e_{n-1} first, then c1 e_n: the sum is the same to the bit (0 + x = x, x + y = y + x)
    if c2 != 0.0:
        prev = _node_key(base.pAp, base.RAp, jc.EK[b0], 12, False)  # node A of element 0
        for k in range(br.n):
            i = b0 + k
            here = _node_key(chain.ppos[i], chain.prot[i], jc.EK[i], 0, False)
            if prev and here:
                for a in range(6):
                    hist.ehist[k, a] += c2 * jc.E[i, a]
            else:
                strain_at(k, br, model, chain.ppos, chain.prot, base.pAp, base.RAp, e)
                for a in range(6):
                    hist.ehist[k, a] += c2 * e[a]
            prev = here
    if c1 != 0.0:
        _node_key(base.pAs, base.RAs, jc.EK[b0], 12, True)
        for k in range(br.n):
            i = b0 + k
            strain_at(k, br, model, chain.pos, chain.rot, base.pAs, base.RAs, e)
            _node_key(chain.pos[i], chain.rot[i], jc.EK[i], 0, True)
            for a in range(6):
                jc.E[i, a] = e[a]
                hist.ehist[k, a] += c1 * e[a]


@njit(**HOT, inline="always")
def _prepare(br, model, chain, sub, base, hist, el, jc):
    """Constants of one (sub)step: cm = c1 c_n + c2 c_{n-1}, vm, Lm (angular momenta),
    thp = c2 theta_{n-1} (relative to R_n), ehist = c1 e_n + c2 e_{n-1} (element strains),
    and the damping factors gs = 1 + beta c0 / h, hs = beta / h (eq 4-5; 1 and 0 for statics).

    The strains e_n are kept in ``jc`` (E, with their inputs as the key EK): e_{n-1} of the next
    whole step is the same function of the same numbers (its t_{n-1} poses are this step's
    start, byte for byte), so it is taken from there when the key matches -- 6 of the 12 element
    evaluations of a 6-body bristle-step, with the result unchanged to the bit."""
    bp = model.bp
    c1 = sub.c1
    c2 = sub.c2
    tmp = el.th
    for k in range(br.n):
        i = br.b0 + k
        beta = 0.0 if sub.static else bp[i].beta
        hist.gs[k] = 1.0 + beta * sub.c0 * sub.inv_h
        hist.hs[k] = beta * sub.inv_h
        for a in range(3):
            for bb in range(3):
                hist.Rn[k, a, bb] = chain.rot[i, a, bb]
            hist.cm[k, a] = c1 * chain.pos[i, a] + c2 * chain.ppos[i, a]
            hist.vm[k, a] = c1 * chain.vel[i, a] + c2 * chain.pvel[i, a]
            hist.Lm[k, a] = 0.0
            hist.thp[k, a] = 0.0
        for which in range(2):
            coef = c1 if which == 0 else c2
            if coef == 0.0:
                continue
            RR = chain.rot[i] if which == 0 else chain.prot[i]
            om = chain.omg[i] if which == 0 else chain.pomg[i]
            ob0 = (RR[0, 0] * om[0] + RR[1, 0] * om[1] + RR[2, 0] * om[2]) * bp[i].J[0]
            ob1 = (RR[0, 1] * om[0] + RR[1, 1] * om[1] + RR[2, 1] * om[2]) * bp[i].J[1]
            ob2 = (RR[0, 2] * om[0] + RR[1, 2] * om[1] + RR[2, 2] * om[2]) * bp[i].J[2]
            for a in range(3):
                hist.Lm[k, a] += coef * (RR[a, 0] * ob0 + RR[a, 1] * ob1 + RR[a, 2] * ob2)
        if c2 != 0.0:
            local_rot_into(chain.prot[i], chain.rot[i], tmp)
            for a in range(3):
                hist.thp[k, a] = c2 * tmp[a]
    _strain_history(br, model, chain, sub, base, hist, el, jc)


@njit(**HOT, inline="always")
def start_step(br, model, chain, sub, base, con, ws, jc):
    """Set up one (sub)step of one bristle: the step constants (``_prepare``), the start state
    kept in ws.it (s_pos, s_rot, s_vel, s_omg) and the tip node's rate history for contact."""
    _prepare(br, model, chain, sub, base, ws.hist, ws.el, jc)
    start_state(br, chain, ws.it, True)
    # tip node history for the contact rate and the stiction deformation
    il = br.il
    tip_state = con.tip_state[br.b]
    half = model.bp[il].half
    for a in range(3):
        ptn = chain.pos[il, a] + half * chain.rot[il, a, 0]
        ptp = chain.ppos[il, a] + half * chain.prot[il, a, 0]
        tip_state.pn[a] = ptn
        # the rate's history relative to p_n (``contact.tip_load``): a tip at rest has v = 0
        # exactly however c0 p rounds (with FMA it did not: docs/benchmarks.md, session 32)
        tip_state.hist[a] = (sub.c0 + sub.c1) * ptn + sub.c2 * ptp


@njit(**HOT, inline="always")
def start_state(br, chain, it, save):
    """save: it.s_pos/s_rot/s_vel/s_omg <- the bristle's state at the (sub)step's start; else the
    bristle back at that state (Newton failed)."""
    for k in range(br.n):
        i = br.b0 + k
        for a in range(3):
            if save:
                it.s_pos[k, a] = chain.pos[i, a]
                it.s_vel[k, a] = chain.vel[i, a]
                it.s_omg[k, a] = chain.omg[i, a]
            else:
                chain.pos[i, a] = it.s_pos[k, a]
                chain.vel[i, a] = it.s_vel[k, a]
                chain.omg[i, a] = it.s_omg[k, a]
            for bb in range(3):
                if save:
                    it.s_rot[k, a, bb] = chain.rot[i, a, bb]
                else:
                    chain.rot[i, a, bb] = it.s_rot[k, a, bb]


@njit(**HOT, inline="always")
def _rows3(src, s0, dst, d0, n):
    """dst[d0 + k] <- src[s0 + k], k < n (rows of 3)."""
    for k in range(n):
        for a in range(3):
            dst[d0 + k, a] = src[s0 + k, a]


@njit(**HOT, inline="always")
def _rows33(src, s0, dst, d0, n):
    """dst[d0 + k] <- src[s0 + k], k < n (3 x 3 blocks)."""
    for k in range(n):
        for a in range(3):
            for c in range(3):
                dst[d0 + k, a, c] = src[s0 + k, a, c]


@njit(**HOT, inline="always")
def chain_rows(chain, c0, v3, R, r0, n, save):
    """The state of bodies c0 .. c0 + n - 1 to (``save``) or from rows r0 .. r0 + n - 1 of the
    stacks v3 (7, m, 3): pos, vel, omg, ppos, pvel, pomg, pppos, and R (3, m, 3, 3): rot, prot,
    pprot.  One contiguous loop per array: the loop over a tuple of the ten arrays indexed at run
    time that this replaced cost ~10 instructions a number (docs/benchmarks.md, session 32)."""
    if save:
        _rows3(chain.pos, c0, v3[0], r0, n)
        _rows3(chain.vel, c0, v3[1], r0, n)
        _rows3(chain.omg, c0, v3[2], r0, n)
        _rows3(chain.ppos, c0, v3[3], r0, n)
        _rows3(chain.pvel, c0, v3[4], r0, n)
        _rows3(chain.pomg, c0, v3[5], r0, n)
        _rows3(chain.pppos, c0, v3[6], r0, n)
        _rows33(chain.rot, c0, R[0], r0, n)
        _rows33(chain.prot, c0, R[1], r0, n)
        _rows33(chain.pprot, c0, R[2], r0, n)
    else:
        _rows3(v3[0], r0, chain.pos, c0, n)
        _rows3(v3[1], r0, chain.vel, c0, n)
        _rows3(v3[2], r0, chain.omg, c0, n)
        _rows3(v3[3], r0, chain.ppos, c0, n)
        _rows3(v3[4], r0, chain.pvel, c0, n)
        _rows3(v3[5], r0, chain.pomg, c0, n)
        _rows3(v3[6], r0, chain.pppos, c0, n)
        _rows33(R[0], r0, chain.rot, c0, n)
        _rows33(R[1], r0, chain.prot, c0, n)
        _rows33(R[2], r0, chain.pprot, c0, n)


@njit(**HOT, inline="always")
def save_chain(br, pos, rot, t_pos, t_rot):
    """t_pos/t_rot <- one bristle's positions and rotations (a trial point to come back to)."""
    for k in range(br.n):
        for a in range(3):
            t_pos[k, a] = pos[br.b0 + k, a]
            for bb in range(3):
                t_rot[k, a, bb] = rot[br.b0 + k, a, bb]


@njit(**HOT, inline="always")
def load_chain(br, pos, rot, t_pos, t_rot):
    """pos/rot of one bristle <- t_pos/t_rot (see ``save_chain``)."""
    for k in range(br.n):
        for a in range(3):
            pos[br.b0 + k, a] = t_pos[k, a]
            for bb in range(3):
                rot[br.b0 + k, a, bb] = t_rot[k, a, bb]


@njit(**HOT, inline="always")
def _to_base(RA, pA, x, a):
    """Component a of RA^T (x - pA) (a point in the base frame)."""
    return RA[0, a] * (x[0] - pA[0]) + RA[1, a] * (x[1] - pA[1]) + RA[2, a] * (x[2] - pA[2])


@njit(**HOT, inline="always")
def _extrapolate(br, chain, order, base, it, mot):
    """chain.pos/rot <- the state at t_n (it.s_pos, it.s_rot) moved on by polynomial
    extrapolation in the base frame.

    With x = RA^T (c - pA) and Q = RA^T R at t_n, t_{n-1}, t_{n-2} (base poses (pAs, RAs),
    (pAp, RAp), (pAq, RAq)):  order 2: x = 2 x_n - x_{n-1}, Q = Q_n Q_{n-1}^T Q_n (constant rates);
    order 3: x = 3 x_n - 3 x_{n-1} + x_{n-2}, Q = exp(phi_2 - 3 phi_1) Q_n with
    phi_j = log(Q_{n-j} Q_n^T) (the quadratic through the three rotation vectors about Q_n).  Then
    back to the world with the base at the step's end (pAe, RAe).

    The 3x3 products run on scalars (``_Q``, ``_QQt``): through the scratch arrays, the one large
    compiled function reloaded each array's data pointer before most multiply-adds (session 34).
    The arithmetic is the same: with strict kernels the result is the same to the bit; with FMA
    (``_kernels.HOT``) LLVM fuses some products differently, a difference in the last bits.
    """
    pos = chain.pos
    rot = chain.rot
    s_pos = it.s_pos
    s_rot = it.s_rot
    ppos = chain.ppos
    prot = chain.prot
    pppos = chain.pppos
    pprot = chain.pprot
    pAs, RAs, pAp, RAp = base.pAs, base.RAs, base.pAp, base.RAp
    pAq, RAq, pAe, RAe = base.pAq, base.RAq, base.pAe, base.RAe
    phi1, phi2 = mot.phi1, mot.phi2
    third = order >= 3
    for k in range(br.n):
        i = br.b0 + k
        x0 = _to_base(RAs, pAs, s_pos[k], 0)
        x1 = _to_base(RAs, pAs, s_pos[k], 1)
        x2 = _to_base(RAs, pAs, s_pos[k], 2)
        m0 = _to_base(RAp, pAp, ppos[i], 0)
        m1 = _to_base(RAp, pAp, ppos[i], 1)
        m2 = _to_base(RAp, pAp, ppos[i], 2)
        if third:
            xp0 = 3.0 * x0 - 3.0 * m0 + _to_base(RAq, pAq, pppos[i], 0)
            xp1 = 3.0 * x1 - 3.0 * m1 + _to_base(RAq, pAq, pppos[i], 1)
            xp2 = 3.0 * x2 - 3.0 * m2 + _to_base(RAq, pAq, pppos[i], 2)
        else:
            xp0 = 2.0 * x0 - m0
            xp1 = 2.0 * x1 - m1
            xp2 = 2.0 * x2 - m2
        Qn = _Q(RAs, s_rot[k])
        Qp = _Q(RAp, prot[i])
        n00, n01, n02, n10, n11, n12, n20, n21, n22 = Qn
        if third:
            Qq = _Q(RAq, pprot[i])
            # log(Q_{n-1} Q_n^T), log(Q_{n-2} Q_n^T) (``local_rot_into``'s products)
            a00, a01, a02, a10, a11, a12, a20, a21, a22 = _QQt(Qp, Qn)
            log3s(a00, a01, a02, a10, a11, a12, a20, a21, a22, phi1)
            a00, a01, a02, a10, a11, a12, a20, a21, a22 = _QQt(Qq, Qn)
            log3s(a00, a01, a02, a10, a11, a12, a20, a21, a22, phi2)
            e00, e01, e02, e10, e11, e12, e20, e21, e22 = rodrigues(
                phi2[0] - 3.0 * phi1[0], phi2[1] - 3.0 * phi1[1], phi2[2] - 3.0 * phi1[2]
            )
        else:
            # Qq = Qn Qp^T, the last step's rotation, repeated once more
            e00, e01, e02, e10, e11, e12, e20, e21, e22 = _QQt(Qn, Qp)
        # Qr = E Qn (``rotate_left``'s and the old product's order)
        r00 = e00 * n00 + e01 * n10 + e02 * n20
        r01 = e00 * n01 + e01 * n11 + e02 * n21
        r02 = e00 * n02 + e01 * n12 + e02 * n22
        r10 = e10 * n00 + e11 * n10 + e12 * n20
        r11 = e10 * n01 + e11 * n11 + e12 * n21
        r12 = e10 * n02 + e11 * n12 + e12 * n22
        r20 = e20 * n00 + e21 * n10 + e22 * n20
        r21 = e20 * n01 + e21 * n11 + e22 * n21
        r22 = e20 * n02 + e21 * n12 + e22 * n22
        for a in range(3):
            pos[i, a] = pAe[a] + RAe[a, 0] * xp0 + RAe[a, 1] * xp1 + RAe[a, 2] * xp2
            rot[i, a, 0] = RAe[a, 0] * r00 + RAe[a, 1] * r10 + RAe[a, 2] * r20
            rot[i, a, 1] = RAe[a, 0] * r01 + RAe[a, 1] * r11 + RAe[a, 2] * r21
            rot[i, a, 2] = RAe[a, 0] * r02 + RAe[a, 1] * r12 + RAe[a, 2] * r22
        reorthonormalize(rot[i])


@njit(**HOT, inline="always")
def _Q(RA, R):
    """The nine entries of RA^T R, row by row."""
    return (
        RA[0, 0] * R[0, 0] + RA[1, 0] * R[1, 0] + RA[2, 0] * R[2, 0],
        RA[0, 0] * R[0, 1] + RA[1, 0] * R[1, 1] + RA[2, 0] * R[2, 1],
        RA[0, 0] * R[0, 2] + RA[1, 0] * R[1, 2] + RA[2, 0] * R[2, 2],
        RA[0, 1] * R[0, 0] + RA[1, 1] * R[1, 0] + RA[2, 1] * R[2, 0],
        RA[0, 1] * R[0, 1] + RA[1, 1] * R[1, 1] + RA[2, 1] * R[2, 1],
        RA[0, 1] * R[0, 2] + RA[1, 1] * R[1, 2] + RA[2, 1] * R[2, 2],
        RA[0, 2] * R[0, 0] + RA[1, 2] * R[1, 0] + RA[2, 2] * R[2, 0],
        RA[0, 2] * R[0, 1] + RA[1, 2] * R[1, 1] + RA[2, 2] * R[2, 1],
        RA[0, 2] * R[0, 2] + RA[1, 2] * R[1, 2] + RA[2, 2] * R[2, 2],
    )


@njit(**HOT, inline="always")
def _QQt(A, B):
    """The nine entries of A B^T, row by row (A, B: nine entries each, row by row)."""
    a00, a01, a02, a10, a11, a12, a20, a21, a22 = A
    b00, b01, b02, b10, b11, b12, b20, b21, b22 = B
    return (
        a00 * b00 + a01 * b01 + a02 * b02,
        a00 * b10 + a01 * b11 + a02 * b12,
        a00 * b20 + a01 * b21 + a02 * b22,
        a10 * b00 + a11 * b01 + a12 * b02,
        a10 * b10 + a11 * b11 + a12 * b12,
        a10 * b20 + a11 * b21 + a12 * b22,
        a20 * b00 + a21 * b01 + a22 * b02,
        a20 * b10 + a21 * b11 + a22 * b12,
        a20 * b20 + a21 * b21 + a22 * b22,
    )


@njit(**HOT, inline="always")
def _rigid_predict(br, chain, base, it, mot):
    """chain.pos/rot <- the start configuration (it.s_pos, it.s_rot) carried rigidly by the
    base's motion over the step, T = base_end o base_start^-1: a driven, nearly quasi-static
    chain starts Newton close."""
    Tr = mot.Tr
    pAs, RAs, pAe, RAe = base.pAs, base.RAs, base.pAe, base.RAe
    s_pos = it.s_pos
    s_rot = it.s_rot
    for a in range(3):
        for bb in range(3):
            Tr[a, bb] = RAe[a, 0] * RAs[bb, 0] + RAe[a, 1] * RAs[bb, 1] + RAe[a, 2] * RAs[bb, 2]
    for k in range(br.n):
        i = br.b0 + k
        for a in range(3):
            chain.pos[i, a] = (
                pAe[a]
                + Tr[a, 0] * (s_pos[k, 0] - pAs[0])
                + Tr[a, 1] * (s_pos[k, 1] - pAs[1])
                + Tr[a, 2] * (s_pos[k, 2] - pAs[2])
            )
            for bb in range(3):
                chain.rot[i, a, bb] = (
                    Tr[a, 0] * s_rot[k, 0, bb]
                    + Tr[a, 1] * s_rot[k, 1, bb]
                    + Tr[a, 2] * s_rot[k, 2, bb]
                )


@njit(**HOT, inline="always")
def predict_start(br, model, chain, sub, base, con, ws, rootw, extrap):
    """Start Newton from the better of two predictors; returns the residual norm there.

    (1) The start configuration carried rigidly by the base's motion over the step.  (2) With
    whole steps of history, the recent motion extrapolated in the base frame (third order with
    two steps, second with one): a bristle that slides or bends steadily starts Newton O(h^3)
    close instead of O(h).  The one with the smaller residual starts Newton (the rigid one wins at
    contact onset, where extrapolation can overshoot into the plate).  A free tip evaluates (1)
    first and stops there if it is already converged; a tip in contact evaluates (2) first and
    stops there unless its residual exceeds ``EXTRAP_TRUST`` times Newton's tolerance (an
    overshoot into the plate shows as a residual of that size: the penalty force of eq 6 of a
    tunnelled tip), so the usual winner costs one residual, not two or three.  Third order only
    for a tip in contact: a free bristle gains too few iterations (1.04 -> 0.95 per step at
    3 ms) to pay for the extra rotation logs (~8 % slower in bench engine)."""
    it = ws.it
    touching = in_contact(con.tip_state[br.b])
    if extrap == 3 and not touching:
        extrap = 2
    # a tip in contact tries the extrapolation first (it wins ~99.7 % of those bristle-steps on
    # the paper turn); the rigid carry is the fall-back when the extrapolation looks tunnelled
    extrap_first = touching and extrap >= 2
    nrm = np.inf
    nx = np.inf
    # one call site each for the residual (first, second, first again) and for each predictor
    # (first or second): all three are inlined, and each copy costs compile time (the scalar
    # extrapolation with its rotation logs most: docs/benchmarks.md, session 35)
    for stage in range(3):
        start = _RELOAD  # stage 2: back to the first start, if it was the better one
        if stage == 0:
            start = _WARM if extrap == WARM else (_EXTRAP if extrap_first else _RIGID)
        elif stage == 1:
            if extrap == WARM:
                break
            if extrap < 2 or nrm <= (EXTRAP_TRUST if extrap_first else 1.0) * sub.rtol:
                break
            save_chain(br, chain.pos, chain.rot, it.t_pos, it.t_rot)
            start = _RIGID if extrap_first else _EXTRAP
        elif nx < nrm:
            nrm = nx
            break
        if start == _EXTRAP:
            _extrapolate(br, chain, extrap, base, it, ws.mot)
        elif start == _RIGID:
            _rigid_predict(br, chain, base, it, ws.mot)
        elif start == _WARM:
            # a later sweep: this bristle's own solution of the previous sweep
            load_chain(br, chain.pos, chain.rot, ws.sw.warm_pos[br.b0 :], ws.sw.warm_rot[br.b0 :])
        else:
            load_chain(br, chain.pos, chain.rot, it.t_pos, it.t_rot)
        r = bristle_residual(br, model, chain, sub, base, con, ws, rootw)
        if stage == 1:
            nx = r
        else:
            nrm = r
    return nrm
