"""Env settings: ``configs/envs/<name>.toml`` plus keyword overrides -> a frozen ``EnvConfig``.

Every setting is a typed field of :class:`EnvConfig` with a default, a unit, an allowed range and
a one-line meaning (``FIELDS`` holds them; ``arguments_table()`` prints them as the Arguments
table of the env docs).  The TOML file groups the same names into sections (``[engine]``,
``[action]``, ...); ``gym.make(id, **overrides)`` takes them as flat keywords::

    gym.make("brush_env/FlatPlate-v0", frame_skip=5, action_mode="3d", patch_size=40.0)

A misspelled or out-of-range setting raises :class:`~brush_env.engine.ConfigError` naming the
parameter, the value and what is allowed (with close matches for unknown names).  Units: mm, N,
s, rad/s, degrees where a name ends in ``_deg``.
"""

from __future__ import annotations

import math
import numbers
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import tomllib

from brush_env.engine.checks import ConfigError, Limit, did_you_mean, type_error
from brush_env.engine.config_files import resolve_config

__all__ = ["EnvConfig", "FIELDS", "SECTIONS", "load_env_config", "arguments_table"]

SECTIONS = ("engine", "action", "observation", "patch", "reward", "episode", "reset", "render")


def _f(
    default, section, unit, doc, *, lo=None, hi=None, lo_open=False, hi_open=False, choices=None
):
    """A config field: default, TOML section, unit, meaning and allowed range or choices."""
    meta = dict(
        section=section,
        unit=unit,
        doc=doc,
        lo=lo,
        hi=hi,
        lo_open=lo_open,
        hi_open=hi_open,
        choices=choices,
    )
    if isinstance(default, dict):
        return field(default_factory=dict, metadata=meta)
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class EnvConfig:
    """All settings of :class:`~brush_env.envs.flat_plate.BrushEnv` (see the module docstring).

    Validated on construction; ``EnvConfig(**kw)`` and :func:`load_env_config` raise
    ``ConfigError`` on bad values.  Vectors are tuples.
    """

    # --- engine -------------------------------------------------------------------------------
    fidelity: str = _f(
        "fast",
        "engine",
        "-",
        "fidelity level (configs/fidelity: reference, paper, balanced, coarse, reduced, fast) or "
        "a TOML path: the "
        "engine settings (bristle model, bodies, solver step, element, integrator, tip-tip "
        "solve, Newton tolerance); empty: the engine's defaults",
    )
    engine_settings: dict = _f(
        {},
        "engine",
        "-",
        "engine settings that replace the level's, under the engine's own names (SimSettings "
        "fields, e.g. {max_substep = 0.004, bodies_per_bristle = 6}); not dt or gravity, which "
        "are the env's engine_dt and gravity",
    )
    brush: str = _f("default", "engine", "-", "brush: a name in configs/brushes or a TOML path")
    scene: str = _f(
        "flat_plate",
        "engine",
        "-",
        "scene: a name in configs/scenes or a TOML path (one plane, normal +z)",
    )
    engine_dt: float = _f(
        0.004,
        "engine",
        "s",
        "engine time step (SimSettings.dt; the level's max_substep splits it into solver steps)",
        lo=0.0,
        hi=0.02,
        lo_open=True,
    )
    frame_skip: int = _f(
        10, "engine", "count", "engine steps per action (control step)", lo=1, hi=1000
    )
    gravity: bool = _f(True, "engine", "-", "gravity on the bristles (-z, 9810 mm/s^2)")
    tip_tip: str = _f(
        "scene",
        "engine",
        "-",
        "tip-tip contact (Table 3): scene = the scene file's setting, on, off",
        choices=("scene", "on", "off"),
    )
    # --- action -------------------------------------------------------------------------------
    action_mode: str = _f(
        "6d",
        "action",
        "-",
        "6d: linear + angular TCP velocity; 3d: linear only",
        choices=("6d", "3d"),
    )
    max_linear_speed: tuple = _f(
        (50.0, 50.0, 20.0),
        "action",
        "mm/s",
        "TCP speed at action +-1 along base x, y, z",
        lo=0.0,
        hi=500.0,
        lo_open=True,
    )
    max_angular_speed: tuple = _f(
        (0.5, 0.5, 1.0),
        "action",
        "rad/s",
        "TCP angular speed at action +-1 about base x, y, z",
        lo=0.0,
        hi=10.0,
        lo_open=True,
    )
    # --- observation --------------------------------------------------------------------------
    observation_mode: str = _f(
        "box",
        "observation",
        "-",
        "box: one flat float32 vector; dict: one Box per block",
        choices=("box", "dict"),
    )
    coarse_map_size: int = _f(
        8, "observation", "cells", "side of the coarse coverage map in the observation", lo=1, hi=64
    )
    tip_velocity_scale: float = _f(
        100.0,
        "observation",
        "mm/s",
        "tip velocity that maps to 1 in the observation",
        lo=0.0,
        hi=1e4,
        lo_open=True,
    )
    force_scale: float = _f(
        10.0, "observation", "N", "TCP force that maps to 1", lo=0.0, hi=1e3, lo_open=True
    )
    moment_scale: float = _f(
        200.0, "observation", "N*mm", "TCP moment that maps to 1", lo=0.0, hi=1e5, lo_open=True
    )
    # --- patch (coverage) ---------------------------------------------------------------------
    patch_size: float = _f(
        64.0,
        "patch",
        "mm",
        "side of the square patch to clean, centred on the plate origin "
        "(default: the 20 mm circle plus the brush footprint)",
        lo=1.0,
        hi=500.0,
    )
    cell_size: float = _f(0.5, "patch", "mm", "side of one coverage cell", lo=0.05, hi=10.0)
    clean_radius: float = _f(
        0.5,
        "patch",
        "mm",
        "cells whose centre lies within this distance of an effective "
        "tip contact point are cleaned (0: the cell under the point)",
        lo=0.0,
        hi=5.0,
    )
    # --- reward -------------------------------------------------------------------------------
    coverage_weight: float = _f(
        100.0, "reward", "1/patch", "reward for cleaning the whole patch", lo=0.0, hi=1e6
    )
    tip_force_window: tuple = _f(
        (0.01, 0.2), "reward", "N", "per-tip normal force [min, max] that cleans", lo=0.0, hi=100.0
    )
    total_force_limit: float = _f(
        4.0,
        "reward",
        "N",
        "safe total normal force (Van der Weijden 1998)",
        lo=0.0,
        hi=1e3,
        lo_open=True,
    )
    total_force_weight: float = _f(
        25.0,
        "reward",
        "1/(N*s)",
        "penalty rate per N of total force above the safe limit",
        lo=0.0,
        hi=1e6,
    )
    tip_force_limit: float = _f(
        0.2, "reward", "N", "safe normal force on one tip", lo=0.0, hi=1e3, lo_open=True
    )
    tip_force_weight: float = _f(
        125.0,
        "reward",
        "1/(N*s)",
        "penalty rate per N of tip force above the tip limit, summed over tips",
        lo=0.0,
        hi=1e6,
    )
    gum_force_limit: float = _f(
        1.0,
        "reward",
        "N",
        "safe total normal force on surfaces labelled 'gum' (ToothRow-v0; no gum on the plate)",
        lo=0.0,
        hi=1e3,
        lo_open=True,
    )
    gum_force_weight: float = _f(
        100.0,
        "reward",
        "1/(N*s)",
        "penalty rate per N of gum force above the gum limit",
        lo=0.0,
        hi=1e6,
    )
    termination_penalty: float = _f(
        10.0, "reward", "-", "one-off penalty when an episode is terminated", lo=0.0, hi=1e6
    )
    # --- episode ------------------------------------------------------------------------------
    max_episode_steps: int = _f(
        300,
        "episode",
        "steps",
        "time limit (gym.make's max_episode_steps takes precedence)",
        lo=1,
        hi=10_000_000,
    )
    hard_force_limit: float = _f(
        15.0,
        "episode",
        "N",
        "total normal force that terminates the episode",
        lo=0.0,
        hi=1e4,
        lo_open=True,
    )
    force_guard: float = _f(
        0.0,
        "episode",
        "N",
        "total normal force after which the TCP backs off (up at max_linear_speed[2]) for the "
        "rest of the control step, as a force-limited robot retracts the tool; 0: off",
        lo=0.0,
        hi=1e4,
    )
    max_penetration: float = _f(
        0.2,
        "episode",
        "mm",
        "tip or shaft penetration at any solver step that terminates the episode",
        lo=0.0,
        hi=10.0,
        lo_open=True,
    )
    workspace_xy: float = _f(
        45.0,
        "episode",
        "mm",
        "half-width of the workspace square about the nominal patch centre",
        lo=1.0,
        hi=1000.0,
    )
    workspace_height: tuple = _f(
        (-5.0, 15.0),
        "episode",
        "mm",
        "[min, max] TCP height above z_t (tips touching the nominal plate)",
        lo=-50.0,
        hi=200.0,
    )
    workspace_edge: str = _f(
        "end",
        "episode",
        "-",
        'at the workspace edge: "end" the episode (termination "workspace"), "stop" the TCP '
        "there (each velocity component limited so the step ends inside, as a robot "
        "controller's workspace limits do; tilt beyond max_tilt_deg still ends it) or "
        '"stop_xy" (x and y stopped, leaving the height range ends it)',
        choices=("end", "stop", "stop_xy"),
    )
    max_tilt_deg: float = _f(
        30.0,
        "episode",
        "deg",
        "largest angle between the bristle axis and -z",
        lo=0.0,
        hi=90.0,
        lo_open=True,
    )
    # --- reset --------------------------------------------------------------------------------
    start_center: tuple = _f(
        (0.0, 0.0),
        "reset",
        "mm",
        "centre of the start positions (x, y) about the nominal patch centre",
        lo=-1000.0,
        hi=1000.0,
    )
    start_xy_range: float = _f(
        5.0, "reset", "mm", "start x, y uniform in centre +- this", lo=0.0, hi=1000.0
    )
    start_height: tuple = _f(
        (1.0, 2.0),
        "reset",
        "mm",
        "start height above z_t (tips touching the nominal plate), uniform in [min, max]",
        lo=-50.0,
        hi=200.0,
    )
    start_yaw_range_deg: float = _f(
        15.0, "reset", "deg", "start yaw about z uniform in +- this", lo=0.0, hi=180.0
    )
    plate_offset_range: tuple = _f(
        (1.0, 1.0, 0.5),
        "reset",
        "mm",
        "plate (and patch) offset from nominal, uniform in +- this per axis x, y, z; not observed",
        lo=0.0,
        hi=100.0,
    )
    # --- render -------------------------------------------------------------------------------
    render_height: int = _f(
        256,
        "render",
        "px",
        "frame height; the frame is 2 x height wide (map | side view)",
        lo=64,
        hi=2048,
    )

    def __post_init__(self) -> None:
        for f in fields(self):
            object.__setattr__(self, f.name, _check(f, getattr(self, f.name)))
        self._cross_checks()

    def sim_settings(self):
        """The engine's ``SimSettings``: the fidelity level with ``engine_settings`` replacing
        its keys, ``engine_dt`` as the step and the env's gravity switch (built once)."""
        return self._sim

    def _cross_checks(self) -> None:
        from brush_env.engine.fidelity import level_settings
        from brush_env.engine.settings import G_EARTH

        gravity = (0.0, 0.0, -G_EARTH) if self.gravity else (0.0, 0.0, 0.0)
        try:  # an unknown level, a bad level file or a bad engine setting names itself
            sim = level_settings(
                self.fidelity, **self.engine_settings, dt=self.engine_dt, gravity=gravity
            )
        except ConfigError as e:
            if self.engine_settings:
                raise ConfigError(f"{e} (engine_settings = {self.engine_settings!r})") from None
            raise
        object.__setattr__(self, "_sim", sim)
        for name in ("tip_force_window", "workspace_height", "start_height"):
            lo, hi = getattr(self, name)
            if lo > hi:
                raise ConfigError(
                    f"{name} = {list(getattr(self, name))!r} is invalid: must be "
                    "[min, max] with min <= max"
                )
        wl, wh = self.workspace_height
        if wl >= wh:
            raise ConfigError(f"workspace_height = {[wl, wh]!r} is invalid: min must be < max")
        n = self.patch_size / self.cell_size
        if n > 2000:
            raise ConfigError(
                f"cell_size = {self.cell_size!r} is too small for patch_size = "
                f"{self.patch_size!r}: must give at most 2000 cells per side "
                f"(cell_size >= {self.patch_size / 2000:g} mm)"
            )
        if self.coarse_map_size > max(1, int(round(n))):
            raise ConfigError(
                f"coarse_map_size = {self.coarse_map_size!r} is out of range: must "
                f"be <= the patch's cells per side ({int(round(n))})"
            )
        reach = max(abs(c) for c in self.start_center) + self.start_xy_range
        if reach >= self.workspace_xy:
            raise ConfigError(
                f"start_center/start_xy_range reach {reach:g} mm from the patch "
                f"centre: must stay inside workspace_xy = {self.workspace_xy:g} mm"
            )
        sl, sh = self.start_height
        if sl < wl or sh >= wh:
            raise ConfigError(
                f"start_height = {[sl, sh]!r} is out of range: must lie inside "
                f"workspace_height = {[wl, wh]!r} (mm)"
            )
        if self.plate_offset_range[2] > sl:
            raise ConfigError(
                f"plate_offset_range[2] = {self.plate_offset_range[2]!r} is out of "
                f"range: must be <= start_height[0] = {sl!r} (mm) so that every "
                "episode starts out of contact"
            )

    def replace(self, **overrides) -> EnvConfig:
        """A validated copy with ``overrides`` (unknown names raise ConfigError)."""
        _check_names(overrides, "override")
        return replace(self, **overrides)


