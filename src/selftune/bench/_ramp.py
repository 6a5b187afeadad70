"""Speed schedules learned from 1 s of data over a speed range (issue 18).

Each run is :func:`selftune.tuning.commission_ramp`: 1 s of the drive with its speed on
a staircase of two held speeds, 5% and 100% of the motor's rated speed (0.5 s each: the
plant is affine in speed, so two speeds determine it; each segment as long as the
interior commissioning's one speed), the current steps under the gentle K0, the motor 20 K
warmer than its nameplate, on the hardware-like drive (carrier PWM, 10 mA noise, a 12-bit
ADC, one sample of delay, 2 V of dead time; 0.5 us on a 48 V bus). Each segment is
identified at its own speed with the motor's structure and the parameters combined; the
schedule is designed on the identified motor over the speeds the data cover (5-100% of
rated; :func:`selftune.model.design_schedule` with ``covered``), and judged against the
true (heated) motor's pointwise digital optimum at the 50 speeds between each pair of its
grid speeds (:meth:`selftune.model.ScheduleDesign.excess_of`, worst initial state). Beside
it, the single-speed controller: the identified motor's optimum at 50% of rated, its
excess at the top speed.

:func:`measure_ramp_draws` runs the same on motors drawn at random across the issue's
range (:func:`~._interior.drawn_motor`), which no table was chosen for.

The motors: the interior bench's six (:data:`~._interior.INTERIOR_MOTORS`: 25 uH to 150 mH,
``L_q / L_d`` 1.5 to 3, 2 to 20 pole pairs) at their speeds taken as rated, and three
surface motors (25 uH to 60 mH, 2 to 10 pole pairs).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from ..config import MotorConfig
from ..errors import SelftuneError
from ..model import SPMSM, Motor, design_schedule
from ..report import RampEvaluation, evaluate_ramp
from ..tuning import tuning_settings
from ..tuning._ramp import RAMP_LEVELS, RAMP_SECONDS, commission_ramp
from ._common import table, with_progress
from ._interior import (
    BOTTOM_SPEED_SHARE,
    INTERIOR_MOTORS,
    drawn_cases,
    study_drive,
)

__all__ = [
    "RAMP_MOTORS",
    "RampCase",
    "RampStudy",
    "markdown_ramp",
    "measure_ramp",
    "measure_ramp_draws",
]

#: The motors: (motor, rated mechanical speed rad/s, rated torque N m, DC bus V).
RAMP_MOTORS: tuple[tuple[Motor, float, float, float], ...] = (
    *INTERIOR_MOTORS,
    (SPMSM(R_s=0.02, L_s=25e-6, phi_pm=0.005, p=10), 15.0, 0.3, 48.0),
    (SPMSM(R_s=1.0, L_s=0.01, phi_pm=0.2, p=5), 60.0, 5.0, 540.0),
    (SPMSM.paper(), 100.0, 4.0, 540.0),
)

#: Where the single-speed controller is designed, a share of the rated speed.
SINGLE_SPEED_SHARE = 0.5


@dataclass(frozen=True)
class RampCase:
    """One run (NaN where it was refused).

    Attributes
    ----------
    motor_text : str
    seed : int
    refusal_text : str
        The refusal's first words ("" when learned).
    parameter_error_percent : float
        The largest relative error of the identified inductances and flux, %.
    schedule_excess_percent : float
        The schedule's largest excess over the true pointwise optimum, %.
    single_speed_excess_percent : float
        The single-speed controller's excess at the top speed, %.
    grid_points : int
        The schedule's grid speeds.
    top_w_e_h : float
        ``p speed h`` at the rated speed, rad per sample.
    wall_seconds : float
    top_current_median_ratio : float
        The median measured current magnitude at the top speed, in rated currents (the
        experiment's: a drive trips far above it).
    top_current_peak_ratio : float
        Its largest, in rated currents.
    largest_z : float
        The largest error of the identified inductances and flux, in their standard
        errors.
    """

    motor_text: str
    seed: int
    refusal_text: str
    parameter_error_percent: float
    schedule_excess_percent: float
    single_speed_excess_percent: float
    grid_points: int
    top_w_e_h: float
    wall_seconds: float
    top_current_median_ratio: float = float("nan")
    top_current_peak_ratio: float = float("nan")
    largest_z: float = float("nan")

    @property
    def learned(self) -> bool:
        """Whether the motor was identified."""
        return not self.refusal_text


@dataclass(frozen=True)
class RampStudy:
    """The runs.

    Attributes
    ----------
    cases : tuple of RampCase
    wall_seconds : float
    encoder_counts : int or None
        The logs' angle in an encoder's counts a turn (None: exact).
    """

    cases: tuple[RampCase, ...]
    wall_seconds: float
    encoder_counts: int | None = None


def _label(motor: Motor) -> str:
    if isinstance(motor, SPMSM):
        return f"SPMSM {motor.L_s * 1e3:g} mH, p {motor.p}"
    return f"IPMSM {motor.L_d * 1e3:g}/{motor.L_q * 1e3:g} mH, p {motor.p}"


def _errors(evaluation: RampEvaluation) -> tuple[float, float]:
    """The largest relative error of the inductances and flux, and the largest in their
    standard errors."""
    names = [name for name in evaluation.parameter_errors if name != "R_s"]
    relative = max(abs(evaluation.parameter_errors[name]) for name in names)
    return float(relative), float(max(abs(evaluation.z[name]) for name in names))


def _case(index: int, seed: int, encoder_counts: int | None = None) -> RampCase:
    motor, speed, torque, bus = RAMP_MOTORS[index]
    label = f"{index + 1}: {_label(motor)}"
    return _run(motor, speed, torque, bus, seed, label, encoder_counts=encoder_counts)


def _run(
    motor: Motor, speed: float, torque: float, bus: float, seed: int, label: str,
    adc_range: float | None = None, encoder_counts: int | None = None,
) -> RampCase:  # fmt: skip
    """One ramp commissioning judged against the truth (``adc_range``, A: the
    hardware-like drive's 50 A unless given; ``encoder_counts``: the log's angle an
    encoder's of that many counts a turn, None: exact)."""
    drive = replace(study_drive(bus, adc_range), encoder_counts=encoder_counts)
    config = MotorConfig(
        motor=motor, speed=speed, torque=torque, drive=drive, drive_h=1e-4,
        learning={"integral_action": True}, source=label,
    )  # fmt: skip
    settings = tuning_settings(config, seed)
    speeds = (BOTTOM_SPEED_SHARE * speed, speed)
    started = time.perf_counter()
    top = motor.p * speed * settings.h
    try:
        result = commission_ramp(
            motor, settings, drive, speeds, seconds=RAMP_SECONDS, levels=RAMP_LEVELS, seed=seed
        )
    except SelftuneError as error:
        nan = float("nan")
        return RampCase(
            label, seed, str(error)[:90], nan, nan, nan, 0, top, time.perf_counter() - started
        )
    identified = design_schedule(
        result.motor, speeds, settings.Q, settings.R, settings.h,
        input_delay=drive.input_delay, integral_weight=result.integral_weight,
        hold=drive.voltage_hold, covered=result.covered,
    )  # fmt: skip
    single = identified.pointwise_optimum(SINGLE_SPEED_SHARE * motor.p * speed).law
    evaluation = evaluate_ramp(result, motor, settings, drive, speeds, identified, single)
    rated = float(np.hypot(*motor.current_reference(torque)))
    currents = result.log.x[:-1][result.record_speeds == speed]  # at the top speed
    magnitude = np.hypot(currents[:, 0], currents[:, 1]) / rated
    relative, z = _errors(evaluation)
    return RampCase(
        label, seed, "", 100.0 * relative,
        100.0 * float(np.max(evaluation.schedule_excess)),
        100.0 * float(evaluation.single_excess[-1]),
        identified.schedule.electrical_speed.size, top, time.perf_counter() - started,
        float(np.median(magnitude)), float(np.max(magnitude)), z,
    )  # fmt: skip


def measure_ramp(
    quick: bool, progress: bool = True, seeds: int = 3, encoder_counts: int | None = None
) -> RampStudy:
    """The study (see the module).

    Parameters
    ----------
    quick : bool
        Two motors (one interior, one surface), one seed; else every motor over ``seeds``
        seeds (about 5-15 s a run).
    progress : bool
        Show a progress bar.
    seeds : int
        Seeds per motor in the full run.
    encoder_counts : int, optional
        The logs' angle as an encoder of that many counts a mechanical turn reads it
        (:class:`~selftune.sim.DriveSettings`); None: the exact angle.
    """
    cases = [(0, 0), (7, 0)] if quick else [
        (index, seed) for index in range(len(RAMP_MOTORS)) for seed in range(seeds)
    ]  # fmt: skip
    started = time.perf_counter()
    results = with_progress(
        cases, lambda case: _case(*case, encoder_counts=encoder_counts), "ramp", progress
    )
    return RampStudy(tuple(results), time.perf_counter() - started, encoder_counts)


def measure_ramp_draws(
    count: int = 60, seed: int = 11, progress: bool = True, encoder_counts: int | None = None
) -> RampStudy:
    """The study on ``count`` motors drawn at random (:func:`~._interior.drawn_cases` with
    ``seed``): what no motor of the table was chosen for (about 3-8 s a run).

    Parameters
    ----------
    count : int
        Motors drawn, surface and interior.
    seed : int
        Seed of the draws and of each run's own seed.
    progress : bool
        Show a progress bar of the runs.
    encoder_counts : int, optional
        The logs' angle as an encoder of that many counts a mechanical turn reads it
        (:class:`~selftune.sim.DriveSettings`); None: the exact angle.
    """

    def run(number: int) -> RampCase:
        motor, speed, torque, bus, case_seed, adc_range = cases[number]
        label = f"drawn {number + 1}: {_label(motor)}, {motor.p * speed:.0f} rad/s"
        return _run(motor, speed, torque, bus, case_seed, label, adc_range, encoder_counts)

    cases = drawn_cases(count, seed)
    started = time.perf_counter()
    results = with_progress(list(range(count)), run, "ramp draws", progress)
    return RampStudy(tuple(results), time.perf_counter() - started, encoder_counts)


def markdown_ramp(study: RampStudy) -> list[str]:
    """The study as a markdown section: a row per run, then the ranges.

    Parameters
    ----------
    study : RampStudy
        The results.
    """
    rows = []
    for case in study.cases:
        if not case.learned:
            refusal = "refused: " + case.refusal_text
            rows.append([case.motor_text, str(case.seed), refusal, "-", "-", "-",
                         f"{case.top_w_e_h:.3f}", "-", f"{case.wall_seconds:.1f}"])  # fmt: skip
            continue
        rows.append([case.motor_text, str(case.seed),
                     f"{case.parameter_error_percent:.3f} ({case.largest_z:.1f} se)",
                     f"{case.schedule_excess_percent:.2e}",
                     f"{case.single_speed_excess_percent:.3f}", str(case.grid_points),
                     f"{case.top_w_e_h:.3f}",
                     f"{case.top_current_median_ratio:.2f} / {case.top_current_peak_ratio:.2f}",
                     f"{case.wall_seconds:.1f}"])  # fmt: skip
    learned = [case for case in study.cases if case.learned]
    schedule = [case.schedule_excess_percent for case in learned]
    single = [case.single_speed_excess_percent for case in learned]
    median = [case.top_current_median_ratio for case in learned]
    summary = (
        f"{len(learned)} of {len(study.cases)} learned; the schedule's largest excess "
        f"{min(schedule):.2e}-{max(schedule):.2e}%, the single-speed controller's at the "
        f"top {min(single):.3f}-{max(single):.3f}%; the experiment's median current at the "
        f"top speed {min(median):.2f}-{max(median):.2f} times the rated; the largest "
        f"inductance or flux error {max(c.parameter_error_percent for c in learned):.3f}%, "
        f"beyond 3 standard errors in {sum(c.largest_z > 3.0 for c in learned)} runs"
        if learned
        else f"0 of {len(study.cases)} learned"
    )
    angle = (
        ""
        if study.encoder_counts is None
        else f", the angle a {study.encoder_counts}-count encoder's"
    )
    return [
        "## Speed schedules from 1 s over 5-100% of rated speed (hardware-like drive, 20 K "
        f"warm{angle})",
        "",
        f"{summary}. {study.wall_seconds:.0f} s.",
        "",
        *table(
            [
                "motor",
                "seed",
                "largest L/flux error % (in standard errors)",
                "schedule excess %",
                "single-speed excess at top %",
                "grid",
                "w_e h at rated",
                "current at top, median / peak, x rated",
                "s",
            ],
            rows,
        ),
    ]
