"""The dead-time channels on the signs the next sample shows
(:func:`selftune.learn.evidence._model_signs.next_sample_signs`).

The ramp's 30-34 uH motors on 48 V at 5% of rated speed (docs/schedule.md, ``drawn_cases(60,
11)``, numbers 9, 17 and 44) were refused by the consistency test: their phase currents
linger near zero, where the measured signs were wrong in 62-133 of 15,000 phase samples,
and each wrong sign's 1.4 A lasts 100 samples in the model's simulation of a plant this
close to an integrator. The next sample shows each of those signs.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import selftune.learn._speeds as speeds_module
import selftune.tuning._ramp as ramp_module
from selftune.bench._interior import drawn_cases, study_drive
from selftune.bench._ramp import _run
from selftune.config import MotorConfig
from selftune.learn.evidence import _model_signs
from selftune.learn.evidence._dead_time import DeadTimeChannels, phase_signs
from selftune.learn.evidence._evidence import gather_evidence
from selftune.report._digital_evaluation import true_motor
from selftune.tuning import commission_interior, tuning_settings

#: The drawn motors of the ramp study refused at 5% of rated speed before.
DRAWN = (9, 17, 44)


class _Stop(Exception):
    """Raised to end a ramp at its first (lowest) speed's part."""


def _lowest_part(number: int, monkeypatch: pytest.MonkeyPatch) -> tuple:  # type: ignore[type-arg]
    """The ramp's log at its lowest speed as the learner gets it, and the true currents."""
    kept: dict[str, object] = {}
    run = ramp_module.run_speed_profile

    def recorded(*args, **kwargs):  # type: ignore[no-untyped-def]
        kept["record"] = run(*args, **kwargs)
        return kept["record"]

    def first(part, problem, K0, options):  # type: ignore[no-untyped-def]
        kept["part"] = (part, problem, options)
        raise _Stop

    motor, speed, torque, bus, seed, adc_range = drawn_cases(60, 11)[number - 1]
    with monkeypatch.context() as patch:
        patch.setattr(ramp_module, "run_speed_profile", recorded)
        patch.setattr(speeds_module, "learn_controller", first)
        with pytest.raises(_Stop):
            _run(motor, speed, torque, bus, seed, f"drawn {number}", adc_range)
    part, problem, options = kept["part"]  # type: ignore[misc]
    record = kept["record"]
    start = int(np.argmin(np.abs(record.trajectory.t - part.t[0])))  # type: ignore[attr-defined]
    true = record.true_currents[start : start + part.x.shape[0]]  # type: ignore[attr-defined]
    return part, problem, options, true


def _wrong_signs(channels: DeadTimeChannels, true: np.ndarray, angle: np.ndarray) -> int:
    """Rows whose dead-time channels are not the true currents' phase signs."""
    w = channels.episodes[0].w
    assert w is not None
    expected = phase_signs(true, angle)[: w.shape[0]]
    return int(np.sum(np.any(np.abs(w[:, -2:] - expected) > 1e-9, axis=1)))


