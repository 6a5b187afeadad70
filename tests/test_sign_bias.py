"""The dead-time model's bias from noisy current signs: measured, removed, and in the bars.

The truth is the digital optimum of the true sampled loop; the drive is the README's
(2 V of dead time on a 540 V bus at 10 kHz, a one-sample delay, 10 mA of current noise),
whose small currents (0.3 A rms) make the signs' errors weigh.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Literal

import numpy as np
import pytest
import scipy.linalg

import selftune
from selftune.config import MotorConfig
from selftune.core import ControlLaw
from selftune.learn import (
    LearnedController,
    LearningOptions,
    LearningProblem,
    Trajectory,
    learn_controller,
)
from selftune.learn.evidence._dead_time import with_dead_time
from selftune.learn.evidence._output_error import _Log
from selftune.learn.evidence._sign_bias import measurement_noise
from selftune.model import IPMSM, ModelBasedSolution, solve_digital_regulation
from selftune.sim import DriveSettings, RealisticDrive, held, uniform
from selftune.sim._inverter import heated_motor
from selftune.tuning import TuningSettings, commission_interior, tuning_settings
from selftune.tuning._saturation import learn_level

MOTOR = selftune.SPMSM(R_s=0.6, L_s=8e-3, phi_pm=0.35, p=3)
SPEED, TORQUE, H = 50.0, 5.0, 1e-4


def _log(samples: int, seed: int) -> Trajectory:
    settings = replace(
        DriveSettings.hardware_like(h=H), logged_input="commanded", adc_bits=None, adc_range=None
    )
    drive = RealisticDrive(MOTOR, SPEED, H, settings)
    w = MOTOR.exogenous(SPEED, TORQUE)
    F = MOTOR.regulation_problem(SPEED).F
    levels = np.array([1.0, 1.0 / 3.0, -1.0 / 3.0, -1.0])

    def reference(t: np.ndarray) -> np.ndarray:
        level = levels[np.floor(t / 0.01).astype(int) % levels.size]
        return np.column_stack([np.full_like(t, w[0]), level * TORQUE])

    law = ControlLaw.regulator(np.eye(2), -F, np.array([[0.0, 0.0], [1.0, 0.0]]))
    return drive.run(
        law, held(reference), num_samples=samples, exploration=uniform(10.8), seed=seed
    )


def _learned(
    log: Trajectory, hold: Literal["rotor", "stationary"], method: Literal["adp", "identify"]
) -> tuple[LearnedController, ModelBasedSolution]:
    """The README's problem learned from the log with dead time, and its truth: the
    digital optimum of the motor sampled with the drive's hold and one-sample delay."""
    problem = MOTOR.regulation_problem(SPEED)
    known = LearningProblem(1e3 * np.eye(2), np.eye(2), C=problem.C, F=problem.F,
                            integral_action=True)  # fmt: skip
    truth = solve_digital_regulation(
        problem, 1e3 * np.eye(2), np.eye(2), H, input_delay=1,
        integral_weight=known.integral_weight, plant=MOTOR.sampled_plant(SPEED, H, hold),
    )  # fmt: skip
    options = LearningOptions(target="digital", input_delay=1, logged_input="commanded",
                              dead_time=True, method=method)  # fmt: skip
    return learn_controller(log, known, np.eye(2), options), truth


@pytest.mark.parametrize(
    "samples, seed", [(10000, 13), pytest.param(20000, 2026, marks=pytest.mark.slow)]
)
def test_the_feedforward_is_within_its_stated_errors_under_dead_time_and_noise(
    samples: int, seed: int
) -> None:
    # At 2 s it was 8.6% off under a stated 1.9% (5.9 standard errors on one entry): the signs
    # the noise flips near zero current were taken as the inverter's, and the resistance
    # took the dead-time voltage they hid.
    result, truth = _learned(_log(samples, seed), "stationary", "adp")
    quality = result.quality
    assert np.all(np.abs(result.U - truth.U) <= 3.0 * quality.U_se)
    assert np.all(np.abs(result.K - truth.K) <= 3.0 * quality.K_se[:, : truth.K.shape[1]])
    assert any("signs near zero" in note for note in quality.notes)


