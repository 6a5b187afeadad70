"""The ``selftune`` command line: argument parsing only.

Each subcommand is one registration function, ``_add_<name>(subparsers)``, listed in
:data:`_COMMANDS`, and one handler, ``_run_<name>(args) -> int``, which imports what its
command needs when it runs (:mod:`selftune.commands`, :mod:`selftune.bench`) and calls it
with plain values. Handlers raise :class:`~selftune.errors.SelftuneError` on bad input;
:func:`main` turns it (and ``OSError``, a usage error, an out-of-memory error) into one
line on stderr, ``selftune: error: <message>``, and exit code 2. Ctrl-C is one line,
``selftune: interrupted``, and exit code 130. Warnings are never shown: a command that
needs them turns a numerical one into an error naming the input.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import re
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, NoReturn, TypeAlias

from . import __version__
from ._interrupts import Interrupts, caused_by_interrupt
from .errors import InputError, SelftuneDeprecationWarning, SelftuneError

if TYPE_CHECKING:
    from .config import MotorConfig

__all__ = ["build_parser", "main"]

#: Exit code of a usage error or of bad input (argparse uses 2 as well).
EXIT_USAGE = 2

#: Exit code after Ctrl-C (128 + SIGINT, as a shell reports it).
EXIT_INTERRUPTED = 130

#: Largest ``--seed`` (numpy's seeds are unbounded; this keeps them reproducible anywhere).
MAX_SEED = 2**32 - 1

_Subparsers: TypeAlias = "argparse._SubParsersAction[_Parser]"

# What argparse takes for a negative number rather than an option: -1, -1.5, -.5, -1e9,
# -1.5E-3, -inf, -nan (argparse's own pattern misses exponents, so --speed -1e9 failed).
_NEGATIVE_NUMBER = re.compile(
    r"^-(?:\d+\.?\d*(?:[eE][+-]?\d+)?|\.\d+(?:[eE][+-]?\d+)?|inf(?:inity)?|nan)$",
    re.IGNORECASE,
)


class _UsageError(Exception):
    """A usage error argparse found; its message is one line."""


class _Parser(argparse.ArgumentParser):
    """argparse with usage errors raised (one line in :func:`main`) rather than printed
    with the usage and an exit, and with negative numbers in any notation as values."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER

    def error(self, message: str) -> NoReturn:
        command = self.prog.partition(" ")[2]  # "solve" of "selftune solve"
        where = f"{command}: " if command else ""
        raise _UsageError(f"{where}{message} (see '{self.prog} --help')")


def _finite_float(text: str) -> float:
    """argparse type: a finite number (rejects nan and inf)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite: {text!r}")
    return value


def _seed(text: str) -> int:
    """argparse type: a whole number from 0 to :data:`MAX_SEED`."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if not 0 <= value <= MAX_SEED:
        raise argparse.ArgumentTypeError(f"must be from 0 to {MAX_SEED}, got {value}")
    return value


def _add_motor_options(parser: argparse.ArgumentParser) -> None:
    """``--motor``, ``--speed``, ``--torque``: the options of every command about a motor."""
    parser.add_argument(
        "--motor",
        metavar="MOTOR.toml",
        help="motor, operating point and cost weights (default: the paper's setting)",
    )
    parser.add_argument(
        "--speed",
        type=_finite_float,
        metavar="S",
        help="mechanical speed, rad/s (overrides the file; paper: 10)",
    )
    parser.add_argument(
        "--torque",
        type=_finite_float,
        metavar="T",
        help="torque reference, N m (overrides the file; paper: 10)",
    )


def _motor_config(args: argparse.Namespace) -> MotorConfig:
    """The configuration named by ``--motor`` (or the paper's), with the overrides applied."""
    from .config import MotorConfig, load_motor_config

    config = MotorConfig.default() if args.motor is None else load_motor_config(args.motor)
    overrides = {
        name: value
        for name, value in (("speed", args.speed), ("torque", args.torque))
        if value is not None
    }
    try:
        return dataclasses.replace(config, **overrides) if overrides else config
    except InputError as exc:  # name the option, and the motor it is checked against
        name, _, reason = str(exc).partition(": ")
        option = f"--{name}" if name in overrides else name
        raise InputError(f"{option}: {reason} ({config.source})") from None


_JSON_HELP = "also write the results to FILE as JSON; '-': the JSON alone, to standard output"


def _add_json_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--json", metavar="FILE", help=_JSON_HELP)


