"""The engine's own record types for tests that call a kernel directly.

numba caches a kernel's machine code once per argument type, and its cache index pickles every
signature it holds: a namedtuple made in a test would be pickled by reference to the ``tests``
package, and any later process that loads that kernel's index without ``tests`` importable
(``brush-env`` run after the test suite) fails with ModuleNotFoundError.  Built from
``records.py``'s types, a test's call shares the engine's cached overloads instead.
"""

from __future__ import annotations

import numpy as np

from brush_env.engine import records as rec
from brush_env.engine.mesh_contact import empty_mesh
from brush_env.engine.sdf import empty_sdf


def contact_scene(tips, pair_ptr, pair_idx) -> rec.ContactScene:
    """A ``records.ContactScene`` with these tips (nb, 7: position [mm], velocity [mm/s],
    radius [mm]) and pair lists (CSR, int64), no surfaces, default tip arguments and states."""
    nb = tips.shape[0]
    args = np.zeros(nb, rec.TIP_ARGS)
    args["radius"] = tips[:, 6]
    return rec.ContactScene(
        np.zeros(0, rec.SURFACE),
        np.zeros(1, rec.CONTACT_LAW),
        np.ascontiguousarray(tips, dtype=float),
        np.ascontiguousarray(pair_ptr, dtype=np.int64),
        np.ascontiguousarray(pair_idx, dtype=np.int64),
        empty_mesh(),
        args,
        np.zeros(nb, rec.TIP_STATE),
        empty_sdf(),
        np.zeros(0, rec.SHAFT),
    )


def whole_lists(nb: int, npair: int, margin: float = -1.0) -> rec.NearPairs:
    """A ``records.NearPairs`` with no near list built (D = inf: every partner loop takes the
    whole list, as outside a step); ``margin`` [mm] for ``near.build``."""
    z = np.zeros(max(npair, 1), np.int64)
    return rec.NearPairs(
        np.zeros(nb + 1, np.int64),
        z,
        z.copy(),
        np.array([np.inf, margin]),
        np.full((nb, 3), np.nan),
    )


def sweeps_scratch(nb: int, npair: int) -> rec.Sweeps:
    """The sweeps' scratch (``records.Sweeps``) of a brush of nb one-body bristles with npair
    pair entries, no near lists."""
    return rec.make_work(1, nb, nb, npair).sw
