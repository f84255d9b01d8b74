"""The reduced bristle model behind the seam (``bristles.py``), registered as ``"prb"``: every
bristle a quasi-static pseudo-rigid-body chain (a clamped stub and two links on bending joints,
``prb_kernels.py``) whose joint springs are calibrated against the continuum rod
(``prb_calibration.py``), with the full model's tip contact: every surface kind with eq 6, the
stick-slip friction of eq 7-10 and the tip-tip law of Table 3 (``contact.tip_load``).  The
fidelity level ``reduced`` uses it (``configs/fidelity/reduced.toml``); the level ``fast``, what a
policy trains on, steps its touching bristles by the tabulated tip law (``TableBristles`` below).

What it leaves out, and why that is what a 25 Hz policy needs (docs/model.md, "The reduced
model"): the bristles' own inertia and their ~100 Hz bending modes (the tip is in equilibrium in
every solver step, with the elements' stiffness-proportional damping), axial and shear
compliance (in the calibration instead), torsion, and the shafts' contact with the surfaces
(the tip sphere alone touches; the head's clearance is reported as for the full model).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from numba import njit

from . import prb_kernels as K
from . import prb_rollout as R_
from . import records as rec
from . import records as rec_
from . import shaft as shf
from . import tip_table
from .bristles import BristleModel, TipContact, register_bristle_model
from .chain import (
    fresh_tip_state,
    head_outline,
    scene_surfaces,
    scene_tip_pairs,
    tip_contact,
    tip_penetration,
)
from .checks import ConfigError
from .config import BrushConfig
from .entry import entry_point
from .prb_calibration import joint_parameters
from .settings import SimSettings, SimulationDivergence
from .simulator import PENETRATION_WARN_FRACTION

#: Newton's tolerance on the joint angles [rad] (a tip error of ~1e-7 mm on a 10 mm bristle; the
#: residual's, this times the stiffest joint [N mm])
ANGLE_TOL = 1e-8
#: Newton iterations per bristle and solver step before the step is refused
MAX_ITER = 30


@dataclass
class PRBGeometry:
    """The brush as the reduced model holds it (the seam's ``model``): two bodies (the links) per
    bristle, ``bstart`` (nb+1,), roots ``root_p`` (nb, 3) [mm] and frames ``root_R`` (nb, 3, 3) in
    the TCP frame, ``length`` (nb,) [mm], ``tip_radius`` (nb,) [mm], ``seg_len`` (2 nb,) [mm] the
    links' lengths, ``prm`` (nb,) ``prb_kernels.JOINT`` the joints (s0, l1, l2 [mm], k_a1, k_b1,
    k_a2, k_b2, k_t [N mm/rad], beta [s], c3 [1/rad^2]: the bending springs' torque is
    k (e + c3 e^3), e = q - q_rest; q_rest (5,) [rad] the rest angles:
    ``prb_calibration.rest_angles``)."""

    bstart: np.ndarray
    root_p: np.ndarray
    root_R: np.ndarray
    length: np.ndarray
    tip_radius: np.ndarray
    seg_len: np.ndarray
    prm: np.ndarray

    @property
    def n_bristles(self) -> int:
        return len(self.bstart) - 1

    @property
    def n_bodies(self) -> int:
        return int(self.bstart[-1])


@dataclass
class PRBState:
    """The reduced model's complete state; ``copy()`` and ``set_state`` restore it exactly.

    q (nb, 5) [rad] joint angles (a1, b1, a2, b2, twist), qp (nb, 5) those of one solver step
    before; tips (nb, 7) tip
    node [mm], velocity [mm/s], radius [mm];
    tip_state (nb,) ``records.TIP_STATE``; pos (2 nb, 3) [mm] / rot (2 nb, 3, 3) the links as
    bodies (derived, for drawing); tcp_p (4, 3) / tcp_R (4, 3, 3) the drive (row 1 now, row 0 one
    solver step before); time [s]; steps."""

    q: np.ndarray
    qp: np.ndarray
    tips: np.ndarray
    tip_state: np.ndarray
    pos: np.ndarray
    rot: np.ndarray
    tcp_p: np.ndarray
    tcp_R: np.ndarray
    time: float = 0.0
    steps: int = 0

    def copy(self) -> PRBState:
        return PRBState(
            self.q.copy(),
            self.qp.copy(),
            self.tips.copy(),
            self.tip_state.copy(),
            self.pos.copy(),
            self.rot.copy(),
            self.tcp_p.copy(),
            self.tcp_R.copy(),
            self.time,
            self.steps,
        )


def build_geometry(brush: BrushConfig) -> PRBGeometry:
    """The reduced model of ``brush``: roots and frames as the full chain's (``chain.build_model``,
    lean included), joints from the calibration of each bristle type."""
    from .chain import build_model  # the roots, frames and lengths exactly as the full model's

    full = build_model(brush.with_bodies(1))
    nb = full.n_bristles
    prm = np.zeros(nb, K.JOINT)
    lean = float(brush.effective_lean)
    for j, br in enumerate(brush.bristles):
        v = joint_parameters(br, lean)
        prm[j] = (v[0:3], v[3:8], v[8], v[9:13], v[13:18])
    seg = np.stack([prm["geo"][:, 1], prm["geo"][:, 2]], axis=1).reshape(-1)
    return PRBGeometry(
        np.arange(0, 2 * nb + 1, 2, dtype=np.int64),
        full.root_p.copy(),
        full.root_R.copy(),
        full.length.copy(),
        full.tip_radius.copy(),
        seg,
        prm,
    )


class PRBBristles(BristleModel):
    """Every bristle of ``scene`` as the reduced model (module docstring)."""

    def __init__(self, scene, settings: SimSettings):
        if settings.bodies_per_bristle not in (0, 2):
            raise ConfigError(
                f"settings.bodies_per_bristle = {settings.bodies_per_bristle!r} is not allowed "
                'with model = "prb": the reduced model has two links per bristle (2, or 0 for '
                "the brush's own number)"
            )
        self.settings = settings
        self.model = build_geometry(scene.brush)
        m = self.model
        nb = m.n_bristles
        self.tip_args = np.zeros(nb, rec.TIP_ARGS)
        self.tip_args["radius"] = m.tip_radius
        # the links are rigid: the bristle's axial compliance L / (E A) [mm/N] sits behind its
        # tip, in series with the contact laws (``contact.series_law``; its direction is set at
        # every step, ``prb_kernels._axial_direction``).  Without it a pressed tip loads the
        # plate at once: 2.3x the full chain's force 0.03 mm into a press (bench touchdown)
        self.tip_args["cax"] = [
            br.length / (br.material.E * br.section.area) for br in scene.brush.bristles
        ]
        self.contact_params = scene.contact.as_array()
        # friction is the reduced model's own return mapping (prb_kernels._friction): the shared
        # tip load runs without it.  And without eq 6's damping term (c v^m2 delta^m3, tip-plate
        # and Table 3's tip-tip): a massless tip has no speed of its own, only the step's
        # (x - x_n) / h, ~200 mm/s when a lifted bristle springs back within one step.  The
        # term is small at the penalty law's depths (m3 = 2); over bench fidelity's 20 random
        # episodes leaving it out moved the errors from 34.1 % / 45.1 % (TCP / tip force) to
        # 32.7 % / 43.8 %.  The joints' damping stands in for the dissipation
        self._cp_frictionless = self.contact_params.copy()
        for key in ("mu_s", "mu_d", "c", "c_tt"):
            self._cp_frictionless[key] = 0.0
        self.surfaces, self.sdf, self.mesh = scene_surfaces(scene)
        self.pair_ptr, self.pair_idx = scene_tip_pairs(_PairModel(m), scene)
        # half of each bristle's weight at its tip, the other half at its root (statics of a
        # uniform cantilever: the same root force, the root moment within the bristle's sag)
        g = np.asarray(settings.gravity, float)
        mass = np.array(
            [br.material.density * br.section.area * br.length for br in scene.brush.bristles]
        )
        self.gtip = 0.5 * mass[:, None] * g[None, :]
        self.root_wrench = np.zeros((nb, 6))
        self._rootpos = np.zeros((nb, 3))
        self._Bw = np.zeros((nb, 3, 3))
        self._wk = _work(nb)
        cp = self.contact_params[0]
        self._wk.fric[:] = (cp["mu_s"], cp["mu_d"], cp["delta_max"])
        self._out = _Out(*(np.zeros(nb, np.int64) for _ in range(4)))
        self._tab = self._tables()
        self._head = (
            head_outline(scene.brush, _PairModel(m))
            if getattr(scene, "head_contact", False) and len(self.surfaces)
            else None
        )
        self._g23 = np.zeros((3, 3))
        self._headw = np.zeros((0 if self._head is None else len(self._head), 3))
        self._geo = K.Geometry(m.root_p, m.root_R, m.prm)
        self._backup = R_.Backup(
            np.zeros((nb, K.NQ)),
            np.zeros((nb, K.NQ)),
            np.zeros((nb, 7)),
            np.zeros(nb, rec.TIP_STATE),
            np.zeros((nb, 6)),
        )
        self._rec = None
        self._rollout_entry = None  # prb_rollout.rollout's entry point (``entry.py``)
        self._Rn = np.zeros((3, 3))
        self._ps = np.zeros(3)
        self._pp = np.zeros(3)
        self._Rp = np.zeros((3, 3))
        self._k = np.zeros(1, np.int64)
        self._frames = K.Frames(self._rootpos, self._Bw)
        self.state: PRBState | None = None
        self._snap: PRBState | None = None

    # ------------------------------------------------------------------ the seam
    @property
    def tips(self) -> np.ndarray:
        return self.state.tips[:, 0:6]

    def tip_states(self) -> np.ndarray:
        return np.array(self.state.tips[:, 0:6])

    @property
    def tip_forces(self) -> np.ndarray:
        return self.tip_args["fext"]

    def set_tip_forces(self, forces) -> None:
        self.tip_args["fext"] = forces

    def __getstate__(self) -> dict:
        """Pickled without the rollout's entry point (a compiled function's address, not
        picklable): the unpickled model looks it up again at its first rollout."""
        state = self.__dict__.copy()
        state["_rollout_entry"] = None
        return state

    def reset(self, tcp_p, tcp_R, time: float) -> None:
        m = self.model
        nb = m.n_bristles
        tips = np.zeros((nb, 7))
        tips[:, 0:3] = tcp_p + (m.root_p + m.length[:, None] * m.root_R[:, :, 0]) @ tcp_R.T
        tips[:, 6] = m.tip_radius
        rest = m.prm["rest"]
        self.state = PRBState(
            rest.copy(),
            rest.copy(),
            tips,
            fresh_tip_state(nb),
            np.zeros((2 * nb, 3)),
            np.zeros((2 * nb, 3, 3)),
            np.stack([tcp_p] * 4),
            np.stack([tcp_R] * 4),
            time,
            0,
        )
        self.root_wrench[:] = 0.0
        self._out.loose[:] = 0
        self._out.rough[:] = 0
        self._links()

    def _links(self) -> None:
        st = self.state
        K.root_frames(
            st.tcp_p[1], st.tcp_R[1], self.model.root_p, self.model.root_R, self._rootpos, self._Bw
        )
        K.link_poses(st.q, self.model.prm, self._rootpos, self._Bw, st.pos, st.rot, self._wk)

    def snapshot(self) -> PRBState:
        st, snap = self.state, self._snap
        if snap is None:
            snap = self._snap = st.copy()
        else:
            for name in ("q", "qp", "tips", "pos", "rot", "tcp_p", "tcp_R"):
                np.copyto(getattr(snap, name), getattr(st, name))
            np.copyto(snap.tip_state.view(np.uint8), st.tip_state.view(np.uint8))
            snap.time, snap.steps = st.time, st.steps
        return snap

    def set_state(self, state: PRBState) -> None:
        self.state = state.copy()
        self._links()

    def advance(self, tcp_p, tcp_R, t_new, rollback=None) -> tuple[int, int]:
        s = self.settings
        return self._solve(tcp_p, tcp_R, s.dt / s.substeps, False, t_new, rollback)

    def solve_static(self, tcp_p, tcp_R) -> tuple[int, int]:
        return self._solve(tcp_p, tcp_R, self.settings.dt, True, self.state.time, None)

    def _solve(self, tcp_p, tcp_R, h, static, t_new, rollback) -> tuple[int, int]:
        if rollback is None:
            rollback = self.snapshot()
        st = self.state
        sub = rec.Substep(1.0, -1.0, 0.0, h, 1.0 / h, static, np.zeros(3), ANGLE_TOL, MAX_ITER, 0)
        wrench0 = self.root_wrench.copy()
        K.step_all(
            st.tcp_p[1],
            st.tcp_R[1],
            np.asarray(tcp_p, float),
            np.asarray(tcp_R, float),
            self._geo,
            K.Joints(st.q, st.qp),
            self._frames,
            self._ctx(sub),
            self.gtip,
            self.root_wrench,
        )
        bad = np.flatnonzero(self._out.status)
        if bad.size or not np.all(np.isfinite(st.tips)):
            self.set_state(rollback)
            self.root_wrench[:] = wrench0  # the bristles solved before the failed one wrote theirs
            raise SimulationDivergence(
                t_new, bad, "the reduced model's equilibrium did not converge (Newton)"
            )
        st.tcp_p[3], st.tcp_R[3] = st.tcp_p[0], st.tcp_R[0]
        st.tcp_p[0], st.tcp_R[0] = st.tcp_p[1], st.tcp_R[1]
        st.tcp_p[1], st.tcp_R[1] = tcp_p, tcp_R
        st.time = t_new
        st.steps += 1
        K.link_poses(st.q, self.model.prm, self._rootpos, self._Bw, st.pos, st.rot, self._wk)
        return int(self._out.iters.sum()), 1

    def rollout(self, v, w, n: int, force_stop: float, penetration_stop: float):
        """``Simulator.rollout`` in one compiled call (``prb_rollout.rollout``): returns (steps
        done, stop reason or None, divergence message or None, the record)."""
        from .rotation import expmap

        s = self.settings
        st = self.state
        nb = self.model.n_bristles
        if self._rec is None or self._rec.p.shape[0] != n:
            self._rec = R_.make_record(n, nb)
        rec = self._rec
        m = s.substeps
        drv = R_.Drive(
            st.tcp_p[1].copy(),
            st.tcp_R[1].copy(),
            np.ascontiguousarray(v, dtype=np.float64),  # the entry point's type (below)
            expmap(w * s.dt),
            s.dt,
            m,
            expmap(w * (s.dt / m)),
            self._g23,
            self._head if self._head is not None else _NO_HEAD,
            self._headw,
            self._Rn,
            self._ps,
            self._pp,
            self._Rp,
            self._k,
            st.pos,
            st.rot,
        )
        h = s.dt / m
        sub = rec_.Substep(1.0, -1.0, 0.0, h, 1.0 / h, False, _ZERO3, ANGLE_TOL, MAX_ITER, 0)
        lim = R_.Limits(float(force_stop), float(penetration_stop), PENETRATION_WARN_FRACTION)
        args = (
            self._geo,
            K.Joints(st.q, st.qp),
            self._frames,
            self._ctx(sub),
            self.gtip,
            self.root_wrench,
            drv,
            lim,
            self._backup,
            rec,
        )
        # every argument keeps its type from call to call (the same records; the drive's
        # arrays made here as float64 copies): after the first call through numba's dispatcher,
        # the overload's entry point, without the dispatch (``entry.py``)
        call = self._rollout_entry
        if call is None:
            done, stop, bad = R_.rollout(*args)
            # the dispatcher itself if no overload matched: never typeof's ~3.7 ms again per call
            self._rollout_entry = entry_point(R_.rollout, args) or R_.rollout
        else:
            done, stop, bad = call(*args)
        if done:  # the drive and the clock move on by the steps done
            last = rec.p[done - 1], rec.R[done - 1]
            before = (rec.p[done - 2], rec.R[done - 2]) if done > 1 else (st.tcp_p[1], st.tcp_R[1])
            st.tcp_p[3], st.tcp_R[3] = st.tcp_p[0], st.tcp_R[0]
            st.tcp_p[0], st.tcp_R[0] = before[0], before[1]
            st.tcp_p[1], st.tcp_R[1] = last
            st.time = st.time + done * s.dt
            st.steps += done
        msg = None  # the kernel left the roots and links where the last step done put them
        if stop == rec_.STOP_DIVERGENCE:
            msg = str(
                SimulationDivergence(
                    st.time + s.dt,
                    np.array([bad]),
                    "the reduced model's equilibrium did not converge (Newton)",
                )
            )
        return done, rec_.STOP_REASONS[stop], msg, rec

    def _tables(self) -> K.Tab:
        """The tabulated tip law's tables: none for the chain's own Newton (``TableBristles``
        has them)."""
        return tip_table.no_tables(self.model.n_bristles)

    def _ctx(self, sub) -> K.Ctx:
        """The kernels' view of a solver step (``prb_kernels.Ctx``)."""
        return K.Ctx(self.model.prm, sub, self._contact(), self._wk, self._out, self._tab)

    def _contact(self) -> rec.ContactScene:
        return rec.ContactScene(
            self.surfaces,
            self._cp_frictionless,
            self.state.tips,
            self.pair_ptr,
            self.pair_idx,
            self.mesh,
            self.tip_args,
            self.state.tip_state,
            self.sdf,
            _NO_SHAFT,
        )

    def contact(self) -> TipContact:
        return tip_contact(self.state.tip_state)

    def tip_penetration(self) -> np.ndarray:
        return tip_penetration(self.state.tip_state)

    def head_clearance(self) -> float | None:
        if self._head is None:
            return None
        st = self.state
        pts = st.tcp_p[1] + self._head @ st.tcp_R[1].T
        g = self._g23
        return float(shf.clearance(self.surfaces, self.mesh, self.sdf, pts, g[0], g[1]))

    def solver_info(self) -> dict:
        """Newton's largest iteration count over the bristles of the last solver step; how many
        bristle-steps since reset were taken at a loose tolerance (prb_kernels.LOOSE_TOL, or a
        sub-step of them at ROUGH_TOL), and how many bristle sub-steps since reset only the last
        resort's ROUGH_TOL took (residual above LOOSE_TOL: a tip-force imbalance of ~1e-3 to
        ~0.1 N on a light contact)."""
        c = _counts(
            self._out.iters, self._out.loose, self._out.rough, self._tab.fallback, self._tab.outside
        )
        return dict(zip(self._INFO_KEYS, c))

    #: ``solver_info``'s keys, in ``_counts``' order (a model with tables adds theirs)
    _INFO_KEYS: tuple[str, ...] = ("newton_max", "loose_steps", "rough_steps")

    @property
    def n_tip_pairs(self) -> int:
        return len(self.pair_idx) // 2


