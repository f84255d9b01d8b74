"""Fidelity levels (configs/fidelity, brush_env.engine.fidelity): loading, what each level sets,
clear errors for bad files and names, and the plumbing into the reference experiment and the env.
"""

from __future__ import annotations

import json

import pytest

from brush_env.engine import ConfigError, SimSettings, Simulator, load_fidelity, load_scene
from brush_env.engine.fidelity import LEVELS, SETTING_KEYS


@pytest.mark.parametrize("name", LEVELS)
def test_every_shipped_level_loads_and_sets_what_it_says(name):
    fid = load_fidelity(name)
    s = fid.settings(dt=4e-3)
    assert isinstance(s, SimSettings) and s.dt == 4e-3
    for key in SETTING_KEYS:
        assert getattr(s, key) == getattr(fid, key), key
    # the simulator discretises the brush into the level's bodies from the settings alone
    sim = Simulator(load_scene("flat_plate"), s)
    assert {b.bodies for b in sim.scene.brush.bristles} == {fid.bodies_per_bristle}
    assert sim.model.n_bodies == fid.bodies_per_bristle * sim.model.n_bristles
    assert name in fid.describe()


def test_levels_are_ordered_by_resolution():
    f = {n: load_fidelity(n) for n in LEVELS}
    assert f["reference"].bodies_per_bristle > f["balanced"].bodies_per_bristle
    assert f["balanced"].bodies_per_bristle > f["coarse"].bodies_per_bristle
    assert f["coarse"].model == "dfm" and f["fast"].model == "table"
    assert f["reference"].max_substep < f["balanced"].max_substep
    assert f["paper"].element == "paper" and f["paper"].bodies_per_bristle == 6  # paper §3


def test_reference_level_is_the_stored_converged_reference():
    """The level named ``reference`` is what the stored converged flat-plate turn was run with."""
    from brush_env.bench.element import load_reference

    meta = load_reference()["settings"]
    meta = json.loads(meta) if isinstance(meta, str) else meta
    ref = load_fidelity("reference")
    assert meta["bodies"] == ref.bodies_per_bristle
    assert meta["dt"] == ref.max_substep
    assert meta["element"] == ref.element and meta["integrator"] == ref.integrator
    assert meta["tip_tip_sweeps"] == ref.tip_tip_sweeps


@pytest.mark.parametrize(
    "text, needle",
    [
        ("[settings]\nbodies_per_bristle = 3\nmax_substep = 1e-3\nbodys = 2\n", "settings.bodys"),
        ("[settings]\nmax_substep = 1e-3\n", "settings.bodies_per_bristle is missing"),
        ("[settings]\nbodies_per_bristle = 0\nmax_substep = 1e-3\n", "bodies_per_bristle"),
        (
            "[settings]\nbodies_per_bristle = 3\nmax_substep = 1e-3\nnewton_max_iter = 0\n",
            "newton_max_iter",
        ),
        ("[settings]\nbodies_per_bristle = 3\nmax_substep = 0.5\n", "max_substep"),
        (
            '[settings]\nbodies_per_bristle = 3\nmax_substep = 1e-3\nelement = "fem"\n',
            "element",
        ),
        ("speed = 3\n[settings]\nbodies_per_bristle = 3\nmax_substep = 1e-3\n", "speed"),
    ],
)
def test_bad_level_file_names_the_key_and_the_value(tmp_path, text, needle):
    p = tmp_path / "mine.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=needle.replace(".", r"\.")):
        load_fidelity(p)


def test_unknown_level_lists_the_known_ones():
    known = "known: balanced, coarse, fast, paper, reduced, reference"
    with pytest.raises(ConfigError, match=f"balansed.*did you mean balanced.*{known}"):
        load_fidelity("balansed")


def test_reference_experiment_runs_at_a_level(tmp_path):
    from brush_env.experiments.run import run_reference

    s = run_reference(
        brush="tiny",
        out_dir=tmp_path,
        turns=0.05,
        dt=5e-3,
        speed=40.0,
        accel=200.0,
        press_time=0.2,
        hold_time=0.05,
        progress=False,
        plots=False,
        fidelity="coarse",
    )
    st = s["settings"]
    assert s["status"] == "ok"
    assert st["fidelity"] == "coarse" and st["bodies"] == [3] and st["tip_tip_sweeps"] == 1
    assert st["max_substep_s"] == load_fidelity("coarse").max_substep


def test_a_renamed_level_names_its_new_name():
    with pytest.raises(ConfigError, match=r"fidelity = 'table': this level is called 'fast' since"):
        load_fidelity("table")
