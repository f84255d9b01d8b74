"""Which parts of curved surfaces the tips scrubbed: area-weighted surface samples, each with a
region and a tooth, cleaned when a tip's contact point passes near (issue 13).

Used by ToothRow-v0's coverage reward (``brush_env.envs.tooth_row``) and by the tooth-row
reference experiment (``brush_env.experiments.tooth_row``) for its per-region coverage.  Units:
mm, mm^2.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SurfaceCoverage", "crown_samples"]


class SurfaceCoverage:
    """Coverage of curved surfaces (ToothRow-v0): area-weighted samples (triangle centroids of
    the crowns above the CEJ, ``brush_env.engine.teeth.surface_samples``), each with a region
    (buccal, occlusal, interproximal, lingual) and a tooth.  A sample is cleaned once an effective
    tip's contact point passes within ``clean_radius`` [mm] of it (3-D distance to the swept
    segment between consecutive effective steps).  ``fraction`` is the cleaned area over the
    area a brush on the buccal side can reach (``teeth.REACHABLE`` regions); ``count`` the
    cleaned area [mm^2], so the env's coverage reward ``weight * new / total`` is an area share.
    ``coarse()`` is the buccal view (x along the row, y up the crowns) in m x m blocks."""

    def __init__(self, points, areas, region, tooth, tooth_names, clean_radius, coarse_size):
        from scipy.spatial import cKDTree

        from .teeth import REACHABLE, REGIONS

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

    @property
    def total(self) -> float:
        return self._total

    @property
    def fraction(self) -> float:
        return self.count / self._total

    def reset(self) -> None:
        self.cleaned[:] = False
        self.count = 0.0

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
            self.cleaned[hit] = True
            new += float(self.areas[hit][self.reach[hit]].sum())
        self.count += new
        return new

    def coarse(self) -> np.ndarray:
        """(m, m) reachable fraction cleaned per block of the buccal view (empty blocks: 0)."""
        w = np.where(self.cleaned & self.reach, self.areas, 0.0)
        c = np.bincount(self._block, w, self.coarse_size**2)
        out = np.divide(c, self._block_area, out=np.zeros_like(c), where=self._block_area > 0)
        return out.reshape(self.coarse_size, self.coarse_size)

    def by_region(self) -> dict[str, float]:
        """Cleaned fraction of each region's area (all teeth)."""
        out = {}
        for k, name in enumerate(self.region_names):
            sel = self.region == k
            tot = float(self.areas[sel].sum())
            out[name] = float(self.areas[sel & self.cleaned].sum()) / tot if tot else 0.0
        return out

    def by_tooth(self) -> dict[str, float]:
        """Cleaned fraction of each tooth's reachable area."""
        out = {}
        for k, name in enumerate(self.tooth_names):
            sel = (self.tooth == k) & self.reach
            tot = float(self.areas[sel].sum())
            out[name] = float(self.areas[sel & self.cleaned].sum()) / tot if tot else 0.0
        return out


def crown_samples(teeth, clean_radius: float, coarse_size: int = 8) -> SurfaceCoverage:
    """A fresh SurfaceCoverage of the crowns (MeshSurfaces labelled ``tooth:<name>``)."""
    from .teeth import surface_samples

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


def tooth_surfaces(scene) -> list:
    """The crowns of a scene: its SDF mesh surfaces labelled ``tooth:...``."""
    from .scene import MeshSurface

    return [s for s in scene.surfaces if isinstance(s, MeshSurface) and s.label.startswith("tooth")]
