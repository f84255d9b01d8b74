"""The reduced bristle model (``engine/prb.py``, the ``fast`` level) against references others
wrote down: the Timoshenko cantilever (small deflection), the geometrically exact rod pressed
onto a plate (``validation.rod``, what ``validate buckling`` checks the full chain against) and
the full chain itself for the side a pressed brush buckles to; and its own consistency: a
rollout is the same steps as ``Simulator.step``, a free bristle's shortcut is Newton's answer.
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np
import pytest

from brush_env.calibration import DRAG_AT, FULL_BODIES, FULL_DT, fit, press_reduced
from brush_env.engine import SimSettings, Simulator, load_brush, load_scene
from brush_env.engine import prb_calibration as pc
from brush_env.engine.fidelity import level_settings
from brush_env.motion import R0
from brush_env.validation.buckling import BucklingCase
from brush_env.validation.references import timoshenko_cantilever_tip
from brush_env.validation.rod import buckled_bristle


@pytest.fixture
def user_cache(tmp_path, monkeypatch):
    """Calibrations made by a test go to a fresh user cache."""
    monkeypatch.setenv("BRUSH_ENV_CACHE", str(tmp_path))
    monkeypatch.setattr(pc, "_memory", {})
    return tmp_path


def _one_bristle(lean_deg=1.0, length=10.0, width=1.3, tip="free"):
    case = BucklingCase(tip=tip, lean_deg=lean_deg, length=length, width=width)
    return case, case.scene()


@pytest.mark.parametrize("model", ["prb", "table"])
@pytest.mark.parametrize("side", ["thin", "wide"])
def test_small_tip_load_deflects_as_the_timoshenko_cantilever(side, model):
    """A 1 mN side load on the tip of the default outer bristle (calibration shipped): the tip
    moves as the Timoshenko cantilever's (bending + shear), within 3 % (the fit's own error on
    the press is ~2 %; the wide side is matched by construction of its scale) -- the chain's
    Newton and the tabulated law (``engine/tip_table.py``; its grid of constant chord left this
    load's deflection 21 % short)."""
    sc = load_scene("flat_plate")
    sim = Simulator(sc.brush, SimSettings(model=model, bodies_per_bristle=2, gravity=(0, 0, 0)))
    sim.reset(np.zeros(3), np.eye(3))
    b = 20  # an outer bristle
    br = sc.brush.bristles[b]
    frame = sim.model.root_R[b]  # columns: axis, width, thickness (TCP frame = world here)
    d = frame[:, 2] if side == "thin" else frame[:, 1]
    P = 1e-3
    f = np.zeros((sim.model.n_bristles, 3))
    f[b] = P * d
    rest = sim.tip_positions()[b].copy()
    sim.set_tip_forces(f)
    sim.solve_static(increments=1)
    moved = float((sim.tip_positions()[b] - rest) @ d)
    sec, mat = br.section, br.material
    inertia = sec.I_y if side == "thin" else sec.I_z
    ref = timoshenko_cantilever_tip(
        P, br.length, mat.E, mat.G, inertia, sec.area, sec.shear_coeff(mat.nu)
    )["v"]
    assert moved == pytest.approx(ref, rel=0.03)


@functools.cache
def _fit_once(lean):
    """``fit`` of the outer bristle type at ``lean`` [deg] (the sliding and the sticking case
    share it: one fit per lean and test process, ~45 s each)."""
    case, _ = _one_bristle(lean_deg=lean, tip="free")
    return fit(case.scene().brush.bristles[0], case.scene().brush.effective_lean)


def _press_against_rod(lean, tip, press):
    """(reduced model's plate force, the rod's) [N] at ``press`` [mm] for the outer bristle at
    ``lean`` [deg], after its type calibrates itself."""
    case, _ = _one_bristle(lean_deg=lean, tip=tip)
    eff = case.scene().brush.effective_lean
    rec = _fit_once(lean)
    got = press_reduced(case, rec["constants"], press)[:, 0]
    ref = buckled_bristle(
        press,
        length=case.length,
        width=case.width,
        thickness=case.thickness,
        E=case.E,
        nu=case.nu,
        lean_deg=math.degrees(eff),
        tip=tip,
        radius=case.radius,
    )["force_N"]
    return got, np.asarray(ref), case


@pytest.mark.slow
@pytest.mark.parametrize("lean", [0.0, 1.0, 3.0])
@pytest.mark.parametrize("tip", ["free", "pinned"])
def test_pressed_bristle_force_is_the_rods(user_cache, lean, tip):
    """Issue 29: one bristle pressed at leans 0, 1 and 3 deg with a sliding and a sticking tip:
    the plate force within 5 % of the rod's (Reissner, validation.rod), after the bristle type
    calibrates itself -- 1-4 mm for the sliding tip, 1-3 mm for the sticking one (4 mm: the
    next test); the straight bristle (lean 0) buckles -- its force stays on the rod's
    post-buckled plateau, an order of magnitude below the straight column's EA delta / L."""
    press = (1.0, 2.0, 3.0, 4.0) if tip == "free" else (1.0, 2.0, 3.0)
    got, ref, case = _press_against_rod(lean, tip, press)
    np.testing.assert_allclose(got, ref, rtol=0.05)
    if lean == 0.0:
        # a column that stayed straight would carry E A delta / L (0.73 N at 1 mm); buckled, the
        # rod's plateau is ~10x lower (0.016 N sliding, 0.078 N sticking)
        axial = case.E * case.width * case.thickness * 1.0 / case.length  # [N] at 1 mm, straight
        assert got[0] < 0.2 * axial


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True,
    reason="issue 29, open: the two-joint chain's sticking-tip plateau rises too fast past "
    "3.5 mm (more than 5 % above the rod at 4 mm; the fit runs to 3.5 mm)",
)
def test_sticking_tip_at_4_mm_is_the_rods(user_cache):
    got, ref, _ = _press_against_rod(1.0, "pinned", (4.0,))
    np.testing.assert_allclose(got, ref, rtol=0.05)


