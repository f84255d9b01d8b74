"""Kernels of the reduced bristle model (``prb.py``): a quasi-static pseudo-rigid-body chain.

Each bristle is a rigid stub of length s0 clamped at its root, then two rigid links (l1, l2)
joined by two bending joints.  Joint i turns its link by a_i about the bristle's local y (the
deflection along local z, the section's thin direction: stiffness from I_y) and then by b_i
about local z (deflection along y: I_z).  Joint 1 also twists everything beyond it by t about
the bristle's axis (torsion, G J): a flat section bent toward its thin side and pushed toward
its wide side turns its bend over instead of bending the stiff way (the full chain twists
~0.2 rad, most of it in the root half; without this joint the reduced chain carried 3x the full
chain's normal force on such a drag: docs/benchmarks.md, ``bench drag``).  In the bristle frame
(x = axis):

    R1 = Rx(t) Ry(a1) Rz(b1),  R2 = R1 Ry(a2) Rz(b2),  tip = s0 e1 + l1 R1 e1 + l2 R2 e1.

The coordinates are q = (a1, b1, a2, b2, t); the chain's factors, in order, are those of
(t, a1, b1, a2, b2) (``_qi``).

The model has no mass: in every solver step of length h it is in equilibrium between the joint
springs (k, calibrated against the rod: ``prb_calibration.py``), the joints' stiffness-
proportional damping (c = beta k, the same damping ratio as the full chain's elements, eq 4-5)
and the load on its tip sphere -- the dead load, the surfaces' eq 6 normal force with the
stick-slip friction of eq 7-10 and the neighbouring tips of Table 3, all from ``contact.tip_load``
(the full model's own tip-load kernel, every surface kind):

    r(q) = K q + (C / h)(q - q_n) - J(q)^T F(tip(q)) = 0,   q = (a1, b1, a2, b2, t),

solved per bristle by Newton with the exact tangent K + C/h - sum_a F_a d2 tip_a/dq2 - J^T Kt J
(the middle term is the geometric stiffness that makes a pressed column buckle).  The joint
angles carry from step to step: the side a bristle buckled to, its snap-through and hysteresis
are those of the mechanism, not of a table.  Tips are solved one after another (one Gauss-Seidel
sweep, partners held where they are, as the ``fast`` full chain's one sweep).
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

from ._kernels import HOT, lu_dense, lus_dense
from .contact import (
    PEN_STEP_MIN,
    in_contact,
    overlap,
    penetration_step_limit,
    presses_on_resultant,
    step10,
    step10_dx,
    tip_load,
)
from .records import ContactScene, Substep
from .surfaces import surface_gap
from .tip_table_kernels import Table
from .tip_table_kernels import lookup as table_lookup

#: the reduced model's kernels: as HOT, strict floating point.  Fast-math (reassociation and
#: fused multiply-add) ran ~11 % faster under random actions but was not deterministic: a
#: process that compiled these kernels gave other results than one that loaded them from the
#: cache (observations of 3 in 5 random episodes differed; ``tests/envs/test_cache_determinism.py``)
PRB = HOT
# Every function below called only from other kernels is ``inline="always"`` (numba inlines it
# into its callers before compiling them) except the few whose call sites would copy a large
# body many times (``_evaluate``, ``solve_bristle``, ``_solve_one``, ``_contact_limit``,
# ``kinematics``): a call between two compiled functions passes the context's many arrays by
# value, and each function compiled on its own costs ~1 s of a cold start.  66 -> 38 kernels
# compiled, 53 -> 43 s CPU for a cold ``gym.make`` + reset + step at ``reduced``, +20-29 % env
# steps/s, results bit for bit unchanged (docs/benchmarks.md, "Inlining the reduced kernels");
# inlining those five too gained 2-8 % more speed for 54-118 s of compile.

#: joint coordinates per bristle: four bending angles and the twist
NQ = 5
#: the bending ones (q[0:4]): the tolerances, the saddle checks and the escape's floor are theirs
NBEND = 4
#: the chain's factors that turn link 1 (Rx(t) Ry(a1) Rz(b1)) and link 2 (all five)
NF1 = 3
#: one bristle's joints (``prb.build_geometry`` fills them from ``prb_calibration``): geo = (s0,
#: l1, l2) [mm] the stub and the links, k (5,) [N mm/rad] the springs (joint 1 about y, about z,
#: joint 2 about y, about z, the twist), beta [s] their damping time, c3 (4,) [1/rad^2] the cubic
#: of each bending spring's torque k (e + c3 e^3), in q's order (the twist's is linear), rest (5,)
#: [rad] their rest angles (e = q - rest)
JOINT = np.dtype(
    [("geo", "f8", 3), ("k", "f8", NQ), ("beta", "f8"), ("c3", "f8", NBEND), ("rest", "f8", NQ)]
)
#: what every kernel of a solver step reads: the joints (JOINT, nb), the step (records.Substep),
#: the contact scene (records.ContactScene), the scratch (prb.py's _Work) and the per-bristle
#: outputs (iters, status, loose)
Ctx = namedtuple("Ctx", ["prm", "sub", "con", "wk", "out", "tab"])
#: the tabulated tip law (``tip_table.py``): the tables' grid (ntab,) ``tip_table_kernels.GRID``,
#: rnat (ntab, nt, np) [mm] and vals (ntab, 2, nr, nt, np) ``ENTRY32``, idx (nb,) each bristle's
#: table (-1: the chain's own Newton), outside (nb,) how many of its steps ended beyond its
#: table, fallback (nb,) how many the table could not take (the chain's Newton took them);
#: scratch: scr (16, 3) (``tip_table_kernels.lookup``'s), m (3, 3, 3), v (6, 3), qv (5,), and
#: the near partner tips of the bristle being solved as a pair list (``_near_partners``):
#: near_ptr (nb + 1,), near_idx (most partners,)
Tab = namedtuple(
    "Tab",
    [
        "grid",
        "rnat",
        "vals",
        "idx",
        "outside",
        "fallback",
        "scr",
        "m",
        "v",
        "qv",
        "near_ptr",
        "near_idx",
    ],
)
#: one bristle's root [mm] and frame in the world, and the weight lumped at its tip [N]
Pose = namedtuple("Pose", ["rw", "B", "gtip"])
#: the brush: roots [mm] and frames in the TCP frame, joints (JOINT)
Geometry = namedtuple("Geometry", ["root_p", "root_R", "prm"])
#: the joint angles now and one solver step before (nb, 4) [rad]
Joints = namedtuple("Joints", ["q", "qp"])
#: every root [mm] and bristle frame in the world at the step's end
Frames = namedtuple("Frames", ["rootpos", "Bw"])
#: largest Newton correction of a joint angle in one iterate [rad] (a longer step is scaled down:
#: keeps a tip that meets a surface from jumping through the penalty range in one iterate)
MAX_DQ = 0.15
#: steps off a saddle (an unstable equilibrium) per bristle and solver step.  4 was too few: a
#: tip stuck on the plate, its bristle bent in an S and then straightened by the TCP turning down
#: at 40 mm/s, came back to the straight saddle after each of them and held 3.6 N (34 N for the
#: brush, a trained policy's episode; tests/envs/test_reduced_saddle.py).  The paper turn and the
#: 20 random episodes of ``bench fidelity`` gave the same numbers with 4 and with 16
MAX_ESCAPES = 16
#: [rad] a bristle whose joints all turn less than this is "straight": only there is a converged
#: equilibrium checked for stability (the saddle of a column pressed along its axis; a bent
#: bristle was followed along its branch from a stable state)
STRAIGHT = 0.005
#: [rad] a converged, pressed bristle whose joints all turn less than this (from straight, not
#: from rest) is checked for stability (``solve_bristle``): the saddle of a leaning column
#: loaded along its links was at 0.005-0.04 rad (random actions, seed 0); a buckled one is at
#: 0.2-1 rad
SADDLE_TURN = 0.1
#: [rad] a pressed bristle whose joints turn less than this from rest keeps to the energy's
#: descent where its conservative tangent is indefinite (``_direction``; all of them, as set)
BUCKLING = 10.0
#: a bristle-step that Newton cannot bring below its tolerance in MAX_ITER iterations (the whole
#: step, or any halving of it) is taken at its best iterate if the residual there is below
#: LOOSE_TOL times the stiffest joint [N mm per N mm/rad]: ~1e-3 N at the tip of a 10 mm
#: bristle (a light sliding contact at the edge of lift-off); counted in
#: ``solver_info()["loose_steps"]``
LOOSE_TOL = 1e-2
#: ... and, for a best iterate whose tip touches nothing, only if no joint's residual is more
#: than LOOSE_TURN [rad] of its own spring.  Why: LOOSE_TOL scales with the stiffest joint, so
#: it let a soft joint sit up to ~0.05 rad off its equilibrium -- more than the rest bend
#: (``prb_calibration.REST_BEND``, 0.02 rad) that, with the drag, picks the buckling side.  A
#: tip grazing the plate in a landing's first 4 ms step ended out of contact with its chain bent
#: 0.013 / 0.021 rad toward the rest side (an iterate had touched), and the bristle buckled onto
#: the stiffening branch: 0.19 N a tip, rising, against the full chain's 0.10 N falling to 0.03
#: (the reference's press on the high plate 4.02 N at ``fast``, 2.58 N with this, 2.15 N at
#: ``balanced``; docs/benchmarks.md, "bench touchdown").  A touching tip keeps LOOSE_TOL alone
#: (a light sliding contact at the edge of lift-off); applied to those too it cost 10 % of the
#: env's speed for the same landing
LOOSE_TURN = 1e-3
#: the same on the smallest halving, the last resort before the step is refused: ~0.1 N at the
#: tip (the stiffest joint over the links' length is ~0.08 N for the default types) -- a light
#: contact (<= 0.1 N) that comes and goes between Newton's iterates at every halving: a tip
#: between a surface and a neighbour's tip, sliding along a tooth row's gum, at the edge of a
#: neighbour's tip (docs/model.md, "ToothRow-v0 at `reduced`").  Counted apart from the loose
#: steps (``solver_info()["rough_steps"]``).  At 0.1 (~1e-2 N) every one of ten scrub-reference
#: episodes on ToothRow-v0 ended on a refused step after 72-213 env steps; at 1.0 one of ten
#: does (a column on its saddle, below), and the steps taken rough were ~2,000 of ~10^6
#: bristle sub-steps with a tip-force imbalance of 0.011 N median, 0.025 N at the 99th
#: percentile, 0.048 N at most, on contacts of 0.01 N median, 0.1 N at most.  The plate's ten
#: random episodes of ``bench episodes`` end at the same steps as with 0.1
ROUGH_TOL = 1.0
#: ... and only with the tip at most this fraction of its radius inside a surface (the penalty
#: law's range, the simulator's PENETRATION_WARN_FRACTION)
LOOSE_PEN = 0.1
#: the iteration count's offset that marks such a step
LOOSE = 1000
#: a bristle-step whose best iterate pushes the tip toward the root harder than this times the
#: softest joint over the links' length [N mm / (N mm/rad)] is never taken loose
#: (``_take_best``).  The fixed-pinned Euler load of the default types is ~11 of it (0.18 N for
#: the inner bristle) and a pressed tip carries about that on the post-buckling plateau; the
#: reference circle at `reduced` (seed 1019, step 51) took 20 straight bristles at 55 of it
#: (0.93 N each, 19 N for the brush, 2 N at `balanced`) as loose steps for one engine step
SADDLE_LOAD = 25.0
#: halvings of a Newton step whose residual rose (``_line_search``)
BACKTRACKS = 4
#: passes of the free bristle's joint-by-joint solve (``_free_step``)
FREE_PASSES = 3
#: a bristle whose step fails is retried in up to 2**MAX_HALVINGS sub-steps (``_halved``)
MAX_HALVINGS = 5
#: passes over the bristles whose tips overlap too far, after the sweep (``step_all``)
TT_PASSES = 2
#: [rad] a free bristle whose joints turned less than this in its last step is settled: when
#: every bristle is, the step is the brush's rigid motion (``_rigid_step``)
SETTLED = 1e-6


@njit(**PRB, inline="always")
def _rot_apply(kind, order, c, s, v, out):
    """out <- Rk(angle)^... : the factor k applied to v, differentiated ``order`` times (0-2);
    kind 0: about y, 1: about z, 2: about x.  d/dt R = R G and d2 R = R G G (G the generator)."""
    w0, w1, w2 = v[0], v[1], v[2]
    if kind == 2:  # generator of x: G v = (0, -v2, v1)
        for _ in range(order):
            w0, w1, w2 = 0.0, -w2, w1
        out[0] = w0
        out[1] = c * w1 - s * w2
        out[2] = s * w1 + c * w2
    elif kind == 0:  # generator of y: G v = (v2, 0, -v0)
        for _ in range(order):
            w0, w1, w2 = w2, 0.0, -w0
        out[0] = c * w0 + s * w2
        out[1] = w1
        out[2] = -s * w0 + c * w2
    else:  # generator of z: G v = (-v1, v0, 0)
        for _ in range(order):
            w0, w1, w2 = -w1, w0, 0.0
        out[0] = c * w0 - s * w1
        out[1] = s * w0 + c * w1
        out[2] = w2


@njit(**PRB, inline="always")
def _qi(f):
    """The coordinate (index into q) of the chain's factor f: factor 0 is the twist (q[4]),
    factors 1-4 the bends (q[0:4])."""
    return NQ - 1 if f == 0 else f - 1


@njit(**PRB, inline="always")
def _kind(f):
    """The axis of the chain's factor f (``_rot_apply``): x, then y, z, y, z."""
    return 2 if f == 0 else (f - 1) % 2


