"""Discrete flexible bristle: element stiffness (eq 1-3), damping (eq 4-5) and body inertia (eq 11).

Discretisation (documented choice, see docs/model.md):

* A bristle of length ``L`` is split into ``n`` equal segments of length ``l = L/n``.  Node 0 is
  the root on the (kinematic) head; node ``k`` (k = 1..n) is the distal end of segment ``k``.
* Rigid body ``k`` carries segment ``k``: its mass and inertia are those of the segment (eq 11,
  with the section's own second moments), its centre of mass sits at the segment's midpoint, and
  its distal end *is* node ``k``.  The tip sphere is centred on node ``n``.
* Element ``k`` (the Timoshenko 6x6 stiffness of eq 1 with the shear factors of eq 2-3) joins node
  ``k-1`` (frame of body ``k-1``, or of the root) to node ``k`` (frame of body ``k``).  Because
  every element is an exact Timoshenko beam between two nodes, the linear static response of the
  chain
  to nodal loads is exact for any ``n``; ``n`` only controls geometric nonlinearity (large
  deflection) and the mass distribution (dynamics).
* Element strain (co-rotational, in the proximal frame A): ``d = R_A^T (p_B - p_A) - l e_x`` and
  ``phi = log(R_A^T R_B)``; element force ``f = K [d; phi] + C [d; phi]'`` (eq 5).
* Damping (eq 4, coefficients not printed in the paper): stiffness proportional, ``C = beta K``
  with ``beta = 2 zeta / omega_1`` so that the bristle's first bending mode has the material's
  damping ratio ``zeta``; higher modes are damped more, which is what a lossy silicone does.

Local bristle frame: x = bristle axis (root -> tip), y = section width direction, z = x cross y
(thickness direction).  ``I_y`` = int z^2 dA governs deflection along z; ``I_z`` deflection along y.
"""

from __future__ import annotations

import numpy as np

EB_BETA1_L = 1.8751040687119611  # first root of 1 + cos x cosh x = 0 (clamped-free beam)


def timoshenko_stiffness(E, G, A, I_y, I_z, J, kappa, l) -> np.ndarray:
    """6x6 element stiffness of eq 1 [N/mm, N, N*mm] for a segment of length ``l`` [mm].

    Order: (dx, dy, dz, phi_x, phi_y, phi_z).  The printed eq 1 mixes I_xx/I_zz in the y-bending
    coupling terms; the consistent Timoshenko element uses I_z throughout the y-deflection /
    z-rotation block and I_y in the z-deflection / y-rotation block (used here).  The shear factors
    of eq 2-3 are ``P = 12 E I / (kappa G A l^2)`` (the paper's shear area ratio A_s = 1/kappa).
    ``J`` is the section's torsion constant (the paper's I_xx in G I_xx / L).
    """
    Py = 12.0 * E * I_z / (kappa * G * A * l * l)
    Pz = 12.0 * E * I_y / (kappa * G * A * l * l)
    K = np.zeros((6, 6))
    K[0, 0] = E * A / l
    K[1, 1] = 12.0 * E * I_z / (l**3 * (1.0 + Py))
    K[1, 5] = K[5, 1] = -6.0 * E * I_z / (l**2 * (1.0 + Py))
    K[5, 5] = (4.0 + Py) * E * I_z / (l * (1.0 + Py))
    K[2, 2] = 12.0 * E * I_y / (l**3 * (1.0 + Pz))
    K[2, 4] = K[4, 2] = 6.0 * E * I_y / (l**2 * (1.0 + Pz))
    K[4, 4] = (4.0 + Pz) * E * I_y / (l * (1.0 + Pz))
    K[3, 3] = G * J / l
    return K


def mid_frame_stiffness(K: np.ndarray, l: float) -> np.ndarray:
    """The element stiffness ``K`` (eq 1, strains in the proximal frame A) carried to the strains
    of the mid-frame element (``_kernels._element_mid``): [R_m^T (p_B - p_A) - l e_x ; psi].

    To first order R_m = R_A exp(psi/2) gives d_m = d_A + (l/2) e_x x psi, i.e. q_m = T q_A with
    T = [[I, (l/2) [e_x]x], [0, I]]; equal strain energy then needs K_m = T^-T K T^-1.  For the
    Timoshenko matrix of eq 1 this is diagonal (EA/l; the shear stiffnesses of the element with
    the bending flexibility l^2/(12 E I) added; G J/l; E I/l), so one element still reproduces the
    linear Timoshenko cantilever under end loads exactly.
    """
    T = np.eye(6)
    T[1, 5] = -0.5 * l  # (e_x x psi)_y = -psi_z
    T[2, 4] = 0.5 * l  # (e_x x psi)_z = psi_y
    Ti = np.linalg.inv(T)
    Km = Ti.T @ K @ Ti
    return 0.5 * (Km + Km.T)


def segment_inertia(density, A, I_y, I_z, l):
    """Mass [t] and principal inertia (Jx, Jy, Jz) [t*mm^2] of one segment about its centre (eq 11).

    Eq 11 prints the round-section case (phi^2/8 axial, phi^2/16 + L^2/12 transverse); here each
    term uses the section's own second moment: Jx = m (I_y + I_z)/A, Jy = m (I_y/A + l^2/12),
    Jz = m (I_z/A + l^2/12), which reduces to eq 11 for a circle.
    """
    m = density * A * l
    return m, np.array(
        [m * (I_y + I_z) / A, m * (I_y / A + l * l / 12.0), m * (I_z / A + l * l / 12.0)]
    )


def first_bending_omega(E, I_min, density, A, L) -> float:
    """First Euler-Bernoulli cantilever bending frequency [rad/s] of the whole bristle."""
    return EB_BETA1_L**2 * np.sqrt(E * I_min / (density * A * L**4))


def bristle_frame(axis, width_dir) -> np.ndarray:
    """Columns (x, y, z) of the bristle's local frame expressed in the head/TCP frame."""
    x = np.asarray(axis, float)
    x = x / np.linalg.norm(x)
    y = np.asarray(width_dir, float) - np.dot(width_dir, x) * x
    y = y / np.linalg.norm(y)
    return np.column_stack([x, y, np.cross(x, y)])