def test_the_measurement_noise_is_read_from_the_one_step_residuals() -> None:
    # an exact linear model with white noise on the states: the lag-one covariance of the
    # one-step residuals is -Ad R whatever the inputs
    rng = np.random.default_rng(5)
    Ad = np.array([[0.95, 0.1], [-0.1, 0.9]])
    Bd = np.array([[0.1, 0.0], [0.02, 0.2]])
    R = np.array([[4e-4, 1e-4], [1e-4, 2e-4]])
    a = rng.standard_normal((200_000, 2))
    x = np.zeros((a.shape[0] + 1, 2))
    for k in range(a.shape[0]):
        x[k + 1] = Ad @ x[k] + Bd @ a[k]
    measured = x + rng.standard_normal(x.shape) @ np.linalg.cholesky(R).T
    estimate = measurement_noise([_Log(x=measured, a=a, w=np.zeros((a.shape[0], 0)))],
                                 (Ad, Bd, np.zeros((2, 0))))  # fmt: skip
    assert estimate is not None
    # the estimate's spread over 2e5 samples is about 1% of R's size
    np.testing.assert_allclose(estimate, R, atol=0.05 * np.max(R))


def _subsample_log(samples: int, seed: int, noise: float, steps: int = 20) -> Trajectory:
    """An independent simulation of the README's motor in which each leg's dead time
    switches with its current's own sign within the sample (``steps`` exact linear steps
    per sample, the signs taken at each), the voltage held in dq and applied one sample
    after it was commanded, ``noise`` A on each measured phase current."""
    R, L, phi, p, v = 0.6, 8e-3, 0.35, 3, 2.0
    omega = p * SPEED
    A = np.array([[-R / L, omega], [-omega, -R / L]])
    step = scipy.linalg.expm(A * H / steps)
    gain = np.linalg.solve(A, step - np.eye(2)) / L
    rng = np.random.default_rng(seed)
    theta0 = rng.uniform(0.0, 2.0 * np.pi)
    half = np.sqrt(3.0) / 2.0
    phases = np.array([[1.0, 0.0], [-0.5, half], [-0.5, -half]])  # alpha, beta -> a, b, c
    levels = np.array([1.0, 1.0 / 3.0, -1.0 / 3.0, -1.0]) * TORQUE
    x, applied = np.zeros(2), np.zeros(2)
    rows = []
    for k in range(samples):
        angle = theta0 + omega * k * H
        rotor = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        measured = phases @ rotor @ x + noise * rng.standard_normal(3)
        i_dq = rotor.T @ (phases.T @ measured) * (2.0 / 3.0)
        torque = levels[int(k * H / 0.01) % 4]
        w = np.array([omega * phi, torque])
        u = -(i_dq - np.array([0.0, 2.0 * torque / (3 * p * phi)])) + np.array([0.0, w[0]])
        u = u + rng.uniform(-10.8, 10.8, 2)
        rows.append(np.concatenate([[k * H], i_dq, u, w, [angle % (2.0 * np.pi)]]))
        for j in range(steps):
            turn = angle + omega * j * H / steps
            rotor = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
            signs = np.sign(phases @ rotor @ x)
            error = -v * (2.0 / 3.0) * rotor.T @ (phases.T @ signs)
            x = step @ x + gain @ (applied + np.array([0.0, -omega * phi]) + error)
        applied = u
    table = np.array(rows)
    return Trajectory(t=table[:, 0], x=table[:, 1:3], u=table[:, 3:5], w=table[:, 5:7],
                      angle=table[:, 7])  # fmt: skip


def test_dead_time_switching_within_the_sample_is_told_from_switching_at_it() -> None:
    shift = 1  # the commanded voltage of a drive with a one-sample delay
    assert with_dead_time([_log(4000, 7)], None, shift).switching == "sample"
    assert with_dead_time([_subsample_log(4000, 7, 0.01)], None, shift).switching == "path"


def test_dead_time_switching_within_the_sample_is_learned_within_its_errors() -> None:
    # An inverter whose legs switch with their currents' own signs within the sample (the
    # physics; the library's simulator holds the sample's signs): with the signs at the
    # samples only, U was 13.5% off under a stated 2.6% (5.2 standard errors) and K 1.9%
    # under 0.7%. The signs averaged along the current's path explain it.
    result, truth = _learned(_subsample_log(20000, 3, 0.01), "rotor", "identify")
    quality = result.quality
    # the block criterion (the norms of each block's error and standard errors)
    K_se = quality.K_se[:, : truth.K.shape[1]]
    assert np.linalg.norm(result.K - truth.K) <= 3.0 * np.linalg.norm(K_se)
    assert np.linalg.norm(result.U - truth.U) <= 3.0 * np.linalg.norm(quality.U_se)


