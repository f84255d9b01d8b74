"""The bristle-model seam (issue 27, ``engine/bristles.py``): a second bristle model plugs in
beside the full DFM chain through ``register_bristle_model`` and a fidelity level's ``model``
key, and runs through FlatPlate-v0 and the reference experiment with no change outside the seam.

The toy model here is rigid bristles: each bristle is a straight rigid rod fixed to the head, its
tip sphere pressed into the plate by the penalty law of eq 6 with m1 = 1 and no damping (k from
the scene's contact table), no friction.  Checked against what a rigid brush must do: the tips
follow the head exactly, and the TCP force balances the plate's push (statics: F_tcp = -sum Fn n,
and the moment of the tip loads about the TCP).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from brush_env.engine import Plane, Simulator, load_scene
from brush_env.engine.bristles import (
    BristleModel,
    TipContact,
    bristle_models,
    register_bristle_model,
)
from brush_env.engine.chain import build_model
from brush_env.engine.checks import ConfigError
from brush_env.engine.fidelity import level_settings

K_TIP = 1.0  # [N/mm] the toy's contact stiffness (soft: a brush of 40 tips pressed 1 mm ~ 40 N)


@dataclass
class RigidState:
    pos: np.ndarray
    rot: np.ndarray
    tcp_p: np.ndarray
    tcp_R: np.ndarray
    tips: np.ndarray
    time: float = 0.0
    steps: int = 0

    def copy(self):
        return RigidState(
            self.pos.copy(),
            self.rot.copy(),
            self.tcp_p.copy(),
            self.tcp_R.copy(),
            self.tips.copy(),
            self.time,
            self.steps,
        )


class RigidBristles(BristleModel):
    """Rigid bristles on planes (module docstring)."""

    def __init__(self, scene, settings):
        self.model = build_model(scene.brush)  # the brush geometry (bstart, roots, lengths)
        self.h = settings.dt / settings.substeps
        self.planes = [s for s in scene.surfaces if isinstance(s, Plane)]
        nb = self.model.n_bristles
        self.root_wrench = np.zeros((nb, 6))
        self._loads = np.zeros((nb, 3))
        self._fn = np.zeros(nb)
        self._pen = np.zeros(nb)
        self._n = np.zeros((nb, 3))
        self.state = None

    @property
    def tip_forces(self):
        return self._loads

    def set_tip_forces(self, forces):
        self._loads[:] = forces

    @property
    def tips(self):
        return self.state.tips

    def _place(self, tcp_p, tcp_R):
        m, st = self.model, self.state
        Rw = np.einsum("ij,bjk->bik", tcp_R, m.root_R)
        roots = tcp_p + m.root_p @ tcp_R.T
        for j in range(m.n_bristles):
            k = np.arange(m.bstart[j], m.bstart[j + 1])
            st.pos[k] = (
                roots[j] + ((k - m.bstart[j]) + 0.5)[:, None] * m.seg_len[k, None] * Rw[j][:, 0]
            )
            st.rot[k] = Rw[j]
        return roots, roots + m.length[:, None] * Rw[:, :, 0]

    def reset(self, tcp_p, tcp_R, time):
        m = self.model
        N, nb = m.n_bodies, m.n_bristles
        self.state = RigidState(
            np.zeros((N, 3)),
            np.zeros((N, 3, 3)),
            np.stack([tcp_p] * 4),
            np.stack([tcp_R] * 4),
            np.zeros((nb, 6)),
            time,
        )
        self._loads_and_contact(tcp_p, tcp_R, None)

    def _loads_and_contact(self, tcp_p, tcp_R, old_tips):
        roots, tips = self._place(tcp_p, tcp_R)
        st = self.state
        if old_tips is not None:
            st.tips[:, 3:6] = (tips - old_tips) / self.h
        st.tips[:, 0:3] = tips
        self._fn[:] = 0.0
        self._pen[:] = 0.0
        f = self._loads.copy()
        for pl in self.planes:
            n = np.asarray(pl.normal, float) / np.linalg.norm(pl.normal)
            gap = (tips - np.asarray(pl.point)) @ n - self.model.tip_radius
            pen = np.maximum(-gap, 0.0)
            deeper = pen > self._pen
            self._pen = np.where(deeper, pen, self._pen)
            self._n[deeper] = n
            self._fn += K_TIP * pen
            f += K_TIP * pen[:, None] * n
        # each rigid bristle passes its tip load to the head: force f, moment (tip - root) x f
        self.root_wrench[:, 0:3] = f
        self.root_wrench[:, 3:6] = np.cross(tips - roots, f)

    def snapshot(self):
        return self.state.copy()

    def set_state(self, state):
        self.state = state.copy()

    def advance(self, tcp_p, tcp_R, t_new, rollback=None):
        st = self.state
        old = st.tips[:, 0:3].copy()
        st.tcp_p[0], st.tcp_R[0] = st.tcp_p[1], st.tcp_R[1]
        st.tcp_p[1], st.tcp_R[1] = tcp_p, tcp_R
        self._loads_and_contact(tcp_p, tcp_R, old)
        st.time, st.steps = t_new, st.steps + 1
        return 0, 1

    def solve_static(self, tcp_p, tcp_R):
        return self.advance(tcp_p, tcp_R, self.state.time)

    def contact(self):
        nb = self.model.n_bristles
        touching = self._fn > 0.0
        return TipContact(
            self._fn.copy(),
            np.zeros((nb, 3)),
            np.zeros(nb, bool),
            self._pen.copy(),
            np.where(touching[:, None], self.state.tips[:, 0:3] - self._pen[:, None] * self._n, 0),
            np.zeros(nb),
            np.where(touching, 0, -1).astype(np.int64),
        )


@pytest.fixture
def rigid_level(tmp_path):
    register_bristle_model("rigid", RigidBristles)
    p = tmp_path / "rigid.toml"
    p.write_text(
        'name = "rigid"\ndescription = "toy: rigid bristles"\n[settings]\nmodel = "rigid"\n'
        "bodies_per_bristle = 2\nmax_substep = 0.002\n"
    )
    return p


def test_the_full_chain_is_registered_and_an_unknown_model_is_named():
    assert "dfm" in bristle_models()
    with pytest.raises(ConfigError, match="settings.model = 'rigdi'.*known: .*dfm"):
        Simulator(load_scene("flat_plate"), level_settings(None, model="rigdi"))


def test_rigid_toy_statics_through_the_simulator(rigid_level):
    """The simulator's TCP wrench from the toy's root reactions equals the statics of a rigid
    brush pressed into the plate: F = -sum Fn n, M = -sum (tip - tcp) x Fn n."""
    sim = Simulator(load_scene("flat_plate"), level_settings(rigid_level, dt=4e-3))
    R = np.diag([1.0, -1.0, -1.0])
    z = sim.touch_height(R, 0.0)
    sim.reset(np.array([0.0, 0.0, z]), R)
    out = sim.step(np.array([0.3, 0.0, z - 0.03]), R)  # 30 um: inside eq 6's range
    assert out.substeps == 2  # 4 ms in solver steps of <= 2 ms
    fn = out.tip_normal_force
    assert fn.sum() > 0.1 and np.all(fn >= 0.0)
    F = np.array([0.0, 0.0, -fn.sum()])
    np.testing.assert_allclose(out.tcp_force, F, atol=1e-12)
    arm = out.tip_pos - np.array([0.3, 0.0, z - 0.03])
    M = -np.cross(arm, fn[:, None] * np.array([0.0, 0.0, 1.0])).sum(axis=0)
    np.testing.assert_allclose(out.tcp_moment, M, atol=1e-9)
    # rigid: the tips moved exactly with the head
    np.testing.assert_allclose(out.tip_vel[:, 0], 0.3 / 4e-3, rtol=1e-9)


# a rigid brush pressed on a plate penetrates as deep as it is pressed: the warning is right
RIGID_PENETRATES = pytest.mark.filterwarnings(
    "ignore::brush_env.engine.simulator.PenetrationWarning"
)


@RIGID_PENETRATES
def test_rigid_toy_runs_through_flat_plate_env(rigid_level):
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env

    import brush_env  # noqa: F401

    env = gym.make("brush_env/FlatPlate-v0", fidelity=str(rigid_level))
    u = env.unwrapped
    assert isinstance(u.sim.bristles, RigidBristles)
    assert u.sim.model.n_bodies == 2 * u.n_bristles
    check_env(u, skip_render_check=True)
    env.reset(seed=0)
    peak = 0.0
    for _ in range(30):
        _, r, term, trunc, info = env.step(np.array([0, 0, -1, 0, 0, 0], np.float32))
        peak = max(peak, float(np.sum(u._last.tip_normal_force)))
        assert np.isfinite(r)
        if term or trunc:
            break
    assert peak > 0.0  # the toy's tips reached the plate through the env
    env.close()


@RIGID_PENETRATES
def test_rigid_toy_runs_the_reference_experiment(rigid_level, tmp_path):
    from brush_env.experiments.run import run_reference

    s = run_reference(
        out_dir=tmp_path / "ref",
        turns=0.05,
        fidelity=str(rigid_level),
        progress=False,
        plots=False,
    )
    assert s["status"] == "ok"
    assert s["settings"]["bodies"] == [2]
    ts = np.genfromtxt(tmp_path / "ref" / "timeseries.csv", delimiter=",", names=True)
    fz = [n for n in ts.dtype.names if n.lower().startswith("fz")][0]
    # the 3 mm press of a rigid brush: the plate pushes back on every tip, K_TIP per mm
    assert np.max(np.abs(ts[fz])) > 1.0
