"""Kernel building blocks against independent numpy references, and the step's rollback.

The block-tridiagonal solver is checked against a dense ``numpy.linalg.solve``; the wrench and tip
kernels against the textbook formulas written with ``np.cross``; a failing step against the state
before it (the simulator must raise and leave the state untouched, bit for bit).
"""

from dataclasses import fields

import numpy as np
import pytest

from brush_env.engine import SimSettings, SimulationDivergence, Simulator, load_brush
from brush_env.engine import records as rec
from brush_env.engine._kernels import block_factor, block_factor_head, block_solve, lu6
from brush_env.engine.predict import _extrapolate
from brush_env.engine.rotation import pose_ok
from brush_env.engine.step import tcp_wrench

R0 = np.diag([1.0, -1.0, -1.0])


def _block_system(n, seed):
    """A random, diagonally dominant block-tridiagonal system (n blocks of 6) and its dense form."""
    rng = np.random.default_rng(seed)
    D = rng.normal(size=(n, 6, 6)) + 12.0 * np.eye(6)
    U = rng.normal(size=(n, 6, 6))
    L = rng.normal(size=(n, 6, 6))
    A = np.zeros((6 * n, 6 * n))
    for i in range(n):
        A[6 * i : 6 * i + 6, 6 * i : 6 * i + 6] = D[i]
        if i + 1 < n:
            A[6 * i : 6 * i + 6, 6 * i + 6 : 6 * i + 12] = U[i]
            A[6 * i + 6 : 6 * i + 12, 6 * i : 6 * i + 6] = L[i + 1]
    return D, U, L, A, rng.normal(size=(n, 6))


