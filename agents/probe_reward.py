"""Scripted probes of the reward: can doing nothing, hovering, leaving or pressing hard pay?

    python -m agents.probe_reward                          # FlatPlate-v0, fast, seeds 0 and 1
    python -m agents.probe_reward --episodes 5 --env-kw fidelity=balanced
    python -m agents.probe_reward --env brush_env/ToothRow-v0
    python -m agents.probe_reward --press-curve            # the force-press curves (docs/rl.md)

Each probe is an SB3-style policy run through ``agents.evaluate.run_episode`` on the same seeds
(episode i resets with ``--seed + i``).  The table gives, per probe, the mean over the episodes
of: return, coverage [%], time above ``total_force_limit`` [s], peak total normal force [N], the
first step with a positive coverage reward, and how the episodes ended.  The probes:

* ``nothing``: zero velocity; the tips start 1-2 mm above the nominal surface and stay there.
* ``hover``: move to the nominal touch height (tips level with the nominal surface, so touching
  or not by the unobserved offset) and hold still there.
* ``leave (up)`` / ``leave (side)``: full speed up / along +x until the workspace ends the episode.
* ``press hard``: full speed down, then hold at the workspace floor (the deepest press allowed).
* ``reference``: the env's reference policy (agents/reference.py) as shipped: FlatPlate-v0's
  circle with the press made while sliding, ToothRow-v0's scrub with the press at rest.
* ``reference (static press)`` / ``reference (sliding press)``: the same motion with the other
  press profile (the one equal to the env's default is skipped): on the plate the static press
  is the paper's order (press at rest, then the circle), which holds the brush above the limit.
* ``reference (deep, 4.5 mm)``: the reference pressed 4.5 mm, 0.5 mm above the workspace floor.
* ``random``: uniform random actions (seeded), for the sparse start.

``--press-curve`` prints two measured force-press curves of the brush on the plate (plate offset
0): the static curve (a 1 mm/s press at rest above P0) and the sliding curve (the sliding
reference at each depth: the peak and mean total normal force once pressed).  docs/rl.md derives
the reference's press depth from them.  Units: mm, N, s.
"""

from __future__ import annotations

import argparse
import math
import sys

import gymnasium as gym
import numpy as np

import brush_env  # noqa: F401  (registers the ids)
from agents.evaluate import check_env_id, parse_env_kw, run_episode
from agents.reference import RandomPolicy, ReferencePolicy
from brush_env.user_errors import OneLineParser, add_env_kw, run_main

ENV_ID = "brush_env/FlatPlate-v0"

#: Depth [mm] of the "deep" probe: 0.5 mm above the workspace floor (5 mm below touching).
DEEP_PRESS_MM = 4.5

__all__ = ["PROBES", "ScriptedPolicy", "make_probe", "probe", "press_curve", "main"]


class ScriptedPolicy:
    """A probe that holds a TCP velocity or a TCP height, from the observation alone.

    ``mode``: ``"velocity"`` commands the constant normalised action ``action``;
    ``"height"`` drives the TCP to ``height`` mm above the nominal touch height (negative: pressed)
    with a proportional law (gain ``kp`` [1/s]), x, y and orientation held.  SB3-style
    ``predict``; raw (un-normalised) observations."""

    def __init__(self, env, mode: str, action=None, height: float = 0.0, kp: float = 10.0):
        u = env.unwrapped
        if mode not in ("velocity", "height"):
            raise ValueError(f"mode = {mode!r}: must be 'velocity' or 'height'")
        self.layout, self.space = u.layout, env.action_space
        self.mode, self.height, self.kp = mode, float(height), float(kp)
        self.v_max = float(u.config.max_linear_speed[2])
        a = np.zeros(self.space.shape, np.float32) if action is None else action
        self.action = np.asarray(a, np.float32)

    def predict(self, observation, state=None, episode_start=None, deterministic=True):
        if self.mode == "velocity":
            return self.action.copy(), state
        p, _ = self.layout.tcp_pose(np.asarray(observation)[None])
        z = p[0, 2] - self.layout.touch_height
        a = np.zeros(self.space.shape, np.float32)
        a[2] = np.clip(self.kp * (self.height - z) / self.v_max, -1.0, 1.0)
        return a, state


#: probe name -> how to make it (env -> policy)
PROBES = (
    "nothing",
    "hover",
    "leave (up)",
    "leave (side)",
    "press hard",
    "reference",
    "reference (static press)",
    "reference (sliding press)",
    f"reference (deep, {DEEP_PRESS_MM:g} mm)",
    "random",
)


