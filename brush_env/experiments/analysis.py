"""Signal analysis of the reference experiment (numpy only): peaks of a force against the rotation
angle θ, the jamming events near the paper's 9π/4 and 13π/4 (§5.1, Figure 7), per-turn statistics,
turn-to-turn repeatability and the asymmetry the eq-12 pitch perturbation introduces (§5.2,
Figure 10).  Units: N, rad."""

from __future__ import annotations

import math
from fractions import Fraction

import numpy as np

TWO_PI = 2.0 * math.pi

#: The paper's jamming angles (§5.1): 9π/4 and 13π/4, i.e. π/4 and 5π/4 modulo 2π.
PAPER_JAMMING_ANGLES = (9.0 * math.pi / 4.0, 13.0 * math.pi / 4.0)
PAPER_JAMMING_LABELS = ("9π/4", "13π/4")

#: Defaults of the reference scenario (documented in docs/reference_experiment.md).


def pi_label(theta: float, denom: int = 4) -> str:
    """``theta`` as a multiple of π with denominator ``denom`` (e.g. '9π/4'), rounded."""
    fr = Fraction(round(theta / math.pi * denom), denom)
    if fr == 0:
        return "0"
    num = "" if abs(fr.numerator) == 1 else str(abs(fr.numerator))
    sign = "-" if fr < 0 else ""
    return f"{sign}{num}π" + ("" if fr.denominator == 1 else f"/{fr.denominator}")


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
    samples = _sorted_samples(theta, y, theta_range)
    if samples is None:
        return []
    th = samples[0]
    if th.size < 3 or th[-1] - th[0] < 2 * grid_step:
        return []
    g, ys = _resampled_smoothed(samples, grid_step, smooth)
    half = max(1, int(round(0.5 * min_separation / grid_step)))
    rng = float(ys.max() - ys.min())
    if not rng > 0.0:
        return []
    thr = max(min_prominence * rng, min_abs_prominence, 1e-12 * max(1.0, float(np.max(np.abs(ys)))))
    chosen = _separated(_candidates(ys, half, thr), g, min_separation)
    hw = max(1, int(round(0.5 * smooth / grid_step)))
    peaks = [_peak_record(samples, g, ys, prom, i, hw * grid_step) for prom, i in chosen]
    if n_per_turn is not None:
        peaks = _most_prominent_per_turn(peaks, n_per_turn)
    return sorted(peaks, key=lambda p: p["theta"])


def _sorted_samples(theta, y, theta_range):
    """(θ, y, index into the input) of the finite samples in ``theta_range``, sorted by θ, with
    the last sample of each θ (rests at constant θ); None when fewer than 3 samples are left
    before the rests are merged."""
    m = np.isfinite(theta) & np.isfinite(y)
    if theta_range is not None:
        lo, hi = theta_range
        m &= (theta >= lo) & (theta <= hi)
    idx_all = np.flatnonzero(m)
    if idx_all.size < 3:
        return None
    th, yy = theta[idx_all], y[idx_all]
    order = np.argsort(th, kind="stable")
    th, yy, idx_all = th[order], yy[order], idx_all[order]
    # unique θ (rests at constant θ): keep the last sample of each θ
    keep = np.concatenate([np.diff(th) > 0, [True]])
    return th[keep], yy[keep], idx_all[keep]


def _resampled_smoothed(samples, grid_step: float, smooth: float):
    """The uniform θ grid of ``grid_step`` rad and the signal on it, smoothed over ``smooth``
    rad (centred moving average)."""
    th, yy, _ = samples
    g = np.arange(th[0], th[-1] + 0.5 * grid_step, grid_step)
    g = g[g <= th[-1]]
    yg = np.interp(g, th, yy)
    return g, _smooth(yg, int(round(smooth / grid_step)) if smooth > 0 else 1)