FIELDS = {f.name: f for f in fields(EnvConfig)}

_VEC_LEN = {f.name: len(f.default) for f in FIELDS.values() if isinstance(f.default, tuple)}


def _range_text(m) -> str:
    if m["choices"]:
        return "one of " + ", ".join(repr(c) for c in m["choices"])
    lo, hi = m["lo"], m["hi"]
    if lo is None and hi is None:
        return "any"
    lb = "(" if m["lo_open"] else "["
    rb = ")" if m["hi_open"] else "]"
    return f"{lb}{lo:g}, {hi:g}{rb}"


@dataclass(frozen=True)
class _Range(Limit):
    """A field's :class:`~brush_env.engine.checks.Limit`, described in the interval notation of
    the Arguments table: ``must be in [1, 1000] (count)``."""

    text: str = "any"

    def describe(self) -> str:
        unit = f" ({self.unit})" if self.unit not in ("-", "") else ""
        return f"must be in {self.text}{unit}"


def _limit(m) -> _Range:
    lo, hi = m["lo"], m["hi"]
    return _Range(
        m["unit"],
        text=_range_text(m),
        gt=lo if m["lo_open"] else None,
        ge=None if m["lo_open"] else lo,
        lt=hi if m["hi_open"] else None,
        le=None if m["hi_open"] else hi,
    )


