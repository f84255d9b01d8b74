"""Implicit time stepping: per-bristle Newton on the block-tridiagonal system (numba kernels).

Scheme: the momentum balance of eq 11 for every body, discretised with the two-step formula
``y'(t_{n+1}) ~ (c0 y_{n+1} + c1 y_n + c2 y_{n-1}) / h`` applied to positions, velocities, angular
momenta and the element strains of the damping term: backward Euler ``(1, -1, 0)`` (L-stable,
first order) or BDF2 ``(3/2, -2, 1/2)`` (L-stable, second order).  Rotations are updated
multiplicatively, ``R <- exp([dtheta]) R``, and enter the rates through rotation vectors relative
to ``R_n``.

Each bristle is an open chain, so its Newton matrix is block tridiagonal (6x6 blocks) and is solved
by block Thomas in O(n).  Newton uses a backtracking line search on the scaled residual.  When
Newton fails, the bristle alone repeats the step as two half steps (recursively, down to
``h / 2**max_levels``), with the base pose interpolated (linear position, geodesic rotation).  A
bristle that still fails is restored to its state at the start of the step and reported.

Bristles are coupled only through the base (kinematic) and tip-tip contact (handled outside, by
splitting), so ``step_bristles`` loops over bristles without Python overhead.

The kernels take the named records of ``records.py`` (model, chain state, drive, contact scene,
Newton cache, scratch), never position-indexed tuples.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import (
    HOT,
    _element_gen,
    _local_rot_into,
    _lu6,
    _node,
    _rotate_left,
    block_factor_head,
    block_solve,
    reorthonormalize,
)
from .contact import (
    A_RADIUS,
    C_VD,
    S_BETA,
    S_BNEW,
    S_DELTA,
    S_DNEW,
    S_HIST,
    S_PN,
    in_contact,
    penetration_step_limit,
    slip_step_limit,
    tip_load,
)
from .coupling import place_partners, store_tip_load
from .records import (
    B_BETA,
    B_FSCALE,
    B_HALF,
    B_JX,
    B_LEN,
    B_MASS,
    Bristle,
    Damp,
    Node,
    Substep,
    Trial,
)
from .tipblock import add_tip_block as _add_tip_block

# status codes per bristle (step_bristles' ``out.status``)
OK = 0
NEWTON_FAILED = 1  # Newton failed on the smallest sub-step; the bristle is restored

# layout of the float64 settings vector ``prm``
P_H = 0  # time step [s]
P_METHOD = 1  # 0 backward Euler, 1 BDF2
P_STATIC = 2  # 1: static equilibrium (no inertia, no damping)
P_RTOL = 3  # Newton tolerance on the residual, relative to the bristle force scale
P_MAXIT = 4  # Newton iterations per attempt
P_MAXLEV = 5  # sub-stepping levels (h / 2**levels is the smallest step)
P_G = 6  # 6, 7, 8: gravity [mm/s^2]
P_JAGE = 9  # steps a factored Newton matrix may be reused
P_SWEEPS = 10  # most Gauss-Seidel sweeps over the bristles per step (1: one sweep, the tip-tip lag)
P_TTTOL = 11  # [mm] a partner tip that moved by less than this does not call for another sweep
N_PRM = 12

STAGNATION = 100.0  # accept a stagnating Newton within this factor of the tolerance
MAX_ROT_STEP = 0.5  # [rad] largest rotation increment of one Newton iteration
MAX_TIP_STEP = 0.25  # largest tip displacement of one Newton iteration, in tip radii
#: Reused Newton factors are rebuilt when an iteration with them reduces the residual by less than
#: SLOW and, at that rate, more than REBUILD_ITERS further iterations would be needed: a rebuild
#: (finite-difference chain Jacobian + factorisation, ~8.5 us at 6 bodies) costs about as much
#: as four iterations with reused factors (~2 us each).
SLOW = 0.1
REBUILD_ITERS = 3.0
#: ``extrap`` of ``_predict`` for a re-solve in a later Gauss-Seidel sweep (warm start)
WARM = -1


@njit(**HOT)
def _base_pose(p0, R0, p1, R1, s, pout, Rout, tmp):
    """Base pose at fraction s of the step: linear in position, geodesic in rotation."""
    for a in range(3):
        pout[a] = (1.0 - s) * p0[a] + s * p1[a]
    _local_rot_into(R1, R0, tmp)  # tmp = log(R1 R0^T)
    _rotate_left(s * tmp[0], s * tmp[1], s * tmp[2], R0, Rout)


# ------------------------------------------------------------------------------ residual (eq 11)
@njit(**HOT, inline="always")
def _element_at(k, br, model, P, Q, pAb, RAb, damp, el):
    """Element k of bristle ``br`` (eq 5) for body poses P/Q (positions/rotations of all bodies)
    and the base node (pAb, RAb): generalised forces into el.out12, strain into el.e."""
    bp = model.bp
    i = br.b0 + k
    kind = model.elem[i]
    B = Node(P[i], Q[i], bp[i, B_HALF])
    # one call with a run-time flag: a literal True/False would compile each element twice more
    isroot = k == 0
    j = i - 1 if k > 0 else i
    A = Node(pAb, RAb, 0.0) if isroot else Node(P[j], Q[j], bp[j, B_HALF])
    _element_gen(kind, isroot, A, pAb, B, model.K[i], bp[i, B_LEN], damp, el.out12, el.e)


@njit(**HOT, inline="always")
def _inertia_residual(br, model, chain, sub, hist, res, th):
    """res <- rate of momentum minus gravity of every body (eq 11, the discrete formula)."""
    bp = model.bp
    pos = chain.pos
    rot = chain.rot
    c0 = sub.c0
    inv_h = sub.inv_h
    gvec = sub.g
    for k in range(br.n):
        i = br.b0 + k
        m = bp[i, B_MASS]
        if sub.static:
            for a in range(3):
                res[k, a] = -m * gvec[a]
                res[k, 3 + a] = 0.0
            continue
        for a in range(3):
            vk = (c0 * pos[i, a] + hist.cm[k, a]) * inv_h
            res[k, a] = m * (c0 * vk + hist.vm[k, a]) * inv_h - m * gvec[a]
        _local_rot_into(rot[i], hist.Rn[k], th)
        om0 = (c0 * th[0] + hist.thp[k, 0]) * inv_h
        om1 = (c0 * th[1] + hist.thp[k, 1]) * inv_h
        om2 = (c0 * th[2] + hist.thp[k, 2]) * inv_h
        R = rot[i]
        ob0 = (R[0, 0] * om0 + R[1, 0] * om1 + R[2, 0] * om2) * bp[i, B_JX]
        ob1 = (R[0, 1] * om0 + R[1, 1] * om1 + R[2, 1] * om2) * bp[i, B_JX + 1]
        ob2 = (R[0, 2] * om0 + R[1, 2] * om1 + R[2, 2] * om2) * bp[i, B_JX + 2]
        for a in range(3):
            La = R[a, 0] * ob0 + R[a, 1] * ob1 + R[a, 2] * ob2
            res[k, 3 + a] = (c0 * La + hist.Lm[k, a]) * inv_h


@njit(**HOT, inline="always")
def _residual_norm(br, bp, res):
    """Scaled max norm of the residual: forces / bristle force scale, moments / (scale * l);
    inf if any entry is not finite."""
    nrm = 0.0
    for k in range(br.n):
        i = br.b0 + k
        fs = bp[i, B_FSCALE]
        ls = fs * bp[i, B_LEN]
        for a in range(3):
            v1 = abs(res[k, a]) / fs
            v2 = abs(res[k, 3 + a]) / ls
            if not np.isfinite(v1) or not np.isfinite(v2):
                return np.inf
            if v1 > nrm:
                nrm = v1
            if v2 > nrm:
                nrm = v2
    return nrm


@njit(**HOT, inline="always")
def _residual(br, model, chain, sub, base, con, ws, rootw):
    """Residual of eq 11 for one bristle (rate of momentum minus forces, N and N*mm) into
    ``ws.it.res``: inertia and gravity, the elements (eq 1-5), the tip load (eq 6-10, Table 3).

    Returns the scaled max norm (``_residual_norm``).  Also fills ``rootw`` (force and moment that
    the root element applies to the head, at the root node) and ``ws.it.tipF``/``tipK`` (tip load
    and its stiffness d F / d p_tip).
    """
    it = ws.it
    hist = ws.hist
    el = ws.el
    res = it.res
    out12 = el.out12
    _inertia_residual(br, model, chain, sub, hist, res, el.th)
    for k in range(br.n):
        damp = Damp(hist.ehist[k], hist.gs[k], hist.hs[k])
        _element_at(k, br, model, chain.pos, chain.rot, base.pAe, base.RAe, damp, el)
        if k == 0:
            for a in range(6):
                rootw[a] = out12[a]
        else:
            for a in range(6):
                res[k - 1, a] -= out12[a]
        for a in range(6):
            res[k, a] -= out12[6 + a]
    il = br.il
    pos = chain.pos
    pt = el.pt
    tipF = it.tipF
    _node(pos[il], chain.rot[il], model.bp[il, B_HALF], pt)
    tip_load(br.b, pt, sub, con, tipF, it.tipK, ws.tipw)
    rx = pt[0] - pos[il, 0]
    ry = pt[1] - pos[il, 1]
    rz = pt[2] - pos[il, 2]
    n = br.n
    res[n - 1, 0] -= tipF[0]
    res[n - 1, 1] -= tipF[1]
    res[n - 1, 2] -= tipF[2]
    res[n - 1, 3] -= ry * tipF[2] - rz * tipF[1]
    res[n - 1, 4] -= rz * tipF[0] - rx * tipF[2]
    res[n - 1, 5] -= rx * tipF[1] - ry * tipF[0]
    return _residual_norm(br, model.bp, res)


# ------------------------------------------------------------------------------ Newton matrix
@njit(**HOT)
def _jacobian(br, model, chain, sub, base, hist, D, U, L, ws):
    """Newton matrix d(res)/d(q), q_k = (dc_k, dtheta_k) in world axes (block tridiagonal).

    Inertia blocks m c0^2/h^2 and R J R^T c0^2/h^2 (terms of order omega*h dropped); element
    blocks by forward differences of the element's generalised forces; tip load blocks from the
    tip stiffness ``ws.it.tipK`` and the lever arm.  The Jacobian only steers Newton: the
    converged state is fixed by the residual alone.
    """
    _jacobian_chain(br, model, chain, sub, base, hist, D, U, L, ws.el)
    _add_tip_block(D[br.n - 1], model.bp, chain.rot, br.il, ws.it, ws.blk)


@njit(**HOT, inline="always")
def _inertia_blocks(br, bp, rot, sub, D):
    """D_k <- the inertia blocks m c0^2/h^2 I and R J R^T c0^2/h^2 (zero for statics)."""
    if sub.static:
        return
    s2 = sub.c0 * sub.c0 * sub.inv_h * sub.inv_h
    for k in range(br.n):
        i = br.b0 + k
        R = rot[i]
        for a in range(3):
            D[k, a, a] = bp[i, B_MASS] * s2
            for b in range(3):
                D[k, 3 + a, 3 + b] = s2 * (
                    R[a, 0] * bp[i, B_JX] * R[b, 0]
                    + R[a, 1] * bp[i, B_JX + 1] * R[b, 1]
                    + R[a, 2] * bp[i, B_JX + 2] * R[b, 2]
                )


@njit(**HOT, inline="always")
def _perturbed(src, col, eps_x, eps_r, pos, rot, cP, RP):
    """(cP, RP) <- body ``src``'s pose moved along coordinate ``col`` (0-2: translation by eps_x,
    3-5: rotation by eps_r about a world axis).  Returns the step taken."""
    for a in range(3):
        cP[a] = pos[src, a]
    if col < 3:
        cP[col] += eps_x
        for a in range(3):
            for b in range(3):
                RP[a, b] = rot[src, a, b]
        return eps_x
    _rotate_left(
        eps_r if col == 3 else 0.0,
        eps_r if col == 4 else 0.0,
        eps_r if col == 5 else 0.0,
        rot[src],
        RP,
    )
    return eps_r


@njit(**HOT)
def _jacobian_chain(br, model, chain, sub, base, hist, D, U, L, el):
    """The inertia and element blocks of ``_jacobian`` (everything but the tip load)."""
    bp = model.bp
    pos = chain.pos
    rot = chain.rot
    pAb = base.pAe
    RAb = base.RAe
    e = el.e
    basef = el.base12
    pert = el.pert12
    for k in range(br.n):
        for a in range(6):
            for b in range(6):
                D[k, a, b] = 0.0
                U[k, a, b] = 0.0
                L[k, a, b] = 0.0
    _inertia_blocks(br, bp, rot, sub, D)
    for k in range(br.n):
        i = br.b0 + k
        hB = bp[i, B_HALF]
        ln = bp[i, B_LEN]
        epsx = 1e-7 * ln
        epsr = 1e-7
        isroot = k == 0
        j = i - 1 if k > 0 else i  # index of body A (unused for the root element)
        A = Node(pAb, RAb, 0.0) if isroot else Node(pos[j], rot[j], bp[j, B_HALF])
        B = Node(pos[i], rot[i], hB)
        damp = Damp(hist.ehist[k], hist.gs[k], hist.hs[k])
        kind = model.elem[i]
        _element_gen(kind, isroot, A, pAb, B, model.K[i], ln, damp, basef, e)
        nside = 1 if isroot else 2
        for side in range(nside):  # side 0: perturb body B (= k), side 1: body A (= k-1)
            src = i if side == 0 else j
            for col in range(6):
                eps = _perturbed(src, col, epsx, epsr, pos, rot, el.cP, el.RP)
                if side == 0:
                    BP = Node(el.cP, el.RP, hB)
                    _element_gen(kind, isroot, A, pAb, BP, model.K[i], ln, damp, pert, e)
                else:
                    AP = Node(el.cP, el.RP, A.half)
                    # (isroot is False on this side)
                    _element_gen(kind, isroot, AP, pAb, B, model.K[i], ln, damp, pert, e)
                for a in range(6):
                    dA = (pert[a] - basef[a]) / eps  # d(force on A)
                    dB = (pert[6 + a] - basef[6 + a]) / eps  # d(force on B)
                    if side == 0:
                        D[k, a, col] -= dB
                        if not isroot:
                            U[k - 1, a, col] -= dA
                    else:
                        D[k - 1, a, col] -= dA
                        L[k, a, col] -= dB


@njit(**HOT, inline="always")
def _tip_refactor(br, D, piv, S, bp, rot, ws):
    """Last block of the factored Newton matrix <- LU(S + tip block at the current tip load).

    S is the tip body's Schur complement without the tip load (``block_factor_head``), so this
    makes the contact part of the Newton matrix current for the price of one 6x6 LU, while the
    chain's blocks (which change slowly) are reused.  Returns False if the block is singular."""
    Dl = D[br.n - 1]
    for a in range(6):
        for c in range(6):
            Dl[a, c] = S[a, c]
    _add_tip_block(Dl, bp, rot, br.il, ws.it, ws.blk)
    return _lu6(Dl, piv[br.n - 1])


