"""The engine's face: ``Simulator(scene, settings)`` driven by the TCP pose, reporting the TCP
wrench.

A designer's script::

    from brush_env.engine import Simulator, SimSettings, load_brush
    sim = Simulator(load_brush("default"), SimSettings(dt=1e-3))
    sim.reset(tcp_p, tcp_R)
    for p, R in poses:
        out = sim.step(p, R)
        print(out.time, out.tcp_force)
"""

from __future__ import annotations

import sys
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import records as rec
from . import step as itg  # the integrator's stages, in order (step.step_bristles)
from ._kernels import ELEMENTS
from .beam import (
    bristle_frame,
    first_bending_omega,
    mid_frame_stiffness,
    segment_inertia,
    timoshenko_stiffness,
)
from .checks import ConfigError, Limit, check_choice, check_int, check_real
from .config import BrushConfig
from .mesh_contact import build_mesh, empty_mesh
from .rotation import expmap, logmap, pose_ok
from .scene import MeshPlate, Scene
from .sdf import pack_grids

G_EARTH = 9810.0  # [mm/s^2]
INTEGRATORS = {"euler": rec.METHOD_EULER, "bdf2": rec.METHOD_BDF2}


#: a tip's penetration beyond this fraction of its radius is outside the penalty law's range
#: (eq 6 models a shallow indentation of the tip sphere): warned once per simulator
PENETRATION_WARN_FRACTION = 0.1


class PenetrationWarning(RuntimeWarning):
    """A tip sphere sank deeper into a surface than the penalty law (eq 6) is meant for."""


def _caller_level() -> int:
    """warnings.warn's stacklevel of the first frame outside this module (the user's call)."""
    level, f = 2, sys._getframe(2)
    while f is not None and f.f_code.co_filename == __file__:
        level += 1
        f = f.f_back
    return level


class SimulationDivergence(RuntimeError):
    """Raised when Newton fails on the smallest sub-step; the state is left as before the step."""

    def __init__(self, time: float, bristles, reason: str):
        self.time = time
        self.bristles = list(int(b) for b in bristles)
        self.reason = reason
        super().__init__(
            f"simulation diverged at t = {time:.6g} s in bristle(s) {self.bristles[:10]}: {reason}"
        )


