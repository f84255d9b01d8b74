"""``bench fidelity``: its rows, error measures and the [measured] table it writes (no timing
asserted)."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from brush_env import cli
from brush_env.bench.fidelity import _pooled_error, compare_episodes, write_measured
from brush_env.engine import load_fidelity


def test_quick_rows(capsys):
    assert cli.main(["bench", "fidelity", "--quick", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["level"] for r in rows] == ["balanced", "fast"]
    ref, fast = rows
    assert ref["turn_rms_force_error"] == 0.0 and ref["against"] == "balanced"
    assert fast["turn_status"] == "ok" and math.isfinite(fast["turn_rms_force_error"])
    # 3 bodies against 6 in a buckled press: not the same forces (bench element: ~10 %)
    assert fast["turn_rms_force_error"] > 0.01
    assert fast["env_steps"] == 3 and fast["env_steps_per_s"] > 0


def test_pooled_error_is_relative_rms():
    ref = np.array([[3.0, 4.0], [0.0, 0.0]])
    assert _pooled_error([(ref, ref)]) == 0.0
    assert _pooled_error([(2 * ref, ref)]) == pytest.approx(1.0)


def test_episodes_compared_over_the_steps_both_reached():
    ref = {"F": np.ones((5, 3)), "fn": np.ones((5, 2)), "coverage": np.linspace(0, 0.5, 5)}
    short = {"F": np.ones((3, 3)), "fn": np.ones((3, 2)), "coverage": np.array([0, 0.1, 0.3])}
    f, t, dc = compare_episodes([short], [ref])
    assert f == 0.0 and t == 0.0
    assert dc == pytest.approx(100 * abs(0.3 - 0.25))  # step 3 of both, in points


def test_write_measured_keeps_the_settings_and_replaces_the_table(tmp_path):
    p = tmp_path / "fast.toml"
    shutil.copy(load_fidelity("fast").path, p)
    row = dict(
        against="reference",
        turn_rms_force_error=0.12,
        turn_tip_force_error=0.3,
        turn_wall_per_sim_s=1.1,
        random_rms_force_error=float("nan"),
        random_tip_force_error=0.2,
        random_coverage_diff_points=0.5,
        env_steps_per_s=20.0,
    )
    for value in (0.12, 0.07):  # twice: the second write replaces the first table
        write_measured(p, dict(row, turn_rms_force_error=value), {"commit": "abc"})
    fid = load_fidelity(p)
    assert fid.measured["turn_rms_force_error"] == 0.07
    assert math.isnan(fid.measured["random_rms_force_error"])
    assert fid.bodies_per_bristle == load_fidelity("fast").bodies_per_bristle
    assert p.read_text().count("[measured]") == 1
