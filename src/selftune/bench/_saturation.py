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

:func:`measure_saturation_draws` runs the same on motors drawn at random across the
issue's range (:func:`drawn_saturating`), each at its rated speed with its own knee,
saturating share and cross-saturation (:data:`SATURATION_DRAWS`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np

from ..config import MotorConfig
from ..errors import InputError, SelftuneError
from ..model import IPMSM
from ..report._saturation_report import (
    CURRENTS,
    SPEEDS,
    evaluate_current_schedule,
    judged_references,
)
from ..sim import DriveSettings, Saturation, SaturationModel
from ..tuning import commission_over_current, tuning_settings
from ._common import table, with_progress
from ._interior import LOW_VOLTAGE_DEAD_TIME, drawn_motor

#: The drive's PWM.
Pwm = Literal["average", "carrier"]

__all__ = [
    "CURRENTS",
    "SATURATING_MOTORS",
    "SATURATION_DRAWS",
    "SaturationCase",
    "SaturationStudy",
    "drawn_saturating",
    "inductance_fall",
    "markdown_saturation",
    "measure_saturation",
    "measure_saturation_draws",
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

#: The drawn motors' saturation (:func:`measure_saturation_draws`), each uniform on its
#: span: the knee ``i_sat`` as a share of the rated q current, ``drop`` and ``cross``.
SATURATION_DRAWS = {"i_sat_share": (0.4, 1.0), "drop": (0.25, 0.5), "cross": (0.0, 0.2)}

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
    redrawn : int
        Motors drawn again (:func:`drawn_saturating`).
    """

    cases: tuple[SaturationCase, ...]
    wall_seconds: float
    pwm: Pwm = "average"
    redrawn: int = 0


def _case(index: int, seed: int, pwm: Pwm = "average") -> SaturationCase:
    """The table's motor ``index`` (from 0) on the run's ``seed``."""
    motor, speed, torque, bus, share, drop = SATURATING_MOTORS[index]
    rated = float(motor.current_reference(torque)[1])
    saturation = SaturationModel.of(motor, i_sat=share * rated, drop=drop, cross=CROSS)
    label = f"{index + 1}: {type(motor).__name__} {motor.L_d * 1e3:g}/{motor.L_q * 1e3:g} mH"
    return _run((motor, speed, torque, bus, None), saturation, seed, label, pwm)


def inductance_fall(motor: IPMSM, torque: float, saturation: Saturation) -> float:
    """The true incremental ``L_qq``'s fall from the first to the last judged current
    (10 % and 100 % of rated torque's, :func:`judged_references`), a share of the first.

    Parameters
    ----------
    motor : IPMSM
        The nameplate motor (its MTPA path).
    torque : float
        Rated torque, N m.
    saturation : SaturationModel or FluxMap
        The true flux linkages.
    """
    references = judged_references(motor, torque)
    low, high = (saturation.incremental(*references[k])[1, 1] for k in (0, -1))
    return float(1.0 - high / low)


def _run(
    nameplate: tuple[IPMSM, float, float, float, float | None], saturation: Saturation,
    seed: int, label: str, pwm: Pwm,
) -> SaturationCase:  # fmt: skip
    """One commissioning over the load judged against the truth: ``nameplate`` is the
    motor, its mechanical speed (rad/s), rated torque (N m), DC bus (V) and the ADC's
    range (A; None: the hardware-like drive's)."""
    motor, speed, torque, bus, adc_range = nameplate
    drive = replace(DriveSettings.hardware_like(dc_voltage=bus), pwm=pwm)
    if bus < 100.0:  # a low-voltage drive's MOSFETs, as the interior study's
        drive = replace(drive, dead_time=LOW_VOLTAGE_DEAD_TIME)
    if adc_range is not None:
        drive = replace(drive, adc_range=adc_range)
    config = MotorConfig(
        motor=motor, speed=speed, torque=torque, drive=drive, drive_h=1e-4,
        learning={"integral_action": True}, source=label, saturation=saturation,
    )  # fmt: skip
    settings = tuning_settings(config, seed)
    fall = 100.0 * inductance_fall(motor, torque, saturation)
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


#: One drawn saturating motor: its nameplate (the interior form; its mechanical speed,
#: rad/s, rated torque, N m, DC bus, V, and ADC range, A), its saturation and its run's seed.
DrawnSaturating = tuple[tuple[IPMSM, float, float, float, float], SaturationModel, int]


def drawn_saturating(count: int, seed: int) -> tuple[list[DrawnSaturating], int]:
    """``count`` motors drawn across the issue's range (the ramp's and the interior
    study's :func:`~._interior.drawn_motor`, a surface motor in its interior form), each
    saturating by :data:`SATURATION_DRAWS` drawn after it, and its run's seed; and how
    many were drawn again: a motor whose drawn knee is under the saturation model's floor
    (1 % of its characteristic current ``phi_pm / L_d``, a motor rated far below it).

    Parameters
    ----------
    count : int
        Motors.
    seed : int
        Seed of the draws.
    """
    rng = np.random.default_rng(seed)
    cases: list[DrawnSaturating] = []
    redrawn = 0
    while len(cases) < count:
        nameplate, speed, torque, bus, adc_range = drawn_motor(rng)
        motor = IPMSM.of(nameplate)
        share, drop, cross = (rng.uniform(*span) for span in SATURATION_DRAWS.values())
        rated = float(motor.current_reference(torque)[1])
        try:
            saturation = SaturationModel.of(motor, i_sat=share * rated, drop=drop, cross=cross)
        except InputError:  # the knee under the model's floor
            redrawn += 1
            continue
        cases.append(((motor, speed, torque, bus, adc_range), saturation, int(rng.integers(1000))))
    return cases, redrawn


def measure_saturation_draws(
    count: int = 20, seed: int = 21, progress: bool = True, pwm: Pwm = "average"
) -> SaturationStudy:
    """The study on ``count`` saturating motors drawn at random
    (:func:`drawn_saturating`), each at its rated speed with the ADC's range it was drawn
    with (about 30-150 s a run).

    Parameters
    ----------
    count : int
        Motors learned.
    seed : int
        Seed of the draws and of each run's own seed.
    progress : bool
        Show a progress bar.
    pwm : str
        The drive's PWM, as :func:`measure_saturation`'s.
    """
    cases, redrawn = drawn_saturating(count, seed)

    def run(number: int) -> SaturationCase:
        nameplate, saturation, case_seed = cases[number]
        motor, bus = nameplate[0], nameplate[3]
        label = (
            f"drawn {number + 1}: {motor.L_d * 1e3:.4g}/{motor.L_q * 1e3:.4g} mH, p {motor.p}, "
            f"{bus:.0f} V"
        )
        return _run(nameplate, saturation, case_seed, label, pwm)

    started = time.perf_counter()
    results = with_progress(list(range(count)), run, "saturation draws", progress)
    return SaturationStudy(tuple(results), time.perf_counter() - started, pwm, redrawn)


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
        f"alone (designed at the motor's speed) there. {study.wall_seconds:.0f} s"
        + (
            f"; {study.redrawn} motors drawn again (their knee under the model's floor)."
            if study.redrawn
            else "."
        ),
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
