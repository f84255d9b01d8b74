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

#: numba options of the hot kernels: no NRT reference counting.  These kernels never allocate
#: (scratch memory comes from the caller), and with NRT on numba increfs/decrefs (atomically)
#: every array view it hands to a helper -- measured with ``perf`` at ~30 % of a whole step.
#: Without NRT a view is a plain struct.  Kernels that do allocate keep the default options.
#: ``fastmath`` is explicit: numba gives a kernel that does not set the flag the flag of the first
#: caller that compiles it (numba issue 7168) and caches that version without the flag in its
#: key, so a strict kernel first reached from the reduced model's fast-math kernels (``PRB``) was
#: compiled fast-math for the whole process -- the full chain's results then depended on which
#: level ran first and on which process wrote the cache (the last digits; issue 32's note).
#: ``contract`` alone: LLVM may fuse a multiply and an add into one FMA (one rounding instead of
#: two, C compilers' default), -11.8 % instructions per bristle-step on the turn; none of the
#: flags that reorder or assume finite values.  Session 32 tried it and reverted: the 7 GPa press of
#: ``tests/engine/test_contact.py`` then failed Newton on its smallest halving -- a limit cycle
#: that the strict kernels escaped by their last bits, closed since by ``newton._line_search``
#: (docs/benchmarks.md, session 33).
HOT = dict(cache=True, _nrt=False, fastmath={"contract"})


# --------------------------------------------------------------------------- small-angle series
# The rotation maps and the mid element take sin, cos and atan2 of angles that are mostly small:
# a body's rotation over one step, an element's bend.  Below a bound each function is its Taylor
# series in the squared angle, summed by Horner: every term kept past the bound's remainder of
# ~1e-17 relative (tests/engine/test_series.py checks each against the closed form at 40 digits),
# so the series is as exact as the libm call it replaces (~1 ulp), at ~1/5 of its instructions
# (docs/benchmarks.md, "Small-angle series").  Coefficients lowest order first.

#: sin(x) / x
SINC = (
    1.0,
    -1.0 / 6.0,
    1.0 / 120.0,
    -1.0 / 5040.0,
    1.0 / 362880.0,
    -1.0 / 39916800.0,
    1.0 / 6227020800.0,
    -1.0 / 1307674368000.0,
)
#: (1 - cos x) / x^2
VERS = (
    0.5,
    -1.0 / 24.0,
    1.0 / 720.0,
    -1.0 / 40320.0,
    1.0 / 3628800.0,
    -1.0 / 479001600.0,
    1.0 / 87178291200.0,
    -1.0 / 20922789888000.0,
)
#: (sin x - x cos x) / (4 x^3), the arc's q of the mid element
QARC = (
    1.0 / 12.0,
    -1.0 / 120.0,
    1.0 / 3360.0,
    -1.0 / 181440.0,
    1.0 / 15966720.0,
    -1.0 / 2075673600.0,
    1.0 / 373621248000.0,
    -1.0 / 88921857024000.0,
)
#: the three above to 1e-17 relative for x^2 below this
TRIG_SERIES_MAX = 0.25
#: asin(s) / s, C(2k, k) / (4^k (2k + 1)); the rotation log's theta / sin(theta)
ASIN = (
    1.0,
    1.0 / 6.0,
    3.0 / 40.0,
    5.0 / 112.0,
    35.0 / 1152.0,
    63.0 / 2816.0,
    231.0 / 13312.0,
    143.0 / 10240.0,
    6435.0 / 557056.0,
    12155.0 / 1245184.0,
    46189.0 / 5505024.0,
)
#: ASIN to 3e-18 relative for s^2 below this (theta < 0.201)
ASIN_SERIES_MAX = 0.04
#: (1 - (x/2) cot(x/2)) / x^2 and tan(x/4) / x, the mid element's J_l^-T and T (Bernoulli numbers)
JL_C = (
    1.0 / 12.0,
    1.0 / 720.0,
    1.0 / 30240.0,
    1.0 / 1209600.0,
    1.0 / 47900160.0,
    691.0 / 1307674368000.0,
    1.0 / 74724249600.0,
    3617.0 / 10670622842880000.0,
    43867.0 / 5109094217170944000.0,
    174611.0 / 802857662698291200000.0,
    77683.0 / 14101100039391805440000.0,
    236364091.0 / 1693824136731743669452800000.0,
)
JL_T = (
    1.0 / 4.0,
    1.0 / 192.0,
    1.0 / 7680.0,
    17.0 / 5160960.0,
    31.0 / 371589120.0,
    691.0 / 326998425600.0,
    5461.0 / 102023508787200.0,
    929569.0 / 685597979049984000.0,
    3202291.0 / 93241325150797824000.0,
    221930581.0 / 255108265612582846464000.0,
    4722116521.0 / 214290943114569591029760000.0,
    56963745931.0 / 102052910320915024057466880000.0,
)
#: JL_C and JL_T to 1e-19 relative for x^2 below this (theta < 1 rad)
JL_SERIES_MAX = 1.0


