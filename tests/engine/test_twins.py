"""The hot kernels against numpy twins written apart from them (issue 10).

``tests/engine/twins.py`` re-derives, from the paper's equations and the kernels' docstrings, the
element force (eq 1-5), the tip load (eq 6-10, Table 3) and the residual of eq 11 with the
two-step time discretisation, in vectorised numpy with scipy's SO(3) log map.  The kernels are
reached only through the adapters below (``kernel_element``, ``kernel_tip_load``,
``kernel_residual``), which take plain, physically named inputs: when the kernels' argument lists
change, only the adapters change.

Beside the twins, checks that need no twin: an element carries no load under a rigid motion of an
unstrained pair and turns with a rigid motion of a strained one, its loads balance (it is
internal), its forces are minus the gradient of its elastic energy in the body positions, and
the tip stiffness is the derivative of the kernel's own tip force (central differences).

Tolerances: exact twins agree to 1e-10 of the largest term of the compared quantity (round-off of
different summation orders, and of two log maps, is ~1e-14 here); the finite-difference checks
to 1e-6 (their truncation error is ~1e-9).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from brush_env.engine import SimSettings, Simulator, load_scene
from brush_env.engine import contact as ct
from brush_env.engine import records as rec
from brush_env.engine._kernels import ELEM_PAPER, element_gen
from brush_env.engine.mesh_contact import empty_mesh
from brush_env.engine.predict import _prepare
from brush_env.engine.residual import bristle_residual
from brush_env.engine.scene import ContactParams
from brush_env.engine.sdf import empty_sdf

from . import twins

EULER = (1.0, -1.0, 0.0)
BDF2 = (1.5, -2.0, 0.5)
CP = {f.name: getattr(ContactParams(), f.name) for f in dataclasses.fields(ContactParams)}
_MESH = empty_mesh()
_SDF = empty_sdf()


# =========================================================================== adapters
def kernel_element(
    cA,
    RA,
    halfA,
    cB,
    RB,
    halfB,
    K,
    length,
    *,
    base=None,
    beta=0.0,
    c=EULER,
    h=1.0,
    e_n=None,
    e_p=None,
    kind=ELEM_PAPER,
):
    """``_kernels.element_gen``: loads of one element on bodies A and B -> (wA, wB, e).

    Bodies: centre c, rotation R (body -> world), half length (node p = c + half R e_x).
    ``base``: the root node (A is then the head: cA and halfA are not used, wA is at the node).
    Damping beta K times the strain rate (c0 e + c1 e_n + c2 e_p) / h; beta = 0: elastic only.
    """
    e_n = np.zeros(6) if e_n is None else np.asarray(e_n, float)
    e_p = np.zeros(6) if e_p is None else np.asarray(e_p, float)
    out12 = np.zeros(12)
    e = np.zeros(6)
    root = base is not None
    pAb = np.asarray(base, float) if root else np.zeros(3)
    if root:
        cA, halfA = pAb, 0.0
    A = rec.Node(np.asarray(cA, float), np.asarray(RA, float), float(halfA))
    B = rec.Node(np.asarray(cB, float), np.asarray(RB, float), float(halfB))
    damp = rec.Damp(c[1] * e_n + c[2] * e_p, 1.0 + beta * c[0] / h, beta / h)
    element_gen(kind, root, A, pAb, B, np.asarray(K, float), length, damp, out12, e)
    return out12[:6].copy(), out12[6:].copy(), e


def kernel_tip_load(
    pt,
    *,
    fext=(0.0, 0.0, 0.0),
    radius,
    planes,
    cp,
    static=False,
    c=EULER,
    h=1e-3,
    p_n=None,
    p_p=None,
    delta=(0.0, 0.0, 0.0),
    beta=0.0,
    partners=(),
    cax=0.0,
    axis=(0.0, 0.0, 0.0),
):
    """``contact.tip_load`` of one tip sphere (centre pt, radius) -> (F, Kt, outputs).

    planes [(point, unit normal)]; cp: contact parameters by name; the tip node at the step start
    p_n and the one before p_p (rate history); delta: committed stiction deformation; beta:
    committed sliding weight; partners [(centre, velocity, radius)] of other tips.  Outputs: the
    contact results the kernel stores (normal and friction force, penetration, contact point, trial
    stiction deformation, beta at the current slip speed, sliding flag, tip-tip force).
    """
    pt = np.asarray(pt, float)
    p_n = pt if p_n is None else np.asarray(p_n, float)
    p_p = p_n if p_p is None else np.asarray(p_p, float)
    # one row per tip the kernel may index: the tip (0) and each partner (its index in ``tips``:
    # the tip-tip law reads the partner's axial compliance): every one with ``cax`` [mm/N] along
    # ``axis`` (0: the full chain's)
    args = np.zeros(max(1, len(partners)), rec.TIP_ARGS)
    args["radius"] = radius
    args["fext"][0] = fext
    args["cax"] = cax
    args["axis"] = axis
    st = np.zeros(1, rec.TIP_STATE)
    st["delta"] = delta
    st["beta"] = beta
    st["pn"] = p_n
    st["hist"] = 0.0 if static else (c[0] + c[1]) * p_n + c[2] * p_p
    surf = np.zeros(len(planes), rec.SURFACE)
    for j, (p0, nrm) in enumerate(planes):
        surf[j] = rec.surface_row(rec.SURF_PLANE, p0, nrm)
    cpa = np.array([tuple(float(cp[f]) for f in rec.CONTACT_LAW.names)], rec.CONTACT_LAW)
    tips = np.zeros((max(len(partners), 1), 7))
    for j, (pj, vj, rj) in enumerate(partners):
        tips[j] = [*pj, *vj, rj]
    pair_ptr = np.array([0, len(partners)], np.int64)
    pair_idx = np.arange(len(partners), dtype=np.int64)
    F = np.zeros(3)
    Kt = np.zeros((3, 3))
    tw = rec.make_work(1).tipw
    shaft = np.zeros(0, rec.SHAFT)  # no shaft contact in the twin
    con = rec.ContactScene(surf, cpa, tips, pair_ptr, pair_idx, _MESH, args, st, _SDF, shaft)
    sub = rec.Substep(c[0], c[1], c[2], h, 1.0 / h, static, np.zeros(3), 0.0, 0, 0.0)
    ct.tip_load(0, pt, sub, con, F, Kt, tw)
    st = con.tip_state[0]
    out = dict(
        Fn=st["fn"],
        Ft=st["ft"].copy(),
        pen=st["pen"],
        cpt=st["cpt"].copy(),
        dnew=st["dnew"].copy(),
        bnew=st["bnew"],
        slide=float(st["slide"]),
        Ftt=st["ftt"],
    )
    return F, Kt, out


def kernel_residual(
    *,
    b,
    bp,
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
    fext,
    radius,
    delta,
    slide_beta,
    ctx,
):
    """``residual.bristle_residual`` of bristle b (after ``_prepare``, as ``newton_solve`` calls
    them).

    bp (n,) ``records.BODY``, K (n, 6, 6): the bristle's rows of the model arrays; (pos, rot):
    the trial chain at t_{n+1}; *_n / *_p: the chain at t_n / t_{n-1}; base*: (root node, head
    rotation) at t_{n+1}, t_n, t_{n-1}; c = (c0, c1, c2), h [s]; tip_args/tip_state: the
    bristle's rows (the tip history slots are filled here); ctx: the simulator's contact context.
    Returns (res (n, 6), root load (6,), tip force (3,), tip stiffness (3, 3), scaled norm).
    """
    n = len(bp)
    bp, K = np.ascontiguousarray(bp), np.ascontiguousarray(K)
    c0, c1, c2 = c
    if static:
        c1 = c2 = 0.0
    model = rec.ModelArrays(
        np.array([0, n], np.int64),
        bp,
        K,
        np.zeros((1, 3)),
        np.zeros((1, 3, 3)),
        np.full(n, ELEM_PAPER, np.int64),
    )
    br = rec.Bristle(b, 0, n, n - 1)
    sub = rec.Substep(c0, c1, c2, h, 1.0 / h, static, np.asarray(gravity, float), 0.0, 0, 0.0)
    ws = rec.make_work(n)
    z3, z33 = np.zeros((n, 3)), np.zeros((n, 3, 3))
    at_n = rec.Chain(
        *(np.ascontiguousarray(a, float) for a in (pos_n, rot_n, vel_n, omg_n)),
        *(np.ascontiguousarray(a, float) for a in (pos_p, rot_p, vel_p, omg_p)),
        z3,
        z33,
    )
    base_rec = rec.Base(
        *(np.ascontiguousarray(a, float) for a in (*base_n, *base, *base_p)), np.zeros(3), z33[0]
    )
    # an empty strain cache (n bodies: the key NaN), so e_{n-1} is evaluated as the twin does
    _prepare(br, model, at_n, sub, base_rec, ws.hist, ws.el, rec.make_newton_cache(n, 1))
    tip_args = ctx.tip_args.copy()
    tip_state = ctx.tip_state.copy()
    tip_args[b] = np.zeros((), rec.TIP_ARGS)
    tip_args[b]["fext"] = fext
    tip_args[b]["radius"] = radius
    tip_state[b] = np.zeros((), rec.TIP_STATE)
    st = tip_state[b : b + 1]
    st["delta"] = delta
    st["beta"] = slide_beta
    ptn = pos_n[-1] + bp[-1]["half"] * rot_n[-1][:, 0]
    ptp = pos_p[-1] + bp[-1]["half"] * rot_p[-1][:, 0]
    st["pn"] = ptn
    st["hist"] = (c0 + c1) * ptn + c2 * ptp
    con = ctx._replace(tip_args=tip_args, tip_state=tip_state)
    trial = at_n._replace(pos=np.array(pos, float), rot=np.array(rot, float))
    rootw = np.zeros(6)
    nrm = bristle_residual(br, model, trial, sub, base_rec, con, ws, rootw)
    res = ws.it.res[:n].copy()
    tipF = ws.it.tipF.copy()
    tipK = ws.it.tipK.copy()
    return res, rootw, tipF, tipK, nrm


def committed_contact(tip_state_row):
    """(Delta, beta) committed in a simulator's tip_state row (the inputs of a step's contact)."""
    return np.array(tip_state_row["delta"]), float(tip_state_row["beta"])


# =========================================================================== helpers
def assert_close(actual, expected, rel, what=""):
    """max |actual - expected| <= rel * max |expected| (one scale for the whole quantity)."""
    actual, expected = np.asarray(actual, float), np.asarray(expected, float)
    scale = np.max(np.abs(expected))
    err = np.max(np.abs(actual - expected))
    assert scale > 0.0, f"{what}: the reference is zero, the comparison would be empty"
    assert err <= rel * scale, f"{what}: max error {err:.3e} > {rel:g} * {scale:.3e}"


def rand_rot(rng, angle=None):
    if angle is None:
        return Rotation.random(random_state=rng).as_matrix()
    axis = rng.normal(size=3)
    return Rotation.from_rotvec(angle * axis / np.linalg.norm(axis)).as_matrix()


def rand_stiffness(rng, symmetric=False):
    """A stiffness-like 6x6 matrix: dominant diagonal of mixed units, coupling off it."""
    scale = np.array([30.0, 2.0, 1.0, 0.5, 3.0, 4.0])
    A = rng.normal(size=(6, 6)) * 0.3
    if symmetric:
        A = A @ A.T
    return np.sqrt(scale)[:, None] * (A + 3.0 * np.eye(6)) * np.sqrt(scale)[None, :]


def rand_element(rng, root, rel_angle=0.3, strain=0.2):
    """Random poses of a strained element: body A (or the base node), body B near its rest place."""
    length = rng.uniform(1.0, 3.0)
    halfA, halfB = rng.uniform(0.5, 1.5, size=2)
    RA = rand_rot(rng)
    cA = rng.normal(size=3) * 5.0
    pA = rng.normal(size=3) * 5.0 if root else cA + halfA * RA[:, 0]
    RB = RA @ rand_rot(rng, rel_angle * rng.uniform(0.5, 1.0))
    pB = pA + RA @ (length * twins.EX + strain * rng.normal(size=3))
    cB = pB - halfB * RB[:, 0]
    return dict(cA=cA, RA=RA, halfA=halfA, cB=cB, RB=RB, halfB=halfB, length=length, pA=pA)


def _element_call(fn, el, K, root, **kw):
    return fn(
        el["cA"],
        el["RA"],
        el["halfA"],
        el["cB"],
        el["RB"],
        el["halfB"],
        K,
        el["length"],
        base=el["pA"] if root else None,
        **kw,
    )


# =========================================================================== 1. element (eq 1-5)
@pytest.mark.parametrize("root", [False, True], ids=["inner", "root"])
@pytest.mark.parametrize("damping", ["none", "euler", "bdf2"])
@pytest.mark.parametrize("rel_angle", [0.3, 2.0, 3.1], ids=["small", "large", "near-pi"])
def test_element_loads_match_the_twin(root, damping, rel_angle):
    """Loads on both bodies and the strain, random poses and (unsymmetric) stiffness; with
    damping the strain history is that of two earlier random poses.  3.1 rad exercises the log
    map's branch near a half turn."""
    rng = np.random.default_rng([int(root), len(damping), int(10 * rel_angle)])
    for _ in range(5):
        el = rand_element(rng, root, rel_angle)
        K = rand_stiffness(rng)
        kw, tw = {}, {}
        if damping != "none":
            c = EULER if damping == "euler" else BDF2
            e_n = twins.element_loads(**_twin_args(rand_element(rng, root), K, root))[2]
            e_p = twins.element_loads(**_twin_args(rand_element(rng, root), K, root))[2]
            beta, h = rng.uniform(1e-4, 1e-3), 1e-3
            kw = dict(beta=beta, c=c, h=h, e_n=e_n, e_p=e_p)
            e = twins.element_loads(**_twin_args(el, K, root))[2]
            tw = dict(beta=beta, edot=twins.rate(c, h, e, e_n, e_p))
        wA, wB, e = _element_call(kernel_element, el, K, root, **kw)
        tA, tB, te = twins.element_loads(**_twin_args(el, K, root), **tw)
        assert_close(e, te, 1e-12, "strain")
        assert_close(np.concatenate([wA, wB]), np.concatenate([tA, tB]), 1e-10, "loads")


