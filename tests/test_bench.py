"""``selftune bench --quick``: the report is complete, its units are named, its numbers sane.

No measured number is hard-coded: the checks are relations that hold whenever the bench
measures what it says (off-policy needs less data than on-policy, the true optimum costs
least, exact simulation has rounding error only, a PI on the nominal flux misses the torque
by exactly the flux error, ...). Timings are only checked to be finite and positive.
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path
from typing import Any

import pytest

from selftune import bench
from selftune.bench import BenchConfig, BenchReport, bench_command
from selftune.bench import _gem as bench_gem
from selftune.bench import _report as bench_report
from selftune.bench._common import progress_bar
from selftune.bench._learning_cost import LearningCost, measure_learning_cost
from selftune.bench._loop import Loop
from selftune.bench._simulation import Simulation, measure_simulation
from selftune.cli import build_parser

SECTIONS = (
    "data_efficiency",
    "learning_cost",
    "simulation",
    "self_tuning_value",
    "drive_rates",
    "honesty",
    "noise",
    "calibration",
    "refusals",
    "online",
    "fleet",
    "interior",
)

#: A numeric key must name its unit (or say it is a ratio, a count, a relative error...).
UNIT_TOKENS = (
    "seconds",
    "us_per_step",
    "per_second",
    "samples",
    "intervals",
    "count",
    "relative",
    "ratio",
    "speedup",
    "percent",
    "ohm",
    "henry",
    "weber",
    "newton_meters",
    "rad_per_second",
    "volt2",
    "factor",
    "seed",
    "processes",
    "hz",
    "amperes",
    "volts",
    "mebibytes",
)
#: Keys of flags and of text.
FLAG_KEYS = {"quick", "available", "met"}
TEXT_SUFFIXES = ("_text", "_version")


@pytest.fixture(scope="module")
def report(quick_bench: BenchReport) -> BenchReport:
    return quick_bench


@pytest.fixture(scope="module")
def learning_cost() -> LearningCost:
    """The quick bench's learning-cost section alone (a fraction of a second of CPU), so
    that a plain ``pytest`` measures with the bench too (the rest reads the whole bench)."""
    return measure_learning_cost(BenchConfig.quick(), progress=False)


@pytest.fixture(scope="module")
def simulation() -> Simulation:
    """The quick bench's simulation section alone (about two seconds of CPU)."""
    return measure_simulation(BenchConfig.quick(), progress=False)


@pytest.fixture(scope="module")
def document(report: BenchReport) -> dict[str, Any]:
    data = report.to_json()
    # What bench.json holds must survive a strict JSON round trip (no NaN or Infinity).
    return json.loads(json.dumps(data, allow_nan=False))


def _leaves(value: Any, key: str = "") -> list[tuple[str, Any]]:
    """(key, value) of every non-container value; list items keep their list's key."""
    if isinstance(value, dict):
        return [leaf for k, v in value.items() for leaf in _leaves(v, k)]
    if isinstance(value, list):
        return [leaf for item in value for leaf in _leaves(item, key)]
    return [(key, value)]


def test_every_section_and_the_environment_are_present(document: dict[str, Any]) -> None:
    assert set(document) >= {*SECTIONS, "environment", "quick", "wall_seconds", "targets"}
    assert document["quick"] is True
    environment = document["environment"]
    for key in ("python_version", "numpy_version", "scipy_version", "machine_cores_count"):
        assert environment[key]
    assert environment["machine_cores_count"] >= 1
    assert {"data_ratio_vs_paper", "speedup_vs_gem"} <= {key for key, _ in _leaves(document)}
    names = [target["name_text"] for target in document["targets"]]
    assert "data_ratio_vs_paper" in names and "speedup_vs_gem" in names


