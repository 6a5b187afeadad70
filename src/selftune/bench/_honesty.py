"""Study 6: honesty. Does any log of a realistic drive get a silently wrong answer?

Logs of the library's realistic drive (:class:`~selftune.sim.RealisticDrive`: a PWM
inverter's stationary-frame hold, a computation delay, noise on the measured phase
currents inside the loop) on motors and seeds that no test uses (a seeded generator,
:func:`honesty_cases`), each with one hazard of a real drive's log
(:data:`HAZARDS`): a commanded voltage logged as applied (shift 1 and 2), float32 and
7-significant-digit values, a clock offset in the time column, ADC quantization, an
inverter's dead time (stated with ``dead_time = True``, or not), short logs, and all of a
hardware-like drive at once. Every log has white current noise of 1-50 mA.

Each log is learned with the options a user would state (:func:`learn_controller`, the
digital target with the drive's delay, the alignment the user believes: "applied") and
its outcome classified against the truth, the optimum of the digital cost on the true
sampled loop with the delay:

- **correct**: K and U each within :data:`SE_MULTIPLE` stated standard errors of the truth,
  ``||K - K*|| <= 3 ||K_se||`` (Frobenius norms; U likewise). For a calibrated Gaussian
  estimate the chance of landing outside 3 norms is at most 0.27% (the case of one
  dominant entry, a chi-square with one degree of freedom beyond 9), so over 220 logs a
  calibrated learner is expected to be flagged less than once; 2 norms would flag up to 5%
  of correct answers;
- **refused**: an exception, by its class and the cause its message names
  (:func:`~._causes.refusal_cause`);
- **silent wrong**: returned, but outside its stated errors;
- **destabilizing**: returned, and the true sampled loop with the delay is unstable
  (:func:`~selftune.learn.closed_loop_radius` on the true discrete model, >= 1).
"""

from __future__ import annotations

import time
from collections import Counter
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..core import Array
from ..learn import DiscreteModel, LearningOptions, Trajectory, closed_loop_radius
from ..model import SPMSM
from ..sim import DriveSettings
from ._causes import CAUSE_TITLES, UNNAMED
from ._common import table, with_progress
from ._experiment import (
    DC_VOLTAGE,
    MOTOR_RANGES_TEXT,
    Experiment,
    Refused,
    attempt,
    random_experiment,
)
from ._motors import Choice, Span
from ._targets import TargetOutcome

__all__ = [
    "HAZARDS",
    "SE_MULTIPLE",
    "HazardTally",
    "Honesty",
    "HonestyCase",
    "HonestyOutcome",
    "honesty_cases",
    "honesty_target",
    "markdown_honesty",
    "measure_honesty",
]

#: A result within this many stated standard errors of the truth is correct.
SE_MULTIPLE = 3.0
#: Seed of the generator of motors, rates, noise and hazards' sizes (no test uses it).
CASES_SEED = 7_000_011
#: Seed of log i's drive (exploration and noise): ``DRIVE_SEED_BASE + i``.
DRIVE_SEED_BASE = 100_000

#: The hazards: key, what the log suffers, the refusal cause expected (None: either a
#: correct result or a named refusal is right).
HAZARDS: tuple[tuple[str, str, str | None], ...] = (
    ("aligned", "noise only, applied voltages logged (the control)", None),
    ("shift 1", "commanded voltages logged, stated as applied, 1-sample delay", "alignment"),
    ("shift 2", "commanded voltages logged, stated as applied, 2-sample delay", "alignment"),
    ("float32", "currents, voltages and reference stored as float32", None),
    ("7 digits", "currents, voltages and reference written with 7 significant digits", None),
    ("clock offset", "absolute times: an offset of 1 ms to 1e6 s, either sign", None),
    ("ADC", "10- or 12-bit ADC, 10-50 mA per LSB", None),
    ("dead time, stated", "0.5-3 V dead time, dead_time = True and the speed given", None),
    ("dead time, unstated", "0.5-3 V dead time, not stated", "consistency"),
    ("short", "5-50 ms logs", None),
    ("hardware-like", "carrier PWM, dead time (stated), 12-bit ADC, float32", None),
)