def _twin_args(el, K, root):
    return dict(
        cA=None if root else el["cA"],
        RA=el["RA"],
        halfA=el["halfA"],
        cB=el["cB"],
        RB=el["RB"],
        halfB=el["halfB"],
        K=K,
        length=el["length"],
        base=el["pA"] if root else None,
    )


@pytest.mark.parametrize("root", [False, True], ids=["inner", "root"])
def test_unstrained_element_carries_no_load_under_rigid_motion(root):
    """A pair at rest shape (B's node l along A's axis, same orientation), placed anywhere and
    moved rigidly between the three time levels: zero strain, zero strain rate, zero load."""
    rng = np.random.default_rng(3 + root)
    K = rand_stiffness(rng)
    for _ in range(5):
        el = rand_element(rng, root, rel_angle=0.0, strain=0.0)
        el["RB"] = el["RA"].copy()
        el["cB"] = el["pA"] + el["length"] * el["RA"][:, 0] - el["halfB"] * el["RB"][:, 0]
        wA, wB, e = _element_call(
            kernel_element, el, K, root, beta=5e-4, c=BDF2, h=1e-3, e_n=np.zeros(6)
        )
        load_scale = np.abs(K).max() * el["length"]
        assert np.abs(e).max() < 1e-13 * el["length"]
        assert np.abs(np.concatenate([wA, wB])).max() < 1e-12 * load_scale


