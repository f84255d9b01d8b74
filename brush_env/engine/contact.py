"""Tip loads: dead external forces (and, with the contact model, eq 6-10 penalty contact).

``tip_args`` row layout per bristle (float64): [0:3] external dead force on the tip [N, world].
"""

from __future__ import annotations

from numba import njit

A_FEXT = 0  # 0:3 external force [N]
N_TIP_ARGS = 3
N_TIP_STATE = 1


@njit(cache=True)
def tip_load(pt, c0, inv_h, static, args, state, F, Kt):
    """Total load on the tip node at position ``pt`` [mm]: force F [N] and dF/dpt [N/mm]."""
    for a in range(3):
        F[a] = args[A_FEXT + a]
        for b in range(3):
            Kt[a, b] = 0.0
