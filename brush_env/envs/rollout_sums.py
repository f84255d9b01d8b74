"""What an env step's reward and info need from a rollout's per-engine-step record
(``engine.prb_rollout.Record``), in one compiled pass: the total normal force's time above its
limit and the integrals of the force excesses (the reward's penalty terms, env docstrings), the
peaks, and the in-step penetration and head-clearance extremes.  Units: N, s, mm.

One pass over the (n, nb) record instead of ~15 numpy reductions (~30 us an env step at the level
``table``, more than its compiled rollout when the brush hovers).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

__all__ = ["Limits", "Sums", "rollout_sums"]

#: the force limits [N] the integrals count the excess over, and the engine step dt [s]
Limits = namedtuple("Limits", ["total", "tip", "gum", "dt"])
#: total_int, tip_int, gum_int [N s] the integrals of max(0, F - limit) over the steps (total:
#: the tips' and shafts' normal force; tip: summed over the tips; gum: the tips on a gum
#: surface); time_above [s] the time the total is above its limit; peak_total, peak_tip,
#: peak_gum [N]; pen_tip, pen_shaft [mm] the deepest in-step penetrations; beyond the solver
#: steps with a tip beyond the penalty range; head [mm] the head's smallest clearance (inf: none)
Sums = namedtuple(
    "Sums",
    [
        "total_int",
        "tip_int",
        "gum_int",
        "time_above",
        "peak_total",
        "peak_tip",
        "peak_gum",
        "pen_tip",
        "pen_shaft",
        "beyond",
        "head",
    ],
)


def rollout_sums(rec, n: int, gum: np.ndarray, lim: Limits) -> Sums:
    """The sums of the first ``n`` rows of the record ``rec``; ``gum`` (surfaces,) bool: which
    surfaces are gum (their tip forces count in the gum terms)."""
    return Sums(*_sums(rec, n, gum, lim))


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def _sums(rec, n, gum, lim):
    f, surf = rec.fn, rec.surf
    nb = f.shape[1]
    any_gum = False
    for s in range(gum.shape[0]):
        any_gum = any_gum or gum[s]
    total_int = tip_int = gum_int = 0.0
    above = 0
    peak_total = peak_tip = peak_gum = 0.0
    pen_tip = pen_shaft = 0.0
    beyond = 0
    head = math.inf
    for k in range(n):
        fn = 0.0
        fg = 0.0
        for b in range(nb):
            x = f[k, b]
            fn += x
            tip_int += max(x - lim.tip, 0.0)
            peak_tip = max(peak_tip, x)
            if any_gum and surf[k, b] >= 0 and gum[surf[k, b]]:
                fg += x
        fn += rec.shaft_fn[k]  # every eq 6 contact: the tips' and the shafts'
        total_int += max(fn - lim.total, 0.0)
        above += int(fn > lim.total)
        gum_int += max(fg - lim.gum, 0.0)
        peak_total = max(peak_total, fn)
        peak_gum = max(peak_gum, fg)
        pen_tip = max(pen_tip, rec.pen_max[k])
        pen_shaft = max(pen_shaft, rec.shaft_pen[k])
        beyond += rec.beyond[k]
        head = min(head, rec.head[k])
    dt = lim.dt
    return (
        dt * total_int,
        dt * tip_int,
        dt * gum_int,
        dt * above,
        peak_total,
        peak_tip,
        peak_gum,
        pen_tip,
        pen_shaft,
        beyond,
        head,
    )