@njit(**PRB, inline="always")
def _c3(c3, i):
    """The cubic of coordinate i's spring: the bending springs' fitted ones, the twist linear."""
    return c3[i] if i < NBEND else 0.0


@njit(**PRB)
def _chain_vec(cs, nf, orders, out, tmp):
    """out <- F_1 F_2 ... F_nf e1 with F_k the k-th factor of the chain (Rx, Ry, Rz, Ry, Rz)
    differentiated orders[k] times; cs (5, 2) the factors' cosines and sines."""
    out[0], out[1], out[2] = 1.0, 0.0, 0.0
    for k in range(nf - 1, -1, -1):
        _rot_apply(_kind(k), orders[k], cs[k, 0], cs[k, 1], out, tmp)
        out[0], out[1], out[2] = tmp[0], tmp[1], tmp[2]


@njit(**PRB)
def kinematics(q, geo, x, J, cs, orders, v, tmp):
    """Tip of one bristle in its local frame x (3,) [mm] and J = dx/dq (3, 5) [mm/rad];
    geo = (s0, l1, l2) [mm].  Leaves the cosines and sines of the chain's factors in cs (5, 2)."""
    for k in range(NQ):
        qk = q[_qi(k)]
        cs[k, 0] = np.cos(qk)
        cs[k, 1] = np.sin(qk)
        orders[k] = 0
    s0, l1, l2 = geo[0], geo[1], geo[2]
    x[0], x[1], x[2] = s0, 0.0, 0.0
    for i in range(NQ):
        for a in range(3):
            J[a, i] = 0.0
    for t in range(2):  # term 1: l1 R1 e1 (factors 0-2); term 2: l2 R2 e1 (factors 0-4)
        nf = NF1 if t == 0 else NQ
        ln = l1 if t == 0 else l2
        _chain_vec(cs, nf, orders, v, tmp)
        for a in range(3):
            x[a] += ln * v[a]
        for i in range(nf):
            orders[i] = 1
            _chain_vec(cs, nf, orders, v, tmp)
            orders[i] = 0
            qi = _qi(i)
            for a in range(3):
                J[a, qi] += ln * v[a]


@njit(**PRB)
def geometric_stiffness(geo, Fl, G, cs, orders, v, tmp):
    """G_ij = sum_a Fl_a d2x_a/dq_i dq_j (5, 5) [N mm] for the local tip load Fl (3,) [N], with
    the cosines and sines cs of ``kinematics``: the load's share of the tangent (negative for a
    column pressed along its axis: what makes it buckle)."""
    for i in range(NQ):
        orders[i] = 0
        for j in range(NQ):
            G[i, j] = 0.0
    for t in range(2):
        nf = NF1 if t == 0 else NQ
        ln = geo[1] if t == 0 else geo[2]
        for i in range(nf):
            orders[i] = 1
            qi = _qi(i)
            for j in range(i, nf):
                orders[j] += 1
                _chain_vec(cs, nf, orders, v, tmp)
                orders[j] -= 1
                g = ln * (Fl[0] * v[0] + Fl[1] * v[1] + Fl[2] * v[2])
                qj = _qi(j)
                G[qi, qj] += g
                if j != i:
                    G[qj, qi] += g
            orders[i] = 0


@njit(**PRB, inline="always")
def _to_world(B, xl, rw, out):
    for a in range(3):
        out[a] = rw[a] + B[a, 0] * xl[0] + B[a, 1] * xl[1] + B[a, 2] * xl[2]


@njit(**PRB)
def root_frames(tcp_p, tcp_R, root_p, root_R, rootw, Bw):
    """Every root in the world (rootw (nb, 3) [mm]) and its bristle frame (Bw (nb, 3, 3))."""
    for j in range(root_p.shape[0]):
        for a in range(3):
            s = tcp_p[a]
            for c in range(3):
                s += tcp_R[a, c] * root_p[j, c]
            rootw[j, a] = s
            for b in range(3):
                t = 0.0
                for c in range(3):
                    t += tcp_R[a, c] * root_R[j, c, b]
                Bw[j, a, b] = t


@njit(**PRB, inline="always")
def _spring(e, c3):
    """(torque / k, its slope) of a joint spring turned by e [rad]: e + c3 e^3 (the fit's cubic),
    continued linearly past the turn where a softening cubic (c3 < 0) has lost half its slope
    (beyond it the cubic would fall to zero torque near 2.8 rad and fold the chain)."""
    if c3 >= 0.0 or e * e <= -0.5 / (3.0 * c3):
        return e * (1.0 + c3 * e * e), 1.0 + 3.0 * c3 * e * e
    em = np.sqrt(-0.5 / (3.0 * c3))
    sg = 1.0 if e > 0.0 else -1.0
    return sg * (em * (1.0 + c3 * em * em) + 0.5 * (abs(e) - em)), 0.5


@njit(**PRB, inline="always")
def _normal_coupling(b, con, wk):
    """(Fn, c): the normal force friction presses against [N] and its coupling to the tip's
    position, -dFn/dx = c v with v left in wk.tw.gd, from the last ``tip_load`` (friction off)
    of a touching tip.  One plane or mesh: the tip's normal force, c = kk = -n^T Kt n, v = n.
    Several or curved surfaces (a tooth row): the resultant R of their normal forces, |R|, with
    c = 1, v = -d|R|/dx (tw.gres), as the full model's friction (``contact._surface_load``): a
    tip wedged between two crowns presses with |R|, not with the sum of its two walls' forces.
    Before (2026-11-26) the sum and kk n were used there too: the friction's tangent did not
    match its force where the walls' normals differ."""
    n = wk.tw.nrm
    v = wk.tw.gd
    if presses_on_resultant(con.surf):
        r = wk.tw.res
        for a in range(3):
            v[a] = wk.tw.gres[a]
        return np.sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]), 1.0
    Kt = wk.Kt
    kk = 0.0
    for a in range(3):
        for c in range(3):
            kk -= n[a] * Kt[a, c] * n[c]
    for a in range(3):
        v[a] = n[a]
    return con.tip_state[b].fn, kk


@njit(**PRB, inline="always")
def _friction(b, x, con, wk, fric):
    """Friction on bristle b's tip at x (world) for a massless tip, as a return mapping: the
    stiction deformation Delta = P_t (Delta_n + x - p_n) (eq 8's, in the contact's tangent plane)
    pulls back with mu Fn g(|Delta| / Delta_max) along Delta (g eq 10's step from 0 to 1); past
    Delta_max the anchor slides (Delta is returned onto |Delta| = Delta_max) and the force is
    mu Fn along the slip, mu = mu_s (1 - beta) + mu_d beta with beta = 1 after a sliding step
    (lagged one step, as ``contact._friction_load``).  This is eq 7-10 without the sliding
    term's dependence on the slip speed (eq 9, v_d = 1.5 mm/s): a tip with no mass has no speed
    of its own within a step -- that term made Newton chatter on every light, sliding contact.
    Adds the force and its tangent (with its dependence on Fn, dFn = -kk n^T dx) to wk.F and
    wk.Kt; stores the trial state (dnew, bnew, ft, slide).  fric = (mu_s, mu_d, Delta_max)."""
    st = con.tip_state[b]
    if st.fn <= 0.0:
        return
    n = wk.tw.nrm
    Kt = wk.Kt
    gc = wk.tw.gd  # with ck: -dFn/dx [N/mm], friction's coupling to the normal force
    fn, ck = _normal_coupling(b, con, wk)
    if fn <= 0.0:
        return
    d = wk.dn3
    for a in range(3):
        d[a] = st.delta[a] + x[a] - st.pn[a]
    dnn = d[0] * n[0] + d[1] * n[1] + d[2] * n[2]
    for a in range(3):
        d[a] -= dnn * n[a]
    dmag = np.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    dmax = fric[2]
    mu = fric[0] * (1.0 - st.beta) + fric[1] * st.beta
    sliding = dmag >= dmax
    st.bnew = 1.0 if sliding else 0.0
    st.slide = 1 if sliding else 0
    if dmag == 0.0:
        for a in range(3):
            st.dnew[a] = 0.0
            st.ft[a] = 0.0
        # the spring's slope at the origin, in the tangent plane
        k0 = mu * fn * step10_dx(0.0, -1.0, -1.0, 1.0, 1.0) / dmax
        for a in range(3):
            for c in range(3):
                Kt[a, c] -= k0 * ((1.0 if a == c else 0.0) - n[a] * n[c])
        return
    u = min(dmag / dmax, 1.0)
    g = step10(u, -1.0, -1.0, 1.0, 1.0)
    f = mu * fn * g  # the force's magnitude
    scale = min(1.0, dmax / dmag)  # the return onto |Delta| = Delta_max
    for a in range(3):
        st.dnew[a] = d[a] * scale
        ft = -f * d[a] / dmag
        st.ft[a] = ft
        wk.F[a] += ft
    # tangent: d(-f u)/dx = -f' u u^T P_t - (f / |Delta|)(P_t - u u^T) - (F_t / Fn) dFn/dx
    fp = 0.0 if sliding else mu * fn * step10_dx(u, -1.0, -1.0, 1.0, 1.0) / dmax
    fr = f / dmag
    for a in range(3):
        ua = d[a] / dmag
        for c in range(3):
            uc = d[c] / dmag
            pac = (1.0 if a == c else 0.0) - n[a] * n[c]
            Kt[a, c] -= fp * ua * uc + fr * (pac - ua * uc)
            Kt[a, c] -= ck * (st.ft[a] / fn) * gc[c]