@dataclass(frozen=True)
class SimSettings:
    """Numerical settings of the engine.

    dt [s] time step (the interval of ``step``); max_substep [s] the longest step the solver
    takes: a longer ``dt`` is split into ceil(dt / max_substep) equal internal steps with the TCP
    pose interpolated between the two commanded poses (linear position, geodesic rotation), so
    that a large control step does not hold an unstable (buckling) equilibrium or jump across a
    stick-slip transition (default 1 ms: the 3 mm press's hold force is within 3 % of a 0.125 ms
    run, docs/model.md); integrator "euler" (backward Euler) or "bdf2"; newton_rtol: Newton
    tolerance on the residual relative to each bristle's force scale E I / L^2 [-];
    newton_max_iter per attempt; max_substep_levels: a failing (internal) step is retried as
    halves down to its length / 2**levels;
    jacobian_max_age: steps a bristle's factored Newton matrix may be reused (0: rebuild at every
    step; reuse changes iteration counts only, the converged state is set by the residual);
    gravity [mm/s^2] as a world vector (default (0, 0, -9810); (0, 0, 0) switches it off);
    max_tcp_speed [mm/s], max_tcp_angular_speed [rad/s]: the fastest TCP motion ``step``
    accepts (default 1000 mm/s, a UR5's tool speed limit, and 10 turns/s): a faster command is
    a jump, not a motion, and is refused with an error naming the speed;
    element: the beam element formulation, "paper" (the paper's Adams-FIELD element, strain in
    the proximal body's frame) or "mid" (co-rotational Timoshenko element in the mid-frame,
    accurate with few bodies in buckled contact; docs/model.md);
    tip_tip_sweeps: most sweeps over the bristles per (internal) step for tip-tip contact
    (Table 3).  1 (default): one sweep, the partners solved later in the sweep held at their
    start-of-step tips (the tip-tip force lags: 6 % on the flat-plate turn even at 0.125 ms).
    > 1: after the first sweep the touching tips are placed by the coupled solve
    (``coupling.py``) and the bristles whose partners moved by more than tip_tip_tol [mm] since
    they were solved are solved again, so both sides of every tip-tip contact see the
    end-of-step tips (action = reaction within 2 k tol); +50 % wall on the flat-plate turn at
    1 ms, but up to ~7x on the four-turn reference experiment (docs/model.md); the fidelity
    levels reference, paper and balanced use 8.
    """

    dt: float = 1e-3
    integrator: str = "bdf2"
    max_substep: float = 1e-3
    max_tcp_speed: float = 1000.0
    max_tcp_angular_speed: float = 20.0 * np.pi
    newton_rtol: float = 1e-7
    newton_max_iter: int = 100
    max_substep_levels: int = 8
    gravity: tuple = (0.0, 0.0, -G_EARTH)
    jacobian_max_age: int = 25
    element: str = "mid"
    tip_tip_sweeps: int = 1
    tip_tip_tol: float = 1e-6

    @property
    def substeps(self) -> int:
        """Internal steps per ``step``: ceil(dt / max_substep)."""
        return max(1, int(np.ceil(self.dt / self.max_substep - 1e-9)))

    def __post_init__(self):
        check_real("settings.dt", self.dt, Limit("s", gt=0, le=0.1))
        check_real("settings.max_substep", self.max_substep, Limit("s", gt=0, le=0.1))
        check_real("settings.max_tcp_speed", self.max_tcp_speed, Limit("mm/s", gt=0, le=1e5))
        check_real(
            "settings.max_tcp_angular_speed",
            self.max_tcp_angular_speed,
            Limit("rad/s", gt=0, le=1e3),
        )
        check_choice("settings.integrator", self.integrator, sorted(INTEGRATORS), "integrator")
        check_choice("settings.element", self.element, sorted(ELEMENTS), "element")
        check_real("settings.newton_rtol", self.newton_rtol, Limit("relative", gt=0, le=1e-2))
        check_int("settings.newton_max_iter", self.newton_max_iter, Limit("", ge=1, le=1000))
        check_int("settings.max_substep_levels", self.max_substep_levels, Limit("", ge=0, le=30))
        check_int(
            "settings.jacobian_max_age", self.jacobian_max_age, Limit("steps", ge=0, le=10000)
        )
        check_int("settings.tip_tip_sweeps", self.tip_tip_sweeps, Limit("", ge=1, le=1000))
        check_real("settings.tip_tip_tol", self.tip_tip_tol, Limit("mm", gt=0, le=1.0))
        if len(self.gravity) != 3 or not np.all(np.isfinite(self.gravity)):
            raise ConfigError(
                f"settings.gravity = {self.gravity!r}: must be 3 finite numbers (mm/s^2)"
            )


@dataclass
class Model:
    """Static arrays of a brush (see _kernels for the layout)."""

    bstart: np.ndarray  # (nb+1,) int64
    bp: np.ndarray  # (N, 8)
    K: np.ndarray  # (N, 6, 6)
    root_p: np.ndarray  # (nb, 3) root node in the TCP frame [mm]
    root_R: np.ndarray  # (nb, 3, 3) bristle frame in the TCP frame
    seg_len: np.ndarray  # (N,) [mm]
    tip_radius: np.ndarray  # (nb,) [mm]
    length: np.ndarray  # (nb,) [mm]
    elem: np.ndarray  # (N,) int64 element formulation of each body's element (_kernels.ELEM_*)

    def arrays(self) -> rec.ModelArrays:
        """The kernels' view of the model (``records.ModelArrays``)."""
        return rec.ModelArrays(self.bstart, self.bp, self.K, self.root_p, self.root_R, self.elem)

    @property
    def n_bristles(self) -> int:
        return len(self.bstart) - 1

    @property
    def n_bodies(self) -> int:
        return int(self.bstart[-1])


