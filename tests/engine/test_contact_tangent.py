"""The contact's Newton tangent against the derivative of the contact load it belongs to.

``contact.tip_load`` returns the tip load F(pt) and its tangent Kt = dF/dpt; Newton converges
quadratically only if Kt is that derivative.  On curved surfaces the normal force's derivative
holds the normal's turning (Fn dn/dpt, 1 / (r + gap) for a sphere of radius r), which the
closed-form curvatures give.  These tests compare Kt with central differences of F (eq 6: the
tangent must be the load's derivative) on every curved surface kind, on a baked crown grid and in
the gap between two surfaces, in the dynamic case (damping through the BDF2 rate formula, with
the tip sliding across the surface or pressing into it).  Friction is switched off: its tangent
leaves out the turning of its tangent plane on purpose (``contact._friction_load``).
"""

from __future__ import annotations

import numpy as np
import pytest

from brush_env.engine import Scene, SimSettings, Simulator, load_scene
from brush_env.engine import contact as ct
from brush_env.engine import records as rec
from brush_env.engine.scene import Capsule, Cylinder, Ellipsoid, Sphere

from .test_contact import R0, one_bristle

RADIUS = 0.44  # tip sphere radius [mm]
H = 1e-3  # step [s]
C0, C1, C2 = 1.5, -2.0, 0.5  # BDF2


def _setup(surfaces):
    """The contact arrays of one bristle over ``surfaces``, friction off."""
    sim = Simulator(Scene(one_bristle(bodies=2), tuple(surfaces), tip_tip=False), SimSettings())
    sim.reset(np.array([0.0, 0.0, 50.0]), R0)
    con = sim.bristles._contact()
    con.cp["mu_s"] = 0.0
    con.cp["mu_d"] = 0.0
    return con


def _load(con, pt):
    F = np.zeros(3)
    Kt = np.zeros((3, 3))
    tw = rec.make_work(1).tipw
    sub = rec.Substep(C0, C1, C2, H, 1.0 / H, False, np.zeros(3), 0.0, 0, 0.0)
    ct.tip_load(0, np.asarray(pt, float), sub, con, F, Kt, tw)
    return F, Kt


def _state(con, pt, v, delta, beta):
    """Tip at pt [mm] moving at v [mm/s] with stiction deformation delta [mm] and frozen beta."""
    st = con.tip_state[0]
    st["pn"] = pt - np.asarray(v) * H  # the tip a step ago
    # the rate history (records.TIP_STATE): v = (C0 (pt - pn) + hist) / H
    st["hist"] = np.asarray(v) * H - C0 * (np.asarray(pt) - st["pn"])
    st["delta"] = delta
    st["beta"] = beta


def _fd_tangent(con, pt, eps=1e-7):
    K = np.zeros((3, 3))
    for b in range(3):
        e = np.zeros(3)
        e[b] = eps
        K[:, b] = (_load(con, pt + e)[0] - _load(con, pt - e)[0]) / (2 * eps)
    return K


def _on(surface_point, normal, depth):
    """A tip centre pressed ``depth`` [mm] into the surface at ``surface_point`` along normal."""
    n = np.asarray(normal, float) / np.linalg.norm(normal)
    return np.asarray(surface_point, float) + (RADIUS - depth) * n, n


def _tangent_dirs(n):
    a = np.cross(n, [0.3, 0.5, 0.8])
    a /= np.linalg.norm(a)
    return a, np.cross(n, a)


CASES = {
    "sphere": (Sphere(center=(0.0, 0.0, 0.0), radius=3.0), (0.6, 0.0, 0.8)),
    "capsule": (Capsule(a=(-4.0, 0.0, 0.0), b=(4.0, 0.0, 0.0), radius=2.0), (0.0, 0.6, 0.8)),
    "cylinder": (
        Cylinder(point=(0.0, 0.0, 0.0), axis=(0.0, 1.0, 0.0), radius=2.5),
        (0.8, 0.0, 0.6),
    ),
    "ellipsoid": (Ellipsoid(center=(0.0, 0.0, 0.0), semi_axes=(4.0, 3.0, 2.0)), (0.3, 0.4, 0.866)),
}


