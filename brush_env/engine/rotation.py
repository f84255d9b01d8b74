"""SO(3) maps for every layer: ``skew``, ``expmap`` (Rodrigues) and ``logmap``.

Rotation matrices map body (local) coordinates to world coordinates; rotation vectors are
axis * angle [rad].  The hot kernels use their own allocation-free scalar forms in ``_kernels``
(``log3s``, ``rotate_left``); ``logmap`` calls ``log3s`` so the log formula exists once.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ._kernels import HOT, log3s

__all__ = ["skew", "expmap", "logmap", "rot_axis", "rotation_vectors", "pose_ok"]


def skew(w) -> np.ndarray:
    """Cross-product matrices [w]x of rotation vectors (..., 3) -> (..., 3, 3)."""
    w = np.asarray(w, dtype=float)
    S = np.zeros(w.shape[:-1] + (3, 3))
    S[..., 0, 1] = -w[..., 2]
    S[..., 0, 2] = w[..., 1]
    S[..., 1, 0] = w[..., 2]
    S[..., 1, 2] = -w[..., 0]
    S[..., 2, 0] = -w[..., 1]
    S[..., 2, 1] = w[..., 0]
    return S


def expmap(w) -> np.ndarray:
    """Rodrigues: rotation vector(s) (..., 3) [rad] -> rotation matrices (..., 3, 3)."""
    w = np.asarray(w, dtype=float)
    if w.shape == (3,):  # one vector (every env step's drive): scalar maths, ~5x faster
        return _expmap1(float(w[0]), float(w[1]), float(w[2]))
    th2 = np.sum(w * w, axis=-1)
    th = np.sqrt(th2)
    small = th < 1e-4
    ths = np.where(small, 1.0, th)
    a = np.where(small, 1.0 - th2 / 6.0 + th2 * th2 / 120.0, np.sin(ths) / ths)
    b = np.where(small, 0.5 - th2 / 24.0 + th2 * th2 / 720.0, (1.0 - np.cos(ths)) / (ths * ths))
    K = skew(w)
    return np.eye(3) + a[..., None, None] * K + b[..., None, None] * (K @ K)


def _expmap1(x: float, y: float, z: float) -> np.ndarray:
    """``expmap`` of one rotation vector (x, y, z) [rad]: I + a K + b K^2, K^2 = w w^T - th^2 I,
    with the same series below th = 1e-4."""
    th2 = x * x + y * y + z * z
    if th2 < 1e-8:
        a = 1.0 - th2 / 6.0 + th2 * th2 / 120.0
        b = 0.5 - th2 / 24.0 + th2 * th2 / 720.0
    else:
        th = math.sqrt(th2)
        a = math.sin(th) / th
        b = (1.0 - math.cos(th)) / (th * th)
    return np.array(
        [
            [1.0 - b * (y * y + z * z), b * x * y - a * z, b * x * z + a * y],
            [b * x * y + a * z, 1.0 - b * (x * x + z * z), b * y * z - a * x],
            [b * x * z - a * y, b * y * z + a * x, 1.0 - b * (x * x + y * y)],
        ]
    )


def logmap(R) -> np.ndarray:
    """Rotation vector(s) [rad] of rotation matrices (..., 3, 3) -> (..., 3), angle in [0, pi]."""
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 9)
    out = np.empty((flat.shape[0], 3))
    for k in range(flat.shape[0]):
        log3s(*flat[k], out[k])
    return out.reshape(R.shape[:-2] + (3,))


def rot_axis(axis, angle) -> np.ndarray:
    """Rotations about a fixed unit ``axis`` (3,) by ``angle`` [rad] (...,) -> (..., 3, 3)."""
    angle = np.asarray(angle, dtype=float)
    return expmap(angle[..., None] * np.asarray(axis, dtype=float))


def rotation_vectors(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) of rotation matrices (N, 3, 3), continuous along the sequence.

    Via unit quaternions whose sign is kept continuous (q_k · q_(k-1) >= 0), so the vector does not
    flip near a rotation of π (the brush's R0 is a half turn about x); the angle may then exceed π.
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    tr = np.trace(R, axis1=1, axis2=2)
    # Shepperd's method, branch per row
    q = np.empty((R.shape[0], 4))
    d = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(d, axis=1)
    for case in range(4):
        m = k == case
        if not np.any(m):
            continue
        Rm = R[m]
        if case == 0:
            s = np.sqrt(1.0 + tr[m]) * 2.0
            q[m] = np.stack(
                [
                    0.25 * s,
                    (Rm[:, 2, 1] - Rm[:, 1, 2]) / s,
                    (Rm[:, 0, 2] - Rm[:, 2, 0]) / s,
                    (Rm[:, 1, 0] - Rm[:, 0, 1]) / s,
                ],
                1,
            )
        elif case == 1:
            s = np.sqrt(1.0 + Rm[:, 0, 0] - Rm[:, 1, 1] - Rm[:, 2, 2]) * 2.0
            q[m] = np.stack(
                [
                    (Rm[:, 2, 1] - Rm[:, 1, 2]) / s,
                    0.25 * s,
                    (Rm[:, 0, 1] + Rm[:, 1, 0]) / s,
                    (Rm[:, 0, 2] + Rm[:, 2, 0]) / s,
                ],
                1,
            )
        elif case == 2:
            s = np.sqrt(1.0 + Rm[:, 1, 1] - Rm[:, 0, 0] - Rm[:, 2, 2]) * 2.0
            q[m] = np.stack(
                [
                    (Rm[:, 0, 2] - Rm[:, 2, 0]) / s,
                    (Rm[:, 0, 1] + Rm[:, 1, 0]) / s,
                    0.25 * s,
                    (Rm[:, 1, 2] + Rm[:, 2, 1]) / s,
                ],
                1,
            )
        else:
            s = np.sqrt(1.0 + Rm[:, 2, 2] - Rm[:, 0, 0] - Rm[:, 1, 1]) * 2.0
            q[m] = np.stack(
                [
                    (Rm[:, 1, 0] - Rm[:, 0, 1]) / s,
                    (Rm[:, 0, 2] + Rm[:, 2, 0]) / s,
                    (Rm[:, 1, 2] + Rm[:, 2, 1]) / s,
                    0.25 * s,
                ],
                1,
            )
    # first quaternion: prefer a non-negative vector part along its largest component
    if q.shape[0]:
        j = int(np.argmax(np.abs(q[0, 1:]))) + 1
        if q[0, 0] < 0 or (abs(q[0, 0]) < 1e-12 and q[0, j] < 0):
            q[0] = -q[0]
        dots = np.einsum("ij,ij->i", q[1:], q[:-1])
        flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0.0, -1.0, 1.0))])
        q = q * flips[:, None]
    v = q[:, 1:]
    nv = np.linalg.norm(v, axis=1)
    ang = 2.0 * np.arctan2(nv, q[:, 0])
    scale = np.where(nv > 1e-12, ang / np.maximum(nv, 1e-300), 2.0)  # small angle: 2 v
    return v * scale[:, None]


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
    det = (
        R[0, 0] * (R[1, 1] * R[2, 2] - R[1, 2] * R[2, 1])
        - R[0, 1] * (R[1, 0] * R[2, 2] - R[1, 2] * R[2, 0])
        + R[0, 2] * (R[1, 0] * R[2, 1] - R[1, 1] * R[2, 0])
    )
    return det >= 0.0
