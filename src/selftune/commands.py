"""What each command does, given its values: :mod:`selftune.cli` only parses.

:mod:`selftune.cli` parses the command line and calls one of these functions with plain
values; each prints its report to standard output, writes its JSON if asked, and raises
:class:`~selftune.errors.SelftuneError` (one line) on bad input. Each imports what only
it needs when it runs, so ``selftune solve`` loads no learner, simulator or benchmark.

Every output is checked before anything is computed: a ``--json`` file must be absent
or a writable regular file (``-`` writes the JSON to standard output instead, and the
report is then left out, so that the output is the JSON alone); an output directory
must be absent, empty or a previous output set of the same command, which is replaced
as a whole. A computation that warns numerically (an overflow) or fails in numpy or
scipy on absurd input is an error naming the input, never a result.
"""

from __future__ import annotations

import json
import sys
import warnings
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np

from .config import LEARN_TABLES, LearnConfig, MotorConfig, load_learn_config
from .core import (
    Array,
    compact,
    finite_or_null,
    labels,
    matrix_block,
    to_jsonable,
    vector,
    write_json,
)
from .core._atomic import check_output_directory, check_output_file
from .errors import DataFileError, InputError, Refusal, SelftuneError
from .model import ModelBasedSolution, solve_optimal_regulation

__all__ = [
    "REPRODUCE_OUTPUTS",
    "STANDARD_OUTPUT",
    "learn_command",
    "model_based",
    "reproduce_command",
    "solve_command",
    "solve_report",
    "tune_command",
]

#: The ``--json`` value that writes the JSON to standard output.
STANDARD_OUTPUT = "-"

#: The files of ``selftune reproduce``'s output set.
REPRODUCE_OUTPUTS = (
    "results.json",
    *(f"fig{index}.{suffix}" for index in range(1, 6) for suffix in ("png", "svg")),
)

#: Relative residual of the Riccati and regulator equations above which the model-based
#: solution is not trusted (it is about 1e-15 on any motor in the plausible ranges).
RESIDUAL_TOLERANCE = 1e-6

_ADVICE = "check that the values are in SI units and of a realistic size"


def _check_json_target(path: str | None) -> None:
    """Refuse, before anything is computed, a ``--json`` file that cannot be written."""
    if path is not None and path != STANDARD_OUTPUT:
        check_output_file(path)


def _write_json(path: str, data: dict[str, Any]) -> None:
    """Write ``data`` to ``path`` atomically (``-``: to stdout); a failure names ``path``."""
    if path == STANDARD_OUTPUT:
        sys.stdout.write(json.dumps(finite_or_null(to_jsonable(data)), indent=2) + "\n")
        return
    try:
        write_json(path, data)
    except OSError as exc:
        raise SelftuneError(f"{path}: cannot write the file ({exc.strerror or exc})") from None


def _print_report(lines: Sequence[str], json_path: str | None) -> None:
    """The report on stdout (not when the JSON goes there), and where the JSON went."""
    if json_path == STANDARD_OUTPUT:
        return
    print("\n".join(lines))
    if json_path is not None:
        print(f"\nwrote {json_path}")


def _check_numerics(
    source: str, caught: Sequence[warnings.WarningMessage], *results: Array
) -> None:
    """Raise if a computation warned (overflow, lost precision) or gave non-finite numbers.

    Extreme inputs (a weight of 1e300, an inductance of 1e-300) pass every check on their
    own but make the numerics meaningless; better an error than wrong numbers. Other
    warnings are dropped (the command line never shows warnings).
    """
    numeric = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if numeric or not all(np.all(np.isfinite(result)) for result in results):
        reason = f" ({numeric[0].message})" if numeric else ""
        raise SelftuneError(
            f"{source}: the solution is not numerically meaningful{reason}; {_ADVICE}"
        )