@njit(**HOT, inline="always")
def _rebuild_factors(br, model, chain, sub, base, jc, ws, key):
    """Fresh Newton matrix of one bristle (``_jacobian_chain``), factored by block Thomas up to
    the tip body, its Schur complement kept in jc.S, the tip block added at the current tip load.
    Returns False (and marks the factors stale) if a pivot block is singular."""
    b0 = br.b0
    n = br.n
    D = jc.D[b0 : b0 + n]
    G = jc.G[b0 : b0 + n]
    L = jc.L[b0 : b0 + n]
    piv = jc.piv[b0 : b0 + n]
    S = jc.S[br.b]
    _jacobian_chain(br, model, chain, sub, base, ws.hist, D, ws.it.U, L, ws.el)
    jc.age[br.b] = 0
    good = block_factor_head(n, D, ws.it.U, L, G, piv)
    if good:
        for a in range(6):
            for c in range(6):
                S[a, c] = D[n - 1, a, c]
        good = _tip_refactor(br, D, piv, S, model.bp, chain.rot, ws)
    jc.key[br.b] = key if good else 0.0
    return good


# ------------------------------------------------------------------------------ step constants
@njit(**HOT)
def _prepare(br, model, chain, sub, base, hist, el):
    """Constants of one (sub)step: cm = c1 c_n + c2 c_{n-1}, vm, Lm (angular momenta),
    thp = c2 theta_{n-1} (relative to R_n), ehist = c1 e_n + c2 e_{n-1} (element strains),
    and the damping factors gs = 1 + beta c0 / h, hs = beta / h (eq 4-5; 1 and 0 for statics)."""
    bp = model.bp
    c1 = sub.c1
    c2 = sub.c2
    e = el.e
    tmp = el.th
    zero6 = el.zero6
    for a in range(6):
        zero6[a] = 0.0
    still = Damp(zero6, 1.0, 0.0)
    for k in range(br.n):
        i = br.b0 + k
        beta = 0.0 if sub.static else bp[i, B_BETA]
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
            ob0 = (RR[0, 0] * om[0] + RR[1, 0] * om[1] + RR[2, 0] * om[2]) * bp[i, B_JX]
            ob1 = (RR[0, 1] * om[0] + RR[1, 1] * om[1] + RR[2, 1] * om[2]) * bp[i, B_JX + 1]
            ob2 = (RR[0, 2] * om[0] + RR[1, 2] * om[1] + RR[2, 2] * om[2]) * bp[i, B_JX + 2]
            for a in range(3):
                hist.Lm[k, a] += coef * (RR[a, 0] * ob0 + RR[a, 1] * ob1 + RR[a, 2] * ob2)
        if c2 != 0.0:
            _local_rot_into(chain.prot[i], chain.rot[i], tmp)
            for a in range(3):
                hist.thp[k, a] = c2 * tmp[a]
        for a in range(6):
            hist.ehist[k, a] = 0.0
        for which in range(2):
            coef = c1 if which == 0 else c2
            if coef == 0.0:
                continue
            if which == 0:
                _element_at(k, br, model, chain.pos, chain.rot, base.pAs, base.RAs, still, el)
            else:
                _element_at(k, br, model, chain.ppos, chain.prot, base.pAp, base.RAp, still, el)
            for a in range(6):
                hist.ehist[k, a] += coef * e[a]


