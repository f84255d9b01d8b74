"""``brush_env/PlanarStroke-v0``: stroke a planar cut of the brush along a surface profile (pymunk).

Description
-----------
The side view of ``brush_env.planar``: the bristles of one planar cut of a brush config (default:
across the rows of the default brush, the plane its bristles lean and buckle in) as pymunk
chains over a surface profile (``"flat"`` or ``"tooth_section"``: two crowns and a gap).  The
agent commands the head's in-plane velocity; coverage is 1-D, along the profile.  The same
reward structure as FlatPlate-v0 (coverage minus total- and per-tip-force penalties, a
termination penalty).  How close this is to the 3-D engine: ``brush-env bench planar``,
docs/planar.md.

Units: mm, N, s, rad.  Frame: x along the stroke, z up; the profile's top at z = 0.

Action Space
------------
``Box(-1, 1, (3,))`` (``action_mode="3d"``): (vx, vz, w) scaled by ``max_speed`` =
(50 mm/s, 20 mm/s, 0.5 rad/s); ``"2d"``: (vx, vz).  NaN/inf or a wrong shape raise ValueError.

Observation Space
-----------------
``Box`` of float32 (``observation_mode="box"``) or a ``Dict`` of the same blocks:

| Block | Shape | Meaning (scaling) |
|---|---|---|
| tip_deflection | (nb, 2) | tip minus its rest position in the head frame (/ L) |
| tip_contact | (nb,) | 1 if the tip touches the surface |
| tip_force | (nb,) | contact force magnitude per tip (/ tip_force_limit) |
| tcp_force | (3,) | Fx, Fz [N] (/ force_scale), moment [N mm] (/ 20 force_scale) |
| tcp_pose | (3,) | x / workspace_x, (z - z_t) / 10 mm, angle / max_tilt |
| coverage | (1 + m,) | fraction cleaned, then per block of ``coverage_blocks`` |
| time_remaining | (1,) | 1 - steps / max_episode_steps |

Rewards
-------
``coverage_weight * newly cleaned cells / cells - total_force_weight * integral of max(0, F - 0.1 N
x nb) dt - tip_force_weight * integral of sum_i max(0, f_i - tip_force_limit) dt -
termination_penalty`` (terms in ``info["reward_terms"]``; the 0.1 N per tip is FlatPlate-v0's
4 N over 40 tips).

Episode End
-----------
``terminated`` with ``info["termination"]``:

* ``"workspace"``: |x| > 30 mm, TCP height outside [-5, 15] mm of touching, or tilt > 30 deg;
* ``"force_limit"``: the control step's mean total force > 0.375 N x nb (FlatPlate-v0's 15 N
  over 40 tips);
* ``"divergence"``: the pymunk model blew up (the message in ``info["divergence"]``).

Truncation by ``max_episode_steps`` (gym.make's TimeLimit, 200).

Arguments
---------
``gym.make("brush_env/PlanarStroke-v0", **kw)``: brush ("default"), cut ("y" or "x"), profile
("flat", "tooth_section"), control_dt (0.04 s), pymunk_dt (1e-4 s), mass_scale (100),
action_mode, observation_mode, coverage_blocks (8), clean_radius (0.5 mm), patch_half_width
(20 mm), max_episode_steps (200), render_mode (None or "rgb_array").
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from brush_env.coverage import LineCoverage
from brush_env.engine import ConfigError, load_brush
from brush_env.planar import PlanarBrush, PlanarSettings, Profile

__all__ = ["PlanarStrokeEnv"]

PROFILES = ("flat", "tooth_section")
TIP_FORCE_LIMIT = 0.2  # [N] FlatPlate-v0's per-tip limit
TOTAL_PER_TIP = 0.1  # [N] FlatPlate-v0's 4 N over its 40 tips
HARD_PER_TIP = 0.375  # [N] FlatPlate-v0's 15 N over its 40 tips


def _check(name, value, lo, hi, unit):
    if not (isinstance(value, (int, float)) and math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(
            f"{name} = {value!r} is out of range: must be in [{lo:g}, {hi:g}] ({unit})"
        )
    return value


class PlanarStrokeEnv(gym.Env):
    """Stroke a planar cut of the brush along a profile (module docstring)."""

    metadata = {"render_modes": ["rgb_array"]}
    reference_motion = None  # no reference policy (agents/train.py skips its comparison)

    def __init__(
        self,
        brush: str = "default",
        cut: str = "y",
        profile: str = "flat",
        control_dt: float = 0.04,
        pymunk_dt: float = 1e-4,
        mass_scale: float = 100.0,
        action_mode: str = "3d",
        observation_mode: str = "box",
        coverage_blocks: int = 8,
        clean_radius: float = 0.5,
        patch_half_width: float = 20.0,
        max_episode_steps: int = 200,
        render_mode: str | None = None,
        coverage_weight: float = 100.0,
        total_force_weight: float = 25.0,
        tip_force_weight: float = 125.0,
        termination_penalty: float = 10.0,
    ):
        if profile not in PROFILES:
            raise ConfigError(f"profile = {profile!r}: must be one of {PROFILES}")
        if action_mode not in ("3d", "2d"):
            raise ConfigError(f"action_mode = {action_mode!r}: must be '3d' (vx, vz, w) or '2d'")
        if observation_mode not in ("box", "dict"):
            raise ConfigError(f"observation_mode = {observation_mode!r}: must be 'box' or 'dict'")
        if render_mode not in (None, "rgb_array"):
            raise ConfigError(f"render_mode = {render_mode!r}: must be None or 'rgb_array'")
        _check("control_dt", control_dt, 1e-3, 1.0, "s")
        _check("clean_radius", clean_radius, 0.0, 5.0, "mm")
        _check("patch_half_width", patch_half_width, 1.0, 200.0, "mm")
        _check("coverage_blocks", coverage_blocks, 1, 100, "count")
        _check("max_episode_steps", max_episode_steps, 1, 10_000_000, "steps")
        self.settings = PlanarSettings(dt=pymunk_dt, mass_scale=mass_scale)
        if control_dt < pymunk_dt:
            raise ConfigError(
                f"control_dt = {control_dt!r} s is shorter than pymunk_dt = {pymunk_dt!r} s"
            )
        self.brush = load_brush(brush)
        self.profile = Profile.flat() if profile == "flat" else Profile.tooth_section()
        self.cut = cut
        self.model = PlanarBrush(self.brush, self.profile, self.settings, cut=cut)  # checks dt
        self.nb = len(self.model.tips)
        self.L = max(b.length for b in self.model.bristles)
        self.z_touch = self.L + self.model.bristles[0].tip_radius
        self.frame_skip = max(1, int(round(control_dt / pymunk_dt)))
        self.dt = self.frame_skip * pymunk_dt
        self.metadata = {**PlanarStrokeEnv.metadata, "render_fps": 1.0 / self.dt}
        self.render_mode = render_mode
        self.action_mode, self.observation_mode = action_mode, observation_mode
        self.max_speed = np.array([50.0, 20.0, 0.5])[: 3 if action_mode == "3d" else 2]
        self.action_space = spaces.Box(-1.0, 1.0, (len(self.max_speed),), np.float32)
        self.w = dict(
            coverage=coverage_weight,
            total=total_force_weight,
            tip=tip_force_weight,
            term=termination_penalty,
        )
        self.horizon = int(max_episode_steps)
        self.half = float(patch_half_width)
        self.clean_radius = float(clean_radius)
        self.blocks = int(coverage_blocks)
        # 0.25 mm coverage cells along x
        self.coverage = LineCoverage(self.half, 0.25, self.clean_radius, self.blocks)
        self.blocks_sizes = {
            "tip_deflection": (self.nb, 2),
            "tip_contact": (self.nb,),
            "tip_force": (self.nb,),
            "tcp_force": (3,),
            "tcp_pose": (3,),
            "coverage": (1 + self.blocks,),
            "time_remaining": (1,),
        }
        bound = {"tip_deflection": 2.0, "tip_force": 10.0, "tcp_force": 5.0, "tcp_pose": 1.5}
        low = {k: -bound.get(k, 0.0) if k in ("tip_deflection", "tcp_force", "tcp_pose") else 0.0
               for k in self.blocks_sizes}  # fmt: skip
        high = {k: bound.get(k, 1.0) for k in self.blocks_sizes}
        self._bounds = (low, high)
        if observation_mode == "dict":
            self.observation_space = spaces.Dict(
                {
                    k: spaces.Box(low[k], high[k], shape, np.float32)
                    for k, shape in self.blocks_sizes.items()
                }
            )
        else:
            lo = np.concatenate(
                [np.full(math.prod(s), low[k]) for k, s in self.blocks_sizes.items()]
            )
            hi = np.concatenate(
                [np.full(math.prod(s), high[k]) for k, s in self.blocks_sizes.items()]
            )
            self.observation_space = spaces.Box(lo.astype(np.float32), hi.astype(np.float32))
        self._started = False

    def set_horizon(self, steps: int) -> None:
        """The time limit [steps] ``time_remaining`` counts down (gym.make passes its
        TimeLimit's, brush_env.envs.horizon)."""
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise ValueError(f"horizon = {steps!r} is out of range: must be an integer >= 1")
        self.horizon = steps

    # ------------------------------------------------------------------ reset / step
    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.model = PlanarBrush(self.brush, self.profile, self.settings, cut=self.cut)
        x0 = float(self.np_random.uniform(-5.0, 5.0))
        h = float(self.np_random.uniform(1.0, 2.0))
        self.model.place(x0, self.z_touch + h)
        self.pose = np.array([x0, self.z_touch + h, 0.0])
        self.coverage.reset()
        self.prev_cp = np.full(self.nb, np.nan)
        self.steps = 0
        self.forces = np.zeros((self.nb, 2))
        self._started, self._done = True, False
        return self._obs(), {"coverage": 0.0}

    def step(self, action):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if self._done:
            raise RuntimeError("the episode has terminated: call reset() before step()")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != self.action_space.shape or not np.all(np.isfinite(a)):
            raise ValueError(
                f"action = {action!r}: must be {self.action_space.shape} finite numbers in [-1, 1]"
            )
        twist = np.zeros(3)
        twist[: len(a)] = np.clip(a, -1.0, 1.0) * self.max_speed
        sdt = self.settings.dt
        total_int = tip_int = mean_total = 0.0
        termination = divergence = None
        new = 0
        for _ in range(self.frame_skip):
            target = self.pose + twist * sdt
            try:
                self.model.step(target[0], target[1], target[2])
            except FloatingPointError as e:
                termination, divergence = "divergence", str(e)
                break
            self.pose = target
            f = self.model.contact_forces()
            fm = np.linalg.norm(f, axis=1)
            self.forces = f
            total = float(fm.sum())
            total_int += sdt * max(0.0, total - TOTAL_PER_TIP * self.nb)
            tip_int += sdt * float(np.maximum(fm - TIP_FORCE_LIMIT, 0.0).sum())
            new += self._stamp(fm)
            mean_total += total / self.frame_skip
        # the hard limit on the control step's mean force: pymunk's rigid contact gives
        # single-step impulse spikes (an axially rigid chain pressed straight) that no robot
        # load cell would see
        if termination is None and mean_total > HARD_PER_TIP * self.nb:
            termination = "force_limit"
        self.steps += 1
        if termination is None and not self._in_workspace():
            termination = "workspace"
        terms = {
            "coverage": self.w["coverage"] * new / self.coverage.n,
            "total_force": -self.w["total"] * total_int,
            "tip_force": -self.w["tip"] * tip_int,
            "termination": -self.w["term"] if termination else 0.0,
        }
        self._done = termination is not None
        info = {
            "reward_terms": terms,
            "coverage": self.coverage.fraction,
            "total_force": float(np.linalg.norm(self.forces, axis=1).sum()),
            "termination": termination,
            "divergence": divergence,
            "time": self.model.time,
        }
        obs = self._obs()
        return obs, float(sum(terms.values())), self._done, False, info

    def _stamp(self, fm) -> int:
        """Clean the cells under tips whose force is inside FlatPlate-v0's window [0.01, 0.2] N,
        swept from their last effective x."""
        x = self.model.tip_positions()[:, 0]
        eff = (fm >= 0.01) & (fm <= TIP_FORCE_LIMIT)
        idx = np.flatnonzero(eff)
        prev = self.prev_cp[idx]
        new = self.coverage.stamp(np.where(np.isfinite(prev), prev, x[idx]), x[idx])
        self.prev_cp = np.where(eff, x, np.nan)
        return new

    def _in_workspace(self) -> bool:
        x, z, ang = self.pose
        h = z - self.z_touch
        return abs(x) <= 30.0 and -5.0 <= h <= 15.0 and abs(ang) <= math.radians(30.0)

    def _obs(self):
        m = self.model
        c, s_ = math.cos(self.pose[2]), math.sin(self.pose[2])
        rel = m.tip_positions() - self.pose[:2]
        local = np.column_stack([c * rel[:, 0] + s_ * rel[:, 1], -s_ * rel[:, 0] + c * rel[:, 1]])
        rest = m.rest_tip_offset
        fm = np.linalg.norm(self.forces, axis=1)
        tcp = self.model.root_force()
        vals = {
            "tip_deflection": (local - rest) / self.L,
            "tip_contact": (fm > 0).astype(float),
            "tip_force": fm / TIP_FORCE_LIMIT,
            "tcp_force": np.array([tcp[0] / 10.0, tcp[1] / 10.0, tcp[2] / 200.0]),
            "tcp_pose": np.array(
                [
                    self.pose[0] / 30.0,
                    (self.pose[1] - self.z_touch) / 10.0,
                    self.pose[2] / math.radians(30.0),
                ]
            ),
            "coverage": np.r_[self.coverage.cleaned.mean(), self.coverage.coarse()],
            "time_remaining": np.array([max(0.0, 1.0 - self.steps / self.horizon)]),
        }
        low, high = self._bounds
        vals = {
            k: np.clip(np.reshape(v, self.blocks_sizes[k]), low[k], high[k]).astype(np.float32)
            for k, v in vals.items()
        }
        if self.observation_mode == "dict":
            return vals
        return np.concatenate([v.ravel() for v in vals.values()]).astype(np.float32)

    # ------------------------------------------------------------------ rendering
    def render(self):
        if self.render_mode is None:
            gym.logger.warn("render() called with render_mode=None: pass render_mode='rgb_array'")
            return None
        import matplotlib

        matplotlib.use("Agg", force=False)
        import matplotlib.pyplot as plt

        # drawn from the pymunk bodies directly: pymunk 7 deprecates its matplotlib DrawOptions
        fig, ax = plt.subplots(figsize=(6.4, 3.2), dpi=80)
        ax.set_xlim(self.pose[0] - 20, self.pose[0] + 20)
        ax.set_ylim(-5, self.z_touch + 6)
        ax.set_aspect("equal")
        prof = np.asarray(self.profile.points)
        ax.fill_between(prof[:, 0], prof[:, 1], -5, color="0.85")
        ax.plot(prof[:, 0], prof[:, 1], "k", lw=0.8)
        head = np.asarray(self.model.head.position)
        fm = np.linalg.norm(self.forces, axis=1)
        for chain, tip, f in zip(self.model.chains, self.model.tips, fm, strict=True):
            pts = [np.asarray(b.local_to_world((0.0, 0.5 * (self.L / len(chain))))) for b in chain]
            pts.append(np.asarray(tip.body.local_to_world(tip.offset)))
            pts = np.array(pts)
            ax.plot(pts[:, 0], pts[:, 1], color="tab:red" if f > 0 else "tab:blue", lw=1.2)
            ax.add_patch(plt.Circle(pts[-1], tip.radius, color="tab:red" if f > 0 else "0.4"))
        ax.plot(*head, "ks", ms=5)
        xs = -self.half + (np.flatnonzero(self.coverage.cleaned) + 0.5) * self.coverage.cell
        ax.plot(xs, np.full(len(xs), -1.0), "g|", ms=4)
        ax.set_title(f"coverage {100 * self.coverage.fraction:.1f} %", fontsize=8)
        fig.canvas.draw()
        img = np.asarray(fig.canvas.buffer_rgba())[..., :3].copy()
        plt.close(fig)
        return img
