"""Contact (eq 6), stick-slip friction (eq 7-10, Table 1) and tip-tip contact (Table 3).

References are the paper's laws and tables with closed-form consequences: the static penetration
(W/k)^(1/m1), the friction limits mu_s Fn / mu_d Fn, the bound Delta_max, energy dissipation.
"""

from __future__ import annotations

import dataclasses
import re
import warnings

import numpy as np
import pytest

from brush_env.engine import (
    BristleConfig,
    BrushConfig,
    ConfigError,
    Material,
    PenetrationWarning,
    Plane,
    Scene,
    Section,
    SimSettings,
    Simulator,
    load_brush,
    load_scene,
)
from brush_env.engine import contact as ct
from brush_env.engine import records as rec
from brush_env.engine.scene import ContactParams
from brush_env.engine.simulator import PENETRATION_WARN_FRACTION

R0 = np.diag([1.0, -1.0, -1.0])  # TCP z down: bristles hang toward the plate z = 0
SILICONE = Material(name="silicone", E=7.0, nu=0.48, density=1.15e-9, damping_ratio=0.1)
CP = ContactParams()  # the scene default: the paper's Tables 2-3


def one_bristle(
    length=10.0, bodies=6, material=SILICONE, section=None, lean=0.0, tip=0.44, root=(0.0, 0.0, 0.0)
):
    br = BristleConfig(
        root=root,
        axis=(0, 0, 1),
        width_dir=(1, 0, 0),
        length=length,
        section=section or Section.rect(1.8, 0.8),
        material=material,
        bodies=bodies,
        tip_radius=tip,
    )
    return BrushConfig(
        name="one", head_offset=(0, 0, 0), head_rpy=(0, 0, 0), bristles=(br,), lean=np.radians(lean)
    )


def plate_scene(brush, tip_tip=False):
    return Scene(brush, (Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)),), tip_tip=tip_tip)


