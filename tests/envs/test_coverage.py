"""CoverageMap: cells cleaned along effective tip paths (geometry against hand counts)."""

import numpy as np
import pytest

from brush_env.coverage import CoverageMap


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
    cov.cleaned[:4, :4] = True  # the (-x, -y) quarter
    cov.count = 16
    assert np.array_equal(cov.coarse(), [[1.0, 0.0], [0.0, 0.0]])
    cov.reset()
    assert cov.count == 0 and not cov.cleaned.any()