#: Outcomes, in table order.
OUTCOMES = ("correct", "refused", "silent wrong", "destabilizing")


@dataclass(frozen=True)
class HonestyCase:
    """One log of the sweep: the motor, the drive, the hazard, what the user states.

    Attributes
    ----------
    log_count : int
        The log's number i (its drive seed is ``100000 + i``).
    seed : int
        The drive's seed (exploration and noise).
    hazard_text : str
        The hazard's key (:data:`HAZARDS`).
    R_s_ohm, L_s_henry, phi_pm_weber : float
        The motor.
    pole_pairs_count : int
        p.
    speed_rad_per_second : float
        Held mechanical speed.
    torque_newton_meters : float
        Torque reference T*.
    sampling_frequency_hz : float
        f_s.
    input_delay_samples : int
        The drive's computation delay (stated correctly to the learner).
    data_seconds : float
        Length of the log.
    current_noise_amperes : float
        Noise on each measured phase current, A rms.
    method_text : str
        ``"adp"`` or ``"identify"`` (digital target).
    clock_offset_seconds : float
        Offset added to the time column, s (clock offset hazard).
    adc_bits_count : int
        ADC resolution, bits (ADC hazard; 0 otherwise).
    adc_range_amperes : float
        ADC full scale, A (ADC hazard).
    dead_time_volts : float
        ``t_d f_sw V_dc`` per phase, V (dead-time hazards).
    """

    log_count: int
    seed: int
    hazard_text: str
    R_s_ohm: float
    L_s_henry: float
    phi_pm_weber: float
    pole_pairs_count: int
    speed_rad_per_second: float
    torque_newton_meters: float
    sampling_frequency_hz: float
    input_delay_samples: int
    data_seconds: float
    current_noise_amperes: float
    method_text: str
    clock_offset_seconds: float = 0.0
    adc_bits_count: int = 0
    adc_range_amperes: float = 0.0
    dead_time_volts: float = 0.0

    @property
    def detail_text(self) -> str:
        """The hazard's size in this log."""
        hazard = self.hazard_text
        if hazard == "clock offset":
            return f"offset {self.clock_offset_seconds:.6g} s"
        if hazard == "ADC":
            return f"{self.adc_bits_count} bits over +-{self.adc_range_amperes:.4g} A"
        if hazard.startswith("dead time"):
            return f"{self.dead_time_volts:.3g} V"
        if hazard == "hardware-like":
            return "2 V dead time, 12-bit ADC over +-50 A, carrier PWM, float32"
        return hazard

    @property
    def experiment(self) -> Experiment:
        """The motor, speed, torque and sampling of the log."""
        motor = SPMSM(
            R_s=self.R_s_ohm, L_s=self.L_s_henry, phi_pm=self.phi_pm_weber, p=self.pole_pairs_count
        )
        return Experiment(
            motor, self.speed_rad_per_second, self.torque_newton_meters,
            1.0 / self.sampling_frequency_hz,
        )  # fmt: skip

    def reproduction_text(self) -> str:
        """The case in one line: enough to rebuild it with :func:`honesty_cases`."""
        return (
            f"log {self.log_count} (seed {self.seed}), {self.hazard_text} ({self.detail_text}); "
            f"motor R_s = {self.R_s_ohm:.4g} ohm, L_s = {self.L_s_henry:.4g} H, phi_pm = "
            f"{self.phi_pm_weber:.4g} Wb, p = {self.pole_pairs_count}, speed "
            f"{self.speed_rad_per_second:.4g} rad/s, T* = {self.torque_newton_meters:.4g} N m; "
            f"{self.sampling_frequency_hz / 1e3:g} kHz, delay {self.input_delay_samples}, "
            f"{self.data_seconds * 1e3:.4g} ms, noise {self.current_noise_amperes * 1e3:.3g} mA; "
            f"method {self.method_text}"
        )


