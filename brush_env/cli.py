"""``brush-env`` command line: one subcommand per module at the edge of the package.

Each subcommand module exposes ``add_arguments(parser)`` and ``run(args) -> int``.
"""

from __future__ import annotations

import argparse
import importlib
import sys

SUBCOMMANDS = {
    "validate": ("brush_env.validation", "validate the beam model against closed-form references"),
    "bench": ("brush_env.bench", "speed-versus-error benchmarks (engine, contact, env)"),
    "reference": ("brush_env.experiment", "the paper's circular reference experiment"),
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="brush-env", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    modules = {}
    for name, (modname, helptext) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=helptext)
        try:
            mod = importlib.import_module(modname)
        except ModuleNotFoundError as exc:  # a subcommand whose module is not there yet
            if exc.name != modname:
                raise
            continue
        mod.add_arguments(p)
        modules[name] = mod
    args = parser.parse_args(argv)
    if args.command not in modules:
        parser.error(f"subcommand {args.command!r} is not available in this build")
    return int(modules[args.command].run(args) or 0)


if __name__ == "__main__":
    sys.exit(main())
