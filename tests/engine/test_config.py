"""Config loading and validation (brush_env.engine.config). Units: mm, MPa, t/mm^3, rad."""

import dataclasses
import math

import numpy as np
import pytest

from brush_env.engine.config import (
    BristleConfig,
    BrushConfig,
    ConfigError,
    Material,
    Section,
    configs_dir,
    load_brush,
    load_materials,
)

# A small valid brush using every entry kind; the error tests break one line of it at a time.
BRUSH = """\
name = "t"
material = "silicone_7MPa"
bodies_per_bristle = 6
tip_radius_mm = 0.44

[sections.inner]
kind = "rect"
width_mm = 1.8
thickness_mm = 0.8

[sections.round]
kind = "circle"
diameter_mm = 0.5

[[grid]]
section = "inner"
length_mm = 9.0
nx = 2
ny = 2
pitch_x_mm = 2.2
pitch_y_mm = 1.6
center_mm = [0.0, 0.0]

[[row]]
section = "round"
length_mm = 8.0
n = 3
start_mm = [-2.0, 3.0]
step_mm = [2.0, 0.0]

[[bristle]]
section = "inner"
length_mm = 10.0
root_mm = [0.0, -3.0, 0.0]
axis = [0.0, 0.2, 1.0]
width_dir = [1.0, 0.0, 0.0]
material = "nylon_PA612"
bodies = 4
tip_radius_mm = 0.3
name = "tilted"
"""

MATERIALS = """\
[soft]
E_MPa = 7.0
nu = 0.48
density_t_per_mm3 = 1.15e-9
damping_ratio = 0.1
"""


def _edit(text, old, new):
    assert text.count(old) == 1, f"test setup: {old!r} must occur once"
    return text.replace(old, new)


def brush_error(tmp_path, old, new):
    """Load BRUSH with one line changed; return the ConfigError message."""
    path = tmp_path / "bad.toml"
    path.write_text(_edit(BRUSH, old, new))
    with pytest.raises(ConfigError) as e:
        load_brush(path)
    return str(e.value)


def material_error(tmp_path, old, new):
    path = tmp_path / "materials.toml"
    path.write_text(_edit(MATERIALS, old, new))
    with pytest.raises(ConfigError) as e:
        load_materials(path)
    return str(e.value)


# ---------------------------------------------------------------------------------------------
# The shipped configs
# ---------------------------------------------------------------------------------------------
def test_default_brush_layout():
    brush = load_brush()
    assert brush.name == "default" and brush.n_bristles == 40
    assert brush.source.endswith("default.toml")
    inner = [b for b in brush.bristles if b.group == "inner"]
    outer = [b for b in brush.bristles if b.group == "outer"]
    assert len(inner) == len(outer) == 20
    for group, (w, h, length) in ((inner, (1.8, 0.8, 9.0)), (outer, (1.3, 0.8, 10.0))):
        for b in group:
            assert b.section == Section.rect(w, h) and b.length == length
            assert b.bodies == 6 and b.tip_radius == 0.44
            assert b.material.name == "silicone_7MPa" and b.material.E == 7.0
            assert b.axis == (0.0, 0.0, 1.0) and b.width_dir == (1.0, 0.0, 0.0)
    assert brush.max_length == 10.0
    roots = np.array([b.root for b in brush.bristles])
    assert np.all(roots[:, 2] == 0.0)
    assert sorted({round(y, 9) for y in roots[:, 1]}) == [-2.4, -0.8, 0.8, 2.4]
    xs = np.sort(np.unique(roots[:, 0].round(9)))
    np.testing.assert_allclose(xs, 2.2 * (np.arange(10) - 4.5), atol=1e-12)
    # symmetric about both head axes: mirroring maps the root set (with its groups) onto itself
    key = {(round(x, 9), round(y, 9), b.group) for (x, y, _), b in zip(roots, brush.bristles)}
    assert key == {(round(-x, 9) + 0.0, y, g) for x, y, g in key}
    assert key == {(x, round(-y, 9) + 0.0, g) for x, y, g in key}
    np.testing.assert_allclose(brush.roots_tcp(), roots)  # head frame == TCP frame by default


