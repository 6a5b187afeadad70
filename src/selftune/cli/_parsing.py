"""The parser's parts every subcommand shares: usage errors as one line, negative numbers
as values, and the options and argument types of several commands."""

from __future__ import annotations

import argparse
import dataclasses
import math
import re
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NoReturn, TypeAlias

from ..errors import InputError

if TYPE_CHECKING:
    from ..config import MotorConfig

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
    from ..config import MotorConfig, load_motor_config

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