@njit(**HOT, inline="always")
def _start(br, model, chain, sub, base, con, ws):
    """Set up one (sub)step of one bristle: the step constants (``_prepare``), the start state
    kept in ws.it (s_pos, s_rot, s_vel, s_omg) and the tip node's rate history for contact."""
    _prepare(br, model, chain, sub, base, ws.hist, ws.el)
    _start_state(br, chain, ws.it, True)
    # tip node history for the contact rate and the stiction deformation
    il = br.il
    tip_state = con.tip_state[br.b]
    half = model.bp[il, B_HALF]
    for a in range(3):
        ptn = chain.pos[il, a] + half * chain.rot[il, a, 0]
        ptp = chain.ppos[il, a] + half * chain.prot[il, a, 0]
        tip_state[S_PN + a] = ptn
        tip_state[S_HIST + a] = sub.c1 * ptn + sub.c2 * ptp


# ------------------------------------------------------------------------------ predictors
@njit(**HOT, inline="always")
def _save_chain(br, pos, rot, t_pos, t_rot):
    """t_pos/t_rot <- one bristle's positions and rotations (a trial point to come back to)."""
    for k in range(br.n):
        for a in range(3):
            t_pos[k, a] = pos[br.b0 + k, a]
            for bb in range(3):
                t_rot[k, a, bb] = rot[br.b0 + k, a, bb]


@njit(**HOT, inline="always")
def _load_chain(br, pos, rot, t_pos, t_rot):
    """pos/rot of one bristle <- t_pos/t_rot (see ``_save_chain``)."""
    for k in range(br.n):
        for a in range(3):
            pos[br.b0 + k, a] = t_pos[k, a]
            for bb in range(3):
                rot[br.b0 + k, a, bb] = t_rot[k, a, bb]


