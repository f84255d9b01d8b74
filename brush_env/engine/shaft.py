"""Shaft contact: every body of a bristle chain as a capsule against the surfaces (issue 28).

Body i spans its axis from its proximal node c - half R e_x to its distal node c + half R e_x;
its capsule has the radius of half the section's smaller side (``SHAFT.radius``).  The tip
body's capsule stops a tip radius short of the tip node (the tip sphere covers the rest), and a
body whose whole axis lies within the tip sphere has none.

One contact per body and surface, a sphere of the shaft radius on the axis at its deepest point:
the surface's signed distance is sampled along the axis (the two ends on a plane, where it is
linear; ``SAMPLES`` points on curved surfaces) and the contact sphere sits at the penetration-
weighted mean of the samples (weights ``(d_j / (r + BAND))**SHARP``, d_j = r + BAND - gap_j > 0).
On a plane this is the deeper end as soon as one end is clearly deeper, and the middle of a body
lying flat (where the pressure's centre is); unlike the exact arg-min it moves continuously, so
the moment about the body's centre does not jump between the ends, which Newton would not
forgive.  The normal force is eq 6 (the scene's ``ContactParams``) at the true gap of that point,
so it starts at zero when a sample first enters the band.  Friction is eq 7-10 with a stiction
state per body (``SHAFT.delta``, ``beta``), committed with the step like the tips' (newton.py),
at the material point of the deepest contact against the resultant of the body's normal forces.

Everything is in the residual of eq 11 (``residual.bristle_residual`` calls ``shaft_load``) and
its Newton matrix (each body's 6x6 block, ``tipblock.add_point_block``), and the Newton step cap
keeps a shaft contact from being thrown deep into a surface (``shaft_step_limit``).  The broad
phase (``broad_phase``, once per solver step) marks the bodies that can reach a surface within
the step: those of a bristle one of whose capsules can, and within it only the bodies whose arc
length from the root spans the root's clearance; the others cost one flag test each.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT
from .contact import PEN_STEP_MIN, friction_load, normal_law
from .records import SURF_PLANE
from .sdf import FAR
from .surfaces import normal_rate, surface_gap
from .tipblock import add_point_block

SAMPLES = 5  # points along a body's axis against a curved surface (a plane: its two ends)
BAND = 0.1  # [mm] a sample within r + BAND of a surface places the contact sphere
SHARP = 8.0  # exponent of the samples' weights (larger: closer to the exact deepest point)
MARGIN = 0.5  # [mm] broad phase: clearance kept beyond the largest travel of the step
#: broad phase: a capsule point lies at most this factor times its arc length from the root (the
#: chain's axial and shear strains are ~1e-4 under the brushing loads; 5 % is far beyond them)
REACH_STRETCH = 1.05
NOT_EVALUATED = -1e30  # SHAFT.pen of a body not evaluated


@njit(**HOT, inline="always")
def _axis_point(c, R, u, out):
    """out <- c + u R e_x (a point on the body's axis, u [mm] from its centre)."""
    for a in range(3):
        out[a] = c[a] + u * R[a, 0]


@njit(**HOT)
def _contact_offset(con, s, c, R, rec, sh):
    """Where the contact sphere sits on body (c, R)'s axis against surface s: (a sample in the
    band, u [mm] from the centre, the smallest sample gap [mm] and its u); the smallest sample's
    normal into sh.gd.  Samples the gap along [lo, hi] (module docstring)."""
    lo = rec.lo
    hi = rec.hi
    r = rec.radius
    m = 2 if con.surf[s].kind == SURF_PLANE else SAMPLES
    wsum = 0.0
    wu = 0.0
    gmin = np.inf
    umin = 0.0
    for j in range(m):
        u = lo + (hi - lo) * j / (m - 1)
        _axis_point(c, R, u, sh.pt)
        gap = surface_gap(con.surf, s, sh.pt, sh.F, sh.pp, con.mesh, con.sdf)
        if gap < gmin:
            gmin = gap
            umin = u
            for a in range(3):
                sh.gd[a] = sh.F[a]
        d = r + BAND - gap
        if d > 0.0:
            w = (d / (r + BAND)) ** SHARP
            wsum += w
            wu += w * u
    if wsum <= 0.0:
        return False, 0.0, gmin, umin
    return True, wu / wsum, gmin, umin


@njit(**HOT, inline="always")
def _candidate(rec, s, pen, u, nrm, cpt):
    """Keep surface s as the body's deepest if its penetration pen [mm] (< 0: clearance) is."""
    if pen > rec.pen:
        rec.pen = pen
        rec.surf = s
        rec.u = u
        for a in range(3):
            rec.nrm[a] = nrm[a]
            rec.cpt[a] = cpt[a]


@njit(**HOT, inline="always")
def _point_velocity(br, k, u, chain, sub, it, v):
    """v <- velocity of the body's material point at u [mm] on its axis by the two-step formula
    (zero for statics); returns nothing.  Start-of-step pose: it.s_pos/s_rot (``Iterate`` or
    ``ShaftWork``); t_{n-1}: ppos/prot."""
    i = br.b0 + k
    if sub.static:
        for a in range(3):
            v[a] = 0.0
        return
    for a in range(3):
        pnow = chain.pos[i, a] + u * chain.rot[i, a, 0]
        pn = it.s_pos[k, a] + u * it.s_rot[k, a, 0]
        pp = chain.ppos[i, a] + u * chain.prot[i, a, 0]
        v[a] = (sub.c0 * pnow + sub.c1 * pn + sub.c2 * pp) * sub.inv_h


@njit(**HOT, inline="always")
def _reset_evaluation(rec):
    rec.fn = 0.0
    rec.pen = NOT_EVALUATED
    rec.surf = -1
    rec.slide = 0
    rec.bnew = 0.0
    rec.u = 0.0
    for a in range(3):
        rec.dnew[a] = 0.0
        rec.ft[a] = 0.0


@njit(**HOT, inline="always")
def _apply(k, i, chain, res, u, F, sh, blk):
    """res[k] -= (F, (p - c) x F) for a load F at the axis point u; its block into sh.D6[k]."""
    R = chain.rot[i]
    r0 = u * R[0, 0]
    r1 = u * R[1, 0]
    r2 = u * R[2, 0]
    res[k, 0] -= F[0]
    res[k, 1] -= F[1]
    res[k, 2] -= F[2]
    res[k, 3] -= r1 * F[2] - r2 * F[1]
    res[k, 4] -= r2 * F[0] - r0 * F[2]
    res[k, 5] -= r0 * F[1] - r1 * F[0]
    sh.pp[0] = r0
    sh.pp[1] = r1
    sh.pp[2] = r2
    add_point_block(sh.D6[k], sh.pp, F, sh.K, blk)
    sh.on[k] = 1


@njit(**HOT)
def shaft_load(br, chain, sub, con, sx, res):
    """Subtract every body's shaft contact load (eq 6, eq 7-10) and its moment about the body's
    centre from the residual ``res`` of bristle ``br``; each body's Newton block into sx.sh.D6
    (sx.sh.on[k] = 1 where set).  No-op without shaft contact (``con.shaft`` empty).  sx:
    ``records.ShaftWork``, the scratch it uses (not the whole ``Work``: numba passes every array
    of an argument, and the whole workspace cost ~1,000 words of arguments per call)."""
    shaft = con.shaft
    sh = sx.sh
    for k in range(br.n):
        sh.on[k] = 0
    if shaft.shape[0] == 0:
        return
    for k in range(br.n):
        rec = shaft[br.b0 + k]
        _reset_evaluation(rec)
        if rec.near == 0 or rec.hi <= rec.lo:
            continue
        for a in range(6):
            for b in range(6):
                sh.D6[k, a, b] = 0.0
        _body_load(br, k, chain, sub, con, sx, res)


@njit(**HOT, inline="always")
def _body_load(br, k, chain, sub, con, sx, res):
    """Body k's normal contacts with every surface (eq 6), then friction (eq 7-10) at the
    deepest one against their resultant."""
    i = br.b0 + k
    rec = con.shaft[i]
    cp = con.cp[0]
    tw = sx.tipw
    sh = sx.sh
    c = chain.pos[i]
    R = chain.rot[i]
    r = rec.radius
    span = max(abs(rec.lo), abs(rec.hi))
    total = 0.0
    r0 = 0.0
    r1 = 0.0
    r2 = 0.0
    touched = 0
    uf = 0.0  # friction's point: the normal forces' mean position on the axis (continuous)
    kk1 = 0.0
    for s in range(con.surf.shape[0]):
        # the gap is 1-Lipschitz: from the centre's, no point of the axis reaches the band (FAR:
        # the centre is outside a baked grid's box, where its ends may still be inside)
        gc = surface_gap(con.surf, s, c, tw.pnrm, tw.pcpt, con.mesh, con.sdf)
        if gc < 0.5 * FAR and gc - span >= r + BAND:
            _candidate(rec, s, r + span - gc, 0.0, tw.pnrm, tw.pcpt)  # a bound (step cap)
            continue
        band, u, gmin, umin = _contact_offset(con, s, c, R, rec, sh)
        if not band:
            _candidate(rec, s, r - gmin, umin, sh.gd, sh.pp)
            continue
        Fn, delta, kk = _normal_contact(br, k, s, u, chain, sub, con, sx)
        if Fn <= 0.0:
            continue
        r0 += sh.F[0]
        r1 += sh.F[1]
        r2 += sh.F[2]
        total += Fn
        touched += 1
        uf += Fn * u
        kk1 = kk
        _apply(k, i, chain, res, u, sh.F, sh, sx.blk)
    rec.fn = total
    fres = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if fres <= 0.0 or (cp.mu_s <= 0.0 and cp.mu_d <= 0.0):
        return
    # friction (eq 7-10) at the material point where the normal forces act on average, in the
    # plane normal to their resultant; the stiction deformation follows that material point
    ubest = uf / total
    tw.nrm[0] = r0 / fres
    tw.nrm[1] = r1 / fres
    tw.nrm[2] = r2 / fres
    _axis_point(c, R, ubest, sh.pt)
    _point_velocity(br, k, ubest, chain, sub, sx, tw.vt)
    for a in range(3):
        rec.pn[a] = sx.s_pos[k, a] + ubest * sx.s_rot[k, a, 0]
        sh.F[a] = 0.0
        for b in range(3):
            sh.K[a, b] = 0.0
    # the friction's coupling to the normal force: exact for one surface, left out for several
    friction_load(sh.pt, fres, kk1 if touched == 1 else 0.0, sub, cp, rec, sh.F, sh.K, tw)
    _apply(k, i, chain, res, ubest, sh.F, sh, sx.blk)


@njit(**HOT)
def _normal_contact(br, k, s, u, chain, sub, con, sx):
    """Eq 6 for body k's contact sphere at u [mm] on its axis against surface s: sh.F <- the
    force [N], sh.K <- its tangent d F / d p [N/mm]; returns (Fn, penetration, normal tangent)
    (Fn = 0: no force).  Keeps the deepest contact in the body's record (``_candidate``)."""
    i = br.b0 + k
    rec = con.shaft[i]
    cp = con.cp[0]
    tw = sx.tipw
    sh = sx.sh
    _axis_point(chain.pos[i], chain.rot[i], u, sh.pt)
    gap = surface_gap(con.surf, s, sh.pt, tw.pnrm, tw.pcpt, con.mesh, con.sdf)
    delta = rec.radius - gap
    _candidate(rec, s, delta, u, tw.pnrm, tw.pcpt)
    if delta <= 0.0:
        return 0.0, delta, 0.0
    _point_velocity(br, k, u, chain, sub, sx, sh.v)
    n = tw.pnrm
    vn = sh.v[0] * n[0] + sh.v[1] * n[1] + sh.v[2] * n[2]
    Fn, kn, cn = normal_law(delta, -vn, cp.k, cp.m1, cp.c, cp.m2, cp.m3)  # eq 6
    if Fn <= 0.0:
        return 0.0, delta, 0.0
    rate = 0.0 if sub.static else sub.c0 * sub.inv_h
    # d(Fn n)/dp = n dFn/dp + Fn dn/dp, dFn/dp = -kn gd - cn (rate n + J^T v)
    normal_rate(con.surf, s, sh.pt, n, gap, con.sdf, sh.J, sh.gd)
    for b in range(3):
        jv = sh.J[0, b] * sh.v[0] + sh.J[1, b] * sh.v[1] + sh.J[2, b] * sh.v[2]
        dfn = -kn * sh.gd[b] - cn * (rate * n[b] + jv)
        for a in range(3):
            sh.K[a, b] = n[a] * dfn + Fn * sh.J[a, b]
    for a in range(3):
        sh.F[a] = Fn * n[a]
    return Fn, delta, kn + cn * rate


@njit(**HOT, inline="always")
def add_shaft_blocks(br, D, sh):
    """D[k] += the shaft contacts' blocks of the last residual evaluation (``shaft_load``)."""
    for k in range(br.n):
        if sh.on[k]:
            for a in range(6):
                for b in range(6):
                    D[k, a, b] += sh.D6[k, a, b]


@njit(**HOT)
def shaft_step_limit(br, chain, con, dq, alpha):
    """Largest fraction (<= alpha) of the Newton correction dq that keeps every evaluated shaft
    contact's penetration below twice the current one (at least PEN_STEP_MIN), along its last
    normal (the tips' ``contact.penetration_step_limit``)."""
    shaft = con.shaft
    if shaft.shape[0] == 0:
        return alpha
    for k in range(br.n):
        i = br.b0 + k
        rec = shaft[i]
        if rec.surf < 0:
            continue
        R = chain.rot[i]
        u = rec.u
        x0 = u * R[0, 0]
        x1 = u * R[1, 0]
        x2 = u * R[2, 0]
        d0 = dq[k, 0] + dq[k, 4] * x2 - dq[k, 5] * x1
        d1 = dq[k, 1] + dq[k, 5] * x0 - dq[k, 3] * x2
        d2 = dq[k, 2] + dq[k, 3] * x1 - dq[k, 4] * x0
        dn = d0 * rec.nrm[0] + d1 * rec.nrm[1] + d2 * rec.nrm[2]
        gap = -rec.pen
        if dn >= 0.0 or gap > -alpha * dn:
            continue
        allow = max(2.0 * max(rec.pen, 0.0), PEN_STEP_MIN)
        a = max((gap + allow) / (-dn), 1e-3)
        if a < alpha:
            alpha = a
    return alpha


@njit(**HOT, inline="always")
def commit_shaft(br, con):
    """Accept the step: every body's stiction deformation and beta (eq 7-10)."""
    shaft = con.shaft
    if shaft.shape[0] == 0:
        return
    for k in range(br.n):
        rec = shaft[br.b0 + k]
        for a in range(3):
            rec.delta[a] = rec.dnew[a]
        rec.beta = rec.bnew


@njit(**HOT)
def broad_phase(bstart, root_p, chain, drive, con, h, g):
    """SHAFT.near <- 1 for every body that can come within the contact band of a surface during
    the solver step of length h [s], else 0.  Both tests pass a body on:

    * **its bristle can reach** (``_bristle_near``): one of the bristle's capsules can come
      within the band by the step's motion;
    * **the body can reach** (``_mark_by_root``): its arc length along the chain from the
      bristle's root (root_p [mm], TCP frame) spans the root's clearance.  A pressed bristle's
      tip body passes, its upper bodies do not (the first test alone passed all six, each then
      checked in every residual evaluation; docs/benchmarks.md).

    g: (3, 3) scratch."""
    if con.shaft.shape[0] == 0:
        return
    for b in range(bstart.shape[0] - 1):
        if _bristle_near(bstart[b], bstart[b + 1], chain, drive, con, h, g):
            _mark_by_root(b, bstart[b], bstart[b + 1], root_p, drive, con, g)
        else:
            for i in range(bstart[b], bstart[b + 1]):
                con.shaft[i].near = 0


@njit(**HOT, inline="always")
def _bristle_near(i0, i1, chain, drive, con, h, g):
    """Can one of the capsules of bodies i0 .. i1-1 come within the contact band of a surface
    during the step?  A body's centre moves at most by the TCP's motion carried to it (rigid:
    translation plus rotation about the TCP over the step, drive rows 1 -> 2) plus
    2 h (|v| + |omega| span) of its own, plus MARGIN; its capsule reaches no further than span
    + radius from the centre, and the surfaces' gaps are 1-Lipschitz."""
    shaft = con.shaft
    surf = con.surf
    pos = chain.pos
    p1 = drive.tcp_p[1]
    p2 = drive.tcp_p[2]
    R1 = drive.tcp_R[1]
    R2 = drive.tcp_R[2]
    # from the tip body up: a pressed bristle's tip body is the one that reaches, and the answer
    # (any body) does not depend on the order
    for i in range(i1 - 1, i0 - 1, -1):
        rec = shaft[i]
        if rec.hi <= rec.lo:
            continue
        span = max(abs(rec.lo), abs(rec.hi))
        # the rigid carry of the centre: p2 + R2 R1^T (c - p1) - c
        mv = 0.0
        for a in range(3):
            x = 0.0
            for q in range(3):
                y = 0.0
                for w in range(3):
                    y += R1[w, q] * (pos[i, w] - p1[w])
                x += R2[a, q] * y
            d = p2[a] + x - pos[i, a]
            mv += d * d
        vv = 0.0
        ww = 0.0
        for a in range(3):
            vv += chain.vel[i, a] ** 2
            ww += chain.omg[i, a] ** 2
        travel = np.sqrt(mv) + 2.0 * h * (np.sqrt(vv) + np.sqrt(ww) * span) + MARGIN
        # SAMPLES points on the axis, each within half their spacing of every axis point
        # (a baked grid is FAR outside its box: a point there tells nothing)
        reach = 0.5 * (rec.hi - rec.lo) / (SAMPLES - 1) + rec.radius + BAND + travel
        for j in range(SAMPLES):
            u = rec.lo + (rec.hi - rec.lo) * j / (SAMPLES - 1)
            _axis_point(pos[i], chain.rot[i], u, g[2])
            for s in range(surf.shape[0]):
                if surface_gap(surf, s, g[2], g[0], g[1], con.mesh, con.sdf) < reach:
                    return True
    return False


@njit(**HOT, inline="always")
def _mark_by_root(b, i0, i1, root_p, drive, con, g):
    """SHAFT.near of bristle b's bodies i0 .. i1-1: 0 where the body cannot touch a surface at
    the step's end whatever the bristle does.  A capsule point lies at most REACH_STRETCH times
    its arc length along the chain from the root (at the TCP's end-of-step pose), and the
    surfaces' gaps are 1-Lipschitz: a body whose farthest capsule point is closer to the root,
    plus radius, band and MARGIN, than the root's clearance cannot reach a surface (unknown
    outside a baked grid's box: passed on)."""
    shaft = con.shaft
    p2 = drive.tcp_p[2]
    R2 = drive.tcp_R[2]
    for a in range(3):
        g[2, a] = (
            p2[a] + R2[a, 0] * root_p[b, 0] + R2[a, 1] * root_p[b, 1] + R2[a, 2] * root_p[b, 2]
        )
    groot = np.inf
    for s in range(con.surf.shape[0]):
        gs = surface_gap(con.surf, s, g[2], g[0], g[1], con.mesh, con.sdf)
        groot = min(groot, gs)
    known = groot < 0.5 * FAR
    arc = 0.0  # [mm] along the chain from the root to the body's proximal node
    for i in range(i0, i1):
        rec = shaft[i]
        half = -rec.lo  # the capsule starts at the proximal node, half a body from the centre
        far = REACH_STRETCH * (arc + half + max(rec.hi, 0.0)) + rec.radius + BAND + MARGIN
        rec.near = 0 if (known and groot > far) or rec.hi <= rec.lo else 1
        arc += 2.0 * half


@njit(**HOT)
def clearance(surf, mesh, sdf, pts, nrm, cpt):
    """Smallest signed distance [mm] of the points pts (n, 3) to the surfaces (inf: none)."""
    best = np.inf
    for j in range(pts.shape[0]):
        for s in range(surf.shape[0]):
            gap = surface_gap(surf, s, pts[j], nrm, cpt, mesh, sdf)
            if gap < best:
                best = gap
    return best