@pytest.mark.parametrize("root", [False, True], ids=["inner", "root"])
def test_element_loads_turn_with_a_rigid_motion(root):
    """Frame indifference: moving a strained pair by (Q, t) leaves the strain unchanged and turns
    the loads (forces and moments about the centres, which move along) by Q."""
    rng = np.random.default_rng(7 + root)
    K = rand_stiffness(rng)
    for _ in range(5):
        el = rand_element(rng, root, rel_angle=1.0)
        Q, t = rand_rot(rng), rng.normal(size=3) * 10.0
        moved = dict(el)
        for key in ("cA", "cB", "pA"):
            moved[key] = Q @ el[key] + t
        moved["RA"], moved["RB"] = Q @ el["RA"], Q @ el["RB"]
        wA, wB, e = _element_call(kernel_element, el, K, root)
        mA, mB, me = _element_call(kernel_element, moved, K, root)
        assert_close(me, e, 1e-12, "strain")
        turned = np.concatenate([Q @ wA[:3], Q @ wA[3:], Q @ wB[:3], Q @ wB[3:]])
        assert_close(np.concatenate([mA, mB]), turned, 1e-11, "loads")


@pytest.mark.parametrize("root", [False, True], ids=["inner", "root"])
def test_element_loads_balance(root):
    """The element is internal: its loads on A and B sum to zero force and zero moment about the
    origin (A's moment is about c_A, or about the root node for the root element)."""
    rng = np.random.default_rng(11 + root)
    for _ in range(5):
        el = rand_element(rng, root, rel_angle=2.0)
        K = rand_stiffness(rng)
        wA, wB, _ = _element_call(
            kernel_element,
            el,
            K,
            root,
            beta=3e-4,
            c=BDF2,
            h=2e-3,
            e_n=rng.normal(size=6) * 0.1,
            e_p=rng.normal(size=6) * 0.1,
        )
        at_A = el["pA"] if root else el["cA"]
        F = wA[:3] + wB[:3]
        M = wA[3:] + np.cross(at_A, wA[:3]) + wB[3:] + np.cross(el["cB"], wB[:3])
        scale = np.abs(wB[:3]).max()
        assert np.abs(F).max() < 1e-13 * scale
        lever = np.abs([*at_A, *el["cB"]]).max()
        assert np.abs(M).max() < 1e-12 * (np.abs(wB[3:]).max() + scale * lever)


