"""Kernels of the tabulated tip law (``tip_table.py``, issue 29): the reduced chain's elastic
law as a function of its tip's position, built once per bristle type and looked up per step.

The reduced chain (``prb_kernels``: a stub s0 clamped at the root, links l1 and l2 on two
bending joints, a twist at joint 1) holds its tip at x (bristle frame, x along the axis) in
equilibrium where its spring energy E(q) is least among the joint angles q that put the tip
there.  The tip fixes three of the five coordinates: the elbow (the joint between the links)
lies on the circle of points l1 from joint 1 (J1 = s0 e1) and l2 from x, at an angle psi about
the chord J1 -> x, and the twist t is free.  So

    U_s(x) = min over (psi, t) on branch s of E(q(x, psi, t)),

and the tip is in equilibrium under a load F where F = grad U_s(x) (the envelope theorem: the
gradient at fixed psi and t).  A bristle pressed past its buckling load has two such minima:
its elbow thrown to one side of the chord or to the other along the section's thin direction
(local z) -- the two branches s = 0 (elbow toward +z) and s = 1 (toward -z); where there is only
one minimum both branches hold it.  A branch that stops existing under the tip is the snap-
through; staying on a branch while it exists is the hysteresis.

The table stores, on a grid of the tip's spherical coordinates about J1 -- rho (the chord's
length), theta (its angle from the axis) and phi (its azimuth from local y toward z, -pi/2 to
pi/2: the chain is its own mirror image across its x-z plane, which turns b1, b2 and t and keeps
the branch, so a tip at -y is looked up at +y and mirrored back) -- for each branch: valid, U,
grad U (3), the damping matrix D (6) of the joints' stiffness-proportional damping seen at the
tip (dq/dx^T K dq/dx) and the joint angles q (5) (for drawing and the state), all in the bristle
frame. The chain is stiff along its
chord and soft across it, so the layers in rho follow the tip's unloaded path: rho_nat(theta,
phi), where the energy along the ray from J1 is least (the chord of a tip pushed sideways only;
a grid of constant rho crossed that path, and its nodes off the path carried the chain's
stretching, which a 1 mN side load's interpolated deflection missed by 21 %). Above the path
(the chain pulled straighter) nu layers up to rho_cap, below it the rest down to rho_min, spaced
by u = ALPHA s + (1 - ALPHA) s^2 of the span (s uniform: fine and even near the path, coarser
far from it); theta on [0, theta_max]; phi on [-pi/2, pi/2].
"""

from __future__ import annotations

from collections import namedtuple

import numpy as np
from numba import njit

#: the builder runs once per bristle type, off the step: it may allocate (HOT may not)
BUILD = dict(cache=True, fastmath=False)

#: one table's grid (a record): the longest and shortest chord in it (rcap, rmin [mm]), the
#: largest angle from the axis (tmax [rad]), the nodes along rho (nr; nu of them above the
#: unloaded path), theta (nt) and phi (np), the layers' linear share alpha, the chain (geo:
#: s0, l1, l2 [mm]).  The unloaded path's chords rho_nat (nt, np) [mm] travel beside it.
GRID = np.dtype(
    [
        ("rcap", "f8"),
        ("rmin", "f8"),
        ("tmax", "f8"),
        ("nr", "i8"),
        ("nt", "i8"),
        ("np", "i8"),
        ("nu", "i8"),
        ("alpha", "f8"),
        ("geo", "f8", 3),
    ]
)
#: one node's entry per branch (module docstring): whether the branch exists (ok), U [N mm],
#: grad U (g [N]), the damping matrix (D [N/mm per unit of beta/h]: xx, yy, zz, xy, xz, yz) and
#: the joint angles q [rad]; built in double
ENTRY = np.dtype([("ok", "f8"), ("U", "f8"), ("g", "f8", 3), ("D", "f8", 6), ("q", "f8", 5)])
#: ... and stored in single precision: 16 floats, one 64-byte cache line -- a lookup reads 8
#: corners, 8 lines with the entries aligned to lines (``tip_table.ALIGN``).  (grad U's Hessian,
#: built and stored until 2026-11-27, was never read: Newton's tangent is the interpolant's own
#: derivative; dropped with each node's own dq/dx, ``grid_damping``)
ENTRY32 = np.dtype([("ok", "f4"), ("U", "f4"), ("g", "f4", 3), ("D", "f4", 6), ("q", "f4", 5)])
#: one table as the kernels read it: grid (GRID record), rnat (nt, np) [mm], vals (2, nr, nt,
#: np) ENTRY32
Table = namedtuple("Table", ["grid", "rnat", "vals"])
#: elbow angles sampled per node in the search for the energy's minima
NPSI = 48
#: [rad] a minimum within this of the plane of the chord and local y belongs to both branches
ON_PLANE = 1e-3
#: the elbow's least distance from the chord in a table entry, in the links' length
STRAIGHT = 5e-3
#: [rad] a joint turned further than this from rest is off the table (a link folded back)
FOLDED = 2.5
#: [rad] the elbow angle's and twist's Newton step at which a minimum is converged
STEP_TOL = 1e-10
#: [rad] ... or a link turned further than this about local z (b1, b2 = asin(...): undefined
#: at pi/2)
SIDEWAYS = 1.3
#: Hessian index pairs of the 6 stored entries (xx, yy, zz, xy, xz, yz)
IH = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))