def _candidates(ys: np.ndarray, half: int, thr: float) -> list[tuple[float, int]]:
    """(prominence, grid index), most prominent first, of the points that are the maximum of
    their window of ±``half`` samples (first point of a plateau) and stand at least ``thr``
    above the higher of the minima within ±2·``half`` samples on either side."""
    n, full = ys.size, 2 * half
    cands = []
    for i in range(half, n - half):
        win = ys[i - half : i + half + 1]
        # not the window's max, or not the first point of a plateau
        if ys[i] < win.max() or (i > 0 and ys[i - 1] == ys[i]):
            continue
        left = ys[max(0, i - full) : i + 1].min()
        right = ys[i : min(n, i + full + 1)].min()
        prom = ys[i] - max(left, right)
        if prom >= thr:
            cands.append((prom, i))
    cands.sort(reverse=True)
    return cands


def _separated(cands, g: np.ndarray, min_separation: float) -> list[tuple[float, int]]:
    """The candidates, most prominent first, without those closer than ``min_separation`` to a
    more prominent one already kept."""
    chosen: list[tuple[float, int]] = []
    for prom, i in cands:
        if all(abs(g[i] - g[j]) >= min_separation for _, j in chosen):
            chosen.append((prom, i))
    return chosen


def _peak_record(samples, g, ys, prom: float, i: int, half_width: float) -> dict:
    """One peak (grid index ``i``): its angle, turn, smoothed and raw value (the raw signal's max
    within ±``half_width`` rad), prominence and the index of the nearest input sample."""
    th, yy, idx_all = samples
    t0 = g[i]
    k = int(np.argmin(np.abs(th - t0)))
    near = (th >= t0 - half_width) & (th <= t0 + half_width)
    raw = float(yy[near].max()) if np.any(near) else float(yy[k])
    return dict(
        theta=float(t0),
        theta_mod_2pi=float(t0 % TWO_PI),
        turn=int(math.floor(t0 / TWO_PI)) + 1,
        value=float(ys[i]),
        raw_value=raw,
        prominence=float(prom),
        index=int(idx_all[k]),
    )


def _most_prominent_per_turn(peaks: list[dict], n_per_turn: int) -> list[dict]:
    """The ``n_per_turn`` most prominent peaks of each turn."""
    by_turn: dict[int, list] = {}
    for p in peaks:
        by_turn.setdefault(p["turn"], []).append(p)
    return [
        p
        for lst in by_turn.values()
        for p in sorted(lst, key=lambda q: -q["prominence"])[:n_per_turn]
    ]


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


def jamming_analysis(
    theta,
    F,
    *,
    theta_range,
    min_separation=math.pi / 2,
    smooth=0.05,
    min_prominence=0.1,
    min_abs_prominence=1e-3,
    n_per_turn=2,
) -> dict:
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
    peaks = detect_peaks(
        theta,
        fh,
        min_separation=min_separation,
        smooth=smooth,
        min_prominence=min_prominence,
        min_abs_prominence=min_abs_prominence,
        theta_range=theta_range,
        n_per_turn=n_per_turn,
    )
    paper_mod = [a % TWO_PI for a in PAPER_JAMMING_ANGLES]
    out_peaks = [_jamming_peak(p, F, paper_mod) for p in peaks]
    events = {
        name: _jamming_event(out_peaks, name, paper_mod[j])
        for j, name in enumerate(PAPER_JAMMING_LABELS)
    }
    return dict(
        signal="Fh = sqrt(Fx^2 + Fy^2)",
        theta_range_rad=list(theta_range),
        method=dict(
            min_separation_rad=min_separation,
            smooth_rad=smooth,
            min_prominence_fraction=min_prominence,
            min_abs_prominence_N=min_abs_prominence,
            n_per_turn=n_per_turn,
        ),
        peaks=out_peaks,
        events=events,
    )


def _jamming_peak(p: dict, F: np.ndarray, paper_mod: list[float]) -> dict:
    """One peak of |F_h| (from ``detect_peaks``): its angle, forces, and the nearest of the
    paper's jamming angles (``paper_mod``, modulo 2π) with the signed offset from it."""
    i = p["index"]
    d = [_circ_dist(p["theta_mod_2pi"], a) for a in paper_mod]
    j = int(np.argmin(d))
    off = (p["theta_mod_2pi"] - paper_mod[j] + math.pi) % TWO_PI - math.pi
    return dict(
        turn=p["turn"],
        theta_rad=p["theta"],
        theta_over_pi=p["theta"] / math.pi,
        theta_mod_2pi_rad=p["theta_mod_2pi"],
        theta_mod_2pi_deg=math.degrees(p["theta_mod_2pi"]),
        theta_label=pi_label(p["theta"], 8),
        Fh_N=p["raw_value"],
        Fh_smoothed_N=p["value"],
        prominence_N=p["prominence"],
        Fx_N=float(F[i, 0]),
        Fy_N=float(F[i, 1]),
        Fz_N=float(F[i, 2]),
        nearest_paper_angle=PAPER_JAMMING_LABELS[j],
        offset_from_paper_rad=float(off),
        offset_from_paper_deg=math.degrees(off),
    )


