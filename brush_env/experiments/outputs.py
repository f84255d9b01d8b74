"""Files of a reference run: timeseries.csv (columns in ``CSV_COLUMNS`` with units), tips.npz,
summary.json (JSON-safe numbers)."""

from __future__ import annotations

import json
import math

import numpy as np

from ..engine.rotation import rotation_vectors
from ..motion import BLEND_RULE, movel_circle_deviation

#: Sign convention of every force in the outputs and figures.
FORCE_CONVENTION = (
    "tcp_force: the force the robot applies to the brush, robot base frame "
    "(z up); moments in N·mm about the TCP"
)

#: Columns of timeseries.csv, in order, with units.
CSV_COLUMNS = (
    "time_s",  # simulation time
    "phase",  # 0 press, 1 hold, 2 circle
    "theta_rad",  # rotation angle θ (0 at P0, unwrapped)
    "x_mm",
    "y_mm",
    "z_mm",  # TCP position, robot base frame
    "rx_rad",
    "ry_rad",
    "rz_rad",  # TCP orientation as a rotation vector (UR convention)
    "pitch_rad",  # imposed eq-12 pitch (0 without --pitch-error)
    "Fx_N",
    "Fy_N",
    "Fz_N",  # force the robot applies to the brush, base frame
    "Mx_Nmm",
    "My_Nmm",
    "Mz_Nmm",  # moment about the TCP, base frame
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
    "status",
    "paper",
    "settings",
    "trajectory",
    "performance",
    "analysis",
    "files",
)


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


def _brush_info(brush_cfg):
    """(materials, groups) of a brush for summary.json."""
    mats, groups = {}, {}
    for b in brush_cfg.bristles:
        m = b.material
        mats[m.name] = dict(
            name=m.name,
            E_MPa=m.E,
            nu=m.nu,
            density_t_per_mm3=m.density,
            damping_ratio=m.damping_ratio,
        )
        sec = dict(kind=b.section.kind, width_mm=b.section.width, thickness_mm=b.section.thickness)
        g = groups.setdefault(
            b.group,
            dict(
                count=0,
                length_mm=b.length,
                bodies=b.bodies,
                section=sec,
                material=m.name,
                tip_radius_mm=b.tip_radius,
            ),
        )
        g["count"] += 1
    return list(mats.values()), groups


def _write_csv(path, r, times, phase, theta, P, R, pitch):
    s = r.step
    n = r.n
    F = s["F"][:n]
    rv = rotation_vectors(R)
    cols = [
        times,
        phase,
        theta,
        P[:, 0],
        P[:, 1],
        P[:, 2],
        rv[:, 0],
        rv[:, 1],
        rv[:, 2],
        pitch,
        F[:, 0],
        F[:, 1],
        F[:, 2],
        s["M"][:n, 0],
        s["M"][:n, 1],
        s["M"][:n, 2],
        np.hypot(F[:, 0], F[:, 1]),
        s["Fn"][:n],
        s["Ft"][:n],
        s["Ft_abs"][:n],
        s["n_contact"][:n],
        s["max_pen"][:n],
        s["iters"][:n],
        s["subs"][:n],
    ]
    data = np.column_stack([np.asarray(c, dtype=float) for c in cols])
    fmt = ["%.6f", "%d", "%.9g"] + ["%.9g"] * 17 + ["%d", "%.6g", "%d", "%d"]
    np.savetxt(path, data, delimiter=",", header=",".join(CSV_COLUMNS), comments="", fmt=fmt)