def test_bad_contact_key_names_key_value_and_range(tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text('brush = "tiny"\n[contact]\nmu_s = -0.1\n')
    with pytest.raises(ConfigError, match=r"contact.mu_s = -0.1 is out of range: must be >= 0"):
        load_scene(scene)
    scene.write_text('brush = "tiny"\n[contact]\nmus = 0.5\n')
    with pytest.raises(ConfigError, match=r"unknown key 'mus'; did you mean mu_s"):
        load_scene(scene)


@pytest.mark.parametrize(
    "W, contact", [(0.01, ""), (0.1, ""), (0.5, ""), (0.1, "k = 250.0\nm1 = 1.5\n")]
)
def test_sphere_under_load_settles_at_closed_form_penetration(W, contact, tmp_path):
    """Static: a vertical bristle standing on the plate under a tip load W: the plate carries
    W - (EA/L) delta = k delta^m1 (eq 6).  k and m1 come from the scene's [contact] table (the
    paper's Table 2 when the table is empty), so a changed key reaches the kernels."""
    brush = one_bristle()
    toml = tmp_path / "plate.toml"
    toml.write_text('tip_tip = false\n[[surface]]\nkind = "plane"\n[contact]\n' + contact)
    scene = load_scene(toml, brush=brush)
    k, m1 = scene.contact.k, scene.contact.m1
    sim = Simulator(scene, SimSettings(gravity=(0, 0, 0)))
    sim.reset(np.array([0.0, 0.0, 10.0 + 0.44]), R0)  # sphere exactly touching
    sim.set_tip_forces(np.array([[0.0, 0.0, -W]]))
    out = sim.solve_static(increments=4)
    sec = brush.bristles[0].section
    ka = SILICONE.E * sec.area / 10.0  # the tip sinks by delta and stretches the bristle by delta
    lo, hi = 0.0, (W / k) ** (1.0 / m1)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if k * mid**m1 + ka * mid < W else (lo, mid)
    delta = 0.5 * (lo + hi)
    assert out.tip_penetration[0] == pytest.approx(delta, rel=1e-6)
    assert out.tip_normal_force[0] == pytest.approx(k * delta**m1, rel=1e-6)
    # the robot's reaction is minus the net external load: -(-W + Fn) = +(EA/L) delta (up)
    assert out.tcp_force[2] == pytest.approx(ka * delta, rel=1e-5)


def test_no_tensile_normal_force_during_separation():
    """A pressed bristle pulled off the plate fast: Fn >= 0 always (no adhesion), then 0."""
    brush = one_bristle(lean=1.0)
    sim = Simulator(plate_scene(brush), SimSettings(dt=1e-3, gravity=(0, 0, 0)))
    z0 = 10.0 + 0.44
    sim.reset(np.array([0.0, 0.0, z0]), R0)
    fn = []
    for k in range(1, 101):  # press 1 mm in 0.1 s
        fn.append(sim.step(np.array([0.0, 0.0, z0 - 0.01 * k]), R0).tip_normal_force[0])
    assert max(fn) > 0.01
    for k in range(1, 41):  # lift at 100 mm/s
        out = sim.step(np.array([0.0, 0.0, z0 - 1.0 + 0.1 * k]), R0)
        fn.append(out.tip_normal_force[0])
    assert min(fn) >= 0.0
    assert fn[-1] == 0.0 and not out.tip_in_contact[0]


def _drag(sim, z, xs, dt):
    """Drive the TCP through the x positions at height z; return per-step outputs."""
    outs = []
    for x in xs:
        outs.append(sim.step(np.array([x, 0.0, z]), R0))
    return outs


def test_stick_then_slide_at_the_friction_coefficients_and_reversal():
    """A short bristle held on the plate by a dead load, its base dragged slowly: the tip sticks
    until |Ft| reaches mu_s Fn (at |Delta| = Delta_max), then slides at mu_d Fn; |Delta| never
    exceeds Delta_max; reversing the drag flips the friction force.

    While sticking the tip creeps at v < v_base, and the paper's stiction state adds the smoothed
    sliding term mu_d Fn s(v / v_d) (slope 1.5 / v_d) to the stiction force: the peak lies in
    [mu_s (1 - beta), mu_s + 1.5 mu_d v_base / v_d] -> [mu_s, mu_s + 0.04] at v_base = 0.05 mm/s.
    """
    brush = one_bristle(length=3.0)
    dt = 2e-3
    sim = Simulator(plate_scene(brush), SimSettings(dt=dt, gravity=(0, 0, 0)))
    z = 3.0 + 0.44
    sim.reset(np.array([0.0, 0.0, z]), R0)
    sim.set_tip_forces(np.array([[0.0, 0.0, -0.05]]))
    for _ in range(50):
        sim.step(np.array([0.0, 0.0, z]), R0)
    x = 0.0
    ratios, deltas, sliding = [], [], []
    for v_base, n in ((0.05, 4000), (4.0, 500), (-4.0, 1000)):  # slow drag, fast drag, reversal
        for _ in range(n):
            x += v_base * dt
            out = sim.step(np.array([x, 0.0, z]), R0)
            ft = out.tip_tangential_force[0]
            ratios.append(np.sign(ft[0]) * np.linalg.norm(ft) / out.tip_normal_force[0])
            deltas.append(np.linalg.norm(sim.state.tip_state[0]["delta"]))
            sliding.append(bool(out.tip_sliding[0]))
    r = np.abs(np.array(ratios))
    slow = r[:4000]
    mu_s, mu_d = CP.mu_s, CP.mu_d
    assert mu_s <= slow.max() <= mu_s + 1.5 * mu_d * 0.05 / CP.v_d + 1e-3
    assert not any(sliding[:1000])  # sticks first
    assert max(deltas) <= CP.delta_max + 1e-12
    fast = np.array(ratios[4000 + 300 : 4500])
    assert np.allclose(fast, -mu_d, atol=1e-6) and all(sliding[4300:4500])  # opposes +x slip
    back = np.array(ratios[4500 + 600 :])
    assert np.allclose(back, mu_d, atol=1e-6)  # sign flipped after the reversal


def test_two_facing_bristles_push_apart_with_table3_law_and_no_friction():
    """Two bristles loaded toward each other: the tip spheres touch; the contact force follows
    F = k delta^m1 along the line of centres (Table 3) and has no tangential part."""
    a = one_bristle(root=(-0.6, 0.0, 0.0), tip=0.44).bristles[0]
    b = dataclasses.replace(a, root=(0.6, 0.0, 0.0))
    brush = BrushConfig(name="pair", head_offset=(0, 0, 0), head_rpy=(0, 0, 0), bristles=(a, b))
    sim = Simulator(Scene(brush, (), tip_tip=True), SimSettings(dt=1e-3, gravity=(0, 0, 0)))
    assert sim.n_tip_pairs == 1
    sim.reset(np.array([0.0, 0.0, 30.0]), R0)
    P = 0.02  # N, pushes the tips together along x (world x = TCP x)
    out = None
    for k in range(1, 3001):  # ramp the loads over 0.5 s (no tunnelling), then settle
        s = min(k / 500.0, 1.0)
        sim.set_tip_forces(s * np.array([[P, 0.0, 0.0], [-P, 0.0, 0.0]]))
        out = sim.step(np.array([0.0, 0.0, 30.0]), R0)
    tips = out.tip_pos
    d = tips[0] - tips[1]
    dist = np.linalg.norm(d)
    delta = 0.88 - dist
    assert delta > 0
    ftt = out.extra["tip_tip_force"]
    # rel 1e-3: the pair is still creeping toward equilibrium (1e-4 after 3 s) and bristle 0 sees
    # bristle 1's tip of the previous step (one Gauss-Seidel sweep per step)
    assert ftt[0] == pytest.approx(100.0 * delta**1.3, rel=1e-3)
    assert ftt[1] == pytest.approx(ftt[0], rel=1e-3)
    # head-on and frictionless: the line of centres stays along x (no sideways force appears)
    assert abs(d[1]) < 1e-9 and abs(d[2]) < 1e-5 and d[0] < 0  # z: Gauss-Seidel asymmetry
    assert np.all(out.tip_tangential_force == 0.0)
    # statics of bristle a along x: load P = contact force + its bending reaction (> 0)
    assert 0.0 < ftt[0] < P


def _energy(sim):
    """Kinetic + elastic (1/2 e^T K e per element) energy of the bristles [N mm]."""
    st, m = sim.state, sim.model
    ke = 0.5 * np.sum(m.bp["mass"] * np.sum(st.vel**2, axis=1))
    for i in range(m.n_bodies):
        om_b = st.rot[i].T @ st.omg[i]
        ke += 0.5 * np.sum(m.bp[i]["J"] * om_b**2)
    from brush_env.validation.modal import element_strains

    e = element_strains(sim)
    pe = 0.5 * np.einsum("ni,nij,nj->", e, m.K, e)
    # penalty contact potential of eq 6's elastic part: k delta^(m1+1) / (m1 + 1)
    pen = st.tip_state["pen"] * (st.tip_state["fn"] > 0)
    pc = np.sum(CP.k * pen ** (CP.m1 + 1.0) / (CP.m1 + 1.0))
    return ke + pe + pc


def test_bristle_dropped_on_plate_loses_energy_and_never_gains_it():
    brush = one_bristle(lean=3.0)
    dt = 1e-3
    sim = Simulator(plate_scene(brush), SimSettings(dt=dt, gravity=(0, 0, 0)))
    z0 = 10.0 + 0.44 + 0.2
    sim.reset(np.array([0.0, 0.0, z0]), R0)
    v = 20.0  # mm/s down; the base stops 1.5 mm below the touch height
    z = z0
    for _ in range(int(round(1.7 / v / dt))):
        z -= v * dt
        sim.step(np.array([0.0, 0.0, z]), R0)
    e = [_energy(sim)]
    touched = False
    for _ in range(1500):  # base held still: no work in; contact, friction and damping dissipate
        out = sim.step(np.array([0.0, 0.0, z]), R0)
        touched |= bool(out.tip_in_contact[0])
        e.append(_energy(sim))
    e = np.array(e)
    assert touched
    assert np.all(np.diff(e) <= 1e-9 * e[0] + 1e-15)
    assert e[-1] < e[0]


HARD_CASES = {
    "press_6mm": dict(press=6.0, stroke=0.0, speed=0.0),
    "reversal_50": dict(press=3.0, stroke=3.0, speed=50.0, reverse=True),
    "reversal_200": dict(press=3.0, stroke=3.0, speed=200.0, reverse=True),
    "stroke_200": dict(press=3.0, stroke=10.0, speed=200.0),
    "stiff_contact_10x": dict(press=3.0, stroke=3.0, speed=20.0, kscale=10.0),
    "material_7GPa": dict(press=0.05, stroke=0.5, speed=20.0, gpa=True),
}


@pytest.mark.parametrize("model", ["dfm", "prb", "table"])
@pytest.mark.parametrize("name", sorted(HARD_CASES))
def test_hard_cases_stay_finite_and_bounded(name, model):
    """Hard cases on the tiny brush, for the full chain, the reduced model and its tabulated tip
    law (the level ``fast``): finite outputs, bounded penetration, wrench in an envelope (|F|
    below the sum of what the tips can push: n_tips * k * (0.1 mm)^m1 = 5 N per tip).  (The
    reduced model of the 7 GPa bristle has no calibration and says so: it runs on the default
    constants, and the table builds its own tables from them, ~50 s.)"""
    case = HARD_CASES[name]
    brush = load_brush("tiny")
    if case.get("gpa"):
        brush = brush.with_material(dataclasses.replace(SILICONE, E=7000.0, name="7GPa"))
    scene = dataclasses.replace(load_scene("flat_plate", brush=brush), tip_tip=True)
    dt = 1e-3
    if "kscale" in case:  # the scene's [contact] stiffnesses (Tables 2-3) scaled
        c = scene.contact
        scene = dataclasses.replace(
            scene,
            contact=dataclasses.replace(c, k=c.k * case["kscale"], k_tt=c.k_tt * case["kscale"]),
        )
    with warnings.catch_warnings():
        # the reduced model's "no calibration" warning for the 7 GPa bristle (its own test:
        # tests/engine/test_prb.py)
        warnings.simplefilter("ignore", RuntimeWarning)
        sim = Simulator(scene, SimSettings(dt=dt, model=model))
    z0 = brush.max_length + 0.44
    sim.reset(np.array([0.0, 0.0, z0]), R0)
    n_press = 300
    poses = [
        np.array([0.0, 0.0, z0 - case["press"] * (3 * s * s - 2 * s**3)])
        for s in np.arange(1, n_press + 1) / n_press
    ]
    if case["speed"]:
        n = int(case["stroke"] / case["speed"] / dt)
        x = np.cumsum(np.full(n, case["speed"] * dt))
        if case.get("reverse"):
            x = np.r_[x, x[-1] - x]  # instant reversal
        poses += [np.array([xi, 0.0, z0 - case["press"]]) for xi in x]
    pen_max = 0.0
    fmax = 0.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PenetrationWarning)
        for p in poses:
            out = sim.step(p, R0)
            assert np.all(np.isfinite(out.tcp_force)) and np.all(np.isfinite(out.tip_pos))
            pen_max = max(pen_max, out.tip_penetration.max())
            fmax = max(fmax, np.linalg.norm(out.tcp_force))
    assert pen_max < 0.1  # mm: a tenth of the tip sphere... far above the silicone's ~5 um
    # a penetration beyond 10 % of the tip radius is announced, once (issue 15)
    deep = pen_max > PENETRATION_WARN_FRACTION * sim.model.tip_radius.min()
    assert len([w for w in caught if w.category is PenetrationWarning]) == int(deep)
    assert fmax < brush.n_bristles * 100.0 * 0.1**1.3 * 2.0


