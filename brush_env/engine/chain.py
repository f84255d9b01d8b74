"""The full discrete flexible multibody bristle model behind the seam (``bristles.py``): every
bristle a chain of rigid bodies (eq 11) joined by Timoshenko beam elements (eq 1-5, the paper's
element or the mid-frame one), its tip sphere in penalty contact with the surfaces (eq 6) with
stick-slip friction (eq 7-10) and with neighbouring tips (Table 3), integrated implicitly per
bristle (``step.step_bristles``).  Registered as bristle model ``"dfm"``; the fidelity
levels reference, paper and balanced use it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from . import chain_rollout as cro  # many steps along prescribed poses in one call
from . import records as rec
from . import shaft as shf  # shaft contact of the bodies' capsules and the head's clearance
from . import step as itg  # the integrator's stages, in order (step.step_bristles)
from ._kernels import ELEMENTS
from .beam import (
    bristle_frame,
    first_bending_omega,
    mid_frame_stiffness,
    segment_inertia,
    timoshenko_stiffness,
)
from .bristles import BristleModel, ShaftContact, TipContact, register_bristle_model
from .checks import ConfigError
from .config import BrushConfig
from .mesh_contact import build_mesh, empty_mesh
from .near import NEAR_MARGIN  # the step's near lists of tip-tip partners
from .scene import MeshPlate
from .sdf import pack_grids
from .settings import INTEGRATORS, SimSettings, SimulationDivergence


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
    time [s]; steps; pppos (N,3) [mm] / pprot (N,3,3): body poses at t_{n-2}; shaft (N,) the
    bodies' shaft contacts (``records.SHAFT``; empty when the scene's shaft contact is off).
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
    shaft: np.ndarray = None

    def copy(self, with_jacobian: bool = True) -> State:
        """Deep copy.  ``jac`` (the factored Newton matrices reused across steps) is part of the
        state so that a restored state continues bit for bit like the original."""
        d = {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in self.__dict__.items()}
        d["jac"] = rec.NewtonCache(*(a.copy() for a in self.jac)) if with_jacobian else self.jac
        return State(**d)


class DFMChain(BristleModel):
    """The full DFM chain of every bristle of ``scene`` under ``settings`` (module docstring)."""

    def __init__(self, scene, settings: SimSettings):
        self.settings = settings
        self.model = build_model(scene.brush, settings.element)
        nb = self.model.n_bristles
        self.tip_args = np.zeros(nb, rec.TIP_ARGS)
        self.tip_args["radius"] = self.model.tip_radius
        self.contact_params = scene.contact.as_array()  # Tables 2-3, from the scene
        self.surfaces, self.sdf, self.mesh = scene_surfaces(scene)
        self.pair_ptr, self.pair_idx = scene_tip_pairs(self.model, scene)
        self._ws = rec.make_work(
            int(np.diff(self.model.bstart).max()),
            self.model.n_bodies,
            nb,
            len(self.pair_idx),
            NEAR_MARGIN,
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
        self.root_wrench = self._out.rootw
        self.shaft_contact_on = bool(getattr(scene, "shaft_contact", False)) and bool(
            len(self.surfaces)
        )
        self._shaft0 = _shaft_capsules(scene.brush, self.model) if self.shaft_contact_on else None
        self._g23 = np.zeros((3, 3))
        self._head = (
            head_outline(scene.brush, self.model)
            if getattr(scene, "head_contact", False) and len(self.surfaces)
            else None
        )
        self.state: State | None = None
        self._snap: State | None = None  # rollback buffers (see snapshot)
        self._prm = self._make_prm(static=False)
        # one sweep and the coupled solve are two kernels: a run compiles only the one it uses
        self._step_kernel = (
            itg.step_bristles_coupled if self.settings.tip_tip_sweeps > 1 else itg.step_bristles
        )
        self._follow_kernel = (
            cro.follow_coupled if self.settings.tip_tip_sweeps > 1 else cro.follow_one_sweep
        )
        self._follow_snap: tuple | None = None  # follow's rollback buffers (_follow_views)

    def _make_prm(self, static: bool) -> rec.StepParams:
        """The kernels' step parameters (``records.StepParams``) from the settings: ``h`` the
        solver step (dt / substeps), ``maxlev`` = max_halvings."""
        s = self.settings
        return rec.StepParams(
            h=float(s.dt if static else s.dt / s.substeps),
            method=int(INTEGRATORS[s.integrator]),
            static=bool(static),
            rtol=float(s.newton_rtol),
            maxit=int(s.newton_max_iter),
            maxlev=int(s.max_halvings),
            g=np.array(s.gravity, dtype=float),
            jage=int(s.jacobian_max_age),
            sweeps=int(s.tip_tip_sweeps),
            tttol=float(s.tip_tip_tol),
        )

    @property
    def tips(self) -> np.ndarray:
        """(nb, 6) tip node position [mm] and velocity [mm/s], world (kept current by the
        kernels)."""
        return self._tips[:, 0:6]

    def tip_states(self) -> np.ndarray:
        """(nb, 6) tip node position and velocity computed from the current state."""
        st, m = self.state, self.model
        out = np.empty((m.n_bristles, 6))
        itg.tip_states(m.bstart, m.bp, st.pos, st.rot, st.vel, st.omg, out)
        return out

    def reset(self, tcp_p, tcp_R, time: float) -> None:
        """Straight, unstressed bristles at rest on a TCP at pose (tcp_p [mm], tcp_R)."""
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
            fresh_tip_state(nb),
            time,
            0,
            rec.make_newton_cache(N, nb),
            pos.copy(),
            rot.copy(),
            self._shaft0.copy() if self._shaft0 is not None else np.zeros(0, rec.SHAFT),
        )
        self.root_wrench[:] = 0.0
        itg.tip_states(m.bstart, m.bp, pos, rot, z, z, self._tips)

    def set_tip_forces(self, forces) -> None:
        self.tip_args["fext"] = forces

    @property
    def tip_forces(self) -> np.ndarray:
        return self.tip_args["fext"]

    def set_state(self, state: State) -> None:
        self.state = state.copy()
        st, m = self.state, self.model
        itg.tip_states(m.bstart, m.bp, st.pos, st.rot, st.vel, st.omg, self._tips)

    def solve_static(self, tcp_p, tcp_R) -> tuple[int, int]:
        """Static equilibrium at the TCP pose under the current tip loads (no halving)."""
        prm = self._make_prm(static=True)._replace(maxlev=0)
        counts = self._advance(tcp_p, tcp_R, prm, self.state.time, None)
        self.state.hist_ok[:] = 0
        return counts

    def advance(self, tcp_p, tcp_R, t_new, rollback=None) -> tuple[int, int]:
        return self._advance(tcp_p, tcp_R, self._prm, t_new, rollback)

    def _advance(self, tcp_p, tcp_R, prm, t_new, snapshot) -> tuple[int, int]:
        """One (internal) step as named stages: base motion -> per-bristle implicit solve
        (contact search, beam, contact, friction, tip-tip inside Newton) -> acceptance or
        rollback -> the drive moves on; returns (Newton iterations, sub-steps) of all bristles.
        ``snapshot``: the state a divergence restores (None: this step's start)."""
        if snapshot is None:
            snapshot = self.snapshot()  # rollback target
        self._base_motion(tcp_p, tcp_R)
        self._solve_bristles(prm)
        self._accept_or_rollback(snapshot, prm, t_new)
        self._shift_drive(tcp_p, tcp_R, t_new)
        out = self._out
        return int(out.iters.sum()), int(out.nsub.sum())

    def follow(self, P, R, limits, record, keep) -> tuple[int, int, SimulationDivergence | None]:
        """Engine steps in one compiled call (``chain_rollout``: the stages of ``_advance`` per
        solver step, with no Python between steps), the TCP at pose (P[i] [mm], R[i]) at the end
        of solver step i (``settings.substeps`` per engine step, ``Simulator._split_poses``); row
        k of ``record`` (``chain_rollout.FollowRecord``) holds engine step k's outputs.  limits,
        keep: ``FollowRun.limits``, ``FollowRun.keep``.  Returns (steps done,
        ``records.STOP_*``); after a divergence the state is that of the failed engine step's
        start, as ``_accept_or_rollback`` leaves it, and the third value its
        ``SimulationDivergence`` (else None)."""
        st, s = self.state, self.settings
        live, snap = self._follow_views()
        head = self._head if self._head is not None else np.zeros((0, 3))
        if P.shape[0] != s.substeps * record.t.shape[0]:
            raise ValueError(
                f"{P.shape[0]} poses for {record.t.shape[0]} steps of {s.substeps} solver steps"
            )
        run = cro.FollowRun(
            P,
            R,
            s.substeps,
            np.array([st.time, s.dt]),
            live,
            snap,
            self.shaft_contact_on,
            self._g23,
            head,
            np.zeros_like(head),
            limits,
            keep,
        )
        chain = rec.Chain(
            st.pos, st.rot, st.vel, st.omg, st.ppos, st.prot, st.pvel, st.pomg, st.pppos, st.pprot
        )
        drive = rec.Drive(st.hist_ok, st.tcp_p, st.tcp_R)
        done, stop, i = self._follow_kernel(
            self._kmodel, chain, drive, self._prm, self._contact(), st.jac, self._ws, self._out,
            run, record,
        )  # fmt: skip
        st.time = float(run.clock[0])
        st.steps += int(done)
        err = None
        if stop == rec.STOP_DIVERGENCE:  # at the end of solver step i % substeps + 1 of the step
            err = self._divergence(st.time + (i % s.substeps + 1) * (s.dt / s.substeps), self._prm)
        return int(done), int(stop), err

    def _follow_views(self) -> tuple[tuple, tuple]:
        """The state's arrays (``snapshot``'s: _STATE_ARRAYS, tip_state, shaft; and the root
        wrenches) as flat float64 views, and buffers of their shapes for the rollback copy (kept
        across calls).  Every field of TIP_STATE and SHAFT is 8 bytes wide, so the bytes copy as
        float64."""
        st = self.state
        # and the root wrenches: after a divergence they are the last accepted step's (a failed
        # step has written those of the bristles it solved)
        arrays = [getattr(st, name) for name in _STATE_ARRAYS] + [
            st.tip_state,
            st.shaft,
            self.root_wrench,
        ]
        live = []
        for a in arrays:
            if not a.flags.c_contiguous or a.dtype.itemsize % 8:
                raise RuntimeError("state arrays must be C-contiguous with 8-byte fields")
            live.append(a.view(np.float64).reshape(-1))
        live = tuple(live)
        snap = self._follow_snap
        if snap is None or any(x.shape != y.shape for x, y in zip(snap, live, strict=True)):
            snap = self._follow_snap = tuple(np.empty_like(v) for v in live)
        return live, snap

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
        con = self._contact()
        if self.shaft_contact_on:  # which bristles' capsules can reach a surface this step
            shf.broad_phase(
                self.model.bstart, self.model.root_p, chain, drive, con, prm.h, self._g23
            )
        self._step_kernel(self._kmodel, chain, drive, prm, con, st.jac, self._ws, self._out)

    def _accept_or_rollback(self, snapshot, prm, t_new) -> None:
        """Stage 3: a bristle that failed on the smallest halving of its step, or a non-finite
        state, restores the whole state and raises ``SimulationDivergence`` (never NaN)."""
        st = self.state
        if self._out.status.any() or not (
            itg.all_finite(st.pos) and itg.all_finite(self.root_wrench)
        ):
            self.set_state(snapshot)
            # the failed attempt refactored Newton matrices at its own (rejected) iterates: mark
            # them all stale, so that what follows depends on the restored state alone
            self.state.jac.key[:] = 0.0
            raise self._divergence(t_new, prm)

    def _divergence(self, t_new, prm) -> SimulationDivergence:
        """The error of a failed step ending at t_new [s]: the bristles that failed on the
        smallest halving (all of them when the state is not finite)."""
        bad = np.flatnonzero(self._out.status)
        return SimulationDivergence(
            t_new,
            bad if bad.size else np.arange(self.model.n_bristles),
            "Newton did not converge on the smallest "
            f"halving of the solver step (h / 2**{prm.maxlev}, max_halvings)",
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

    def snapshot(self) -> State:
        """Copy of the state into buffers kept across steps (no allocation per step).  The
        Newton factors are shared, not copied: they are only a cache, and a failed step marks
        them all stale (``_accept_or_rollback``)."""
        st, snap = self.state, self._snap
        if snap is None:
            snap = self._snap = st.copy(with_jacobian=False)
        else:
            for name in _STATE_ARRAYS:
                np.copyto(getattr(snap, name), getattr(st, name))
            # the tip states (structured, records.TIP_STATE) as their bytes: numpy copies a
            # structured array field by field through its casting machinery, ~7 us a step on
            # flat_plate (~1.5 % of the step loop's instructions), a byte copy ~1 us
            np.copyto(snap.tip_state.view(np.uint8), st.tip_state.view(np.uint8))
            np.copyto(snap.shaft.view(np.uint8), st.shaft.view(np.uint8))  # records.SHAFT
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
            self.state.shaft,
        )

    def contact(self) -> TipContact:
        return tip_contact(self.state.tip_state)

    def tip_penetration(self) -> np.ndarray:
        return tip_penetration(self.state.tip_state)

    def shaft_contact(self) -> ShaftContact | None:
        """Per-body shaft contact of the last solver step (None when the scene's is off)."""
        sh = self.state.shaft
        if not self.shaft_contact_on or sh is None or sh.size == 0:
            return None
        fn = sh["fn"].copy()
        touching = fn > 0.0
        return ShaftContact(
            fn,
            sh["ft"].copy(),
            np.maximum(sh["pen"], 0.0) * touching,
            sh["cpt"].copy(),
            np.where(touching, sh["surf"], -1).astype(np.int64),
        )

    def shaft_penetration_max(self) -> float:
        """The deepest shaft penetration [mm] of the last solver step (0 when off): the
        per-solver-step peak, without building a ``ShaftContact``."""
        sh = self.state.shaft
        if not self.shaft_contact_on or sh is None or sh.size == 0:
            return 0.0
        return float(np.max(np.maximum(sh["pen"], 0.0) * (sh["fn"] > 0.0)))

    def head_clearance(self) -> float | None:
        """Smallest signed distance [mm] of the head's outline (``head_outline``) to the
        surfaces at the current TCP pose (< 0: inside); None when the scene's head contact is
        off."""
        if self._head is None:
            return None
        st = self.state
        pts = st.tcp_p[1] + self._head @ st.tcp_R[1].T
        g = self._g23
        return float(shf.clearance(self.surfaces, self.mesh, self.sdf, pts, g[0], g[1]))

    def solver_info(self) -> dict:
        count = self._ws.sw.count
        return {
            # sweeps and bristle re-solves of the (last internal) step, and whether its
            # tip-tip partners settled within tip_tip_tol before the sweeps ran out
            "sweeps": int(count[0]),
            "resolves": int(count[1]),
            "tip_tip_settled": bool(count[2] == 0),
            "tip_tip_fallback": bool(count[2] == 2),
        }

    @property
    def n_tip_pairs(self) -> int:
        """Number of tip-tip pairs kept for this scene (each counted once)."""
        return len(self.pair_idx) // 2


register_bristle_model("dfm", DFMChain)


#: the unstructured array fields of State (copied by DFMChain.snapshot; tip_state as bytes)
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
)