@njit(**HOT, inline="always")
def _extrapolate(br, chain, order, base, it, mot):
    """chain.pos/rot <- the state at t_n (it.s_pos, it.s_rot) moved on by polynomial
    extrapolation in the base frame.

    With x = RA^T (c - pA) and Q = RA^T R at t_n, t_{n-1}, t_{n-2} (base poses (pAs, RAs),
    (pAp, RAp), (pAq, RAq)):  order 2: x = 2 x_n - x_{n-1}, Q = Q_n Q_{n-1}^T Q_n (constant rates);
    order 3: x = 3 x_n - 3 x_{n-1} + x_{n-2}, Q = exp(phi_2 - 3 phi_1) Q_n with
    phi_j = log(Q_{n-j} Q_n^T) (the quadratic through the three rotation vectors about Q_n).  Then
    back to the world with the base at the step's end (pAe, RAe).
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
    Qn, Qp, Qq, Qr = mot.Qn, mot.Qp, mot.Qq, mot.Qr
    phi1, phi2, xp = mot.phi1, mot.phi2, mot.xp
    for k in range(br.n):
        i = br.b0 + k
        for a in range(3):
            xn = (
                RAs[0, a] * (s_pos[k, 0] - pAs[0])
                + RAs[1, a] * (s_pos[k, 1] - pAs[1])
                + RAs[2, a] * (s_pos[k, 2] - pAs[2])
            )
            xm = (
                RAp[0, a] * (ppos[i, 0] - pAp[0])
                + RAp[1, a] * (ppos[i, 1] - pAp[1])
                + RAp[2, a] * (ppos[i, 2] - pAp[2])
            )
            if order >= 3:
                xq = (
                    RAq[0, a] * (pppos[i, 0] - pAq[0])
                    + RAq[1, a] * (pppos[i, 1] - pAq[1])
                    + RAq[2, a] * (pppos[i, 2] - pAq[2])
                )
                xp[a] = 3.0 * xn - 3.0 * xm + xq
            else:
                xp[a] = 2.0 * xn - xm
            for bb in range(3):
                Qn[a, bb] = (
                    RAs[0, a] * s_rot[k, 0, bb]
                    + RAs[1, a] * s_rot[k, 1, bb]
                    + RAs[2, a] * s_rot[k, 2, bb]
                )
                Qp[a, bb] = (
                    RAp[0, a] * prot[i, 0, bb]
                    + RAp[1, a] * prot[i, 1, bb]
                    + RAp[2, a] * prot[i, 2, bb]
                )
                if order >= 3:
                    Qq[a, bb] = (
                        RAq[0, a] * pprot[i, 0, bb]
                        + RAq[1, a] * pprot[i, 1, bb]
                        + RAq[2, a] * pprot[i, 2, bb]
                    )
        if order >= 3:
            _local_rot_into(Qp, Qn, phi1)  # log(Q_{n-1} Q_n^T)
            _local_rot_into(Qq, Qn, phi2)  # log(Q_{n-2} Q_n^T)
            _rotate_left(
                phi2[0] - 3.0 * phi1[0], phi2[1] - 3.0 * phi1[1], phi2[2] - 3.0 * phi1[2], Qn, Qr
            )
        else:
            for a in range(3):  # Qq = Qn Qp^T, the last step's rotation
                for bb in range(3):
                    Qq[a, bb] = Qn[a, 0] * Qp[bb, 0] + Qn[a, 1] * Qp[bb, 1] + Qn[a, 2] * Qp[bb, 2]
            for a in range(3):  # Qr = Qq Qn, repeated once more
                for bb in range(3):
                    Qr[a, bb] = Qq[a, 0] * Qn[0, bb] + Qq[a, 1] * Qn[1, bb] + Qq[a, 2] * Qn[2, bb]
        for a in range(3):
            pos[i, a] = pAe[a] + RAe[a, 0] * xp[0] + RAe[a, 1] * xp[1] + RAe[a, 2] * xp[2]
            for bb in range(3):
                rot[i, a, bb] = (
                    RAe[a, 0] * Qr[0, bb] + RAe[a, 1] * Qr[1, bb] + RAe[a, 2] * Qr[2, bb]
                )
        reorthonormalize(rot[i])


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
def _predict(br, model, chain, sub, base, con, ws, rootw, extrap):
    """Start Newton from the better of two predictors; returns the residual norm there.

    (1) The start configuration carried rigidly by the base's motion over the step.  (2) With
    whole steps of history, the recent motion extrapolated in the base frame (third order with
    two steps, second with one): a bristle that slides or bends steadily starts Newton O(h^3)
    close instead of O(h).  The one with the smaller residual starts Newton (the rigid one wins at
    contact onset, where extrapolation can overshoot into the plate).  Evaluated in this order,
    the usual winner (2) costs two residuals, not three.  Third order only for a tip in contact: a
    free bristle gains too few iterations (1.04 -> 0.95 per step at 3 ms) to pay for the extra
    rotation logs (~8 % slower in bench engine)."""
    it = ws.it
    if extrap == 3 and not in_contact(con.tip_state[br.b]):
        extrap = 2
    nrm = np.inf
    nx = np.inf
    # one residual call site for the three evaluations (rigid, extrapolated, rigid again): the
    # residual is inlined, and each copy costs compile time
    for stage in range(3):
        if stage == 0:
            if extrap == WARM:
                # a later sweep: this bristle's own solution of the previous sweep
                _load_chain(
                    br, chain.pos, chain.rot, ws.sw.warm_pos[br.b0 :], ws.sw.warm_rot[br.b0 :]
                )
            else:
                _rigid_predict(br, chain, base, it, ws.mot)
        elif stage == 1:
            if extrap == WARM:
                break
            if extrap < 2 or nrm <= sub.rtol:
                break
            _save_chain(br, chain.pos, chain.rot, it.t_pos, it.t_rot)
            _extrapolate(br, chain, extrap, base, it, ws.mot)
        else:
            if nx < nrm:
                nrm = nx
                break
            _load_chain(br, chain.pos, chain.rot, it.t_pos, it.t_rot)
        r = _residual(br, model, chain, sub, base, con, ws, rootw)
        if stage == 1:
            nx = r
        else:
            nrm = r
    return nrm


# ------------------------------------------------------------------------------ Newton iteration
@njit(**HOT, inline="always")
def _chain_update(br, model, chain, it, alpha, base, mot):
    """Apply the Newton correction alpha*it.dq to one bristle (from the trial point it.t_pos,
    it.t_rot), rebuilding the chain from the root.

    Rotations: R <- exp(alpha dtheta) R.  Positions: each element's translational strain d gets
    its linearised increment, d <- d + alpha dd, and nodes are rebuilt from the root with the new
    rotations, p_B = p_A + R_A (l e_x + d).  To first order this is the plain update c += alpha dc
    (so Newton keeps its quadratic convergence), but a large rotation increment no longer creates
    spurious axial/shear strain ~ l theta^2/2, which the stiff axial terms would turn into huge
    residuals.
    """
    bp = model.bp
    pos = chain.pos
    rot = chain.rot
    t_pos = it.t_pos
    t_rot = it.t_rot
    dq = it.dq
    pAb = base.pAe
    RAb = base.RAe
    pAo, pBo, dpA, dpB, pAn, dd = mot.pAo, mot.pBo, mot.dpA, mot.dpB, mot.pAn, mot.dd
    for a in range(3):
        pAn[a] = pAb[a]
    for k in range(br.n):
        i = br.b0 + k
        hB = bp[i, B_HALF]
        _rotate_left(alpha * dq[k, 3], alpha * dq[k, 4], alpha * dq[k, 5], t_rot[k], rot[i])
        # old nodes and node increments: dp = dc + dtheta x (R r)
        for a in range(3):
            pBo[a] = t_pos[k, a] + hB * t_rot[k, a, 0]
        rB0 = hB * t_rot[k, 0, 0]
        rB1 = hB * t_rot[k, 1, 0]
        rB2 = hB * t_rot[k, 2, 0]
        dpB[0] = dq[k, 0] + dq[k, 4] * rB2 - dq[k, 5] * rB1
        dpB[1] = dq[k, 1] + dq[k, 5] * rB0 - dq[k, 3] * rB2
        dpB[2] = dq[k, 2] + dq[k, 3] * rB1 - dq[k, 4] * rB0
        if k == 0:
            for a in range(3):
                pAo[a] = pAb[a]
                dpA[a] = 0.0
            t0 = 0.0
            t1 = 0.0
            t2 = 0.0
            RAo = RAb
            RAn = RAb
        else:
            hA = bp[i - 1, B_HALF]
            RAo = t_rot[k - 1]
            RAn = rot[i - 1]
            rA0 = hA * RAo[0, 0]
            rA1 = hA * RAo[1, 0]
            rA2 = hA * RAo[2, 0]
            for a in range(3):
                pAo[a] = t_pos[k - 1, a] + hA * RAo[a, 0]
            t0 = dq[k - 1, 3]
            t1 = dq[k - 1, 4]
            t2 = dq[k - 1, 5]
            dpA[0] = dq[k - 1, 0] + t1 * rA2 - t2 * rA1
            dpA[1] = dq[k - 1, 1] + t2 * rA0 - t0 * rA2
            dpA[2] = dq[k - 1, 2] + t0 * rA1 - t1 * rA0
        # dd = R_A^T (d(pB - pA) + (pB - pA) x dtheta_A); new d = old d + alpha dd
        x0 = pBo[0] - pAo[0]
        x1 = pBo[1] - pAo[1]
        x2 = pBo[2] - pAo[2]
        v0 = dpB[0] - dpA[0] + x1 * t2 - x2 * t1
        v1 = dpB[1] - dpA[1] + x2 * t0 - x0 * t2
        v2 = dpB[2] - dpA[2] + x0 * t1 - x1 * t0
        for a in range(3):
            dd[a] = (
                RAo[0, a] * (x0 + alpha * v0)
                + RAo[1, a] * (x1 + alpha * v1)
                + RAo[2, a] * (x2 + alpha * v2)
            )  # = l e_x + d_old + alpha dd (A frame)
        for a in range(3):
            pBn = pAn[a] + RAn[a, 0] * dd[0] + RAn[a, 1] * dd[1] + RAn[a, 2] * dd[2]
            pos[i, a] = pBn - hB * rot[i, a, 0]
            pAn[a] = pBn


@njit(**HOT, inline="always")
def _direction(br, jc, ws):
    """it.dq <- the Newton correction -A^-1 r on the current factors (it.r0 keeps r).  Returns
    g0 = dq . r, the line search's slope at alpha = 0."""
    it = ws.it
    b0 = br.b0
    n = br.n
    for k in range(n):
        for a in range(6):
            it.r0[k, a] = it.res[k, a]
            it.res[k, a] = -it.res[k, a]
    block_solve(
        n,
        jc.D[b0 : b0 + n],
        jc.L[b0 : b0 + n],
        jc.G[b0 : b0 + n],
        jc.piv[b0 : b0 + n],
        it.res,
        it.dq,
    )
    g0 = 0.0
    for k in range(n):
        for a in range(6):
            g0 += it.dq[k, a] * it.r0[k, a]
    return g0


