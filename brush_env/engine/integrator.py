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

# status codes per bristle (step_bristles' ``status``)
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
N_PRM = 10

STAGNATION = 100.0  # accept a stagnating Newton within this factor of the tolerance
MAX_ROT_STEP = 0.5  # [rad] largest rotation increment of one Newton iteration
MAX_TIP_STEP = 0.25  # largest tip displacement of one Newton iteration, in tip radii
#: Reused Newton factors are rebuilt when an iteration with them reduces the residual by less than
#: SLOW and, at that rate, more than REBUILD_ITERS further iterations would be needed: a rebuild
#: (finite-difference chain Jacobian + factorisation, ~8.5 us at 6 bodies) costs about as much
#: as four iterations with reused factors (~2 us each).
SLOW = 0.1
REBUILD_ITERS = 3.0


N_SW = 16  # rows of the (N_SW, 12) scratch ``sw`` shared by the kernels (see their bodies)


def make_workspace(nmax: int, n_tip_state: int):
    """Scratch arrays for ``step_bristles`` (allocated once per Simulator; nmax = most bodies)."""
    return (
        np.zeros((8, nmax, 3, 3)),
        np.zeros((6, nmax, 6)),
        np.zeros((nmax, 6, 6)),
        np.zeros((N_SW, 12)),
        np.zeros(32),
        np.zeros((7, nmax, 3)),
        np.zeros((3, nmax, 3, 3)),
        np.zeros(n_tip_state),
    )


def make_jacobian_store(n_bodies: int, n_bristles: int):
    """Per-bristle factored Newton matrices kept across steps (see ``_newton``): D, G, L, pivots,
    key, age, and the tip body's Schur complement without the tip load (nb, 6, 6)."""
    return (
        np.zeros((n_bodies, 6, 6)),
        np.zeros((n_bodies, 6, 6)),
        np.zeros((n_bodies, 6, 6)),
        np.zeros((n_bodies, 6), np.int64),
        np.zeros(n_bristles),
        np.zeros(n_bristles, np.int64),
        np.zeros((n_bristles, 6, 6)),
    )


@njit(**HOT, inline="always")
def _skew_into(x, y, z, S):
    """S <- [v]x, the cross-product matrix of v = (x, y, z)."""
    S[0, 0] = 0.0
    S[0, 1] = -z
    S[0, 2] = y
    S[1, 0] = z
    S[1, 1] = 0.0
    S[1, 2] = -x
    S[2, 0] = -y
    S[2, 1] = x
    S[2, 2] = 0.0


@njit(**HOT, inline="always")
def _mul3(A, B, C):
    """C <- A B for 3x3 matrices (C distinct from A and B)."""
    for a in range(3):
        for b in range(3):
            C[a, b] = A[a, 0] * B[0, b] + A[a, 1] * B[1, b] + A[a, 2] * B[2, b]


@njit(**HOT)
def _base_pose(p0, R0, p1, R1, s, pout, Rout, tmp):
    """Base pose at fraction s of the step: linear in position, geodesic in rotation."""
    for a in range(3):
        pout[a] = (1.0 - s) * p0[a] + s * p1[a]
    _local_rot_into(R1, R0, tmp)  # tmp = log(R1 R0^T)
    _rotate_left(s * tmp[0], s * tmp[1], s * tmp[2], R0, Rout)


@njit(**HOT)
def _residual(
    b,
    b0,
    n,
    bp,
    K,
    pos,
    rot,
    gvec,
    static,
    c0,
    inv_h,
    cm,
    vm,
    Lm,
    thp,
    Rn,
    ehist,
    gs,
    hs,
    pAb,
    RAb,
    tip_args,
    tip_state,
    ctx,
    res,
    rootw,
    tipF,
    tipK,
    sw,
):
    """Residual of eq 11 for one bristle (rate of momentum minus forces, N and N*mm).

    Returns the scaled max norm: forces / bristle force scale and moments / (scale * l).  Also
    fills ``rootw`` (force and moment that the root element applies to the head, at the root node)
    and ``tipF``/``tipK`` (tip load and its stiffness d F / d p_tip).
    """
    e = sw[0, 0:6]
    out12 = sw[1]
    th = sw[6, 0:3]
    pt = sw[6, 3:6]
    for k in range(n):
        i = b0 + k
        m = bp[i, 0]
        if static:
            for a in range(3):
                res[k, a] = -m * gvec[a]
                res[k, 3 + a] = 0.0
            continue
        for a in range(3):
            vk = (c0 * pos[i, a] + cm[k, a]) * inv_h
            res[k, a] = m * (c0 * vk + vm[k, a]) * inv_h - m * gvec[a]
        _local_rot_into(rot[i], Rn[k], th)
        om0 = (c0 * th[0] + thp[k, 0]) * inv_h
        om1 = (c0 * th[1] + thp[k, 1]) * inv_h
        om2 = (c0 * th[2] + thp[k, 2]) * inv_h
        R = rot[i]
        ob0 = (R[0, 0] * om0 + R[1, 0] * om1 + R[2, 0] * om2) * bp[i, 1]
        ob1 = (R[0, 1] * om0 + R[1, 1] * om1 + R[2, 1] * om2) * bp[i, 2]
        ob2 = (R[0, 2] * om0 + R[1, 2] * om1 + R[2, 2] * om2) * bp[i, 3]
        for a in range(3):
            La = R[a, 0] * ob0 + R[a, 1] * ob1 + R[a, 2] * ob2
            res[k, 3 + a] = (c0 * La + Lm[k, a]) * inv_h
    for k in range(n):
        i = b0 + k
        if k == 0:
            _element_gen(
                True,
                pAb,
                RAb,
                0.0,
                pAb,
                pos[i],
                rot[i],
                bp[i, 4],
                K[i],
                bp[i, 5],
                ehist[k],
                gs[k],
                hs[k],
                out12,
                e,
            )
            for a in range(6):
                rootw[a] = out12[a]
        else:
            _element_gen(
                False,
                pos[i - 1],
                rot[i - 1],
                bp[i - 1, 4],
                pAb,
                pos[i],
                rot[i],
                bp[i, 4],
                K[i],
                bp[i, 5],
                ehist[k],
                gs[k],
                hs[k],
                out12,
                e,
            )
            for a in range(6):
                res[k - 1, a] -= out12[a]
        for a in range(6):
            res[k, a] -= out12[6 + a]
    il = b0 + n - 1
    _node(pos[il], rot[il], bp[il, 4], pt)
    surf, cp, tips, pair_ptr, pair_idx, mesh = ctx
    tip_load(
        b,
        pt,
        c0,
        inv_h,
        static,
        tip_args,
        tip_state,
        surf,
        cp,
        tips,
        pair_ptr,
        pair_idx,
        mesh,
        tipF,
        tipK,
        sw[2:4],
    )
    rx = pt[0] - pos[il, 0]
    ry = pt[1] - pos[il, 1]
    rz = pt[2] - pos[il, 2]
    res[n - 1, 0] -= tipF[0]
    res[n - 1, 1] -= tipF[1]
    res[n - 1, 2] -= tipF[2]
    res[n - 1, 3] -= ry * tipF[2] - rz * tipF[1]
    res[n - 1, 4] -= rz * tipF[0] - rx * tipF[2]
    res[n - 1, 5] -= rx * tipF[1] - ry * tipF[0]
    nrm = 0.0
    for k in range(n):
        i = b0 + k
        fs = bp[i, 7]
        ls = fs * bp[i, 5]
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


