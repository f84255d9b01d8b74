"""Tests of eq 10 cubic step (motion.profiles)."""

import numpy as np
import pytest

from brush_env.motion import smoothstep, smoothstep_dot


def test_smoothstep_values_and_vectorised():
    assert smoothstep(-1.0, 0.0, 2.0, 1.0, 5.0) == 2.0
    assert smoothstep(2.0, 0.0, 2.0, 1.0, 5.0) == 5.0
    assert smoothstep(0.5, 0.0, 2.0, 1.0, 5.0) == pytest.approx(3.5)
    x = np.linspace(-1, 2, 31)
    y = smoothstep(x, 0.0, 0.0, 1.0, 1.0)
    assert y.shape == x.shape
    u = np.clip(x, 0, 1)
    np.testing.assert_allclose(y, 3 * u**2 - 2 * u**3)
    assert np.all(np.diff(y) >= 0)


def test_smoothstep_dot_matches_finite_difference():
    x = np.linspace(-0.5, 2.5, 301)
    e = 1e-6
    num = (smoothstep(x + e, 0.2, -1.0, 2.0, 3.0) - smoothstep(x - e, 0.2, -1.0, 2.0, 3.0)) / (
        2 * e
    )
    # at x0, x1 the second derivative jumps: central differences are off by O(e) there
    np.testing.assert_allclose(smoothstep_dot(x, 0.2, -1.0, 2.0, 3.0), num, atol=1e-5)
    assert smoothstep_dot(0.2, 0.2, -1.0, 2.0, 3.0) == 0.0
    assert smoothstep_dot(2.0, 0.2, -1.0, 2.0, 3.0) == 0.0


def test_smoothstep_reversed_interval_and_error():
    # x1 < x0: mirrored step, h1 at the low side
    assert smoothstep(-1.0, 1.0, 0.0, 0.0, 1.0) == 1.0
    assert smoothstep(2.0, 1.0, 0.0, 0.0, 1.0) == 0.0
    with pytest.raises(ValueError, match="x1"):
        smoothstep(0.3, 1.0, 0.0, 1.0, 1.0)