def _small_motor_on_48_volts(seed: int) -> tuple[IPMSM, DriveSettings, TuningSettings]:
    """A 25 uH, 0.02 ohm interior motor on 48 V with the hardware-like drive's 2 V of dead
    time (4.2 us), 20 K warm: the dead-time voltage is about 25 times the resistive drop
    and the noise decides the signs near zero current."""
    motor = IPMSM(R_s=0.02, L_d=25e-6, L_q=50e-6, phi_pm=0.005, p=10)
    drive = replace(DriveSettings.hardware_like(dc_voltage=48.0), temperature_rise=20.0)
    config = MotorConfig(
        motor=motor, speed=15.0, torque=0.3, drive=drive, drive_h=H,
        learning={"integral_action": True}, source="test",
    )  # fmt: skip
    return motor, drive, tuning_settings(config, seed)


def test_a_fit_carried_by_the_measured_signs_is_refused_not_returned() -> None:
    """Seed 1 of that motor: the fit explains the log only through the measured signs, and
    the next sample's signs do not explain it either. Before this refusal the
    commissioning returned R_s 62-71% high and L_d 3-5% low at 4-6 standard errors (seeds
    0 and 2, at 2% of the bus of exploration); now the cause is named. (At an interior
    motor's 3%, seeds 1 and 4 are refused so, and 0, 2 and 3 learned within 1.2 standard
    errors.)"""
    motor, drive, settings = _small_motor_on_48_volts(1)
    with pytest.raises(selftune.ModelMissesEffect, match="only through the measured currents'"):
        commission_interior(motor, settings, drive, seed=1)


def test_a_fit_carried_by_the_measured_signs_is_learned_on_the_next_samples_signs() -> None:
    """Seed 2 of that motor, refused as seed 0 is until the next sample's signs were tried:
    on them the fit explains the data, and its motor is within its errors of the heated
    truth (seeds 2-4: every parameter within 0.19% and 1.3 standard errors)."""
    motor, drive, settings = _small_motor_on_48_volts(2)
    result = commission_interior(motor, settings, drive, seed=2)
    hot = heated_motor(motor, drive.temperature_rise)
    for name in ("R_s", "L_d", "L_q", "phi_pm"):
        error = getattr(result.motor, name) - getattr(hot, name)
        assert abs(error) <= 3.0 * result.standard_errors[name], name
    assert result.learned.quality is not None
    assert any("as the next sample shows them" in note for note in result.learned.quality.notes)


@pytest.mark.parametrize("seed", [3, 5])
def test_a_level_whose_measured_signs_bias_it_is_learned_on_the_next_samples_signs(
    seed: int,
) -> None:
    """A 0.6/1.2 mH interior motor at 10% of rated torque, ``w_e h`` = 0.125, on 300 V with
    2 us of dead time (6 V): the dead time moves the current about 0.9 A a sample against
    1.2 A rms of phase current and chatters it about zero (the true phase currents change
    sign in 37% of the samples), and the noise and the ADC make 1.2% of the samples' measured
    signs wrong, each a 12 V error for a sample. On the measured signs seed 3 passed every
    test with R_s 0.53 ohm against 0.1 (7.9 standard errors) and seed 5 with 0.53 (10.6):
    their own simulations departed from the currents by 0.44-0.49 of their spread, where
    the signs' bias is not measured. On the signs the next sample shows the fit explains
    the data (departure 0.01-0.02), and it is the one reported, with a note."""
    motor = IPMSM(R_s=0.1, L_d=0.6e-3, L_q=1.2e-3, phi_pm=0.04, p=5)
    drive = replace(DriveSettings.hardware_like(dc_voltage=300.0), pwm="average", dead_time=2e-6)
    config = MotorConfig(
        motor=motor, speed=250.0, torque=3.0, drive=drive, drive_h=H,
        learning={"integral_action": True}, source="test",
    )  # fmt: skip
    level = learn_level(motor, None, tuning_settings(config, seed), drive, 0.1, seed=seed)
    truth = np.array([motor.R_s, motor.L_d, motor.L_q])
    assert np.all(np.abs(level.theta[:3] - truth) <= 3.0 * level.standard_errors[:3])
    assert level.learned.quality is not None
    assert any("as the next sample shows them" in note for note in level.learned.quality.notes)