@njit(**HOT)
def _jacobian(
    b0, n, bp, K, pos, rot, static, c0, inv_h, ehist, gs, hs, pAb, RAb, tipF, tipK, D, U, L, sw
):
    """Newton matrix d(res)/d(q), q_k = (dc_k, dtheta_k) in world axes (block tridiagonal).

    Inertia blocks m c0^2/h^2 and R J R^T c0^2/h^2 (terms of order omega*h dropped); element
    blocks by forward differences of the element's generalised forces; tip load blocks from the
    tip stiffness ``tipK`` and the lever arm.  The Jacobian only steers Newton: the converged
    state is fixed by the residual alone.
    """
    _jacobian_chain(b0, n, bp, K, pos, rot, static, c0, inv_h, ehist, gs, hs, pAb, RAb, D, U, L, sw)
    _add_tip_block(D[n - 1], bp, rot, b0 + n - 1, tipF, tipK, sw)


@njit(**HOT)
def _jacobian_chain(
    b0, n, bp, K, pos, rot, static, c0, inv_h, ehist, gs, hs, pAb, RAb, D, U, L, sw
):
    """The inertia and element blocks of ``_jacobian`` (everything but the tip load)."""
    e = sw[0, 0:6]
    cP = sw[6, 6:9]
    base = sw[7]
    pert = sw[1]
    RP = sw[8:11, 0:3]
    for k in range(n):
        for a in range(6):
            for b in range(6):
                D[k, a, b] = 0.0
                U[k, a, b] = 0.0
                L[k, a, b] = 0.0
    if not static:
        s2 = c0 * c0 * inv_h * inv_h
        for k in range(n):
            i = b0 + k
            R = rot[i]
            for a in range(3):
                D[k, a, a] = bp[i, 0] * s2
                for b in range(3):
                    D[k, 3 + a, 3 + b] = s2 * (
                        R[a, 0] * bp[i, 1] * R[b, 0]
                        + R[a, 1] * bp[i, 2] * R[b, 1]
                        + R[a, 2] * bp[i, 3] * R[b, 2]
                    )
    for k in range(n):
        i = b0 + k
        hB = bp[i, 4]
        ln = bp[i, 5]
        epsx = 1e-7 * ln
        epsr = 1e-7
        isroot = k == 0
        j = i - 1 if k > 0 else i  # index of body A (unused for the root element)
        hA = bp[j, 4]
        RAk = RAb if isroot else rot[j]
        cAk = pAb if isroot else pos[j]
        _element_gen(
            isroot, cAk, RAk, hA, pAb, pos[i], rot[i], hB, K[i], ln, ehist[k], gs[k], hs[k], base, e
        )
        nside = 1 if isroot else 2
        for side in range(nside):  # side 0: perturb body B (= k), side 1: body A (= k-1)
            src = i if side == 0 else j
            for col in range(6):
                for a in range(3):
                    cP[a] = pos[src, a]
                if col < 3:
                    cP[col] += epsx
                    eps = epsx
                    for a in range(3):
                        for b in range(3):
                            RP[a, b] = rot[src, a, b]
                else:
                    _rotate_left(
                        epsr if col == 3 else 0.0,
                        epsr if col == 4 else 0.0,
                        epsr if col == 5 else 0.0,
                        rot[src],
                        RP,
                    )
                    eps = epsr
                if side == 0:
                    _element_gen(
                        isroot,
                        cAk,
                        RAk,
                        hA,
                        pAb,
                        cP,
                        RP,
                        hB,
                        K[i],
                        ln,
                        ehist[k],
                        gs[k],
                        hs[k],
                        pert,
                        e,
                    )
                else:
                    _element_gen(
                        False,
                        cP,
                        RP,
                        hA,
                        pAb,
                        pos[i],
                        rot[i],
                        hB,
                        K[i],
                        ln,
                        ehist[k],
                        gs[k],
                        hs[k],
                        pert,
                        e,
                    )
                for a in range(6):
                    dA = (pert[a] - base[a]) / eps  # d(force on A)
                    dB = (pert[6 + a] - base[6 + a]) / eps  # d(force on B)
                    if side == 0:
                        D[k, a, col] -= dB
                        if not isroot:
                            U[k - 1, a, col] -= dA
                    else:
                        D[k - 1, a, col] -= dA
                        L[k, a, col] -= dB