@njit(**HOT, inline="always")
def _step_cap(br, model, chain, sub, con, ws):
    """Largest safe fraction alpha of the Newton correction: the rotation increment (keeps the
    log map far from pi), a trust region on the tip's displacement while in contact (the contact
    laws are ~10^3 times stiffer than the bristle, and an unbounded step can throw the tip deep
    into the plate or a neighbour), the penetration limit and the slip turning point
    (contact.py)."""
    it = ws.it
    dq = it.dq
    n = br.n
    dmax = 0.0
    for k in range(n):
        for a in range(3):
            if abs(dq[k, 3 + a]) > dmax:
                dmax = abs(dq[k, 3 + a])
    alpha = 1.0 if dmax <= MAX_ROT_STEP else MAX_ROT_STEP / dmax
    kl = n - 1
    il = br.il
    rot = chain.rot
    hl = model.bp[il, B_HALF]
    r0x = hl * rot[il, 0, 0]
    r0y = hl * rot[il, 1, 0]
    r0z = hl * rot[il, 2, 0]
    dp = it.dtip
    dp[0] = dq[kl, 0] + dq[kl, 4] * r0z - dq[kl, 5] * r0y
    dp[1] = dq[kl, 1] + dq[kl, 5] * r0x - dq[kl, 3] * r0z
    dp[2] = dq[kl, 2] + dq[kl, 3] * r0y - dq[kl, 4] * r0x
    dtip = np.sqrt(dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2])
    radius = con.tip_args[br.b, A_RADIUS]
    tip_state = con.tip_state[br.b]
    tipcap = MAX_TIP_STEP * radius
    if in_contact(tip_state) and alpha * dtip > tipcap:
        alpha = tipcap / dtip
    pt = it.tip
    for a in range(3):
        pt[a] = chain.pos[il, a] + hl * rot[il, a, 0]
    apen = penetration_step_limit(br.b, pt, dp, radius, con, ws.tipw)
    if apen < alpha:
        alpha = max(apen, 1e-3)
    if not sub.static:
        aslip = slip_step_limit(pt, dp, tip_state, sub.c0, sub.inv_h, con.cp[C_VD])
        if aslip < alpha:
            alpha = max(aslip, 1e-4)
    return alpha


