"""Physics validation of the engine (issue "engine core", items 5 and 7).

Every assertion compares the engine with an independent reference (closed form, exact elastica,
an exact rigid-body solution, or a much finer time step); none compares with numbers the engine
produced earlier.  Units: mm, N, s, tonne.
"""

import json
import math

import numpy as np
import pytest

from brush_env import cli
from brush_env.engine import Scene, SimSettings, Simulator, load_brush
from brush_env.validation import PAPER_INNER, SLENDER, Geometry, classified_modes
from brush_env.validation import references as ref
from brush_env.validation.modal import bristle_stiffness_mass

R0 = np.diag([1.0, -1.0, -1.0])  # default TCP orientation: bristles hang toward -z


def _rot(axis, angle):
    """Rodrigues rotation matrix."""
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * K @ K


def _static_tip(geom: Geometry, bodies: int, force, increments: int = 1):
    """Static tip position [mm] and last-body rotation of a bristle along world x under a dead
    tip force [N]."""
    sim = geom.simulator(bodies)
    sim.set_tip_forces(np.asarray(force, float)[None, :])
    out = sim.solve_static(increments=increments)
    return out.tip_pos[0], sim.state.rot[sim.model.bstart[1] - 1]


def _rigidly_moved(tips, p0, R0_, p1, R1):
    """Tip positions [mm] carried rigidly from the TCP pose (p0, R0_) to (p1, R1)."""
    return p1 + (tips - p0) @ (R1 @ R0_.T).T


def _chord_lengths(sim, tips):
    """Root-to-tip distance [mm] of every bristle (its length L when unbent)."""
    st = sim.state
    roots = st.tcp_p[1] + sim.model.root_p @ st.tcp_R[1].T
    return np.linalg.norm(tips - roots, axis=1)


# --------------------------------------------------------------------------- statics
@pytest.mark.parametrize("plane", ["thin", "wide"])
@pytest.mark.parametrize("alpha, tol", [(0.01, 1e-4), (0.1, 5e-3)])
def test_small_deflection_matches_timoshenko_with_shear(plane, alpha, tol):
    # paper's inner bristle, L/h = 12.5: shear adds 0.6 % (thin) and 2.7 % (wide) to v
    g = PAPER_INNER
    sec, mat = g.section, g.material
    c, I = (2, sec.I_y) if plane == "thin" else (1, sec.I_z)
    P = alpha * mat.E * I / g.length**2
    force = np.zeros(3)
    force[c] = P
    tip, R = _static_tip(g, 6, force)
    tim = ref.timoshenko_cantilever_tip(
        P, g.length, mat.E, mat.G, I, sec.area, sec.shear_coeff(mat.nu)
    )
    angle = math.atan2(R[c, 0], R[0, 0])
    assert tip[c] == pytest.approx(tim["v"], rel=tol)
    assert angle == pytest.approx(tim["theta"], rel=tol)
    if alpha <= 0.01:  # the tight check resolves shear: Euler-Bernoulli is 5-27 tol away
        v_eb = P * g.length**3 / (3.0 * mat.E * I)
        assert abs(tip[c] / v_eb - 1.0) > 5.0 * tol
    assert abs(tip[3 - c]) < 1e-12 * g.length  # no out-of-plane deflection


def test_axial_stiffness():
    g = PAPER_INNER
    P = 1e-4 * g.E * g.section.area  # strain 1e-4, tension
    tip, _ = _static_tip(g, 6, [P, 0.0, 0.0])
    assert tip[0] - g.length == pytest.approx(
        ref.axial_tip(P, g.length, g.E, g.section.area), rel=1e-3
    )
    assert np.abs(tip[1:]).max() < 1e-12


@pytest.mark.parametrize("geom", [PAPER_INNER, SLENDER], ids=["inner", "slender"])
def test_torsional_stiffness(geom):
    # unit torque about the axis on the last body through the static tangent stiffness
    n = 6
    K, _ = bristle_stiffness_mass(geom.simulator(n), 0)
    twist = np.linalg.solve(K, np.eye(6 * n)[:, 6 * n - 3])
    mat = geom.material
    assert twist[6 * n - 3] == pytest.approx(
        ref.torsion_tip(1.0, geom.length, mat.G, geom.section.J), rel=1e-4
    )


