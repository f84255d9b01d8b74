"""The paper's circular reference experiment end to end: ``brush-env reference``.

Cirelli et al., Machines 2023, §3-§5: the brush starts with its tips touching a flat plate, is
pressed 3 mm along the bristle axis, then the robot drives it four times round a 20 mm circle
built, as on the UR5, from four MoveL control points with blend radius = circle radius
(Algorithm 1, Figure 6).  The forces at the TCP are reported against the rotation angle θ (0 at
the start point P0; the first quarter P0 -> P1 is excluded from the analysis; turns 2-4 are θ in
[2π, 8π]) and show two jamming peaks per turn (the paper: near 9π/4 and 13π/4).  With
``--pitch-error`` the run is repeated with the 1° pitch perturbation of eq 12 (§5.2, Figure 10) and
the asymmetry it introduces is quantified.

Library entry point: ``run_reference(...) -> summary dict``; CLI: ``add_arguments`` / ``run`` (wired
into ``brush_env.cli``).  Analysis helpers: ``detect_peaks`` (peaks of a signal against the rotation
angle), ``jamming_analysis``, ``per_turn_stats``, ``repeatability``, ``pitch_asymmetry``.

This module sits at the edge of the package: it uses matplotlib (Agg) and tqdm and is never imported
by the engine.  Units: mm, N, N·mm, s, rad.  See docs/reference_experiment.md.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from dataclasses import replace
from fractions import Fraction
from pathlib import Path

import numpy as np

from .engine import SimSettings, SimulationDivergence, Simulator, load_brush, load_scene
from .engine.config import BrushConfig
from .engine.scene import Plane
from .motion import (
    BLEND_RULE,
    R0,
    Circle,
    Hold,
    PitchPerturbation,
    Press,
    Sequence,
    movel_circle_deviation,
    paper_circle_movel,
)

TWO_PI = 2.0 * math.pi

#: The paper's jamming angles (§5.1): 9π/4 and 13π/4, i.e. π/4 and 5π/4 modulo 2π.
PAPER_JAMMING_ANGLES = (9.0 * math.pi / 4.0, 13.0 * math.pi / 4.0)

#: Defaults of the reference scenario (documented in docs/reference_experiment.md).
DEFAULTS = dict(
    turns=4.0,  # paper §4: four complete rotations
    radius=20.0,  # paper §5.1: 20 mm circle [mm]
    speed=20.0,  # tool speed [mm/s] (not printed in the paper)
    accel=100.0,  # tool acceleration [mm/s^2] (not printed; ramp 0.2 s / 2 mm, inside P0 -> P1)
    press_depth=3.0,  # paper §3: 3 mm along the bristle axis [mm]
    press_time=0.5,  # [s] minimum-jerk press (peak speed 11.25 mm/s)
    hold_time=0.25,  # [s] settling after the press
    dt=1e-3,  # [s]
    integrator="bdf2",
    path="movel",  # "movel" (paper Algorithm 1) or "circle" (exact circle)
    pitch_window=(2.0 * math.pi, 2.5 * math.pi),  # eq 12 support [rad]
    tips_dt=5e-3,  # sampling interval of tips.npz [s]
    shapes_dt=2e-2,  # sampling interval of the stored bristle centre lines [s]
)

#: Columns of timeseries.csv, in order, with units.
CSV_COLUMNS = (
    "time_s",  # simulation time
    "phase",  # 0 press, 1 hold, 2 circle
    "theta_rad",  # rotation angle θ (0 at P0, unwrapped)
    "x_mm", "y_mm", "z_mm",  # TCP position, robot base frame
    "rx_rad", "ry_rad", "rz_rad",  # TCP orientation as a rotation vector (UR convention)
    "pitch_rad",  # imposed eq-12 pitch (0 without --pitch-error)
    "Fx_N", "Fy_N", "Fz_N",  # force the robot applies to the brush, base frame
    "Mx_Nmm", "My_Nmm", "Mz_Nmm",  # moment about the TCP, base frame
    "Fh_N",  # horizontal force magnitude sqrt(Fx^2 + Fy^2) (jamming detector)
    "Fn_total_N",  # sum of the tips' normal contact forces
    "Ft_total_N",  # |vector sum of the tips' tangential (friction) forces|
    "Ft_abs_sum_N",  # sum of |tangential force| over the tips
    "n_contact",  # tips in contact with a surface
    "max_penetration_mm",  # largest tip penetration
    "newton_iterations",  # Newton iterations of the step (all bristles)
    "substeps",  # sub-steps of the step (all bristles)
)

SUMMARY_KEYS = (
    "status", "paper", "settings", "trajectory", "performance", "analysis", "files",
)


# =============================================================================================
# small helpers
# =============================================================================================
def _json(x):
    """Make numpy scalars/arrays and non-finite floats JSON-safe."""
    if isinstance(x, dict):
        return {str(k): _json(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_json(v) for v in x]
    if isinstance(x, np.ndarray):
        return _json(x.tolist())
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else None
    return x


def pi_label(theta: float, denom: int = 4) -> str:
    """``theta`` as a multiple of π with denominator ``denom`` (e.g. '9π/4'), rounded."""
    fr = Fraction(round(theta / math.pi * denom), denom)
    if fr == 0:
        return "0"
    num = "" if abs(fr.numerator) == 1 else str(abs(fr.numerator))
    sign = "-" if fr < 0 else ""
    return f"{sign}{num}π" + ("" if fr.denominator == 1 else f"/{fr.denominator}")


def rotation_vectors(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (N, 3) of rotation matrices (N, 3, 3), continuous along the sequence.

    Via unit quaternions whose sign is kept continuous (q_k · q_(k-1) >= 0), so the vector does not
    flip near a rotation of π (the brush's R0 is a half turn about x); the angle may then exceed π.
    """
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    tr = np.trace(R, axis1=1, axis2=2)
    # Shepperd's method, branch per row
    q = np.empty((R.shape[0], 4))
    d = np.stack([tr, R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]], axis=1)
    k = np.argmax(d, axis=1)
    for case in range(4):
        m = k == case
        if not np.any(m):
            continue
        Rm = R[m]
        if case == 0:
            s = np.sqrt(1.0 + tr[m]) * 2.0
            q[m] = np.stack([0.25 * s, (Rm[:, 2, 1] - Rm[:, 1, 2]) / s,
                             (Rm[:, 0, 2] - Rm[:, 2, 0]) / s, (Rm[:, 1, 0] - Rm[:, 0, 1]) / s], 1)
        elif case == 1:
            s = np.sqrt(1.0 + Rm[:, 0, 0] - Rm[:, 1, 1] - Rm[:, 2, 2]) * 2.0
            q[m] = np.stack([(Rm[:, 2, 1] - Rm[:, 1, 2]) / s, 0.25 * s,
                             (Rm[:, 0, 1] + Rm[:, 1, 0]) / s, (Rm[:, 0, 2] + Rm[:, 2, 0]) / s], 1)
        elif case == 2:
            s = np.sqrt(1.0 + Rm[:, 1, 1] - Rm[:, 0, 0] - Rm[:, 2, 2]) * 2.0
            q[m] = np.stack([(Rm[:, 0, 2] - Rm[:, 2, 0]) / s, (Rm[:, 0, 1] + Rm[:, 1, 0]) / s,
                             0.25 * s, (Rm[:, 1, 2] + Rm[:, 2, 1]) / s], 1)
        else:
            s = np.sqrt(1.0 + Rm[:, 2, 2] - Rm[:, 0, 0] - Rm[:, 1, 1]) * 2.0
            q[m] = np.stack([(Rm[:, 1, 0] - Rm[:, 0, 1]) / s, (Rm[:, 0, 2] + Rm[:, 2, 0]) / s,
                             (Rm[:, 1, 2] + Rm[:, 2, 1]) / s, 0.25 * s], 1)
    # first quaternion: prefer a non-negative vector part along its largest component
    if q.shape[0]:
        j = int(np.argmax(np.abs(q[0, 1:]))) + 1
        if q[0, 0] < 0 or (abs(q[0, 0]) < 1e-12 and q[0, j] < 0):
            q[0] = -q[0]
        dots = np.einsum("ij,ij->i", q[1:], q[:-1])
        flips = np.concatenate([[1.0], np.cumprod(np.where(dots < 0.0, -1.0, 1.0))])
        q = q * flips[:, None]
    v = q[:, 1:]
    nv = np.linalg.norm(v, axis=1)
    ang = 2.0 * np.arctan2(nv, q[:, 0])
    scale = np.where(nv > 1e-12, ang / np.maximum(nv, 1e-300), 2.0)  # small angle: 2 v
    return v * scale[:, None]