#: the head's outline reaches this far beyond its outermost roots [mm] (a rigid head plate around
#: the tufts; docs/model.md)
HEAD_MARGIN = 1.0
#: points per side of the grid that samples the head's outline rectangle (its corners and edges
#: hold the smallest clearance to a plane; the grid covers curved surfaces)
HEAD_GRID = 5


def head_outline(brush: BrushConfig, model: Model) -> np.ndarray:
    """(HEAD_GRID**2, 3) points [mm, TCP frame] of the head: the rectangle bounding the roots
    in the head plane (normal: the head's z), HEAD_MARGIN wider on every side, in the plane of
    the roots, sampled on a HEAD_GRID x HEAD_GRID grid."""
    n = brush.head_rotation() @ np.array([0.0, 0.0, 1.0])
    e1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    roots = model.root_p
    o = roots.mean(axis=0)
    a = (roots - o) @ e1
    b = (roots - o) @ e2
    h = float(np.mean((roots - o) @ n))
    ga = np.linspace(a.min() - HEAD_MARGIN, a.max() + HEAD_MARGIN, HEAD_GRID)
    gb = np.linspace(b.min() - HEAD_MARGIN, b.max() + HEAD_MARGIN, HEAD_GRID)
    A, B = np.meshgrid(ga, gb, indexing="ij")
    return o + h * n + A.reshape(-1, 1) * e1 + B.reshape(-1, 1) * e2


