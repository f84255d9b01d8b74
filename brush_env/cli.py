"""brush-env: run the paper's reference experiment, validate the beam model, benchmark, warm up.

    brush-env reference                 # the paper's 3 mm press + 20 mm circle, default brush
    brush-env validate all              # beam model against closed-form references
    brush-env bench engine              # speed-versus-error tables
    brush-env warmup                    # compile the numba kernels once (first run only)

A user mistake (bad path, key or value) is reported in one line on stderr with exit code 2;
``--debug`` shows the traceback.  Each subcommand module exposes ``add_arguments(parser)`` and
``run(args) -> int``.
"""

from __future__ import annotations

import gc
import importlib
import sys

from .kernel_cache import announce
from .user_errors import OneLineParser, run_main

#: name -> (module, one-line help)
SUBCOMMANDS = {
    "reference": (
        "brush_env.experiments.cli",
        "run the paper's circular UR5 experiment (Sec. 4-5) and write Figure 7/9 data",
    ),
    "validate": (
        "brush_env.validation.cli",
        "check the beam and contact model against closed-form references",
    ),
    "bench": (
        "brush_env.bench.cli",
        "speed-versus-error benchmarks (engine, contact, env), first-start compile",
    ),
    "sweep": (
        "brush_env.sweeps.cli",
        "design sweep: vary brush/material/scene/motion keys, run the experiment per variant "
        "(local pool or Ray), one results table",
    ),
    "sweep-report": (
        "brush_env.sweeps.report_cli",
        "effects and sensitivity ranking of a sweep (DIR/report.md with figures)",
    ),
    "warmup": ("brush_env.cli", "compile the numba kernels once, so later runs start at once"),
    "calibrate": (
        "brush_env.calibration",
        "fit the reduced bristle model (fidelity level 'reduced') of a brush's bristle types to "
        "the rod, cached by content",
    ),
}


def add_arguments(parser) -> None:
    """``brush-env warmup`` takes no options."""


def run(args) -> int:
    """``brush-env warmup``: compile (or load) every kernel group and report the time; while it
    compiles, a progress line every 10 s on stderr (group k of n, elapsed, estimate)."""
    from .kernel_cache import announce, to_stderr

    announce()
    from .engine.warmup import warm_up

    print(f"kernels ready in {warm_up(notice=to_stderr):.1f} s")
    return 0


def build_parser(command: str | None = None) -> tuple[OneLineParser, dict]:
    """The top-level parser and the loaded subcommand module(s).

    Only ``command``'s module is imported (all of them when None), so a run starts in well
    under a second and ``brush-env --help`` imports none of the heavy ones.
    """
    parser = OneLineParser(
        prog="brush-env",
        description=__doc__.splitlines()[0],
        epilog="--debug (anywhere) shows tracebacks of user errors",
    )
    sub = parser.add_subparsers(
        dest="command", required=True, metavar="COMMAND", parser_class=OneLineParser
    )
    modules = {}
    for name, (modname, helptext) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=helptext, description=helptext)
        if command is None or name == command:
            modules[name] = importlib.import_module(modname)
            modules[name].add_arguments(p)
    return parser, modules


def _main(argv) -> int:
    command = next((a for a in argv if not a.startswith("-")), None)
    if (
        command in ("reference", "bench", "validate", "sweep")
        and "-h" not in argv
        and "--help" not in argv
    ):
        announce()  # before the heavy imports: a first start compiles for about a minute
    parser, modules = build_parser(command if command in SUBCOMMANDS else "")
    args = parser.parse_args(argv)
    return int(modules[args.command].run(args) or 0)


def main(argv=None) -> int:
    """Entry point of the ``brush-env`` script (``argv`` None: the process's own arguments)."""
    code = run_main(_main, argv, prog="brush-env")
    if argv is None:
        # The program is done and its files are closed.  The interpreter's exit would now walk
        # every object numba's typing and matplotlib left (the cyclic collector's last passes:
        # 0.2-0.4 s of a `brush-env reference`, issue 32); frozen, they are left to the OS.
        # Nothing else changes: objects still die by reference count, only cycles are not
        # searched for.  Not when a caller passes ``argv`` (a test, a script): its process
        # goes on.  (docs/benchmarks.md, session 39, "The program's exit")
        gc.freeze()
    return code


if __name__ == "__main__":
    sys.exit(main())
