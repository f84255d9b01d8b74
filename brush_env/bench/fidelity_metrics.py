"""The error measures of ``bench fidelity`` (issue 29, item 5: metrics that separate timing from
level), as plain functions of sampled signals.  Nothing here runs a simulation.

Notation: a run's TCP force ``F(t)`` [N] (world frame, (n, 3)) and its tips' normal forces
``f_i(t)`` [N], sampled on a grid of times ``t`` [s]; ``ref`` marks the reference run's.

**Pooled relative RMS error** (``pooled_rms_error``)::

    e = sqrt( sum |x - x_ref|^2 / sum |x_ref|^2 )        [-]

summed over every sample (and every component / tip) of every (x, x_ref) pair.  The TCP-force
error of the turn is this over the 5 ms grid, the per-tip normal-force error the same over the
grid and the 40 tips (f_i against f_i,ref, pooled: a tip's error counts in proportion to the
reference's force scale, not per tip).

**Phase means** (``phase_means``): the mean of ``|F(t)|`` [N] over the samples whose time lies in
each phase's half-open window ``(start, end]`` -- for the paper's turn ``press`` = (0, 0.5] s,
``hold`` = (0.5, 0.75] s and ``sliding`` = (0.75 s, end] (the circle, ramps included).  Its
error (``phase_mean_errors``) is signed and relative, ``(m - m_ref) / m_ref`` [-], per phase.

**Stick-slip events** (``stick_slip_events``, ``long_stick_events``): a tip's stick->slip
transition is a sample ``k`` at which its ``tip_sliding`` flag goes False -> True while the tip
is in contact at both samples ``k-1`` and ``k`` (a tip that lands already sliding, or slides off
into the air, makes no event); its time is ``t[k]`` [s], the end of the first sliding step, and
its stick duration ``t[k] - t[j]`` [s], ``j`` the first sample of the unbroken stick (in
contact, not sliding) that ends at ``k-1``.  Events are taken at the resolution the run was
stepped at (every solver step, not the 5 ms grid).  An event *counts* when its stick lasted at
least ``MIN_STICK`` = 5 ms: at a stick-slip boundary the flag can flicker, stick one step and
slide the next (the reference turn at 0.125 ms steps has 627 transitions, 530 of them in the
0.25 s of the break-away, most 0.25 ms apart on one bristle); 5 ms, the comparison grid, is
longer than one step at every level (0.125-4 ms), so a flicker is left out at every level alike.

**RMS outside the events** (``rms_error_outside``, ``event_mask``): the pooled relative RMS
TCP-force error over the grid samples farther than ``half_width`` (10 ms) from every one of the
reference's counting stick->slip events (of any bristle): ``|t_k - t_ev| > half_width`` for all
events.  It is the level's force error with the timing of the transitions taken out (issue 11:
a chain whose break-away comes 8.5 ms late reads 5 % RMS while agreeing within 1-2 %
elsewhere).

**Event-time error** (``match_events``): each counting reference event (bristle b, time t_ref)
is matched to the same bristle's counting event in the level's run nearest in time,
``dt = t_run - t_ref``; a reference event with no event of its bristle within ``max_dt``
(default 100 ms) is *unmatched* (and not in the statistics).  Reported: the median and the
largest ``|dt|`` [ms] over the matched events, and the counts (reference events, matched,
unmatched, and the run's own events).

**Buckling side** (``lateral_offsets``, ``buckling_sides``, ``same_side_count``): at the end of
the hold (the last sample at or before 0.75 s) each tip's lateral offset ``d_i = (p_i -
p_i,rest) . z_i`` [mm], where ``p_i`` is the tip node, ``p_i,rest`` where the straight unloaded
bristle's tip would be at the TCP's current pose (root + length along the bristle axis, moved
with the TCP) and ``z_i`` the bristle's thickness direction (the root frame's local z,
``tcp_R @ model.root_R[i, :, 2]``, the direction the lean tilts the tip toward).  Its side is
``sign(d_i)``, or 0 if ``|d_i| < tol`` (0.01 mm: not bent out of line).  ``same_side_count`` is
the number of bristles whose side equals the reference's (0 = 0 counts as the same).

A tip that sticks through the hold keeps the offset it slid to during the press (on the default
brush 0.04-0.08 mm, the lean's way, at every level), so the offset's side says where the tip
went, not which way the bristle bowed.  The bench therefore also counts the bristles whose
**lateral tip force** has the reference's side: ``sign(t_i . z_i)`` of the tip's tangential
(friction) force ``t_i`` [N] at the same instant, 0 if below ``SIDE_FORCE_TOL`` (1 mN) -- the
friction that holds a stuck tip balances the bent bristle's lateral push, whose sign follows the
bristle's bent shape (the two groups of the default brush push -38 and -29 mN at ``balanced``;
at the reduced ``fast`` of 5958706 the outer group pushes +11 mN).

**Coverage difference** (``compare_episodes``): over random-policy episodes with the same seeds
and actions, ``mean_e |c_e - c_e,ref|`` in points of the patch [0-100], with ``c`` the coverage
fraction at the last step both runs of episode ``e`` reached; the TCP-force and per-tip
normal-force errors of the episodes are ``pooled_rms_error`` over the same steps.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping

import numpy as np

#: [s] an event counts when its tip stuck at least this long before it slipped
MIN_STICK = 5e-3
#: [s] half-width of the window around each reference stick->slip event left out of the RMS
EVENT_HALF_WIDTH = 10e-3
#: [s] a reference event with no event of the same bristle this close in the run is unmatched
MATCH_MAX_DT = 100e-3
#: [mm] a tip offset smaller than this from its straight position has no buckling side (0)
SIDE_TOL = 0.01
#: [N] a lateral tip force smaller than this has no side (0)
SIDE_FORCE_TOL = 1e-3


def pooled_rms_error(pairs: Iterable[tuple[np.ndarray, np.ndarray]]) -> float:
    """``sqrt(sum |x - x_ref|^2 / sum |x_ref|^2)`` [-] over (x, x_ref) pairs of equal shape
    (NaN if the reference is all zero)."""
    num = den = 0.0
    for x, r in pairs:
        num += float(np.sum((np.asarray(x) - np.asarray(r)) ** 2))
        den += float(np.sum(np.asarray(r) ** 2))
    return math.sqrt(num / den) if den > 0 else math.nan


def on_grid(grid: np.ndarray, t: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """``Y`` (sampled at increasing times ``t`` [s], shape (n,) or (n, m)) linearly interpolated
    onto the times ``grid`` [s] (held constant beyond the ends)."""
    Y = np.asarray(Y, float)
    if Y.ndim == 1:
        return np.interp(grid, t, Y)
    return np.stack([np.interp(grid, t, Y[:, c]) for c in range(Y.shape[1])], axis=1)


def phase_means(
    t: np.ndarray, F: np.ndarray, phases: Mapping[str, tuple[float, float]]
) -> dict[str, float]:
    """Per phase name, the mean of ``|F|`` [N] over the samples with ``start < t <= end``
    (``phases``: name -> (start, end) [s]; ``F`` (n, 3) [N] or (n,) [N]); NaN for an empty
    phase."""
    t = np.asarray(t, float)
    F = np.asarray(F, float)
    mag = np.linalg.norm(F, axis=1) if F.ndim == 2 else np.abs(F)
    out = {}
    eps = 1e-9
    for name, (a, b) in phases.items():
        sel = (t > a + eps) & (t <= b + eps)
        out[name] = float(mag[sel].mean()) if sel.any() else math.nan
    return out


def phase_mean_errors(means: Mapping[str, float], ref: Mapping[str, float]) -> dict[str, float]:
    """Signed relative error ``(m - m_ref) / m_ref`` [-] per phase of ``ref``."""
    return {k: (means[k] - r) / r if (r and math.isfinite(r)) else math.nan for k, r in ref.items()}


def stick_slip_events(
    t: np.ndarray, sliding: np.ndarray, in_contact: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stick->slip events (module docstring) of a run sampled at times ``t`` [s] (n,) with
    per-tip flags ``sliding`` and ``in_contact`` (n, nb) bool.  Returns (bristle indices, event
    times [s], stick durations [s]), sorted by time, then bristle; an event's stick duration is
    ``t[k] - t[j]`` with ``j`` the first sample of the unbroken stick (in contact, not sliding)
    that ends at ``k - 1``."""
    s = np.asarray(sliding, bool)
    c = np.asarray(in_contact, bool)
    t = np.asarray(t, float)
    stuck = c & ~s
    hit = stuck[:-1] & s[1:] & c[1:]
    k, b = np.nonzero(hit)
    # first sample of each stick spell: one past the last sample that was not stuck
    idx = np.arange(len(t))[:, None]
    start = np.maximum.accumulate(np.where(stuck, -1, idx), axis=0) + 1
    times = t[k + 1]
    stick = times - t[start[k, b]] if k.size else np.zeros(0)
    order = np.lexsort((b, times))
    return b[order].astype(np.int64), times[order], stick[order]


