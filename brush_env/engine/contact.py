"""Tip contact: penalty normal law (eq 6), stick-slip friction (eq 7, 8, 9, 10, Table 1), tip-tip
(Table 3).

All kernels act on one bristle's tip sphere (centre ``pt`` at the tip node, radius R).

Normal law (eq 6, printed garbled; intended form as in Adams' IMPACT): for penetration delta > 0
``Fn = k delta^m1 + c sign(ddelta) |ddelta|^m2 delta^m3``, clamped at Fn >= 0 (no adhesion);
Fn = 0 for delta <= 0.  delta is measured along the surface normal from the sphere's closest point.

Friction (eq 7-10, our reading of Table 1, documented in docs/model.md):
    F_t = -(1 - beta) mu_s Fn g(|Delta| / Delta_max) Delta_hat  -  mu_d Fn s(|v| / v_d) v_hat
with beta = step(|v|, 0, 0, v_s, 1) (0 at rest, 1 for |v| >= v_s; C1 variant of the printed
step(|v|, -v_s, -1, v_s, 1), see the kernel), g(x) = step(x, -1, -1, 1, 1)
(0 at x = 0, 1 at x = 1: the printed step of F_s between -Delta_max and +Delta_max) and s(x) the
same step (the printed step of F_d between -v_t and +v_t).  v is the tangential slip velocity of
the tip
and Delta the stiction deformation: a per-contact state created at contact onset, advanced with the
tangential tip displacement of each step, bounded by Delta_max, kept across steps and dropped on
separation.  So a tip at rest holds up to mu_s Fn (reached at |Delta| = Delta_max), and a sliding
tip (|v| >= max(v_s, v_d)) carries exactly mu_d Fn against its slip.

Tip-tip contact (Table 3): the same normal law between two tip spheres along the line of centres,
no friction.  The partner tip is held at its latest position (Gauss-Seidel splitting across
bristles, see step.step_bristles).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT
from .records import SURF_MESH, SURF_PLANE
from .sdf import FAR
from .surfaces import normal_rate, surface_gap

PEN_STEP_MIN = 2e-3  # [mm] a Newton step may always reach this penetration
#: the first surface's index, typed int64: a literal 0 made numba compile ``surface_gap`` (and its
#: callees) once more, specialised on the constant (issue 32, session 36)
FIRST = np.int64(0)
#: [N] a tip with an axial compliance (``series_law``) may always step as deep as this load
#: compresses it: its overlap with a surface is mostly the bristle's compression (~0.09 mm at
#: 0.1 N for the default brush's inner bristle), which the doubling rule of
#: ``penetration_step_limit`` would reach only over ~6 iterates from PEN_STEP_MIN
SERIES_ALLOW_LOAD = 0.05
#: the series law's Newton: at most this many iterates, stopping at a residual of SERIES_TOL x
#: the overlap [mm]
SERIES_MAXIT = 30
SERIES_TOL = 1e-12


@njit(**HOT)
def step10(x, x0, h0, x1, h1):
    """Eq 10: cubic step from h0 (x <= x0) to h1 (x >= x1)."""
    if x <= x0:
        return h0
    if x >= x1:
        return h1
    u = (x - x0) / (x1 - x0)
    return h0 + (h1 - h0) * u * u * (3.0 - 2.0 * u)


@njit(**HOT)
def step10_dx(x, x0, h0, x1, h1):
    if x <= x0 or x >= x1:
        return 0.0
    u = (x - x0) / (x1 - x0)
    return (h1 - h0) * 6.0 * u * (1.0 - u) / (x1 - x0)


@njit(**HOT)
def _power(x, e):
    """x ** e for x >= 0; the whole exponents of the paper's tables (Tables 2-3: m2 = 1, m3 = 2,
    and m - 1 of those) by multiplication: libm's pow costs ~150 instructions a call, and eq 6
    took six per evaluation (2-3 % of a bristle-step on the turn, ``bench cost``)."""
    if e == 1.0:
        return x
    if e == 2.0:
        return x * x
    if e == 0.0:
        return 1.0
    return x**e


@njit(**HOT)
def normal_law(delta, ddelta, k, m1, c, m2, m3):
    """Eq 6 for delta > 0: returns (Fn, dFn/ddelta, dFn/d(ddelta)); Fn clamped >= 0."""
    if delta <= 0.0:
        return 0.0, 0.0, 0.0
    # delta^m1 = delta delta^(m1 - 1): one pow for the force and its slope
    pk = _power(delta, m1 - 1.0)
    el = k * pk * delta
    # exact slope (it vanishes as delta -> 0 for m1 > 1: overshoot at contact onset is handled by
    # the pre-search tangent and the penetration step limit, not by altering this slope, because
    # an over-stiff tangent turns Newton's convergence linear near onset)
    kel = k * m1 * pk
    ad = abs(ddelta)
    sg = 1.0 if ddelta > 0.0 else (-1.0 if ddelta < 0.0 else 0.0)
    pd = _power(delta, m3 - 1.0)
    dm = pd * delta
    vm = _power(ad, m2)
    damp = c * sg * vm * dm
    F = el + damp
    if F <= 0.0:
        return 0.0, 0.0, 0.0
    dF_dd = kel + c * sg * vm * m3 * pd
    dF_dv = c * m2 * _power(ad, m2 - 1.0) * dm if ad > 0.0 or m2 == 1.0 else 0.0
    return F, dF_dd, dF_dv


@njit(**HOT, inline="always")
def compliance(args, nrm) -> float:
    """The tip's axial compliance seen along the contact normal ``nrm`` [mm/N]:
    ``cax (a . n)^2`` (``records.TIP_ARGS``): a normal force Fn has the axial part (a . n) Fn,
    which shortens the bristle by cax (a . n) Fn along a, of which (a . n) moves the tip along n.
    0 for the full chain."""
    if args.cax == 0.0:
        return 0.0
    an = args.axis[0] * nrm[0] + args.axis[1] * nrm[1] + args.axis[2] * nrm[2]
    return args.cax * an * an


@njit(**HOT)
def series_law(delta, ddelta, k, m1, c, m2, m3, cs):
    """Eq 6 in series with a compliance cs [mm/N]: the geometric overlap ``delta`` [mm] of a
    rigid tip is the contact's penetration dc plus the spring's compression cs Fn, with
    Fn = eq 6 (dc, ddelta).  Returns (Fn, dFn/d delta, dFn/d(ddelta), dc): the slopes of the
    series spring, kn / (1 + cs kn) and cn / (1 + cs kn) (kn, cn: eq 6's own at dc).

    dc solves h(dc) = dc + cs Fn(dc) - delta = 0 by Newton from above: h rises and, for
    m1 >= 1, is convex, so iterates from a point with h >= 0 fall monotonically onto the root.
    The start: the smaller of delta (no compression) and the penetration that the spring's whole
    share would load, (delta / (cs k))^(1/m1) (an upper bound when eq 6's damping term is not
    negative: k dc^m1 <= Fn <= delta / cs).  cs = 0: eq 6 itself (``normal_law``)."""
    if cs <= 0.0:
        F, kn, cn = normal_law(delta, ddelta, k, m1, c, m2, m3)
        return F, kn, cn, delta
    if delta <= 0.0:
        return 0.0, 0.0, 0.0, delta
    x = delta
    if c == 0.0 or ddelta >= 0.0:
        xb = (delta / (cs * k)) ** (1.0 / m1)
        if xb < x:
            x = xb
    F, kn, cn = normal_law(x, ddelta, k, m1, c, m2, m3)
    for _ in range(SERIES_MAXIT):
        h = x + cs * F - delta
        if h <= SERIES_TOL * delta:
            break
        x -= h / (1.0 + cs * kn)
        F, kn, cn = normal_law(x, ddelta, k, m1, c, m2, m3)
    s = 1.0 / (1.0 + cs * kn)
    return F, kn * s, cn * s, x


@njit(**HOT, inline="always")
def overlap(args, state, nrm) -> float:
    """The geometric overlap [mm] of a touching tip with its surface (``state`` from the last
    ``tip_load``, ``nrm`` its normal): the contact's penetration plus the axial compression that
    ``series_law`` put behind it (the penetration alone for the full chain)."""
    return state.pen + compliance(args, nrm) * state.fn


@njit(**HOT, inline="always")
def _from_partner(pt, tips, j):
    """(d, |d|): the vector from partner tip j's centre to ``pt`` [mm] and its length."""
    d0 = pt[0] - tips[j, 0]
    d1 = pt[1] - tips[j, 1]
    d2 = pt[2] - tips[j, 2]
    return d0, d1, d2, np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@njit(**HOT)
def tip_load(b, pt, sub, con, F, Kt, tw):
    """Total load on bristle b's tip node at ``pt`` [mm]: force F [N] and dF/dpt Kt [N/mm].

    Sums the dead external force, the tip-surface contact of the deepest surface (eq 6, with
    friction eq 7-10) and the tip-tip contacts (Table 3) with the partner tips listed in
    con.pair_idx[con.pair_ptr[b]:con.pair_ptr[b+1]] (partners held at con.tips[j, 0:3] with
    velocity con.tips[j, 3:6]).  Stores the contact outputs and the trial stiction deformation in
    con.tip_state[b].  Kt is the Newton tangent (normal stiffness and damping, tangential friction
    stiffness, and the friction's dependence on Fn).  sub: the (sub)step (c0, inv_h, static);
    tw: ``records.TipScratch``.
    """
    state = con.tip_state[b]
    R = con.tip_args[b].radius
    vt = tw.vt
    for a in range(3):
        F[a] = con.tip_args[b].fext[a]
        for bb in range(3):
            Kt[a, bb] = 0.0
        # tip velocity from the discrete rate formula, in the tip's move since the step start
        # (records.TIP_STATE's hist; zero for statics)
        vt[a] = 0.0 if sub.static else (sub.c0 * (pt[a] - state.pn[a]) + state.hist[a]) * sub.inv_h
    state.fn = 0.0
    state.ft[0] = 0.0
    state.ft[1] = 0.0
    state.ft[2] = 0.0
    state.slide = 0
    state.pen = 0.0
    state.ftt = 0.0
    state.bnew = 0.0
    state.surf = -1
    for a in range(3):
        state.dnew[a] = 0.0
        state.cpt[a] = pt[a]
    _surface_load(pt, con.tip_args[b], sub, con, state, F, Kt, tw)
    _tip_tip_load(b, pt, R, sub, con, state, F, Kt, vt)


@njit(**HOT, inline="always")
def presses_on_resultant(surf) -> bool:
    """True for several surfaces or one curved one (``_several_surfaces``): friction presses
    against the resultant of their normal forces (tw.res, tw.gres); False for one plane or mesh."""
    return surf.shape[0] > 1 or (
        surf.shape[0] == 1 and surf[0].kind != SURF_PLANE and surf[0].kind != SURF_MESH
    )


@njit(**HOT, inline="always")
def _surface_load(pt, args, sub, con, state, F, Kt, tw):
    """Tip-surface contact: the penalty normal force of eq 6 (in series with the tip's axial
    compliance, ``series_law``: state.pen is then the contact's own penetration) and its tangent,
    then friction (eq 7-10, ``_friction_load``).

    A plane or a triangle mesh alone (the plate): its contact, flat.  Several surfaces, or one
    curved one (``_several_surfaces``, with the curvature in the tangent): the normal
    force of every touched surface whose contact point is not inside another one (a tip in the
    gap between two crowns feels both walls; the gum inside a crown is hidden), and friction
    against their resultant: ``|sum_s Fn_s n_s|`` in the plane normal to it.  The resultant is
    continuous as a contact comes, goes or stops being the deepest; friction against the deepest
    surface alone flipped its plane between Newton iterates where two surfaces were equally
    deep, and Newton failed even at dt/256."""
    surf = con.surf
    cp = con.cp[0]
    vt = tw.vt
    nrm = tw.nrm
    cpt = tw.cpt
    R = args.radius
    if presses_on_resultant(surf):
        Fn = _several_surfaces(pt, args, sub, con, state, F, Kt, tw)
        if Fn > 0.0 and (cp.mu_s > 0.0 or cp.mu_d > 0.0):
            # friction ~ |R|: its Newton coupling dF_t = (F_t / |R|) d|R|, d|R| = -g^T dpt with
            # g = -A^T n (tw.gres, from _several_surfaces), not kk n
            _friction_load(pt, Fn, 0.0, sub, cp, state, F, Kt, tw)
            g = tw.gres
            ft = tw.ft
            for a in range(3):
                for bb in range(3):
                    Kt[a, bb] -= ft[a] / Fn * g[bb]
        return
    if surf.shape[0] == 0:
        return
    best = surface_gap(surf, FIRST, pt, nrm, cpt, con.mesh, con.sdf)
    if best >= R:
        return
    delta = R - best
    vn = vt[0] * nrm[0] + vt[1] * nrm[1] + vt[2] * nrm[2]
    cs = compliance(args, nrm)
    Fn, kn, cn, dc = series_law(delta, -vn, cp.k, cp.m1, cp.c, cp.m2, cp.m3, cs)  # eq 6
    for a in range(3):
        state.cpt[a] = cpt[a]
    state.pen = dc
    state.surf = 0
    if Fn <= 0.0:
        return
    state.fn = Fn
    # normal force and tangent: delta = R - n.(pt - p0) -> d delta/d pt = -n;
    # d(ddelta)/d pt = -(c0/h) n
    kk = kn + (0.0 if sub.static else cn * sub.c0 * sub.inv_h)
    for a in range(3):
        F[a] += Fn * nrm[a]
        for bb in range(3):
            Kt[a, bb] -= kk * nrm[a] * nrm[bb]
    if cp.mu_s > 0.0 or cp.mu_d > 0.0:
        _friction_load(pt, Fn, kk, sub, cp, state, F, Kt, tw)


@njit(**HOT)
def _several_surfaces(pt, args, sub, con, state, F, Kt, tw):
    """Normal forces (eq 6) of every touched, not hidden surface (a contact point more than 1 um
    inside another surface is hidden in their union); adds them to F, Kt, stores the total in
    state.fn, the deepest in state.pen, .cpt, .surf.  Leaves the resultant's direction in tw.nrm and
    d|R|/dpt's negative in tw.gres for friction, R itself in tw.res, and returns its magnitude |R|
    (0: no friction)."""
    surf = con.surf
    cp = con.cp[0]
    vt = tw.vt
    nrm = tw.pnrm
    cpt = tw.pcpt
    R = args.radius
    tw.res[0], tw.res[1], tw.res[2] = 0.0, 0.0, 0.0
    best = FAR
    ibest = -1
    touched = 0  # bit s: surface s is within R (only those are evaluated again below)
    for s in range(surf.shape[0]):
        gap = surface_gap(surf, s, pt, nrm, cpt, con.mesh, con.sdf)
        if gap < R and s < 63:
            touched |= 1 << s
        if gap < best:
            best = gap
            ibest = s
    if ibest < 0 or best >= R:
        return 0.0
    total = 0.0
    r0 = 0.0  # resultant normal force sum_s Fn_s n_s: friction acts in the plane normal to it
    r1 = 0.0
    r2 = 0.0
    A = tw.A  # its derivative d(sum_s Fn_s n_s)/dpt, the contacts' Newton tangent
    J = tw.J
    gd = tw.gd
    for a in range(3):
        for bb in range(3):
            A[a, bb] = 0.0
    rate = 0.0 if sub.static else sub.c0 * sub.inv_h
    for s in range(surf.shape[0]):
        if s < 63 and not (touched >> s) & 1:
            continue
        gap = surface_gap(surf, s, pt, nrm, cpt, con.mesh, con.sdf)
        if gap >= R:
            continue
        if s != ibest:
            hidden = False
            for o in range(surf.shape[0]):
                if o != s and surface_gap(surf, o, cpt, tw.vs, tw.dn, con.mesh, con.sdf) < -1e-3:
                    hidden = True
                    break
            if hidden:
                continue
        vn = vt[0] * nrm[0] + vt[1] * nrm[1] + vt[2] * nrm[2]
        cs = compliance(args, nrm)
        Fn, kn, cn, dc = series_law(R - gap, -vn, cp.k, cp.m1, cp.c, cp.m2, cp.m3, cs)
        if s == ibest:
            for a in range(3):
                state.cpt[a] = cpt[a]
            state.pen = dc
            state.surf = s
        if Fn <= 0.0:
            continue
        normal_rate(surf, s, pt, nrm, gap, con.sdf, J, gd)
        # d(Fn n) = n dFn + Fn J dpt, with dFn = -kn gd^T dpt - cn (rate n + J^T v)^T dpt
        # (delta = R - gap, ddelta = -v.n)
        for bb in range(3):
            jv = J[0, bb] * vt[0] + J[1, bb] * vt[1] + J[2, bb] * vt[2]
            dfn = -kn * gd[bb] - cn * (rate * nrm[bb] + jv)
            for a in range(3):
                A[a, bb] += nrm[a] * dfn + Fn * J[a, bb]
        for a in range(3):
            F[a] += Fn * nrm[a]
        total += Fn
        r0 += Fn * nrm[0]
        r1 += Fn * nrm[1]
        r2 += Fn * nrm[2]
    for a in range(3):
        for bb in range(3):
            Kt[a, bb] += A[a, bb]
    state.fn = total
    tw.res[0], tw.res[1], tw.res[2] = r0, r1, r2
    f_res = np.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    if f_res <= 0.0:
        return 0.0
    n0, n1, n2 = r0 / f_res, r1 / f_res, r2 / f_res
    tw.nrm[0], tw.nrm[1], tw.nrm[2] = n0, n1, n2
    # d|R|/dpt = n^T A = -g: friction's Newton coupling to the normal force
    for bb in range(3):
        tw.gres[bb] = -(n0 * A[0, bb] + n1 * A[1, bb] + n2 * A[2, bb])
    return f_res


@njit(**HOT, inline="always")
def _friction_load(pt, Fn, kk, sub, cp, state, F, Kt, tw):
    """Friction on a tip pressed with Fn [N] (normal tangent kk [N/mm]): eq 7 (F_mu = stiction +
    sliding), eq 8 (stiction), eq 9 (sliding), with the steps of eq 10; adds force and Newton
    tangent to F, Kt and stores the trial stiction deformation and beta in ``state``."""
    mus = cp.mu_s
    nrm = tw.nrm
    vt = tw.vt
    vn = vt[0] * nrm[0] + vt[1] * nrm[1] + vt[2] * nrm[2]
    # slip velocity and stiction deformation in the tangent plane
    vs = tw.vs
    for a in range(3):
        vs[a] = vt[a] - vn * nrm[a]
    vmag = np.sqrt(vs[0] ** 2 + vs[1] ** 2 + vs[2] ** 2)
    dn = tw.dn
    for a in range(3):
        dn[a] = state.delta[a] + pt[a] - state.pn[a]
    dnn = dn[0] * nrm[0] + dn[1] * nrm[1] + dn[2] * nrm[2]
    for a in range(3):
        dn[a] -= dnn * nrm[a]
    dmag = np.sqrt(dn[0] ** 2 + dn[1] ** 2 + dn[2] ** 2)
    dmax = cp.delta_max
    dtrial = dmag  # before the clamp: the tangent of the clamped Delta scales with dmax / dtrial
    if dmag > dmax:
        for a in range(3):
            dn[a] *= dmax / dmag
        dmag = dmax
    for a in range(3):
        state.dnew[a] = dn[a]
    v_s = cp.v_s
    v_d = cp.v_d
    # beta: C1 form step(|v|, 0, 0, v_s, 1).  The printed step(|v|, -v_s, -1, v_s, 1) has the same
    # end values but a kink at v = 0 (slope 1.5/v_s in |v|), which makes Newton cycle around v = 0
    # for a sticking tip.  beta is taken at the slip speed of the step start (lagged one step):
    # with mu_s > mu_d the law is non-monotone in |v| once Delta = Delta_max (the stick-slip drop),
    # and an implicit step through the falling branch has no unique solution for a nearly massless
    # tip; with beta frozen within the step the friction force rises monotonically with |v| and
    # |Delta|, and the break-away still happens, over one step.
    beta = state.beta
    state.bnew = step10(vmag, 0.0, 0.0, v_s, 1.0)
    gst = step10(dmag / dmax, -1.0, -1.0, 1.0, 1.0)
    gsl = step10(vmag / v_d, -1.0, -1.0, 1.0, 1.0)
    fst = (1.0 - beta) * mus * Fn * gst  # eq 8: stiction force magnitude
    fsl = cp.mu_d * Fn * gsl  # eq 9: sliding force magnitude
    ft = tw.ft
    for a in range(3):
        ft[a] = 0.0
    if dmag > 0.0:
        for a in range(3):
            ft[a] -= fst * dn[a] / dmag
    if vmag > 0.0:
        for a in range(3):
            ft[a] -= fsl * vs[a] / vmag
    for a in range(3):  # eq 7: F_mu = F_stiction + F_sliding
        F[a] += ft[a]
        state.ft[a] = ft[a]
    state.slide = 1 if vmag > v_s else 0
    # Exact Newton tangent of F_t w.r.t. pt (beta is frozen within the step):
    # dDelta/dpt = P_t (unclamped), dv/dpt = (c0/h) P_t; for a magnitude f(|x|) along
    # u = x/|x|:  d(-f u)/dx = -f' u u^T - (f/|x|)(P_t - u u^T).
    rate = 0.0 if sub.static else sub.c0 * sub.inv_h
    if dmag > 0.0:
        dfd = 0.0
        if dmag < dmax:
            dfd = (1.0 - beta) * mus * Fn * step10_dx(dmag / dmax, -1.0, -1.0, 1.0, 1.0) / dmax
        ftr = fst / dtrial  # d(Delta_hat)/dpt = (P_t - u u^T) / |Delta_trial|, clamped or not
        for a in range(3):
            ua = dn[a] / dmag
            for bb in range(3):
                ub = dn[bb] / dmag
                pab = (1.0 if a == bb else 0.0) - nrm[a] * nrm[bb]
                Kt[a, bb] -= dfd * ua * ub + ftr * (pab - ua * ub)
    else:  # Delta = 0: the stiction spring's slope at the origin
        kst = (1.0 - beta) * mus * Fn * step10_dx(0.0, -1.0, -1.0, 1.0, 1.0) / dmax
        for a in range(3):
            for bb in range(3):
                Kt[a, bb] -= kst * ((1.0 if a == bb else 0.0) - nrm[a] * nrm[bb])
    if rate > 0.0:
        if vmag > 0.0:
            dfv = cp.mu_d * Fn * step10_dx(vmag / v_d, -1.0, -1.0, 1.0, 1.0) / v_d
            ftr = fsl / vmag
            for a in range(3):
                ua = vs[a] / vmag
                for bb in range(3):
                    ub = vs[bb] / vmag
                    pab = (1.0 if a == bb else 0.0) - nrm[a] * nrm[bb]
                    Kt[a, bb] -= rate * (dfv * ua * ub + ftr * (pab - ua * ub))
        else:
            dfv = cp.mu_d * Fn * step10_dx(0.0, -1.0, -1.0, 1.0, 1.0) / v_d
            for a in range(3):
                for bb in range(3):
                    Kt[a, bb] -= rate * dfv * ((1.0 if a == bb else 0.0) - nrm[a] * nrm[bb])
    # friction is proportional to Fn: dF_t = (F_t / Fn) dFn, dFn = -kk n^T dpt
    for a in range(3):
        for bb in range(3):
            Kt[a, bb] -= kk * ft[a] / Fn * nrm[bb]


#: the friction law of eq 7-10 for the shaft contacts (shaft.py)
friction_load = _friction_load


@njit(**HOT, inline="always")
def _tip_tip_load(b, pt, R, sub, con, state, F, Kt, vt):
    """Tip-tip contact, no friction (Table 3): the normal law of eq 6 with the tip-tip parameters
    along the line of centres, for every listed partner (held at its latest position), in
    series with the two bristles' axial compliances seen along that line (``series_law``)."""
    pair_ptr = con.pair_ptr
    if pair_ptr.shape[0] <= b + 1:
        return
    tips = con.tips
    cp = con.cp[0]
    for q in range(pair_ptr[b], pair_ptr[b + 1]):
        j = con.pair_idx[q]
        d0, d1, d2, dist = _from_partner(pt, tips, j)
        rj = tips[j, 6]
        delta = R + rj - dist
        if dist < 1e-12 or delta <= 0.0:
            continue
        u0 = d0 / dist
        u1 = d1 / dist
        u2 = d2 / dist
        rv = 0.0
        if not sub.static:
            rv = u0 * (vt[0] - tips[j, 3]) + u1 * (vt[1] - tips[j, 4]) + u2 * (vt[2] - tips[j, 5])
        # in series with both bristles' axial compliance along the line of centres (zero for
        # the full chain): with the plate contact compliant and this one stiff, a tip stuck on
        # the plate and pressed by a neighbour's ran Newton out at every halving (~1 bristle-step
        # an env step taken at the last resort, 62 sub-steps each: a third of the env's time)
        u = (u0, u1, u2)
        cs = compliance(con.tip_args[b], u) + compliance(con.tip_args[j], u)
        Fn, kn, cn, _ = series_law(delta, -rv, cp.k_tt, cp.m1_tt, cp.c_tt, cp.m2_tt, cp.m3_tt, cs)
        if Fn <= 0.0:
            continue
        state.ftt += Fn
        kk = kn + (0.0 if sub.static else cn * sub.c0 * sub.inv_h)
        F[0] += Fn * u0
        F[1] += Fn * u1
        F[2] += Fn * u2
        u = (u0, u1, u2)
        # d(Fn u)/dpt = -kk u u^T + (Fn / dist)(I - u u^T): the second (geometric) term is
        # ~10x the bristle's lateral stiffness for a squeezed tip; without it Newton crawls
        geo = Fn / dist
        for a in range(3):
            for bb in range(3):
                Kt[a, bb] += -kk * u[a] * u[bb] + geo * ((1.0 if a == bb else 0.0) - u[a] * u[bb])


@njit(**HOT)
def pair_law(b, j, pj, con, c0_inv_h, f, C):
    """The Table 3 contact of tip b (at con.tips[b]) with partner j held at ``pj`` (3,) [mm]
    (velocities from con.tips): f <- the force on b [N]; C <- dF_b/dp_j [N/mm], the negative of
    the pair's term in b's own tangent (``_tip_tip_load``); c0_inv_h = c0 / h weighs the damping
    (0 for statics).  Returns False (f, C untouched) if the tips do not touch."""
    tips = con.tips
    cp = con.cp[0]
    d0 = tips[b, 0] - pj[0]
    d1 = tips[b, 1] - pj[1]
    d2 = tips[b, 2] - pj[2]
    dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    delta = tips[b, 6] + tips[j, 6] - dist
    if dist < 1e-12 or delta <= 0.0:
        return False
    u = (d0 / dist, d1 / dist, d2 / dist)
    rv = 0.0
    for a in range(3):
        rv += u[a] * (tips[b, 3 + a] - tips[j, 3 + a])
    Fn, kn, cn = normal_law(delta, -rv, cp.k_tt, cp.m1_tt, cp.c_tt, cp.m2_tt, cp.m3_tt)
    if Fn <= 0.0:
        return False
    kk = kn + cn * c0_inv_h
    geo = Fn / dist
    for a in range(3):
        f[a] = Fn * u[a]
        for bb in range(3):
            C[a, bb] = kk * u[a] * u[bb] - geo * ((1.0 if a == bb else 0.0) - u[a] * u[bb])
    return True


@njit(**HOT)
def penetration_step_limit(b, pt, dp, R, con, tw, pmin):
    """Largest fraction of the tip step ``dp`` that keeps every penetration (surfaces and partner
    tips) below twice the current one (at least pmin [mm]: the chain's Newton passes
    PEN_STEP_MIN, the tabulated law's ``prb_kernels.TAB_PEN_MIN``): a Newton iterate coming from
    outside the stiff penalty contact otherwise lands deep inside it, and the next one is thrown
    back out (a limit cycle).  This replaces a "pre-search" tangent, which made Newton converge
    only linearly whenever a tip rests just outside a contact.  A tip with an axial compliance
    (``series_law``) may also reach the overlap that SERIES_ALLOW_LOAD compresses it by.
    tw: ``records.TipScratch``."""
    nrm = tw.pnrm
    cpt = tw.pcpt
    surf = con.surf
    tips = con.tips
    pair_ptr = con.pair_ptr
    amax = 1.0
    for s in range(surf.shape[0]):
        gap = surface_gap(surf, s, pt, nrm, cpt, con.mesh, con.sdf) - R  # < 0: penetrating
        dn = dp[0] * nrm[0] + dp[1] * nrm[1] + dp[2] * nrm[2]
        if dn >= 0.0:
            continue
        allow = max(
            2.0 * max(-gap, 0.0), pmin, compliance(con.tip_args[b], nrm) * SERIES_ALLOW_LOAD
        )
        # penetration after the step: -(gap + a dn) <= allow
        a = (gap + allow) / (-dn)
        if a < amax:
            amax = max(a, 0.0)
    # the same for the partner tips (held fixed), along the current line of centres
    if pair_ptr.shape[0] > b + 1:
        for q in range(pair_ptr[b], pair_ptr[b + 1]):
            j = con.pair_idx[q]
            d0, d1, d2, dist = _from_partner(pt, tips, j)
            if dist < 1e-12:
                continue
            gap = dist - R - tips[j, 6]
            dn = (dp[0] * d0 + dp[1] * d1 + dp[2] * d2) / dist
            if dn >= 0.0 or gap > -dn:  # moving apart, or cannot reach the partner
                continue
            allow = max(2.0 * max(-gap, 0.0), pmin)
            a = (gap + allow) / (-dn)
            if a < amax:
                amax = max(a, 0.0)
    return amax


@njit(**HOT, inline="always")
def in_contact(state):
    """True if the tip's last evaluation touched a surface or a partner tip (fn or ftt > 0)."""
    return state.fn > 0.0 or state.ftt > 0.0


@njit(**HOT)
def slip_step_limit(pt, dp, state, c0, inv_h, v_d):
    """Largest fraction of the tip step ``dp`` that does not carry a sliding tip's slip velocity
    past its turning point.

    Sliding friction has a constant magnitude mu_d Fn for |v| >= v_d, so along the slip direction
    Newton's tangent holds only the bristle's own (soft) stiffness and proposes a tip step that
    reverses the slip, which flips the friction force: the residual then rises at any fraction of
    the step larger than the closest approach of v to zero (at small sub-steps v changes by
    c0 |dp| / h, ~10^3 mm/s per 0.01 mm).  Stopping there (or where the path reaches
    |v| = v_d / 2, whichever comes first) lands in the smooth part of eq 10, where the exact
    tangent converges.  Uses the contact normal of the last evaluation; 1 when not in contact or
    static.
    """
    if state.fn <= 0.0 or inv_h == 0.0:
        return 1.0
    n0 = pt[0] - state.cpt[0]
    n1 = pt[1] - state.cpt[1]
    n2 = pt[2] - state.cpt[2]
    nn = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
    if nn < 1e-12:
        return 1.0
    n0 /= nn
    n1 /= nn
    n2 /= nn
    rate = c0 * inv_h
    v0 = (c0 * (pt[0] - state.pn[0]) + state.hist[0]) * inv_h
    v1 = (c0 * (pt[1] - state.pn[1]) + state.hist[1]) * inv_h
    v2 = (c0 * (pt[2] - state.pn[2]) + state.hist[2]) * inv_h
    w0 = rate * dp[0]
    w1 = rate * dp[1]
    w2 = rate * dp[2]
    vn = v0 * n0 + v1 * n1 + v2 * n2
    wn = w0 * n0 + w1 * n1 + w2 * n2
    v0 -= vn * n0
    v1 -= vn * n1
    v2 -= vn * n2
    w0 -= wn * n0
    w1 -= wn * n1
    w2 -= wn * n2
    vv = v0 * v0 + v1 * v1 + v2 * v2
    if vv <= v_d * v_d:
        return 1.0  # already in the smooth band: the exact tangent holds
    vw = v0 * w0 + v1 * w1 + v2 * w2
    ww = w0 * w0 + w1 * w1 + w2 * w2
    if vw >= 0.0 or ww == 0.0:
        return 1.0  # the slip speed grows along the step
    a_close = -vw / ww  # closest approach of v + a w to zero
    # |v + a w| = v_d / 2 (smaller root): inside the band, where eq 10's step has a slope (it is
    # flat at |v| = v_d, so landing on the band's edge would repeat the overshoot)
    vb = 0.5 * v_d
    disc = vw * vw - ww * (vv - vb * vb)
    a_band = (-vw - np.sqrt(disc)) / ww if disc > 0.0 else a_close
    return min(1.0, a_band, a_close)