@njit(**BUILD, inline="always")
def _w(e, c3):
    """(energy / k, its second derivative) of a bending spring turned by e [rad]: the integral
    of ``prb_kernels._spring``'s torque e + c3 e^3, continued linearly (slope 1/2) past the
    turn where a softening cubic has lost half its slope."""
    if c3 >= 0.0 or e * e <= -0.5 / (3.0 * c3):
        return 0.5 * e * e + 0.25 * c3 * e * e * e * e, 1.0 + 3.0 * c3 * e * e
    em = np.sqrt(-0.5 / (3.0 * c3))
    wm = 0.5 * em * em + 0.25 * c3 * em * em * em * em
    tm = em * (1.0 + c3 * em * em)
    d = abs(e) - em
    return wm + tm * d + 0.25 * d * d, 0.5


@njit(**BUILD)
def energy(q, j):
    """Spring energy [N mm] of the chain with joints j (``prb_kernels.JOINT``) at q (a1, b1,
    a2, b2, t): the bending joints' cubic springs and the linear twist (``prb_kernels._evaluate``'s
    torques integrated)."""
    k, c3, rest = j.k, j.c3, j.rest
    e = 0.0
    for i in range(4):
        e += k[i] * _w(q[i] - rest[i], c3[i])[0]
    t = q[4] - rest[4]
    return e + 0.5 * k[4] * t * t


@njit(cache=True, _nrt=False, fastmath=False, inline="always")
def chord_frame(u, fr):
    """fr (3, 3) <- the rotation that takes e1 to the unit vector u along the great circle
    (singular only at u = -e1, outside every table): its columns 1 and 2 are the chord's
    reference directions for the elbow angle (e2 and e3 turned with it)."""
    c = u[0]
    # axis e1 x u = (0, -u2, u1), sin = its length; R = c I + [a]x + (1 - c)/(s^2) a a^T
    a1, a2 = -u[2], u[1]
    f = 1.0 / (1.0 + c)
    fr[0, 0] = c
    fr[0, 1] = -a2
    fr[0, 2] = a1
    fr[1, 0] = a2
    fr[1, 1] = c + f * a1 * a1
    fr[1, 2] = f * a1 * a2
    fr[2, 0] = -a1
    fr[2, 1] = f * a1 * a2
    fr[2, 2] = c + f * a2 * a2


@njit(**BUILD)
def ik(x, psi, t, geo, q, fr):
    """q (5,) <- the joint angles that put the tip at x (bristle frame [mm]) with the elbow at
    angle psi [rad] about the chord from joint 1 and twist t [rad]; geo = (s0, l1, l2).  False
    if x is out of reach (q then undefined).  The inverse of ``prb_kernels.kinematics``."""
    s0, l1, l2 = geo[0], geo[1], geo[2]
    u0, u1, u2 = x[0] - s0, x[1], x[2]
    rho = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    if rho > l1 + l2 or rho < abs(l1 - l2) or rho == 0.0:
        return False
    u = np.empty(3)
    u[0], u[1], u[2] = u0 / rho, u1 / rho, u2 / rho
    if u[0] <= -1.0 + 1e-12:
        return False
    chord_frame(u, fr)
    a = (l1 * l1 - l2 * l2 + rho * rho) / (2.0 * rho)
    r = np.sqrt(max(l1 * l1 - a * a, 0.0))
    cp, sp = np.cos(psi), np.sin(psi)
    d1 = np.empty(3)
    d2 = np.empty(3)
    for i in range(3):
        o = cp * fr[i, 1] + sp * fr[i, 2]
        d1[i] = (a * u[i] + r * o) / l1
        d2[i] = (rho * u[i] - a * u[i] - r * o) / l2
    ct, st = np.cos(t), np.sin(t)
    # v = Rx(-t) d1 = Ry(a1) Rz(b1) e1 = (cos a1 cos b1, sin b1, -sin a1 cos b1)
    v0, v1, v2 = d1[0], ct * d1[1] + st * d1[2], -st * d1[1] + ct * d1[2]
    b1 = np.arcsin(min(max(v1, -1.0), 1.0))
    a1 = np.arctan2(-v2, v0)
    # w = R1^T d2 = Rz(-b1) Ry(-a1) Rx(-t) d2
    w0, w1, w2 = d2[0], ct * d2[1] + st * d2[2], -st * d2[1] + ct * d2[2]
    ca, sa = np.cos(a1), np.sin(a1)
    w0, w2 = ca * w0 - sa * w2, sa * w0 + ca * w2
    cb, sb = np.cos(b1), np.sin(b1)
    w0, w1 = cb * w0 + sb * w1, -sb * w0 + cb * w1
    q[0] = a1
    q[1] = b1
    q[2] = np.arctan2(-w2, w0)
    q[3] = np.arcsin(min(max(w1, -1.0), 1.0))
    q[4] = t
    return True


