"""``bench random``: the random-action env benchmark's rows and table (no timing asserted)."""

from __future__ import annotations

from brush_env.bench.random_actions import format_table, random_run


def test_same_seed_same_actions_and_the_table():
    """Two limits, one seed: the rows are complete and deterministic per seed (the same run
    twice gives the same peaks), and the table counts spikes against the smallest limit."""
    a = random_run(0.004, 0, 4)
    b = random_run(0.001, 0, 4)
    again = random_run(0.001, 0, 4)
    assert b["peaks"] == again["peaks"]  # same seed and actions: bit for bit
    for r in (a, b):
        assert r["steps"] == 4 and len(r["peaks"]) == 4
        assert r["divergences"] == 0 and r["peak_tip_force_N"] >= 0.0
        assert r["max_penetration_um"] >= 0.0
    fake = dict(b, max_substep=0.002, peaks=[2.0, 0.0, 0.0, 0.0], steps_above_1N=1)
    table = format_table([fake, b])
    assert table.count("\n") == 3
    assert "| 0.002 | 0 | 0 | 0 |" in table and "| 1 | 1 |" in table


def test_the_level_is_the_one_asked_for():
    """``--fidelity``: the run is made at that level (issue 32 asks its line of `balanced`), and
    the row says which.  (`reduced` here: its kernels are in the warm-up, so this test compiles
    nothing while ``bench compile``'s test checks that the engine's cache did not change.)"""
    assert random_run(0.001, 0, 1)["fidelity"] == "fast"  # the env's default
    assert random_run(0.001, 0, 1, "reduced")["fidelity"] == "reduced"