def make_probe(name: str, env, seed: int = 0):
    """The policy of probe ``name`` (one of :data:`PROBES`) for ``env``."""
    n = env.action_space.shape[0]
    unit = np.eye(n, dtype=np.float32)
    floor = float(env.unwrapped.config.workspace_height[0])
    makers = {
        "nothing": lambda: ScriptedPolicy(env, "velocity"),
        "hover": lambda: ScriptedPolicy(env, "height", height=0.0),
        "leave (up)": lambda: ScriptedPolicy(env, "velocity", action=unit[2]),
        "leave (side)": lambda: ScriptedPolicy(env, "velocity", action=unit[0]),
        # hold 0.1 mm above the floor: the deepest press that does not end the episode
        "press hard": lambda: ScriptedPolicy(env, "height", height=floor + 0.1),
        "reference": lambda: ReferencePolicy.for_env(env),
        "reference (static press)": lambda: ReferencePolicy.for_env(env, press="static"),
        "reference (sliding press)": lambda: ReferencePolicy.for_env(env, press="sliding"),
        f"reference (deep, {DEEP_PRESS_MM:g} mm)": lambda: ReferencePolicy.for_env(
            env, press_depth=DEEP_PRESS_MM
        ),
        "random": lambda: RandomPolicy(env.action_space, seed=seed),
    }
    if name not in makers:
        raise ValueError(f"probe = {name!r} is unknown: must be one of {list(PROBES)}")
    return makers[name]()


def probe(env, name: str, seeds) -> list[dict]:
    """Per-episode metrics of probe ``name`` on ``env``, one episode per seed (see
    ``agents.evaluate.run_episode``), plus ``first_reward_step``: the first step whose coverage
    reward is positive (None if none)."""
    rows = []
    for seed in seeds:
        policy = make_probe(name, env, seed)
        metrics, series, _ = run_episode(env, policy, seed)
        cov = np.asarray(series["coverage"])
        hit = np.flatnonzero(cov > 0)
        metrics["first_reward_step"] = int(hit[0]) if len(hit) else None
        rows.append(metrics)
    return rows


def summary_row(name: str, rows: list[dict]) -> dict:
    ret = np.array([r["return"] for r in rows])
    ends: dict[str, int] = {}
    for r in rows:
        key = r["termination"] or "time limit"
        ends[key] = ends.get(key, 0) + 1
    first = [r["first_reward_step"] for r in rows if r["first_reward_step"] is not None]
    return {
        "probe": name,
        "return": float(ret.mean()),
        "return_min": float(ret.min()),
        "return_max": float(ret.max()),
        "coverage": 100.0 * float(np.mean([r["coverage"] for r in rows])),
        "time_above": float(np.mean([r["time_above_force_limit"] for r in rows])),
        "peak_force": float(np.max([r["peak_normal_force"] for r in rows])),
        "first_reward_step": (f"{min(first)}-{max(first)}" if first else "never"),
        "ended": ", ".join(f"{v} {k}" for k, v in ends.items()),
    }


def table(summaries: list[dict]) -> str:
    head = (
        "| probe | return, mean (min .. max) | coverage [%] | time above limit [s] | "
        "peak total force [N] | first rewarded step | episodes ended |\n"
        "|---|---|---|---|---|---|---|\n"
    )
    lines = [
        f"| {s['probe']} | {s['return']:+.2f} ({s['return_min']:+.2f} .. {s['return_max']:+.2f})"
        f" | {s['coverage']:.1f} | {s['time_above']:.2f} | {s['peak_force']:.2f} | "
        f"{s['first_reward_step']} | {s['ended']} |"
        for s in summaries
    ]
    return head + "\n".join(lines)


