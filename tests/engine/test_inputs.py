"""Issue 28: inputs that ran (or crashed) before are refused with a ConfigError naming the
parameter, the value and what is allowed (the API side; the CLI side: tests/test_cli_errors.py)."""

from __future__ import annotations

import numpy as np
import pytest

from brush_env.engine import ConfigError, load_brush, load_scene
from brush_env.engine.scene import ContactParams, Cylinder, MeshSurface, Plane, mesh_surface
from brush_env.experiments.plan import check_press_depth, press_range
from brush_env.geometry.meshes import load_mesh_file
from brush_env.geometry.sdf_bake import bake_mesh

from ..test_cli_errors import FILES, SCENE, box_obj


def test_static_friction_below_dynamic_is_refused():
    with pytest.raises(ConfigError, match=r"contact.mu_s = 0.3 is out of range: must be >= "):
        ContactParams(mu_s=0.3)
    assert ContactParams(mu_s=0.76).mu_s == 0.76  # equal is allowed


@pytest.mark.parametrize("bad", [(0, 0, 0), (0, float("nan"), 1), (0, 0, float("inf"))])
def test_zero_or_non_finite_directions_are_refused(bad):
    with pytest.raises(ConfigError, match=r"plane.normal = .* is invalid"):
        Plane(normal=bad)
    with pytest.raises(ConfigError, match=r"cylinder.axis = .* is invalid"):
        Cylinder(axis=bad)


