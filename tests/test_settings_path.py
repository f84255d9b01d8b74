"""One settings path (issue 27): every way of running at a fidelity level -- ``gym.make(...,
fidelity=L)``, ``brush-env reference --fidelity L``, a sweep at L, ``bench fidelity`` and
``bench steps`` -- hands the simulator the same ``SimSettings`` (the caller's own step ``dt``
and the env's gravity switch aside), and every key of every level's [settings] table arrives
under its own name, ``newton_rtol`` included.

The settings are caught where they enter the engine: ``Simulator.__init__`` is replaced by one
that records them and stops the caller (a ``BaseException``, so no ``except Exception`` of the
callers swallows it), so nothing is stepped.  A kernel warm-up that runs inside a caller (a cold
cache: each path compiles its level's groups first) builds its own tiny Simulators; those pass
through to the real constructor and are not recorded.
"""

from __future__ import annotations

import dataclasses
import sys
from pathlib import Path

import pytest
import tomllib

from brush_env.engine import simulator, warmup
from brush_env.engine.fidelity import LEVELS, SETTING_KEYS, fidelity_path


class _Stop(BaseException):
    pass


@pytest.fixture
def caught(monkeypatch):
    seen = []
    real = simulator.Simulator.__init__

    def init(self, scene, settings=None):
        if _in_warm_up():
            return real(self, scene, settings)
        seen.append(settings)
        raise _Stop

    monkeypatch.setattr(simulator.Simulator, "__init__", init)
    return seen


def _in_warm_up() -> bool:
    """Whether the Simulator being built is the kernel warm-up's (engine/warmup.py on the stack)."""
    f = sys._getframe(1)
    while f is not None:
        if f.f_globals.get("__name__") == warmup.__name__:
            return True
        f = f.f_back
    return False


def _one(seen, fn):
    with pytest.raises(_Stop):
        fn()
    assert len(seen) >= 1
    return seen.pop()


def _by_env(level):
    import gymnasium as gym

    import brush_env  # noqa: F401

    return gym.make("brush_env/FlatPlate-v0", fidelity=level)


def _by_cli(level, tmp):
    from brush_env.cli import main

    return main(["reference", "--fidelity", level, "--out", str(tmp), "--turns", "0.01"])


def _by_sweep(level, tmp):
    from brush_env.sweeps.run import execute, prepare
    from brush_env.sweeps.spec import load_spec

    tmp.mkdir(parents=True, exist_ok=True)
    p = tmp / "s.toml"
    p.write_text(
        f'name = "one"\nbrush = "tiny"\nfidelity = "{level}"\nmotions = ["circle"]\n'
        '[sample]\nmethod = "grid"\n[[vary]]\nkey = "material.E_MPa"\nvalues = [7.0]\n'
    )
    spec = load_spec(p)
    return execute(prepare(spec, spec.runs()[0], tmp / "out"))


def _by_bench_fidelity(level):
    from brush_env.bench.fidelity import turn_run

    return turn_run(level, quick=True)


def _by_bench_steps(level):
    import argparse

    from brush_env.bench.steps import bench_steps

    return bench_steps(
        argparse.Namespace(
            json=True,
            callgrind=False,
            scene="flat_plate",
            motion="scrub",
            fidelity=level,
            strokes=1,
            bodies=None,
            sweeps=None,
            window=None,
            symbols=None,
        )
    )


def _same_but_step(s):
    """The settings with the caller's step and gravity set aside."""
    return dataclasses.replace(s, dt=1e-3, gravity=(0.0, 0.0, 0.0))


@pytest.mark.parametrize("level", LEVELS)
def test_every_path_builds_the_same_settings_and_every_level_key_arrives(level, caught, tmp_path):
    got = {
        "gym.make": _one(caught, lambda: _by_env(level)),
        "brush-env reference": _one(caught, lambda: _by_cli(level, tmp_path / "ref")),
        "sweep": _one(caught, lambda: _by_sweep(level, tmp_path / "sweep")),
        "bench fidelity": _one(caught, lambda: _by_bench_fidelity(level)),
        "bench steps": _one(caught, lambda: _by_bench_steps(level)),
    }
    table = tomllib.loads(Path(fidelity_path(level)).read_text())["settings"]
    assert set(table) <= set(SETTING_KEYS)
    for path, s in got.items():
        for key, value in table.items():  # every key of the level, under its own name
            assert getattr(s, key) == value, f"{path}: {key}"
    first = _same_but_step(got["gym.make"])
    for path, s in got.items():
        assert _same_but_step(s) == first, path


def test_env_overrides_use_the_engine_names_and_win_over_the_level(caught):
    import gymnasium as gym

    import brush_env  # noqa: F401

    s = _one(
        caught,
        lambda: gym.make(
            "brush_env/FlatPlate-v0",
            fidelity="balanced",
            engine_settings={"max_substep": 2e-3, "newton_rtol": 1e-8},
        ),
    )
    assert (s.max_substep, s.newton_rtol, s.bodies_per_bristle) == (2e-3, 1e-8, 6)


def test_env_refuses_an_engine_setting_it_owns_or_does_not_know():
    from brush_env.engine import ConfigError
    from brush_env.envs.config import EnvConfig

    with pytest.raises(ConfigError, match="engine_settings.dt .*engine_dt"):
        EnvConfig(engine_settings={"dt": 1e-3})
    with pytest.raises(ConfigError, match="engine_settings.max_substp .*did you mean max_substep"):
        EnvConfig(engine_settings={"max_substp": 1e-3})
    with pytest.raises(ConfigError, match="settings.newton_rtol = 0.5"):
        EnvConfig(engine_settings={"newton_rtol": 0.5})