def test_every_key_names_its_unit(document: dict[str, Any]) -> None:
    for key, value in _leaves(document):
        if isinstance(value, bool) or key in FLAG_KEYS:
            assert key in FLAG_KEYS, f"{key}: a flag with an unexpected name"
        elif isinstance(value, str) or key.endswith(TEXT_SUFFIXES):
            assert key.endswith(TEXT_SUFFIXES), f"{key}: text without _text/_version"
        else:
            assert value is None or isinstance(value, int | float), key
            assert any(token in key for token in UNIT_TOKENS), f"{key}: no unit in the name"


def test_times_are_finite_and_positive(document: dict[str, Any]) -> None:
    timings = [
        (key, value)
        for key, value in _leaves(document)
        if key in ("wall_seconds", "us_per_step", "steps_per_second", "warm_steps_per_second")
    ]
    assert len(timings) >= 10
    for key, value in timings:
        assert value is not None and math.isfinite(value) and value > 0, key
    # the whole bench took at least as long as its parts
    parts = sum(document[section]["wall_seconds"] for section in SECTIONS)
    assert document["wall_seconds"] >= parts


def test_offpolicy_needs_less_data_than_onpolicy(report: BenchReport) -> None:
    data = report.data_efficiency
    target = data.target_relative_error
    assert data.onpolicy_seconds is not None and data.offpolicy_seconds is not None
    assert data.offpolicy_seconds < data.onpolicy_seconds
    assert data.data_ratio_vs_paper == pytest.approx(data.onpolicy_seconds / data.offpolicy_seconds)
    # on-policy data come in whole episodes; off-policy cannot beat the identifiability floor
    episodes = data.onpolicy_seconds / data.onpolicy_episode_seconds
    assert episodes == pytest.approx(round(episodes)) and round(episodes) >= 2
    assert data.offpolicy_intervals is not None
    assert data.offpolicy_intervals >= data.identifiability_floor_intervals == 11
    assert data.offpolicy_seconds == pytest.approx(data.offpolicy_samples * data.sampling_seconds)
    # the curve agrees with the reported shortest batch: from it on, every point meets both
    # targets (the criterion is the median of the larger error, which bounds both medians)
    curve = data.offpolicy_curve
    assert len(curve.data_seconds) == len(curve.K_relative_error) == len(curve.U_relative_error)
    shortest = curve.data_seconds.index(
        min(curve.data_seconds, key=lambda s: abs(s - data.offpolicy_seconds))
    )
    for k, u in zip(
        curve.K_relative_error[shortest:], curve.U_relative_error[shortest:], strict=True
    ):
        assert k is not None and u is not None and k <= target and u <= target
    # the sweep starts at the floor: one sample per interval, 11 intervals
    assert curve.data_seconds[0] == pytest.approx(11 * data.sampling_seconds)
    # the on-policy curve starts at K0, U0 = 0 and ends meeting both targets
    on = data.onpolicy_curve
    assert on.data_seconds[0] == 0 and on.U_relative_error[0] == pytest.approx(1.0)
    assert on.K_relative_error[-1] is not None and on.K_relative_error[-1] <= target
    assert on.U_relative_error[-1] is not None and on.U_relative_error[-1] <= target