@njit(**HOT)
def series(x2, coefs):
    """sum_k coefs[k] x2^k by Horner (a small function: LLVM inlines it; numba does not need to)."""
    r = 0.0
    for k in range(len(coefs) - 1, -1, -1):
        r = r * x2 + coefs[k]
    return r


# --------------------------------------------------------------------------- small linear algebra
@njit(**HOT, inline="always")
def log3s(r00, r01, r02, r10, r11, r12, r20, r21, r22, out):
    """Rotation vector of the rotation matrix given by its 9 entries, into ``out`` (no alloc)."""
    c = 0.5 * (r00 + r11 + r22 - 1.0)
    if c > 1.0:
        c = 1.0
    elif c < -1.0:
        c = -1.0
    w0 = 0.5 * (r21 - r12)
    w1 = 0.5 * (r02 - r20)
    w2 = 0.5 * (r10 - r01)
    s2 = w0 * w0 + w1 * w1 + w2 * w2
    if c > 0.0 and s2 < ASIN_SERIES_MAX:
        # |w| = sin(theta): theta / sin(theta) by its series (a step's rotation, most bends)
        f = series(s2, ASIN)
        out[0] = w0 * f
        out[1] = w1 * f
        out[2] = w2 * f
        return
    s = np.sqrt(s2)
    th = np.arctan2(s, c)
    if th < 3.0:
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


@njit(**HOT)
def local_rot_into(R, Rn, out):
    """out = log(R Rn^T): world-frame rotation vector taking Rn to R."""
    log3s(
        R[0, 0] * Rn[0, 0] + R[0, 1] * Rn[0, 1] + R[0, 2] * Rn[0, 2],
        R[0, 0] * Rn[1, 0] + R[0, 1] * Rn[1, 1] + R[0, 2] * Rn[1, 2],
        R[0, 0] * Rn[2, 0] + R[0, 1] * Rn[2, 1] + R[0, 2] * Rn[2, 2],
        R[1, 0] * Rn[0, 0] + R[1, 1] * Rn[0, 1] + R[1, 2] * Rn[0, 2],
        R[1, 0] * Rn[1, 0] + R[1, 1] * Rn[1, 1] + R[1, 2] * Rn[1, 2],
        R[1, 0] * Rn[2, 0] + R[1, 1] * Rn[2, 1] + R[1, 2] * Rn[2, 2],
        R[2, 0] * Rn[0, 0] + R[2, 1] * Rn[0, 1] + R[2, 2] * Rn[0, 2],
        R[2, 0] * Rn[1, 0] + R[2, 1] * Rn[1, 1] + R[2, 2] * Rn[1, 2],
        R[2, 0] * Rn[2, 0] + R[2, 1] * Rn[2, 1] + R[2, 2] * Rn[2, 2],
        out,
    )


