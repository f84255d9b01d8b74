"""``brush-env reference``: the paper's circular experiment from the command line."""

from __future__ import annotations

import argparse
import math

from ..user_errors import add_flag
from .plan import DEFAULTS, pitch_window_cut
from .run import run_reference

#: how the messages name each argument: the flag the user typed (with the flag's unit)
LABELS = {
    "turns": "--turns",
    "dt": "--dt",
    "speed": "--speed",
    "accel": "--accel",
    "head_yaw_deg": "--head-yaw",
    "p0_angle_deg": "--p0-angle",
    "pitch_error_deg": "--pitch-error",
    "press_depth": "--press-depth",
}
#: the largest --bodies (BristleConfig's own limit)
MAX_BODIES = 200


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``brush-env reference`` (units in each help text)."""
    d = DEFAULTS
    parser.description = (
        "Run the paper's circular reference experiment (3 mm press, four turns "
        "of a 20 mm circle) and write timeseries.csv, tips.npz, "
        "forces_vs_angle.png, deformed_shapes.png and summary.json (with "
        "--pitch-error also "
        "timeseries_pitch.csv, tips_pitch.npz and forces_vs_angle_pitch.png)."
    )
    parser.add_argument(
        "--brush",
        default=None,
        help="brush config file or name in configs/brushes (default: the scene's)",
    )
    parser.add_argument(
        "--scene",
        default=None,
        help="scene config file or name in configs/scenes (default: flat_plate)",
    )
    parser.add_argument("--out", default="runs/reference", help="output directory")
    parser.add_argument(
        "--pitch-error",
        type=float,
        default=0.0,
        metavar="DEG",
        help="also run with the eq-12 pitch perturbation of this amplitude [deg] "
        "and produce the Figure-10 comparison (paper: 1)",
    )
    parser.add_argument(
        "--turns",
        type=float,
        default=d["turns"],
        help="number of turns (paper: 4; fractions allowed for quick checks)",
    )
    parser.add_argument("--dt", type=float, default=d["dt"], help="time step [s]")
    parser.add_argument(
        "--bodies",
        type=int,
        default=None,
        help="override the bodies per bristle of the brush config",
    )
    parser.add_argument(
        "--integrator",
        choices=("bdf2", "euler"),
        default=d["integrator"],
        help="implicit scheme: bdf2 (2nd order, default) or euler (1st order)",
    )
    parser.add_argument(
        "--element",
        choices=("mid", "paper"),
        default=d["element"],
        help="beam element: mid (default; accurate with few bodies in buckled contact) or paper "
        "(the paper's element, to reproduce it); docs/model.md",
    )
    parser.add_argument(
        "--fidelity",
        default=None,
        help="fidelity level: reference, paper, balanced, coarse, reduced, fast (configs/fidelity) "
        "or a TOML path; sets bodies, element, integrator, solver step limit and tip-tip solve "
        "(--bodies, --element, --integrator given explicitly still win)",
    )
    parser.add_argument("--speed", type=float, default=d["speed"], help="tool speed [mm/s]")
    parser.add_argument(
        "--accel", type=float, default=d["accel"], help="tool acceleration [mm/s^2]"
    )
    parser.add_argument(
        "--path",
        choices=("movel", "circle"),
        default=d["path"],
        help="circle built from four MoveL points with blends (paper Algorithm 1) "
        "or the exact circle",
    )
    parser.add_argument(
        "--head-yaw",
        type=float,
        default=d["head_yaw_deg"],
        metavar="DEG",
        help="the head turned on the flange about TCP z [deg] (default 90: the handle along TCP "
        "y, which puts the jams at the paper's 9pi/4 and 13pi/4; docs/reference_experiment.md)",
    )
    parser.add_argument(
        "--p0-angle",
        type=float,
        default=d["p0_angle_deg"],
        metavar="DEG",
        help="polar angle of the start point P0 about the circle's centre [deg] (default 180)",
    )
    add_flag(parser, "--clockwise", "travel the circle clockwise seen from above the plate")
    parser.add_argument(
        "--mesh",
        default=None,
        metavar="FILE",
        help="a closed tooth mesh (STL, OBJ, PLY, ...) in place of the tooth row's crowns "
        "(with --scene tooth_row; placed with its top at z = 0, centred in x, y; the surface "
        "to brush must face +z); runs the press-and-scrub experiment",
    )
    parser.add_argument(
        "--mesh-units",
        default="mm",
        choices=("mm", "cm", "m", "um", "in"),
        help="units of the --mesh file's coordinates (default mm)",
    )
    parser.add_argument(
        "--press-depth",
        type=float,
        default=None,
        metavar="MM",
        help="press depth past contact [mm] (default: plate 3, tooth row 2)",
    )
    add_flag(parser, "--no-progress", "no progress bar")


def _is_tooth_scene(args) -> bool:
    from ..engine import load_scene
    from ..engine.scene import tooth_surfaces

    if args.mesh is not None:
        return True
    return bool(args.scene) and bool(tooth_surfaces(load_scene(args.scene)))


def run_teeth(args) -> int:
    """The tooth-row press-and-scrub experiment (brush_env.experiments.tooth_row)."""
    from .tooth_row import run_tooth_row

    extra = {} if args.press_depth is None else {"press_depth": args.press_depth}
    s = run_tooth_row(
        brush=args.brush,
        scene=args.scene or "tooth_row",
        out_dir=args.out,
        mesh=args.mesh,
        mesh_units=args.mesh_units,
        fidelity=args.fidelity,
        bodies=args.bodies,
        progress=not args.no_progress,
        dt=args.dt,
        labels=LABELS,
        **extra,
    )
    perf, an = s["performance"], s["analysis"]
    print(
        f"status: {s['status']}; wall {perf['wall_time_s']:.1f} s (simulation "
        f"{perf['sim_wall_time_s']:.1f} s, real-time factor {perf['real_time_factor'] or 0:.2f}); "
        f"outputs in {args.out}"
    )
    st = an["strokes"]
    if st["normal_force_N"]:
        print(
            f"  strokes: normal force mean {st['normal_force_N']['mean']:.2f} N, peak "
            f"{st['normal_force_N']['peak']:.2f} N; gum force peak "
            f"{st['gum_force_N']['peak']:.2f} N"
        )
    if "coverage" in an:
        c = an["coverage"]
        regions = ", ".join(f"{k} {100 * v:.1f} %" for k, v in c["regions"].items())
        print(f"  coverage {100 * c['reachable']:.1f} % of the reachable area ({regions})")
    return 0 if s["status"] == "ok" else 1


def _check_bodies(bodies: int | None) -> None:
    """--bodies, in the flag's terms (0 would silently mean "the brush's own")."""
    from ..engine.checks import ConfigError

    if bodies is not None and not 1 <= bodies <= MAX_BODIES:
        raise ConfigError(
            f"--bodies = {bodies} is out of range: must be >= 1 and <= {MAX_BODIES} "
            "(bodies per bristle)"
        )


