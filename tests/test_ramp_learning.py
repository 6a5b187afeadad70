"""Learning the motor from a log over several speeds (:mod:`selftune.tuning._ramp`), and
the schedule refused outside the speeds the data cover.

The fit is checked against the truth on hypothesis-drawn motors across the issue's range
(surface and interior, ``L_q / L_d`` up to 3, 25 uH to 100 mH, 2 to 20 pole pairs) from
1 s of a two-speed staircase at 5% and 100% of the rated speed on a drive with a
one-sample delay, 10 mA of noise and the stationary hold (average PWM, no dead time:
the dead-time model's refusals are another matter, measured in bench/_ramp.py): each
parameter within 4 standard errors, and the schedule designed on the identified motor
within 1% of the true motor's pointwise digital optimum at 50 speeds between its grid
speeds.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import Phase, given, settings
from hypothesis import strategies as st

from selftune.config import MotorConfig
from selftune.core import ControlLaw
from selftune.errors import InputError
from selftune.learn import Trajectory
from selftune.model import EXCESS, IPMSM, SPMSM, Motor, design_schedule
from selftune.sim import DriveSettings, constant, ramp_speeds, run_speed_profile
from selftune.tuning import tuning_settings
from selftune.tuning._ramp import MIN_SEGMENT, commission_ramp, speed_segments

H = 1e-4
MOTOR = IPMSM(R_s=0.2, L_d=2e-3, L_q=5e-3, phi_pm=0.1, p=4)


def staircase_log(speeds: np.ndarray) -> Trajectory:
    """The drive over ``speeds`` (one per sample) under a small proportional law."""
    law = ControlLaw.regulator(
        0.2 * np.diag([MOTOR.L_d, MOTOR.L_q]) / H, np.zeros((2, 3)), np.zeros((2, 3))
    )
    record = run_speed_profile(
        MOTOR, speeds, H, DriveSettings(), law, constant([0.0, 0.0, 0.0]), exploration=None,
        seed=0,
    )  # fmt: skip
    return record.trajectory


def test_a_staircase_is_cut_at_its_speeds() -> None:
    speeds = ramp_speeds(10.0, 100.0, 1500, levels=3)
    segments = speed_segments(staircase_log(speeds), H)
    assert [(a, b) for a, b, _ in segments] == [(0, 500), (500, 1000), (1000, 1500)]
    np.testing.assert_allclose(
        [speed for _, _, speed in segments], [4 * 10.0, 4 * 55.0, 4 * 100.0], rtol=1e-9
    )


def test_a_speed_that_changes_every_sample_is_refused_saying_why() -> None:
    log = staircase_log(ramp_speeds(10.0, 100.0, 1500))
    with pytest.raises(InputError, match=r"changes every sample.*staircase"):
        speed_segments(log, H)
    short = ramp_speeds(10.0, 100.0, round(3 * MIN_SEGMENT / H), levels=6)
    with pytest.raises(InputError, match=f"at least {MIN_SEGMENT:g} s"):
        speed_segments(staircase_log(short), H)


def test_speeds_the_data_do_not_cover_are_refused_by_name() -> None:
    Q, R = 1e3 * np.eye(2), np.eye(2)
    covered = (4 * 5.0, 4 * 100.0)  # electrical
    design = design_schedule(MOTOR, [5.0, 100.0], Q, R, H, covered=covered)
    assert design.schedule.covered == covered
    with pytest.raises(InputError, match=r"speeds: 4, 600 rad/s \(electrical\) outside the "
                       r"speeds the data cover, 20 to 400 rad/s"):  # fmt: skip
        design_schedule(MOTOR, [1.0, 50.0, 150.0], Q, R, H, covered=covered)


@st.composite
def drawn_motors(draw: st.DrawFn) -> tuple[Motor, float, float]:
    """A motor across the issue's range, its rated mechanical speed and torque."""
    L_d = 10 ** draw(st.floats(np.log10(25e-6), -1.0))
    ratio = draw(st.sampled_from([1.0, draw(st.floats(1.2, 3.0))]))
    tau = 10 ** draw(st.floats(-3.0, -1.0))  # L / R, s
    p = draw(st.integers(2, 20))
    w_e = 10 ** draw(st.floats(np.log10(300.0), np.log10(2000.0)))  # rated, rad/s
    phi = 60.0 / w_e  # 60 V of back-EMF at rated speed on a 540 V bus
    current = 0.5 * np.sqrt(1e-3 / L_d)  # from 0.5 A at 1 mH: the noise's 10 mA small
    if ratio == 1.0:
        motor: Motor = SPMSM(R_s=L_d / tau, L_s=L_d, phi_pm=phi, p=p)
    else:
        motor = IPMSM(R_s=L_d / tau, L_d=L_d, L_q=ratio * L_d, phi_pm=phi, p=p)
    return motor, w_e / p, 1.5 * p * phi * current


DRIVE = DriveSettings(current_noise=0.01, dc_voltage=540.0)


@settings(max_examples=4, deadline=None, phases=[Phase.explicit, Phase.reuse, Phase.generate])
@given(drawn_motors(), st.integers(0, 1000))
def test_a_two_speed_log_gives_the_motor_and_its_schedule(
    drawn: tuple[Motor, float, float], seed: int
) -> None:
    motor, speed, torque = drawn
    config = MotorConfig(
        motor=motor, speed=speed, torque=torque, drive=DRIVE, drive_h=H,
        learning={"integral_action": True}, source="drawn",
    )  # fmt: skip
    tuning = tuning_settings(config, seed)  # (no shrinking: an example takes seconds)
    speeds = (0.05 * speed, speed)
    result = commission_ramp(motor, tuning, DRIVE, speeds, seed=seed, levels=2)
    np.testing.assert_allclose(result.covered, np.array(speeds) * motor.p, rtol=1e-9)
    for name, se in result.standard_errors.items():
        error = getattr(result.motor, name) - getattr(motor, name)
        assert abs(error) <= 4.0 * se, (name, error, se)
    designs = [
        design_schedule(
            model,
            speeds,
            tuning.Q,
            tuning.R,
            H,
            integral_weight=result.integral_weight,
            hold=DRIVE.voltage_hold,
        )
        for model in (result.motor, motor)
    ]
    assert float(np.max(designs[1].excess_of(designs[0].schedule))) <= EXCESS
