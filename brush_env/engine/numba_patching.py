"""What the engine's patches of numba share (``numba_inline``, ``numba_lowering``,
``numba_linking``, ``numba_loading``): reading numba's source for the guard that it is the code a
patch was written against, the environment switch that leaves numba as shipped, and applying a
patch once."""

from __future__ import annotations

import inspect
import os
from collections.abc import Callable


def sources(*objs) -> list[str] | None:
    """The source text of each object, or None where one cannot be read (a frozen install)."""
    try:
        return [inspect.getsource(o) for o in objs]
    except (OSError, TypeError):
        return None


def switched_off(switch: str) -> bool:
    """True if the environment variable ``switch`` leaves numba as shipped (set to anything but
    "" or "0")."""
    return os.environ.get(switch, "") not in ("", "0")


def apply(
    owner,
    replacements: dict[str, object],
    switch: str,
    recognised: Callable[[], bool],
    original: dict[str, object],
) -> bool:
    """Set each ``owner.<name>`` to its replacement, once (idempotent); returns True if the patch
    is in place.  Not applied when the environment variable ``switch`` is set to anything but ""
    or "0", or when ``recognised()`` says numba is not the code the patch was written against.
    ``original`` receives what was replaced (the patched functions call it)."""
    if all(getattr(owner, name) is fn for name, fn in replacements.items()):
        return True
    if switched_off(switch):
        return False
    if not recognised():
        return False
    for name, fn in replacements.items():
        original[name] = getattr(owner, name)
        setattr(owner, name, fn)
    return True