def test_default_layout_leaves_gaps_between_sections():
    gap, i, j = load_brush().min_root_gap()
    assert gap == pytest.approx(0.4)  # inner sections along x: 2.2 - 1.8 mm
    assert {load_brush().bristles[k].group for k in (i, j)} == {"inner"}
    # the thicker-outer variant still leaves 0.4 mm (x) and 0.7 mm (y, inner-outer)
    assert load_brush("default_outer_1p0").min_root_gap()[0] == pytest.approx(0.4)


def test_default_outer_1p0_changes_one_number():
    a, b = load_brush("default"), load_brush("default_outer_1p0")
    assert b.name == "default_outer_1p0" and a.n_bristles == b.n_bristles
    for x, y in zip(a.bristles, b.bristles):
        if x.group == "outer":
            assert y.section == Section.rect(1.3, 1.0)
            y = dataclasses.replace(y, section=x.section)
        assert x == y


def test_shipped_materials():
    mats = load_materials()
    assert set(mats) >= {"silicone_7MPa", "silicone_7GPa_printed", "nylon_PA612"}
    soft, printed = mats["silicone_7MPa"], mats["silicone_7GPa_printed"]
    assert (soft.E, soft.nu, soft.density, soft.damping_ratio) == (7.0, 0.48, 1.15e-9, 0.1)
    assert printed.E == 7000.0 and printed.density == soft.density and printed.nu == soft.nu
    assert mats["nylon_PA612"].E == 3000.0
    assert all(m.description for m in mats.values())


def test_all_entry_kinds_and_per_group_overrides(tmp_path):
    path = tmp_path / "b.toml"
    path.write_text(BRUSH)
    brush = load_brush(path)
    assert brush.n_bristles == 4 + 3 + 1
    grid, row, (tilted,) = brush.bristles[:4], brush.bristles[4:7], brush.bristles[7:]
    assert [b.root for b in grid] == [
        (-1.1, -0.8, 0.0),
        (1.1, -0.8, 0.0),
        (-1.1, 0.8, 0.0),
        (1.1, 0.8, 0.0),
    ]
    assert [b.root for b in row] == [(-2.0, 3.0, 0.0), (0.0, 3.0, 0.0), (2.0, 3.0, 0.0)]
    assert row[0].section == Section.circle(0.5) and row[0].group == "row[0]"
    assert tilted.group == "tilted" and tilted.material.name == "nylon_PA612"
    assert tilted.bodies == 4 and tilted.tip_radius == 0.3
    np.testing.assert_allclose(tilted.axis, np.array([0.0, 0.2, 1.0]) / math.hypot(0.2, 1.0))
    assert np.dot(tilted.axis, tilted.width_dir) == pytest.approx(0.0, abs=1e-15)


def test_width_dir_is_orthogonalised_against_axis(tmp_path):
    text = _edit(BRUSH, "width_dir = [1.0, 0.0, 0.0]", "width_dir = [2.0, 0.0, 3.0]")
    (tmp_path / "b.toml").write_text(text)
    b = load_brush(tmp_path / "b.toml").bristles[-1]
    assert np.linalg.norm(b.width_dir) == pytest.approx(1.0)
    assert np.dot(b.axis, b.width_dir) == pytest.approx(0.0, abs=1e-15)
    assert np.cross(b.axis, b.width_dir) == pytest.approx(b.thickness_dir)


def test_overrides_nested_and_dotted():
    brush = load_brush(
        "default",
        overrides={
            "bodies_per_bristle": 3,
            "sections.outer.thickness_mm": 1.0,
            "grid[0]": {"length_mm": 8.5},
            "head_rpy_deg": [0.0, 0.0, 90.0],
        },
    )
    assert {b.bodies for b in brush.bristles} == {3}
    assert {b.section.thickness for b in brush.bristles if b.group == "outer"} == {1.0}
    assert {b.length for b in brush.bristles if b.group == "inner"} == {8.5}
    assert "overrides" in brush.source
    with pytest.raises(ConfigError, match=r"index \[5\] does not exist \(2 entries\)"):
        load_brush(overrides={"grid[5].length_mm": 1.0})
    with pytest.raises(ConfigError, match=r"brush.grid\[1\].length_mm = -1.0 is out of range"):
        load_brush(overrides={"grid[1].length_mm": -1.0})