def test_torsional_frequency():
    # clamped-free torsion bar: f = sqrt(G J / (rho I_p)) / (4 L), I_p = I_y + I_z.
    # Each rigid body carries its segment's whole polar inertia at the twist of its distal node,
    # so the lumped chain converges at first order (-2 % at 24 bodies, -8 % at 6).
    g = SLENDER
    sec, mat = g.section, g.material
    f_ref = math.sqrt(mat.G * sec.J / (mat.density * (sec.I_y + sec.I_z))) / (4.0 * g.length)
    errs = []
    for n in (12, 24):
        f, kinds = classified_modes(g.simulator(n))
        errs.append(abs(f[kinds.index("torsion")] / f_ref - 1.0))
    assert errs[1] < 0.03
    assert errs[1] < errs[0]


@pytest.mark.parametrize("alpha", [1.0, 2.0, 5.0, 10.0])
@pytest.mark.parametrize("bodies, tol_v, tol_h", [(6, 0.02, 0.03), (24, 0.003, 0.005)])
def test_large_deflection_matches_elastica(alpha, bodies, tol_v, tol_h):
    g = SLENDER  # L/h = 80: shear and axial strain are negligible next to the tolerances
    P = alpha * g.E * g.section.I_y / g.length**2
    tip, _ = _static_tip(g, bodies, [0.0, 0.0, P], increments=math.ceil(alpha))
    e = ref.elastica_cantilever(alpha)
    assert tip[2] / g.length == pytest.approx(e["v_over_L"], rel=tol_v)
    assert 1.0 - tip[0] / g.length == pytest.approx(e["h_over_L"], rel=tol_h)


@pytest.mark.parametrize("bodies, tol", [(6, 0.03), (24, 0.005)])
@pytest.mark.parametrize("plane", ["thin", "wide"])
def test_first_bending_frequency(bodies, tol, plane):
    g = SLENDER
    sec = g.section
    I = sec.I_y if plane == "thin" else sec.I_z
    f_ref = ref.euler_bernoulli_cantilever_frequencies(g.length, g.E, I, g.density, sec.area, 1)
    f, kinds = classified_modes(g.simulator(bodies))
    assert f[kinds.index("bend_" + plane)] == pytest.approx(f_ref[0], rel=tol)
    if plane == "thin":  # a flat bristle's lowest mode is bending about its thin direction
        assert kinds[0] == "bend_thin"


# --------------------------------------------------------------------------- rigid base motions
def test_static_rigid_pose_gives_zero_wrench_and_straight_bristles():
    brush = load_brush()
    sim = Simulator(brush, SimSettings(gravity=(0.0, 0.0, 0.0)))
    p, R = np.array([3.0, -4.0, 25.0]), _rot((1.0, 2.0, 3.0), 0.7)
    tips0 = sim.reset().tip_pos  # unstressed bristles at the identity pose
    sim.reset(p, R)
    out = sim.solve_static()
    assert np.abs(out.tcp_force).max() < 1e-9
    assert np.abs(out.tcp_moment).max() < 1e-9
    assert np.abs(out.tip_pos - _rigidly_moved(tips0, np.zeros(3), np.eye(3), p, R)).max() < 1e-9
    lengths = np.array([b.length for b in brush.bristles])
    assert np.abs(_chord_lengths(sim, out.tip_pos) - lengths).max() < 1e-9  # straight