@njit(**BUILD)
def _e_at(x, psi, t, j, q, fr):
    if not ik(x, psi, t, j.geo, q, fr):
        return np.inf
    return energy(q, j)


@njit(**BUILD)
def _min_twist(x, psi, t, j, q, fr):
    """(t, E): the twist that minimises the energy at elbow angle psi, by Newton on finite
    differences from t."""
    h = 1e-5
    e0 = _e_at(x, psi, t, j, q, fr)
    for _ in range(8):
        ep = _e_at(x, psi, t + h, j, q, fr)
        em = _e_at(x, psi, t - h, j, q, fr)
        d1 = (ep - em) / (2.0 * h)
        d2 = (ep - 2.0 * e0 + em) / (h * h)
        dt = -d1 / d2 if d2 > 0.0 else -0.05 * np.sign(d1)
        dt = min(max(dt, -0.2), 0.2)
        tn = t + dt
        en = _e_at(x, psi, tn, j, q, fr)
        while en > e0 and abs(dt) > 1e-12:
            dt *= 0.5
            tn = t + dt
            en = _e_at(x, psi, tn, j, q, fr)
        if en > e0:
            break
        t, e0 = tn, en
        if abs(dt) < 1e-10:
            break
    return t, e0


@njit(**BUILD)
def local_min(x, psi, t, j, q, fr):
    """(psi, t, E, ok): the energy's minimum over (psi, t) nearest the start, by Newton on
    finite differences with backtracking, and the steepest descent where Newton's step does not
    lower the energy (an indefinite Hessian, or differences too coarse for it).  ok: Newton's
    step fell below STEP_TOL [rad] (or the gradient below 1e-12 of the springs' largest)."""
    h = 1e-5
    gtol = 1e-9 * max(j.k[0], j.k[1], j.k[2], j.k[3])
    e0 = _e_at(x, psi, t, j, q, fr)
    if not np.isfinite(e0):
        return psi, t, e0, False
    conv = False
    for _ in range(80):
        epp = _e_at(x, psi + h, t, j, q, fr)
        epm = _e_at(x, psi - h, t, j, q, fr)
        etp = _e_at(x, psi, t + h, j, q, fr)
        etm = _e_at(x, psi, t - h, j, q, fr)
        e11 = _e_at(x, psi + h, t + h, j, q, fr)
        e22 = _e_at(x, psi - h, t - h, j, q, fr)
        gp = (epp - epm) / (2.0 * h)
        gt = (etp - etm) / (2.0 * h)
        hpp = (epp - 2.0 * e0 + epm) / (h * h)
        htt = (etp - 2.0 * e0 + etm) / (h * h)
        hpt = (e11 - epp - etp + 2.0 * e0 - epm - etm + e22) / (2.0 * h * h)
        det = hpp * htt - hpt * hpt
        # converged when Newton's step is below STEP_TOL (the load's error is the angles' error
        # times the energy's cross slope in x: a nearly straight chain's energy is flat in the
        # elbow's angle, and a small gradient there left the load 7e-4 off)
        if hpp > 0.0 and det > 0.0:
            sp = (htt * gp - hpt * gt) / det
            st = (hpp * gt - hpt * gp) / det
            if max(abs(sp), abs(st)) < STEP_TOL:
                conv = True
                break
        if max(abs(gp), abs(gt)) < 1e-3 * gtol:
            conv = True
            break
        moved = False
        for attempt in range(2):
            if attempt == 0 and hpp > 0.0 and det > 0.0:
                dp = -(htt * gp - hpt * gt) / det
                dt = -(hpp * gt - hpt * gp) / det
            elif attempt == 0:
                continue
            else:  # steepest descent, scaled by the diagonal's size
                sc = 1.0 / max(abs(hpp), abs(htt), 1e-9)
                dp, dt = -gp * sc, -gt * sc
            m = max(abs(dp), abs(dt))
            if m > 0.2:
                dp *= 0.2 / m
                dt *= 0.2 / m
            if attempt == 0 and m < 1e-6:
                # near the minimum the energy changes below its round-off: Newton's step taken
                # as it is (a line search cannot see it)
                psi += dp
                t += dt
                e0 = _e_at(x, psi, t, j, q, fr)
                moved = True
                break
            for _ in range(40):
                en = _e_at(x, psi + dp, t + dt, j, q, fr)
                if en < e0:
                    break
                dp *= 0.5
                dt *= 0.5
            if en < e0:
                psi += dp
                t += dt
                e0 = en
                moved = True
                break
        if not moved:
            break
    return psi, t, e0, conv