def _add_out_option(parser: argparse.ArgumentParser, default: str, what: str) -> None:
    """``--out DIR``: where a command writes ``what``, replacing an earlier output whole."""
    parser.add_argument(
        "--out",
        metavar="DIR",
        default=default,
        help=f"directory for {what}: new, empty, or an earlier output of this command,"
        " replaced as a whole (default: %(default)s)",
    )


def _add_seed_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--seed", type=_seed, default=0, help="exploration seed (default: 0)")


def _add_command(
    subparsers: _Subparsers,
    name: str,
    handler: Callable[[argparse.Namespace], int],
    *,
    help: str,
    description: str,
) -> argparse.ArgumentParser:
    """The subcommand ``name``, run by ``handler`` with the parsed arguments."""
    parser = subparsers.add_parser(name, help=help, description=description)
    parser.set_defaults(handler=handler)
    return parser


# -- the commands ---------------------------------------------------------------------


def _add_solve(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "solve",
        _run_solve,
        help="the model-based optimal torque controller (K*, P*, X*, U*, Theta*)",
        description=(
            "Solve the optimal output regulation problem of the PMSM in torque-control"
            " mode from its model: the LQR gain K* and value P* (Riccati equation), the"
            " regulator-equation solution X*, U*, the data-equation unknowns Theta*, and"
            " the operating point x_e = X* w, u_e = U* w. Without --motor, the paper's"
            " motor and setting."
        ),
    )
    _add_motor_options(parser)
    _add_json_option(parser)


def _run_solve(args: argparse.Namespace) -> int:
    from .commands import solve_command

    return solve_command(_motor_config(args), args.json)


def _add_learn(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "learn",
        _run_learn,
        help="learn the optimal controller from logged data (no model needed)",
        description=(
            "Learn the optimal feedback K*, the value P* and (with a [regulation] table)"
            " the feedforward X*, U* from sampled data of any linear plant, by off-policy"
            " policy iteration on one batch of data (Jiang & Jiang 2012; Gao & Jiang"
            " 2016). DATA is a CSV (header t,x1..xn,u1..um,w1..wq) or NPZ file."
        ),
    )
    parser.add_argument("data", metavar="DATA", help="the samples: a .csv or .npz file")
    parser.add_argument(
        "--config",
        metavar="CONFIG.toml",
        required=True,
        help="cost weights, initial policy, optional [regulation] and [learning] tables",
    )
    _add_json_option(parser)


def _run_learn(args: argparse.Namespace) -> int:
    from .commands import learn_command

    return learn_command(args.data, args.config, args.json)


def _add_reproduce(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "reproduce",
        _run_reproduce,
        help="regenerate the paper's Section V: table, results.json and Figs. 1-5",
        description=(
            "Run Algorithms 1, 2, 3 and the off-policy variant with the paper's settings on"
            " the paper's motor (reconciled parameters), print Theta* against each learned"
            " Theta, and write fig1..fig5 (PNG and SVG) and results.json."
        ),
    )
    _add_out_option(parser, "selftune-results", "the figures and results.json")
    _add_seed_option(parser)


def _run_reproduce(args: argparse.Namespace) -> int:
    from .commands import reproduce_command

    return reproduce_command(args.out, args.seed)


def _add_tune(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "tune",
        _run_tune,
        help="run a self-tuning session on the motor in a file and compare with the optimum",
        description=(
            "Self-tune the torque controller of the (simulated) motor in MOTOR.toml with one"
            " of the paper's algorithms or the off-policy variant, on the ideal drive or the"
            " realistic one of its [drive] table; print the controller a drive can run, its"
            " quality, its steady torque on the simulated drive and how it compares with the"
            " model-based optimum. The learner is told only the pole pairs, the speed, the"
            " torque reference and the nameplate flux (Algorithm 3 identifies the flux)."
            " With --online PROFILE.toml the drive, once commissioned, runs through the"
            " profile's heating and faults with the online tuner in the loop: it prints the"
            " switches and their reasons, the estimates against the truth, the cost against"
            " the law tuned cold and against the optimum of each instant, and the steady"
            " torque error."
        ),
    )
    parser.add_argument("--motor", metavar="MOTOR.toml", required=True, help="the motor file")
    parser.add_argument(
        "--algorithm",
        choices=["1", "2", "3", "offpolicy"],
        default=None,
        help="which algorithm (default: offpolicy)",
    )
    parser.add_argument(
        "--target",
        choices=["continuous", "digital"],
        default=None,
        help=(
            "the controller to learn: the paper's continuous one, or the optimum of the"
            " sampled loop with the drive's delay (default: the motor file's [learning]"
            " target; continuous, or digital with a [drive] table)"
        ),
    )
    parser.add_argument(
        "--online",
        metavar="PROFILE.toml",
        default=None,
        help=(
            "commission the drive, then run it through the R_s, L_s and phi_pm profile of"
            " PROFILE.toml with the online tuner in the loop (digital target, integral"
            " action, the off-policy learner)"
        ),
    )
    parser.add_argument(
        "--report",
        metavar="DIR",
        default=None,
        help="with --online: write its figures, JSON and printed report into DIR",
    )
    _add_relearn_option(parser)
    _add_seed_option(parser)
    _add_json_option(parser)


