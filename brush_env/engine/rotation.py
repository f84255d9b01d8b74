"""SO(3) helpers used by the kernels and by Python code.

Rotation matrices map body (local) coordinates to world coordinates.  Rotation vectors are
axis * angle [rad].  Every function is a numba kernel (``cache=True``) that also runs from Python.
"""

from __future__ import annotations

import numpy as np
from numba import njit

_SMALL = 1e-6  # [rad] below this angle the series expansions are exact to double precision


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


@njit(cache=True)
def cross(a, b):
    out = np.empty(3)
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]
    return out


@njit(cache=True)
def expmap(v):
    """Rodrigues' formula: rotation matrix of the rotation vector ``v`` [rad]."""
    th2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2]
    th = np.sqrt(th2)
    if th < _SMALL:
        a = 1.0 - th2 / 6.0
        b = 0.5 - th2 / 24.0
    else:
        a = np.sin(th) / th
        b = (1.0 - np.cos(th)) / th2
    K = skew(v)
    R = np.eye(3) + a * K + b * (K @ K)
    return R


@njit(cache=True)
def logmap(R):
    """Rotation vector [rad] of the rotation matrix ``R`` (angle in [0, pi])."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    c = 0.5 * (tr - 1.0)
    if c > 1.0:
        c = 1.0
    elif c < -1.0:
        c = -1.0
    w = np.empty(3)
    w[0] = 0.5 * (R[2, 1] - R[1, 2])
    w[1] = 0.5 * (R[0, 2] - R[2, 0])
    w[2] = 0.5 * (R[1, 0] - R[0, 1])
    s = np.sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2])  # = sin(theta)
    th = np.arctan2(s, c)
    if th < _SMALL:
        return w * (1.0 + th * th / 6.0)
    if th < 3.0:
        return w * (th / s)
    # near pi: axis from the symmetric part (w is ill-conditioned there)
    B = 0.5 * (R + R.T) - c * np.eye(3)
    k = 0
    if B[1, 1] > B[k, k]:
        k = 1
    if B[2, 2] > B[k, k]:
        k = 2
    axis = B[:, k] / np.sqrt(max(B[k, k], 1e-300))
    if axis[0] * w[0] + axis[1] * w[1] + axis[2] * w[2] < 0.0:
        axis = -axis
    return axis * th


@njit(cache=True)
def orthonormalize(R):
    """Project a nearly orthogonal matrix back onto SO(3) (Gram-Schmidt on columns)."""
    x = R[:, 0] / np.sqrt(R[0, 0] ** 2 + R[1, 0] ** 2 + R[2, 0] ** 2)
    y = R[:, 1] - (x[0] * R[0, 1] + x[1] * R[1, 1] + x[2] * R[2, 1]) * x
    y = y / np.sqrt(y[0] ** 2 + y[1] ** 2 + y[2] ** 2)
    z = cross(x, y)
    out = np.empty((3, 3))
    out[:, 0] = x
    out[:, 1] = y
    out[:, 2] = z
    return out


def rpy_matrix(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll) for fixed-axis roll/pitch/yaw angles [rad]."""
    r, p, y = (float(a) for a in rpy)
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def slerp(R0: np.ndarray, R1: np.ndarray, s: float) -> np.ndarray:
    """Geodesic interpolation between two rotations, s in [0, 1]."""
    return expmap(s * logmap(R1 @ R0.T)) @ R0
