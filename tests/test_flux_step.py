"""Algorithm 3's flux step at speed: 100 to 5,000 rad/s electrical, on drives that hold
their voltage in the stationary frame (PWM) with a one-sample delay, carrier PWM and dead
time, at 10 and 20 kHz.

The motors are ones for which those speeds are physical, each on a bus whose linear range
its back-EMF stays well inside: the paper's motor at low speed, a 540 V motor of a few mH
in the middle, a low-inductance motor (0.08 ohm, 0.9 mH, 10 mWb) at the top. The truth is
the simulated motor's flux at the drive's temperature (selftune.report.true_motor) and the
optimum of the same sampled loop (selftune.report.evaluate); each identified value must lie
within three of its own stated standard errors of it."""

from __future__ import annotations

from dataclasses import replace

import pytest

from selftune import SPMSM, ModelMissesEffect, MotorConfig
from selftune.report import evaluate, true_motor
from selftune.sim import DriveSettings, RealisticDrive
from selftune.tuning import TuningSettings, run_algorithm, tuning_settings
from selftune.tuning._flux import identify_flux

PAPER = SPMSM(R_s=0.439, L_s=0.0601, phi_pm=0.46, p=2)
MIDDLE = SPMSM(R_s=0.9, L_s=3e-3, phi_pm=0.08, p=4)
LOW_INDUCTANCE = SPMSM(R_s=0.08, L_s=0.9e-3, phi_pm=0.010, p=4)

#: How many stated standard errors an identified value may be from the truth.
STANDARD_ERRORS = 3.0

#: The current of the operating point, A.
CURRENT = 5.0


def session(
    motor: SPMSM, electrical_speed: float, frequency: float, dc_voltage: float, **learning: object
) -> tuple[TuningSettings, DriveSettings]:
    """The settings `selftune tune` uses for this motor on a hardware-like drive of this
    switching frequency and bus (one-sample delay, carrier PWM, dead time, noise, ADC)."""
    h = 1.0 / frequency
    drive = DriveSettings.hardware_like(dc_voltage=dc_voltage, h=h)
    config = MotorConfig(
        motor=motor,
        speed=electrical_speed / motor.p,
        torque=float(motor.torque(CURRENT)),
        learning=learning,
        source="test",
        drive=drive,
        drive_h=h,
    )
    return tuning_settings(config), drive


def flux_within_its_errors(
    motor: SPMSM, electrical_speed: float, frequency: float, dc_voltage: float
) -> None:
    settings, drive = session(motor, electrical_speed, frequency, dc_voltage)
    plant = RealisticDrive(motor, settings.speed, settings.h, drive)
    flux = identify_flux(plant, settings, motor.phi_pm)
    truth = true_motor(motor, drive).phi_pm
    assert abs(flux.phi_pm - truth) <= STANDARD_ERRORS * flux.standard_error, (
        flux.phi_pm / truth - 1.0,
        flux.standard_error / truth,
    )


# (motor, electrical speed rad/s, V_dc): back-EMF at most 40% of the linear range V_dc/sqrt(3)
SPEEDS = [
    pytest.param(PAPER, 100.0, 540.0, id="paper-100"),
    pytest.param(PAPER, 300.0, 540.0, id="paper-300"),
    pytest.param(MIDDLE, 1000.0, 540.0, id="middle-1000"),
    pytest.param(MIDDLE, 2500.0, 540.0, id="middle-2500"),
    pytest.param(LOW_INDUCTANCE, 2500.0, 150.0, id="low-inductance-2500"),
    # K0 (1.25% of L_s/h) against w_e L_s = 20-40 K0, and 3 V of exploration against
    # 4.5 ohm, leave the currents at 0.2-0.3 A, where the dead-time model's phase signs are
    # the noise's: refused (consistency 413 against 97.65) until the model was judged on
    # the signs the next sample shows; now learned, 0.085% low at 1.0 standard error
    pytest.param(LOW_INDUCTANCE, 5000.0, 150.0, id="low-inductance-5000"),
]