def _shaft_capsules(brush: BrushConfig, model: Model) -> np.ndarray:
    """Every body's capsule (``records.SHAFT``: radius = half the section's smaller side, axis
    from lo to hi about the centre [mm]; the tip body's stops a tip radius short of the tip node)
    and a fresh contact state."""
    sh = np.zeros(model.n_bodies, rec.SHAFT)
    sh["surf"] = -1
    sh["pen"] = shf.NOT_EVALUATED
    for j, br in enumerate(brush.bristles):
        i0, i1 = model.bstart[j], model.bstart[j + 1]
        seg = model.seg_len[i0:i1]
        # distance along the chain from each body's centre to the tip node
        after = np.concatenate([np.cumsum(seg[::-1])[::-1][1:], [0.0]])
        sh["radius"][i0:i1] = 0.5 * min(br.section.width, br.section.thickness)
        sh["lo"][i0:i1] = -0.5 * seg
        sh["hi"][i0:i1] = np.minimum(0.5 * seg, 0.5 * seg + after - model.tip_radius[j])
    return sh


def scene_surfaces(scene) -> tuple[np.ndarray, object, object]:
    """The kernels' view of a scene's surfaces: their records (``surface_rows``), the packed SDF
    grids and the triangle mesh (at most one; an empty one without)."""
    surfaces, grids = surface_rows(scene.surfaces)
    meshes = [srf for srf in scene.surfaces if isinstance(srf, MeshPlate)]
    if len(meshes) > 1:
        raise ConfigError(
            f"scene {scene.name!r}: at most one triangle-mesh surface, got {len(meshes)}"
        )
    mesh = build_mesh(*meshes[0].triangles()) if meshes else empty_mesh()
    return surfaces, pack_grids(grids), mesh