@pytest.mark.parametrize("integrator", ["euler", "bdf2"])
def test_constant_velocity_translation_is_force_free(integrator):
    # a brush translating rigidly at constant velocity is an exact, force-free solution: start it
    # on that solution (bodies and history moving with the TCP) and step 50 times
    brush = load_brush()
    dt = 1e-3
    sim = Simulator(brush, SimSettings(gravity=(0.0, 0.0, 0.0), dt=dt, integrator=integrator))
    p, R, v = np.array([3.0, -4.0, 25.0]), _rot((0.0, 1.0, 1.0), 2.0), np.array([50.0, -20.0, 10.0])
    tips0 = sim.reset(p, R).tip_pos
    st = sim.get_state()
    st.vel[:] = v
    st.pvel[:] = v
    st.ppos[:] = st.pos - v * dt
    st.tcp_p[0] = p - v * dt
    sim.set_state(st)
    for k in range(1, 51):
        out = sim.step(p + v * k * dt, R)
        assert np.abs(out.tcp_force).max() < 1e-9
        assert np.abs(out.tcp_moment).max() < 1e-9
    assert np.abs(out.tip_pos - (tips0 + v * 50 * dt)).max() < 1e-9
    assert np.abs(out.tip_vel - v).max() < 1e-8


def test_slow_large_rotation_then_static_is_wrench_free():
    brush = load_brush()
    sim = Simulator(brush, SimSettings(gravity=(0.0, 0.0, 0.0), dt=1e-3, newton_rtol=1e-10))
    p, R = np.array([0.0, 0.0, 10.0]), R0
    axis = (0.3, -1.0, 0.5)
    tips0 = sim.reset(p, R).tip_pos
    for k in range(1, 201):  # 90 degrees in 0.2 s
        sim.step(p, _rot(axis, 0.5 * math.pi * k / 200) @ R)
    R1 = _rot(axis, 0.5 * math.pi) @ R
    out = sim.solve_static()
    assert np.abs(out.tcp_force).max() < 1e-9
    assert np.abs(out.tcp_moment).max() < 1e-9
    assert np.abs(out.tip_pos - _rigidly_moved(tips0, p, R, p, R1)).max() < 1e-9
    lengths = np.array([b.length for b in brush.bristles])
    assert np.abs(_chord_lengths(sim, out.tip_pos) - lengths).max() < 1e-9  # straight


def test_static_wrench_balances_tip_loads():
    # tip-tip contact off: the random loads push some neighbouring tips into each other, and the
    # static solve with tip-tip contact does not converge (reported); contact forces between tips
    # are internal and would cancel in the balance anyway
    brush = load_brush()
    sim = Simulator(
        Scene(brush, tip_tip=False), SimSettings(gravity=(0.0, 0.0, 0.0), newton_rtol=1e-10)
    )
    p = np.array([0.0, 0.0, 10.0])
    tips0 = sim.reset(p, R0).tip_pos
    F = np.random.default_rng(7).normal(scale=1e-3, size=(brush.n_bristles, 3))
    sim.set_tip_forces(F)
    out = sim.solve_static(increments=2)
    moment = np.cross(out.tip_pos - p, F).sum(axis=0)  # about the TCP, at the deformed tips
    assert np.abs(out.tcp_force + F.sum(axis=0)).max() < 1e-10
    assert np.abs(out.tcp_moment + moment).max() < 1e-9
    assert np.abs(out.tip_pos - tips0).max() > 1e-3  # the loads did bend the bristles


# --------------------------------------------------------------------------- time integration
def _driven_bristle(dt, integrator, T=0.05):
    """Paper's inner bristle (f1 ~ 100 Hz) on a base moving sideways by sin^4(pi f t), f = 20 Hz,
    1 mm: C^2-smooth start from rest.  Returns times [s], TCP force [N] and tip position [mm]."""
    # Newton's error well below the time discretisation's at every dt here: at the default
    # tolerance (1e-5 of E I / L^2) it floors the force error at ~3e-4 below 0.1 ms steps, where
    # BDF2's own error is smaller (the order is a property of the scheme, not of the solve)
    sim = PAPER_INNER.simulator(
        6, SimSettings(gravity=(0.0, 0.0, 0.0), dt=dt, integrator=integrator, newton_rtol=1e-10)
    )
    n = int(round(T / dt))
    F, X = [np.zeros(3)], [sim.tip_positions()[0].copy()]
    for k in range(1, n + 1):
        t = k * dt
        out = sim.step(np.array([0.0, math.sin(math.pi * 20.0 * t) ** 4, 0.0]), np.eye(3))
        F.append(out.tcp_force.copy())
        X.append(out.tip_pos[0].copy())
    return np.arange(n + 1) * dt, np.array(F), np.array(X)


