"""Saturating motors: the current schedule against the true pointwise optimum.

Each motor saturates by :class:`~selftune.sim.SaturationModel` (``drop`` of its ``L_q``
saturating at the scale ``i_sat``, cross-saturation 0.1, so that its incremental
``L_qq`` falls by 20-40 % between no load and rated current). It runs on the realistic
drive with the hardware-like drive's one-sample delay, 2 V of dead time, 10 mA noise and
12-bit ADC, but average PWM (carrier PWM steps the saturating motor segment by segment,
about three times the time: ``measure_saturation(..., pwm="carrier")``; docs/saturation.md),
10 kHz.
:func:`~selftune.tuning.commission_over_current` learns it at 10, 40, 70 and 100 % of
rated torque (and between them where the identified inductance moves by more than
:data:`~selftune.tuning._saturation.INDUCTANCE_MOVE`) and schedules the law over
``i_q*``.

Judged at :data:`CURRENTS` q-axis current references from 10 % to 100 % of rated
torque's (the nameplate MTPA path): the excess cost (worst initial state,
:func:`~selftune.model.worst_excess`) over the TRUE pointwise digital optimum, designed
on the true incremental plant at that current (``saturation.incremental`` and the flux
offset there, :func:`~selftune.tuning._saturation.incremental_theta`), of the schedule,
of the one law learned at rated current and of the one learned at 10 %. Also, per level,
the identified incremental inductances against the truth at the level's mean current, in
standard errors. The law is also scheduled over speed and current together, from 5 % to
100 % of the motor's speed (:data:`SPEED_SHARES`), and judged likewise at
:data:`~selftune.report._saturation_report.SPEEDS` speeds over that range times those
currents, beside the schedule over ``i_q*`` alone there.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ..config import MotorConfig
from ..errors import SelftuneError
from ..model import IPMSM
from ..report._saturation_report import (
    CURRENTS,
    SPEEDS,
    evaluate_current_schedule,
    judged_references,
)
from ..sim import DriveSettings, SaturationModel
from ..tuning import commission_over_current, tuning_settings
from ._common import table, with_progress
from ._interior import LOW_VOLTAGE_DEAD_TIME

#: The drive's PWM.
Pwm = Literal["average", "carrier"]

__all__ = [
    "CURRENTS",
    "SATURATING_MOTORS",
    "SaturationCase",
    "SaturationStudy",
    "markdown_saturation",
    "measure_saturation",
]

#: The motors: (motor, mechanical speed rad/s, rated torque N m, DC bus V, i_sat as a
#: share of the rated q current, drop): an interior one with L_q / L_d = 3, a surface one
#: (the interior form with L_d = L_q) and a low-inductance interior one on a 48 V bus
#: (with the interior study's low-voltage dead time, 0.5 us).
SATURATING_MOTORS: tuple[tuple[IPMSM, float, float, float, float, float], ...] = (
    (IPMSM(R_s=0.2, L_d=2e-3, L_q=6e-3, phi_pm=0.1, p=4), 100.0, 5.0, 540.0, 0.6, 0.35),
    (IPMSM(R_s=0.5, L_d=4e-3, L_q=4e-3, phi_pm=0.1, p=4), 100.0, 4.0, 540.0, 0.6, 0.35),
    (IPMSM(R_s=0.05, L_d=1e-4, L_q=3e-4, phi_pm=0.01, p=7), 50.0, 1.0, 48.0, 0.6, 0.3),
)

#: Cross-saturation of every motor.
CROSS = 0.1

#: The schedule over speed and current spans these shares of the motor's speed.
SPEED_SHARES = (0.05, 1.0)


@dataclass(frozen=True)
class SaturationCase:
    """One motor's commissioning over its load (NaN where it was refused).

    Attributes
    ----------
    motor_text : str
    seed : int
    refusal_text : str
        The refusal's first words ("" when learned).
    L_qq_fall_percent : float
        The true incremental ``L_qq``'s fall from 10 % to 100 % of rated current, %.
    levels : int
        The levels learned.
    refused_logs : int
        The levels' logs refused and logged again.
    schedule_excess_percent : float
        The schedule's largest excess over the true pointwise optimum, %.
    rated_excess_percent, low_excess_percent : float
        The largest excess of the one law learned at rated current and at 10 %, %.
    z : tuple of float
        The identified ``L_dd``, ``L_qq``, ``L_dq`` of every level against the truth at
        the level's mean current, in standard errors.
    errors_percent : tuple of float
        The same errors relative to the true ``L_qq``, %.
    wall_seconds : float
    speed_excess_percent : float
        The schedule over speed and current's largest excess over the true pointwise
        optimum at the judged speeds and currents, %.
    alone_excess_percent : float
        That of the schedule over ``i_q*`` alone (designed at the motor's speed) there, %.
    """

    motor_text: str
    seed: int
    refusal_text: str
    L_qq_fall_percent: float
    levels: int
    refused_logs: int
    schedule_excess_percent: float
    rated_excess_percent: float
    low_excess_percent: float
    z: tuple[float, ...]
    errors_percent: tuple[float, ...]
    wall_seconds: float
    speed_excess_percent: float = float("nan")
    alone_excess_percent: float = float("nan")

    @property
    def learned(self) -> bool:
        """Whether a schedule was learned."""
        return not self.refusal_text


@dataclass(frozen=True)
class SaturationStudy:
    """The saturation study's runs.

    Attributes
    ----------
    cases : tuple of SaturationCase
    wall_seconds : float
    pwm : str
        The drive's PWM, ``"average"`` or ``"carrier"``.
    """

    cases: tuple[SaturationCase, ...]
    wall_seconds: float
    pwm: Pwm = "average"


def _case(index: int, seed: int, pwm: Pwm = "average") -> SaturationCase:
    motor, speed, torque, bus, share, drop = SATURATING_MOTORS[index]
    drive = replace(DriveSettings.hardware_like(dc_voltage=bus), pwm=pwm)
    if bus < 100.0:  # a low-voltage drive's MOSFETs, as the interior study's
        drive = replace(drive, dead_time=LOW_VOLTAGE_DEAD_TIME)
    rated = float(motor.current_reference(torque)[1])
    saturation = SaturationModel.of(motor, i_sat=share * rated, drop=drop, cross=CROSS)
    config = MotorConfig(
        motor=motor, speed=speed, torque=torque, drive=drive, drive_h=1e-4,
        learning={"integral_action": True}, source=f"saturating motor {index + 1}",
        saturation=saturation,
    )  # fmt: skip
    settings = tuning_settings(config, seed)
    references = judged_references(motor, torque)
    low, high = (saturation.incremental(*references[k])[1, 1] for k in (0, -1))
    fall = 100.0 * (1.0 - high / low)
    label = f"{index + 1}: {type(motor).__name__} {motor.L_d * 1e3:g}/{motor.L_q * 1e3:g} mH"
    started = time.perf_counter()
    try:
        result = commission_over_current(
            motor, saturation, settings, drive, seed=seed,
            speeds=[share * speed for share in SPEED_SHARES],
        )  # fmt: skip
    except SelftuneError as error:
        nan = float("nan")
        return SaturationCase(
            label, seed, str(error)[:90], fall, 0, 0, nan, nan, nan, (), (),
            time.perf_counter() - started,
        )  # fmt: skip
    evaluation = evaluate_current_schedule(result, motor, saturation, settings)
    excess = [
        float(np.max(values))
        for values in (evaluation.schedule_excess, evaluation.rated_excess, evaluation.low_excess)
    ]
    z = evaluation.z.ravel().tolist()
    errors = (100.0 * evaluation.errors).ravel().tolist()
    return SaturationCase(
        label, seed, "", fall, len(result.levels), len(result.refusals), 100.0 * excess[0],
        100.0 * excess[1],
        100.0 * excess[2], tuple(z), tuple(errors), time.perf_counter() - started,
        100.0 * float(np.max(evaluation.speed_excess)),
        100.0 * float(np.max(evaluation.current_only_excess)),
    )  # fmt: skip


def measure_saturation(
    quick: bool, progress: bool = True, seeds: int = 2, pwm: Pwm = "average"
) -> SaturationStudy:
    """The saturation study (see the module).

    Parameters
    ----------
    quick : bool
        The first motor, one seed; else every motor over ``seeds`` seeds.
    progress : bool
        Show a progress bar.
    seeds : int
        Seeds per motor in the full run.
    pwm : str
        The drive's PWM: ``"average"`` (the study's) or ``"carrier"`` (each carrier
        segment stepped: about three times the time).
    """
    cases = [(0, 0)] if quick else [
        (index, seed) for index in range(len(SATURATING_MOTORS)) for seed in range(seeds)
    ]  # fmt: skip
    started = time.perf_counter()
    results = with_progress(cases, lambda case: _case(*case, pwm), "saturation", progress)
    return SaturationStudy(tuple(results), time.perf_counter() - started, pwm)


def _within_one(cases: list[SaturationCase]) -> str:
    values = [abs(z) <= 1.0 for case in cases for z in case.z]
    return f"{np.mean(values):.0%} of {len(values)}" if values else "-"


def markdown_saturation(study: SaturationStudy) -> list[str]:
    """The study's table in markdown.

    Parameters
    ----------
    study : SaturationStudy
        The results.
    """
    rows = []
    for case in study.cases:
        if not case.learned:
            rows.append([case.motor_text, str(case.seed), f"{case.L_qq_fall_percent:.0f}",
                         "refused: " + case.refusal_text, "-", "-", "-", "-", "-", "-",
                         f"{case.wall_seconds:.0f}"])  # fmt: skip
            continue
        rows.append([case.motor_text, str(case.seed), f"{case.L_qq_fall_percent:.0f}",
                     f"{case.levels} ({case.refused_logs})", f"{case.schedule_excess_percent:.3f}",
                     f"{case.rated_excess_percent:.3f}", f"{case.low_excess_percent:.3f}",
                     f"{max(abs(e) for e in case.errors_percent):.3f}",
                     f"{case.speed_excess_percent:.3f}", f"{case.alone_excess_percent:.3f}",
                     f"{case.wall_seconds:.0f}"])  # fmt: skip
    learned = [case for case in study.cases if case.learned]
    return [
        "## Saturating motors: the current schedule",
        "",
        f"Excess cost over the true pointwise digital optimum at {CURRENTS} currents from "
        f"10% to 100% of rated on {study.pwm} PWM, largest (target <= 2%); incremental "
        f"inductances learned within one standard error of the truth: {_within_one(learned)} "
        "(68% expected). Over speed and current: the schedule over both from "
        f"{SPEED_SHARES[0]:.0%} to {SPEED_SHARES[1]:.0%} of the motor's speed, judged at "
        f"{SPEEDS} speeds over that range times those currents, and the schedule over i_q* "
        f"alone (designed at the motor's speed) there. {study.wall_seconds:.0f} s.",
        "",
        *table(
            [
                "motor",
                "seed",
                "L_qq fall %",
                "levels (logs refused)",
                "schedule %",
                "law at rated %",
                "law at 10% %",
                "largest L error % of L_qq",
                "over speed and current %",
                "i_q* schedule alone over speed %",
                "s",
            ],
            rows,
        ),
    ]