def build_model(brush: BrushConfig, element: str = "mid") -> Model:
    """Flatten a brush config into kernel arrays (eq 1-3 stiffness, eq 11 inertia, damping) for
    the beam element ``element`` ("paper" or "mid", see SimSettings)."""
    nbod = [b.bodies for b in brush.bristles]
    bstart = np.zeros(len(nbod) + 1, np.int64)
    bstart[1:] = np.cumsum(nbod)
    N = int(bstart[-1])
    bp = np.zeros(N, rec.BODY)
    K = np.zeros((N, 6, 6))
    seg = np.zeros(N)
    R_head = brush.head_rotation()
    root_p = np.zeros((len(nbod), 3))
    root_R = np.zeros((len(nbod), 3, 3))
    for j, br in enumerate(brush.bristles):
        sec, mat = br.section, br.material
        n = br.bodies
        l = br.length / n
        A, Iy, Iz, J = sec.area, sec.I_y, sec.I_z, sec.J
        kappa = sec.shear_coeff(mat.nu)
        Kel = timoshenko_stiffness(mat.E, mat.G, A, Iy, Iz, J, kappa, l)
        if element == "mid":
            Kel = mid_frame_stiffness(Kel, l)
        m, Jb = segment_inertia(mat.density, A, Iy, Iz, l)
        Imin = min(Iy, Iz)
        beta = 2.0 * mat.damping_ratio / first_bending_omega(mat.E, Imin, mat.density, A, br.length)
        fscale = mat.E * Imin / br.length**2
        sl = slice(bstart[j], bstart[j + 1])
        K[sl] = Kel
        bp["mass"][sl] = m
        bp["J"][sl] = Jb
        bp["half"][sl] = 0.5 * l
        bp["length"][sl] = l
        bp["beta"][sl] = beta
        bp["fscale"][sl] = fscale
        seg[sl] = l
        root_p[j] = np.asarray(brush.head_offset, float) + R_head @ np.asarray(br.root, float)
        # lean: rotate about the width axis so the tip moves toward the thickness direction
        c, s_ = np.cos(brush.effective_lean), np.sin(brush.effective_lean)
        Ry = np.array([[c, 0.0, -s_], [0.0, 1.0, 0.0], [s_, 0.0, c]])  # x -> (c, 0, +s)
        root_R[j] = R_head @ bristle_frame(br.axis, br.width_dir) @ Ry
    return Model(
        bstart,
        bp,
        K,
        root_p,
        root_R,
        seg,
        np.array([b.tip_radius for b in brush.bristles]),
        np.array([b.length for b in brush.bristles]),
        np.full(N, ELEMENTS[element], np.int64),
    )


@dataclass
class State:
    """Complete dynamic state; ``copy()`` and ``Simulator.set_state`` restore it exactly.

    pos (N,3) [mm] body centres of mass, rot (N,3,3) body->world, vel (N,3) [mm/s],
    omg (N,3) [rad/s] world; p* the same at the previous step (BDF2 history); hist_ok (nb,) how many
    whole steps lie behind the history, 0-2 (0: the next step starts with backward Euler; 2: the
    predictor extrapolates at third order); tcp_p (4,3) [mm] / tcp_R (4,3,3): TCP pose at t_{n-1},
    t_n, t_{n-2} (rows 0, 1, 3; row 2 is scratch); tip_state (nb, ns): per-contact state;
    time [s]; steps; pppos (N,3) [mm] / pprot (N,3,3): body poses at t_{n-2}.
    """

    pos: np.ndarray
    rot: np.ndarray
    vel: np.ndarray
    omg: np.ndarray
    ppos: np.ndarray
    prot: np.ndarray
    pvel: np.ndarray
    pomg: np.ndarray
    hist_ok: np.ndarray
    tcp_p: np.ndarray
    tcp_R: np.ndarray
    tip_state: np.ndarray
    time: float = 0.0
    steps: int = 0
    jac: rec.NewtonCache = None
    pppos: np.ndarray = None
    pprot: np.ndarray = None

    def copy(self, with_jacobian: bool = True) -> State:
        """Deep copy.  ``jac`` (the factored Newton matrices reused across steps) is part of the
        state so that a restored state continues bit for bit like the original."""
        d = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}
        d["jac"] = rec.NewtonCache(*(a.copy() for a in self.jac)) if with_jacobian else self.jac
        return State(**d)


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
    tip_normal_force: np.ndarray = None
    tip_tangential_force: np.ndarray = None
    tip_in_contact: np.ndarray = None
    tip_sliding: np.ndarray = None
    tip_penetration: np.ndarray = None
    tip_contact_point: np.ndarray = None
    extra: dict = field(default_factory=dict)


