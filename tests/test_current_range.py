"""An experiment that drives the current beyond the ADC's full scale (by more than
:data:`~selftune.tuning._interior.CLIP_TOLERANCE` of it) is refused, naming the current and
the scale (:func:`selftune.tuning.check_current_range`), not learned from clipped readings.

At twice the interior bench's speed (``w_e h`` = 0.08), the 2/5 mH motor's experiment under
K0 alone against the back-EMF reached 62-70 A on a +-50 A ADC; before the check the
clipped log was learned with L_d 1.6-2.3% and the flux 1.4-2.1% high (torque errors
1.3-1.8%). The interior commissioning now feeds the back-EMF and the cross-coupling
forward and stays in range, and so does the ramp, with each held speed's feedforward.
"""

from __future__ import annotations

from dataclasses import replace

import pytest

from selftune.config import MotorConfig
from selftune.errors import CurrentOverrange
from selftune.model import IPMSM
from selftune.sim import DriveSettings
from selftune.tuning import (
    TuningSettings,
    commission_interior,
    commission_ramp,
    tuning_settings,
)

MOTOR = IPMSM(R_s=0.2, L_d=2e-3, L_q=5e-3, phi_pm=0.1, p=4)
SPEED = 200.0  # mechanical rad/s: w_e h = 0.08 at 10 kHz
TORQUE = 5.0  # N m: 8.3 A of q current with the nameplate flux
DRIVE = DriveSettings(input_delay=1, current_noise=0.01, adc_bits=12, adc_range=50.0)


def _settings(drive: DriveSettings, seed: int = 1) -> TuningSettings:
    config = MotorConfig(
        motor=MOTOR, speed=SPEED, torque=TORQUE, drive=drive, drive_h=1e-4,
        learning={"integral_action": True}, source="test",
    )  # fmt: skip
    return tuning_settings(config, seed)


def test_a_ramp_beyond_the_adc_range_is_refused_naming_it() -> None:
    """With each held speed's feedforward the ramp's currents follow their references (up
    to 8.3 A of q current and half of it in d), in range at +-50 A and learned; an ADC of
    +-10 A clips the steps' transients."""
    learned = commission_ramp(
        MOTOR, _settings(DRIVE), DRIVE, (10.0, SPEED), seconds=1.0, levels=4, seed=1
    )
    for name in ("L_d", "L_q", "phi_pm"):
        assert getattr(learned.motor, name) == pytest.approx(getattr(MOTOR, name), rel=5e-3)
    small = replace(DRIVE, adc_range=10.0)
    with pytest.raises(CurrentOverrange, match=r"the ramp from 10 to 200 rad/s drove") as caught:
        commission_ramp(
            MOTOR, _settings(small), small, (10.0, SPEED), seconds=1.0, levels=4, seed=1
        )
    assert caught.value.peak > 1.05 * caught.value.full_scale
    message = str(caught.value)
    assert "adc_range = 10 A" in message and "[learning] exploration" in message
    assert "\n" not in message


def test_the_commissioning_at_that_speed_stays_in_range_and_is_learned() -> None:
    """The commissioning feeds the back-EMF and the cross-coupling forward: its currents
    follow their references, and the motor is learned (under K0 alone it reached 62-66 A
    and was refused)."""
    result = commission_interior(MOTOR, _settings(DRIVE), DRIVE, seed=1)
    for name in ("L_d", "L_q", "phi_pm"):
        assert getattr(result.motor, name) == pytest.approx(getattr(MOTOR, name), rel=5e-3)
