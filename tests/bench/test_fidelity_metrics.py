"""``bench.fidelity_metrics``: each measure on synthetic signals whose answer is known by
construction (no simulation, no timing)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from brush_env.bench import fidelity_metrics as fm

DT = 1e-3  # [s] the synthetic runs' step


def _steps(times_on: list[float], n: int = 1000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """t (n,) [s] and per-bristle flags: bristle i in contact throughout, sticking until
    ``times_on[i]`` [s] and sliding from then on."""
    t = DT * np.arange(1, n + 1)
    sliding = np.stack([t >= ton - 1e-12 for ton in times_on], axis=1)
    return t, sliding, np.ones_like(sliding)


def test_pooled_rms_error_is_relative_and_pools_pairs():
    ref = np.array([[3.0, 4.0], [0.0, 0.0]])
    assert fm.pooled_rms_error([(ref, ref)]) == 0.0
    assert fm.pooled_rms_error([(2 * ref, ref)]) == pytest.approx(1.0)
    # two pairs: sum of squares over both, not the mean of two ratios
    a, b = np.array([1.0]), np.array([10.0])
    e = fm.pooled_rms_error([(a + 1.0, a), (b, b)])
    assert e == pytest.approx(math.sqrt(1.0 / 101.0))
    assert math.isnan(fm.pooled_rms_error([(a, np.zeros(1))]))


def test_phase_means_of_a_piecewise_constant_signal():
    t = DT * np.arange(1, 1001)  # (0, 1] s
    Fz = np.where(t <= 0.5, 2.0, np.where(t <= 0.75, 3.0, 5.0))
    F = np.stack([np.zeros_like(t), np.zeros_like(t), -Fz], axis=1)  # |F| = Fz
    phases = {"press": (0.0, 0.5), "hold": (0.5, 0.75), "sliding": (0.75, 1.0)}
    m = fm.phase_means(t, F, phases)
    assert m == pytest.approx({"press": 2.0, "hold": 3.0, "sliding": 5.0})
    # the mean is of the magnitude: a rotating lateral force of 4 N over a 3 N normal -> 5 N
    ang = 2 * np.pi * t
    F2 = np.stack([4 * np.cos(ang), 4 * np.sin(ang), np.full_like(t, 3.0)], axis=1)
    assert fm.phase_means(t, F2, {"all": (0.0, 1.0)})["all"] == pytest.approx(5.0)
    err = fm.phase_mean_errors({"press": 2.2, "hold": 2.7}, {"press": 2.0, "hold": 3.0})
    assert err == pytest.approx({"press": 0.1, "hold": -0.1})
    assert math.isnan(fm.phase_means(t, F, {"none": (2.0, 3.0)})["none"])


def test_stick_slip_events_need_contact_at_both_samples():
    t, sliding, contact = _steps([0.2, 0.5], n=600)
    b, te, stick = fm.stick_slip_events(t, sliding, contact)
    assert b.tolist() == [0, 1] and te == pytest.approx([0.2, 0.5])
    assert stick == pytest.approx([0.2 - DT, 0.5 - DT])  # stuck from the first sample on
    # bristle 1 lands already sliding at 0.5 s (out of contact before): no stick->slip
    contact[:, 1] = t >= 0.5 - 1e-12
    b, te, _ = fm.stick_slip_events(t, sliding, contact)
    assert b.tolist() == [0]
    # slip -> stick -> slip again: two events of one bristle, sorted by time; the second
    # stuck from 0.301 s (the first sample of the stick) to 0.4 s
    s = sliding[:, :1].copy()
    s[(t > 0.3) & (t < 0.4), 0] = False
    b, te, stick = fm.stick_slip_events(t, s, np.ones_like(s))
    assert b.tolist() == [0, 0] and te == pytest.approx([0.2, 0.4])
    assert stick[1] == pytest.approx(0.4 - 0.301)


def test_a_flickering_flag_makes_no_counting_event():
    """Stick 100 ms, then the flag alternates every step for 20 steps, then slides: one event
    that counts (the first), 10 one-step flickers that do not."""
    t = DT * np.arange(1, 301)
    s = t > 0.1 + 1e-9
    flick = (t > 0.1 + 1e-9) & (t < 0.12 - 1e-9)
    s[flick] = (np.round(t[flick] / DT).astype(int) % 2) == 1
    s = s[:, None]
    raw = fm.stick_slip_events(t, s, np.ones_like(s))
    assert len(raw[0]) == 10
    b, te, stick = fm.long_stick_events(raw, min_stick=5e-3)
    assert te == pytest.approx([0.101]) and stick == pytest.approx([0.1])
    assert len(fm.long_stick_events(raw, min_stick=0.0)[0]) == 10


def test_event_time_error_of_an_8_ms_shift():
    """Two step signals 8 ms apart: every event is 8 ms late."""
    ton = [0.2, 0.31, 0.5]
    ref = fm.stick_slip_events(*_steps(ton))
    run = fm.stick_slip_events(*_steps([x + 8e-3 for x in ton]))
    m = fm.match_events(ref, run)
    assert m["median_abs_ms"] == pytest.approx(8.0)
    assert m["max_abs_ms"] == pytest.approx(8.0)
    assert m["median_ms"] == pytest.approx(8.0)  # late: positive
    assert (m["n_ref"], m["n_matched"], m["n_unmatched"], m["n_run"]) == (3, 3, 0, 3)


def test_event_matching_takes_the_same_bristle_and_counts_the_unmatched():
    ref = (np.array([0, 1, 2]), np.array([0.2, 0.2, 0.2]))
    # bristle 0: 3 ms early; bristle 1's only event is 150 ms late (beyond 100 ms: unmatched);
    # bristle 2 has none; bristle 3's event (no reference event) is not counted against any
    run = (np.array([0, 0, 1, 3]), np.array([0.197, 0.6, 0.35, 0.2]))
    m = fm.match_events(ref, run, max_dt=0.1)
    assert m["n_matched"] == 1 and m["n_unmatched"] == 2 and m["n_run"] == 4
    assert m["median_abs_ms"] == pytest.approx(3.0) and m["median_ms"] == pytest.approx(-3.0)
    none = fm.match_events(ref, (np.array([], int), np.array([])))
    assert none["n_unmatched"] == 3 and math.isnan(none["median_abs_ms"])


def test_rms_outside_the_events_leaves_the_shifted_transition_out():
    """A force step delayed by 8 ms: its whole RMS error lies within 10 ms of the reference's
    event, so outside the window the error is 0, and a 1 % level error elsewhere shows."""
    t = DT * np.arange(1, 1001)
    ref_F = np.stack([np.where(t < 0.5, 1.0, 2.0), np.zeros_like(t), np.zeros_like(t)], 1)
    run_F = np.stack([np.where(t < 0.508, 1.0, 2.0), np.zeros_like(t), np.zeros_like(t)], 1)
    grid = t[4::5]  # a 5 ms grid
    i = np.arange(4, 1000, 5)
    mask = fm.event_mask(grid, np.array([0.5]), 10e-3)
    assert grid[mask] == pytest.approx(np.arange(0.490, 0.5101, 0.005))
    assert fm.pooled_rms_error([(run_F[i], ref_F[i])]) > 0.01
    assert fm.rms_error_outside(run_F[i], ref_F[i], mask) == 0.0
    assert fm.rms_error_outside(1.01 * run_F[i], ref_F[i], mask) == pytest.approx(0.01)
    assert not fm.event_mask(grid, np.array([]), 10e-3).any()
    assert math.isnan(fm.rms_error_outside(run_F[i], ref_F[i], np.ones(len(i), bool)))


def test_event_mask_with_several_events():
    grid = np.arange(0.0, 1.0001, 0.01)
    mask = fm.event_mask(grid, np.array([0.8, 0.1, 0.5]), 0.02)
    expect = np.zeros(grid.shape, bool)
    for c in (0.1, 0.5, 0.8):
        expect |= np.abs(grid - c) <= 0.02 + 1e-9
    assert (mask == expect).all() and mask.sum() == 15


def test_buckling_sides_and_the_same_side_count():
    rest = np.zeros((4, 3))
    z = np.tile([0.0, 0.0, 1.0], (4, 1))
    tips = np.array([[0.3, 0.0, 0.2], [0.0, 0.0, -0.4], [0.0, 0.0, 0.001], [5.0, 0.0, 0.0]])
    off = fm.lateral_offsets(tips, rest, z)
    assert off == pytest.approx([0.2, -0.4, 0.001, 0.0])
    sides = fm.buckling_sides(off, tol=0.01)
    assert sides.tolist() == [1, -1, 0, 0]  # a motion along the axis is no side
    assert fm.same_side_count(sides, np.array([1, 1, 0, -1])) == 2


def test_coverage_difference_over_the_steps_both_reached():
    ref = {"F": np.ones((5, 3)), "fn": np.ones((5, 2)), "coverage": np.linspace(0, 0.5, 5)}
    short = {"F": np.ones((3, 3)), "fn": np.ones((3, 2)), "coverage": np.array([0, 0.1, 0.3])}
    f, t, dc = fm.compare_episodes([short], [ref])
    assert f == 0.0 and t == 0.0
    assert dc == pytest.approx(100 * abs(0.3 - 0.25))  # step 3 of both, in points


def test_on_grid_interpolates_a_4_ms_run_onto_5_ms():
    t = 4e-3 * np.arange(1, 11)
    Y = np.stack([t, 2 * t], axis=1)  # linear: interpolation is exact
    grid = 5e-3 * np.arange(1, 9)
    assert fm.on_grid(grid, t, Y) == pytest.approx(np.stack([grid, 2 * grid], axis=1))
    assert fm.on_grid(grid, t, t) == pytest.approx(grid)