class Simulator:
    """Discrete flexible multibody brush driven by a prescribed TCP pose (see module docstring)."""

    def __init__(self, scene, settings: SimSettings | None = None):
        if isinstance(scene, BrushConfig):
            scene = Scene(scene)
        self.scene = scene
        brush = scene.brush
        self.brush = brush
        self.settings = settings or SimSettings()
        self.model = build_model(brush, self.settings.element)
        nb = self.model.n_bristles
        self.tip_args = np.zeros(nb, rec.TIP_ARGS)
        self.tip_args["radius"] = self.model.tip_radius
        self.contact_params = scene.contact.as_array()  # Tables 2-3, from the scene
        self.surfaces, grids = _surface_rows(scene.surfaces)
        self.sdf = pack_grids(grids)
        meshes = [srf for srf in scene.surfaces if isinstance(srf, MeshPlate)]
        if len(meshes) > 1:
            raise ConfigError(
                f"scene {scene.name!r}: at most one triangle-mesh surface, got {len(meshes)}"
            )
        self.mesh = build_mesh(*meshes[0].triangles()) if meshes else empty_mesh()
        self.pair_ptr, self.pair_idx = (
            tip_pairs(self.model, scene)
            if scene.tip_tip
            else (np.zeros(nb + 1, np.int64), np.zeros(0, np.int64))
        )
        self._ws = rec.make_work(
            int(np.diff(self.model.bstart).max()),
            self.model.n_bodies,
            nb,
            len(self.pair_idx),
        )
        self._kmodel = self.model.arrays()
        self._tips = np.zeros((nb, 7))
        self._tips[:, 6] = self.model.tip_radius
        self._out = rec.StepOut(
            np.zeros((nb, 6)),
            np.zeros(nb, np.int64),
            np.zeros(nb, np.int64),
            np.zeros(nb, np.int64),
        )
        self._rootw = self._out.rootw
        self.state: State | None = None
        self._snap: State | None = None  # rollback buffers (see _snapshot)
        self._prm = self._make_prm(static=False)
        self._pen_warned = False

    # ------------------------------------------------------------------ set-up
    def _make_prm(self, static: bool) -> rec.StepParams:
        s = self.settings
        return rec.StepParams(
            h=float(s.dt if static else s.dt / s.substeps),
            method=int(INTEGRATORS[s.integrator]),
            static=bool(static),
            rtol=float(s.newton_rtol),
            maxit=int(s.newton_max_iter),
            maxlev=int(s.max_substep_levels),
            g=np.array(s.gravity, dtype=float),
            jage=int(s.jacobian_max_age),
            sweeps=int(s.tip_tip_sweeps),
            tttol=float(s.tip_tip_tol),
        )

    def reset(self, tcp_p=None, tcp_R=None, time: float = 0.0) -> StepResult:
        """Straight, unstressed bristles at rest on a TCP at pose (tcp_p [mm], tcp_R)."""
        tcp_p = np.zeros(3) if tcp_p is None else np.asarray(tcp_p, float)
        tcp_R = np.eye(3) if tcp_R is None else np.asarray(tcp_R, float)
        self._check_pose(tcp_p, tcp_R)
        m = self.model
        N, nb = m.n_bodies, m.n_bristles
        pos = np.zeros((N, 3))
        rot = np.zeros((N, 3, 3))
        for j in range(nb):
            Rw = tcp_R @ m.root_R[j]
            root_w = tcp_p + tcp_R @ m.root_p[j]
            for k, i in enumerate(range(m.bstart[j], m.bstart[j + 1])):
                pos[i] = root_w + (k + 0.5) * m.seg_len[i] * Rw[:, 0]
                rot[i] = Rw
        z = np.zeros((N, 3))
        self.state = State(
            pos,
            rot,
            z.copy(),
            z.copy(),
            pos.copy(),
            rot.copy(),
            z.copy(),
            z.copy(),
            np.zeros(nb, np.int64),
            np.stack([tcp_p] * 4),
            np.stack([tcp_R] * 4),
            _fresh_tip_state(nb),
            time,
            0,
            rec.make_newton_cache(N, nb),
            pos.copy(),
            rot.copy(),
        )
        self._rootw[:] = 0.0
        itg.tip_states(m.bstart, m.bp, pos, rot, z, z, self._tips)
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
        self.tip_args["fext"] = f

    def get_state(self) -> State:
        return self.state.copy()

    def set_state(self, state: State) -> None:
        self.state = state.copy()
        st, m = self.state, self.model
        itg.tip_states(m.bstart, m.bp, st.pos, st.rot, st.vel, st.omg, self._tips)

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
        n = self.settings.substeps
        if n == 1:
            return self._result(*self._advance(tcp_p, tcp_R, self._prm, st.time + self.settings.dt))
        return self._advance_split(tcp_p, tcp_R, n)

    def _advance_split(self, tcp_p, tcp_R, n: int) -> StepResult:
        """``step`` as n equal internal steps (settings.max_substep), the TCP pose interpolated
        as the kernels interpolate within a step (linear position, geodesic rotation).  A
        divergence in any of them restores the state of the start of the whole step."""
        st = self.state
        t0, h = st.time, self.settings.dt / n
        p0, R0 = st.tcp_p[1].copy(), st.tcp_R[1].copy()
        w = logmap(tcp_R @ R0.T)  # world-frame rotation vector from R0 to tcp_R
        start = self._snapshot(st)  # the rollback target of every internal step
        iters = nsub = 0
        for k in range(1, n + 1):
            s = k / n
            p = tcp_p if k == n else (1.0 - s) * p0 + s * tcp_p
            R = tcp_R if k == n else expmap(s * w) @ R0
            it, ns = self._advance(p, R, self._prm, t0 + k * h, start)
            iters += it
            nsub += ns
        st.time = t0 + self.settings.dt  # no round-off drift of the step grid
        st.steps = start.steps + 1  # steps counts calls of step, not internal steps
        return self._result(iters, nsub)

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
        prm = self._make_prm(static=True)
        prm = prm._replace(maxlev=0)
        full = self.tip_args.copy()
        try:
            for k in range(1, increments + 1):
                # every field scaled, the tip radius too (kept as it was: bit-identical results)
                for name in rec.TIP_ARGS.names:
                    self.tip_args[name] = full[name] * (k / increments)
                counts = self._advance(tcp_p, tcp_R, prm, st.time)
        finally:
            self.tip_args[:] = full
        self.state.hist_ok[:] = 0
        return self._result(*counts)

    def _advance(self, tcp_p, tcp_R, prm, t_new, snapshot=None) -> tuple[int, int]:
        """One (internal) step as named stages: base motion -> per-bristle implicit solve
        (contact search, beam, contact, friction, tip-tip inside Newton) -> acceptance or
        rollback -> the penetration check; returns (Newton iterations, sub-steps) of all
        bristles (``_result`` builds the outputs once per ``step``).  ``snapshot``: the state a
        divergence restores (default: this step's start; a split step passes its own start)."""
        if snapshot is None:
            snapshot = self._snapshot(self.state)  # rollback target
        self._base_motion(tcp_p, tcp_R)
        self._solve_bristles(prm)
        self._accept_or_rollback(snapshot, prm, t_new)
        self._shift_drive(tcp_p, tcp_R, t_new)
        out = self._out
        if not self._pen_warned:
            self._warn_penetration(self._penetration())
        return int(out.iters.sum()), int(out.nsub.sum())

    def _base_motion(self, tcp_p, tcp_R) -> None:
        """Stage 1: the prescribed TCP pose at t + dt (row 2 of the drive); the kernels
        interpolate it over sub-steps (linear position, geodesic rotation)."""
        st = self.state
        st.tcp_p[2] = tcp_p
        st.tcp_R[2] = tcp_R

    def _solve_bristles(self, prm) -> None:
        """Stage 2: every bristle's implicit step (step.step_bristles): per bristle, the
        momentum balance (eq 11) with the beam elements (eq 1-5), the tip's contact search over
        the surfaces and its pre-searched tip-tip partners (§2.2, ``tip_pairs``), the normal law
        (eq 6), friction (eq 7-10) and tip-tip contact (Table 3), solved by Newton."""
        st = self.state
        chain = rec.Chain(
            st.pos, st.rot, st.vel, st.omg, st.ppos, st.prot, st.pvel, st.pomg, st.pppos, st.pprot
        )
        drive = rec.Drive(st.hist_ok, st.tcp_p, st.tcp_R)
        itg.step_bristles(
            self._kmodel, chain, drive, prm, self._contact(), st.jac, self._ws, self._out
        )

    def _accept_or_rollback(self, snapshot, prm, t_new) -> None:
        """Stage 3: a bristle that failed on its smallest sub-step, or a non-finite state,
        restores the whole state and raises ``SimulationDivergence`` (never NaN)."""
        st, m = self.state, self.model
        bad = np.flatnonzero(self._out.status)
        if bad.size == 0 and not (itg.all_finite(st.pos) and itg.all_finite(self._rootw)):
            bad = np.arange(m.n_bristles)
        if bad.size:
            self.set_state(snapshot)
            # the failed attempt refactored Newton matrices at its own (rejected) iterates: mark
            # them all stale, so that what follows depends on the restored state alone
            self.state.jac.key[:] = 0.0
            raise SimulationDivergence(
                t_new,
                bad,
                f"Newton did not converge on the smallest sub-step (dt / 2**{prm.maxlev})",
            )

    def _shift_drive(self, tcp_p, tcp_R, t_new) -> None:
        """Stage 4: the TCP history moves on (t_{n-2} <- t_{n-1} <- t_n <- t_{n+1}), time too."""
        st = self.state
        st.tcp_p[3] = st.tcp_p[0]
        st.tcp_R[3] = st.tcp_R[0]
        st.tcp_p[0] = st.tcp_p[1]
        st.tcp_R[0] = st.tcp_R[1]
        st.tcp_p[1] = tcp_p
        st.tcp_R[1] = tcp_R
        st.time = t_new
        st.steps += 1

    def _snapshot(self, st: State) -> State:
        """Copy of ``st`` into buffers kept across steps (no allocation per step).  The Newton
        factors are shared, not copied: they are only a cache, and a failed step marks them all
        stale (``_advance``)."""
        snap = self._snap
        if snap is None:
            snap = self._snap = st.copy(with_jacobian=False)
        else:
            for name in _STATE_ARRAYS:
                np.copyto(getattr(snap, name), getattr(st, name))
            snap.time, snap.steps, snap.jac = st.time, st.steps, st.jac
        return snap

    def _contact(self) -> rec.ContactScene:
        """The kernels' view of the contact scene and the per-tip state."""
        return rec.ContactScene(
            self.surfaces,
            self.contact_params,
            self._tips,
            self.pair_ptr,
            self.pair_idx,
            self.mesh,
            self.tip_args,
            self.state.tip_state,
            self.sdf,
        )

    def touch_height(self, tcp_R=None, plate_z: float = 0.0) -> float:
        """TCP height z [mm] at which the lowest tip sphere of the unloaded brush just touches the
        horizontal plate z = ``plate_z`` [mm], with the TCP orientation ``tcp_R`` (default the
        brush pointing down, diag(1, -1, -1)).  Reset there (or higher) so that the first step
        does not start with the tips inside the plate."""
        R = np.diag([1.0, -1.0, -1.0]) if tcp_R is None else np.asarray(tcp_R, float)
        m = self.model
        tips_tcp = m.root_p + m.length[:, None] * m.root_R[:, :, 0]
        return float(plate_z - np.min((tips_tcp @ R.T)[:, 2] - m.tip_radius))

    @property
    def n_tip_pairs(self) -> int:
        """Number of tip-tip pairs kept for this scene (each counted once)."""
        return len(self.pair_idx) // 2

    # ------------------------------------------------------------------ outputs
    def tip_positions(self) -> np.ndarray:
        """Tip node (sphere centre) of every bristle [mm, world], (nb, 3)."""
        return self._tip_states()[:, 0:3]

    def tip_velocities(self) -> np.ndarray:
        """Tip node velocity of every bristle [mm/s, world], (nb, 3)."""
        return self._tip_states()[:, 3:6]

    def _tip_states(self) -> np.ndarray:
        st, m = self.state, self.model
        out = np.empty((m.n_bristles, 6))
        itg.tip_states(m.bstart, m.bp, st.pos, st.rot, st.vel, st.omg, out)
        return out

    def _penetration(self) -> np.ndarray:
        """(nb,) [mm] each tip's penetration, 0 where it does not touch."""
        ts = self.state.tip_state
        return np.maximum(ts["pen"], 0.0) * (ts["fn"] > 0.0)

    def _warn_penetration(self, pen: np.ndarray) -> None:
        """Once per simulator: the deepest tip beyond PENETRATION_WARN_FRACTION of its radius."""
        excess = pen / self.model.tip_radius
        b = int(np.argmax(excess))
        if excess[b] > PENETRATION_WARN_FRACTION:
            self._pen_warned = True
            warnings.warn(
                f"t = {self.state.time:.6g} s: tip of bristle {b} penetrates "
                f"{1e3 * pen[b]:.1f} um = {100 * excess[b]:.0f} % of its radius "
                f"({self.model.tip_radius[b]:g} mm), beyond the "
                f"{100 * PENETRATION_WARN_FRACTION:.0f} % the penalty law (eq 6) is meant for: "
                "contact forces there are not reliable (stiffer material or deeper press than "
                "the scene's contact parameters were fitted for); warned once per simulator",
                PenetrationWarning,
                stacklevel=_caller_level(),
            )

    def _result(self, iters: int, nsub: int) -> StepResult:
        st = self.state
        R_tcp = st.tcp_R[1]
        w = np.empty(6)
        itg.tcp_wrench(R_tcp, self.model.root_p, self._rootw, w)
        F, M = w[0:3], w[3:6]
        ts = st.tip_state
        fn = ts["fn"].copy()
        tips = self._tips[:, 0:6].copy()  # step_bristles / tip_states keep them current
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
            fn,
            ts["ft"].copy(),
            fn > 0.0,
            (ts["slide"] > 0) & (fn > 0.0),
            self._penetration(),
            ts["cpt"].copy(),
            extra={
                "tip_tip_force": ts["ftt"].copy(),
                # index of the surface each tip touches deepest (-1: none; Scene.surfaces order)
                "tip_surface": np.where(fn > 0.0, ts["surf"], -1),
                # sweeps and bristle re-solves of the (last internal) step, and whether its
                # tip-tip partners settled within tip_tip_tol before the sweeps ran out
                "sweeps": int(self._ws.sw.count[0]),
                "resolves": int(self._ws.sw.count[1]),
                "tip_tip_settled": bool(self._ws.sw.count[2] == 0),
                "tip_tip_fallback": bool(self._ws.sw.count[2] == 2),
            },
        )