#: Each numeric field's allowed range (made once from its metadata).
_LIMITS = {name: _limit(f.metadata) for name, f in FIELDS.items()}


def _check(f, value):
    """Type- and range-check one field; returns the normalised value."""
    m, name, default = f.metadata, f.name, f.default
    if name == "engine_settings":
        return _check_engine_settings(value)
    limit = _LIMITS[name]
    unit = f" ({m['unit']})" if m["unit"] not in ("-", "") else ""
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise ConfigError(f"{name} = {value!r} has the wrong type: expected true/false")
        return value
    if isinstance(default, str):
        if not isinstance(value, (str, os.PathLike)):
            raise ConfigError(f"{name} = {value!r} has the wrong type: expected a string")
        value = os.fspath(value)
        if m["choices"] and value not in m["choices"]:
            raise ConfigError(f"{name} = {value!r} is not allowed: must be {limit.text}")
        return value
    if isinstance(default, tuple):
        n = len(default)
        if hasattr(value, "tolist"):
            value = value.tolist()
        if not isinstance(value, (list, tuple)) or len(value) != n:
            raise type_error(name, value, f"a list of {n} numbers{unit}, each in {limit.text}")
        return tuple(_number(f"{name}[{i}]", v, float, limit) for i, v in enumerate(value))
    return _number(name, value, int if isinstance(default, int) else float, limit)


