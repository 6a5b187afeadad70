"""``selftune learn``'s speed schedule by the paper's ADP: the law learned at each held
speed of a log, scheduled over them, with no motor model.

``[learning] method = "adp"`` with a ``[schedule]`` table: the log is cut at its held
speeds (:func:`selftune.learn.speed_segments`) and each part's law is learned by ADP from
that part alone (:func:`selftune.learn.learn_over_speeds`). ADP knows a law only where it
has data, so the schedule's grid is the ``[schedule]``'s speeds (``p`` times the
mechanical), each of them a held speed of the log within :data:`SPEED_MATCH`; with
``speed_range`` the held speeds within the range, its ends among them. A speed the log
does not hold is refused, naming it and the held ones.

The interpolated schedule is checked between neighbouring grid speeds by the rules of
every schedule (:func:`selftune.model._refine.check_interval`: 1 % excess for the worst
initial state, 0.9 of the optimum's stability margin, 1 % feedforward error) against the
digital optimum of the plant there. That plant is the two parts' identified sampled
models (the learner's own evidence: the output-error fit, its reference channels)
interpolated linearly in speed: the continuous plant is affine in speed, its sampled one
nearly so (the curvature is about ``(omega h)^2 / 8`` of it between two speeds, and an
error of the plant moves the optimum's cost by its square). An interval that fails is
refused, naming the speed to log between them: ADP cannot add a grid speed without data
there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from itertools import pairwise
from typing import TYPE_CHECKING, Any

import numpy as np

from ..config import LearnConfig, learning_problem
from ..core import Array, ControlLaw, cost_document
from ..errors import DataFileError, UnsolvableError
from ..learn import LearnedController, LearningProblem, SpeedsLearned
from ..learn.evidence._discrete_model import DiscreteModel
from ..learn.learners._identify import design_digital
from ..loop import SampledLoop
from ..model import EXCESS, FINE_POINTS, ScheduleCheck, SpeedSchedule, excess_over
from ..model._refine import check_interval, joined_checks
from ._schedule import check_document

if TYPE_CHECKING:  # matplotlib only to draw
    from matplotlib.figure import Figure

__all__ = ["SPEED_MATCH", "AdpSchedule", "adp_schedule"]

#: A ``[schedule]`` speed is a held speed of the log within this share of it.
SPEED_MATCH = 0.01


@dataclass(frozen=True)
class _Optimum:
    """The digital optimum on one identified sampled plant, as the check reads it."""

    loop: SampledLoop
    Q: Array
    R: Array
    P: Array
    law: ControlLaw
    sampled_plant: tuple[Array, Array, Array]

    @property
    def U(self) -> Array:
        """The law's feedforward."""
        return self.law.U

    @property
    def X(self) -> Array:
        """The law's steady-state map."""
        return self.law.X


@dataclass(frozen=True, eq=False)
class AdpSchedule:
    """The laws ADP learned at the held speeds, scheduled over them, and the check.

    Attributes
    ----------
    schedule : SpeedSchedule
        The laws at the grid speeds (electrical, rad/s).
    check : ScheduleCheck
        The interpolated laws against the optimum on the interpolated identified plants
        at the fine speeds.
    loop : SampledLoop
        The loop the laws were learned for (period, delay, integral action).
    single_excess : ndarray
        The law learned at the highest speed: its excess cost at the check's speeds.
    single_speed : float
        That speed, electrical rad/s.
    document : dict
        The JSON keys ``schedule`` and ``schedule_design``.
    hold : str
        What the drive holds over a sample (as the ``[learning]`` table says).
    """

    schedule: SpeedSchedule
    check: ScheduleCheck
    loop: SampledLoop
    single_excess: Array
    single_speed: float
    document: dict[str, Any]
    hold: str = "stationary"

    def figure(self) -> Figure:
        """The schedule's figure (:func:`selftune.report.figure_schedule`), the
        single-speed law being the one learned at the highest speed."""
        from ..report import figure_schedule

        return figure_schedule(self, self.single_excess, self.single_speed,
                               "law learned at the highest speed")  # fmt: skip

    def lines(self, speeds: SpeedsLearned) -> list[str]:
        """What ``selftune learn`` prints of the schedule.

        Parameters
        ----------
        speeds : SpeedsLearned
            The log learned speed by speed.
        """
        check, grid = self.check, self.schedule.electrical_speed
        worst = check.worst
        low, high = speeds.covered
        return [
            "",
            f"learned by ADP at {len(speeds.parts)} held speeds, covering {low:g} to {high:g} "
            "rad/s (electrical); the law above is the one at the highest",
            f"Speed schedule of the laws learned at {grid.size} held speeds, "
            + ", ".join(f"{speed:g}" for speed in grid)
            + " rad/s (electrical), no motor model",
            f"  worst excess cost {check.excess[worst]:.3g} at omega_e = "
            f"{check.electrical_speed[worst]:.6g} rad/s over the optimum on the identified "
            f"sampled plants interpolated in speed (limit {check.limit:g}; "
            f"{check.points.size} speeds checked)",
            f"  the law learned at {self.single_speed:g} rad/s alone: excess up to "
            f"{float(np.max(self.single_excess)):.3g} over the schedule's range",
        ]


