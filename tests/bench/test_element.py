"""``bench element`` and the stored converged reference of the flat-plate turn (issue 11)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from brush_env import cli
from brush_env.bench.contact import simulate_contact
from brush_env.bench.element import (
    REFERENCE_FILE,
    REFERENCE_SETTINGS,
    errors_against,
    load_reference,
)


@pytest.fixture(scope="module")
def reference():
    return load_reference()


def test_stored_reference_is_the_converged_run(reference):
    """The file holds what REFERENCE_SETTINGS name (mid element, 24 bodies, 0.125 ms), over the
    whole motion (press 0.5 s + hold 0.25 s + one turn of the circle of radius 20 mm at 20 mm/s,
    whose 100 mm/s^2 ramps add v/a = 0.2 s)."""
    s = reference["settings"]
    for k, v in REFERENCE_SETTINGS.items():
        assert s[k] == v, k
    t, F = reference["t"], reference["F"]
    assert REFERENCE_FILE.stat().st_size < 500_000
    assert np.all(np.diff(t) > 0) and np.all(np.isfinite(F))
    assert reference["t_circle"] == pytest.approx(0.75)
    assert t[-1] == pytest.approx(0.75 + 2 * np.pi * 20.0 / 20.0 + 0.2, abs=0.01)
    # the held press: the brush pushes the plate down (Fz < 0 is the TCP's reaction convention)
    hold = (t > 0.6) & (t < 0.75)
    assert np.all(F[hold, 2] < -1.0)


def test_few_mid_bodies_match_the_converged_press(reference):
    """Pressed 3 mm and held (bristles buckled, tips sticking: the state validate buckling
    checks), 6 mid-element bodies at 1 ms stay within 1 % of the converged reference over the
    press and hold; the paper's element at 6 bodies does not (the element, not the step)."""
    t_end = reference["t_circle"]
    mine = simulate_contact(6, 1e-3, "bdf2", True, 0.5, 0.25, 0.0, element="mid")
    paper = simulate_contact(6, 1e-3, "bdf2", True, 0.5, 0.25, 0.0, element="paper")
    part = {k: v for k, v in reference.items()}
    keep = reference["t"] <= t_end + 1e-9
    part["t"], part["F"] = reference["t"][keep], reference["F"][keep]
    err_mid = errors_against(mine.t, mine.F, part, 0.0)[0]
    err_paper = errors_against(paper.t, paper.F, part, 0.0)[0]
    assert err_mid < 0.01, err_mid
    assert err_paper > 0.05, err_paper


def test_cli_bench_element_quick(capsys):
    assert cli.main(["bench", "element", "--quick", "--json"]) == 0
    rows = [json.loads(line) for line in capsys.readouterr().out.splitlines() if line.strip()]
    assert {r["element"] for r in rows} == {"paper", "mid"}
    assert all(r["status"] == "ok" for r in rows)


def test_break_away_events_quick(capsys):
    """``--events``: during the hold every tip sticks (no first slip before the circle starts at
    0.75 s); the drag then breaks every one of the 40 tips away, in groups, before 1.12 s."""
    assert cli.main(["bench", "element", "--events", "--quick", "--json"]) == 0
    (row,) = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert row["status"] == "ok" and row["bodies"] == 3
    times = [t for t, _ in row["groups"]]
    assert times == sorted(times) and times[0] > 750.0 and times[-1] < 1120.0
    assert sum(n for _, n in row["groups"]) == 40
    assert len(row["t"]) == len(row["F"]) and abs(row["t"][0] - 1.05) < 1e-9