def _smooth(y: np.ndarray, w: int) -> np.ndarray:
    """Centred moving average over ``w`` samples (odd), edges padded with the edge values."""
    if w <= 1:
        return y.copy()
    w = w | 1
    h = w // 2
    yp = np.concatenate([np.full(h, y[0]), y, np.full(h, y[-1])])
    c = np.cumsum(np.concatenate([[0.0], yp]))
    return (c[w:] - c[:-w]) / w


# =============================================================================================
# peak detection (jamming)
# =============================================================================================
def detect_peaks(
    theta,
    y,
    *,
    min_separation: float = math.pi / 2,
    smooth: float = 0.05,
    min_prominence: float = 0.1,
    min_abs_prominence: float = 0.0,
    theta_range=None,
    n_per_turn: int | None = None,
    grid_step: float = 0.005,
) -> list[dict]:
    """Peaks of a signal ``y`` against the rotation angle ``theta`` (rad).

    Method: restrict to ``theta_range`` (default: all), resample on a uniform θ grid of
    ``grid_step`` rad, smooth with a centred moving average of width ``smooth`` rad, then keep the
    points that are the maximum of the smoothed signal within ±``min_separation``/2 (windows cut by
    the range ends are not accepted, so a signal still rising at the end is no peak) and whose
    prominence — height above the higher of the two minima within ±``min_separation`` on either
    side — is at least ``min_prominence`` times the smoothed signal's range (max - min) and at least
    ``min_abs_prominence`` (same unit as ``y``; keeps numerical noise of a ~zero signal out).  Peaks
    closer than ``min_separation`` are suppressed in favour of the more prominent one.  With
    ``n_per_turn``, only the most prominent ``n_per_turn`` peaks of each turn (turn k = θ in
    [2π(k-1), 2πk)) are kept.

    Returns a list sorted by θ of dicts: ``theta`` (rad), ``theta_mod_2pi``, ``turn`` (1-based),
    ``value`` (peak of the smoothed signal), ``raw_value`` (max of the raw signal within ±smooth/2),
    ``prominence``, ``index`` (index into the input arrays nearest the peak).
    """
    theta = np.asarray(theta, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if theta.shape != y.shape:
        raise ValueError(f"theta and y must have the same length, got {theta.shape} and {y.shape}")
    if not (min_separation > 0 and grid_step > 0 and smooth >= 0 and min_prominence >= 0):
        raise ValueError("min_separation, grid_step must be > 0; smooth, min_prominence >= 0")
    m = np.isfinite(theta) & np.isfinite(y)
    if theta_range is not None:
        lo, hi = theta_range
        m &= (theta >= lo) & (theta <= hi)
    idx_all = np.flatnonzero(m)
    if idx_all.size < 3:
        return []
    th, yy = theta[idx_all], y[idx_all]
    order = np.argsort(th, kind="stable")
    th, yy, idx_all = th[order], yy[order], idx_all[order]
    # unique θ (rests at constant θ): keep the last sample of each θ
    keep = np.concatenate([np.diff(th) > 0, [True]])
    th, yy, idx_all = th[keep], yy[keep], idx_all[keep]
    if th.size < 3 or th[-1] - th[0] < 2 * grid_step:
        return []
    g = np.arange(th[0], th[-1] + 0.5 * grid_step, grid_step)
    g = g[g <= th[-1]]
    yg = np.interp(g, th, yy)
    ys = _smooth(yg, int(round(smooth / grid_step)) if smooth > 0 else 1)
    n = ys.size
    half = max(1, int(round(0.5 * min_separation / grid_step)))
    full = 2 * half
    rng = float(ys.max() - ys.min())
    if not rng > 0.0:
        return []
    thr = max(min_prominence * rng, min_abs_prominence,
              1e-12 * max(1.0, float(np.max(np.abs(ys)))))
    cands = []
    for i in range(half, n - half):
        win = ys[i - half:i + half + 1]
        # not the window's max, or not the first point of a plateau
        if ys[i] < win.max() or (i > 0 and ys[i - 1] == ys[i]):
            continue
        left = ys[max(0, i - full):i + 1].min()
        right = ys[i:min(n, i + full + 1)].min()
        prom = ys[i] - max(left, right)
        if prom >= thr:
            cands.append((prom, i))
    cands.sort(reverse=True)
    chosen: list[tuple[float, int]] = []
    for prom, i in cands:
        if all(abs(g[i] - g[j]) >= min_separation for _, j in chosen):
            chosen.append((prom, i))
    peaks = []
    hw = max(1, int(round(0.5 * smooth / grid_step)))
    for prom, i in chosen:
        t0 = g[i]
        k = int(np.argmin(np.abs(th - t0)))
        near = (th >= t0 - hw * grid_step) & (th <= t0 + hw * grid_step)
        raw = float(yy[near].max()) if np.any(near) else float(yy[k])
        peaks.append(dict(theta=float(t0), theta_mod_2pi=float(t0 % TWO_PI),
                          turn=int(math.floor(t0 / TWO_PI)) + 1, value=float(ys[i]),
                          raw_value=raw, prominence=float(prom), index=int(idx_all[k])))
    if n_per_turn is not None:
        by_turn: dict[int, list] = {}
        for p in peaks:
            by_turn.setdefault(p["turn"], []).append(p)
        peaks = [p for lst in by_turn.values()
                 for p in sorted(lst, key=lambda q: -q["prominence"])[:n_per_turn]]
    return sorted(peaks, key=lambda p: p["theta"])


def _circ_dist(a: float, b: float) -> float:
    """Distance between two angles on the circle (rad, in [0, π])."""
    d = (a - b) % TWO_PI
    return float(min(d, TWO_PI - d))


def _circ_mean_std(angles) -> tuple[float, float]:
    a = np.asarray(angles, dtype=float)
    c, s = np.mean(np.cos(a)), np.mean(np.sin(a))
    r = min(1.0, math.hypot(c, s))
    mean = math.atan2(s, c) % TWO_PI
    std = math.sqrt(max(0.0, -2.0 * math.log(max(r, 1e-300))))
    return mean, std


def jamming_analysis(theta, F, *, theta_range, min_separation=math.pi / 2, smooth=0.05,
                     min_prominence=0.1, min_abs_prominence=1e-3, n_per_turn=2) -> dict:
    """Jamming peaks of the horizontal force |F_h| = sqrt(Fx² + Fy²) against θ.

    Detects up to ``n_per_turn`` peaks per turn in ``theta_range`` (``detect_peaks``; a peak must
    stand at least ``min_prominence`` x the signal's range and ``min_abs_prominence`` N (1 mN)
    above its surroundings, within ``min_separation`` rad), reports for
    each the angle (absolute and modulo 2π), |F_h|, Fx, Fy, Fz at the peak, and the nearest of the
    paper's jamming angles (9π/4 ≡ π/4 and 13π/4 ≡ 5π/4 modulo 2π) with the signed offset.  Peaks
    are then grouped by that nearest paper angle into two ``events`` with their circular mean angle,
    spread, count and mean peak force.
    """
    theta = np.asarray(theta, dtype=float)
    F = np.asarray(F, dtype=float)
    fh = np.hypot(F[:, 0], F[:, 1])
    peaks = detect_peaks(theta, fh, min_separation=min_separation, smooth=smooth,
                         min_prominence=min_prominence, min_abs_prominence=min_abs_prominence,
                         theta_range=theta_range,
                         n_per_turn=n_per_turn)
    paper_mod = [a % TWO_PI for a in PAPER_JAMMING_ANGLES]
    out_peaks = []
    for p in peaks:
        i = p["index"]
        d = [_circ_dist(p["theta_mod_2pi"], a) for a in paper_mod]
        j = int(np.argmin(d))
        off = (p["theta_mod_2pi"] - paper_mod[j] + math.pi) % TWO_PI - math.pi
        out_peaks.append(dict(
            turn=p["turn"], theta_rad=p["theta"], theta_over_pi=p["theta"] / math.pi,
            theta_mod_2pi_rad=p["theta_mod_2pi"],
            theta_mod_2pi_deg=math.degrees(p["theta_mod_2pi"]),
            theta_label=pi_label(p["theta"], 8), Fh_N=p["raw_value"], Fh_smoothed_N=p["value"],
            prominence_N=p["prominence"], Fx_N=float(F[i, 0]), Fy_N=float(F[i, 1]),
            Fz_N=float(F[i, 2]), nearest_paper_angle=("9π/4", "13π/4")[j],
            offset_from_paper_rad=float(off), offset_from_paper_deg=math.degrees(off)))
    events = {}
    for j, name in enumerate(("9π/4", "13π/4")):
        ps = [p for p in out_peaks if p["nearest_paper_angle"] == name]
        if ps:
            mean, std = _circ_mean_std([p["theta_mod_2pi_rad"] for p in ps])
            off = (mean - paper_mod[j] + math.pi) % TWO_PI - math.pi
            events[name] = dict(
                paper_angle_mod_2pi_rad=paper_mod[j], count=len(ps), turns=[p["turn"] for p in ps],
                mean_angle_mod_2pi_rad=mean, mean_angle_mod_2pi_deg=math.degrees(mean),
                angle_std_deg=math.degrees(std), mean_offset_from_paper_deg=math.degrees(off),
                mean_Fh_N=float(np.mean([p["Fh_N"] for p in ps])),
                mean_Fx_N=float(np.mean([p["Fx_N"] for p in ps])),
                mean_Fy_N=float(np.mean([p["Fy_N"] for p in ps])))
        else:
            events[name] = dict(paper_angle_mod_2pi_rad=paper_mod[j], count=0)
    return dict(signal="Fh = sqrt(Fx^2 + Fy^2)", theta_range_rad=list(theta_range),
                method=dict(min_separation_rad=min_separation, smooth_rad=smooth,
                            min_prominence_fraction=min_prominence,
                            min_abs_prominence_N=min_abs_prominence, n_per_turn=n_per_turn),
                peaks=out_peaks, events=events)


# =============================================================================================
# per-turn statistics and repeatability
# =============================================================================================
def _turn_ranges(theta_lo: float, theta_hi: float) -> list[tuple[int, float, float, bool]]:
    """(turn, lo, hi, complete) for every turn overlapping [theta_lo, theta_hi]."""
    out = []
    k = int(math.floor(theta_lo / TWO_PI)) + 1
    while (k - 1) * TWO_PI < theta_hi - 1e-9:
        lo, hi = max(theta_lo, (k - 1) * TWO_PI), min(theta_hi, k * TWO_PI)
        if hi > lo:
            complete = lo <= (k - 1) * TWO_PI + 1e-6 and hi >= k * TWO_PI - 1e-6
            out.append((k, lo, hi, complete))
        k += 1
    return out


def per_turn_stats(theta, F, *, theta_range, extra=None) -> list[dict]:
    """Peak (max and min) Fx, Fy, Fz, |F_h| with their angles, and means, for every turn in range.

    Turn k covers θ in [2π(k-1), 2πk], cut to ``theta_range``; ``complete`` says whether the whole
    turn is in range.  ``extra``: optional dict name -> per-sample array also averaged per turn (its
    max is reported too).
    """
    theta = np.asarray(theta, dtype=float)
    F = np.asarray(F, dtype=float)
    fh = np.hypot(F[:, 0], F[:, 1])
    comps = {"Fx": F[:, 0], "Fy": F[:, 1], "Fz": F[:, 2], "Fh": fh}
    rows = []
    for k, lo, hi, complete in _turn_ranges(*theta_range):
        m = (theta >= lo) & (theta <= hi)
        if not np.any(m):
            continue
        idx = np.flatnonzero(m)
        row = dict(turn=k, theta_range_rad=[lo, hi], complete=complete, samples=int(idx.size))
        for name, y in comps.items():
            ym = y[idx]
            imax, imin = idx[int(np.argmax(ym))], idx[int(np.argmin(ym))]
            row[f"{name}_max_N"] = float(y[imax])
            row[f"{name}_max_theta_rad"] = float(theta[imax])
            row[f"{name}_max_theta_mod_2pi_deg"] = math.degrees(theta[imax] % TWO_PI)
            row[f"{name}_min_N"] = float(y[imin])
            row[f"{name}_min_theta_rad"] = float(theta[imin])
            row[f"{name}_min_theta_mod_2pi_deg"] = math.degrees(theta[imin] % TWO_PI)
            row[f"{name}_mean_N"] = float(np.mean(ym))
        for name, y in (extra or {}).items():
            y = np.asarray(y, dtype=float)
            row[f"{name}_mean"] = float(np.mean(y[idx]))
            row[f"{name}_max"] = float(np.max(y[idx]))
        rows.append(row)
    return rows


def repeatability(theta, F, turn_rows, *, jamming=None, grid_step=0.01) -> dict:
    """Turn-to-turn repeatability over the complete turns >= 2.

    ``trace_rms_spread_N``: for each of Fx, Fy, Fz, |F_h|, the RMS over θ (mod 2π) of the standard
    deviation across turns of the force traces resampled on a common θ grid; ``trace_rms_N``: RMS of
    the mean trace (for scale); ``peak_cv``: std / |mean| across turns of the per-turn max of each
    component; ``mean_std_N``: std across turns of the per-turn means; ``jamming_angle_std_deg``
    per event (from ``jamming``).  ``None`` entries when fewer than two complete turns exist.
    """
    theta = np.asarray(theta, dtype=float)
    F = np.asarray(F, dtype=float)
    rows = [r for r in turn_rows if r["complete"] and r["turn"] >= 2]
    out = dict(turns=[r["turn"] for r in rows])
    if len(rows) < 2:
        out.update(trace_rms_spread_N=None, trace_rms_N=None, peak_cv=None, mean_std_N=None,
                   jamming_angle_std_deg=None,
                   note="needs at least two complete turns >= 2 (θ in [2π, 6π])")
        return out
    fh = np.hypot(F[:, 0], F[:, 1])
    comps = {"Fx": F[:, 0], "Fy": F[:, 1], "Fz": F[:, 2], "Fh": fh}
    g = np.arange(0.0, TWO_PI, grid_step)
    spread, rms = {}, {}
    for name, y in comps.items():
        traces = []
        for r in rows:
            lo = (r["turn"] - 1) * TWO_PI
            m = (theta >= lo - 1e-9) & (theta <= lo + TWO_PI + 1e-9)
            th, yy = theta[m], y[m]
            keep = np.concatenate([np.diff(th) > 0, [True]])
            traces.append(np.interp(lo + g, th[keep], yy[keep]))
        T = np.array(traces)
        spread[name] = float(np.sqrt(np.mean(np.std(T, axis=0) ** 2)))
        rms[name] = float(np.sqrt(np.mean(np.mean(T, axis=0) ** 2)))
    peak_cv, mean_std = {}, {}
    for name in comps:
        pk = np.array([r[f"{name}_max_N"] for r in rows])
        mn = np.array([r[f"{name}_mean_N"] for r in rows])
        peak_cv[name] = float(np.std(pk) / abs(np.mean(pk))) if abs(np.mean(pk)) > 1e-12 else None
        mean_std[name] = float(np.std(mn))
    out.update(trace_rms_spread_N=spread, trace_rms_N=rms, peak_cv=peak_cv, mean_std_N=mean_std)
    if jamming is not None:
        out["jamming_angle_std_deg"] = {
            k: v.get("angle_std_deg") for k, v in jamming["events"].items()}
    return out


def pitch_asymmetry(theta, F_base, F_pitch, window, *, pitch=None) -> dict:
    """How the eq-12 pitch perturbation changes the forces (Figure 10 vs Figure 7).

    In the perturbed interval ``window`` = [θs, θe] (default [2π, 5π/2]), for the run without
    (``baseline``) and with (``pitch``) the perturbation: the positive and negative peaks of Fy, the
    peaks of |Fx|, |Fy|, Fz and their ratio |Fx|/|Fy|, and the largest slope |dFy/dθ|; the change
    (pitch - baseline, absolute and in %).  ``turn_to_turn``: the same jamming event one turn later
    (θ in window + 2π, unperturbed in both runs) as reference — the ratio of the |Fy| peak in the
    window to the one a turn later is ~1 without perturbation, and its change measures the
    asymmetry.  ``rms_difference_N``: RMS of pitch - baseline inside the window and after it (θ >
    θe), per component, showing how local the effect is.
    """
    theta = np.asarray(theta, dtype=float)
    Fb, Fp = np.asarray(F_base, dtype=float), np.asarray(F_pitch, dtype=float)
    n = min(len(theta), len(Fb), len(Fp))
    theta, Fb, Fp = theta[:n], Fb[:n], Fp[:n]
    lo, hi = window
    m = (theta >= lo) & (theta <= hi)
    if not np.any(m):
        return dict(window_rad=[lo, hi], note="the run does not reach the perturbed window")

    def stats(F, mask):
        fx, fy, fz = F[mask, 0], F[mask, 1], F[mask, 2]
        th = theta[mask]
        dfy = np.gradient(fy, th) if fy.size > 2 and np.all(np.diff(th) > 0) else np.zeros(1)
        ax, ay = float(np.max(np.abs(fx))), float(np.max(np.abs(fy)))
        return dict(Fy_max_N=float(fy.max()), Fy_max_theta_rad=float(th[np.argmax(fy)]),
                    Fy_min_N=float(fy.min()), Fy_min_theta_rad=float(th[np.argmin(fy)]),
                    absFx_peak_N=ax, absFy_peak_N=ay, Fz_max_N=float(fz.max()),
                    Fz_min_N=float(fz.min()),
                    Fx_over_Fy_peak_ratio=(ax / ay) if ay > 1e-12 else None,
                    max_abs_dFy_dtheta_N_per_rad=float(np.max(np.abs(dfy))))

    b, p = stats(Fb, m), stats(Fp, m)

    def change(kb, kp):
        out = {}
        for k in kb:
            if k.endswith("theta_rad") or kb[k] is None or kp[k] is None:
                continue
            d = kp[k] - kb[k]
            out[k] = dict(baseline=kb[k], pitch=kp[k], change=d,
                          change_percent=(100.0 * d / abs(kb[k])) if abs(kb[k]) > 1e-12 else None)
        return out

    res = dict(window_rad=[lo, hi], window_label=[pi_label(lo), pi_label(hi)],
               baseline=b, pitch=p, change=change(b, p))
    m2 = (theta >= lo + TWO_PI) & (theta <= hi + TWO_PI)
    if np.any(m2):
        b2, p2 = stats(Fb, m2), stats(Fp, m2)
        tt = {}
        for name, (x1, x2) in {"baseline": (b, b2), "pitch": (p, p2)}.items():
            tt[name] = dict(
                absFy_peak_ratio_window_to_next_turn=(x1["absFy_peak_N"] / x2["absFy_peak_N"])
                if x2["absFy_peak_N"] > 1e-12 else None,
                Fy_max_ratio_window_to_next_turn=(x1["Fy_max_N"] / x2["Fy_max_N"])
                if abs(x2["Fy_max_N"]) > 1e-12 else None,
                Fx_over_Fy_ratio_window=x1["Fx_over_Fy_peak_ratio"],
                Fx_over_Fy_ratio_next_turn=x2["Fx_over_Fy_peak_ratio"])
        res["turn_to_turn"] = tt
    diff = Fp - Fb
    after = theta > hi
    res["rms_difference_N"] = {
        "window": {c: float(np.sqrt(np.mean(diff[m, i] ** 2))) for i, c in enumerate("xyz")},
        "after_window": ({c: float(np.sqrt(np.mean(diff[after, i] ** 2)))
                          for i, c in enumerate("xyz")} if np.any(after) else None)}
    if pitch is not None:
        pitch = np.asarray(pitch, dtype=float)[:n]
        k = int(np.argmax(np.abs(pitch)))
        res["pitch_peak_deg"] = math.degrees(float(pitch[k]))
        res["pitch_peak_theta_rad"] = float(theta[k])
    return res


def analyse_run(theta, F, Fn_total, n_contact, max_pen, *, theta_lo=0.5 * math.pi) -> dict:
    """The analysis of one run over θ >= ``theta_lo`` (the first quarter P0 -> P1 is excluded):
    ``per_turn`` statistics, ``jamming`` peaks, turn-to-turn ``repeatability`` and overall maxima
    and means (see docs/reference_experiment.md)."""
    theta, F = np.asarray(theta, float), np.asarray(F, float)
    Fn_total, n_contact, max_pen = (np.asarray(x, float) for x in (Fn_total, n_contact, max_pen))
    rng = (theta_lo, float(theta[-1]))
    if not rng[1] > rng[0]:
        return dict(theta_range_rad=list(rng), note="the run ends before θ = π/2", per_turn=[],
                    jamming=None, repeatability=None, max_penetration_mm=None,
                    max_penetration_whole_run_mm=float(max_pen.max()))
    jam = jamming_analysis(theta, F, theta_range=rng)
    rows = per_turn_stats(theta, F, theta_range=rng, extra={
        "Fn_total_N": Fn_total, "n_contact": n_contact, "max_penetration_mm": max_pen})
    m = theta >= theta_lo
    return dict(
        theta_range_rad=list(rng), excluded="θ < π/2 (first quarter P0 -> P1, §4)",
        per_turn=rows, jamming=jam, repeatability=repeatability(theta, F, rows, jamming=jam),
        max_penetration_mm=float(max_pen[m].max()),
        max_penetration_whole_run_mm=float(max_pen.max()),
        max_Fh_N=float(np.hypot(F[m, 0], F[m, 1]).max()), max_abs_Fz_N=float(np.abs(F[m, 2]).max()),
        mean_Fz_N=float(F[m, 2].mean()), mean_Fn_total_N=float(Fn_total[m].mean()),
        mean_n_contact=float(n_contact[m].mean()))


def _brush_info(brush_cfg):
    """(materials, groups) of a brush for summary.json."""
    mats, groups = {}, {}
    for b in brush_cfg.bristles:
        m = b.material
        mats[m.name] = dict(name=m.name, E_MPa=m.E, nu=m.nu, density_t_per_mm3=m.density,
                            damping_ratio=m.damping_ratio)
        sec = dict(kind=b.section.kind, width_mm=b.section.width,
                   thickness_mm=b.section.thickness)
        g = groups.setdefault(b.group, dict(count=0, length_mm=b.length, bodies=b.bodies,
                                            section=sec, material=m.name,
                                            tip_radius_mm=b.tip_radius))
        g["count"] += 1
    return list(mats.values()), groups


# =============================================================================================
# the run
# =============================================================================================
class _Recorder:
    """Preallocated per-step and sampled (tips, shapes) records of one run."""

    def __init__(self, n_rows, nb, nbody, tips_stride, shapes_stride):
        self.n = 0
        self.tips_stride, self.shapes_stride = tips_stride, shapes_stride
        self.step = dict(
            time=np.zeros(n_rows), F=np.zeros((n_rows, 3)), M=np.zeros((n_rows, 3)),
            Fn=np.zeros(n_rows), Ft=np.zeros(n_rows), Ft_abs=np.zeros(n_rows),
            n_contact=np.zeros(n_rows, np.int32), max_pen=np.zeros(n_rows),
            iters=np.zeros(n_rows, np.int32), subs=np.zeros(n_rows, np.int32))
        nt = (n_rows - 1) // tips_stride + 1
        ns = (n_rows - 1) // shapes_stride + 1
        f32 = np.float32
        self.tips = dict(
            row=np.zeros(nt, np.int64), pos=np.zeros((nt, nb, 3), f32),
            vel=np.zeros((nt, nb, 3), f32), fn=np.zeros((nt, nb), f32),
            ft=np.zeros((nt, nb, 3), f32), fc=np.zeros((nt, nb, 3), f32),
            contact=np.zeros((nt, nb), bool), sliding=np.zeros((nt, nb), bool),
            pen=np.zeros((nt, nb), f32), tiptip=np.zeros((nt, nb), f32))
        self.nt = 0
        self.shapes = dict(row=np.zeros(ns, np.int64), body=np.zeros((ns, nbody, 3), f32),
                           tip=np.zeros((ns, nb, 3), f32), contact=np.zeros((ns, nb), bool))
        self.ns = 0

    def copy(self):
        new = _Recorder.__new__(_Recorder)
        new.n, new.nt, new.ns = self.n, self.nt, self.ns
        new.tips_stride, new.shapes_stride = self.tips_stride, self.shapes_stride
        new.step = {k: v.copy() for k, v in self.step.items()}
        new.tips = {k: v.copy() for k, v in self.tips.items()}
        new.shapes = {k: v.copy() for k, v in self.shapes.items()}
        return new

    def add(self, out, sim):
        i = self.n
        s = self.step
        s["time"][i] = out.time
        s["F"][i] = out.tcp_force
        s["M"][i] = out.tcp_moment
        fn = out.tip_normal_force
        ft = out.tip_tangential_force
        s["Fn"][i] = float(fn.sum())
        s["Ft"][i] = float(np.linalg.norm(ft.sum(axis=0)))
        s["Ft_abs"][i] = float(np.linalg.norm(ft, axis=1).sum())
        s["n_contact"][i] = int(np.count_nonzero(out.tip_in_contact))
        s["max_pen"][i] = float(out.tip_penetration.max()) if out.tip_penetration.size else 0.0
        s["iters"][i] = out.iterations
        s["subs"][i] = out.substeps
        if i % self.tips_stride == 0:
            k = self.nt
            t = self.tips
            t["row"][k] = i
            t["pos"][k] = out.tip_pos
            t["vel"][k] = out.tip_vel
            t["fn"][k] = fn
            t["ft"][k] = ft
            d = out.tip_pos - out.tip_contact_point
            nd = np.linalg.norm(d, axis=1, keepdims=True)
            nrm = np.where(nd > 1e-12, d / np.maximum(nd, 1e-300), 0.0)
            t["fc"][k] = np.where(out.tip_in_contact[:, None], fn[:, None] * nrm + ft, 0.0)
            t["contact"][k] = out.tip_in_contact
            t["sliding"][k] = out.tip_sliding
            t["pen"][k] = out.tip_penetration
            tt = out.extra.get("tip_tip_force") if out.extra else None
            if tt is not None:
                t["tiptip"][k] = tt
            self.nt += 1
        if i % self.shapes_stride == 0:
            k = self.ns
            sh = self.shapes
            sh["row"][k] = i
            sh["body"][k] = sim.state.pos
            sh["tip"][k] = out.tip_pos
            sh["contact"][k] = out.tip_in_contact
            self.ns += 1
        self.n += 1


def _touch_height(sim: Simulator, R: np.ndarray, plate_z: float) -> float:
    """TCP height at which the lowest tip sphere touches the plate z = plate_z (unloaded)."""
    m = sim.model
    tips_tcp = np.array([m.root_p[j] + m.length[j] * (m.root_R[j][:, 0])
                         for j in range(m.n_bristles)])
    tips_w = tips_tcp @ R.T
    return float(plate_z - np.min(tips_w[:, 2] - m.tip_radius))


def _plate_height(scene) -> float:
    planes = [s for s in scene.surfaces if isinstance(s, Plane)]
    if not scene.surfaces:
        return 0.0
    if not planes:
        kinds = [type(s).__name__ for s in scene.surfaces]
        raise ValueError(f"scene {scene.name!r}: the reference experiment needs a flat plate (a "
                         f"'plane' surface with normal +z), got {kinds}")
    pl = planes[0]
    n = np.asarray(pl.normal, dtype=float)
    n = n / np.linalg.norm(n)
    if abs(n[2] - 1.0) > 1e-9:
        raise ValueError(f"scene {scene.name!r}: the plate normal must be +z (world), "
                         f"got {pl.normal}")
    return float(pl.point[2])


def build_trajectory(*, start_xy, touch_z, radius, speed, accel, turns, press_depth, press_time,
                     hold_time, path, pitch_error_deg=0.0, pitch_window=DEFAULTS["pitch_window"]):
    """The reference motion: Press (along the bristle axis) -> Hold -> circle, optionally pitched.

    Returns ``(trajectory, phase_starts, circle)`` with ``phase_starts = (0, t_hold, t_circle)``.
    ``path='movel'``: the paper's four MoveL control points with blend radius = circle radius
    (``paper_circle_movel``, ``ceil(turns)`` turns); ``'circle'``: the exact ``Circle``.
    The circle is centred at (start_xy + radius · x) so that P0 (θ = 0, polar angle π) is
    ``start_xy`` and the motion is counter-clockwise about +z.
    """
    p_touch = np.array([start_xy[0], start_xy[1], touch_z], dtype=float)
    press = Press((p_touch, R0), press_depth, press_time)
    p_pressed, _ = press.end_pose
    segs = [press]
    if hold_time > 0:
        segs.append(Hold((p_pressed, R0), hold_time))
    center = p_pressed + np.array([radius, 0.0, 0.0])
    if path == "movel":
        circ = paper_circle_movel(center, radius, speed, accel, turns=int(math.ceil(turns - 1e-9)),
                                  orientation=np.array(R0))
    elif path == "circle":
        circ = Circle(center, radius, speed, accel, turns=turns, start_angle=math.pi, R=R0)
    else:
        raise ValueError(f"path must be 'movel' or 'circle', got {path!r}")
    segs.append(circ)
    # remove the fp residue of P0 = centre + r (cos π, sin π) so Sequence's continuity check passes
    seq = Sequence(segs)
    phase_starts = tuple(float(t) for t in seq.start_times[:-1])
    traj = seq
    if pitch_error_deg:
        traj = PitchPerturbation(seq, math.radians(pitch_error_deg), theta_start=pitch_window[0],
                                 theta_end=pitch_window[1])
    return traj, phase_starts, circ


def _simulate(sim, P, R, rec, theta, i0, i1, bar, label):
    """Step rows i0..i1-1 (row i is the pose at time i·dt; row 0 is the reset)."""
    last = i0
    for i in range(i0, i1):
        out = sim.step(P[i], R[i])
        rec.add(out, sim)
        if bar is not None and (i % 50 == 0 or i == i1 - 1):
            bar.update(i + 1 - last)
            last = i + 1
            bar.set_postfix_str(f"{label} θ={theta[i] / math.pi:5.2f}π "
                                f"Fz={out.tcp_force[2]:+.2f} N", refresh=False)


def run_reference(
    brush=None,
    scene=None,
    out_dir="runs/reference",
    turns: float = DEFAULTS["turns"],
    pitch_error_deg: float = 0.0,
    dt: float = DEFAULTS["dt"],
    bodies: int | None = None,
    integrator: str = DEFAULTS["integrator"],
    speed: float = DEFAULTS["speed"],
    accel: float = DEFAULTS["accel"],
    progress: bool = True,
    *,
    path: str = DEFAULTS["path"],
    radius: float = DEFAULTS["radius"],
    press_depth: float = DEFAULTS["press_depth"],
    press_time: float = DEFAULTS["press_time"],
    hold_time: float = DEFAULTS["hold_time"],
    pitch_window=DEFAULTS["pitch_window"],
    tips_dt: float = DEFAULTS["tips_dt"],
    shapes_dt: float = DEFAULTS["shapes_dt"],
    plots: bool = True,
) -> dict:
    """Run the paper's circular reference experiment and write its outputs to ``out_dir``.

    ``brush``: a ``BrushConfig``, a path or a name in configs/brushes (default: the scene's brush);
    ``scene``: a ``Scene``, path or name (default ``flat_plate``).  ``turns`` (may be fractional for
    quick runs: the motion is then cut when θ reaches 2π·turns), ``pitch_error_deg`` (0: no
    perturbation; else a second run with the eq-12 pitch of this amplitude in ``pitch_window``),
    ``dt`` [s], ``bodies`` (override bodies per bristle), ``integrator`` ('bdf2' | 'euler'),
    ``speed`` [mm/s], ``accel`` [mm/s²], ``path`` ('movel' | 'circle').  Writes timeseries.csv,
    tips.npz, forces_vs_angle.png, deformed_shapes.png, summary.json (and, with a pitch error,
    timeseries_pitch.csv and tips_pitch.npz) and returns the summary dict.
    """
    t_wall0 = time.perf_counter()
    turns = float(turns)
    if not (turns > 0 and math.isfinite(turns)):
        raise ValueError(f"turns must be > 0, got {turns!r}")
    for name, v in (("dt", dt), ("speed", speed), ("accel", accel), ("radius", radius),
                    ("press_time", press_time), ("tips_dt", tips_dt), ("shapes_dt", shapes_dt)):
        if not (float(v) > 0 and math.isfinite(float(v))):
            raise ValueError(f"{name} must be > 0, got {v!r}")
    if not (hold_time >= 0 and press_depth >= 0):
        raise ValueError("hold_time and press_depth must be >= 0")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)

    # ---- scene, brush, simulator
    if scene is None or isinstance(scene, (str, os.PathLike)):
        scene_obj = load_scene(scene, brush=brush if brush is not None else None)
    else:
        scene_obj = scene
        if brush is not None:
            b = brush if isinstance(brush, BrushConfig) else load_brush(brush)
            scene_obj = replace(scene, brush=b)
    if bodies is not None:
        scene_obj = replace(scene_obj, brush=scene_obj.brush.with_bodies(int(bodies)))
    brush_cfg = scene_obj.brush
    settings = SimSettings(dt=float(dt), integrator=integrator)
    t_setup = time.perf_counter()
    sim = Simulator(scene_obj, settings)
    plate_z = _plate_height(scene_obj)
    touch_z = _touch_height(sim, np.array(R0), plate_z)
    start_xy = (0.0, 0.0)

    trajs = {}
    traj, phase_starts, circ = build_trajectory(
        start_xy=start_xy, touch_z=touch_z, radius=radius, speed=speed, accel=accel, turns=turns,
        press_depth=press_depth, press_time=press_time, hold_time=hold_time, path=path)
    trajs["baseline"] = traj
    if pitch_error_deg:
        trajs["pitch"], _, _ = build_trajectory(
            start_xy=start_xy, touch_z=touch_z, radius=radius, speed=speed, accel=accel,
            turns=turns, press_depth=press_depth, press_time=press_time, hold_time=hold_time,
            path=path, pitch_error_deg=pitch_error_deg, pitch_window=pitch_window)

    # ---- time grid, poses, angle
    theta_end = TWO_PI * turns
    T = traj.duration
    n_full = int(math.ceil(T / dt - 1e-9))
    times = np.arange(n_full + 1) * dt
    theta_full = np.asarray(traj.angle(np.minimum(times, T)), dtype=float)
    reach = np.flatnonzero(theta_full >= theta_end - 1e-9)
    n_steps = int(reach[0]) if reach.size else n_full
    times = times[:n_steps + 1]
    theta = theta_full[:n_steps + 1]
    phase = np.searchsorted(np.asarray(phase_starts), times, side="right") - 1
    phase = np.where(phase >= len(phase_starts) - 1, 2, phase)
    if hold_time <= 0:
        phase = np.where(phase >= 1, 2, phase)
    poses = {}
    for name, tr in trajs.items():
        Pn, Rn, _, _ = tr.sample(times)
        poses[name] = (Pn, Rn)
    pitch_series = {"baseline": np.zeros(n_steps + 1)}
    if "pitch" in trajs:
        pitch_series["pitch"] = trajs["pitch"].pitch(times)

    nb, nbody = sim.model.n_bristles, sim.model.n_bodies
    tips_stride = max(1, int(round(tips_dt / dt)))
    shapes_stride = max(1, int(round(shapes_dt / dt)))

    # ---- simulate (the pitch run shares the prefix before the perturbation starts)
    from tqdm.auto import tqdm

    status = {}
    recs = {}
    perf = {}
    P, R = poses["baseline"]
    rec = _Recorder(n_steps + 1, nb, nbody, tips_stride, shapes_stride)
    rec.add(sim.reset(P[0], R[0]), sim)
    t_setup = time.perf_counter() - t_setup
    branch = n_steps + 1  # first row whose pose differs between the two runs
    if "pitch" in poses:
        Pp, Rp = poses["pitch"]
        diff = np.flatnonzero((np.abs(Pp - P).max(axis=1) > 0)
                              | (np.abs(Rp - R).max(axis=(1, 2)) > 0))
        branch = int(diff[0]) if diff.size else n_steps + 1
    total = n_steps + (n_steps + 1 - branch if "pitch" in poses else 0)
    bar = tqdm(total=total, unit="step", desc="reference", mininterval=0.5,
               dynamic_ncols=True) if progress else None
    snapshot = rec_snapshot = None
    t0 = time.perf_counter()
    try:
        if branch <= n_steps:
            _simulate(sim, P, R, rec, theta, 1, branch, bar, "baseline")
            snapshot, rec_snapshot = sim.get_state(), rec.copy()
            _simulate(sim, P, R, rec, theta, branch, n_steps + 1, bar, "baseline")
        else:
            _simulate(sim, P, R, rec, theta, 1, n_steps + 1, bar, "baseline")
        status["baseline"] = "ok"
    except SimulationDivergence as exc:
        status["baseline"] = f"diverged: {exc}"
    recs["baseline"] = rec
    perf["baseline"] = dict(wall_s=time.perf_counter() - t0, steps=rec.n - 1,
                            simulated_s=float(rec.step["time"][rec.n - 1]))
    if "pitch" in poses:
        Pp, Rp = poses["pitch"]
        t0 = time.perf_counter()
        if branch > n_steps:  # the perturbation does not start within the run: same as baseline
            rec_p = rec.copy()
            status["pitch"] = status["baseline"]
            perf["pitch"] = dict(wall_s=0.0, steps=0, shared_prefix_steps=rec.n - 1,
                                 simulated_s=0.0)
        elif snapshot is None:  # the baseline diverged before the perturbation starts
            rec_p = rec.copy()
            status["pitch"] = "not run: the baseline diverged before the perturbation starts"
            perf["pitch"] = dict(wall_s=0.0, steps=0, shared_prefix_steps=rec.n - 1,
                                 simulated_s=0.0)
        else:
            sim.set_state(snapshot)
            rec_p = rec_snapshot
            try:
                _simulate(sim, Pp, Rp, rec_p, theta, branch, n_steps + 1, bar, "pitch")
                status["pitch"] = "ok"
            except SimulationDivergence as exc:
                status["pitch"] = f"diverged: {exc}"
            perf["pitch"] = dict(wall_s=time.perf_counter() - t0, steps=rec_p.n - branch,
                                 shared_prefix_steps=branch - 1,
                                 simulated_s=float(rec_p.step["time"][rec_p.n - 1]
                                                   - times[branch - 1]))
        recs["pitch"] = rec_p
    if bar is not None:
        bar.close()
    wall_sim = sum(p["wall_s"] for p in perf.values())
    sim_time = sum(p["simulated_s"] for p in perf.values())

    # ---- outputs
    files = {}
    analysis = {}
    for name, r in recs.items():
        sfx = "" if name == "baseline" else "_pitch"
        nrow = r.n
        Pn, Rn = poses[name]
        csv_path = out_dir / f"timeseries{sfx}.csv"
        _write_csv(csv_path, r, times[:nrow], phase[:nrow], theta[:nrow], Pn[:nrow], Rn[:nrow],
                   pitch_series[name][:nrow])
        npz_path = out_dir / f"tips{sfx}.npz"
        _write_npz(npz_path, r, times, theta, poses[name], sim, brush_cfg, dt)
        files[f"timeseries{sfx}"] = csv_path.name
        files[f"tips{sfx}"] = npz_path.name
        analysis[name] = analyse_run(theta[:nrow], r.step["F"][:nrow], r.step["Fn"][:nrow],
                                     r.step["n_contact"][:nrow], r.step["max_pen"][:nrow])
    if "pitch" in recs:
        nrow = min(recs["baseline"].n, recs["pitch"].n)
        analysis["pitch_asymmetry"] = pitch_asymmetry(
            theta[:nrow], recs["baseline"].step["F"][:nrow], recs["pitch"].step["F"][:nrow],
            pitch_window, pitch=pitch_series["pitch"][:nrow])

    t_plot = time.perf_counter()
    if plots:
        fig_path = out_dir / "forces_vs_angle.png"
        plot_forces_vs_angle(fig_path, recs, theta, analysis, pitch_series, pitch_window,
                             title=f"brush '{brush_cfg.name}', {path}, v = {speed:g} mm/s, "
                                   f"dt = {dt:g} s")
        files["forces_vs_angle"] = fig_path.name
        shp_path = out_dir / "deformed_shapes.png"
        plot_deformed_shapes(shp_path, recs["baseline"], theta, poses["baseline"], sim,
                             brush_cfg, analysis["baseline"], times)
        files["deformed_shapes"] = shp_path.name
    t_plot = time.perf_counter() - t_plot

    # ---- summary
    materials, groups = _brush_info(brush_cfg)
    traj_info = dict(
        path=path, duration_s=float(times[-1]), phase_starts_s=dict(
            press=phase_starts[0], hold=phase_starts[1] if len(phase_starts) > 2 else None,
            circle=phase_starts[-1]),
        start_point_P0_mm=list(poses["baseline"][0][0]),
        touch_tcp_z_mm=touch_z, plate_z_mm=plate_z,
        circle_center_mm=list(np.asarray(start_xy) + [radius, 0.0]),
        direction="counter-clockwise about +z (seen from above), P0 at polar angle π",
        theta_end_rad=float(theta[-1]), cut_before_end_of_motion=bool(n_steps < n_full),
        speed_mm_s=speed, accel_mm_s2=accel,
        accel_ramp_s=speed / accel, accel_ramp_mm=speed ** 2 / (2 * accel))
    if path == "movel":
        dev = movel_circle_deviation([0.0, 0.0, 0.0], radius, radius)
        traj_info["movel"] = dict(
            control_points="corners of the square circumscribed about the circle, P1 first after "
                           "P0 (paper_circle_waypoints, 'circumscribed')",
            blend_radius_mm=radius, blend_rule=BLEND_RULE, deviation_from_circle=dev)
    base = recs["baseline"]
    summary = dict(
        status="ok" if all(v == "ok" for v in status.values()) else "diverged",
        run_status=status,
        paper=dict(reference="Cirelli et al., Machines 2023, §4-5, Figures 7, 9, 10",
                   jamming_angles_rad=list(PAPER_JAMMING_ANGLES),
                   jamming_angles_label=["9π/4", "13π/4"],
                   jamming_angles_mod_2pi_deg=[45.0, 225.0]),
        settings=dict(
            brush=dict(name=brush_cfg.name, file=brush_cfg.source, n_bristles=nb,
                       bodies_total=nbody, groups=groups, max_length_mm=brush_cfg.max_length),
            material=materials,
            scene=dict(name=scene_obj.name, tip_tip=scene_obj.tip_tip, plate_z_mm=plate_z),
            dt_s=dt, integrator=integrator,
            bodies=sorted({b.bodies for b in brush_cfg.bristles}),
            bodies_override=bodies, speed_mm_s=speed, accel_mm_s2=accel, path=path,
            radius_mm=radius, turns=turns, press_depth_mm=press_depth, press_time_s=press_time,
            press_profile="quintic (minimum jerk)", hold_time_s=hold_time,
            pitch_error_deg=pitch_error_deg, pitch_window_rad=list(pitch_window),
            pitch_axis="TCP y (the head's pitch axis), pivot at the TCP",
            tips_dt_s=tips_stride * dt, shapes_dt_s=shapes_stride * dt,
            force_convention="tcp_force: the force the robot applies to the brush, robot base "
                             "frame (z up); moments in N·mm about the TCP"),
        trajectory=traj_info,
        performance=dict(
            wall_time_s=time.perf_counter() - t_wall0, setup_s=t_setup, sim_wall_time_s=wall_sim,
            simulated_time_s=sim_time,
            real_time_factor=sim_time / wall_sim if wall_sim > 0 else None,
            plot_s=t_plot, runs=perf,
            newton_iterations_per_step=float(base.step["iters"][1:base.n].mean())
            if base.n > 1 else None,
            substeps_total=int(base.step["subs"][:base.n].sum())),
        analysis=analysis,
        files=files,
    )
    summary["files"]["summary"] = "summary.json"
    with open(out_dir / "summary.json", "w") as f:
        json.dump(_json(summary), f, indent=2, ensure_ascii=False)
    return _json(summary)


