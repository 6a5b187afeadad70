"""Study 1: seconds of motor data until K and U are learned to 1e-4, on-policy vs off-policy."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

from ..errors import ConvergenceError, ExcitationError
from ..model import SPMSM, ModelBasedSolution
from ..tuning import TuningSettings, run_algorithm
from ._common import (
    IDENTIFIABILITY_FLOOR_INTERVALS,
    TARGET_DATA_RATIO,
    TARGET_RELATIVE_ERROR,
    BenchConfig,
    finite_or_none,
    median,
    ms,
    paper_setting,
    progress_bar,
    relative,
    sci,
    table,
    with_progress,
)


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
        (item.data_seconds, relative(item.K, optimum.K), relative(item.U, optimum.U))
        for item in result.history
    ]


def _error_curve(
    points: Sequence[float], errors: Sequence[Sequence[tuple[float, float]]]
) -> ErrorCurve:
    """Medians over seeds; ``errors[i][s]`` is the (K, U) error at point i for seed s."""
    K_median = [median([k for k, _ in row]) for row in errors]
    U_median = [median([u for _, u in row]) for row in errors]
    return ErrorCurve(
        data_seconds=tuple(points),
        K_relative_error=tuple(finite_or_none(value) for value in K_median),
        U_relative_error=tuple(finite_or_none(value) for value in U_median),
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
    if not result.history:  # policy iteration failed, the model designed it: not ADP's
        return math.inf, math.inf
    return relative(result.K, optimum.K), relative(result.U, optimum.U)


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
    started = time.perf_counter()
    motor, settings, optimum = paper_setting()
    traces = with_progress(
        config.seeds,
        lambda seed: _onpolicy_trace(motor, dataclasses.replace(settings, seed=seed), optimum),
        "data efficiency: on-policy",
        progress,
    )
    first_met, onpolicy_seconds = _first_met(traces)
    grid, onpolicy_rows = _onpolicy_rows(traces, settings, optimum)
    offpolicy_rows = _offpolicy_rows(config, motor, settings, optimum, progress)
    shortest = _shortest_batch(config.offpolicy_samples, offpolicy_rows)
    offpolicy_seconds = math.inf if shortest is None else shortest * settings.h
    ratio = onpolicy_seconds / offpolicy_seconds
    return DataEfficiency(
        target_relative_error=TARGET_RELATIVE_ERROR,
        sampling_seconds=settings.h,
        seeds=config.seeds,
        onpolicy_episode_seconds=settings.episode_length,
        onpolicy_intervals_per_episode=-(-settings.samples_per_episode // settings.interval),
        onpolicy_seconds_per_seed=tuple(first_met),
        onpolicy_seconds=finite_or_none(onpolicy_seconds),
        onpolicy_curve=_error_curve(grid, onpolicy_rows),
        offpolicy_interval_samples=1,
        offpolicy_curve=_error_curve(
            [samples * settings.h for samples in config.offpolicy_samples],
            offpolicy_rows,
        ),
        offpolicy_samples=shortest,
        offpolicy_intervals=shortest,
        offpolicy_seconds=finite_or_none(offpolicy_seconds),
        identifiability_floor_intervals=IDENTIFIABILITY_FLOOR_INTERVALS,
        offpolicy_intervals_vs_floor_ratio=(
            None if shortest is None else shortest / IDENTIFIABILITY_FLOOR_INTERVALS
        ),
        data_ratio_vs_paper=finite_or_none(ratio) if math.isfinite(offpolicy_seconds) else None,
        data_ratio_target=TARGET_DATA_RATIO,
        wall_seconds=time.perf_counter() - started,
    )


def _first_met(traces: list[list[tuple[float, float, float]]]) -> tuple[list[float | None], float]:
    """Per seed, the data used when both errors first meet the target (None: never); and
    their median (inf if most never do)."""
    target = TARGET_RELATIVE_ERROR
    first_met: list[float | None] = []
    for trace in traces:
        met = [seconds for seconds, k, u in trace if k <= target and u <= target]
        first_met.append(met[0] if met else None)
    values = [math.inf if value is None else value for value in first_met]
    return first_met, median(values) if values else math.inf


def _onpolicy_rows(
    traces: list[list[tuple[float, float, float]]],
    settings: TuningSettings,
    optimum: ModelBasedSolution,
) -> tuple[list[float], list[list[tuple[float, float]]]]:
    """The on-policy curve: the (K, U) errors of the controller in force after each whole
    number of episodes, per seed."""
    episode = settings.episode_length
    longest = max(trace[-1][0] for trace in traces)
    grid = [episode * k for k in range(round(longest / episode) + 1)]
    start_errors = (relative(settings.K0, optimum.K), 1.0)  # U0 = 0
    rows = []
    for seconds in grid:
        row = []
        for trace in traces:
            used = [(k, u) for data, k, u in trace if data <= seconds * (1 + 1e-9)]
            row.append(used[-1] if used else start_errors)
        rows.append(row)
    return grid, rows


def _offpolicy_rows(
    config: BenchConfig,
    motor: SPMSM,
    settings: TuningSettings,
    optimum: ModelBasedSolution,
    progress: bool,
) -> list[list[tuple[float, float]]]:
    """The off-policy (K, U) errors for each batch length and seed."""
    rows = []
    with progress_bar(
        len(config.offpolicy_samples), "data efficiency: off-policy", progress
    ) as bar:
        for samples in config.offpolicy_samples:
            row = []
            for seed in config.seeds:
                batch_settings = dataclasses.replace(
                    settings,
                    episode_length=samples * settings.h,
                    interval=1,
                    seed=seed,
                )
                row.append(_offpolicy_errors(motor, batch_settings, optimum))
            rows.append(row)
            bar.update(1)
    return rows


def _shortest_batch(lengths: tuple[int, ...], rows: list[list[tuple[float, float]]]) -> int | None:
    """The shortest batch length from which every longer one meets the target (median)."""
    worst = [median([max(k, u) for k, u in row]) for row in rows]
    shortest: int | None = None
    for index in range(len(worst) - 1, -1, -1):
        if worst[index] > TARGET_RELATIVE_ERROR:
            break
        shortest = lengths[index]
    return shortest


def markdown_data(data: DataEfficiency) -> list[str]:
    """Section 1 of bench.md: the data each method needs, and its error curves."""
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
    per_seed = ", ".join(ms(value) for value in data.onpolicy_seconds_per_seed)
    ratio = data.data_ratio_vs_paper
    lines += table(
        ["method", "data (ms)", "samples", "intervals", "per seed (ms)"],
        [
            [
                "on-policy (paper, Algorithm 2)",
                ms(data.onpolicy_seconds),
                "n/a"
                if data.onpolicy_seconds is None
                else f"{round(data.onpolicy_seconds / data.sampling_seconds)}",
                f"{data.onpolicy_intervals_per_episode} per episode",
                per_seed,
            ],
            [
                "off-policy (one batch)",
                ms(data.offpolicy_seconds),
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
    ]
    return lines + _markdown_curves(data)


def _markdown_curves(data: DataEfficiency) -> list[str]:
    """The error-against-data tables of both methods."""
    lines = ["Error against data (medians over seeds):", ""]
    on = data.onpolicy_curve
    lines += table(
        ["on-policy data (ms)", "K rel. error", "U rel. error"],
        [
            [f"{s * 1e3:.0f}", sci(k), sci(u)]
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
            rows.append([f"{s * 1e3:.2f}", str(samples), sci(k), sci(u), str(failed)])
    lines += table(
        ["off-policy data (ms)", "samples", "K rel. error", "U rel. error", "failed runs"], rows
    )
    return lines
