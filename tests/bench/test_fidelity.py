"""``bench fidelity``: its rows, error measures and the [measured] table it writes (no timing
asserted)."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest

from brush_env import cli
from brush_env.bench.fidelity import (
    PHASE_NAMES,
    batched_too_slow,
    load_reference_episodes,
    load_reference_turn,
    save_episodes,
    save_turn,
    turn_metrics,
    turn_summary,
    vector_steps_per_s,
    write_measured,
)
from brush_env.engine import load_fidelity


def test_quick_rows(capsys):
    assert cli.main(["bench", "fidelity", "--quick", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [r["level"] for r in rows] == ["balanced", "fast"]
    ref, fast = rows
    assert ref["turn_rms_force_error"] == 0.0 and ref["against"] == "balanced"
    assert fast["turn_status"] == "ok" and math.isfinite(fast["turn_rms_force_error"])
    # the tabulated tip law against 6 bodies in a buckled press: not the same forces
    assert fast["turn_rms_force_error"] > 0.01
    assert fast["env_steps"] == 3 and fast["env_steps_per_s"] > 0
    # the measures of issue 29 are there (the quick press has no stick-slip event)
    for k in PHASE_NAMES:
        assert math.isfinite(fast[f"turn_phase_mean_{k}_N"]) or k == "hold"  # no hold in quick
    assert fast["bristles"] == 40 and 0 <= fast["buckling_same_side"] <= 40
    assert 0 <= fast["lateral_force_same_side"] <= 40
    assert ref["buckling_same_side"] == 40 and ref["lateral_force_same_side"] == 40
    assert ref["turn_rms_error_outside_events"] == 0.0
    assert fast["events_ref"] == 0 and math.isnan(fast["event_dt_median_ms"])
    # --vec-sizes are not measured in --quick: they read "n/a" / "not measured"
    assert math.isnan(fast["env_steps_per_s_vec16"]) and "N=16" in fast["vec_note"]


@pytest.mark.filterwarnings("ignore::brush_env.engine.simulator.PenetrationWarning")
def test_batched_rate_is_measured_on_the_batched_env():
    """(c) on a short run: gym.make_vec(..., "vector_entry_point") at the reduced level, N = 4,
    three timed steps (a rate, no timing asserted)."""
    rate, note = vector_steps_per_s("reduced", 4, seconds=600.0, max_steps=3)
    assert math.isfinite(rate) and rate > 0, note
    assert note.startswith("3 steps of 4 envs in ")


def test_batched_rows_skip_levels_too_slow_to_measure():
    note = batched_too_slow(5.0, 64, 10.0)  # ~13 s per batched step of 64
    assert note.startswith("n/a (too slow:") and "5 env steps/s single" in note
    assert batched_too_slow(1000.0, 64, 10.0) == ""
    assert batched_too_slow(float("nan"), 16, 10.0).startswith("n/a (no single-env rate")


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
        event_dt_median_ms=3.5,
        buckling_same_side=38,
        env_steps_per_s_vec16=float("nan"),
    )
    for value in (0.12, 0.07):  # twice: the second write replaces the first table
        write_measured(p, dict(row, turn_rms_force_error=value), {"commit": "abc"})
    fid = load_fidelity(p)
    assert fid.measured["turn_rms_force_error"] == 0.07
    assert math.isnan(fid.measured["random_rms_force_error"])
    assert fid.measured["event_dt_median_ms"] == 3.5 and fid.measured["buckling_same_side"] == 38
    assert math.isnan(fid.measured["env_steps_per_s_vec16"])
    assert fid.bodies_per_bristle == load_fidelity("fast").bodies_per_bristle
    assert p.read_text().count("[measured]") == 1


def _synthetic_turn(delay: float = 0.0, scale: float = 1.0) -> dict:
    """A turn record of 2 tips on a 1 ms step: |F| 1 N in the press, 2 N in the hold, 3 N
    sliding; tip 0 slips at 0.8 s + delay, tip 1 at 0.9 s + delay, the force steps from 3 N to
    3.5 N at the first slip."""
    t = 1e-3 * np.arange(1, 1201)
    mag = np.where(t <= 0.5, 1.0, np.where(t <= 0.75, 2.0, 3.0))
    mag = np.where(t >= 0.8 + delay - 1e-12, 3.5, mag) * scale
    F = np.stack([np.zeros_like(t), np.zeros_like(t), mag], axis=1)
    sliding = np.stack([t >= 0.8 + delay - 1e-12, t >= 0.9 + delay - 1e-12], axis=1)
    phases = {"press": (0.0, 0.5), "hold": (0.5, 0.75), "sliding": (0.75, 1.2)}
    fn = np.stack([mag / 2, mag / 2], axis=1)
    off, lat = np.array([0.2, -0.3]), np.array([-0.03, 0.02])
    return turn_summary(t, F, fn, sliding, np.ones_like(sliding), off, lat, phases, 1.0, "ok")


def test_turn_metrics_of_a_delayed_copy():
    ref = _synthetic_turn()
    late = _synthetic_turn(delay=8e-3)
    m = turn_metrics(late, ref)
    assert m["event_dt_median_ms"] == pytest.approx(8.0)
    assert m["event_dt_max_ms"] == pytest.approx(8.0)
    assert m["events_ref"] == 2 and m["events_unmatched"] == 0
    assert m["turn_rms_force_error"] > 0.01 and m["turn_rms_error_outside_events"] == 0.0
    assert m["turn_phase_mean_hold_N"] == pytest.approx(2.0)
    assert m["turn_phase_err_press"] == 0.0 and m["buckling_same_side"] == 2
    assert m["lateral_force_same_side"] == 2
    louder = turn_metrics(_synthetic_turn(scale=1.02), ref)
    assert louder["turn_phase_err_hold"] == pytest.approx(0.02)
    assert louder["turn_rms_error_outside_events"] == pytest.approx(0.02)
    assert louder["turn_tip_force_error"] == pytest.approx(0.02)


def test_stored_turn_and_episodes_round_trip(tmp_path):
    run = _synthetic_turn()
    save_turn(tmp_path / "turn.npz", run, "reference", "synthetic")
    back = load_reference_turn(tmp_path / "turn.npz")
    assert back["meta"]["level"] == "reference"
    assert turn_metrics(back, run)["turn_rms_force_error"] == pytest.approx(0.0, abs=1e-7)
    assert back["events"][1] == pytest.approx(run["events"][1])
    eps = [
        {
            "F": np.ones((n, 3)),
            "fn": np.ones((n, 4)),
            "coverage": np.zeros(n),
            "wall_s": 2.0,
            "end": end,
        }
        for n, end in ((5, "steps"), (2, "force_limit"))
    ]
    p = tmp_path / "eps.npz"
    save_episodes(p, eps, "reference", "synthetic", steps=5)
    assert load_reference_episodes("balanced", 2, 5, p) is None  # another level
    assert load_reference_episodes("reference", 3, 5, p) is None  # more episodes than stored
    assert load_reference_episodes("reference", 2, 6, p) is None  # longer than stored
    got = load_reference_episodes("reference", 2, 4, p)
    assert [len(e["F"]) for e in got] == [4, 2]
    assert got[0]["wall_s"] == pytest.approx(2.0 * 4 / 5) and got[1]["end"] == "force_limit"


@pytest.mark.slow  # one 100-step random episode at `balanced` (~30 s)
def test_balanced_follows_the_reference_through_a_hard_random_episode():
    """Random-policy episode 1 of ``bench fidelity`` (the stored `reference` run: 24 bodies,
    0.125 ms) is the hardest of the 20 for the full chain: its tips stick, slip and lift off
    while tip-tip contacts come and go.  At `balanced` (6 bodies, 1 ms) the TCP force stays
    within 10 % RMS of the reference's -- issue 29's line for a fast model, here asked of the
    accurate one.  With 100 Newton iterations per attempt (``newton_max_iter``, `balanced`'s
    setting until 2026-11-28) it read 17.1 %: long attempts on stale factors wandered to other
    roots instead of halving the step as the small-step run does (docs/benchmarks.md, "Newton's
    iteration cap")."""
    from brush_env.bench.fidelity import episode_run
    from brush_env.bench.fidelity_metrics import pooled_rms_error

    ref = load_reference_episodes("reference", 20, 100)
    assert ref is not None, "tests/data holds the reference level's random episodes"
    run = episode_run("balanced", 1, 100)
    n = min(len(run["F"]), len(ref[1]["F"]))
    assert n == len(ref[1]["F"])  # ran as long as the reference did
    assert pooled_rms_error([(run["F"][:n], ref[1]["F"][:n])]) <= 0.10
