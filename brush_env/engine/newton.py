"""Newton's method on one bristle's (sub)step: direction, step cap, line search, commit.

``newton_solve`` solves the residual of eq 11 (``residual.py``) for the bristle's end-of-step
configuration: start -> predict (``predict.py``) -> [factors -> direction -> cap -> line search]*
-> commit (or restore).  The step cap keeps rotation increments small, holds the tip in a trust
region while in contact and respects the penetration limit (eq 6) and the slip turning point
(eq 7-10); the line search uses the directional derivative dq . r as its merit.  ``_commit``
takes the rates from the two-step formula and commits the stiction deformation (eq 7-10).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._kernels import HOT, block_solve, reorthonormalize, rotate_left
from .contact import PEN_STEP_MIN, in_contact, penetration_step_limit, slip_step_limit
from .near import tip_scene
from .predict import load_chain, predict_start, save_chain, start_state, start_step
from .records import Trial
from .residual import bristle_residual, rebuild_factors, tip_refactor
from .shaft import commit_shaft, shaft_step_limit
from .surfaces import surface_gap

#: [mm] a tip that ends its (sub)step this much deeper in a surface than it started, having met
#: the surface within the step or ending it sliding, has the step split (``_met_within``).  On
#: the plate eq 6 gives 0.24 N at this depth (above the env's 0.2 N tip limit); the 0.25 ms run's
#: tips stay below it under random actions
ONSET_PEN = 1e-2

STAGNATION = 100.0  # accept a stagnating Newton within this factor of the tolerance
MAX_ROT_STEP = 0.5  # [rad] largest rotation increment of one Newton iteration
MAX_TIP_STEP = 0.25  # largest tip displacement of one Newton iteration, in tip radii
#: halvings of a step that is no descent direction of the line search's merit (``_line_search``)
UPHILL_HALVINGS = 20
#: a solve's first such step is taken whole if the residual norm at most rises by this factor
UPHILL_RISE = 2.0
#: Reused Newton factors are rebuilt when an iteration with them reduces the residual by less than
#: SLOW and, at that rate, more than REBUILD_ITERS further iterations would be needed: a rebuild
#: (finite-difference chain Jacobian + factorisation, ~8.5 us at 6 bodies) costs about as much
#: as four iterations with reused factors (~2 us each).
SLOW = 0.1
REBUILD_ITERS = 3.0


@njit(**HOT, inline="always")
def _chain_update(br, model, chain, it, alpha, base, mot):
    """Apply the Newton correction alpha*it.dq to one bristle (from the trial point it.t_pos,
    it.t_rot), rebuilding the chain from the root.

    Rotations: R <- exp(alpha dtheta) R.  Positions: each element's translational strain d gets
    its linearised increment, d <- d + alpha dd, and nodes are rebuilt from the root with the new
    rotations, p_B = p_A + R_A (l e_x + d).  To first order this is the plain update c += alpha dc
    (so Newton keeps its quadratic convergence), but a large rotation increment no longer creates
    spurious axial/shear strain ~ l theta^2/2, which the stiff axial terms would turn into huge
    residuals.
    """
    bp = model.bp
    pos = chain.pos
    rot = chain.rot
    t_pos = it.t_pos
    t_rot = it.t_rot
    dq = it.dq
    pAb = base.pAe
    RAb = base.RAe
    pAo, pBo, dpA, dpB, pAn, dd = mot.pAo, mot.pBo, mot.dpA, mot.dpB, mot.pAn, mot.dd
    for a in range(3):
        pAn[a] = pAb[a]
    for k in range(br.n):
        i = br.b0 + k
        hB = bp[i].half
        rotate_left(alpha * dq[k, 3], alpha * dq[k, 4], alpha * dq[k, 5], t_rot[k], rot[i])
        # old nodes and node increments: dp = dc + dtheta x (R r)
        for a in range(3):
            pBo[a] = t_pos[k, a] + hB * t_rot[k, a, 0]
        rB0 = hB * t_rot[k, 0, 0]
        rB1 = hB * t_rot[k, 1, 0]
        rB2 = hB * t_rot[k, 2, 0]
        dpB[0] = dq[k, 0] + dq[k, 4] * rB2 - dq[k, 5] * rB1
        dpB[1] = dq[k, 1] + dq[k, 5] * rB0 - dq[k, 3] * rB2
        dpB[2] = dq[k, 2] + dq[k, 3] * rB1 - dq[k, 4] * rB0
        if k == 0:
            for a in range(3):
                pAo[a] = pAb[a]
                dpA[a] = 0.0
            t0 = 0.0
            t1 = 0.0
            t2 = 0.0
            RAo = RAb
            RAn = RAb
        else:
            hA = bp[i - 1].half
            RAo = t_rot[k - 1]
            RAn = rot[i - 1]
            rA0 = hA * RAo[0, 0]
            rA1 = hA * RAo[1, 0]
            rA2 = hA * RAo[2, 0]
            for a in range(3):
                pAo[a] = t_pos[k - 1, a] + hA * RAo[a, 0]
            t0 = dq[k - 1, 3]
            t1 = dq[k - 1, 4]
            t2 = dq[k - 1, 5]
            dpA[0] = dq[k - 1, 0] + t1 * rA2 - t2 * rA1
            dpA[1] = dq[k - 1, 1] + t2 * rA0 - t0 * rA2
            dpA[2] = dq[k - 1, 2] + t0 * rA1 - t1 * rA0
        # dd = R_A^T (d(pB - pA) + (pB - pA) x dtheta_A); new d = old d + alpha dd
        x0 = pBo[0] - pAo[0]
        x1 = pBo[1] - pAo[1]
        x2 = pBo[2] - pAo[2]
        v0 = dpB[0] - dpA[0] + x1 * t2 - x2 * t1
        v1 = dpB[1] - dpA[1] + x2 * t0 - x0 * t2
        v2 = dpB[2] - dpA[2] + x0 * t1 - x1 * t0
        for a in range(3):
            dd[a] = (
                RAo[0, a] * (x0 + alpha * v0)
                + RAo[1, a] * (x1 + alpha * v1)
                + RAo[2, a] * (x2 + alpha * v2)
            )  # = l e_x + d_old + alpha dd (A frame)
        for a in range(3):
            pBn = pAn[a] + RAn[a, 0] * dd[0] + RAn[a, 1] * dd[1] + RAn[a, 2] * dd[2]
            pos[i, a] = pBn - hB * rot[i, a, 0]
            pAn[a] = pBn


@njit(**HOT, inline="always")
def _direction(br, jc, ws):
    """it.dq <- the Newton correction -A^-1 r on the current factors (it.r0 keeps r).  Returns
    g0 = dq . r, the line search's slope at alpha = 0."""
    it = ws.it
    b0 = br.b0
    n = br.n
    for k in range(n):
        for a in range(6):
            it.r0[k, a] = it.res[k, a]
            it.res[k, a] = -it.res[k, a]
    block_solve(
        n,
        jc.D[b0 : b0 + n],
        jc.L[b0 : b0 + n],
        jc.G[b0 : b0 + n],
        jc.piv[b0 : b0 + n],
        it.res,
        it.dq,
    )
    g0 = 0.0
    for k in range(n):
        for a in range(6):
            g0 += it.dq[k, a] * it.r0[k, a]
    return g0


