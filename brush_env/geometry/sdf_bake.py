"""Baking a closed triangle mesh into a narrow-band signed-distance grid (``SdfGrid``), and the
disk cache of baked grids (issue 13; moved out of ``brush_env.engine.sdf``, issue 27).

Distance at the grid nodes is exact (closest triangle, Ericson's closest-feature test), its sign
from the angle-weighted pseudonormal of the closest feature (Baerentzen & Aanaes, IEEE TVCG 11(3),
2005), correct for any closed, consistently oriented mesh.  Outside nodes farther than ``band``
are clamped to +band; inside nodes beyond the band get -(band + their distance to the band) and
its gradient as normal.  The grid's query kernels (trilinear ``grid_gap``) stay in the engine
(``brush_env.engine.sdf``), which reads the ``SdfGrid`` this module produces.  Baked grids are
cached on disk (``cache_dir()``) under the SHA-256 of the mesh, cell, band and ``BAKE_VERSION``.
A grid whose bake would need more than ``BAKE_MAX_BYTES`` is refused before anything is allocated
(``check_grid_size``, ConfigError naming the coarsest cell that fits).  Units: mm.
"""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np
from numba import njit

from brush_env.engine.checks import ConfigError
from brush_env.engine.mesh_contact import closest_feature, dot3
from brush_env.engine.sdf import SdfGrid

__all__ = [
    "BAKE_VERSION",
    "BAKE_BYTES_PER_NODE",
    "BAKE_MAX_BYTES",
    "SdfGrid",
    "bake_mesh",
    "bake_mesh_cached",
    "cache_dir",
    "check_grid_size",
    "grid_dims",
    "mesh_key",
]

BAKE_VERSION = 2  # bump when the baking changes: cached grids of older versions are not used


@njit(cache=True, fastmath=False)  # explicit: never inherited from a caller (_kernels.HOT)
def _splat(V, T, pseudo, lo, h, band, dist, nrm, known):
    """Exact distance and sign at every node within ``band`` of a triangle (node-by-triangle
    minimum); sign and normal from the closest feature's pseudonormal (``pseudo`` = (face, edge,
    vertex) pseudonormals)."""
    fn, en, vn = pseudo
    i0 = np.empty(3, np.int64)
    i1 = np.empty(3, np.int64)
    for t in range(T.shape[0]):
        a, b, c = V[T[t, 0]], V[T[t, 1]], V[T[t, 2]]
        for k in range(3):
            mn = min(a[k], min(b[k], c[k])) - band
            mx = max(a[k], max(b[k], c[k])) + band
            i0[k] = max(int(np.floor((mn - lo[k]) / h)), 0)
            i1[k] = min(int(np.ceil((mx - lo[k]) / h)), dist.shape[k] - 1)
        for i in range(i0[0], i1[0] + 1):
            p0 = lo[0] + h * i
            for j in range(i0[1], i1[1] + 1):
                p1 = lo[1] + h * j
                for k in range(i0[2], i1[2] + 1):
                    p2 = lo[2] + h * k
                    q0, q1, q2, feat = closest_feature(p0, p1, p2, a, b, c)
                    r0, r1, r2 = p0 - q0, p1 - q1, p2 - q2
                    dd = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
                    if dd > band or dd >= abs(dist[i, j, k]):
                        continue
                    if feat == 0:
                        pn = fn[t]
                    elif feat <= 3:
                        pn = vn[T[t, feat - 1]]
                    else:
                        pn = en[t, feat - 4]
                    s = 1.0 if dot3(r0, r1, r2, pn[0], pn[1], pn[2]) >= 0.0 else -1.0
                    dist[i, j, k] = s * dd
                    if dd > 1e-9:
                        nrm[i, j, k, 0] = s * r0 / dd
                        nrm[i, j, k, 1] = s * r1 / dd
                        nrm[i, j, k, 2] = s * r2 / dd
                    else:
                        nrm[i, j, k, 0] = pn[0]
                        nrm[i, j, k, 1] = pn[1]
                        nrm[i, j, k, 2] = pn[2]
                    known[i, j, k] = True