@dataclass(frozen=True)
class HonestyOutcome:
    """What became of one log.

    Attributes
    ----------
    case : HonestyCase
    outcome_text : str
        ``"correct"``, ``"refused"``, ``"silent wrong"`` or ``"destabilizing"``.
    cause_text : str
        The refusal's cause key (empty unless refused).
    error_text : str
        The exception's class and message (empty unless refused).
    K_relative_error, U_relative_error : float or None
        Against the true digital optimum (None if refused).
    K_relative_se, U_relative_se : float or None
        The stated relative standard errors (None if refused).
    true_loop_radius_ratio : float or None
        Spectral radius of the true sampled loop with the delay under the learned law
        (None if refused; >= 1: unstable).
    peak_current_amperes : float
        The largest true current magnitude ``|i_dq|`` of the log, A (against an ADC's
        range: above it, the sensor saturated).
    """

    case: HonestyCase
    outcome_text: str
    cause_text: str
    error_text: str
    K_relative_error: float | None
    U_relative_error: float | None
    K_relative_se: float | None
    U_relative_se: float | None
    true_loop_radius_ratio: float | None
    peak_current_amperes: float


@dataclass(frozen=True)
class HazardTally:
    """The outcomes of one hazard's logs (or of all: ``hazard_text = "all"``).

    Attributes
    ----------
    hazard_text : str
    logs_count, correct_count, refused_count, silent_wrong_count, destabilizing_count : int
    expected_cause_text : str
        The refusal cause expected (empty: none in particular).
    refusals_text : str
        Refusals by cause, e.g. ``"alignment 20"``.
    expected_cause_count : int
        Refusals that name the expected cause (0 when none is expected).
    unnamed_refusals_count : int
        Refusals whose message names no recognizable cause.
    """

    hazard_text: str
    logs_count: int
    correct_count: int
    refused_count: int
    silent_wrong_count: int
    destabilizing_count: int
    expected_cause_text: str
    refusals_text: str
    expected_cause_count: int
    unnamed_refusals_count: int


@dataclass(frozen=True)
class Honesty:
    """Study 6's results.

    Attributes
    ----------
    se_multiple_factor : float
        A result within this many stated standard errors is correct (3).
    cases_seed : int
        Seed of the generator of the cases.
    outcomes : tuple of HonestyOutcome
        Every log's outcome.
    tallies : tuple of HazardTally
        Per hazard, then all logs.
    wall_seconds : float
        Time the study took, s.
    """

    se_multiple_factor: float
    cases_seed: int
    outcomes: tuple[HonestyOutcome, ...]
    tallies: tuple[HazardTally, ...]
    wall_seconds: float

    @property
    def overall(self) -> HazardTally:
        """The tally of all logs."""
        return self.tallies[-1]

    def failures(self) -> list[HonestyOutcome]:
        """The silent wrong and destabilizing outcomes."""
        return [o for o in self.outcomes if o.outcome_text in ("silent wrong", "destabilizing")]


