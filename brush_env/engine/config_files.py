"""The config files: where they live, name -> path, TOML reading with checked tables, and the
dotted-key overrides (issue 27: one resolver for brushes, scenes, envs, fidelity levels and sweep
specs).

``resolve_config(kind, name_or_path)``: a bare name (a string with no ``.toml`` suffix and no path
separator) means ``configs/<folder>/<name>.toml`` (``CONFIG_KINDS``); anything else is a path.
Unknown names and missing files raise :class:`ConfigError` with a did-you-mean hint and the known
names.  ``configs_dir()`` is ``$BRUSH_ENV_CONFIGS`` if set, else the repository's ``configs/``.
"""

from __future__ import annotations

import builtins
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from .checks import ConfigError, Limit, check_int, check_real, check_vec, did_you_mean, type_error

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib  # type: ignore[no-redef]

__all__ = [
    "CONFIG_KINDS",
    "REQUIRED",
    "Table",
    "apply_overrides",
    "configs_dir",
    "in_file",
    "is_config_name",
    "known_configs",
    "materials_path",
    "read_toml",
    "resolve_config",
]

#: kind -> (folder under configs/, the name the errors use, the default name)
CONFIG_KINDS: dict[str, tuple[str, str, str | None]] = {
    "brush": ("brushes", "brush", "default"),
    "scene": ("scenes", "scene", "flat_plate"),
    "env": ("envs", "env config", "flat_plate"),
    "fidelity": ("fidelity", "fidelity level", None),
    "sweep": ("sweeps", "sweep spec", None),
    "agent": ("agents", "agent config", None),
}


def configs_dir() -> Path:
    """The ``configs/`` directory: $BRUSH_ENV_CONFIGS if set, else the repository's ``configs/``."""
    env = os.environ.get("BRUSH_ENV_CONFIGS")
    return Path(env) if env else Path(__file__).resolve().parents[2] / "configs"


def materials_path(path: str | os.PathLike | None = None) -> Path:
    """``path``, or the default materials file ``configs/materials.toml``."""
    return Path(path) if path is not None else configs_dir() / "materials.toml"


def is_config_name(name_or_path: Any) -> bool:
    """True for a bare config name: a ``str`` without ``.toml`` and without a path separator
    (a ``pathlib.Path`` is always a path)."""
    return (
        isinstance(name_or_path, str)
        and not name_or_path.endswith(".toml")
        and not re.search(r"[\\/]", name_or_path)
    )


def known_configs(kind: str) -> list[str]:
    """The names of ``kind`` under ``configs/`` (sorted)."""
    folder = CONFIG_KINDS[kind][0]
    return sorted(p.stem for p in (configs_dir() / folder).glob("*.toml"))


def resolve_config(kind: str, name_or_path: str | os.PathLike | None = None) -> Path:
    """The TOML file of a config of ``kind`` (a key of ``CONFIG_KINDS``): a bare name means
    ``configs/<folder>/<name>.toml`` (``None`` or ``""``: the kind's default name), anything else
    is a path that must exist."""
    if kind not in CONFIG_KINDS:
        raise ValueError(f"config kind {kind!r} is unknown: one of {', '.join(CONFIG_KINDS)}")
    folder, noun, default = CONFIG_KINDS[kind]
    if name_or_path is None or name_or_path == "":
        if default is None:
            raise ConfigError(f"{noun}: no name or path given")
        name_or_path = default
    s = os.fspath(name_or_path)
    if is_config_name(name_or_path):
        path = configs_dir() / folder / f"{s}.toml"
        if not path.is_file():
            known = known_configs(kind)
            raise ConfigError(
                f"{noun} {s!r} is not a known {noun}{did_you_mean(s, known)}"
                f" (known: {', '.join(known)})"
            )
        return path
    path = Path(s)
    if not path.is_file():
        raise ConfigError(
            f"{noun} file {s!r} does not exist (give a TOML path or a name from "
            f"{configs_dir() / folder}{did_you_mean(path.stem, known_configs(kind))})"
        )
    return path


