"""The running drive (DriveSession) against one run, the stepper, the law's own equations
and the motor's continuous steady state.

Agreement found (paper motor at 100 rad/s, 10 kHz):

- from rest, one chunk equals RealisticDrive.record: to the bit where the stepper runs
  (carrier PWM, dead time, ADC; the voltage limit reached), 4e-14 A and 1.3e-12 V where
  the loop runs as matrices (average PWM);
- chunks of any sizes equal one run with the same seed (noise, a heating profile, a
  step): to the bit on the stepper, 2e-14 A on the matrices; the matrices equal the
  stepper through a ramp and a step to 1e-12 (A and V);
- the steady currents after an R_s and flux ramp equal the continuous dq steady state
  ``(R_s + j w_e L_s + K) i = ...`` of the heated motor to 1e-12 relative;
- the carrier plant (the three legs' pulses superposed, in Python floats) equals the
  sorted segments' exact solution to 16 eps of ``V_dc h / L_s`` and ``V_dc``, and the
  sensor's one-motor reading equals numpy's to the bit.

Timings (``python tests/test_drive_session.py``: samples per CPU second, best of two,
this 2-core machine with one BLAS thread, the ranges over runs beside other work; 10 kHz,
the servo law below; 10 k/s is real time):

=====================  ==================  =============  ===============
settings               motor               chunks of 100  chunks of 1,000
=====================  ==================  =============  ===============
average PWM, noise     constant            142-277 k/s    799-1,248 k/s
average PWM, noise     warming, 10 ms hold 52-73 k/s      130-223 k/s
hardware_like          constant            20-35 k/s      21-39 k/s
hardware_like          warming, 10 ms hold 20-28 k/s      22-31 k/s
=====================  ==================  =============  ===============

(hardware_like was 2.5 k/s with each carrier period in numpy.)
"""

from __future__ import annotations

import dataclasses
import sys
import time

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from numpy.typing import NDArray

from example_counts import examples
from selftune import SPMSM, InputError
from selftune.core import ControlLaw
from selftune.sim import (
    DriveChunk,
    DriveSettings,
    ParameterProfile,
    RealisticDrive,
    constant,
    run_drive_batch,
    uniform,
)
from selftune.sim._inverter import CurrentSensor
from selftune.sim._linear import LinearLoop
from selftune.sim._pwm import carrier_edges, carrier_sample, carrier_segments

Array = NDArray[np.float64]
MOTOR = SPMSM.paper()
H = 1e-4  # 10 kHz
SPEED = 100.0  # rad/s mechanical
W_E = MOTOR.p * SPEED
REFERENCE = np.array([W_E * MOTOR.phi_pm, 0.5 * 1.5 * MOTOR.p * MOTOR.phi_pm])  # i_q* = 0.5 A
#: Rounding of a loop propagated as matrices, against one stepped sample by sample: the
#: contracting loop keeps it at a few eps of the largest current, per sample; 1e-12 A
#: leaves room for the N = 2,000 samples of the longest run here.
ROUNDING = 1e-12
#: The same on the voltages: the law's gains (30 V/A, 0.2 V/V, 200 V/(A s) h) turn the
#: currents' rounding into the commands'.
VOLTAGE_ROUNDING = 100 * ROUNDING
VOLTAGES = ("logged_input", "applied_voltages", "commanded_voltages")

NOISY = DriveSettings(current_noise=0.01, dc_voltage=540.0)  # the loop as matrices
HARDWARE = dataclasses.replace(DriveSettings.hardware_like(), dead_time_compensation=True)
WARMING = ParameterProfile(
    time=[0.0, 0.05, 0.05, 0.2], R_s=[1.0, 1.1, 1.3, 1.4], phi_pm=[1.0, 0.98, 0.98, 0.92]
)


def feedforward(motor: SPMSM = MOTOR) -> tuple[Array, Array]:
    """X, U of the known-flux regulation form (model-based, nameplate)."""
    problem = motor.regulation_problem(SPEED)
    X = -problem.F
    U = -np.linalg.solve(problem.B, problem.A @ X + problem.D)
    return X, np.asarray(U, dtype=float)


def servo_law(gain: float = 30.0, integral: float = 200.0) -> ControlLaw:
    """Feedback on x and the one past command, feedforward, integral action on x - X w."""
    X, U = feedforward()
    K = np.hstack([gain * np.eye(2), 0.2 * np.eye(2)])
    return ControlLaw(K, X, U, history=1, K_i=integral * np.eye(2), C=np.eye(2), F=-X, h=H)


