"""The realistic drive over a speed profile (:func:`selftune.sim.run_speed_profile`).

A profile of one speed is the drive's own record to the bit; a ramp's currents are an
independent numerical integration's (scipy's ``solve_ivp``, DOP853, at tight tolerances)
of the dq model with the rotor angle integrated as a third state, the speed held within
each sample (the stated approximation), over the drive's own voltages; and the log's angle
column is that integrated angle.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from selftune.core import ControlLaw
from selftune.errors import InputError
from selftune.model import IPMSM, SPMSM, Motor
from selftune.sim import (
    DriveSettings,
    RealisticDrive,
    constant,
    held,
    ramp_speeds,
    run_speed_profile,
    uniform,
)
from selftune.sim._inverter import heated_motor, phasor_mean

Array = NDArray[np.float64]
H = 1e-4
SALIENT = IPMSM(R_s=0.2, L_d=2e-3, L_q=6e-3, phi_pm=0.05, p=4)
SURFACE = SPMSM.paper()
HARDWARE = DriveSettings.hardware_like()
AVERAGE_DEAD_TIME = dataclasses.replace(
    HARDWARE, pwm="average", current_noise=0.0, temperature_rise=20.0
)


def law_for(motor: Motor, speed: float) -> ControlLaw:
    """Feedforward of the regulation form at ``speed``, a quarter of the dead-beat
    proportional gains, integral action."""
    problem = motor.regulation_problem(speed)
    X = -problem.F
    U = -np.linalg.solve(problem.B, problem.A @ X + problem.D)
    K = 0.25 * np.diag([motor.L_d, motor.L_q]) / H
    return ControlLaw(K, X, U, K_i=20.0 * K, C=np.eye(2), F=-X, h=H)


@pytest.mark.parametrize("motor", [SALIENT, SURFACE], ids=["interior", "surface"])
@pytest.mark.parametrize(
    "settings",
    [DriveSettings(), AVERAGE_DEAD_TIME, HARDWARE],
    ids=["average", "dead time", "hardware"],
)
def test_one_speed_is_the_drives_record(motor: Motor, settings: DriveSettings) -> None:
    speed = 100.0
    law, w = law_for(motor, speed), motor.exogenous(speed, 1.0)
    drive = RealisticDrive(motor, speed, H, settings)
    held = drive.record(law, constant(w), num_samples=600, exploration=uniform(3.0), seed=5)
    profile = run_speed_profile(
        motor, np.full(600, speed), H, settings, law, constant(w), exploration=uniform(3.0),
        seed=5,
    )  # fmt: skip
    for name in ("true_currents", "applied_voltages", "commanded_voltages", "torque"):
        assert np.array_equal(getattr(profile, name), getattr(held, name)), name
    for name in ("x", "u", "w", "angle"):
        assert np.array_equal(getattr(profile.trajectory, name), getattr(held.trajectory, name))


def integrate(motor: IPMSM, speeds: Array, held: NDArray[np.complex128]) -> tuple[Array, Array]:
    """The rotor-frame currents and the angle at each sample's end from rest: the motor's
    dq model ``L_d di_d/dt = -R_s i_d + w_e L_q i_q + u_d``, ``L_q di_q/dt = -R_s i_q -
    w_e L_d i_d - w_e phi_pm + u_q`` with ``u = exp(-j theta) V`` of the stationary vector
    V held over each sample and ``dtheta/dt = w_e`` (electrical speed ``p speeds[k]`` over
    sample k), integrated by DOP853 at ``rtol = atol / 1 A = 1e-12``."""
    state, ends = np.zeros(3), []
    for k, (speed, V) in enumerate(zip(speeds, held, strict=True)):
        w_e = motor.p * speed

        def rate(t: float, y: Array, w_e: float = w_e, V: complex = complex(V)) -> Array:
            u = np.exp(-1j * y[2]) * V
            d = (-motor.R_s * y[0] + w_e * motor.L_q * y[1] + u.real) / motor.L_d
            q = -motor.R_s * y[1] - w_e * motor.L_d * y[0] - w_e * motor.phi_pm + u.imag
            return np.array([d, q / motor.L_q, w_e])

        solution = solve_ivp(
            rate, (k * H, (k + 1) * H), state, method="DOP853", rtol=1e-12, atol=1e-12
        )
        state = solution.y[:, -1]
        ends.append(state)
    path = np.array(ends)
    return path[:, :2], path[:, 2]


#: DOP853 at rtol = atol / 1 A = 1e-12 per sample, over 600 samples whose errors the
#: motor's decay (L / R = 10 to 30 ms) forgets, as tests/test_salient_drive.py bounds them.
INTEGRATION_AGREES = 1e-11


@pytest.mark.parametrize("levels", [None, 6], ids=["linear", "staircase"])
@pytest.mark.parametrize("motor", [SALIENT, SURFACE], ids=["interior", "surface"])
def test_a_ramp_is_the_integrated_motor(motor: Motor, levels: int | None) -> None:
    """From ``w_e h`` = 0.02 to 0.3 over 600 samples, average PWM with dead time, the motor
    20 K warm: the stationary vector held over sample k is the mean dq voltage turned
    back, ``applied_k exp(j theta_k) / mean(exp(-j w_e s))``."""
    count = 600
    speeds = ramp_speeds(0.02 / (motor.p * H), 0.3 / (motor.p * H), count, levels)
    top = float(speeds[-1])
    law = law_for(motor, top)
    record = run_speed_profile(
        motor, speeds, H, AVERAGE_DEAD_TIME, law, constant(motor.exogenous(top, 1.0)),
        exploration=uniform(3.0), seed=5,
    )  # fmt: skip
    truth = heated_motor(motor, AVERAGE_DEAD_TIME.temperature_rise)
    as_interior = IPMSM(R_s=truth.R_s, L_d=truth.L_d, L_q=truth.L_q, phi_pm=truth.phi_pm, p=truth.p)
    w_e = motor.p * speeds
    theta = np.concatenate([[0.0], np.cumsum(w_e * H)])
    applied = record.applied_voltages[:, 0] + 1j * record.applied_voltages[:, 1]
    held = applied * np.exp(1j * theta[:-1]) / phasor_mean(w_e * H)
    currents, angle = integrate(as_interior, speeds, held)
    scale = np.max(np.abs(record.true_currents))
    assert scale > 0.5
    np.testing.assert_allclose(
        record.true_currents[1:], currents, rtol=0, atol=INTEGRATION_AGREES * scale
    )
    logged = record.trajectory.angle
    assert logged is not None
    np.testing.assert_allclose(np.exp(1j * logged[1:]), np.exp(1j * angle), rtol=0, atol=1e-11)


def test_a_law_per_speed_is_called_at_each_held_speed_and_its_state_carries_over() -> None:
    """A function of the speed gives the law over each run of equal speeds: the
    feedforward following the speed. Given the same law at every speed, the record is
    the law's own to the bit; a law whose state differs is refused naming the speed."""
    motor, count = SALIENT, 600
    speeds = ramp_speeds(20.0, 200.0, count, 3)
    w = constant(motor.exogenous(200.0, 1.0))
    fixed = law_for(motor, 200.0)
    asked: list[float] = []

    def same(speed: float) -> ControlLaw:
        asked.append(speed)
        return fixed

    records = [
        run_speed_profile(motor, speeds, H, HARDWARE, law, w, exploration=uniform(3.0), seed=5)
        for law in (fixed, same)
    ]
    assert asked == [20.0, 110.0, 200.0]
    for name in ("true_currents", "applied_voltages", "commanded_voltages"):
        assert np.array_equal(getattr(records[0], name), getattr(records[1], name)), name

    # each speed's own law from the first sample at that speed: the first level is the
    # run under the lowest speed's law alone to the bit, up to the second level
    def exogenous(t: Array) -> Array:  # w_1 following the speed
        rows = np.minimum(np.round(t / H).astype(int), count - 1)
        return np.array([motor.exogenous(speed, 1.0) for speed in speeds[rows]])

    following, lowest = (
        run_speed_profile(
            motor, speeds, H, HARDWARE, law, held(exogenous), exploration=uniform(3.0), seed=5
        )
        for law in (lambda speed: law_for(motor, speed), law_for(motor, 20.0))
    )
    change = count // 3  # the second level's first sample
    ours, theirs = following.commanded_voltages, lowest.commanded_voltages  # (N, 2)
    assert np.array_equal(ours[:change], theirs[:change])
    assert not np.array_equal(ours[change], theirs[change])

    def changing(speed: float) -> ControlLaw:
        return fixed if speed < 100.0 else ControlLaw.regulator(fixed.K, fixed.X, fixed.U)

    with pytest.raises(InputError, match="at 110 rad/s"):
        run_speed_profile(motor, speeds, H, HARDWARE, changing, w, exploration=None, seed=5)


def test_ramp_speeds() -> None:
    linear = ramp_speeds(5.0, 100.0, 11)
    np.testing.assert_allclose(linear, np.linspace(5.0, 100.0, 11))
    stairs = ramp_speeds(5.0, 100.0, 10, levels=3)
    assert stairs.tolist() == [5.0] * 4 + [52.5] * 3 + [100.0] * 3
    with pytest.raises(InputError, match="levels"):
        ramp_speeds(5.0, 100.0, 2, levels=3)
