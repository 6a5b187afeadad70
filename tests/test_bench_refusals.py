"""The refusals corpus (bench study 10): its exact dq plant agrees with the library's
sampled model where both are exact, its logs are what the issue asks for, a refusal is
called false exactly when a shorter prefix or a sibling seed was learned, and the quick
study's counts add up."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from selftune.bench import RefusalsConfig, measure_refusals
from selftune.bench._corpus import ADC_BITS, MOTORS, PLANTS, corpus_logs, exact_dq_log
from selftune.bench._refusals import (
    CorpusOutcome,
    _with_false_refusals,
    markdown_refusals,
    refusals_target,
)
from selftune.core import rotating_hold

BY_NAME = {motor.name_text: motor for motor in MOTORS}


def _phase_currents(x: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """i_a, i_b, i_c of dq currents at the electrical angles (amplitude-invariant)."""
    alpha = np.cos(angle) * x[:, 0] - np.sin(angle) * x[:, 1]
    beta = np.sin(angle) * x[:, 0] + np.cos(angle) * x[:, 1]
    return np.column_stack(
        [alpha, -0.5 * alpha + 0.5 * np.sqrt(3) * beta, -0.5 * alpha - 0.5 * np.sqrt(3) * beta]
    )


@pytest.mark.parametrize("name", ["README", "fast"])
def test_without_dead_time_noise_or_adc_the_plant_is_the_rotor_hold_model(name: str) -> None:
    motor = BY_NAME[name]
    experiment = motor.experiment
    log = exact_dq_log(motor, 400, seed=3, noise=0.0, dead_time=0.0, adc=False)
    assert log.w is not None and log.angle is not None
    Ad, Bd, Ed = experiment.motor.sampled_plant(experiment.speed, experiment.h, "rotor")
    # the command logged at k acts over [t_(k+1), t_(k+2)): one sample of delay
    predicted = log.x[1:-1] @ Ad.T + log.u[:-1] @ Bd.T + log.w[1:-1] @ Ed.T
    scale = np.max(np.abs(log.x))
    np.testing.assert_allclose(log.x[2:], predicted, rtol=0.0, atol=1e-12 * scale)
    np.testing.assert_allclose(np.diff(np.unwrap(log.angle)), experiment.electrical_speed
                               * experiment.h, rtol=1e-12)  # fmt: skip


def test_the_dead_time_is_held_in_the_stationary_frame_with_the_true_currents_signs() -> None:
    motor = BY_NAME["fast"]  # w_e h = 0.16 rad: the turning of the held vector shows
    experiment = motor.experiment
    volts = 1.5
    log = exact_dq_log(motor, 300, seed=4, noise=0.0, dead_time=volts, adc=False)
    assert log.w is not None and log.angle is not None
    problem = experiment.problem()
    Ad, Bd, Ed = experiment.motor.sampled_plant(experiment.speed, experiment.h, "rotor")
    held = rotating_hold(problem.A, problem.B, experiment.h, experiment.electrical_speed)
    phases = _phase_currents(log.x, log.angle)[1:-1]  # noise-free: the true currents
    error = -volts * np.sign(phases)
    alpha = (2 * error[:, 0] - error[:, 1] - error[:, 2]) / 3
    beta = (error[:, 1] - error[:, 2]) / np.sqrt(3)
    angle = log.angle[1:-1]
    d = np.cos(angle) * alpha + np.sin(angle) * beta
    q = -np.sin(angle) * alpha + np.cos(angle) * beta
    predicted = (log.x[1:-1] @ Ad.T + log.u[:-1] @ Bd.T + log.w[1:-1] @ Ed.T
                 + np.column_stack([d, q]) @ held.T)  # fmt: skip
    scale = np.max(np.abs(log.x))
    np.testing.assert_allclose(log.x[2:], predicted, rtol=0.0, atol=1e-11 * scale)


def test_the_measured_phase_currents_differ_by_whole_adc_steps() -> None:
    motor = BY_NAME["48 V"]
    log = exact_dq_log(motor, 200, seed=5, noise=0.02, dead_time=1.0)
    assert log.angle is not None
    steps = _phase_currents(log.x, log.angle) / (2 * motor.adc_range_amperes / 2**ADC_BITS)
    # dq drops the three readings' common mode; their differences are whole steps
    between = steps - np.roll(steps, 1, axis=1)
    np.testing.assert_allclose(between, np.round(between), atol=1e-9)
    assert np.ptp(steps) > 10  # the currents move over many steps


def test_the_corpus_is_the_issues() -> None:
    rates = {m.name_text: m.pole_pairs_count * m.speed_rad_per_second for m in MOTORS}
    assert len(MOTORS) >= 5
    low_voltage = BY_NAME["48 V"]
    assert low_voltage.dc_voltage_volts == 48.0 and low_voltage.L_s_henry < 1e-3
    assert BY_NAME["fast"].sampling_frequency_hz == 1e4 and rates["fast"] > 1000.0
    full = RefusalsConfig.full()
    assert set(full.plants_text) == set(PLANTS) and len(full.seeds) >= 2
    assert len(full.durations_seconds) >= 3 and list(full.durations_seconds) == sorted(
        full.durations_seconds
    )
    logs = corpus_logs(full)
    assert len(logs) == len(MOTORS) * len(PLANTS) * len(full.seeds)
    for log in logs:
        assert 1e-3 <= log.current_noise_amperes <= 5e-2
        assert 0.5 <= log.dead_time_volts <= 2.0
    # a log's draws do not depend on which others are run
    quick = corpus_logs(RefusalsConfig.quick())
    assert all(log in logs for log in quick)


def _run(motor: str, seed: int, seconds: float, refused: bool) -> CorpusOutcome:
    log = replace(corpus_logs(RefusalsConfig.quick())[0], motor=BY_NAME[motor], seed=seed)
    cause = "too little data" if refused else ""
    return CorpusOutcome(log, seconds, log.text(seconds), cause, cause, "", None, None, (), 0.0)


def test_a_refusal_is_false_when_a_shorter_prefix_or_a_sibling_seed_was_learned() -> None:
    outcomes = _with_false_refusals([
        _run("README", 1, 0.1, refused=False),
        _run("README", 1, 0.5, refused=True),  # its prefix was learned: false
        _run("README", 2, 0.1, refused=True),  # seed 1 of 0.1 s was learned: false
        _run("README", 2, 0.5, refused=True),  # no shorter prefix, no sibling: true
        _run("paper", 1, 0.1, refused=True),  # another motor's learned run is no sibling
    ])  # fmt: skip
    marked = [o.false_refusal_text for o in outcomes]
    assert marked[0] == "" and marked[3] == "" and marked[4] == ""
    assert "0.1 s prefix" in marked[1] and "seed 1" in marked[2]


def test_the_quick_studys_counts_add_up() -> None:
    refusals = measure_refusals(RefusalsConfig.quick())
    quick = RefusalsConfig.quick()
    assert refusals.logs_count == len(quick.plants_text) * len(quick.seeds) * len(
        quick.durations_seconds
    )
    assert refusals.learned_count + refusals.refused_count == refusals.logs_count
    for block in refusals.blocks:
        own = [o for o in refusals.outcomes if block.plant_text in ("all", o.log.plant_text)]
        assert block.results_count == sum(not o.refused for o in own)
        if block.within_one_ratio is not None and block.within_three_ratio is not None:
            assert 0.0 <= block.within_one_ratio <= block.within_three_ratio <= 1.0
    for outcome in refusals.outcomes:
        assert outcome.refused == (outcome.true_loop_radius_ratio is None)
        assert outcome.refused == (outcome.blocks == ())
    lines = markdown_refusals(refusals)
    assert lines[0] == "## 10. Refusals and calibration"
    assert refusals_target(refusals, quick=True).met is None


def test_a_shorter_log_is_a_prefix_of_a_longer_one() -> None:
    motor = BY_NAME["README"]
    short, long = (exact_dq_log(motor, n, seed=6, noise=0.01, dead_time=1.0) for n in (50, 120))
    np.testing.assert_array_equal(short.x, long.x[:51])
    np.testing.assert_array_equal(short.u, long.u[:50])