@njit(**PRB)
def _evaluate(b, q, qn, damp, pose, ctx):
    """Residual wk.s = K (e + c3 e^3) + damp K (q - qn) - J^T F (5,) [N mm] of bristle b at the
    angles q (e = q - q_rest), its tip (wk.x local, wk.xw world), tip load (wk.F world, wk.Fl
    local: ``contact.tip_load`` with the scene's friction off, then ``_friction``) and the load's
    tangent (wk.Kt, world).  Returns max |s|."""
    j = ctx.prm[b]
    geo, kq, c3 = j.geo, j.k, j.c3
    rw, B, gtip = pose.rw, pose.B, pose.gtip
    sub, con, wk = ctx.sub, ctx.con, ctx.wk
    x, xw, J, F, Kt, Fl = wk.x, wk.xw, wk.J, wk.F, wk.Kt, wk.Fl
    kinematics(q, geo, x, J, wk.cs, wk.orders, wk.v, wk.tmp)
    _to_world(B, x, rw, xw)
    tip_load(b, xw, sub, con, F, Kt, wk.tw)
    _friction(b, xw, con, wk, wk.fric)
    for a in range(3):
        F[a] += gtip[a]
    for a in range(3):  # the load in the bristle frame
        Fl[a] = B[0, a] * F[0] + B[1, a] * F[1] + B[2, a] * F[2]
    smax = 0.0
    for i in range(NQ):
        qi = q[i]
        ei = qi - wk.qr[i]  # the spring's turn from its rest angle
        si = kq[i] * (_spring(ei, _c3(c3, i))[0] + damp * (qi - qn[i]))
        for a in range(3):
            si -= J[a, i] * Fl[a]
        wk.s[i] = si
        if abs(si) > smax:
            smax = abs(si)
    return smax


@njit(**PRB, inline="always")
def _tangent(q, geo, kq, c3, damp, B, wk):
    """wk.A <- the Newton matrix K (1 + 3 c3 q^2 + damp) - G - J^T Kt J at the last
    ``_evaluate`` (at q)."""
    geometric_stiffness(geo, wk.Fl, wk.G, wk.cs, wk.orders, wk.v, wk.tmp)
    J, Kt, Ktl, JK, A = wk.J, wk.Kt, wk.Ktl, wk.JK, wk.A
    for a in range(3):  # Kt in the bristle frame, then J^T Kt J
        for c in range(3):
            t = 0.0
            for d in range(3):
                for e in range(3):
                    t += B[d, a] * Kt[d, e] * B[e, c]
            Ktl[a, c] = t
    for a in range(3):
        for i in range(NQ):
            t = 0.0
            for c in range(3):
                t += Ktl[a, c] * J[c, i]
            JK[a, i] = t
    for i in range(NQ):
        for j in range(NQ):
            t = -wk.G[i, j]
            for a in range(3):
                t -= J[a, i] * JK[a, j]
            A[i, j] = t
        ei = q[i] - wk.qr[i]
        A[i, i] += kq[i] * (_spring(ei, _c3(c3, i))[1] + damp)


@njit(**PRB, inline="always")
def _stable(A, S):
    """True if the symmetric part of A (5, 5) is positive definite (Cholesky on S, scratch)."""
    for i in range(NQ):
        for j in range(NQ):
            S[i, j] = 0.5 * (A[i, j] + A[j, i])
    for j in range(NQ):
        d = S[j, j]
        for k in range(j):
            d -= S[j, k] * S[j, k]
        if d <= 0.0:
            return False
        d = np.sqrt(d)
        S[j, j] = d
        for i in range(j + 1, NQ):
            t = S[i, j]
            for k in range(j):
                t -= S[i, k] * S[j, k]
            S[i, j] = t / d
    return True


@njit(**PRB, inline="always")
def _along(q, dq, alpha, out):
    for i in range(NQ):
        out[i] = q[i] + alpha * dq[i]


@njit(**PRB, inline="always")
def _slope(s, dq):
    t = 0.0
    for i in range(NQ):
        t += s[i] * dq[i]
    return t


@njit(**PRB, inline="always")
def _jacobi_rotate(S, V, p, r):
    """One Jacobi rotation zeroing S[p, r] (S <- J^T S J, V <- V J)."""
    if abs(S[p, r]) < 1e-300:
        return
    th = 0.5 * (S[r, r] - S[p, p]) / S[p, r]
    t = (1.0 if th >= 0.0 else -1.0) / (abs(th) + np.sqrt(th * th + 1.0))
    c = 1.0 / np.sqrt(t * t + 1.0)
    sn = t * c
    for k in range(NQ):
        skp, skr = S[k, p], S[k, r]
        S[k, p] = c * skp - sn * skr
        S[k, r] = sn * skp + c * skr
    for k in range(NQ):
        spk, srk = S[p, k], S[r, k]
        S[p, k] = c * spk - sn * srk
        S[r, k] = sn * spk + c * srk
    for k in range(NQ):
        vkp, vkr = V[k, p], V[k, r]
        V[k, p] = c * vkp - sn * vkr
        V[k, r] = sn * vkp + c * vkr


@njit(**PRB, inline="always")
def _sym_min_eig(A, S, V, w):
    """Smallest eigenvalue of the symmetric part of A (5, 5) and its eigenvector (left in w) by
    cyclic Jacobi rotations on S (scratch); V scratch (5, 5)."""
    for i in range(NQ):
        for j in range(NQ):
            S[i, j] = 0.5 * (A[i, j] + A[j, i])
            V[i, j] = 1.0 if i == j else 0.0
    for _ in range(12):
        off = 0.0
        for i in range(NQ):
            for j in range(i + 1, NQ):
                off += S[i, j] * S[i, j]
        if off < 1e-30:
            break
        for p in range(NQ):
            for r in range(p + 1, NQ):
                _jacobi_rotate(S, V, p, r)
    m = 0
    for i in range(1, NQ):
        if S[i, i] < S[m, m]:
            m = i
    for i in range(NQ):
        w[i] = V[i, m]
    return S[m, m]


@njit(**PRB, inline="always")
def _bow_side(q, geo, wk):
    """+1 or -1: the sign of the buckling mode wk.w (5,) that takes the branch of a leaning
    bristle: the elbow (joint 2) moves across the load away from the side the tip stands off the
    load's line through the root.  That is the branch the full chain and the rod take (their tip
    pushes the plate toward the lean; checked in tests/engine/test_prb.py against the full chain,
    bristle by bristle, for a pressed brush), and the one Newton finds from a bristle pressed
    slowly enough to bend before it is compressed past its buckling load.  With no offset at
    all (a perfectly straight bristle pressed along its axis), the side q already leans to."""
    Fl = wk.Fl
    fm = np.sqrt(Fl[0] * Fl[0] + Fl[1] * Fl[1] + Fl[2] * Fl[2])
    if fm == 0.0:
        return 1.0
    u0, u1, u2 = Fl[0] / fm, Fl[1] / fm, Fl[2] / fm
    x = wk.x  # the tip, bristle frame (root at the origin)
    xu = x[0] * u0 + x[1] * u1 + x[2] * u2
    o0, o1, o2 = x[0] - xu * u0, x[1] - xu * u1, x[2] - xu * u2
    # the elbow's motion along w: l1 d(R1 e1)/dq . w, i.e. J's first link part
    l1 = geo[1]
    e0 = e1 = e2 = 0.0
    for i in range(NF1):
        for f in range(NF1):
            wk.orders[f] = 0
        wk.orders[i] = 1
        _chain_vec(wk.cs, NF1, wk.orders, wk.v, wk.tmp)
        wi = wk.w[_qi(i)]
        e0 += l1 * wk.v[0] * wi
        e1 += l1 * wk.v[1] * wi
        e2 += l1 * wk.v[2] * wi
    for f in range(NF1):
        wk.orders[f] = 0
    eo = e0 * o0 + e1 * o1 + e2 * o2
    if abs(eo) > 1e-12 * l1 * l1:
        return -1.0 if eo > 0.0 else 1.0
    return 1.0 if _slope(q, wk.w) >= 0.0 else -1.0


@njit(**PRB, inline="always")
def _escape(q, s, A, kq, geo, wk, dq, push):
    """dq <- a step off a saddle when the Newton matrix is not positive definite (a column
    pressed past its buckling load, held straight by the last Newton iterates): the saddle-free
    Newton step -sum_m v_m (v_m . s) / max(|lam_m|, floor) over the eigenpairs of A's symmetric
    part (Newton along the stable modes, down the energy along the unstable ones, never back up
    onto the saddle), plus, with ``push`` (at the saddle itself, where s ~ 0), a move along the
    direction of negative curvature to the side ``_bow_side`` picks.  Returns the smallest
    eigenvalue (>= 0: A is fine, dq untouched)."""
    lam = _sym_min_eig(A, wk.S, wk.V, wk.w)
    if lam >= 0.0:
        return lam
    # the floor keeps a mode near its buckling load (lam ~ 0) from a step beyond MAX_DQ
    floor = 1e-2 * max(kq[0], kq[1], kq[2], kq[3])
    for i in range(NQ):
        dq[i] = 0.0
    for m in range(NQ):
        vs = 0.0
        for i in range(NQ):
            vs += wk.V[i, m] * s[i]
        c = vs / max(abs(wk.S[m, m]), floor)
        for i in range(NQ):
            dq[i] -= c * wk.V[i, m]
    if push:
        # the side is the geometry's (``_bow_side``), not the residual's: a tip that meets the
        # plate within a step loads the straight column at once, and its residual's component
        # along the mode (friction, the penetration) would pick the side by accident
        sign = _bow_side(q, geo, wk)
        along = _slope(dq, wk.w)
        for i in range(NQ):
            dq[i] += (sign * 0.5 * MAX_DQ - along) * wk.w[i]
    return lam