def test_fit_error_is_stored_with_the_shipped_calibration():
    """The shipped calibrations carry their fit errors (the calibration prints and stores them),
    and every one is within the 5 % the press acceptance asks."""
    import json

    data = json.loads(pc.SHIPPED.read_text())
    assert data, "no shipped calibration"
    for rec in data.values():
        n = len(rec["press_mm"])
        assert max(abs(e) for e in rec["force_error_free"]) < 0.05
        assert len(rec["force_error_pinned"]) == n
        assert rec["max_abs_force_error"] < 0.1  # the sticking tip at 4 mm: docs/model.md
        assert len(rec["constants"]) == 9  # ... the wide side's scale, the twist, c3w
        assert len(rec["drag_error_wide"]) == len(rec["drag_error_thin"]) == 2 * len(DRAG_AT)
        assert len(rec["sliding_normal_error"]) == 2


def test_shipped_calibrations_are_exactly_the_configs_brushes_types():
    """``calibrate --all --ship`` leaves no record nothing looks up (an older VERSION's) and
    misses none of the brushes in configs/brushes."""
    import json

    from brush_env.engine import configs_dir

    used = set()
    for path in (configs_dir() / "brushes").glob("*.toml"):
        used.update(pc.bristle_types(load_brush(path.stem)))
    assert set(json.loads(pc.SHIPPED.read_text())) == used


def test_prune_keeps_only_the_named_keys(tmp_path):
    import json

    path = tmp_path / "cal.json"
    path.write_text(json.dumps({"a": {"x": 1}, "b": {"x": 2}, "c": {"x": 3}}))
    assert pc.prune({"a", "c", "z"}, path) == 1
    assert json.loads(path.read_text()) == {"a": {"x": 1}, "c": {"x": 3}}
    assert list(tmp_path.iterdir()) == [path]  # no temporary file left


@pytest.mark.slow
def test_shipped_calibration_is_reproduced(user_cache):
    """A fresh calibration of the default brush's inner bristle matches the shipped one (same
    constants within the fit's tolerance: the same forces within 0.5 %)."""
    sc = load_scene("flat_plate")
    (key, (br, lean)), *_ = pc.bristle_types(sc.brush).items()
    shipped = pc.lookup(key)
    rec = fit(br, lean)
    case = BucklingCase(
        length=br.length, width=br.section.width, thickness=br.section.thickness, tip="pinned"
    )
    a = press_reduced(case, shipped["constants"])[:, 0]
    b = press_reduced(case, rec["constants"])[:, 0]
    np.testing.assert_allclose(a, b, rtol=5e-3)


