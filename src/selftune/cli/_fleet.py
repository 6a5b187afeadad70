"""``selftune fleet``: its registration and handler (see :mod:`selftune.cli`)."""

from __future__ import annotations

import argparse

from ._parsing import _add_command, _Subparsers


def _positive_count(text: str) -> int:
    """argparse type: a whole number of at least 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _add_fleet(subparsers: _Subparsers) -> None:
    parser = _add_command(
        subparsers,
        "fleet",
        _run_fleet,
        help="learn a fleet's logs on Dask into one table, with the outliers and refusals",
        description=(
            "Learn every log as selftune learn does, on a Dask cluster (a local one sized"
            " to the machine, or --scheduler), streaming a row per log into"
            " DIR/results.parquet and DIR/results.csv: the drive, the verdict or why not,"
            " K, K_i, U, the identified R_s, L_s, phi_pm and dead-time voltage with their"
            " standard errors, the data used and the time taken. Then DIR/summary.md and"
            " DIR/fleet.png: the spread of the parameters, the drives that stand out of"
            " their group, the refusals by cause. A rerun skips the logs already in the"
            " table. Needs the extra: pip install 'selftune[fleet]'."
        ),
    )
    parser.add_argument(
        "logs",
        metavar="LOGS",
        nargs="+",
        help=(
            "logs (.csv, .npz), directories of them, globs, or a manifest CSV (header"
            " path,drive[,group,config,table.key...]: per-drive overrides of CONFIG.toml)"
        ),
    )
    parser.add_argument(
        "--config", metavar="CONFIG.toml", required=True, help="selftune learn's configuration"
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        required=True,
        help="output directory: new, empty, or an earlier fleet's (its table is added to)",
    )
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="a running Dask scheduler (tcp://host:8786); default: a local cluster",
    )
    parser.add_argument(
        "--workers",
        type=_positive_count,
        default=None,
        metavar="N",
        help="worker processes of the local cluster (default: the machine's cores)",
    )
    parser.add_argument(
        "--serial",
        action="store_true",
        help="learn here, one log after another, without a cluster",
    )


def _run_fleet(args: argparse.Namespace) -> int:
    from ..commands import fleet_command
    from ..errors import InputError

    if args.serial and (args.scheduler is not None or args.workers is not None):
        raise InputError("--serial: runs without a cluster; leave out --scheduler and --workers")
    if args.scheduler is not None and args.workers is not None:
        raise InputError("--workers: sizes the local cluster; leave it out with --scheduler")
    return fleet_command(
        args.logs, args.config, args.out, args.scheduler, args.workers, args.serial
    )
