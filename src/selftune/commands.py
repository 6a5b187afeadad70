"""What each command does, given its values: :mod:`selftune.cli` only parses.

:mod:`selftune.cli` parses the command line and calls one of these functions with plain
values; each prints its report to standard output, writes its JSON if asked, and raises
:class:`~selftune.errors.SelftuneError` (one line) on bad input. Each imports what only
it needs when it runs, so ``selftune solve`` loads no learner, simulator or benchmark.
"""

from __future__ import annotations

import sys
import warnings
from collections.abc import Sequence
from typing import Any

import numpy as np

from .config import MotorConfig, load_learn_config
from .core import Array, compact, labels, matrix_block, vector, write_json
from .errors import SelftuneError
from .model import ModelBasedSolution, solve_optimal_regulation

__all__ = [
    "learn_command",
    "model_based",
    "reproduce_command",
    "solve_command",
    "solve_report",
    "tune_command",
]


def _write_json(path: str, data: dict[str, Any]) -> None:
    """Write ``data`` to ``path`` atomically; a failure names ``path``."""
    try:
        write_json(path, data)
    except OSError as exc:
        raise SelftuneError(f"{path}: cannot write the file ({exc.strerror or exc})") from None


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


def model_based(config: MotorConfig) -> ModelBasedSolution:
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


