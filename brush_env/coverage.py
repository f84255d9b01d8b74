"""Coverage: what the brush's effective tips cleaned, written once for every env and experiment
(issue 27).  Units: mm, mm^2.

An *effective* tip touches a surface with a normal force inside the tip-force window
``[f_min, f_max]`` [N].  Between two consecutive engine steps at which a tip is effective, its
contact point is swept along the segment joining them (``EffectiveSweep``), so a cell or sample
counts as cleaned at any speed.  Three maps, one per surface kind:

* ``CoverageMap`` (FlatPlate-v0): a square patch of the plate in square cells;
* ``SurfaceCoverage`` (ToothRow-v0, the tooth-row experiment): area-weighted samples on curved
  crowns, each with a region and a tooth (``crown_samples``);
* ``LineCoverage`` (PlanarStroke-v0): cells along the planar profile's x.

``gum_force`` is the normal force of the tips whose deepest contact is a surface labelled
``gum`` (ToothRow-v0's gum-force term, the tooth-row experiment's ``F_gum`` column).

The engine does not use this module; it reads only the engine's step results.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from brush_env.geometry.teeth import REACHABLE, REGIONS, surface_samples

__all__ = [
    "CoverageMap",
    "EffectiveSweep",
    "LineCoverage",
    "SurfaceCoverage",
    "crown_samples",
    "gum_force",
    "gum_forces",
]


# ------------------------------------------------------------------ effective tips
class EffectiveSweep:
    """The swept segments of effective tips, step by step: ``segments(out)`` returns the
    (start, end) contact points [mm] ((m, 3) each) of the tips effective at this step (start =
    the tip's contact point at its previous effective step if it was effective at the previous
    step, else the point itself), or None when no tip is effective."""

    def __init__(self, n_tips: int, window: tuple[float, float]):
        self.lo, self.hi = window
        self.prev_eff = np.zeros(n_tips, bool)
        self.prev_cp = np.zeros((n_tips, 3))

    def reset(self) -> None:
        self.prev_eff = np.zeros(len(self.prev_eff), bool)
        self.prev_cp = np.zeros((len(self.prev_eff), 3))

    def segments(self, out) -> tuple[np.ndarray, np.ndarray] | None:
        f = out.tip_normal_force
        eff = out.tip_in_contact & (f >= self.lo) & (f <= self.hi)
        seg = None
        if eff.any():
            cp = out.tip_contact_point[eff]
            both = self.prev_eff[eff]
            seg = (np.where(both[:, None], self.prev_cp[eff], cp), cp)
            self.prev_cp[eff] = cp
        self.prev_eff = eff
        return seg

    def segments_many(
        self, f: np.ndarray, cp: np.ndarray, contact: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """``segments`` over n steps at once: tip normal forces f (n, nb) [N], contact points cp
        (n, nb, 3) [mm], in-contact flags (n, nb); returns all (start, end) pairs ((m, 3) each,
        in step order, m = 0 when no tip was effective)."""
        eff = contact & (f >= self.lo) & (f <= self.hi)
        n = len(f)
        if n == 0:
            return np.zeros((0, 3)), np.zeros((0, 3))
        prev = np.concatenate([self.prev_eff[None], eff[:-1]], axis=0)
        # the last effective contact point of each tip before each step (the sweep's start)
        last = np.empty_like(cp)
        held = self.prev_cp
        for k in range(n):
            last[k] = held
            held = np.where(eff[k][:, None], cp[k], held)
        self.prev_cp = held.copy()
        self.prev_eff = eff[-1].copy()
        starts = np.where(prev[..., None], last, cp)[eff]
        return starts, cp[eff]


def gum_force(out, gum: np.ndarray) -> float:
    """Normal force [N] of the tips whose deepest contact is a gum surface (``gum``: one bool a
    surface of the scene, ``engine.scene.surface_labels(scene) == "gum"``); 0 without a gum."""
    return float(gum_forces(out.tip_normal_force[None], out.extra["tip_surface"][None], gum)[0])


def gum_forces(fn: np.ndarray, surf: np.ndarray, gum: np.ndarray) -> np.ndarray:
    """``gum_force`` of n steps: tip normal forces fn (n, nb) [N], the surface each tip touches
    deepest surf (n, nb) (-1: none); returns (n,) [N]."""
    out = np.zeros(len(fn))
    if gum.any():
        on = (surf >= 0) & gum[np.maximum(surf, 0)]
        for k in range(len(fn)):
            out[k] = fn[k][on[k]].sum()
    return out


# ------------------------------------------------------------------ the plate's patch
class CoverageMap:
    """Boolean cleaned-cell grid with segment stamping (FlatPlate-v0).

    The patch is a square of side ``patch_size`` [mm] centred on the (actual) plate origin,
    split into square cells of side ``cell_size``.  A cell counts as cleaned once an effective
    contact passes over it: the swept segment is sampled every half cell, and every cell whose
    centre lies within ``clean_radius`` of a sample (or the cell holding the sample when
    ``clean_radius`` is 0) is cleaned.

    Grid indices: ``cleaned[i, j]`` is the cell with centre ``x = -S/2 + (j + 1/2) c``,
    ``y = -S/2 + (i + 1/2) c`` (rows along +y, columns along +x).
    """

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
        # each cell row's (= column's) block, and the cleaned cells per block, counted as the
        # stamps set them (``coarse`` without summing the grid every step)
        self._block = np.searchsorted(self._edges, np.arange(self.n), side="right") - 1
        self._block_count = np.zeros((self.coarse_size, self.coarse_size), np.int64)

    @property
    def total(self) -> int:
        return self.n * self.n

    @property
    def fraction(self) -> float:
        return self.count / self.total

    def reset(self) -> None:
        self.cleaned[:] = False
        self.count = 0
        self._block_count[:] = 0

    def stamp(self, start: np.ndarray, end: np.ndarray) -> int:
        """Clean along segments ``start[k] -> end[k]`` ((m, 2) or (m, 3) contact points in mm,
        patch-centred; only x, y are used); returns the number of newly cleaned cells."""
        if len(end) == 0:
            return 0
        start = np.ascontiguousarray(np.asarray(start)[:, :2], dtype=np.float64)
        end = np.ascontiguousarray(np.asarray(end)[:, :2], dtype=np.float64)
        new = _stamp_segments(self._grid(), start, end)
        self.count += new
        return new

    def sweep(self, sweep: EffectiveSweep, f: np.ndarray, cp: np.ndarray) -> int:
        """``sweep.segments_many(f, cp, f > 0)`` stamped, in one compiled call: tip normal forces
        f (n, nb) [N] and contact points cp (n, nb, 3) [mm] of n engine steps (a tip touches
        where f > 0); ``sweep``'s state moves on as ``segments_many`` moves it.  Returns the
        number of newly cleaned cells."""
        new = _sweep_stamp(
            self._grid(),
            f,
            cp,
            sweep.lo,
            sweep.hi,
            sweep.prev_eff,
            sweep.prev_cp,
        )
        self.count += new
        return new

    def _grid(self) -> Grid:
        return Grid(
            self.cleaned,
            self.patch_size,
            self.cell,
            self.clean_radius,
            self._block,
            self._block_count,
        )

    def coarse(self) -> np.ndarray:
        """(coarse_size, coarse_size) fraction cleaned per block (rows along +y)."""
        return self._block_count / self._block_area


#: a CoverageMap's grid as the kernels see it: cleaned (n, n) bool, the patch side and cell side
#: [mm], the cleaning radius [mm], block (n,) each cell row's (= column's) coarse block and
#: block_count (m, m) the cleaned cells per block
Grid = namedtuple("Grid", ["cleaned", "patch_size", "cell", "radius", "block", "block_count"])


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def _stamp_segment(g, start, end):
    """Mark the cells within ``g.radius`` of samples (every half cell) along the segment start ->
    end (x, y [mm], patch-centred; the cell holding a sample where the radius is 0), counting
    them per coarse block; returns the number of cells newly set."""
    cleaned = g.cleaned
    n = cleaned.shape[0]
    cell = g.cell
    half = 0.5 * g.patch_size
    rho = g.radius / cell
    rho2 = rho * rho
    k = int(np.floor(rho + 0.5))  # offsets that can hold a centre within rho of the sample
    new = 0
    dx = end[0] - start[0]
    dy = end[1] - start[1]
    m = int(np.ceil(max(abs(dx), abs(dy)) / (0.5 * cell))) + 1
    for q in range(m):
        f = q / (m - 1) if m > 1 else 1.0
        ux = (start[0] + f * dx + half) / cell
        uy = (start[1] + f * dy + half) / cell
        bi = int(np.floor(uy))
        bj = int(np.floor(ux))
        if g.radius == 0.0:
            if 0 <= bi < n and 0 <= bj < n and not cleaned[bi, bj]:
                cleaned[bi, bj] = True
                g.block_count[g.block[bi], g.block[bj]] += 1
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
                    g.block_count[g.block[i], g.block[j]] += 1
                    new += 1
    return new


@njit(cache=True, fastmath=False)
def _stamp_segments(g, start, end):
    """``_stamp_segment`` along each segment start[k] -> end[k] ((m, 2) [mm]); returns the number
    of cells newly set."""
    new = 0
    for k in range(start.shape[0]):
        new += _stamp_segment(g, start[k], end[k])
    return new


@njit(cache=True, fastmath=False)
def _sweep_stamp(g, f, cp, lo, hi, prev_eff, prev_cp):
    """``EffectiveSweep.segments_many`` and ``_stamp_segment`` over n engine steps in one pass
    (``CoverageMap.sweep``): a tip effective at step k (f in [lo, hi], f > 0) sweeps from its
    contact point at step k - 1 if it was effective then, else from its own point; prev_eff (nb,)
    and prev_cp (nb, 3) move on in place.  Returns the number of cells newly set."""
    new = 0
    p = np.empty(2)
    e = np.empty(2)
    for s in range(f.shape[0]):
        for b in range(f.shape[1]):
            fb = f[s, b]
            eff = fb > 0.0 and lo <= fb <= hi
            if eff:
                e[0], e[1] = cp[s, b, 0], cp[s, b, 1]
                if prev_eff[b]:
                    p[0], p[1] = prev_cp[b, 0], prev_cp[b, 1]
                else:
                    p[0], p[1] = e[0], e[1]
                new += _stamp_segment(g, p, e)
                for a in range(3):
                    prev_cp[b, a] = cp[s, b, a]
            prev_eff[b] = eff
    return new


# ------------------------------------------------------------------ curved surfaces
class SurfaceCoverage:
    """Coverage of curved surfaces (ToothRow-v0): area-weighted samples (triangle centroids of
    the crowns above the CEJ, ``brush_env.geometry.teeth.surface_samples``), each with a region
    (buccal, occlusal, interproximal, lingual) and a tooth.  A sample is cleaned once an effective
    tip's contact point passes within ``clean_radius`` [mm] of it (3-D distance to the swept
    segment between consecutive effective steps).  ``fraction`` is the cleaned area over the
    area a brush on the buccal side can reach (``teeth.REACHABLE`` regions); ``count`` the
    cleaned area [mm^2], so the env's coverage reward ``weight * new / total`` is an area share.
    ``coarse()`` is the buccal view (x along the row, y up the crowns) in m x m blocks."""

    def __init__(self, points, areas, region, tooth, tooth_names, clean_radius, coarse_size):
        from scipy.spatial import cKDTree

        self.points = np.ascontiguousarray(points, float)
        self.areas = np.asarray(areas, float)
        self.region = np.asarray(region, np.int64)
        self.tooth = np.asarray(tooth, np.int64)
        self.tooth_names = tuple(tooth_names)
        self.region_names = REGIONS
        self.reach = np.isin(self.region, REACHABLE)
        self.clean_radius = float(clean_radius)
        self.coarse_size = int(coarse_size)
        self._tree = cKDTree(self.points)
        self.cleaned = np.zeros(len(self.points), bool)
        self.count = 0.0
        self._total = float(self.areas[self.reach].sum())
        lo, hi = self.points[:, :2].min(axis=0), self.points[:, :2].max(axis=0)
        m = self.coarse_size
        ij = np.clip(((self.points[:, :2] - lo) / (hi - lo + 1e-9) * m).astype(int), 0, m - 1)
        self._block = ij[:, 1] * m + ij[:, 0]  # rows along +y, columns along +x
        w = np.where(self.reach, self.areas, 0.0)
        self._block_area = np.bincount(self._block, w, m * m)
        self.extent = (lo, hi)
        # each block's, region's and tooth's area [mm^2] (reachable only for blocks and teeth),
        # and how much of it is cleaned, kept as ``stamp`` cleans (the env reads them every step:
        # reductions over every sample cost ~0.2 ms there)
        self._region_area = np.bincount(self.region, self.areas, len(self.region_names))
        self._tooth_area = np.bincount(self.tooth, w, len(self.tooth_names))
        self._block_clean = np.zeros(m * m)
        self._region_clean = np.zeros(len(self.region_names))
        self._tooth_clean = np.zeros(len(self.tooth_names))

    @property
    def total(self) -> float:
        return self._total

    @property
    def fraction(self) -> float:
        return self.count / self._total

    def reset(self) -> None:
        self.cleaned[:] = False
        self.count = 0.0
        self._block_clean[:] = 0.0
        self._region_clean[:] = 0.0
        self._tooth_clean[:] = 0.0

    def sweep(self, sweep: EffectiveSweep, f: np.ndarray, cp: np.ndarray) -> float:
        """``CoverageMap.sweep``'s contract: the effective tips' segments of n engine steps
        (``sweep.segments_many``) stamped; returns the newly cleaned area [mm^2]."""
        starts, ends = sweep.segments_many(f, cp, f > 0.0)
        return self.stamp(starts, ends) if len(starts) else 0.0

    def stamp(self, start: np.ndarray, end: np.ndarray) -> float:
        """Clean along segments start[k] -> end[k] ((m, 3) contact points [mm]); returns the newly
        cleaned reachable area [mm^2]."""
        if len(end) == 0:
            return 0.0
        a = np.asarray(start, float)
        b = np.asarray(end, float)
        mid = 0.5 * (a + b)
        half = 0.5 * np.linalg.norm(b - a, axis=1)
        lists = self._tree.query_ball_point(mid, self.clean_radius + half)
        new = 0.0
        for k, idx in enumerate(lists):
            if not idx:
                continue
            idx = np.asarray(idx)
            idx = idx[~self.cleaned[idx]]
            if idx.size == 0:
                continue
            ab = b[k] - a[k]
            L2 = float(ab @ ab)
            q = self.points[idx] - a[k]
            t = np.clip(q @ ab / L2, 0.0, 1.0) if L2 > 0 else np.zeros(len(idx))
            d2 = np.sum((q - t[:, None] * ab) ** 2, axis=1)
            hit = idx[d2 <= self.clean_radius**2]
            if hit.size == 0:
                continue
            self.cleaned[hit] = True
            ah = self.areas[hit]
            reach = self.reach[hit]
            new += float(ah[reach].sum())
            np.add.at(self._region_clean, self.region[hit], ah)
            np.add.at(self._block_clean, self._block[hit[reach]], ah[reach])
            np.add.at(self._tooth_clean, self.tooth[hit[reach]], ah[reach])
        self.count += new
        return new

    def coarse(self) -> np.ndarray:
        """(m, m) reachable fraction cleaned per block of the buccal view (empty blocks: 0)."""
        c, a = self._block_clean, self._block_area
        out = np.divide(c, a, out=np.zeros_like(c), where=a > 0)
        return out.reshape(self.coarse_size, self.coarse_size)

    def by_region(self) -> dict[str, float]:
        """Cleaned fraction of each region's area (all teeth)."""
        return _fractions(self.region_names, self._region_clean, self._region_area)

    def by_tooth(self) -> dict[str, float]:
        """Cleaned fraction of each tooth's reachable area."""
        return _fractions(self.tooth_names, self._tooth_clean, self._tooth_area)


