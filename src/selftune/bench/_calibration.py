"""Study 8: are the stated standard errors calibrated on motors no test uses?

Seeded trials (:func:`~._experiment.random_experiment`, a generator seed no test uses): a
motor, operating point and rate; the experiment of :mod:`._experiment` on the library's
drive with a one-sample delay, dq zero-order hold (so that both the continuous and the
digital optimum are exact truths) and white noise of 2-50 mA on the measured phase currents
inside the loop; 0.2-0.5 s of data. Every method learns from the same log; each returned
result is compared with the truth of its target.

The criterion (issue 11: "the true K lies within 2 standard errors in >= 90% of seeded
trials"): **norm-based**, ``||K - K*|| <= 2 ||K_se||`` (Frobenius norms over K's entries,
with the delayed inputs' columns for the digital target). For calibrated Gaussian errors it
holds with probability at least 95% (the chi-square of one degree of freedom, when one
entry dominates; more when the entries share the error), so a coverage below 90% means
the errors are understated. The entry-wise coverage (the fraction of all entries within
2 of their own standard errors; 95.4% when calibrated) is reported beside it, and U
likewise. Refusals are counted apart (a refusal states no error to cover).
"""

from __future__ import annotations

import statistics
import time
from collections import Counter
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..learn import LearnedController
from ._common import table, with_progress
from ._experiment import (
    MOTOR_RANGES_TEXT,
    Experiment,
    Refused,
    attempt,
    delayed_drive,
    random_experiment,
)
from ._motors import Span
from ._noise_study import NOISE_METHODS
from ._targets import TargetOutcome

__all__ = [
    "COVERAGE_MULTIPLE",
    "TARGET_COVERAGE",
    "Calibration",
    "CalibrationMethod",
    "CalibrationTrial",
    "calibration_target",
    "markdown_calibration",
    "measure_calibration",
]

#: The truth must lie within this many standard errors...
COVERAGE_MULTIPLE = 2.0
#: ...in at least this fraction of the trials.
TARGET_COVERAGE = 0.9
#: Seed of the generator of the trials (no test uses it).
TRIALS_SEED = 8_000_003
#: Seed of trial i's drive (exploration and noise): ``DRIVE_SEED_BASE + i``.
DRIVE_SEED_BASE = 200_000


@dataclass(frozen=True)
class CalibrationTrial:
    """One method on one trial's log.

    Attributes
    ----------
    trial_count : int
        The trial's number i (drive seed ``200000 + i``).
    method_text : str
        The method's key (as in study 7).
    experiment_text : str
        Motor, operating point, rate, noise and length, for reproduction.
    cause_text : str
        The refusal's cause key (empty if returned).
    K_error_over_se_ratio, U_error_over_se_ratio : float or None
        ``||K - K*|| / ||K_se||`` (U likewise); None if refused.
    K_entries_count : int
        Entries of K (0 if refused).
    K_entries_within_count, U_entries_within_count : int
        Entries within 2 of their standard errors.
    U_entries_count : int
    """

    trial_count: int
    method_text: str
    experiment_text: str
    cause_text: str
    K_error_over_se_ratio: float | None
    U_error_over_se_ratio: float | None
    K_entries_count: int
    K_entries_within_count: int
    U_entries_count: int
    U_entries_within_count: int


