"""The realistic drive against independent truth: the ideal drive, solve_ivp, closed forms.

Agreement found (paper motor at 100 rad/s, h = 100 us, 10 kHz):

- ideal settings vs SimulatedDrive (expm in dq, the other implementation): 9e-15 relative
  (7e-15 at the paper's 10 us);
- delay 1 and 2, angle compensation on and off, against the loop closed around solve_ivp
  (rtol 1e-11) of the stationary-frame ODE: 5e-14 relative; the derived exact data
  equation ``x_(k+1) = Ad x_k + (1 - a) / R_s Rot(eps - w_e h) u_k + Ed w``: 5e-15
  (the dq-hold Bd misses by 1.4e-6 with compensation, 2.5e-3 without, d = 1);
- carrier PWM: volt-seconds equal to the command to 6e-16 of ``V_dc h``; sampled
  currents equal to a segment-by-segment solve_ivp to 1e-14; average vs carrier with the
  same commands: 8.3e-8 A apart, within the bound ``e^(gamma h) (2/3 + 1/sqrt 3) gamma
  h^2 V_dc / (24 L_s)`` = 3.4e-5 A;
- dead time (2 V): mean dq error (4/pi) t_d f_sw V_dc to 4e-5 relative, 180.4 degrees
  from the current (the sign held over a sample lags by up to w_e h / 2 = 0.57 degrees);
  compensation leaves 0.052 V, 2% (its sign is d = 1 sample old: predicted
  ``(4/pi) V0 2 sin(w_e h / 2)`` = 0.051 V);
- noise: 1.003 and 0.997 of ``sqrt(2/3) current_noise`` on i_d and i_q over 20,000 samples.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from selftune import SPMSM, InputError
from selftune.core import ControlLaw, discretize
from selftune.learn import Trajectory
from selftune.sim import SimulatedDrive, constant, held, steps, uniform
from selftune.sim._inverter import CLARKE, CurrentSensor, carrier_segments, leg_duties, to_phases
from selftune.sim._realistic import DriveRecord, DriveSettings, RealisticDrive, run_drive_batch

Array = NDArray[np.float64]
MOTOR = SPMSM.paper()
H = 1e-4  # 10 kHz
SPEED = 100.0  # rad/s: w_e = 200 rad/s, 314 samples per electrical period
RTOL_IVP = 1e-11


def relative_error(actual: Array, expected: Array) -> float:
    return float(np.max(np.abs(actual - expected)) / max(1.0, float(np.max(np.abs(expected)))))


def feedforward(motor: SPMSM, speed: float) -> tuple[Array, Array]:
    """X, U of the known-flux regulation form (model-based)."""
    problem = motor.regulation_problem(speed)
    X = -problem.F
    U = -np.linalg.solve(problem.B, problem.A @ X + problem.D)
    return X, np.asarray(U, dtype=float)


def torque_for(motor: SPMSM, i_q: float) -> float:
    return 1.5 * motor.p * motor.phi_pm * i_q


def complex_of(pairs: Array) -> NDArray[np.complex128]:
    return pairs[..., 0] + 1j * pairs[..., 1]


def rotor(t: Array, motor: SPMSM = MOTOR, speed: float = SPEED) -> NDArray[np.complex128]:
    return np.exp(1j * motor.p * speed * t)


def delayed_law(gain: float = 30.0, motor: SPMSM = MOTOR, speed: float = SPEED) -> ControlLaw:
    """Feedback on x and on the one past command (history 1), with feedforward."""
    X, U = feedforward(motor, speed)
    K = np.hstack([gain * np.eye(2), 0.2 * np.eye(2)])
    return ControlLaw(K, X, U, history=1)


# -- exactness -----------------------------------------------------------------------------


@pytest.mark.parametrize("no_load", [False, True])
def test_ideal_settings_reproduce_the_simulated_drive(no_load: bool) -> None:
    K = 20.0 * np.pi * np.eye(2)
    ideal = RealisticDrive(MOTOR, SPEED, H, DriveSettings.ideal())
    exact = SimulatedDrive(MOTOR, SPEED, H)
    if no_load:
        law = ControlLaw.regulator(K, np.zeros((2, 1)), np.zeros((2, 1)))
        mine = ideal.run_no_load(law, num_samples=3000, exploration=uniform(1.0), seed=4)
        theirs = exact.run_no_load(law, num_samples=3000, exploration=uniform(1.0), seed=4)
    else:
        X, U = feedforward(MOTOR, SPEED)
        w0 = MOTOR.exogenous(SPEED, 10.0)  # w_1 must be the true back-EMF: it is physics here
        reference = held(lambda t: w0 + np.column_stack([0.0 * t, np.cos(3000.0 * t)]))
        mine = ideal.run(
            ControlLaw.regulator(K, X, U), reference, num_samples=3000,
            exploration=uniform(1.0), seed=4,
        )  # fmt: skip
        theirs = exact.run(
            ControlLaw.regulator(K, X, U), reference, num_samples=3000,
            exploration=uniform(1.0), seed=4,
        )  # fmt: skip
    assert relative_error(mine.x, theirs.x) < 1e-12
    assert relative_error(mine.u, theirs.u) < 1e-12
    assert mine.w is not None and theirs.w is not None
    np.testing.assert_array_equal(mine.w, theirs.w)


def closed_loop_ivp(
    law: ControlLaw, w: Array, rho: Array, delay: int, angle: Callable[[int], float]
) -> Array:
    """The loop integrated independently: solve_ivp of the stationary-frame ODE over each
    sample, the law applied to the ivp's own currents, the command computed at k applied
    over sample k + delay with the stationary angle ``angle(k)``."""
    motor, w_e = MOTOR, MOTOR.p * SPEED

    def field(voltage: complex) -> Callable[[float, Array], Array]:
        def rhs(t: float, i: Array) -> Array:
            emf = w_e * motor.phi_pm * np.array([-np.sin(w_e * t), np.cos(w_e * t)])
            v = np.array([voltage.real, voltage.imag])
            return (v - motor.R_s * i - emf) / motor.L_s

        return rhs

    count = rho.shape[0]
    i_ab, x = np.zeros(2), np.zeros((count + 1, 2))
    commands = np.zeros((count + 2, 2))  # commands[k + 2] computed at k
    for k in range(count + 1):
        dq = complex(i_ab[0], i_ab[1]) * np.exp(-1j * w_e * k * H)
        x[k] = [dq.real, dq.imag]
        if k == count:
            break
        past = commands[k + 2 - law.history : k + 2][np.newaxis]
        commands[k + 2] = law.command(x[k][np.newaxis], w[k][np.newaxis], past)[0] + rho[k]
        u = commands[k + 2 - delay]
        voltage = complex(u[0], u[1]) * np.exp(1j * angle(k - delay))
        span = (k * H, (k + 1) * H)
        solution = solve_ivp(field(voltage), span, i_ab, rtol=RTOL_IVP, atol=1e-13, method="DOP853")
        i_ab = solution.y[:, -1]
    return x


@pytest.mark.parametrize(("delay", "compensation"), [(1, True), (1, False), (2, True)])
def test_delayed_loop_against_solve_ivp(delay: int, compensation: bool) -> None:
    count, seed = 120, 7
    law = delayed_law()
    settings = DriveSettings(input_delay=delay, angle_compensation=compensation)
    w0 = MOTOR.exogenous(SPEED, 8.0)
    data = RealisticDrive(MOTOR, SPEED, H, settings).run(
        law, constant(w0), num_samples=count, exploration=uniform(2.0), seed=seed
    )
    t = H * np.arange(count + 1)
    rho = uniform(2.0).sample(t, 2, np.random.default_rng(seed))
    w_e = MOTOR.p * SPEED
    # the stationary angle of the command computed at j: theta_j + w_e (d + 1/2) h, or theta_j
    lead = (delay + 0.5) * w_e * H if compensation else 0.0
    x = closed_loop_ivp(law, np.tile(w0, (count + 1, 1)), rho, delay, lambda j: w_e * j * H + lead)
    assert relative_error(data.x, x) < 1e-10  # found 5e-14


@pytest.mark.parametrize(("delay", "compensation"), [(0, True), (1, True), (1, False), (2, False)])
def test_the_derived_exact_data_equation_holds(delay: int, compensation: bool) -> None:
    """``x_(k+1) = Ad x_k + (1 - a) / R_s Rot(eps - w_e h) u_k + Ed w`` with the applied
    log: the dq hold's Ad and Ed, the stationary hold's input matrix."""
    settings = DriveSettings(input_delay=delay, angle_compensation=compensation)
    w0 = MOTOR.exogenous(SPEED, 8.0)
    data = RealisticDrive(MOTOR, SPEED, H, settings).run(
        delayed_law(), constant(w0), num_samples=400, exploration=uniform(2.0), seed=1
    )
    problem = MOTOR.regulation_problem(SPEED)
    exact = discretize(problem.A, problem.B, H, D=problem.D)
    w_e, a = MOTOR.p * SPEED, np.exp(-MOTOR.gamma * H)
    eps = 0.5 * w_e * H if compensation else -delay * w_e * H
    angle = eps - w_e * H
    Bd = (
        (1.0 - a)
        / MOTOR.R_s
        * np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    )
    predicted = data.x[:-1] @ exact.Ad.T + data.u @ Bd.T + w0 @ exact.Ed.T
    assert relative_error(data.x[1:], predicted) < 1e-12
    # the dq hold's input matrix is off by (w_e h)^2 / 24 - j gamma w_e h^2 / 12 (with
    # compensation) or rotated by -(d + 1/2) w_e h (without)
    dq_hold = complex(exact.Bd[0, 0], exact.Bd[1, 0])
    mine = complex(Bd[0, 0], Bd[1, 0])
    if compensation:
        expected = (w_e * H) ** 2 / 24 - 1j * MOTOR.gamma * w_e * H**2 / 12
        assert abs(mine / dq_hold - 1.0 - expected) < 1e-3 * abs(expected)
    else:
        assert np.angle(mine / dq_hold) == pytest.approx(-(delay + 0.5) * w_e * H, rel=1e-3)


def test_the_probed_law_is_the_law_with_noise_inside_the_loop() -> None:
    """The logged commands are ``law.command`` of the logged (noisy) currents, with the
    law's past commands and integrator."""
    X, U = feedforward(MOTOR, SPEED)
    K = np.hstack([25.0 * np.eye(2), np.array([[0.1, 0.0], [0.05, 0.2]])])
    law = ControlLaw(K, X, U, history=1, K_i=3000.0 * np.eye(2), C=np.eye(2), F=-X, h=H)
    settings = DriveSettings(current_noise=0.05, logged_input="commanded")
    w0 = MOTOR.exogenous(SPEED, 5.0)
    reference = steps([0.01], [w0, MOTOR.exogenous(SPEED, 8.0)])
    data = RealisticDrive(MOTOR, SPEED, H, settings).run(
        law, reference, num_samples=300, exploration=uniform(1.0), seed=2
    )
    assert data.w is not None
    rho = uniform(1.0).sample(data.t, 2, np.random.default_rng(2))
    z, past = np.zeros(2), np.zeros(2)
    for k in range(data.num_samples):
        u = law.command(data.x[k], data.w[k], past[np.newaxis], z) + rho[k]
        assert np.allclose(u, data.u[k], rtol=1e-12, atol=1e-12)
        z = z + H * (data.x[k] - X @ data.w[k])
        past = data.u[k]