def scene_tip_pairs(model, scene) -> tuple[np.ndarray, np.ndarray]:
    """``tip_pairs`` of the model if the scene has tip-tip contact on, else no pairs."""
    if scene.tip_tip:
        return tip_pairs(model, scene)
    return np.zeros(model.n_bristles + 1, np.int64), np.zeros(0, np.int64)


def tip_contact(ts: np.ndarray) -> TipContact:
    """The seam's ``TipContact`` of the tips' contact states (``records.TIP_STATE``), copied (one
    compiled pass, ``_contact_arrays``: every env step reads it)."""
    return TipContact(*_contact_arrays(ts))


@njit(cache=True, fastmath=False)
def _contact_arrays(ts):
    """``TipContact``'s arrays of the tip states ts: normal force [N], friction (nb, 3) [N],
    sliding, penetration [mm] (0 off contact), contact point (nb, 3) [mm], tip-tip force [N] and
    the surface touched (-1: none)."""
    nb = ts.shape[0]
    fn = np.empty(nb)
    ft = np.empty((nb, 3))
    sliding = np.empty(nb, np.bool_)
    pen = np.empty(nb)
    cpt = np.empty((nb, 3))
    ftt = np.empty(nb)
    surf = np.empty(nb, np.int64)
    for i in range(nb):
        st = ts[i]
        touching = st.fn > 0.0
        fn[i] = st.fn
        for a in range(3):
            ft[i, a] = st.ft[a]
            cpt[i, a] = st.cpt[a]
        sliding[i] = st.slide > 0 and touching
        pen[i] = max(st.pen, 0.0) if touching else 0.0
        ftt[i] = st.ftt
        surf[i] = st.surf if touching else -1
    return fn, ft, sliding, pen, cpt, ftt, surf


def tip_penetration(ts: np.ndarray) -> np.ndarray:
    """(nb,) [mm] each tip's penetration of its last evaluation (0 where it does not touch)."""
    return np.maximum(ts["pen"], 0.0) * (ts["fn"] > 0.0)


def fresh_tip_state(nb: int) -> np.ndarray:
    """Tip states of untouched tips: zeros, no surface (surf = -1)."""
    ts = np.zeros(nb, rec.TIP_STATE)
    ts["surf"] = -1
    return ts


def surface_rows(surfaces) -> tuple[np.ndarray, list]:
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