@dataclass(frozen=True)
class CalibrationMethod:
    """One method's coverage over the trials.

    Attributes
    ----------
    method_text : str
    trials_count : int
    refused_count : int
    refusals_text : str
        Refusals by cause.
    K_norm_coverage_ratio, U_norm_coverage_ratio : float or None
        Fraction of the returned results with ``||K - K*|| <= 2 ||K_se||`` (U likewise);
        None when none was returned.
    K_entry_coverage_ratio, U_entry_coverage_ratio : float or None
        Fraction of all returned entries within 2 of their standard errors.
    K_median_error_over_se_ratio, K_max_error_over_se_ratio : float or None
        Median and largest ``||K - K*|| / ||K_se||`` (1 on average when calibrated).
    K_within_one_se_ratio, K_within_three_se_ratio : float or None
        Fraction of the returned results with ``||K - K*|| <= c ||K_se||``, c = 1, 3
        (calibrated: ``P(chi2_d <= d)``, 0.68 for one entry to 0.57 for eight; and over
        0.99); None when none was returned.
    U_within_one_se_ratio, U_within_three_se_ratio : float or None
        The same for U.
    worst_trial_text : str
        The trial with the largest ratio, for reproduction.
    """

    method_text: str
    trials_count: int
    refused_count: int
    refusals_text: str
    K_norm_coverage_ratio: float | None
    U_norm_coverage_ratio: float | None
    K_entry_coverage_ratio: float | None
    U_entry_coverage_ratio: float | None
    K_median_error_over_se_ratio: float | None
    K_max_error_over_se_ratio: float | None
    K_within_one_se_ratio: float | None
    K_within_three_se_ratio: float | None
    U_within_one_se_ratio: float | None
    U_within_three_se_ratio: float | None
    worst_trial_text: str


@dataclass(frozen=True)
class Calibration:
    """Study 8's results.

    Attributes
    ----------
    coverage_multiple_factor : float
        The multiple of the standard errors (2).
    target_coverage_ratio : float
        The coverage targeted (0.9).
    trials_seed : int
        Seed of the generator of the trials.
    methods : tuple of CalibrationMethod
    trials : tuple of CalibrationTrial
    wall_seconds : float
    """

    coverage_multiple_factor: float
    target_coverage_ratio: float
    trials_seed: int
    methods: tuple[CalibrationMethod, ...]
    trials: tuple[CalibrationTrial, ...]
    wall_seconds: float


def _text(index: int, experiment: Experiment, noise: float, seconds: float) -> str:
    motor = experiment.motor
    return (
        f"trial {index} (seed {DRIVE_SEED_BASE + index}): R_s = {motor.R_s:.4g} ohm, L_s = "
        f"{motor.L_s:.4g} H, phi_pm = {motor.phi_pm:.4g} Wb, p = {motor.p}, speed "
        f"{experiment.speed:.4g} rad/s, T* = {experiment.torque:.4g} N m, "
        f"{1e-3 / experiment.h:g} kHz, noise {noise * 1e3:.3g} mA, {seconds * 1e3:.4g} ms"
    )


def _judged(
    index: int,
    key: str,
    text: str,
    learned: LearnedController,
    truth: tuple[np.ndarray, np.ndarray],
) -> CalibrationTrial:
    quality = learned.verdict
    K_gap, U_gap = np.abs(learned.K - truth[0]), np.abs(learned.U - truth[1])
    return CalibrationTrial(
        trial_count=index, method_text=key, experiment_text=text, cause_text="",
        K_error_over_se_ratio=float(np.linalg.norm(K_gap) / np.linalg.norm(quality.K_se)),
        U_error_over_se_ratio=float(np.linalg.norm(U_gap) / np.linalg.norm(quality.U_se)),
        K_entries_count=K_gap.size,
        K_entries_within_count=int(np.sum(K_gap <= COVERAGE_MULTIPLE * quality.K_se)),
        U_entries_count=U_gap.size,
        U_entries_within_count=int(np.sum(U_gap <= COVERAGE_MULTIPLE * quality.U_se)),
    )  # fmt: skip


def _draw(index: int, rng: np.random.Generator) -> tuple[int, Experiment, float, float]:
    """Trial ``index``'s motor, noise and length, drawn in the trials' order."""
    experiment = random_experiment(rng)
    noise, seconds = Span(2e-3, 5e-2, log=True).draw(rng), Span(0.2, 0.5).draw(rng)
    return index, experiment, noise, seconds


