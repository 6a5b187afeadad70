"""An experiment that drives the current beyond the ADC's full scale (by more than
:data:`~selftune.tuning._interior.CLIP_TOLERANCE` of it) is refused, naming the current and
the scale (:func:`selftune.tuning.check_current_range`), not learned from clipped readings.

At twice the interior bench's speed (``w_e h`` = 0.08), the 2/5 mH motor's experiment under
K0 alone against the back-EMF reached 62-70 A on a +-50 A ADC; before the check the
clipped log was learned with L_d 1.6-2.3% and the flux 1.4-2.1% high (torque errors
1.3-1.8%). The interior commissioning now feeds the back-EMF and the cross-coupling
forward and stays in range; the ramp still runs under K0 alone.
"""

from __future__ import annotations

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
    """The ramp runs under K0 alone: at 200 rad/s the back-EMF drives 8 times the rated
    current."""
    with pytest.raises(CurrentOverrange, match=r"the ramp from 10 to 200 rad/s drove") as caught:
        commission_ramp(MOTOR, _settings(DRIVE), DRIVE, (10.0, SPEED), seconds=1.0, seed=1)
    assert caught.value.peak > 1.05 * caught.value.full_scale
    assert "adc_range = 50 A" in str(caught.value) and "[learning] K0" in str(caught.value)
    assert "\n" not in str(caught.value)


def test_the_commissioning_at_that_speed_stays_in_range_and_is_learned() -> None:
    """The commissioning feeds the back-EMF and the cross-coupling forward: its currents
    follow their references, and the motor is learned (under K0 alone it reached 62-66 A
    and was refused)."""
    result = commission_interior(MOTOR, _settings(DRIVE), DRIVE, seed=1)
    for name in ("L_d", "L_q", "phi_pm"):
        assert getattr(result.motor, name) == pytest.approx(getattr(MOTOR, name), rel=5e-3)
