"""The bench report: every study's result, its targets, and bench.md and bench.json."""

from __future__ import annotations

import dataclasses
import os
import platform
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy
import scipy.linalg

from .. import __version__
from ..core import (
    finite_or_null,
    to_jsonable,
    write_json,
    write_text,
)
from ..core._atomic import check_output_directory, output_directory
from ..fleet import fleet_client
from ._calibration import (
    Calibration,
    calibration_target,
    markdown_calibration,
    measure_calibration,
)
from ._common import (
    CONTROLLER_TITLES,
    EXACT_RELATIVE_ERROR,
    TARGET_DATA_RATIO,
    TARGET_SPEEDUP,
    BenchConfig,
    table,
)
from ._corpus import RefusalsConfig
from ._data_efficiency import DataEfficiency, markdown_data, measure_data_efficiency
from ._drive_rates import (
    RATE_FREQUENCIES,
    DriveRates,
    drive_rates_target,
    markdown_drive_rates,
    measure_drive_rates,
)
from ._fleet import FleetDesign, FleetStudy, fleet_targets, markdown_fleet, measure_fleet
from ._gem import gem_version
from ._honesty import Honesty, honesty_target, markdown_honesty, measure_honesty
from ._interior import InteriorStudy, interior_targets, markdown_interior, measure_interior
from ._learning_cost import LearningCost, markdown_learning, measure_learning_cost
from ._noise_report import markdown_noise, noise_targets
from ._noise_study import NoiseConfig, NoiseStudy, measure_noise
from ._online import OnlineStudy, markdown_online, measure_online, online_targets
from ._realistic_drive import (
    RealisticDriveComparison,
    markdown_realistic_drive,
    measure_realistic_drive,
)
from ._refusals import Refusals, markdown_refusals, measure_refusals, refusals_target
from ._simulation import Simulation, markdown_simulation, measure_simulation
from ._targets import TargetOutcome
from ._value import SelfTuningValue, markdown_value, measure_self_tuning_value


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
            gym_electric_motor_version=gem_version(),
            platform_text=platform.platform(),
            machine_cores_count=os.cpu_count() or 1,
            load_average_processes=os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        )