def solve_report(config: MotorConfig, solution: ModelBasedSolution) -> str:
    """The human-readable report that ``selftune solve`` prints.

    Parameters
    ----------
    config : MotorConfig
        The motor, operating point and weights that were solved.
    solution : ModelBasedSolution
        The result of :func:`~selftune.model.solve_optimal_regulation`.

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
        f"  cost weights: Q = {compact(config.Q)}, R = {compact(config.R)}",
        "  state x = [i_d, i_q] (A), input u = [u_d, u_q] (V),",
        f"  exogenous w = [p speed phi_pm (V), T* (N m)] = {vector(w)}",
        "  control u = -K* (x - X* w) + U* w",
        "",
        *matrix_block("K*  optimal feedback gain, V/A", solution.K, inputs, state),
        "",
        *matrix_block(
            "P*  value matrix: optimal cost-to-go (x - X* w)' P* (x - X* w)",
            solution.P,
            state,
            state,
        ),
        "",
        *matrix_block(
            "X*  steady-state map, x_e = X* w (A/V, A/(N m))", solution.X, state, exogenous
        ),
        "",
        *matrix_block(
            "U*  feedforward map, u_e = U* w (V/V, V/(N m))", solution.U, inputs, exogenous
        ),
        "",
        "Theta* = [vecs(P*); vec(K*); vec((D + A X*)' P*)]  (unknowns of the data equation)",
        f"  {vector(solution.theta)}",
        "",
        "Operating point",
        f"  x_e = X* w = {vector(x_e)} A  [i_d, i_q]",
        f"  u_e = U* w = {vector(u_e)} V  [u_d, u_q]",
    ]
    return "\n".join(lines)


def solve_command(config: MotorConfig, json_path: str | None) -> int:
    """``selftune solve``: print the model-based optimum of ``config``; write its JSON."""
    solution = model_based(config)
    w = config.exogenous()
    if json_path is not None:
        document = {name: getattr(solution, name) for name in ("K", "P", "X", "U", "theta")}
        document.update({"x_e": solution.X @ w, "u_e": solution.U @ w, "w": w})
        document.update({"motor": config.motor})
        document.update({"operating_point": {"speed": config.speed, "torque": config.torque}})
        document.update({"cost": {"Q": config.Q, "R": config.R}})
        _write_json(json_path, document)
    print(solve_report(config, solution))
    if json_path is not None:
        print(f"\nwrote {json_path}")
    return 0


def learn_command(data_path: str, config_path: str, json_path: str | None) -> int:
    """``selftune learn``: the learned controller from a CSV or NPZ log and a config."""
    from .learn import learn_lqr, learn_output_regulation, load_trajectory

    data = load_trajectory(data_path)
    config = load_learn_config(config_path, data.n, data.m, data.q)
    interval, iterations, tolerance = config.interval, config.max_iterations, config.tolerance
    try:
        if config.C is not None and config.E is not None and config.F is not None:
            result: Any = learn_output_regulation(
                data, config.C, config.E, config.F, config.Q, config.R, config.K0,
                interval=interval, max_iterations=iterations, tolerance=tolerance,
            )  # fmt: skip
        else:
            result = learn_lqr(
                data, config.Q, config.R, config.K0,
                interval=interval, max_iterations=iterations, tolerance=tolerance,
            )  # fmt: skip
    except SelftuneError as exc:
        raise type(exc)(f"{data_path}: {exc}") from None
    states, inputs = labels("x", data.n), labels("u", data.m)
    lines = [
        f"learned from {data_path}: {data.num_samples} samples, {data.duration:.6g} s",
        f"policy iteration: {result.iterations} steps, converged, regression rank "
        f"{result.rank} of {result.unknowns} unknowns"
        + (f" ({result.rows} intervals, {result.method} method)" if config.regulation else ""),
        "",
        *matrix_block("K  optimal feedback gain, u = -K x", result.K, inputs, states),
        *matrix_block("P  value matrix", result.P, states, states),
        *matrix_block("B  estimated input matrix", result.B, states, inputs),
    ]
    output: dict[str, Any] = {"P": result.P, "K": result.K, "B": result.B}
    if config.regulation:
        exogenous = labels("w", data.q)
        lines += [
            *matrix_block("X  steady-state map, x_ss = X w", result.X, states, exogenous),
            *matrix_block("U  feedforward map, u_ss = U w", result.U, inputs, exogenous),
            *matrix_block("L  = U + K X, u = -K x + L w", result.L, inputs, exogenous),
        ]
        output.update({"X": result.X, "U": result.U, "L": result.L})
    output.update(
        {
            "iterations": result.iterations,
            "converged": result.converged,
            "rank": result.rank,
            "unknowns": result.unknowns,
        }
    )
    if json_path is not None:
        _write_json(json_path, output)
    print("\n".join(lines))
    if json_path is not None:
        print(f"\nwrote {json_path}")
    return 0


_NAMES = {"1": "Algorithm 1", "2": "Algorithm 2", "3": "Algorithm 3", "offpolicy": "off-policy"}


def tune_command(config: MotorConfig, algorithm: str, seed: int, json_path: str | None) -> int:
    """``selftune tune``: a self-tuning session on the simulated motor of ``config``."""
    from .report import evaluate, history_document, regulator_document
    from .tuning import run_algorithm, tuning_settings

    settings = tuning_settings(config, seed)
    optimum = model_based(config)
    try:
        result = run_algorithm(algorithm, config.motor, settings)  # type: ignore[arg-type]
    except SelftuneError as exc:
        raise type(exc)(f"{config.source}: {exc}") from None
    evaluation = evaluate(result, config.motor, settings)
    states, inputs, exogenous = ["i_d", "i_q"], ["u_d", "u_q"], ["w1", "w2"]
    lines = [
        f"{_NAMES[algorithm]} on {config.source}: {result.data_seconds * 1e3:.3g} ms of "
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
        lines += matrix_block(f"learned {title}", learned, rows, columns)
        lines += matrix_block(f"model-based {title}", truth, rows, columns)
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
    if json_path is not None:
        learned_document: dict[str, object] = dict(regulator_document(result))
        learned_document.update(result.identified)
        _write_json(
            json_path,
            {
                "algorithm": algorithm,
                "learned": learned_document,
                "model_based": regulator_document(optimum),
                "theta_relative_error": evaluation.final_theta_error,
                "data_seconds": result.data_seconds,
                "history": history_document(result, evaluation),
            },
        )
    print("\n".join(lines))
    if json_path is not None:
        print(f"\nwrote {json_path}")
    return 0


def reproduce_command(out: str, seed: int) -> int:
    """``selftune reproduce``: the paper's Section V into ``out``, with progress on a
    terminal."""
    from tqdm import tqdm

    from .report import ALGORITHMS, report, reproduce, write_outputs

    with tqdm(
        total=len(ALGORITHMS) + 2,
        desc="reproduce",
        file=sys.stderr,
        disable=None,
        leave=False,
        bar_format="{desc}: {n_fmt}/{total_fmt} {bar} {postfix}",
    ) as bar:

        def step(label: str) -> None:
            bar.set_postfix_str(label)
            bar.update(1)

        reproduction = reproduce(seed, step=step)
        step("figures")
        paths = write_outputs(reproduction, out)
    print(report(reproduction))
    print(
        f"\nlearning and simulation took {reproduction.wall_seconds:.2f} s; wrote "
        f"{len(paths)} files to {out}/ (fig1..fig5 .png/.svg, results.json)"
    )
    return 0