def _on_grid(t, Y, grid):
    return np.stack([np.interp(grid, t, Y[:, c]) for c in range(Y.shape[1])], axis=1)


@pytest.fixture(scope="module")
def fine_reference():
    t, F, X = _driven_bristle(1e-5, "bdf2")
    grid = np.arange(0.0, 0.05 + 1e-12, 2e-4)  # common to every dt below
    return grid, _on_grid(t, F, grid), _on_grid(t, X, grid)


@pytest.mark.parametrize("integrator, lo, hi", [("euler", 1.6, 2.5), ("bdf2", 3.0, 5.0)])
def test_convergence_order(fine_reference, integrator, lo, hi):
    # error against a dt = 1e-5 BDF2 reference must halve (euler) / quarter (bdf2) with dt
    grid, Fr, Xr = fine_reference
    errF, errX = [], []
    for dt in (2e-4, 1e-4, 5e-5):
        t, F, X = _driven_bristle(dt, integrator)
        errF.append(np.abs(_on_grid(t, F, grid) - Fr).max() / np.abs(Fr).max())
        errX.append(np.abs(_on_grid(t, X, grid) - Xr).max())
    for err in (errF, errX):
        for a, b in zip(err[:-1], err[1:]):
            assert lo <= a / b <= hi, (integrator, err)


# --------------------------------------------------------------------------- reproducibility
def _drive(sim, k0, k1):
    out = []
    for k in range(k0, k1):
        t = k * sim.settings.dt
        p = np.array(
            [
                2.0 * math.sin(4.0 * math.pi * t),
                1.0 - math.cos(4.0 * math.pi * t),
                10.0 - 0.5 * math.sin(10.0 * math.pi * t),
            ]
        )
        r = sim.step(p, _rot((0.0, 1.0, 0.0), 0.2 * math.sin(6.0 * math.pi * t)) @ R0)
        out.append(np.concatenate([r.tcp_force, r.tcp_moment, r.tip_pos.ravel()]))
    return np.array(out)


def _loaded_sim():
    brush = load_brush()
    sim = Simulator(brush, SimSettings(dt=1e-3))
    sim.reset(np.array([0.0, 0.0, 10.0]), R0)
    sim.set_tip_forces(np.random.default_rng(3).normal(scale=1e-3, size=(brush.n_bristles, 3)))
    return sim


def test_runs_are_bit_identical():
    a = _drive(_loaded_sim(), 1, 31)
    b = _drive(_loaded_sim(), 1, 31)
    assert np.array_equal(a, b)


def test_state_round_trip_reproduces_continuation():
    sim = _loaded_sim()
    _drive(sim, 1, 11)
    saved = sim.get_state()
    first = _drive(sim, 11, 31)
    _drive(sim, 31, 36)  # move on, then restore
    sim.set_state(saved)
    assert np.array_equal(_drive(sim, 11, 31), first)