#: Paper §3: k, c and the m_i are "set to ensure a penetration lower than 5 um".  The paper's brush
#: layout (tuft count, lengths) is not printed, so our default brush's per-tip forces can differ
#: from the paper's; we allow a factor 2 on the criterion (a tip force 2^1.3 = 2.5x the paper's
#: design point), and call the criterion broken when it is exceeded 20x.
PAPER_PENETRATION_UM = 5.0


@pytest.mark.parametrize("E, must_meet", [(7.0, True), (7000.0, False)])
def test_paper_penetration_criterion_7MPa_meets_7GPa_does_not(E, must_meet):
    """A 3 mm press of the default brush, then a hold: the silicone (7 MPa) keeps the held tips
    within 2x the paper's 5 um; the printed 7 GPa sinks them by more than 20x (docs/model.md)."""
    brush = load_brush("default")
    brush = brush.with_material(dataclasses.replace(brush.bristles[0].material, E=E, name="m"))
    sim = Simulator(load_scene("flat_plate", brush=brush), SimSettings(dt=1e-3))
    z0 = brush.max_length + 0.44
    sim.reset(np.array([0.0, 0.0, z0]), R0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", PenetrationWarning)
        for k in range(1, 601):  # 0.4 s minimum-jerk-like press, 0.2 s hold
            s = min(k / 400.0, 1.0)
            out = sim.step(np.array([0.0, 0.0, z0 - 3.0 * (3 * s * s - 2 * s**3)]), R0)
    pen_um = out.tip_penetration.max() * 1e3
    warned = [str(w.message) for w in caught if w.category is PenetrationWarning]
    if must_meet:
        assert pen_um <= 2.0 * PAPER_PENETRATION_UM
        assert not warned
    else:
        assert pen_um > 20.0 * PAPER_PENETRATION_UM
        # the 7 GPa press leaves the penalty law's range: one warning naming bristle and depth
        assert len(warned) == 1 and re.search(r"tip of bristle \d+ penetrates [\d.]+ um", warned[0])


def test_a_deep_sliding_press_closes_no_newton_limit_cycle():
    """The 7 GPa press above at t = 0.248 s, its state saved from a run whose arithmetic differed in
    the last bits (FMA, docs/benchmarks.md, session 33): bristle 38's tip sinks 0.93 mm into the
    plate and slides.  Newton took a direction uphill of its line search's merit whole (old
    factors at a kink of the friction law: the residual rose 12x), which closed a
    four-iteration limit cycle at every halving of the step, down to h / 256, and the press
    diverged.  Now only a solve's first such direction is taken whole, the later ones halved
    until the residual falls (``newton._line_search``): the next ten steps run, and the press
    stays as deep as the criterion above says."""
    from pathlib import Path

    data = np.load(Path(__file__).parents[1] / "data" / "deep_press_7GPa_state.npz")
    brush = load_brush("default")
    brush = brush.with_material(dataclasses.replace(brush.bristles[0].material, E=7000.0, name="m"))
    sim = Simulator(load_scene("flat_plate", brush=brush), SimSettings(dt=1e-3))
    z0 = brush.max_length + 0.44
    sim.reset(np.array([0.0, 0.0, z0]), R0)
    st = sim.get_state()
    arrays = {k: data[k] for k in data.files if not k.startswith("jac_")}
    arrays["time"] = float(arrays["time"])
    arrays["steps"] = int(arrays["steps"])
    jac = st.jac._replace(**{k[4:]: data[k] for k in data.files if k.startswith("jac_")})
    sim.set_state(dataclasses.replace(st, **arrays, jac=jac))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PenetrationWarning)
        for k in range(249, 259):
            s = k / 400.0
            out = sim.step(np.array([0.0, 0.0, z0 - 3.0 * (3 * s * s - 2 * s**3)]), R0)
    assert np.all(np.isfinite(out.tcp_force)) and sim.state.steps == 258
    assert out.tip_penetration.max() * 1e3 > 20.0 * PAPER_PENETRATION_UM


