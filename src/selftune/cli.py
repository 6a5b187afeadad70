"""The ``selftune`` command line.

Each subcommand is one handler function, ``_run_<name>(args) -> int``, and one
registration function, ``_add_<name>(subparsers)``, listed in :data:`_COMMANDS`. Handlers
raise :class:`~selftune.errors.SelftuneError` on bad input; :func:`main` turns it (and
``OSError``) into one line on stderr, ``selftune: error: <message>``, and exit code 2.

Commands
--------
``selftune solve [--motor MOTOR.toml] [--speed S] [--torque T] [--json FILE]``
    The model-based optimal torque controller (K*, P*, X*, U*, Theta*) and the operating
    point (x_e, u_e), for the paper's motor or the one in MOTOR.toml.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import os
import sys
import warnings
from collections.abc import Callable, Sequence
from typing import TypeAlias

import numpy as np
from numpy.typing import NDArray

from . import __version__
from ._atomic import write_json
from .config import MotorConfig, load_learn_config, load_motor_config
from .errors import SelftuneError
from .io import load_trajectory
from .learning import learn_lqr, learn_output_regulation
from .regulation import ModelBasedSolution, solve_optimal_regulation

__all__ = ["build_parser", "main", "solve_report"]

Array = NDArray[np.float64]

#: Exit code of a usage error or of bad input (argparse uses 2 as well).
EXIT_USAGE = 2

_Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


# -- shared options and helpers -------------------------------------------------------


def _finite_float(text: str) -> float:
    """argparse type: a finite number (rejects nan and inf)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite: {text!r}")
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
    config = MotorConfig.default() if args.motor is None else load_motor_config(args.motor)
    overrides = {
        name: value
        for name, value in (("speed", args.speed), ("torque", args.torque))
        if value is not None
    }
    return dataclasses.replace(config, **overrides) if overrides else config


def _number(value: float) -> str:
    """Four decimals, and never ``-0.0000``."""
    text = f"{value:.4f}"
    return text[1:] if text == "-0.0000" else text


def _vector(values: Array) -> str:
    return "[" + ", ".join(_number(float(value)) for value in values) + "]"


def _matrix_block(
    title: str, matrix: Array, rows: Sequence[str], columns: Sequence[str]
) -> list[str]:
    """A titled matrix with labelled rows and columns."""
    cells = [[_number(float(value)) for value in row] for row in matrix]
    width = max([len(cell) for row in cells for cell in row] + [len(c) for c in columns])
    label_width = max(len(label) for label in rows)
    lines = [title, " " * (2 + label_width) + "".join(f"  {c:>{width}}" for c in columns)]
    for label, row in zip(rows, cells, strict=True):
        lines.append(f"  {label:<{label_width}}" + "".join(f"  {c:>{width}}" for c in row))
    return lines


def _write_json(path: str, data: dict[str, object]) -> None:
    """Write ``data`` to ``path`` atomically; a failure names ``path``."""
    try:
        write_json(path, data)
    except OSError as exc:
        raise SelftuneError(f"{path}: cannot write the file ({exc.strerror or exc})") from None


# -- selftune solve -------------------------------------------------------------------