# --------------------------------------------------------------------------- CLI
def test_cli_validate_cantilever_json(capsys):
    assert cli.main(["validate", "cantilever", "--alpha", "0.1", "--bodies", "6", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["reference_kind"] == "timoshenko"
    for part in ("computed", "reference", "rel_error"):
        assert set(res[part]) == {"v_over_L", "h_over_L", "tip_angle_rad"}
    assert res["reference"]["tip_angle_rad"] == pytest.approx(0.05)  # P L^2 / (2 E I)
    assert abs(res["rel_error"]["v_over_L"]) < 5e-3


def test_cli_validate_frequency_json(capsys):
    assert cli.main(["validate", "frequency", "--bodies", "6", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert abs(res["rel_error"]) < 0.03


@pytest.mark.slow  # `validate all` (~13 s)
def test_cli_validate_all_passes(capsys):
    assert cli.main(["validate", "all", "--json"]) == 0
    res = json.loads(capsys.readouterr().out)
    assert res["passed"] and len(res["checks"]) >= 20


def _bench_rows(capsys, target: str, keys=()) -> list[dict]:
    """The JSON rows of ``brush-env bench TARGET --quick --json`` (exit 0); at least one, each
    with every name in ``keys``."""
    assert cli.main(["bench", target, "--quick", "--json"]) == 0
    out = capsys.readouterr().out
    rows = [json.loads(line) for line in out.splitlines() if line.startswith("{")]
    assert rows and all(set(keys) <= set(r) for r in rows)
    return rows


def test_cli_bench_engine_quick(capsys):
    keys = {
        "bodies",
        "dt",
        "integrator",
        "rms_force_error",
        "rms_moment_error",
        "wall_s",
        "rtf",
        "newton_per_step_per_bristle",
    }
    rows = _bench_rows(capsys, "engine", keys)
    assert all(np.isfinite(r["rms_force_error"]) and r["wall_s"] > 0 for r in rows)


@pytest.mark.slow  # a full bench CLI run (~4 s)
def test_cli_bench_contact_quick(capsys):
    keys = {
        "bodies",
        "dt",
        "integrator",
        "tip_tip",
        "rtf",
        "rms_force_error",
        "status",
        "newton_per_step_per_bristle",
        "substeps_extra",
        "reference",
    }
    rows = _bench_rows(capsys, "contact", keys)
    assert {r["tip_tip"] for r in rows} == {False, True}
    grid = [r for r in rows if not r["reference"]]
    assert grid and all(
        r["rtf"] > 0 and r["newton_per_step_per_bristle"] > 0 for r in rows if r["status"] == "ok"
    )
    # a diverged row is reported with a NaN error, never dropped or given a number
    assert all(np.isfinite(r["rms_force_error"]) == (r["status"] == "ok") for r in grid)
    # quick grid: its reference has the rows' own bodies (3), so both errors are the same number
    assert all("rms_force_error_same_bodies" in r for r in grid)
    assert all(
        r["rms_force_error_same_bodies"] == r["rms_force_error"]
        for r in grid
        if r["status"] == "ok"
    )


@pytest.mark.slow  # a full bench CLI run (~6 s)
def test_cli_bench_convergence_quick(capsys):
    """Self-convergence in dt: below 1 ms (where the 3 mm press stays on one buckling branch,
    docs/model.md) the error against the finest run shrinks as dt is refined; the body series
    compares against its most refined run."""
    rows = _bench_rows(capsys, "convergence")
    assert {r["series"] for r in rows} == {"dt", "bodies", "lag"}
    dt_rows = sorted((r for r in rows if r["series"] == "dt"), key=lambda r: -r["dt"])
    assert all(r["status"] == "ok" for r in dt_rows)
    finest = dt_rows[-1]
    assert all(r["against"] == f"{finest['bodies']} bodies, dt={finest['dt']:g}" for r in dt_rows)
    errs = [r["rms_force_error"] for r in dt_rows if 0.0 < r["dt"] <= 1e-3 and r is not finest]
    assert len(errs) >= 2 and all(e > 0.0 for e in errs)
    assert all(a > b for a, b in zip(errs, errs[1:])), errs  # refining dt reduces the error
    # the one-sweep (lag) series is held to the coupled finest run, and starts from the same step
    lag_rows = [r for r in rows if r["series"] == "lag"]
    assert all(r["against"] == finest["against"] and r["tip_tip_sweeps"] == 1 for r in lag_rows)
    assert {r["dt"] for r in lag_rows} == {r["dt"] for r in dt_rows}
    body_rows = [r for r in rows if r["series"] == "bodies"]
    most = max(body_rows, key=lambda r: r["bodies"])
    assert all(r["against"] == f"{most['bodies']} bodies, dt={most['dt']:g}" for r in body_rows)