@pytest.mark.parametrize("root", [False, True], ids=["inner", "root"])
def test_element_force_is_minus_the_energy_gradient_in_position(root):
    """With a symmetric K the element stores U = e^T K e / 2; a translation of a body's centre
    changes only the strain's position part (by +-R_A^T dc), so the force on B is -dU/dc_B, and on
    A -dU/dc_A (central differences of the twin's strain).  Moments are not gradients of U in
    general (the co-rotational rotation strain is not conservative), so they are not checked."""
    rng = np.random.default_rng(13 + root)
    for _ in range(3):
        el = rand_element(rng, root, rel_angle=1.0)
        K = rand_stiffness(rng, symmetric=True)
        wA, wB, _ = _element_call(kernel_element, el, K, root)

        def energy(shiftA, shiftB, el=el, K=K):
            pA = el["pA"] + shiftA
            pB = el["cB"] + shiftB + el["halfB"] * el["RB"][:, 0]
            e = twins.element_strain(pA, el["RA"], pB, el["RB"], el["length"])
            return 0.5 * e @ K @ e

        d = 1e-6
        gB = np.zeros(3)
        gA = np.zeros(3)
        for a in range(3):
            s = np.zeros(3)
            s[a] = d
            gB[a] = (energy(0, s) - energy(0, -s)) / (2 * d)
            gA[a] = (energy(s, 0) - energy(-s, 0)) / (2 * d)
        assert_close(wB[:3], -gB, 1e-6, "force on B")
        assert_close(wA[:3], -gA, 1e-6, "force on A")


