"""SO(3) helpers for code outside the hot kernels.

Rotation matrices map body (local) coordinates to world coordinates; rotation vectors are
axis * angle [rad].  The kernels' own allocation-free versions live in ``_kernels`` (``_log3s``,
``_rotate_left``); these wrappers reuse them rather than repeat the formulas.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import _log3s


@njit(cache=True)
def skew(a):
    """3x3 cross-product matrix [a]x, so that skew(a) @ b == cross(a, b)."""
    out = np.zeros((3, 3))
    out[0, 1] = -a[2]
    out[0, 2] = a[1]
    out[1, 0] = a[2]
    out[1, 2] = -a[0]
    out[2, 0] = -a[1]
    out[2, 1] = a[0]
    return out


def logmap(R) -> np.ndarray:
    """Rotation vector [rad] of the rotation matrix ``R`` (angle in [0, pi])."""
    out = np.empty(3)
    _log3s(*np.asarray(R, float).ravel(), out)
    return out
