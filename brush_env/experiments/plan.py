"""The experiment's plan: defaults (§3–5 of the paper and the choices it leaves open), the plate
and touch heights, and the reference motion (press along the bristle axis -> hold -> the MoveL
circle of Algorithm 1, optionally with the eq-12 pitch perturbation)."""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from ..calibration import ensure_calibrated
from ..engine import Simulator, load_brush, load_scene
from ..engine.checks import ConfigError, Limit, check_choice, check_real
from ..engine.config import BrushConfig
from ..engine.scene import Plane
from ..motion import R0, Circle, Hold, PitchPerturbation, Press, Sequence, paper_circle_movel

TWO_PI = 2.0 * math.pi

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
    element="mid",  # beam element: "mid" (accurate with few bodies) or "paper" (docs/model.md)
    path="movel",  # "movel" (paper Algorithm 1) or "circle" (exact circle)
    # the set-up the paper leaves open (issue 17, docs/reference_experiment.md "Set-up"):
    head_yaw_deg=90.0,  # [deg] the head turned on the flange about TCP z: the handle along TCP y
    p0_angle_deg=180.0,  # [deg] polar angle of P0 about the circle's centre (world x axis)
    clockwise=False,  # direction of travel seen from above the plate (False: counter-clockwise)
    pitch_window=(2.0 * math.pi, 2.5 * math.pi),  # eq 12 support [rad]
    tips_dt=5e-3,  # sampling interval of tips.npz [s]
    shapes_dt=2e-2,  # sampling interval of the stored bristle centre lines [s]
)


def plate_height(scene) -> float:
    planes = [s for s in scene.surfaces if isinstance(s, Plane)]
    if not scene.surfaces:
        return 0.0
    if not planes:
        kinds = [type(s).__name__ for s in scene.surfaces]
        raise ValueError(
            f"scene {scene.name!r}: the reference experiment needs a flat plate (a "
            f"'plane' surface with normal +z), got {kinds}"
        )
    pl = planes[0]
    n = np.asarray(pl.normal, dtype=float)
    n = n / np.linalg.norm(n)
    if abs(n[2] - 1.0) > 1e-9:
        raise ValueError(
            f"scene {scene.name!r}: the plate normal must be +z (world), got {pl.normal}"
        )
    return float(pl.point[2])


def build_trajectory(
    *,
    start_xy,
    touch_z,
    radius,
    speed,
    accel,
    turns,
    press_depth,
    press_time,
    hold_time,
    path,
    pitch_error_deg=0.0,
    pitch_window=DEFAULTS["pitch_window"],
    p0_angle_deg=180.0,
    clockwise=False,
    pitch_axis=(0.0, 1.0, 0.0),
):
    """The reference motion: Press (along the bristle axis) -> Hold -> circle, optionally pitched.

    Returns ``(trajectory, phase_starts, circle)`` with ``phase_starts = (0, t_hold, t_circle)``.
    ``path='movel'``: the paper's four MoveL control points with blend radius = circle radius
    (``paper_circle_movel``, ``ceil(turns)`` turns); ``'circle'``: the exact ``Circle``.
    The circle is centred so that P0 (θ = 0) is ``start_xy`` at polar angle ``p0_angle_deg``
    about the centre (default 180: the centre at start_xy + radius · x), travelled
    counter-clockwise about +z (``clockwise``: the other way).  The eq-12 pitch turns about the
    TCP-frame ``pitch_axis`` (the head's lateral axis).
    """
    p_touch = np.array([start_xy[0], start_xy[1], touch_z], dtype=float)
    press = Press((p_touch, R0), press_depth, press_time)
    p_pressed, _ = press.end_pose
    segs = [press]
    if hold_time > 0:
        segs.append(Hold((p_pressed, R0), hold_time))
    phi0 = math.radians(p0_angle_deg)
    center = p_pressed - radius * np.array([math.cos(phi0), math.sin(phi0), 0.0])
    if path == "movel":
        circ = paper_circle_movel(
            center,
            radius,
            speed,
            accel,
            turns=int(math.ceil(turns - 1e-9)),
            start_angle=phi0,
            clockwise=clockwise,
            orientation=np.array(R0),
        )
    elif path == "circle":
        circ = Circle(
            center,
            radius,
            speed,
            accel,
            turns=turns,
            start_angle=phi0,
            R=R0,
            clockwise=clockwise,
        )
    else:
        raise ValueError(f"path must be 'movel' or 'circle', got {path!r}")
    segs.append(circ)
    # remove the fp residue of P0 = centre + r (cos π, sin π) so Sequence's continuity check passes
    seq = Sequence(segs)
    phase_starts = tuple(float(t) for t in seq.start_times[:-1])
    traj = seq
    if pitch_error_deg:
        traj = PitchPerturbation(
            seq,
            math.radians(pitch_error_deg),
            theta_start=pitch_window[0],
            theta_end=pitch_window[1],
            axis=pitch_axis,
        )
    return traj, phase_starts, circ