#: the array fields of State (copied by Simulator._snapshot)
_STATE_ARRAYS = (
    "pos",
    "rot",
    "vel",
    "omg",
    "ppos",
    "prot",
    "pvel",
    "pomg",
    "pppos",
    "pprot",
    "hist_ok",
    "tcp_p",
    "tcp_R",
    "tip_state",
)


def _fresh_tip_state(nb: int) -> np.ndarray:
    """Tip states of untouched tips: zeros, no surface (surf = -1)."""
    ts = np.zeros(nb, rec.TIP_STATE)
    ts["surf"] = -1
    return ts


def _surface_rows(surfaces) -> tuple[np.ndarray, list]:
    """The scene's surfaces as kernel records (``records.SURFACE``), and the baked SDF grids that
    records of kind SURF_GRID index (in their order)."""
    rows = np.zeros(len(surfaces), rec.SURFACE)
    grids = []
    for j, srf in enumerate(surfaces):
        if hasattr(srf, "sdf_grid"):
            rows[j] = rec.surface_row(rec.SURF_GRID, grid=len(grids))
            grids.append(srf.sdf_grid())
        else:
            rows[j] = srf.kernel_row()
    return rows, grids


def tip_pairs(model: Model, scene, travel_fraction: float | None = None):
    """Tip-tip pairs the scene can bring together, as CSR lists (each pair listed for both tips).

    Two tips can touch only if their roots are closer than the sum of the tips' largest travels
    plus the two sphere radii.  A tip's travel is bounded by its bristle length (it swings about
    its root), times ``scene.tip_travel_fraction`` (default 0.6: a bristle pressed onto a plate
    and dragged leans over but does not fold back, so its tip stays within ~0.6 L of the root
    line; documented choice, checked against the full pair set in tests).
    """
    frac = (
        getattr(scene, "tip_travel_fraction", 0.6) if travel_fraction is None else travel_fraction
    )
    nb = model.n_bristles
    roots = model.root_p
    reach = frac * model.length + model.tip_radius
    d = np.linalg.norm(roots[:, None, :] - roots[None, :, :], axis=2)
    ok = (d <= reach[:, None] + reach[None, :]) & ~np.eye(nb, dtype=bool)
    ptr = np.zeros(nb + 1, np.int64)
    ptr[1:] = np.cumsum(ok.sum(axis=1))
    idx = np.nonzero(ok)[1].astype(np.int64)
    return ptr, idx