def test_mesh_plate_and_analytic_plane_give_the_same_forces():
    """The paper meshed its flat plate: the triangle mesh (closest point on triangles, grid index)
    and the analytic plane give the same press-and-drag forces to solver tolerance."""
    from brush_env.engine import MeshPlate

    brush = load_brush("tiny")
    runs = []
    for surf in (Plane((0.0, 0.0, 0.0), (0.0, 0.0, 1.0)), MeshPlate((0.0, 0.0, 0.0), 60.0, 12)):
        sim = Simulator(
            Scene(brush, (surf,), tip_tip=False), SimSettings(dt=1e-3, newton_rtol=1e-10)
        )
        z0 = brush.max_length + 0.44
        sim.reset(np.array([0.0, 0.0, z0]), R0)
        F = []
        for k in range(1, 601):  # press 2 mm in 0.3 s, then drag 3 mm along a diagonal
            s = min(k / 300.0, 1.0)
            d = max(k - 300, 0) * 0.01
            out = sim.step(np.array([d, 0.7 * d, z0 - 2.0 * (3 * s * s - 2 * s**3)]), R0)
            F.append(np.r_[out.tcp_force, out.tip_normal_force])
        runs.append(np.array(F))
    assert np.abs(runs[0]).max() > 0.05
    assert np.allclose(runs[0], runs[1], rtol=0, atol=1e-7)