@njit(**HOT)
def _add_tip_block(Dk, bp, rot, il, tipF, tipK, sw):
    """Dk += d(-tip load, -its moment about c)/d(dc, dtheta) of the tip body ``il``.

    Tip load F at p_tip = c + r, r = half * R e_x:  dp_tip = dc - [r]x dtheta."""
    Sr = sw[8:11, 3:6]
    SF = sw[8:11, 6:9]
    KS = sw[8:11, 9:12]
    SrK = sw[11:14, 0:3]
    SrKS = sw[11:14, 3:6]
    SFSr = sw[11:14, 6:9]
    hl = bp[il, 4]
    _skew_into(hl * rot[il, 0, 0], hl * rot[il, 1, 0], hl * rot[il, 2, 0], Sr)
    _skew_into(tipF[0], tipF[1], tipF[2], SF)
    _mul3(tipK, Sr, KS)
    _mul3(Sr, tipK, SrK)
    _mul3(Sr, KS, SrKS)
    _mul3(SF, Sr, SFSr)
    # residual rows: -F and -(r x F); dF = K (dc - [r]x dth); d(r x F) = [r]x dF + [F]x [r]x dth
    for a in range(3):
        for b in range(3):
            Dk[a, b] -= tipK[a, b]
            Dk[a, 3 + b] += KS[a, b]
            Dk[3 + a, b] -= SrK[a, b]
            Dk[3 + a, 3 + b] += SrKS[a, b] - SFSr[a, b]


@njit(**HOT)
def _tip_refactor(n, D, piv, S, bp, rot, il, tipF, tipK, sw):
    """Last block of the factored Newton matrix <- LU(S + tip block at the current tip load).

    S is the tip body's Schur complement without the tip load (``block_factor_head``), so this
    makes the contact part of the Newton matrix current for the price of one 6x6 LU, while the
    chain's blocks (which change slowly) are reused.  Returns False if the block is singular."""
    Dl = D[n - 1]
    for a in range(6):
        for c in range(6):
            Dl[a, c] = S[a, c]
    _add_tip_block(Dl, bp, rot, il, tipF, tipK, sw)
    return _lu6(Dl, piv[n - 1])


@njit(**HOT)
def _prepare(
    b0,
    n,
    bp,
    K,
    pos,
    rot,
    vel,
    omg,
    ppos,
    prot,
    pvel,
    pomg,
    c1,
    c2,
    pAs,
    RAs,
    pAp,
    RAp,
    cm,
    vm,
    Lm,
    thp,
    Rn,
    ehist,
    sw,
):
    """Constants of one (sub)step: cm = c1 c_n + c2 c_{n-1}, vm, Lm (angular momenta),
    thp = c2 theta_{n-1} (relative to R_n), ehist = c1 e_n + c2 e_{n-1} (element strains)."""
    e = sw[0, 0:6]
    out12 = sw[1]
    tmp = sw[6, 0:3]
    zero6 = sw[6, 6:12]
    for a in range(6):
        zero6[a] = 0.0
    for k in range(n):
        i = b0 + k
        for a in range(3):
            for bb in range(3):
                Rn[k, a, bb] = rot[i, a, bb]
            cm[k, a] = c1 * pos[i, a] + c2 * ppos[i, a]
            vm[k, a] = c1 * vel[i, a] + c2 * pvel[i, a]
            Lm[k, a] = 0.0
            thp[k, a] = 0.0
        for which in range(2):
            coef = c1 if which == 0 else c2
            if coef == 0.0:
                continue
            RR = rot[i] if which == 0 else prot[i]
            om = omg[i] if which == 0 else pomg[i]
            ob0 = (RR[0, 0] * om[0] + RR[1, 0] * om[1] + RR[2, 0] * om[2]) * bp[i, 1]
            ob1 = (RR[0, 1] * om[0] + RR[1, 1] * om[1] + RR[2, 1] * om[2]) * bp[i, 2]
            ob2 = (RR[0, 2] * om[0] + RR[1, 2] * om[1] + RR[2, 2] * om[2]) * bp[i, 3]
            for a in range(3):
                Lm[k, a] += coef * (RR[a, 0] * ob0 + RR[a, 1] * ob1 + RR[a, 2] * ob2)
        if c2 != 0.0:
            _local_rot_into(prot[i], rot[i], tmp)
            for a in range(3):
                thp[k, a] = c2 * tmp[a]
        for a in range(6):
            ehist[k, a] = 0.0
        for which in range(2):
            coef = c1 if which == 0 else c2
            if coef == 0.0:
                continue
            P = pos if which == 0 else ppos
            Q = rot if which == 0 else prot
            if k == 0:
                pa = pAs if which == 0 else pAp
                Ra = RAs if which == 0 else RAp
                _element_gen(
                    True,
                    pa,
                    Ra,
                    0.0,
                    pa,
                    P[i],
                    Q[i],
                    bp[i, 4],
                    K[i],
                    bp[i, 5],
                    zero6,
                    1.0,
                    0.0,
                    out12,
                    e,
                )
            else:
                _element_gen(
                    False,
                    P[i - 1],
                    Q[i - 1],
                    bp[i - 1, 4],
                    pAs,
                    P[i],
                    Q[i],
                    bp[i, 4],
                    K[i],
                    bp[i, 5],
                    zero6,
                    1.0,
                    0.0,
                    out12,
                    e,
                )
            for a in range(6):
                ehist[k, a] += coef * e[a]


