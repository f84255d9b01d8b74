"""The engine's face: ``Simulator(scene, settings)`` driven by the TCP pose, reporting the TCP
wrench.

A designer's script::

    from brush_env.engine import Simulator, load_fidelity, load_scene
    sim = Simulator(load_scene("flat_plate"), load_fidelity("balanced").settings(dt=1e-3))
    sim.reset(tcp_p, tcp_R)
    for p, R in poses:
        out = sim.step(p, R)
        print(out.time, out.tcp_force)

The simulator knows the drive (poses checked, ``dt`` split into solver steps, a divergence rolled
back) and the outputs; the bristles themselves are stepped through the seam of ``bristles.py``
(the full DFM chain, ``chain.py``, or another registered model: ``SimSettings.model``).
"""

from __future__ import annotations

import dataclasses
import math
import sys
import warnings
from dataclasses import dataclass, field
from types import FrameType
from typing import Any

import numpy as np

from . import step as itg  # the integrator's stages, in order (step.step_bristles)
from .bristles import make_bristle_model
from .chain import State
from .chain_rollout import make_follow_record
from .config import BrushConfig
from .records import STOP_REASONS
from .rotation import expmap, logmap, pose_ok
from .scene import Scene
from .settings import G_EARTH, INTEGRATORS, SimSettings, SimulationDivergence

__all__ = [
    "G_EARTH",
    "INTEGRATORS",
    "PENETRATION_WARN_FRACTION",
    "PenetrationWarning",
    "Follow",
    "Rollout",
    "SimSettings",
    "SimulationDivergence",
    "Simulator",
    "State",
    "StepResult",
]

#: a tip's penetration beyond this fraction of its radius is outside the penalty law's range
#: (eq 6 models a shallow indentation of the tip sphere): warned once per simulator episode (the
#: warning is re-armed by ``reset``), and every solver step beyond it is counted
#: (``StepResult.extra["steps_beyond_penalty_range"]``)
PENETRATION_WARN_FRACTION = 0.1


class PenetrationWarning(RuntimeWarning):
    """A tip sphere sank deeper into a surface than the penalty law (eq 6) is meant for."""


def _caller_level() -> int:
    """warnings.warn's stacklevel of the first frame outside this module (the user's call)."""
    level = 2
    f: FrameType | None = sys._getframe(2)
    while f is not None and f.f_code.co_filename == __file__:
        level += 1
        f = f.f_back
    return level


@dataclass
class StepResult:
    """Outputs after a step (world frame unless stated).

    tcp_force [N], tcp_moment [N*mm] about the TCP: the wrench the TCP (robot) applies to the brush,
    i.e. the constraint reaction of the prescribed base motion (in the static case exactly minus
    the sum of external loads and their moments).  ``*_tcp`` are the same in the TCP frame.
    tip_pos (nb,3) [mm], tip_vel (nb,3) [mm/s] of the tip nodes (sphere centres);
    contact per tip (zero without surfaces): tip_normal_force (nb,) [N], tip_tangential_force
    (nb,3) [N, world], tip_in_contact (nb,) bool, tip_sliding (nb,) bool, tip_penetration (nb,)
    [mm], tip_contact_point (nb,3) [mm]; iterations (Newton, all bristles), substeps.

    ``extra`` (besides the bristle model's counters): tip_tip_force (nb,) [N], tip_surface (nb,);
    over every solver step of this step (the in-step peaks a step-end value hides):
    max_tip_penetration [mm], max_shaft_penetration [mm] (0 without shaft contact),
    steps_beyond_penalty_range (solver steps with a tip deeper than PENETRATION_WARN_FRACTION of
    its radius); with the scene's shaft contact: shaft_normal_force (nb,) [N] per bristle, summed
    over its bodies, at the step's end; with its head contact: head_clearance [mm], the smallest
    clearance of the head's outline to the surfaces over the solver steps (<= 0: the head
    touches).
    """

    time: float
    tcp_force: np.ndarray
    tcp_moment: np.ndarray
    tcp_force_tcp: np.ndarray
    tcp_moment_tcp: np.ndarray
    tip_pos: np.ndarray
    tip_vel: np.ndarray
    iterations: int
    substeps: int
    tip_normal_force: np.ndarray
    tip_tangential_force: np.ndarray
    tip_in_contact: np.ndarray
    tip_sliding: np.ndarray
    tip_penetration: np.ndarray
    tip_contact_point: np.ndarray
    extra: dict = field(default_factory=dict)


