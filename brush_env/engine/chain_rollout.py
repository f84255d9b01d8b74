"""Many steps of the full chain along prescribed TCP poses in one compiled call
(``Simulator.follow``; the reduced model's ``prb_rollout`` pattern).

Per solver step the kernel does what ``DFMChain.advance`` and ``Simulator._track`` do through
Python: set the drive's pose, run the shaft broad phase, solve every bristle
(``step.step_bristles`` or ``step_bristles_coupled``), accept or restore, move the drive on, keep
the peaks; per engine step (``substeps`` solver steps, one rollback copy) it writes what
``Simulator._result`` reports into a row of a :data:`FollowRecord`.  The physics is the step
kernels' unchanged: a run through ``follow`` and the same poses through ``Simulator.step`` give
the same state, wrench and tip states to the bit (``tests/engine/test_follow.py``).  What it
saves is the Python around each step: the snapshot, the records built per call, the checks, the
per-step peaks and the ``StepResult``
(docs/benchmarks.md, "A compiled pose rollout").

Two kernels, ``follow_one_sweep`` and ``follow_coupled``, each calling one step kernel, so that
a run compiles only the solve its level uses (as ``step.py``).  Units: mm, N, N mm, s.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from ._kernels import HOT
from .records import (
    STOP_DIVERGENCE,
    STOP_FORCE,
    STOP_HEAD,
    STOP_NONE,
    STOP_PENETRATION,
)
from .shaft import broad_phase, clearance
from .step import all_finite, step_bristles, step_bristles_coupled, tcp_wrench, tip_states

#: the per-engine-step outputs of a follow (n poses asked for, nb bristles; rows past ``done``
#: untouched): t (n,) [s] time at the step's end; FM (n, 6) the TCP wrench on the brush
#: (force [N], moment [N mm] about the TCP, world; ``step.tcp_wrench``); iters, nsub (n,) Newton
#: iterations and sub-steps of all bristles; sweeps (n, 3) the sweep counters
#: (``DFMChain.solver_info``: sweeps, re-solves, 0 settled / 1 unsettled / 2 fell back); tips
#: (n, nb, 6) tip node position [mm] and velocity [mm/s]; per tip: fn (n, nb) [N] normal force
#: (eq 6), ft (n, nb, 3) [N] friction (eq 7-10), slide (n, nb) 1 sliding, pen (n, nb) [mm]
#: penetration (0 off contact), cpt (n, nb, 3) [mm] contact point, ftt (n, nb) [N] tip-tip force
#: (Table 3), surf (n, nb) deepest surface (-1 none); pen_max (n,) [mm] deepest tip penetration,
#: beyond (n,) 1 if a tip is beyond the penalty law's range, shaft_pen (n,) [mm] deepest shaft
#: penetration, shaft_fn (n, nb) [N] each bristle's shaft normal force, head (n,) [mm] the head's
#: clearance (inf without head contact); body (m, n bodies, 3) [mm] every body's centre at the
#: rows ``FollowRun.keep`` names (m = 0: none kept)
FollowRecord = namedtuple(
    "FollowRecord",
    [
        "t",
        "FM",
        "iters",
        "nsub",
        "sweeps",
        "tips",
        "fn",
        "ft",
        "slide",
        "pen",
        "cpt",
        "ftt",
        "surf",
        "pen_max",
        "beyond",
        "shaft_pen",
        "shaft_fn",
        "head",
        "body",
    ],
)

#: the run's inputs and scratch: P (n sub, 3) [mm] / R (n sub, 3, 3) the TCP poses at the ends
#: of the solver steps, sub per engine step (``Simulator._split_poses``); clock (2,) [time s (moved
#: on in place), dt s (the engine step)]; live / snap: the state's arrays as flat float64
#: views and their rollback copies (``DFMChain._follow_views``); shaft_on: the shaft broad phase
#: runs; g23 (3, 3) scratch; head (nh, 3) [mm] the head's outline in the TCP frame (empty: no
#: head contact), headw (nh, 3) scratch; limits (4,): stop after a step whose total normal force
#: exceeds limits[0] [N], whose deepest penetration exceeds limits[1] [mm], whose head clearance
#: is <= limits[2] [mm] (-inf: never); limits[3] the penetration fraction of the tip radius beyond
#: which a step counts in ``beyond``; keep (n,) int64: the slot of ``FollowRecord.body`` that
#: engine step k's body centres go to (-1: not kept)
FollowRun = namedtuple(
    "FollowRun",
    [
        "P", "R", "sub", "clock", "live", "snap", "shaft_on", "g23", "head", "headw", "limits",
        "keep",
    ],
)  # fmt: skip


def make_follow_record(n: int, nb: int, kept: int = 0, n_bodies: int = 0) -> FollowRecord:
    """Zeroed record of n steps of nb bristles (head clearance inf), with room for the body
    centres of ``kept`` steps of ``n_bodies`` bodies."""
    return FollowRecord(
        np.zeros(n),
        np.zeros((n, 6)),
        np.zeros(n, np.int64),
        np.zeros(n, np.int64),
        np.zeros((n, 3), np.int64),
        np.zeros((n, nb, 6)),
        np.zeros((n, nb)),
        np.zeros((n, nb, 3)),
        np.zeros((n, nb), np.int64),
        np.zeros((n, nb)),
        np.zeros((n, nb, 3)),
        np.zeros((n, nb)),
        np.full((n, nb), -1, np.int64),
        np.zeros(n),
        np.zeros(n, np.int64),
        np.zeros(n),
        np.zeros((n, nb)),
        np.full(n, np.inf),
        np.zeros((kept, n_bodies, 3)),
    )


@njit(**HOT)
def follow_one_sweep(model, chain, drive, prm, con, jc, ws, out, run, rec):
    """Up to rec.t.shape[0] engine steps of run.sub solver steps each, with one sweep
    (``step.step_bristles``); returns (steps done, STOP_*, the solver step it stopped at or
    -1).  Arguments as ``step_bristles``' plus ``run`` (``FollowRun``) and ``rec``
    (``FollowRecord``).  A divergence restores the
    state of the failed engine step's start (as ``Simulator._advance_split``; its Newton factors
    marked stale) and counts that step as not done."""
    n = rec.t.shape[0]
    for k in range(n):
        _copy_state(run.live, run.snap)  # the rollback target of the step's solver steps
        for i in range(k * run.sub, (k + 1) * run.sub):
            _begin(i, model, chain, drive, prm, con, run)
            step_bristles(model, chain, drive, prm, con, jc, ws, out)
            stop = _end(i, model, chain, drive, con, jc, ws, out, run, rec)
            if stop != STOP_NONE:
                return (k if stop == STOP_DIVERGENCE else k + 1), stop, i
    return n, STOP_NONE, -1


@njit(**HOT)
def follow_coupled(model, chain, drive, prm, con, jc, ws, out, run, rec):
    """``follow_one_sweep`` with the coupled tip-tip solve (``step.step_bristles_coupled``)."""
    n = rec.t.shape[0]
    for k in range(n):
        _copy_state(run.live, run.snap)  # the rollback target of the step's solver steps
        for i in range(k * run.sub, (k + 1) * run.sub):
            _begin(i, model, chain, drive, prm, con, run)
            step_bristles_coupled(model, chain, drive, prm, con, jc, ws, out)
            stop = _end(i, model, chain, drive, con, jc, ws, out, run, rec)
            if stop != STOP_NONE:
                return (k if stop == STOP_DIVERGENCE else k + 1), stop, i
    return n, STOP_NONE, -1


@njit(**HOT, inline="always")
def _copy_state(src, dst):
    """dst[j] <- src[j] for the tuples of flat arrays src, dst (the rollback copy)."""
    for j in range(len(src)):
        s = src[j]
        d = dst[j]
        for i in range(s.shape[0]):
            d[i] = s[i]


@njit(**HOT, inline="always")
def _begin(i, model, chain, drive, prm, con, run):
    """Before solver step i: the drive's pose at its end (row 2, ``DFMChain._base_motion``) and
    the shaft broad phase (``_solve_bristles``)."""
    for a in range(3):
        drive.tcp_p[2, a] = run.P[i, a]
        for c in range(3):
            drive.tcp_R[2, a, c] = run.R[i, a, c]
    if run.shaft_on:
        broad_phase(model.bstart, model.root_p, chain, drive, con, prm.h, run.g23)


@njit(**HOT, inline="always")
def _failed(chain, out):
    """True if a bristle failed on its smallest halving or the state is not finite
    (``DFMChain._accept_or_rollback``)."""
    for b in range(out.status.shape[0]):
        if out.status[b] != 0:
            return True
    return not (all_finite(chain.pos) and all_finite(out.rootw))


@njit(**HOT, inline="always")
def _end(i, model, chain, drive, con, jc, ws, out, run, rec):
    """After solver step i: accept or restore, move the drive on (``DFMChain._shift_drive``),
    the step's peaks (``Simulator._track``) and, after the engine step's last solver step, its
    row of ``rec``; returns STOP_*."""
    if _failed(chain, out):
        _copy_state(run.snap, run.live)
        tip_states(model.bstart, model.bp, chain.pos, chain.rot, chain.vel, chain.omg, con.tips)
        for b in range(jc.key.shape[0]):
            jc.key[b] = 0.0  # factors of the rejected iterates: stale
        return STOP_DIVERGENCE
    tp, tR = drive.tcp_p, drive.tcp_R
    for a in range(3):
        tp[3, a] = tp[0, a]
        tp[0, a] = tp[1, a]
        tp[1, a] = run.P[i, a]
        for c in range(3):
            tR[3, a, c] = tR[0, a, c]
            tR[0, a, c] = tR[1, a, c]
            tR[1, a, c] = run.R[i, a, c]
    k = i // run.sub
    _peaks(i, k, model, con, out, run, rec)
    if i % run.sub != run.sub - 1:
        return STOP_NONE
    run.clock[0] = run.clock[0] + run.clock[1]  # t0 + dt: no drift of the step grid
    return _record(i, k, model, chain, con, ws, out, run, rec)


@njit(**HOT, inline="always")
def _peaks(i, k, model, con, out, run, rec):
    """Row k's in-step peaks after its solver step i (``Simulator._track``): the deepest tip and
    shaft penetrations [mm], the solver steps with a tip beyond the penalty range, the head's
    smallest clearance [mm]; and its Newton iterations and sub-steps."""
    for b in range(out.iters.shape[0]):
        rec.iters[k] += out.iters[b]
        rec.nsub[k] += out.nsub[b]
    beyond = 0
    for b in range(rec.fn.shape[1]):
        st = con.tip_state[b]
        pen = max(st.pen, 0.0) if st.fn > 0.0 else 0.0
        rec.pen_max[k] = max(rec.pen_max[k], pen)
        if pen / con.tip_args[b].radius > run.limits[3]:
            beyond = 1
    rec.beyond[k] += beyond
    if run.shaft_on:
        for j in range(con.shaft.shape[0]):
            sh = con.shaft[j]
            if sh.fn > 0.0:
                rec.shaft_pen[k] = max(rec.shaft_pen[k], max(sh.pen, 0.0))
    if run.head.shape[0] > 0:
        rec.head[k] = min(rec.head[k], _head_clearance(i, con, run))


@njit(**HOT, inline="always")
def _record(i, k, model, chain, con, ws, out, run, rec):
    """Row k of ``rec`` after the engine step's last solver step i (and the body centres, if
    ``run.keep`` keeps the step's); returns STOP_* by ``run.limits``."""
    rec.t[k] = run.clock[0]
    slot = run.keep[k]
    if slot >= 0:
        for j in range(chain.pos.shape[0]):
            for a in range(3):
                rec.body[slot, j, a] = chain.pos[j, a]
    tcp_wrench(run.R[i], model.root_p, out.rootw, rec.FM[k])  # R[i]: the drive's row 1 now
    for a in range(3):
        rec.sweeps[k, a] = ws.sw.count[a]
    total = 0.0
    for b in range(rec.fn.shape[1]):
        st = con.tip_state[b]
        touching = st.fn > 0.0
        for a in range(6):
            rec.tips[k, b, a] = con.tips[b, a]
        for a in range(3):
            rec.ft[k, b, a] = st.ft[a]
            rec.cpt[k, b, a] = st.cpt[a]
        rec.fn[k, b] = st.fn
        rec.slide[k, b] = 1 if (st.slide > 0 and touching) else 0
        rec.pen[k, b] = max(st.pen, 0.0) if touching else 0.0
        rec.ftt[k, b] = st.ftt
        rec.surf[k, b] = st.surf if touching else -1
        total += st.fn
    if run.shaft_on:
        bstart = model.bstart
        for b in range(bstart.shape[0] - 1):
            f = 0.0
            for j in range(bstart[b], bstart[b + 1]):
                f += con.shaft[j].fn
            rec.shaft_fn[k, b] = f
            total += f
    if total > run.limits[0]:
        return STOP_FORCE
    if rec.head[k] <= run.limits[2]:
        return STOP_HEAD
    if max(rec.pen_max[k], rec.shaft_pen[k]) > run.limits[1]:
        return STOP_PENETRATION
    return STOP_NONE


@njit(**HOT, inline="always")
def _head_clearance(i, con, run):
    """Smallest distance [mm] of the head's outline to the surfaces at the pose of solver step i
    (``DFMChain.head_clearance``)."""
    P, R, pts = run.P, run.R, run.headw
    for j in range(run.head.shape[0]):
        h = run.head[j]
        for a in range(3):
            pts[j, a] = P[i, a] + (R[i, a, 0] * h[0] + R[i, a, 1] * h[1] + R[i, a, 2] * h[2])
    return clearance(con.surf, con.mesh, con.sdf, pts, run.g23[0], run.g23[1])