@njit(**HOT, inline="always")
def _save_chain(b0, n, pos, rot, t_pos, t_rot):
    """t_pos/t_rot <- one bristle's positions and rotations (a trial point to come back to)."""
    for k in range(n):
        for a in range(3):
            t_pos[k, a] = pos[b0 + k, a]
            for bb in range(3):
                t_rot[k, a, bb] = rot[b0 + k, a, bb]


@njit(**HOT, inline="always")
def _load_chain(b0, n, pos, rot, t_pos, t_rot):
    """pos/rot of one bristle <- t_pos/t_rot (see ``_save_chain``)."""
    for k in range(n):
        for a in range(3):
            pos[b0 + k, a] = t_pos[k, a]
            for bb in range(3):
                rot[b0 + k, a, bb] = t_rot[k, a, bb]


@njit(**HOT)
def _extrapolate(
    b0,
    n,
    pos,
    rot,
    s_pos,
    s_rot,
    ppos,
    prot,
    pppos,
    pprot,
    order,
    pAs,
    RAs,
    pAp,
    RAp,
    pAq,
    RAq,
    pAe,
    RAe,
    sw,
):
    """pos/rot <- the state at t_n moved on by polynomial extrapolation in the base frame.

    With x = RA^T (c - pA) and Q = RA^T R at t_n, t_{n-1}, t_{n-2} (base poses (pAs, RAs),
    (pAp, RAp), (pAq, RAq)):  order 2: x = 2 x_n - x_{n-1}, Q = Q_n Q_{n-1}^T Q_n (constant rates);
    order 3: x = 3 x_n - 3 x_{n-1} + x_{n-2}, Q = exp(phi_2 - 3 phi_1) Q_n with
    phi_j = log(Q_{n-j} Q_n^T) (the quadratic through the three rotation vectors about Q_n).  Then
    back to the world with the base at the step's end (pAe, RAe).
    """
    Qn = sw[8:11, 0:3]
    Qp = sw[8:11, 3:6]
    Qq = sw[8:11, 6:9]
    Qr = sw[11:14, 0:3]
    phi1 = sw[11, 3:6]
    phi2 = sw[11, 6:9]
    xp = sw[11, 9:12]
    for k in range(n):
        i = b0 + k
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


@njit(**HOT)
def _rigid_predict(b0, n, pos, rot, s_pos, s_rot, pAs, RAs, pAe, RAe, sw):
    """pos/rot <- the start configuration (s_pos, s_rot) carried rigidly by the base's motion over
    the step, T = base_end o base_start^-1: a driven, nearly quasi-static chain starts Newton
    close."""
    Tr = sw[8:11, 0:3]
    for a in range(3):
        for bb in range(3):
            Tr[a, bb] = RAe[a, 0] * RAs[bb, 0] + RAe[a, 1] * RAs[bb, 1] + RAe[a, 2] * RAs[bb, 2]
    for k in range(n):
        i = b0 + k
        for a in range(3):
            pos[i, a] = (
                pAe[a]
                + Tr[a, 0] * (s_pos[k, 0] - pAs[0])
                + Tr[a, 1] * (s_pos[k, 1] - pAs[1])
                + Tr[a, 2] * (s_pos[k, 2] - pAs[2])
            )
            for bb in range(3):
                rot[i, a, bb] = (
                    Tr[a, 0] * s_rot[k, 0, bb]
                    + Tr[a, 1] * s_rot[k, 1, bb]
                    + Tr[a, 2] * s_rot[k, 2, bb]
                )


@njit(**HOT)
def _chain_update(b0, n, bp, pos, rot, t_pos, t_rot, dq, alpha, pAb, RAb, sw):
    """Apply the Newton correction alpha*dq to one bristle, rebuilding the chain from the root.

    Rotations: R <- exp(alpha dtheta) R.  Positions: each element's translational strain d gets
    its linearised increment, d <- d + alpha dd, and nodes are rebuilt from the root with the new
    rotations, p_B = p_A + R_A (l e_x + d).  To first order this is the plain update c += alpha dc
    (so Newton keeps its quadratic convergence), but a large rotation increment no longer creates
    spurious axial/shear strain ~ l theta^2/2, which the stiff axial terms would turn into huge
    residuals.
    """
    pAo = sw[14, 0:3]
    pBo = sw[14, 3:6]
    dpA = sw[14, 6:9]
    dpB = sw[14, 9:12]
    pAn = sw[15, 0:3]
    dd = sw[15, 3:6]
    for a in range(3):
        pAn[a] = pAb[a]
    for k in range(n):
        i = b0 + k
        hB = bp[i, 4]
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
            hA = bp[i - 1, 4]
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


