"""The speed schedule of a motor file's ``[schedule]`` table: designed, printed, written.

``selftune solve`` and ``selftune tune`` design it when MOTOR.toml has a ``[schedule]``
table (:mod:`selftune.config._schedule_file`): the optimal digital controller on a grid of
speeds (:func:`selftune.model.design_schedule`) for the loop the file's drive runs (the
digital servo settings of an online tuner: the ``[learning]`` or ``[drive]`` sampling
period, the ``[drive]`` delay and hold, or a drive's defaults, one sample and the
stationary-frame hold; integral action and its weight as ``[learning]`` and ``[cost]``
say). Beside it, the single-speed controller: the same optimum at the operating point's
speed, and its excess cost at each speed the schedule is checked at.

``solve`` designs on the file's motor (the model). ``tune`` never does: it designs on the
motor it identified, which the JSON states in ``schedule_design.motor``: an interior
motor's commissioning at the operating speed, or a surface motor's over a staircase of
the schedule's speeds (``covered``: the speeds its data cover, outside which the schedule
is refused).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ..config import LearnConfig, MotorConfig
from ..core import Array, ControlLaw, cost_document
from ..errors import SelftuneError
from ..model import (
    ModelBasedSolution,
    Motor,
    ScheduleCheck,
    ScheduleDesign,
    bandwidth,
    design_schedule,
)

if TYPE_CHECKING:  # selftune solve loads no learner, and matplotlib only to draw
    from matplotlib.figure import Figure

    from ..learn import LearnedController, SpeedsLearned

__all__ = [
    "LearnedSchedule",
    "ScheduleRun",
    "check_document",
    "learned_schedule",
    "schedule_document",
    "schedule_lines",
    "scheduled",
]


@dataclass(frozen=True, eq=False)
class ScheduleRun:
    """A motor file's schedule, its loop, and the single-speed controller beside it.

    Attributes
    ----------
    design : ScheduleDesign
        The schedule, its grid's optima and its check.
    single : ModelBasedSolution
        The optimum at the operating point's speed (the single-speed controller).
    single_excess : ndarray
        Its excess cost at each speed of the check's fine grid.
    Q_i : ndarray or None
        The integral weight of the design (None without integral action).
    key : str
        The [schedule] key the speeds came from.
    speeds : tuple of float
        The speeds the file gave, mechanical rad/s.
    motor : SPMSM or IPMSM
        The motor the schedule was designed on.
    designed_on : str
        What that motor is: ``"the model"`` (the file's) or ``"the identified motor"``.
    covered : (float, float) or None
        The electrical speeds the identifying data cover, rad/s (None: the model's, no
        such limit).
    """

    design: ScheduleDesign
    single: ModelBasedSolution
    single_excess: Array
    Q_i: Array | None
    key: str
    speeds: tuple[float, ...]
    motor: Motor
    designed_on: str
    covered: tuple[float, float] | None = None

    @property
    def single_law(self) -> ControlLaw:
        """The single-speed controller's law."""
        return self.single.law

    def figure(self, operating_speed: float) -> Figure:
        """The schedule's figure (:func:`selftune.report.figure_schedule`).

        Parameters
        ----------
        operating_speed : float
            The operating point's mechanical speed, rad/s (the single-speed law's).
        """
        from ..report import figure_schedule

        return figure_schedule(self.design, self.single_excess, self.motor.p * operating_speed)


@dataclass(frozen=True, eq=False)
class LearnedSchedule:
    """``selftune learn``'s schedule: designed on the motor learned from a log over
    several held speeds, beside the law learned at the highest of them.

    Attributes
    ----------
    motor : SPMSM or IPMSM
        The motor combined from the speeds' parts, the schedule's design model.
    design : ScheduleDesign
        The schedule, its grid's optima and its check.
    single_excess : ndarray
        The law learned at the highest speed: its excess cost at the check's speeds.
    single_speed : float
        That speed, electrical rad/s.
    document : dict
        The JSON keys ``schedule`` and ``schedule_design``.
    """

    motor: Motor
    design: ScheduleDesign
    single_excess: Array
    single_speed: float
    document: dict[str, Any]

    def figure(self) -> Figure:
        """The schedule's figure (:func:`selftune.report.figure_schedule`), the
        single-speed law being the one learned at the highest speed."""
        from ..report import figure_schedule

        return figure_schedule(self.design, self.single_excess, self.single_speed)


def scheduled(
    config: MotorConfig,
    identified: Motor | None = None,
    covered: tuple[float, float] | None = None,
) -> ScheduleRun | None:
    """The schedule of ``config`` (None without a ``[schedule]`` table).

    Parameters
    ----------
    config : MotorConfig
        The motor file's content.
    identified : SPMSM or IPMSM, optional
        The motor a tuner identified, to design on; default: the file's (the model).
    covered : (float, float), optional
        The electrical speeds the tuner's data cover, rad/s: the schedule refuses speeds
        outside them (:func:`selftune.model.design_schedule`); default: no such limit.
    """
    if config.schedule is None:
        return None
    from ..report._evaluate import learner_integral_weight
    from ._tune import _online_drive

    settings, drive = _online_drive(config, 0)
    motor = config.motor if identified is None else identified
    Q_i = learner_integral_weight(motor, settings) if settings.integral_action else None
    try:
        design = design_schedule(
            motor, config.schedule.speeds, config.Q, config.R, settings.h,
            input_delay=drive.input_delay, integral_weight=Q_i, hold=drive.voltage_hold,
            covered=covered,
        )  # fmt: skip
    except SelftuneError as exc:  # said against the file's [schedule]
        raise exc.retold(f"{config.source}: [schedule] {exc}") from None
    single = design.pointwise_optimum(motor.p * config.speed)
    return ScheduleRun(
        design=design,
        single=single,
        single_excess=design.excess_of(single.law),
        Q_i=Q_i,
        key=config.schedule.key,
        speeds=config.schedule.speeds,
        motor=motor,
        designed_on="the model" if identified is None else "the identified motor",
        covered=covered,
    )


def _norm(matrix: Array | None) -> str:
    return "-" if matrix is None else f"{float(np.linalg.norm(matrix)):.4g}"


def schedule_lines(run: ScheduleRun, operating_speed: float) -> list[str]:
    """The schedule as a short table: per grid speed the gains' norms, the closed loop's
    dominant-pole bandwidth and the worst excess cost up to the next speed.

    Parameters
    ----------
    run : ScheduleRun
        The schedule.
    operating_speed : float
        The operating point's mechanical speed, rad/s (the single-speed controller's).
    """
    design, check = run.design, run.design.check
    loop = design.loop
    grid = design.schedule.electrical_speed
    lines = [
        "",
        f"Speed schedule ([schedule] {run.key}): the digital optimum at {grid.size} electrical"
        f" speeds, h = {loop.h:g} s, delay {loop.input_delay} sample(s), {design.hold} hold,"
        f" {'with' if loop.r else 'without'} integral action",
        f"  {'omega_e (rad/s)':>16} {'|K|':>10} {'|K_i|':>10} {'bandwidth (rad/s)':>18}"
        f" {'worst excess to next':>21}",
    ]
    for index, (speed, optimum) in enumerate(zip(grid, design.optima, strict=True)):
        radius = loop.spectral_radius(optimum.sampled_plant[:2], optimum.law)
        rate = float(bandwidth(radius, loop.h))
        if index + 1 < grid.size:
            inside = (check.electrical_speed > speed) & (check.electrical_speed < grid[index + 1])
            worst = f"{float(np.max(check.excess[inside])):.3g}"
        else:
            worst = "-"
        lines.append(
            f"  {speed:16.6g} {_norm(optimum.law.K):>10} {_norm(optimum.law.K_i):>10}"
            f" {rate:18.5g} {worst:>21}"
        )
    worst_index = check.worst
    top = int(np.argmax(check.electrical_speed))
    lines += [
        f"  worst excess cost {check.excess[worst_index]:.3g} at omega_e ="
        f" {check.electrical_speed[worst_index]:.6g} rad/s (limit {check.limit:g}; "
        f"{check.electrical_speed.size} speeds checked, {len(design.added)} added)",
        f"  the single-speed controller (designed at {operating_speed:g} rad/s mechanical):"
        f" excess {run.single_excess[top]:.3g} at omega_e = {check.electrical_speed[top]:.6g}"
        f" rad/s, at most {float(np.max(run.single_excess)):.3g} over the schedule",
    ]
    return lines


def check_document(check: ScheduleCheck, single_excess: Array) -> dict[str, Any]:
    """The JSON of a schedule's check at the fine speeds, with a single-speed law's
    excess at each (``schedule_design.check``).

    Parameters
    ----------
    check : ScheduleCheck
        The schedule's check.
    single_excess : ndarray
        The single-speed law's excess cost at each fine speed.
    """
    return {
        "electrical_speed": check.electrical_speed,
        "excess": check.excess,
        "spectral_radius": check.radius,
        "optimal_spectral_radius": check.optimal_radius,
        "feedforward_error": check.feedforward_error,
        "single_speed_excess": single_excess,
    }


def learned_schedule(
    speeds: SpeedsLearned, config: LearnConfig, top: LearnedController
) -> LearnedSchedule:
    """``selftune learn``'s schedule: designed on the motor learned from a log over
    several held speeds, within the speeds it covers, for the log's loop (its period, the
    learner's delay, the ``[learning]`` hold, the ``[cost]`` with integral action as the
    learner's); and its JSON keys (``schedule``, ``schedule_design``; ``top``'s law, learned
    at the highest speed, is the single-speed law judged beside it).

    Parameters
    ----------
    speeds : SpeedsLearned
        The log learned speed by speed.
    config : LearnConfig
        The learning configuration, with its ``[schedule]``.
    top : LearnedController
        The law learned at the highest speed.

    Raises
    ------
    SelftuneError
        Said against the configuration's ``[schedule]``: a speed the log does not cover
        (naming it), or a design that fails.
    """
    from ..config import learning_problem
    from ..tuning._interior import motor_of

    assert config.schedule is not None and config.pole_pairs is not None
    assert speeds.motor is not None  # identify-then-design combines the parts' motors
    motor, _ = motor_of(speeds.motor, config.pole_pairs)
    problem = learning_problem(config)
    Q_i = problem.integral_weight if config.integral_action else None
    hold = str(config.options["voltage_hold"])
    assert top.h is not None  # identify-then-design reads h off the log
    try:
        design = design_schedule(
            motor, config.schedule.speeds, config.Q, config.R, top.h,
            input_delay=top.input_delay, integral_weight=Q_i, hold=hold,  # type: ignore[arg-type]
            covered=speeds.covered,
        )  # fmt: skip
    except SelftuneError as exc:
        raise exc.retold(f"{config.source}: [schedule] {exc}") from None
    single_excess = design.excess_of(top.law)
    document = {
        "schedule": design.schedule.document(),
        "schedule_design": {
            "h": design.loop.h,
            "input_delay": design.loop.input_delay,
            "hold": design.hold,
            "cost": cost_document(config.Q, config.R, Q_i),
            "pole_pairs": config.pole_pairs,
            "designed_on": "the identified motor",
            "motor": motor,
            "covered": list(speeds.covered),
            config.schedule.key: list(config.schedule.speeds),
            "added": list(design.added),
            "excess_limit": design.check.limit,
            "check": check_document(design.check, single_excess),
        },
    }
    return LearnedSchedule(motor, design, single_excess, speeds.top[0], document)


def schedule_document(run: ScheduleRun, config: MotorConfig) -> dict[str, Any]:
    """The JSON keys of a schedule: ``schedule`` (the tables, :meth:`~selftune.model.
    SpeedSchedule.document`) and ``schedule_design``: everything the design needs to be
    recomputed from the file (the loop's period, delay and hold, the cost with ``Q_i``, the
    speeds given) and its check on the fine grid, with the single-speed controller's
    excess (``control_law`` is that controller).

    Parameters
    ----------
    run : ScheduleRun
        The schedule.
    config : MotorConfig
        The motor file's content.
    """
    design, check = run.design, run.design.check
    return {
        "schedule": design.schedule.document(),
        "schedule_design": {
            "h": design.loop.h,
            "input_delay": design.loop.input_delay,
            "hold": design.hold,
            "cost": cost_document(config.Q, config.R, run.Q_i),
            "pole_pairs": config.motor.p,
            "designed_on": run.designed_on,
            "motor": run.motor,
            run.key: list(run.speeds),
            **({} if run.covered is None else {"covered": list(run.covered)}),
            "added": list(design.added),
            "excess_limit": check.limit,
            "check": check_document(design.check, run.single_excess),
            "single_speed": {
                "speed": config.speed,
                "electrical_speed": config.motor.p * config.speed,
            },
        },
        "control_law": run.single_law.document(),
    }
