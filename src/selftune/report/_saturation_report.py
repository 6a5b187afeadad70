"""A saturating motor commissioned over its load against the truth (evaluation only), and
what ``selftune tune`` prints and writes of it (a ``[saturation]`` table).

The reference is the TRUE pointwise digital optimum at each q-axis current reference from
10 % to 100 % of rated torque's (the nameplate MTPA path, :data:`CURRENTS` of them),
designed on the true incremental plant there (``saturation.incremental`` and the flux
offset, :func:`~selftune.tuning._saturation.incremental_theta`). Against it: the excess
cost (worst initial state, :func:`~selftune.model.excess_over`) of the current schedule,
of the one law learned at rated current and of the one learned at the lowest level; and,
per level, the identified incremental inductances against the truth at the level's mean
current, in standard errors. The saturation study (:mod:`selftune.bench._saturation`)
calls the same functions.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core import Array, ControlLaw, cost_document
from ..learn import IncrementalStructure, LearnedController
from ..model import (
    IPMSM,
    CurrentScheduleDesign,
    ModelBasedSolution,
    RegulationProblem,
    SpeedCurrentDesign,
    excess_over,
    solve_digital_regulation,
)
from ..sim import DriveSettings, FluxMap, Saturation
from ..tuning import TuningSettings
from ..tuning._curvature import LevelFields
from ..tuning._interior import CURRENT_REFERENCE_F
from ..tuning._saturation import CurrentCommissioning, CurrentLevel, incremental_theta
from ._schedule_figure import figure_schedule
from ._tune_report import drive_text

if TYPE_CHECKING:  # matplotlib is loaded only to draw
    from matplotlib.figure import Figure

__all__ = [
    "CURRENTS",
    "CURVATURE_NOTE",
    "SPEEDS",
    "CurrentEvaluation",
    "check_entry",
    "current_document",
    "current_lines",
    "current_schedule_figure",
    "evaluate_current_schedule",
    "judged_references",
    "level_document",
    "level_table",
    "schedule_check_lines",
    "speed_current_lines",
    "true_current_optima",
]

#: The currents judged between 10 % and 100 % of rated torque.
CURRENTS = 24

#: The speeds a schedule over speed and current is judged at, evenly over its range.
SPEEDS = 12

#: The levels' table notes the curvature's part of the inductances' standard errors where
#: it is more than this many times the noise's at some level (the fit's average over the
#: log's currents then differs from the value at the level by more than the noise shows).
CURVATURE_NOTE = 1.0

#: The identified incremental inductances' names (``theta[1:4]``).
INDUCTANCES = ("L_dd", "L_qq", "L_dq")


def judged_references(motor: IPMSM, torque: float) -> Array:
    """The :data:`CURRENTS` current references judged, ``[i_d*, i_q*]`` (A, shape (N, 2)):
    the nameplate MTPA from 10 % to 100 % of ``torque`` (rated, N m).

    Parameters
    ----------
    motor : IPMSM
        The nameplate motor.
    torque : float
        Rated torque, N m.
    """
    shares = np.linspace(0.1, 1.0, CURRENTS)
    return np.array([motor.current_reference(share * torque) for share in shares])


def true_current_optima(
    motor: IPMSM, saturation: Saturation, speed: float, h: float,
    references: Array, weights: tuple[Array, Array, Array | None], input_delay: int,
) -> list[ModelBasedSolution]:  # fmt: skip
    """The true pointwise digital optimum at each current reference (the motor's steady
    current there, the integrator holding it).

    Parameters
    ----------
    motor : IPMSM
        The nameplate motor (its R_s, flux and pole pairs).
    saturation : SaturationModel or FluxMap
        The true flux linkages.
    speed : float
        Mechanical speed, rad/s.
    h : float
        Sampling period, s.
    references : ndarray, shape (N, 2)
        ``[i_d*, i_q*]`` at each current, A.
    weights : (ndarray, ndarray, ndarray or None)
        ``Q``, ``R`` and the integral weight.
    input_delay : int
        The loop's delay, samples.
    """
    structure = IncrementalStructure(motor.p * speed, h)
    optima = []
    for current in references:
        theta = incremental_theta(saturation, motor.R_s, current, motor.phi_pm)
        A, B, D = structure.continuous(theta)
        problem = RegulationProblem(
            A=A, B=B, C=np.eye(2), D=D, E=np.zeros((3, 3)), F=CURRENT_REFERENCE_F
        )
        optimum = solve_digital_regulation(
            problem, weights[0], weights[1], h, input_delay=input_delay,
            integral_weight=weights[2], plant=structure(theta),
        )  # fmt: skip
        optima.append(optimum)
    return optima


@dataclass(frozen=True)
class CurrentEvaluation:
    """A current schedule against the true pointwise optimum (evaluation only).

    Attributes
    ----------
    references : ndarray, shape (N, 2)
        The judged ``[i_d*, i_q*]``, A: the nameplate MTPA from 10 % to 100 % of rated.
    schedule_excess, rated_excess, low_excess : ndarray, shape (N,)
        The excess cost over the true optimum at each (dimensionless, worst initial
        state) of the schedule, of the law learned at the highest level and of the one
        learned at the lowest.
    z : ndarray, shape (levels, 3)
        Each level's identified ``L_dd``, ``L_qq``, ``L_dq`` against the truth at its
        mean current, in standard errors.
    errors : ndarray, shape (levels, 3)
        The same errors relative to the true ``L_qq`` there.
    electrical_speeds : ndarray, shape (S,)
        With a schedule over speed and current: the judged speeds, rad/s (electrical),
        :data:`SPEEDS` over its range; else empty.
    speed_excess : ndarray, shape (S, N)
        That schedule's excess over the true optimum at each judged speed and current
        (empty without one).
    current_only_excess : ndarray, shape (S, N)
        The same of the schedule over ``i_q*`` alone, designed at the operating speed
        (empty without a schedule over speed and current).
    """

    references: Array
    schedule_excess: Array
    rated_excess: Array
    low_excess: Array
    z: Array
    errors: Array
    electrical_speeds: Array = field(default_factory=lambda: np.zeros(0))
    speed_excess: Array = field(default_factory=lambda: np.zeros((0, 0)))
    current_only_excess: Array = field(default_factory=lambda: np.zeros((0, 0)))


def evaluate_current_schedule(
    result: CurrentCommissioning,
    motor: IPMSM,
    saturation: Saturation,
    settings: TuningSettings,
) -> CurrentEvaluation:
    """``result`` against the true motor (see the module docstring).

    Parameters
    ----------
    result : CurrentCommissioning
        The commissioning.
    motor : IPMSM
        The nameplate motor.
    saturation : SaturationModel or FluxMap
        The true flux linkages.
    settings : TuningSettings
        Operating point (speed; rated torque ``torque``), cost, sampling period.
    """
    references = judged_references(motor, settings.torque)
    first = result.levels[0].learned.law
    weights = (settings.Q, settings.R, result.integral_weight)
    optima = true_current_optima(
        motor, saturation, settings.speed, settings.h, references, weights, first.history
    )
    # the firmware holds the end laws outside the levels' currents (the lowest may be left
    # out: CurrentCommissioning.left_out)
    low, high = result.design.schedule.covered
    schedule = [
        result.design.schedule.law_at(float(np.clip(q, low, high))) for q in references[:, 1]
    ]
    schedule_excess, rated_excess, low_excess = (
        np.asarray(excess_over(optima, law), dtype=float)
        for law in (schedule, result.levels[-1].learned.law, first)
    )
    speeds, speed_excess, current_only = _speed_current_excess(
        result, motor, saturation, settings, references
    )
    z, errors = [], []
    for level in result.levels:
        truth = incremental_theta(saturation, motor.R_s, level.mean_current, motor.phi_pm)
        z.append(((level.theta - truth) / level.standard_errors)[1:4])
        errors.append((level.theta - truth)[1:4] / truth[2])
    return CurrentEvaluation(
        references, schedule_excess, rated_excess, low_excess, np.array(z), np.array(errors),
        speeds, speed_excess, current_only,
    )  # fmt: skip


def _speed_current_excess(
    result: CurrentCommissioning, motor: IPMSM, saturation: Saturation,
    settings: TuningSettings, references: Array,
) -> tuple[Array, Array, Array]:  # fmt: skip
    """The schedule over speed and current, and the one over ``i_q*`` alone (designed at
    the operating speed), against the true optimum at :data:`SPEEDS` speeds over the
    former's range times the judged currents (the end laws held beyond the grids'
    currents, as the firmware does); empty arrays without one."""
    design = result.speed_design
    if design is None:
        return np.zeros(0), np.zeros((0, 0)), np.zeros((0, 0))
    schedule, alone = design.schedule, result.design.schedule
    (low, high), (lowest, highest) = schedule.covered
    first, last = alone.covered
    speeds = np.linspace(low, high, SPEEDS)
    weights = (settings.Q, settings.R, result.integral_weight)
    delay = result.levels[0].learned.law.history
    both, single = [], []
    for speed in speeds:
        optima = true_current_optima(
            motor, saturation, float(speed) / motor.p, settings.h, references, weights, delay
        )
        laws = [
            schedule.law_at(float(speed), float(np.clip(q, lowest, highest)))
            for q in references[:, 1]
        ]
        both.append(np.asarray(excess_over(optima, laws), dtype=float))
        laws = [alone.law_at(float(np.clip(q, first, last))) for q in references[:, 1]]
        single.append(np.asarray(excess_over(optima, laws), dtype=float))
    return speeds, np.array(both), np.array(single)


def current_lines(
    source: str,
    result: CurrentCommissioning,
    evaluation: CurrentEvaluation,
    drive: DriveSettings,
) -> list[str]:
    """The report ``selftune tune`` prints for a saturating motor.

    Parameters
    ----------
    source : str
        The motor file's name.
    result : CurrentCommissioning
        The commissioning.
    evaluation : CurrentEvaluation
        Its comparison with the truth.
    drive : DriveSettings
        The drive it ran on.
    """
    lines = [
        f"Saturating PM motor commissioned over its load on {source}, {drive_text(drive)}: "
        f"{len(result.levels)} current levels learned with the incremental structure"
        + (f" ({len(result.refusals)} logs refused and logged again)" if result.refusals else ""),
        *level_table(
            "share of rated", [f"{level.share:.0%}" for level in result.levels], result.levels
        ),
        *schedule_check_lines(result.design),
        *speed_current_lines(result.speed_design),
        *([f"  note: levels {result.left_out_text}"] if result.left_out_text else []),
    ]
    rated, low = evaluation.rated_excess, evaluation.low_excess
    lines += [
        f"  against the true motor's pointwise optimum from 10% to 100% of rated (only to "
        f"compare): largest excess {float(np.max(evaluation.schedule_excess)):.3g}; one law "
        f"learned at rated current {float(np.max(rated)):.3g}, at the lowest level "
        f"{float(np.max(low)):.3g}",
        *(
            [
                f"  the schedule over speed and current against the true motor's pointwise "
                f"optimum at {evaluation.electrical_speeds.size} speeds from "
                f"{evaluation.electrical_speeds[0]:.4g} to {evaluation.electrical_speeds[-1]:.4g}"
                f" rad/s (electrical) times those currents (only to compare): largest excess "
                f"{float(np.max(evaluation.speed_excess)):.3g}; the schedule over i_q* alone, "
                "designed at the operating speed, "
                f"{float(np.max(evaluation.current_only_excess)):.3g}"
            ]
            if evaluation.speed_excess.size
            else []
        ),
        f"  the identified inductances against the truth at each level's mean current: "
        f"{np.mean(np.abs(evaluation.z) <= 1.0):.0%} of {evaluation.z.size} within one "
        f"standard error, the largest {float(np.max(np.abs(evaluation.errors))):.2%} of L_qq",
    ]
    return lines


def level_table(title: str, names: Sequence[str], levels: Sequence[LevelFields]) -> list[str]:
    """The levels' identified incremental inductances, a line each (after a blank line
    and the header), and a note where their curvature over the logs' currents is more
    of their standard errors than the noise (:data:`CURVATURE_NOTE`).

    Parameters
    ----------
    title : str
        The first column's header (what names a level).
    names : sequence of str
        Each level's name.
    levels : sequence of CurrentLevel or LearnedLevel
        Each level's ``[i_d*, i_q*]`` (A), identified ``theta`` and its standard errors
        (:func:`~selftune.tuning._saturation.incremental_parameters`, the curvature's
        included: :func:`~selftune.tuning._curvature.with_curvature`).
    """
    width = max(len(title), *(len(name) for name in names))
    lines = [
        "",
        f"  {title:>{width}}  i_d* (A)  i_q* (A)"
        + "".join(f"{name + ' (H) +- se':>22}" for name in INDUCTANCES),
    ]
    for name, level in zip(names, levels, strict=True):
        theta, errors, reference = level.theta, level.standard_errors, level.reference
        values = "".join(f"{theta[k]:12.4g} +-{errors[k]:7.1g}" for k in (1, 2, 3))
        lines.append(f"  {name:>{width}}  {reference[0]:8.4g}  {reference[1]:8.4g}" + values)
    noise = [
        np.sqrt(np.maximum(level.standard_errors[1:4] ** 2 - level.curvature_errors**2, 0.0))
        for level in levels
    ]
    ratios = [
        float(np.max(level.curvature_errors / np.maximum(own, np.finfo(float).tiny)))
        for level, own in zip(levels, noise, strict=True)
    ]
    worst = int(np.argmax(ratios))
    if ratios[worst] > CURVATURE_NOTE:
        lines.append(
            f"  note: the inductances' standard errors include their curvature over each "
            f"log's currents, up to {ratios[worst]:.2g} times the noise's (at {names[worst]}, "
            f"where the log's i_q spreads by {levels[worst].current_spread[1]:.3g} A): the fit "
            "finds the inductances averaged over its log's currents; a smaller exploration "
            "and smaller steps about each level would find them nearer the level"
        )
    return lines


def schedule_check_lines(design: CurrentScheduleDesign) -> list[str]:
    """The current schedule's grid and its worst excess cost over the identified models'
    pointwise optimum (after a blank line).

    Parameters
    ----------
    design : CurrentScheduleDesign
        The schedule and its check.
    """
    schedule, check = design.schedule, design.check
    worst = int(np.argmax(check.excess))
    return [
        "",
        f"Current schedule: the digital optimum at {schedule.current.size} currents i_q* = "
        + ", ".join(f"{current:.4g}" for current in schedule.current)
        + " A",
        f"  worst excess cost {check.excess[worst]:.3g} at i_q* = {check.points[worst]:.4g} A "
        f"over the identified models' pointwise optimum (limit {check.limit:g})",
    ]


def speed_current_lines(design: SpeedCurrentDesign | None) -> list[str]:
    """The schedule over speed and current: its grid and its worst excess cost over the
    identified models' pointwise optimum (none without one).

    Parameters
    ----------
    design : SpeedCurrentDesign or None
        The schedule and its check.
    """
    if design is None:
        return []
    schedule, check = design.schedule, design.check
    worst = check.worst
    return [
        f"Speed and current schedule: the digital optimum at {schedule.electrical_speed.size} "
        "speeds omega_e = "
        + ", ".join(f"{speed:.4g}" for speed in schedule.electrical_speed)
        + f" rad/s times {schedule.current.size} currents i_q* = "
        + ", ".join(f"{current:.4g}" for current in schedule.current)
        + " A, interpolated bilinearly",
        f"  worst excess cost {check.excess[worst]:.3g} at omega_e = "
        f"{check.electrical_speed[worst]:.4g} rad/s, i_q* = {check.current[worst]:.4g} A over "
        f"the identified models' pointwise optimum (limit {check.limit:g}; "
        f"{check.excess.size} points on lines through every cell)",
    ]


def check_entry(design: CurrentScheduleDesign) -> dict[str, Any]:
    """The schedule's check as the JSON states it: the fine grid's ``i_q`` (A), the
    excess cost at each and its limit.

    Parameters
    ----------
    design : CurrentScheduleDesign
        The schedule and its check.
    """
    check = design.check
    return {"i_q": check.points, "excess": check.excess, "limit": check.limit}


def current_schedule_figure(
    design: CurrentScheduleDesign, law: ControlLaw, current: float, label: str | None = None
) -> Figure:
    """The current schedule's figure (:func:`~._schedule_figure.figure_schedule`) with one
    law learned at a level beside it (its excess over the check's pointwise optima).

    Parameters
    ----------
    design : CurrentScheduleDesign
        The schedule and its check.
    law : ControlLaw
        The one law.
    current : float
        The ``i_q*`` it was learned at, A.
    label : str, optional
        Its legend (default: the law at rated current).
    """
    single = excess_over(design.check.optima, law)
    return figure_schedule(design, np.asarray(single, dtype=float), current, label)


def level_document(
    reference: Array,
    mean_current: Array,
    theta: Array,
    errors: Array,
    learned: LearnedController,
    spread: Array,
    curvature: Array,
) -> dict[str, Any]:
    """A level's entry in ``current_schedule_design``: its reference, the log's mean
    current and spread, the identified incremental model with its standard errors and
    names, the part of the inductances' that is their curvature over the log, and the
    learner's verdict.

    Parameters
    ----------
    reference : ndarray, shape (2,)
        ``[i_d*, i_q*]``, A.
    mean_current : ndarray, shape (2,)
        The log's mean ``[i_d, i_q]``, A.
    theta, errors : ndarray, shape (6,)
        The identified parameters and their standard errors.
    learned : LearnedController
        The law learned on the level's log, with its verdict.
    spread : ndarray, shape (2,)
        The log's standard deviation of ``[i_d, i_q]``, A.
    curvature : ndarray, shape (3,)
        The part of the standard errors of ``[L_dd, L_qq, L_dq]`` that is their curvature
        over the log's currents, H (:func:`~selftune.tuning._curvature.curvature_errors`).
    """
    return {
        "i_d": float(reference[0]),
        "i_q": float(reference[1]),
        "mean_current": mean_current,
        "current_spread": spread,
        "theta": theta,
        "theta_se": errors,
        "theta_names": ["R_s", *INDUCTANCES, "kappa", "kappa_q"],
        "inductance_curvature_se": curvature,
        "quality": learned.verdict,
    }


def current_document(
    motor: IPMSM,
    saturation: Saturation,
    settings: TuningSettings,
    result: CurrentCommissioning,
    evaluation: CurrentEvaluation,
    drive: DriveSettings,
) -> dict[str, Any]:
    """The JSON ``selftune tune --json`` writes for a saturating motor: the schedule over
    ``i_q*`` (``current_schedule``, in :meth:`~selftune.model.CurrentSchedule.document`'s
    form) with every level's identified incremental model, the law at rated current
    (``control_law``), the whole cost, h and the delay, and the comparison with the truth.

    Parameters
    ----------
    motor : IPMSM
        The nameplate motor.
    saturation : SaturationModel or FluxMap
        The true flux linkages (stated, for the comparison).
    settings : TuningSettings
        The settings.
    result : CurrentCommissioning
        The commissioning.
    evaluation : CurrentEvaluation
        Its comparison with the truth.
    drive : DriveSettings
        The drive.
    """
    schedule = result.design.schedule
    rated = result.levels[-1]
    return {
        "method": "identify",
        "structure": "incremental",
        "target": "digital",
        "control_law": schedule.law_at(float(rated.reference[1])).document(),
        "current_schedule": schedule.document(),
        "current_schedule_design": {
            "levels": [_level_entry(level) for level in result.levels],
            "refusals": [{"share": share, "error": text} for share, text in result.refusals],
            "left_out": [_level_entry(level) for level in result.left_out],
            "left_out_reason": result.left_out_text,
            "unlearned": list(result.unlearned),
            "check": check_entry(result.design),
        },
        "true_excess": {
            "i_q": evaluation.references[:, 1],
            "schedule": evaluation.schedule_excess,
            "rated_law": evaluation.rated_excess,
            "low_law": evaluation.low_excess,
            **(
                {
                    "electrical_speed": evaluation.electrical_speeds,
                    "speed_current_schedule": evaluation.speed_excess,
                    "current_schedule_over_speed": evaluation.current_only_excess,
                }
                if result.speed_design is not None
                else {}
            ),
        },
        **_speed_current_entries(result.speed_design),
        "inductance_z": evaluation.z,
        "motor": motor,
        "saturation": _saturation_document(saturation),
        "drive": {"settings": drive},
        "settings": settings,
        "cost": cost_document(settings.Q, settings.R, result.integral_weight),
        "h": settings.h,
        "input_delay": rated.learned.law.history,
    }


def _speed_current_entries(design: SpeedCurrentDesign | None) -> dict[str, Any]:
    """``speed_current_schedule`` (:meth:`~selftune.model.SpeedCurrentSchedule.document`)
    and its design's check and added points, for the JSON (none without one)."""
    if design is None:
        return {}
    check = design.check
    return {
        "speed_current_schedule": design.schedule.document(),
        "speed_current_schedule_design": {
            "check": {
                "electrical_speed": check.electrical_speed, "i_q": check.current,
                "excess": check.excess, "limit": check.limit,
            },
            "added_speeds": list(design.added_speeds),
            "added_currents": list(design.added_currents),
        },
    }  # fmt: skip


def _level_entry(level: CurrentLevel) -> dict[str, Any]:
    """A commissioned level's entry in ``current_schedule_design``: its share of rated
    torque and :func:`level_document`'s."""
    return {
        "share": level.share,
        **level_document(
            level.reference,
            level.mean_current,
            level.theta,
            level.standard_errors,
            level.learned,
            level.current_spread,
            level.curvature_errors,
        ),
    }


def _saturation_document(saturation: Saturation) -> dict[str, Any]:
    """The ``[saturation]`` table's content as the JSON states it: the analytic model's
    ``i_sat`` (A), ``drop`` and ``cross``, or the flux map's grid (A) and flux linkages (Wb,
    a row an ``i_d``)."""
    names: tuple[str, ...] = ("i_sat", "drop", "cross")
    if isinstance(saturation, FluxMap):
        names = ("i_d", "i_q", "psi_d", "psi_q")
    return {name: getattr(saturation, name) for name in names}