@njit(**HOT)
def _newton(
    b,
    b0,
    n,
    bp,
    K,
    pos,
    rot,
    vel,
    omg,
    ppos,
    prot,
    pvel,
    pomg,
    pppos,
    pprot,
    prm,
    c0,
    c1,
    c2,
    h,
    pAs,
    RAs,
    pAe,
    RAe,
    pAp,
    RAp,
    pAq,
    RAq,
    tip_args,
    tip_state,
    ctx,
    rootw,
    jac,
    ws,
    extrap,
):
    """One implicit (sub)step of one bristle, in place.  Returns (converged, iterations).

    Start-of-step values are in pos/rot/vel/omg (t_n) and ppos/... (t_{n-1}); the base node moves
    from (pAs, RAs) to (pAe, RAe); (pAp, RAp) is the base at t_{n-1} (BDF2 damping history).
    On failure the bristle's arrays are left at their start-of-step values.

    jac = (jD, jG, jL, jpiv, jkey, jage): factored Newton matrices kept per bristle across steps
    (simplified Newton).  They are rebuilt when the step size or scheme changes (key c0/h), when
    they are older than prm[P_JAGE] steps, and whenever an iteration with old factors converges
    slowly (residual ratio > 0.25) or fails its line search: the converged state is always set by
    the residual, the Jacobian's age only changes the iteration count.
    ws: scratch memory, see ``make_workspace``.
    """
    static = prm[P_STATIC] != 0.0
    inv_h = 1.0 / h
    gvec = prm[P_G : P_G + 3]
    jD, jG, jL, jpiv, jkey, jage, jS = jac
    S = jS[b]
    D = jD[b0 : b0 + n]
    G = jG[b0 : b0 + n]
    L = jL[b0 : b0 + n]
    piv = jpiv[b0 : b0 + n]
    w3, w6, wU, sw, small, bk3, bkR, bktip = ws
    U = wU[:n]
    Rn = w3[0, :n]
    s_rot = w3[1, :n]
    t_rot = w3[2, :n]
    res = w6[0, :n]
    r0 = w6[1, :n]
    dq = w6[2, :n]
    ehist = w6[3, :n]
    cm = w3[3, :n, 0]
    vm = w3[3, :n, 1]
    Lm = w3[3, :n, 2]
    thp = w3[4, :n, 0]
    s_pos = w3[4, :n, 1]
    s_vel = w3[4, :n, 2]
    s_omg = w3[5, :n, 0]
    t_pos = w3[5, :n, 1]
    gs = w6[4, :n, 0]
    hs = w6[4, :n, 1]
    tipF = small[0:3]
    th = small[3:6]
    tipK = w3[6, 0]
    if static:
        c1u = 0.0
        c2u = 0.0
    else:
        c1u = c1
        c2u = c2
    _prepare(
        b0,
        n,
        bp,
        K,
        pos,
        rot,
        vel,
        omg,
        ppos,
        prot,
        pvel,
        pomg,
        c1u,
        c2u,
        pAs,
        RAs,
        pAp,
        RAp,
        cm,
        vm,
        Lm,
        thp,
        Rn,
        ehist,
        sw,
    )
    for k in range(n):
        i = b0 + k
        beta = 0.0 if static else bp[i, 6]
        gs[k] = 1.0 + beta * c0 * inv_h
        hs[k] = beta * inv_h
        for a in range(3):
            s_pos[k, a] = pos[i, a]
            s_vel[k, a] = vel[i, a]
            s_omg[k, a] = omg[i, a]
            for bb in range(3):
                s_rot[k, a, bb] = rot[i, a, bb]
    # tip node history for the contact rate and the stiction deformation
    il = b0 + n - 1
    for a in range(3):
        ptn = pos[il, a] + bp[il, 4] * rot[il, a, 0]
        ptp = ppos[il, a] + bp[il, 4] * prot[il, a, 0]
        tip_state[S_PN + a] = ptn
        tip_state[S_HIST + a] = c1u * ptn + c2u * ptp
    rtol = prm[P_RTOL]
    maxit = int(prm[P_MAXIT])
    # Predictors.  (1) The start configuration carried rigidly by the base's motion over the
    # step.  (2) With whole steps of history, the recent motion extrapolated in the base frame
    # (third order with two steps, second with one): a bristle that slides or bends steadily starts
    # Newton O(h^3) close instead of O(h).  The one with the smaller residual starts Newton (the
    # rigid one wins at contact onset, where extrapolation can overshoot into the plate).
    # Evaluated in this order, the usual winner (2) costs two residuals, not three.  Third order
    # only for a tip in contact: a free bristle gains too few iterations (1.04 -> 0.95 per step
    # at 3 ms) to pay for the extra rotation logs (~8 % slower in bench engine).
    if extrap == 3 and not in_contact(tip_state):
        extrap = 2
    _rigid_predict(b0, n, pos, rot, s_pos, s_rot, pAs, RAs, pAe, RAe, sw)
    nrm = _residual(
        b,
        b0,
        n,
        bp,
        K,
        pos,
        rot,
        gvec,
        static,
        c0,
        inv_h,
        cm,
        vm,
        Lm,
        thp,
        Rn,
        ehist,
        gs,
        hs,
        pAe,
        RAe,
        tip_args,
        tip_state,
        ctx,
        res,
        rootw,
        tipF,
        tipK,
        sw,
    )
    if extrap >= 2 and nrm > rtol:
        _save_chain(b0, n, pos, rot, t_pos, t_rot)
        _extrapolate(
            b0,
            n,
            pos,
            rot,
            s_pos,
            s_rot,
            ppos,
            prot,
            pppos,
            pprot,
            extrap,
            pAs,
            RAs,
            pAp,
            RAp,
            pAq,
            RAq,
            pAe,
            RAe,
            sw,
        )
        nx = _residual(
            b,
            b0,
            n,
            bp,
            K,
            pos,
            rot,
            gvec,
            static,
            c0,
            inv_h,
            cm,
            vm,
            Lm,
            thp,
            Rn,
            ehist,
            gs,
            hs,
            pAe,
            RAe,
            tip_args,
            tip_state,
            ctx,
            res,
            rootw,
            tipF,
            tipK,
            sw,
        )
        if nx < nrm:
            nrm = nx
        else:
            _load_chain(b0, n, pos, rot, t_pos, t_rot)
            nrm = _residual(
                b,
                b0,
                n,
                bp,
                K,
                pos,
                rot,
                gvec,
                static,
                c0,
                inv_h,
                cm,
                vm,
                Lm,
                thp,
                Rn,
                ehist,
                gs,
                hs,
                pAe,
                RAe,
                tip_args,
                tip_state,
                ctx,
                res,
                rootw,
                tipF,
                tipK,
                sw,
            )
    it = 0
    ok = nrm <= rtol
    key = -1.0 if static else c0 * inv_h
    jage[b] += 1
    need = jkey[b] != key or jage[b] > prm[P_JAGE]
    while not ok and it < maxit and np.isfinite(nrm):
        it += 1
        fresh = need
        if need:
            _jacobian_chain(
                b0, n, bp, K, pos, rot, static, c0, inv_h, ehist, gs, hs, pAe, RAe, D, U, L, sw
            )
            need = False
            jage[b] = 0
            good = block_factor_head(n, D, U, L, G, piv)
            if good:
                for a in range(6):
                    for c in range(6):
                        S[a, c] = D[n - 1, a, c]
                good = _tip_refactor(n, D, piv, S, bp, rot, b0 + n - 1, tipF, tipK, sw)
            if good:
                jkey[b] = key
            else:
                jkey[b] = 0.0
                break
        elif in_contact(tip_state):
            # contact: the tip block at the current load, on the reused chain factors
            if not _tip_refactor(n, D, piv, S, bp, rot, b0 + n - 1, tipF, tipK, sw):
                need = True
                it -= 1
                continue
        for k in range(n):
            for a in range(6):
                r0[k, a] = res[k, a]
                res[k, a] = -res[k, a]
        block_solve(n, D, L, G, piv, res, dq)
        # Line search on the directional derivative g(alpha) = dq . r(q + alpha dq) (the
        # energy-like measure of structural Newton solvers): the residual norm itself is a poor
        # merit here, because the stiff axial/shear terms react to second-order geometry.
        g0 = 0.0
        dmax = 0.0
        _save_chain(b0, n, pos, rot, t_pos, t_rot)
        for k in range(n):
            for a in range(6):
                g0 += dq[k, a] * r0[k, a]
            for a in range(3):
                if abs(dq[k, 3 + a]) > dmax:
                    dmax = abs(dq[k, 3 + a])
        # cap the rotation increment of one iteration (keeps the log map far from pi) and the
        # tip's displacement (a trust region: the contact laws are ~10^3 times stiffer than the
        # bristle, and an unbounded step can throw the tip deep into the plate or a neighbour)
        alpha = 1.0 if dmax <= MAX_ROT_STEP else MAX_ROT_STEP / dmax
        kl = n - 1
        il = b0 + kl
        hl = bp[il, 4]
        r0x = hl * rot[il, 0, 0]
        r0y = hl * rot[il, 1, 0]
        r0z = hl * rot[il, 2, 0]
        dpx = dq[kl, 0] + dq[kl, 4] * r0z - dq[kl, 5] * r0y
        dpy = dq[kl, 1] + dq[kl, 5] * r0x - dq[kl, 3] * r0z
        dpz = dq[kl, 2] + dq[kl, 3] * r0y - dq[kl, 4] * r0x
        dtip = np.sqrt(dpx * dpx + dpy * dpy + dpz * dpz)
        tipcap = MAX_TIP_STEP * tip_args[3]
        touching = in_contact(tip_state)
        if touching and alpha * dtip > tipcap:
            alpha = tipcap / dtip
        small[6] = dpx
        small[7] = dpy
        small[8] = dpz
        for a in range(3):
            small[9 + a] = pos[il, a] + hl * rot[il, a, 0]
        apen = penetration_step_limit(
            b, small[9:12], small[6:9], tip_args[3], ctx[0], ctx[2], ctx[3], ctx[4], ctx[5], sw[4]
        )
        if apen < alpha:
            alpha = max(apen, 1e-3)
        if not static:
            aslip = slip_step_limit(small[9:12], small[6:9], tip_state, c0, inv_h, ctx[1][C_VD])
            if aslip < alpha:
                alpha = max(aslip, 1e-4)
        accepted = False
        for _ls in range(8):
            _chain_update(b0, n, bp, pos, rot, t_pos, t_rot, dq, alpha, pAe, RAe, sw)
            new = _residual(
                b,
                b0,
                n,
                bp,
                K,
                pos,
                rot,
                gvec,
                static,
                c0,
                inv_h,
                cm,
                vm,
                Lm,
                thp,
                Rn,
                ehist,
                gs,
                hs,
                pAe,
                RAe,
                tip_args,
                tip_state,
                ctx,
                res,
                rootw,
                tipF,
                tipK,
                sw,
            )
            if not np.isfinite(new):
                alpha *= 0.25
                continue
            ga = 0.0
            for k in range(n):
                for a in range(6):
                    ga += dq[k, a] * res[k, a]
            if new <= rtol or g0 >= 0.0 or ga <= 0.5 * abs(g0) or new < 0.9 * nrm:
                accepted = True
                break
            # overshoot (g changed sign): secant estimate of the zero of g, safeguarded
            alpha = max(0.1 * alpha, min(0.9 * alpha, alpha * (-g0) / (ga - g0)))
        if not accepted:
            # restore the iterate; retry with fresh factors unless they were fresh already
            _load_chain(b0, n, pos, rot, t_pos, t_rot)
            if fresh:
                break
            need = True
            nrm = _residual(
                b,
                b0,
                n,
                bp,
                K,
                pos,
                rot,
                gvec,
                static,
                c0,
                inv_h,
                cm,
                vm,
                Lm,
                thp,
                Rn,
                ehist,
                gs,
                hs,
                pAe,
                RAe,
                tip_args,
                tip_state,
                ctx,
                res,
                rootw,
                tipF,
                tipK,
                sw,
            )
            continue
        if fresh and new > 0.5 * nrm and new <= STAGNATION * rtol:
            # stagnation: a fresh Newton step no longer reduces a residual already within
            # STAGNATION x the tolerance (observed floors 1e-7..1e-6 relative to E I / L^2 for tips
            # sticking in friction contact, i.e. ~1e-9 N): accept rather than sub-step
            nrm = new
            ok = True
            break
        if alpha < 1.0:
            need = True  # the step was cut: the factors no longer describe the way down
        elif not fresh and new > SLOW * nrm and new > rtol:
            # old factors converge slowly: rebuild unless the rest is cheaper at this rate
            rho = new / nrm
            if rho >= 1.0 or np.log(rtol / new) / np.log(rho) > REBUILD_ITERS:
                need = True
        nrm = new
        # round-off floor: the update no longer moves the state (|alpha dq| at the level of the
        # coordinates' last bits) and the residual is within 100x of the tolerance: accept
        if nrm <= 100.0 * rtol:
            stepmax = 0.0
            for k in range(n):
                for a in range(3):
                    v = abs(alpha * dq[k, a]) / (abs(pos[b0 + k, a]) + bp[b0 + k, 5])
                    if v > stepmax:
                        stepmax = v
                    v = abs(alpha * dq[k, 3 + a])
                    if v > stepmax:
                        stepmax = v
            if stepmax < 1e-13:
                ok = True
                break
        ok = nrm <= rtol
    if not ok:
        for k in range(n):
            i = b0 + k
            for a in range(3):
                pos[i, a] = s_pos[k, a]
                vel[i, a] = s_vel[k, a]
                omg[i, a] = s_omg[k, a]
                for bb in range(3):
                    rot[i, a, bb] = s_rot[k, a, bb]
        return False, it
    # accept: commit the stiction deformation, rates from the discrete formula, shift history
    for a in range(3):
        tip_state[S_DELTA + a] = tip_state[S_DNEW + a]
    tip_state[S_BETA] = tip_state[S_BNEW]
    for k in range(n):
        i = b0 + k
        reorthonormalize(rot[i])  # see the kernel: keeps the chain update free of drift
        if static:
            for a in range(3):
                vel[i, a] = 0.0
                omg[i, a] = 0.0
        else:
            _local_rot_into(rot[i], Rn[k], th)
            for a in range(3):
                vel[i, a] = (c0 * pos[i, a] + cm[k, a]) * inv_h
                omg[i, a] = (c0 * th[a] + thp[k, a]) * inv_h
        for a in range(3):
            pppos[i, a] = ppos[i, a]
            ppos[i, a] = s_pos[k, a]
            pvel[i, a] = s_vel[k, a]
            pomg[i, a] = s_omg[k, a]
            for bb in range(3):
                pprot[i, a, bb] = prot[i, a, bb]
                prot[i, a, bb] = s_rot[k, a, bb]
    return True, it


