"""``selftune solve``: the model-based optimum, checked against its own equations."""

from __future__ import annotations

import numpy as np

from ..config import MotorConfig
from ..core import compact, cost_document, matrix_block, vector
from ..core._atomic import check_output_directory, output_directory
from ..errors import InputError
from ..model import ModelBasedSolution, solve_optimal_regulation
from ._output import (
    STANDARD_OUTPUT,
    _check_json_target,
    _check_numerics,
    _numerics,
    _print_report,
    _write_json,
)
from ._schedule import ScheduleRun, schedule_document, schedule_lines, scheduled

#: Relative residual of the Riccati and regulator equations above which the model-based
#: solution is not trusted (it is about 1e-15 on any motor in the plausible ranges).
RESIDUAL_TOLERANCE = 1e-6


#: Each reference entry's unit and note, for the printout.
_UNITS = {"p speed phi_pm": ("V", ""), "T*": ("N m", ""), "i_d*": ("A", ", MTPA"),
          "i_q*": ("A", ", MTPA")}  # fmt: skip


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
    exogenous = tuple(f"w_{i + 1}" for i in range(w.size))
    units = [_UNITS[name][0] for name in motor.reference_names]
    names = [f"{name} ({_UNITS[name][0]}{_UNITS[name][1]})" for name in motor.reference_names]

    def per(unit: str) -> str:
        return ", ".join(
            f"{unit}/({other})" if " " in other else f"{unit}/{other}" for other in units
        )

    lines = [
        f"Model-based optimal torque control ({config.source})",
        f"  motor: {motor.describe()}",
        f"  operating point: speed = {config.speed:g} rad/s (mechanical),"
        f" torque = {config.torque:g} N m",
        f"  cost weights: Q = {compact(config.Q)}, R = {compact(config.R)}",
        "  state x = [i_d, i_q] (A), input u = [u_d, u_q] (V),",
        f"  exogenous w = [{', '.join(names)}] = {vector(w)}",
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
            f"X*  steady-state map, x_e = X* w ({per('A')})", solution.X, state, exogenous
        ),
        "",
        *matrix_block(
            f"U*  feedforward map, u_e = U* w ({per('V')})", solution.U, inputs, exogenous
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


def solve_command(config: MotorConfig, json_path: str | None, report_dir: str | None = None) -> int:
    """``selftune solve``: print the model-based optimum of ``config``; write its JSON
    (with the whole problem: the motor, the operating point, the cost ``Q, R, Q_i``, the
    sampling period and the delay, 0 for this continuous-time optimum). With a
    ``[schedule]`` table, also the digital optimum scheduled over speed and its check
    (:mod:`._schedule`): printed as a table, and in the JSON ``schedule``,
    ``schedule_design`` and ``control_law`` (the digital optimum at the operating point).

    Parameters
    ----------
    config : MotorConfig
        The motor, operating point and weights.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    report_dir : str or None
        Where to write the schedule's figure (:data:`selftune.report.SCHEDULE_FILES`); needs a
        ``[schedule]`` table.
    """
    _check_json_target(json_path)
    if report_dir is not None:
        if config.schedule is None:
            raise InputError(
                f"--report: the figure is a speed schedule's, and {config.source} has no"
                " [schedule] table (speeds = [...] or speed_range = [min, max])"
            )
        from ..report import SCHEDULE_FILES  # drawing loads the report (not otherwise)

        check_output_directory(report_dir, SCHEDULE_FILES, "schedule report")
    solution = model_based(config)
    w = config.exogenous()
    with _numerics(config.source) as caught:
        run = scheduled(config)
    lines = [solve_report(config, solution)]
    if config.saturation is not None:
        from ..sim import FluxMap

        whose = "nameplate" if isinstance(config.saturation, FluxMap) else "unsaturated"
        lines.append(
            f"note: [saturation] is the simulated drive's; this is the optimum of the {whose}"
            " [motor] (selftune tune schedules the saturating motor's over its current"
            + (", and with [schedule] over speed and current together)" if run else ")")
        )
    if run is not None:
        _check_numerics(config.source, caught, run.design.schedule.table("K"))
        lines += schedule_lines(run, config.speed)
    if json_path is not None:
        document = {name: getattr(solution, name) for name in ("K", "P", "X", "U", "theta")}
        document.update({"x_e": solution.X @ w, "u_e": solution.U @ w, "w": w})
        document.update({"motor": config.motor})
        document.update({"operating_point": {"speed": config.speed, "torque": config.torque}})
        document.update({"cost": cost_document(config.Q, config.R, solution.integral_weight)})
        document.update({"h": solution.h, "input_delay": solution.input_delay})
        if run is not None:
            document.update(schedule_document(run, config))
        _write_json(json_path, document)
    written = None
    if report_dir is not None and run is not None:
        written = _write_schedule_figure(run, config, report_dir)
    _print_report(lines, json_path)
    if written is not None and json_path != STANDARD_OUTPUT:
        print(f"wrote {report_dir}/ ({', '.join(written)})")
    return 0


def _write_schedule_figure(
    run: ScheduleRun, config: MotorConfig, directory: str
) -> tuple[str, ...]:
    """The schedule's figure as one set of files in ``directory``; their names."""
    from ..report import SCHEDULE_FILES
    from ..report._figures import save_figure

    figure = run.figure(config.speed)
    with output_directory(directory, SCHEDULE_FILES, "schedule report") as temporary:
        save_figure(figure, temporary / "schedule")
    return SCHEDULE_FILES
