"""``selftune bench``: data efficiency, cost of learning, simulation speed, value of self-tuning.

Every comparison runs in one process on this machine; :func:`run_bench` returns a typed
:class:`BenchReport`, which :meth:`BenchReport.to_json` and :meth:`BenchReport.to_markdown`
render for ``bench.json`` and ``bench.md``. Each field name carries its unit
(``offpolicy_seconds``, ``us_per_step``, ``cost_volt2_seconds``, ...), and the JSON keys
are the field names.

1. :func:`measure_data_efficiency` -- seconds of motor data until
   ``||K - K*|| / ||K*|| <= 1e-4`` and ``||U - U*|| / ||U*|| <= 1e-4`` on the paper's case:
   the paper's on-policy Algorithm 2 (episodes of 5 ms) against the off-policy variant
   (one batch, as short as it can be, against the identifiability floor of 11 intervals).
2. :func:`measure_learning_cost` -- the customized learner against the general one of
   Gao & Jiang (2016) on the same data.
3. :func:`measure_simulation` -- microseconds per control step of the current loop at
   10 us sampling: :func:`~selftune.simulate.simulate` against scipy's ``solve_ivp``
   (RK45) and gym-electric-motor's PMSM environment (optional extra ``[bench]``), each
   checked against the exact solution; and a batch of 1,000 motors.
4. :func:`measure_self_tuning_value` -- the cost (5) of a torque step and the steady-state
   torque error when R_s, L_s and phi_pm are 30% off (8 motors): LQR + feedforward and PI
   designed on nominal values (and on nominal R_s, L_s with the measured flux), the
   self-tuned controllers (off-policy with the flux known; Algorithm 3 with it identified),
   and the true optimum.

The learners never see a model; the model-based optimum and the exact closed-form
solution are used only to score them.
"""

from __future__ import annotations

import argparse
import cmath
import dataclasses
import functools
import importlib
import importlib.metadata
import itertools
import math
import os
import platform
import statistics
import sys
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import scipy
import scipy.integrate
import scipy.linalg
from numpy.typing import NDArray

from . import __version__
from ._atomic import finite_or_null, to_jsonable, write_json, write_text
from .errors import ConvergenceError, ExcitationError
from .learning import learn_output_regulation
from .motor import SPMSM
from .regulation import ModelBasedSolution, solve_optimal_regulation
from .simulate import constant, discretize, held, simulate, simulate_batch, uniform
from .torque import (
    SimulatedDrive,
    TuningSettings,
    known_flux_form,
    reference_perturbation,
    run_algorithm,
)
from .vectorize import theta_sizes

__all__ = [
    "BatchMeasurement",
    "BenchConfig",
    "BenchReport",
    "ControllerOutcome",
    "DataEfficiency",
    "Environment",
    "ErrorCurve",
    "GymElectricMotor",
    "LearningCost",
    "LearningDataset",
    "LearningRun",
    "MismatchCase",
    "SelfTuningValue",
    "Simulation",
    "SimulatorMeasurement",
    "TargetOutcome",
    "add_bench_arguments",
    "measure_data_efficiency",
    "measure_learning_cost",
    "measure_self_tuning_value",
    "measure_simulation",
    "run_bench",
    "run_bench_command",
]

Array = NDArray[np.float64]

#: Relative error of K and of U that counts as learned (issue 5), dimensionless.
TARGET_RELATIVE_ERROR = 1e-4
#: Target of ``data_ratio_vs_paper``: on-policy data over off-policy data.
TARGET_DATA_RATIO = 50.0
#: Target of ``speedup_vs_gem``: gym-electric-motor's time per step over ours.
TARGET_SPEEDUP = 50.0
#: Largest relative error that counts as exact simulation (rounding only).
EXACT_RELATIVE_ERROR = 1e-9
#: Relative parameter error of the mismatch study (R_s, L_s, phi_pm each +-30%).
MISMATCH = 0.3
#: Horizon of the cost (5) of the torque step, s: at least 20 time constants of the optimal
#: loop of every motor of the study, so that what the optimum leaves beyond it (a relative
#: e^-40 of its cost) cannot let another controller beat it by the horizon alone.
COST_HORIZON_SECONDS = 0.05
#: Regression unknowns of the motor, n(n+1)/2 + m n + q n = 3 + 4 + 4: the fewest intervals
#: that can determine Theta.
IDENTIFIABILITY_FLOOR_INTERVALS = sum(theta_sizes(2, 2, 2))
#: The controllers of the mismatch study, in table order.
CONTROLLERS = (
    "lqr_nominal",
    "lqr_true_flux",
    "pi_nominal",
    "pi_true_flux",
    "self_tuned",
    "self_tuned_unknown_flux",
    "optimum",
)
_CONTROLLER_TITLES = {
    "lqr_nominal": "(a) LQR+FF, nominal",
    "lqr_true_flux": "(a') LQR+FF, nominal R L, true flux",
    "pi_nominal": "(b) PI, nominal",
    "pi_true_flux": "(b') PI, true flux",
    "self_tuned": "(c) self-tuned, off-policy",
    "self_tuned_unknown_flux": "(c') self-tuned, Algorithm 3",
    "optimum": "(d) true optimum",
}


# -- configuration -----------------------------------------------------------------------


@dataclass(frozen=True)
class BenchConfig:
    """Sizes of the sweeps and repeats: :meth:`full` (the published run) or :meth:`quick` (CI).

    Attributes
    ----------
    seeds : tuple of int
        Exploration seeds; every data-efficiency result is a median over them.
    offpolicy_samples : tuple of int
        Batch lengths of the off-policy sweep, samples (10 us each), increasing.
    learning_repeats : int
        Timed repeats of each learning run (the median is reported).
    learning_datasets : tuple of (float, int)
        Sampling period (s) and length (samples) of each data set of the learning-cost
        comparison.
    simulate_samples : int
        Samples of the timed :func:`~selftune.simulate.simulate` run.
    loop_samples : int
        Samples of the timed step-by-step loop (``discretize`` and one product a step).
    compare_samples : int
        Samples of the runs compared with the exact solution (solve_ivp, gym-electric-motor).
    batch_motors : int
        Motors in the batch run.
    batch_samples : int
        Samples per motor in the batch run.
    timing_repeats : int
        Repeats of the fast timed runs (the median is reported).
    batch_repeats : int
        Repeats of the batch run, each on fresh motors.
    """

    seeds: tuple[int, ...]
    offpolicy_samples: tuple[int, ...]
    learning_repeats: int
    learning_datasets: tuple[tuple[float, int], ...]
    simulate_samples: int
    loop_samples: int
    compare_samples: int
    batch_motors: int
    batch_samples: int
    timing_repeats: int
    batch_repeats: int

    @classmethod
    def full(cls) -> BenchConfig:
        """The published run: 5 seeds, every batch length from 11 to 60 samples, and more."""
        lengths = (*range(11, 61), *range(70, 201, 10), 300, 500)
        return cls(
            seeds=(0, 1000, 2000, 3000, 4000),
            offpolicy_samples=lengths,
            learning_repeats=30,
            learning_datasets=((1e-5, 500), (1e-5, 5000), (1e-6, 5000)),
            simulate_samples=100_000,
            loop_samples=20_000,
            compare_samples=2_000,
            batch_motors=1_000,
            batch_samples=1_000,
            timing_repeats=5,
            batch_repeats=3,
        )

    @classmethod
    def quick(cls) -> BenchConfig:
        """A CI-sized run: 3 seeds, a coarse sweep, few repeats, short runs."""
        return cls(
            seeds=(0, 1000, 2000),
            offpolicy_samples=(11, 15, 20, 25, 30, 40, 50, 60, 80, 100, 200),
            learning_repeats=3,
            learning_datasets=((1e-5, 500), (1e-6, 5000)),
            simulate_samples=10_000,
            loop_samples=2_000,
            compare_samples=300,
            batch_motors=1_000,
            batch_samples=200,
            timing_repeats=2,
            batch_repeats=1,
        )


# -- progress ----------------------------------------------------------------------------


class _Progress:
    """A tqdm bar on stderr, shown only on a terminal and when asked for."""

    def __init__(self, enabled: bool) -> None:
        self.enabled = enabled and sys.stderr.isatty()

    @contextmanager
    def bar(self, total: int, description: str) -> Iterator[Callable[[], None]]:
        """Yield a function that advances the bar by one step."""
        if not self.enabled:
            yield lambda: None
            return
        from tqdm import tqdm

        progress = tqdm(total=total, desc=description, file=sys.stderr, leave=False)
        try:
            yield lambda: progress.update(1)
        finally:
            progress.close()


# -- small helpers -----------------------------------------------------------------------


def _relative(value: Array, reference: Array) -> float:
    """``||value - reference|| / ||reference||`` (Frobenius), dimensionless."""
    return float(np.linalg.norm(value - reference)) / float(np.linalg.norm(reference))


def _median(values: Sequence[float]) -> float:
    """Median; ``inf`` entries (failed runs) count as larger than any number."""
    return float(statistics.median(values))