def test_rotations_stay_orthonormal_through_a_long_sliding_contact():
    """SO(3) is preserved: after 1000 implicit steps of a pressed bristle dragged round a circle
    (about 10^4 incremental rotation updates per body) every body's R R^T - I stays at round-off.

    Without re-orthonormalisation the drift grows by ~1e-16 per update and reached 1.7e-12 after
    640 steps of the FlatPlate env, enough to stall Newton on a sticking tip (integrator docs)."""
    brush = one_bristle(length=10.0, bodies=3, lean=1.0)
    sim = Simulator(plate_scene(brush), SimSettings(dt=4e-3))
    z = 10.0 + 0.44 - 1.0  # 1 mm press
    sim.reset(np.array([5.0, 0.0, z]), R0)
    for k in range(1000):
        phi = 2 * np.pi * k / 250
        out = sim.step(np.array([5.0 * np.cos(phi), 5.0 * np.sin(phi), z]), R0)
    assert out.tip_normal_force[0] > 0.0  # still pressed
    R = sim.state.rot
    err = np.abs(np.einsum("bij,bkj->bik", R, R) - np.eye(3)).max()
    assert err < 2e-15  # a few ulps of 1 (without the fix: 1.7e-14 here)


@pytest.mark.parametrize("case", ["reversal", "band", "inside", "speeding_up"])
def test_slip_step_limit_stops_a_newton_step_at_the_slip_turning_point(case):
    """A sliding tip (|v| = 5 mm/s along x on the plane z = 0): a Newton step that would reverse
    the slip is cut where the slip speed reaches v_d / 2 (inside the smooth band of eq 10), or at
    its closest approach to zero if the path passes the band; steps that do not slow the slip, or
    a tip already inside the band, are not limited."""
    h, v_d = 1e-3, CP.v_d
    state = np.zeros(1, rec.TIP_STATE)[0]
    state["fn"] = 0.1
    pt = np.array([0.0, 0.0, 0.43])
    state["cpt"] = (0.0, 0.0, 0.0)
    v0 = np.array([0.0 if case == "inside" else 5.0, 0.0, 0.0]) + (case == "inside") * 0.5
    state["hist"] = v0 * h - (pt - state["pn"])  # backward Euler: v = (pt - pn + hist) / h
    dv = {
        "reversal": [-10.0, 0.0, 0.0],
        "band": [-10.0, 2.0, 0.0],
        "inside": [-10.0, 0.0, 0.0],
        "speeding_up": [3.0, 1.0, 0.0],
    }[case]
    dp = np.array(dv) * h
    a = ct.slip_step_limit(pt, dp, state, 1.0, 1.0 / h, v_d)
    v = v0 + a * np.array(dv)
    if case == "reversal":  # passes through zero: stop at |v| = v_d / 2, still moving forward
        assert np.isclose(np.linalg.norm(v), v_d / 2) and v[0] > 0
    elif case == "band":  # the path's closest approach to v = 0 (|v| = 50 / |dv| = 0.98 mm/s)
        closest = 10.0 / np.sqrt(104.0)
        assert closest > v_d / 2 and np.isclose(np.linalg.norm(v), closest)
    else:
        assert a == 1.0