#: SimSettings fields the env sets itself (engine_dt, gravity), so not in engine_settings
_ENV_OWNED = ("dt", "gravity")


def _check_engine_settings(value) -> dict:
    """``engine_settings``: a table of SimSettings fields (their values are checked when the
    settings are built, ``EnvConfig.sim_settings``)."""
    from brush_env.engine.settings import engine_keys

    if not isinstance(value, dict):
        raise type_error("engine_settings", value, "a table of engine settings")
    allowed = [k for k in engine_keys() if k not in _ENV_OWNED]
    for k in value:
        if k not in allowed:
            raise ConfigError(
                f"engine_settings.{k} is not an engine setting the env passes on"
                f"{did_you_mean(str(k), allowed)} (allowed: {', '.join(allowed)}; "
                "the step is engine_dt and gravity is the env's gravity)"
            )
    return dict(value)


def _number(name: str, value, kind: type, limit: _Range):
    """A real (``kind`` float) or integral (``kind`` int; 3.0 passes as 3) number in ``limit``."""
    ok = isinstance(value, numbers.Real) and not isinstance(value, bool)
    if ok and kind is int:
        ok = math.isfinite(value) and float(value) == int(value)
    if not ok:
        what = "an integer" if kind is int else "a number"
        unit = f" ({limit.unit})" if limit.unit not in ("-", "") else ""
        raise type_error(name, value, f"{what}{unit} in {limit.text}")
    return limit.check(name, kind(value))


