"""The paper's circular reference experiment end to end (Cirelli et al., Machines 2023, §3–5).

The brush starts with its tips touching a flat plate, is pressed 3 mm along the bristle axis, then
the robot drives it four times round a 20 mm circle built, as on the UR5, from four MoveL control
points with blend radius = circle radius (Algorithm 1, Figure 6).  Forces at the TCP are reported
against the rotation angle θ (0 at P0; the first quarter is excluded from the analysis) and show
two jamming peaks per turn (the paper: near 9π/4 and 13π/4).  With a pitch error the run is
repeated with the 1° pitch perturbation of eq 12 (§5.2, Figure 10).  Units: mm, N, N·mm, s, rad.
"""

from __future__ import annotations

import time
from pathlib import Path

from ..engine.fidelity import level_settings, load_fidelity
from ..engine.warmup import ensure_compiled, groups_for
from .analysis import PAPER_JAMMING_ANGLES, analyse_run, pitch_asymmetry
from .outputs import (
    performance_info,
    settings_info,
    trajectory_info,
    write_run_files,
    write_summary,
)
from .plan import DEFAULTS, check_press_depth, check_run_args, make_plan, resolve_scene
from .plots import plot_deformed_shapes, plot_forces_vs_angle
from .record import simulate_runs

PAPER = dict(
    reference="Cirelli et al., Machines 2023, §4-5, Figures 7, 9, 10",
    jamming_angles_rad=list(PAPER_JAMMING_ANGLES),
    jamming_angles_label=["9π/4", "13π/4"],
    jamming_angles_mod_2pi_deg=[45.0, 225.0],
)


def run_reference(
    brush=None,
    scene=None,
    out_dir="runs/reference",
    turns: float = DEFAULTS["turns"],
    pitch_error_deg: float = 0.0,
    dt: float = DEFAULTS["dt"],
    bodies: int | None = None,
    integrator: str = DEFAULTS["integrator"],
    element: str = DEFAULTS["element"],
    speed: float = DEFAULTS["speed"],
    accel: float = DEFAULTS["accel"],
    progress: bool = True,
    *,
    path: str = DEFAULTS["path"],
    head_yaw_deg: float = DEFAULTS["head_yaw_deg"],
    p0_angle_deg: float = DEFAULTS["p0_angle_deg"],
    clockwise: bool = DEFAULTS["clockwise"],
    max_substep: float | None = None,
    fidelity=None,
    radius: float = DEFAULTS["radius"],
    press_depth: float = DEFAULTS["press_depth"],
    press_time: float = DEFAULTS["press_time"],
    hold_time: float = DEFAULTS["hold_time"],
    pitch_window=DEFAULTS["pitch_window"],
    tips_dt: float = DEFAULTS["tips_dt"],
    shapes_dt: float = DEFAULTS["shapes_dt"],
    plots: bool = True,
    labels: dict | None = None,
) -> dict:
    """Run the experiment and write its outputs to ``out_dir``; returns the summary dict.

    ``brush``: a ``BrushConfig``, a path or a name in configs/brushes (default: the scene's);
    ``scene``: a ``Scene``, path or name (default ``flat_plate``); ``turns`` (fractional for quick
    runs: cut when θ reaches 2π·turns); ``pitch_error_deg`` (0: none; else a second run with the
    eq-12 pitch of this amplitude [deg] in ``pitch_window`` [rad]); ``dt`` [s]; ``bodies`` per
    bristle (override); ``integrator`` 'bdf2' | 'euler'; ``element`` 'mid' | 'paper' (beam
    element); ``speed`` [mm/s]; ``accel`` [mm/s²]; ``path`` 'movel' (Algorithm 1) | 'circle';
    the set-up the paper leaves open: ``head_yaw_deg`` (the head turned on the flange about TCP
    z, default 90: handle along TCP y), ``p0_angle_deg`` (P0's polar angle about the centre,
    default 180), ``clockwise`` (default False); ``max_substep`` [s]: SimSettings.max_substep
    (None: its default, 1 ms); ``fidelity``: a fidelity level (name in configs/fidelity, path or
    ``Fidelity``, ``brush_env.engine.fidelity``) that sets the bodies per bristle, element,
    integrator, solver step limit and tip-tip solve; ``bodies`` and ``max_substep``, if given,
    still override it, and so do ``integrator``/``element`` when they differ from DEFAULTS.
    ``labels``: how the caller names the arguments in error messages (the CLI: its flags).
    Files: docs/reference_experiment.md.
    """
    args = dict(locals())
    t_wall0 = time.perf_counter()
    check_run_args(args, labels)
    # one SimSettings from the level (fidelity.level_settings); explicit arguments win over it
    over: dict = {"dt": float(dt)}
    if max_substep is not None:
        over["max_substep"] = float(max_substep)
    if bodies is not None:
        over["bodies_per_bristle"] = int(bodies)
    for key in ("integrator", "element"):
        if fidelity is None or args[key] != DEFAULTS[key]:
            over[key] = args[key]
    fid = None if fidelity is None else load_fidelity(fidelity)
    settings = level_settings(fid, **over)
    if fid is not None:
        bodies = settings.bodies_per_bristle
        args["bodies"] = bodies
        args["fidelity"] = fid.name
    scene_obj = resolve_scene(brush, scene, bodies, head_yaw_deg)
    check_press_depth(press_depth, scene_obj.brush, labels)  # inputs valid past here
    # only the kernels this level runs (warmup.groups_for); `brush-env warmup` compiles all
    compile_s = ensure_compiled(
        notice=print if progress else None, groups=groups_for(settings, follow=True)
    )
    t_setup = time.perf_counter()
    plan = make_plan(scene_obj, settings, args)
    t_setup = time.perf_counter() - t_setup
    recs, status, perf = simulate_runs(plan, progress)
    analysis = analyse(plan, recs, pitch_window)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    files = write_run_files(out_dir, plan, recs, scene_obj.brush, settings.dt)
    t_plot = time.perf_counter()
    if plots:
        files.update(draw_figures(out_dir, plan, recs, analysis, args))
    t_plot = time.perf_counter() - t_plot
    return write_summary(
        out_dir,
        dict(
            status="ok" if all(v == "ok" for v in status.values()) else "diverged",
            run_status=status,
            paper=PAPER,
            settings=settings_info(plan, settings, args),
            trajectory=trajectory_info(plan, path=path, radius=radius, speed=speed, accel=accel),
            performance=performance_info(
                perf,
                recs,
                wall_s=time.perf_counter() - t_wall0,
                setup_s=t_setup,
                compile_s=compile_s,
                plot_s=t_plot,
            ),
            analysis=analysis,
            files=files,
        ),
    )