#: The numeric arguments of a run and their allowed ranges (``check_run_args``)
RUN_LIMITS = {
    "turns": Limit("turns", gt=0),
    "dt": Limit("s", gt=0, le=0.1),
    "speed": Limit("mm/s", gt=0),
    "accel": Limit("mm/s^2", gt=0),
    "radius": Limit("mm", gt=0),
    "press_time": Limit("s", gt=0),
    "tips_dt": Limit("s", gt=0),
    "shapes_dt": Limit("s", gt=0),
    "hold_time": Limit("s", ge=0),
    "press_depth": Limit("mm", ge=0),
    "head_yaw_deg": Limit("deg", ge=-360.0, le=360.0),
    "p0_angle_deg": Limit("deg", ge=-360.0, le=360.0),
    # eq 12 tilts the head about its lateral axis: beyond a quarter turn it is no pitch error
    "pitch_error_deg": Limit("deg", ge=-90.0, le=90.0),
}


def say(name: str, value, unit: str, labels: Mapping[str, str] | None) -> str:
    """How a message shows argument ``name`` = ``value``: in the caller's own terms when
    ``labels`` names it (the CLI: ``--pitch-error = 100 deg``), else by its Python name."""
    if labels and name in labels:
        shown = f"{value:g}" if isinstance(value, (int, float)) else repr(value)
        return f"{labels[name]} = {shown}" + (f" {unit}" if unit else "")
    return f"{name} = {value!r}"


def check_run_args(args: Mapping, labels: Mapping[str, str] | None = None) -> None:
    """Every number of a run (``args``: ``run_reference``'s arguments by name), checked before
    anything is built or written (ConfigError names the argument, the value and the allowed
    range).  ``labels``: how the caller calls each argument (the CLI: its flags, whose values
    the messages then show in the flag's unit)."""
    for name, limit in RUN_LIMITS.items():
        try:
            check_real(name, args[name], limit)
        except ConfigError:
            if not (labels and name in labels):
                raise
            raise ConfigError(
                f"{say(name, args[name], limit.unit, labels)} is out of range: {limit.describe()}"
            ) from None
    if not isinstance(args["clockwise"], bool):
        raise ConfigError(f"clockwise = {args['clockwise']!r}: must be true or false")
    check_choice("path", args["path"], ("movel", "circle"), "path")
    check_choice("integrator", args["integrator"], ("bdf2", "euler"), "integrator")
    check_choice("element", args["element"], ("mid", "paper"), "beam element")
    _check_pitch_window(args, labels)


def _check_pitch_window(args: Mapping, labels: Mapping[str, str] | None) -> None:
    """A pitch error needs a run that reaches its eq-12 window (else the 'pitch' run would be
    the baseline again, reported as if it had been perturbed)."""
    lo, hi = args["pitch_window"]
    end = TWO_PI * float(args["turns"])
    if args["pitch_error_deg"] and end <= lo:
        raise ConfigError(
            f"{say('pitch_error_deg', args['pitch_error_deg'], 'deg', labels)} has no effect "
            f"with {say('turns', args['turns'], 'turns', labels)}: the eq-12 pitch window "
            f"θ = {math.degrees(lo):g}-{math.degrees(hi):g}° starts after the run ends at "
            f"θ = {math.degrees(end):g}°; needs {(labels or {}).get('turns', 'turns')} >= "
            f"{hi / TWO_PI:g}"
        )


