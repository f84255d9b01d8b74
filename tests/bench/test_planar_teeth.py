"""``bench planar`` and ``bench teeth``: the commands' rows (no timing asserted).

bench planar: both cuts, every phase, the stability trials; a planar chain along a row cannot
buckle out of its plane, so the 3-D tips leave that plane and not the cross-row one.
bench teeth: both scenes ran, and every crown's grid stays inside the rigorous sqrt(3) h bound.
"""

from __future__ import annotations

import json

from brush_env import cli


def test_bench_planar_quick_rows(capsys):
    assert cli.main(["bench", "planar", "--quick", "--json", "--plot", ""]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    err = [r for r in rows if r["table"] == "error"]
    assert {(r["cut"], r["phase"]) for r in err} >= {("y", "press + hold"), ("x", "press + hold")}
    by = {(r["cut"], r["phase"]): r for r in err}
    assert by[("y", "press + hold")]["out_of_plane_max_mm"] < 1e-6
    speed = [r for r in rows if r["table"] == "speed"]
    assert {r["cut"] for r in speed} == {"x", "y"}
    for r in speed:
        assert any(t["ok"] for t in r["trials"]) and not all(t["ok"] for t in r["trials"])


def test_bench_teeth_quick_rows(capsys):
    assert cli.main(["bench", "teeth", "--quick", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    speed = [r for r in rows if r["table"] == "speed"]
    assert [r["scene"] for r in speed] == ["flat_plate", "tooth_row"]
    assert all(r["status"] == "ok" for r in speed)
    sdf = [r for r in rows if r["table"] == "sdf"]
    assert len(sdf) == 4
    assert all(r["band_max_err_mm"] <= r["bound_mm"] for r in sdf)
