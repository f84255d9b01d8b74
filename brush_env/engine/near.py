"""The step's near lists of tip-tip partners: the partner loops of Table 3 over the partners that
can touch within the step, with the same results as over every listed partner.

A brush's pair list (``chain.scene_tip_pairs``) names every partner a tip could ever touch: ~31
per tip on the default brush, of which a few are within reach at any moment.  The contact load,
the penetration limit, the sweeps' test of moved partners, the coupling's groups and the first
guess's lead looped over all of them, every residual and every sweep (~17 % of a coupled
bristle-step, docs/benchmarks.md, session 38).

When the lists are built (``build``) every tip b keeps, in its pair list's order, the partners j
with |a_b - a_j| < r_b + r_j + M at the tips' positions a then, their anchors (``NearPairs.anc``;
M = ``NEAR_MARGIN`` [mm]).  They are built at a step's start, and kept for the next step while
no tip has moved more than ``ANCHOR_MOVE`` M from its anchor.  D is the largest distance of any
held tip (``con.tips``) from its anchor: at a step's start, and after every write of a held tip
(``moved``).  A partner off the near list is then at least r_b + r_j + M - D - s from a tip s
from its anchor, so a loop may use the near list
whenever what it tests stays below that distance (``fits``): the contact load at a tip moved s
(s + D <= M: no partner off the list is within reach), the penetration limit of a step dp
(s + |dp| + D <= M), the moved-partner test (4 D <= M: a partner's move and its distance are both
within 2 D of their anchors), the coupling's groups (2 D <= M), a placement x
(2 sqrt(3) max_r |x_r| + 2 D <= M: |x_b| + |x_j| bounded by its components) and the lead of the
first guess (2 D + 2 LEAD_MAX r_max <= M).  Otherwise the loop takes the whole list, as it does
outside a step (D = inf) and for the reduced model, which never builds one.
Skipped partners are those that contribute nothing, in the same order, so every sum is the same
to the bit (``tests/engine/test_near.py``: the paper turn's forces equal with the lists on and off).
Units: mm.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT
from .records import ContactScene

#: [mm] partners within r_b + r_j + NEAR_MARGIN of each other at their anchors are near.  A
#: 1 ms step of the paper turn moves a tip ~0.02 mm; the moved-partner test keeps the near list
#: while no held tip is more than NEAR_MARGIN / 4 from its anchor
NEAR_MARGIN = 1.0
#: [-] the near lists are kept from one step to the next while no tip is more than this fraction
#: of NEAR_MARGIN from where they were built (its anchor): D starts a kept step at that distance,
#: well inside what the loops allow (the tightest, the moved-partner test, 4 D <= M).  A 1 ms step
#: of the paper turn moves a tip ~0.02 mm: the lists are rebuilt every few steps instead of every
#: step (~2 % of a one-sweep bristle-step, docs/benchmarks.md, session 39)
ANCHOR_MOVE = 0.125
#: [mm] the round-off allowance of the distance tests (positions are < 1e3 mm: ~1e-13 mm)
NEAR_ROUND = 1e-9


@njit(**HOT, inline="always")
def from_anchor(near, b, x):
    """|x[0:3] - anchor of tip b| [mm]: how far the point x is from where b's list was built."""
    d0 = x[0] - near.anc[b, 0]
    d1 = x[1] - near.anc[b, 1]
    d2 = x[2] - near.anc[b, 2]
    return np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(**HOT)
def build(con, near, tips0):
    """At a step's start (held tips at ``tips0`` (nb, >= 3)): keep the near lists if no tip is
    more than ``ANCHOR_MOVE`` x M from its anchor (D <- the largest such distance), else rebuild
    them: every tip's partners within r_b + r_j + M of it at ``tips0`` (CSR over the pair list:
    near.ptr (nb + 1), near.q the pair entries, near.idx the partners), the anchors
    ``near.anc`` <- tips0, D = 0.  With M < 0 (``NearPairs.d[1]``: the lists off) every list is
    empty and D = inf."""
    ptr = con.pair_ptr
    nb = tips0.shape[0]
    M = near.d[1]
    if M >= 0.0:
        keep = True
        far = 0.0
        for b in range(nb):
            d = from_anchor(near, b, tips0[b])
            if not d <= ANCHOR_MOVE * M:  # moved too far, or NaN: never built
                keep = False
                break
            far = max(far, d)
        if keep:
            near.d[0] = far
            return
    n = 0
    near.ptr[0] = 0
    for b in range(nb):
        if M >= 0.0:
            for a in range(3):
                near.anc[b, a] = tips0[b, a]
        if M >= 0.0 and ptr.shape[0] > b + 1:
            rb = con.tips[b, 6]
            for q in range(ptr[b], ptr[b + 1]):
                j = con.pair_idx[q]
                d0 = tips0[b, 0] - tips0[j, 0]
                d1 = tips0[b, 1] - tips0[j, 1]
                d2 = tips0[b, 2] - tips0[j, 2]
                reach = rb + con.tips[j, 6] + M
                if d0 * d0 + d1 * d1 + d2 * d2 < reach * reach:
                    near.q[n] = q
                    near.idx[n] = j
                    n += 1
        near.ptr[b + 1] = n
    near.d[0] = 0.0 if M >= 0.0 else np.inf


@njit(**HOT, inline="always")
def close(near):
    """After the step: no near list (every loop takes the whole list until the next ``build``)."""
    near.d[0] = np.inf


@njit(**HOT, inline="always")
def moved(con, near, b):
    """D <- max(D, |con.tips[b] - anchor of b|) after held tip b was written."""
    d = from_anchor(near, b, con.tips[b])
    if d > near.d[0]:
        near.d[0] = d


@njit(**HOT, inline="always")
def fits(near, need):
    """True if a loop whose test reaches ``need`` [mm] beyond contact reach may take the near
    lists (``need`` <= M, less the round-off allowance; D = inf never fits)."""
    return need <= near.d[1] - NEAR_ROUND


@njit(**HOT, inline="always")
def span(con, near, b, need):
    """(first, end, near?) of bristle b's partner loop: entries k of near.q / near.idx if
    ``fits(near, need)``, else of the whole list (pair entry q = k, partner con.pair_idx[k]).
    ``need`` includes the D term of the loop's test (a multiple of near.d[0]), so that after
    ``close`` (D = inf) nothing fits."""
    if fits(near, need):
        return near.ptr[b], near.ptr[b + 1], True
    return con.pair_ptr[b], con.pair_ptr[b + 1], False


@njit(**HOT, inline="always")
def entry(con, near, k, on):
    """(q, j): the pair entry and the partner at loop index k of ``span``."""
    if on:
        return near.q[k], near.idx[k]
    return k, con.pair_idx[k]


@njit(**HOT, inline="always")
def tip_scene(con, near, b, pt, reach):
    """The contact scene for tip b evaluated at ``pt`` (3,) [mm] with tests reaching ``reach``
    [mm] beyond contact: ``con`` with b's near list as its pair list (``contact.tip_load``, the
    penetration limit) where it fits, else ``con``."""
    s = from_anchor(near, b, pt)
    if fits(near, s + reach + near.d[0]):
        return ContactScene(
            con.surf,
            con.cp,
            con.tips,
            near.ptr,
            near.idx,
            con.mesh,
            con.tip_args,
            con.tip_state,
            con.sdf,
            con.shaft,
        )
    return con