# -- inverter ------------------------------------------------------------------------------


def random_references(rng: np.random.Generator, count: int, dc: float) -> NDArray[np.complex128]:
    """Voltage references inside the linear range of space-vector PWM, V."""
    magnitude = dc / np.sqrt(3.0) * np.sqrt(rng.uniform(0.0, 1.0, count))
    return magnitude * np.exp(1j * rng.uniform(-np.pi, np.pi, count))


def test_carrier_volt_seconds_equal_the_command_and_dead_time_shifts_them() -> None:
    rng = np.random.default_rng(0)
    dc, period, dead_time = 540.0, H, 1e-6
    reference = random_references(rng, 500, dc)
    signs = rng.choice([-1.0, 1.0], size=(500, 3))
    clean = carrier_segments(reference, dc, period, 0.0, signs)
    volt_seconds = np.sum(clean.voltages * np.diff(clean.boundaries, axis=-1), axis=-1)
    assert np.max(np.abs(volt_seconds - reference * period)) < 1e-12 * dc * period
    assert np.all(np.diff(clean.boundaries, axis=-1) >= 0.0)
    # symmetric pulses: the voltage's first moment about the period's center is the mean's
    middle = 0.5 * (clean.boundaries[:, 1:] + clean.boundaries[:, :-1]) - 0.5 * period
    moment = np.sum(clean.voltages * np.diff(clean.boundaries, axis=-1) * middle, axis=-1)
    assert np.max(np.abs(moment)) < 1e-12 * dc * period**2
    # with dead time: each switching leg loses t_d V_dc sign(i) volt-seconds, unless its
    # pulse is shorter than t_d or its late falling edge would leave the period
    duties = leg_duties(reference, dc)
    room = (duties * period > dead_time) & ((1.0 - duties) * period > 2.0 * dead_time)
    inside = np.all(room, axis=-1)
    shifted = carrier_segments(reference, dc, period, dead_time, signs)
    error = np.sum(shifted.voltages * np.diff(shifted.boundaries, axis=-1), axis=-1) - volt_seconds
    expected = -dead_time * dc * (signs @ CLARKE)
    assert inside.sum() > 400
    assert np.max(np.abs(error - expected)[inside]) < 1e-12 * dc * period