def _mj_press(level: str, dt: float):
    """The paper's press (3 mm, minimum jerk, 0.5 s) of the default brush from touching."""
    sim = Simulator(load_scene("flat_plate"), level_settings(level, dt=dt))
    z = sim.touch_height(R0)
    sim.reset(np.array([0.0, 0.0, z]), R0)
    n = int(round(0.5 / dt))
    for k in range(1, n + 1):
        s = k / n
        out = sim.step(np.array([0.0, 0.0, z - 3.0 * (10 * s**3 - 15 * s**4 + 6 * s**5)]), R0)
    return out


@pytest.mark.slow
def test_pressed_brush_buckles_to_the_full_chains_side():
    """Every bristle of the default brush pressed 3 mm buckles to the side the full chain's do
    (the sign of its tip's friction across the lean), and the TCP force agrees (normal within
    3 %, the side force within 15 %).  A faster level on another buckling branch is a wrong
    answer, not a larger error (the brief)."""
    fast = _mj_press("reduced", 4e-3)
    full = _mj_press("balanced", 1e-3)
    np.testing.assert_array_equal(
        np.sign(fast.tip_tangential_force[:, 1]), np.sign(full.tip_tangential_force[:, 1])
    )
    assert fast.tcp_force[2] == pytest.approx(full.tcp_force[2], rel=0.03)
    assert fast.tcp_force[1] == pytest.approx(full.tcp_force[1], rel=0.15)


def test_rollout_is_the_same_steps_as_step():
    """``Simulator.rollout`` (one compiled call) and ``Simulator.step`` on the same poses give the
    same tips and forces (to round-off: the pose products are formed in numba vs numpy)."""
    sc = load_scene("flat_plate")
    a = Simulator(sc, level_settings("reduced", dt=4e-3))
    b = Simulator(sc, level_settings("reduced", dt=4e-3))
    z = a.touch_height(R0) + 0.3
    for s in (a, b):
        s.reset(np.array([0.0, 0.0, z]), R0)
    v, w = np.array([15.0, -5.0, -12.0]), np.array([0.0, 0.0, 0.3])
    p, R = np.array([0.0, 0.0, z]), R0.copy()
    from brush_env.engine.rotation import expmap

    dR = expmap(w * 4e-3)
    for _ in range(6):
        ro = a.rollout(v, w, 10)
        for _ in range(10):
            p, R = p + v * 4e-3, dR @ R
            out = b.step(p, R)
    assert ro.done == 10 and ro.stop is None
    assert out.tip_in_contact.sum() > 10  # pressed: Newton, friction and tip-tip at work
    np.testing.assert_allclose(ro.last.tip_pos, out.tip_pos, atol=1e-7)
    np.testing.assert_allclose(ro.last.tip_normal_force, out.tip_normal_force, atol=1e-7)
    np.testing.assert_allclose(ro.last.tcp_force, out.tcp_force, atol=1e-6)
    assert ro.last.time == pytest.approx(out.time, abs=1e-12)


def test_rollout_is_deterministic():
    """Same start and twist: the same result bit for bit."""
    sc = load_scene("flat_plate")
    outs = []
    for _ in range(2):
        s = Simulator(sc, level_settings("reduced", dt=4e-3))
        s.reset(np.array([0.0, 0.0, s.touch_height(R0) + 0.2]), R0)
        for _ in range(4):
            ro = s.rollout(np.array([20.0, 0.0, -15.0]), np.zeros(3), 10)
        outs.append(ro.last)
    assert np.array_equal(outs[0].tip_pos, outs[1].tip_pos)
    assert np.array_equal(outs[0].tcp_force, outs[1].tcp_force)


def test_free_bristle_shortcut_is_newtons_answer():
    """A bristle that touches nothing takes a shortcut (its joints relax, one contact
    evaluation); a dead load of 1e-12 N sends it through Newton instead: the same tip."""
    sc = dataclasses.replace(load_scene("flat_plate"), surfaces=())
    res = []
    for load in (0.0, 1e-12):
        s = Simulator(sc, level_settings("reduced", dt=4e-3))
        s.reset(np.zeros(3), R0)
        s.set_state(s.get_state())
        st = s.get_state()
        st.q[:, 0] += 0.2  # bent: it springs back over the steps
        s.set_state(st)
        f = np.zeros((s.model.n_bristles, 3))
        f[:, 0] = load
        s.set_tip_forces(f)
        for k in range(5):
            out = s.step(np.array([0.1 * k, 0.0, 0.0]), R0)
        res.append(out.tip_pos)
    np.testing.assert_allclose(res[0], res[1], atol=1e-6)


