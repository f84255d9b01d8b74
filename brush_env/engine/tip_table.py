"""The tabulated tip law (issue 29): the reduced chain's equilibria (``prb_kernels``) tabulated
by its tip's position, so that a touching bristle's step is a Newton on its tip's three
coordinates instead of the chain's five joint angles (``tip_table_kernels`` for the table and
its branches; ``prb_kernels.table_solve`` for the step).

One table per distinct joint record (a bristle type and the brush's lean: the springs, cubics,
damping and rest angles), named by its content: those of the brushes in configs/brushes ship
with the package (``SHIPPED``, remade by ``brush-env calibrate --all --ship``), others are built
in numba on first use (~60 s on one core) and cached under the user's cache directory
(``prb_calibration.user_cache``'s folder).  The model that uses it is
registered as ``"table"`` (``prb.TableBristles``): every bristle touching nothing still takes the
chain's free step, and a step the table cannot take (no branch under the tip) falls back to the
chain's own Newton.
"""

from __future__ import annotations

import hashlib
import math
import os
from collections import OrderedDict
from pathlib import Path

import numpy as np

from . import prb_kernels as K
from . import tip_table_kernels as T
from .prb_calibration import user_cache

#: bump when the table or its kernels change: older cached tables are not used
VERSION = 17
#: nodes along rho (the chord's length), theta (from the axis, 3 deg apart) and phi (the
#: azimuth, -90 to 90 deg, 7.5 deg apart).  rho matters most: the chain is stiff along its
#: chord, and 33 layers of constant rho left a 1 mN side load's deflection 21 % short of the
#: chain's (the layers now follow the unloaded path, tip_table_kernels).  Against the chain's
#: own minimum at random tips 0.3-6 mm off the axis the load's median error is 0.06-0.6 %; with
#: (65, 41, 13) (2.4 times faster to build, 6 MB) 0.3-0.7 %, but the random episodes' per-tip
#: force error against `reference` rose from 34.1 % to 48.2 % (bench fidelity, 2026-11-27)
SHAPE = (65, 51, 25)
#: [rad] the largest angle of the chord from the bristle's axis in the table
THETA_MAX = math.radians(150.0)
#: the shortest chord in the table, as a fraction of the links' length
RHO_MIN = 0.3
#: the top of rho at most, below the links' full reach (where the chain is straight and the
#: elbow's angle undefined), as a fraction of it
RHO_TOP = 1.0 - 1e-6
#: of the rho layers, those above the unloaded path (the chain pulled straighter)
LAYERS_ABOVE = 12
#: the layers' spacing: u = ALPHA s + (1 - ALPHA) s^2 of the span for s uniform in [0, 1]
ALPHA = 0.1


def table_grid(joint, shape=SHAPE) -> np.ndarray:
    """The grid (``tip_table_kernels.GRID``, one record in a (1,) array) of the table of one
    joint record."""
    s0, l1, l2 = (float(v) for v in joint["geo"])
    L = l1 + l2
    g = np.zeros(1, T.GRID)
    # the top: just short of the full reach, where the elbow's angle is undefined (a chain bent
    # at rest, a leaning bristle's, gets there by straightening: a tip pushed against its rest
    # bend runs along its unloaded path to within 3e-4 mm of it; past the top the kernels hold
    # the tip with a stiff axial spring)
    g["rcap"] = RHO_TOP * L
    g["rmin"] = max(RHO_MIN * L, abs(l1 - l2) * 1.001)
    g["tmax"] = THETA_MAX
    g["nr"], g["nt"], g["np"] = shape
    g["nu"], g["alpha"] = LAYERS_ABOVE, ALPHA
    g["geo"] = (s0, l1, l2)
    return g


def table_key(joint, shape=SHAPE) -> str:
    """Content key of a joint record's table."""
    h = hashlib.sha256()
    h.update(
        repr((VERSION, tuple(shape), THETA_MAX, RHO_MIN, RHO_TOP, LAYERS_ABOVE, ALPHA)).encode()
    )
    h.update(np.ascontiguousarray(joint).tobytes())
    return h.hexdigest()[:20]


def build_table(joint, shape=SHAPE) -> T.Table:
    """The table (``tip_table_kernels.Table``: grid (1,), rnat (nt, np), vals (2, nr, nt, np)
    ENTRY32) of one joint record (``prb_kernels.JOINT``)."""
    rest = np.asarray(joint["rest"], float)
    if rest[1] != 0.0 or rest[3] != 0.0 or rest[4] != 0.0:
        # the table holds one half of the tips and mirrors the other (tip_table_kernels)
        raise ValueError(f"tip table: rest angles {rest.tolist()} turn b1, b2 or t (must be 0)")
    grid = table_grid(joint, shape)
    rnat = np.zeros(shape[1:])
    vals = np.zeros((2, *shape), T.ENTRY)
    T.build(T.Table(grid[0], rnat, vals), np.asarray(joint).reshape(1)[0])
    # the damping matrices from the joint angles as stored (single precision): a table's D is
    # then remade exactly from the table itself (tests/engine/test_tip_table.py)
    vals["q"] = vals["q"].astype(np.float32)
    T.grid_damping(T.Table(grid[0], rnat, vals), np.asarray(joint).reshape(1)[0])
    # stored in single precision (the forces to ~1e-7 of themselves) and without the Hessian
    # (``tip_table_kernels.ENTRY32``)
    out = np.zeros(vals.shape, T.ENTRY32)
    for name in T.ENTRY32.names:
        out[name] = vals[name]
    return T.Table(grid, rnat, out)


def _cache_dir() -> Path:
    return user_cache().parent / "tip_tables"


#: the tables of the brushes in configs/brushes, shipped with the package (``ship``: remade by
#: ``brush-env calibrate --all --ship``), so that a user of those brushes never builds one
SHIPPED = Path(__file__).with_name("tip_tables")


