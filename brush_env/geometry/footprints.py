"""Root footprints of a brush's bristles: the smallest clearance between two root
cross-sections (separating axes), the check behind ``BrushConfig.min_root_gap`` (moved out of
``brush_env.engine.config``, issue 27).  Units: mm, head frame.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["min_root_gap"]


def _perp_unit(e: np.ndarray, fallback: tuple[float, float]) -> np.ndarray:
    """Unit 2D normal of edge direction ``e`` (``fallback`` if the edge projects to a point)."""
    n = float(np.linalg.norm(e))
    return np.array([e[1], -e[0]]) / n if n > 1e-12 else np.array(fallback)


def min_root_gap(bristles) -> tuple[float, int, int]:
    """Smallest clearance [mm] between two bristles' root cross-sections, and that pair
    (``bristles``: ``BristleConfig``s; see ``BrushConfig.min_root_gap``)."""
    n = len(bristles)
    centres = np.array([b.root[:2] for b in bristles])
    corners: list = []
    radii: list = []
    normals: list = []
    for b in bristles:
        w, t = np.asarray(b.width_dir)[:2], np.asarray(b.thickness_dir)[:2]
        if b.section.kind == "rect":
            hw, ht = b.section.width / 2 * w, b.section.thickness / 2 * t
            corners.append([-hw - ht, hw - ht, hw + ht, -hw + ht])
            radii.append(0.0)
            normals.append([_perp_unit(w, (0.0, 1.0)), _perp_unit(t, (1.0, 0.0))])
        else:
            corners.append(np.zeros((4, 2)))
            radii.append(b.section.width / 2)
            normals.append(np.eye(2))
    poly = centres[:, None, :] + np.array(corners)  # (n, 4, 2)
    rad, nrm = np.array(radii), np.array(normals)  # (n,), (n, 2, 2)
    best = (math.inf, -1, -1)
    for i in range(n - 1):
        j = np.arange(i + 1, n)
        d = centres[j] - centres[i]
        dn = np.linalg.norm(d, axis=1, keepdims=True)
        line = np.where(dn > 1e-12, d / np.maximum(dn, 1e-12), [1.0, 0.0])
        axes = np.concatenate(
            [np.broadcast_to(nrm[i], (len(j), 2, 2)), nrm[j], line[:, None, :]], axis=1
        )  # (m, 5, 2)
        pi = np.einsum("vd,mad->mav", poly[i], axes)
        pj = np.einsum("mvd,mad->mav", poly[j], axes)
        lo_i, hi_i = pi.min(-1) - rad[i], pi.max(-1) + rad[i]
        lo_j, hi_j = pj.min(-1) - rad[j, None], pj.max(-1) + rad[j, None]
        gap = np.maximum(lo_j - hi_i, lo_i - hi_j).max(axis=1)
        k = int(np.argmin(gap))
        if gap[k] < best[0]:
            best = (float(gap[k]), i, int(j[k]))
    return best