def long_stick_events(
    events: tuple[np.ndarray, np.ndarray, np.ndarray], min_stick: float = MIN_STICK
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The events of ``stick_slip_events`` whose tip stuck for at least ``min_stick`` [s]
    before it slipped (the rest: a flag flickering at the stick-slip boundary)."""
    b, t, stick = events
    keep = np.asarray(stick) >= min_stick - 1e-12
    return np.asarray(b)[keep], np.asarray(t)[keep], np.asarray(stick)[keep]


def event_mask(grid: np.ndarray, event_times: np.ndarray, half_width: float) -> np.ndarray:
    """Bool (len(grid),): True where a grid time [s] lies within ``half_width`` [s] (inclusive)
    of any of ``event_times`` [s]."""
    grid = np.asarray(grid, float)
    ev = np.sort(np.asarray(event_times, float))
    if ev.size == 0:
        return np.zeros(grid.shape, bool)
    j = np.searchsorted(ev, grid)
    lo = ev[np.clip(j - 1, 0, ev.size - 1)]
    hi = ev[np.clip(j, 0, ev.size - 1)]
    near = np.minimum(np.abs(grid - lo), np.abs(grid - hi))
    return near <= half_width + 1e-12


def rms_error_outside(F: np.ndarray, F_ref: np.ndarray, masked: np.ndarray) -> float:
    """``pooled_rms_error`` [-] of ``F`` against ``F_ref`` (same grid, (n, 3)) over the samples
    where ``masked`` is False (NaN if none is left)."""
    keep = ~np.asarray(masked, bool)
    if not keep.any():
        return math.nan
    return pooled_rms_error([(np.asarray(F)[keep], np.asarray(F_ref)[keep])])


def match_events(
    ref_events: tuple[np.ndarray, ...],
    run_events: tuple[np.ndarray, ...],
    max_dt: float = MATCH_MAX_DT,
) -> dict:
    """Event-time error (module docstring).  ``*_events``: (bristle indices, times [s], ...) as
    ``stick_slip_events`` returns.  Returns ``median_abs_ms``, ``max_abs_ms`` [ms] (NaN if none
    matched), ``median_ms`` [ms] (signed: > 0 the run is late), ``n_ref``, ``n_matched``,
    ``n_unmatched``, ``n_run`` and ``dt_ms`` (the matched signed differences [ms])."""
    rb, rt = (np.asarray(a) for a in ref_events[:2])
    qb, qt = (np.asarray(a) for a in run_events[:2])
    dts = []
    for b, t0 in zip(rb, rt):
        mine = qt[qb == b]
        if mine.size == 0:
            continue
        d = mine[np.argmin(np.abs(mine - t0))] - t0
        if abs(d) <= max_dt + 1e-12:
            dts.append(1e3 * float(d))
    d = np.array(dts)
    return {
        "median_abs_ms": float(np.median(np.abs(d))) if d.size else math.nan,
        "max_abs_ms": float(np.max(np.abs(d))) if d.size else math.nan,
        "median_ms": float(np.median(d)) if d.size else math.nan,
        "n_ref": int(rb.size),
        "n_matched": int(d.size),
        "n_unmatched": int(rb.size - d.size),
        "n_run": int(qb.size),
        "dt_ms": d,
    }


def lateral_offsets(
    tip_pos: np.ndarray, rest_tip_world: np.ndarray, lateral_dir: np.ndarray
) -> np.ndarray:
    """(nb,) [mm]: ``(tip_pos - rest_tip_world) . lateral_dir`` per tip (all (nb, 3); positions
    [mm], directions unit vectors)."""
    return components_along(np.asarray(tip_pos) - np.asarray(rest_tip_world), lateral_dir)


def components_along(v: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """(nb,): each row of ``v`` (nb, 3) (any unit) dotted with its unit ``directions`` row."""
    return np.einsum("ij,ij->i", np.asarray(v, float), np.asarray(directions, float))


def buckling_sides(offsets: np.ndarray, tol: float = SIDE_TOL) -> np.ndarray:
    """(nb,) int: +1 / -1 the sign of each lateral offset [mm], 0 where ``|offset| < tol``
    [mm]."""
    o = np.asarray(offsets, float)
    return np.where(np.abs(o) < tol, 0, np.sign(o)).astype(np.int64)


def same_side_count(sides: np.ndarray, ref_sides: np.ndarray) -> int:
    """Number of bristles whose buckling side equals the reference's."""
    return int(np.sum(np.asarray(sides) == np.asarray(ref_sides)))


def compare_episodes(eps: list, refs: list) -> tuple[float, float, float]:
    """(TCP-force error [-], tip normal-force error [-], mean |coverage difference| [points]) of
    random-policy episodes against the reference's with the same seeds: each pair over the steps
    both reached (``F`` (n, 3) [N], ``fn`` (n, nb) [N], ``coverage`` (n,) [0-1] per env step)."""
    pf, pt, dc = [], [], []
    for e, r in zip(eps, refs):
        n = min(len(e["F"]), len(r["F"]))
        if n == 0:
            continue
        pf.append((e["F"][:n], r["F"][:n]))
        pt.append((e["fn"][:n], r["fn"][:n]))
        dc.append(100.0 * abs(e["coverage"][n - 1] - r["coverage"][n - 1]))
    return pooled_rms_error(pf), pooled_rms_error(pt), float(np.mean(dc)) if dc else math.nan