@contextmanager
def _numerics(source: str) -> Iterator[list[warnings.WarningMessage]]:
    """Record numerical warnings in the block; name ``source`` in any failure of it.

    A :class:`SelftuneError` gets ``source`` in front; numpy's and scipy's
    ``LinAlgError`` (an SVD that does not converge, a singular matrix) on absurd input
    becomes an :class:`InputError` naming ``source``.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        try:
            yield caught
        except SelftuneError as exc:
            raise exc.retold(f"{source}: {exc}") from None
        except (np.linalg.LinAlgError, FloatingPointError, OverflowError) as exc:
            raise InputError(f"{source}: the computation failed ({exc}); {_ADVICE}") from None


def _check_residuals(config: MotorConfig, solution: ModelBasedSolution) -> None:
    """Raise unless the solution satisfies its equations to :data:`RESIDUAL_TOLERANCE`."""
    problem = solution.problem
    A, B, P, X = problem.A, problem.B, solution.P, solution.X
    equations = {
        "Riccati": [A.T @ P, P @ A, -P @ B @ solution.K, config.Q],
        "regulator": [A @ X, B @ solution.U, problem.D, -X @ problem.E],
        "output": [problem.C @ X, problem.F],
    }
    for name, terms in equations.items():
        residual = float(np.linalg.norm(sum(terms)))
        scale = sum(float(np.linalg.norm(term)) for term in terms)
        if not residual <= RESIDUAL_TOLERANCE * scale:
            raise InputError(
                f"{config.source}: the model-based solution is not numerically meaningful"
                f" (relative residual of the {name} equation {residual / scale:.1e}): the"
                " cost weights Q, R and the motor's parameters are too far apart in scale"
            )


def model_based(config: MotorConfig) -> ModelBasedSolution:
    """The model-based optimum of ``config``; any failure names ``config.source``.

    For every command that needs the truth (``solve``, and those comparing against it).

    Parameters
    ----------
    config : MotorConfig
        The motor, operating point and weights.
    """
    with _numerics(config.source) as caught:
        solution = solve_optimal_regulation(config.regulation_problem(), config.Q, config.R)
        w = config.exogenous()
        steady_state = (solution.X @ w, solution.U @ w)
    _check_numerics(config.source, caught, solution.theta, *steady_state)
    _check_residuals(config, solution)
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
    """``selftune solve``: print the model-based optimum of ``config``; write its JSON.

    Parameters
    ----------
    config : MotorConfig
        The motor, operating point and weights.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    """
    _check_json_target(json_path)
    solution = model_based(config)
    w = config.exogenous()
    if json_path is not None:
        document = {name: getattr(solution, name) for name in ("K", "P", "X", "U", "theta")}
        document.update({"x_e": solution.X @ w, "u_e": solution.U @ w, "w": w})
        document.update({"motor": config.motor})
        document.update({"operating_point": {"speed": config.speed, "torque": config.torque}})
        document.update({"cost": {"Q": config.Q, "R": config.R}})
        _write_json(json_path, document)
    _print_report([solve_report(config, solution)], json_path)
    return 0


def _learn(data: Any, config: LearnConfig, source: str) -> Any:
    """The learned controller for ``config`` on ``data``; any failure names ``source``."""
    from .learn import LearningOptions, LearningProblem, learn_controller

    problem = LearningProblem(
        config.Q, config.R, C=config.C, E=config.E, F=config.F,
        integral_action=config.integral_action,
    )  # fmt: skip
    options = LearningOptions(
        interval=config.interval, max_iterations=config.max_iterations,
        tolerance=config.tolerance, **config.options,  # type: ignore[arg-type]
    )  # fmt: skip
    mistake: DataFileError | None = None
    with _numerics(source) as caught:
        try:
            result = learn_controller(data, problem, config.K0, options)
        except InputError as exc:
            mistake = _against_config(exc, config.source)
            if mistake is None:
                raise
    if mistake is not None:
        raise mistake
    _check_numerics(source, caught, result.P, result.K, result.U)
    return result


def _against_config(error: InputError, config_file: str) -> DataFileError | None:
    """The learner's objection to a configuration value (a key of CONFIG.toml, not a
    refusal of the data), said against the configuration file and its table; None for
    any other error."""
    key, _, reason = str(error).partition(": ")
    tables = [name for name, keys in LEARN_TABLES.items() if key in keys]
    if isinstance(error, Refusal) or not tables or not reason:
        return None
    return DataFileError(f"{config_file}: [{tables[0]}] {key}: {reason}")


def learn_command(data_path: str, config_path: str, json_path: str | None) -> int:
    """``selftune learn``: the learned controller from a CSV or NPZ log and a config.

    The data file's header gives n, m, q; the configuration is read and checked against
    them completely before the rows are loaded. The controller comes with its quality;
    data that do not support one give an error that says why.

    Parameters
    ----------
    data_path : str
        The CSV or NPZ log.
    config_path : str
        CONFIG.toml.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    """
    from .learn import load_trajectory
    from .learn.data._io import trajectory_dimensions

    _check_json_target(json_path)
    config = load_learn_config(config_path, *trajectory_dimensions(data_path))
    data = load_trajectory(data_path)
    result = _learn(data, config, data_path)
    law = result.law
    states, inputs = labels("x", data.n), labels("u", data.m)
    servo = " with integral action" if law.K_i is not None else ""
    lines = [
        f"learned from {data_path}: {data.num_samples} samples, {data.duration:.6g} s",
        f"{result.target} controller{servo} by {result.method} "
        f"({len(result.history)} policy-iteration steps)"
        if result.method == "adp"
        else f"{result.target} controller{servo} by identify-then-design",
        "",
        "the controller (K's columns: " + ", ".join(law.state) + "):",
        f"  {law.equations()}",
        *matrix_block("K", law.K, inputs, list(law.state[: law.K.shape[1]])),
    ]
    if law.K_i is not None:
        lines += matrix_block("K_i", law.K_i, inputs, labels("z", law.K_i.shape[1]))
    if config.regulation:
        exogenous = labels("w", data.q)
        lines += matrix_block("X  steady-state map, x_e = X w", law.X, states, exogenous)
        lines += matrix_block("U  feedforward map, u_e = U w", law.U, inputs, exogenous)
    lines += matrix_block("B  estimated input matrix", result.B, states, inputs)
    lines += ["", *result.quality.lines()]
    if json_path is not None:
        _write_json(json_path, _learn_document(result))
    _print_report(lines, json_path)
    return 0


def _learn_document(result: Any) -> dict[str, Any]:
    """The JSON of ``selftune learn``: the law, its quality, how it was learned."""
    law = result.law
    alignment = result.alignment
    return {
        "target": result.target,
        "method": result.method,
        "h": result.h,
        "input_delay": result.input_delay,
        "state": list(law.state),
        "control_law": law.document(),
        "K": law.K,
        "K_i": law.K_i,
        "X": law.X,
        "U": law.U,
        "P": result.P,
        "B": result.B,
        "quality": result.quality,
        "alignment": {
            "logged_input": alignment.logged_input,
            "shift": alignment.shift,
            "detected_shift": alignment.detected_shift,
            "residuals": {str(shift): value for shift, value in alignment.residuals.items()},
        },
        "iterations": len(result.history),
    }


def tune_command(
    config: MotorConfig,
    algorithm: str,
    seed: int,
    json_path: str | None,
    target: str | None = None,
) -> int:
    """``selftune tune``: a self-tuning session on the simulated drive of ``config``.

    The drive is the ideal one, or the realistic one of the file's ``[drive]`` table; the
    report gives the controller a drive can run, its quality, and what it does on the
    simulated drive (steady torque, also after R_s rose 40%).

    Parameters
    ----------
    config : MotorConfig
        The motor file's content (its [learning] table gives the settings).
    algorithm : str
        ``"1"``, ``"2"``, ``"3"`` or ``"offpolicy"``.
    seed : int
        Exploration seed.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    target : {"continuous", "digital"}, optional
        Overrides the motor file's target.
    """
    from .report import evaluate, torque_check, tune_document, tune_lines
    from .tuning import run_algorithm, tuning_settings

    _check_json_target(json_path)
    settings = tuning_settings(config, seed, target)
    with _numerics(config.source) as caught:
        result = run_algorithm(algorithm, config.motor, settings, drive=config.drive)  # type: ignore[arg-type]
        evaluation = evaluate(result, config.motor, settings, config.drive)
        torque = torque_check(config.motor, settings, result, config.drive)
    _check_numerics(config.source, caught, result.P, result.K)
    lines = tune_lines(config.source, result, evaluation, torque, config.drive)
    if json_path is not None:
        _write_json(json_path, tune_document(config.motor, settings, result, evaluation, torque))
    _print_report(lines, json_path)
    return 0


def _online_drive(config: MotorConfig, seed: int) -> tuple[Any, Any]:
    """The digital servo settings and the drive an online tuner works with (the motor
    file's ``[drive]``, or the ideal drive at the ``[learning]`` sampling period)."""
    from .sim import DriveSettings
    from .tuning import tuning_settings

    drive = config.drive if config.drive is not None else DriveSettings()
    return tuning_settings(config, seed, "digital"), drive


def online_command(
    config: MotorConfig,
    profile_path: str,
    seed: int,
    json_path: str | None,
    report_dir: str | None,
    learner: str = "identify",
) -> int:
    """``selftune tune --online``: commission the drive of ``config``, then run it
    through the profile with the online tuner in the loop; print, and write the JSON and
    the report's figures.

    Parameters
    ----------
    config : MotorConfig
        The motor file's content (its ``[drive]`` table: the drive; without one, the
        ideal drive at the ``[learning]`` sampling period).
    profile_path : str
        PROFILE.toml (:func:`selftune.config.load_online_config`).
    seed : int
        The seed of the commissioning, the noise and the probing.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    report_dir : str or None
        Where to write the figures, the JSON and the printed report as one set.
    learner : {"identify", "adp"}
        How the tuner re-learns.
    """
    from tqdm import tqdm

    from .config import load_online_config
    from .report import (
        ONLINE_REPORT_FILES,
        evaluate_online,
        online_document,
        online_lines,
        write_online_report,
    )
    from .tuning import run_online

    _check_json_target(json_path)
    if report_dir is not None:
        check_output_directory(report_dir, ONLINE_REPORT_FILES, "online report")
    online = load_online_config(profile_path)
    settings, drive = _online_drive(config, seed)
    with (
        tqdm(
            total=round(online.duration, 3), desc="online", unit=" s", file=sys.stderr,
            disable=None, leave=False, bar_format="{desc}: {n:.1f}/{total} s {bar} {elapsed}",
        ) as bar,
        _numerics(config.source) as caught,
    ):  # fmt: skip

        def progress(now: float) -> None:
            bar.update(now - bar.n)

        run = run_online(
            config.motor, settings, drive, online.profile, online.duration, seed=seed,
            progress=progress, learner=learner,  # type: ignore[arg-type]
        )  # fmt: skip
        evaluation = evaluate_online(run)
    _check_numerics(config.source, caught, run.cold.P, run.cold.K)
    lines = online_lines(config.source, run, evaluation)
    if json_path is not None:
        _write_json(json_path, online_document(run, evaluation))
    if report_dir is not None:
        write_online_report(run, evaluation, lines, report_dir)
    _print_report(lines, json_path)
    if report_dir is not None and json_path != STANDARD_OUTPUT:
        print(f"wrote {report_dir}/ ({', '.join(ONLINE_REPORT_FILES)})")
    return 0


def follow_command(
    config: MotorConfig, law_path: str, log_path: str, learner: str = "identify"
) -> int:
    """``selftune follow``: the online tuner's events on a drive's log as it arrives,
    one JSON line each on standard output.

    Parameters
    ----------
    config : MotorConfig
        What the tuner knows (the motor file; without a ``[drive]`` table, the ideal
        drive at the ``[learning]`` sampling period).
    law_path : str
        The JSON result whose controller is in force at the log's first row.
    log_path : str
        The CSV log, or ``-`` for standard input.
    learner : {"identify", "adp"}
        How the tuner re-learns.
    """
    import io

    from .config import load_control_law
    from .core._atomic import open_regular_file
    from .learn import read_csv_chunks
    from .learn.online import OnlineTuner
    from .tuning import CHUNK_SECONDS, follow, online_settings

    settings, drive = _online_drive(config, 0)
    tuner = online_settings(config.motor, settings, drive, learner)  # type: ignore[arg-type]
    law = load_control_law(law_path)
    try:  # the law must fit the drive: said of the file that gave it
        OnlineTuner(tuner, law)
    except InputError as exc:
        raise DataFileError(f"{law_path}: {exc}") from None
    rows = max(1, round(CHUNK_SECONDS / settings.h))
    if log_path == STANDARD_OUTPUT:
        stream, source = sys.stdin, "standard input"
    else:
        stream = io.TextIOWrapper(open_regular_file(log_path), encoding="utf-8", newline="")
        source = log_path
    names = tuner.structure.names(tuner.dead_time)
    with stream:
        for time, event in follow(tuner, law, read_csv_chunks(stream, source, rows), source):
            line: dict[str, Any] = {"time": time, "kind": event.kind, "reason": event.reason}
            if event.law is not None:
                line["control_law"] = event.law.document()
            if event.estimate is not None:
                line["estimate"] = dict(zip(names, event.estimate.theta, strict=True))
                line["standard_errors"] = dict(
                    zip(names, event.estimate.standard_errors, strict=True)
                )
            print(json.dumps(finite_or_null(to_jsonable(line))), flush=True)
    return 0


def reproduce_command(out: str, seed: int) -> int:
    """``selftune reproduce``: the paper's Section V into ``out``, with progress on a
    terminal.

    Parameters
    ----------
    out : str
        The output directory: absent, empty, or a previous output of this command (its
        files are replaced as one set); checked before anything is computed.
    seed : int
        Exploration seed.
    """
    from tqdm import tqdm

    from .report import ALGORITHM_LABELS, report, reproduce, write_outputs

    check_output_directory(out, REPRODUCE_OUTPUTS, "selftune reproduce output")
    with tqdm(
        total=len(ALGORITHM_LABELS) + 2,
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
