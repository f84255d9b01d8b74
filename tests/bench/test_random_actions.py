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


def test_the_level_is_the_one_asked_for(monkeypatch):
    """``--fidelity`` reaches ``gym.make`` (issue 32 asks its line of `balanced`), and the row
    names the level the env runs.  The env itself is made at the default level here: a run at
    another level would compile kernels that the warm-up does not, while ``bench compile``'s test
    (another xdist worker) checks that the engine's cache does not change."""
    import gymnasium as gym

    asked = {}
    make = gym.make

    def spy(env_id, **kw):
        asked.update(kw)
        kw.pop("fidelity", None)
        return make(env_id, **kw)

    monkeypatch.setattr(gym, "make", spy)
    row = random_run(0.001, 0, 1, "balanced")
    assert asked["fidelity"] == "balanced"
    assert row["fidelity"] == "fast"  # what the spy made: the env's default level