def _finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _timed(function: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``function()`` over ``repeats`` calls, s (time.perf_counter)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return float(statistics.median(times))


def _optimum(motor: SPMSM, settings: TuningSettings) -> ModelBasedSolution:
    return solve_optimal_regulation(
        motor.regulation_problem(settings.speed), settings.Q, settings.R
    )


# -- 1. data efficiency ------------------------------------------------------------------


@dataclass(frozen=True)
class ErrorCurve:
    """Learning error against the motor data used, medians over the seeds.

    Attributes
    ----------
    data_seconds : tuple of float
        Motor data used, s.
    K_relative_error : tuple of float or None
        Median over seeds of ``||K - K*|| / ||K*||``; None when most runs failed.
    U_relative_error : tuple of float or None
        Median over seeds of ``||U - U*|| / ||U*||``; None when most runs failed.
    failed_runs_count : tuple of int
        Runs that raised (e.g. too few intervals to determine Theta) at each point.
    """

    data_seconds: tuple[float, ...]
    K_relative_error: tuple[float | None, ...]
    U_relative_error: tuple[float | None, ...]
    failed_runs_count: tuple[int, ...]


@dataclass(frozen=True)
class DataEfficiency:
    """Motor data needed to learn K* and U* to the target, on-policy against off-policy.

    Attributes
    ----------
    target_relative_error : float
        Both ``||K - K*||/||K*||`` and ``||U - U*||/||U*||`` must be at most this.
    sampling_seconds : float
        Sampling period, s.
    seeds : tuple of int
        Exploration seeds (on-policy episode j of seed s uses seed s + j).
    onpolicy_episode_seconds : float
        Length of each on-policy episode, s (the paper's 5 ms).
    onpolicy_intervals_per_episode : int
        Regression intervals (rows) of each on-policy episode.
    onpolicy_seconds_per_seed : tuple of float or None
        Data the paper's Algorithm 2 had used when its controller first met both targets,
        s, per seed (None: never).
    onpolicy_seconds : float or None
        Median of ``onpolicy_seconds_per_seed``, s.
    onpolicy_curve : ErrorCurve
        The controller in force after each multiple of the episode length.
    offpolicy_interval_samples : int
        Samples per regression interval in the off-policy sweep.
    offpolicy_curve : ErrorCurve
        Error of the off-policy result against the batch length.
    offpolicy_samples : int or None
        Shortest swept batch, samples, such that it and every longer swept batch meet both
        targets (median over seeds of the larger of the two errors).
    offpolicy_intervals : int or None
        Regression intervals (rows) of that batch.
    offpolicy_seconds : float or None
        Its length, s.
    identifiability_floor_intervals : int
        Unknowns of the regression (11): no batch with fewer intervals can work.
    offpolicy_intervals_vs_floor_ratio : float or None
        ``offpolicy_intervals / identifiability_floor_intervals``.
    data_ratio_vs_paper : float or None
        ``onpolicy_seconds / offpolicy_seconds``.
    data_ratio_target : float
        Target of the ratio (50).
    wall_seconds : float
        Time this comparison took, s.
    """

    target_relative_error: float
    sampling_seconds: float
    seeds: tuple[int, ...]
    onpolicy_episode_seconds: float
    onpolicy_intervals_per_episode: int
    onpolicy_seconds_per_seed: tuple[float | None, ...]
    onpolicy_seconds: float | None
    onpolicy_curve: ErrorCurve
    offpolicy_interval_samples: int
    offpolicy_curve: ErrorCurve
    offpolicy_samples: int | None
    offpolicy_intervals: int | None
    offpolicy_seconds: float | None
    identifiability_floor_intervals: int
    offpolicy_intervals_vs_floor_ratio: float | None
    data_ratio_vs_paper: float | None
    data_ratio_target: float
    wall_seconds: float


def _onpolicy_trace(
    motor: SPMSM, settings: TuningSettings, optimum: ModelBasedSolution
) -> list[tuple[float, float, float]]:
    """``(data_seconds, K error, U error)`` of the controller in force after each step."""
    result = run_algorithm("2", motor, settings)
    return [
        (item.data_seconds, _relative(item.K, optimum.K), _relative(item.U, optimum.U))
        for item in result.history
    ]


def _error_curve(
    points: Sequence[float], errors: Sequence[Sequence[tuple[float, float]]]
) -> ErrorCurve:
    """Medians over seeds; ``errors[i][s]`` is the (K, U) error at point i for seed s."""
    K_median = [_median([k for k, _ in row]) for row in errors]
    U_median = [_median([u for _, u in row]) for row in errors]
    return ErrorCurve(
        data_seconds=tuple(points),
        K_relative_error=tuple(_finite_or_none(value) for value in K_median),
        U_relative_error=tuple(_finite_or_none(value) for value in U_median),
        failed_runs_count=tuple(
            sum(1 for k, u in row if not (math.isfinite(k) and math.isfinite(u))) for row in errors
        ),
    )


def _offpolicy_errors(
    motor: SPMSM, settings: TuningSettings, optimum: ModelBasedSolution
) -> tuple[float, float]:
    try:
        result = run_algorithm("offpolicy", motor, settings)
    except (ExcitationError, ConvergenceError):  # too short a batch: a failed run
        return math.inf, math.inf
    return _relative(result.K, optimum.K), _relative(result.U, optimum.U)


def measure_data_efficiency(config: BenchConfig, progress: bool = False) -> DataEfficiency:
    """Seconds of motor data to reach the target errors, on-policy and off-policy.

    On-policy: the paper's Algorithm 2 with its settings (:class:`TuningSettings`
    defaults); the data counted is what it has used when the controller in force first
    meets both targets. Off-policy: one batch of N samples under ``K0`` with exploration
    and the perturbed reference, learned with one sample per regression interval; N is
    swept over ``config.offpolicy_samples``.

    Parameters
    ----------
    config : BenchConfig
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).

    Returns
    -------
    DataEfficiency
    """
    bars = _Progress(progress)
    started = time.perf_counter()
    motor = SPMSM.paper()
    settings = TuningSettings.paper()
    optimum = _optimum(motor, settings)
    target = TARGET_RELATIVE_ERROR

    traces: list[list[tuple[float, float, float]]] = []
    with bars.bar(len(config.seeds), "data efficiency: on-policy") as step:
        for seed in config.seeds:
            traces.append(_onpolicy_trace(motor, dataclasses.replace(settings, seed=seed), optimum))
            step()
    first_met: list[float | None] = []
    for trace in traces:
        met = [seconds for seconds, k, u in trace if k <= target and u <= target]
        first_met.append(met[0] if met else None)
    onpolicy_seconds = (
        _median([math.inf if value is None else value for value in first_met])
        if first_met
        else math.inf
    )
    # The curve: the controller in force after each whole number of episodes.
    episode = settings.episode_length
    longest = max(trace[-1][0] for trace in traces)
    grid = [episode * k for k in range(round(longest / episode) + 1)]
    start_errors = (_relative(settings.K0, optimum.K), 1.0)  # U0 = 0
    onpolicy_rows = []
    for seconds in grid:
        row = []
        for trace in traces:
            used = [(k, u) for data, k, u in trace if data <= seconds * (1 + 1e-9)]
            row.append(used[-1] if used else start_errors)
        onpolicy_rows.append(row)

    offpolicy_rows = []
    with bars.bar(len(config.offpolicy_samples), "data efficiency: off-policy") as step:
        for samples in config.offpolicy_samples:
            row = []
            for seed in config.seeds:
                batch_settings = dataclasses.replace(
                    settings,
                    episode_length=samples * settings.sampling,
                    interval=1,
                    seed=seed,
                )
                row.append(_offpolicy_errors(motor, batch_settings, optimum))
            offpolicy_rows.append(row)
            step()
    worst = [_median([max(k, u) for k, u in row]) for row in offpolicy_rows]
    shortest: int | None = None
    for index in range(len(worst) - 1, -1, -1):
        if worst[index] > target:
            break
        shortest = config.offpolicy_samples[index]
    offpolicy_seconds = math.inf if shortest is None else shortest * settings.sampling
    ratio = onpolicy_seconds / offpolicy_seconds
    return DataEfficiency(
        target_relative_error=target,
        sampling_seconds=settings.sampling,
        seeds=config.seeds,
        onpolicy_episode_seconds=episode,
        onpolicy_intervals_per_episode=-(-settings.samples_per_episode // settings.interval),
        onpolicy_seconds_per_seed=tuple(first_met),
        onpolicy_seconds=_finite_or_none(onpolicy_seconds),
        onpolicy_curve=_error_curve(grid, onpolicy_rows),
        offpolicy_interval_samples=1,
        offpolicy_curve=_error_curve(
            [samples * settings.sampling for samples in config.offpolicy_samples],
            offpolicy_rows,
        ),
        offpolicy_samples=shortest,
        offpolicy_intervals=shortest,
        offpolicy_seconds=_finite_or_none(offpolicy_seconds),
        identifiability_floor_intervals=IDENTIFIABILITY_FLOOR_INTERVALS,
        offpolicy_intervals_vs_floor_ratio=(
            None if shortest is None else shortest / IDENTIFIABILITY_FLOOR_INTERVALS
        ),
        data_ratio_vs_paper=_finite_or_none(ratio) if math.isfinite(offpolicy_seconds) else None,
        data_ratio_target=TARGET_DATA_RATIO,
        wall_seconds=time.perf_counter() - started,
    )


# -- 2. cost of learning -----------------------------------------------------------------


@dataclass(frozen=True)
class LearningRun:
    """One learner on one data set.

    Attributes
    ----------
    unknowns_count : int
        Unknowns of each policy-iteration regression.
    rows_count : int
        Regression rows (intervals).
    least_squares_solves_count : int
        Least-squares solves per learning run (policy-iteration steps plus, for the general
        method, one Sylvester solve per basis element of ``C X + F = 0``).
    iterations_count : int
        Policy-iteration steps.
    regression_condition_ratio : float
        Condition number (largest over smallest singular value, columns scaled to unit
        norm) of the last policy-iteration regression.
    wall_seconds : float
        Median wall time of a whole learning run (moments, iteration, feedforward), s.
    repeats_count : int
        Timed repeats.
    theta_relative_error : float
        ``||Theta - Theta*|| / ||Theta*||`` against the model-based Theta*.
    K_relative_error, U_relative_error : float
        ``||K - K*|| / ||K*||`` and ``||U - U*|| / ||U*||``.
    """

    unknowns_count: int
    rows_count: int
    least_squares_solves_count: int
    iterations_count: int
    regression_condition_ratio: float
    wall_seconds: float
    repeats_count: int
    theta_relative_error: float
    K_relative_error: float
    U_relative_error: float


@dataclass(frozen=True)
class LearningDataset:
    """The customized and the general learner on the same off-policy batch.

    Attributes
    ----------
    samples : int
        Samples in the batch.
    sampling_seconds : float
        Sampling period, s.
    interval_samples : int
        Samples per regression interval.
    data_seconds : float
        Batch length, s.
    customized : LearningRun
        The paper's customized learner (``xbar = x - X* w`` with the unique X*).
    general : LearningRun
        Gao & Jiang (2016): iteration on ``x``, then the Sylvester-map solves.
    """

    samples: int
    sampling_seconds: float
    interval_samples: int
    data_seconds: float
    customized: LearningRun
    general: LearningRun


@dataclass(frozen=True)
class LearningCost:
    """The customized learner against the general one (Gao & Jiang 2016).

    Attributes
    ----------
    datasets : tuple of LearningDataset
    wall_seconds : float
        Time this comparison took, s.
    """

    datasets: tuple[LearningDataset, ...]
    wall_seconds: float


def _offpolicy_batch(
    motor: SPMSM, settings: TuningSettings, samples: int, seed: int
) -> tuple[Any, Array, Array, Array]:
    """The off-policy batch (as :func:`selftune.torque.offpolicy` makes it) and ``C, E, F``."""
    C, E, F, w = known_flux_form(motor.p, settings.speed, settings.torque, motor.phi_pm)
    X = -F  # C = I
    drive = SimulatedDrive(motor=motor, speed=settings.speed, sampling=settings.sampling)

    def perturbed(t: Array) -> Array:
        return w + reference_perturbation(t, settings.perturbation)

    batch = drive.run(
        settings.K0,
        X,
        np.zeros((2, 2)),
        held(perturbed),
        num_samples=samples,
        exploration=uniform(settings.exploration),
        seed=seed,
    )
    return batch, C, E, F


def measure_learning_cost(config: BenchConfig, progress: bool = False) -> LearningCost:
    """Unknowns, rows, solves, wall time and accuracy of the two learners on the same data.

    Parameters
    ----------
    config : BenchConfig
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).

    Returns
    -------
    LearningCost
    """
    bars = _Progress(progress)
    started = time.perf_counter()
    motor = SPMSM.paper()
    settings = TuningSettings.paper()
    optimum = _optimum(motor, settings)
    datasets = []
    methods: tuple[Literal["customized", "general"], ...] = ("customized", "general")
    with bars.bar(len(config.learning_datasets) * 2, "learning cost") as step:
        for sampling, samples in config.learning_datasets:
            settings = TuningSettings.paper(sampling=sampling)
            batch, C, E, F = _offpolicy_batch(motor, settings, samples, seed=config.seeds[0])
            learners = {
                method: functools.partial(
                    learn_output_regulation,
                    batch,
                    C,
                    E,
                    F,
                    settings.Q,
                    settings.R,
                    settings.K0,
                    interval=settings.interval,
                    method=method,
                )
                for method in methods
            }
            # warm-up, and the results whose accuracy is reported
            results = {method: learn() for method, learn in learners.items()}
            # the methods alternate, so that both see the same load on the machine
            times: dict[str, list[float]] = {method: [] for method in methods}
            for _ in range(config.learning_repeats):
                for method, learn in learners.items():
                    times[method].append(_timed(learn, 1))
            runs = {}
            for method, learned in results.items():
                runs[method] = LearningRun(
                    unknowns_count=learned.unknowns,
                    rows_count=learned.rows,
                    least_squares_solves_count=learned.least_squares_solves,
                    iterations_count=learned.iterations,
                    regression_condition_ratio=learned.history[-1].regression.condition,
                    wall_seconds=float(statistics.median(times[method])),
                    repeats_count=config.learning_repeats,
                    theta_relative_error=_relative(learned.theta, optimum.theta),
                    K_relative_error=_relative(learned.K, optimum.K),
                    U_relative_error=_relative(learned.U, optimum.U),
                )
                step()
            datasets.append(
                LearningDataset(
                    samples=samples,
                    sampling_seconds=sampling,
                    interval_samples=settings.interval,
                    data_seconds=samples * sampling,
                    customized=runs["customized"],
                    general=runs["general"],
                )
            )
    return LearningCost(datasets=tuple(datasets), wall_seconds=time.perf_counter() - started)


# -- 3. simulation -----------------------------------------------------------------------


@dataclass(frozen=True)
class SimulatorMeasurement:
    """Time per control step and error against the exact solution, for one simulator.

    Attributes
    ----------
    us_per_step : float
        Wall time per simulated control step (10 us of motor time), microseconds.
    timed_samples : int
        Steps in the timed run.
    max_relative_error : float
        ``max_k ||x_k - x_exact,k||_inf / max_k ||x_exact,k||_inf`` over the compared run.
    compared_samples : int
        Steps compared with the exact solution.
    """

    us_per_step: float
    timed_samples: int
    max_relative_error: float
    compared_samples: int


@dataclass(frozen=True)
class GymElectricMotor:
    """gym-electric-motor's ``Cont-CC-PMSM-v0`` with the same motor, if installed.

    Attributes
    ----------
    available : bool
        Whether it was installed and ran.
    version_text : str or None
        Its version.
    reason_text : str or None
        Why it was not measured.
    default_solver : SimulatorMeasurement or None
        Its default ODE solver (scipy ``ode``, dopri5).
    euler_solver : SimulatorMeasurement or None
        Its explicit Euler solver (its fastest).
    """

    available: bool
    version_text: str | None
    reason_text: str | None
    default_solver: SimulatorMeasurement | None
    euler_solver: SimulatorMeasurement | None


@dataclass(frozen=True)
class BatchMeasurement:
    """:func:`~selftune.simulate.simulate_batch` on a batch of motors.

    Attributes
    ----------
    motors_count : int
        Motors (parameter sets) in the batch.
    samples_per_motor : int
        Steps simulated for each motor.
    steps_per_second : float
        Motor-steps simulated per second of wall time.
    wall_seconds : float
        Median wall time of the batch run, s, with fresh motors each repeat (so the
        discretization of every motor, a matrix exponential each, is included).
    warm_steps_per_second : float
        The same run again on the same motors, whose discretization is then cached.
    max_relative_error : float
        Error of the first motor's trajectory against its exact solution (as above).
    """

    motors_count: int
    samples_per_motor: int
    steps_per_second: float
    wall_seconds: float
    warm_steps_per_second: float
    max_relative_error: float


@dataclass(frozen=True)
class Simulation:
    """Simulation speed and exactness on the SPMSM current loop at 10 us sampling.

    Every run is the closed loop of the paper's motor at 10 rad/s under the optimal
    controller ``u = -K* (x - X* w) + U* w + rho`` from rest, T* = 10 N m, with the same
    uniform exploration ``rho`` (1 V) in all simulators.

    Attributes
    ----------
    sampling_seconds : float
        Control period, s.
    selftune_simulate : SimulatorMeasurement
        :func:`~selftune.simulate.simulate`: the whole closed loop in one call.
    selftune_step_loop : SimulatorMeasurement
        An interactive Python loop, one step at a time, on
        :func:`~selftune.simulate.discretize` (what a user with their own controller code
        would write).
    solve_ivp_rk45 : SimulatorMeasurement
        ``scipy.integrate.solve_ivp`` (RK45, default tolerances), sample by sample with the
        input held.
    solve_ivp_rk45_tight : SimulatorMeasurement
        The same with ``rtol = 1e-10``, ``atol = 1e-12``.
    gym_electric_motor : GymElectricMotor
    batch : BatchMeasurement
    speedup_vs_gem : float or None
        gym-electric-motor's time per step (default solver) over ``selftune_simulate``'s.
    speedup_vs_gem_euler : float or None
        The same against its Euler solver.
    step_loop_speedup_vs_gem : float or None
        gym-electric-motor's (default solver) over the interactive loop's.
    speedup_target : float
        Target of ``speedup_vs_gem`` (50).
    wall_seconds : float
        Time this comparison took, s.
    """

    sampling_seconds: float
    selftune_simulate: SimulatorMeasurement
    selftune_step_loop: SimulatorMeasurement
    solve_ivp_rk45: SimulatorMeasurement
    solve_ivp_rk45_tight: SimulatorMeasurement
    gym_electric_motor: GymElectricMotor
    batch: BatchMeasurement
    speedup_vs_gem: float | None
    speedup_vs_gem_euler: float | None
    step_loop_speedup_vs_gem: float | None
    speedup_target: float
    wall_seconds: float


@dataclass(frozen=True)
class _Loop:
    """The closed loop every simulator runs: plant, controller, exploration."""

    motor: SPMSM
    speed: float
    h: float
    A: Array
    B: Array
    D: Array
    w: Array
    K: Array
    L: Array  # u = -K x + L w + rho
    optimum: ModelBasedSolution

    @classmethod
    def paper(cls) -> _Loop:
        motor = SPMSM.paper()
        settings = TuningSettings.paper()
        problem = motor.regulation_problem(settings.speed)
        optimum = _optimum(motor, settings)
        return cls(
            motor=motor,
            speed=settings.speed,
            h=settings.sampling,
            A=np.asarray(problem.A),
            B=np.asarray(problem.B),
            D=np.asarray(problem.D),
            w=motor.exogenous(settings.speed, settings.torque),
            K=np.asarray(optimum.K),
            L=np.asarray(optimum.L),
            optimum=optimum,
        )

    def exploration(self, samples: int, seed: int = 0) -> Array:
        """The exploration ``rho`` (samples, 2), V: uniform in [-1, 1] V."""
        return np.random.default_rng(seed).uniform(-1.0, 1.0, size=(samples, 2))


def _exact_states(loop: _Loop, motor: SPMSM, rho: Array) -> Array:
    """The closed loop's states at the sample times, exact up to rounding, (N + 1, 2).

    Independent of the matrix exponential: in complex form ``z = i_d + j i_q`` the current
    dynamics are ``z' = lambda z + f`` with ``lambda = -R_s/L_s - j p speed`` and the forcing
    ``f = u / L_s + D w`` held over a sample, so ``z_(k+1) = exp(lambda h) z_k +
    expm1(lambda h)/lambda f_k`` exactly.
    """
    rate = complex(-motor.gamma, -motor.p * loop.speed)
    decay = cmath.exp(rate * loop.h)
    gain = complex(np.expm1(rate * loop.h)) / rate
    feedforward = loop.L @ loop.w
    back_emf = _exogenous_matrix(motor, loop.speed) @ loop.w  # D w, A/s
    z = 0j
    K = loop.K
    states = np.empty((rho.shape[0] + 1, 2))
    states[0] = 0.0
    for k in range(rho.shape[0]):
        i_d, i_q = z.real, z.imag
        u_d = -K[0, 0] * i_d - K[0, 1] * i_q + feedforward[0] + rho[k, 0]
        u_q = -K[1, 0] * i_d - K[1, 1] * i_q + feedforward[1] + rho[k, 1]
        forcing = complex(u_d / motor.L_s + back_emf[0], u_q / motor.L_s + back_emf[1])
        z = decay * z + gain * forcing
        states[k + 1] = (z.real, z.imag)
    return states


def _exogenous_matrix(motor: SPMSM, speed: float) -> Array:
    return np.asarray(motor.regulation_problem(speed).D)


def _max_relative_error(states: Array, exact: Array) -> float:
    return float(np.max(np.abs(states - exact))) / float(np.max(np.abs(exact)))


def _measure_simulate(loop: _Loop, samples: int, repeats: int) -> SimulatorMeasurement:
    rho = loop.exploration(samples)

    def run() -> Array:
        return simulate(
            loop.A,
            loop.B,
            D=loop.D,
            exogenous=constant(loop.w),
            K=loop.K,
            X=loop.optimum.X,
            U=loop.optimum.U,
            exploration=rho,
            h=loop.h,
            num_samples=samples,
        ).x

    seconds = _timed(run, repeats)
    error = _max_relative_error(run(), _exact_states(loop, loop.motor, rho))
    return SimulatorMeasurement(
        us_per_step=seconds / samples * 1e6,
        timed_samples=samples,
        max_relative_error=error,
        compared_samples=samples,
    )


def _measure_step_loop(loop: _Loop, samples: int, repeats: int) -> SimulatorMeasurement:
    rho = loop.exploration(samples)

    def run() -> Array:
        model = discretize(loop.A, loop.B, loop.h, D=loop.D)
        Phi, Gamma_u = model.Phi, model.Gamma_u
        drift = model.Gamma_w @ loop.w
        reference = loop.L @ loop.w
        K = loop.K
        states = np.empty((samples + 1, 2))
        x = np.zeros(2)
        states[0] = x
        for k in range(samples):
            u = reference - K @ x + rho[k]
            x = Phi @ x + Gamma_u @ u + drift
            states[k + 1] = x
        return states

    seconds = _timed(run, repeats)
    error = _max_relative_error(run(), _exact_states(loop, loop.motor, rho))
    return SimulatorMeasurement(
        us_per_step=seconds / samples * 1e6,
        timed_samples=samples,
        max_relative_error=error,
        compared_samples=samples,
    )


def _measure_solve_ivp(
    loop: _Loop, samples: int, rtol: float | None, atol: float | None
) -> SimulatorMeasurement:
    rho = loop.exploration(samples)
    A, B = loop.A, loop.B
    back_emf = loop.D @ loop.w
    reference = loop.L @ loop.w
    options: dict[str, float] = {}
    if rtol is not None:
        options["rtol"] = rtol
    if atol is not None:
        options["atol"] = atol
    states = np.empty((samples + 1, 2))
    x = np.zeros(2)
    states[0] = x
    start = time.perf_counter()
    for k in range(samples):
        u = reference - loop.K @ x + rho[k]
        forcing = B @ u + back_emf

        def derivative(_t: float, state: Array, forcing: Array = forcing) -> Array:
            return A @ state + forcing

        solution = scipy.integrate.solve_ivp(
            derivative, (k * loop.h, (k + 1) * loop.h), x, method="RK45", **options
        )
        x = solution.y[:, -1]
        states[k + 1] = x
    seconds = time.perf_counter() - start
    return SimulatorMeasurement(
        us_per_step=seconds / samples * 1e6,
        timed_samples=samples,
        max_relative_error=_max_relative_error(states, _exact_states(loop, loop.motor, rho)),
        compared_samples=samples,
    )


def _gem_version() -> str | None:
    try:
        return importlib.metadata.version("gym-electric-motor")
    except importlib.metadata.PackageNotFoundError:
        return None


def _run_gem(loop: _Loop, samples: int, euler: bool) -> SimulatorMeasurement:
    """gym-electric-motor's continuous current-control PMSM env with the paper's motor.

    The action is the phase-voltage vector of a B6 bridge, normalized by half the DC
    voltage; it is computed from the dq voltage with the rotor angle at the start of the
    step, which the environment uses to transform it back, so the motor sees exactly the
    held dq voltage (the angle advance of gym-electric-motor's dq wrapper would rotate it
    by half a step). The DC link (2 kV) and the limits (1 kA) are set so that nothing
    saturates or terminates.
    """
    gem: Any = importlib.import_module("gym_electric_motor")
    systems: Any = importlib.import_module("gym_electric_motor.physical_systems")
    references: Any = importlib.import_module("gym_electric_motor.reference_generators")
    motor = loop.motor
    half_dc = 1000.0
    options: dict[str, Any] = {}
    if euler:
        options["ode_solver"] = systems.EulerSolver()
    limits = {"i": 1000.0, "u": 1000.0, "omega": 10.0 * loop.speed}
    env = gem.make(
        "Cont-CC-PMSM-v0",
        motor={
            "motor_parameter": {
                "p": motor.p,
                "l_d": motor.L_s,
                "l_q": motor.L_s,
                "j_rotor": motor.J or 0.0163,
                "r_s": motor.R_s,
                "psi_p": motor.phi_pm,
            },
            "limit_values": limits,
            "nominal_values": limits,
        },
        load={"omega_fixed": loop.speed},
        supply={"u_nominal": 2.0 * half_dc},
        tau=loop.h,
        reference_generator=references.ConstReferenceGenerator("i_sq", 0.0),
        visualization=(),
        constraints=(),
        **options,
    )
    names = list(env.unwrapped.physical_system.state_names)
    scale = np.asarray(env.unwrapped.physical_system.limits, dtype=float)
    index_d, index_q, index_angle = (names.index(n) for n in ("i_sd", "i_sq", "epsilon"))
    to_abc = systems.ThreePhaseMotor.t_32
    rotate = systems.ThreePhaseMotor.q
    rho = loop.exploration(samples)
    reference = loop.L @ loop.w
    states = np.empty((samples + 1, 2))
    (observation, _), _ = env.reset(seed=0)
    x = observation[[index_d, index_q]] * scale[[index_d, index_q]]
    states[0] = x
    start = time.perf_counter()
    for k in range(samples):
        u = reference - loop.K @ x + rho[k]
        angle = observation[index_angle] * scale[index_angle]
        action = to_abc(rotate(u / half_dc, angle))
        (observation, _), _, terminated, truncated, _ = env.step(action)
        x = observation[[index_d, index_q]] * scale[[index_d, index_q]]
        states[k + 1] = x
        if terminated or truncated:
            raise RuntimeError(f"the environment ended the episode at step {k}")
    seconds = time.perf_counter() - start
    env.close()
    return SimulatorMeasurement(
        us_per_step=seconds / samples * 1e6,
        timed_samples=samples,
        max_relative_error=_max_relative_error(states, _exact_states(loop, motor, rho)),
        compared_samples=samples,
    )


def _measure_gem(loop: _Loop, samples: int) -> GymElectricMotor:
    version = _gem_version()
    if version is None:
        return GymElectricMotor(
            available=False,
            version_text=None,
            reason_text="not installed (pip install 'selftune[bench]')",
            default_solver=None,
            euler_solver=None,
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            default = _run_gem(loop, samples, euler=False)
            euler = _run_gem(loop, samples, euler=True)
    except Exception as exc:  # an optional third-party package: report, do not fail
        return GymElectricMotor(
            available=False,
            version_text=version,
            reason_text=f"installed but failed: {type(exc).__name__}: {exc}",
            default_solver=None,
            euler_solver=None,
        )
    return GymElectricMotor(
        available=True,
        version_text=version,
        reason_text=None,
        default_solver=default,
        euler_solver=euler,
    )


def _random_motors(count: int, seed: int) -> list[SPMSM]:
    """``count`` motors with R_s, L_s, phi_pm uniform within +-30% of the paper's."""
    nominal = SPMSM.paper()
    factors = np.random.default_rng(seed).uniform(1 - MISMATCH, 1 + MISMATCH, size=(count, 3))
    return [
        SPMSM(R_s=nominal.R_s * r, L_s=nominal.L_s * ell, phi_pm=nominal.phi_pm * phi, p=nominal.p)
        for r, ell, phi in factors
    ]


def _measure_batch(loop: _Loop, motors: int, samples: int, repeats: int) -> BatchMeasurement:
    rho = loop.exploration(samples)
    cold, warm = [], []
    first: tuple[SPMSM, Array] | None = None
    for repeat in range(repeats):
        batch_motors = _random_motors(motors, seed=repeat)
        A = np.stack([m.torque_mode(loop.speed)[0] for m in batch_motors])
        B = np.stack([m.torque_mode(loop.speed)[1] for m in batch_motors])
        D = np.stack([_exogenous_matrix(m, loop.speed) for m in batch_motors])

        def run(A: Array = A, B: Array = B, D: Array = D) -> Array:
            result = simulate_batch(
                A,
                B,
                D=D,
                exogenous=constant(loop.w),
                K=loop.K,
                X=loop.optimum.X,
                U=loop.optimum.U,
                exploration=rho,
                h=loop.h,
                num_samples=samples,
            )
            return np.asarray(result.x[0])

        cold.append(_timed(run, 1))
        warm.append(_timed(run, 1))
        if first is None:
            first = (batch_motors[0], run())
    assert first is not None
    seconds = float(statistics.median(cold))
    error = _max_relative_error(first[1], _exact_states(loop, first[0], rho))
    return BatchMeasurement(
        motors_count=motors,
        samples_per_motor=samples,
        steps_per_second=motors * samples / seconds,
        wall_seconds=seconds,
        warm_steps_per_second=motors * samples / float(statistics.median(warm)),
        max_relative_error=error,
    )


def measure_simulation(config: BenchConfig, progress: bool = False) -> Simulation:
    """Time per step and exactness of each simulator, and a batch of motors.

    Parameters
    ----------
    config : BenchConfig
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).

    Returns
    -------
    Simulation
    """
    bars = _Progress(progress)
    started = time.perf_counter()
    loop = _Loop.paper()
    with bars.bar(6, "simulation") as step:
        ours = _measure_simulate(loop, config.simulate_samples, config.timing_repeats)
        step()
        step_loop = _measure_step_loop(loop, config.loop_samples, config.timing_repeats)
        step()
        rk45 = _measure_solve_ivp(loop, config.compare_samples, None, None)
        step()
        rk45_tight = _measure_solve_ivp(loop, config.compare_samples, 1e-10, 1e-12)
        step()
        gem = _measure_gem(loop, config.compare_samples)
        step()
        batch = _measure_batch(
            loop, config.batch_motors, config.batch_samples, config.batch_repeats
        )
        step()

    def speedup(reference: SimulatorMeasurement | None, ours: SimulatorMeasurement) -> float | None:
        return None if reference is None else reference.us_per_step / ours.us_per_step

    return Simulation(
        sampling_seconds=loop.h,
        selftune_simulate=ours,
        selftune_step_loop=step_loop,
        solve_ivp_rk45=rk45,
        solve_ivp_rk45_tight=rk45_tight,
        gym_electric_motor=gem,
        batch=batch,
        speedup_vs_gem=speedup(gem.default_solver, ours),
        speedup_vs_gem_euler=speedup(gem.euler_solver, ours),
        step_loop_speedup_vs_gem=speedup(gem.default_solver, step_loop),
        speedup_target=TARGET_SPEEDUP,
        wall_seconds=time.perf_counter() - started,
    )


# -- 4. the value of self-tuning ---------------------------------------------------------


@dataclass(frozen=True)
class ControllerOutcome:
    """One controller's torque step on one motor.

    Attributes
    ----------
    cost_volt2_seconds : float
        The cost (5) of the step over the horizon, V^2 s (Q in V^2/A^2, R dimensionless).
    excess_cost_percent : float
        ``100 (cost / cost of the true optimum - 1)``, %.
    steady_torque_error_newton_meters : float
        Steady-state torque minus T* (t -> infinity), N m.
    steady_torque_error_percent : float
        The same relative to T*, %.
    """

    cost_volt2_seconds: float
    excess_cost_percent: float
    steady_torque_error_newton_meters: float
    steady_torque_error_percent: float


@dataclass(frozen=True)
class MismatchCase:
    """One true motor (R_s, L_s, phi_pm each 30% above or below nominal) and the controllers.

    Attributes
    ----------
    R_s_factor, L_s_factor, phi_pm_factor : float
        True value over nominal (0.7 or 1.3), dimensionless.
    R_s_ohm, L_s_henry, phi_pm_weber : float
        The true values, ohm, H, Wb.
    lqr_nominal, lqr_true_flux, pi_nominal, pi_true_flux : ControllerOutcome
        The nominal designs (see :class:`SelfTuningValue`).
    self_tuned, self_tuned_unknown_flux, optimum : ControllerOutcome
        The self-tuned controllers and the true optimum.
    self_tuned_data_seconds : float
        Motor data the off-policy self-tuning used, s.
    self_tuned_K_relative_error, self_tuned_U_relative_error : float
        Its ``||K - K*||/||K*||`` and ``||U - U*||/||U*||`` against the true optimum.
    unknown_flux_data_seconds : float
        Motor data Algorithm 3 used, s.
    unknown_flux_phi_pm_relative_error : float
        ``|identified phi_pm / true phi_pm - 1|``.
    """

    R_s_factor: float
    L_s_factor: float
    phi_pm_factor: float
    R_s_ohm: float
    L_s_henry: float
    phi_pm_weber: float
    lqr_nominal: ControllerOutcome
    lqr_true_flux: ControllerOutcome
    pi_nominal: ControllerOutcome
    pi_true_flux: ControllerOutcome
    self_tuned: ControllerOutcome
    self_tuned_unknown_flux: ControllerOutcome
    optimum: ControllerOutcome
    self_tuned_data_seconds: float
    self_tuned_K_relative_error: float
    self_tuned_U_relative_error: float
    unknown_flux_data_seconds: float
    unknown_flux_phi_pm_relative_error: float


@dataclass(frozen=True)
class SelfTuningValue:
    """Torque-step cost and torque error on mismatched motors, four kinds of controller.

    The engineer knows the nominal (paper's) motor; the true motor has each of R_s, L_s,
    phi_pm 30% above or below (8 cases). Controllers, all acting in continuous time:
    (a) ``lqr_nominal``: the optimal ``u = -K (x - X w) + U w`` of the nominal model, with
    the nominal flux in ``w`` and ``X``; (a') ``lqr_true_flux``: the same design with the
    true flux (measured) and the nominal R_s, L_s; (b) ``pi_nominal``: a PI current
    controller on each axis, ``u = k_p (i* - i) + k_i int (i* - i)``, ``k_p = alpha_c L_s``,
    ``k_i = alpha_c R_s`` (nominal values; no decoupling), ``i*`` from the nominal flux;
    (b') ``pi_true_flux``: the same PI with ``i*`` from the true flux; (c) ``self_tuned``: the
    off-policy self-tuning run on the true motor from ``K0`` = the nominal LQR gain, with
    the flux known (measured, the premise of the paper's known-flux algorithms);
    (c') ``self_tuned_unknown_flux``: Algorithm 3 (flux identified at no load, on-policy)
    from the same ``K0``; (d) ``optimum``: the model-based optimum of the true motor.

    Attributes
    ----------
    horizon_seconds : float
        Horizon of the cost, s.
    speed_rad_per_second : float
        Held mechanical speed, rad/s.
    torque_reference_newton_meters : float
        T*, N m (the step is 0 -> T* at t = 0).
    mismatch_relative : float
        Relative parameter error (0.3).
    Q_diagonal_volt2_per_ampere2 : float
        ``Q = q I``, V^2/A^2.
    R_diagonal_relative : float
        ``R = r I``, dimensionless.
    pi_bandwidth_rad_per_second : float
        alpha_c: the bandwidth of the nominal LQR loop, ``-max Re eig(A - B K*)``.
    cases : tuple of MismatchCase
    wall_seconds : float
        Time this comparison took, s.
    """

    horizon_seconds: float
    speed_rad_per_second: float
    torque_reference_newton_meters: float
    mismatch_relative: float
    Q_diagonal_volt2_per_ampere2: float
    R_diagonal_relative: float
    pi_bandwidth_rad_per_second: float
    cases: tuple[MismatchCase, ...]
    wall_seconds: float

    def worst_excess_cost_percent(self, controller: str) -> float:
        """Largest excess cost of ``controller`` over the cases, %."""
        return max(getattr(case, controller).excess_cost_percent for case in self.cases)

    def worst_torque_error_percent(self, controller: str) -> float:
        """Largest ``|steady-state torque error|`` of ``controller`` over the cases, %."""
        return max(
            abs(getattr(case, controller).steady_torque_error_percent) for case in self.cases
        )


def _quadratic_cost(M: Array, W: Array, z0: Array, horizon: float) -> float:
    """``int_0^horizon z' W z dt`` along ``z' = M z``, ``z(0) = z0``, exactly.

    Van Loan's block exponential gives the integral over a piece short enough for the
    exponential of ``-M'`` to stay well conditioned; the pieces are chained by
    ``G(t + d) = G(d) + Phi(d)' G(t) Phi(d)`` with ``Phi(d) = expm(M d)``.
    """
    size = M.shape[0]
    radius = float(np.max(np.abs(np.linalg.eigvals(M))))
    pieces = max(1, math.ceil(horizon * radius))
    piece = horizon / pieces
    block = np.zeros((2 * size, 2 * size))
    block[:size, :size] = -M.T
    block[:size, size:] = W
    block[size:, size:] = M
    exp = scipy.linalg.expm(block * piece)
    Phi = exp[size:, size:]
    G_piece = Phi.T @ exp[:size, size:]
    G = np.zeros((size, size))
    for _ in range(pieces):
        G = G_piece + Phi.T @ G @ Phi
    G = 0.5 * (G + G.T)
    return float(z0 @ G @ z0)


@dataclass(frozen=True)
class _TrueMotor:
    """The true motor's model and optimum at the operating point (for evaluation only)."""

    motor: SPMSM
    A: Array
    B: Array
    D: Array
    w: Array
    x_e: Array
    u_e: Array
    optimum: ModelBasedSolution

    @classmethod
    def of(cls, motor: SPMSM, settings: TuningSettings) -> _TrueMotor:
        problem = motor.regulation_problem(settings.speed)
        optimum = _optimum(motor, settings)
        x_e, u_e = motor.equilibrium(settings.speed, settings.torque)
        return cls(
            motor=motor,
            A=np.asarray(problem.A),
            B=np.asarray(problem.B),
            D=np.asarray(problem.D),
            w=motor.exogenous(settings.speed, settings.torque),
            x_e=x_e,
            u_e=u_e,
            optimum=optimum,
        )


def _outcome(
    cost: float, steady_current_q: float, true: _TrueMotor, torque: float, optimum_cost: float
) -> ControllerOutcome:
    steady_torque = float(true.motor.torque(steady_current_q))
    return ControllerOutcome(
        cost_volt2_seconds=cost,
        excess_cost_percent=100.0 * (cost / optimum_cost - 1.0),
        steady_torque_error_newton_meters=steady_torque - torque,
        steady_torque_error_percent=100.0 * (steady_torque / torque - 1.0),
    )


def _state_feedback_step(
    true: _TrueMotor, K: Array, L_w: Array, settings: TuningSettings, horizon: float
) -> tuple[float, float]:
    """Cost and steady-state i_q of ``u = -K x + L_w`` (``L_w`` the controller's ``L w``).

    The state ``z = [i_d, i_q, 1]`` with ``z' = M z``; ``e = x - x_e``, ``v = u - u_e``.
    """
    A_cl = true.A - true.B @ K
    forcing = true.B @ L_w + true.D @ true.w
    M = np.zeros((3, 3))
    M[:2, :2] = A_cl
    M[:2, 2] = forcing
    S_e = np.hstack([np.eye(2), -true.x_e[:, None]])
    S_v = np.hstack([-K, (L_w - true.u_e)[:, None]])
    W = S_e.T @ settings.Q @ S_e + S_v.T @ settings.R @ S_v
    z0 = np.array([0.0, 0.0, 1.0])
    steady = np.linalg.solve(A_cl, -forcing)
    return _quadratic_cost(M, W, z0, horizon), float(steady[1])


def _pi_step(
    true: _TrueMotor,
    k_p: float,
    k_i: float,
    current_reference: Array,
    settings: TuningSettings,
    horizon: float,
) -> tuple[float, float]:
    """Cost and steady-state i_q of the PI loop ``u = k_p (i* - i) + k_i xi``, ``xi' = i* - i``.

    State ``z = [i_d, i_q, xi_d, xi_q, 1]``. Before the step the loop rests at zero
    torque: ``i = 0`` and the integrators hold the voltage the motor needs there,
    ``xi(0) = u_e(T* = 0) / k_i``.
    """
    eye = np.eye(2)
    M = np.zeros((5, 5))
    M[:2, :2] = true.A - k_p * true.B
    M[:2, 2:4] = k_i * true.B
    M[:2, 4] = k_p * true.B @ current_reference + true.D @ true.w
    M[2:4, :2] = -eye
    M[2:4, 4] = current_reference
    S_e = np.hstack([eye, np.zeros((2, 2)), -true.x_e[:, None]])
    S_v = np.hstack([-k_p * eye, k_i * eye, (k_p * current_reference - true.u_e)[:, None]])
    W = S_e.T @ settings.Q @ S_e + S_v.T @ settings.R @ S_v
    _, u_rest = true.motor.equilibrium(settings.speed, 0.0)
    z0 = np.concatenate([np.zeros(2), u_rest / k_i, [1.0]])
    # At steady state the integrators force i = i* exactly.
    return _quadratic_cost(M, W, z0, horizon), float(current_reference[1])


def measure_self_tuning_value(config: BenchConfig, progress: bool = False) -> SelfTuningValue:
    """Cost (5) of a torque step and steady-state torque error on 8 mismatched motors.

    The step: at ``t = 0`` the currents are zero (the zero-torque operating point of any
    motor; the PI's integrators hold the zero-torque voltage) and the reference steps from
    0 to T*. The cost is ``int_0^H (e' Q e + v' R v) dt`` with ``e = x - x_e``,
    ``v = u - u_e``, ``(x_e, u_e)`` the TRUE motor's operating point for T*, and
    ``H = COST_HORIZON_SECONDS``; evaluated exactly (augmented LTI, matrix exponential).

    Parameters
    ----------
    config : BenchConfig
        Unused sizes (every case always runs); kept for a uniform signature.
    progress : bool
        Show a progress bar on stderr (only when it is a terminal).

    Returns
    -------
    SelfTuningValue
    """
    del config
    bars = _Progress(progress)
    started = time.perf_counter()
    nominal = SPMSM.paper()
    settings = TuningSettings.paper()
    horizon = COST_HORIZON_SECONDS
    design = _TrueMotor.of(nominal, settings)
    K_nominal = np.asarray(design.optimum.K)
    L_w_nominal = np.asarray(design.optimum.L) @ design.w
    alpha = -float(np.max(np.linalg.eigvals(design.A - design.B @ K_nominal).real))
    k_p, k_i = alpha * nominal.L_s, alpha * nominal.R_s
    current_reference = nominal.current_reference(settings.torque)
    # K0 of the self-tuning: the nominal design
    tuning = dataclasses.replace(settings, K0=K_nominal)
    cases = []
    signs = list(itertools.product((-1.0, 1.0), repeat=3))
    with bars.bar(len(signs), "self-tuning value") as step:
        for sign_R, sign_L, sign_phi in signs:
            factors = (1 + MISMATCH * sign_R, 1 + MISMATCH * sign_L, 1 + MISMATCH * sign_phi)
            motor = SPMSM(
                R_s=nominal.R_s * factors[0],
                L_s=nominal.L_s * factors[1],
                phi_pm=nominal.phi_pm * factors[2],
                p=nominal.p,
            )
            true = _TrueMotor.of(motor, settings)
            measured_flux = _TrueMotor.of(
                dataclasses.replace(nominal, phi_pm=motor.phi_pm), settings
            )
            tuned = run_algorithm("offpolicy", motor, tuning)
            identified = run_algorithm("3", motor, tuning)
            steps = {
                "lqr_nominal": _state_feedback_step(
                    true, K_nominal, L_w_nominal, settings, horizon
                ),
                "lqr_true_flux": _state_feedback_step(
                    true,
                    np.asarray(measured_flux.optimum.K),
                    np.asarray(measured_flux.optimum.L) @ measured_flux.w,
                    settings,
                    horizon,
                ),
                "pi_nominal": _pi_step(true, k_p, k_i, current_reference, settings, horizon),
                "pi_true_flux": _pi_step(
                    true, k_p, k_i, motor.current_reference(settings.torque), settings, horizon
                ),
                "self_tuned": _state_feedback_step(
                    true, tuned.K, (tuned.U + tuned.K @ tuned.X) @ tuned.w, settings, horizon
                ),
                "self_tuned_unknown_flux": _state_feedback_step(
                    true,
                    identified.K,
                    (identified.U + identified.K @ identified.X) @ identified.w,
                    settings,
                    horizon,
                ),
                "optimum": _state_feedback_step(
                    true,
                    np.asarray(true.optimum.K),
                    np.asarray(true.optimum.L) @ true.w,
                    settings,
                    horizon,
                ),
            }
            optimum_cost = steps["optimum"][0]
            outcomes = {
                name: _outcome(cost, i_q, true, settings.torque, optimum_cost)
                for name, (cost, i_q) in steps.items()
            }
            cases.append(
                MismatchCase(
                    R_s_factor=factors[0],
                    L_s_factor=factors[1],
                    phi_pm_factor=factors[2],
                    R_s_ohm=motor.R_s,
                    L_s_henry=motor.L_s,
                    phi_pm_weber=motor.phi_pm,
                    lqr_nominal=outcomes["lqr_nominal"],
                    lqr_true_flux=outcomes["lqr_true_flux"],
                    pi_nominal=outcomes["pi_nominal"],
                    pi_true_flux=outcomes["pi_true_flux"],
                    self_tuned=outcomes["self_tuned"],
                    self_tuned_unknown_flux=outcomes["self_tuned_unknown_flux"],
                    optimum=outcomes["optimum"],
                    self_tuned_data_seconds=tuned.data_seconds,
                    self_tuned_K_relative_error=_relative(tuned.K, true.optimum.K),
                    self_tuned_U_relative_error=_relative(tuned.U, true.optimum.U),
                    unknown_flux_data_seconds=identified.data_seconds,
                    unknown_flux_phi_pm_relative_error=abs(
                        identified.identified["phi_pm"] / motor.phi_pm - 1.0
                    ),
                )
            )
            step()
    return SelfTuningValue(
        horizon_seconds=horizon,
        speed_rad_per_second=settings.speed,
        torque_reference_newton_meters=settings.torque,
        mismatch_relative=MISMATCH,
        Q_diagonal_volt2_per_ampere2=float(settings.Q[0, 0]),
        R_diagonal_relative=float(settings.R[0, 0]),
        pi_bandwidth_rad_per_second=alpha,
        cases=tuple(cases),
        wall_seconds=time.perf_counter() - started,
    )


# -- the report --------------------------------------------------------------------------


@dataclass(frozen=True)
class Environment:
    """Where the bench ran.

    Attributes
    ----------
    python_version, numpy_version, scipy_version, selftune_version : str
    gym_electric_motor_version : str or None
        None when not installed.
    platform_text : str
        Operating system and machine.
    machine_cores_count : int
        Logical cores (``os.cpu_count()``).
    load_average_processes : float or None
        1-minute load average when the bench ended (other work on the machine slows the
        timings), processes; None where the system has none.
    """

    python_version: str
    numpy_version: str
    scipy_version: str
    selftune_version: str
    gym_electric_motor_version: str | None
    platform_text: str
    machine_cores_count: int
    load_average_processes: float | None

    @classmethod
    def here(cls) -> Environment:
        """This machine and these packages."""
        return cls(
            python_version=platform.python_version(),
            numpy_version=np.__version__,
            scipy_version=scipy.__version__,
            selftune_version=__version__,
            gym_electric_motor_version=_gem_version(),
            platform_text=platform.platform(),
            machine_cores_count=os.cpu_count() or 1,
            load_average_processes=os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        )


@dataclass(frozen=True)
class TargetOutcome:
    """One target of issue 5, met or missed.

    Attributes
    ----------
    name_text : str
    target_text : str
        The target, in words.
    value_text : str
        What was measured.
    met : bool or None
        None when it could not be measured (``why_text`` says why).
    why_text : str
    """

    name_text: str
    target_text: str
    value_text: str
    met: bool | None
    why_text: str


@dataclass(frozen=True)
class BenchReport:
    """Everything ``selftune bench`` measured; renders ``bench.json`` and ``bench.md``.

    Attributes
    ----------
    quick : bool
        True for the CI-sized run (``--quick``).
    wall_seconds : float
        Time the whole bench took, s.
    environment : Environment
    data_efficiency : DataEfficiency
    learning_cost : LearningCost
    simulation : Simulation
    self_tuning_value : SelfTuningValue
    """

    quick: bool
    wall_seconds: float
    environment: Environment
    data_efficiency: DataEfficiency
    learning_cost: LearningCost
    simulation: Simulation
    self_tuning_value: SelfTuningValue

    def targets(self) -> list[TargetOutcome]:
        """The targets of issue 5, each met or missed, with why."""
        data = self.data_efficiency
        ratio = data.data_ratio_vs_paper
        simulation = self.simulation
        speedup = simulation.speedup_vs_gem
        gem = simulation.gym_electric_motor
        errors = {
            "simulate": simulation.selftune_simulate.max_relative_error,
            "batch": simulation.batch.max_relative_error,
        }
        worst_error = max(errors.values())
        value = self.self_tuning_value
        tuned_excess = value.worst_excess_cost_percent("self_tuned")
        nominal_excess = {
            name: value.worst_excess_cost_percent(name)
            for name in ("lqr_nominal", "lqr_true_flux", "pi_nominal", "pi_true_flux")
        }
        return [
            TargetOutcome(
                name_text="data_ratio_vs_paper",
                target_text=f">= {TARGET_DATA_RATIO:g}x less data than the paper's Algorithm 2",
                value_text="not reached" if ratio is None else f"{ratio:.1f}x",
                met=None if ratio is None else ratio >= TARGET_DATA_RATIO,
                why_text=(
                    "on-policy spends a new 5 ms episode on every iteration (feedback episodes "
                    "until Theta_1 settles, then feedforward episodes); off-policy reuses one "
                    "short batch for every iteration"
                    if ratio is not None
                    else "a method did not reach the target error in the sweep"
                ),
            ),
            TargetOutcome(
                name_text="speedup_vs_gem",
                target_text=f">= {TARGET_SPEEDUP:g}x faster per step than gym-electric-motor",
                value_text="not measured" if speedup is None else f"{speedup:.0f}x",
                met=None if speedup is None else speedup >= TARGET_SPEEDUP,
                why_text=(
                    gem.reason_text or ""
                    if speedup is None
                    else "one vectorized call for the whole closed loop against a Python "
                    "env.step and an ODE solve per sample; an interactive Python loop on "
                    f"discretize is {simulation.step_loop_speedup_vs_gem or 0:.0f}x"
                ),
            ),
            TargetOutcome(
                name_text="exact simulation",
                target_text=f"max relative error <= {EXACT_RELATIVE_ERROR:g} against the exact "
                "solution",
                value_text=f"{worst_error:.1e}",
                met=worst_error <= EXACT_RELATIVE_ERROR,
                why_text="zero-order hold by the matrix exponential: only rounding remains",
            ),
            TargetOutcome(
                name_text="self-tuning value",
                target_text="(a check of this bench, not in issue 5) self-tuned cost within "
                "0.01% of the optimum on every motor, every nominal design worse",
                value_text=f"worst excess cost: self-tuned {tuned_excess:.2g}%; "
                + ", ".join(
                    f"{_CONTROLLER_TITLES[name].split()[0]} {excess:.3g}%"
                    for name, excess in nominal_excess.items()
                ),
                met=tuned_excess <= 0.01 and min(nominal_excess.values()) > tuned_excess,
                why_text="the off-policy run learns the true motor's K* and U* from 5 ms of "
                "data; most of what the nominal designs lose is the flux error (compare (a), "
                "(b) with (a'), (b'))",
            ),
        ]

    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``bench.json``: field names as keys, units in the names.

        Non-finite numbers become None (JSON has no infinity).
        """
        data = dataclasses.asdict(self)
        data["targets"] = [dataclasses.asdict(target) for target in self.targets()]
        # A measurement not made (gym-electric-motor not installed) is left out, not a
        # null number: "available" and "reason_text" say why.
        gem = data["simulation"]["gym_electric_motor"]
        for key in ("default_solver", "euler_solver"):
            if gem[key] is None:
                del gem[key]
        return finite_or_null(to_jsonable(data))

    def to_markdown(self) -> str:
        """The tables of ``bench.md``."""
        return _markdown(self)


def run_bench(quick: bool, progress: bool = True) -> BenchReport:
    """Run every comparison of issue 5 on this machine.

    Parameters
    ----------
    quick : bool
        The CI-sized run (:meth:`BenchConfig.quick`, well under a minute) instead of the
        full one (:meth:`BenchConfig.full`, a few minutes on 2 cores).
    progress : bool
        Show progress bars on stderr (only when it is a terminal).

    Returns
    -------
    BenchReport
    """
    config = BenchConfig.quick() if quick else BenchConfig.full()
    started = time.perf_counter()
    data_efficiency = measure_data_efficiency(config, progress)
    learning_cost = measure_learning_cost(config, progress)
    simulation = measure_simulation(config, progress)
    self_tuning_value = measure_self_tuning_value(config, progress)
    return BenchReport(
        quick=quick,
        wall_seconds=time.perf_counter() - started,
        environment=Environment.here(),
        data_efficiency=data_efficiency,
        learning_cost=learning_cost,
        simulation=simulation,
        self_tuning_value=self_tuning_value,
    )


# -- markdown ----------------------------------------------------------------------------


def _table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(row) + " |" for row in rows)
    return lines


def _sci(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.1e}"


def _ms(seconds: float | None) -> str:
    return "not reached" if seconds is None else f"{seconds * 1e3:.2f}"


def _markdown_data(data: DataEfficiency) -> list[str]:
    lines = [
        "## 1. Data efficiency (the paper's case)",
        "",
        f"Seconds of motor data until ||K - K*||/||K*|| <= {data.target_relative_error:g} "
        f"and ||U - U*||/||U*|| <= {data.target_relative_error:g}, median over "
        f"{len(data.seeds)} seeds; sampling {data.sampling_seconds * 1e6:g} us. On-policy: "
        f"the paper's Algorithm 2, episodes of {data.onpolicy_episode_seconds * 1e3:g} ms. "
        "Off-policy: one batch under K0 with exploration and the perturbed reference, "
        f"{data.offpolicy_interval_samples} sample per regression interval; the shortest "
        "swept batch that meets both targets (median of the larger error) and so does every "
        "longer one.",
        "",
    ]
    per_seed = ", ".join(_ms(value) for value in data.onpolicy_seconds_per_seed)
    ratio = data.data_ratio_vs_paper
    lines += _table(
        ["method", "data (ms)", "samples", "intervals", "per seed (ms)"],
        [
            [
                "on-policy (paper, Algorithm 2)",
                _ms(data.onpolicy_seconds),
                "n/a"
                if data.onpolicy_seconds is None
                else f"{round(data.onpolicy_seconds / data.sampling_seconds)}",
                f"{data.onpolicy_intervals_per_episode} per episode",
                per_seed,
            ],
            [
                "off-policy (one batch)",
                _ms(data.offpolicy_seconds),
                str(data.offpolicy_samples),
                f"{data.offpolicy_intervals} (floor {data.identifiability_floor_intervals})",
                "",
            ],
        ],
    )
    lines += [
        "",
        f"data_ratio_vs_paper = **{'n/a' if ratio is None else f'{ratio:.1f}'}x** "
        f"(target >= {data.data_ratio_target:g}x); the shortest off-policy batch has "
        + (
            "n/a"
            if data.offpolicy_intervals_vs_floor_ratio is None
            else f"{data.offpolicy_intervals_vs_floor_ratio:.2f}"
        )
        + f" times the {data.identifiability_floor_intervals} intervals of the "
        "identifiability floor.",
        "",
        "Error against data (medians over seeds):",
        "",
    ]
    on = data.onpolicy_curve
    lines += _table(
        ["on-policy data (ms)", "K rel. error", "U rel. error"],
        [
            [f"{s * 1e3:.0f}", _sci(k), _sci(u)]
            for s, k, u in zip(
                on.data_seconds, on.K_relative_error, on.U_relative_error, strict=True
            )
        ],
    )
    lines.append("")
    off = data.offpolicy_curve
    shown = {11, 12, 13, 15, 20, 25, 30, 35, 40, 50, 60, 80, 100, 200, 500}
    rows = []
    for s, k, u, failed in zip(
        off.data_seconds, off.K_relative_error, off.U_relative_error, off.failed_runs_count,
        strict=True,
    ):  # fmt: skip
        samples = round(s / data.sampling_seconds)
        if samples in shown or samples == data.offpolicy_samples:
            rows.append([f"{s * 1e3:.2f}", str(samples), _sci(k), _sci(u), str(failed)])
    lines += _table(
        ["off-policy data (ms)", "samples", "K rel. error", "U rel. error", "failed runs"], rows
    )
    return lines


def _markdown_learning(cost: LearningCost) -> list[str]:
    lines = [
        "## 2. Cost of learning: customized (paper) vs general (Gao & Jiang 2016)",
        "",
        "Same off-policy batch for both (paper's motor, K0 = 20 pi I, 1 V exploration, "
        "perturbed reference); wall time of a whole learning run (moments, policy iteration, "
        "feedforward), median of repeats; errors against the model-based optimum; "
        "condition = of the last regression, columns scaled. Both learners integrate the data "
        "to second order in the sampling period h; the general one's regression on x (not "
        "x - X* w) is worse conditioned, so the same O(h^2) quadrature error costs it more "
        "accuracy (compare the rows at 10 us and 1 us sampling).",
        "",
    ]
    rows = []
    for dataset in cost.datasets:
        for name, run in (("customized", dataset.customized), ("general", dataset.general)):
            rows.append(
                [
                    f"{dataset.data_seconds * 1e3:g} ms at {dataset.sampling_seconds * 1e6:g} us"
                    f" / {dataset.interval_samples}",
                    name,
                    str(run.unknowns_count),
                    str(run.rows_count),
                    str(run.least_squares_solves_count),
                    f"{run.wall_seconds * 1e3:.2f}",
                    _sci(run.regression_condition_ratio),
                    _sci(run.theta_relative_error),
                    _sci(run.K_relative_error),
                    _sci(run.U_relative_error),
                ]
            )
    lines += _table(
        [
            "data / interval (samples)",
            "method",
            "unknowns",
            "rows",
            "LS solves",
            "wall (ms)",
            "condition",
            "Theta rel. error",
            "K rel. error",
            "U rel. error",
        ],
        rows,
    )
    return lines


def _markdown_simulation(simulation: Simulation) -> list[str]:
    gem = simulation.gym_electric_motor
    lines = [
        "## 3. Simulation speed and exactness (SPMSM current loop, 10 us sampling)",
        "",
        "Closed loop of the paper's motor under the optimal controller plus 1 V uniform "
        "exploration, from rest, T* = 10 N m; error = max |x - x_exact| / max |x_exact| "
        "against the exact sampled solution (closed form, independent of expm).",
        "",
    ]
    entries: list[tuple[str, SimulatorMeasurement | None, str]] = [
        ("selftune simulate (whole loop, one call)", simulation.selftune_simulate, ""),
        ("selftune discretize + Python step loop", simulation.selftune_step_loop, ""),
        ("scipy solve_ivp RK45, default tol.", simulation.solve_ivp_rk45, ""),
        ("scipy solve_ivp RK45, rtol 1e-10", simulation.solve_ivp_rk45_tight, ""),
        (
            "gym-electric-motor"
            + (f" {gem.version_text}" if gem.version_text else "")
            + " (default: dopri5)",
            gem.default_solver,
            gem.reason_text or "",
        ),
        ("gym-electric-motor (Euler)", gem.euler_solver, gem.reason_text or ""),
    ]
    rows = []
    for name, measured, reason in entries:
        if measured is None:
            rows.append([name, reason or "n/a", "", "", ""])
        else:
            rows.append(
                [
                    name,
                    f"{measured.us_per_step:.3g}",
                    str(measured.timed_samples),
                    _sci(measured.max_relative_error),
                    str(measured.compared_samples),
                ]
            )
    lines += _table(
        ["simulator", "us/step", "timed steps", "max rel. error", "compared steps"], rows
    )
    batch = simulation.batch
    speedup = simulation.speedup_vs_gem
    lines += [
        "",
        f"Batch: {batch.motors_count} motors (R_s, L_s, phi_pm within +-30%) x "
        f"{batch.samples_per_motor} steps in {batch.wall_seconds:.3f} s = "
        f"**{batch.steps_per_second / 1e6:.2f} M steps/s** (discretization of every motor "
        f"included; {batch.warm_steps_per_second / 1e6:.2f} M steps/s again on the same "
        f"motors, discretization cached), max rel. error {_sci(batch.max_relative_error)}.",
        "",
        "speedup_vs_gem = "
        + ("not measured" if speedup is None else f"**{speedup:.0f}x**")
        + f" (target >= {simulation.speedup_target:g}x); against its Euler solver "
        + (
            "n/a"
            if simulation.speedup_vs_gem_euler is None
            else f"{simulation.speedup_vs_gem_euler:.0f}x"
        )
        + "; interactive step loop vs gym-electric-motor "
        + (
            "n/a"
            if simulation.step_loop_speedup_vs_gem is None
            else f"{simulation.step_loop_speedup_vs_gem:.0f}x"
        )
        + ".",
    ]
    return lines


def _markdown_value(value: SelfTuningValue) -> list[str]:
    lines = [
        "## 4. The value of self-tuning (R_s, L_s, phi_pm each 30% off nominal)",
        "",
        f"Torque step 0 -> {value.torque_reference_newton_meters:g} N m at "
        f"{value.speed_rad_per_second:g} rad/s. At t = 0 the currents are zero (the PI's "
        "integrators hold the zero-torque voltage). Cost (5) = int_0^H (e'Qe + v'Rv) dt with "
        f"H = {value.horizon_seconds * 1e3:g} ms, e = x - x_e, v = u - u_e, (x_e, u_e) the "
        f"TRUE motor's operating point, Q = {value.Q_diagonal_volt2_per_ampere2:g} I, "
        f"R = {value.R_diagonal_relative:g} I; in V^2 s, computed exactly (augmented LTI, "
        "matrix exponential), controllers in continuous time. Steady-state torque error at "
        "t -> infinity. Controllers: (a) LQR + feedforward of the nominal model (nominal "
        "R_s, L_s, phi_pm); (a') the same design with the true flux (measured at no load) "
        "and the nominal R_s, L_s; (b) PI per axis, k_p = alpha_c L_s, k_i = alpha_c R_s "
        f"(nominal), alpha_c = {value.pi_bandwidth_rad_per_second:.1f} rad/s = the nominal LQR "
        "loop's bandwidth -max Re eig(A - B K*), no decoupling, i* from the nominal flux; "
        "(b') the same PI with i* from the true flux; (c) off-policy self-tuning on the true "
        "motor (one 5 ms batch, flux known as in (a')) from K0 = the nominal LQR gain; "
        "(c') Algorithm 3 from the same K0, flux identified at no load (on-policy); (d) the "
        "true optimum.",
        "",
    ]
    header = ["R_s, L_s, phi_pm", *(_CONTROLLER_TITLES[name] for name in CONTROLLERS)]
    cost_rows = []
    torque_rows = []
    for case in value.cases:
        label = ", ".join(
            f"{factor - 1:+.0%}"
            for factor in (case.R_s_factor, case.L_s_factor, case.phi_pm_factor)
        )
        outcomes = [getattr(case, name) for name in CONTROLLERS]
        cost_rows.append(
            [label]
            + [
                f"{o.cost_volt2_seconds:.4g} ({o.excess_cost_percent:+.3g}%)"
                if name != "optimum"
                else f"{o.cost_volt2_seconds:.4g}"
                for name, o in zip(CONTROLLERS, outcomes, strict=True)
            ]
        )
        torque_rows.append(
            [label]
            + [
                f"{o.steady_torque_error_newton_meters:+.3g} "
                f"({o.steady_torque_error_percent:+.3g}%)"
                for o in outcomes
            ]
        )
    lines += ["Cost (V^2 s), and excess over the true optimum:", ""]
    lines += _table(header, cost_rows)
    lines += ["", "Steady-state torque error, N m (% of T*):", ""]
    lines += _table(header, torque_rows)
    lines += [
        "",
        "Worst case over the 8 motors: "
        + "; ".join(
            f"{_CONTROLLER_TITLES[name]}: excess cost {value.worst_excess_cost_percent(name):.3g}%,"
            f" |torque error| {value.worst_torque_error_percent(name):.3g}%"
            for name in CONTROLLERS[:-1]
        )
        + ".",
    ]
    return lines


def _markdown(report: BenchReport) -> str:
    environment = report.environment
    lines = [
        "# selftune bench" + (" (quick)" if report.quick else ""),
        "",
        f"Python {environment.python_version}, numpy {environment.numpy_version}, scipy "
        f"{environment.scipy_version}, selftune {environment.selftune_version}, "
        "gym-electric-motor "
        + (environment.gym_electric_motor_version or "not installed")
        + f"; {environment.platform_text}, {environment.machine_cores_count} cores"
        + (
            ""
            if environment.load_average_processes is None
            else f", load average {environment.load_average_processes:.1f} at the end"
        )
        + ". "
        f"Whole bench: {report.wall_seconds:.1f} s. Regenerate: `selftune bench"
        + (" --quick" if report.quick else "")
        + "`.",
        "",
        "## Targets",
        "",
    ]
    lines += _table(
        ["target", "goal", "measured", "met", "why"],
        [
            [
                target.name_text,
                target.target_text,
                target.value_text,
                {True: "met", False: "MISSED", None: "not measured"}[target.met],
                target.why_text,
            ]
            for target in report.targets()
        ],
    )
    for section in (
        _markdown_data(report.data_efficiency),
        _markdown_learning(report.learning_cost),
        _markdown_simulation(report.simulation),
        _markdown_value(report.self_tuning_value),
    ):
        lines += ["", *section]
    return "\n".join(lines) + "\n"


# -- command line ------------------------------------------------------------------------


def add_bench_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the options of ``selftune bench``: ``--quick`` and ``--out DIR``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The ``bench`` subcommand's parser.
    """
    parser.add_argument(
        "--quick",
        action="store_true",
        help="CI-sized run: smaller sweeps and repeats (well under a minute)",
    )
    parser.add_argument(
        "--out",
        metavar="DIR",
        default=".",
        help="directory for bench.md and bench.json (default: the current directory)",
    )


def run_bench_command(args: argparse.Namespace) -> int:
    """Run the bench, print its tables, write ``bench.md`` and ``bench.json`` to ``args.out``.

    Parameters
    ----------
    args : argparse.Namespace
        With ``quick`` (bool) and ``out`` (directory, created if missing).

    Returns
    -------
    int
        0.

    Raises
    ------
    OSError
        If the directory or the files cannot be written (nothing partial is left).
    """
    report = run_bench(quick=bool(args.quick), progress=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    markdown = report.to_markdown()
    write_text(out / "bench.md", markdown)
    write_json(out / "bench.json", report.to_json())
    print(markdown, end="")
    print(f"\nwrote {out / 'bench.md'} and {out / 'bench.json'} ({report.wall_seconds:.1f} s)")
    return 0