def run(args) -> int:
    """Run the experiment, print its status, real-time factor and jamming angles."""
    _check_bodies(args.bodies)
    if _is_tooth_scene(args):
        return run_teeth(args)
    summary = run_reference(
        brush=args.brush,
        scene=args.scene,
        out_dir=args.out,
        turns=args.turns,
        pitch_error_deg=args.pitch_error,
        dt=args.dt,
        bodies=args.bodies,
        integrator=args.integrator,
        element=args.element,
        fidelity=args.fidelity,
        speed=args.speed,
        accel=args.accel,
        progress=not args.no_progress,
        path=args.path,
        head_yaw_deg=args.head_yaw,
        p0_angle_deg=args.p0_angle,
        clockwise=args.clockwise,
        labels=LABELS,
        **({} if args.press_depth is None else {"press_depth": args.press_depth}),
    )
    perf = summary["performance"]
    print(
        f"status: {summary['status']}; wall {perf['wall_time_s']:.1f} s "
        f"(simulation {perf['sim_wall_time_s']:.1f} s, real-time factor "
        f"{perf['real_time_factor'] or 0:.2f}); outputs in {args.out}"
    )
    jam = summary["analysis"]["baseline"].get("jamming")
    if jam:
        from .plots import mean_angle_text  # the figures quote the same text

        for name, ev in jam["events"].items():
            if ev.get("count"):
                print(
                    f"  jamming near {name}: {ev['count']} peak(s), mean angle "
                    f"{mean_angle_text(ev)} (paper "
                    f"{math.degrees(ev['paper_angle_mod_2pi_rad']):.0f}°), mean |F_h| "
                    f"{ev['mean_Fh_N']:.3f} N"
                )
    cut = pitch_window_cut(
        dict(
            turns=args.turns,
            pitch_error_deg=args.pitch_error,
            pitch_window=DEFAULTS["pitch_window"],
        )
    )
    if cut:
        print(f"  {cut}")
    if "pitch_asymmetry" in summary["analysis"]:
        ch = summary["analysis"]["pitch_asymmetry"].get("change", {})
        if "Fy_max_N" in ch:
            c = ch["Fy_max_N"]
            print(
                f"  pitch error: Fy peak in the perturbed interval {c['baseline']:.3f} -> "
                f"{c['pitch']:.3f} N"
            )
    return 0 if summary["status"] == "ok" else 1