def proportional_law(gain: float = 30.0) -> ControlLaw:
    X, U = feedforward()
    return ControlLaw(gain * np.eye(2), X, U)


def joined(chunks: list[DriveChunk], name: str) -> Array:
    """A per-sample field of consecutive chunks as one run's (the shared samples once)."""
    arrays = [np.asarray(getattr(chunk, name)) for chunk in chunks]
    if arrays[0].shape[0] == chunks[0].num_samples:  # per sample: N rows
        return np.concatenate(arrays)
    return np.concatenate([array[:-1] for array in arrays[:-1]] + [arrays[-1]])


PER_SAMPLE = (
    "measured", "logged_input", "angle", "true_currents", "applied_voltages",
    "commanded_voltages", "torque", "R_s", "L_s", "phi_pm",
)  # fmt: skip


def run_in_chunks(
    drive: RealisticDrive, sizes: list[int], law: ControlLaw, **start: object
) -> list[DriveChunk]:
    session = drive.start(law, seed=7, **start)  # type: ignore[arg-type]
    return [session.advance(size, REFERENCE) for size in sizes]


def assert_chunks_equal_one_run(
    drive: RealisticDrive, sizes: list[int], law: ControlLaw, tolerance: float, **start: object
) -> None:
    one = run_in_chunks(drive, [sum(sizes)], law, **start)[0]
    chunks = run_in_chunks(drive, sizes, law, **start)
    assert [chunk.first_sample for chunk in chunks] == list(np.cumsum([0, *sizes[:-1]]))
    for name in PER_SAMPLE:
        atol = tolerance * (VOLTAGE_ROUNDING / ROUNDING if name in VOLTAGES else 1.0)
        np.testing.assert_allclose(joined(chunks, name), getattr(one, name), rtol=0, atol=atol)
    np.testing.assert_array_equal(joined(chunks, "time"), one.time)


# -- from rest: the drive's own one-run record ------------------------------------------


@pytest.mark.parametrize(
    ("settings", "tolerance"),
    [
        (dataclasses.replace(HARDWARE, current_noise=0.0), 0.0),  # stepper: to the bit
        (DriveSettings(dc_voltage=540.0), ROUNDING),  # matrices
        (DriveSettings(dc_voltage=30.0), 0.0),  # the limit reached: the stepper
        (DriveSettings(input_delay=2, logged_input="commanded"), ROUNDING),
        (DriveSettings.ideal(), ROUNDING),
        (dataclasses.replace(HARDWARE, current_noise=0.0, encoder_counts=1001), 0.0),
    ],
)
def test_one_chunk_from_rest_is_the_drives_record(
    settings: DriveSettings, tolerance: float
) -> None:
    drive = RealisticDrive(MOTOR, SPEED, H, settings)
    law = servo_law()
    count = 1500
    record = drive.record(
        law, constant(REFERENCE), num_samples=count, exploration=uniform(2.0), seed=3
    )
    rho = uniform(2.0).sample(drive.h * np.arange(count + 1), 2, np.random.default_rng(3))
    chunk = drive.start(law, seed=11).advance(count, REFERENCE, probing=rho)
    if settings.dc_voltage == 30.0:  # the case is the one meant: the limit acts
        magnitude = np.hypot(*record.commanded_voltages.T)
        assert np.max(magnitude) == pytest.approx(30.0 / np.sqrt(3.0))
    pairs = [
        (chunk.trajectory.x, record.trajectory.x),
        (chunk.trajectory.u, record.trajectory.u),
        (chunk.true_currents, record.true_currents),
        (chunk.commanded_voltages, record.commanded_voltages),
        (chunk.applied_voltages, record.applied_voltages),
        (chunk.torque, record.torque),
    ]
    for index, (actual, expected) in enumerate(pairs):
        volts = index in (1, 3, 4)  # u, the commands, the applied voltages
        atol = tolerance * (VOLTAGE_ROUNDING / ROUNDING if volts else 1.0)
        np.testing.assert_allclose(actual, expected, rtol=0, atol=atol)
    np.testing.assert_array_equal(chunk.trajectory.t, record.trajectory.t)
    np.testing.assert_array_equal(chunk.trajectory.angle, record.trajectory.angle)