# =========================================================================== 2. tip load (eq 6-10)
NOFRICTION = {**CP, "mu_s": 0.0, "mu_d": 0.0}


def _plane(rng):
    n = rng.normal(size=3)
    return rng.normal(size=3), n / np.linalg.norm(n)


def _tip_case(name, rng):
    """(kernel kwargs) of a named contact situation; the tip moves with velocity V since two steps
    (p_n = pt - h V, p_p = pt - 2 h V: both schemes' rate is exactly V)."""
    p0, n = _plane(rng)
    radius, h, pen = 0.44, 1e-3, 2e-3
    t = np.cross(n, rng.normal(size=3))
    t /= np.linalg.norm(t)
    pt = p0 + rng.normal(size=3)
    pt = pt - ((pt - p0) @ n) * n + (radius - pen) * n  # penetration pen
    V = np.zeros(3)
    kw = dict(planes=[(p0, n)], radius=radius, h=h, fext=rng.normal(size=3) * 0.01, cp=CP)
    if name == "static-normal":
        kw.update(static=True, cp=NOFRICTION)
    elif name == "pressing":  # moving into the plate, damping adds to the spring
        V = -0.8 * n + 0.3 * t
        kw.update(cp=NOFRICTION)
    elif name == "releasing":  # moving out: damping subtracts, force stays positive
        V = 0.1 * n
        kw.update(cp=NOFRICTION)
    elif name == "pulled-off":  # moving out fast, strong damping: the force clamps at zero
        V = 20.0 * n
        kw.update(cp={**NOFRICTION, "c": 1e3})
    elif name == "stick-at-rest":  # sticking, stiction spring loaded, no slip
        kw.update(delta=0.03 * t)
    elif name == "stick-unloaded":  # sticking at rest with Delta = 0 (contact onset)
        pass
    elif name == "creeping":  # slow slip below v_s, beta between 0 and 1
        V = 0.6 * t - 0.05 * n
        kw.update(delta=0.02 * t + 0.01 * np.cross(n, t), beta=0.4)
    elif name == "sliding":  # fast slip, stiction released (beta = 1), Delta at its bound
        V = 20.0 * t
        kw.update(delta=0.1 * t, beta=1.0)
    elif name == "static-friction":
        kw.update(static=True, delta=0.05 * t)
    elif name == "at-stiction-limit":  # trial Delta beyond Delta_max: clamped to the bound
        kw.update(delta=0.099 * t + 0.01 * t, beta=0.0)
    elif name == "tip-tip":  # two partner tips, one touching (with relative speed), one not
        kw.update(planes=[])
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        V = rng.normal(size=3)
        kw.update(
            partners=[
                (pt - (2 * radius - 3e-3) * u, 0.5 * rng.normal(size=3), radius),
                (pt + (2 * radius + 1e-2) * u, np.zeros(3), radius),
            ]
        )
    else:
        raise ValueError(name)
    kw.update(p_n=pt - h * V, p_p=pt - 2 * h * V)
    return pt, V, kw