@njit(**HOT, inline="always")
def _step_cap(br, model, chain, sub, con, ws):
    """Largest safe fraction alpha of the Newton correction: the rotation increment (keeps the
    log map far from pi), a trust region on the tip's displacement while in contact (the contact
    laws are ~10^3 times stiffer than the bristle, and an unbounded step can throw the tip deep
    into the plate or a neighbour), the penetration limit and the slip turning point
    (contact.py)."""
    it = ws.it
    dq = it.dq
    n = br.n
    dmax = 0.0
    for k in range(n):
        for a in range(3):
            if abs(dq[k, 3 + a]) > dmax:
                dmax = abs(dq[k, 3 + a])
    alpha = 1.0 if dmax <= MAX_ROT_STEP else MAX_ROT_STEP / dmax
    kl = n - 1
    il = br.il
    rot = chain.rot
    hl = model.bp[il].half
    r0x = hl * rot[il, 0, 0]
    r0y = hl * rot[il, 1, 0]
    r0z = hl * rot[il, 2, 0]
    dp = it.dtip
    dp[0] = dq[kl, 0] + dq[kl, 4] * r0z - dq[kl, 5] * r0y
    dp[1] = dq[kl, 1] + dq[kl, 5] * r0x - dq[kl, 3] * r0z
    dp[2] = dq[kl, 2] + dq[kl, 3] * r0y - dq[kl, 4] * r0x
    dtip = np.sqrt(dp[0] * dp[0] + dp[1] * dp[1] + dp[2] * dp[2])
    radius = con.tip_args[br.b].radius
    tip_state = con.tip_state[br.b]
    tipcap = MAX_TIP_STEP * radius
    if in_contact(tip_state) and alpha * dtip > tipcap:
        alpha = tipcap / dtip
    pt = it.tip
    for a in range(3):
        pt[a] = chain.pos[il, a] + hl * rot[il, a, 0]
    # the partners the step can reach: the step's near list where it holds (``near.py``)
    pcon = tip_scene(con, ws.sw.near, br.b, pt, dtip)
    apen = penetration_step_limit(br.b, pt, dp, radius, pcon, ws.tipw, PEN_STEP_MIN)
    if apen < alpha:
        alpha = max(apen, 1e-3)
    if not sub.static:
        aslip = slip_step_limit(pt, dp, tip_state, sub.c0, sub.inv_h, con.cp[0].v_d)
        if aslip < alpha:
            alpha = max(aslip, 1e-4)
    return shaft_step_limit(br, chain, con, dq, alpha)


