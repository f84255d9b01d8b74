"""The bristle-on-plate reference (brush_env.validation.rod) against independent results.

Each expected value comes from a closed form or a linearised equation written down by others
(cited per test), evaluated here with scipy.special / brentq, never from the module's own output.
Units: mm, N, MPa.
"""

from __future__ import annotations

import ast
import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq
from scipy.special import ellipe, ellipk

from brush_env.validation import rod
from brush_env.validation.rod import buckled_bristle, section_stiffness

L = 10.0
B, H = 1.8, 0.8
E_MOD, NU = 7.0, 0.48
EA, GA, EI = section_stiffness(B, H, E_MOD, NU)
K_PINNED = 4.493409457909064  # smallest positive root of tan k = k (clamped-pinned column)


def test_module_imports_no_engine():
    tree = ast.parse(Path(rod.__file__).read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.add(("." * node.level) + (node.module or ""))
    assert not any("engine" in n for n in names), names
    assert names <= {
        "__future__",
        "math",
        "numbers",
        "collections.abc",
        "numpy",
        "scipy.integrate",
        "scipy.optimize",
    }, names


def test_stiffness_is_the_engines():
    """Same EA, GA_s (Cowper's shear coefficient) and EI as the engine's Timoshenko element."""
    from brush_env.engine.config import Section, load_brush, load_materials

    mat = load_materials()["silicone_7MPa"]
    sec = Section.rect(B, H)
    ea, ga, ei = section_stiffness(B, H, mat.E, mat.nu)
    assert ea == pytest.approx(mat.E * sec.area, rel=1e-14)
    assert ga == pytest.approx(sec.shear_coeff(mat.nu) * mat.G * sec.area, rel=1e-14)
    assert ei == pytest.approx(mat.E * sec.I_y, rel=1e-14)
    assert (mat.E, mat.nu) == (E_MOD, NU)  # the defaults of buckled_bristle
    assert load_brush().bristles[0].tip_radius == 0.44  # buckled_bristle's default radius


# ------------------------------------------------------------------ 1. linear buckling loads
@pytest.mark.parametrize("tip, kL", [("free", math.pi / 2), ("pinned", K_PINNED)])
def test_elastica_starts_at_euler_load(tip, kL):
    """Straight column (lean 0), tiny compression: P -> (kL)^2 EI / L^2.

    Clamped-free pi^2 EI / (4 L^2), clamped-pinned 20.19 EI / L^2 (Timoshenko & Gere, Theory of
    Elastic Stability, 2nd ed., sections 2.1 and 2.5).  Post-buckling raises P by O(delta / L)
    (clamped-free: P / P_E = 1 + delta / (2 L) + ..., from the elliptic solution of test 2), so
    at delta / L = 1e-5 the tolerance is 1e-4.
    """
    r = buckled_bristle(1e-4, length=L, lean_deg=0.0, tip=tip, model="elastica")
    assert r["force_N"] == pytest.approx(kL**2 * EI / L**2, rel=1e-4)


def test_vanishing_lean_tends_to_euler_branch():
    """Free elastica at delta = 0.01 mm: as the lean -> 0 the force tends to the lean-0 branch
    value P_E (1 + delta / (2 L)) (Timoshenko & Gere section 2.7 expansion)."""
    P_E = math.pi**2 * EI / (4 * L**2)
    target = P_E * (1 + 0.01 / (2 * L))
    errs = [
        abs(buckled_bristle(0.01, lean_deg=lean, model="elastica")["force_N"] / target - 1)
        for lean in (0.1, 0.01, 0.001)
    ]
    assert errs[0] > errs[1] > errs[2]
    assert errs[2] < 1e-3


def _reissner_critical(tip, ea, ga, ei, length):
    """Critical load of the straight rod with extension and shear (shear in the section frame).

    Linearising the Reissner equations about the compressed straight rod gives
    EI phi'' + P (1 + P/GA - P/EA) phi = -H (1 + P/GA - P/EA), i.e. with
    k^2 = P L^2 (1 + P/GA - P/EA) / EI:
    clamped-free  k = pi/2, i.e. P (1 + P/GA - P/EA) = P_E: for EA -> inf this is Haringx's
    formula P (1 + P/GA) = P_E (Haringx, Philips Res. Rep. 3 (1948) 401; Bazant, J. Eng. Mech.
    129 (2003) 1022 on Haringx vs Engesser), and Euler's for EA, GA -> inf;
    clamped-pinned (x(L) fixed): tan k / k = 1 - (P/GA) / (1 + P/GA - P/EA); tan k = k for
    EA, GA -> inf (Euler).
    """

    def beta(P):
        return 1 + P / ga - P / ea

    if tip == "free":
        P_E = math.pi**2 * ei / (4 * length**2)
        return brentq(lambda P: P * beta(P) - P_E, 0.5 * P_E, 1.5 * P_E, xtol=1e-16, rtol=1e-15)

    def f(P):
        k = math.sqrt(P * length**2 * beta(P) / ei)
        return math.tan(k) / k - 1 + (P / ga) / beta(P)

    P_E = K_PINNED**2 * ei / length**2
    return brentq(f, 0.9 * P_E, 1.02 * P_E, xtol=1e-16, rtol=1e-15)


@pytest.mark.parametrize("tip", ["free", "pinned"])
def test_reissner_straight_then_buckles_at_shear_corrected_load(tip):
    """Lean 0: pure compression (P = EA delta / L) up to delta_cr = P_cr L / EA, then the
    buckled branch starting at P_cr of the linearised Reissner equations (see above)."""
    P_cr = _reissner_critical(tip, EA, GA, EI, L)
    d_cr = P_cr * L / EA
    r = buckled_bristle([0.999 * d_cr, d_cr + 1e-5], lean_deg=0.0, tip=tip, model="reissner")
    assert r["force_N"][0] == pytest.approx(EA * 0.999 * d_cr / L, rel=1e-9)
    assert r["end_rotation_rad"][0] == 0.0
    # 1e-5 mm past the bifurcation the post-buckling rise is ~ P_cr * 1e-5 / (2 L) = 5e-7 P_cr
    assert r["force_N"][1] == pytest.approx(P_cr, rel=5e-6)
    assert r["end_rotation_rad"][1] > 0
    P_E = (math.pi**2 / 4 if tip == "free" else K_PINNED**2) * EI / L**2
    assert abs(P_cr / P_E - 1) > 1e-3  # the corrections are resolved, not below tolerance


def test_slender_reissner_tends_to_euler():
    """EA, GA_s >> P: a 50 mm x 0.05 mm strip (P_E / GA_s ~ 4e-6) buckles at Euler's load."""
    ea, ga, ei = section_stiffness(B, 0.05, E_MOD, NU)
    P_E = math.pi**2 * ei / (4 * 50.0**2)
    d = P_E * 50.0 / ea + 1e-4
    r = buckled_bristle(d, length=50.0, thickness=0.05, lean_deg=0.0, model="reissner")
    assert r["force_N"] == pytest.approx(P_E, rel=2e-5)


# ------------------------------------------------------------------ 2. elliptic integrals
def test_free_elastica_post_buckling_matches_elliptic_integrals():
    """Clamped-free elastica under a vertical end load (Timoshenko & Gere section 2.7):
    with k = sin(alpha/2), L sqrt(P/EI) = K(k); shortening delta / L = 2 - 2 E(k)/K(k);
    horizontal tip deflection 2 k sqrt(EI/P) = 2 k L / K(k).  (scipy's ellipk/ellipe take
    m = k^2.)"""
    deltas = [0.25, 0.5, 1.0, 2.0, 3.0]
    r = buckled_bristle(deltas, length=L, lean_deg=0.0, tip="free", model="elastica")
    for i, d in enumerate(deltas):
        m = brentq(lambda m, d=d: 2 - 2 * ellipe(m) / ellipk(m) - d / L, 1e-12, 0.99, xtol=1e-15)
        K, k = ellipk(m), math.sqrt(m)
        assert r["force_N"][i] == pytest.approx(EI * K**2 / L**2, rel=1e-7)
        assert r["tip_shift_mm"][i] == pytest.approx(2 * k * L / K, abs=1e-6)
        assert r["end_rotation_rad"][i] == pytest.approx(2 * math.asin(k), abs=1e-7)
        x, z = r["shape"][i]
        assert z[-1] == pytest.approx(0.44, abs=1e-9)  # end R above the plate
        assert z[0] - z[-1] == pytest.approx(L - d, abs=1e-8)


# ------------------------------------------------------------------ 3. small deflection, lean sign
@pytest.mark.parametrize("tip", ["free", "pinned"])
def test_below_buckling_the_bristle_is_an_axial_spring(tip):
    """Small lean t0, delta = half the critical compression: a column spring EA / L.

    Pinned (t0 = 0.1 deg): the end moves straight up relative to the clamp, axially
    delta cos t0 and sideways delta sin t0, so V = EA delta cos^2(t0) / L plus the sideways
    bending's vertical part, ~ 3 EI t0^2 delta / L^3 (x2 amplification) = 1e-8 of it.
    Free (t0 = 0.01 deg):
    Free: the vertical end force V splits into an axial P = V cos t0 and a lateral Q = V sin t0
    load; the end's lateral deflection Q [(tan u - u) / (k P) + L / GA_s] (beam-column,
    Timoshenko & Gere section 1.3, plus the Timoshenko shear term) adds its vertical part
    (times sin t0) to the axial shortening P L cos t0 / EA, and so does the shortening due to
    bending, (1/2) int w'^2 dx (T&G section 2.7), with the beam-column's
    w' = (Q / P) (tan u sin kx + cos kx - 1).  The lean terms are ~6e-5 of delta here
    (t0^2 L / delta); what they leave out is O(P / GA_s) of them, < 1e-6 of delta.
    """
    lean = 0.1 if tip == "pinned" else 0.01
    t0 = math.radians(lean)
    d = 0.5 * _reissner_critical(tip, EA, GA, EI, L) * L / EA
    r = buckled_bristle(d, lean_deg=lean, tip=tip, model="reissner")
    V = r["force_N"]
    if tip == "pinned":
        assert V == pytest.approx(EA * d * math.cos(t0) ** 2 / L, rel=1e-6)
        return
    P, Q = V * math.cos(t0), V * math.sin(t0)
    k = math.sqrt(P / EI)
    w = Q * ((math.tan(k * L) - k * L) / (k * P) + L / GA)
    u = k * L
    bend = (
        0.5
        * quad(
            lambda x: (Q / P * (math.tan(u) * math.sin(k * x) + math.cos(k * x) - 1)) ** 2,
            0.0,
            L,
            epsabs=0,
            epsrel=1e-12,
        )[0]
    )
    expected = P * L * math.cos(t0) / EA + w * math.sin(t0) + bend * math.cos(t0)
    assert expected == pytest.approx(d, rel=1e-6)
    assert V == pytest.approx(EA * d / L, rel=2e-4)  # the plain spring, lean term included
    # the beam-column leaves out the O(P/GA_s) shift of the buckling load (see
    # _reissner_critical), which moves its amplification P_cr / (P_cr - P) by ~0.5 % here
    assert r["tip_shift_mm"] == pytest.approx(w * math.cos(t0), rel=1e-2)
    assert r["tip_shift_mm"] > 0  # toward the lean


def test_leaning_elastica_is_a_beam_column():
    """Below P_E a leaning clamped-free column is a beam-column with axial load P cos(t0) and
    lateral end load P sin(t0); its end deflection is Q (tan u - u) / (k P_ax), u = k L,
    k^2 = P_ax / EI (Timoshenko & Gere section 1.3).  Tolerance 1 %: the deflection's nonlinear
    and axis-tilt terms are O(lean, deflection / L) ~ 1e-2 at lean 0.5 deg."""
    t0 = math.radians(0.5)
    r = buckled_bristle(2e-4, lean_deg=0.5, tip="free", model="elastica")
    P_ax = r["force_N"] * math.cos(t0)
    assert P_ax < 0.9 * math.pi**2 * EI / (4 * L**2)
    k = math.sqrt(P_ax / EI)
    w = r["force_N"] * math.sin(t0) * (math.tan(k * L) - k * L) / (k * P_ax)
    assert r["tip_shift_mm"] == pytest.approx(w, rel=1e-2)


def test_buckles_toward_the_lean():
    """+lean buckles toward +x (end rotates toward +x, free tip slides toward +x, the whole
    free bristle lies on the +x side of its unloaded line); a negative lean mirrors every
    horizontal quantity exactly; the pinned end keeps its touch position."""
    pin = buckled_bristle(0.5, lean_deg=1.0, tip="pinned")
    assert pin["end_rotation_rad"] > 0.3
    assert pin["tip_shift_mm"] == 0.0
    x, _ = pin["shape"]
    assert x[-1] == pytest.approx(L * math.sin(math.radians(1.0)), abs=1e-9)
    p = buckled_bristle(1.0, lean_deg=1.0, tip="free")
    n = buckled_bristle(1.0, lean_deg=-1.0, tip="free")
    assert p["end_rotation_rad"] > 0.3
    assert n["end_rotation_rad"] == pytest.approx(-p["end_rotation_rad"], rel=1e-12)
    assert n["force_N"] == pytest.approx(p["force_N"], rel=1e-12)
    assert n["horizontal_N"] == pytest.approx(-p["horizontal_N"], rel=1e-12, abs=1e-15)
    assert n["tip_shift_mm"] == pytest.approx(-p["tip_shift_mm"], rel=1e-12, abs=1e-15)
    x, _ = p["shape"]
    assert p["tip_shift_mm"] > 1.0
    straight = np.linspace(0, L, x.size) * math.sin(math.radians(1.0))
    assert np.all(x[1:] > straight[1:])
    assert np.array_equal(n["shape"][0], -x)


# ------------------------------------------------------------------ arguments
@pytest.mark.parametrize(
    "kwargs, text",
    [
        ({"length": -1.0}, "length = -1.0 is out of range: must be > 0 and <= 100 (mm)"),
        ({"tip": "stuck"}, "tip = 'stuck' is not allowed (allowed: free, pinned)"),
        ({"model": "euler"}, "model = 'euler' is not allowed"),
        ({"lean_deg": 12}, "lean_deg = 12 is out of range"),
        ({"nu": 0.5}, "nu = 0.5 is out of range: must be > -1 and < 0.5"),
        ({"E": "7"}, "E = '7' has the wrong type: expected a number (MPa)"),
        ({"steps": 2}, "steps = 2 is out of range"),
    ],
)
def test_bad_arguments_name_parameter_value_and_range(kwargs, text):
    with pytest.raises(ValueError, match="buckled_bristle: " + re.escape(text)):
        buckled_bristle(1.0, **kwargs)


def test_bad_delta_in_a_list_is_named_by_index():
    msg = "delta_mm[1] = 5.0 is out of range: must be >= 0 and <= 4"
    with pytest.raises(ValueError, match=re.escape(msg)):
        buckled_bristle([1.0, 5.0], length=L)