@njit(**HOT, inline="always")
def _line_search(br, model, chain, sub, base, con, ws, rootw, trial):
    """Move along the correction from the saved trial point (``ws.it.t_pos``/``t_rot``); returns
    (accepted, residual norm, alpha taken).  ``trial``: ``Trial(alpha, g0, nrm)``, the capped
    step, the slope dq . r at alpha = 0 and the residual norm there.

    The merit is the directional derivative g(alpha) = dq . r(q + alpha dq) (the energy-like
    measure of structural Newton solvers): the residual norm itself is a poor merit here, because
    the stiff axial/shear terms react to second-order geometry.  On overshoot (g changed sign) the
    next alpha is the secant estimate of the zero of g, safeguarded."""
    it = ws.it
    alpha = trial.alpha
    g0 = trial.g0
    new = np.inf
    for _ls in range(8):
        _chain_update(br, model, chain, it, alpha, base, ws.mot)
        new = _residual(br, model, chain, sub, base, con, ws, rootw)
        if not np.isfinite(new):
            alpha *= 0.25
            continue
        ga = 0.0
        for k in range(br.n):
            for a in range(6):
                ga += it.dq[k, a] * it.res[k, a]
        if new <= sub.rtol or g0 >= 0.0 or ga <= 0.5 * abs(g0) or new < 0.9 * trial.nrm:
            return True, new, alpha
        alpha = max(0.1 * alpha, min(0.9 * alpha, alpha * (-g0) / (ga - g0)))
    return False, new, alpha


@njit(**HOT, inline="always")
def _stale(fresh, alpha, new, nrm, rtol):
    """True if the factors should be rebuilt before the next iteration: the step was cut (the
    factors no longer describe the way down), or old factors converge so slowly that finishing
    at this rate costs more than a rebuild."""
    if alpha < 1.0:
        return True
    if not fresh and new > SLOW * nrm and new > rtol:
        rho = new / nrm
        return rho >= 1.0 or np.log(rtol / new) / np.log(rho) > REBUILD_ITERS
    return False


@njit(**HOT, inline="always")
def _update_negligible(br, model, chain, it, alpha):
    """True if |alpha dq| is at the level of the coordinates' last bits (a round-off floor)."""
    stepmax = 0.0
    for k in range(br.n):
        for a in range(3):
            v = abs(alpha * it.dq[k, a]) / (
                abs(chain.pos[br.b0 + k, a]) + model.bp[br.b0 + k, B_LEN]
            )
            if v > stepmax:
                stepmax = v
            v = abs(alpha * it.dq[k, 3 + a])
            if v > stepmax:
                stepmax = v
    return stepmax < 1e-13


@njit(**HOT, inline="always")
def _start_state(br, chain, it, save):
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
def _commit(br, chain, sub, con, ws):
    """Accept the step: commit the stiction deformation and beta (eq 7-10), rates from the
    discrete formula, shift the history (t_n -> t_{n-1} -> t_{n-2})."""
    it = ws.it
    hist = ws.hist
    th = ws.el.th
    tip_state = con.tip_state[br.b]
    for a in range(3):
        tip_state[S_DELTA + a] = tip_state[S_DNEW + a]
    tip_state[S_BETA] = tip_state[S_BNEW]
    pos, rot = chain.pos, chain.rot
    for k in range(br.n):
        i = br.b0 + k
        reorthonormalize(rot[i])  # see the kernel: keeps the chain update free of drift
        if sub.static:
            for a in range(3):
                chain.vel[i, a] = 0.0
                chain.omg[i, a] = 0.0
        else:
            _local_rot_into(rot[i], hist.Rn[k], th)
            for a in range(3):
                chain.vel[i, a] = (sub.c0 * pos[i, a] + hist.cm[k, a]) * sub.inv_h
                chain.omg[i, a] = (sub.c0 * th[a] + hist.thp[k, a]) * sub.inv_h
        for a in range(3):
            chain.pppos[i, a] = chain.ppos[i, a]
            chain.ppos[i, a] = it.s_pos[k, a]
            chain.pvel[i, a] = it.s_vel[k, a]
            chain.pomg[i, a] = it.s_omg[k, a]
            for bb in range(3):
                chain.pprot[i, a, bb] = chain.prot[i, a, bb]
                chain.prot[i, a, bb] = it.s_rot[k, a, bb]


@njit(**HOT)
def _newton(br, model, chain, sub, base, con, jc, ws, rootw, extrap):
    """One implicit (sub)step of one bristle, in place.  Returns (converged, iterations).

    Start-of-step values are in chain.pos/rot/vel/omg (t_n) and chain.ppos/... (t_{n-1}); the
    base node moves from (pAs, RAs) to (pAe, RAe) of ``base``.  On failure the bristle's arrays
    are left at their start-of-step values.  ``jc``: factored Newton matrices kept per bristle
    across steps (simplified Newton), rebuilt when the step size or scheme changes (key c0/h),
    when older than sub.jage steps, and whenever old factors converge slowly or fail their line
    search: the converged state is always set by the residual, the factors' age only changes the
    iteration count.  Stages: start -> predict -> [factors -> direction -> cap -> line search]*
    -> commit (or restore).
    """
    b = br.b
    _start(br, model, chain, sub, base, con, ws)
    nrm = _predict(br, model, chain, sub, base, con, ws, rootw, extrap)
    rtol = sub.rtol
    it = 0
    ok = nrm <= rtol
    key = -1.0 if sub.static else sub.c0 * sub.inv_h
    jc.age[b] += 1
    need = jc.key[b] != key or jc.age[b] > sub.jage
    while not ok and it < sub.maxit and np.isfinite(nrm):
        it += 1
        fresh = need
        if need:
            if not _rebuild_factors(br, model, chain, sub, base, jc, ws, key):
                break
            need = False
        elif in_contact(con.tip_state[b]):
            # contact: the tip block at the current load, on the reused chain factors
            D = jc.D[br.b0 : br.b0 + br.n]
            if not _tip_refactor(
                br, D, jc.piv[br.b0 : br.b0 + br.n], jc.S[b], model.bp, chain.rot, ws
            ):
                need = True
                it -= 1
                continue
        g0 = _direction(br, jc, ws)
        _save_chain(br, chain.pos, chain.rot, ws.it.t_pos, ws.it.t_rot)
        alpha = _step_cap(br, model, chain, sub, con, ws)
        trial = Trial(alpha, g0, nrm)
        accepted, new, alpha = _line_search(br, model, chain, sub, base, con, ws, rootw, trial)
        if not accepted:
            # restore the iterate; retry with fresh factors unless they were fresh already
            _load_chain(br, chain.pos, chain.rot, ws.it.t_pos, ws.it.t_rot)
            if fresh:
                break
            need = True
            nrm = _residual(br, model, chain, sub, base, con, ws, rootw)
            continue
        if fresh and new > 0.5 * nrm and new <= STAGNATION * rtol:
            # stagnation: a fresh Newton step no longer reduces a residual already within
            # STAGNATION x the tolerance (observed floors 1e-7..1e-6 relative to E I / L^2 for tips
            # sticking in friction contact, i.e. ~1e-9 N): accept rather than sub-step
            nrm = new
            ok = True
            break
        need = _stale(fresh, alpha, new, nrm, rtol)
        nrm = new
        # round-off floor: the update no longer moves the state and the residual is within 100x
        # of the tolerance: accept
        if nrm <= 100.0 * rtol and _update_negligible(br, model, chain, ws.it, alpha):
            ok = True
            break
        ok = nrm <= rtol
    if not ok:
        _start_state(br, chain, ws.it, False)  # restore
        return False, it
    _commit(br, chain, sub, con, ws)
    return True, it