def _jamming_event(peaks: list[dict], name: str, paper_angle: float) -> dict:
    """The peaks nearest the paper's angle ``name`` (``paper_angle`` modulo 2π) as one event:
    count, turns, circular mean angle, spread, offset from the paper and mean forces."""
    ps = [p for p in peaks if p["nearest_paper_angle"] == name]
    if not ps:
        return dict(paper_angle_mod_2pi_rad=paper_angle, count=0)
    mean, std = _circ_mean_std([p["theta_mod_2pi_rad"] for p in ps])
    off = (mean - paper_angle + math.pi) % TWO_PI - math.pi
    return dict(
        paper_angle_mod_2pi_rad=paper_angle,
        count=len(ps),
        turns=[p["turn"] for p in ps],
        mean_angle_mod_2pi_rad=mean,
        mean_angle_mod_2pi_deg=math.degrees(mean),
        angle_std_deg=math.degrees(std),
        mean_offset_from_paper_deg=math.degrees(off),
        mean_Fh_N=float(np.mean([p["Fh_N"] for p in ps])),
        mean_Fx_N=float(np.mean([p["Fx_N"] for p in ps])),
        mean_Fy_N=float(np.mean([p["Fy_N"] for p in ps])),
    )


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
        out.update(
            trace_rms_spread_N=None,
            trace_rms_N=None,
            peak_cv=None,
            mean_std_N=None,
            jamming_angle_std_deg=None,
            note="needs at least two complete turns >= 2 (θ in [2π, 6π])",
        )
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
            k: v.get("angle_std_deg") for k, v in jamming["events"].items()
        }
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
    b, p = _window_stats(theta, Fb, m), _window_stats(theta, Fp, m)
    res = dict(
        window_rad=[lo, hi],
        window_label=[pi_label(lo), pi_label(hi)],
        baseline=b,
        pitch=p,
        change=_change(b, p),
    )
    m2 = (theta >= lo + TWO_PI) & (theta <= hi + TWO_PI)
    if np.any(m2):
        b2, p2 = _window_stats(theta, Fb, m2), _window_stats(theta, Fp, m2)
        res["turn_to_turn"] = {
            name: _turn_to_turn(x1, x2)
            for name, (x1, x2) in {"baseline": (b, b2), "pitch": (p, p2)}.items()
        }
    res["rms_difference_N"] = _rms_difference(Fp - Fb, m, theta > hi)
    if pitch is not None:
        pitch = np.asarray(pitch, dtype=float)[:n]
        k = int(np.argmax(np.abs(pitch)))
        res["pitch_peak_deg"] = math.degrees(float(pitch[k]))
        res["pitch_peak_theta_rad"] = float(theta[k])
    return res


def _window_stats(theta, F, mask) -> dict:
    """Peaks of Fy (with their angles), |Fx|, |Fy|, Fz, the ratio |Fx|/|Fy| and the largest
    slope |dFy/dθ| over the samples in ``mask``."""
    fx, fy, fz = F[mask, 0], F[mask, 1], F[mask, 2]
    th = theta[mask]
    dfy = np.gradient(fy, th) if fy.size > 2 and np.all(np.diff(th) > 0) else np.zeros(1)
    ax, ay = float(np.max(np.abs(fx))), float(np.max(np.abs(fy)))
    return dict(
        Fy_max_N=float(fy.max()),
        Fy_max_theta_rad=float(th[np.argmax(fy)]),
        Fy_min_N=float(fy.min()),
        Fy_min_theta_rad=float(th[np.argmin(fy)]),
        absFx_peak_N=ax,
        absFy_peak_N=ay,
        Fz_max_N=float(fz.max()),
        Fz_min_N=float(fz.min()),
        Fx_over_Fy_peak_ratio=(ax / ay) if ay > 1e-12 else None,
        max_abs_dFy_dtheta_N_per_rad=float(np.max(np.abs(dfy))),
    )