@njit(**HOT, inline="always")
def _line_search(br, model, chain, sub, base, con, ws, rootw, trial):
    """Move along the correction from the saved trial point (``ws.it.t_pos``/``t_rot``); returns
    (accepted, residual norm, alpha taken).  ``trial``: ``Trial(alpha, g0, nrm, whole, fresh)``,
    the capped step, the slope dq . r at alpha = 0, the residual norm there, whether a direction
    uphill of the merit may be taken whole and whether the factors are fresh.  Not accepted: the
    bristle is back at the trial point, and with old factors the norm returned is its residual's
    (the solve goes on with fresh factors from there).

    The merit is the directional derivative g(alpha) = dq . r(q + alpha dq) (the energy-like
    measure of structural Newton solvers): the residual norm itself is a poor merit here, because
    the stiff axial/shear terms react to second-order geometry.  On overshoot (g changed sign) the
    next alpha is the secant estimate of the zero of g, safeguarded.  A direction along which g
    starts uphill (g0 >= 0: old factors, or a kink of the friction or contact law) is taken
    whole the first time in a solve (``trial.whole``) if the residual norm at most doubles
    (UPHILL_RISE), and otherwise halved until the residual norm falls (up to UPHILL_HALVINGS
    times): taking every such step whole closed a limit cycle, halving every one cost the tooth
    row 27 % more Newton iterations (docs/benchmarks.md, session 34)."""
    it = ws.it
    alpha = trial.alpha
    g0 = trial.g0
    new = np.inf
    tries = 8 if g0 < 0.0 else UPHILL_HALVINGS
    for ls in range(tries + 1):
        if ls < tries:
            _chain_update(br, model, chain, it, alpha, base, ws.mot)
        else:
            # out of tries: back to the trial point, and (old factors: the solve goes on with
            # fresh ones) its residual -- at this one call site: the residual is inlined, and
            # each copy costs compile time (docs/benchmarks.md, session 35)
            load_chain(br, chain.pos, chain.rot, it.t_pos, it.t_rot)
            if trial.fresh:
                return False, new, alpha
        new = bristle_residual(br, model, chain, sub, base, con, ws, rootw)
        if ls == tries:
            return False, new, alpha
        if not np.isfinite(new):
            alpha *= 0.25
            continue
        if g0 >= 0.0 and trial.whole and new <= UPHILL_RISE * trial.nrm:
            # the solve's first uphill direction, taken whole when the residual at most doubles
            # (a non-monotone step: on curved surfaces such steps mostly pay; once per solve and
            # bounded, the rise cannot repeat in a cycle)
            return True, new, alpha
        if g0 >= 0.0:
            # dq is no descent direction of the merit (a kink of the friction or contact law
            # between the iterate and the factors' point): taken whole, such a step raised the
            # residual 12x and closed a four-iteration limit cycle at every halving of a deep
            # sliding press (the 7 GPa press, docs/benchmarks.md, session 33); backtrack on the
            # residual norm, which every Newton direction of fresh factors descends
            if new <= sub.rtol or new < trial.nrm:
                return True, new, alpha
            alpha *= 0.5
            continue
        ga = 0.0
        for k in range(br.n):
            for a in range(6):
                ga += it.dq[k, a] * it.res[k, a]
        if new <= sub.rtol or ga <= 0.5 * abs(g0) or new < 0.9 * trial.nrm:
            return True, new, alpha
        alpha = max(0.1 * alpha, min(0.9 * alpha, alpha * (-g0) / (ga - g0)))
    return False, new, alpha  # (not reached: the last try returns)