@dataclass(frozen=True)
class DriveStudiesConfig:
    """Sizes of studies 5-8 and 10 (drive rates, honesty, noise, calibration, refusals):
    :meth:`full` or :meth:`quick`.

    Attributes
    ----------
    rate_frequencies_hz : tuple of float
        Sampling frequencies of the drive-rates sweep, Hz.
    honesty_logs_per_hazard : int
        Logs of each of the honesty sweep's 11 hazards.
    honesty_short_logs : bool
        Honesty logs of 50-100 ms instead of 0.1-0.4 s.
    noise : NoiseConfig
        Rates, noise levels, lengths and seeds of the noise study.
    calibration_trials_count : int
        Seeded motors of the calibration study.
    refusals : RefusalsConfig
        Motors, plants, seeds and lengths of the refusals study's corpus.
    fleet : FleetDesign
        The fleet of study 12.
    """

    rate_frequencies_hz: tuple[float, ...]
    honesty_logs_per_hazard: int
    honesty_short_logs: bool
    noise: NoiseConfig
    calibration_trials_count: int
    refusals: RefusalsConfig
    fleet: FleetDesign

    @classmethod
    def full(cls) -> DriveStudiesConfig:
        """The published run: 5-50 kHz, 220 honesty logs, the issue's noise study, 60 motors,
        the refusals corpus of five motors on two plants, the fleet of 1,000 logs."""
        return cls(
            RATE_FREQUENCIES, 20, False, NoiseConfig.full(), 60, RefusalsConfig.full(),
            FleetDesign(),
        )  # fmt: skip

    @classmethod
    def quick(cls) -> DriveStudiesConfig:
        """CI-sized: 10 kHz, one short log per hazard, 2 seeds, 3 motors, 2 corpus logs, a
        fleet of 6 logs."""
        return cls(
            (1e4,), 1, True, NoiseConfig.quick(), 3, RefusalsConfig.quick(),
            FleetDesign(motors_count=1, units_count=6, hot_count=1, broken_count=1),
        )  # fmt: skip


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
    drive_rates : DriveRates
    honesty : Honesty
    noise : NoiseStudy
    calibration : Calibration
    realistic_drive : RealisticDriveComparison
    refusals : Refusals
    online : OnlineStudy
    interior : InteriorStudy
        Study 13: interior PM motors commissioned.
    fleet : FleetStudy
    """

    quick: bool
    wall_seconds: float
    environment: Environment
    data_efficiency: DataEfficiency
    learning_cost: LearningCost
    simulation: Simulation
    self_tuning_value: SelfTuningValue
    drive_rates: DriveRates
    honesty: Honesty
    noise: NoiseStudy
    calibration: Calibration
    realistic_drive: RealisticDriveComparison
    refusals: Refusals
    online: OnlineStudy
    interior: InteriorStudy
    fleet: FleetStudy

    def targets(self) -> list[TargetOutcome]:
        """The bench's targets, each met or missed, with why."""
        return [
            _data_target(self.data_efficiency),
            _speed_target(self.simulation),
            _exact_target(self.simulation),
            _value_target(self.self_tuning_value),
            drive_rates_target(self.drive_rates),
            honesty_target(self.honesty, self.quick),
            *noise_targets(self.noise),
            calibration_target(self.calibration, self.quick),
            *self.realistic_drive.targets(),
            refusals_target(self.refusals, self.quick),
            *online_targets(self.online, self.quick),
            *interior_targets(self.interior, self.quick),
            *fleet_targets(self.fleet),
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


def _ratio_target(
    name: str,
    ratio: float | None,
    target: float,
    what: str,
    missing: tuple[str, str],
    why: str,
) -> TargetOutcome:
    """A target ``ratio >= target`` (``what`` it is, e.g. "faster per step than ...");
    ``missing`` is the value's text when the ratio is None and the format when it is not."""
    absent, form = missing
    return TargetOutcome(
        name_text=name,
        target_text=f">= {target:g}x {what}",
        value_text=absent if ratio is None else f"{ratio:{form}}x",
        met=None if ratio is None else ratio >= target,
        why_text=why,
    )


def _data_target(data: DataEfficiency) -> TargetOutcome:
    ratio = data.data_ratio_vs_paper
    return _ratio_target(
        "data_ratio_vs_paper",
        ratio,
        TARGET_DATA_RATIO,
        "less data than the paper's Algorithm 2",
        ("not reached", ".1f"),
        "on-policy spends a new 5 ms episode on every iteration (feedback episodes "
        "until Theta_1 settles, then feedforward episodes); off-policy reuses one "
        "short batch for every iteration"
        if ratio is not None
        else "a method did not reach the target error in the sweep",
    )


def _speed_target(simulation: Simulation) -> TargetOutcome:
    speedup = simulation.speedup_vs_gem
    gem = simulation.gym_electric_motor
    return _ratio_target(
        "speedup_vs_gem",
        speedup,
        TARGET_SPEEDUP,
        "faster per step than gym-electric-motor",
        ("not measured", ".0f"),
        gem.reason_text or ""
        if speedup is None
        else "one vectorized call for the whole closed loop against a Python "
        "env.step and an ODE solve per sample; an interactive Python loop on "
        f"discretize is {simulation.step_loop_speedup_vs_gem or 0:.0f}x",
    )


def _exact_target(simulation: Simulation) -> TargetOutcome:
    worst_error = max(
        simulation.selftune_simulate.max_relative_error, simulation.batch.max_relative_error
    )
    return TargetOutcome(
        name_text="exact simulation",
        target_text=f"max relative error <= {EXACT_RELATIVE_ERROR:g} against the exact solution",
        value_text=f"{worst_error:.1e}",
        met=worst_error <= EXACT_RELATIVE_ERROR,
        why_text="zero-order hold by the matrix exponential: only rounding remains",
    )


def _value_target(value: SelfTuningValue) -> TargetOutcome:
    tuned_excess = value.worst_excess_cost_percent("self_tuned")
    nominal_excess = {
        name: value.worst_excess_cost_percent(name)
        for name in ("lqr_nominal", "lqr_true_flux", "pi_nominal", "pi_true_flux")
    }
    return TargetOutcome(
        name_text="self-tuning value",
        target_text="self-tuned cost within 0.01% of the optimum on every motor, every "
        "nominal design worse",
        value_text=f"worst excess cost: self-tuned {tuned_excess:.2g}%; "
        + ", ".join(
            f"{CONTROLLER_TITLES[name].split()[0]} {excess:.3g}%"
            for name, excess in nominal_excess.items()
        ),
        met=tuned_excess <= 0.01 and min(nominal_excess.values()) > tuned_excess,
        why_text="the off-policy run learns the true motor's K* and U* from 5 ms of "
        "data; most of what the nominal designs lose is the flux error (compare (a), "
        "(b) with (a'), (b'))",
    )


def run_bench(quick: bool, progress: bool = True, client: Any = None) -> BenchReport:
    """Run every comparison of the bench on this machine.

    Parameters
    ----------
    quick : bool
        The CI-sized run (:meth:`BenchConfig.quick` and :meth:`DriveStudiesConfig.quick`,
        under a minute) instead of the full one (:meth:`BenchConfig.full` and
        :meth:`DriveStudiesConfig.full`, about 7 minutes on 2 cores).
    progress : bool
        Show progress bars on stderr (only when it is a terminal).
    client : distributed.Client, optional
        Run the seeded studies (honesty, noise, calibration) on its cluster, through the
        fleet's engine (default: here; the same numbers).

    Returns
    -------
    BenchReport
    """
    config = BenchConfig.quick() if quick else BenchConfig.full()
    sizes = DriveStudiesConfig.quick() if quick else DriveStudiesConfig.full()
    started = time.perf_counter()
    data_efficiency = measure_data_efficiency(config, progress)
    learning_cost = measure_learning_cost(config, progress)
    simulation = measure_simulation(config, progress)
    self_tuning_value = measure_self_tuning_value(config, progress)
    drive_rates = measure_drive_rates(progress, sizes.rate_frequencies_hz)
    honesty = measure_honesty(
        sizes.honesty_logs_per_hazard, sizes.honesty_short_logs, progress, client
    )
    noise = measure_noise(sizes.noise, quick, progress, client)
    calibration = measure_calibration(sizes.calibration_trials_count, progress, client)
    realistic_drive = measure_realistic_drive(quick, progress)
    refusals = measure_refusals(sizes.refusals, progress)
    online = measure_online(quick, progress)
    fleet = measure_fleet(sizes.fleet, quick, progress)
    interior = measure_interior(quick, progress)
    return BenchReport(
        quick=quick,
        wall_seconds=time.perf_counter() - started,
        environment=Environment.here(),
        data_efficiency=data_efficiency,
        learning_cost=learning_cost,
        simulation=simulation,
        self_tuning_value=self_tuning_value,
        drive_rates=drive_rates,
        honesty=honesty,
        noise=noise,
        calibration=calibration,
        realistic_drive=realistic_drive,
        refusals=refusals,
        online=online,
        interior=interior,
        fleet=fleet,
    )


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
    lines += table(
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
        markdown_data(report.data_efficiency),
        markdown_learning(report.learning_cost),
        markdown_simulation(report.simulation),
        markdown_value(report.self_tuning_value),
        markdown_drive_rates(report.drive_rates),
        markdown_honesty(report.honesty),
        markdown_noise(report.noise),
        markdown_calibration(report.calibration),
        markdown_realistic_drive(report.realistic_drive),
        markdown_refusals(report.refusals),
        markdown_online(report.online),
        markdown_fleet(report.fleet),
        markdown_interior(report.interior),
    ):
        lines += ["", *section]
    return "\n".join(lines) + "\n"


#: The files of ``selftune bench``'s output set.
BENCH_OUTPUTS = ("bench.md", "bench.json")

_WHAT = "selftune bench output"


def bench_command(out: str, quick: bool, scheduler: str | None = None) -> int:
    """Run the bench, print its tables, write ``bench.md`` and ``bench.json`` to ``out``.

    ``out`` is checked before the bench runs, and the two files are put in place as one
    set (:func:`~selftune.core._atomic.output_directory`): both or neither, never one
    of them beside an earlier run's other.

    Parameters
    ----------
    out : str
        Directory for the two files: absent (created), empty, or holding only an earlier
        ``bench.md`` and ``bench.json`` (replaced).
    quick : bool
        The CI-sized run (:meth:`BenchConfig.quick`).
    scheduler : str, optional
        A running Dask scheduler: the seeded studies run on its cluster (default: here).

    Returns
    -------
    int
        0.

    Raises
    ------
    InputError
        If ``out`` is not a directory, holds other files, or cannot be written (before
        the bench runs).
    OSError
        If the files cannot be written (nothing partial is left).
    """
    check_output_directory(out, BENCH_OUTPUTS, _WHAT)
    if scheduler is None:
        report = run_bench(quick=quick, progress=True)
    else:
        with fleet_client(scheduler) as client:
            report = run_bench(quick=quick, progress=True, client=client)
    directory = Path(out)
    markdown = report.to_markdown()
    with output_directory(out, BENCH_OUTPUTS, _WHAT) as temporary:
        write_text(temporary / "bench.md", markdown)
        write_json(temporary / "bench.json", report.to_json())
    print(markdown, end="")
    print(
        f"\nwrote {directory / 'bench.md'} and {directory / 'bench.json'} "
        f"({report.wall_seconds:.1f} s)"
    )
    return 0
