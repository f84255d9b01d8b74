"""Many steps of the reduced model in one compiled call (``Simulator.rollout``): the TCP driven at a
constant twist, every engine step recorded (tip forces and contact points, the in-step
penetration peaks, the head's clearance), and the run stopped where a limit is crossed.

This is what lets an env step of the ``fast`` level cost tens of microseconds: one call per
action instead of one Python ``Simulator.step`` per engine step.  The physics is ``prb_kernels``'
(``step_all``) unchanged; a test checks that a rollout and the same steps through
``Simulator.step`` agree.
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from .prb_kernels import PRB, link_poses, root_frames, step_all
from .records import (
    STOP_DIVERGENCE,
    STOP_FORCE,
    STOP_HEAD,
    STOP_NONE,
    STOP_PENETRATION,
)
from .shaft import clearance

#: the per-engine-step record of a rollout (n = steps asked for; rows past ``done`` untouched):
#: fn (n, nb) [N] tip normal forces, cpt (n, nb, 3) [mm] contact points, surf (n, nb) deepest
#: surface (-1 none), pen_max (n,) [mm] deepest tip penetration over the step's solver steps,
#: beyond (n,) solver steps with a tip beyond the penalty range, head (n,) [mm] the head's smallest
#: clearance over the solver steps (inf without head contact), p (n, 3) [mm] / R (n, 3, 3) the TCP
#: at the step's end, shaft_fn (n,) [N] the shafts' total normal force at the step's end and
#: shaft_pen (n,) [mm] their deepest penetration over its solver steps (0 for a model without)
Record = namedtuple(
    "Record", ["fn", "cpt", "surf", "pen_max", "beyond", "head", "p", "R", "shaft_fn", "shaft_pen"]
)
#: scratch and model arrays of the rollout kernel; pos (2 nb, 3) [mm], rot (2 nb, 3, 3): the
#: links' poses at the end (``PRBState.pos``/``rot``, written by the kernel)
Drive = namedtuple(
    "Drive",
    [
        "p",
        "R",
        "v",
        "dR",
        "dt",
        "substeps",
        "dR_sub",
        "Rtmp",
        "head",
        "headw",
        "Rn",
        "ps",
        "pp",
        "Rp",
        "k",
        "pos",
        "rot",
    ],
)
Limits = namedtuple("Limits", ["force", "penetration", "warn_fraction"])
Backup = namedtuple("Backup", ["q", "qp", "tips", "tip_state", "rootw"])


def make_record(n: int, nb: int) -> Record:
    return Record(
        np.zeros((n, nb)),
        np.zeros((n, nb, 3)),
        np.zeros((n, nb), np.int64),
        np.zeros(n),
        np.zeros(n, np.int64),
        np.zeros(n),
        np.zeros((n, 3)),
        np.zeros((n, 3, 3)),
        np.zeros(n),
        np.zeros(n),
    )


@njit(**PRB, inline="always")
def _left(dR, R, out):
    """out <- dR @ R (3 x 3)."""
    for a in range(3):
        for b in range(3):
            out[a, b] = dR[a, 0] * R[0, b] + dR[a, 1] * R[1, b] + dR[a, 2] * R[2, b]


@njit(**PRB, inline="always")
def _copy2(src, dst):
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@njit(**PRB, inline="always")
def _save(q, qp, tips, ts, rootw, bk, restore):
    """bk <- the bristles' state (q, tips, tip states, root wrenches), or back from bk with
    ``restore`` (the wrenches too: a failed step has written those of the bristles before the
    one that failed)."""
    a = ts.view(np.uint8)
    c = bk.tip_state.view(np.uint8)
    if restore:
        _copy2(bk.q, q)
        _copy2(bk.qp, qp)
        _copy2(bk.tips, tips)
        _copy2(bk.rootw, rootw)
        for i in range(a.shape[0]):
            a[i] = c[i]
    else:
        _copy2(q, bk.q)
        _copy2(qp, bk.qp)
        _copy2(tips, bk.tips)
        _copy2(rootw, bk.rootw)
        for i in range(a.shape[0]):
            c[i] = a[i]


@njit(**PRB, inline="always")
def _head_clearance(drv, p, R, con):
    """Smallest distance [mm] of the head's outline (TCP frame) to the surfaces at pose (p, R)."""
    pts = drv.headw
    for j in range(drv.head.shape[0]):
        for a in range(3):
            pts[j, a] = (
                p[a]
                + R[a, 0] * drv.head[j, 0]
                + R[a, 1] * drv.head[j, 1]
                + (R[a, 2] * drv.head[j, 2])
            )
    return clearance(con.surf, con.mesh, con.sdf, pts, drv.Rtmp[0], drv.Rtmp[1])


