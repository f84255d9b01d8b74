"""The residual of the discrete momentum balance (eq 11) and its Newton matrix, per bristle.

Residual (``bristle_residual``): for every body, the rate of momentum by the two-step formula minus
gravity (eq 11, ``_inertia_residual``), minus the element loads of its two elements (eq 1-5,
``_kernels.element_gen``), and on the tip body minus the tip load (eq 6-10 and Table 3,
``contact.tip_load``).  Newton matrix (``jacobian``): inertia blocks m c0^2/h^2 and
R J R^T c0^2/h^2, element blocks by forward differences of eq 5, the tip block from the tip
stiffness (``tipblock.add_tip_block``); block tridiagonal (6x6 blocks), factored by block
Thomas (``rebuild_factors``, ``tip_refactor``).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import (
    HOT,
    block_factor_head,
    body_node,
    element_gen,
    element_strain,
    local_rot_into,
    lu6,
    rotate_left,
)
from .contact import tip_load
from .near import tip_scene
from .records import Damp, Node, ShaftWork
from .shaft import add_shaft_blocks, shaft_load
from .tipblock import add_tip_block as _add_tip_block


@njit(**HOT, inline="always")
def element_at(k, br, model, P, Q, pAb, RAb, damp, el):
    """Element k of bristle ``br`` (eq 5) for body poses P/Q (positions/rotations of all bodies)
    and the base node (pAb, RAb): generalised forces into el.out12, strain into el.e."""
    bp = model.bp
    i = br.b0 + k
    kind = model.elem[i]
    B = Node(P[i], Q[i], bp[i].half)
    # one call with a run-time flag: a literal True/False would compile each element twice more
    isroot = k == 0
    j = i - 1 if k > 0 else i
    A = Node(pAb, RAb, 0.0) if isroot else Node(P[j], Q[j], bp[j].half)
    element_gen(kind, isroot, A, pAb, B, model.K[i], bp[i].length, damp, el.out12, el.e)


@njit(**HOT, inline="always")
def strain_at(k, br, model, P, Q, pAb, RAb, e):
    """The strain of element k of bristle ``br`` (``element_at``'s ``el.e``, to the same bits)
    into ``e``, without its loads (``_kernels.element_strain``)."""
    bp = model.bp
    i = br.b0 + k
    B = Node(P[i], Q[i], bp[i].half)
    isroot = k == 0
    j = i - 1 if k > 0 else i
    A = Node(pAb, RAb, 0.0) if isroot else Node(P[j], Q[j], bp[j].half)
    element_strain(model.elem[i], isroot, A, pAb, B, bp[i].length, e)


@njit(**HOT, inline="always")
def _inertia_residual(br, model, chain, sub, hist, res):
    """res <- rate of momentum minus gravity of every body (eq 11, the discrete formula); each
    body's rotation vector log(R R_n^T) into hist.thn (``newton._commit`` takes the converged
    iterate's from there: the last residual evaluated is always at the committed state)."""
    bp = model.bp
    pos = chain.pos
    rot = chain.rot
    c0 = sub.c0
    inv_h = sub.inv_h
    gvec = sub.g
    for k in range(br.n):
        i = br.b0 + k
        m = bp[i].mass
        if sub.static:
            for a in range(3):
                res[k, a] = -m * gvec[a]
                res[k, 3 + a] = 0.0
            continue
        for a in range(3):
            vk = (c0 * pos[i, a] + hist.cm[k, a]) * inv_h
            res[k, a] = m * (c0 * vk + hist.vm[k, a]) * inv_h - m * gvec[a]
        th = hist.thn[k]
        local_rot_into(rot[i], hist.Rn[k], th)
        om0 = (c0 * th[0] + hist.thp[k, 0]) * inv_h
        om1 = (c0 * th[1] + hist.thp[k, 1]) * inv_h
        om2 = (c0 * th[2] + hist.thp[k, 2]) * inv_h
        R = rot[i]
        ob0 = (R[0, 0] * om0 + R[1, 0] * om1 + R[2, 0] * om2) * bp[i].J[0]
        ob1 = (R[0, 1] * om0 + R[1, 1] * om1 + R[2, 1] * om2) * bp[i].J[1]
        ob2 = (R[0, 2] * om0 + R[1, 2] * om1 + R[2, 2] * om2) * bp[i].J[2]
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
        fs = bp[i].fscale
        ls = fs * bp[i].length
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
def bristle_residual(br, model, chain, sub, base, con, ws, rootw):
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
    _inertia_residual(br, model, chain, sub, hist, res)
    for k in range(br.n):
        damp = Damp(hist.ehist[k], hist.gs[k], hist.hs[k])
        element_at(k, br, model, chain.pos, chain.rot, base.pAe, base.RAe, damp, el)
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
    body_node(pos[il], chain.rot[il], model.bp[il].half, pt)
    # the partners that can touch this tip: the step's near list where it holds (``near.py``)
    tcon = tip_scene(con, ws.sw.near, br.b, pt, 0.0)
    tip_load(br.b, pt, sub, tcon, tipF, it.tipK, ws.tipw)
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
    # the bodies' capsules (shaft.py; no-op if off), given only the scratch they use
    sx = ShaftWork(ws.sh, ws.tipw, ws.blk, it.s_pos, it.s_rot)
    shaft_load(br, chain, sub, con, sx, res)
    return _residual_norm(br, model.bp, res)


@njit(**HOT)
def jacobian(br, model, chain, sub, base, hist, D, U, L, ws):
    """Newton matrix d(res)/d(q), q_k = (dc_k, dtheta_k) in world axes (block tridiagonal).

    Inertia blocks m c0^2/h^2 and R J R^T c0^2/h^2 (terms of order omega*h dropped); element
    blocks by forward differences of the element's generalised forces; tip load blocks from the
    tip stiffness ``ws.it.tipK`` and the lever arm.  The Jacobian only steers Newton: the
    converged state is fixed by the residual alone.
    """
    _jacobian_chain(br, model, chain, sub, base, hist, D, U, L, ws.el)
    add_shaft_blocks(br, D, ws.sh)
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
            D[k, a, a] = bp[i].mass * s2
            for b in range(3):
                D[k, 3 + a, 3 + b] = s2 * (
                    R[a, 0] * bp[i].J[0] * R[b, 0]
                    + R[a, 1] * bp[i].J[1] * R[b, 1]
                    + R[a, 2] * bp[i].J[2] * R[b, 2]
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
    rotate_left(
        eps_r if col == 3 else 0.0,
        eps_r if col == 4 else 0.0,
        eps_r if col == 5 else 0.0,
        rot[src],
        RP,
    )
    return eps_r


@njit(**HOT)
def _jacobian_chain(br, model, chain, sub, base, hist, D, U, L, el):
    """The inertia and element blocks of ``jacobian`` (everything but the tip load)."""
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
        hB = bp[i].half
        ln = bp[i].length
        epsx = 1e-7 * ln
        epsr = 1e-7
        isroot = k == 0
        j = i - 1 if k > 0 else i  # index of body A (unused for the root element)
        A = Node(pAb, RAb, 0.0) if isroot else Node(pos[j], rot[j], bp[j].half)
        B = Node(pos[i], rot[i], hB)
        damp = Damp(hist.ehist[k], hist.gs[k], hist.hs[k])
        kind = model.elem[i]
        element_gen(kind, isroot, A, pAb, B, model.K[i], ln, damp, basef, e)
        nside = 1 if isroot else 2
        for side in range(nside):  # side 0: perturb body B (= k), side 1: body A (= k-1)
            src = i if side == 0 else j
            for col in range(6):
                eps = _perturbed(src, col, epsx, epsr, pos, rot, el.cP, el.RP)
                if side == 0:
                    BP = Node(el.cP, el.RP, hB)
                    element_gen(kind, isroot, A, pAb, BP, model.K[i], ln, damp, pert, e)
                else:
                    AP = Node(el.cP, el.RP, A.half)
                    # (isroot is False on this side)
                    element_gen(kind, isroot, AP, pAb, B, model.K[i], ln, damp, pert, e)
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
def tip_refactor(br, D, piv, S, bp, rot, ws):
    """Last block of the factored Newton matrix <- LU(S + tip block at the current tip load).

    S is the tip body's Schur complement without the tip load (``block_factor_head``), so this
    makes the contact part of the Newton matrix current for the price of one 6x6 LU, while the
    chain's blocks (which change slowly) are reused.  Returns False if the block is singular."""
    Dl = D[br.n - 1]
    for a in range(6):
        for c in range(6):
            Dl[a, c] = S[a, c]
    _add_tip_block(Dl, bp, rot, br.il, ws.it, ws.blk)
    return lu6(Dl, piv[br.n - 1])


@njit(**HOT, inline="always")
def rebuild_factors(br, model, chain, sub, base, jc, ws, key):
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
    add_shaft_blocks(br, D, ws.sh)  # the shaft contacts' blocks (part of S for the tip body)
    jc.age[br.b] = 0
    good = block_factor_head(n, D, ws.it.U, L, G, piv)
    if good:
        for a in range(6):
            for c in range(6):
                S[a, c] = D[n - 1, a, c]
        good = tip_refactor(br, D, piv, S, model.bp, chain.rot, ws)
    jc.key[br.b] = key if good else 0.0
    return good
