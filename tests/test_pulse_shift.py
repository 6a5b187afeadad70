"""The dead time's late and short pulses in the identify-then-design learner's reported
error bars (:mod:`selftune.learn.evidence._pulses`).

On carrier PWM with dead time every pulse comes half the dead time late, which the
dead-time model's ``-v sign(i)`` does not carry: the flux of the three motors drawn here
came out 0.007-0.02% low at 4.6-6.4 standard errors (docs/schedule.md), within 0.3-2.7 on
average PWM with the same dead time. With the drive's DC bus the reported standard
errors hold the shift; the decisions (the law, its verdict) and the values do not move.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

import selftune.tuning._ramp as ramp_module
from selftune.bench._interior import BOTTOM_SPEED_SHARE, drawn_cases, study_drive
from selftune.config import MotorConfig
from selftune.errors import InputError
from selftune.learn import LearningOptions
from selftune.learn.evidence._dead_time import pulse_delay_gain
from selftune.model import SPMSM
from selftune.report._digital_evaluation import true_motor
from selftune.tuning import tuning_settings
from selftune.tuning._ramp import RampCommissioning, commission_ramp

#: Drawn motors of the ramp study (docs/schedule.md, ``drawn_cases(60, 11)``) whose flux
#: was low beyond 3 standard errors: a 0.79 mH surface motor on 540 V, a 40 uH one on
#: 48 V, a 1.2/3.7 mH interior one on 540 V.
DRAWN = (38, 45, 14)


def _ramp(number: int, with_bus: bool, monkeypatch: pytest.MonkeyPatch) -> tuple:  # type: ignore[type-arg]
    motor, speed, torque, bus, seed, adc_range = drawn_cases(60, 11)[number - 1]
    drive = study_drive(bus, adc_range)
    config = MotorConfig(
        motor=motor, speed=speed, torque=torque, drive=drive, drive_h=1e-4,
        learning={"integral_action": True}, source=f"drawn {number}",
    )  # fmt: skip
    settings = tuning_settings(config, seed)
    with monkeypatch.context() as patch:
        if not with_bus:  # what a learn file's log without the bus gives
            patch.setattr(ramp_module, "pulse_bus", lambda _: None)
        result = commission_ramp(
            motor, settings, drive, (BOTTOM_SPEED_SHARE * speed, speed), seconds=1.0, levels=2,
            seed=seed,
        )  # fmt: skip
    return result, true_motor(motor, drive), drive


def _names(result: RampCommissioning) -> tuple[str, ...]:
    return ("L_s", "phi_pm") if isinstance(result.motor, SPMSM) else ("L_d", "L_q", "phi_pm")


@pytest.mark.parametrize("number", DRAWN)
def test_the_reported_bars_hold_the_late_pulses_and_nothing_else_moves(
    number: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without the bus the flux is beyond 3 standard errors (the bias is there); with it
    every inductance and the flux are within 3 of the reported ones, the values, each
    part's law and its verdict's numbers are the same, and the standard errors only grow."""
    bare, truth, _ = _ramp(number, False, monkeypatch)
    result, _, _ = _ramp(number, True, monkeypatch)
    names = _names(result)
    z_bare = [(getattr(bare.motor, n) - getattr(truth, n)) / bare.standard_errors[n] for n in names]
    z = [(getattr(result.motor, n) - getattr(truth, n)) / result.standard_errors[n] for n in names]
    assert abs(z_bare[-1]) > 3.0, z_bare
    assert max(abs(value) for value in z) <= 3.0, z
    for name in (*names, "R_s"):
        assert getattr(result.motor, name) == getattr(bare.motor, name)
        assert result.standard_errors[name] >= bare.standard_errors[name]
    for (_, learned), (_, plain) in zip(result.segments, bare.segments, strict=True):
        assert learned.quality is not None and plain.quality is not None
        np.testing.assert_array_equal(learned.law.K, plain.law.K)
        np.testing.assert_array_equal(learned.law.U, plain.law.U)
        np.testing.assert_array_equal(learned.quality.U_se, plain.quality.U_se)
        assert learned.quality.stability_margin == plain.quality.stability_margin
        assert len(learned.quality.notes) == len(plain.quality.notes) + 1


def test_far_from_the_modulations_limit_a_surface_motors_shift_is_the_delays(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """No pulse is short below the limit, and a surface motor's voltage moving the
    current ``g`` times more (:func:`pulse_delay_gain`) is the held model with ``R_s``,
    ``L_s``, the back-EMF ratio and the dead-time voltage all divided by ``g``: the
    shift is ``(1 / g - 1)`` times each, at either speed."""
    result, _, drive = _ramp(DRAWN[0], True, monkeypatch)
    for _, learned in result.segments:
        assert learned.evidence is not None and learned.evidence.fit is not None
        theta = learned.evidence.fit.parameters  # R_s, L_s, kappa, v
        t_d = theta[3] * 1e-4 / drive.dc_voltage
        gain = pulse_delay_gain(float(theta[0]), float(theta[1]), t_d)
        assert learned.evidence.pulse_shift is not None
        np.testing.assert_allclose(
            learned.evidence.pulse_shift, (1.0 / gain - 1.0) * theta, rtol=0.02
        )


def test_a_bus_that_is_not_positive_is_refused_by_name() -> None:
    with pytest.raises(InputError, match="dc_voltage"):
        replace(LearningOptions(), dc_voltage=-48.0)