def analyse(plan, recs, pitch_window) -> dict:
    """Jamming peaks, per-turn statistics and repeatability of every run (§5.1); with a pitch
    run, the asymmetry it introduces in the perturbed window (§5.2)."""
    th = plan.theta
    analysis = {
        name: analyse_run(
            th[: r.n],
            r.step["F"][: r.n],
            r.step["Fn"][: r.n],
            r.step["n_contact"][: r.n],
            r.step["max_pen"][: r.n],
        )
        for name, r in recs.items()
    }
    if "pitch" in recs:
        n = min(recs["baseline"].n, recs["pitch"].n)
        analysis["pitch_asymmetry"] = pitch_asymmetry(
            th[:n],
            recs["baseline"].step["F"][:n],
            recs["pitch"].step["F"][:n],
            pitch_window,
            pitch=plan.pitch["pitch"][:n],
        )
    return analysis


def draw_figures(out_dir: Path, plan, recs, analysis, args) -> dict:
    """Figure 7 (forces_vs_angle.png), Figure 10 with a pitch run (forces_vs_angle_pitch.png)
    and Figure 9 (deformed_shapes.png); returns {key: file name}."""
    brush_cfg = plan.scene.brush
    title = (
        f"brush '{brush_cfg.name}', {args['path']}, v = {args['speed']:g} mm/s, "
        f"dt = {args['dt']:g} s"
    )
    files = {}
    figures = [("forces_vs_angle", {"baseline": recs["baseline"]})]
    if "pitch" in recs:
        figures.append(("forces_vs_angle_pitch", recs))
    for key, runs in figures:
        plot_forces_vs_angle(
            out_dir / f"{key}.png",
            runs,
            plan.theta,
            analysis,
            plan.pitch,
            args["pitch_window"],
            title=title,
            complete=plan.n_steps == plan.n_full,
        )
        files[key] = f"{key}.png"
    plot_deformed_shapes(
        out_dir / "deformed_shapes.png",
        recs["baseline"],
        plan.theta,
        plan.poses["baseline"],
        plan.sim,
        brush_cfg,
        analysis["baseline"],
        plan.times,
    )
    files["deformed_shapes"] = "deformed_shapes.png"
    return files