@njit(**PRB, inline="always")
def _direction(b, q, geo, kq, B, con, wk, dq, escape, push):
    """dq <- the Newton direction -A^-1 s from wk.A (kept in wk.A2), or, with ``escape`` and A
    not positive definite, the step off the saddle (``_escape``).  Returns (ok, escaped)."""
    for i in range(NQ):
        dq[i] = -wk.s[i]
        for j in range(NQ):
            wk.A2[i, j] = wk.A[i, j]
    if not lu_dense(wk.A, NQ, wk.piv):
        return False, False
    lus_dense(wk.A, NQ, wk.piv, dq)
    if escape:
        _conservative_part(b, con, B, wk)
        if not _stable(wk.A2, wk.S):
            return True, _escape(q, wk.s, wk.A2, kq, geo, wk, dq, push) < 0.0
    return True, False


@njit(**PRB, inline="always")
def _conservative_part(b, con, B, wk):
    """wk.A2 <- the Newton matrix without friction's dependence on the normal force (the rank-one
    term -F_t g^T / F_n of ``_friction``, ``_normal_coupling``): what is left is the
    tangent of an energy (springs, the load's geometric stiffness, the normal contact, the
    stiction spring and the sliding force's turn), whose definiteness says whether the
    equilibrium is stable.  (The coupling's symmetric part is indefinite, of the order of the
    penalty stiffness, and would flag every pressed tip.)"""
    st = con.tip_state[b]
    if st.fn <= 0.0:
        return
    fn, ck = _normal_coupling(b, con, wk)
    g = wk.tw.gd
    if fn <= 0.0 or ck <= 0.0:
        return
    for a in range(3):  # the friction force and the coupling in the bristle frame, through J
        wk.tmp[a] = B[0, a] * st.ft[0] + B[1, a] * st.ft[1] + B[2, a] * st.ft[2]
        wk.v[a] = B[0, a] * g[0] + B[1, a] * g[1] + B[2, a] * g[2]
    c = ck / fn
    for i in range(NQ):
        fi = wk.J[0, i] * wk.tmp[0] + wk.J[1, i] * wk.tmp[1] + wk.J[2, i] * wk.tmp[2]
        for j in range(NQ):
            nj = wk.J[0, j] * wk.v[0] + wk.J[1, j] * wk.v[1] + wk.J[2, j] * wk.v[2]
            wk.A2[i, j] -= c * fi * nj


@njit(**PRB, inline="always")
def _partner_limit(b, x, dp, R, con, amax, pmin):
    """The fraction (at most amax) of the tip step dp from x [mm] that keeps the tip out of every
    partner tip by more than twice its overlap now (at least pmin [mm]), along the whole
    straight path (a ray against the partner's sphere).  ``penetration_step_limit`` looks along
    the line of centres only: a massless tip springing back ~1 mm in one iterate passed across
    that line and landed 0.6 mm inside its neighbour's tip (random actions, seed 10), where the
    Table 3 push runs along both bristles' links and nothing gives."""
    tips = con.tips
    ptr = con.pair_ptr
    if ptr.shape[0] <= b + 1:
        return amax
    aa = dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2]
    if aa == 0.0:
        return amax
    for q in range(ptr[b], ptr[b + 1]):
        j = con.pair_idx[q]
        d0, d1, d2 = x[0] - tips[j, 0], x[1] - tips[j, 1], x[2] - tips[j, 2]
        dd = d0 * d0 + d1 * d1 + d2 * d2
        rs = R + tips[j, 6]
        gap = np.sqrt(dd) - rs
        rt = rs - max(2.0 * max(-gap, 0.0), pmin)  # the closest the centres may come
        c = dd - rt * rt
        if c <= 0.0:
            continue
        bb = 2.0 * (dp[0] * d0 + dp[1] * d1 + dp[2] * d2)
        disc = bb * bb - 4.0 * aa * c
        if bb >= 0.0 or disc < 0.0:  # moving away, or the path misses the sphere
            continue
        a = (-bb - np.sqrt(disc)) / (2.0 * aa)
        if a < amax:
            amax = max(a, 0.0)
    return amax


@njit(**PRB)
def _contact_limit(b, B, dq, con, wk):
    """The fraction of the joint step dq that the tip's (linearised) step wk.dp = B J dq may take
    from wk.xw (J in wk.J): the full model's penetration limit and ``_partner_limit``."""
    for a in range(3):
        t = 0.0
        for i in range(NQ):
            t += wk.J[a, i] * dq[i]
        wk.tmp[a] = t
    dp = wk.dp
    for a in range(3):
        dp[a] = B[a, 0] * wk.tmp[0] + B[a, 1] * wk.tmp[1] + B[a, 2] * wk.tmp[2]
    R = con.tip_args[b].radius
    a_pen = penetration_step_limit(b, wk.xw, dp, R, con, wk.tw, PEN_STEP_MIN)
    return _partner_limit(b, wk.xw, dp, R, con, a_pen, PEN_STEP_MIN)


@njit(**PRB, inline="always")
def _step_limit(b, B, dq, static, sub, con, wk, leaving):
    """(fraction of dq to take, max |dq|, held): the cap MAX_DQ on the angles, the full model's
    contact limits on the tip's (linearised) step (``penetration_step_limit``,
    ``slip_step_limit``) and their mirror for a tip leaving its surface (held: it was held back;
    ``leaving``: it was held back the iterate before, and goes now)."""
    dmax = 0.0
    for i in range(NQ):
        dmax = max(dmax, abs(dq[i]))
    alpha = 1.0 if dmax <= MAX_DQ else MAX_DQ / dmax
    a_pen = _contact_limit(b, B, dq, con, wk)
    alpha, held = _tip_limits(b, alpha, a_pen, con, wk, leaving)
    return alpha, dmax, held


@njit(**PRB, inline="always")
def _tip_limits(b, alpha, a_pen, con, wk, leaving):
    """(alpha, held): the fraction alpha of the tip step wk.dp from wk.xw cut to the contact
    limit a_pen (``_contact_limit``) and, for a touching tip, to leave its surface and its
    partners at most halfway per iterate (``_step_limit``; the tabulated law's step too)."""
    if a_pen < alpha:
        alpha = max(a_pen, 1e-3)
    dp = wk.dp
    st = con.tip_state[b]
    if st.fn > 0.0 and st.pen > 0.0 and not leaving:
        # a touching tip leaves its surface at most halfway per iterate (the mirror of the
        # penetration limit): Newton's tangent inside the contact holds its stiffness, outside
        # none, and an iterate thrown out comes back deep in -- the contact's on/off cycle.  A
        # second iterate in a row that wants out goes (the tip lifts off).  Halfway of the
        # geometric overlap: the chain's tip is out when the axial compression is undone too
        nrm = wk.tw.nrm
        dn = dp[0] * nrm[0] + dp[1] * nrm[1] + dp[2] * nrm[2]  # > 0: out of the surface
        over = overlap(con.tip_args[b], st, nrm)
        if dn * alpha > 0.5 * over:
            return 0.5 * over / dn, True
    if st.ftt > 0.0 and not leaving:
        # ... and its partner tips likewise (Table 3's law has no stiffness at first touch: out
        # of the partner, Newton heads for the relaxed pose, the penetration limit stops it 2 um
        # inside, and from there it jumped back out -- until it gave up, random actions seed 8)
        held = False
        for q in range(con.pair_ptr[b], con.pair_ptr[b + 1]):
            j = con.pair_idx[q]
            d0, d1, d2 = (
                wk.xw[0] - con.tips[j, 0],
                wk.xw[1] - con.tips[j, 1],
                wk.xw[2] - con.tips[j, 2],
            )
            dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            over = con.tip_args[b].radius + con.tips[j, 6] - dist
            if over <= 0.0 or dist < 1e-12:
                continue
            dn = (dp[0] * d0 + dp[1] * d1 + dp[2] * d2) / dist  # > 0: out of the partner
            if dn * alpha > 0.5 * over:
                alpha = 0.5 * over / dn
                held = True
        if held:
            return alpha, True
    return alpha, False


@njit(**PRB, inline="always")
def _line_search(b, q, qn, damp, pose, ctx, dq, alpha, smax0, descend):
    """Move to q + alpha dq if the residual falls there (max |s| below smax0, the current one)
    and ``descend`` is False; else, where the slope g(a) = dq . s(q + a dq) turned positive, to
    the energy's minimum along dq (regula falsi, Illinois), or back off by halving.
    ``descend``: off a saddle, where a falling residual may lead straight back to it (its
    residual is zero), only the energy counts.  The last evaluation is at the returned point.
    Returns (alpha taken, max |s| there)."""
    wk = ctx.wk
    qt = wk.qt2
    g0 = _slope(wk.s, dq)
    _along(q, dq, alpha, qt)
    smax = _evaluate(b, qt, qn, damp, pose, ctx)
    g1 = _slope(wk.s, dq)
    if smax < smax0 and not descend:
        return alpha, smax  # the residual fell (Newton's quadratic step)
    if g0 < 0.0 and g1 <= 0.0 and alpha < 1.0:
        # a step cut short by a contact limit (a tip meeting a surface or a partner tip) with
        # the energy still falling at its end: taken, though the residual rose -- the contact
        # has just begun to push, and backing off to where it did not kept a tip at the edge
        # of a partner's, in and out of it, until Newton gave up (random actions, seed 8)
        return alpha, smax
    if not (g0 < 0.0 and g1 > 0.0):
        # no minimum to find along dq, and the residual rose: back off (halving), keeping the
        # best point (a tip thrown across the edge of a contact, where the tangent of one side
        # says nothing of the other)
        best_a, best_s = alpha, smax
        a_try = alpha
        for _ in range(BACKTRACKS):
            a_try *= 0.5
            _along(q, dq, a_try, qt)
            s_try = _evaluate(b, qt, qn, damp, pose, ctx)
            if s_try < best_s:
                best_a, best_s = a_try, s_try
            if s_try < smax0:
                break
        if best_a != a_try:  # leave the last evaluation at the point returned
            _along(q, dq, best_a, qt)
            best_s = _evaluate(b, qt, qn, damp, pose, ctx)
        return best_a, best_s
    lo, glo, hi, ghi = 0.0, g0, alpha, g1
    side = 0
    for _ in range(12):
        alpha = lo - glo * (hi - lo) / (ghi - glo)
        _along(q, dq, alpha, qt)
        smax = _evaluate(b, qt, qn, damp, pose, ctx)
        g = _slope(wk.s, dq)
        if abs(g) <= 0.1 * abs(g0):
            break
        if g > 0.0:
            hi, ghi = alpha, g
            if side == 1:
                glo *= 0.5
            side = 1
        else:
            lo, glo = alpha, g
            if side == -1:
                ghi *= 0.5
            side = -1
    return alpha, smax


