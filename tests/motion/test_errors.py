"""Tests of bad input: errors name the parameter, the value and the allowed range."""

import numpy as np
import pytest

from brush_env.motion import (
    R0,
    Approach,
    Hold,
    MoveL,
    PitchPerturbation,
    Press,
    Sequence,
    movel_circle_deviation,
    paper_circle_movel,
    paper_circle_waypoints,
)

from .conftest import A, V, make_circle


@pytest.mark.parametrize(
    "build, match",
    [
        (lambda: make_circle(radius=0.0), r"radius = 0\.0 .*> 0 \(mm\)"),
        (lambda: make_circle(speed=-1.0), r"speed.*> 0"),
        (lambda: make_circle(accel=0), r"accel.*> 0"),
        (lambda: make_circle(turns=0), r"turns.*> 0"),
        (lambda: make_circle(normal=(0, 0, 0)), r"normal"),
        (lambda: make_circle(R=np.ones((3, 3))), r"R must be a rotation"),
        (lambda: make_circle(center=[1, 2]), r"center"),
        (lambda: Hold(([0, 0, 0], R0), 0.0), r"duration.*> 0"),
        (lambda: Press(([0, 0, 0], R0), float("nan"), 1.0), r"depth"),
        (lambda: Press(([0, 0, 0], R0), 1.0, -1.0), r"duration.*> 0"),
        (lambda: Press(([0, 0, 0], R0), 1.0, 1.0, profile="linear"), r"profile"),
        (lambda: Approach(([0, 0, 0], R0), ([1, 0, 0], R0), 0.0), r"duration.*> 0"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, A, -1.0), r"blend_radius = -1\.0 .*>= 0 \(mm\)"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], 0.0, A), r"speed.*> 0"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, float("inf")), r"accel.*> 0"),
        (lambda: MoveL([[0, 0, 0], [0, 0, 0]], V, A), r"non-zero length"),
        (lambda: MoveL([[0, 0], [1, 0]], V, A), r"waypoints"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, A).angle(0.0), r"center"),
        (lambda: MoveL([[0, 0, 0], [1, 0, 0]], V, A).path_points(1), r"n = 1 .*>= 2"),
        (lambda: PitchPerturbation(make_circle(), alpha_rad=3.0), r"alpha_rad"),
        (lambda: Sequence([]), r"segments"),
        (lambda: paper_circle_waypoints([0, 0, 0], -2.0), r"radius.*> 0"),
        (lambda: paper_circle_waypoints([0, 0, 0], 2.0, placement="x"), r"placement"),
        (lambda: movel_circle_deviation([0, 0, 0], 20.0, -1.0), r"blend_radius"),
        (lambda: paper_circle_movel([0, 0, 0], 20.0, V, A, turns=0), r"turns.*>= 1"),
        (lambda: make_circle().sample([[0.0, 1.0]]), r"times"),
    ],
)
def test_validation_errors(build, match):
    with pytest.raises(ValueError, match=match):
        build()