def pseudonormals(V: np.ndarray, T: np.ndarray):
    """(face (nt, 3), edge (nt, 3, 3) for edges ab, bc, ca, vertex (nv, 3)) unit pseudonormals:
    edges the sum of their two faces' normals, vertices the angle-weighted sum (Baerentzen &
    Aanaes 2005)."""
    P = V[T]  # (nt, 3, 3)
    fn = np.cross(P[:, 1] - P[:, 0], P[:, 2] - P[:, 0])
    fn /= np.linalg.norm(fn, axis=1)[:, None]
    E = np.stack([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]], axis=1).reshape(-1, 2)
    key = np.sort(E, axis=1)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    inv = inv.ravel()
    acc = np.zeros((inv.max() + 1, 3))
    np.add.at(acc, inv, np.repeat(fn, 3, axis=0))
    acc /= np.maximum(np.linalg.norm(acc, axis=1), 1e-300)[:, None]
    en = acc[inv].reshape(-1, 3, 3)
    vn = np.zeros_like(V)
    for k in range(3):
        e1 = P[:, (k + 1) % 3] - P[:, k]
        e2 = P[:, (k + 2) % 3] - P[:, k]
        cosang = np.einsum("ij,ij->i", e1, e2) / (
            np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
        )
        ang = np.arccos(np.clip(cosang, -1.0, 1.0))
        np.add.at(vn, T[:, k], ang[:, None] * fn)
    vn /= np.maximum(np.linalg.norm(vn, axis=1), 1e-300)[:, None]
    return fn, en, vn


#: [bytes] memory a bake needs per grid node at its peak: distance (8) and normal (24) in float64,
#: the band flags and component labels (~7), and for nodes deep inside the distance transform
#: and its gradient (~60)
BAKE_BYTES_PER_NODE = 100
#: [bytes] the largest bake allowed (2 GiB): a bigger grid is refused before anything is allocated
BAKE_MAX_BYTES = 2 * 1024**3


def grid_dims(vertices, cell: float, band: float) -> tuple[np.ndarray, np.ndarray]:
    """(lo (3,) [mm], dims (3,)): the origin and node counts of the grid ``bake_mesh`` bakes."""
    V = np.asarray(vertices, float)
    lo = V.min(axis=0) - band - cell
    dims = np.ceil((V.max(axis=0) + band + cell - lo) / cell).astype(np.int64) + 1
    return lo, dims


def check_grid_size(vertices, cell: float, band: float, what: str = "mesh") -> None:
    """Refuse (ConfigError) a bake whose grid would need more than ``BAKE_MAX_BYTES``: the
    message gives the grid, its estimated memory and the coarsest ``cell_mm`` that would fit."""
    _, dims = grid_dims(vertices, cell, band)
    need = float(np.prod(dims.astype(float))) * BAKE_BYTES_PER_NODE
    if need <= BAKE_MAX_BYTES:
        return
    fit = float(cell)
    while True:  # the finest cell (1 % steps) whose grid fits
        fit *= 1.01
        _, d = grid_dims(vertices, fit, max(band, 2 * fit))
        if float(np.prod(d.astype(float))) * BAKE_BYTES_PER_NODE <= BAKE_MAX_BYTES:
            break
    ext = np.ptp(np.asarray(vertices, float), axis=0)
    raise ConfigError(
        f"{what}: cell_mm = {cell:g} is too fine for a mesh of {ext[0]:.4g} x {ext[1]:.4g} x "
        f"{ext[2]:.4g} mm: its SDF grid of {dims[0]} x {dims[1]} x {dims[2]} nodes would need "
        f"~{need / 1024**3:.3g} GiB to bake, more than the {BAKE_MAX_BYTES / 1024**3:g} GiB "
        f"allowed: refused (use cell_mm >= {np.ceil(fit * 1000) / 1000:g}, band_mm >= 2 cell_mm, "
        "or a smaller mesh)"
    )