# --------------------------------------------------------------- eq 6 in series with a spring
SERIES_CASES = [  # (overlap [mm], rate [mm/s], compliance [mm/N], damping c)
    (1e-4, 0.0, 0.9, 0.0),
    (0.05, 0.0, 0.9, 0.0),  # mostly the spring's: ~0.05 N
    (0.3, 0.0, 0.9, 0.0),
    (0.02, 0.0, 1e-3, 0.0),  # a stiff spring: mostly eq 6's
    (0.05, 3.0, 0.9, 0.5),  # closing, with eq 6's damping
    (0.05, -3.0, 0.9, 0.5),  # opening
]


@pytest.mark.parametrize(("delta", "rate", "cs", "c"), SERIES_CASES)
def test_series_law_splits_the_overlap_into_penetration_and_compression(delta, rate, cs, c):
    """The rigid tip's overlap is eq 6's penetration plus the spring's compression cs Fn (two
    springs in series), and eq 6 holds at that penetration."""
    cp = ContactParams()
    args = (cp.k, cp.m1, c, cp.m2, cp.m3)
    F, kn, cn, dc = ct.series_law(delta, rate, *args, cs)
    assert 0.0 < dc < delta and F > 0.0
    assert dc + cs * F == pytest.approx(delta, rel=1e-10)
    assert F == pytest.approx(ct.normal_law(dc, rate, *args)[0], rel=1e-12)
    if c == 0.0:  # closed form: F = k dc^m1
        assert F == pytest.approx(cp.k * dc**cp.m1, rel=1e-12)