def pitch_window_cut(args: Mapping) -> str | None:
    """A notice when the run ends inside the eq-12 pitch window (the perturbation is cut short),
    else None."""
    lo, hi = args["pitch_window"]
    end = TWO_PI * float(args["turns"])
    if args["pitch_error_deg"] and lo < end < hi:
        return (
            f"notice: the run ends at θ = {math.degrees(end):g}°, inside the eq-12 pitch window "
            f"θ = {math.degrees(lo):g}-{math.degrees(hi):g}°: the pitch error is cut short "
            f"(turns >= {hi / TWO_PI:g} runs it whole)"
        )
    return None


def press_range(brush: BrushConfig) -> tuple[float, float]:
    """(free length, head clearance) [mm] of ``brush`` pressed onto a plate at the start
    orientation R0: the longest bristle's length (root to tip centre), and the height of the head
    (its lowest bristle root) above the plate when the lowest tip sphere touches it."""
    R = np.asarray(R0, dtype=float)
    roots = brush.roots_tcp() @ R.T
    lengths = np.array([b.length for b in brush.bristles])
    radii = np.array([b.tip_radius for b in brush.bristles])
    tips = roots + lengths[:, None] * (brush.axes_tcp() @ R.T)
    touch = float(np.min(tips[:, 2] - radii))
    return float(lengths.max()), float(np.min(roots[:, 2]) - touch)


def check_press_depth(
    depth: float, brush: BrushConfig, labels: Mapping[str, str] | None = None
) -> float:
    """A press depth [mm] past the touch that stays below the bristles' free length and keeps
    the head clear of the surface (``press_range``); ConfigError naming both otherwise
    (``labels``: as in ``check_run_args``)."""
    free, clear = press_range(brush)
    top = min(free, clear)
    if not (math.isfinite(depth) and 0.0 <= depth < top):
        raise ConfigError(
            f"{say('press_depth', depth, 'mm', labels)} is out of range: must be >= 0 and < "
            f"{top:.4g} (mm), below the bristles' free length {free:.4g} mm of brush "
            f"{brush.name!r} (the head is {clear:.4g} mm above the surface when the tips touch; "
            "a deeper press drives it in)"
        )
    return depth


@dataclass
class Plan:
    """Everything decided before the first step: scene, simulator, motion and the time grid.

    ``times`` (n_steps + 1,) [s], ``theta`` the rotation angle of each row [rad], ``phase`` 0 press,
    1 hold, 2 circle; ``poses[name] = (P (n, 3) [mm], R (n, 3, 3))`` per run ('baseline' and,
    with a pitch error, 'pitch'); ``pitch[name]`` the imposed eq-12 pitch [rad]."""

    scene: object
    sim: Simulator
    plate_z: float
    touch_z: float
    start_xy: tuple
    phase_starts: tuple
    times: np.ndarray
    theta: np.ndarray
    phase: np.ndarray
    poses: dict
    pitch: dict
    n_steps: int
    n_full: int
    tips_stride: int
    shapes_stride: int


def pitch_axis(brush: BrushConfig) -> np.ndarray:
    """The eq-12 pitch axis in the TCP frame: the head's lateral axis (head y; §5.2 "the pitch
    direction of the brush's main body", whose handle runs along head x)."""
    return brush.head_rotation() @ np.array([0.0, 1.0, 0.0])


def mount_head(brush: BrushConfig, yaw_deg: float) -> BrushConfig:
    """``brush`` turned by ``yaw_deg`` about the TCP z axis on the flange: its head pose (offset
    and roll/pitch/yaw, R = Rz(yaw) Ry Rx) pre-rotated by Rz(yaw_deg)."""
    if yaw_deg == 0.0:
        return brush
    a = math.radians(yaw_deg)
    c, s = math.cos(a), math.sin(a)
    x, y, z = brush.head_offset
    r, p, yaw = brush.head_rpy
    return replace(
        brush,
        head_offset=(c * x - s * y, s * x + c * y, z),
        head_rpy=(r, p, yaw + a),
    )


