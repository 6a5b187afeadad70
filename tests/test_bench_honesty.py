"""The honesty sweep's pieces: its cases are reproducible and not the tests', and a case's
log is what its hazard says (its refusal causes are counted by class: test_refusals.py)."""

from __future__ import annotations

import numpy as np

from selftune.bench._honesty import (
    HAZARDS,
    _as_logged,
    _options,
    _outcome,
    _settings,
    honesty_cases,
)


def test_the_cases_are_reproducible_balanced_and_use_no_test_seed() -> None:
    cases = honesty_cases(2)
    assert cases == honesty_cases(2)
    assert len(cases) == 2 * len(HAZARDS)
    for key, _, _ in HAZARDS:
        own = [case for case in cases if case.hazard_text == key]
        assert len(own) == 2 and {case.method_text for case in own} == {"adp", "identify"}
    for case in cases:
        assert case.seed >= 100_000
        assert case.sampling_frequency_hz in (1e4, 2e4)
        assert 1e-3 <= case.current_noise_amperes <= 5e-2
        motor = case.experiment.motor
        assert motor.p * case.speed_rad_per_second * motor.phi_pm <= 150.0 + 1e-9
        if case.hazard_text == "short":
            assert 0.005 <= case.data_seconds <= 0.05
        delay = 2 if case.hazard_text == "shift 2" else 1
        assert case.input_delay_samples == _settings(case).input_delay == delay
        assert _options(case).target == "digital"
        assert _options(case).dead_time == (case.hazard_text in ("dead time, stated",
                                                                 "hardware-like"))  # fmt: skip


def test_a_log_is_written_as_its_hazard_says() -> None:
    cases = {case.hazard_text: case for case in honesty_cases(1, short=True)}
    for key in ("float32", "7 digits", "clock offset"):
        case = cases[key]
        record = case.experiment.records(_settings(case), 0.005, [case.seed])[0]
        log = _as_logged(case, record.trajectory)
        assert log.w is not None
        if key == "float32":
            assert np.array_equal(log.x.astype(np.float32), log.x)
        elif key == "7 digits":
            assert all(float(f"{value:.7g}") == value for value in log.u.ravel())
        else:  # the offset is dropped: times are stored relative to the first sample
            assert log.t[0] == 0.0 and case.clock_offset_seconds != 0.0


def test_a_commanded_log_stated_as_applied_is_refused_naming_the_shift() -> None:
    case = next(case for case in honesty_cases(1, short=True) if case.hazard_text == "shift 1")
    outcome = _outcome(case)
    assert outcome.outcome_text == "refused" and outcome.cause_text == "alignment"
    assert "shift of 1 sample" in outcome.error_text