@njit(**PRB, inline="always")
def _solver_step(drv, Rs, geo, joints, frames, ctx, gtip, rootw, lim, rec):
    """One solver step from the pose (drv.pp, drv.Rp) to (drv.ps, Rs); records its penetration
    peak in row drv.k[0] of ``rec``; False if a bristle failed."""
    step_all(drv.pp, drv.Rp, drv.ps, Rs, geo, joints, frames, ctx, gtip, rootw)
    con, out = ctx.con, ctx.out
    nb = joints.q.shape[0]
    for b in range(nb):
        if out.status[b] != 0:
            return False
    k = drv.k[0]
    beyond = False
    for b in range(nb):
        st = con.tip_state[b]
        if st.fn > 0.0 and st.pen > 0.0:
            if st.pen > rec.pen_max[k]:
                rec.pen_max[k] = st.pen
            if st.pen > lim.warn_fraction * con.tip_args[b].radius:
                beyond = True
    rec.beyond[k] += int(beyond)
    return True


@njit(**PRB, inline="always")
def _record_step(k, con, rec):
    """Row k of the record: the tips' normal forces, contact points and surfaces; returns the
    total normal force [N]."""
    total = 0.0
    for b in range(rec.fn.shape[1]):
        st = con.tip_state[b]
        fn = st.fn
        rec.fn[k, b] = fn
        rec.surf[k, b] = st.surf if fn > 0.0 else -1
        for a in range(3):
            rec.cpt[k, b, a] = st.cpt[a]
        total += fn
    return total


@njit(**PRB)
def rollout(geo, joints, frames, ctx, gtip, rootw, drv, lim, bk, rec):
    """Up to rec.p.shape[0] engine steps (module docstring); returns (steps done, STOP_*, the
    failed bristle or -1).  drv.p, drv.R: the TCP pose now, moved along in place; each engine step
    is drv.substeps solver steps (position linear, rotation by drv.dR_sub each).  At the end the
    roots (frames) and the links' poses (drv.pos, drv.rot) are those of the last step done."""
    r = _run(geo, joints, frames, ctx, gtip, rootw, drv, lim, bk, rec)
    root_frames(drv.p, drv.R, geo.root_p, geo.root_R, frames.rootpos, frames.Bw)
    link_poses(joints.q, geo.prm, frames.rootpos, frames.Bw, drv.pos, drv.rot, ctx.wk)
    return r


@njit(**PRB, inline="always")
def _run(geo, joints, frames, ctx, gtip, rootw, drv, lim, bk, rec):
    """``rollout``'s steps."""
    n = rec.p.shape[0]
    q, qp, con, out = joints.q, joints.qp, ctx.con, ctx.out
    p, R, Rn, ps = drv.p, drv.R, drv.Rn, drv.ps
    for k in range(n):
        drv.k[0] = k
        _save(q, qp, con.tips, con.tip_state, rootw, bk, False)
        rec.pen_max[k] = 0.0
        rec.beyond[k] = 0
        rec.head[k] = np.inf
        Rs = rec.R[k]
        _copy2(R, Rs)
        _copy2(R, drv.Rp)
        for a in range(3):
            drv.pp[a] = p[a]
        for s in range(1, drv.substeps + 1):
            for a in range(3):
                ps[a] = p[a] + (s / drv.substeps) * drv.v[a] * drv.dt
            _left(drv.dR if s == drv.substeps else drv.dR_sub, R if s == drv.substeps else Rs, Rn)
            _copy2(Rn, Rs)
            if not _solver_step(drv, Rs, geo, joints, frames, ctx, gtip, rootw, lim, rec):
                _save(q, qp, con.tips, con.tip_state, rootw, bk, True)
                for b in range(q.shape[0]):
                    if out.status[b] != 0:
                        return k, STOP_DIVERGENCE, b
            if drv.head.shape[0] > 0:
                rec.head[k] = min(rec.head[k], _head_clearance(drv, ps, Rs, con))
            _copy2(Rs, drv.Rp)
            for a in range(3):
                drv.pp[a] = ps[a]
        for a in range(3):
            p[a] = ps[a]
            rec.p[k, a] = ps[a]
        _copy2(Rs, R)
        if _record_step(k, con, rec) > lim.force:
            return k + 1, STOP_FORCE, -1
        if rec.head[k] <= 0.0:
            return k + 1, STOP_HEAD, -1
        if rec.pen_max[k] > lim.penetration:
            return k + 1, STOP_PENETRATION, -1
    return n, STOP_NONE, -1
