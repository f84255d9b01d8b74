"""The tabulated tip law (``engine/tip_table.py``, the level ``fast``): its geometry inverts the
reduced chain's kinematics, every table entry is an equilibrium of the chain (the spring torques
are the tip load's through the chain's own Jacobian, ``prb_kernels.kinematics``), and the model
built on it carries the chain's load and runs the same twice (the Timoshenko cantilever's small
load: ``tests/engine/test_prb.py``, both models).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from brush_env.engine import Simulator, load_scene, tip_table
from brush_env.engine import prb_kernels as K
from brush_env.engine import tip_table_kernels as T
from brush_env.engine.config import load_brush
from brush_env.engine.fidelity import level_settings
from brush_env.engine.prb import build_geometry
from brush_env.motion import R0


@functools.cache
def _joint(group: str):
    """The default brush's joint record of an inner (bristle 0) or outer (bristle 20) tuft."""
    prm = build_geometry(load_brush("default")).prm
    return prm[0 if group == "inner" else 20]


def test_the_shipped_brushes_tables_ship_with_the_package():
    """Every joint record of every brush in configs/brushes has its table in the package
    (``tip_table.SHIPPED``): a user of a shipped brush never builds one (~60 s each), and a brush
    or calibration changed without ``brush-env calibrate --all --ship`` fails here."""
    from brush_env.engine import configs_dir

    names = sorted(p.stem for p in (configs_dir() / "brushes").glob("*.toml"))
    assert "default" in names
    for name in names:
        for j in tip_table.distinct_joints(build_geometry(load_brush(name)).prm).values():
            path = tip_table.SHIPPED / f"{tip_table.table_key(j)}.npz"
            assert path.is_file(), f"{name}: {path.name} not shipped"


@pytest.mark.parametrize("group", ["inner", "outer"])
def test_a_fresh_table_matches_the_shipped_one(group):
    """The unloaded path and four layers (just below the top, the unloaded path's, two below it:
    the highest and lowest layers hold no branch) built here (their damping matrices from the
    shipped table's joint angles),
    from the shipped calibration, against the shipped table of the default brush's inner and
    outer tufts: the same branches exist at every node, and their values agree to a few units of
    the single precision they are stored in (another machine's build differs in the last bits of
    its minima, not more)."""
    j = _joint(group)
    shipped = tip_table.load(tip_table.SHIPPED / f"{tip_table.table_key(j)}.npz")
    assert shipped is not None, "the default brush's table is not shipped"
    grid = tip_table.table_grid(j)
    g = grid[0]
    rnat = np.zeros(tip_table.SHAPE[1:])
    vals = np.zeros((2, *tip_table.SHAPE), T.ENTRY)
    fresh = T.Table(g, rnat, vals)
    T.build_rnat(fresh, np.asarray(j).reshape(1)[0])
    np.testing.assert_allclose(rnat, shipped.rnat, rtol=1e-9)
    for i in (1, int(g["nu"]), 40, 60):
        T.build_layer(fresh, np.asarray(j).reshape(1)[0], i)
        new, old = vals[:, i], shipped.vals[:, i]
        np.testing.assert_array_equal(new["ok"], old["ok"])
        on = new["ok"] == 1.0
        assert on.sum() > 100
        for name in ("U", "g", "q"):
            a, b = new[name][on], old[name][on].astype(float)
            scale = np.abs(a).max()
            np.testing.assert_allclose(a, b, rtol=0, atol=2e-6 * scale, err_msg=f"layer {i} {name}")
    # the damping matrices come from the joint angles of the whole table (``grid_damping``):
    # from the shipped angles, the shipped matrices (to their single precision)
    full = np.zeros(shipped.vals.shape, T.ENTRY)
    for name in T.ENTRY32.names:
        full[name] = shipped.vals[name]
    T.grid_damping(T.Table(g, shipped.rnat, full), np.asarray(j).reshape(1)[0])
    on = full["ok"] == 1.0
    np.testing.assert_allclose(full["D"][on], shipped.vals["D"][on], rtol=1e-6, atol=1e-12)


def _kin(q, geo):
    x, J = np.zeros(3), np.zeros((3, K.NQ))
    K.kinematics(
        np.asarray(q, float),
        geo,
        x,
        J,
        np.zeros((K.NQ, 2)),
        np.zeros(K.NQ, np.int64),
        np.zeros(3),
        np.zeros(3),
    )
    return x, J