def honesty_cases(logs_per_hazard: int, short: bool = False) -> list[HonestyCase]:
    """The sweep's logs: ``logs_per_hazard`` of each hazard, interleaved.

    Motors and rates from :func:`~._experiment.random_experiment`; noise 1-50 mA
    (log-uniform), logs of 0.1-0.4 s (5-50 ms for the short hazard); the method alternates
    between digital ADP and identify-then-design within each hazard.

    Parameters
    ----------
    logs_per_hazard : int
        Logs of each hazard.
    short : bool
        Logs of 50-100 ms instead of 0.1-0.4 s (the quick run).
    """
    rng = np.random.default_rng(CASES_SEED)
    cases = []
    for index in range(logs_per_hazard * len(HAZARDS)):
        hazard = HAZARDS[index % len(HAZARDS)][0]
        experiment = random_experiment(rng)
        motor = experiment.motor
        noise = Span(1e-3, 5e-2, log=True).draw(rng)
        seconds = (Span(0.05, 0.1) if short else Span(0.1, 0.4)).draw(rng)
        if hazard == "short":
            seconds = Span(0.005, 0.05).draw(rng)
        current = float(motor.current_reference(experiment.torque)[1])
        offset, bits, full_scale, volts = _sizes(hazard, rng, current)
        cases.append(
            HonestyCase(
                log_count=index, seed=DRIVE_SEED_BASE + index, hazard_text=hazard,
                R_s_ohm=motor.R_s, L_s_henry=motor.L_s, phi_pm_weber=motor.phi_pm,
                pole_pairs_count=motor.p, speed_rad_per_second=experiment.speed,
                torque_newton_meters=experiment.torque, sampling_frequency_hz=1.0 / experiment.h,
                input_delay_samples=2 if hazard == "shift 2" else 1,
                data_seconds=seconds, current_noise_amperes=noise,
                method_text=("adp", "identify")[(index // len(HAZARDS)) % 2],
                clock_offset_seconds=offset, adc_bits_count=bits, adc_range_amperes=full_scale,
                dead_time_volts=volts,
            )
        )  # fmt: skip
    return cases


def _sizes(
    hazard: str, rng: np.random.Generator, current: float
) -> tuple[float, int, float, float]:
    """The hazard's size, drawn: clock offset (s), ADC bits and range (A), dead time (V)."""
    if hazard == "clock offset":
        sign = Choice((-1.0, 1.0)).draw(rng)
        return sign * Span(1e-3, 1e6, log=True).draw(rng), 0, 0.0, 0.0
    if hazard == "ADC":
        lsb = Span(0.01, 0.05, log=True).draw(rng)
        bits = 12 if 2**9 * lsb < 3.0 * current else int(Choice((10, 12)).draw(rng))
        return 0.0, bits, lsb * 2 ** (bits - 1), 0.0
    if hazard.startswith("dead time"):
        return 0.0, 0, 0.0, Span(0.5, 3.0).draw(rng)
    return 0.0, 0, 0.0, 0.0


def _settings(case: HonestyCase) -> DriveSettings:
    """The drive of the case: the library's realistic drive with the hazard's effects."""
    h = 1.0 / case.sampling_frequency_hz
    base = DriveSettings(
        input_delay=case.input_delay_samples, current_noise=case.current_noise_amperes
    )
    hazard = case.hazard_text
    if hazard.startswith("shift"):
        return replace(base, logged_input="commanded")
    if hazard == "ADC":
        return replace(base, adc_bits=case.adc_bits_count, adc_range=case.adc_range_amperes)
    if hazard.startswith("dead time"):
        dead_time = case.dead_time_volts * h / DC_VOLTAGE
        return replace(base, dead_time=dead_time, dc_voltage=DC_VOLTAGE)
    if hazard == "hardware-like":
        return replace(
            DriveSettings.hardware_like(DC_VOLTAGE, h), current_noise=case.current_noise_amperes
        )
    return base


def _seven_digits(values: Array) -> Array:
    return np.array([float(f"{value:.7g}") for value in values.ravel()]).reshape(values.shape)


def _as_logged(case: HonestyCase, log: Trajectory) -> Trajectory:
    """The log as the hazard writes it (precision, time column)."""
    hazard = case.hazard_text
    assert log.w is not None
    if hazard in ("float32", "hardware-like"):
        single = [part.astype(np.float32) for part in (log.x, log.u, log.w)]
        return Trajectory(log.t, *single)
    if hazard == "7 digits":
        return Trajectory(log.t, *(_seven_digits(part) for part in (log.x, log.u, log.w)))
    if hazard == "clock offset":
        return Trajectory(log.t + case.clock_offset_seconds, log.x, log.u, log.w)
    return log


def _options(case: HonestyCase) -> LearningOptions:
    """What the user states: the digital target, the drive's delay, the voltages logged
    as applied; the dead time and the speed where the user knows of a dead time."""
    stated = case.hazard_text in ("dead time, stated", "hardware-like")
    return LearningOptions(
        target="digital", method=case.method_text, input_delay=case.input_delay_samples,  # type: ignore[arg-type]
        dead_time=stated, electrical_speed=case.experiment.electrical_speed if stated else None,
    )  # fmt: skip


def _outcome(case: HonestyCase) -> HonestyOutcome:
    experiment = case.experiment
    record = experiment.records(_settings(case), case.data_seconds, [case.seed])[0]
    peak = float(np.max(np.linalg.norm(record.true_currents, axis=1)))
    # the log as read (its time column is checked there), then learned
    tried = attempt(lambda: _as_logged(case, record.trajectory), experiment.known(), _options(case))
    if isinstance(tried, Refused):
        return HonestyOutcome(case, "refused", tried.cause, tried.message, *(None,) * 5, peak)
    learned = tried.controller
    truth = experiment.digital_optimum(case.input_delay_samples, "stationary")
    K_error, U_error = tried.errors((truth.K, truth.U))
    quality = learned.verdict
    model = DiscreteModel.given(*truth.sampled_plant, experiment.h)
    radius = closed_loop_radius(model, learned.law, case.input_delay_samples)
    if radius >= 1.0:
        outcome = "destabilizing"
    elif K_error <= SE_MULTIPLE * quality.K_relative_se and (
        U_error <= SE_MULTIPLE * quality.U_relative_se
    ):
        outcome = "correct"
    else:
        outcome = "silent wrong"
    return HonestyOutcome(
        case, outcome, "", "", K_error, U_error, quality.K_relative_se, quality.U_relative_se,
        radius, peak,
    )  # fmt: skip


def _tally(hazard: str, expected: str | None, outcomes: list[HonestyOutcome]) -> HazardTally:
    counts = Counter(o.outcome_text for o in outcomes)
    causes = Counter(o.cause_text for o in outcomes if o.outcome_text == "refused")
    return HazardTally(
        hazard_text=hazard,
        logs_count=len(outcomes),
        correct_count=counts["correct"],
        refused_count=counts["refused"],
        silent_wrong_count=counts["silent wrong"],
        destabilizing_count=counts["destabilizing"],
        expected_cause_text=expected or "",
        refusals_text=", ".join(f"{cause} {count}" for cause, count in causes.most_common()),
        expected_cause_count=causes[expected] if expected else 0,
        unnamed_refusals_count=causes[UNNAMED],
    )


def measure_honesty(
    logs_per_hazard: int, short: bool = False, progress: bool = False, client: Any = None
) -> Honesty:
    """Study 6 (see the module docstring).

    Parameters
    ----------
    logs_per_hazard : int
        Logs of each of the 11 hazards (20 in the full run: 220 logs).
    short : bool
        Logs of 50-100 ms (the quick run).
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).
    client : distributed.Client, optional
        Run the logs on its cluster (default: here; the same numbers).

    Returns
    -------
    Honesty
    """
    started = time.perf_counter()
    cases = honesty_cases(logs_per_hazard, short)
    outcomes = with_progress(cases, _outcome, "honesty", progress, client)
    tallies = [
        _tally(key, expected, [o for o in outcomes if o.case.hazard_text == key])
        for key, _, expected in HAZARDS
    ]
    tallies.append(_tally("all", None, outcomes))
    return Honesty(
        se_multiple_factor=SE_MULTIPLE,
        cases_seed=CASES_SEED,
        outcomes=tuple(outcomes),
        tallies=tuple(tallies),
        wall_seconds=time.perf_counter() - started,
    )


def markdown_honesty(honesty: Honesty) -> list[str]:
    """Section 6 of bench.md: outcomes per hazard, and every failure with its reproduction.

    Parameters
    ----------
    honesty : Honesty
        The study's results.
    """
    overall = honesty.overall
    lines = [
        "## 6. Honesty: no silent wrong answer from a realistic drive's log",
        "",
        f"{overall.logs_count} logs of the library's realistic drive (stationary-frame PWM "
        "hold, computation delay, white noise of 1-50 mA on the measured phase currents "
        f"inside the loop) on motors and seeds no test uses (generator seed "
        f"{honesty.cases_seed}; {MOTOR_RANGES_TEXT}), each with one hazard, learned with the "
        "options a user would state (digital target, the drive's delay, voltages stated as "
        "applied). Correct: K and U each within "
        f"{honesty.se_multiple_factor:g} stated standard errors of the true digital optimum "
        "(||K - K*|| <= 3 ||K_se||, U likewise: a calibrated estimate lands outside with "
        "probability at most 0.27%, so fewer than one correct answer in 220 is expected to be "
        "flagged); silent wrong: returned but outside them; destabilizing: the true sampled "
        "loop with the delay is unstable under the returned controller (spectral radius of "
        "the true discrete model's loop >= 1). Truth: the digital optimum of the true "
        "stationary-hold sampled plant (SPMSM.sampled_plant).",
        "",
    ]
    described = {key: text for key, text, _ in HAZARDS}
    lines += table(
        ["hazard", "logs", "correct", "refused", "silent wrong", "destabilizing",
         "refusals by cause", "naming the expected cause", "unnamed"],
        [
            [f"{t.hazard_text}: {described[t.hazard_text]}" if t.hazard_text in described
             else "**all**", str(t.logs_count), str(t.correct_count), str(t.refused_count),
             str(t.silent_wrong_count), str(t.destabilizing_count), t.refusals_text or "-",
             f"{t.expected_cause_count} ({t.expected_cause_text})" if t.expected_cause_text
             else "-", str(t.unnamed_refusals_count)]
            for t in honesty.tallies
        ],
    )  # fmt: skip
    causes = sorted({o.cause_text for o in honesty.outcomes if o.cause_text})
    lines += ["", "Causes: " + "; ".join(f"{key}: {CAUSE_TITLES[key]}" for key in causes) + "."]
    unnamed = [
        f"- refused without a recognizable cause: {o.case.reproduction_text()}: {o.error_text}"
        for o in honesty.outcomes
        if o.cause_text == UNNAMED
    ]
    lines += ["", *unnamed] if unnamed else []
    failures = honesty.failures()
    lines += ["", f"Silent wrong or destabilizing: {len(failures)}."]
    for failure in failures:
        lines.append(
            f"- {failure.outcome_text}: {failure.case.reproduction_text()}: K off by "
            f"{failure.K_relative_error:.3g} (stated se {failure.K_relative_se:.3g}), U off by "
            f"{failure.U_relative_error:.3g} (stated se {failure.U_relative_se:.3g}), true "
            f"loop radius {failure.true_loop_radius_ratio:.6f}, peak current "
            f"{failure.peak_current_amperes:.3g} A"
        )
    return lines


#: Logs the issue asks the sweep to cover, at least.
TARGET_LOGS = 200


def honesty_target(honesty: Honesty, quick: bool) -> TargetOutcome:
    """The issue's target: 0 silent wrong, 0 destabilizing over >= 200 logs, every refusal
    naming its cause (not judged on the quick run).

    Parameters
    ----------
    honesty : Honesty
        The study's results.
    quick : bool
        Whether it is the CI-sized run.
    """
    overall = honesty.overall
    clean = (
        overall.silent_wrong_count == 0
        and overall.destabilizing_count == 0
        and overall.unnamed_refusals_count == 0
    )
    return TargetOutcome(
        name_text="honesty",
        target_text=f"over >= {TARGET_LOGS} logs with hazards: 0 silent wrong, 0 "
        "destabilizing, every refusal names its cause",
        value_text=f"{overall.logs_count} logs: {overall.silent_wrong_count} silent wrong, "
        f"{overall.destabilizing_count} destabilizing, {overall.refused_count} refused "
        f"({overall.unnamed_refusals_count} without a named cause), "
        f"{overall.correct_count} correct",
        met=None if quick else bool(clean and overall.logs_count >= TARGET_LOGS),
        why_text=f"quick run ({overall.logs_count} logs): judged by the full bench"
        if quick
        else "correct: K and U within 3 stated standard errors of the true digital optimum; "
        "section 6 lists every failure with its reproduction",
    )