def test_the_next_sample_shows_the_signs_the_measurement_does_not(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """On the lowest speed of drawn 17 (a 33 uH motor, ADC steps of 0.2 A) the measured
    signs are wrong in many rows, the next sample's in a tenth of them or fewer, and the
    data are learned."""
    part, problem, options, true = _lowest_part(17, monkeypatch)
    seen: list[tuple[DeadTimeChannels, DeadTimeChannels]] = []
    chosen = _model_signs.next_sample_signs

    def spied(channels, shift, fit):  # type: ignore[no-untyped-def]
        result = chosen(channels, shift, fit)
        seen.append((channels, result))
        return result

    monkeypatch.setattr(_model_signs, "next_sample_signs", spied)
    evidence = gather_evidence([part], problem, options)
    assert evidence.consistency.passed
    [(measured, next_sample)] = seen
    wrong = _wrong_signs(measured, true, part.angle)
    assert wrong >= 50, wrong
    assert 10 * _wrong_signs(next_sample, true, part.angle) <= wrong


@pytest.mark.parametrize("number", DRAWN)
def test_the_small_inductances_at_low_speed_are_learned_within_their_bars(number: int) -> None:
    """Each drawn motor is learned, its inductances and flux within 3 standard errors."""
    motor, speed, torque, bus, seed, adc_range = drawn_cases(60, 11)[number - 1]
    case = _run(motor, speed, torque, bus, seed, f"drawn {number}", adc_range)
    assert case.refusal_text == "", case.refusal_text
    assert case.largest_z <= 3.0, case.largest_z


def test_the_motor_that_missed_half_a_percent_now_meets_it() -> None:
    """Drawn 15 of the interior study (``drawn_cases(30, 13, interior=True)``, a 0.93/1.40
    mH motor rated 1.2 A at ``w_e h`` = 0.18 on 540 V with 2 V of dead time). At 2% of the
    bus of exploration its phase currents' signs near zero were the noise's so often that
    L_d came out 0.64% low (0.8 standard errors of 0.80%): the issue's 0.5% missed. At an
    interior motor's default 3% (``default_exploration``) the exploration outweighs the
    dead time's voltage: L_d, L_q and the flux within 0.5% and 3 standard errors."""
    from selftune.bench._interior import _run as interior_run

    motor, speed, torque, bus, seed, adc_range = drawn_cases(30, 13, interior=True)[14]
    case = interior_run(motor, speed, torque, bus, seed, "drawn 15", adc_range)  # type: ignore[arg-type]
    assert case.learned, case.refusal_text
    for name in ("L_d", "L_q", "phi_pm"):
        assert abs(case.error_percent(name)) <= 0.5, (name, case.error_percent(name))
        assert abs(case.z(name)) <= 3.0, (name, case.z(name))


@pytest.mark.parametrize(
    ("number", "share", "dead_time"), [(4, 0.05, None), (15, 1.0, 2e-6), (16, 1.0, 2e-6)]
)
def test_where_the_measured_signs_fit_is_wrong_the_next_samples_is_reported(
    number: int, share: float, dead_time: float | None
) -> None:
    """Drawn interior motors whose measured signs' fit passed every test and was off:
    drawn 4 (0.11/0.28 mH on 48 V) at 5% of its rated speed, L_d 1.31% off at 1.5
    standard errors; drawn 15 and 16 (0.93/1.40 and 0.74/1.11 mH on 540 V) with 2 us of
    dead time, R_s 17 and 3.7 times the truth and L_d 2.8% and 4.0% low at 5.4 and 7.8
    standard errors (then refused by the R_s check). On the next sample's signs (the bus
    given; for 15 and 16 both fits' own simulations departing beyond a third of the
    currents' spread) L_d, L_q and the flux are within 0.1%, every parameter within 3
    standard errors."""
    motor, speed, torque, bus, seed, adc_range = drawn_cases(30, 13, interior=True)[number - 1]
    drive = study_drive(bus, adc_range)
    if dead_time is not None:
        drive = replace(drive, dead_time=dead_time)
    config = MotorConfig(
        motor=motor, speed=share * speed, torque=torque, drive=drive, drive_h=1e-4,
        learning={"integral_action": True}, source=f"drawn {number}",
    )  # fmt: skip
    result = commission_interior(motor, tuning_settings(config, seed), drive, seed=seed)
    evidence = result.learned.evidence
    assert evidence is not None and evidence.next_sample_signs > 0
    truth = true_motor(motor, drive)
    for name, se in result.standard_errors.items():
        error = getattr(result.motor, name) - getattr(truth, name)
        assert abs(error) <= 3.0 * se, (name, error / se)
        if name != "R_s":
            assert abs(error) <= 1e-3 * abs(getattr(truth, name)), (name, error)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_next_sample_decides_the_signs_on_a_plant_whose_signs_are_known(seed: int) -> None:
    """A 33 uH, 0.02 ohm surface plant at 10 kHz with 0.24 V of dead time switched on its
    true currents' signs, driven about zero current, measured with 20 mA of noise: a
    wrong sign moves the next sample by 1.45 A, 70 noise deviations, so the next sample
    (:func:`~selftune.learn.evidence._next_signs.next_signs`, with the true model and
    noise) names the true signs wherever the measurement leaves them undecided."""
    from selftune.learn.evidence._next_signs import next_signs

    rng = np.random.default_rng(seed)
    h, L, R, v, noise, count = 1e-4, 33e-6, 0.02, 0.24, 0.02, 4000
    Ad, Bd = (1.0 - R * h / L) * np.eye(2), (h / L) * np.eye(2)
    Ed = -v * Bd  # the signs' gain, no other exogenous channel
    angle = 300.0 * h * np.arange(count + 1)
    a = 0.05 * rng.standard_normal((count, 2))  # 0.15 A a sample about zero
    x = np.zeros((count + 1, 2))
    for k in range(count):
        held = phase_signs(x[k : k + 1], angle[k : k + 1])[0]
        x[k + 1] = Ad @ x[k] + Bd @ a[k] + Ed @ held
    measured = x + noise * rng.standard_normal(x.shape)
    truth = phase_signs(x[:-1], angle[:-1])
    wrong_measured = np.any(np.abs(phase_signs(measured[:-1], angle[:-1]) - truth) > 1e-9, axis=1)
    chosen = next_signs(
        measured, a, np.zeros((count, 0)), angle[:-1], (Ad, Bd, Ed), noise**2 * np.eye(2)
    )
    wrong_next = np.any(np.abs(chosen - truth) > 1e-9, axis=1)
    assert np.sum(wrong_measured) >= 20, np.sum(wrong_measured)
    assert np.sum(wrong_next) <= np.sum(wrong_measured) // 10, np.sum(wrong_next)