#: At 20 kHz the 5,000 rad/s log is still refused (consistency 565 against 97.65).
SPEEDS_20_KHZ = [
    *SPEEDS[:-1],
    pytest.param(
        LOW_INDUCTANCE, 5000.0, 150.0, id="low-inductance-5000",
        marks=pytest.mark.xfail(
            raises=ModelMissesEffect, strict=True,
            reason="the currents of 0.2-0.3 A leave the phase signs to the noise, and neither "
            "the model's own signs nor the next sample's explain the log at 20 kHz",
        ),
    ),
]  # fmt: skip


@pytest.mark.parametrize(("motor", "electrical_speed", "dc_voltage"), SPEEDS)
def test_the_flux_step_finds_the_flux_within_its_errors_at_10_kHz(
    motor: SPMSM, electrical_speed: float, dc_voltage: float
) -> None:
    flux_within_its_errors(motor, electrical_speed, 10e3, dc_voltage)


@pytest.mark.slow  # the same at twice the samples; the 10 kHz cases cover the mechanism
@pytest.mark.parametrize(("motor", "electrical_speed", "dc_voltage"), SPEEDS_20_KHZ)
def test_the_flux_step_finds_the_flux_within_its_errors_at_20_kHz(
    motor: SPMSM, electrical_speed: float, dc_voltage: float
) -> None:
    flux_within_its_errors(motor, electrical_speed, 20e3, dc_voltage)


@pytest.mark.parametrize("hold", ["stationary", "rotor"])
@pytest.mark.parametrize("electrical_speed", [1250.0, 2500.0, 5000.0])
def test_the_flux_step_is_exact_on_noise_free_data_whatever_the_hold(
    electrical_speed: float, hold: str
) -> None:
    # A PWM inverter holds its voltage in the stationary frame while the back-EMF is
    # constant in dq: Bd^-1 Ed is then (sin(w_e h/2) / (w_e h/2)) times B^-1 D, and the
    # flux read as if it were B^-1 D came out (w_e h)^2 / 24 low (1.0% at w_e h = 0.5).
    motor = LOW_INDUCTANCE
    drive = replace(DriveSettings(input_delay=1, dc_voltage=150.0), voltage_hold=hold)
    settings, _ = session(motor, electrical_speed, 10e3, 150.0, dead_time=False)
    plant = RealisticDrive(motor, settings.speed, settings.h, drive)
    flux = identify_flux(plant, settings, motor.phi_pm)
    assert abs(flux.phi_pm / motor.phi_pm - 1.0) <= 1e-9  # rounding: the model is exact


def test_algorithm_3_at_speed_learns_the_optimum_within_its_errors() -> None:
    # 2,500 rad/s at 10 kHz: w_e h = 0.25, where the flux came out 54 standard errors low
    motor, electrical_speed, dc_voltage = MIDDLE, 2500.0, 540.0
    _check_algorithm_3(motor, electrical_speed, 10e3, dc_voltage)


@pytest.mark.slow  # whole sessions (the paper's motor: 15-30 s each)
@pytest.mark.parametrize("frequency", [10e3, 20e3])
@pytest.mark.parametrize(
    ("motor", "electrical_speed", "dc_voltage"),
    [
        pytest.param(PAPER, 100.0, 540.0, id="paper-100"),
        pytest.param(PAPER, 300.0, 540.0, id="paper-300"),
        pytest.param(MIDDLE, 1000.0, 540.0, id="middle-1000"),
    ],
)
def test_algorithm_3_over_the_speeds_learns_the_optimum_within_its_errors(
    motor: SPMSM, electrical_speed: float, dc_voltage: float, frequency: float
) -> None:
    _check_algorithm_3(motor, electrical_speed, frequency, dc_voltage)


def _check_algorithm_3(
    motor: SPMSM, electrical_speed: float, frequency: float, dc_voltage: float
) -> None:
    """Algorithm 3's flux, K and U each within their stated errors of the true drive's."""
    settings, drive = session(motor, electrical_speed, frequency, dc_voltage)
    result = run_algorithm("3", motor, settings, drive=drive)
    truth = true_motor(motor, drive).phi_pm
    flux, flux_se = result.identified["phi_pm"], result.identified["phi_pm_se"]
    assert abs(flux - truth) <= STANDARD_ERRORS * flux_se
    evaluation = evaluate(result, motor, settings, drive)
    assert evaluation.K_error <= STANDARD_ERRORS * result.quality.K_relative_se
    assert evaluation.U_error <= STANDARD_ERRORS * result.quality.U_relative_se