def press_curve(env, depths, speed: float = 1.0) -> tuple[list[tuple], list[tuple]]:
    """(static, sliding) force-press curves on the plate at offset 0 [mm, N].

    Static: from 0.5 mm above touching, a press at ``speed`` mm/s at rest above P0 = (-20, 0)
    down to ``max(depths)``: rows (depth, total normal force).  Sliding: the sliding reference
    pressed to each of ``depths``: rows (depth, peak total force over the episode, mean and max
    total force once pressed)."""
    u = env.unwrapped
    zt, v_max = u.touch_height, float(u.config.max_linear_speed[2])
    static = []
    obs, info = env.reset(
        seed=0, options={"plate_offset": [0, 0, 0], "tcp_position": [-20, 0, zt + 0.5]}
    )
    a = np.zeros(env.action_space.shape, np.float32)
    a[2] = -speed / v_max
    deepest = float(max(depths))
    while True:
        obs, _, term, trunc, info = env.step(a)
        d = zt - float(info["tcp_position"][2])
        static.append((d, float(info["total_normal_force"])))
        if term or trunc or d >= deepest:
            break
    sliding = []
    for depth in depths:
        policy = ReferencePolicy.for_env(env, press_depth=float(depth))
        obs, info = env.reset(seed=0, options={"plate_offset": [0, 0, 0]})
        k, peak, held = 0, 0.0, []
        t_pressed = None
        while True:
            act, _ = policy.predict(obs)
            obs, _, term, trunc, info = env.step(act)
            k += 1
            t_pressed = policy.controller(0).pressed_at
            peak = max(peak, float(info["peak_normal_force"]))
            if info["time"] >= t_pressed:
                held.append(float(info["total_normal_force"]))
            if term or trunc:
                break
        sliding.append((float(depth), peak, float(np.mean(held)), float(np.max(held))))
    return static, sliding


def _fmt_curves(static, sliding) -> str:
    out = ["static press (1 mm/s at rest, plate offset 0): depth [mm] -> total normal force [N]"]
    out.append("| depth [mm] | total force [N] |\n|---|---|")
    step = max(1, len(static) // 25)
    out += [f"| {d:.2f} | {f:.2f} |" for d, f in static[::step]]
    out.append("\nsliding press (the reference pressed while circling, plate offset 0):")
    out.append(
        "| depth [mm] | peak total force [N] | mean once pressed [N] | max once pressed [N] |\n"
        "|---|---|---|---|"
    )
    out += [f"| {d:.2f} | {p:.2f} | {m:.2f} | {x:.2f} |" for d, p, m, x in sliding]
    return "\n".join(out)


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="python -m agents.probe_reward",
        description="Scripted reward probes (do nothing, hover, leave, press hard, reference).",
    )
    p.add_argument("--env", default=ENV_ID, help=f"env id (default {ENV_ID})")
    p.add_argument("--episodes", type=int, default=2, help="episodes per probe (default 2)")
    p.add_argument("--seed", type=int, default=0, help="episode i resets with seed + i")
    p.add_argument(
        "--probe", action="append", default=None, help=f"run only these probes (of {PROBES})"
    )
    p.add_argument(
        "--press-curve",
        action="store_true",
        help="print the static and sliding force-press curves instead of the probes",
    )
    p.add_argument(
        "--depths",
        default="1,1.5,2,2.5,3,3.5,4,4.5",
        help="sliding-curve depths [mm], comma-separated (--press-curve)",
    )
    add_env_kw(p, "e.g. --env-kw fidelity=balanced")
    return p


def _main(argv) -> int:
    args = build_parser().parse_args(argv)
    if args.episodes < 1:
        raise ValueError(f"--episodes = {args.episodes} is out of range: must be >= 1")
    check_env_id(args.env)
    kw = parse_env_kw(args.env_kw)
    env = gym.make(args.env, **kw)
    try:
        if args.press_curve:
            depths = [float(x) for x in args.depths.split(",") if x.strip()]
            if not depths or not all(math.isfinite(d) and d > 0 for d in depths):
                raise ValueError(f"--depths = {args.depths!r}: must be positive numbers (mm)")
            print(_fmt_curves(*press_curve(env, depths)))
            return 0
        default_press = ReferencePolicy.for_env(env).controller(0).press
        same = f"reference ({default_press} press)"  # the reference itself
        names = args.probe or [n for n in PROBES if n != same]
        for n in names:
            if n not in PROBES:
                raise ValueError(f"--probe {n!r} is unknown: must be one of {list(PROBES)}")
        seeds = [args.seed + i for i in range(args.episodes)]
        summaries = []
        for n in names:
            summaries.append(summary_row(n, probe(env, n, seeds)))
            print(f"  {n}: done", file=sys.stderr, flush=True)
        print(f"{args.env}, seeds {seeds[0]}..{seeds[-1]}, {kw or 'env defaults'}")
        print(table(summaries))
    finally:
        env.close()
    return 0


def main(argv=None) -> int:
    return run_main(_main, argv, prog="python -m agents.probe_reward")


if __name__ == "__main__":
    sys.exit(main())