def _elbow_angle(q, geo):
    """The elbow's angle about the chord from joint 1 to the tip (``tip_table_kernels``)."""
    s0, l1, l2 = geo
    x, _ = _kin(q, geo)
    q1 = np.array([q[0], q[1], 0.0, 0.0, q[4]])
    xe, _ = _kin(q1, np.array([s0, l1, 0.0]))  # joint 1 + l1 * link 1: the elbow
    u = x - np.array([s0, 0.0, 0.0])
    rho = np.linalg.norm(u)
    fr = np.zeros((3, 3))
    T.chord_frame(u / rho, fr)
    a = (l1 * l1 - l2 * l2 + rho * rho) / (2.0 * rho)
    o = xe - np.array([s0, 0.0, 0.0]) - a * u / rho
    return x, float(np.arctan2(o @ fr[:, 2], o @ fr[:, 1]))


def test_inverse_kinematics_inverts_the_chain():
    """For 200 random joint angles: the tip of ``prb_kernels.kinematics`` and its elbow angle
    give the same angles back through ``tip_table_kernels.ik``."""
    j = _joint("inner")
    geo = np.array(j["geo"], float)
    rng = np.random.default_rng(0)
    q2, fr = np.zeros(5), np.zeros((3, 3))
    for _ in range(200):
        q = rng.uniform(-1.0, 1.0, 5) * np.array([1.2, 0.6, 1.2, 0.6, 0.5])
        x, psi = _elbow_angle(q, geo)
        assert T.ik(x, psi, q[4], geo, q2, fr)
        np.testing.assert_allclose(q2, q, atol=1e-9)


@pytest.mark.parametrize("group", ["inner", "outer"])
def test_every_entry_is_an_equilibrium_of_the_chain(group):
    """At every 7th node of both branches: the stored joint angles put the tip on the node (to their
    single precision), and the joints' spring torques K (e + c3 e^3) are the stored tip load through
    the chain's Jacobian, J^T grad U (the chain in equilibrium under that load), to 1e-3 of the
    torque (and 1e-6 of the stiffest joint's, at the unloaded tip). The load is a difference
    quotient of the energy; 99.99 % of the entries are within 1e-4, the rest (a chain pulled nearly
    straight, the first layers above its unloaded path) within 7.5e-4."""
    j = _joint(group)
    tb = tip_table.table(j)
    tbk = T.Table(tb.grid[0], tb.rnat, tb.vals)
    geo = np.array(j["geo"], float)
    k, c3, rest = (np.array(j[f], float) for f in ("k", "c3", "rest"))
    x = np.zeros(3)
    g = tb.grid[0]
    checked = 0
    for n, (i, jj, m) in enumerate(np.ndindex(int(g["nr"]), int(g["nt"]), int(g["np"]))):
        if n % 7:
            continue
        T.node_x(tbk, i, jj, m, x)
        for s in range(2):
            v = tb.vals[s, i, jj, m]
            if v["ok"] == 0.0:
                continue
            q = v["q"].astype(float)
            xt, J = _kin(q, geo)
            # (the angles are stored in single precision: ~1.5e-7 rad at 2.5 rad)
            np.testing.assert_allclose(xt, x, atol=1e-6 * geo[1:].sum())
            e = q - rest
            tau = k * np.array([K._spring(e[i], c3[i] if i < 4 else 0.0)[0] for i in range(5)])
            load = J.T @ v["g"].astype(float)
            assert np.abs(tau - load).max() <= 1e-3 * np.abs(tau).max() + 1e-6 * k.max()
            checked += 1
    assert checked > 1000


def _lookup(tbk, s, xl, e):
    """(w, out, g, Jg, D, T) of ``tip_table_kernels.lookup`` at xl with the tip's move e."""
    g, Jg, D, q, scr = (
        np.zeros(3),
        np.zeros((3, 3)),
        np.zeros((3, 3)),
        np.zeros(5),
        np.zeros((16, 3)),
    )
    scr[12] = e
    w, out, _ = T.lookup(tbk, s, np.asarray(xl, float), g, Jg, D, q, True, scr)
    return w, out, g, Jg, D, scr[13:16].copy()


