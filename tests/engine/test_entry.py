"""engine/entry.py: a compiled kernel's entry point gives the dispatcher's results for the same
argument types, and none for types the kernel was never compiled for."""

from collections import namedtuple

import numpy as np
from numba import njit

from brush_env.engine.entry import entry_point

Pair = namedtuple("Pair", ["a", "b"])


@njit(cache=False, fastmath=False)
def _axpy(p, x, out):
    for i in range(out.shape[0]):
        out[i] = p.a[i] * x + p.b[i]
    return out.sum()


def test_entry_point_gives_the_dispatchers_result_for_the_same_types():
    p = Pair(np.arange(4.0), np.ones(4))
    out1, out2 = np.zeros(4), np.zeros(4)
    assert entry_point(_axpy, (p, 2.0, out1)) is None  # never compiled for these types
    r1 = _axpy(p, 2.0, out1)
    call = entry_point(_axpy, (p, 2.0, out2))
    assert call is not None
    q = Pair(np.arange(4.0) + 1.0, np.full(4, 3.0))  # other arrays of the same types
    r2 = call(q, 0.5, out2)
    assert r1 == 2.0 * 6.0 + 4.0
    assert np.array_equal(out2, q.a * 0.5 + q.b) and r2 == float((q.a * 0.5 + q.b).sum())
    assert np.array_equal(out1, p.a * 2.0 + p.b)


def test_entry_point_is_none_for_other_argument_types():
    p = Pair(np.arange(4.0), np.ones(4))
    _axpy(p, 2.0, np.zeros(4))
    p32 = Pair(np.arange(4.0, dtype=np.float32), np.ones(4, dtype=np.float32))
    assert entry_point(_axpy, (p32, 2.0, np.zeros(4))) is None
    assert entry_point(_axpy, (p, 2.0, np.zeros((4, 1)))) is None