@njit(**BUILD)
def minima(x, j, out, q, fr):
    """The energy's minima over the elbow angle (the twist minimised at each) at the tip x:
    out (4, 3) rows (psi, t, E), returns how many (at most 4)."""
    ev = np.empty(NPSI)
    tv = np.empty(NPSI)
    t = j.rest[4]
    for i in range(NPSI):
        psi = 2.0 * np.pi * i / NPSI
        # the twist has minima of its own (the bend turned over toward the thin side, or not):
        # from the last elbow angle's and from rest, the lower
        t, e = _min_twist(x, psi, t, j, q, fr)
        t2, e2 = _min_twist(x, psi, j.rest[4], j, q, fr)
        if e2 < e:
            t, e = t2, e2
        ev[i] = e
        tv[i] = t
    n = 0
    for i in range(NPSI):
        em, ep = ev[(i - 1) % NPSI], ev[(i + 1) % NPSI]
        if ev[i] < em and ev[i] <= ep and n < 4:
            psi, tt, e, ok = local_min(x, 2.0 * np.pi * i / NPSI, tv[i], j, q, fr)
            if not ok:
                continue
            psi = psi % (2.0 * np.pi)
            dup = False
            for r in range(n):
                d = abs(psi - out[r, 0])
                if min(d, 2.0 * np.pi - d) < 1e-4:
                    dup = True
            if not dup:
                out[n, 0], out[n, 1], out[n, 2] = psi, tt, e
                n += 1
    return n


@njit(**BUILD)
def _e_near(x, psi, t, j, q, fr, q0):
    """The energy at (x, psi, t) with every angle taken within pi of q0's (atan2 wraps at pi:
    a link folded back past it would jump by 2 pi between two neighbouring tips)."""
    if not ik(x, psi, t, j.geo, q, fr):
        return np.inf
    for i in range(5):
        q[i] = q0[i] + ((q[i] - q0[i] + np.pi) % (2.0 * np.pi) - np.pi)
    return energy(q, j)


@njit(**BUILD)
def envelope_grad(x, psi, t, j, g, q, fr, h):
    """g (3,) <- grad U at x [N]: the energy's gradient in x at fixed (psi, t), central
    differences of step h [mm] (one-sided where x + h is out of reach)."""
    xp = np.empty(3)
    q0 = np.empty(5)
    ik(x, psi, t, j.geo, q0, fr)
    e0 = energy(q0, j)
    for a in range(3):
        for c in range(3):
            xp[c] = x[c]
        xp[a] = x[a] + h
        ep = _e_near(xp, psi, t, j, q, fr, q0)
        xp[a] = x[a] - h
        em = _e_near(xp, psi, t, j, q, fr, q0)
        if np.isfinite(ep) and np.isfinite(em):
            g[a] = (ep - em) / (2.0 * h)
        else:
            g[a] = (ep - e0) / h if np.isfinite(ep) else (e0 - em) / h


@njit(**BUILD)
def node_values(x, psi, t, e, j, h, out, q, fr):
    """out (an ENTRY record) <- one branch's values at x from its minimum (psi, t, E): U,
    grad U and q; D is left for ``grid_damping`` (from the joint angles of the neighbouring
    nodes).  h [mm]: the scale of the load's differences."""
    geo = j.geo
    out.ok = 1.0
    out.U = e
    # the load's differences: a thousandth of h or of the elbow's distance from the chord (the
    # load turns faster the straighter the chain)
    rho = np.sqrt((x[0] - geo[0]) ** 2 + x[1] ** 2 + x[2] ** 2)
    a = (geo[1] ** 2 - geo[2] ** 2 + rho * rho) / (2.0 * rho)
    he = 1e-3 * min(h, np.sqrt(max(geo[1] ** 2 - a * a, 0.0)))
    g0 = np.empty(3)
    envelope_grad(x, psi, t, j, g0, q, fr, he)
    q0 = np.empty(5)
    ik(x, psi, t, geo, q0, fr)
    for a in range(3):
        out.g[a] = g0[a]
    for i in range(5):
        out.q[i] = q0[i]
        q[i] = q0[i]
    for m in range(6):
        out.D[m] = 0.0


@njit(**BUILD, inline="always")
def _ray_x(grid, rho, jj, m, x):
    """x (3,) <- the tip [mm] at chord rho on the ray (jj, m)."""
    th = grid.tmax * jj / (grid.nt - 1)
    ph = np.pi * (m / (grid.np - 1) - 0.5)
    x[0] = grid.geo[0] + rho * np.cos(th)
    x[1] = rho * np.sin(th) * np.cos(ph)
    x[2] = rho * np.sin(th) * np.sin(ph)


@njit(**BUILD)
def node_rho(tb, i, jj, m):
    """The chord [mm] of layer i on the ray (jj, m) of table tb (module docstring)."""
    grid = tb.grid
    nr, nu, al = grid.nr, grid.nu, grid.alpha
    rn = tb.rnat[jj, m]
    if i < nu:
        s = (nu - i) / nu
        return rn + (grid.rcap - rn) * (al * s + (1.0 - al) * s * s)
    s = (i - nu) / (nr - 1 - nu)
    return rn - (rn - grid.rmin) * (al * s + (1.0 - al) * s * s)