@njit(**HOT, inline="always")
def rodrigues(v0, v1, v2):
    """exp([v]) = I + a K + b K^2 (Rodrigues; K = [v]x, a = sin t / t, b = (1 - cos t) / t^2,
    t = |v|) by its nine entries, row by row.  Inlined by numba: as a call (LLVM does not inline
    it, its 9-tuple returns through memory) the step took 1.9 % more instructions."""
    th2 = v0 * v0 + v1 * v1 + v2 * v2
    if th2 < TRIG_SERIES_MAX:
        a = series(th2, SINC)
        b = series(th2, VERS)
    else:
        th = np.sqrt(th2)
        a = np.sin(th) / th
        b = (1.0 - np.cos(th)) / th2
    return (
        1.0 - b * (v1 * v1 + v2 * v2),
        -a * v2 + b * v0 * v1,
        a * v1 + b * v0 * v2,
        a * v2 + b * v0 * v1,
        1.0 - b * (v0 * v0 + v2 * v2),
        -a * v0 + b * v1 * v2,
        -a * v1 + b * v0 * v2,
        a * v0 + b * v1 * v2,
        1.0 - b * (v0 * v0 + v1 * v1),
    )


@njit(**HOT, inline="always")
def rotate_left(v0, v1, v2, R, out):
    """out = exp([v]) @ R (Rodrigues), no allocation."""
    E00, E01, E02, E10, E11, E12, E20, E21, E22 = rodrigues(v0, v1, v2)
    for j in range(3):
        r0 = R[0, j]
        r1 = R[1, j]
        r2 = R[2, j]
        out[0, j] = E00 * r0 + E01 * r1 + E02 * r2
        out[1, j] = E10 * r0 + E11 * r1 + E12 * r2
        out[2, j] = E20 * r0 + E21 * r1 + E22 * r2


@njit(**HOT)
def reorthonormalize(R):
    """R <- R (3 I - R^T R) / 2 in place: one step of the polar (Newton-Schulz) iteration.

    Products of many small rotations drift from orthonormality by ~1e-16 per product; after a few
    hundred steps ``R R^T - I`` reaches ~1e-12 and the chain update, which maps strains through
    ``R_A^T`` and back through ``R_A``, then shifts nodes by ~1e-12 mm on its own.  A sticking
    friction contact (tangent stiffness ~1e4 N/mm at small sub-steps) turns that shift into a
    residual floor Newton cannot pass.  The error is squared by each step, so one per accepted
    time step keeps R orthonormal to round-off.
    """
    m00 = 1.5 - 0.5 * (R[0, 0] * R[0, 0] + R[1, 0] * R[1, 0] + R[2, 0] * R[2, 0])
    m11 = 1.5 - 0.5 * (R[0, 1] * R[0, 1] + R[1, 1] * R[1, 1] + R[2, 1] * R[2, 1])
    m22 = 1.5 - 0.5 * (R[0, 2] * R[0, 2] + R[1, 2] * R[1, 2] + R[2, 2] * R[2, 2])
    m01 = -0.5 * (R[0, 0] * R[0, 1] + R[1, 0] * R[1, 1] + R[2, 0] * R[2, 1])
    m02 = -0.5 * (R[0, 0] * R[0, 2] + R[1, 0] * R[1, 2] + R[2, 0] * R[2, 2])
    m12 = -0.5 * (R[0, 1] * R[0, 2] + R[1, 1] * R[1, 2] + R[2, 1] * R[2, 2])
    for a in range(3):
        r0 = R[a, 0]
        r1 = R[a, 1]
        r2 = R[a, 2]
        R[a, 0] = r0 * m00 + r1 * m01 + r2 * m02
        R[a, 1] = r0 * m01 + r1 * m11 + r2 * m12
        R[a, 2] = r0 * m02 + r1 * m12 + r2 * m22


@njit(**HOT)
def lu6(A, piv):
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


@njit(**HOT)
def lus6(A, piv, b):
    """Solve in place with the factors of lu6 (b is a 6-vector)."""
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


@njit(**HOT)
def lu_dense(A, n, piv):
    """In-place LU with partial pivoting of A[:n, :n].  Returns False if singular."""
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
            f = A[i, k] * inv
            A[i, k] = f
            if f != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= f * A[k, j]
    return True


@njit(**HOT)
def lus_dense(A, n, piv, b):
    """Solve in place with the factors of ``lu_dense`` (b[:n])."""
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
@njit(**HOT)
def body_node(c, R, half, out):
    """Distal node of a body: p = c + half * R e_x."""
    out[0] = c[0] + half * R[0, 0]
    out[1] = c[1] + half * R[1, 0]
    out[2] = c[2] + half * R[2, 0]


