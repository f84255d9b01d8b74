"""Numba kernels: beam element forces, per-bristle residual/Jacobian, block-tridiagonal Newton.

Flat structure-of-arrays over all bodies of all bristles (N bodies, nb bristles):

=============  ===========  ================================================================
array          shape        meaning [unit]
=============  ===========  ================================================================
bstart         (nb+1,)      body index range of each bristle
bp             (N, 8)       body params: mass [t], Jx, Jy, Jz [t mm^2], half length [mm],
                            element length l [mm], damping beta [s], force scale [N]
K              (N, 6, 6)    stiffness of the element that ends at this body (eq 1)
pos, rot       (N,3),(N,3,3) centre of mass [mm] and rotation (body -> world)
vel, omg       (N, 3)       velocity [mm/s] and angular velocity [rad/s] (world)
=============  ===========  ================================================================

Scratch memory is allocated once per kernel call and reused, so the hot loops do not allocate.
The integrator is written with the generic two-step formula ``y' ~ (c0 y_{n+1} + c1 y_n +
c2 y_{n-1}) / h``: backward Euler (1, -1, 0) or BDF2 (3/2, -2, 1/2).  Rotations use local
rotation vectors about R_n, so the same coefficients apply on SO(3).
"""

from __future__ import annotations

import numpy as np
from numba import njit


# status codes per bristle
OK = 0
NEWTON_FAILED = 1
NONFINITE = 2



# --------------------------------------------------------------------------- small linear algebra
@njit(cache=True, inline="always")
def _log3s(r00, r01, r02, r10, r11, r12, r20, r21, r22, out):
    """Rotation vector of the rotation matrix given by its 9 entries, into ``out`` (no allocation)."""
    c = 0.5 * (r00 + r11 + r22 - 1.0)
    if c > 1.0:
        c = 1.0
    elif c < -1.0:
        c = -1.0
    w0 = 0.5 * (r21 - r12)
    w1 = 0.5 * (r02 - r20)
    w2 = 0.5 * (r10 - r01)
    s = np.sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    th = np.arctan2(s, c)
    if th < 1e-6:
        f = 1.0 + th * th / 6.0
    elif th < 3.0:
        f = th / s
    else:
        # close to pi: the axis is the dominant column of the symmetric part (R + R^T)/2 - c I
        if r00 >= r11 and r00 >= r22:
            a0, a1, a2 = r00 - c, 0.5 * (r10 + r01), 0.5 * (r20 + r02)
        elif r11 >= r22:
            a0, a1, a2 = 0.5 * (r01 + r10), r11 - c, 0.5 * (r21 + r12)
        else:
            a0, a1, a2 = 0.5 * (r02 + r20), 0.5 * (r12 + r21), r22 - c
        nrm = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
        if a0 * w0 + a1 * w1 + a2 * w2 < 0.0:
            nrm = -nrm
        out[0] = th * a0 / nrm
        out[1] = th * a1 / nrm
        out[2] = th * a2 / nrm
        return
    out[0] = w0 * f
    out[1] = w1 * f
    out[2] = w2 * f


@njit(cache=True)
def _local_rot_into(R, Rn, out):
    """out = log(R Rn^T): world-frame rotation vector taking Rn to R."""
    _log3s(R[0, 0] * Rn[0, 0] + R[0, 1] * Rn[0, 1] + R[0, 2] * Rn[0, 2],
           R[0, 0] * Rn[1, 0] + R[0, 1] * Rn[1, 1] + R[0, 2] * Rn[1, 2],
           R[0, 0] * Rn[2, 0] + R[0, 1] * Rn[2, 1] + R[0, 2] * Rn[2, 2],
           R[1, 0] * Rn[0, 0] + R[1, 1] * Rn[0, 1] + R[1, 2] * Rn[0, 2],
           R[1, 0] * Rn[1, 0] + R[1, 1] * Rn[1, 1] + R[1, 2] * Rn[1, 2],
           R[1, 0] * Rn[2, 0] + R[1, 1] * Rn[2, 1] + R[1, 2] * Rn[2, 2],
           R[2, 0] * Rn[0, 0] + R[2, 1] * Rn[0, 1] + R[2, 2] * Rn[0, 2],
           R[2, 0] * Rn[1, 0] + R[2, 1] * Rn[1, 1] + R[2, 2] * Rn[1, 2],
           R[2, 0] * Rn[2, 0] + R[2, 1] * Rn[2, 1] + R[2, 2] * Rn[2, 2], out)