def _grid(speeds: SpeedsLearned, config: LearnConfig) -> list[int]:
    """The parts (indices into ``speeds.parts``) at the ``[schedule]``'s grid speeds."""
    assert config.schedule is not None and config.pole_pairs is not None
    held = np.array([speed for speed, _ in speeds.parts])
    named = ", ".join(f"{speed:g}" for speed in sorted(held))
    wanted = [config.pole_pairs * speed for speed in config.schedule.speeds]
    if config.schedule.automatic:  # speed_range: the held speeds within it
        low, high = wanted
        inside = [
            int(k) for k in np.argsort(held)
            if low * (1 - SPEED_MATCH) - 1e-9 <= held[k] <= high * (1 + SPEED_MATCH) + 1e-9
        ]  # fmt: skip
        ends = [end for end in (low, high) if not any(_matches(held[k], end) for k in inside)]
    else:
        inside = [int(np.argmin(np.abs(held - speed))) for speed in wanted]
        ends = [
            speed for speed, k in zip(wanted, inside, strict=True) if not _matches(held[k], speed)
        ]
    if ends:
        raise DataFileError(
            f"{config.source}: [schedule] {config.schedule.key}: {ends[0]:g} rad/s "
            f"(electrical) is no held speed of the log ({named} rad/s): ADP learns the law "
            "at a speed only from data held there; log that speed, or schedule the held "
            'ones (or learn the motor: method = "identify" with a structure)'
        )
    return inside


def _matches(held: float, speed: float) -> bool:
    return abs(held - speed) <= SPEED_MATCH * max(abs(speed), abs(held)) + 1e-9


def _plant(learned: LearnedController, q: int) -> DiscreteModel:
    """A part's identified sampled plant, its reference channels only."""
    assert learned.evidence is not None  # the pipeline's result carries its evidence
    model = learned.evidence.model
    return replace(model, Ed=model.Ed[:, :q])


def _optimum_between(
    low: tuple[float, DiscreteModel], high: tuple[float, DiscreteModel],
    problem: LearningProblem, delay: int,
) -> Callable[[float], _Optimum]:  # fmt: skip
    """The digital optimum at a speed between two parts', on their plants interpolated
    linearly in speed."""
    (a, first), (b, second) = low, high
    loop = problem.loop(first.h, delay)

    def optimum(speed: float) -> _Optimum:
        share = (speed - a) / (b - a)
        model = replace(
            first,
            Ad=(1 - share) * first.Ad + share * second.Ad,
            Bd=(1 - share) * first.Bd + share * second.Bd,
            Ed=(1 - share) * first.Ed + share * second.Ed,
        )
        designed = design_digital(model, problem, delay)
        plant = (model.Ad, model.Bd, model.Ed)
        return _Optimum(loop, problem.Q, problem.R, designed.P, designed.law, plant)

    return optimum


def adp_schedule(speeds: SpeedsLearned, config: LearnConfig, top: LearnedController) -> AdpSchedule:
    """``selftune learn``'s schedule by ADP (see the module).

    Parameters
    ----------
    speeds : SpeedsLearned
        The log learned by ADP speed by speed.
    config : LearnConfig
        The learning configuration, with its ``[schedule]``.
    top : LearnedController
        The law learned at the highest speed (judged beside the schedule).

    Raises
    ------
    DataFileError
        A ``[schedule]`` speed the log does not hold (naming it and the held ones).
    UnsolvableError
        Where the interpolated law fails the check between two held speeds (naming them
        and the speed to log between).
    """
    assert config.schedule is not None
    problem = learning_problem(config)
    parts = [speeds.parts[k] for k in _grid(speeds, config)]
    grid = [speed for speed, _ in parts]
    schedule = SpeedSchedule(grid, [learned.law for _, learned in parts])
    delay = top.input_delay
    plants = [(speed, _plant(learned, problem.q)) for speed, learned in parts]
    checks = []
    for low, high in pairwise(plants):
        optimum = _optimum_between(low, high, problem, delay)
        check = check_interval(optimum, schedule, (low[0], high[0]), FINE_POINTS, EXCESS)
        if not np.all(check.passed):
            raise UnsolvableError(
                f"{config.source}: [schedule]: between the held speeds {low[0]:g} and "
                f"{high[0]:g} rad/s (electrical) the laws ADP learned there, interpolated, "
                f"have {check.shortfall()} on the identified plants: log a held speed near "
                f"{0.5 * (low[0] + high[0]):g} rad/s"
            )
        checks.append(check)
    joined = joined_checks(checks)
    single_excess = np.asarray(excess_over(joined.optima, top.law), dtype=float)
    single_speed = speeds.top[0]
    loop = problem.loop(plants[0][1].h, delay)
    document = {
        "schedule": schedule.document(),
        "schedule_design": {
            "method": "adp",
            "h": loop.h,
            "input_delay": delay,
            "hold": config.options["voltage_hold"],
            "cost": cost_document(config.Q, config.R, problem.integral_weight),
            "pole_pairs": config.pole_pairs,
            "designed_on": "the laws ADP learned at the held speeds",
            "held_speeds": [speed for speed, _ in speeds.parts],
            "covered": list(speeds.covered),
            config.schedule.key: list(config.schedule.speeds),
            "excess_limit": EXCESS,
            "check": check_document(joined, single_excess),
        },
    }
    hold = str(config.options["voltage_hold"])
    return AdpSchedule(schedule, joined, loop, single_excess, single_speed, document, hold)