def carrier_run(settings: DriveSettings, count: int, law: ControlLaw | None = None) -> DriveRecord:
    X, U = feedforward(MOTOR, SPEED)
    law = law or ControlLaw.regulator(30.0 * np.eye(2), X, U)
    reference = constant(MOTOR.exogenous(SPEED, torque_for(MOTOR, 5.0)))
    drive = RealisticDrive(MOTOR, SPEED, H, settings)
    return drive.record(law, reference, num_samples=count, exploration=uniform(5.0), seed=3)


def test_carrier_samples_equal_a_segment_by_segment_solve_ivp() -> None:
    settings = DriveSettings.hardware_like()
    record = carrier_run(settings, 400)
    assert settings.dc_voltage is not None
    w_e = MOTOR.p * SPEED
    t = record.trajectory.t
    i_ab = complex_of(record.true_currents) * rotor(t)
    for k in (0, 1, 57, 200, 399):
        # the stationary reference: the applied command at the compensated angle
        voltage = complex_of(record.trajectory.u[k]) * np.exp(1j * w_e * (t[k] + 0.5 * H))
        signs = np.sign(to_phases(i_ab[k : k + 1]))
        segments = carrier_segments(
            np.array([voltage]), settings.dc_voltage, H, settings.dead_time, signs
        )
        state = np.array([i_ab[k].real, i_ab[k].imag])
        for j in range(7):
            start, stop = t[k] + segments.boundaries[0, j], t[k] + segments.boundaries[0, j + 1]
            if stop <= start:
                continue
            v = segments.voltages[0, j]

            def rhs(time: float, i: Array, v: complex = v) -> Array:
                emf = w_e * MOTOR.phi_pm * np.array([-np.sin(w_e * time), np.cos(w_e * time)])
                return (np.array([v.real, v.imag]) - MOTOR.R_s * i - emf) / MOTOR.L_s

            state = solve_ivp(rhs, (start, stop), state, rtol=RTOL_IVP, atol=1e-13).y[:, -1]
        expected = complex(state[0], state[1])
        assert abs(i_ab[k + 1] - expected) < 1e-10 * max(1.0, abs(expected))


