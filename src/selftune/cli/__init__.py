"""The ``selftune`` command line: argument parsing only.

Each subcommand is one registration function, ``_add_<name>(subparsers)``, listed in
:data:`_COMMANDS`, and one handler, ``_run_<name>(args) -> int``, both in a module of
the subcommands (:mod:`selftune.cli._commands`; the options several commands share are in
:mod:`selftune.cli._parsing`). The handler imports what its
command needs when it runs (:mod:`selftune.commands`, :mod:`selftune.bench`) and calls it
with plain values. Handlers raise :class:`~selftune.errors.SelftuneError` on bad input;
:func:`main` turns it (and ``OSError``, a usage error, an out-of-memory error) into one
line on stderr, ``selftune: error: <message>``, and exit code 2. Ctrl-C is one line,
``selftune: interrupted``, and exit code 130. Warnings are never shown: a command that
needs them turns a numerical one into an error naming the input.
"""

from __future__ import annotations

import argparse
import os
import sys
import warnings
from collections.abc import Callable, Sequence

from .. import __version__
from .._interrupts import Interrupts, caused_by_interrupt
from ..errors import SelftuneDeprecationWarning, SelftuneError, error_line
from ._commands import (
    _add_bench,
    _add_follow,
    _add_learn,
    _add_reproduce,
    _add_solve,
    _add_tune,
)
from ._export import _add_export
from ._fleet import _add_fleet
from ._parsing import _Parser, _Subparsers, _UsageError

__all__ = ["build_parser", "main"]

#: Exit code of a usage error or of bad input (argparse uses 2 as well).
EXIT_USAGE = 2

#: Exit code after Ctrl-C (128 + SIGINT, as a shell reports it).
EXIT_INTERRUPTED = 130

#: Registration functions, one per subcommand, in the order of ``selftune --help``.
_COMMANDS: tuple[Callable[[_Subparsers], None], ...] = (
    _add_reproduce,
    _add_tune,
    _add_solve,
    _add_learn,
    _add_export,
    _add_follow,
    _add_fleet,
    _add_bench,
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``selftune`` with every subcommand registered.

    Returns
    -------
    argparse.ArgumentParser
    """
    parser = _Parser(
        prog="selftune",
        description=(
            "Self-tuning optimal torque control of PMSM drives by adaptive dynamic"
            " programming (Wang 2022)."
        ),
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for register in _COMMANDS:
        register(subparsers)
    return parser


def _silence_stdout() -> None:
    """Point stdout at the null device, so that the interpreter's final flush cannot fail."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError, AttributeError):  # stdout is not a real file (tests)
        pass


def _fail(message: str) -> int:
    print(f"selftune: error: {' '.join(message.split())}", file=sys.stderr)
    return EXIT_USAGE


def _run(argv: Sequence[str] | None) -> int:
    """Parse ``argv`` and run its command; every user error is one line."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except _UsageError as exc:
        return _fail(str(exc))
    except SystemExit as exc:  # --help / --version (0)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    handler: Callable[[argparse.Namespace], int] = args.handler
    try:
        return handler(args)
    except BrokenPipeError:  # the reader went away (``selftune solve | head``): stop quietly
        _silence_stdout()
        return 1
    except (SelftuneError, OSError) as exc:
        return _fail(error_line(exc) or str(exc))
    except MemoryError:  # sizes are bounded at the door; this is the last resort
        return _fail(f"{args.command}: out of memory (the inputs ask for more than is free)")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``selftune`` command line; return the exit code.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments (default: ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success; 2 on a usage error or bad input, after one line on stderr
        ``selftune: error: <message>``; 130 after Ctrl-C, with one line
        ``selftune: interrupted`` (no output set is left half written). Without
        ``argv`` (the process's own command line), an interrupt ends the process at once
        with code 130, without finalizing the interpreter.
    """
    with Interrupts() as interrupts:
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("ignore")  # numerical warnings never on the terminal
                warnings.simplefilter("always", SelftuneDeprecationWarning)
                code = _run(argv)
            if code == 0:  # a failure says only what failed
                for message in dict.fromkeys(
                    str(item.message)
                    for item in caught
                    if issubclass(item.category, SelftuneDeprecationWarning)
                ):
                    print(f"selftune: warning: {message}", file=sys.stderr)
        except KeyboardInterrupt:
            interrupts.received = True
        except Exception as exc:
            # After Ctrl-C, whatever the interrupted code raised is its consequence: a C
            # extension's import fails with an ImportError, a binding's argument
            # conversion with a TypeError.
            if not (interrupts.received or caused_by_interrupt(exc)):
                raise
            interrupts.received = True
    if not interrupts.received:
        return code
    _interrupted()
    if argv is None:  # the process's own command line: end it now (see _exit_now)
        _exit_now(EXIT_INTERRUPTED)
    return EXIT_INTERRUPTED


def _interrupted() -> None:
    try:
        print("selftune: interrupted", file=sys.stderr)
    except (OSError, ValueError):  # stderr is gone
        pass


def _exit_now(code: int) -> None:
    """Flush the output and end the process without finalizing the interpreter.

    An interrupt can leave a C extension half initialized (its import cut short), and
    finalizing it may then crash the interpreter (a fatal error, SIGABRT) or re-raise
    the interrupt; the outputs are already complete or removed, so nothing is lost.
    """
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)