def test_uncalibrated_type_warns_once_naming_the_bristle(user_cache):
    """A bristle type with no calibration is never used silently: one warning naming its
    section, length and the command that fits it."""
    case, scene = _one_bristle(lean_deg=2.5, length=8.5, width=1.1)
    with pytest.warns(RuntimeWarning, match=r"no calibration for a rect 1\.1 x 0\.8 mm.*calibrate"):
        Simulator(scene, SimSettings(model="prb", bodies_per_bristle=2))


def _chain(q, geo):
    from brush_env.engine import prb_kernels as K

    x, J = np.zeros(3), np.zeros((3, K.NQ))
    cs, orders = np.zeros((K.NQ, 2)), np.zeros(K.NQ, np.int64)
    K.kinematics(np.asarray(q, float), geo, x, J, cs, orders, np.zeros(3), np.zeros(3))
    return x, J, cs, orders


def test_chain_jacobian_and_geometric_stiffness_are_the_kinematics_derivatives():
    """J = dx/dq and G = d(J^T F)/dq (fixed F) of the five-coordinate chain (bends and twist)
    against central differences of the tip position, at random bent and twisted states."""
    from brush_env.engine import prb_kernels as K

    rng = np.random.default_rng(7)
    geo = np.array([0.6, 2.9, 5.5])
    h = 1e-6
    for _ in range(5):
        q = rng.uniform(-0.8, 0.8, K.NQ)
        F = rng.normal(size=3)
        x, J, cs, orders = _chain(q, geo)
        G = np.zeros((K.NQ, K.NQ))
        K.geometric_stiffness(geo, F, G, cs, orders, np.zeros(3), np.zeros(3))
        for i in range(K.NQ):
            dq = np.zeros(K.NQ)
            dq[i] = h
            xp, Jp, *_ = _chain(q + dq, geo)
            xm, Jm, *_ = _chain(q - dq, geo)
            np.testing.assert_allclose(J[:, i], (xp - xm) / (2 * h), atol=1e-7)
            np.testing.assert_allclose(G[:, i], (Jp.T @ F - Jm.T @ F) / (2 * h), atol=1e-6)
        np.testing.assert_allclose(G, G.T, atol=1e-12)  # a Hessian


def test_twist_turns_the_bent_chain_about_its_axis():
    """The twist coordinate is a rigid turn of the whole chain beyond joint 1 about the
    bristle's axis: tip(q, t) = Rx(t) tip(q, 0); a straight bristle's tip does not move."""

    geo = np.array([0.6, 2.9, 5.5])
    q = np.array([0.3, -0.2, -0.5, 0.1, 0.0])
    x0, *_ = _chain(q, geo)
    for t in (0.25, -1.1):
        c, s = math.cos(t), math.sin(t)
        Rx = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        x, *_ = _chain(np.r_[q[:4], t], geo)
        np.testing.assert_allclose(x, Rx @ x0, atol=1e-12)
        xs, *_ = _chain(np.r_[0.0, 0.0, 0.0, 0.0, t], geo)
        np.testing.assert_allclose(xs, [geo.sum(), 0.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("group", ["inner", "outer"])
@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.0, 1.0)], ids=["wide", "thin"])
def test_pressed_bristle_dragged_slides_as_the_full_chain(group, direction):
    """Each default bristle type pressed a quarter of its length and dragged toward its wide and
    its thin side: the sliding normal and tangential tip forces within 5 % of the converged chain
    (12 mid-element bodies at 0.5 ms, within 0.1 % of 24).  Toward the wide side the full chain
    turns its bend over by twisting (with its torsion 100x stiffer the inner strip carries 3x the
    normal force): the reduced chain's twist joint does the same."""
    from brush_env.bench import drag as D
    from brush_env.engine import load_brush

    no_g = (0.0, 0.0, 0.0)
    types = pc.bristle_types(load_brush("default")).values()
    br, lean = next((b, ln) for b, ln in types if b.group == group)
    full = Simulator(D.bristle_scene(br, lean, FULL_BODIES), SimSettings(dt=FULL_DT, gravity=no_g))
    red = Simulator(D.bristle_scene(br, lean, 2), SimSettings(dt=4e-3, model="prb", gravity=no_g))
    ref = D.drag_bristle(full, br.length, direction)
    got = D.drag_bristle(red, br.length, direction)
    assert got["fn_N"] == pytest.approx(ref["fn_N"], rel=0.05)
    assert got["ft_N"] == pytest.approx(ref["ft_N"], rel=0.05)