@dataclass
class _PairModel:
    """What ``chain.tip_pairs`` and ``chain.head_outline`` read of a model."""

    g: PRBGeometry

    @property
    def n_bristles(self):
        return self.g.n_bristles

    @property
    def root_p(self):
        return self.g.root_p

    @property
    def length(self):
        return self.g.length

    @property
    def tip_radius(self):
        return self.g.tip_radius


from collections import namedtuple  # noqa: E402

_Out = namedtuple("_Out", ["iters", "status", "loose", "rough"])


@njit(cache=True, fastmath=False)
def _counts(it, loose, rough, fallback, outside):
    """``solver_info``'s counts in one compiled pass (every env step reads them): Newton's largest
    iteration count of the last solver step (``_Out.iters``, modulo LOOSE), the loose and rough
    bristle-steps, the table's fallbacks and its steps beyond it since reset
    (``prb_kernels.Tab``)."""
    m = 0
    for b in range(it.shape[0]):
        m = max(m, it[b])
    c1 = 0
    c2 = 0
    for b in range(loose.shape[0]):
        c1 += loose[b]
        c2 += rough[b]
    c3 = 0
    c4 = 0
    for b in range(fallback.shape[0]):
        c3 += fallback[b]
        c4 += outside[b]
    return m % K.LOOSE, c1, c2, c3, c4


