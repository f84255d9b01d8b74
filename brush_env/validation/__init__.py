"""brush_env.validation: the engine against references someone else wrote down.

``references`` (closed-form Timoshenko, axial and torsion results, the exact elastica, the
Euler-Bernoulli cantilever frequencies; numpy only, never imports the engine), ``suite`` (the
validate cases and the acceptance table), ``cli`` (``brush-env validate``).  Not dynamics, so
not in the engine.
"""

from . import references
from .cli import add_arguments, run
from .suite import (
    PAPER_INNER,
    SLENDER,
    Check,
    Geometry,
    axial,
    cantilever,
    classified_modes,
    frequency,
    suite,
    torsion,
)

__all__ = [
    "PAPER_INNER",
    "SLENDER",
    "Check",
    "Geometry",
    "add_arguments",
    "axial",
    "cantilever",
    "classified_modes",
    "frequency",
    "references",
    "run",
    "suite",
    "torsion",
]