class Simulator:
    """A brush driven by a prescribed TCP pose (see the module docstring).

    ``scene``: a ``Scene`` (or a ``BrushConfig``: no surfaces); ``settings``: ``SimSettings``
    (a fidelity level's ``settings()``), whose ``bodies_per_bristle`` (if not 0) re-discretises
    the scene's brush and whose ``model`` picks the bristle model behind the seam.
    """

    def __init__(self, scene, settings: SimSettings | None = None):
        if isinstance(scene, BrushConfig):
            scene = Scene(scene)
        self.settings = settings or SimSettings()
        if self.settings.bodies_per_bristle:
            scene = dataclasses.replace(
                scene, brush=scene.brush.with_bodies(self.settings.bodies_per_bristle)
            )
        self.scene = scene
        self.brush = scene.brush
        self.bristles = make_bristle_model(scene, self.settings)
        self._pen_warned = False
        self._peaks = _Peaks()

    @property
    def model(self):
        """The brush geometry of the bristle model (``bristles.py``: bstart, root_p, ...)."""
        return self.bristles.model

    @property
    def state(self):
        """The bristle model's state (``pos``, ``rot``, ``tcp_p``, ``tcp_R``, ``time``, ...)."""
        return self.bristles.state

    def reset(self, tcp_p=None, tcp_R=None, time: float = 0.0) -> StepResult:
        """Straight, unstressed bristles at rest on a TCP at pose (tcp_p [mm], tcp_R)."""
        tcp_p = np.zeros(3) if tcp_p is None else np.asarray(tcp_p, float)
        tcp_R = np.eye(3) if tcp_R is None else np.asarray(tcp_R, float)
        self._check_pose(tcp_p, tcp_R)
        self.bristles.reset(tcp_p, tcp_R, time)
        self._pen_warned = False  # warned once per episode, not once per Simulator
        self._peaks = _Peaks()
        self._track()
        return self._result(0, 0)

    @staticmethod
    def _check_pose(p, R):
        if p.shape == (3,) and R.shape == (3, 3) and pose_ok(p, R, 1e-6):
            return
        if p.shape != (3,) or not np.all(np.isfinite(p)):
            raise ValueError(f"tcp_p = {p!r}: must be 3 finite numbers (mm)")
        raise ValueError(
            f"tcp_R = {R!r}: must be a rotation matrix (orthonormal, det +1, tolerance 1e-6)"
        )

    def _check_motion(self, tcp_p, tcp_R) -> None:
        """A command the TCP cannot reach within one step at the allowed speeds is refused
        before anything changes (an implicit step would otherwise try to follow the jump)."""
        s, st = self.settings, self.state
        v = float(np.linalg.norm(tcp_p - st.tcp_p[1])) / s.dt
        if v > s.max_tcp_speed:
            raise ValueError(
                f"tcp_p = {tcp_p.tolist()} is {v * s.dt:.4g} mm from the current TCP position in "
                f"one step of dt = {s.dt:g} s: {v:.4g} mm/s, allowed up to "
                f"settings.max_tcp_speed = {s.max_tcp_speed:g} mm/s"
            )
        w = float(np.linalg.norm(logmap(tcp_R @ st.tcp_R[1].T))) / s.dt
        if w > s.max_tcp_angular_speed:
            raise ValueError(
                f"tcp_R turns {w * s.dt:.4g} rad from the current TCP orientation in one step of "
                f"dt = {s.dt:g} s: {w:.4g} rad/s, allowed up to settings.max_tcp_angular_speed "
                f"= {s.max_tcp_angular_speed:g} rad/s"
            )

    def set_tip_forces(self, forces) -> None:
        """Dead external loads on the tips [N, world], shape (nb, 3)."""
        f = np.asarray(forces, float)
        if f.shape != (self.model.n_bristles, 3) or not np.all(np.isfinite(f)):
            raise ValueError(
                f"tip forces must be finite with shape ({self.model.n_bristles}, 3)"
                f", got shape {f.shape}"
            )
        self.bristles.set_tip_forces(f)

    def get_state(self):
        return self.state.copy()

    def set_state(self, state) -> None:
        self.bristles.set_state(state)

    # ------------------------------------------------------------------ stepping
    def step(self, tcp_p, tcp_R) -> StepResult:
        """Advance one step of ``settings.dt`` to the TCP pose (tcp_p [mm], tcp_R) at t + dt."""
        st = self.state
        if st is None:
            raise RuntimeError("call reset() before step()")
        tcp_p = np.asarray(tcp_p, float)
        tcp_R = np.asarray(tcp_R, float)
        self._check_pose(tcp_p, tcp_R)
        self._check_motion(tcp_p, tcp_R)
        self._peaks = _Peaks()
        n = self.settings.substeps
        if n == 1:
            return self._result(*self._advance(tcp_p, tcp_R, st.time + self.settings.dt))
        return self._advance_split(tcp_p, tcp_R, n)

    def _advance_split(self, tcp_p, tcp_R, n: int) -> StepResult:
        """``step`` as n equal internal steps (settings.max_substep) to the poses of
        ``_split_poses``.  A divergence in any of them restores the state of the start of the
        whole step."""
        st = self.state
        t0, h = st.time, self.settings.dt / n
        P, R = _split_poses(st.tcp_p[1], st.tcp_R[1], tcp_p, tcp_R, n)
        start = self.bristles.snapshot()  # the rollback target of every internal step
        iters = nsub = 0
        for k in range(1, n + 1):
            it, ns = self._advance(P[k - 1], R[k - 1], t0 + k * h, start)
            iters += it
            nsub += ns
        st.time = t0 + self.settings.dt  # no round-off drift of the step grid
        st.steps = start.steps + 1  # steps counts calls of step, not internal steps
        return self._result(iters, nsub)

    def rollout(
        self,
        v,
        w,
        n: int,
        force_stop: float = math.inf,
        penetration_stop: float = math.inf,
    ) -> Rollout:
        """``n`` steps of ``settings.dt`` with the TCP at the constant twist (v [mm/s], w [rad/s],
        world): p_k = p_{k-1} + v dt, R_k = expmap(w dt) R_{k-1}.  Stops after the step at which
        the total tip normal force exceeds ``force_stop`` [N], the head touches a surface
        (``head_clearance`` <= 0) or a tip's in-step penetration exceeds ``penetration_stop``
        [mm]; a divergence restores the last converged step and stops (``Rollout.stop``).

        A bristle model with a compiled rollout (the reduced model) runs all of it in one call
        (``prb_rollout.py``); any other goes through ``step`` (``Rollout.record`` holds the same
        per-step arrays either way)."""
        st = self.state
        if st is None:
            raise RuntimeError("call reset() before rollout()")
        v = np.asarray(v, float)
        w = np.asarray(w, float)
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"n = {n!r}: must be an integer >= 1 (steps)")
        s = self.settings
        # |v|, |w| by math (every env step comes here: numpy's norm and isfinite cost ~10 us);
        # a NaN or inf entry makes the norm NaN or inf, refused below as numpy's test did
        sp, wp = math.hypot(*v), math.hypot(*w)
        if not (math.isfinite(sp) and sp <= s.max_tcp_speed):
            raise ValueError(
                f"v = {v.tolist()}: must be finite, |v| = {sp:.4g} mm/s up to "
                f"settings.max_tcp_speed = {s.max_tcp_speed:g} mm/s"
            )
        if not (math.isfinite(wp) and wp <= s.max_tcp_angular_speed):
            raise ValueError(
                f"w = {w.tolist()}: must be finite, |w| = {wp:.4g} rad/s up to "
                f"settings.max_tcp_angular_speed = {s.max_tcp_angular_speed:g} rad/s"
            )
        fast = getattr(self.bristles, "rollout", None)
        if fast is not None:
            done, stop, msg, rec = fast(v, w, int(n), force_stop, penetration_stop)
            beyond = int(rec.beyond[:done].sum()) if done else 0
            self._peaks = _Peaks(
                float(rec.pen_max[:done].max()) if done else 0.0,
                0.0,
                beyond,
                float(rec.head[:done].min()) if done else math.inf,
            )
            if beyond and not self._pen_warned:
                self._warn_penetration(*self._deepest(rec, done))
            return Rollout(done, stop, msg, rec, self._result(0, done * s.substeps))
        return self._rollout_steps(v, w, int(n), force_stop, penetration_stop)

    def follow(
        self,
        P,
        R,
        force_stop: float = math.inf,
        penetration_stop: float = math.inf,
        stop_at_head_contact: bool = False,
        keep_bodies=(),
    ) -> Follow:
        """``len(P)`` steps of ``settings.dt``, the TCP at pose (P[k] [mm], R[k]) at the end of
        step k -- ``step`` for each pose, with every step's outputs in the arrays of
        ``Follow.record`` (``chain_rollout.FollowRecord``) instead of a ``StepResult`` each.

        A bristle model with a compiled follow (the full chain) runs all of it in one call
        (``chain_rollout.py``; with ``settings.substeps`` > 1 at the solver steps' poses of
        ``_split_poses``, as ``step``); otherwise the steps go through ``step`` and fill the
        same record.  The results are those of ``step`` to the bit.  Every
        pose is checked before anything moves (as ``step`` checks one).  Stops after the step at
        which the total normal force (tips and shafts) exceeds ``force_stop`` [N], a penetration
        exceeds ``penetration_stop`` [mm], or (``stop_at_head_contact``) the head touches; a
        divergence restores the state of the failed step's start and stops
        (``Follow.error`` holds the ``SimulationDivergence``).  ``keep_bodies``: the steps
        (indices into P, increasing) after which every body's centre [mm] (``State.pos``) is
        kept, in ``Follow.record.body`` in that order: a caller that stores bristle shapes
        every few steps need not end a ``follow`` at each."""
        st = self.state
        if st is None:
            raise RuntimeError("call reset() before follow()")
        P = np.ascontiguousarray(P, dtype=float)
        R = np.ascontiguousarray(R, dtype=float)
        self._check_poses(P, R)
        n, nb = P.shape[0], self.model.n_bristles
        keep = _keep_slots(keep_bodies, n)
        kept = int(keep.max()) + 1  # (n >= 1: _check_poses)
        rec = make_follow_record(n, nb, kept, st.pos.shape[0] if kept else 0)
        limits = np.array(
            [
                force_stop,
                penetration_stop,
                0.0 if stop_at_head_contact else -math.inf,
                PENETRATION_WARN_FRACTION,
            ],
            dtype=float,
        )
        fast = getattr(self.bristles, "follow", None)
        if fast is None:
            return self._follow_steps(P, R, limits, rec, keep)
        sub = self.settings.substeps
        if sub > 1:  # every solver step's pose, as _advance_split interpolates them
            Pi, Ri = np.empty((n * sub, 3)), np.empty((n * sub, 3, 3))
            p0, R0 = st.tcp_p[1], st.tcp_R[1]
            for k in range(n):
                rows = slice(k * sub, (k + 1) * sub)
                Pi[rows], Ri[rows] = _split_poses(p0, R0, P[k], R[k], sub)
                p0, R0 = P[k], R[k]
            P, R = Pi, Ri
        done, stop, error = fast(P, R, limits, rec, keep)
        if done:
            k = done - 1
            self._peaks = _Peaks(
                float(rec.pen_max[k]),
                float(rec.shaft_pen[k]),
                int(rec.beyond[k]),
                float(rec.head[k]),
            )
            first = np.flatnonzero(rec.beyond[:done])
            if first.size and not self._pen_warned:
                j = int(first[0])
                pen = rec.pen[j]
                self._warn_penetration(pen, pen / self.model.tip_radius, float(rec.t[j]))
        return Follow(done, STOP_REASONS[stop], error, rec)

    def _check_poses(self, P, R) -> None:
        """``step``'s checks of every pose of a ``follow`` (the first refused is named)."""
        if P.ndim != 2 or P.shape[1:] != (3,) or R.shape != (P.shape[0], 3, 3) or not len(P):
            raise ValueError(
                f"P {P.shape}, R {R.shape}: must be (n, 3) positions [mm] and (n, 3, 3) "
                "rotations, n >= 1"
            )
        s = self.settings
        for k in range(P.shape[0]):
            if not pose_ok(P[k], R[k], 1e-6):
                try:
                    self._check_pose(P[k], R[k])
                except ValueError as e:
                    raise ValueError(f"pose {k}: {e}") from None
        prev_p = np.vstack([self.state.tcp_p[1][None], P[:-1]])
        prev_R = np.concatenate([self.state.tcp_R[1][None], R[:-1]])
        v = np.linalg.norm(P - prev_p, axis=1) / s.dt
        cos = (np.einsum("kab,kab->k", R, prev_R) - 1.0) / 2.0  # trace(R_k R_{k-1}^T) = 2 cos + 1
        w = np.arccos(np.clip(cos, -1.0, 1.0)) / s.dt
        for name, speed, limit, unit in (
            ("max_tcp_speed", v, s.max_tcp_speed, "mm/s"),
            ("max_tcp_angular_speed", w, s.max_tcp_angular_speed, "rad/s"),
        ):
            over = np.flatnonzero(speed > limit)
            if over.size:
                k = int(over[0])
                raise ValueError(
                    f"pose {k}: {speed[k]:.4g} {unit} from the pose before it in one step of dt = "
                    f"{s.dt:g} s, allowed up to settings.{name} = {limit:g} {unit}"
                )

    def _follow_steps(self, P, R, limits, rec, keep) -> Follow:
        """``follow`` through ``step`` (models without a compiled one)."""
        done, stop, error = 0, None, None
        for k in range(P.shape[0]):
            try:
                out = self.step(P[k], R[k])
            except SimulationDivergence as e:
                stop, error = "divergence", e
                break
            record_row(rec, k, out)
            if keep[k] >= 0:
                rec.body[keep[k]] = self.state.pos
            done = k + 1
            total = float(out.tip_normal_force.sum()) + float(rec.shaft_fn[k].sum())
            if total > limits[0]:
                stop = "force_limit"
            elif rec.head[k] <= limits[2]:
                stop = "head_contact"
            elif max(rec.pen_max[k], rec.shaft_pen[k]) > limits[1]:
                stop = "penetration"
            if stop is not None:
                break
        return Follow(done, stop, error, rec)

    def _deepest(self, rec, done) -> tuple[np.ndarray, np.ndarray]:
        """(penetration, excess) of the step's deepest tip, as ``_track`` gives them."""
        pen = self.bristles.tip_penetration()
        k = int(np.argmax(rec.pen_max[:done]))
        pen = np.maximum(pen, 0.0)
        b = int(np.argmax(pen))
        pen = pen.copy()
        pen[b] = max(pen[b], float(rec.pen_max[k]))
        return pen, pen / self.model.tip_radius

    def _rollout_steps(self, v, w, n, force_stop, penetration_stop) -> Rollout:
        """``rollout`` through ``follow`` (models without a compiled rollout): the poses of the
        constant twist, then ``follow``'s record in ``prb_rollout``'s layout."""
        from .prb_rollout import Record  # the record's layout (numpy only)

        dt = self.settings.dt
        dR = expmap(w * dt)
        P = np.empty((n, 3))
        R = np.empty((n, 3, 3))
        p, Rk = self.state.tcp_p[1].copy(), self.state.tcp_R[1].copy()
        for k in range(n):
            p, Rk = p + v * dt, dR @ Rk
            P[k], R[k] = p, Rk
        run = self.follow(P, R, force_stop, penetration_stop, stop_at_head_contact=True)
        f = run.record
        rec = Record(
            f.fn, f.cpt, f.surf, f.pen_max, f.beyond, f.head, P, R, f.shaft_fn.sum(axis=1),
            f.shaft_pen,
        )  # fmt: skip
        k = run.done - 1
        out = self._result(int(f.iters[k]), int(f.nsub[k])) if run.done else self._result(0, 0)
        return Rollout(run.done, run.stop, None if run.error is None else str(run.error), rec, out)

    def solve_static(self, tcp_p=None, tcp_R=None, increments: int = 1) -> StepResult:
        """Static equilibrium at the given (or current) TCP pose under the current tip loads.

        The external tip loads are applied in ``increments`` equal load steps (continuation for
        large deflections).  Velocities are set to zero.
        """
        st = self.state
        if st is None:
            raise RuntimeError("call reset() before solve_static()")
        tcp_p = st.tcp_p[1].copy() if tcp_p is None else np.asarray(tcp_p, float)
        tcp_R = st.tcp_R[1].copy() if tcp_R is None else np.asarray(tcp_R, float)
        self._check_pose(tcp_p, tcp_R)
        full = self.bristles.tip_forces.copy()
        self._peaks = _Peaks()
        try:
            for k in range(1, increments + 1):
                self.bristles.set_tip_forces(full * (k / increments))
                counts = self.bristles.solve_static(tcp_p, tcp_R)
                self._track()
        finally:
            self.bristles.set_tip_forces(full)
        return self._result(*counts)

    def _advance(self, tcp_p, tcp_R, t_new, rollback=None) -> tuple[int, int]:
        """One solver step of the bristle model, then the penetration check and the in-step
        peaks."""
        counts = self.bristles.advance(tcp_p, tcp_R, t_new, rollback)
        pen, excess = self._track()
        if not self._pen_warned:
            self._warn_penetration(pen, excess)
        return counts

    def _track(self) -> tuple[np.ndarray, np.ndarray]:
        """The in-step peaks (``_Peaks``) after a solver step; returns the tips' penetrations
        [mm] and the same as fractions of their radii."""
        pk = self._peaks
        pen = self.bristles.tip_penetration()
        excess = pen / self.model.tip_radius
        if pen.size:
            pk.tip = max(pk.tip, float(pen.max()))
            pk.beyond += int(bool(np.any(excess > PENETRATION_WARN_FRACTION)))
        pk.shaft = max(pk.shaft, self.bristles.shaft_penetration_max())
        hc = self.bristles.head_clearance()
        if hc is not None:
            pk.head = min(pk.head, hc)
        return pen, excess

    def touch_height(self, tcp_R=None, plate_z: float = 0.0) -> float:
        """TCP height z [mm] at which the lowest tip sphere of the unloaded brush just touches the
        horizontal plate z = ``plate_z`` [mm], with the TCP orientation ``tcp_R`` (default the
        brush pointing down, diag(1, -1, -1)).  Reset there (or higher) so that the first step
        does not start with the tips inside the plate."""
        R = np.diag([1.0, -1.0, -1.0]) if tcp_R is None else np.asarray(tcp_R, float)
        return float(plate_z - np.min((self.rest_tips() @ R.T)[:, 2] - self.model.tip_radius))

    def rest_tips(self) -> np.ndarray:
        """(nb, 3) [mm] the tip nodes (sphere centres) of the straight, unloaded brush in the TCP
        frame: each root plus its length along the bristle's axis."""
        m = self.model
        return m.root_p + m.length[:, None] * m.root_R[:, :, 0]

    @property
    def n_tip_pairs(self) -> int:
        """Number of tip-tip pairs kept for this scene (each counted once; 0 if the model keeps
        none)."""
        return int(getattr(self.bristles, "n_tip_pairs", 0))

    # ------------------------------------------------------------------ outputs
    def tip_positions(self) -> np.ndarray:
        """Tip node (sphere centre) of every bristle [mm, world], (nb, 3)."""
        return self.bristles.tip_states()[:, 0:3]

    def tip_velocities(self) -> np.ndarray:
        """Tip node velocity of every bristle [mm/s, world], (nb, 3)."""
        return self.bristles.tip_states()[:, 3:6]

    def _warn_penetration(
        self, pen: np.ndarray, excess: np.ndarray, time: float | None = None
    ) -> None:
        """Once per reset: the deepest tip beyond PENETRATION_WARN_FRACTION of its radius
        (``excess``: penetration / radius) at ``time`` [s] (default: now)."""
        b = int(np.argmax(excess))
        if excess[b] > PENETRATION_WARN_FRACTION:
            self._pen_warned = True
            warnings.warn(
                f"t = {self.state.time if time is None else time:.6g} s: tip of bristle {b} "
                "penetrates "
                f"{1e3 * pen[b]:.1f} um = {100 * excess[b]:.0f} % of its radius "
                f"({self.model.tip_radius[b]:g} mm), beyond the "
                f"{100 * PENETRATION_WARN_FRACTION:.0f} % the penalty law (eq 6) is meant for: "
                "contact forces there are not reliable (stiffer material or deeper press than "
                "the scene's contact parameters were fitted for); warned once per reset",
                PenetrationWarning,
                stacklevel=_caller_level(),
            )

    def _result(self, iters: int, nsub: int) -> StepResult:
        st = self.state
        R_tcp = st.tcp_R[1]
        w = np.empty(6)
        itg.tcp_wrench(R_tcp, self.model.root_p, self.bristles.root_wrench, w)
        F, M = w[0:3], w[3:6]
        c = self.bristles.contact()
        tips = self.bristles.tips.copy()
        pk = self._peaks
        extra = {
            "tip_tip_force": c.tip_tip_force,
            # index of the surface each tip touches deepest (-1: none; Scene.surfaces order)
            "tip_surface": c.surface,
            "max_tip_penetration": pk.tip,
            "max_shaft_penetration": pk.shaft,
            "steps_beyond_penalty_range": pk.beyond,
        }
        sc = self.bristles.shaft_contact()
        if sc is not None:
            extra["shaft_normal_force"] = np.add.reduceat(sc.normal_force, self.model.bstart[:-1])
        if np.isfinite(pk.head):
            extra["head_clearance"] = pk.head
        return StepResult(
            st.time,
            F,
            M,
            R_tcp.T @ F,
            R_tcp.T @ M,
            tips[:, 0:3],
            tips[:, 3:6],
            iters,
            nsub,
            c.normal_force,
            c.tangential_force,
            c.normal_force > 0.0,
            c.sliding,
            c.penetration,
            c.contact_point,
            extra={**extra, **self.bristles.solver_info()},
        )