@njit(cache=True, inline="always")
def _rotate_left(v0, v1, v2, R, out):
    """out = exp([v]) @ R (Rodrigues), no allocation."""
    th2 = v0 * v0 + v1 * v1 + v2 * v2
    th = np.sqrt(th2)
    if th < 1e-6:
        a = 1.0 - th2 / 6.0
        b = 0.5 - th2 / 24.0
    else:
        a = np.sin(th) / th
        b = (1.0 - np.cos(th)) / th2
    # E = I + a K + b K^2, K = skew(v)
    E00 = 1.0 - b * (v1 * v1 + v2 * v2)
    E11 = 1.0 - b * (v0 * v0 + v2 * v2)
    E22 = 1.0 - b * (v0 * v0 + v1 * v1)
    E01 = -a * v2 + b * v0 * v1
    E10 = a * v2 + b * v0 * v1
    E02 = a * v1 + b * v0 * v2
    E20 = -a * v1 + b * v0 * v2
    E12 = -a * v0 + b * v1 * v2
    E21 = a * v0 + b * v1 * v2
    for j in range(3):
        r0 = R[0, j]
        r1 = R[1, j]
        r2 = R[2, j]
        out[0, j] = E00 * r0 + E01 * r1 + E02 * r2
        out[1, j] = E10 * r0 + E11 * r1 + E12 * r2
        out[2, j] = E20 * r0 + E21 * r1 + E22 * r2


@njit(cache=True)
def reorthonormalize(R):
    """R <- R (3 I - R^T R) / 2 in place: one step of the polar (Newton-Schulz) iteration.

    Products of many small rotations drift from orthonormality by ~1e-16 per product; after a few
    hundred steps ``R R^T - I`` reaches ~1e-12 and the chain update, which maps strains through
    ``R_A^T`` and back through ``R_A``, then shifts nodes by ~1e-12 mm on its own.  A sticking
    friction contact (tangent stiffness ~1e4 N/mm at small sub-steps) turns that shift into a
    residual floor Newton cannot pass.  The error is squared by each step, so one per accepted
    time step keeps R orthonormal to round-off.
    """
    M = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            M[a, b] = -0.5 * (R[0, a] * R[0, b] + R[1, a] * R[1, b] + R[2, a] * R[2, b])
        M[a, a] += 1.5
    for a in range(3):
        r0 = R[a, 0]
        r1 = R[a, 1]
        r2 = R[a, 2]
        for b in range(3):
            R[a, b] = r0 * M[0, b] + r1 * M[1, b] + r2 * M[2, b]


@njit(cache=True)
def _lu6(A, piv):
    """In-place LU with partial pivoting of a 6x6 block. Returns False if singular."""
    n = 6
    for k in range(n):
        p = k
        amax = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > amax:
                amax = abs(A[i, k])
                p = i
        piv[k] = p
        if amax == 0.0 or not np.isfinite(amax):
            return False
        if p != k:
            for j in range(n):
                t = A[k, j]
                A[k, j] = A[p, j]
                A[p, j] = t
        inv = 1.0 / A[k, k]
        for i in range(k + 1, n):
            A[i, k] *= inv
            f = A[i, k]
            for j in range(k + 1, n):
                A[i, j] -= f * A[k, j]
    return True