@njit(**HOT, inline="always")
def _element_chord(aIsBase, A, pAbase, B):
    """Nodes of an element (p_A = c_A + half_A R_A e_x, or the base point; p_B likewise) as the
    scalars (p_A, r_B = p_B - c_B, d = p_B - p_A)."""
    cA = A.c
    RA = A.R
    if aIsBase:
        pA0 = pAbase[0]
        pA1 = pAbase[1]
        pA2 = pAbase[2]
    else:
        pA0 = cA[0] + A.half * RA[0, 0]
        pA1 = cA[1] + A.half * RA[1, 0]
        pA2 = cA[2] + A.half * RA[2, 0]
    RB = B.R
    rB0 = B.half * RB[0, 0]
    rB1 = B.half * RB[1, 0]
    rB2 = B.half * RB[2, 0]
    dx = B.c[0] + rB0 - pA0
    dy = B.c[1] + rB1 - pA1
    dz = B.c[2] + rB2 - pA2
    return rB0, rB1, rB2, dx, dy, dz


@njit(**HOT, inline="always")
def _relative_rotation(RA, RB, out):
    """out <- log(R_A^T R_B), the element's rotation strain."""
    log3s(
        RA[0, 0] * RB[0, 0] + RA[1, 0] * RB[1, 0] + RA[2, 0] * RB[2, 0],
        RA[0, 0] * RB[0, 1] + RA[1, 0] * RB[1, 1] + RA[2, 0] * RB[2, 1],
        RA[0, 0] * RB[0, 2] + RA[1, 0] * RB[1, 2] + RA[2, 0] * RB[2, 2],
        RA[0, 1] * RB[0, 0] + RA[1, 1] * RB[1, 0] + RA[2, 1] * RB[2, 0],
        RA[0, 1] * RB[0, 1] + RA[1, 1] * RB[1, 1] + RA[2, 1] * RB[2, 1],
        RA[0, 1] * RB[0, 2] + RA[1, 1] * RB[1, 2] + RA[2, 1] * RB[2, 2],
        RA[0, 2] * RB[0, 0] + RA[1, 2] * RB[1, 0] + RA[2, 2] * RB[2, 0],
        RA[0, 2] * RB[0, 1] + RA[1, 2] * RB[1, 1] + RA[2, 2] * RB[2, 1],
        RA[0, 2] * RB[0, 2] + RA[1, 2] * RB[1, 2] + RA[2, 2] * RB[2, 2],
        out,
    )


@njit(**HOT, inline="always")
def _element_stress(K, e, ehist, gs, hs):
    """Generalised element forces f = K (gs e + hs ehist) (eq 5 with C = beta K), as 6 scalars."""
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
    return f0, f1, f2, m0, m1, m2


#: element formulations (``records.ModelArrays.elem``, ``SimSettings.element``)
ELEM_PAPER = 0  # the paper's (Adams FIELD): strain in the proximal body's frame
ELEM_MID = 1  # co-rotational Timoshenko element in the mid-frame between its nodes (issue 11)
ELEMENTS = {"paper": ELEM_PAPER, "mid": ELEM_MID}


