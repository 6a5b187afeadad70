"""The realistic drive with an interior motor (IPMSM, ``L_d != L_q``).

Three checks of the rotor-frame propagation (:mod:`selftune.sim._salient`): with ``L_d ==
L_q`` it is the surface motor's complex path to rounding; a salient motor's currents are
an independent numerical integration's (scipy's ``solve_ivp``, DOP853, at tight
tolerances) over the drive's own voltages; and they are motulator's (an independent
simulator's machine model, its own simulation loop). Then what the drive does with the
motor: torque with the reluctance term, the heated motor, the profile's factors, a
session as matrices against the stepper.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

from selftune.core import ControlLaw
from selftune.core._phases import to_phases
from selftune.model import IPMSM, SPMSM, Motor
from selftune.sim import (
    DriveRecord,
    DriveSettings,
    ParameterProfile,
    RealisticDrive,
    constant,
    run_drive_batch,
    uniform,
)
from selftune.sim._inverter import phasor_mean
from selftune.sim._pwm import carrier_segments

Array = NDArray[np.float64]
H = 1e-4  # 10 kHz
SURFACE = SPMSM.paper()
#: The surface motor as an IPMSM: the rotor-frame path with L_d == L_q.
SURFACE_AS_INTERIOR = IPMSM(
    R_s=SURFACE.R_s, L_d=SURFACE.L_s, L_q=SURFACE.L_s, phi_pm=SURFACE.phi_pm, p=SURFACE.p
)
#: A salient motor, L_q / L_d = 3.
SALIENT = IPMSM(R_s=0.2, L_d=2e-3, L_q=6e-3, phi_pm=0.05, p=4)
#: ``w_e h`` = 0.3 and 0.02 (mechanical rad/s).
HIGH_SPEED = 0.3 / (SALIENT.p * H)
LOW_SPEED = 0.02 / (SALIENT.p * H)
HARDWARE = DriveSettings.hardware_like()
AVERAGE_DEAD_TIME = dataclasses.replace(HARDWARE, pwm="average", current_noise=0.0)
CARRIER = dataclasses.replace(HARDWARE, current_noise=0.0, adc_bits=None, adc_range=None)


def law_for(motor: Motor, speed: float, share: float = 0.25) -> ControlLaw:
    """Feedforward of the motor's regulation form and proportional feedback of ``share``
    of the dead-beat gains ``L / h`` on each axis, with integral action."""
    problem = motor.regulation_problem(speed)
    X = -problem.F
    U = -np.linalg.solve(problem.B, problem.A @ X + problem.D)
    K = share * np.diag([motor.L_d, motor.L_q]) / H
    return ControlLaw(K, X, U, K_i=20.0 * K, C=np.eye(2), F=-X, h=H)


def record(
    motor: Motor, speed: float, settings: DriveSettings, law: ControlLaw, w: Array, count: int
) -> DriveRecord:
    drive = RealisticDrive(motor, speed, H, settings)
    return drive.record(law, constant(w), num_samples=count, exploration=uniform(3.0), seed=5)


# -- the general path against the surface motor's --------------------------------------

#: The two paths round differently (a complex scalar against 2 x 2 matrices formed from
#: the Sylvester solution); the contracting loop keeps it at a few hundred eps of the
#: largest current over the run (measured: 2e-14 to 2e-13 relative).
PATHS_AGREE = 1e-12


@pytest.mark.parametrize(
    "settings",
    [
        DriveSettings(),
        DriveSettings(voltage_hold="rotor"),
        AVERAGE_DEAD_TIME,
        CARRIER,
        dataclasses.replace(CARRIER, dead_time_compensation=True),
    ],
    ids=["average", "rotor hold", "average, dead time", "carrier", "carrier, compensation"],
)
def test_equal_inductances_reproduce_the_surface_path(settings: DriveSettings) -> None:
    speed = 100.0
    law = law_for(SURFACE, speed)
    w = SURFACE.exogenous(speed, 1.0)
    surface = record(SURFACE, speed, settings, law, w, 2000)
    interior = record(SURFACE_AS_INTERIOR, speed, settings, law, w, 2000)
    scale = np.max(np.abs(surface.true_currents))
    assert scale > 0.5  # the run carries current
    for name in ("true_currents", "torque"):
        expected = getattr(surface, name)
        np.testing.assert_allclose(
            getattr(interior, name), expected, rtol=0, atol=PATHS_AGREE * np.max(np.abs(expected))
        )
    volts = np.max(np.abs(surface.trajectory.u))
    np.testing.assert_allclose(
        interior.trajectory.u, surface.trajectory.u, rtol=0, atol=PATHS_AGREE * volts
    )


def test_a_batch_with_an_interior_motor_runs_all_in_the_rotor_frame() -> None:
    """A mixed batch: each motor's record is its own drive's (the surface motor's to
    rounding: the batch takes the rotor-frame path for all)."""
    speed = 100.0
    law = law_for(SURFACE, speed)
    w = SURFACE.exogenous(speed, 1.0)
    motors: list[Motor] = [SURFACE, SURFACE_AS_INTERIOR]
    both = run_drive_batch(
        motors, speed, H, CARRIER, law, constant(w), num_samples=500, exploration=uniform(3.0),
        seed=5,
    )  # fmt: skip
    for motor, batch in zip(motors, both, strict=True):
        alone = record(motor, speed, CARRIER, law, w, 500)
        scale = np.max(np.abs(alone.true_currents))
        np.testing.assert_allclose(
            batch.true_currents, alone.true_currents, rtol=0, atol=PATHS_AGREE * scale
        )


# -- against a numerical integration ----------------------------------------------------


def integrate(
    motor: IPMSM, speed: float, segments: list[tuple[float, float, complex]], start: Array
) -> Array:
    """The rotor-frame currents at each segment's end from ``start`` (A), the stationary
    vector of each ``(t0, t1, V)`` held over it (absolute time, s; V in V): the motor's
    own ``torque_mode`` and back-EMF (its regulation form's D), integrated by DOP853 at
    ``rtol = atol / 1 A = 1e-12``."""
    A, B = motor.torque_mode(speed)
    w_e = motor.p * speed
    emf = motor.regulation_problem(speed).D[:, 0] * (w_e * motor.phi_pm)
    current, ends = np.asarray(start, dtype=float), []
    for t0, t1, V in segments:

        def rate(t: float, i: Array, V: complex = V) -> Array:
            u = np.exp(-1j * w_e * t) * V
            return np.asarray(A @ i + B @ np.array([u.real, u.imag]) + emf)

        solution = solve_ivp(rate, (t0, t1), current, method="DOP853", rtol=1e-12, atol=1e-12)
        current = solution.y[:, -1]
        ends.append(current)
    return np.array(ends)


#: DOP853 at rtol = atol / 1 A = 1e-12 per step, over up to 1,400 segments whose errors
#: the motor's decay (L / R = 10 to 30 ms, 100 to 300 samples) forgets: at most about 1e-11
#: of the current (measured: 8e-15 to 3.5e-13); the exact propagation is at rounding.
INTEGRATION_AGREES = 1e-11


@pytest.mark.parametrize("speed", [HIGH_SPEED, LOW_SPEED], ids=["w_e h = 0.3", "w_e h = 0.02"])
def test_average_pwm_is_the_integrated_motor(speed: float) -> None:
    """Average PWM with dead time: the stationary vector held over sample k is the mean
    dq voltage turned back, ``applied_k exp(j theta_k) / mean(exp(-j w_e s))``."""
    count = 300
    rec = record(
        SALIENT, speed, AVERAGE_DEAD_TIME, law_for(SALIENT, speed), SALIENT.exogenous(speed, 2.0),
        count,
    )  # fmt: skip
    w_e = SALIENT.p * speed
    t = H * np.arange(count + 1)
    applied = rec.applied_voltages[:, 0] + 1j * rec.applied_voltages[:, 1]
    held = applied * np.exp(1j * w_e * t[:-1]) / phasor_mean(w_e * H)
    segments = [(t[k], t[k + 1], complex(held[k])) for k in range(count)]
    expected = integrate(SALIENT, speed, segments, np.zeros(2))
    scale = np.max(np.abs(rec.true_currents))
    assert scale > 1.0
    np.testing.assert_allclose(
        rec.true_currents[1:], expected, rtol=0, atol=INTEGRATION_AGREES * scale
    )


@pytest.mark.parametrize("speed", [HIGH_SPEED, LOW_SPEED], ids=["w_e h = 0.3", "w_e h = 0.02"])
def test_carrier_pwm_is_the_integrated_motor(speed: float) -> None:
    """Carrier PWM with dead time: each carrier period's seven segments rebuilt from the
    applied command (``exp(j (theta_k + w_e h / 2)) u_k``, angle compensation) and the
    true phase currents' signs at its start (:func:`carrier_segments`)."""
    count = 200
    settings = CARRIER
    rec = record(
        SALIENT, speed, settings, law_for(SALIENT, speed), SALIENT.exogenous(speed, 2.0), count
    )
    w_e = SALIENT.p * speed
    t = H * np.arange(count + 1)
    assert settings.logged_input == "applied" and settings.angle_compensation
    u = rec.trajectory.u[:, 0] + 1j * rec.trajectory.u[:, 1]
    command = np.exp(1j * w_e * (t[:-1] + 0.5 * H)) * u
    true = rec.true_currents[:, 0] + 1j * rec.true_currents[:, 1]
    stationary = true * np.exp(1j * w_e * t)
    signs = np.sign(to_phases(stationary[:-1]))
    assert settings.dc_voltage is not None
    pwm = carrier_segments(command, settings.dc_voltage, H, settings.dead_time, signs)
    segments, ends = [], []
    for k in range(count):
        bounds = t[k] + pwm.boundaries[k]
        for j in range(7):
            if bounds[j + 1] > bounds[j]:
                segments.append((bounds[j], bounds[j + 1], complex(pwm.voltages[k, j])))
        ends.append(len(segments) - 1)
    expected = integrate(SALIENT, speed, segments, np.zeros(2))[ends]
    scale = np.max(np.abs(rec.true_currents))
    assert scale > 1.0
    np.testing.assert_allclose(
        rec.true_currents[1:], expected, rtol=0, atol=INTEGRATION_AGREES * scale
    )


# -- against motulator ------------------------------------------------------------------


@pytest.mark.parametrize(
    ("max_step", "tolerance"),
    [(np.inf, 1e-3), (H / 10, 1e-6)],
    ids=["its default solver", "steps of h / 10"],
)
def test_motulator_gives_the_same_currents_and_torque(max_step: float, tolerance: float) -> None:
    """motulator 0.5 (an independent simulator: its ``SynchronousMachine`` at a speed
    held by ``ExternalRotorSpeed``, its ``VoltageSourceConverter`` and its ``Simulation``
    loop, which integrates with scipy's ``solve_ivp`` at its defaults, RK45 at ``rtol =
    1e-3``, ``atol = 1e-6``, and only ``max_step`` set) fed the stationary voltages our
    drive applied (average PWM, no dead time) over 200 samples at ``w_e h = 0.3``.

    Conventions (motulator's source): its space vectors are peak-valued, ``abc2complex(u)
    = (2/3) (u_a + a u_b + a^2 u_c)``, our amplitude-invariant Clarke; its rotor frame is
    at the electrical angle ``theta_m`` (``d exp(j theta_m)/dt = j n_p w_M exp(j
    theta_m)``), ``psi_s = L_d i_d + psi_f + j L_q i_q``, d along the magnet as ours, so
    its ``i_ss`` is our ``i_ab``, its ``R_s, L_d, L_q, psi_f, n_p`` our ``R_s, L_d, L_q,
    phi_pm, p``, its ``tau_M = 1.5 n_p Im(i_s conj(psi_s))`` our torque. Its model delays
    the duty ratios by one sample (its ``Delay(1)``), ours computes with the same delay:
    the controller stub hands it sample k + 1's voltage at sample k (our first is zero,
    as its delay line's). The duties are ``1/2 + v_x / u_dc``; its DC bus is made large
    enough that they stay within [0, 1].

    Tolerances: the default solver's ``rtol = 1e-3`` (measured 5e-5 of the largest current);
    at steps of h / 10 its tolerance no longer binds and its fifth-order error in ``w_e
    max_step = 0.03`` is the bound, about 1e-6 over the run (measured 7e-10).
    """
    motulator = pytest.importorskip("motulator")
    assert motulator is not None
    from motulator.common.utils import complex2abc
    from motulator.drive import model
    from motulator.drive.utils import SynchronousMachinePars

    speed, count = HIGH_SPEED, 200
    settings = DriveSettings(dc_voltage=540.0)
    rec = record(
        SALIENT, speed, settings, law_for(SALIENT, speed), SALIENT.exogenous(speed, 2.0), count
    )
    w_e = SALIENT.p * speed
    t = H * np.arange(count + 1)
    applied = rec.applied_voltages[:, 0] + 1j * rec.applied_voltages[:, 1]
    held = applied * np.exp(1j * w_e * t[:-1]) / phasor_mean(w_e * H)
    assert held[0] == 0.0  # the delay line's zero, as motulator's
    dc_voltage = 4.0 * float(np.max(np.abs(held)))

    class Controller:
        """motulator's control-system interface: (T_s, duty ratios) at each sample."""

        def __init__(self) -> None:
            self.sample = 0

        def __call__(self, _: object) -> tuple[float, Array]:
            following = self.sample + 1
            self.sample = following
            voltage = held[following] if following < count else 0j
            return H, 0.5 + complex2abc(voltage) / dc_voltage

        def post_process(self) -> None:
            """Nothing to post-process."""

    parameters = SynchronousMachinePars(
        n_p=SALIENT.p, R_s=SALIENT.R_s, L_d=SALIENT.L_d, L_q=SALIENT.L_q, psi_f=SALIENT.phi_pm
    )
    drive = model.Drive(
        converter=model.VoltageSourceConverter(dc_voltage),
        machine=model.SynchronousMachine(parameters),
        mechanics=model.ExternalRotorSpeed(w_M=lambda time: speed + 0.0 * time),
    )
    model.Simulation(drive, Controller()).simulate(t_stop=(count - 0.5) * H, max_step=max_step)
    data = drive.machine.data
    at = [np.flatnonzero(np.abs(data.t - k * H) < 1e-9 * H)[-1] for k in range(count + 1)]
    ours = (rec.true_currents[:, 0] + 1j * rec.true_currents[:, 1]) * np.exp(1j * w_e * t)
    scale = np.max(np.abs(ours))
    assert scale > 1.0
    np.testing.assert_allclose(data.i_ss[at], ours, rtol=0, atol=tolerance * scale)
    torque_scale = np.max(np.abs(rec.torque))
    np.testing.assert_allclose(data.tau_M[at], rec.torque, rtol=0, atol=tolerance * torque_scale)


# -- what the drive does with the motor -------------------------------------------------

#: Two rounding paths of one loop (the matrices against the stepper, or a scaled motor's
#: values rounded in another order): a few eps of the largest current per sample, kept
#: there by the contracting loop over the run (as tests/test_drive_session.py's ROUNDING).
ROUNDING = 1e-12


def test_the_torque_has_the_reluctance_term_and_the_heated_flux() -> None:
    speed, rise = LOW_SPEED, 60.0
    drive = RealisticDrive(SALIENT, speed, H, DriveSettings(temperature_rise=rise))
    true = drive.true_motor
    assert isinstance(true, IPMSM)
    assert (true.L_d, true.L_q, true.p) == (SALIENT.L_d, SALIENT.L_q, SALIENT.p)
    assert true.R_s == pytest.approx(SALIENT.R_s * (1 + 0.0039 * rise), rel=1e-15)
    assert true.phi_pm == pytest.approx(SALIENT.phi_pm * (1 - 0.001 * rise), rel=1e-15)
    law = law_for(SALIENT, speed)
    rec = drive.record(
        law, constant(SALIENT.exogenous(speed, 2.0)), num_samples=300, exploration=None, seed=0
    )
    i_d, i_q = rec.true_currents.T
    expected = true.torque(i_q, i_d)
    np.testing.assert_allclose(rec.torque, expected, rtol=0, atol=4e-16 * np.max(np.abs(expected)))
    reluctance = 1.5 * true.p * (true.L_d - true.L_q) * i_d * i_q
    assert np.max(np.abs(reluctance)) > 0.1 * np.max(np.abs(rec.torque))  # the term matters


def test_the_no_load_reference_is_the_motors() -> None:
    speed = LOW_SPEED
    drive = RealisticDrive(SALIENT, speed, H, DriveSettings())
    problem = SALIENT.no_load_problem(speed)
    law = ControlLaw(np.diag([1.0, 3.0]), np.zeros((2, 1)), np.zeros((2, 1)))
    assert problem.D.shape == (2, 1)
    log = drive.run_no_load(law, num_samples=10, exploration=None, seed=0)
    np.testing.assert_array_equal(log.w, np.tile(SALIENT.no_load_exogenous(speed), (11, 1)))


@pytest.mark.parametrize(
    ("settings", "tolerance"),
    [(DriveSettings(dc_voltage=540.0), ROUNDING), (CARRIER, 0.0)],
    ids=["as matrices", "stepper"],
)
def test_a_session_is_the_drives_record(settings: DriveSettings, tolerance: float) -> None:
    """From rest, one chunk of a session equals the drive's record: as matrices (the
    rotor-frame sample map read off the inverter's step with the units 1 and j) to
    rounding, through the stepper to the bit."""
    speed, count = HIGH_SPEED, 600
    drive = RealisticDrive(SALIENT, speed, H, settings)
    law = law_for(SALIENT, speed)
    w = SALIENT.exogenous(speed, 2.0)
    rec = drive.record(law, constant(w), num_samples=count, exploration=uniform(3.0), seed=3)
    rho = uniform(3.0).sample(H * np.arange(count + 1), 2, np.random.default_rng(3))
    chunk = drive.start(law, seed=11).advance(count, w, probing=rho)
    scale = np.max(np.abs(rec.true_currents))
    for name in ("true_currents", "torque"):
        expected = getattr(rec, name)
        np.testing.assert_allclose(
            getattr(chunk, name), expected, rtol=0, atol=tolerance * np.max(np.abs(expected))
        )
    np.testing.assert_allclose(chunk.trajectory.x, rec.trajectory.x, rtol=0, atol=tolerance * scale)


@pytest.mark.parametrize("settings", [DriveSettings(dc_voltage=540.0), CARRIER])
def test_the_profiles_inductance_factor_scales_both_axes(settings: DriveSettings) -> None:
    """A profile's constant factors make the drive of the scaled motor (L_d and L_q both
    times the L_s factor); the chunk reports the values and the torque of that motor."""
    speed, count = HIGH_SPEED, 400
    factors = {"R_s": 1.2, "L_s": 0.9, "phi_pm": 0.95}
    profile = ParameterProfile(
        time=[0.0], R_s=[factors["R_s"]], phi_pm=[factors["phi_pm"]], L_s=[factors["L_s"]]
    )
    scaled = IPMSM(
        R_s=SALIENT.R_s * factors["R_s"], L_d=SALIENT.L_d * factors["L_s"],
        L_q=SALIENT.L_q * factors["L_s"], phi_pm=SALIENT.phi_pm * factors["phi_pm"], p=SALIENT.p,
    )  # fmt: skip
    law = law_for(SALIENT, speed)
    w = SALIENT.exogenous(speed, 2.0)
    chunk = RealisticDrive(SALIENT, speed, H, settings).start(law, seed=0, profile=profile)
    got = chunk.advance(count, w)
    rec = RealisticDrive(scaled, speed, H, settings).record(
        law, constant(w), num_samples=count, exploration=None, seed=0
    )
    for name, value in (("R_s", scaled.R_s), ("L_d", scaled.L_d), ("L_q", scaled.L_q)):
        np.testing.assert_allclose(getattr(got, name), value, rtol=1e-15)
    np.testing.assert_allclose(got.phi_pm, scaled.phi_pm, rtol=1e-15)
    for name in ("true_currents", "torque"):
        expected = getattr(rec, name)
        np.testing.assert_allclose(
            getattr(got, name), expected, rtol=0, atol=ROUNDING * np.max(np.abs(expected))
        )
