"""User mistakes at the command line: one clear line on stderr and exit code 2, no traceback.

Every user-facing command (``brush-env ...``, ``python -m agents.*``) runs its ``main`` through
:func:`run_main`.  A bad path, key, value or hyperparameter raises one of :data:`USER_ERRORS`
(``ConfigError`` is a ``ValueError`` naming the parameter, the value and the allowed range); it is
printed as ``<prog>: error: <message>`` and the command exits with 2.  ``--debug`` anywhere on
the command line shows the full traceback instead.  Anything else is a bug and keeps its
traceback.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Sequence

__all__ = [
    "UserError",
    "USER_ERRORS",
    "OneLineParser",
    "run_main",
    "one_line",
    "add_flag",
    "add_env_kw",
]


class UserError(Exception):
    """A mistake in what the user asked for (not a bug): reported in one line, exit code 2."""


#: Exceptions that mean "the input was wrong", reported without a traceback.
USER_ERRORS = (
    UserError,
    ValueError,
    FileNotFoundError,
    NotADirectoryError,
    IsADirectoryError,
    PermissionError,
)


def one_line(exc: BaseException) -> str:
    """The exception's message on one line (inner newlines folded)."""
    msg = str(exc).strip() or type(exc).__name__
    if isinstance(exc, FileNotFoundError) and exc.filename and str(exc.filename) not in msg:
        msg = f"{msg}: {exc.filename}"
    return " ".join(part.strip() for part in msg.splitlines() if part.strip())


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line (exit 2) instead of usage + error."""

    def error(self, message: str):  # noqa: D401 - argparse's hook
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def add_flag(parser: argparse.ArgumentParser, name: str, help: str) -> None:
    """An on/off option of a command: ``name`` given means True (argparse's ``store_true``)."""
    parser.add_argument(name, action="store_true", help=help)


def add_env_kw(parser: argparse.ArgumentParser, example: str) -> None:
    """``--env-kw KEY=VALUE``, repeatable: an env setting override of the ``agents`` commands
    (read with ``agents.evaluate.parse_env_kw``); ``example`` ends the help text."""
    parser.add_argument(
        "--env-kw",
        action="append",
        metavar="KEY=VALUE",
        help=f"env setting override, repeatable ({example})",
    )


def run_main(
    main: Callable[[Sequence[str] | None], int],
    argv: Sequence[str] | None = None,
    prog: str | None = None,
) -> int:
    """Run ``main(argv)``; turn a user mistake into one stderr line and exit code 2.

    ``--debug`` is taken out of ``argv`` and makes errors show their traceback.
    """
    args = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in args
    args = [a for a in args if a != "--debug"]
    prog = prog or "brush-env"
    try:
        return int(main(args) or 0)
    except USER_ERRORS as exc:
        if debug:
            raise
        print(f"{prog}: error: {one_line(exc)} (--debug shows the traceback)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