@njit(**HOT, inline="always")
def _stale(fresh, alpha, new, nrm, rtol):
    """True if the factors should be rebuilt before the next iteration: the step was cut (the
    factors no longer describe the way down), or old factors converge so slowly that finishing
    at this rate costs more than a rebuild."""
    if alpha < 1.0:
        return True
    if not fresh and new > SLOW * nrm and new > rtol:
        rho = new / nrm
        return rho >= 1.0 or np.log(rtol / new) / np.log(rho) > REBUILD_ITERS
    return False


@njit(**HOT, inline="always")
def _update_negligible(br, model, chain, it, alpha):
    """True if |alpha dq| is at the level of the coordinates' last bits (a round-off floor)."""
    stepmax = 0.0
    for k in range(br.n):
        for a in range(3):
            v = abs(alpha * it.dq[k, a]) / (
                abs(chain.pos[br.b0 + k, a]) + model.bp[br.b0 + k].length
            )
            if v > stepmax:
                stepmax = v
            v = abs(alpha * it.dq[k, 3 + a])
            if v > stepmax:
                stepmax = v
    return stepmax < 1e-13


@njit(**HOT, inline="always")
def _commit(br, chain, sub, con, ws):
    """Accept the step: commit the stiction deformation and beta (eq 7-10), rates from the
    discrete formula, shift the history (t_n -> t_{n-1} -> t_{n-2}).

    The angular rates take each body's rotation vector log(R R_n^T) from the last residual
    evaluation (hist.thn): every path to a commit ends with a residual at the committed iterate
    (the predictor's or the accepted line-search point), so this is the rate the converged
    momentum balance used -- six rotation logs a bristle-step fewer (issue 32, session 37).  The
    rotations are then re-orthonormalised for the next step (a round-off change: before,
    the rate was taken after it)."""
    it = ws.it
    hist = ws.hist
    tip_state = con.tip_state[br.b]
    for a in range(3):
        tip_state.delta[a] = tip_state.dnew[a]
    tip_state.beta = tip_state.bnew
    commit_shaft(br, con)
    pos, rot = chain.pos, chain.rot
    for k in range(br.n):
        i = br.b0 + k
        reorthonormalize(rot[i])  # see the kernel: keeps the chain update free of drift
        if sub.static:
            for a in range(3):
                chain.vel[i, a] = 0.0
                chain.omg[i, a] = 0.0
        else:
            th = hist.thn[k]
            for a in range(3):
                chain.vel[i, a] = (sub.c0 * pos[i, a] + hist.cm[k, a]) * sub.inv_h
                chain.omg[i, a] = (sub.c0 * th[a] + hist.thp[k, a]) * sub.inv_h
        for a in range(3):
            chain.pppos[i, a] = chain.ppos[i, a]
            chain.ppos[i, a] = it.s_pos[k, a]
            chain.pvel[i, a] = it.s_vel[k, a]
            chain.pomg[i, a] = it.s_omg[k, a]
            for bb in range(3):
                chain.pprot[i, a, bb] = chain.prot[i, a, bb]
                chain.prot[i, a, bb] = it.s_rot[k, a, bb]


@njit(**HOT, inline="always")
def _met_within(br, con, ws):
    """True if bristle br's tip, at its converged iterate, sank more than ONSET_PEN deeper into a
    surface than it was at the (sub)step's start (tip_state.pn, ``start_step``): a tip that met
    the surface, or slipped and dived into it, within the step, where one implicit step puts the
    whole approach into the penalty law at once (a one-step force spike that a shorter step does
    not show)."""
    st = con.tip_state[br.b]
    if st.pen <= ONSET_PEN:
        return False
    surf = con.surf
    R = con.tip_args[br.b].radius
    tw = ws.tipw
    # the start's tip node as a plain array: the record's field (a nested array) is another type,
    # for which numba compiled every surface's gap kernel a second time (issue 32, session 36)
    pn = ws.it.tip
    for a in range(3):
        pn[a] = st.pn[a]
    pen0 = 0.0
    for k in range(surf.shape[0]):
        pen0 = max(pen0, R - surface_gap(surf, k, pn, tw.pnrm, tw.pcpt, con.mesh, con.sdf))
    # ... a tip that met it (clear at the start) or ends the step sliding; a stuck tip pressed
    # deeper (a column loaded past its buckling load, which buckles) is left to the step: halving
    # it kept one such bristle straight at 1.8 N where the 0.25 ms run buckles (seed 7)
    return st.pen - pen0 > ONSET_PEN and (pen0 <= 0.0 or st.slide != 0)