def test_lookup_tangents_are_the_interpolants_derivatives():
    """Newton's tangents of the table (``lookup``): Jg = d grad U / dxl and T = dD/dxl e (the
    damping force's change with the tip through its matrix) against central differences of the
    interpolant, at 600 random tips (both sides of the mirror plane y = 0, both branches); those
    inside the table where the branch holds all 8 corners of the cell are compared (about 40 %
    are not: a branch exists in part of the space only).  A difference whose two one-sided
    quotients disagree straddles a cell face (the interpolant's slope jumps there) and is not
    compared either; at least 250 are."""
    j = _joint("inner")
    tb = tip_table.table(j)
    tbk = T.Table(tb.grid[0], tb.rnat, tb.vals)
    geo = np.array(j["geo"], float)
    L = geo[1] + geo[2]
    rng = np.random.default_rng(3)
    h = 1e-7  # [mm]: cells are ~0.1 mm
    checked = 0
    for _ in range(600):
        rho = rng.uniform(0.5, 0.95) * L
        th, ph = np.radians(rng.uniform(5.0, 120.0)), rng.uniform(-np.pi, np.pi)
        xl = np.array(
            [
                geo[0] + rho * np.cos(th),
                rho * np.sin(th) * np.cos(ph),
                rho * np.sin(th) * np.sin(ph),
            ]
        )
        e = rng.normal(size=3) * 0.3
        s = int(rng.integers(2))
        w, out, g0, Jg, D0, Tm = _lookup(tbk, s, xl, e)
        full = 1.0 - 1e-9  # the corners' weights sum to 1 (to rounding) where all 8 hold the branch
        if w < full or out != 0:
            continue
        ok = True
        fd_J, fd_T = np.zeros((3, 3)), np.zeros((3, 3))
        for m in range(3):
            dx = np.zeros(3)
            dx[m] = h
            wp, op, gp, _, Dp, _ = _lookup(tbk, s, xl + dx, e)
            wm, om, gm, _, Dm, _ = _lookup(tbk, s, xl - dx, e)
            if min(wp, wm) < full or op or om:
                ok = False
                break
            fwd, bwd = (gp - g0) / h, (g0 - gm) / h
            if not np.allclose(fwd, bwd, rtol=1e-3, atol=1e-6 * np.abs(Jg).max()):
                ok = False  # a cell face between the two
                break
            fd_J[:, m] = (gp - gm) / (2 * h)
            fd_T[:, m] = (Dp - Dm) @ e / (2 * h)
        if not ok:
            continue
        np.testing.assert_allclose(Jg, fd_J, rtol=1e-4, atol=1e-5 * np.abs(Jg).max())
        np.testing.assert_allclose(Tm, fd_T, rtol=1e-4, atol=1e-5 * max(np.abs(fd_T).max(), 1e-12))
        checked += 1
    assert checked >= 250


def _scrub(level):
    """The brush pressed 0.3 mm past touch while it moves 20 mm/s along x and 15 mm/s down for
    40 engine steps (4 ms), then held: (tips, TCP force) at the end."""
    sc = load_scene("flat_plate")
    s = Simulator(sc, level_settings(level, dt=4e-3))
    s.reset(np.array([0.0, 0.0, s.touch_height(R0) + 0.2]), R0)
    for _ in range(4):
        ro = s.rollout(np.array([20.0, 0.0, -15.0]), np.zeros(3), 10)
    return ro.last


def test_models_of_one_brush_share_its_tables():
    """Two simulators of the default brush at ``table`` read the same table arrays (N envs of one
    brush held N copies of ~30 MB), each with its own counters; the shared tables give the same
    steps as before: ``test_rollout_is_deterministic`` runs two models, one after the other."""
    sc = load_scene("flat_plate")
    a = Simulator(sc, level_settings("fast", dt=4e-3)).bristles._tab
    b = Simulator(sc, level_settings("fast", dt=4e-3)).bristles._tab
    assert a.vals is b.vals and a.grid is b.grid and a.rnat is b.rnat
    assert a.fallback is not b.fallback and a.scr is not b.scr


def test_rollout_is_deterministic():
    """Same start and motion at the level ``fast``: the same result bit for bit."""
    a, b = _scrub("fast"), _scrub("fast")
    assert np.array_equal(a.tip_pos, b.tip_pos)
    assert np.array_equal(a.tcp_force, b.tcp_force)


def test_table_carries_the_chains_load():
    """The brush pressed and dragged (``_scrub``): the table's TCP force within 3 % of the
    chain it tabulates (level ``reduced``), every tip within 0.05 mm of the chain's."""
    a, b = _scrub("fast"), _scrub("reduced")
    assert b.tip_in_contact.sum() > 20
    assert np.linalg.norm(a.tcp_force - b.tcp_force) <= 0.03 * np.linalg.norm(b.tcp_force)
    assert np.abs(a.tip_pos - b.tip_pos).max() < 0.05