def test_a_non_unit_normal_is_normalised(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text(SCENE.replace("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 2.5]"))
    row = load_scene(p).surfaces[0].kernel_row()
    assert np.allclose(row["b"], [0.0, 0.0, 1.0])
    p.write_text(SCENE.replace("normal = [0.0, 0.0, 1.0]", "normal = [0.0, 0.0, 0.0]"))
    with pytest.raises(ConfigError, match=r"s.toml: surface\[0\].normal = \[0.0, 0.0, 0.0\]"):
        load_scene(p)


def test_overlapping_tip_spheres_are_refused_with_the_pair():
    with pytest.raises(ConfigError) as e:
        load_brush("default", overrides={"tip_radius_mm": 5.0})
    msg = str(e.value)
    # ten pairs tie at 1.6 mm (0-10, 1-11, ...): the first is named
    assert "the tip spheres of bristle 0 (group 'inner', tip_radius_mm = 5)" in msg
    assert "bristle 10 (group 'inner', tip_radius_mm = 5) overlap by 8.4 mm at rest" in msg
    assert "tip_radius_mm <= 0.8 mm" in msg
    assert load_brush("default").min_tip_gap()[0] > 0


@pytest.mark.parametrize("direct", [True, False])
def test_nearest_tips_of_a_lattice(monkeypatch, direct):
    """Tips on a square lattice of pitch 0.25 mm (exact in binary: every neighbour pair ties) with
    radius 0.13 mm overlap by 0.01 mm with each lattice neighbour; the first such pair is
    (0, 1).  Both ways to find the pairs (every distance; scipy's k-d tree for large brushes)
    give it."""
    from types import SimpleNamespace

    from brush_env.engine import config

    monkeypatch.setattr(config, "TIP_PAIRS_DIRECT", 512 if direct else 0)
    xy = [(0.25 * i, 0.25 * j, 0.0) for j in range(5) for i in range(5)]
    up = np.array([0.0, 0.0, 1.0])
    bristles = [SimpleNamespace(root=p, length=6.0, axis=up, tip_radius=0.13) for p in xy]
    gap, i, j = config.BrushConfig.min_tip_gap(SimpleNamespace(bristles=bristles))
    assert gap == pytest.approx(0.25 - 2 * 0.13, abs=1e-12)
    assert (i, j) == (0, 1)


def test_a_scene_syntax_error_names_the_file(tmp_path):
    p = tmp_path / "dup.toml"
    p.write_text(FILES["dup.toml"])
    with pytest.raises(
        ConfigError, match=r"dup.toml: invalid TOML: Cannot overwrite a value \(at line 5"
    ):
        load_scene(p)


@pytest.mark.parametrize("brush", [None, "default"])
def test_a_scene_brush_key_is_checked_even_when_overridden(tmp_path, brush):
    p = tmp_path / "nobrush.toml"
    p.write_text(FILES["nobrush.toml"])
    with pytest.raises(ConfigError, match=r"brush = 'nosuchbrush': brush 'nosuchbrush' is not"):
        load_scene(p, brush=brush)
    p.write_text(SCENE.replace("tip_tip = true", 'tip_tip = "false"'))
    with pytest.raises(ConfigError, match=r"tip_tip = 'false' has the wrong type"):
        load_scene(p, brush=brush)


def test_a_grid_too_large_to_bake_is_refused_before_allocating(tmp_path):
    V = np.array([[0, 0, 0], [150, 0, 0], [0, 150, 0], [0, 0, 150]], float)
    T = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    with pytest.raises(ConfigError, match=r"refused \(use cell_mm >= 0\.\d+"):
        bake_mesh(V, T, 0.15, 1.0)
    with pytest.raises(ConfigError, match=r"~\d+ GiB to bake, more than the 2 GiB allowed"):
        MeshSurface(V, T, 0.15, 1.0)
    (tmp_path / "box150.obj").write_text(FILES["box150.obj"])
    with pytest.raises(ConfigError, match=r"box150.obj': mesh: cell_mm = 0.15 is too fine"):
        mesh_surface(tmp_path / "box150.obj")
    assert MeshSurface(V, T, 1.0, 2.0).cell == 1.0  # coarse enough: accepted


def test_self_intersecting_and_mis_scaled_tooth_meshes_are_refused(tmp_path):
    f = tmp_path / "crossing.obj"
    f.write_text(FILES["crossing.obj"])
    with pytest.raises(ConfigError, match=r"the surface intersects itself \(triangles \d+ and"):
        load_mesh_file(f)
    g = tmp_path / "arch_cm.obj"
    g.write_text(FILES["arch_cm.obj"])
    load_mesh_file(g)  # as a generic surface 5 x 1 x 1 mm is a plausible size
    with pytest.raises(ConfigError, match=r"read as 'cm' it would be 10 mm \(--mesh-units cm\)"):
        load_mesh_file(g, tooth=True)
    V, _ = load_mesh_file(g, "cm", tooth=True)
    assert np.ptp(V, axis=0).tolist() == pytest.approx([50.0, 10.0, 10.0])
    h = tmp_path / "apart.obj"  # two boxes side by side: closed, no crossing
    h.write_text(box_obj((6.0, 6.0, 6.0), ((0, 0, 0), (8.0, 0, 0))))
    load_mesh_file(h, tooth=True)


def test_press_depth_must_stay_below_the_free_length():
    brush = load_brush("default")
    assert press_range(brush) == pytest.approx((10.0, 10.44))
    assert check_press_depth(3.0, brush) == 3.0
    for bad in (15.0, 10.0, -1.0, float("nan")):
        with pytest.raises(ConfigError, match=r"press_depth = .* must be >= 0 and < 10 \(mm\)"):
            check_press_depth(bad, brush)


def test_run_reference_refuses_a_deep_press_before_writing(tmp_path):
    from brush_env.experiments import run_reference

    with pytest.raises(ConfigError, match=r"press_depth = 15.0 is out of range"):
        run_reference(out_dir=tmp_path / "out", press_depth=15.0, turns=0.01, progress=False)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    "v, w, match",
    [
        ((np.nan, 0.0, 0.0), (0.0, 0.0, 0.0), r"v = \[nan, 0.0, 0.0\]: must be finite"),
        ((0.0, np.inf, 0.0), (0.0, 0.0, 0.0), r"v = \[0.0, inf, 0.0\]: must be finite"),
        ((3000.0, 0.0, 0.0), (0.0, 0.0, 0.0), r"\|v\| = 3000 mm/s up to settings.max_tcp_speed"),
        ((0.0, 0.0, 0.0), (0.0, np.nan, 0.0), r"w = \[0.0, nan, 0.0\]: must be finite"),
    ],
)
def test_a_rollout_refuses_a_non_finite_or_too_fast_twist(v, w, match):
    """``Simulator.rollout`` checks the twist before any step: a NaN or inf entry or a speed
    above the settings' limit is refused naming the parameter, its value and the limit, and the
    state is untouched."""
    from brush_env.engine import Simulator
    from brush_env.engine.fidelity import level_settings
    from brush_env.motion import R0

    s = Simulator(load_scene("flat_plate"), level_settings("fast", dt=4e-3))
    s.reset(np.array([0.0, 0.0, s.touch_height(R0) + 1.0]), R0)
    tips = s.bristles.tips.copy()
    with pytest.raises(ValueError, match=match):
        s.rollout(np.array(v), np.array(w), 3)
    assert np.array_equal(s.bristles.tips, tips) and s.state.steps == 0
