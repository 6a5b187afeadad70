"""The subcommands: one registration function ``_add_<name>(subparsers)`` and one handler
``_run_<name>(args) -> int`` each (see :mod:`selftune.cli`)."""

from __future__ import annotations

import argparse

from ._parsing import (
    _add_command,
    _add_json_option,
    _add_motor_options,
    _add_out_option,
    _add_relearn_option,
    _add_seed_option,
    _motor_config,
    _Subparsers,
)


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
    parser.add_argument(
        "--report",
        metavar="DIR",
        default=None,
        help=(
            "with a [schedule] table: write its figure into DIR, schedule.png and"
            " schedule.svg (the gains, the closed loop's bandwidth and the excess costs"
            " of the schedule and of the single-speed controller against speed)"
        ),
    )


def _run_solve(args: argparse.Namespace) -> int:
    from ..commands import solve_command

    return solve_command(_motor_config(args), args.json, args.report)


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
            " 2016). DATA is a CSV (header t,x1..xn,u1..um,w1..wq), NPZ or MAT file; several"
            " DATA are a saturating motor's current levels, its law scheduled over i_q*."
        ),
    )
    parser.add_argument(
        "data",
        metavar="DATA",
        nargs="+",
        help=(
            "the samples: a .csv, .npz or .mat file; several: a saturating motor's current"
            ' levels, one a log ([learning] structure = "incremental"), the law'
            " scheduled over i_q*"
        ),
    )
    parser.add_argument(
        "--config",
        metavar="CONFIG.toml",
        required=True,
        help="cost weights, initial policy, optional [regulation] and [learning] tables",
    )
    _add_json_option(parser)
    _add_report_option(parser)


def _add_report_option(parser: argparse.ArgumentParser, online: str = "") -> None:
    parser.add_argument(
        "--report",
        metavar="DIR",
        default=None,
        help=(
            "write the report of the learned controller into DIR: report.html (the verdict,"
            " the numbers and six figures, self-contained) and the figures as PNG" + online
        ),
    )


def _run_learn(args: argparse.Namespace) -> int:
    from ..commands import learn_command

    return learn_command(args.data, args.config, args.json, args.report)


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
    from ..commands import reproduce_command

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
    _add_report_option(parser, "; with --online: the online run's figures, JSON and printed report")
    _add_relearn_option(parser)
    _add_seed_option(parser)
    _add_json_option(parser)


def _run_tune(args: argparse.Namespace) -> int:
    from ..commands import online_command, tune_command
    from ..config import load_motor_config
    from ..errors import InputError

    if args.online is None:
        if args.relearn != "identify":
            raise InputError("--relearn: needs --online PROFILE.toml (the online tuner's)")
        return tune_command(
            load_motor_config(args.motor), args.algorithm or "offpolicy", args.seed, args.json,
            target=args.target, report_dir=args.report,
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
    from ..commands import follow_command
    from ..config import load_motor_config

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
    parser.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        default=None,
        help="run the seeded studies on this running Dask scheduler (default: here)",
    )


def _run_bench(args: argparse.Namespace) -> int:
    from ..bench import bench_command

    if args.scheduler is None:  # the same call as ever
        return bench_command(args.out, args.quick)
    return bench_command(args.out, args.quick, args.scheduler)