def test_carrier_and_average_agree_within_the_ripple_curvature() -> None:
    """Open loop (K = 0), so both see the same commands; the difference of the sampled
    currents is bounded by the ripple's curvature (see the module docstring)."""
    X, U = feedforward(MOTOR, SPEED)
    law = ControlLaw.regulator(np.zeros((2, 2)), X, U)
    records = {}
    for pwm in ("average", "carrier"):
        settings = DriveSettings(pwm=pwm, dc_voltage=540.0)
        # ten electrical periods (314 samples each) pass every sector with every sign of
        # current many times; 2 s (20,000 samples) found the same largest difference
        records[pwm] = carrier_run(settings, 10 * 314, law)
    np.testing.assert_array_equal(records["average"].trajectory.u, records["carrier"].trajectory.u)
    gamma = MOTOR.gamma
    bound = np.exp(gamma * H) * (2 / 3 + 1 / np.sqrt(3)) * gamma * H**2 * 540.0 / (24 * MOTOR.L_s)
    difference = np.abs(records["average"].true_currents - records["carrier"].true_currents)
    assert np.max(np.abs(records["average"].true_currents)) > 5.0
    assert 0.0 < np.max(difference) < bound  # found 8e-8 A < 3.4e-5 A


def phase_currents(data: Trajectory) -> Array:
    """Phase currents reconstructed from the logged dq currents (zero common mode)."""
    return to_phases(complex_of(data.x) * rotor(data.t))


