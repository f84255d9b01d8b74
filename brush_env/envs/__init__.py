"""Gymnasium environments of brush_env (``brush_env/FlatPlate-v0``).

Importing this package imports gymnasium; ``import brush_env`` only registers the ids (entry
point strings), so the env modules load on the first ``gym.make``.
"""

from .config import EnvConfig, load_env_config
from .flat_plate import BrushEnv

__all__ = ["BrushEnv", "EnvConfig", "load_env_config"]