def _trials(drawn: tuple[int, Experiment, float, float]) -> list[CalibrationTrial]:
    """Every method on a trial's log (its draws: :func:`_draw`)."""
    index, experiment, noise, seconds = drawn
    text = _text(index, experiment, noise, seconds)
    log = experiment.logs(delayed_drive(noise), seconds, [DRIVE_SEED_BASE + index])[0]
    truths = experiment.truths()
    trials = []
    for key, _, options in NOISE_METHODS:
        if options.structure == "spmsm":
            options = replace(options, electrical_speed=experiment.electrical_speed)
        tried = attempt(log, experiment.known(), options)
        if isinstance(tried, Refused):
            trials.append(CalibrationTrial(index, key, text, tried.cause, None, None, 0, 0, 0, 0))
            continue
        trials.append(_judged(index, key, text, tried.controller, truths[options.target]))
    return trials


def _fraction(numerator: int, denominator: int) -> float | None:
    return numerator / denominator if denominator else None


def _method(key: str, trials: list[CalibrationTrial]) -> CalibrationMethod:
    returned = [t for t in trials if not t.cause_text]
    causes = Counter(t.cause_text for t in trials if t.cause_text)
    K_ratios = [t.K_error_over_se_ratio for t in returned if t.K_error_over_se_ratio is not None]
    U_ratios = [t.U_error_over_se_ratio for t in returned if t.U_error_over_se_ratio is not None]
    worst = max(returned, key=lambda t: t.K_error_over_se_ratio or 0.0, default=None)
    return CalibrationMethod(
        method_text=key, trials_count=len(trials), refused_count=sum(causes.values()),
        refusals_text=", ".join(f"{cause} {count}" for cause, count in causes.most_common()),
        K_norm_coverage_ratio=_fraction(
            sum(r <= COVERAGE_MULTIPLE for r in K_ratios), len(K_ratios)),
        U_norm_coverage_ratio=_fraction(
            sum(r <= COVERAGE_MULTIPLE for r in U_ratios), len(U_ratios)),
        K_entry_coverage_ratio=_fraction(
            sum(t.K_entries_within_count for t in returned),
            sum(t.K_entries_count for t in returned)),
        U_entry_coverage_ratio=_fraction(
            sum(t.U_entries_within_count for t in returned),
            sum(t.U_entries_count for t in returned)),
        K_median_error_over_se_ratio=statistics.median(K_ratios) if K_ratios else None,
        K_max_error_over_se_ratio=max(K_ratios) if K_ratios else None,
        K_within_one_se_ratio=_fraction(sum(r <= 1.0 for r in K_ratios), len(K_ratios)),
        K_within_three_se_ratio=_fraction(sum(r <= 3.0 for r in K_ratios), len(K_ratios)),
        U_within_one_se_ratio=_fraction(sum(r <= 1.0 for r in U_ratios), len(U_ratios)),
        U_within_three_se_ratio=_fraction(sum(r <= 3.0 for r in U_ratios), len(U_ratios)),
        worst_trial_text="" if worst is None else worst.experiment_text,
    )  # fmt: skip


def measure_calibration(
    trials_count: int, progress: bool = False, client: Any = None
) -> Calibration:
    """Study 8 (see the module docstring).

    Parameters
    ----------
    trials_count : int
        Seeded trials (motors); every method learns from each.
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).
    client : distributed.Client, optional
        Run the trials on its cluster (default: here; the same numbers).

    Returns
    -------
    Calibration
    """
    started = time.perf_counter()
    rng = np.random.default_rng(TRIALS_SEED)
    drawn = [_draw(index, rng) for index in range(trials_count)]
    each = with_progress(drawn, _trials, "calibration", progress, client)
    trials = [trial for group in each for trial in group]
    methods = [
        _method(key, [t for t in trials if t.method_text == key]) for key, _, _ in NOISE_METHODS
    ]
    return Calibration(
        coverage_multiple_factor=COVERAGE_MULTIPLE, target_coverage_ratio=TARGET_COVERAGE,
        trials_seed=TRIALS_SEED, methods=tuple(methods), trials=tuple(trials),
        wall_seconds=time.perf_counter() - started,
    )  # fmt: skip


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.0f}%"