def test_dead_time_error_opposes_the_current_and_compensation_removes_it() -> None:
    X, U = feedforward(MOTOR, SPEED)
    law = ControlLaw.regulator(50.0 * np.eye(2), X, U)
    reference = constant(MOTOR.exogenous(SPEED, torque_for(MOTOR, 5.0)))
    w_e, volts = MOTOR.p * SPEED, 2.0  # t_d f_sw V_dc
    per_period = 2.0 * np.pi / (w_e * H)  # 314.16 samples
    # after 0.1 s (80 time constants of the loop), 10 periods of 314 samples (0.05% short):
    # the dead-time error's mean is the same as over 50 periods, to 2e-5
    window = slice(1000, 1000 + 10 * 314)
    errors = {}
    for compensation in (False, True):
        settings = DriveSettings(
            dc_voltage=540.0, dead_time=volts * H / 540.0, dead_time_compensation=compensation,
            current_noise=0.01,
        )  # fmt: skip
        record = RealisticDrive(MOTOR, SPEED, H, settings).record(
            law, reference, num_samples=window.stop, exploration=None, seed=0
        )
        # the applied mean dq voltage of the command alone is sinc(w_e h / 2) u
        command = np.sinc(w_e * H / (2 * np.pi)) * record.trajectory.u
        errors[compensation] = (record.applied_voltages - command)[window].mean(axis=0)
        current = record.true_currents[window].mean(axis=0)
    assert per_period == pytest.approx(314.16, abs=0.01)
    plain = complex(*errors[False])
    assert abs(plain) == pytest.approx(4.0 / np.pi * volts, rel=1e-3)  # found 1e-5
    opposite = np.angle(-plain / complex(*current))
    assert abs(opposite) < 0.5 * w_e * H  # the sign held over a sample lags by h / 2
    # compensation's sign is one sample (d = 1) old: (4/pi) V0 2 sin(w_e h / 2) remains
    residual = abs(complex(*errors[True]))
    assert residual == pytest.approx(4.0 / np.pi * volts * 2 * np.sin(0.5 * w_e * H), rel=0.1)
    assert residual < 0.03 * abs(plain)


# -- measurement, limits, temperature ---------------------------------------------------------


def test_noise_has_the_stated_level_with_the_current_held_at_zero() -> None:
    """Speed 0 and a zero law: the true current stays 0, the log is the noise alone. The
    Clarke transform of three noisy phases gives ``sqrt(2/3) current_noise`` per axis."""
    law = ControlLaw.regulator(np.zeros((2, 2)), np.zeros((2, 2)), np.zeros((2, 2)))
    settings = DriveSettings(current_noise=0.02)
    # 5,000 samples: a standard deviation's relative error is 1/sqrt(2 N) = 1%, a fifth of
    # the 5% allowed (found 1.3% at most)
    record = RealisticDrive(MOTOR, 0.0, H, settings).record(
        law, constant([0.0, 0.0]), num_samples=5000, exploration=None, seed=5
    )
    np.testing.assert_array_equal(record.true_currents, 0.0)
    std = record.trajectory.x.std(axis=0)
    assert np.all(np.abs(std / (np.sqrt(2.0 / 3.0) * 0.02) - 1.0) < 0.05)
    phases = phase_currents(record.trajectory)
    assert np.all(np.abs(phases.std(axis=0) / (np.sqrt(2.0 / 3.0) * 0.02) - 1.0) < 0.05)