TIP_CASES = [
    "static-normal",
    "pressing",
    "releasing",
    "pulled-off",
    "stick-at-rest",
    "stick-unloaded",
    "creeping",
    "sliding",
    "static-friction",
    "at-stiction-limit",
    "tip-tip",
]


@pytest.mark.parametrize("c", [EULER, BDF2], ids=["euler", "bdf2"])
@pytest.mark.parametrize("name", TIP_CASES)
def test_tip_load_matches_the_twin(name, c):
    """Force and stored contact outputs against the twin of eq 6-10 / Table 3."""
    rng = np.random.default_rng(TIP_CASES.index(name))
    pt, V, kw = _tip_case(name, rng)
    F, _, out = kernel_tip_load(pt, c=c, **kw)
    partners = kw.get("partners", ())
    tw = twins.tip_load(
        pt,
        fext=kw["fext"],
        radius=kw["radius"],
        planes=kw["planes"],
        cp=kw["cp"],
        static=kw.get("static", False),
        v_tip=V,
        p_n=kw["p_n"],
        delta=kw.get("delta", np.zeros(3)),
        beta=kw.get("beta", 0.0),
        partners=partners,
    )
    assert_close(F, tw["F"], 1e-12, "tip force")
    contact = (tw["Fn"] if kw["planes"] else tw["Ftt"]) > 0.0
    assert contact == (name != "pulled-off"), "the case does not test what it says"
    for key in ("Fn", "pen", "Ftt", "bnew", "slide"):
        assert out[key] == pytest.approx(tw[key], rel=1e-12, abs=1e-300), key
    for key in ("Ft", "cpt", "dnew"):
        np.testing.assert_allclose(out[key], tw[key], rtol=1e-12, atol=1e-15, err_msg=key)
    if name in ("creeping", "stick-at-rest", "sliding", "at-stiction-limit"):
        assert np.abs(tw["Ft"]).max() > 0.0, "friction expected"


