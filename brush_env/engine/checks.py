"""Argument and config checks shared by every layer (engine, motion, experiments, envs, agents).

Each check returns the normalised value or raises :class:`ConfigError` (a ``ValueError``) whose
message names the parameter, the bad value and the allowed range with its unit, e.g.
``brush.grid[1].length_mm = -2.0 is out of range: must be > 0 and <= 100 (mm)``.
"""

from __future__ import annotations

import difflib
import math
import numbers
import operator
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "ConfigError",
    "Limit",
    "check_real",
    "check_int",
    "check_vec",
    "check_unit",
    "check_rotation",
    "check_choice",
    "check_keys",
    "did_you_mean",
    "type_error",
    "POSITIVE",
    "NONNEG",
    "FINITE",
]


class ConfigError(ValueError):
    """A config value or argument is missing, unknown, of the wrong type or out of range.

    The message names the key path, the bad value and what is allowed (with its unit).
    """


@dataclass(frozen=True)
class Limit:
    """An allowed numeric range with its unit; bounds left None are open (value must be finite)."""

    unit: str
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None

    def describe(self) -> str:
        ops = ((">", self.gt), (">=", self.ge), ("<", self.lt), ("<=", self.le))
        parts = [f"{op} {bound:g}" for op, bound in ops if bound is not None] or ["finite"]
        unit = f" ({self.unit})" if self.unit else ""
        return f"must be {' and '.join(parts)}{unit}"

    def check(self, path: str, value: float) -> Any:
        """Return ``value`` if it lies in the range, else raise ConfigError naming ``path``."""
        ops = (
            (operator.gt, self.gt),
            (operator.ge, self.ge),
            (operator.lt, self.lt),
            (operator.le, self.le),
        )
        ok = math.isfinite(value) and all(b is None or cmp(value, b) for cmp, b in ops)
        if not ok:
            raise ConfigError(f"{path} = {value!r} is out of range: {self.describe()}")
        return value


#: Common ranges whose unit the caller does not need to spell (dimension-free checks).
POSITIVE = Limit("", gt=0)
NONNEG = Limit("", ge=0)
FINITE = Limit("")


def type_error(path: str, value: Any, expected: str) -> ConfigError:
    """The wrong-type error: names the parameter, the value, what was expected and what came."""
    got = type(value).__name__
    if isinstance(value, (list, tuple)):
        got = f"a {got} of {len(value)}"
    return ConfigError(f"{path} = {value!r} has the wrong type: expected {expected}, got {got}")


def check_real(path: str, value: Any, limit: Limit = FINITE) -> float:
    """A real number (numpy scalars included; bool, complex and None refused) within ``limit``."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value.item()
    if not isinstance(value, numbers.Real) or isinstance(value, bool):
        raise type_error(path, value, "a number" + (f" ({limit.unit})" if limit.unit else ""))
    return limit.check(path, float(value))


def check_int(path: str, value: Any, limit: Limit = FINITE) -> int:
    """An integer (bool refused) within ``limit``."""
    if not isinstance(value, numbers.Integral) or isinstance(value, bool):
        raise type_error(path, value, "an integer" + (f" ({limit.unit})" if limit.unit else ""))
    return limit.check(path, int(value))


def check_vec(path: str, value: Any, n: int, limit: Limit = FINITE) -> tuple[float, ...]:
    """A list/tuple/array of ``n`` real numbers, each within ``limit``."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise type_error(path, value, f"a list of {n} numbers ({limit.unit})")
    return tuple(check_real(f"{path}[{i}]", v, limit) for i, v in enumerate(value))


def check_unit(path: str, value: Any) -> np.ndarray:
    """A non-zero 3-vector, normalised."""
    v = np.asarray(check_vec(path, value, 3, Limit("dimensionless direction")))
    norm = float(np.linalg.norm(v))
    if norm < 1e-12:
        raise ConfigError(f"{path} = {list(value)!r} is invalid: must be a non-zero 3-vector")
    return v / norm


def check_rotation(path: str, value: Any, tol: float = 1e-6) -> np.ndarray:
    """A finite 3x3 rotation matrix (R^T R = I within ``tol``, det = +1), as a float array."""
    try:
        R = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"{path} must be a 3x3 rotation matrix, got {value!r}") from None
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ConfigError(f"{path} must be a finite 3x3 rotation matrix, got shape {R.shape}")
    err = float(np.max(np.abs(R.T @ R - np.eye(3))))
    det = float(np.linalg.det(R))
    if err > tol or det <= 0.0:
        raise ConfigError(
            f"{path} must be a rotation matrix (R^T R = I within {tol:g}, "
            f"det = +1); got |R^T R - I|max = {err:.3g}, det = {det:.6g}"
        )
    return R


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """'; did you mean a, b?' for the closest known names, or '' when none is close."""
    close = difflib.get_close_matches(str(name), list(known), n=3)
    return f"; did you mean {', '.join(close)}?" if close else ""


def check_choice(path: str, value: Any, choices: Iterable[str], what: str = "value") -> str:
    """One of ``choices`` (strings), with a did-you-mean hint."""
    choices = list(choices)
    if not isinstance(value, str) or value not in choices:
        raise ConfigError(
            f"{path} = {value!r} is not a known {what}{did_you_mean(value, choices)}"
            f" (known: {', '.join(choices)})"
        )
    return value


def check_keys(path: str, keys: Iterable[str], allowed: Iterable[str]) -> None:
    """Every key is one of ``allowed``; else name the first unknown one with a did-you-mean."""
    allowed = list(allowed)
    for key in keys:
        if key not in allowed:
            raise ConfigError(
                f"{path}: unknown key {key!r}{did_you_mean(key, allowed)} "
                f"(allowed: {', '.join(allowed)})"
            )