def test_learning_cost_compares_the_methods_on_the_same_data(learning_cost: LearningCost) -> None:
    datasets = learning_cost.datasets
    assert len(datasets) >= 2
    for dataset in datasets:
        customized, general = dataset.customized, dataset.general
        assert customized.unknowns_count == general.unknowns_count == 11
        assert customized.rows_count == general.rows_count
        assert customized.rows_count == -(-dataset.samples // dataset.interval_samples)
        assert customized.least_squares_solves_count == customized.iterations_count
        assert general.least_squares_solves_count == general.iterations_count + 1  # C = I
        assert customized.theta_relative_error < 1e-4
        assert dataset.data_seconds == pytest.approx(dataset.samples * dataset.sampling_seconds)
    # both learners get more accurate with finer sampling (the O(h^2) quadrature error)
    coarse = max(datasets, key=lambda d: d.sampling_seconds)
    fine = min(datasets, key=lambda d: d.sampling_seconds)
    assert fine.sampling_seconds < coarse.sampling_seconds
    for method in ("customized", "general"):
        assert (
            getattr(fine, method).theta_relative_error
            < getattr(coarse, method).theta_relative_error
        )


def test_simulation_is_exact_and_the_speedup_is_the_ratio_of_times(simulation: Simulation) -> None:
    for measured in (simulation.selftune_simulate, simulation.selftune_step_loop):
        assert measured.max_relative_error <= bench.EXACT_RELATIVE_ERROR
        assert measured.us_per_step > 0
    assert simulation.batch.max_relative_error <= bench.EXACT_RELATIVE_ERROR
    batch = simulation.batch
    assert batch.motors_count == 1000
    assert batch.steps_per_second == pytest.approx(
        batch.motors_count * batch.samples_per_motor / batch.wall_seconds
    )
    for measured in (simulation.solve_ivp_rk45, simulation.solve_ivp_rk45_tight):
        assert math.isfinite(measured.max_relative_error) and measured.us_per_step > 0
    gem = simulation.gym_electric_motor
    if gem.available:
        assert gem.default_solver is not None and gem.euler_solver is not None
        assert simulation.speedup_vs_gem == pytest.approx(
            gem.default_solver.us_per_step / simulation.selftune_simulate.us_per_step
        )
        # its Euler solver is first order: worse than its default solver
        assert gem.euler_solver.max_relative_error > gem.default_solver.max_relative_error
    else:
        assert simulation.speedup_vs_gem is None and gem.reason_text


def test_without_gym_electric_motor_the_bench_says_so(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(bench_gem, "gem_version", lambda: None)
    measured = bench_gem.measure_gem(Loop.paper(), samples=10)
    assert not measured.available and measured.default_solver is None
    assert measured.reason_text is not None and "not installed" in measured.reason_text


def test_the_true_optimum_costs_least_and_self_tuning_recovers_it(report: BenchReport) -> None:
    value = report.self_tuning_value
    signs = {(case.R_s_factor, case.L_s_factor, case.phi_pm_factor) for case in value.cases}
    assert signs == set(itertools.product((0.7, 1.3), repeat=3))
    for case in value.cases:
        optimum = case.optimum.cost_volt2_seconds
        assert optimum > 0
        for name in bench.CONTROLLERS:
            outcome = getattr(case, name)
            assert optimum <= outcome.cost_volt2_seconds * (1 + 1e-9), name
            assert outcome.excess_cost_percent == pytest.approx(
                100 * (outcome.cost_volt2_seconds / optimum - 1), abs=1e-9
            )
        # a PI on the nominal flux regulates i_q to the nominal i_q*, so its torque is off
        # by exactly the flux error; the optimum has none
        assert case.pi_nominal.steady_torque_error_percent == pytest.approx(
            100 * (case.phi_pm_factor - 1)
        )
        assert abs(case.optimum.steady_torque_error_newton_meters) < 1e-9
        assert abs(case.pi_true_flux.steady_torque_error_newton_meters) < 1e-9
        # nominal designs pay for the mismatch; the self-tuned controller does not
        assert case.lqr_nominal.excess_cost_percent > 1
        assert case.pi_nominal.excess_cost_percent > 1
        assert case.self_tuned.excess_cost_percent < 1e-3
        # knowing the flux is not enough: R_s and L_s matter too, and self-tuning learns them
        assert case.self_tuned.excess_cost_percent < case.lqr_true_flux.excess_cost_percent
        assert case.lqr_true_flux.excess_cost_percent < case.lqr_nominal.excess_cost_percent
        assert abs(case.self_tuned.steady_torque_error_percent) < 1e-3
        assert case.self_tuned_K_relative_error < 1e-4
        assert case.unknown_flux_phi_pm_relative_error < 1e-4


def test_markdown_has_every_table_and_says_which_targets_are_met(report: BenchReport) -> None:
    text = report.to_markdown()
    for heading in (
        "## Targets",
        "## 1. Data efficiency",
        "## 2. Cost of learning",
        "## 3. Simulation speed",
        "## 4. The value of self-tuning",
        "## 5. At drive rates",
        "## 6. Honesty",
        "## 7. Measurement noise",
        "## 8. Calibration",
        "## 9. On a realistic drive",
        "## 10. Refusals and calibration",
        "## 11. The online tuner on drives that heat",
        "## 12. A fleet of drives on the distributed engine",
        "## 13. Interior PM motors commissioned",
    ):
        assert heading in text
    section = text.split("## Targets")[1].split("\n## ")[0]
    for target in report.targets():
        row = next(
            line for line in section.splitlines() if line.startswith(f"| {target.name_text} |")
        )
        status = {True: "| met |", False: "| MISSED |", None: "| not measured |"}[target.met]
        assert status in row
    assert "nan" not in text.lower().replace("nanoseconds", "")
    for target in report.targets():  # a "|" would split the targets table's cells
        texts = (target.name_text, target.target_text, target.value_text, target.why_text)
        assert not any("|" in text for text in texts), target


def test_arguments() -> None:
    parser = build_parser()
    defaults = parser.parse_args(["bench"])
    assert defaults.quick is False and defaults.out == "selftune-bench"
    given = parser.parse_args(["bench", "--quick", "--out", "results"])
    assert given.quick is True and given.out == "results"


def test_the_command_writes_both_files(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    report: BenchReport,
) -> None:
    """The command around the session's quick bench (run once): what it asks run_bench
    for, its progress bars (the bench's own, asked for, silent off a terminal), its files."""
    asked: list[tuple[bool, bool]] = []

    def session_bench(quick: bool, progress: bool) -> BenchReport:
        asked.append((quick, progress))
        with progress_bar(1, "bench", progress) as bar:
            bar.update(1)
        return report

    monkeypatch.setattr(bench_report, "run_bench", session_bench)
    out = tmp_path / "new" / "dir"
    status = bench_command(str(out), quick=True)
    assert asked == [(True, True)]
    assert status == 0
    assert sorted(path.name for path in out.iterdir()) == ["bench.json", "bench.md"]
    data = json.loads((out / "bench.json").read_text(encoding="utf-8"))
    assert set(data) >= {*SECTIONS, "environment", "quick"} and data["quick"] is True
    markdown = (out / "bench.md").read_text(encoding="utf-8")
    captured = capsys.readouterr()
    assert markdown in captured.out
    assert captured.err == ""  # no progress bar when stderr is not a terminal


def test_at_drive_rates_the_digital_learners_are_exact_or_refuse_by_name(
    report: BenchReport,
) -> None:
    rates = report.drive_rates
    assert len({e.motor_text for e in rates.errors}) == 3
    for e in rates.errors:
        for value in (
            e.digital_adp_K_relative_error,
            e.digital_adp_U_relative_error,
            e.identify_K_relative_error,
            e.identify_U_relative_error,
        ):
            assert value is not None and value <= 1e-9
        refused = e.continuous_adp_K_relative_error is None
        assert refused == ("adp (continuous)" in e.refusals_text)
        assert "unnamed" not in e.refusals_text
    for cost in rates.costs:  # the digital optimum costs least on its own loop
        assert cost.excess_cost_no_delay_percent >= -1e-6
        delayed = cost.excess_cost_one_sample_delay_percent
        assert delayed is None or delayed >= -1e-6


def test_honesty_classifies_every_log_and_names_every_refusal(report: BenchReport) -> None:
    honesty = report.honesty
    hazards = [tally.hazard_text for tally in honesty.tallies[:-1]]
    assert len(set(hazards)) == len(hazards) == 11 and honesty.overall.hazard_text == "all"
    assert (
        len(honesty.outcomes)
        == honesty.overall.logs_count
        == sum(tally.logs_count for tally in honesty.tallies[:-1])
    )
    for tally in honesty.tallies:
        assert tally.logs_count == (
            tally.correct_count
            + tally.refused_count
            + tally.silent_wrong_count
            + tally.destabilizing_count
        )
    multiple = honesty.se_multiple_factor
    for outcome in honesty.outcomes:
        assert outcome.case.seed >= 100_000  # no test's seed
        if outcome.outcome_text == "refused":
            assert outcome.cause_text != "unnamed", outcome.error_text
            assert outcome.K_relative_error is None
            continue
        assert outcome.K_relative_error is not None and outcome.K_relative_se is not None
        assert outcome.U_relative_error is not None and outcome.U_relative_se is not None
        assert outcome.true_loop_radius_ratio is not None
        within = (
            outcome.K_relative_error <= multiple * outcome.K_relative_se
            and outcome.U_relative_error <= multiple * outcome.U_relative_se
        )
        unstable = outcome.true_loop_radius_ratio >= 1.0
        expected = "destabilizing" if unstable else "correct" if within else "silent wrong"
        assert outcome.outcome_text == expected
        # a log whose voltages act a sample later than stated is never learned
        assert not outcome.case.hazard_text.startswith("shift"), outcome.case.reproduction_text()
    assert len(honesty.failures()) == (
        honesty.overall.silent_wrong_count + honesty.overall.destabilizing_count
    )


def test_the_noise_study_covers_every_method_and_its_ratios_are_of_its_medians(
    report: BenchReport,
) -> None:
    study = report.noise
    methods = {cell.method_text for cell in study.cells}
    assert methods == {"continuous_adp", "digital_adp", "identify", "identify_spmsm"}
    places = {(c.sampling_frequency_hz, c.current_noise_amperes) for c in study.cells}
    assert len(study.cells) == len(methods) * len(places) * len(study.lengths_seconds)
    for cell in study.cells:
        assert cell.runs_count == len(study.seeds)
        assert 0 <= cell.refused_count <= cell.runs_count
        assert cell.within_se_count <= cell.runs_count - cell.refused_count
        assert 0 < cell.learning_min_seconds <= cell.learning_median_seconds
        assert cell.learning_median_seconds <= cell.learning_max_seconds
        for median, p90 in (
            (cell.K_median_relative_error, cell.K_p90_relative_error),
            (cell.U_median_relative_error, cell.U_p90_relative_error),
        ):
            assert p90 is None or (median is not None and median <= p90)
        if cell.too_little_data_count:  # a refusal for too little data asks for more
            assert cell.needed_median_seconds is not None
            assert cell.needed_median_seconds > cell.data_seconds
    _, middle, long = study.lengths_seconds
    for ratio in study.ratios:
        key = (ratio.method_text, ratio.sampling_frequency_hz, ratio.current_noise_amperes)
        at_middle, at_long = study.cell(*key, middle), study.cell(*key, long)
        if ratio.K_ratio is not None:
            assert at_long.K_median_relative_error is not None
            assert at_middle.K_median_relative_error is not None
            assert ratio.K_ratio == pytest.approx(
                at_long.K_median_relative_error / at_middle.K_median_relative_error
            )
    names = [target.name_text for target in report.targets()]
    assert "noise: consistency" in names and "noise: short logs" in names
    # the quick run's sizes are not the issue's: its noise targets are not judged
    assert all(
        target.met is None
        for target in report.targets()
        if target.name_text.startswith("noise") and target.name_text != "noise: short logs"
    )


def test_calibration_counts_every_trial_of_every_method(report: BenchReport) -> None:
    calibration = report.calibration
    trials = {trial.trial_count for trial in calibration.trials}
    assert len(calibration.methods) == 4
    for method in calibration.methods:
        own = [t for t in calibration.trials if t.method_text == method.method_text]
        assert method.trials_count == len(own) == len(trials)
        assert method.refused_count == sum(bool(t.cause_text) for t in own)
        for coverage in (method.K_norm_coverage_ratio, method.K_entry_coverage_ratio):
            assert coverage is None or 0.0 <= coverage <= 1.0
    for trial in calibration.trials:
        assert trial.K_entries_within_count <= trial.K_entries_count
        assert (trial.K_error_over_se_ratio is None) == bool(trial.cause_text)
