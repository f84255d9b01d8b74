"""The tip load's block of a bristle's Newton matrix (numba kernels): the derivative of the tip
load (eq 6-10, Table 3) and its moment about the tip body's centre with respect to the tip body's
(dc, dtheta).  Used by the per-bristle Newton (newton.py, residual.py) and the tip-tip coupling
(coupling.py)."""

from __future__ import annotations

from numba import njit

from ._kernels import HOT


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


@njit(**HOT, inline="always")
def add_tip_block(Dk, bp, rot, il, it, blk):
    """Dk += d(-tip load, -its moment about c)/d(dc, dtheta) of the tip body ``il``.

    Tip load F = it.tipF at p_tip = c + r, r = half * R e_x, stiffness it.tipK:
    dp_tip = dc - [r]x dtheta."""
    tipF = it.tipF
    tipK = it.tipK
    Sr = blk.Sr
    hl = bp[il].half
    _skew_into(hl * rot[il, 0, 0], hl * rot[il, 1, 0], hl * rot[il, 2, 0], Sr)
    _skew_into(tipF[0], tipF[1], tipF[2], blk.SF)
    _mul3(tipK, Sr, blk.KS)
    _mul3(Sr, tipK, blk.SrK)
    _mul3(Sr, blk.KS, blk.SrKS)
    _mul3(blk.SF, Sr, blk.SFSr)
    # residual rows: -F and -(r x F); dF = K (dc - [r]x dth); d(r x F) = [r]x dF + [F]x [r]x dth
    for a in range(3):
        for b in range(3):
            Dk[a, b] -= tipK[a, b]
            Dk[a, 3 + b] += blk.KS[a, b]
            Dk[3 + a, b] -= blk.SrK[a, b]
            Dk[3 + a, 3 + b] += blk.SrKS[a, b] - blk.SFSr[a, b]


@njit(**HOT, inline="always")
def add_point_block(Dk, r, F, K, blk):
    """Dk += d(-F, -(r x F))/d(dc, dtheta) of a load F [N] with stiffness K = dF/dp [N/mm] acting
    at the body point p = c + r (r [mm] turning with the body): the shaft contacts' block
    (shaft.py), the same algebra as ``add_tip_block``."""
    Sr = blk.Sr
    _skew_into(r[0], r[1], r[2], Sr)
    _skew_into(F[0], F[1], F[2], blk.SF)
    _mul3(K, Sr, blk.KS)
    _mul3(Sr, K, blk.SrK)
    _mul3(Sr, blk.KS, blk.SrKS)
    _mul3(blk.SF, Sr, blk.SFSr)
    for a in range(3):
        for b in range(3):
            Dk[a, b] -= K[a, b]
            Dk[a, 3 + b] += blk.KS[a, b]
            Dk[3 + a, b] -= blk.SrK[a, b]
            Dk[3 + a, 3 + b] += blk.SrKS[a, b] - blk.SFSr[a, b]
