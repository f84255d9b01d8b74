"""The mid-frame element (issue 11) against its definition, written apart from the kernel.

The element stores U = e^T K e / 2 with the strain of ``_kernels._element_mid``:
psi = log(R_A^T R_B), R_m = R_A exp(psi / 2), e = [R_m^T (p_B - p_A) - l sinc(|psi_b| / 2) e_x;
psi] (psi_b = (psi_y, psi_z)).  The kernel claims its loads are the exact gradient of U, so they
are checked against central differences of U computed here with scipy's rotations: forces
-dU/dc and moments -dU/dphi (a small world rotation of a body about its centre, its node moving
with it), for both bodies.  Also: an arc has no axial or shear strain, a rigid motion changes no
load but their direction, the loads balance, and the carried stiffness is the linear element's.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from brush_env.engine import records as rec
from brush_env.engine._kernels import ELEM_MID, element_gen
from brush_env.engine.beam import mid_frame_stiffness, timoshenko_stiffness


def _rot(v):
    return Rotation.from_rotvec(v).as_matrix()


def _log(R):
    return Rotation.from_matrix(R).as_rotvec()


def mid_strain(pA, RA, pB, RB, length):
    """The mid-frame element's strain, from its definition."""
    psi = _log(RA.T @ RB)
    Rm = RA @ _rot(0.5 * psi)
    x = 0.5 * np.hypot(psi[1], psi[2])
    chord = length * (np.sin(x) / x if x > 0 else 1.0)
    return np.concatenate([Rm.T @ (pB - pA) - [chord, 0.0, 0.0], psi])


def kernel_loads(cA, RA, hA, cB, RB, hB, K, length, root):
    """(load on A, load on B, strain) of the kernel: force [N], moment about the centre [N mm]."""
    out12, e = np.zeros(12), np.zeros(6)
    A = rec.Node(np.asarray(cA, float), np.asarray(RA, float), float(hA))
    B = rec.Node(np.asarray(cB, float), np.asarray(RB, float), float(hB))
    damp = rec.Damp(np.zeros(6), 1.0, 0.0)
    element_gen(ELEM_MID, root, A, np.asarray(cA, float), B, K, length, damp, out12, e)
    return out12[:6], out12[6:], e


def _case(rng, root, bend):
    """Random strained element: body A (or the base node, root) and body B one element away."""
    length, hA, hB = 1.7, 0.85, 0.85
    RA = _rot(rng.normal(size=3))
    cA = rng.normal(size=3)
    pA = cA if root else cA + hA * RA[:, 0]
    psi = rng.normal(size=3) * bend
    RB = RA @ _rot(psi)
    pB = pA + RA @ _rot(0.5 * psi) @ np.array([length, 0.0, 0.0]) + rng.normal(size=3) * 0.02
    cB = pB - hB * RB[:, 0]
    return dict(cA=cA, RA=RA, hA=0.0 if root else hA, cB=cB, RB=RB, hB=hB, length=length)


def _stiffness(rng):
    K = mid_frame_stiffness(
        timoshenko_stiffness(7.0, 2.4, 1.44, 0.0768, 0.389, 0.2, 0.85, 1.7), 1.7
    )
    A = rng.normal(size=(6, 6)) * 0.05
    return K + A @ A.T  # symmetric, with couplings the diagonal matrix would not test


@pytest.mark.parametrize("root", [False, True], ids=["inner", "root"])
@pytest.mark.parametrize("bend", [0.05, 0.6, 1.5])
def test_loads_are_minus_the_energy_gradient(root, bend):
    rng = np.random.default_rng(int(10 * bend) + root)
    c = _case(rng, root, bend)
    K = _stiffness(rng)
    wA, wB, e = kernel_loads(
        c["cA"], c["RA"], c["hA"], c["cB"], c["RB"], c["hB"], K, c["length"], root
    )

    def energy(dcA, dpA, dcB, dpB):
        RA, RB = _rot(dpA) @ c["RA"], _rot(dpB) @ c["RB"]
        cA, cB = c["cA"] + dcA, c["cB"] + dcB
        pA = cA if root else cA + c["hA"] * RA[:, 0]
        ee = mid_strain(pA, RA, cB + c["hB"] * RB[:, 0], RB, c["length"])
        return 0.5 * ee @ K @ ee

    z = np.zeros(3)
    np.testing.assert_allclose(
        e,
        mid_strain(
            c["cA"] if root else c["cA"] + c["hA"] * c["RA"][:, 0],
            c["RA"],
            c["cB"] + c["hB"] * c["RB"][:, 0],
            c["RB"],
            c["length"],
        ),
        atol=1e-12,
    )
    h = 1e-6
    grad = np.zeros((4, 3))
    for a in range(3):
        s = np.zeros(3)
        s[a] = h
        for j in range(4):
            args_p = [s if k == j else z for k in range(4)]
            args_m = [-s if k == j else z for k in range(4)]
            grad[j, a] = (energy(*args_p) - energy(*args_m)) / (2 * h)
    scale = max(np.abs(grad).max(), 1e-12)
    np.testing.assert_allclose(wB[:3], -grad[2], atol=1e-6 * scale)
    np.testing.assert_allclose(wB[3:], -grad[3], atol=1e-6 * scale)
    if not root:
        np.testing.assert_allclose(wA[:3], -grad[0], atol=1e-6 * scale)
        np.testing.assert_allclose(wA[3:], -grad[1], atol=1e-6 * scale)