@pytest.mark.parametrize("n", [1, 2, 6])
def test_block_thomas_matches_dense_solve(n):
    D, U, L, A, r = _block_system(n, seed=n)
    G = np.zeros_like(D)
    piv = np.zeros((n, 6), np.int64)
    x = np.zeros((n, 6))
    assert block_factor(n, D, U, L, G, piv)
    block_solve(n, D, L, G, piv, r, x)
    np.testing.assert_allclose(x.ravel(), np.linalg.solve(A, r.ravel()), rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("n", [1, 3, 6])
def test_changing_the_last_block_needs_only_its_schur_complement(n):
    """block_factor_head leaves the last block's Schur complement S; factoring S + dD alone then
    solves the system whose last diagonal block is D_{n-1} + dD (the tip-contact refresh)."""
    D, U, L, A, r = _block_system(n, seed=10 + n)
    dD = np.random.default_rng(99).normal(size=(6, 6))
    A2 = A.copy()
    A2[-6:, -6:] += dD
    G = np.zeros_like(D)
    piv = np.zeros((n, 6), np.int64)
    assert block_factor_head(n, D, U, L, G, piv)
    D[n - 1] += dD
    assert lu6(D[n - 1], piv[n - 1])
    x = np.zeros((n, 6))
    block_solve(n, D, L, G, piv, r, x)
    np.testing.assert_allclose(x.ravel(), np.linalg.solve(A2, r.ravel()), rtol=1e-12, atol=1e-13)


def test_tcp_wrench_and_tip_states_match_the_formulas():
    rng = np.random.default_rng(5)
    nb = 7
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    R = q * np.sign(np.linalg.det(q))
    root_p = rng.normal(size=(nb, 3))
    rootw = rng.normal(size=(nb, 6))
    w = np.zeros(6)
    tcp_wrench(R, root_p, rootw, w)
    x = root_p @ R.T  # root nodes relative to the TCP, world axes
    np.testing.assert_allclose(w[0:3], -rootw[:, 0:3].sum(0), rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(
        w[3:6], -(rootw[:, 3:6] + np.cross(x, rootw[:, 0:3])).sum(0), rtol=1e-13, atol=1e-13
    )

    sim = Simulator(load_brush(overrides={"bodies_per_bristle": 3}), SimSettings(dt=1e-3))
    sim.reset(np.array([0.0, 0.0, 10.0]), R0)
    st, m = sim.state, sim.model
    st.vel[:] = rng.normal(size=st.vel.shape)
    st.omg[:] = rng.normal(size=st.omg.shape)
    last = m.bstart[1:] - 1
    r = m.bp["half"][last][:, None] * st.rot[last][:, :, 0]
    np.testing.assert_allclose(sim.tip_positions(), st.pos[last] + r, rtol=1e-15, atol=1e-14)
    np.testing.assert_allclose(
        sim.tip_velocities(), st.vel[last] + np.cross(st.omg[last], r), rtol=1e-14, atol=1e-14
    )


def test_pose_check():
    p = np.array([1.0, 2.0, 3.0])
    assert pose_ok(p, R0, 1e-6)
    assert not pose_ok(p, np.diag([1.0, 1.0, -1.0]), 1e-6)  # a reflection
    assert not pose_ok(p, 1.001 * np.eye(3), 1e-6)  # not orthonormal
    assert not pose_ok(np.array([0.0, np.nan, 0.0]), R0, 1e-6)
    bad = R0.copy()
    bad[0, 0] = np.inf
    assert not pose_ok(p, bad, 1e-6)


def test_a_failed_step_raises_and_leaves_the_state_untouched():
    """Two Newton iterations and no sub-steps cannot follow a 2 mm jump of the TCP in 1 ms: the
    step must raise SimulationDivergence (time, bristles) and restore every state array bit for
    bit -- twice in a row, since the rollback buffers are reused -- and the simulator must then
    go on from that state."""
    brush = load_brush(overrides={"bodies_per_bristle": 3})
    # (max_tcp_speed raised: the default refuses a 2000 mm/s command before Newton sees it)
    settings = SimSettings(dt=1e-3, newton_max_iter=2, max_halvings=0, max_tcp_speed=1e4)
    sim = Simulator(brush, settings)
    p0 = np.array([0.0, 0.0, 10.0])
    sim.reset(p0, R0)
    for k in range(1, 4):
        sim.step(p0 + [0.0, 0.0, 1e-4 * k], R0)
    before = sim.get_state()
    tips_before = sim.tip_positions().copy()
    for _ in range(2):
        with pytest.raises(SimulationDivergence) as err:
            sim.step(p0 + [2.0, 0.0, 0.0], R0)
        assert err.value.time == pytest.approx(before.time + 1e-3)
        assert len(err.value.bristles) > 0
        now = sim.state
        for name in [f.name for f in fields(now) if isinstance(getattr(now, f.name), np.ndarray)]:
            assert np.array_equal(getattr(now, name), getattr(before, name)), name
        assert now.time == before.time and now.steps == before.steps
        assert np.array_equal(sim.tip_positions(), tips_before)
    out = sim.step(p0 + [0.0, 0.0, 4e-4], R0)  # a small move converges again
    assert np.all(np.isfinite(out.tcp_force))


def _rodrigues(v):
    th = np.linalg.norm(v)
    if th == 0.0:
        return np.eye(3)
    k = np.asarray(v) / th
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(th) * K + (1.0 - np.cos(th)) * K @ K


@pytest.mark.parametrize("order", [2, 3])
def test_predictor_is_exact_for_polynomial_motion(order):
    """The extrapolating predictor reproduces, in the moving base frame, a motion polynomial in
    time of degree order - 1 exactly: positions x(t) and a rotation about a fixed axis with
    angle theta(t), while the base itself translates and turns."""
    rng = np.random.default_rng(order)
    n, h = 4, 1e-3
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1)[:, None]
    x0, v, acc = rng.normal(size=(n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3)) * 1e3
    th0, w, al = rng.normal(size=n), rng.normal(size=n), rng.normal(size=n) * 1e2
    if order == 2:
        acc[:] = 0.0
        al[:] = 0.0
    Q0 = np.stack([_rodrigues(rng.normal(size=3)) for _ in range(n)])

    def local(t):  # positions and rotations in the base frame
        x = x0 + v * t + 0.5 * acc * t * t
        Q = np.stack(
            [
                _rodrigues(axis[k] * (th0[k] + w[k] * t + 0.5 * al[k] * t * t)) @ Q0[k]
                for k in range(n)
            ]
        )
        return x, Q

    def base(t):  # an arbitrary moving base pose
        return np.array([1.0, 2.0, 3.0]) + 40.0 * t * np.array([1.0, -0.5, 0.2]), _rodrigues(
            np.array([0.3, -0.2, 0.5]) + 5.0 * t * np.array([0.1, 0.7, -0.2])
        )

    def world(t):
        pA, RA = base(t)
        x, Q = local(t)
        return pA + x @ RA.T, np.einsum("ij,kjl->kil", RA, Q)

    (pq, Rq), (pp, Rp), (ps, Rs), (pe, Re) = (world(k * h) for k in (-2, -1, 0, 1))
    (bq, BQ), (bp, BP), (bs, BS), (be, BE) = (base(k * h) for k in (-2, -1, 0, 1))
    pos, rot = np.zeros((n, 3)), np.zeros((n, 3, 3))
    ws = rec.make_work(n)
    ws.it.s_pos[:], ws.it.s_rot[:] = ps, Rs
    z = np.zeros((n, 3))
    chain = rec.Chain(pos, rot, z, z, pp, Rp, z, z, pq, Rq)
    base = rec.Base(bs, BS, be, BE, bp, BP, bq, BQ)
    _extrapolate(rec.Bristle(0, 0, n, n - 1), chain, order, base, ws.it, ws.mot)
    np.testing.assert_allclose(pos, pe, rtol=0, atol=1e-11)
    np.testing.assert_allclose(rot, Re, rtol=0, atol=1e-11)
