"""``bench coupled``: its comparison against the 0.125 ms reference, on signals written here
(the measures are fidelity_metrics', tested in test_fidelity_metrics.py)."""

from __future__ import annotations

import numpy as np
import pytest

from brush_env.bench.coupled import compare


def _run(scale=1.0, slip_at=1.0):
    """A 2 s run of 2 tips on a 1 ms grid: |F| = 1 + t [N], scaled; tip 0 sticks from 0.6 s and
    slips at ``slip_at`` [s]; tip 1 slides throughout."""
    t = np.arange(0, 2001) * 1e-3
    F = np.zeros((t.size, 3))
    F[:, 2] = scale * (1.0 + t)
    sl = np.ones((t.size, 2), bool)
    sl[(t >= 0.6) & (t < slip_at), 0] = False
    return {
        "t": t,
        "F": F,
        "event_t": t,
        "sliding": sl,
        "in_contact": np.ones_like(sl),
        "status": "ok",
    }


def test_a_run_equal_to_its_reference_has_no_error():
    r = compare(_run(), _run())
    assert r["rms"] == 0.0 and r["rms_outside_events"] == 0.0
    assert (r["events_matched"], r["events_ref"], r["event_max_ms"]) == (1, 1, 0.0)


def test_a_force_one_percent_high_and_a_late_slip():
    """1 % more force everywhere: 1 % RMS and +1 % in every phase; the slip 8 ms late: one
    matched event 8 ms off."""
    r = compare(_run(scale=1.01, slip_at=1.008), _run())
    assert r["rms"] == pytest.approx(0.01, rel=1e-9)
    for phase in ("phase_press", "phase_hold", "phase_sliding"):
        assert r[phase] == pytest.approx(0.01, rel=1e-9)
    assert r["event_median_ms"] == pytest.approx(8.0, abs=1e-6)


def test_a_diverged_run_has_no_errors_but_its_status():
    run = _run() | {"status": "diverged at t=1 s"}
    assert compare(run, _run()) == {"status": "diverged at t=1 s"}


def test_an_ensemble_summary_averages_the_finished_members_only():
    """Three members compared against one reference, 0 %, 2 % and 4 % high, and one that
    diverged: the summary's RMS is their mean (2 %) with range [0, 4] %, over 3 of 4 runs."""
    from brush_env.bench.coupled import ensemble_summary

    ref = _run()
    members = []
    for scale in (1.0, 1.02, 1.04):
        members.append({"bodies": 6, "dt": 1e-3, "sweeps": 8, "tol": 1e-6, "status": "ok"})
        members[-1] |= compare(_run(scale=scale), ref) | {"cpu_s": 2.0 * scale}
    members.append(members[0] | {"status": "diverged at t=1 s", "rms": 9.0})
    s = ensemble_summary(members)
    assert (s["ensemble"], s["finished"]) == (4, 3)
    assert s["rms"] == pytest.approx(0.02, rel=1e-9)
    assert (s["rms_min"], s["rms_max"]) == (0.0, pytest.approx(0.04, rel=1e-9))
    assert s["cpu_s"] == pytest.approx(2.04, rel=1e-12)