@njit(**BUILD)
def node_x(tb, i, jj, m, x):
    """x (3,) <- the tip position [mm] (bristle frame) of node (i, jj, m) of table tb."""
    _ray_x(tb.grid, node_rho(tb, i, jj, m), jj, m, x)


@njit(**BUILD)
def build(tb, j):
    """tb.rnat and tb.vals (2, nr, nt, np) ENTRY <- the unloaded path and both branches' values
    at every node of the chain with joints j (module docstring; the damping matrices zero until
    ``grid_damping``).  One thread: numba's parallel
    loops do not take the records (GRID, JOINT) this reads."""
    build_rnat(tb, j)
    for i in range(tb.grid.nr):
        build_layer(tb, j, i)


@njit(**BUILD)
def grid_damping(tb, j):
    """Every entry's D <- dq/dx^T K dq/dx with dq/dx from the branch's joint angles at the
    neighbouring nodes (central differences along the grid's three directions where both
    neighbours hold the branch, one-sided where one does; solved for dq/dx from the nodes'
    positions, least squares where a direction has none).

    Each node's own D (until 2026-11-27 ``node_values`` differenced the branch's minima 0.01
    mm apart) is dq/dx of the chain's equilibria at a point, which grows without bound toward a
    branch's end (the snap-through) and a chain pulled straight: interpolated over the ~0.1 mm
    cells beside such a node it
    multiplied the damping of tips that move as gently as the rest by 10-20 (the largest
    eigenvalue 47 where the equilibria 0.003-0.03 mm apart give dq/dx of at most 1.5 rad/mm)
    and threw a dragged brush's 20 tips into the plate at 0.84 N each, against 0.11 N in the
    chain's own Newton (docs/model.md, 2026-11-27).  Differenced between nodes, dq/dx is the
    joints' turn across a cell, bounded by it, as is the damping of a step that crosses it."""
    grid, vals = tb.grid, tb.vals
    kd = np.empty(5)
    xa = np.empty(3)
    xb = np.empty(3)
    X = np.zeros((3, 3))
    Q = np.zeros((3, 5))
    idx = np.empty(3, np.int64)
    node = np.empty(3, np.int64)
    for s in range(2):
        for i in range(grid.nr):
            for jj in range(grid.nt):
                for m in range(grid.np):
                    v = vals[s, i, jj, m]
                    if v.ok == 0.0:
                        continue
                    node[0], node[1], node[2] = i, jj, m
                    for d in range(3):
                        _grid_row(tb, s, node, d, X, Q, xa, xb, idx)
                    # X G = Q for G = (dq/dx)^T (3, 5): least squares (a direction without
                    # neighbours, or the axis where phi does not move the node, adds nothing)
                    G = np.linalg.pinv(X) @ Q
                    for r in range(4):
                        kd[r] = j.k[r] * _w(v.q[r] - j.rest[r], j.c3[r])[1]
                    kd[4] = j.k[4]
                    for n in range(6):
                        a, c = IH[n]
                        dd = 0.0
                        for r in range(5):
                            dd += kd[r] * G[a, r] * G[c, r]
                        v.D[n] = dd


@njit(**BUILD)
def _has_branch(tb, s, idx):
    """Whether node idx (layer, theta, phi) lies in table tb and holds branch s."""
    g = tb.grid
    if idx[0] < 0 or idx[0] >= g.nr or idx[1] < 0 or idx[1] >= g.nt:
        return False
    if idx[2] < 0 or idx[2] >= g.np:
        return False
    return tb.vals[s, idx[0], idx[1], idx[2]].ok != 0.0


@njit(**BUILD)
def _grid_row(tb, s, node, d, X, Q, xa, xb, idx):
    """Row d of ``grid_damping``'s system: X[d] <- the position difference [mm] and Q[d] <- the
    joint angles' [rad] between the neighbours of node (layer, theta, phi) along direction d on
    branch s -- both, or one and the node itself; zeros where neither holds it."""
    i, jj, m = node[0], node[1], node[2]
    for a in range(3):
        X[d, a] = 0.0
    for r in range(5):
        Q[d, r] = 0.0
    idx[0], idx[1], idx[2] = i, jj, m
    idx[d] += 1
    hi_ok = _has_branch(tb, s, idx)
    idx[d] -= 2
    lo_ok = _has_branch(tb, s, idx)
    if not (hi_ok or lo_ok):
        return
    if not lo_ok:  # the lower end: the neighbour below, else the node itself
        idx[d] += 1
    node_x(tb, idx[0], idx[1], idx[2], xb)
    qb = tb.vals[s, idx[0], idx[1], idx[2]].q
    idx[0], idx[1], idx[2] = i, jj, m
    if hi_ok:
        idx[d] += 1
    node_x(tb, idx[0], idx[1], idx[2], xa)
    qa = tb.vals[s, idx[0], idx[1], idx[2]].q
    for a in range(3):
        X[d, a] = xa[a] - xb[a]
    for r in range(5):
        Q[d, r] = qa[r] - qb[r]