def _savez_fast(path, **arrays) -> None:
    """``np.savez_compressed`` at deflate level 1 (numpy's uses zlib's default, 6): the same
    .npz for ``np.load``; the reference's tips.npz 5 % larger, 0.2 s faster to write (0.37 s)."""
    import zipfile

    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=1) as z:
        for name, value in arrays.items():
            with z.open(f"{name}.npy", "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.asanyarray(value), allow_pickle=False)


def _write_npz(path, r, times, theta, pose, sim, brush_cfg, dt):
    t, sh = r.tips, r.shapes
    nt, ns = r.nt, r.ns
    m = sim.model
    P, R = pose
    rows_t, rows_s = t["row"][:nt], sh["row"][:ns]
    roots_s = P[rows_s][:, None, :] + np.einsum("kij,bj->kbi", R[rows_s], m.root_p)
    _savez_fast(
        path,
        time=times[rows_t],
        theta=theta[rows_t],
        step_index=rows_t,
        tip_pos=t["pos"][:nt],
        tip_vel=t["vel"][:nt],
        tip_normal_force=t["fn"][:nt],
        tip_tangential_force=t["ft"][:nt],
        tip_contact_force=t["fc"][:nt],
        tip_in_contact=t["contact"][:nt],
        tip_sliding=t["sliding"][:nt],
        tip_penetration=t["pen"][:nt],
        tip_tip_force=t["tiptip"][:nt],
        tcp_pos=P[rows_t],
        tcp_rot=R[rows_t],
        shape_time=times[rows_s],
        shape_theta=theta[rows_s],
        shape_step_index=rows_s,
        shape_body_pos=sh["body"][:ns],
        shape_tip_pos=sh["tip"][:ns],
        shape_root_pos=roots_s.astype(np.float32),
        shape_in_contact=sh["contact"][:ns],
        shape_tcp_pos=P[rows_s],
        bstart=m.bstart,
        root_p_tcp=m.root_p,
        bristle_length=m.length,
        tip_radius=m.tip_radius,
        group=np.array([b.group for b in brush_cfg.bristles]),
        dt=np.float64(dt),
        units=np.array(
            "mm, s, N; world = robot base frame, z up; tip_contact_force = force of "
            "the surface on the tip (normal + tangential)"
        ),
    )


def write_run_files(out_dir, plan, recs, brush_cfg, dt) -> dict:
    """timeseries{,_pitch}.csv and tips{,_pitch}.npz of every run; returns {key: file name}."""
    files = {}
    for name, r in recs.items():
        sfx = "" if name == "baseline" else "_pitch"
        n = r.n
        Pn, Rn = plan.poses[name]
        csv_path = out_dir / f"timeseries{sfx}.csv"
        _write_csv(
            csv_path,
            r,
            plan.times[:n],
            plan.phase[:n],
            plan.theta[:n],
            Pn[:n],
            Rn[:n],
            plan.pitch[name][:n],
        )
        npz_path = out_dir / f"tips{sfx}.npz"
        _write_npz(npz_path, r, plan.times, plan.theta, plan.poses[name], plan.sim, brush_cfg, dt)
        files[f"timeseries{sfx}"] = csv_path.name
        files[f"tips{sfx}"] = npz_path.name
    return files


def trajectory_info(plan, *, path, radius, speed, accel) -> dict:
    """summary.json's ``trajectory``: phases, P0, heights, circle, cut, MoveL blend deviation."""
    ps = plan.phase_starts
    info = dict(
        path=path,
        duration_s=float(plan.times[-1]),
        phase_starts_s=dict(press=ps[0], hold=ps[1] if len(ps) > 2 else None, circle=ps[-1]),
        start_point_P0_mm=list(plan.poses["baseline"][0][0]),
        touch_tcp_z_mm=plan.touch_z,
        plate_z_mm=plan.plate_z,
        circle_center_mm=list(np.asarray(plan.start_xy) + [radius, 0.0]),
        direction="counter-clockwise about +z (seen from above), P0 at polar angle π",
        theta_end_rad=float(plan.theta[-1]),
        cut_before_end_of_motion=bool(plan.n_steps < plan.n_full),
        speed_mm_s=speed,
        accel_mm_s2=accel,
        accel_ramp_s=speed / accel,
        accel_ramp_mm=speed**2 / (2 * accel),
    )
    if path == "movel":
        info["movel"] = dict(
            control_points="corners of the square circumscribed about the circle, P1 first after "
            "P0 (paper_circle_waypoints, 'circumscribed')",
            blend_radius_mm=radius,
            blend_rule=BLEND_RULE,
            deviation_from_circle=movel_circle_deviation([0.0, 0.0, 0.0], radius, radius),
        )
    return info


def settings_info(plan, settings, args: dict) -> dict:
    """summary.json's ``settings``: brush, material, scene and every run argument with units."""
    brush_cfg, scene = plan.scene.brush, plan.scene
    materials, groups = _brush_info(brush_cfg)
    return dict(
        brush=dict(
            name=brush_cfg.name,
            file=brush_cfg.source,
            n_bristles=brush_cfg.n_bristles,
            bodies_total=plan.sim.model.n_bodies,
            groups=groups,
            max_length_mm=brush_cfg.max_length,
        ),
        material=materials,
        scene=dict(name=scene.name, tip_tip=scene.tip_tip, plate_z_mm=plan.plate_z),
        dt_s=settings.dt,
        max_substep_s=settings.max_substep,
        fidelity=args.get("fidelity"),
        tip_tip_sweeps=settings.tip_tip_sweeps,
        integrator=settings.integrator,
        element=settings.element,
        bodies=sorted({b.bodies for b in brush_cfg.bristles}),
        bodies_override=args["bodies"],
        speed_mm_s=args["speed"],
        accel_mm_s2=args["accel"],
        path=args["path"],
        head_yaw_deg=args["head_yaw_deg"],
        p0_angle_deg=args["p0_angle_deg"],
        clockwise=args["clockwise"],
        radius_mm=args["radius"],
        turns=args["turns"],
        press_depth_mm=args["press_depth"],
        press_time_s=args["press_time"],
        press_profile="quintic (minimum jerk)",
        hold_time_s=args["hold_time"],
        pitch_error_deg=args["pitch_error_deg"],
        pitch_window_rad=list(args["pitch_window"]),
        pitch_axis="TCP y (the head's pitch axis), pivot at the TCP",
        tips_dt_s=plan.tips_stride * settings.dt,
        shapes_dt_s=plan.shapes_stride * settings.dt,
        force_convention=FORCE_CONVENTION,
    )


def performance_info(perf, recs, *, wall_s, setup_s, compile_s, plot_s) -> dict:
    """summary.json's ``performance``; the real-time factor excludes the first-start compile."""
    wall_sim = sum(p["wall_s"] for p in perf.values())
    sim_time = sum(p["simulated_s"] for p in perf.values())
    base = recs["baseline"]
    return dict(
        wall_time_s=wall_s,
        compile_s=compile_s,
        setup_s=setup_s,
        sim_wall_time_s=wall_sim,
        simulated_time_s=sim_time,
        real_time_factor=sim_time / wall_sim if wall_sim > 0 else None,
        plot_s=plot_s,
        runs=perf,
        newton_iterations_per_step=float(base.step["iters"][1 : base.n].mean())
        if base.n > 1
        else None,
        substeps_total=int(base.step["subs"][: base.n].sum()),
    )


def write_summary(out_dir, summary: dict) -> dict:
    """summary.json (JSON-safe); returns what was written."""
    summary["files"]["summary"] = "summary.json"
    safe = _json(summary)
    with open(out_dir / "summary.json", "w") as f:
        json.dump(safe, f, indent=2, ensure_ascii=False)
    return safe