def _write_csv(path, r, times, phase, theta, P, R, pitch):
    s = r.step
    n = r.n
    F = s["F"][:n]
    rv = rotation_vectors(R)
    cols = [times, phase, theta, P[:, 0], P[:, 1], P[:, 2], rv[:, 0], rv[:, 1], rv[:, 2], pitch,
            F[:, 0], F[:, 1], F[:, 2], s["M"][:n, 0], s["M"][:n, 1], s["M"][:n, 2],
            np.hypot(F[:, 0], F[:, 1]), s["Fn"][:n], s["Ft"][:n], s["Ft_abs"][:n],
            s["n_contact"][:n], s["max_pen"][:n], s["iters"][:n], s["subs"][:n]]
    data = np.column_stack([np.asarray(c, dtype=float) for c in cols])
    fmt = ["%.6f", "%d", "%.9g"] + ["%.9g"] * 17 + ["%d", "%.6g", "%d", "%d"]
    np.savetxt(path, data, delimiter=",", header=",".join(CSV_COLUMNS), comments="", fmt=fmt)


def _write_npz(path, r, times, theta, pose, sim, brush_cfg, dt):
    t, sh = r.tips, r.shapes
    nt, ns = r.nt, r.ns
    m = sim.model
    P, R = pose
    rows_t, rows_s = t["row"][:nt], sh["row"][:ns]
    roots_s = P[rows_s][:, None, :] + np.einsum("kij,bj->kbi", R[rows_s], m.root_p)
    np.savez_compressed(
        path,
        time=times[rows_t], theta=theta[rows_t], step_index=rows_t,
        tip_pos=t["pos"][:nt], tip_vel=t["vel"][:nt],
        tip_normal_force=t["fn"][:nt], tip_tangential_force=t["ft"][:nt],
        tip_contact_force=t["fc"][:nt], tip_in_contact=t["contact"][:nt],
        tip_sliding=t["sliding"][:nt], tip_penetration=t["pen"][:nt],
        tip_tip_force=t["tiptip"][:nt],
        tcp_pos=P[rows_t], tcp_rot=R[rows_t],
        shape_time=times[rows_s], shape_theta=theta[rows_s], shape_step_index=rows_s,
        shape_body_pos=sh["body"][:ns], shape_tip_pos=sh["tip"][:ns],
        shape_root_pos=roots_s.astype(np.float32), shape_in_contact=sh["contact"][:ns],
        shape_tcp_pos=P[rows_s], bstart=m.bstart, root_p_tcp=m.root_p,
        bristle_length=m.length, tip_radius=m.tip_radius,
        group=np.array([b.group for b in brush_cfg.bristles]), dt=np.float64(dt),
        units=np.array("mm, s, N; world = robot base frame, z up; tip_contact_force = force of "
                       "the surface on the tip (normal + tangential)"))