@dataclass
class Rollout:
    """What ``Simulator.rollout`` did: ``done`` steps (<= n), ``stop`` why it stopped early (None,
    "divergence", "force_limit", "head_contact", "penetration"), ``message`` (the divergence's),
    ``record`` the per-step arrays (``prb_rollout.Record``; rows < done), ``last`` the
    ``StepResult`` of the last step done (its ``extra`` peaks cover the whole rollout)."""

    done: int
    stop: str | None
    message: str | None
    record: Any  # prb_rollout.Record (a namedtuple of arrays)
    last: StepResult


def record_row(rec, k: int, out: StepResult) -> None:
    """Row k of a ``chain_rollout.FollowRecord`` from the ``StepResult`` of a step (what the
    compiled follow writes there)."""
    ex = out.extra
    rec.t[k] = out.time
    rec.FM[k, 0:3] = out.tcp_force
    rec.FM[k, 3:6] = out.tcp_moment
    rec.iters[k] = out.iterations
    rec.nsub[k] = out.substeps
    rec.sweeps[k] = [ex.get("sweeps", 0), ex.get("resolves", 0), 0]
    if "tip_tip_settled" in ex:
        rec.sweeps[k, 2] = 2 if ex["tip_tip_fallback"] else int(not ex["tip_tip_settled"])
    rec.tips[k, :, 0:3] = out.tip_pos
    rec.tips[k, :, 3:6] = out.tip_vel
    rec.fn[k] = out.tip_normal_force
    rec.ft[k] = out.tip_tangential_force
    rec.slide[k] = out.tip_sliding
    rec.pen[k] = out.tip_penetration
    rec.cpt[k] = out.tip_contact_point
    rec.ftt[k] = ex["tip_tip_force"]
    rec.surf[k] = ex["tip_surface"]
    rec.pen_max[k] = ex["max_tip_penetration"]
    rec.beyond[k] = ex["steps_beyond_penalty_range"]
    rec.shaft_pen[k] = ex["max_shaft_penetration"]
    if "shaft_normal_force" in ex:
        rec.shaft_fn[k] = ex["shaft_normal_force"]
    rec.head[k] = ex.get("head_clearance", math.inf)