def test_adc_quantizes_to_the_lsb_and_clips_at_the_range() -> None:
    settings = DriveSettings(input_delay=1, current_noise=0.01, adc_bits=8, adc_range=4.0)
    lsb = 4.0 / 128
    record = carrier_run(settings, 3000)  # i_q about 5 A: above the ADC's range
    phases = phase_currents(record.trajectory)
    # the log loses the phases' common mode, not their differences
    line = phases - np.roll(phases, 1, axis=1)
    assert np.max(np.abs(line / lsb - np.round(line / lsb))) < 1e-9
    assert np.max(np.abs(line)) <= 2 * 4.0
    true_line = to_phases(complex_of(record.true_currents) * rotor(record.trajectory.t))
    assert np.max(np.abs(true_line - np.roll(true_line, 1, axis=1))) > 2.5 * 4.0
    sensor = CurrentSensor(noise=None, lsb=lsb, codes=128)
    measured = sensor.phases(np.array([10.0 + 0.0j, 0.011 + 0.0j]), 0)
    np.testing.assert_allclose(measured[0], [4.0 - lsb, -4.0, -4.0])
    np.testing.assert_allclose(measured[1], [lsb * np.round(0.011 / lsb), 0.0, 0.0])


def test_an_encoder_logs_the_angle_in_whole_counts_and_changes_nothing_else() -> None:
    """With ``encoder_counts`` the log's angle is the exact one rounded to whole counts of
    ``2 pi p / counts`` as it turns (p times the mechanical angle's counts; within half a
    count of it), wrapped; every other column, the true currents and the commands are the
    exact-angle run's to the bit (the drive turns its command with the exact angle)."""
    settings = DriveSettings.hardware_like()
    exact = carrier_run(settings, 500)
    # 1001 counts on 2 pole pairs: 500.5 counts an electrical turn, so the counts' grid
    # moves by half a count from one electrical turn to the next
    counted = carrier_run(dataclasses.replace(settings, encoder_counts=1001), 500)
    count = 2 * np.pi * MOTOR.p / 1001
    angle, truth = counted.trajectory.angle, exact.trajectory.angle
    assert angle is not None and truth is not None
    turned = np.unwrap(angle) / count
    np.testing.assert_allclose(turned, np.round(turned), atol=1e-9)
    assert np.all(np.abs(angle) <= np.pi)
    error = np.abs(np.angle(np.exp(1j * (angle - truth))))
    assert np.max(error) <= 0.5 * count + 1e-12
    assert np.max(error) > 0.1 * count  # the counts are seen
    for name in ("x", "u", "w", "t"):
        np.testing.assert_array_equal(
            getattr(counted.trajectory, name), getattr(exact.trajectory, name)
        )
    np.testing.assert_array_equal(counted.true_currents, exact.true_currents)


@pytest.mark.parametrize("pwm", ["average", "carrier"])
def test_the_voltage_never_exceeds_the_linear_range(pwm: str) -> None:
    settings = DriveSettings(pwm=pwm, dc_voltage=120.0)  # type: ignore[arg-type]
    record = carrier_run(settings, 2000)  # back-EMF 92 V, the loop asks for more
    limit = 120.0 / np.sqrt(3.0)
    magnitude = np.linalg.norm(record.commanded_voltages, axis=1)
    assert np.max(magnitude) <= limit * (1 + 1e-12)
    assert np.mean(np.isclose(magnitude, limit, rtol=1e-12)) > 0.5  # the limit is active
    assert np.max(np.linalg.norm(record.trajectory.u, axis=1)) <= limit * (1 + 1e-12)
    if pwm == "average":
        assert np.max(np.linalg.norm(record.applied_voltages, axis=1)) <= limit * (1 + 1e-12)


