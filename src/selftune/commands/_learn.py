"""``selftune learn``: the learned controller from a drive's log and a configuration."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from ..config import learn_log, learning_problem
from ..core import cost_document, labels, matrix_block
from ..model import Motor, ScheduleDesign
from ._output import (
    _check_json_target,
    _check_report_target,
    _print_report,
    _say_report_written,
    _write_json,
    _write_report,
)
from ._schedule import learned_schedule

if TYPE_CHECKING:  # selftune solve loads no learner
    from ..learn import SpeedsLearned


def learn_command(
    data_path: str | Sequence[str],
    config_path: str,
    json_path: str | None,
    report_dir: str | None = None,
) -> int:
    """``selftune learn``: the learned controller from a CSV, NPZ or MAT log and a config.

    The data file's header (or the configuration's ``[log]`` table) gives n, m, q; the
    configuration is read and checked against them completely before the rows are loaded.
    The controller comes with its quality; data that do not support one give an error
    that says why. Several logs are a saturating motor's current levels, the law
    scheduled over ``i_q*`` (:func:`~selftune.commands._levels.learn_levels`).

    Parameters
    ----------
    data_path : str or sequence of str
        The CSV, NPZ or MAT log (in selftune's columns, or the ``[log]`` table's); or
        several, one a current level.
    config_path : str
        CONFIG.toml.
    json_path : str or None
        Where to write the JSON (``-``: standard output, without the report).
    report_dir : str or None
        Where to write the report: one HTML page and its figures
        (:func:`selftune.report.write_learn_report`), checked before the log is read.
    """
    from ..learn import pi_equivalent_or_reason

    _check_json_target(json_path)
    _check_report_target(report_dir)
    paths = [data_path] if isinstance(data_path, str) else list(data_path)
    levels = None
    if len(paths) > 1:
        from ._levels import learn_levels

        levels = learn_levels(paths, config_path)
        data_path, data, config = levels.top.source, levels.top_data, levels.config
        result: Any = levels.top.learned
    else:
        [data_path] = paths
        learned = learn_log(data_path, config_path)
        data, config = learned.data, learned.config
        result = learned.result
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
    problem = learning_problem(config)
    pi, why = pi_equivalent_or_reason(result.law, problem, result.judged, result.target)
    lines += ["", *(pi.lines(inputs, states) if pi else [f"no PI equivalent: {why}"])]
    schedule: Any = None
    if levels is not None:
        schedule = levels
        lines += levels.lines()
    elif learned.speeds is not None and config.options["method"] == "adp":
        from ._adp_schedule import adp_schedule

        schedule = adp_schedule(learned.speeds, config, result)
        lines += schedule.lines(learned.speeds)
    elif learned.speeds is not None:
        schedule = learned_schedule(learned.speeds, config, result)
        lines += _schedule_lines(learned.speeds, schedule.motor, schedule.design)
    if json_path is not None:
        scheduled = {} if schedule is None else schedule.document
        _write_json(json_path, {**_learn_document(result, problem, pi), **scheduled})
    figure = schedule.figure() if schedule is not None and report_dir is not None else None
    _write_report(result, f"selftune learn: {data_path}", lines, report_dir, schedule=figure)
    _print_report(lines, json_path)
    _say_report_written(report_dir, json_path, scheduled=schedule is not None)
    return 0


def _schedule_lines(speeds: SpeedsLearned, motor: Motor, design: ScheduleDesign) -> list[str]:
    """The held speeds learned, the motor combined and the schedule designed on it."""
    from ..report._ramp_report import STANDSTILL  # here: selftune solve loads no learner

    check = design.check
    low, high = speeds.covered
    worst = check.worst
    assert speeds.motor is not None  # identify-then-design combines the parts' motors
    return [
        "",
        f"learned at {len(speeds.parts)} held speeds, covering {low:g} to {high:g} rad/s "
        "(electrical); the law above is the one at the highest",
        *([STANDSTILL] if speeds.standstill else []),
        f"  the motor combined: {speeds.motor.text()}",
        f"Speed schedule on it ({type(motor).__name__}): {design.schedule.electrical_speed.size}"
        " electrical speeds, "
        + ", ".join(f"{speed:g}" for speed in design.schedule.electrical_speed)
        + " rad/s",
        f"  worst excess cost {check.excess[worst]:.3g} at omega_e = "
        f"{check.electrical_speed[worst]:.6g} rad/s (limit {check.limit:g}; "
        f"{check.electrical_speed.size} speeds checked, {len(design.added)} added)",
    ]


def _learn_document(result: Any, problem: Any = None, pi: Any = None) -> dict[str, Any]:
    """The JSON of ``selftune learn``: the law, its quality, how it was learned, the whole
    cost it optimized (with ``problem``) and its PI equivalent (``pi``, or null)."""
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
        **(
            {}
            if problem is None
            else {"cost": cost_document(problem.Q, problem.R, problem.integral_weight)}
        ),
        "pi_equivalent": None if pi is None else pi.document(),
    }