def bake_mesh(vertices, triangles, cell: float = 0.2, band: float = 1.0) -> SdfGrid:
    """Bake a closed, outward-oriented triangle mesh (vertices [mm]) into a narrow-band grid of
    cell ``cell`` [mm] reaching ``band`` [mm] beyond the mesh's bounding box."""
    from scipy import ndimage

    V = np.ascontiguousarray(vertices, float)
    T = np.ascontiguousarray(triangles, np.int64)
    if not (cell > 0 and band >= 2 * cell):
        raise ValueError(
            f"sdf cell = {cell!r} mm, band = {band!r} mm: need cell > 0, band >= 2 cell"
        )
    check_grid_size(V, cell, band)
    lo, dims = grid_dims(V, cell, band)
    fn, en, vn = pseudonormals(V, T)
    dist = np.full(tuple(dims), np.inf)
    nrm = np.zeros((*dims, 3))
    known = np.zeros(tuple(dims), bool)
    _splat(V, T, (fn, en, vn), lo, float(cell), float(band), dist, nrm, known)
    # nodes beyond the band: outside if connected to the grid's border without crossing the band
    labels, _ = ndimage.label(~known)
    border = np.unique(
        np.concatenate(
            [
                labels[[0, -1], :, :].ravel(),
                labels[:, [0, -1], :].ravel(),
                labels[:, :, [0, -1]].ravel(),
            ]
        )
    )
    outside = np.isin(labels, border[border > 0])
    dist[~known] = np.where(outside[~known], band, -band)
    # inside beyond the band: -(band + distance to the band) with the gradient as normal, so a
    # tip that lands deep inside (a snap-through predictor step) is pushed out, not lost
    deep = ~known & ~outside
    if deep.any():
        dist[deep] = -band - cell * ndimage.distance_transform_edt(deep)[deep]
        g = np.stack(list(np.gradient(dist, cell)), axis=-1)
        gn = np.linalg.norm(g, axis=-1)
        ok = deep & (gn > 1e-12)
        nrm[ok] = g[ok] / gn[ok][:, None]
    return SdfGrid(tuple(float(x) for x in lo), float(cell), float(band), dist, nrm)


def cache_dir() -> Path:
    """Where baked grids are kept: $BRUSH_ENV_CACHE/sdf, else ~/.cache/brush_env/sdf."""
    root = os.environ.get("BRUSH_ENV_CACHE") or os.path.join(
        os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "brush_env"
    )
    return Path(root) / "sdf"


def mesh_key(vertices, triangles, cell: float, band: float) -> str:
    """Content hash of a bake: mesh arrays, cell, band and BAKE_VERSION."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(vertices, np.float64).tobytes())
    h.update(np.ascontiguousarray(triangles, np.int64).tobytes())
    h.update(f"{cell!r},{band!r},{BAKE_VERSION}".encode())
    return h.hexdigest()[:32]


def bake_mesh_cached(vertices, triangles, cell: float = 0.2, band: float = 1.0) -> SdfGrid:
    """``bake_mesh`` through the disk cache (a corrupt or unwritable cache only costs a bake)."""
    path = cache_dir() / f"{mesh_key(vertices, triangles, cell, band)}.npz"
    try:
        with np.load(path) as z:
            return SdfGrid(
                tuple(z["origin"]), float(z["cell"]), float(z["band"]), z["distance"], z["normal"]
            )
    except (OSError, KeyError, ValueError):
        pass
    grid = bake_mesh(vertices, triangles, cell, band)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
        np.savez_compressed(
            tmp,
            origin=np.array(grid.origin),
            cell=grid.cell,
            band=grid.band,
            distance=grid.distance.astype(np.float32),
            normal=grid.normal.astype(np.float32),
        )
        os.replace(tmp, path)
    except OSError:
        pass
    return grid