@pytest.mark.parametrize("c", [EULER, BDF2], ids=["euler", "bdf2"])
@pytest.mark.parametrize("name", TIP_CASES)
def test_tip_stiffness_is_the_derivative_of_the_tip_force(name, c):
    """tipK = dF/dp_tip against central differences of the kernel's own force (the committed
    contact state, the step start and the lagged beta held fixed, as within a Newton step)."""
    rng = np.random.default_rng(TIP_CASES.index(name))
    pt, _, kw = _tip_case(name, rng)
    _, Kt, _ = kernel_tip_load(pt, c=c, **kw)
    d = 1e-7
    fd = np.zeros((3, 3))
    for b in range(3):
        s = np.zeros(3)
        s[b] = d
        fd[:, b] = kernel_tip_load(pt + s, c=c, **kw)[0] - kernel_tip_load(pt - s, c=c, **kw)[0]
        fd[:, b] /= 2 * d
    if name == "pulled-off":
        assert np.abs(fd).max() == 0.0 and np.abs(Kt).max() == 0.0
        return
    assert_close(Kt, fd, 1e-6, "tip stiffness")


# =========================================================================== 3. residual (eq 11)
R0 = np.diag([1.0, -1.0, -1.0])  # TCP z down: the bristles hang toward the plate z = 0


@pytest.fixture(scope="module")
def pressed_brush():
    """The tiny brush (4 bristles x 3 bodies) on the flat plate, pressed 20 um into it and moved
    sideways over four steps: real model arrays, contact context and sticking/sliding tips."""
    scene = load_scene("flat_plate", brush="tiny")
    sim = Simulator(scene, SimSettings(dt=1e-3, integrator="bdf2"))
    z0 = sim.touch_height(R0)
    sim.reset(np.array([0.0, 0.0, z0]), R0)
    for k in range(1, 5):
        sim.step(np.array([2e-3 * k, 0.0, z0 - 5e-3 * k]), R0)
    return sim


def _head_pose(sim, b, tcp_p, tcp_R):
    m = sim.model
    return tcp_p + tcp_R @ m.root_p[b], tcp_R @ m.root_R[b]