def _fractions(names, clean: np.ndarray, area: np.ndarray) -> dict[str, float]:
    """name -> cleaned area / area (0 where there is no area)."""
    return {
        name: float(clean[k]) / float(area[k]) if area[k] else 0.0 for k, name in enumerate(names)
    }


def crown_samples(teeth, clean_radius: float, coarse_size: int = 8) -> SurfaceCoverage:
    """A fresh SurfaceCoverage of the crowns (MeshSurfaces labelled ``tooth:<name>``)."""
    pts, areas, region, tooth, names = [], [], [], [], []
    for k, s in enumerate(teeth):
        c, a, r = surface_samples(s.vertices, s.triangles)
        pts.append(c)
        areas.append(a)
        region.append(r)
        tooth.append(np.full(len(c), k))
        names.append(s.label.split(":", 1)[-1])
    return SurfaceCoverage(
        np.concatenate(pts),
        np.concatenate(areas),
        np.concatenate(region),
        np.concatenate(tooth),
        names,
        clean_radius,
        coarse_size,
    )


# ------------------------------------------------------------------ the planar profile
class LineCoverage:
    """Cells of ``cell`` [mm] along x over [-half, half] (PlanarStroke-v0): a cell is cleaned when
    an effective tip's swept x-interval, widened by ``clean_radius`` [mm], covers it."""

    def __init__(self, half_width: float, cell: float, clean_radius: float, blocks: int):
        self.half = float(half_width)
        self.cell = float(cell)
        self.n = int(round(2 * self.half / self.cell))
        self.clean_radius = float(clean_radius)
        self.blocks = int(blocks)
        self.cleaned = np.zeros(self.n, bool)

    @property
    def fraction(self) -> float:
        return float(self.cleaned.mean())

    def reset(self) -> None:
        self.cleaned = np.zeros(self.n, bool)

    def stamp(self, start: np.ndarray, end: np.ndarray) -> int:
        """Clean along x-intervals ``start[k] -> end[k]`` [mm]; returns the newly cleaned cells."""
        new = 0
        for a, x in zip(start, end):
            lo = min(a, x) - self.clean_radius + self.half
            hi = max(a, x) + self.clean_radius + self.half
            i0 = max(int(math.floor(lo / self.cell)), 0)
            i1 = min(int(math.ceil(hi / self.cell)), self.n)
            if i1 > i0:
                new += int((~self.cleaned[i0:i1]).sum())
                self.cleaned[i0:i1] = True
        return new

    def coarse(self) -> np.ndarray:
        """(blocks,) fraction cleaned per block along x."""
        if self.n % self.blocks == 0:
            return self.cleaned.reshape(self.blocks, -1).mean(axis=1)
        return np.array([b.mean() for b in np.array_split(self.cleaned, self.blocks)])