_Work = namedtuple(
    "_Work",
    [
        "x",
        "xw",
        "J",
        "G",
        "F",
        "Kt",
        "Fl",
        "A",
        "r",
        "JK",
        "Ktl",
        "zero3",
        "cs",
        "orders",
        "v",
        "tmp",
        "piv",
        "qn",
        "qt",
        "tw",
        "s",
        "dq",
        "qt2",
        "dp",
        "A2",
        "S",
        "V",
        "w",
        "rp0",
        "B0",
        "d0",
        "xs",
        "qs",
        "rws",
        "Bs",
        "qr",
        "qb",
        "fric",
        "dn3",
        "start",
    ],
)
_NO_SHAFT = np.zeros(0, rec.SHAFT)
_NO_HEAD = np.zeros((0, 3))
_ZERO3 = np.zeros(3)


def _work(nb: int) -> _Work:
    z = np.zeros
    tw = rec.TipScratch(*(z((3, 3)) if f in ("J", "A") else z(3) for f in rec.TipScratch._fields))
    return _Work(
        z(3),
        z(3),
        z((3, K.NQ)),
        z((K.NQ, K.NQ)),
        z(3),
        z((3, 3)),
        z(3),
        z((K.NQ, K.NQ)),
        z(K.NQ),
        z((3, K.NQ)),
        z((3, 3)),
        z(3),
        z((K.NQ, 2)),
        np.zeros(K.NQ, np.int64),
        z(3),
        z(3),
        np.zeros(K.NQ, np.int64),
        z(K.NQ),
        z(K.NQ),
        tw,
        z(K.NQ),
        z(K.NQ),
        z(K.NQ),
        z(3),
        z((K.NQ, K.NQ)),
        z((K.NQ, K.NQ)),
        z((K.NQ, K.NQ)),
        z(K.NQ),
        z((nb, 3)),
        z((nb, 3, 3)),
        z(4),
        z(3),
        z(K.NQ),
        z(3),
        z((3, 3)),
        z(K.NQ),
        z(K.NQ),
        z(3),
        z(3),
        z((nb, 2 * K.NQ + 10)),
    )