@pytest.mark.slow  # ~14 s: presses a brush and compiles the twins (module fixture)
@pytest.mark.parametrize("mode", ["euler", "bdf2", "static"])
def test_residual_matches_the_twin(pressed_brush, mode):
    """res (n, 6), the root load, the tip force and the scaled norm of every bristle at a trial
    chain = the state at t_n carried along by the next TCP move (5 um down, deeper into the plate)
    plus random body displacements (0.5 um) and rotations (0.2 mrad), with random velocities
    behind it and a random dead tip force."""
    sim = pressed_brush
    st, m = sim.state, sim.model
    rng = np.random.default_rng(["euler", "bdf2", "static"].index(mode))
    c = BDF2 if mode == "bdf2" else EULER
    static = mode == "static"
    h = sim.settings.dt
    gravity = np.array(sim.settings.gravity, float)
    tcp_next = st.tcp_p[1] + np.array([2e-3, 1e-3, -5e-3])
    ctx = sim.bristles._contact()
    cpd = {f.name: getattr(sim.scene.contact, f.name) for f in dataclasses.fields(ContactParams)}
    planes = [(np.array(s.point, float), np.array(s.normal, float)) for s in sim.scene.surfaces]
    in_contact = 0
    for b in range(m.n_bristles):
        sl = slice(m.bstart[b], m.bstart[b + 1])
        n = sl.stop - sl.start
        bp, K = m.bp[sl], m.K[sl]
        pos = st.pos[sl] + (tcp_next - st.tcp_p[1]) + rng.normal(size=(n, 3)) * 5e-4
        rot = np.array([rand_rot(rng, 2e-4) @ R for R in st.rot[sl]])
        hist = dict(
            pos_n=st.pos[sl],
            rot_n=st.rot[sl],
            pos_p=st.ppos[sl],
            rot_p=st.prot[sl],
            vel_n=st.vel[sl] + rng.normal(size=(n, 3)),
            omg_n=st.omg[sl] + rng.normal(size=(n, 3)),
            vel_p=st.pvel[sl] + rng.normal(size=(n, 3)),
            omg_p=st.pomg[sl] + rng.normal(size=(n, 3)),
        )
        base = _head_pose(sim, b, tcp_next, st.tcp_R[1])
        base_n = _head_pose(sim, b, st.tcp_p[1], st.tcp_R[1])
        base_p = _head_pose(sim, b, st.tcp_p[0], st.tcp_R[0])
        delta, beta = committed_contact(st.tip_state[b])
        tip = dict(fext=rng.normal(size=3) * 1e-3, radius=m.tip_radius[b], delta=delta)
        res, rootw, tipF, _, nrm = kernel_residual(
            b=b,
            bp=bp,
            K=K,
            pos=pos,
            rot=rot,
            **hist,
            base=base,
            base_n=base_n,
            base_p=base_p,
            c=c,
            h=h,
            static=static,
            gravity=gravity,
            **tip,
            slide_beta=beta,
            ctx=ctx,
        )

        # the twin's tip load: the scene's planes, the partner tips from the state itself
        last = np.array([m.bstart[j + 1] - 1 for j in range(m.n_bristles)])
        r = m.bp["half"][last][:, None] * st.rot[last][:, :, 0]
        tips_p, tips_v = st.pos[last] + r, st.vel[last] + np.cross(st.omg[last], r)
        partners = [
            (tips_p[j], tips_v[j], m.tip_radius[j])
            for j in sim.bristles.pair_idx[sim.bristles.pair_ptr[b] : sim.bristles.pair_ptr[b + 1]]
        ]
        pt_n = hist["pos_n"][-1] + bp[-1]["half"] * hist["rot_n"][-1][:, 0]
        tips = []

        def tip_force(pt, v, tip=tip, beta=beta, pt_n=pt_n, partners=partners, tips=tips):
            out = twins.tip_load(
                pt,
                **tip,
                beta=beta,
                planes=planes,
                cp=cpd,
                static=static,
                v_tip=v,
                p_n=pt_n,
                partners=partners,
            )
            tips.append(out)
            return out["F"]

        tres, troot = twins.residual(
            mass=bp["mass"],
            inertia=bp["J"],
            half=bp["half"],
            length=bp["length"],
            beta=bp["beta"],
            K=K,
            pos=pos,
            rot=rot,
            **hist,
            base=base,
            base_n=base_n,
            base_p=base_p,
            c=c,
            h=h,
            static=static,
            gravity=gravity,
            tip_force=tip_force,
        )
        in_contact += tips[0]["Fn"] > 0.0
        # one scale per row kind: the elastic loads dominate both residual and cancellation
        assert_close(res[:, :3], tres[:, :3], 1e-10, f"bristle {b} forces")
        assert_close(res[:, 3:], tres[:, 3:], 1e-10, f"bristle {b} moments")
        assert_close(rootw, troot, 1e-10, f"bristle {b} root load")
        assert_close(tipF, tips[0]["F"], 1e-12, f"bristle {b} tip force")  # fext makes it > 0
        fs, ls = bp["fscale"][:, None], bp["fscale"][:, None] * bp["length"][:, None]
        tnrm = max(np.abs(tres[:, :3] / fs).max(), np.abs(tres[:, 3:] / ls).max())
        assert nrm == pytest.approx(tnrm, rel=1e-9)
    assert in_contact >= 2, "the pressed brush should have tips on the plate"


def test_tip_tip_contact_is_in_series_with_both_bristles_axial_compliance():
    """Two reduced tips meeting along their axes: the overlap of the rigid tips is Table 3's
    penetration plus both columns' shortening, (cax_b (a.u)^2 + cax_j (a.u)^2) Fn (the
    closed form of ``contact.series_law``); with the axes across the line of centres, Table 3
    alone."""
    k, m1 = CP["k_tt"], CP["m1_tt"]
    radius, over = 0.44, 0.05
    axis = np.array([0.0, np.sin(0.4), -np.cos(0.4)])
    for a, along in ((axis, axis), (axis, np.array([1.0, 0.0, 0.0]))):
        pt = np.zeros(3)
        pj = pt - (2 * radius - over) * along  # the partner's centre, ``over`` into the tip
        kw = dict(radius=radius, planes=[], cp=CP, static=True)
        _, _, out = kernel_tip_load(pt, partners=[(pj, np.zeros(3), radius)], cax=0.9, axis=a, **kw)
        an = float(a @ along)
        cs = 2 * 0.9 * an * an
        dc = over
        if cs > 0:  # dc + cs k dc^m1 = over
            dc = brentq(lambda x, cs=cs: x + cs * k * x**m1 - over, 0, over, xtol=1e-15)
        assert out["Ftt"] == pytest.approx(k * dc**m1, rel=1e-9)