@njit(**HOT, inline="always")
def _mid_strain(aIsBase, A, pAbase, B, length, e):
    """The mid-frame element's strain (``_element_mid``) into ``e``; returns what its loads
    need of the way there: (r_B, theta^2, theta/2, sin and cos of theta/2, the arc's q,
    exp(psi/2) by rows (9), the chord in the A frame (3)).  Shared by the loads and
    ``element_strain``, so both give the strain to the same bits."""
    RA = A.R
    rB0, rB1, rB2, dx, dy, dz = _element_chord(aIsBase, A, pAbase, B)
    # relative rotation psi = log(R_A^T R_B) (the same components in the A, mid and B frames)
    _relative_rotation(RA, B.R, e[3:6])
    s0 = e[3]
    s1 = e[4]
    s2 = e[5]
    th2 = s0 * s0 + s1 * s1 + s2 * s2
    # E = exp(psi / 2) (Rodrigues), the mid-frame relative to A: R_m = R_A E
    h0 = 0.5 * s0
    h1 = 0.5 * s1
    h2 = 0.5 * s2
    E = rodrigues(h0, h1, h2)
    E00, E01, E02, E10, E11, E12, E20, E21, E22 = E
    # theta/2's sine and cosine for J_l^-T and T in the loads, which take series of their own
    # below 1 rad (hh2 < TRIG_SERIES_MAX): only above it are these needed
    hh2 = 0.25 * th2
    hn = 0.0
    sh = 0.0
    ch = 1.0
    if hh2 >= TRIG_SERIES_MAX:
        hn = np.sqrt(hh2)
        sh = np.sin(hn)
        ch = np.cos(hn)
    # chord in the A frame, then in the mid-frame
    a0 = RA[0, 0] * dx + RA[1, 0] * dy + RA[2, 0] * dz
    a1 = RA[0, 1] * dx + RA[1, 1] * dy + RA[2, 1] * dz
    a2 = RA[0, 2] * dx + RA[1, 2] * dy + RA[2, 2] * dz
    # the chord of a circular arc of length l bent by psi_b (the bending part of psi) is
    # l sinc(|psi_b| / 2), along the mid-frame's axis: measure the axial strain against it
    xb2 = 0.25 * (s1 * s1 + s2 * s2)
    if xb2 < TRIG_SERIES_MAX:
        sinc = series(xb2, SINC)
        qarc = series(xb2, QARC)
    else:
        xb = np.sqrt(xb2)
        sinc = np.sin(xb) / xb
        qarc = (np.sin(xb) - xb * np.cos(xb)) / (4.0 * xb2 * xb)
    e[0] = E00 * a0 + E10 * a1 + E20 * a2 - length * sinc
    e[1] = E01 * a0 + E11 * a1 + E21 * a2
    e[2] = E02 * a0 + E12 * a1 + E22 * a2
    return (rB0, rB1, rB2), th2, hn, sh, ch, qarc, E, (a0, a1, a2)


@njit(**HOT, inline="always")
def _paper_strain(aIsBase, A, pAbase, B, length, e):
    """The paper element's strain (``_element_paper``, eq 5) into ``e``: [R_A^T (p_B - p_A) -
    l e_x ; log(R_A^T R_B)]; returns (r_B, d) (``_element_chord``)."""
    RA = A.R
    rB0, rB1, rB2, dx, dy, dz = _element_chord(aIsBase, A, pAbase, B)
    e[0] = RA[0, 0] * dx + RA[1, 0] * dy + RA[2, 0] * dz - length
    e[1] = RA[0, 1] * dx + RA[1, 1] * dy + RA[2, 1] * dz
    e[2] = RA[0, 2] * dx + RA[1, 2] * dy + RA[2, 2] * dz
    _relative_rotation(RA, B.R, e[3:6])
    return rB0, rB1, rB2, dx, dy, dz


@njit(**HOT)
def element_strain(kind, aIsBase, A, pAbase, B, length, e):
    """The strain of one element (``element_gen``'s ``e`` without its loads) by formulation
    ``kind``: what the two-step formula's strain history needs (``predict._prepare``), at about
    half an element's cost."""
    if kind == ELEM_MID:
        _mid_strain(aIsBase, A, pAbase, B, length, e)
    else:
        _paper_strain(aIsBase, A, pAbase, B, length, e)


@njit(**HOT, inline="always")
def element_gen(kind, aIsBase, A, pAbase, B, K, length, damp, out12, e):
    """Generalised forces of one beam element on the centres of its bodies A and B, by
    formulation ``kind``: ``ELEM_PAPER`` (``_element_paper``, eq 5) or ``ELEM_MID``
    (``_element_mid``).  Arguments as ``_element_paper``."""
    if kind == ELEM_MID:
        _element_mid(aIsBase, A, pAbase, B, K, length, damp, out12, e)
    else:
        _element_paper(aIsBase, A, pAbase, B, K, length, damp, out12, e)


