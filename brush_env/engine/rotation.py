"""SO(3) helpers for code outside the hot kernels.

Rotation matrices map body (local) coordinates to world coordinates; rotation vectors are
axis * angle [rad].  The kernels' own allocation-free versions live in ``_kernels`` (``_log3s``,
``_rotate_left``); these wrappers reuse them rather than repeat the formulas.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT, _log3s


def logmap(R) -> np.ndarray:
    """Rotation vector [rad] of the rotation matrix ``R`` (angle in [0, pi])."""
    out = np.empty(3)
    _log3s(*np.asarray(R, float).ravel(), out)
    return out


@njit(**HOT)
def pose_ok(p, R, tol):
    """True if p (3,) is finite and R (3, 3) is a finite rotation matrix: max |R R^T - I| <= tol
    and det R >= 0 (the checks of a TCP pose, ~1 us instead of ~15 us with numpy calls)."""
    for a in range(3):
        if not np.isfinite(p[a]):
            return False
        for b in range(3):
            if not np.isfinite(R[a, b]):
                return False
    for a in range(3):
        for b in range(3):
            d = R[a, 0] * R[b, 0] + R[a, 1] * R[b, 1] + R[a, 2] * R[b, 2]
            if a == b:
                d -= 1.0
            if abs(d) > tol:
                return False
    det = (R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1])
           - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
           + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0]))
    return det >= 0.0