def _keep_slots(keep_bodies, n: int) -> np.ndarray:
    """``FollowRun.keep`` for ``Simulator.follow``'s ``keep_bodies`` (steps of n): step k's slot
    in ``FollowRecord.body``, -1 where not kept."""
    rows = np.asarray(keep_bodies, dtype=np.int64).reshape(-1)
    if rows.size and (rows[0] < 0 or rows[-1] >= n or np.any(np.diff(rows) <= 0)):
        raise ValueError(
            f"keep_bodies {rows.tolist()}: must be increasing step indices in [0, {n - 1}]"
        )
    keep = np.full(n, -1, np.int64)
    keep[rows] = np.arange(rows.size)
    return keep


def _split_poses(p0, R0, p1, R1, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The TCP poses at the ends of n equal internal steps from (p0 [mm], R0) to (p1, R1), as
    the kernels interpolate within a step (linear position, geodesic rotation); the last is
    (p1, R1) exactly."""
    w = logmap(R1 @ R0.T)  # world-frame rotation vector from R0 to R1
    P, R = np.empty((n, 3)), np.empty((n, 3, 3))
    for k in range(1, n + 1):
        s = k / n
        P[k - 1] = p1 if k == n else (1.0 - s) * p0 + s * p1
        R[k - 1] = R1 if k == n else expmap(s * w) @ R0
    return P, R


@dataclass
class Follow:
    """What ``Simulator.follow`` did: ``done`` steps (<= len(P)), ``stop`` why it stopped early
    (None, "divergence", "force_limit", "head_contact", "penetration"), ``error`` the
    ``SimulationDivergence`` of a divergence (else None), ``record`` the per-step arrays
    (``chain_rollout.FollowRecord``; rows < done)."""

    done: int
    stop: str | None
    error: SimulationDivergence | None
    record: Any


@dataclass
class _Peaks:
    """The largest tip and shaft penetration [mm], the solver steps with a tip beyond the penalty
    law's range and the head's smallest clearance [mm] over the solver steps of one ``step``."""

    tip: float = 0.0
    shaft: float = 0.0
    beyond: int = 0
    head: float = float("inf")