@njit(**HOT)
def newton_solve(br, model, chain, sub, base, con, jc, ws, rootw, attempt):
    """One implicit (sub)step of one bristle, in place.  Returns (converged, iterations).

    Start-of-step values are in chain.pos/rot/vel/omg (t_n) and chain.ppos/... (t_{n-1}); the
    base node moves from (pAs, RAs) to (pAe, RAe) of ``base``.  On failure the bristle's arrays
    are left at their start-of-step values.  ``jc``: factored Newton matrices kept per bristle
    across steps (simplified Newton), rebuilt when the step size or scheme changes (key c0/h),
    when older than sub.jage steps, and whenever old factors converge slowly or fail their line
    search: the converged state is always set by the residual, the factors' age only changes the
    iteration count.  ``attempt`` (``records.Attempt``): the predictor's order, and whether a
    converged step whose tip dived into a surface is refused (``_met_within``) so that the
    caller halves it.  Stages: start -> predict -> [factors -> direction -> cap -> line search]*
    -> check -> commit (or restore).
    """
    b = br.b
    start_step(br, model, chain, sub, base, con, ws, jc)
    nrm = predict_start(br, model, chain, sub, base, con, ws, rootw, attempt.extrap)
    rtol = sub.rtol
    it = 0
    ok = nrm <= rtol
    key = -1.0 if sub.static else sub.c0 * sub.inv_h
    jc.age[b] += 1
    need = jc.key[b] != key or jc.age[b] > sub.jage
    whole = True  # the solve's first direction uphill of the merit is taken whole
    while not ok and it < sub.maxit and np.isfinite(nrm):
        it += 1
        fresh = need
        if need:
            if not rebuild_factors(br, model, chain, sub, base, jc, ws, key):
                break
            need = False
        elif in_contact(con.tip_state[b]):
            # contact: the tip block at the current load, on the reused chain factors
            D = jc.D[br.b0 : br.b0 + br.n]
            if not tip_refactor(
                br, D, jc.piv[br.b0 : br.b0 + br.n], jc.S[b], model.bp, chain.rot, ws
            ):
                need = True
                it -= 1
                continue
        g0 = _direction(br, jc, ws)
        save_chain(br, chain.pos, chain.rot, ws.it.t_pos, ws.it.t_rot)
        alpha = _step_cap(br, model, chain, sub, con, ws)
        trial = Trial(alpha, g0, nrm, whole, fresh)
        accepted, new, alpha = _line_search(br, model, chain, sub, base, con, ws, rootw, trial)
        if g0 >= 0.0:
            whole = False
        if not accepted:
            # the iterate restored (``_line_search``); retry with fresh factors unless they
            # were fresh already (then ``new`` is the residual at the restored iterate)
            if fresh:
                break
            need = True
            nrm = new
            continue
        if fresh and new > 0.5 * nrm and new <= STAGNATION * rtol:
            # stagnation: a fresh Newton step no longer reduces a residual already within
            # STAGNATION x the tolerance (observed floors 1e-7..1e-6 relative to E I / L^2 for tips
            # sticking in friction contact, i.e. ~1e-9 N): accept rather than sub-step
            nrm = new
            ok = True
            break
        need = _stale(fresh, alpha, new, nrm, rtol)
        nrm = new
        ok = nrm <= rtol
        # round-off floor: the update no longer moves the state and the residual is within 100x
        # of the tolerance: accept (tested only when not converged: it is ~70 divisions)
        if not ok and nrm <= 100.0 * rtol and _update_negligible(br, model, chain, ws.it, alpha):
            ok = True
            break
    if not ok or (attempt.split and _met_within(br, con, ws)):
        start_state(br, chain, ws.it, False)  # restore (a contact met within: halved)
        return False, it
    _commit(br, chain, sub, con, ws)
    return True, it
