"""Coupled tip-tip contact: where to hold each bristle's partners so that both sides of every
tip-tip contact (Table 3) see the end-of-step tips (numba kernels).

``step.step_bristles`` solves each bristle with its partners' tips held.  A partner solved
later in the sweep is held where it was, not where it ends: the tip-tip force lags.  The Table 3
law is ~10^3-10^4 times stiffer than a bristle's bending, so repeating the sweeps (block
Gauss-Seidel) converges at a rate close to 1: 50 sweeps do not settle two facing bristles under a
10 Hz load (tests/engine/test_coupling.py).  Instead, after a sweep, one Newton step of the
coupled problem condensed onto the tip nodes (the Schur complement of every chain on its tip)
tells where every touching tip will be:

    H_b dx_b - sum_j C_bj dx_j = dF_b                                         (3 rows per tip)

linearised at the consistent point x* (every tip where its own solve left it): dF_b is the
change of bristle b's tip-tip force between the partners it was solved against (u_bj) and x*,
exact, so the right-hand side is the residual every bristle has at x*; C_bj = dF_b/dp_j [N/mm]
at x* (``contact.pair_law``); H_b [N/mm] the tip node's stiffness, the inverse of
T A_b^-1 T^T with A_b the tip body's Schur complement of the chain (the Newton factors' jc.S,
T = [I, -[r]x]) plus the tip's own load block at x* (surface, friction and tip-tip, from the
load of b's last evaluation corrected to x*).  Everything is taken at one point, so the common
motion of touching tips, which only the soft bending resists, is not lost in the difference of
two stiff contact terms.  One dense LU per connected group of touching tips; the partners
are placed at x* + alpha dx (alpha halved until no pair passes through each other or
overlaps much deeper than now, ``_safe_fraction``) and the group is solved again,
warm-started.  At the fixed
point every bristle was solved against its partners' own solutions (within
``SimSettings.tip_tip_tol``).  A step whose partners still move by more than
``sweeps.FALLBACK_MOVE`` when the sweeps run out is solved again as one plain sweep.  H and C
only steer: the solution is set by the bristles' residuals alone.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from ._kernels import HOT, lu6, lu_dense, lus6, lus_dense
from .contact import pair_law
from .near import entry, moved, span
from .records import MAX_GROUP  # a larger group keeps plain Gauss-Seidel
from .tipblock import add_tip_block

#: [mm] a placement may always create tip-tip overlaps up to this (Table 3: ~0.03 N at 3 um)
PLACE_OVERLAP = 3e-3
#: the tip load of one bristle in the form ``add_tip_block`` reads (force [N], dF/dp [N/mm])
TipLoad = namedtuple("TipLoad", ["tipF", "tipK"])


@njit(**HOT)
def store_tip_load(b, it, sw):
    """sw.tipF[b], sw.tipK[b] <- the tip load and its tangent of bristle b's last evaluation
    (its solution)."""
    for a in range(3):
        sw.tipF[b, a] = it.tipF[a]
        for c in range(3):
            sw.tipK[b, a, c] = it.tipK[a, c]


@njit(**HOT, inline="always")
def _root(parent, b):
    while parent[b] != b:
        parent[b] = parent[parent[b]]
        b = parent[b]
    return b


@njit(**HOT)
def place_partners(model, chain, con, jc, ws, c0_inv_h):
    """Solve the condensed coupled equations (module docstring) for every group of touching
    tips and move their entries in con.tips there (position; velocity by the same change times
    c0/h).  Marks sw.grouped[b] = 1 for every bristle placed, 0 otherwise; returns how many were
    placed."""
    sw = ws.sw
    tips = con.tips
    nb = tips.shape[0]
    parent = sw.parent
    for b in range(nb):
        parent[b] = b
        sw.grouped[b] = 0
    # over the near lists while no held tip moved by half their margin (``near.py``)
    need = 2.0 * sw.near.d[0]
    for b in range(nb):  # groups: connected components of the pairs touching at x* or u
        k0, k1, on = span(con, sw.near, b, need)
        for k in range(k0, k1):
            q, j = entry(con, sw.near, k, on)
            if pair_law(b, j, tips[j], con, c0_inv_h, sw.f, sw.C) or pair_law(
                b, j, sw.used[q], con, c0_inv_h, sw.f, sw.C
            ):
                rb = _root(parent, b)
                rj = _root(parent, j)
                if rb != rj:
                    parent[max(rb, rj)] = min(rb, rj)
    placed = 0
    for g in range(nb):
        if _root(parent, g) != g:
            continue
        m = 0
        for b in range(g, nb):  # members in bristle order
            if _root(parent, b) == g:
                sw.slot[b] = m
                sw.members[m] = b
                m += 1
        if m < 2 or m > MAX_GROUP:
            continue
        placed += _solve_group(model, chain, con, jc, ws, m, c0_inv_h)
    return placed


@njit(**HOT)
def _tip_stiffness(b, model, chain, jc, ws, load):
    """sw.H <- the tip node's stiffness [N/mm] of bristle b: (T A^-1 T^T)^-1 with A = jc.S[b]
    + the tip load block of ``load``.  Returns False if the bristle has no valid factors or A
    is singular."""
    sw = ws.sw
    if jc.key[b] == 0.0:
        return False
    il = model.bstart[b + 1] - 1
    A6 = sw.A6
    for a in range(6):
        for c in range(6):
            A6[a, c] = jc.S[b, a, c]
    add_tip_block(A6, model.bp, chain.rot, il, load, ws.blk)
    if not lu6(A6, sw.piv6):
        return False
    hl = model.bp[il].half
    r0 = hl * chain.rot[il, 0, 0]
    r1 = hl * chain.rot[il, 1, 0]
    r2 = hl * chain.rot[il, 2, 0]
    W = sw.W3
    e6 = sw.e6
    for c in range(3):
        for a in range(6):
            e6[a] = 0.0
        e6[c] = 1.0  # a unit force along c at the tip node: generalised load (f, r x f)
        e6[3] = r1 * e6[2] - r2 * e6[1]
        e6[4] = r2 * e6[0] - r0 * e6[2]
        e6[5] = r0 * e6[1] - r1 * e6[0]
        lus6(A6, sw.piv6, e6)
        W[0, c] = e6[0] + e6[4] * r2 - e6[5] * r1  # tip node displacement dc + dtheta x r
        W[1, c] = e6[1] + e6[5] * r0 - e6[3] * r2
        W[2, c] = e6[2] + e6[3] * r1 - e6[4] * r0
    return _inv3(W, sw.H)


@njit(**HOT, inline="always")
def _inv3(M, out):
    """out <- M^-1 (3x3); False if singular."""
    c00 = M[1, 1] * M[2, 2] - M[1, 2] * M[2, 1]
    c01 = M[1, 2] * M[2, 0] - M[1, 0] * M[2, 2]
    c02 = M[1, 0] * M[2, 1] - M[1, 1] * M[2, 0]
    det = M[0, 0] * c00 + M[0, 1] * c01 + M[0, 2] * c02
    if det == 0.0 or not np.isfinite(det):
        return False
    inv = 1.0 / det
    out[0, 0] = c00 * inv
    out[1, 0] = c01 * inv
    out[2, 0] = c02 * inv
    out[0, 1] = (M[0, 2] * M[2, 1] - M[0, 1] * M[2, 2]) * inv
    out[1, 1] = (M[0, 0] * M[2, 2] - M[0, 2] * M[2, 0]) * inv
    out[2, 1] = (M[0, 1] * M[2, 0] - M[0, 0] * M[2, 1]) * inv
    out[0, 2] = (M[0, 1] * M[1, 2] - M[0, 2] * M[1, 1]) * inv
    out[1, 2] = (M[0, 2] * M[1, 0] - M[0, 0] * M[1, 2]) * inv
    out[2, 2] = (M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]) * inv
    return True


@njit(**HOT)
def _solve_group(model, chain, con, jc, ws, m, c0_inv_h):
    """The condensed equations of one group (members sw.members[:m]): dense LU, tips placed.
    Returns m, or 0 if a stiffness or the system is singular (the tips stay where they are)."""
    sw = ws.sw
    tips = con.tips
    A = sw.A
    x = sw.x
    C = sw.C
    f = sw.f
    load = TipLoad(sw.Fc, sw.Kc)
    n = 3 * m
    for r in range(n):
        x[r] = 0.0
        for c in range(n):
            A[r, c] = 0.0
    need = 2.0 * sw.near.d[0]  # pairs off the near lists do not touch (``near.py``)
    for s in range(m):
        b = sw.members[s]
        for a in range(3):
            sw.Fc[a] = sw.tipF[b, a]
            for c in range(3):
                sw.Kc[a, c] = sw.tipK[b, a, c]
        k0, k1, on = span(con, sw.near, b, need)
        for k in range(k0, k1):
            q, j = entry(con, sw.near, k, on)
            t = sw.slot[j]
            if t >= m or sw.members[t] != j:
                continue  # not in this group (touches b only since another group was placed)
            # the pair at the partner b was solved against (u): out of b's load and tangent
            if pair_law(b, j, sw.used[q], con, c0_inv_h, f, C):
                for a in range(3):
                    sw.Fc[a] -= f[a]
                    x[3 * s + a] -= f[a]
                    for c in range(3):
                        sw.Kc[a, c] += C[a, c]  # own tangent of the pair is -C
            # ... and at x*: into the load, the tangent and the coupling blocks
            if pair_law(b, j, tips[j], con, c0_inv_h, f, C):
                for a in range(3):
                    sw.Fc[a] += f[a]
                    x[3 * s + a] += f[a]
                    for c in range(3):
                        sw.Kc[a, c] -= C[a, c]
                        A[3 * s + a, 3 * t + c] -= C[a, c]
        if not _tip_stiffness(b, model, chain, jc, ws, load):
            return 0
        for a in range(3):
            for c in range(3):
                A[3 * s + a, 3 * s + c] += sw.H[a, c]
    if not lu_dense(A, n, sw.piv):
        return 0
    lus_dense(A, n, sw.piv, x)
    alpha = _safe_fraction(con, sw, m)
    for s in range(m):
        b = sw.members[s]
        for a in range(6):
            sw.xs[b, a] = tips[b, a]  # its solution, restored if it is not solved again
        for a in range(3):
            tips[b, a] += alpha * x[3 * s + a]
            tips[b, 3 + a] += alpha * c0_inv_h * x[3 * s + a]
        moved(con, sw.near, b)
        sw.grouped[b] = 1
    return m


@njit(**HOT)
def _safe_fraction(con, sw, m):
    """The largest fraction alpha (1, 1/2, 1/4, ...) of the group's placement dx such that no
    touching or nearby pair of the group passes through each other (the line of centres keeps
    its sense) or overlaps by more than max(2 x its deepest overlap now, PLACE_OVERLAP): the
    linear model knows no non-penetration, and a full step at contact onset can tunnel."""
    tips = con.tips
    x = sw.x
    near = sw.near
    # a pair off the near lists stays out of reach while 2 |x| + 2 D fits their margin
    # (``near.py``): it adds nothing to the deepest overlap and never limits alpha
    xmax = 0.0
    for r in range(3 * m):
        xmax = max(xmax, abs(x[r]))
    need = 2.0 * np.sqrt(3.0) * xmax + 2.0 * near.d[0]
    deepest = 0.0
    for s in range(m):
        b = sw.members[s]
        k0, k1, on = span(con, near, b, need)
        for k in range(k0, k1):
            _q, j = entry(con, near, k, on)
            d = 0.0
            for a in range(3):
                d += (tips[b, a] - tips[j, a]) ** 2
            deepest = max(deepest, tips[b, 6] + tips[j, 6] - np.sqrt(d))
    cap = max(2.0 * deepest, PLACE_OVERLAP)
    alpha = 1.0
    for _halving in range(12):
        ok = True
        for s in range(m):
            b = sw.members[s]
            k0, k1, on = span(con, near, b, need)
            for k in range(k0, k1):
                _q, j = entry(con, near, k, on)
                t = sw.slot[j]
                inside = t < m and sw.members[t] == j
                dot = 0.0
                d2 = 0.0
                for a in range(3):
                    d0 = tips[b, a] - tips[j, a]
                    d1 = d0 + alpha * (x[3 * s + a] - (x[3 * t + a] if inside else 0.0))
                    dot += d0 * d1
                    d2 += d1 * d1
                if dot <= 0.0 or tips[b, 6] + tips[j, 6] - np.sqrt(d2) > cap:
                    ok = False
                    break
            if not ok:
                break
        if ok:
            return alpha
        alpha *= 0.5
    return 0.0
