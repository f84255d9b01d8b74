"""brush_env.bench: speed-versus-error benchmarks (``brush-env bench TARGET``).

``harness`` (machine line, cold start, best-of-repeats, tables) and one module per target:
``engine``, ``contact``, ``convergence``, ``env``; ``cli`` wires them into the command line.
Figures go to docs/benchmarks.md with the command that made them; no timing enters a test.
"""

from .cli import TARGETS, add_arguments, run
from .harness import machine_info, markdown_table

__all__ = ["TARGETS", "add_arguments", "machine_info", "markdown_table", "run"]