@njit(**PRB)
def solve_bristle(b, q, qn, pose, ctx, loose):
    """Quasi-static equilibrium of bristle b (module docstring) from the guess q (4,), updated
    in place; qn the joint angles at the step start; ``pose`` its root, frame and tip weight;
    the step (``ctx.sub``): h, static, maxit, rtol (the tolerance on the angles [rad]).

    Newton with the full model's safeguards (``newton.py``): the step is capped (``_step_limit``)
    and searched along (``_line_search``), which stops the limit cycle of a tip thrown in and out
    of the stiff penalty contact.  Converged when the residual is below tol times the stiffest
    joint, or the step below tol; an equilibrium whose tangent is not positive definite (a
    column held straight past its buckling load) is left along its negative curvature
    (``_escape``, at most MAX_ESCAPES times).  Leaves the tip (world) in wk.xw and its load in
    wk.F at the returned q.  Returns the Newton iterations, or -1 if it did not converge.

    ``loose`` > 0: if Newton has not converged after maxit iterations, the iterate with the
    smallest residual is taken when that residual is below loose times the stiffest joint
    [N mm] (a light, sliding contact at the edge of lift-off, where the contact's on/off and
    friction's turn keep Newton from converging; returns maxit + LOOSE, counted by the caller)."""
    j = ctx.prm[b]
    geo, kq, c3 = j.geo, j.k, j.c3
    sub, con, wk = ctx.sub, ctx.con, ctx.wk
    B = pose.B
    static, maxit, tol = sub.static, sub.maxit, sub.rtol
    for i in range(NQ):
        wk.qr[i] = j.rest[i]
    damp = 0.0 if static else j.beta / sub.h
    ftol = tol * max(kq[0], kq[1], kq[2], kq[3])
    kmin = min(kq[0], kq[1], kq[2], kq[3])
    lsum = geo[1] + geo[2]
    dq = wk.dq
    escapes = 0
    small = False  # the last step was below tol
    stalls = 0  # modified Newton steps cut below 1 % by the line search
    held = False  # the last step was held back from leaving a contact
    smax = _evaluate(b, q, qn, damp, pose, ctx)
    best = np.inf
    for it in range(1, maxit + 1):
        if not np.isfinite(smax):
            return -1
        if smax < best:
            best = smax
            for i in range(NQ):
                wk.qb[i] = q[i]
        converged = smax <= ftol or small
        # a converged bristle whose tip is pressed toward its root may sit on a saddle: its links
        # in line with the load (a column with no axial give holds any load there -- straight,
        # or leaning with its tip held by stiction), so nearly straight in its own frame (a bent
        # chain's elbow is off the load's line, and its springs bound the load); checked when the
        # axial load is past a tenth of the softest joint's over the bristle's length (the
        # buckling loads are ~1)
        # ... and whatever its bend, when it carries more than SADDLE_LOAD: the shipped PPO
        # policy at `reduced` (seed 1019, step 154) met nine bristles converged at 0.1 rad, just
        # past SADDLE_TURN, with up to 1.7 N on a tip (9x the Euler load), 15.5 N for the brush
        axial = -wk.Fl[0] * lsum
        check = (
            converged
            and escapes < MAX_ESCAPES
            and axial > 0.1 * kmin
            and (
                max(abs(q[0]), abs(q[1]), abs(q[2]), abs(q[3])) < SADDLE_TURN
                or _past_saddle_load(j, wk.Fl)
            )
        )
        if converged and not check:
            return it
        _tangent(q, geo, kq, c3, damp, B, wk)
        # a tip pressed toward its root: wherever the conservative tangent is indefinite (past
        # a buckling load) Newton takes the shifted, positive definite one and the energy's line
        # search (plain Newton heads for the nearest equilibrium: back onto the saddle, or over
        # to the other side's branch); at a converged straight one, it steps off the saddle
        turn = 0.0
        for i in range(NQ):
            turn = max(turn, abs(q[i] - wk.qr[i]))
        pressed = wk.Fl[0] < 0.0 and turn < BUCKLING and (stalls < 2 or converged)
        # on the saddle itself (straight, or converged) the step also moves along the mode
        push = pressed and (turn < STRAIGHT or converged) and escapes < MAX_ESCAPES
        ok, modified = _direction(b, q, geo, kq, B, con, wk, dq, pressed, push)
        if not ok:
            return -1
        if converged and not modified:
            return it
        escapes += int(modified and push)
        alpha, dmax, held = _step_limit(b, B, dq, static, sub, con, wk, held)
        alpha, smax = _line_search(b, q, qn, damp, pose, ctx, dq, alpha, smax, modified)
        for i in range(NQ):
            q[i] = wk.qt2[i]
        small = dmax * alpha < tol and not modified
        # the energy's descent stalls where friction, not an energy, shapes the tangent (a
        # sliding tip on a bent bristle): plain Newton from then on
        stalls += int(modified and alpha < 1e-2)
    if smax < best:
        best = smax
        for i in range(NQ):
            wk.qb[i] = q[i]
    kmax = max(kq[0], kq[1], kq[2], kq[3])
    within = best <= loose * kmax
    if loose > 0.0 and _take_best(b, q, qn, damp, pose, ctx, within, loose < ROUGH_TOL):
        if best > LOOSE_TOL * kmax:  # taken only by the last resort (ROUGH_TOL)
            ctx.out.rough[b] += 1
        return maxit + LOOSE
    return -1


@njit(**PRB, inline="always")
def _past_saddle_load(j, Fl):
    """True if the local tip load Fl [N] pushes the tip of the bristle with joints j toward its
    root harder than SADDLE_LOAD times its softest bending joint over the links' length."""
    k, geo = j.k, j.geo
    return -Fl[0] * (geo[1] + geo[2]) > SADDLE_LOAD * min(k[0], k[1], k[2], k[3])


@njit(**PRB, inline="always")
def _take_best(b, q, qn, damp, pose, ctx, small, fine):
    """After Newton ran out: q <- the best iterate (ctx.wk.qb) if its residual was ``small``, its
    contact shallow and its push along the bristle below SADDLE_LOAD (a force along the links
    turns no joint, so a tip deep in a surface, or a column held straight far past its buckling
    load, leaves a small residual) and, with ``fine`` (LOOSE_TOL, not the last resort), a tip
    that touches nothing there has every joint within LOOSE_TURN of its equilibrium; True if
    taken."""
    if not small:
        return False
    for i in range(NQ):
        q[i] = ctx.wk.qb[i]
    _evaluate(b, q, qn, damp, pose, ctx)
    con = ctx.con
    if _past_saddle_load(ctx.prm[b], ctx.wk.Fl):
        return False
    if fine and not in_contact(con.tip_state[b]):
        kq = ctx.prm[b].k
        for i in range(NQ):
            if abs(ctx.wk.s[i]) > LOOSE_TURN * kq[i]:
                return False
    return con.tip_state[b].pen <= LOOSE_PEN * con.tip_args[b].radius


@njit(**PRB, inline="always")
def _free_step(b, pose, ctx):
    """The step of a bristle that touches nothing: every joint on its own, e + c3 e^3 +
    damp (q - q_n) = g / k (e = q - q_rest, g the torque of the weight lumped at the tip), solved
    by scalar Newton with g from the last pass (FREE_PASSES passes: the weight is ~1e-4 N, its
    coupling between the joints ~1e-3 of their springs).  The tip's load is evaluated at the
    result; if anything touches it (a surface, a partner tip, a dead load) nothing is kept and
    False is returned (the bristle is solved by Newton).  Costs a few tip positions and one
    contact evaluation instead of Newton's tangents; tests/engine/test_prb.py checks it against
    Newton."""
    j = ctx.prm[b]
    geo, c3 = j.geo, j.c3
    rw, B, gtip = pose.rw, pose.B, pose.gtip
    sub, con, wk = ctx.sub, ctx.con, ctx.wk
    damp = j.beta / sub.h
    x, xw, J, F = wk.x, wk.xw, wk.J, wk.F
    for a in range(3):
        wk.Fl[a] = B[0, a] * gtip[0] + B[1, a] * gtip[1] + B[2, a] * gtip[2]
    for i in range(NQ):
        wk.qr[i] = j.rest[i]
        wk.qt[i] = wk.qn[i]
    for _ in range(FREE_PASSES):
        kinematics(wk.qt, geo, x, J, wk.cs, wk.orders, wk.v, wk.tmp)
        for i in range(NQ):
            g = (J[0, i] * wk.Fl[0] + J[1, i] * wk.Fl[1] + J[2, i] * wk.Fl[2]) / j.k[i]
            en = wk.qn[i] - wk.qr[i]
            ei = wk.qt[i] - wk.qr[i]
            for _ in range(3):
                t, dt = _spring(ei, _c3(c3, i))
                ei -= (t + damp * (ei - en) - g) / (dt + damp)
            wk.qt[i] = ei + wk.qr[i]
    kinematics(wk.qt, geo, x, J, wk.cs, wk.orders, wk.v, wk.tmp)
    _to_world(B, x, rw, xw)
    tip_load(b, xw, sub, con, F, wk.Kt, wk.tw)
    st = con.tip_state[b]
    if st.fn > 0.0 or st.ftt > 0.0 or F[0] != 0.0 or F[1] != 0.0 or F[2] != 0.0:
        return False
    for a in range(3):
        F[a] = gtip[a]
    return True


@njit(**PRB, inline="always")
def _frame_at(b, s, rw0, B0, rw1, B1, rw, B):
    """The root (rw [mm]) and frame (B) of bristle b at the fraction s of the step: linear
    between its start and end, the frame's columns re-orthonormalised (Gram-Schmidt)."""
    for a in range(3):
        rw[a] = rw0[b, a] + s * (rw1[b, a] - rw0[b, a])
        for c in range(3):
            B[a, c] = B0[b, a, c] + s * (B1[b, a, c] - B0[b, a, c])
    for c in range(3):
        for d in range(c):
            t = B[0, c] * B[0, d] + B[1, c] * B[1, d] + B[2, c] * B[2, d]
            for a in range(3):
                B[a, c] -= t * B[a, d]
        t = np.sqrt(B[0, c] * B[0, c] + B[1, c] * B[1, c] + B[2, c] * B[2, c])
        for a in range(3):
            B[a, c] /= t


