"""``bench branch``: rows, agreement rule and table (no timing asserted)."""

from __future__ import annotations

import json

import pytest

from brush_env import cli
from brush_env.bench.branch import _agrees, format_branch_table


@pytest.mark.slow  # a bench CLI run (~4 s)
def test_quick_row_keeps_the_small_step_branch(capsys):
    """A 4 ms step (split into 1 ms solver steps by default) against the 1 ms run: the same
    hold force direction, and no jamming event in a third of a turn in either."""
    assert cli.main(["bench", "branch", "--quick", "--json"]) == 0
    (row,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert row["status"] == "ok" and row["max_substep"] == 1e-3
    assert row["agrees"], row["why"]
    assert (
        abs(row["ref_hold_F_N"][0]) > 0.1
    )  # the hold does push sideways: the sign means something


def test_agreement_rule():
    ref = {"status": "ok", "hold_F_N": [-1.0, 0.05], "jam_deg": {"9π/4": 54.0, "13π/4": 234.0}}
    same = {"status": "ok", "hold_F_N": [-0.9, -0.04], "jam_deg": {"9π/4": 57.0, "13π/4": 231.0}}
    assert _agrees(same, ref) == (True, "")  # Fy below 0.1 N carries no sign
    flipped = dict(same, hold_F_N=[0.2, 0.0])
    assert _agrees(flipped, ref)[1].startswith("hold Fx +0.20 N")
    late = dict(same, jam_deg={"9π/4": 64.0, "13π/4": 234.0})
    assert "9π/4 at 64.0" in _agrees(late, ref)[1]
    wrap = dict(same, jam_deg={"9π/4": 54.0, "13π/4": 234.0})
    assert _agrees(
        dict(wrap, jam_deg={"9π/4": 358.0, "13π/4": 234.0}),
        dict(ref, jam_deg={"9π/4": 2.0, "13π/4": 234.0}),
    )[0]
    missing = dict(same, jam_deg={"9π/4": None, "13π/4": 234.0})
    assert "missing" in _agrees(missing, ref)[1]
    row = dict(
        bodies=3,
        lean_deg=1.0,
        integrator="bdf2",
        dt=4e-3,
        max_substep=4e-3,
        hold_F_N=[0.2, 0.0],
        ref_hold_F_N=[-1.0, 0.05],
        jam_deg=same["jam_deg"],
        ref_jam_deg=ref["jam_deg"],
        agrees=False,
        why="hold Fx +0.20 N vs -1.00 N",
    )
    assert "**no**: hold Fx" in format_branch_table([row])