def _check_names(names, what: str, section: str | None = None) -> None:
    for k in names:
        if k not in FIELDS:
            raise ConfigError(
                f"unknown env {what} {k!r}{did_you_mean(k, FIELDS)} (known: {', '.join(FIELDS)})"
            )
        if section is not None and FIELDS[k].metadata["section"] != section:
            raise ConfigError(
                f"env setting {k!r} is in section [{section}]: it belongs in "
                f"[{FIELDS[k].metadata['section']}]"
            )


def env_config_path(path_or_name: str | os.PathLike | None) -> Path:
    """``configs/envs/<name>.toml`` for a bare name, else the path itself."""
    return resolve_config("env", path_or_name)


def load_env_config(
    path_or_name: str | os.PathLike | None = "flat_plate", **overrides: Any
) -> EnvConfig:
    """Read an env TOML file (sections as in ``SECTIONS``) and apply flat keyword overrides."""
    path = env_config_path(path_or_name)
    try:
        data = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{path}: not valid TOML: {e}") from None
    flat: dict[str, Any] = {}
    for sec, table in data.items():
        if sec not in SECTIONS or not isinstance(table, dict):
            raise ConfigError(
                f"{path}: unknown section or top-level key {sec!r} (allowed "
                f"sections: {', '.join(SECTIONS)})"
            )
        try:
            _check_names(table, "setting", section=sec)
        except ConfigError as e:
            raise ConfigError(f"{path}: {e}") from None
        flat.update(table)
    _check_names(overrides, "override")
    flat.update(overrides)
    try:
        return EnvConfig(**flat)
    except ConfigError as e:
        src = str(path) + (f" with overrides {overrides!r}" if overrides else "")
        raise ConfigError(f"{src}: {e}") from None


def arguments_table() -> str:
    """The Arguments table (Markdown) of every setting: name, section, default, unit, range."""
    rows = [
        "| Parameter | Section | Default | Unit | Allowed | Meaning |",
        "|---|---|---|---|---|---|",
    ]
    for f in FIELDS.values():
        m = f.metadata
        d = list(f.default) if isinstance(f.default, tuple) else f.default
        if f.name == "engine_settings":
            d = {}
        rows.append(
            f"| `{f.name}` | {m['section']} | `{d!r}` | {m['unit']} "
            f"| {_LIMITS[f.name].text} | {m['doc']} |"
        )
    return "\n".join(rows)
