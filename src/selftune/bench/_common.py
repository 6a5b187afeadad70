"""What every study of the bench shares: its sizes, targets, timing and table helpers."""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, TypeVar

import numpy as np

from ..core import (
    Array,
    theta_sizes,
)
from ..fleet import map_ordered
from ..fleet import progress_bar as progress_bar  # the bench's bars are the engine's
from ..model import SPMSM, ModelBasedSolution, solve_optimal_regulation
from ..tuning import TuningSettings

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
CONTROLLER_TITLES = {
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


Item = TypeVar("Item")
Result = TypeVar("Result")


def with_progress(
    items: Sequence[Item],
    function: Callable[[Item], Result],
    description: str,
    enabled: bool,
    client: Any = None,
) -> list[Result]:
    """``function(item)`` for every item, in order, each advancing a :func:`progress_bar`:
    the fleet's engine (:func:`~selftune.fleet.map_ordered`), here or on a cluster.

    Parameters
    ----------
    items : sequence
        The trials (seeds, cases, ...): each a self-contained, seeded job.
    function : callable
        One trial's run.
    description : str
        The bar's title.
    enabled : bool
        Show the bar (only when stderr is a terminal).
    client : distributed.Client, optional
        Run the trials on its cluster (default: here, one after another).
    """
    return map_ordered(function, items, client, (description, enabled))


def relative(value: Array, reference: Array) -> float:
    """``||value - reference|| / ||reference||`` (Frobenius), dimensionless."""
    return float(np.linalg.norm(value - reference)) / float(np.linalg.norm(reference))


def median(values: Sequence[float]) -> float:
    """Median; ``inf`` entries (failed runs) count as larger than any number."""
    return float(statistics.median(values))


def finite_or_none(value: float) -> float | None:
    return value if math.isfinite(value) else None


def timed(function: Callable[[], object], repeats: int) -> float:
    """Median wall time of ``function()`` over ``repeats`` calls, s (time.perf_counter)."""
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        function()
        times.append(time.perf_counter() - start)
    return float(statistics.median(times))


def model_optimum(motor: SPMSM, settings: TuningSettings) -> ModelBasedSolution:
    return solve_optimal_regulation(
        motor.regulation_problem(settings.speed), settings.Q, settings.R
    )


def paper_setting() -> tuple[SPMSM, TuningSettings, ModelBasedSolution]:
    """The paper's motor, its settings, and their model-based optimum."""
    motor = SPMSM.paper()
    settings = TuningSettings.paper()
    return motor, settings, model_optimum(motor, settings)


def table(header: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines.extend("| " + " | ".join(row) + " |" for row in rows)
    return lines


def sci(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.1e}"


def ms(seconds: float | None) -> str:
    return "not reached" if seconds is None else f"{seconds * 1e3:.2f}"
