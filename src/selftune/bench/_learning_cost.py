"""Study 2: the customized learner against the general one of Gao & Jiang (2016), same data."""

from __future__ import annotations

import functools
import statistics
import time
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..core import (
    Array,
    ControlLaw,
)
from ..learn import LearnedController, LearningOptions, LearningProblem, learn_regulator
from ..model import SPMSM
from ..sim import SimulatedDrive, held, uniform
from ..tuning import TuningSettings, known_flux_form, reference_perturbation
from ._common import BenchConfig, paper_setting, progress_bar, relative, sci, table, timed


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
    drive = SimulatedDrive(motor=motor, speed=settings.speed, h=settings.h)

    def perturbed(t: Array) -> Array:
        return w + reference_perturbation(t, settings.perturbation)

    batch = drive.run(
        ControlLaw.regulator(settings.K0, X, np.zeros((2, 2))),
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
    started = time.perf_counter()
    motor, settings, optimum = paper_setting()
    datasets = []
    methods: tuple[Literal["customized", "general"], ...] = ("customized", "general")
    with progress_bar(len(config.learning_datasets) * 2, "learning cost", progress) as bar:
        for h, samples in config.learning_datasets:
            settings = TuningSettings.paper(h=h)
            batch, C, E, F = _offpolicy_batch(motor, settings, samples, seed=config.seeds[0])
            learners = {
                method: functools.partial(
                    learn_regulator,
                    batch,
                    LearningProblem(settings.Q, settings.R, C=C, E=E, F=F),
                    settings.K0,
                    LearningOptions(interval=settings.interval),
                    formulation=method,
                )
                for method in methods
            }
            # warm-up, and the results whose accuracy is reported
            results = {method: learn() for method, learn in learners.items()}
            # the methods alternate, so that both see the same load on the machine
            times: dict[str, list[float]] = {method: [] for method in methods}
            for _ in range(config.learning_repeats):
                for method, learn in learners.items():
                    times[method].append(timed(learn, 1))
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
                    theta_relative_error=relative(_theta(learned), optimum.theta),
                    K_relative_error=relative(learned.K, optimum.K),
                    U_relative_error=relative(learned.U, optimum.U),
                )
                bar.update(1)
            datasets.append(
                LearningDataset(
                    samples=samples,
                    sampling_seconds=h,
                    interval_samples=settings.interval,
                    data_seconds=samples * h,
                    customized=runs["customized"],
                    general=runs["general"],
                )
            )
    return LearningCost(datasets=tuple(datasets), wall_seconds=time.perf_counter() - started)


def markdown_learning(cost: LearningCost) -> list[str]:
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
                    sci(run.regression_condition_ratio),
                    sci(run.theta_relative_error),
                    sci(run.K_relative_error),
                    sci(run.U_relative_error),
                ]
            )
    lines += table(
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


def _theta(learned: LearnedController) -> Array:
    """Theta of a regulator learned by policy iteration (it always has one)."""
    assert learned.theta is not None
    return learned.theta