@njit(**BUILD)
def build_rnat(tb, j):
    """tb.rnat <- the unloaded path's chords (the layers' reference: ``node_rho``)."""
    grid = tb.grid
    for jj in range(grid.nt):
        for m in range(grid.np):
            if jj == 0 and m > 0:
                continue
            tb.rnat[jj, m] = _natural_rho(grid, j, jj, m)
    for m in range(1, grid.np):
        tb.rnat[0, m] = tb.rnat[0, 0]


@njit(**BUILD)
def _least_energy(grid, j, rho, jj, m, scr):
    """The chain's least energy [N mm] with its tip at chord rho on the ray (jj, m); scr: the
    scratch (x, q, fr, mins) of ``_natural_rho``."""
    x, q, fr, mins = scr
    _ray_x(grid, rho, jj, m, x)
    n = minima(x, j, mins, q, fr)
    e = np.inf
    for r in range(n):
        e = min(e, mins[r, 2])
    return e


@njit(**BUILD)
def _natural_rho(grid, j, jj, m):
    """The chord [mm] on the ray (jj, m) where the chain's least energy is least: the unloaded
    path (golden section between rho_min and rho_cap, to 1e-7 of the links' length)."""
    scr = (np.empty(3), np.empty(5), np.empty((3, 3)), np.empty((4, 3)))
    a, b = grid.rmin, grid.rcap
    tol = 1e-7 * (grid.geo[1] + grid.geo[2])
    gr = 0.5 * (np.sqrt(5.0) - 1.0)
    c = b - gr * (b - a)
    d = a + gr * (b - a)
    fc = _least_energy(grid, j, c, jj, m, scr)
    fd = _least_energy(grid, j, d, jj, m, scr)
    while b - a > tol:
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - gr * (b - a)
            fc = _least_energy(grid, j, c, jj, m, scr)
        else:
            a, c, fc = c, d, fd
            d = a + gr * (b - a)
            fd = _least_energy(grid, j, d, jj, m, scr)
    return 0.5 * (a + b)


@njit(**BUILD, inline="always")
def _straight(x, geo):
    """True if the chain with its tip at x is nearly straight (its elbow within STRAIGHT of the
    chord): the elbow's angle is undefined there and the load turns without bound near full
    reach (a chain bent at rest, straightened).  No branch in the table there; the chain's own
    Newton takes such a tip (``prb_kernels.table_solve`` gives up)."""
    rho = np.sqrt((x[0] - geo[0]) ** 2 + x[1] ** 2 + x[2] ** 2)
    a = (geo[1] ** 2 - geo[2] ** 2 + rho * rho) / (2.0 * rho)
    return geo[1] ** 2 - a * a < (STRAIGHT * (geo[1] + geo[2])) ** 2


@njit(**BUILD, inline="always")
def _pick(mins, n, s):
    """Of the n minima (psi, t, E), the least on branch s's side of the chord (-1: none)."""
    best = np.inf
    pick = -1
    for r in range(n):
        sp = np.sin(mins[r, 0])
        on = sp >= -ON_PLANE if s == 0 else sp <= ON_PLANE
        if on and mins[r, 2] < best:
            best = mins[r, 2]
            pick = r
    return pick


@njit(**BUILD, inline="always")
def _folded(q, rest):
    """True if a joint turned past FOLDED from rest, or a link past SIDEWAYS about local z:
    beyond anything a bristle does (and where atan2 and asin wrap)."""
    out = abs(q[1]) > SIDEWAYS or abs(q[3]) > SIDEWAYS
    for r in range(5):
        if abs(q[r] - rest[r]) > FOLDED:
            out = True
    return out


@njit(**BUILD, inline="always")
def _copy_entry(src, dst):
    dst.ok, dst.U = src.ok, src.U
    for a in range(3):
        dst.g[a] = src.g[a]
    for a in range(6):
        dst.D[a] = src.D[a]
    for a in range(5):
        dst.q[a] = src.q[a]


@njit(**BUILD)
def build_layer(tb, j, i):
    """Layer i of table tb (``build``; each layer on its own, after ``build_rnat``)."""
    grid, vals = tb.grid, tb.vals
    geo = grid.geo
    h = 1e-3 * (geo[1] + geo[2])
    x = np.empty(3)
    q = np.empty(5)
    fr = np.empty((3, 3))
    mins = np.empty((4, 3))
    for jj in range(grid.nt):
        for m in range(grid.np):
            for s in range(2):
                if jj == 0 and m > 0:  # the axis: one point for every azimuth
                    _copy_entry(vals[s, i, 0, 0], vals[s, i, jj, m])
                else:
                    vals[s, i, jj, m].ok = 0.0
            if jj == 0 and m > 0:
                continue
            node_x(tb, i, jj, m, x)
            if _straight(x, geo):
                continue
            n = minima(x, j, mins, q, fr)
            for s in range(2):
                r = _pick(mins, n, s)
                if r < 0:
                    continue
                ik(x, mins[r, 0], mins[r, 1], geo, q, fr)
                if _folded(q, j.rest):
                    continue
                node_values(x, mins[r, 0], mins[r, 1], mins[r, 2], j, h, vals[s, i, jj, m], q, fr)