@njit(**HOT)
def _element_paper(aIsBase, A, pAbase, B, K, length, damp, out12, e):
    """Generalised forces of one Timoshenko element (eq 5) on the centres of its bodies A and B.

    Nodes: p_A = c_A + halfA R_A e_x (or ``pAbase`` for the root element, whose A is the head) and
    p_B = c_B + halfB R_B e_x.  Strain e = [R_A^T (p_B - p_A) - l e_x ; log(R_A^T R_B)]
    (co-rotational, proximal frame A).  Generalised force f = K (gs * e + hs * ehist): with damping
    C = beta K, gs = 1 + beta c0 / h and hs = beta / h, ehist = c1 e_n + c2 e_{n-1} (gs = 1,
    hs = 0 for statics).  The node moment on A balances the element exactly,
    M_A = -M_B - (p_B - p_A) x F_B, and each node load is carried to its body's centre,
    M_c = M_node + (p - c) x F.
    out12[0:6]: force [N] and moment [N mm] on A (at the root node when A is the head, else about
    c_A), out12[6:12]: on B about c_B (world).  ``e`` receives the strain.
    A, B: ``records.Node`` (centre, rotation, half length); damp: ``records.Damp``.

    Written out in scalars on purpose: array views and helper calls cost reference counting in
    numba, which made this (the innermost kernel) ~6x slower than its arithmetic.
    """
    RA = A.R
    halfA = A.half
    rB0, rB1, rB2, dx, dy, dz = _paper_strain(aIsBase, A, pAbase, B, length, e)
    f0, f1, f2, m0, m1, m2 = _element_stress(K, e, damp.ehist, damp.gs, damp.hs)
    FB0 = -(RA[0, 0] * f0 + RA[0, 1] * f1 + RA[0, 2] * f2)
    FB1 = -(RA[1, 0] * f0 + RA[1, 1] * f1 + RA[1, 2] * f2)
    FB2 = -(RA[2, 0] * f0 + RA[2, 1] * f1 + RA[2, 2] * f2)
    MB0 = -(RA[0, 0] * m0 + RA[0, 1] * m1 + RA[0, 2] * m2)
    MB1 = -(RA[1, 0] * m0 + RA[1, 1] * m1 + RA[1, 2] * m2)
    MB2 = -(RA[2, 0] * m0 + RA[2, 1] * m1 + RA[2, 2] * m2)
    # node A: F_A = -F_B, M_A = -M_B - d x F_B
    MA0 = -MB0 - (dy * FB2 - dz * FB1)
    MA1 = -MB1 - (dz * FB0 - dx * FB2)
    MA2 = -MB2 - (dx * FB1 - dy * FB0)
    out12[0] = -FB0
    out12[1] = -FB1
    out12[2] = -FB2
    if aIsBase:
        out12[3] = MA0
        out12[4] = MA1
        out12[5] = MA2
    else:  # + (p_A - c_A) x F_A with p_A - c_A = halfA R_A e_x
        rA0 = halfA * RA[0, 0]
        rA1 = halfA * RA[1, 0]
        rA2 = halfA * RA[2, 0]
        out12[3] = MA0 - (rA1 * FB2 - rA2 * FB1)
        out12[4] = MA1 - (rA2 * FB0 - rA0 * FB2)
        out12[5] = MA2 - (rA0 * FB1 - rA1 * FB0)
    out12[6] = FB0
    out12[7] = FB1
    out12[8] = FB2
    out12[9] = MB0 + rB1 * FB2 - rB2 * FB1
    out12[10] = MB1 + rB2 * FB0 - rB0 * FB2
    out12[11] = MB2 + rB0 * FB1 - rB1 * FB0


