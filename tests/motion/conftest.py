"""Shared builders and independent helpers of the brush_env.motion tests."""

import math

import numpy as np

from brush_env.motion import (
    R0,
    Approach,
    Circle,
    Hold,
    MoveL,
    PitchPerturbation,
    Press,
    Sequence,
    paper_circle_movel,
)

L_BRISTLE = 10.0  # TCP height at which the tips touch the plate
V, A = 20.0, 100.0  # tool speed (mm/s) and acceleration (mm/s^2) used throughout


# ------------------------------------------------------------------------------------------
# helpers
# ------------------------------------------------------------------------------------------
def log_so3(R):
    """Independent small-angle-safe rotation vector (angles well below pi)."""
    c = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    th = math.acos(c)
    vee = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    if th < 1e-8:
        return 0.5 * vee
    return th / (2.0 * math.sin(th)) * vee


def rot_y(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def numeric_twist(traj, t, e=1e-6):
    pp, Rp = traj.pose(t + e)
    pm, Rm = traj.pose(t - e)
    v = (pp - pm) / (2 * e)
    w = log_so3(Rp @ Rm.T) / (2 * e)
    return v, w


def paper_center(depth=3.0):
    return np.array([50.0, -20.0, L_BRISTLE - depth])


def make_circle(**kw):
    args = {"center": paper_center(), "radius": 20.0, "speed": V, "accel": A, "turns": 4}
    args["start_angle"] = math.pi
    args.update(kw)
    return Circle(**args)


def press_circle_sequence():
    circ = make_circle()
    p_touch = circ.start_pose[0] + np.array([0.0, 0.0, 3.0])
    press = Press((p_touch, R0), depth=3.0, duration=0.5)
    return Sequence([Hold((p_touch, R0), 0.2), press, circ, Hold(circ.end_pose, 0.3)]), circ


def all_trajectories():
    c = paper_center()
    circ = make_circle(turns=1.5)
    seq, _ = press_circle_sequence()
    R_tilted = (
        R0
        @ rot_y(0.3)
        @ np.array(
            [[math.cos(0.2), -math.sin(0.2), 0], [math.sin(0.2), math.cos(0.2), 0], [0, 0, 1]]
        )
    )
    mv = paper_circle_movel(c, 20.0, V, A, turns=2)
    return {
        "hold": Hold((c, R0), 1.0),
        "press": Press((c + [0, 0, 3], R0), 3.0, 0.5),
        "press_cubic": Press((c, R0), -2.0, 0.4, axis=(1, 1, 0), profile="cubic"),
        "approach": Approach((c + [0, 0, 40], R_tilted), (c, R0), 1.2),
        "circle": circ,
        "circle_cw_tilted": make_circle(turns=0.8, clockwise=True, normal=(0.1, 0.2, 1.0)),
        "movel_paper": mv,
        "movel_stops": MoveL([[0, 0, 0], [10, 0, 0], [10, 10, 5]], V, A, 0.0),
        "pitch_circle": PitchPerturbation(make_circle(turns=3), np.deg2rad(1.0)),
        "pitch_circle_pivot": PitchPerturbation(
            make_circle(turns=3), np.deg2rad(5.0), pivot=(0.0, 0.0, -30.0)
        ),
        "pitch_movel": PitchPerturbation(mv, np.deg2rad(2.0)),
        "pitch_fn_numeric_rate": PitchPerturbation(
            make_circle(turns=3), np.deg2rad(3.0), angle_fn=make_circle(turns=3).angle
        ),
        "sequence": seq,
        "pitch_sequence": PitchPerturbation(seq, np.deg2rad(1.0), pivot=(1.0, 2.0, -20.0)),
    }