def test_a_circular_arc_has_no_axial_or_shear_strain():
    """Nodes on a circle of radius r with tangent frames: the element is an inextensible arc of
    length l = r * angle, so e = (0, 0, 0, psi) whatever the bend."""
    for angle in (0.01, 0.4, 1.2, 2.5):
        r = 1.7 / angle
        RA = _rot([0.0, 0.0, 0.3])
        RB = RA @ _rot([0.0, angle, 0.0])  # bend about y: the arc lies in the x-z plane of A
        pA = np.zeros(3)
        # arc in A's x-z plane: tangent x, turning toward -z for a positive rotation about y
        pB = pA + RA @ np.array([r * np.sin(angle), 0.0, -r * (1 - np.cos(angle))])
        cB = pB - 0.85 * RB[:, 0]
        _, _, e = kernel_loads(pA, RA, 0.0, cB, RB, 0.85, np.eye(6), 1.7, True)
        np.testing.assert_allclose(e[:3], 0.0, atol=1e-12)
        np.testing.assert_allclose(e[3:], [0.0, angle, 0.0], atol=1e-12)


def test_rigid_motion_turns_the_loads_and_they_balance():
    rng = np.random.default_rng(7)
    c = _case(rng, False, 0.8)
    K = _stiffness(rng)
    wA, wB, e = kernel_loads(
        c["cA"], c["RA"], c["hA"], c["cB"], c["RB"], c["hB"], K, c["length"], False
    )
    Q, t = _rot([0.4, -1.1, 2.0]), np.array([3.0, -1.0, 0.5])
    vA, vB, e2 = kernel_loads(
        Q @ c["cA"] + t,
        Q @ c["RA"],
        c["hA"],
        Q @ c["cB"] + t,
        Q @ c["RB"],
        c["hB"],
        K,
        c["length"],
        False,
    )
    np.testing.assert_allclose(e2, e, atol=1e-12)
    for w, v in ((wA, vA), (wB, vB)):
        np.testing.assert_allclose(v[:3], Q @ w[:3], atol=1e-12)
        np.testing.assert_allclose(v[3:], Q @ w[3:], atol=1e-12)
    # internal element: zero net force and zero net moment about the origin
    np.testing.assert_allclose(wA[:3] + wB[:3], 0.0, atol=1e-12)
    M = wA[3:] + wB[3:] + np.cross(c["cA"], wA[:3]) + np.cross(c["cB"], wB[:3])
    np.testing.assert_allclose(M, 0.0, atol=1e-11)


def test_carried_stiffness_keeps_the_linear_element():
    """K_m = T^-T K T^-1 stores the same energy for small strains: the mid-frame strain of a
    slightly deformed element equals T times the proximal one, and e_m^T K_m e_m = e_A^T K e_A."""
    l = 1.7
    K = timoshenko_stiffness(7.0, 2.4, 1.44, 0.0768, 0.389, 0.2, 0.85, l)
    Km = mid_frame_stiffness(K, l)
    np.testing.assert_allclose(Km, np.diag(np.diag(Km)), atol=1e-12 * np.abs(Km).max())
    rng = np.random.default_rng(3)
    q = rng.normal(size=6) * 1e-6
    RA = np.eye(3)
    RB = _rot(q[3:])
    pB = np.array([l, 0, 0]) + q[:3]
    eA = np.concatenate([pB - [l, 0, 0], _log(RB)])
    em = mid_strain(np.zeros(3), RA, pB, RB, l)
    np.testing.assert_allclose(eA @ K @ eA, em @ Km @ em, rtol=1e-5)