def test_materials_argument_and_helpers():
    nylon = load_materials()["nylon_PA612"]
    brush = load_brush(materials={"silicone_7MPa": nylon})  # a name -> Material mapping
    assert {b.material for b in brush.bristles} == {nylon}
    soft = load_brush().with_material(load_materials()["silicone_7MPa"])
    assert {b.material.name for b in soft.bristles} == {"silicone_7MPa"}
    assert {b.bodies for b in soft.with_bodies(12).bristles} == {12}
    with pytest.raises(ConfigError, match=r"BristleConfig.bodies = 0 is out of range"):
        soft.with_bodies(0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        soft.name = "x"


def test_head_pose_in_tcp_frame():
    yaw90 = load_brush(overrides={"head_offset_mm": [1.0, 2.0, 3.0], "head_rpy_deg": [0, 0, 90]})
    R = yaw90.head_rotation()
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(R @ [1.0, 0, 0], [0, 1.0, 0], atol=1e-15)
    b0 = yaw90.bristles[0]
    np.testing.assert_allclose(yaw90.roots_tcp()[0], [1.0 - b0.root[1], 2.0 + b0.root[0], 3.0])
    np.testing.assert_allclose(yaw90.width_dirs_tcp()[0], [0, 1.0, 0], atol=1e-15)
    # R = Rz(yaw) Ry(pitch) Rx(roll): roll 90 deg then yaw 90 deg sends head z to TCP x
    rz = load_brush(overrides={"head_rpy_deg": [90, 0, 90]})
    np.testing.assert_allclose(rz.axes_tcp()[0], [1.0, 0, 0], atol=1e-15)


def test_configs_dir_env(monkeypatch, tmp_path):
    assert (configs_dir() / "brushes" / "default.toml").is_file()
    (tmp_path / "brushes").mkdir()
    (tmp_path / "brushes" / "mine.toml").write_text(BRUSH)
    (tmp_path / "materials.toml").write_text((configs_dir() / "materials.toml").read_text())
    monkeypatch.setenv("BRUSH_ENV_CONFIGS", str(tmp_path))
    assert configs_dir() == tmp_path and load_brush("mine").n_bristles == 8
    with pytest.raises(ConfigError, match=r"'nope' is not a known brush.*\(known: mine\)"):
        load_brush("nope")


# ---------------------------------------------------------------------------------------------
# Section and material properties against hand formulas
# ---------------------------------------------------------------------------------------------
def test_rect_section_properties():
    b, h = 1.8, 0.8
    s = Section.rect(b, h)
    assert s.area == pytest.approx(b * h)
    assert s.I_y == pytest.approx(b * h**3 / 12)  # deflection along local z (thickness)
    assert s.I_z == pytest.approx(h * b**3 / 12)
    assert s.polar_radius_sq == pytest.approx((s.I_y + s.I_z) / s.area)
    assert s.shear_coeff(0.3) == pytest.approx(10 * 1.3 / (12 + 3.3))
    assert Section.rect(h, b).J == pytest.approx(s.J)  # J does not care which side is which
    # thin-strip limit: J -> b h^3 / 3 as h/b -> 0
    assert Section.rect(20.0, 0.1).J == pytest.approx(20 * 0.1**3 / 3, rel=0.01)


def test_square_torsion_constant():
    a = 0.8
    assert Section.rect(a, a).J == pytest.approx(0.1406 * a**4, rel=2e-3)


def test_circle_section_properties():
    d = 0.6
    s = Section.circle(d)
    assert s.width == s.thickness == d
    assert s.area == pytest.approx(math.pi * d**2 / 4)
    assert s.I_y == s.I_z == pytest.approx(math.pi * d**4 / 64)
    assert s.J == pytest.approx(2 * s.I_y)
    assert s.polar_radius_sq == pytest.approx(d**2 / 8) == pytest.approx(2 * s.I_y / s.area)
    assert s.shear_coeff(0.3) == pytest.approx(6 * 1.3 / (7 + 1.8))


def test_material_shear_modulus():
    m = Material("m", E=7.0, nu=0.48, density=1.15e-9, damping_ratio=0.1)
    assert m.G == pytest.approx(7.0 / 2.96)


def test_constructors_validate_too():
    with pytest.raises(ConfigError, match=r"Material\('m'\).E = -1.0 is out of range"):
        Material("m", E=-1.0, nu=0.3, density=1e-9, damping_ratio=0.1)
    with pytest.raises(ConfigError, match=r"Section.kind = 'hex' is not allowed"):
        Section("hex", 1.0, 1.0)
    with pytest.raises(ConfigError, match=r"thickness = 2.0 must equal width = 1.0 for a circle"):
        Section("circle", 1.0, 2.0)
    m = Material("m", E=7.0, nu=0.48, density=1.15e-9, damping_ratio=0.1)
    with pytest.raises(ConfigError, match=r"BristleConfig.length = 0.0 is out of range"):
        BristleConfig((0, 0, 0), (0, 0, 1), (1, 0, 0), 0.0, Section.circle(1.0), m, 6, 0.4)
    with pytest.raises(ConfigError, match=r"BrushConfig.bristles is empty"):
        BrushConfig("b", (0, 0, 0), (0, 0, 0), ())


# ---------------------------------------------------------------------------------------------
# One test per error path: the message names the key path, the value and the allowed range
# ---------------------------------------------------------------------------------------------
def test_unknown_brush_key(tmp_path):
    msg = brush_error(tmp_path, "length_mm = 9.0", "lenght_mm = 9.0")
    assert "brush.grid[0]: unknown key 'lenght_mm' (allowed: section, length_mm, nx," in msg
    assert str(tmp_path / "bad.toml") in msg  # and the file


def test_unknown_top_level_key(tmp_path):
    msg = brush_error(tmp_path, 'name = "t"', 'name = "t"\nbodies_per_bristel = 3')
    assert "brush: unknown key 'bodies_per_bristel' (allowed: name, material," in msg


def test_unknown_material_key(tmp_path):
    msg = material_error(tmp_path, "E_MPa = 7.0", "E_Mpa = 7.0")
    assert (
        "material 'soft': unknown key 'E_Mpa' (allowed: E_MPa, nu, density_t_per_mm3, "
        "damping_ratio, description)"
    ) in msg


def test_unknown_section_key_for_kind(tmp_path):
    msg = brush_error(tmp_path, "diameter_mm = 0.5", "width_mm = 0.5")
    assert "brush.sections.round: unknown key 'width_mm' (allowed: kind, diameter_mm)" in msg


def test_missing_key(tmp_path):
    msg = brush_error(tmp_path, "length_mm = 9.0\n", "")
    assert (
        "brush.grid[0]: missing required key 'length_mm' "
        "(a number that must be > 0 and <= 100 (mm))"
    ) in msg


def test_missing_material_key(tmp_path):
    msg = material_error(tmp_path, "nu = 0.48\n", "")
    assert "material 'soft': missing required key 'nu'" in msg and "> -1 and < 0.5" in msg


def test_missing_pitch_when_needed(tmp_path):
    msg = brush_error(tmp_path, "pitch_x_mm = 2.2\n", "")
    assert "brush.grid[0]: missing required key 'pitch_x_mm'" in msg


def test_wrong_type_string_for_number(tmp_path):
    msg = brush_error(tmp_path, "length_mm = 9.0", 'length_mm = "9.0"')
    assert (
        "brush.grid[0].length_mm = '9.0' has the wrong type: expected a number (mm), got str" in msg
    )


def test_wrong_type_float_for_integer(tmp_path):
    msg = brush_error(tmp_path, "bodies_per_bristle = 6", "bodies_per_bristle = 6.5")
    assert (
        "brush.bodies_per_bristle = 6.5 has the wrong type: expected an integer (count), got float"
    ) in msg


def test_wrong_type_vector_length(tmp_path):
    msg = brush_error(tmp_path, "center_mm = [0.0, 0.0]", "center_mm = [0.0]")
    assert "brush.grid[0].center_mm = [0.0] has the wrong type: expected a list of 2 numbers" in msg


def test_wrong_type_table(tmp_path):
    msg = brush_error(tmp_path, "[[row]]", "[row]")
    assert "brush.row = {" in msg and "expected an array of [[row]] tables, got dict" in msg


@pytest.mark.parametrize(
    "old, new, expected",
    [
        (
            "E_MPa = 7.0",
            "E_MPa = 0.0",
            "material 'soft'.E_MPa = 0.0 is out of range: must be > 0 and <= 1e+06 (MPa)",
        ),
        (
            "E_MPa = 7.0",
            "E_MPa = 2e6",
            "material 'soft'.E_MPa = 2000000.0 is out of range: must be > 0 and <= 1e+06 (MPa)",
        ),
        (
            "nu = 0.48",
            "nu = 0.5",
            "material 'soft'.nu = 0.5 is out of range: must be > -1 and < 0.5 (dimensionless)",
        ),
        (
            "density_t_per_mm3 = 1.15e-9",
            "density_t_per_mm3 = 1.15e-6",
            "material 'soft'.density_t_per_mm3 = 1.15e-06 is out of range: "
            "must be > 0 and <= 1e-07 (t/mm^3)",
        ),
        (
            "damping_ratio = 0.1",
            "damping_ratio = -0.1",
            "material 'soft'.damping_ratio = -0.1 is out of range: "
            "must be >= 0 and <= 2 (dimensionless)",
        ),
    ],
    ids=["E_zero", "E_high", "nu", "density", "damping_ratio"],
)
def test_material_range(tmp_path, old, new, expected):
    assert expected in material_error(tmp_path, old, new)


@pytest.mark.parametrize(
    "old, new, expected",
    [
        (
            "width_mm = 1.8",
            "width_mm = 0.0",
            "brush.sections.inner.width_mm = 0.0 is out of range: must be > 0 and <= 20 (mm)",
        ),
        (
            "thickness_mm = 0.8",
            "thickness_mm = 25.0",
            "brush.sections.inner.thickness_mm = 25.0 is out of range: must be > 0 and <= 20 (mm)",
        ),
        (
            "diameter_mm = 0.5",
            "diameter_mm = -0.5",
            "brush.sections.round.diameter_mm = -0.5 is out of range: must be > 0 and <= 20 (mm)",
        ),
        (
            "length_mm = 9.0",
            "length_mm = -2.0",
            "brush.grid[0].length_mm = -2.0 is out of range: must be > 0 and <= 100 (mm)",
        ),
        (
            "length_mm = 9.0",
            "length_mm = nan",
            "brush.grid[0].length_mm = nan is out of range: must be > 0 and <= 100 (mm)",
        ),
        (
            "bodies_per_bristle = 6",
            "bodies_per_bristle = 0",
            "brush.bodies_per_bristle = 0 is out of range: must be >= 1 and <= 200 (count)",
        ),
        (
            "bodies = 4",
            "bodies = 201",
            "brush.bristle[0].bodies = 201 is out of range: must be >= 1 and <= 200 (count)",
        ),
        (
            "tip_radius_mm = 0.44",
            "tip_radius_mm = 6.0",
            "brush.tip_radius_mm = 6.0 is out of range: "
            "must be > 0 and <= 5 (mm; at most min(5 mm, bristle length))",
        ),
        (
            "tip_radius_mm = 0.3",
            "tip_radius_mm = 0.0",
            "brush.bristle[0].tip_radius_mm = 0.0 is out of range: must be > 0 and <= 5 (mm;",
        ),
        (
            "length_mm = 8.0",
            "length_mm = 0.4",  # inherited tip radius 0.44 > bristle length
            "brush.tip_radius_mm (used by brush.row[0]) = 0.44 is out of range: "
            "must be > 0 and <= 0.4 (mm; at most min(5 mm, bristle length))",
        ),
        (
            "pitch_x_mm = 2.2",
            "pitch_x_mm = 0.0",
            "brush.grid[0].pitch_x_mm = 0.0 is out of range: must be > 0 and <= 50 (mm)",
        ),
        (
            "pitch_y_mm = 1.6",
            "pitch_y_mm = 60.0",
            "brush.grid[0].pitch_y_mm = 60.0 is out of range: must be > 0 and <= 50 (mm)",
        ),
        (
            "nx = 2",
            "nx = 0",
            "brush.grid[0].nx = 0 is out of range: must be >= 1 and <= 1000 (count)",
        ),
        (
            'name = "t"',
            'name = "t"\nhead_rpy_deg = [0, 400, 0]',
            "brush.head_rpy_deg[1] = 400.0 is out of range: must be >= -360 and <= 360 (deg)",
        ),
        (
            "root_mm = [0.0, -3.0, 0.0]",
            "root_mm = [0.0, -300.0, 0.0]",
            "brush.bristle[0].root_mm[1] = -300.0 is out of range: "
            "must be >= -100 and <= 100 (mm, head frame)",
        ),
    ],
    ids=[
        "width",
        "thickness",
        "diameter",
        "length",
        "length_nan",
        "bodies_top",
        "bodies_group",
        "tip_radius_top",
        "tip_radius_group",
        "tip_radius_vs_length",
        "pitch_x",
        "pitch_y",
        "count",
        "head_angle",
        "root_position",
    ],
)
def test_brush_range(tmp_path, old, new, expected):
    assert expected in brush_error(tmp_path, old, new)


def test_unknown_material_name(tmp_path):
    msg = brush_error(tmp_path, 'material = "nylon_PA612"', 'material = "nylon"')
    assert (
        "brush.bristle[0].material = 'nylon' is not a known material "
        "(known: silicone_7MPa, silicone_7GPa_printed, nylon_PA612)"
    ) in msg


def test_unknown_section_name(tmp_path):
    msg = brush_error(tmp_path, 'section = "round"', 'section = "rond"')
    assert "brush.row[0].section = 'rond' is not a known section (known: inner, round)" in msg


def test_unknown_section_kind(tmp_path):
    msg = brush_error(tmp_path, 'kind = "circle"', 'kind = "hexagon"')
    assert (
        "brush.sections.round.kind = 'hexagon' is not a known section kind (known: rect, circle)"
    ) in msg


def test_axis_parallel_to_width_dir(tmp_path):
    msg = brush_error(tmp_path, "axis = [0.0, 0.2, 1.0]", "axis = [-2.0, 0.0, 0.0]")
    assert (
        "brush.bristle[0].width_dir = [1.0, 0.0, 0.0] is invalid: must not be parallel to "
        "axis = [-2.0, 0.0, 0.0]"
    ) in msg


def test_zero_axis(tmp_path):
    msg = brush_error(tmp_path, "axis = [0.0, 0.2, 1.0]", "axis = [0.0, 0.0, 0.0]")
    assert "brush.bristle[0].axis = [0.0, 0.0, 0.0] is invalid: must be a non-zero 3-vector" in msg


def test_overlapping_sections(tmp_path):
    msg = brush_error(tmp_path, "pitch_x_mm = 2.2", "pitch_x_mm = 1.7")  # < 1.8 mm width
    assert "bristle 0 (group 'grid[0]')" in msg and "bristle 1 (group 'grid[0]')" in msg
    assert "overlap at the root: clearance = -0.1, must be > 0 (mm)" in msg


def test_overlapping_circles(tmp_path):
    msg = brush_error(tmp_path, "step_mm = [2.0, 0.0]", "step_mm = [0.4, 0.0]")  # < 0.5 mm diameter
    assert "(group 'row[0]')" in msg and "clearance = -0.1, must be > 0 (mm)" in msg


def test_root_gap_of_rotated_sections():
    m = Material("m", E=7.0, nu=0.48, density=1.15e-9, damping_ratio=0.1)
    sq = Section.rect(1.0, 1.0)
    diag = (1.0, 1.0, 0.0)  # squares turned by 45 deg: half-diagonal sqrt(0.5) along x

    def pair(dx, wd):
        return BrushConfig(
            "b",
            (0, 0, 0),
            (0, 0, 0),
            tuple(
                BristleConfig((x, 0.0, 0.0), (0, 0, 1), wd, 5.0, sq, m, 6, 0.4) for x in (0.0, dx)
            ),
        )

    assert pair(1.5, (1, 0, 0)).min_root_gap() == pytest.approx((0.5, 0, 1))
    assert pair(1.5, diag).min_root_gap()[0] == pytest.approx(1.5 - 2 * math.sqrt(0.5))
    assert pair(1.3, diag).min_root_gap()[0] < 0


def test_invalid_toml(tmp_path):
    msg = brush_error(tmp_path, "nx = 2", "nx = = 2")
    assert "bad.toml: invalid TOML" in msg


def test_unknown_brush_name():
    with pytest.raises(ConfigError, match=r"'nope' is not a known brush.*known: default"):
        load_brush("nope")