def load(path: Path, shape=SHAPE) -> T.Table | None:
    """The table stored at ``path``, or None (no file, or not a table of this version)."""
    try:
        with np.load(path) as z:
            tb = T.Table(z["grid"], z["rnat"], z["vals"])
    except (OSError, KeyError, ValueError):
        return None
    if tb.vals.dtype != T.ENTRY32 or tb.vals.shape != (2, *shape):
        return None
    return tb


def _save(tb: T.Table, path: Path, compressed: bool) -> None:
    """Store ``tb`` at ``path`` (written to a temporary file and renamed: a reader never sees
    half a table)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
    (np.savez_compressed if compressed else np.savez)(tmp, grid=tb.grid, rnat=tb.rnat, vals=tb.vals)
    os.replace(tmp, path)


def _places(joint, shape) -> tuple[Path, Path]:
    """Where the table of a joint record is looked for: shipped, then the user's cache."""
    name = f"{table_key(joint, shape)}.npz"
    return SHIPPED / name, _cache_dir() / name


def table(joint, shape=SHAPE) -> T.Table:
    """The table of a joint record: shipped, else from the user's cache, else built (~50-60 s
    on one core) and cached."""
    places = _places(joint, shape)
    for path in places:
        tb = load(path, shape)
        if tb is not None:
            return tb
    tb = build_table(joint, shape)
    _save(tb, places[1], compressed=False)
    return tb


def is_stored(joint, shape=SHAPE) -> bool:
    """Whether the table of a joint record is shipped or cached (``table`` needs no build)."""
    return any(path.is_file() for path in _places(joint, shape))


def ship(prm: np.ndarray) -> list[Path]:
    """Store the tables of the joint records ``prm`` (a brush's, ``prb.build_geometry``) in the
    package (``SHIPPED``, compressed: ~4.8 MB each); returns their paths."""
    out = []
    for j in distinct_joints(prm).values():
        path = _places(j, SHAPE)[0]
        if load(path) is None:
            _save(table(j), path, compressed=True)
        out.append(path)
    return out


def distinct_joints(prm: np.ndarray) -> dict[bytes, np.void]:
    """The distinct joint records of ``prm`` by their bytes, in order of first use."""
    out: dict[bytes, np.void] = {}
    for j in prm:
        out.setdefault(np.ascontiguousarray(j).tobytes(), j)
    return out


def tables_for(prm: np.ndarray) -> K.Tab:
    """The kernels' tables (``prb_kernels.Tab``) of every bristle of a brush (joints ``prm``).
    The tables themselves (~10.6 MB each) are shared by every model of the process with the same
    distinct joint records (``_stacked``): the kernels only read them, and N envs of one brush
    held N copies (N = 16: ~470 MB, and a kernel ~2x slower per env step than a single env's
    from the cache misses)."""
    joints = distinct_joints(prm)
    order = {kb: t for t, kb in enumerate(joints)}
    idx = np.array([order[np.ascontiguousarray(j).tobytes()] for j in prm], np.int64)
    grid, rnat, vals = _stacked(tuple(joints), list(joints.values()))
    return _tab(grid, rnat, vals, idx)


#: the stacked tables by their joint records' bytes (``tables_for``), shared within the process;
#: the last STACKS_KEPT distinct brushes' (a model holds its own arrays however long it lives)
_STACKS: OrderedDict[tuple[bytes, ...], tuple[np.ndarray, np.ndarray, np.ndarray]] = OrderedDict()
STACKS_KEPT = 4


def _stacked(records: tuple[bytes, ...], joints: list):
    """(grid, rnat, vals) of the tables of ``joints`` (their records' bytes ``records``), in
    order: built or loaded once (``table``), the same arrays for every model after that."""
    got = _STACKS.pop(records, None)
    if got is None:
        tables = [table(j) for j in joints]
        vals = _aligned((len(tables), *tables[0].vals.shape), tables[0].vals.dtype)
        for k, t in enumerate(tables):
            vals[k] = t.vals
        got = (np.concatenate([t.grid for t in tables]), np.stack([t.rnat for t in tables]), vals)
    _STACKS[records] = got  # the most recent last
    while len(_STACKS) > STACKS_KEPT:
        _STACKS.popitem(last=False)
    return got


#: [bytes] the stacked tables' entries start on a cache line: an entry is one line
#: (``tip_table_kernels.ENTRY32``), and numpy's large arrays start 16 bytes past a page
ALIGN = 64


def _aligned(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
    """An empty array of ``shape`` and ``dtype`` whose data start on an ALIGN-byte boundary."""
    n = int(np.prod(shape)) * dtype.itemsize
    raw = np.empty(n + ALIGN, np.uint8)
    off = -raw.ctypes.data % ALIGN
    return raw[off : off + n].view(dtype).reshape(shape)


def no_tables(nb: int) -> K.Tab:
    """A ``Tab`` that no bristle uses (the chain's own Newton for all)."""
    return _tab(
        np.zeros(1, T.GRID),
        np.zeros((1, 2, 2)),
        np.zeros((1, 2, 2, 2, 2), T.ENTRY32),
        np.full(nb, -1, np.int64),
    )


def _tab(grid, rnat, vals, idx) -> K.Tab:
    nb = len(idx)
    return K.Tab(
        grid,
        rnat,
        vals,
        idx,
        np.zeros(nb, np.int64),
        np.zeros(nb, np.int64),
        np.zeros((16, 3)),
        np.zeros((3, 3, 3)),
        np.zeros((6, 3)),
        np.zeros(5),
        np.zeros(nb + 1, np.int64),
        np.zeros(max(nb - 1, 1), np.int64),  # at most every other tip is a partner
    )