@pytest.mark.parametrize("group", ["inner", "outer"])
def test_stuck_tip_dragged_loads_as_the_full_chain(group):
    """Each default bristle type pressed a quarter of its length with its tip stuck (mu = 5) and
    its root dragged toward both sides (``calibration.drag_targets``): the tip's normal and
    tangential force up to 0.4 L of travel within 10 % of the converged chain's (12 bodies), of
    the side's first normal force.  Before the fit had drag targets (2026-11-27) the reduced
    inner type toward its wide side was +15 % at 0.3 L and +28 % at 0.4 L: it kept its normal
    force while the full chain lays over, and let go 0.75 mm late; with the drag targets and a
    linear wide-side spring still +18 % at 0.4 L (docs/model.md)."""
    from brush_env.calibration import drag_errors, drag_targets
    from brush_env.engine import load_brush

    no_g = (0.0, 0.0, 0.0)
    types = pc.bristle_types(load_brush("default")).values()
    br, lean = next((b, ln) for b, ln in types if b.group == group)
    ref = drag_targets(br, lean, SimSettings(dt=FULL_DT, gravity=no_g), FULL_BODIES)
    got = drag_targets(br, lean, SimSettings(dt=4e-3, model="prb", gravity=no_g), 2)
    err = drag_errors(got, ref)
    m = len(DRAG_AT)
    upto = list(range(m))
    for side in range(2):  # wide, thin: normal then tangential samples
        for part in range(2):
            e = err[2 * m * side + m * part + np.array(upto)]
            assert np.all(np.abs(e) < 0.10), (side, part, e)


@pytest.mark.parametrize("model", ["prb", "dfm"])
def test_tip_sliding_along_a_groove_rubs_with_mu_d_times_the_walls_resultant(model):
    """A default inner bristle pressed into a 90° V-groove (two planes) and dragged along it: the
    friction presses against the resultant R of the two walls' normal forces (design.md,
    ``contact._surface_load``), so once the tip slides the TCP force along the groove is
    mu_d |R| -- not mu_d (Fn_1 + Fn_2), 1.41x as much, which the reduced model's friction took
    before 2026-11-26 -- in both models.  Quasi-static, no gravity: the TCP force is the tip's
    load, R its part across the groove."""
    from brush_env.bench import drag as D
    from brush_env.engine import load_brush
    from brush_env.engine.scene import ContactParams, Plane
    from brush_env.validation.buckling import R_DOWN

    types = pc.bristle_types(load_brush("default")).values()
    br, lean = next((b, ln) for b, ln in types if b.group == "inner")
    s = math.sqrt(0.5)
    bodies, dt = (2, 4e-3) if model == "prb" else (8, 5e-4)
    scene = D.bristle_scene(br, lean, bodies)
    settings = SimSettings(dt=dt, model=model, gravity=(0.0, 0.0, 0.0))
    top = 30.0
    probe = Simulator(dataclasses.replace(scene, surfaces=()), settings)
    probe.reset(np.array([0.0, 0.0, top]), R_DOWN)
    tip0 = probe.tip_positions()[0]
    # the groove's floor line under the tip, along y; the tip sphere touches both walls with its
    # centre r / cos 45° above it
    x0 = float(tip0[0])
    groove = (Plane((x0, 0.0, 0.0), (s, 0.0, s)), Plane((x0, 0.0, 0.0), (-s, 0.0, s)))
    sim = Simulator(dataclasses.replace(scene, surfaces=groove), settings)
    z_touch = top - (tip0[2] - br.tip_radius / s)
    sim.reset(np.array([0.0, 0.0, z_touch]), R_DOWN)
    press = 0.2 * br.length
    t_press, t_hold, speed, travel = 0.25, 0.05, 10.0, 8.0
    n = int(round((t_press + t_hold + travel / speed) / dt))
    F = []
    for k in range(1, n + 1):
        t = k * dt
        y = max(t - t_press - t_hold, 0.0) * speed
        z = z_touch - press * D._min_jerk(t / t_press)
        out = sim.step(np.array([0.0, y, z]), R_DOWN)
        if y > travel - 2.0:
            assert out.tip_sliding[0]
            F.append(out.tcp_force.copy())
    F = np.mean(F, axis=0)
    across = math.hypot(F[0], F[2])
    assert across > 0.005  # pressed into both walls
    assert abs(F[1]) / across == pytest.approx(ContactParams().mu_d, rel=0.02)
