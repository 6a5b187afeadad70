"""An experiment that drives the current beyond the ADC's full scale (by more than
:data:`~selftune.tuning._interior.CLIP_TOLERANCE` of it) is refused, naming the current and
the scale (:func:`selftune.tuning.check_current_range`), not learned from clipped readings.

At twice the interior bench's speed (``w_e h`` = 0.08), the 2/5 mH motor's experiment under
K0 alone against the back-EMF reached 62-66 A on a +-50 A ADC; before the check the
clipped log was learned with L_d 1.6-2.3% and the flux 1.4-2.1% high (torque errors
1.3-1.8%). The same experiment on an ADC of +-500 A is learned within 0.5%.
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


def test_an_experiment_beyond_the_adc_range_is_refused_naming_it() -> None:
    with pytest.raises(
        CurrentOverrange, match=r"beyond the ADC's full scale adc_range = 50 A"
    ) as caught:
        commission_interior(MOTOR, _settings(DRIVE), DRIVE, seed=1)
    assert caught.value.peak > caught.value.full_scale == 50.0
    assert "at 200 rad/s" in str(caught.value) and "\n" not in str(caught.value)
    assert "[learning] K0" in str(caught.value)


def test_the_same_experiment_within_the_range_is_learned() -> None:
    drive = replace(DRIVE, adc_range=500.0)
    result = commission_interior(MOTOR, _settings(drive), drive, seed=1)
    for name in ("L_d", "L_q", "phi_pm"):
        assert getattr(result.motor, name) == pytest.approx(getattr(MOTOR, name), rel=5e-3)


def test_a_ramp_beyond_the_adc_range_is_refused_naming_it() -> None:
    with pytest.raises(CurrentOverrange, match=r"the ramp from 10 to 200 rad/s drove"):
        commission_ramp(MOTOR, _settings(DRIVE), DRIVE, (10.0, SPEED), seconds=1.0, seed=1)