# =============================================================================================
# figures
# =============================================================================================
def _pi_ticks(ax, lo, hi, denom=4):
    step = math.pi / denom
    k0, k1 = int(math.ceil(lo / step - 1e-9)), int(math.floor(hi / step + 1e-9))
    ks = list(range(k0, k1 + 1))
    stride = max(1, len(ks) // 14 + 1)
    ks = ks[::stride]
    ax.set_xticks([k * step for k in ks])
    ax.set_xticklabels([pi_label(k * step, denom) for k in ks])


def _plot_range(theta_end):
    if theta_end > TWO_PI + 0.25:
        k = int(math.ceil(theta_end / TWO_PI - 1e-9))
        full = abs(theta_end - k * TWO_PI) < 1e-6
        return TWO_PI, theta_end, (f"turns 2-{k}" if full and k > 2 else
                                   f"θ in [2π, {theta_end / math.pi:.2f}π]")
    if theta_end > 0.5 * math.pi:
        return 0.5 * math.pi, theta_end, "θ ≥ π/2 (turn 1 after the excluded quarter)"
    return 0.0, max(theta_end, 1e-3), "whole run (θ < π/2: no analysis range)"


def plot_forces_vs_angle(path, recs, theta, analysis, pitch_series, pitch_window, title=""):
    """Figure 7 (with a pitch run, Figure 10): Fx, Fy, Fz and |F_h| against θ over turns 2-4."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    base = recs["baseline"]
    th_end = float(theta[base.n - 1])
    lo, hi, what = _plot_range(th_end)
    fig, axes = plt.subplots(4, 1, figsize=(11, 10), sharex=True,
                             gridspec_kw=dict(height_ratios=[3, 3, 3, 2]))
    styles = {"baseline": dict(color="C0", lw=1.2, label="without pitch error"),
              "pitch": dict(color="C3", lw=1.2, ls="--", label="with pitch error (eq 12)")}
    names = ["Fx [N]", "Fy [N]", "Fz [N]", "|F_h| [N]"]
    for name, r in recs.items():
        n = r.n
        th = theta[:n]
        m = (th >= lo) & (th <= hi)
        F = r.step["F"][:n]
        ys = [F[:, 0], F[:, 1], F[:, 2], np.hypot(F[:, 0], F[:, 1])]
        st = dict(styles[name])
        if len(recs) == 1:
            st["label"] = None
        for ax, y in zip(axes, ys):
            ax.plot(th[m], y[m], **st)
        jam = (analysis.get(name) or {}).get("jamming")
        if jam:
            for p in jam["peaks"]:
                if lo <= p["theta_rad"] <= hi:
                    i = int(np.argmin(np.abs(th - p["theta_rad"])))
                    for ax, y in zip(axes, ys):
                        ax.axvline(p["theta_rad"], color=st["color"], lw=0.6, ls=":", alpha=0.8)
                        ax.plot(th[i], y[i], "v", color=st["color"], ms=6, mec="k", mew=0.5)
    # the paper's jamming angles 9π/4 + 2πk and 13π/4 + 2πk
    for a0 in PAPER_JAMMING_ANGLES:
        k = math.floor((lo - a0) / TWO_PI)
        a = a0 + k * TWO_PI
        while a <= hi:
            if a >= lo:
                for ax in axes:
                    ax.axvline(a, color="0.6", lw=1.0, ls="-.", alpha=0.6, zorder=0)
            a += TWO_PI
    if "pitch" in recs:
        for ax in axes:
            ax.axvspan(pitch_window[0], pitch_window[1], color="C3", alpha=0.08, zorder=0)
        ax2 = axes[3].twinx()
        m = (theta >= lo) & (theta <= hi)
        ax2.plot(theta[m], np.degrees(pitch_series["pitch"][m]), color="C3", lw=0.8, alpha=0.6)
        ax2.set_ylabel("pitch [deg]", color="C3")
    for ax, nm in zip(axes, names):
        ax.set_ylabel(nm)
        ax.grid(alpha=0.3)
    axes[-1].set_xlabel("rotation angle θ [rad]  (0 at P0; ▼ detected jamming peaks of |F_h|; "
                        "dash-dot: the paper's 9π/4 + 2πk, 13π/4 + 2πk)")
    _pi_ticks(axes[-1], lo, hi, 4)
    axes[0].set_xlim(lo, hi)
    if "pitch" in recs:
        axes[0].legend(loc="upper right", fontsize=8)
        fig.suptitle(f"Forces vs rotation angle, {what}: with and without the pitch error "
                     f"(paper Figure 10)\n{title}", fontsize=10)
    else:
        fig.suptitle(f"Forces vs rotation angle, {what} (paper Figure 7)\n{title}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _shape_events(analysis, theta_lo, theta_hi):
    """The angles to show in deformed_shapes.png: the jamming peaks of the first turn that has
    them (>= 2 if possible), else the paper's angles in range, else two evenly spaced angles."""
    jam = analysis.get("jamming") if analysis else None
    peaks = jam["peaks"] if jam else []
    if peaks:
        turns = sorted({p["turn"] for p in peaks})
        t = next((k for k in turns if k >= 2), turns[0])
        sel = [p for p in peaks if p["turn"] == t][:2]
        return [(p["theta_rad"], f"jamming peak at θ = {p['theta_label']} "
                                 f"({p['theta_mod_2pi_deg']:.0f}° mod 2π)") for p in sel]
    out = []
    for a0 in PAPER_JAMMING_ANGLES:
        for a in (a0 - TWO_PI, a0, a0 + TWO_PI):
            if theta_lo <= a <= theta_hi:
                out.append((a, f"paper's jamming angle {pi_label(a)} (no peak detected)"))
                break
    if out:
        return out[:2]
    return [(theta_lo + f * (theta_hi - theta_lo), "no jamming peak detected")
            for f in (0.35, 0.85)]


def plot_deformed_shapes(path, rec, theta, pose, sim, brush_cfg, analysis, times,
                         offsets=(-math.pi / 8, -math.pi / 24, 0.0, math.pi / 8)):
    """Figure 9: bristle centre lines around each jamming point, side (x-z) and top (x-y) views.

    Coordinates are world (robot base) axes relative to the TCP position; the plate is z = 0 in the
    side view.  Columns: angles θ_peak + offsets; rows: side and top view of each event.  Tips in
    contact are drawn red, the others black; the arrow in the top view is the TCP velocity.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ns = rec.ns
    rows = rec.shapes["row"][:ns]
    th_s = theta[rows]
    th_end = float(theta[rec.n - 1])
    lo = 0.5 * math.pi if th_end > 0.5 * math.pi else 0.0
    events = _shape_events(analysis, lo, th_end)
    m = sim.model
    P, R = pose
    groups = [b.group for b in brush_cfg.bristles]
    gnames = sorted(set(groups))
    gcol = {g: f"C{k}" for k, g in enumerate(gnames)}
    ncol = len(offsets)
    fig, axes = plt.subplots(2 * len(events), ncol, figsize=(3.2 * ncol, 3.0 * 2 * len(events)),
                             squeeze=False)
    L = brush_cfg.max_length
    span = np.ptp(m.root_p[:, 0]) / 2 + 0.7 * L
    spany = np.ptp(m.root_p[:, 1]) / 2 + 0.7 * L
    for e, (th0, label) in enumerate(events):
        for c, off in enumerate(offsets):
            want = th0 + off
            k = int(np.argmin(np.abs(th_s - want)))
            i = int(rows[k])
            p_tcp, R_tcp = P[i], R[i]
            body = rec.shapes["body"][k].astype(float)
            tips = rec.shapes["tip"][k].astype(float)
            cont = rec.shapes["contact"][k]
            roots = p_tcp + m.root_p @ R_tcp.T
            ax_s, ax_t = axes[2 * e, c], axes[2 * e + 1, c]
            for j in range(m.n_bristles):
                line = np.vstack([roots[j], body[m.bstart[j]:m.bstart[j + 1]], tips[j]])
                rel = line - [p_tcp[0], p_tcp[1], 0.0]
                col = gcol[groups[j]]
                ax_s.plot(rel[:, 0], rel[:, 2], "-", color=col, lw=1.0, alpha=0.8)
                ax_t.plot(rel[:, 0], rel[:, 1], "-", color=col, lw=1.0, alpha=0.8)
                tc = "r" if cont[j] else "k"
                ax_s.plot(rel[-1, 0], rel[-1, 2], "o", color=tc, ms=2.5)
                ax_t.plot(rel[-1, 0], rel[-1, 1], "o", color=tc, ms=2.5)
                ax_t.plot(rel[0, 0], rel[0, 1], "s", color=col, ms=2.5)
            ax_s.axhline(0.0, color="0.3", lw=1.5)
            ax_s.set_xlim(-span, span)
            ax_s.set_ylim(min(-1.0, float(tips[:, 2].min()) - 0.5), p_tcp[2] + 1.0)
            ax_t.set_xlim(-span, span)
            ax_t.set_ylim(-spany, spany)
            if i + 1 < len(P):
                v = (P[min(i + 1, len(P) - 1)] - P[max(i - 1, 0)])
                nv = np.linalg.norm(v[:2])
                if nv > 0:
                    d = v[:2] / nv * 0.5 * spany
                    ax_t.annotate("", xy=(d[0], d[1]), xytext=(0, 0),
                                  arrowprops=dict(arrowstyle="->", color="C3", lw=1.5))
            for ax in (ax_s, ax_t):
                ax.set_aspect("equal")
                ax.grid(alpha=0.3)
                ax.tick_params(labelsize=7)
            ax_s.set_title(f"θ = {th_s[k] / math.pi:.3f}π ({math.degrees(th_s[k] % TWO_PI):.0f}°)"
                           f"{'  [peak]' if off == 0 else ''}", fontsize=8)
            if c == 0:
                ax_s.set_ylabel(f"side: z [mm]\n{label}", fontsize=7)
                ax_t.set_ylabel("top: y - y_TCP [mm]", fontsize=7)
            ax_s.set_xlabel("x - x_TCP [mm]", fontsize=7)
            ax_t.set_xlabel("x - x_TCP [mm]", fontsize=7)
    handles = [plt.Line2D([], [], color=gcol[g], label=g) for g in gnames]
    handles += [plt.Line2D([], [], ls="", marker="o", color="r", label="tip in contact"),
                plt.Line2D([], [], color="C3", label="TCP velocity (top view)")]
    fig.legend(handles=handles, loc="lower center", fontsize=8, ncol=len(handles))
    fig.suptitle(f"Deformed bristles around the jamming points (paper Figure 9), brush "
                 f"'{brush_cfg.name}'; world axes relative to the TCP, plate at z = 0", fontsize=10)
    fig.tight_layout(rect=(0, 0.04, 1, 0.97))
    fig.savefig(path, dpi=100)
    plt.close(fig)


# =============================================================================================
# CLI
# =============================================================================================
def add_arguments(parser: argparse.ArgumentParser) -> None:
    d = DEFAULTS
    parser.description = ("Run the paper's circular reference experiment (3 mm press, four turns "
                          "of a 20 mm circle) and write timeseries.csv, tips.npz, "
                          "forces_vs_angle.png, deformed_shapes.png and summary.json.")
    parser.add_argument("--brush", default=None,
                        help="brush config file or name in configs/brushes (default: the scene's)")
    parser.add_argument("--scene", default=None,
                        help="scene config file or name in configs/scenes (default: flat_plate)")
    parser.add_argument("--out", default="runs/reference", help="output directory")
    parser.add_argument("--pitch-error", type=float, default=0.0, metavar="DEG",
                        help="also run with the eq-12 pitch perturbation of this amplitude [deg] "
                             "and produce the Figure-10 comparison (paper: 1)")
    parser.add_argument("--turns", type=float, default=d["turns"],
                        help="number of turns (paper: 4; fractions allowed for quick checks)")
    parser.add_argument("--dt", type=float, default=d["dt"], help="time step [s]")
    parser.add_argument("--bodies", type=int, default=None,
                        help="override the bodies per bristle of the brush config")
    parser.add_argument("--integrator", choices=("bdf2", "euler"), default=d["integrator"])
    parser.add_argument("--speed", type=float, default=d["speed"], help="tool speed [mm/s]")
    parser.add_argument("--accel", type=float, default=d["accel"],
                        help="tool acceleration [mm/s^2]")
    parser.add_argument("--path", choices=("movel", "circle"), default=d["path"],
                        help="circle built from four MoveL points with blends (paper Algorithm 1) "
                             "or the exact circle")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")


def run(args) -> int:
    summary = run_reference(
        brush=args.brush, scene=args.scene, out_dir=args.out, turns=args.turns,
        pitch_error_deg=args.pitch_error, dt=args.dt, bodies=args.bodies,
        integrator=args.integrator, speed=args.speed, accel=args.accel,
        progress=not args.no_progress, path=args.path)
    perf = summary["performance"]
    print(f"status: {summary['status']}; wall {perf['wall_time_s']:.1f} s "
          f"(simulation {perf['sim_wall_time_s']:.1f} s, real-time factor "
          f"{perf['real_time_factor'] or 0:.2f}); outputs in {args.out}")
    jam = summary["analysis"]["baseline"].get("jamming")
    if jam:
        for name, ev in jam["events"].items():
            if ev.get("count"):
                print(f"  jamming near {name}: {ev['count']} peak(s), mean angle "
                      f"{ev['mean_angle_mod_2pi_deg']:.1f}° mod 360° (paper "
                      f"{math.degrees(ev['paper_angle_mod_2pi_rad']):.0f}°), mean |F_h| "
                      f"{ev['mean_Fh_N']:.3f} N")
    if "pitch_asymmetry" in summary["analysis"]:
        ch = summary["analysis"]["pitch_asymmetry"].get("change", {})
        if "Fy_max_N" in ch:
            c = ch["Fy_max_N"]
            print(f"  pitch error: Fy peak in the perturbed interval {c['baseline']:.3f} -> "
                  f"{c['pitch']:.3f} N")
    return 0 if summary["status"] == "ok" else 1