# ------------------------------------------------------------------------------ all bristles
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
def _substep(prm, whole, hist_ok, h):
    """The (sub)step's ``Substep``: BDF2 on a whole step with history, else backward Euler;
    c1 = c2 = 0 for statics (no history)."""
    static = prm[P_STATIC] != 0.0
    if int(prm[P_METHOD]) == 1 and whole and hist_ok != 0:
        c0, c1, c2 = 1.5, -2.0, 0.5
    else:
        c0, c1, c2 = 1.0, -1.0, 0.0
    if static:
        c1 = 0.0
        c2 = 0.0
    return Substep(
        c0,
        c1,
        c2,
        h,
        1.0 / h,
        static,
        prm[P_G : P_G + 3],
        prm[P_RTOL],
        int(prm[P_MAXIT]),
        prm[P_JAGE],
    )


@njit(**HOT, inline="always")
def _backup(br, chain, con, bk, save):
    """save: bk <- the bristle's state at the start of the step; else the bristle <- bk (every
    sub-step level failed)."""
    b0 = br.b0
    v3 = (chain.pos, chain.vel, chain.omg, chain.ppos, chain.pvel, chain.pomg, chain.pppos)
    vR = (chain.rot, chain.prot, chain.pprot)
    for k in range(br.n):
        for a in range(3):
            for q in range(7):
                if save:
                    bk.v3[q, k, a] = v3[q][b0 + k, a]
                else:
                    v3[q][b0 + k, a] = bk.v3[q, k, a]
            for c in range(3):
                for q in range(3):
                    if save:
                        bk.R[q, k, a, c] = vR[q][b0 + k, a, c]
                    else:
                        vR[q][b0 + k, a, c] = bk.R[q, k, a, c]
    ts = con.tip_state[br.b]
    for a in range(ts.shape[0]):
        if save:
            bk.tip_state[a] = ts[a]
        else:
            ts[a] = bk.tip_state[a]


@njit(**HOT, inline="always")
def _advance_bristle(br, model, chain, drive, prm, con, jc, ws, out, warm):
    """One bristle over one step h = prm[P_H]: Newton on the whole step, halved recursively on
    failure (down to h / 2**max_levels) and regrown when aligned; restored and flagged
    NEWTON_FAILED if the smallest sub-step fails.  warm: Newton on the whole step starts from
    ``ws.sw.warm_pos/warm_rot`` (a re-solve in a later sweep) instead of the predictors."""
    b = br.b
    h = prm[P_H]
    maxlev = int(prm[P_MAXLEV])
    hist_ok = drive.hist_ok[b]
    _backup(br, chain, con, ws.backup, True)
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
        sub = _substep(prm, whole, hist_ok, h * ds)
        _base_of_substep(br, model, drive, s, ds, ws)
        # predictor order: 3 with two whole steps of history, 2 with one, none otherwise
        extrap = 0
        if whole and warm:
            extrap = WARM
        elif whole and not sub.static and hist_ok > 0:
            extrap = 3 if hist_ok >= 2 else 2
        ok, it = _newton(br, model, chain, sub, ws.base, con, jc, ws, out.rootw[b], extrap)
        tot += it
        if ok:
            s += ds
            nsteps += 1
            # after a success, try a larger sub-step again when aligned
            if level > 0 and abs(s / (2.0 * ds) - np.floor(s / (2.0 * ds) + 0.5)) < 1e-9:
                level -= 1
        else:
            level += 1
            if level > maxlev:
                out.status[b] = NEWTON_FAILED
                _backup(br, chain, con, ws.backup, False)  # restore
                break
    out.iters[b] = tot
    out.nsub[b] = nsteps
    drive.hist_ok[b] = min(hist_ok + 1, 2) if (nsteps == 1 and out.status[b] == OK) else 0


@njit(**HOT, inline="always")
def _tip_node_state(b, il, bp, pos, rot, vel, omg, out):
    """out[b, 0:3] <- tip node (sphere centre) [mm], out[b, 3:6] <- its velocity [mm/s] (world):
    p = c + r, v = v_c + omega x r with r = half R e_x of the last body ``il``."""
    hl = bp[il, B_HALF]
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
def tip_states(bstart, bp, pos, rot, vel, omg, out):
    """Tip node position and velocity of every bristle into out (nb, >= 6), see _tip_node_state."""
    for b in range(bstart.shape[0] - 1):
        _tip_node_state(b, bstart[b + 1] - 1, bp, pos, rot, vel, omg, out)


@njit(**HOT)
def step_bristles(model, chain, drive, prm, con, jc, ws, out):
    """Advance every bristle by one step h = prm[P_H] (in place).

    drive: TCP pose at t_{n-1}, t_n, t_{n+1}, t_{n-2} (rows 0, 1, 2, 3) and hist_ok (whole steps
    behind each bristle's history, 0, 1 or 2; after a sub-stepped step the history is not on the
    step grid: 0).  con: surfaces, contact laws (Tables 2-3), every tip's node, velocity and radius,
    the tip-tip partner lists (CSR), the scene's mesh, tip arguments and per-contact state.

    Bristles are coupled only through tip-tip contact (Table 3).  Each is solved with its
    partners' tips held (``con.tips``), in order (a Gauss-Seidel sweep): a partner solved earlier
    in the sweep at its new tip, one solved later at its start-of-step tip.
    With prm[P_SWEEPS] > 1, while some bristle's touching partners have moved by more than
    prm[P_TTTOL] since it was solved, the partners are placed where the linearised coupled
    problem puts them (``coupling.place_partners``) and those bristles are solved again from the
    step's start, warm-started at their last solution: at convergence both sides of every
    tip-tip contact see the end-of-step tips (no lag).  Outputs per bristle in ``out``: rootw
    (force, moment of the root element on the head, at the root node, world), iters (Newton
    iterations, all sweeps), nsub (sub-steps used), status (OK / NEWTON_FAILED); ws.sw.count =
    [sweeps run, re-solves, 0 settled / 1 out of sweeps with partners still moving by less than
    FALLBACK_MOVE / 2 fell back to the plain sweep].
    """
    nb = model.bstart.shape[0] - 1
    sw = ws.sw
    npair = con.pair_idx.shape[0]
    sweeps = int(prm[P_SWEEPS]) if npair > 0 else 1
    static = prm[P_STATIC] != 0.0
    c0_inv_h = 0.0 if static else (1.5 if int(prm[P_METHOD]) == 1 else 1.0) / prm[P_H]
    for b in range(nb):
        out.iters[b] = 0
        for a in range(6):
            sw.tips0[b, a] = con.tips[b, a]
    if sweeps > 1:
        _save_all(chain, con, drive, sw)
    sw.count[0] = 1
    sw.count[1] = 0
    sw.count[2] = 0
    _sweep(model, chain, drive, prm, con, jc, ws, out, SWEEP_FIRST)
    for sweep in range(1, sweeps + 1):
        moved = _max_partner_move(nb, con, sw.used)
        if moved <= prm[P_TTTOL]:
            break
        if sweep == sweeps:
            sw.count[2] = 1  # out of sweeps with partners still moving
            if sweeps > 1 and moved > FALLBACK_MOVE:
                # far from settled (the coupled step went astray): the plain sweep instead
                sw.count[2] = 2
                _sweep(model, chain, drive, prm, con, jc, ws, out, SWEEP_PLAIN)
            break
        sw.count[0] = sweep + 1
        place_partners(model, chain, con, jc, ws, c0_inv_h)
        _sweep(model, chain, drive, prm, con, jc, ws, out, SWEEP_AGAIN)