@njit(**HOT)
def _element_mid(aIsBase, A, pAbase, B, K, length, damp, out12, e):
    """Co-rotational Timoshenko element in the mid-frame between its two nodes (issue 11).

    Nodes as ``_element_paper``: p_A (distal node of A, or the base point) and p_B, with the
    nodes' rotations R_A and R_B.  Strain in the mid-frame R_m = R_A exp(psi / 2),
    psi = log(R_A^T R_B):  e = [R_m^T (p_B - p_A) - l c(psi_b) e_x ; psi], with psi_b the bending
    part (psi_y, psi_z) and c = sinc(|psi_b| / 2): the element is read as a circular arc of length
    l, whose chord is l c along the mid-frame's axis.  So the axial and shear forces act along and
    across the chord's mean direction, not the proximal axis, and an inextensible arc carries no
    axial strain: the chain of chords no longer stiffens bending by N l / 12 (the polygon's error,
    (k l)^2 / 12 on a buckling load); e is invariant under rigid motions of both nodes.  K is the
    paper's Timoshenko matrix carried to mid-frame strains (``beam.mid_frame_stiffness``): for a
    straight element it is diagonal, and one element reproduces the linear Timoshenko cantilever
    under end loads exactly.  f = K (gs e + hs ehist) as in eq 5 (damping C = beta K).

    Node loads are the exact gradient of the strain energy (so the element is conservative and
    balances force and moment to round-off): with F = R_m f_t (world), v = F x d, d = p_B - p_A,
    f_r' = f_r + f_x d e_x / d psi, w = J_l(psi)^-T f_r' and T = R_A (I + exp(psi/2))^-1 R_A^T
    (the mid-frame's share of each node's rotation, delta phi_m = (I - T) delta phi_A +
    T delta phi_B):
    F_A = F, F_B = -F;  M_A = -v + T^T v + R_A w,  M_B = -T^T v - R_A w;  then carried to the
    bodies' centres, M_c = M_node + (p - c) x F.
    """
    RA = A.R
    halfA = A.half
    rB, th2, hn, sh, ch, qarc, E, a = _mid_strain(aIsBase, A, pAbase, B, length, e)
    rB0, rB1, rB2 = rB
    E00, E01, E02, E10, E11, E12, E20, E21, E22 = E
    a0, a1, a2 = a
    s0 = e[3]
    s1 = e[4]
    s2 = e[5]
    f0, f1, f2, m0, m1, m2 = _element_stress(K, e, damp.ehist, damp.gs, damp.hs)
    # the arc's chord: the axial force is conjugate to psi_b through e_x = ... - l sinc(|psi_b|/2),
    # d e_x / d psi_b = l q psi_b (the element's own P-delta, see the docstring)
    m1 += f0 * length * qarc * s1
    m2 += f0 * length * qarc * s2
    # F = R_m f_t: g = E f_t in the A frame
    g0 = E00 * f0 + E01 * f1 + E02 * f2
    g1 = E10 * f0 + E11 * f1 + E12 * f2
    g2 = E20 * f0 + E21 * f1 + E22 * f2
    # w = J_l(psi)^-T m = m + psi x m / 2 + c psi x (psi x m)
    if th2 < JL_SERIES_MAX:  # = TRIG_SERIES_MAX for theta / 2: hn, sh, ch not computed
        c = series(th2, JL_C)
        t = series(th2, JL_T)
    else:  # c = (1 - (theta/2) cot(theta/2)) / theta^2, t = tan(theta/4) / theta
        c = (1.0 - hn * ch / sh) / th2
        t = sh / ((1.0 + ch) * 2.0 * hn)
    x0 = s1 * m2 - s2 * m1
    x1 = s2 * m0 - s0 * m2
    x2 = s0 * m1 - s1 * m0
    w0 = m0 + 0.5 * x0 + c * (s1 * x2 - s2 * x1)
    w1 = m1 + 0.5 * x1 + c * (s2 * x0 - s0 * x2)
    w2 = m2 + 0.5 * x2 + c * (s0 * x1 - s1 * x0)
    # u = R_A^T (F x d) = g x a; T^T v in the A frame: (u + t psi x u) / 2
    u0 = g1 * a2 - g2 * a1
    u1 = g2 * a0 - g0 * a2
    u2 = g0 * a1 - g1 * a0
    y0 = 0.5 * (u0 + t * (s1 * u2 - s2 * u1))
    y1 = 0.5 * (u1 + t * (s2 * u0 - s0 * u2))
    y2 = 0.5 * (u2 + t * (s0 * u1 - s1 * u0))
    # node moments in the A frame: M_A = -u + y + w, M_B = -y - w
    ma0 = -u0 + y0 + w0
    ma1 = -u1 + y1 + w1
    ma2 = -u2 + y2 + w2
    mb0 = -y0 - w0
    mb1 = -y1 - w1
    mb2 = -y2 - w2
    F0 = RA[0, 0] * g0 + RA[0, 1] * g1 + RA[0, 2] * g2
    F1 = RA[1, 0] * g0 + RA[1, 1] * g1 + RA[1, 2] * g2
    F2 = RA[2, 0] * g0 + RA[2, 1] * g1 + RA[2, 2] * g2
    MA0 = RA[0, 0] * ma0 + RA[0, 1] * ma1 + RA[0, 2] * ma2
    MA1 = RA[1, 0] * ma0 + RA[1, 1] * ma1 + RA[1, 2] * ma2
    MA2 = RA[2, 0] * ma0 + RA[2, 1] * ma1 + RA[2, 2] * ma2
    MB0 = RA[0, 0] * mb0 + RA[0, 1] * mb1 + RA[0, 2] * mb2
    MB1 = RA[1, 0] * mb0 + RA[1, 1] * mb1 + RA[1, 2] * mb2
    MB2 = RA[2, 0] * mb0 + RA[2, 1] * mb1 + RA[2, 2] * mb2
    out12[0] = F0
    out12[1] = F1
    out12[2] = F2
    if aIsBase:
        out12[3] = MA0
        out12[4] = MA1
        out12[5] = MA2
    else:  # + (p_A - c_A) x F_A with p_A - c_A = halfA R_A e_x
        rA0 = halfA * RA[0, 0]
        rA1 = halfA * RA[1, 0]
        rA2 = halfA * RA[2, 0]
        out12[3] = MA0 + rA1 * F2 - rA2 * F1
        out12[4] = MA1 + rA2 * F0 - rA0 * F2
        out12[5] = MA2 + rA0 * F1 - rA1 * F0
    out12[6] = -F0
    out12[7] = -F1
    out12[8] = -F2
    out12[9] = MB0 - (rB1 * F2 - rB2 * F1)
    out12[10] = MB1 - (rB2 * F0 - rB0 * F2)
    out12[11] = MB2 - (rB0 * F1 - rB1 * F0)