# -- chunks --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("settings", "tolerance"), [(HARDWARE, 0.0), (NOISY, ROUNDING)], ids=["stepper", "matrices"]
)
@pytest.mark.parametrize("profile", [None, WARMING], ids=["constant", "warming"])
def test_chunks_of_any_sizes_equal_one_run(
    settings: DriveSettings, tolerance: float, profile: ParameterProfile | None
) -> None:
    drive = RealisticDrive(MOTOR, SPEED, H, settings)
    sizes = [1, 2, 97, 400, 3, 497] if settings is HARDWARE else [1, 2, 97, 400, 3, 1497]
    assert_chunks_equal_one_run(
        drive, sizes, servo_law(), tolerance, profile=profile, max_hold=1e-3
    )


def test_an_encoders_counts_continue_across_chunks() -> None:
    """The angle column as an encoder logs it, chunk after chunk, is the one run's (to
    the bit) and stays on one grid of counts of the turns since the start: 1001 counts on
    the motor's pole pairs, so an electrical turn is not a whole number of counts and a
    chunk that read its own angle from its first sample would move the grid."""
    drive = RealisticDrive(MOTOR, SPEED, H, dataclasses.replace(HARDWARE, encoder_counts=1001))
    sizes = [1, 2, 97, 400, 3, 497]
    one = run_in_chunks(drive, [sum(sizes)], servo_law())[0]
    angle = joined(run_in_chunks(drive, sizes, servo_law()), "angle")
    np.testing.assert_array_equal(angle, one.angle)
    count = 2 * np.pi * MOTOR.p / 1001
    turned = np.unwrap(angle) / count
    np.testing.assert_allclose(turned, np.round(turned), rtol=0, atol=1e-9)
    exact = RealisticDrive(MOTOR, SPEED, H, HARDWARE)
    truth = joined(run_in_chunks(exact, sizes, servo_law()), "angle")
    error = np.abs(np.angle(np.exp(1j * (angle - truth))))
    assert 0.1 * count < np.max(error) <= 0.5 * count + 1e-12