def _add_solve(subparsers: _Subparsers) -> None:
    parser = subparsers.add_parser(
        "solve",
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
    parser.add_argument(
        "--json", metavar="FILE", help="also write the results to FILE as JSON (nested lists)"
    )
    parser.set_defaults(handler=_run_solve)


def solve_report(config: MotorConfig, solution: ModelBasedSolution) -> str:
    """The human-readable report that ``selftune solve`` prints.

    Parameters
    ----------
    config : MotorConfig
        The motor, operating point and weights that were solved.
    solution : ModelBasedSolution
        The result of :func:`~selftune.regulation.solve_optimal_regulation`.

    Returns
    -------
    str
        Several lines, numbers to 4 decimals.
    """
    motor = config.motor
    w = config.exogenous()
    x_e, u_e = solution.X @ w, solution.U @ w
    state, inputs = ("i_d", "i_q"), ("u_d", "u_q")
    exogenous = ("w_1", "w_2")
    inertia = "" if motor.J is None else f", J = {motor.J:g} kg m^2"
    lines = [
        f"Model-based optimal torque control ({config.source})",
        f"  motor: R_s = {motor.R_s:g} ohm, L_s = {motor.L_s:g} H,"
        f" phi_pm = {motor.phi_pm:g} Wb, p = {motor.p}{inertia}",
        f"  operating point: speed = {config.speed:g} rad/s (mechanical),"
        f" torque = {config.torque:g} N m",
        f"  cost weights: Q = {_compact(config.Q)}, R = {_compact(config.R)}",
        "  state x = [i_d, i_q] (A), input u = [u_d, u_q] (V),",
        f"  exogenous w = [p speed phi_pm (V), T* (N m)] = {_vector(w)}",
        "  control u = -K* (x - X* w) + U* w",
        "",
    ]
    lines += _matrix_block("K*  optimal feedback gain, V/A", solution.K, inputs, state)
    lines += [""]
    lines += _matrix_block(
        "P*  value matrix: optimal cost-to-go (x - X* w)' P* (x - X* w)", solution.P, state, state
    )
    lines += [""]
    lines += _matrix_block(
        "X*  steady-state map, x_e = X* w (A/V, A/(N m))", solution.X, state, exogenous
    )
    lines += [""]
    lines += _matrix_block(
        "U*  feedforward map, u_e = U* w (V/V, V/(N m))", solution.U, inputs, exogenous
    )
    lines += [
        "",
        "Theta* = [vecs(P*); vec(K*); vec((D + A X*)' P*)]  (unknowns of the data equation)",
        f"  {_vector(solution.theta)}",
        "",
        "Operating point",
        f"  x_e = X* w = {_vector(x_e)} A  [i_d, i_q]",
        f"  u_e = U* w = {_vector(u_e)} V  [u_d, u_q]",
    ]
    return "\n".join(lines)


def _check_numerics(
    source: str, caught: Sequence[warnings.WarningMessage], *results: Array
) -> None:
    """Raise if a computation warned (overflow, lost precision) or gave non-finite numbers.

    Extreme inputs (a weight of 1e300, an inductance of 1e-300) pass every check on their
    own but make the numerics meaningless; better an error than wrong numbers.
    """
    numeric = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if numeric or not all(np.all(np.isfinite(result)) for result in results):
        reason = f" ({numeric[0].message})" if numeric else ""
        raise SelftuneError(
            f"{source}: the solution is not numerically meaningful{reason};"
            " check that the values are in SI units and of a realistic size"
        )
    for other in caught:  # anything else: show it as usual
        warnings.showwarning(other.message, other.category, other.filename, other.lineno)


def _compact(M: Array) -> str:
    """A small matrix on one line, ``[[1000, 0], [0, 1000]]``."""
    return "[" + ", ".join("[" + ", ".join(f"{v:g}" for v in row) + "]" for row in M) + "]"


def _model_based(config: MotorConfig) -> ModelBasedSolution:
    """The model-based optimum of ``config``; any failure names ``config.source``.

    For every command that needs the truth (``solve``, and those comparing against it).
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        try:
            solution = solve_optimal_regulation(config.regulation_problem(), config.Q, config.R)
            w = config.exogenous()
            steady_state = (solution.X @ w, solution.U @ w)
        except SelftuneError as exc:
            raise type(exc)(f"{config.source}: {exc}") from None
    _check_numerics(config.source, caught, solution.theta, *steady_state)
    return solution


def _run_solve(args: argparse.Namespace) -> int:
    config = _motor_config(args)
    solution = _model_based(config)
    w = config.exogenous()
    x_e, u_e = solution.X @ w, solution.U @ w
    if args.json is not None:
        motor = config.motor
        _write_json(
            args.json,
            {
                "K": solution.K,
                "P": solution.P,
                "X": solution.X,
                "U": solution.U,
                "theta": solution.theta,
                "x_e": x_e,
                "u_e": u_e,
                "w": w,
                "motor": {
                    "R_s": motor.R_s,
                    "L_s": motor.L_s,
                    "phi_pm": motor.phi_pm,
                    "p": motor.p,
                    "J": motor.J,
                },
                "operating_point": {"speed": config.speed, "torque": config.torque},
                "cost": {"Q": config.Q, "R": config.R},
            },
        )
    print(solve_report(config, solution))
    if args.json is not None:
        print(f"\nwrote {args.json}")
    return 0


# -- selftune learn -------------------------------------------------------------------


def _add_learn(subparsers: _Subparsers) -> None:
    parser = subparsers.add_parser(
        "learn",
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
    parser.add_argument("--json", metavar="FILE", help="also write the results to FILE as JSON")
    parser.set_defaults(handler=_run_learn)


def _labels(prefix: str, count: int) -> list[str]:
    return [f"{prefix}{index + 1}" for index in range(count)]


def _run_learn(args: argparse.Namespace) -> int:
    data = load_trajectory(args.data)
    config = load_learn_config(args.config, data.n, data.m, data.q)
    try:
        if config.regulation:
            assert config.C is not None and config.E is not None and config.F is not None
            learned = learn_output_regulation(
                data,
                config.C,
                config.E,
                config.F,
                config.Q,
                config.R,
                config.K0,
                interval=config.interval,
                max_iterations=config.max_iterations,
                tolerance=config.tolerance,
            )
        else:
            learned_lqr = learn_lqr(
                data,
                config.Q,
                config.R,
                config.K0,
                interval=config.interval,
                max_iterations=config.max_iterations,
                tolerance=config.tolerance,
            )
    except SelftuneError as exc:
        raise type(exc)(f"{args.data}: {exc}") from None
    result = learned if config.regulation else learned_lqr
    states, inputs = _labels("x", data.n), _labels("u", data.m)
    lines = [
        f"learned from {args.data}: {data.num_samples} samples, {data.duration:.6g} s",
        f"policy iteration: {result.iterations} steps, converged, regression rank "
        f"{result.rank} of {result.unknowns} unknowns"
        + (f" ({learned.rows} intervals, {learned.method} method)" if config.regulation else ""),
        "",
        *_matrix_block("K  optimal feedback gain, u = -K x", result.K, inputs, states),
        *_matrix_block("P  value matrix", result.P, states, states),
        *_matrix_block("B  estimated input matrix", result.B, states, inputs),
    ]
    output: dict[str, object] = {"P": result.P, "K": result.K, "B": result.B}
    if config.regulation:
        exogenous = _labels("w", data.q)
        lines += [
            *_matrix_block("X  steady-state map, x_ss = X w", learned.X, states, exogenous),
            *_matrix_block("U  feedforward map, u_ss = U w", learned.U, inputs, exogenous),
            *_matrix_block("L  = U + K X, u = -K x + L w", learned.L, inputs, exogenous),
        ]
        output.update({"X": learned.X, "U": learned.U, "L": learned.L})
    output.update(
        {
            "iterations": result.iterations,
            "converged": result.converged,
            "rank": result.rank,
            "unknowns": result.unknowns,
        }
    )
    if args.json is not None:
        _write_json(args.json, output)
    print("\n".join(lines))
    if args.json is not None:
        print(f"\nwrote {args.json}")
    return 0


# -- selftune reproduce ---------------------------------------------------------------


def _progress(total: int, description: str) -> Callable[[str], None]:
    """A step callback showing a progress bar on a terminal (stderr), silent otherwise."""
    from tqdm import tqdm

    bar = tqdm(
        total=total,
        desc=description,
        file=sys.stderr,
        disable=not sys.stderr.isatty(),
        leave=False,
        bar_format="{desc}: {n_fmt}/{total_fmt} {bar} {postfix}",
    )
    started = False

    def step(label: str) -> None:
        nonlocal started
        if started:
            bar.update(1)
        started = True
        bar.set_postfix_str(label)
        if bar.n >= total - 1 and label == "done":
            bar.close()

    return step


def _add_reproduce(subparsers: _Subparsers) -> None:
    parser = subparsers.add_parser(
        "reproduce",
        help="regenerate the paper's Section V: table, results.json and Figs. 1-5",
        description=(
            "Run Algorithms 1, 2, 3 and the off-policy variant with the paper's settings on"
            " the paper's motor (reconciled parameters), print Theta* against each learned"
            " Theta, and write fig1..fig5 (PNG and SVG) and results.json."
        ),
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        default="selftune-results",
        help="directory for the figures and results.json (default: %(default)s)",
    )
    parser.add_argument("--seed", type=int, default=0, help="exploration seed (default: 0)")
    parser.set_defaults(handler=_run_reproduce)


def _run_reproduce(args: argparse.Namespace) -> int:
    from .reproduce import ALGORITHMS, report, reproduce, write_outputs

    step = _progress(len(ALGORITHMS) + 3, "reproduce")
    reproduction = reproduce(args.seed, step=step)
    step("figures")
    paths = write_outputs(reproduction, args.out)
    step("done")
    print(report(reproduction))
    print(
        f"\nlearning and simulation took {reproduction.wall_seconds:.2f} s; wrote "
        f"{len(paths)} files to {args.out}/ (fig1..fig5 .png/.svg, results.json)"
    )
    return 0


# -- selftune tune --------------------------------------------------------------------


def _add_tune(subparsers: _Subparsers) -> None:
    parser = subparsers.add_parser(
        "tune",
        help="run a self-tuning session on the motor in a file and compare with the optimum",
        description=(
            "Self-tune the torque controller of the (simulated) motor in MOTOR.toml with one"
            " of the paper's algorithms or the off-policy variant, then print the learned"
            " controller against the model-based one. The learner is told only the pole"
            " pairs, the speed, the torque reference and (except Algorithm 3) the flux."
        ),
    )
    parser.add_argument("--motor", metavar="MOTOR.toml", required=True, help="the motor file")
    parser.add_argument(
        "--algorithm",
        choices=["1", "2", "3", "offpolicy"],
        default="offpolicy",
        help="which algorithm (default: %(default)s)",
    )
    parser.add_argument("--seed", type=int, default=0, help="exploration seed (default: 0)")
    parser.add_argument("--json", metavar="FILE", help="also write the results to FILE as JSON")
    parser.set_defaults(handler=_run_tune)


def _run_tune(args: argparse.Namespace) -> int:
    from .config import tuning_settings
    from .reproduce import history_document, regulator_document
    from .torque import evaluate, run_algorithm

    config = load_motor_config(args.motor)
    settings = tuning_settings(config, args.seed)
    optimum = _model_based(config)
    try:
        result = run_algorithm(args.algorithm, config.motor, settings)
    except SelftuneError as exc:
        raise type(exc)(f"{args.motor}: {exc}") from None
    evaluation = evaluate(result, config.motor, settings)
    names = {"1": "Algorithm 1", "2": "Algorithm 2", "3": "Algorithm 3", "offpolicy": "off-policy"}
    states, inputs, exogenous = ["i_d", "i_q"], ["u_d", "u_q"], ["w1", "w2"]
    lines = [
        f"{names[args.algorithm]} on {config.source}: {result.data_seconds * 1e3:.3g} ms of "
        f"motor data, {1 + result.history[-1].iteration} iterations, "
        f"{'converged' if result.converged else 'NOT converged'}",
        "",
    ]
    for title, learned, truth, rows, columns in (
        ("K, V/A", result.K, optimum.K, inputs, states),
        ("P", result.P, optimum.P, states, states),
        ("X", result.X, optimum.X, states, exogenous),
        ("U", result.U, optimum.U, inputs, exogenous),
    ):
        lines += _matrix_block(f"learned {title}", learned, rows, columns)
        lines += _matrix_block(f"model-based {title}", truth, rows, columns)
    lines += [
        "",
        f"||Theta - Theta*|| / ||Theta*|| = {evaluation.final_theta_error:.2e}",
        f"||K - K*|| / ||K*|| = {evaluation.K_error:.2e},  "
        f"||U - U*|| / ||U*|| = {evaluation.U_error:.2e}",
    ]
    if result.identified:
        lines.append(
            f"identified phi_pm = {result.identified['phi_pm']:.8g} Wb "
            f"(true {config.motor.phi_pm:g}), L_s = {result.identified['L_s']:.8g} H "
            f"(true {config.motor.L_s:g})"
        )
    lines += list(result.notes)
    if args.json is not None:
        learned_document: dict[str, object] = dict(regulator_document(result))
        if result.identified:
            learned_document.update(result.identified)
        _write_json(
            args.json,
            {
                "algorithm": args.algorithm,
                "learned": learned_document,
                "model_based": regulator_document(optimum),
                "theta_relative_error": evaluation.final_theta_error,
                "data_seconds": result.data_seconds,
                "history": history_document(result, evaluation),
            },
        )
    print("\n".join(lines))
    if args.json is not None:
        print(f"\nwrote {args.json}")
    return 0


# -- selftune bench -------------------------------------------------------------------


def _add_bench(subparsers: _Subparsers) -> None:
    from .bench import add_bench_arguments

    parser = subparsers.add_parser(
        "bench",
        help="benchmarks: data efficiency, cost of learning, simulation speed, self-tuning value",
        description=(
            "Run every comparison in one process and write bench.md (tables) and"
            " bench.json (numbers, units in the key names) into --out."
        ),
    )
    add_bench_arguments(parser)
    parser.set_defaults(handler=_run_bench)


def _run_bench(args: argparse.Namespace) -> int:
    from .bench import run_bench_command

    return run_bench_command(args)


# -- the parser and main --------------------------------------------------------------

#: Registration functions, one per subcommand, in the order of ``selftune --help``.
_COMMANDS: tuple[Callable[[_Subparsers], None], ...] = (
    _add_reproduce,
    _add_tune,
    _add_solve,
    _add_learn,
    _add_bench,
)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``selftune`` with every subcommand registered."""
    parser = argparse.ArgumentParser(
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
        ``selftune: error: <message>``.
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # usage error (2), or --help / --version (0)
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