@njit(**HOT)
def block_factor(n, D, U, L, G, piv):
    """Factor the block-tridiagonal matrix (L_i, D_i, U_i) in place (block Thomas, O(n)).

    D becomes the LU factors of the Schur complements, G_i = D_i^-1 U_i.  Returns False if a pivot
    block is singular.  Solve with ``block_solve``; the factors can be reused for many solves.
    """
    if not block_factor_head(n, D, U, L, G, piv):
        return False
    return lu6(D[n - 1], piv[n - 1])


@njit(**HOT)
def block_factor_head(n, D, U, L, G, piv):
    """``block_factor`` of blocks 0..n-2; D[n-1] is left as its Schur complement
    D_{n-1} - L_{n-1} G_{n-2}, not yet factored.  Blocks 0..n-2 do not depend on D_{n-1}, so a
    change of the last diagonal block only needs ``lu6`` of (Schur complement + change)."""
    for i in range(n):
        if i > 0:
            for a in range(6):
                for b in range(6):
                    s = 0.0
                    for k in range(6):
                        s += L[i, a, k] * G[i - 1, k, b]
                    D[i, a, b] -= s
        if i == n - 1:
            return True
        if not lu6(D[i], piv[i]):
            return False
        for b in range(6):
            for a in range(6):
                G[i, a, b] = U[i, a, b]
            lus6(D[i], piv[i], G[i, :, b])
    return True


@njit(**HOT)
def block_solve(n, D, L, G, piv, r, x):
    """Solve with the factors of ``block_factor``: x = A^-1 r (r is left unchanged)."""
    for i in range(n):
        for a in range(6):
            s = r[i, a]
            if i > 0:
                for k in range(6):
                    s -= L[i, a, k] * x[i - 1, k]
            x[i, a] = s
        lus6(D[i], piv[i], x[i])
    for i in range(n - 2, -1, -1):
        for a in range(6):
            s = 0.0
            for k in range(6):
                s += G[i, a, k] * x[i + 1, k]
            x[i, a] -= s