def test_the_matrices_are_the_stepper_through_a_ramp_and_a_step(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The loop as matrices, its motor changing between the intervals of a chunk, against
    the same session stepped sample by sample (the linear path switched off)."""
    drive = RealisticDrive(MOTOR, SPEED, H, NOISY)
    sizes = [1, 613, 1386]  # intervals of 1 ms cut by the step at sample 500
    matrices = run_in_chunks(drive, sizes, servo_law(), profile=WARMING, max_hold=1e-3)
    monkeypatch.setattr(LinearLoop, "applies", staticmethod(lambda settings: False))
    stepped = run_in_chunks(drive, sizes, servo_law(), profile=WARMING, max_hold=1e-3)
    for name in PER_SAMPLE:
        atol = VOLTAGE_ROUNDING if name in VOLTAGES else ROUNDING
        np.testing.assert_allclose(joined(matrices, name), joined(stepped, name), rtol=0, atol=atol)
    assert np.ptp(joined(stepped, "R_s")) > 0.3 * MOTOR.R_s  # the motor did change


@examples(full=60, quick=8)
@given(sizes=st.lists(st.integers(1, 300), min_size=1, max_size=8))
def test_random_chunkings_equal_one_run(sizes: list[int]) -> None:
    drive = RealisticDrive(MOTOR, SPEED, H, NOISY)
    assert_chunks_equal_one_run(drive, sizes, servo_law(), ROUNDING, profile=WARMING)


def test_the_noise_continues_across_chunks() -> None:
    """The measurement errors are the seed's one stream, not restarted per chunk."""
    drive = RealisticDrive(MOTOR, 0.0, H, DriveSettings(current_noise=0.01))
    session = drive.start(proportional_law(), seed=5)
    first, second = session.advance(200, REFERENCE), session.advance(200, REFERENCE)
    errors = np.concatenate(
        [
            first.measured[:-1] - first.true_currents[:-1],
            second.measured - second.true_currents,
        ]
    )
    stream = np.random.default_rng(5).normal(0.0, 0.01, size=(401, 3))
    expected = stream @ (2.0 / 3.0 * np.exp(2j * np.pi * np.arange(3) / 3))  # Clarke, theta 0
    np.testing.assert_allclose(errors[:, 0] + 1j * errors[:, 1], expected, atol=1e-15)


# -- switching laws --------------------------------------------------------------------------


def integrator_of(*chunks: DriveChunk) -> Array:
    """The servo law's integrator after the chunks (from rest), summed from their log:
    ``z_N = h sum_k (x_k - X w)``."""
    X, _ = feedforward()
    measured = np.concatenate([chunk.measured[:-1] for chunk in chunks])
    return np.sum(measured - REFERENCE @ X.T, axis=0) * H


def test_a_switched_law_computes_the_chunks_first_command() -> None:
    drive = RealisticDrive(MOTOR, SPEED, H, NOISY)
    old, new = servo_law(), servo_law(gain=20.0, integral=100.0)
    session = drive.start(old, seed=1)
    before = session.advance(300, REFERENCE)
    z_old, past = session.integrator, session.past_commands[-1:]
    np.testing.assert_allclose(z_old, integrator_of(before), rtol=1e-12)
    z = np.array([0.3, -0.2])
    after = session.advance(200, REFERENCE, law=new, integrator=z)
    x = before.measured[-1]  # the measurement the switch's first command uses
    np.testing.assert_allclose(after.measured[0], x, rtol=0, atol=ROUNDING)
    expected = new.command(x, REFERENCE, past, z)
    np.testing.assert_allclose(after.commanded_voltages[0], expected, rtol=0, atol=1e-12)
    kept = old.command(x, REFERENCE, past, z_old)  # what the old law would have computed
    assert np.max(np.abs(kept - expected)) > 1.0
    assert session.law is new
    # and the new law's integrator runs on from z
    np.testing.assert_allclose(session.integrator, z + integrator_of(after), rtol=1e-12)


def test_a_bumpless_switch_keeps_the_command() -> None:
    """The integrator the caller chooses so that the new law's first command is the old
    law's: the commanded voltage is continuous across the switch."""
    drive = RealisticDrive(MOTOR, SPEED, H, NOISY)
    old, new = servo_law(), servo_law(gain=15.0, integral=400.0)
    staying = drive.start(old, seed=2)
    staying.advance(400, REFERENCE)
    kept = staying.advance(50, REFERENCE)
    session = drive.start(old, seed=2)
    session.advance(400, REFERENCE)
    x, past = kept.measured[0], session.past_commands[-1:]
    z = new.bumpless_integrator(x, REFERENCE, past, kept.commanded_voltages[0])
    switched = session.advance(50, REFERENCE, law=new, integrator=z)
    np.testing.assert_allclose(
        switched.commanded_voltages[0], kept.commanded_voltages[0], rtol=0, atol=1e-12
    )
    assert np.max(np.abs(switched.commanded_voltages[1:] - kept.commanded_voltages[1:])) > 0.1


def test_switching_to_the_same_law_changes_nothing() -> None:
    drive = RealisticDrive(MOTOR, SPEED, H, HARDWARE)
    law = servo_law()
    one = run_in_chunks(drive, [300], law)[0]
    session = drive.start(law, seed=7)
    first = session.advance(120, REFERENCE)
    second = session.advance(180, REFERENCE, law=law, integrator=session.integrator)
    np.testing.assert_array_equal(joined([first, second], "measured"), one.measured)


def test_bad_arguments_are_named() -> None:
    drive = RealisticDrive(MOTOR, SPEED, H, NOISY)
    session = drive.start(servo_law(), seed=0)
    with pytest.raises(InputError, match=r"^probing: expected \(10, 2\)"):
        session.advance(10, REFERENCE, probing=np.zeros((9, 2)))
    with pytest.raises(InputError, match=r"^reference: expected 2 finite"):
        session.advance(10, [1.0, 2.0, 3.0])
    with pytest.raises(InputError, match=r"^integrator: given without a law"):
        session.advance(10, REFERENCE, integrator=[0.0, 0.0])
    with pytest.raises(InputError, match=r"^integrator: the law has 0 integrator"):
        session.advance(10, REFERENCE, law=proportional_law())
    with pytest.raises(InputError, match=r"^integrator: expected 2 finite"):
        session.advance(10, REFERENCE, law=servo_law(), integrator=[1.0])
    with pytest.raises(InputError, match=r"^num_samples"):
        session.advance(0, REFERENCE)
    with pytest.raises(InputError, match=r"^reference"):  # a refused chunk switches nothing
        session.advance(10, [np.nan, 0.0], law=proportional_law(), integrator=[])
    assert session.law.K_i is not None
    with pytest.raises(InputError, match=r"^max_hold"):
        drive.start(servo_law(), seed=0, max_hold=-1.0)
    assert session.sample == 0  # nothing ran


# -- the motor over time --------------------------------------------------------------------


def steady_current(motor: SPMSM, law: ControlLaw, w: Array) -> Array:
    """The continuous dq steady state of the motor under a proportional law (rotor hold,
    no delay: the sampled loop's steady state is the continuous one):
    ``(R_s I + w_e L_s J + K) i = U w + K X w - [0, w_e phi_pm]``."""
    J = np.array([[0.0, -1.0], [1.0, 0.0]])
    matrix = motor.R_s * np.eye(2) + W_E * motor.L_s * J + law.K
    right = law.U @ w + law.K @ law.X @ w - np.array([0.0, W_E * motor.phi_pm])
    return np.linalg.solve(matrix, right)


def test_the_heated_motor_is_the_profiles_and_settles_where_its_equations_say() -> None:
    ramp = ParameterProfile(time=[0.0, 0.1], R_s=[1.0, 1.4], phi_pm=[1.0, 0.92], L_s=[1.0, 0.9])
    hold = 1e-3
    drive = RealisticDrive(MOTOR, SPEED, H, DriveSettings.ideal())
    law = proportional_law()
    session = drive.start(law, seed=0, profile=ramp, max_hold=hold)
    chunks = [session.advance(size, REFERENCE) for size in (333, 667, 1000)]
    t = joined(chunks, "time")
    factors = ramp.factors(t)
    for name in ("R_s", "L_s", "phi_pm"):
        held = joined(chunks, name) / getattr(MOTOR, name)
        change = abs(getattr(ramp, name)[-1] - 1.0) / 0.1 * hold  # the ramp over one hold
        assert np.max(np.abs(held - getattr(factors, name))) <= 0.5 * change * (1 + 1e-9)
        assert np.max(np.abs(held - getattr(factors, name))) >= 0.4 * change  # it is held
    hot = SPMSM(R_s=1.4 * MOTOR.R_s, L_s=0.9 * MOTOR.L_s, phi_pm=0.92 * MOTOR.phi_pm, p=MOTOR.p)
    expected = steady_current(hot, law, REFERENCE)
    np.testing.assert_allclose(chunks[-1].true_currents[-1], expected, rtol=1e-12)
    np.testing.assert_allclose(
        chunks[-1].torque[-1], 1.5 * MOTOR.p * hot.phi_pm * expected[1], rtol=1e-12
    )
    cold = steady_current(MOTOR, law, REFERENCE)
    assert np.max(np.abs(expected - cold)) > 1e3 * 1e-12 * np.max(np.abs(cold))


@pytest.mark.parametrize("settings", [DriveSettings.ideal(), HARDWARE], ids=["ideal", "hardware"])
def test_a_step_lands_at_its_time(settings: DriveSettings) -> None:
    """An R_s step at 0.05 s: the current at sample 500 is the old motor's, from sample
    501 on the new one's; the chunks split elsewhere."""
    step = ParameterProfile(time=[0.0, 0.05, 0.05], R_s=[1.0, 1.0, 1.2], phi_pm=[1.0] * 3)
    drive = RealisticDrive(MOTOR, SPEED, H, settings)
    sizes = [123, 456, 421]
    faulty = run_in_chunks(drive, sizes, proportional_law(), profile=step)
    healthy = run_in_chunks(drive, sizes, proportional_law())
    R_s = joined(faulty, "R_s")
    np.testing.assert_array_equal(R_s[:500], MOTOR.R_s)
    np.testing.assert_array_equal(R_s[500:], 1.2 * MOTOR.R_s)
    i_faulty, i_healthy = joined(faulty, "true_currents"), joined(healthy, "true_currents")
    rounding = 0.0 if settings is HARDWARE else ROUNDING
    np.testing.assert_allclose(i_faulty[:501], i_healthy[:501], rtol=0, atol=rounding)
    # over sample 500 the current decays faster by about dR_s h / L_s of itself (to
    # first order in h: 5% covers the turning and the command's part)
    jump = float(np.linalg.norm(i_faulty[501] - i_healthy[501]))
    expected = 0.2 * MOTOR.R_s * H / MOTOR.L_s * float(np.linalg.norm(i_healthy[500]))
    assert jump == pytest.approx(expected, rel=0.05)
    assert jump > 1e6 * ROUNDING


def test_the_profile_rules_name_the_row_and_key() -> None:
    cases = [
        (dict(time=[1.0], R_s=[1.0], phi_pm=[1.0]), "row 1: time: must be 0"),
        (
            dict(time=[0.0, -1.0], R_s=[1.0, 1.0], phi_pm=[1.0, 1.0]),
            "row 2: time: -1.0 s is before",
        ),
        (dict(time=[0.0, 1.0, 1.0, 1.0], R_s=[1.0] * 4, phi_pm=[1.0] * 4), "row 4: time: a third"),
        (dict(time=[0.0, 1.0], R_s=[1.0, 0.0], phi_pm=[1.0, 1.0]), "row 2: R_s: must be positive"),
        (dict(time=[0.0], R_s=[1.0], phi_pm=[np.inf]), "phi_pm: contains NaN or infinite"),
        (dict(time=[0.0], R_s=[1.0], phi_pm=[1.0], L_s=[-2.0]), "row 1: L_s: must be positive"),
        (dict(time=[0.0], R_s=[1.0, 2.0], phi_pm=[1.0]), "R_s: expected 1 values"),
    ]
    for arguments, message in cases:
        with pytest.raises(InputError, match="^" + message):
            ParameterProfile(**arguments)  # type: ignore[arg-type]


def test_profile_factors_interpolate_and_step() -> None:
    profile = ParameterProfile(
        time=[0.0, 60.0, 60.0, 120.0], R_s=[1.0, 1.2, 1.44, 1.5], phi_pm=[1.0, 0.95, 0.95, 0.9]
    )
    at = profile.factors([0.0, 30.0, np.nextafter(60.0, 0.0), 60.0, 90.0, 120.0, 500.0])
    np.testing.assert_allclose(at.R_s, [1.0, 1.1, 1.2, 1.44, 1.47, 1.5, 1.5], rtol=1e-14)
    np.testing.assert_allclose(at.phi_pm, [1.0, 0.975, 0.95, 0.95, 0.925, 0.9, 0.9], rtol=1e-14)
    np.testing.assert_array_equal(at.L_s, 1.0)


# -- the carrier plant, one motor in Python floats ----------------------------------------


def segment_by_segment(
    current: complex, voltage: complex, signs: Array, emf: complex, rotor: complex
) -> tuple[complex, complex]:
    """``i_ab`` after one carrier period and the mean dq voltage over it, summed over the
    sorted segments of :func:`carrier_segments` (the exact solution for a constant voltage
    over each: ``i(b) = a i(a) + v (1 - a) / R_s``, ``a = exp(-gamma (b - a))``, ``1 - a``
    without cancellation)."""
    assert HARDWARE.dc_voltage is not None
    segments = carrier_segments(
        np.array([voltage]), HARDWARE.dc_voltage, H, HARDWARE.dead_time, signs[np.newaxis]
    )
    gamma, w_e = MOTOR.R_s / MOTOR.L_s, W_E
    after, total = current, 0j
    for j in range(7):
        start, stop = segments.boundaries[0, j], segments.boundaries[0, j + 1]
        v, change = segments.voltages[0, j], np.expm1(-gamma * (stop - start))
        after = (1.0 + change) * after - v * change / MOTOR.R_s
        # the integral of exp(-j w_e s) over the segment, without cancellation
        length = stop - start
        middle = np.exp(-1j * w_e * (start + stop) / 2)
        total += v * length * middle * np.sinc(w_e * length / (2 * np.pi))
    return after + emf, np.conj(rotor) * total / H


def test_the_superposed_legs_are_the_segments_exact_solution() -> None:
    """The carrier plant propagates the three legs' pulses, superposed; summed segment by
    segment the period gives the same current and mean voltage, to rounding: terms of
    V_dc h / L_s (0.9 A) and V_dc (540 V) cancel to a few eps of them."""
    assert HARDWARE.dc_voltage is not None
    rng = np.random.default_rng(4)
    gamma = MOTOR.R_s / MOTOR.L_s
    motor = (gamma, MOTOR.R_s, W_E, float(np.exp(-gamma * H)))
    dc, size = HARDWARE.dc_voltage, HARDWARE.dc_voltage * H / MOTOR.L_s
    for _ in range(300):
        voltage = complex(
            dc / np.sqrt(3.0) * np.sqrt(rng.uniform()) * np.exp(2j * np.pi * rng.uniform())
        )
        current, emf = complex(*rng.normal(0.0, 5.0, 2)), complex(*rng.normal(0.0, 0.1, 2))
        rotor = complex(np.exp(2j * np.pi * rng.uniform()))
        signs = rng.choice([-1.0, 0.0, 1.0], size=3)
        edges = carrier_edges(voltage, dc, H, HARDWARE.dead_time, signs.tolist())
        after, mean = carrier_sample(motor, current, edges, dc, H, emf, rotor)
        expected_after, expected_mean = segment_by_segment(current, voltage, signs, emf, rotor)
        eps = np.finfo(float).eps
        assert abs(after - expected_after) < 16 * eps * (abs(current) + size)
        assert abs(mean - expected_mean) < 16 * eps * dc


def test_the_sensor_reads_one_motor_as_numpy_reads_many() -> None:
    """:meth:`CurrentSensor.phase_values` (Python floats) equals :meth:`CurrentSensor.phases`
    to the bit: the noise, the rounding half to even, the clipping at the codes."""
    lsb = 50.0 / 2048
    values = [
        [2.5 * lsb, -3.5 * lsb, 0.5 * lsb],  # ties: to even
        [-0.5 * lsb, 1e9, -1e9],  # clipped to the codes
        [2047.5 * lsb, -2048.5 * lsb, np.inf],
    ]
    noise = np.concatenate([values, np.random.default_rng(2).normal(0.0, 3.0, (50, 3))])[np.newaxis]
    for sensor in (
        CurrentSensor(noise=noise, lsb=lsb, codes=2048),
        CurrentSensor(noise=noise, lsb=None, codes=0),
    ):
        for k in range(noise.shape[1]):
            expected = sensor.phases(np.zeros(1, dtype=complex), k)[0]  # the phases: the noise
            actual = sensor.phase_values((0.0, 0.0, 0.0), noise[0, k].tolist())
            np.testing.assert_array_equal(actual, expected)


# -- speed --------------------------------------------------------------------------------


def measure(
    settings: DriveSettings, chunk: int, total: int, profile: ParameterProfile | None
) -> float:
    """Samples per CPU second of a session advanced in chunks (best of two)."""
    drive = RealisticDrive(MOTOR, SPEED, H, settings)
    best = 0.0
    for _ in range(2):
        session = drive.start(servo_law(), seed=0, profile=profile)
        start = time.process_time()
        for _ in range(total // chunk):
            session.advance(chunk, REFERENCE)
        best = max(best, total / (time.process_time() - start))
    return best


if __name__ == "__main__":  # python tests/test_drive_session.py: the timings
    warm = ParameterProfile(time=[0.0, 120.0], R_s=[1.0, 1.4], phi_pm=[1.0, 0.92])
    for name, settings, total in (
        ("average PWM, noise", NOISY, 100_000),
        ("hardware_like", HARDWARE, 20_000),
    ):
        for profile in (None, warm):
            for chunk in (100, 1000):
                rate = measure(settings, chunk, total, profile)
                label = "warming" if profile else "constant"
                print(
                    f"{name:20s} {label:9s} chunks of {chunk:5d}: {rate:10.0f} samples/s, "
                    f"{rate * H:6.1f}x real time at 10 kHz"
                )
    # one run of 20,000 samples from rest (the timings of selftune.sim._realistic)
    dead_time = dataclasses.replace(DriveSettings.hardware_like(), pwm="average")
    for name, settings in (
        ("average PWM", DriveSettings()),
        ("dead time, noise, ADC", dead_time),
        ("hardware_like", DriveSettings.hardware_like()),
    ):
        for motors in (1, 20):
            seconds = []
            for _ in range(2):
                start = time.process_time()
                run_drive_batch(
                    [MOTOR] * motors, SPEED, H, settings, servo_law(), constant(REFERENCE),
                    num_samples=20_000, exploration=uniform(2.0), seed=0,
                )  # fmt: skip
                seconds.append(time.process_time() - start)
            print(f"{name:22s} {motors:2d} motor(s) x 20,000 samples: {min(seconds):6.2f} s")
    sys.exit(0)
