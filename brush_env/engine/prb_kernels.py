"""Kernels of the reduced bristle model (``prb.py``): a quasi-static pseudo-rigid-body chain.

Each bristle is a rigid stub of length s0 clamped at its root, then two rigid links (l1, l2)
joined by two bending joints.  Joint i turns its link by a_i about the bristle's local y (the
deflection along local z, the section's thin direction: stiffness from I_y) and then by b_i
about local z (deflection along y: I_z).  In the bristle frame (x = axis):

    R1 = Ry(a1) Rz(b1),  R2 = R1 Ry(a2) Rz(b2),  tip = s0 e1 + l1 R1 e1 + l2 R2 e1.

The model has no mass: in every solver step of length h it is in equilibrium between the joint
springs (k, calibrated against the rod: ``prb_calibration.py``), the joints' stiffness-
proportional damping (c = beta k, the same damping ratio as the full chain's elements, eq 4-5)
and the load on its tip sphere -- the dead load, the surfaces' eq 6 normal force with the
stick-slip friction of eq 7-10 and the neighbouring tips of Table 3, all from ``contact.tip_load``
(the full model's own tip-load kernel, every surface kind):

    r(q) = K q + (C / h)(q - q_n) - J(q)^T F(tip(q)) = 0,   q = (a1, b1, a2, b2),

solved per bristle by Newton with the exact tangent K + C/h - sum_a F_a d2 tip_a/dq2 - J^T Kt J
(the middle term is the geometric stiffness that makes a pressed column buckle).  The joint
angles carry from step to step: the side a bristle buckled to, its snap-through and hysteresis
are those of the mechanism, not of a table.  Tips are solved one after another (one Gauss-Seidel
sweep, partners held where they are, as the ``fast`` full chain's one sweep).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT, lu_dense, lus_dense
from .contact import penetration_step_limit, slip_step_limit, tip_load

#: joint coordinates per bristle
NQ = 4
#: largest Newton correction of a joint angle in one iterate [rad] (a longer step is scaled down:
#: keeps a tip that meets a surface from jumping through the penalty range in one iterate)
MAX_DQ = 0.15
#: steps off a saddle (an unstable equilibrium) per bristle and solver step
MAX_ESCAPES = 4


@njit(**HOT, inline="always")
def _rot_apply(kind, order, c, s, v, out):
    """out <- Rk(angle)^... : the factor k applied to v, differentiated ``order`` times (0-2);
    kind 0: about y, 1: about z.  d/dt R = R G and d2 R = R G G (G the generator)."""
    w0, w1, w2 = v[0], v[1], v[2]
    if kind == 0:  # generator of y: G v = (v2, 0, -v0)
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


@njit(**HOT)
def _chain_vec(cs, nf, orders, out, tmp):
    """out <- F_1 F_2 ... F_nf e1 with F_k the k-th joint factor (Ry, Rz, Ry, Rz) differentiated
    orders[k] times; cs (4, 2) the cosines and sines."""
    out[0], out[1], out[2] = 1.0, 0.0, 0.0
    for k in range(nf - 1, -1, -1):
        _rot_apply(k % 2, orders[k], cs[k, 0], cs[k, 1], out, tmp)
        out[0], out[1], out[2] = tmp[0], tmp[1], tmp[2]


@njit(**HOT)
def kinematics(q, geo, x, J, cs, orders, v, tmp):
    """Tip of one bristle in its local frame x (3,) [mm] and J = dx/dq (3, 4) [mm/rad];
    geo = (s0, l1, l2) [mm].  Leaves the cosines and sines of q in cs (4, 2)."""
    for k in range(NQ):
        cs[k, 0] = np.cos(q[k])
        cs[k, 1] = np.sin(q[k])
        orders[k] = 0
    s0, l1, l2 = geo[0], geo[1], geo[2]
    x[0], x[1], x[2] = s0, 0.0, 0.0
    for i in range(NQ):
        for a in range(3):
            J[a, i] = 0.0
    for t in range(2):  # term 1: l1 R1 e1 (factors 0, 1); term 2: l2 R2 e1 (factors 0-3)
        nf = 2 if t == 0 else 4
        ln = l1 if t == 0 else l2
        _chain_vec(cs, nf, orders, v, tmp)
        for a in range(3):
            x[a] += ln * v[a]
        for i in range(nf):
            orders[i] = 1
            _chain_vec(cs, nf, orders, v, tmp)
            orders[i] = 0
            for a in range(3):
                J[a, i] += ln * v[a]


@njit(**HOT)
def geometric_stiffness(geo, Fl, G, cs, orders, v, tmp):
    """G_ij = sum_a Fl_a d2x_a/dq_i dq_j (4, 4) [N mm] for the local tip load Fl (3,) [N], with
    the cosines and sines cs of ``kinematics``: the load's share of the tangent (negative for a
    column pressed along its axis: what makes it buckle)."""
    for i in range(NQ):
        orders[i] = 0
        for j in range(NQ):
            G[i, j] = 0.0
    for t in range(2):
        nf = 2 if t == 0 else 4
        ln = geo[1] if t == 0 else geo[2]
        for i in range(nf):
            orders[i] = 1
            for j in range(i, nf):
                orders[j] += 1
                _chain_vec(cs, nf, orders, v, tmp)
                orders[j] -= 1
                g = ln * (Fl[0] * v[0] + Fl[1] * v[1] + Fl[2] * v[2])
                G[i, j] += g
                if j != i:
                    G[j, i] += g
            orders[i] = 0


@njit(**HOT, inline="always")
def _to_world(B, xl, rw, out):
    for a in range(3):
        out[a] = rw[a] + B[a, 0] * xl[0] + B[a, 1] * xl[1] + B[a, 2] * xl[2]


@njit(**HOT)
def frames(tcp_p, tcp_R, root_p, root_R, rootw, Bw):
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


@njit(**HOT)
def _evaluate(b, q, qn, geo, kq, damp, rw, B, sub, con, gtip, wk, tangent):
    """Residual wk.s = K q + damp K (q - qn) - J^T F (4,) [N mm] of bristle b at the angles q, its
    tip (wk.x local, wk.xw world) and tip load (wk.F world, wk.Fl local) and, with ``tangent``,
    the Newton matrix wk.A = K (1 + damp) - G - J^T Kt J.  Returns max |s|."""
    x, xw, J, F, Kt, Fl = wk.x, wk.xw, wk.J, wk.F, wk.Kt, wk.Fl
    kinematics(q, geo, x, J, wk.cs, wk.orders, wk.v, wk.tmp)
    _to_world(B, x, rw, xw)
    tip_load(b, xw, sub, con, F, Kt, wk.tw)
    for a in range(3):
        F[a] += gtip[a]
    for a in range(3):  # the load in the bristle frame
        Fl[a] = B[0, a] * F[0] + B[1, a] * F[1] + B[2, a] * F[2]
    smax = 0.0
    for i in range(NQ):
        si = kq[i] * (q[i] + damp * (q[i] - qn[i]))
        for a in range(3):
            si -= J[a, i] * Fl[a]
        wk.s[i] = si
        if abs(si) > smax:
            smax = abs(si)
    if not tangent:
        return smax
    geometric_stiffness(geo, Fl, wk.G, wk.cs, wk.orders, wk.v, wk.tmp)
    Ktl, JK, A = wk.Ktl, wk.JK, wk.A
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
        A[i, i] += kq[i] * (1.0 + damp)
    return smax


@njit(**HOT, inline="always")
def _along(q, dq, alpha, out):
    for i in range(NQ):
        out[i] = q[i] + alpha * dq[i]


@njit(**HOT, inline="always")
def _slope(s, dq):
    return s[0] * dq[0] + s[1] * dq[1] + s[2] * dq[2] + s[3] * dq[3]


@njit(**HOT)
def _sym_min_eig(A, S, V, w):
    """Smallest eigenvalue of the symmetric part of A (4, 4) and its eigenvector (left in w) by
    cyclic Jacobi rotations on S (scratch); V scratch (4, 4)."""
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
                if abs(S[p, r]) < 1e-300:
                    continue
                th = 0.5 * (S[r, r] - S[p, p]) / S[p, r]
                t = (1.0 if th >= 0.0 else -1.0) / (abs(th) + np.sqrt(th * th + 1.0))
                c = 1.0 / np.sqrt(t * t + 1.0)
                sn = t * c
                for k in range(NQ):  # S <- J^T S J
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
    m = 0
    for i in range(1, NQ):
        if S[i, i] < S[m, m]:
            m = i
    for i in range(NQ):
        w[i] = V[i, m]
    return S[m, m]


@njit(**HOT)
def _escape(q, s, A, kq, wk, dq):
    """dq <- a step off a saddle when the Newton matrix is not positive definite (a column
    pressed past its buckling load, held straight by the last Newton iterates): the shifted
    Newton step (A - lam I + eps) dq = -s plus a move along the direction of negative curvature,
    signed to go down the residual, or (at the saddle itself) toward the side q already leans
    to.  Returns the smallest eigenvalue (>= 0: A is fine, dq untouched)."""
    lam = _sym_min_eig(A, wk.S, wk.V, wk.w)
    if lam >= 0.0:
        return lam
    kmax = max(kq[0], kq[1], kq[2], kq[3])
    for i in range(NQ):
        for j in range(NQ):
            wk.S[i, j] = 0.5 * (A[i, j] + A[j, i])
        wk.S[i, i] += -lam + 1e-3 * kmax
        dq[i] = -s[i]
    lu_dense(wk.S, NQ, wk.piv)
    lus_dense(wk.S, NQ, wk.piv, dq)
    sv = _slope(s, wk.w)
    qv = _slope(q, wk.w)
    sign = (
        -1.0 if sv > 1e-12 * kmax else (1.0 if sv < -1e-12 * kmax else (1.0 if qv >= 0 else -1.0))
    )
    for i in range(NQ):
        dq[i] += sign * 0.5 * MAX_DQ * wk.w[i]
    return lam


@njit(**HOT)
def solve_bristle(b, q, qn, prm, rw, B, h, static, sub, con, gtip, wk, maxit, tol):
    """Quasi-static equilibrium of bristle b (module docstring) from the guess q (4,), updated
    in place; qn the joint angles at the step start.  prm[b] = (s0, l1, l2, ka1, kb1, ka2, kb2,
    beta); rw, B its root [mm] and frame in the world; gtip (3,) its lumped weight [N].

    Newton with the full model's safeguards (``newton.py``): the step is capped (MAX_DQ, and
    ``contact.penetration_step_limit`` / ``slip_step_limit`` on the tip's step), then a line
    search on the slope g(alpha) = dq . s(q + alpha dq) (regula falsi where it changes sign: the
    minimum of the energy along dq), which stops the limit cycle of a tip thrown in and out of
    the stiff penalty contact.  Leaves the tip (world) in wk.xw and its load in wk.F at the
    returned q.  Returns the Newton iterations, or -1 if it did not converge."""
    geo = prm[b, 0:3]
    kq = prm[b, 3:7]
    damp = 0.0 if static else prm[b, 7] / h
    dq, qt, dp = wk.dq, wk.qt2, wk.dp
    st = con.tip_state[b]
    escapes = 0
    for it in range(1, maxit + 1):
        smax = _evaluate(b, q, qn, geo, kq, damp, rw, B, sub, con, gtip, wk, True)
        if not np.isfinite(smax):
            return -1
        for i in range(NQ):
            dq[i] = -wk.s[i]
            for j in range(NQ):
                wk.A2[i, j] = wk.A[i, j]
        if not lu_dense(wk.A, NQ, wk.piv):
            return -1
        lus_dense(wk.A, NQ, wk.piv, dq)
        g0 = _slope(wk.s, dq)
        dmax = 0.0
        for i in range(NQ):
            if abs(dq[i]) > dmax:
                dmax = abs(dq[i])
        if g0 >= 0.0 or (dmax < tol and escapes < MAX_ESCAPES):
            # not a descent direction, or converged: is the equilibrium stable?
            if _escape(q, wk.s, wk.A2, kq, wk, dq) < 0.0 and escapes < MAX_ESCAPES:
                escapes += 1
                g0 = _slope(wk.s, dq)
                dmax = 0.0
                for i in range(NQ):
                    if abs(dq[i]) > dmax:
                        dmax = abs(dq[i])
            elif dmax < tol:
                return it
        elif dmax < tol:
            return it
        alpha = 1.0 if dmax <= MAX_DQ else MAX_DQ / dmax
        # the tip's step (world), linearised, for the contact step limits
        for a in range(3):
            t = 0.0
            for i in range(NQ):
                t += wk.J[a, i] * dq[i]
            wk.tmp[a] = t
        for a in range(3):
            dp[a] = B[a, 0] * wk.tmp[0] + B[a, 1] * wk.tmp[1] + B[a, 2] * wk.tmp[2]
        a_pen = penetration_step_limit(b, wk.xw, dp, con.tip_args[b].radius, con, wk.tw)
        if a_pen < alpha:
            alpha = max(a_pen, 1e-3)
        if not static:
            a_slip = slip_step_limit(wk.xw, dp, st, sub.c0, sub.inv_h, con.cp[0].v_d)
            if a_slip < alpha:
                alpha = max(a_slip, 1e-4)
        _along(q, dq, alpha, qt)
        _evaluate(b, qt, qn, geo, kq, damp, rw, B, sub, con, gtip, wk, False)
        g1 = _slope(wk.s, dq)
        if g0 < 0.0 and g1 > 0.0:
            # overshoot: the energy's minimum along dq lies inside (0, alpha); Illinois
            lo, glo, hi, ghi = 0.0, g0, alpha, g1
            side = 0
            for _ in range(12):
                a_new = lo - glo * (hi - lo) / (ghi - glo)
                _along(q, dq, a_new, qt)
                _evaluate(b, qt, qn, geo, kq, damp, rw, B, sub, con, gtip, wk, False)
                g = _slope(wk.s, dq)
                alpha = a_new
                if abs(g) <= 0.1 * abs(g0):
                    break
                if g > 0.0:
                    hi, ghi = a_new, g
                    if side == 1:
                        glo *= 0.5
                    side = 1
                else:
                    lo, glo = a_new, g
                    if side == -1:
                        ghi *= 0.5
                    side = -1
        for i in range(NQ):
            q[i] = qt[i]
        if dmax * alpha < tol:
            return it
    return -1


@njit(**HOT)
def step_all(tcp_p, tcp_R, root_p, root_R, prm, q, sub, con, gtip, rootw, Bw, rootpos, wk, out):
    """One solver step of every bristle to the TCP pose (tcp_p [mm], tcp_R) at the step's end:
    each bristle's equilibrium (``solve_bristle``) in turn, its stiction state committed (eq 7-10)
    and its tip (con.tips: position [mm], velocity [mm/s]) moved on, so that the next bristle sees
    it (one Gauss-Seidel sweep of the tip-tip contacts).  out.rootw (nb, 6): the force [N] and
    moment [N mm] about the root with which each bristle pushes on the head (its tip load and its
    weight, gtip being half of it).  A bristle that fails leaves its state untouched and sets
    out.status[b] = 1 (the caller rolls the whole step back)."""
    frames(tcp_p, tcp_R, root_p, root_R, rootpos, Bw)
    h = sub.h
    tips = con.tips
    for b in range(q.shape[0]):
        st = con.tip_state[b]
        for a in range(3):
            st.pn[a] = tips[b, a]
            st.hist[a] = -tips[b, a]  # backward Euler: v = (p - p_n) / h
        for i in range(NQ):
            wk.qn[i] = q[b, i]
            wk.qt[i] = q[b, i]
        n = solve_bristle(
            b,
            wk.qt,
            wk.qn,
            prm,
            rootpos[b],
            Bw[b],
            h,
            sub.static,
            sub,
            con,
            gtip[b],
            wk,
            sub.maxit,
            sub.rtol,
        )
        out.iters[b] = max(n, 0)
        if n < 0:
            out.status[b] = 1
            continue
        out.status[b] = 0
        for i in range(NQ):
            q[b, i] = wk.qt[i]
        for a in range(3):
            st.delta[a] = st.dnew[a]
        st.beta = st.bnew
        xw, F = wk.xw, wk.F
        for a in range(3):
            tips[b, 3 + a] = 0.0 if sub.static else (xw[a] - tips[b, a]) * sub.inv_h
            tips[b, a] = xw[a]
            rootw[b, a] = F[a] + gtip[b, a]
        d0 = xw[0] - rootpos[b, 0]
        d1 = xw[1] - rootpos[b, 1]
        d2 = xw[2] - rootpos[b, 2]
        rootw[b, 3] = d1 * F[2] - d2 * F[1]
        rootw[b, 4] = d2 * F[0] - d0 * F[2]
        rootw[b, 5] = d0 * F[1] - d1 * F[0]


@njit(**HOT)
def link_poses(q, prm, rootpos, Bw, pos, rot, wk):
    """The two links of every bristle as bodies (for drawing and ``State.pos``): centre [mm] and
    frame (x along the link) in the world, bodies 2 b and 2 b + 1."""
    for b in range(q.shape[0]):
        s0, l1, l2 = prm[b, 0], prm[b, 1], prm[b, 2]
        c = wk.cs
        for k in range(NQ):
            c[k, 0] = np.cos(q[b, k])
            c[k, 1] = np.sin(q[b, k])
        for link in range(2):
            nf = 2 * (link + 1)
            for col in range(3):  # the link's frame in the bristle frame: F_1..F_nf e_col
                v = wk.v
                v[0], v[1], v[2] = 0.0, 0.0, 0.0
                v[col] = 1.0
                for k in range(nf - 1, -1, -1):
                    _rot_apply(k % 2, 0, c[k, 0], c[k, 1], v, wk.tmp)
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