@njit(**PRB, inline="always")
def _halved(b, ctx, gtip, x0, frames):
    """Bristle b's step as 2, 4, ... 2**MAX_HALVINGS equal sub-steps (the root moving linearly
    through them) after the whole step failed: the joints' damping (C / h) grows as the step
    shrinks, which carries the bristle through a snap (a tip torn off its stiction and slipping
    far, a bristle springing back) that has no equilibrium near the last one.  Each sub-step
    commits its stiction state, as a shorter step would.  Leaves the result in wk.qt (and the
    tip and load as ``solve_bristle``); returns the iterations, or -1.  The root moves from
    (ctx.wk.rp0, ctx.wk.B0) to (frames.rootpos, frames.Bw); x0 the tip at the step's start."""
    sub, wk = ctx.sub, ctx.wk
    st = ctx.con.tip_state[b]
    rw0, B0, rw1, B1 = wk.rp0, wk.B0, frames.rootpos, frames.Bw
    pose = Pose(wk.rws, wk.Bs, gtip)
    for lev in range(1, MAX_HALVINGS + 1):
        m = 1 << lev
        hs = sub.h / m
        subk = Substep(1.0, -1.0, 0.0, hs, 1.0 / hs, False, sub.g, sub.rtol, sub.maxit, sub.jage)
        ctxk = Ctx(ctx.prm, subk, ctx.con, wk, ctx.out, ctx.tab)
        for a in range(3):  # back to the step's start
            st.delta[a] = wk.d0[a]
            wk.xs[a] = x0[a]
        st.beta = wk.d0[3]
        for i in range(NQ):
            wk.qs[i] = wk.qn[i]
        iters = 0
        for k in range(1, m + 1):
            _frame_at(b, k / m, rw0, B0, rw1, B1, wk.rws, wk.Bs)
            for a in range(3):
                st.pn[a] = wk.xs[a]
                st.hist[a] = 0.0  # backward Euler: v = (p - p_n) / h
            for i in range(NQ):
                wk.qt[i] = wk.qs[i]
            loose = LOOSE_TOL if lev < MAX_HALVINGS else ROUGH_TOL
            n = solve_bristle(b, wk.qt, wk.qs, pose, ctxk, loose)
            if n < 0:
                iters = -1
                break
            iters += n
            for a in range(3):
                st.delta[a] = st.dnew[a]
                wk.xs[a] = wk.xw[a]
            st.beta = st.bnew
            for i in range(NQ):
                wk.qs[i] = wk.qt[i]
        if iters >= 0:
            return iters
    return -1


#: [mm per mm of the links] the longest step of the tabulated law's tip Newton per iterate
TAB_MAX_DX = 0.05
#: the links' axial stiffness past their reach, in the stiffest joint over the links' length
#: squared: the chain is inextensible, the table ends there (a stretch of ~1e-3 mm per 0.1 N)
TAB_AXIAL = 1e3


#: [rad] a branch's joint angles that move further than this from the last iterate's are checked
#: against the other branch's (``_table_branch``)
TAB_JUMP = 0.02


#: [mm] the tabulated law's step lists the partner tips within R + R_j + 2 TAB_NEAR of a point
#: x_ref (``_near_partners``) and uses that list while its tip stays within TAB_NEAR of x_ref and
#: its Newton step is at most TAB_NEAR long: no other partner can then touch the tip or limit the
#: step (each is farther than R + R_j + TAB_NEAR from every point of it), so the list changes
#: no result.  The pair list holds 23 partners per tip for the default brush, ~3 within reach
TAB_NEAR = 0.5
#: [mm] the penetration a Newton iterate of the tabulated law may always reach from outside a
#: surface or partner tip (the chain's PEN_STEP_MIN is 2e-3).  A light sliding contact cycled:
#: the free tip's step, headed for an equilibrium below the plate, was cut 2 um deep (~0.03 N on
#: the plate, against the ~1e-3 N it carries), the next step from there left the plate, and round
#: again until the iterates ran out -- most of the chain fallbacks.  0.2 um: 1.62 -> 1.30
#: fallbacks per random env step (5e-5 mm: 1.32, 5e-4: 1.34), docs/benchmarks.md (2026-11-27)
TAB_PEN_MIN = 2e-4
#: [-] the tabulated law's dynamic step is converged when its largest force residual is below
#: TAB_FTOL times the stiffest joint over the links' length (kmax / L: 0.06-0.19 N for the default
#: brush's bristles, so 0.06-0.19 mN: 0.1 % of the per-tip force limit of the envs, 0.2 N).  The
#: chain's angle tolerance (ANGLE_TOL, 1e-8, as a force ~1e-9 N) made most touching steps take a
#: third lookup only to confirm the second: iterates per touching step 4.02 -> 2.62 under random
#: actions, the errors against `reference` within 0.1 percentage point of before
#: (docs/benchmarks.md, 2026-11-27).  A static solve keeps the strict tolerance.
TAB_FTOL = 1e-3


@njit(**PRB, inline="always")
def _near_partners(b, x, con, tab):
    """tab.near_idx[0:n] <- the partner tips of bristle b within R_b + R_j + 2 TAB_NEAR [mm] of
    x, tab.near_ptr[b:b+2] <- (0, n); returns the contact scene whose pair list is that
    (``TAB_NEAR``)."""
    ptr, tips = con.pair_ptr, con.tips
    n = 0
    if ptr.shape[0] > b + 1:
        R = con.tip_args[b].radius
        for q in range(ptr[b], ptr[b + 1]):
            j = con.pair_idx[q]
            d0, d1, d2 = x[0] - tips[j, 0], x[1] - tips[j, 1], x[2] - tips[j, 2]
            reach = R + tips[j, 6] + 2.0 * TAB_NEAR
            if d0 * d0 + d1 * d1 + d2 * d2 < reach * reach:
                tab.near_idx[n] = j
                n += 1
    tab.near_ptr[b] = 0
    tab.near_ptr[b + 1] = n
    return ContactScene(
        con.surf,
        con.cp,
        con.tips,
        tab.near_ptr,
        tab.near_idx,
        con.mesh,
        con.tip_args,
        con.tip_state,
        con.sdf,
        con.shaft,
    )


@njit(**PRB, inline="always")
def _table_branch(tb, xl, qprev, s0, tab, g, Jg, D):
    """(s, w, out): the branch of table tb (``tip_table_kernels``) to follow from the joint angles
    qprev (on branch s0, or -1: unknown) with the tip at xl -- of those that exist there, the one
    whose joint angles are nearest (the chain follows its branch continuously: a branch's elbow may
    cross the chord, where both hold the same configuration, and a side chosen by the elbow alone
    would then jump); if none exists, the one with most of its cell (s = -1: no branch at all).
    Branch s0 is kept without looking at the other while it exists and its angles move less than
    TAB_JUMP. Leaves the branch's values in g, Jg, D and its joint angles in qprev."""
    qv = tab.qv
    if s0 >= 0:
        w, out, _ = table_lookup(tb, s0, xl, g, Jg, D, qv, True, tab.scr)
        d = 0.0
        for i in range(NQ):
            d = max(d, abs(qv[i] - qprev[i]))
        if w >= 0.5 and d < TAB_JUMP:
            for i in range(NQ):
                qprev[i] = qv[i]
            return s0, w, out
    best, pick = np.inf, -1
    wbest = 0.0
    for s in range(2):
        w, _, _ = table_lookup(tb, s, xl, g, Jg, D, qv, True, tab.scr)
        if w <= 0.0:
            continue
        d = 0.0
        for i in range(NQ):
            d = max(d, abs(qv[i] - qprev[i]))
        if (w >= 0.5 and (wbest < 0.5 or d < best)) or (wbest < 0.5 and w > wbest):
            best, pick, wbest = d, s, w
    if pick < 0:
        return -1, 0.0, 0
    w, out, _ = table_lookup(tb, pick, xl, g, Jg, D, qprev, True, tab.scr)
    return pick, w, out


@njit(**PRB, inline="always")
def _axial_penalty(xl, s0, rcap, kax, g, Jg, u):
    """Past the table's longest chord rcap [mm]: g, Jg += the stiff axial spring kax [N/mm] that
    holds the tip at it (the chain is inextensible); u (3,) scratch."""
    u0, u1, u2 = xl[0] - s0, xl[1], xl[2]
    rho = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    ext = rho - rcap
    u[0], u[1], u[2] = u0 / rho, u1 / rho, u2 / rho
    for a in range(3):
        g[a] += kax * ext * u[a]
        for c in range(3):
            dac = 1.0 if a == c else 0.0
            Jg[a, c] += kax * (u[a] * u[c] + ext / rho * (dac - u[a] * u[c]))


@njit(**PRB, inline="always")
def _table_residual(b, pose, ctx, xln, damp):
    """max |r| of r = F_load(x) - B (g + damp D (xl - xln)) at the tip wk.xw (world; xl, g, Jg,
    D as left by the lookup): the tip load (``contact.tip_load``, ``_friction``, the weight) in
    wk.F and wk.Kt, r in tab.v[2]."""
    tab, con, wk = ctx.tab, ctx.con, ctx.wk
    B, gtip = pose.B, pose.gtip
    g, ge, r, D, xl, F = tab.v[0], tab.v[1], tab.v[2], tab.m[1], wk.x, wk.F
    for a in range(3):
        ge[a] = g[a] + damp * (
            D[a, 0] * (xl[0] - xln[0]) + D[a, 1] * (xl[1] - xln[1]) + D[a, 2] * (xl[2] - xln[2])
        )
    tip_load(b, wk.xw, ctx.sub, con, F, wk.Kt, wk.tw)
    _friction(b, wk.xw, con, wk, wk.fric)
    rmax = 0.0
    for a in range(3):
        F[a] += gtip[a]
        r[a] = F[a] - (B[a, 0] * ge[0] + B[a, 1] * ge[1] + B[a, 2] * ge[2])
        rmax = max(rmax, abs(r[a]))
    return rmax


@njit(**PRB, inline="always")
def _table_newton(b, B, ctx, damp, L, held, full):
    """(alpha, |dx|, held, ok): Newton's tip step dx (tab.v[3]) from
    (Kt - B (Jg + damp (D + T)) B^T) dx = -r and the fraction alpha of it to take: at most
    TAB_MAX_DX of the links' length, and the chain's contact limits per iterate (``_tip_limits``)
    against ctx.con's partners (the near ones: ``_near_partners``), or all of them (``full``, the
    contact scene) for a step longer than TAB_NEAR."""
    tab, con, wk = ctx.tab, ctx.con, ctx.wk
    Jg, D, A, r, dx = tab.m[0], tab.m[1], tab.m[2], tab.v[2], tab.v[3]
    # the damping force damp D(xl) (xl - xln): its tangent is damp (D + T), T = dD/dxl (xl - xln)
    # from the lookup.  With D alone (before 2026-11-27) a bristle springing back ~1 mm in a step
    # converged only linearly (~0.85 per iterate: D changes fast near the straight chain) and ran
    # out of iterates: 1.89 -> 1.62 fallbacks to the chain per env step under random actions
    T = tab.scr[13:16]
    for a in range(3):
        for c in range(3):
            wk.Ktl[a, c] = Jg[a, c] + damp * (D[a, c] + T[a, c])
    for a in range(3):
        for c in range(3):
            v = wk.Kt[a, c]
            for d in range(3):
                for e in range(3):
                    v -= B[a, d] * wk.Ktl[d, e] * B[c, e]
            A[a, c] = v
    if not lu_dense(A, 3, wk.piv):
        return 0.0, 0.0, held, False
    for a in range(3):
        dx[a] = -r[a]
    lus_dense(A, 3, wk.piv, dx)
    dn = np.sqrt(dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2])
    alpha = 1.0 if dn <= TAB_MAX_DX * L else TAB_MAX_DX * L / dn
    for a in range(3):
        wk.dp[a] = dx[a]
    R = con.tip_args[b].radius
    if dn > TAB_NEAR:  # the near partners' list does not cover so long a step: all of them
        con = full
    a_pen = penetration_step_limit(b, wk.xw, wk.dp, R, con, wk.tw, TAB_PEN_MIN)
    a_pen = _partner_limit(b, wk.xw, wk.dp, R, con, a_pen, TAB_PEN_MIN)
    alpha, held = _tip_limits(b, alpha, a_pen, con, wk, held)
    return alpha, dn, held, True


