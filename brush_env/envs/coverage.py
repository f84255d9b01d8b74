"""Coverage of a square patch by effective tip contacts.

The patch is a square of side ``patch_size`` [mm] centred on the (actual) plate origin, split into
square cells of side ``cell_size``.  A cell counts as cleaned once an *effective* contact passes
over it: a tip touching the plate with a normal force inside the per-tip effectiveness window
``[f_min, f_max]``.  "Passes over" is made gap-free at any speed: between two consecutive engine
steps at which a tip is effective, its contact point is swept along the straight segment joining
them, sampled every half cell, and every cell whose centre lies within ``clean_radius`` of a
sample (or the cell holding the sample when ``clean_radius`` is 0) is cleaned.

Grid indices: ``cleaned[i, j]`` is the cell with centre ``x = -S/2 + (j + 1/2) c``,
``y = -S/2 + (i + 1/2) c`` (rows along +y, columns along +x).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from brush_env.engine.scrub import SurfaceCoverage  # curved surfaces (ToothRow-v0)

__all__ = ["CoverageMap", "SurfaceCoverage"]


class CoverageMap:
    """Boolean cleaned-cell grid with segment stamping (see the module docstring)."""

    def __init__(self, patch_size: float, cell_size: float, clean_radius: float, coarse_size: int):
        self.patch_size = float(patch_size)
        self.n = max(1, int(round(patch_size / cell_size)))
        self.cell = self.patch_size / self.n  # the patch is split exactly
        self.clean_radius = float(clean_radius)
        self.coarse_size = int(coarse_size)
        self.cleaned = np.zeros((self.n, self.n), bool)
        self.count = 0
        # coarse blocks: edges in cell indices (blocks differ by at most one cell in size)
        self._edges = np.linspace(0, self.n, self.coarse_size + 1).round().astype(int)
        self._block_area = np.diff(self._edges)[:, None] * np.diff(self._edges)[None, :]

    @property
    def total(self) -> int:
        return self.n * self.n

    @property
    def fraction(self) -> float:
        return self.count / self.total

    def reset(self) -> None:
        self.cleaned[:] = False
        self.count = 0

    def stamp(self, start: np.ndarray, end: np.ndarray) -> int:
        """Clean along segments ``start[k] -> end[k]`` ((m, 2) or (m, 3) contact points in mm,
        patch-centred; only x, y are used); returns the number of newly cleaned cells."""
        if len(end) == 0:
            return 0
        new = _stamp_segments(
            self.cleaned,
            np.ascontiguousarray(np.asarray(start)[:, :2], dtype=np.float64),
            np.ascontiguousarray(np.asarray(end)[:, :2], dtype=np.float64),
            self.patch_size,
            self.cell,
            self.clean_radius,
        )
        self.count += new
        return new

    def coarse(self) -> np.ndarray:
        """(coarse_size, coarse_size) fraction cleaned per block (rows along +y)."""
        c = np.add.reduceat(
            np.add.reduceat(self.cleaned, self._edges[:-1], axis=0), self._edges[:-1], axis=1
        )
        return c / self._block_area


@njit(cache=True)
def _stamp_segments(cleaned, start, end, patch_size, cell, radius):
    """Mark cells within ``radius`` of samples (every half cell) along each segment; returns the
    number of cells newly set.  ``cleaned`` (n, n) bool is modified in place."""
    n = cleaned.shape[0]
    half = 0.5 * patch_size
    rho = radius / cell
    rho2 = rho * rho
    k = int(np.floor(rho + 0.5))  # offsets that can hold a centre within rho of the sample
    new = 0
    for s in range(start.shape[0]):
        dx = end[s, 0] - start[s, 0]
        dy = end[s, 1] - start[s, 1]
        m = int(np.ceil(max(abs(dx), abs(dy)) / (0.5 * cell))) + 1
        for q in range(m):
            f = q / (m - 1) if m > 1 else 1.0
            ux = (start[s, 0] + f * dx + half) / cell
            uy = (start[s, 1] + f * dy + half) / cell
            bi = int(np.floor(uy))
            bj = int(np.floor(ux))
            if radius == 0.0:
                if 0 <= bi < n and 0 <= bj < n and not cleaned[bi, bj]:
                    cleaned[bi, bj] = True
                    new += 1
                continue
            for i in range(bi - k, bi + k + 1):
                if i < 0 or i >= n:
                    continue
                for j in range(bj - k, bj + k + 1):
                    if j < 0 or j >= n or cleaned[i, j]:
                        continue
                    ex = j + 0.5 - ux
                    ey = i + 0.5 - uy
                    if ex * ex + ey * ey <= rho2:
                        cleaned[i, j] = True
                        new += 1
    return new
