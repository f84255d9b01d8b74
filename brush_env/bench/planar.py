"""``brush-env bench planar``: the pymunk planar row against the 3-D engine, in one run.

The same stroke runs in both (issue 14), for both planar cuts of the default brush:

* across the rows (``cut="y"``: the 4 bristles at one head x, stroke along head y) and along a
  row (``cut="x"``: the 10 bristles of an inner row, stroke along head x);
* a flat plate;
* a 3 mm press in 0.5 s, a 0.2 s hold, a 20 mm drag at 20 mm/s, then the same back.

The 3-D engine runs the cut's bristles alone (``BrushConfig`` with only those bristles,
tip-tip contact on, the default 6 bodies at 1 ms, ``SimSettings`` defaults), the motion in the
cut's plane.
pymunk runs ``brush_env.planar.PlanarBrush`` at its defaults.

Reported per phase (press + hold, drag out, drag back):

* RMS error of the total contact force on the tips, vertical (Fz) and along the stroke (Fx),
  relative to the 3-D RMS (or 0.01 N per bristle where that is smaller): it counts a snap that
  happens a few ms apart in the two models as a large error;
* the error of the phase's mean force on the same scale (the force level);
* RMS tip-position error (x, z) [mm];
* the 3-D tips' largest out-of-plane excursion [mm] (what a planar model cannot have);
* wall time per simulated second of each.

Then pymunk's largest stable step, found by trial: the press with dt = 0.25 ... 4 x 2/omega_max
at safety 1.  The overlay plot goes to ``docs/figures/planar_vs_3d.png`` (``--plot PATH``).

    brush-env bench planar [--json] [--quick] [--plot PATH]
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

from .harness import emit, markdown_table, open_log

PRESS, HOLD, DRAG, SPEED = 0.5, 0.2, 20.0, 20.0  # s, s, mm, mm/s


def add_arguments(p) -> None:
    from ..user_errors import add_flag

    add_flag(p, "--json", "one JSON object per row on stdout (machine info on stderr)")
    add_flag(p, "--quick", "press and a 2 mm drag only (for tests)")
    p.add_argument("--plot", default="docs/figures/planar_vs_3d.png", help="overlay plot path")


def stroke(t, z_touch, drag=DRAG):
    """TCP (x, z) [mm] at times t: quintic 3 mm press, hold, drag +drag and back at SPEED with
    quintic rest-to-rest segments of the same peak speed; and the phase (0 press/hold, 1 out,
    2 back)."""
    t = np.asarray(t, float)
    T = 1.875 * drag / SPEED

    def q(u):
        u = np.clip(u, 0.0, 1.0)
        return u**3 * (10 - 15 * u + 6 * u * u)

    z = z_touch - 3.0 * q(t / PRESS)
    t1 = PRESS + HOLD
    x = drag * q((t - t1) / T) - drag * q((t - t1 - T) / T)
    phase = np.where(t < t1, 0, np.where(t < t1 + T, 1, 2))
    return x, z, phase, t1 + 2 * T


def _run_3d(row_brush, times, ss, zs, cut):
    """The cut's bristles alone in the 3-D engine, the TCP moving in the cut's plane: contact
    force on the tips (along the stroke, normal), tip positions (in-plane, z) and the tips'
    out-of-plane coordinate.  With the TCP at R0 = diag(1, -1, -1), head x is world x and head
    y is world -y."""
    from ..engine import Plane, Scene, SimSettings, Simulator
    from ..motion import R0

    sim = Simulator(Scene(row_brush, (Plane(),), tip_tip=True), SimSettings(dt=1e-3))
    R = np.array(R0)
    sgn, ax_in, ax_out = (1.0, 0, 1) if cut == "x" else (-1.0, 1, 0)

    def tcp(k):
        p = np.array([0.0, 0.0, zs[k]])
        p[ax_in] = sgn * ss[k]
        return p

    sim.reset(tcp(0), R)
    nb = sim.model.n_bristles
    F = np.zeros((len(times), 2))
    tips = np.zeros((len(times), nb, 2))
    out_of_plane = np.zeros((len(times), nb))
    t0 = time.perf_counter()
    for k in range(len(times)):
        if k:
            out = sim.step(tcp(k), R)
            F[k, 0] = sgn * out.tip_tangential_force[:, ax_in].sum()
            F[k, 1] = out.tip_normal_force.sum()
            tp = out.tip_pos
        else:
            tp = sim.tip_positions()
        tips[k, :, 0] = sgn * tp[:, ax_in]
        tips[k, :, 1] = tp[:, 2]
        out_of_plane[k] = tp[:, ax_out]
    return F, tips, out_of_plane, time.perf_counter() - t0


def _run_2d(brush, times, xs, zs, cut, settings=None):
    from ..planar import PlanarBrush, PlanarSettings, Profile

    pb = PlanarBrush(brush, Profile.flat(), settings or PlanarSettings(), cut=cut)
    sub = max(1, int(round((times[1] - times[0]) / pb.settings.dt)))
    pb.place(xs[0], zs[0])
    F = np.zeros((len(times), 2))
    tips = np.zeros((len(times), len(pb.tips), 2))
    tips[0] = pb.tip_positions()
    t0 = time.perf_counter()
    for k in range(1, len(times)):
        acc = np.zeros(2)
        for j in range(1, sub + 1):
            a = j / sub
            pb.step((1 - a) * xs[k - 1] + a * xs[k], (1 - a) * zs[k - 1] + a * zs[k])
            acc += pb.contact_forces().sum(axis=0)
        F[k] = acc / sub
        tips[k] = pb.tip_positions()
    return F, tips, time.perf_counter() - t0, pb


def largest_stable_step(brush, z_touch, cut="y") -> tuple[float, list]:
    """Largest dt (multiples of 2/omega_max) whose press completes with finite, bounded forces."""
    from ..planar import PlanarBrush, PlanarSettings, Profile

    w = PlanarBrush(brush, Profile.flat(), cut=cut).omega_max
    trials = []
    best = 0.0
    for f in (0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.0):
        dt = f * 2.0 / w
        ok = True
        try:
            pb = PlanarBrush(
                brush, Profile.flat(), PlanarSettings(dt=min(dt, 0.01), safety=1.0), cut=cut
            )
            pb.place(0.0, z_touch)
            n = max(1, int(PRESS / pb.settings.dt))
            for k in range(n):
                pb.step(0.0, z_touch - 3.0 * (k + 1) / n)
            f_end = float(np.abs(pb.contact_forces()).sum())
            ok = bool(np.isfinite(f_end) and f_end < 1e3)
        except (FloatingPointError, ValueError):
            ok = False
        trials.append((f, dt, ok))
        if ok:
            best = dt
    return best, trials


CUTS = {"y": "across the rows (stroke along head y)", "x": "along a row (stroke along head x)"}


def bench_planar(args) -> int:
    from ..engine import load_brush
    from ..planar import row_bristles

    log = open_log(args)
    brush = load_brush("default")
    rows, speed, curves = [], [], {}
    for cut, what in CUTS.items():
        sel, at = row_bristles(brush, cut)
        row_brush = dataclasses.replace(brush, bristles=tuple(sel))
        z_touch = max(b.length for b in sel) + sel[0].tip_radius
        drag = 2.0 if args.quick else DRAG
        _, _, _, T = stroke(0.0, z_touch, drag)
        times = np.arange(0.0, T + 1e-9, 1e-3)
        xs, zs, phase, _ = stroke(times, z_touch, drag)
        print(f"cut {cut} ({what}) at {at:g} mm: {len(sel)} bristles; {T:.3f} s", file=log)
        F3, tips3, oop, wall3 = _run_3d(row_brush, times, xs, zs, cut)
        F2, tips2, wall2, pb = _run_2d(row_brush, times, xs, zs, cut)
        curves[cut] = (times, F3, F2, phase)
        err_tip = np.linalg.norm(tips2 - tips3, axis=2)
        y_out = np.abs(oop - oop[0])
        for ph, name in ((0, "press + hold"), (1, "drag out"), (2, "drag back")):
            m = phase == ph
            if not m.any():
                continue
            r = dict(cut=cut, bristles=len(sel), phase=name)
            for j, comp in ((1, "Fz"), (0, "Fx")):
                ref = math.sqrt(np.mean(F3[m, j] ** 2))
                r[f"{comp}_3d_rms_N"] = ref
                r[f"{comp}_2d_rms_N"] = math.sqrt(np.mean(F2[m, j] ** 2))
                # relative to the larger of the 3-D RMS and 0.01 N x bristles (a force scale
                # where the 3-D force is ~0, e.g. Fx during the press)
                scale = max(ref, 0.01 * len(sel))
                r[f"{comp}_rel_err"] = math.sqrt(np.mean((F2[m, j] - F3[m, j]) ** 2)) / scale
                # the phase's mean force (its level, insensitive to when a snap happens)
                r[f"{comp}_mean_err"] = abs(np.mean(F2[m, j]) - np.mean(F3[m, j])) / scale
            r["tip_pos_rms_err_mm"] = float(np.sqrt(np.mean(err_tip[m] ** 2)))
            r["out_of_plane_max_mm"] = float(y_out[m].max())
            r["within_10pct"] = bool(r["Fz_rel_err"] <= 0.1 and r["Fx_rel_err"] <= 0.1)
            r["mean_within_10pct"] = bool(r["Fz_mean_err"] <= 0.1 and r["Fx_mean_err"] <= 0.1)
            rows.append(emit(args, dict(table="error", **r)))
        best, trials = largest_stable_step(row_brush, z_touch, cut)
        speed.append(
            emit(
                args,
                dict(
                    table="speed",
                    cut=cut,
                    simulated_s=float(T),
                    wall_per_sim_3d=wall3 / T,
                    wall_per_sim_2d=wall2 / T,
                    pymunk_dt=pb.settings.dt,
                    mass_scale=pb.settings.mass_scale,
                    two_over_omega_max_s=2.0 / pb.omega_max,
                    largest_stable_dt_s=best,
                    trials=[dict(factor=f, dt=dt, ok=ok) for f, dt, ok in trials],
                ),
            )
        )
    if not args.json:
        print(
            markdown_table(
                rows,
                [
                    ("cut", lambda r: f"{r['cut']} ({r['bristles']})"),
                    ("phase", lambda r: r["phase"]),
                    (
                        "Fz rms 3-D / 2-D [N]",
                        lambda r: f"{r['Fz_3d_rms_N']:.3f} / {r['Fz_2d_rms_N']:.3f}",
                    ),
                    ("Fz error", lambda r: f"{100 * r['Fz_rel_err']:.1f} %"),
                    ("Fz mean err", lambda r: f"{100 * r['Fz_mean_err']:.1f} %"),
                    (
                        "Fx rms 3-D / 2-D [N]",
                        lambda r: f"{r['Fx_3d_rms_N']:.3f} / {r['Fx_2d_rms_N']:.3f}",
                    ),
                    ("Fx error", lambda r: f"{100 * r['Fx_rel_err']:.1f} %"),
                    ("Fx mean err", lambda r: f"{100 * r['Fx_mean_err']:.1f} %"),
                    ("tip pos rms err [mm]", lambda r: f"{r['tip_pos_rms_err_mm']:.3f}"),
                    ("3-D out-of-plane max [mm]", lambda r: f"{r['out_of_plane_max_mm']:.3f}"),
                    (
                        "within 10 %: rms / mean",
                        lambda r: (
                            f"{'yes' if r['within_10pct'] else 'no'} / "
                            f"{'yes' if r['mean_within_10pct'] else 'no'}"
                        ),
                    ),
                ],
            )
        )
        print()
        print(
            markdown_table(
                speed,
                [
                    ("cut", lambda r: r["cut"]),
                    ("3-D wall / sim s", lambda r: f"{r['wall_per_sim_3d']:.3f}"),
                    ("pymunk wall / sim s", lambda r: f"{r['wall_per_sim_2d']:.3f}"),
                    ("pymunk dt [s]", lambda r: f"{r['pymunk_dt']:g}"),
                    ("mass scale", lambda r: f"{r['mass_scale']:g}"),
                    ("2/omega_max [s]", lambda r: f"{r['two_over_omega_max_s']:.3g}"),
                    ("largest stable dt (trial) [s]", lambda r: f"{r['largest_stable_dt_s']:.3g}"),
                    (
                        "trials (x 2/omega_max)",
                        lambda r: ", ".join(
                            f"{t['factor']:g} {'ok' if t['ok'] else 'blew up'}" for t in r["trials"]
                        ),
                    ),
                ],
            )
        )
    if args.plot and not args.quick:
        _plot(args.plot, curves)
        print(f"plot: {args.plot}", file=log)
    return 0


def _plot(path, curves):
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, axs = plt.subplots(2, len(curves), figsize=(11, 5), dpi=110, sharex="col", squeeze=False)
    for c, (cut, (t, F3, F2, phase)) in enumerate(curves.items()):
        for r, (j, name) in enumerate(((1, "Fz (normal, all tips)"), (0, "F along the stroke"))):
            ax = axs[r, c]
            ax.plot(t, F3[:, j], "k", lw=1.0, label="3-D engine (6 bodies, 1 ms)")
            ax.plot(t, F2[:, j], "tab:orange", lw=0.9, label="pymunk planar")
            ax.set_ylabel(f"{name} [N]", fontsize=8)
            for ts in t[np.flatnonzero(np.diff(phase)) + 1]:
                ax.axvline(ts, color="0.6", lw=0.6, ls="--")
        axs[0, c].set_title(f"cut {cut}: {CUTS[cut]}", fontsize=9)
        axs[1, c].set_xlabel("t [s]")
    axs[0, 0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