def _surface_point(surface, n):
    """The point of the surface whose outward normal is n (closed forms)."""
    n = np.asarray(n, float) / np.linalg.norm(n)
    if isinstance(surface, Ellipsoid):
        a2 = np.asarray(surface.semi_axes) ** 2
        lam = 1.0 / np.sqrt(np.sum(a2 * n**2))
        return np.asarray(surface.center) + lam * a2 * n, n
    if isinstance(surface, Sphere):
        return np.asarray(surface.center) + surface.radius * n, n
    return n * surface.radius, n  # capsule (middle) and cylinder through the origin


@pytest.mark.parametrize("kind", sorted(CASES))
@pytest.mark.parametrize("motion", ["sliding", "pressing"])
def test_tangent_is_the_load_derivative_on_curves(kind, motion):
    surface, normal = CASES[kind]
    con = _setup([surface])
    q, n = _surface_point(surface, normal)
    pt, n = _on(q, n, 0.02)
    t1, t2 = _tangent_dirs(n)
    if motion == "sliding":  # across the surface (the damping's J^T v term) and into it
        _state(con, pt, 30.0 * t1 + 4.0 * t2 - 2.0 * n, 0.0, 1.0)
    else:  # into the surface
        _state(con, pt, 0.2 * t1 - 20.0 * n, 0.0, 0.0)
    F, Kt = _load(con, pt)
    fn = con.tip_state[0]["fn"]
    assert fn > 0.0
    K = _fd_tangent(con, pt)
    # the curvature terms are what this checks: without them Kt misses K by ~Fn / r
    scale = np.abs(K).max()
    assert np.abs(Kt - K).max() <= 1e-5 * scale, (Kt, K)
    if kind == "sphere":  # closed form: across the surface, Fn n turns at Fn / |pt - centre|
        P = np.eye(3) - np.outer(n, n)
        expect = fn / np.linalg.norm(pt - np.asarray(surface.center)) * P
        assert np.abs(P @ Kt @ P - expect).max() <= 1e-9 * fn


def test_tangent_in_a_gap_between_two_surfaces():
    """A tip touching two spheres at once (an interproximal gap): both normals turn."""
    a = Sphere(center=(-3.3, 0.0, 0.0), radius=3.0, label="a")
    b = Sphere(center=(3.3, 0.0, 0.0), radius=3.0, label="b")
    con = _setup([a, b])
    pt = np.array([0.0, 0.1, 0.8])  # 0.04 mm into both
    _state(con, pt, (0.0, 30.0, -1.0), 0.0, 1.0)
    F, Kt = _load(con, pt)
    assert con.tip_state[0]["fn"] > 0.0
    assert abs(F[0]) < 1e-9 * abs(F[2])  # symmetric walls: no net x force
    K = _fd_tangent(con, pt)
    assert np.abs(Kt - K).max() <= 1e-5 * np.abs(K).max(), (Kt, K)


def test_tangent_on_a_baked_crown():
    """On the tooth row's first crown (a baked SDF grid): the derivative of the interpolation."""
    scene = load_scene("tooth_row")
    con = _setup(scene.surfaces)
    crown = scene.surfaces[0]
    V, T = crown.vertices, crown.triangles
    c = V[T].mean(axis=1)
    nr = np.cross(V[T[:, 1]] - V[T[:, 0]], V[T[:, 2]] - V[T[:, 0]])
    nr /= np.linalg.norm(nr, axis=1)[:, None]
    rng = np.random.default_rng(3)
    checked = 0
    for t in rng.integers(0, len(T), 40):
        pt = c[t] + nr[t] * (RADIUS - 0.02)
        t1, _ = _tangent_dirs(nr[t])
        _state(con, pt, 30.0 * t1 - nr[t], 0.0, 1.0)
        F, Kt = _load(con, pt)
        if con.tip_state[0]["fn"] <= 0.0:
            continue
        K = _fd_tangent(con, pt, eps=1e-8)
        if np.abs(_fd_tangent(con, pt, eps=2e-8) - K).max() > 1e-3 * np.abs(K).max():
            continue  # on a cell face of the grid: the interpolation has a kink there
        assert np.abs(Kt - K).max() <= 1e-4 * np.abs(K).max(), (t, Kt, K)
        checked += 1
    assert checked >= 20