@njit(**PRB)
def table_solve(b, q0, pose, ctx, xs, xln):
    """Bristle b's step with the tabulated tip law (``tip_table.py``): Newton on its tip's
    position x (world) alone, F_load(x) = B (grad U_s(B^T (x - root)) + beta/h D (xl - xln)) --
    the branch s's elastic law with the joints' damping seen at the tip (xln the tip in the
    bristle frame at the step's start) -- with the same tip load (eq 6, eq 7-10 as a return
    mapping, Table 3, the tip's weight) and the same contact limits per iterate as the chain's
    Newton.  The branch is the one nearest the last iterate's joint angles (q0 at first:
    ``_table_branch``); where it ends under the tip (the snap-through) the other is taken.
    Starts from xs; leaves the tip in wk.xw, its load in wk.F and the joint angles the table
    holds there in wk.qt.  Returns the iterations, or -1 (the caller then solves the chain
    itself)."""
    tab = ctx.tab
    t = tab.idx[b]
    tb = Table(tab.grid[t], tab.rnat[t], tab.vals[t])
    j = ctx.prm[b]
    geo, kq = j.geo, j.k
    sub, wk = ctx.sub, ctx.wk
    rw, B = pose.rw, pose.B
    xl, xw = wk.x, wk.xw
    damp = 0.0 if sub.static else j.beta / sub.h
    L = geo[1] + geo[2]
    kmax = max(kq[0], kq[1], kq[2], kq[3])
    ftol = (sub.rtol if sub.static else TAB_FTOL) * kmax / L
    kax = TAB_AXIAL * kmax / (L * L)
    qprev = wk.qb  # the joint angles of the last iterate (its branch's)
    for i in range(NQ):
        qprev[i] = q0[i]
        wk.qt[i] = q0[i]
    for a in range(3):
        xw[a] = xs[a]
    held = False
    small = False
    s = -1
    # the partner tips near the tip (``_near_partners``), listed about xref = xs, again about the
    # tip whenever it has moved more than TAB_NEAR from where they were listed
    full, xref = ctx.con, xs
    ctxn = Ctx(ctx.prm, sub, _near_partners(b, xref, full, tab), wk, ctx.out, tab)
    for it in range(1, sub.maxit + 1):
        d0, d1, d2 = xw[0] - xref[0], xw[1] - xref[1], xw[2] - xref[2]
        if d0 * d0 + d1 * d1 + d2 * d2 > TAB_NEAR * TAB_NEAR:
            for a in range(3):
                xref[a] = xw[a]
            _near_partners(b, xref, full, tab)
        for a in range(3):
            xl[a] = (
                B[0, a] * (xw[0] - rw[0]) + B[1, a] * (xw[1] - rw[1]) + B[2, a] * (xw[2] - rw[2])
            )
        for a in range(3):  # the lookup's damping tangent needs the tip's move in the step
            tab.scr[12, a] = xl[a] - xln[a]
        s, w, out = _table_branch(tb, xl, qprev, s, tab, tab.v[0], tab.m[0], tab.m[1])
        if s < 0:
            return -1
        if out == 2:
            _axial_penalty(xl, geo[0], tb.grid.rcap, kax, tab.v[0], tab.m[0], wk.v)
        rmax = _table_residual(b, pose, ctxn, xln, damp)
        if not np.isfinite(rmax):
            return -1
        if rmax <= ftol or small:
            for i in range(NQ):
                wk.qt[i] = qprev[i]
            tab.outside[b] += int(out == 1)
            return it
        alpha, dn, held, ok = _table_newton(b, B, ctxn, damp, L, held, full)
        if not ok:
            return -1
        for a in range(3):
            xw[a] += alpha * tab.v[3][a]
        small = alpha * dn < sub.rtol * L
    return -1


@njit(**PRB, inline="always")
def _table_step(b, qb, qpb, pose, ctx, touching):
    """Bristle b's step with the tabulated law (``table_solve``), from the first guess: a tip
    that touched something where it was, moved on by its last velocity as far as the contact
    limits let it (and, where the table fails, the chain's free step if that touches nothing:
    ``_free_step``); else carried with its root -- and taken so, at no further cost, if its
    joints had settled (turned less than SETTLED in the last step: ``_rigid_step``'s test, per
    bristle) and the carried tip touches nothing, else the chain's free step if that touches
    nothing, else the table.  Returns the iterations, or -1."""
    sub, wk, con = ctx.sub, ctx.wk, ctx.con
    x0, xln, xs = con.tips[b], ctx.tab.v[4], ctx.tab.v[5]
    rw, B = pose.rw, pose.B
    for a in range(3):
        xln[a] = (
            wk.B0[b, 0, a] * (x0[0] - wk.rp0[b, 0])
            + wk.B0[b, 1, a] * (x0[1] - wk.rp0[b, 1])
            + wk.B0[b, 2, a] * (x0[2] - wk.rp0[b, 2])
        )
    if touching and not sub.static:
        for a in range(3):
            wk.xw[a] = x0[a]
            wk.dp[a] = x0[3 + a] * sub.h
        R = con.tip_args[b].radius
        lim = penetration_step_limit(b, wk.xw, wk.dp, R, con, wk.tw, PEN_STEP_MIN)
        lim = _partner_limit(b, wk.xw, wk.dp, R, con, lim, PEN_STEP_MIN)
        for a in range(3):
            xs[a] = x0[a] + lim * wk.dp[a]
        n = table_solve(b, qb, pose, ctx, xs, xln)
        # a tip that springs off its contact in the step: the chain's free step, where the
        # table's Newton failed (near the bristle's axis its polar grid makes the load a cone,
        # on which Newton oscillates across the axis until its iterates run out)
        if n < 0 and _free_step(b, pose, ctx):
            return 1
        return n
    for a in range(3):
        xs[a] = rw[a] + B[a, 0] * xln[0] + B[a, 1] * xln[1] + B[a, 2] * xln[2]
    settled = not sub.static
    for i in range(NQ):
        if abs(qb[i] - qpb[i]) > SETTLED:
            settled = False
    if settled:
        for a in range(3):
            wk.xw[a] = xs[a]
        tip_load(b, wk.xw, sub, con, wk.F, wk.Kt, wk.tw)
        st = con.tip_state[b]
        F = wk.F
        if st.fn <= 0.0 and st.ftt <= 0.0 and F[0] == 0.0 and F[1] == 0.0 and F[2] == 0.0:
            for a in range(3):
                F[a] = pose.gtip[a]
            for i in range(NQ):
                wk.qt[i] = qb[i]
            return 1
    # a free bristle still moving: the chain's free step (its joints one by one: cheaper than the
    # table's Newton, which near the axis oscillated; 4.17 -> 3.40 fallbacks to the chain per
    # random env step, docs/benchmarks.md), the table's Newton only where that touches something
    if not sub.static and _free_step(b, pose, ctx):
        return 1
    return table_solve(b, qb, pose, ctx, xs, xln)


@njit(**PRB)
def _solve_one(b, joints, frames, ctx, gtip):
    """Bristle b's step (``step_all``): the free shortcut, else Newton from its first guess, else
    halved; returns the iterations (or -1), the result in ctx.wk.qt."""
    q, qp = joints.q, joints.qp
    sub, wk = ctx.sub, ctx.wk
    st = ctx.con.tip_state[b]
    pose = Pose(frames.rootpos[b], frames.Bw[b], gtip)
    touching = st.fn > 0.0 or st.ftt > 0.0  # at the end of the last step
    # the shortcut only for a bristle that touched nothing either: one that did may spring back
    # off its contact only through Newton (its relaxed pose may lie past the surface)
    tabled = ctx.tab.idx[b] >= 0
    if tabled:
        n = _table_step(b, q[b], qp[b], pose, ctx, touching)
        if n >= 0:
            return n
        ctx.tab.fallback[b] += 1
        for i in range(NQ):
            wk.qt[i] = q[b, i]
    # (a bristle the table failed has had its free step there: ``_table_step``)
    if not sub.static and not touching and not tabled and _free_step(b, pose, ctx):
        return 1
    # first guess: the joints' last motion carried on (a tip held or dragged along moves its
    # joints smoothly); from rest or after a snap (whose motion does not go on), the last angles
    ex = 1.0 if touching and not sub.static else 0.0
    for i in range(NQ):
        if abs(q[b, i] - qp[b, i]) > MAX_DQ:
            ex = 0.0
    if ex > 0.0:
        # ... no further than a Newton step may go (``_step_limit``'s contact limits): carried on
        # blindly, it put a tip 0.6 mm inside its neighbour's, on an equilibrium whose push runs
        # along the links (random actions, seed 10)
        for i in range(NQ):
            wk.dq[i] = q[b, i] - qp[b, i]
        geo = ctx.prm[b].geo
        kinematics(q[b], geo, wk.x, wk.J, wk.cs, wk.orders, wk.v, wk.tmp)
        _to_world(pose.B, wk.x, pose.rw, wk.xw)
        ex = _contact_limit(b, pose.B, wk.dq, ctx.con, wk)
    for i in range(NQ):
        wk.qt[i] = q[b, i] + ex * (q[b, i] - qp[b, i])
    n = solve_bristle(b, wk.qt, wk.qn, pose, ctx, LOOSE_TOL)
    if n < 0 and not sub.static:
        n = _halved(b, ctx, gtip, ctx.con.tips[b], frames)
    return n


@njit(**PRB, inline="always")
def _accept(b, joints, frames, ctx, gtip, rootw):
    """Bristle b's solved step taken: its angles, stiction state (eq 7-10), tip (position,
    velocity) and root wrench (its tip load and weight, force [N] and moment [N mm] about the
    root with which it pushes on the head)."""
    q, qp = joints.q, joints.qp
    sub, wk, tips = ctx.sub, ctx.wk, ctx.con.tips
    st = ctx.con.tip_state[b]
    rootpos = frames.rootpos
    for i in range(NQ):
        qp[b, i] = q[b, i]
        q[b, i] = wk.qt[i]
    for a in range(3):
        st.delta[a] = st.dnew[a]
    st.beta = st.bnew
    xw, F = wk.xw, wk.F
    for a in range(3):
        tips[b, 3 + a] = 0.0 if sub.static else (xw[a] - tips[b, a]) * sub.inv_h
        tips[b, a] = xw[a]
        rootw[b, a] = F[a] + gtip[a]
    d0 = xw[0] - rootpos[b, 0]
    d1 = xw[1] - rootpos[b, 1]
    d2 = xw[2] - rootpos[b, 2]
    rootw[b, 3] = d1 * F[2] - d2 * F[1]
    rootw[b, 4] = d2 * F[0] - d0 * F[2]
    rootw[b, 5] = d0 * F[1] - d1 * F[0]


