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
import difflib
import sys
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager

__all__ = [
    "UserError",
    "USER_ERRORS",
    "OneLineParser",
    "run_main",
    "one_line",
    "add_flag",
    "add_env_kw",
    "did_you_mean",
    "one_line_show",
    "one_line_warnings",
    "write_line",
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


def did_you_mean(name: str, known: Iterable[str]) -> str:
    """'; did you mean a, b?' for the closest known names, or '' when none is close (as
    ``engine.checks.did_you_mean``; here without importing the engine, so a usage error costs
    no numba import)."""
    close = difflib.get_close_matches(str(name), [str(k) for k in known], n=3)
    return f"; did you mean {', '.join(close)}?" if close else ""


class OneLineParser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line (exit 2) instead of usage + error, with a
    did-you-mean for a misspelt choice (subcommands, targets, --integrator, ...)."""

    def error(self, message: str):  # noqa: D401 - argparse's hook
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")

    def _check_value(self, action, value):  # argparse's hook for `choices`
        if action.choices is not None and value not in action.choices:
            choices = ", ".join(map(repr, action.choices))
            raise argparse.ArgumentError(
                action,
                f"invalid choice: {value!r}{did_you_mean(value, action.choices)} "
                f"(choose from {choices})",
            )


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
        with one_line_warnings():
            return int(main(args) or 0)
    except USER_ERRORS as exc:
        if debug:
            raise
        print(f"{prog}: error: {one_line(exc)} (--debug shows the traceback)", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130


@contextmanager
def one_line_warnings() -> Iterator[None]:
    """Inside: a warning shown to the user is one line, ``<Category>: <message>``, written above
    any progress bar (``tqdm.write``) -- never the default two lines whose second is the source
    line of the ``warnings.warn`` call, which broke the bar in the middle of a run."""
    shown = warnings.showwarning
    warnings.showwarning = one_line_show(write_line)
    try:
        yield
    finally:
        warnings.showwarning = shown


def one_line_show(write: Callable[[str, object], None]):
    """A ``warnings.showwarning`` that hands ``write(text, file)`` one line,
    ``<Category>: <message>`` (no source line; inner newlines folded)."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        text = " ".join(str(message).split())
        write(f"{category.__name__}: {text}", file or sys.stderr)

    return show


def write_line(text: str, file=None) -> None:
    """One line on ``file`` (stderr), above any tqdm progress bar if tqdm is in use."""
    file = file or sys.stderr
    tqdm = sys.modules.get("tqdm")
    if tqdm is not None:  # only if a bar may be on screen: no import for a plain message
        tqdm.tqdm.write(text, file=file)
    else:
        print(text, file=file, flush=True)