@njit(**HOT)
def _tcp_to_base(tp, tR, rp, rR, pout, Rout):
    """Root node pose in the world: p = p_tcp + R_tcp r, R = R_tcp R_root."""
    for a in range(3):
        pout[a] = tp[a] + tR[a, 0] * rp[0] + tR[a, 1] * rp[1] + tR[a, 2] * rp[2]
        for b in range(3):
            Rout[a, b] = tR[a, 0] * rR[0, b] + tR[a, 1] * rR[1, b] + tR[a, 2] * rR[2, b]


@njit(**HOT, inline="always")
def _tip_node_state(b, il, bp, pos, rot, vel, omg, out):
    """out[b, 0:3] <- tip node (sphere centre) [mm], out[b, 3:6] <- its velocity [mm/s] (world):
    p = c + r, v = v_c + omega x r with r = half R e_x of the last body ``il``."""
    hl = bp[il, 4]
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


@njit(cache=True)
def step_bristles(
    bstart,
    bp,
    K,
    pos,
    rot,
    vel,
    omg,
    ppos,
    prot,
    pvel,
    pomg,
    pppos,
    pprot,
    hist_ok,
    tcp_p,
    tcp_R,
    root_p,
    root_R,
    prm,
    tip_args,
    tip_state,
    ctx,
    jac,
    ws,
    rootw,
    iters,
    nsub,
    status,
):
    """Advance every bristle by one step h = prm[P_H] (in place).

    tcp_p (4, 3), tcp_R (4, 3, 3): TCP pose at t_{n-1}, t_n, t_{n+1}, t_{n-2} (rows 0, 1, 2, 3).
    pppos/pprot: positions and rotations at t_{n-2} (the third-order predictor's history).
    hist_ok (nb,): whole steps behind each bristle's history, 0, 1 or 2 (after a sub-stepped step
    the history is not on the step grid: 0).
    root_p (nb, 3), root_R (nb, 3, 3): root node pose of each bristle in the TCP frame.
    tip_args (nb, na), tip_state (nb, ns): tip-load parameters and per-contact state (contact.py).
    ctx = (surf, cp, tips, pair_ptr, pair_idx, mesh): surfaces, contact law parameters, every
    tip's node position/velocity/radius (nb, 7), the tip-tip partner lists (CSR) and the scene's
    triangle mesh with its grid index (contact.build_mesh).  Bristles are
    solved in order; each one sees its partners' latest tips (one Gauss-Seidel sweep), and its
    own entry in ``tips`` is updated as soon as it has been advanced.
    Outputs per bristle: rootw (force, moment of the root element on the head, at the root node,
    world), iters (Newton iterations), nsub (sub-steps used), status (OK / NEWTON_FAILED).
    """
    nb = bstart.shape[0] - 1
    h = prm[P_H]
    method = int(prm[P_METHOD])
    maxlev = int(prm[P_MAXLEV])
    tp = np.empty(3)
    tR = np.empty((3, 3))
    tmp = np.empty(3)
    pAs = np.empty(3)
    RAs = np.empty((3, 3))
    pAe = np.empty(3)
    RAe = np.empty((3, 3))
    pAp = np.empty(3)
    RAp = np.empty((3, 3))
    pAq = np.empty(3)
    RAq = np.empty((3, 3))
    for b in range(nb):
        b0 = bstart[b]
        n = bstart[b + 1] - b0
        bk3 = ws[5]
        bkR = ws[6]
        bktip = ws[7]
        bk3[0, :n] = pos[b0 : b0 + n]
        bk3[1, :n] = vel[b0 : b0 + n]
        bk3[2, :n] = omg[b0 : b0 + n]
        bk3[3, :n] = ppos[b0 : b0 + n]
        bk3[4, :n] = pvel[b0 : b0 + n]
        bk3[5, :n] = pomg[b0 : b0 + n]
        bk3[6, :n] = pppos[b0 : b0 + n]
        bkR[0, :n] = rot[b0 : b0 + n]
        bkR[1, :n] = prot[b0 : b0 + n]
        bkR[2, :n] = pprot[b0 : b0 + n]
        bktip[:] = tip_state[b]
        s = 0.0
        level = 0
        tot = 0
        nsteps = 0
        status[b] = OK
        _tcp_to_base(tcp_p[0], tcp_R[0], root_p[b], root_R[b], pAp, RAp)
        _tcp_to_base(tcp_p[3], tcp_R[3], root_p[b], root_R[b], pAq, RAq)
        while s < 1.0 - 1e-12:
            ds = 0.5**level
            if s + ds > 1.0:
                ds = 1.0 - s
            whole = level == 0 and s == 0.0
            if method == 1 and whole and hist_ok[b] != 0:
                c0, c1, c2 = 1.5, -2.0, 0.5
            else:
                c0, c1, c2 = 1.0, -1.0, 0.0
            _base_pose(tcp_p[1], tcp_R[1], tcp_p[2], tcp_R[2], s, tp, tR, tmp)
            _tcp_to_base(tp, tR, root_p[b], root_R[b], pAs, RAs)
            _base_pose(tcp_p[1], tcp_R[1], tcp_p[2], tcp_R[2], s + ds, tp, tR, tmp)
            _tcp_to_base(tp, tR, root_p[b], root_R[b], pAe, RAe)
            # predictor order: 3 with two whole steps of history, 2 with one, none otherwise
            extrap = 0
            if whole and prm[P_STATIC] == 0.0 and hist_ok[b] > 0:
                extrap = 3 if hist_ok[b] >= 2 else 2
            ok, it = _newton(
                b,
                b0,
                n,
                bp,
                K,
                pos,
                rot,
                vel,
                omg,
                ppos,
                prot,
                pvel,
                pomg,
                pppos,
                pprot,
                prm,
                c0,
                c1,
                c2,
                h * ds,
                pAs,
                RAs,
                pAe,
                RAe,
                pAp,
                RAp,
                pAq,
                RAq,
                tip_args[b],
                tip_state[b],
                ctx,
                rootw[b],
                jac,
                ws,
                extrap,
            )
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
                    status[b] = NEWTON_FAILED
                    pos[b0 : b0 + n] = bk3[0, :n]
                    vel[b0 : b0 + n] = bk3[1, :n]
                    omg[b0 : b0 + n] = bk3[2, :n]
                    ppos[b0 : b0 + n] = bk3[3, :n]
                    pvel[b0 : b0 + n] = bk3[4, :n]
                    pomg[b0 : b0 + n] = bk3[5, :n]
                    pppos[b0 : b0 + n] = bk3[6, :n]
                    rot[b0 : b0 + n] = bkR[0, :n]
                    prot[b0 : b0 + n] = bkR[1, :n]
                    pprot[b0 : b0 + n] = bkR[2, :n]
                    tip_state[b] = bktip
                    break
        iters[b] = tot
        nsub[b] = nsteps
        _tip_node_state(b, b0 + n - 1, bp, pos, rot, vel, omg, ctx[2])
        hist_ok[b] = min(hist_ok[b] + 1, 2) if (nsteps == 1 and status[b] == OK) else 0