def _run_tune(args: argparse.Namespace) -> int:
    from .commands import online_command, tune_command
    from .config import load_motor_config
    from .errors import InputError

    if args.online is None:
        if args.report is not None:
            raise InputError("--report: needs --online PROFILE.toml (the online run's report)")
        if args.relearn != "identify":
            raise InputError("--relearn: needs --online PROFILE.toml (the online tuner's)")
        return tune_command(
            load_motor_config(args.motor), args.algorithm or "offpolicy", args.seed, args.json,
            target=args.target,
        )  # fmt: skip
    if args.algorithm not in (None, "offpolicy") or args.target not in (None, "digital"):
        raise InputError(
            "--online: the drive is commissioned with the off-policy learner for the digital"
            " target; leave out --algorithm and --target (or give offpolicy, digital)"
        )
    return online_command(
        load_motor_config(args.motor), args.online, args.seed, args.json, args.report,
        args.relearn,
    )  # fmt: skip


def _add_relearn_option(parser: argparse.ArgumentParser) -> None:
    """``--relearn``: how the online tuner learns its candidates."""
    parser.add_argument(
        "--relearn",
        choices=["identify", "adp"],
        default="identify",
        help=(
            "how the online tuner learns a candidate law: identify-then-design on the"
            " motor's estimated parameters, or the paper's ADP on the last second of the"
            " log (either is certified before a switch; default: %(default)s)"
        ),
    )


def _add_follow(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "follow",
        _run_follow,
        help="run the online tuner on a drive's log as it arrives (a CSV file or standard input)",
        description=(
            "Feed a drive's log, as it arrives, to the online tuner: LOG.csv (or - for"
            " standard input) with the columns t,x1,x2,u1,u2,w1,w2 and, with dead time,"
            " theta (u the voltage commanded at each row). MOTOR.toml says what the tuner"
            " knows (pole pairs, speed, torque reference, nameplate flux, cost, the [drive]"
            " table's period, delay and dead time); --law the controller in force at the"
            " first row (a selftune JSON result). Prints one JSON line per event: a change"
            " detected, a law to switch to (certified, rescaled for the flux, or the"
            " watchdog's return) with every matrix, or why the law in force stays."
        ),
    )
    parser.add_argument("log", metavar="LOG.csv", help="the log, or - for standard input")
    parser.add_argument("--motor", metavar="MOTOR.toml", required=True, help="the motor file")
    parser.add_argument(
        "--law",
        metavar="RESULT.json",
        required=True,
        help="the controller in force at the first row: a selftune tune or learn JSON",
    )
    _add_relearn_option(parser)


def _run_follow(args: argparse.Namespace) -> int:
    from .commands import follow_command
    from .config import load_motor_config

    return follow_command(load_motor_config(args.motor), args.law, args.log, args.relearn)


def _add_bench(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "bench",
        _run_bench,
        help="benchmarks: data efficiency, cost of learning, simulation speed, self-tuning value",
        description=(
            "Run every comparison in one process and write bench.md (tables) and"
            " bench.json (numbers, units in the key names) into --out."
        ),
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help="CI-sized run: smaller sweeps and repeats (well under a minute)",
    )
    _add_out_option(parser, "selftune-bench", "bench.md and bench.json")


def _run_bench(args: argparse.Namespace) -> int:
    from .bench import bench_command

    return bench_command(args.out, args.quick)


#: Registration functions, one per subcommand, in the order of ``selftune --help``.
_COMMANDS: tuple[Callable[[_Subparsers], None], ...] = (
    _add_reproduce,
    _add_tune,
    _add_solve,
    _add_learn,
    _add_follow,
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
    except SelftuneError as exc:
        return _fail(str(exc))
    except BrokenPipeError:  # the reader went away (``selftune solve | head``): stop quietly
        _silence_stdout()
        return 1
    except OSError as exc:
        where = f"{os.fsdecode(exc.filename)}: " if exc.filename is not None else ""
        return _fail(f"{where}{exc.strerror or exc}")
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
