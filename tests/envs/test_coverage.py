"""CoverageMap: cells cleaned along effective tip paths (geometry against hand counts)."""

import numpy as np
import pytest

from brush_env.coverage import CoverageMap, EffectiveSweep


def _band(cov):
    rows = np.flatnonzero(cov.cleaned.any(axis=1))
    cols = np.flatnonzero(cov.cleaned.any(axis=0))
    return rows, cols


def test_point_with_zero_radius_cleans_its_cell():
    cov = CoverageMap(10.0, 1.0, 0.0, 2)
    assert cov.stamp(np.array([[0.3, -0.2]]), np.array([[0.3, -0.2]])) == 1
    assert cov.cleaned[4, 5]  # x = 0.3 -> column 5, y = -0.2 -> row 4 (rows along +y)
    assert cov.fraction == pytest.approx(0.01)


def test_straight_stroke_cleans_a_band_of_twice_the_radius():
    cov = CoverageMap(20.0, 0.5, 1.0, 4)
    new = cov.stamp(np.array([[-5.0, 0.1]]), np.array([[5.0, 0.1]]))
    rows, cols = _band(cov)
    # cell centres at y = +-0.25, +-0.75 lie within 1 mm of y = 0.1 (1.25 - 0.1 > 1: not -1.25)
    assert len(rows) == 4
    assert cols.min() * 0.5 - 10 == pytest.approx(-6.0) and (cols.max() + 1) * 0.5 - 10 == 6.0
    assert new == cov.count == cov.cleaned.sum()
    assert cov.stamp(np.array([[-5.0, 0.1]]), np.array([[5.0, 0.1]])) == 0  # already clean


def test_fast_segments_leave_no_gaps_and_outside_points_are_ignored():
    cov = CoverageMap(10.0, 0.5, 0.0, 1)
    cov.stamp(np.array([[-4.9, 0.0], [20.0, 20.0]]), np.array([[4.9, 0.0], [30.0, 30.0]]))
    row = cov.cleaned[10]
    assert row.all() and cov.count == 20


def test_coarse_map_is_block_fraction():
    cov = CoverageMap(8.0, 1.0, 0.0, 2)
    # the (-x, -y) quarter: one point in each of its 16 cells
    xy = np.array([(x, y) for x in (-3.5, -2.5, -1.5, -0.5) for y in (-3.5, -2.5, -1.5, -0.5)])
    assert cov.stamp(xy, xy) == 16
    assert cov.cleaned[:4, :4].all() and cov.count == 16
    assert np.array_equal(cov.coarse(), [[1.0, 0.0], [0.0, 0.0]])
    cov.reset()
    assert cov.count == 0 and not cov.cleaned.any() and not cov.coarse().any()


def test_coarse_map_counts_match_the_grid_on_uneven_blocks():
    """The per-block counts the stamps keep equal the cleaned cells summed over each block, for
    blocks of unequal size (13 cells in 3 blocks: 4, 5, 4)."""
    rng = np.random.default_rng(3)
    cov = CoverageMap(6.5, 0.5, 0.6, 3)
    for _ in range(20):
        cov.stamp(rng.uniform(-4, 4, (3, 2)), rng.uniform(-4, 4, (3, 2)))
        e = cov._edges
        rows = [cov.cleaned[e[i] : e[i + 1]] for i in range(3)]
        sums = np.array([[r[:, e[j] : e[j + 1]].sum() for j in range(3)] for r in rows])
        area = np.diff(e)[:, None] * np.diff(e)[None, :]
        assert np.array_equal(cov.coarse(), sums / area)
    assert cov.count == cov.cleaned.sum()


def test_sweep_is_segments_many_stamped():
    """``CoverageMap.sweep`` (one compiled pass) cleans the same cells as the effective tips'
    segments (``EffectiveSweep.segments_many``) stamped, and moves the sweep's state alike, over
    several calls (a tip effective across a call's boundary sweeps from its last point)."""
    rng = np.random.default_rng(7)
    window = (0.01, 0.2)
    a, b = CoverageMap(20.0, 0.5, 0.5, 4), CoverageMap(20.0, 0.5, 0.5, 4)
    sa, sb = EffectiveSweep(6, window), EffectiveSweep(6, window)
    for _ in range(8):
        n = int(rng.integers(1, 12))
        f = np.where(rng.random((n, 6)) < 0.3, 0.0, rng.uniform(0.0, 0.3, (n, 6)))
        cp = np.cumsum(rng.normal(0.0, 0.7, (n, 6, 3)), axis=0)
        starts, ends = sa.segments_many(f, cp, f > 0.0)
        new_a = a.stamp(starts, ends)
        new_b = b.sweep(sb, f, cp)
        assert new_a == new_b
        assert np.array_equal(a.cleaned, b.cleaned) and np.array_equal(a.coarse(), b.coarse())
        assert np.array_equal(sa.prev_eff, sb.prev_eff) and np.array_equal(sa.prev_cp, sb.prev_cp)
    assert a.count == b.count > 0