def markdown_calibration(calibration: Calibration) -> list[str]:
    """Section 8 of bench.md: coverage of the stated standard errors, per method.

    Parameters
    ----------
    calibration : Calibration
        The study's results.
    """
    titles = {key: title for key, title, _ in NOISE_METHODS}
    count = len({t.trial_count for t in calibration.trials})
    multiple = f"{calibration.coverage_multiple_factor:g}"
    lines = [
        "## 8. Calibration of the stated standard errors",
        "",
        f"{count} seeded trials on motors no test uses (generator seed "
        f"{calibration.trials_seed}; {MOTOR_RANGES_TEXT}; noise 2-50 mA inside the loop, "
        "0.2-0.5 s, one-sample delay, dq hold). Coverage: the fraction of returned results "
        f"with ||K - K*|| <= {multiple} ||K_se|| (Frobenius; >= 95% when calibrated, target "
        f">= {100 * calibration.target_coverage_ratio:.0f}%), and of all entries within "
        f"{multiple} of their own standard errors (95% when calibrated); U likewise. "
        "||K - K*|| / ||K_se|| is about 1 when the errors are calibrated. Within 1 and 3: "
        "the fractions with ||K - K*|| <= 1 and 3 ||K_se|| (K: the feedback of the currents "
        "and the delayed voltages; calibrated, 57-68% and over 99%).",
        "",
    ]
    lines += table(
        ["method", "trials", "refused", "K coverage (norm)", "K coverage (entries)",
         "U coverage (norm)", "U coverage (entries)", "median ratio", "largest ratio",
         "K within 1 / 3", "U within 1 / 3", "refusals by cause"],
        [
            [titles[m.method_text], str(m.trials_count), str(m.refused_count),
             _percent(m.K_norm_coverage_ratio), _percent(m.K_entry_coverage_ratio),
             _percent(m.U_norm_coverage_ratio), _percent(m.U_entry_coverage_ratio),
             "n/a" if m.K_median_error_over_se_ratio is None
             else f"{m.K_median_error_over_se_ratio:.2f}",
             "n/a" if m.K_max_error_over_se_ratio is None
             else f"{m.K_max_error_over_se_ratio:.2f}",
             f"{_percent(m.K_within_one_se_ratio)} / {_percent(m.K_within_three_se_ratio)}",
             f"{_percent(m.U_within_one_se_ratio)} / {_percent(m.U_within_three_se_ratio)}",
             m.refusals_text or "-"]
            for m in calibration.methods
        ],
    )  # fmt: skip
    lines += [""] + [
        f"- {titles[m.method_text]}: largest ratio on {m.worst_trial_text}"
        for m in calibration.methods
        if m.worst_trial_text
    ]
    return lines


def calibration_target(calibration: Calibration, quick: bool) -> TargetOutcome:
    """The issue's target: the true K within 2 standard errors in >= 90% of the trials,
    for every method (norm criterion; not judged on the quick run).

    Parameters
    ----------
    calibration : Calibration
        The study's results.
    quick : bool
        Whether it is the CI-sized run.
    """
    coverages = {
        m.method_text: m.K_norm_coverage_ratio
        for m in calibration.methods
        if m.K_norm_coverage_ratio is not None
    }
    worst = min(coverages, key=lambda key: coverages[key]) if coverages else None
    count = len({t.trial_count for t in calibration.trials})
    return TargetOutcome(
        name_text="calibration",
        target_text=f"norm(K - K*) <= {calibration.coverage_multiple_factor:g} norm(K_se) in >= "
        f"{100 * calibration.target_coverage_ratio:.0f}% of seeded trials, every method",
        value_text="no result"
        if worst is None
        else f"lowest {100 * coverages[worst]:.0f}% ({worst}) over {count} motors",
        met=None
        if quick or worst is None
        else bool(coverages[worst] >= calibration.target_coverage_ratio),
        why_text=f"quick run ({count} motors): judged by the full bench"
        if quick
        else "motors no test uses; refusals state no error and are counted apart (section 8)",
    )