@njit(cache=True)
def _lus6(A, piv, b):
    """Solve in place with the factors of _lu6 (b is a 6-vector)."""
    n = 6
    for k in range(n):
        p = piv[k]
        if p != k:
            t = b[k]
            b[k] = b[p]
            b[p] = t
    for i in range(1, n):
        s = b[i]
        for j in range(i):
            s -= A[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= A[i, j] * b[j]
        b[i] = s / A[i, i]


# --------------------------------------------------------------------------- beam element (eq 1-5)
@njit(cache=True)
def element_forces(RA, pA, RB, pB, K, length, ehist, gs, hs, out, e):
    """Forces of one Timoshenko element (eq 5) on its two nodes.

    Strain e = [R_A^T (p_B - p_A) - l e_x ; log(R_A^T R_B)] (co-rotational, proximal frame A).
    Generalised force f = K (gs * e + hs * ehist): with damping C = beta K, gs = 1 + beta c0 / h
    and hs = beta / h, ehist = c1 e_n + c2 e_{n-1} (gs = 1, hs = 0 for statics).
    out[0:3], out[3:6]: force and moment on node A (world); out[6:9], out[9:12]: on node B.
    The moment on A balances the element exactly: M_A = -M_B - (p_B - p_A) x F_B.
    """
    dx = pB[0] - pA[0]
    dy = pB[1] - pA[1]
    dz = pB[2] - pA[2]
    e[0] = RA[0, 0] * dx + RA[1, 0] * dy + RA[2, 0] * dz - length
    e[1] = RA[0, 1] * dx + RA[1, 1] * dy + RA[2, 1] * dz
    e[2] = RA[0, 2] * dx + RA[1, 2] * dy + RA[2, 2] * dz
    # relative rotation R_A^T R_B
    q00 = RA[0, 0] * RB[0, 0] + RA[1, 0] * RB[1, 0] + RA[2, 0] * RB[2, 0]
    q01 = RA[0, 0] * RB[0, 1] + RA[1, 0] * RB[1, 1] + RA[2, 0] * RB[2, 1]
    q02 = RA[0, 0] * RB[0, 2] + RA[1, 0] * RB[1, 2] + RA[2, 0] * RB[2, 2]
    q10 = RA[0, 1] * RB[0, 0] + RA[1, 1] * RB[1, 0] + RA[2, 1] * RB[2, 0]
    q11 = RA[0, 1] * RB[0, 1] + RA[1, 1] * RB[1, 1] + RA[2, 1] * RB[2, 1]
    q12 = RA[0, 1] * RB[0, 2] + RA[1, 1] * RB[1, 2] + RA[2, 1] * RB[2, 2]
    q20 = RA[0, 2] * RB[0, 0] + RA[1, 2] * RB[1, 0] + RA[2, 2] * RB[2, 0]
    q21 = RA[0, 2] * RB[0, 1] + RA[1, 2] * RB[1, 1] + RA[2, 2] * RB[2, 1]
    q22 = RA[0, 2] * RB[0, 2] + RA[1, 2] * RB[1, 2] + RA[2, 2] * RB[2, 2]
    _log3s(q00, q01, q02, q10, q11, q12, q20, q21, q22, e[3:6])
    f0 = 0.0
    f1 = 0.0
    f2 = 0.0
    m0 = 0.0
    m1 = 0.0
    m2 = 0.0
    for j in range(6):
        gj = gs * e[j] + hs * ehist[j]
        f0 += K[0, j] * gj
        f1 += K[1, j] * gj
        f2 += K[2, j] * gj
        m0 += K[3, j] * gj
        m1 += K[4, j] * gj
        m2 += K[5, j] * gj
    FB0 = -(RA[0, 0] * f0 + RA[0, 1] * f1 + RA[0, 2] * f2)
    FB1 = -(RA[1, 0] * f0 + RA[1, 1] * f1 + RA[1, 2] * f2)
    FB2 = -(RA[2, 0] * f0 + RA[2, 1] * f1 + RA[2, 2] * f2)
    MB0 = -(RA[0, 0] * m0 + RA[0, 1] * m1 + RA[0, 2] * m2)
    MB1 = -(RA[1, 0] * m0 + RA[1, 1] * m1 + RA[1, 2] * m2)
    MB2 = -(RA[2, 0] * m0 + RA[2, 1] * m1 + RA[2, 2] * m2)
    out[6] = FB0
    out[7] = FB1
    out[8] = FB2
    out[9] = MB0
    out[10] = MB1
    out[11] = MB2
    out[0] = -FB0
    out[1] = -FB1
    out[2] = -FB2
    out[3] = -MB0 - (dy * FB2 - dz * FB1)
    out[4] = -MB1 - (dz * FB0 - dx * FB2)
    out[5] = -MB2 - (dx * FB1 - dy * FB0)


@njit(cache=True)
def _node(c, R, half, out):
    """Distal node of a body: p = c + half * R e_x."""
    out[0] = c[0] + half * R[0, 0]
    out[1] = c[1] + half * R[1, 0]
    out[2] = c[2] + half * R[2, 0]


@njit(cache=True)
def _body_gen(cn, pn, F, out):
    """Generalised force on a body from a node force/moment: (F, M + (p - c) x F)."""
    rx = pn[0] - cn[0]
    ry = pn[1] - cn[1]
    rz = pn[2] - cn[2]
    out[0] = F[0]
    out[1] = F[1]
    out[2] = F[2]
    out[3] = F[3] + ry * F[2] - rz * F[1]
    out[4] = F[4] + rz * F[0] - rx * F[2]
    out[5] = F[5] + rx * F[1] - ry * F[0]


@njit(cache=True)
def _element_gen(aIsBase, cA, RA, halfA, pAbase, cB, RB, halfB, K, length, ehist, gs, hs,
                 out12, e, w):
    """Generalised forces (on body A COM, on body B COM) of one element; w: (4, 12) scratch."""
    pA = w[0, 0:3]
    pB = w[0, 3:6]
    if aIsBase:
        pA[0] = pAbase[0]
        pA[1] = pAbase[1]
        pA[2] = pAbase[2]
    else:
        _node(cA, RA, halfA, pA)
    _node(cB, RB, halfB, pB)
    nf = w[1]
    element_forces(RA, pA, RB, pB, K, length, ehist, gs, hs, nf, e)
    if aIsBase:
        for i in range(6):
            out12[i] = nf[i]
    else:
        _body_gen(cA, pA, nf[0:6], out12[0:6])
    _body_gen(cB, pB, nf[6:12], out12[6:12])




@njit(cache=True)
def block_factor(n, D, U, L, G, piv):
    """Factor the block-tridiagonal matrix (L_i, D_i, U_i) in place (block Thomas, O(n)).

    D becomes the LU factors of the Schur complements, G_i = D_i^-1 U_i.  Returns False if a pivot
    block is singular.  Solve with ``block_solve``; the factors can be reused for many solves.
    """
    tmp = np.empty(6)
    for i in range(n):
        if i > 0:
            for a in range(6):
                for b in range(6):
                    s = 0.0
                    for k in range(6):
                        s += L[i, a, k] * G[i - 1, k, b]
                    D[i, a, b] -= s
        if not _lu6(D[i], piv[i]):
            return False
        if i < n - 1:
            for b in range(6):
                for a in range(6):
                    tmp[a] = U[i, a, b]
                _lus6(D[i], piv[i], tmp)
                for a in range(6):
                    G[i, a, b] = tmp[a]
    return True


@njit(cache=True)
def block_solve(n, D, L, G, piv, r, x):
    """Solve with the factors of ``block_factor``: x = A^-1 r (r is left unchanged)."""
    for i in range(n):
        for a in range(6):
            s = r[i, a]
            if i > 0:
                for k in range(6):
                    s -= L[i, a, k] * x[i - 1, k]
            x[i, a] = s
        _lus6(D[i], piv[i], x[i])
    for i in range(n - 2, -1, -1):
        for a in range(6):
            s = 0.0
            for k in range(6):
                s += G[i, a, k] * x[i + 1, k]
            x[i, a] -= s