def resolve_scene(brush, scene, bodies, head_yaw_deg: float = 0.0):
    """The scene to run: a Scene, a path or a name (default flat_plate), with ``brush`` (a
    BrushConfig, path or name) and ``bodies`` per bristle overriding the scene's, the head
    mounted ``head_yaw_deg`` about TCP z (``mount_head``)."""
    if scene is None or isinstance(scene, (str, os.PathLike)):
        scene_obj = load_scene(scene, brush=brush if brush is not None else None)
    else:
        scene_obj = scene
        if brush is not None:
            b = brush if isinstance(brush, BrushConfig) else load_brush(brush)
            scene_obj = replace(scene, brush=b)
    if bodies is not None:
        scene_obj = replace(scene_obj, brush=scene_obj.brush.with_bodies(int(bodies)))
    if head_yaw_deg:
        scene_obj = replace(scene_obj, brush=mount_head(scene_obj.brush, head_yaw_deg))
    return scene_obj


#: The arguments of a run that shape its motion (``build_trajectory``'s, but turns and poses).
MOTION_ARGS = (
    "radius",
    "speed",
    "accel",
    "press_depth",
    "press_time",
    "hold_time",
    "path",
    "p0_angle_deg",
    "clockwise",
)


def make_plan(scene_obj, settings, args: Mapping) -> Plan:
    """Simulator, touch height, the baseline (and pitched) motion sampled on the time grid; the
    run stops when θ reaches 2π·turns (§4: four turns).  ``args``: ``run_reference``'s arguments
    by name (``MOTION_ARGS``, turns, pitch_error_deg, pitch_window, tips_dt, shapes_dt)."""
    ensure_calibrated(scene_obj.brush, settings)  # the reduced model of `fast`
    sim = Simulator(scene_obj, settings)
    dt = settings.dt
    plate_z = plate_height(scene_obj)
    touch_z = sim.touch_height(np.array(R0), plate_z)
    start_xy = (0.0, 0.0)
    turns = float(args["turns"])
    common = dict(start_xy=start_xy, touch_z=touch_z, turns=turns)
    common.update((k, args[k]) for k in MOTION_ARGS)
    traj, phase_starts, _ = build_trajectory(**common)
    trajs = {"baseline": traj}
    if args["pitch_error_deg"]:
        trajs["pitch"], _, _ = build_trajectory(
            **common,
            pitch_error_deg=args["pitch_error_deg"],
            pitch_window=args["pitch_window"],
            pitch_axis=pitch_axis(scene_obj.brush),
        )
    n_full, times, theta = _time_grid(traj, dt, turns)
    n_steps = len(times) - 1
    pitch = {"baseline": np.zeros(n_steps + 1)}
    if "pitch" in trajs:
        pitch["pitch"] = trajs["pitch"].pitch(times)
    return Plan(
        scene=scene_obj,
        sim=sim,
        plate_z=plate_z,
        touch_z=touch_z,
        start_xy=start_xy,
        phase_starts=phase_starts,
        times=times,
        theta=theta,
        phase=_phases(times, phase_starts, args["hold_time"]),
        poses={name: tuple(tr.sample(times)[:2]) for name, tr in trajs.items()},
        pitch=pitch,
        n_steps=n_steps,
        n_full=n_full,
        tips_stride=max(1, int(round(args["tips_dt"] / dt))),
        shapes_stride=max(1, int(round(args["shapes_dt"] / dt))),
    )


def _time_grid(traj, dt: float, turns: float):
    """(steps of the whole motion, times [s], θ [rad]): the grid of step ``dt`` cut at the first
    step where θ reaches 2π·``turns`` (the whole motion when it never does)."""
    T = traj.duration
    n_full = int(math.ceil(T / dt - 1e-9))
    times = np.arange(n_full + 1) * dt
    theta_full = np.asarray(traj.angle(np.minimum(times, T)), dtype=float)
    reach = np.flatnonzero(theta_full >= TWO_PI * turns - 1e-9)
    n_steps = int(reach[0]) if reach.size else n_full
    return n_full, times[: n_steps + 1], theta_full[: n_steps + 1]


def _phases(times, phase_starts, hold_time) -> np.ndarray:
    """The phase of each time: 0 press, 1 hold, 2 circle (no 1 without a hold)."""
    phase = np.searchsorted(np.asarray(phase_starts), times, side="right") - 1
    phase = np.where(phase >= len(phase_starts) - 1, 2, phase)
    if hold_time <= 0:
        phase = np.where(phase >= 1, 2, phase)
    return phase
