"""Modal analysis of one bristle, linearised about the simulator's current (equilibrium) state.

Stiffness: the static Newton matrix of the kernels (the same element forces the time stepper uses,
so this checks the model, not a second implementation); mass: blockdiag(m I, R J R^T) per body
(eq 11).  Solves K phi = omega^2 M phi densely (6n x 6n; n is at most a few dozen).
"""

from __future__ import annotations

import numpy as np

from ..engine import records as rec
from ..engine.residual import jacobian
from ..engine.rotation import expmap, logmap
from ..engine.settings import ELEMENTS

ELEM_MID = ELEMENTS["mid"]  # the kernels' code of the mid-frame element


def bristle_stiffness_mass(sim, bristle: int = 0):
    """Dense tangent stiffness K [N/mm, N, N*mm] and mass M [t, t*mm^2] of one bristle."""
    st, m = sim.state, sim.model
    b0, b1 = int(m.bstart[bristle]), int(m.bstart[bristle + 1])
    n = b1 - b0
    pA = st.tcp_p[1] + st.tcp_R[1] @ m.root_p[bristle]
    RA = st.tcp_R[1] @ m.root_R[bristle]
    D, U, L = (np.zeros((n, 6, 6)) for _ in range(3))
    ws = rec.make_work(n)
    ws.hist.gs[:n] = 1.0  # statics: no damping, no rate history
    base = ws.base
    base.pAe[:], base.RAe[:] = pA, RA
    chain = rec.Chain(
        st.pos, st.rot, st.vel, st.omg, st.ppos, st.prot, st.pvel, st.pomg, st.pppos, st.pprot
    )
    sub = rec.Substep(1.0, 0.0, 0.0, 1.0, 1.0, True, np.zeros(3), 0.0, 0, 0.0)
    br = rec.Bristle(bristle, b0, n, b1 - 1)
    jacobian(br, m.arrays(), chain, sub, base, ws.hist, D, U, L, ws)
    K = np.zeros((6 * n, 6 * n))
    M = np.zeros((6 * n, 6 * n))
    for k in range(n):
        i = b0 + k
        K[6 * k : 6 * k + 6, 6 * k : 6 * k + 6] = D[k]
        if k + 1 < n:
            K[6 * k : 6 * k + 6, 6 * k + 6 : 6 * k + 12] = U[k]
        if k > 0:
            K[6 * k : 6 * k + 6, 6 * k - 6 : 6 * k] = L[k]
        R = st.rot[i]
        M[6 * k : 6 * k + 3, 6 * k : 6 * k + 3] = m.bp[i]["mass"] * np.eye(3)
        M[6 * k + 3 : 6 * k + 6, 6 * k + 3 : 6 * k + 6] = R @ np.diag(m.bp[i]["J"]) @ R.T
    return K, M


def natural_frequencies(sim, bristle: int = 0, n_modes: int = 6) -> np.ndarray:
    """Lowest natural frequencies [Hz] of one bristle about the current state (base clamped)."""
    K, M = bristle_stiffness_mass(sim, bristle)
    Ks = 0.5 * (K + K.T)  # the finite-difference tangent is symmetric up to ~1e-7
    Lc = np.linalg.cholesky(M)
    Li = np.linalg.inv(Lc)
    w2 = np.linalg.eigvalsh(Li @ Ks @ Li.T)
    return np.sqrt(np.clip(np.sort(w2)[:n_modes], 0.0, None)) / (2.0 * np.pi)


def element_strains(sim) -> np.ndarray:
    """Co-rotational strain [d (mm); phi (rad)] of every element (N, 6), as the kernels define it
    (eq 5 with the strain in the proximal frame, or in the mid-frame R_A exp(phi/2) for the "mid"
    element); 1/2 e^T K e is the element's elastic energy."""
    st, m = sim.state, sim.model
    out = np.zeros((m.n_bodies, 6))
    for j in range(m.n_bristles):
        pA = st.tcp_p[1] + st.tcp_R[1] @ m.root_p[j]
        RA = st.tcp_R[1] @ m.root_R[j]
        for i in range(m.bstart[j], m.bstart[j + 1]):
            pB = st.pos[i] + m.bp[i]["half"] * st.rot[i][:, 0]
            out[i, 3:] = logmap(RA.T @ st.rot[i])
            chord = m.bp[i]["length"]
            Rf = RA
            if m.elem[i] == ELEM_MID:  # mid-frame and the arc's chord (_kernels._element_mid)
                Rf = RA @ expmap(0.5 * out[i, 3:])
                x = 0.5 * np.hypot(out[i, 4], out[i, 5])
                chord *= np.sinc(x / np.pi)
            out[i, :3] = Rf.T @ (pB - pA) - np.array([chord, 0.0, 0.0])
            pA, RA = pB, st.rot[i]
    return out
