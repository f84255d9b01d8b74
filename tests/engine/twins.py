"""Plain-numpy twins of the engine's hot kernels, written from the physics, not from the kernels.

Sources: the paper's eq 1-11 (/work/shared/paper-toothbrush-dfm-2023.md), the design notes and the
kernels' docstrings (what they compute, not how).  Everything here is vectorised numpy plus
``scipy.spatial.transform.Rotation`` for the SO(3) log map; nothing imports ``brush_env``, so a
shared helper cannot hide a shared mistake.

Units: mm, s, N, t (t mm/s^2 = N).  Rotation matrices map body axes to world axes; a body's axis
is its local x (e_x); rotation vectors are axis * angle [rad].

Time discretisation (integrator docstring): y'(t_{n+1}) ~ (c0 y_{n+1} + c1 y_n + c2 y_{n-1}) / h,
backward Euler (1, -1, 0) or BDF2 (3/2, -2, 1/2), applied to positions, velocities, angular
momenta, element strains (damping) and the tip node (contact rate).  Rotations enter as rotation
vectors relative to R_n: theta_k = log(R_k R_n^T), so theta_n = 0.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

EX = np.array([1.0, 0.0, 0.0])


def log_so3(R):
    """Rotation vector of a rotation matrix (scipy's log map; angle in [0, pi])."""
    return Rotation.from_matrix(R).as_rotvec()


# --------------------------------------------------------------------------- element (eq 1-5)
def element_strain(pA, RA, pB, RB, length):
    """Co-rotational strain of an element between node A (proximal frame RA) and node B:
    relative position in A's frame minus the rest length along A's axis, and the relative
    rotation vector log(R_A^T R_B)."""
    return np.concatenate([RA.T @ (pB - pA) - length * EX, log_so3(RA.T @ RB)])


def element_loads(cA, RA, halfA, cB, RB, halfB, K, length, *, base=None, beta=0.0, edot=None):
    """Loads of one element on its two bodies.

    Nodes: p = c + half R e_x (the distal end of each body); for the root element ``base`` is the
    root node p_A (then A is the head, cA is ignored and A's load is reported at p_A).  Eq 5 with
    stiffness-proportional damping C = beta K: f = K (e + beta edot), in A's frame, is the load the
    element's distal end takes, acting *against* the strain: the force and moment on B's node are
    -R_A f.  The element is internal, so A's node takes the opposite force and the moment that
    balances it about A's node.  Each node load is then moved to its body's centre.

    Returns (wA, wB, e): 6-vectors (force [N], moment [N mm], world) on A (about c_A, or about p_A
    for the root) and on B (about c_B), and the strain e.
    """
    pA = np.asarray(base, float) if base is not None else cA + halfA * RA[:, 0]
    pB = cB + halfB * RB[:, 0]
    e = element_strain(pA, RA, pB, RB, length)
    g = e if edot is None else e + beta * np.asarray(edot)
    f = K @ g
    FB = -RA @ f[:3]
    MB = -RA @ f[3:]
    FA = -FB
    MA = -MB - np.cross(pB - pA, FB)  # sum of moments about p_A is zero
    if base is None:
        MA = MA + np.cross(pA - cA, FA)
    wA = np.concatenate([FA, MA])
    wB = np.concatenate([FB, MB + np.cross(pB - cB, FB)])
    return wA, wB, e


# --------------------------------------------------------------------------- contact (eq 6-10)
def step10(x, x0, h0, x1, h1):
    """Eq 10: h0 below x0, h1 above x1, the cubic h0 + (h1 - h0) u^2 (3 - 2 u) between."""
    if x <= x0:
        return h0
    if x >= x1:
        return h1
    u = (x - x0) / (x1 - x0)
    return h0 + (h1 - h0) * u * u * (3.0 - 2.0 * u)


def normal_force(delta, rate, k, m1, c, m2, m3):
    """Eq 6 (intended form): k delta^m1 + c sign(rate) |rate|^m2 delta^m3 for delta > 0, clamped
    at >= 0 (no adhesion); 0 without penetration."""
    if delta <= 0.0:
        return 0.0
    return max(k * delta**m1 + c * np.sign(rate) * abs(rate) ** m2 * delta**m3, 0.0)


def tip_load(
    pt,
    *,
    fext,
    radius,
    planes,
    cp,
    static,
    v_tip,
    p_n=None,
    delta=None,
    beta=0.0,
    partners=(),
):
    """Load on a tip sphere (centre pt, radius) and its contact outputs.

    fext: dead force; planes: [(point, outward unit normal)], the deepest one (smallest gap) acts;
    cp: contact parameters by name (scene.ContactParams fields); v_tip: the tip velocity (ignored
    when static); p_n: the tip at the step start and delta the committed stiction deformation
    Delta (friction); beta: the sliding weight committed at the step start (lagged one step, see
    contact.tip_load); partners: [(centre, velocity, radius)] of other tips (Table 3, no friction).

    Friction (eq 7-9 with the steps of eq 10 as documented in contact.py):
    F_t = -(1 - beta) mu_s Fn g(|D| / D_max) D_hat - mu_d Fn s(|v_t| / v_d) v_t_hat with
    g = s = step(x, -1, -1, 1, 1), v_t the tangential tip velocity and D the trial stiction
    deformation: the committed one plus the tip's displacement since the step start, projected on
    the tangent plane and clamped to |D| <= D_max.
    """
    pt = np.asarray(pt, float)
    v = np.zeros(3) if static else np.asarray(v_tip, float)
    out = dict(F=np.array(fext, float), Fn=0.0, Ft=np.zeros(3), pen=0.0, cpt=pt.copy())
    out.update(dnew=np.zeros(3), bnew=0.0, slide=0.0, Ftt=0.0)
    if planes:
        gaps = [float(np.dot(pt - np.asarray(p0), n)) for p0, n in planes]
        j = int(np.argmin(gaps))
        n = np.asarray(planes[j][1], float)
        if gaps[j] < radius:
            pen = radius - gaps[j]
            out["pen"] = pen
            out["cpt"] = pt - gaps[j] * n
            vn = float(v @ n)
            Fn = normal_force(pen, -vn, cp["k"], cp["m1"], cp["c"], cp["m2"], cp["m3"])
            out["Fn"] = Fn
            out["F"] = out["F"] + Fn * n
            if Fn > 0.0 and (cp["mu_s"] > 0.0 or cp["mu_d"] > 0.0):
                P = np.eye(3) - np.outer(n, n)
                vt = P @ v
                D = P @ (np.asarray(delta, float) + pt - np.asarray(p_n, float))
                dmax = cp["delta_max"]
                if np.linalg.norm(D) > dmax:
                    D = D * (dmax / np.linalg.norm(D))
                out["dnew"] = D
                out["bnew"] = step10(np.linalg.norm(vt), 0.0, 0.0, cp["v_s"], 1.0)
                out["slide"] = 1.0 if np.linalg.norm(vt) > cp["v_s"] else 0.0
                Ft = np.zeros(3)
                dm, vm = np.linalg.norm(D), np.linalg.norm(vt)
                if dm > 0.0:
                    Ft -= (1.0 - beta) * cp["mu_s"] * Fn * step10(dm / dmax, -1, -1, 1, 1) * D / dm
                if vm > 0.0:
                    Ft -= cp["mu_d"] * Fn * step10(vm / cp["v_d"], -1, -1, 1, 1) * vt / vm
                out["Ft"] = Ft
                out["F"] = out["F"] + Ft
    for pj, vj, rj in partners:
        d = pt - np.asarray(pj, float)
        dist = np.linalg.norm(d)
        pen = radius + rj - dist
        if dist < 1e-12 or pen <= 0.0:
            continue
        u = d / dist
        rate = 0.0 if static else -float(u @ (v - np.asarray(vj, float)))
        Fn = normal_force(pen, rate, cp["k_tt"], cp["m1_tt"], cp["c_tt"], cp["m2_tt"], cp["m3_tt"])
        out["Ftt"] += Fn
        out["F"] = out["F"] + Fn * u
    return out


# --------------------------------------------------------------------------- residual (eq 11)
def rate(c, h, y, y_n, y_p):
    """Two-step rate (c0 y_{n+1} + c1 y_n + c2 y_{n-1}) / h."""
    return (c[0] * np.asarray(y) + c[1] * np.asarray(y_n) + c[2] * np.asarray(y_p)) / h


def residual(
    *,
    mass,
    inertia,
    half,
    length,
    beta,
    K,
    pos,
    rot,
    pos_n,
    rot_n,
    vel_n,
    omg_n,
    pos_p,
    rot_p,
    vel_p,
    omg_p,
    base,
    base_n,
    base_p,
    c,
    h,
    static,
    gravity,
    tip_force,
):
    """Eq 11 of one bristle (n bodies) at the trial configuration (pos, rot) at t_{n+1}.

    Row k: rate of momentum minus all forces on body k, [N] and [N mm] about its centre (world):
    m a - m g - (element loads) - (tip load on the last body), where
    * v_{n+1} = rate(c) of the centre, a = rate(c) of the velocity (v_n, v_{n-1} given);
    * omega_{n+1} = rate(c) of the rotation vectors relative to R_n; the world angular momentum
      L = R J R^T omega, and its rate(c) (L_n, L_{n-1} from the given omega_n, omega_{n-1});
    * element k joins body k-1 (or the base, whose pose at t_{n+1}, t_n, t_{n-1} is ``base``,
      ``base_n``, ``base_p``) to body k, with damping beta_k K_k times the strain rate rate(c);
    * tip_force(pt, v_tip) -> force at the tip node pt of the last body (moved to its centre).
    Static: no inertia, no damping, v_tip = 0.  Returns (res (n, 6), root load on the head at the
    root node (6,)).
    """
    n = len(mass)
    res = np.zeros((n, 6))
    g = np.asarray(gravity, float)

    def strain(k, P, Q, bse):
        if k == 0:
            return element_strain(bse[0], bse[1], P[0] + half[0] * Q[0][:, 0], Q[0], length[0])
        pA = P[k - 1] + half[k - 1] * Q[k - 1][:, 0]
        return element_strain(pA, Q[k - 1], P[k] + half[k] * Q[k][:, 0], Q[k], length[k])

    for k in range(n):
        res[k, :3] = -mass[k] * g
        if static:
            continue
        v = rate(c, h, pos[k], pos_n[k], pos_p[k])
        res[k, :3] += mass[k] * rate(c, h, v, vel_n[k], vel_p[k])
        Rn = rot_n[k]
        th = log_so3(rot[k] @ Rn.T)
        th_p = log_so3(rot_p[k] @ Rn.T)
        om = rate(c, h, th, np.zeros(3), th_p)

        def L(R, w, J=inertia[k]):
            return R @ (J * (R.T @ w))

        res[k, 3:] = rate(c, h, L(rot[k], om), L(rot_n[k], omg_n[k]), L(rot_p[k], omg_p[k]))
    rootw = None
    for k in range(n):
        edot = None
        if not static:
            edot = rate(
                c,
                h,
                strain(k, pos, rot, base),
                strain(k, pos_n, rot_n, base_n),
                strain(k, pos_p, rot_p, base_p),
            )
        bk = 0.0 if static else beta[k]
        if k == 0:
            wA, wB, _ = element_loads(
                None,
                base[1],
                0.0,
                pos[0],
                rot[0],
                half[0],
                K[0],
                length[0],
                base=base[0],
                beta=bk,
                edot=edot,
            )
            rootw = wA
        else:
            wA, wB, _ = element_loads(
                pos[k - 1],
                rot[k - 1],
                half[k - 1],
                pos[k],
                rot[k],
                half[k],
                K[k],
                length[k],
                beta=bk,
                edot=edot,
            )
            res[k - 1] -= wA
        res[k] -= wB
    pt = pos[-1] + half[-1] * rot[-1][:, 0]
    pt_n = pos_n[-1] + half[-1] * rot_n[-1][:, 0]
    pt_p = pos_p[-1] + half[-1] * rot_p[-1][:, 0]
    F = tip_force(pt, np.zeros(3) if static else rate(c, h, pt, pt_n, pt_p))
    res[-1, :3] -= F
    res[-1, 3:] -= np.cross(pt - pos[-1], F)
    return res, rootw