#: FlatPlate-v0 (3-d actions, reset seed 1018): a PPO policy's first 8 actions -- the brush
#: lowered onto the plate, then swept sideways 2 mm in one 40 ms step while 20 tips stick
DRAG_ACTIONS = [[-0.2948, -0.6961, -0.3883]] + [
    [-0.2564 + 0.0032 * k, -0.6950 + 0.0023 * k, -0.3784 - 0.0013 * k] for k in range(6)
]
DRAG_ACTIONS.append([1.0, 0.588, -0.4661])


def _drag_forces(level):
    import gymnasium as gym

    env = gym.make(
        "brush_env/FlatPlate-v0",
        fidelity=level,
        action_mode="3d",
        frame_skip=1,
        max_episode_steps=1000,
    )
    env.reset(seed=1018)
    out = []
    for a in DRAG_ACTIONS:
        for _ in range(10):  # the policy's 25 Hz: ten 4 ms engine steps per action
            _, _, term, _, info = env.step(np.asarray(a, np.float32))
            assert not term, info.get("termination")
            out.append(info["total_normal_force"])
    env.close()
    return np.array(out)


def test_a_dragged_brush_with_stuck_tips_carries_the_chains_force():
    """The damping the table puts on a moving tip (``tip_table_kernels.grid_damping``): the
    brush lowered onto the plate and dragged 2 mm sideways in 40 ms with 20 tips stuck.  The
    chain the table tabulates (level ``reduced``) carries 1.6 N falling to 1.0 N through the drag
    (2.1-2.3 N before its tips had the axial compliance, session 17; the full chain at
    ``balanced`` 1.56-1.71 N, 1.08 N at the last step); the table's force stays within 30 % of
    the chain's until the step's last 4 ms (where the table's tips snap to the other branch a
    step before the chain's and unload).  With each node's own damping matrix (dq/dx differenced
    0.01 mm apart, unbounded beside a branch's end) the table read 8.9 and 16.8 N there: the
    force limit stopped the episode."""
    a, b = _drag_forces("fast"), _drag_forces("reduced")
    assert b[-10:].min() > 0.9  # pressed: the 20 tips carry the brush's force
    np.testing.assert_array_less(np.abs(a[:-1] - b[:-1]), 0.3 * b[:-1] + 1e-3)
    assert a.max() <= 1.3 * b.max()


def test_flat_plate_at_fast_passes_both_env_checkers():
    """FlatPlate-v0 at the level ``fast``: Gymnasium's and stable-baselines3's env checkers,
    and a pressed episode's first 20 steps finite."""
    import gymnasium as gym
    from gymnasium.utils.env_checker import check_env
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    import brush_env  # noqa: F401

    env = gym.make("brush_env/FlatPlate-v0", fidelity="fast")
    check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=True)
    env.reset(seed=0)
    for _ in range(20):
        obs, r, term, trunc, _ = env.step(np.array([0, 0, -1, 0, 0, 0], np.float32))
        assert np.isfinite(r) and all(np.all(np.isfinite(v)) for v in _flat(obs))
        if term or trunc:
            break
    env.close()


def _flat(obs):
    return obs.values() if isinstance(obs, dict) else [obs]


def test_a_tip_beyond_its_table_warns_once_per_reset_naming_the_bristle():
    """A step that ends with a tip beyond its table (counted by the kernel in ``Tab.outside``)
    warns once per reset, naming the bristle and the table's limits; the counts of such steps
    and of the steps the table handed to the chain are in ``solver_info``."""
    from brush_env.engine.prb import TableRangeWarning

    sc = load_scene("flat_plate")
    s = Simulator(sc, level_settings("fast", dt=4e-3))
    p = np.array([0.0, 0.0, s.touch_height(R0) + 1.0])
    s.reset(p, R0)
    tab = s.bristles._tab
    tab.outside[7] = 1  # as the lookup counts a step that ended beyond the table
    with pytest.warns(TableRangeWarning, match=r"bristle 7 left its tip table.*<= 150 deg"):
        s.rollout(np.zeros(3), np.zeros(3), 2)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error", TableRangeWarning)
        s.rollout(np.zeros(3), np.zeros(3), 2)  # once per reset
    info = s.bristles.solver_info()
    assert info["table_outside"] == 1 and info["table_fallbacks"] >= 0
    s.reset(p, R0)
    assert s.bristles.solver_info()["table_outside"] == 0