class TableBristles(PRBBristles):
    """The reduced model with its touching bristles stepped by the tabulated tip law
    (``tip_table.py``): the same chain, springs and tip contact, its equilibria looked up by the
    tip's position (a Newton on three coordinates instead of five joint angles)."""

    _range_warned = False  # warned of a tip beyond its table since reset (``_check_range``)

    def _tables(self) -> K.Tab:
        return tip_table.tables_for(self.model.prm)

    def reset(self, tcp_p, tcp_R, time: float) -> None:
        """As the chain's, with every tip where its joints put it: the chain's reset leaves the
        tips on the straight bristles' axes (its first free step moves them), and the table's
        step carries a settled free tip with its root as it stands (``_table_step``)."""
        super().reset(tcp_p, tcp_R, time)
        st, wk = self.state, self._wk
        for b in range(self.model.n_bristles):
            K.kinematics(
                st.q[b], self.model.prm[b]["geo"], wk.x, wk.J, wk.cs, wk.orders, wk.v, wk.tmp
            )
            st.tips[b, 0:3] = self._rootpos[b] + self._Bw[b] @ wk.x
        self._tab.outside[:] = 0
        self._tab.fallback[:] = 0
        self._range_warned = False

    def advance(self, tcp_p, tcp_R, t_new, rollback=None) -> tuple[int, int]:
        r = super().advance(tcp_p, tcp_R, t_new, rollback)
        self._check_range()
        return r

    def rollout(self, v, w, n: int, force_stop: float, penetration_stop: float):
        r = super().rollout(v, w, n, force_stop, penetration_stop)
        self._check_range()
        return r

    def _check_range(self) -> None:
        """Warn once per reset when a step ended with a tip beyond its table (chord below the
        table's shortest or angle from the root's axis past its largest: the edge's values were
        used, not an extrapolation), naming the bristle and where its tip is."""
        if self._range_warned or not self._tab.outside.any():
            return
        self._range_warned = True
        b = int(np.argmax(self._tab.outside))
        g = self._tab.grid[self._tab.idx[b]]
        u = self._Bw[b].T @ (self.state.tips[b, 0:3] - self._rootpos[b])
        u[0] -= g["geo"][0]  # about joint 1, where the table's spherical grid is centred
        rho = float(np.linalg.norm(u))
        theta = math.degrees(math.acos(max(-1.0, min(1.0, u[0] / max(rho, 1e-300)))))
        warnings.warn(
            f"t = {self.state.time:.4g} s: the tip of bristle {b} left its tip table "
            f"(tip_table.py): chord {rho:.3g} mm (table: >= {g['rmin']:.3g} mm) at "
            f"{theta:.3g} deg from the root's axis (table: <= {math.degrees(g['tmax']):.0f} deg); "
            "the table's edge values were used there (a bristle folded this far is outside the "
            "calibrated range of the reduced model); warned once per reset",
            TableRangeWarning,
            stacklevel=3,
        )

    #: ``solver_info``: the chain's (``PRBBristles.solver_info``) and, since reset, the
    #: bristle-steps the table could not take (``table_fallbacks``: the chain's Newton took them)
    #: and those that ended beyond the table (``table_outside``)
    _INFO_KEYS = (*PRBBristles._INFO_KEYS, "table_fallbacks", "table_outside")


class TableRangeWarning(UserWarning):
    """A tip left the range its table covers (``TableBristles._check_range``)."""


register_bristle_model("prb", PRBBristles)
register_bristle_model("table", TableBristles)