# --------------------------------------------------------------------------- the lookup (per step)
#: the lookup's scratch per call: corner weights and their derivatives
LOOK = dict(cache=True, _nrt=False, fastmath=False)


@njit(**LOOK, inline="always")
def _layer(U, al):
    """(u, du/dU): the layer coordinate u in [0, 1] of the span fraction U (U = al u + (1 - al)
    u^2, ``node_rho``)."""
    r = np.sqrt(al * al + 4.0 * (1.0 - al) * U)
    return (r - al) / (2.0 * (1.0 - al)), 1.0 / r


@njit(**LOOK)
def lookup(tb, s, xl, g, Jg, D, q, want_q, scr):  # noqa: C901
    """The branch s of one table (``Table``: grid, rnat, vals) at the tip xl (bristle frame
    [mm]): g (3,) <- grad U [N] and Jg (3, 3) <- its derivative in xl [N/mm] (of
    the interpolant itself: Newton's tangent), D (3, 3) <- the damping matrix [N/mm per unit of
    beta/h], q (5,) <- the joint angles if ``want_q``; scr (16, 3) scratch, with scr[12] the
    tip's move in the step e = xl - xln [mm] (input) and scr[13:16] <- T [N/mm per unit of
    beta/h], T[a, m] = sum_c dD[a, c]/dxl_m e_c: the damping force's change with the tip through
    its matrix (Newton's tangent of D e is D + T).  Trilinear in the
    layer, theta and phi over the cell's corners where the branch exists, their weights
    renormalised.

    Returns (w, out, U): w the weight of the corners where the branch exists (the branch exists
    at xl where w >= 0.5), out 1 where xl lies beyond the table (rho below rho_min or theta past
    theta_max: the values of its edge, clamped), 2 where the chord is longer than rho_cap (the
    caller adds the axial penalty; the values are the top layer's), U the branch's energy
    [N mm]."""
    grid, rnat, vals = tb.grid, tb.rnat, tb.vals
    rcap, rmin, tmax = grid.rcap, grid.rmin, grid.tmax
    nr, nt, npp = grid.nr, grid.nt, grid.np
    nu, al = grid.nu, grid.alpha
    nd = nr - 1 - nu
    u0, u1, u2 = xl[0] - grid.geo[0], xl[1], xl[2]
    # a tip at -y: the mirror image's values (module docstring), mirrored back at the end
    sy = 1.0
    if u1 < 0.0:
        sy = -1.0
        u1 = -u1
    rho = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    out = 0
    ux = u0 / rho
    th = np.arccos(min(max(ux, -1.0), 1.0))
    sth = np.sin(th)
    ph = np.arctan2(u2, u1)  # in [-pi/2, pi/2]: u1 >= 0
    fj = th / tmax * (nt - 1)
    fpj = (nt - 1) / tmax
    if fj > nt - 1:
        fj, fpj = float(nt - 1), 0.0
        out = 1
    fm = (ph / np.pi + 0.5) * (npp - 1)
    fpm = (npp - 1) / np.pi
    j0 = min(int(fj), nt - 2)
    m0 = min(max(int(fm), 0), npp - 2)
    m1 = m0 + 1
    b, c = fj - j0, fm - m0
    # d rho, d theta, d phi / d xl
    drho, dth, dph = scr[0], scr[1], scr[2]
    drho[0], drho[1], drho[2] = u0 / rho, u1 / rho, u2 / rho
    if sth > 1e-9:
        dth[0] = -(1.0 - ux * drho[0]) / (rho * sth)
        dth[1] = ux * drho[1] / (rho * sth)
        dth[2] = ux * drho[2] / (rho * sth)
        r2 = u1 * u1 + u2 * u2
        dph[0], dph[1], dph[2] = 0.0, -u2 / r2, u1 / r2
    else:
        for k in range(3):
            dth[k] = 0.0
            dph[k] = 0.0
    # the unloaded path's chord here (bilinear in theta, phi) and its slopes
    rn00 = rnat[j0, m0]
    rn01 = rnat[j0, m1]
    rn10 = rnat[j0 + 1, m0]
    rn11 = rnat[j0 + 1, m1]
    rn = (1 - b) * ((1 - c) * rn00 + c * rn01) + b * ((1 - c) * rn10 + c * rn11)
    dn_j = (1 - c) * (rn10 - rn00) + c * (rn11 - rn01)
    dn_m = (1 - b) * (rn01 - rn00) + b * (rn11 - rn10)
    # the layer: fi and its slopes in rho and in rn.  Below the unloaded path (compressed)
    # U = (rn - rho) / (rn - rmin) and fi = nu + u nd; above it (pulled straighter)
    # U = (rho - rn) / (rcap - rn) and fi = nu - u nu; on both sides
    # d fi = n du/dU ((1 - U) d rn - d rho) / span
    if rho <= rn:
        sg, span, nside, edge = 1.0, rn - rmin, nd, 1
    else:
        sg, span, nside, edge = -1.0, rcap - rn, nu, 2
    U = sg * (rn - rho) / span
    clamped = U > 1.0
    if clamped:
        U = 1.0
        out = edge
    uu, du = _layer(U, al)
    ku, kr = 0.0, 0.0
    if not clamped:
        ku = -(nside * du / span)
        kr = (1.0 - U) * (nside * du / span)
    fi = nu + sg * uu * nside
    i0 = min(int(fi), nr - 2)
    a = fi - i0
    for k in range(3):
        g[k] = 0.0
        for m in range(3):
            Jg[k, m] = 0.0
            D[k, m] = 0.0
    if want_q:
        for k in range(5):
            q[k] = 0.0
    w = 0.0
    U = 0.0
    # the interpolant and its derivative in (fi, fj, fm): sum over corners of weight * value
    gv = scr[3:6]  # rows: d/dfi, d/dfj, d/dfm of g
    for k in range(3):
        for m in range(3):
            gv[k, m] = 0.0
    # the damping's change with the tip, contracted with e = scr[12] (the tip's move in the step,
    # xl - xln; mirrored like xl): rows of tv as gv's, of D e
    tv = scr[6:9]
    for k in range(3):
        for m in range(3):
            tv[k, m] = 0.0
    e0, e1, e2 = scr[12, 0], sy * scr[12, 1], scr[12, 2]
    for ci in range(2):
        wi = a if ci else 1.0 - a
        di = 1.0 if ci else -1.0
        for cj in range(2):
            wj = b if cj else 1.0 - b
            dj = 1.0 if cj else -1.0
            for cm in range(2):
                wm = c if cm else 1.0 - c
                dm = 1.0 if cm else -1.0
                v = vals[s, i0 + ci, j0 + cj, m1 if cm else m0]
                if v.ok == 0.0:
                    continue
                wc = wi * wj * wm
                w += wc
                U += wc * v.U
                for k in range(3):
                    gk = v.g[k]
                    g[k] += wc * gk
                    gv[0, k] += di * wj * wm * gk
                    gv[1, k] += wi * dj * wm * gk
                    gv[2, k] += wi * wj * dm * gk
                for n in range(6):
                    p, r = IH[n]
                    D[p, r] += wc * v.D[n]
                vd = v.D  # IH: 00, 11, 22, 01, 02, 12
                de0 = vd[0] * e0 + vd[3] * e1 + vd[4] * e2
                de1 = vd[3] * e0 + vd[1] * e1 + vd[5] * e2
                de2 = vd[4] * e0 + vd[5] * e1 + vd[2] * e2
                w0, w1, w2 = di * wj * wm, wi * dj * wm, wi * wj * dm
                tv[0, 0] += w0 * de0
                tv[0, 1] += w0 * de1
                tv[0, 2] += w0 * de2
                tv[1, 0] += w1 * de0
                tv[1, 1] += w1 * de1
                tv[1, 2] += w1 * de2
                tv[2, 0] += w2 * de0
                tv[2, 1] += w2 * de1
                tv[2, 2] += w2 * de2
                if want_q:
                    for k in range(5):
                        q[k] += wc * v.q[k]
    if w <= 0.0:
        return 0.0, out, 0.0
    # the renormalisation's derivative is left out: within the branch's cells (w = 1) it is 0
    inv = 1.0 / w
    for k in range(3):
        g[k] *= inv
    for n in range(6):
        p, r = IH[n]
        D[p, r] *= inv
        if p != r:
            D[r, p] = D[p, r]
    if want_q:
        for k in range(5):
            q[k] *= inv
    # d fi = ku d rho + kr d rn, d rn = dn_j d fj + dn_m d fm
    # T[a, m] = sum_c dD[a, c]/dxl_m e_c, the damping's change with the tip
    T = scr[13:16]
    for m in range(3):
        dfj = fpj * dth[m]
        dfm = fpm * dph[m]
        dfi = ku * drho[m] + kr * (dn_j * dfj + dn_m * dfm)
        for k in range(3):
            Jg[k, m] = inv * (gv[0, k] * dfi + gv[1, k] * dfj + gv[2, k] * dfm)
            T[k, m] = inv * (tv[0, k] * dfi + tv[1, k] * dfj + tv[2, k] * dfm)
    if sy < 0.0:  # back from the mirror image: y components and b1, b2, t turn sign
        g[1] = -g[1]
        for k in range(3):
            if k != 1:
                Jg[1, k] = -Jg[1, k]
                Jg[k, 1] = -Jg[k, 1]
                T[1, k] = -T[1, k]
                T[k, 1] = -T[k, 1]
                D[1, k] = -D[1, k]
                D[k, 1] = -D[k, 1]
        if want_q:
            q[1] = -q[1]
            q[3] = -q[3]
            q[4] = -q[4]
    return w, out, U * inv