def test_temperature_scales_resistance_and_flux() -> None:
    """Open loop at a constant dq voltage (ideal settings): the steady state gives
    ``R_s`` and ``phi_pm`` back exactly."""
    motor, speed, rise = SPMSM(R_s=1.0, L_s=2e-3, phi_pm=0.1, p=4), 50.0, 80.0
    u = np.array([3.0, 25.0])
    law = ControlLaw.regulator(np.zeros((2, 2)), np.zeros((2, 2)), np.diag(u))
    settings = DriveSettings(input_delay=0, voltage_hold="rotor", temperature_rise=rise)
    record = RealisticDrive(motor, speed, H, settings).record(
        law, constant([1.0, 1.0]), num_samples=1000, exploration=None, seed=0
    )
    w_e, i = motor.p * speed, complex(*record.true_currents[-1])
    z = complex(*u) - 1j * w_e * motor.L_s * i  # = R_s i + j w_e phi_pm
    R_s = z.real / i.real
    phi_pm = (z.imag - R_s * i.imag) / w_e
    assert R_s == pytest.approx(motor.R_s * (1 + 0.0039 * rise), rel=1e-9)
    assert phi_pm == pytest.approx(motor.phi_pm * (1 - 0.001 * rise), rel=1e-9)
    assert record.torque[-1] == pytest.approx(1.5 * motor.p * phi_pm * i.imag, rel=1e-12)
    hot = RealisticDrive(motor, speed, H, settings).true_motor
    assert (hot.R_s, hot.phi_pm) == pytest.approx((R_s, phi_pm), rel=1e-9)


# -- logging, reproducibility, batch, validation ----------------------------------------------


def test_commanded_log_is_the_applied_log_shifted_by_the_delay() -> None:
    logs = {}
    for logged in ("applied", "commanded"):
        settings = DriveSettings(input_delay=2, logged_input=logged)
        logs[logged] = RealisticDrive(MOTOR, SPEED, H, settings).run(
            delayed_law(), constant(MOTOR.exogenous(SPEED, 5.0)), num_samples=300,
            exploration=uniform(1.0), seed=9,
        )  # fmt: skip
    np.testing.assert_array_equal(logs["applied"].x, logs["commanded"].x)
    np.testing.assert_array_equal(logs["applied"].u[2:], logs["commanded"].u[:-2])
    np.testing.assert_array_equal(logs["applied"].u[:2], 0.0)


def test_runs_are_reproducible_and_no_load_gives_q_1() -> None:
    drive = RealisticDrive(MOTOR, SPEED, H, DriveSettings.hardware_like())
    law = ControlLaw.regulator(30.0 * np.eye(2), np.zeros((2, 1)), np.zeros((2, 1)))
    runs = [
        drive.run_no_load(law, num_samples=200, exploration=uniform(1.0), seed=seed)
        for seed in (1, 1, 2)
    ]
    np.testing.assert_array_equal(runs[0].x, runs[1].x)
    np.testing.assert_array_equal(runs[0].u, runs[1].u)
    assert not np.array_equal(runs[0].x, runs[2].x)
    assert runs[0].q == 1 and runs[0].w is not None
    np.testing.assert_array_equal(runs[0].w, MOTOR.p * SPEED)


