"""Named fidelity levels: how finely a brush is modelled and solved, as data (issue 12).

A fidelity level is a file ``configs/fidelity/<name>.toml`` with a ``[settings]`` table (what the
level sets) and a ``[measured]`` table that ``brush-env bench fidelity --write`` fills in (its
error against ``reference`` and its speed; never edited by hand).  Levels shipped:

=============  ==============================================================================
``reference``  converged: 24 mid-element bodies, 0.125 ms solver steps (validation)
``paper``      the paper's model: its element (Adams FIELD) and 6 bodies, 1 ms
``balanced``   6 mid-element bodies, 1 ms (experiments, design studies)
``coarse``     3 mid-element bodies, 1 ms, one tip-tip sweep (the full chain at its coarsest)
``reduced``    the reduced model: a quasi-static 2-joint chain per bristle, 4 ms
``fast``       the reduced model stepped by the tabulated tip law, 4 ms (RL; every env's default)
=============  ==============================================================================

Use::

    sim = Simulator(scene, level_settings("balanced", dt=4e-3))

A level resolves to one ``SimSettings`` (``settings.py``): every key of its [settings] table is a
``SimSettings`` field of the same name (the bristle model, the bodies per bristle, the solver step,
the element, the integrator, the tip-tip solve, the Newton tolerance).  ``level_settings(level,
**overrides)`` is the one path from a level to the engine: the env, the experiments, the sweeps and
the benches all call it and pass its value to ``Simulator`` unchanged; ``dt`` (the caller's step)
and any other ``SimSettings`` field come from the overrides.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .checks import ConfigError, Limit, check_choice, check_int, check_real, did_you_mean
from .config_files import read_toml, resolve_config

#: the levels shipped in configs/fidelity, most to least accurate
LEVELS = ("reference", "paper", "balanced", "coarse", "reduced", "fast")
#: what a level's [settings] table may set: these SimSettings fields, under their own names
SETTING_KEYS = (
    "model",
    "bodies_per_bristle",
    "max_substep",
    "element",
    "integrator",
    "tip_tip_sweeps",
    "newton_rtol",
    "newton_max_iter",
)
MEASURED_MARK = "# --- measured by `brush-env bench fidelity --write` (not edited by hand) ---"


@dataclass(frozen=True)
class Fidelity:
    """One fidelity level (module docstring).  model: the bristle model ("dfm": the full chain);
    bodies_per_bristle [count]; max_substep [s] the
    longest solver step; element "mid" | "paper"; integrator "bdf2" | "euler"; tip_tip_sweeps
    [count] (1: partners one sweep behind, >1: coupled); newton_rtol [-] relative to each
    bristle's force scale; newton_max_iter [count] Newton iterations per attempt before the
    solver step is halved (these two: None takes ``SimSettings``' default); measured: the
    bench's figures (errors [-], speeds) or empty."""

    name: str
    description: str
    bodies_per_bristle: int
    max_substep: float
    model: str = "dfm"
    element: str = "mid"
    integrator: str = "bdf2"
    tip_tip_sweeps: int = 8
    # None: SimSettings' own default, set at construction (one source: they cannot drift apart)
    newton_rtol: float | None = None
    newton_max_iter: int | None = None
    measured: dict = field(default_factory=dict)
    path: Path | None = None

    def __post_init__(self):
        from .settings import SimSettings

        # a setting the level leaves out takes SimSettings' default (one source of it)
        for key in ("newton_rtol", "newton_max_iter"):
            if getattr(self, key) is None:
                object.__setattr__(self, key, SimSettings.__dataclass_fields__[key].default)
        p = f"fidelity {self.name!r}: settings."
        check_int(p + "bodies_per_bristle", self.bodies_per_bristle, Limit("count", ge=1, le=64))
        # the rest is checked by SimSettings; build one now so a bad file fails at load
        self.settings()

    def settings(self, **overrides: Any):
        """``SimSettings`` of this level; ``overrides`` (e.g. ``dt``) win over the level."""
        from .settings import SimSettings

        kw: dict[str, Any] = dict(
            model=self.model,
            bodies_per_bristle=self.bodies_per_bristle,
            max_substep=self.max_substep,
            element=self.element,
            integrator=self.integrator,
            tip_tip_sweeps=self.tip_tip_sweeps,
            newton_rtol=self.newton_rtol,
            newton_max_iter=self.newton_max_iter,
        )
        kw.update(overrides)
        kw.setdefault("dt", min(1e-3, kw["max_substep"]))
        return SimSettings(**kw)

    def describe(self) -> str:
        """One line: the level's name and what it sets."""
        what = "" if self.model == "dfm" else f" ({self.model} bristle model)"
        return (
            f"{self.name}{what}: {self.bodies_per_bristle} {self.element}-element bodies per "
            "bristle, "
            f"solver steps <= {self.max_substep * 1e3:g} ms ({self.integrator}), tip-tip "
            + ("coupled" if self.tip_tip_sweeps > 1 else "one sweep")
        )


#: levels renamed on 2026-11-27: a script or config still using the old name is told the new one
#: (the old ``fast``, the 3-body chain, is ``coarse``; its name now means the tip table)
RENAMED = {"table": "fast"}


def fidelity_path(name_or_path: str | os.PathLike) -> Path:
    """``configs/fidelity/<name>.toml`` for a bare name, else the path itself
    (``config_files.resolve_config``; the error names the ``fidelity`` key)."""
    if isinstance(name_or_path, str) and name_or_path in RENAMED:
        raise ConfigError(
            f"fidelity = {name_or_path!r}: this level is called {RENAMED[name_or_path]!r} since "
            "2026-11-27 (the 3-body chain that was 'fast' is 'coarse'); known: "
            f"{', '.join(LEVELS)}"
        )
    try:
        return resolve_config("fidelity", name_or_path)
    except ConfigError as e:
        raise ConfigError(f"fidelity = {os.fspath(name_or_path)!r}: {e}") from None


def load_fidelity(name_or_path: str | os.PathLike | Fidelity) -> Fidelity:
    """The fidelity level ``name_or_path`` (a name in configs/fidelity or a TOML path)."""
    if isinstance(name_or_path, Fidelity):
        return name_or_path
    if not isinstance(name_or_path, (str, os.PathLike)):
        raise ConfigError(
            f"fidelity = {name_or_path!r}: must be a level name ({', '.join(LEVELS)}) or a path"
        )
    path = fidelity_path(name_or_path)
    data = read_toml(path)
    unknown = set(data) - {"name", "description", "settings", "measured"}
    if unknown:
        raise ConfigError(
            f"{path}: unknown top-level keys {sorted(unknown)} "
            "(allowed: name, description, [settings], [measured])"
        )
    st = data.get("settings", {})
    bad = set(st) - set(SETTING_KEYS)
    if bad:
        key = sorted(bad)[0]
        raise ConfigError(
            f"{path}: settings.{key} is not a fidelity setting{did_you_mean(key, SETTING_KEYS)} "
            f"(allowed: {', '.join(SETTING_KEYS)})"
        )
    for key in ("bodies_per_bristle", "max_substep"):
        if key not in st:
            raise ConfigError(f"{path}: settings.{key} is missing")
    name = data.get("name", path.stem)
    check_choice(f"{path}: settings.element", st.get("element", "mid"), ("mid", "paper"))
    check_real(f"{path}: settings.max_substep", st["max_substep"], Limit("s", gt=0, le=0.1))
    try:
        return Fidelity(
            name=name,
            description=data.get("description", ""),
            measured=dict(data.get("measured", {})),
            path=path,
            **st,
        )
    except ConfigError as e:
        raise ConfigError(f"{path}: {e}") from None


def level_settings(level, **overrides: Any):
    """The ``SimSettings`` of fidelity ``level`` (a name, a TOML path or a ``Fidelity``) with
    ``overrides`` (``SimSettings`` fields under their own names, e.g. ``dt``, ``max_substep``)
    winning; ``level`` None or "": ``SimSettings`` defaults with the overrides.  The one path from
    a level to the engine (module docstring)."""
    from .settings import SimSettings

    if level is None or level == "":
        return SimSettings(**overrides)
    return load_fidelity(level).settings(**overrides)