@pytest.mark.parametrize(("delta", "rate", "cs", "c"), SERIES_CASES)
def test_series_law_slopes_match_central_differences(delta, rate, cs, c):
    cp = ContactParams()
    args = (cp.k, cp.m1, c, cp.m2, cp.m3)
    _, kn, cn, _ = ct.series_law(delta, rate, *args, cs)
    h = 1e-6 * delta
    fd = (
        ct.series_law(delta + h, rate, *args, cs)[0] - ct.series_law(delta - h, rate, *args, cs)[0]
    ) / (2 * h)
    assert kn == pytest.approx(fd, rel=1e-5)
    # and the series spring's slope: 1 / (1 / k_eq6 + cs)
    dc = ct.series_law(delta, rate, *args, cs)[3]
    k6 = ct.normal_law(dc, rate, *args)[1]
    assert kn == pytest.approx(1.0 / (1.0 / k6 + cs), rel=1e-10)
    if c > 0.0:
        hv = 1e-6
        fv = (
            ct.series_law(delta, rate + hv, *args, cs)[0]
            - ct.series_law(delta, rate - hv, *args, cs)[0]
        ) / (2 * hv)
        assert cn == pytest.approx(fv, rel=1e-4)


def test_series_law_without_a_spring_is_eq6_and_without_overlap_nothing():
    cp = ContactParams()
    args = (cp.k, cp.m1, cp.c, cp.m2, cp.m3)
    assert ct.series_law(0.01, 2.0, *args, 0.0)[:3] == ct.normal_law(0.01, 2.0, *args)
    assert ct.series_law(0.0, 2.0, *args, 0.9) == (0.0, 0.0, 0.0, 0.0)
    assert ct.series_law(-0.1, 2.0, *args, 0.9)[0] == 0.0


def test_compliance_acts_along_the_axis_squared():
    args = np.zeros(1, rec.TIP_ARGS)[0]
    n = np.array([0.0, 0.0, 1.0])
    assert ct.compliance(args, n) == 0.0  # the full chain: none
    args["cax"] = 0.9
    args["axis"] = [0.0, np.sin(0.3), -np.cos(0.3)]
    assert ct.compliance(args, n) == pytest.approx(0.9 * np.cos(0.3) ** 2, rel=1e-14)