def test_a_batch_equals_single_runs() -> None:
    """Equal to rounding: a batch pads shorter histories and missing integrators with
    zero gains, which changes only the summation order of the feedback (found 6e-14 V on
    commands of about 100 V; with one law for all motors the batch is bitwise equal)."""
    motors = [MOTOR, SPMSM(R_s=0.3, L_s=0.05, phi_pm=0.4, p=2), SPMSM(1.2, 0.08, 0.5, 3)]
    X, U = feedforward(MOTOR, SPEED)
    integral = ControlLaw(25.0 * np.eye(2), X, U, K_i=2000.0 * np.eye(2), C=np.eye(2), F=-X, h=H)
    laws = [delayed_law(), ControlLaw.regulator(25.0 * np.eye(2), X, U), integral]
    reference = constant(MOTOR.exogenous(SPEED, 6.0))
    settings = DriveSettings.hardware_like()
    for seed in (11, [11, 12, 13]):
        batch = run_drive_batch(
            motors, SPEED, H, settings, laws, reference, num_samples=500,
            exploration=uniform(1.0), seed=seed,
        )  # fmt: skip
        for index, (motor, law) in enumerate(zip(motors, laws, strict=True)):
            single_seed = seed if isinstance(seed, int) else seed[index]
            single = RealisticDrive(motor, SPEED, H, settings).record(
                law, reference, num_samples=500, exploration=uniform(1.0), seed=single_seed
            )
            pairs = [
                (batch[index].true_currents, single.true_currents),
                (batch[index].applied_voltages, single.applied_voltages),
                (batch[index].commanded_voltages, single.commanded_voltages),
                (batch[index].torque, single.torque),
                (batch[index].trajectory.x, single.trajectory.x),
                (batch[index].trajectory.u, single.trajectory.u),
            ]
            for mine, theirs in pairs:
                np.testing.assert_allclose(mine, theirs, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    ("fields", "name"),
    [
        ({"dead_time": -1e-6, "dc_voltage": 540.0}, "dead_time"),
        ({"dead_time": 1e-6}, "dc_voltage"),
        ({"pwm": "carrier"}, "dc_voltage"),
        ({"pwm": "sinusoidal"}, "pwm"),
        ({"adc_bits": 12}, "adc_range"),
        ({"adc_range": 50.0}, "adc_range"),
        ({"adc_bits": 0, "adc_range": 50.0}, "adc_bits"),
        ({"adc_bits": 12, "adc_range": -1.0}, "adc_range"),
        ({"input_delay": 3}, "input_delay"),
        ({"input_delay": 1.0}, "input_delay"),
        ({"current_noise": -0.1}, "current_noise"),
        ({"dc_voltage": 0.0}, "dc_voltage"),
        ({"temperature_rise": 2000.0}, "temperature_rise"),
        ({"temperature_rise": float("nan")}, "temperature_rise"),
        ({"logged_input": "computed"}, "logged_input"),
        ({"angle_compensation": 1}, "angle_compensation"),
        ({"voltage_hold": "rotor", "pwm": "carrier", "dc_voltage": 540.0}, "voltage_hold"),
        ({"encoder_counts": 2}, "encoder_counts"),
        ({"encoder_counts": 4096.0}, "encoder_counts"),
    ],
)
def test_bad_settings_name_the_field(fields: dict[str, object], name: str) -> None:
    with pytest.raises(InputError, match=f"^{name}:"):
        DriveSettings(**fields)  # type: ignore[arg-type]


def test_bad_drive_arguments_name_the_argument() -> None:
    with pytest.raises(InputError, match=r"^dead_time:"):
        RealisticDrive(MOTOR, SPEED, 1e-6, DriveSettings(dead_time=1e-6, dc_voltage=540.0))
    with pytest.raises(InputError, match=r"^h:"):
        RealisticDrive(MOTOR, SPEED, -1e-4)
    drive = RealisticDrive(MOTOR, SPEED, H)
    with pytest.raises(InputError, match=r"^laws:"):
        drive.run_no_load(delayed_law(), num_samples=10, exploration=None, seed=0)
    with pytest.raises(InputError, match=r"^seed:"):
        run_drive_batch(
            [MOTOR, MOTOR], SPEED, H, DriveSettings(), delayed_law(),
            constant(MOTOR.exogenous(SPEED, 1.0)), num_samples=10, exploration=None,
            seed=[1, 2, 3],
        )  # fmt: skip


def test_an_unstable_loop_is_reported() -> None:
    law = ControlLaw.regulator(-2000.0 * np.eye(2), np.zeros((2, 2)), np.zeros((2, 2)))
    drive = RealisticDrive(MOTOR, SPEED, H, DriveSettings(input_delay=0))
    with pytest.raises(InputError, match="overflow"):  # at sample 241
        drive.run(law, constant([1.0, 0.0]), num_samples=1000, exploration=uniform(1.0), seed=0)