#: modes of ``_sweep``
SWEEP_FIRST = 0  # every bristle, from the step's start
SWEEP_AGAIN = 1  # the bristles whose partners moved (or were placed), warm-started
SWEEP_PLAIN = 2  # every bristle again from the step's start, partners back at their start
#: [mm] partners still moving by more than this when the sweeps run out: the coupled iteration
#: went astray (contact onset, a stick-slip switch); the step falls back to the plain sweep
FALLBACK_MOVE = 1e-4


@njit(**HOT)
def _sweep(model, chain, drive, prm, con, jc, ws, out, mode):
    """One pass over the bristles in order (``step_bristles``); ``mode``: SWEEP_*."""
    bstart = model.bstart
    nb = bstart.shape[0] - 1
    sw = ws.sw
    npair = con.pair_idx.shape[0]
    coupled = int(prm[P_SWEEPS]) > 1 and npair > 0
    if mode == SWEEP_PLAIN:
        for b in range(nb):
            for a in range(6):
                con.tips[b, a] = sw.tips0[b, a]
    for b in range(nb):
        b0 = bstart[b]
        n = bstart[b + 1] - b0
        br = Bristle(b, b0, n, b0 + n - 1)
        if mode == SWEEP_AGAIN:
            if not _partners_moved(b, con, sw.used, prm[P_TTTOL]):
                if sw.grouped[b] != 0:  # placed but held as it is: back to its solution
                    for a in range(6):
                        con.tips[b, a] = sw.xs[b, a]
                continue
            sw.count[1] += 1
            _save_chain(br, chain.pos, chain.rot, sw.warm_pos[b0:], sw.warm_rot[b0:])
        if mode != SWEEP_FIRST:
            _restore_bristle(br, chain, con, drive, sw)
        for q in range(con.pair_ptr[b], con.pair_ptr[b + 1]):
            j = con.pair_idx[q]
            for a in range(3):
                sw.used[q, a] = con.tips[j, a]
        prev = out.iters[b]
        _advance_bristle(br, model, chain, drive, prm, con, jc, ws, out, mode == SWEEP_AGAIN)
        out.iters[b] += prev
        _tip_node_state(b, br.il, model.bp, chain.pos, chain.rot, chain.vel, chain.omg, con.tips)
        if coupled:
            store_tip_load(b, ws.it, sw)


@njit(**HOT, inline="always")
def _max_partner_move(nb, con, used):
    """The largest move [mm] of a partner within contact reach of a bristle since that bristle
    was solved (``_partners_moved``), over all bristles."""
    m = 0.0
    for b in range(nb):
        m = max(m, _partner_move(b, con, used))
    return m


@njit(**HOT, inline="always")
def _partners_moved(b, con, used, tol):
    """True if a partner of bristle b that is (or was, when b was solved) within contact reach
    of b's tip has moved by more than ``tol`` [mm] since b was solved."""
    return _partner_move(b, con, used) > tol


@njit(**HOT)
def _partner_move(b, con, used):
    """The largest move [mm] since bristle b was solved of a partner that is (or was, when b was
    solved) within contact reach of b's tip."""
    tips = con.tips
    rb = tips[b, 6]
    m = 0.0
    for q in range(con.pair_ptr[b], con.pair_ptr[b + 1]):
        j = con.pair_idx[q]
        reach = rb + tips[j, 6]
        dn0 = tips[b, 0] - tips[j, 0]
        dn1 = tips[b, 1] - tips[j, 1]
        dn2 = tips[b, 2] - tips[j, 2]
        du0 = tips[b, 0] - used[q, 0]
        du1 = tips[b, 1] - used[q, 1]
        du2 = tips[b, 2] - used[q, 2]
        m0 = tips[j, 0] - used[q, 0]
        m1 = tips[j, 1] - used[q, 1]
        m2 = tips[j, 2] - used[q, 2]
        mv = np.sqrt(m0 * m0 + m1 * m1 + m2 * m2)
        r2 = (reach + mv) * (reach + mv)
        if dn0 * dn0 + dn1 * dn1 + dn2 * dn2 > r2 and du0 * du0 + du1 * du1 + du2 * du2 > r2:
            continue
        m = max(m, mv)
    return m


@njit(**HOT, inline="always")
def _save_all(chain, con, drive, sw):
    """sw <- every bristle's state at the step's start (chain, contact state, hist_ok)."""
    v3 = (chain.pos, chain.vel, chain.omg, chain.ppos, chain.pvel, chain.pomg, chain.pppos)
    vR = (chain.rot, chain.prot, chain.pprot)
    for k in range(chain.pos.shape[0]):
        for a in range(3):
            for q in range(7):
                sw.v3[q, k, a] = v3[q][k, a]
            for c in range(3):
                for q in range(3):
                    sw.R[q, k, a, c] = vR[q][k, a, c]
    for b in range(con.tip_state.shape[0]):
        for a in range(con.tip_state.shape[1]):
            sw.tip_state[b, a] = con.tip_state[b, a]
        sw.hist_ok[b] = drive.hist_ok[b]


@njit(**HOT, inline="always")
def _restore_bristle(br, chain, con, drive, sw):
    """One bristle <- its state at the step's start (``_save_all``)."""
    v3 = (chain.pos, chain.vel, chain.omg, chain.ppos, chain.pvel, chain.pomg, chain.pppos)
    vR = (chain.rot, chain.prot, chain.pprot)
    for k in range(br.b0, br.b0 + br.n):
        for a in range(3):
            for q in range(7):
                v3[q][k, a] = sw.v3[q, k, a]
            for c in range(3):
                for q in range(3):
                    vR[q][k, a, c] = sw.R[q, k, a, c]
    for a in range(con.tip_state.shape[1]):
        con.tip_state[br.b, a] = sw.tip_state[br.b, a]
    drive.hist_ok[br.b] = sw.hist_ok[br.b]


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