@njit(**PRB, inline="always")
def _keep_start(b, joints, con, wk, restore):
    """wk.start[b] <- bristle b's state at the step's start (angles now and before, tip position
    and velocity, stiction deformation and sliding flag), or back from it with ``restore``."""
    st = con.tip_state[b]
    keep = wk.start[b]
    tips = con.tips
    if restore:
        for i in range(NQ):
            joints.q[b, i] = keep[i]
            joints.qp[b, i] = keep[NQ + i]
        for a in range(6):
            tips[b, a] = keep[2 * NQ + a]
        for a in range(3):
            st.delta[a] = keep[2 * NQ + 6 + a]
        st.beta = keep[2 * NQ + 9]
        return
    for i in range(NQ):
        keep[i] = joints.q[b, i]
        keep[NQ + i] = joints.qp[b, i]
    for a in range(6):
        keep[2 * NQ + a] = tips[b, a]
    for a in range(3):
        keep[2 * NQ + 6 + a] = st.delta[a]
    keep[2 * NQ + 9] = st.beta


@njit(**PRB, inline="always")
def _axial_direction(b, frames, con, rp0):
    """The direction its axial compliance acts along (``contact.series_law``), held through the
    step: bristle b's chord at the step's start, from its root there (rp0, (nb, 3) [mm]) to its
    tip.  A pressed column carries its tip's load along the chord.  (The chord to the step's end
    root instead turned with a fast-turning TCP, and one of 30 random episodes diverged.)"""
    args = con.tip_args[b]
    if args.cax == 0.0:
        return
    d0 = con.tips[b, 0] - rp0[b, 0]
    d1 = con.tips[b, 1] - rp0[b, 1]
    d2 = con.tips[b, 2] - rp0[b, 2]
    n = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    if n < 1e-9:  # a degenerate chain: its rest axis
        for a in range(3):
            args.axis[a] = frames.Bw[b, a, 0]  # the root frame's x: the bristle's axis
        return
    args.axis[0], args.axis[1], args.axis[2] = d0 / n, d1 / n, d2 / n


@njit(**PRB, inline="always")
def _step_one(b, joints, frames, ctx, gtip, rootw):
    """Bristle b's solver step from its state at the step's start (``_solve_one``), taken
    (``_accept``) or, if it failed even halved, left as it was with ctx.out.status[b] = 1."""
    wk, out, con = ctx.wk, ctx.out, ctx.con
    tips = con.tips
    st = con.tip_state[b]
    _axial_direction(b, frames, con, wk.rp0)
    for a in range(3):
        st.pn[a] = tips[b, a]
        st.hist[a] = 0.0  # backward Euler: v = (p - p_n) / h (records.TIP_STATE)
        wk.d0[a] = st.delta[a]
    wk.d0[3] = st.beta
    for i in range(NQ):
        wk.qn[i] = joints.q[b, i]
        wk.qt[i] = joints.q[b, i]
    n = _solve_one(b, joints, frames, ctx, gtip)
    out.iters[b] += max(n, 0)
    if n >= LOOSE:
        out.loose[b] += 1
    if n < 0:
        out.status[b] = 1
        for a in range(3):
            st.delta[a] = wk.d0[a]
        st.beta = wk.d0[3]
        return
    out.status[b] = 0
    _accept(b, joints, frames, ctx, gtip, rootw)


@njit(**PRB, inline="always")
def _all_settled(q, qp, con):
    """True if no bristle touches anything, carries a dead load or turned its joints by more
    than SETTLED in its last step (``_rigid_step``)."""
    for b in range(q.shape[0]):
        st = con.tip_state[b]
        if st.fn > 0.0 or st.ftt > 0.0:
            return False
        fx = con.tip_args[b].fext
        if fx[0] != 0.0 or fx[1] != 0.0 or fx[2] != 0.0:
            return False
        for i in range(NQ):
            if abs(q[b, i] - qp[b, i]) > SETTLED:
                return False
    return True


@njit(**PRB, inline="always")
def _rigid_tips(frames, con, wk, new):
    """new (nb, 3) <- every tip moved with its root from the step's start (wk.rp0, wk.B0) to its
    end (frames); False as soon as one of them reaches a surface."""
    tips = con.tips
    surf = con.surf
    tw = wk.tw
    for b in range(new.shape[0]):
        for a in range(3):  # the tip in the bristle frame at the step's start
            wk.v[a] = tips[b, a] - wk.rp0[b, a]
        for c in range(3):
            wk.x[c] = wk.B0[b, 0, c] * wk.v[0] + wk.B0[b, 1, c] * wk.v[1] + wk.B0[b, 2, c] * wk.v[2]
        Bw = frames.Bw[b]
        for a in range(3):  # ... and in the world at its end
            new[b, a] = (
                frames.rootpos[b, a] + Bw[a, 0] * wk.x[0] + Bw[a, 1] * wk.x[1] + Bw[a, 2] * wk.x[2]
            )
            wk.xw[a] = new[b, a]
        R = con.tip_args[b].radius
        for k in range(surf.shape[0]):
            if surface_gap(surf, k, wk.xw, tw.pnrm, tw.pcpt, con.mesh, con.sdf) < R:
                return False
    return True


@njit(**PRB, inline="always")
def _rigid_step(joints, frames, ctx, gtip, rootw):
    """The step of a brush none of whose bristles touches anything or moves against its root
    (all settled: joints turned less than SETTLED in their last step, no dead load) and none of
    whose tips reaches a surface at the step's end: every tip moves with its root (relative
    distances kept, so no tip-tip contact either), its joints stay.  Costs a transform and a
    surface gap per bristle instead of a free step (``_free_step``: four tip kinematics and a
    contact evaluation over every partner).  The gravity sag is kept from the last solved step
    (its change with the brush's turn is below 4e-4 rad, ~4 um at the tip, for the default
    bristle).  Returns False, changing nothing, where any condition fails."""
    q, qp = joints.q, joints.qp
    wk, con, sub = ctx.wk, ctx.con, ctx.sub
    if sub.static or not _all_settled(q, qp, con):
        return False
    new = wk.start  # scratch: the tips at the step's end
    if not _rigid_tips(frames, con, wk, new):
        return False
    tips = con.tips
    nb = q.shape[0]
    for b in range(nb):
        st = con.tip_state[b]
        g = gtip[b]
        for i in range(NQ):
            qp[b, i] = q[b, i]
        for a in range(3):
            tips[b, 3 + a] = (new[b, a] - tips[b, a]) * sub.inv_h
            tips[b, a] = new[b, a]
            st.cpt[a] = new[b, a]
            rootw[b, a] = 2.0 * g[a]  # the half of the weight at the tip and the half at the root
        d0 = new[b, 0] - frames.rootpos[b, 0]
        d1 = new[b, 1] - frames.rootpos[b, 1]
        d2 = new[b, 2] - frames.rootpos[b, 2]
        rootw[b, 3] = d1 * g[2] - d2 * g[1]
        rootw[b, 4] = d2 * g[0] - d0 * g[2]
        rootw[b, 5] = d0 * g[1] - d1 * g[0]
        ctx.out.iters[b] = 1
        ctx.out.status[b] = 0
    return True


@njit(**PRB)
def step_all(p0, R0, p, R, geo, joints, frames, ctx, gtip, rootw):
    """One solver step of every bristle from the TCP pose (p0, R0) to (p [mm], R) at the step's
    end (``geo``: the brush; ``joints``: the angles, updated; ``frames``: filled with the roots
    and frames at the end; ``gtip`` (nb, 3) [N] the weights lumped at the tips): each bristle's
    equilibrium (``_solve_one``) in turn, its stiction state committed and its tip moved on
    (``_accept``), so that the next bristle sees it (one Gauss-Seidel sweep of the tip-tip
    contacts).  rootw (nb, 6): each bristle's push on the head.  A bristle that fails even
    halved leaves its state untouched and sets ctx.out.status[b] = 1 (the caller rolls the
    whole step back).

    Then, up to TT_PASSES times, a bristle whose tips' overlap with its neighbours went past the
    penalty law's range (Table 3's force at LOOSE_PEN of its radius) is solved again from the
    step's start with its partners where the sweep left them: a massless bristle springs back
    within one step, and the sweep held the neighbour it springs into where that one stood
    before it sprang back too (two tips on one spot, a 50 N push, under random actions)."""
    wk, out, con = ctx.wk, ctx.out, ctx.con
    root_frames(p, R, geo.root_p, geo.root_R, frames.rootpos, frames.Bw)
    root_frames(p0, R0, geo.root_p, geo.root_R, wk.rp0, wk.B0)
    nb = joints.q.shape[0]
    cp = con.cp[0]
    if _rigid_step(joints, frames, ctx, gtip, rootw):
        return
    for b in range(nb):
        out.iters[b] = 0
        _keep_start(b, joints, con, wk, False)
        _step_one(b, joints, frames, ctx, gtip[b], rootw)
    if con.pair_ptr.shape[0] <= 1:
        return
    for _ in range(TT_PASSES):
        again = False
        for b in range(nb):
            lim = cp.k_tt * (LOOSE_PEN * con.tip_args[b].radius) ** cp.m1_tt
            if out.status[b] == 0 and con.tip_state[b].ftt > lim:
                _keep_start(b, joints, con, wk, True)
                _step_one(b, joints, frames, ctx, gtip[b], rootw)
                again = True
        if not again:
            return


@njit(**PRB)
def link_poses(q, prm, rootpos, Bw, pos, rot, wk):
    """The two links of every bristle as bodies (for drawing and ``State.pos``): centre [mm] and
    frame (x along the link) in the world, bodies 2 b and 2 b + 1."""
    for b in range(q.shape[0]):
        geo = prm[b].geo
        s0, l1, l2 = geo[0], geo[1], geo[2]
        c = wk.cs
        for k in range(NQ):
            qk = q[b, _qi(k)]
            c[k, 0] = np.cos(qk)
            c[k, 1] = np.sin(qk)
        for link in range(2):
            nf = NF1 if link == 0 else NQ
            for col in range(3):  # the link's frame in the bristle frame: F_1..F_nf e_col
                v = wk.v
                v[0], v[1], v[2] = 0.0, 0.0, 0.0
                v[col] = 1.0
                for k in range(nf - 1, -1, -1):
                    _rot_apply(_kind(k), 0, c[k, 0], c[k, 1], v, wk.tmp)
                    v[0], v[1], v[2] = wk.tmp[0], wk.tmp[1], wk.tmp[2]
                for a in range(3):
                    rot[2 * b + link, a, col] = (
                        Bw[b, a, 0] * v[0] + Bw[b, a, 1] * v[1] + Bw[b, a, 2] * v[2]
                    )
        for a in range(3):
            j1 = rootpos[b, a] + s0 * Bw[b, a, 0]
            j2 = j1 + l1 * rot[2 * b, a, 0]
            pos[2 * b, a] = j1 + 0.5 * l1 * rot[2 * b, a, 0]
            pos[2 * b + 1, a] = j2 + 0.5 * l2 * rot[2 * b + 1, a, 0]