def _change(kb: dict, kp: dict) -> dict:
    """pitch - baseline of every statistic but the angles, absolute and in %."""
    out = {}
    for k in kb:
        if k.endswith("theta_rad") or kb[k] is None or kp[k] is None:
            continue
        d = kp[k] - kb[k]
        out[k] = dict(
            baseline=kb[k],
            pitch=kp[k],
            change=d,
            change_percent=(100.0 * d / abs(kb[k])) if abs(kb[k]) > 1e-12 else None,
        )
    return out


def _turn_to_turn(x1: dict, x2: dict) -> dict:
    """One run's statistics in the window (``x1``) against the same event a turn later (``x2``)."""
    return dict(
        absFy_peak_ratio_window_to_next_turn=(x1["absFy_peak_N"] / x2["absFy_peak_N"])
        if x2["absFy_peak_N"] > 1e-12
        else None,
        Fy_max_ratio_window_to_next_turn=(x1["Fy_max_N"] / x2["Fy_max_N"])
        if abs(x2["Fy_max_N"]) > 1e-12
        else None,
        Fx_over_Fy_ratio_window=x1["Fx_over_Fy_peak_ratio"],
        Fx_over_Fy_ratio_next_turn=x2["Fx_over_Fy_peak_ratio"],
    )


def _rms_difference(diff: np.ndarray, window: np.ndarray, after: np.ndarray) -> dict:
    """RMS of pitch - baseline per component inside the window and after it (None: the run
    ends in the window)."""
    return {
        "window": {c: float(np.sqrt(np.mean(diff[window, i] ** 2))) for i, c in enumerate("xyz")},
        "after_window": (
            {c: float(np.sqrt(np.mean(diff[after, i] ** 2))) for i, c in enumerate("xyz")}
            if np.any(after)
            else None
        ),
    }


def analyse_run(theta, F, Fn_total, n_contact, max_pen, *, theta_lo=0.5 * math.pi) -> dict:
    """The analysis of one run over θ >= ``theta_lo`` (the first quarter P0 -> P1 is excluded):
    ``per_turn`` statistics, ``jamming`` peaks, turn-to-turn ``repeatability`` and overall maxima
    and means (see docs/reference_experiment.md)."""
    theta, F = np.asarray(theta, float), np.asarray(F, float)
    Fn_total, n_contact, max_pen = (np.asarray(x, float) for x in (Fn_total, n_contact, max_pen))
    rng = (theta_lo, float(theta[-1]))
    if not rng[1] > rng[0]:
        return dict(
            theta_range_rad=list(rng),
            note="the run ends before θ = π/2",
            per_turn=[],
            jamming=None,
            repeatability=None,
            max_penetration_mm=None,
            max_penetration_whole_run_mm=float(max_pen.max()),
        )
    jam = jamming_analysis(theta, F, theta_range=rng)
    rows = per_turn_stats(
        theta,
        F,
        theta_range=rng,
        extra={"Fn_total_N": Fn_total, "n_contact": n_contact, "max_penetration_mm": max_pen},
    )
    m = theta >= theta_lo
    return dict(
        theta_range_rad=list(rng),
        excluded="θ < π/2 (first quarter P0 -> P1, §4)",
        per_turn=rows,
        jamming=jam,
        repeatability=repeatability(theta, F, rows, jamming=jam),
        max_penetration_mm=float(max_pen[m].max()),
        max_penetration_whole_run_mm=float(max_pen.max()),
        max_Fh_N=float(np.hypot(F[m, 0], F[m, 1]).max()),
        max_abs_Fz_N=float(np.abs(F[m, 2]).max()),
        mean_Fz_N=float(F[m, 2].mean()),
        mean_Fn_total_N=float(Fn_total[m].mean()),
        mean_n_contact=float(n_contact[m].mean()),
    )