def read_toml(path: Path) -> dict:
    """The TOML file's data; a syntax error raises ConfigError naming the file."""
    with open(path, "rb") as f:
        try:
            return tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            raise ConfigError(f"{path}: invalid TOML: {e}") from None


def in_file(path: Path, err: ConfigError) -> ConfigError:
    """``err`` with the file's path in front."""
    return ConfigError(f"{path}: {err}")


# --------------------------------------------------------------------------------------------------
# Checked tables
# --------------------------------------------------------------------------------------------------
REQUIRED = object()


class Table:
    """A TOML table being read: knows its key path and rejects keys not in ``allowed``."""

    def __init__(self, data: Any, path: str, allowed: tuple[str, ...]):
        if not isinstance(data, dict):
            raise type_error(path, data, "a table")
        for key in data:
            if key not in allowed:
                raise ConfigError(f"{path}: unknown key {key!r} (allowed: {', '.join(allowed)})")
        self.data, self.path = data, path

    def key(self, key: str) -> str:
        return f"{self.path}.{key}"

    def get(self, key: str, default: Any, expected: str) -> Any:
        if key in self.data:
            return self.data[key]
        if default is REQUIRED:
            raise ConfigError(f"{self.path}: missing required key {key!r} ({expected})")
        return default

    # the readers return None only when the caller's default is None, hence ``Any``
    def num(self, key: str, limit: Limit, default: Any = REQUIRED) -> Any:
        v = self.get(key, default, f"a number that {limit.describe()}")
        return v if v is None else check_real(self.key(key), v, limit)

    def int(self, key: str, limit: Limit, default: Any = REQUIRED) -> Any:
        v = self.get(key, default, f"an integer that {limit.describe()}")
        return v if v is None else check_int(self.key(key), v, limit)

    def vec(self, key: str, n: builtins.int, limit: Limit, default: Any = REQUIRED) -> Any:
        v = self.get(key, default, f"a list of {n} numbers ({limit.unit})")
        return v if v is None else check_vec(self.key(key), v, n, limit)

    def str(
        self,
        key: builtins.str,
        default: Any = REQUIRED,
        choices: Any = None,
        what: builtins.str = "",
    ) -> Any:
        v = self.get(key, default, "a string" + (f" ({what})" if what else ""))
        if v is None:
            return v
        if not isinstance(v, str):
            raise type_error(self.key(key), v, "a string")
        if choices is not None and v not in choices:
            raise ConfigError(
                f"{self.key(key)} = {v!r} is not a known {what} (known: {', '.join(choices)})"
            )
        return v


def apply_overrides(data: dict, overrides: Mapping[str, Any], prefix: str = "") -> None:
    """Merge ``overrides`` (nested tables and/or dotted keys with [i] indices) into ``data``."""
    for dotted, value in overrides.items():
        parts: list[Any] = [
            int(p[1:-1]) if p.startswith("[") else p
            for p in re.findall(r"\[\d+\]|[^.\[\]]+", str(dotted))
        ]
        where = f"overrides[{prefix + str(dotted)!r}]"
        if not parts:
            raise ConfigError(f"{where}: empty key")
        node: Any = data
        for part, nxt in zip(parts[:-1], parts[1:]):
            node = _child(node, part, where, create={} if isinstance(nxt, str) else None)
        last = parts[-1]
        _child(node, last, where, create=None if isinstance(last, int) else {})
        if isinstance(value, Mapping) and isinstance(node[last], dict):
            apply_overrides(node[last], value, prefix + str(dotted) + ".")
        else:
            node[last] = value


def _child(node: Any, part: Any, where: str, create: Any) -> Any:
    if isinstance(part, int):
        if not isinstance(node, list) or not -len(node) <= part < len(node):
            size = f"{len(node)} entries" if isinstance(node, list) else "not an array"
            raise ConfigError(f"{where}: index [{part}] does not exist ({size})")
        return node[part]
    if not isinstance(node, dict):
        raise ConfigError(f"{where}: {part!r} is inside a value that is not a table")
    if part not in node:
        if create is None:
            raise ConfigError(f"{where}: {part!r} does not exist")
        node[part] = create
    return node[part]
