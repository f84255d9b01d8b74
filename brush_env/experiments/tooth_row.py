"""The reference experiment on a tooth row (issue 13): press, then horizontal strokes along the row.

``brush-env reference --scene tooth_row`` runs it (``--mesh FILE`` puts the user's tooth mesh in
place of the procedural crowns).  The brush starts with its tips touching the crowns' buccal
plane (z = 0 of the scene, as the paper's plate), is pressed ``press_depth`` mm along the bristle
axis over the middle of the row at crown height ``y``, held, then driven ``strokes`` times along
the row (x) between ``x_range`` (rest-to-rest quintic strokes, peak ``speed``) -- the
horizontal scrub.  Outputs in ``out_dir`` (as the plate experiment's where they apply):
``timeseries.csv`` (TCP force and moment in the TCP frame, total normal force, gum force, tips in
contact, deepest penetration per step), ``tips.npz`` (tip positions and forces, sampled),
``summary.json`` (settings, motion, performance, forces per phase, coverage per region and per
tooth), ``forces_vs_time.png`` and ``coverage.png`` (the crowns coloured by what the tips
scrubbed, and the buccal coverage map).  Units: mm, N, N mm, s.
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np

from ..calibration import ensure_calibrated
from ..coverage import EffectiveSweep, crown_samples, gum_forces
from ..engine import Simulator
from ..engine.fidelity import level_settings
from ..engine.scene import surface_labels, tooth_surfaces, with_mesh
from ..engine.warmup import ensure_compiled, groups_for
from ..motion import R0, Approach, Hold, Press, Sequence
from .plan import check_press_depth, resolve_scene, say

#: effective tip force window [N] and cleaning radius [mm] of the coverage (configs/envs/
#: tooth_row.toml's tip_force_window and clean_radius)
TIP_WINDOW = (0.01, 0.2)
CLEAN_RADIUS = 0.5

#: units of the timeseries.csv columns
TIMESERIES_UNITS = dict(
    t="s",
    phase="0 press, 1 hold, 2 strokes",
    Fx="N (TCP frame: the force the TCP applies to the brush)",
    Fy="N",
    Fz="N",
    Mx="N mm (about the TCP, TCP frame)",
    My="N mm",
    Mz="N mm",
    Fn="N (total normal force on the tips)",
    F_gum="N (normal force of the tips touching the gum)",
    n_contact="tips in contact",
    max_pen="mm (deepest tip penetration)",
)

DEFAULTS = dict(
    press_depth=2.0,  # [mm] past the crowns' buccal plane (3 mm: gum peak 1.4 N > its 1 N limit)
    press_time=0.5,  # [s]
    hold_time=0.25,  # [s]
    speed=20.0,  # [mm/s] peak stroke speed (the plate experiment's tool speed)
    strokes=4,  # one-way strokes along the row
    x_range=(-9.0, 9.0),  # [mm] stroke ends (row centre 0; the brush is 22 mm long)
    y=3.5,  # [mm] stroke height on the crowns (CEJ = 0): the brush spans ~0.7 ... 6.3 mm
    dt=1e-3,  # [s]
    tips_dt=5e-3,  # [s] sampling of tips.npz
)


def scrub_motion(sim, motion):
    """(trajectory, phase starts) of ``stroke_motion`` for ``sim``'s scene with the arguments of
    ``motion`` (DEFAULTS' keys): the tips touch the crowns' highest point (z = 0 without crowns)."""
    teeth = tooth_surfaces(sim.scene)
    z_surf = max((float(s.vertices[:, 2].max()) for s in teeth), default=0.0)
    return stroke_motion(
        sim.touch_height(np.array(R0), z_surf),
        motion["press_depth"],
        motion["press_time"],
        motion["hold_time"],
        motion["speed"],
        int(motion["strokes"]),
        motion["x_range"],
        motion["y"],
    )


def stroke_motion(z_touch, press_depth, press_time, hold_time, speed, strokes, x_range, y):
    """(trajectory, phase start times (press, hold, strokes)) of the press-and-scrub motion."""
    x0, x1 = x_range
    p_touch = np.array([0.5 * (x0 + x1), y, z_touch])
    press = Press((p_touch, R0), press_depth, press_time)
    p, _ = press.end_pose
    segs = [press, Hold((p, R0), hold_time)] if hold_time > 0 else [press]
    ends = [x0] + [x1 if k % 2 else x0 for k in range(1, strokes)]
    for xe in ends:
        q = np.array([xe, y, p[2]])
        L = abs(q[0] - p[0])
        segs.append(Approach((p, R0), (q, R0), 1.875 * L / speed))
        p = q
    seq = Sequence(segs)
    return seq, tuple(float(t) for t in seq.start_times[:3])


def _analysis(rows: np.ndarray, cov) -> dict:
    """Forces over the strokes, the press peak, the deepest penetration and the coverage."""
    strokes = rows[rows[:, 1] == 2] if len(rows) else rows
    F = np.linalg.norm(strokes[:, 2:5], axis=1) if len(strokes) else np.zeros(0)

    def stat(x):
        return {"mean": float(np.mean(x)), "peak": float(np.max(x))} if len(x) else None

    analysis = {
        "strokes": {
            "tcp_force_N": stat(F),
            "normal_force_N": stat(strokes[:, 8]),
            "gum_force_N": stat(strokes[:, 9]),
            "tips_in_contact": stat(strokes[:, 10]),
        },
        "press_peak_normal_force_N": float(np.max(rows[:, 8])) if len(rows) else None,
        "max_penetration_mm": float(np.nanmax(rows[:, 11])) if len(rows) else None,
    }
    if cov is not None:
        analysis["coverage"] = {
            "reachable": cov.fraction,
            "regions": cov.by_region(),
            "teeth": cov.by_tooth(),
            "tip_force_window_N": list(TIP_WINDOW),
            "clean_radius_mm": CLEAN_RADIUS,
        }
    return analysis


#: engine steps per ``Simulator.follow`` call
CHUNK = 500


def run_tooth_row(
    brush=None,
    scene="tooth_row",
    out_dir="runs/tooth_row",
    *,
    mesh=None,
    mesh_units: str = "mm",
    fidelity=None,
    bodies=None,
    progress: bool = True,
    plots: bool = True,
    labels: dict | None = None,
    **motion,
) -> dict:
    """Run the press-and-scrub experiment; returns the summary dict (also in summary.json).
    ``motion``: any key of DEFAULTS (press_depth, press_time, hold_time, speed, strokes,
    x_range, y, dt, tips_dt); ``labels``: how the caller names them in error messages (the CLI:
    its flags)."""
    unknown = set(motion) - set(DEFAULTS)
    if unknown:
        raise ValueError(f"unknown motion keys {sorted(unknown)}: allowed {sorted(DEFAULTS)}")
    a = {**DEFAULTS, **motion}
    for k, unit in (("press_time", "s"), ("speed", "mm/s"), ("dt", "s"), ("tips_dt", "s")):
        if not (math.isfinite(a[k]) and a[k] > 0):
            raise ValueError(f"{say(k, a[k], unit, labels)} is out of range: must be > 0 ({unit})")
    if not (0.0 <= a["press_depth"] <= 6.0):
        raise ValueError(
            f"{say('press_depth', a['press_depth'], 'mm', labels)} is out of range: "
            "must be >= 0 and <= 6 (mm)"
        )
    t0 = time.perf_counter()
    # one SimSettings from the level (fidelity.level_settings); ``bodies`` wins over it
    over = {} if bodies is None else {"bodies_per_bristle": int(bodies)}
    settings = level_settings(fidelity, dt=float(a["dt"]), **over)
    bodies = settings.bodies_per_bristle or None
    scene_obj = resolve_scene(brush, scene, bodies)
    if mesh is not None:
        scene_obj = with_mesh(scene_obj, mesh, mesh_units)
    check_press_depth(a["press_depth"], scene_obj.brush, labels)
    # only the kernels this level runs (warmup.groups_for); `brush-env warmup` compiles all
    compile_s = ensure_compiled(
        notice=print if progress else None, groups=groups_for(settings, follow=True)
    )
    t_setup = time.perf_counter()
    ensure_calibrated(scene_obj.brush, settings)  # the reduced model of `fast`
    sim = Simulator(scene_obj, settings)
    teeth = tooth_surfaces(scene_obj)
    traj, phases = scrub_motion(sim, a)
    dt = settings.dt
    n = int(math.ceil(traj.duration / dt - 1e-9))
    times = np.arange(n + 1) * dt
    P, Rs, _, _ = traj.sample(times)
    cov = crown_samples(teeth, CLEAN_RADIUS) if teeth else None
    gum = np.array([lab == "gum" for lab in surface_labels(scene_obj)], bool)
    t_setup = time.perf_counter() - t_setup
    cols = ("t", "phase", "Fx", "Fy", "Fz", "Mx", "My", "Mz", "Fn", "F_gum", "n_contact", "max_pen")
    rows = np.full((n + 1, len(cols)), np.nan)
    stride = max(1, int(round(a["tips_dt"] / dt)))
    tips_t, tips_p, tips_f = [], [], []
    status, message = "ok", None
    sim.reset(P[0], Rs[0])
    sweep = EffectiveSweep(sim.model.n_bristles, TIP_WINDOW)
    from tqdm import tqdm

    bar = tqdm(total=n, unit="step", desc="tooth row", mininterval=1.0, disable=not progress)
    t_sim = time.perf_counter()
    done = 0
    iterations = 0
    last = None  # the last step's tips, forces and time (coverage.png)
    k = 1
    while k <= n:  # the steps in Simulator.follow calls (compiled, no Python between steps)
        run = sim.follow(P[k : k + CHUNK], Rs[k : k + CHUNK])
        fr, m = run.record, run.done
        fn = fr.fn[:m]
        fg = gum_forces(fn, fr.surf[:m], gum)
        for q in range(m):
            i = k + q
            ph = int(np.searchsorted(phases, times[i], side="right") - 1)
            R_tcp = Rs[i]  # the TCP's frame at the step's end (StepResult.tcp_force_tcp)
            rows[i] = (
                times[i],
                ph,
                *(R_tcp.T @ fr.FM[q, 0:3]),
                *(R_tcp.T @ fr.FM[q, 3:6]),
                fn[q].sum(),
                fg[q],
                np.count_nonzero(fn[q] > 0.0),
                fr.pen[q].max(),
            )
            if i % stride == 0:
                tips_t.append(times[i])
                tips_p.append(fr.tips[q, :, 0:3].copy())
                tips_f.append(fn[q].copy())
        iterations += int(fr.iters[:m].sum())
        if cov is not None and m:
            cov.sweep(sweep, fn, fr.cpt[:m])
        done = k + m - 1
        if m:
            last = (fr.tips[m - 1, :, 0:3], fn[m - 1], float(fr.t[m - 1]))
        bar.update(m)
        if run.error is not None:
            status, message = "diverged", str(run.error)
            break
        k += m
    bar.close()
    t_sim = time.perf_counter() - t_sim
    rows = rows[1 : done + 1]
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    np.savetxt(
        out_dir / "timeseries.csv",
        rows,
        delimiter=",",
        header=",".join(cols),  # units: TIMESERIES_UNITS
        comments="",
        fmt="%.9g",
    )
    np.savez_compressed(
        out_dir / "tips.npz",
        t=np.array(tips_t),
        tip_pos=np.array(tips_p),
        tip_normal_force=np.array(tips_f),
    )
    analysis = _analysis(rows, cov)
    files = ["timeseries.csv", "tips.npz", "summary.json"]
    if plots and len(rows):
        _plot_forces(out_dir / "forces_vs_time.png", rows, phases)
        files.append("forces_vs_time.png")
        if cov is not None and last is not None:
            _plot_coverage(out_dir / "coverage.png", sim, last, teeth, cov)
            files.append("coverage.png")
    sim_time = float(rows[-1, 0]) if len(rows) else 0.0
    summary = {
        "status": status,
        "message": message,
        "scene": scene_obj.name,
        "surfaces": surface_labels(scene_obj),
        "mesh": None if mesh is None else str(mesh),
        "settings": {
            "fidelity": None if fidelity is None else str(fidelity),
            "bodies_per_bristle": int(np.diff(sim.model.bstart).max()),
            "dt_s": dt,
            "max_substep_s": settings.max_substep,
            "element": settings.element,
            "tip_tip_sweeps": settings.tip_tip_sweeps,
        },
        "motion": {k: (list(v) if isinstance(v, tuple) else v) for k, v in a.items()},
        "timeseries_units": TIMESERIES_UNITS,
        "performance": {
            "compile_s": compile_s,
            "setup_s": t_setup,
            "sim_wall_time_s": t_sim,
            "simulated_s": sim_time,
            "wall_per_sim_s": t_sim / sim_time if sim_time else None,
            "real_time_factor": sim_time / t_sim if t_sim else None,
            "wall_time_s": time.perf_counter() - t0,
            # Newton iterations summed over the bristles, per step: machine-independent cost
            "newton_iterations_per_step": iterations / done if done else None,
        },
        "analysis": analysis,
        "files": files,
    }
    (out_dir / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def _plot_coverage(path, sim, last, teeth, cov) -> None:
    """coverage.png: the crowns coloured by what the tips scrubbed, with the bristles; ``last``:
    the last step's (tip positions [mm], tip normal forces [N], time [s])."""
    import matplotlib.pyplot as plt

    from ..viz.tooth_row import tooth_row_figure

    m = sim.model
    pos = sim.state.pos
    chains = np.stack([pos[m.bstart[b] : m.bstart[b + 1]][[0, -1]] for b in range(m.n_bristles)])
    tip_pos, fn, t = last
    chains = np.concatenate([chains, tip_pos[:, None]], axis=1)
    fig = tooth_row_figure(
        teeth,
        cov,
        chains,
        fn,
        480,
        title=f"coverage {cov.fraction:.1%} at the end of the run (t = {t:.2f} s)",
        legend=True,
    )
    fig.savefig(path, dpi=100)
    plt.close(fig)


#: what starts at each phase boundary after the first (``scrub_motion``'s phases)
PHASE_STARTS = ("hold", "strokes")


def _plot_forces(path, rows, phases):
    """forces_vs_time.png: TCP force, total normal and gum force; the phase boundaries dashed
    and named."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.2), dpi=110)
    t = rows[:, 0]
    for j, lab in ((2, "Fx"), (3, "Fy"), (4, "Fz")):
        ax.plot(t, rows[:, j], lw=0.8, label=f"TCP {lab}")
    ax.plot(t, rows[:, 8], "k", lw=0.9, label="normal force (all tips)")
    ax.plot(t, rows[:, 9], "m", lw=0.9, label="gum force")
    for ts, name in zip(phases[1:], PHASE_STARTS):
        ax.axvline(ts, color="0.6", lw=0.6, ls="--")
        # named where it stands, along the line (phases a fraction of a second apart on a
        # many-second axis would overlap written across)
        ax.annotate(
            f"{name} starts", (ts, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -3),
            textcoords="offset points", ha="left", va="top", rotation=90, fontsize=7,
            color="0.35",
        )  # fmt: skip
    ax.plot([], [], color="0.6", lw=0.6, ls="--", label="phase change (press, hold, strokes)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("force [N] (TCP frame)")
    ax.set_title("Forces on the brush: press, hold, then strokes along the row", fontsize=9)
    # below the axes: a legend inside would hide part of the curves
    ax.legend(fontsize=7, ncol=3, loc="upper center", bbox_to_anchor=(0.5, -0.16), frameon=False)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
