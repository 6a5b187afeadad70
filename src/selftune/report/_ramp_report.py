"""What ``selftune tune`` prints and writes for a surface motor with a ``[schedule]``: the
motor identified from a staircase of speeds over the schedule's range, each held speed's
verdict, and the schedule designed on it, judged against the true motor's pointwise
digital optimum (evaluation only).

The comparison is the ramp bench's (:mod:`selftune.bench._ramp`, which calls
:func:`evaluate_ramp`): the same schedule is designed on the true (heated) motor, and
the identified motor's schedule, and the single-speed law beside it, are costed on that
truth at the speeds its check visits (:meth:`~selftune.model.ScheduleDesign.excess_of`,
worst initial state).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..core import Array, ControlLaw, cost_document
from ..model import SPMSM, Motor, ScheduleDesign, design_schedule
from ..sim import DriveSettings
from ..tuning import TuningSettings
from ..tuning._ramp import RampCommissioning
from ._digital_evaluation import true_motor
from ._tune_report import drive_text

__all__ = ["STANDSTILL", "RampEvaluation", "evaluate_ramp", "ramp_document", "ramp_lines"]

#: What a report says of a held speed at standstill.
STANDSTILL = (
    "  and standstill, covered but not learned: its back-EMF is zero, so the flux is not in"
    " it; the motor learned at the others is the plant there too"
)


@dataclass(frozen=True)
class RampEvaluation:
    """A motor commissioned over a speed ramp against the truth (evaluation only).

    Attributes
    ----------
    truth : ScheduleDesign
        The schedule designed on the true (heated) motor: its check's pointwise optima
        are the reference.
    schedule_excess : ndarray
        The identified motor's schedule: its excess cost over the true pointwise optimum
        at each speed of ``truth.check`` (dimensionless, worst initial state).
    single_excess : ndarray
        The single-speed law's, at the same speeds.
    parameter_errors : dict of str to float
        Each identified parameter's relative error against the true motor.
    z : dict of str to float
        Each parameter's error in its standard errors.
    """

    truth: ScheduleDesign
    schedule_excess: Array
    single_excess: Array
    parameter_errors: dict[str, float]
    z: dict[str, float]

    @property
    def speeds(self) -> Array:
        """The electrical speeds the excesses are at, rad/s."""
        return self.truth.check.electrical_speed


def parameter_names(motor: Motor) -> tuple[str, ...]:
    """The identified parameters of a motor's structure: R_s, the inductances, the flux.

    Parameters
    ----------
    motor : SPMSM or IPMSM
        The motor (its type gives the structure).
    """
    if isinstance(motor, SPMSM):
        return ("R_s", "L_s", "phi_pm")
    return ("R_s", "L_d", "L_q", "phi_pm")


def evaluate_ramp(
    result: RampCommissioning,
    motor: Motor,
    settings: TuningSettings,
    drive: DriveSettings,
    speeds: Sequence[float],
    schedule: ScheduleDesign,
    single: ControlLaw,
) -> RampEvaluation:
    """``schedule`` (designed on ``result.motor``) against the true motor's optimum.

    Parameters
    ----------
    result : RampCommissioning
        The commissioning.
    motor : SPMSM or IPMSM
        The true motor (nameplate values; the drive heats it).
    settings : TuningSettings
        The cost and the sampling period.
    drive : DriveSettings
        The drive (its delay and hold are the loop's).
    speeds : sequence of float
        The schedule's speeds, mechanical rad/s.
    schedule : ScheduleDesign
        The schedule designed on the identified motor.
    single : ControlLaw
        The single-speed law judged beside it.
    """
    truth: Motor = true_motor(motor, drive)  # type: ignore[type-var]
    design = design_schedule(
        truth, speeds, settings.Q, settings.R, settings.h, input_delay=drive.input_delay,
        integral_weight=result.integral_weight, hold=drive.voltage_hold,
    )  # fmt: skip
    errors, z = {}, {}
    for name in parameter_names(truth):
        error = float(getattr(result.motor, name) - getattr(truth, name))
        errors[name] = error / float(getattr(truth, name))
        z[name] = error / result.standard_errors[name]
    return RampEvaluation(
        truth=design,
        schedule_excess=design.excess_of(schedule.schedule),
        single_excess=design.excess_of(single),
        parameter_errors=errors,
        z=z,
    )


def ramp_lines(
    source: str, result: RampCommissioning, evaluation: RampEvaluation, drive: DriveSettings
) -> list[str]:
    """The report ``selftune tune`` prints for a motor commissioned over a speed ramp
    (the schedule's own lines follow it).

    Parameters
    ----------
    source : str
        The motor file's name.
    result : RampCommissioning
        The commissioning.
    evaluation : RampEvaluation
        Its comparison with the truth.
    drive : DriveSettings
        The drive it ran on.
    """
    low, high = result.covered
    lines = [
        f"Surface PM motor commissioned over a speed ramp on {source}, {drive_text(drive)}: "
        f"identify-then-design from {result.data_seconds * 1e3:.4g} ms of motor data, "
        f"{len(result.segments)} held speeds learned, covering {low:.6g} to {high:.6g} rad/s "
        "(electrical)",
        "",
    ]
    if result.standstill:
        lines[-1:-1] = [STANDSTILL]
    for speed, learned in result.segments:
        lines += [f"at {speed:.6g} rad/s (electrical):", *learned.verdict.lines()]
    identified = ", ".join(
        f"{name} {getattr(result.motor, name):.6g} +- {result.standard_errors[name]:.2g}"
        for name in parameter_names(result.motor)
    )
    errors = ", ".join(
        f"{name} {value:+.3%} ({evaluation.z[name]:+.2f} se)"
        for name, value in evaluation.parameter_errors.items()
    )
    worst = int(np.argmax(evaluation.schedule_excess))
    lines += [
        "",
        f"the motor, the held speeds combined: {identified}",
        f"  against the truth (only to compare): {errors}",
        f"  the schedule against the true motor's pointwise digital optimum: largest excess "
        f"{evaluation.schedule_excess[worst]:.3g} at omega_e = "
        f"{evaluation.speeds[worst]:.6g} rad/s; the single-speed law's "
        f"{float(np.max(evaluation.single_excess)):.3g}",
    ]
    return lines


def ramp_document(
    motor: Motor,
    settings: TuningSettings,
    result: RampCommissioning,
    evaluation: RampEvaluation,
    drive: DriveSettings,
) -> dict[str, Any]:
    """The JSON ``selftune tune --json`` writes for a motor commissioned over a speed ramp
    (the schedule's keys, ``schedule``, ``schedule_design`` and ``control_law``, are added
    by the command).

    Parameters
    ----------
    motor : SPMSM or IPMSM
        The true motor (nameplate values).
    settings : TuningSettings
        The settings.
    result : RampCommissioning
        The commissioning.
    evaluation : RampEvaluation
        Its comparison with the truth.
    drive : DriveSettings
        The drive.
    """
    identified: dict[str, float] = {}
    for name in parameter_names(result.motor):
        identified[name] = float(getattr(result.motor, name))
        identified[f"{name}_se"] = result.standard_errors[name]
    return {
        "method": "identify",
        "structure": "spmsm" if isinstance(result.motor, SPMSM) else "ipmsm",
        "target": "digital",
        "experiment": "speed ramp",
        "covered": list(result.covered),
        "standstill": result.standstill,
        "segments": [
            {"electrical_speed": speed, "quality": learned.verdict}
            for speed, learned in result.segments
        ],
        "identified": identified,
        "data_seconds": result.data_seconds,
        "parameter_relative_errors": evaluation.parameter_errors,
        "true_schedule_excess": {
            "electrical_speed": evaluation.speeds,
            "schedule": evaluation.schedule_excess,
            "single_speed": evaluation.single_excess,
        },
        "motor": motor,
        "drive": {"settings": drive},
        "settings": settings,
        "cost": cost_document(settings.Q, settings.R, result.integral_weight),
        "h": settings.h,
        "input_delay": drive.input_delay,
    }
