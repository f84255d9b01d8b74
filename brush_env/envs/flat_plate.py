"""``brush_env/FlatPlate-v0``: brush a square patch of a flat plate clean without pressing too hard.

Description
-----------
A discrete-flexible-multibody toothbrush (the paper's silicone brush by default: 40 bristles,
tip spheres with the eq 6-10 contact and stick-slip friction) is held by a velocity-controlled
robot above the flat plate z = 0 of Cirelli et al. (Machines 2023).  The agent commands the
tool centre point (TCP) velocity at the control rate; the engine integrates the bristles with
``frame_skip`` implicit steps per action.  A patch of the plate counts as cleaned where a tip
touching it with a normal force inside the per-tip effectiveness window passes over it.  The
paper's press-then-circle trajectory (``agents/reference.py``) is the baseline.

Units: mm, N, s, rad.  Base frame: robot base, z up, origin at the *nominal* patch centre on the
nominal plate surface.  TCP frame: z along the bristles (towards the plate at the start
orientation ``diag(1, -1, -1)`` rotated by the start yaw).  ``L`` = longest bristle; ``z_t`` =
touch height, the TCP height at which the lowest tip sphere touches the nominal plate at the start
orientation (L + tip radius = 10.44 mm for the default brush).

Action Space
------------
``Box(-1, 1, (6,), float32)`` (``action_mode="6d"``) or ``Box(-1, 1, (3,), float32)`` (``"3d"``):
a TCP velocity in the base frame, scaled inside the env, held for the control step.  Finite
values outside [-1, 1] are clipped; NaN/inf or a wrong shape raise ``ValueError``.

| Index | Action | Unit | Scaled by (config key, default) | Modes |
|---|---|---|---|---|
| 0 | vx: TCP linear velocity along base x | mm/s | max_linear_speed[0] = 50 | 6d, 3d |
| 1 | vy: TCP linear velocity along base y | mm/s | max_linear_speed[1] = 50 | 6d, 3d |
| 2 | vz: TCP linear velocity along base z | mm/s | max_linear_speed[2] = 20 | 6d, 3d |
| 3 | wx: TCP angular velocity about base x | rad/s | max_angular_speed[0] = 0.5 | 6d |
| 4 | wy: TCP angular velocity about base y | rad/s | max_angular_speed[1] = 0.5 | 6d |
| 5 | wz: TCP angular velocity about base z | rad/s | max_angular_speed[2] = 1.0 | 6d |

Observation Space
-----------------
``Box(low, high, (8 nb + 23 + m^2,), float32)`` with ``nb`` bristles and an ``m x m`` coarse map
(``coarse_map_size``): 407 for the default brush (nb = 40, m = 8).  With
``observation_mode="dict"`` a ``Dict`` of the same blocks (keys = block names, shapes as listed).
Each value is divided by its scale and clipped to its bounds.  Index ranges (inclusive, Python
expressions in nb and m):

| Index | Block | Shape | Bounds | Meaning (scaling) |
|---|---|---|---|---|
| 0 .. 3*nb-1 | tip_deflection | (nb, 3) | [-2, 2] | tip minus its rest position, TCP frame (/ L) |
| 3*nb .. 6*nb-1 | tip_velocity | (nb, 3) | [-10, 10] | tip velocity relative to the rigidly moving head, TCP frame (/ tip_velocity_scale) |
| 6*nb .. 7*nb-1 | tip_normal_force | (nb,) | [0, 10] | plate normal force per tip (/ tip_force_limit) |
| 7*nb .. 8*nb-1 | tip_contact | (nb,) | [0, 1] | 1 if the tip touches the plate |
| 8*nb .. 8*nb+2 | tcp_force | (3,) | [-5, 5] | force the TCP applies to the brush, TCP frame (/ force_scale) |
| 8*nb+3 .. 8*nb+5 | tcp_moment | (3,) | [-5, 5] | moment about the TCP, TCP frame (/ moment_scale) |
| 8*nb+6 .. 8*nb+8 | tcp_position | (3,) | [-1.5, 1.5] | TCP (x, y, z - z_t), base frame (/ workspace_xy, workspace_xy, max abs workspace_height) |
| 8*nb+9 .. 8*nb+14 | tcp_orientation | (6,) | [-1, 1] | TCP x and y axes in the base frame (first two columns of R) |
| 8*nb+15 .. 8*nb+20 | tcp_twist | (6,) | [-1, 1] | commanded (v, w), base frame (/ max_linear_speed, max_angular_speed) |
| 8*nb+21 .. 8*nb+21 | coverage_fraction | (1,) | [0, 1] | fraction of the patch cleaned |
| 8*nb+22 .. 8*nb+21+m*m | coverage_map | (m, m) | [0, 1] | fraction cleaned per block, rows along +y, columns along +x |
| 8*nb+22+m*m .. 8*nb+22+m*m | time_remaining | (1,) | [0, 1] | 1 - elapsed steps / max_episode_steps |

The plate offset drawn at reset is not observed: contact forces reveal it.

Rewards
-------
``reward = sum(info["reward_terms"].values())``; penalties are integrals over the control step,
so their weights are rates and the trade-off does not depend on ``frame_skip``.  ``F_n`` is the
total plate normal force (sum over tips), ``f_i`` the normal force on tip i.

| Term | Formula | Config keys (default) |
|---|---|---|
| coverage | + coverage_weight * newly cleaned cells / patch cells | coverage_weight (100) |
| total_force | - total_force_weight * integral of max(0, F_n - total_force_limit) dt | total_force_weight (25 /(N s)), total_force_limit (4 N) |
| tip_force | - tip_force_weight * integral of sum_i max(0, f_i - tip_force_limit) dt | tip_force_weight (125 /(N s)), tip_force_limit (0.2 N) |
| termination | - termination_penalty once, on the terminating step | termination_penalty (10) |

A cell is cleaned when an *effective* tip (touching, ``tip_force_window[0] <= f_i <=
tip_force_window[1]``, default [0.01, 0.2] N) passes within ``clean_radius`` of its centre.  Why
these numbers: ``configs/envs/flat_plate.toml`` and ``docs/env.md``.

Starting State
--------------
Straight bristles at rest; TCP at (x, y) = start_center + U(-start_xy_range, start_xy_range)^2,
tip spheres U(start_height) above the nominal plate (TCP z = z_t + U(start_height)), yaw U(+-start_yaw_range_deg) about z; the plate and
patch offset from nominal by U(+-plate_offset_range) per axis.  ``reset(seed=...)`` reproduces
an episode bit for bit.  ``options`` may fix ``"tcp_position"`` (3 floats, base frame, mm),
``"yaw_deg"`` and ``"plate_offset"`` (3 floats, mm).

Episode End
-----------
``terminated`` (``info["termination"]`` says why, else None):
``"divergence"`` the engine failed to converge (``info["divergence"]`` holds the message; the
state is the last converged engine step, never corrupted); ``"force_limit"`` the total normal
force exceeded ``hard_force_limit`` (15 N) at an engine step (the robot's protective stop: the
step ends there; the total normal force is the tips' plus the shafts', i.e. every eq 6 contact);
``"head_contact"`` the head's outline (the roots' bounding rectangle, 1 mm wider) reached a surface
at a solver step (``info["head_clearance_mm"] <= 0``: a rigid stop, the step ends there);
``"penetration"`` a tip or shaft sank deeper than ``max_penetration`` (0.2 mm) at any solver step
of the control step -- the in-step peak ``info["max_tip_penetration_mm"]`` /
``info["max_shaft_penetration_mm"]``, not the step-end value, which hides contact-onset overshoot
(the penalty law is not meant for it); ``"workspace"`` the TCP left ``|x|, |y| <= workspace_xy``, ``workspace_height``
(TCP z - z_t) or tilted more than ``max_tilt_deg``; with ``workspace_edge = "stop"`` the TCP
velocity is instead limited, component by component, so each control step ends inside that box
(the robot's Cartesian limits) and only the tilt ends the episode; with ``"stop_xy"`` only x and
y are limited, and leaving the height range still ends it.  With ``force_guard`` > 0 (N, below
``hard_force_limit``) the TCP backs off (up at ``max_linear_speed[2]``) for the rest of a control
step after the engine step at which the total normal force exceeds it, as a force-limited robot
retracts the tool, and the episode goes on (``info["force_guard"]``: it acted).  Stepping a
terminated episode raises
``RuntimeError``.  ``truncated`` only through the ``TimeLimit`` wrapper (``max_episode_steps``,
default 300 = 12 s at 25 Hz).  The horizon that ``time_remaining`` counts down is passed to the
env explicitly: the config's ``max_episode_steps``, or ``set_horizon(N)``, which ``gym.make``
calls with its ``TimeLimit``'s N (``brush_env.envs.horizon``).

Arguments
---------
``gym.make("brush_env/FlatPlate-v0", config="flat_plate", render_mode=None, **overrides)``:
``config`` is an env config name in ``configs/envs`` or a TOML path; every setting below is also
a keyword override.  Ranges: ``brush_env.envs.config.arguments_table()`` / ``docs/env.md``.

| Parameter | Default | Unit | Meaning |
|---|---|---|---|
| fidelity | "fast" | - | fidelity level (configs/fidelity): the engine's settings (model, bodies, solver step, element, tip-tip solve) |
| engine_settings | {} | - | engine settings replacing the level's, under the engine's names, e.g. {"max_substep": 0.004} |
| brush | "default" | - | brush name in configs/brushes or a TOML path |
| scene | "flat_plate" | - | scene name in configs/scenes or a TOML path |
| engine_dt | 0.004 | s | engine time step (the level's max_substep splits it into solver steps) |
| frame_skip | 10 | count | engine steps per action; dt = engine_dt * frame_skip |
| gravity | True | - | gravity on the bristles |
| tip_tip | "scene" | - | tip-tip contact: the scene file's (on for flat_plate), "on", "off" |
| action_mode | "6d" | - | "6d" or "3d" |
| max_linear_speed | (50, 50, 20) | mm/s | velocity at action +-1 |
| max_angular_speed | (0.5, 0.5, 1.0) | rad/s | angular velocity at action +-1 |
| observation_mode | "box" | - | "box" or "dict" |
| coarse_map_size | 8 | cells | m of the m x m coverage map |
| tip_velocity_scale | 100.0 | mm/s | tip velocity scale |
| force_scale | 10.0 | N | TCP force scale |
| moment_scale | 200.0 | N mm | TCP moment scale |
| patch_size | 64.0 | mm | side of the square patch |
| cell_size | 0.5 | mm | coverage cell side |
| clean_radius | 0.5 | mm | cleaning radius about a tip contact |
| coverage_weight | 100.0 | 1/patch | coverage reward weight |
| tip_force_window | (0.01, 0.2) | N | per-tip force that cleans |
| total_force_limit | 4.0 | N | safe total normal force |
| total_force_weight | 25.0 | 1/(N s) | total force penalty rate |
| tip_force_limit | 0.2 | N | safe per-tip force |
| tip_force_weight | 125.0 | 1/(N s) | per-tip force penalty rate |
| gum_force_limit | 1.0 | N | safe gum force (ToothRow-v0; no gum here) |
| gum_force_weight | 100.0 | 1/(N s) | gum force penalty rate (ToothRow-v0) |
| termination_penalty | 10.0 | - | one-off penalty on termination |
| max_episode_steps | 300 | steps | time limit (gym.make's value wins) |
| hard_force_limit | 15.0 | N | total normal force that terminates |
| force_guard | 0.0 | N | total normal force after which the TCP backs off for the rest of the control step (0: off) |
| max_penetration | 0.2 | mm | tip or shaft penetration at any solver step that terminates |
| workspace_xy | 45.0 | mm | workspace half-width |
| workspace_height | (-5.0, 15.0) | mm | TCP height range above touching |
| workspace_edge | "end" | - | at the workspace edge: "end" the episode, "stop" the TCP, or "stop_xy" |
| max_tilt_deg | 30.0 | deg | largest tilt of the bristle axis |
| start_center | (0.0, 0.0) | mm | centre of the start positions |
| start_xy_range | 5.0 | mm | start x, y spread |
| start_height | (1.0, 2.0) | mm | start height above touching |
| start_yaw_range_deg | 15.0 | deg | start yaw spread |
| plate_offset_range | (1.0, 1.0, 0.5) | mm | plate offset spread per axis |
| render_height | 256 | px | frame height (width 2x) |

Version History
---------------
* v0: initial version (engine with eq 6-10 contact; coverage reward with a per-tip force window,
  total and per-tip force penalties; 6-D/3-D velocity actions; Box/Dict observations).
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Any

import gymnasium as gym
import numpy as np

from brush_env.calibration import ensure_calibrated
from brush_env.coverage import CoverageMap, EffectiveSweep
from brush_env.engine import (
    ConfigError,
    Plane,
    Simulator,
    load_brush,
    load_scene,
)
from brush_env.engine.clearance import deepest_tip
from brush_env.engine.rotation import rot_axis
from brush_env.engine.scene import surface_labels
from brush_env.motion import R0

from .action import make_action_type
from .config import EnvConfig, load_env_config
from .observation import ObservationLayout, make_observation_type
from .rendering import Renderer, RenderInput
from .rollout_sums import Limits, rollout_sums

__all__ = ["BrushEnv", "R_START"]

#: TCP orientation at zero yaw: tool x = base x, tool z = -base z (bristles down onto the plate);
#: the engine trajectories' ``R0``.
R_START = R0

REWARD_TERMS = ("coverage", "total_force", "tip_force", "termination")
RESET_OPTIONS = ("tcp_position", "yaw_deg", "plate_offset")
_Z = np.array([0.0, 0.0, 1.0])  # the start yaw is about base z


class BrushEnv(gym.Env):
    """Brush a patch of the flat plate clean (see the module docstring for the full spec).

    ``BrushEnv(config="flat_plate", render_mode=None, **overrides)``; ``config`` may also be an
    :class:`EnvConfig`.  Attributes: ``config`` (the validated EnvConfig), ``sim`` (the engine's
    Simulator), ``layout`` (ObservationLayout), ``dt`` (control step [s]), ``horizon`` (the time
    limit in steps), ``L`` (longest bristle [mm]), ``touch_height`` (z_t [mm]).
    """

    metadata = {"render_modes": ["rgb_array", "human"]}
    reference_motion = "circle"  # agents/reference.py: the paper's press-then-circle

    def __init__(
        self,
        config: str | os.PathLike | EnvConfig | None = "flat_plate",
        render_mode: str | None = None,
        **overrides,
    ):
        if isinstance(config, EnvConfig):
            cfg = config.replace(**overrides) if overrides else config
        else:
            cfg = load_env_config(config, **overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(
                f"render_mode = {render_mode!r} is not allowed: must be None or one "
                f"of {self.metadata['render_modes']}"
            )
        self.config = cfg
        self.render_mode = render_mode
        brush = load_brush(cfg.brush)
        scene = load_scene(cfg.scene, brush=brush)
        if cfg.tip_tip != "scene":
            scene = dataclasses.replace(scene, tip_tip=cfg.tip_tip == "on")
        self.scene = scene
        self.plate_z = self._surface_height(scene)
        # surfaces whose contact force has a limit of its own (the gum of a tooth row)
        self._gum = np.array([s == "gum" for s in surface_labels(scene)], bool)
        # the level's settings as one value, passed on unchanged (EnvConfig.sim_settings)
        ensure_calibrated(scene.brush, cfg.sim_settings())  # the reduced model of `fast`
        self.sim = Simulator(scene, cfg.sim_settings())
        self.scene = self.sim.scene  # with the level's bodies per bristle
        model = self.sim.model
        self.n_bristles = model.n_bristles
        self.L = float(brush.max_length)
        # touch height: lowest tip sphere of the straight brush at the start orientation R_START
        rest = self.sim.rest_tips()
        self.touch_height = float(np.max(rest[:, 2] + model.tip_radius))
        # which bounds end the episode (workspace_edge); the TCP is stopped at the others
        self._xy_ends = cfg.workspace_edge == "end"
        self._height_ends = cfg.workspace_edge != "stop"
        xy = cfg.workspace_xy
        h_lo, h_hi = (-math.inf, math.inf) if self._height_ends else cfg.workspace_height
        self._edge_lo = np.array([-xy, -xy, h_lo])  # mm: TCP x, y and height above z_t
        self._edge_hi = np.array([xy, xy, h_hi])
        self.action_type = make_action_type(cfg)
        self.action_space = self.action_type.space()
        self.layout = ObservationLayout(cfg, self.n_bristles, self.L, self.touch_height)
        self.observation_type = make_observation_type(cfg, self.layout)
        self.observation_space = self.observation_type.space()
        self.coverage = self._make_coverage()
        self._sweep = EffectiveSweep(self.n_bristles, cfg.tip_force_window)
        # render_fps depends on the configured dt, hence per instance (Gymnasium MuJoCo style)
        self.metadata = {**BrushEnv.metadata, "render_fps": 1.0 / self.dt}
        # chains for the side view: body indices per bristle, padded with the bristle's last body
        nbod = np.diff(model.bstart)
        k = int(nbod.max())
        self._chain_idx = np.minimum(
            model.bstart[:-1, None] + np.arange(k)[None, :], model.bstart[1:, None] - 1
        )
        self._renderer: Any = None  # a Renderer (or ToothRow-v0's FrameWindow), made on first use
        self._horizon = cfg.max_episode_steps
        self._started = False
        self._done = False

    def _surface_height(self, scene) -> float:
        """z [mm] of the surface the brush works on at the nominal pose: the plate's."""
        planes = [
            s
            for s in scene.surfaces
            if isinstance(s, Plane)
            and np.allclose(np.asarray(s.normal) / np.linalg.norm(s.normal), [0, 0, 1])
        ]
        if not planes:
            raise ConfigError(
                f"scene = {self.config.scene!r} has no plane with normal +z: FlatPlate-v0 needs "
                "a flat plate (e.g. configs/scenes/flat_plate.toml; teeth: ToothRow-v0)"
            )
        return float(planes[0].point[2])

    def _make_coverage(self):
        cfg = self.config
        return CoverageMap(cfg.patch_size, cfg.cell_size, cfg.clean_radius, cfg.coarse_map_size)

    # ------------------------------------------------------------------ timing
    @property
    def dt(self) -> float:
        """Control step [s] = engine_dt * frame_skip."""
        return self.config.engine_dt * self.config.frame_skip

    @property
    def horizon(self) -> int:
        """Time limit in control steps that ``time_remaining`` counts down: the config's
        ``max_episode_steps``, or the number passed to :meth:`set_horizon` (``gym.make`` passes
        its ``TimeLimit``'s, so ``gym.make(id, max_episode_steps=N)`` sets it to N)."""
        return self._horizon

    def set_horizon(self, steps: int) -> None:
        """Set the time limit [control steps] that ``time_remaining`` counts down.

        ``gym.make`` calls it through ``brush_env.envs.horizon.TimeLimitHorizon`` with its
        ``TimeLimit``'s ``max_episode_steps``; call it yourself when wrapping a ``BrushEnv`` in a
        ``TimeLimit`` by hand with a number other than the config's ``max_episode_steps``."""
        if isinstance(steps, bool) or not isinstance(steps, int) or steps < 1:
            raise ValueError(
                f"horizon = {steps!r} is out of range: must be an integer >= 1 (control steps)"
            )
        self._horizon = steps

    # ------------------------------------------------------------------ reset
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        cfg, rng = self.config, self.np_random
        # draws in a fixed order (reproducibility): start x, y, height, yaw, plate offset
        xy = np.asarray(cfg.start_center) + rng.uniform(-cfg.start_xy_range, cfg.start_xy_range, 2)
        h = rng.uniform(*cfg.start_height)
        yaw = math.radians(rng.uniform(-cfg.start_yaw_range_deg, cfg.start_yaw_range_deg))
        off = rng.uniform(-1.0, 1.0, 3) * np.asarray(cfg.plate_offset_range)
        p_obs = np.array([xy[0], xy[1], self.touch_height + h])
        opts = dict(options or {})
        for key in opts:
            if key not in RESET_OPTIONS:
                raise ValueError(f"reset option {key!r} is unknown: allowed {RESET_OPTIONS}")
        if "tcp_position" in opts:
            p_obs = self._vec_option("tcp_position", opts["tcp_position"])
        if "yaw_deg" in opts:
            yaw = math.radians(float(opts["yaw_deg"]))
        if "plate_offset" in opts:
            off = self._vec_option("plate_offset", opts["plate_offset"])
        self.plate_offset = off
        self._p = self._to_engine(p_obs)
        self._R = rot_axis(_Z, yaw) @ R_START
        if "tcp_position" in opts or "plate_offset" in opts:
            self._check_start(p_obs, opts)
        self._v = np.zeros(3)
        self._w = np.zeros(3)
        self._last = self.sim.reset(self._p, self._R)
        self._rest_tips = (self._last.tip_pos - self._p) @ self._R
        self.coverage.reset()
        self._sweep.reset()
        self._steps = 0
        self._total_force = 0.0
        self._started, self._done = True, False
        if self.render_mode == "human":
            self.render()
        return self._get_obs(), self._reset_info()

    @staticmethod
    def _vec_option(name, value) -> np.ndarray:
        v = np.asarray(value, dtype=float)
        if v.shape != (3,) or not np.all(np.isfinite(v)):
            raise ValueError(f"reset option {name} = {value!r}: must be 3 finite numbers (mm)")
        return v

    def _check_start(self, p_obs: np.ndarray, opts: dict) -> None:
        """Refuse a start pose given in ``options`` whose tip spheres would begin inside a
        surface (the first step would start from a deep, unphysical penetration)."""
        m = self.sim.model
        tips = self._p + self.sim.rest_tips() @ self._R.T
        depth, tip, srf = deepest_tip(self.scene, tips, m.tip_radius)
        if depth > 1e-6:
            given = ", ".join(
                f"{k} = {np.asarray(opts[k], float).tolist()!r}"
                for k in ("tcp_position", "plate_offset")
                if k in opts
            )
            label = surface_labels(self.scene)[srf]
            raise ConfigError(
                f"reset option {given} starts the tip of bristle {tip} {depth:.3g} mm inside "
                f"surface {srf} ({label!r}): the tip spheres must start outside every surface "
                f"(lift the TCP by >= {depth:.3g} mm; at z = z_t = {self.touch_height:.4g} mm "
                "the tips touch the nominal surface)"
            )

    def _to_engine(self, p_obs: np.ndarray) -> np.ndarray:
        """Base-frame position (about the nominal patch centre / nominal plate) -> engine frame
        (actual patch centre at the origin, plate at ``plate_z``)."""
        return p_obs - self.plate_offset + np.array([0.0, 0.0, self.plate_z])

    def _to_obs(self, p_eng: np.ndarray) -> np.ndarray:
        q = p_eng + self.plate_offset
        q[2] -= self.plate_z  # (three times per env step: no array for (0, 0, plate_z))
        return q

    # ------------------------------------------------------------------ step
    def step(self, action):
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if self._done:
            raise RuntimeError("the episode has terminated: call reset() before step()")
        a = self.action_type.check(action)
        self._v, self._w = self.action_type.twist(a)
        if not self._xy_ends:  # workspace_edge "stop" / "stop_xy"
            self._v = self._limit_to_workspace(self._v)
        sim = self._simulate()
        self._steps += 1
        obs = self._get_obs()
        terms = self._get_rew(sim)
        reward = float(sum(terms.values()))
        terminated = sim["termination"] is not None
        self._done = terminated
        info = self._get_info(sim, terms)
        if self.render_mode == "human":
            self.render()
        return obs, reward, terminated, False, info

    def _simulate(self) -> dict:
        """``frame_skip`` engine steps at the commanded twist (``Simulator.rollout``: one compiled
        call for the reduced model of ``fast``); forces and coverage accumulated from its per-step
        record.

        The rollout stops early on divergence (the engine restores its last converged state),
        when the total normal force exceeds the hard limit, the head touches or a penetration
        exceeds ``max_penetration``.  Workspace is checked on the final pose."""
        cfg = self.config
        dte = cfg.engine_dt
        ro, rec, guarded = self._rollout()
        n = ro.done
        if n:
            self._p, self._R, self._last = rec.p[n - 1].copy(), rec.R[n - 1].copy(), ro.last
        lim = Limits(cfg.total_force_limit, cfg.tip_force_limit, cfg.gum_force_limit, dte)
        sums = rollout_sums(rec, n, self._gum, lim)
        self._total_force = self._normal_force(self._last)
        new_cells = self.coverage.sweep(self._sweep, rec.fn[:n], rec.cpt[:n])
        termination = ro.stop
        if termination is None and not self._in_workspace():
            termination = "workspace"
        return dict(
            new_cells=new_cells,
            total_int=sums.total_int,
            tip_int=sums.tip_int,
            time_above=sums.time_above,
            gum_int=sums.gum_int,
            peak_gum=sums.peak_gum,
            peak_total=sums.peak_total,
            peak_tip=sums.peak_tip,
            termination=termination,
            divergence=ro.message,
            pen_tip=sums.pen_tip,
            pen_shaft=sums.pen_shaft,
            beyond=int(sums.beyond),
            head=sums.head,
            force_guard=guarded,
        )

    def _rollout(self):
        """The control step's engine steps at the commanded twist; with ``force_guard`` set, the
        TCP backs off (base +z at ``max_linear_speed[2]``, no rotation) for the rest of the
        control step after the engine step at which the total normal force exceeds it, as a
        force-limited robot retracts the tool.  Held still instead, a pressed brush stayed on its
        buckled plateau above the limit (docs/rl.md).  Returns the last rollout (its ``done`` the
        steps of both), the record of every step and whether the guard acted."""
        cfg = self.config
        guard = cfg.force_guard if 0.0 < cfg.force_guard < cfg.hard_force_limit else math.inf
        stop_at = min(guard, cfg.hard_force_limit)
        ro = self.sim.rollout(self._v, self._w, cfg.frame_skip, stop_at, cfg.max_penetration)
        if ro.stop != "force_limit" or not math.isfinite(guard):
            return ro, ro.record, False
        k = ro.done - 1
        if ro.record.fn[k].sum() + ro.record.shaft_fn[k] > cfg.hard_force_limit:
            return ro, ro.record, False  # the hard limit itself: the episode ends
        ro.stop = None
        left = cfg.frame_skip - ro.done
        if left == 0:
            return ro, ro.record, True
        up = np.array([0.0, 0.0, cfg.max_linear_speed[2]])  # away from the plate
        back = self.sim.rollout(up, np.zeros(3), left, cfg.hard_force_limit, cfg.max_penetration)
        n1, n2 = ro.done, back.done
        rec = type(ro.record)(
            *[np.concatenate([a[:n1], b[:n2]]) for a, b in zip(ro.record, back.record)]
        )
        back.done = n1 + n2
        return back, rec, True

    @staticmethod
    def _normal_force(out) -> float:
        """Total normal force [N] of an engine step: the tips' and the shafts' (eq 6)."""
        fn = float(out.tip_normal_force.sum())
        shaft = out.extra.get("shaft_normal_force")
        return fn if shaft is None else fn + float(shaft.sum())

    def _limit_to_workspace(self, v: np.ndarray) -> np.ndarray:
        """``workspace_edge = "stop"``: each component of the TCP velocity [mm/s] limited so that
        the control step (``frame_skip`` engine steps at constant v) ends inside the workspace box
        (|x|, |y| <= workspace_xy, height in workspace_height): a component towards an edge
        slows to reach it exactly, as a robot controller's Cartesian limits stop the tool, and
        the episode goes on.  The TCP's path is a straight line, so its end bounds the step.
        ``"stop_xy"``: x and y only (the height bounds, which end the episode, are infinite
        here)."""
        cfg = self.config
        p = self._to_obs(self._p)
        p[2] -= self.touch_height
        lo, hi = self._edge_lo - p, self._edge_hi - p
        # inside the box lo <= 0 <= hi, so v = 0 is always allowed; a pose a rounding error
        # past an edge (the previous step ended on it) only forbids moving further out
        t = cfg.engine_dt * cfg.frame_skip
        return np.minimum(np.maximum(v, np.minimum(lo, 0.0) / t), np.maximum(hi, 0.0) / t)

    def _in_workspace(self) -> bool:
        cfg = self.config
        p = self._to_obs(self._p)
        h = p[2] - self.touch_height
        tilt = math.degrees(math.acos(min(1.0, max(-1.0, -self._R[2, 2]))))
        return (
            (not self._xy_ends or (abs(p[0]) <= cfg.workspace_xy and abs(p[1]) <= cfg.workspace_xy))
            and (not self._height_ends or cfg.workspace_height[0] <= h <= cfg.workspace_height[1])
            and tilt <= cfg.max_tilt_deg
        )

    # ------------------------------------------------------------------ obs / reward / info
    def _get_obs(self):
        out = self._last
        flat = self.layout.flat(
            p=self._p,
            R=self._R,
            v=self._v,
            w=self._w,
            tip_pos=out.tip_pos,
            tip_vel=out.tip_vel,
            rest_tips=self._rest_tips,
            tip_force=out.tip_normal_force,
            tip_contact=out.tip_in_contact,
            tcp_force_tcp=out.tcp_force_tcp,
            tcp_moment_tcp=out.tcp_moment_tcp,
            p_obs=self._to_obs(self._p),
            coverage_fraction=self.coverage.fraction,
            coverage_map=self.coverage.coarse(),
            time_remaining=max(0.0, 1.0 - self._steps / self.horizon),
        )
        return self.observation_type.observe(flat)

    def _get_rew(self, sim: dict) -> dict[str, float]:
        """Signed reward terms (costs negative); the reward is their sum."""
        cfg = self.config
        return {
            "coverage": cfg.coverage_weight * sim["new_cells"] / self.coverage.total,
            "total_force": -cfg.total_force_weight * sim["total_int"],
            "tip_force": -cfg.tip_force_weight * sim["tip_int"],
            "termination": -cfg.termination_penalty if sim["termination"] else 0.0,
        }

    def _reset_info(self) -> dict:
        return {
            "coverage": 0.0,
            "tcp_position": self._to_obs(self._p),
            "plate_offset": self.plate_offset.copy(),
            "time": 0.0,
        }

    def _get_info(self, sim: dict, terms: dict) -> dict:
        out = self._last
        return {
            "reward_terms": terms,
            "coverage": self.coverage.fraction,
            "cells_cleaned": self.coverage.count,
            "total_normal_force": self._total_force,
            "peak_normal_force": sim["peak_total"],
            "peak_tip_force": sim["peak_tip"],
            "time_above_force_limit": sim["time_above"],
            "tips_in_contact": int(out.tip_in_contact.sum()),
            "tcp_position": self._to_obs(self._p),
            "plate_offset": self.plate_offset.copy(),
            "time": float(out.time),
            "termination": sim["termination"],
            "divergence": sim["divergence"],
            # over every solver step of the control step (a step-end value hides them)
            "max_tip_penetration_mm": sim["pen_tip"],
            "max_shaft_penetration_mm": sim["pen_shaft"],
            "steps_beyond_penalty_range": sim["beyond"],
            "head_clearance_mm": sim["head"],
            # the TCP backed off for the rest of the control step (force_guard)
            "force_guard": sim["force_guard"],
        }

    # ------------------------------------------------------------------ rendering
    def render(self):
        if self.render_mode is None:
            gym.logger.warn(
                "render() called with render_mode=None: pass render_mode='rgb_array' "
                "or 'human' to gym.make"
            )
            return None
        frame = self._frame()
        if self.render_mode == "rgb_array":
            return frame
        self._renderer.show(frame, self.metadata["render_fps"])
        return None

    def _frame(self) -> np.ndarray:
        cfg = self.config
        if self._renderer is None:
            m = self.sim.model
            reach = float(np.abs(m.root_p[:, :2]).max()) + self.L
            self._renderer = Renderer(
                cfg.render_height,
                cfg.patch_size,
                self.coverage.n,
                2.0 * reach + 2.0,
                cfg.tip_force_window,
                cfg.tip_force_limit,
                cfg.total_force_limit,
                cfg.hard_force_limit,
            )
        if not self._started:
            raise RuntimeError("call reset() before render()")
        out, st, m = self._last, self.sim.state, self.sim.model
        assert st is not None  # reset() ran
        roots = self._p + m.root_p @ self._R.T
        chains = np.concatenate(
            [roots[:, None], st.pos[self._chain_idx], out.tip_pos[:, None]], axis=1
        )
        return self._renderer.frame(
            RenderInput(
                cleaned=self.coverage.cleaned,
                coverage=self.coverage.fraction,
                tcp_p=self._p,
                tip_pos=out.tip_pos,
                tip_force=out.tip_normal_force,
                tip_contact=out.tip_in_contact,
                chains=chains,
                root_pos=roots,
                total_force=self._total_force,
                time=out.time,
            )
        )

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
